// trace.wgsl — the runtime's tracer: one compute invocation per pixel walks the frame's tree
// (HDDA: 128³ regions → 8³ leaf slots → voxels, skipping by per-node and per-brick max) and
// writes the mode's colour and raw value. It exists so the GPU draws exactly what the CPU
// reference tracer (`crates/trace`, whose crate docs define every mode) draws; the runtime tests
// compare the two images. Concatenated after `volume.wgsl`; `{{TARGET_FORMAT}}` is replaced by
// the storage-texture format the renderer was created for.
//
// Single scatter and delta tracking walk through an iterator (`wk_next`) instead of the visitor
// walk, so that the shadow march (WGSL has no recursion) is a second bounded walk and each march
// is written once. Every loop is bounded (DDA budgets, 2^20 samples per march, 2^16 events per
// path or shadow ray, spp ≤ 2^16). Note for software Vulkan: llvmpipe/lavapipe stops all loops
// of an invocation after 65535 iterations in total (LP_MAX_TGSI_LOOP_ITERATIONS), which cuts
// very heavy pixels (many dense delta paths, tiny steps) short there; hardware has no such cap.
//
// Group 1: `params` (uniform, written once per render: camera, settings, frame).
// Group 2: the target: a storage texture and/or a storage buffer (`out_flags` says which),
//          buffer layout: width·height RGBA (f32 × 4) then width·height raw values.

struct Params {
    // Ray origin (the eye) in cell space (asset index + 1/2: voxel a is the cell [a, a + 1)).
    eye_index: vec4<f32>,
    // Camera basis in world space; right and up scaled by the image-plane half extents.
    forward: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    // Rows of the inverse linear part of index_to_world (world direction → cell direction).
    inv_a0: vec4<f32>,
    inv_a1: vec4<f32>,
    inv_a2: vec4<f32>,
    // xyz: root extent in voxels.
    extent: vec4<f32>,
    // xyz: the frame's content box [lo, hi) in index space (empty: lo > hi); every leaf outside
    // holds values <= 0, which the sampling modes pass over, so they clip their rays to it.
    content_lo: vec4<f32>,
    content_hi: vec4<f32>,
    width: u32,
    height: u32,
    mode: u32,
    frame_root: u32,
    absorb: f32,
    cutoff: f32,
    near: f32,
    far: f32,
    value_max: f32,
    out_flags: u32,
    shadow_step: f32,
    gain: f32,
    spp: u32,
    first_sample: u32,
    // Emission read from this channel of a multi-channel asset (0: from the rendered grid, by
    // each mode's own march; else `channel_emission`, with `shading.emission.w` 0).
    emit_channel: u32,
    _pad0: u32,
    // With `emit_channel`: the cell box [lo, hi) where that channel may glow (empty: lo > hi).
    emit_lo: vec4<f32>,
    emit_hi: vec4<f32>,
    // The lit mode's primary levels of detail (`vdbcook_scene::level_start`): x levels read (1:
    // full resolution only), y the root-offset stride between levels (frames · root length),
    // z the camera's pixel angle (bits of an f32); w 1 for the voxel march (`March::resolve`;
    // `LIT_VOXELS`, the pipeline variant, decides).
    lod: vec4<u32>,
    // The light, the medium's phase and emission, the step and seed (every shaded mode reads
    // them; `lit.wgsl`), and the one volume's placement: extinction and albedo (every shaded
    // mode), the index-space direction toward the light, the lit mode's light volume.
    shading: VdbShading,
    place: VdbLitPlace,
}

@group(1) @binding(0) var<uniform> params: Params;
@group(2) @binding(0) var out_texture: texture_storage_2d<{{TARGET_FORMAT}}, write>;
@group(2) @binding(1) var<storage, read_write> out_buffer: array<f32>;
// Group 3: the lit mode's light volume (`lit.wgsl`'s `lit_tau` and `lit_ms`).

