//! The one cook pipeline: select → read, build, pool ([`crate::ingest`]) → drop empty channels →
//! lod → cluster (k-means) → budget (given, default guard or the `--max-bytes` search) → guard
//! and encode → assemble → report. A single grid is the one-channel case of several, so every
//! option means the same for both and composes with every other; the only difference a single
//! grid keeps is its layout (a constant region is a root tile, the header lists no channels), so
//! its assets stay byte for byte what they always were.

use std::sync::Arc;
use std::time::Instant;

use vdbcook_asset::{Asset, PayloadFormat, L2_WORDS};
use vdbcook_vdb::sequence::Frame;
use vdbcook_vdb::{ErrorKind, VdbFile};

use crate::assemble::{self, Assembled};
use crate::build::NonFinite;
use crate::cluster::{self, ClusterOptions, Grouped, Guarded};
use crate::encode::{self, EncodeOptions, Encoded};
use crate::error::{input, CookError};
use crate::frames::choose_grid;
use crate::ingest::{self, ChannelSource, ChannelState, Ingested, ReadOptions};
use crate::options::{Budget, CookOptions, Grids, Lod};
use crate::progress::{Progress, ProgressSink};
use crate::report::{self, CookReport, DroppedChannel};
use crate::{budget, lod};

/// Where a cook reports, and what its errors may suggest.
pub struct Context {
    pub progress: Progress,
    /// Errors may suggest `--allow-missing-grid` and `--replace-non-finite` (the caller has them).
    pub hint_missing_grid: bool,
    pub hint_non_finite: bool,
}

impl Context {
    /// Stages and notes into `sink` (`None`: nothing is reported).
    pub fn with_sink(sink: Option<Arc<dyn ProgressSink>>) -> Context {
        Context {
            progress: Progress::with(sink, true, false),
            hint_missing_grid: true,
            hint_non_finite: true,
        }
    }
    /// Nothing reported.
    pub fn quiet() -> Context {
        Context::with_sink(None)
    }
}

/// A cook held in memory: the asset, its file bytes and the report `cook --json` prints
/// (without `output` and `seconds.write`, which only the writer knows).
pub struct Cooked {
    pub asset: Asset,
    pub bytes: Vec<u8>,
    pub report: CookReport,
}

/// Cooks `frames` (resolved by [`crate::frames::resolve_frames`]) with `opts`.
pub fn cook(opts: &CookOptions, frames: Vec<Frame>, cx: &Context) -> Result<Cooked, CookError> {
    opts.validate()?;
    if frames.is_empty() {
        return Err(CookError::Options("no frames to cook".into()));
    }
    let (sources, requested) = select(opts, &frames, cx)?;
    cook_sources(opts, &frames, &sources, requested, cx)
}

/// [`cook`] of the frames `inputs` name (files, folders, frame patterns or globs), in sequence
/// order, then those `opts.frames` selects.
pub fn cook_inputs(
    inputs: &[String],
    opts: &CookOptions,
    cx: &Context,
) -> Result<Cooked, CookError> {
    opts.validate()?;
    let frames = crate::frames::resolve_frames(inputs, opts.allow_gaps, opts.frames)?;
    cook(opts, frames, cx)
}

