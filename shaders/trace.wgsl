// trace.wgsl — the runtime's tracer: one compute invocation per pixel walks the frame's tree
// (HDDA: 128³ regions → 8³ leaf slots → voxels, skipping by per-node and per-brick max) and
// writes the mode's colour and raw value. It exists so the GPU draws exactly what the CPU
// reference tracer (`crates/trace`, whose crate docs define every mode) draws; the runtime tests
// compare the two images. Concatenated after `volume.wgsl`; `{{TARGET_FORMAT}}` is replaced by
// the storage-texture format the renderer was created for.
//
// Group 1: `params` (uniform, written once per render: camera, settings, frame).
// Group 2: the target: a storage texture and/or a storage buffer (`out_flags` says which),
//          buffer layout: width·height RGBA (f32 × 4) then width·height raw values.

struct Params {
    // Ray origin (the eye) in asset index space.
    eye_index: vec4<f32>,
    // Camera basis in world space; right and up scaled by the image-plane half extents.
    forward: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    // Rows of the inverse linear part of index_to_world (world direction → index direction).
    inv_a0: vec4<f32>,
    inv_a1: vec4<f32>,
    inv_a2: vec4<f32>,
    // xyz: root extent in voxels.
    extent: vec4<f32>,
    width: u32,
    height: u32,
    mode: u32,
    frame_root: u32,
    absorb: f32,
    cutoff: f32,
    near: f32,
    far: f32,
    value_max: f32,
    voxel_units: u32,
    out_flags: u32,
    _pad: u32,
}

@group(1) @binding(0) var<uniform> params: Params;
@group(2) @binding(0) var out_texture: texture_storage_2d<{{TARGET_FORMAT}}, write>;
@group(2) @binding(1) var<storage, read_write> out_buffer: array<f32>;

const MODE_DENSITY: u32 = 0u;
const MODE_DEPTH: u32 = 1u;
const MODE_FIRST_HIT: u32 = 2u;
const MODE_BRICK_HUE: u32 = 3u;
const MODE_STEPS: u32 = 4u;

// Optical depth beyond which a density ray stops (`vdbcook_trace::OPAQUE_DEPTH`).
const OPAQUE_DEPTH: f32 = 20.0;
// Holder of a span: background, tile, or (any other value) the brick index.
const HOLDER_EMPTY: u32 = 0xffffffffu;
const HOLDER_TILE: u32 = 0xfffffffeu;
// Loop caps: a DDA over a box of n cells per axis takes at most 3n + 3 iterations.
const REGION_ITERS: i32 = 99;
const LEAF_ITERS: i32 = 51;
const VOXEL_ITERS: i32 = 27;

// The visitor state of the walk (one ray per invocation).
var<private> v_density: bool;
var<private> v_per_t: f32;
var<private> v_tau: f32;
var<private> v_steps: u32;
var<private> v_hit: bool;
var<private> v_hit_t: f32;
var<private> v_hit_value: f32;
var<private> v_hit_holder: u32;

// Whether a node, leaf or voxel of max `m` is passed over.
fn vis_skip(m: f32) -> bool {
    if (v_density) {
        return !(m > 0.0);
    }
    return !(m > params.cutoff);
}

// A span [ta, tb] of constant value `v`; true: stop the walk.
fn vis_uniform(ta: f32, tb: f32, v: f32, holder: u32) -> bool {
    if (vis_skip(v)) {
        return false;
    }
    if (v_density) {
        v_tau += v * (tb - ta) * v_per_t;
        return params.absorb * v_tau >= OPAQUE_DEPTH;
    }
    v_hit = true;
    v_hit_t = ta;
    v_hit_value = v;
    v_hit_holder = holder;
    return true;
}

