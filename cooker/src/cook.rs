//! `vdbcook cook`: read → build → dedup → encode → write, each stage timed. Frames stream
//! through in chunks (read and built in parallel, added to the pool in sequence order), so memory
//! holds the pool and a chunk of frames, never the whole sequence; the output is byte-identical at
//! any thread count. The asset is written by `output::write` (temporary file, renamed into place).

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use serde_json::Value;
use vdbcook_asset::*;
use vdbcook_vdb::sequence::{self, Frame};
use vdbcook_vdb::{ErrorKind, Transform, VdbError, VdbFile};

use crate::bcenc::Bc7Quality;
use crate::build::{build_frame, BuiltFrame, NonFinite};
use crate::cluster;
use crate::cook_report::{self as report, CookReport};
use crate::encode;
use crate::errors::CliError;
use crate::pool::{ranges, Pool};
use crate::progress::Progress;
use crate::size_budget;

/// A cook's options: the struct the CLI parses, and what a program fills in
/// (`Args::defaults`, then the fields it wants) before calling [`cook`].
#[derive(clap::Args, Clone)]
pub struct Args {
    /// VDB files, folders, frame patterns (smoke.####.vdb, smoke.%04d.vdb) or globs.
    #[arg(required_unless_present = "manifest", value_name = "INPUT")]
    pub inputs: Vec<String>,
    /// Output asset file.
    /// (Required unless --manifest.)
    #[arg(short = 'o', long = "output", value_name = "OUT")]
    pub output_given: Option<PathBuf>,
    /// The output path `cook` uses (`output_given`, filled in by `run`; set directly by callers).
    #[arg(skip)]
    pub output: PathBuf,
    /// Cook only the frames numbered A to B, both included, as the file names number them
    /// (`10..90`, `10..`, `..90`).
    #[arg(long, value_name = "A..B")]
    pub frames: Option<String>,
    /// Cook every asset a TOML manifest lists, with a content-addressed cache: unchanged assets
    /// are not recooked (`docs/cli.md`, "Batch cooking").
    #[arg(long, value_name = "TOML", conflicts_with_all = ["inputs", "frames"])]
    pub manifest: Option<PathBuf>,
    /// The cache folder of --manifest (default: `.vdbcook-cache` beside the manifest). A plain
    /// folder of files named by key: a build farm can share it.
    #[arg(long, value_name = "DIR", requires = "manifest")]
    pub cache_dir: Option<PathBuf>,
    /// Brick payload: f32 (bit exact), f16, unorm8 (8 bit), bc4 (4 bit) or bc7 (2 bit per voxel).
    /// Default f32; with --max-error and no --format, the smallest that meets the error.
    #[arg(long, value_parser = ["f32", "f16", "unorm8", "bc4", "bc7"])]
    pub format: Option<String>,
    /// Every voxel of every frame decodes within E of its source value, as any conformant GPU
    /// reads it: each brick takes the cheapest representation that meets E (tile, bc7, bc4,
    /// unorm8, f16, f32), starting at --format when one is given. Without it a lossy cook gets
    /// 10% of the value range as an artefact guard. With --grids, one budget per channel:
    /// `density=0.01,temperature=5` (a bare E applies to the channels not named).
    #[arg(
        long = "max-error",
        value_name = "E|NAME=E,..",
        allow_negative_numbers = true,
        value_parser = parse_max_error
    )]
    pub max_error_arg: Option<MaxErrorArg>,
    /// The budget of every channel (`--max-error E`); what programs linking the library set.
    #[arg(skip)]
    pub max_error: Option<f32>,
    /// Per-channel budgets (`--max-error NAME=E,..`; with `grids`).
    #[arg(skip)]
    pub max_error_per: Vec<(String, f32)>,
    /// Size budget instead of an error budget: the smallest error bound whose asset's GPU bytes
    /// (topology + atlas, as `info` reports them) fit in SIZE: bytes, or K/M/G (10³…) or
    /// KiB/MiB/GiB (2¹⁰…), e.g. 32MiB. Reports the bound it reached.
    #[arg(long, value_name = "SIZE", value_parser = crate::size_budget::parse_size)]
    pub max_bytes: Option<u64>,
    /// Quantization range of unorm8/bc4/bc7 bricks: each brick's own min/max, or one global range.
    #[arg(long, default_value = "brick", value_parser = ["brick", "global"])]
    pub range: String,
    /// BC7 encoder quality: ultra-fast, very-fast, fast, basic, slow.
    #[arg(long, default_value = "fast")]
    pub bc7_quality: String,
    /// Grid to cook: a name, `name[N]` for duplicates, or `#N` (default: `density`, else the only float grid).
    #[arg(long)]
    pub grid: Option<String>,
    /// Cook several float grids into one multi-channel asset on one shared topology (fire:
    /// `--grids density,temperature,flame`); the first is the one plain renders show. At most 8.
    /// `--grids auto` picks them by name from the first frame as `inspect` suggests (a density,
    /// a temperature and a flame grid of Blender, Houdini or EmberGen caches).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "A,B,..",
        conflicts_with = "grid"
    )]
    pub grids: Vec<String>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
    /// Accept gaps in the frame numbering.
    #[arg(long)]
    pub allow_gaps: bool,
    /// Cluster the low-variance bricks into K centroid bricks (k-means, L1 distance); lossy.
    #[arg(long, value_name = "K")]
    pub clusters: Option<usize>,
    /// k-means iterations, 1 to 1000 (with --clusters; default 5).
    #[arg(long, value_name = "N")]
    pub iterations: Option<usize>,
    /// Bricks whose normalized variance (variance / |mean|) exceeds T keep their own data
    /// (with --clusters; finite, >= 0; default 0.1).
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    pub variance_threshold: Option<f32>,
    /// A frame without the sequence's grid is cooked as an empty frame (by default an error
    /// naming the frame).
    #[arg(long)]
    pub allow_missing_grid: bool,
    /// Keep a channel of --grids that carries nothing (every active value within its budget of
    /// its background, or none at all); by default it is dropped with a note in the report.
    #[arg(long)]
    pub keep_empty_channels: bool,
    /// Also store coarser levels of every frame (level of detail for shadow and secondary
    /// rays): level k a 2x box filter of level k-1 (voxels 2^k wide), down to level N or, with
    /// `all`, to one 8^3 brick. Same payload and error budget; +22% (WDAS cloud) to +99%
    /// (stormscape) GPU bytes on the samples from level 1, docs/asset.md (`lod` in --json says
    /// what it added). One grid only.
    #[arg(long, value_name = "N|all", value_parser = crate::lod::parse_levels)]
    pub lod: Option<crate::lod::Levels>,
    /// Store the levels of --lod from level K on (1 to 12; default 1): the finer ones are built
    /// and dropped. The first coarse level is most of a chain's bytes, and a light volume reads
    /// level K only where its cells are wider than 2^(K+1) voxels. Implies `--lod all` without
    /// --lod. Example: `--lod-from 2` (WDAS cloud: +6% instead of +22%).
    #[arg(long, value_name = "K", value_parser = crate::lod::parse_first)]
    pub lod_from: Option<u32>,
    /// Replace NaN and ±Inf active values with VALUE (by default they are an error).
    #[arg(long, value_name = "VALUE", allow_negative_numbers = true)]
    pub replace_non_finite: Option<f32>,
    /// No progress line (set by commands that cook in memory and report progress themselves).
    #[arg(skip)]
    pub quiet: bool,
    /// The calling command has no `--replace-non-finite` (so errors do not suggest it).
    #[arg(skip)]
    pub no_non_finite_flag: bool,
    /// Where a program linking the library gets the cook's stages and notes (`None`: the CLI's
    /// stderr display unless quiet or `--json`).
    #[arg(skip)]
    pub progress: Option<std::sync::Arc<dyn crate::progress::ProgressSink>>,
}

