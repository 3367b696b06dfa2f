//! The reader against OpenVDB's own numbers: every fixture in `fixtures/` (written by real OpenVDB,
//! truth computed by OpenVDB at generation time) and every sample in `../shared/samples` that has
//! a truth file in `fixtures/samples-truth/`.

mod common;

use common::*;
use serde_json::Value;

fn load(p: &std::path::Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn every_fixture_matches_openvdb_truth() {
    let truths: Vec<_> = truth_files(&fixtures().join("vdb"))
        .into_iter()
        .chain(truth_files(&fixtures().join("seq")))
        .collect();
    assert!(
        truths.len() >= 20,
        "expected the fixture set, found {} truth files",
        truths.len()
    );
    let mut failures = Vec::new();
    let mut codes = [0u64; 7];
    for t in &truths {
        let vdb = std::path::PathBuf::from(t.to_string_lossy().replace(".truth.json", ".vdb"));
        let (errs, c) = compare_with_truth(&vdb, &load(t));
        for (total, n) in codes.iter_mut().zip(c.metadata_codes) {
            *total += n;
        }
        for e in errs {
            failures.push(format!("{}: {e}", vdb.display()));
        }
    }
    assert!(
        failures.is_empty(),
        "{} mismatches:\n{}",
        failures.len(),
        failures.join("\n")
    );
    // The fixture set must exercise all seven per-node mask-compression codes.
    assert!(
        codes.iter().all(|&c| c > 0),
        "per-node compression codes seen: {codes:?}"
    );
}

#[test]
fn shared_samples_match_openvdb_truth() {
    let Some(samples) = samples() else {
        return;
    };
    let truths = truth_files(&fixtures().join("samples-truth"));
    assert!(
        !truths.is_empty(),
        "no sample truth files in fixtures/samples-truth"
    );
    let mut failures = Vec::new();
    let mut checked = 0;
    for t in &truths {
        let stem = t
            .file_name()
            .unwrap()
            .to_string_lossy()
            .replace(".truth.json", "");
        let (folder, file) = stem.split_once("__").expect("folder__file naming");
        let Some(vdb) = sample(&samples, &format!("{folder}/{file}.vdb")) else {
            continue;
        };
        checked += 1;
        let (errs, _) = compare_with_truth(&vdb, &load(t));
        for e in errs {
            failures.push(format!("{}: {e}", vdb.display()));
        }
    }
    eprintln!("checked {checked} sample files against OpenVDB truth");
    assert!(
        failures.is_empty(),
        "{} mismatches:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
