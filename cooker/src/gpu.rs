//! The GPU side of the CLI (`render --backend gpu`, the GPU trace times of `report`): opens the
//! default adapter headless, uploads an asset through the runtime crate (`vdbcook-runtime`, the
//! same calls an engine makes), renders into a buffer target and reads the image back as a
//! `vdbcook_trace::Image`, so GPU and CPU images compare directly. Times come from timestamp
//! queries around the runtime's pass when the adapter has them, and from submit-to-idle wall
//! time always.
//!
//! Built with the `gpu` feature (on by default); without it `open` says so.

use vdbcook_asset::Asset;
use vdbcook_trace::{Camera, Image, Integrator, RenderSettings};

/// One rendered image and its times (one entry per timed run, after one warm-up).
pub struct GpuRender {
    pub image: Image,
    /// GPU time of the runtime's pass (timestamp queries), ms; empty without the feature.
    pub gpu_ms: Vec<f64>,
    /// Submit-and-wait wall time, ms.
    pub wall_ms: Vec<f64>,
}

/// An IEEE 754 half float's value (what an `Rgba16Float` read-back holds).
pub fn f16_to_f32(h: u16) -> f32 {
    let (s, e, m) = ((h >> 15) & 1, (h >> 10) & 0x1f, (h & 0x3ff) as f32);
    let v = match e {
        0 => m * 2f32.powi(-24),
        31 if m == 0.0 => f32::INFINITY,
        31 => f32::NAN,
        _ => (1.0 + m / 1024.0) * 2f32.powi(e as i32 - 15),
    };
    if s == 1 {
        -v
    } else {
        v
    }
}

#[cfg(feature = "gpu")]
mod imp {
    use std::time::Instant;

    use vdbcook_runtime::{GpuTimer, GpuVolume, Renderer};

    use super::*;

    /// A copy of a texture's mip 0 on its way to the CPU: [`TextureReadback::record`] puts the
    /// copy into the caller's encoder; after that encoder is submitted, [`TextureReadback::read`]
    /// waits for it and returns the rows packed tightly (`width · texel_bytes` bytes each,
    /// top row first). Blocking, so for the CLI (`render` over a scene, `view --screenshot`),
    /// never the runtime.
    pub struct TextureReadback {
        buffer: wgpu::Buffer,
        /// Bytes per row in the buffer (padded to `COPY_BYTES_PER_ROW_ALIGNMENT`) and packed.
        row: usize,
        packed: usize,
        height: usize,
    }

    /// A 2D texture of `size` (one mip, one sample): the CLI's one way to make its targets,
    /// images and scene plates.
    pub fn texture_2d(
        device: &wgpu::Device,
        label: &str,
        format: wgpu::TextureFormat,
        usage: wgpu::TextureUsages,
        (width, height): (u32, u32),
    ) -> wgpu::Texture {
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    }

