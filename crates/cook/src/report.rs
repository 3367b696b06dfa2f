//! The typed result of a cook: what `vdbcook cook --json` prints, as serde structs, so the CLI,
//! `report`, `manifest` and programs linking the library read fields rather than untyped JSON.
//! The field names are the JSON keys, which are part of the CLI contract
//! (`../shared/notes/product.md`: `frames`, `active_voxels`, `bricks {source, unique,
//! after_clustering, stored}`, `bytes {topology, atlas, file}`, `bits_per_active_voxel`, `error
//! {rmse, psnr_db, max_abs}`, `seconds {total, read, build, dedup, cluster, encode, write}`);
//! `docs/cli.md` defines every one. Renaming a field breaks scripts: add, never rename.

use serde::{Deserialize, Serialize};
use vdbcook_asset::{PayloadFormat, RangeMode};

use crate::assemble::{section_sizes, topology_and_atlas, Figures};
use crate::ingest::ChannelState;
use crate::nanovdb::NanoGrids;

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
    /// The same source frames as NanoVDB grids at the same error: the GPU bytes a NanoVDB
    /// renderer would hold instead (`None` in reports written before it existed).
    #[serde(default)]
    pub nanovdb: Option<NanoComparison>,
}

/// What the source frames would take as NanoVDB grids (`crate::nanovdb`: NanoVDB 32.4's layout,
/// checked byte for byte against `nanovdb_convert`): FpN under each channel's budget
/// (`nanovdb_convert --fpN -a E`), float grids where a channel is lossless.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NanoComparison {
    /// `"FpN"`, `"float"` (a lossless cook), or `"FpN+float"` (channels of both kinds).
    pub format: String,
    /// One grid per frame and channel.
    pub grids: u64,
    /// NanoVDB's bytes (its file is its GPU layout; file headers left out).
    pub gpu_bytes: u64,
    /// Of them, grid headers, root tables and internal nodes (an upper node is 270,400 bytes
    /// whatever it holds: small volumes pay mostly for these); the rest are leaves.
    pub node_bytes: u64,
    pub bits_per_active_voxel: f64,
    /// The asset's GPU bytes (`bytes.topology + bytes.atlas`) over NanoVDB's (`None` where
    /// they do not compare: `eval --grid` on one channel of several).
    pub ratio: Option<f64>,
}

impl NanoComparison {
    /// The comparison of `channels` (each channel's source grids and its budget, `None`:
    /// lossless), over `active_voxels`, against the asset's GPU bytes when given; `None` without
    /// a grid.
    pub fn of<'a>(
        channels: impl IntoIterator<Item = (&'a NanoGrids, Option<f32>)>,
        active_voxels: u64,
        asset_gpu_bytes: Option<u64>,
    ) -> Option<NanoComparison> {
        let (mut bytes, mut grids, mut node_bytes) = (Some(0u64), 0u64, 0u64);
        let (mut fpn, mut float) = (false, false);
        for (n, budget) in channels {
            grids += n.grids;
            node_bytes += n.fixed_bytes;
            let channel = match budget {
                Some(e) => {
                    fpn = true;
                    n.fpn_bytes(e)
                }
                None => {
                    float = true;
                    Some(n.float_bytes())
                }
            };
            // Every lossy cook measures its leaves for FpN (`ReadOptions::track_uses`), eval
            // every budgeted channel.
            debug_assert!(
                channel.is_some(),
                "FpN leaves not measured for a budgeted channel"
            );
            bytes = bytes.zip(channel).map(|(a, c)| a + c);
        }
        bytes.filter(|_| grids > 0).map(|bytes| NanoComparison {
            format: match (fpn, float) {
                (true, true) => "FpN+float",
                (true, false) => "FpN",
                _ => "float",
            }
            .to_string(),
            grids,
            gpu_bytes: bytes,
            node_bytes,
            bits_per_active_voxel: if active_voxels > 0 {
                bytes as f64 * 8.0 / active_voxels as f64
            } else {
                0.0
            },
            ratio: asset_gpu_bytes.map(|g| g as f64 / bytes.max(1) as f64),
        })
    }
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
    /// Bound on what any GPU reads (≤ `max_error`).
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
    /// Bricks packed at 1, 2, .., 7 bits a voxel.
    #[serde(default)]
    pub packed: [u64; 7],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SizeSearch {
    pub limit: u64,
    pub predicted_gpu_bytes: u64,
    pub trials: usize,
    /// Channel 0's bound at each step.
    pub steps: Vec<SizeStep>,
    /// The fraction of each channel's value range (background included) the bounds are
    /// (`None`: lossless f32 fits).
    #[serde(default)]
    pub fraction_of_range: Option<f64>,
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
    /// 0 until the asset is written (by the caller).
    pub write: f64,
}

/// What [`build`] makes the report from.
pub struct BuildInputs<'a> {
    pub asset: &'a vdbcook_asset::Asset,
    pub file_bytes: u64,
    pub channels: &'a [ChannelState],
    pub budgets: &'a [Option<f32>],
    pub budget_source: &'a [Option<&'a str>],
    pub figures: &'a Figures,
    /// The format the bricks were encoded from (f32 when `--max-bytes` found lossless fits).
    pub format: PayloadFormat,
    /// Bricks the encoder made tiles of.
    pub tiles_made: u64,
    pub missing: Vec<String>,
    pub bricks: Bricks,
    pub clustering: Option<Clustering>,
    pub size_search: Option<SizeSearch>,
    pub bc7_quality: &'a str,
    pub range: RangeMode,
    pub seconds: Seconds,
    pub lod_max_abs: f64,
}

