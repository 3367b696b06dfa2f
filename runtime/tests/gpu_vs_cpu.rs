//! The GPU tracer against the CPU reference tracer (`vdbcook_trace::render`, the independent
//! truth): every deterministic mode the GPU implements, every payload format (hand-built
//! assets; one also written to bytes and loaded back), voxel and world length units, a rotated
//! anisotropic transform, awkward cameras (inside the volume, axis-aligned), frame switching and
//! a bad frame index. Runs on whatever adapter exists (software Vulkan in CI); without one each
//! test prints why it skipped, unless `VDBCOOK_REQUIRE_GPU=1`.
//!
//! Payload layouts: every `Layout` is forced on the same adapter (BC in 3D textures, BC in 2D
//! arrays, BC decoded into 8-bit textures, everything in buffers), every voxel is read back
//! through `VOLUME_WGSL` and compared with `Asset::decode_brick`, and every deterministic mode is
//! rendered in every layout; an adapter without BC features and too-small limits are covered too.
//!
//! Tolerances: the GPU works in f32 where the CPU works in f64; bricks read exactly as the CPU
//! decodes them up to f32 rounding of the dequantization (native BC excepted:
//! `payload::read_codes_per_voxel`), so values agree to rounding: density and depth within 1e-3 (relative for depth), first-hit
//! values within `FIRST_HIT_TOL`. Discrete answers (first-hit voxel, brick index, step
//! count) are equal except where a ray passes within f32 rounding of a voxel edge or corner,
//! where the two DDAs may order a tie differently: at most 0.5% of pixels may differ, and the
//! counts are printed.
//!
//! Single scatter is held to 2e-3 per channel and value (`SCATTER_TOL`; measured: at most
//! ~1e-6 on framed views, 2.1e-4 on one BC4 frame, 1.15e-3 for views along region and leaf
//! planes, where an f32 sample point lands in the neighbouring voxel). Delta tracking runs the
//! same PCG streams as the CPU, but f32 free flights round differently from f64 ones and a few
//! paths take another branch, so it is compared statistically (`check_delta`).

mod common;

use common::*;
use vdbcook_asset::{payload, Asset, PayloadFormat};
use vdbcook_runtime::{
    GpuTimer, GpuVolume, Layout, Readback, Renderer, RuntimeError, UploadOptions, GPU_MODES,
    OPTIONAL_FEATURES,
};
use vdbcook_trace::{
    Image, Integrator, Lighting, March, Medium, Mode, MsModel, Output, RenderSettings,
};

const W: u32 = 160;
const H: u32 = 90;

/// The modes with one exact answer per pixel (all but delta tracking, which is compared
/// statistically: `delta_tracking_matches_the_cpu_statistically`).
const DETERMINISTIC: [Mode; 7] = [
    Mode::Density,
    Mode::Depth,
    Mode::FirstHitDensity,
    Mode::BrickHue,
    Mode::Steps,
    Mode::SingleScatter,
    Mode::Lit,
];

/// Single scatter, per channel and value: f32 sample positions and exponentials against f64.
const SCATTER_TOL: f32 = 2e-3;
/// First-hit density value, relative (`(1 + |v|)·tol`): f32 dequantization on both sides.
const FIRST_HIT_TOL: f32 = 1e-6;

struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
}

impl Gpu {
    fn new(test: &str) -> Option<Gpu> {
        gpu(test).map(|(device, queue)| Gpu { device, queue })
    }
    fn setup(&self, asset: &Asset) -> (GpuVolume, Renderer) {
        self.setup_with(asset, UploadOptions::default())
    }
    fn setup_with(&self, asset: &Asset, options: UploadOptions) -> (GpuVolume, Renderer) {
        let vol =
            GpuVolume::upload_with(&self.device, &self.queue, asset, options).expect("upload");
        let r =
            Renderer::new(&self.device, &vol, wgpu::TextureFormat::Rgba8Unorm).expect("renderer");
        (vol, r)
    }
    fn render(
        &self,
        r: &Renderer,
        target: &vdbcook_runtime::BufferTarget,
        cam: &vdbcook_trace::Camera,
        s: &RenderSettings,
    ) -> Result<Readback, RuntimeError> {
        let mut enc = self.device.create_command_encoder(&Default::default());
        r.render_to_buffer(&self.queue, &mut enc, target, s.output.frame, cam, s)?;
        self.queue.submit([enc.finish()]);
        Ok(target.read(&self.device, &self.queue))
    }
}

fn small(mode: Mode, frame: usize) -> RenderSettings {
    RenderSettings {
        output: Output {
            width: W,
            height: H,
            frame,
        },
        lighting: Lighting {
            // A light volume of 24 cells along the longest side: the CPU builds it per render.
            light_res: 24,
            ..Default::default()
        },
        integrator: Integrator {
            mode,
            ..Default::default()
        },
        ..Default::default()
    }
}

/// Counts pixels where the GPU and CPU images differ beyond the mode's tolerance.
/// Also returns the largest difference of any channel or value.
fn mismatches(cpu: &Image, gpu: &Readback, mode: Mode) -> (usize, String, f32) {
    mismatches_with(cpu, gpu, mode, 0.0)
}

/// As [`mismatches`], every tolerance widened by `slack` (absolute).
fn mismatches_with(cpu: &Image, gpu: &Readback, mode: Mode, slack: f32) -> (usize, String, f32) {
    assert_eq!((cpu.width, cpu.height), (gpu.width, gpu.height));
    assert!(
        gpu.rgba.iter().chain(&gpu.value).all(|v| v.is_finite()),
        "{mode:?}: NaN or infinite pixel on the GPU"
    );
    let (tol_rgba, tol_value) = match mode {
        Mode::Density => (1e-3, 1e-3),
        Mode::Depth => (1e-3, 1e-3),
        Mode::SingleScatter | Mode::Lit => (SCATTER_TOL, SCATTER_TOL),
        // Values are dequantized in f32 on both sides, the GPU with its own unorm conversion
        // and fused multiply-adds: a few ulps of the brick's range (measured ≤ 6e-8 on ranges
        // up to 2.5). Steps and brick hues are exact.
        Mode::FirstHitDensity => (1e-4, FIRST_HIT_TOL),
        _ => (1e-4, 0.0),
    };
    let (tol_rgba, tol_value) = (tol_rgba + slack, tol_value + slack);
    let mut bad = 0;
    let mut first = String::new();
    let mut max_diff = 0.0f32;
    for p in 0..cpu.value.len() {
        let (a, b) = (cpu.value[p], gpu.value[p]);
        max_diff = max_diff.max((a - b).abs());
        for c in 0..4 {
            max_diff = max_diff.max((cpu.rgba[4 * p + c] - gpu.rgba[4 * p + c]).abs());
        }
        let scale = if matches!(mode, Mode::Depth | Mode::FirstHitDensity) {
            1.0 + a.abs()
        } else {
            1.0
        };
        let mut ok = (a - b).abs() <= tol_value * scale;
        for c in 0..4 {
            ok &= (cpu.rgba[4 * p + c] - gpu.rgba[4 * p + c]).abs() <= tol_rgba;
        }
        if !ok {
            if bad == 0 {
                first = format!(
                    "pixel ({}, {}): cpu {a} {:?}, gpu {b} {:?}",
                    p as u32 % cpu.width,
                    p as u32 / cpu.width,
                    &cpu.rgba[4 * p..4 * p + 4],
                    &gpu.rgba[4 * p..4 * p + 4]
                );
            }
            bad += 1;
        }
    }
    (bad, first, max_diff)
}

/// Renders every GPU mode of `frame` on both tracers and checks they agree.
fn check_modes(
    gpu: &Gpu,
    asset: &Asset,
    what: &str,
    frame: usize,
    tweak: impl Fn(&mut RenderSettings),
) {
    let (vol, r) = gpu.setup(asset);
    // Native BC textures may read up to `payload::native_read_codes` off the decode.
    let (slack, flips_per_mille) = if vol.exact() {
        (0.0, 5)
    } else {
        (BC4_IMAGE_SLACK, 20)
    };
    let target = r.buffer_target(&gpu.device, W, H).unwrap();
    let cam = vdbcook_trace::Camera::framing(asset, frame, W as f64 / H as f64).unwrap();
    for mode in DETERMINISTIC {
        let mut s = small(mode, frame);
        tweak(&mut s);
        let cpu = vdbcook_trace::render(asset, &cam, &s).unwrap();
        let g = gpu.render(&r, &target, &cam, &s).unwrap();
        let (bad, first, max_diff) = mismatches_with(&cpu, &g, mode, slack);
        let n = cpu.value.len();
        eprintln!(
            "{what} frame {frame} {mode:?} ({}): {bad}/{n} pixels differ (max diff {max_diff:.2e}) {first}",
            vol.layout().layout.name()
        );
        assert!(
            bad * 1000 <= n * flips_per_mille,
            "{what} frame {frame} {mode:?}: {bad}/{n} pixels differ; first {first}"
        );
    }
}

fn blob_asset(format: PayloadFormat) -> Asset {
    blob_asset_then(blob_frame([140.0, 110.0, 50.0], 28.0, 2.5, None), format)
}

/// The blob's first frame, then `second`.
fn blob_asset_then(second: FrameSpec, format: PayloadFormat) -> Asset {
    build(
        [2, 2, 2],
        rotated(25.0, [0.5, 0.7, 1.2], [3.0, -2.0, 1.0]),
        0.0,
        &[
            blob_frame([120.0, 100.0, 40.0], 34.0, 1.2, Some([1, 1, 1])),
            second,
        ],
        format,
    )
}

/// A two-frame asset read as one frame with one coarser level: its second frame becomes level 1.
fn second_frame_as_level(mut asset: Asset) -> Asset {
    asset.header.frames.truncate(1);
    asset.header.lod_levels = 1;
    asset.validate().unwrap();
    asset
}

#[test]
fn every_mode_matches_the_cpu_tracer_in_every_format() {
    let Some(gpu) = Gpu::new("every_mode_matches_the_cpu_tracer_in_every_format") else {
        return;
    };
    for format in PayloadFormat::ORDER {
        let asset = blob_asset(format);
        for frame in 0..2 {
            check_modes(&gpu, &asset, format.name(), frame, |_| {});
        }
    }
}

