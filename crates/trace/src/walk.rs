//! The hierarchical walk (HDDA): a DDA over the frame's 128³ regions, inside an L2 node a DDA
//! over its 16³ leaf slots, inside a brick a DDA over its 8³ voxels. Each level skips what its
//! `[min, max]` range proves irrelevant (the visitor decides from the max), so empty and
//! near-empty space costs one step per node. Everything is read through the asset's sampler API.

use vdbcook_asset::{Asset, LeafRef, BRICK_VOXELS, EMPTY, L2_SPAN, TILE_BIT};

use crate::dda::{walk_cells, Flow};
use crate::space::IndexRay;
use vdbcook_scene::{content_box, for_each_slot_max};

/// What a constant-valued span belongs to (for the brick-hue mode).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Holder {
    /// Background (an empty region or leaf slot).
    Empty,
    /// A tiled 128³ region or a tile leaf.
    Tile,
    /// A voxel of brick `b`.
    Brick(u32),
}

/// What a walk reports to.
pub(crate) trait Visitor {
    /// Whether a node, leaf or voxel whose values are at most `max` can be passed over.
    fn skip(&self, max: f32) -> bool;
    /// Whether bricks are walked voxel by voxel (`span` per voxel) or handed over whole (`brick`).
    fn voxels(&self) -> bool;
    /// A span `[ta, tb]` of constant value `v`.
    fn span(&mut self, ta: f64, tb: f64, v: f32, holder: Holder) -> Flow;
    /// A span `[ta, tb]` inside brick `b` (values at `64x + 8y + z`, origin `origin`), whose
    /// values are at most `max`. Only called when `voxels()` is false.
    fn brick(
        &mut self,
        _ta: f64,
        _tb: f64,
        _max: f32,
        _origin: [i64; 3],
        _values: &[f32; BRICK_VOXELS],
    ) -> Flow {
        Flow::Go
    }
    /// One traversal step (a region, leaf slot or voxel visited).
    fn count(&mut self) {}
    /// Whether the walk may pass over whole 4³-slot blocks of an L2 node (only for visitors that
    /// do not count steps: the spans are the same, the step count is not).
    fn coarse(&self) -> bool {
        false
    }
}

/// A visitor that samples along the ray by position (scatter, shadow, delta and ratio tracking):
/// constant spans and whole bricks both reach `sample_span` with a value function and the span's
/// majorant, so each of them is written once.
pub(crate) trait SpanSampler {
    /// Whether a node, leaf or voxel whose values are at most `max` can be passed over.
    fn skip_max(&self, max: f32) -> bool;
    /// `[ta, tb]` where the value at index point `p` is `value(p)`, at most `max`.
    fn sample_span(&mut self, ta: f64, tb: f64, max: f32, value: impl Fn([f64; 3]) -> f32) -> Flow;
}

impl<T: SpanSampler> Visitor for T {
    fn skip(&self, max: f32) -> bool {
        self.skip_max(max)
    }
    fn voxels(&self) -> bool {
        false
    }
    fn coarse(&self) -> bool {
        true
    }
    fn span(&mut self, ta: f64, tb: f64, v: f32, _: Holder) -> Flow {
        self.sample_span(ta, tb, v, |_| v)
    }
    fn brick(
        &mut self,
        ta: f64,
        tb: f64,
        max: f32,
        origin: [i64; 3],
        values: &[f32; BRICK_VOXELS],
    ) -> Flow {
        self.sample_span(ta, tb, max, |p| brick_value(values, origin, p))
    }
}

/// Decoded bricks, direct-mapped by index: rays of one row (and shadow rays from neighbouring
/// samples) cross the same bricks.
pub struct BrickCache {
    /// The asset whose bricks the cache holds (its address): a cache handed another asset
    /// forgets what it held, so one `Scratch` may serve tracers of several assets.
    owner: usize,
    keys: Vec<u32>,
    values: Vec<[f32; BRICK_VOXELS]>,
}

const CACHE_SLOTS: usize = 64;

impl Default for BrickCache {
    fn default() -> Self {
        BrickCache {
            owner: 0,
            keys: vec![u32::MAX; CACHE_SLOTS],
            values: vec![[0.0; BRICK_VOXELS]; CACHE_SLOTS],
        }
    }
}

