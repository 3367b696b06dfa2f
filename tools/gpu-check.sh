#!/usr/bin/env bash
# `just gpu-check`: what a machine with a real GPU runs (in under 5 minutes on one) so that the
# project has figures from hardware, not only from lavapipe: the runtime's tests on the adapter
# (VDBCOOK_REQUIRE_GPU=1: a missing adapter fails instead of skipping), then `vdbcook bench` at
# 1920×1080 with 1, 8 and 64 instances on the WDAS cloud, the 200-frame stormscape sequence
# (both from ../shared/samples) and the fire fixture, written as a table with the adapter's name
# and the date to docs/gpu/<adapter>.md (commit it); on stormscape also the lit crossfade dithered
# (`--lit-crossfade dither`) beside the default lerp, the light volumes built without the
# gathered orders (`--ms-gather 0`) beside the default two, and built ahead (`--light-ahead 2`). SIZE=WxH and COUNTS=1,8,64 override;
# SKIP_TESTS=1 skips the tests (a dry run of the tables); RESOLUTIONS=full,half,quarter the marches
# benched. For a machine without cargo (binaries built
# elsewhere): VDBCOOK=path/to/vdbcook skips the build, RUNTIME_TESTS="bin ..." runs those prebuilt
# test binaries of the runtime instead of `cargo test`, ASSETS=dir benches the dir's *.vdbc as cooked.
set -euo pipefail
cd "$(dirname "$0")/.."
SAMPLES=${SAMPLES:-../shared/samples}
SIZE=${SIZE:-1920x1080}
COUNTS=${COUNTS:-1,8,64}
W=${SIZE%x*}
H=${SIZE#*x}
OUT=${OUT:-bench-data/gpu-check}
mkdir -p "$OUT" docs/gpu
if [ -z "${VDBCOOK:-}" ]; then
    cargo build --release -p vdbcook
    VDBCOOK=target/release/vdbcook
fi
if [ -z "${SKIP_TESTS:-}" ]; then
    if [ -n "${RUNTIME_TESTS:-}" ]; then
        for t in $RUNTIME_TESTS; do VDBCOOK_REQUIRE_GPU=1 "$t"; done
    else
        VDBCOOK_REQUIRE_GPU=1 cargo test --release -p vdbcook-runtime
    fi
fi
assets=()
cook() { # name, input... (cooked fresh each run: vdbcook writes atomically, never a partial file)
    local name=$1
    shift
    "$VDBCOOK" cook "$@" -o "$OUT/$name.vdbc" >/dev/null || exit 1
    assets+=("$name")
}
if [ -n "${ASSETS:-}" ]; then
    for f in "$ASSETS"/*.vdbc; do
        name=$(basename "$f" .vdbc)
        cp "$f" "$OUT/$name.vdbc"
        assets+=("$name")
    done
else
if [ -f "$SAMPLES/wdas-cloud/wdas_cloud_sixteenth.vdb" ]; then
    cook wdas "$SAMPLES/wdas-cloud/wdas_cloud_sixteenth.vdb"
    # What packed bricks cost to read against the formats they replace (issue 33): the same
    # 2% bound with and without them, at full resolution only.
    cook wdas-e2 "$SAMPLES/wdas-cloud/wdas_cloud_sixteenth.vdb" --max-error 0.02
    cook wdas-e2-nopacked "$SAMPLES/wdas-cloud/wdas_cloud_sixteenth.vdb" --max-error 0.02 \
        --no-packed
fi
if [ -d "$SAMPLES/stormscape-cloud-seq" ]; then
    cook stormscape "$SAMPLES/stormscape-cloud-seq"
fi
cook fire fixtures/seq/fire --grids auto
fi
RESOLUTIONS=${RESOLUTIONS:-full,half,quarter}
runs=()
for name in "${assets[@]}"; do
    case $name in
    *-e2*) resolutions=full ;;
    *) resolutions=$RESOLUTIONS ;;
    esac
    for res in ${resolutions//,/ }; do
        "$VDBCOOK" bench "$OUT/$name.vdbc" --width "$W" --height "$H" --march-resolution "$res" \
            --instances "$COUNTS" --frames 60 --runs 10 --json >"$OUT/$name-$res.json" || exit 1
        runs+=("$name-$res")
    done
    # A lit crossfade that reads one frame per sample (`--lit-crossfade dither`), against the
    # default lerp above: its cost and its grain (`crossfade_error`), full resolution.
    if [ "$name" = stormscape ]; then
        "$VDBCOOK" bench "$OUT/$name.vdbc" --width "$W" --height "$H" --modes lit \
            --lit-crossfade dither --instances "$COUNTS" --frames 60 --runs 10 --json \
            >"$OUT/$name-dither-full.json" || exit 1
        runs+=("$name-dither-full")
        # The light-volume build without the gathered orders (`--ms-gather 0`, the solve
        # alone), against the default two above: what the gather costs on this GPU (the
        # playing mean holds 0.4 builds per displayed frame).
        "$VDBCOOK" bench "$OUT/$name.vdbc" --width "$W" --height "$H" --modes lit \
            --ms-gather 0 --instances "$COUNTS" --frames 60 --runs 10 --json \
            >"$OUT/$name-gather0-full.json" || exit 1
        runs+=("$name-gather0-full")
        # Each next frame's light volume built over the two displayed frames before it
        # (`--light-ahead 2`): the same light and mean, the builds' frames (max) against the
        # default's.
        "$VDBCOOK" bench "$OUT/$name.vdbc" --width "$W" --height "$H" --modes lit \
            --light-ahead 2 --instances "$COUNTS" --frames 60 --runs 10 --json \
            >"$OUT/$name-ahead2-full.json" || exit 1
        runs+=("$name-ahead2-full")
        # One light volume per two flip-book frames while playing (`--light-stride 2`): half
        # the builds, its playing error against each frame's exact light.
        "$VDBCOOK" bench "$OUT/$name.vdbc" --width "$W" --height "$H" --modes lit \
            --light-stride 2 --instances "$COUNTS" --frames 60 --runs 10 --json \
            >"$OUT/$name-stride2-full.json" || exit 1
        runs+=("$name-stride2-full")
    fi
done
python3 - "$OUT" "${runs[@]}" <<'PY'
import json, re, sys, datetime
out, names = sys.argv[1], sys.argv[2:]
docs = {n: json.load(open(f"{out}/{n}.json")) for n in names}
adapter = next(iter(docs.values()))["adapter"]
slug = re.sub(r"[^a-z0-9]+", "-", adapter.lower()).strip("-")[:60]
clocks = sorted({d["clock"] for d in docs.values()})
lines = [f"# `vdbcook bench` on {adapter}", "",
         f"{datetime.date.today()}, `just gpu-check` (tools/gpu-check.sh); clock: {', '.join(clocks)}. GPU ms per displayed frame (the timestamp span from before the drawer's prepare to after its passes: light-volume builds included), median; the mean while playing is the amortized cost; draw: the drawer's passes alone. Playing: the flip-book at 24 fps shown at 60 fps. Error: the playing path against a fresh drawer (largest relative RMSE of three frames). March: full (a ray per pixel), half or quarter (a ray per 2×2 or 4×4 block away from depth edges, upsampled; `MarchResolution`), with its static frame's relative RMSE against the full march. Lit crossfades lerp both frames per sample (the default) except in the `-dither` rows (`--lit-crossfade dither`: one frame per sample), whose crossfade error is their playing frames' relative RMSE against the lerp. The `-gather0` rows build light volumes without the gathered orders (`--ms-gather 0`): their playing mean against the default's is what the gather costs (0.4 builds per displayed frame). The `-ahead2` rows build each next frame's light volume over the two displayed frames before it (`--light-ahead 2`): compare their playing max (the worst displayed frame) with the default's. The `-stride2` rows light the playing flip-book by one light volume per two frames (`--light-stride 2`): half the builds, their playing error against each frame's exact light. Light build: what building the static frame's light volumes adds to a displayed frame (lit; every instance's volume).", "",
         "| asset | size | march | mode | instances | static ms | playing ms | playing mean ms | playing max ms | playing draw ms | playing / static | light build ms | playing error | vs full march | crossfade error |",
         "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
def num(v, f=".2f"):
    return "–" if v is None else format(v, f)
for n, d in docs.items():
    for r in d["results"]:
        ratio = r["playing_ms"] / r["static_ms"] if r["static_ms"] else None
        asset = n.rsplit("-", 1)[0]
        lines.append(f"| {asset} | {d['width']}×{d['height']} | {d.get('march_resolution', 'full')} | {r['mode']} | {r['instances']} | {num(r['static_ms'])} | {num(r['playing_ms'])} | {num(r['playing_mean_ms'])} | {num(r.get('playing_max_ms'))} | {num(r['playing_draw_ms'])} | {num(ratio)} | {num(r.get('light_build_ms'))} | {num(r['playing_error'], '.1e')} | {num(r.get('resolution_error'), '.3f')} | {num(r.get('crossfade_error'), '.1e')} |")
path = f"docs/gpu/{slug}.md"
open(path, "w").write("\n".join(lines) + "\n")
print(f"wrote {path}")
PY
