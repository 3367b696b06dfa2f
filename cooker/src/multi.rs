//! Multi-channel cooks (`cook --grids density,temperature,flame`): several float grids of a
//! sequence in one asset (format version 3) on one shared topology, the union of their active
//! regions. Each leaf slot holds one ref per channel (`EMPTY` where that channel is its own
//! background), bricks of every channel go to one deduplicated pool, and each brick is encoded
//! under the smallest budget of the channels that read it, so every channel's `--max-error`
//! holds on every voxel. Single-grid cooks never come here: their bytes stay what `cook.rs`
//! writes (version 2).
//!
//! Not supported with several channels (refused by [`validate`]): `--clusters` (k-means over
//! bricks of mixed units), `--max-bytes` (one scalar search) and `--range global`.

use std::collections::{BTreeSet, HashMap};
use std::time::Instant;

use rayon::prelude::*;
use vdbcook_asset::*;
use vdbcook_vdb::sequence::Frame;
use vdbcook_vdb::{ErrorKind, Transform, VdbFile};

use crate::bcenc::Bc7Quality;
use crate::build::{build_frame, BuiltFrame, LeafContent, NonFinite, Region};
use crate::cook::{
    asset_index_to_world, err, frame_info, peak_memory_bytes, read_named_in, section_sizes,
    topology_and_atlas, use_errors, Args, Cooked,
};
use crate::cook_report::{self as report, ChannelReport, CookReport, DroppedChannel};
use crate::encode;
use crate::errors::CliError;
use crate::pool::{ranges, Pool};
use crate::progress::Progress;

/// `--grids auto`: the grids are picked from the first frame (`grid_pick`) when the cook starts.
pub fn is_auto(a: &Args) -> bool {
    matches!(&a.grids[..], [g] if g == "auto")
}

/// Checks the multi-channel options (`--grids`, per-channel `--max-error`) before any work;
/// `--grids auto` counts as several grids whose names are not known yet (checked again once
/// picked).
pub fn validate(a: &Args) -> Result<(), CliError> {
    let bad = |m: String| Err(CliError::Usage(m));
    let auto = is_auto(a);
    if a.grids.len() > MAX_CHANNELS {
        return bad(format!(
            "--grids names {} grids; an asset holds at most {MAX_CHANNELS}",
            a.grids.len()
        ));
    }
    for (i, g) in a.grids.iter().enumerate() {
        if g.trim().is_empty() {
            return bad("--grids has an empty name".into());
        }
        if a.grids[..i].contains(g) {
            return bad(format!("--grids names '{g}' twice"));
        }
    }
    for (name, e) in &a.max_error_per {
        let known = if auto {
            true
        } else if a.grids.is_empty() {
            a.grid.as_deref() == Some(name.as_str()) || (a.grid.is_none() && name == "density")
        } else {
            a.grids.contains(name)
        };
        if !known {
            return bad(format!(
                "--max-error {name}={e}: '{name}' is not a cooked grid{}",
                if a.grids.is_empty() {
                    " (per-channel budgets name grids of --grids)".to_string()
                } else {
                    format!(" (--grids {})", a.grids.join(","))
                }
            ));
        }
        if !(e.is_finite() && *e > 0.0) {
            return bad(format!(
                "--max-error {name}={e} is out of range: E must be a finite number > 0"
            ));
        }
    }
    if a.grids.is_empty() && a.max_error_per.len() > 1 {
        return bad("budgets for several grids need --grids naming them".into());
    }
    if a.grids.len() > 1 || auto {
        let refuse = |what: &str| {
            bad(format!(
                "{what} is not supported with several grids (--grids) yet: cook the channels \
                 without it"
            ))
        };
        if a.clusters.is_some() {
            return refuse("--clusters");
        }
        if a.max_bytes.is_some() {
            return refuse("--max-bytes");
        }
        if a.range == "global" {
            return refuse("--range global");
        }
        if a.manifest.is_some() {
            return refuse("--manifest");
        }
    }
    Ok(())
}

/// One channel of one frame, read and built.
struct Channel {
    label: String,
    transform: Transform,
    background: f32,
    built: BuiltFrame,
}

/// One frame's channels (`None`: the grid is missing, `--allow-missing-grid`).
struct PreparedFrame {
    frame: Frame,
    channels: Vec<Option<Channel>>,
}

