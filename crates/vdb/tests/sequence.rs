//! Frame-sequence resolution and reading: patterns, folders, globs, natural order, gaps,
//! duplicate numbers, mismatched transforms (fixtures written by OpenVDB), parallel reads.

mod common;

use std::path::Path;

use vdbcook_vdb::sequence::{frame_number, natural_cmp, read_sequence, resolve_inputs};
use vdbcook_vdb::ErrorKind;

fn touch(dir: &Path, names: &[&str]) {
    for n in names {
        std::fs::write(dir.join(n), b"").unwrap();
    }
}

fn numbers(frames: &[vdbcook_vdb::sequence::Frame]) -> Vec<i64> {
    frames.iter().map(|f| f.number.unwrap()).collect()
}

#[test]
fn patterns_folders_and_globs_resolve_in_frame_order() {
    let d = tempfile::tempdir().unwrap();
    touch(
        d.path(),
        &[
            "smoke.0009.vdb",
            "smoke.0010.vdb",
            "smoke.0008.vdb",
            "smoke.0011.vdb",
            "notes.txt",
            "other.vdb.bak",
        ],
    );
    let p = d.path().display().to_string();
    for input in [
        format!("{p}/smoke.####.vdb"),
        format!("{p}/smoke.%04d.vdb"),
        format!("{p}/smoke.*.vdb"),
        p.clone(),
    ] {
        let f = resolve_inputs(std::slice::from_ref(&input), false)
            .unwrap_or_else(|e| panic!("{input}: {e}"));
        assert_eq!(numbers(&f), vec![8, 9, 10, 11], "{input}");
    }
}

#[test]
fn unpadded_numbers_sort_naturally() {
    let d = tempfile::tempdir().unwrap();
    touch(
        d.path(),
        &[
            "f_1.vdb", "f_10.vdb", "f_2.vdb", "f_3.vdb", "f_4.vdb", "f_5.vdb", "f_6.vdb",
            "f_7.vdb", "f_8.vdb", "f_9.vdb",
        ],
    );
    let f = resolve_inputs(&[d.path().display().to_string()], false).unwrap();
    assert_eq!(numbers(&f), (1..=10).collect::<Vec<_>>());
    assert_eq!(natural_cmp("a2", "a10"), std::cmp::Ordering::Less);
    assert_eq!(frame_number(Path::new("cache/smoke_v2.0042.vdb")), Some(42));
    assert_eq!(frame_number(Path::new("smoke.-0005.vdb")), Some(-5));
}

#[test]
fn gaps_are_errors_unless_allowed() {
    let d = tempfile::tempdir().unwrap();
    touch(
        d.path(),
        &["s.0001.vdb", "s.0002.vdb", "s.0004.vdb", "s.0007.vdb"],
    );
    let input = format!("{}/s.####.vdb", d.path().display());
    let e = resolve_inputs(std::slice::from_ref(&input), false).unwrap_err();
    assert_eq!(e.kind, ErrorKind::Sequence);
    let m = e.to_string();
    assert!(
        m.contains("3 missing") && m.contains("3, 5, 6") && m.contains("--allow-gaps"),
        "{m}"
    );
    assert_eq!(
        numbers(&resolve_inputs(&[input], true).unwrap()),
        vec![1, 2, 4, 7]
    );
}

#[test]
fn a_uniform_stride_is_not_a_gap_and_duplicates_are_refused() {
    let d = tempfile::tempdir().unwrap();
    touch(d.path(), &["s.0010.vdb", "s.0020.vdb", "s.0030.vdb"]);
    assert_eq!(
        numbers(&resolve_inputs(&[d.path().display().to_string()], false).unwrap()),
        vec![10, 20, 30]
    );
    let d2 = tempfile::tempdir().unwrap();
    touch(d2.path(), &["s.1.vdb", "s.01.vdb"]);
    let e = resolve_inputs(&[d2.path().display().to_string()], false).unwrap_err();
    assert!(e.to_string().contains("appears twice"), "{e}");
}

#[test]
fn missing_inputs_name_themselves() {
    let e = resolve_inputs(&["/no/such/smoke.####.vdb"], false).unwrap_err();
    assert!(e.to_string().contains("/no/such"), "{e}");
    let e = resolve_inputs(&["/no/such/file.vdb"], false).unwrap_err();
    assert!(e.to_string().contains("/no/such/file.vdb"), "{e}");
    let d = tempfile::tempdir().unwrap();
    let e = resolve_inputs(&[format!("{}/x.*.vdb", d.path().display())], false).unwrap_err();
    assert!(e.to_string().contains("no files match"), "{e}");
}

#[test]
fn fixture_sequence_reads_in_parallel_in_order() {
    let dir = common::fixtures().join("seq/smoke5");
    let frames = resolve_inputs(&[dir.display().to_string()], false).unwrap();
    assert_eq!(numbers(&frames), vec![1, 2, 3, 4, 5]);
    let loaded = read_sequence(&frames, None).unwrap();
    assert_eq!(loaded.len(), 5);
    for (f, l) in frames.iter().zip(&loaded) {
        assert_eq!(f, &l.frame);
        // Each frame agrees with reading it alone.
        let single = vdbcook_vdb::sequence::read_frame(f, None).unwrap();
        assert_eq!(single.grid.stats(), l.grid.stats());
    }
    // The blob moves: frames differ.
    assert_ne!(loaded[0].grid.stats(), loaded[4].grid.stats());
}

#[test]
fn fixture_gap_sequence_is_reported() {
    let dir = common::fixtures().join("seq/gap");
    let e = resolve_inputs(&[dir.display().to_string()], false).unwrap_err();
    assert!(e.to_string().contains("missing frame"), "{e}");
    assert_eq!(
        numbers(&resolve_inputs(&[dir.display().to_string()], true).unwrap()),
        vec![1, 2, 4]
    );
}

#[test]
fn mismatched_transforms_name_both_frames() {
    let dir = common::fixtures().join("seq/xform_mismatch");
    let frames = resolve_inputs(&[dir.display().to_string()], false).unwrap();
    let e = read_sequence(&frames, None).unwrap_err();
    let m = e.to_string();
    assert!(
        m.contains("f.0001.vdb") && m.contains("f.0002.vdb") && m.contains("different transform"),
        "{m}"
    );
}
