//! Shared helpers for the blosc integration tests: loading the c-blosc test
//! vectors written by `fixtures/gen/gen_blosc.py` (`fixtures/blosc/cases.tsv`,
//! `cases/CASE.blosc`, `inputs/INPUT.raw`) and a small seeded PRNG.
#![allow(dead_code)]

use std::path::PathBuf;

pub fn fixtures_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/blosc")
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

/// xorshift64* — deterministic, dependency-free.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    pub fn byte(&mut self) -> u8 {
        (self.next() >> 56) as u8
    }
}
