// draw.wgsl — the engine drawer (`vdbcook_runtime::VolumeDrawer`): it exists so that volumes can
// be drawn into an engine's own frame — its view and projection, its depth buffer, its colour
// target — rather than into an image of their own. Two entry points:
//
// - `draw_main` (compute, one invocation per pixel): unprojects the pixel centre (+ jitter)
//   through the engine's projection, cuts the ray at the engine's depth (a `Depth32Float`
//   texture, standard or reversed Z, `textureLoad`), and marches every instance of the volume
//   with the density march (`vdb_optical_depth` in `volume.wgsl`: the CPU tracer's Density mode),
//   front to back in the order the CPU sorted them, writing premultiplied radiance and
//   transmittance (L, T) to an `Rgba16Float` storage texture. With lighting (`DRAW_LIT`, a
//   second pipeline) each lit instance is marched as the tracer's lit mode (`lit_primary` in
//   `trace.wgsl`, the CPU's `lit` module): samples on the same grid, density by nearest or
//   trilinear lookup (crossfades lerp it), sun and sky from the instance's light volumes (group 2, built by
//   `light_build.wgsl` in the instance's cell space; crossfades lerp their depths and light), the
//   near field toward the sun walked per frame of a crossfade (`DRAW_NEAR`; both frames gated on
//   the lerped density and the one transmittance: the CPU draws single frames only).
// The composite that blends (L, T) over the engine's colour target is `composite.wgsl`.
//
// Concatenated after `volume.wgsl`, `light.wgsl` and `lit.wgsl` (group 0: the volume). Group 1: the view
// (uniform), the instances (storage), the scene depth, the (L, T) output. Group 2: the light
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
    // The channel whose emission the voxel-exact emission pass draws (`lit_channel_emission`)
    // for flat instances (any channel, `emit_flat`) and for lit ones (another channel than the
    // density, `emit_lit`; the lit march glows its own channel itself).
    emit_channel: u32,
    emit_flat: u32,
    emit_lit: u32,
    // The pixel of the dispatch's first invocation: the dispatch covers only the pixels the
    // instances can reach (`PreparedDraw::covered`).
    origin: vec2<u32>,
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
    _pad: u32,
    // The lit march's medium and light volumes in the instance's cell space (`lit.wgsl`).
    place: VdbLitPlace,
}

@group(1) @binding(0) var<uniform> draw_view: DrawView;
@group(1) @binding(1) var<storage, read> draw_instances: array<DrawInstance>;
@group(1) @binding(2) var draw_depth: texture_depth_2d;
@group(1) @binding(3) var draw_out: texture_storage_2d<rgba16float, write>;
// Group 2: the light volumes (`lit.wgsl`'s `lit_tau` and `lit_ms`).

