//! Cluster stage (lossy, optional): k-means over the low-variance bricks of the deduplicated
//! pool, Manhattan (L1) distance as in the thesis, so near-identical bricks share one centroid
//! brick. Bricks whose normalized variance (variance / |mean|) exceeds the threshold keep their
//! own data. Deterministic: seeded initialisation, assignments per brick, and centroid sums
//! reduced in fixed-size chunks in a fixed order, so the result is the same at any thread count.
//!
//! The distance kernel is written for the compiler to vectorise (16 independent accumulators);
//! `docs/decisions.md` records why this is the project's own k-means rather than linfa's.

use rayon::prelude::*;
use vdbcook_asset::BRICK_VOXELS;

#[derive(Clone, Copy, Debug)]
pub struct ClusterOptions {
    pub clusters: usize,
    pub iterations: usize,
    pub variance_threshold: f32,
    pub seed: u64,
}

pub struct ClusterResult {
    /// Centroid values, `BRICK_VOXELS` each.
    pub centroids: Vec<f32>,
    /// For each pool brick: the centroid it joined, if any.
    pub member_of: Vec<Option<u32>>,
    pub candidates: usize,
    pub rejected_by_variance: usize,
    pub iterations_run: usize,
}

/// Bricks per chunk of the centroid reduction (fixed, so sums do not depend on threads).
const CHUNK: usize = 2048;

/// L1 distance between two bricks, 16 lanes at a time (the same lane structure as `nearest`).
#[cfg(test)]
pub fn l1(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0f32; 16];
    for (ca, cb) in a.chunks_exact(16).zip(b.chunks_exact(16)) {
        for i in 0..16 {
            acc[i] += (ca[i] - cb[i]).abs();
        }
    }
    acc.iter().sum()
}

/// Normalized variance of a brick: variance / |mean| (infinite for a zero mean with spread).
pub fn normalized_variance(v: &[f32]) -> f32 {
    let n = v.len() as f64;
    let mean = v.iter().map(|&x| x as f64).sum::<f64>() / n;
    let var = v.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / n;
    if var == 0.0 {
        0.0
    } else if mean == 0.0 {
        f32::INFINITY
    } else {
        (var / mean.abs()) as f32
    }
}

/// Index of the nearest centroid (lowest index on ties), starting from `hint` (the previous
/// assignment): with a tight best distance from the start, most other centroids are abandoned
/// after a few partial sums (terms are non-negative and the partial sums are computed in the
/// same order as the full one, so they never decrease: the result is exactly the full argmin).
/// Uses AVX-512 or AVX2 when the CPU has them; the lane structure is the same in every version,
/// so the sums — and the clusters — are bit-identical.
fn nearest(b: &[f32], centroids: &[f32], hint: u32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU supports AVX-512F (checked just above).
            return unsafe { nearest_avx512(b, centroids, hint) };
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { nearest_avx2(b, centroids, hint) };
        }
    }
    nearest_portable(b, centroids, hint)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn nearest_avx512(b: &[f32], centroids: &[f32], hint: u32) -> u32 {
    nearest_portable(b, centroids, hint)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn nearest_avx2(b: &[f32], centroids: &[f32], hint: u32) -> u32 {
    nearest_portable(b, centroids, hint)
}

/// L1 distance to one centroid, abandoned (returning a value ≥ `bound`) once it cannot win.
#[inline(always)]
fn partial_l1(b: &[f32], cv: &[f32], bound: f32, strict: bool) -> f32 {
    let mut acc = [0f32; 16];
    let mut done = 0f32;
    for (part_a, part_c) in b.chunks_exact(128).zip(cv.chunks_exact(128)) {
        for (ca, cb) in part_a.chunks_exact(16).zip(part_c.chunks_exact(16)) {
            for i in 0..16 {
                acc[i] += (ca[i] - cb[i]).abs();
            }
        }
        done = acc.iter().sum();
        if done > bound || (strict && done == bound) {
            return done;
        }
    }
    done
}

#[inline(always)]
fn nearest_portable(b: &[f32], centroids: &[f32], hint: u32) -> u32 {
    let k = centroids.len() / BRICK_VOXELS;
    let hint = (hint as usize).min(k - 1);
    let cent = |c: usize| &centroids[c * BRICK_VOXELS..(c + 1) * BRICK_VOXELS];
    let mut best = (partial_l1(b, cent(hint), f32::INFINITY, false), hint);
    for c in 0..k {
        if c == hint {
            continue;
        }
        // A centroid after the best one must beat it strictly; one before it may tie.
        let d = partial_l1(b, cent(c), best.0, c > best.1);
        if d < best.0 || (d == best.0 && c < best.1) {
            best = (d, c);
        }
    }
    best.1 as u32
}

/// A seeded xorshift64* generator (no dependency, reproducible everywhere).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
}

