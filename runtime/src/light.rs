//! The lit mode's light volumes on the GPU (`shaders/light_build.wgsl`): its six pipelines, one
//! buffer that holds every light volume a draw needs (grown on demand up to the device's binding
//! limit, never shrunk), the density scratch they are built through (one at a time), and the
//! cache that skips the passes while the frames, the lights and the media stay the same (one
//! entry: the last list built). The renderer and the drawer record the passes into the caller's
//! encoder ahead of their own dispatch and read the volumes through one bind group (the
//! renderer's group 3, `lv_tau`; the drawer's group 2, `draw_lv`).

use std::sync::Mutex;

use bytemuck::{Pod, Zeroable};
use vdbcook_scene::{light_dirs, Affine, LengthUnit, LightGrid};
use wgpu::util::DeviceExt;

use crate::upload::{buffer_entry, GpuVolume};
use crate::RuntimeError;

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
    /// Root offset of the frame at the density pass's level of detail.
    pub frame_root: u32,
    /// Element of cell 0 in the shared buffer (set by [`LightPass::record`]).
    pub base: u32,
    /// The density pass's level of detail (`LightGrid::density_level`): full-resolution
    /// indices shift right by it.
    pub level: u32,
    pub _pad2: u32,
}

impl LightParams {
    /// The pass's uniform for `grid` (`vdbcook_scene::light_dirs` in f64, then f32):
    /// the cell space of `xf`, the world direction `light_dir` toward the light, `extinction`
    /// per unit density per length `unit`.
    pub fn new(
        grid: &LightGrid,
        xf: &Affine,
        light_dir: [f32; 3],
        extinction: f64,
        unit: LengthUnit,
        frame_root: u32,
        (levels, level_stride): (usize, usize),
    ) -> LightParams {
        let ((l, sun_len), axis) = light_dirs(xf, light_dir, unit);
        let (level, sub) = grid.density_level(levels);
        LightParams {
            lo: [grid.lo[0], grid.lo[1], grid.lo[2], grid.cell].map(|v| v as f32),
            dims: [grid.dims[0], grid.dims[1], grid.dims[2], sub],
            sun: [l[0], l[1], l[2], sun_len].map(|v| v as f32),
            axis_len: [axis[0], axis[1], axis[2], extinction].map(|v| v as f32),
            frame_root: frame_root + level * level_stride as u32,
            base: 0,
            level,
            _pad2: 0,
        }
    }

    fn cells(&self) -> usize {
        self.dims[..3].iter().map(|&d| d as usize).product()
    }
}

/// What was built last: the buffers and the uniforms of the volumes in them.
#[derive(Default)]
struct State {
    /// The shared buffer (`vec2<f32>` per cell), its capacity in cells, its read bind group.
    pool: Option<(wgpu::Buffer, usize, wgpu::BindGroup)>,
    /// The density scratch and its capacity in cells.
    scratch: Option<(wgpu::Buffer, usize)>,
    /// The light volumes the pool holds (`None`: invalidated).
    built: Option<Vec<LightParams>>,
}

/// The light-volume passes of one renderer or drawer.
pub(crate) struct LightPass {
    /// `light_build.wgsl`'s passes in their order: density, sun, the three axes, sky.
    passes: [wgpu::ComputePipeline; 6],
    build_layout: wgpu::BindGroupLayout,
    pub read_layout: wgpu::BindGroupLayout,
    /// Bound at group 3 by draws that read no light volume.
    pub empty_group: wgpu::BindGroup,
    state: Mutex<State>,
}

const WORKGROUP: u32 = 4;

