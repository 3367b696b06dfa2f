//! Shared by the runtime's GPU tests: a device on whatever adapter exists (a missing adapter
//! skips with a printed reason, or fails when `VDBCOOK_REQUIRE_GPU=1`, as CI sets), hand-built
//! assets in every payload format whose voxels are known by construction (no cooker involved),
//! and the conversions between the CPU reference tracer's camera/settings and the runtime's.
#![allow(dead_code)]

pub use vdbcook_runtime::wgpu;
pub use vdbcook_testkit::*;

use vdbcook_asset::*;

/// A device and queue on the first adapter wgpu finds (with the BC features it has), or `None`
/// (after printing why) when there is none and `VDBCOOK_REQUIRE_GPU` is not `1`.
pub fn gpu(test: &str) -> Option<(wgpu::Device, wgpu::Queue)> {
    gpu_with(test, vdbcook_runtime::OPTIONAL_FEATURES, None)
}

/// As [`gpu`], enabling only `features ∩ the adapter's`, with the adapter's limits or `limits`
/// (the test kit's opener).
pub fn gpu_with(
    test: &str,
    features: wgpu::Features,
    limits: Option<wgpu::Limits>,
) -> Option<(wgpu::Device, wgpu::Queue)> {
    vdbcook_testkit::gpu::open_device(test, features, limits)
}

/// A smooth blob (a cloud-like ball of radius `r` around `c`, density up to `peak`, 0 outside)
/// as bricks, with fully inside leaves of near-constant density turned into tiles, plus one
/// tiled 128³ region at `tiled_region` (if any) — what a cooked smoke frame looks like.
pub fn blob_frame(c: [f64; 3], r: f64, peak: f32, tiled_region: Option<[i64; 3]>) -> FrameSpec {
    let mut f = FrameSpec::default();
    if let Some(t) = tiled_region {
        f.regions.insert(t, 0.05);
    }
    let lo = c.map(|x| ((x - r).floor() as i64).div_euclid(8));
    let hi = c.map(|x| ((x + r).ceil() as i64).div_euclid(8));
    for lz in lo[2]..=hi[2] {
        for ly in lo[1]..=hi[1] {
            for lx in lo[0]..=hi[0] {
                let o = [lx * 8, ly * 8, lz * 8];
                let vals: Vec<f32> = (0..BRICK_VOXELS)
                    .map(|i| {
                        let p = [
                            (o[0] + (i / 64) as i64) as f64 + 0.5,
                            (o[1] + (i / 8 % 8) as i64) as f64 + 0.5,
                            (o[2] + (i % 8) as i64) as f64 + 0.5,
                        ];
                        let d2: f64 = (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f64>() / (r * r);
                        let ripple = 0.8 + 0.2 * (p[0] * 0.7).sin() * (p[1] * 0.5).cos();
                        if d2 < 1.0 {
                            (peak as f64 * (1.0 - d2) * ripple) as f32
                        } else {
                            0.0
                        }
                    })
                    .collect();
                if vals.iter().all(|&v| v == 0.0) {
                    continue;
                }
                let leaf = if (lx + ly + lz) % 7 == 0 {
                    Leaf::Tile(vals.iter().sum::<f32>() / BRICK_VOXELS as f32)
                } else {
                    Leaf::Brick(vals)
                };
                f.leaves.insert(o, leaf);
            }
        }
    }
    f
}
