//! Uploads an asset once: every frame's roots, the L2 nodes (masks, bases, prefixes, ranges),
//! the leaf refs, tile values, brick ranges and quantization ranges into one storage buffer of
//! u32 words, and the brick pool — the quantized formats (BC7, BC4, unorm8) as **textures**, the
//! float formats (f16, f32) in up to four storage buffers, the packed formats (1–7 bits a voxel)
//! as their own words after the float bricks in the same buffers — plus what the renderer needs
//! per frame on the CPU side (stored boxes, value ranges).
//!
//! The upload checks the device's features and limits and picks a [`Layout`] for the quantized
//! bricks (first that works: BC in 3D textures, BC in 2D arrays, BC decoded at upload into
//! unorm8 textures, everything decoded into storage buffers); [`UploadOptions::force`] pins one
//! (tests use it to cover every path on one adapter). The choice is logged (`log::info!`) and
//! readable through [`GpuVolume::layout`] and [`GpuVolume::describe`].
//!
//! # Texture layouts (shared by every texture-backed group; `volume.wgsl` reads them)
//! Each quantized format that has bricks gets one texture ("group": BC7, BC4, unorm8). A brick is
//! a *tile* of 8×8 texels and `S` slices: `S = 8` for BC4 and unorm8 (slice `z` = voxel z), `S =
//! 2` for BC7 (texel (x, y) of slice `s` holds voxels z = 4s..4s+3 in R, G, B, A — the asset's
//! own encoding, see `docs/payloads.md`). Brick `b` of the group (its index minus the group's
//! first brick) lies at tile `(b mod tx, (b / tx) mod ty, b / (tx·ty))`, i.e. texels
//! `[8·cx, 8·cx+8) × [8·cy, 8·cy+8) × [S·cz, S·cz+S)`, in a texture of `8·tx × 8·ty × S·tz`
//! texels (3D) or `8·tx × 8·ty` texels and `S·tz` layers (2D array): the two are addressed
//! alike, only the binding differs. Texel formats: `Bc4RUnorm` / `Bc7RgbaUnorm` (the asset's
//! blocks copied as they are: BC blocks are 4×4×1, so every slice is independent), or
//! `R8Unorm` / `Rgba8Unorm` holding the 8-bit codes (unorm8 bricks, and BC bricks decoded at
//! upload with the asset's decoder). A voxel is `lo + (hi − lo)·texel` with the brick's
//! `brick_quant` `[lo, hi]`, the CPU's `payload::dequantize`.

use bytemuck::{Pod, Zeroable};
use vdbcook_asset::{bc, Asset, LeafRef, PayloadFormat, BRICK_VOXELS, FORMATS, L2_WORDS};
use vdbcook_scene::LevelChain;
use wgpu::util::DeviceExt;

use crate::{Result, RuntimeError};

/// Streaming a window of frames under a byte budget (a child module: it plans and binds its
/// pool with this module's private pieces).
#[path = "stream.rs"]
pub(crate) mod stream;

/// Payload storage buffers the shader binds (`vdb_payload0..3`).
pub const PAYLOAD_BINDINGS: usize = 4;

/// Device features the runtime uses when they are enabled (BC textures, BC in 3D textures).
/// Request `adapter.features() & OPTIONAL_FEATURES` when creating the device; without them the
/// upload falls back to decoding BC bricks (same images, more bytes).
pub const OPTIONAL_FEATURES: wgpu::Features =
    wgpu::Features::TEXTURE_COMPRESSION_BC.union(wgpu::Features::TEXTURE_COMPRESSION_BC_SLICED_3D);

/// Where the quantized bricks (BC7, BC4, unorm8) go; f16/f32 bricks are always in storage
/// buffers. Listed in the order the automatic choice tries them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Layout {
    /// BC bricks as BC 3D textures (needs `TEXTURE_COMPRESSION_BC` and
    /// `TEXTURE_COMPRESSION_BC_SLICED_3D`), unorm8 as an `R8Unorm` 3D texture.
    Bc3d,
    /// BC bricks as BC 2D-array textures (needs `TEXTURE_COMPRESSION_BC`), unorm8 as an
    /// `R8Unorm` 2D array.
    Bc2dArray,
    /// BC bricks decoded at upload into `R8Unorm` (BC4) / `Rgba8Unorm` (BC7) 3D textures,
    /// unorm8 as is: works on any adapter, exact, 2 (BC4) or 4 (BC7) times the BC bytes.
    Decoded3d,
    /// As [`Layout::Decoded3d`] in 2D arrays (for 3D limits too small for the pool).
    Decoded2dArray,
    /// Every brick decoded to f32 (or f16 when f32 would not fit) in storage buffers.
    Buffers,
}

