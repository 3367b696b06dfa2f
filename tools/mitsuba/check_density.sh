#!/usr/bin/env bash
# Geometry check: vdbcook's density mode (1 - T, exact per voxel) vs Mitsuba's T (albedo 0,
# constant sky 1, emitters visible), and both vs an exact float64 voxel walk
# (exact_transmittance.py). See README.md.
#
#   tools/mitsuba/check_density.sh OUTDIR NAME VDB GRID ABSORB EX,EY,EZ,LX,LY,LZ,FOV W H SPP
#
# Env: VDBCOOK (vdbcook binary, default /tmp/vdbcook-old), MI_PY (default /tmp/mi-venv/bin/python),
#      SS (vdbcook supersampling factor for the sensor comparison, default 8),
#      DRJIT_LIBLLVM_PATH (an LLVM >= 16 for llvm_ad_rgb; the centres comparison is skipped when
#      llvm_ad_rgb cannot run).
set -euo pipefail
[ $# -eq 9 ] || { sed -n 2,12p "$0"; exit 2; }
OUT=$1 NAME=$2 VDB=$3 GRID=$4 ABSORB=$5 CAM=$6 W=$7 H=$8 SPP=$9
HERE=$(cd "$(dirname "$0")" && pwd)
VDBCOOK=${VDBCOOK:-/tmp/vdbcook-old}
MI_PY=${MI_PY:-/tmp/mi-venv/bin/python}
SS=${SS:-8}
mkdir -p "$OUT"
IFS=, read -r ex ey ez lx ly lz fov <<<"$CAM"
cat >"$OUT/$NAME.density.json" <<EOF
{"vdb": "$(realpath "$VDB")", "grid": "$GRID", "width": $W, "height": $H,
 "camera": {"eye": [$ex, $ey, $ez], "look": [$lx, $ly, $lz], "up": [0, 1, 0], "fov_y_deg": $fov},
 "extinction": $ABSORB, "albedo": 0.0, "phase_g": 0.0, "sun": null, "sky": [1, 1, 1],
 "spp": $SPP, "max_depth": 2, "hide_emitters": false}
EOF
common=(--mode density --units world --absorb "$ABSORB" --scatter 0 --camera="$CAM" --backend cpu --grid "$GRID")
"$VDBCOOK" render "$VDB" "${common[@]}" --width "$W" --height "$H" -o "$OUT/$NAME.ours.pfm"
"$VDBCOOK" render "$VDB" "${common[@]}" --width $((W * SS)) --height $((H * SS)) -o "$OUT/$NAME.ours_ss.pfm"
"$MI_PY" "$HERE/exact_transmittance.py" "$OUT/$NAME.density.json" -o "$OUT/$NAME.exact.pfm"
echo "== $NAME: vdbcook vs exact float64 voxel walk (pixel centres; deterministic)"
"$MI_PY" "$HERE/compare.py" "$OUT/$NAME.ours.pfm" "$OUT/$NAME.exact.pfm" --one-minus-a \
    --mask-from "$OUT/$NAME.ours.pfm"
"$MI_PY" "$HERE/render_mitsuba.py" "$OUT/$NAME.density.json" -o "$OUT/$NAME.mi_sensor.pfm" \
    --stderr-out "$OUT/$NAME.mi_sensor_err.pfm" --variant scalar_rgb
echo "== $NAME: vdbcook ${SS}x supersampled vs Mitsuba sensor (pixel area)"
"$MI_PY" "$HERE/compare.py" "$OUT/$NAME.ours_ss.pfm" "$OUT/$NAME.mi_sensor.pfm" --one-minus-a \
    --downsample-a "$SS" --mask-from "$OUT/$NAME.ours_ss.pfm" --stderr-b "$OUT/$NAME.mi_sensor_err.pfm"
if "$MI_PY" -c 'import mitsuba as mi, drjit as dr; mi.set_variant("llvm_ad_rgb"); print(dr.sum(dr.minimum(mi.Float(1, 2, 3) * 3 - 1, 2.0)))' >/dev/null 2>&1; then
    "$MI_PY" "$HERE/render_mitsuba.py" "$OUT/$NAME.density.json" -o "$OUT/$NAME.mi_centres.pfm" \
        --stderr-out "$OUT/$NAME.mi_centres_err.pfm" --variant llvm_ad_rgb --rays centres
    echo "== $NAME: vdbcook vs Mitsuba on vdbcook's own pixel-centre rays"
    "$MI_PY" "$HERE/compare.py" "$OUT/$NAME.ours.pfm" "$OUT/$NAME.mi_centres.pfm" --one-minus-a \
        --mask-from "$OUT/$NAME.ours.pfm" --stderr-b "$OUT/$NAME.mi_centres_err.pfm"
    echo "== $NAME: exact float64 voxel walk vs Mitsuba (pixel-centre rays)"
    "$MI_PY" "$HERE/compare.py" "$OUT/$NAME.exact.pfm" "$OUT/$NAME.mi_centres.pfm" \
        --mask-from "$OUT/$NAME.ours.pfm" --stderr-b "$OUT/$NAME.mi_centres_err.pfm"
else
    echo "(llvm_ad_rgb unavailable: centres comparison skipped)"
fi
