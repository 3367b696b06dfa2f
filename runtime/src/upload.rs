//! Uploads an asset once: every frame's roots, the L2 nodes (masks, bases, prefixes, ranges),
//! the leaf refs, tile values and brick ranges into one storage buffer of u32 words, and the
//! brick pool — decoded on the CPU with the asset's own decoders, so every payload format
//! (BC7, BC4, unorm8, f16, f32) reaches the shader exactly as the CPU sampler reads it — into up
//! to four storage buffers that each respect `max_storage_buffer_binding_size`. It also keeps
//! what the renderer needs per frame on the CPU side (stored boxes, value ranges).
//!
//! Native BC / unorm8 textures (3D with `TEXTURE_COMPRESSION_BC_SLICED_3D`, else 2D arrays) are
//! a later step: today's layouts cost 4 (f32) or 2 (f16) bytes per voxel of the pool.

use bytemuck::{Pod, Zeroable};
use vdbcook_asset::{Asset, LeafRef, PayloadFormat, BRICK_VOXELS, L2_WORDS};
use wgpu::util::DeviceExt;

use crate::{Result, RuntimeError};

/// Payload storage buffers the shader binds (`vdb_payload0..3`).
pub const PAYLOAD_BINDINGS: usize = 4;

/// How the brick pool lies on the GPU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PayloadLayout {
    /// Every brick decoded to f32 (exact for every format).
    F32 {
        buffers: usize,
        bricks_per_buffer: u32,
    },
    /// Two f16 per u32 (`unpack2x16float`): `exact` when every brick is stored as f16, else the
    /// decoded values rounded to half (chosen only when f32 would not fit the limits).
    F16 {
        buffers: usize,
        bricks_per_buffer: u32,
        exact: bool,
    },
}

impl PayloadLayout {
    fn code(self) -> u32 {
        match self {
            PayloadLayout::F32 { .. } => 0,
            PayloadLayout::F16 { .. } => 1,
        }
    }
    /// Bricks each payload buffer holds.
    pub fn bricks_per_buffer(self) -> u32 {
        match self {
            PayloadLayout::F32 {
                bricks_per_buffer, ..
            }
            | PayloadLayout::F16 {
                bricks_per_buffer, ..
            } => bricks_per_buffer,
        }
    }
}

/// The `VolumeInfo` uniform of `volume.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct VolumeInfo {
    root_dims: [u32; 3],
    root_len: u32,
    off_masks: u32,
    off_base: u32,
    off_prefix: u32,
    off_l2_ranges: u32,
    off_refs: u32,
    off_tiles: u32,
    off_brick_ranges: u32,
    bricks_per_binding: u32,
    background: f32,
    payload_layout: u32,
    frames: u32,
    _pad: u32,
}

/// An asset on the GPU: all frames and the whole brick pool, with the bind group (group 0 of
/// `VOLUME_WGSL`) an engine's pipelines can use as is.
pub struct GpuVolume {
    pub(crate) bind_group_layout: wgpu::BindGroupLayout,
    pub(crate) bind_group: wgpu::BindGroup,
    layout: PayloadLayout,
    frames: usize,
    root_len: usize,
    root_dims: [u32; 3],
    index_to_world: [[f64; 4]; 4],
    /// Per frame, the index-space box `[lo, hi)` of what it stores (`vdbcook_trace::stored_bbox`).
    bboxes: Vec<Option<([f64; 3], [f64; 3])>>,
    frame_max: Vec<f32>,
    gpu_bytes: u64,
}

/// Per brick, the box (voxel coordinates, `[lo, hi)`) of voxels that differ from `background`.
fn brick_box(values: &[f32; BRICK_VOXELS], background: f32) -> Option<([u8; 3], [u8; 3])> {
    let (mut lo, mut hi) = ([8u8; 3], [0u8; 3]);
    for (i, &v) in values.iter().enumerate() {
        if v != background {
            let x = [(i / 64) as u8, (i / 8 % 8) as u8, (i % 8) as u8];
            for a in 0..3 {
                lo[a] = lo[a].min(x[a]);
                hi[a] = hi[a].max(x[a] + 1);
            }
        }
    }
    (lo[0] < hi[0]).then_some((lo, hi))
}

fn words_of_f32(v: &[[f32; 2]]) -> impl Iterator<Item = u32> + '_ {
    v.iter().flat_map(|p| [p[0].to_bits(), p[1].to_bits()])
}

