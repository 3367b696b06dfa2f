// draw.wgsl — the engine drawer (`vdbcook_runtime::VolumeDrawer`): it exists so that volumes can
// be drawn into an engine's own frame — its view and projection, its depth buffer, its colour
// target — rather than into an image of their own. Two entry points:
//
// - `draw_main` (compute, one invocation per pixel): unprojects the pixel centre (+ jitter)
//   through the engine's projection, cuts the ray at the engine's depth (a `Depth32Float`
//   texture, standard or reversed Z, `textureLoad`), and marches every instance of the volume
//   with the density march (`vdb_optical_depth` in `volume.wgsl`: the CPU tracer's Density mode),
//   front to back in the order the CPU sorted them — or, where instances' bounds overlap
//   (`DRAW_INTERLEAVE`), interleaved along the ray (`draw_pieces`) — writing premultiplied radiance and
//   transmittance (L, T) to an `Rgba16Float` storage texture. With lighting (`DRAW_LIT`, a
//   pipeline variant) each lit instance is marched as the tracer's lit mode (`lit_primary` in
//   `trace.wgsl`, the CPU's `lit` module): samples on the same grid, density by nearest or
//   trilinear lookup, sun and sky from the instance's light volumes (group 2, built by
//   `light_build.wgsl` in the instance's cell space), the near field toward the sun walked
//   (`LIT_NEAR`). A crossfade lerps both frames' density, depths and light (`LitCrossfade::Lerp`,
//   the default: each frame's walk gated on the lerped density and the one transmittance; the
//   CPU draws single frames only) or takes each sample, density and light, from one of its
//   frames (`Dither`).
// - `draw_half_main` (compute, one invocation per 2×2 or 4×4 block of pixels; `MarchResolution`
//   `Half`/`Quarter`): marches the block's centre ray where no scene depth of the block cuts the
//   instances' boxes, into a per-block (L, T) texture that `draw_main` then upsamples
//   bilinearly, marching at full resolution the pixels next to a block it left (a depth edge).
// The composite that blends (L, T) over the engine's colour target is `composite.wgsl`.
//
// Concatenated after `volume.wgsl`, `light.wgsl` and `lit.wgsl` (group 0: the volume). Group 1: the view
// (uniform), the instances (storage), the scene depth, the (L, T) output, the per-block (L, T)
// written (4) and read (5). Group 2: the light
// volumes, (τ_sun, τ_sky) per cell, each instance's at its own base elements, and (binding 1)
// the diffusion model's light, six words per cell at 6·(base + cell). The structs mirror `runtime/src/
// draw.rs` (`DrawView`, `DrawInstance`; sizes checked by its unit tests and by the bindings'
// minimum sizes).

struct DrawView {
    // Inverse projection: clip → view space (eye-relative, so no large translation is involved).
    view_from_clip: mat4x4<f32>,
    // Inverse view: view space → world (translation: the eye).
    world_from_view: mat4x4<f32>,
    // xyz: the unit view-space direction of every ray (orthographic); w: 1 perspective, 0 ortho.
    forward: vec4<f32>,
    viewport: vec2<u32>,
    // In pixels, added to the pixel centre.
    jitter: vec2<f32>,
    // NDC depth of the near plane (0 standard, 1 reversed Z): where orthographic rays start.
    near_ndc: f32,
    instance_count: u32,
    has_depth: u32,
    // The channel whose emission the voxel-exact emission pass draws (`lit_channel_emission`;
    // the pass runs in the `DRAW_EMIT` variant: flat draws with any emission, lit ones with
    // emission from another channel than the density, as the lit march glows its own).
    emit_channel: u32,
    // The pixel of the dispatch's first invocation: the dispatch covers only the pixels the
    // instances can reach (`PreparedDraw::covered`).
    origin: vec2<u32>,
    // The reduced-resolution march (`MarchResolution::Half`, `Quarter`): its blocks [half_lo,
    // half_hi) of `block`² pixels (block b: pixels [block·b, block·b + block) on each axis);
    // `block` 0: it did not run.
    half_lo: vec2<u32>,
    half_hi: vec2<u32>,
    block: u32,
    _pad: u32,
    // The light, phase, emission, step and seed (`lit.wgsl`; the renderer's packing too).
    shading: VdbShading,
}