fn prepare(
    f: &Frame,
    names: &[String],
    allow_missing: bool,
    hint: bool,
    nf: NonFinite,
) -> Result<PreparedFrame, CliError> {
    let file = VdbFile::open(&f.path)?;
    let mut channels = Vec::with_capacity(names.len());
    for name in names {
        let how = "named by --grids";
        let Some(loaded) = read_named_in(&file, f, name, how, allow_missing, hint)? else {
            channels.push(None);
            continue;
        };
        let label = loaded.grid_label.clone();
        let (transform, background) = (loaded.grid.transform.clone(), loaded.grid.background);
        let built = build_frame(loaded.grid, nf)
            .map_err(|m| err(&f.path, ErrorKind::Corrupt, format!("grid '{label}': {m}")))?;
        channels.push(Some(Channel {
            label,
            transform,
            background,
            built,
        }));
    }
    Ok(PreparedFrame {
        frame: f.clone(),
        channels,
    })
}

/// The pool plus what a multi-channel cook tracks per brick and per frame.
struct Channels {
    n: usize,
    pool: Pool,
    /// Per pool brick: a bit per channel that reads it.
    brick_channels: Vec<u8>,
    /// Constant 128³ regions (no channel has leaves there): the node per tuple of refs.
    tile_nodes: HashMap<Vec<u32>, u32>,
}

impl Channels {
    /// Adds one frame's channels to the pool: per 128³ region of the union, an L2 node over the
    /// union of the channels' leaf slots with `n` refs per slot; `pool.uses` gains `n` lists
    /// (channel `c` of frame `f` at `f·n + c`).
    fn add(&mut self, built: &[Option<BuiltFrame>]) {
        let n = self.n;
        let pool = &mut self.pool;
        if pool.track_uses {
            pool.uses.extend((0..n).map(|_| Vec::new()));
        }
        let first_use = pool.uses.len().saturating_sub(n);
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
                    Some(Region::Tile(v)) => pool.tile(*v),
                    _ => EMPTY,
                })
                .collect();
            if !has_leaves {
                // Every channel is a constant (or its background) over the region: a full node
                // of tile refs, built once per tuple of values.
                let node = match self.tile_nodes.get(&region_tile) {
                    Some(&nd) => nd,
                    None => {
                        let refs: Vec<u32> = region_tile
                            .iter()
                            .copied()
                            .cycle()
                            .take(L2_SLOTS * n)
                            .collect();
                        let nd = pool.node([u64::MAX; L2_WORDS], refs);
                        self.tile_nodes.insert(region_tile, nd);
                        nd
                    }
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
                                        pool.source_tiles += 1;
                                        pool.tile(v)
                                    }
                                    LeafContent::Brick { index, hash } => {
                                        pool.source_bricks += 1;
                                        let bricks = &built[c].as_ref().expect("has leaves").bricks;
                                        let i = index as usize * BRICK_VOXELS;
                                        let values: &[f32; BRICK_VOXELS] =
                                            bricks[i..i + BRICK_VOXELS].try_into().expect("512");
                                        let b = pool.brick_unrecorded(values, hash);
                                        if pool.track_uses {
                                            pool.uses[first_use + c].push(b);
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
            entries.push((o, pool.node(mask, refs)));
        }
        pool.frames.push(entries);
    }
}

/// Per channel: what the sequence check and the report need.
struct ChannelState {
    name: String,
    background: Option<f32>,
    /// Frame whose background set `background` (for the error message).
    background_from: String,
    value_range: [f32; 2],
    active: Vec<u64>,
}

