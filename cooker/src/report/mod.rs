//! `vdbcook report`: cooks one input across a matrix of configurations (payload formats,
//! clustering, `--max-error` tolerances), measures each one's size, voxel error, image error,
//! cook time and trace time (CPU reference always, GPU when an adapter exists), runs the peers
//! that are installed (NanoVDB quantization, `vdb_render`) on the same input, and writes charts
//! of speed against accuracy, a side-by-side figure of renders with error images, and the rows
//! as JSON, CSV and Markdown. Everything is computed before DIR is touched: a failure leaves
//! nothing behind. Three stages, one module each: `collect` → `figures` → `write`.

pub mod chart;
mod collect;
mod figures;
mod peers;
mod write;

use collect::{collect, Collected};
use figures::{figures, Figures};
use write::write;

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;
use serde_json::{json, Value};
use vdbcook_trace::{Camera, Image, Integrator, Mode, Output, RenderSettings};
use vdbcook_vdb::sequence;

use crate::errors::CliError;
use crate::gpu::Gpu;
use chart::{Point, Series, Tile, PALETTE};

#[derive(clap::Args)]
pub struct Args {
    /// VDB files, folders, frame patterns (smoke.####.vdb) or globs: one sequence.
    #[arg(required = true, value_name = "INPUT")]
    inputs: Vec<String>,
    /// Output folder (created; report.md, report.json, report.csv and the PNGs go there).
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// Grid to cook (default: `density`, else the only float grid).
    #[arg(long)]
    grid: Option<String>,
    /// A small matrix (each format, one clustering, one tolerance), smaller renders, one run.
    #[arg(long)]
    quick: bool,
    /// Print the rows as one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
    /// Accept gaps in the frame numbering.
    #[arg(long)]
    allow_gaps: bool,
    /// Frame rendered for image error and trace time (0-based).
    #[arg(long, default_value_t = 0)]
    frame: usize,
    /// Deterministic render mode for image error and trace time (scatter is what vdb_render
    /// draws, so its time is comparable).
    #[arg(long, default_value = "scatter", value_parser = ["scatter", "density", "first-hit", "depth"])]
    mode: String,
    /// Render width (default 640; 320 with --quick).
    #[arg(long)]
    width: Option<u32>,
    /// Render height (default 360; 180 with --quick).
    #[arg(long)]
    height: Option<u32>,
    /// Timed renders per configuration; the median is reported (default 3; 1 with --quick).
    #[arg(long)]
    runs: Option<usize>,
    /// `--max-error` tolerances as fractions of the value range (default 0.002,0.01,0.05;
    /// 0.01 with --quick).
    #[arg(long, value_delimiter = ',', value_name = "F,F,...")]
    tolerances: Option<Vec<f64>>,
    /// Skip the GPU trace times.
    #[arg(long)]
    no_gpu: bool,
    /// Skip the peers (nanovdb_convert, vdb_render) even when installed.
    #[arg(long)]
    no_peers: bool,
}

fn other(m: impl Into<String>) -> CliError {
    CliError::Other(m.into())
}

/// One cook configuration.
struct Config {
    label: String,
    format: Option<&'static str>,
    clusters: Option<(usize, f32)>,
    /// As a fraction of the value range (resolved once the range is known).
    tolerance: Option<f64>,
    /// Chart series: 0 formats, 1 clustered, 2 max-error.
    series: usize,
}

fn matrix(quick: bool, tolerances: &[f64]) -> Vec<Config> {
    let mut v: Vec<Config> = ["f32", "f16", "unorm8", "bc4", "bc7"]
        .iter()
        .map(|f| Config {
            label: f.to_string(),
            format: Some(f),
            clusters: None,
            tolerance: None,
            series: 0,
        })
        .collect();
    let clusterings: &[(usize, f32)] = if quick {
        &[(64, 0.1)]
    } else {
        &[(64, 0.1), (256, 0.5)]
    };
    for &(k, t) in clusterings {
        v.push(Config {
            label: format!("f16 k={k} T={t}"),
            format: Some("f16"),
            clusters: Some((k, t)),
            tolerance: None,
            series: 1,
        });
    }
    for &e in tolerances {
        v.push(Config {
            label: format!("E={e}r"),
            format: None,
            clusters: None,
            tolerance: Some(e),
            series: 2,
        });
    }
    if !quick {
        if let Some(&e) = tolerances.get(tolerances.len() / 2) {
            v.push(Config {
                label: format!("E={e}r k=256"),
                format: None,
                clusters: Some((256, 0.5)),
                tolerance: Some(e),
                series: 2,
            });
        }
    }
    v
}

