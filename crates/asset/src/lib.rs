//! `vdbcook-asset`: the flip-book volume asset — its format, a writer, a validating loader and a
//! CPU sampler. Both the cooker and the runtime depend on this crate, so it stays light (serde,
//! bincode 2, zstd, half, xxhash).
//!
//! # The model
//! Every frame is a sparse 5-4-3 tree over one shared brick pool, in an *asset index space*: source
//! index `s` maps to asset index `a = s - index_offset` (`index_offset` is a multiple of 128, so
//! OpenVDB's 8³ and 128³ tiles stay aligned), and the whole sequence must fit in 4096³.
//!
//! - **Root (L1)**: per frame, a dense grid of `root_dims` (≤ 32 per axis) entries, one per 128³
//!   region of the asset's extent — only the extent the sequence covers, not 32³. Entry
//!   `x + dx·(y + dy·z)` of frame `f` is `roots[f·root_len + …]`. Selecting a frame = one offset.
//! - **L2 nodes**: 16³ slots of 8³ leaves. A 4096-bit `mask` says which slots exist; their refs are
//!   stored contiguously from `l2_base[n]` in slot order, so slot `s`'s ref is at
//!   `l2_base[n] + l2_prefix[n][s / 64] + popcount(mask[n][s / 64] & ((1 << s % 64) - 1))`.
//!   Slot `s = x + 16·(y + 16·z)` for the leaf at `(8x, 8y, 8z)` inside the node.
//!   Identical L2 nodes (same mask, same refs) are stored once, across all frames (a DAG over time).
//! - **L3 refs** (`u32`): a brick index, or `TILE_BIT | t` for a leaf whose 512 values all equal
//!   `tiles[t]`. Root entries use the same encoding (`TILE_BIT | t` = the whole 128³ region is
//!   `tiles[t]`), plus `EMPTY` (the region is background).
//! - **Bricks**: 8³ values; identical bricks across all frames are stored once. Each brick is in
//!   one of twelve formats (see [`PayloadFormat`]), grouped by format in [`PayloadFormat::ORDER`]
//!   (BC7, BC4, unorm8, f16, f32, packed1..packed7): brick `b` belongs to the group its index
//!   falls in according to `Header::brick_counts`, and each group has its own atlas (one payload
//!   section per format; the packed atlases share the last section, format version 7).
//!   f32/f16 bricks keep OpenVDB's voxel order `64·x + 8·y + z`; unorm8/BC bricks are texture
//!   tiles (slices along z of 8×8 texels) over the brick's `[lo, hi]` in `brick_quant`; packed
//!   bricks are a bit stream in voxel order over the same range.
//! - **Ranges**: `[min, max]` of the *stored* values per brick, per L2 node (over its whole 128³
//!   region, so background counts when a slot is empty) and per frame: majorants for empty-space
//!   skipping and delta tracking.
//! - Values are what OpenVDB reads for active voxels; inactive voxels are the background.
//!
//! # Several channels (format version 3)
//! Fire needs several grids (density, temperature, flame) per voxel. A multi-channel asset holds
//! `N = channels.len()` (2..=8) of them on **one** topology, the union of their active regions:
//! the roots, L2 masks, `l2_base` and `l2_prefix` are shared (and count slots, not refs), while
//! each slot holds `N` refs, channel `c`'s at `l3_refs[slot_index · N + c]`; `EMPTY` there means
//! channel `c` is its own background in that leaf. `l2_ranges[n · N + c]` and
//! `frame_ranges[f · N + c]` are per channel. Root entries are never tiles (a constant 128³
//! region is an L2 node whose 4096 slots all hold tile refs). Bricks, tiles and payloads form one
//! pool shared by all channels. Single-channel assets are version 2, without `channels`.
//!
//! # Level of detail (format version 4)
//! An asset cooked with `--lod` also stores `L = Header::lod_levels` coarser levels of every
//! frame, each a box-filtered 2× reduction of the one before, down to (at most) one brick. They
//! are more root sets in `roots` and `frame_ranges`, after the full-resolution ones: level `k`
//! of frame `f` is root set `f + k·frames` ([`Asset::lod_set`]), over the same L2 nodes, tiles
//! and bricks (deduplicated with the full-resolution ones) and the same `root_dims` (a coarse
//! level uses the first `⌈dims / 2^k⌉` entries per axis; the rest are `EMPTY`). Level `k`'s
//! asset index `i` covers full-resolution indices `2^k·i + [0, 2^k)³`; its value is the mean of
//! level `k − 1`'s eight voxels `2i + {0,1}³` (background where nothing is stored), so every
//! level's value is the mean of the full-resolution voxels it covers, up to the payload's error.
//! Node, brick and root-set ranges bound each level's own values, as at full resolution.
//!
//! # A chain from a coarser level (format version 5)
//! An asset cooked with `--lod-from K` (`K ≥ 2`, `Header::lod_first`) stores levels `K, K+1, …`
//! only: stored level `i ≥ 1` is level `K + i − 1` of the chain above (its voxel `i` covers
//! `2^(K+i−1)` full-resolution voxels per axis; [`Header::level_shift`]), built through the
//! levels it skips, which are not stored. Everything else is as in version 4, which is the same
//! layout with `K = 1`.
//!
//! # The file
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic `b"VDBCOOK\x1a"` |
//! | 8 | 4 | format version (`u32` LE: 2 for one channel, 3 for several, 4 with coarser levels, 5 with coarser levels from level 2 or beyond, 6 with what the source says of itself, 7 with packed bricks) |
//! | 12 | 4 | header length `H` (`u32` LE) |
//! | 16 | H | [`Header`], bincode 2 (standard config) |
//! | 16 + H | … | sections: zstd frames at `Header::sections[i].offset` (relative to 16 + H) |
//!
//! Sections, in this order, each the little-endian array named: `roots` (u32), `frame_ranges`
//! (f32 pairs), `l2_masks` (u64 × 64 per node), `l2_base` (u32), `l2_prefix` (u16 × 64 per node),
//! `l2_ranges` (f32 pairs), `l3_refs` (u32), `tiles` (f32), `brick_ranges` (f32 pairs),
//! `brick_quant` (f32 pairs: the `[lo, hi]` of quantized bricks, `[0, 0]` for float ones), then one
//! payload section per format of versions 2–6 in `PayloadFormat::ORDER` (bytes, `bytes_per_brick`
//! each), and in version 7 one `payload_packed` section with the packed atlases in that order. Each section records its raw length and an xxh3 hash; `content_hash` is the xxh3 of the header (with the hash
//! zeroed) followed by all raw sections in order. Loading = read, decompress, validate every index and count; there is no
//! per-node deserialization.

