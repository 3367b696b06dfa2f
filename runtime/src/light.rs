//! The lit mode's light volumes on the GPU (`shaders/light_build.wgsl`): its six pipelines, the
//! builds (each a buffer holding every light volume one draw needs, up to the device's binding
//! limit), the density scratch they are built through (one at a time), and the builds kept for
//! reuse while the frames, the lights and the media stay the same. A build is recorded into an
//! encoder of its own and submitted at once, in `prepare`: a caller's encoder holds only draws,
//! so dropping one never leaves light volumes unbuilt. The renderer and the drawer read a build
//! through one bind group (`lit.wgsl`'s `lit_tau`, `lit_ms`: the renderer's group 3, the
//! drawer's group 2); the draws holding it keep it from being overwritten. Volumes may also be
//! built ahead of need, one at a time, a share of a build's dispatches per call
//! (`LightPass::ahead`, the drawer's `set_light_ahead`): the same dispatches (`Recording`), a
//! scratch of their own.
//!
//! A volume built for `MsModel::Diffusion` also gathers the sun's light scattered once and
//! twice (`Lighting::ms_gather` orders) and runs the diffusion solve on the rest (`ms_*` passes,
//! eight more pipelines over a scratch of every level, one `MsParams` record per level and sweep
//! parity bound with a dynamic offset) and stores six 32-bit words per cell in a second buffer
//! (cell `i` of the volume at base `b` at words `6(b + i)..`): `ρ·φ_sun/4π`, `ρ·φ_sky/4π` and
//! `ρ` as f32, then each field's flux per axis as `J/φ` in 16 bits (`ms_store_main`,
//! `vdbcook_scene::ms_stored_flux`; binding 1 of the read group; `lv_diffuse_*` in `light.wgsl`
//! reads it). 24 bytes a cell: 6 MiB at `light_res` 64 on a cubic box (48 until 2026-11-26).

use std::ops::Range;
use std::sync::{Arc, Mutex};

use bytemuck::{Pod, Zeroable};
use vdbcook_scene::{
    light_dirs, ms_levels, ms_sweeps, sun_pass_stop, Affine, DiffusionInputs, LengthUnit,
    LevelChain, LightGrid, MsModel, MS_GATHER_WEIGHTS, MS_SHARED_PATHS,
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
    /// x: the extinction at which the sun pass stops a cell's walk at the opaque depth, 0 for
    /// none (`vdbcook_scene::sun_pass_stop`); y: 1 where the volume solves the diffusion model
    /// (the sun pass then keeps each cell's entry depth for the solve's source, third in the
    /// density scratch), else 0; zw: 0.
    pub stop: [f32; 4],
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
    /// per unit density per length `unit`, the multiple-scattering model `ms_model`, over the
    /// frame `at` names.
    pub fn new(
        grid: &LightGrid,
        xf: &Affine,
        (light_dir, ms_model): ([f32; 3], MsModel),
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
            stop: [
                sun_pass_stop(ms_model, extinction) as f32,
                f32::from(u8::from(ms_model == MsModel::Diffusion)),
                0.0,
                0.0,
            ],
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
#[non_exhaustive]
pub struct LightBuilds {
    /// Volumes built by the light passes (and the diffusion solve).
    pub built: u64,
    /// Volumes read from an earlier build: whole lists kept, or single volumes copied.
    pub reused: u64,
    /// Of `built`, those built ahead of need (`VolumeDrawer::set_light_ahead`).
    pub ahead: u64,
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
    /// x: this level's index.
    pub level: [u32; 4],
    /// Per level, four per element, the first element of its shared gather paths in the
    /// scratch (26 per cell, from `MS_SHARED_PATHS` up; 0 below).
    pub paths: [[u32; 4]; 2],
}

/// The bytes between two diffusion records in the uniform buffer: the record's size rounded up to
/// a multiple of the device's dynamic-offset alignment (a power of two; 64 on NVIDIA, so a
/// 416-byte record takes 448 — every offset must be a multiple of the alignment).
fn ms_record_stride(min_uniform_offset_alignment: u32) -> usize {
    (MS_PARAMS_SIZE as usize).next_multiple_of(min_uniform_offset_alignment.max(1) as usize)
}

/// The records of one volume's solve, `[level][parity]`, and the scratch it needs (f32s).
fn ms_records(dims: [u32; 3], m: &DiffusionInputs) -> (Vec<[MsParams; 2]>, usize) {
    let levels = ms_levels(dims);
    let cells = |d: [u32; 3]| d.iter().map(|&v| v as usize).product::<usize>();
    // `MsParams::levels` and `paths` hold eight: `MAX_LIGHT_RES` (256) makes seven.
    assert!(levels.len() <= 8, "{} diffusion levels", levels.len());
    let mut offs = Vec::with_capacity(levels.len());
    let mut total = 0usize;
    for &d in &levels {
        offs.push(total as u32);
        total += MS_FLOATS_PER_CELL * cells(d);
    }
    // Level 0 walks its own steps: its paths would overwrite the level's data.
    const { assert!(MS_SHARED_PATHS >= 1) };
    // The shared gather paths, 26 per cell of each level from `MS_SHARED_PATHS` (≥ 1) up: in
    // the φ A and φ B place of the level below, free until the solve, where they fit (4 per
    // cell of that level: every side of about 14 cells or more), else after the levels.
    let mut paths = [0u32; 8];
    for k in MS_SHARED_PATHS..levels.len() {
        let need = 26 * cells(levels[k]);
        let below = cells(levels[k - 1]);
        paths[k] = if need <= 4 * below {
            offs[k - 1] + 3 * below as u32
        } else {
            total += need;
            (total - need) as u32
        };
    }
    let orders = m.gathered_orders();
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
                level: [k as u32, 0, 0, 0],
                paths: [0, 1].map(|h| std::array::from_fn(|c| paths[4 * h + c])),
            })
        })
        .collect();
    (records, total)
}