/// Runs k-means over the candidate bricks of `pool`.
pub fn cluster(pool: &[f32], o: &ClusterOptions) -> ClusterResult {
    let n = pool.len() / BRICK_VOXELS;
    let brick = |b: usize| &pool[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS];
    let nv: Vec<f32> = (0..n)
        .into_par_iter()
        .map(|b| normalized_variance(brick(b)))
        .collect();
    let cand: Vec<usize> = (0..n).filter(|&b| nv[b] <= o.variance_threshold).collect();
    let mut member_of = vec![None; n];
    let k = o.clusters.min(cand.len());
    if k == 0 {
        return ClusterResult {
            centroids: Vec::new(),
            member_of,
            candidates: cand.len(),
            rejected_by_variance: n - cand.len(),
            iterations_run: 0,
        };
    }
    // Initial centroids: k distinct candidates drawn with a seeded partial Fisher-Yates shuffle.
    let mut order = cand.clone();
    let mut rng = Rng(o.seed | 1);
    for i in 0..k {
        let j = i + (rng.next() % (order.len() - i) as u64) as usize;
        order.swap(i, j);
    }
    let mut centroids: Vec<f32> = order[..k]
        .iter()
        .flat_map(|&b| brick(b).iter().copied())
        .collect();
    let mut assign = vec![0u32; cand.len()];
    let mut iterations_run = 0;
    for _ in 0..o.iterations.max(1) {
        iterations_run += 1;
        let next: Vec<u32> = cand
            .par_iter()
            .zip(assign.par_iter())
            .map(|(&b, &h)| nearest(brick(b), &centroids, h))
            .collect();
        let changed = next != assign || iterations_run == 1;
        assign = next;
        // New centroids: the mean of their members, reduced in fixed chunks in order.
        let partial: Vec<(Vec<f64>, Vec<u32>)> = cand
            .par_chunks(CHUNK)
            .zip(assign.par_chunks(CHUNK))
            .map(|(bs, cs)| {
                let mut sum = vec![0f64; k * BRICK_VOXELS];
                let mut cnt = vec![0u32; k];
                for (&b, &c) in bs.iter().zip(cs) {
                    cnt[c as usize] += 1;
                    let s = &mut sum[c as usize * BRICK_VOXELS..(c as usize + 1) * BRICK_VOXELS];
                    for (a, &v) in s.iter_mut().zip(brick(b)) {
                        *a += v as f64;
                    }
                }
                (sum, cnt)
            })
            .collect();
        let mut sum = vec![0f64; k * BRICK_VOXELS];
        let mut cnt = vec![0u32; k];
        for (s, c) in &partial {
            for (a, b) in sum.iter_mut().zip(s) {
                *a += b;
            }
            for (a, b) in cnt.iter_mut().zip(c) {
                *a += b;
            }
        }
        for c in 0..k {
            // An empty cluster keeps its previous centroid.
            if cnt[c] > 0 {
                let inv = 1.0 / cnt[c] as f64;
                for (dst, s) in centroids[c * BRICK_VOXELS..(c + 1) * BRICK_VOXELS]
                    .iter_mut()
                    .zip(&sum[c * BRICK_VOXELS..(c + 1) * BRICK_VOXELS])
                {
                    *dst = (s * inv) as f32;
                }
            }
        }
        if !changed {
            break;
        }
    }
    // Final assignment to the final centroids.
    let fin: Vec<u32> = cand
        .par_iter()
        .zip(assign.par_iter())
        .map(|(&b, &h)| nearest(brick(b), &centroids, h))
        .collect();
    for (&b, &c) in cand.iter().zip(&fin) {
        member_of[b] = Some(c);
    }
    ClusterResult {
        centroids,
        member_of,
        candidates: cand.len(),
        rejected_by_variance: n - cand.len(),
        iterations_run,
    }
}

#[cfg(test)]
mod tests {
    //! Defined behaviour at the edges (no panic, no NaN) and determinism.
    use super::*;

    fn opts(k: usize) -> ClusterOptions {
        ClusterOptions {
            clusters: k,
            iterations: 5,
            variance_threshold: f32::INFINITY,
            seed: 7,
        }
    }

