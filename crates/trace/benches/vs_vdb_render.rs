//! The CPU reference tracer against OpenVDB's `vdb_render`, and the image-space error of each
//! lossy payload against the f32 asset (the results: `docs/rendering.md`).
//!
//! For each source VDB (default: the WDAS cloud at 1/16 and stormscape frame 0, from
//! `../shared/samples`), at 640×360 and 1920×1080, from the tracer's default view
//! (`Camera::framing`) and with the tracer's default medium and light (= `vdb_render`'s):
//! 1. `vdb_render` single scatter with the same camera and settings spelled out, median of
//!    [`RUNS`] (render-only time from its `-v` output, and the whole process);
//! 2. the tracer's `SingleScatter` and `Density` on the f32 asset, median of [`RUNS`], all cores;
//!    the ratio; and the RMSE of the tracer's 8-bit scatter image against `vdb_render`'s (a check
//!    that the two look through the same camera: they differ by trilinear vs nearest sampling);
//! 3. `Density` and `FirstHitDensity` (deterministic) of the f16, unorm8, bc4, bc7 and
//!    `--max-error 0.01` assets against the f32 asset's: RMSE and max |Δ| of `Image::value`.
//!
//! Cooks with the release `vdbcook` binary (the trace crate does not depend on the cooker):
//! `cargo build --release -p vdbcook`, then
//! `cargo bench -p vdbcook-trace --bench vs_vdb_render [-- SOURCE.vdb ...]`.
//! `VDBCOOK` overrides the binary. Assets and images are left in `target/vs-vdb-render/` (the GPU
//! bench `runtime/benches/gpu.rs` reads the f32 assets from there). Without `vdb_render`
//! (Debian `libopenvdb-tools`) step 1 is skipped with a note.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use vdbcook_asset::Asset;
use vdbcook_trace::{render, vdb_render, Camera, Image, Integrator, Mode, Output, RenderSettings};

const RUNS: usize = 3;
const SIZES: [(u32, u32); 2] = [(640, 360), (1920, 1080)];
/// The lossy assets: file label and the cook flags.
const LOSSY: [(&str, &[&str]); 5] = [
    ("f16", &["--format", "f16"]),
    ("unorm8", &["--format", "unorm8"]),
    ("bc4", &["--format", "bc4"]),
    ("bc7", &["--format", "bc7"]),
    ("maxerr0.01", &["--max-error", "0.01"]),
];

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn cook(vdbcook: &Path, src: &Path, out: &Path, flags: &[&str]) -> Asset {
    let status = Command::new(vdbcook)
        .arg("cook")
        .arg(src)
        .arg("-o")
        .arg(out)
        .args(flags)
        .stdout(std::process::Stdio::null())
        .status()
        .expect("run vdbcook");
    assert!(
        status.success(),
        "vdbcook cook {} {flags:?} failed",
        src.display()
    );
    Asset::load(out).expect("a valid asset")
}

/// Runs `vdb_render` once: (render-only seconds from its `-v` output, whole-process seconds).
fn run_vdb_render(src: &Path, out: &Path, args: &[String]) -> (f64, f64) {
    let t = Instant::now();
    let o = Command::new("vdb_render")
        .arg(src)
        .arg(out)
        .args(args)
        .output()
        .expect("run vdb_render");
    let wall = t.elapsed().as_secs_f64();
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "vdb_render failed: {text}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let render = vdb_render::render_seconds(&text).expect("vdb_render -v prints the render time");
    (render, wall)
}

/// A binary PPM (P6, maxval 255) as RGB bytes.
fn read_ppm(path: &Path) -> (u32, u32, Vec<u8>) {
    let bytes = std::fs::read(path).expect("read the PPM");
    vdb_render::read_ppm(&bytes).expect("a binary 8-bit PPM")
}

