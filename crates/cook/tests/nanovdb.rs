//! The NanoVDB size model (`vdbcook_cook::nanovdb`) against NanoVDB's own converter: for real
//! files (the committed fixtures, and the samples of `../shared/samples` when present), the grid
//! size `nanovdb_convert` writes (the `gridSize` of the file's first grid record) must equal the
//! model's bytes, as float grids and as FpN at several absolute tolerances (a double grid stays
//! double either way).
//!
//! Needs `nanovdb_convert` (Debian: `libnanovdb-tools`). Without it the test skips and says so,
//! unless `VDBCOOK_REQUIRE_PEERS=1` (CI sets it and installs the tool): then it fails.

#[path = "../../vdb/tests/support/samples.rs"]
mod samples;

use std::path::{Path, PathBuf};
use std::process::Command;

use vdbcook_cook::nanovdb::NanoGrids;
use vdbcook_vdb::VdbFile;

fn tool_available() -> bool {
    let found = Command::new("nanovdb_convert")
        .arg("--version")
        .output()
        .is_ok();
    let required = std::env::var("VDBCOOK_REQUIRE_PEERS").is_ok_and(|v| v == "1");
    assert!(
        found || !required,
        "nanovdb_convert is missing (Debian: libnanovdb-tools) and VDBCOOK_REQUIRE_PEERS=1"
    );
    if !found {
        eprintln!("skipping: nanovdb_convert not found (Debian: libnanovdb-tools)");
    }
    found
}

/// The grid size `nanovdb_convert OPTIONS -g GRID input` writes.
fn converted_grid_bytes(input: &Path, grid: &str, options: &[&str], dir: &Path) -> u64 {
    let out = dir.join("out.nvdb");
    let o = Command::new("nanovdb_convert")
        .arg("-f")
        .args(options)
        .args(["-g", grid])
        .arg(input)
        .arg(&out)
        .output()
        .expect("nanovdb_convert runs");
    assert!(
        o.status.success(),
        "nanovdb_convert {options:?} {}: {}",
        input.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    let bytes = std::fs::read(&out).unwrap();
    // FileHeader (16 bytes: magic, version, grid count, codec), then the first grid's
    // FileMetaData, whose first field is the grid's size in bytes.
    assert_eq!(u16::from_le_bytes([bytes[12], bytes[13]]), 1, "one grid");
    u64::from_le_bytes(bytes[16..24].try_into().unwrap())
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn check(path: &Path, grid: Option<&str>, tolerances: &[f32], dir: &Path) {
    let file = VdbFile::open(path).unwrap();
    let idx = file.select(grid).unwrap();
    let name = file.grids[idx].name.clone();
    let g = file.read_float_grid(idx).unwrap();
    let mut model = NanoGrids::default();
    model.add_grid(&g, true);
    let float = converted_grid_bytes(path, &name, &[], dir);
    assert_eq!(
        model.float_bytes(),
        float,
        "{} float: model {} vs nanovdb_convert {float}",
        path.display(),
        model.float_bytes()
    );
    for &e in tolerances {
        let a = format!("{e}");
        let fpn = converted_grid_bytes(path, &name, &["--fpN", "-a", &a], dir);
        assert_eq!(
            model.fpn_bytes(e),
            Some(fpn),
            "{} FpN -a {e}: model {} vs nanovdb_convert {fpn}",
            path.display(),
            model.fpn_bytes(e).unwrap()
        );
        eprintln!(
            "{} ({} leaves): float {float} B, FpN -a {e}: {fpn} B",
            path.display(),
            g.leaves.len()
        );
    }
}

#[test]
fn the_model_is_the_size_nanovdb_convert_writes_on_fixtures() {
    if !tool_available() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let f = repo().join("fixtures");
    for (file, grid) in [
        ("seq/smoke5/smoke.0003.vdb", None),
        ("seq/fire/fire.0002.vdb", Some("temperature")),
        ("vdb/fog_f16_blosc_mask.vdb", None),
        ("vdb/fire_houdini.vdb", Some("density")),
        // A double grid stays double in NanoVDB, `--fpN` or not.
        ("vdb/double_only.vdb", None),
    ] {
        check(&f.join(file), grid, &[0.001, 0.02, 0.1], dir.path());
    }
}

#[test]
fn the_model_is_the_size_nanovdb_convert_writes_on_real_samples() {
    if !tool_available() {
        return;
    }
    let Some(s) = samples::samples_dir(&repo()) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    for (file, grid, tolerances) in [
        (
            "wdas-cloud/wdas_cloud_sixteenth.vdb",
            None,
            [0.002, 0.02, 0.1],
        ),
        ("openvdb-smoke1/smoke.vdb", None, [0.002, 0.02, 0.1]),
        (
            "stormscape-cloud-seq/output_cube_fluid_70_frame_0100.vdb",
            None,
            [0.03, 0.3, 1.5],
        ),
        ("volumetric-path-tracer/box.vdb", None, [0.002, 0.02, 0.1]),
        (
            "volumetric-path-tracer/dragon_with_xform.vdb",
            None,
            [0.002, 0.02, 0.1],
        ),
    ] {
        if let Some(path) = samples::sample(&s, file) {
            check(&path, grid, &tolerances, dir.path());
        }
    }
}
