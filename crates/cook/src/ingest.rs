//! The read, build and pool stages, run together: frames stream through in chunks — read and
//! built in parallel (every channel of a frame from one open file), added to the pool in
//! sequence order while the next chunk is read — so memory holds the pool and a chunk of frames,
//! never the whole sequence, and the pool does not depend on scheduling. Every frame's channels
//! are checked against the sequence: one linear transform for all, one background per channel.

use std::path::PathBuf;
use std::time::Instant;

use rayon::prelude::*;
use vdbcook_asset::{FrameInfo, SourceInfo};
use vdbcook_vdb::sequence::Frame;
use vdbcook_vdb::{ErrorKind, Transform, VdbFile};

use crate::build::{build_frame, BuiltFrame, NonFinite};
use crate::error::{input, CookError};
use crate::frames::{frame_info, read_named_in};
use crate::nanovdb::NanoGrids;
use crate::pool::Pool;
use crate::progress::{self, Progress};

/// One grid a cook reads from every frame: one channel of the asset.
#[derive(Clone, Debug)]
pub struct ChannelSource {
    /// The grid's label as the files name it.
    pub name: String,
    /// How it was chosen (for error messages: "given by --grid", "named by --grids", ...).
    pub how: String,
}

/// What the read of every frame of one channel found.
#[derive(Clone, Debug)]
pub struct ChannelState {
    pub name: String,
    /// Its background (the same in every frame that has the grid).
    pub background: f32,
    /// Finite active value range over the sequence (`lo > hi`: no active value).
    pub value_range: [f32; 2],
    /// Active voxels per frame (0 where the grid is missing).
    pub active: Vec<u64>,
    /// Its frames as NanoVDB grids (what the report compares the asset's GPU bytes with).
    pub nanovdb: NanoGrids,
}

impl ChannelState {
    /// The value range with the background in it (what a default budget is a share of).
    pub fn range_with_background(&self) -> [f32; 2] {
        let r = self.value_range;
        [r[0].min(self.background), r[1].max(self.background)]
    }
    /// The active value range, `None` without active values.
    pub fn active_range(&self) -> Option<[f32; 2]> {
        (self.value_range[0] <= self.value_range[1]).then_some(self.value_range)
    }
}

/// The sequence in the pool, and what the later stages need to know of it.
pub struct Ingested {
    pub pool: Pool,
    pub channels: Vec<ChannelState>,
    /// The shared transform, and the first frame that has a grid (for error messages).
    pub transform: Transform,
    pub first_path: PathBuf,
    /// The label of channel 0's grid as the first frame that has it names it.
    pub label: String,
    /// What the first frame with a grid says of its writer, class and up axis.
    pub source: SourceInfo,
    pub infos: Vec<FrameInfo>,
    /// `file (grid)` for every grid missing from a frame (`--allow-missing-grid`).
    pub missing: Vec<String>,
    /// Wall-clock seconds: read and build (their share of the worker time), pool.
    pub read_s: f64,
    pub build_s: f64,
    pub pool_s: f64,
}

/// How frames are read.
#[derive(Clone, Copy)]
pub struct ReadOptions {
    pub allow_missing: bool,
    /// Errors may suggest `--allow-missing-grid`.
    pub hint_missing: bool,
    pub non_finite: NonFinite,
    /// Record every brick use (for the error figures of a lossy cook), and measure the source
    /// leaves for the NanoVDB FpN comparison.
    pub track_uses: bool,
}

/// One channel of one frame, read and built.
struct Channel {
    label: String,
    /// Its file's writer, the grid's class and the writer's up axis.
    source: SourceInfo,
    transform: Transform,
    background: f32,
    built: BuiltFrame,
}

/// One frame read and built (in a parallel task), with the time each step took.
struct Prepared {
    frame: Frame,
    /// Per channel (`None`: the grid is missing).
    channels: Result<Vec<Option<Channel>>, CookError>,
    read_s: f64,
    build_s: f64,
}

/// Grids only Blender's fluid caches (Mantaflow, and the smoke solver before it) write.
const BLENDER_GRIDS: [&str; 5] = ["shadow", "flags", "phi_obstacle", "phi_inflow", "phi_out"];

/// A file's writer (`creator` metadata, empty when absent) and the up axis its convention
/// implies: `z` for Blender (its `creator`, or the grids only its fluid caches write: Mantaflow
/// writes no `creator`), `y` for Houdini and Maya, else empty.
pub fn source_of(file: &VdbFile) -> (String, String) {
    let creator = file.metadata.get_str("creator").unwrap_or("").to_string();
    let c = creator.to_ascii_lowercase();
    let blender = c.contains("blender")
        || file
            .grids
            .iter()
            .any(|g| BLENDER_GRIDS.contains(&g.name.as_str()));
    let up = if blender {
        "z"
    } else if c.contains("houdini") || c.contains("maya") {
        "y"
    } else {
        ""
    };
    (creator, up.to_string())
}

