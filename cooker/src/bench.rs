//! `vdbcook bench`: what an effect costs in a game on this machine's GPU. The runtime's engine
//! drawer (`VolumeDrawer`, the code an engine links) draws N instances of the asset, flat
//! (density) and lit, into an `Rgba16Float` target with a depth buffer, with the look `render`
//! gives from the same flags (`crate::look`). Per mode and count, each displayed frame timed
//! three ways: the GPU span of the frame by timestamp queries, from a stamp submitted before
//! the drawer's `prepare` to one after its passes (the light-volume builds `prepare` submits
//! count, and so do the idle gaps while `prepare` encodes on the CPU); the drawer's passes
//! alone (a second timer around `record`); `prepare`'s CPU time and the frame's wall time.
//! - **static**: one frame drawn again and again (what a paused effect costs);
//! - **playing**: the flip-book at `--fps` shown at `--display-fps`, one draw per displayed
//!   frame as a game would run it (fractional times crossfade two frames; a lit draw builds the
//!   light volumes of the crossfaded pair whenever the pair changes, inside that displayed
//!   frame): median and mean (the amortized cost).
//!
//! and the image error of the playing path: three displayed frames (a third, two thirds and the
//! end of the run; with `--light-stride N`, also the N − 1 flip-book frames after each) against
//! the same view and time drawn by a fresh drawer (no light volume or pipeline carried over)
//! with each frame's own light, the largest relative RMSE over RGB: what
//! any shortcut of the playing path costs (0 up to f16 rounding when every light volume is
//! built exactly; `--light-stride N`'s light of every N-th frame is such a shortcut).

use std::path::PathBuf;

use crate::errors::CliError;

