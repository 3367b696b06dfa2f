//! Constants and the serialized header of the asset format (see the crate docs for the layout).

use serde::{Deserialize, Serialize};

pub const MAGIC: [u8; 8] = *b"VDBCOOK\x1a";
/// The newest version this build writes and reads: bricks packed at their own bit depth
/// ([`PayloadFormat::Packed1`]..[`PayloadFormat::Packed7`]; 12 brick counts and a
/// `payload_packed` section). Assets without packed bricks are still written as the oldest
/// version that holds them ([`FORMAT_VERSION_SOURCE`], [`FORMAT_VERSION_LOD_FROM`],
/// [`FORMAT_VERSION_LOD`], [`FORMAT_VERSION_CHANNELS`] or [`FORMAT_VERSION_SINGLE`]), byte for
/// byte what earlier builds wrote.
pub const FORMAT_VERSION: u32 = 7;
/// What the source was ([`Header::source`]: its writer, its grid class, its up axis).
pub const FORMAT_VERSION_SOURCE: u32 = 6;
/// A level-of-detail chain that starts below level 1 ([`Header::lod_first`] > 1, `cook
/// --lod-from`).
pub const FORMAT_VERSION_LOD_FROM: u32 = 5;
/// A level-of-detail chain from level 1 ([`Header::lod_levels`] > 0, [`Header::lod_first`] 1),
/// with one channel or several.
pub const FORMAT_VERSION_LOD: u32 = 4;
/// Several channels on one topology ([`Header::channels`]), no level-of-detail chain.
pub const FORMAT_VERSION_CHANNELS: u32 = 3;
/// The version of single-channel assets (no `channels` in the header).
pub const FORMAT_VERSION_SINGLE: u32 = 2;
/// Most coarser levels one asset holds (2¹² = 4096 voxels, the largest extent, down to one).
pub const MAX_LOD_LEVELS: u32 = 12;
/// Most channels one asset holds.
pub const MAX_CHANNELS: usize = 8;
/// Root entry: the 128³ region is background. In a multi-channel asset also a leaf ref: this
/// channel is background in this leaf (other channels are not).
pub const EMPTY: u32 = u32::MAX;
/// Ref flag: the low 31 bits index `tiles`.
pub const TILE_BIT: u32 = 1 << 31;
/// Voxels along an L2 node (16 leaves of 8).
pub const L2_SPAN: i32 = 128;
/// Leaf slots per L2 node and mask words per node.
pub const L2_SLOTS: usize = 4096;
pub const L2_WORDS: usize = 64;
pub const BRICK_DIM: i32 = 8;
pub const BRICK_VOXELS: usize = 512;
/// Root entries per axis at most (32 × 128 = 4096 voxels).
pub const ROOT_DIM_MAX: u32 = 32;
/// Largest header accepted when loading.
pub const MAX_HEADER_BYTES: usize = 64 << 20;

/// How brick voxels are stored. An asset may mix formats (one atlas per format): bricks are
/// grouped by format in [`PayloadFormat::ORDER`], so brick `b`'s format follows from
/// `Header::brick_counts`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum PayloadFormat {
    /// 32-bit float, bit exact; voxel order `64·x + 8·y + z`.
    F32,
    /// IEEE half float (round to nearest even); voxel order `64·x + 8·y + z`.
    F16,
    /// 8-bit unsigned normalized over the brick's quantization range; texture order
    /// `x + 8·y + 64·z` (8 slices of 8×8 texels).
    Unorm8,
    /// BC4 (one channel, 4 bit/voxel) over the brick's range: 8 slices × 2×2 blocks of 8 bytes.
    Bc4,
    /// BC7 (RGBA, 2 bit/voxel) over the brick's range: texel (x, y) of slice `s` holds voxels
    /// z = 4s..4s+3 in R, G, B, A; 2 slices × 2×2 blocks of 16 bytes.
    Bc7,
    /// `b`-bit codes (`Packed1` .. `Packed7`: b = 1..7) over the brick's range, 64·b bytes:
    /// voxel `n = 64·x + 8·y + z` at bits `[b·n, b·n + b)` of the brick's bytes read as
    /// little-endian u32 words. Code `q` stands for the 8-bit code `round(255·q / (2^b − 1))`
    /// ([`crate::payload::packed_code`]), dequantized as unorm8 is: every level is an unorm8
    /// level, so any GPU reads it exactly (format version 7).
    Packed1,
    Packed2,
    Packed3,
    Packed4,
    Packed5,
    Packed6,
    Packed7,
}