impl BrickCache {
    pub fn get(&mut self, asset: &Asset, b: u32) -> &[f32; BRICK_VOXELS] {
        let owner = asset as *const Asset as usize;
        if owner != self.owner {
            self.keys.fill(u32::MAX);
            self.owner = owner;
        }
        let s = (b as usize).wrapping_mul(0x9E37_79B9) % CACHE_SLOTS;
        if self.keys[s] != b {
            asset.decode_brick(b, &mut self.values[s]);
            self.keys[s] = b;
        }
        &self.values[s]
    }
}

/// The root extent in index units.
pub(crate) fn extent(asset: &Asset) -> [f64; 3] {
    asset.header.root_dims.map(|d| d as f64 * L2_SPAN as f64)
}

/// Leaf slots per block edge: an L2 node's 16³ slots form 4³ blocks of 4³ slots (32³ voxels).
const BLOCK_SLOTS: i64 = 4;

/// One frame of an asset, with what the walk precomputes for it: per L2 node of the frame, the max
/// over each of its 4³ blocks of the slots' maxes (background for an empty slot, the tile value,
/// the brick's `brick_ranges` max; a NaN max counts as +∞), and the box of the leaves (tiled or
/// empty regions) whose max is not `≤ 0`. A visitor that does not count steps passes over a whole block by its max, so
/// empty space inside a node costs one step per 32³ voxels instead of per 8³, and, if it passes
/// over values `≤ 0`, walks only the part of the ray inside that box. The spans it reports are the
/// same (see `walk`).
pub(crate) struct Grid<'a> {
    pub asset: &'a Asset,
    pub frame: usize,
    /// Per L2 node: an index into `block_max`, or `u32::MAX` for nodes not in this frame.
    block_of: Vec<u32>,
    block_max: Vec<[f32; 64]>,
    /// `[lo, hi)` in index units: every leaf outside holds values `≤ 0` (empty box: `lo ≥ hi`).
    content: ([f64; 3], [f64; 3]),
}

