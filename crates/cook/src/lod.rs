//! Level of detail (`cook --lod`): after the full-resolution frames are in the pool, each frame
//! (every channel of it) gains coarser levels, each a 2× box-filtered reduction of the one before, built from the
//! pool's exact (pre-encode) values and added to the same pool as more root sets, so their
//! bricks are deduplicated, clustered and encoded with the rest under the same error budget.
//! Secondary rays (the light volume's density pass, shadow and sky depths) read the level whose
//! voxel matches their footprint with one read instead of 8^k.
//!
//! Level `k`'s voxel `i` (asset index) is the mean of level `k − 1`'s voxels `2i + {0,1}³`, the
//! background standing in where nothing is stored. Levels are placed in the pool's source
//! coordinates as `index_offset + i`, so they lie inside the full-resolution extent and its
//! root grid (see the asset crate's "Level of detail").

use std::collections::BTreeMap;

use vdbcook_asset::{BRICK_VOXELS, EMPTY, L2_SPAN, L2_WORDS, TILE_BIT};

use crate::build::{region_of, BuiltFrame, BuiltLeaf, LeafContent, Region};
use crate::options::Levels;
use crate::pool::Pool;

/// Levels below full resolution until an extent of `root_dims` regions fits one brick.
pub fn levels_to_one_brick(root_dims: [u32; 3]) -> u32 {
    let span = root_dims.iter().max().copied().unwrap_or(1) as u64 * L2_SPAN as u64;
    let mut k = 0;
    while (span >> k) > 8 {
        k += 1;
    }
    k
}

/// How many levels `want` gives on an extent of `root_dims` regions.
pub fn resolve(want: Levels, root_dims: [u32; 3]) -> u32 {
    let full = levels_to_one_brick(root_dims);
    match want {
        Levels::All => full,
        Levels::Count(n) => n.min(full),
    }
}

/// One 8³ leaf of a level: background, a constant, or 512 values (voxel order `64x + 8y + z`).
#[derive(Clone, Copy)]
enum Leaf<'a> {
    Tile(f32),
    Brick(&'a [f32]),
}

impl Leaf<'_> {
    #[inline]
    fn at(&self, v: usize) -> f32 {
        match self {
            Leaf::Tile(t) => *t,
            Leaf::Brick(b) => b[v],
        }
    }
}

/// Every stored leaf of channel `c` of pool frame `pf` by asset-index origin (8-aligned), a
/// tiled region expanded into its 4096 leaves; slots where the channel is its background
/// (`EMPTY`) are left out.
fn leaves_of<'a>(
    pool: &'a Pool,
    pf: usize,
    c: usize,
    offset: [i32; 3],
) -> Vec<([i32; 3], Leaf<'a>)> {
    let n = pool.channels;
    let mut out = Vec::new();
    for &(origin, e) in &pool.frames[pf] {
        let r = [0, 1, 2].map(|a| origin[a] - offset[a]);
        let at = |s: usize| {
            let l = [s % 16, (s / 16) % 16, s / 256];
            [0, 1, 2].map(|a| r[a] + 8 * l[a] as i32)
        };
        let leaf = |rf: u32| -> Leaf<'a> {
            if rf & TILE_BIT != 0 {
                Leaf::Tile(pool.tiles[(rf & !TILE_BIT) as usize])
            } else {
                let b = rf as usize * BRICK_VOXELS;
                Leaf::Brick(&pool.bricks[b..b + BRICK_VOXELS])
            }
        };
        if e == EMPTY {
            continue;
        }
        if e & TILE_BIT != 0 {
            let t = leaf(e);
            out.extend((0..L2_WORDS * 64).map(|s| (at(s), t)));
            continue;
        }
        let nd = e as usize;
        let refs = &pool.l2_refs[nd];
        let mut k = 0;
        for (w, &word) in pool.l2_masks[nd * L2_WORDS..(nd + 1) * L2_WORDS]
            .iter()
            .enumerate()
        {
            let mut bits = word;
            while bits != 0 {
                let s = w * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let rf = refs[k * n + c];
                if rf != EMPTY {
                    out.push((at(s), leaf(rf)));
                }
                k += 1;
            }
        }
    }
    out
}