// Whether this pipeline draws emission (`Renderer::new` compiles it out unless asked).
const TRACE_EMISSION: bool = {{EMISSION}};
// Whether this pipeline reads trilinear density in the lit mode (a variant the renderer makes on
// the first render that asks; the nearest-voxel march does not carry its code).
const LIT_TRILINEAR: bool = {{TRILINEAR}};
// Whether the lit march can walk the near field toward the sun, and march voxels
// (`runtime/src/render.rs`'s `LitVariant`: lavapipe pays for code that is present).
const LIT_NEAR: bool = {{LIT_NEAR}};
const LIT_VOXELS: bool = {{LIT_VOXELS}};

const MODE_DENSITY: u32 = 0u;
const MODE_DEPTH: u32 = 1u;
const MODE_FIRST_HIT: u32 = 2u;
const MODE_BRICK_HUE: u32 = 3u;
const MODE_STEPS: u32 = 4u;
const MODE_SCATTER: u32 = 5u;
const MODE_DELTA: u32 = 6u;
const MODE_LIT: u32 = 7u;

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
var<private> v_emit: vec3<f32>;
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

// Emission from channel `params.emit_channel` along `ray` up to `t_end` (`lit.wgsl`'s
// `lit_channel_emission` over the channel's box of this frame).
fn channel_emission(ray: VdbRay, ext: f32, t_end: f32) -> vec3<f32> {
    return lit_channel_emission(params.frame_root, ray, ext, t_end, params.emit_channel,
        params.emit_lo.xyz, params.emit_hi.xyz);
}