fn prepare(f: &Frame, sources: &[ChannelSource], o: ReadOptions) -> Prepared {
    let (mut read_s, mut build_s) = (0.0, 0.0);
    let mut run = || -> Result<Vec<Option<Channel>>, CookError> {
        let t = Instant::now();
        let file = VdbFile::open(&f.path);
        read_s += t.elapsed().as_secs_f64();
        let file = file?;
        let (creator, up) = source_of(&file);
        let mut out = Vec::with_capacity(sources.len());
        for s in sources {
            let t = Instant::now();
            let loaded = read_named_in(&file, f, &s.name, &s.how, o.allow_missing, o.hint_missing);
            read_s += t.elapsed().as_secs_f64();
            let Some(loaded) = loaded? else {
                out.push(None);
                continue;
            };
            let t = Instant::now();
            let label = loaded.grid_label;
            let class = file
                .grids
                .iter()
                .find(|g| g.label == label)
                .map(|g| g.class())
                .filter(|c| *c != "unknown")
                .unwrap_or_default()
                .to_string();
            // Recorded only where it changes what a renderer does (an up axis, a class that
            // is not a fog): other sources stay at the older format versions, byte for byte.
            let source = if up.is_empty() && (class.is_empty() || class == "fog volume") {
                SourceInfo::default()
            } else {
                SourceInfo {
                    creator: creator.clone(),
                    grid_class: class,
                    up: up.clone(),
                }
            };
            let (transform, background) = (loaded.grid.transform.clone(), loaded.grid.background);
            let built = build_frame(loaded.grid, o.non_finite, o.track_uses)
                .map_err(|m| input(&f.path, ErrorKind::Corrupt, format!("grid '{label}': {m}")));
            build_s += t.elapsed().as_secs_f64();
            out.push(Some(Channel {
                label,
                source,
                transform,
                background,
                built: built?,
            }));
        }
        Ok(out)
    };
    let channels = run();
    Prepared {
        frame: f.clone(),
        channels,
        read_s,
        build_s,
    }
}

/// The sequence's checks and tallies, filled frame by frame in sequence order.
struct Tally<'a> {
    sources: &'a [ChannelSource],
    /// The first frame with a grid: its path, transform and channel 0's label (or the first
    /// grid's).
    first: Option<(Frame, Transform, String, SourceInfo)>,
    /// Per channel: background and the frame that set it.
    backgrounds: Vec<Option<(f32, String)>>,
    ranges: Vec<[f32; 2]>,
    active: Vec<Vec<u64>>,
    nanovdb: Vec<NanoGrids>,
    infos: Vec<FrameInfo>,
    missing: Vec<String>,
}

impl Tally<'_> {
    /// Checks one frame's channels against the sequence and returns what the pool takes.
    fn frame(
        &mut self,
        frame: &Frame,
        channels: Vec<Option<Channel>>,
    ) -> Result<Vec<Option<BuiltFrame>>, CookError> {
        let n = self.sources.len();
        let mut built = Vec::with_capacity(n);
        let mut frame_active = 0u64;
        for (c, chan) in channels.into_iter().enumerate() {
            let Some(mut chan) = chan else {
                self.missing.push(if n == 1 {
                    frame.path.display().to_string()
                } else {
                    format!("{} ({})", frame.path.display(), self.sources[c].name)
                });
                self.active[c].push(0);
                built.push(None);
                continue;
            };
            match &self.first {
                None => {
                    if !chan.transform.kind.is_linear() {
                        return Err(input(
                            &frame.path,
                            ErrorKind::Unsupported,
                            format!(
                                "grid '{}' has a {} transform; vdbcook cooks linear transforms only",
                                chan.label,
                                chan.transform.kind.type_name()
                            ),
                        ));
                    }
                    self.first = Some((
                        frame.clone(),
                        chan.transform.clone(),
                        chan.label.clone(),
                        chan.source.clone(),
                    ));
                }
                Some((f0, t0, l0, _)) => {
                    if !chan.transform.approx_eq(t0, 1e-9) {
                        return Err(input(
                            &frame.path,
                            ErrorKind::Sequence,
                            format!(
                                "grid '{}' (voxel size {:?}) and grid '{}' of {} (voxel size \
                                 {:?}) have different transforms; every frame and grid of an \
                                 asset shares one transform (resampling is not supported)",
                                chan.label,
                                chan.transform.voxel_size(),
                                l0,
                                f0.path.display(),
                                t0.voxel_size(),
                            ),
                        ));
                    }
                }
            }
            match &self.backgrounds[c] {
                None => {
                    self.backgrounds[c] = Some((chan.background, frame.path.display().to_string()))
                }
                Some((bg, from)) if bg.to_bits() != chan.background.to_bits() => {
                    return Err(input(
                        &frame.path,
                        ErrorKind::Sequence,
                        format!(
                            "grid '{}': background {} differs from frame {from} ({bg})",
                            chan.label, chan.background
                        ),
                    ));
                }
                Some(_) => {}
            }
            if let Some(r) = chan.built.value_range {
                let v = &mut self.ranges[c];
                *v = [v[0].min(r[0]), v[1].max(r[1])];
            }
            self.active[c].push(chan.built.active_voxels);
            self.nanovdb[c].merge(std::mem::take(&mut chan.built.nano));
            frame_active += chan.built.active_voxels;
            built.push(Some(chan.built));
        }
        self.infos.push(frame_info(frame, frame_active));
        Ok(built)
    }
}

