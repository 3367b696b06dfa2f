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

/// Runs compute entry point `entry` of `source` (workgroups of 64, one invocation per point)
/// over `points` and reads back one f32 per point: group `io` holds the points
/// (`binding(0)`, `array<vec4<f32>>`, read) and the results (`binding(1)`, `array<f32>`,
/// written); `groups` are bound, in order, at the other indices from 0. `constants`: the
/// pipeline-overridable constants (a volume's `pipeline_constants()`). Waits for the device.
#[allow(clippy::too_many_arguments)]
pub fn eval_points(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    source: &str,
    entry: &str,
    constants: &[(&str, f64)],
    groups: &[(&wgpu::BindGroupLayout, &wgpu::BindGroup)],
    io: usize,
    points: &[[f32; 4]],
) -> Vec<f32> {
    use wgpu::util::DeviceExt;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("eval_points"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let storage = |binding, read_only| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    };
    let io_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("eval_points io"),
        entries: &[storage(0, true), storage(1, false)],
    });
    let size = 4 * points.len() as u64;
    let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("eval_points points"),
        contents: bytemuck::cast_slice(points),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let buffer = |usage| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("eval_points results"),
            size,
            usage,
            mapped_at_creation: false,
        })
    };
    let out = buffer(wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC);
    let read = buffer(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
    let io_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("eval_points io"),
        layout: &io_layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: input.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: out.as_entire_binding(),
            },
        ],
    });
    let mut bound: Vec<(&wgpu::BindGroupLayout, &wgpu::BindGroup)> = groups.to_vec();
    bound.insert(io, (&io_layout, &io_group));
    let layouts: Vec<Option<&wgpu::BindGroupLayout>> = bound.iter().map(|g| Some(g.0)).collect();
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("eval_points"),
        bind_group_layouts: &layouts,
        immediate_size: 0,
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("eval_points"),
        layout: Some(&layout),
        module: &module,
        entry_point: Some(entry),
        compilation_options: wgpu::PipelineCompilationOptions {
            constants,
            ..Default::default()
        },
        cache: None,
    });
    let mut enc = device.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        for (i, (_, group)) in bound.iter().enumerate() {
            pass.set_bind_group(i as u32, *group, &[]);
        }
        pass.dispatch_workgroups((points.len() as u32).div_ceil(64), 1, 1);
    }
    enc.copy_buffer_to_buffer(&out, 0, &read, 0, size);
    queue.submit([enc.finish()]);
    read.slice(..)
        .map_async(wgpu::MapMode::Read, |r| r.expect("map eval_points results"));
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .expect("device poll");
    let data = Mapped::into_view(read.slice(..).get_mapped_range()).expect("mapped range");
    bytemuck::cast_slice(&data).to_vec()
}

/// wgpu 29's `get_mapped_range()` returns the view, wgpu 30's a `Result` (as the runtime's
/// `gpu_compat::MappedRange`).
trait Mapped {
    fn into_view(self) -> Option<wgpu::BufferView>;
}
impl Mapped for wgpu::BufferView {
    fn into_view(self) -> Option<wgpu::BufferView> {
        Some(self)
    }
}
impl<E> Mapped for Result<wgpu::BufferView, E> {
    fn into_view(self) -> Option<wgpu::BufferView> {
        self.ok()
    }
}
