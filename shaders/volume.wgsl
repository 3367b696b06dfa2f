// volume.wgsl — the one WGSL source of the flip-book tree access: bindings of an uploaded
// `GpuVolume` (group 0), the L1 → L2 → L3 → brick lookup with the node masks, the brick payload
// read, and the bounded 3D DDA that the hierarchical walk nests. It exists on its own so that an
// engine can include it (`vdbcook_runtime::VOLUME_WGSL`) in its own shaders and sample the
// volume with `vdb_value`, or walk it with `vdb_dda_init` / `vdb_dda_next`, without the tracer.
//
// Everything mirrors `crates/asset` (layout, sampler) and `crates/trace` (DDA rules): the CPU
// reference is the definition; this file follows it in f32.
//
// Group 0 (created by `GpuVolume::upload`, or `upload_set` for a volume set of several assets):
//   binding 0: `vdb_info` (uniform): per asset (`VdbAsset`, at most 16) its section offsets into
//              `vdb_topo`, root dims, frames, channels, background; the buffer payload layout,
//              the per-slot brick ranges and the brick groups, shared by the set's assets.
//              `vdb_select(a)` picks the asset the lookups that follow read (0 by default);
//   binding 1: `vdb_topo` (storage, u32 words), per asset: roots of all frames, L2 masks (each u64 as two
//              u32, low word first), L2 bases, L2 prefixes (one u32 each), L2 ranges and brick
//              ranges (f32 bits, [min, max] pairs), L3 refs, tile values (f32 bits);
//   bindings 2..5: the bricks kept in storage buffers (f16/f32 bricks; every brick with the
//              `buffers` layout), split over four buffers of `bricks_per_binding` bricks each:
//              f32 bits (payload_layout 0) or two f16 per u32 (payload_layout 1), voxel (x, y, z)
//              of a brick at 64x + 8y + z. Unused bindings hold a 4-byte dummy;
//   bindings 6..11: the quantized bricks as textures, per format (BC7, BC4, unorm8) a 3D and a
//              2D-array binding (the one not used, and those of formats without bricks, hold a
//              1-texel dummy). A brick is a tile of 8×8 texels and S slices (8; BC7: 2, voxel z
//              in channel z % 4 of slice z / 4); local brick i lies at tile
//              (i % tiles_x, (i / tiles_x) % tiles_y, i / (tiles_x·tiles_y)), texels
//              8·tile.xy + (x, y) and slice S·tile.z + z (3D depth or array layer). Texel formats:
//              Bc4RUnorm / Bc7RgbaUnorm (native), or R8Unorm / Rgba8Unorm holding the 8-bit codes.
//              A voxel is lo + (hi − lo)·texel over the brick's quantization range [lo, hi].
//
// Bricks are grouped by format (BC7, BC4, unorm8, then f16 and f32, then packed1..packed7):
// `groups[g]` says where the bricks from `groups[g].first` to the next group's first are read
// (kind 0: buffers at local index b − first + base; 1: the group's 3D texture; 2: its 2D array;
// 3: packed, `tiles_x` bits a voxel, the brick's 16·bits words from payload word
// base + (b − first)·16·bits on, after the buffered bricks' words: voxel n = 64x + 8y + z at
// bits [bits·n, bits·n + bits) of them, code q standing for the 8-bit code
// round(255·q / (2^bits − 1)), read as an unorm8 texel).

