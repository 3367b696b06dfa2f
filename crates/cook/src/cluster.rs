//! Cluster stage (lossy, optional): k-means over the low-variance bricks of the deduplicated
//! pool (per channel group, [`cluster_groups`]; then guarded by the budget, [`Grouped::guard`]), Manhattan (L1) distance as in the thesis, so near-identical bricks share one centroid
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

/// Voxels per step of the pruned search: the partial sum is checked against the bound after each.
const BLOCK: usize = 128;
/// Accumulator lanes of the distance kernel (the lane structure every version shares).
const LANES: usize = 16;
/// Centroids scored together in the batched first block (one vector of centroids per lane).
const GROUP: usize = 16;

/// The centroids in the two layouts the search reads: brick-major (`rows`, `BRICK_VOXELS` per
/// centroid) and the first `BLOCK` voxels transposed per group of `GROUP` centroids
/// (`head[group * BLOCK + v][i]` is voxel `v` of centroid `group * GROUP + i`, the last group
/// padded with zeros), so the first block can be scored for `GROUP` centroids at once with the
/// exact per-centroid arithmetic of [`finish_l1`].
struct Centroids<'a> {
    rows: &'a [f32],
    k: usize,
    head: Vec<[f32; GROUP]>,
}

impl<'a> Centroids<'a> {
    fn new(rows: &'a [f32]) -> Self {
        let k = rows.len() / BRICK_VOXELS;
        let mut head = vec![[0f32; GROUP]; k.div_ceil(GROUP) * BLOCK];
        for c in 0..k {
            for v in 0..BLOCK {
                head[c / GROUP * BLOCK + v][c % GROUP] = rows[c * BRICK_VOXELS + v];
            }
        }
        Centroids { rows, k, head }
    }

    fn row(&self, c: usize) -> &[f32] {
        &self.rows[c * BRICK_VOXELS..(c + 1) * BRICK_VOXELS]
    }
}

/// Per-thread scratch of [`nearest`]: after the first block, each centroid's 16 lane sums
/// (`lanes[group * LANES + j][i]`: lane `j` of centroid `group * GROUP + i`) and their total
/// (`first[c]`), exactly as [`finish_l1`] has them at its first check.
#[derive(Default)]
struct Scratch {
    lanes: Vec<[f32; GROUP]>,
    first: Vec<f32>,
}

