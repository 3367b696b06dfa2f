//! Shared helpers for the blosc integration tests: loading the c-blosc test
//! vectors written by `fixtures/gen/gen_blosc.py` (`fixtures/blosc/cases.tsv`,
//! `cases/CASE.blosc`, `inputs/INPUT.raw`); the seeded PRNG is the test kit's.
#![allow(dead_code)]

use std::path::PathBuf;

pub fn fixtures_dir() -> PathBuf {
    vdbcook_testkit::fixtures().join("blosc")
}

pub struct Case {
    pub name: String,
    pub input: String,
    pub codec: String,
    pub shuffle: String,
    pub typesize: usize,
    pub splitmode: String,
    /// Whether c-blosc itself decodes this frame.
    pub cblosc_roundtrip: bool,
}

pub fn load_cases() -> (Vec<Case>, String) {
    let dir = fixtures_dir();
    let tsv = std::fs::read_to_string(dir.join("cases.tsv")).expect("fixtures/blosc/cases.tsv");
    let mut comments = String::new();
    let mut cases = Vec::new();
    for line in tsv.lines() {
        if let Some(c) = line.strip_prefix('#') {
            comments.push_str(c);
            comments.push('\n');
            continue;
        }
        let f: Vec<&str> = line.split('\t').collect();
        assert_eq!(f.len(), 9, "bad cases.tsv line: {line}");
        cases.push(Case {
            name: f[0].to_string(),
            input: f[1].to_string(),
            codec: f[2].to_string(),
            shuffle: f[3].to_string(),
            typesize: f[4].parse().unwrap(),
            splitmode: f[7].to_string(),
            cblosc_roundtrip: f[8] == "yes",
        });
    }
    (cases, comments)
}

pub fn frame(name: &str) -> Vec<u8> {
    std::fs::read(fixtures_dir().join("cases").join(format!("{name}.blosc")))
        .unwrap_or_else(|e| panic!("case {name}: {e}"))
}

pub fn raw(input: &str) -> Vec<u8> {
    std::fs::read(fixtures_dir().join("inputs").join(format!("{input}.raw")))
        .unwrap_or_else(|e| panic!("input {input}: {e}"))
}