impl Layout {
    /// Every layout, in the order the automatic choice tries them on a hardware adapter.
    pub const ALL: [Layout; 5] = [
        Layout::Bc3d,
        Layout::Bc2dArray,
        Layout::Decoded3d,
        Layout::Decoded2dArray,
        Layout::Buffers,
    ];
    /// The automatic order on a software adapter (`DeviceType::Cpu`: lavapipe, WARP,
    /// SwiftShader): there a BC texel fetch decodes its block in software on every read (native
    /// BC7 measured 4–5× slower than decoded on lavapipe, `docs/rendering.md`) and the "GPU"
    /// memory is host memory anyway, so decoded 8-bit textures come first.
    pub const SOFTWARE_ORDER: [Layout; 5] = [
        Layout::Decoded3d,
        Layout::Decoded2dArray,
        Layout::Bc3d,
        Layout::Bc2dArray,
        Layout::Buffers,
    ];
    /// The order the automatic choice tries on `device`.
    pub fn automatic_order(device: &wgpu::Device) -> [Layout; 5] {
        if device.adapter_info().device_type == wgpu::DeviceType::Cpu {
            Layout::SOFTWARE_ORDER
        } else {
            Layout::ALL
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            Layout::Bc3d => "bc-3d",
            Layout::Bc2dArray => "bc-2d-array",
            Layout::Decoded3d => "decoded-3d",
            Layout::Decoded2dArray => "decoded-2d-array",
            Layout::Buffers => "buffers",
        }
    }
    fn native_bc(self) -> bool {
        matches!(self, Layout::Bc3d | Layout::Bc2dArray)
    }
    fn dim3(self) -> bool {
        matches!(self, Layout::Bc3d | Layout::Decoded3d)
    }
}

/// Options of [`GpuVolume::upload_with`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct UploadOptions {
    /// Use this layout or fail (`RuntimeError::Limits` / `Unsupported`) instead of choosing.
    pub force: Option<Layout>,
}

/// How the bricks held in storage buffers are stored. Packed bricks, where the layout is not
/// [`Layout::Buffers`], follow the buffered bricks in the same buffers as their own words.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BufferLayout {
    /// No brick is in a buffer (the bindings hold 4-byte dummies).
    None,
    /// Every buffered brick decoded to f32 (exact for every format).
    F32 {
        buffers: usize,
        bricks_per_buffer: u32,
    },
    /// Two f16 per u32 (`unpack2x16float`): `exact` when every buffered brick is stored as
    /// f16, else the decoded values rounded to half (chosen only when f32 would not fit).
    F16 {
        buffers: usize,
        bricks_per_buffer: u32,
        exact: bool,
    },
}

impl BufferLayout {
    fn code(self) -> u32 {
        match self {
            BufferLayout::F16 { .. } => 1,
            _ => 0,
        }
    }
    /// Payload words per buffer, in the float bricks' stride (`bricks_per_buffer` bricks).
    pub fn words_per_buffer(self) -> u64 {
        self.bricks_per_buffer() as u64 * self.brick_words()
    }
    /// Words one buffered brick takes (512 f32 or 256 f16 pairs).
    pub fn brick_words(self) -> u64 {
        match self {
            BufferLayout::F16 { .. } => 256,
            _ => 512,
        }
    }
    /// Bricks each payload buffer holds.
    pub fn bricks_per_buffer(self) -> u32 {
        match self {
            BufferLayout::None => 1,
            BufferLayout::F32 {
                bricks_per_buffer, ..
            }
            | BufferLayout::F16 {
                bricks_per_buffer, ..
            } => bricks_per_buffer,
        }
    }
}

/// One texture of the brick pool (see the module docs for the tile layout).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TextureGroup {
    /// The asset format whose bricks it holds.
    pub source: PayloadFormat,
    pub format: wgpu::TextureFormat,
    /// 3D texture (`true`) or 2D array.
    pub dim3: bool,
    /// Tiles per row, rows per slice, tile layers (bricks along x, y, z).
    pub tiles: [u32; 3],
    /// Texels: width, height, depth or layers.
    pub size: [u32; 3],
    pub bytes: u64,
}

/// How the brick pool lies on the GPU.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PayloadLayout {
    /// The layout of the quantized bricks.
    pub layout: Layout,
    /// The bricks in storage buffers (float bricks; every brick with [`Layout::Buffers`]).
    pub buffers: BufferLayout,
    /// Bytes of the payload buffers (buffered and packed bricks).
    pub buffer_bytes: u64,
    /// Of those, the bytes of packed bricks (read as their own words, not decoded).
    pub packed_bytes: u64,
    /// One per quantized format with bricks in a texture.
    pub textures: Vec<TextureGroup>,
}

/// Group slots of `VolumeInfo` (BC7, BC4, unorm8, floats, packed1..packed7), in brick order.
const GROUPS: usize = 11;
const KIND_BUFFER: u32 = 0;
const KIND_3D: u32 = 1;
const KIND_ARRAY: u32 = 2;
const KIND_PACKED: u32 = 3;

/// The group slot of `VolumeInfo` that holds bricks of `format` (f16 and f32 share one).
pub(crate) fn group_of(format: PayloadFormat) -> usize {
    match format.rank() {
        r @ 0..=2 => r,
        3 | 4 => 3,
        r => r - 1,
    }
}
/// The first format (in [`PayloadFormat::ORDER`]) of group slot `g`.
fn group_first_format(g: usize) -> usize {
    if g <= 3 {
        g
    } else {
        g + 1
    }
}
/// The u32 words one packed brick of `format` takes (its bytes / 4), 0 for other formats.
pub(crate) fn packed_words(format: PayloadFormat) -> u64 {
    format
        .packed_bits()
        .map_or(0, |_| format.bytes_per_brick() as u64 / 4)
}