impl Args {
    /// The options `vdbcook cook INPUTS -o OUTPUT` would have: f32, per-brick range, no
    /// clustering. Used by commands that cook in memory (`render` of a VDB, `report`).
    pub fn defaults(inputs: Vec<String>, output: PathBuf) -> Args {
        Args {
            inputs,
            output_given: Some(output.clone()),
            output,
            frames: None,
            manifest: None,
            cache_dir: None,
            format: None,
            max_error_arg: None,
            max_error: None,
            max_error_per: Vec::new(),
            max_bytes: None,
            range: "brick".into(),
            bc7_quality: "fast".into(),
            grid: None,
            grids: Vec::new(),
            json: false,
            allow_gaps: false,
            clusters: None,
            iterations: None,
            variance_threshold: None,
            allow_missing_grid: false,
            keep_empty_channels: false,
            lod: None,
            lod_from: None,
            replace_non_finite: None,
            quiet: true,
            no_non_finite_flag: false,
            progress: None,
        }
    }
}

/// Largest `--clusters` (centroid indices stay far inside the asset's 31-bit brick references).
pub const MAX_CLUSTERS: usize = 1 << 24;
/// Largest `--iterations`.
pub const MAX_ITERATIONS: usize = 1000;

impl Args {
    /// Checks every option's range and combination before any work; each message names the
    /// flag and its range.
    pub fn validate(&self) -> Result<(), CliError> {
        let bad = |m: String| Err(CliError::Usage(m));
        if (self.lod.is_some() || self.lod_from.is_some()) && self.grids.len() > 1 {
            return bad(format!(
                "--lod stores coarser levels of one grid; --grids {} names several (cook each \
                 with --grid G --lod, or cook the channels without --lod)",
                self.grids.join(",")
            ));
        }
        if let (Some(crate::lod::Levels::Count(n)), Some(k)) = (self.lod, self.lod_from) {
            if k > n {
                return bad(format!(
                    "--lod-from {k} starts past --lod {n}, the last level stored (give --lod {k} \
                     or more, or --lod all)"
                ));
            }
        }
        if Bc7Quality::parse(&self.bc7_quality).is_none() {
            return bad(format!(
                "unknown --bc7-quality '{}' (ultra-fast, very-fast, fast, basic, slow)",
                self.bc7_quality
            ));
        }
        if let Some(k) = self.clusters {
            if !(1..=MAX_CLUSTERS).contains(&k) {
                return bad(format!(
                    "--clusters {k} is out of range: K must be 1 to {MAX_CLUSTERS} (and is capped at the number of candidate bricks)"
                ));
            }
        } else {
            if self.iterations.is_some() {
                return bad("--iterations only applies with --clusters K".into());
            }
            if self.variance_threshold.is_some() {
                return bad("--variance-threshold only applies with --clusters K".into());
            }
        }
        if let Some(n) = self.iterations {
            if !(1..=MAX_ITERATIONS).contains(&n) {
                return bad(format!(
                    "--iterations {n} is out of range: N must be 1 to {MAX_ITERATIONS}"
                ));
            }
        }
        if let Some(t) = self.variance_threshold {
            if !(t.is_finite() && t >= 0.0) {
                return bad(format!(
                    "--variance-threshold {t} is out of range: T must be a finite number >= 0"
                ));
            }
        }
        if let Some(e) = self.max_error {
            if !(e.is_finite() && e > 0.0) {
                return bad(format!(
                    "--max-error {e} is out of range: E must be a finite number > 0 (for a lossless asset use --format f32)"
                ));
            }
        }
        if let Some(f) = &self.frames {
            parse_frame_range(f).map_err(CliError::Usage)?;
        }
        crate::multi::validate(self)?;
        if let Some(n) = self.max_bytes {
            if n == 0 {
                return bad("--max-bytes 0 is out of range: SIZE must be > 0".into());
            }
            if self.max_error.is_some() {
                return bad(
                    "--max-bytes and --max-error each set the error bound: give one of them".into(),
                );
            }
            if self.clusters.is_some() {
                return bad(
                    "--max-bytes with --clusters is not supported yet: the size search varies \
                     the error bound per brick format only; cluster with --max-error instead"
                        .into(),
                );
            }
        }
        if let Some(v) = self.replace_non_finite {
            if !v.is_finite() {
                return bad(format!(
                    "--replace-non-finite {v}: VALUE must be a finite number"
                ));
            }
        }
        Ok(())
    }
}

/// `--max-error`: one budget, or budgets per channel (`NAME=E`, plus at most one bare `E` for
/// the channels not named).
#[derive(Debug, Clone, PartialEq)]
pub enum MaxErrorArg {
    All(f32),
    Per {
        all: Option<f32>,
        per: Vec<(String, f32)>,
    },
}

/// Parses `--max-error`: `E` or `NAME=E[,NAME=E..]` (with at most one bare `E` among them).
pub fn parse_max_error(s: &str) -> Result<MaxErrorArg, String> {
    let num = |t: &str| -> Result<f32, String> {
        t.trim()
            .parse::<f32>()
            .map_err(|_| format!("'{t}' is not a number (expected E or NAME=E,..)"))
    };
    if !s.contains('=') {
        return num(s).map(MaxErrorArg::All);
    }
    let (mut all, mut per) = (None, Vec::new());
    for part in s.split(',') {
        match part.split_once('=') {
            Some((name, e)) => {
                let name = name.trim();
                if name.is_empty() {
                    return Err(format!("'{part}': a channel name is missing before '='"));
                }
                if per.iter().any(|(n, _)| n == name) {
                    return Err(format!("channel '{name}' is given twice"));
                }
                per.push((name.to_string(), num(e)?));
            }
            None if all.is_none() => all = Some(num(part)?),
            None => return Err("at most one budget without a channel name".into()),
        }
    }
    Ok(MaxErrorArg::Per { all, per })
}

