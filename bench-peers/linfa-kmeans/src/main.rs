//! Benchmark only (not part of the workspace, never built by CI): linfa-clustering 0.8.1's
//! k-means — the card's choice — beside vdbcook's own (`cooker/src/cluster.rs`, included as a
//! module) on the same synthetic bricks, same k and iterations, Manhattan distance, one run,
//! random initialisation (k-means++ costs ≈ k/2 passes: see ../shared/notes/dependencies.md).
//! Run: `cargo run --release --manifest-path bench-peers/linfa-kmeans/Cargo.toml -- N K ITER`.

#[path = "../../../cooker/src/cluster.rs"]
#[allow(dead_code)]
mod cluster;

use std::time::Instant;

use linfa::prelude::*;
use linfa_clustering::{KMeans, KMeansInit};
use linfa_nn::distance::Distance;
use ndarray::{Array2, ArrayView, Dimension};
use rand_xoshiro::rand_core::SeedableRng;
use rand_xoshiro::Xoshiro256Plus;
use rayon::prelude::*;

const BRICK: usize = 512;

/// Hand-written L1 through linfa's `Distance` trait (its built-in `L1Dist` does not vectorise).
#[derive(Clone, Copy)]
struct FastL1;

impl Distance<f32> for FastL1 {
    fn distance<D: Dimension>(&self, a: ArrayView<f32, D>, b: ArrayView<f32, D>) -> f32 {
        match (a.as_slice(), b.as_slice()) {
            (Some(x), Some(y)) => {
                let mut acc = [0f32; 16];
                for (cx, cy) in x.chunks_exact(16).zip(y.chunks_exact(16)) {
                    for i in 0..16 {
                        acc[i] += (cx[i] - cy[i]).abs();
                    }
                }
                acc.iter().sum()
            }
            _ => a.iter().zip(b.iter()).map(|(p, q)| (p - q).abs()).sum(),
        }
    }
}

fn bricks(n: usize) -> Vec<f32> {
    let mut pool = vec![0f32; n * BRICK];
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
    pool
}

fn main() {
    let a: Vec<usize> = std::env::args().skip(1).filter_map(|s| s.parse().ok()).collect();
    let (n, k, it) = (a.first().copied().unwrap_or(200_000), a.get(1).copied().unwrap_or(100), a.get(2).copied().unwrap_or(5));
    let pool = bricks(n);
    let t = Instant::now();
    let r = cluster::cluster(&pool, &cluster::ClusterOptions { clusters: k, iterations: it, variance_threshold: f32::INFINITY, seed: 1 });
    let ours = t.elapsed().as_secs_f64();
    println!("vdbcook: {n} bricks, k = {k}, {} iterations: {ours:.2} s", r.iterations_run);
    let data = Array2::from_shape_vec((n, BRICK), pool).unwrap();
    let ds = DatasetBase::from(data);
    let t = Instant::now();
    let model = KMeans::params_with(k, Xoshiro256Plus::seed_from_u64(1), FastL1)
        .init_method(KMeansInit::Random)
        .n_runs(1)
        .max_n_iterations(it as u64)
        .tolerance(1e-12)
        .fit(&ds)
        .expect("linfa k-means");
    let theirs = t.elapsed().as_secs_f64();
    println!("linfa-clustering 0.8.1 (hand-written L1, random init, 1 run): {theirs:.2} s ({} centroids)", model.centroids().nrows());
    println!("ratio linfa / vdbcook: {:.1}x", theirs / ours);
    println!("{{\"bench\":\"kmeans-peer\",\"n\":{n},\"k\":{k},\"iterations\":{it},\"vdbcook_s\":{ours:.3},\"linfa_s\":{theirs:.3}}}");
}