struct DrawInstance {
    // Rows of the 3×4 map world → cell space of this instance (cell = index + ½).
    cell_from_world0: vec4<f32>,
    cell_from_world1: vec4<f32>,
    cell_from_world2: vec4<f32>,
    // xyz: the tint; w: absorb · density scale.
    tint_absorb: vec4<f32>,
    // xyz: the cell-space box the ray is clipped to (the frames' content boxes); w: crossfade
    // weight a of the second frame.
    box_lo: vec4<f32>,
    box_hi: vec4<f32>,
    // The cell-space box where the emission channel may glow (both frames; empty: lo > hi).
    emit_lo: vec4<f32>,
    emit_hi: vec4<f32>,
    // Root offsets (frame · root_len) of frames floor(time) and floor(time) + 1.
    frame_root0: u32,
    frame_root1: u32,
    // 1: marched lit (`place` holds its light volumes), 0: the flat density march.
    lit: u32,
    // The instance's asset in the volume set (`vdb_select`).
    asset: u32,
    // The lit march's medium and light volumes in the instance's cell space (`lit.wgsl`).
    place: VdbLitPlace,
}

@group(1) @binding(0) var<uniform> draw_view: DrawView;
@group(1) @binding(1) var<storage, read> draw_instances: array<DrawInstance>;
@group(1) @binding(2) var draw_depth: texture_depth_2d;
@group(1) @binding(3) var draw_out: texture_storage_2d<rgba16float, write>;
// The reduced-resolution march's (L, T) per block: written by `draw_half_main` (binding 4), read by
// `draw_main` (binding 5); a 1×1 stand-in at the other binding. T < 0: not marched (a depth
// edge in the block).
@group(1) @binding(4) var draw_half_out: texture_storage_2d<rgba16float, write>;
@group(1) @binding(5) var draw_half_in: texture_2d<f32>;
// Group 2: the light volumes (`lit.wgsl`'s `lit_tau` and `lit_ms`).

// Whether this pipeline marches lit instances (the flat pipeline compiles the lit march out).
const DRAW_LIT: bool = {{DRAW_LIT}};
// Whether instances may overlap along a ray, so that the march interleaves them (a pipeline
// variant: the sweep costs about twice the plain march on software Vulkan).
const DRAW_INTERLEAVE: bool = {{DRAW_INTERLEAVE}};
// Whether the draw has an emission pass (a pipeline variant: `Variant::emit`).
const DRAW_EMIT: bool = {{DRAW_EMIT}};
// Whether the lit march reads trilinear density (a pipeline variant).
const DRAW_TRILINEAR: bool = {{DRAW_TRILINEAR}};
// Whether the lit march can walk the near field toward the sun (`Lighting::sun_near` > 0;
// `lit.wgsl` reads it).
const LIT_NEAR: bool = {{LIT_NEAR}};
// Most samples of one lit instance march (`vdbcook_trace::MAX_MARCH_SAMPLES`).
const DRAW_MAX_SAMPLES: u32 = 1048576u;

// The lit march's density of one frame at cell-space point `p`: the nearest voxel (≥ 0), or
// trilinear inside leaves the tracer's walk visits (bound > 0), as its lit march reads it.
fn draw_density(frame_root: u32, p: vec3<f32>) -> f32 {
    let cell = vec3<i32>(floor(p));
    if (DRAW_TRILINEAR && lit_trilinear_on()) {
        if (vdb_leaf_bound(frame_root, cell) > 0.0) {
            return vdb_trilinear(frame_root, p);
        }
        return 0.0;
    }
    return max(vdb_value(frame_root, cell), 0.0);
}

