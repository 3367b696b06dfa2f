// lit.wgsl — the lit march's light, written once for both of its GPU users: the renderer
// (`trace.wgsl`'s lit mode) and the engine drawer (`draw.wgsl`'s lit instances). What a sample of
// a lit march scatters toward the eye from the sun and the sky: the sun's optical depth from the
// light volume (`light_build.wgsl` built it in the march's cell space), with the near field
// toward the sun walked exactly through the tree, the multiple scattering by octaves or from the
// diffusion solve, the once-scattered light below the light volume's cells, a crossfade of two
// frames lerped; and the emission of the march's own channel. `vdbcook_trace`'s `lit` module is
// the definition the GPU tests compare against.
//
// Concatenated after `volume.wgsl` and `light.wgsl`. The includer replaces `{{LIT_GROUP}}` with
// the bind group of its light volumes (binding 0: (τ_sun, τ_sky) per cell; binding 1: the
// diffusion model's six words per cell) and `{{SHADING}}` with the expression of its
// `VdbShading` uniform. Both structs mirror `runtime/src/shading.rs` (`ShadingUniform`,
// `LitPlace`: one packing for both users, checked member by member against this file).

// The light, the medium's phase and emission, and the integrator's knobs of a lit march
// (`ShadingUniform::new`).
struct VdbShading {
    // xyz: the unit world direction toward the sun; w: the march step (length unit).
    sun: vec4<f32>,
    // xyz: the sun's irradiance (linear RGB); w: `Lighting::near_scatter`.
    sun_color: vec4<f32>,
    // xyz: the sky's radiance; w: 1 for trilinear density.
    sky: vec4<f32>,
    // x, y: the dual lobe's g; z: the first lobe's weight; w: the phase's mean cosine.
    phase: vec4<f32>,
    // The octave falloff (a, b, c) of `MsModel::Octaves`; w: unused.
    ms: vec4<f32>,
    // Octaves of the sun's multiple scattering; 0: the diffusion model.
    octaves: u32,
    seed: u32,
    // 1: lengths are per voxel (`LengthUnit::Voxel`), 0: per world unit.
    voxel_units: u32,
    _pad: u32,
    // Emission of the march's own channel (`vdbcook_scene::Emission`): x, y the value range,
    // z the intensity, w 1 when on; the blackbody colours over its Kelvin range.
    emission: vec4<f32>,
    emit_table: array<vec4<f32>, 32>,
}

// One lit march's medium and light volumes in its cell space: a drawer instance, or the
// renderer's one volume (`LitPlace::new`).
struct VdbLitPlace {
    // xyz: the cell-space image of the unit world direction toward the sun; w: the extinction
    // per unit density per length unit (density scale included).
    sun_cell: vec4<f32>,
    // xyz: length per cell-space unit along each axis (the diffusion's metric); w: the albedo.
    axis: vec4<f32>,
    // The light volumes of frames 0 and 1 (a crossfade): xyz the corner of cell 0 in cell space,
    // w the cell edge in voxels; xyz cells per axis, w the volume's base element.
    lv_lo0: vec4<f32>,
    lv_dims0: vec4<u32>,
    lv_lo1: vec4<f32>,
    lv_dims1: vec4<u32>,
    // Per frame (x, y: frame 0; z, w: frame 1): the near field toward the sun in voxels
    // (`LightGrid::near_voxels`; 0: none), a light-volume cell's edge in the length unit (the
    // shortest axis).
    near: vec4<f32>,
    // x, y: the full-resolution root offsets of frames 0 and 1.
    roots: vec4<u32>,
    // x: k of the sky's source (`lv_sky_source`); y: the crossfade weight of frame 1 (0: frame 0
    // alone); z: 1 where the drawer takes each sample from one frame of the crossfade
    // (`LitCrossfade::Dither`: `draw.wgsl`'s `draw_lit`), 0 where it lerps both.
    misc: vec4<f32>,
}

@group({{LIT_GROUP}}) @binding(0) var<storage, read> lit_tau: array<vec2<f32>>;
@group({{LIT_GROUP}}) @binding(1) var<storage, read> lit_ms: array<vec2<u32>>;

// Whether the march reads trilinear density (`Integrator::filter`).
fn lit_trilinear_on() -> bool {
    return {{SHADING}}.sky.w != 0.0;
}

