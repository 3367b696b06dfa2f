//! Assemble stage: the pool, pointed at what the encoder made of each brick, becomes the asset —
//! per-frame roots over the sequence's extent, node layout and value ranges per channel, the
//! header — which is validated and serialized; the error of every brick use is summed per frame
//! and channel on the way (what a GPU may add included). Also the byte accounting
//! `cook`, `info` and `eval` share (`section_sizes`, `topology_and_atlas`).

use std::collections::BTreeSet;

use rayon::prelude::*;
use vdbcook_asset::*;
use vdbcook_vdb::Transform;

use crate::cluster::Guarded;
use crate::encode::{EncodeOptions, Encoded};
use crate::error::CookError;
use crate::ingest::ChannelState;
use crate::pool::{ranges, Pool};

/// What the assembly is made from.
pub struct Inputs<'a> {
    pub pool: Pool,
    pub enc: Encoded,
    /// The guard's encode input (with `--clusters`); else the encoder read the pool itself.
    pub guarded: Option<Guarded>,
    pub channels: &'a [ChannelState],
    pub chan_budget: &'a [Option<f32>],
    pub eopts: &'a EncodeOptions,
    /// The `--grid` a single-grid cook records (`None`: the default grid, or several).
    pub requested: Option<String>,
    /// Channel 0's grid label.
    pub label: String,
    /// What the source says of itself.
    pub source: vdbcook_asset::SourceInfo,
    pub infos: Vec<FrameInfo>,
    pub transform: &'a Transform,
    pub offset: [i32; 3],
    pub root_dims: [u32; 3],
    /// (levels stored, first level).
    pub lod: (u32, u32),
    /// Pool bricks the coarser levels use.
    pub lod_bricks: &'a [u32],
    pub replace_non_finite: Option<f32>,
    pub allow_gaps: bool,
}

/// Error sums of one frame of one channel.
#[derive(Default, Clone, Copy, Debug)]
pub struct FrameErr {
    pub sum_sq: f64,
    pub max_abs: f64,
    /// Bound on any GPU's read: per voxel, its error plus its native-read slack.
    pub gpu_bound: f64,
}

/// Per channel, what its voxels cost in the atlas.
#[derive(Default, Clone, Copy, Debug)]
pub struct ChannelCost {
    /// Stored bricks it reads (a brick two channels share counts in both).
    pub bricks: u64,
    pub atlas_bytes: u64,
    /// Leaf slots where it is its background.
    pub empty_leaf_refs: u64,
}

/// The error and cost figures of an assembled cook.
pub struct Figures {
    /// Per frame and channel (`f·channels + c`); empty for a lossless cook (exact).
    pub errors: Vec<FrameErr>,
    pub channels: usize,
    pub cost: Vec<ChannelCost>,
}

impl Figures {
    pub fn of(&self, frame: usize, channel: usize) -> FrameErr {
        self.errors
            .get(frame * self.channels + channel)
            .copied()
            .unwrap_or_default()
    }
}

pub struct Assembled {
    pub asset: Asset,
    pub bytes: Vec<u8>,
    pub figures: Figures,
    /// Leaves that became bricks, and those that were constant, over all frames.
    pub source_bricks: u64,
    pub source_tiles: u64,
    pub unique_bricks: u64,
    pub after_clustering: u64,
    /// Bricks the encoder made tiles of.
    pub tiles_made: u64,
    /// Largest |decoded − box mean| over the coarser levels' bricks.
    pub lod_max_abs: f64,
}

/// The error sums of each list of brick uses (a frame's channel's): every use of pool brick `b`
/// compares its source values `bricks` with `decoded`, and `slack(b, out)` fills what a GPU's
/// native read of each of its voxels may add. Inactive voxels hold the background in the pool: a lossy payload that
/// moves them off it is an error too (a tracer samples them), counted as `eval` counts it. The
/// RMSE divides by the active voxel count.
pub fn use_errors(
    uses: &[Vec<u32>],
    bricks: &[f32],
    decoded: &[f32],
    slack: impl Fn(u32, &mut [f32; BRICK_VOXELS]) + Sync,
) -> Vec<FrameErr> {
    uses.par_iter()
        .map(|uses| {
            let mut fe = FrameErr::default();
            let mut k = [0f32; BRICK_VOXELS];
            for &b in uses {
                let r = b as usize * BRICK_VOXELS..(b as usize + 1) * BRICK_VOXELS;
                let mut brick_max = 0.0f64;
                slack(b, &mut k);
                for ((s, v), k) in bricks[r.clone()].iter().zip(&decoded[r]).zip(&k) {
                    let e = (*v as f64 - *s as f64).abs();
                    fe.sum_sq += e * e;
                    brick_max = brick_max.max(e);
                    fe.gpu_bound = fe.gpu_bound.max(e + *k as f64);
                }
                fe.max_abs = fe.max_abs.max(brick_max);
            }
            fe
        })
        .collect()
}