/// A cook held in memory: the asset, its file bytes and the report `cook --json` prints
/// (without `seconds.write`, which only `run` knows).
pub struct Cooked {
    pub asset: Asset,
    pub bytes: Vec<u8>,
    pub report: CookReport,
}

pub(crate) fn err(path: &Path, kind: ErrorKind, m: impl Into<String>) -> CliError {
    CliError::Vdb(VdbError::new(kind, path, m))
}

/// One frame read and built (in a parallel task), with the time each step took.
struct Prepared {
    result: Result<PreparedFrame, CliError>,
    read_s: f64,
    build_s: f64,
}

struct PreparedFrame {
    frame: Frame,
    label: String,
    /// `None` for a frame without the sequence's grid, cooked empty (`--allow-missing-grid`).
    transform: Option<Transform>,
    background: f32,
    built: BuiltFrame,
}

/// The grid the whole sequence is cooked from, chosen once: `--grid` as given (an index `#N` is
/// resolved to its label in the first frame), else the first frame's `density`, else its only
/// float grid. Returns the label and how it was chosen (for error messages).
pub fn choose_grid(frames: &[Frame], grid: Option<&str>) -> Result<(String, String), CliError> {
    match grid {
        Some(g) if !g.starts_with('#') => Ok((g.to_string(), "given by --grid".into())),
        _ => {
            let f0 = &frames[0].path;
            let file = VdbFile::open(f0)?;
            let i = file.select(grid)?;
            let how = match grid {
                Some(g) => format!("--grid {g} in the first frame {}", f0.display()),
                None => format!(
                    "chosen from the first frame {} ('density', else its only float grid)",
                    f0.display()
                ),
            };
            Ok((file.grids[i].label.clone(), how))
        }
    }
}

/// Reads grid `name` of one frame. A frame without it is `Ok(None)` under `allow_missing`,
/// else an error naming the frame (`hint`: mention `--allow-missing-grid`).
pub fn read_named(
    f: &Frame,
    name: &str,
    how: &str,
    allow_missing: bool,
    hint: bool,
) -> Result<Option<sequence::LoadedFrame>, VdbError> {
    let file = VdbFile::open(&f.path)?;
    read_named_in(&file, f, name, how, allow_missing, hint)
}

/// [`read_named`] from a file already open (a frame's several grids are read from one open).
pub fn read_named_in(
    file: &VdbFile,
    f: &Frame,
    name: &str,
    how: &str,
    allow_missing: bool,
    hint: bool,
) -> Result<Option<sequence::LoadedFrame>, VdbError> {
    let present = file
        .grids
        .iter()
        .any(|g| g.label == name || g.name == name || g.unique_name == name);
    if !present {
        if allow_missing {
            return Ok(None);
        }
        let floats = file.float_grid_labels();
        return Err(VdbError::new(
            ErrorKind::GridSelection,
            &f.path,
            format!(
                "this frame has no grid '{name}' ({how}; every frame must have it); float grids here: {}{}",
                if floats.is_empty() { "none".into() } else { floats.join(", ") },
                if hint { "; pass --allow-missing-grid to cook such frames as empty frames" } else { "" }
            ),
        ));
    }
    let idx = file.select(Some(name))?;
    let grid = file.read_float_grid(idx)?;
    Ok(Some(sequence::LoadedFrame {
        frame: f.clone(),
        grid_label: file.grids[idx].label.clone(),
        grid,
    }))
}

/// What `prepare` is told about the grid.
#[derive(Clone, Copy)]
struct GridChoice<'a> {
    name: &'a str,
    how: &'a str,
    allow_missing: bool,
    hint: bool,
}

fn prepare(f: &Frame, g: GridChoice, nf: NonFinite) -> Prepared {
    let t = Instant::now();
    let loaded = match read_named(f, g.name, g.how, g.allow_missing, g.hint) {
        Ok(Some(l)) => l,
        Ok(None) => {
            return Prepared {
                result: Ok(PreparedFrame {
                    frame: f.clone(),
                    label: g.name.to_string(),
                    transform: None,
                    background: 0.0,
                    built: BuiltFrame {
                        bricks: Vec::new(),
                        regions: Default::default(),
                        active_voxels: 0,
                        value_range: None,
                    },
                }),
                read_s: t.elapsed().as_secs_f64(),
                build_s: 0.0,
            }
        }
        Err(e) => {
            return Prepared {
                result: Err(e.into()),
                read_s: t.elapsed().as_secs_f64(),
                build_s: 0.0,
            }
        }
    };
    let read_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let sequence::LoadedFrame {
        frame,
        grid_label: label,
        grid,
    } = loaded;
    let (transform, background) = (grid.transform.clone(), grid.background);
    let built = build_frame(grid, nf);
    let build_s = t.elapsed().as_secs_f64();
    let result = built
        .map(|built| PreparedFrame {
            frame: frame.clone(),
            label: label.clone(),
            transform: Some(transform),
            background,
            built,
        })
        .map_err(|m| {
            err(
                &frame.path,
                ErrorKind::Corrupt,
                format!("grid '{label}': {m}"),
            )
        });
    Prepared {
        result,
        read_s,
        build_s,
    }
}

/// Error sums of one frame (of one channel).
#[derive(Default, Clone, Copy)]
pub(crate) struct FrameErr {
    pub sum_sq: f64,
    pub max_abs: f64,
    /// Bound on any conformant GPU's read: per brick, its error plus its native-read slack.
    pub gpu_bound: f64,
}

/// The error sums of each list of brick uses (a frame's, or a frame's channel's): every use of
/// pool brick `b` compares its source values `bricks` with `decoded`, and `slack(b)` is what a
/// GPU's native read of it may add. Inactive voxels hold the background in the pool: a lossy
/// payload that moves them off it is an error too (a tracer samples them), counted as `eval`
/// counts it. The RMSE divides by the active voxel count.
pub(crate) fn use_errors(
    uses: &[Vec<u32>],
    bricks: &[f32],
    decoded: &[f32],
    slack: impl Fn(u32) -> f32 + Sync,
) -> Vec<FrameErr> {
    uses.par_iter()
        .map(|uses| {
            let mut fe = FrameErr::default();
            for &b in uses {
                let r = b as usize * BRICK_VOXELS..(b as usize + 1) * BRICK_VOXELS;
                let mut brick_max = 0.0f64;
                for (s, v) in bricks[r.clone()].iter().zip(&decoded[r]) {
                    let e = (*v as f64 - *s as f64).abs();
                    fe.sum_sq += e * e;
                    brick_max = brick_max.max(e);
                }
                fe.gpu_bound = fe.gpu_bound.max(brick_max + slack(b) as f64);
                fe.max_abs = fe.max_abs.max(brick_max);
            }
            fe
        })
        .collect()
}

