//! What an engine does with `VolumeDrawer`, start to finish and headless: its own device, an
//! opaque scene rasterized with a real render pipeline into an sRGB colour target and a
//! `Depth32Float` depth buffer (a Lambert-shaded checkered ground plane and a box that cuts into
//! the cloud), then two instances of one cooked asset (different places, different times of the
//! flip-book, one crossfading two frames) recorded with `VolumeDrawer::record` into the same
//! encoder, clipped by the scene's depth and blended over its colours. The colour target is read
//! back before and after the volumes and written as two PNGs. `docs/engine.md` §7 walks through
//! it; `runtime/tests/engine_example.rs` runs `render_scene` and checks the pictures.
//!
//! `cargo run -p vdbcook-runtime --example engine_scene -- ASSET.vdbc [OUT_DIR]`
//! (make an asset with `vdbcook cook fixtures/seq/smoke5 -o smoke5.vdbc`; OUT_DIR defaults to
//! `target/engine_scene/`).

use std::error::Error;
use std::process::ExitCode;

use vdbcook_runtime::glam::{Affine3A, Quat, Vec3};
use vdbcook_runtime::wgpu::util::DeviceExt;
use vdbcook_runtime::{
    wgpu, Asset, DrawTarget, GpuVolume, Instance, Lighting, MarchResolution, Shading, View,
    VolumeDrawer,
};

/// The colour target's format: 8-bit sRGB, as a swapchain (the drawer blends in linear space).
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// The opaque scene: vertices are position, normal, albedo (linear) and a checker flag.
const SCENE_WGSL: &str = r#"
struct Scene {
    view_proj: mat4x4<f32>,
    sun: vec4<f32>,      // xyz: unit direction toward the sun
    checker: vec4<f32>,  // x: checker cell size in world units
};
@group(0) @binding(0) var<uniform> scene: Scene;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) albedo: vec3<f32>,
    @location(3) checker: f32,
};

@vertex
fn scene_vs(@location(0) p: vec3<f32>, @location(1) n: vec3<f32>, @location(2) albedo: vec3<f32>,
            @location(3) checker: f32) -> VsOut {
    var o: VsOut;
    o.clip = scene.view_proj * vec4<f32>(p, 1.0);
    o.world = p;
    o.normal = n;
    o.albedo = albedo;
    o.checker = checker;
    return o;
}

@fragment
fn scene_fs(i: VsOut) -> @location(0) vec4<f32> {
    var albedo = i.albedo;
    if (i.checker > 0.5) {
        let c = floor(i.world.xz / scene.checker.x);
        if ((i32(c.x) + i32(c.y)) % 2 == 0) { albedo = albedo * 0.6; }
    }
    let lambert = max(dot(normalize(i.normal), scene.sun.xyz), 0.0);
    // The smoke's shadow: the sun's transmittance through the drawer's lit volumes
    // (`vdbcook_runtime::shadow_wgsl`, prepended to this shader, bound at group 1).
    let shadow = vdb_sun_transmittance(i.world);
    return vec4<f32>(albedo * (0.25 + 0.75 * lambert * shadow), 1.0);
}
"#;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Vertex {
    p: [f32; 3],
    n: [f32; 3],
    albedo: [f32; 3],
    checker: f32,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct SceneUniform {
    view_proj: [[f32; 4]; 4],
    sun: [f32; 4],
    checker: [f32; 4],
}

/// An axis-aligned world box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub lo: Vec3,
    pub hi: Vec3,
}

impl Aabb {
    fn of_points(points: impl IntoIterator<Item = Vec3>) -> Aabb {
        let mut b = Aabb {
            lo: Vec3::INFINITY,
            hi: Vec3::NEG_INFINITY,
        };
        for p in points {
            b.lo = b.lo.min(p);
            b.hi = b.hi.max(p);
        }
        b
    }

    fn corners(&self) -> [Vec3; 8] {
        std::array::from_fn(|c| {
            Vec3::new(
                if c & 1 == 0 { self.lo.x } else { self.hi.x },
                if c & 2 == 0 { self.lo.y } else { self.hi.y },
                if c & 4 == 0 { self.lo.z } else { self.hi.z },
            )
        })
    }

    /// The entry and exit distances of the ray `o + t·d` (t ≥ 0), if it meets the box.
    pub fn hit(&self, o: Vec3, d: Vec3) -> Option<(f32, f32)> {
        let inv = d.recip();
        let (a, b) = ((self.lo - o) * inv, (self.hi - o) * inv);
        let t0 = a.min(b).max_element().max(0.0);
        let t1 = a.max(b).min_element();
        (t0 <= t1).then_some((t0, t1))
    }
}