#[test]
fn random_bricks_tiles_and_negative_values_match() {
    let Some(gpu) = Gpu::new("random_bricks_tiles_and_negative_values_match") else {
        return;
    };
    let mut rng = XorShift(7);
    let frames = [random_frame(&mut rng), random_frame(&mut rng)];
    for format in [PayloadFormat::F32, PayloadFormat::Bc4] {
        let asset = build(
            [2, 2, 1],
            rotated(0.0, [1.0; 3], [0.0; 3]),
            0.0,
            &frames,
            format,
        );
        check_modes(&gpu, &asset, format.name(), 1, |_| {});
        // World length units and a nonzero cutoff on the same asset.
        check_modes(&gpu, &asset, "world units", 0, |s| {
            s.medium.unit = vdbcook_trace::LengthUnit::World;
            s.integrator.cutoff = 0.5;
            s.medium.absorb = 0.3;
        });
    }
}

#[test]
fn written_and_loaded_f16_asset_matches_and_uploads_exactly() {
    let Some(gpu) = Gpu::new("written_and_loaded_f16_asset_matches_and_uploads_exactly") else {
        return;
    };
    let built = blob_asset(PayloadFormat::F16);
    let (bytes, _) = built.to_bytes().expect("write");
    let asset = Asset::from_bytes(&bytes).expect("load");
    let (vol, _) = gpu.setup(&asset);
    assert!(
        matches!(
            vol.layout().buffers,
            vdbcook_runtime::BufferLayout::F16 { exact: true, .. }
        ),
        "an all-f16 asset keeps its halves: {:?}",
        vol.layout()
    );
    assert!(vol.exact());
    check_modes(&gpu, &asset, "f16 file", 0, |_| {});
    // The runtime's stored boxes (its depth range) equal the CPU tracer's, also with tiles
    // that hold the background (they store nothing: a leaf tile far from the blob and a
    // tiled region, both of value 0).
    for f in 0..asset.frame_count() {
        assert_eq!(vol.frame_bbox(f), vdbcook_trace::stored_bbox(&asset, f));
    }
    let mut frame = blob_frame([120.0, 100.0, 40.0], 34.0, 1.2, None);
    frame.leaves.insert([200, 8, 232], Leaf::Tile(0.0));
    frame.regions.insert([0, 1, 1], 0.0);
    let padded = build(
        [2, 2, 2],
        rotated(25.0, [0.5, 0.7, 1.2], [3.0, -2.0, 1.0]),
        0.0,
        &[frame],
        PayloadFormat::F32,
    );
    let (vol, _) = gpu.setup(&padded);
    let cpu = vdbcook_trace::stored_bbox(&padded, 0).unwrap();
    assert_eq!(vol.frame_bbox(0), Some(cpu));
    assert!(
        cpu.1[2] < 128.0,
        "the background tiles are not stored content: {cpu:?}"
    );
}