#[derive(clap::Args)]
pub struct Args {
    /// The cooked asset (.vdbc), or VDB sources (cooked in memory, f32, first).
    #[arg(value_name = "ASSET|VDB")]
    input: PathBuf,
    #[arg(long, default_value_t = 640)]
    width: u32,
    #[arg(long, default_value_t = 360)]
    height: u32,
    /// Instance counts, each a run: N copies on a cubic lattice 2.2 radii apart, all in view.
    #[arg(
        long,
        default_value = "1",
        value_delimiter = ',',
        value_name = "N[,N..]"
    )]
    instances: Vec<usize>,
    /// The drawer's modes: density (flat) and lit (sun and sky, light volumes).
    #[arg(long, default_value = "density,lit", value_delimiter = ',',
          value_parser = ["density", "lit"], value_name = "MODE[,MODE..]")]
    modes: Vec<String>,
    /// The flip-book's frame rate.
    #[arg(long, default_value_t = 24.0)]
    fps: f64,
    /// The game's display rate while playing.
    #[arg(long, default_value_t = 60.0)]
    display_fps: f64,
    /// How the playing run shows the flip-book between its frames: crossfade (fractional
    /// times: two frames read and lerped per sample, their light volumes built as pairs change)
    /// or hold (whole frames, as an engine passing floor(time) draws: one frame read, one light
    /// volume built per frame change).
    #[arg(long, default_value = "crossfade", value_parser = ["crossfade", "hold"])]
    blend: String,
    /// How the lit march crosses two frames: lerp (both frames read and lerped per sample, the
    /// drawer's default) or dither (each sample one frame's density and light, frame 1 on the
    /// crossfade weight's share of a ray's samples: about a whole frame's cost, a per-pixel
    /// grain). With dither, `crossfade_error` is the playing frames' relative RMSE against the
    /// lerp (`LitCrossfade`).
    #[arg(long, default_value = "lerp", value_parser = ["lerp", "dither"])]
    lit_crossfade: String,
    /// Build each lit instance's next light volume ahead, over N displayed frames (0: none, the
    /// drawer's default; `VolumeDrawer::set_light_ahead`): the same light, its builds spread
    /// over the frames before they are needed instead of landing in the frame that needs them
    /// (compare `playing_max_ms`). 2 suits 24 fps under 60.
    #[arg(long, default_value_t = 0, value_name = "N")]
    light_ahead: u32,
    /// While playing, light the flip-book's frames in spans of N, one light volume a span built
    /// from its middle frame (`Instance::light_stride`; 1, the default: every frame its own
    /// light): N times fewer light builds, for light up to N/2 frames off. `playing_error` is
    /// then the playing frames' relative RMSE against each frame's exact light; the static
    /// frames (a paused effect) keep their exact light.
    #[arg(long, default_value_t = 1, value_name = "N")]
    light_stride: u32,
    /// Rays the drawer marches: full (one per pixel), half or quarter (one per 2×2 or 4×4 block
    /// away from depth edges, upsampled: `MarchResolution`); with half or quarter,
    /// `resolution_error` is the static frame's relative RMSE against the full-resolution draw.
    #[arg(long, default_value = "full", value_parser = ["full", "half", "quarter"])]
    march_resolution: String,
    /// Also write each run's static frame as DIR/MODE-N-RESOLUTION.png and the three playing
    /// checkpoints of `playing_error` as DIR/MODE-N-RESOLUTION-BLEND-LITCROSSFADE-tTIME.png
    /// (…-LITCROSSFADE-strideS-tTIME.png with `--light-stride S` above 1; tone-mapped sRGB over
    /// the bench's backdrop, as `render` maps radiance): to see what was timed.
    #[arg(long, value_name = "DIR")]
    png: Option<PathBuf>,
    /// Displayed frames timed while playing (after one warm-up frame).
    #[arg(long, default_value_t = 60)]
    frames: u32,
    /// Static draws timed (after a first draw that compiles, then warm-up draws filling at least
    /// 0.3 s).
    #[arg(long, default_value_t = 10)]
    runs: u32,
    /// Grid to cook when the input is VDB.
    #[arg(long)]
    grid: Option<String>,
    /// Accept gaps in the frame numbering (VDB input).
    #[arg(long)]
    allow_gaps: bool,
    #[command(flatten)]
    look: crate::look::LookArgs,
    /// Print one JSON document on stdout: `{adapter, width, height, clock, fps, display_fps,
    /// results: [{mode, instances, static_ms, playing_ms, playing_error, light_build_ms, …}]}`
    /// (every key: docs/cli.md).
    #[arg(long)]
    pub json: bool,
}

/// The flags' ranges, checked before any GPU work.
fn check(a: &Args) -> Result<(), CliError> {
    let usage = |m: String| Err(CliError::Usage(m));
    if a.instances.iter().any(|&n| !(1..=4096).contains(&n)) {
        return usage(format!(
            "--instances {:?}: each count 1..=4096",
            a.instances
        ));
    }
    if !(1..=16384).contains(&a.width) || !(1..=16384).contains(&a.height) {
        return usage(format!(
            "--width {} --height {}: 1..=16384 each",
            a.width, a.height
        ));
    }
    let rate = |r: f64| r > 0.0 && r <= 1000.0;
    if !(rate(a.fps) && rate(a.display_fps)) {
        return usage(format!(
            "--fps {} --display-fps {}: each in (0, 1000]",
            a.fps, a.display_fps
        ));
    }
    if a.light_ahead > 1000 {
        return usage(format!("--light-ahead {}: 0..=1000", a.light_ahead));
    }
    if !(1..=1000).contains(&a.light_stride) {
        return usage(format!("--light-stride {}: 1..=1000", a.light_stride));
    }
    if !(1..=100_000).contains(&a.frames) || !(1..=100_000).contains(&a.runs) {
        return usage(format!(
            "--frames {} --runs {}: 1..=100000 each",
            a.frames, a.runs
        ));
    }
    Ok(())
}