/// Payload formats an asset may hold ([`PayloadFormat::ORDER`]'s length).
pub const FORMATS: usize = 12;
/// Formats of versions 2 to 6 (the first five of [`PayloadFormat::ORDER`]).
pub const FORMATS_V6: usize = 5;

impl PayloadFormat {
    /// Atlas order: brick indices run through the formats' groups in this order. The five
    /// formats of versions 2–6 first (BC7, BC4, unorm8, f16, f32, as those versions group them),
    /// then the packed widths.
    pub const ORDER: [PayloadFormat; FORMATS] = [
        PayloadFormat::Bc7,
        PayloadFormat::Bc4,
        PayloadFormat::Unorm8,
        PayloadFormat::F16,
        PayloadFormat::F32,
        PayloadFormat::Packed1,
        PayloadFormat::Packed2,
        PayloadFormat::Packed3,
        PayloadFormat::Packed4,
        PayloadFormat::Packed5,
        PayloadFormat::Packed6,
        PayloadFormat::Packed7,
    ];
    /// Cheapest first: the fallback order of `--max-error` (at equal bytes BC7 before packed2
    /// and BC4 before packed4, the formats older runtimes read).
    pub const BY_COST: [PayloadFormat; FORMATS] = [
        PayloadFormat::Packed1,
        PayloadFormat::Bc7,
        PayloadFormat::Packed2,
        PayloadFormat::Packed3,
        PayloadFormat::Bc4,
        PayloadFormat::Packed4,
        PayloadFormat::Packed5,
        PayloadFormat::Packed6,
        PayloadFormat::Packed7,
        PayloadFormat::Unorm8,
        PayloadFormat::F16,
        PayloadFormat::F32,
    ];
    /// The packed widths, 1 to 7 bits.
    pub const PACKED: [PayloadFormat; 7] = [
        PayloadFormat::Packed1,
        PayloadFormat::Packed2,
        PayloadFormat::Packed3,
        PayloadFormat::Packed4,
        PayloadFormat::Packed5,
        PayloadFormat::Packed6,
        PayloadFormat::Packed7,
    ];

    /// Bits per voxel of a packed format (`None` for the others).
    pub fn packed_bits(self) -> Option<u32> {
        Self::PACKED
            .iter()
            .position(|&f| f == self)
            .map(|i| i as u32 + 1)
    }
    /// Bytes one 8³ brick takes in this format.
    pub fn bytes_per_brick(self) -> usize {
        match self {
            PayloadFormat::F32 => 2048,
            PayloadFormat::F16 => 1024,
            PayloadFormat::Unorm8 => 512,
            PayloadFormat::Bc4 => 256,
            PayloadFormat::Bc7 => 128,
            f => 64 * f.packed_bits().expect("packed") as usize,
        }
    }
    /// Position in [`PayloadFormat::ORDER`].
    pub fn rank(self) -> usize {
        Self::ORDER
            .iter()
            .position(|&f| f == self)
            .expect("in ORDER")
    }
    /// Stored through a per-brick `[lo, hi]` quantization range.
    pub fn is_quantized(self) -> bool {
        !matches!(self, PayloadFormat::F16 | PayloadFormat::F32)
    }
    pub fn name(self) -> &'static str {
        match self {
            PayloadFormat::F32 => "f32",
            PayloadFormat::F16 => "f16",
            PayloadFormat::Unorm8 => "unorm8",
            PayloadFormat::Bc4 => "bc4",
            PayloadFormat::Bc7 => "bc7",
            PayloadFormat::Packed1 => "packed1",
            PayloadFormat::Packed2 => "packed2",
            PayloadFormat::Packed3 => "packed3",
            PayloadFormat::Packed4 => "packed4",
            PayloadFormat::Packed5 => "packed5",
            PayloadFormat::Packed6 => "packed6",
            PayloadFormat::Packed7 => "packed7",
        }
    }
    pub fn parse(s: &str) -> Option<Self> {
        Self::ORDER.iter().copied().find(|f| f.name() == s)
    }
}