/// f32s of the diffusion solve's scratch per cell of a level (`light_build.wgsl`: st, sr, q,
/// two fields in φ A and φ B, two resistances, the sun's open faces' six; before the solve the
/// gather's beams and second order's φ use the resistances' and open faces' place, the shared
/// paths of the next coarser level φ A's and φ B's where they fit, and the gathered light waits
/// in the output's words).
const MS_FLOATS_PER_CELL: usize = 15;
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

impl LightEntry {
    /// A build's entry over its two buffers (`pool`, `ms_pool`) of the given capacities in
    /// cells, with the bind group that reads them.
    fn new(
        lp: &LightPass,
        device: &wgpu::Device,
        key: (Vec<LightParams>, Vec<Option<DiffusionInputs>>),
        (pool, ms_pool): (wgpu::Buffer, wgpu::Buffer),
        (cells, ms_cells): (usize, usize),
    ) -> LightEntry {
        let read = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vdbcook light read"),
            layout: &lp.read_layout,
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
        let bases = key.0.iter().map(|lp| lp.base).collect();
        LightEntry {
            key,
            pool,
            ms_pool,
            cells,
            ms_cells,
            read,
            bases,
        }
    }

    /// Whether it holds the volume `lp` with the diffusion inputs `m` (wherever placed).
    fn holds(&self, lp: &LightParams, m: &Option<DiffusionInputs>) -> bool {
        self.base_of(lp, m).is_some()
    }

    /// Where it holds the volume `lp` with the diffusion inputs `m`: its base element.
    fn base_of(&self, lp: &LightParams, m: &Option<DiffusionInputs>) -> Option<u32> {
        let (vols, solves) = &self.key;
        vols.iter()
            .zip(solves)
            .find(|(v, d)| v.same_volume(lp) && *d == m)
            .map(|(v, _)| v.base)
    }
}

/// Builds kept for reuse: a repeated list of light volumes (the same frames, lights and media)
/// is read from its build instead of rebuilt.
const KEPT_BUILDS: usize = 8;

/// The two scratch buffers a build runs through, with their capacities: the density's (f32s:
/// two per cell, the cells' mean densities then their transport densities, `lv_density_main`,
/// and, where a volume solves the diffusion model, a third, the sun's depth where its beam
/// enters each cell, `lv_sun_main`: within the `MS_OUT_BYTES` a cell `Plan::new` checks)
/// and the diffusion solve's (every level of one volume, f32s).
#[derive(Default)]
struct Scratch {
    density: Option<(wgpu::Buffer, usize)>,
    ms: Option<(wgpu::Buffer, usize)>,
}

/// The builds and the scratch they are made through.
#[derive(Default)]
struct State {
    /// Most recently used last.
    builds: Vec<Arc<LightEntry>>,
    /// The scratch of the builds `prepare` records at once.
    scratch: Scratch,
    /// A build under way ahead of need, and the scratch of such builds (their own:
    /// the builds of `prepare` run between its shares).
    ahead: Option<Ahead>,
    ahead_scratch: Scratch,
    counts: LightBuilds,
}

/// The light-volume passes of one renderer or drawer.
pub(crate) struct LightPass {
    /// `light_build.wgsl`'s passes in their order: density, sun, the three axes, sky.
    passes: [wgpu::ComputePipeline; 6],
    /// The diffusion solve's: source, gather, second, restrict, prolong, limit, update, store,
    /// paths, vacuum.
    ms_passes: [wgpu::ComputePipeline; 10],
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
            "ms_paths_main",
            "ms_vacuum_main",
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