// A span [ta, tb] of constant value `v`; true: stop the walk.
fn vis_uniform(ta: f32, tb: f32, v: f32, holder: u32) -> bool {
    if (vis_skip(v)) {
        return false;
    }
    if (v_density) {
        if (TRACE_EMISSION && params.shading.emission.w != 0.0) {
            // Emitted light reaching the eye: T_before · E(v) · ℓ · (1 − e^{−x})/x, x = absorb·v·ℓ.
            let r = lit_emission(v);
            if (any(r != vec3<f32>(0.0))) {
                let len = (tb - ta) * v_per_t;
                let x = params.absorb * v * len;
                v_emit += exp(-params.absorb * v_tau) * len * lv_phi(x, exp(-x)) * r;
            }
        }
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
    let bg = vdb_background();
    let dims = vec3<i32>(vdb_root_dims());
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

// ---- The media modes (single scatter, delta tracking) ----------------------------------------
// WGSL has no recursion and inlining a visitor at every call site of the walk would multiply the
// shader, so these modes walk the tree through an iterator (`wk_next`) that yields the spans a
// visitor would see (`voxels()` false: constant spans, and bricks handed over whole), with the
// CPU walk's skip rule `!(m >= lo && m > 0)` (single scatter: lo = cutoff; delta: lo = −BIG).
// The primary march and its shadow march are two separate bounded loops over two walkers.

// A brick's span has `brick` = its index; a constant span has NO_BRICK and value `v`.
const NO_BRICK: u32 = 0xffffffffu;
// Most samples one single-scatter march takes (`vdbcook_trace::MAX_MARCH_SAMPLES`).
const MAX_MARCH_SAMPLES: u32 = 1048576u;
// Most tentative collisions per delta path or shadow ray (`vdbcook_trace::MAX_EVENTS`).
const MAX_EVENTS: u32 = 65536u;
// Shadow weight below which ratio tracking stops (`vdbcook_trace::MIN_SHADOW_WEIGHT`).
const MIN_SHADOW_WEIGHT: f32 = 1e-6;
// Spans one walk can yield: every span takes at least one region or leaf DDA step.
const WALK_SPANS: i32 = 5148; // REGION_ITERS · (LEAF_ITERS + 1)

struct Walker {
    rd: VdbDda,
    ld: VdbDda,
    node: u32,
    in_node: bool,
    // The root set walked (`params.frame_root` unless a level of detail is asked for).
    root: u32,
}

struct WkSpan {
    ok: bool,
    ta: f32,
    tb: f32,
    // The constant value (constant span) or the brick max.
    m: f32,
    brick: u32,
    origin: vec3<i32>,
}

fn wk_init(ray: VdbRay, t0: f32, t1: f32) -> Walker {
    var w: Walker;
    w.rd = vdb_dda_init(ray, 128.0, vec3<i32>(0), vec3<i32>(vdb_root_dims()), t0, t1);
    w.ld = w.rd;
    w.ld.budget = 0;
    w.node = 0u;
    w.in_node = false;
    w.root = params.frame_root;
    return w;
}

fn wk_skip(m: f32, lo: f32) -> bool {
    return !(m >= lo && m > 0.0);
}

fn wk_const(ta: f32, tb: f32, v: f32) -> WkSpan {
    var o: WkSpan;
    o.ok = true;
    o.ta = ta;
    o.tb = tb;
    o.m = v;
    o.brick = NO_BRICK;
    o.origin = vec3<i32>(0);
    return o;
}

// The next span not passed over (`ok` false when the walk is over).
fn wk_next(ray: VdbRay, w: ptr<function, Walker>, lo: f32) -> WkSpan {
    var out: WkSpan;
    out.ok = false;
    let bg = vdb_background();
    for (var g = 0; g < WALK_SPANS; g++) {
        if ((*w).in_node) {
            var ld = (*w).ld;
            let ls = vdb_dda_next(ray, &ld);
            (*w).ld = ld;
            if (!ls.ok) {
                (*w).in_node = false;
                continue;
            }
            let r = vdb_leaf_ref((*w).node, ls.cell);
            if (r == VDB_EMPTY) {
                if (wk_skip(bg, lo)) {
                    continue;
                }
                return wk_const(ls.ta, ls.tb, bg);
            }
            if ((r & VDB_TILE_BIT) != 0u) {
                let v = vdb_tile(r & ~VDB_TILE_BIT);
                if (wk_skip(v, lo)) {
                    continue;
                }
                return wk_const(ls.ta, ls.tb, v);
            }
            let m = vdb_brick_range(r).y;
            if (wk_skip(m, lo)) {
                continue;
            }
            out = wk_const(ls.ta, ls.tb, m);
            out.brick = r;
            out.origin = ls.cell * 8;
            return out;
        }
        var rd = (*w).rd;
        let rs = vdb_dda_next(ray, &rd);
        (*w).rd = rd;
        if (!rs.ok) {
            return out;
        }
        let e = vdb_root_entry((*w).root, rs.cell);
        if (e == VDB_EMPTY) {
            if (wk_skip(bg, lo)) {
                continue;
            }
            return wk_const(rs.ta, rs.tb, bg);
        }
        if ((e & VDB_TILE_BIT) != 0u) {
            let v = vdb_tile(e & ~VDB_TILE_BIT);
            if (wk_skip(v, lo)) {
                continue;
            }
            return wk_const(rs.ta, rs.tb, v);
        }
        if (wk_skip(vdb_l2_range(e).y, lo)) {
            continue;
        }
        let llo = rs.cell * 16;
        (*w).ld = vdb_dda_init(ray, 8.0, llo, llo + vec3<i32>(16), rs.ta, rs.tb);
        (*w).node = e;
        (*w).in_node = true;
    }
    return out;
}

// The value of a span at index point `p` (`walk::brick_value`: clamped into the brick).
fn wk_value(sp: WkSpan, p: vec3<f32>) -> f32 {
    if (sp.brick == NO_BRICK) {
        return sp.m;
    }
    let c = clamp(vec3<i32>(floor(p)) - sp.origin, vec3<i32>(0), vec3<i32>(7));
    return vdb_brick_voxel(sp.brick, c);
}

// `ray`'s t range inside both the root extent and the frame's content box (the CPU tracer's
// coarse walk for visitors that pass over values <= 0).
fn media_clip(ray: VdbRay) -> vec2<f32> {
    let a = vdb_clip(ray, params.extent.xyz);
    let b = vdb_clip_box(ray, params.content_lo.xyz, params.content_hi.xyz);
    return vec2<f32>(max(a.x, b.x), min(a.y, b.y));
}

fn light_ray(p: vec3<f32>) -> VdbRay {
    var r: VdbRay;
    r.o = p;
    r.d = params.place.sun_cell.xyz;
    r.per_t = select(1.0, length(r.d), params.shading.voxel_units != 0u);
    return r;
}

// `vdb_render`'s shadow march from index point `p` toward the light: transmittance.
fn shadow_march(p: vec3<f32>) -> f32 {
    let ray = light_ray(p);
    let clip = media_clip(ray);
    if (!(clip.y > clip.x)) {
        return 1.0;
    }
    let step = params.shadow_step;
    let cutoff = params.cutoff;
    var w = wk_init(ray, clip.x, clip.y);
    var budget = MAX_MARCH_SAMPLES;
    var trans = 1.0;
    for (var g = 0; g < WALK_SPANS; g++) {
        let sp = wk_next(ray, &w, cutoff);
        if (!sp.ok) {
            break;
        }
        let sb = sp.tb * ray.per_t;
        var k = max(ceil(sp.ta * ray.per_t / step), 1.0);
        var stop = false;
        for (var n = 0u; n <= MAX_MARCH_SAMPLES; n++) {
            if (!(k * step < sb)) {
                break;
            }
            if (budget == 0u) {
                stop = true;
                break;
            }
            budget -= 1u;
            let s = k * step;
            k += 1.0;
            let d = wk_value(sp, ray.o + (s / ray.per_t) * ray.d);
            if (d < cutoff || d <= 0.0) {
                continue;
            }
            trans *= exp(-params.place.sun_cell.w * d * step / (1.0 + s * params.gain));
            if (3.0 * trans * trans < cutoff) {
                stop = true;
                break;
            }
        }
        if (stop) {
            break;
        }
    }
    return trans;
}

// Single scatter along the primary ray for t in [t0, t1]: (luminance, transmittance).
fn scatter_primary(ray: VdbRay, t0: f32, t1: f32) -> vec2<f32> {
    let step = params.shading.sun.w;
    let cutoff = params.cutoff;
    var w = wk_init(ray, t0, t1);
    var budget = MAX_MARCH_SAMPLES;
    var trans = 1.0;
    var lum = 0.0;
    for (var g = 0; g < WALK_SPANS; g++) {
        let sp = wk_next(ray, &w, cutoff);
        if (!sp.ok) {
            break;
        }
        let sb = sp.tb * ray.per_t;
        var k = max(ceil(sp.ta * ray.per_t / step), 0.0);
        var stop = false;
        for (var n = 0u; n <= MAX_MARCH_SAMPLES; n++) {
            if (!(k * step < sb)) {
                break;
            }
            if (budget == 0u) {
                stop = true;
                break;
            }
            budget -= 1u;
            let s = k * step;
            k += 1.0;
            let p = ray.o + (s / ray.per_t) * ray.d;
            let sigma = wk_value(sp, p);
            if (sigma < cutoff || sigma <= 0.0) {
                continue;
            }
            let x = params.place.sun_cell.w * sigma * step;
            let dt = exp(-x);
            if (TRACE_EMISSION && params.shading.emission.w != 0.0) {
                // Emission over the step, absorbed as the step attenuates: T · E · step · φ(x).
                v_emit += trans * step * lv_phi(x, dt) * lit_emission(sigma);
            }
            let ts = shadow_march(p);
            lum += params.place.axis.w * ts * trans * (1.0 - dt);
            trans *= dt;
            if (3.0 * trans * trans < cutoff) {
                stop = true;
                break;
            }
        }
        if (stop) {
            break;
        }
    }
    return vec2<f32>(lum, trans);
}

// ---- The lit mode (`vdbcook_trace`'s `lit` module) -----------------------------------------

// `vdbcook_scene::level_start`: where level k begins along a ray whose pixel spans `grow`
// voxels per unit of t.
fn lod_start(k: u32, grow: f32) -> f32 {
    if (k == 0u) {
        return 0.0;
    }
    if (grow > 0.0) {
        return f32(1u << min(k, 31u)) / grow;
    }
    return VDB_BIG;
}

// The leaf (8³ cell) and holder of the span the lit march is in when it is a brick of the
// full-resolution frame (else leaf −1): the near field's walks start there without a descent
// (10% of the lit march on the WDAS cloud with the lean DDA, lavapipe; a second entry for the
// leaf the last walk ended in measured slower).
var<private> lit_hint_leaf: vec3<i32>;
var<private> lit_hint_ref: u32;

// One lit march's state: radiance, transmittance, whether it stopped, samples left, the
// sun's phase per octave at the ray's μ, the direction toward the eye in the diffusion's
// metric.
struct LitState {
    rad: vec3<f32>,
    trans: f32,
    stop: bool,
    budget: u32,
    ph: array<f32, 8>,
    eye: vec3<f32>,
    // The last walked segment's end, the sun's depth there and 0 (−1 for none):
    // `lit_scattered`'s `exit`.
    exit: vec3<f32>,
}

// `LitMarch::light`: the segment of `ray` from length `sa` over `len` of optical depth `x`
// (mean density `rho`), the source read at its mean scattering depth (`lit_scattered`).
fn lit_light(st: ptr<function, LitState>, ray: VdbRay, sa: f32, len: f32, x: f32, rho: f32) {
    if ((*st).budget == 0u) {
        (*st).stop = true;
        return;
    }
    (*st).budget -= 1u;
    let e = exp(-x);
    let trans = (*st).trans;
    let md = lv_mean_depth(x, e);
    let q = ray.o + ((sa + len * md) / ray.per_t) * ray.d;
    var ph = (*st).ph;
    var exit = (*st).exit;
    let src = lit_scattered(params.place, ray, sa, len, q, rho, trans, (*st).eye, &ph, vec3<f32>(x, e, md), lit_hint_leaf, lit_hint_ref, &exit, 0.0);
    (*st).exit = exit;
    (*st).rad += trans * params.place.axis.w * (1.0 - e) * src;
    (*st).trans = trans * e;
    if ((*st).trans < LV_MIN_TRANS) {
        (*st).stop = true;
    }
}

// `LitMarch::add`: the segment's emission (at transmittance `trans`), then its light.
fn lit_add(st: ptr<function, LitState>, ray: VdbRay, sa: f32, len: f32, rho: f32) {
    let x = params.place.sun_cell.w * rho * len;
    if (TRACE_EMISSION && params.shading.emission.w != 0.0) {
        v_emit += (*st).trans * len * lv_phi(x, exp(-x)) * lit_emission(rho);
    }
    lit_light(st, ray, sa, len, x, rho);
}

// `VoxelMarch::span`: a constant span [ta, tb] of value `v`, cut into equal segments of at
// most `step` (`lit::segments`).
fn lit_span(st: ptr<function, LitState>, ray: VdbRay, ta: f32, tb: f32, v: f32, step: f32) {
    if (!(v > 0.0)) {
        return;
    }
    let all = (tb - ta) * ray.per_t;
    let n = max(ceil(all / step - 1e-3), 1.0);
    let len = all / n;
    for (var j = 0u; j < MAX_MARCH_SAMPLES; j++) {
        if (f32(j) >= n || (*st).stop) {
            return;
        }
        lit_add(st, ray, ta * ray.per_t + f32(j) * len, len, v);
    }
}

// The lit march for t in [t0, t1] (the ray's clip to the root extent): (radiance rgb,
// transmittance). `dw`: the unit world direction. Level k of detail (`params.lod`) is walked
// over [t_k, t_{k+1}) in its cell space (full resolution's scaled by 2^-k, exact in binary),
// clipped to the frame's content box widened to that level's leaves, stepping `step·2^k`.
// `LIT_VOXELS` (the pipeline variant): the voxel march (`March::Voxels`: each brick's voxels by a DDA, constant
// spans whole, `lit_span`); else samples every step, jittered.
fn lit_primary(ray: VdbRay, dw: vec3<f32>, t0: f32, t1: f32, pixel: u32) -> vec4<f32> {
    // The phase per octave at this ray's μ, the sky's (isotropic: 1).
    var st: LitState;
    st.ph = lit_sun_phases(dw);
    st.rad = vec3<f32>(0.0);
    st.trans = 1.0;
    st.stop = false;
    st.budget = MAX_MARCH_SAMPLES;
    st.eye = lv_eye_dir(ray.d, params.place.axis.xyz);
    st.exit = vec3<f32>(0.0, 0.0, -1.0);
    let jitter = lv_jitter(params.shading.seed, pixel);
    let levels = max(params.lod.x, 1u);
    let grow = bitcast<f32>(params.lod.z) * length(ray.d);
    // The pipeline variant decides (`params.lod.w` says the same): the other march compiles out.
    let voxels = LIT_VOXELS;
    for (var lvl = 0u; lvl < levels; lvl++) {
        if (st.stop) {
            break;
        }
        let scale = 1.0 / f32(1u << lvl);
        var lray = ray;
        lray.o = ray.o * scale;
        lray.d = ray.d * scale;
        // The content box in the level's cell space, out to whole leaves of the level.
        var clo = params.content_lo.xyz;
        var chi = params.content_hi.xyz;
        if (lvl > 0u) {
            clo = floor(clo * (scale / 8.0)) * 8.0;
            chi = ceil(chi * (scale / 8.0)) * 8.0;
        }
        let cb = vdb_clip_box(lray, clo, chi);
        var a = max(t0, cb.x);
        var b = min(t1, cb.y);
        a = max(a, lod_start(lvl, grow));
        if (lvl + 1u < levels) {
            b = min(b, lod_start(lvl + 1u, grow));
        }
        if (!(b > a)) {
            continue;
        }
        let root = params.frame_root + lvl * params.lod.y;
        let step = params.shading.sun.w / scale;
        var w = wk_init(lray, a, b);
        w.root = root;
        for (var g = 0; g < WALK_SPANS; g++) {
            let sp = wk_next(lray, &w, -3.0e38);
            if (!sp.ok || st.stop) {
                break;
            }
            lit_hint_leaf = vec3<i32>(-1);
            lit_hint_ref = VDB_EMPTY;
            if (lvl == 0u && sp.brick != NO_BRICK) {
                lit_hint_leaf = sp.origin >> vec3<u32>(3u);
                lit_hint_ref = sp.brick;
            }
            if (voxels) {
                // A constant span whole, or a brick's voxels by a DDA: one `lit_span` call site
                // (lavapipe inlines each one, and the lit march's light is large).
                let in_brick = sp.brick != NO_BRICK;
                var vd: VdbDda;
                if (in_brick) {
                    vd = vdb_dda_init(lray, 1.0, sp.origin, sp.origin + vec3<i32>(8), sp.ta, sp.tb);
                }
                for (var vi = 0; vi <= VOXEL_ITERS; vi++) {
                    var ta = sp.ta;
                    var tb = sp.tb;
                    var v = sp.m;
                    if (in_brick) {
                        let vs = vdb_dda_next(lray, &vd);
                        if (!vs.ok) {
                            break;
                        }
                        ta = vs.ta;
                        tb = vs.tb;
                        v = vdb_brick_voxel(sp.brick, vs.cell);
                    } else if (vi > 0) {
                        break;
                    }
                    if (st.stop) {
                        break;
                    }
                    lit_span(&st, ray, ta, tb, v, step);
                }
                continue;
            }
            let sb = sp.tb * ray.per_t;
            var k = max(ceil(sp.ta * ray.per_t / step - jitter), 0.0);
            for (var n = 0u; n <= MAX_MARCH_SAMPLES; n++) {
                let s = (k + jitter) * step;
                if (!(s < sb) || st.stop) {
                    break;
                }
                k += 1.0;
                let p = lray.o + (s / ray.per_t) * lray.d;
                var rho = 0.0;
                if (LIT_TRILINEAR && lit_trilinear_on()) {
                    // Eight descents, not the span's brick read where the taps lie in it: a
                    // SIMD group pays for both sides of that branch (+9% on lavapipe, 2026-12-07).
                    rho = vdb_trilinear(root, p);
                } else {
                    rho = wk_value(sp, p);
                }
                if (!(rho > 0.0)) {
                    continue;
                }
                lit_add(&st, ray, s - 0.5 * step, step, rho);
            }
        }
    }
    return vec4<f32>(st.rad, st.trans);
}


// `Rng::uniform`: the next number of the stream in `state`, in [0, 1), 24 bits.
fn rng_uniform(state: ptr<function, u32>) -> f32 {
    *state = *state * 747796405u + 2891336453u;
    let s = *state;
    let word = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    return f32(((word >> 22u) ^ word) >> 8u) * (1.0 / 16777216.0);
}

// Ratio tracking from index point `p` toward the light: the shadow weight.
fn ratio_shadow(p: vec3<f32>, rng: ptr<function, u32>) -> f32 {
    let ray = light_ray(p);
    let clip = media_clip(ray);
    if (!(clip.y > clip.x)) {
        return 1.0;
    }
    let ext = params.place.sun_cell.w;
    var w = wk_init(ray, clip.x, clip.y);
    var events = MAX_EVENTS;
    var weight = 1.0;
    for (var g = 0; g < WALK_SPANS; g++) {
        let sp = wk_next(ray, &w, -VDB_BIG);
        if (!sp.ok) {
            break;
        }
        let mu_bar = ext * sp.m;
        if (!(mu_bar > 0.0)) {
            continue;
        }
        var s = sp.ta * ray.per_t;
        let sb = sp.tb * ray.per_t;
        var stop = false;
        for (var n = 0u; n <= MAX_EVENTS; n++) {
            if (events == 0u) {
                stop = true;
                break;
            }
            events -= 1u;
            s -= log(1.0 - rng_uniform(rng)) / mu_bar;
            if (!(s < sb)) {
                break;
            }
            let v = max(wk_value(sp, ray.o + (s / ray.per_t) * ray.d), 0.0);
            let mu = ext * v / (1.0 + params.gain * s);
            weight *= 1.0 - mu / mu_bar;
            if (weight < MIN_SHADOW_WEIGHT) {
                weight = 0.0;
                stop = true;
                break;
            }
        }
        if (stop) {
            break;
        }
    }
    return weight;
}

// One delta-tracking path along the primary ray: (light scored, escaped 0 or 1); `v_hit_t` is
// set to where the flight ended (`VDB_BIG` if it escaped).
fn delta_path(ray: VdbRay, t0: f32, t1: f32, rng: ptr<function, u32>) -> vec2<f32> {
    let ext = params.place.sun_cell.w;
    v_hit_t = VDB_BIG;
    var w = wk_init(ray, t0, t1);
    var events = MAX_EVENTS;
    var lum = 0.0;
    // One exit at the end (no return from inside the loops).
    var escaped = 1.0;
    for (var g = 0; g < WALK_SPANS; g++) {
        let sp = wk_next(ray, &w, -VDB_BIG);
        if (!sp.ok) {
            break;
        }
        let base = ext * sp.m;
        // Emission (`vdbcook_trace`'s delta `Path`): the majorant at least 1/step where the span
        // can emit, `E / μ̄` gathered at each tentative collision.
        let emits = TRACE_EMISSION && params.shading.emission.w != 0.0 && sp.m > params.shading.emission.x;
        var mu_bar = base;
        if (emits) {
            mu_bar = max(base, 1.0 / params.shading.sun.w);
        }
        let boosted = mu_bar != base;
        if (!(mu_bar > 0.0)) {
            continue;
        }
        var s = sp.ta * ray.per_t;
        let sb = sp.tb * ray.per_t;
        for (var n = 0u; n <= MAX_EVENTS; n++) {
            if (events == 0u) {
                // Out of events: absorbed.
                escaped = 0.0;
                break;
            }
            events -= 1u;
            s -= log(1.0 - rng_uniform(rng)) / mu_bar;
            if (!(s < sb)) {
                break;
            }
            let p = ray.o + (s / ray.per_t) * ray.d;
            let v = wk_value(sp, p);
            let sigma = max(v, 0.0);
            if (emits) {
                v_emit += lit_emission(v) / mu_bar;
            }
            var null_collision: bool;
            if (boosted) {
                null_collision = rng_uniform(rng) * mu_bar >= ext * sigma;
            } else {
                null_collision = rng_uniform(rng) * sp.m >= sigma;
            }
            if (null_collision) {
                continue; // null collision
            }
            escaped = 0.0;
            if (rng_uniform(rng) < params.place.axis.w) {
                lum = ratio_shadow(p, rng);
            }
            break;
        }
        if (escaped == 0.0) {
            v_hit_t = s / ray.per_t;
            break;
        }
    }
    return vec2<f32>(lum, escaped);
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
    ray.per_t = select(1.0, length(ray.d), params.shading.voxel_units != 0u);

    v_density = params.mode == MODE_DENSITY || params.mode == MODE_STEPS;
    v_per_t = ray.per_t;
    v_tau = 0.0;
    v_emit = vec3<f32>(0.0);
    v_steps = 0u;
    v_hit = false;

    let clip = vdb_clip(ray, params.extent.xyz);
    let media = params.mode == MODE_SCATTER || params.mode == MODE_DELTA || params.mode == MODE_LIT;
    if (clip.y > clip.x && !media) {
        walk(ray, clip.x, clip.y);
    }

    var rgba = vec4<f32>(0.0);
    var value = 0.0;
    if (media) {
        // (luminance, transmittance); a ray missing the root box or the content: (0, 1).
        var lt = vec2<f32>(0.0, 1.0);
        var lit = vec3<f32>(0.0);
        let mclip = media_clip(ray);
        if (params.mode == MODE_LIT) {
            // Clipped per level of detail to that level's content box.
            if (clip.y > clip.x) {
                let r = lit_primary(ray, dw, clip.x, clip.y, gid.y * w + gid.x);
                lit = r.xyz;
                lt = vec2<f32>(0.0, r.w);
            }
        } else if (mclip.y > mclip.x) {
            if (params.mode == MODE_SCATTER) {
                lt = scatter_primary(ray, mclip.x, mclip.y);
            } else {
                let pixel = gid.y * w + gid.x;
                var lum = 0.0;
                var escaped = 0.0;
                for (var k = 0u; k < params.spp; k++) {
                    let si = params.first_sample + k;
                    var rng = pcg_hash(params.shading.seed ^ pcg_hash(pixel ^ pcg_hash(si)));
                    let r = delta_path(ray, mclip.x, mclip.y, &rng);
                    lum += r.x;
                    escaped += r.y;
                    if (TRACE_EMISSION && params.emit_channel != 0u) {
                        // Another channel's emission: the track-length estimator of the flight.
                        v_emit += channel_emission(ray, 0.0, v_hit_t);
                    }
                }
                let n = f32(params.spp);
                lt = vec2<f32>(lum / n, escaped / n);
                v_emit /= n;
            }
        } else if (params.mode == MODE_DELTA && TRACE_EMISSION && params.emit_channel != 0u) {
            // No medium on the ray: every flight escapes.
            v_emit = channel_emission(ray, 0.0, VDB_BIG);
        }
        rgba = vec4<f32>(params.shading.sun_color.xyz * lt.x + lit + v_emit, 1.0 - lt.y);
        value = lt.y;
    } else if (v_density) {
        let t = exp(-params.absorb * v_tau);
        if (params.mode == MODE_DENSITY) {
            rgba = vec4<f32>(vec3<f32>(1.0 - t) + v_emit, 1.0);
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
    if (TRACE_EMISSION && params.emit_channel != 0u) {
        if (params.mode == MODE_DENSITY) {
            rgba += vec4<f32>(channel_emission(ray, params.absorb, VDB_BIG), 0.0);
        } else if (params.mode == MODE_SCATTER || params.mode == MODE_LIT) {
            rgba += vec4<f32>(channel_emission(ray, params.place.sun_cell.w, VDB_BIG), 0.0);
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
