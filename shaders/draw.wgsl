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
// Concatenated after `volume.wgsl` and `light.wgsl` (group 0: the volume). Group 1: the view
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
    voxel_units: u32,
    // Lighting (lit instances only): xyz the unit world direction toward the light, w the march
    // step (length unit); xyz the light colour, w `Lighting::near_scatter`; xyz the sky
    // radiance; the phase
    // (g0, g1, weight); the octave falloff (a, b, c), w 1 for trilinear density.
    light_dir: vec4<f32>,
    light_color: vec4<f32>,
    sky: vec4<f32>,
    phase: vec4<f32>,
    ms: vec4<f32>,
    // Octaves of the sun's multiple scattering; 0: the diffusion model.
    ms_octaves: u32,
    seed: u32,
    // Light-volume cells of the near field toward the sun (`Lighting::sun_near`; 0: none).
    sun_near: f32,
    _pad1: u32,
    // Emission of lit instances (`vdbcook_scene::Emission`): x, y the range in Kelvin, z the
    // intensity, w 1 when on; the blackbody colours over the range.
    emission: vec4<f32>,
    emit_table: array<vec4<f32>, 32>,
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
    // Root offsets (frame · root_len) of frames floor(time) and floor(time) + 1.
    frame_root0: u32,
    frame_root1: u32,
    // 1: marched lit (`lv_*` hold its light volumes), 0: the flat density march.
    lit: u32,
    // Lit: albedo; extinction is `(absorb + scatter) · density scale` per unit density.
    albedo: f32,
    extinction: f32,
    // Base elements of the light volumes of frames floor(time) and floor(time) + 1.
    lv_base0: u32,
    lv_base1: u32,
    // k of the sky's source (`lv_sky_source`: it depends on the albedo).
    sky_k: f32,
    // Their grids: xyz corner of cell 0 (cell space), w cell edge; xyz cells per axis.
    lv_lo0: vec4<f32>,
    lv_dims0: vec4<u32>,
    lv_lo1: vec4<f32>,
    lv_dims1: vec4<u32>,
    // xyz: length per cell-space unit along each axis (the diffusion's metric); w: the phase's
    // mean cosine.
    lv_axis: vec4<f32>,
}

@group(1) @binding(0) var<uniform> draw_view: DrawView;
@group(1) @binding(1) var<storage, read> draw_instances: array<DrawInstance>;
@group(1) @binding(2) var draw_depth: texture_depth_2d;
@group(1) @binding(3) var draw_out: texture_storage_2d<rgba16float, write>;
@group(2) @binding(0) var<storage, read> draw_lv: array<vec2<f32>>;
// The diffusion model's six words per cell of `draw_lv` (`light_build.wgsl`'s `ms_store_main`).
@group(2) @binding(1) var<storage, read> draw_lv_ms: array<vec2<u32>>;

// Whether this pipeline marches lit instances (the flat pipeline compiles the lit march out).
const DRAW_LIT: bool = {{DRAW_LIT}};
// Whether the lit march reads trilinear density (a third pipeline, made on first use).
const DRAW_TRILINEAR: bool = {{DRAW_TRILINEAR}};
// Whether the lit march can walk the near field toward the sun (`Lighting::sun_near` > 0).
const DRAW_NEAR: bool = {{DRAW_NEAR}};
// Most samples of one lit instance march (`vdbcook_trace::MAX_MARCH_SAMPLES`).
const DRAW_MAX_SAMPLES: u32 = 1048576u;

// (τ_sun, τ_sky) of the light volume at `base` over the grid (lo.xyz, cell lo.w; dims) at `p`.
fn draw_lv_lookup(base: u32, lo: vec4<f32>, dims: vec4<u32>, p: vec3<f32>) -> vec2<f32> {
    let t = lv_taps(p, lo.xyz, lo.w, dims.xyz);
    var out = vec2<f32>(0.0);
    for (var k = 0u; k < 8u; k++) {
        out += t.w[k] * draw_lv[base + t.idx[k]];
    }
    return out;
}

// The diffusion model's (sun, sky) light of the light volume at `base` at `p` toward `eye`
// (the tracer's `lit_diffuse`).
fn draw_diffuse(base: u32, lo: vec4<f32>, dims: vec4<u32>, p: vec3<f32>, eye: vec4<f32>) -> vec2<f32> {
    let t = lv_taps(p, lo.xyz, lo.w, dims.xyz);
    var acc: LvDiffuse;
    for (var k = 0u; k < 8u; k++) {
        let i = 3u * (base + t.idx[k]);
        lv_diffuse_add(&acc, t.w[k], draw_lv_ms[i], draw_lv_ms[i + 1u], draw_lv_ms[i + 2u]);
    }
    return lv_diffuse_read(acc, eye.xyz, eye.w);
}