// (τ_sun, τ_sky) of the light volume over (lo: corner, cell edge; dims: cells, base) at `p`.
fn lit_lookup(lo: vec4<f32>, dims: vec4<u32>, p: vec3<f32>) -> vec2<f32> {
    let t = lv_taps(p, lo.xyz, lo.w, dims.xyz);
    var out = vec2<f32>(0.0);
    for (var k = 0u; k < 8u; k++) {
        out += t.w[k] * lit_tau[dims.w + t.idx[k]];
    }
    return out;
}

// The diffusion model's (sun, sky) light of one light volume at `p` toward `eye`
// (`LightVolume::diffuse_at`).
fn lit_diffuse(lo: vec4<f32>, dims: vec4<u32>, p: vec3<f32>, eye: vec3<f32>) -> vec2<f32> {
    let t = lv_taps(p, lo.xyz, lo.w, dims.xyz);
    var acc: LvDiffuse;
    for (var k = 0u; k < 8u; k++) {
        let i = 3u * (dims.w + t.idx[k]);
        lv_diffuse_add(&acc, t.w[k], lit_ms[i], lit_ms[i + 1u], lit_ms[i + 2u]);
    }
    return lv_diffuse_read(acc, eye, {{SHADING}}.phase.w);
}

// `Tracer::near_sun_depth`: the depth toward the sun from `q` over `near` voxels walked through
// the frame at `root` (`hint_leaf`/`hint_ref`: a leaf whose holder the caller knows, −1 for
// none), the light volume's depth where the walk ends beyond.
fn lit_near_depth(P: VdbLitPlace, root: u32, lo: vec4<f32>, dims: vec4<u32>, q: vec3<f32>, near: f32, hint_leaf: vec3<i32>, hint_ref: u32) -> f32 {
    var ray: VdbRay;
    ray.o = q;
    ray.d = P.sun_cell.xyz;
    ray.per_t = select(1.0, length(ray.d), {{SHADING}}.voxel_units != 0u);
    let c = vdb_clip(ray, vdb_extent());
    if (!(c.y > c.x)) {
        return 0.0;
    }
    let t_near = near / length(ray.d);
    // The whole near field (no opaque stop: the octaves read e^{-b^i·σ·τ}).
    let tau = vdb_optical_depth_near_from(root, ray, c.x, min(c.y, t_near), 0.0, hint_leaf, hint_ref);
    if (t_near >= c.y) {
        return tau;
    }
    let p = ray.o + t_near * ray.d;
    let l = normalize(ray.d);
    let te = lv_box_entry(lo, dims.xyz, p, l);
    if (te < 0.0) {
        return tau;
    }
    return tau + lit_lookup(lo, dims, p + te * l).x;
}

// `Tracer::sun_depth`'s test for frame `f` (0 or 1) at a sample of density `rho` and primary
// transmittance `trans`: whether the near field is walked (one cell optically thick, the ray
// still bright).
fn lit_walks(P: VdbLitPlace, f: u32, rho: f32, trans: f32) -> bool {
    let near = select(P.near.xy, P.near.zw, f == 1u);
    return LIT_NEAR && near.x > 0.0 && P.sun_cell.w * rho * near.y >= LV_NEAR_DEPTH
        && trans >= LV_NEAR_TRANS;
}