// The lit march of one instance for t in [t0, t1]: (radiance before the tint, transmittance).
// Samples on the tracer's jittered grid; the light of each from `lit_scattered`.
fn draw_lit(inst: DrawInstance, ray: VdbRay, t0: f32, t1: f32, dw: vec3<f32>, pixel: u32) -> vec4<f32> {
    let step = draw_view.shading.sun.w;
    var sun_ph = lit_sun_phases(dw);
    let jitter = lv_jitter(draw_view.shading.seed, pixel);
    let place = inst.place;
    let ext = place.sun_cell.w;
    let a = inst.box_lo.w;
    // Toward the eye in the diffusion's metric.
    let eye = lv_eye_dir(ray.d, place.axis.xyz);
    let sb = t1 * ray.per_t;
    var k = max(ceil(t0 * ray.per_t / step - jitter), 0.0);
    var trans = 1.0;
    var rad = vec3<f32>(0.0);
    // The last walked segment's end, depth and frame (`lit_scattered`).
    var exit = vec3<f32>(0.0, 0.0, -1.0);
    // `LitCrossfade::Dither`: sample k is frame 1's (density and light) where
    // fract(u + k·φ⁻¹) < a (a golden-ratio sequence from a second per-pixel offset: a fraction a
    // of the ray's samples, spread evenly along it), frame 0's elsewhere; the place then names
    // that frame alone. (At half and quarter resolution `pixel` is the block's: its grain is
    // upsampled with it.)
    let dither = a > 0.0 && place.misc.z != 0.0;
    let u = lv_jitter(draw_view.shading.seed ^ 0x9e3779b9u, pixel);
    for (var n = 0u; n < DRAW_MAX_SAMPLES; n++) {
        let s = (k + jitter) * step;
        if (!(s < sb)) {
            break;
        }
        // k·φ⁻¹ mod 1 in integers (2654435769 = 2³²/φ), exact however far the ray starts.
        let kf = f32((u32(k) * 2654435769u) >> 8u) / 16777216.0;
        let one = dither && fract(u + kf) < a;
        k += 1.0;
        let p = ray.o + (s / ray.per_t) * ray.d;
        var rho = 0.0;
        if (dither) {
            rho = draw_density(select(inst.frame_root0, inst.frame_root1, one), p);
        } else {
            var r2 = vec2<f32>(0.0);
            for (var f = 0u; f < select(1u, 2u, a > 0.0); f++) {
                r2[f] = draw_density(select(inst.frame_root0, inst.frame_root1, f == 1u), p);
            }
            rho = r2.x;
            if (a > 0.0) {
                rho = mix(r2.x, r2.y, a);
            }
        }
        if (!(rho > 0.0)) {
            continue;
        }
        let x = ext * rho * step;
        let e = exp(-x);
        if (draw_view.shading.emission.w != 0.0) {
            // Emission over the step, absorbed as the step attenuates (the tracer's lit march).
            rad += trans * step * lv_phi(x, e) * lit_emission(rho);
        }
        let md = lv_mean_depth(x, e);
        let q = ray.o + ((s - 0.5 * step + step * md) / ray.per_t) * ray.d;
        var pl = place;
        if (dither) {
            pl.lv_lo0 = select(place.lv_lo0, place.lv_lo1, one);
            pl.lv_dims0 = select(place.lv_dims0, place.lv_dims1, one);
            pl.near = select(place.near, place.near.zwzw, one);
            pl.roots.x = select(place.roots.x, place.roots.y, one);
            pl.misc.y = 0.0;
        }
        // A dithered crossfade's samples alternate frames: the tag keeps a walk of one frame's
        // medium from serving as the next sample's entry in the other's.
        let src = lit_scattered(pl, ray, s - 0.5 * step, step, q, rho, trans, eye, &sun_ph, vec3<f32>(x, e, md), vec3<i32>(-1), VDB_EMPTY, &exit, select(0.0, 1.0, one));
        rad += trans * place.axis.w * (1.0 - e) * src;
        trans *= e;
        if (trans < LV_MIN_TRANS) {
            break;
        }
    }
    return vec4<f32>(rad, trans);
}

// The emission pass of one instance up to `t_end`: `lit_channel_emission` of the channel per
// frame of the crossfade (lerped), behind the density's optical depth with extinction `ext`.
fn draw_emission(inst: DrawInstance, ray: VdbRay, ext: f32, t_end: f32) -> vec3<f32> {
    let c = draw_view.emit_channel;
    var e = lit_channel_emission(inst.frame_root0, ray, ext, t_end, c, inst.emit_lo.xyz, inst.emit_hi.xyz);
    let a = inst.box_lo.w;
    if (a > 0.0) {
        e = mix(e, lit_channel_emission(inst.frame_root1, ray, ext, t_end, c, inst.emit_lo.xyz, inst.emit_hi.xyz), a);
    }
    return e;
}

