//! The hierarchical walk (HDDA): a DDA over the frame's 128³ regions, inside an L2 node a DDA
//! over its 16³ leaf slots, inside a brick a DDA over its 8³ voxels. Each level skips what its
//! `[min, max]` range proves irrelevant (the visitor decides from the max), so empty and
//! near-empty space costs one step per node. Everything is read through the asset's sampler API.

use vdbcook_asset::{Asset, LeafRef, BRICK_VOXELS, EMPTY, L2_SPAN, TILE_BIT};

use crate::dda::{walk_cells, Flow};
use crate::space::IndexRay;

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
    keys: Vec<u32>,
    values: Vec<[f32; BRICK_VOXELS]>,
}

const CACHE_SLOTS: usize = 64;

impl Default for BrickCache {
    fn default() -> Self {
        BrickCache {
            keys: vec![u32::MAX; CACHE_SLOTS],
            values: vec![[0.0; BRICK_VOXELS]; CACHE_SLOTS],
        }
    }
}

impl BrickCache {
    pub fn get(&mut self, asset: &Asset, b: u32) -> &[f32; BRICK_VOXELS] {
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

/// Walks `frame` along `ray` for `t ∈ [t0, t1]` (already clipped to the root extent).
pub(crate) fn walk(
    asset: &Asset,
    frame: usize,
    ray: &IndexRay,
    t0: f64,
    t1: f64,
    cache: &mut BrickCache,
    v: &mut impl Visitor,
) -> Flow {
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
        if v.skip(asset.l2_ranges[e as usize][1]) {
            return Flow::Go;
        }
        let lo = r.map(|c| c * 16);
        walk_cells(ray, 8.0, lo, lo.map(|c| c + 16), ta, tb, |l, la, lb| {
            v.count();
            let origin = l.map(|c| c * 8);
            match asset.leaf_at(frame, origin) {
                LeafRef::Empty => uniform(v, la, lb, background, Holder::Empty),
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
        })
    })
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
/// rounding error outside reads its nearest voxel).
#[inline]
pub(crate) fn brick_value(values: &[f32; BRICK_VOXELS], origin: [i64; 3], p: [f64; 3]) -> f32 {
    let i = [0, 1, 2].map(|a| ((p[a].floor() as i64 - origin[a]).clamp(0, 7)) as usize);
    values[64 * i[0] + 8 * i[1] + i[2]]
}