#[cfg(not(feature = "gpu"))]
pub fn run(a: &Args) -> Result<(), CliError> {
    check(a)?;
    Err(CliError::Other(
        "vdbcook bench needs the GPU runtime: this build has no `gpu` feature".into(),
    ))
}

#[cfg(feature = "gpu")]
pub fn run(a: &Args) -> Result<(), CliError> {
    imp::run(a)
}

#[cfg(feature = "gpu")]
mod imp {
    use std::time::Instant;

    use serde_json::json;
    use vdbcook_runtime::glam::{Affine3A, Vec3, Vec4};
    use vdbcook_runtime::{
        wgpu, DrawTarget, GpuTimer, GpuVolume, Instance, LitCrossfade, MarchResolution, Shading,
        View, VolumeDrawer,
    };
    use vdbcook_trace::{Camera, Mode, Output};

    use super::{check, Args};
    use crate::errors::CliError;

    /// The least wall time of static draws before the timed ones (clock ramp-up, compilation).
    const WARM_UP: std::time::Duration = std::time::Duration::from_millis(300);
    use crate::gpu::{cleared_pass, f16_to_f32, texture_2d, Gpu, TextureReadback};

    const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

    fn other(m: impl Into<String>) -> CliError {
        CliError::Other(m.into())
    }

    fn median(mut v: Vec<f64>) -> f64 {
        v.sort_by(|a, b| a.total_cmp(b));
        middle(&v)
    }

    /// The median of values already sorted (the upper middle of an even count).
    fn middle(sorted: &[f64]) -> f64 {
        sorted[sorted.len() / 2]
    }

    /// One run's scene: the targets, the view, the instances' placements, the depth plane.
    struct Scene {
        color: wgpu::Texture,
        color_view: wgpu::TextureView,
        depth_view: wgpu::TextureView,
        view: View,
        camera: Camera,
        places: Vec<Affine3A>,
        behind: f32,
    }

