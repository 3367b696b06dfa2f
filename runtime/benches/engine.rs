//! What the engine drawer (`VolumeDrawer`) costs per frame: N = 1, 8, 64 instances of one asset
//! on a cubic lattice, all in view (a reversed-Z infinite perspective framing the lattice), with
//! a depth buffer (a plane behind everything, so the depth read runs) and an `Rgba8UnormSrgb`
//! colour target, at 640×360 and 1920×1080. GPU time by timestamp queries
//! (`vdbcook_runtime::GpuTimer`) around the recorded compute and composite passes, median of
//! RUNS after one warm-up, plus submit+wait wall time; the cost per instance is GPU ms / N. The
//! figures: `docs/engine.md`.
//!
//! `cargo bench -p vdbcook-runtime --bench engine [-- ASSET.vdbc]`; by default the wdas f32 asset
//! that `crates/trace/benches/vs_vdb_render.rs` leaves in `target/vs-vdb-render/`.
//! `VDBCOOK_BENCH_SIZES=small`: 640×360 only. `VDBCOOK_BENCH_LIGHTING=lit`: the instances drawn
//! lit (`Shading::lighting` with the tracer's defaults; the translated copies share one light
//! volume, built in the warm-up run), instead of flat; `VDBCOOK_BENCH_SUN_NEAR=CELLS` sets their
//! near field toward the sun (`Lighting::sun_near`; 0: none).

use std::path::PathBuf;
use std::time::Instant;
use vdbcook_runtime::wgpu;

use vdbcook_runtime::glam::{Affine3A, Vec3, Vec4};
use vdbcook_runtime::{
    Asset, DrawTarget, GpuTimer, GpuVolume, Instance, Interleave, Lighting, PreparedDraw, Shading,
    View, VolumeDrawer,
};

