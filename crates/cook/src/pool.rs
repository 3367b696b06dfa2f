//! Pool stage: frames are added in order, all their channels at once; identical bricks (hash,
//! then a full bitwise compare) are stored once whichever channel they come from, constant leaves
//! and regions become tile values, and identical L2 nodes are shared across frames (a DAG over
//! time). Several channels share one topology: the union of their active regions, with one ref
//! per channel per leaf slot. The pool then lays out the roots, the nodes and their value ranges
//! as the asset stores them.

use std::collections::{BTreeSet, HashMap};

use vdbcook_asset::*;

use crate::build::{BuiltFrame, LeafContent, Region};

/// Keys of the dedup maps are already xxh3 hashes: use them as they are.
#[derive(Default, Clone, Copy)]
pub struct KeyIsHash;

pub struct PassThrough(u64);

impl std::hash::Hasher for PassThrough {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = self.0.rotate_left(8) ^ b as u64;
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = v;
    }
}

impl std::hash::BuildHasher for KeyIsHash {
    type Hasher = PassThrough;
    fn build_hasher(&self) -> PassThrough {
        PassThrough(0)
    }
}

#[derive(Default)]
pub struct Pool {
    /// Channels per leaf slot (1 for a single grid).
    pub channels: usize,
    /// Record `uses` (needed only when the payload is lossy, for error statistics).
    pub track_uses: bool,
    /// Unique bricks, 512 f32 each, in first-seen order.
    pub bricks: Vec<f32>,
    /// Per frame, every brick use (pool brick index) — for per-frame error statistics.
    pub uses: Vec<Vec<u32>>,
    brick_index: HashMap<u64, Vec<u32>, KeyIsHash>,
    pub tiles: Vec<f32>,
    tile_index: HashMap<u32, u32>,
    pub l2_masks: Vec<u64>,
    pub l2_refs: Vec<Vec<u32>>,
    l2_index: HashMap<u64, Vec<u32>, KeyIsHash>,
    /// Per frame: (region source origin, root entry).
    pub frames: Vec<Vec<([i32; 3], u32)>>,
    /// Per pool brick: a bit per channel that reads it.
    pub brick_channels: Vec<u8>,
    /// Constant 128³ regions of a multi-channel frame: the node per tuple of channel refs.
    tile_nodes: HashMap<Vec<u32>, u32>,
    /// Leaves that became bricks, over all frames, before dedup.
    pub source_bricks: u64,
    pub source_tiles: u64,
}

impl Pool {
    /// An empty pool of `channels` refs per leaf slot; `track_uses` records every brick use (for
    /// the error figures of a lossy cook).
    pub fn new(channels: usize, track_uses: bool) -> Self {
        Pool {
            channels,
            track_uses,
            ..Pool::default()
        }
    }

    pub fn brick_count(&self) -> usize {
        self.bricks.len() / BRICK_VOXELS
    }

    pub(crate) fn tile(&mut self, v: f32) -> u32 {
        let n = self.tiles.len() as u32;
        let idx = *self.tile_index.entry(v.to_bits()).or_insert(n);
        if idx == n {
            self.tiles.push(v);
        }
        TILE_BIT | idx
    }

    /// The pool index of a brick with these values (added if new), without recording a use.
    pub(crate) fn brick_unrecorded(&mut self, values: &[f32; BRICK_VOXELS], hash: u64) -> u32 {
        // Bitwise equality (so -0.0 and 0.0 differ, and NaN payloads are kept apart), as memcmp.
        let want: &[u32] = bytemuck::cast_slice(&values[..]);
        let bits = |s: &[f32]| -> bool { bytemuck::cast_slice::<f32, u32>(s) == want };
        let found = self.brick_index.get(&hash).and_then(|c| {
            c.iter().copied().find(|&b| {
                bits(&self.bricks[b as usize * BRICK_VOXELS..(b as usize + 1) * BRICK_VOXELS])
            })
        });
        let b = match found {
            Some(b) => b,
            None => {
                let b = self.brick_count() as u32;
                self.bricks.extend_from_slice(values);
                self.brick_index.entry(hash).or_default().push(b);
                b
            }
        };
        b
    }