impl<'a> Grid<'a> {
    pub fn new(asset: &'a Asset, frame: usize) -> Grid<'a> {
        let mut block_of = vec![u32::MAX; asset.l2_count()];
        let mut block_max = Vec::new();
        let background = asset.header.background;
        for &e in asset.frame_roots(frame) {
            // Unstored and tiled regions have no blocks; a node met twice has them already.
            if e == EMPTY || e & TILE_BIT != 0 || block_of[e as usize] != u32::MAX {
                continue;
            }
            let mut m = [f32::NEG_INFINITY; 64];
            // A NaN slot max counts as +∞: skip rules pass over NaN (`!(NaN >= c)`), so a NaN
            // block max would pass over the block's other slots too, which the fine walk visits.
            let put = |m: &mut f32, v: f32| {
                let v = if v.is_nan() { f32::INFINITY } else { v };
                if v > *m {
                    *m = v;
                }
            };
            // Slots missing from a 4³ block hold the background (mask layout: `for_each_slot_max`).
            let node = e as usize;
            for (w, &word) in asset.l2_mask(node).iter().enumerate() {
                let (z, yb) = (w / 4, w % 4);
                for bx in 0..4 {
                    let full = 0x000F_000F_000F_000Fu64 << (4 * bx);
                    if word & full != full {
                        put(&mut m[bx + 4 * (yb + 4 * (z / 4))], background);
                    }
                }
            }
            for_each_slot_max(asset, node, |w, bit, v| {
                let (z, yb) = (w / 4, w % 4);
                put(&mut m[bit % 16 / 4 + 4 * (yb + 4 * (z / 4))], v);
            });
            block_of[e as usize] = block_max.len() as u32;
            block_max.push(m);
        }
        Grid {
            asset,
            frame,
            block_of,
            block_max,
            // An empty box (`lo = hi`) when nothing is content: every clip to it is empty.
            content: content_box(asset, frame).unwrap_or(([0.0; 3], [0.0; 3])),
        }
    }
}

/// Walks the grid's frame along `ray` for `t ∈ [t0, t1]` (already clipped to the root extent).
///
/// For a visitor with `coarse()`, an L2 node is walked as a DDA over its 4³ blocks, then over the
/// 4³ leaf slots of each block not passed over. That reports the same spans as the DDA over the
/// node's 16³ slots: the crossing parameters are recomputed from cell indices (`dda`), and a block
/// boundary is a leaf boundary, so both compute the same parameters; a block is passed over only
/// when every slot in it would be (`skip` is monotone in the max).
///
/// Such a visitor that also passes over `0` walks only `[t0, t1]` ∩ the content box: everything
/// outside would be passed over, and the entry into the first leaf not passed over is the box
/// entry computed by the same formula (`(face − o)/d`) as the DDA's crossing into it, as the leaf
/// shares that face with the box (up to the last bit where the ray enters through an edge or a
/// corner, where the two may take a different axis's rounding: a sample must then fall within
/// one ulp of the entry to be counted differently).
pub(crate) fn walk(
    grid: &Grid,
    ray: &IndexRay,
    t0: f64,
    t1: f64,
    cache: &mut BrickCache,
    v: &mut impl Visitor,
) -> Flow {
    let (t0, t1) = if v.coarse() && v.skip(0.0) {
        let (lo, hi) = grid.content;
        match ray.clip_box(lo, hi) {
            Some((a, b)) => (t0.max(a), t1.min(b)),
            None => return Flow::Go,
        }
    } else {
        (t0, t1)
    };
    let asset = grid.asset;
    let frame = grid.frame;
    let dims = asset.header.root_dims.map(|d| d as i64);
    let background = asset.header.background;
    let span = L2_SPAN as i64;
    walk_cells(ray, span as f64, [0; 3], dims, t0, t1, |r, ta, tb| {
        v.count();
        let e = asset.root_entry(frame, r.map(|c| c * span));
        if e == EMPTY {
            return uniform(v, ta, tb, background, Holder::Empty);
        }
        if e & TILE_BIT != 0 {
            let value = asset.tiles[(e & !TILE_BIT) as usize];
            return uniform(v, ta, tb, value, Holder::Tile);
        }
        if v.skip(asset.l2_range(e as usize, 0)[1]) {
            return Flow::Go;
        }
        let block = grid.block_of[e as usize];
        if v.coarse() && block != u32::MAX {
            let maxes = &grid.block_max[block as usize];
            let lo = r.map(|c| c * BLOCK_SLOTS);
            let hi = lo.map(|c| c + BLOCK_SLOTS);
            return walk_cells(ray, 32.0, lo, hi, ta, tb, |k, ka, kb| {
                let i = k.map(|c| (c & 3) as usize);
                if v.skip(maxes[i[0] + 4 * (i[1] + 4 * i[2])]) {
                    return Flow::Go;
                }
                let lo = k.map(|c| c * BLOCK_SLOTS);
                walk_cells(
                    ray,
                    8.0,
                    lo,
                    lo.map(|c| c + BLOCK_SLOTS),
                    ka,
                    kb,
                    |l, la, lb| leaf(asset, e, l, la, lb, ray, cache, v),
                )
            });
        }
        let lo = r.map(|c| c * 16);
        walk_cells(ray, 8.0, lo, lo.map(|c| c + 16), ta, tb, |l, la, lb| {
            leaf(asset, e, l, la, lb, ray, cache, v)
        })
    })
}

/// Leaf slot `l` (in leaves, asset index space) of L2 node `node`, crossed for `[la, lb]`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn leaf(
    asset: &Asset,
    node: u32,
    l: [i64; 3],
    la: f64,
    lb: f64,
    ray: &IndexRay,
    cache: &mut BrickCache,
    v: &mut impl Visitor,
) -> Flow {
    v.count();
    let origin = l.map(|c| c * 8);
    let i = l.map(|c| (c & 15) as usize);
    match asset.l2_leaf(node, i[0] + 16 * (i[1] + 16 * i[2])) {
        LeafRef::Empty => uniform(v, la, lb, asset.header.background, Holder::Empty),
        LeafRef::Tile(value) => uniform(v, la, lb, value, Holder::Tile),
        LeafRef::Brick(b) => {
            let max = asset.brick_ranges[b as usize][1];
            if v.skip(max) {
                return Flow::Go;
            }
            let values = cache.get(asset, b);
            if !v.voxels() {
                return v.brick(la, lb, max, origin, values);
            }
            walk_cells(
                ray,
                1.0,
                origin,
                origin.map(|c| c + 8),
                la,
                lb,
                |x, xa, xb| {
                    v.count();
                    let i = x.map(|c| (c & 7) as usize);
                    let value = values[64 * i[0] + 8 * i[1] + i[2]];
                    uniform(v, xa, xb, value, Holder::Brick(b))
                },
            )
        }
    }
}

