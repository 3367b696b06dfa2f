//! The in-memory result of reading one float grid: leaves with their full 8³ value arrays, tiles at
//! every level, the background, and the transform. Layout is flat (one value array for all leaves)
//! so iteration is a linear scan; lookups by coordinate build a hash index on demand.

use std::collections::HashMap;

use crate::transform::Transform;

/// Voxels along one edge of a leaf (OpenVDB's LeafNode<3>).
pub const LEAF_DIM: i32 = 8;
/// Values per leaf.
pub const LEAF_VOXELS: usize = 512;

/// Where a tile sits in OpenVDB's tree, which fixes its extent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum TileLevel {
    /// A value slot of an InternalNode<4> (a "level 1" tile): 8³ voxels.
    L8 = 1,
    /// A value slot of an InternalNode<5> ("level 2"): 128³ voxels.
    L128 = 2,
    /// A root-node tile ("level 3"): 4096³ voxels.
    L4096 = 3,
}

impl TileLevel {
    pub fn dim(self) -> i32 {
        match self {
            TileLevel::L8 => 8,
            TileLevel::L128 => 128,
            TileLevel::L4096 => 4096,
        }
    }
    pub fn voxels(self) -> u64 {
        let d = self.dim() as u64;
        d * d * d
    }
}

/// One tile. Active tiles count as `dim³` active voxels; inactive tiles are kept only when their
/// value differs from the background (e.g. the inside of a level set).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tile {
    pub origin: [i32; 3],
    pub level: TileLevel,
    pub value: f32,
    pub active: bool,
}

/// A leaf header: origin (multiple of 8) and the active-voxel mask.
///
/// Voxel `n` of a leaf (0..512) is at `origin + (n >> 6, (n >> 3) & 7, n & 7)` (x slowest, as in
/// OpenVDB) and is active when bit `n & 63` of `mask[n >> 6]` is set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Leaf {
    pub origin: [i32; 3],
    pub mask: [u64; 8],
}

impl Leaf {
    pub fn active_count(&self) -> u32 {
        self.mask.iter().map(|w| w.count_ones()).sum()
    }
    pub fn is_active(&self, n: usize) -> bool {
        self.mask[n >> 6] >> (n & 63) & 1 == 1
    }
}

/// Offset of voxel (x, y, z) inside its leaf.
#[inline]
pub fn leaf_offset(ijk: [i32; 3]) -> usize {
    (((ijk[0] & 7) << 6) | ((ijk[1] & 7) << 3) | (ijk[2] & 7)) as usize
}

/// A float grid as OpenVDB reads it (double grids are converted to f32).
#[derive(Debug, Clone)]
pub struct FloatGrid {
    pub background: f32,
    /// Leaves in file order.
    pub leaves: Vec<Leaf>,
    /// `values[i * 512 .. (i + 1) * 512]` are leaf `i`'s values, inactive ones included.
    pub values: Vec<f32>,
    /// Active tiles, and inactive tiles whose value is not the background.
    pub tiles: Vec<Tile>,
    pub transform: Transform,
    /// The source stored doubles (converted to f32 on read).
    pub converted_from_double: bool,
}

/// Summary statistics over active voxels; tiles are weighted by their size, never expanded.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GridStats {
    pub active_voxels: u64,
    pub active_tiles: u64,
    pub active_tiles_by_level: [u64; 3],
    pub leaf_count: u64,
    /// Inclusive index-space bounds of the active voxels; `None` when there are none.
    pub bbox: Option<([i32; 3], [i32; 3])>,
    pub value_min: Option<f32>,
    pub value_max: Option<f32>,
    pub value_sum: f64,
    pub value_sum_sq: f64,
    /// Active voxels whose value is NaN or infinite (tiles weighted); excluded from min/max/sums.
    pub non_finite: u64,
    /// First active non-finite voxel (a tile's origin for tiles).
    pub first_non_finite: Option<[i32; 3]>,
}

impl FloatGrid {
    pub fn leaf_values(&self, i: usize) -> &[f32] {
        &self.values[i * LEAF_VOXELS..(i + 1) * LEAF_VOXELS]
    }

    /// Calls `f(ijk, value)` for every active voxel inside leaves (tiles are not expanded).
    pub fn for_each_active_leaf_voxel(&self, mut f: impl FnMut([i32; 3], f32)) {
        for (li, leaf) in self.leaves.iter().enumerate() {
            let vals = self.leaf_values(li);
            for (w, &word) in leaf.mask.iter().enumerate() {
                if word == u64::MAX {
                    // A fully active row of 64 voxels: no bit scanning.
                    for (b, &v) in vals[w * 64..w * 64 + 64].iter().enumerate() {
                        f(leaf_voxel(leaf.origin, w * 64 + b), v);
                    }
                    continue;
                }
                let mut bits = word;
                while bits != 0 {
                    let b = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let n = w * 64 + b;
                    f(leaf_voxel(leaf.origin, n), vals[n]);
                }
            }
        }
    }

