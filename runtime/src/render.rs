//! The renderer: created once per volume and target format (shader module, pipeline, bind
//! groups, the parameter uniform); each render validates `(frame, camera, settings)` on the CPU,
//! writes the one uniform, and records one compute dispatch into the caller's encoder. Targets
//! (a storage-capable texture, or a buffer of RGBA + raw values for tests and tools) are bound
//! once when they are created, so rendering creates nothing.

use bytemuck::{Pod, Zeroable};

use vdbcook_scene::{
    depth_range, pixel_angle, Affine, DiffusionInputs, Filter, LightGrid, March, Mode, MsModel,
    LIT_NEAR_DEPTH, MAX_SIDE,
};

use crate::light::{FrameAt, LightParams, LightPass};
use crate::shading::{LitPlace, ShadingUniform};
use crate::upload::{buffer_entry, Bound, GpuVolume};
use crate::{Camera, Result, RuntimeError, Settings, TRACE_WGSL};

/// The `Params` uniform of `trace.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct Params {
    eye_index: [f32; 4],
    forward: [f32; 4],
    right: [f32; 4],
    up: [f32; 4],
    inv_a0: [f32; 4],
    inv_a1: [f32; 4],
    inv_a2: [f32; 4],
    extent: [f32; 4],
    /// xyz: the frame's content box `[lo, hi)` in index space (empty: lo > hi), which the
    /// sampling modes clip their rays to.
    content_lo: [f32; 4],
    content_hi: [f32; 4],
    width: u32,
    height: u32,
    mode: u32,
    frame_root: u32,
    absorb: f32,
    cutoff: f32,
    near: f32,
    far: f32,
    value_max: f32,
    out_flags: u32,
    shadow_step: f32,
    gain: f32,
    spp: u32,
    first_sample: u32,
    /// Emission read from this channel (`Emission::channel`; 0: from the rendered grid, by the
    /// modes' own marches).
    emit_channel: u32,
    _pad0: u32,
    /// With `emit_channel`: the cell box `[lo, hi)` where that channel may glow (empty: lo > hi).
    emit_lo: [f32; 4],
    emit_hi: [f32; 4],
    /// The lit mode's primary levels of detail (`vdbcook_scene::level_start`): levels read (1:
    /// full resolution only), the root-offset stride between levels, the camera's pixel angle
    /// (f32 bits), 1 for the voxel march (`March::resolve`; the pipeline variant, `LIT_VOXELS`,
    /// decides which march runs).
    lod: [u32; 4],
    /// The light, phase, emission, step and seed (`ShadingUniform`, the drawer's packing too).
    shading: ShadingUniform,
    /// The volume's extinction, albedo, light direction and light volume (`LitPlace`).
    place: LitPlace,
}

const WORKGROUP: u32 = 8;
const OUT_TEXTURE: u32 = 1;
const OUT_BUFFER: u32 = 2;

/// A texture the renderer writes (format as the renderer's, `STORAGE_BINDING` usage).
pub struct TextureTarget {
    bind_group: wgpu::BindGroup,
    width: u32,
    height: u32,
}

/// A storage buffer target: `width·height` RGBA (f32 × 4) followed by `width·height` raw values
/// (the mode's quantity, as `vdbcook_trace::Image::value`).
pub struct BufferTarget {
    bind_group: wgpu::BindGroup,
    buffer: wgpu::Buffer,
    readback: wgpu::Buffer,
    width: u32,
    height: u32,
}

/// A target's image read back: RGBA (`width·height·4`) and raw values (`width·height`).
#[derive(Debug, Clone, PartialEq)]
pub struct Readback {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<f32>,
    pub value: Vec<f32>,
}

impl BufferTarget {
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    /// Copies the image back (its own submission; waits for the GPU).
    pub fn read(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Readback {
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("vdbcook readback"),
        });
        enc.copy_buffer_to_buffer(&self.buffer, 0, &self.readback, 0, self.buffer.size());
        queue.submit([enc.finish()]);
        let slice = self.readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |r| r.expect("map readback buffer"));
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("device poll");
        let floats: Vec<f32> = {
            let data = crate::gpu_compat::mapped_range(&slice).expect("mapped range");
            bytemuck::cast_slice(&data).to_vec()
        };
        self.readback.unmap();
        let n = self.width as usize * self.height as usize;
        Readback {
            width: self.width,
            height: self.height,
            rgba: floats[..4 * n].to_vec(),
            value: floats[4 * n..5 * n].to_vec(),
        }
    }
}