#[test]
fn awkward_cameras_match_and_make_no_nan() {
    let Some(gpu) = Gpu::new("awkward_cameras_match_and_make_no_nan") else {
        return;
    };
    let asset = build(
        [2, 2, 2],
        rotated(0.0, [1.0; 3], [0.0; 3]),
        0.0,
        &[blob_frame([120.0, 100.0, 40.0], 34.0, 1.2, Some([1, 1, 1]))],
        PayloadFormat::F32,
    );
    let (_vol, r) = gpu.setup(&asset);
    let target = r.buffer_target(&gpu.device, W, H).unwrap();
    // (eye, look-at, up, on exact node boundaries).
    let cams = [
        // Inside the blob.
        (
            [120.0, 100.0, 40.0],
            [200.0, 130.0, 60.0],
            [0.0, 1.0, 0.0],
            false,
        ),
        // Axis-aligned, the eye exactly on a region plane (y = 128) and a leaf plane (z = 40):
        // with this image size, whole families of rays run exactly through voxel edges.
        (
            [-20.0, 128.0, 40.0],
            [300.0, 128.0, 40.0],
            [0.0, 1.0, 0.0],
            true,
        ),
        // The same view a fraction of a voxel off the planes.
        (
            [-20.0, 128.37, 40.23],
            [300.0, 128.37, 40.23],
            [0.0, 1.0, 0.0],
            false,
        ),
        // Straight down with an up parallel to the view.
        (
            [120.0, 100.0, 400.0],
            [120.0, 100.0, 0.0],
            [0.0, 0.0, 1.0],
            false,
        ),
    ];
    let mut failures = vec![];
    for (eye, look_at, up, on_edges) in cams {
        let cam = vdbcook_trace::Camera {
            eye,
            look_at,
            up,
            fov_y_deg: 60.0,
        };
        for mode in DETERMINISTIC {
            let s = small(mode, 0);
            let cpu = vdbcook_trace::render(&asset, &cam, &s).unwrap();
            let g = gpu.render(&r, &target, &cam, &s).unwrap();
            let (bad, first, max_diff) = mismatches(&cpu, &g, mode);
            let n = cpu.value.len();
            eprintln!(
                "camera {eye:?} {mode:?}: {bad}/{n} differ (max diff {max_diff:.2e}) {first}"
            );
            if on_edges && mode == Mode::Steps {
                // A ray exactly through a voxel edge is a DDA tie: f64 (CPU) and f32 (GPU)
                // resolve it differently and visit different neighbour cells, so step counts
                // differ on such rays; the totals must still agree closely.
                let (a, b): (f32, f32) = (cpu.value.iter().sum(), g.value.iter().sum());
                eprintln!("  total steps cpu {a}, gpu {b}");
                if (a - b).abs() > 0.02 * a {
                    failures.push(format!("{eye:?} {mode:?}: total steps {a} vs {b}"));
                }
                continue;
            }
            if bad * 200 > n {
                failures.push(format!("{eye:?} {mode:?}: {bad}/{n}; {first}"));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn volume_fills_the_frame_frames_switch_and_bad_frame_is_an_error() {
    let Some(gpu) = Gpu::new("volume_fills_the_frame_frames_switch_and_bad_frame_is_an_error")
    else {
        return;
    };
    let asset = blob_asset(PayloadFormat::F32);
    let (_vol, r) = gpu.setup(&asset);
    let target = r.buffer_target(&gpu.device, W, H).unwrap();
    // The default view of frame 0 frames its tiled region too; halve the distance to the blob.
    let mut cam = vdbcook_trace::Camera::framing(&asset, 1, W as f64 / H as f64).unwrap();
    cam.eye = [0, 1, 2].map(|a| 0.5 * (cam.eye[a] + cam.look_at[a]));
    let a = gpu
        .render(&r, &target, &cam, &small(Mode::Density, 0))
        .unwrap();
    let covered = a.value.iter().filter(|&&t| t < 0.99).count();
    assert!(
        covered * 5 >= a.value.len(),
        "the volume covers only {covered}/{} pixels",
        a.value.len()
    );
    let b = gpu
        .render(&r, &target, &cam, &small(Mode::Density, 1))
        .unwrap();
    let changed = a
        .value
        .iter()
        .zip(&b.value)
        .filter(|(x, y)| (*x - *y).abs() > 1e-3)
        .count();
    assert!(
        changed * 10 >= a.value.len(),
        "frame switch changed only {changed} pixels"
    );
    // Back to frame 0: the same image (nothing re-uploaded, only the uniform changed).
    let c = gpu
        .render(&r, &target, &cam, &small(Mode::Density, 0))
        .unwrap();
    assert_eq!(a, c);
    let err = gpu
        .render(&r, &target, &cam, &small(Mode::Density, 2))
        .unwrap_err();
    assert_eq!(
        err,
        RuntimeError::Frame {
            frame: 2,
            frames: 2
        }
    );
    // Every mode of the CPU tracer but the reference path tracer is implemented on the GPU;
    // the reference is refused as unsupported.
    let cpu_only = [Mode::Reference];
    let gpu_modes: Vec<Mode> = Mode::ALL
        .into_iter()
        .filter(|m| !cpu_only.contains(m))
        .collect();
    assert_eq!(GPU_MODES.to_vec(), gpu_modes);
    let e = gpu
        .render(&r, &target, &cam, &small(Mode::Reference, 0))
        .unwrap_err();
    assert!(matches!(e, RuntimeError::Unsupported(_)), "{e}");
    for mode in GPU_MODES {
        let mut s = small(mode, 0);
        s.integrator.spp = 1;
        gpu.render(&r, &target, &cam, &s).unwrap();
    }
    let mut bad = small(Mode::Density, 0);
    bad.medium.absorb = f32::NAN;
    assert!(matches!(
        gpu.render(&r, &target, &cam, &bad).unwrap_err(),
        RuntimeError::Setting(_)
    ));
}

#[test]
fn texture_target_holds_the_same_image() {
    let Some(gpu) = Gpu::new("texture_target_holds_the_same_image") else {
        return;
    };
    let asset = blob_asset(PayloadFormat::Bc7);
    let (_vol, r) = gpu.setup(&asset);
    let tex = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: None,
        size: wgpu::Extent3d {
            width: W,
            height: H,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let view = tex.create_view(&Default::default());
    let tt = r.texture_target(&gpu.device, &tex, &view).unwrap();
    let cam = vdbcook_trace::Camera::framing(&asset, 0, W as f64 / H as f64).unwrap();
    let s = small(Mode::BrickHue, 0);
    let row = (W * 4).div_ceil(256) * 256;
    let rb = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: (row * H) as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    r.render(&gpu.queue, &mut enc, &tt, 0, &cam, &s).unwrap();
    enc.copy_texture_to_buffer(
        tex.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &rb,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: None,
            },
        },
        wgpu::Extent3d {
            width: W,
            height: H,
            depth_or_array_layers: 1,
        },
    );
    gpu.queue.submit([enc.finish()]);
    rb.slice(..).map_async(wgpu::MapMode::Read, |r| r.unwrap());
    gpu.device
        .poll(wgpu::PollType::wait_indefinitely())
        .unwrap();
    let data = vdbcook_runtime::gpu_compat::mapped_range(&rb.slice(..))
        .unwrap()
        .to_vec();
    let cpu = vdbcook_trace::render(&asset, &cam, &s).unwrap().to_rgba8();
    let mut bad = 0;
    for y in 0..H as usize {
        for x in 0..W as usize {
            let g = &data[y * row as usize + 4 * x..][..4];
            let c = &cpu[4 * (y * W as usize + x)..][..4];
            if g.iter().zip(c).any(|(a, b)| a.abs_diff(*b) > 1) {
                bad += 1;
            }
        }
    }
    eprintln!("texture target: {bad} pixels differ from the CPU's 8-bit image");
    assert!(bad * 200 <= (W * H) as usize, "{bad} pixels differ");
}

/// Delta tracking: the same seed gives the same random streams, but f32 (GPU) and f64 (CPU)
/// round free-flight distances and comparisons differently, so a few paths take other branches.
/// The images must agree statistically: per pixel within `Z_MAX` standard deviations of the
/// difference of two `spp`-sample means (scores and escapes lie in [0, 1], so a mean `m` has
/// variance at most `m(1 − m)/spp`), for all but 0.2% of the pixels, and the image means of the
/// transmittance and of the luminance within 2% (relative, plus 1e-3 absolute).
fn check_delta(gpu: &Gpu, asset: &Asset, what: &str, frame: usize, s: &RenderSettings) {
    const Z_MAX: f64 = 4.0;
    let (_vol, r) = gpu.setup(asset);
    let target = r.buffer_target(&gpu.device, W, H).unwrap();
    let cam = vdbcook_trace::Camera::framing(asset, frame, W as f64 / H as f64).unwrap();
    let cpu = vdbcook_trace::render(asset, &cam, s).unwrap();
    let g = gpu.render(&r, &target, &cam, s).unwrap();
    assert!(
        g.rgba.iter().chain(&g.value).all(|v| v.is_finite()),
        "{what}: NaN or infinite pixel on the GPU"
    );
    let n = cpu.value.len();
    let spp = s.integrator.spp as f64;
    let lc = s.lighting.light_color[0] as f64;
    let (mut bad, mut z_max, mut equal) = (0, 0.0f64, 0);
    let (mut sums_c, mut sums_g) = ([0.0f64; 2], [0.0f64; 2]);
    for p in 0..n {
        // (escaped fraction, mean luminance score) of both.
        let c = [cpu.value[p] as f64, cpu.rgba[4 * p] as f64 / lc];
        let q = [g.value[p] as f64, g.rgba[4 * p] as f64 / lc];
        let mut same = true;
        for i in 0..2 {
            sums_c[i] += c[i];
            sums_g[i] += q[i];
            let m = (0.5 * (c[i] + q[i])).clamp(0.0, 1.0);
            let sigma = (2.0 * m * (1.0 - m) / spp).sqrt().max(0.5 / spp);
            let z = (c[i] - q[i]).abs() / sigma;
            z_max = z_max.max(z);
            same &= (c[i] - q[i]).abs() < 1e-5;
            if z > Z_MAX {
                bad += 1;
            }
        }
        equal += same as usize;
        assert!(
            (0.0..=1.0).contains(&q[0]),
            "{what}: escaped fraction {}",
            q[0]
        );
    }
    let mean = |a: f64| a / n as f64;
    eprintln!(
        "{what}: {equal}/{n} pixels equal to 1e-5, {bad} channels beyond {Z_MAX}σ (max z {z_max:.2}); \
         mean T cpu {:.5} gpu {:.5}, mean L cpu {:.5} gpu {:.5}",
        mean(sums_c[0]),
        mean(sums_g[0]),
        mean(sums_c[1]),
        mean(sums_g[1])
    );
    assert!(
        bad * 500 <= n,
        "{what}: {bad} pixel channels beyond {Z_MAX}σ"
    );
    for i in 0..2 {
        let (a, b) = (mean(sums_c[i]), mean(sums_g[i]));
        assert!(
            (a - b).abs() <= 0.02 * a.abs() + 1e-3,
            "{what}: image mean {i} cpu {a} gpu {b}"
        );
    }
}

#[test]
fn delta_tracking_matches_the_cpu_statistically() {
    let Some(gpu) = Gpu::new("delta_tracking_matches_the_cpu_statistically") else {
        return;
    };
    let asset = blob_asset(PayloadFormat::F32);
    for frame in 0..2 {
        let s = {
            let base = small(Mode::DeltaTracking, frame);
            RenderSettings {
                integrator: Integrator {
                    spp: 64,
                    seed: 7,
                    ..base.integrator
                },
                ..base
            }
        };
        check_delta(
            &gpu,
            &asset,
            &format!("delta blob frame {frame}"),
            frame,
            &s,
        );
    }
    // Tiles, negative values, world units, another seed, a later batch of samples.
    let mut rng = XorShift(7);
    let frames = [random_frame(&mut rng), random_frame(&mut rng)];
    let asset = build(
        [2, 2, 1],
        rotated(0.0, [1.0; 3], [0.0; 3]),
        0.0,
        &frames,
        PayloadFormat::Bc4,
    );
    let s = {
        let base = small(Mode::DeltaTracking, 1);
        RenderSettings {
            medium: Medium {
                unit: vdbcook_trace::LengthUnit::World,
                absorb: 0.3,
                ..base.medium
            },
            integrator: Integrator {
                spp: 64,
                seed: 123,
                first_sample: 64,
                ..base.integrator
            },
            ..base
        }
    };
    check_delta(&gpu, &asset, "delta random world units", 1, &s);
}

#[test]
fn dense_media_match() {
    let Some(gpu) = Gpu::new("dense_media_match") else {
        return;
    };
    // A thick, bright medium: single-scatter rays end early on 3T² < cutoff and shadow rays
    // cross much density; delta paths collide often and ratio tracking hits its weight floor.
    let asset = blob_asset(PayloadFormat::F32);
    let dense = |s: &mut RenderSettings| {
        s.medium.absorb = 0.5;
        s.medium.scatter = 6.0;
        s.integrator.gain = 0.05;
        s.integrator.step = 0.5;
        s.integrator.shadow_step = 1.25;
        s.lighting.light_dir = [-0.4, 0.8, 0.3];
    };
    check_modes(&gpu, &asset, "dense", 1, dense);
    // 16 spp, not 64: lavapipe (llvmpipe) ends every loop once an invocation has run 65535 loop
    // iterations in all (`LP_MAX_TGSI_LOOP_ITERATIONS`, counted over the whole shader), and 64
    // dense paths of a pixel (with their walks and shadow rays) pass that, which silently cuts
    // the sample loop short there. Hardware drivers have no such limit.
    let mut s = {
        let base = small(Mode::DeltaTracking, 1);
        RenderSettings {
            integrator: Integrator {
                spp: 16,
                seed: 99,
                ..base.integrator
            },
            ..base
        }
    };
    dense(&mut s);
    check_delta(&gpu, &asset, "delta dense", 1, &s);
}

// ---- Payload layouts: every layout forced on the same adapter, against the CPU decode. ----

// Native BC textures read each voxel up to `payload::read_codes_per_voxel` codes of the brick's
// `(hi − lo)/255` from the asset's decode (BC4: per block, one code of an integer decoder's
// rounding plus D3D's 3% of the endpoint gap, half a code more for inexact palettes; BC7 1):
// the bound the API specs allow, not what one driver does. Measured on these seeded random
// blocks: lavapipe BC4 ≤ 2 codes and at most 0.87 of each block's bound, an NVIDIA H100 ≤ 3.2
// codes (before the bound was per block); BC7 exact on both (`docs/payloads.md`).

/// An asset with bricks in every format (cycled per brick: the packed widths 3, 5, 6 and 7
/// have voxels whose bits cross a word boundary), the blob frames.
fn mixed_asset() -> Asset {
    build_mixed(
        [2, 2, 2],
        rotated(25.0, [0.5, 0.7, 1.2], [3.0, -2.0, 1.0]),
        0.0,
        &[
            blob_frame([120.0, 100.0, 40.0], 34.0, 1.2, Some([1, 1, 1])),
            blob_frame([140.0, 110.0, 50.0], 28.0, 2.5, None),
        ],
        PayloadFormat::Bc7,
        0x5eed_00ff,
        |i| PayloadFormat::ORDER[i % PayloadFormat::ORDER.len()],
    )
}

/// The BC4 blob with every block's palette made exact (`payload::bc4_palette_exact`, as the
/// cooker's encoder writes them): the second endpoint moved in to the nearest gap that is a
/// multiple of 7 (`red_0 > red_1`; a gap under 7 becomes 0) or 5, gaps from 0 to 255. (lavapipe
/// read them within 1 code when this was written; the test asserts each block's own bound.)
fn exact_bc4_asset() -> Asset {
    let mut noise = XorShift(0x5eed_b4e7);
    vdbcook_asset::builder::AssetBuilder::new([2, 2, 2])
        .index_to_world(rotated(25.0, [0.5, 0.7, 1.2], [3.0, -2.0, 1.0]))
        .format(PayloadFormat::Bc4)
        .frames([
            blob_frame([120.0, 100.0, 40.0], 34.0, 1.2, Some([1, 1, 1])),
            blob_frame([140.0, 110.0, 50.0], 28.0, 2.5, None),
        ])
        .build_with(|_, vals| {
            let mut brick = test_brick(PayloadFormat::Bc4, vals, &mut noise);
            for block in brick.bytes.chunks_exact_mut(8) {
                let (r0, r1) = (block[0] as i32, block[1] as i32);
                block[1] = if r0 > r1 {
                    (r0 - 7 * ((r0 - r1) / 7)) as u8
                } else {
                    (r0 + 5 * ((r1 - r0) / 5)) as u8
                };
                assert!(payload::bc4_palette_exact(block[0], block[1]));
            }
            brick
        })
        .unwrap()
}

/// The assets every layout is checked on: one per quantized format (packed: one width), BC4
/// with exact palettes, and the mixed one.
fn layout_assets() -> Vec<(&'static str, Asset)> {
    vec![
        ("bc7", blob_asset(PayloadFormat::Bc7)),
        ("bc4", blob_asset(PayloadFormat::Bc4)),
        ("bc4-exact", exact_bc4_asset()),
        ("unorm8", blob_asset(PayloadFormat::Unorm8)),
        ("packed5", blob_asset(PayloadFormat::Packed5)),
        ("mixed", mixed_asset()),
    ]
}

/// Every voxel of every brick as the GPU reads it (`vdb_brick_voxel` of `VOLUME_WGSL`, in an
/// engine-style pipeline of its own), in the CPU's order: brick-major, voxel `64x + 8y + z`.
/// In chunks of bricks whose values fit one storage binding of the device.
fn read_voxels(gpu: &Gpu, vol: &GpuVolume, bricks: usize) -> Vec<f32> {
    let per = (gpu.device.limits().max_storage_buffer_binding_size / 2048).max(1) as usize;
    let mut out = Vec::with_capacity(bricks * 512);
    for first in (0..bricks).step_by(per) {
        out.extend(read_voxel_range(gpu, vol, first, per.min(bricks - first)));
    }
    out
}

/// `read_voxels` of bricks `first .. first + bricks`.
fn read_voxel_range(gpu: &Gpu, vol: &GpuVolume, first: usize, bricks: usize) -> Vec<f32> {
    let n = (bricks * 512).max(64);
    assert!(n / 64 <= 65535, "test asset too large for one dispatch row");
    let source = format!(
        "{}\nconst VOX_FIRST: u32 = {first}u;\n{}",
        vdbcook_runtime::VOLUME_WGSL,
        r#"
@group(1) @binding(0) var<storage, read_write> vox_out: array<f32>;
@compute @workgroup_size(64)
fn read_voxels(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= arrayLength(&vox_out)) {
        return;
    }
    let v = i % 512u;
    let m = vec3<i32>(i32(v / 64u), i32((v / 8u) % 8u), i32(v % 8u));
    vox_out[i] = vdb_brick_voxel(VOX_FIRST + i / 512u, m);
}
"#
    );
    let d = &gpu.device;
    let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("read voxels"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let out_layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: None,
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: false },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }],
    });
    let (vol_layout, vol_group) = vol.bind_group();
    let layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: None,
        bind_group_layouts: &[Some(vol_layout), Some(&out_layout)],
        immediate_size: 0,
    });
    let pipeline = d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("read voxels"),
        layout: Some(&layout),
        module: &module,
        entry_point: Some("read_voxels"),
        compilation_options: Default::default(),
        cache: None,
    });
    let size = (n * 4) as u64;
    let out = d.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let read = d.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let out_group = d.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &out_layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: out.as_entire_binding(),
        }],
    });
    let mut enc = d.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, vol_group, &[]);
        pass.set_bind_group(1, &out_group, &[]);
        pass.dispatch_workgroups((n as u32).div_ceil(64), 1, 1);
    }
    enc.copy_buffer_to_buffer(&out, 0, &read, 0, size);
    gpu.queue.submit([enc.finish()]);
    read.slice(..)
        .map_async(wgpu::MapMode::Read, |r| r.expect("map"));
    d.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let v: Vec<f32> =
        bytemuck::cast_slice(&vdbcook_runtime::gpu_compat::mapped_range(&read.slice(..)).unwrap())
            .to_vec();
    v[..bricks * 512].to_vec()
}

