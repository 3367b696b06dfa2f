//! `vdbcook render`: draws one frame of a cooked asset (or of VDB sources, cooked in memory
//! losslessly first) to a PNG or a linear PFM, with the CPU reference tracer (`vdbcook-trace`,
//! any machine) or the GPU runtime (`vdbcook-runtime`, the code engines link), optionally
//! composited over a scene: `--background PLATE.png` (the scene's colours, sRGB) and `--depth
//! DEPTH.pfm` (its depth along the view axis, which cuts the density march as an engine's depth
//! buffer does; on the GPU through the engine drawer, `VolumeDrawer`). `--json` reports the
//! settings, the camera (with view and projection matrices that reproduce it), backend and
//! timing.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde_json::json;
use vdbcook_asset::Asset;
use vdbcook_trace::srgb_to_linear;
use vdbcook_trace::{Camera, Display, Image, March, Mode, Output, RenderSettings, Scratch, Tracer};

use crate::errors::CliError;
use crate::gpu::Gpu;

#[derive(clap::Args)]
pub struct Args {
    /// The cooked asset (.vdbc), or VDB sources (file, folder, frame pattern or glob), which
    /// are cooked in memory (f32, lossless) first.
    #[arg(value_name = "ASSET|VDB")]
    input: PathBuf,
    /// Output: .png (8-bit sRGB RGBA through --exposure and --tonemap), .pfm (linear RGB
    /// floats, `PF`) or .exr (OpenEXR linear RGBA, premultiplied, 32-bit float; --exr-half:
    /// 16-bit); a device or FIFO gets PNG.
    #[arg(short, long, value_name = "OUT")]
    output: PathBuf,
    /// The scene's colours to composite over (8-bit sRGB PNG of the output's size): the output
    /// is `L + T·plate` in linear light, sRGB-encoded in a PNG.
    #[arg(long, value_name = "PLATE.png")]
    background: Option<PathBuf>,
    /// The scene's depth (PFM greyscale `Pf`, the output's size, rows bottom to top): distance
    /// along the view axis in world units; non-finite or ≤ 0 = no surface. Cuts each ray at
    /// depth / cos(angle to the view axis). Density mode only.
    #[arg(long, value_name = "DEPTH.pfm")]
    depth: Option<PathBuf>,
    /// Frame index (0-based).
    #[arg(long, default_value_t = 0)]
    frame: usize,
    /// What pixels show.
    #[arg(long, default_value = "density",
          value_parser = ["density", "depth", "first-hit", "brick-hue", "steps", "scatter", "delta",
                          "reference", "lit"])]
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
    /// EYE_X,EYE_Y,EYE_Z,LOOK_X,LOOK_Y,LOOK_Z,FOV_Y_DEG in world units (up: --up). Default: a
    /// three-quarter view that frames the frame's stored box.
    #[arg(long, value_name = "E,E,E,L,L,L,FOV", allow_hyphen_values = true)]
    camera: Option<String>,
    #[command(flatten)]
    pub look: crate::look::LookArgs,
    /// EXR output in 16-bit half floats instead of 32-bit.
    #[arg(long)]
    exr_half: bool,
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

use crate::look::numbers;

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
    up: [f64; 3],
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
                up,
                fov_y_deg: v[6],
            })
        }
        None => Camera::framing_up(asset, frame, aspect, up).map_err(|e| other(e.to_string())),
    }
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

/// What `render` writes, from the output's name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum OutFormat {
    Png,
    Pfm,
    Exr,
}

/// `render` writes PNG or PFM: the output name must say which (a device or FIFO gets PNG).
fn check_output_format(out: &Path) -> Result<OutFormat, CliError> {
    let ext = |x: &str| out.extension().is_some_and(|e| e.eq_ignore_ascii_case(x));
    if ext("png") || (!ext("pfm") && crate::output::is_special(out)) {
        Ok(OutFormat::Png)
    } else if ext("pfm") {
        Ok(OutFormat::Pfm)
    } else if ext("exr") {
        Ok(OutFormat::Exr)
    } else {
        Err(CliError::Usage(format!(
            "{}: render writes PNG (8-bit sRGB), PFM (linear float RGB) or EXR (linear RGBA), \
             not {}; give an output name ending in .png, .pfm or .exr",
            out.display(),
            out.extension()
                .map(|e| format!(".{}", e.to_string_lossy()))
                .unwrap_or_else(|| "a name without an extension".into())
        )))
    }
}

/// A background plate: linear RGB and alpha per pixel, row 0 at the top.
pub struct Plate {
    pub width: u32,
    pub height: u32,
    /// `width × height × 4`: linear RGB (decoded from sRGB) and alpha.
    pub rgba: Vec<f32>,
}

