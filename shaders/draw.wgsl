// draw.wgsl — the engine drawer (`vdbcook_runtime::VolumeDrawer`): it exists so that volumes can
// be drawn into an engine's own frame — its view and projection, its depth buffer, its colour
// target — rather than into an image of their own. Two entry points:
//
// - `draw_main` (compute, one invocation per pixel): unprojects the pixel centre (+ jitter)
//   through the engine's projection, cuts the ray at the engine's depth (a `Depth32Float`
//   texture, standard or reversed Z, `textureLoad`), and marches every instance of the volume
//   with the density march (`vdb_optical_depth` in `volume.wgsl`: the CPU tracer's Density mode),
//   front to back in the order the CPU sorted them, writing premultiplied radiance and
//   transmittance (L, T) to an `Rgba16Float` storage texture.
// The composite that blends (L, T) over the engine's colour target is `composite.wgsl`.
//
// Concatenated after `volume.wgsl` (group 0: the volume). Group 1: the view (uniform), the
// instances (storage), the scene depth, the (L, T) output. The structs mirror `runtime/src/
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
    _pad0: u32,
    _pad1: u32,
}

@group(1) @binding(0) var<uniform> draw_view: DrawView;
@group(1) @binding(1) var<storage, read> draw_instances: array<DrawInstance>;
@group(1) @binding(2) var draw_depth: texture_depth_2d;
@group(1) @binding(3) var draw_out: texture_storage_2d<rgba16float, write>;

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
