//! Build stage: one source frame → its non-empty 128³ regions, each either a constant tile or a
//! list of leaves (slot, tile value or 8³ brick in asset voxel order). Runs in parallel per frame;
//! nothing here depends on other frames, so the result is the same at any thread count.

use std::collections::BTreeMap;

use vdbcook_asset::{BRICK_VOXELS, L2_SPAN};
use vdbcook_vdb::{FloatGrid, TileLevel};

use crate::nanovdb::NanoGrids;

/// One leaf of a region: its slot `x + 16·(y + 16·z)` inside the L2 node and its content.
pub struct BuiltLeaf {
    pub slot: u16,
    pub content: LeafContent,
}

pub enum LeafContent {
    /// All 512 voxels have this value (not the background).
    Tile(f32),
    /// Brick `index` of the frame's `bricks` (values in voxel order `64·x + 8·y + z`, inactive
    /// voxels set to the background) and a hash of the value bits.
    Brick { index: u32, hash: u64 },
}

pub enum Region {
    /// The whole 128³ region has this value.
    Tile(f32),
    /// Leaves sorted by slot.
    Leaves(Vec<BuiltLeaf>),
}

pub struct BuiltFrame {
    /// The frame's bricks, 512 values each, in one allocation.
    pub bricks: Vec<f32>,
    /// Non-empty regions by their 128-aligned source origin (sorted: deterministic).
    pub regions: BTreeMap<[i32; 3], Region>,
    pub active_voxels: u64,
    /// Finite active value range of the source.
    pub value_range: Option<[f32; 2]>,
    /// The source grid as NanoVDB would store it (the comparison in the cook's report).
    pub nano: NanoGrids,
}

/// How NaN/Inf active values are handled.
#[derive(Clone, Copy)]
pub struct NonFinite {
    pub replace_with: Option<f32>,
    /// Whether the error may suggest `--replace-non-finite` (the command accepts it).
    pub hint: bool,
}

pub fn region_of(c: [i32; 3]) -> [i32; 3] {
    c.map(|v| v & !(L2_SPAN - 1))
}

fn slot_of(c: [i32; 3]) -> u16 {
    let l = c.map(|v| ((v & (L2_SPAN - 1)) >> 3) as u16);
    l[0] + 16 * (l[1] + 16 * l[2])
}