// The hierarchical walk of frame `params.frame_root` along `ray` for t in [t0, t1].
fn walk(ray: VdbRay, t0: f32, t1: f32) {
    let bg = vdb_info.background;
    let dims = vec3<i32>(vdb_info.root_dims);
    var rd = vdb_dda_init(ray, 128.0, vec3<i32>(0), dims, t0, t1);
    for (var ri = 0; ri < REGION_ITERS; ri++) {
        let rs = vdb_dda_next(ray, &rd);
        if (!rs.ok) {
            return;
        }
        v_steps += 1u;
        let e = vdb_root_entry(params.frame_root, rs.cell);
        if (e == VDB_EMPTY) {
            if (vis_uniform(rs.ta, rs.tb, bg, HOLDER_EMPTY)) {
                return;
            }
            continue;
        }
        if ((e & VDB_TILE_BIT) != 0u) {
            if (vis_uniform(rs.ta, rs.tb, vdb_tile(e & ~VDB_TILE_BIT), HOLDER_TILE)) {
                return;
            }
            continue;
        }
        if (vis_skip(vdb_l2_range(e).y)) {
            continue;
        }
        let llo = rs.cell * 16;
        var ld = vdb_dda_init(ray, 8.0, llo, llo + vec3<i32>(16), rs.ta, rs.tb);
        for (var li = 0; li < LEAF_ITERS; li++) {
            let ls = vdb_dda_next(ray, &ld);
            if (!ls.ok) {
                break;
            }
            v_steps += 1u;
            let r = vdb_leaf_ref(e, ls.cell);
            if (r == VDB_EMPTY) {
                if (vis_uniform(ls.ta, ls.tb, bg, HOLDER_EMPTY)) {
                    return;
                }
                continue;
            }
            if ((r & VDB_TILE_BIT) != 0u) {
                if (vis_uniform(ls.ta, ls.tb, vdb_tile(r & ~VDB_TILE_BIT), HOLDER_TILE)) {
                    return;
                }
                continue;
            }
            if (vis_skip(vdb_brick_range(r).y)) {
                continue;
            }
            let origin = ls.cell * 8;
            var vd = vdb_dda_init(ray, 1.0, origin, origin + vec3<i32>(8), ls.ta, ls.tb);
            for (var vi = 0; vi < VOXEL_ITERS; vi++) {
                let vs = vdb_dda_next(ray, &vd);
                if (!vs.ok) {
                    break;
                }
                v_steps += 1u;
                if (vis_uniform(vs.ta, vs.tb, vdb_brick_voxel(r, vs.cell), r)) {
                    return;
                }
            }
        }
    }
}

// hsv(h, s, 1), h in turns (`vdbcook_trace::color::hue`).
fn hue(h: f32, s: f32) -> vec3<f32> {
    let h6 = fract(h) * 6.0;
    let n = vec3<f32>(5.0, 3.0, 1.0);
    let x = (n + vec3<f32>(h6)) % vec3<f32>(6.0);
    let c = clamp(min(x, vec3<f32>(4.0) - x), vec3<f32>(0.0), vec3<f32>(1.0));
    return vec3<f32>(1.0) - s * c;
}

fn brick_color(b: u32) -> vec3<f32> {
    // fract(b · 0.618034) with the integer part split off first, so large indices keep precision.
    let hi = b >> 12u;
    let lo = b & 4095u;
    // 4096 · 0.618034 = 2531.467264.
    let h = fract(f32(hi) * 0.467264) + fract(f32(lo) * 0.618034);
    return hue(h, 0.75);
}

// Black → blue → green → yellow → red at 0, ¼, ½, ¾, 1 (`vdbcook_trace::heat`).
fn heat(x: f32) -> vec3<f32> {
    let s = clamp(x, 0.0, 1.0) * 4.0;
    let i = min(floor(s), 3.0);
    let f = s - i;
    var a: vec3<f32>;
    var b: vec3<f32>;
    if (i < 1.0) {
        a = vec3<f32>(0.0, 0.0, 0.0);
        b = vec3<f32>(0.0, 0.0, 1.0);
    } else if (i < 2.0) {
        a = vec3<f32>(0.0, 0.0, 1.0);
        b = vec3<f32>(0.0, 1.0, 0.0);
    } else if (i < 3.0) {
        a = vec3<f32>(0.0, 1.0, 0.0);
        b = vec3<f32>(1.0, 1.0, 0.0);
    } else {
        a = vec3<f32>(1.0, 1.0, 0.0);
        b = vec3<f32>(1.0, 0.0, 0.0);
    }
    return a + (b - a) * f;
}

