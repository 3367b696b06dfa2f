//! `vdbcook view`: an interactive flip-book viewer built only on the runtime's public API
//! (`vdbcook_runtime`: `GpuVolume`, `Renderer`, `GpuTimer`, `Camera`, `Mode`, `Settings`, its
//! re-exported `wgpu`) — it exists to prove that API is enough to put an asset on screen. A winit
//! window with a wgpu surface; the runtime's tracer renders each frame into an `Rgba8Unorm`
//! storage texture that one full-screen triangle copies onto the surface. Orbit camera (left
//! drag, wheel), play/pause (space) at `--fps`, frame steps (arrows), mode cycling (`m`), camera
//! reset (`r`), Esc quits; the frame, mode and frame time are in the window title.
//!
//! `--frames N [--screenshot OUT.png]` is the headless path the tests run: no window and no
//! surface, a texture of the window's format instead, and the same per-frame code
//! ([`ViewerState::frame`]), advancing the flip-book one frame and orbiting the camera
//! [`ORBIT_STEP_DEG`] per rendered frame; it prints per-frame GPU and CPU times (`--json`: with the
//! final camera, which `vdbcook render --camera` reproduces).
//!
//! Built with the `view` feature (on by default; it pulls in winit); without it `run` says so.

use std::path::PathBuf;

use crate::errors::CliError;

/// The modes `m` cycles through (the runtime tracer's, `vdbcook_runtime::GPU_MODES`).
pub const MODE_NAMES: [&str; 8] = [
    "density",
    "depth",
    "first-hit",
    "brick-hue",
    "steps",
    "scatter",
    "delta",
    "lit",
];

/// Degrees the headless path orbits the camera (about the vertical axis) per rendered frame.
pub const ORBIT_STEP_DEG: f64 = 10.0;

#[derive(clap::Args)]
pub struct Args {
    /// The cooked asset (.vdbc), or VDB sources (file, folder, frame pattern or glob), which
    /// are cooked in memory (f32, lossless) first.
    #[arg(value_name = "ASSET|VDB")]
    input: PathBuf,
    /// First frame shown (0-based); the camera starts from this frame's framing.
    #[arg(long, default_value_t = 0)]
    frame: usize,
    /// First mode shown (`m` cycles).
    #[arg(long, default_value = "density", value_parser = MODE_NAMES)]
    mode: String,
    /// Window (or headless image) width in pixels.
    #[arg(long, default_value_t = 960)]
    width: u32,
    /// Window (or headless image) height in pixels.
    #[arg(long, default_value_t = 540)]
    height: u32,
    /// Headless: render N frames offscreen (no window), one flip-book frame and one orbit step
    /// each, print their times and exit.
    #[arg(long, value_name = "N")]
    frames: Option<u32>,
    /// Headless: write the last rendered frame as a PNG (implies --frames 1 when not given).
    #[arg(long, value_name = "OUT.png")]
    screenshot: Option<PathBuf>,
    /// Flip-book playback rate (frames per second) when playing (space).
    #[arg(long, default_value_t = 24.0)]
    fps: f64,
    /// Grid to cook when the input is VDB (default: `density`, else the only float grid).
    #[arg(long)]
    grid: Option<String>,
    /// Accept gaps in the frame numbering (VDB input).
    #[arg(long)]
    allow_gaps: bool,
    /// Headless: print one JSON document on stdout (per-frame times, the final camera).
    #[arg(long)]
    pub json: bool,
    /// The look, as `render` takes it (medium, lights, emission, colour pipeline, up axis).
    #[command(flatten)]
    pub look: crate::look::LookArgs,
}

/// The render settings the flags ask for (the mode is the viewer's own, switched with `m`)
/// and, on `asset`, the starting camera and what `look::resolve` decided, as `render` resolves
/// them: the same flags give the same picture.
fn base_settings(
    a: &Args,
    asset: Option<&vdbcook_asset::Asset>,
) -> Result<
    (
        vdbcook_trace::RenderSettings,
        Option<(vdbcook_trace::Camera, crate::look::Resolved)>,
    ),
    CliError,
> {
    let usage = |m: String| CliError::Usage(m);
    // A flag the viewer cannot take is a usage error (exit 2) before any window opens.
    let as_usage = |e: CliError| match e {
        CliError::Other(m) => CliError::Usage(m),
        e => e,
    };
    let mut s = crate::look::settings(
        &a.look,
        vdbcook_trace::Output {
            width: a.width,
            height: a.height,
            frame: a.frame,
        },
        // Resolved for the lit look (the filter); each draw takes the viewer's own mode.
        vdbcook_trace::Mode::Lit,
    )
    .map_err(as_usage)?;
    a.look.display(false).validate().map_err(usage)?;
    let resolved = match asset {
        Some(asset) => {
            let camera = crate::render::camera(
                None,
                asset,
                a.frame,
                a.width as f64 / a.height.max(1) as f64,
                a.look.up_axis(asset),
            )?;
            let r = crate::look::resolve(&a.look, &mut s, asset, &camera).map_err(as_usage)?;
            Some((camera, r))
        }
        None => None,
    };
    s.validate(asset.map_or(a.frame + 1, |x| x.frame_count()))
        .map_err(|e| usage(e.to_string()))?;
    Ok((s, resolved))
}

