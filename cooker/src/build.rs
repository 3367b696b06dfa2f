//! Build stage: one source frame → its non-empty 128³ regions, each either a constant tile or a
//! list of leaves (slot, tile value or 8³ brick in asset voxel order). Runs in parallel per frame;
//! nothing here depends on other frames, so the result is the same at any thread count.

use std::collections::BTreeMap;

use vdbcook_asset::{BRICK_VOXELS, L2_SPAN};
use vdbcook_vdb::{FloatGrid, TileLevel};

/// One leaf of a region: its slot `x + 16·(y + 16·z)` inside the L2 node and its content.
pub struct BuiltLeaf {
    pub slot: u16,
    pub content: LeafContent,
}

pub enum LeafContent {
    /// All 512 voxels have this value (not the background).
    Tile(f32),
    /// Values in asset voxel order (`x + 8·(y + 8·z)`), the active mask in the same order, and
    /// a hash of the value bits.
    Brick {
        values: Box<[f32; BRICK_VOXELS]>,
        active: [u64; 8],
        hash: u64,
    },
}

pub enum Region {
    /// The whole 128³ region has this value.
    Tile(f32),
    /// Leaves sorted by slot.
    Leaves(Vec<BuiltLeaf>),
}

pub struct BuiltFrame {
    /// Non-empty regions by their 128-aligned source origin (sorted: deterministic).
    pub regions: BTreeMap<[i32; 3], Region>,
    pub active_voxels: u64,
    /// Finite active value range of the source.
    pub value_range: Option<[f32; 2]>,
}

/// How NaN/Inf active values are handled.
#[derive(Clone, Copy)]
pub struct NonFinite {
    pub replace_with: Option<f32>,
}

pub fn region_of(c: [i32; 3]) -> [i32; 3] {
    c.map(|v| v & !(L2_SPAN - 1))
}

fn slot_of(c: [i32; 3]) -> u16 {
    let l = c.map(|v| ((v & (L2_SPAN - 1)) >> 3) as u16);
    l[0] + 16 * (l[1] + 16 * l[2])
}

/// Builds one frame. `Err` carries a message (NaN/Inf without a replacement).
pub fn build_frame(grid: &FloatGrid, bg: f32, nf: NonFinite) -> Result<BuiltFrame, String> {
    let stats = grid.stats();
    if stats.non_finite > 0 && nf.replace_with.is_none() {
        return Err(format!(
            "{} active voxel(s) are NaN or infinite (first at index {:?}); fix the source or pass --replace-non-finite VALUE",
            stats.non_finite,
            stats.first_non_finite.unwrap_or_default()
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
    for (li, leaf) in grid.leaves.iter().enumerate() {
        let src = grid.leaf_values(li);
        let mut values = Box::new([bg; BRICK_VOXELS]);
        let mut active = [0u64; 8];
        // Source order is x-slowest (n = x·64 + y·8 + z); the asset's is x-fastest.
        for (w, &word) in leaf.mask.iter().enumerate() {
            let mut bits = word;
            while bits != 0 {
                let n = w * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let (x, y, z) = (n >> 6, (n >> 3) & 7, n & 7);
                let a = x + 8 * (y + 8 * z);
                values[a] = fix(src[n]);
                active[a >> 6] |= 1 << (a & 63);
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
        leaves_of(
            leaf.origin,
            BuiltLeaf {
                slot: slot_of(leaf.origin),
                content: LeafContent::Brick {
                    values,
                    active,
                    hash,
                },
            },
            &mut regions,
        );
    }
    for t in grid.tiles.iter().filter(|t| t.active) {
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
        regions,
        active_voxels: stats.active_voxels,
        value_range: stats.value_min.zip(stats.value_max).map(|(a, b)| [a, b]),
    })
}