// Instance `i`'s ray in its cell space (t stays the world distance along `dw`). The
// instances are read field by field where the whole struct is not needed (a copy of it is
// large).
fn draw_ray(i: u32, ow: vec3<f32>, dw: vec3<f32>) -> VdbRay {
    var ray: VdbRay;
    let o4 = vec4<f32>(ow, 1.0);
    let d4 = vec4<f32>(dw, 0.0);
    let r0 = draw_instances[i].cell_from_world0;
    let r1 = draw_instances[i].cell_from_world1;
    let r2 = draw_instances[i].cell_from_world2;
    ray.o = vec3<f32>(dot(r0, o4), dot(r1, o4), dot(r2, o4));
    ray.d = vec3<f32>(dot(r0, d4), dot(r1, d4), dot(r2, d4));
    ray.per_t = select(1.0, length(ray.d), draw_view.shading.voxel_units != 0u);
    return ray;
}

// Whether the instance is marched lit.
fn draw_is_lit(inst: DrawInstance) -> bool {
    return DRAW_LIT && inst.lit != 0u;
}

// The extinction the emission pass attenuates by.
fn draw_ext(inst: DrawInstance) -> f32 {
    return select(inst.tint_absorb.w, inst.place.sun_cell.w, draw_is_lit(inst));
}

// The t interval where the instance's density lies (its content box, cut at the scene depth);
// x ≥ y when none.
fn draw_span(i: u32, ray: VdbRay, t_max: f32) -> vec2<f32> {
    let clip = vdb_clip_box(ray, draw_instances[i].box_lo.xyz, draw_instances[i].box_hi.xyz);
    return vec2<f32>(clip.x, min(clip.y, t_max));
}

// Where the instance's emission pass is added along the ray (its light behind its own density,
// in front of what lies behind its entry): the entry into its content or emission box, or
// VDB_BIG when it has no emission pass or the ray misses both before the scene depth.
fn draw_glow_at(i: u32, ray: VdbRay, t_max: f32) -> f32 {
    if (!DRAW_EMIT) {
        return VDB_BIG;
    }
    let ce = draw_span(i, ray, VDB_BIG);
    let ee = vdb_clip_box(ray, draw_instances[i].emit_lo.xyz, draw_instances[i].emit_hi.xyz);
    var g = VDB_BIG;
    if (ce.y > ce.x) {
        g = ce.x;
    }
    if (ee.y > ee.x) {
        g = min(g, ee.x);
    }
    return select(VDB_BIG, g, g <= t_max);
}

// One instance over [t0, t1] of the ray: (tinted radiance, transmittance) of the lit march or
// of the flat density march (`L = tint·(1 − T)`).
fn draw_march(inst: DrawInstance, ray: VdbRay, t0: f32, t1: f32, dw: vec3<f32>, pixel: u32) -> vec4<f32> {
    vdb_select(inst.asset);
    if (draw_is_lit(inst)) {
        let r = draw_lit(inst, ray, t0, t1, dw, pixel);
        return vec4<f32>(inst.tint_absorb.xyz * r.xyz, r.w);
    }
    let absorb = inst.tint_absorb.w;
    var tau = draw_tau(inst.frame_root0, ray, t0, t1, absorb);
    let a = inst.box_lo.w;
    if (a > 0.0) {
        tau = mix(tau, draw_tau(inst.frame_root1, ray, t0, t1, absorb), a);
    }
    let ti = exp(-absorb * tau);
    return vec4<f32>(inst.tint_absorb.xyz * (1.0 - ti), ti);
}

// The flat march's optical depth over [t0, t1]: the hierarchical walk, or in the interleaving
// variant for a stretch of a few voxels (a piece of `draw_pieces`) the flat voxel walk.
fn draw_tau(frame_root: u32, ray: VdbRay, t0: f32, t1: f32, absorb: f32) -> f32 {
    if (DRAW_INTERLEAVE && (t1 - t0) * length(ray.d) < 4.0) {
        return vdb_optical_depth_near(frame_root, ray, t0, t1, absorb);
    }
    return vdb_optical_depth(frame_root, ray, t0, t1, absorb);
}

// Most pieces `draw_pieces` cuts one stretch into.
const DRAW_MAX_PIECES: f32 = 1024.0;
// Most covering instances `draw_pieces` lists (more are found again per piece).
const DRAW_COVER_LIST: u32 = 8u;
// The optical depth of a piece (all media together) below which `draw_pieces` cuts no finer.
const DRAW_PIECE_DEPTH: f32 = 0.05;

