//! The `vdbcook` binary as scripts use it: `inspect --json` keys and values on fixtures and
//! samples, tables for people, and failures that exit non-zero naming the file.

mod common;

use common::{root, sample, vdbcook};
use serde_json::Value;

#[test]
fn inspect_json_has_the_contract_keys() {
    let (code, out, err) = vdbcook(&["inspect", "--json", "fixtures/seq/smoke5"]);
    assert_eq!(code, 0, "{err}");
    let doc: Value = serde_json::from_str(&out).expect("one JSON document");
    let files = doc["files"].as_array().unwrap();
    assert_eq!(files.len(), 5);
    for (i, f) in files.iter().enumerate() {
        assert!(f["file"]
            .as_str()
            .unwrap()
            .ends_with(&format!("smoke.000{}.vdb", i + 1)));
        assert_eq!(f["file_version"], 224);
        let g = &f["grids"][0];
        for k in [
            "name",
            "value_type",
            "class",
            "half_float",
            "compression",
            "active_voxels",
            "tiles",
            "bbox_min",
            "bbox_max",
            "value_min",
            "value_max",
            "value_sum",
        ] {
            assert!(!g[k].is_null(), "missing {k}");
        }
        for k in ["kind", "voxel_size", "translation", "matrix"] {
            assert!(!g["transform"][k].is_null(), "missing transform.{k}");
        }
        // Cross-check with OpenVDB's truth for this frame.
        let truth: Value = serde_json::from_str(
            &std::fs::read_to_string(
                root().join(format!("fixtures/seq/smoke5/smoke.000{}.truth.json", i + 1)),
            )
            .unwrap(),
        )
        .unwrap();
        assert_eq!(g["active_voxels"], truth["grids"][0]["active_voxels"]);
        assert_eq!(g["bbox_min"], truth["grids"][0]["bbox_min"]);
        assert_eq!(g["bbox_max"], truth["grids"][0]["bbox_max"]);
    }
}

#[test]
fn inspect_lists_non_float_grids_with_their_type() {
    let (code, out, _) = vdbcook(&["inspect", "--json", "fixtures/vdb/multi_grids.vdb"]);
    assert_eq!(code, 0);
    let doc: Value = serde_json::from_str(&out).unwrap();
    let grids = doc["files"][0]["grids"].as_array().unwrap();
    let vel = grids.iter().find(|g| g["name"] == "vel").unwrap();
    assert_eq!(vel["value_type"], "vec3s");
    assert!(vel["active_voxels"].is_null());
    let heat = grids.iter().find(|g| g["name"] == "heat_d").unwrap();
    assert_eq!(heat["converted_from_double"], true);
}

#[test]
fn inspect_table_for_people() {
    let (code, out, _) = vdbcook(&["inspect", "fixtures/vdb/levelset_sphere.vdb"]);
    assert_eq!(code, 0);
    assert!(
        out.contains("level set") && out.contains("active voxels"),
        "{out}"
    );
}

#[test]
fn broken_input_exits_non_zero_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let src = std::fs::read(root().join("fixtures/vdb/fog_f32_zip_mask.vdb")).unwrap();
    let bad = dir.path().join("cut.vdb");
    std::fs::write(&bad, &src[..src.len() / 2]).unwrap();
    let (code, out, err) = vdbcook(&["inspect", bad.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(out.is_empty());
    assert!(
        err.contains("cut.vdb") && err.starts_with("error: "),
        "{err}"
    );
    let (code, out, _) = vdbcook(&["inspect", "--json", bad.to_str().unwrap()]);
    assert_eq!(code, 1);
    let doc: Value = serde_json::from_str(&out).expect("an error document");
    assert_eq!(doc["error"]["kind"], "corrupt");
    assert!(doc["error"]["file"].as_str().unwrap().ends_with("cut.vdb"));
    let (code, _, err) = vdbcook(&["inspect", "does/not/exist.vdb"]);
    assert_eq!(code, 1);
    assert!(err.contains("does/not/exist.vdb"), "{err}");
}

#[test]
fn inspect_real_samples_match_the_published_counts() {
    let (Some(wdas), Some(smoke1), Some(points)) = (
        sample("wdas-cloud/wdas_cloud_sixteenth.vdb"),
        sample("openvdb-smoke1/smoke.vdb"),
        sample("negative/points.vdb"),
    ) else {
        return;
    };
    let (code, out, err) = vdbcook(&["inspect", "--json", &wdas, &smoke1]);
    assert_eq!(code, 0, "{err}");
    let doc: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(doc["files"][0]["grids"][0]["active_voxels"], 415642);
    assert_eq!(doc["files"][0]["grids"][0]["tiles"], 130);
    assert_eq!(doc["files"][1]["grids"][0]["active_voxels"], 1049275);
    assert_eq!(doc["files"][1]["grids"][0]["half_float"], true);
    // Point grids: listed with their type, not a crash.
    let (code, out, _) = vdbcook(&["inspect", "--json", &points]);
    assert_eq!(code, 0);
    assert!(out.contains("ptdataidx32"));
}
