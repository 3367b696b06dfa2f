//! GPU time of one render per mode (`VDBCOOK_BENCH_MODES`, default `density,scatter,lit`; any
//! of the tracer's mode names; `lit` twice per multiple-scattering model (`VDBCOOK_BENCH_MS`,
//! default `octaves,diffusion`; the march `VDBCOOK_BENCH_MARCH`, `voxels` or `steps`, default
//! `steps`): with its light volume cached, and rebuilt per render) from the
//! default view at 640×360 and 1920×1080, measured with
//! timestamp queries (`vdbcook_runtime::GpuTimer`) around the runtime's compute pass: median of
//! RUNS (after one warm-up), plus the CPU wall time of submit-and-wait. Without
//! `TIMESTAMP_QUERY` only the wall time is printed. The results: `docs/rendering.md`.
//!
//! `cargo bench -p vdbcook-runtime --bench gpu [-- ASSET.vdbc ...]`; by default the f32 assets
//! that `crates/trace/benches/vs_vdb_render.rs` leaves in `target/vs-vdb-render/`. Each asset is
//! uploaded with the automatic layout, or with every layout when `VDBCOOK_BENCH_LAYOUTS=all`
//! (the table gives the layout and the payload bytes on the GPU); `VDBCOOK_BENCH_SIZES=small`
//! renders 640×360 only.

use std::path::{Path, PathBuf};
use std::time::Instant;
use vdbcook_runtime::wgpu;

use vdbcook_runtime::{
    Asset, Camera, GpuTimer, GpuVolume, Integrator, Layout, Lighting, March, Mode, MsModel,
    Renderer, Settings, UploadOptions,
};

const RUNS: usize = 5;
const SIZES: [(u32, u32); 2] = [(640, 360), (1920, 1080)];

