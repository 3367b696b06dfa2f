//! Seeded corruption tests: the decoder must never panic, and must never
//! return output of a size other than the header's `nbytes`, whatever the input
//! (flipped bytes, truncation, garbage, absurd header fields).

mod common;

use common::*;
use vdbcook_blosc::{decompress, decompress_into, parse_header, BloscError, HEADER_LEN};
use vdbcook_testkit::XorShift;

const MAX_LEN: usize = 1 << 20;

/// Decodes `src` both ways; checks the only acceptable outcomes.
fn check(src: &[u8]) -> bool {
    let res = decompress(src, MAX_LEN);
    if let Ok(out) = &res {
        let h = parse_header(src).expect("Ok output without a valid header");
        assert_eq!(
            out.len(),
            h.nbytes,
            "output size differs from the header's nbytes"
        );
        assert!(h.nbytes <= MAX_LEN);
    }
    if let Ok(h) = parse_header(src) {
        if h.nbytes <= MAX_LEN {
            let mut dst = vec![0u8; h.nbytes];
            assert_eq!(decompress_into(src, &mut dst).is_ok(), res.is_ok());
        }
    }
    if let Err(e) = &res {
        assert!(!e.to_string().is_empty());
    }
    res.is_ok()
}

/// Small vectors that between them reach every codec, shuffle and block layout.
const VICTIMS: &[&str] = &[
    "lz4-byteshuf-ts4-vdbleaf",
    "lz4hc-bitshuf-ts4-vdbleaf",
    "blosclz-byteshuf-ts4-smooth",
    "blosclz-noshuf-ts1-min128",
    "blosclz-noshuf-ts1-far",
    "zlib-bitshuf-ts2-odd",
    "zstd-byteshuf-ts8-smooth",
    "snappy-byteshuf-ts4-smooth",
    "lz4-bitshuf-ts8-quant-bs2k-nosplit",
    "blosclz-byteshuf-ts8-min128-splitALWAYS",
    "lz4-noshuf-ts1-random",
    "zstd-noshuf-ts4-empty",
];

fn victims() -> Vec<(String, Vec<u8>)> {
    let (cases, _) = load_cases();
    VICTIMS
        .iter()
        .filter(|v| cases.iter().any(|c| c.name == **v))
        .map(|v| (v.to_string(), frame(v)))
        .collect()
}

#[test]
fn victims_decode_before_corruption() {
    let v = victims();
    assert!(v.len() >= VICTIMS.len() - 1, "victim vectors missing");
    for (name, src) in &v {
        assert!(check(src), "{name} should decode");
    }
}

#[test]
fn flip_every_byte() {
    for (_name, src) in victims() {
        for i in 0..src.len() {
            for mask in [0x01u8, 0x10, 0x80, 0xFF] {
                let mut m = src.clone();
                m[i] ^= mask;
                check(&m);
            }
        }
    }
}

#[test]
fn set_every_byte_to_extremes() {
    for (_name, src) in victims() {
        for i in 0..src.len().min(64) {
            for v in [0u8, 1, 0x7F, 0x80, 0xFE, 0xFF] {
                let mut m = src.clone();
                m[i] = v;
                check(&m);
            }
        }
    }
}

#[test]
fn truncate_at_every_length() {
    for (name, src) in victims() {
        for len in 0..src.len() {
            // As is: cbytes now exceeds the buffer.
            let t = &src[..len];
            assert!(!check(t), "{name} truncated to {len} decoded");
            // With cbytes patched to the new length, so decoding goes deeper.
            if len >= HEADER_LEN {
                let mut p = t.to_vec();
                p[12..16].copy_from_slice(&(len as i32).to_le_bytes());
                check(&p);
            }
        }
    }
}

#[test]
fn random_multi_byte_mutations() {
    let mut rng = XorShift(0x9E37_79B9_7F4A_7C15);
    for (_name, src) in victims() {
        for _ in 0..3000 {
            let mut m = src.clone();
            let flips = 1 + rng.below(8);
            for _ in 0..flips {
                let i = rng.below(m.len());
                m[i] = rng.byte();
            }
            check(&m);
        }
    }
}

#[test]
fn random_garbage_with_plausible_headers() {
    let mut rng = XorShift(42);
    let mut oks = 0;
    for iter in 0..200_000 {
        let len = rng.below(300);
        let mut m: Vec<u8> = (0..len).map(|_| rng.byte()).collect();
        if len >= HEADER_LEN && iter % 4 != 0 {
            m[0] = 2;
            m[1] = 1;
            m[2] &= !0x08;
            m[2] = (m[2] & 0x1F) | ((rng.below(5) as u8) << 5);
            m[3] = [1u8, 2, 4, 8, 3, 17][rng.below(6)];
            let nbytes = rng.below(2000) as i32;
            m[4..8].copy_from_slice(&nbytes.to_le_bytes());
            let bs = 1 + rng.below(nbytes.max(1) as usize) as i32;
            m[8..12].copy_from_slice(&bs.to_le_bytes());
            m[12..16].copy_from_slice(&(len as i32).to_le_bytes());
            // Block starts that mostly land inside the frame.
            let nblocks = (nbytes as usize).div_ceil(bs as usize);
            for j in 0..nblocks {
                let at = HEADER_LEN + 4 * j;
                if at + 4 <= len && iter % 3 != 0 {
                    let start = (HEADER_LEN + 4 * nblocks + rng.below(8)) as i32;
                    m[at..at + 4].copy_from_slice(&start.to_le_bytes());
                }
            }
        }
        if check(&m) {
            oks += 1;
        }
    }
    eprintln!("{oks} garbage frames decoded (sizes respected)");
}

