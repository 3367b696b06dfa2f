//! What the same frames would cost as NanoVDB grids on the GPU — the comparison every cook
//! states beside its own GPU bytes. A NanoVDB grid is one flat buffer that a renderer uploads as
//! it is, so its size is its GPU footprint; `nanovdb_convert` (OpenVDB 10, NanoVDB 32.4) writes
//! one grid per frame, nothing shared between frames.
//!
//! The size is a model of that layout, computed from the source grids: a grid and tree header,
//! the root table, every upper (32³) and lower (16³) internal node at its fixed size, and every
//! OpenVDB leaf — float leaves at a fixed size, FpN leaves at the bit width NanoVDB's own oracle
//! picks for them under an absolute tolerance (`nanovdb_convert --fpN -a E`): the first of 1, 2,
//! 4, 8 bits whose quantization of all 512 values is within E, else 16. The quantization is
//! NanoVDB's arithmetic, in f32, without dithering. `tests/nanovdb.rs` checks the model against
//! the grid size `nanovdb_convert` writes, byte for byte, on real files.

use std::collections::BTreeSet;

use vdbcook_vdb::{FloatGrid, TileLevel};

/// `GridData` (672) and `TreeData` (64).
pub const GRID_HEADER_BYTES: u64 = 672 + 64;
/// `RootData` without its table (float and FpN grids; 96 for double grids).
pub const ROOT_BYTES: u64 = 64;
pub const DOUBLE_ROOT_BYTES: u64 = 96;
/// One root table entry (an upper node or a root tile).
pub const ROOT_ENTRY_BYTES: u64 = 32;
/// `InternalNode<5>`: 32³ table entries of 8 bytes, two masks, bounds and statistics.
pub const UPPER_BYTES: u64 = 270_400;
/// `InternalNode<4>`: 16³ entries.
pub const LOWER_BYTES: u64 = 33_856;
/// A float leaf: 512 values, mask, bounds and statistics.
pub const FLOAT_LEAF_BYTES: u64 = 2144;
/// A double leaf (`nanovdb_convert` keeps a double grid double, `--fpN` or not).
pub const DOUBLE_LEAF_BYTES: u64 = 4224;
/// An FpN leaf's header; its values take `64·bits` bytes more.
pub const FPN_LEAF_HEADER_BYTES: u64 = 96;

/// The FpN bit widths below 16, NanoVDB's `logBitWidth` 0..=3.
const FPN_BITS: [u64; 4] = [1, 2, 4, 8];

/// NanoVDB's view of a set of grids (the frames of one channel): fixed bytes (headers, root
/// tables, internal nodes), the leaves of double and float grids and, where measured,
/// per leaf the smallest tolerance each FpN bit width meets.
///
/// Node counts come from the leaves and tiles the reader keeps (active tiles, and inactive ones
/// off the background): an internal node holding nothing else, or a background root tile, that
/// an unpruned file keeps would be missed. None of the fixtures or samples has one
/// (`tests/nanovdb.rs`).
#[derive(Clone, Debug, Default)]
pub struct NanoGrids {
    pub grids: u64,
    /// Headers, root tables and internal nodes of every grid.
    pub fixed_bytes: u64,
    /// Leaves of double grids (double whatever the tolerance).
    pub double_leaves: u64,
    /// Leaves of float grids (FpN or float, by the tolerance).
    pub float_leaves: u64,
    /// Per measured float leaf, for 1, 2, 4 and 8 bits: the largest quantization error of its
    /// 512 values (`f32::INFINITY` where a value is not finite). A constant leaf is all zeros.
    pub leaf_errors: Vec<[f32; 4]>,
}