#[inline]
fn uniform(v: &mut impl Visitor, ta: f64, tb: f64, value: f32, h: Holder) -> Flow {
    if v.skip(value) {
        Flow::Go
    } else {
        v.span(ta, tb, value, h)
    }
}

/// The value of brick voxel holding index-space point `p` (clamped into the brick, so a point a
/// rounding error outside reads its nearest voxel): `clamp(floor(p) − origin, 0, 7)` per axis,
/// computed as `clamp(trunc(p − origin), 0, 7)`. The same: `p − origin` is exact wherever the
/// clamp does not decide (within a few voxels of the brick, `p` and the integer `origin` share
/// the bits it needs), `floor(x) = trunc(x)` for `x ≥ 0`, and `x < 0` (or NaN) gives 0 both ways.
#[inline]
pub(crate) fn brick_value(values: &[f32; BRICK_VOXELS], origin: [i64; 3], p: [f64; 3]) -> f32 {
    let i = |a: usize| {
        let x = p[a] - origin[a] as f64;
        if x < 0.0 {
            0
        } else {
            (x as i64).min(7) as usize
        }
    };
    values[64 * i(0) + 8 * i(1) + i(2)]
}

#[cfg(test)]
mod tests {
    //! The coarse walk (blocks, content box) against the fine one on random content: the same
    //! spans, bit for bit; and `Grid`'s precomputation against a per-slot reference.
    use super::*;
    use crate::test_common::*;
    use vdbcook_asset::PayloadFormat;
    use vdbcook_scene::normalize;

    /// Records every span and brick handed over, as bits; passes over what single scatter
    /// passes over (its cutoff is positive, so `max ≥ cutoff` implies `max > 0`).
    struct Rec {
        coarse: bool,
        spans: Vec<(u64, u64, u32, [i64; 3])>,
    }

    impl Visitor for Rec {
        fn skip(&self, max: f32) -> bool {
            !(max >= 0.005)
        }
        fn voxels(&self) -> bool {
            false
        }
        fn coarse(&self) -> bool {
            self.coarse
        }
        fn span(&mut self, ta: f64, tb: f64, v: f32, _: Holder) -> Flow {
            self.spans
                .push((ta.to_bits(), tb.to_bits(), v.to_bits(), [-1; 3]));
            Flow::Go
        }
        fn brick(
            &mut self,
            ta: f64,
            tb: f64,
            max: f32,
            origin: [i64; 3],
            _: &[f32; BRICK_VOXELS],
        ) -> Flow {
            self.spans
                .push((ta.to_bits(), tb.to_bits(), max.to_bits(), origin));
            Flow::Go
        }
    }

    fn asset(seed: u64, background: f32) -> Asset {
        let mut rng = XorShift(seed);
        let f = random_frame(&mut rng);
        build(
            [2, 2, 1],
            uniform_scale(1.0, [0.0; 3]),
            background,
            &[f],
            PayloadFormat::F32,
        )
    }

    fn spans(
        grid: &Grid,
        o: [f64; 3],
        d: [f64; 3],
        coarse: bool,
    ) -> Vec<(u64, u64, u32, [i64; 3])> {
        let ray = IndexRay::new(o, normalize(d), true);
        let mut v = Rec {
            coarse,
            spans: Vec::new(),
        };
        if let Some((t0, t1)) = ray.clip(extent(grid.asset)) {
            walk(grid, &ray, t0, t1, &mut BrickCache::default(), &mut v);
        }
        v.spans
    }

    #[test]
    fn coarse_walk_reports_the_same_spans_as_the_fine_walk() {
        for (seed, background) in [(3u64, 0.0f32), (4, 0.0), (5, 0.3), (6, -0.2)] {
            coarse_equals_fine(&asset(seed, background), seed);
        }
    }

