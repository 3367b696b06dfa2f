//! Decodes every c-blosc test vector in `fixtures/blosc` and compares the
//! bytes with the original input (the truth is c-blosc 1.21 via python-blosc).

mod common;

use common::*;
use std::collections::BTreeMap;
use vdbcook_blosc::{decompress, decompress_into, parse_header, Codec};

fn codec_of(name: &str) -> Codec {
    match name {
        "blosclz" => Codec::BloscLz,
        "lz4" | "lz4hc" => Codec::Lz4,
        "snappy" => Codec::Snappy,
        "zlib" => Codec::Zlib,
        "zstd" => Codec::Zstd,
        other => panic!("unknown codec {other} in cases.tsv"),
    }
}

#[test]
fn every_vector_decodes_exactly() {
    let (cases, comments) = load_cases();
    assert!(
        cases.len() >= 800,
        "only {} cases in cases.tsv",
        cases.len()
    );
    let mut per_codec: BTreeMap<String, usize> = BTreeMap::new();
    let mut failures = Vec::new();
    for case in &cases {
        let src = frame(&case.name);
        let want = raw(&case.input);
        let h = parse_header(&src).unwrap_or_else(|e| panic!("{}: {e}", case.name));
        assert_eq!(h.nbytes, want.len(), "{}: nbytes", case.name);
        assert_eq!(h.cbytes, src.len(), "{}: cbytes", case.name);
        assert_eq!(h.codec, codec_of(&case.codec), "{}: codec", case.name);
        let expect_ts = if case.typesize > 255 {
            1
        } else {
            case.typesize
        };
        assert_eq!(h.typesize, expect_ts, "{}: typesize", case.name);

        match decompress(&src, want.len()) {
            Ok(got) if got == want => {}
            Ok(got) => {
                let first = got.iter().zip(&want).position(|(a, b)| a != b);
                failures.push(format!(
                    "{}: wrong bytes (first difference at {first:?})",
                    case.name
                ));
                continue;
            }
            Err(e) => {
                failures.push(format!("{}: {e}", case.name));
                continue;
            }
        }
        // Same through decompress_into, into a dirty buffer.
        let mut dst = vec![0xA5u8; want.len()];
        decompress_into(&src, &mut dst).unwrap();
        assert_eq!(dst, want, "{}: decompress_into", case.name);
        // Trailing bytes after cbytes are ignored.
        let mut padded = src.clone();
        padded.extend_from_slice(&[0xEE; 7]);
        assert_eq!(
            decompress(&padded, want.len()).unwrap(),
            want,
            "{}: padded",
            case.name
        );
        // The limit is enforced.
        if !want.is_empty() {
            assert!(
                decompress(&src, want.len() - 1).is_err(),
                "{}: max_len",
                case.name
            );
        }
        *per_codec.entry(case.codec.clone()).or_default() += 1;
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
    eprintln!("decoded {} vectors: {per_codec:?}", cases.len());
    for codec in ["blosclz", "lz4", "lz4hc", "zlib", "zstd"] {
        assert!(
            per_codec.get(codec).copied().unwrap_or(0) >= 100,
            "too few {codec} vectors"
        );
    }
    if !comments.contains("snappy: NOT covered") {
        assert!(
            per_codec.get("snappy").copied().unwrap_or(0) >= 100,
            "too few snappy vectors"
        );
    }
}

#[test]
fn vectors_cover_the_format_features() {
    let (cases, _) = load_cases();
    let mut memcpyed = 0;
    let mut multi_block_leftover = 0;
    let mut bitshuffle_leftover_bytes = 0;
    let mut split = 0;
    let mut always_quirk = 0;
    for case in &cases {
        let src = frame(&case.name);
        let h = parse_header(&src).unwrap();
        if h.memcpyed() {
            memcpyed += 1;
            continue;
        }
        if h.nblocks() > 1 && !h.nbytes.is_multiple_of(h.blocksize) {
            multi_block_leftover += 1;
        }
        if case.shuffle == "bitshuf" && !h.nbytes.is_multiple_of(h.typesize) {
            bitshuffle_leftover_bytes += 1;
        }
        if !h.dont_split() && h.typesize > 1 {
            split += 1;
        }
        if !case.cblosc_roundtrip {
            always_quirk += 1;
            assert_eq!(case.splitmode, "ALWAYS", "{}", case.name);
        }
    }
    assert!(memcpyed >= 50, "memcpyed {memcpyed}");
    assert!(
        multi_block_leftover >= 50,
        "multi-block {multi_block_leftover}"
    );
    assert!(
        bitshuffle_leftover_bytes >= 20,
        "bitshuffle leftovers {bitshuffle_leftover_bytes}"
    );
    assert!(split >= 50, "split {split}");
    assert!(
        always_quirk >= 1,
        "ALWAYS-split small-block frames {always_quirk}"
    );
}