// The light a lit sample at `q` (density `rho`, the primary ray's transmittance `trans`)
// scatters toward the eye per unit albedo·(1 − e^{−x}): the sun's and the sky's radiance times
// their sources (`LitMarch::light`). `eye`: the unit direction toward the eye in the diffusion's
// metric; `ph`: the sun's phase per octave at the ray's μ; `seg`: the segment's optical depth
// x, e^{−x} and its mean scattering depth as a fraction; the segment runs along `ray` from
// length `sa` over `len`, and where the near field is walked (`lit_walks`) the sun's depth is
// walked at `q` and at the segment's ends (`lv_segment_sun`), the entry's taken from `exit`
// (the last segment's end, its depth and `tag`, −1 for none) where it starts there; `exit`
// then holds this segment's. A crossfade lerps the frames' depths and diffusion light
// (`P.misc.y`).
fn lit_scattered(P: VdbLitPlace, ray: VdbRay, sa: f32, len: f32, q: vec3<f32>, rho: f32, trans: f32, eye: vec3<f32>, ph: ptr<function, array<f32, 8>>, seg: vec3<f32>, hint_leaf: vec3<i32>, hint_ref: u32, exit: ptr<function, vec3<f32>>, tag: f32) -> vec3<f32> {
    let ext = P.sun_cell.w;
    let a = P.misc.y;
    let frames = select(1u, 2u, a > 0.0);
    // The segment's ends, from the mean-depth point (not the ray's origin, whose f32 distance
    // would move them by more than a dense skin: `LitMarch::light`), just inside it
    // (`vdbcook_trace::SEGMENT_END`).
    let q0 = q + (len * (LV_SEGMENT_END - seg.z) / ray.per_t) * ray.d;
    let q1 = q + (len * (1.0 - LV_SEGMENT_END - seg.z) / ray.per_t) * ray.d;
    let joined = (*exit).z == tag && abs(sa - (*exit).x) <= LV_SEGMENT_JOIN * len;
    // Per frame the depth at `q`, the light volume's there, whether walked; the depths at the
    // ends (the one at `q` where that frame does not walk). All walks from one call site
    // (lavapipe inlines each): `q`, then the exit, then the entry unless joined.
    var tau_f = array<vec3<f32>, 2>(vec3<f32>(0.0), vec3<f32>(0.0));
    var ends = array<vec2<f32>, 2>(vec2<f32>(0.0), vec2<f32>(0.0));
    for (var f = 0u; f < frames; f++) {
        let one = f == 1u;
        let lo = select(P.lv_lo0, P.lv_lo1, one);
        let dims = select(P.lv_dims0, P.lv_dims1, one);
        let cells = lit_lookup(lo, dims, q).x;
        tau_f[f] = vec3<f32>(cells, cells, 0.0);
        ends[f] = vec2<f32>(cells);
        let walks = select(0u, select(3u, 2u, joined), lit_walks(P, f, rho, trans));
        let root = select(P.roots.x, P.roots.y, one);
        let near = select(P.near.x, P.near.z, one);
        for (var k = 0u; k < walks; k++) {
            // Only frame 0's walk at `q` knows the caller's leaf.
            let hinted = k == 0u && f == 0u;
            let d = lit_near_depth(P, root, lo, dims, select(select(q0, q1, k == 1u), q, k == 0u), near,
                select(vec3<i32>(-1), hint_leaf, hinted), select(VDB_EMPTY, hint_ref, hinted));
            if (k == 0u) {
                tau_f[f] = vec3<f32>(d, cells, 1.0);
                ends[f] = vec2<f32>(d);
            } else if (k == 1u) {
                ends[f].y = d;
            } else {
                ends[f].x = d;
            }
        }
    }
    var tau_sun = tau_f[0];
    var end = ends[0];
    if (a > 0.0) {
        tau_sun = mix(tau_f[0], tau_f[1], a);
        end = mix(ends[0], ends[1], a);
    }
    // The sun's transmittance at `q`, and its mean over the segment's scattering where the
    // near field was walked (`LitMarch::light`).
    let direct = exp(-ext * tau_sun.x);
    var direct_mean = direct;
    if (tau_sun.z > 0.0) {
        if (joined) {
            end.x = (*exit).y;
        }
        *exit = vec3<f32>(sa + len, end.y, tag);
        direct_mean = lv_segment_sun(seg.x, seg.y, seg.z, ext * vec3<f32>(end.x, tau_sun.x, end.y));
    } else {
        *exit = vec3<f32>(0.0, 0.0, -1.0);
    }
    var sun = 0.0;
    var sky = 0.0;
    if ({{SHADING}}.octaves == 0u) {
        // The diffusion model: single scattering plus the solve's sun (with the once-scattered
        // light below its cells where the near field was walked); the solve's sky.
        // Two frames lit by one light volume (a light stride's span: `Instance::light_stride`)
        // read it once: the lerp of a value with itself.
        let one_light = all(P.lv_dims0 == P.lv_dims1) && all(P.lv_lo0 == P.lv_lo1);
        let reads = select(frames, 1u, one_light);
        var d = array<vec2<f32>, 2>(vec2<f32>(0.0), vec2<f32>(0.0));
        for (var f = 0u; f < reads; f++) {
            let one = f == 1u;
            d[f] = lit_diffuse(select(P.lv_lo0, P.lv_lo1, one), select(P.lv_dims0, P.lv_dims1, one), q, eye);
        }
        var diffuse = d[0];
        if (reads == 2u) {
            diffuse = mix(d[0], d[1], a);
        }
        sun = (*ph)[0] * direct_mean
            + max(diffuse.x + lv_near_scatter({{SHADING}}.sun_color.w, P.axis.w, direct_mean, exp(-ext * tau_sun.y)), 0.0);
        sky = diffuse.y;
    } else {
        var tau_sky = lit_lookup(P.lv_lo0, P.lv_dims0, q).y;
        if (a > 0.0) {
            tau_sky = mix(tau_sky, lit_lookup(P.lv_lo1, P.lv_dims1, q).y, a);
        }
        sun = lv_octaves(ext * tau_sun.x, {{SHADING}}.ms.xyz, {{SHADING}}.octaves, ph)
            + (*ph)[0] * (direct_mean - direct);
        sky = lv_sky_source(ext * tau_sky, P.misc.x);
    }
    return {{SHADING}}.sun_color.xyz * sun + {{SHADING}}.sky.xyz * sky;
}