// The sun's depth at `q` (density `rho`) of one frame of a lit instance (root `root`, its light
// volume at `base` over `lo`, `dims`), the tracer's `lit_sun_depth` in the instance's cell
// space: the first `sun_near` cells toward the sun (`l`: the cell-space image of the unit
// world direction) walked exactly where a cell is optically thick and the ray's transmittance
// `trans` is above `LV_NEAR_TRANS`, the light volume beyond; and the light volume's depth at
// `q` (the same without a walk).
fn draw_sun_depth(inst: DrawInstance, root: u32, base: u32, lo: vec4<f32>, dims: vec4<u32>, q: vec3<f32>, rho: f32, trans: f32, l: vec3<f32>) -> vec2<f32> {
    let cells = draw_lv_lookup(base, lo, dims, q).x;
    let cell = lo.w;
    let near = min(draw_view.sun_near * cell, LV_NEAR_MAX_VOXELS);
    let axis = inst.lv_axis.xyz;
    let cell_len = cell * min(axis.x, min(axis.y, axis.z));
    if (!DRAW_NEAR || !(near > 0.0) || !(inst.extinction * rho * cell_len >= lv_near_depth(cell))
        || !(trans >= LV_NEAR_TRANS)) {
        return vec2<f32>(cells);
    }
    return vec2<f32>(draw_near_sun_depth(root, base, lo, dims, q, near, l), cells);
}

// The near field's depth toward the sun from `q` over `near` voxels (`l`: the cell-space image
// of the unit world direction toward the sun), the light volume's beyond.
fn draw_near_sun_depth(root: u32, base: u32, lo: vec4<f32>, dims: vec4<u32>, q: vec3<f32>, near: f32, l: vec3<f32>) -> f32 {
    var ray: VdbRay;
    ray.o = q;
    ray.d = l;
    ray.per_t = select(1.0, length(l), draw_view.voxel_units != 0u);
    let c = vdb_clip(ray, vec3<f32>(vdb_info.root_dims * 128u));
    if (!(c.y > c.x)) {
        return 0.0;
    }
    let t_near = near / length(l);
    // The whole near field (no opaque stop: the octaves read e^{-b^i·σ·τ}).
    let tau = vdb_optical_depth_near(root, ray, c.x, min(c.y, t_near), 0.0);
    if (t_near >= c.y) {
        return tau;
    }
    let p = q + t_near * l;
    let u = normalize(l);
    let te = lv_box_entry(lo, dims.xyz, p, u);
    if (te < 0.0) {
        return tau;
    }
    return tau + draw_lv_lookup(base, lo, dims, p + te * u).x;
}

// The lit march's density of one frame at cell-space point `p`: the nearest voxel (≥ 0), or
// trilinear inside leaves the tracer's walk visits (bound > 0), as its lit march reads it.
fn draw_density(frame_root: u32, p: vec3<f32>) -> f32 {
    let cell = vec3<i32>(floor(p));
    if (DRAW_TRILINEAR && draw_view.ms.w != 0.0) {
        if (vdb_leaf_bound(frame_root, cell) > 0.0) {
            return vdb_trilinear(frame_root, p);
        }
        return 0.0;
    }
    return max(vdb_value(frame_root, cell), 0.0);
}

