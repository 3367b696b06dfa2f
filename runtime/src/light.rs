//! The lit mode's light volumes on the GPU (`shaders/light_build.wgsl`): its six pipelines, the
//! builds (each a buffer holding every light volume one draw needs, up to the device's binding
//! limit), the density scratch they are built through (one at a time), and the builds kept for
//! reuse while the frames, the lights and the media stay the same. A build is recorded into an
//! encoder of its own and submitted at once, in `prepare`: a caller's encoder holds only draws,
//! so dropping one never leaves light volumes unbuilt. The renderer and the drawer read a build
//! through one bind group (`lit.wgsl`'s `lit_tau`, `lit_ms`: the renderer's group 3, the
//! drawer's group 2); the draws holding it keep it from being overwritten.
//!
//! A volume built for `MsModel::Diffusion` also gathers the sun's light scattered once and
//! twice (`Lighting::ms_gather` orders) and runs the diffusion solve on the rest (`ms_*` passes,
//! eight more pipelines over a scratch of every level, one `MsParams` record per level and sweep
//! parity bound with a dynamic offset) and stores six 32-bit words per cell in a second buffer
//! (cell `i` of the volume at base `b` at words `6(b + i)..`): `ρ·φ_sun/4π`, `ρ·φ_sky/4π` and
//! `ρ` as f32, then each field's flux per axis as `J/φ` in 16 bits (`ms_store_main`,
//! `vdbcook_scene::ms_stored_flux`; binding 1 of the read group; `lv_diffuse_*` in `light.wgsl`
//! reads it). 24 bytes a cell: 6 MiB at `light_res` 64 on a cubic box (48 until 2026-11-26).

use std::sync::{Arc, Mutex};

use bytemuck::{Pod, Zeroable};
use vdbcook_scene::{
    light_dirs, ms_levels, ms_sweeps, Affine, DiffusionInputs, LengthUnit, LevelChain, LightGrid,
    MS_GATHER_WEIGHTS,
};
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
    /// Element of cell 0 in the shared buffer (set by [`LightPass::prepare`]).
    pub base: u32,
    /// The density pass's level of detail (`LightGrid::density_level`'s shift): full-resolution
    /// indices shift right by it.
    pub level: u32,
    /// The asset of the volume set whose density it reads.
    pub asset: u32,
}

/// The frame a light volume reads: its asset in the volume set, its root offset at full
/// resolution and the asset's levels of detail with their root-offset stride
/// (`AssetMeta::lod`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct FrameAt {
    pub asset: u32,
    pub frame_root: u32,
    pub lod: (LevelChain, usize),
}

impl LightParams {
    /// The pass's uniform for `grid` (`vdbcook_scene::light_dirs` in f64, then f32):
    /// the cell space of `xf`, the world direction `light_dir` toward the light, `extinction`
    /// per unit density per length `unit`, over the frame `at` names.
    pub fn new(
        grid: &LightGrid,
        xf: &Affine,
        light_dir: [f32; 3],
        extinction: f64,
        unit: LengthUnit,
        at: FrameAt,
    ) -> LightParams {
        let FrameAt {
            asset,
            frame_root,
            lod: (levels, level_stride),
        } = at;
        let ((l, sun_len), axis) = light_dirs(xf, light_dir, unit);
        let (level, shift, sub) = grid.density_level(levels);
        LightParams {
            lo: [grid.lo[0], grid.lo[1], grid.lo[2], grid.cell].map(|v| v as f32),
            dims: [grid.dims[0], grid.dims[1], grid.dims[2], sub],
            sun: [l[0], l[1], l[2], sun_len].map(|v| v as f32),
            axis_len: [axis[0], axis[1], axis[2], extinction].map(|v| v as f32),
            frame_root: frame_root + (level * level_stride) as u32,
            base: 0,
            level: shift,
            asset,
        }
    }

    fn cells(&self) -> usize {
        self.dims[..3].iter().map(|&d| d as usize).product()
    }