/// Reads a PNG plate (any colour type and depth, normalized to 8 bits, decoded from sRGB).
pub fn read_plate(path: &Path) -> Result<Plate, CliError> {
    let at = |m: String| other(format!("{}: {m}", path.display()));
    let file = std::fs::File::open(path).map_err(|e| at(format!("cannot read the plate: {e}")))?;
    let mut dec = png::Decoder::new(std::io::BufReader::new(file));
    dec.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = dec
        .read_info()
        .map_err(|e| at(format!("not a readable PNG plate: {e}")))?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| at(format!("not a readable PNG plate: {e}")))?;
    let (w, h) = (info.width, info.height);
    let n = (w * h) as usize;
    let ch = match info.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        c => {
            return Err(at(format!(
                "PNG colour type {c:?} not supported as a plate"
            )))
        }
    };
    let data = &buf[..info.buffer_size()];
    let mut rgba = Vec::with_capacity(4 * n);
    for p in data.chunks_exact(ch).take(n) {
        let (rgb, a) = match ch {
            1 => ([p[0]; 3], 255),
            2 => ([p[0]; 3], p[1]),
            3 => ([p[0], p[1], p[2]], 255),
            _ => ([p[0], p[1], p[2]], p[3]),
        };
        rgba.extend(rgb.map(srgb_to_linear));
        rgba.push(a as f32 / 255.0);
    }
    Ok(Plate {
        width: w,
        height: h,
        rgba,
    })
}

/// The next whitespace-separated token of a PNM-style header at `*pos`, and the position after
/// it (on the single whitespace byte that ends it).
fn pfm_token<'b>(b: &'b [u8], pos: &mut usize) -> Option<&'b str> {
    while *pos < b.len() && b[*pos].is_ascii_whitespace() {
        *pos += 1;
    }
    let start = *pos;
    while *pos < b.len() && !b[*pos].is_ascii_whitespace() && *pos - start < 32 {
        *pos += 1;
    }
    (*pos > start && *pos < b.len())
        .then(|| std::str::from_utf8(&b[start..*pos]).ok())
        .flatten()
}

/// A PFM image: width, height, channels (1 for `Pf`, 3 for `PF`) and the floats, rows top to
/// bottom (flipped from the file's bottom-to-top order).
pub fn parse_pfm(b: &[u8]) -> Result<(u32, u32, usize, Vec<f32>), String> {
    let mut pos = 0;
    let magic = pfm_token(b, &mut pos).ok_or("not a PFM (empty or no header)")?;
    let ch = match magic {
        "Pf" => 1,
        "PF" => 3,
        m => return Err(format!("not a PFM: magic {m:?} (expected Pf or PF)")),
    };
    let dim = |t: Option<&str>| {
        t.and_then(|t| t.parse::<u32>().ok())
            .filter(|&v| v > 0 && v <= vdbcook_trace::MAX_SIDE)
    };
    let w = dim(pfm_token(b, &mut pos)).ok_or("PFM width missing or out of range")?;
    let h = dim(pfm_token(b, &mut pos)).ok_or("PFM height missing or out of range")?;
    let scale: f32 = pfm_token(b, &mut pos)
        .and_then(|t| t.parse().ok())
        .filter(|s: &f32| s.is_finite() && *s != 0.0)
        .ok_or("PFM scale missing or not a non-zero number")?;
    pos += 1; // the single whitespace byte after the scale
    let data = &b[pos..];
    let want = w as usize * h as usize * ch * 4;
    if data.len() != want {
        return Err(format!(
            "PFM {w}x{h} ({ch} channel(s)) needs {want} bytes of data, the file has {}",
            data.len()
        ));
    }
    let row = w as usize * ch;
    let mut out = vec![0.0f32; row * h as usize];
    for (k, c) in data.chunks_exact(4).enumerate() {
        let bytes = [c[0], c[1], c[2], c[3]];
        let v = if scale < 0.0 {
            f32::from_le_bytes(bytes)
        } else {
            f32::from_be_bytes(bytes)
        };
        let (y, x) = (k / row, k % row);
        out[(h as usize - 1 - y) * row + x] = v;
    }
    Ok((w, h, ch, out))
}