pub mod bc;
pub mod builder;
mod error;
mod format;
mod load;
pub mod payload;
mod sample;
mod write;

pub use error::AssetError;
pub use format::*;
pub use sample::LeafRef;

/// A flip-book asset in memory (as cooked, or as loaded and validated).
#[derive(Debug, Clone, PartialEq)]
pub struct Asset {
    pub header: Header,
    /// `frames × levels × root_len` entries (root set `f + level·frames` at
    /// `(f + level·frames)·root_len`): `EMPTY`, `TILE_BIT | tile`, or an L2 node index.
    pub roots: Vec<u32>,
    /// Per root set (frame and level) and channel, `[min, max]` of stored values over its extent.
    pub frame_ranges: Vec<[f32; 2]>,
    /// Per L2 node, 64 words: which of the 4096 slots exist.
    pub l2_masks: Vec<u64>,
    /// Per L2 node: index of its first ref in `l3_refs`.
    pub l2_base: Vec<u32>,
    /// Per L2 node, 64 entries: set slots in the mask words before word `w`.
    pub l2_prefix: Vec<u16>,
    pub l2_ranges: Vec<[f32; 2]>,
    /// Leaf refs: brick index or `TILE_BIT | tile` (`channels` per slot; `EMPTY` too when
    /// several).
    pub l3_refs: Vec<u32>,
    /// Constant values of tiles (deduplicated).
    pub tiles: Vec<f32>,
    pub brick_ranges: Vec<[f32; 2]>,
    /// Per brick `[lo, hi]` of its quantization range (quantized formats; `[0, 0]` otherwise).
    pub brick_quant: Vec<[f32; 2]>,
    /// One atlas per format, in [`PayloadFormat::ORDER`].
    pub payloads: [Vec<u8>; FORMATS],
}