/// What `render_scene` drew: both pictures (8-bit sRGB RGBA, row 0 at the top) and the scene's
/// layout, so a test can tell which surface each pixel shows.
pub struct SceneImages {
    pub width: u32,
    pub height: u32,
    /// The opaque scene alone.
    pub scene: Vec<u8>,
    /// The scene with both volume instances composited over it.
    pub composite: Vec<u8>,
    pub view: View,
    /// The ground plane's height (the plane `y = ground_y`).
    pub ground_y: f32,
    /// The opaque box.
    pub block: Aabb,
    /// Each instance's world box (the asset's stored voxels of every frame, one voxel wider).
    pub clouds: Vec<Aabb>,
    pub instances: Vec<Instance>,
}

/// Uploads `asset`, rasterizes the ground and the box, draws two instances of the asset over
/// them in the same encoder and reads the colour target back before and after the volumes.
pub fn render_scene(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    asset: &Asset,
    size: (u32, u32),
) -> Result<SceneImages, Box<dyn Error>> {
    render_scene_at(device, queue, asset, size, MarchResolution::Full)
}

/// [`render_scene`] with the drawer marching at `resolution` (`MarchResolution::Half` or
/// `Quarter`: fewer rays, upsampled, the box's edges still marched per pixel).
// The vertex layout's `.into()` is the identity on wgpu 29 (feature `wgpu29`).
#[allow(clippy::useless_conversion)]
pub fn render_scene_at(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    asset: &Asset,
    (width, height): (u32, u32),
    resolution: MarchResolution,
) -> Result<SceneImages, Box<dyn Error>> {
    let volume = GpuVolume::upload(device, queue, asset)?;
    let mut drawer = VolumeDrawer::new(device, &volume, COLOR_FORMAT)?;
    drawer.set_march_resolution(resolution);

    // The cloud's world box: the stored content of every frame, one voxel wider all round.
    let i2w = volume.index_to_world();
    let to_world = |p: [f64; 3]| {
        Vec3::from_array(std::array::from_fn(|r| {
            (i2w[r][0] * p[0] + i2w[r][1] * p[1] + i2w[r][2] * p[2] + i2w[r][3]) as f32
        }))
    };
    let boxes: Vec<_> = (0..volume.frame_count())
        .filter_map(|f| volume.frame_bbox(f))
        .collect();
    if boxes.is_empty() {
        return Err("the asset stores no voxels in any frame".into());
    }
    let cloud = Aabb::of_points(boxes.iter().flat_map(|(lo, hi)| {
        let index = Aabb {
            lo: Vec3::from_array(lo.map(|v| v as f32 - 1.0)),
            hi: Vec3::from_array(hi.map(|v| v as f32 + 1.0)),
        };
        index.corners().map(|c| to_world(c.as_dvec3().to_array()))
    }));
    let size = cloud.hi - cloud.lo;
    let centre = 0.5 * (cloud.lo + cloud.hi);

    // Two instances: the asset where it is at frame 0, and a second one beside and behind it,
    // turned about its centre, denser, warmer, crossfading two frames.
    let last = volume.frame_count().saturating_sub(1) as f32;
    let turn = Affine3A::from_translation(centre)
        * Affine3A::from_quat(Quat::from_rotation_y(0.6))
        * Affine3A::from_translation(-centre);
    let second = Affine3A::from_translation(Vec3::new(1.1 * size.x, 0.0, -0.6 * size.z)) * turn;
    let instances = vec![
        Instance {
            density_scale: 4.0,
            tint: Vec3::new(1.0, 0.97, 0.92),
            ..Instance::at(Affine3A::IDENTITY)
        },
        Instance {
            world_from_volume: second,
            time: 0.6 * last,
            density_scale: 6.0,
            tint: Vec3::new(1.0, 0.78, 0.6),
            ..Instance::default()
        },
    ];
    let clouds: Vec<Aabb> = instances
        .iter()
        .map(|i| {
            Aabb::of_points(
                cloud
                    .corners()
                    .map(|c| i.world_from_volume.transform_point3(c)),
            )
        })
        .collect();
    let all = Aabb::of_points(clouds.iter().flat_map(|c| c.corners()));

    // The opaque scene: a ground plane just under the cloud, a box that cuts into the first
    // instance's front, bottom and left (half of it outside the cloud's box, half inside).
    let ground_y = cloud.lo.y - 0.02 * size.y;
    let block = Aabb {
        lo: Vec3::new(centre.x - 0.4 * size.x, ground_y, centre.z - 0.1 * size.z),
        hi: Vec3::new(centre.x - 0.1 * size.x, centre.y, centre.z + 0.9 * size.z),
    };
    let diag = (all.hi - all.lo).length();
    let mut vertices = Vec::new();
    let mut quad = |c: [Vec3; 4], n: Vec3, albedo: [f32; 3], checker: f32| {
        for k in [0, 1, 2, 0, 2, 3] {
            vertices.push(Vertex {
                p: c[k].to_array(),
                n: n.to_array(),
                albedo,
                checker,
            });
        }
    };
    let (g, r) = (0.5 * (all.lo + all.hi), 4.0 * diag);
    quad(
        [
            Vec3::new(g.x - r, ground_y, g.z - r),
            Vec3::new(g.x + r, ground_y, g.z - r),
            Vec3::new(g.x + r, ground_y, g.z + r),
            Vec3::new(g.x - r, ground_y, g.z + r),
        ],
        Vec3::Y,
        [0.42, 0.45, 0.38],
        1.0,
    );
    let c = block.corners();
    // Faces as corner indices (bit 0: x, bit 1: y, bit 2: z) and their normals.
    for (idx, n) in [
        ([0, 2, 6, 4], Vec3::NEG_X),
        ([1, 5, 7, 3], Vec3::X),
        ([0, 4, 5, 1], Vec3::NEG_Y),
        ([2, 3, 7, 6], Vec3::Y),
        ([0, 1, 3, 2], Vec3::NEG_Z),
        ([4, 6, 7, 5], Vec3::Z),
    ] {
        quad(idx.map(|i| c[i]), n, [0.62, 0.2, 0.16], 0.0);
    }

    // The engine's camera: above and in front, looking down at both clouds (right-handed,
    // reversed-Z infinite perspective, as View::look_at makes).
    let fov_y = 40f32.to_radians();
    let look = Vec3::new(g.x, all.lo.y + 0.4 * (all.hi.y - all.lo.y), g.z);
    let dist = 0.5 * diag / (0.5 * fov_y).tan() * 0.8;
    let eye = look + Vec3::new(0.3, 0.35, 1.0).normalize() * dist;
    let view = View::look_at(
        eye,
        look,
        Vec3::Y,
        fov_y,
        width as f32 / height as f32,
        0.01 * dist,
        (width, height),
    )?;

    let sun = Vec3::new(0.4, 0.8, 0.3).normalize();
    let uniform = SceneUniform {
        view_proj: (view.proj * view.view).to_cols_array_2d(),
        sun: sun.extend(0.0).to_array(),
        checker: [0.25 * size.x.max(size.z), 0.0, 0.0, 0.0],
    };
    let uniform_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("engine_scene uniform"),
        contents: bytemuck::bytes_of(&uniform),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let vertex_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("engine_scene vertices"),
        contents: bytemuck::cast_slice(&vertices),
        usage: wgpu::BufferUsages::VERTEX,
    });
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("engine_scene"),
        source: wgpu::ShaderSource::Wgsl(
            format!("{}\n{SCENE_WGSL}", vdbcook_runtime::shadow_wgsl(1)).into(),
        ),
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("engine_scene"),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }],
    });
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("engine_scene"),
        layout: &layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: uniform_buffer.as_entire_binding(),
        }],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("engine_scene"),
        bind_group_layouts: &[Some(&layout), Some(drawer.shadow_layout())],
        immediate_size: 0,
    });
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("engine_scene"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("scene_vs"),
            compilation_options: Default::default(),
            buffers: &[wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<Vertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &wgpu::vertex_attr_array![
                    0 => Float32x3, 1 => Float32x3, 2 => Float32x3, 3 => Float32
                ],
            }
            // `Option<VertexBufferLayout>` in wgpu 30, the layout itself in wgpu 29.
            .into()],
        },
        primitive: wgpu::PrimitiveState::default(),
        // Reversed Z: cleared to 0 (infinitely far), nearer surfaces have larger depths.
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Greater),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("scene_fs"),
            compilation_options: Default::default(),
            targets: &[Some(COLOR_FORMAT.into())],
        }),
        multiview_mask: None,
        cache: None,
    });

    let texture = |format, usage| {
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some("engine_scene target"),
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
    };
    let color = texture(
        COLOR_FORMAT,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
    );
    // The drawer reads the depth buffer: TEXTURE_BINDING besides RENDER_ATTACHMENT.
    let depth = texture(
        wgpu::TextureFormat::Depth32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
    );
    let color_view = color.create_view(&Default::default());
    let depth_view = depth.create_view(&Default::default());
    let row = (width * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let readback = |label| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: row as u64 * height as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    };
    let (scene_buffer, composite_buffer) = (readback("scene"), readback("composite"));
    let copy = |encoder: &mut wgpu::CommandEncoder, buffer| {
        encoder.copy_texture_to_buffer(
            color.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: None,
                },
            },
            color.size(),
        );
    };

    // Lit by the scene's sun (the same direction its Lambert shading uses) and a bright sky:
    // the tracer's lit mode, per instance, through light volumes the drawer builds.
    let medium = Shading {
        lighting: Some(Lighting {
            light_dir: sun.to_array(),
            light_color: [2.6, 2.5, 2.3],
            sky: [0.55, 0.62, 0.75],
            light_res: 48,
            ..Default::default()
        }),
        ..Default::default()
    };
    // Prepare (everything but commands: the light volumes, submitted by the drawer; uniforms;
    // bind groups), then one encoder for the whole frame: opaque pass (it reads the smoke's
    // shadows), copy, volumes, copy.
    let shadows = drawer.sun_shadows(device, queue, &instances, &medium)?;
    let volumes = drawer.prepare(
        device,
        queue,
        &DrawTarget {
            color: &color_view,
            depth: Some(&depth_view),
        },
        &view,
        &instances,
        &medium,
    )?;
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("engine_scene opaque"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: 0.32,
                        g: 0.45,
                        b: 0.7,
                        a: 1.0,
                    }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(0.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.set_bind_group(1, &shadows.bind_group, &[]);
        pass.set_vertex_buffer(0, vertex_buffer.slice(..));
        pass.draw(0..vertices.len() as u32, 0..1);
    }
    copy(&mut encoder, &scene_buffer);
    drawer.record(&mut encoder, &volumes);
    copy(&mut encoder, &composite_buffer);
    queue.submit([encoder.finish()]);

    let mut images = Vec::new();
    for buffer in [&scene_buffer, &composite_buffer] {
        buffer
            .slice(..)
            .map_async(wgpu::MapMode::Read, |r| r.expect("map readback"));
    }
    device.poll(wgpu::PollType::wait_indefinitely())?;
    for buffer in [&scene_buffer, &composite_buffer] {
        let data =
            vdbcook_runtime::gpu_compat::mapped_range(&buffer.slice(..)).ok_or("mapped range")?;
        let mut pixels = Vec::with_capacity((width * height * 4) as usize);
        for y in 0..height as usize {
            pixels.extend_from_slice(&data[y * row as usize..][..4 * width as usize]);
        }
        images.push(pixels);
    }
    let composite = images.pop().expect("two images");
    let scene = images.pop().expect("two images");
    Ok(SceneImages {
        width,
        height,
        scene,
        composite,
        view,
        ground_y,
        block,
        clouds,
        instances,
    })
}