/// RMSE and max |Δ| of two equal-length sequences.
fn diff(a: impl Iterator<Item = f64>, b: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0usize);
    for (x, y) in a.zip(b) {
        let d = x - y;
        sum += d * d;
        max = max.max(d.abs());
        n += 1;
    }
    ((sum / n.max(1) as f64).sqrt(), max)
}

fn timed(asset: &Asset, camera: &Camera, s: &RenderSettings) -> (f64, Image) {
    let mut times = Vec::new();
    let mut img = None;
    for _ in 0..RUNS {
        let t = Instant::now();
        let i = render(asset, camera, s).expect("render");
        times.push(t.elapsed().as_secs_f64());
        img = Some(i);
    }
    (median(times), img.unwrap())
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let sources: Vec<PathBuf> = if args.is_empty() {
        let s = workspace().join("../shared/samples");
        vec![
            s.join("wdas-cloud/wdas_cloud_sixteenth.vdb"),
            s.join("stormscape-cloud-seq/output_cube_fluid_70_frame_0000.vdb"),
        ]
    } else {
        args.iter().map(PathBuf::from).collect()
    };
    let vdbcook = std::env::var_os("VDBCOOK")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace().join("target/release/vdbcook"));
    if !vdbcook.is_file() {
        eprintln!(
            "skipping: no {} (cargo build --release -p vdbcook, or set VDBCOOK)",
            vdbcook.display()
        );
        return;
    }
    let have_vdb_render = Command::new("vdb_render")
        .arg("-version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !have_vdb_render {
        println!("note: vdb_render not found (Debian libopenvdb-tools): its timings are skipped");
    }
    let dir = workspace().join("target/vs-vdb-render");
    std::fs::create_dir_all(&dir).expect("create target/vs-vdb-render");
    let threads = rayon::current_num_threads();
    println!(
        "tracer: {threads} threads; median of {RUNS}; output in {}",
        dir.display()
    );
    println!("vdb_render: trilinear sampling; the tracer: nearest (same camera and settings)");

    let mut timing_rows = Vec::new();
    let mut error_rows = Vec::new();
    let mut size_rows = Vec::new();
    for src in &sources {
        if !src.is_file() {
            println!("note: skipping missing source {}", src.display());
            continue;
        }
        let label = src.file_stem().unwrap().to_string_lossy().into_owned();
        let t = Instant::now();
        let f32_path = dir.join(format!("{label}_f32.vdbc"));
        let f32_asset = cook(&vdbcook, src, &f32_path, &[]);
        let lossy: Vec<(&str, Asset, u64)> = LOSSY
            .iter()
            .map(|(name, flags)| {
                let p = dir.join(format!("{label}_{name}.vdbc"));
                let a = cook(&vdbcook, src, &p, flags);
                (*name, a, std::fs::metadata(&p).unwrap().len())
            })
            .collect();
        println!(
            "{label}: cooked 6 assets in {:.1} s",
            t.elapsed().as_secs_f64()
        );
        let f32_bytes = std::fs::metadata(&f32_path).unwrap().len();
        size_rows.push(format!("| {label} | f32 | {f32_bytes} |"));
        for (name, _, bytes) in &lossy {
            size_rows.push(format!("| {label} | {name} | {bytes} |"));
        }

        for (w, h) in SIZES {
            let camera = Camera::framing(&f32_asset, 0, w as f64 / h as f64).expect("camera");
            let base = RenderSettings {
                output: Output {
                    width: w,
                    height: h,
                    frame: 0,
                },
                ..Default::default()
            };
            let scatter = RenderSettings {
                integrator: Integrator {
                    mode: Mode::SingleScatter,
                    ..base.integrator.clone()
                },
                ..base.clone()
            };
            // (2) the tracer on the f32 asset.
            let (t_scatter, img_scatter) = timed(&f32_asset, &camera, &scatter);
            let (t_density, _) = timed(&f32_asset, &camera, &base);
            // (1) vdb_render with the same camera and settings.
            let (vr, vr_wall, vs_rmse) = if have_vdb_render {
                let args = vdb_render::args(&camera, &scatter, None);
                if w == SIZES[0].0 {
                    println!("{label} {w}x{h}: vdb_render SRC OUT.ppm {}", args.join(" "));
                }
                let out = dir.join(format!("{label}_{w}x{h}_vdb_render.ppm"));
                let runs: Vec<(f64, f64)> = (0..RUNS)
                    .map(|_| run_vdb_render(src, &out, &args))
                    .collect();
                // Some `vdb_render` builds drop the `.ppm` extension when they save.
                let bare = out.with_extension("");
                if !out.is_file() && bare.is_file() {
                    std::fs::rename(&bare, &out).expect("rename the PPM");
                }
                let (pw, ph, rgb) = read_ppm(&out);
                assert_eq!((pw, ph), (w, h));
                let ours = img_scatter.to_rgba8();
                let (rmse, _) = diff(
                    rgb.iter().map(|&c| c as f64 / 255.0),
                    ours.chunks(4)
                        .flat_map(|p| p[..3].to_vec())
                        .map(|c| c as f64 / 255.0),
                );
                (
                    Some(median(runs.iter().map(|r| r.0).collect())),
                    Some(median(runs.iter().map(|r| r.1).collect())),
                    Some(rmse),
                )
            } else {
                (None, None, None)
            };
            let ms = |t: Option<f64>| t.map_or("–".into(), |t| format!("{:.0}", t * 1e3));
            let row = format!(
                "| {label} | {w}×{h} | {} | {} | {:.0} | {:.0} | {} | {} |",
                ms(vr),
                ms(vr_wall),
                t_scatter * 1e3,
                t_density * 1e3,
                vr.map_or("–".into(), |v| format!("{:.2}×", v / t_scatter)),
                vs_rmse.map_or("–".into(), |r| format!("{r:.4}")),
            );
            println!("{row}");
            timing_rows.push(row);

            // (3) image-space error of each lossy asset against the f32 asset.
            for mode in [Mode::Density, Mode::FirstHitDensity] {
                let s = RenderSettings {
                    integrator: Integrator {
                        mode,
                        ..base.integrator.clone()
                    },
                    ..base.clone()
                };
                let reference = render(&f32_asset, &camera, &s).expect("render");
                for (name, asset, _) in &lossy {
                    let img = render(asset, &camera, &s).expect("render");
                    let (rmse, max) = diff(
                        img.value.iter().map(|&v| v as f64),
                        reference.value.iter().map(|&v| v as f64),
                    );
                    // First hit: pixels that hit in one image and miss (value −1) in the other.
                    let flips = img
                        .value
                        .iter()
                        .zip(&reference.value)
                        .filter(|(a, b)| (**a < 0.0) != (**b < 0.0))
                        .count();
                    let row = format!(
                        "| {label} | {w}×{h} | {} | {name} | {rmse:.2e} | {max:.2e} | {} |",
                        mode.name(),
                        if mode == Mode::FirstHitDensity {
                            flips.to_string()
                        } else {
                            "–".into()
                        }
                    );
                    println!("{row}");
                    error_rows.push(row);
                }
            }
        }
    }

    println!("\n### Time (ms, median of {RUNS})\n");
    println!("| source | size | vdb_render render | vdb_render process | tracer scatter | tracer density | vdb_render / tracer scatter | scatter RMSE vs vdb_render (8-bit rgb) |");
    println!("|---|---|---:|---:|---:|---:|---:|---:|");
    for r in &timing_rows {
        println!("{r}");
    }
    println!("\n### Image-space error against the f32 asset (`Image::value`)\n");
    println!("| source | size | mode | asset | RMSE | max abs | hit/miss flips |");
    println!("|---|---|---|---|---:|---:|---:|");
    for r in &error_rows {
        println!("{r}");
    }
    println!("\n### Asset sizes (bytes)\n");
    println!("| source | asset | bytes |");
    println!("|---|---|---:|");
    for r in &size_rows {
        println!("{r}");
    }
}