// The lit march of one instance for t in [t0, t1]: (radiance before the tint, transmittance).
fn draw_lit(inst: DrawInstance, ray: VdbRay, t0: f32, t1: f32, dw: vec3<f32>, pixel: u32) -> vec4<f32> {
    let step = draw_view.light_dir.w;
    let ms = draw_view.ms.xyz;
    let octaves = draw_view.ms_octaves;
    let mu = dot(dw, draw_view.light_dir.xyz);
    var sun_ph = lv_sun_phases(draw_view.phase.xyz, ms.z, mu);
    let jitter = lv_jitter(draw_view.seed, pixel);
    let ext = inst.extinction;
    let a = inst.box_lo.w;
    // Toward the eye in the diffusion's metric, and the phase's mean cosine.
    let eye = vec4<f32>(lv_eye_dir(ray.d, inst.lv_axis.xyz), inst.lv_axis.w);
    // The cell-space image of the unit world direction toward the sun.
    let lw = draw_view.light_dir.xyz;
    let l = vec3<f32>(dot(inst.cell_from_world0.xyz, lw), dot(inst.cell_from_world1.xyz, lw),
                      dot(inst.cell_from_world2.xyz, lw));
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
        if (draw_view.emission.w != 0.0) {
            // Emission over the step, absorbed as the step attenuates (the tracer's lit march).
            let w = lv_emission_at(rho, draw_view.emission);
            let i = u32(w.x);
            let c0 = draw_view.emit_table[i].xyz;
            rad += trans * step * lv_phi(x, e) * w.z * (c0 + w.y * (draw_view.emit_table[i + 1u].xyz - c0));
        }
        let q = ray.o + ((s - 0.5 * step + step * lv_mean_depth(x)) / ray.per_t) * ray.d;
        // Each frame of the crossfade (one call site: lavapipe inlines each one).
        // Per frame (walked, cells).
        var tau_f = array<vec2<f32>, 2>(vec2<f32>(0.0), vec2<f32>(0.0));
        for (var f = 0u; f < select(1u, 2u, a > 0.0); f++) {
            let one = f == 1u;
            tau_f[f] = draw_sun_depth(inst, select(inst.frame_root0, inst.frame_root1, one),
                select(inst.lv_base0, inst.lv_base1, one), select(inst.lv_lo0, inst.lv_lo1, one),
                select(inst.lv_dims0, inst.lv_dims1, one), q, rho, trans, l);
        }
        var tau_sun = tau_f[0];
        if (a > 0.0) {
            tau_sun = mix(tau_f[0], tau_f[1], a);
        }
        var sun = 0.0;
        var sky = 0.0;
        if (octaves == 0u) {
            // The diffusion model: single scattering plus the solve's sun; the solve's sky.
            var d = array<vec2<f32>, 2>(vec2<f32>(0.0), vec2<f32>(0.0));
            for (var f = 0u; f < select(1u, 2u, a > 0.0); f++) {
                let one = f == 1u;
                d[f] = draw_diffuse(select(inst.lv_base0, inst.lv_base1, one),
                    select(inst.lv_lo0, inst.lv_lo1, one), select(inst.lv_dims0, inst.lv_dims1, one),
                    q, eye);
            }
            var diffuse = d[0];
            if (a > 0.0) {
                diffuse = mix(d[0], d[1], a);
            }
            let direct = exp(-ext * tau_sun.x);
            sun = sun_ph[0] * direct
                + max(diffuse.x + lv_near_scatter(draw_view.light_color.w, inst.albedo, direct, exp(-ext * tau_sun.y)), 0.0);
            sky = diffuse.y;
        } else {
            var tau_sky = draw_lv_lookup(inst.lv_base0, inst.lv_lo0, inst.lv_dims0, q).y;
            if (a > 0.0) {
                tau_sky = mix(tau_sky, draw_lv_lookup(inst.lv_base1, inst.lv_lo1, inst.lv_dims1, q).y, a);
            }
            sun = lv_octaves(ext * tau_sun.x, ms, octaves, &sun_ph);
            sky = lv_sky_source(ext * tau_sky, inst.sky_k);
        }
        rad += trans * inst.albedo * (1.0 - e) * (draw_view.light_color.xyz * sun + draw_view.sky.xyz * sky);
        trans *= e;
        if (trans < LV_MIN_TRANS) {
            break;
        }
    }
    return vec4<f32>(rad, trans);
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
fn draw_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = draw_view.viewport;
    if (gid.x >= size.x || gid.y >= size.y) {
        return;
    }
    let pc = vec2<f32>(gid.xy) + vec2<f32>(0.5) + draw_view.jitter;
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
        let d = textureLoad(draw_depth, vec2<i32>(gid.xy), 0);
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
        ray.per_t = select(1.0, length(ray.d), draw_view.voxel_units != 0u);
        let clip = vdb_clip_box(ray, inst.box_lo.xyz, inst.box_hi.xyz);
        let t1 = min(clip.y, t_max);
        if (!(t1 > clip.x)) {
            continue;
        }
        if (DRAW_LIT && inst.lit != 0u) {
            let r = draw_lit(inst, ray, clip.x, t1, dw, gid.y * size.x + gid.x);
            lum += trans * inst.tint_absorb.xyz * r.xyz;
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
        lum += trans * inst.tint_absorb.xyz * (1.0 - ti);
        trans *= ti;
    }
    textureStore(draw_out, vec2<i32>(gid.xy), vec4<f32>(lum, trans));
}