impl GpuVolume {
    /// Uploads every frame and the whole brick pool. Checks the device's limits and picks the
    /// payload layout (logged, and returned by [`GpuVolume::layout`]); refuses an asset whose
    /// topology or pool cannot fit them.
    pub fn upload(device: &wgpu::Device, _queue: &wgpu::Queue, asset: &Asset) -> Result<GpuVolume> {
        let limits = device.limits();
        let max_binding = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        if limits.max_storage_buffers_per_shader_stage < 1 + PAYLOAD_BINDINGS as u32 {
            return Err(RuntimeError::Limits(format!(
                "max_storage_buffers_per_shader_stage {} (need {})",
                limits.max_storage_buffers_per_shader_stage,
                1 + PAYLOAD_BINDINGS
            )));
        }

        // Topology: one u32 buffer, sections at word offsets.
        let mut topo: Vec<u32> = Vec::new();
        topo.extend_from_slice(&asset.roots);
        let off_masks = topo.len();
        topo.extend(
            asset
                .l2_masks
                .iter()
                .flat_map(|&w| [w as u32, (w >> 32) as u32]),
        );
        let off_base = topo.len();
        topo.extend_from_slice(&asset.l2_base);
        let off_prefix = topo.len();
        topo.extend(asset.l2_prefix.iter().map(|&p| p as u32));
        let off_l2_ranges = topo.len();
        topo.extend(words_of_f32(&asset.l2_ranges));
        let off_refs = topo.len();
        topo.extend_from_slice(&asset.l3_refs);
        let off_tiles = topo.len();
        topo.extend(asset.tiles.iter().map(|t| t.to_bits()));
        let off_brick_ranges = topo.len();
        topo.extend(words_of_f32(&asset.brick_ranges));
        if topo.is_empty() {
            topo.push(0);
        }
        let topo_bytes = topo.len() as u64 * 4;
        if topo_bytes > max_binding || topo.len() > u32::MAX as usize {
            return Err(RuntimeError::Limits(format!(
                "topology takes {topo_bytes} bytes, one storage binding holds {max_binding}"
            )));
        }
        debug_assert_eq!(asset.l2_masks.len(), asset.l2_count() * L2_WORDS);

        // Payload layout.
        let bricks = asset.brick_count() as u64;
        let all_f16 = bricks > 0 && asset.header.brick_counts[PayloadFormat::F16.rank()] == bricks;
        let fits = |bytes_per_brick: u64| {
            let per = (max_binding / bytes_per_brick).min(1 << 22);
            (per > 0 && bricks <= per * PAYLOAD_BINDINGS as u64).then_some(per)
        };
        let layout = if all_f16 {
            fits(1024).map(|per| (per, true, true))
        } else {
            fits(2048)
                .map(|per| (per, false, true))
                .or_else(|| fits(1024).map(|per| (per, true, false)))
        };
        let Some((per, half_layout, exact)) = layout else {
            return Err(RuntimeError::Limits(format!(
                "{bricks} bricks do not fit {PAYLOAD_BINDINGS} storage bindings of {max_binding} bytes"
            )));
        };
        let buffers = (bricks.div_ceil(per) as usize).max(1);
        let per = per as u32;
        let layout = if half_layout {
            PayloadLayout::F16 {
                buffers,
                bricks_per_buffer: per,
                exact,
            }
        } else {
            PayloadLayout::F32 {
                buffers,
                bricks_per_buffer: per,
            }
        };

        // Decode every brick once: payload words and the per-brick stored boxes.
        let background = asset.header.background;
        let mut boxes = Vec::with_capacity(bricks as usize);
        let mut payload: Vec<Vec<u32>> = vec![Vec::new(); buffers];
        let mut values = [0.0f32; BRICK_VOXELS];
        for b in 0..bricks as u32 {
            let out = &mut payload[(b / per) as usize];
            if all_f16 {
                let (_, bytes) = asset.brick_bytes(b);
                out.extend(
                    bytes
                        .chunks_exact(4)
                        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])),
                );
                asset.decode_brick(b, &mut values);
            } else {
                asset.decode_brick(b, &mut values);
                if half_layout {
                    out.extend(values.chunks_exact(2).map(|p| {
                        half::f16::from_f32(p[0]).to_bits() as u32
                            | (half::f16::from_f32(p[1]).to_bits() as u32) << 16
                    }));
                } else {
                    out.extend(values.iter().map(|v| v.to_bits()));
                }
            }
            boxes.push(brick_box(&values, background));
        }

        // Per-frame stored boxes (for the depth mode's range and the default framing).
        let bboxes = (0..asset.frame_count())
            .map(|f| frame_box(asset, f, &boxes))
            .collect();
        let frame_max = asset.frame_ranges.iter().map(|r| r[1]).collect();

        let info = VolumeInfo {
            root_dims: asset.header.root_dims,
            root_len: asset.root_len() as u32,
            off_masks: off_masks as u32,
            off_base: off_base as u32,
            off_prefix: off_prefix as u32,
            off_l2_ranges: off_l2_ranges as u32,
            off_refs: off_refs as u32,
            off_tiles: off_tiles as u32,
            off_brick_ranges: off_brick_ranges as u32,
            bricks_per_binding: per,
            background,
            payload_layout: layout.code(),
            frames: asset.frame_count() as u32,
            _pad: 0,
        };
        let storage = wgpu::BufferUsages::STORAGE;
        let info_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vdbcook volume info"),
            contents: bytemuck::bytes_of(&info),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let topo_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vdbcook topology"),
            contents: bytemuck::cast_slice(&topo),
            usage: storage,
        });
        let mut gpu_bytes = topo_bytes + std::mem::size_of::<VolumeInfo>() as u64;
        let payload_buffers: Vec<wgpu::Buffer> = (0..PAYLOAD_BINDINGS)
            .map(|i| {
                let words = payload.get(i).filter(|w| !w.is_empty());
                let dummy = [0u32];
                let contents: &[u32] = words.map(|w| w.as_slice()).unwrap_or(&dummy);
                gpu_bytes += contents.len() as u64 * 4;
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("vdbcook brick pool"),
                    contents: bytemuck::cast_slice(contents),
                    usage: storage,
                })
            })
            .collect();

        let bind_group_layout = volume_bind_group_layout(device);
        let mut entries = vec![
            wgpu::BindGroupEntry {
                binding: 0,
                resource: info_buffer.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: topo_buffer.as_entire_binding(),
            },
        ];
        for (i, b) in payload_buffers.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: 2 + i as u32,
                resource: b.as_entire_binding(),
            });
        }
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("vdbcook volume"),
            layout: &bind_group_layout,
            entries: &entries,
        });

        let bc3d = device
            .features()
            .contains(wgpu::Features::TEXTURE_COMPRESSION_BC_SLICED_3D);
        log::info!(
            "vdbcook: uploaded {} frames, {} bricks as {:?} ({} bytes on the GPU; bricks decoded at upload, \
             native BC textures not used yet, BC in 3D {}available)",
            asset.frame_count(),
            bricks,
            layout,
            gpu_bytes,
            if bc3d { "" } else { "not " }
        );
        Ok(GpuVolume {
            bind_group_layout,
            bind_group,
            layout,
            frames: asset.frame_count(),
            root_len: asset.root_len(),
            root_dims: asset.header.root_dims,
            index_to_world: asset.header.index_to_world,
            bboxes,
            frame_max,
            gpu_bytes,
        })
    }

    /// The payload layout chosen at upload.
    pub fn layout(&self) -> PayloadLayout {
        self.layout
    }
    pub fn frame_count(&self) -> usize {
        self.frames
    }
    /// Bytes uploaded (topology, pool, info).
    pub fn gpu_bytes(&self) -> u64 {
        self.gpu_bytes
    }
    /// The bind group of `VOLUME_WGSL`'s group 0 and its layout, for an engine's own pipelines.
    pub fn bind_group(&self) -> (&wgpu::BindGroupLayout, &wgpu::BindGroup) {
        (&self.bind_group_layout, &self.bind_group)
    }
    /// Index-space box `[lo, hi)` of what `frame` stores (`None`: nothing, or no such frame).
    pub fn frame_bbox(&self, frame: usize) -> Option<([f64; 3], [f64; 3])> {
        self.bboxes.get(frame).copied().flatten()
    }
    pub fn index_to_world(&self) -> &[[f64; 4]; 4] {
        &self.index_to_world
    }
    pub(crate) fn root_len(&self) -> usize {
        self.root_len
    }
    pub(crate) fn root_extent(&self) -> [f64; 3] {
        self.root_dims.map(|d| d as f64 * 128.0)
    }
    pub(crate) fn frame_max(&self, frame: usize) -> f32 {
        self.frame_max[frame]
    }
    /// Whether the payload layout reads back every brick exactly as the CPU decoder does.
    pub fn exact(&self) -> bool {
        !matches!(self.layout, PayloadLayout::F16 { exact: false, .. })
    }
}