    pub(crate) fn node(&mut self, mask: [u64; L2_WORDS], refs: Vec<u32>) -> u32 {
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        h.update(bytemuck::cast_slice(&mask));
        h.update(bytemuck::cast_slice(&refs));
        let hash = h.digest();
        if let Some(c) = self.l2_index.get(&hash) {
            for &n in c {
                if self.l2_masks[n as usize * L2_WORDS..(n as usize + 1) * L2_WORDS] == mask[..]
                    && self.l2_refs[n as usize] == refs
                {
                    return n;
                }
            }
        }
        let n = self.l2_refs.len() as u32;
        self.l2_masks.extend_from_slice(&mask);
        self.l2_refs.push(refs);
        self.l2_index.entry(hash).or_default().push(n);
        n
    }

    /// Adds the next frame's channels (frames in sequence order; `None`: the channel's grid is
    /// missing, cooked as its background). Per 128³ region of the union of the channels'
    /// regions, an L2 node over the union of their leaf slots with one ref per channel per slot
    /// (`EMPTY` where a channel is its own background there); `uses` gains one list per channel
    /// (channel `c` of frame `f` at `f·channels + c`) and every brick records the channels that
    /// read it. With one channel a constant region is a tile in the root, not a node: a
    /// single-grid asset is laid out as it always was.
    pub fn add_frame(&mut self, built: &[Option<BuiltFrame>]) {
        let n = self.channels;
        assert_eq!(built.len(), n, "one entry per channel");
        if self.track_uses {
            self.uses.extend((0..n).map(|_| Vec::new()));
        }
        let first_use = self.uses.len().saturating_sub(n);
        let origins: BTreeSet<[i32; 3]> = built
            .iter()
            .flatten()
            .flat_map(|b| b.regions.keys().copied())
            .collect();
        let mut entries = Vec::with_capacity(origins.len());
        for o in origins {
            let regs: Vec<Option<&Region>> = built
                .iter()
                .map(|b| b.as_ref().and_then(|b| b.regions.get(&o)))
                .collect();
            let has_leaves = regs.iter().any(|r| matches!(r, Some(Region::Leaves(_))));
            // Per channel, the ref of a constant over the whole region (`EMPTY` otherwise).
            let region_tile: Vec<u32> = regs
                .iter()
                .map(|r| match r {
                    Some(Region::Tile(v)) => self.tile(*v),
                    _ => EMPTY,
                })
                .collect();
            if !has_leaves {
                let node = if n == 1 {
                    region_tile[0]
                } else if let Some(&nd) = self.tile_nodes.get(&region_tile) {
                    nd
                } else {
                    // Every channel is a constant (or its background) over the region: a full
                    // node of tile refs, built once per tuple of values.
                    let refs: Vec<u32> = region_tile
                        .iter()
                        .copied()
                        .cycle()
                        .take(L2_SLOTS * n)
                        .collect();
                    let nd = self.node([u64::MAX; L2_WORDS], refs);
                    self.tile_nodes.insert(region_tile, nd);
                    nd
                };
                entries.push((o, node));
                continue;
            }
            let mut mask = [0u64; L2_WORDS];
            for r in &regs {
                match r {
                    Some(Region::Tile(_)) => mask = [u64::MAX; L2_WORDS],
                    Some(Region::Leaves(leaves)) => {
                        for l in leaves {
                            mask[l.slot as usize >> 6] |= 1 << (l.slot & 63);
                        }
                    }
                    None => {}
                }
            }
            let slots: usize = mask.iter().map(|w| w.count_ones() as usize).sum();
            let mut refs = Vec::with_capacity(slots * n);
            let mut cursor = vec![0usize; n];
            for s in 0..L2_SLOTS {
                if mask[s >> 6] & (1 << (s & 63)) == 0 {
                    continue;
                }
                for c in 0..n {
                    let r = match regs[c] {
                        None | Some(Region::Tile(_)) => region_tile[c],
                        Some(Region::Leaves(leaves)) => match leaves.get(cursor[c]) {
                            Some(l) if l.slot as usize == s => {
                                cursor[c] += 1;
                                match l.content {
                                    LeafContent::Tile(v) => {
                                        self.source_tiles += 1;
                                        self.tile(v)
                                    }
                                    LeafContent::Brick { index, hash } => {
                                        self.source_bricks += 1;
                                        let bricks = &built[c].as_ref().expect("has leaves").bricks;
                                        let i = index as usize * BRICK_VOXELS;
                                        let values: &[f32; BRICK_VOXELS] =
                                            bricks[i..i + BRICK_VOXELS].try_into().expect("512");
                                        let b = self.brick_unrecorded(values, hash);
                                        if self.track_uses {
                                            self.uses[first_use + c].push(b);
                                        }
                                        if self.brick_channels.len() <= b as usize {
                                            self.brick_channels.resize(b as usize + 1, 0);
                                        }
                                        self.brick_channels[b as usize] |= 1 << c;
                                        b
                                    }
                                }
                            }
                            _ => EMPTY,
                        },
                    };
                    refs.push(r);
                }
            }
            entries.push((o, self.node(mask, refs)));
        }
        self.frames.push(entries);
    }