// The stretch [t0, t1] where several instances overlap, in pieces: as many as the stretch's
// optical depth X over DRAW_PIECE_DEPTH, none shorter than a cell of the finest instance, at
// most DRAW_MAX_PIECES. In each piece every instance's own march gives (L_i, T_i); with optical
// depths x_i = −ln T_i and X = Σ x_i the piece's light is the mixture
// (1 − e^−X) Σ (x_i / X)·L_i / (1 − T_i): exact when each medium's density and source are
// constant over the piece (the media then add their extinction and share attenuation), and
// the closer the thinner the piece.
fn draw_pieces(ow: vec3<f32>, dw: vec3<f32>, t0: f32, t1: f32, t_max: f32, pixel: u32, whole: bool) -> vec4<f32> {
    // The instances covering the stretch (listed when at most DRAW_COVER_LIST do, else found
    // again per piece).
    let n = draw_view.instance_count;
    var list: array<u32, DRAW_COVER_LIST>;
    var rays: array<VdbRay, DRAW_COVER_LIST>;
    var m = 0u;
    var cells = 0.0;
    var depth = 0.0;
    for (var i = 0u; i < n; i++) {
        let span = draw_span_of(i, ow, dw, t_max);
        if (!(span.x <= t0 && span.y >= t1)) {
            continue;
        }
        let ray = draw_ray(i, ow, dw);
        if (m < DRAW_COVER_LIST) {
            list[m] = i;
            rays[m] = ray;
        }
        m += 1u;
        if (!whole) {
            cells = max(cells, length(ray.d));
            let inst = draw_instances[i];
            vdb_select(inst.asset);
            let ext = draw_ext(inst);
            var tau = vdb_optical_depth(inst.frame_root0, ray, t0, t1, ext);
            if (inst.box_lo.w > 0.0) {
                tau = mix(tau, vdb_optical_depth(inst.frame_root1, ray, t0, t1, ext), inst.box_lo.w);
            }
            depth += ext * tau;
        }
    }
    let listed = m <= DRAW_COVER_LIST;
    let by_depth = min(ceil(depth / DRAW_PIECE_DEPTH), ceil((t1 - t0) * cells));
    let count = select(clamp(by_depth, 1.0, DRAW_MAX_PIECES), 1.0, whole);
    let h = (t1 - t0) / count;
    var lt = vec4<f32>(vec3<f32>(0.0), 1.0);
    for (var k = 0.0; k < count; k += 1.0) {
        let a = t0 + k * h;
        let b = select(t0 + (k + 1.0) * h, t1, k + 1.0 >= count);
        var x_sum = 0.0;
        var src = vec3<f32>(0.0);
        var l_sum = vec3<f32>(0.0);
        for (var j = 0u; j < select(n, m, listed); j++) {
            var i = j;
            var ray: VdbRay;
            if (listed) {
                i = list[j];
                ray = rays[j];
            } else {
                let span = draw_span_of(i, ow, dw, t_max);
                if (!(span.x <= t0 && span.y >= t1)) {
                    continue;
                }
                ray = draw_ray(i, ow, dw);
            }
            let r = draw_march(draw_instances[i], ray, a, b, dw, pixel);
            let x = -log(max(r.w, 1.0e-30));
            x_sum += x;
            l_sum += r.xyz;
            src += x * r.xyz / max(1.0 - r.w, 1.0e-30);
        }
        var l = l_sum;
        if (x_sum > 1.0e-4) {
            l = (1.0 - exp(-x_sum)) * src / x_sum;
        }
        lt = vec4<f32>(lt.xyz + lt.w * l, lt.w * exp(-x_sum));
        if (lt.w < 1.0e-6) {
            break;
        }
    }
    return lt;
}

// The interleaving sweep's spans and glow entries of the first DRAW_SPAN_CACHE instances, per
// invocation (the sweep reads them once per cut; later instances are computed again).
const DRAW_SPAN_CACHE: u32 = 32u;
var<private> draw_spans: array<vec3<f32>, DRAW_SPAN_CACHE>;

// Fills the cache for the ray from `ow` along `dw`.
fn draw_cache_spans(ow: vec3<f32>, dw: vec3<f32>, t_max: f32) {
    for (var i = 0u; i < min(draw_view.instance_count, DRAW_SPAN_CACHE); i++) {
        let ray = draw_ray(i, ow, dw);
        draw_spans[i] = vec3<f32>(draw_span(i, ray, t_max), draw_glow_at(i, ray, t_max));
    }
}