/// The tracer for one uploaded volume and one target format.
pub struct Renderer {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    params_group: wgpu::BindGroup,
    target_layout: wgpu::BindGroupLayout,
    format: wgpu::TextureFormat,
    dummy_texture_view: wgpu::TextureView,
    dummy_buffer: wgpu::Buffer,
    xf: Affine,
    vol: Bound,
    /// Whether the pipeline was compiled with emission.
    emission: bool,
    /// The lit mode's light-volume pass (and the device its buffers are made on, when a lit
    /// render first needs them).
    light: LightPass,
    device: wgpu::Device,
    /// Groups 1–3 of the pipelines, and the lit mode's variants (made on first use), indexed by
    /// [`LitVariant::index`] (index 0 is `pipeline`).
    layouts: [wgpu::BindGroupLayout; 3],
    lit_variants: [std::sync::OnceLock<wgpu::ComputePipeline>; 8],
    /// The light volumes of the last lit render, held until the next render (one render per
    /// submission: by then it was submitted), so no later build overwrites them first.
    last_light: std::sync::Mutex<Option<std::sync::Arc<crate::light::LightEntry>>>,
}

/// The parts of the lit march compiled into a pipeline (`trace.wgsl`'s `LIT_*` constants):
/// code that is present costs lavapipe (software Vulkan) time even where it never runs (the
/// near field doubled the lit march there on a frame that never walked it), so each render
/// uses the pipeline with only what it can reach.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct LitVariant {
    /// `Filter::Trilinear`.
    trilinear: bool,
    /// The near field toward the sun (`sun_near` > 0 on a frame dense enough for some sample to
    /// walk it: `vdbcook_scene::LIT_NEAR_DEPTH`).
    near: bool,
    /// `March::Voxels`.
    voxels: bool,
}

impl LitVariant {
    fn index(self) -> usize {
        self.trilinear as usize | (self.near as usize) << 1 | (self.voxels as usize) << 2
    }
}

/// The tracer's WGSL for a target format, with emission and the lit march's parts compiled in
/// or out.
fn trace_source(format: &str, emission: bool, lit: LitVariant) -> String {
    let flag = |on: bool| if on { "true" } else { "false" };
    format!(
        "{}\n{}",
        crate::shading::lit_source(3, "params.shading"),
        TRACE_WGSL
            .replace("{{TARGET_FORMAT}}", format)
            .replace("{{EMISSION}}", flag(emission))
            .replace("{{TRILINEAR}}", flag(lit.trilinear))
            .replace("{{LIT_NEAR}}", flag(lit.near))
            .replace("{{LIT_VOXELS}}", flag(lit.voxels))
    )
}