/// A device on the default adapter, with the BC features it has (bricks stay compressed).
pub fn device() -> Result<(wgpu::Device, wgpu::Queue), Box<dyn Error>> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
    let adapter = pollster::block_on(instance.request_adapter(&Default::default()))
        .map_err(|e| format!("no GPU adapter ({e}); on Linux install mesa-vulkan-drivers"))?;
    eprintln!("adapter: {:?}", adapter.get_info().name);
    Ok(pollster::block_on(adapter.request_device(
        &wgpu::DeviceDescriptor {
            label: Some("engine_scene"),
            required_limits: adapter.limits(),
            required_features: adapter.features() & vdbcook_runtime::OPTIONAL_FEATURES,
            ..Default::default()
        },
    ))?)
}

fn write_png(path: &std::path::Path, w: u32, h: u32, rgba: &[u8]) -> Result<(), Box<dyn Error>> {
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let mut enc = png::Encoder::new(file, w, h);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    // The target is sRGB-encoded: say so in the file.
    enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    enc.write_header()?.write_image_data(rgba)?;
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("engine_scene: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().collect();
    let Some(asset_path) = args.get(1) else {
        return Err(
            "usage: engine_scene ASSET.vdbc [OUT_DIR]\n  make an asset first: \
                    vdbcook cook fixtures/seq/smoke5 -o smoke5.vdbc"
                .into(),
        );
    };
    let out = std::path::PathBuf::from(
        args.get(2)
            .map(String::as_str)
            .unwrap_or("target/engine_scene"),
    );
    let asset = Asset::load(asset_path).map_err(|e| format!("{asset_path}: {e}"))?;
    let (device, queue) = device()?;
    let start = std::time::Instant::now();
    let images = render_scene(&device, &queue, &asset, (960, 540))?;
    eprintln!(
        "rendered {}x{} (scene, two instances) in {:.1} ms",
        images.width,
        images.height,
        start.elapsed().as_secs_f64() * 1e3
    );
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    for (name, pixels) in [
        ("scene.png", &images.scene),
        ("scene_with_volumes.png", &images.composite),
    ] {
        let path = out.join(name);
        write_png(&path, images.width, images.height, pixels)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}