/// `VdbGroup` of `volume.wgsl`: bricks `[first, next group's first)` are read at local index
/// `b − first + base`, from the payload buffers (`kind` 0) or the group's texture (1: 3D, 2:
/// 2D array) with `tiles` tiles per row / rows per slice; packed bricks (`kind` 3) at payload
/// word `base + (b − first)·16·bits`, `tiles_x` holding `bits`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, Default)]
pub(crate) struct GroupInfo {
    first: u32,
    base: u32,
    kind: u32,
    tiles_x: u32,
    tiles_y: u32,
    _pad: [u32; 3],
}

/// `VdbAsset` of `volume.wgsl`: where one asset's sections lie in the topology (word offsets),
/// its extent, frames, channels and background.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable, Default)]
pub(crate) struct AssetInfo {
    pub root_dims: [u32; 3],
    pub root_len: u32,
    pub off_roots: u32,
    pub off_masks: u32,
    pub off_base: u32,
    pub off_prefix: u32,
    pub off_l2_ranges: u32,
    pub off_refs: u32,
    pub off_tiles: u32,
    pub off_channel_bg: u32,
    pub background: f32,
    pub frames: u32,
    pub channels: u32,
    pub _pad: u32,
}

/// Most assets one volume set holds (`VDB_MAX_ASSETS` of `volume.wgsl`).
pub const MAX_ASSETS: usize = 16;

/// The `VolumeInfo` uniform of `volume.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct VolumeInfo {
    pub bricks_per_binding: u32,
    pub payload_layout: u32,
    pub off_brick_ranges: u32,
    pub off_brick_quant: u32,
    pub asset_count: u32,
    pub _pad: [u32; 3],
    pub groups: [GroupInfo; GROUPS],
    pub assets: [AssetInfo; MAX_ASSETS],
}

/// An asset on the GPU: all frames and the whole brick pool, with the bind group (group 0 of
/// `VOLUME_WGSL`) an engine's pipelines can use as is.
pub struct GpuVolume {
    pub(crate) bind_group_layout: wgpu::BindGroupLayout,
    pub(crate) bind_group: wgpu::BindGroup,
    layout: PayloadLayout,
    gpu_bytes: u64,
    /// The assets on the volume's pool (one, or the assets of a volume set), in set order.
    pub(crate) assets: Vec<AssetMeta>,
}

/// What the CPU side knows of one asset of a volume: its frames (a streamed window's, window
/// local), transform, levels, per-frame boxes and ranges, and its channels' boxes.
#[derive(Debug, Clone)]
pub(crate) struct AssetMeta {
    pub frames: usize,
    /// Levels of detail uploaded (`LevelChain::of`): stored level `k` of frame `f` is root set
    /// `f + k·frames`.
    pub levels: LevelChain,
    pub root_len: usize,
    pub root_dims: [u32; 3],
    pub index_to_world: [[f64; 4]; 4],
    /// Per frame, the index-space box `[lo, hi)` of what it stores (`vdbcook_scene::stored_bbox`).
    pub bboxes: Vec<Option<([f64; 3], [f64; 3])>>,
    /// Per frame: `vdbcook_scene::content_box` (the sampling modes clip their rays to it).
    pub content: Vec<Option<([f64; 3], [f64; 3])>>,
    pub frame_max: Vec<f32>,
    /// Channels 1.. of a multi-channel asset (empty for one channel): per channel, its
    /// background and per frame the box where it exceeds it (`vdbcook_scene::content_box_above`),
    /// for emission read from that channel.
    pub channels: Vec<ChannelBoxes>,
}

impl AssetMeta {
    pub fn extent(&self) -> [f64; 3] {
        self.root_dims.map(|d| d as f64 * 128.0)
    }
    /// Levels of detail and the root-offset stride between levels (`frames · root_len`), for
    /// `LightParams::new`.
    pub fn lod(&self) -> (LevelChain, usize) {
        (self.levels, self.frames * self.root_len)
    }
    /// The cell box of `frame` where emission `e` may glow (`None`: nowhere): its channel's
    /// voxels above the channel's background, or everywhere when the background glows itself
    /// (`vdbcook_trace::Tracer` takes the same box); the density's content box for channel 0
    /// (emission ranges start at 0 K or above, and the content box holds every value above 0).
    pub fn emission_box(
        &self,
        e: &vdbcook_scene::Emission,
        frame: usize,
    ) -> crate::Result<Option<([f64; 3], [f64; 3])>> {
        if e.channel == 0 {
            return Ok(self.content[frame]);
        }
        let Some(ch) = self.channels.get(e.channel - 1) else {
            return Err(crate::RuntimeError::Setting(format!(
                "emission channel {} is not in the asset ({} channel(s))",
                e.channel,
                self.channels.len() + 1
            )));
        };
        Ok(if e.range[0] >= ch.background {
            ch.boxes[frame]
        } else {
            Some(([0.0; 3], self.extent()))
        })
    }
}

/// [`GpuVolume::channels`]' entry of one channel.
#[derive(Debug, Clone)]
pub(crate) struct ChannelBoxes {
    pub background: f32,
    pub boxes: Vec<Option<([f64; 3], [f64; 3])>>,
}

