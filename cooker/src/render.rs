//! `vdbcook render`: draws one frame of a cooked asset (or of VDB sources, cooked in memory
//! losslessly first) to a PNG, with the CPU reference tracer (`vdbcook-trace`, any machine) or
//! the GPU runtime (`vdbcook-runtime`, the code engines link). `--json` reports the settings,
//! camera, backend and timing.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde_json::json;
use vdbcook_asset::Asset;
use vdbcook_trace::{Camera, LengthUnit, Mode, RenderSettings};

use crate::cook;
use crate::errors::CliError;
use crate::gpu::Gpu;

#[derive(clap::Args)]
pub struct Args {
    /// The cooked asset (.vdbc), or VDB sources (file, folder, frame pattern or glob), which
    /// are cooked in memory (f32, lossless) first.
    #[arg(value_name = "ASSET|VDB")]
    input: PathBuf,
    /// Output PNG (8-bit RGBA): the name must end in .png (or be a device or FIFO).
    #[arg(short, long, value_name = "OUT")]
    output: PathBuf,
    /// Frame index (0-based).
    #[arg(long, default_value_t = 0)]
    frame: usize,
    /// What pixels show.
    #[arg(long, default_value = "density",
          value_parser = ["density", "depth", "first-hit", "brick-hue", "steps", "scatter", "delta"])]
    mode: String,
    /// Renderer: cpu (the reference tracer), gpu (the wgpu runtime on the default adapter), or
    /// auto: gpu on a hardware adapter, else cpu.
    #[arg(long, default_value = "auto", value_parser = ["auto", "cpu", "gpu"])]
    backend: String,
    /// Grid to cook when the input is VDB (default: `density`, else the only float grid).
    #[arg(long)]
    grid: Option<String>,
    /// Accept gaps in the frame numbering (VDB input).
    #[arg(long)]
    allow_gaps: bool,
    /// Replace NaN and ±Inf active values with VALUE when cooking VDB input (by default they
    /// are an error).
    #[arg(long, value_name = "VALUE", allow_negative_numbers = true)]
    replace_non_finite: Option<f32>,
    #[arg(long, default_value_t = 640)]
    width: u32,
    #[arg(long, default_value_t = 360)]
    height: u32,
    /// EYE_X,EYE_Y,EYE_Z,LOOK_X,LOOK_Y,LOOK_Z,FOV_Y_DEG in world units (Y up). Default: a
    /// three-quarter view that frames the frame's stored box.
    #[arg(long, value_name = "E,E,E,L,L,L,FOV", allow_hyphen_values = true)]
    camera: Option<String>,
    /// Absorption per unit density per unit length.
    #[arg(long, default_value_t = 0.1)]
    absorb: f32,
    /// Scattering per unit density per unit length (scatter and delta modes).
    #[arg(long, default_value_t = 1.5)]
    scatter: f32,
    /// Direction toward the light and optional colour: DX,DY,DZ[,R,G,B].
    #[arg(
        long,
        default_value = "0.3,0.3,0,0.7,0.7,0.7",
        allow_hyphen_values = true
    )]
    light: String,
    /// Primary-ray step of the scatter mode (in --units).
    #[arg(long, default_value_t = 1.0)]
    step: f32,
    /// Shadow-ray step of the scatter mode (in --units).
    #[arg(long, default_value_t = 3.0)]
    shadow_step: f32,
    /// Density and transmittance cutoff (scatter), first-hit threshold (depth, first-hit,
    /// brick-hue).
    #[arg(long, default_value_t = 0.005)]
    cutoff: f32,
    /// Shadow falloff: shadow extinction at distance s is divided by 1 + gain·s.
    #[arg(long, default_value_t = 0.2)]
    gain: f32,
    /// Samples per pixel (delta).
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Random seed (delta).
    #[arg(long, default_value_t = 1)]
    seed: u32,
    /// Length unit of absorb, scatter, step, shadow-step and gain: voxel (as vdb_render) or world.
    #[arg(long, default_value = "voxel", value_parser = ["voxel", "world"])]
    units: String,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

/// An f32 as the f64 with the same shortest decimal form (0.1, not 0.10000000149011612).
fn short(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(x as f64)
}