    /// A fragment shader's unfilterable 2D float texture at `binding` (the CLI's passes read
    /// their images with `textureLoad`).
    pub fn texture_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
        wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        }
    }

    /// A render pass that clears `color` to black and `depth` to `depth_clear`, stored.
    pub fn cleared_pass<'e>(
        encoder: &'e mut wgpu::CommandEncoder,
        label: &str,
        color: &wgpu::TextureView,
        depth: &wgpu::TextureView,
        depth_clear: f32,
    ) -> wgpu::RenderPass<'e> {
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(label),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: color,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(depth_clear),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    impl TextureReadback {
        pub fn record(
            device: &wgpu::Device,
            encoder: &mut wgpu::CommandEncoder,
            texture: &wgpu::Texture,
            texel_bytes: u32,
        ) -> TextureReadback {
            let (w, h) = (texture.width(), texture.height());
            let row = (w * texel_bytes).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("vdbcook read-back"),
                size: row as u64 * h as u64,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            encoder.copy_texture_to_buffer(
                texture.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(row),
                        rows_per_image: None,
                    },
                },
                texture.size(),
            );
            TextureReadback {
                buffer,
                row: row as usize,
                packed: (w * texel_bytes) as usize,
                height: h as usize,
            }
        }

        /// Waits for the copy (its encoder must have been submitted) and returns the rows.
        pub fn read(self, device: &wgpu::Device) -> Result<Vec<u8>, String> {
            let slice = self.buffer.slice(..);
            slice.map_async(wgpu::MapMode::Read, |r| r.expect("map read-back"));
            device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| format!("GPU: {e}"))?;
            let data = slice
                .get_mapped_range()
                .map_err(|e| format!("GPU read-back: {e}"))?;
            Ok((0..self.height)
                .flat_map(|y| &data[y * self.row..][..self.packed])
                .copied()
                .collect())
        }
    }

    /// An adapter's name and backend, marked when it is a software rasterizer (the CLI's one
    /// wording for `render`, `report` and `view`).
    pub fn describe_adapter(info: &wgpu::AdapterInfo) -> String {
        let soft = if info.device_type == wgpu::DeviceType::Cpu {
            ", software"
        } else {
            ""
        };
        format!("{} ({:?}{soft})", info.name, info.backend)
    }

    /// An open device and what it is.
    pub struct Gpu {
        device: wgpu::Device,
        queue: wgpu::Queue,
        info: wgpu::AdapterInfo,
    }

    /// An asset on the device, ready to render.
    pub struct Uploaded {
        volume: GpuVolume,
        renderer: Renderer,
    }

    impl Uploaded {
        /// Bytes of the payload and tree on the device.
        pub fn gpu_bytes(&self) -> u64 {
            self.volume.gpu_bytes()
        }
        /// How the payload was laid out (the runtime's choice for this adapter).
        pub fn layout(&self) -> String {
            self.volume.describe()
        }
    }

    impl Gpu {
        /// The default adapter (high performance), with timestamp queries and BC textures
        /// when it has them. An error (not a panic) when there is none.
        pub fn open() -> Result<Gpu, String> {
            let instance =
                wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
            let adapter =
                pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                    power_preference: wgpu::PowerPreference::HighPerformance,
                    ..Default::default()
                }))
                .map_err(|e| {
                    format!(
                    "no GPU adapter ({e}); on Linux install mesa-vulkan-drivers for a software \
                     one, or use --backend cpu"
                )
                })?;
            // BC textures when the adapter has them (the runtime picks its layout from them).
            let wanted = wgpu::Features::TIMESTAMP_QUERY | vdbcook_runtime::OPTIONAL_FEATURES;
            let features = adapter.features() & wanted;
            let (device, queue) =
                pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
                    label: Some("vdbcook"),
                    required_limits: adapter.limits(),
                    required_features: features,
                    ..Default::default()
                }))
                .map_err(|e| format!("cannot open the GPU device: {e}"))?;
            Ok(Gpu {
                device,
                queue,
                info: adapter.get_info(),
            })
        }

        /// The adapter's name and backend, marked when it is a software rasterizer.
        pub fn describe(&self) -> String {
            describe_adapter(&self.info)
        }

        /// Whether the adapter runs on the CPU (lavapipe, WARP, SwiftShader).
        pub fn is_software(&self) -> bool {
            self.info.device_type == wgpu::DeviceType::Cpu
        }

        /// The open device, for work beyond `render` (the engine drawer of `render --depth`).
        pub fn device(&self) -> &wgpu::Device {
            &self.device
        }

        /// The device's queue.
        pub fn queue(&self) -> &wgpu::Queue {
            &self.queue
        }

        pub fn upload(&self, asset: &Asset) -> Result<Uploaded, String> {
            self.upload_for(asset, false)
        }

        /// As [`Gpu::upload`], the renderer compiled with emission when `emission`.
        pub fn upload_for(&self, asset: &Asset, emission: bool) -> Result<Uploaded, String> {
            let volume = GpuVolume::upload(&self.device, &self.queue, asset)
                .map_err(|e| format!("GPU upload: {e}"))?;
            let format = wgpu::TextureFormat::Rgba8Unorm;
            let renderer = if emission {
                Renderer::with_emission(&self.device, &volume, format)
            } else {
                Renderer::new(&self.device, &volume, format)
            }
            .map_err(|e| format!("GPU renderer: {e}"))?;
            Ok(Uploaded { volume, renderer })
        }

        /// Renders `settings.frame` once to warm up, then `runs` timed times; returns the last
        /// image. Delta tracking runs in dispatches of at most [`SAMPLES_PER_DISPATCH`] samples
        /// (the runtime's progressive `first_sample` batches), one submission each, averaged
        /// here weighted by their sample counts; a run's times are the sums over its batches.
        pub fn render(
            &self,
            up: &Uploaded,
            camera: &Camera,
            settings: &RenderSettings,
            runs: usize,
        ) -> Result<GpuRender, String> {
            let (w, h) = (settings.output.width, settings.output.height);
            let target = up
                .renderer
                .buffer_target(&self.device, w, h)
                .map_err(|e| format!("GPU target: {e}"))?;
            let batches = sample_batches(settings);
            // `None` when the device has no timestamp queries: wall time only.
            let timer = GpuTimer::new(&self.device, &self.queue);
            let (mut gpu_ms, mut wall_ms) = (Vec::new(), Vec::new());
            let mut image = None;
            for run in 0..=runs {
                let (mut wall, mut gpu) = (0.0, Some(0.0));
                for batch in &batches {
                    let start = Instant::now();
                    let mut encoder = self.device.create_command_encoder(&Default::default());
                    if let Some(t) = &timer {
                        t.begin(&mut encoder);
                    }
                    up.renderer
                        .render_to_buffer(
                            &self.queue,
                            &mut encoder,
                            &target,
                            settings.output.frame,
                            camera,
                            batch,
                        )
                        .map_err(|e| e.to_string())?;
                    if let Some(t) = &timer {
                        t.end(&mut encoder);
                    }
                    self.queue.submit([encoder.finish()]);
                    self.device
                        .poll(wgpu::PollType::wait_indefinitely())
                        .map_err(|e| format!("GPU: {e}"))?;
                    wall += start.elapsed().as_secs_f64() * 1e3;
                    gpu = gpu
                        .zip(timer.as_ref().and_then(|t| t.read_ms(&self.device)))
                        .map(|(a, b)| a + b);
                    if run == runs {
                        let r = target.read(&self.device, &self.queue);
                        let weight =
                            batch.integrator.spp as f32 / settings.integrator.spp.max(1) as f32;
                        let img = Image {
                            width: r.width,
                            height: r.height,
                            rgba: r.rgba,
                            value: r.value,
                        };
                        image = Some(match image {
                            None if batches.len() == 1 => img,
                            acc => add_scaled(acc, img, weight),
                        });
                    }
                }
                if run > 0 {
                    wall_ms.push(wall);
                    gpu_ms.extend(gpu);
                }
            }
            Ok(GpuRender {
                image: image.expect("at least one batch"),
                gpu_ms,
                wall_ms,
            })
        }
    }

    /// `acc + k · img` (`k · img` without `acc`).
    fn add_scaled(acc: Option<Image>, mut img: Image, k: f32) -> Image {
        let Some(mut acc) = acc else {
            img.rgba
                .iter_mut()
                .chain(img.value.iter_mut())
                .for_each(|v| *v *= k);
            return img;
        };
        let sums = acc.rgba.iter_mut().chain(acc.value.iter_mut());
        for (a, b) in sums.zip(img.rgba.iter().chain(&img.value)) {
            *a += k * b;
        }
        acc
    }
}