/// One configuration's measurements (the `--json` rows; the first keys are the CLI contract).
#[derive(Serialize, Clone)]
pub struct Row {
    pub format: String,
    pub clusters: Option<usize>,
    pub max_error: Option<f64>,
    pub bytes_gpu: u64,
    pub bytes_file: u64,
    pub bits_per_active_voxel: f64,
    pub rmse: f64,
    pub psnr_db: Option<f64>,
    pub max_abs: f64,
    pub image_rmse: f64,
    pub cook_seconds: f64,
    pub trace_ms_cpu: f64,
    pub trace_ms_gpu: Option<f64>,
    /// A short name for charts and tables.
    pub label: String,
    pub variance_threshold: Option<f32>,
    pub bits_per_active_voxel_gpu: f64,
    pub image_max_abs: f64,
    /// Cook stages in seconds (read, build, dedup, cluster, encode).
    pub cook_stages: Value,
    /// Bricks stored per representation (tile, bc7, bc4, unorm8, f16, f32, packed1..7).
    pub representations: crate::cook_report::Representations,
    /// What the runtime put on the GPU for this asset (bytes and layout), when measured.
    pub gpu_upload_bytes: Option<u64>,
    pub gpu_layout: Option<String>,
    /// The same frames as NanoVDB grids at this row's bound (the cook's `nanovdb`): GPU bits per
    /// active voxel.
    pub nanovdb_bits_per_active_voxel: Option<f64>,
}

/// A peer's measurements, in the rows' units.
#[derive(Serialize, Clone)]
pub struct PeerRow {
    pub tool: String,
    pub config: String,
    pub bytes_file: Option<u64>,
    pub bytes_gpu: Option<u64>,
    pub bits_per_active_voxel: Option<f64>,
    pub bits_per_active_voxel_gpu: Option<f64>,
    pub rmse: Option<f64>,
    pub psnr_db: Option<f64>,
    pub max_abs: Option<f64>,
    pub image_rmse: Option<f64>,
    pub cook_seconds: Option<f64>,
    pub trace_ms_cpu: Option<f64>,
}

/// A progress bar on a terminal, a line per step otherwise (silent under `--json` unless on a
/// terminal).
struct Progress {
    total: usize,
    done: usize,
    tty: bool,
    on: bool,
    start: Instant,
}