fn header(flags: u8, ts: u8, nbytes: i32, blocksize: i32, cbytes: i32) -> Vec<u8> {
    let mut h = vec![2u8, 1, flags, ts];
    h.extend_from_slice(&nbytes.to_le_bytes());
    h.extend_from_slice(&blocksize.to_le_bytes());
    h.extend_from_slice(&cbytes.to_le_bytes());
    h
}

#[test]
fn absurd_sizes_are_refused_before_allocating() {
    // 2 GiB claimed, tiny limit: refused by the limit, nothing allocated.
    let h = header(0x20, 4, i32::MAX - 16, 1 << 20, 16);
    assert!(matches!(
        decompress(&h, MAX_LEN),
        Err(BloscError::TooLarge { .. })
    ));
    // Negative nbytes / blocksize / cbytes.
    assert!(matches!(
        parse_header(&header(0x20, 4, -1, 16, 32)),
        Err(BloscError::BadNbytes { .. })
    ));
    assert!(matches!(
        parse_header(&header(0x20, 4, 64, -4, 32)),
        Err(BloscError::BadBlocksize { .. })
    ));
    assert!(matches!(
        parse_header(&header(0x20, 4, 64, 128, 32)),
        Err(BloscError::BadBlocksize { .. })
    ));
    assert!(matches!(
        parse_header(&header(0x20, 4, 64, 16, 3)),
        Err(BloscError::BadCbytes { .. })
    ));
    // cbytes past the buffer.
    let mut f = header(0x20, 4, 64, 64, 1000);
    f.extend_from_slice(&[0; 40]);
    assert!(matches!(
        decompress(&f, MAX_LEN),
        Err(BloscError::FrameTruncated { .. })
    ));
    // Too many blocks for the bstarts table (1-byte blocks).
    let f = header(0x20, 1, 1 << 20, 1, 64);
    let mut f2 = f.clone();
    f2.resize(64, 0);
    assert!(matches!(
        decompress(&f2, 2 << 20),
        Err(BloscError::BstartsTruncated { .. })
    ));
    // Wrong destination size.
    let mut dst = [0u8; 10];
    let mut m = header(0x02, 1, 11, 11, 27);
    m.resize(27, 7);
    assert!(matches!(
        decompress_into(&m, &mut dst),
        Err(BloscError::OutputSizeMismatch { .. })
    ));
    let mut dst = [0u8; 11];
    decompress_into(&m, &mut dst).unwrap();
    assert_eq!(dst, [7u8; 11]);
    // Memcpyed with the wrong cbytes.
    let mut m = header(0x02, 1, 11, 11, 26);
    m.resize(30, 7);
    assert!(matches!(
        decompress(&m, 64),
        Err(BloscError::MemcpyedSizeMismatch { .. })
    ));
    // Header checks.
    assert!(matches!(
        parse_header(&[2; 15]),
        Err(BloscError::HeaderTruncated { len: 15 })
    ));
    let mut v = header(0x20, 4, 64, 64, 32);
    v[0] = 3;
    assert!(matches!(
        parse_header(&v),
        Err(BloscError::UnsupportedVersion { version: 3 })
    ));
    assert!(matches!(
        parse_header(&header(0x28, 4, 64, 64, 32)),
        Err(BloscError::ReservedFlag { .. })
    ));
    assert!(matches!(
        parse_header(&header(0xA0, 4, 64, 64, 32)),
        Err(BloscError::UnknownCodec { code: 5 })
    ));
    assert!(matches!(
        parse_header(&header(0x20, 0, 64, 64, 32)),
        Err(BloscError::ZeroTypesize)
    ));
}

#[test]
fn bad_block_starts_and_stream_sizes() {
    // One 256-byte block, lz4, no split, no shuffle.
    let base = |start: i32, csize: i32| {
        let mut f = header(0x30, 1, 256, 256, 0);
        f.extend_from_slice(&start.to_le_bytes());
        f.extend_from_slice(&csize.to_le_bytes());
        f.extend_from_slice(&[0u8; 20]);
        let n = f.len() as i32;
        f[12..16].copy_from_slice(&n.to_le_bytes());
        f
    };
    for (start, csize) in [
        (-1, 4),
        (1 << 30, 4),
        (40, 4),
        (30, 4),
        (20, -5),
        (20, 21),
        (20, i32::MAX),
        (20, 0),
    ] {
        let e = decompress(&base(start, csize), MAX_LEN).unwrap_err();
        assert!(!e.to_string().is_empty());
    }
    // A raw stream (csize == neblock) that would run past the frame.
    let e = decompress(&base(20, 256), MAX_LEN).unwrap_err();
    assert!(matches!(e, BloscError::StreamOutOfBounds { .. }), "{e}");
}

#[test]
fn blosclz_match_before_output_start() {
    // blosclz frame, one 64-byte block: literal "a", then a match 9 bytes back.
    let mut body = vec![0u8, b'a', 2 << 5, 8, 0, b'z'];
    body.resize(body.len(), 0);
    let mut f = header(0x10, 1, 64, 64, 0);
    f.extend_from_slice(&20i32.to_le_bytes());
    f.extend_from_slice(&(body.len() as i32).to_le_bytes());
    f.extend_from_slice(&body);
    let n = f.len() as i32;
    f[12..16].copy_from_slice(&n.to_le_bytes());
    let e = decompress(&f, MAX_LEN).unwrap_err();
    assert!(e.to_string().contains("before the block start"), "{e}");
}

#[test]
fn mutate_every_vector() {
    let (cases, _) = load_cases();
    let mut rng = XorShift(7);
    for case in &cases {
        let src = frame(&case.name);
        for _ in 0..20 {
            let mut m = src.clone();
            let i = rng.below(m.len());
            m[i] ^= 1 << rng.below(8);
            check(&m);
        }
    }
}
