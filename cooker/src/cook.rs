//! `vdbcook cook`: the CLI over the cooking library (`vdbcook_cook`). Its flags are parsed into
//! the library's typed [`CookOptions`] ([`Args::options`]), everything that can be checked is
//! checked before any frame is read (options, inputs, the output's folder), the pipeline runs,
//! and the asset is written by `output::write` (temporary file, renamed into place). With
//! `--manifest`, many cooks from a TOML file with a content-addressed cache (`manifest`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde_json::Value;
use vdbcook_asset::{Asset, PayloadFormat, RangeMode};
use vdbcook_cook::frames::resolve_frames;
use vdbcook_cook::progress::Progress;
use vdbcook_cook::{
    Bc7Quality, Budget, Clustering, Context, CookOptions, FrameRange, Grids, Levels, Lod,
};
use vdbcook_vdb::{ErrorKind, VdbError};

use crate::errors::CliError;
use crate::spell::{self, MaxErrorArg};

pub use vdbcook_cook::Cooked;

/// `vdbcook cook`'s flags.
#[derive(clap::Args, Clone)]
pub struct Args {
    /// VDB files, folders, frame patterns (smoke.####.vdb, smoke.%04d.vdb) or globs.
    #[arg(required_unless_present = "manifest", value_name = "INPUT")]
    pub inputs: Vec<String>,
    /// Output asset file.
    /// (Required unless --manifest.)
    #[arg(short = 'o', long = "output", value_name = "OUT")]
    pub output: Option<PathBuf>,
    /// Cook only the frames numbered A to B, both included, as the file names number them
    /// (`10..90`, `10..`, `..90`).
    #[arg(long, value_name = "A..B", value_parser = spell::parse_frames)]
    pub frames: Option<FrameRange>,
    /// Cook every asset a TOML manifest lists, with a content-addressed cache: unchanged assets
    /// are not recooked (`docs/cli.md`, "Batch cooking").
    #[arg(long, value_name = "TOML", conflicts_with_all = ["inputs", "frames"])]
    pub manifest: Option<PathBuf>,
    /// The cache folder of --manifest (default: `.vdbcook-cache` beside the manifest). A plain
    /// folder of files named by key: a build farm can share it.
    #[arg(long, value_name = "DIR", requires = "manifest")]
    pub cache_dir: Option<PathBuf>,
    /// Brick payload: f32 (bit exact), f16, unorm8 (8 bit), bc4 (4 bit), bc7 (2 bit per voxel)
    /// or packed1..packed7 (1..7 bit per voxel, read exactly on any GPU). Default f32; with
    /// --max-error and no --format, per brick the smallest that meets the error.
    #[arg(long, value_parser = [
        "f32", "f16", "unorm8", "bc4", "bc7", "packed1", "packed2", "packed3", "packed4",
        "packed5", "packed6", "packed7",
    ])]
    pub format: Option<String>,
    /// Under an error budget, do not store bricks packed at their own bit depth (packed1..7):
    /// only BC7, BC4, unorm8, f16, f32, as runtimes before asset format 7 read.
    #[arg(long)]
    pub no_packed: bool,
    /// Every voxel of every frame decodes within E of its source value, as any GPU reads it
    /// whose BC decoding meets D3D's precision rule (docs/payloads.md): each brick takes the
    /// cheapest representation that meets E (tile, packed1, bc7, packed2, packed3, bc4, packed4..7,
    /// unorm8, f16, f32), starting at
    /// --format when one is given. Without it a lossy cook gets
    /// 10% of the value range as an artefact guard. With --grids, one budget per channel:
    /// `density=0.01,temperature=5` (a bare E applies to the channels not named).
    #[arg(
        long = "max-error",
        value_name = "E|NAME=E,..",
        allow_negative_numbers = true,
        value_parser = spell::parse_max_error
    )]
    pub max_error: Option<MaxErrorArg>,
    /// Size budget instead of an error budget: the smallest error bound whose asset's GPU bytes
    /// (topology + atlas, as `info` reports them) fit in SIZE: bytes, or K/M/G (10³…) or
    /// KiB/MiB/GiB (2¹⁰…), e.g. 32MiB. With --grids the bound is one share of every channel's
    /// value range. Reports the bound it reached.
    #[arg(long, value_name = "SIZE", value_parser = spell::parse_size)]
    pub max_bytes: Option<u64>,
    /// Quantization range of unorm8/bc4/bc7 bricks: each brick's own min/max, or one global
    /// range (one grid only).
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
    /// a temperature and a flame grid of Blender, Houdini or EmberGen caches). Composes with
    /// every other option (--clusters, --max-bytes, --lod, --frames).
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
    /// With --grids, bricks of different grids never share a centroid (K is shared among them).
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
    /// `all`, to one 8^3 brick; every channel of --grids. Same payload and error budget; +22%
    /// (WDAS cloud) to +99% (stormscape) GPU bytes on the samples from level 1, docs/asset.md
    /// (`lod` in --json says what it added).
    #[arg(long, value_name = "N|all", value_parser = spell::parse_levels)]
    pub lod: Option<Levels>,
    /// Store the levels of --lod from level K on (1 to 12; default 1): the finer ones are built
    /// and dropped. The first coarse level is most of a chain's bytes, and a light volume reads
    /// level K only where its cells are wider than 2^(K+1) voxels. Implies `--lod all` without
    /// --lod. Example: `--lod-from 2` (WDAS cloud: +6% instead of +22%).
    #[arg(long, value_name = "K", value_parser = spell::parse_first)]
    pub lod_from: Option<u32>,
    /// Replace NaN and ±Inf active values with VALUE (by default they are an error).
    #[arg(long, value_name = "VALUE", allow_negative_numbers = true)]
    pub replace_non_finite: Option<f32>,
}

