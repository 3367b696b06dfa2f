# Development recipes. Each is a plain command; `just` is optional.

# Run the whole test suite (the README's test command).
test:
    cargo test --workspace --exclude vdbcook-bevy && cargo test -p vdbcook-runtime -p vdbcook-bevy --no-default-features --features vdbcook-runtime/wgpu29

# Formatting and lints, as CI runs them.
lint:
    cargo fmt --all -- --check
    cargo clippy --workspace --exclude vdbcook-bevy --all-targets -- -D warnings
    cargo clippy -p vdbcook-runtime -p vdbcook-bevy --no-default-features --features vdbcook-runtime/wgpu29 --all-targets -- -D warnings

# Reader throughput on a generated 256³ blosc fog, side by side with vdb-rs; then cook vs read
# on the 200-frame stormscape sequence (needs ../shared/samples).
# Needs python3-openvdb (apt) once, to write the input file with real OpenVDB.
bench:
    test -f bench-data/fog256.vdb || (mkdir -p bench-data && /usr/bin/python3 crates/vdb/benches/gen_fog.py bench-data/fog256.vdb 256)
    cargo bench -p vdbcook-vdb --bench read -- "$(pwd)/bench-data/fog256.vdb"
    cargo bench -p vdbcook --bench cook -- "$(realpath ../shared/samples/stormscape-cloud-seq)" 9

# The speed-vs-accuracy reports of docs/performance.md and docs/accuracy.md: the wdas cloud, the
# stormscape sequence (../shared/samples) and a generated 100-frame smoke (python3-openvdb once).
# NanoVDB and vdb_render join when installed (Debian: libnanovdb-tools, libopenvdb-tools).
report-docs:
    cargo build --release -p vdbcook
    test -d bench-data/smoke100 || /usr/bin/python3 cooker/benches/gen_smoke_seq.py bench-data/smoke100 100
    target/release/vdbcook report ../shared/samples/wdas-cloud/wdas_cloud_sixteenth.vdb -o docs/report/wdas
    target/release/vdbcook report ../shared/samples/stormscape-cloud-seq -o docs/report/stormscape
    target/release/vdbcook report bench-data/smoke100 -o docs/report/smoke100
    cargo bench -p vdbcook --bench channel_payloads -- fixtures/seq/fire density,temperature,flame docs/report/channels

# Regenerate fixtures/ with OpenVDB (installs Debian's OpenVDB packages first).
fixtures:
    bash fixtures/gen/build.sh

# Fuzz the reader (needs nightly-free cargo-fuzz: `cargo install cargo-fuzz`).
fuzz seconds="60":
    cd fuzz && cargo fuzz run read_vdb -- -max_total_time={{seconds}}

# The main job on the built-in default input.
run:
    cargo run --release -- cook fixtures/seq/smoke5 -o smoke5.vdbc

# On a machine with a real GPU: the runtime's tests on it and `vdbcook bench` (WDAS, stormscape,
# the fire fixture; 1920×1080; 1, 8, 64 instances) into docs/gpu/<adapter>.md. Under 5 minutes
# on a GPU; commit the table.
gpu-check:
    bash tools/gpu-check.sh