fn other(m: impl Into<String>) -> CliError {
    CliError::Other(m.into())
}

/// Comma-separated finite numbers.
fn numbers(what: &str, s: &str) -> Result<Vec<f64>, CliError> {
    s.split(',')
        .map(|t| match t.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(other(format!("--{what}: {t:?} is not a finite number"))),
        })
        .collect()
}

/// Whether `input` names VDB sources rather than an asset.
pub fn looks_like_vdb(input: &Path) -> bool {
    let s = input.to_string_lossy();
    if input.is_dir() || s.contains('#') || s.contains('%') || s.contains('*') {
        return true;
    }
    if input
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vdb"))
    {
        return true;
    }
    // OpenVDB's magic number, 0x56444220 little-endian: only the first four bytes are read (an
    // asset is read once, by the loader).
    let mut magic = [0u8; 4];
    std::fs::File::open(input)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic))
        .map(|_| magic == [0x20, 0x42, 0x44, 0x56])
        .unwrap_or(false)
}

/// The camera from `--camera`, or the default framing of `frame`.
pub fn camera(
    spec: Option<&str>,
    asset: &Asset,
    frame: usize,
    aspect: f64,
) -> Result<Camera, CliError> {
    match spec {
        Some(c) => {
            let v = numbers("camera", c)?;
            if v.len() != 7 {
                return Err(other(format!(
                    "--camera takes 7 numbers (eye, look-at, fov), got {}",
                    v.len()
                )));
            }
            Ok(Camera {
                eye: [v[0], v[1], v[2]],
                look_at: [v[3], v[4], v[5]],
                up: [0.0, 1.0, 0.0],
                fov_y_deg: v[6],
            })
        }
        None => Camera::framing(asset, frame, aspect).map_err(|e| other(e.to_string())),
    }
}

fn settings(a: &Args) -> Result<RenderSettings, CliError> {
    let light = numbers("light", &a.light)?;
    let (dir, color) = match light.len() {
        3 => (&light[..3], [0.7f32; 3]),
        6 => (
            &light[..3],
            [light[3] as f32, light[4] as f32, light[5] as f32],
        ),
        n => return Err(other(format!("--light takes 3 or 6 numbers, got {n}"))),
    };
    Ok(RenderSettings {
        width: a.width,
        height: a.height,
        mode: Mode::parse(&a.mode).expect("clap checked"),
        frame: a.frame,
        absorb: a.absorb,
        scatter: a.scatter,
        light_dir: [dir[0] as f32, dir[1] as f32, dir[2] as f32],
        light_color: color,
        step: a.step,
        shadow_step: a.shadow_step,
        cutoff: a.cutoff,
        gain: a.gain,
        spp: a.spp,
        first_sample: 0,
        seed: a.seed,
        unit: if a.units == "world" {
            LengthUnit::World
        } else {
            LengthUnit::Voxel
        },
    })
}

/// The PNG bytes of an 8-bit RGBA image.
pub fn encode_png(width: u32, height: u32, rgba: &[u8]) -> Result<Vec<u8>, CliError> {
    let fail = |e: &dyn std::fmt::Display| other(format!("cannot encode PNG: {e}"));
    let mut bytes = Vec::new();
    let mut enc = png::Encoder::new(&mut bytes, width, height);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().map_err(|e| fail(&e))?;
    w.write_image_data(rgba).map_err(|e| fail(&e))?;
    w.finish().map_err(|e| fail(&e))?;
    Ok(bytes)
}

/// Writes an 8-bit RGBA PNG through `output::write` (atomic, never over an input).
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<(), CliError> {
    crate::output::write(path, &encode_png(width, height, rgba)?, "PNG")
}

/// `render` writes PNG only: the output name must say so (or be a device or FIFO, written
/// as PNG bytes).
fn check_output_format(out: &Path) -> Result<(), CliError> {
    let png = out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if png || crate::output::is_special(out) {
        Ok(())
    } else {
        Err(CliError::Usage(format!(
            "{}: render writes PNG only; give an output name ending in .png",
            out.display()
        )))
    }
}

