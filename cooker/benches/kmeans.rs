//! k-means speed: N candidate bricks (default 1 M, synthetic smooth densities with a few dozen
//! underlying shapes plus noise), k = 100, 5 iterations, the project's k-means
//! (`vdbcook::cluster`) on all cores. Times `cluster()` only (not the data generation) and prints
//! seconds, candidates·k·iterations per second (the rate), the same counting the
//! final assignment pass too, and a fingerprint of the result (FNV-1a over the assignments and
//! the centroids' bits) to check that a change keeps the clusters bit-identical.
//! Usage: `cargo bench -p vdbcook --bench kmeans -- [N] [K] [ITERATIONS]`.

use vdbcook::cluster;

use std::time::Instant;

const BRICK: usize = 512;

fn main() {
    let a: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|s| s.parse().ok())
        .collect();
    let (n, k, it) = (
        a.first().copied().unwrap_or(1_000_000),
        a.get(1).copied().unwrap_or(100),
        a.get(2).copied().unwrap_or(5),
    );
    let t = Instant::now();
    let mut pool = vec![0f32; n * BRICK];
    use rayon::prelude::*;
    pool.par_chunks_mut(BRICK).enumerate().for_each(|(b, v)| {
        let shape = (b * 2654435761) % 37;
        let mut s = (b as u64).wrapping_mul(0x9E3779B97F4A7C15) | 1;
        for (i, x) in v.iter_mut().enumerate() {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let noise = (s % 1000) as f32 / 1000.0 * 0.05;
            *x = 0.2 + 0.5 * (((i / 64) as f32 * 0.3 + shape as f32).sin() * 0.5 + 0.5) + noise;
        }
    });
    println!("generated {n} bricks in {:.1} s", t.elapsed().as_secs_f64());
    let o = cluster::ClusterOptions {
        clusters: k,
        iterations: it,
        variance_threshold: f32::INFINITY,
        seed: 1,
    };
    let t = Instant::now();
    let r = cluster::cluster(&pool, &o);
    let s = t.elapsed().as_secs_f64();
    let per_iter = r.candidates as f64 * k as f64;
    let ops = per_iter * (r.iterations_run + 1) as f64;
    println!(
        "vdbcook k-means: {} candidates, k = {k}, {} iterations (+ final assignment) in {s:.3} s on {} threads = {:.2e} candidate·centroid·iteration/s ({:.2e}/s counting the final assignment; {:.2e} L1 terms/s nominal)",
        r.candidates,
        r.iterations_run,
        rayon::current_num_threads(),
        per_iter * r.iterations_run as f64 / s,
        ops / s,
        ops * BRICK as f64 / s
    );
    // FNV-1a over the assignments and the centroids' bits.
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let words = r
        .member_of
        .iter()
        .map(|m| m.map_or(u32::MAX, |c| c))
        .chain(r.centroids.iter().map(|x| x.to_bits()));
    for w in words {
        for byte in w.to_le_bytes() {
            h = (h ^ byte as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    println!("result fingerprint {h:016x}");
    println!(
        "{{\"bench\":\"kmeans\",\"n\":{n},\"k\":{k},\"iterations\":{},\"seconds\":{s:.3}}}",
        r.iterations_run
    );
}