impl NanoGrids {
    /// Adds one source grid (before anything is changed in it: inactive values count, as
    /// NanoVDB quantizes all 512 values of a leaf). `fpn`: measure its leaves for FpN (a lossy
    /// cook compares with FpN; a lossless one with float grids, which needs only the counts).
    pub fn add_grid(&mut self, grid: &FloatGrid, fpn: bool) {
        let mut lower = BTreeSet::new();
        let mut upper = BTreeSet::new();
        let mut root_tiles = 0u64;
        let key = |o: [i32; 3], span: i32| o.map(|v| v.div_euclid(span));
        for leaf in &grid.leaves {
            lower.insert(key(leaf.origin, 128));
            upper.insert(key(leaf.origin, 4096));
        }
        for t in &grid.tiles {
            match t.level {
                TileLevel::L8 => {
                    lower.insert(key(t.origin, 128));
                    upper.insert(key(t.origin, 4096));
                }
                TileLevel::L128 => {
                    upper.insert(key(t.origin, 4096));
                }
                TileLevel::L4096 => root_tiles += 1,
            }
        }
        let double = grid.converted_from_double;
        self.grids += 1;
        self.fixed_bytes += GRID_HEADER_BYTES
            + if double {
                DOUBLE_ROOT_BYTES
            } else {
                ROOT_BYTES
            }
            + ROOT_ENTRY_BYTES * (upper.len() as u64 + root_tiles)
            + UPPER_BYTES * upper.len() as u64
            + LOWER_BYTES * lower.len() as u64;
        let leaves = grid.leaves.len() as u64;
        if double {
            self.double_leaves += leaves;
            return;
        }
        self.float_leaves += leaves;
        if fpn {
            self.leaf_errors.extend(
                grid.values
                    .chunks_exact(512)
                    .take(grid.leaves.len())
                    .map(leaf_errors),
            );
        }
    }

    pub fn merge(&mut self, other: NanoGrids) {
        self.grids += other.grids;
        self.fixed_bytes += other.fixed_bytes;
        self.double_leaves += other.double_leaves;
        self.float_leaves += other.float_leaves;
        self.leaf_errors.extend(other.leaf_errors);
    }

    /// Bytes as float grids (`nanovdb_convert` without options: exact).
    pub fn float_bytes(&self) -> u64 {
        self.fixed_bytes
            + DOUBLE_LEAF_BYTES * self.double_leaves
            + FLOAT_LEAF_BYTES * self.float_leaves
    }

    /// Bytes as FpN grids under the absolute tolerance `tolerance` (`--fpN -a tolerance`);
    /// `None` unless every float leaf was measured ([`NanoGrids::add_grid`]'s `fpn`).
    pub fn fpn_bytes(&self, tolerance: f32) -> Option<u64> {
        (self.leaf_errors.len() as u64 == self.float_leaves).then(|| {
            self.fixed_bytes
                + DOUBLE_LEAF_BYTES * self.double_leaves
                + self
                    .leaf_errors
                    .iter()
                    .map(|e| FPN_LEAF_HEADER_BYTES + 64 * fpn_bits(e, tolerance))
                    .sum::<u64>()
        })
    }
}

/// The bit width NanoVDB's FpN picks for a leaf with these errors under `tolerance`.
fn fpn_bits(errors: &[f32; 4], tolerance: f32) -> u64 {
    errors
        .iter()
        .zip(FPN_BITS)
        .find(|(e, _)| **e <= tolerance)
        .map_or(16, |(_, b)| b)
}

