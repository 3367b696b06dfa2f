//! Decode-throughput benchmark for the blosc decoder.
//!
//! Why this file exists: the OpenVDB reader needs > 100 M floats/s overall and
//! lz4 + byte shuffle (typesize 4) should decode at >= 1 GB/s.  It measures:
//!
//! 1. one big c-blosc frame of 64 MiB of smooth floats (lz4, byte shuffle,
//!    typesize 4, clevel 9), and
//! 2. the same data as 2 KiB frames, one per OpenVDB float leaf (how .vdb files
//!    store values), decoded one by one into a reused buffer.
//!
//! Inputs come from `python3 fixtures/gen/gen_blosc.py --bench`
//! (`/tmp/blosc_bench.bin`, `/tmp/blosc_bench_leaves.bin`: u32 length + frame,
//! repeated).  When absent, equivalent frames are built here with lz4_flex
//! (layout as c-blosc writes it: 16-byte header, block starts, 4 split streams).
//!
//! Run: `cargo run --release -p vdbcook-blosc --example bench [BIG [LEAVES]]`

use std::time::Instant;
use vdbcook_blosc::{decompress_into, parse_header};

fn smooth_floats(n: usize) -> Vec<u8> {
    let step = 1.0f64 / 4096.0;
    let mut out = Vec::with_capacity(n * 4);
    for i in 0..n {
        let x = i as f64 * step;
        let v = (x.sin() * 100.0 + (0.37 * x).cos()) as f32;
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Builds an lz4 + byte-shuffle frame the way c-blosc lays it out.
fn build_frame(data: &[u8], blocksize: usize) -> Vec<u8> {
    let ts = 4usize;
    let nblocks = data.len().div_ceil(blocksize);
    let mut body = Vec::new();
    let mut starts = Vec::new();
    let base = 16 + 4 * nblocks;
    for block in data.chunks(blocksize) {
        starts.push((base + body.len()) as i32);
        let leftover = block.len() < blocksize;
        let n = block.len() / ts;
        let mut shuf = block.to_vec();
        for i in 0..n {
            for j in 0..ts {
                shuf[j * n + i] = block[i * ts + j];
            }
        }
        let nsplits = if !leftover && n >= 128 { ts } else { 1 };
        for stream in shuf.chunks(block.len() / nsplits) {
            let c = lz4_flex::block::compress(stream);
            let c: &[u8] = if c.len() >= stream.len() { stream } else { &c };
            body.extend_from_slice(&(c.len() as i32).to_le_bytes());
            body.extend_from_slice(c);
        }
    }
    let mut f = vec![2u8, 1, 0x21, ts as u8];
    f.extend_from_slice(&(data.len() as i32).to_le_bytes());
    f.extend_from_slice(&(blocksize as i32).to_le_bytes());
    f.extend_from_slice(&((base + body.len()) as i32).to_le_bytes());
    for s in starts {
        f.extend_from_slice(&s.to_le_bytes());
    }
    f.extend_from_slice(&body);
    f
}

fn report(what: &str, bytes: usize, secs: &[f64]) {
    let best = secs.iter().cloned().fold(f64::INFINITY, f64::min);
    let mean = secs.iter().sum::<f64>() / secs.len() as f64;
    let mb = bytes as f64 / 1e6;
    println!(
        "{what}: {:.1} MB decoded; best {:.0} MB/s ({:.0} M floats/s), mean {:.0} MB/s over {} runs",
        mb,
        mb / best,
        bytes as f64 / 4.0 / 1e6 / best,
        mb / mean,
        secs.len()
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let big_path = args
        .get(1)
        .map(String::as_str)
        .unwrap_or("/tmp/blosc_bench.bin");
    let leaves_path = args
        .get(2)
        .map(String::as_str)
        .unwrap_or("/tmp/blosc_bench_leaves.bin");

    let (big, leaves, origin) = match (std::fs::read(big_path), std::fs::read(leaves_path)) {
        (Ok(b), Ok(l)) => (b, l, "c-blosc (python-blosc)"),
        _ => {
            let data = smooth_floats(16 << 20);
            let big = build_frame(&data, 1 << 20);
            let mut leaves = Vec::new();
            for leaf in data.chunks(2048) {
                let f = build_frame(leaf, 2048);
                leaves.extend_from_slice(&(f.len() as u32).to_le_bytes());
                leaves.extend_from_slice(&f);
            }
            (
                big,
                leaves,
                "built in Rust with lz4_flex (gen_blosc.py --bench not run)",
            )
        }
    };
    println!("input frames: {origin}");

    // 1. One big frame.
    let h = parse_header(&big).expect("bench frame header");
    println!(
        "big frame: {} -> {} bytes, blocksize {}, typesize {}, codec {}, flags {:#04x}",
        h.cbytes, h.nbytes, h.blocksize, h.typesize, h.codec, h.flags
    );
    let mut out = vec![0u8; h.nbytes];
    let mut secs = Vec::new();
    for _ in 0..8 {
        let t = Instant::now();
        decompress_into(&big, &mut out).expect("decode");
        secs.push(t.elapsed().as_secs_f64());
    }
    report("lz4+shuffle ts4, one 64 MiB frame", h.nbytes, &secs);

    // 2. Many 2 KiB leaf frames.
    let mut frames = Vec::new();
    let mut pos = 0;
    while pos + 4 <= leaves.len() {
        let n = u32::from_le_bytes(leaves[pos..pos + 4].try_into().unwrap()) as usize;
        frames.push(&leaves[pos + 4..pos + 4 + n]);
        pos += 4 + n;
    }
    let mut buf = vec![0u8; 2048];
    let mut total = 0;
    let mut secs = Vec::new();
    for _ in 0..8 {
        total = 0;
        let t = Instant::now();
        for f in &frames {
            let h = parse_header(f).expect("leaf header");
            let dst = &mut buf[..h.nbytes];
            decompress_into(f, dst).expect("leaf decode");
            total += h.nbytes;
        }
        secs.push(t.elapsed().as_secs_f64());
    }
    report(
        &format!("lz4+shuffle ts4, {} leaf frames of 2 KiB", frames.len()),
        total,
        &secs,
    );
}