/// The asset's `index_to_world`: the source transform with the asset's index offset folded in.
pub(crate) fn asset_index_to_world(transform: &Transform, offset: [i32; 3]) -> [[f64; 4]; 4] {
    let mut m = transform.index_to_world;
    for (r, row) in m.iter_mut().enumerate().take(3) {
        row[3] = transform.index_to_world[r][3]
            + (0..3)
                .map(|c| transform.index_to_world[r][c] * offset[c] as f64)
                .sum::<f64>();
    }
    m
}

/// Wall-clock seconds per stage.
#[derive(Default)]
struct Stages {
    read: f64,
    build: f64,
    dedup: f64,
    cluster: f64,
    encode: f64,
    write: f64,
}

pub fn run(a: &Args) -> Result<(), CliError> {
    let mut owned = a.clone();
    owned.output = a.output_given.clone().unwrap_or_default();
    match owned.max_error_arg.take() {
        Some(MaxErrorArg::All(e)) => owned.max_error = Some(e),
        Some(MaxErrorArg::Per { all, per }) => {
            owned.max_error = all;
            owned.max_error_per = per;
        }
        None => {}
    }
    let a = &owned;
    if a.manifest.is_some() {
        if a.output_given.is_some() {
            return Err(CliError::Usage(
                "--manifest writes the outputs its entries name: drop -o/--output".into(),
            ));
        }
        return crate::manifest::run(a);
    }
    if a.output_given.is_none() {
        return Err(CliError::Usage(
            "the output asset is required: -o OUT (or --manifest TOML for batch cooking)".into(),
        ));
    }
    let t0 = Instant::now();
    a.validate()?;
    // Refuse an output that is (or would join) one of the inputs before any work.
    let frames = resolve_frames(a)?;
    crate::output::refuse_inputs(&a.output, &frames, &a.inputs, "asset")?;
    let Cooked {
        bytes, mut report, ..
    } = cook_frames(a, frames)?;
    let t = Instant::now();
    let stage =
        Progress::with(a.progress.clone(), a.json || a.quiet, !a.quiet).stage("write", "bytes");
    crate::output::write(&a.output, &bytes, "asset")?;
    stage.finish();
    report.seconds.write = t.elapsed().as_secs_f64();
    report.seconds.total = t0.elapsed().as_secs_f64();
    let doc = serde_json::to_value(&report).expect("json");
    if a.json {
        println!("{}", serde_json::to_string_pretty(&doc).expect("json"));
    } else {
        print_summary(&doc);
    }
    Ok(())
}

/// The frames `a` cooks: its inputs resolved (`sequence::resolve_inputs`), then `--frames`.
pub fn resolve_frames(a: &Args) -> Result<Vec<Frame>, CliError> {
    let frames = sequence::resolve_inputs(&a.inputs, a.allow_gaps)?;
    match &a.frames {
        None => Ok(frames),
        Some(spec) => select_frames(frames, spec),
    }
}

/// Parses `A..B`, `A..` or `..B` (both ends included) into bounds.
pub fn parse_frame_range(spec: &str) -> Result<(Option<i64>, Option<i64>), String> {
    let bad = || format!("--frames '{spec}': expected A..B, A.. or ..B with frame numbers");
    let (a, b) = spec.split_once("..").ok_or_else(bad)?;
    let num = |t: &str| -> Result<Option<i64>, String> {
        let t = t.trim();
        if t.is_empty() {
            Ok(None)
        } else {
            t.parse().map(Some).map_err(|_| bad())
        }
    };
    let (lo, hi) = (num(a)?, num(b)?);
    if let (Some(l), Some(h)) = (lo, hi) {
        if l > h {
            return Err(format!(
                "--frames '{spec}': the first frame is after the last"
            ));
        }
    }
    Ok((lo, hi))
}

/// The frames numbered within `spec` (both ends included). Every frame must carry a number, and
/// the range must select at least one.
pub fn select_frames(frames: Vec<Frame>, spec: &str) -> Result<Vec<Frame>, CliError> {
    let (lo, hi) = parse_frame_range(spec).map_err(CliError::Usage)?;
    let (first, last) = (
        frames.iter().filter_map(|f| f.number).min(),
        frames.iter().filter_map(|f| f.number).max(),
    );
    if let Some(f) = frames.iter().find(|f| f.number.is_none()) {
        return Err(CliError::Usage(format!(
            "--frames needs numbered frames, and {} has no frame number in its name",
            f.path.display()
        )));
    }
    let picked: Vec<Frame> = frames
        .into_iter()
        .filter(|f| {
            let n = f.number.expect("checked");
            lo.is_none_or(|l| n >= l) && hi.is_none_or(|h| n <= h)
        })
        .collect();
    if picked.is_empty() {
        return Err(CliError::Usage(format!(
            "--frames '{spec}' selects no frame (the inputs number {} to {})",
            first.map_or("?".into(), |v| v.to_string()),
            last.map_or("?".into(), |v| v.to_string())
        )));
    }
    Ok(picked)
}

/// The header's record of one source frame: its number, its file name (no folders, so cooks are
/// reproducible across machines) and its active voxels.
pub(crate) fn frame_info(frame: &Frame, active_voxels: u64) -> FrameInfo {
    FrameInfo {
        number: frame.number,
        source: frame
            .path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        active_voxels,
    }
}

/// Cooks `a.inputs` with the options in `a`, in memory (nothing is written).
pub fn cook(a: &Args) -> Result<Cooked, CliError> {
    a.validate()?;
    let frames = resolve_frames(a)?;
    cook_frames(a, frames)
}