/// 10·log10(peak²/mse) for a nonzero error, with `peak` the value range.
fn psnr(rmse: f64, peak: Option<f64>) -> Option<f64> {
    peak.filter(|&p| rmse > 0.0 && p > 0.0)
        .map(|p| 20.0 * (p / rmse).log10())
}

fn figures(sum_sq: f64, max_abs: f64, gpu: f64, active: u64, peak: Option<f64>) -> ErrorFigures {
    let rmse = if active > 0 {
        (sum_sq / active as f64).sqrt()
    } else {
        0.0
    };
    ErrorFigures {
        rmse,
        psnr_db: psnr(rmse, peak),
        max_abs,
        exact: max_abs == 0.0,
        max_abs_any_gpu: gpu,
    }
}

/// The report of an assembled cook: sizes, error per channel, frame and overall, stage times.
pub fn build(b: BuildInputs) -> CookReport {
    let asset = b.asset;
    let n = b.channels.len();
    let nframes = asset.frame_count();
    let active: u64 = asset.header.frames.iter().map(|f| f.active_voxels).sum();
    let (topology, atlas) = topology_and_atlas(&section_sizes(asset));
    let bpv = |x: u64| {
        if active > 0 {
            x as f64 * 8.0 / active as f64
        } else {
            0.0
        }
    };
    let peak_of = |c: usize| b.channels[c].active_range().map(|r| (r[1] - r[0]) as f64);
    let channel_reports: Vec<ChannelReport> = (0..n)
        .map(|c| {
            let s = &b.channels[c];
            let (mut sq, mut mx, mut gpu) = (0.0, 0.0f64, 0.0f64);
            for f in 0..nframes {
                let e = b.figures.of(f, c);
                sq += e.sum_sq;
                mx = mx.max(e.max_abs);
                gpu = gpu.max(e.gpu_bound);
            }
            let act: u64 = s.active.iter().sum();
            let cost = b.figures.cost[c];
            ChannelReport {
                name: s.name.clone(),
                background: s.background,
                active_voxels: act,
                value_range: s.active_range(),
                max_error: b.budgets[c],
                max_error_source: b.budget_source[c].map(str::to_string),
                error: figures(sq, mx, gpu, act, peak_of(c)),
                bricks: cost.bricks,
                atlas_bytes: cost.atlas_bytes,
                empty_leaf_refs: cost.empty_leaf_refs,
            }
        })
        .collect();
    let all = b.figures.errors.iter();
    let total_sq = all.clone().fold(0.0f64, |a, e| a + e.sum_sq);
    let total_max = all.clone().fold(0.0f64, |m, e| m.max(e.max_abs));
    let total_gpu = all.fold(0.0f64, |m, e| m.max(e.gpu_bound));
    let mut overall = figures(total_sq, total_max, total_gpu, active, None);
    // One channel: its own PSNR; several mix units, so the worst channel's.
    overall.psnr_db = channel_reports
        .iter()
        .filter_map(|c| c.error.psnr_db)
        .reduce(f64::min);
    let frame_errors = (0..nframes)
        .map(|f| {
            let (mut sq, mut mx) = (0.0, 0.0f64);
            for c in 0..n {
                let e = b.figures.of(f, c);
                sq += e.sum_sq;
                mx = mx.max(e.max_abs);
            }
            let act = asset.header.frames[f].active_voxels;
            let rmse = if act > 0 {
                (sq / act as f64).sqrt()
            } else {
                0.0
            };
            FrameError {
                frame: f,
                number: asset.header.frames[f].number,
                rmse,
                psnr_db: if n == 1 { psnr(rmse, peak_of(0)) } else { None },
                max_abs: mx,
            }
        })
        .collect();
    let nanovdb = NanoComparison::of(
        b.channels
            .iter()
            .map(|c| &c.nanovdb)
            .zip(b.budgets.iter().copied()),
        active,
        Some(topology + atlas),
    );
    let [r0, r1, r2, r3, r4, packed @ ..] = asset.header.brick_counts;
    let shared = match b.budgets {
        [b0, rest @ ..] if rest.iter().all(|x| x == b0) => *b0,
        _ => None,
    };
    CookReport {
        output: String::new(),
        format: b.format.name().to_string(),
        grid: asset.header.grid_name.clone(),
        missing_grid_frames: b.missing,
        frames: nframes,
        active_voxels: active,
        bricks: b.bricks,
        nodes: Nodes {
            l2: asset.l2_count() as u64,
            leaf_refs: asset.l3_refs.len() as u64,
            root_dims: asset.header.root_dims,
        },
        bytes: Bytes {
            topology,
            atlas,
            file: b.file_bytes,
        },
        bits_per_active_voxel: bpv(b.file_bytes),
        bits_per_active_voxel_gpu: bpv(topology + atlas),
        topology_bits_per_active_voxel: bpv(topology),
        error: overall,
        frame_errors,
        clustering: b.clustering,
        representations: Representations {
            tile: b.tiles_made,
            bc7: r0,
            bc4: r1,
            unorm8: r2,
            f16: r3,
            f32: r4,
            packed,
        },
        max_error: shared,
        max_error_source: b.budget_source[0].map(str::to_string),
        max_bytes: b.size_search,
        bc7_quality: b.bc7_quality.to_string(),
        range: match b.range {
            RangeMode::Brick => "brick",
            RangeMode::Global => "global",
        }
        .to_string(),
        peak_memory_bytes: peak_memory_bytes(),
        seconds: b.seconds,
        channels: if n == 1 { Vec::new() } else { channel_reports },
        dropped_channels: Vec::new(),
        lod: (asset.header.lod_levels > 0).then(|| {
            let x = crate::lod::extra(asset);
            let full = (topology + atlas).saturating_sub(x.topology + x.atlas);
            LodReport {
                levels: asset.header.lod_levels,
                first: asset.header.lod_first,
                l2_nodes: x.l2_nodes,
                bricks: x.bricks,
                topology_bytes: x.topology,
                atlas_bytes: x.atlas,
                share: (x.topology + x.atlas) as f64 / full.max(1) as f64,
                max_abs: b.lod_max_abs,
            }
        }),
        nanovdb,
    }
}

/// Peak resident memory of this process (Linux `VmHWM`), if known.
pub fn peak_memory_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