/// The asset's `index_to_world`: the source transform with the asset's index offset folded in.
pub fn asset_index_to_world(transform: &Transform, offset: [i32; 3]) -> [[f64; 4]; 4] {
    let mut m = transform.index_to_world;
    for (r, row) in m.iter_mut().enumerate().take(3) {
        row[3] = transform.index_to_world[r][3]
            + (0..3)
                .map(|c| transform.index_to_world[r][c] * offset[c] as f64)
                .sum::<f64>();
    }
    m
}

pub fn assemble(i: Inputs) -> Result<Assembled, CookError> {
    let Inputs {
        mut pool,
        enc,
        guarded,
        channels,
        chan_budget,
        eopts,
        requested,
        label,
        source,
        infos,
        transform,
        offset,
        root_dims,
        lod: (lod_levels, lod_first),
        lod_bricks,
        replace_non_finite,
        allow_gaps,
    } = i;
    let n = channels.len();
    let n_pool = pool.brick_count();
    let input_of: Vec<u32> = match &guarded {
        Some(g) => g.input_of.clone(),
        None => (0..n_pool as u32).collect(),
    };
    let after_clustering = match &guarded {
        Some(g) => (g.input.len() / BRICK_VOXELS) as u64,
        None => n_pool as u64,
    };
    // Decoded values of what each pool brick now points at (for the error figures).
    let gathered: Vec<f32> = match &guarded {
        Some(g) => {
            let dec = enc.decoded_or(&g.input);
            let mut d = vec![0f32; pool.bricks.len()];
            for (b, &i) in input_of.iter().enumerate() {
                d[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS].copy_from_slice(
                    &dec[i as usize * BRICK_VOXELS..(i as usize + 1) * BRICK_VOXELS],
                );
            }
            d
        }
        None => Vec::new(),
    };
    drop(guarded);
    // Bricks that became tiles append their values to the pool's tiles.
    let remap = pool.apply_encoding(
        input_of.iter().map(|&i| enc.remap[i as usize]),
        &enc.new_tiles,
    );
    let decoded: &[f32] = if gathered.is_empty() {
        enc.decoded_or(&pool.bricks)
    } else {
        &gathered
    };
    let root_len = root_dims.iter().map(|&d| d as usize).product::<usize>();
    let roots = pool.roots(offset, root_dims);
    let bgs: Vec<f32> = channels.iter().map(|c| c.background).collect();
    let rg = ranges(
        enc.brick_ranges.clone(),
        &pool.tiles,
        &pool.l2_refs,
        &roots,
        root_len,
        &bgs,
    );
    let (l2_base, l2_prefix, l3_refs) = pool.layout();
    // Error per (frame, channel) over every brick use; tiles from the source are stored exactly,
    // lossy tiles made under a bound are in `decoded`.
    let errors = use_errors(&pool.uses, &pool.bricks, decoded, |b, out| {
        enc.voxel_slack(input_of[b as usize] as usize, out)
    });
    let lod_max_abs = lod_bricks.iter().fold(0.0f64, |m, &b| {
        let r = b as usize * BRICK_VOXELS..(b as usize + 1) * BRICK_VOXELS;
        pool.bricks[r.clone()]
            .iter()
            .zip(&decoded[r])
            .fold(m, |m, (x, y)| m.max((x - y).abs() as f64))
    });
    // Stored bricks each channel reads, and its empty slots.
    let mut per_channel: Vec<BTreeSet<u32>> = vec![BTreeSet::new(); n];
    for (b, &m) in pool.brick_channels.iter().enumerate() {
        let r = remap[b];
        if r & TILE_BIT == 0 {
            for (c, set) in per_channel.iter_mut().enumerate() {
                if m & (1 << c) != 0 {
                    set.insert(r);
                }
            }
        }
    }
    let mut empty_refs = vec![0u64; n];
    for (k, &r) in l3_refs.iter().enumerate() {
        if r == EMPTY {
            empty_refs[k % n] += 1;
        }
    }
    let unique_bricks = n_pool as u64;
    let enc_tiles = enc.representation.tile;
    let (source_bricks, source_tiles) = (pool.source_bricks, pool.source_tiles);
    // The f32 pool is no longer needed: free it before serializing.
    drop(gathered);
    pool.bricks = Vec::new();
    pool.uses = Vec::new();
    let shared_budget = match chan_budget {
        [b0, rest @ ..] if rest.iter().all(|b| b == b0) => *b0,
        _ => None,
    };
    let asset = Asset {
        header: Header {
            tool: format!("vdbcook {}", env!("CARGO_PKG_VERSION")),
            options: CookOptions {
                format: eopts.format,
                max_error: shared_budget,
                range: eopts.range,
                bc7_quality: eopts.bc7_quality.name().to_string(),
                grid: requested,
                replace_non_finite,
                allow_gaps,
            },
            grid_name: label,
            source,
            frames: infos,
            index_offset: offset,
            root_dims,
            index_to_world: asset_index_to_world(transform, offset),
            source_map: transform.kind.type_name().to_string(),
            voxel_size: transform.voxel_size(),
            background: bgs[0],
            brick_counts: enc.brick_counts,
            sections: Vec::new(),
            content_hash: 0,
            channels: if n == 1 {
                Vec::new()
            } else {
                channels
                    .iter()
                    .zip(chan_budget)
                    .map(|(s, b)| ChannelInfo {
                        name: s.name.clone(),
                        background: s.background,
                        max_error: *b,
                        active_voxels: s.active.clone(),
                    })
                    .collect()
            },
            lod_levels,
            lod_first,
        },
        roots,
        frame_ranges: rg.frames,
        l2_masks: std::mem::take(&mut pool.l2_masks),
        l2_base,
        l2_prefix,
        l2_ranges: rg.l2,
        l3_refs,
        tiles: std::mem::take(&mut pool.tiles),
        brick_ranges: rg.bricks,
        brick_quant: enc.brick_quant,
        payloads: enc.payloads,
    };
    asset.validate().map_err(|e| {
        CookError::Internal(format!(
            "internal error: cooked asset fails validation: {e}"
        ))
    })?;
    let (bytes, _) = asset
        .to_bytes()
        .map_err(|e| CookError::Internal(e.to_string()))?;
    let cost = per_channel
        .iter()
        .zip(&empty_refs)
        .map(|(set, &e)| ChannelCost {
            bricks: set.len() as u64,
            atlas_bytes: set
                .iter()
                .map(|&b| asset.brick_format(b).0.bytes_per_brick() as u64)
                .sum(),
            empty_leaf_refs: e,
        })
        .collect();
    Ok(Assembled {
        asset,
        bytes,
        figures: Figures {
            errors,
            channels: n,
            cost,
        },
        source_bricks,
        source_tiles,
        unique_bricks,
        after_clustering,
        tiles_made: enc_tiles,
        lod_max_abs,
    })
}