// Replaces a non-finite channel by 0 (never expected: a last guard against NaN pixels).
fn finite4(c: vec4<f32>) -> vec4<f32> {
    var o = c;
    for (var i = 0; i < 4; i++) {
        let v = o[i];
        if (!(abs(v) <= 3.0e38)) {
            o[i] = 0.0;
        }
    }
    return o;
}

@compute @workgroup_size(8, 8, 1)
fn trace_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let w = params.width;
    let h = params.height;
    if (gid.x >= w || gid.y >= h) {
        return;
    }
    let x = 2.0 * (f32(gid.x) + 0.5) / f32(w) - 1.0;
    let y = 1.0 - 2.0 * (f32(gid.y) + 0.5) / f32(h);
    let dw = normalize(params.forward.xyz + x * params.right.xyz + y * params.up.xyz);
    var ray: VdbRay;
    ray.o = params.eye_index.xyz;
    ray.d = vec3<f32>(dot(params.inv_a0.xyz, dw), dot(params.inv_a1.xyz, dw), dot(params.inv_a2.xyz, dw));
    ray.per_t = select(1.0, length(ray.d), params.voxel_units != 0u);

    v_density = params.mode == MODE_DENSITY || params.mode == MODE_STEPS;
    v_per_t = ray.per_t;
    v_tau = 0.0;
    v_steps = 0u;
    v_hit = false;

    let clip = vdb_clip(ray, params.extent.xyz);
    if (clip.y > clip.x) {
        walk(ray, clip.x, clip.y);
    }

    var rgba = vec4<f32>(0.0);
    var value = 0.0;
    if (v_density) {
        let t = exp(-params.absorb * v_tau);
        if (params.mode == MODE_DENSITY) {
            rgba = vec4<f32>(vec3<f32>(1.0 - t), 1.0);
            value = t;
        } else {
            rgba = vec4<f32>(heat(f32(v_steps) / 256.0), 1.0);
            value = f32(v_steps);
        }
    } else if (!v_hit) {
        value = -1.0;
    } else if (params.mode == MODE_DEPTH) {
        let g = 1.0 - clamp((v_hit_t - params.near) / (params.far - params.near), 0.0, 1.0);
        rgba = vec4<f32>(vec3<f32>(g), 1.0);
        value = v_hit_t;
    } else if (params.mode == MODE_FIRST_HIT) {
        let g = clamp(v_hit_value / params.value_max, 0.0, 1.0);
        rgba = vec4<f32>(vec3<f32>(g), 1.0);
        value = v_hit_value;
    } else {
        if (v_hit_holder == HOLDER_EMPTY || v_hit_holder == HOLDER_TILE) {
            rgba = vec4<f32>(0.5, 0.5, 0.5, 1.0);
            value = -2.0;
        } else {
            rgba = vec4<f32>(brick_color(v_hit_holder), 1.0);
            value = f32(v_hit_holder);
        }
    }
    rgba = finite4(rgba);
    if (!(abs(value) <= 3.0e38)) {
        value = 0.0;
    }

    if ((params.out_flags & 1u) != 0u) {
        textureStore(out_texture, vec2<i32>(gid.xy), rgba);
    }
    if ((params.out_flags & 2u) != 0u) {
        let p = gid.y * w + gid.x;
        out_buffer[4u * p] = rgba.x;
        out_buffer[4u * p + 1u] = rgba.y;
        out_buffer[4u * p + 2u] = rgba.z;
        out_buffer[4u * p + 3u] = rgba.w;
        out_buffer[4u * w * h + p] = value;
    }
}
