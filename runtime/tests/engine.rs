//! The engine drawer (`VolumeDrawer`) on whatever adapter exists (lavapipe in CI), each answer
//! checked against the CPU reference tracer (`Tracer::optical_depth` per pixel, along the rays of
//! `ViewRays`, the f64 twin of the GPU's unprojection) or against a closed form: depth planes in
//! front of, beyond and through the cloud; `out = L + T·scene` for two backgrounds; translated,
//! rotated and jittered instances; several instances in one draw; many draws of two volumes in
//! one encoder against one submission each; crossfades; standard-Z, reversed-Z and orthographic
//! projections; an 8-bit sRGB target; and the refusals (bad targets, singular views, times out of range).
//!
//! Tolerance: the GPU marches in f32 and stores `(L, T)` and the colour target in half floats
//! (relative step 2⁻¹¹), so a pixel may differ from the CPU's f64 by `TOL` per channel.

mod common;

use common::*;
use vdbcook_asset::{Asset, PayloadFormat};
use vdbcook_runtime::glam::{Affine3A, EulerRot, Mat4, Quat, Vec2, Vec3, Vec4};
use vdbcook_runtime::{
    DrawTarget, Filter, GpuVolume, Instance, LitCrossfade, MarchResolution, RuntimeError, Shading,
    View, ViewRays, VolumeDrawer, DRAW_DEPTH_FORMATS,
};
use vdbcook_scene::content_box;
use vdbcook_trace::{
    Camera, Integrator, LengthUnit, Lighting, Medium, MsModel, Output, RenderSettings, Scratch,
    Tracer,
};

const W: u32 = 160;
const H: u32 = 96;
const TOL: f32 = 3e-3;
const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// Three frames of a cloud that moves and thickens (frame 2 also holds a tiled region).
fn cloud(format: PayloadFormat) -> Asset {
    build(
        [2, 2, 2],
        rotated(25.0, [0.5, 0.7, 1.2], [3.0, -2.0, 1.0]),
        0.0,
        &[
            blob_frame([120.0, 100.0, 40.0], 34.0, 1.2, None),
            blob_frame([140.0, 110.0, 50.0], 28.0, 2.5, None),
            blob_frame([100.0, 120.0, 60.0], 30.0, 0.8, Some([1, 1, 1])),
        ],
        format,
    )
}

struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
}

/// A colour target and a depth buffer of the test size.
struct Frame {
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    readback: wgpu::Buffer,
}

impl Gpu {
    fn new(test: &str) -> Option<Gpu> {
        gpu(test).map(|(device, queue)| Gpu { device, queue })
    }

    fn frame(&self) -> Frame {
        self.frame_with_depth(wgpu::TextureFormat::Depth32Float)
    }

    /// As [`Gpu::frame`] with a depth buffer of `depth_format`.
    fn frame_with_depth(&self, depth_format: wgpu::TextureFormat) -> Frame {
        let tex = |format, usage| {
            self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("test target"),
                size: wgpu::Extent3d {
                    width: W,
                    height: H,
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
        let color = tex(
            FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let depth = tex(
            depth_format,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("test readback"),
            size: (W * H * 8) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Frame {
            color_view: color.create_view(&Default::default()),
            depth_view: depth.create_view(&Default::default()),
            color,
            readback,
        }
    }

    /// Records clearing the colour target to `bg` and, with `depth`, the depth buffer to it (a
    /// plane of constant NDC depth: what an engine's depth pre-pass leaves).
    fn clear(&self, enc: &mut wgpu::CommandEncoder, f: &Frame, bg: [f64; 3], depth: Option<f32>) {
        let _ = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("test clear"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &f.color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: bg[0],
                        g: bg[1],
                        b: bg[2],
                        a: 1.0,
                    }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: depth.map(|d| wgpu::RenderPassDepthStencilAttachment {
                view: &f.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(d),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
    }

    /// Reads the colour target back (RGBA, f32 from the half floats).
    fn read(&self, f: &Frame) -> Vec<f32> {
        let mut enc = self.device.create_command_encoder(&Default::default());
        enc.copy_texture_to_buffer(
            f.color.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &f.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(W * 8),
                    rows_per_image: Some(H),
                },
            },
            f.color.size(),
        );
        self.queue.submit([enc.finish()]);
        let slice = f.readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |r| r.expect("map"));
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("poll");
        let out = {
            let data = vdbcook_runtime::gpu_compat::mapped_range(&slice).expect("mapped");
            data.chunks_exact(2)
                .map(|b| half::f16::from_le_bytes([b[0], b[1]]).to_f32())
                .collect()
        };
        f.readback.unmap();
        out
    }

    /// Clears (background `bg`, depth plane `depth`), draws, submits and reads back.
    #[allow(clippy::too_many_arguments)]
    fn draw(
        &self,
        drawer: &mut VolumeDrawer,
        f: &Frame,
        view: &View,
        instances: &[Instance],
        medium: &Shading,
        bg: [f64; 3],
        depth: Option<f32>,
    ) -> Vec<f32> {
        let mut enc = self.device.create_command_encoder(&Default::default());
        self.clear(&mut enc, f, bg, depth);
        let target = DrawTarget {
            color: &f.color_view,
            depth: depth.map(|_| &f.depth_view),
        };
        let _held = drawer
            .draw(
                &self.device,
                &self.queue,
                &mut enc,
                &target,
                view,
                instances,
                medium,
            )
            .expect("draw");
        self.queue.submit([enc.finish()]);
        self.read(f)
    }
}

/// The CPU reference of one instance: a tracer per frame of the crossfade on the asset moved by
/// the instance's transform, absorption scaled by its density.
struct CpuInstance<'a> {
    tracers: Vec<(Tracer<'a>, f64)>,
    absorb: f64,
    tint: Vec3,
}

fn cpu_instance<'a>(moved: &'a Asset, inst: &Instance, shading: &Shading) -> CpuInstance<'a> {
    let (f0, f1, a) = inst.frames(moved.frame_count()).unwrap();
    let cam = Camera::framing(moved, 0, 1.0).unwrap();
    let medium = &shading.medium;
    let absorb = medium.absorb * inst.density_scale;
    let tracer = |frame| {
        let s = RenderSettings {
            output: Output {
                width: 4,
                height: 4,
                frame,
            },
            medium: Medium {
                absorb,
                unit: medium.unit,
                ..Default::default()
            },
            ..Default::default()
        };
        Tracer::new(moved, &cam, &s).unwrap()
    };
    let mut tracers = vec![(tracer(f0), 1.0 - a as f64)];
    if a > 0.0 {
        tracers.push((tracer(f1), a as f64));
    }
    CpuInstance {
        tracers,
        absorb: absorb as f64,
        tint: inst.tint,
    }
}

/// The CPU references of `insts`, each on its asset already moved by it (`moved`).
fn cpu_instances<'a>(
    insts: &[Instance],
    moved: &'a [Asset],
    shading: &Shading,
) -> Vec<CpuInstance<'a>> {
    insts
        .iter()
        .zip(moved)
        .map(|(i, m)| {
            cpu_instance(
                m,
                &Instance {
                    world_from_volume: Affine3A::IDENTITY,
                    ..*i
                },
                shading,
            )
        })
        .collect()
}

/// The asset as the instance places it (what the CPU tracer gets).
fn moved(asset: &Asset, inst: &Instance) -> Asset {
    let mut a = asset.clone();
    a.header.index_to_world = inst.index_to_world(&asset.header.index_to_world);
    a
}

/// Per pixel `(L, T)` on the CPU: instances composited in the order given (tests use equal
/// tints wherever instances overlap, where the order does not matter), rays cut at the depth.
fn cpu_lt(rays: &ViewRays, instances: &[CpuInstance], depth: Option<f32>) -> Vec<[f64; 4]> {
    let mut scratch = Scratch::default();
    let mut out = Vec::with_capacity((W * H) as usize);
    for y in 0..H {
        for x in 0..W {
            let (o, d) = rays.ray(x, y);
            let t_max = depth.map_or(f64::INFINITY, |z| rays.depth_distance(x, y, z));
            out.push(cpu_lt_one_ray(
                instances,
                (o.into(), d.into()),
                t_max,
                &mut scratch,
            ));
        }
    }
    out
}

/// Largest difference between the GPU picture and `L + T·bg` from the CPU.
/// Asserts that the GPU image is within `tol` of the CPU's `(L, T)` over `BG` (printing the
/// largest difference and where it is).
fn assert_matches(what: &str, gpu: &[f32], cpu: &[[f64; 4]], tol: f32) {
    let (d, at) = max_diff(gpu, cpu, BG);
    eprintln!("{what}: max diff {d:.2e} {at}");
    assert!(d <= tol, "{what}: {at}");
}

fn max_diff(gpu: &[f32], cpu: &[[f64; 4]], bg: [f64; 3]) -> (f32, String) {
    let mut worst = (0.0f32, String::new());
    for (p, lt) in cpu.iter().enumerate() {
        for c in 0..3 {
            let want = (lt[c] + lt[3] * bg[c]) as f32;
            let got = gpu[4 * p + c];
            let d = (got - want).abs();
            // NaN counts as the worst.
            if d.is_nan() || d > worst.0 {
                worst = (
                    d,
                    format!(
                        "pixel ({}, {}) channel {c}: gpu {got}, cpu {want} (T {})",
                        p as u32 % W,
                        p as u32 / W,
                        lt[3]
                    ),
                );
            }
        }
    }
    worst
}

/// A view of the moved asset as the CPU tracer's default framing sees it: reversed-Z infinite
/// perspective (`View::look_at`).
fn framing_view(asset: &Asset) -> (View, Camera) {
    let cam = Camera::framing(asset, 0, W as f64 / H as f64).unwrap();
    let v = |a: [f64; 3]| Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32);
    let view = View::look_at(
        v(cam.eye),
        v(cam.look_at),
        v(cam.up),
        (cam.fov_y_deg as f32).to_radians(),
        W as f32 / H as f32,
        0.05,
        (W, H),
    )
    .unwrap();
    (view, cam)
}

/// The NDC depth `proj` gives a point `dist` in front of a right-handed camera.
fn ndc_depth(proj: &Mat4, dist: f32) -> f32 {
    let c = *proj * Vec4::new(0.0, 0.0, -dist, 1.0);
    c.z / c.w
}

/// Distance from the eye to the framing camera's look-at point (the cloud's box centre).
fn centre_distance(cam: &Camera) -> f32 {
    let d: f64 = (0..3).map(|k| (cam.look_at[k] - cam.eye[k]).powi(2)).sum();
    d.sqrt() as f32
}