/// [`cook`] of frames the caller has already resolved from `a` ([`resolve_frames`]) and whose
/// options it has validated (`Args::validate`): `run` and the manifest check their outputs
/// against the frames first, and the frames are not listed twice.
pub fn cook_frames(a: &Args, frames: Vec<Frame>) -> Result<Cooked, CliError> {
    if crate::multi::is_auto(a) {
        let f0 = &frames[0].path;
        let file = VdbFile::open(f0)?;
        let pick = crate::grid_pick::suggest(&file);
        if pick.grids.is_empty() {
            let floats = file.float_grid_labels();
            return Err(err(
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
        let mut picked = a.clone();
        picked.grids = pick.grids;
        Progress::with(a.progress.clone(), a.json || a.quiet, !a.quiet).note(&format!(
            "note: --grids auto cooks {} (named as in {}){}",
            picked.grids.join(","),
            f0.display(),
            pick.skipped
                .iter()
                .map(|(g, why)| format!("; not '{g}': {why}"))
                .collect::<String>()
        ));
        crate::multi::validate(&picked)?;
        return cook_frames(&picked, frames);
    }
    if a.grids.len() > 1 {
        return crate::multi::cook_channels(a, frames);
    }
    if let [g] = &a.grids[..] {
        // One grid named by --grids: a single-channel cook of it, as `--grid` would be.
        let mut one = a.clone();
        one.grid = Some(g.clone());
        one.grids.clear();
        if let [(_, e)] = &one.max_error_per[..] {
            one.max_error = Some(*e);
        }
        one.max_error_per.clear();
        return cook_frames(&one, frames);
    }
    let t0 = Instant::now();
    let format = a
        .format
        .as_deref()
        .map(|f| PayloadFormat::parse(f).expect("clap checked"));
    let mut eopts = encode::EncodeOptions {
        format: format.unwrap_or(if a.max_error.is_some() || a.max_bytes.is_some() {
            PayloadFormat::Bc7
        } else {
            PayloadFormat::F32
        }),
        format_given: format.is_some(),
        max_error: a.max_error,
        lossy_tiles: a.max_error.is_some() || a.max_bytes.is_some(),
        range: if a.range == "global" {
            RangeMode::Global
        } else {
            RangeMode::Brick
        },
        bc7_quality: Bc7Quality::parse(&a.bc7_quality).ok_or_else(|| {
            err(
                &a.output,
                ErrorKind::Sequence,
                format!(
                    "unknown --bc7-quality '{}' (ultra-fast, very-fast, fast, basic, slow)",
                    a.bc7_quality
                ),
            )
        })?,
    };
    let format = eopts.format;
    let nf = NonFinite {
        replace_with: a.replace_non_finite,
        hint: !a.no_non_finite_flag,
    };
    if let Some(v) = a.replace_non_finite {
        if !v.is_finite() {
            return Err(err(
                &a.output,
                ErrorKind::Sequence,
                "--replace-non-finite needs a finite value",
            ));
        }
    }
    let mut st = Stages::default();
    // Lossless payloads need no per-voxel use counts: their error is checked to be zero below.
    let mut pool =
        Pool::new(format != PayloadFormat::F32 || a.max_error.is_some() || a.clusters.is_some());
    // (--max-bytes starts the format list at BC7, so `format` is lossy there too.)
    let mut first: Option<(Frame, Transform, f32, String)> = None;
    let (grid_name, grid_how) = choose_grid(&frames, a.grid.as_deref())?;
    let choice = GridChoice {
        name: &grid_name,
        how: &grid_how,
        allow_missing: a.allow_missing_grid,
        hint: !a.quiet,
    };
    // Frames without the grid, cooked empty (`--allow-missing-grid`).
    let mut missing: Vec<String> = Vec::new();
    let mut infos = Vec::with_capacity(frames.len());
    let mut value_range = [f32::INFINITY, f32::NEG_INFINITY];
    let progress = Progress::with(a.progress.clone(), a.json || a.quiet, !a.quiet);
    let stage = progress.stage("read, build, dedup", "frames");
    crate::progress::add_total(frames.len() as u64);
    let threads = rayon::current_num_threads().max(1);
    let chunk = (threads * 2).max(2);
    // Pipeline: while the frames of chunk k are read and built in parallel, chunk k-1 is added to
    // the pool (in sequence order, so the output does not depend on scheduling).
    let mut pending: Vec<Prepared> = Vec::new();
    let mut read_cpu = 0.0f64;
    let mut build_cpu = 0.0f64;
    let groups: Vec<&[Frame]> = frames.chunks(chunk).collect();
    for gi in 0..=groups.len() {
        let todo = std::mem::take(&mut pending);
        let (prepared, added) = rayon::join(
            || {
                groups.get(gi).map(|g| {
                    g.par_iter()
                        .map(|f| prepare(f, choice, nf))
                        .collect::<Vec<_>>()
                })
            },
            || -> Result<f64, CliError> {
                let t = Instant::now();
                for p in todo {
                    let PreparedFrame {
                        frame,
                        label,
                        transform,
                        background,
                        built,
                    } = p.result?;
                    let Some(transform) = transform else {
                        missing.push(frame.path.display().to_string());
                        infos.push(frame_info(&frame, 0));
                        pool.add_frame(built);
                        crate::progress::advance(1);
                        continue;
                    };
                    match &first {
                        None => {
                            if !transform.kind.is_linear() {
                                return Err(err(&frame.path, ErrorKind::Unsupported, format!("grid '{label}' has a {} transform; vdbcook cooks linear transforms only", transform.kind.type_name())));
                            }
                            first = Some((frame.clone(), transform, background, label));
                        }
                        Some((f0, t0, bg0, _)) => {
                            if !transform.approx_eq(t0, 1e-9) {
                                return Err(err(&frame.path, ErrorKind::Sequence, format!("grid '{label}' has a different transform (voxel size {:?}) from frame {} (voxel size {:?}); all frames must share one transform", transform.voxel_size(), f0.path.display(), t0.voxel_size())));
                            }
                            if background.to_bits() != bg0.to_bits() {
                                return Err(err(
                                    &frame.path,
                                    ErrorKind::Sequence,
                                    format!(
                                        "background {background} differs from frame {} ({bg0})",
                                        f0.path.display()
                                    ),
                                ));
                            }
                        }
                    }
                    if let Some(r) = built.value_range {
                        value_range = [value_range[0].min(r[0]), value_range[1].max(r[1])];
                    }
                    infos.push(frame_info(&frame, built.active_voxels));
                    pool.add_frame(built);
                    crate::progress::advance(1);
                }
                Ok(t.elapsed().as_secs_f64())
            },
        );
        st.dedup += added?;
        if let Some(p) = prepared {
            for x in &p {
                read_cpu += x.read_s;
                build_cpu += x.build_s;
            }
            pending = p;
        }
    }
    // Read and build overlap (per-frame tasks on all threads): report each as its share of the
    // worker time, in wall-clock seconds.
    st.read = read_cpu / threads as f64;
    st.build = build_cpu / threads as f64;
    stage.finish();
    let Some((f0, transform, bg, label)) = first else {
        return Err(err(
            &frames[0].path,
            ErrorKind::GridSelection,
            format!("no frame has the grid '{grid_name}' ({grid_how})"),
        ));
    };
    if !missing.is_empty() {
        progress.note(&format!(
            "note: {} frame(s) have no grid '{grid_name}' and are cooked as empty frames (--allow-missing-grid): {}",
            missing.len(),
            missing.join(", ")
        ));
    }
    let (offset, root_dims) = pool
        .extent()
        .map_err(|m| err(&f0.path, ErrorKind::Unsupported, m))?;
    // --lod: the coarser levels join the pool (exact values) before encoding; --lod-from K
    // stores them from level K (alone, it means --lod all).
    let lod_first = a.lod_from.unwrap_or(1);
    let lod_last = match (a.lod, a.lod_from) {
        (None, None) => 0,
        (want, _) => crate::lod::resolve(want.unwrap_or(crate::lod::Levels::All), root_dims),
    };
    if lod_last > 0 && lod_first > lod_last {
        return Err(err(
            &f0.path,
            ErrorKind::Unsupported,
            format!(
                "--lod-from {lod_first}: an extent of {} voxels has levels 1 to {lod_last} (the \
                 last one brick wide); give --lod-from {lod_last} or less",
                root_dims.iter().max().copied().unwrap_or(1) as u64 * 128
            ),
        ));
    }
    let lod_levels = if lod_last > 0 {
        lod_last + 1 - lod_first
    } else {
        0
    };
    let mut lod_bricks: Vec<u32> = Vec::new();
    if lod_levels > 0 {
        let stage = progress.stage("level of detail", "levels");
        crate::lod::add_levels(&mut pool, frames.len(), (lod_first, lod_last), offset, bg);
        lod_bricks = crate::lod::pool_bricks(&pool, frames.len());
        stage.finish();
    }

    // Every lossy cook has an error budget: --max-error, or the default share of the value range
    // (the background included), so neither BC7 outliers nor clustering go unchecked.
    let lossy = format != PayloadFormat::F32 || a.clusters.is_some();
    let mut budget_source = match (a.max_error, lossy) {
        (Some(_), _) => Some("given"),
        (None, true) => {
            let r = [value_range[0].min(bg), value_range[1].max(bg)];
            eopts.max_error = Some(encode::default_budget(r));
            Some("default")
        }
        (None, false) => None,
    };
    // --max-bytes: the smallest bound whose GPU bytes fit (lossless f32 if it fits).
    let mut size_doc: Option<report::SizeSearch> = None;
    if let Some(max_bytes) = a.max_bytes {
        let root_len = root_dims.iter().map(|&d| d as u64).product::<u64>();
        let n_l2 = pool.l2_refs.len() as u64;
        let refs: u64 = pool.l2_refs.iter().map(|r| r.len() as u64).sum();
        // roots, frame ranges, L2 masks, bases, prefixes and ranges, leaf refs (section_sizes).
        let fixed_topology = pool.frames.len() as u64 * (root_len * 4 + 8)
            + pool.l2_masks.len() as u64 * 8
            + n_l2 * (4 + L2_WORDS as u64 * 2 + 8)
            + refs * 4;
        let r = [value_range[0].min(bg), value_range[1].max(bg)];
        let search_stage = progress.stage("size search", "encodes");
        let mut steps = Vec::new();
        let found = size_budget::search(
            &pool.bricks,
            &eopts,
            fixed_topology,
            pool.tiles.len(),
            r[1] - r[0],
            max_bytes,
            |e, b| {
                steps.push(report::SizeStep {
                    max_error: e,
                    gpu_bytes: b,
                })
            },
        )
        .map_err(CliError::Usage)?;
        search_stage.finish();
        match found.max_error {
            None => {
                eopts.format = PayloadFormat::F32;
                eopts.format_given = true;
                eopts.max_error = None;
                eopts.lossy_tiles = false;
                budget_source = None;
            }
            Some(e) => {
                eopts.max_error = Some(e);
                budget_source = Some("max_bytes");
                let default = encode::default_budget(r);
                if e > default {
                    progress.note(&format!(
                        "warning: --max-bytes {max_bytes} needs an error bound of {e:e}, over the \
                         default artefact guard ({default:e}, 10% of the value range): expect \
                         visible artefacts"
                    ));
                }
            }
        }
        size_doc = Some(report::SizeSearch {
            limit: max_bytes,
            predicted_gpu_bytes: found.gpu_bytes,
            trials: found.trials,
            steps,
        });
    }
    let format = eopts.format;
    let budget = eopts.max_error;

    // Cluster (optional): members of a cluster are re-pointed to its centroid brick.
    let tc = Instant::now();
    let stage = a.clusters.map(|_| progress.stage("cluster", "bricks"));
    let n_pool = pool.brick_count();
    let mut input_of: Vec<u32> = (0..n_pool as u32).collect();
    let mut enc_input: Option<Vec<f32>> = None;
    let mut cstats: Option<report::Clustering> = None;
    if let Some(k) = a.clusters {
        let copts = cluster::ClusterOptions {
            clusters: k,
            iterations: a.iterations.unwrap_or(5),
            variance_threshold: a.variance_threshold.unwrap_or(0.1),
            seed: 1,
        };
        let r = cluster::cluster(&pool.bricks, &copts);
        let n_centroids = r.centroids.len() / BRICK_VOXELS;
        // The guard (always on: every lossy cook has a budget): a brick joins its cluster only if
        // the *decoded* centroid, plus what a GPU's native read may add, is within E of each of
        // its voxels.
        let mut rejected_by_error = 0usize;
        let mut member_of = r.member_of.clone();
        if budget.is_some() {
            let ce = encode::encode(&r.centroids, &eopts)
                .map_err(|m| err(&f0.path, ErrorKind::Unsupported, m))?;
            rejected_by_error =
                encode::guard_members(&pool.bricks, &r.centroids, &ce, &mut member_of, &eopts);
        }
        // Encode input: bricks that keep their own data, then the centroids that have members.
        let mut used = vec![u32::MAX; n_centroids];
        let mut input = Vec::new();
        let mut next = 0u32;
        for (b, m) in member_of.iter().enumerate() {
            if m.is_none() {
                input.extend_from_slice(&pool.bricks[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS]);
                input_of[b] = next;
                next += 1;
            }
        }
        for (b, m) in member_of.iter().enumerate() {
            if let Some(c) = *m {
                if used[c as usize] == u32::MAX {
                    used[c as usize] = next;
                    next += 1;
                    input.extend_from_slice(
                        &r.centroids[c as usize * BRICK_VOXELS..(c as usize + 1) * BRICK_VOXELS],
                    );
                }
                input_of[b] = used[c as usize];
            }
        }
        let clusters_used = used.iter().filter(|&&u| u != u32::MAX).count();
        // What clustering did, said whenever it is less than what was asked.
        if r.candidates == 0 {
            progress.note(&format!(
                "note: --clusters {k}: no brick has normalized variance <= {} (0 of {n_pool} candidates); nothing was clustered",
                copts.variance_threshold
            ));
        } else if k > r.candidates {
            progress.note(&format!(
                "note: --clusters {k} exceeds the {} candidate bricks; k is capped at {}",
                r.candidates, r.candidates
            ));
        }
        if r.candidates > 0 && clusters_used == 0 {
            progress.note(&format!(
                "note: --clusters {k}: every candidate was rejected by the error guard ({rejected_by_error} bricks; budget {}); nothing was clustered",
                budget.unwrap_or(0.0)
            ));
        }
        cstats = Some(report::Clustering {
            candidates: r.candidates,
            clusters_requested: k,
            clusters: clusters_used,
            iterations: r.iterations_run,
            rejected_by_variance: r.rejected_by_variance,
            rejected_by_error,
            variance_threshold: copts.variance_threshold,
            seconds: tc.elapsed().as_secs_f64(),
        });
        enc_input = Some(input);
    }
    st.cluster = tc.elapsed().as_secs_f64();
    drop(stage);
    let after_clustering = enc_input
        .as_ref()
        .map(|v| v.len() / BRICK_VOXELS)
        .unwrap_or(n_pool);
    // Encode.
    let t = Instant::now();
    let stage = progress.stage("encode", "blocks");
    let enc = encode::encode(enc_input.as_deref().unwrap_or(&pool.bricks), &eopts)
        .map_err(|m| err(&f0.path, ErrorKind::Unsupported, m))?;
    // Decoded values of what each pool brick now points at (for the error figures).
    let decoded_pool: Vec<f32> = if enc_input.is_some() {
        let mut d = vec![0f32; pool.bricks.len()];
        for (b, &i) in input_of.iter().enumerate() {
            d[b * BRICK_VOXELS..(b + 1) * BRICK_VOXELS].copy_from_slice(
                &enc.decoded_or(enc_input.as_deref().unwrap_or(&[]))
                    [i as usize * BRICK_VOXELS..(i as usize + 1) * BRICK_VOXELS],
            );
        }
        d
    } else {
        Vec::new()
    };
    drop(enc_input);
    // Bricks that became tiles append their values to the pool's tiles.
    pool.apply_encoding(
        input_of.iter().map(|&i| enc.remap[i as usize]),
        &enc.new_tiles,
    );
    let decoded: &[f32] = if decoded_pool.is_empty() {
        enc.decoded_or(&pool.bricks)
    } else {
        &decoded_pool
    };
    let root_len = root_dims.iter().map(|&d| d as usize).product::<usize>();
    let roots = pool.roots(offset, root_dims);
    let rg = ranges(
        enc.brick_ranges.clone(),
        &pool.tiles,
        &pool.l2_refs,
        &roots,
        root_len,
        &[bg],
    );
    let (l2_base, l2_prefix, l3_refs) = pool.layout(1);
    // Error over active voxels, per frame (every active use of a brick); tiles from the source
    // are stored exactly, lossy tiles made by --max-error are in `decoded`.
    let per_frame: Vec<FrameErr> = if pool.track_uses {
        use_errors(&pool.uses, &pool.bricks, decoded, |b| {
            enc.slack[input_of[b as usize] as usize]
        })
    } else {
        vec![FrameErr::default(); frames.len()]
    };
    let sum_sq: f64 = per_frame.iter().map(|f| f.sum_sq).sum();
    let max_abs = per_frame.iter().fold(0.0f64, |m, f| m.max(f.max_abs));
    let gpu_bound = per_frame.iter().fold(0.0f64, |m, f| m.max(f.gpu_bound));
    let lod_max_abs = lod_bricks.iter().fold(0.0f64, |m, &b| {
        let r = b as usize * BRICK_VOXELS..(b as usize + 1) * BRICK_VOXELS;
        pool.bricks[r.clone()]
            .iter()
            .zip(&decoded[r])
            .fold(m, |m, (x, y)| m.max((x - y).abs() as f64))
    });
    // The f32 pool is no longer needed: free it before serializing.
    let unique_bricks = pool.brick_count();
    pool.bricks = Vec::new();
    pool.uses = Vec::new();
    let m = asset_index_to_world(&transform, offset);
    let asset = Asset {
        header: Header {
            tool: format!("vdbcook {}", env!("CARGO_PKG_VERSION")),
            options: CookOptions {
                format,
                max_error: budget,
                range: eopts.range,
                bc7_quality: eopts.bc7_quality.name().to_string(),
                grid: a.grid.clone(),
                replace_non_finite: a.replace_non_finite,
                allow_gaps: a.allow_gaps,
            },
            grid_name: label,
            frames: infos,
            index_offset: offset,
            root_dims,
            index_to_world: m,
            source_map: transform.kind.type_name().to_string(),
            voxel_size: transform.voxel_size(),
            background: bg,
            brick_counts: enc.brick_counts,
            sections: Vec::new(),
            content_hash: 0,
            channels: Vec::new(),
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
        CliError::Other(format!(
            "internal error: cooked asset fails validation: {e}"
        ))
    })?;
    let (bytes, _) = asset
        .to_bytes()
        .map_err(|e| CliError::Other(e.to_string()))?;
    st.encode += t.elapsed().as_secs_f64();
    stage.finish();

    let active: u64 = asset.header.frames.iter().map(|f| f.active_voxels).sum();
    let sizes = section_sizes(&asset);
    let (topology, atlas) = topology_and_atlas(&sizes);
    if let Some(max_bytes) = a.max_bytes {
        // The search counted these bytes without building the asset: hold it to that.
        let predicted = size_doc.as_ref().map_or(0, |s| s.predicted_gpu_bytes);
        if topology + atlas != predicted || topology + atlas > max_bytes {
            return Err(CliError::Other(format!(
                "internal: --max-bytes {max_bytes} predicted {predicted} GPU bytes, the asset has {}",
                topology + atlas
            )));
        }
    }
    let rmse = if active > 0 {
        (sum_sq / active as f64).sqrt()
    } else {
        0.0
    };
    let peak = (value_range[1] - value_range[0]) as f64;
    let psnr = (rmse > 0.0 && peak > 0.0).then(|| 20.0 * (peak / rmse).log10());
    let bpv = |b: u64| {
        if active > 0 {
            b as f64 * 8.0 / active as f64
        } else {
            0.0
        }
    };
    let [r0, r1, r2, r3, r4] = enc.representation.per_format;
    let report = CookReport {
        output: a.output.display().to_string(),
        format: format.name().to_string(),
        grid: asset.header.grid_name.clone(),
        missing_grid_frames: missing,
        frames: asset.frame_count(),
        active_voxels: active,
        bricks: report::Bricks {
            source: pool.source_bricks,
            unique: unique_bricks as u64,
            after_clustering: after_clustering as u64,
            stored: asset.brick_count() as u64,
            tiles: asset.tiles.len() as u64,
            tile_leaves: pool.source_tiles,
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
        error: report::ErrorFigures {
            rmse,
            psnr_db: psnr,
            max_abs,
            exact: max_abs == 0.0,
            max_abs_any_gpu: gpu_bound,
        },
        frame_errors: per_frame
            .iter()
            .zip(&asset.header.frames)
            .enumerate()
            .map(|(i, (e, f))| {
                let rmse = if f.active_voxels > 0 {
                    (e.sum_sq / f.active_voxels as f64).sqrt()
                } else {
                    0.0
                };
                report::FrameError {
                    frame: i,
                    number: f.number,
                    rmse,
                    psnr_db: (rmse > 0.0 && peak > 0.0).then(|| 20.0 * (peak / rmse).log10()),
                    max_abs: e.max_abs,
                }
            })
            .collect(),
        clustering: cstats,
        representations: report::Representations {
            tile: enc.representation.tile,
            bc7: r0,
            bc4: r1,
            unorm8: r2,
            f16: r3,
            f32: r4,
        },
        max_error: budget,
        max_error_source: budget_source.map(str::to_string),
        max_bytes: size_doc,
        bc7_quality: eopts.bc7_quality.name().to_string(),
        range: match eopts.range {
            RangeMode::Brick => "brick",
            RangeMode::Global => "global",
        }
        .to_string(),
        peak_memory_bytes: peak_memory_bytes(),
        seconds: report::Seconds {
            total: t0.elapsed().as_secs_f64(),
            read: st.read,
            build: st.build,
            dedup: st.dedup,
            cluster: st.cluster,
            encode: st.encode,
            write: st.write,
        },
        channels: Vec::new(),
        dropped_channels: Vec::new(),
        lod: (lod_levels > 0).then(|| {
            let x = crate::lod::extra(&asset);
            let full = (topology + atlas).saturating_sub(x.topology + x.atlas);
            report::LodReport {
                levels: lod_levels,
                first: lod_first,
                l2_nodes: x.l2_nodes,
                bricks: x.bricks,
                topology_bytes: x.topology,
                atlas_bytes: x.atlas,
                share: (x.topology + x.atlas) as f64 / full.max(1) as f64,
                max_abs: lod_max_abs,
            }
        }),
    };
    Ok(Cooked {
        asset,
        bytes,
        report,
    })
}

/// Reads and validates an asset, with errors naming the file once.
pub fn load_asset(path: &Path) -> Result<Asset, CliError> {
    let bytes =
        std::fs::read(path).map_err(|e| err(path, ErrorKind::Io, format!("cannot read: {e}")))?;
    Asset::from_bytes(&bytes).map_err(|e| {
        err(
            path,
            ErrorKind::Corrupt,
            format!("not a valid asset: {}", e.0),
        )
    })
}

/// Peak resident memory of this process (Linux `VmHWM`), if known.
pub(crate) fn peak_memory_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
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
    for (f, p) in PayloadFormat::ORDER.iter().zip(&asset.payloads) {
        v.push((SectionKind::payload(*f).name(), p.len() as u64));
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

fn print_summary(d: &Value) {
    println!(
        "cooked {} frame(s) of '{}' into {} ({})",
        d["frames"],
        d["grid"].as_str().unwrap_or(""),
        d["output"].as_str().unwrap_or(""),
        d["format"].as_str().unwrap_or("")
    );
    println!("  active voxels  {}", d["active_voxels"]);
    let b = &d["bricks"];
    println!(
        "  bricks         {} source -> {} unique, {} stored; {} tile values",
        b["source"], b["unique"], b["stored"], b["tiles"]
    );
    let y = &d["bytes"];
    println!(
        "  bytes          file {}, GPU topology {} + atlas {}",
        y["file"], y["topology"], y["atlas"]
    );
    println!(
        "  bits/voxel     {:.3} (file), {:.3} (GPU), topology {:.3}",
        d["bits_per_active_voxel"].as_f64().unwrap_or(0.0),
        d["bits_per_active_voxel_gpu"].as_f64().unwrap_or(0.0),
        d["topology_bits_per_active_voxel"].as_f64().unwrap_or(0.0)
    );
    let e = &d["error"];
    println!(
        "  error          rmse {:.3e}, max abs {:.3e}, psnr {}",
        e["rmse"].as_f64().unwrap_or(0.0),
        e["max_abs"].as_f64().unwrap_or(0.0),
        e["psnr_db"]
            .as_f64()
            .map(|p| format!("{p:.1} dB"))
            .unwrap_or_else(|| "exact".into())
    );
    if let Some(budget) = d["max_error"].as_f64() {
        let how = match d["max_error_source"].as_str() {
            Some("default") => " (default: 10% of the value range; set --max-error for a target)",
            _ => " (--max-error)",
        };
        println!(
            "  budget         every voxel within {budget:.3e}{how}; any conformant GPU reads within {:.3e}",
            e["max_abs_any_gpu"].as_f64().unwrap_or(0.0)
        );
    }
    let dropped: Vec<&str> = d["dropped_channels"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|c| c["name"].as_str())
        .collect();
    if !dropped.is_empty() {
        println!(
            "  dropped        {} (carry nothing within their budgets)",
            dropped.join(", ")
        );
    }
    let c = &d["clustering"];
    if !c.is_null() {
        println!(
            "  clustering     {} of {} requested clusters from {} candidate bricks ({} rejected by variance, {} by the error guard)",
            c["clusters"], c["clusters_requested"], c["candidates"], c["rejected_by_variance"], c["rejected_by_error"]
        );
    }
    let s = &d["seconds"];
    let f = |k: &str| s[k].as_f64().unwrap_or(0.0);
    println!("  seconds        total {:.2} (read {:.2}, build {:.2}, dedup {:.2}, encode {:.2}, write {:.2})", f("total"), f("read"), f("build"), f("dedup"), f("encode"), f("write"));
}