impl Args {
    /// The cook these flags ask for, with every flag-level combination checked (the library
    /// checks the rest: [`CookOptions::validate`]).
    pub fn options(&self) -> Result<CookOptions, CliError> {
        let bad = |m: &str| Err(CliError::Usage(m.into()));
        if self.clusters.is_none() {
            if self.iterations.is_some() {
                return bad("--iterations only applies with --clusters K");
            }
            if self.variance_threshold.is_some() {
                return bad("--variance-threshold only applies with --clusters K");
            }
        }
        let budget = match (&self.max_error, self.max_bytes) {
            (Some(_), Some(_)) => {
                return bad(
                    "--max-bytes and --max-error each set the error bound: give one of them",
                )
            }
            (None, Some(n)) => Budget::MaxBytes(n),
            (Some(MaxErrorArg::All(e)), None) => Budget::MaxError {
                all: Some(*e),
                per: Vec::new(),
            },
            (Some(MaxErrorArg::Per { all, per }), None) => Budget::MaxError {
                all: *all,
                per: per.clone(),
            },
            (None, None) => Budget::Default,
        };
        let opts = CookOptions {
            grids: match (&self.grids[..], &self.grid) {
                ([], None) => Grids::Default,
                ([], Some(g)) => Grids::One(g.clone()),
                ([g], _) if g == "auto" => Grids::Auto,
                (g, _) => Grids::Several(g.to_vec()),
            },
            format: self
                .format
                .as_deref()
                .map(|f| PayloadFormat::parse(f).expect("clap checked")),
            budget,
            range: if self.range == "global" {
                RangeMode::Global
            } else {
                RangeMode::Brick
            },
            packed: !self.no_packed,
            bc7_quality: Bc7Quality::parse(&self.bc7_quality).ok_or_else(|| {
                CliError::Usage(format!(
                    "unknown --bc7-quality '{}' (ultra-fast, very-fast, fast, basic, slow)",
                    self.bc7_quality
                ))
            })?,
            clustering: self.clusters.map(|k| {
                let d = Clustering::new(k);
                Clustering {
                    iterations: self.iterations.unwrap_or(d.iterations),
                    variance_threshold: self.variance_threshold.unwrap_or(d.variance_threshold),
                    ..d
                }
            }),
            lod: match (self.lod, self.lod_from) {
                (None, None) => None,
                (levels, first) => Some(Lod {
                    levels: levels.unwrap_or(Levels::All),
                    first: first.unwrap_or(1),
                }),
            },
            frames: self.frames,
            allow_gaps: self.allow_gaps,
            allow_missing_grid: self.allow_missing_grid,
            keep_empty_channels: self.keep_empty_channels,
            replace_non_finite: self.replace_non_finite,
        };
        opts.validate()?;
        Ok(opts)
    }
}