    #[test]
    fn a_nan_brick_max_does_not_make_the_coarse_walk_pass_over_its_block() {
        // A NaN max is passed over at its own slot (`!(NaN >= c)`), but its block's other slots
        // must still be walked: the block max treats NaN as unbounded.
        let mut a = asset(3, 0.0);
        for b in (0..a.brick_ranges.len()).step_by(5) {
            a.brick_ranges[b][1] = f32::NAN;
        }
        coarse_equals_fine(&a, 3);
    }

    fn coarse_equals_fine(a: &Asset, seed: u64) {
        {
            let grid = Grid::new(a, 0);
            let mut rng = XorShift(seed * 31);
            let ext = extent(a);
            let mut nonempty = 0;
            for i in 0..4000 {
                let (o, d) = if i % 4 == 0 {
                    // Axis-parallel, on leaf, block and region boundaries and between them.
                    let c = [0.0, 8.0, 32.0, 64.0, 96.0, 127.5, 128.0, 160.0, 200.25];
                    let axis = (rng.next_u64() % 3) as usize;
                    let mut o = [0, 1, 2].map(|_| c[(rng.next_u64() % c.len() as u64) as usize]);
                    let mut d = [0.0; 3];
                    d[axis] = if rng.f() < 0.5 { 1.0 } else { -1.0 };
                    o[axis] = if d[axis] > 0.0 { -3.0 } else { ext[axis] + 3.0 };
                    (o, d)
                } else {
                    // From anywhere near the extent (inside it too) toward a random point in it.
                    let o = [0, 1, 2].map(|k| rng.range(-40.0, ext[k] + 40.0));
                    let p = [0, 1, 2].map(|k| rng.range(0.0, ext[k]));
                    (o, [0, 1, 2].map(|k| p[k] - o[k]))
                };
                if d == [0.0; 3] {
                    continue;
                }
                let fine = spans(&grid, o, d, false);
                let coarse = spans(&grid, o, d, true);
                assert_eq!(coarse, fine, "seed {seed} ray {o:?} {d:?}");
                nonempty += !fine.is_empty() as u32;
            }
            assert!(
                nonempty > 1000,
                "seed {seed}: only {nonempty} rays met content"
            );
        }
    }

    #[test]
    fn grid_matches_a_per_slot_reference() {
        for (seed, background) in [(7u64, 0.0f32), (8, 0.4), (9, -1.0)] {
            let a = asset(seed, background);
            let grid = Grid::new(&a, 0);
            let d = a.header.root_dims.map(|d| d as usize);
            let (mut lo, mut hi) = ([i64::MAX; 3], [i64::MIN; 3]);
            for (i, &e) in a.frame_roots(0).iter().enumerate() {
                let o = [i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1])].map(|c| c as i64 * 128);
                let region =
                    |m: f32, lo: &mut [i64; 3], hi: &mut [i64; 3], size: i64, o: [i64; 3]| {
                        if !(m <= 0.0) {
                            for k in 0..3 {
                                lo[k] = lo[k].min(o[k]);
                                hi[k] = hi[k].max(o[k] + size);
                            }
                        }
                    };
                if e == EMPTY || e & TILE_BIT != 0 {
                    let m = if e == EMPTY {
                        background
                    } else {
                        a.tiles[(e & !TILE_BIT) as usize]
                    };
                    region(m, &mut lo, &mut hi, 128, o);
                    continue;
                }
                let mut want = [f32::NEG_INFINITY; 64];
                for s in 0..4096usize {
                    let l = [s % 16, (s / 16) % 16, s / 256];
                    let v = match a.l2_leaf(e, s) {
                        LeafRef::Empty => background,
                        LeafRef::Tile(v) => v,
                        LeafRef::Brick(b) => a.brick_ranges[b as usize][1],
                    };
                    let k = l[0] / 4 + 4 * (l[1] / 4 + 4 * (l[2] / 4));
                    want[k] = want[k].max(v);
                    region(
                        v,
                        &mut lo,
                        &mut hi,
                        8,
                        [0, 1, 2].map(|k| o[k] + 8 * l[k] as i64),
                    );
                }
                let got = grid.block_max[grid.block_of[e as usize] as usize];
                assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "seed {seed}");
            }
            assert_eq!(
                grid.content,
                (lo.map(|c| c as f64), hi.map(|c| c as f64)),
                "seed {seed}"
            );
        }
    }
}