const RUNS: usize = 3;
const SIZES: [(u32, u32); 2] = [(640, 360), (1920, 1080)];
const COUNTS: [usize; 3] = [1, 8, 64];

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn main() {
    let arg = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with("--"))
        .map(PathBuf::from);
    let path = arg.unwrap_or_else(|| {
        let target = std::env::var("CARGO_TARGET_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(|_| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target"));
        target.join("vs-vdb-render/wdas_cloud_sixteenth_f32.vdbc")
    });
    let Ok(asset) = Asset::load(&path) else {
        eprintln!(
            "skipping: cannot load {} (run the vdbcook-trace vs_vdb_render bench, or give a path)",
            path.display()
        );
        return;
    };
    let sizes: &[(u32, u32)] = if std::env::var("VDBCOOK_BENCH_SIZES").as_deref() == Ok("small") {
        &SIZES[..1]
    } else {
        &SIZES
    };
    // The test kit's opener: BC textures and timestamps where the adapter has them.
    let Some((device, queue)) = vdbcook_testkit::gpu::open_device(
        "engine bench",
        vdbcook_runtime::OPTIONAL_FEATURES | wgpu::Features::TIMESTAMP_QUERY,
        None,
    ) else {
        return;
    };
    let timestamps = device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
    let info = device.adapter_info();
    let volume = GpuVolume::upload(&device, &queue, &asset).expect("upload");
    let format = wgpu::TextureFormat::Rgba8UnormSrgb;
    let mut drawer = VolumeDrawer::new(&device, &volume, format).expect("drawer");
    // `VDBCOOK_BENCH_INTERLEAVE=always|never`: force the interleaving sweep on or off.
    drawer.set_interleave(match std::env::var("VDBCOOK_BENCH_INTERLEAVE").as_deref() {
        Ok("always") => Interleave::Always,
        Ok("never") => Interleave::Never,
        _ => Interleave::Auto,
    });
    let timer = GpuTimer::new(&device, &queue);
    println!(
        "adapter: {} ({:?}); timestamp queries: {timestamps}; {}; median of {RUNS}",
        info.name,
        info.backend,
        path.display()
    );

    // The asset's stored box in world space: its centre and radius.
    let (lo, hi) = volume.frame_bbox(0).expect("frame 0 stores something");
    let m = asset.header.index_to_world;
    let world = |p: [f64; 3]| {
        Vec3::from_array(
            [0, 1, 2].map(|r| (m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3]) as f32),
        )
    };
    let (wlo, whi) = (world(lo), world(hi));
    let centre = 0.5 * (wlo + whi);
    let radius = 0.5 * (whi - wlo).length();

    println!("| instances | size | GPU ms (timestamps) | GPU ms per instance | submit+wait ms |");
    println!("|---:|---|---:|---:|---:|");
    for &(w, h) in sizes {
        let (color, depth) = targets(&device, format, (w, h));
        // `VDBCOOK_BENCH_SUN_NEAR=CELLS`: the lit march's near field (default: the tracer's).
        let sun_near = std::env::var("VDBCOOK_BENCH_SUN_NEAR")
            .ok()
            .and_then(|v| v.parse().ok());
        let medium = Shading {
            lighting: (std::env::var("VDBCOOK_BENCH_LIGHTING").as_deref() == Ok("lit")).then(
                || {
                    let l = Lighting::default();
                    Lighting {
                        sun_near: sun_near.unwrap_or(l.sun_near),
                        ..l
                    }
                },
            ),
            ..Default::default()
        };
        for n in COUNTS {
            // A k×k×k lattice (k = ⌈∛n⌉), spacing 2.2 radii (`VDBCOOK_BENCH_SPACING`: another
            // number of radii; below 2 the boxes overlap and the draw interleaves them), the
            // first n sites.
            let k = (1..).find(|k| k * k * k >= n).unwrap();
            let spacing = std::env::var("VDBCOOK_BENCH_SPACING")
                .ok()
                .and_then(|v| v.parse::<f32>().ok())
                .unwrap_or(2.2)
                * radius;
            let instances: Vec<Instance> = (0..n)
                .map(|i| {
                    let c = Vec3::new((i % k) as f32, ((i / k) % k) as f32, (i / (k * k)) as f32)
                        - Vec3::splat(0.5 * (k - 1) as f32);
                    Instance {
                        tint: Vec3::new(1.0, 0.5 + 0.5 * (i % 2) as f32, 0.8),
                        ..Instance::at(Affine3A::from_translation(c * spacing))
                    }
                })
                .collect();
            let fov = 40f32.to_radians();
            let reach = radius + spacing * 0.5 * (k - 1) as f32 * 3f32.sqrt();
            let dist = reach / (0.5 * fov).sin();
            let dir = Vec3::new(0.6, 0.4, 1.0).normalize();
            let view = View::look_at(
                centre + dir * dist,
                centre,
                Vec3::Y,
                fov,
                w as f32 / h as f32,
                0.1,
                (w, h),
            )
            .expect("view");
            let behind = {
                let c = view.proj * Vec4::new(0.0, 0.0, -(dist + 2.0 * reach), 1.0);
                c.z / c.w
            };
            let target = DrawTarget {
                color: &color,
                depth: Some(&depth),
            };
            let (gpu, wall, _) = timed(&device, &queue, &mut drawer, timer.as_ref(), |d, enc| {
                clear(enc, &color, &depth, behind);
                d.prepare(&device, &queue, &target, &view, &instances, &medium)
                    .expect("prepare")
            });
            let (g, per) = if gpu.is_empty() {
                ("–".to_string(), "–".to_string())
            } else {
                let g = median(gpu);
                (format!("{g:.1}"), format!("{:.2}", g / n as f64))
            };
            println!("| {n} | {w}×{h} | {g} | {per} | {:.1} |", median(wall));
        }
    }
    coverage(
        &device,
        &queue,
        &mut drawer,
        timer.as_ref(),
        (centre, radius),
    );
}