    /// Points every brick ref at what the encoder made of its brick: `encoded` yields, per pool
    /// brick, the encoder's ref (a final brick index, or `TILE_BIT | k` for the `k`-th of
    /// `new_tiles`, which are appended to the pool's tiles). Returns the final ref per pool brick.
    pub fn apply_encoding(
        &mut self,
        encoded: impl Iterator<Item = u32>,
        new_tiles: &[f32],
    ) -> Vec<u32> {
        let first_new_tile = self.tiles.len() as u32;
        self.tiles.extend_from_slice(new_tiles);
        let remap: Vec<u32> = encoded
            .map(|r| {
                if r & TILE_BIT != 0 {
                    TILE_BIT | (first_new_tile + (r & !TILE_BIT))
                } else {
                    r
                }
            })
            .collect();
        for refs in self.l2_refs.iter_mut() {
            for r in refs.iter_mut() {
                if *r & TILE_BIT == 0 {
                    *r = remap[*r as usize];
                }
            }
        }
        remap
    }

    /// Every frame's root entries over the extent `(offset, root_dims)` of [`Pool::extent`]
    /// (`EMPTY` where a frame has no region).
    pub fn roots(&self, offset: [i32; 3], root_dims: [u32; 3]) -> Vec<u32> {
        let root_len = root_dims.iter().map(|&d| d as usize).product::<usize>();
        let mut roots = vec![EMPTY; self.frames.len() * root_len];
        for (fi, entries) in self.frames.iter().enumerate() {
            for (o, e) in entries {
                let r = [0, 1, 2].map(|i| ((o[i] - offset[i]) / L2_SPAN) as usize);
                roots[fi * root_len
                    + r[0]
                    + root_dims[0] as usize * (r[1] + root_dims[1] as usize * r[2])] = *e;
            }
        }
        roots
    }

    /// The asset's `l2_base` (in slots), `l2_prefix` and `l3_refs` of the nodes, whose refs hold
    /// one per channel per slot.
    pub fn layout(&self) -> (Vec<u32>, Vec<u16>, Vec<u32>) {
        let channels = self.channels;
        let mut l2_base = Vec::with_capacity(self.l2_refs.len());
        let mut l2_prefix = Vec::with_capacity(self.l2_refs.len() * L2_WORDS);
        let mut l3_refs = Vec::new();
        for (n, refs) in self.l2_refs.iter().enumerate() {
            l2_base.push((l3_refs.len() / channels) as u32);
            let mut c = 0u16;
            for w in &self.l2_masks[n * L2_WORDS..(n + 1) * L2_WORDS] {
                l2_prefix.push(c);
                c += w.count_ones() as u16;
            }
            l3_refs.extend_from_slice(refs);
        }
        (l2_base, l2_prefix, l3_refs)
    }