    /// Forgets the kept builds and any build under way ahead (the volume behind them changed).
    pub fn invalidate(&self) {
        let mut state = self.state.lock().expect("light state");
        state.builds.clear();
        state.ahead = None;
    }

    /// The light volumes `volumes`, built one after the other into one buffer and submitted
    /// at once on `queue` (so a caller's dropped encoder never leaves them unbuilt), unless a
    /// kept build holds the same ones. `diffusion[i]`: the inputs of volume `i`'s diffusion
    /// solve (`MsModel::Diffusion`), if it runs one (a shorter slice: the rest run none). Hold
    /// the returned build while a draw that reads it is pending. A build under way ahead
    /// ([`LightPass::ahead`]) that holds one of them is finished first, and its volumes copied.
    pub fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        volume_group: &wgpu::BindGroup,
        volumes: &[LightParams],
        diffusion: &[Option<DiffusionInputs>],
    ) -> Result<Arc<LightEntry>, RuntimeError> {
        let plan = Plan::new(device, volumes, diffusion)?;
        let mut state = self.state.lock().expect("light state");
        let wanted = plan.key.0.iter().zip(&plan.key.1);
        if let Some(a) = state
            .ahead
            .take_if(|a| wanted.clone().any(|(lp, m)| a.entry.holds(lp, m)))
        {
            let mut encoder = device.create_command_encoder(&Default::default());
            a.rec.record(self, &mut encoder, a.next..a.rec.steps.len());
            queue.submit([encoder.finish()]);
            self.keep(&mut state, a.entry, true);
        }
        let key = plan.key.clone();
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
                let mut kept = state.builds.iter().rev();
                kept.find_map(|b| b.base_of(lp, m).map(|at| (b.clone(), at)))
            })
            .collect();
        let built: Vec<bool> = sources.iter().map(Option::is_none).collect();
        let (mut rec, entry) = self.build(device, &mut state, volume_group, plan, &built, false)?;
        for ((lp, m), src) in placed.iter().zip(diffusion).zip(&sources) {
            if let Some((from, at)) = src {
                let n = lp.cells() as u64;
                let (at, to) = (u64::from(*at), u64::from(lp.base));
                rec.copies
                    .push((from.pool.clone(), 8 * at, entry.pool.clone(), 8 * to, 8 * n));
                if m.is_some() {
                    let w = MS_OUT_BYTES as u64;
                    let (src, dst) = (from.ms_pool.clone(), entry.ms_pool.clone());
                    rec.copies.push((src, w * at, dst, w * to, w * n));
                }
            }
        }
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("vdbcook light volumes"),
        });
        rec.record(self, &mut encoder, 0..rec.steps.len());
        queue.submit([encoder.finish()]);
        let copied = sources.iter().flatten().count() as u64;
        drop(sources);
        state.counts.reused += copied;
        state.counts.built += placed.len() as u64 - copied;
        Ok(self.keep(&mut state, entry, false))
    }

    /// Builds `volumes` ahead of the draws that will need them, one volume after the other and a
    /// share of the work a call, so that the light volume of a flip-book frame about to be shown
    /// is built over the displayed frames before it rather than inside the one that reaches it.
    /// A call records whole dispatches worth about `queued / spread` of one volume's build by
    /// their estimated costs (`VOLUME_COST`, `MS_COST`: the gathers are the largest), `queued`
    /// being the volumes not built yet (the one under way included), with what earlier calls
    /// recorded over or under their budgets for the volume under way carried over: `spread`
    /// calls build them all. Volumes a kept build holds are not built again. A completed volume
    /// joins the kept builds, where [`LightPass::prepare`] copies it from; a `prepare` that
    /// needs the volume under way finishes it at once, and builds those not begun itself. The
    /// volume under way is finished even when no longer asked for (one volume at most is built
    /// in vain). Best effort: volumes over the device's limits are left to `prepare` (which
    /// reports them). Built ahead, a volume is the same bits `prepare` builds.
    pub fn ahead(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        volume_group: &wgpu::BindGroup,
        volumes: &[LightParams],
        diffusion: &[Option<DiffusionInputs>],
        spread: u32,
    ) {
        let mut state = self.state.lock().expect("light state");
        let state = &mut *state;
        let mut wanted: Vec<(LightParams, Option<DiffusionInputs>)> = Vec::new();
        for (i, lp) in volumes.iter().enumerate() {
            let m = diffusion.get(i).copied().flatten();
            let held = state.builds.iter().any(|b| b.holds(lp, &m))
                || state.ahead.as_ref().is_some_and(|a| a.entry.holds(lp, &m))
                || wanted.iter().any(|(v, d)| v.same_volume(lp) && *d == m);
            if !held {
                wanted.push((*lp, m));
            }
        }
        let queued = wanted.len() + usize::from(state.ahead.is_some());
        if queued == 0 {
            return;
        }
        let mut wanted = wanted.into_iter();
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("vdbcook light volumes (ahead)"),
        });
        // This call's budget, once the first volume's cost is known.
        let mut budget = None;
        let mut spent = 0.0;
        loop {
            if state.ahead.is_none() {
                // The budget spent on a volume this call completed: the next one waits.
                if budget.is_some_and(|b| spent >= b) {
                    break;
                }
                let Some((lp, m)) = wanted.next() else {
                    break;
                };
                state.ahead = self.begin_ahead(device, state, volume_group, lp, m);
                if state.ahead.is_none() {
                    continue;
                }
            }
            let a = state.ahead.as_mut().expect("under way");
            let share = a.total * queued as f64 / f64::from(spread.max(1));
            let budget = *budget.get_or_insert(share + a.carry);
            // Whole dispatches (at least one a call), each taken while it brings the spent cost
            // nearer to the budget than leaving it would; the build's rest all at once when it
            // is under a quarter of a share over the budget (no tail left for another call).
            let first = a.next;
            let mut rest: f64 = a.rec.steps[a.next..].iter().map(|s| s.cost).sum();
            while let Some(s) = a.rec.steps.get(a.next) {
                let all = spent + rest <= budget + 0.25 * share;
                if spent > 0.0 && !all && spent + 0.5 * s.cost > budget {
                    break;
                }
                spent += s.cost;
                rest -= s.cost;
                a.next += 1;
            }
            a.rec.record(self, &mut encoder, first..a.next);
            if a.next < a.rec.steps.len() {
                // What this call recorded over or under its budget, within a share either way.
                a.carry = (budget - spent).clamp(-share, share);
                break;
            }
            let a = state.ahead.take().expect("under way");
            self.keep(state, a.entry, true);
        }
        queue.submit([encoder.finish()]);
    }

    /// Forgets the build under way ahead and the ahead builds' scratch (building ahead turned
    /// off).
    pub fn drop_ahead(&self) {
        let mut state = self.state.lock().expect("light state");
        state.ahead = None;
        state.ahead_scratch = Scratch::default();
    }

    /// The build of the one volume `lp` ahead of need (none when it is over the device's
    /// limits), through the ahead builds' own scratch: `prepare`'s builds run between its shares.
    fn begin_ahead(
        &self,
        device: &wgpu::Device,
        state: &mut State,
        volume_group: &wgpu::BindGroup,
        lp: LightParams,
        m: Option<DiffusionInputs>,
    ) -> Option<Ahead> {
        let plan = Plan::new(device, &[lp], &[m]).ok()?;
        let (rec, entry) = self
            .build(device, state, volume_group, plan, &[true], true)
            .ok()?;
        let total = rec.steps.iter().map(|s| s.cost).sum::<f64>();
        Some(Ahead {
            entry,
            rec,
            next: 0,
            total,
            carry: 0.0,
        })
    }

    /// Adds a completed build to the kept ones (counting its volumes as built, and as built
    /// ahead when `ahead`); kept builds beyond the limit that no draw holds go, oldest first.
    fn keep(&self, state: &mut State, entry: LightEntry, ahead: bool) -> Arc<LightEntry> {
        if ahead {
            let n = entry.key.0.len() as u64;
            state.counts.built += n;
            state.counts.ahead += n;
        }
        let entry = Arc::new(entry);
        state.builds.push(entry.clone());
        while state.builds.len() > KEPT_BUILDS {
            match state.builds.iter().position(|b| Arc::strong_count(b) == 1) {
                Some(i) => {
                    state.builds.remove(i);
                }
                None => break,
            }
        }
        entry
    }

    /// The build of `plan`'s volumes that `built` marks (the solves' records checked against the
    /// device's limits first, so that an error loses no kept build), into a destination
    /// (`destination`) through the scratch of builds recorded at once or, `ahead`, of builds
    /// made ahead: its dispatches and the entry it becomes.
    fn build(
        &self,
        device: &wgpu::Device,
        state: &mut State,
        volume_group: &wgpu::BindGroup,
        plan: Plan,
        built: &[bool],
        ahead: bool,
    ) -> Result<(Recording, LightEntry), RuntimeError> {
        let solves = plan.solves(built)?;
        let (pool, ms_pool, cells, ms_cells) = self.destination(device, state, &plan);
        let (slot, labels) = if ahead {
            let labels = ["density (ahead)", "diffusion scratch (ahead)"];
            (&mut state.ahead_scratch, labels)
        } else {
            (&mut state.scratch, ["density", "diffusion scratch"])
        };
        let label = |l: &str| format!("vdbcook light {l}");
        let scratch = grown(
            device,
            &mut slot.density,
            // A third f32 a cell where a volume solves the diffusion model (`ms_total > 0`).
            if plan.ms_total > 0 {
                3 * plan.largest
            } else {
                2 * plan.largest
            },
            &label(labels[0]),
        );
        let ms_floats = solves.iter().flatten().map(|s| s.1).max().unwrap_or(0);
        let ms_scratch =
            (ms_floats > 0).then(|| grown(device, &mut slot.ms, ms_floats, &label(labels[1])));
        let rec = self.recording(
            device,
            volume_group,
            &plan,
            (built, &solves),
            (&scratch, ms_scratch.as_ref()),
            (&pool, &ms_pool),
        );
        let entry = LightEntry::new(self, device, plan.key, (pool, ms_pool), (cells, ms_cells));
        Ok((rec, entry))
    }

    /// Where a build goes: the buffers of the oldest kept build no draw holds that is large
    /// enough (that build is forgotten), else new ones (`keep` forgets builds beyond the limit).
    /// Returns them and their capacities in cells.
    fn destination(
        &self,
        device: &wgpu::Device,
        state: &mut State,
        plan: &Plan,
    ) -> (wgpu::Buffer, wgpu::Buffer, usize, usize) {
        let free = state.builds.iter().position(|b| {
            Arc::strong_count(b) == 1 && b.cells >= plan.total && b.ms_cells >= plan.ms_total
        });
        match free.map(|i| state.builds.remove(i)) {
            Some(b) => (b.pool.clone(), b.ms_pool.clone(), b.cells, b.ms_cells),
            None => (
                storage_buffer(device, "vdbcook light volumes", 8 * plan.total),
                storage_buffer(
                    device,
                    "vdbcook light diffusion",
                    (MS_OUT_BYTES * plan.ms_total).max(MS_OUT_BYTES),
                ),
                plan.total,
                plan.ms_total,
            ),
        }
    }

    /// The dispatches that build `plan`'s volumes that `built` marks (the others are copied from
    /// kept builds: see `prepare`; `solves` holds the records of those built with one) into `pool` and
    /// `ms_pool`, through the density scratch and the diffusion scratch `scratch`: per volume
    /// the six light-volume passes, then for a diffusion volume the source, the gathered orders
    /// and the multigrid solve (`vdbcook_trace::diffusion` on the CPU, in the same order).
    fn recording(
        &self,
        device: &wgpu::Device,
        volume_group: &wgpu::BindGroup,
        plan: &Plan,
        (built, solves): (&[bool], &[Option<Solve>]),
        scratch: (&wgpu::Buffer, Option<&wgpu::Buffer>),
        (pool, ms_pool): (&wgpu::Buffer, &wgpu::Buffer),
    ) -> Recording {
        let align = ms_record_stride(device.limits().min_uniform_buffer_offset_alignment);
        let mut bytes: Vec<u8> = Vec::new();
        for (records, _) in solves.iter().flatten() {
            for r in records.iter().flatten() {
                bytes.extend_from_slice(bytemuck::bytes_of(r));
                bytes.resize(bytes.len().next_multiple_of(align), 0);
            }
        }
        let ms_group = scratch.1.filter(|_| !bytes.is_empty()).map(|ms_scratch| {
            let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("vdbcook light diffusion params"),
                contents: &bytes,
                usage: wgpu::BufferUsages::UNIFORM,
            });
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
        let mut rec = Recording {
            volume_group: volume_group.clone(),
            groups: Vec::new(),
            ms_group,
            copies: Vec::new(),
            steps: Vec::new(),
        };
        let mut next_record = 0usize;
        for ((lp, solve), &b) in plan.key.0.iter().zip(solves).zip(built) {
            if !b {
                continue;
            }
            let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("vdbcook light params"),
                contents: bytemuck::bytes_of(lp),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let g = rec.groups.len();
            rec.groups
                .push(device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("vdbcook light build"),
                    layout: &self.build_layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: uniform.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: scratch.0.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: pool.as_entire_binding(),
                        },
                    ],
                }));
            // Per cell (4³ groups) or per column of an axis (8² groups over the other two).
            let [x, y, z, sub] = lp.dims;
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
            let n = lp.cells() as f64;
            for (k, size) in sizes.into_iter().enumerate() {
                let per_cell = match k {
                    0 => 2.0 * f64::from(sub).powi(3),
                    // The sun's pass walks the voxels toward the sun from every cell: as many
                    // as the longest side holds of the level the density pass reads.
                    1 => {
                        let voxels_per_cell = f64::from(lp.lo[3]) / f64::from(1u32 << lp.level);
                        VOLUME_COST[1] * f64::from(x.max(y).max(z)) * voxels_per_cell
                    }
                    _ => VOLUME_COST[k],
                };
                rec.steps.push(Step {
                    pass: Pass::Volume(k),
                    group: g,
                    offset: 0,
                    size,
                    cost: per_cell * n,
                });
            }
            let Some((records, _)) = solve else {
                continue;
            };
            let first = next_record;
            next_record += 2 * records.len();
            let mut run = |pass: usize, k: usize, parity: usize| {
                let d = records[k][0].dims;
                rec.steps.push(Step {
                    pass: Pass::Ms(pass),
                    group: g,
                    // The dynamic offset of level `k`'s record of `parity`.
                    offset: ((first + 2 * k + parity) * align) as u32,
                    size: [d[0], d[1], d[2]].map(|v| v.div_ceil(WORKGROUP)),
                    cost: MS_COST[pass] * f64::from(d[0] * d[1] * d[2]),
                });
            };
            let [source, gather, second, restrict, prolong, limit, update, store, paths, vacuum] =
                [0, 1, 2, 3, 4, 5, 6, 7, 8, 9];
            run(source, 0, 0);
            for k in 1..records.len() {
                run(restrict, k, 0);
            }
            // The light scattered once, then twice (the record's parity), as many orders
            // as the inputs ask.
            for order in 0..records[0][0].parent[3] as usize {
                // The shared paths, coarsest first, then each cell's own steps.
                for k in (MS_SHARED_PATHS..records.len()).rev() {
                    run(paths, k, order);
                }
                run(gather, 0, order);
                run(second, 0, order);
                for k in 1..records.len() {
                    run(restrict, k, 0);
                }
            }
            for k in (0..records.len()).rev() {
                // The sun's open faces, once per level (its sources are final here).
                run(vacuum, k, 0);
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
        rec
    }
}

