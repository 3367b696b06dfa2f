#!/usr/bin/env bash
# Multiple scattering: vdbcook's `--mode reference` (radiance L of the medium, the directly seen
# sky left out) vs Mitsuba's volpath with hide_emitters. See README.md.
#
#   tools/mitsuba/check_reference.sh OUTDIR NAME VDB GRID ABSORB SCATTER DX,DY,DZ,R,G,B SR,SG,SB G \
#       BOUNCES EX,EY,EZ,LX,LY,LZ,FOV W H SPP_OURS SPP_MITSUBA
#
# vdbcook renders twice (seeds 1 and 2) at W x H (pixel centres) and twice at SS*W x SS*H with
# SPP_OURS/SS^2 samples each (pixel area, for Mitsuba's sensor); Mitsuba renders once with its
# sensor (scalar_rgb) and once on vdbcook's pixel-centre rays (llvm_ad_rgb, when it runs).
# Mitsuba: extinction = ABSORB + SCATTER, albedo = SCATTER / (ABSORB + SCATTER), HG g = G,
# max_depth = BOUNCES + 1 (vdbcook's BOUNCES = most scattering events; Mitsuba's max_depth 1 is
# emitters only, each real scattering event adds one, crossings of the null-BSDF cube add none).
#
# Env: VDBCOOK (default /tmp/vdbcook-new), MI_PY (default /tmp/mi-venv/bin/python), SS (default 4),
#      DRJIT_LIBLLVM_PATH (an LLVM >= 16 for llvm_ad_rgb),
#      WHICH (default "sensor centres"): which of the two comparisons to run.
set -euo pipefail
[ $# -eq 15 ] || { sed -n 2,17p "$0"; exit 2; }
OUT=$1 NAME=$2 VDB=$3 GRID=$4 ABSORB=$5 SCATTER=$6 LIGHT=$7 SKY=$8 G=$9
BOUNCES=${10} CAM=${11} W=${12} H=${13} SPP=${14} MSPP=${15}
HERE=$(cd "$(dirname "$0")" && pwd)
VDBCOOK=${VDBCOOK:-/tmp/vdbcook-new}
MI_PY=${MI_PY:-/tmp/mi-venv/bin/python}
SS=${SS:-4}
WHICH=${WHICH:-sensor centres}
mkdir -p "$OUT"
IFS=, read -r ex ey ez lx ly lz fov <<<"$CAM"
IFS=, read -r dx dy dz lr lg lb <<<"$LIGHT"
ext=$("$MI_PY" -c "print(repr($ABSORB + $SCATTER))")
alb=$("$MI_PY" -c "print(repr($SCATTER / ($ABSORB + $SCATTER)))")
cat >"$OUT/$NAME.reference.json" <<EOF
{"vdb": "$(realpath "$VDB")", "grid": "$GRID", "width": $W, "height": $H,
 "camera": {"eye": [$ex, $ey, $ez], "look": [$lx, $ly, $lz], "up": [0, 1, 0], "fov_y_deg": $fov},
 "extinction": $ext, "albedo": $alb, "phase_g": $G,
 "sun": {"dir": [$dx, $dy, $dz], "irradiance": [$lr, $lg, $lb]}, "sky": [$SKY],
 "spp": $MSPP, "max_depth": $((BOUNCES + 1)), "hide_emitters": true}
EOF
common=(--mode reference --units world --absorb "$ABSORB" --scatter "$SCATTER" --light="$LIGHT"
        --sky="$SKY" --phase="$G,0,1" --bounces "$BOUNCES" --camera="$CAM" --backend cpu --grid "$GRID")
secs() { "$MI_PY" -c 'import json,sys; print(json.load(sys.stdin)["render_seconds"])'; }
for seed in 1 2; do
    [[ $WHICH == *centres* ]] || continue
    t=$("$VDBCOOK" render "$VDB" "${common[@]}" --spp "$SPP" --seed $seed --width "$W" --height "$H" \
        -o "$OUT/$NAME.ours_s$seed.pfm" --json | secs)
    echo "vdbcook ${W}x$H spp $SPP seed $seed: render ${t}s"
done
for seed in 1 2; do
    [[ $WHICH == *sensor* ]] || continue
    t=$("$VDBCOOK" render "$VDB" "${common[@]}" --spp $((SPP / SS / SS)) --seed $seed \
        --width $((W * SS)) --height $((H * SS)) -o "$OUT/$NAME.ours_ss_s$seed.pfm" --json | secs)
    echo "vdbcook $((W * SS))x$((H * SS)) spp $((SPP / SS / SS)) seed $seed: render ${t}s"
done
if [[ $WHICH == *sensor* ]]; then
"$MI_PY" "$HERE/render_mitsuba.py" "$OUT/$NAME.reference.json" -o "$OUT/$NAME.mi_sensor.pfm" \
    --stderr-out "$OUT/$NAME.mi_sensor_err.pfm" --variant scalar_rgb
echo "== $NAME: vdbcook ${SS}x supersampled vs Mitsuba sensor (pixel area)"
"$MI_PY" "$HERE/compare.py" "$OUT/$NAME.ours_ss_s1.pfm" "$OUT/$NAME.mi_sensor.pfm" \
    --a2 "$OUT/$NAME.ours_ss_s2.pfm" --downsample-a "$SS" --stderr-b "$OUT/$NAME.mi_sensor_err.pfm" \
    --diff "$OUT/$NAME.diff_sensor.pfm"
fi
[[ $WHICH == *centres* ]] || exit 0
if "$MI_PY" -c 'import mitsuba as mi, drjit as dr; mi.set_variant("llvm_ad_rgb"); print(dr.sum(dr.minimum(mi.Float(1, 2, 3) * 3 - 1, 2.0)))' >/dev/null 2>&1; then
    "$MI_PY" "$HERE/render_mitsuba.py" "$OUT/$NAME.reference.json" -o "$OUT/$NAME.mi_centres.pfm" \
        --stderr-out "$OUT/$NAME.mi_centres_err.pfm" --variant llvm_ad_rgb --rays centres
    echo "== $NAME: vdbcook vs Mitsuba on vdbcook's own pixel-centre rays"
    "$MI_PY" "$HERE/compare.py" "$OUT/$NAME.ours_s1.pfm" "$OUT/$NAME.mi_centres.pfm" \
        --a2 "$OUT/$NAME.ours_s2.pfm" --stderr-b "$OUT/$NAME.mi_centres_err.pfm" \
        --diff "$OUT/$NAME.diff_centres.pfm"
else
    echo "(llvm_ad_rgb unavailable: centres comparison skipped)"
fi