pub fn run(a: &Args) -> Result<(), CliError> {
    let t0 = Instant::now();
    check_output_format(&a.output)?;
    // The output must not replace the input (an asset, or a VDB file or frame set).
    let input_str = a.input.to_string_lossy().into_owned();
    let in_frames = if looks_like_vdb(&a.input) {
        vdbcook_vdb::sequence::resolve_inputs(std::slice::from_ref(&input_str), a.allow_gaps)
            .unwrap_or_default()
    } else {
        vec![vdbcook_vdb::sequence::Frame {
            path: a.input.clone(),
            number: None,
        }]
    };
    crate::output::refuse_inputs(&a.output, &in_frames, &[input_str], "PNG")?;
    let s = settings(a)?;
    // Open the GPU first: a missing adapter is reported before any cooking.
    let gpu = match a.backend.as_str() {
        "gpu" => Some(Gpu::open().map_err(other)?),
        "auto" => Gpu::open().ok().filter(|g| !g.is_software()),
        _ => None,
    };
    let (asset, cooked_from) = if looks_like_vdb(&a.input) {
        let mut c = cook::Args::defaults(
            vec![a.input.to_string_lossy().into_owned()],
            a.output.clone(),
        );
        c.grid = a.grid.clone();
        c.allow_gaps = a.allow_gaps;
        c.replace_non_finite = a.replace_non_finite;
        let t = Instant::now();
        (cook::cook(&c)?.asset, Some(t.elapsed().as_secs_f64()))
    } else {
        (cook::load_asset(&a.input)?, None)
    };
    let at = |e: &dyn std::fmt::Display| other(format!("{}: {e}", a.input.display()));
    let camera = camera(
        a.camera.as_deref(),
        &asset,
        a.frame,
        a.width as f64 / a.height.max(1) as f64,
    )
    .map_err(|e| at(&e))?;
    let t_render = Instant::now();
    let (image, backend, adapter, gpu_ms) = match &gpu {
        Some(g) => {
            let up = g.upload(&asset).map_err(|e| at(&e))?;
            let r = g.render(&up, &camera, &s, 1).map_err(|e| at(&e))?;
            (
                r.image,
                "gpu",
                Some(g.describe()),
                r.gpu_ms.first().copied(),
            )
        }
        None => (
            vdbcook_trace::render(&asset, &camera, &s).map_err(|e| at(&e))?,
            "cpu",
            None,
            None,
        ),
    };
    let render_seconds = t_render.elapsed().as_secs_f64();
    write_png(&a.output, image.width, image.height, &image.to_rgba8())?;
    let seconds = t0.elapsed().as_secs_f64();
    if a.json {
        let doc = json!({
            "output": a.output.display().to_string(),
            "asset": a.input.display().to_string(),
            "cooked_in_memory_seconds": cooked_from,
            "mode": s.mode.name(),
            "frame": s.frame,
            "width": s.width,
            "height": s.height,
            "backend": backend,
            "adapter": adapter,
            "seconds": seconds,
            "render_seconds": render_seconds,
            "gpu_ms": gpu_ms,
            "threads": rayon::current_num_threads(),
            "camera": {
                "eye": camera.eye, "look_at": camera.look_at, "up": camera.up,
                "fov_y_deg": camera.fov_y_deg,
            },
            "settings": {
                "absorb": short(s.absorb), "scatter": short(s.scatter),
                "light_dir": s.light_dir.map(short), "light_color": s.light_color.map(short),
                "step": short(s.step), "shadow_step": short(s.shadow_step),
                "cutoff": short(s.cutoff), "gain": short(s.gain), "spp": s.spp, "seed": s.seed,
                "units": a.units,
            },
        });
        println!("{}", serde_json::to_string_pretty(&doc).expect("json"));
    } else {
        let on = adapter.map(|d| format!(" on {d}")).unwrap_or_default();
        println!(
            "wrote {} ({}x{}, {}, frame {}, {backend} backend{on}) in {:.3} s (render {:.3} s)",
            a.output.display(),
            s.width,
            s.height,
            s.mode.name(),
            s.frame,
            seconds,
            render_seconds
        );
    }
    Ok(())
}