/// Checks every voxel the GPU reads against `Asset::decode_brick`; returns (voxels off by more
/// than f32 rounding, the largest difference in 1/255 steps of the brick range).
fn check_voxels(gpu: &Gpu, vol: &GpuVolume, asset: &Asset, what: &str) -> (usize, f32) {
    let got = read_voxels(gpu, vol, asset.brick_count());
    let native = |f: wgpu::TextureFormat| vol.layout().textures.iter().any(|t| t.format == f);
    let (native_bc4, native_bc7) = (
        native(wgpu::TextureFormat::Bc4RUnorm),
        native(wgpu::TextureFormat::Bc7RgbaUnorm),
    );
    let (mut off, mut max_codes) = (0, 0.0f32);
    let mut dec = [0.0f32; 512];
    let mut read_codes = [0.0f32; 512];
    for b in 0..asset.brick_count() {
        asset.decode_brick(b as u32, &mut dec);
        let (format, bytes) = asset.brick_bytes(b as u32);
        payload::read_codes_per_voxel(format, bytes, &mut read_codes);
        let [lo, hi] = asset.brick_quant[b];
        // f32 dequantization on both sides: a few ulps of the range.
        let round = 4.0 * f32::EPSILON * (lo.abs() + hi.abs());
        for (i, (&c, &g)) in dec.iter().zip(&got[b * 512..(b + 1) * 512]).enumerate() {
            let diff = (c - g).abs();
            if !format.is_quantized() {
                assert!(
                    c.to_bits() == g.to_bits(),
                    "{what}: {} brick {b} voxel {i}: cpu {c}, gpu {g}",
                    format.name()
                );
                continue;
            }
            let codes = if hi > lo {
                diff / ((hi - lo) / 255.0)
            } else {
                0.0
            };
            if diff > round {
                off += 1;
                max_codes = max_codes.max(codes);
            }
            // What the specs let a conformant decoder read of this voxel's block
            // (`payload::read_codes_per_voxel`).
            let native = (native_bc4 && format == PayloadFormat::Bc4)
                || (native_bc7 && format == PayloadFormat::Bc7);
            let allowed = if native {
                payload::codes_to_value(read_codes[i], [lo, hi]) + round
            } else {
                round
            };
            assert!(
                diff <= allowed,
                "{what}: {} brick {b} voxel {i}: cpu {c}, gpu {g} ({codes:.3} codes)",
                format.name()
            );
        }
    }
    (off, max_codes)
}

#[test]
fn every_voxel_reads_back_as_the_cpu_decodes_in_every_layout() {
    let Some(gpu) = Gpu::new("every_voxel_reads_back_as_the_cpu_decodes_in_every_layout") else {
        return;
    };
    for (name, asset) in layout_assets() {
        for layout in Layout::ALL {
            let options = UploadOptions {
                force: Some(layout),
            };
            let vol = GpuVolume::upload_with(&gpu.device, &gpu.queue, &asset, options)
                .unwrap_or_else(|e| panic!("{name} {}: {e}", layout.name()));
            let l = vol.layout();
            assert_eq!(l.layout, layout);
            // Where each quantized format went.
            for t in &l.textures {
                use wgpu::TextureFormat as F;
                let want = match (layout, t.source) {
                    (_, PayloadFormat::Unorm8) => F::R8Unorm,
                    (Layout::Bc3d | Layout::Bc2dArray, PayloadFormat::Bc4) => F::Bc4RUnorm,
                    (Layout::Bc3d | Layout::Bc2dArray, PayloadFormat::Bc7) => F::Bc7RgbaUnorm,
                    (_, PayloadFormat::Bc4) => F::R8Unorm,
                    (_, PayloadFormat::Bc7) => F::Rgba8Unorm,
                    (_, f) => panic!("{} bricks in a texture", f.name()),
                };
                assert_eq!(t.format, want, "{name} {}", layout.name());
                assert_eq!(
                    t.dim3,
                    matches!(layout, Layout::Bc3d | Layout::Decoded3d),
                    "{name} {}",
                    layout.name()
                );
            }
            // Packed bricks keep their own words unless every brick is decoded into buffers.
            let packed: u64 = PayloadFormat::PACKED
                .iter()
                .map(|f| asset.header.brick_counts[f.rank()] * f.bytes_per_brick() as u64)
                .sum();
            let want_packed = if layout == Layout::Buffers { 0 } else { packed };
            assert_eq!(l.packed_bytes, want_packed, "{name} {}", layout.name());
            let quantized: u64 = asset.header.brick_counts[..3].iter().sum();
            assert_eq!(
                l.textures.is_empty(),
                layout == Layout::Buffers || quantized == 0,
                "{name} {}: {}",
                layout.name(),
                vol.describe()
            );
            let (off, max_codes) = check_voxels(&gpu, &vol, &asset, name);
            eprintln!(
                "{name} {}: {off}/{} voxels beyond f32 rounding, max {max_codes:.3}/255 of the \
                 brick range; {}",
                layout.name(),
                asset.brick_count() * 512,
                vol.describe()
            );
        }
    }
}

/// Renders every deterministic mode of `frame` with `vol`/`r` and the CPU tracer; native BC4
/// widens the tolerances by `slack` and allows `flips_per_mille` pixels beyond them (a value one
/// code off can move a first hit or a cutoff decision to another voxel).
fn check_modes_in(
    gpu: &Gpu,
    asset: &Asset,
    r: &Renderer,
    what: &str,
    frame: usize,
    slack: f32,
    flips_per_mille: usize,
) -> Vec<String> {
    let target = r.buffer_target(&gpu.device, W, H).unwrap();
    // The default view frames the stored box; halve the distance so the blob fills the frame.
    let mut cam = vdbcook_trace::Camera::framing(asset, frame, W as f64 / H as f64).unwrap();
    cam.eye = [0, 1, 2].map(|a| 0.5 * (cam.eye[a] + cam.look_at[a]));
    let mut failures = vec![];
    for mode in DETERMINISTIC {
        let s = small(mode, frame);
        let cpu = vdbcook_trace::render(asset, &cam, &s).unwrap();
        if mode == Mode::Density {
            let covered = cpu.value.iter().filter(|&&t| t < 0.99).count();
            assert!(
                covered * 5 >= cpu.value.len(),
                "{what}: the volume covers only {covered}/{} pixels",
                cpu.value.len()
            );
        }
        let g = gpu.render(r, &target, &cam, &s).unwrap();
        let (bad, first, max_diff) = mismatches_with(&cpu, &g, mode, slack);
        let n = cpu.value.len();
        eprintln!("{what} {mode:?}: {bad}/{n} pixels differ (max diff {max_diff:.2e}) {first}");
        if bad * 1000 > n * flips_per_mille {
            failures.push(format!("{what} {mode:?}: {bad}/{n}; {first}"));
        }
    }
    failures
}