// Instance i's span (`draw_span`).
fn draw_span_of(i: u32, ow: vec3<f32>, dw: vec3<f32>, t_max: f32) -> vec2<f32> {
    if (i < DRAW_SPAN_CACHE) {
        return draw_spans[i].xy;
    }
    return draw_span(i, draw_ray(i, ow, dw), t_max);
}

// Instance i's glow entry (`draw_glow_at`).
fn draw_glow_of(i: u32, ow: vec3<f32>, dw: vec3<f32>, t_max: f32) -> f32 {
    if (i < DRAW_SPAN_CACHE) {
        return draw_spans[i].z;
    }
    return draw_glow_at(i, draw_ray(i, ow, dw), t_max);
}

// The view-space point of NDC `(xy, z)`, or w = 0 when it is at infinity.
fn draw_unproject(xy: vec2<f32>, z: f32) -> vec4<f32> {
    let h = draw_view.view_from_clip * vec4<f32>(xy, z, 1.0);
    if (!(abs(h.w) > 1.0e-30)) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(h.xyz / h.w, 1.0);
}

// A pixel-space point's ray in view space (origin `ov`, unit direction `dv`; t is view
// distance) and its NDC.
struct DrawPixelRay {
    ov: vec3<f32>,
    dv: vec3<f32>,
    ndc: vec2<f32>,
}

fn draw_pixel_ray(pc: vec2<f32>) -> DrawPixelRay {
    let size = draw_view.viewport;
    var r: DrawPixelRay;
    r.ndc = vec2<f32>(2.0 * pc.x / f32(size.x) - 1.0, 1.0 - 2.0 * pc.y / f32(size.y));
    r.ov = vec3<f32>(0.0);
    r.dv = draw_view.forward.xyz;
    if (draw_view.forward.w != 0.0) {
        let p = draw_unproject(r.ndc, 0.5);
        r.dv = normalize(p.xyz);
    } else {
        r.ov = draw_unproject(r.ndc, draw_view.near_ndc).xyz;
    }
    return r;
}

// The view distance along `r` to the scene depth stored at pixel `pix` (VDB_BIG without one).
fn draw_depth_t(pix: vec2<u32>, r: DrawPixelRay) -> f32 {
    var t_max = VDB_BIG;
    if (draw_view.has_depth != 0u) {
        let d = textureLoad(draw_depth, vec2<i32>(pix), 0);
        let p = draw_unproject(r.ndc, d);
        if (p.w != 0.0) {
            let t = dot(p.xyz - r.ov, r.dv);
            if (abs(t) < VDB_BIG) {
                t_max = t;
            }
        }
    }
    return t_max;
}

// A view ray in world space: origin, unit direction, and its cut (a view distance, VDB_BIG for
// none) in world units (a view matrix with a scale makes a view-space length `s` world units).
struct DrawWorldRay {
    ow: vec3<f32>,
    dw: vec3<f32>,
    t_max: f32,
}

fn draw_world_ray(r: DrawPixelRay, t_view: f32) -> DrawWorldRay {
    let wfv = draw_view.world_from_view;
    var w: DrawWorldRay;
    w.ow = (wfv * vec4<f32>(r.ov, 1.0)).xyz;
    let dws = (wfv * vec4<f32>(r.dv, 0.0)).xyz;
    let s = length(dws);
    w.dw = dws / s;
    w.t_max = t_view;
    if (t_view < VDB_BIG) {
        w.t_max = t_view * s;
    }
    return w;
}