    /// The same light volume wherever it is placed (all but `base`).
    fn same_volume(&self, other: &LightParams) -> bool {
        LightParams { base: 0, ..*self } == LightParams { base: 0, ..*other }
    }
}

/// How many light volumes a renderer's or a drawer's `prepare` calls have built and how many
/// they took from earlier builds (a kept build of the same list, or a copy of one volume).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LightBuilds {
    /// Volumes built by the light passes (and the diffusion solve).
    pub built: u64,
    /// Volumes read from an earlier build: whole lists kept, or single volumes copied.
    pub reused: u64,
}

/// `MsParams` of `light_build.wgsl`: one level of the diffusion solve and one sweep parity.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, PartialEq)]
pub(crate) struct MsParams {
    /// xyz: the level's cells per axis; w: the sweep's parity (0: φ A → B).
    pub dims: [u32; 4],
    /// x: the level's first element in the scratch; y: its finer child's; z: its parent's;
    /// w: 1 when it has a parent.
    pub off: [u32; 4],
    /// xyz: the child's cells per axis; w: how many levels the solve has.
    pub child: [u32; 4],
    /// xyz: the parent's cells per axis; w: the orders gathered before the solve.
    pub parent: [u32; 4],
    /// xyz: the cell edge per axis (length unit); w: the albedo.
    pub h: [f32; 4],
    /// x: the phase's mean cosine; y: the sun's chord per cell slab; z: the extinction.
    pub medium: [f32; 4],
    /// The gather's 26 direction weights (`DiffusionInputs::gather`), four per element, the
    /// last two 0.
    pub gather: [[f32; 4]; 7],
    /// xyz: the phase (g0, g1, the first lobe's weight).
    pub phase: [f32; 4],
    /// xyz: `vdbcook_scene::MS_GATHER_WEIGHTS` (a direction's share of the sphere).
    pub share: [f32; 4],
    /// Every level (`child.w` of them): xyz its cells per axis, w its first element in the
    /// scratch (the gather reads them all).
    pub levels: [[u32; 4]; 8],
}

/// The bytes between two diffusion records in the uniform buffer: the record's size rounded up to
/// a multiple of the device's dynamic-offset alignment (a power of two; 64 on NVIDIA, so a
/// 368-byte record takes 384 — every offset must be a multiple of the alignment).
fn ms_record_stride(min_uniform_offset_alignment: u32) -> usize {
    (MS_PARAMS_SIZE as usize).next_multiple_of(min_uniform_offset_alignment.max(1) as usize)
}

/// The records of one volume's solve, `[level][parity]`, and the scratch it needs (f32s).
fn ms_records(dims: [u32; 3], m: &DiffusionInputs) -> (Vec<[MsParams; 2]>, usize) {
    let levels = ms_levels(dims);
    let cells = |d: [u32; 3]| d.iter().map(|&v| v as usize).product::<usize>();
    let mut offs = Vec::with_capacity(levels.len());
    let mut total = 0usize;
    for &d in &levels {
        offs.push(total as u32);
        total += MS_FLOATS_PER_CELL * cells(d);
    }
    let orders = m.gathered_orders();
    // `MsParams::levels` holds eight: `MAX_LIGHT_RES` (256) makes seven.
    assert!(levels.len() <= 8, "{} diffusion levels", levels.len());
    let records = (0..levels.len())
        .map(|k| {
            let d = levels[k];
            let child = k.checked_sub(1).map_or([0; 3], |c| levels[c]);
            let parent = levels.get(k + 1).copied();
            let scale = f64::from(1u32 << k);
            [0u32, 1].map(|parity| MsParams {
                dims: [d[0], d[1], d[2], parity],
                off: [
                    offs[k],
                    k.checked_sub(1).map_or(0, |c| offs[c]),
                    offs.get(k + 1).copied().unwrap_or(0),
                    parent.is_some() as u32,
                ],
                child: [child[0], child[1], child[2], levels.len() as u32],
                parent: parent.map_or([0, 0, 0, orders], |p| [p[0], p[1], p[2], orders]),
                h: [m.h[0] * scale, m.h[1] * scale, m.h[2] * scale, m.albedo].map(|v| v as f32),
                medium: [m.mean_cos(), m.chord, m.extinction, 0.0].map(|v| v as f32),
                phase: [m.phase.0[0], m.phase.0[1], m.phase.1, 0.0],
                share: [
                    MS_GATHER_WEIGHTS[0] as f32,
                    MS_GATHER_WEIGHTS[1] as f32,
                    MS_GATHER_WEIGHTS[2] as f32,
                    0.0,
                ],
                levels: std::array::from_fn(|k| {
                    levels
                        .get(k)
                        .map_or([0; 4], |d| [d[0], d[1], d[2], offs[k]])
                }),
                gather: std::array::from_fn(|k| {
                    std::array::from_fn(|c| m.gather.get(4 * k + c).map_or(0.0, |&w| w as f32))
                }),
            })
        })
        .collect();
    (records, total)
}

