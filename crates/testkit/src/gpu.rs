//! The GPU tests' device opener (feature `gpu`), formerly in the runtime's `tests/common`:
//! one place that decides what a missing adapter means. Without an adapter a test skips with a
//! printed reason, or fails when `VDBCOOK_REQUIRE_GPU=1` (as CI sets), so a CI machine that
//! lost its GPU cannot pass by skipping.

/// A device and queue on the first adapter wgpu finds, enabling `features ∩ the adapter's`,
/// with the adapter's limits or `limits`; `None` (after printing why, naming `test`) when
/// there is no adapter and `VDBCOOK_REQUIRE_GPU` is not `1`, a panic when it is.
pub fn open_device(
    test: &str,
    features: wgpu::Features,
    limits: Option<wgpu::Limits>,
) -> Option<(wgpu::Device, wgpu::Queue)> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
    let adapter = match pollster::block_on(instance.request_adapter(&Default::default())) {
        Ok(a) => a,
        Err(e) => {
            let msg = format!(
                "{test}: skipped, no GPU adapter ({e}); install mesa-vulkan-drivers for software Vulkan"
            );
            if require_gpu() {
                panic!("{msg} (VDBCOOK_REQUIRE_GPU=1 makes this a failure)");
            }
            eprintln!("{msg}");
            return None;
        }
    };
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("vdbcook test"),
        // BC textures where the adapter has them: the default upload then uses them.
        required_features: adapter.features() & features,
        required_limits: limits.unwrap_or_else(|| adapter.limits()),
        ..Default::default()
    }))
    .expect("device on the adapter");
    Some((device, queue))
}

/// Whether a missing adapter is a failure: `VDBCOOK_REQUIRE_GPU` is exactly `1`.
pub fn require_gpu() -> bool {
    std::env::var("VDBCOOK_REQUIRE_GPU").as_deref() == Ok("1")
}