/// The grids every frame gives, as channels, and the `--grid` a single-grid cook records.
fn select(
    opts: &CookOptions,
    frames: &[Frame],
    cx: &Context,
) -> Result<(Vec<ChannelSource>, Option<String>), CookError> {
    let one = |g: Option<&str>| -> Result<(Vec<ChannelSource>, Option<String>), CookError> {
        let (name, how) = choose_grid(frames, g)?;
        Ok((vec![ChannelSource { name, how }], g.map(str::to_string)))
    };
    let several = |names: &[String]| {
        names
            .iter()
            .map(|n| ChannelSource {
                name: n.clone(),
                how: "named by --grids".into(),
            })
            .collect::<Vec<_>>()
    };
    match &opts.grids {
        Grids::Default => one(None),
        Grids::One(g) => one(Some(g)),
        Grids::Several(g) if g.len() == 1 => one(Some(&g[0])),
        Grids::Several(g) => Ok((several(g), None)),
        Grids::Auto => {
            let f0 = &frames[0].path;
            let file = VdbFile::open(f0)?;
            let pick = crate::grid_pick::suggest(&file);
            if pick.grids.is_empty() {
                let floats = file.float_grid_labels();
                return Err(input(
                    f0,
                    ErrorKind::GridSelection,
                    format!(
                        "--grids auto: no float grid here is named as a density, temperature or \
                         flame grid (float grids: {}); name the grids with --grids A,B",
                        if floats.is_empty() {
                            "none".into()
                        } else {
                            floats.join(", ")
                        }
                    ),
                ));
            }
            cx.progress.note(&format!(
                "note: --grids auto cooks {} (named as in {}){}",
                pick.grids.join(","),
                f0.display(),
                pick.skipped
                    .iter()
                    .map(|(g, why)| format!("; not '{g}': {why}"))
                    .collect::<String>()
            ));
            // The per-channel budgets must name picked grids.
            CookOptions {
                grids: Grids::Several(pick.grids.clone()),
                ..opts.clone()
            }
            .validate()?;
            if pick.grids.len() == 1 {
                one(Some(&pick.grids[0]))
            } else {
                Ok((several(&pick.grids), None))
            }
        }
    }
}

/// The payload a cook starts from: `--format`, else BC7 under a bound, else f32.
fn start_format(opts: &CookOptions) -> PayloadFormat {
    opts.format.unwrap_or(if opts.bounded() {
        PayloadFormat::Bc7
    } else {
        PayloadFormat::F32
    })
}

/// Each channel's budget before any size search, and where it came from: given, the default
/// guard of a lossy cook (a share of the channel's range), or none.
fn channel_budgets(
    opts: &CookOptions,
    channels: &[ChannelState],
    lossy: bool,
) -> Vec<Option<(f32, &'static str)>> {
    channels
        .iter()
        .map(|c| match (opts.max_error_of(&c.name), lossy) {
            (Some(e), _) => Some((e, "given")),
            (None, true) => Some((encode::default_budget(c.range_with_background()), "default")),
            (None, false) => None,
        })
        .collect()
}