    fn bricks(n: usize, f: impl Fn(usize, usize) -> f32) -> Vec<f32> {
        (0..n * BRICK_VOXELS)
            .map(|i| f(i / BRICK_VOXELS, i % BRICK_VOXELS))
            .collect()
    }

    #[test]
    fn edge_cases_are_defined() {
        // No candidates.
        let r = cluster(&[], &opts(4));
        assert!(r.centroids.is_empty() && r.member_of.is_empty());
        // K larger than the candidates, a single candidate, all identical candidates.
        let one = bricks(1, |_, v| v as f32);
        let r = cluster(&one, &opts(10));
        assert_eq!(r.centroids, one);
        assert_eq!(r.member_of, vec![Some(0)]);
        let same = bricks(5, |_, v| (v % 7) as f32);
        let r = cluster(&same, &opts(3));
        assert_eq!(r.centroids.len(), 3 * BRICK_VOXELS);
        assert!(r.centroids.iter().all(|x| x.is_finite()));
        assert!(r.member_of.iter().all(|m| m.is_some()));
        // Zero-mean bricks: infinite normalized variance, never candidates below a finite T.
        let zm = bricks(3, |b, v| {
            if v % 2 == 0 {
                1.0 + b as f32
            } else {
                -1.0 - b as f32
            }
        });
        let r = cluster(
            &zm,
            &ClusterOptions {
                variance_threshold: 1e6,
                ..opts(2)
            },
        );
        assert_eq!(r.candidates, 0);
        assert_eq!(r.rejected_by_variance, 3);
        assert_eq!(normalized_variance(&[0.0; 512]), 0.0);
    }

    #[test]
    fn empty_clusters_keep_their_centroid_and_everything_stays_finite() {
        // Two tight groups and k = 5: some clusters end up empty.
        let data = bricks(40, |b, v| {
            if b < 20 {
                1.0 + 1e-3 * v as f32
            } else {
                5.0 + 1e-3 * v as f32
            }
        });
        let r = cluster(&data, &opts(5));
        assert!(r.centroids.iter().all(|x| x.is_finite()));
        for b in 0..40 {
            let c = r.member_of[b].unwrap() as usize;
            let cv = &r.centroids[c * BRICK_VOXELS..(c + 1) * BRICK_VOXELS];
            let want = if b < 20 { 1.0 } else { 5.0 };
            assert!(
                (cv[0] - want).abs() < 0.1,
                "brick {b} joined centroid starting at {}",
                cv[0]
            );
        }
    }

    #[test]
    fn same_clusters_at_any_thread_count() {
        let data = bricks(3000, |b, v| {
            ((b * 31 + v * 7) % 97) as f32 / 97.0 + (b % 5) as f32
        });
        let run = |t: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .unwrap()
                .install(|| cluster(&data, &opts(16)))
        };
        let (a, b) = (run(1), run(2));
        assert_eq!(a.member_of, b.member_of);
        assert_eq!(
            a.centroids.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            b.centroids.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }

    #[test]
    fn pruned_search_from_any_hint_is_the_exact_argmin() {
        // Includes exact ties (duplicate centroids), where the lowest index must win.
        let cents = bricks(12, |c, v| ((c % 6) * 3 + v % 5) as f32 * 0.25);
        let data = bricks(60, |b, v| ((b * 13 + v * 3) % 23) as f32 * 0.2);
        for b in 0..60 {
            let x = &data[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS];
            let full = (0..12)
                .map(|c| (l1(x, &cents[c * BRICK_VOXELS..(c + 1) * BRICK_VOXELS]), c))
                .fold((f32::INFINITY, 0), |m, d| if d.0 < m.0 { d } else { m });
            for h in 0..12 {
                assert_eq!(nearest(x, &cents, h) as usize, full.1, "brick {b} hint {h}");
                assert_eq!(nearest_portable(x, &cents, h) as usize, full.1);
            }
        }
    }

    #[test]
    fn l1_matches_the_plain_sum() {
        let a: Vec<f32> = (0..512).map(|i| (i as f32 * 0.37).sin()).collect();
        let b: Vec<f32> = (0..512).map(|i| (i as f32 * 0.11).cos()).collect();
        let plain: f64 = a.iter().zip(&b).map(|(x, y)| (x - y).abs() as f64).sum();
        assert!((l1(&a, &b) as f64 - plain).abs() < 1e-3);
    }
}