impl Progress {
    fn new(total: usize, json: bool) -> Self {
        let tty = std::io::stderr().is_terminal() && std::env::var_os("CI").is_none();
        Progress {
            total,
            done: 0,
            tty,
            on: tty || !json,
            start: Instant::now(),
        }
    }
    fn step(&mut self, what: &str) {
        if !self.on {
            return;
        }
        let t = self.start.elapsed().as_secs_f64();
        if self.tty {
            let n = 24;
            let f = (self.done * n) / self.total.max(1);
            eprint!(
                "\r  [{}{}] {}/{} {:<40.40} {t:6.1} s",
                "#".repeat(f),
                "-".repeat(n - f),
                self.done,
                self.total,
                what
            );
            let _ = std::io::stderr().flush();
        } else {
            eprintln!("  [{}/{}] {what} ({t:.1} s)", self.done + 1, self.total);
        }
        self.done += 1;
    }
    fn finish(&self) {
        if self.on && self.tty {
            eprintln!(
                "\r  [{}] {}/{} done in {:.1} s{}",
                "#".repeat(24),
                self.total,
                self.total,
                self.start.elapsed().as_secs_f64(),
                " ".repeat(30)
            );
        }
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// RMSE and max |Δ| over the RGB channels of two RGBA images (linear display values).
fn image_error(a: &Image, b: &Image) -> (f64, f64) {
    let (mut sum, mut max, mut n) = (0.0f64, 0.0f64, 0u64);
    for (p, q) in a.rgba.chunks_exact(4).zip(b.rgba.chunks_exact(4)) {
        for c in 0..3 {
            let d = p[c] as f64 - q[c] as f64;
            sum += d * d;
            max = max.max(d.abs());
            n += 1;
        }
    }
    ((sum / n.max(1) as f64).sqrt(), max)
}

/// The CPU reference render, `runs` times (after no warm-up: the tracer has no caches that
/// outlive a call); the median in ms and the image.
fn cpu_trace(
    asset: &vdbcook_asset::Asset,
    camera: &Camera,
    s: &RenderSettings,
    runs: usize,
) -> Result<(f64, Image), CliError> {
    let mut times = Vec::new();
    let mut img = None;
    for _ in 0..runs.max(1) {
        let t = Instant::now();
        img = Some(vdbcook_trace::render(asset, camera, s).map_err(|e| other(e.to_string()))?);
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    Ok((median(times), img.expect("one run")))
}

fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    format!(
        "{cpu}, {cores} cores ({} threads used), {}",
        rayon::current_num_threads(),
        std::env::consts::OS
    )
}

/// A round gain (1, 2 or 5 × 10ⁿ, at least 1) that maps `worst` to at most full scale.
fn nice_gain(worst: f64) -> f64 {
    if worst.is_nan() || worst <= 0.0 {
        return 1.0;
    }
    let g = 1.0 / worst;
    let e = g.log10().floor();
    let base = 10f64.powf(e);
    let m = [5.0, 2.0, 1.0]
        .into_iter()
        .find(|m| m * base <= g)
        .unwrap_or(1.0);
    (m * base).max(1.0)
}

/// Halves an RGB8 image (2×2 box) until it is at most `max_w` wide.
fn shrink(mut rgb: Vec<u8>, mut w: u32, mut h: u32, max_w: u32) -> (Vec<u8>, u32, u32) {
    while w > max_w && w >= 2 && h >= 2 {
        let (nw, nh) = (w / 2, h / 2);
        let mut out = vec![0u8; (nw * nh * 3) as usize];
        for y in 0..nh {
            for x in 0..nw {
                for c in 0..3 {
                    let at = |xx: u32, yy: u32| rgb[((yy * w + xx) * 3 + c) as usize] as u32;
                    let s = at(2 * x, 2 * y)
                        + at(2 * x + 1, 2 * y)
                        + at(2 * x, 2 * y + 1)
                        + at(2 * x + 1, 2 * y + 1);
                    out[((y * nw + x) * 3 + c) as usize] = ((s + 2) / 4) as u8;
                }
            }
        }
        (rgb, w, h) = (out, nw, nh);
    }
    (rgb, w, h)
}

fn fmt_opt(v: Option<f64>, p: usize) -> String {
    v.filter(|x| x.is_finite())
        .map(|x| format!("{x:.p$}"))
        .unwrap_or_else(|| "–".into())
}

fn sci(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else {
        format!("{v:.2e}")
    }
}

fn csv_field(v: &Value) -> String {
    match v {
        Value::Null => String::new(),
        Value::String(s) => {
            if s.contains([',', '"', '\n']) {
                format!("\"{}\"", s.replace('"', "\"\""))
            } else {
                s.clone()
            }
        }
        other => other.to_string(),
    }
}

/// The rows as CSV: the contract keys first, then label, threshold, GPU bits, image max.
fn to_csv(rows: &[Row]) -> String {
    let keys = [
        "label",
        "format",
        "clusters",
        "variance_threshold",
        "max_error",
        "bytes_gpu",
        "bytes_file",
        "bits_per_active_voxel",
        "bits_per_active_voxel_gpu",
        "rmse",
        "psnr_db",
        "max_abs",
        "image_rmse",
        "image_max_abs",
        "cook_seconds",
        "trace_ms_cpu",
        "trace_ms_gpu",
        "gpu_upload_bytes",
    ];
    let mut s = keys.join(",") + "\n";
    for r in rows {
        let v = serde_json::to_value(r).expect("row json");
        let line: Vec<String> = keys.iter().map(|k| csv_field(&v[*k])).collect();
        s += &line.join(",");
        s += "\n";
    }
    s
}

/// One file of the report, through `output::write` (atomic, removed on failure or a signal).
fn write_file(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), CliError> {
    crate::output::write(&dir.join(name), bytes, name)
}

pub fn run(a: &Args) -> Result<(), CliError> {
    let mut c = collect(a)?;
    let f = figures(a, &mut c)?;
    write(a, &c, &f)
}

/// The rows as a Markdown table.
fn table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| config | GPU bit/vox | NanoVDB bit/vox, same bound | file bit/vox | voxel RMSE | PSNR dB | max abs | image RMSE | cook s | CPU trace ms | GPU trace ms |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {:.3} | {} | {:.3} | {} | {} | {} | {} | {:.3} | {:.1} | {} |\n",
            r.label,
            r.bits_per_active_voxel_gpu,
            fmt_opt(r.nanovdb_bits_per_active_voxel, 3),
            r.bits_per_active_voxel,
            sci(r.rmse),
            fmt_opt(r.psnr_db, 1),
            sci(r.max_abs),
            sci(r.image_rmse),
            r.cook_seconds,
            r.trace_ms_cpu,
            fmt_opt(r.trace_ms_gpu, 1)
        );
    }
    s
}