    pub fn stats(&self) -> GridStats {
        let mut s = GridStats {
            leaf_count: self.leaves.len() as u64,
            ..Default::default()
        };
        let mut lo = [i32::MAX; 3];
        let mut hi = [i32::MIN; 3];
        let mut acc = ValueAcc::default();
        for (li, leaf) in self.leaves.iter().enumerate() {
            let n = leaf.active_count() as u64;
            if n == 0 {
                continue;
            }
            s.active_voxels += n;
            let vals = self.leaf_values(li);
            for (w, &word) in leaf.mask.iter().enumerate() {
                let mut bits = word;
                while bits != 0 {
                    let k = w * 64 + bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    acc.add(vals[k], 1, || leaf_voxel(leaf.origin, k));
                }
            }
            let (l, h) = leaf_bbox(leaf);
            for a in 0..3 {
                lo[a] = lo[a].min(leaf.origin[a] + l[a]);
                hi[a] = hi[a].max(leaf.origin[a] + h[a]);
            }
        }
        for t in &self.tiles {
            if !t.active {
                continue;
            }
            let n = t.level.voxels();
            s.active_voxels = s.active_voxels.saturating_add(n);
            s.active_tiles += 1;
            s.active_tiles_by_level[t.level as usize - 1] += 1;
            acc.add(t.value, n, || t.origin);
            for a in 0..3 {
                lo[a] = lo[a].min(t.origin[a]);
                hi[a] = hi[a].max(t.origin[a] + (t.level.dim() - 1));
            }
        }
        if s.active_voxels > 0 {
            s.bbox = Some((lo, hi));
        }
        if acc.any_finite {
            s.value_min = Some(acc.min);
            s.value_max = Some(acc.max);
        }
        s.value_sum = acc.sum;
        s.value_sum_sq = acc.sum_sq;
        s.non_finite = acc.non_finite;
        s.first_non_finite = acc.first_non_finite;
        s
    }

    /// An index for `value_at` lookups (build once, query many times).
    pub fn lookup(&self) -> GridLookup<'_> {
        let mut leaves = HashMap::with_capacity(self.leaves.len());
        for (i, l) in self.leaves.iter().enumerate() {
            leaves.insert(l.origin, i as u32);
        }
        let mut tiles = HashMap::with_capacity(self.tiles.len());
        for (i, t) in self.tiles.iter().enumerate() {
            tiles.insert((t.level, t.origin), i as u32);
        }
        GridLookup {
            grid: self,
            leaves,
            tiles,
        }
    }
}

/// Index coordinate of voxel `n` of a leaf at `origin`.
#[inline]
pub fn leaf_voxel(origin: [i32; 3], n: usize) -> [i32; 3] {
    [
        origin[0] + (n >> 6) as i32,
        origin[1] + ((n >> 3) & 7) as i32,
        origin[2] + (n & 7) as i32,
    ]
}

/// Running min/max/sums over active values; non-finite values are counted apart.
struct ValueAcc {
    min: f32,
    max: f32,
    any_finite: bool,
    sum: f64,
    sum_sq: f64,
    non_finite: u64,
    first_non_finite: Option<[i32; 3]>,
}

impl Default for ValueAcc {
    fn default() -> Self {
        ValueAcc {
            min: f32::INFINITY,
            max: f32::NEG_INFINITY,
            any_finite: false,
            sum: 0.0,
            sum_sq: 0.0,
            non_finite: 0,
            first_non_finite: None,
        }
    }
}

impl ValueAcc {
    #[inline]
    fn add(&mut self, v: f32, n: u64, at: impl FnOnce() -> [i32; 3]) {
        if v.is_finite() {
            self.any_finite = true;
            self.min = self.min.min(v);
            self.max = self.max.max(v);
            let d = v as f64 * n as f64;
            self.sum += d;
            self.sum_sq += d * v as f64;
        } else {
            self.non_finite += n;
            if self.first_non_finite.is_none() {
                self.first_non_finite = Some(at());
            }
        }
    }
}

/// Inclusive bounds of the active voxels of a leaf, relative to its origin (mask must be non-empty).
fn leaf_bbox(leaf: &Leaf) -> ([i32; 3], [i32; 3]) {
    let mut lo = [7; 3];
    let mut hi = [0; 3];
    for (w, &word) in leaf.mask.iter().enumerate() {
        if word == 0 {
            continue;
        }
        // Word w covers x = w, y = 0..8 (8 bits each), z = bit & 7.
        let x = w as i32;
        lo[0] = lo[0].min(x);
        hi[0] = hi[0].max(x);
        let mut zs = 0u8;
        for y in 0..8 {
            let byte = (word >> (y * 8)) as u8;
            if byte != 0 {
                lo[1] = lo[1].min(y);
                hi[1] = hi[1].max(y);
                zs |= byte;
            }
        }
        lo[2] = lo[2].min(zs.trailing_zeros() as i32);
        hi[2] = hi[2].max(7 - zs.leading_zeros() as i32);
    }
    (lo, hi)
}

/// Value lookups by index coordinate with OpenVDB's semantics: leaf value, else the tile that
/// covers the voxel, else the background.
pub struct GridLookup<'g> {
    grid: &'g FloatGrid,
    leaves: HashMap<[i32; 3], u32>,
    tiles: HashMap<(TileLevel, [i32; 3]), u32>,
}

impl GridLookup<'_> {
    /// `(value, active)` at `ijk`.
    pub fn value_at(&self, ijk: [i32; 3]) -> (f32, bool) {
        let o8 = ijk.map(|c| c & !7);
        if let Some(&li) = self.leaves.get(&o8) {
            let n = leaf_offset(ijk);
            let leaf = &self.grid.leaves[li as usize];
            return (self.grid.leaf_values(li as usize)[n], leaf.is_active(n));
        }
        for level in [TileLevel::L8, TileLevel::L128, TileLevel::L4096] {
            let o = ijk.map(|c| c & !(level.dim() - 1));
            if let Some(&ti) = self.tiles.get(&(level, o)) {
                let t = &self.grid.tiles[ti as usize];
                return (t.value, t.active);
            }
        }
        (self.grid.background, false)
    }
}