/// The default lighting with a small light volume (20 cells: quick to build on lavapipe).
/// [`lit_shading`] with the multiple-scattering model `ms_model`.
fn lit_with(ms_model: MsModel) -> Shading {
    Shading {
        lighting: Some(Lighting {
            light_res: 20,
            ms_model,
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// One instance at the origin at flip-book time `time`.
fn at_time(time: f32) -> [Instance; 1] {
    [Instance {
        time,
        ..Default::default()
    }]
}

fn lit_shading() -> Shading {
    Shading {
        lighting: Some(Lighting {
            light_res: 20,
            ..Default::default()
        }),
        ..Default::default()
    }
}

fn setup(gpu: &Gpu, asset: &Asset) -> (GpuVolume, VolumeDrawer) {
    let vol = GpuVolume::upload(&gpu.device, &gpu.queue, asset).expect("upload");
    let drawer = VolumeDrawer::new(&gpu.device, &vol, FORMAT).expect("drawer");
    (vol, drawer)
}

const BG: [f64; 3] = [0.25, 0.5, 0.75];

#[test]
fn depth_planes_in_front_beyond_and_through_the_cloud() {
    let Some(gpu) = Gpu::new("depth_planes_in_front_beyond_and_through_the_cloud") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let (_vol, mut drawer) = setup(&gpu, &asset);
    let (view, cam) = framing_view(&asset);
    let rays = view.rays().unwrap();
    let inst = [Instance::default()];
    let medium = Shading::default();
    let mid = centre_distance(&cam);
    // Both depth formats the drawer reads; Depth24Plus may quantize the stored depth to 24 bits,
    // which moves the cut by far less than a voxel here (the CPU cuts at the unquantized depth).
    for depth_format in DRAW_DEPTH_FORMATS {
        eprintln!("{depth_format:?}:");
        let f = gpu.frame_with_depth(depth_format);

        let free = gpu.draw(&mut drawer, &f, &view, &inst, &medium, BG, None);
        let cpu_free = cpu_lt(&rays, &[cpu_instance(&asset, &inst[0], &medium)], None);
        assert_matches("no depth", &free, &cpu_free, TOL);
        assert!(
            cpu_free.iter().filter(|p| p[3] < 0.5).count() > 100,
            "the cloud covers the picture"
        );

        // In front of the cloud: the background, bit for bit.
        let near = gpu.draw(
            &mut drawer,
            &f,
            &view,
            &inst,
            &medium,
            BG,
            Some(ndc_depth(&view.proj, 0.2 * mid)),
        );
        let bg16: Vec<f32> = (0..(W * H) as usize)
            .flat_map(|_| [BG[0], BG[1], BG[2], 1.0])
            .map(|v| half::f16::from_f64(v).to_f32())
            .collect();
        assert_eq!(
            near, bg16,
            "a depth plane in front of the cloud changed pixels"
        );

        // Beyond it: the same pixels as without depth.
        let far = gpu.draw(
            &mut drawer,
            &f,
            &view,
            &inst,
            &medium,
            BG,
            Some(ndc_depth(&view.proj, 4.0 * mid)),
        );
        assert_eq!(far, free, "a depth plane beyond the cloud changed pixels");

        // Through its centre: cut, as the CPU cut at the same distances.
        let z = ndc_depth(&view.proj, mid);
        let cut = gpu.draw(&mut drawer, &f, &view, &inst, &medium, BG, Some(z));
        let cpu_cut = cpu_lt(&rays, &[cpu_instance(&asset, &inst[0], &medium)], Some(z));
        assert_matches("depth through the centre", &cut, &cpu_cut, TOL);
        let thinner = (0..cpu_cut.len())
            .filter(|&p| cpu_cut[p][3] > cpu_free[p][3] + 0.05)
            .count();
        assert!(
            thinner > 100,
            "the cut removes part of the cloud ({thinner} pixels)"
        );
    }
}

#[test]
fn blend_is_radiance_plus_transmittance_times_scene() {
    let Some(gpu) = Gpu::new("blend_is_radiance_plus_transmittance_times_scene") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let (_vol, mut drawer) = setup(&gpu, &asset);
    let f = gpu.frame();
    let (view, _) = framing_view(&asset);
    let inst = [Instance {
        tint: Vec3::new(1.0, 0.6, 0.3),
        ..Default::default()
    }];
    let medium = Shading::default();
    let (a, b) = ([0.9, 0.1, 0.4], [0.0, 0.8, 0.2]);
    let ga = gpu.draw(&mut drawer, &f, &view, &inst, &medium, a, None);
    let gb = gpu.draw(&mut drawer, &f, &view, &inst, &medium, b, None);
    let cpu = cpu_lt(
        &view.rays().unwrap(),
        &[cpu_instance(&asset, &inst[0], &medium)],
        None,
    );
    let mut worst = 0.0f32;
    for (p, lt) in cpu.iter().enumerate() {
        for c in 0..3 {
            // out_a − out_b = T·(a − b), and out_a − T·a = L = tint·(1 − T).
            let t = (ga[4 * p + c] - gb[4 * p + c]) as f64 / (a[c] - b[c]);
            let l = ga[4 * p + c] as f64 - t * a[c];
            worst = worst.max((t - lt[3]).abs() as f32);
            worst = worst.max((l - lt[c]).abs() as f32);
            assert!(
                (t - lt[3]).abs() < 4e-3 && (l - lt[c]).abs() < 4e-3,
                "pixel {p} channel {c}: T {t} vs {}, L {l} vs {}",
                lt[3],
                lt[c]
            );
        }
        // The target's alpha is kept.
        assert_eq!(ga[4 * p + 3], 1.0);
    }
    eprintln!("blend: T and L within {worst:.2e} of the CPU");
}

#[test]
fn moved_and_jittered_instances_match_the_cpu() {
    let Some(gpu) = Gpu::new("moved_and_jittered_instances_match_the_cpu") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let (_vol, mut drawer) = setup(&gpu, &asset);
    let f = gpu.frame();
    let medium = Shading::default();
    let cases = [
        (
            "translated",
            Affine3A::from_translation(Vec3::new(30.0, -12.0, 7.0)),
        ),
        (
            "rotated and scaled",
            Affine3A::from_scale_rotation_translation(
                Vec3::splat(1.3),
                Quat::from_euler(EulerRot::XYZ, 0.4, -0.9, 1.7),
                Vec3::new(-5.0, 4.0, 3.0),
            ),
        ),
    ];
    for (what, xf) in cases {
        let inst = Instance {
            density_scale: 1.7,
            tint: Vec3::new(0.5, 1.0, 2.0),
            ..Instance::at(xf)
        };
        let m = moved(&asset, &inst);
        let (mut view, _) = framing_view(&m);
        view.jitter = Vec2::new(0.3, -0.45);
        let g = gpu.draw(&mut drawer, &f, &view, &[inst], &medium, BG, None);
        let unit = Instance {
            world_from_volume: Affine3A::IDENTITY,
            ..inst
        };
        let cpu = cpu_lt(
            &view.rays().unwrap(),
            &[cpu_instance(&m, &unit, &medium)],
            None,
        );
        assert_matches(what, &g, &cpu, 2.0 * TOL);
        assert!(cpu.iter().filter(|p| p[3] < 0.5).count() > 100, "{what}");
    }
    // World length units too.
    let medium = Shading {
        medium: Medium {
            absorb: 0.2,
            unit: LengthUnit::World,
            ..Default::default()
        },
        ..Default::default()
    };
    let (view, _) = framing_view(&asset);
    let g = gpu.draw(
        &mut drawer,
        &f,
        &view,
        &[Instance::default()],
        &medium,
        BG,
        None,
    );
    let cpu = cpu_lt(
        &view.rays().unwrap(),
        &[cpu_instance(&asset, &Instance::default(), &medium)],
        None,
    );
    assert_matches("world units", &g, &cpu, TOL);
}

/// Lit instances draw what the CPU tracer's lit mode draws for the asset as the instance
/// places it (extinction and scattering scaled by the density scale, radiance by the tint):
/// moved, rotated and scaled, at each of two frames (each with its own light volume), with a
/// sub-pixel jitter. The lit march's sample offsets are the tracer's per-pixel ones.
#[test]
fn lit_instances_match_the_cpu_lit_mode() {
    let Some(gpu) = Gpu::new("lit_instances_match_the_cpu_lit_mode") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let (_vol, mut drawer) = setup(&gpu, &asset);
    let f = gpu.frame();
    let lighting = Lighting {
        light_res: 24,
        light_dir: [0.4, 0.8, -0.3],
        ..Default::default()
    };
    let medium = Shading {
        lighting: Some(lighting.clone()),
        ..Default::default()
    };
    let rotated = Affine3A::from_scale_rotation_translation(
        Vec3::splat(1.3),
        Quat::from_euler(EulerRot::XYZ, 0.4, -0.9, 1.7),
        Vec3::new(-5.0, 4.0, 3.0),
    );
    let cases = [
        (
            "translated, frame 0",
            0.0,
            Affine3A::from_translation(Vec3::new(30.0, -12.0, 7.0)),
            Filter::Nearest,
        ),
        ("rotated and scaled, frame 1", 1.0, rotated, Filter::Nearest),
        (
            "rotated and scaled, frame 1, trilinear",
            1.0,
            rotated,
            Filter::Trilinear,
        ),
        (
            "rotated and scaled, frame 1, emission",
            1.0,
            rotated,
            Filter::Nearest,
        ),
        (
            "rotated and scaled, frame 1, diffusion",
            1.0,
            rotated,
            Filter::Nearest,
        ),
    ];
    for (what, time, xf, filter) in cases {
        // The values read as Kelvin over a small range: the test is of the march, not of fire.
        let emission = what
            .ends_with("emission")
            .then_some(vdbcook_trace::Emission {
                range: [0.3, 1.5],
                kelvin: [0.3, 1.5],
                intensity: 0.8,
                channel: 0,
            });
        // With emission: a pure glow (no scattering, no light), thin enough to see into.
        let glow = emission.is_some();
        let ms_model = if what.ends_with("diffusion") {
            MsModel::Diffusion
        } else {
            MsModel::Octaves
        };
        let medium = Shading {
            lighting: Some(Lighting {
                ms_model,
                ms_sky: ms_model.default_ms_sky(),
                ..lighting.clone()
            }),
            medium: Medium {
                emission,
                scatter: if glow { 0.0 } else { medium.medium.scatter },
                absorb: if glow { 0.02 } else { medium.medium.absorb },
                ..medium.medium.clone()
            },
            integrator: Integrator {
                filter,
                ..medium.integrator.clone()
            },
        };
        let inst = Instance {
            density_scale: 1.7,
            tint: Vec3::new(0.5, 1.0, 2.0),
            time,
            ..Instance::at(xf)
        };
        let m = moved(&asset, &inst);
        let (mut view, cam) = framing_view(&m);
        view.jitter = Vec2::new(0.3, -0.45);
        let g = gpu.draw(&mut drawer, &f, &view, &[inst], &medium, BG, None);
        // The CPU: the lit mode on the moved asset, the medium scaled by the density.
        let base = medium.settings();
        let s = RenderSettings {
            output: Output {
                frame: time as usize,
                ..base.output
            },
            medium: Medium {
                absorb: base.medium.absorb * inst.density_scale,
                scatter: base.medium.scatter * inst.density_scale,
                ..base.medium
            },
            ..base
        };
        let tracer = Tracer::new(&m, &cam, &s).unwrap();
        let rays = view.rays().unwrap();
        let mut scratch = Scratch::default();
        let mut cpu = Vec::new();
        for y in 0..H {
            for x in 0..W {
                let (o, d) = rays.ray(x, y);
                let px = tracer.trace(o.into(), d.into(), y * W + x, &mut scratch);
                let t = inst.tint;
                let l = [0, 1, 2].map(|c| (px.rgba[c] * t[c]) as f64);
                cpu.push([l[0], l[1], l[2], px.value as f64]);
            }
        }
        if glow {
            // Radiances up to ~10: the f32 march's voxel choice at brick boundaries (the drawer
            // reads the tree, the tracers clamp into the span's brick) moves a pixel by up to
            // ~1.4% (measured on lavapipe; median 0.07%), so the tolerance is relative here.
            let mut worst = 0.0f64;
            for (p, lt) in cpu.iter().enumerate() {
                for c in 0..3 {
                    let want = lt[c] + lt[3] * BG[c];
                    let d = (g[4 * p + c] as f64 - want).abs() - 2.0 * TOL as f64;
                    worst = worst.max(d / want.abs().max(1e-9));
                }
            }
            eprintln!(
                "{what}: worst relative difference beyond {} {worst:.2e}",
                2.0 * TOL
            );
            assert!(worst < 0.02, "{what}: {worst}");
        } else {
            assert_matches(what, &g, &cpu, 2.0 * TOL);
        }
        assert!(cpu.iter().filter(|p| p[3] < 0.5).count() > 100, "{what}");
        if glow {
            let warm = cpu
                .iter()
                .filter(|p| p[0] > 0.05 && p[0] > p[2] / 2.0)
                .count();
            assert!(warm > 100, "{what}: the glow shows ({warm} warm pixels)");
        }
        let lit = cpu.iter().filter(|p| p[0] > 0.02).count();
        assert!(lit > 100, "{what}: the cloud is lit ({lit} pixels)");
    }
    // A lit setting out of range is refused, nothing recorded.
    let bad = Shading {
        lighting: Some(Lighting {
            ms_octaves: 0,
            ..lighting
        }),
        ..medium
    };
    let (view, _) = framing_view(&asset);
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    let target = DrawTarget {
        color: &f.color_view,
        depth: None,
    };
    let e = drawer
        .draw(
            &gpu.device,
            &gpu.queue,
            &mut enc,
            &target,
            &view,
            &[Instance::default()],
            &bad,
        )
        .expect_err("refused");
    assert!(matches!(e, RuntimeError::Setting(_)), "{e}");
}

/// Three overlapping copies (equal tints: the result does not depend on their order).
fn three_copies() -> Vec<Instance> {
    [0.0f32, 12.0, 24.0]
        .iter()
        .enumerate()
        .map(|(i, &dx)| Instance {
            time: i as f32 * 0.5,
            density_scale: 0.6,
            tint: Vec3::new(0.8, 0.9, 1.0),
            ..Instance::at(Affine3A::from_translation(Vec3::new(dx, 0.5 * dx, 0.0)))
        })
        .collect()
}

#[test]
fn overlapping_instances_in_one_draw_multiply_transmittances() {
    let Some(gpu) = Gpu::new("overlapping_instances_in_one_draw_multiply_transmittances") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let (_vol, mut drawer) = setup(&gpu, &asset);
    let f = gpu.frame();
    let medium = Shading::default();
    let insts = three_copies();
    let (view, cam) = framing_view(&moved(&asset, &insts[1]));
    let z = ndc_depth(&view.proj, 1.1 * centre_distance(&cam));
    let g = gpu.draw(&mut drawer, &f, &view, &insts, &medium, BG, Some(z));
    let movedv: Vec<Asset> = insts.iter().map(|i| moved(&asset, i)).collect();
    let cpu_insts = cpu_instances(&insts, &movedv, &medium);
    let cpu = cpu_lt(&view.rays().unwrap(), &cpu_insts, Some(z));
    assert_matches("three overlapping instances", &g, &cpu, TOL);
}

/// A small dense ember (one 128³ root, voxels 0.3 world units, turned): a second asset for the
/// volume-set tests, in another payload format than the cloud.
fn ember() -> Asset {
    build(
        [1, 1, 1],
        rotated(-40.0, [0.3, 0.3, 0.3], [0.0, 0.0, 0.0]),
        0.0,
        &[blob_frame([40.0, 40.0, 40.0], 24.0, 0.6, None)],
        PayloadFormat::F16,
    )
}

/// World point of index point `p` of `asset`.
fn world_of(asset: &Asset, p: [f64; 3]) -> Vec3 {
    let w = vdbcook_trace::Affine::cells(&asset.header.index_to_world)
        .unwrap()
        .world_of(p);
    Vec3::new(w[0] as f32, w[1] as f32, w[2] as f32)
}

/// `(L, T)` of flat media that overlap along one ray, integrated on the CPU in f64: each
/// medium's optical depth from its tracer (`optical_depth` to t, differenced), the ray cut into
/// pieces halved wherever two media are both present until a piece is `h` long, each piece
/// composited as the exact mixture of media of constant density there
/// (`(1 − e^−X)·Σ (x_i/X)·tint_i`, X = Σ x_i).
fn mixture_lt(
    insts: &[CpuInstance],
    (o, d): ([f64; 3], [f64; 3]),
    t_far: f64,
    h: f64,
    scratch: &mut Scratch,
) -> [f64; 4] {
    let mut x_at = |t: f64| -> Vec<f64> {
        insts
            .iter()
            .map(|inst| {
                inst.absorb
                    * inst
                        .tracers
                        .iter()
                        .map(|(tr, w)| w * tr.optical_depth(o, d, t, scratch))
                        .sum::<f64>()
            })
            .collect()
    };
    let mut out = [0.0, 0.0, 0.0, 1.0];
    // Depth-first over pieces, front to back.
    let mut stack = vec![(0.0, t_far, x_at(0.0), x_at(t_far))];
    while let Some((a, b, xa, xb)) = stack.pop() {
        let dx: Vec<f64> = xa.iter().zip(&xb).map(|(p, q)| (q - p).max(0.0)).collect();
        let present = dx.iter().filter(|x| **x > 1e-12).count();
        if present >= 2 && b - a > h {
            let m = 0.5 * (a + b);
            let xm = x_at(m);
            stack.push((m, b, xm.clone(), xb));
            stack.push((a, m, xa, xm));
            continue;
        }
        let total: f64 = dx.iter().sum();
        if total > 0.0 {
            let k = out[3] * (1.0 - (-total).exp()) / total;
            for (inst, x) in insts.iter().zip(&dx) {
                for (o, tint) in out.iter_mut().zip(inst.tint.to_array()) {
                    *o += k * x * tint as f64;
                }
            }
            out[3] *= (-total).exp();
        }
    }
    out
}

/// An instance of one asset inside a cloud of another, both of one volume set, in one draw:
/// the drawer interleaves them along each ray (cloud in front, ember, cloud behind) and
/// matches the CPU's f64 mixture of the two media; composited one after the other (the sorted
/// order) the picture would be far off, so the test tells interleaving from sorting.
#[test]
fn an_instance_inside_a_cloud_of_another_asset_interleaves() {
    let Some(gpu) = Gpu::new("an_instance_inside_a_cloud_of_another_asset_interleaves") else {
        return;
    };
    let (cloud, ember) = (cloud(PayloadFormat::F32), ember());
    let vol = GpuVolume::upload_set(
        &gpu.device,
        &gpu.queue,
        &[&cloud, &ember],
        Default::default(),
    )
    .expect("upload the set");
    assert_eq!(vol.asset_count(), 2);
    let mut drawer = VolumeDrawer::new(&gpu.device, &vol, FORMAT).expect("drawer");
    // The ember's centre on the cloud's (frame 0: blob at index (120, 100, 40)).
    let shift = world_of(&cloud, [120.0, 100.0, 40.0]) - world_of(&ember, [40.0, 40.0, 40.0]);
    let insts = [
        Instance {
            density_scale: 0.5,
            tint: Vec3::new(0.9, 0.95, 1.0),
            ..Instance::default()
        },
        Instance {
            asset: 1,
            density_scale: 1.0,
            tint: Vec3::new(1.0, 0.35, 0.05),
            ..Instance::at(Affine3A::from_translation(shift))
        },
    ];
    let medium = Shading::default();
    let f = gpu.frame();
    let (view, cam) = framing_view(&cloud);
    let g = gpu.draw(&mut drawer, &f, &view, &insts, &medium, BG, None);

    let moved_assets = [moved(&cloud, &insts[0]), moved(&ember, &insts[1])];
    let cpu_insts = cpu_instances(&insts, &moved_assets, &medium);
    let rays = view.rays().unwrap();
    let t_far = 2.0 * centre_distance(&cam) as f64;
    let mut scratch = Scratch::default();
    let (mut worst, mut at, mut inside) = (0.0f32, String::new(), 0);
    let mut sorted_worst = 0.0f64;
    for y in (0..H).step_by(2) {
        for x in (0..W).step_by(2) {
            let (o, d) = rays.ray(x, y);
            let ray = (o.into(), d.into());
            // A twentieth of the ember's voxel (0.3 world units).
            let lt = mixture_lt(&cpu_insts, ray, t_far, 0.015, &mut scratch);
            let p = (y * W + x) as usize;
            for c in 0..3 {
                let want = (lt[c] + lt[3] * BG[c]) as f32;
                let diff = (g[4 * p + c] - want).abs();
                if diff.is_nan() || diff > worst {
                    worst = diff;
                    let only = cpu_lt_one_ray(&cpu_insts[..1], ray, f64::INFINITY, &mut scratch);
                    at = format!(
                        "pixel ({x}, {y}) channel {c}: gpu {}, cpu {want}, cloud alone {}",
                        g[4 * p + c],
                        only[c] + only[3] * BG[c]
                    );
                }
            }
            // The ember seen through the cloud: where sorting would go wrong.
            let ember_tau =
                cpu_insts[1].tracers[0]
                    .0
                    .optical_depth(o.into(), d.into(), t_far, &mut scratch);
            if ember_tau > 0.5 {
                inside += 1;
                let sorted = cpu_lt_one_ray(&cpu_insts, ray, f64::INFINITY, &mut scratch);
                for c in 0..3 {
                    sorted_worst = sorted_worst.max((sorted[c] - lt[c]).abs());
                }
            }
        }
    }
    eprintln!(
        "ember inside a cloud: max diff {worst:.2e} {at}; {inside} rays through the ember, \
         sorted compositing off by up to {sorted_worst:.3}"
    );
    assert!(inside > 20, "the ember is in view ({inside} rays)");
    assert!(
        sorted_worst > 10.0 * TOL as f64,
        "the scene tells interleaving from sorting"
    );
    assert!(worst <= TOL, "{at}");
}

/// `(L, T)` of the instances composited one after the other (the order given), along one ray
/// cut at `t_max`.
fn cpu_lt_one_ray(
    insts: &[CpuInstance],
    (o, d): ([f64; 3], [f64; 3]),
    t_max: f64,
    scratch: &mut Scratch,
) -> [f64; 4] {
    let (mut l, mut t) = ([0.0f64; 3], 1.0f64);
    for inst in insts {
        let tau: f64 = inst
            .tracers
            .iter()
            .map(|(tr, w)| w * tr.optical_depth(o, d, t_max, scratch))
            .sum();
        let ti = (-inst.absorb * tau).exp();
        for (c, lc) in l.iter_mut().enumerate() {
            *lc += t * inst.tint[c] as f64 * (1.0 - ti);
        }
        t *= ti;
    }
    [l[0], l[1], l[2], t]
}

/// Draws of two volumes, flat and lit, prepared and recorded into one encoder composite as they
/// do one submission each: every prepared draw keeps its own uniforms and light volumes (the lit
/// instances sit at different frames, so each draw has a build of its own).
#[test]
fn many_draws_in_one_encoder_equal_one_submission_each() {
    many_draws(Shading::default());
    many_draws(Shading {
        lighting: Some(Lighting {
            light_res: 16,
            ..Default::default()
        }),
        ..Default::default()
    });
}

fn many_draws(medium: Shading) {
    let Some(gpu) = Gpu::new("many_draws_in_one_encoder_equal_one_submission_each") else {
        return;
    };
    // Two volumes (one of them quantized), two instances each, different tints.
    let a = cloud(PayloadFormat::F32);
    let b = cloud(PayloadFormat::Unorm8);
    let (_va, mut da) = setup(&gpu, &a);
    let (_vb, mut db) = setup(&gpu, &b);
    let (view, cam) = framing_view(&a);
    let z = Some(ndc_depth(&view.proj, centre_distance(&cam)));
    let draws: Vec<(bool, Instance)> = (0..4)
        .map(|i| {
            (
                i % 2 == 0,
                Instance {
                    time: [0.0, 1.5, 2.0, 0.25][i],
                    tint: Vec3::new(1.0, 0.3 * i as f32, 0.5),
                    ..Instance::at(Affine3A::from_translation(Vec3::new(
                        8.0 * i as f32,
                        -4.0 * i as f32,
                        0.0,
                    )))
                },
            )
        })
        .collect();
    let target = |f: &'_ Frame| -> (wgpu::TextureView, wgpu::TextureView) {
        (f.color_view.clone(), f.depth_view.clone())
    };
    // One encoder.
    let f1 = gpu.frame();
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    gpu.clear(&mut enc, &f1, BG, z);
    let (c, d) = target(&f1);
    let mut held = Vec::new();
    for (first, inst) in &draws {
        let drawer = if *first { &mut da } else { &mut db };
        let t = DrawTarget {
            color: &c,
            depth: Some(&d),
        };
        held.push(
            drawer
                .draw(
                    &gpu.device,
                    &gpu.queue,
                    &mut enc,
                    &t,
                    &view,
                    &[*inst],
                    &medium,
                )
                .unwrap(),
        );
    }
    gpu.queue.submit([enc.finish()]);
    drop(held);
    let one = gpu.read(&f1);
    // One submission each.
    let f2 = gpu.frame();
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    gpu.clear(&mut enc, &f2, BG, z);
    gpu.queue.submit([enc.finish()]);
    let (c, d) = target(&f2);
    for (first, inst) in &draws {
        let drawer = if *first { &mut da } else { &mut db };
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        let t = DrawTarget {
            color: &c,
            depth: Some(&d),
        };
        let _held = drawer
            .draw(
                &gpu.device,
                &gpu.queue,
                &mut enc,
                &t,
                &view,
                &[*inst],
                &medium,
            )
            .unwrap();
        gpu.queue.submit([enc.finish()]);
    }
    let each = gpu.read(&f2);
    assert_eq!(one, each);
    let changed = (0..one.len())
        .filter(|&i| i % 4 != 3 && one[i] != f32::from(half::f16::from_f64(BG[i % 4])))
        .count();
    assert!(
        changed > 100,
        "the draws changed the picture ({changed} channels)"
    );
}

#[test]
fn crossfades_lerp_the_densities() {
    let Some(gpu) = Gpu::new("crossfades_lerp_the_densities") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let (_vol, mut drawer) = setup(&gpu, &asset);
    let f = gpu.frame();
    let medium = Shading::default();
    let (view, _) = framing_view(&asset);
    let rays = view.rays().unwrap();
    let draw = |drawer: &mut VolumeDrawer, time: f32| {
        let inst = Instance {
            time,
            ..Default::default()
        };
        let g = gpu.draw(drawer, &f, &view, &[inst], &medium, BG, None);
        let cpu = cpu_lt(&rays, &[cpu_instance(&asset, &inst, &medium)], None);
        (g, cpu)
    };
    let mut frames = Vec::new();
    for k in 0..3 {
        let (g, cpu) = draw(&mut drawer, k as f32);
        assert_matches(&format!("time {k}"), &g, &cpu, TOL);
        frames.push(g);
    }
    assert_ne!(frames[0], frames[1]);
    for time in [0.5f32, 1.25, 1.999] {
        let (g, cpu) = draw(&mut drawer, time);
        assert_matches(&format!("time {time}"), &g, &cpu, TOL);
    }
}

#[test]
fn standard_reversed_and_orthographic_projections() {
    let Some(gpu) = Gpu::new("standard_reversed_and_orthographic_projections") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let (_vol, mut drawer) = setup(&gpu, &asset);
    let f = gpu.frame();
    let medium = Shading::default();
    let inst = [Instance::default()];
    let (base, cam) = framing_view(&asset);
    let mid = centre_distance(&cam);
    let aspect = W as f32 / H as f32;
    let fov = (cam.fov_y_deg as f32).to_radians();
    let half_h = mid * (0.5 * fov).tan();
    let projections = [
        (
            "standard Z",
            vdbcook_runtime::glam::camera::rh::proj::directx::perspective(
                fov,
                aspect,
                0.5,
                4.0 * mid,
            ),
        ),
        (
            "reversed Z",
            vdbcook_runtime::glam::camera::rh::proj::directx::perspective(
                fov,
                aspect,
                4.0 * mid,
                0.5,
            ),
        ),
        (
            "standard Z, infinite far",
            vdbcook_runtime::glam::camera::rh::proj::directx::perspective_infinite(
                fov, aspect, 0.5,
            ),
        ),
        (
            "orthographic",
            vdbcook_runtime::glam::camera::rh::proj::directx::orthographic(
                -half_h * aspect,
                half_h * aspect,
                -half_h,
                half_h,
                0.1 * mid,
                3.0 * mid,
            ),
        ),
        (
            "orthographic, reversed Z",
            vdbcook_runtime::glam::camera::rh::proj::directx::orthographic(
                -half_h * aspect,
                half_h * aspect,
                -half_h,
                half_h,
                3.0 * mid,
                0.1 * mid,
            ),
        ),
    ];
    for (what, proj) in projections {
        let view = View::new(base.view, proj, (W, H)).unwrap();
        let rays = view.rays().unwrap();
        let mut free: Vec<[f64; 4]> = Vec::new();
        for (plane, depth) in [("no depth", None), ("depth", Some(ndc_depth(&proj, mid)))] {
            let g = gpu.draw(&mut drawer, &f, &view, &inst, &medium, BG, depth);
            let cpu = cpu_lt(&rays, &[cpu_instance(&asset, &inst[0], &medium)], depth);
            if depth.is_none() {
                free = cpu.clone();
            } else {
                let thinner = (0..cpu.len())
                    .filter(|&p| cpu[p][3] > free[p][3] + 0.05)
                    .count();
                assert!(
                    thinner > 100,
                    "{what}: the depth plane cuts the cloud ({thinner})"
                );
            }
            assert_matches(&format!("{what}, {plane}"), &g, &cpu, TOL);
            assert!(
                cpu.iter().filter(|p| p[3] < 0.9).count() > 100,
                "{what}, {plane}: the cloud is in view"
            );
        }
    }
}

#[test]
fn bad_inputs_are_errors() {
    let Some(gpu) = Gpu::new("bad_inputs_are_errors") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let (vol, mut drawer) = setup(&gpu, &asset);
    let f = gpu.frame();
    let (view, _) = framing_view(&asset);
    let medium = Shading::default();
    let inst = [Instance::default()];
    let tex = |w, h, format, usage| {
        gpu.device
            .create_texture(&wgpu::TextureDescriptor {
                label: None,
                size: wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
            .create_view(&Default::default())
    };
    let depth_usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
    let small_depth = tex(W / 2, H, wgpu::TextureFormat::Depth32Float, depth_usage);
    let d16 = tex(W, H, wgpu::TextureFormat::Depth16Unorm, depth_usage);
    let rgba8 = tex(
        W,
        H,
        wgpu::TextureFormat::Rgba8Unorm,
        wgpu::TextureUsages::RENDER_ATTACHMENT,
    );
    let mut record = |target: DrawTarget, view: &View, insts: &[Instance]| {
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        drawer.draw(
            &gpu.device,
            &gpu.queue,
            &mut enc,
            &target,
            view,
            insts,
            &medium,
        )
    };
    let with_depth = |d| DrawTarget {
        color: &f.color_view,
        depth: Some(d),
    };
    let e = record(with_depth(&small_depth), &view, &inst).unwrap_err();
    assert!(
        matches!(e, RuntimeError::Target(_)) && e.to_string().contains("80x96"),
        "{e}"
    );
    let e = record(with_depth(&d16), &view, &inst).unwrap_err();
    assert!(e.to_string().contains("Depth16Unorm"), "{e}");
    let e = record(
        DrawTarget {
            color: &rgba8,
            depth: None,
        },
        &view,
        &inst,
    )
    .unwrap_err();
    assert!(e.to_string().contains("Rgba8Unorm"), "{e}");
    let ok = DrawTarget {
        color: &f.color_view,
        depth: Some(&f.depth_view),
    };
    // A singular view matrix (a user's bug: an all-zero matrix, or a degenerate scale).
    let singular = View {
        view: Mat4::from_scale(Vec3::new(1.0, 0.0, 1.0)),
        ..view
    };
    let e = record(ok, &singular, &inst).unwrap_err();
    assert!(
        matches!(e, RuntimeError::Camera(_)) && e.to_string().contains("singular"),
        "{e}"
    );
    // A viewport other than the targets'.
    let e = record(
        ok,
        &View {
            viewport: (W, H + 1),
            ..view
        },
        &inst,
    )
    .unwrap_err();
    assert!(matches!(e, RuntimeError::Target(_)), "{e}");
    // Time out of range, NaN time, negative density.
    for bad in [
        Instance {
            time: 2.5,
            ..Default::default()
        },
        Instance {
            time: f32::NAN,
            ..Default::default()
        },
        Instance {
            density_scale: -1.0,
            ..Default::default()
        },
    ] {
        let e = record(ok, &view, &[Instance::default(), bad]).unwrap_err();
        assert!(matches!(e, RuntimeError::Setting(_)), "{e}");
    }
    let e = record(
        ok,
        &view,
        &[Instance {
            time: 7.0,
            ..Default::default()
        }],
    )
    .unwrap_err();
    assert!(e.to_string().contains("[0, 2]"), "{e}");
    // A colour format the composite cannot blend onto.
    let Err(e) = VolumeDrawer::new(&gpu.device, &vol, wgpu::TextureFormat::Rgba32Float) else {
        panic!("Rgba32Float accepted");
    };
    assert!(matches!(e, RuntimeError::Target(_)), "{e}");
    // Every listed format builds.
    for format in vdbcook_runtime::DRAW_COLOR_FORMATS {
        VolumeDrawer::new(&gpu.device, &vol, format).unwrap();
    }
    // Nothing went wrong on the device.
    let _ = gpu.device.poll(wgpu::PollType::wait_indefinitely());
}

#[test]
fn srgb_8_bit_targets_blend_in_linear_space() {
    let Some(gpu) = Gpu::new("srgb_8_bit_targets_blend_in_linear_space") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let vol = GpuVolume::upload(&gpu.device, &gpu.queue, &asset).expect("upload");
    let format = wgpu::TextureFormat::Bgra8UnormSrgb;
    let mut drawer = VolumeDrawer::new(&gpu.device, &vol, format).expect("drawer");
    let (view, _) = framing_view(&asset);
    let medium = Shading::default();
    let inst = [Instance {
        tint: Vec3::new(1.0, 0.6, 0.3),
        ..Default::default()
    }];
    let color = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: None,
        size: wgpu::Extent3d {
            width: W,
            height: H,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let cv = color.create_view(&Default::default());
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    let _ = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: None,
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: &cv,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color {
                    r: BG[0],
                    g: BG[1],
                    b: BG[2],
                    a: 1.0,
                }),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    let target = DrawTarget {
        color: &cv,
        depth: None,
    };
    let _held = drawer
        .draw(
            &gpu.device,
            &gpu.queue,
            &mut enc,
            &target,
            &view,
            &inst,
            &medium,
        )
        .unwrap();
    // 160 texels · 4 bytes = 640: rows padded to 768 for the copy.
    let row = 768u32;
    let buf = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: (row * H) as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    enc.copy_texture_to_buffer(
        color.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buf,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: Some(H),
            },
        },
        color.size(),
    );
    gpu.queue.submit([enc.finish()]);
    buf.slice(..)
        .map_async(wgpu::MapMode::Read, |r| r.expect("map"));
    gpu.device
        .poll(wgpu::PollType::wait_indefinitely())
        .expect("poll");
    let bytes = vdbcook_runtime::gpu_compat::mapped_range(&buf.slice(..))
        .expect("mapped")
        .to_vec();
    let cpu = cpu_lt(
        &view.rays().unwrap(),
        &[cpu_instance(&asset, &inst[0], &medium)],
        None,
    );
    let to_srgb = |l: f64| {
        let l = l.clamp(0.0, 1.0);
        255.0
            * if l <= 0.0031308 {
                12.92 * l
            } else {
                1.055 * l.powf(1.0 / 2.4) - 0.055
            }
    };
    let mut worst = 0.0f64;
    for y in 0..H as usize {
        for x in 0..W as usize {
            let lt = cpu[y * W as usize + x];
            let px = &bytes[y * row as usize + 4 * x..][..4];
            // BGRA in memory.
            for (c, &b) in [2usize, 1, 0].iter().zip(&px[..3]) {
                let want = to_srgb(lt[*c] + lt[3] * BG[*c]);
                worst = worst.max((b as f64 - want).abs());
            }
            assert_eq!(px[3], 255, "the target's alpha is kept");
        }
    }
    eprintln!("Bgra8UnormSrgb: within {worst:.2} of 255 levels of the CPU");
    // Half-float (L, T), then 8-bit sRGB: at most one level plus rounding.
    assert!(worst <= 1.6, "{worst} levels");
}

/// The sun's shadows an engine reads (`shadow_wgsl`'s `vdb_sun_transmittance`, bound through
/// `VolumeDrawer::sun_shadows`) against the CPU's `Tracer::sun_transmittance` of each lit
/// instance on the moved asset, multiplied: at a lattice of world points around, inside and under
/// two instances (one translated at frame 0, one rotated and scaled in a crossfade at time 1.5,
/// whose optical depths lerp).
/// `record` only records: it takes no device, so it cannot create a buffer, a bind group or a
/// pipeline (a signature that gained one would not compile here); `prepare` makes what it
/// binds.
#[test]
fn record_takes_no_device_and_creates_nothing() {
    let _: fn(&VolumeDrawer, &mut wgpu::CommandEncoder, &vdbcook_runtime::PreparedDraw) =
        VolumeDrawer::record;
}

/// A draw prepared for one colour texture and recorded onto another of the same kind (an
/// engine's ping-pong targets, as Bevy's) lands on the other exactly as a draw prepared for it
/// does, and leaves the first untouched; a texture of another size is refused.
#[test]
fn record_onto_another_texture_of_the_same_kind() {
    let Some(gpu) = Gpu::new("record_onto_another_texture_of_the_same_kind") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let (_vol, mut drawer) = setup(&gpu, &asset);
    let (fa, fb) = (gpu.frame(), gpu.frame());
    let (view, _) = framing_view(&asset);
    let inst = [Instance::default()];
    let medium = Shading::default();
    let bg = [0.2, 0.3, 0.4];
    let direct = gpu.draw(&mut drawer, &fb, &view, &inst, &medium, bg, None);
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    gpu.clear(&mut enc, &fa, bg, None);
    gpu.clear(&mut enc, &fb, bg, None);
    let target = DrawTarget {
        color: &fa.color_view,
        depth: None,
    };
    let draw = drawer
        .prepare(&gpu.device, &gpu.queue, &target, &view, &inst, &medium)
        .expect("prepare");
    drawer
        .record_onto(&mut enc, &draw, &fb.color_view)
        .expect("same kind of texture");
    gpu.queue.submit([enc.finish()]);
    let (onto, first) = (gpu.read(&fb), gpu.read(&fa));
    assert_eq!(onto, direct, "recorded onto B = prepared for B");
    // Untouched: every pixel still the clear colour (as the half-float target stores it).
    let uniform = |v: &[f32]| v.chunks(4).all(|p| p == &v[..4]);
    assert!(uniform(&first), "A untouched");
    assert!((first[0] - bg[0] as f32).abs() < 1e-3);
    assert!(!uniform(&onto), "the volume is in B");
    let small = gpu
        .device
        .create_texture(&wgpu::TextureDescriptor {
            label: Some("small"),
            size: wgpu::Extent3d {
                width: W / 2,
                height: H,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        })
        .create_view(&Default::default());
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    let refused = drawer.record_onto(&mut enc, &draw, &small);
    assert!(
        matches!(refused, Err(vdbcook_runtime::RuntimeError::Target(_))),
        "{refused:?}"
    );
}

/// A lit draw whose encoder is dropped unsubmitted leaves nothing unbuilt: the next draw of the
/// same instances (the same light volumes) draws what a fresh drawer draws. (Before the light
/// volumes were built in the caller's encoder, and a cache hit after a dropped one read
/// volumes never built: 4,375 wrong pixels in an engine client.)
#[test]
fn a_dropped_encoder_leaves_the_next_lit_draw_right() {
    let Some(gpu) = Gpu::new("a_dropped_encoder_leaves_the_next_lit_draw_right") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let (_vol, mut drawer) = setup(&gpu, &asset);
    let (_vol2, mut fresh) = setup(&gpu, &asset);
    let medium = Shading {
        lighting: Some(Lighting {
            light_res: 20,
            ..Default::default()
        }),
        ..Default::default()
    };
    let f = gpu.frame();
    let (view, _) = framing_view(&asset);
    let inst = [Instance::default()];
    {
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        let target = DrawTarget {
            color: &f.color_view,
            depth: None,
        };
        let d = drawer
            .draw(
                &gpu.device,
                &gpu.queue,
                &mut enc,
                &target,
                &view,
                &inst,
                &medium,
            )
            .unwrap();
        drop(enc);
        drop(d);
    }
    let again = gpu.draw(&mut drawer, &f, &view, &inst, &medium, BG, None);
    let want = gpu.draw(&mut fresh, &f, &view, &inst, &medium, BG, None);
    assert!(
        want.chunks(4).any(|p| (p[0] as f64 - BG[0]).abs() > 0.05),
        "the cloud shows"
    );
    assert_eq!(again, want);
}

/// A crossfade moving on by one frame builds one light volume and copies the other from the
/// build before (issue 34: crossfaded frames share work), in both multiple-scattering models
/// (the diffusion model copies its solve too): the image is the one a fresh drawer, which
/// builds both, gives at the same time, bit for bit; a pair drawn again builds nothing.
#[test]
fn a_crossfade_moving_on_builds_one_light_volume_and_draws_as_a_fresh_drawer() {
    let Some(gpu) =
        Gpu::new("a_crossfade_moving_on_builds_one_light_volume_and_draws_as_a_fresh_drawer")
    else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let f = gpu.frame();
    let (view, _) = framing_view(&asset);
    for ms_model in [MsModel::Diffusion, MsModel::Octaves] {
        let (_vol, mut drawer) = setup(&gpu, &asset);
        let medium = lit_with(ms_model);
        gpu.draw(&mut drawer, &f, &view, &at_time(0.5), &medium, BG, None);
        let first = drawer.light_builds();
        assert_eq!((first.built, first.reused), (2, 0), "{ms_model:?}");
        let moved_on = gpu.draw(&mut drawer, &f, &view, &at_time(1.5), &medium, BG, None);
        let next = drawer.light_builds();
        assert_eq!(
            (next.built, next.reused),
            (3, 1),
            "{ms_model:?}: frame 1 copied"
        );
        let (_vol2, mut fresh) = setup(&gpu, &asset);
        let want = gpu.draw(&mut fresh, &f, &view, &at_time(1.5), &medium, BG, None);
        assert!(
            want.chunks(4).any(|p| (p[0] as f64 - BG[0]).abs() > 0.05),
            "the cloud shows"
        );
        assert_eq!(moved_on, want, "{ms_model:?}");
        assert_eq!(fresh.light_builds().built, 2);
        gpu.draw(&mut drawer, &f, &view, &at_time(1.75), &medium, BG, None);
        let again = drawer.light_builds();
        assert_eq!(
            (again.built, again.reused),
            (3, 3),
            "{ms_model:?}: same pair"
        );
    }
}

/// Light built ahead (`VolumeDrawer::set_light_ahead`, issue 34: light volumes amortized over
/// displayed frames): a flip-book played at 0.4 frames per displayed frame, then stopped, in
/// both multiple-scattering models. Each displayed frame is the image of a drawer that builds
/// every light volume when it needs it, bit for bit (the light is the exact build, moving on and
/// stopped); frame 2's volume is built over the two displayed frames before its pair is shown
/// (spread 2), and the displayed frame that reaches it builds nothing (its volumes are copied);
/// each of the three frames' volumes is built once in all, none wasted; stopped, the drawer
/// builds nothing more. Then one drawer draws two lights in turn, every image the exact build's.
/// (That a build ahead has a scratch of its own, apart from `prepare`'s, is by construction; no
/// test here makes `prepare` build between two shares of one volume.)
#[test]
fn light_built_ahead_is_the_exact_build_spread_over_displayed_frames() {
    let Some(gpu) = Gpu::new("light_built_ahead_is_the_exact_build_spread_over_displayed_frames")
    else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let f = gpu.frame();
    let (view, _) = framing_view(&asset);
    for ms_model in [MsModel::Diffusion, MsModel::Octaves] {
        let (_vol, mut ahead) = setup(&gpu, &asset);
        ahead.set_light_ahead(2);
        let (_vol2, mut exact) = setup(&gpu, &asset);
        let medium = lit_with(ms_model);
        let mut shown = false;
        for (k, time) in [0.0f32, 0.4, 0.8, 1.2, 1.6, 1.6, 1.6]
            .into_iter()
            .enumerate()
        {
            let before = ahead.light_builds();
            let got = gpu.draw(&mut ahead, &f, &view, &at_time(time), &medium, BG, None);
            let after = ahead.light_builds();
            let want = gpu.draw(&mut exact, &f, &view, &at_time(time), &medium, BG, None);
            shown |= want.chunks(4).any(|p| (p[0] as f64 - BG[0]).abs() > 0.05);
            assert!(
                got == want,
                "{ms_model:?}: time {time} differs from the exact build"
            );
            let own = (after.built - after.ahead) - (before.built - before.ahead);
            eprintln!("{ms_model:?} time {time}: {after:?} (built in the frame itself: {own})");
            if time == 0.4 {
                // Frame 1's build finished, frame 2's begun: a half of it in this frame.
                assert_eq!(after.ahead, 1, "{ms_model:?}: {after:?}");
            }
            if time == 0.8 {
                assert_eq!(
                    (own, after.ahead),
                    (0, 2),
                    "{ms_model:?}: frame 2's second half"
                );
            }
            if time == 1.2 {
                assert_eq!(
                    after.built, before.built,
                    "{ms_model:?}: frame 2 was built ahead"
                );
            }
            if k >= 5 {
                assert_eq!(
                    after.built, before.built,
                    "{ms_model:?}: stopped, nothing built"
                );
            }
        }
        assert!(shown, "the cloud shows");
        assert_eq!(
            ahead.light_builds().built,
            3,
            "{ms_model:?}: each frame's volume once"
        );
        assert_eq!(exact.light_builds().built, 3, "{ms_model:?}");
    }
    // Two lights drawn in turn by one drawer: each light's volumes built ahead are shared out
    // over both lights' draws, and every image is still the exact build's.
    let (_vol3, mut both) = setup(&gpu, &asset);
    both.set_light_ahead(3);
    let shadings = [[0.3f32, 0.3, 0.0], [-0.3, 0.8, 0.5]].map(|light_dir| Shading {
        lighting: Some(Lighting {
            light_res: 20,
            light_dir,
            ..Default::default()
        }),
        ..Default::default()
    });
    let mut exact: Vec<_> = shadings.iter().map(|_| setup(&gpu, &asset)).collect();
    for k in 0..10 {
        let time = 0.2 * k as f32;
        for (s, (_, ex)) in shadings.iter().zip(&mut exact) {
            let inst = [Instance {
                time,
                ..Default::default()
            }];
            let got = gpu.draw(&mut both, &f, &view, &inst, s, BG, None);
            let want = gpu.draw(ex, &f, &view, &inst, s, BG, None);
            assert!(
                got == want,
                "two lights: time {time} differs from the exact build"
            );
        }
    }
    let counts = both.light_builds();
    assert!(counts.ahead >= 4, "two lights: {counts:?}");
}

/// A cell-space box `(lo, hi)`.
type Box3 = ([f64; 3], [f64; 3]);

/// A light stride (`Instance::light_stride`, issue 34 item 2: a playing effect lit by one light
/// volume per span of frames). The 3-frame cloud at stride 3 is one span, lit by frame 1's light
/// volume over the union of the three frames' content boxes: each frame drawn so matches the
/// CPU's lit mode of that frame with its light taken from frame 1 over that box
/// (`Tracer::with_light_from`, the box taken here from `content_box` of each frame), in both
/// multiple-scattering models, and frames 0 and 2 visibly differ from their exact light (so the
/// test sees the stride). The span builds one light volume for its three frames; stopped
/// (stride 1) the drawer builds the frame's own volume and draws what a fresh drawer draws, bit
/// for bit.
#[test]
fn a_light_stride_lights_a_span_from_its_middle_frame() {
    let Some(gpu) = Gpu::new("a_light_stride_lights_a_span_from_its_middle_frame") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let f = gpu.frame();
    let (view, cam) = framing_view(&asset);
    let rays = view.rays().unwrap();
    let boxes: Vec<_> = (0..3).map(|k| content_box(&asset, k).unwrap()).collect();
    let union = (
        [0, 1, 2].map(|k| boxes.iter().map(|b| b.0[k]).fold(f64::INFINITY, f64::min)),
        [0, 1, 2].map(|k| {
            boxes
                .iter()
                .map(|b| b.1[k])
                .fold(f64::NEG_INFINITY, f64::max)
        }),
    );
    assert!(
        boxes.iter().all(|b| *b != union),
        "the frames' boxes differ"
    );
    for ms_model in [MsModel::Diffusion, MsModel::Octaves] {
        let medium = lit_with(ms_model);
        let cpu = |frame: usize, light: Option<(usize, Option<Box3>)>| {
            let base = medium.settings();
            let s = RenderSettings {
                output: Output {
                    frame,
                    ..base.output
                },
                ..base
            };
            let tracer = Tracer::with_light_from(&asset, &cam, &s, light).unwrap();
            let mut scratch = Scratch::default();
            let mut out = Vec::new();
            for y in 0..H {
                for x in 0..W {
                    let (o, d) = rays.ray(x, y);
                    let px = tracer.trace(o.into(), d.into(), y * W + x, &mut scratch);
                    let r = px.rgba;
                    out.push([r[0] as f64, r[1] as f64, r[2] as f64, px.value as f64]);
                }
            }
            out
        };
        let (_vol, mut drawer) = setup(&gpu, &asset);
        for frame in [0usize, 1, 2] {
            let inst = [Instance {
                time: frame as f32,
                light_stride: 3,
                ..Default::default()
            }];
            let g = gpu.draw(&mut drawer, &f, &view, &inst, &medium, BG, None);
            let what = format!("{ms_model:?}, frame {frame} at stride 3");
            assert_matches(&what, &g, &cpu(frame, Some((1, Some(union)))), 2.0 * TOL);
            if frame != 1 {
                let (d, at) = max_diff(&g, &cpu(frame, None), BG);
                eprintln!("{what}: against its exact light {d:.2e} {at}");
                assert!(d > 10.0 * TOL, "{what}: the stride shows ({d})");
            }
        }
        assert_eq!(
            drawer.light_builds().built,
            1,
            "{ms_model:?}: one volume a span"
        );
        // Stopped: the frame's own light, as a fresh drawer draws it.
        let got = gpu.draw(&mut drawer, &f, &view, &at_time(2.0), &medium, BG, None);
        assert_eq!(drawer.light_builds().built, 2, "{ms_model:?}: stopped");
        let (_vol2, mut fresh) = setup(&gpu, &asset);
        let want = gpu.draw(&mut fresh, &f, &view, &at_time(2.0), &medium, BG, None);
        assert!(got == want, "{ms_model:?}: stopped, the exact light");
        // Stride 2: spans [0, 2) (frame 0's light over frames 0 and 1's boxes) and the short
        // last span [2, 3), which is frame 2's own light, the exact build's bits. A crossfade
        // within the first span builds nothing more and reads one light volume.
        let union01 = (
            [0, 1, 2].map(|k| boxes[0].0[k].min(boxes[1].0[k])),
            [0, 1, 2].map(|k| boxes[0].1[k].max(boxes[1].1[k])),
        );
        let (_vol3, mut two) = setup(&gpu, &asset);
        let stride2 = |time: f32| {
            [Instance {
                time,
                light_stride: 2,
                ..Default::default()
            }]
        };
        let g = gpu.draw(&mut two, &f, &view, &stride2(1.0), &medium, BG, None);
        let what = format!("{ms_model:?}, frame 1 at stride 2");
        assert_matches(&what, &g, &cpu(1, Some((0, Some(union01)))), 2.0 * TOL);
        let half = gpu.draw(&mut two, &f, &view, &stride2(0.5), &medium, BG, None);
        assert_eq!(
            two.light_builds().built,
            1,
            "{ms_model:?}: a crossfade in one span"
        );
        assert!(half != g, "{ms_model:?}: the crossfade draws");
        let last = gpu.draw(&mut two, &f, &view, &stride2(2.0), &medium, BG, None);
        assert!(
            last == want,
            "{ms_model:?}: the short last span is frame 2's own light"
        );
    }
}

/// `LitCrossfade::Dither` takes each sample (density and light) from one frame: frame 1 where
/// the per-sample sequence falls below the crossfade weight. Checked against `Lerp` (both
/// frames per sample, lerped), whose whole frames the other tests pin to the CPU:
/// - a whole frame is the same image bit for bit;
/// - near either end of a crossfade (weight 0.001 or 0.999) the dither takes that end's frame on
///   nearly every sample: the mean difference from the lerp over the image is under 2% of the
///   mean change the crossfade makes and its RMSE under a quarter of the change's (the mapping
///   reversed would be about all of it);
/// - halfway it differs from the lerp (it did dither), its mean within 5% of the change (the
///   sequence spreads frame 1 over half of each ray's samples; what is left is second order in
///   the frames' difference) and its RMSE under a quarter of the change's (the grain).
///
/// This test's frames differ far more than a simulation's neighbouring frames do (the blobs
/// jump: the crossfade changes the light by about its whole amount), so its grain is the worst
/// case; on stormscape `vdbcook bench` measures it at about 1e-4.
#[test]
fn a_dithered_crossfade_takes_each_sample_from_one_frame() {
    let Some(gpu) = Gpu::new("a_dithered_crossfade_takes_each_sample_from_one_frame") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let f = gpu.frame();
    let (view, _) = framing_view(&asset);
    let lit = lit_shading();
    let draw = |how: LitCrossfade, time: f32| {
        let (_vol, mut drawer) = setup(&gpu, &asset);
        drawer.set_lit_crossfade(how);
        let inst = [Instance {
            time,
            ..Default::default()
        }];
        gpu.draw(&mut drawer, &f, &view, &inst, &lit, BG, None)
    };
    // (mean signed difference, mean absolute difference, RMSE) of `b` against `a` over every
    // pixel and channel.
    let diff = |a: &[f32], b: &[f32]| {
        let (mut sum, mut abs, mut sq, mut n) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for (a, b) in a.chunks(4).zip(b.chunks(4)) {
            for k in 0..3 {
                let d = b[k] as f64 - a[k] as f64;
                sum += d;
                abs += d.abs();
                sq += d * d;
                n += 1.0;
            }
        }
        (sum / n, abs / n, (sq / n).sqrt())
    };
    assert_eq!(
        draw(LitCrossfade::Dither, 1.0),
        draw(LitCrossfade::Lerp, 1.0),
        "a whole frame"
    );
    // The change the crossfade makes: the lerp near its two ends.
    let (lo, hi) = (1.001f32, 1.999f32);
    let ends = [lo, hi].map(|t| draw(LitCrossfade::Lerp, t));
    let (_, mean_change, rms_change) = diff(&ends[0], &ends[1]);
    assert!(mean_change > 0.01, "the frames differ: {mean_change}");
    for (t, lerp) in [lo, hi].into_iter().zip(&ends) {
        let (mean, _, rms) = diff(lerp, &draw(LitCrossfade::Dither, t));
        eprintln!(
            "time {t}: dither - lerp mean {mean:.2e}, RMSE {rms:.2e} (change: mean {mean_change:.3}, RMS {rms_change:.3})"
        );
        assert!(
            mean.abs() <= 0.02 * mean_change,
            "time {t}: {mean} against {mean_change}"
        );
        assert!(
            rms <= 0.25 * rms_change,
            "time {t}: RMSE {rms} against {rms_change}"
        );
    }
    let (mean, _, rms) = diff(
        &draw(LitCrossfade::Lerp, 1.5),
        &draw(LitCrossfade::Dither, 1.5),
    );
    eprintln!(
        "time 1.5: dither - lerp mean {mean:.2e}, RMSE {rms:.2e} (change: mean {mean_change:.3}, RMS {rms_change:.3})"
    );
    assert!(
        mean.abs() <= 0.05 * mean_change,
        "halfway: mean {mean} against {mean_change}"
    );
    assert!(
        rms > 0.0 && rms <= 0.25 * rms_change,
        "halfway: RMSE {rms} against {rms_change}"
    );
}

/// The reduced-resolution marches (`MarchResolution::Half`, `Quarter`), flat and lit: with
/// nothing cutting the cloud each is the full draw upsampled (relative RMSE of the drawn light
/// against the full draw's within the bound below, and not 0: it did march fewer rays); with a
/// depth plane through the cloud the blocks with a depth edge among the volumes are marched per
/// pixel, as the full draw marches them (within the same bound); with a plane in front of the
/// cloud nothing is drawn (the background, bit for bit). The bounds are the design's (this test
/// image is small, 160×96, so a block is a large part of the cloud): measured on lavapipe half
/// 0.016 flat / 0.058 lit, the lit march's per-pixel jitter included.
#[test]
fn half_resolution_march_upsamples_away_from_depth_edges() {
    let Some(gpu) = Gpu::new("half_resolution_march_upsamples_away_from_depth_edges") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let (view, cam) = framing_view(&asset);
    let mid = centre_distance(&cam);
    let f = gpu.frame();
    let inst = [Instance::default()];
    let lit = lit_shading();
    // Relative RMSE of the light drawn over the background (RGB), and the pixels that differ.
    let error = |full: &[f32], half: &[f32]| {
        let (mut num, mut den, mut differ) = (0.0f64, 0.0f64, 0usize);
        for (a, b) in full.chunks(4).zip(half.chunks(4)) {
            let mut same = true;
            for k in 0..3 {
                num += (b[k] as f64 - a[k] as f64).powi(2);
                den += (a[k] as f64 - BG[k]).powi(2);
                same &= a[k] == b[k];
            }
            differ += !same as usize;
        }
        ((num / den).sqrt(), differ)
    };
    let cases = [
        (
            "flat, half",
            Shading::default(),
            MarchResolution::Half,
            0.04,
        ),
        ("lit, half", lit.clone(), MarchResolution::Half, 0.08),
        (
            "flat, quarter",
            Shading::default(),
            MarchResolution::Quarter,
            0.08,
        ),
        ("lit, quarter", lit, MarchResolution::Quarter, 0.15),
    ];
    for (what, medium, resolution, bound) in cases {
        let (_v, mut full) = setup(&gpu, &asset);
        let (_v2, mut half) = setup(&gpu, &asset);
        half.set_march_resolution(resolution);
        assert_eq!(half.march_resolution(), resolution);
        let mut draw = |depth: Option<f32>| {
            (
                gpu.draw(&mut full, &f, &view, &inst, &medium, BG, depth),
                gpu.draw(&mut half, &f, &view, &inst, &medium, BG, depth),
            )
        };
        let (a, b) = draw(None);
        let (free, differ) = error(&a, &b);
        eprintln!("{what}, nothing cutting: relative RMSE {free:.4}, {differ} pixels differ");
        assert!(free > 0.0 && free < bound, "{what}: {free}");
        let (a, b) = draw(Some(ndc_depth(&view.proj, mid)));
        let (cut, differ) = error(&a, &b);
        eprintln!(
            "{what}, a plane through the cloud: relative RMSE {cut:.4}, {differ} pixels differ"
        );
        assert!(cut < bound, "{what}: {cut}");
        let (a, b) = draw(Some(ndc_depth(&view.proj, 0.2 * mid)));
        assert_eq!(a, b, "{what}: a plane in front of the cloud");
    }
}

/// Writes `left` as the depth of the pixels left of column `split` and `right` right of it
/// (a depth-only pass: an occluder's straight edge), with the colour cleared to `BG`.
fn step_depth(gpu: &Gpu, enc: &mut wgpu::CommandEncoder, f: &Frame, split: u32, depths: [f32; 2]) {
    gpu.clear(enc, f, BG, Some(0.0));
    let source = format!(
        "@vertex fn vs(@builtin(vertex_index) v: u32, @builtin(instance_index) i: u32) \
         -> @builtin(position) vec4<f32> {{\n\
         let xy = vec2<f32>(f32((v << 1u) & 2u), f32(v & 2u)) * 2.0 - 1.0;\n\
         return vec4<f32>(xy, select({:.9}, {:.9}, i == 1u), 1.0);\n}}",
        depths[0], depths[1]
    );
    let module = gpu
        .device
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("test step depth"),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
    let pipeline = gpu
        .device
        .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("test step depth"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: wgpu::TextureFormat::Depth32Float,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Always),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: None,
            multiview_mask: None,
            cache: None,
        });
    let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("test step depth"),
        color_attachments: &[],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: &f.depth_view,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Load,
                store: wgpu::StoreOp::Store,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    pass.set_pipeline(&pipeline);
    pass.set_scissor_rect(0, 0, split, H);
    pass.draw(0..3, 0..1);
    pass.set_scissor_rect(split, 0, W - split, H);
    pass.draw(0..3, 1..2);
}

/// An occluder's straight edge in front of the cloud, on a block boundary (column 80, a multiple
/// of 2 and 4), with the cloud showing beside it: at every march resolution the occluder's
/// pixels keep the background bit for bit (no cloud bleeds over the edge: the blocks beside it
/// are marched per pixel) and the first visible column is what the full march draws there.
#[test]
fn reduced_resolution_keeps_an_occluders_edge() {
    let Some(gpu) = Gpu::new("reduced_resolution_keeps_an_occluders_edge") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let (view, cam) = framing_view(&asset);
    let mid = centre_distance(&cam);
    let f = gpu.frame();
    let inst = [Instance::default()];
    let split = W / 2;
    let depths = [
        ndc_depth(&view.proj, 0.2 * mid),
        ndc_depth(&view.proj, 4.0 * mid),
    ];
    let lit = lit_shading();
    let bg16 = BG.map(|v| half::f16::from_f64(v).to_f32());
    for (what, medium) in [("flat", Shading::default()), ("lit", lit)] {
        let mut images = Vec::new();
        for resolution in [
            MarchResolution::Full,
            MarchResolution::Half,
            MarchResolution::Quarter,
        ] {
            let (_v, mut drawer) = setup(&gpu, &asset);
            drawer.set_march_resolution(resolution);
            let mut enc = gpu.device.create_command_encoder(&Default::default());
            step_depth(&gpu, &mut enc, &f, split, depths);
            let target = DrawTarget {
                color: &f.color_view,
                depth: Some(&f.depth_view),
            };
            let _held = drawer
                .draw(
                    &gpu.device,
                    &gpu.queue,
                    &mut enc,
                    &target,
                    &view,
                    &inst,
                    &medium,
                )
                .expect("draw");
            gpu.queue.submit([enc.finish()]);
            images.push((resolution, gpu.read(&f)));
        }
        let full = &images[0].1;
        let at = |img: &[f32], x: u32, y: u32| {
            let k = 4 * (y * W + x) as usize;
            [img[k], img[k + 1], img[k + 2]]
        };
        let shows = (0..H).filter(|&y| at(full, split, y) != bg16).count();
        assert!(
            shows > 10,
            "{what}: the cloud shows beside the edge ({shows} rows)"
        );
        for (resolution, img) in &images {
            for y in 0..H {
                for x in 0..split {
                    assert_eq!(
                        at(img, x, y),
                        bg16,
                        "{what} {resolution:?}: ({x}, {y}) is hidden"
                    );
                }
                assert_eq!(
                    at(img, split, y),
                    at(full, split, y),
                    "{what} {resolution:?}: ({split}, {y}), the first visible column"
                );
            }
        }
    }
}

/// The draw covers the pixels its instances can reach and no more: a small instance far off
/// costs a small dispatch (`PreparedDraw::covered`), every pixel it changes lies inside it, and
/// the image is what a draw over the whole viewport gives (the moved instance's CPU image
/// agrees in `moved_and_jittered_instances_match_the_cpu`).
#[test]
fn a_small_instance_covers_a_small_rectangle() {
    let Some(gpu) = Gpu::new("a_small_instance_covers_a_small_rectangle") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    let (_vol, mut drawer) = setup(&gpu, &asset);
    let f = gpu.frame();
    let (view, _) = framing_view(&asset);
    let medium = Shading::default();
    // A quarter-size copy shifted toward a corner of the view.
    let inst = [Instance::at(Affine3A::from_scale_rotation_translation(
        Vec3::splat(0.25),
        Quat::IDENTITY,
        Vec3::new(-20.0, 12.0, 0.0),
    ))];
    let target = DrawTarget {
        color: &f.color_view,
        depth: None,
    };
    let d = drawer
        .prepare(&gpu.device, &gpu.queue, &target, &view, &inst, &medium)
        .unwrap();
    let [x, y, w, h] = d.covered();
    assert!(
        (w * h) as f64 <= 0.15 * (W * H) as f64,
        "covered {w}x{h} of {W}x{H}"
    );
    drop(d);
    let g = gpu.draw(&mut drawer, &f, &view, &inst, &medium, BG, None);
    let mut changed = 0;
    for py in 0..H {
        for px in 0..W {
            let p = (py * W + px) as usize;
            let moved = (0..3).any(|c| (g[4 * p + c] as f64 - BG[c]).abs() > 1e-3);
            if moved {
                changed += 1;
                assert!(
                    px >= x && px < x + w && py >= y && py < y + h,
                    "pixel ({px}, {py}) changed outside the covered {x},{y} {w}x{h}"
                );
            }
        }
    }
    assert!(changed > 20, "the instance shows ({changed} pixels)");
}

#[test]
fn sun_shadows_match_the_cpu() {
    let Some(gpu) = Gpu::new("sun_shadows_match_the_cpu") else {
        return;
    };
    let asset = cloud(PayloadFormat::F32);
    sun_shadows_case(&gpu, &[&asset], [0, 0]);
}

/// Two assets of one volume set cast their shadows through one binding, read by one function
/// in the engine's shader.
#[test]
fn sun_shadows_of_two_assets_in_one_shader() {
    let Some(gpu) = Gpu::new("sun_shadows_of_two_assets_in_one_shader") else {
        return;
    };
    let (b, a) = (cloud(PayloadFormat::F32), ember());
    sun_shadows_case(&gpu, &[&b, &a], [1, 0]);
}

/// Two lit instances (of `assets[which[0]]` and `assets[which[1]]`) shadow a lattice of world
/// points: the GPU's `vdb_sun_transmittance` against the product of the CPU tracers'.
fn sun_shadows_case(gpu: &Gpu, assets: &[&Asset], which: [usize; 2]) {
    let vol =
        GpuVolume::upload_set(&gpu.device, &gpu.queue, assets, Default::default()).expect("upload");
    let mut drawer = VolumeDrawer::new(&gpu.device, &vol, FORMAT).expect("drawer");
    let lighting = Lighting {
        light_res: 24,
        light_dir: [0.3, 0.9, -0.2],
        ..Default::default()
    };
    let medium = Shading {
        lighting: Some(lighting),
        ..Default::default()
    };
    let instances = [
        Instance {
            density_scale: 1.0,
            asset: which[0],
            ..Instance::at(Affine3A::from_translation(Vec3::new(30.0, -12.0, 7.0)))
        },
        Instance {
            density_scale: 1.5,
            time: if assets[which[1]].frame_count() > 2 {
                1.5
            } else {
                0.0
            },
            asset: which[1],
            ..Instance::at(Affine3A::from_scale_rotation_translation(
                Vec3::splat(1.3),
                Quat::from_euler(EulerRot::XYZ, 0.4, -0.9, 1.7),
                Vec3::new(-5.0, 4.0, 3.0),
            ))
        },
    ];
    // Without lighting: refused.
    let e = drawer
        .sun_shadows(&gpu.device, &gpu.queue, &instances, &Shading::default())
        .err()
        .expect("no lighting, no shadows");
    assert!(matches!(e, RuntimeError::Setting(_)), "{e}");

    // The CPU: per instance and frame a lit tracer on the moved asset.
    let mut tracers = Vec::new();
    for inst in &instances {
        let asset = assets[inst.asset];
        let m = moved(asset, inst);
        let (f0, f1, a) = inst.frames(asset.frame_count()).unwrap();
        let base = medium.settings();
        let s = RenderSettings {
            medium: Medium {
                absorb: base.medium.absorb * inst.density_scale,
                scatter: base.medium.scatter * inst.density_scale,
                ..base.medium
            },
            ..base
        };
        let ext = (s.medium.absorb + s.medium.scatter) as f64;
        tracers.push((m, [f0, f1], a as f64, s, ext));
    }
    // World points: a lattice over the instances' world boxes, grown by half.
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for (m, ..) in &tracers {
        let (blo, bhi) = vdbcook_trace::content_box(m, 0).unwrap();
        let xf = vdbcook_trace::Affine::cells(&m.header.index_to_world).unwrap();
        for c in 0..8 {
            let p = [0, 1, 2].map(|k| if c >> k & 1 == 0 { blo[k] } else { bhi[k] });
            let w = xf.world_of(p);
            let w = Vec3::new(w[0] as f32, w[1] as f32, w[2] as f32);
            (lo, hi) = (lo.min(w), hi.max(w));
        }
    }
    let (c, h) = (0.5 * (lo + hi), 0.75 * (hi - lo));
    let n = 12;
    let points: Vec<[f32; 4]> = (0..n * n * n)
        .map(|i| {
            let f = |k: usize| (k as f32 + 0.5) / n as f32 * 2.0 - 1.0;
            let p = c + h * Vec3::new(f(i % n), f(i / n % n), f(i / (n * n)));
            [p.x, p.y, p.z, 0.0]
        })
        .collect();
    // One lit tracer per instance and frame (each builds its light volume once).
    let lit: Vec<(Vec<Tracer>, f64, f64)> = tracers
        .iter()
        .map(|(m, frames, a, s, ext)| {
            let cam = Camera::framing(m, 0, 1.0).unwrap();
            let t = frames
                .iter()
                .map(|&frame| {
                    Tracer::new(
                        m,
                        &cam,
                        &RenderSettings {
                            output: Output {
                                frame,
                                ..s.output.clone()
                            },
                            ..s.clone()
                        },
                    )
                    .unwrap()
                })
                .collect();
            (t, *a, *ext)
        })
        .collect();
    let cpu: Vec<f64> = points
        .iter()
        .map(|p| {
            let w = [p[0] as f64, p[1] as f64, p[2] as f64];
            lit.iter()
                .map(|(t, a, ext)| {
                    let tau: Vec<f64> = t
                        .iter()
                        .map(|t| -t.sun_transmittance(w).unwrap().ln() / ext)
                        .collect();
                    (-ext * ((1.0 - a) * tau[0] + a * tau[1])).exp()
                })
                .product()
        })
        .collect();

    // The GPU: a compute shader over the points, the shadows bound at group 0.
    let shadows = drawer
        .sun_shadows(&gpu.device, &gpu.queue, &instances, &medium)
        .unwrap();
    assert_eq!(shadows.casters, 2);
    let source = format!(
        "{}\n@group(1) @binding(0) var<storage, read> pts: array<vec4<f32>>;\n\
         @group(1) @binding(1) var<storage, read_write> out_t: array<f32>;\n\
         @compute @workgroup_size(64) fn main(@builtin(global_invocation_id) id: vec3<u32>) {{\n\
         if (id.x >= arrayLength(&pts)) {{ return; }}\n\
         out_t[id.x] = vdb_sun_transmittance(pts[id.x].xyz);\n}}\n",
        vdbcook_runtime::shadow_wgsl(0)
    );
    let got = vdbcook_testkit::gpu::eval_points(
        &gpu.device,
        &gpu.queue,
        &source,
        "main",
        &[],
        &[(drawer.shadow_layout(), &shadows.bind_group)],
        1,
        &points,
    );

    let mut worst = 0.0f64;
    for (g, c) in got.iter().zip(&cpu) {
        worst = worst.max((*g as f64 - c).abs());
    }
    let dark = cpu.iter().filter(|t| **t < 0.9).count();
    let clear = cpu.iter().filter(|t| **t > 0.999).count();
    eprintln!("sun shadows: worst |gpu − cpu| {worst:.2e}; {dark} points below 0.9, {clear} unshadowed of {}", cpu.len());
    assert!(worst < 1e-3, "worst {worst}");
    assert!(
        dark > 50 && clear > 50,
        "a lattice with shadow and light ({dark}, {clear})"
    );
}