/// How a view starts: the settings and camera [`base_settings`] resolves, the colour pipeline,
/// and whether the sky stays out.
pub struct Start {
    pub settings: vdbcook_trace::RenderSettings,
    pub camera: vdbcook_trace::Camera,
    pub display: vdbcook_trace::Display,
    /// `--filter auto`: the filter was chosen for the lit mode, and the other modes read
    /// nearest, as `render` does in them.
    pub filter_auto: bool,
    pub transparent: bool,
}

/// The start of a view of `asset` from the flags.
pub fn start(a: &Args, asset: &vdbcook_asset::Asset) -> Result<Start, CliError> {
    let (settings, resolved) = base_settings(a, Some(asset))?;
    let (camera, resolved) = resolved.expect("resolved on the asset");
    Ok(Start {
        settings,
        camera,
        display: a.look.display(false),
        filter_auto: resolved.filter_auto,
        transparent: a.look.transparent,
    })
}

/// The headless run's frame count, after checking the flags: `None` for the interactive viewer.
fn headless_frames(a: &Args) -> Result<Option<u32>, CliError> {
    let usage = |m: String| Err(CliError::Usage(m));
    base_settings(a, None)?;
    if !(a.fps.is_finite() && a.fps > 0.0 && a.fps <= 1000.0) {
        return usage(format!(
            "--fps {} is out of range: give 0 < F <= 1000",
            a.fps
        ));
    }
    if a.width == 0 || a.height == 0 || a.width > 16384 || a.height > 16384 {
        return usage(format!(
            "--width {} --height {}: each side must be 1 to 16384",
            a.width, a.height
        ));
    }
    if let Some(p) = &a.screenshot {
        if p.extension().is_none_or(|e| !e.eq_ignore_ascii_case("png")) {
            return usage(format!(
                "{}: --screenshot writes a PNG; give a name ending in .png",
                p.display()
            ));
        }
    }
    match (a.frames, &a.screenshot) {
        (Some(0), _) => usage("--frames 0: the headless run renders at least one frame".into()),
        (Some(n), _) => Ok(Some(n)),
        (None, Some(_)) => Ok(Some(1)),
        (None, None) if a.json => {
            usage("--json reports a headless run: give --frames N (and --screenshot)".into())
        }
        (None, None) => Ok(None),
    }
}

#[cfg(feature = "view")]
pub use imp::{Orbit, ViewerState};

#[cfg(feature = "view")]
pub fn run(a: &Args) -> Result<(), CliError> {
    imp::run(a)
}

#[cfg(not(feature = "view"))]
pub fn run(a: &Args) -> Result<(), CliError> {
    headless_frames(a)?;
    Err(CliError::Other(
        "this vdbcook was built without the `view` feature".into(),
    ))
}

#[cfg(feature = "view")]
mod imp {
    use std::sync::Arc;
    use std::time::Instant;

    use serde_json::json;
    use vdbcook_runtime::{
        wgpu, Asset, Camera, GpuTimer, GpuVolume, Integrator, Medium, Mode, Renderer, Settings,
        TextureTarget, OPTIONAL_FEATURES,
    };
    use winit::application::ApplicationHandler;
    use winit::dpi::PhysicalSize;
    use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
    use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
    use winit::keyboard::{Key, NamedKey};
    use winit::window::{Window, WindowId};

    use super::*;

    /// The headless target's format: what the window asks its surface for
    /// ([`pick_surface_format`] prefers it), so both paths run the same blit.
    const HEADLESS_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Bgra8Unorm;
    /// What the tracer writes (storage-capable everywhere): radiance, unclamped, for the
    /// colour pipeline of the blit.
    const TRACE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