/// A storage buffer of `bytes` (at least 8) that copies may read and write.
fn storage_buffer(device: &wgpu::Device, label: &str, bytes: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(8) as u64,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// The scratch buffer in `slot`, made anew when it holds fewer than `floats` f32s.
fn grown(
    device: &wgpu::Device,
    slot: &mut Option<(wgpu::Buffer, usize)>,
    floats: usize,
    label: &str,
) -> wgpu::Buffer {
    if slot.as_ref().is_none_or(|s| s.1 < floats) {
        *slot = Some((storage_buffer(device, label, 4 * floats), floats));
    }
    slot.as_ref().expect("just made").0.clone()
}

/// One volume's diffusion solve: its records `[level][parity]` and the scratch it needs (f32s).
type Solve = (Vec<[MsParams; 2]>, usize);

/// A list of light volumes placed one after the other in one buffer, checked against the
/// device's limits.
struct Plan {
    /// The volumes (placed) and the diffusion inputs of those that solve it.
    key: (Vec<LightParams>, Vec<Option<DiffusionInputs>>),
    /// Cells in all, cells of the diffusion output (all of them when any volume solves it, else
    /// 0), and of the largest volume.
    total: usize,
    ms_total: usize,
    largest: usize,
    /// The device's largest storage binding, in bytes.
    most: usize,
}

impl Plan {
    fn new(
        device: &wgpu::Device,
        volumes: &[LightParams],
        diffusion: &[Option<DiffusionInputs>],
    ) -> Result<Plan, RuntimeError> {
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
        let largest = placed.iter().map(|lp| lp.cells()).max().unwrap_or(1);
        Ok(Plan {
            key: (placed, diffusion),
            total,
            ms_total: if per_cell == MS_OUT_BYTES { total } else { 0 },
            largest,
            most,
        })
    }

    /// The diffusion solves' records of the volumes `built` marks (and that solve one), and the
    /// scratch each needs; refused when that scratch exceeds the device's binding limit.
    fn solves(&self, built: &[bool]) -> Result<Vec<Option<Solve>>, RuntimeError> {
        let solves: Vec<_> = self
            .key
            .0
            .iter()
            .zip(&self.key.1)
            .zip(built)
            .map(|((lp, m), &b)| {
                m.filter(|_| b)
                    .map(|m| ms_records([lp.dims[0], lp.dims[1], lp.dims[2]], &m))
            })
            .collect();
        let ms_floats = solves.iter().flatten().map(|s| s.1).max().unwrap_or(0);
        if 4 * ms_floats > self.most {
            return Err(RuntimeError::Limits(format!(
                "the diffusion solve needs {} bytes of scratch, the device binds at most {} \
                 (lower light_res, or use MsModel::Octaves)",
                4 * ms_floats,
                self.most
            )));
        }
        Ok(solves)
    }
}

/// Relative cost per cell of the light-volume passes (the sun's per cell and voxel of the grid's
/// longest side, in the level the density pass reads; the three axes, sky; the density pass's is
/// `2·sub³`, not measured) and of the
/// diffusion passes (source, gather, second, restrict, prolong, limit, update, store, paths,
/// vacuum — the last not measured: taken as an update's, once per level), by
/// which [`LightPass::ahead`] shares a build out. Measured on lavapipe, one dispatch per
/// displayed frame of a 64³ stormscape volume (`vdbcook bench --light-ahead 1000 --fps 0.5`,
/// the spans less the static frame; a unit ≈ 2.5 ms there): sun 49 ms, axes 0.5–2.7, sky 1.3,
/// source 13, gather 280–300 (the level-1 paths about 20), second 31 (4.8 after the last
/// order), limit 8, update 22, store 20. The sun's pass walks the voxels since 2026-11-27
/// (`lv_sun_main`): re-measured 2026-11-28, 263–271 ms against gathers of 297–350 ms (and
/// 448–482 against 382–539 in a slower stretch), about 0.9 of a gather on that volume's 72
/// voxels a side (1.125 a cell): 1.4 per voxel. Its walk's length is in voxels, not cells, so
/// the estimate follows `light_res` only as far as the cells are wider than a voxel. The same
/// profile read the fine level's update at 32 ms and the gathers a little above the figures
/// here; the MS estimates are relative to each other and were left as they are.
const VOLUME_COST: [f64; 6] = [0.0, 1.4, 0.5, 0.5, 0.5, 0.5];
const MS_COST: [f64; 10] = [5.0, 112.0, 12.0, 10.0, 1.0, 3.0, 9.0, 8.0, 60.0, 9.0];

/// Which pipeline a step runs: `LightPass::passes[k]` or `ms_passes[k]`.
#[derive(Debug, Clone, Copy)]
enum Pass {
    Volume(usize),
    Ms(usize),
}

/// One dispatch of a build.
struct Step {
    pass: Pass,
    /// The volume's `LightParams` group in `Recording::groups`.
    group: usize,
    /// The diffusion record's dynamic offset (`Pass::Ms`).
    offset: u32,
    size: [u32; 3],
    /// Estimated (`VOLUME_COST`, `MS_COST`).
    cost: f64,
}

/// A build as buffer copies and dispatches, recorded at once (`prepare`) or a share at a time
/// (`ahead`): the bind groups keep every buffer they read alive.
struct Recording {
    volume_group: wgpu::BindGroup,
    groups: Vec<wgpu::BindGroup>,
    ms_group: Option<wgpu::BindGroup>,
    /// `(from, byte, to, byte, bytes)`, recorded before the first step.
    copies: Vec<(wgpu::Buffer, u64, wgpu::Buffer, u64, u64)>,
    steps: Vec<Step>,
}

impl Recording {
    /// Records `steps` (with the copies when it starts at 0): each light-volume pass in a compute
    /// pass of its own, each run of diffusion passes in one.
    fn record(&self, lp: &LightPass, encoder: &mut wgpu::CommandEncoder, steps: Range<usize>) {
        if steps.start == 0 {
            for (from, at, to, to_at, bytes) in &self.copies {
                encoder.copy_buffer_to_buffer(from, *at, to, *to_at, *bytes);
            }
        }
        let mut k = steps.start;
        while k < steps.end {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("vdbcook light volume"),
                timestamp_writes: None,
            });
            loop {
                let s = &self.steps[k];
                match s.pass {
                    Pass::Volume(p) => {
                        pass.set_pipeline(&lp.passes[p]);
                        pass.set_bind_group(0, &self.volume_group, &[]);
                        pass.set_bind_group(1, &self.groups[s.group], &[]);
                    }
                    Pass::Ms(p) => {
                        pass.set_pipeline(&lp.ms_passes[p]);
                        pass.set_bind_group(1, &self.groups[s.group], &[]);
                        let group = self.ms_group.as_ref().expect("a diffusion build");
                        pass.set_bind_group(2, group, &[s.offset]);
                    }
                }
                pass.dispatch_workgroups(s.size[0], s.size[1], s.size[2]);
                k += 1;
                let both_ms = |a: Pass, b: Pass| matches!((a, b), (Pass::Ms(_), Pass::Ms(_)));
                if k == steps.end || !both_ms(s.pass, self.steps[k].pass) {
                    break;
                }
            }
        }
    }
}