// The reduced-resolution (L, T) at pixel `pix`: bilinear over the four nearest block centres
// (block b's at pixel coordinate block·b + block/2), clamped to the marched blocks; T < 0 when
// one of them was not marched, or when hidden blocks (T = 2: scene depth in front of every
// volume) meet others (an occluder's edge), so that the pixel is marched at full resolution.
fn draw_upsample(pix: vec2<u32>) -> vec4<f32> {
    let k = f32(draw_view.block);
    let u = (vec2<f32>(pix) + vec2<f32>(0.5 - 0.5 * k)) / k;
    let b0f = floor(u);
    let f = u - b0f;
    let lo = vec2<i32>(draw_view.half_lo);
    let hi = vec2<i32>(draw_view.half_hi) - vec2<i32>(1);
    let b0 = clamp(vec2<i32>(b0f), lo, hi);
    let b1 = clamp(vec2<i32>(b0f) + vec2<i32>(1), lo, hi);
    let s00 = textureLoad(draw_half_in, b0, 0);
    let s10 = textureLoad(draw_half_in, vec2<i32>(b1.x, b0.y), 0);
    let s01 = textureLoad(draw_half_in, vec2<i32>(b0.x, b1.y), 0);
    let s11 = textureLoad(draw_half_in, b1, 0);
    let t = vec4<f32>(s00.w, s10.w, s01.w, s11.w);
    let hidden = t == vec4<f32>(DRAW_HIDDEN);
    if (any(t < vec4<f32>(0.0)) || (any(hidden) && !all(hidden))) {
        return vec4<f32>(0.0, 0.0, 0.0, -1.0);
    }
    if (all(hidden)) {
        return vec4<f32>(0.0, 0.0, 0.0, 1.0);
    }
    return mix(mix(s00, s10, f.x), mix(s01, s11, f.x), f.y);
}

@compute @workgroup_size(8, 8, 1)
fn draw_main(@builtin(global_invocation_id) global: vec3<u32>) {
    let size = draw_view.viewport;
    let pix = global.xy + draw_view.origin;
    if (pix.x >= size.x || pix.y >= size.y) {
        return;
    }
    if (draw_view.block != 0u) {
        let up = draw_upsample(pix);
        if (up.w >= 0.0) {
            textureStore(draw_out, vec2<i32>(pix), up);
            return;
        }
    }
    let r = draw_pixel_ray(vec2<f32>(pix) + vec2<f32>(0.5) + draw_view.jitter);
    let w = draw_world_ray(r, draw_depth_t(pix, r));
    textureStore(draw_out, vec2<i32>(pix), draw_lt(w.ow, w.dw, w.t_max, pix.y * size.x + pix.x));
}

// The T a hidden block stores (every pixel's scene depth in front of every volume on its ray).
const DRAW_HIDDEN: f32 = 2.0;

// The reduced-resolution march (`MarchResolution::Half`, `Quarter`): one ray per block of
// `block`² pixels through its centre, where every pixel's scene depth lies beyond every
// instance's boxes along that pixel's own ray (or meets none); a block where every pixel's depth
// lies in front of the boxes on its ray is hidden (T = DRAW_HIDDEN: nothing drawn); any other
// block (a depth edge among the volumes, or both kinds of pixel) is left to `draw_main`, which
// marches its pixels at full resolution.
@compute @workgroup_size(8, 8, 1)
fn draw_half_main(@builtin(global_invocation_id) global: vec3<u32>) {
    let size = draw_view.viewport;
    let b = global.xy + draw_view.half_lo;
    if (b.x >= draw_view.half_hi.x || b.y >= draw_view.half_hi.y) {
        return;
    }
    let bk = draw_view.block;
    let p0 = bk * b;
    let centre = draw_world_ray(draw_pixel_ray(vec2<f32>(p0) + vec2<f32>(0.5 * f32(bk)) + draw_view.jitter), VDB_BIG);
    // Each pixel against the boxes (content and glow) on its own ray: beyond them all, in front
    // of them all, or cutting through.
    var beyond = 0u;
    var in_front = 0u;
    for (var k = 0u; k < bk * bk; k++) {
        let pix = min(p0 + vec2<u32>(k % bk, k / bk), size - vec2<u32>(1u));
        let r = draw_pixel_ray(vec2<f32>(pix) + vec2<f32>(0.5) + draw_view.jitter);
        let w = draw_world_ray(r, VDB_BIG);
        let t = draw_world_ray(r, draw_depth_t(pix, r)).t_max;
        var e_lo = VDB_BIG;
        var e_hi = -VDB_BIG;
        for (var i = 0u; i < draw_view.instance_count; i++) {
            let ray = draw_ray(i, w.ow, w.dw);
            let c = draw_span(i, ray, VDB_BIG);
            if (c.y > c.x) {
                e_lo = min(e_lo, c.x);
                e_hi = max(e_hi, c.y);
            }
            if (DRAW_EMIT) {
                let g = vdb_clip_box(ray, draw_instances[i].emit_lo.xyz, draw_instances[i].emit_hi.xyz);
                if (g.y > g.x) {
                    e_lo = min(e_lo, g.x);
                    e_hi = max(e_hi, g.y);
                }
            }
        }
        if (!(e_hi > e_lo) || t >= e_hi) {
            beyond += 1u;
        } else if (t <= e_lo) {
            in_front += 1u;
        }
    }
    var out = vec4<f32>(0.0, 0.0, 0.0, -1.0);
    if (in_front == bk * bk) {
        out = vec4<f32>(0.0, 0.0, 0.0, DRAW_HIDDEN);
    } else if (beyond == bk * bk) {
        // Every pixel sees its volumes whole: the centre ray is not cut either.
        out = draw_lt(centre.ow, centre.dw, VDB_BIG, b.y * size.x + b.x);
    }
    textureStore(draw_half_out, vec2<i32>(b), out);
}