impl ChannelBoxes {
    /// Per channel `1..` of `asset`: its background and its boxes per frame.
    pub(crate) fn of(asset: &Asset) -> Vec<ChannelBoxes> {
        (1..asset.channel_count())
            .map(|c| {
                let bg = asset.header.channel_background(c);
                ChannelBoxes {
                    background: bg,
                    boxes: (0..asset.frame_count())
                        .map(|f| vdbcook_scene::content_box_above(asset, f, c, bg))
                        .collect(),
                }
            })
            .collect()
    }
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

/// A texture group's geometry before it exists: texel format, bytes per storage unit (a BC
/// block or a texel), unit edge in texels (4 for BC, 1 otherwise), slices per brick.
#[derive(Debug, Clone, Copy)]
struct Plan {
    source: PayloadFormat,
    format: wgpu::TextureFormat,
    unit_bytes: usize,
    unit_dim: u32,
    slices: u32,
    bricks: u32,
    dim3: bool,
    tiles: [u32; 3],
}

impl Plan {
    fn size(&self) -> [u32; 3] {
        [
            8 * self.tiles[0],
            8 * self.tiles[1],
            self.slices * self.tiles[2],
        ]
    }
    fn bytes(&self) -> u64 {
        let [w, h, d] = self.size();
        let u = self.unit_dim as u64;
        (w as u64 / u) * (h as u64 / u) * d as u64 * self.unit_bytes as u64
    }
    fn group(&self) -> TextureGroup {
        TextureGroup {
            source: self.source,
            format: self.format,
            dim3: self.dim3,
            tiles: self.tiles,
            size: self.size(),
            bytes: self.bytes(),
        }
    }
}

/// Tiles `[tx, ty, tz]` for `n` bricks of `slices` slices in a texture of at most `max` texels
/// (width, height, depth or layers), or why they do not fit.
fn tile_grid(n: u32, slices: u32, max: [u32; 3]) -> std::result::Result<[u32; 3], String> {
    let (mx, my, mz) = (max[0] / 8, max[1] / 8, max[2] / slices);
    if mx == 0 || my == 0 || mz == 0 {
        return Err(format!("texture limits {max:?} hold no 8×8×{slices} tile"));
    }
    let tx = n.min(mx);
    let rows = n.div_ceil(tx);
    let tz = rows.div_ceil(my);
    if tz > mz {
        return Err(format!(
            "{n} bricks need {} tile layers of {tx}×{my}, the limits {max:?} allow {mz}",
            tz
        ));
    }
    let ty = rows.div_ceil(tz);
    // Narrow the rows again so the last tile row and layer waste fewer than ty·tz tiles.
    let tx = n.div_ceil(ty * tz);
    Ok([tx, ty, tz])
}

/// The texture plan of one quantized format under `layout`, or why it cannot be used.
fn plan_group(
    device: &wgpu::Device,
    layout: Layout,
    source: PayloadFormat,
    bricks: u32,
) -> std::result::Result<Plan, String> {
    use wgpu::TextureFormat as F;
    let (format, unit_bytes, unit_dim, slices) = match (source, layout.native_bc()) {
        (PayloadFormat::Bc4, true) => (F::Bc4RUnorm, 8, 4, 8),
        (PayloadFormat::Bc7, true) => (F::Bc7RgbaUnorm, 16, 4, 2),
        (PayloadFormat::Bc4, false) | (PayloadFormat::Unorm8, _) => (F::R8Unorm, 1, 1, 8),
        (PayloadFormat::Bc7, false) => (F::Rgba8Unorm, 4, 1, 2),
        (f, _) => return Err(format!("{} bricks are not texture bricks", f.name())),
    };
    let features = device.features();
    if format.is_compressed() {
        if !features.contains(wgpu::Features::TEXTURE_COMPRESSION_BC) {
            return Err("the device has no TEXTURE_COMPRESSION_BC".into());
        }
        if layout.dim3() && !features.contains(wgpu::Features::TEXTURE_COMPRESSION_BC_SLICED_3D) {
            return Err("the device has no TEXTURE_COMPRESSION_BC_SLICED_3D".into());
        }
    }
    let l = device.limits();
    let max = if layout.dim3() {
        [l.max_texture_dimension_3d; 3]
    } else {
        [
            l.max_texture_dimension_2d,
            l.max_texture_dimension_2d,
            l.max_texture_array_layers,
        ]
    };
    let tiles = tile_grid(bricks, slices, max).map_err(|e| format!("{}: {e}", source.name()))?;
    Ok(Plan {
        source,
        format,
        unit_bytes,
        unit_dim,
        slices,
        bricks,
        dim3: layout.dim3(),
        tiles,
    })
}

/// The bytes of a brick as `plan` stores it: storage units ordered slice, unit row, unit column
/// (the asset's own order for BC blocks and unorm8 texels; BC decoded here when `plan` is 8-bit).
fn brick_units(plan: &Plan, format: PayloadFormat, bytes: &[u8], out: &mut Vec<u8>) {
    out.clear();
    match (format, plan.format.is_compressed()) {
        (PayloadFormat::Unorm8, _) | (_, true) => out.extend_from_slice(bytes),
        (PayloadFormat::Bc4, false) => {
            out.resize(BRICK_VOXELS, 0);
            for (bi, block) in bytes.chunks_exact(8).enumerate() {
                let texels = bc::decode_bc4_block(block.try_into().expect("8-byte block"));
                let (z, by, bx) = (bi / 4, (bi / 2) % 2, bi % 2);
                for (t, &q) in texels.iter().enumerate() {
                    let (x, y) = (4 * bx + t % 4, 4 * by + t / 4);
                    out[x + 8 * y + 64 * z] = q;
                }
            }
        }
        (PayloadFormat::Bc7, false) => {
            out.resize(2 * 64 * 4, 0);
            for (bi, block) in bytes.chunks_exact(16).enumerate() {
                let texels = bc::decode_bc7_block(block.try_into().expect("16-byte block"));
                let (s, by, bx) = (bi / 4, (bi / 2) % 2, bi % 2);
                for (t, rgba) in texels.iter().enumerate() {
                    let (x, y) = (4 * bx + t % 4, 4 * by + t / 4);
                    let i = 4 * (x + 8 * y + 64 * s);
                    out[i..i + 4].copy_from_slice(rgba);
                }
            }
        }
        (f, _) => unreachable!("{} is not a texture format", f.name()),
    }
}

/// The (empty) texture of `plan` and its view: 3D or a 2D array, written with `COPY_DST`.
fn empty_group_texture(
    device: &wgpu::Device,
    plan: &Plan,
    label: &str,
) -> (wgpu::Texture, wgpu::TextureView) {
    let [w, h, d] = plan.size();
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: d,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: if plan.dim3 {
            wgpu::TextureDimension::D3
        } else {
            wgpu::TextureDimension::D2
        },
        format: plan.format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let view = texture.create_view(&wgpu::TextureViewDescriptor {
        label: Some(label),
        dimension: Some(if plan.dim3 {
            wgpu::TextureViewDimension::D3
        } else {
            wgpu::TextureViewDimension::D2Array
        }),
        ..Default::default()
    });
    (texture, view)
}

/// Appends buffered brick `values` (decoded, voxel order) as payload words: an f16 brick's own
/// bytes under the f16 layout, other bricks rounded to f16 pairs under it, else f32 bits.
fn push_brick_words(
    out: &mut Vec<u32>,
    format: PayloadFormat,
    bytes: &[u8],
    values: &[f32; BRICK_VOXELS],
    half_layout: bool,
) {
    if format == PayloadFormat::F16 && half_layout {
        out.extend(
            bytes
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])),
        );
    } else if half_layout {
        out.extend(values.chunks_exact(2).map(|p| {
            half::f16::from_f32(p[0]).to_bits() as u32
                | (half::f16::from_f32(p[1]).to_bits() as u32) << 16
        }));
    } else {
        out.extend(values.iter().map(|v| v.to_bits()));
    }
}