/// Where the quantization range of unorm8 / BC bricks comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RangeMode {
    /// Each brick's own min/max (default: faint bricks keep their precision).
    Brick,
    /// One range for the whole asset (the thesis's method; loses faint densities).
    Global,
}

/// The options a cook ran with (recorded so an asset says how it was made).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CookOptions {
    /// `--format` (with `--max-error`: the preferred format).
    pub format: PayloadFormat,
    /// `--max-error`: every voxel decodes within this of its source value.
    pub max_error: Option<f32>,
    /// Quantization range of unorm8 / BC bricks.
    pub range: RangeMode,
    /// BC7 encoder quality name.
    pub bc7_quality: String,
    /// `--grid` as given (`None`: the default choice).
    pub grid: Option<String>,
    /// `--replace-non-finite`: the value NaN/±Inf were replaced with.
    pub replace_non_finite: Option<f32>,
    pub allow_gaps: bool,
}

/// One frame's source.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameInfo {
    /// Frame number parsed from the file name.
    pub number: Option<i64>,
    /// Source file name (no directories, so cooks are reproducible across machines).
    pub source: String,
    /// Active voxels in the source grid (tiles counted by size).
    pub active_voxels: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum SectionKind {
    Roots,
    FrameRanges,
    L2Masks,
    L2Base,
    L2Prefix,
    L2Ranges,
    L3Refs,
    Tiles,
    BrickRanges,
    BrickQuant,
    PayloadBc7,
    PayloadBc4,
    PayloadUnorm8,
    PayloadF16,
    PayloadF32,
    /// Every packed brick (format version 7): the packed groups' atlases one after another, in
    /// [`PayloadFormat::ORDER`].
    PayloadPacked,
}

impl SectionKind {
    /// The sections of a version-7 asset, in file order; versions 2–6 have all but the last
    /// ([`SectionKind::of_version`]).
    pub const ALL: [SectionKind; 16] = [
        SectionKind::Roots,
        SectionKind::FrameRanges,
        SectionKind::L2Masks,
        SectionKind::L2Base,
        SectionKind::L2Prefix,
        SectionKind::L2Ranges,
        SectionKind::L3Refs,
        SectionKind::Tiles,
        SectionKind::BrickRanges,
        SectionKind::BrickQuant,
        SectionKind::PayloadBc7,
        SectionKind::PayloadBc4,
        SectionKind::PayloadUnorm8,
        SectionKind::PayloadF16,
        SectionKind::PayloadF32,
        SectionKind::PayloadPacked,
    ];
    /// The sections an asset of format version `version` holds, in file order.
    pub fn of_version(version: u32) -> &'static [SectionKind] {
        if version >= FORMAT_VERSION {
            &Self::ALL
        } else {
            &Self::ALL[..15]
        }
    }
    /// The payload section of a format.
    pub fn payload(f: PayloadFormat) -> SectionKind {
        match f {
            PayloadFormat::Bc7 => SectionKind::PayloadBc7,
            PayloadFormat::Bc4 => SectionKind::PayloadBc4,
            PayloadFormat::Unorm8 => SectionKind::PayloadUnorm8,
            PayloadFormat::F16 => SectionKind::PayloadF16,
            PayloadFormat::F32 => SectionKind::PayloadF32,
            _ => SectionKind::PayloadPacked,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            SectionKind::Roots => "roots",
            SectionKind::FrameRanges => "frame_ranges",
            SectionKind::L2Masks => "l2_masks",
            SectionKind::L2Base => "l2_base",
            SectionKind::L2Prefix => "l2_prefix",
            SectionKind::L2Ranges => "l2_ranges",
            SectionKind::L3Refs => "l3_refs",
            SectionKind::Tiles => "tiles",
            SectionKind::BrickRanges => "brick_ranges",
            SectionKind::BrickQuant => "brick_quant",
            SectionKind::PayloadBc7 => "payload_bc7",
            SectionKind::PayloadBc4 => "payload_bc4",
            SectionKind::PayloadUnorm8 => "payload_unorm8",
            SectionKind::PayloadF16 => "payload_f16",
            SectionKind::PayloadF32 => "payload_f32",
            SectionKind::PayloadPacked => "payload_packed",
        }
    }
}