/// Raw bytes of each section (what a GPU upload holds).
pub fn section_sizes(asset: &Asset) -> Vec<(&'static str, u64)> {
    let pair = 8u64;
    let mut v = vec![
        ("roots", asset.roots.len() as u64 * 4),
        ("frame_ranges", asset.frame_ranges.len() as u64 * pair),
        ("l2_masks", asset.l2_masks.len() as u64 * 8),
        ("l2_base", asset.l2_base.len() as u64 * 4),
        ("l2_prefix", asset.l2_prefix.len() as u64 * 2),
        ("l2_ranges", asset.l2_ranges.len() as u64 * pair),
        ("l3_refs", asset.l3_refs.len() as u64 * 4),
        ("tiles", asset.tiles.len() as u64 * 4),
        ("brick_ranges", asset.brick_ranges.len() as u64 * pair),
        ("brick_quant", asset.brick_quant.len() as u64 * pair),
    ];
    // One entry per section the file holds: the packed atlases share one (format version 7).
    let packed: u64 = PayloadFormat::PACKED
        .iter()
        .map(|f| asset.payloads[f.rank()].len() as u64)
        .sum();
    for (f, p) in PayloadFormat::ORDER.iter().zip(&asset.payloads) {
        if f.packed_bits().is_none() {
            v.push((SectionKind::payload(*f).name(), p.len() as u64));
        }
    }
    if asset.header.format_version() >= vdbcook_asset::FORMAT_VERSION {
        v.push((SectionKind::PayloadPacked.name(), packed));
    }
    v
}

/// GPU bytes split into topology (roots, nodes, refs, tiles, node ranges) and atlas (the brick
/// payloads and the per-brick value and quantization ranges that travel with them).
pub fn topology_and_atlas(sizes: &[(&'static str, u64)]) -> (u64, u64) {
    let atlas_part =
        |k: &str| k.starts_with("payload") || k == "brick_ranges" || k == "brick_quant";
    let t = sizes
        .iter()
        .filter(|(k, _)| !atlas_part(k))
        .map(|(_, n)| n)
        .sum();
    let a = sizes
        .iter()
        .filter(|(k, _)| atlas_part(k))
        .map(|(_, n)| n)
        .sum();
    (t, a)
}