/// Builds one frame. `Err` carries a message (NaN/Inf without a replacement).
/// Consumes the grid: its value array becomes the frame's brick storage (inactive voxels are set
/// to the background in place), so no voxel is copied.
/// `nano_fpn`: measure the leaves for the NanoVDB FpN comparison (a lossy cook's report).
pub fn build_frame(grid: FloatGrid, nf: NonFinite, nano_fpn: bool) -> Result<BuiltFrame, String> {
    let bg = grid.background;
    let mut nano = NanoGrids::default();
    nano.add_grid(&grid, nano_fpn);
    // One pass for the source statistics and the non-finite check (cheaper than `grid.stats()`).
    let mut active_voxels = 0u64;
    let mut range = [f32::INFINITY, f32::NEG_INFINITY];
    let mut non_finite = 0u64;
    let mut first_bad = None;
    for (li, leaf) in grid.leaves.iter().enumerate() {
        active_voxels += leaf.active_count() as u64;
        let vals = grid.leaf_values(li);
        let full = leaf.mask.iter().all(|&w| w == u64::MAX);
        if full && vals.iter().all(|v| v.is_finite()) {
            // Fully active, all finite (the common case): a loop the compiler vectorises.
            let (lo, hi) = vals.iter().fold((range[0], range[1]), |(lo, hi), &v| {
                (if v < lo { v } else { lo }, if v > hi { v } else { hi })
            });
            range = [lo, hi];
            continue;
        }
        if vals.iter().all(|v| v.is_finite()) {
            // Partially active, all finite: visit the active bits with the range in registers.
            let (mut lo, mut hi) = (range[0], range[1]);
            for (w, &word) in leaf.mask.iter().enumerate() {
                let mut bits = word;
                while bits != 0 {
                    let v = vals[w * 64 + bits.trailing_zeros() as usize];
                    bits &= bits - 1;
                    lo = if v < lo { v } else { lo };
                    hi = if v > hi { v } else { hi };
                }
            }
            range = [lo, hi];
            continue;
        }
        for (w, &word) in leaf.mask.iter().enumerate() {
            let mut bits = word;
            while bits != 0 {
                let n = w * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let v = vals[n];
                if v.is_finite() {
                    range = [range[0].min(v), range[1].max(v)];
                } else {
                    non_finite += 1;
                    first_bad.get_or_insert_with(|| vdbcook_vdb::leaf_voxel(leaf.origin, n));
                }
            }
        }
    }
    for t in grid.tiles.iter().filter(|t| t.active) {
        active_voxels += t.level.voxels();
        if t.value.is_finite() {
            range = [range[0].min(t.value), range[1].max(t.value)];
        } else {
            non_finite += t.level.voxels();
            first_bad.get_or_insert(t.origin);
        }
    }
    if non_finite > 0 && nf.replace_with.is_none() {
        return Err(format!(
            "{non_finite} active voxel(s) are NaN or infinite (first at index {:?}); fix the source{}",
            first_bad.unwrap_or_default(),
            if nf.hint {
                " or pass --replace-non-finite VALUE"
            } else {
                ""
            }
        ));
    }
    let fix = |v: f32| {
        if v.is_finite() {
            v
        } else {
            nf.replace_with.unwrap_or(v)
        }
    };
    let mut regions: BTreeMap<[i32; 3], Region> = BTreeMap::new();
    let leaves_of =
        |origin: [i32; 3], leaf: BuiltLeaf, regions: &mut BTreeMap<[i32; 3], Region>| match regions
            .entry(region_of(origin))
            .or_insert_with(|| Region::Leaves(Vec::new()))
        {
            Region::Leaves(v) => v.push(leaf),
            Region::Tile(_) => {}
        };
    let FloatGrid {
        leaves,
        values: mut bricks,
        tiles,
        ..
    } = grid;
    for (li, leaf) in leaves.iter().enumerate() {
        let values = &mut bricks[li * BRICK_VOXELS..(li + 1) * BRICK_VOXELS];
        // Bricks keep OpenVDB's voxel order (n = 64·x + 8·y + z); inactive voxels become bg.
        if leaf.mask.iter().any(|&w| w != u64::MAX) {
            for (w, &word) in leaf.mask.iter().enumerate() {
                let mut off = !word;
                while off != 0 {
                    values[w * 64 + off.trailing_zeros() as usize] = bg;
                    off &= off - 1;
                }
            }
        }
        if non_finite > 0 {
            for v in values.iter_mut() {
                *v = fix(*v);
            }
        }
        let first = values[0].to_bits();
        if values.iter().all(|v| v.to_bits() == first) {
            if values[0] != bg {
                leaves_of(
                    leaf.origin,
                    BuiltLeaf {
                        slot: slot_of(leaf.origin),
                        content: LeafContent::Tile(values[0]),
                    },
                    &mut regions,
                );
            }
            continue;
        }
        let hash = xxhash_rust::xxh3::xxh3_64(bytemuck::cast_slice(&values[..]));
        let index = li as u32;
        leaves_of(
            leaf.origin,
            BuiltLeaf {
                slot: slot_of(leaf.origin),
                content: LeafContent::Brick { index, hash },
            },
            &mut regions,
        );
    }
    for t in tiles.iter().filter(|t| t.active) {
        let v = fix(t.value);
        if v == bg {
            continue;
        }
        match t.level {
            TileLevel::L8 => leaves_of(
                t.origin,
                BuiltLeaf {
                    slot: slot_of(t.origin),
                    content: LeafContent::Tile(v),
                },
                &mut regions,
            ),
            TileLevel::L128 => {
                regions.insert(t.origin, Region::Tile(v));
            }
            TileLevel::L4096 => {
                for x in 0..32 {
                    for y in 0..32 {
                        for z in 0..32 {
                            let o = [
                                t.origin[0] + x * L2_SPAN,
                                t.origin[1] + y * L2_SPAN,
                                t.origin[2] + z * L2_SPAN,
                            ];
                            regions.insert(o, Region::Tile(v));
                        }
                    }
                }
            }
        }
    }
    for r in regions.values_mut() {
        if let Region::Leaves(v) = r {
            v.sort_by_key(|l| l.slot);
        }
    }
    Ok(BuiltFrame {
        bricks,
        regions,
        active_voxels,
        value_range: (range[0] <= range[1]).then_some(range),
        nano,
    })
}