/// Bricks in the buffers and how they are stored, or why they do not fit: `buffered` bricks
/// (decoded, or f16/f32) and then `packed` words of packed bricks.
fn plan_buffers(
    buffered: u64,
    all_f16: bool,
    packed: u64,
    max_binding: u64,
) -> std::result::Result<BufferLayout, String> {
    if buffered == 0 && packed == 0 {
        return Ok(BufferLayout::None);
    }
    let fits = |bytes_per_brick: u64| {
        let per = (max_binding / bytes_per_brick).min(1 << 22);
        let words = buffered * bytes_per_brick / 4 + packed;
        let per_buffer = per * bytes_per_brick / 4;
        (per > 0 && words <= per_buffer * PAYLOAD_BINDINGS as u64)
            .then(|| ((words.div_ceil(per_buffer) as usize).max(1), per as u32))
    };
    let layout = if all_f16 {
        fits(1024).map(|(buffers, per)| BufferLayout::F16 {
            buffers,
            bricks_per_buffer: per,
            exact: true,
        })
    } else {
        fits(2048)
            .map(|(buffers, per)| BufferLayout::F32 {
                buffers,
                bricks_per_buffer: per,
            })
            .or_else(|| {
                fits(1024).map(|(buffers, per)| BufferLayout::F16 {
                    buffers,
                    bricks_per_buffer: per,
                    exact: false,
                })
            })
    };
    layout.ok_or_else(|| {
        format!(
            "{buffered} buffered bricks and {packed} words of packed bricks do not fit \
             {PAYLOAD_BINDINGS} storage bindings of {max_binding} bytes"
        )
    })
}

/// A full plan: texture groups (BC7, BC4, unorm8 slots) and the buffer layout.
struct FullPlan {
    layout: Layout,
    textures: [Option<Plan>; 3],
    buffers: BufferLayout,
}

/// `counts`: bricks per format, in [`PayloadFormat::ORDER`] (an asset's `brick_counts`, or the
/// slots of a streamed pool). Packed bricks keep their words unless the layout is
/// [`Layout::Buffers`] (then they are decoded as every brick is).
fn plan_layout(
    device: &wgpu::Device,
    counts: &[u64; FORMATS],
    layout: Layout,
    max_binding: u64,
) -> std::result::Result<FullPlan, String> {
    let mut textures = [None; 3];
    if layout != Layout::Buffers {
        for (slot, format) in PayloadFormat::ORDER[..3].iter().enumerate() {
            let n = counts[format.rank()];
            if n == 0 {
                continue;
            }
            let n = u32::try_from(n).map_err(|_| format!("{n} {} bricks", format.name()))?;
            textures[slot] = Some(plan_group(device, layout, *format, n)?);
        }
    }
    let textured: u64 = textures.iter().flatten().map(|p| p.bricks as u64).sum();
    let packed: u64 = if layout == Layout::Buffers {
        0
    } else {
        PayloadFormat::PACKED
            .iter()
            .map(|f| counts[f.rank()] * packed_words(*f))
            .sum()
    };
    let packed_bricks: u64 = if packed > 0 {
        PayloadFormat::PACKED.iter().map(|f| counts[f.rank()]).sum()
    } else {
        0
    };
    let buffered = counts.iter().sum::<u64>() - textured - packed_bricks;
    let all_f16 = buffered > 0 && counts[PayloadFormat::F16.rank()] == buffered;
    let buffers = plan_buffers(buffered, all_f16, packed, max_binding)?;
    Ok(FullPlan {
        layout,
        textures,
        buffers,
    })
}