/// [`trace_source`] compiled.
fn trace_module(
    device: &wgpu::Device,
    format: &str,
    emission: bool,
    lit: LitVariant,
) -> wgpu::ShaderModule {
    let source = trace_source(format, emission, lit);
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("vdbcook trace"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

/// The WGSL name of a storage-texture format the renderer can write.
fn wgsl_format(f: wgpu::TextureFormat) -> Option<&'static str> {
    match f {
        wgpu::TextureFormat::Rgba8Unorm => Some("rgba8unorm"),
        wgpu::TextureFormat::Rgba16Float => Some("rgba16float"),
        wgpu::TextureFormat::Rgba32Float => Some("rgba32float"),
        _ => None,
    }
}

impl Renderer {
    /// Builds the pipeline for `volume` writing textures of `format` (`Rgba8Unorm`,
    /// `Rgba16Float` or `Rgba32Float`; buffer targets work with any of them). Emission is
    /// compiled out of this pipeline (it cost 1.4–1.7× in the density mode on lavapipe even
    /// when off); settings with `emission` need [`Renderer::with_emission`].
    pub fn new(
        device: &wgpu::Device,
        volume: &GpuVolume,
        format: wgpu::TextureFormat,
    ) -> Result<Renderer> {
        Renderer::build(device, volume, format, false)
    }

    /// As [`Renderer::new`], with blackbody emission compiled in (`Settings::emission`, in the
    /// density, scatter and delta modes); renders without emission too, a little slower.
    pub fn with_emission(
        device: &wgpu::Device,
        volume: &GpuVolume,
        format: wgpu::TextureFormat,
    ) -> Result<Renderer> {
        Renderer::build(device, volume, format, true)
    }

    fn build(
        device: &wgpu::Device,
        volume: &GpuVolume,
        format: wgpu::TextureFormat,
        emission: bool,
    ) -> Result<Renderer> {
        let Some(fmt) = wgsl_format(format) else {
            return Err(RuntimeError::Target(format!(
                "format {format:?} (storage formats: Rgba8Unorm, Rgba16Float, Rgba32Float)"
            )));
        };
        let xf = Affine::cells(volume.index_to_world())?;
        let module = trace_module(device, fmt, emission, LitVariant::default());
        let params_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vdbcook params"),
            entries: &[buffer_entry(0, wgpu::BufferBindingType::Uniform)],
        });
        let target_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vdbcook target"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                    count: None,
                },
                buffer_entry(1, wgpu::BufferBindingType::Storage { read_only: false }),
            ],
        });
        let light = LightPass::new(device, volume);
        let pipeline = volume.compute_pipeline(
            device,
            "vdbcook trace",
            &module,
            "trace_main",
            &[&params_layout, &target_layout, &light.read_layout],
        );
        let layouts = [
            params_layout.clone(),
            target_layout.clone(),
            light.read_layout.clone(),
        ];
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vdbcook params"),
            size: std::mem::size_of::<Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let params_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vdbcook params"),
            layout: &params_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: params.as_entire_binding(),
            }],
        });
        let dummy_texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("vdbcook dummy target"),
            size: wgpu::Extent3d {
                width: 1,
                height: 1,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::STORAGE_BINDING,
            view_formats: &[],
        });
        let dummy_texture_view = dummy_texture.create_view(&Default::default());
        let dummy_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vdbcook dummy target"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        Ok(Renderer {
            pipeline,
            params,
            params_group,
            target_layout,
            format,
            dummy_texture_view,
            dummy_buffer,
            xf,
            vol: Bound::of(volume),
            emission,
            light,
            device: device.clone(),
            layouts,
            lit_variants: Default::default(),
            last_light: std::sync::Mutex::new(None),
        })
    }

    /// Draws from `volume` from now on, keeping the pipeline: for a [`crate::StreamingVolume`]
    /// after its window moved (`stream.volume()`; frames are then window-local). Refuses
    /// ([`RuntimeError::Rebind`]) a volume laid out differently from the one this renderer was
    /// built for. Work recorded before still reads the old window's topology.
    pub fn rebind(&mut self, volume: &GpuVolume) -> Result<()> {
        self.vol.rebind(volume)?;
        self.light.invalidate();
        Ok(())
    }

    /// Makes the next lit render rebuild its light volume. The renderer records the light-volume
    /// pass only when the frame, the light, the medium or the grid changed since the last lit
    /// render it recorded, assuming that recording was submitted: call this after dropping an
    /// encoder that held a lit render without submitting it.
    pub fn invalidate_light_volume(&self) {
        self.light.invalidate();
    }

    /// The texture format this renderer writes.
    pub fn format(&self) -> wgpu::TextureFormat {
        self.format
    }

    fn check_size(width: u32, height: u32) -> Result<()> {
        if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
            return Err(RuntimeError::Target(format!(
                "size {width}x{height} (each side 1..={MAX_SIDE})"
            )));
        }
        Ok(())
    }

    /// Binds the caller's texture (2D, the renderer's format, `STORAGE_BINDING` usage) once.
    pub fn texture_target(
        &self,
        device: &wgpu::Device,
        texture: &wgpu::Texture,
        view: &wgpu::TextureView,
    ) -> Result<TextureTarget> {
        if texture.format() != self.format {
            return Err(RuntimeError::Target(format!(
                "texture format {:?}, renderer writes {:?}",
                texture.format(),
                self.format
            )));
        }
        if !texture
            .usage()
            .contains(wgpu::TextureUsages::STORAGE_BINDING)
            || texture.dimension() != wgpu::TextureDimension::D2
        {
            return Err(RuntimeError::Target(
                "needs a 2D texture with STORAGE_BINDING usage".into(),
            ));
        }
        let (width, height) = (texture.width(), texture.height());
        Self::check_size(width, height)?;
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vdbcook texture target"),
            layout: &self.target_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: self.dummy_buffer.as_entire_binding(),
                },
            ],
        });
        Ok(TextureTarget {
            bind_group,
            width,
            height,
        })
    }

    /// A buffer target of `width × height` (RGBA then raw values, f32), with its read-back.
    pub fn buffer_target(
        &self,
        device: &wgpu::Device,
        width: u32,
        height: u32,
    ) -> Result<BufferTarget> {
        Self::check_size(width, height)?;
        let size = width as u64 * height as u64 * 5 * 4;
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vdbcook buffer target"),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vdbcook readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vdbcook buffer target"),
            layout: &self.target_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&self.dummy_texture_view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: buffer.as_entire_binding(),
                },
            ],
        });
        Ok(BufferTarget {
            bind_group,
            buffer,
            readback,
            width,
            height,
        })
    }

    /// Renders `frame` into a texture target. The lit mode first records its light-volume pass
    /// into `encoder` when the frame, the light or the medium changed (the first lit render
    /// also makes the light volume's buffers, grown when a larger grid needs them). As with the
    /// parameter uniform, one render per submission: a second render recorded into the same
    /// encoder overwrites the first one's uniforms. Delta tracking: render at most 64 samples
    /// per pixel per submission and average progressive batches (`first_sample`); on lavapipe
    /// one dispatch of 256 samples came back biased dark (`vdbcook`'s `gpu::sample_batches`).
    pub fn render(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        target: &TextureTarget,
        frame: usize,
        camera: &Camera,
        settings: &Settings,
    ) -> Result<()> {
        let (w, h) = (target.width, target.height);
        self.record(
            queue,
            encoder,
            &target.bind_group,
            (w, h, OUT_TEXTURE),
            frame,
            camera,
            settings,
        )
    }

    /// Renders `frame` into a buffer target.
    pub fn render_to_buffer(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        target: &BufferTarget,
        frame: usize,
        camera: &Camera,
        settings: &Settings,
    ) -> Result<()> {
        let (w, h) = (target.width, target.height);
        self.record(
            queue,
            encoder,
            &target.bind_group,
            (w, h, OUT_BUFFER),
            frame,
            camera,
            settings,
        )
    }

    /// Validates, writes the parameter uniform, records the dispatch.
    #[allow(clippy::too_many_arguments)]
    fn record(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::BindGroup,
        (width, height, out_flags): (u32, u32, u32),
        frame: usize,
        camera: &Camera,
        settings: &Settings,
    ) -> Result<()> {
        let (params, grid) = self.params(width, height, out_flags, frame, camera, settings)?;
        let light_group = if settings.integrator.mode == Mode::Lit {
            let extinction = settings.medium.absorb as f64 + settings.medium.scatter as f64;
            let lp = LightParams::new(
                &grid,
                &self.xf,
                (settings.lighting.light_dir, settings.lighting.ms_model),
                extinction,
                settings.medium.unit,
                FrameAt {
                    asset: 0,
                    frame_root: params.frame_root,
                    lod: self.vol.lod(),
                },
            );
            let diffusion = (settings.lighting.ms_model == MsModel::Diffusion)
                .then(|| DiffusionInputs::of_settings(&grid, &self.xf, settings));
            let build =
                self.light
                    .prepare(&self.device, queue, &self.vol.group, &[lp], &[diffusion])?;
            let group = build.read.clone();
            *self.last_light.lock().expect("light") = Some(build);
            group
        } else {
            self.light.empty_group.clone()
        };
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("vdbcook trace"),
            timestamp_writes: None,
        });
        let variant = if settings.integrator.mode == Mode::Lit {
            let trilinear = settings.integrator.filter == Filter::Trilinear;
            LitVariant {
                trilinear,
                // As the march's per-sample test, at the frame's largest value (a margin for
                // f32 rounding: a variant with the near field draws the same without it).
                near: params.place.near[0] > 0.0
                    && params.place.sun_cell[3] * params.value_max * params.place.near[1]
                        >= LIT_NEAR_DEPTH as f32 * (1.0 - 1e-4),
                voxels: March::resolve(settings, self.vol.frame_max[frame]) == March::Voxels,
            }
        } else {
            LitVariant::default()
        };
        pass.set_pipeline(match variant.index() {
            0 => &self.pipeline,
            i => self.lit_variants[i].get_or_init(|| {
                let fmt = wgsl_format(self.format).expect("checked at construction");
                let module = trace_module(&self.device, fmt, self.emission, variant);
                let [a, b, c] = &self.layouts;
                self.vol.compute_pipeline(
                    &self.device,
                    "vdbcook trace (lit variant)",
                    &module,
                    "trace_main",
                    &[a, b, c],
                )
            }),
        });
        pass.set_bind_group(0, &self.vol.group, &[]);
        pass.set_bind_group(1, &self.params_group, &[]);
        pass.set_bind_group(2, target, &[]);
        pass.set_bind_group(3, &light_group, &[]);
        pass.dispatch_workgroups(width.div_ceil(WORKGROUP), height.div_ceil(WORKGROUP), 1);
        Ok(())
    }

    /// The uniform for one render (the CPU tracer's `Tracer::new` in f64, then f32), and the
    /// grid of the lit mode's light volume (`vdbcook_trace::LightVolume`'s).
    fn params(
        &self,
        width: u32,
        height: u32,
        out_flags: u32,
        frame: usize,
        camera: &Camera,
        settings: &Settings,
    ) -> Result<(Params, LightGrid)> {
        let mode = crate::camera::validate(settings, width, height, frame, self.vol.frames)?;
        if settings.medium.emission.is_some() && !self.emission {
            return Err(RuntimeError::Unsupported(
                "emission: this renderer's pipeline was built without it; create it with \
                 Renderer::with_emission"
                    .into(),
            ));
        }
        let basis = camera.basis(width, height)?;
        let eye = self.xf.index_of(camera.eye);
        // Depth range: nearest and farthest corner of the frame's stored box (0 inside it).
        let bbox = self.vol.bboxes[frame].unwrap_or(([0.0; 3], self.vol.extent()));
        let [near, far] = depth_range(&self.xf, bbox, camera.eye);
        let vmax = self.vol.frame_max[frame];
        let v4 = |v: [f64; 3]| [v[0] as f32, v[1] as f32, v[2] as f32, 0.0];
        let inv = self.xf.inv_a;
        let grid = LightGrid::with_levels(
            self.vol.content[frame],
            settings.lighting.light_res,
            self.vol.lod().0,
        );
        // Emission from another channel: the modes' own emission is off (`emission.w = 0`) and
        // `channel_emission` draws it over the channel's box (as `vdbcook_trace::Tracer`).
        let (emit_channel, emit_box) = match settings.medium.emission {
            Some(e) if e.channel > 0 => (e.channel as u32, self.vol.emission_box(&e, frame)?),
            _ => (0, None),
        };
        let frame_root = (frame * self.vol.root_len) as u32;
        let params = Params {
            eye_index: v4(eye),
            forward: v4(basis.forward),
            right: v4(basis.right),
            up: v4(basis.up),
            inv_a0: v4(inv[0]),
            inv_a1: v4(inv[1]),
            inv_a2: v4(inv[2]),
            extent: v4(self.vol.extent()),
            content_lo: self.vol.content[frame].map_or([1.0, 1.0, 1.0, 0.0], |b| v4(b.0)),
            content_hi: self.vol.content[frame].map_or([0.0; 4], |b| v4(b.1)),
            width,
            height,
            mode,
            frame_root,
            absorb: settings.medium.absorb,
            cutoff: settings.integrator.cutoff,
            near: near as f32,
            far: far as f32,
            value_max: if vmax > 0.0 { vmax } else { 1.0 },
            out_flags,
            shadow_step: settings.integrator.shadow_step,
            gain: settings.integrator.gain,
            spp: settings.integrator.spp,
            first_sample: settings.integrator.first_sample,
            emit_channel,
            _pad0: 0,
            emit_lo: emit_box.map_or([1.0, 1.0, 1.0, 0.0], |b| v4(b.0)),
            emit_hi: emit_box.map_or([0.0; 4], |b| v4(b.1)),
            lod: [
                if settings.integrator.mode == Mode::Lit && settings.integrator.primary_lod {
                    self.vol.lod().0.consecutive() as u32
                } else {
                    1
                },
                self.vol.lod().1 as u32,
                (pixel_angle(camera.fov_y_deg, height) as f32).to_bits(),
                // 1: the voxel march (`March::resolve`; trilinear density marches in steps).
                (March::resolve(settings, vmax) == March::Voxels) as u32,
            ],
            shading: ShadingUniform::new(
                &settings.medium,
                &settings.lighting,
                &settings.integrator,
                emit_channel == 0,
            ),
            place: LitPlace::new(
                &self.xf,
                &settings.medium,
                &settings.lighting,
                1.0,
                &[(&grid, 0, frame_root)],
                0.0,
            ),
        };
        Ok((params, grid))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout_check::{assert_mirrors, rust_layout};

    #[test]
    fn params_mirror_the_wgsl() {
        let all = LitVariant {
            trilinear: true,
            near: true,
            voxels: true,
        };
        assert_mirrors(
            &trace_source("rgba8unorm", true, all),
            "Params",
            rust_layout!(Params {
                eye_index,
                forward,
                right,
                up,
                inv_a0,
                inv_a1,
                inv_a2,
                extent,
                content_lo,
                content_hi,
                width,
                height,
                mode,
                frame_root,
                absorb,
                cutoff,
                near,
                far,
                value_max,
                out_flags,
                shadow_step,
                gain,
                spp,
                first_sample,
                emit_channel,
                _pad0,
                emit_lo,
                emit_hi,
                lod,
                shading,
                place,
            }),
        );
    }
}