struct VdbGroup {
    first: u32,
    base: u32,
    kind: u32,
    tiles_x: u32,
    tiles_y: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// One asset of the volume set: where its frames' roots and its nodes lie in `vdb_topo` (word
// offsets: each asset's sections are its own; only the brick pool and its ranges are shared),
// its extent, frames, channels and backgrounds.
struct VdbAsset {
    root_dims: vec3<u32>,
    root_len: u32,
    off_roots: u32,
    off_masks: u32,
    off_base: u32,
    off_prefix: u32,
    off_l2_ranges: u32,
    off_refs: u32,
    off_tiles: u32,
    // Where the backgrounds of channels 1.. lie (f32 bits; channel c at + c).
    off_channel_bg: u32,
    background: f32,
    frames: u32,
    // Channels per leaf slot and node range (1, or 2..8 for a multi-channel asset: channel c's
    // ref of slot index i at refs[i·channels + c]).
    channels: u32,
    _pad: u32,
}

// Most assets one volume set holds.
const VDB_MAX_ASSETS: u32 = 16u;

struct VolumeInfo {
    bricks_per_binding: u32,
    // Buffered bricks: 0: f32 bits, one per word; 1: f16 pairs.
    payload_layout: u32,
    // The pool's per-brick value and quantization ranges ([min, max] f32 bits).
    off_brick_ranges: u32,
    off_brick_quant: u32,
    asset_count: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    // BC7, BC4, unorm8, floats (f16 and f32), packed1..packed7.
    groups: array<VdbGroup, 11>,
    assets: array<VdbAsset, 16>,
}

@group(0) @binding(0) var<uniform> vdb_info: VolumeInfo;
@group(0) @binding(1) var<storage, read> vdb_topo: array<u32>;
@group(0) @binding(2) var<storage, read> vdb_payload0: array<u32>;
@group(0) @binding(3) var<storage, read> vdb_payload1: array<u32>;
@group(0) @binding(4) var<storage, read> vdb_payload2: array<u32>;
@group(0) @binding(5) var<storage, read> vdb_payload3: array<u32>;
@group(0) @binding(6) var vdb_bc7_3d: texture_3d<f32>;
@group(0) @binding(7) var vdb_bc7_array: texture_2d_array<f32>;
@group(0) @binding(8) var vdb_bc4_3d: texture_3d<f32>;
@group(0) @binding(9) var vdb_bc4_array: texture_2d_array<f32>;
@group(0) @binding(10) var vdb_u8_3d: texture_3d<f32>;
@group(0) @binding(11) var vdb_u8_array: texture_2d_array<f32>;

const VDB_EMPTY: u32 = 0xffffffffu;
const VDB_TILE_BIT: u32 = 0x80000000u;
// Stands for +infinity (WGSL implementations need not honour real infinities).
const VDB_BIG: f32 = 3.0e38;

// The asset of the set every lookup reads (0 unless set: a volume of one asset needs nothing).
var<private> vdb_asset: u32;

// Makes every following lookup of this invocation read asset `a` of the volume set.
fn vdb_select(a: u32) {
    vdb_asset = min(a, vdb_info.asset_count - 1u);
}

// The selected asset's root regions per axis, roots per frame, frames, channels, background.
fn vdb_root_dims() -> vec3<u32> {
    return vdb_info.assets[vdb_asset].root_dims;
}
fn vdb_root_len() -> u32 {
    return vdb_info.assets[vdb_asset].root_len;
}
fn vdb_frames() -> u32 {
    return vdb_info.assets[vdb_asset].frames;
}
fn vdb_channels() -> u32 {
    return vdb_info.assets[vdb_asset].channels;
}
fn vdb_background() -> f32 {
    return vdb_info.assets[vdb_asset].background;
}
// The selected asset's extent in voxels.
fn vdb_extent() -> vec3<f32> {
    return vec3<f32>(vdb_root_dims() * 128u);
}

// The root entry (EMPTY, TILE_BIT | tile, or an L2 node) of region `r` (in the root box) of the
// frame whose roots start at `frame_root` (= frame · root_len).
fn vdb_root_entry(frame_root: u32, r: vec3<i32>) -> u32 {
    let d = vdb_root_dims();
    let i = u32(r.x) + d.x * (u32(r.y) + d.y * u32(r.z));
    return vdb_topo[vdb_info.assets[vdb_asset].off_roots + frame_root + i];
}

// The ref in slot `s` (0..4096) of L2 node `n`, or EMPTY when the mask has no such slot
// (channel 0: what every mode renders).
fn vdb_slot_ref(n: u32, s: u32) -> u32 {
    return vdb_slot_ref_c(n, s, 0u);
}

// The background of channel `c`.
fn vdb_channel_bg(c: u32) -> f32 {
    if (c == 0u) {
        return vdb_background();
    }
    return bitcast<f32>(vdb_topo[vdb_info.assets[vdb_asset].off_channel_bg + c]);
}

// `vdb_slot_ref` of channel `c` (EMPTY also where the slot exists but `c` is its background).
fn vdb_slot_ref_c(n: u32, s: u32, c: u32) -> u32 {
    let w = s >> 6u;
    let b = s & 63u;
    let off_masks = vdb_info.assets[vdb_asset].off_masks;
    let lo = vdb_topo[off_masks + n * 128u + 2u * w];
    let hi = vdb_topo[off_masks + n * 128u + 2u * w + 1u];
    var below: u32;
    if (b < 32u) {
        if (((lo >> b) & 1u) == 0u) {
            return VDB_EMPTY;
        }
        below = countOneBits(lo & ((1u << b) - 1u));
    } else {
        if (((hi >> (b - 32u)) & 1u) == 0u) {
            return VDB_EMPTY;
        }
        below = countOneBits(lo) + countOneBits(hi & ((1u << (b - 32u)) - 1u));
    }
    let asset = vdb_info.assets[vdb_asset];
    let idx = vdb_topo[asset.off_base + n] + vdb_topo[asset.off_prefix + n * 64u + w] + below;
    return vdb_topo[asset.off_refs + idx * asset.channels + c];
}

// The ref of the leaf at leaf coordinate `l` (asset index / 8) inside L2 node `n`.
fn vdb_leaf_ref(n: u32, l: vec3<i32>) -> u32 {
    let m = vec3<u32>(l & vec3<i32>(15));
    return vdb_slot_ref(n, m.x + 16u * (m.y + 16u * m.z));
}

fn vdb_tile(t: u32) -> f32 {
    return bitcast<f32>(vdb_topo[vdb_info.assets[vdb_asset].off_tiles + t]);
}

// [min, max] of the stored values of L2 node `n` (over its whole 128³ region; channel 0).
fn vdb_l2_range(n: u32) -> vec2<f32> {
    return vdb_l2_range_c(n, 0u);
}

// `vdb_l2_range` of channel `c`.
fn vdb_l2_range_c(n: u32, c: u32) -> vec2<f32> {
    let i = vdb_info.assets[vdb_asset].off_l2_ranges + 2u * (n * vdb_channels() + c);
    return vec2<f32>(bitcast<f32>(vdb_topo[i]), bitcast<f32>(vdb_topo[i + 1u]));
}

// [min, max] of brick `b`.
fn vdb_brick_range(b: u32) -> vec2<f32> {
    let i = vdb_info.off_brick_ranges + 2u * b;
    return vec2<f32>(bitcast<f32>(vdb_topo[i]), bitcast<f32>(vdb_topo[i + 1u]));
}

fn vdb_payload_word(binding: u32, i: u32) -> u32 {
    switch binding {
        case 0u: { return vdb_payload0[i]; }
        case 1u: { return vdb_payload1[i]; }
        case 2u: { return vdb_payload2[i]; }
        default: { return vdb_payload3[i]; }
    }
}

// [lo, hi] of the quantization range of brick `b` ([0, 0] for float bricks).
fn vdb_brick_quant(b: u32) -> vec2<f32> {
    let i = vdb_info.off_brick_quant + 2u * b;
    return vec2<f32>(bitcast<f32>(vdb_topo[i]), bitcast<f32>(vdb_topo[i + 1u]));
}

// The group (0: BC7, 1: BC4, 2: unorm8, 3: floats, 4..10: packed1..packed7) brick `b` belongs
// to.
fn vdb_brick_group(b: u32) -> u32 {
    var g = 0u;
    if (b >= vdb_info.groups[1].first) {
        g = 1u;
    }
    if (b >= vdb_info.groups[2].first) {
        g = 2u;
    }
    if (b >= vdb_info.groups[3].first) {
        g = 3u;
    }
    if ((VDB_PATHS & 128u) != 0u) {
        // Constant indices (a count of the groups that start at or before `b`): no dynamic
        // indexing of the uniform array.
        g += u32(b >= vdb_info.groups[4].first) + u32(b >= vdb_info.groups[5].first)
            + u32(b >= vdb_info.groups[6].first) + u32(b >= vdb_info.groups[7].first)
            + u32(b >= vdb_info.groups[8].first) + u32(b >= vdb_info.groups[9].first)
            + u32(b >= vdb_info.groups[10].first);
    }
    return g;
}

// Payload word `w` counted across the four buffers (each `bricks_per_binding` buffered bricks'
// words long).
fn vdb_payload_word_at(w: u32) -> u32 {
    let per = vdb_info.bricks_per_binding * select(512u, 256u, vdb_info.payload_layout == 1u);
    let binding = vdb_binding_of(w, per);
    return vdb_payload_word(binding, w - binding * per);
}

// Which of the four payload bindings holds element `i` (`per` to a binding): compares, not a
// division (software rasterizers divide lane by lane; `3·per` stays below 2^32 since a binding
// holds at most 2^30 words or 2^22 bricks).
fn vdb_binding_of(i: u32, per: u32) -> u32 {
    return u32(i >= per) + u32(i >= 2u * per) + u32(i >= 3u * per);
}

// Voxel `m` of brick `b` of packed group `grp` as its unorm8 texel (`payload::packed_code`).
fn vdb_packed_texel(grp: VdbGroup, b: u32, m: vec3<u32>) -> f32 {
    let bits = grp.tiles_x;
    let at = (64u * m.x + 8u * m.y + m.z) * bits;
    let w = grp.base + (b - grp.first) * 16u * bits + (at >> 5u);
    let s = at & 31u;
    // The next word only where the voxel's bits cross into it (never for widths 1, 2, 4).
    var q = vdb_payload_word_at(w) >> s;
    if (s + bits > 32u) {
        q |= vdb_payload_word_at(w + 1u) << (32u - s);
    }
    q &= (1u << bits) - 1u;
    // round(255·q / (2^bits − 1)) with `tiles_y` holding 255 / (2^bits − 1) as f32 bits: the
    // product is never within 1/254 of a half, so the rounding is exact.
    return unpack4x8unorm(u32(floor(f32(q) * bitcast<f32>(grp.tiles_y) + 0.5))).x;
}

// Voxel `m` (0..8 per axis) of the `local`-th buffered brick.
fn vdb_buffer_voxel(local: u32, m: vec3<u32>) -> f32 {
    let per = vdb_info.bricks_per_binding;
    let binding = vdb_binding_of(local, per);
    let i = (local - binding * per) * 512u + 64u * m.x + 8u * m.y + m.z;
    if (vdb_info.payload_layout == 0u) {
        return bitcast<f32>(vdb_payload_word(binding, i));
    }
    let pair = unpack2x16float(vdb_payload_word(binding, i >> 1u));
    return select(pair.x, pair.y, (i & 1u) == 1u);
}

// Which brick read paths a pipeline keeps (a bit mask; `GpuVolume::pipeline_constants` gives
// the volume's value, the default keeps them all): 1 buffers, 2 BC7 3D, 4 BC7 2D array, 8 BC4
// 3D, 16 BC4 2D array, 32 unorm8 3D, 64 unorm8 2D array, 128 packed words. The paths a volume does not use are then
// dead code the driver removes; with buffers alone the read is the plain buffer read (a volume
// whose bricks are all buffered has local index = brick index), which keeps software
// rasterizers (lavapipe runs every side of a divergent branch) from paying for texture paths.
override VDB_PATHS: u32 = 255u;

// Voxel `v` (0..8 per axis, taken mod 8) of brick `b`: one buffer word or one texel (nearest
// voxel, no filtering), dequantized with the brick's range.
fn vdb_brick_voxel(b: u32, v: vec3<i32>) -> f32 {
    let m = vec3<u32>(v & vec3<i32>(7));
    if (VDB_PATHS == 1u) {
        return vdb_buffer_voxel(b, m);
    }
    let g = vdb_brick_group(b);
    let grp = vdb_info.groups[g];
    let local = b - grp.first + grp.base;
    if ((VDB_PATHS & 1u) != 0u && grp.kind == 0u) {
        return vdb_buffer_voxel(local, m);
    }
    if ((VDB_PATHS & 128u) != 0u && grp.kind == 3u) {
        let q = vdb_brick_quant(b);
        return q.x + (q.y - q.x) * vdb_packed_texel(grp, b, m);
    }
    let tile = vec3<u32>(local % grp.tiles_x, (local / grp.tiles_x) % grp.tiles_y,
                         local / (grp.tiles_x * grp.tiles_y));
    let xy = vec2<i32>(8u * tile.xy + m.xy);
    let s8 = i32(8u * tile.z + m.z);
    var t = 0.0;
    if (g == 0u) {
        let s = i32(2u * tile.z + (m.z >> 2u));
        var c = vec4<f32>(0.0);
        if ((VDB_PATHS & 2u) != 0u && grp.kind == 1u) {
            c = textureLoad(vdb_bc7_3d, vec3<i32>(xy, s), 0);
        } else if ((VDB_PATHS & 4u) != 0u && grp.kind == 2u) {
            c = textureLoad(vdb_bc7_array, xy, s, 0);
        }
        t = c[m.z & 3u];
    } else if (g == 1u) {
        if ((VDB_PATHS & 8u) != 0u && grp.kind == 1u) {
            t = textureLoad(vdb_bc4_3d, vec3<i32>(xy, s8), 0).x;
        } else if ((VDB_PATHS & 16u) != 0u && grp.kind == 2u) {
            t = textureLoad(vdb_bc4_array, xy, s8, 0).x;
        }
    } else {
        if ((VDB_PATHS & 32u) != 0u && grp.kind == 1u) {
            t = textureLoad(vdb_u8_3d, vec3<i32>(xy, s8), 0).x;
        } else if ((VDB_PATHS & 64u) != 0u && grp.kind == 2u) {
            t = textureLoad(vdb_u8_array, xy, s8, 0).x;
        }
    }
    let q = vdb_brick_quant(b);
    return q.x + (q.y - q.x) * t;
}

// What holds asset index `a` of channel `c` in the frame whose roots start at `frame_root`:
// `VDB_EMPTY` (the channel's background: nothing stored, or outside the root extent),
// `VDB_TILE_BIT | t` (a region's or a leaf slot's tile `t`), or a brick index. The one descent
// root → L2 → leaf slot every point lookup takes.
fn vdb_holder_c(frame_root: u32, a: vec3<i32>, c: u32) -> u32 {
    let ext = vec3<i32>(vdb_root_dims() * 128u);
    if (any(a < vec3<i32>(0)) || any(a >= ext)) {
        return VDB_EMPTY;
    }
    let e = vdb_root_entry(frame_root, a >> vec3<u32>(7u));
    if (e == VDB_EMPTY || (e & VDB_TILE_BIT) != 0u) {
        return e;
    }
    let m = vec3<u32>((a >> vec3<u32>(3u)) & vec3<i32>(15));
    return vdb_slot_ref_c(e, m.x + 16u * (m.y + 16u * m.z), c);
}

// `vdb_holder_c` of channel 0 (what every mode renders).
fn vdb_holder(frame_root: u32, a: vec3<i32>) -> u32 {
    return vdb_holder_c(frame_root, a, 0u);
}

// The value of channel `c` at asset index `a` of the frame whose roots start at `frame_root`
// (the channel's background where nothing is stored and outside the root extent):
// `Asset::value_c` on the GPU.
fn vdb_value_c(frame_root: u32, a: vec3<i32>, c: u32) -> f32 {
    let r = vdb_holder_c(frame_root, a, c);
    if (r == VDB_EMPTY) {
        return vdb_channel_bg(c);
    }
    if ((r & VDB_TILE_BIT) != 0u) {
        return vdb_tile(r & ~VDB_TILE_BIT);
    }
    return vdb_brick_voxel(r, a);
}

// `vdb_value_c` of channel 0: `Asset::value` on the GPU.
fn vdb_value(frame_root: u32, a: vec3<i32>) -> f32 {
    return vdb_value_c(frame_root, a, 0u);
}

// The bound of the leaf (8³ voxels) holding asset index `a`: its brick's max, its tile's value,
// or the background where nothing is stored (the walks pass over leaves whose bound is ≤ 0).
fn vdb_leaf_bound(frame_root: u32, a: vec3<i32>) -> f32 {
    let r = vdb_holder(frame_root, a);
    if (r == VDB_EMPTY) {
        return vdb_background();
    }
    if ((r & VDB_TILE_BIT) != 0u) {
        return vdb_tile(r & ~VDB_TILE_BIT);
    }
    return vdb_brick_range(r).y;
}

// The trilinear density at cell-space point `p` (cell = index + ½: voxel centres at a + ½),
// each of the eight taps `max(v, 0)` (NaN reads 0), read through the tree so bricks, tiles and
// unstored space join without seams: `vdbcook_trace::Tracer::trilinear_density`.
fn vdb_trilinear(frame_root: u32, p: vec3<f32>) -> f32 {
    return vdb_trilinear_c(frame_root, p, 0u);
}

// `vdb_trilinear` of channel `c`.
fn vdb_trilinear_c(frame_root: u32, p: vec3<f32>, c: u32) -> f32 {
    let u = p - vec3<f32>(0.5);
    let base = floor(u);
    let f = u - base;
    let b = vec3<i32>(base);
    var sum = 0.0;
    for (var k = 0u; k < 8u; k++) {
        let hi = vec3<bool>((k & 1u) != 0u, (k & 2u) != 0u, (k & 4u) != 0u);
        let w = select(vec3<f32>(1.0) - f, f, hi);
        let v = vdb_value_c(frame_root, b + select(vec3<i32>(0), vec3<i32>(1), hi), c);
        if (v > 0.0) {
            sum += w.x * w.y * w.z * v;
        }
    }
    return sum;
}

// The value nearest to the continuous asset index point `p`, by OpenVDB's convention: voxel `a`
// sits at index `a` and covers [a - 1/2, a + 1/2) (OpenVDB's point sampler rounds). A world point
// maps to `p` by the inverse of the asset's `index_to_world` (`GpuVolume::index_to_world`).
fn vdb_value_nearest(frame_root: u32, p: vec3<f32>) -> f32 {
    return vdb_value(frame_root, vec3<i32>(floor(p + vec3<f32>(0.5))));
}

// The density an engine's own shader samples at a world point, with no tracer state:
// `world_to_index` maps world space to the asset's index space (the inverse of the instance's
// world_from_volume times the asset's index_to_world: `vdbcook_runtime::world_to_index`), the
// nearest voxel by OpenVDB's rounding, and a fractional flip-book `time` (clamped to the sequence)
// crossfades frames floor(time) and floor(time) + 1.
fn vdb_sample(world_to_index: mat4x4<f32>, world_pos: vec3<f32>, time: f32) -> f32 {
    let p = (world_to_index * vec4<f32>(world_pos, 1.0)).xyz;
    let t = clamp(time, 0.0, f32(vdb_frames() - 1u));
    let f0 = u32(floor(t));
    let f1 = min(f0 + 1u, vdb_frames() - 1u);
    let a = t - f32(f0);
    let v0 = vdb_value_nearest(f0 * vdb_root_len(), p);
    if (a <= 0.0) {
        return v0;
    }
    return mix(v0, vdb_value_nearest(f1 * vdb_root_len(), p), a);
}

// A ray in cell space (asset index + 1/2, so voxel `a` is the cell [a, a + 1) and `floor` finds
// it: `vdbcook_trace::Affine::cells`), p(t) = o + t·d, t in world units (d is the cell-space image
// of a unit world direction); `per_t` converts t to the length unit (|d| for voxels, else 1).
struct VdbRay {
    o: vec3<f32>,
    d: vec3<f32>,
    per_t: f32,
}

// The t interval (from t = 0) of the ray inside the half-open box [0, ext); x > y when empty.
fn vdb_clip(ray: VdbRay, ext: vec3<f32>) -> vec2<f32> {
    return vdb_clip_box(ray, vec3<f32>(0.0), ext);
}

// The ray's t range inside the box [lo, hi) (t >= 0), or (1, 0) when it misses.
fn vdb_clip_box(ray: VdbRay, lo: vec3<f32>, hi: vec3<f32>) -> vec2<f32> {
    var t0 = 0.0;
    var t1 = VDB_BIG;
    for (var i = 0; i < 3; i++) {
        if (ray.d[i] == 0.0) {
            if (!(ray.o[i] >= lo[i] && ray.o[i] < hi[i])) {
                return vec2<f32>(1.0, 0.0);
            }
        } else {
            let a = (lo[i] - ray.o[i]) / ray.d[i];
            let b = (hi[i] - ray.o[i]) / ray.d[i];
            t0 = max(t0, min(a, b));
            t1 = min(t1, max(a, b));
        }
    }
    if (t1 > t0 && t1 < VDB_BIG) {
        return vec2<f32>(t0, t1);
    }
    return vec2<f32>(1.0, 0.0);
}

// One level of the hierarchical DDA: cells of edge `size` in the box [lo, hi) (cell
// coordinates), for t in [tm, t1]. Rules (`crates/trace/src/dda.rs`): start cell clamped into the
// box; crossings recomputed from the cell index; ties step x, then y, then z; zero-length
// segments are not reported; at most (cells across x + y + z + 3) iterations.
struct VdbDda {
    cell: vec3<i32>,
    step: vec3<i32>,
    next: vec3<f32>,
    lo: vec3<i32>,
    hi: vec3<i32>,
    size: f32,
    tm: f32,
    t1: f32,
    budget: i32,
}

// A segment [ta, tb] of cell `cell`; `ok` false when the walk is over.
struct VdbSeg {
    ok: bool,
    cell: vec3<i32>,
    ta: f32,
    tb: f32,
}

fn vdb_crossing(ray: VdbRay, size: f32, cell: i32, axis: i32) -> f32 {
    let d = ray.d[axis];
    if (d > 0.0) {
        return (f32(cell + 1) * size - ray.o[axis]) / d;
    }
    if (d < 0.0) {
        return (f32(cell) * size - ray.o[axis]) / d;
    }
    return VDB_BIG;
}

fn vdb_dda_init(ray: VdbRay, size: f32, lo: vec3<i32>, hi: vec3<i32>, t0: f32, t1: f32) -> VdbDda {
    var s: VdbDda;
    s.lo = lo;
    s.hi = hi;
    s.size = size;
    s.tm = t0;
    s.t1 = t1;
    s.budget = 0;
    // `!(t1 > t0)` also refuses NaN: an empty walk.
    if (t1 > t0) {
        let hs = hi - lo;
        s.budget = hs.x + hs.y + hs.z + 3;
    }
    let p = ray.o + t0 * ray.d;
    for (var i = 0; i < 3; i++) {
        let c = clamp(floor(p[i] / size), -1.0e9, 1.0e9);
        s.cell[i] = clamp(i32(c), lo[i], hi[i] - 1);
        s.step[i] = select(select(0, -1, ray.d[i] < 0.0), 1, ray.d[i] > 0.0);
        s.next[i] = vdb_crossing(ray, size, s.cell[i], i);
    }
    return s;
}

// The next segment of a DDA (bounded by its budget).
fn vdb_dda_next(ray: VdbRay, s: ptr<function, VdbDda>) -> VdbSeg {
    var out: VdbSeg;
    out.ok = false;
    for (var guard = 0; guard < 4096; guard++) {
        if ((*s).budget <= 0) {
            return out;
        }
        (*s).budget -= 1;
        let n = (*s).next;
        var a = 2;
        if (n.x <= n.y && n.x <= n.z) {
            a = 0;
        } else if (n.y <= n.z) {
            a = 1;
        }
        let tn = n[a];
        let te = max(min(tn, (*s).t1), (*s).tm);
        let report = te > (*s).tm;
        out.cell = (*s).cell;
        out.ta = (*s).tm;
        out.tb = te;
        if (!(tn < (*s).t1)) {
            (*s).budget = 0;
        } else {
            (*s).tm = te;
            (*s).cell[a] += (*s).step[a];
            if ((*s).cell[a] < (*s).lo[a] || (*s).cell[a] >= (*s).hi[a]) {
                (*s).budget = 0;
            } else {
                (*s).next[a] = vdb_crossing(ray, (*s).size, (*s).cell[a], a);
            }
        }
        if (report) {
            out.ok = true;
            return out;
        }
    }
    return out;
}

// Optical depth beyond which `vdb_optical_depth` stops (`vdbcook_trace::OPAQUE_DEPTH`).
const VDB_OPAQUE_DEPTH: f32 = 20.0;

// `vdb_optical_depth` for a short stretch of `ray` (a few voxels, at most 1024; `absorb` 0: no
// opaque stop): one flat voxel DDA over the box the stretch [t0, t1] crosses, the tree descended
// once per 8³ leaf entered (`vdb_holder`) and each voxel read from it: the same voxels and sum as
// the hierarchical walk in less code (which software Vulkan runs faster).
fn vdb_optical_depth_near(frame_root: u32, ray: VdbRay, t0: f32, t1: f32, absorb: f32) -> f32 {
    return vdb_optical_depth_near_from(frame_root, ray, t0, t1, absorb, vec3<i32>(-1), VDB_EMPTY);
}

// `vdb_optical_depth_near` for a caller that knows the holder `r0` of 8³ leaf `leaf0` (leaf
// coordinates: index >> 3; −1 for none), typically the brick its own walk is in: no descent for
// that leaf. The DDA keeps its three crossings in a vector and advances the nearest (ties: x,
// then y), the crossing of a cell boundary b being (b − o)·(1/d).
fn vdb_optical_depth_near_from(frame_root: u32, ray: VdbRay, t0: f32, t1: f32, absorb: f32, leaf0: vec3<i32>, r0: u32) -> f32 {
    var tau = 0.0;
    if (!(t1 > t0)) {
        return tau;
    }
    let pa = ray.o + t0 * ray.d;
    let pb = ray.o + t1 * ray.d;
    let ext = vec3<i32>(vdb_root_dims() * 128u);
    let lo = max(vec3<i32>(floor(min(pa, pb))), vec3<i32>(0));
    let hi = min(vec3<i32>(floor(max(pa, pb))) + vec3<i32>(1), ext);
    let pos = ray.d > vec3<f32>(0.0);
    let moves = pos | (ray.d < vec3<f32>(0.0));
    let step = select(vec3<i32>(0), select(vec3<i32>(-1), vec3<i32>(1), pos), moves);
    let up = select(vec3<i32>(0), vec3<i32>(1), pos);
    let inv = select(vec3<f32>(0.0), 1.0 / ray.d, moves);
    var cell = clamp(vec3<i32>(clamp(floor(pa), vec3<f32>(-1.0e9), vec3<f32>(1.0e9))), lo, hi - vec3<i32>(1));
    var next = select(vec3<f32>(VDB_BIG), (vec3<f32>(cell + up) - ray.o) * inv, moves);
    let hs = hi - lo;
    let n = min(hs.x + hs.y + hs.z + 3, 4096);
    var tm = t0;
    var leaf = leaf0;
    var r = r0;
    for (var i = 0; i < n; i++) {
        let ax = next.x <= next.y && next.x <= next.z;
        let ay = !ax && next.y <= next.z;
        let m = vec3<bool>(ax, ay, !(ax || ay));
        let tn = select(select(next.z, next.y, ay), next.x, ax);
        let te = max(min(tn, t1), tm);
        if (te > tm) {
            let l = cell >> vec3<u32>(3u);
            if (any(l != leaf)) {
                leaf = l;
                r = vdb_holder(frame_root, cell);
            }
            var v = vdb_background();
            if ((r & VDB_TILE_BIT) != 0u && r != VDB_EMPTY) {
                v = vdb_tile(r & ~VDB_TILE_BIT);
            } else if (r != VDB_EMPTY) {
                v = vdb_brick_voxel(r, cell);
            }
            if (v > 0.0) {
                tau += v * (te - tm) * ray.per_t;
                if (absorb * tau >= VDB_OPAQUE_DEPTH) {
                    break;
                }
            }
        }
        if (!(tn < t1)) {
            break;
        }
        tm = te;
        cell += select(vec3<i32>(0), step, m);
        if (any(cell < lo) || any(cell >= hi)) {
            break;
        }
        next = select(next, (vec3<f32>(cell + up) - ray.o) * inv, m);
    }
    return tau;
}

// The density march of the frame whose roots start at `frame_root` along `ray` for t in
// [t0, t1] (inside the root extent, e.g. from `vdb_clip`): τ = Σ v·ℓ over the voxels, tiles and
// background spans crossed whose value is > 0 (ℓ: segment length times `ray.per_t`), exact (no
// step error), stopping once `absorb·τ ≥ 20`. Transmittance: `exp(−absorb·τ)`. This is the CPU
// tracer's Density mode (`vdbcook_trace::Tracer::optical_depth`); nodes, leaves and bricks whose
// max is ≤ 0 are passed over in one step.
fn vdb_optical_depth(frame_root: u32, ray: VdbRay, t0: f32, t1: f32, absorb: f32) -> f32 {
    let bg = vdb_background();
    let dims = vec3<i32>(vdb_root_dims());
    var tau = 0.0;
    var rd = vdb_dda_init(ray, 128.0, vec3<i32>(0), dims, t0, t1);
    for (var ri = 0; ri < 99; ri++) {
        let rs = vdb_dda_next(ray, &rd);
        if (!rs.ok) {
            break;
        }
        let e = vdb_root_entry(frame_root, rs.cell);
        if (e == VDB_EMPTY || (e & VDB_TILE_BIT) != 0u) {
            var v = bg;
            if (e != VDB_EMPTY) {
                v = vdb_tile(e & ~VDB_TILE_BIT);
            }
            if (v > 0.0) {
                tau += v * (rs.tb - rs.ta) * ray.per_t;
                if (absorb * tau >= VDB_OPAQUE_DEPTH) {
                    break;
                }
            }
            continue;
        }
        if (!(vdb_l2_range(e).y > 0.0)) {
            continue;
        }
        let llo = rs.cell * 16;
        var ld = vdb_dda_init(ray, 8.0, llo, llo + vec3<i32>(16), rs.ta, rs.tb);
        var opaque = false;
        for (var li = 0; li < 51; li++) {
            let ls = vdb_dda_next(ray, &ld);
            if (!ls.ok) {
                break;
            }
            let r = vdb_leaf_ref(e, ls.cell);
            if (r == VDB_EMPTY || (r & VDB_TILE_BIT) != 0u) {
                var v = bg;
                if (r != VDB_EMPTY) {
                    v = vdb_tile(r & ~VDB_TILE_BIT);
                }
                if (v > 0.0) {
                    tau += v * (ls.tb - ls.ta) * ray.per_t;
                    if (absorb * tau >= VDB_OPAQUE_DEPTH) {
                        opaque = true;
                        break;
                    }
                }
                continue;
            }
            if (!(vdb_brick_range(r).y > 0.0)) {
                continue;
            }
            let origin = ls.cell * 8;
            var vd = vdb_dda_init(ray, 1.0, origin, origin + vec3<i32>(8), ls.ta, ls.tb);
            for (var vi = 0; vi < 27; vi++) {
                let vs = vdb_dda_next(ray, &vd);
                if (!vs.ok) {
                    break;
                }
                let v = vdb_brick_voxel(r, vs.cell);
                if (v > 0.0) {
                    tau += v * (vs.tb - vs.ta) * ray.per_t;
                    if (absorb * tau >= VDB_OPAQUE_DEPTH) {
                        opaque = true;
                        break;
                    }
                }
            }
            if (opaque) {
                break;
            }
        }
        if (opaque) {
            break;
        }
    }
    return tau;
}