impl GpuVolume {
    /// Uploads every frame and the whole brick pool. Checks the device's features and limits
    /// and picks the payload layout (logged, and returned by [`GpuVolume::layout`]); refuses an
    /// asset whose topology or pool cannot fit them.
    pub fn upload(device: &wgpu::Device, queue: &wgpu::Queue, asset: &Asset) -> Result<GpuVolume> {
        Self::upload_with(device, queue, asset, UploadOptions::default())
    }

    /// [`GpuVolume::upload`] with options (e.g. a forced [`Layout`]). The whole asset is the one
    /// window of a pool holding every brick: the streamed volume's own upload
    /// ([`crate::StreamingVolume`]), so there is one uploader.
    pub fn upload_with(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        asset: &Asset,
        options: UploadOptions,
    ) -> Result<GpuVolume> {
        stream::StreamingVolume::upload_whole(device, queue, &[asset], options)
    }

    /// Several assets on one pool: a *volume set* (at most [`MAX_ASSETS`]). Their bricks share
    /// the payload buffers and textures, each keeps its own topology section, frames, transform
    /// and levels; a [`crate::VolumeDrawer`] built on the set draws instances of any of them
    /// in one pass (`Instance::asset`), so overlapping volumes blend where they overlap and
    /// one sun's shadows fall from every asset on every other.
    pub fn upload_set(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        assets: &[&Asset],
        options: UploadOptions,
    ) -> Result<GpuVolume> {
        stream::StreamingVolume::upload_whole(device, queue, assets, options)
    }

    /// The payload layout chosen at upload.
    pub fn layout(&self) -> &PayloadLayout {
        &self.layout
    }
    /// Pipeline-overridable constants of `VOLUME_WGSL` for this volume (`VDB_PATHS`: the brick
    /// read paths it uses). Pass them as `PipelineCompilationOptions::constants` so the unused
    /// paths compile away; pipelines without them keep every path and work too.
    pub fn pipeline_constants(&self) -> Vec<(&'static str, f64)> {
        let l = &self.layout;
        let mut paths = 0u32;
        // Buffered bricks (the buffers hold more than the packed words).
        if l.buffer_bytes > l.packed_bytes {
            paths |= 1;
        }
        if l.packed_bytes > 0 {
            paths |= 128;
        }
        for t in &l.textures {
            let slot = match t.source {
                PayloadFormat::Bc7 => 0,
                PayloadFormat::Bc4 => 1,
                _ => 2,
            };
            paths |= 2 << (2 * slot + (!t.dim3) as u32);
        }
        vec![("VDB_PATHS", paths.max(1) as f64)]
    }
    /// One line saying how the pool lies on the GPU (layout, textures, buffers, bytes).
    pub fn describe(&self) -> String {
        let l = &self.layout;
        let mut parts = vec![if l.textures.is_empty() && l.layout != Layout::Buffers {
            if l.packed_bytes > 0 {
                "no texture bricks".to_string()
            } else {
                "no quantized bricks".to_string()
            }
        } else {
            format!("layout {}", l.layout.name())
        }];
        for t in &l.textures {
            parts.push(format!(
                "{} bricks in a {:?} {} {}×{}×{} ({} bytes)",
                t.source.name(),
                t.format,
                if t.dim3 { "3D texture" } else { "2D array" },
                t.size[0],
                t.size[1],
                t.size[2],
                t.bytes
            ));
        }
        // Buffers are sized to their words: what is not packed is buffered bricks.
        let buffered = l.buffer_bytes > l.packed_bytes;
        let what = match l.buffers {
            BufferLayout::F32 { .. } if buffered => "buffered bricks as f32",
            BufferLayout::F16 { exact: true, .. } if buffered => "buffered bricks as f16",
            BufferLayout::F16 { .. } if buffered => "buffered bricks as f16 (rounded)",
            _ => "",
        };
        let what = match (what, l.packed_bytes) {
            (w, 0) => w.to_string(),
            ("", p) => format!("packed bricks ({p} bytes)"),
            (w, p) => format!("{w} and packed bricks ({p} bytes)"),
        };
        if l.buffers != BufferLayout::None {
            parts.push(format!(
                "{what} in {} storage buffer(s) ({} bytes)",
                match l.buffers {
                    BufferLayout::F32 { buffers, .. } | BufferLayout::F16 { buffers, .. } =>
                        buffers,
                    BufferLayout::None => 0,
                },
                l.buffer_bytes
            ));
        }
        parts.push(format!("{} bytes on the GPU in all", self.gpu_bytes));
        parts.join(", ")
    }
    /// Frames of the volume's (first) asset.
    pub fn frame_count(&self) -> usize {
        self.assets[0].frames
    }
    /// Assets on the volume (1, or a volume set's).
    pub fn asset_count(&self) -> usize {
        self.assets.len()
    }
    /// Bytes uploaded (topology, pool, info).
    pub fn gpu_bytes(&self) -> u64 {
        self.gpu_bytes
    }
    /// A compute pipeline over this volume: group 0 is the volume's, groups 1.. are `layouts`,
    /// compiled with [`GpuVolume::pipeline_constants`] (the tracer's and the drawer's).
    pub(crate) fn compute_pipeline(
        &self,
        device: &wgpu::Device,
        label: &str,
        module: &wgpu::ShaderModule,
        entry_point: &str,
        layouts: &[&wgpu::BindGroupLayout],
    ) -> wgpu::ComputePipeline {
        let constants = self.pipeline_constants();
        let volume = (&self.bind_group_layout, &constants[..]);
        volume_pipeline(device, volume, label, module, entry_point, layouts)
    }

