// shadow.wgsl — the sun's transmittance through a drawer's lit volumes at a world point, for an
// engine's own shaders: `vdb_sun_transmittance(world)` darkens its geometry under the smoke
// (multiply the sun's term by it). It exists so that the light volumes the drawer builds for its
// lit march (`light_build.wgsl`) also shadow the scene, at the cost of one ray-box test and one
// trilinear read per lit instance. Needs `light.wgsl` before it (`vdbcook_runtime::shadow_wgsl`
// puts it there); the bindings are in group 0 here, moved to the engine's group by that call.
// Bind `VolumeDrawer::sun_shadows`'s bind group there, from the same frame's encoder.
//
// Per lit instance (`VdbShadowInstance`, mirrored by `runtime/src/draw.rs`'s `ShadowInstance`):
// world → its cell space, the unit cell-space direction toward the sun and the extinction, and
// the light volumes of the two frames of its crossfade (grid and base element), lerped by the
// crossfade weight as the drawer lerps them. The depth at a point outside a light volume is the
// one where the ray toward the sun enters it (`vdbcook_trace::LightVolume::sun_depth_at`).

struct VdbShadowInstance {
    cell_from_world0: vec4<f32>,
    cell_from_world1: vec4<f32>,
    cell_from_world2: vec4<f32>,
    // xyz: unit cell-space direction toward the sun; w: extinction per unit density per length.
    sun: vec4<f32>,
    // Light volumes of the two frames: xyz corner of cell 0, w cell edge; xyz cells, w base.
    lo0: vec4<f32>,
    dims0: vec4<u32>,
    lo1: vec4<f32>,
    dims1: vec4<u32>,
    // x: the crossfade weight of the second frame.
    weight: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> vdb_shadow_instances: array<VdbShadowInstance>;
@group(0) @binding(1) var<storage, read> vdb_shadow_lv: array<vec2<f32>>;

// The sun's optical depth of one light volume at cell-space point `p` (`l`: toward the sun).
fn vdb_shadow_depth(lo: vec4<f32>, dims: vec4<u32>, p: vec3<f32>, l: vec3<f32>) -> f32 {
    let t0 = lv_box_entry(lo, dims.xyz, p, l);
    if (t0 < 0.0) {
        return 0.0;
    }
    let t = lv_taps(p + t0 * l, lo.xyz, lo.w, dims.xyz);
    var tau = 0.0;
    for (var k = 0u; k < 8u; k++) {
        tau += t.w[k] * vdb_shadow_lv[dims.w + t.idx[k]].x;
    }
    return tau;
}

// The sun's transmittance through every lit instance at world point `world` (1: no shadow).
fn vdb_sun_transmittance(world: vec3<f32>) -> f32 {
    var trans = 1.0;
    let w4 = vec4<f32>(world, 1.0);
    for (var i = 0u; i < arrayLength(&vdb_shadow_instances); i++) {
        let inst = vdb_shadow_instances[i];
        if (!(inst.sun.w > 0.0)) {
            continue;
        }
        let p = vec3<f32>(dot(inst.cell_from_world0, w4), dot(inst.cell_from_world1, w4),
                          dot(inst.cell_from_world2, w4));
        var tau = vdb_shadow_depth(inst.lo0, inst.dims0, p, inst.sun.xyz);
        if (inst.weight.x > 0.0) {
            tau = mix(tau, vdb_shadow_depth(inst.lo1, inst.dims1, p, inst.sun.xyz), inst.weight.x);
        }
        trans *= exp(-inst.sun.w * tau);
    }
    return trans;
}