/// Most samples per pixel one GPU dispatch of delta tracking takes. On lavapipe (Mesa 22.3,
/// LLVM 15) a dispatch of more than about 72 samples per pixel comes back biased dark (fewer
/// escaped paths; 256 samples in one dispatch gave about half the light of the CPU's same
/// samples, while every 64-sample window matched it to 2e-7); the cause was not found in the
/// shader. Short dispatches also keep one submission well under an OS GPU watchdog.
pub const SAMPLES_PER_DISPATCH: u32 = 64;

/// `settings` split into progressive batches (`first_sample`, `spp`) of at most
/// [`SAMPLES_PER_DISPATCH`] samples for delta tracking; any other mode as it is.
pub fn sample_batches(settings: &RenderSettings) -> Vec<RenderSettings> {
    if settings.integrator.mode != vdbcook_trace::Mode::DeltaTracking
        || settings.integrator.spp <= SAMPLES_PER_DISPATCH
    {
        return vec![settings.clone()];
    }
    (0..settings.integrator.spp)
        .step_by(SAMPLES_PER_DISPATCH as usize)
        .map(|k| RenderSettings {
            integrator: Integrator {
                first_sample: settings.integrator.first_sample.wrapping_add(k),
                spp: SAMPLES_PER_DISPATCH.min(settings.integrator.spp - k),
                ..settings.integrator.clone()
            },
            ..settings.clone()
        })
        .collect()
}

