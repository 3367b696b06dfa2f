//! The lit mode's light volume on the GPU (`shaders/light_build.wgsl`): its two pipelines, its
//! buffers (grown on demand, never shrunk), and the cache that skips the pass while the frame,
//! the light and the medium stay the same. The renderer records it into the caller's encoder
//! ahead of the trace dispatch; the trace reads it through group 3.

use std::sync::Mutex;

use bytemuck::{Pod, Zeroable};
use vdbcook_scene::{length, normalize, Affine, LengthUnit, LightGrid};

use crate::upload::GpuVolume;
use crate::Settings;

/// `LightParams` of `light_build.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub(crate) struct LightParams {
    /// xyz: corner of cell 0 (cell space); w: the cell edge in voxels.
    pub lo: [f32; 4],
    /// xyz: cells per axis; w: density sample points per cell axis.
    pub dims: [u32; 4],
    /// xyz: unit cell-space direction toward the light; w: length per cell-space unit along it.
    pub sun: [f32; 4],
    /// xyz: length per cell-space unit along each axis; w: the extinction.
    pub axis_len: [f32; 4],
    pub frame_root: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

impl LightParams {
    /// The pass's uniform for `grid` (as `vdbcook_trace::light_dirs` in f64, then f32).
    pub fn new(grid: &LightGrid, xf: &Affine, s: &Settings, frame_root: u32) -> LightParams {
        let voxel = s.unit == LengthUnit::Voxel;
        let l = xf.dir_to_index(normalize(s.light_dir.map(|c| c as f64)));
        let n = length(l);
        let axis = [0, 1, 2].map(|a| {
            if voxel {
                1.0
            } else {
                length([xf.a[0][a], xf.a[1][a], xf.a[2][a]])
            }
        });
        let ext = s.absorb as f64 + s.scatter as f64;
        LightParams {
            lo: [grid.lo[0], grid.lo[1], grid.lo[2], grid.cell].map(|v| v as f32),
            dims: [grid.dims[0], grid.dims[1], grid.dims[2], grid.sub],
            sun: [
                l[0] / n,
                l[1] / n,
                l[2] / n,
                if voxel { 1.0 } else { 1.0 / n },
            ]
            .map(|v| v as f32),
            axis_len: [axis[0], axis[1], axis[2], ext].map(|v| v as f32),
            frame_root,
            _pad0: 0,
            _pad1: 0,
            _pad2: 0,
        }
    }
}

/// Buffers of one capacity and their bind groups.
struct Buffers {
    cells: usize,
    build_group: wgpu::BindGroup,
    read_group: wgpu::BindGroup,
}

/// The light-volume pass of one renderer.
pub(crate) struct LightPass {
    density: wgpu::ComputePipeline,
    tau: wgpu::ComputePipeline,
    build_layout: wgpu::BindGroupLayout,
    pub read_layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    /// Bound at group 3 by the modes that read no light volume.
    pub empty_group: wgpu::BindGroup,
    /// The buffers, and the uniform of the last pass recorded into them (`None`: none yet, or
    /// invalidated).
    state: Mutex<(Option<Buffers>, Option<LightParams>)>,
}

const WORKGROUP: u32 = 4;

fn storage(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl LightPass {
    pub fn new(device: &wgpu::Device, volume: &GpuVolume) -> LightPass {
        let source = format!(
            "{}\n{}\n{}",
            crate::VOLUME_WGSL,
            crate::LIGHT_WGSL,
            crate::LIGHT_BUILD_WGSL
        );
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("vdbcook light volume"),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        let build_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vdbcook light build"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                storage(1, false),
                storage(2, false),
            ],
        });
        let read_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vdbcook light read"),
            entries: &[storage(0, true)],
        });
        let density = volume.compute_pipeline(
            device,
            "vdbcook light density",
            &module,
            "lv_density_main",
            &[&build_layout],
        );
        let tau = volume.compute_pipeline(
            device,
            "vdbcook light tau",
            &module,
            "lv_tau_main",
            &[&build_layout],
        );
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vdbcook light params"),
            size: std::mem::size_of::<LightParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let empty = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vdbcook light volume (none)"),
            size: 8,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let empty_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vdbcook light volume (none)"),
            layout: &read_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: empty.as_entire_binding(),
            }],
        });
        LightPass {
            density,
            tau,
            build_layout,
            read_layout,
            params,
            empty_group,
            state: Mutex::new((None, None)),
        }
    }

    /// Forgets the cached light volume (the volume behind it changed).
    pub fn invalidate(&self) {
        self.state.lock().expect("light state").1 = None;
    }

    /// Records the pass for `lp` unless the last one recorded was for the same uniform, and
    /// returns the bind group the trace reads it through.
    pub fn record(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        volume_group: &wgpu::BindGroup,
        lp: LightParams,
    ) -> wgpu::BindGroup {
        let mut state = self.state.lock().expect("light state");
        let cells = lp.dims[..3].iter().map(|&d| d as usize).product::<usize>();
        if state.0.as_ref().is_none_or(|b| b.cells < cells) {
            let buffer = |label: &str, bytes: usize| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: bytes as u64,
                    usage: wgpu::BufferUsages::STORAGE,
                    mapped_at_creation: false,
                })
            };
            let density = buffer("vdbcook light density", 4 * cells);
            let tau = buffer("vdbcook light volume", 8 * cells);
            let build_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vdbcook light build"),
                layout: &self.build_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.params.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: density.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: tau.as_entire_binding(),
                    },
                ],
            });
            let read_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vdbcook light read"),
                layout: &self.read_layout,
                entries: &[wgpu::BindGroupEntry {
                    binding: 0,
                    resource: tau.as_entire_binding(),
                }],
            });
            *state = (
                Some(Buffers {
                    cells,
                    build_group,
                    read_group,
                }),
                None,
            );
        }
        let (Some(buffers), last) = &mut *state else {
            unreachable!("buffers were just made")
        };
        if *last != Some(lp) {
            queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&lp));
            let groups = lp.dims.map(|d| d.div_ceil(WORKGROUP));
            for (label, pipeline) in [
                ("vdbcook light density", &self.density),
                ("vdbcook light tau", &self.tau),
            ] {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(label),
                    timestamp_writes: None,
                });
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, volume_group, &[]);
                pass.set_bind_group(1, &buffers.build_group, &[]);
                pass.dispatch_workgroups(groups[0], groups[1], groups[2]);
            }
            *last = Some(lp);
        }
        buffers.read_group.clone()
    }
}