fn cook_sources(
    opts: &CookOptions,
    frames: &[Frame],
    sources: &[ChannelSource],
    requested: Option<String>,
    cx: &Context,
) -> Result<Cooked, CookError> {
    let t0 = Instant::now();
    let progress = &cx.progress;
    let n = sources.len();
    let format = start_format(opts);
    let lossy = format != PayloadFormat::F32 || opts.bounded() || opts.clustering.is_some();
    let read = ReadOptions {
        allow_missing: opts.allow_missing_grid,
        hint_missing: cx.hint_missing_grid,
        non_finite: NonFinite {
            replace_with: opts.replace_non_finite,
            hint: cx.hint_non_finite,
        },
        track_uses: lossy,
    };
    let Ingested {
        mut pool,
        channels,
        transform,
        first_path,
        label,
        source,
        infos,
        missing,
        read_s,
        build_s,
        pool_s,
    } = ingest::ingest(frames, sources, read, progress)?;
    if !missing.is_empty() {
        progress.note(&if n == 1 {
            format!(
                "note: {} frame(s) have no grid '{}' and are cooked as empty frames \
                 (--allow-missing-grid): {}",
                missing.len(),
                sources[0].name,
                missing.join(", ")
            )
        } else {
            format!(
                "note: {} grid(s) missing from frames are cooked as background \
                 (--allow-missing-grid): {}",
                missing.len(),
                missing.join(", ")
            )
        });
    }
    let budgets = channel_budgets(opts, &channels, lossy);

    // Channels after the first that carry nothing are not cooked: cook the others again.
    let dropped: Vec<DroppedChannel> = (1..n)
        .filter(|_| !opts.keep_empty_channels)
        .filter_map(|c| {
            let (active, bg) = (channels[c].active_range(), channels[c].background);
            let e = budgets[c].map(|b| b.0);
            let e0 = e.unwrap_or(0.0);
            active
                .is_none_or(|r| r[0] >= bg - e0 && r[1] <= bg + e0)
                .then(|| DroppedChannel {
                    name: channels[c].name.clone(),
                    background: bg,
                    value_range: active,
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
        drop(pool);
        let kept: Vec<ChannelSource> = sources
            .iter()
            .filter(|s| !dropped.iter().any(|d| d.name == s.name))
            .cloned()
            .collect();
        let requested = (kept.len() == 1).then(|| kept[0].name.clone());
        let mut cooked = cook_sources(opts, frames, &kept, requested, cx)?;
        cooked.report.dropped_channels = dropped;
        return Ok(cooked);
    }

    let (offset, root_dims) = pool
        .extent()
        .map_err(|m| input(&first_path, ErrorKind::Unsupported, m))?;
    let bgs: Vec<f32> = channels.iter().map(|c| c.background).collect();

    // Levels of detail join the pool (exact values) before clustering and encoding.
    let (lod_first, lod_levels) = match opts.lod {
        None => (1, 0),
        Some(Lod { levels, first }) => {
            let last = lod::resolve(levels, root_dims);
            if first > last {
                return Err(input(
                    &first_path,
                    ErrorKind::Unsupported,
                    format!(
                        "--lod-from {first}: an extent of {} voxels has levels 1 to {last} (the \
                         last one brick wide); give --lod-from {last} or less",
                        root_dims.iter().max().copied().unwrap_or(1) as u64 * 128
                    ),
                ));
            }
            let stage = progress.stage("level of detail", "levels");
            lod::add_levels(&mut pool, frames.len(), (first, last), offset, &bgs);
            stage.finish();
            (first, last + 1 - first)
        }
    };
    let lod_bricks = if lod_levels > 0 {
        lod::pool_bricks(&pool, frames.len())
    } else {
        Vec::new()
    };

    // k-means (optional): independent of the budget, which only guards its members.
    let tc = Instant::now();
    let grouped: Option<Grouped> = opts.clustering.map(|c| {
        let stage = progress.stage("cluster", "bricks");
        let g = cluster::cluster_groups(
            &pool.bricks,
            &pool.brick_channels,
            &ClusterOptions {
                clusters: c.clusters,
                iterations: c.iterations,
                variance_threshold: c.variance_threshold,
                seed: 1,
            },
        );
        stage.finish();
        g
    });
    let mut cluster_s = tc.elapsed().as_secs_f64();

    let mut eopts = EncodeOptions {
        format,
        format_given: opts.format.is_some(),
        max_error: None,
        lossy_tiles: opts.bounded(),
        range: opts.range,
        bc7_quality: opts.bc7_quality,
        packed: opts.packed,
    };
    // The bound of each channel; per pool brick, the smallest of the channels that read it.
    let per_brick = |chan: &[Option<f32>]| -> Vec<f32> {
        pool.brick_channels
            .iter()
            .map(|&m| {
                (0..n)
                    .filter(|c| m & (1 << c) != 0)
                    .filter_map(|c| chan[c])
                    .fold(f32::INFINITY, f32::min)
            })
            .collect()
    };
    let mut chan_budget: Vec<Option<f32>> = budgets.iter().map(|b| b.map(|x| x.0)).collect();
    let mut budget_source: Vec<Option<&str>> = budgets.iter().map(|b| b.map(|x| x.1)).collect();
    let root_len = root_dims.iter().map(|&d| d as u64).product::<u64>();
    // Guard and encode at the channel bounds `chan`.
    let guard_encode = |chan: &[Option<f32>],
                        eopts: &EncodeOptions|
     -> Result<(Option<Guarded>, Encoded), String> {
        let bricks_budget = per_brick(chan);
        match &grouped {
            Some(g) => {
                let guarded = g.guard(&pool.bricks, &bricks_budget, eopts)?;
                let enc = encode::encode_budgets(
                    &guarded.input,
                    eopts,
                    eopts.max_error.map(|_| &guarded.budgets[..]),
                )?;
                Ok((Some(guarded), enc))
            }
            None => {
                let enc = encode::encode_budgets(
                    &pool.bricks,
                    eopts,
                    eopts.max_error.map(|_| &bricks_budget[..]),
                )?;
                Ok((None, enc))
            }
        }
    };

    // --max-bytes: the smallest fraction of every channel's range whose GPU bytes fit.
    let mut size_doc: Option<report::SizeSearch> = None;
    if let Budget::MaxBytes(max_bytes) = opts.budget {
        let n_l2 = pool.l2_refs.len() as u64;
        let refs: u64 = pool.l2_refs.iter().map(|r| r.len() as u64).sum();
        // roots, frame ranges, L2 masks, bases, prefixes and ranges, leaf refs (section_sizes).
        let fixed_topology = pool.frames.len() as u64 * (root_len * 4 + 8 * n as u64)
            + pool.l2_masks.len() as u64 * 8
            + n_l2 * (4 + L2_WORDS as u64 * 2 + 8 * n as u64)
            + refs * 4;
        let ranges: Vec<f32> = channels
            .iter()
            .map(|c| {
                let r = c.range_with_background();
                (r[1] - r[0]).max(f32::MIN_POSITIVE)
            })
            .collect();
        let at = |t: f64| -> Vec<Option<f32>> {
            ranges
                .iter()
                .map(|r| Some((*r as f64 * t) as f32))
                .collect()
        };
        let stage = progress.stage("size search", "encodes");
        let mut steps = Vec::new();
        let lossless = fixed_topology
            + 4 * pool.tiles.len() as u64
            + pool.brick_count() as u64 * (PayloadFormat::F32.bytes_per_brick() as u64 + 16);
        let found = budget::search(lossless, fixed_topology, max_bytes, |t| {
            let chan = at(t);
            let o = EncodeOptions {
                max_error: chan.iter().flatten().copied().reduce(f32::min),
                lossy_tiles: true,
                ..eopts
            };
            let (_, enc) = guard_encode(&chan, &o)?;
            let b = budget::gpu_bytes(fixed_topology, pool.tiles.len(), &enc);
            steps.push(report::SizeStep {
                max_error: chan[0].unwrap_or(0.0),
                gpu_bytes: b,
            });
            Ok(b)
        })
        .map_err(CookError::Options)?;
        stage.finish();
        match found.fraction {
            None => {
                eopts.format = PayloadFormat::F32;
                eopts.format_given = true;
                eopts.lossy_tiles = false;
                chan_budget = vec![None; n];
                budget_source = vec![None; n];
            }
            Some(t) => {
                chan_budget = at(t);
                budget_source = vec![Some("max_bytes"); n];
                for (c, ch) in channels.iter().enumerate() {
                    let default = encode::default_budget(ch.range_with_background());
                    let e = chan_budget[c].unwrap_or(0.0);
                    if e > default {
                        progress.note(&format!(
                            "warning: --max-bytes {max_bytes} needs an error bound of {e:e}{}, \
                             over the default artefact guard ({default:e}, 10% of the value \
                             range): expect visible artefacts",
                            if n > 1 {
                                format!(" on '{}'", ch.name)
                            } else {
                                String::new()
                            }
                        ));
                    }
                }
            }
        }
        size_doc = Some(report::SizeSearch {
            limit: max_bytes,
            predicted_gpu_bytes: found.gpu_bytes,
            trials: found.trials,
            steps,
            fraction_of_range: found.fraction,
        });
    }
    eopts.max_error = chan_budget.iter().flatten().copied().reduce(f32::min);

    // Guard and encode.
    let t = Instant::now();
    let stage = progress.stage("encode", "blocks");
    let tg = Instant::now();
    let (guarded, enc) = guard_encode(&chan_budget, &eopts)
        .map_err(|m| input(&first_path, ErrorKind::Unsupported, m))?;
    if grouped.is_some() {
        cluster_s += tg.elapsed().as_secs_f64();
    }
    let cstats = match (&grouped, &guarded) {
        (Some(g), Some(gd)) => Some(cluster_report(g, gd, &chan_budget, cluster_s, progress)),
        _ => None,
    };
    let Assembled {
        asset,
        bytes,
        figures,
        source_bricks,
        source_tiles,
        unique_bricks,
        after_clustering,
        tiles_made,
        lod_max_abs,
    } = assemble::assemble(assemble::Inputs {
        pool,
        enc,
        guarded,
        channels: &channels,
        chan_budget: &chan_budget,
        eopts: &eopts,
        requested,
        label,
        source,
        infos,
        transform: &transform,
        offset,
        root_dims,
        lod: (lod_levels, lod_first),
        lod_bricks: &lod_bricks,
        replace_non_finite: opts.replace_non_finite,
        allow_gaps: opts.allow_gaps,
    })?;
    let encode_s = t.elapsed().as_secs_f64();
    stage.finish();
    if let Some(s) = &size_doc {
        // The search counted these bytes without building the asset: hold it to that.
        let (topology, atlas) = assemble::topology_and_atlas(&assemble::section_sizes(&asset));
        if topology + atlas != s.predicted_gpu_bytes || topology + atlas > s.limit {
            return Err(CookError::Internal(format!(
                "internal: --max-bytes {} predicted {} GPU bytes, the asset has {}",
                s.limit,
                s.predicted_gpu_bytes,
                topology + atlas
            )));
        }
    }
    let report = report::build(report::BuildInputs {
        asset: &asset,
        file_bytes: bytes.len() as u64,
        channels: &channels,
        budgets: &chan_budget,
        budget_source: &budget_source,
        figures: &figures,
        format: eopts.format,
        tiles_made,
        missing,
        bricks: report::Bricks {
            source: source_bricks,
            unique: unique_bricks,
            after_clustering,
            stored: asset.brick_count() as u64,
            tiles: asset.tiles.len() as u64,
            tile_leaves: source_tiles,
        },
        clustering: cstats,
        size_search: size_doc,
        bc7_quality: eopts.bc7_quality.name(),
        range: eopts.range,
        seconds: report::Seconds {
            total: t0.elapsed().as_secs_f64(),
            read: read_s,
            build: build_s,
            dedup: pool_s,
            cluster: cluster_s,
            encode: encode_s,
            write: 0.0,
        },
        lod_max_abs,
    });
    Ok(Cooked {
        asset,
        bytes,
        report,
    })
}

/// What clustering did, with a note whenever it is less than what was asked.
fn cluster_report(
    g: &Grouped,
    gd: &Guarded,
    chan_budget: &[Option<f32>],
    seconds: f64,
    progress: &Progress,
) -> report::Clustering {
    let (k, candidates) = (g.requested, g.candidates());
    let n_pool = gd.input_of.len();
    if candidates == 0 {
        progress.note(&format!(
            "note: --clusters {k}: no brick has normalized variance <= {} (0 of {n_pool} candidates); nothing was clustered",
            g.variance_threshold
        ));
    } else if k > candidates {
        progress.note(&format!(
            "note: --clusters {k} exceeds the {candidates} candidate bricks; k is capped at {candidates}"
        ));
    }
    if candidates > 0 && gd.clusters_used == 0 {
        progress.note(&format!(
            "note: --clusters {k}: every candidate was rejected by the error guard ({} bricks; budget {}); nothing was clustered",
            gd.rejected_by_error,
            chan_budget.iter().flatten().copied().reduce(f32::min).unwrap_or(0.0)
        ));
    }
    report::Clustering {
        candidates,
        clusters_requested: k,
        clusters: gd.clusters_used,
        iterations: g.iterations_run(),
        rejected_by_variance: g.rejected_by_variance(),
        rejected_by_error: gd.rejected_by_error,
        variance_threshold: g.variance_threshold,
        seconds,
    }
}
