//! BC4 / BC7 encoder throughput and quality (the cook's BC4 fit beside Intel's BC4, and every BC7
//! effort, to choose the default): encode a
//! smooth density-like surface (waves + gradients + a little noise, RGBA = 4 consecutive z-slices
//! as the asset packs bricks) with each encoder and quality, then decode it with the asset crate's
//! decoder and report MPix/s with the mean / max absolute error (in 8-bit units).
//!
//! Usage: `cargo bench -p vdbcook --bench bc -- [SIZE] [SECONDS]` (default 2048 and 6). Slow
//! qualities are timed on the top rows of the surface only, sized from a quick probe so that each
//! row of the table takes about SECONDS; the table says how many rows were used.

use std::time::Instant;

use rayon::prelude::*;
use vdbcook::bcenc::{encode_bc4_intel, encode_bc7, Bc7Quality};
use vdbcook_asset::bc::{decode_bc4_block, decode_bc7_block};

/// Smooth density in [0, 1]: low-frequency waves and a diagonal gradient.
fn density(x: f64, y: f64, z: f64, size: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let s = 0.15
        + 0.35 * (x + y) / (2.0 * size)
        + 0.2 * (tau * (x / 211.0 + 0.1)).sin() * (tau * (y / 157.0)).cos()
        + 0.12 * (tau * (z / 53.0 + y / 373.0)).sin()
        + 0.06 * (tau * (x / 31.0 - z / 37.0 + y / 47.0)).cos();
    s.clamp(0.0, 1.0)
}