// Whether this pipeline marches lit instances (the flat pipeline compiles the lit march out).
const DRAW_LIT: bool = {{DRAW_LIT}};
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
    for (var n = 0u; n < DRAW_MAX_SAMPLES; n++) {
        let s = (k + jitter) * step;
        if (!(s < sb)) {
            break;
        }
        k += 1.0;
        let p = ray.o + (s / ray.per_t) * ray.d;
        var r2 = vec2<f32>(0.0);
        for (var f = 0u; f < select(1u, 2u, a > 0.0); f++) {
            r2[f] = draw_density(select(inst.frame_root0, inst.frame_root1, f == 1u), p);
        }
        var rho = r2.x;
        if (a > 0.0) {
            rho = mix(r2.x, r2.y, a);
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
        let q = ray.o + ((s - 0.5 * step + step * lv_mean_depth(x)) / ray.per_t) * ray.d;
        let src = lit_scattered(place, q, rho, trans, eye, &sun_ph, vec3<i32>(-1), VDB_EMPTY);
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

// The view-space point of NDC `(xy, z)`, or w = 0 when it is at infinity.
fn draw_unproject(xy: vec2<f32>, z: f32) -> vec4<f32> {
    let h = draw_view.view_from_clip * vec4<f32>(xy, z, 1.0);
    if (!(abs(h.w) > 1.0e-30)) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(h.xyz / h.w, 1.0);
}

@compute @workgroup_size(8, 8, 1)
fn draw_main(@builtin(global_invocation_id) global: vec3<u32>) {
    let size = draw_view.viewport;
    let pix = global.xy + draw_view.origin;
    if (pix.x >= size.x || pix.y >= size.y) {
        return;
    }
    let pc = vec2<f32>(pix) + vec2<f32>(0.5) + draw_view.jitter;
    let ndc = vec2<f32>(2.0 * pc.x / f32(size.x) - 1.0, 1.0 - 2.0 * pc.y / f32(size.y));
    // The ray in view space: origin `ov`, unit direction `dv`; t is view (= world) distance.
    var ov = vec3<f32>(0.0);
    var dv = draw_view.forward.xyz;
    if (draw_view.forward.w != 0.0) {
        let p = draw_unproject(ndc, 0.5);
        dv = normalize(p.xyz);
    } else {
        ov = draw_unproject(ndc, draw_view.near_ndc).xyz;
    }
    var t_max = VDB_BIG;
    if (draw_view.has_depth != 0u) {
        let d = textureLoad(draw_depth, vec2<i32>(pix), 0);
        let p = draw_unproject(ndc, d);
        if (p.w != 0.0) {
            let t = dot(p.xyz - ov, dv);
            if (abs(t) < VDB_BIG) {
                t_max = t;
            }
        }
    }
    // To world; a view matrix with a scale makes a view-space length `s` world units long.
    let wfv = draw_view.world_from_view;
    let ow = (wfv * vec4<f32>(ov, 1.0)).xyz;
    let dws = (wfv * vec4<f32>(dv, 0.0)).xyz;
    let s = length(dws);
    let dw = dws / s;
    if (t_max < VDB_BIG) {
        t_max *= s;
    }

    var lum = vec3<f32>(0.0);
    var trans = 1.0;
    for (var i = 0u; i < draw_view.instance_count; i++) {
        let inst = draw_instances[i];
        var ray: VdbRay;
        let o4 = vec4<f32>(ow, 1.0);
        let d4 = vec4<f32>(dw, 0.0);
        ray.o = vec3<f32>(dot(inst.cell_from_world0, o4), dot(inst.cell_from_world1, o4),
                          dot(inst.cell_from_world2, o4));
        ray.d = vec3<f32>(dot(inst.cell_from_world0, d4), dot(inst.cell_from_world1, d4),
                          dot(inst.cell_from_world2, d4));
        ray.per_t = select(1.0, length(ray.d), draw_view.shading.voxel_units != 0u);
        let lit = DRAW_LIT && inst.lit != 0u;
        // The emission pass (its box may reach past the density's): light behind the instance's
        // own density, added before the instance attenuates what lies behind it.
        var glow = vec3<f32>(0.0);
        if (select(draw_view.emit_flat, draw_view.emit_lit, lit) != 0u) {
            glow = draw_emission(inst, ray, select(inst.tint_absorb.w, inst.place.sun_cell.w, lit), t_max);
        }
        let clip = vdb_clip_box(ray, inst.box_lo.xyz, inst.box_hi.xyz);
        let t1 = min(clip.y, t_max);
        if (!(t1 > clip.x)) {
            lum += trans * inst.tint_absorb.xyz * glow;
            continue;
        }
        if (lit) {
            let r = draw_lit(inst, ray, clip.x, t1, dw, pix.y * size.x + pix.x);
            lum += trans * inst.tint_absorb.xyz * (r.xyz + glow);
            trans *= r.w;
            continue;
        }
        let absorb = inst.tint_absorb.w;
        var tau = vdb_optical_depth(inst.frame_root0, ray, clip.x, t1, absorb);
        let a = inst.box_lo.w;
        if (a > 0.0) {
            let tau1 = vdb_optical_depth(inst.frame_root1, ray, clip.x, t1, absorb);
            tau = mix(tau, tau1, a);
        }
        let ti = exp(-absorb * tau);
        lum += trans * inst.tint_absorb.xyz * (1.0 - ti + glow);
        trans *= ti;
    }
    textureStore(draw_out, vec2<i32>(pix), vec4<f32>(lum, trans));
}
