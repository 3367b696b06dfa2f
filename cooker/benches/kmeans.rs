//! k-means speed: N candidate bricks (default 1 M, synthetic smooth densities with a few dozen
//! underlying shapes plus noise), k = 100, 5 iterations, the project's k-means (`cooker/src/cluster.rs`,
//! included here as a module) on all cores. Prints seconds and candidates·k·iterations per second.
//! Usage: `cargo bench -p vdbcook --bench kmeans -- [N] [K] [ITERATIONS]`.

#[path = "../src/cluster.rs"]
#[allow(dead_code)]
mod cluster;

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
    let ops = r.candidates as f64 * k as f64 * (r.iterations_run + 1) as f64;
    println!(
        "vdbcook k-means: {} candidates, k = {k}, {} iterations (+ final assignment) in {s:.2} s on {} threads = {:.2e} candidate·centroid distances/s ({:.2e} L1 terms/s)",
        r.candidates,
        r.iterations_run,
        rayon::current_num_threads(),
        ops / s,
        ops * BRICK as f64 / s
    );
    println!(
        "{{\"bench\":\"kmeans\",\"n\":{n},\"k\":{k},\"iterations\":{},\"seconds\":{s:.3}}}",
        r.iterations_run
    );
}