pub fn run(a: &Args) -> Result<(), CliError> {
    if a.manifest.is_some() {
        if a.output.is_some() {
            return Err(CliError::Usage(
                "--manifest writes the outputs its entries name: drop -o/--output".into(),
            ));
        }
        return crate::manifest::run(a);
    }
    let Some(output) = a.output.clone() else {
        return Err(CliError::Usage(
            "the output asset is required: -o OUT (or --manifest TOML for batch cooking)".into(),
        ));
    };
    let t0 = Instant::now();
    let opts = a.options()?;
    // Everything checkable is checked before the work: the inputs resolve to frames, the output
    // is neither an input nor in a folder that cannot take it.
    let frames = resolve_frames(&a.inputs, opts.allow_gaps, opts.frames)?;
    crate::output::refuse_inputs(&output, &frames, &a.inputs, "asset")?;
    crate::output::check_writable(&output, "asset")?;
    let cx = Context {
        progress: Progress::with(None, a.json, true),
        hint_missing_grid: true,
        hint_non_finite: true,
    };
    let Cooked {
        bytes, mut report, ..
    } = vdbcook_cook::cook(&opts, frames, &cx)?;
    report.output = output.display().to_string();
    let t = Instant::now();
    let stage = Progress::with(None, a.json, true).stage("write", "bytes");
    crate::output::write(&output, &bytes, "asset")?;
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

/// Reads and validates an asset, with errors naming the file once.
pub fn load_asset(path: &Path) -> Result<Asset, CliError> {
    let bytes = std::fs::read(path).map_err(|e| {
        CliError::Vdb(VdbError::new(
            ErrorKind::Io,
            path,
            format!("cannot read: {e}"),
        ))
    })?;
    Asset::from_bytes(&bytes).map_err(|e| {
        CliError::Vdb(VdbError::new(
            ErrorKind::Corrupt,
            path,
            format!("not a valid asset: {}", e.0),
        ))
    })
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
    let n = |v: &Value| v.as_u64().unwrap_or(0);
    println!(
        "  GPU            {} bytes, {:.3} bit/active voxel (topology {}, {:.3} bit/voxel; atlas {})",
        n(&y["topology"]) + n(&y["atlas"]),
        d["bits_per_active_voxel_gpu"].as_f64().unwrap_or(0.0),
        y["topology"],
        d["topology_bits_per_active_voxel"].as_f64().unwrap_or(0.0),
        y["atlas"]
    );
    let nano = &d["nanovdb"];
    if !nano.is_null() {
        let fmt = nano["format"].as_str().unwrap_or("");
        println!(
            "  vs NanoVDB     {} bytes as {} at the same {} ({:.3} bit/active voxel): this asset is {:.3}x",
            nano["gpu_bytes"],
            fmt,
            if fmt == "float" { "exactness" } else { "bound" },
            nano["bits_per_active_voxel"].as_f64().unwrap_or(0.0),
            nano["ratio"].as_f64().unwrap_or(0.0)
        );
    }
    println!(
        "  file           {} bytes, {:.3} bit/active voxel",
        y["file"],
        d["bits_per_active_voxel"].as_f64().unwrap_or(0.0)
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
            "  budget         every voxel within {budget:.3e}{how}; a GPU within the BC precision rules reads within {:.3e}",
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