    /// N instances of the asset (world centre `centre`, radius `radius`) on a k×k×k lattice
    /// 2.2 radii apart, framed by a 40° view from (0.6, 0.4, 1), up `up`.
    fn scene(
        device: &wgpu::Device,
        (w, h): (u32, u32),
        n: usize,
        (centre, radius): (Vec3, f32),
        up: Vec3,
    ) -> Result<Scene, CliError> {
        let tex = |format, usage| texture_2d(device, "vdbcook bench target", format, usage, (w, h));
        let color = tex(
            COLOR,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let depth = tex(
            wgpu::TextureFormat::Depth32Float,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let k = (1..).find(|k| k * k * k >= n).unwrap_or(1);
        let spacing = 2.2 * radius;
        let places = (0..n)
            .map(|i| {
                let c = Vec3::new((i % k) as f32, ((i / k) % k) as f32, (i / (k * k)) as f32)
                    - Vec3::splat(0.5 * (k - 1) as f32);
                Affine3A::from_translation(c * spacing)
            })
            .collect();
        let fov = 40f32.to_radians();
        let reach = radius + spacing * 0.5 * (k - 1) as f32 * 3f32.sqrt();
        let dist = reach / (0.5 * fov).sin();
        let f = vdbcook_trace::up_frame([0.6, 0.4, 1.0], up.as_dvec3().to_array());
        let dir = Vec3::new(f[0] as f32, f[1] as f32, f[2] as f32).normalize();
        let eye = centre + dir * dist;
        // The near plane well inside the eye's distance to the nearest instance, at any scale.
        let near = (0.5 * (dist - reach)).max(1e-6);
        let view = View::look_at(eye, centre, up, fov, w as f32 / h as f32, near, (w, h))
            .map_err(|e| other(e.to_string()))?;
        let behind = {
            let c = view.proj * Vec4::new(0.0, 0.0, -(dist + 2.0 * reach), 1.0);
            c.z / c.w
        };
        let camera = Camera {
            eye: eye.as_dvec3().to_array(),
            look_at: centre.as_dvec3().to_array(),
            up: up.as_dvec3().to_array(),
            fov_y_deg: 40.0,
        };
        Ok(Scene {
            color_view: color.create_view(&Default::default()),
            color,
            depth_view: depth.create_view(&Default::default()),
            view,
            camera,
            places,
            behind,
        })
    }

    /// Clears the colour target and sets the depth buffer to the plane behind the instances.
    fn clear(enc: &mut wgpu::CommandEncoder, s: &Scene) {
        cleared_pass(
            enc,
            "vdbcook bench clear",
            &s.color_view,
            &s.depth_view,
            s.behind,
        );
    }

    /// The timers of a displayed frame: the span from before `prepare` to after the passes,
    /// and the passes alone.
    struct Clocks {
        span: GpuTimer,
        draw: GpuTimer,
    }

    /// One displayed frame's times (ms): the GPU span and the passes (timestamps; `None`
    /// without them or when a read-back failed), `prepare`'s CPU time, the wall time.
    struct Timing {
        span: Option<f64>,
        draw: Option<f64>,
        prepare: f64,
        wall: f64,
    }

    /// One displayed frame: the span's first stamp and the clear (submitted), prepare (light
    /// volumes built and submitted here when the crossfaded pair changes), the draw between
    /// the draw timer's stamps and the span's second stamp (submitted), wait. Its times and,
    /// when `read`, the image (RGB, linear).
    #[allow(clippy::too_many_arguments)]
    fn frame(
        gpu: &Gpu,
        drawer: &mut VolumeDrawer,
        clocks: Option<&Clocks>,
        s: &Scene,
        (time, light_stride): (f32, u32),
        shading: &Shading,
        read: bool,
    ) -> Result<(Timing, Option<Vec<f32>>), CliError> {
        let (device, queue) = (gpu.device(), gpu.queue());
        let start = Instant::now();
        let instances: Vec<Instance> = s
            .places
            .iter()
            .map(|&p| Instance {
                time,
                light_stride,
                ..Instance::at(p)
            })
            .collect();
        let mut enc = device.create_command_encoder(&Default::default());
        if let Some(c) = clocks {
            c.span.begin(&mut enc);
        }
        clear(&mut enc, s);
        queue.submit([enc.finish()]);
        let target = DrawTarget {
            color: &s.color_view,
            depth: Some(&s.depth_view),
        };
        let t_prepare = Instant::now();
        let prepared = drawer
            .prepare(device, queue, &target, &s.view, &instances, shading)
            .map_err(|e| other(e.to_string()))?;
        let prepare = t_prepare.elapsed().as_secs_f64() * 1e3;
        let mut enc = device.create_command_encoder(&Default::default());
        if let Some(c) = clocks {
            c.draw.begin(&mut enc);
        }
        drawer.record(&mut enc, &prepared);
        if let Some(c) = clocks {
            c.draw.end(&mut enc);
            c.span.end(&mut enc);
        }
        let readback = read.then(|| TextureReadback::record(device, &mut enc, &s.color, 8));
        queue.submit([enc.finish()]);
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| other(format!("GPU: {e}")))?;
        let wall = start.elapsed().as_secs_f64() * 1e3;
        let timing = Timing {
            span: clocks.and_then(|c| c.span.read_ms(device)),
            draw: clocks.and_then(|c| c.draw.read_ms(device)),
            prepare,
            wall,
        };
        let image = match readback {
            Some(r) => {
                let bytes = r.read(device).map_err(other)?;
                Some(
                    bytes
                        .chunks_exact(8)
                        .flat_map(|t| {
                            (0..3).map(move |c| {
                                f16_to_f32(u16::from_le_bytes([t[2 * c], t[2 * c + 1]]))
                            })
                        })
                        .collect(),
                )
            }
            None => None,
        };
        Ok((timing, image))
    }

    /// The medians (and the mean of the span) of a run's frames; the clock they came from.
    struct Summary {
        ms: f64,
        mean_ms: f64,
        /// The 95th percentile (nearest rank) and the largest span: the frames the builds land in.
        p95_ms: f64,
        max_ms: f64,
        /// Every frame's span, in order.
        spans: Vec<f64>,
        draw_ms: Option<f64>,
        prepare_ms: f64,
        wall_ms: f64,
        /// Frames whose span had no timestamps (their wall time stands in).
        walls: usize,
    }

    fn summary(t: &[Timing]) -> Summary {
        let spans: Vec<f64> = t.iter().map(|f| f.span.unwrap_or(f.wall)).collect();
        let mut sorted = spans.clone();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        let draws: Vec<f64> = t.iter().filter_map(|f| f.draw).collect();
        Summary {
            ms: middle(&sorted),
            mean_ms: spans.iter().sum::<f64>() / n as f64,
            p95_ms: sorted[((0.95 * n as f64).ceil() as usize).clamp(1, n) - 1],
            max_ms: sorted[n - 1],
            spans,
            draw_ms: (!draws.is_empty()).then(|| median(draws)),
            prepare_ms: median(t.iter().map(|f| f.prepare).collect()),
            wall_ms: median(t.iter().map(|f| f.wall).collect()),
            walls: t.iter().filter(|f| f.span.is_none()).count(),
        }
    }

    /// The worse of a running error and a new one: a NaN (an image not read back) is kept
    /// until a later finite error replaces it.
    fn worse(acc: f64, e: f64) -> f64 {
        if e.is_nan() {
            e
        } else {
            acc.max(e)
        }
    }

    /// Relative RMSE of `a` against `b` (0 when both are black).
    fn rel_rmse(a: &[f32], b: &[f32]) -> f64 {
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for (x, y) in a.iter().zip(b) {
            num += (*x as f64 - *y as f64).powi(2);
            den += (*y as f64).powi(2);
        }
        if den > 0.0 {
            (num / den).sqrt()
        } else {
            num.sqrt()
        }
    }

    pub fn run(a: &Args) -> Result<(), CliError> {
        check(a)?;
        let (asset, _) =
            crate::render::load_input(&a.input, a.grid.clone(), a.allow_gaps, None, &a.look)?;
        let at = |e: &dyn std::fmt::Display| other(format!("{}: {e}", a.input.display()));
        crate::render::refuse_unshowable(&asset, &a.input, Mode::Density)?;
        let gpu = Gpu::open().map_err(other)?;
        let (device, queue) = (gpu.device(), gpu.queue());
        let max = device.limits().max_texture_dimension_2d;
        if a.width > max || a.height > max {
            return Err(CliError::Usage(format!(
                "--width {} --height {}: this adapter's textures reach {max} pixels a side",
                a.width, a.height
            )));
        }
        let volume = GpuVolume::upload(device, queue, &asset).map_err(|e| at(&e))?;
        let clocks = GpuTimer::new(device, queue)
            .zip(GpuTimer::new(device, queue))
            .map(|(span, draw)| Clocks { span, draw });
        let mut walls = 0usize;
        // The asset's stored box (frame 0, else any frame) in world space.
        let bbox = (0..asset.frame_count())
            .find_map(|f| volume.frame_bbox(f))
            .ok_or_else(|| at(&"no frame stores anything"))?;
        let m = asset.header.index_to_world;
        let world = |p: [f64; 3]| {
            Vec3::from_array(
                [0, 1, 2]
                    .map(|r| (m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3]) as f32),
            )
        };
        let (wlo, whi) = (world(bbox.0), world(bbox.1));
        let bounds = (0.5 * (wlo + whi), 0.5 * (whi - wlo).length().max(1e-6));
        let up = {
            let u = a.look.up_axis(&asset);
            Vec3::new(u[0] as f32, u[1] as f32, u[2] as f32)
        };
        let frames = asset.frame_count() as f64;
        let mut results = Vec::new();
        if !a.json {
            println!(
                "{} on {}: {}×{}, flip-book {} fps shown at {} fps ({}); GPU ms per displayed \
                 frame (timestamp span: light builds and passes), median unless said",
                a.input.display(),
                gpu.describe(),
                a.width,
                a.height,
                a.fps,
                a.display_fps,
                a.blend
            );
            println!(
                "| mode | instances | static ms | playing ms | playing mean ms | playing max ms \
                 | playing / static | playing draw ms | light builds / frame | light build ms \
                 | playing error |"
            );
            println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
        }
        for mode_name in &a.modes {
            let mode = Mode::parse(mode_name).expect("clap checked");
            for &n in &a.instances {
                let s = scene(device, (a.width, a.height), n, bounds, up)?;
                let mut settings = crate::look::settings(
                    &a.look,
                    Output {
                        width: a.width,
                        height: a.height,
                        frame: 0,
                    },
                    mode,
                )?;
                crate::look::resolve(&a.look, &mut settings, &asset, &s.camera)?;
                let shading = Shading::of_settings(&settings);
                let resolution = match a.march_resolution.as_str() {
                    "half" => MarchResolution::Half,
                    "quarter" => MarchResolution::Quarter,
                    _ => MarchResolution::Full,
                };
                let light = match a.lit_crossfade.as_str() {
                    "dither" => LitCrossfade::Dither,
                    _ => LitCrossfade::Lerp,
                };
                let fresh_drawer = |resolution, light| -> Result<VolumeDrawer, CliError> {
                    let mut d = VolumeDrawer::new(device, &volume, COLOR).map_err(|e| at(&e))?;
                    d.set_march_resolution(resolution);
                    d.set_lit_crossfade(light);
                    Ok(d)
                };
                let mut drawer = fresh_drawer(resolution, light)?;
                // Static: frame 0 again and again, after one draw that compiles and builds and
                // then a warm-up of at least WARM_UP of draws (a real GPU idles at a low clock
                // while the pipelines compile and needs a fraction of a second of work to ramp
                // up: with the compile inside the warm-up, an H100 showed each mode's first
                // configuration up to 3.8 times slower static than playing the same frame).
                let c = clocks.as_ref();
                frame(&gpu, &mut drawer, c, &s, (0.0, 1), &shading, false)?;
                let warm = std::time::Instant::now();
                loop {
                    frame(&gpu, &mut drawer, c, &s, (0.0, 1), &shading, false)?;
                    if warm.elapsed() >= WARM_UP {
                        break;
                    }
                }
                let mut statics = Vec::new();
                for _ in 0..a.runs {
                    let (t, _) = frame(&gpu, &mut drawer, c, &s, (0.0, 1), &shading, false)?;
                    statics.push(t);
                }
                // One build of the static frame's light volumes (lit): frame 0 drawn again after
                // the kept volumes are dropped, its span less the static frame's, median of
                // `runs` (what a displayed frame pays when the flip-book reaches a frame whose
                // light is not built; a crossfade's pair builds its second volume too).
                let rebuilds = if shading.lighting.is_some() {
                    let mut t = Vec::new();
                    for _ in 0..a.runs {
                        drawer.invalidate_light_volumes();
                        t.push(frame(&gpu, &mut drawer, c, &s, (0.0, 1), &shading, false)?.0);
                    }
                    Some(summary(&t))
                } else {
                    None
                };
                // Playing: one draw per displayed frame, the flip-book time advancing by
                // fps / display_fps frames each (wrapping), light built as pairs change; the
                // image kept at three checkpoints.
                // Building ahead from here on: a paused effect builds nothing ahead once its next
                // frame's volume is kept, so the static frames are timed without it.
                drawer.set_light_ahead(a.light_ahead);
                let mut playing = Vec::new();
                let hold = a.blend == "hold";
                let mut builds_before = 0;
                let checks = [a.frames / 3, 2 * a.frames / 3, a.frames];
                let mut kept = Vec::new();
                // Crossfaded times wrap over [0, frames − 1] (the last frame has no successor to
                // fade to), whole frames over all of them; a one-frame asset stays at 0.
                let span = if hold { frames } else { frames - 1.0 };
                for k in 0..=a.frames {
                    let t = if frames > 1.0 {
                        ((k as f64 + 1.0) * a.fps / a.display_fps) % span
                    } else {
                        0.0
                    } as f32;
                    let t = if hold { t.floor() } else { t };
                    if k == 1 {
                        builds_before = drawer.light_builds().built;
                    }
                    let read = k > 0 && checks.contains(&k);
                    let (timing, img) = frame(
                        &gpu,
                        &mut drawer,
                        c,
                        &s,
                        (t, a.light_stride),
                        &shading,
                        read,
                    )?;
                    if k > 0 {
                        playing.push(timing);
                    }
                    if let Some(img) = img {
                        kept.push((t, img));
                    }
                }
                // Light volumes built per timed displayed frame (the rest were reused or copied).
                let builds = (drawer.light_builds().built - builds_before) as f64 / a.frames as f64;
                // With a light stride, also the stride − 1 flip-book frames after each kept one
                // (drawn by the playing drawer, whose light for a time depends on that time alone),
                // so that every frame's place in its span is checked, not only the spans' middle
                // frames that the checkpoints may all fall on.
                let mut checked = kept.clone();
                for (t, _) in &kept {
                    for j in 1..a.light_stride.min(frames as u32) {
                        let t = ((*t as f64 + j as f64) % span) as f32;
                        let stride = (t, a.light_stride);
                        let (_, img) = frame(&gpu, &mut drawer, None, &s, stride, &shading, true)?;
                        checked.push((t, img.unwrap_or_default()));
                    }
                }
                // The same views and times drawn from nothing: a fresh drawer each, every frame
                // its own light.
                let mut error = 0.0f64;
                for (t, img) in &checked {
                    let mut fresh = fresh_drawer(resolution, light)?;
                    let (_, exact) = frame(&gpu, &mut fresh, None, &s, (*t, 1), &shading, true)?;
                    let e = match exact {
                        Some(x) if img.len() == x.len() => rel_rmse(img, &x),
                        _ => f64::NAN,
                    };
                    error = worse(error, e);
                }
                // A dithered lit crossfade against the lerp of both frames, at the same
                // times (only where some kept time falls between two frames). One drawer draws
                // them all: a drawer carried over draws what a fresh one does (`playing_error`).
                let crossfade_error = if mode_name == "lit"
                    && light == LitCrossfade::Dither
                    && kept.iter().any(|(t, _)| t.fract() != 0.0)
                {
                    let mut lerp = fresh_drawer(resolution, LitCrossfade::Lerp)?;
                    let mut worst = 0.0f64;
                    for (t, img) in &kept {
                        let (_, want) = frame(
                            &gpu,
                            &mut lerp,
                            None,
                            &s,
                            (*t, a.light_stride),
                            &shading,
                            true,
                        )?;
                        worst = worse(worst, want.map_or(f64::NAN, |x| rel_rmse(img, &x)));
                    }
                    Some(worst)
                } else {
                    None
                };
                if let Some(dir) = &a.png {
                    let display = a.look.display(false);
                    let write = |name: String, img: &[f32]| -> Result<(), CliError> {
                        let rgba: Vec<u8> = img
                            .chunks_exact(3)
                            .flat_map(|p| {
                                let [r, g, b] = display.encode8([p[0], p[1], p[2]]);
                                [r, g, b, 255]
                            })
                            .collect();
                        std::fs::create_dir_all(dir).map_err(|e| {
                            CliError::Other(format!("cannot create {}: {e}", dir.display()))
                        })?;
                        crate::render::write_png(&dir.join(name), a.width, a.height, &rgba)
                    };
                    let (_, img) = frame(&gpu, &mut drawer, None, &s, (0.0, 1), &shading, true)?;
                    if let Some(img) = img {
                        write(format!("{mode_name}-{n}-{}.png", a.march_resolution), &img)?;
                    }
                    // The playing path's checked frames, named by how they were drawn and when.
                    let stride = match a.light_stride {
                        1 => String::new(),
                        stride => format!("-stride{stride}"),
                    };
                    for (t, img) in &kept {
                        let name = format!(
                            "{mode_name}-{n}-{}-{}-{}{stride}-t{t:.3}.png",
                            a.march_resolution, a.blend, a.lit_crossfade
                        );
                        write(name, img)?;
                    }
                }
                // The reduced-resolution march against the full one, static frame (same view).
                let resolution_error = if resolution != MarchResolution::Full {
                    let (_, img) = frame(&gpu, &mut drawer, None, &s, (0.0, 1), &shading, true)?;
                    let mut full = fresh_drawer(MarchResolution::Full, light)?;
                    let (_, exact) = frame(&gpu, &mut full, None, &s, (0.0, 1), &shading, true)?;
                    match (img, exact) {
                        (Some(i), Some(x)) => Some(rel_rmse(&i, &x)),
                        _ => None,
                    }
                } else {
                    None
                };
                let (st, pl) = (summary(&statics), summary(&playing));
                walls += st.walls + pl.walls + rebuilds.as_ref().map_or(0, |r| r.walls);
                let light_build_ms = rebuilds.map(|r| r.ms - st.ms);
                if !a.json {
                    println!(
                        "| {mode_name} | {n} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {} | \
                         {builds:.2} | {} | {error:.1e} |",
                        st.ms,
                        pl.ms,
                        pl.mean_ms,
                        pl.max_ms,
                        pl.ms / st.ms,
                        pl.draw_ms.map_or("–".into(), |d| format!("{d:.2}")),
                        light_build_ms.map_or("–".into(), |d| format!("{d:.2}")),
                    );
                }
                results.push(json!({
                    "mode": mode_name, "instances": n, "static_ms": st.ms, "playing_ms": pl.ms,
                    "playing_error": error, "playing_mean_ms": pl.mean_ms,
                    "playing_p95_ms": pl.p95_ms, "playing_max_ms": pl.max_ms,
                    "playing_spans_ms": pl.spans,
                    "static_draw_ms": st.draw_ms, "playing_draw_ms": pl.draw_ms,
                    "static_prepare_ms": st.prepare_ms, "playing_prepare_ms": pl.prepare_ms,
                    "static_wall_ms": st.wall_ms, "playing_wall_ms": pl.wall_ms,
                    "playing_light_builds": builds, "light_build_ms": light_build_ms,
                    "resolution_error": resolution_error,
                    "crossfade_error": crossfade_error,
                }));
            }
        }
        let clock = match (clocks.is_some(), walls) {
            (false, _) => "wall",
            (true, 0) => "timestamps",
            (true, _) => "mixed",
        };
        if a.json {
            let doc = json!({
                "adapter": gpu.describe(),
                "asset": a.input.display().to_string(),
                "width": a.width,
                "height": a.height,
                "clock": clock,
                "fps": a.fps,
                "display_fps": a.display_fps,
                "blend": a.blend,
                "lit_crossfade": a.lit_crossfade,
                "light_ahead": a.light_ahead,
                "light_stride": a.light_stride,
                "march_resolution": a.march_resolution,
                "frames": a.frames,
                "runs": a.runs,
                "results": results,
            });
            println!("{}", serde_json::to_string_pretty(&doc).expect("json"));
        }
        Ok(())
    }
}