// The blackbody radiance of the march's own channel at value `v` (0 at or below the range):
// `vdbcook_scene::Emission::radiance`.
fn lit_emission(v: f32) -> vec3<f32> {
    let w = lv_emission_at(v, {{SHADING}}.emission);
    let i = u32(w.x);
    let c0 = {{SHADING}}.emit_table[i].xyz;
    return w.z * (c0 + w.y * ({{SHADING}}.emit_table[i + 1u].xyz - c0));
}

// Emission from channel `channel` along `ray` up to `t_end` in the frame at `root`
// (`vdbcook_trace::Tracer`'s `ChannelEmission`): over the voxels of the channel's box
// [box_lo, box_hi) inside the root extent, each
// `T · E · ℓ · φ(x)` with `x = ext·ρ·ℓ` (ρ: channel 0, nearest voxel), `T` starting from channel
// 0's exact optical depth from the extent's entry to the box's; stops once T < 1e-6. `ext` 0:
// no attenuation (delta tracking's track-length estimator over one flight). With the trilinear
// filter (`lit_trilinear_on`) each voxel's part reads both channels trilinearly at its midpoint
// (no voxel cubes in the glow), over the box grown by one voxel (the taps' reach).
fn lit_channel_emission(root: u32, ray: VdbRay, ext: f32, t_end: f32, channel: u32, box_lo: vec3<f32>, box_hi: vec3<f32>) -> vec3<f32> {
    var light = vec3<f32>(0.0);
    let smooth_taps = lit_trilinear_on();
    let grow = select(vec3<f32>(0.0), vec3<f32>(1.0), smooth_taps);
    let c = vdb_clip(ray, vdb_extent());
    let b = vdb_clip_box(ray, box_lo - grow, box_hi + grow);
    let a0 = max(c.x, b.x);
    let a1 = min(min(c.y, b.y), t_end);
    if (!(a0 < a1)) {
        return light;
    }
    var tau = 0.0;
    if (a0 > c.x && ext > 0.0) {
        tau = vdb_optical_depth(root, ray, c.x, a0, ext);
    }
    var trans = exp(-ext * tau);
    var d = vdb_dda_init(ray, 1.0, vec3<i32>(box_lo - grow), vec3<i32>(box_hi + grow), a0, a1);
    for (var i = 0; i < 1000000; i++) {
        let s = vdb_dda_next(ray, &d);
        if (!s.ok) {
            break;
        }
        let l = (s.tb - s.ta) * ray.per_t;
        var x = 0.0;
        let mid = ray.o + (0.5 * (s.ta + s.tb)) * ray.d;
        if (ext > 0.0) {
            var rho = 0.0;
            if (smooth_taps) {
                rho = vdb_trilinear(root, mid);
            } else {
                rho = vdb_value(root, s.cell);
            }
            if (rho > 0.0) {
                x = ext * rho * l;
            }
        }
        let e = exp(-x);
        var v = 0.0;
        if (smooth_taps) {
            v = vdb_trilinear_c(root, mid, channel);
        } else {
            v = vdb_value_c(root, s.cell, channel);
        }
        light += trans * l * lv_phi(x, e) * lit_emission(v);
        trans *= e;
        if (trans < 1.0e-6) {
            break;
        }
    }
    return light;
}

// The sun's phase per octave for a ray along unit world direction `dw`.
fn lit_sun_phases(dw: vec3<f32>) -> array<f32, 8> {
    return lv_sun_phases({{SHADING}}.phase.xyz, {{SHADING}}.ms.z, dot(dw, {{SHADING}}.sun.xyz));
}