fn markdown(
    a: &Args,
    rows: &[Row],
    peers: &[PeerRow],
    notes: &[String],
    meta: &Value,
    layouts: &[String],
) -> String {
    let mut s = format!("# vdbcook report: {}\n\n", a.inputs.join(" "));
    s += &format!(
        "Grid `{}`, {} frame(s), {} active voxels, value range {:.4}. Machine: {}. GPU: {}.\n\n",
        meta["grid"].as_str().unwrap_or(""),
        meta["frames"],
        meta["active_voxels"],
        meta["value_range"].as_f64().unwrap_or(0.0),
        meta["machine"].as_str().unwrap_or(""),
        meta["gpu"].as_str().unwrap_or("none")
    );
    let mut cmd = format!(
        "vdbcook report {} -o {}",
        a.inputs.join(" "),
        a.output.display()
    );
    if a.quick {
        cmd += " --quick";
    }
    if let Some(g) = &a.grid {
        cmd += &format!(" --grid {g}");
    }
    s += &format!("Regenerate: `{cmd}`\n\n");
    s += "![size vs error](size_vs_error.png)\n\n![cook time vs error](cook_time_vs_error.png)\n\n![trace time vs error](trace_time_vs_error.png)\n\n![renders](renders.png)\n\n";
    s += "## Configurations\n\n";
    s += "`E=…r` rows are `--max-error` at that fraction r of the value range (each brick the \
          cheapest representation within E); `k`/`T` rows cluster with `--clusters k \
          --variance-threshold T`. Voxel error is over every active voxel of every frame; image \
          error is over the RGB of one render against the f32 asset's render. Times are medians; \
          cook time is the whole in-memory cook (read included, no file write).\n\n";
    s += &table(rows);
    if !peers.is_empty() {
        s += "\n## Peers (same input, same run)\n\n| tool | config | GPU bit/vox | voxel RMSE | max abs | convert s | trace ms | image RMSE |\n|---|---|---:|---:|---:|---:|---:|---:|\n";
        for p in peers {
            s += &format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} |\n",
                p.tool,
                p.config,
                fmt_opt(p.bits_per_active_voxel_gpu, 3),
                p.rmse.map(sci).unwrap_or_else(|| "–".into()),
                p.max_abs.map(sci).unwrap_or_else(|| "–".into()),
                fmt_opt(p.cook_seconds, 3),
                fmt_opt(p.trace_ms_cpu, 1),
                p.image_rmse.map(sci).unwrap_or_else(|| "–".into()),
            );
        }
        s += "\nNanoVDB bytes are the `.nvdb` file (its GPU buffer); its error is measured by \
              converting back to VDB and comparing every source voxel. `vdb_render` renders the \
              source VDB with trilinear sampling; its image error is against our f32 render in \
              8-bit RGB, so it shows the filtering difference, not a loss.\n";
    }
    if !layouts.is_empty() {
        s += "\n## GPU payload layout chosen by the runtime\n\n";
        for l in layouts {
            s += &format!("- {l}\n");
        }
    }
    if !notes.is_empty() {
        s += "\n## Notes\n\n";
        for n in notes {
            s += &format!("- {n}\n");
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_matrix_has_every_format_clustering_and_tolerance() {
        let m = matrix(false, &[0.002, 0.01, 0.05]);
        let labels: Vec<&str> = m.iter().map(|c| c.label.as_str()).collect();
        for f in ["f32", "f16", "unorm8", "bc4", "bc7"] {
            assert!(labels.contains(&f));
        }
        assert_eq!(m[0].label, "f32", "the reference comes first");
        assert_eq!(m.iter().filter(|c| c.clusters.is_some()).count(), 3);
        assert_eq!(m.iter().filter(|c| c.tolerance.is_some()).count(), 4);
        let q = matrix(true, &[0.01]);
        assert!(q.len() < m.len());
    }

    #[test]
    fn shrink_halves_with_a_box_filter() {
        let rgb: Vec<u8> = [0u8, 0, 0, 100, 100, 100, 200, 200, 200, 100, 100, 100].to_vec();
        let (out, w, h) = shrink(rgb, 2, 2, 1);
        assert_eq!((w, h), (1, 1));
        assert_eq!(out, vec![100, 100, 100]);
    }

    #[test]
    fn error_gain_is_round_and_keeps_the_worst_error_in_range() {
        assert_eq!(nice_gain(0.0), 1.0);
        assert_eq!(nice_gain(0.3), 2.0);
        assert_eq!(nice_gain(0.004), 200.0);
        assert_eq!(nice_gain(3.0), 1.0);
        for w in [1e-5, 3.3e-4, 0.07, 0.9] {
            let g = nice_gain(w);
            assert!(g * w <= 1.0 + 1e-12 && g * w > 0.19, "{w}: {g}");
        }
    }

    #[test]
    fn csv_quotes_fields_with_commas() {
        assert_eq!(csv_field(&json!("a,b")), "\"a,b\"");
        assert_eq!(csv_field(&Value::Null), "");
        assert_eq!(csv_field(&json!(1.5)), "1.5");
    }
}