/// A volume's build under way ahead of need ([`LightPass::ahead`]): its destination (the entry
/// it becomes), its dispatches, how far they have been recorded and their estimated cost.
struct Ahead {
    entry: LightEntry,
    rec: Recording,
    /// The next step to record.
    next: usize,
    total: f64,
    /// The estimated cost the calls so far recorded under (+) or over (−) their budgets.
    carry: f64,
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

    /// The gather's shared paths (26 per cell of each level from `MS_SHARED_PATHS`) lie where
    /// nothing the gathers read or write is: the φ A and φ B place ([3n, 7n), untouched until the
    /// solve) of the level below when they fit there, else after the levels; each level's paths
    /// apart. So a light volume's scratch grows only by its smallest levels' paths (the
    /// near-field test's 128-cell volume, 109 MB, exceeded the default 128 MiB binding when all
    /// of them followed the levels).
    #[test]
    fn shared_gather_paths_fit_in_the_solve_scratch() {
        let m = DiffusionInputs {
            extinction: 1.0,
            albedo: 0.9,
            h: [1.0; 3],
            chord: 1.0,
            gather: [1.0 / 26.0; 26],
            phase: ([0.0; 2], 1.0),
            orders: 2,
        };
        let cells = |d: [u32; 3]| d.iter().map(|&v| v as usize).product::<usize>();
        for dims in [
            [64, 64, 64],
            [128, 128, 100],
            [128, 101, 77],
            [33, 17, 65],
            [24, 24, 18],
            [9, 9, 9],
            [7, 5, 3],
        ] {
            let (records, total) = ms_records(dims, &m);
            let levels = ms_levels(dims);
            let offs: Vec<usize> = levels
                .iter()
                .scan(0, |at, &d| {
                    *at += MS_FLOATS_PER_CELL * cells(d);
                    Some(*at - MS_FLOATS_PER_CELL * cells(d))
                })
                .collect();
            let data: usize = levels.iter().map(|&d| MS_FLOATS_PER_CELL * cells(d)).sum();
            let mut regions = Vec::new();
            let mut appended = 0;
            for k in MS_SHARED_PATHS..levels.len() {
                let at = records[0][0].paths[k / 4][k % 4] as usize;
                let end = at + 26 * cells(levels[k]);
                let below = cells(levels[k - 1]);
                let free = offs[k - 1] + 3 * below..offs[k - 1] + 7 * below;
                if at >= data {
                    appended += 26 * cells(levels[k]);
                    assert!(end <= total, "{dims:?} level {k}: past the scratch");
                } else {
                    assert!(
                        free.contains(&at) && end <= free.end,
                        "{dims:?} level {k}: {at}..{end} outside {free:?}"
                    );
                }
                regions.push((at, end));
            }
            regions.sort();
            for w in regions.windows(2) {
                assert!(w[0].1 <= w[1].0, "{dims:?}: paths overlap");
            }
            assert_eq!(total, data + appended, "{dims:?}");
            // Large grids keep nearly all of them in place.
            if levels[0].iter().all(|&v| v >= 64) {
                assert!(appended * 200 < data, "{dims:?}: {appended} of {data}");
            }
            assert!(records
                .iter()
                .flatten()
                .all(|r| r.paths == records[0][0].paths));
        }
    }