#[test]
fn every_mode_matches_the_cpu_tracer_in_every_layout() {
    let Some(gpu) = Gpu::new("every_mode_matches_the_cpu_tracer_in_every_layout") else {
        return;
    };
    let mut failures = vec![];
    for (name, asset) in layout_assets() {
        for layout in Layout::ALL {
            let (vol, r) = gpu.setup_with(
                &asset,
                UploadOptions {
                    force: Some(layout),
                },
            );
            let (slack, flips) = if vol.exact() {
                (0.0, 5)
            } else {
                (BC4_IMAGE_SLACK, 20)
            };
            let what = format!("{name} {}", layout.name());
            failures.extend(check_modes_in(&gpu, &asset, &r, &what, 1, slack, flips));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Images from native BC textures: absolute slack on every tolerance, the BC4 read bound over the
/// largest brick range of these assets (2.5): a first-hit value moves at most that much;
/// transmittance and scatter move far less.
const BC4_IMAGE_SLACK: f32 = payload::BC4_NATIVE_CODES * 2.5 / 255.0;

#[test]
fn gpu_timer_brackets_a_render() {
    let test = "gpu_timer_brackets_a_render";
    let Some((device, queue)) = gpu_with(test, wgpu::Features::TIMESTAMP_QUERY, None) else {
        return;
    };
    let Some(timer) = GpuTimer::new(&device, &queue) else {
        assert!(!device.features().contains(wgpu::Features::TIMESTAMP_QUERY));
        eprintln!("{test}: skipped, the adapter has no timestamp queries");
        return;
    };
    let gpu = Gpu { device, queue };
    let asset = blob_asset(PayloadFormat::F32);
    let (_, r) = gpu.setup(&asset);
    let target = r.buffer_target(&gpu.device, W, H).unwrap();
    let cam = vdbcook_trace::Camera::framing(&asset, 0, W as f64 / H as f64).unwrap();
    let s = small(Mode::SingleScatter, 0);
    for _ in 0..2 {
        let start = std::time::Instant::now();
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        timer.begin(&mut enc);
        r.render_to_buffer(&gpu.queue, &mut enc, &target, 0, &cam, &s)
            .unwrap();
        timer.end(&mut enc);
        gpu.queue.submit([enc.finish()]);
        let ms = timer.read_ms(&gpu.device).expect("timestamps read back");
        let wall = start.elapsed().as_secs_f64() * 1e3;
        // Positive, and within the wall time of submit-to-read (plus clock granularity).
        assert!(ms > 0.0 && ms <= wall + 1.0, "GPU {ms} ms, wall {wall} ms");
    }
    // The engine's way: request after submitting, then non-blocking polls (as an engine's later
    // frames would) until the time is there; nothing before the request.
    assert_eq!(timer.try_read_ms(), None, "nothing requested");
    let start = std::time::Instant::now();
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    timer.begin(&mut enc);
    r.render_to_buffer(&gpu.queue, &mut enc, &target, 0, &cam, &s)
        .unwrap();
    timer.end(&mut enc);
    gpu.queue.submit([enc.finish()]);
    timer.request();
    timer.request(); // a second request while one is under way does nothing
    let mut ms = None;
    for _ in 0..60_000 {
        gpu.device.poll(wgpu::PollType::Poll).unwrap();
        ms = timer.try_read_ms();
        if ms.is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    let ms = ms.expect("the non-blocking read completes once the device is polled");
    let wall = start.elapsed().as_secs_f64() * 1e3;
    assert!(ms > 0.0 && ms <= wall + 1.0, "GPU {ms} ms, wall {wall} ms");
    assert_eq!(timer.try_read_ms(), None, "read once");
}

#[test]
fn the_automatic_layout_prefers_decoded_textures_on_software_adapters_only() {
    let test = "the_automatic_layout_prefers_decoded_textures_on_software_adapters_only";
    let Some((device, queue)) = gpu_with(test, OPTIONAL_FEATURES, None) else {
        return;
    };
    let software = device.adapter_info().device_type == wgpu::DeviceType::Cpu;
    let bc = device.features().contains(OPTIONAL_FEATURES);
    let want = match (software, bc) {
        (true, _) | (false, false) => Layout::Decoded3d,
        (false, true) => Layout::Bc3d,
    };
    assert_eq!(
        Layout::automatic_order(&device)[0],
        if software {
            Layout::Decoded3d
        } else {
            Layout::Bc3d
        }
    );
    for format in [PayloadFormat::Bc4, PayloadFormat::Bc7] {
        let vol = GpuVolume::upload(&device, &queue, &blob_asset(format)).unwrap();
        assert_eq!(vol.layout().layout, want, "{}", vol.describe());
    }
}

#[test]
fn an_adapter_without_bc_decodes_at_upload_and_forced_bc_is_refused() {
    let Some((device, queue)) = gpu_with(
        "an_adapter_without_bc_decodes_at_upload_and_forced_bc_is_refused",
        wgpu::Features::empty(),
        None,
    ) else {
        return;
    };
    let gpu = Gpu { device, queue };
    for format in [PayloadFormat::Bc4, PayloadFormat::Bc7] {
        let asset = blob_asset(format);
        let (vol, r) = gpu.setup(&asset);
        assert_eq!(vol.layout().layout, Layout::Decoded3d, "{}", vol.describe());
        assert!(vol.exact());
        check_voxels(&gpu, &vol, &asset, "no BC");
        let f = check_modes_in(&gpu, &asset, &r, "no BC", 1, 0.0, 5);
        assert!(f.is_empty(), "{f:#?}");
        for layout in [Layout::Bc3d, Layout::Bc2dArray] {
            let force = Some(layout);
            match GpuVolume::upload_with(&gpu.device, &gpu.queue, &asset, UploadOptions { force }) {
                Err(RuntimeError::Limits(m)) => {
                    assert!(m.contains("TEXTURE_COMPRESSION_BC"), "{m}")
                }
                Err(e) => panic!("{}: unexpected error {e}", layout.name()),
                Ok(v) => panic!("{}: uploaded as {}", layout.name(), v.describe()),
            }
        }
    }
}

/// Bytes of `asset`'s topology as one storage binding holds it (roots, nodes, refs, tiles and the
/// per-brick ranges).
fn topology_bytes(asset: &Asset) -> u64 {
    4 * (asset.roots.len()
        + 2 * asset.l2_masks.len()
        + asset.l2_base.len()
        + asset.l2_prefix.len()
        + 2 * asset.l2_ranges.len()
        + asset.l3_refs.len()
        + asset.tiles.len()
        + 4 * asset.brick_count()) as u64
}

#[test]
fn small_limits_fall_back_to_buffers_and_a_pool_too_big_is_an_error() {
    let test = "small_limits_fall_back_to_buffers_and_a_pool_too_big_is_an_error";
    let asset = mixed_asset();
    let small_textures = wgpu::Limits {
        max_texture_dimension_1d: 16,
        max_texture_dimension_2d: 16,
        max_texture_dimension_3d: 16,
        max_texture_array_layers: 8,
        ..wgpu::Limits::default()
    };
    let Some((device, queue)) = gpu_with(test, OPTIONAL_FEATURES, Some(small_textures.clone()))
    else {
        return;
    };
    let gpu = Gpu { device, queue };
    let (vol, r) = gpu.setup(&asset);
    assert_eq!(vol.layout().layout, Layout::Buffers, "{}", vol.describe());
    check_voxels(&gpu, &vol, &asset, "small limits");
    let f = check_modes_in(&gpu, &asset, &r, "small limits", 1, 0.0, 5);
    assert!(f.is_empty(), "{f:#?}");
    // Forcing a texture layout the limits cannot hold is an error that says why.
    let force = Some(Layout::Decoded3d);
    let err = GpuVolume::upload_with(&gpu.device, &gpu.queue, &asset, UploadOptions { force })
        .err()
        .expect("refused");
    assert!(
        matches!(&err, RuntimeError::Limits(m) if m.contains("tile layers")),
        "{err}"
    );

    // Storage bindings that hold the topology but not a quarter of the pool either: an error.
    let topo_bytes = topology_bytes(&asset) as u32;
    let binding = topo_bytes.next_multiple_of(1024);
    assert!(
        (binding as usize / 1024) * 4 < asset.brick_count(),
        "the test asset must not fit"
    );
    let tiny = wgpu::Limits {
        max_storage_buffer_binding_size: binding as u64,
        ..small_textures
    };
    let Some((device, queue)) = gpu_with(test, OPTIONAL_FEATURES, Some(tiny)) else {
        return;
    };
    match GpuVolume::upload(&device, &queue, &asset) {
        Err(RuntimeError::Limits(m)) => {
            eprintln!("refused: {m}");
            assert!(m.contains("no payload layout fits"), "{m}");
        }
        Err(e) => panic!("unexpected error {e}"),
        Ok(v) => panic!("uploaded as {}", v.describe()),
    }
}

#[test]
fn packed_bricks_spread_over_several_payload_buffers_read_back_exactly() {
    let test = "packed_bricks_spread_over_several_payload_buffers_read_back_exactly";
    let asset = blob_asset(PayloadFormat::Packed7);
    let topo_bytes = topology_bytes(&asset);
    let packed = asset.payloads[PayloadFormat::Packed7.rank()].len() as u64;
    // Bindings that hold the topology and about a third of the packed words (in whole f32
    // bricks, the buffers' stride): 448-byte bricks then cross from one buffer into the next.
    let binding = topo_bytes.max(packed / 3).next_multiple_of(2048);
    assert!(
        packed > 2 * binding && packed <= 4 * binding,
        "the test asset must span 3 or 4 buffers: {packed} bytes, bindings of {binding}"
    );
    let limits = wgpu::Limits {
        max_storage_buffer_binding_size: binding,
        ..wgpu::Limits::default()
    };
    let Some((device, queue)) = gpu_with(test, OPTIONAL_FEATURES, Some(limits)) else {
        return;
    };
    let gpu = Gpu { device, queue };
    let force = Some(Layout::Decoded3d);
    let vol = GpuVolume::upload_with(&gpu.device, &gpu.queue, &asset, UploadOptions { force })
        .unwrap_or_else(|e| panic!("{e}"));
    let l = vol.layout();
    assert_eq!(l.packed_bytes, packed, "{}", vol.describe());
    assert!(
        matches!(l.buffers, vdbcook_runtime::BufferLayout::F32 { buffers, .. } if buffers >= 3),
        "{}",
        vol.describe()
    );
    let (off, max_codes) = check_voxels(&gpu, &vol, &asset, test);
    assert_eq!(off, 0, "{off} voxels off by up to {max_codes} codes");
}

/// Cooked assets (real encoder output, not seeded noise): `VDBCOOK_TEST_ASSETS=a.vdbc,b.vdbc`
/// reads every voxel back in every layout and prints how far native BC4 lands from the exact
/// decode. Skipped (with a line saying so) when the variable is unset.
#[test]
fn cooked_assets_from_the_environment_read_back_in_every_layout() {
    let Ok(list) = std::env::var("VDBCOOK_TEST_ASSETS") else {
        eprintln!("skipped: set VDBCOOK_TEST_ASSETS=a.vdbc,b.vdbc to check cooked assets");
        return;
    };
    let Some(gpu) = Gpu::new("cooked_assets_from_the_environment_read_back_in_every_layout") else {
        return;
    };
    for path in list.split(',').filter(|p| !p.is_empty()) {
        let asset = Asset::load(path).unwrap_or_else(|e| panic!("{path}: {e}"));
        if asset.brick_count() * 512 / 64 > 65535 {
            eprintln!(
                "{path}: {} bricks, too many for one dispatch row",
                asset.brick_count()
            );
            continue;
        }
        for layout in Layout::ALL {
            let force = Some(layout);
            let vol = match GpuVolume::upload_with(
                &gpu.device,
                &gpu.queue,
                &asset,
                UploadOptions { force },
            ) {
                Ok(v) => v,
                Err(e) => {
                    eprintln!("{path} {}: {e}", layout.name());
                    continue;
                }
            };
            let (off, max_codes) = check_voxels(&gpu, &vol, &asset, path);
            eprintln!(
                "{path} {}: {off}/{} voxels beyond f32 rounding, max {max_codes:.3}/255; {}",
                layout.name(),
                asset.brick_count() * 512,
                vol.describe()
            );
        }
    }
}

/// Blackbody emission in the density march: the GPU's image is the CPU's (the same table, the
/// same per-voxel closed form), on a blob whose values are temperatures (peak 2000 K) under a
/// rotated transform; the glow is there (warm pixels: red over green over blue).
#[test]
fn emission_matches_the_cpu() {
    let Some(gpu) = Gpu::new("emission_matches_the_cpu") else {
        return;
    };
    let asset = build(
        [2, 2, 2],
        rotated(25.0, [0.5, 0.7, 1.2], [3.0, -2.0, 1.0]),
        0.0,
        &[blob_frame([120.0, 100.0, 40.0], 34.0, 2000.0, None)],
        PayloadFormat::F32,
    );
    let (vol, plain) = gpu.setup(&asset);
    // Emission is compiled out of `Renderer::new`'s pipeline: refused there.
    let cam = vdbcook_trace::Camera::framing(&asset, 0, W as f64 / H as f64).unwrap();
    let emission = Some(vdbcook_trace::Emission {
        range: [800.0, 2500.0],
        kelvin: [800.0, 2500.0],
        intensity: 0.5,
        channel: 0,
    });
    let probe = {
        let base = small(Mode::Density, 0);
        RenderSettings {
            medium: Medium {
                emission,
                ..base.medium
            },
            ..base
        }
    };
    let t0 = plain.buffer_target(&gpu.device, W, H).unwrap();
    let e = gpu.render(&plain, &t0, &cam, &probe).unwrap_err();
    assert!(matches!(e, RuntimeError::Unsupported(_)), "{e}");
    let r = vdbcook_runtime::Renderer::with_emission(
        &gpu.device,
        &vol,
        wgpu::TextureFormat::Rgba8Unorm,
    )
    .unwrap();
    let target = r.buffer_target(&gpu.device, W, H).unwrap();
    let s = {
        let base = small(Mode::Density, 0);
        RenderSettings {
            medium: Medium {
                absorb: 2e-5,
                emission,
                ..base.medium
            },
            ..base
        }
    };
    let cpu = vdbcook_trace::render(&asset, &cam, &s).unwrap();
    let g = gpu.render(&r, &target, &cam, &s).unwrap();
    let (bad, first, max_diff) = mismatches(&cpu, &g, Mode::Density);
    eprintln!("emission: {bad} pixels differ (max diff {max_diff:.2e}) {first}");
    assert_eq!(bad, 0, "{first}");
    // The scatter mode's emission at its samples, lit by the light too (f32 on the GPU: the
    // scatter mode's tolerance).
    let sc = RenderSettings {
        medium: Medium {
            absorb: 1e-5,
            scatter: 1e-5,
            ..s.medium.clone()
        },
        integrator: Integrator {
            mode: Mode::SingleScatter,
            ..s.integrator.clone()
        },
        ..s.clone()
    };
    let cpu_sc = vdbcook_trace::render(&asset, &cam, &sc).unwrap();
    let g_sc = gpu.render(&r, &target, &cam, &sc).unwrap();
    let (bad, first, max_diff) = mismatches(&cpu_sc, &g_sc, Mode::SingleScatter);
    eprintln!("scatter emission: {bad} pixels differ (max diff {max_diff:.2e}) {first}");
    assert!(
        bad * 1000 <= cpu_sc.value.len() * 5,
        "{bad} pixels; {first}"
    );
    assert!(
        cpu_sc
            .rgba
            .chunks(4)
            .filter(|p| p[0] > 0.05 && p[0] > p[2])
            .count()
            * 20
            > cpu_sc.value.len(),
        "the scatter image glows"
    );
    // The lit mode's emission at its samples, over its light volume.
    let lit = RenderSettings {
        integrator: Integrator {
            mode: Mode::Lit,
            ..sc.integrator.clone()
        },
        ..sc.clone()
    };
    let cpu_lit = vdbcook_trace::render(&asset, &cam, &lit).unwrap();
    let g_lit = gpu.render(&r, &target, &cam, &lit).unwrap();
    let (bad, first, max_diff) = mismatches(&cpu_lit, &g_lit, Mode::Lit);
    eprintln!("lit emission: {bad} pixels differ (max diff {max_diff:.2e}) {first}");
    assert!(
        bad * 1000 <= cpu_lit.value.len() * 5,
        "{bad} pixels; {first}"
    );
    assert!(
        cpu_lit
            .rgba
            .chunks(4)
            .filter(|p| p[0] > 0.05 && p[0] > p[2])
            .count()
            * 20
            > cpu_lit.value.len(),
        "the lit image glows"
    );
    // Delta tracking's collision estimator (f32 free flights on the GPU draw other tentative
    // collisions than the CPU's f64 ones): the image means per channel within 2%.
    let dl = RenderSettings {
        medium: Medium {
            scatter: 0.0,
            ..sc.medium.clone()
        },
        lighting: Lighting {
            light_color: [0.0; 3],
            ..sc.lighting.clone()
        },
        integrator: Integrator {
            mode: Mode::DeltaTracking,
            spp: 32,
            ..sc.integrator.clone()
        },
        ..sc.clone()
    };
    let cpu_dl = vdbcook_trace::render(&asset, &cam, &dl).unwrap();
    let g_dl = gpu.render(&r, &target, &cam, &dl).unwrap();
    assert!(g_dl.rgba.iter().all(|v| v.is_finite()));
    for c in 0..3 {
        let mean = |x: &[f32]| x.iter().skip(c).step_by(4).map(|&v| v as f64).sum::<f64>();
        let (a, b) = (mean(&cpu_dl.rgba), mean(&g_dl.rgba));
        eprintln!("delta emission channel {c}: cpu {a:.3}, gpu {b:.3}");
        assert!(c > 0 || a > 1.0, "the delta image glows red: {a}");
        assert!(
            (a - b).abs() <= 0.02 * a + 1e-3,
            "channel {c}: cpu {a} gpu {b}"
        );
    }
    let glowing = cpu
        .rgba
        .chunks(4)
        .filter(|p| p[0] > 0.05 && p[0] > p[1] && p[1] > p[2])
        .count();
    assert!(glowing * 20 > cpu.value.len(), "only {glowing} warm pixels");
}

/// The renderer records the lit mode's light-volume pass only when the frame, the light or the
/// medium changed: every render of a sequence that switches them back and forth matches the CPU
/// (a stale light volume would light frame 1 with frame 0's shadows, or with the old sun).
#[test]
fn lit_light_volume_follows_the_frame_and_the_light() {
    let Some(gpu) = Gpu::new("lit_light_volume_follows_the_frame_and_the_light") else {
        return;
    };
    let asset = blob_asset(PayloadFormat::F32);
    let (_vol, r) = gpu.setup(&asset);
    let target = r.buffer_target(&gpu.device, W, H).unwrap();
    let cam = vdbcook_trace::Camera::framing(&asset, 0, W as f64 / H as f64).unwrap();
    let sun_a = [0.3, 0.3, 0.0];
    let sun_b = [-0.5, 0.2, 0.6];
    let mut last: Option<Vec<f32>> = None;
    for (frame, sun, scatter) in [
        (0, sun_a, 1.5),
        (1, sun_a, 1.5),
        (1, sun_b, 1.5),
        (1, sun_b, 0.5),
        (0, sun_a, 1.5),
    ] {
        let s = {
            let base = small(Mode::Lit, frame);
            RenderSettings {
                medium: Medium {
                    scatter,
                    ..base.medium
                },
                lighting: Lighting {
                    light_dir: sun,
                    ..base.lighting
                },
                ..base
            }
        };
        let cpu = vdbcook_trace::render(&asset, &cam, &s).unwrap();
        let g = gpu.render(&r, &target, &cam, &s).unwrap();
        let (bad, first, max_diff) = mismatches(&cpu, &g, Mode::Lit);
        eprintln!("frame {frame} sun {sun:?} scatter {scatter}: {bad} differ (max {max_diff:.2e}) {first}");
        assert!(bad * 1000 <= cpu.value.len() * 5, "{bad} pixels; {first}");
        // Each step changes the image (the test would not see a stale volume otherwise).
        if let Some(prev) = &last {
            let changed = prev
                .iter()
                .zip(&g.rgba)
                .filter(|(a, b)| (*a - *b).abs() > 1e-2)
                .count();
            assert!(
                changed > 100,
                "frame {frame} sun {sun:?}: only {changed} values changed"
            );
        }
        last = Some(g.rgba);
    }
}

/// The diffusion model (`MsModel::Diffusion`): the light-volume build's solve (`ms_*` passes in
/// `light_build.wgsl`: every level, every sweep) and the march's density-weighted read match the
/// CPU's `vdbcook_trace::diffusion` through a sequence that switches the model, the frame and
/// the sun (the light volume's cache must tell the models apart).
#[test]
fn lit_diffusion_matches_the_cpu() {
    let Some(gpu) = Gpu::new("lit_diffusion_matches_the_cpu") else {
        return;
    };
    let asset = blob_asset(PayloadFormat::F32);
    let (_vol, r) = gpu.setup(&asset);
    let target = r.buffer_target(&gpu.device, W, H).unwrap();
    let cam = vdbcook_trace::Camera::framing(&asset, 0, W as f64 / H as f64).unwrap();
    let mut last: Option<Vec<f32>> = None;
    for (model, frame, sun) in [
        (MsModel::Octaves, 0, [0.3, 0.3, 0.0]),
        (MsModel::Diffusion, 0, [0.3, 0.3, 0.0]),
        (MsModel::Diffusion, 1, [-0.5, 0.2, 0.6]),
        (MsModel::Octaves, 1, [-0.5, 0.2, 0.6]),
    ] {
        let s = {
            let base = small(Mode::Lit, frame);
            RenderSettings {
                lighting: Lighting {
                    light_dir: sun,
                    ms_model: model,
                    ms_sky: model.default_ms_sky(),
                    ..base.lighting
                },
                ..base
            }
        };
        let cpu = vdbcook_trace::render(&asset, &cam, &s).unwrap();
        let g = gpu.render(&r, &target, &cam, &s).unwrap();
        let (bad, first, max_diff) = mismatches(&cpu, &g, Mode::Lit);
        eprintln!("{model:?} frame {frame}: {bad} differ (max {max_diff:.2e}) {first}");
        assert!(bad * 1000 <= cpu.value.len() * 5, "{bad} pixels; {first}");
        if let Some(prev) = &last {
            let changed = prev
                .iter()
                .zip(&g.rgba)
                .filter(|(a, b)| (*a - *b).abs() > 1e-2)
                .count();
            assert!(
                changed > 100,
                "{model:?} frame {frame}: only {changed} values changed"
            );
        }
        last = Some(g.rgba);
    }
    // Each light alone, bright, so that every one of the six stored fluxes (16 bits per axis
    // and field, `ms_store_main`) carries a visible share of the image: a read that mixes up
    // their order differs from the CPU on many pixels.
    for (light_color, sky) in [([6.0f32; 3], [0.0f32; 3]), ([0.0; 3], [2.0; 3])] {
        let s = {
            let base = small(Mode::Lit, 1);
            RenderSettings {
                lighting: Lighting {
                    light_dir: [-0.5, 0.2, 0.6],
                    light_color,
                    sky,
                    ..base.lighting
                },
                ..base
            }
        };
        let cpu = vdbcook_trace::render(&asset, &cam, &s).unwrap();
        let g = gpu.render(&r, &target, &cam, &s).unwrap();
        let (bad, first, max_diff) = mismatches(&cpu, &g, Mode::Lit);
        eprintln!("sun {light_color:?} sky {sky:?}: {bad} differ (max {max_diff:.2e}) {first}");
        // 1‰: the lit mode's allowance for a pixel whose near-field gate flips in f32, tighter
        // than the 5‰ above (where a mixed-up read shows on fewer pixels).
        assert!(bad * 1000 <= cpu.value.len(), "{bad} pixels; {first}");
    }
    // Fewer gathered orders (`Lighting::ms_gather`: the solve from the first order's light, or
    // alone): the GPU skips the same passes the CPU skips, and each changes the image. Then
    // both orders at `light_res` 64 (levels of 64 to 4 cells: the gather's shared paths,
    // `ms_paths_main`, on levels 1 to 3 go on to a coarser level's, on level 4 to the grid's
    // end; at 24, on level 1, and level 2 is the coarsest) and 9 (levels of 9 and 5 cells: the
    // paths do not fit in level 0's free place and follow the levels).
    let mut prev: Option<Vec<f32>> = None;
    for (ms_gather, light_res) in [(0, 24), (1, 24), (2, 64), (2, 9)] {
        let base = small(Mode::Lit, 1);
        let s = RenderSettings {
            lighting: Lighting {
                light_dir: [-0.5, 0.2, 0.6],
                light_color: [6.0; 3],
                sky: [0.0; 3],
                ms_gather,
                light_res,
                ..base.lighting
            },
            ..base
        };
        let cpu = vdbcook_trace::render(&asset, &cam, &s).unwrap();
        let g = gpu.render(&r, &target, &cam, &s).unwrap();
        let (bad, first, max_diff) = mismatches(&cpu, &g, Mode::Lit);
        eprintln!(
            "ms_gather {ms_gather} light_res {light_res}: {bad} differ (max {max_diff:.2e}) {first}"
        );
        assert!(bad * 1000 <= cpu.value.len(), "{bad} pixels; {first}");
        if let Some(p) = &prev {
            let changed = values_changed(p, &g.rgba);
            assert!(
                changed > 100,
                "ms_gather {ms_gather} light_res {light_res}: {changed} values changed"
            );
        }
        prev = Some(g.rgba);
    }
}

/// Both lit marches against the CPU on random bricks and tiles (rotated) and the blob: the voxel
/// march (`March::Voxels`) follows each brick's voxels by a DDA and cuts constant spans into
/// equal segments; the step march (the default, which every other lit test runs) samples every
/// step, jittered. The two draw different images (the test would not see a march ignored).
#[test]
fn lit_marches_match_the_cpu() {
    let Some(gpu) = Gpu::new("lit_marches_match_the_cpu") else {
        return;
    };
    let mut rng = XorShift(11);
    let frames = [random_frame(&mut rng)];
    let assets = [
        (
            "random f32, rotated",
            build(
                [2, 2, 1],
                rotated(25.0, [0.5, 0.7, 1.2], [3.0, -2.0, 1.0]),
                0.0,
                &frames,
                PayloadFormat::F32,
            ),
        ),
        ("blob", blob_asset(PayloadFormat::F32)),
    ];
    for (what, asset) in &assets {
        let (_vol, r) = gpu.setup(asset);
        let target = r.buffer_target(&gpu.device, W, H).unwrap();
        let cam = vdbcook_trace::Camera::framing(asset, 0, W as f64 / H as f64).unwrap();
        let mut images = Vec::new();
        for (march, step) in [
            (March::Voxels, 1.0f32),
            (March::Voxels, 0.4),
            (March::Steps, 1.0),
        ] {
            let s = {
                let base = small(Mode::Lit, 0);
                RenderSettings {
                    integrator: Integrator {
                        march,
                        step,
                        ..base.integrator
                    },
                    ..base
                }
            };
            let label = format!("{what}, {march:?} step {step}");
            images.push(lit_matches_cpu(&gpu, &r, &target, asset, &cam, &s, &label));
        }
        let changed = values_changed(&images[0], &images[2]);
        assert!(
            changed > 100,
            "{what}: the marches differ in {changed} values only"
        );
    }
}

/// Renders `s` (a lit mode) on the CPU and the GPU and asserts they differ in at most 0.5% of
/// the pixels beyond the lit mode's tolerance; the GPU's rgba.
fn lit_matches_cpu(
    gpu: &Gpu,
    r: &Renderer,
    target: &vdbcook_runtime::BufferTarget,
    asset: &Asset,
    cam: &vdbcook_trace::Camera,
    s: &RenderSettings,
    label: &str,
) -> Vec<f32> {
    let cpu = vdbcook_trace::render(asset, cam, s).unwrap();
    let g = gpu.render(r, target, cam, s).unwrap();
    let (bad, first, max_diff) = mismatches(&cpu, &g, Mode::Lit);
    eprintln!("{label}: {bad} differ (max {max_diff:.2e}) {first}");
    assert!(
        bad * 1000 <= cpu.value.len() * 5,
        "{label}: {bad} pixels; {first}"
    );
    g.rgba
}

/// How many values of two images differ by more than 10⁻³.
fn values_changed(a: &[f32], b: &[f32]) -> usize {
    a.iter()
        .zip(b)
        .filter(|(x, y)| (*x - *y).abs() > 1e-3)
        .count()
}

/// The near field toward the sun (`sun_near`): from each sample of a dense medium the first
/// light-volume cells toward the sun are walked voxel by voxel through the tree (a pipeline
/// variant with that code), the light volume's depth beyond. On the blob (cells of about eight
/// voxels at `light_res` 24, optical depth up to 15 across one) both marches match the CPU, and
/// the near field and the once-scattered light it adds below the cells (`near_scatter`) change
/// the image (a renderer that left either out would not).
#[test]
fn lit_near_field_matches_the_cpu() {
    let Some(gpu) = Gpu::new("lit_near_field_matches_the_cpu") else {
        return;
    };
    let asset = blob_asset(PayloadFormat::F32);
    let (_vol, r) = gpu.setup(&asset);
    let target = r.buffer_target(&gpu.device, W, H).unwrap();
    let cam = vdbcook_trace::Camera::framing(&asset, 0, W as f64 / H as f64).unwrap();
    for march in [March::Steps, March::Voxels] {
        let mut images = Vec::new();
        // The default; the near field without the once-scattered light below the cells
        // (`near_scatter`); no near field.
        for (sun_near, near_scatter) in [(3.0f32, 0.5f32), (3.0, 0.0), (0.0, 0.5)] {
            let s = {
                let base = small(Mode::Lit, 0);
                RenderSettings {
                    lighting: Lighting {
                        sun_near,
                        near_scatter,
                        ..base.lighting
                    },
                    integrator: Integrator {
                        march,
                        ..base.integrator
                    },
                    ..base
                }
            };
            let label = format!("{march:?} sun_near {sun_near} near_scatter {near_scatter}");
            images.push(lit_matches_cpu(&gpu, &r, &target, &asset, &cam, &s, &label));
        }
        for (k, what) in [(1, "near_scatter"), (2, "the near field")] {
            let changed = values_changed(&images[0], &images[k]);
            assert!(
                changed > 100,
                "{march:?}: {what} changed {changed} values only"
            );
        }
    }
    // Cells narrower than a voxel still walk where one is optically thick (a voxel's skin
    // is blurred between cell centres as well): the second frame, the denser blob without a
    // tile, at 128 cells, forty times denser (optical depth up to 160 per voxel: the cells
    // walk from an optical depth of 0.25 per cell, `LIT_NEAR_DEPTH`, as any cells do).
    let fine = {
        let base = small(Mode::Lit, 1);
        RenderSettings {
            medium: Medium {
                absorb: 4.0,
                scatter: 60.0,
                ..base.medium
            },
            lighting: Lighting {
                light_res: 128,
                ..base.lighting
            },
            integrator: Integrator {
                march: March::Voxels,
                ..base.integrator
            },
            ..base
        }
    };
    let cam = vdbcook_trace::Camera::framing(&asset, 1, W as f64 / H as f64).unwrap();
    let grid = vdbcook_trace::LightGrid::new(vdbcook_trace::content_box(&asset, 1), 128);
    assert!(grid.cell < 1.0, "cells of {} voxels", grid.cell);
    let mut images = Vec::new();
    for sun_near in [3.0f32, 0.0] {
        let s = RenderSettings {
            lighting: Lighting {
                sun_near,
                ..fine.lighting.clone()
            },
            ..fine.clone()
        };
        let label = format!("cells of {:.2} voxels, sun_near {sun_near}", grid.cell);
        images.push(lit_matches_cpu(&gpu, &r, &target, &asset, &cam, &s, &label));
    }
    let changed = values_changed(&images[0], &images[1]);
    assert!(
        changed > 100,
        "sub-voxel cells: the near field changed {changed} values only"
    );
}

/// An asset with a level of detail (`cook --lod`, format version 4, and `--lod-from 2`,
/// version 5): the light volume's density pass reads the coarser level's root set with indices
/// shifted by the level's place in the chain, on cells snapped to its voxels
/// (`LightGrid::with_levels`). The blob's second frame stands in as frame 0's stored level 1
/// (the runtime does not check that a level is a box filter; the cooker's `lod` tests do), so a
/// pass reading the wrong root set or shift draws a different image than the CPU's.
#[test]
fn lit_reads_the_level_of_detail_like_the_cpu() {
    let Some(gpu) = Gpu::new("lit_reads_the_level_of_detail_like_the_cpu") else {
        return;
    };
    let plain = blob_asset(PayloadFormat::F32);
    let cam = vdbcook_trace::Camera::framing(&plain, 0, W as f64 / H as f64).unwrap();
    // (first level stored, light_res): cells of 4-8 voxels read level 1, of 8-16 level 2.
    for (first, light_res) in [(1u32, 6u32), (2, 3)] {
        let mut lod = second_frame_as_level(plain.clone());
        lod.header.lod_first = first;
        lod.validate().unwrap();
        let s = {
            let base = small(Mode::Lit, 0);
            RenderSettings {
                lighting: Lighting {
                    light_res,
                    ..base.lighting
                },
                ..base
            }
        };
        let content = vdbcook_trace::content_box(&lod, 0);
        let chain = vdbcook_trace::LevelChain::of(&lod);
        let grid = vdbcook_trace::LightGrid::with_levels(content, s.lighting.light_res, chain);
        let (level, shift, _) = grid.density_level(chain);
        assert_eq!(
            (level, shift),
            (1, first),
            "cells of {} voxels read stored level 1",
            grid.cell
        );
        let mut images = Vec::new();
        for asset in [&plain, &lod] {
            let (_vol, r) = gpu.setup(asset);
            let target = r.buffer_target(&gpu.device, W, H).unwrap();
            let cpu = vdbcook_trace::render(asset, &cam, &s).unwrap();
            let g = gpu.render(&r, &target, &cam, &s).unwrap();
            let (bad, first_bad, max_diff) = mismatches(&cpu, &g, Mode::Lit);
            eprintln!(
                "from level {first}, levels {}: {bad} pixels differ (max {max_diff:.2e}) {first_bad}",
                asset.level_count()
            );
            assert!(
                bad * 1000 <= cpu.value.len() * 5,
                "{bad} pixels; {first_bad}"
            );
            images.push(g.rgba);
        }
        let changed = images[0]
            .iter()
            .zip(&images[1])
            .filter(|(a, b)| (*a - *b).abs() > 1e-2)
            .count();
        assert!(
            changed > 100,
            "from level {first}: the level changed only {changed} values"
        );
    }
}

/// The lit mode's primary rays by pixel footprint (`primary_lod`, `vdbcook_scene::level_start`):
/// where a pixel spans more than two voxels the rays read level 1, stepping two voxels; the GPU
/// splits the rays and clips each level to its content box as the CPU does, nearest and
/// trilinear, and the image differs from full resolution's.
#[test]
fn lit_primary_lod_matches_the_cpu() {
    let Some(gpu) = Gpu::new("lit_primary_lod_matches_the_cpu") else {
        return;
    };
    // Level 1 stands in as the first frame's blob at half the resolution (centre and radius
    // halved), so the far part of each ray reads a coarser blob where the near part left off.
    let lod = second_frame_as_level(blob_asset_then(
        blob_frame([60.0, 50.0, 20.0], 17.0, 1.2, None),
        PayloadFormat::F32,
    ));
    // 40×24 pixels over the blob: a pixel spans about three voxels, so every ray reads level 1
    // beyond the near side of the blob.
    let (w, h) = (40, 24);
    let cam = vdbcook_trace::Camera::framing(&lod, 0, w as f64 / h as f64).unwrap();
    let (_vol, r) = gpu.setup(&lod);
    let target = r.buffer_target(&gpu.device, w, h).unwrap();
    for filter in [
        vdbcook_trace::Filter::Nearest,
        vdbcook_trace::Filter::Trilinear,
    ] {
        let mut images = Vec::new();
        for primary_lod in [false, true] {
            let s = {
                let base = small(Mode::Lit, 0);
                RenderSettings {
                    output: Output {
                        width: w,
                        height: h,
                        ..base.output
                    },
                    lighting: Lighting {
                        light_res: 6,
                        ..base.lighting
                    },
                    integrator: Integrator {
                        filter,
                        primary_lod,
                        ..base.integrator
                    },
                    ..base
                }
            };
            let cpu = vdbcook_trace::render(&lod, &cam, &s).unwrap();
            let g = gpu.render(&r, &target, &cam, &s).unwrap();
            let (bad, first, max_diff) = mismatches(&cpu, &g, Mode::Lit);
            eprintln!("{filter:?} primary_lod {primary_lod}: {bad} pixels differ (max {max_diff:.2e}) {first}");
            assert!(bad * 100 <= cpu.value.len(), "{bad} pixels; {first}");
            images.push(g.rgba);
        }
        let changed = images[0]
            .iter()
            .zip(&images[1])
            .filter(|(a, b)| (*a - *b).abs() > 1e-2)
            .count();
        eprintln!("{filter:?}: level 1 changed {changed} values");
        assert!(
            changed * 10 > images[0].len(),
            "level 1 changed only {changed} values"
        );
    }
}

/// The lit mode's trilinear density (`vdb_trilinear`, eight tree reads per sample) against the
/// CPU's, on random bricks with tiles and negative values (f32 and BC4) and on the blob.
#[test]
fn lit_trilinear_matches_the_cpu() {
    let Some(gpu) = Gpu::new("lit_trilinear_matches_the_cpu") else {
        return;
    };
    let mut rng = XorShift(7);
    let frames = [random_frame(&mut rng), random_frame(&mut rng)];
    let assets = [
        (
            "random f32",
            build(
                [2, 2, 1],
                rotated(0.0, [1.0; 3], [0.0; 3]),
                0.0,
                &frames,
                PayloadFormat::F32,
            ),
        ),
        (
            "random bc4",
            build(
                [2, 2, 1],
                rotated(0.0, [1.0; 3], [0.0; 3]),
                0.0,
                &frames,
                PayloadFormat::Bc4,
            ),
        ),
        ("blob", blob_asset(PayloadFormat::F32)),
    ];
    for (what, asset) in &assets {
        let (vol, r) = gpu.setup(asset);
        let slack = if vol.exact() { 0.0 } else { BC4_IMAGE_SLACK };
        let target = r.buffer_target(&gpu.device, W, H).unwrap();
        let cam = vdbcook_trace::Camera::framing(asset, 1, W as f64 / H as f64).unwrap();
        let s = {
            let base = small(Mode::Lit, 1);
            RenderSettings {
                integrator: Integrator {
                    filter: vdbcook_trace::Filter::Trilinear,
                    ..base.integrator
                },
                ..base
            }
        };
        let cpu = vdbcook_trace::render(asset, &cam, &s).unwrap();
        let g = gpu.render(&r, &target, &cam, &s).unwrap();
        let (bad, first, max_diff) = mismatches_with(&cpu, &g, Mode::Lit, slack);
        eprintln!("{what} trilinear: {bad} pixels differ (max diff {max_diff:.2e}) {first}");
        assert!(
            bad * 1000 <= cpu.value.len() * 5,
            "{what}: {bad} pixels; {first}"
        );
    }
}

/// A light volume larger than the device binds is a `RuntimeError::Limits`, not a wgpu
/// validation panic: the blob at `light_res` 256 needs about 256³ cells × 8 bytes, over wgpu's
/// default 128 MiB storage binding (a device that binds more renders it); the diffusion model's
/// solve needs at least 60 bytes per cell of every level (`light_build.wgsl`'s scratch layout:
/// fifteen f32 per cell, levels halved, rounding up, down to 6 cells a side; the coarse levels'
/// shared gather paths may add more), refused the same way.
#[test]
fn a_light_volume_over_the_binding_limit_is_an_error() {
    let Some(gpu) = Gpu::new("a_light_volume_over_the_binding_limit_is_an_error") else {
        return;
    };
    let asset = blob_asset(PayloadFormat::F32);
    let (_vol, r) = gpu.setup(&asset);
    let target = r.buffer_target(&gpu.device, 16, 9).unwrap();
    let cam = vdbcook_trace::Camera::framing(&asset, 0, 16.0 / 9.0).unwrap();
    let mut s = {
        let base = small(Mode::Lit, 0);
        RenderSettings {
            output: Output {
                width: 16,
                height: 9,
                ..base.output
            },
            lighting: Lighting {
                light_res: vdbcook_trace::MAX_LIGHT_RES,
                ..base.lighting
            },
            ..base
        }
    };
    let grid =
        vdbcook_trace::LightGrid::new(vdbcook_trace::content_box(&asset, 0), s.lighting.light_res);
    let limits = gpu.device.limits();
    let most = limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size);
    let pool = 8 * grid.cells() as u64;
    let mut scratch = 0u64;
    let mut d = grid.dims.map(|v| v as u64);
    loop {
        scratch += 60 * d.iter().product::<u64>();
        if d.iter().all(|&v| v <= 6) {
            break;
        }
        d = d.map(|v| v.div_ceil(2));
    }
    for (model, bytes) in [
        (MsModel::Octaves, pool),
        (MsModel::Diffusion, pool.max(scratch)),
    ] {
        s.lighting.ms_model = model;
        match gpu.render(&r, &target, &cam, &s) {
            Err(RuntimeError::Limits(m)) => {
                assert!(
                    bytes > most,
                    "{model:?}: refused {bytes} bytes under the limit {most}: {m}"
                )
            }
            Ok(_) => assert!(
                bytes <= most,
                "{model:?}: {bytes} bytes over the limit {most} rendered"
            ),
            Err(e) => panic!("{e}"),
        }
    }
    // The renderer still works at a resolution that fits.
    let ok = RenderSettings {
        lighting: Lighting {
            light_res: 24,
            ..s.lighting
        },
        ..s
    };
    gpu.render(&r, &target, &cam, &ok).unwrap();
}