    /// The extent every frame fits in: (index offset, root dims), or an error naming the extent.
    pub fn extent(&self) -> Result<([i32; 3], [u32; 3]), String> {
        let mut lo = [i32::MAX; 3];
        let mut hi = [i32::MIN; 3];
        for (o, _) in self.frames.iter().flatten() {
            for a in 0..3 {
                lo[a] = lo[a].min(o[a]);
                hi[a] = hi[a].max(o[a]);
            }
        }
        if lo[0] == i32::MAX {
            return Ok(([0; 3], [1; 3]));
        }
        let dims = [0, 1, 2].map(|a| ((hi[a] as i64 - lo[a] as i64) / L2_SPAN as i64 + 1) as u64);
        if dims.iter().any(|&d| d > ROOT_DIM_MAX as u64) {
            let vox = dims.map(|d| d * L2_SPAN as u64);
            return Err(format!(
                "the sequence spans {}x{}x{} voxels (from index {:?}); one asset holds at most 4096 per axis",
                vox[0], vox[1], vox[2], lo
            ));
        }
        Ok((lo, dims.map(|d| d as u32)))
    }
}

/// Value range of stored bricks, L2 nodes and frames, computed from decoded payload values.
pub struct Ranges {
    pub bricks: Vec<[f32; 2]>,
    pub l2: Vec<[f32; 2]>,
    pub frames: Vec<[f32; 2]>,
}

fn widen(r: &mut [f32; 2], lo: f32, hi: f32) {
    r[0] = r[0].min(lo);
    r[1] = r[1].max(hi);
}

/// Ranges of L2 nodes and frames from the final bricks' ranges (`bricks`) and tile values, per
/// channel: `bgs` holds each channel's background (one for a single-channel asset), the node
/// refs hold `bgs.len()` refs per slot, and the result `bgs.len()` ranges per node and frame
/// (channel fastest), as the asset stores them.
pub fn ranges(
    bricks: Vec<[f32; 2]>,
    tiles: &[f32],
    l2_refs: &[Vec<u32>],
    roots: &[u32],
    root_len: usize,
    bgs: &[f32],
) -> Ranges {
    let nch = bgs.len();
    let ref_range = |r: u32, c: usize| {
        if r == EMPTY {
            [bgs[c], bgs[c]]
        } else if r & TILE_BIT != 0 {
            let v = tiles[(r & !TILE_BIT) as usize];
            [v, v]
        } else {
            bricks[r as usize]
        }
    };
    let l2: Vec<[f32; 2]> = l2_refs
        .iter()
        .flat_map(|refs| {
            (0..nch).map(move |c| {
                let mut r = [f32::INFINITY, f32::NEG_INFINITY];
                for &x in refs.iter().skip(c).step_by(nch) {
                    let x = ref_range(x, c);
                    widen(&mut r, x[0], x[1]);
                }
                if refs.len() < L2_SLOTS * nch {
                    widen(&mut r, bgs[c], bgs[c]);
                }
                r
            })
        })
        .collect();
    let frames = roots
        .chunks_exact(root_len)
        .flat_map(|entries| {
            let l2 = &l2;
            (0..nch).map(move |c| {
                let mut r = [f32::INFINITY, f32::NEG_INFINITY];
                for &e in entries {
                    let x = if e == EMPTY {
                        [bgs[c], bgs[c]]
                    } else if e & TILE_BIT != 0 {
                        ref_range(e, c)
                    } else {
                        l2[e as usize * nch + c]
                    };
                    widen(&mut r, x[0], x[1]);
                }
                r
            })
        })
        .collect();
    Ranges { bricks, l2, frames }
}