/// Hash-based noise in [-1, 1], so every texel is independent and the surface reproducible.
fn noise(x: usize, y: usize, z: usize) -> f64 {
    let mut h = (x as u64) << 42 ^ (y as u64) << 21 ^ z as u64 ^ 0x9E37_79B9_7F4A_7C15;
    h ^= h >> 33;
    h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    h ^= h >> 33;
    h = h.wrapping_mul(0xC4CE_B9FE_1A85_EC53);
    h ^= h >> 33;
    (h >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// RGBA8 surface: channel z = slice z of the density, plus ±2 units of noise.
fn make_rgba(size: usize) -> Vec<u8> {
    let mut v = vec![0u8; 4 * size * size];
    v.par_chunks_mut(4 * size).enumerate().for_each(|(y, row)| {
        for x in 0..size {
            for z in 0..4 {
                let d = density(x as f64, y as f64, z as f64, size as f64) * 255.0
                    + 2.0 * noise(x, y, z);
                row[4 * x + z] = d.round().clamp(0.0, 255.0) as u8;
            }
        }
    });
    v
}

fn decode_bc4(width: usize, height: usize, blocks: &[u8]) -> Vec<u8> {
    let bx = width / 4;
    let mut out = vec![0u8; width * height];
    out.par_chunks_mut(4 * width)
        .enumerate()
        .for_each(|(by, rows)| {
            for x in 0..bx {
                let at = (by * bx + x) * 8;
                let texels = decode_bc4_block(blocks[at..at + 8].try_into().unwrap());
                for (t, &v) in texels.iter().enumerate() {
                    rows[(t / 4) * width + 4 * x + t % 4] = v;
                }
            }
        });
    out
}

fn decode_bc7(width: usize, height: usize, blocks: &[u8]) -> Vec<u8> {
    let bx = width / 4;
    let mut out = vec![0u8; 4 * width * height];
    out.par_chunks_mut(16 * width)
        .enumerate()
        .for_each(|(by, rows)| {
            for x in 0..bx {
                let at = (by * bx + x) * 16;
                let texels = decode_bc7_block(blocks[at..at + 16].try_into().unwrap());
                for (t, rgba) in texels.iter().enumerate() {
                    let p = 4 * ((t / 4) * width + 4 * x + t % 4);
                    rows[p..p + 4].copy_from_slice(rgba);
                }
            }
        });
    out
}

/// (mean, max) absolute difference.
fn errors(a: &[u8], b: &[u8]) -> (f64, u8) {
    let (sum, max) = a
        .par_iter()
        .zip(b)
        .map(|(x, y)| {
            let d = x.abs_diff(*y);
            (u64::from(d), d)
        })
        .reduce(|| (0, 0), |p, q| (p.0 + q.0, p.1.max(q.1)));
    (sum as f64 / a.len() as f64, max)
}

/// Runs `f` until at least `min_secs` have passed (and at least once); seconds per run.
fn time_per_run(min_secs: f64, mut f: impl FnMut()) -> f64 {
    let start = Instant::now();
    let mut runs = 0u32;
    loop {
        f();
        runs += 1;
        let t = start.elapsed().as_secs_f64();
        if t >= min_secs {
            return t / f64::from(runs);
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let size: usize = args.first().map_or(2048, |s| s.parse().expect("SIZE"));
    let budget: f64 = args.get(1).map_or(6.0, |s| s.parse().expect("SECONDS"));
    assert!(
        size >= 64 && size.is_multiple_of(4),
        "SIZE must be a multiple of 4, >= 64"
    );

    let rgba = make_rgba(size);
    let r8: Vec<u8> = rgba.chunks_exact(4).map(|p| p[0]).collect();
    println!(
        "BC encode, {size}x{size} smooth density surface, {} rayon threads",
        rayon::current_num_threads()
    );
    println!(
        "{:<6} {:<11} {:>11} {:>9} {:>10} {:>9}",
        "format", "quality", "rows", "MPix/s", "mean err", "max err"
    );

    // BC4: the whole surface, repeated for about a second.
    let mut blocks = Vec::new();
    let secs = time_per_run(1.0, || {
        blocks = encode_bc4_intel(size as u32, size as u32, &r8)
    });
    let (mean, max) = errors(&r8, &decode_bc4(size, size, &blocks));
    println!(
        "{:<6} {:<11} {:>11} {:>9.1} {:>10.3} {:>9}",
        "BC4",
        "intel",
        size,
        (size * size) as f64 / secs / 1e6,
        mean,
        max
    );

    // BC4 as the cook encodes it (exact palettes fitted to the worst texel as any GPU reads
    // it), on the same surface, block rows in parallel.
    let fit = |r8: &[u8]| -> Vec<u8> {
        let bw = size / 4;
        let mut out = vec![0u8; bw * bw * 8];
        out.par_chunks_mut(bw * 8)
            .enumerate()
            .for_each(|(by, row)| {
                for (bx, dst) in row.chunks_exact_mut(8).enumerate() {
                    let codes: [f32; 16] = std::array::from_fn(|t| {
                        r8[(4 * by + t / 4) * size + 4 * bx + t % 4] as f32
                    });
                    dst.copy_from_slice(&vdbcook::bc4fit::fit_block(&codes));
                }
            });
        out
    };
    let secs = time_per_run(1.0, || blocks = fit(&r8));
    let (mean, max) = errors(&r8, &decode_bc4(size, size, &blocks));
    println!(
        "{:<6} {:<11} {:>11} {:>9.1} {:>10.3} {:>9}",
        "BC4",
        "fit (cook)",
        size,
        (size * size) as f64 / secs / 1e6,
        mean,
        max
    );

    for q in Bc7Quality::ALL {
        // Probe on 16 rows to size the measured part to the time budget.
        let probe_rows = 16;
        let probe = &rgba[..4 * size * probe_rows];
        let t = Instant::now();
        encode_bc7(size as u32, probe_rows as u32, probe, q);
        let rate = (size * probe_rows) as f64 / t.elapsed().as_secs_f64();
        let rows = ((rate * budget / size as f64) as usize / 4 * 4).clamp(probe_rows, size);
        let part = &rgba[..4 * size * rows];

        let mut blocks = Vec::new();
        let secs = time_per_run(budget.min(1.0), || {
            blocks = encode_bc7(size as u32, rows as u32, part, q)
        });
        let (mean, max) = errors(part, &decode_bc7(size, rows, &blocks));
        println!(
            "{:<6} {:<11} {:>11} {:>9.2} {:>10.3} {:>9}",
            "BC7",
            q.name(),
            rows,
            (size * rows) as f64 / secs / 1e6,
            mean,
            max
        );
    }
}