/// Every leaf of a frame built by [`reduce`] and not added to the pool (a level `--lod-from`
/// skips), as [`leaves_of`] gives a pool frame's.
fn leaves_of_built(frame: &BuiltFrame, offset: [i32; 3]) -> Vec<([i32; 3], Leaf<'_>)> {
    let mut out = Vec::new();
    for (origin, region) in &frame.regions {
        let r = [0, 1, 2].map(|a| origin[a] - offset[a]);
        let at = |s: usize| {
            let l = [s % 16, (s / 16) % 16, s / 256];
            [0, 1, 2].map(|a| r[a] + 8 * l[a] as i32)
        };
        match region {
            Region::Tile(v) => out.extend((0..L2_WORDS * 64).map(|s| (at(s), Leaf::Tile(*v)))),
            Region::Leaves(leaves) => out.extend(leaves.iter().map(|l| {
                let leaf = match l.content {
                    LeafContent::Tile(v) => Leaf::Tile(v),
                    LeafContent::Brick { index, .. } => {
                        let b = index as usize * BRICK_VOXELS;
                        Leaf::Brick(&frame.bricks[b..b + BRICK_VOXELS])
                    }
                };
                (at(l.slot as usize), leaf)
            })),
        }
    }
    out
}

/// The 2× reduction of a frame's `leaves` (asset-index space from `offset`; [`leaves_of`],
/// [`leaves_of_built`]), as a frame in the pool's source coordinates. `bg` is the value of
/// every voxel not stored.
fn reduce(leaves: Vec<([i32; 3], Leaf<'_>)>, offset: [i32; 3], bg: f32) -> BuiltFrame {
    // Child leaf origin → its eight parent leaves (octant x + 2y + 4z), `None` = background.
    let mut groups: BTreeMap<[i32; 3], [Option<Leaf<'_>>; 8]> = BTreeMap::new();
    for (p, leaf) in leaves {
        let child = p.map(|v| (v >> 4) << 3);
        let oct = [0, 1, 2]
            .iter()
            .map(|&a| (((p[a] >> 3) & 1) as usize) << a)
            .sum::<usize>();
        groups.entry(child).or_insert([None; 8])[oct] = Some(leaf);
    }
    let mut bricks: Vec<f32> = Vec::new();
    let mut regions: BTreeMap<[i32; 3], Vec<BuiltLeaf>> = BTreeMap::new();
    let mut values = [0f32; BRICK_VOXELS];
    for (child, parts) in groups {
        for x in 0..8 {
            for y in 0..8 {
                for z in 0..8 {
                    let oct = (x >> 2) | ((y >> 2) << 1) | ((z >> 2) << 2);
                    let mut sum = 0f64;
                    for dx in 0..2 {
                        for dy in 0..2 {
                            for dz in 0..2 {
                                let v = 64 * (2 * (x & 3) + dx)
                                    + 8 * (2 * (y & 3) + dy)
                                    + (2 * (z & 3) + dz);
                                sum += parts[oct].map_or(bg, |l| l.at(v)) as f64;
                            }
                        }
                    }
                    values[64 * x + 8 * y + z] = (sum / 8.0) as f32;
                }
            }
        }
        let first = values[0].to_bits();
        let content = if values.iter().all(|v| v.to_bits() == first) {
            if values[0] == bg {
                continue;
            }
            LeafContent::Tile(values[0])
        } else {
            let index = (bricks.len() / BRICK_VOXELS) as u32;
            bricks.extend_from_slice(&values);
            LeafContent::Brick {
                index,
                hash: xxhash_rust::xxh3::xxh3_64(bytemuck::cast_slice(&values[..])),
            }
        };
        let src = [0, 1, 2].map(|a| offset[a] + child[a]);
        let l = src.map(|v| ((v & (L2_SPAN - 1)) >> 3) as u16);
        regions.entry(region_of(src)).or_default().push(BuiltLeaf {
            slot: l[0] + 16 * (l[1] + 16 * l[2]),
            content,
        });
    }
    BuiltFrame {
        bricks,
        regions: regions
            .into_iter()
            .map(|(o, mut leaves)| {
                leaves.sort_by_key(|l| l.slot);
                (o, Region::Leaves(leaves))
            })
            .collect(),
        active_voxels: 0,
        value_range: None,
        // Coarser levels are the asset's own: NanoVDB has none to compare.
        nano: Default::default(),
    }
}

/// Adds levels `first..=last` of the pool's `frames` full-resolution frames, level by level
/// (each from the one before, every channel on its own with its background `bgs[c]`; levels
/// below `first` are built in memory and not added), without recording brick uses (the error
/// figures of the cook report are over the source's active voxels; the levels share the
/// encoder's budget). The pool then holds stored level `i ≥ 1` of frame `f` as pool frame
/// `f + i·frames`.
pub fn add_levels(
    pool: &mut Pool,
    frames: usize,
    (first, last): (u32, u32),
    offset: [i32; 3],
    bgs: &[f32],
) {
    let track = std::mem::replace(&mut pool.track_uses, false);
    // Per frame, the level below in memory, a frame per channel (`None`: it is in the pool).
    let mut below: Vec<Option<Vec<BuiltFrame>>> = (0..frames).map(|_| None).collect();
    for k in 1..=last {
        for (f, held) in below.iter_mut().enumerate() {
            let coarse: Vec<BuiltFrame> = (0..pool.channels)
                .map(|c| {
                    let leaves = match held {
                        Some(chans) => leaves_of_built(&chans[c], offset),
                        // Level k − 1 is full resolution or a stored level: pool frame
                        // f + i·frames.
                        None => leaves_of(
                            pool,
                            (k.saturating_sub(first) as usize) * frames + f,
                            c,
                            offset,
                        ),
                    };
                    reduce(leaves, offset, bgs[c])
                })
                .collect();
            if k >= first {
                pool.add_frame(&coarse.into_iter().map(Some).collect::<Vec<_>>());
                *held = None;
            } else {
                *held = Some(coarse);
            }
        }
    }
    pool.track_uses = track;
}

/// Pool bricks (pre-encode indices) the coarser levels use, their own and those they share
/// with full resolution (for the levels' error figure).
pub fn pool_bricks(pool: &Pool, frames: usize) -> Vec<u32> {
    let mut out = std::collections::BTreeSet::new();
    for &(_, e) in pool.frames[frames..].iter().flatten() {
        if e != EMPTY && e & TILE_BIT == 0 {
            out.extend(
                pool.l2_refs[e as usize]
                    .iter()
                    .filter(|&&r| r & TILE_BIT == 0),
            );
        }
    }
    out.into_iter().collect()
}

/// What the coarser levels of an asset add to it, as uploaded (the `cook --json` `lod` object
/// and `info`): the root sets and ranges of the levels, plus the L2 nodes, leaf refs, tiles and
/// bricks no full-resolution frame uses (shared ones are counted once, at full resolution).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Extra {
    pub l2_nodes: u64,
    pub bricks: u64,
    pub tiles: u64,
    /// Topology bytes (roots, root-set ranges, nodes, their refs, tiles).
    pub topology: u64,
    /// Atlas bytes (payload and per-brick ranges).
    pub atlas: u64,
}

pub fn extra(asset: &vdbcook_asset::Asset) -> Extra {
    use std::collections::BTreeSet;
    let (nf, nch) = (asset.frame_count(), asset.channel_count());
    let mut used: [(BTreeSet<u32>, BTreeSet<u32>, BTreeSet<u32>); 2] = Default::default();
    for set in 0..asset.root_set_count() {
        let u = &mut used[usize::from(set >= nf)];
        for &e in asset.frame_roots(set) {
            if e == EMPTY {
                continue;
            }
            if e & TILE_BIT != 0 {
                u.2.insert(e & !TILE_BIT);
                continue;
            }
            if !u.0.insert(e) {
                continue;
            }
            let n = e as usize;
            let count: usize = asset
                .l2_mask(n)
                .iter()
                .map(|w| w.count_ones() as usize)
                .sum();
            let base = asset.l2_base[n] as usize * nch;
            for &r in asset.l3_refs[base..base + count * nch]
                .iter()
                .filter(|&&r| r != EMPTY)
            {
                if r & TILE_BIT != 0 {
                    u.2.insert(r & !TILE_BIT);
                } else {
                    u.1.insert(r);
                }
            }
        }
    }
    let [full, coarse] = &used;
    let nodes: Vec<u32> = coarse.0.difference(&full.0).copied().collect();
    let refs: u64 = nodes
        .iter()
        .map(|&n| {
            asset
                .l2_mask(n as usize)
                .iter()
                .map(|w| w.count_ones() as u64)
                .sum::<u64>()
        })
        .sum();
    let bricks: Vec<u32> = coarse.1.difference(&full.1).copied().collect();
    let tiles = coarse.2.difference(&full.2).count() as u64;
    let sets = (asset.root_set_count() - nf) as u64;
    let node_bytes = (L2_WORDS * 8 + 4 + L2_WORDS * 2 + 8 * nch) as u64;
    Extra {
        l2_nodes: nodes.len() as u64,
        bricks: bricks.len() as u64,
        tiles,
        topology: sets * (asset.root_len() as u64 * 4 + 8 * nch as u64)
            + nodes.len() as u64 * node_bytes
            + refs * 4 * nch as u64
            + tiles * 4,
        atlas: bricks
            .iter()
            .map(|&b| asset.brick_format(b).0.bytes_per_brick() as u64 + 16)
            .sum(),
    }
}

/// One level of an asset, over all frames (`info`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LevelStats {
    /// Distinct bricks its leaves point at.
    pub bricks: u64,
    /// Of those, bricks no finer level uses, and their payload bytes.
    pub new_bricks: u64,
    pub new_atlas_bytes: u64,
}