/// Group 0 of `VOLUME_WGSL`: info uniform, topology, four payload buffers.
fn volume_bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let vis = wgpu::ShaderStages::COMPUTE | wgpu::ShaderStages::FRAGMENT;
    let mut entries = vec![wgpu::BindGroupLayoutEntry {
        binding: 0,
        visibility: vis,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }];
    for binding in 1..2 + PAYLOAD_BINDINGS as u32 {
        entries.push(wgpu::BindGroupLayoutEntry {
            binding,
            visibility: vis,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        });
    }
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("vdbcook volume"),
        entries: &entries,
    })
}

/// `vdbcook_trace::stored_bbox` from per-brick boxes: tiled regions, tile leaves, and the brick
/// voxels that differ from the background.
fn frame_box(
    asset: &Asset,
    frame: usize,
    boxes: &[Option<([u8; 3], [u8; 3])>],
) -> Option<([f64; 3], [f64; 3])> {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    let mut add = |a: [i64; 3], b: [i64; 3]| {
        for i in 0..3 {
            lo[i] = lo[i].min(a[i] as f64);
            hi[i] = hi[i].max(b[i] as f64);
        }
    };
    asset.for_each_leaf(frame, |o, r, region| match r {
        LeafRef::Empty => {}
        LeafRef::Tile(_) => {
            let size = if region { 128 } else { 8 };
            add(o, o.map(|c| c + size));
        }
        LeafRef::Brick(b) => {
            if let Some((bl, bh)) = boxes[b as usize] {
                add(
                    [0, 1, 2].map(|a| o[a] + bl[a] as i64),
                    [0, 1, 2].map(|a| o[a] + bh[a] as i64),
                );
            }
        }
    });
    (lo[0] <= hi[0]).then_some((lo, hi))
}