/// One leaf's largest error at 1, 2, 4 and 8 bits, quantized as NanoVDB does: over the leaf's
/// `[min, max]` (NaN values skipped, as its comparisons skip them),
/// `code = u32(encode·(v − min) + 0.5)`, `approx = code·decode + min`, in f32. A leaf whose range is not positive (constant,
/// or nothing but NaN) is stored at 1 bit without a check; otherwise a NaN value fails every
/// width (16 bits).
// `max(0).min(256)`, not `clamp`: `clamp` keeps a NaN, `f32::max` turns it into 0.
#[allow(clippy::manual_clamp)]
fn leaf_errors(values: &[f32]) -> [f32; 4] {
    let (min, max) = values.iter().fold((f32::MAX, -f32::MAX), |(lo, hi), &v| {
        (if v < lo { v } else { lo }, if v > hi { v } else { hi })
    });
    let range = max - min;
    // `!(range > 0)` as NanoVDB writes it: a NaN range too.
    if range.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return [0.0; 4];
    }
    if !range.is_finite() || values.iter().any(|v| !v.is_finite()) {
        return [f32::INFINITY; 4];
    }
    FPN_BITS.map(|bits| {
        let mask = ((1u32 << bits) - 1) as f32;
        let (encode, decode) = (mask / range, range / mask);
        if !encode.is_finite() {
            // A range so small that `mask / range` overflows: NanoVDB's float-to-integer
            // conversion (gcc, x86-64) then gives code 0 for every value, so approx = min.
            return values.iter().fold(0.0f32, |m, &v| m.max(v - min));
        }
        // Eight independent maxima (lanes the compiler can keep in vector registers), then one.
        let mut lanes = [0.0f32; 8];
        for chunk in values.chunks_exact(8) {
            for (worst, &v) in lanes.iter_mut().zip(chunk) {
                // v is finite and in [min, max] and encode finite, so x is in
                // [0.5, mask + 0.5 + ε]; the bounds (which also map a NaN to 0) only make the
                // truncation below sound for any input. It truncates as NanoVDB's `uint32_t(x)`.
                let x = (encode * (v - min) + 0.5).max(0.0).min(256.0);
                // SAFETY: x is in [0, 256] (`f32::max` returns 0 for a NaN x), so it is finite
                // and fits an i32.
                let code = unsafe { x.to_int_unchecked::<i32>() };
                let e = (v - (code as f32 * decode + min)).abs();
                *worst = if e > *worst { e } else { *worst };
            }
        }
        lanes.into_iter().fold(0.0, f32::max)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_widths_follow_the_tolerance() {
        // A ramp over [0, 1]: 1 bit is half the range off, 8 bits half of 1/255.
        let ramp: Vec<f32> = (0..512).map(|i| i as f32 / 511.0).collect();
        let e = leaf_errors(&ramp);
        assert!(e[0] > 0.49 && e[0] <= 0.5, "{e:?}");
        assert!(e[3] <= 0.5 / 255.0 + 1e-7, "{e:?}");
        assert!(e.windows(2).all(|w| w[0] > w[1]), "{e:?}");
        assert_eq!(fpn_bits(&e, 0.5), 1);
        assert_eq!(fpn_bits(&e, 0.01), 8);
        assert_eq!(fpn_bits(&e, 1e-6), 16);
        assert_eq!(fpn_bits(&leaf_errors(&[0.3; 512]), 0.0), 1);
    }

    #[test]
    fn nan_follows_nanovdbs_comparisons() {
        // NaN is skipped by the min/max: a constant leaf with a NaN is still 1 bit (no check),
        // a leaf with a range and a NaN fails every width.
        let mut c = vec![0.3f32; 512];
        c[7] = f32::NAN;
        assert_eq!(fpn_bits(&leaf_errors(&c), 0.0), 1);
        assert_eq!(fpn_bits(&leaf_errors(&[f32::NAN; 512]), 0.0), 1);
        c[8] = 0.5;
        assert_eq!(fpn_bits(&leaf_errors(&c), 1.0), 16);
    }

    #[test]
    fn a_range_too_small_to_invert_quantizes_to_the_minimum() {
        // 255 / 1e-38 overflows f32: every value is read back as the minimum.
        let mut v = vec![0.0f32; 512];
        v[3] = 1e-38;
        let e = leaf_errors(&v);
        assert_eq!(e[0], 0.0, "1 bit still resolves it: {e:?}");
        assert_eq!(e[3], 1e-38, "{e:?}");
        assert_eq!(fpn_bits(&e, 0.0), 1);
    }
}