pub fn per_level(asset: &vdbcook_asset::Asset) -> Vec<LevelStats> {
    use std::collections::BTreeSet;
    let mut seen = BTreeSet::new();
    (0..asset.level_count())
        .map(|k| {
            let mut here = BTreeSet::new();
            for f in 0..asset.frame_count() {
                for c in 0..asset.channel_count() {
                    asset.for_each_leaf_c(asset.lod_set(f, k), c, |_, r, _| {
                        if let vdbcook_asset::LeafRef::Brick(b) = r {
                            here.insert(b);
                        }
                    });
                }
            }
            let new: Vec<u32> = here.difference(&seen).copied().collect();
            let st = LevelStats {
                bricks: here.len() as u64,
                new_bricks: new.len() as u64,
                new_atlas_bytes: new
                    .iter()
                    .map(|&b| asset.brick_format(b).0.bytes_per_brick() as u64)
                    .sum(),
            };
            seen.extend(here);
            st
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_counts_reach_one_brick() {
        // 128 voxels → 8 after 4 halvings; 4096 → 8 after 9.
        assert_eq!(levels_to_one_brick([1, 1, 1]), 4);
        assert_eq!(levels_to_one_brick([2, 1, 1]), 5);
        assert_eq!(levels_to_one_brick([3, 1, 1]), 6);
        assert_eq!(levels_to_one_brick([32, 32, 32]), 9);
        assert_eq!(resolve(Levels::Count(2), [1, 1, 1]), 2);
        assert_eq!(resolve(Levels::Count(12), [1, 1, 1]), 4);
    }
}