/// f32s of the diffusion solve's scratch per cell of a level (`light_build.wgsl`: st, sr, q,
/// two fields in φ A and φ B, six resistances; before the solve the gather's beams and second
/// order use the last two's place, and the gathered light waits in the output's words).
const MS_FLOATS_PER_CELL: usize = 13;
/// Bytes of the diffusion model's output per cell (six words: three f32, six 16-bit fluxes).
const MS_OUT_BYTES: usize = 24;

/// The light volumes of one build: where they lie and the bind group that reads them. The draws
/// that read a build hold it (an `Arc`), so a build no draw holds is the one a new build may
/// overwrite: draws prepared for one submission each keep their own light, whatever was built
/// after them.
pub(crate) struct LightEntry {
    /// The volumes (placed) and the diffusion inputs of those that solve it.
    key: (Vec<LightParams>, Vec<Option<DiffusionInputs>>),
    /// `(τ_sun, τ_sky)` per cell, and the diffusion model's six words per cell.
    pub pool: wgpu::Buffer,
    ms_pool: wgpu::Buffer,
    /// Capacities in cells.
    cells: usize,
    ms_cells: usize,
    pub read: wgpu::BindGroup,
    /// Each volume's base element.
    pub bases: Vec<u32>,
}

/// Builds kept for reuse: a repeated list of light volumes (the same frames, lights and media)
/// is read from its build instead of rebuilt.
const KEPT_BUILDS: usize = 8;

/// The builds and the scratch they are made through.
#[derive(Default)]
struct State {
    /// Most recently used last.
    builds: Vec<Arc<LightEntry>>,
    /// The density scratch and its capacity in cells.
    scratch: Option<(wgpu::Buffer, usize)>,
    /// The diffusion solve's scratch (every level of one volume) and its capacity in f32s.
    ms_scratch: Option<(wgpu::Buffer, usize)>,
    counts: LightBuilds,
}

/// The light-volume passes of one renderer or drawer.
pub(crate) struct LightPass {
    /// `light_build.wgsl`'s passes in their order: density, sun, the three axes, sky.
    passes: [wgpu::ComputePipeline; 6],
    /// The diffusion solve's: source, gather, second, restrict, prolong, limit, update, store.
    ms_passes: [wgpu::ComputePipeline; 8],
    build_layout: wgpu::BindGroupLayout,
    ms_layout: wgpu::BindGroupLayout,
    pub read_layout: wgpu::BindGroupLayout,
    /// Bound at the light group (the renderer's 3, the drawer's 2) by draws that read no light
    /// volume.
    pub empty_group: wgpu::BindGroup,
    state: Mutex<State>,
}