fn storage(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    buffer_entry(binding, wgpu::BufferBindingType::Storage { read_only })
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
                buffer_entry(0, wgpu::BufferBindingType::Uniform),
                storage(1, false),
                storage(2, false),
            ],
        });
        let read_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vdbcook light read"),
            entries: &[storage(0, true)],
        });
        let pipeline =
            |label, entry| volume.compute_pipeline(device, label, &module, entry, &[&build_layout]);
        let passes = [
            "lv_density_main",
            "lv_sun_main",
            "lv_axis0_main",
            "lv_axis1_main",
            "lv_axis2_main",
            "lv_sky_main",
        ]
        .map(|entry| pipeline("vdbcook light volume", entry));
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
            passes,
            build_layout,
            read_layout,
            empty_group,
            state: Mutex::new(State::default()),
        }
    }

    /// Forgets the cached light volumes (the volume behind them changed, or a recording was
    /// dropped unsubmitted).
    pub fn invalidate(&self) {
        self.state.lock().expect("light state").built = None;
    }

    /// Records the passes that build `volumes` one after the other into one buffer, unless the
    /// last call built the same ones (and its recording was submitted), and returns the bind
    /// group that reads them, each one's base element, and the buffer.
    pub fn record(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        volume_group: &wgpu::BindGroup,
        volumes: &[LightParams],
    ) -> Result<(wgpu::BindGroup, Vec<u32>, wgpu::Buffer), RuntimeError> {
        let mut placed = volumes.to_vec();
        let mut total = 0usize;
        for lp in &mut placed {
            lp.base = total as u32;
            total += lp.cells();
        }
        let limits = device.limits();
        let most = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size.min(u32::MAX as u64)) as usize;
        if 8 * total > most {
            return Err(RuntimeError::Limits(format!(
                "{} light volumes of {total} cells in all need {} bytes, the device binds at most \
                 {most} (lower light_res, or draw fewer distinct lit instances at once)",
                placed.len(),
                8 * total
            )));
        }
        let bases = placed.iter().map(|lp| lp.base).collect();
        let largest = placed.iter().map(|lp| lp.cells()).max().unwrap_or(1);
        let mut state = self.state.lock().expect("light state");
        let buffer = |label: &str, bytes: usize| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(8) as u64,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        if state.pool.as_ref().is_none_or(|p| p.1 < total) {
            let pool = buffer("vdbcook light volumes", 8 * total);
            let read = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vdbcook light read"),
                layout: &self.read_layout,
                entries: &[wgpu::BindGroupEntry {
                    binding: 0,
                    resource: pool.as_entire_binding(),
                }],
            });
            state.pool = Some((pool, total, read));
            state.built = None;
        }
        if state.scratch.as_ref().is_none_or(|s| s.1 < largest) {
            state.scratch = Some((buffer("vdbcook light density", 4 * largest), largest));
        }
        let (pool, _, read) = state.pool.as_ref().expect("just made");
        let (scratch, _) = state.scratch.as_ref().expect("just made");
        if state.built.as_ref() != Some(&placed) {
            for lp in &placed {
                let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("vdbcook light params"),
                    contents: bytemuck::bytes_of(lp),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
                let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("vdbcook light build"),
                    layout: &self.build_layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: uniform.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: scratch.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: pool.as_entire_binding(),
                        },
                    ],
                });
                // Per cell (4³ groups) or per column of an axis (8² groups over the other two).
                let [x, y, z, _] = lp.dims;
                let cells = [x, y, z].map(|d| d.div_ceil(WORKGROUP));
                let columns = |u: u32, v: u32| [u.div_ceil(8), v.div_ceil(8), 1];
                let sizes = [
                    cells,
                    cells,
                    columns(y, z),
                    columns(z, x),
                    columns(x, y),
                    cells,
                ];
                for (pipeline, size) in self.passes.iter().zip(sizes) {
                    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("vdbcook light volume"),
                        timestamp_writes: None,
                    });
                    pass.set_pipeline(pipeline);
                    pass.set_bind_group(0, volume_group, &[]);
                    pass.set_bind_group(1, &group, &[]);
                    pass.dispatch_workgroups(size[0], size[1], size[2]);
                }
            }
        }
        let (read, pool) = (read.clone(), pool.clone());
        state.built = Some(placed);
        Ok((read, bases, pool))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout_check::{assert_mirrors, rust_layout};

    #[test]
    fn light_params_mirror_the_wgsl() {
        assert_mirrors(
            &format!(
                "{}\n{}\n{}",
                crate::VOLUME_WGSL,
                crate::LIGHT_WGSL,
                crate::LIGHT_BUILD_WGSL
            ),
            "LightParams",
            rust_layout!(LightParams {
                lo,
                dims,
                sun,
                axis_len,
                frame_root,
                base,
                level,
                _pad2,
            }),
        );
    }
}