/// Cost follows screen coverage: at 640×360, one flat instance filling the view against the same
/// instance shrunk to cover about 1% of the pixels, each timed as above; the dispatch and the
/// composite cover only the pixels the instance's projected box reaches
/// (`PreparedDraw::covered`).
fn coverage(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    drawer: &mut VolumeDrawer,
    timer: Option<&GpuTimer>,
    (centre, radius): (Vec3, f32),
) {
    let (w, h) = (640u32, 360u32);
    let (color, depth) = targets(device, drawer.color_format(), (w, h));
    let fov = 40f32.to_radians();
    // Close enough that the box overflows the view: every pixel covered.
    let dist = 0.6 * radius / (0.5 * fov).tan();
    let view = View::look_at(
        centre + Vec3::new(0.0, 0.0, dist),
        centre,
        Vec3::Y,
        fov,
        w as f32 / h as f32,
        0.1,
        (w, h),
    )
    .expect("view");
    let medium = Shading::default();
    let target = DrawTarget {
        color: &color,
        depth: Some(&depth),
    };
    // Scaled about the asset's centre.
    let scaled = |scale: f32| {
        Instance::at(
            Affine3A::from_translation(centre)
                * Affine3A::from_scale(Vec3::splat(scale))
                * Affine3A::from_translation(-centre),
        )
    };
    let share = |scale: f32, drawer: &mut VolumeDrawer| {
        let p = drawer
            .prepare(device, queue, &target, &view, &[scaled(scale)], &medium)
            .expect("prepare");
        let c = p.covered();
        (c[2] * c[3]) as f64 / (w * h) as f64
    };
    // The scale whose covered rectangle is 1% of the pixels (bisection on log scale).
    let (mut lo, mut hi) = (1e-3f32, 1.0f32);
    for _ in 0..20 {
        let mid = (lo * hi).sqrt();
        if share(mid, drawer) < 0.01 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    println!();
    println!("| instance | covered pixels | GPU ms (timestamps) | submit+wait ms |");
    println!("|---|---:|---:|---:|");
    let mut rows = Vec::new();
    for (name, scale) in [("full screen", 1.0f32), ("1% of the screen", hi)] {
        let inst = scaled(scale);
        let (gpu, wall, covered) = timed(device, queue, drawer, timer, |d, enc| {
            clear(enc, &color, &depth, 0.0);
            d.prepare(device, queue, &target, &view, &[inst], &medium)
                .expect("prepare")
        });
        let share = (covered[2] * covered[3]) as f64 / (w * h) as f64;
        let g = (!gpu.is_empty()).then(|| median(gpu));
        println!(
            "| {name} | {:.1}% | {} | {:.1} |",
            100.0 * share,
            g.map_or("–".into(), |g| format!("{g:.2}")),
            median(wall.clone())
        );
        rows.push((g, median(wall)));
    }
    if let (Some(full), Some(small)) = (rows[0].0, rows[1].0) {
        println!("1% / full screen GPU time: {:.3}", small / full);
    }
    println!("1% / full screen wall time: {:.3}", rows[1].1 / rows[0].1);
}

/// A colour target of `format` and a `Depth32Float` depth buffer of `size`.
fn targets(
    device: &wgpu::Device,
    format: wgpu::TextureFormat,
    (w, h): (u32, u32),
) -> (wgpu::TextureView, wgpu::TextureView) {
    let tex = |format, usage| {
        device
            .create_texture(&wgpu::TextureDescriptor {
                label: Some("engine bench target"),
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
    let color = tex(format, wgpu::TextureUsages::RENDER_ATTACHMENT);
    let depth = tex(
        wgpu::TextureFormat::Depth32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
    );
    (color, depth)
}

/// Runs a draw `RUNS + 1` times, the first a warm-up: each run `prepare` records the clear into
/// a new encoder and prepares the draw, which is then recorded between the timer's stamps,
/// submitted and waited for. Returns the timed runs' GPU ms (timestamps; none without the
/// feature) and wall ms (prepare to the end of the wait), and the last draw's covered pixels.
fn timed(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    drawer: &mut VolumeDrawer,
    timer: Option<&GpuTimer>,
    mut prepare: impl FnMut(&mut VolumeDrawer, &mut wgpu::CommandEncoder) -> PreparedDraw,
) -> (Vec<f64>, Vec<f64>, [u32; 4]) {
    let (mut gpu, mut wall) = (Vec::new(), Vec::new());
    let mut covered = [0u32; 4];
    for run in 0..=RUNS {
        let start = Instant::now();
        let mut enc = device.create_command_encoder(&Default::default());
        let prepared = prepare(drawer, &mut enc);
        covered = prepared.covered();
        if let Some(t) = timer {
            t.begin(&mut enc);
        }
        drawer.record(&mut enc, &prepared);
        if let Some(t) = timer {
            t.end(&mut enc);
        }
        queue.submit([enc.finish()]);
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .expect("poll");
        let elapsed = start.elapsed().as_secs_f64() * 1e3;
        let ms = timer.and_then(|t| t.read_ms(device));
        if run > 0 {
            wall.push(elapsed);
            gpu.extend(ms);
        }
    }
    (gpu, wall, covered)
}

/// Clears the colour target and sets the depth buffer to the plane `depth`.
fn clear(
    enc: &mut wgpu::CommandEncoder,
    color: &wgpu::TextureView,
    depth: &wgpu::TextureView,
    d: f32,
) {
    let _ = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("engine bench clear"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: color,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color {
                    r: 0.2,
                    g: 0.3,
                    b: 0.5,
                    a: 1.0,
                }),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: depth,
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