const WORKGROUP: u32 = 4;
/// Bytes of one [`MsParams`].
const MS_PARAMS_SIZE: u64 = std::mem::size_of::<MsParams>() as u64;

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
        let ms_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vdbcook light diffusion"),
            entries: &[
                storage(0, false),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: true,
                        min_binding_size: wgpu::BufferSize::new(MS_PARAMS_SIZE),
                    },
                    count: None,
                },
                storage(2, false),
            ],
        });
        let read_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("vdbcook light read"),
            entries: &[storage(0, true), storage(1, true)],
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
        let constants = volume.pipeline_constants();
        let ms_passes = [
            "ms_source_main",
            "ms_gather_main",
            "ms_second_main",
            "ms_restrict_main",
            "ms_prolong_main",
            "ms_limit_main",
            "ms_update_main",
            "ms_store_main",
        ]
        .map(|entry| {
            // Group 0 (the volume) left out: the solve reads no voxel, and the volume's
            // storage buffers with the solve's four would exceed WebGPU's 8 per stage.
            let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("vdbcook light diffusion"),
                bind_group_layouts: &[None, Some(&build_layout), Some(&ms_layout)],
                immediate_size: 0,
            });
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("vdbcook light diffusion"),
                layout: Some(&layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    ..Default::default()
                },
                cache: None,
            })
        });
        let empty = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vdbcook light volume (none)"),
            size: MS_OUT_BYTES as u64,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let empty_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vdbcook light volume (none)"),
            layout: &read_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: empty.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: empty.as_entire_binding(),
                },
            ],
        });
        LightPass {
            passes,
            ms_passes,
            build_layout,
            ms_layout,
            read_layout,
            empty_group,
            state: Mutex::new(State::default()),
        }
    }

    /// Volumes built and reused so far.
    pub fn counts(&self) -> LightBuilds {
        self.state.lock().expect("light state").counts
    }

    /// Forgets the kept builds (the volume behind them changed).
    pub fn invalidate(&self) {
        self.state.lock().expect("light state").builds.clear();
    }

    /// The light volumes `volumes`, built one after the other into one buffer and submitted
    /// at once on `queue` (so a caller's dropped encoder never leaves them unbuilt), unless a
    /// kept build holds the same ones. `diffusion[i]`: the inputs of volume `i`'s diffusion
    /// solve (`MsModel::Diffusion`), if it runs one (a shorter slice: the rest run none). Hold
    /// the returned build while a draw that reads it is pending.
    pub fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        volume_group: &wgpu::BindGroup,
        volumes: &[LightParams],
        diffusion: &[Option<DiffusionInputs>],
    ) -> Result<Arc<LightEntry>, RuntimeError> {
        let diffusion: Vec<Option<DiffusionInputs>> = (0..volumes.len())
            .map(|i| diffusion.get(i).copied().flatten())
            .collect();
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
        // The diffusion output, when any volume solves it, is the largest binding.
        let per_cell = if diffusion.iter().any(Option::is_some) {
            MS_OUT_BYTES
        } else {
            8
        };
        if per_cell * total > most {
            return Err(RuntimeError::Limits(format!(
                "{} light volumes of {total} cells in all need {} bytes, the device binds at most \
                 {most} (lower light_res, or draw fewer distinct lit instances at once)",
                placed.len(),
                per_cell * total
            )));
        }
        let key = (placed, diffusion);
        let mut state = self.state.lock().expect("light state");
        if let Some(i) = state.builds.iter().position(|b| b.key == key) {
            let b = state.builds.remove(i);
            state.builds.push(b.clone());
            state.counts.reused += key.0.len() as u64;
            return Ok(b);
        }
        let (placed, diffusion) = &key;
        // A volume a kept build already holds (the same frame, light, medium and grid) is copied
        // from it instead of built: a crossfade whose pair moves on by one frame builds one
        // volume, not two. The clones held here keep the sources from being picked as the
        // destination below (a build no one else holds).
        let sources: Vec<Option<(Arc<LightEntry>, u32)>> = placed
            .iter()
            .zip(diffusion)
            .map(|(lp, m)| {
                state.builds.iter().rev().find_map(|b| {
                    let (vols, solves) = &b.key;
                    vols.iter()
                        .zip(solves)
                        .find(|(v, d)| v.same_volume(lp) && *d == m)
                        .map(|(v, _)| (b.clone(), v.base))
                })
            })
            .collect();
        let buffer = |label: &str, bytes: usize| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(8) as u64,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        // Cells the diffusion output must hold: all of them when any volume solves it.
        let ms_total = if per_cell == MS_OUT_BYTES { total } else { 0 };
        // The diffusion solves' records, all built volumes', each `align`-aligned (checked
        // before a kept build is taken over, so that an error loses none).
        let solves: Vec<Option<(Vec<[MsParams; 2]>, usize)>> = placed
            .iter()
            .zip(diffusion)
            .zip(&sources)
            .map(|((lp, m), src)| {
                m.filter(|_| src.is_none())
                    .map(|m| ms_records([lp.dims[0], lp.dims[1], lp.dims[2]], &m))
            })
            .collect();
        let ms_floats = solves.iter().flatten().map(|s| s.1).max().unwrap_or(0);
        if 4 * ms_floats > most {
            return Err(RuntimeError::Limits(format!(
                "the diffusion solve needs {} bytes of scratch, the device binds at most {most} \
                 (lower light_res, or use MsModel::Octaves)",
                4 * ms_floats
            )));
        }
        // Where to build: a kept build no draw holds (its buffers when large enough), else new.
        let free = state.builds.iter().position(|b| Arc::strong_count(b) == 1);
        let old = free.map(|i| state.builds.remove(i));
        let (pool, ms_pool, cells, ms_cells) = match old {
            Some(b) if b.cells >= total && b.ms_cells >= ms_total => {
                (b.pool.clone(), b.ms_pool.clone(), b.cells, b.ms_cells)
            }
            _ => (
                buffer("vdbcook light volumes", 8 * total),
                buffer(
                    "vdbcook light diffusion",
                    (MS_OUT_BYTES * ms_total).max(MS_OUT_BYTES),
                ),
                total,
                ms_total,
            ),
        };
        let read = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vdbcook light read"),
            layout: &self.read_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: pool.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: ms_pool.as_entire_binding(),
                },
            ],
        });
        let largest = placed.iter().map(|lp| lp.cells()).max().unwrap_or(1);
        if state.scratch.as_ref().is_none_or(|s| s.1 < largest) {
            state.scratch = Some((buffer("vdbcook light density", 4 * largest), largest));
        }
        if ms_floats > 0 && state.ms_scratch.as_ref().is_none_or(|s| s.1 < ms_floats) {
            state.ms_scratch = Some((
                buffer("vdbcook light diffusion scratch", 4 * ms_floats),
                ms_floats,
            ));
        }
        let (scratch, _) = state.scratch.as_ref().expect("just made");
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("vdbcook light volumes"),
        });
        let align = ms_record_stride(limits.min_uniform_buffer_offset_alignment);
        let mut bytes: Vec<u8> = Vec::new();
        for (records, _) in solves.iter().flatten() {
            for r in records.iter().flatten() {
                bytes.extend_from_slice(bytemuck::bytes_of(r));
                bytes.resize(bytes.len().next_multiple_of(align), 0);
            }
        }
        let ms_group = (!bytes.is_empty()).then(|| {
            let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("vdbcook light diffusion params"),
                contents: &bytes,
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let (ms_scratch, _) = state.ms_scratch.as_ref().expect("made above");
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("vdbcook light diffusion"),
                layout: &self.ms_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: ms_scratch.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &uniform,
                            offset: 0,
                            size: wgpu::BufferSize::new(MS_PARAMS_SIZE),
                        }),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: ms_pool.as_entire_binding(),
                    },
                ],
            })
        });
        let mut next_record = 0usize;
        for ((lp, solve), (src, m)) in placed
            .iter()
            .zip(&solves)
            .zip(sources.iter().zip(diffusion))
        {
            if let Some((from, at)) = src {
                let n = lp.cells() as u64;
                let (at, to) = (u64::from(*at), u64::from(lp.base));
                encoder.copy_buffer_to_buffer(&from.pool, 8 * at, &pool, 8 * to, 8 * n);
                if m.is_some() {
                    let w = MS_OUT_BYTES as u64;
                    encoder.copy_buffer_to_buffer(&from.ms_pool, w * at, &ms_pool, w * to, w * n);
                }
                continue;
            }
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
            if let (Some((records, _)), Some(ms_group)) = (solve, &ms_group) {
                let first = next_record;
                next_record += 2 * records.len();
                // The dynamic offset of level `k`'s record of `parity`.
                let at = |k: usize, parity: usize| ((first + 2 * k + parity) * align) as u32;
                let groups = |k: usize| {
                    let d = records[k][0].dims;
                    [d[0], d[1], d[2]].map(|v| v.div_ceil(WORKGROUP))
                };
                let [source, gather, second, restrict, prolong, limit, update, store] =
                    &self.ms_passes;
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("vdbcook light diffusion"),
                    timestamp_writes: None,
                });
                pass.set_bind_group(1, &group, &[]);
                let mut run = |pipeline: &wgpu::ComputePipeline, k: usize, parity: usize| {
                    pass.set_pipeline(pipeline);
                    pass.set_bind_group(2, ms_group, &[at(k, parity)]);
                    let [x, y, z] = groups(k);
                    pass.dispatch_workgroups(x, y, z);
                };
                run(source, 0, 0);
                for k in 1..records.len() {
                    run(restrict, k, 0);
                }
                // The light scattered once, then twice (the record's parity), as many orders
                // as the inputs ask.
                for order in 0..records[0][0].parent[3] as usize {
                    run(gather, 0, order);
                    run(second, 0, order);
                    for k in 1..records.len() {
                        run(restrict, k, 0);
                    }
                }
                for k in (0..records.len()).rev() {
                    run(prolong, k, 0);
                    for sweep in 0..ms_sweeps(k) {
                        run(limit, k, sweep % 2);
                        run(update, k, sweep % 2);
                    }
                }
                // The resistances of the result (in φ A), for the flux.
                run(limit, 0, 0);
                run(store, 0, 0);
            }
        }
        queue.submit([encoder.finish()]);
        let copied = sources.iter().flatten().count() as u64;
        drop(sources);
        state.counts.reused += copied;
        state.counts.built += placed.len() as u64 - copied;
        let bases = placed.iter().map(|lp| lp.base).collect();
        let entry = Arc::new(LightEntry {
            key: key.clone(),
            pool,
            ms_pool,
            cells,
            ms_cells,
            read,
            bases,
        });
        state.builds.push(entry.clone());
        // Kept builds beyond the limit that no draw holds go, oldest first.
        while state.builds.len() > KEPT_BUILDS {
            match state.builds.iter().position(|b| Arc::strong_count(b) == 1) {
                Some(i) => {
                    state.builds.remove(i);
                }
                None => break,
            }
        }
        Ok(entry)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout_check::{assert_mirrors, rust_layout};

    /// Found on an H100 (alignment 64): a stride of max(alignment, record) = 96 put records at
    /// offsets wgpu refuses; lavapipe's smaller alignment hid it. Every alignment a conformant
    /// device may report (powers of two, 1..=256) gives offsets that respect it.
    #[test]
    fn diffusion_records_respect_every_dynamic_offset_alignment() {
        for shift in 0..=8 {
            let alignment = 1u32 << shift;
            let stride = ms_record_stride(alignment);
            assert!(stride >= MS_PARAMS_SIZE as usize, "{alignment}: {stride}");
            assert!(stride < MS_PARAMS_SIZE as usize + alignment as usize);
            for k in 0..20 {
                assert_eq!(
                    (k * stride) % alignment as usize,
                    0,
                    "{alignment}: record {k}"
                );
            }
        }
    }

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
                asset,
            }),
        );
        assert_mirrors(
            &format!(
                "{}\n{}\n{}",
                crate::VOLUME_WGSL,
                crate::LIGHT_WGSL,
                crate::LIGHT_BUILD_WGSL
            ),
            "MsParams",
            rust_layout!(MsParams {
                dims,
                off,
                child,
                parent,
                h,
                medium,
                gather,
                phase,
                share,
                levels,
            }),
        );
    }
}