/// Index of the nearest centroid (lowest index on ties), starting from `hint` (the previous
/// assignment; `None`: the centroid with the lowest first-block sum): with a tight best distance
/// from the start, most other centroids are abandoned after a few partial sums (terms are
/// non-negative and the partial sums are computed in the same order as the full one, so they
/// never decrease: the result is exactly the full argmin).
///
/// The first block of every centroid is scored up front, `GROUP` centroids at a time (vectorised
/// across centroids, so the additions are independent instead of one latency-bound chain per
/// centroid); each centroid's lanes and total are bit-identical to [`partial_l1`]'s first check,
/// and the scan then takes exactly the decisions the one-centroid-at-a-time search takes,
/// continuing the survivors from their saved lanes. Uses AVX-512 or AVX2 when the CPU has them;
/// the arithmetic is the same in every version, so the sums — and the clusters — are
/// bit-identical.
fn nearest(b: &[f32], cents: &Centroids, hint: Option<u32>, scratch: &mut Scratch) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU supports AVX-512F (checked just above).
            return unsafe { nearest_avx512(b, cents, hint, scratch) };
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { nearest_avx2(b, cents, hint, scratch) };
        }
    }
    nearest_portable(b, cents, hint, scratch)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn nearest_avx512(
    b: &[f32],
    cents: &Centroids,
    hint: Option<u32>,
    scratch: &mut Scratch,
) -> u32 {
    nearest_portable(b, cents, hint, scratch)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn nearest_avx2(
    b: &[f32],
    cents: &Centroids,
    hint: Option<u32>,
    scratch: &mut Scratch,
) -> u32 {
    nearest_portable(b, cents, hint, scratch)
}

/// L1 distance to one centroid, abandoned (returning a value ≥ `bound`) once it cannot win.
/// The reference for the search's arithmetic (the search itself starts from [`first_blocks`]).
#[cfg(test)]
#[inline(always)]
fn partial_l1(b: &[f32], cv: &[f32], bound: f32, strict: bool) -> f32 {
    finish_l1(b, cv, [0f32; LANES], 0, bound, strict)
}

/// Continues [`partial_l1`] from the lane sums `acc` of the first `from` voxels: adds the rest
/// one `BLOCK` at a time, 16 lanes, returning after any block whose total exceeds `bound` (or
/// equals it, when `strict`), else the full sum.
#[inline(always)]
fn finish_l1(
    b: &[f32],
    cv: &[f32],
    mut acc: [f32; LANES],
    from: usize,
    bound: f32,
    strict: bool,
) -> f32 {
    let mut done = acc.iter().sum();
    for (part_a, part_c) in b[from..]
        .chunks_exact(BLOCK)
        .zip(cv[from..].chunks_exact(BLOCK))
    {
        for (ca, cb) in part_a.chunks_exact(LANES).zip(part_c.chunks_exact(LANES)) {
            for i in 0..LANES {
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

/// Scores the first `BLOCK` voxels of brick `b` against every centroid, `GROUP` centroids per
/// pass: lane `j` of centroid `c` sums `|b[16m + j] - c[16m + j]|` over `m` in order and the
/// total adds the lanes in order, as [`finish_l1`] does — only vectorised across centroids.
#[inline(always)]
fn first_blocks(b: &[f32], cents: &Centroids, scratch: &mut Scratch) {
    let groups = cents.head.len() / BLOCK;
    scratch.lanes.resize(groups * LANES, [0.0; GROUP]);
    scratch.first.resize(groups * GROUP, 0.0);
    let x: &[f32; BLOCK] = b[..BLOCK].try_into().unwrap();
    for ((head, lanes), first) in cents
        .head
        .chunks_exact(BLOCK)
        .zip(scratch.lanes.chunks_exact_mut(LANES))
        .zip(scratch.first.chunks_exact_mut(GROUP))
    {
        let head: &[[f32; GROUP]; BLOCK] = head.try_into().unwrap();
        // `Iterator::sum` of the 16 lanes, per centroid: a fold from -0.0 in lane order.
        let mut total = [-0f32; GROUP];
        for (j, out) in lanes.iter_mut().enumerate() {
            let mut acc = [0f32; GROUP];
            for m in 0..BLOCK / LANES {
                let v = m * LANES + j;
                for (a, &cv) in acc.iter_mut().zip(&head[v]) {
                    *a += (x[v] - cv).abs();
                }
            }
            for (t, &a) in total.iter_mut().zip(&acc) {
                *t += a;
            }
            *out = acc;
        }
        first.copy_from_slice(&total);
    }
}

/// The rest of centroid `c`'s distance (see [`finish_l1`]), from its saved first-block lanes.
#[inline(always)]
fn rest_l1(
    b: &[f32],
    cents: &Centroids,
    lanes: &[[f32; GROUP]],
    c: usize,
    bound: f32,
    strict: bool,
) -> f32 {
    let mut acc = [0f32; LANES];
    for (j, a) in acc.iter_mut().enumerate() {
        *a = lanes[c / GROUP * LANES + j][c % GROUP];
    }
    finish_l1(b, cents.row(c), acc, BLOCK, bound, strict)
}

#[inline(always)]
fn nearest_portable(b: &[f32], cents: &Centroids, hint: Option<u32>, scratch: &mut Scratch) -> u32 {
    let k = cents.k;
    first_blocks(b, cents, scratch);
    let (first, lanes) = (&scratch.first[..k], &scratch.lanes[..]);
    let hint = match hint {
        Some(h) => (h as usize).min(k - 1),
        // Lowest first-block sum, lowest index on ties (any start gives the same argmin).
        None => (0..k).fold(0, |m, c| if first[c] < first[m] { c } else { m }),
    };
    let mut best = (rest_l1(b, cents, lanes, hint, f32::INFINITY, false), hint);
    for (c, &d1) in first.iter().enumerate() {
        if c == hint {
            continue;
        }
        // A centroid after the best one must beat it strictly; one before it may tie.
        let strict = c > best.1;
        if d1 > best.0 || (strict && d1 == best.0) {
            continue; // abandoned after the first block, as `finish_l1` would be
        }
        let d = rest_l1(b, cents, lanes, c, best.0, strict);
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

/// The nearest centroid of each candidate, in parallel, each search starting from the
/// candidate's previous assignment when there is one.
fn assign_all(pool: &[f32], cand: &[usize], centroids: &[f32], prev: Option<&[u32]>) -> Vec<u32> {
    let cents = Centroids::new(centroids);
    let brick = |b: usize| &pool[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS];
    (0..cand.len())
        .into_par_iter()
        .map_init(Scratch::default, |scratch, i| {
            nearest(brick(cand[i]), &cents, prev.map(|p| p[i]), scratch)
        })
        .collect()
}

/// New centroids: the mean of their members; an empty cluster keeps its previous centroid.
///
/// The sums are the fixed-order reduction the result is defined by: candidates in `CHUNK`-sized
/// chunks, each chunk's sum over its members in candidate order (from 0), the chunk sums added
/// in chunk order (from 0), in f64. Computed per centroid (the members bucketed by centroid in
/// candidate order) rather than per chunk, so no k × 512 buffer is built per chunk and each
/// member brick is read once, whole; chunks without members would add 0.0, which changes no
/// sum, so the result is bit-identical to the per-chunk reduction. With few centroids for the
/// threads, each centroid is split in 4 voxel ranges so the work still spreads.
fn update_centroids(pool: &[f32], cand: &[usize], assign: &[u32], centroids: &mut [f32]) {
    let k = centroids.len() / BRICK_VOXELS;
    // Counting sort of candidate positions by centroid (stable: candidate order within each).
    let mut start = vec![0usize; k + 1];
    for &c in assign {
        start[c as usize + 1] += 1;
    }
    for c in 0..k {
        start[c + 1] += start[c];
    }
    let mut fill = start.clone();
    let mut members = vec![0u32; assign.len()];
    for (i, &c) in assign.iter().enumerate() {
        members[fill[c as usize]] = i as u32;
        fill[c as usize] += 1;
    }
    let span = if k >= 4 * rayon::current_num_threads() {
        BRICK_VOXELS
    } else {
        BRICK_VOXELS / 4
    };
    centroids
        .par_chunks_mut(span)
        .enumerate()
        .for_each(|(task, dst)| {
            let (c, v0) = (task * span / BRICK_VOXELS, task * span % BRICK_VOXELS);
            let mine = &members[start[c]..start[c + 1]];
            if mine.is_empty() {
                return;
            }
            let mut total = [0f64; BRICK_VOXELS];
            let mut part = [0f64; BRICK_VOXELS];
            let (total, part) = (&mut total[..span], &mut part[..span]);
            let mut chunk = mine[0] as usize / CHUNK;
            for &i in mine {
                if i as usize / CHUNK != chunk {
                    for (t, p) in total.iter_mut().zip(part.iter_mut()) {
                        *t += *p;
                        *p = 0.0;
                    }
                    chunk = i as usize / CHUNK;
                }
                let b = cand[i as usize] * BRICK_VOXELS + v0;
                for (p, &v) in part.iter_mut().zip(&pool[b..b + span]) {
                    *p += v as f64;
                }
            }
            let inv = 1.0 / mine.len() as f64;
            for ((d, t), p) in dst.iter_mut().zip(total.iter_mut()).zip(part.iter()) {
                *t += *p;
                *d = (*t * inv) as f32;
            }
        });
}

/// [`normalized_variance`] of every brick of `pool`, bit-identical, but `LOCKSTEP` bricks at a
/// time, so each f64 sum (kept in its own order) overlaps the others instead of waiting on
/// its own add latency.
fn normalized_variances(pool: &[f32]) -> Vec<f32> {
    const LOCKSTEP: usize = 8;
    let mut out = vec![0f32; pool.len() / BRICK_VOXELS];
    out.par_chunks_mut(LOCKSTEP)
        .zip(pool.par_chunks(LOCKSTEP * BRICK_VOXELS))
        .for_each(|(out, bricks)| {
            if out.len() < LOCKSTEP {
                for (o, b) in out.iter_mut().zip(bricks.chunks_exact(BRICK_VOXELS)) {
                    *o = normalized_variance(b);
                }
                return;
            }
            let n = BRICK_VOXELS as f64;
            let x = |j: usize, i: usize| bricks[j * BRICK_VOXELS + i] as f64;
            // `Iterator::sum` folds from -0.0 in element order.
            let mut sum = [-0f64; LOCKSTEP];
            for i in 0..BRICK_VOXELS {
                for (j, s) in sum.iter_mut().enumerate() {
                    *s += x(j, i);
                }
            }
            let mean = sum.map(|s| s / n);
            let mut sq = [-0f64; LOCKSTEP];
            for i in 0..BRICK_VOXELS {
                for (j, s) in sq.iter_mut().enumerate() {
                    *s += (x(j, i) - mean[j]).powi(2);
                }
            }
            for j in 0..LOCKSTEP {
                let var = sq[j] / n;
                out[j] = if var == 0.0 {
                    0.0
                } else if mean[j] == 0.0 {
                    f32::INFINITY
                } else {
                    (var / mean[j].abs()) as f32
                };
            }
        });
    out
}

/// Runs k-means over the candidate bricks of `pool`.
pub fn cluster(pool: &[f32], o: &ClusterOptions) -> ClusterResult {
    let n = pool.len() / BRICK_VOXELS;
    let brick = |b: usize| &pool[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS];
    let nv = normalized_variances(pool);
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
    // Previous assignments (the search's starting points); none before the first iteration.
    let mut assign: Option<Vec<u32>> = None;
    let mut iterations_run = 0;
    for _ in 0..o.iterations.max(1) {
        iterations_run += 1;
        let next = assign_all(pool, &cand, &centroids, assign.as_deref());
        let changed = assign.as_ref() != Some(&next);
        update_centroids(pool, &cand, &next, &mut centroids);
        assign = Some(next);
        if !changed {
            break;
        }
    }
    // Final assignment to the final centroids.
    let fin = assign_all(pool, &cand, &centroids, assign.as_deref());
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

/// k-means over the pool by channel group: bricks that the same set of channels reads (one
/// group for a single grid) are clustered among themselves, so no centroid mixes the units of two
/// grids, and each group is guarded by its own budget. The centroids requested are shared among
/// the groups in proportion to their sizes (all of them to a lone group).
pub struct Grouped {
    /// Per group: its pool bricks (ascending) and its k-means over them.
    pub groups: Vec<(Vec<u32>, ClusterResult)>,
    pub requested: usize,
    pub variance_threshold: f32,
}

/// The bricks `members` of `bricks`, in order: `bricks` itself when the members are all of it.
fn gather<'a>(bricks: &'a [f32], members: &[u32]) -> std::borrow::Cow<'a, [f32]> {
    if members.len() * BRICK_VOXELS == bricks.len() {
        // Members are ascending and distinct: all of the bricks, in order.
        return std::borrow::Cow::Borrowed(bricks);
    }
    let mut v = Vec::with_capacity(members.len() * BRICK_VOXELS);
    for &b in members {
        let b = b as usize;
        v.extend_from_slice(&bricks[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS]);
    }
    std::borrow::Cow::Owned(v)
}

/// What the guard let through: per pool brick, the encode input it reads, and that input.
pub struct Guarded {
    /// Per pool brick: its index in `input`.
    pub input_of: Vec<u32>,
    /// Bricks that keep their own data (pool order), then the centroids that kept members.
    pub input: Vec<f32>,
    /// Per input brick: the bound it is encoded under (its own, or its group's for a centroid).
    pub budgets: Vec<f32>,
    pub clusters_used: usize,
    pub rejected_by_error: usize,
}

/// Runs k-means over every channel group of `bricks` (`channels[b]`: the mask of pool brick `b`).
pub fn cluster_groups(bricks: &[f32], channels: &[u8], o: &ClusterOptions) -> Grouped {
    let n = bricks.len() / BRICK_VOXELS;
    let mut masks: Vec<u8> = channels[..n].to_vec();
    masks.sort_unstable();
    masks.dedup();
    let lone = masks.len() == 1;
    let groups = masks
        .iter()
        .map(|&m| {
            let members: Vec<u32> = (0..n as u32)
                .filter(|&b| channels[b as usize] == m)
                .collect();
            let k = if lone {
                o.clusters
            } else {
                ((o.clusters as f64 * members.len() as f64 / n as f64).round() as usize).max(1)
            };
            let r = cluster(
                &gather(bricks, &members),
                &ClusterOptions { clusters: k, ..*o },
            );
            (members, r)
        })
        .collect();
    Grouped {
        groups,
        requested: o.clusters,
        variance_threshold: o.variance_threshold,
    }
}

impl Grouped {
    pub fn candidates(&self) -> usize {
        self.groups.iter().map(|g| g.1.candidates).sum()
    }
    pub fn rejected_by_variance(&self) -> usize {
        self.groups.iter().map(|g| g.1.rejected_by_variance).sum()
    }
    pub fn iterations_run(&self) -> usize {
        self.groups
            .iter()
            .map(|g| g.1.iterations_run)
            .max()
            .unwrap_or(0)
    }

    /// The encode input under the per-brick budgets `budget` (`None`: lossless, nothing is
    /// guarded): each member joins its centroid only if the *decoded* centroid, plus what a GPU's
    /// native read of it may add, is within its group's budget of each of its voxels
    /// ([`crate::encode::guard_members`]).
    pub fn guard(
        &self,
        bricks: &[f32],
        budget: &[f32],
        eopts: &crate::encode::EncodeOptions,
    ) -> Result<Guarded, String> {
        let n = bricks.len() / BRICK_VOXELS;
        // Per pool brick: (group, centroid) it joined.
        let mut joined: Vec<Option<(usize, u32)>> = vec![None; n];
        let mut rejected_by_error = 0;
        for (g, (members, r)) in self.groups.iter().enumerate() {
            let mut member_of = r.member_of.clone();
            if let (Some(&b0), Some(_)) = (members.first(), eopts.max_error) {
                let o = crate::encode::EncodeOptions {
                    max_error: Some(budget[b0 as usize]),
                    ..*eopts
                };
                let ce = crate::encode::encode(&r.centroids, &o)?;
                let own = gather(bricks, members);
                rejected_by_error +=
                    crate::encode::guard_members(&own, &r.centroids, &ce, &mut member_of, &o);
            }
            for (i, m) in member_of.iter().enumerate() {
                if let Some(c) = m {
                    joined[members[i] as usize] = Some((g, *c));
                }
            }
        }
        let mut input_of = vec![0u32; n];
        let mut input = Vec::new();
        let mut budgets = Vec::new();
        let mut next = 0u32;
        for (b, j) in joined.iter().enumerate() {
            if j.is_none() {
                input.extend_from_slice(&bricks[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS]);
                budgets.push(budget[b]);
                input_of[b] = next;
                next += 1;
            }
        }
        let mut used: Vec<Vec<u32>> = self
            .groups
            .iter()
            .map(|g| vec![u32::MAX; g.1.centroids.len() / BRICK_VOXELS])
            .collect();
        let mut clusters_used = 0;
        for (b, j) in joined.iter().enumerate() {
            if let Some((g, c)) = *j {
                let slot = &mut used[g][c as usize];
                if *slot == u32::MAX {
                    *slot = next;
                    next += 1;
                    clusters_used += 1;
                    let cents = &self.groups[g].1.centroids;
                    input.extend_from_slice(
                        &cents[c as usize * BRICK_VOXELS..(c as usize + 1) * BRICK_VOXELS],
                    );
                    budgets.push(budget[b]);
                }
                input_of[b] = *slot;
            }
        }
        Ok(Guarded {
            input_of,
            input,
            budgets,
            clusters_used,
            rejected_by_error,
        })
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
        // Includes exact ties (duplicate centroids), where the lowest index must win; 20
        // centroids, so the batched first block has a padded group.
        let cents = bricks(20, |c, v| ((c % 6) * 3 + v % 5) as f32 * 0.25);
        let data = bricks(60, |b, v| ((b * 13 + v * 3) % 23) as f32 * 0.2);
        let view = Centroids::new(&cents);
        let mut scratch = Scratch::default();
        for b in 0..60 {
            let x = &data[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS];
            let full = (0..20)
                .map(|c| (l1(x, &cents[c * BRICK_VOXELS..(c + 1) * BRICK_VOXELS]), c))
                .fold((f32::INFINITY, 0), |m, d| if d.0 < m.0 { d } else { m });
            let hints = (0..20).map(Some).chain([None]);
            for h in hints {
                let got = nearest(x, &view, h, &mut scratch) as usize;
                assert_eq!(got, full.1, "brick {b} hint {h:?}");
                assert_eq!(nearest_portable(x, &view, h, &mut scratch) as usize, full.1);
            }
        }
    }

    #[test]
    fn batched_first_block_is_bit_identical_to_the_one_centroid_kernel() {
        let cents = bricks(21, |c, v| ((c * 7 + v * 11) % 29) as f32 * 0.137 - 1.0);
        let data = bricks(8, |b, v| ((b * 5 + v * 3) % 31) as f32 * 0.093);
        let view = Centroids::new(&cents);
        let mut scratch = Scratch::default();
        for b in 0..8 {
            let x = &data[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS];
            first_blocks(x, &view, &mut scratch);
            for c in 0..21 {
                let cv = view.row(c);
                // The kernel's first check (bound 0: it returns right after the first block).
                let want = partial_l1(x, cv, 0.0, true);
                assert_eq!(
                    scratch.first[c].to_bits(),
                    want.to_bits(),
                    "brick {b} c {c}"
                );
                let full = partial_l1(x, cv, f32::INFINITY, false);
                assert_eq!(full.to_bits(), l1(x, cv).to_bits());
            }
        }
    }

    /// The k-means the result is defined by, written plainly: full L1 distances (the kernel's
    /// lane order), argmin with the lowest index on ties, centroid sums per `CHUNK` of candidates
    /// in order and the chunk sums added in order, in f64.
    fn reference(pool: &[f32], o: &ClusterOptions) -> (Vec<f32>, Vec<Option<u32>>, usize) {
        let n = pool.len() / BRICK_VOXELS;
        let brick = |b: usize| &pool[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS];
        let cand: Vec<usize> = (0..n)
            .filter(|&b| normalized_variance(brick(b)) <= o.variance_threshold)
            .collect();
        let k = o.clusters.min(cand.len());
        let mut order = cand.clone();
        let mut rng = Rng(o.seed | 1);
        for i in 0..k {
            let j = i + (rng.next() % (order.len() - i) as u64) as usize;
            order.swap(i, j);
        }
        let mut cents: Vec<f32> = order[..k].iter().flat_map(|&b| brick(b).to_vec()).collect();
        let nearest_full = |x: &[f32], cents: &[f32]| {
            let mut best = (f32::INFINITY, 0);
            for c in 0..k {
                let d = l1(x, &cents[c * BRICK_VOXELS..(c + 1) * BRICK_VOXELS]);
                if d < best.0 {
                    best = (d, c);
                }
            }
            best.1 as u32
        };
        let mut assign: Vec<u32> = Vec::new();
        let mut runs = 0;
        for _ in 0..o.iterations.max(1) {
            runs += 1;
            let next: Vec<u32> = cand
                .iter()
                .map(|&b| nearest_full(brick(b), &cents))
                .collect();
            let changed = next != assign;
            assign = next;
            let mut sum = vec![0f64; k * BRICK_VOXELS];
            let mut cnt = vec![0u32; k];
            for (bs, cs) in cand.chunks(CHUNK).zip(assign.chunks(CHUNK)) {
                let mut part = vec![0f64; k * BRICK_VOXELS];
                for (&b, &c) in bs.iter().zip(cs) {
                    cnt[c as usize] += 1;
                    let s = &mut part[c as usize * BRICK_VOXELS..][..BRICK_VOXELS];
                    for (a, &v) in s.iter_mut().zip(brick(b)) {
                        *a += v as f64;
                    }
                }
                for (a, p) in sum.iter_mut().zip(&part) {
                    *a += p;
                }
            }
            for c in 0..k {
                if cnt[c] > 0 {
                    let inv = 1.0 / cnt[c] as f64;
                    for v in 0..BRICK_VOXELS {
                        cents[c * BRICK_VOXELS + v] = (sum[c * BRICK_VOXELS + v] * inv) as f32;
                    }
                }
            }
            if !changed {
                break;
            }
        }
        let mut member_of = vec![None; n];
        for &b in &cand {
            member_of[b] = Some(nearest_full(brick(b), &cents));
        }
        (cents, member_of, runs)
    }

    #[test]
    fn same_result_as_the_plain_reference_k_means() {
        // 4500 noisy bricks of 9 shapes (3 reduction chunks), some rejected by variance, k = 21
        // (a padded group in the batched search), duplicate bricks (exact distance ties).
        let mut s = 0x9E37_79B9_7F4A_7C15u64;
        let mut noise = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s % 1000) as f32 / 1000.0
        };
        let n = 4500;
        let mut data = Vec::with_capacity(n * BRICK_VOXELS);
        for b in 0..n {
            let shape = (b * 7919) % 9;
            for v in 0..BRICK_VOXELS {
                let base = 0.3 + 0.2 * ((v / 64) as f32 * 0.4 + shape as f32).sin();
                let amp = if b % 50 == 0 { 2.0 } else { 0.04 };
                data.push(if b % 17 == 3 {
                    base
                } else {
                    base + amp * noise()
                });
            }
        }
        let o = ClusterOptions {
            clusters: 21,
            iterations: 6,
            variance_threshold: 0.12,
            seed: 11,
        };
        let r = cluster(&data, &o);
        let (cents, member_of, runs) = reference(&data, &o);
        let (cand, rej) = (r.candidates, r.rejected_by_variance);
        assert!(
            rej > 0 && cand > 2 * CHUNK,
            "{cand} candidates, {rej} rejected"
        );
        assert_eq!(r.iterations_run, runs);
        assert_eq!(r.member_of, member_of);
        assert_eq!(
            r.centroids.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            cents.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }

    #[test]
    fn lockstep_variances_are_bit_identical() {
        // 21 bricks (a partial lockstep group), including constant, zero-mean and -0.0 bricks.
        let data = bricks(21, |b, v| match b {
            0 => 0.25,
            1 => -0.0,
            2 => [1.5, -1.5][v % 2],
            _ => ((b * 37 + v * 11) % 53) as f32 * 0.01 * (b as f32 - 6.5),
        });
        let got = normalized_variances(&data);
        for (b, g) in got.iter().enumerate() {
            let want = normalized_variance(&data[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS]);
            assert_eq!(g.to_bits(), want.to_bits(), "brick {b}");
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