#[cfg(not(feature = "gpu"))]
mod imp {
    use super::*;

    pub struct Gpu;
    pub struct Uploaded;

    impl Uploaded {
        pub fn gpu_bytes(&self) -> u64 {
            0
        }
        pub fn layout(&self) -> String {
            String::new()
        }
    }

    impl Gpu {
        pub fn open() -> Result<Gpu, String> {
            Err("this vdbcook was built without the `gpu` feature; use --backend cpu".into())
        }
        pub fn describe(&self) -> String {
            String::new()
        }
        pub fn is_software(&self) -> bool {
            true
        }
        pub fn upload(&self, _: &Asset) -> Result<Uploaded, String> {
            Err("built without the `gpu` feature".into())
        }
        pub fn upload_for(&self, _: &Asset, _: bool) -> Result<Uploaded, String> {
            Err("built without the `gpu` feature".into())
        }
        pub fn render(
            &self,
            _: &Uploaded,
            _: &Camera,
            _: &RenderSettings,
            _: usize,
        ) -> Result<GpuRender, String> {
            Err("built without the `gpu` feature".into())
        }
    }
}

pub use imp::Gpu;
#[cfg(feature = "gpu")]
pub use imp::{cleared_pass, describe_adapter, texture_2d, texture_entry, TextureReadback};

/// Containers usually run without `XDG_RUNTIME_DIR`; the Vulkan loader's window-system probes
/// then print "error: XDG_RUNTIME_DIR is invalid or not set" on stderr although nothing failed.
/// When it is unset, point it at a private folder (`$TMPDIR/vdbcook-runtime-UID`, mode 0700,
/// ours). Called at start-up, before any thread, by the commands that may open the GPU.
pub fn private_runtime_dir() {
    #[cfg(unix)]
    {
        use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
        if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
            return;
        }
        // SAFETY: getuid has no preconditions.
        let uid = unsafe { libc::getuid() };
        let dir = std::env::temp_dir().join(format!("vdbcook-runtime-{uid}"));
        let _ = std::fs::DirBuilder::new().mode(0o700).create(&dir);
        let ours = std::fs::symlink_metadata(&dir)
            .is_ok_and(|m| m.is_dir() && m.uid() == uid && m.permissions().mode() & 0o077 == 0);
        if ours {
            // Single-threaded here (start-up), so changing the environment is sound.
            std::env::set_var("XDG_RUNTIME_DIR", &dir);
        }
    }
}