/// `VDBCOOK_BENCH_SIZES=small`: only the first size.
fn sizes() -> &'static [(u32, u32)] {
    if std::env::var("VDBCOOK_BENCH_SIZES").as_deref() == Ok("small") {
        &SIZES[..1]
    } else {
        &SIZES
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn main() {
    let args: Vec<PathBuf> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .map(PathBuf::from)
        .collect();
    let assets = if args.is_empty() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/vs-vdb-render");
        let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
            .map(|d| {
                d.filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.to_string_lossy().ends_with("_f32.vdbc"))
                    .collect()
            })
            .unwrap_or_default();
        v.sort();
        v
    } else {
        args
    };
    if assets.is_empty() {
        eprintln!("skipping: no assets (run the vdbcook-trace vs_vdb_render bench, or give paths)");
        return;
    }

    // The test kit's opener: BC textures and timestamps where the adapter has them.
    let Some((device, queue)) = vdbcook_testkit::gpu::open_device(
        "gpu bench",
        vdbcook_runtime::OPTIONAL_FEATURES | wgpu::Features::TIMESTAMP_QUERY,
        None,
    ) else {
        return;
    };
    let timestamps = device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
    let info = device.adapter_info();
    println!(
        "adapter: {} ({:?}); timestamp queries: {timestamps}; median of {RUNS}",
        info.name, info.backend
    );
    println!(
        "| asset | layout | payload bytes on GPU | size | mode | GPU ms (timestamps) | submit+wait ms |"
    );
    println!("|---|---|---:|---|---|---:|---:|");
    let all_layouts = std::env::var("VDBCOOK_BENCH_LAYOUTS").as_deref() == Ok("all");

    let timer = GpuTimer::new(&device, &queue);
    let modes: Vec<Mode> = std::env::var("VDBCOOK_BENCH_MODES")
        .unwrap_or_else(|_| "density,scatter,lit".into())
        .split(',')
        .map(|m| Mode::parse(m.trim()).unwrap_or_else(|| panic!("unknown mode {m}")))
        .collect();
    let march = std::env::var("VDBCOOK_BENCH_MARCH")
        .map(|m| March::parse(&m).unwrap_or_else(|| panic!("unknown march {m}")))
        .unwrap_or(March::Steps);
    let ms_models: Vec<MsModel> = std::env::var("VDBCOOK_BENCH_MS")
        .unwrap_or_else(|_| "octaves,diffusion".into())
        .split(',')
        .map(|m| MsModel::parse(m.trim()).unwrap_or_else(|| panic!("unknown ms model {m}")))
        .collect();

    let runs: Vec<(PathBuf, Option<Layout>)> = assets
        .iter()
        .flat_map(|p| {
            // Layouts only matter for quantized bricks.
            let quantized = all_layouts
                && Asset::load(p).is_ok_and(|a| a.header.brick_counts[..3].iter().sum::<u64>() > 0);
            let layouts: Vec<Option<Layout>> = if quantized {
                Layout::ALL.iter().map(|&l| Some(l)).collect()
            } else {
                vec![None]
            };
            layouts.into_iter().map(move |l| (p.clone(), l))
        })
        .collect();
    for (path, force) in &runs {
        let asset = Asset::load(path).expect("a valid asset");
        let volume = match GpuVolume::upload_with(
            &device,
            &queue,
            &asset,
            UploadOptions { force: *force },
        ) {
            Ok(v) => v,
            Err(e) => {
                eprintln!("{}: {e}", path.display());
                continue;
            }
        };
        eprintln!("{}: {}", path.display(), volume.describe());
        let l = volume.layout();
        let payload_bytes = l.buffer_bytes + l.textures.iter().map(|t| t.bytes).sum::<u64>();
        let layout_name = if l.textures.is_empty() && l.layout != Layout::Buffers {
            "(no quantized bricks)"
        } else {
            l.layout.name()
        };
        let format = wgpu::TextureFormat::Rgba8Unorm;
        let renderer = Renderer::new(&device, &volume, format).expect("renderer");
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        for &(w, h) in sizes() {
            let texture = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("gpu bench target"),
                size: wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::STORAGE_BINDING,
                view_formats: &[],
            });
            let view = texture.create_view(&Default::default());
            let target = renderer
                .texture_target(&device, &texture, &view)
                .expect("target");
            let bbox = volume.frame_bbox(0).expect("frame 0 stores something");
            // The stored bounding box's framing (not `Camera::framing`'s tighter fit since
            // 2026-11-23), so figures stay comparable with those in docs/.
            let camera = Camera::framing_box(volume.index_to_world(), bbox, w as f64 / h as f64)
                .expect("camera");
            // The lit mode twice: its light volume cached (a still frame and light), and
            // rebuilt on every render (the light moves a little: a playing flip-book).
            let variants = modes.iter().flat_map(|&m| {
                let lit: Vec<(MsModel, bool)> = if m == Mode::Lit {
                    ms_models
                        .iter()
                        .flat_map(|&ms| [(ms, false), (ms, true)])
                        .collect()
                } else {
                    vec![(MsModel::Octaves, false)]
                };
                lit.into_iter().map(move |(ms, r)| (m, ms, r))
            });
            for (mode, ms_model, rebuild) in variants {
                let (mut gpu, mut wall) = (Vec::new(), Vec::new());
                for run in 0..=RUNS {
                    let settings = Settings {
                        lighting: Lighting {
                            light_dir: [0.3, 0.3, if rebuild { 1e-3 * run as f32 } else { 0.0 }],
                            ms_model,
                            ms_sky: ms_model.default_ms_sky(),
                            ..Default::default()
                        },
                        integrator: Integrator {
                            mode,
                            march,
                            ..Default::default()
                        },
                        ..Default::default()
                    };
                    let start = Instant::now();
                    let mut encoder = device.create_command_encoder(&Default::default());
                    if let Some(t) = &timer {
                        t.begin(&mut encoder);
                    }
                    renderer
                        .render(&queue, &mut encoder, &target, 0, &camera, &settings)
                        .expect("render");
                    if let Some(t) = &timer {
                        t.end(&mut encoder);
                    }
                    queue.submit([encoder.finish()]);
                    device
                        .poll(wgpu::PollType::wait_indefinitely())
                        .expect("poll");
                    let elapsed = start.elapsed().as_secs_f64() * 1e3;
                    let ms = timer.as_ref().and_then(|t| t.read_ms(&device));
                    if run > 0 {
                        wall.push(elapsed);
                        gpu.extend(ms);
                    }
                }
                let g = if gpu.is_empty() {
                    "–".to_string()
                } else {
                    format!("{:.1}", median(gpu))
                };
                let name_of = if mode == Mode::Lit {
                    format!("{} ({})", mode.name(), ms_model.name())
                } else {
                    mode.name().to_string()
                };
                let what = if rebuild {
                    format!("{name_of} + light volume")
                } else {
                    name_of
                };
                println!(
                    "| {name} | {layout_name} | {payload_bytes} | {w}×{h} | {what} | {g} | {:.1} |",
                    median(wall)
                );
            }
        }
    }
}