impl Asset {
    pub fn frame_count(&self) -> usize {
        self.header.frames.len()
    }
    /// Levels stored (1 without a level-of-detail chain).
    pub fn level_count(&self) -> usize {
        self.header.level_count()
    }
    /// Stored level `level`'s shift (`Header::level_shift`): `level` itself unless the asset
    /// was cooked with `--lod-from`.
    pub fn level_shift(&self, level: usize) -> u32 {
        self.header.level_shift(level)
    }
    /// Root sets stored: every frame at every level (`frames × levels`).
    pub fn root_set_count(&self) -> usize {
        self.frame_count() * self.level_count()
    }
    /// The root set of `frame` at stored level `level` (0 = full resolution): pass it as the
    /// `frame` of any per-frame accessor ([`Asset::value`], [`Asset::leaf_at`],
    /// [`Asset::for_each_leaf`], [`Asset::frame_range`], [`Asset::frame_roots`]) to read that
    /// level, whose asset index `i` covers full-resolution indices `2^s · i + [0, 2^s)³`, `s =`
    /// [`Asset::level_shift`]`(level)`.
    pub fn lod_set(&self, frame: usize, level: usize) -> usize {
        debug_assert!(frame < self.frame_count() && level < self.level_count());
        frame + level * self.frame_count()
    }
    /// Channels stored (1 for a single-channel asset).
    pub fn channel_count(&self) -> usize {
        self.header.channel_count()
    }
    /// `[min, max]` of channel `c`'s stored values over `frame`'s extent.
    pub fn frame_range(&self, frame: usize, c: usize) -> [f32; 2] {
        self.frame_ranges[frame * self.channel_count() + c]
    }
    /// `[min, max]` of channel `c` over L2 node `n`'s 128³ region.
    pub fn l2_range(&self, n: usize, c: usize) -> [f32; 2] {
        self.l2_ranges[n * self.channel_count() + c]
    }
    pub fn root_len(&self) -> usize {
        self.header.root_dims.iter().map(|&d| d as usize).product()
    }
    pub fn l2_count(&self) -> usize {
        self.l2_base.len()
    }
    pub fn brick_count(&self) -> usize {
        self.brick_ranges.len()
    }
    /// The root entries of one frame.
    pub fn frame_roots(&self, frame: usize) -> &[u32] {
        let n = self.root_len();
        &self.roots[frame * n..(frame + 1) * n]
    }
    /// Format of brick `b` and its index inside that format's atlas.
    pub fn brick_format(&self, b: u32) -> (PayloadFormat, usize) {
        locate_brick(&self.header.brick_counts, b as u64)
            .expect("brick index beyond the pool (validated assets never get here)")
    }
    /// The stored bytes of brick `b`.
    pub fn brick_bytes(&self, b: u32) -> (PayloadFormat, &[u8]) {
        let (f, i) = self.brick_format(b);
        let n = f.bytes_per_brick();
        (f, &self.payloads[f.rank()][i * n..(i + 1) * n])
    }
    /// Total payload bytes over all formats.
    pub fn payload_bytes(&self) -> usize {
        self.payloads.iter().map(|p| p.len()).sum()
    }
    /// The 64 mask words of L2 node `n`.
    pub fn l2_mask(&self, n: usize) -> &[u64] {
        &self.l2_masks[n * L2_WORDS..(n + 1) * L2_WORDS]
    }
}

/// Brick `b` of a pool grouped by format (`counts[i]` bricks of [`PayloadFormat::ORDER`]`[i]`,
/// in that order): its format and its index inside that format's atlas; `None` past the end.
pub fn locate_brick(counts: &[u64; FORMATS], b: u64) -> Option<(PayloadFormat, usize)> {
    let mut b = b;
    for (f, &n) in PayloadFormat::ORDER.iter().zip(counts) {
        if b < n {
            return Some((*f, b as usize));
        }
        b -= n;
    }
    None
}