    /// The bind group of `VOLUME_WGSL`'s group 0 and its layout, for an engine's own pipelines.
    pub fn bind_group(&self) -> (&wgpu::BindGroupLayout, &wgpu::BindGroup) {
        (&self.bind_group_layout, &self.bind_group)
    }
    /// Index-space box `[lo, hi)` of what `frame` stores (`None`: nothing, or no such frame).
    pub fn frame_bbox(&self, frame: usize) -> Option<([f64; 3], [f64; 3])> {
        self.assets[0].bboxes.get(frame).copied().flatten()
    }
    /// [`GpuVolume::frame_bbox`] of asset `asset` of a volume set.
    pub fn asset_frame_bbox(&self, asset: usize, frame: usize) -> Option<([f64; 3], [f64; 3])> {
        self.assets.get(asset)?.bboxes.get(frame).copied().flatten()
    }
    /// The (first) asset's `index_to_world`.
    pub fn index_to_world(&self) -> &[[f64; 4]; 4] {
        &self.assets[0].index_to_world
    }
    /// Asset `asset`'s `index_to_world` (a volume set's), `None` past the last asset.
    pub fn asset_index_to_world(&self, asset: usize) -> Option<&[[f64; 4]; 4]> {
        self.assets.get(asset).map(|a| &a.index_to_world)
    }
    /// Whether the specs guarantee that the GPU reads every brick exactly as the CPU decoder
    /// does, up to f32 rounding of the dequantization: false for rounded f16 buffers and for
    /// native BC4 and BC7 textures, which a conformant driver may read up to
    /// `vdbcook_asset::payload::read_codes_per_voxel` codes of the brick range off (BC4 1 to 9.15
    /// by block, BC7 1; the cooker's `--max-error` counts that slack, so the budget holds either
    /// way).
    pub fn exact(&self) -> bool {
        !matches!(self.layout.buffers, BufferLayout::F16 { exact: false, .. })
            && !self.layout.textures.iter().any(|t| {
                matches!(
                    t.format,
                    wgpu::TextureFormat::Bc4RUnorm | wgpu::TextureFormat::Bc7RgbaUnorm
                )
            })
    }
}

/// What a [`crate::Renderer`] or [`crate::VolumeDrawer`] keeps of the volume it draws: its bind
/// group and the CPU-side per-frame boxes that go into each dispatch's uniform. A renderer is
/// built for one bind-group layout and one set of pipeline constants; [`Bound::rebind`] takes
/// another volume with the same ones (a [`crate::StreamingVolume`]'s next window) without
/// rebuilding any pipeline.
pub(crate) struct Bound {
    pub layout: wgpu::BindGroupLayout,
    pub group: wgpu::BindGroup,
    constants: Vec<(&'static str, f64)>,
    /// The volume's assets (`GpuVolume::assets`).
    pub assets: Vec<AssetMeta>,
}

impl std::ops::Deref for Bound {
    type Target = AssetMeta;
    /// The first asset: a renderer's, and a drawer's of one asset.
    fn deref(&self) -> &AssetMeta {
        &self.assets[0]
    }
}

/// Checks that `device` binds what a volume needs (its storage buffers and textures per stage);
/// returns the largest storage binding in bytes.
pub(crate) fn check_limits(device: &wgpu::Device) -> Result<u64> {
    let limits = device.limits();
    if limits.max_storage_buffers_per_shader_stage < 1 + PAYLOAD_BINDINGS as u32 {
        return Err(RuntimeError::Limits(format!(
            "max_storage_buffers_per_shader_stage {} (need {})",
            limits.max_storage_buffers_per_shader_stage,
            1 + PAYLOAD_BINDINGS
        )));
    }
    if limits.max_sampled_textures_per_shader_stage < TEXTURE_BINDINGS {
        return Err(RuntimeError::Limits(format!(
            "max_sampled_textures_per_shader_stage {} (need {TEXTURE_BINDINGS})",
            limits.max_sampled_textures_per_shader_stage
        )));
    }
    Ok(limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size))
}

