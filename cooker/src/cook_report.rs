//! The typed result of a cook: what `vdbcook cook --json` prints, as serde structs, so the CLI,
//! `report`, `manifest` and programs linking the library read fields rather than untyped JSON.
//! The field names are the JSON keys, which are part of the CLI contract
//! (`../shared/notes/product.md`: `frames`, `active_voxels`, `bricks {source, unique,
//! after_clustering, stored}`, `bytes {topology, atlas, file}`, `bits_per_active_voxel`, `error
//! {rmse, psnr_db, max_abs}`, `seconds {total, read, build, dedup, cluster, encode, write}`);
//! `docs/cli.md` defines every one. Renaming a field breaks scripts: add, never rename.

use serde::{Deserialize, Serialize};

/// `cook --json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CookReport {
    pub output: String,
    /// The format the cook started from (`--format`, or BC7 under a budget without one).
    pub format: String,
    /// The grid cooked (the name chosen once for the whole sequence).
    pub grid: String,
    /// Source files without the grid, cooked as empty frames (`--allow-missing-grid`).
    pub missing_grid_frames: Vec<String>,
    pub frames: usize,
    pub active_voxels: u64,
    pub bricks: Bricks,
    pub nodes: Nodes,
    pub bytes: Bytes,
    /// File bits per active voxel.
    pub bits_per_active_voxel: f64,
    /// GPU (topology + atlas) bits per active voxel.
    pub bits_per_active_voxel_gpu: f64,
    pub topology_bits_per_active_voxel: f64,
    pub error: ErrorFigures,
    pub frame_errors: Vec<FrameError>,
    /// `None` without `--clusters`.
    pub clustering: Option<Clustering>,
    pub representations: Representations,
    /// The budget used: given, default or found by `--max-bytes`; `None` for a lossless cook.
    pub max_error: Option<f32>,
    /// `"given"`, `"default"`, `"max_bytes"`, or `None`.
    pub max_error_source: Option<String>,
    /// The size search of `--max-bytes`.
    pub max_bytes: Option<SizeSearch>,
    pub bc7_quality: String,
    /// `"brick"` or `"global"`.
    pub range: String,
    /// Peak resident memory of the process (Linux), if known.
    pub peak_memory_bytes: Option<u64>,
    pub seconds: Seconds,
    /// Per channel of a multi-channel cook (`--grids`), in channel order; empty for a
    /// single-grid cook (its figures are the ones above).
    #[serde(default)]
    pub channels: Vec<ChannelReport>,
    /// Grids of `--grids` left out because they carry nothing: every active value of every
    /// frame within the channel's budget of its background (exactly the background in a
    /// lossless cook), or no active value at all. Empty unless some were dropped.
    #[serde(default)]
    pub dropped_channels: Vec<DroppedChannel>,
    /// The coarser levels of `--lod`; `None` without it.
    #[serde(default)]
    pub lod: Option<LodReport>,
}

/// What `--lod` stored (`CookReport::lod`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LodReport {
    /// Coarser levels stored (level k: 2^k voxels per axis in one).
    pub levels: u32,
    /// The first of them (`--lod-from`; 1 by default): levels `first..first + levels`.
    pub first: u32,
    /// L2 nodes and bricks only the coarser levels use.
    pub l2_nodes: u64,
    pub bricks: u64,
    /// GPU bytes the levels add (`bytes.topology` and `bytes.atlas` include them).
    pub topology_bytes: u64,
    pub atlas_bytes: u64,
    /// Those bytes over the GPU bytes of the full-resolution frames alone.
    pub share: f64,
    /// Largest |decoded − box mean| over the levels' bricks (within `max_error`; 0 lossless).
    pub max_abs: f64,
}

/// A grid of `--grids` that was not cooked (`CookReport::dropped_channels`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DroppedChannel {
    pub name: String,
    pub background: f32,
    /// `[min, max]` of its active values over all frames (`None`: none).
    pub value_range: Option<[f32; 2]>,
    /// The budget it was held to (`None`: lossless, so only the background itself counts).
    pub max_error: Option<f32>,
}

/// One channel of a multi-channel cook. Its error figures are over its own stored voxels in its
/// own units; the asset-wide `error` mixes units (its `psnr_db` is the worst channel's).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChannelReport {
    /// Source grid name.
    pub name: String,
    pub background: f32,
    /// Over all frames.
    pub active_voxels: u64,
    /// `[min, max]` of the active source values over all frames (`None`: none).
    pub value_range: Option<[f32; 2]>,
    /// This channel's budget (`None`: lossless).
    pub max_error: Option<f32>,
    /// `"given"`, `"default"` or `None`.
    pub max_error_source: Option<String>,
    pub error: ErrorFigures,
    /// Stored bricks this channel reads (a brick two channels share counts in both).
    pub bricks: u64,
    /// Their payload bytes.
    pub atlas_bytes: u64,
    /// Leaf slots where this channel is its background (it costs a 4-byte ref and no atlas).
    pub empty_leaf_refs: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Bricks {
    pub source: u64,
    pub unique: u64,
    pub after_clustering: u64,
    pub stored: u64,
    pub tiles: u64,
    pub tile_leaves: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Nodes {
    pub l2: u64,
    pub leaf_refs: u64,
    pub root_dims: [u32; 3],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Bytes {
    pub topology: u64,
    pub atlas: u64,
    pub file: u64,
}

/// Error over every stored voxel (`eval`'s definition, `docs/cli.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ErrorFigures {
    pub rmse: f64,
    /// `None` when the error is zero.
    pub psnr_db: Option<f64>,
    pub max_abs: f64,
    pub exact: bool,
    /// Bound on what any conformant GPU reads (≤ `max_error`).
    pub max_abs_any_gpu: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameError {
    pub frame: usize,
    pub number: Option<i64>,
    pub rmse: f64,
    pub psnr_db: Option<f64>,
    pub max_abs: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Clustering {
    pub candidates: usize,
    pub clusters_requested: usize,
    pub clusters: usize,
    pub iterations: usize,
    pub rejected_by_variance: usize,
    pub rejected_by_error: usize,
    pub variance_threshold: f32,
    pub seconds: f64,
}

/// Bricks per representation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Representations {
    pub tile: u64,
    pub bc7: u64,
    pub bc4: u64,
    pub unorm8: u64,
    pub f16: u64,
    pub f32: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SizeSearch {
    pub limit: u64,
    pub predicted_gpu_bytes: u64,
    pub trials: usize,
    pub steps: Vec<SizeStep>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SizeStep {
    pub max_error: f32,
    pub gpu_bytes: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Seconds {
    pub total: f64,
    pub read: f64,
    pub build: f64,
    pub dedup: f64,
    pub cluster: f64,
    pub encode: f64,
    /// 0 until the asset is written (`cook::run`).
    pub write: f64,
}