// (L, T) of every instance along the world ray from `ow` along `dw`, cut at `t_max` (world
// distance); `pixel` seeds the lit march's jitter.
fn draw_lt(ow: vec3<f32>, dw: vec3<f32>, t_max: f32, pixel: u32) -> vec4<f32> {
    let n = draw_view.instance_count;
    var lt = vec4<f32>(vec3<f32>(0.0), 1.0);
    if (!DRAW_INTERLEAVE) {
        // No two instances' boxes overlap (`VolumeDrawer::prepare` checks): each is marched
        // whole, front to back in the order the CPU sorted them.
        for (var i = 0u; i < n; i++) {
            let inst = draw_instances[i];
            let ray = draw_ray(i, ow, dw);
            // The emission pass (its box may reach past the density's): light behind the
            // instance's own density, added before the instance attenuates what lies behind.
            var glow = vec3<f32>(0.0);
            if (DRAW_EMIT) {
                vdb_select(inst.asset);
                glow = inst.tint_absorb.xyz * draw_emission(inst, ray, draw_ext(inst), t_max);
            }
            let span = draw_span(i, ray, t_max);
            var r = vec4<f32>(vec3<f32>(0.0), 1.0);
            if (span.y > span.x) {
                r = draw_march(inst, ray, span.x, span.y, dw, pixel);
            }
            lt = vec4<f32>(lt.xyz + lt.w * (r.xyz + glow), lt.w * r.w);
        }
    } else {
        // The instances interleaved along the ray: the ray is cut at every instance's entry and
        // exit (`draw_span`) and glow entry (`draw_glow_at`); a stretch inside one instance is
        // marched whole, one inside several in pieces of at most a cell of the finest
        // (`draw_pieces`). Light and transmittance compose front to back across stretches.
        draw_cache_spans(ow, dw, t_max);
        var t = 0.0;
        for (var guard = 0u; guard < 3u * n + 2u; guard++) {
            // The next cut after t.
            var e = VDB_BIG;
            for (var i = 0u; i < n; i++) {
                let span = draw_span_of(i, ow, dw, t_max);
                if (span.y > span.x) {
                    e = select(e, min(e, span.x), span.x > t);
                    e = select(e, min(e, span.y), span.y > t);
                }
                let g = draw_glow_of(i, ow, dw, t_max);
                e = select(e, min(e, g), g > t && g < VDB_BIG);
            }
            // The glows entering in [t, e), then the instances covering [t, e).
            var covering = 0u;
            for (var i = 0u; i < n; i++) {
                let g = draw_glow_of(i, ow, dw, t_max);
                if (g >= t && g < e && g < VDB_BIG) {
                    let inst = draw_instances[i];
                    vdb_select(inst.asset);
                    let glow = draw_emission(inst, draw_ray(i, ow, dw), draw_ext(inst), t_max);
                    lt = vec4<f32>(lt.xyz + lt.w * inst.tint_absorb.xyz * glow, lt.w);
                }
                let span = draw_span_of(i, ow, dw, t_max);
                if (span.x <= t && span.y >= e && span.y > span.x && e < VDB_BIG) {
                    covering += 1u;
                }
            }
            if (!(e < VDB_BIG)) {
                break;
            }
            if (covering > 0u) {
                let r = draw_pieces(ow, dw, t, e, t_max, pixel, covering == 1u);
                lt = vec4<f32>(lt.xyz + lt.w * r.xyz, lt.w * r.w);
            }
            t = e;
            if (lt.w < 1.0e-6) {
                break;
            }
        }
    }
    return lt;
}