/// The bytes of a colour PFM (`PF`, little-endian) of `rgb` (3 floats per pixel, row 0 at the
/// top; written bottom to top as PFM stores rows).
pub fn encode_pfm(width: u32, height: u32, rgb: &[f32]) -> Vec<u8> {
    let mut out = format!("PF\n{width} {height}\n-1.0\n").into_bytes();
    let row = 3 * width as usize;
    for y in (0..height as usize).rev() {
        for v in &rgb[y * row..(y + 1) * row] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

/// Reads a depth PFM (`Pf`): per pixel the view-axis distance, row 0 at the top.
fn read_depth(path: &Path) -> Result<(u32, u32, Vec<f32>), CliError> {
    let at = |m: String| other(format!("{}: {m}", path.display()));
    let bytes = std::fs::read(path).map_err(|e| at(format!("cannot read the depth: {e}")))?;
    let (w, h, ch, v) = parse_pfm(&bytes).map_err(at)?;
    if ch != 1 {
        return Err(at(
            "a colour PFM (PF); the depth is one float per pixel (greyscale Pf)".into(),
        ));
    }
    Ok((w, h, v))
}

/// The world distance along a ray at `cos` to the view axis to a surface at view-axis depth
/// `d`: `d / cos`, or `∞` where there is no surface (non-finite or ≤ 0).
fn depth_to_t(d: f32, cos: f64) -> f64 {
    if d.is_finite() && d > 0.0 && cos > 0.0 {
        d as f64 / cos
    } else {
        f64::INFINITY
    }
}

/// The density mode on the CPU with every ray cut at the scene depth (`Tracer::optical_depth`):
/// the same pixels as `vdbcook_trace::render` in density mode where the depth does not cut.
fn render_clipped(
    asset: &Asset,
    camera: &Camera,
    s: &RenderSettings,
    depth: &[f32],
) -> Result<Image, vdbcook_trace::TraceError> {
    use rayon::prelude::*;
    let tracer = Tracer::new(asset, camera, s)?;
    let (w, h) = (s.output.width, s.output.height);
    let b = camera.basis(w, h)?;
    let mut rgba = vec![0.0f32; w as usize * h as usize * 4];
    let mut value = vec![0.0f32; w as usize * h as usize];
    rgba.par_chunks_mut(w as usize * 4)
        .zip(value.par_chunks_mut(w as usize))
        .enumerate()
        .for_each_init(Scratch::default, |scratch, (j, (row, vrow))| {
            for i in 0..w as usize {
                let x = 2.0 * (i as f64 + 0.5) / w as f64 - 1.0;
                let y = 1.0 - 2.0 * (j as f64 + 0.5) / h as f64;
                let d = [0, 1, 2].map(|a| b.forward[a] + x * b.right[a] + y * b.up[a]);
                let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                let dir = d.map(|c| c / len);
                let cos = (0..3).map(|a| dir[a] * b.forward[a]).sum::<f64>();
                let t_max = depth_to_t(depth[j * w as usize + i], cos);
                if s.integrator.mode == Mode::Lit {
                    let px = tracer.trace_until(
                        camera.eye,
                        dir,
                        t_max,
                        (j * w as usize + i) as u32,
                        scratch,
                    );
                    row[4 * i..4 * i + 4].copy_from_slice(&px.rgba);
                    vrow[i] = px.value;
                    continue;
                }
                let tau = tracer.optical_depth(camera.eye, dir, t_max, scratch);
                let t = (-(s.medium.absorb as f64) * tau).exp() as f32;
                let g = 1.0 - t;
                let e = tracer.emission_until(camera.eye, dir, t_max, scratch);
                let e = e.map(|c| c as f32);
                row[4 * i..4 * i + 4].copy_from_slice(&[g + e[0], g + e[1], g + e[2], 1.0]);
                vrow[i] = t;
            }
        });
    Ok(Image {
        width: w,
        height: h,
        rgba,
        value,
    })
}

/// `out = L + T·plate` per pixel, the plate's alpha kept: `L` is the image's colour, `T` its
/// transmittance (density: the raw value; steps: 0; other modes: 1 − alpha).
fn composite_over(img: &mut Image, plate: &Plate, mode: Mode) {
    for (k, px) in img.rgba.chunks_exact_mut(4).enumerate() {
        let t = match mode {
            Mode::Density => img.value[k],
            Mode::Steps => 0.0,
            _ => 1.0 - px[3],
        };
        let p = &plate.rgba[4 * k..4 * k + 4];
        for c in 0..3 {
            px[c] += t * p[c];
        }
        px[3] = p[3];
    }
}

/// A 4×4 matrix, row-major (column vectors).
pub type Mat4Rows = [[f64; 4]; 4];

/// The camera as matrices another renderer can use: the view matrix (world → view, right-handed,
/// the camera looking down −Z) and a reversed-Z infinite perspective projection (wgpu's depth
/// range: NDC z = near / view-axis distance), both row-major, for column vectors.
pub fn camera_matrices(
    camera: &Camera,
    width: u32,
    height: u32,
    near: f64,
) -> Result<(Mat4Rows, Mat4Rows), vdbcook_trace::TraceError> {
    let b = camera.basis(width, height)?;
    let unit = |v: [f64; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|c| c / l)
    };
    let (r, u, f) = (unit(b.right), unit(b.up), b.forward);
    let e = camera.eye;
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let view = [
        [r[0], r[1], r[2], -dot(r, e)],
        [u[0], u[1], u[2], -dot(u, e)],
        [-f[0], -f[1], -f[2], dot(f, e)],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let fy = 1.0 / (camera.fov_y_deg.to_radians() * 0.5).tan();
    let aspect = width as f64 / height as f64;
    let proj = [
        [fy / aspect, 0.0, 0.0, 0.0],
        [0.0, fy, 0.0, 0.0],
        [0.0, 0.0, 0.0, near],
        [0.0, 0.0, -1.0, 0.0],
    ];
    Ok((view, proj))
}

/// The near plane of the reported projection (and of the GPU composite's depth buffer): a
/// thousandth of the eye's distance to the look-at point.
fn near_plane(camera: &Camera) -> f64 {
    let d = [0, 1, 2].map(|i| camera.look_at[i] - camera.eye[i]);
    1e-3 * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// The asset to draw: `input` loaded, or, when it names VDB sources, cooked in memory (f32,
/// lossless; `grid`, `allow_gaps` and `replace_non_finite` as `cook`'s options; the emission's
/// grid, or a fire's grids, as `look` asks) with the seconds that took. Shared by `render`,
/// `view` and `bench`.
pub fn load_input(
    input: &Path,
    grid: Option<String>,
    allow_gaps: bool,
    replace_non_finite: Option<f32>,
    look: &crate::look::LookArgs,
) -> Result<(Asset, Option<f64>), CliError> {
    let extra_grid = look.emission_grid.as_deref();
    let fire_grids = look.emission != "off";
    if looks_like_vdb(input) {
        let t = Instant::now();
        let frames = vdbcook_cook::frames::resolve_frames(
            &[input.to_string_lossy().into_owned()],
            allow_gaps,
            None,
        )?;
        // With emission on and no grid named, a fire's grids (density, temperature, flame) as
        // `cook --grids auto` picks them, when the first frame holds two or more.
        let fire = fire_grids
            && grid.is_none()
            && extra_grid.is_none()
            && frames.first().is_some_and(|f| {
                vdbcook_vdb::VdbFile::open(&f.path)
                    .map(|file| vdbcook_cook::grid_pick::suggest(&file).grids.len() >= 2)
                    .unwrap_or(false)
            });
        let opts = vdbcook_cook::CookOptions {
            grids: match (extra_grid, grid) {
                _ if fire => vdbcook_cook::Grids::Auto,
                // A second grid (emission): a two-channel cook, the rendered grid first.
                (Some(e), g) if g.as_deref() != Some(e) => vdbcook_cook::Grids::Several(vec![
                    g.unwrap_or_else(|| "density".into()),
                    e.to_string(),
                ]),
                (_, Some(g)) => vdbcook_cook::Grids::One(g),
                (_, None) => vdbcook_cook::Grids::Default,
            },
            allow_gaps,
            replace_non_finite,
            ..Default::default()
        };
        let cx = vdbcook_cook::Context::quiet();
        Ok((
            vdbcook_cook::cook(&opts, frames, &cx)?.asset,
            Some(t.elapsed().as_secs_f64()),
        ))
    } else {
        Ok((crate::cook::load_asset(input)?, None))
    }
}

/// Whether a mode's pixels are radiance (through the colour pipeline) rather than false colours.
pub fn is_radiance(mode: Mode) -> bool {
    matches!(
        mode,
        Mode::Density | Mode::SingleScatter | Mode::DeltaTracking | Mode::Reference | Mode::Lit
    )
}

/// Whether a mode is lit (the sky is its fill light and its default background).
pub fn is_shaded(mode: Mode) -> bool {
    matches!(
        mode,
        Mode::SingleScatter | Mode::DeltaTracking | Mode::Reference | Mode::Lit
    )
}

/// Linear RGBA, premultiplied: the image's radiance and its opacity (the density mode's is
/// `1 − T`; over a plate or the sky, the alpha written).
fn linear_rgba(image: &Image, mode: Mode, transparent: bool) -> Vec<[f32; 4]> {
    image
        .rgba
        .chunks_exact(4)
        .zip(&image.value)
        .map(|(p, &t)| {
            let alpha = if transparent && mode == Mode::Density {
                1.0 - t
            } else {
                p[3]
            };
            [p[0], p[1], p[2], alpha.clamp(0.0, 1.0)]
        })
        .collect()
}

/// 8-bit sRGB RGBA through the colour pipeline (`Display`); `straight`: colour divided by the
/// alpha first (PNG's alpha is straight, the image's radiance premultiplied).
pub fn display_rgba8(image: &Image, mode: Mode, display: Display, straight: bool) -> Vec<u8> {
    linear_rgba(image, mode, straight)
        .into_iter()
        .flat_map(|[r, g, b, alpha]| {
            let k = if straight && alpha > 0.0 {
                1.0 / alpha
            } else {
                1.0
            };
            let [r, g, b] = display.encode8([r * k, g * k, b * k]);
            [r, g, b, (alpha * 255.0).round() as u8]
        })
        .collect()
}

/// OpenEXR bytes of linear RGBA (premultiplied, scene-referred; half or 32-bit float samples,
/// ZIP-compressed), through the `exr` crate.
pub fn encode_exr(
    width: u32,
    height: u32,
    rgba: &[[f32; 4]],
    half: bool,
) -> Result<Vec<u8>, CliError> {
    use exr::prelude::*;
    let (w, h) = (width as usize, height as usize);
    let at = |x: usize, y: usize| rgba[y * w + x];
    let mut out = std::io::Cursor::new(Vec::new());
    let fail = |e: exr::error::Error| other(format!("cannot encode EXR: {e}"));
    let attrs = LayerAttributes::named("rgba");
    if half {
        let pixels = SpecificChannels::rgba(|Vec2(x, y)| {
            let p = at(x, y);
            (
                f16::from_f32(p[0]),
                f16::from_f32(p[1]),
                f16::from_f32(p[2]),
                f16::from_f32(p[3]),
            )
        });
        Image::from_layer(Layer::new((w, h), attrs, Encoding::SMALL_LOSSLESS, pixels))
            .write()
            .to_buffered(&mut out)
            .map_err(fail)?;
    } else {
        let pixels = SpecificChannels::rgba(|Vec2(x, y)| {
            let p = at(x, y);
            (p[0], p[1], p[2], p[3])
        });
        Image::from_layer(Layer::new((w, h), attrs, Encoding::SMALL_LOSSLESS, pixels))
            .write()
            .to_buffered(&mut out)
            .map_err(fail)?;
    }
    Ok(out.into_inner())
}

/// Refuses grids the renderers would draw as something they are not: a level set's signed
/// distance marched as a fog is one flat colour (surfaces are not drawn yet). The diagnostic
/// modes that show the stored values (brick-hue, steps) still may.
pub fn refuse_unshowable(asset: &Asset, input: &Path, mode: Mode) -> Result<(), CliError> {
    let class = asset.header.source.grid_class.as_str();
    let marches = !matches!(mode, Mode::BrickHue | Mode::Steps);
    if marches && !class.is_empty() && class != "fog volume" {
        return Err(CliError::Usage(format!(
            "{}: the grid '{}' is a {class}, and vdbcook draws fog volumes only: marched as a \
             fog, its {} would show as one flat colour. Convert it to a fog volume first \
             (OpenVDB's levelSetToFogVolume, or `vdb_tool -i IN.vdb -l2f -o OUT.vdb`), or look \
             at its bricks with --mode brick-hue",
            input.display(),
            asset.header.grid_name,
            if class == "level set" {
                "signed distance"
            } else {
                "values"
            }
        )));
    }
    Ok(())
}

pub fn run(a: &Args) -> Result<(), CliError> {
    let t0 = Instant::now();
    let format = check_output_format(&a.output)?;
    let what = match format {
        OutFormat::Png => "PNG",
        OutFormat::Pfm => "PFM",
        OutFormat::Exr => "EXR",
    };
    crate::output::check_writable(&a.output, what)?;
    // The output must not replace the input (an asset, or a VDB file or frame set), the plate
    // or the depth.
    let input_str = a.input.to_string_lossy().into_owned();
    let mut in_frames = if looks_like_vdb(&a.input) {
        vdbcook_vdb::sequence::resolve_inputs(std::slice::from_ref(&input_str), a.allow_gaps)
            .unwrap_or_default()
    } else {
        vec![vdbcook_vdb::sequence::Frame {
            path: a.input.clone(),
            number: None,
        }]
    };
    for p in [&a.background, &a.depth].into_iter().flatten() {
        in_frames.push(vdbcook_vdb::sequence::Frame {
            path: p.clone(),
            number: None,
        });
    }
    crate::output::refuse_inputs(&a.output, &in_frames, &[input_str], what)?;
    let mode = Mode::parse(&a.mode).expect("clap checked");
    let s = crate::look::settings(
        &a.look,
        Output {
            width: a.width,
            height: a.height,
            frame: a.frame,
        },
        mode,
    )?;
    a.look
        .display(a.background.is_some())
        .validate()
        .map_err(CliError::Usage)?;
    if a.background.is_some() && (a.look.exposure != 0.0 || a.look.transparent) {
        return Err(CliError::Usage(format!(
            "{} applies to the volume alone, and over a --background plate the image is the \
             composite (the plate is display-referred and comes back as it is): render without \
             the plate (--transparent, EXR) and composite it yourself",
            if a.look.transparent {
                "--transparent"
            } else {
                "--exposure"
            }
        )));
    }
    if a.depth.is_some() && !matches!(s.integrator.mode, Mode::Density | Mode::Lit) {
        return Err(CliError::Usage(format!(
            "--depth cuts the density and lit modes only (the other modes do not stop at a \
             depth yet), not --mode {}",
            s.integrator.mode.name()
        )));
    }
    // The scene (plate, depth) is read and checked before any cooking or rendering.
    let size_check = |path: &Path, what: &str, w: u32, h: u32| {
        if (w, h) != (s.output.width, s.output.height) {
            Err(other(format!(
                "{}: the {what} is {w}x{h}, the output {}x{} (--width, --height); they must match",
                path.display(),
                s.output.width,
                s.output.height
            )))
        } else {
            Ok(())
        }
    };
    let plate = match &a.background {
        Some(p) => {
            let plate = read_plate(p)?;
            size_check(p, "background", plate.width, plate.height)?;
            Some(plate)
        }
        None => None,
    };
    let depth = match &a.depth {
        Some(p) => {
            let (w, h, d) = read_depth(p)?;
            size_check(p, "depth", w, h)?;
            Some(d)
        }
        None => None,
    };
    if a.backend == "gpu" && s.integrator.mode == Mode::Reference {
        return Err(CliError::Usage(
            "--mode reference is the CPU path tracer: use --backend cpu (or auto)".into(),
        ));
    }
    // Open the GPU first: a missing adapter is reported before any cooking.
    let gpu = match a.backend.as_str() {
        "gpu" => Some(Gpu::open().map_err(other)?),
        // The reference path tracer is CPU only: `auto` takes the CPU for it.
        "auto" if s.integrator.mode == Mode::Reference => None,
        "auto" => Gpu::open().ok().filter(|g| !g.is_software()),
        _ => None,
    };
    let (asset, cooked_from) = load_input(
        &a.input,
        a.grid.clone(),
        a.allow_gaps,
        a.replace_non_finite,
        &a.look,
    )?;
    let at = |e: &dyn std::fmt::Display| other(format!("{}: {e}", a.input.display()));
    refuse_unshowable(&asset, &a.input, mode)?;
    let mut s = s;
    // Over a scene (a plate or a depth) the lit mode draws as the engine drawer does, which
    // steps (it does not walk the tree): `--march auto` steps there on both backends, so that
    // the two draw the same picture.
    if s.integrator.mode == Mode::Lit
        && s.integrator.march == March::Auto
        && (a.background.is_some() || a.depth.is_some())
    {
        s.integrator.march = March::Steps;
    }
    let camera = camera(
        a.camera.as_deref(),
        &asset,
        a.frame,
        a.width as f64 / a.height.max(1) as f64,
        a.look.up_axis(&asset),
    )
    .map_err(|e| at(&e))?;
    let resolved = crate::look::resolve(&a.look, &mut s, &asset, &camera)?;
    let s = s;
    let near = near_plane(&camera);
    let (view_m, proj_m) =
        camera_matrices(&camera, s.output.width, s.output.height, near).map_err(|e| at(&e))?;
    #[cfg(feature = "gpu")]
    let scene = plate.is_some() || depth.is_some();
    let t_render = Instant::now();
    // `composited`: whether the plate is already under the image (the GPU drawer does it).
    let (mut image, backend, adapter, gpu_ms, composited) = match &gpu {
        #[cfg(feature = "gpu")]
        // The drawer composites density or lit over a plate on the GPU, emission of any
        // channel included. Lit with a depth and no plate needs its transmittance as alpha,
        // which the drawer's blend keeps from the scene: the CPU's cut march draws it.
        Some(g)
            if scene
                && (s.integrator.mode == Mode::Density
                    || (s.integrator.mode == Mode::Lit && plate.is_some())) =>
        {
            s.validate(asset.frame_count()).map_err(|e| at(&e))?;
            let (image, gpu_ms) = drawer::composite(
                g,
                &asset,
                &s,
                view_m,
                proj_m,
                near,
                plate.as_ref(),
                depth.as_deref(),
            )
            .map_err(|e| at(&e))?;
            (image, "gpu", Some(g.describe()), gpu_ms, true)
        }
        Some(_) if s.integrator.mode == Mode::Lit && depth.is_some() => {
            let image = render_clipped(&asset, &camera, &s, depth.as_deref().unwrap_or_default())
                .map_err(|e| at(&e))?;
            (image, "cpu", None, None, false)
        }
        Some(g) => {
            let up = g
                .upload_for(&asset, s.medium.emission.is_some())
                .map_err(|e| at(&e))?;
            let r = g.render(&up, &camera, &s, 1).map_err(|e| at(&e))?;
            (
                r.image,
                "gpu",
                Some(g.describe()),
                r.gpu_ms.first().copied(),
                false,
            )
        }
        None => {
            let image = match &depth {
                Some(d) => render_clipped(&asset, &camera, &s, d),
                None => vdbcook_trace::render(&asset, &camera, &s),
            }
            .map_err(|e| at(&e))?;
            (image, "cpu", None, None, false)
        }
    };
    if let (Some(p), false) = (&plate, composited) {
        composite_over(&mut image, p, s.integrator.mode);
    }
    // The sky behind the shaded modes' volume (a plate replaces it; --transparent leaves none).
    let sky_behind = plate.is_none() && !a.look.transparent && is_shaded(mode);
    if sky_behind {
        let sky = s.lighting.sky;
        for px in image.rgba.chunks_exact_mut(4) {
            let t = 1.0 - px[3];
            for c in 0..3 {
                px[c] += t * sky[c];
            }
            px[3] = 1.0;
        }
    }
    let render_seconds = t_render.elapsed().as_secs_f64();
    let display = a.look.display(plate.is_some());
    match format {
        OutFormat::Pfm => {
            let rgb: Vec<f32> = image
                .rgba
                .chunks_exact(4)
                .flat_map(|p| [p[0], p[1], p[2]])
                .collect();
            crate::output::write(
                &a.output,
                &encode_pfm(s.output.width, s.output.height, &rgb),
                "PFM",
            )?;
        }
        OutFormat::Exr => {
            let rgba = linear_rgba(&image, mode, a.look.transparent);
            crate::output::write(
                &a.output,
                &encode_exr(image.width, image.height, &rgba, a.exr_half)?,
                "EXR",
            )?;
        }
        // Radiance through the colour pipeline; over a plate (decoded to linear light) a
        // diagnostic mode's image is sRGB-encoded back with no tone map, so that the plate comes
        // back as it was.
        OutFormat::Png if is_radiance(mode) || plate.is_some() => {
            let display = if is_radiance(mode) {
                display
            } else {
                Display {
                    exposure_ev: 0.0,
                    tonemap: vdbcook_trace::Tonemap::None,
                }
            };
            let rgba = display_rgba8(&image, mode, display, a.look.transparent);
            write_png(&a.output, image.width, image.height, &rgba)?;
        }
        // Alone, the diagnostic modes' false colours are display values already.
        OutFormat::Png => write_png(&a.output, image.width, image.height, &image.to_rgba8())?,
    }
    let seconds = t0.elapsed().as_secs_f64();
    if a.json {
        let path = |p: &Option<PathBuf>| p.as_ref().map(|p| p.display().to_string());
        // The emission used and how it was chosen (one json! per object keeps the macro's
        // recursion shallow).
        let emission_json = s.medium.emission.map(|e| {
            json!({
                "channel": asset.header.channel_name(e.channel),
                "range": e.range.map(short),
                "range_kelvin": e.kelvin.map(short),
                "intensity": short(e.intensity),
                "convention": resolved.convention.as_ref().map_or("given", |c| c.name),
                "why": resolved.convention.as_ref().map(|c| c.why.clone()),
            })
        });
        let look = json!({
            "exposure_ev": short(display.exposure_ev),
            "tonemap": display.tonemap.name(),
            "light_auto": resolved.light_auto,
            "filter_auto": resolved.filter_auto,
            "up": resolved.up,
            "background_sky": sky_behind,
            "source_creator": asset.header.source.creator,
        });
        let mut doc = json!({
            "output": a.output.display().to_string(),
            "output_format": what.to_ascii_lowercase(),
            "asset": a.input.display().to_string(),
            "background": path(&a.background),
            "depth": path(&a.depth),
            "cooked_in_memory_seconds": cooked_from,
            "mode": s.integrator.mode.name(),
            "frame": s.output.frame,
            "width": s.output.width,
            "height": s.output.height,
            "backend": backend,
            // Which path drew: the CPU tracer, the runtime's full-screen tracer (`Renderer`)
            // or the engine drawer (`VolumeDrawer`, over a plate or a depth).
            "runtime_path": if composited { "drawer" } else if backend == "gpu" { "tracer" } else { "cpu" },
            "adapter": adapter,
            "seconds": seconds,
            "render_seconds": render_seconds,
            "gpu_ms": gpu_ms,
            "threads": rayon::current_num_threads(),
            "camera": {
                "eye": camera.eye, "look_at": camera.look_at, "up": camera.up,
                "fov_y_deg": camera.fov_y_deg,
                "view_matrix": view_m,
                "projection_matrix": proj_m,
                "near": near,
                "projection": "perspective, right-handed, reversed Z, infinite far plane, \
                               NDC z in [0, 1] = near / view-axis distance; row-major, column vectors",
            },
            "settings": {
                "absorb": short(s.medium.absorb), "scatter": short(s.medium.scatter),
                "light_dir": s.lighting.light_dir.map(short), "light_color": s.lighting.light_color.map(short),
                "step": short(s.integrator.step), "shadow_step": short(s.integrator.shadow_step),
                "cutoff": short(s.integrator.cutoff), "gain": short(s.integrator.gain), "spp": s.integrator.spp, "seed": s.integrator.seed,
                "units": a.look.units,
                "sky": s.lighting.sky.map(short), "phase_g": s.medium.phase_g.map(short),
                "phase_w": short(s.medium.phase_w), "bounces": s.integrator.bounces,
                "emission": emission_json,
            },
        });
        // The march the lit mode took (`March::resolve`; the engine drawer, which composites lit
        // over a plate on the GPU, always steps).
        let march_used = (s.integrator.mode == Mode::Lit).then(|| {
            if composited {
                "steps"
            } else {
                vdbcook_trace::March::resolve(&s, asset.frame_range(s.output.frame, 0)[1]).name()
            }
        });
        // The lit mode's keys (one json! per object keeps the macro's recursion shallow).
        let lit = json!({
            "light_res": s.lighting.light_res, "ms_octaves": s.lighting.ms_octaves, "ms": s.lighting.ms.map(short),
            "ms_sky": short(s.lighting.ms_sky), "ms_model": s.lighting.ms_model.name(), "filter": s.integrator.filter.name(),
            "march": a.look.march, "march_used": march_used, "sun_near": short(s.lighting.sun_near),
            "near_scatter": short(s.lighting.near_scatter),
            "ms_gather": s.lighting.ms_gather,
            "primary_lod": s.integrator.primary_lod,
        });
        if let (Some(settings), Some(lit), Some(look)) = (
            doc["settings"].as_object_mut(),
            lit.as_object(),
            look.as_object(),
        ) {
            settings.extend(lit.clone());
            settings.extend(look.clone());
        }
        println!("{}", serde_json::to_string_pretty(&doc).expect("json"));
    } else {
        let on = adapter.map(|d| format!(" on {d}")).unwrap_or_default();
        let over = match (&a.background, &a.depth) {
            (None, None) => String::new(),
            (b, d) => format!(
                ", over{}{}",
                b.as_ref()
                    .map(|p| format!(" {}", p.display()))
                    .unwrap_or_default(),
                d.as_ref()
                    .map(|p| format!(" depth {}", p.display()))
                    .unwrap_or_default()
            ),
        };
        println!(
            "wrote {} ({}x{}, {}, frame {}, {backend} backend{on}{over}) in {:.3} s (render {:.3} s)",
            a.output.display(),
            s.output.width,
            s.output.height,
            s.integrator.mode.name(),
            s.output.frame,
            seconds,
            render_seconds
        );
    }
    Ok(())
}

/// The scene for the GPU composite: linear RGBA per pixel (black, opaque without a plate) and
/// the NDC depth of the reversed-Z projection (0 = no surface).
#[cfg(feature = "gpu")]
mod drawer {
    use vdbcook_runtime::glam::Mat4;
    use vdbcook_runtime::{DrawTarget, GpuTimer, GpuVolume, Instance, View, VolumeDrawer};

    use super::*;

    /// Writes the scene into the colour target and the depth buffer: a full-screen triangle
    /// that copies the plate (linear floats) and writes `frag_depth`.
    const SCENE_WGSL: &str = r#"
@group(0) @binding(0) var plate: texture_2d<f32>;
@group(0) @binding(1) var ndc_depth: texture_2d<f32>;
@vertex
fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let p = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(p * 2.0 - 1.0, 0.0, 1.0);
}
struct Out { @location(0) color: vec4<f32>, @builtin(frag_depth) depth: f32 };
@fragment
fn fs(@builtin(position) pos: vec4<f32>) -> Out {
    let q = vec2<i32>(pos.xy);
    var o: Out;
    o.color = textureLoad(plate, q, 0);
    o.depth = textureLoad(ndc_depth, q, 0).x;
    return o;
}
"#;

    const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

    use crate::gpu::f16_to_f32;

    /// The density mode composited by the runtime's engine drawer on `gpu`'s device over
    /// `plate` (black without one), cut at `depth` (view-axis distances, row 0 at the top): the
    /// image (linear RGB, the plate's alpha) and the GPU time of the drawer's passes.
    #[allow(clippy::too_many_arguments)]
    pub fn composite(
        gpu: &crate::gpu::Gpu,
        asset: &Asset,
        s: &RenderSettings,
        view: [[f64; 4]; 4],
        proj: [[f64; 4]; 4],
        near: f64,
        plate: Option<&Plate>,
        depth: Option<&[f32]>,
    ) -> Result<(Image, Option<f64>), String> {
        let (w, h) = (s.output.width, s.output.height);
        let n = (w * h) as usize;
        let (device, queue) = (gpu.device(), gpu.queue());
        let volume = GpuVolume::upload(device, queue, asset).map_err(|e| e.to_string())?;
        let mut drawer = VolumeDrawer::new(device, &volume, COLOR).map_err(|e| e.to_string())?;
        let m4 = |m: [[f64; 4]; 4]| {
            Mat4::from_cols_array_2d(&m.map(|r| r.map(|v| v as f32))).transpose()
        };
        let view = View::new(m4(view), m4(proj), (w, h)).map_err(|e| e.to_string())?;

        let tex = |format, usage| {
            crate::gpu::texture_2d(device, "vdbcook render composite", format, usage, (w, h))
        };
        let upload = |format, texel: u32, bytes: &[u8]| {
            let t = tex(
                format,
                wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            );
            queue.write_texture(
                t.as_image_copy(),
                bytes,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(w * texel),
                    rows_per_image: None,
                },
                t.size(),
            );
            t.create_view(&Default::default())
        };
        let scene_rgba: Vec<f32> = match plate {
            Some(p) => p.rgba.clone(),
            None => [0.0, 0.0, 0.0, 1.0].repeat(n),
        };
        // Reversed-Z infinite: NDC z = near / d (clamped to the near plane), 0 = no surface.
        let ndc: Vec<f32> = match depth {
            Some(d) => d
                .iter()
                .map(|&d| {
                    if d.is_finite() && d > 0.0 {
                        (near / d as f64).min(1.0) as f32
                    } else {
                        0.0
                    }
                })
                .collect(),
            None => vec![0.0; n],
        };
        let plate_view = upload(
            wgpu::TextureFormat::Rgba32Float,
            16,
            bytemuck::cast_slice(&scene_rgba),
        );
        let depth_in = upload(wgpu::TextureFormat::R32Float, 4, bytemuck::cast_slice(&ndc));
        let color = tex(
            COLOR,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let depth_tex = tex(
            wgpu::TextureFormat::Depth32Float,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let (color_view, depth_view) = (
            color.create_view(&Default::default()),
            depth_tex.create_view(&Default::default()),
        );

        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("vdbcook render scene"),
            source: wgpu::ShaderSource::Wgsl(SCENE_WGSL.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vdbcook render scene"),
            entries: &[crate::gpu::texture_entry(0), crate::gpu::texture_entry(1)],
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vdbcook render scene"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&plate_view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&depth_in),
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("vdbcook render scene"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("vdbcook render scene"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: wgpu::TextureFormat::Depth32Float,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Always),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs"),
                compilation_options: Default::default(),
                targets: &[Some(COLOR.into())],
            }),
            multiview_mask: None,
            cache: None,
        });

        let timer = GpuTimer::new(device, queue);
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = crate::gpu::cleared_pass(
                &mut encoder,
                "vdbcook render scene",
                &color_view,
                &depth_view,
                0.0,
            );
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.draw(0..3, 0..1);
        }
        if let Some(t) = &timer {
            t.begin(&mut encoder);
        }
        let inst = Instance {
            time: s.output.frame as f32,
            ..Default::default()
        };
        let _held = drawer
            .draw(
                device,
                queue,
                &mut encoder,
                &DrawTarget {
                    color: &color_view,
                    depth: Some(&depth_view),
                },
                &view,
                &[inst],
                &vdbcook_runtime::Shading::of_settings(s),
            )
            .map_err(|e| e.to_string())?;
        if let Some(t) = &timer {
            t.end(&mut encoder);
        }
        // Rgba16Float: 8 bytes per texel.
        let readback = crate::gpu::TextureReadback::record(device, &mut encoder, &color, 8);
        queue.submit([encoder.finish()]);
        let data = readback.read(device)?;
        let gpu_ms = timer.as_ref().and_then(|t| t.read_ms(device));
        let rgba: Vec<f32> = data
            .chunks_exact(2)
            .map(|c| f16_to_f32(u16::from_le_bytes([c[0], c[1]])))
            .collect();
        Ok((
            Image {
                width: w,
                height: h,
                rgba,
                value: vec![0.0; n],
            },
            gpu_ms,
        ))
    }
}
