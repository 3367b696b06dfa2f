//! Bad input never panics or aborts: a seeded corruption harness over the committed fixtures
//! (truncations, flipped bytes, absurd lengths, random bytes). Every outcome must be `Ok` or an
//! error naming the file; a panic fails the test with the mutation that caused it. The same
//! routine backs the `cargo fuzz` target in `fuzz/`.

mod common;

use std::path::{Path, PathBuf};

use vdbcook_testkit::XorShift;
use vdbcook_vdb::VdbFile;

/// Opens and fully reads every float grid; returns the error text if any.
fn exercise(path: &Path, bytes: Vec<u8>) -> Result<(), String> {
    let f = VdbFile::from_bytes(path, bytes).map_err(|e| e.to_string())?;
    for i in 0..f.grids.len() {
        if f.grids[i].is_float() {
            let g = f.read_float_grid(i).map_err(|e| e.to_string())?;
            let _ = g.stats();
        }
    }
    Ok(())
}

fn corpus() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(common::fixtures().join("vdb"))
        .map(|rd| {
            rd.flatten()
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "vdb"))
                .collect()
        })
        .unwrap_or_default();
    files.retain(|p| {
        std::fs::metadata(p)
            .map(|m| m.len() < 400_000)
            .unwrap_or(false)
    });
    files.sort();
    files
}

fn run_case(path: &Path, bytes: Vec<u8>, what: &str) {
    let r = std::panic::catch_unwind(|| exercise(path, bytes));
    match r {
        Err(_) => panic!("{}: the reader panicked on {what}", path.display()),
        Ok(Err(msg)) => assert!(
            msg.contains(&path.display().to_string()),
            "error does not name the file: {msg}"
        ),
        Ok(Ok(())) => {}
    }
}

#[test]
fn truncated_files_are_refused_cleanly() {
    let files = corpus();
    assert!(!files.is_empty(), "no fixtures found");
    for p in &files {
        let data = std::fs::read(p).unwrap();
        let n = data.len();
        let step = (n / 300).max(1);
        let mut cut = 0;
        while cut < n {
            let r = exercise(p, data[..cut].to_vec());
            assert!(
                r.is_err(),
                "{}: truncated to {cut} of {n} bytes was accepted",
                p.display()
            );
            cut += if cut < 256 { 1 } else { step };
        }
    }
}

#[test]
fn flipped_bytes_never_panic() {
    let mut rng = XorShift(0x5eed_1234_abcd_0001);
    for p in &corpus() {
        let data = std::fs::read(p).unwrap();
        // Every byte of the header region, then a seeded sample of the rest.
        let positions: Vec<usize> = (0..data.len().min(512))
            .chain((0..400).map(|_| rng.below(data.len())))
            .collect();
        for pos in positions {
            let mut d = data.clone();
            d[pos] ^= (rng.next_u64() as u8) | 1;
            run_case(p, d, &format!("a flipped byte at {pos}"));
        }
    }
}

#[test]
fn absurd_lengths_never_panic_or_allocate() {
    let mut rng = XorShift(42);
    for p in &corpus() {
        let data = std::fs::read(p).unwrap();
        for _ in 0..300 {
            let pos = rng.below(data.len().saturating_sub(8).max(1));
            let mut d = data.clone();
            let v: [u8; 8] = match rng.below(4) {
                0 => u64::MAX.to_le_bytes(),
                1 => (i64::MAX).to_le_bytes(),
                2 => [0xff, 0xff, 0xff, 0x7f, 0, 0, 0, 0],
                _ => (rng.next_u64() | 0x8000_0000).to_le_bytes(),
            };
            let len = if rng.below(2) == 0 { 4 } else { 8 };
            let end = (pos + len).min(d.len());
            d[pos..end].copy_from_slice(&v[..end - pos]);
            run_case(p, d, &format!("an absurd length at {pos}"));
        }
    }
}

#[test]
fn random_bytes_after_a_valid_prefix_never_panic() {
    let mut rng = XorShift(7);
    for p in corpus().iter().take(6) {
        let data = std::fs::read(p).unwrap();
        for _ in 0..60 {
            let keep = rng.below(data.len());
            let mut d = data[..keep].to_vec();
            let extra = rng.below(4096);
            d.extend((0..extra).map(|_| rng.next_u64() as u8));
            run_case(p, d, &format!("random bytes after {keep}"));
        }
    }
}

#[test]
fn non_vdb_inputs_are_refused_with_the_file_name() {
    let p = Path::new("not-a-volume.vdb");
    for bytes in [
        Vec::new(),
        b"hello world, this is text".to_vec(),
        vec![0u8; 100],
        (0..255u8).collect(),
    ] {
        let e = VdbFile::from_bytes(p, bytes).unwrap_err();
        assert_eq!(e.kind, vdbcook_vdb::ErrorKind::Corrupt);
        assert!(e.to_string().starts_with("not-a-volume.vdb: "), "{e}");
    }
    let e = VdbFile::open("/definitely/missing/file.vdb").unwrap_err();
    assert_eq!(e.kind, vdbcook_vdb::ErrorKind::Io);
    assert!(e.to_string().contains("/definitely/missing/file.vdb"));
}

#[test]
fn old_versions_are_refused_naming_the_version() {
    let p = corpus().into_iter().next().expect("a fixture");
    let mut d = std::fs::read(&p).unwrap();
    d[8..12].copy_from_slice(&219u32.to_le_bytes());
    let e = VdbFile::from_bytes(&p, d).unwrap_err();
    assert_eq!(e.kind, vdbcook_vdb::ErrorKind::Unsupported);
    assert!(e.to_string().contains("219"), "{e}");
}
