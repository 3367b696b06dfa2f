// light_build.wgsl — the lit mode's light-volume pass (`vdbcook_trace::LightVolume::build` on the
// GPU): `lv_density` box-filters the frame's voxels into the coarse cells, then `lv_tau` marches
// each cell's centre toward the sun through that density and sums it along the six axes into the
// sky's depth. Concatenated after `volume.wgsl` and `light.wgsl`; group 0 is the volume.
// Run once per frame and light (the renderer and the drawer cache it), each entry one invocation
// per cell.

struct LightParams {
    // xyz: corner of cell 0 (cell space); w: the cell edge in voxels.
    lo: vec4<f32>,
    // xyz: cells per axis; w: density sample points per cell axis.
    dims: vec4<u32>,
    // xyz: unit cell-space direction toward the light; w: length (in the settings' unit) per
    // cell-space unit along it.
    sun: vec4<f32>,
    // xyz: length per cell-space unit along each axis; w: the extinction (absorb + scatter).
    axis_len: vec4<f32>,
    frame_root: u32,
    // Element of cell 0 in `lv_tau` (several light volumes share one buffer; the density
    // scratch holds one at a time).
    base: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(1) @binding(0) var<uniform> lp: LightParams;
@group(1) @binding(1) var<storage, read_write> lv_density: array<f32>;
@group(1) @binding(2) var<storage, read_write> lv_tau: array<vec2<f32>>;

// Largest sky optical depth kept (`vdbcook_trace::LIT_MAX_SKY_DEPTH`).
const LV_MAX_SKY_DEPTH: f32 = 80.0;
// Most sun-march steps per cell: the diagonal of 256³ cells at half a cell per step.
const LV_MAX_STEPS: u32 = 1024u;

@compute @workgroup_size(4, 4, 4)
fn lv_density_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let dims = lp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let sub = lp.dims.w;
    let cell = lp.lo.w;
    var sum = 0.0;
    for (var k = 0u; k < sub * sub * sub; k++) {
        let q = vec3<u32>(k % sub, (k / sub) % sub, k / (sub * sub));
        let f = (vec3<f32>(gid) + (vec3<f32>(q) + vec3<f32>(0.5)) / f32(sub)) * cell;
        let a = vec3<i32>(floor(lp.lo.xyz + f));
        let v = vdb_value(lp.frame_root, a);
        if (v > 0.0) {
            sum += v;
        }
    }
    lv_density[lv_index(gid, dims)] = sum / f32(sub * sub * sub);
}

fn lv_density_at(p: vec3<f32>) -> f32 {
    let t = lv_taps(p, lp.lo.xyz, lp.lo.w, lp.dims.xyz);
    var d = 0.0;
    for (var k = 0u; k < 8u; k++) {
        d += t.w[k] * lv_density[t.idx[k]];
    }
    return d;
}

@compute @workgroup_size(4, 4, 4)
fn lv_tau_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let dims = lp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let cell = lp.lo.w;
    let lo = lp.lo.xyz;
    let p = lo + (vec3<f32>(gid) + vec3<f32>(0.5)) * cell;
    // The grid's far side along the light (`LightGrid::exit`).
    let l = lp.sun.xyz;
    let hi = lo + vec3<f32>(dims) * cell;
    var t_exit = 3.0e38;
    for (var a = 0; a < 3; a++) {
        if (l[a] > 0.0) {
            t_exit = min(t_exit, (hi[a] - p[a]) / l[a]);
        } else if (l[a] < 0.0) {
            t_exit = min(t_exit, (lo[a] - p[a]) / l[a]);
        }
    }
    let h = cell / 2.0;
    var sum = 0.0;
    for (var k = 0u; k < LV_MAX_STEPS; k++) {
        let t = (f32(k) + 0.5) * h;
        if (!(t < t_exit)) {
            break;
        }
        sum += lv_density_at(p + t * l);
    }
    let tau_sun = sum * h * lp.sun.w;
    // The six axis directions: half this cell plus every cell beyond it.
    let ext = lp.axis_len.w;
    let own = lv_density[lv_index(gid, dims)] / 2.0;
    var t_mean = 0.0;
    var tau_mean = 0.0;
    for (var a = 0; a < 3; a++) {
        for (var s = 0; s < 2; s++) {
            var acc = own;
            var c = vec3<i32>(gid);
            let dir = select(1, -1, s == 0);
            for (var n = 0u; n < 256u; n++) {
                c[a] += dir;
                if (c[a] < 0 || c[a] >= i32(dims[a])) {
                    break;
                }
                acc += lv_density[lv_index(vec3<u32>(c), dims)];
            }
            let tau = acc * cell * lp.axis_len[a];
            tau_mean += tau / 6.0;
            t_mean += exp(-ext * tau) / 6.0;
        }
    }
    var tau_sky = tau_mean;
    if (ext > 0.0) {
        tau_sky = max(-log(max(t_mean, exp(-LV_MAX_SKY_DEPTH))) / ext, 0.0);
    }
    lv_tau[lp.base + lv_index(gid, dims)] = vec2<f32>(tau_sun, tau_sky);
}
