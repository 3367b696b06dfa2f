//! Shared by the runtime's GPU tests: a device on whatever adapter exists (a missing adapter
//! skips with a printed reason, or fails when `VDBCOOK_REQUIRE_GPU=1`, as CI sets), and the test
//! kit re-exported (`vdbcook_testkit`: hand-built assets whose voxels are known by construction,
//! no cooker involved, seeded random content, the repository's paths).
#![allow(dead_code, unused_imports)]

pub use vdbcook_runtime::wgpu;
pub use vdbcook_testkit::*;

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