/// A compute-stage buffer binding of `ty` at `binding` (no dynamic offset, no minimum size).
pub(crate) fn buffer_entry(
    binding: u32,
    ty: wgpu::BufferBindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A compute pipeline whose group 0 is a volume's (`volume`: its layout and pipeline
/// constants) and groups 1.. are `layouts`.
pub(crate) fn volume_pipeline(
    device: &wgpu::Device,
    volume: (&wgpu::BindGroupLayout, &[(&'static str, f64)]),
    label: &str,
    module: &wgpu::ShaderModule,
    entry_point: &str,
    layouts: &[&wgpu::BindGroupLayout],
) -> wgpu::ComputePipeline {
    let groups: Vec<Option<&wgpu::BindGroupLayout>> = std::iter::once(volume.0)
        .chain(layouts.iter().copied())
        .map(Some)
        .collect();
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &groups,
        immediate_size: 0,
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&layout),
        module,
        entry_point: Some(entry_point),
        compilation_options: wgpu::PipelineCompilationOptions {
            constants: volume.1,
            ..Default::default()
        },
        cache: None,
    })
}

impl Bound {
    /// [`volume_pipeline`] over the bound volume (pipelines made after construction, e.g. a
    /// variant compiled on first use).
    pub fn compute_pipeline(
        &self,
        device: &wgpu::Device,
        label: &str,
        module: &wgpu::ShaderModule,
        entry_point: &str,
        layouts: &[&wgpu::BindGroupLayout],
    ) -> wgpu::ComputePipeline {
        volume_pipeline(
            device,
            (&self.layout, &self.constants),
            label,
            module,
            entry_point,
            layouts,
        )
    }

    pub fn of(volume: &GpuVolume) -> Bound {
        Bound {
            layout: volume.bind_group_layout.clone(),
            group: volume.bind_group.clone(),
            constants: volume.pipeline_constants(),
            assets: volume.assets.clone(),
        }
    }

    /// Binds `volume` instead, if the pipelines built for the current one can read it: the same
    /// bind-group layout object and pipeline constants, and the same assets (transform and root
    /// extent).
    pub fn rebind(&mut self, volume: &GpuVolume) -> Result<()> {
        let same_assets =
            volume.assets.len() == self.assets.len()
                && volume.assets.iter().zip(&self.assets).all(|(a, b)| {
                    a.index_to_world == b.index_to_world && a.root_dims == b.root_dims
                });
        if volume.bind_group_layout != self.layout
            || volume.pipeline_constants() != self.constants
            || !same_assets
        {
            return Err(RuntimeError::Rebind(
                "the volume is not laid out like the one the pipelines were built for (a \
                 StreamingVolume's windows can be swapped in; another volume needs a new renderer)"
                    .into(),
            ));
        }
        *self = Bound::of(volume);
        Ok(())
    }
}

/// First of the six texture bindings: (BC7, BC4, unorm8) × (3D, 2D array).
const FIRST_TEXTURE_BINDING: u32 = 2 + PAYLOAD_BINDINGS as u32;
const TEXTURE_BINDINGS: u32 = 6;

/// A 1×1×1 `R8Unorm` view for texture bindings a volume does not use.
fn dummy_view(device: &wgpu::Device, dim3: bool) -> wgpu::TextureView {
    let t = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("vdbcook unused brick texture"),
        size: wgpu::Extent3d {
            width: 1,
            height: 1,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: if dim3 {
            wgpu::TextureDimension::D3
        } else {
            wgpu::TextureDimension::D2
        },
        format: wgpu::TextureFormat::R8Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING,
        view_formats: &[],
    });
    t.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(if dim3 {
            wgpu::TextureViewDimension::D3
        } else {
            wgpu::TextureViewDimension::D2Array
        }),
        ..Default::default()
    })
}

/// Group 0 of `VOLUME_WGSL`: info uniform, topology, four payload buffers, six brick textures.
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
    for i in 0..TEXTURE_BINDINGS {
        entries.push(wgpu::BindGroupLayoutEntry {
            binding: FIRST_TEXTURE_BINDING + i,
            visibility: vis,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: true },
                view_dimension: if i % 2 == 0 {
                    wgpu::TextureViewDimension::D3
                } else {
                    wgpu::TextureViewDimension::D2Array
                },
                multisampled: false,
            },
            count: None,
        });
    }
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("vdbcook volume"),
        entries: &entries,
    })
}

/// `vdbcook_scene::stored_bbox` from per-brick boxes: tiled regions and tile leaves whose value
/// is not the background, and the brick voxels that differ from the background.
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
        LeafRef::Tile(v) if v == asset.header.background => {}
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout_check::{assert_mirrors, rust_layout};

    #[test]
    fn volume_info_mirrors_the_wgsl() {
        assert_mirrors(
            crate::VOLUME_WGSL,
            "VdbGroup",
            rust_layout!(GroupInfo {
                first,
                base,
                kind,
                tiles_x,
                tiles_y,
                _pad
            }),
        );
        assert_mirrors(
            crate::VOLUME_WGSL,
            "VolumeInfo",
            rust_layout!(VolumeInfo {
                bricks_per_binding,
                payload_layout,
                off_brick_ranges,
                off_brick_quant,
                asset_count,
                _pad,
                groups,
                assets,
            }),
        );
        assert_mirrors(
            crate::VOLUME_WGSL,
            "VdbAsset",
            rust_layout!(AssetInfo {
                root_dims,
                root_len,
                off_roots,
                off_masks,
                off_base,
                off_prefix,
                off_l2_ranges,
                off_refs,
                off_tiles,
                off_channel_bg,
                background,
                frames,
                channels,
                _pad,
            }),
        );
    }
}