/// Where a section lies (offset from the end of the header) and how to check it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SectionInfo {
    pub kind: SectionKind,
    pub offset: u64,
    pub compressed_len: u64,
    pub raw_len: u64,
    pub hash: u64,
}

/// Everything about an asset but its arrays.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// e.g. `vdbcook 0.1.0`.
    pub tool: String,
    pub options: CookOptions,
    /// Label of the grid that was cooked.
    pub grid_name: String,
    pub frames: Vec<FrameInfo>,
    /// Asset index + offset = source index. A multiple of 128 per axis.
    pub index_offset: [i32; 3],
    /// Root entries per axis (each covers 128³ voxels).
    pub root_dims: [u32; 3],
    /// Asset index → world, row-major, column vectors (`world = M · [i j k 1]ᵀ`); the source
    /// transform with `index_offset` folded in.
    pub index_to_world: [[f64; 4]; 4],
    /// The source map type (e.g. `UniformScaleMap`).
    pub source_map: String,
    pub voxel_size: [f64; 3],
    /// Value of every voxel the asset does not store.
    pub background: f32,
    /// Bricks per format, in [`PayloadFormat::ORDER`]; brick indices run through the groups.
    /// Versions 2–6 store the first five (the packed counts are 0).
    pub brick_counts: [u64; FORMATS],
    /// Filled in by the writer.
    pub sections: Vec<SectionInfo>,
    /// xxh3-64 of the header (this field zeroed) and all raw sections. Filled in by the writer.
    pub content_hash: u64,
    /// The channels of a multi-channel asset (format version 3), at least 2, in cook order;
    /// channel 0 is `grid_name` with `background`. Empty for a single-channel asset (version 2):
    /// its one channel is `grid_name`.
    pub channels: Vec<ChannelInfo>,
    /// Coarser levels stored after the full-resolution frames (format versions 4 and 5; 0 in
    /// versions 2 and 3). Stored level `k` of frame `f` is the root set `f + k·frames`, over the
    /// same L2 nodes, tiles and bricks, in an index space scaled by `2^-s` (`s =`
    /// [`Header::level_shift`]`(k)`): its voxel `i` is the mean of the full-resolution voxels
    /// `2^s·i + [0, 2^s)³` (background where nothing is stored), built as a chain of 2× box
    /// filters.
    pub lod_levels: u32,
    /// The level the first stored coarser level is (format version 5; 1 in versions 2–4): with
    /// `lod_first = K`, stored level `i ≥ 1` holds level `K + i − 1` of the chain, its voxels
    /// `2^(K + i − 1)` full-resolution voxels wide ([`Header::level_shift`]); the levels between
    /// full resolution and `K` are not stored. At least 2 in version 5, and `K + lod_levels − 1
    /// ≤ MAX_LOD_LEVELS`.
    pub lod_first: u32,
    /// What the source files say of themselves (format versions 6 and 7; empty before).
    pub source: SourceInfo,
}

/// What the source says of itself, for the renderers' defaults: the up axis of the default
/// view and whether the grid can be drawn as a fog at all. A cook records it only where it
/// matters (an up axis is known, or the class is not a fog volume); else it stays empty and
/// the asset keeps the older format version.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct SourceInfo {
    /// The first frame's `creator` file metadata (e.g. `Houdini 20.5.654/GEO_VDBTranslator`,
    /// `Blender/Smoke`), empty when absent.
    pub creator: String,
    /// The cooked grid's (channel 0's) `class` metadata: `fog volume`, `level set`, ... (empty:
    /// absent or `unknown`).
    pub grid_class: String,
    /// The world's up axis by the writer's convention: `z` (Blender), `y` (Houdini, Maya), or
    /// empty when nothing tells.
    pub up: String,
}

/// One grid of a multi-channel asset. All channels share the asset's topology (the union of
/// their active regions); `l3_refs`, `l2_ranges` and `frame_ranges` hold one entry per channel
/// per slot, node and frame (index `i · channels + c`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChannelInfo {
    /// Source grid name.
    pub name: String,
    /// This channel's value where it stores nothing.
    pub background: f32,
    /// Its `--max-error` budget (`None`: lossless or the format's own precision).
    pub max_error: Option<f32>,
    /// Active voxels of the source grid per frame (0 where the grid was missing or empty).
    pub active_voxels: Vec<u64>,
}