/// Reads, builds and pools every frame of `sources`.
pub fn ingest(
    frames: &[Frame],
    sources: &[ChannelSource],
    o: ReadOptions,
    progress: &Progress,
) -> Result<Ingested, CookError> {
    let n = sources.len();
    let mut pool = Pool::new(n, o.track_uses);
    let mut tally = Tally {
        sources,
        first: None,
        backgrounds: vec![None; n],
        ranges: vec![[f32::INFINITY, f32::NEG_INFINITY]; n],
        active: vec![Vec::with_capacity(frames.len()); n],
        nanovdb: vec![NanoGrids::default(); n],
        infos: Vec::with_capacity(frames.len()),
        missing: Vec::new(),
    };
    let stage = progress.stage("read, build, dedup", "frames");
    progress::add_total(frames.len() as u64);
    let threads = rayon::current_num_threads().max(1);
    let chunk = (threads * 2).max(2);
    // While the frames of chunk k are read and built in parallel, chunk k-1 joins the pool (in
    // sequence order, so the output does not depend on scheduling).
    let mut pending: Vec<Prepared> = Vec::new();
    let (mut read_cpu, mut build_cpu, mut pool_s) = (0.0f64, 0.0f64, 0.0f64);
    let groups: Vec<&[Frame]> = frames.chunks(chunk).collect();
    for gi in 0..=groups.len() {
        let todo = std::mem::take(&mut pending);
        let (prepared, added) = rayon::join(
            || {
                groups.get(gi).map(|g| {
                    g.par_iter()
                        .map(|f| prepare(f, sources, o))
                        .collect::<Vec<_>>()
                })
            },
            || -> Result<f64, CookError> {
                let t = Instant::now();
                for p in todo {
                    let built = tally.frame(&p.frame, p.channels?)?;
                    pool.add_frame(&built);
                    progress::advance(1);
                }
                Ok(t.elapsed().as_secs_f64())
            },
        );
        pool_s += added?;
        if let Some(p) = prepared {
            for x in &p {
                read_cpu += x.read_s;
                build_cpu += x.build_s;
            }
            pending = p;
        }
    }
    stage.finish();
    let Some((f0, transform, label, source)) = tally.first else {
        let s = &sources[0];
        return Err(input(
            &frames[0].path,
            ErrorKind::GridSelection,
            if n == 1 {
                format!("no frame has the grid '{}' ({})", s.name, s.how)
            } else {
                format!(
                    "no frame has any of the grids {}",
                    sources
                        .iter()
                        .map(|s| s.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            },
        ));
    };
    let mut channels = Vec::with_capacity(n);
    for (c, s) in sources.iter().enumerate() {
        let Some((background, _)) = tally.backgrounds[c] else {
            return Err(input(
                &frames[0].path,
                ErrorKind::GridSelection,
                format!("no frame has the grid '{}' ({})", s.name, s.how),
            ));
        };
        channels.push(ChannelState {
            name: s.name.clone(),
            background,
            value_range: tally.ranges[c],
            active: std::mem::take(&mut tally.active[c]),
            nanovdb: std::mem::take(&mut tally.nanovdb[c]),
        });
    }
    // Read and build overlap (per-frame tasks on all threads): each is reported as its share of
    // the worker time, in wall-clock seconds.
    Ok(Ingested {
        pool,
        channels,
        transform,
        first_path: f0.path,
        label: if n == 1 {
            label
        } else {
            sources[0].name.clone()
        },
        source,
        infos: tally.infos,
        missing: tally.missing,
        read_s: read_cpu / threads as f64,
        build_s: build_cpu / threads as f64,
        pool_s,
    })
}