/// Cooks `frames` into a multi-channel asset of the grids `a.grids` (at least two).
pub fn cook_channels(a: &Args, frames: Vec<Frame>) -> Result<Cooked, CliError> {
    let t0 = Instant::now();
    let names = &a.grids;
    let n = names.len();
    let format = a
        .format
        .as_deref()
        .map(|f| PayloadFormat::parse(f).expect("clap checked"));
    let given = |c: usize| -> Option<f32> {
        a.max_error_per
            .iter()
            .find(|(nm, _)| nm == &names[c])
            .map(|(_, e)| *e)
            .or(a.max_error)
    };
    let any_given = (0..n).any(|c| given(c).is_some());
    let mut eopts = encode::EncodeOptions {
        format: format.unwrap_or(if any_given {
            PayloadFormat::Bc7
        } else {
            PayloadFormat::F32
        }),
        format_given: format.is_some(),
        max_error: None,
        lossy_tiles: any_given,
        range: RangeMode::Brick,
        bc7_quality: Bc7Quality::parse(&a.bc7_quality)
            .ok_or_else(|| CliError::Usage(format!("unknown --bc7-quality '{}'", a.bc7_quality)))?,
    };
    let lossy = eopts.format != PayloadFormat::F32 || any_given;
    let nf = NonFinite {
        replace_with: a.replace_non_finite,
        hint: !a.no_non_finite_flag,
    };
    let mut ch = Channels {
        n,
        pool: Pool::new(lossy),
        brick_channels: Vec::new(),
        tile_nodes: HashMap::new(),
    };
    let mut states: Vec<ChannelState> = names
        .iter()
        .map(|nm| ChannelState {
            name: nm.clone(),
            background: None,
            background_from: String::new(),
            value_range: [f32::INFINITY, f32::NEG_INFINITY],
            active: Vec::with_capacity(frames.len()),
        })
        .collect();
    let mut first: Option<(Frame, Transform, String)> = None;
    let mut missing: Vec<String> = Vec::new();
    let mut infos = Vec::with_capacity(frames.len());
    let progress = Progress::with(a.progress.clone(), a.json || a.quiet, !a.quiet);
    let stage = progress.stage("read, build, dedup", "frames");
    crate::progress::add_total(frames.len() as u64);
    let (mut read_s, mut dedup_s) = (0.0, 0.0);
    let chunk = (rayon::current_num_threads() * 2).max(2);
    for group in frames.chunks(chunk) {
        let t = Instant::now();
        let prepared: Vec<Result<PreparedFrame, CliError>> = group
            .par_iter()
            .map(|f| prepare(f, names, a.allow_missing_grid, !a.quiet, nf))
            .collect();
        read_s += t.elapsed().as_secs_f64();
        let t = Instant::now();
        for p in prepared {
            let PreparedFrame { frame, channels } = p?;
            let mut built = Vec::with_capacity(n);
            let mut frame_active = 0u64;
            for (c, chan) in channels.into_iter().enumerate() {
                let st = &mut states[c];
                let Some(chan) = chan else {
                    missing.push(format!("{} ({})", frame.path.display(), st.name));
                    st.active.push(0);
                    built.push(None);
                    continue;
                };
                match &first {
                    None => {
                        if !chan.transform.kind.is_linear() {
                            return Err(err(
                                &frame.path,
                                ErrorKind::Unsupported,
                                format!(
                                    "grid '{}' has a {} transform; vdbcook cooks linear \
                                     transforms only",
                                    chan.label,
                                    chan.transform.kind.type_name()
                                ),
                            ));
                        }
                        first = Some((frame.clone(), chan.transform.clone(), chan.label.clone()));
                    }
                    Some((f0, t0, l0)) => {
                        if !chan.transform.approx_eq(t0, 1e-9) {
                            return Err(err(
                                &frame.path,
                                ErrorKind::Sequence,
                                format!(
                                    "grid '{}' (voxel size {:?}) and grid '{l0}' of {} (voxel \
                                     size {:?}) have different transforms; the channels of an \
                                     asset share one transform (resampling is not supported)",
                                    chan.label,
                                    chan.transform.voxel_size(),
                                    f0.path.display(),
                                    t0.voxel_size()
                                ),
                            ));
                        }
                    }
                }
                match st.background {
                    None => {
                        st.background = Some(chan.background);
                        st.background_from = frame.path.display().to_string();
                    }
                    Some(bg) if bg.to_bits() != chan.background.to_bits() => {
                        return Err(err(
                            &frame.path,
                            ErrorKind::Sequence,
                            format!(
                                "grid '{}': background {} differs from frame {} ({bg})",
                                chan.label, chan.background, st.background_from
                            ),
                        ));
                    }
                    Some(_) => {}
                }
                if let Some(r) = chan.built.value_range {
                    st.value_range = [st.value_range[0].min(r[0]), st.value_range[1].max(r[1])];
                }
                st.active.push(chan.built.active_voxels);
                frame_active += chan.built.active_voxels;
                built.push(Some(chan.built));
            }
            infos.push(frame_info(&frame, frame_active));
            ch.add(&built);
            crate::progress::advance(1);
        }
        dedup_s += t.elapsed().as_secs_f64();
    }
    stage.finish();
    let Some((f0, transform, _)) = first else {
        return Err(err(
            &frames[0].path,
            ErrorKind::GridSelection,
            format!("no frame has any of the grids {}", names.join(", ")),
        ));
    };
    if let Some(st) = states.iter().find(|s| s.background.is_none()) {
        return Err(err(
            &frames[0].path,
            ErrorKind::GridSelection,
            format!("no frame has the grid '{}' (named by --grids)", st.name),
        ));
    }
    let bgs: Vec<f32> = states
        .iter()
        .map(|s| s.background.expect("checked"))
        .collect();
    if !missing.is_empty() {
        progress.note(&format!(
            "note: {} grid(s) missing from frames are cooked as background \
             (--allow-missing-grid): {}",
            missing.len(),
            missing.join(", ")
        ));
    }
    let (offset, root_dims) = ch
        .pool
        .extent()
        .map_err(|m| err(&f0.path, ErrorKind::Unsupported, m))?;

    // Budgets per channel: given, else (lossy) the default share of its own value range.
    let budgets: Vec<Option<(f32, &str)>> = (0..n)
        .map(|c| match (given(c), lossy) {
            (Some(e), _) => Some((e, "given")),
            (None, true) => {
                let r = states[c].value_range;
                let r = [r[0].min(bgs[c]), r[1].max(bgs[c])];
                Some((encode::default_budget(r), "default"))
            }
            (None, false) => None,
        })
        .collect();
    // Channels after the first that carry nothing are not cooked: cook the others again.
    let dropped: Vec<DroppedChannel> = (1..n)
        .filter(|_| !a.keep_empty_channels)
        .filter_map(|c| {
            let (r, bg) = (states[c].value_range, bgs[c]);
            let e = budgets[c].map(|b| b.0);
            let none = r[0] > r[1]; // never set: no active value
            let e0 = e.unwrap_or(0.0);
            (none || (r[0] >= bg - e0 && r[1] <= bg + e0)).then(|| DroppedChannel {
                name: names[c].clone(),
                background: bg,
                value_range: (!none).then_some(r),
                max_error: e,
            })
        })
        .collect();
    if !dropped.is_empty() {
        progress.note(&format!(
            "note: not cooked, as they carry nothing (every active value within the channel's \
             budget of its background, or none; --keep-empty-channels keeps them): {}",
            dropped
                .iter()
                .map(|d| match d.value_range {
                    None => format!("'{}' (no active value)", d.name),
                    Some([lo, hi]) => format!(
                        "'{}' (values {lo}..{hi}, background {}{})",
                        d.name,
                        d.background,
                        d.max_error
                            .map(|e| format!(", budget {e}"))
                            .unwrap_or_default()
                    ),
                })
                .collect::<Vec<_>>()
                .join(", ")
        ));
        let mut kept = a.clone();
        kept.grids.retain(|g| !dropped.iter().any(|d| &d.name == g));
        kept.max_error_per.retain(|(g, _)| kept.grids.contains(g));
        kept.keep_empty_channels = true;
        let mut cooked = crate::cook::cook_frames(&kept, frames)?;
        cooked.report.dropped_channels = dropped;
        return Ok(cooked);
    }
    let t = Instant::now();
    let stage = progress.stage("encode", "blocks");
    let pool = &mut ch.pool;
    let n_pool = pool.brick_count();
    ch.brick_channels.resize(n_pool, 0);
    let enc = if lossy {
        let per_brick: Vec<f32> = ch
            .brick_channels
            .iter()
            .map(|&m| {
                (0..n)
                    .filter(|c| m & (1 << c) != 0)
                    .filter_map(|c| budgets[c].map(|b| b.0))
                    .fold(f32::INFINITY, f32::min)
            })
            .collect();
        eopts.max_error = budgets.iter().flatten().map(|b| b.0).reduce(f32::min);
        encode::encode_budgets(&pool.bricks, &eopts, Some(&per_brick))
    } else {
        encode::encode(&pool.bricks, &eopts)
    }
    .map_err(|m| err(&f0.path, ErrorKind::Unsupported, m))?;
    let remap = pool.apply_encoding(enc.remap.iter().copied(), &enc.new_tiles);
    let decoded = enc.decoded_or(&pool.bricks);
    let root_len = root_dims.iter().map(|&d| d as usize).product::<usize>();
    let roots = pool.roots(offset, root_dims);
    let rg = ranges(
        enc.brick_ranges.clone(),
        &pool.tiles,
        &pool.l2_refs,
        &roots,
        root_len,
        &bgs,
    );
    let (l2_base, l2_prefix, l3_refs) = pool.layout(n);
    // Error per (frame, channel) over every brick use; tiles from the source are exact, lossy
    // tiles are in `decoded`.
    let errs = use_errors(&pool.uses, &pool.bricks, decoded, |b| enc.slack[b as usize]);
    let err_of = |f: usize, c: usize| errs.get(f * n + c).copied().unwrap_or_default();
    // Stored bricks and atlas bytes each channel reads.
    let mut per_channel_bricks = vec![BTreeSet::new(); n];
    for (b, &m) in ch.brick_channels.iter().enumerate() {
        let r = remap[b];
        if r & TILE_BIT == 0 {
            for (c, set) in per_channel_bricks.iter_mut().enumerate() {
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
    let unique_bricks = pool.brick_count();
    pool.bricks = Vec::new();
    pool.uses = Vec::new();
    let m = asset_index_to_world(&transform, offset);
    let shared_budget = match &budgets[..] {
        [b0, rest @ ..] if rest.iter().all(|b| b.map(|x| x.0) == b0.map(|x| x.0)) => {
            b0.map(|x| x.0)
        }
        _ => None,
    };
    let channels: Vec<ChannelInfo> = states
        .iter()
        .zip(&budgets)
        .zip(&bgs)
        .map(|((s, b), &bg)| ChannelInfo {
            name: s.name.clone(),
            background: bg,
            max_error: b.map(|x| x.0),
            active_voxels: s.active.clone(),
        })
        .collect();
    let asset = Asset {
        header: Header {
            tool: format!("vdbcook {}", env!("CARGO_PKG_VERSION")),
            options: CookOptions {
                format: eopts.format,
                max_error: shared_budget,
                range: eopts.range,
                bc7_quality: eopts.bc7_quality.name().to_string(),
                grid: None,
                replace_non_finite: a.replace_non_finite,
                allow_gaps: a.allow_gaps,
            },
            grid_name: names[0].clone(),
            frames: infos,
            index_offset: offset,
            root_dims,
            index_to_world: m,
            source_map: transform.kind.type_name().to_string(),
            voxel_size: transform.voxel_size(),
            background: bgs[0],
            brick_counts: enc.brick_counts,
            sections: Vec::new(),
            content_hash: 0,
            channels,
            lod_levels: 0,
            lod_first: 1,
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
        brick_quant: enc.brick_quant.clone(),
        payloads: enc.payloads.clone(),
    };
    asset.validate().map_err(|e| {
        CliError::Other(format!(
            "internal error: cooked asset fails validation: {e}"
        ))
    })?;
    let (bytes, _) = asset
        .to_bytes()
        .map_err(|e| CliError::Other(e.to_string()))?;
    let encode_s = t.elapsed().as_secs_f64();
    stage.finish();

    let nframes = asset.frame_count();
    let figures = |sum_sq: f64, max_abs: f64, gpu: f64, active: u64, peak: Option<f64>| {
        let rmse = if active > 0 {
            (sum_sq / active as f64).sqrt()
        } else {
            0.0
        };
        report::ErrorFigures {
            rmse,
            psnr_db: peak
                .filter(|&p| rmse > 0.0 && p > 0.0)
                .map(|p| 20.0 * (p / rmse).log10()),
            max_abs,
            exact: max_abs == 0.0,
            max_abs_any_gpu: gpu,
        }
    };
    let channel_reports: Vec<ChannelReport> = (0..n)
        .map(|c| {
            let s = &states[c];
            let (mut sq, mut mx, mut gpu) = (0.0, 0.0f64, 0.0f64);
            for f in 0..nframes {
                let e = err_of(f, c);
                sq += e.sum_sq;
                mx = mx.max(e.max_abs);
                gpu = gpu.max(e.gpu_bound);
            }
            let active: u64 = s.active.iter().sum();
            let vr = (s.value_range[0] <= s.value_range[1]).then_some(s.value_range);
            let peak = vr.map(|r| (r[1] - r[0]) as f64);
            let bricks = &per_channel_bricks[c];
            ChannelReport {
                name: s.name.clone(),
                background: bgs[c],
                active_voxels: active,
                value_range: vr,
                max_error: budgets[c].map(|b| b.0),
                max_error_source: budgets[c].map(|b| b.1.to_string()),
                error: figures(sq, mx, gpu, active, peak),
                bricks: bricks.len() as u64,
                atlas_bytes: bricks
                    .iter()
                    .map(|&b| asset.brick_format(b).0.bytes_per_brick() as u64)
                    .sum(),
                empty_leaf_refs: empty_refs[c],
            }
        })
        .collect();
    let active: u64 = asset.header.frames.iter().map(|f| f.active_voxels).sum();
    let sizes = section_sizes(&asset);
    let (topology, atlas) = topology_and_atlas(&sizes);
    let bpv = |b: u64| {
        if active > 0 {
            b as f64 * 8.0 / active as f64
        } else {
            0.0
        }
    };
    let total_sq: f64 = errs.iter().map(|e| e.sum_sq).sum();
    let total_max = errs.iter().fold(0.0f64, |m, e| m.max(e.max_abs));
    let total_gpu = errs.iter().fold(0.0f64, |m, e| m.max(e.gpu_bound));
    let mut overall = figures(total_sq, total_max, total_gpu, active, None);
    overall.psnr_db = channel_reports
        .iter()
        .filter_map(|c| c.error.psnr_db)
        .reduce(f64::min);
    let [r0, r1, r2, r3, r4] = enc.representation.per_format;
    let report = CookReport {
        output: a.output.display().to_string(),
        format: eopts.format.name().to_string(),
        grid: names[0].clone(),
        missing_grid_frames: missing,
        frames: nframes,
        active_voxels: active,
        bricks: report::Bricks {
            source: ch.pool.source_bricks,
            unique: unique_bricks as u64,
            after_clustering: unique_bricks as u64,
            stored: asset.brick_count() as u64,
            tiles: asset.tiles.len() as u64,
            tile_leaves: ch.pool.source_tiles,
        },
        nodes: report::Nodes {
            l2: asset.l2_count() as u64,
            leaf_refs: asset.l3_refs.len() as u64,
            root_dims,
        },
        bytes: report::Bytes {
            topology,
            atlas,
            file: bytes.len() as u64,
        },
        bits_per_active_voxel: bpv(bytes.len() as u64),
        bits_per_active_voxel_gpu: bpv(topology + atlas),
        topology_bits_per_active_voxel: bpv(topology),
        error: overall,
        frame_errors: (0..nframes)
            .map(|f| {
                let (mut sq, mut mx) = (0.0, 0.0f64);
                for c in 0..n {
                    sq += err_of(f, c).sum_sq;
                    mx = mx.max(err_of(f, c).max_abs);
                }
                let act = asset.header.frames[f].active_voxels;
                report::FrameError {
                    frame: f,
                    number: asset.header.frames[f].number,
                    rmse: if act > 0 {
                        (sq / act as f64).sqrt()
                    } else {
                        0.0
                    },
                    psnr_db: None,
                    max_abs: mx,
                }
            })
            .collect(),
        clustering: None,
        representations: report::Representations {
            tile: enc.representation.tile,
            bc7: r0,
            bc4: r1,
            unorm8: r2,
            f16: r3,
            f32: r4,
        },
        max_error: shared_budget,
        max_error_source: budgets[0].map(|b| b.1.to_string()),
        max_bytes: None,
        bc7_quality: eopts.bc7_quality.name().to_string(),
        range: "brick".into(),
        peak_memory_bytes: peak_memory_bytes(),
        seconds: report::Seconds {
            total: t0.elapsed().as_secs_f64(),
            read: read_s,
            build: 0.0,
            dedup: dedup_s,
            cluster: 0.0,
            encode: encode_s,
            write: 0.0,
        },
        channels: channel_reports,
        dropped_channels: Vec::new(),
        lod: None,
    };
    Ok(Cooked {
        asset,
        bytes,
        report,
    })
}