/// The header as format version 2 stores it (a single channel): [`Header`] without `channels`,
/// the same fields in the same order. Frozen: bincode is not self-describing, so any change
/// here would stop version-2 files from decoding.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct HeaderV2 {
    pub tool: String,
    pub options: CookOptions,
    pub grid_name: String,
    pub frames: Vec<FrameInfo>,
    pub index_offset: [i32; 3],
    pub root_dims: [u32; 3],
    pub index_to_world: [[f64; 4]; 4],
    pub source_map: String,
    pub voxel_size: [f64; 3],
    pub background: f32,
    pub brick_counts: [u64; 5],
    pub sections: Vec<SectionInfo>,
    pub content_hash: u64,
}

/// The header as format version 3 stores it (several channels, no level-of-detail chain):
/// [`HeaderV2`]'s fields, then `channels`. bincode writes a nested struct's fields in place, so
/// this is [`Header`] without `lod_levels`. Frozen, as [`HeaderV2`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct HeaderV3 {
    pub v2: HeaderV2,
    pub channels: Vec<ChannelInfo>,
}

/// The header as format version 4 stores it (a level-of-detail chain from level 1):
/// [`HeaderV3`]'s fields, then `lod_levels`; [`Header`] without `lod_first`. Frozen, as
/// [`HeaderV2`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct HeaderV4 {
    pub v3: HeaderV3,
    pub lod_levels: u32,
}

/// The header as format version 5 stores it (a level-of-detail chain from a level below 1):
/// [`HeaderV4`]'s fields, then `lod_first`; [`Header`] without `source`. Frozen, as
/// [`HeaderV2`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct HeaderV5 {
    pub v4: HeaderV4,
    pub lod_first: u32,
}

/// The header as format version 6 stores it (what the source says of itself): [`HeaderV5`]'s
/// fields, then `source`; [`Header`] with five brick counts. Frozen, as [`HeaderV2`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct HeaderV6 {
    pub v5: HeaderV5,
    pub source: SourceInfo,
}

impl From<&Header> for HeaderV6 {
    fn from(h: &Header) -> HeaderV6 {
        HeaderV6 {
            v5: HeaderV5::from(h),
            source: h.source.clone(),
        }
    }
}

impl From<HeaderV6> for Header {
    fn from(h: HeaderV6) -> Header {
        Header {
            source: h.source,
            ..Header::from(h.v5)
        }
    }
}

impl From<&Header> for HeaderV5 {
    fn from(h: &Header) -> HeaderV5 {
        HeaderV5 {
            v4: HeaderV4::from(h),
            lod_first: h.lod_first,
        }
    }
}

impl From<HeaderV5> for Header {
    fn from(h: HeaderV5) -> Header {
        Header {
            lod_first: h.lod_first,
            ..Header::from(h.v4)
        }
    }
}

impl From<&Header> for HeaderV4 {
    fn from(h: &Header) -> HeaderV4 {
        HeaderV4 {
            v3: HeaderV3::from(h),
            lod_levels: h.lod_levels,
        }
    }
}

impl From<HeaderV4> for Header {
    fn from(h: HeaderV4) -> Header {
        Header {
            lod_levels: h.lod_levels,
            ..Header::from(h.v3)
        }
    }
}

impl From<&Header> for HeaderV3 {
    fn from(h: &Header) -> HeaderV3 {
        HeaderV3 {
            v2: HeaderV2::from(h),
            channels: h.channels.clone(),
        }
    }
}

impl From<HeaderV3> for Header {
    fn from(h: HeaderV3) -> Header {
        Header {
            channels: h.channels,
            ..Header::from(h.v2)
        }
    }
}

impl From<&Header> for HeaderV2 {
    fn from(h: &Header) -> HeaderV2 {
        HeaderV2 {
            tool: h.tool.clone(),
            options: h.options.clone(),
            grid_name: h.grid_name.clone(),
            frames: h.frames.clone(),
            index_offset: h.index_offset,
            root_dims: h.root_dims,
            index_to_world: h.index_to_world,
            source_map: h.source_map.clone(),
            voxel_size: h.voxel_size,
            background: h.background,
            brick_counts: std::array::from_fn(|i| h.brick_counts[i]),
            sections: h.sections.clone(),
            content_hash: h.content_hash,
        }
    }
}