    /// Copies the tracer's image onto the target, pixel for pixel, through the colour pipeline
    /// (`display.wgsl`, as `render` writes a PNG): radiance modes get the sky behind the shaded
    /// ones, exposure and the tone map, then the sRGB curve (the target's own on an sRGB
    /// target); the diagnostic modes' false colours are display values already.
    const BLIT_WGSL: &str = r#"
struct BlitLook {
    scale: f32,
    curve: u32,
    // Bit 0: radiance (else false colours); bit 1: the sky behind; bit 2: an sRGB target.
    flags: u32,
    _pad: u32,
    sky: vec4<f32>,
}
@group(0) @binding(0) var image: texture_2d<f32>;
@group(0) @binding(1) var<uniform> look: BlitLook;
@vertex
fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let p = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(p * 2.0 - 1.0, 0.0, 1.0);
}
@fragment
fn fs(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    var c = textureLoad(image, vec2<i32>(pos.xy), 0);
    let srgb_target = (look.flags & 4u) != 0u;
    if ((look.flags & 1u) == 0u) {
        let v = clamp(c.rgb, vec3<f32>(0.0), vec3<f32>(1.0));
        return vec4<f32>(select(v, display_srgb_decode(v), srgb_target), clamp(c.a, 0.0, 1.0));
    }
    if ((look.flags & 2u) != 0u) {
        c = vec4<f32>(c.rgb + (1.0 - c.a) * look.sky.rgb, 1.0);
    }
    let d = display_map(c.rgb, look.scale, look.curve);
    return vec4<f32>(select(display_srgb_encode(d), d, srgb_target), clamp(c.a, 0.0, 1.0));
}
"#;

    fn other(m: impl Into<String>) -> CliError {
        CliError::Other(m.into())
    }

    /// An orbit around a centre: yaw about +Y (0: looking down −Z from +Z), pitch above the
    /// horizontal, distance, and the vertical field of view.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct Orbit {
        pub centre: [f64; 3],
        /// The world's up axis (yaw turns about it; the angles live in a frame where it is +Y).
        pub up: [f64; 3],
        pub yaw: f64,
        pub pitch: f64,
        pub radius: f64,
        pub fov_y_deg: f64,
    }

    /// Pitch limit (radians), short of the poles where the Y-up basis degenerates.
    const MAX_PITCH: f64 = 1.55;

    impl Orbit {
        /// The orbit through `camera`'s eye around its look-at point.
        pub fn from_camera(c: &Camera) -> Orbit {
            let d = [0, 1, 2].map(|i| c.eye[i] - c.look_at[i]);
            let d = vdbcook_trace::from_up_frame(d, c.up);
            let radius = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-9);
            Orbit {
                centre: c.look_at,
                up: vdbcook_trace::up_frame([0.0, 1.0, 0.0], c.up),
                yaw: d[0].atan2(d[2]),
                pitch: (d[1] / radius).clamp(-1.0, 1.0).asin(),
                radius,
                fov_y_deg: c.fov_y_deg,
            }
        }

        pub fn camera(&self) -> Camera {
            let (sy, cy) = self.yaw.sin_cos();
            let (sp, cp) = self.pitch.sin_cos();
            let c = self.centre;
            let d = vdbcook_trace::up_frame(
                [
                    self.radius * cp * sy,
                    self.radius * sp,
                    self.radius * cp * cy,
                ],
                self.up,
            );
            Camera {
                eye: [0, 1, 2].map(|i| c[i] + d[i]),
                look_at: c,
                up: self.up,
                fov_y_deg: self.fov_y_deg,
            }
        }

        pub fn rotate(&mut self, dyaw: f64, dpitch: f64) {
            self.yaw = (self.yaw + dyaw).rem_euclid(std::f64::consts::TAU);
            self.pitch = (self.pitch + dpitch).clamp(-MAX_PITCH, MAX_PITCH);
        }
    }

    /// What the viewer shows and the GPU objects that draw it: the camera, the flip-book frame,
    /// the mode, playback, and the tracer with its image and the blit onto the target. The
    /// interactive loop and the headless path both draw through [`ViewerState::frame`].
    pub struct ViewerState {
        pub orbit: Orbit,
        home: Orbit,
        pub frame: usize,
        pub frames: usize,
        /// Index into [`MODE_NAMES`].
        pub mode: usize,
        pub playing: bool,
        fps: f64,
        /// Seconds of playback not yet turned into frame steps.
        clock: f64,
        settings: Settings,
        display: vdbcook_trace::Display,
        filter_auto: bool,
        transparent: bool,
        srgb_target: bool,
        look_buf: wgpu::Buffer,
        renderer: Renderer,
        size: (u32, u32),
        image: Option<(TextureTarget, wgpu::BindGroup)>,
        blit: wgpu::RenderPipeline,
        blit_layout: wgpu::BindGroupLayout,
        timer: Option<GpuTimer>,
        /// A timer read was requested and has not been collected (no new `end` until then).
        timer_pending: bool,
        /// The latest GPU time the timer returned (ms).
        pub gpu_ms: Option<f64>,
        _volume: GpuVolume,
    }

    impl ViewerState {
        /// Uploads `asset` and builds the tracer and the blit onto targets of `format`, sized
        /// `size`; starts at `frame` in mode `mode` with `Camera::framing` of that frame.
        #[allow(clippy::too_many_arguments)]
        pub fn new(
            device: &wgpu::Device,
            queue: &wgpu::Queue,
            asset: &Asset,
            format: wgpu::TextureFormat,
            size: (u32, u32),
            frame: usize,
            mode: usize,
            fps: f64,
            start: &Start,
        ) -> Result<ViewerState, String> {
            let emission = start.settings.medium.emission.is_some();
            let frames = asset.frame_count();
            if frame >= frames {
                return Err(format!(
                    "--frame {frame} is out of range: the asset has {frames} frame(s)"
                ));
            }
            let camera = start.camera;
            let volume =
                GpuVolume::upload(device, queue, asset).map_err(|e| format!("GPU upload: {e}"))?;
            // Emission is compiled in when asked for (it slows the other renders).
            let renderer = if emission {
                Renderer::with_emission(device, &volume, TRACE_FORMAT)
            } else {
                Renderer::new(device, &volume, TRACE_FORMAT)
            }
            .map_err(|e| format!("GPU renderer: {e}"))?;
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("vdbcook view blit"),
                source: wgpu::ShaderSource::Wgsl(
                    format!("{}\n{BLIT_WGSL}", vdbcook_runtime::DISPLAY_WGSL).into(),
                ),
            });
            let blit_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("vdbcook view blit"),
                entries: &[
                    crate::gpu::texture_entry(0),
                    wgpu::BindGroupLayoutEntry {
                        binding: 1,
                        visibility: wgpu::ShaderStages::FRAGMENT,
                        ty: wgpu::BindingType::Buffer {
                            ty: wgpu::BufferBindingType::Uniform,
                            has_dynamic_offset: false,
                            min_binding_size: None,
                        },
                        count: None,
                    },
                ],
            });
            let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("vdbcook view blit"),
                bind_group_layouts: &[Some(&blit_layout)],
                immediate_size: 0,
            });
            let look_buf = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("vdbcook view blit look"),
                size: 32,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let blit = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("vdbcook view blit"),
                layout: Some(&layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs"),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                primitive: Default::default(),
                depth_stencil: None,
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some("fs"),
                    compilation_options: Default::default(),
                    targets: &[Some(format.into())],
                }),
                multiview_mask: None,
                cache: None,
            });
            let orbit = Orbit::from_camera(&camera);
            let mut state = ViewerState {
                orbit,
                home: orbit,
                frame,
                frames,
                mode,
                playing: false,
                fps,
                clock: 0.0,
                settings: start.settings.clone(),
                display: start.display,
                filter_auto: start.filter_auto,
                transparent: start.transparent,
                srgb_target: format.is_srgb(),
                look_buf,
                renderer,
                size: (0, 0),
                image: None,
                blit,
                blit_layout,
                timer: GpuTimer::new(device, queue),
                timer_pending: false,
                gpu_ms: None,
                _volume: volume,
            };
            state.resize(device, size)?;
            Ok(state)
        }

        /// Re-creates the tracer's image for targets of `size` (nothing is drawn at 0 × 0).
        pub fn resize(&mut self, device: &wgpu::Device, size: (u32, u32)) -> Result<(), String> {
            if size == self.size && self.image.is_some() {
                return Ok(());
            }
            self.size = size;
            self.image = None;
            if size.0 == 0 || size.1 == 0 {
                return Ok(());
            }
            let texture = crate::gpu::texture_2d(
                device,
                "vdbcook view image",
                TRACE_FORMAT,
                wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
                size,
            );
            let view = texture.create_view(&Default::default());
            let target = self
                .renderer
                .texture_target(device, &texture, &view)
                .map_err(|e| format!("GPU target: {e}"))?;
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vdbcook view blit"),
                layout: &self.blit_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::TextureView(&view),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: self.look_buf.as_entire_binding(),
                    },
                ],
            });
            self.image = Some((target, group));
            Ok(())
        }

        pub fn mode(&self) -> Mode {
            Mode::parse(MODE_NAMES[self.mode]).expect("MODE_NAMES are modes")
        }

        pub fn camera(&self) -> Camera {
            self.orbit.camera()
        }

        /// Steps the flip-book by `delta` frames, wrapping around.
        pub fn step(&mut self, delta: i64) {
            let n = self.frames as i64;
            self.frame = (self.frame as i64 + delta).rem_euclid(n) as usize;
        }

        pub fn cycle_mode(&mut self) {
            self.mode = (self.mode + 1) % MODE_NAMES.len();
        }

        pub fn reset_camera(&mut self) {
            self.orbit = self.home;
        }

        /// Multiplies the orbit's distance by `factor` (kept within 1/1000 to 100 times the
        /// framing distance).
        pub fn zoom(&mut self, factor: f64) {
            let r = self.home.radius;
            self.orbit.radius = (self.orbit.radius * factor).clamp(1e-3 * r, 1e2 * r);
        }

        /// Playback: `dt` seconds passed; steps the flip-book at `fps` while playing.
        pub fn advance(&mut self, dt: f64) {
            if !self.playing {
                self.clock = 0.0;
                return;
            }
            self.clock += dt;
            let period = 1.0 / self.fps;
            let steps = (self.clock / period).floor();
            if steps >= 1.0 {
                self.clock -= steps * period;
                self.step((steps as u64 % self.frames as u64) as i64);
            }
        }

        /// Records the frame: the tracer's dispatch into the image, then the blit onto `target`
        /// (a view of a texture of the state's format and size).
        pub fn draw(
            &mut self,
            queue: &wgpu::Queue,
            encoder: &mut wgpu::CommandEncoder,
            target: &wgpu::TextureView,
        ) -> Result<(), String> {
            let Some((image, group)) = &self.image else {
                return Ok(());
            };
            let mode = self.mode();
            let settings = Settings {
                medium: Medium {
                    // Emission is drawn by the shaded modes.
                    emission: self.settings.medium.emission.filter(|_| {
                        matches!(
                            mode,
                            Mode::Density | Mode::SingleScatter | Mode::DeltaTracking | Mode::Lit
                        )
                    }),
                    ..self.settings.medium.clone()
                },
                integrator: Integrator {
                    mode,
                    // `--filter auto` is trilinear in the lit mode only (as `render` resolves it).
                    filter: if self.filter_auto && mode != Mode::Lit {
                        vdbcook_trace::Filter::Nearest
                    } else {
                        self.settings.integrator.filter
                    },
                    ..self.settings.integrator.clone()
                },
                ..self.settings.clone()
            };
            self.renderer
                .render(
                    queue,
                    encoder,
                    image,
                    self.frame,
                    &self.orbit.camera(),
                    &settings,
                )
                .map_err(|e| e.to_string())?;
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("vdbcook view blit"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            let radiance = crate::render::is_radiance(mode);
            let sky = radiance && !self.transparent && crate::render::is_shaded(mode);
            let flags = radiance as u32 | (sky as u32) << 1 | (self.srgb_target as u32) << 2;
            let s = self.settings.lighting.sky;
            let mut look = [0u8; 32];
            look[0..4].copy_from_slice(&self.display.scale().to_le_bytes());
            look[4..8].copy_from_slice(&self.display.tonemap.code().to_le_bytes());
            look[8..12].copy_from_slice(&flags.to_le_bytes());
            for (i, v) in s.iter().enumerate() {
                look[16 + 4 * i..20 + 4 * i].copy_from_slice(&v.to_le_bytes());
            }
            queue.write_buffer(&self.look_buf, 0, &look);
            pass.set_pipeline(&self.blit);
            pass.set_bind_group(0, group, &[]);
            pass.draw(0..3, 0..1);
            Ok(())
        }

        /// One frame, as both paths run it: collects a finished GPU time (never waits), records
        /// [`ViewerState::draw`] (bracketed by the timer when no read is outstanding), submits,
        /// and asks for the timer's read-back.
        pub fn frame(
            &mut self,
            device: &wgpu::Device,
            queue: &wgpu::Queue,
            target: &wgpu::TextureView,
        ) -> Result<(), String> {
            self.collect_time();
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("vdbcook view"),
            });
            let timed = match &self.timer {
                Some(t) if !self.timer_pending => {
                    t.begin(&mut encoder);
                    true
                }
                _ => false,
            };
            self.draw(queue, &mut encoder, target)?;
            if let (true, Some(t)) = (timed, &self.timer) {
                t.end(&mut encoder);
            }
            queue.submit([encoder.finish()]);
            if let (true, Some(t)) = (timed, &self.timer) {
                t.request();
                self.timer_pending = true;
            }
            Ok(())
        }

        /// Takes the GPU time of an earlier frame if its read-back has completed (never waits).
        pub fn collect_time(&mut self) {
            if let (true, Some(t)) = (self.timer_pending, &self.timer) {
                if let Some(ms) = t.try_read_ms() {
                    self.gpu_ms = Some(ms);
                    self.timer_pending = false;
                }
            }
        }

        /// Whether the device has timestamp queries (GPU times); otherwise only CPU times.
        pub fn has_timer(&self) -> bool {
            self.timer.is_some()
        }
    }

    /// Opens the default adapter (compatible with `surface` when there is one), with timestamp
    /// queries and BC textures when it has them.
    fn open_device(
        instance: &wgpu::Instance,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<(wgpu::Adapter, wgpu::Device, wgpu::Queue), String> {
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            compatible_surface: surface,
            ..Default::default()
        }))
        .map_err(|e| {
            format!("no GPU adapter ({e}); on Linux install mesa-vulkan-drivers for a software one")
        })?;
        let wanted = wgpu::Features::TIMESTAMP_QUERY | OPTIONAL_FEATURES;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("vdbcook view"),
            required_limits: adapter.limits(),
            required_features: adapter.features() & wanted,
            ..Default::default()
        }))
        .map_err(|e| format!("cannot open the GPU device: {e}"))?;
        Ok((adapter, device, queue))
    }

    fn describe(adapter: &wgpu::Adapter) -> String {
        crate::gpu::describe_adapter(&adapter.get_info())
    }

    pub fn run(a: &Args) -> Result<(), CliError> {
        let headless = headless_frames(a)?;
        if let Some(shot) = &a.screenshot {
            let input = a.input.to_string_lossy().into_owned();
            let frames = if crate::render::looks_like_vdb(&a.input) {
                vdbcook_vdb::sequence::resolve_inputs(std::slice::from_ref(&input), a.allow_gaps)
                    .unwrap_or_default()
            } else {
                vec![vdbcook_vdb::sequence::Frame {
                    path: a.input.clone(),
                    number: None,
                }]
            };
            crate::output::refuse_inputs(shot, &frames, &[input], "PNG")?;
            crate::output::check_writable(shot, "PNG")?;
        }
        let (asset, _) =
            crate::render::load_input(&a.input, a.grid.clone(), a.allow_gaps, None, &a.look)?;
        // `m` cycles through modes that march: refused whatever mode the view starts in.
        crate::render::refuse_unshowable(&asset, &a.input, Mode::Density)?;
        if a.frame >= asset.frame_count() {
            return Err(CliError::Usage(format!(
                "--frame {} is out of range: {} has {} frame(s)",
                a.frame,
                a.input.display(),
                asset.frame_count()
            )));
        }
        let mode = MODE_NAMES
            .iter()
            .position(|m| *m == a.mode)
            .expect("clap checked");
        match headless {
            Some(n) => headless_run(a, &asset, mode, n),
            None => interactive(a, asset, mode),
        }
    }

    /// `--frames N`: N frames offscreen through [`ViewerState::frame`], the last one read back.
    fn headless_run(a: &Args, asset: &Asset, mode: usize, n: u32) -> Result<(), CliError> {
        let at = |e: String| other(format!("{}: {e}", a.input.display()));
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
        let (adapter, device, queue) = open_device(&instance, None).map_err(other)?;
        let (w, h) = (a.width, a.height);
        let mut state = ViewerState::new(
            &device,
            &queue,
            asset,
            HEADLESS_FORMAT,
            (w, h),
            a.frame,
            mode,
            a.fps,
            &start(a, asset)?,
        )
        .map_err(at)?;
        let target = crate::gpu::texture_2d(
            &device,
            "vdbcook view headless target",
            HEADLESS_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            (w, h),
        );
        let target_view = target.create_view(&Default::default());
        let mut per_frame = Vec::new();
        for i in 0..n {
            if i > 0 {
                state.step(1);
                state.orbit.rotate(ORBIT_STEP_DEG.to_radians(), 0.0);
            }
            let t = Instant::now();
            state.frame(&device, &queue, &target_view).map_err(at)?;
            // Headless only: wait for the frame so that its CPU time and GPU time are its own.
            device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| other(format!("GPU: {e}")))?;
            let cpu_ms = t.elapsed().as_secs_f64() * 1e3;
            state.gpu_ms = None;
            state.collect_time();
            per_frame.push((state.frame, state.gpu_ms, cpu_ms));
            if !a.json {
                let gpu = state
                    .gpu_ms
                    .map(|g| format!("GPU {g:.3} ms, "))
                    .unwrap_or_default();
                println!(
                    "frame {i}: flip-book frame {}, {}: {gpu}CPU {cpu_ms:.3} ms",
                    state.frame, MODE_NAMES[state.mode]
                );
            }
        }
        if let Some(shot) = &a.screenshot {
            let rgba = read_back(&device, &queue, &target);
            crate::render::write_png(shot, w, h, &rgba)?;
        }
        let c = state.camera();
        if a.json {
            let doc = json!({
                "asset": a.input.display().to_string(),
                "screenshot": a.screenshot.as_ref().map(|p| p.display().to_string()),
                "width": w,
                "height": h,
                "frames": n,
                "frame": state.frame,
                "mode": MODE_NAMES[state.mode],
                "format": format!("{HEADLESS_FORMAT:?}"),
                "adapter": describe(&adapter),
                "timestamps": state.has_timer(),
                "orbit_step_deg": ORBIT_STEP_DEG,
                "per_frame": per_frame.iter().map(|(f, g, c)| json!({
                    "frame": f, "gpu_ms": g, "cpu_ms": c,
                })).collect::<Vec<_>>(),
                "camera": {
                    "eye": c.eye, "look_at": c.look_at, "up": c.up, "fov_y_deg": c.fov_y_deg,
                },
            });
            println!("{}", serde_json::to_string_pretty(&doc).expect("json"));
        } else {
            if let Some(shot) = &a.screenshot {
                println!(
                    "wrote {} ({w}x{h}, {}, frame {}) on {}",
                    shot.display(),
                    MODE_NAMES[state.mode],
                    state.frame,
                    describe(&adapter)
                );
            }
            println!(
                "camera: --camera {},{},{},{},{},{},{}",
                c.eye[0], c.eye[1], c.eye[2], c.look_at[0], c.look_at[1], c.look_at[2], c.fov_y_deg
            );
        }
        Ok(())
    }

    /// The target's pixels as RGBA8 (its own submission; waits).
    fn read_back(device: &wgpu::Device, queue: &wgpu::Queue, target: &wgpu::Texture) -> Vec<u8> {
        let mut encoder = device.create_command_encoder(&Default::default());
        let readback = crate::gpu::TextureReadback::record(device, &mut encoder, target, 4);
        queue.submit([encoder.finish()]);
        let mut rgba = readback.read(device).expect("read-back");
        if matches!(
            target.format(),
            wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
        ) {
            for p in rgba.chunks_exact_mut(4) {
                p.swap(0, 2);
            }
        }
        rgba
    }

    /// The surface format: [`HEADLESS_FORMAT`] when offered, else another 8-bit or half-float
    /// format the blit can write (an sRGB one is handled by the blit).
    fn pick_surface_format(formats: &[wgpu::TextureFormat]) -> Option<wgpu::TextureFormat> {
        use wgpu::TextureFormat as F;
        [
            F::Bgra8Unorm,
            F::Rgba8Unorm,
            F::Bgra8UnormSrgb,
            F::Rgba8UnormSrgb,
            F::Rgba16Float,
        ]
        .into_iter()
        .find(|f| formats.contains(f))
        .or_else(|| formats.first().copied())
    }

    /// The window, its surface and the device, once the event loop has resumed.
    struct Gfx {
        window: Arc<Window>,
        surface: wgpu::Surface<'static>,
        config: wgpu::SurfaceConfiguration,
        device: wgpu::Device,
        queue: wgpu::Queue,
        state: ViewerState,
        adapter: String,
    }

    struct App {
        asset: Asset,
        args_size: (u32, u32),
        frame: usize,
        mode: usize,
        fps: f64,
        start: Start,
        gfx: Option<Gfx>,
        error: Option<String>,
        dragging: bool,
        cursor: Option<(f64, f64)>,
        last: Option<Instant>,
        /// Smoothed frame-to-frame interval (ms).
        cpu_ms: Option<f64>,
    }

    impl App {
        fn start(&mut self, event_loop: &ActiveEventLoop) -> Result<Gfx, String> {
            let attrs = Window::default_attributes()
                .with_title("vdbcook view")
                .with_inner_size(PhysicalSize::new(self.args_size.0, self.args_size.1));
            let window = Arc::new(
                event_loop
                    .create_window(attrs)
                    .map_err(|e| format!("cannot open a window: {e}"))?,
            );
            let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_with_display_handle(
                Box::new(window.clone()),
            ));
            let surface = instance
                .create_surface(window.clone())
                .map_err(|e| format!("cannot create a surface: {e}"))?;
            let (adapter, device, queue) = open_device(&instance, Some(&surface))?;
            let size = window.inner_size();
            let caps = surface.get_capabilities(&adapter);
            let format = pick_surface_format(&caps.formats)
                .ok_or("the surface offers no format".to_string())?;
            let mut config = surface
                .get_default_config(&adapter, size.width.max(1), size.height.max(1))
                .ok_or("the surface is not supported by the adapter".to_string())?;
            config.format = format;
            config.present_mode = wgpu::PresentMode::AutoVsync;
            surface.configure(&device, &config);
            let state = ViewerState::new(
                &device,
                &queue,
                &self.asset,
                format,
                (config.width, config.height),
                self.frame,
                self.mode,
                self.fps,
                &self.start,
            )?;
            let adapter = describe(&adapter);
            eprintln!(
                "vdbcook view on {adapter}, surface {format:?}: left-drag orbits, wheel zooms, \
                 space plays/pauses, left/right step, m cycles modes, r resets the camera, \
                 Esc quits"
            );
            Ok(Gfx {
                window,
                surface,
                config,
                device,
                queue,
                state,
                adapter,
            })
        }

        fn fail(&mut self, event_loop: &ActiveEventLoop, e: String) {
            self.error = Some(e);
            event_loop.exit();
        }

        fn redraw(&mut self) -> Result<(), String> {
            let now = Instant::now();
            let dt = self
                .last
                .map(|l| now.duration_since(l).as_secs_f64())
                .unwrap_or(0.0);
            self.last = Some(now);
            if dt > 0.0 {
                let ms = dt * 1e3;
                self.cpu_ms = Some(self.cpu_ms.map_or(ms, |p| 0.9 * p + 0.1 * ms));
            }
            let Some(g) = &mut self.gfx else {
                return Ok(());
            };
            g.state.advance(dt);
            // Drive the timer's read-back without waiting.
            let _ = g.device.poll(wgpu::PollType::Poll);
            let texture = match g.surface.get_current_texture() {
                wgpu::CurrentSurfaceTexture::Success(t)
                | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
                wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                    g.surface.configure(&g.device, &g.config);
                    return Ok(());
                }
                _ => return Ok(()),
            };
            let view = texture.texture.create_view(&Default::default());
            g.state.frame(&g.device, &g.queue, &view)?;
            g.window.pre_present_notify();
            g.queue.present(texture);
            let s = &g.state;
            let time = match (s.gpu_ms, s.has_timer()) {
                (Some(ms), _) => format!("GPU {ms:.2} ms"),
                (None, true) => "GPU … ms".into(),
                (None, false) => format!("CPU {:.2} ms", self.cpu_ms.unwrap_or(0.0)),
            };
            let fps = self.cpu_ms.map(|ms| 1e3 / ms).unwrap_or(0.0);
            g.window.set_title(&format!(
                "vdbcook view — frame {} of {} — {} — {time} — {fps:.0} fps{} — {}",
                s.frame,
                s.frames,
                MODE_NAMES[s.mode],
                if s.playing { "" } else { " — paused" },
                g.adapter
            ));
            Ok(())
        }
    }

    impl ApplicationHandler for App {
        fn resumed(&mut self, event_loop: &ActiveEventLoop) {
            if self.gfx.is_some() {
                return;
            }
            match self.start(event_loop) {
                Ok(g) => {
                    g.window.request_redraw();
                    self.gfx = Some(g);
                }
                Err(e) => self.fail(event_loop, e),
            }
        }

        fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
            match event {
                WindowEvent::CloseRequested => event_loop.exit(),
                WindowEvent::Resized(size) => {
                    if let Some(g) = &mut self.gfx {
                        if size.width > 0 && size.height > 0 {
                            g.config.width = size.width;
                            g.config.height = size.height;
                            g.surface.configure(&g.device, &g.config);
                        }
                        if let Err(e) = g.state.resize(&g.device, (size.width, size.height)) {
                            self.fail(event_loop, e);
                        }
                    }
                }
                WindowEvent::RedrawRequested => {
                    if let Err(e) = self.redraw() {
                        self.fail(event_loop, e);
                    }
                }
                WindowEvent::KeyboardInput { event, .. } if event.state.is_pressed() => {
                    let Some(g) = &mut self.gfx else { return };
                    let s = &mut g.state;
                    match event.logical_key.as_ref() {
                        Key::Named(NamedKey::Escape) => event_loop.exit(),
                        Key::Named(NamedKey::Space) => s.playing = !s.playing,
                        Key::Named(NamedKey::ArrowRight) => s.step(1),
                        Key::Named(NamedKey::ArrowLeft) => s.step(-1),
                        Key::Character(c) if c.eq_ignore_ascii_case("m") => s.cycle_mode(),
                        Key::Character(c) if c.eq_ignore_ascii_case("r") => s.reset_camera(),
                        _ => {}
                    }
                }
                WindowEvent::MouseInput {
                    state,
                    button: MouseButton::Left,
                    ..
                } => self.dragging = state == ElementState::Pressed,
                WindowEvent::CursorMoved { position, .. } => {
                    let p = (position.x, position.y);
                    if let (true, Some(prev), Some(g)) = (self.dragging, self.cursor, &mut self.gfx)
                    {
                        g.state
                            .orbit
                            .rotate(-(p.0 - prev.0) * 0.01, (p.1 - prev.1) * 0.01);
                    }
                    self.cursor = Some(p);
                }
                WindowEvent::CursorLeft { .. } => self.cursor = None,
                WindowEvent::MouseWheel { delta, .. } => {
                    let lines = match delta {
                        MouseScrollDelta::LineDelta(_, y) => y as f64,
                        MouseScrollDelta::PixelDelta(p) => p.y / 40.0,
                    };
                    if let Some(g) = &mut self.gfx {
                        g.state.zoom(0.9f64.powf(lines));
                    }
                }
                _ => {}
            }
        }

        fn about_to_wait(&mut self, _: &ActiveEventLoop) {
            // Continuous redraw: playback, and a fresh frame time in the title (presenting with
            // vsync paces it).
            if let Some(g) = &self.gfx {
                g.window.request_redraw();
            }
        }
    }

    fn interactive(a: &Args, asset: Asset, mode: usize) -> Result<(), CliError> {
        let event_loop = EventLoop::new().map_err(|e| {
            other(format!(
                "cannot open a window ({e}); without a display use --frames N --screenshot OUT.png"
            ))
        })?;
        event_loop.set_control_flow(ControlFlow::Poll);
        let start = start(a, &asset)?;
        let mut app = App {
            asset,
            args_size: (a.width, a.height),
            frame: a.frame,
            mode,
            fps: a.fps,
            start,
            gfx: None,
            error: None,
            dragging: false,
            cursor: None,
            last: None,
            cpu_ms: None,
        };
        event_loop
            .run_app(&mut app)
            .map_err(|e| other(format!("window event loop: {e}")))?;
        match app.error {
            Some(e) => Err(other(format!("{}: {e}", a.input.display()))),
            None => Ok(()),
        }
    }
}

#[cfg(all(test, feature = "view"))]
mod tests {
    use super::*;
    use vdbcook_runtime::Camera;

    #[test]
    fn orbit_reproduces_the_camera_and_turns_about_the_vertical() {
        let c = Camera {
            eye: [4.0, 3.0, 5.0],
            look_at: [1.0, 1.0, 1.0],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 40.0,
        };
        let mut o = Orbit::from_camera(&c);
        let back = o.camera();
        for i in 0..3 {
            assert!((back.eye[i] - c.eye[i]).abs() < 1e-12, "{back:?}");
        }
        o.rotate(std::f64::consts::PI, 0.0);
        let half = o.camera();
        // Half a turn: the opposite side at the same height and distance.
        assert!((half.eye[0] - (2.0 - c.eye[0])).abs() < 1e-9, "{half:?}");
        assert!((half.eye[1] - c.eye[1]).abs() < 1e-9);
        assert!((half.eye[2] - (2.0 - c.eye[2])).abs() < 1e-9, "{half:?}");
        o.rotate(0.0, 10.0);
        assert!(o.pitch <= 1.55);
    }
}
