//! The CPU sampler: the value at (frame, index) straight from the asset's arrays — what `eval`,
//! the tests and the CPU reference tracer read, and the same walk the WGSL does.

use crate::format::*;
use crate::payload;
use crate::Asset;

/// What a leaf position holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LeafRef {
    /// Background.
    Empty,
    /// Every voxel has this value.
    Tile(f32),
    /// A brick in the pool.
    Brick(u32),
}

impl Asset {
    /// The ref of channel `c` at slot `slot` of L2 node `node` (`None`: the slot is not stored).
    #[inline]
    fn slot_ref(&self, node: usize, slot: usize, c: usize) -> Option<u32> {
        let w = slot >> 6;
        let word = self.l2_masks[node * L2_WORDS + w];
        let bit = 1u64 << (slot & 63);
        if word & bit == 0 {
            return None;
        }
        let idx = self.l2_base[node] as usize
            + self.l2_prefix[node * L2_WORDS + w] as usize
            + (word & (bit - 1)).count_ones() as usize;
        Some(self.l3_refs[idx * self.channel_count() + c])
    }

    #[inline]
    fn decode_ref(&self, r: u32) -> LeafRef {
        if r == EMPTY {
            LeafRef::Empty
        } else if r & TILE_BIT != 0 {
            LeafRef::Tile(self.tiles[(r & !TILE_BIT) as usize])
        } else {
            LeafRef::Brick(r)
        }
    }

    /// The root entry (`EMPTY`, `TILE_BIT | t` or an L2 node) of the 128³ region holding `a`.
    pub fn root_entry(&self, frame: usize, a: [i64; 3]) -> u32 {
        let d = self.header.root_dims;
        if a.iter()
            .zip(d)
            .any(|(&c, dim)| c < 0 || c >= dim as i64 * L2_SPAN as i64)
        {
            return EMPTY;
        }
        let r = [0, 1, 2].map(|i| (a[i] / L2_SPAN as i64) as usize);
        let root = r[0] + d[0] as usize * (r[1] + d[1] as usize * r[2]);
        self.roots[frame * self.root_len() + root]
    }

    /// What the leaf containing asset index `a` holds in `frame` (channel 0).
    pub fn leaf_at(&self, frame: usize, a: [i64; 3]) -> LeafRef {
        self.leaf_at_c(frame, a, 0)
    }

    /// What channel `c` of the leaf containing asset index `a` holds in `frame`.
    pub fn leaf_at_c(&self, frame: usize, a: [i64; 3], c: usize) -> LeafRef {
        let e = self.root_entry(frame, a);
        if e == EMPTY {
            return LeafRef::Empty;
        }
        if e & TILE_BIT != 0 {
            return LeafRef::Tile(self.tiles[(e & !TILE_BIT) as usize]);
        }
        let l = [0, 1, 2].map(|i| ((a[i] & 127) >> 3) as usize);
        self.l2_leaf_c(e, l[0] + 16 * (l[1] + 16 * l[2]), c)
    }

    /// What slot `s = x + 16·(y + 16·z)` of L2 node `node` holds (for walks that already hold
    /// the node: no descent from the root).
    #[inline]
    pub fn l2_leaf(&self, node: u32, s: usize) -> LeafRef {
        self.l2_leaf_c(node, s, 0)
    }

    /// [`Asset::l2_leaf`] of channel `c`.
    #[inline]
    pub fn l2_leaf_c(&self, node: u32, s: usize, c: usize) -> LeafRef {
        match self.slot_ref(node as usize, s, c) {
            None => LeafRef::Empty,
            Some(r) => self.decode_ref(r),
        }
    }

    /// Value at asset index `a` of `frame` (background outside what is stored; channel 0).
    pub fn value(&self, frame: usize, a: [i64; 3]) -> f32 {
        self.value_c(frame, a, 0)
    }

    /// Value of channel `c` at asset index `a` of `frame`.
    pub fn value_c(&self, frame: usize, a: [i64; 3], c: usize) -> f32 {
        match self.leaf_at_c(frame, a, c) {
            LeafRef::Empty => self.header.channel_background(c),
            LeafRef::Tile(v) => v,
            LeafRef::Brick(b) => {
                let (f, bytes) = self.brick_bytes(b);
                let q = self.brick_quant[b as usize];
                payload::decode_voxel(
                    f,
                    bytes,
                    q,
                    (a[0] & 7) as usize,
                    (a[1] & 7) as usize,
                    (a[2] & 7) as usize,
                )
            }
        }
    }

    /// Value at a *source* index coordinate (channel 0).
    pub fn value_at_source(&self, frame: usize, s: [i32; 3]) -> f32 {
        self.value(frame, self.header.to_asset_index(s))
    }

    /// Value of channel `c` at a *source* index coordinate.
    pub fn value_at_source_c(&self, frame: usize, s: [i32; 3], c: usize) -> f32 {
        self.value_c(frame, self.header.to_asset_index(s), c)
    }

    /// All 512 values of brick `b`, voxel `(x, y, z)` at `64·x + 8·y + z`.
    pub fn decode_brick(&self, b: u32, out: &mut [f32; BRICK_VOXELS]) {
        let (f, bytes) = self.brick_bytes(b);
        payload::decode_brick(f, bytes, self.brick_quant[b as usize], out)
    }

    /// Calls `f(leaf asset origin, ref)` for every stored leaf of `frame` (tiled root regions are
    /// reported once as `(region origin, Tile)` with `region = true`; channel 0).
    pub fn for_each_leaf(&self, frame: usize, f: impl FnMut([i64; 3], LeafRef, bool)) {
        self.for_each_leaf_c(frame, 0, f)
    }

    /// [`Asset::for_each_leaf`] of channel `c`: leaves where `c` is background (`EMPTY` refs of
    /// a multi-channel asset) are not reported.
    pub fn for_each_leaf_c(
        &self,
        frame: usize,
        c: usize,
        mut f: impl FnMut([i64; 3], LeafRef, bool),
    ) {
        let nch = self.channel_count();
        let d = self.header.root_dims.map(|x| x as usize);
        for (i, &e) in self.frame_roots(frame).iter().enumerate() {
            if e == EMPTY {
                continue;
            }
            let r = [i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1])];
            let o = r.map(|c| c as i64 * L2_SPAN as i64);
            if e & TILE_BIT != 0 {
                f(o, LeafRef::Tile(self.tiles[(e & !TILE_BIT) as usize]), true);
                continue;
            }
            let node = e as usize;
            let mask = self.l2_mask(node);
            let mut k = self.l2_base[node] as usize;
            for (w, &word) in mask.iter().enumerate() {
                let mut bits = word;
                while bits != 0 {
                    let s = w * 64 + bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let l = [s % 16, (s / 16) % 16, s / 256];
                    let r = self.l3_refs[k * nch + c];
                    k += 1;
                    if r == EMPTY {
                        continue;
                    }
                    f(
                        [0, 1, 2].map(|a| o[a] + 8 * l[a] as i64),
                        self.decode_ref(r),
                        false,
                    );
                }
            }
        }
    }
}