impl From<HeaderV2> for Header {
    fn from(h: HeaderV2) -> Header {
        Header {
            tool: h.tool,
            options: h.options,
            grid_name: h.grid_name,
            frames: h.frames,
            index_offset: h.index_offset,
            root_dims: h.root_dims,
            index_to_world: h.index_to_world,
            source_map: h.source_map,
            voxel_size: h.voxel_size,
            background: h.background,
            brick_counts: std::array::from_fn(|i| h.brick_counts.get(i).copied().unwrap_or(0)),
            sections: h.sections,
            content_hash: h.content_hash,
            channels: Vec::new(),
            lod_levels: 0,
            lod_first: 1,
            source: SourceInfo::default(),
        }
    }
}

impl Header {
    /// Channels stored (1 for a single-channel asset).
    pub fn channel_count(&self) -> usize {
        self.channels.len().max(1)
    }
    /// The format version this header is written as.
    pub fn format_version(&self) -> u32 {
        if self.brick_counts[FORMATS_V6..].iter().any(|&n| n > 0) {
            FORMAT_VERSION
        } else if self.source != SourceInfo::default() {
            FORMAT_VERSION_SOURCE
        } else if self.lod_levels > 0 && self.lod_first > 1 {
            FORMAT_VERSION_LOD_FROM
        } else if self.lod_levels > 0 {
            FORMAT_VERSION_LOD
        } else if self.channels.is_empty() {
            FORMAT_VERSION_SINGLE
        } else {
            FORMAT_VERSION_CHANNELS
        }
    }
    /// Levels stored: the full resolution and [`Header::lod_levels`] coarser ones.
    pub fn level_count(&self) -> usize {
        1 + self.lod_levels as usize
    }
    /// Stored level `level`'s place in the chain: its voxel `i` covers full-resolution indices
    /// `2^shift · i + [0, 2^shift)³` (0 for full resolution, `lod_first + level − 1` above).
    pub fn level_shift(&self, level: usize) -> u32 {
        if level == 0 {
            0
        } else {
            self.lod_first + level as u32 - 1
        }
    }
    /// Name of channel `c`.
    pub fn channel_name(&self, c: usize) -> &str {
        match self.channels.get(c) {
            Some(ch) => &ch.name,
            None => &self.grid_name,
        }
    }
    /// Background of channel `c`.
    pub fn channel_background(&self, c: usize) -> f32 {
        match self.channels.get(c) {
            Some(ch) => ch.background,
            None => self.background,
        }
    }
    /// Active voxels of channel `c`'s source grid in `frame`.
    pub fn channel_active_voxels(&self, c: usize, frame: usize) -> u64 {
        match self.channels.get(c) {
            Some(ch) => ch.active_voxels[frame],
            None => self.frames[frame].active_voxels,
        }
    }
    /// The channel named `name`.
    pub fn channel_index(&self, name: &str) -> Option<usize> {
        (0..self.channel_count()).find(|&c| self.channel_name(c) == name)
    }
    /// Encodes the header as its version stores it (bincode 2, standard config).
    pub(crate) fn encode(&self) -> Result<Vec<u8>, crate::AssetError> {
        let config = bincode::config::standard();
        let r = match self.format_version() {
            FORMAT_VERSION_SINGLE => bincode::serde::encode_to_vec(HeaderV2::from(self), config),
            FORMAT_VERSION_CHANNELS => bincode::serde::encode_to_vec(HeaderV3::from(self), config),
            FORMAT_VERSION_LOD => bincode::serde::encode_to_vec(HeaderV4::from(self), config),
            FORMAT_VERSION_LOD_FROM => bincode::serde::encode_to_vec(HeaderV5::from(self), config),
            FORMAT_VERSION_SOURCE => bincode::serde::encode_to_vec(HeaderV6::from(self), config),
            _ => bincode::serde::encode_to_vec(self, config),
        };
        r.map_err(|e| crate::AssetError(format!("cannot encode the header: {e}")))
    }
    /// Source index → asset index.
    pub fn to_asset_index(&self, source: [i32; 3]) -> [i64; 3] {
        [0, 1, 2].map(|a| source[a] as i64 - self.index_offset[a] as i64)
    }
}