    /// The shader's copy of `MS_SHARED_PATHS` (where `ms_gather_main` stops walking and reads a
    /// path) is the one the records place paths for and the CPU's gather shares from.
    #[test]
    fn the_shader_shares_paths_from_the_same_level() {
        let decl = format!("const MS_SHARED_PATHS: u32 = {MS_SHARED_PATHS}u;");
        assert!(
            crate::LIGHT_BUILD_WGSL.contains(&decl),
            "light_build.wgsl lacks `{decl}`"
        );
    }

    /// The shader's copies of `MAX_SUB` (the density pass keeps a cell's samples in arrays of
    /// that size for the transport density) are the scene crate's.
    #[test]
    fn the_shader_keeps_as_many_density_samples_as_a_cell_has() {
        let m = vdbcook_scene::MAX_SUB;
        for decl in [
            format!("const LV_MAX_SUB: u32 = {m}u;"),
            format!("const LV_MAX_SUB_SAMPLES: u32 = {}u;", m * m * m),
            format!("const LV_MAX_SUB_COLUMNS: u32 = {}u;", m * m),
        ] {
            assert!(
                crate::LIGHT_BUILD_WGSL.contains(&decl),
                "light_build.wgsl lacks `{decl}`"
            );
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
                stop,
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
                level,
                paths,
            }),
        );
    }
}
