// light.wgsl — the light volume of the lit mode, as both of its users read it: the trilinear
// lookup (`vdbcook_scene::LightGrid::taps`) and the octave source of multiple scattering
// (`vdbcook_scene::octave_source`). Concatenated into the tracer (which reads the volume) and
// into the light-volume pass (`light_build.wgsl`, which builds it). Nothing here binds anything.
//
// Layout of a light volume over `dims` cells: cell (x, y, z) is element x + dims.x·(y + dims.y·z);
// cell c covers lo + c·cell .. lo + (c + 1)·cell in cell space, its value sits at the centre;
// lookups clamp to the outermost centres.

const LV_MAX_OCTAVES: u32 = 8u;

struct LvTaps {
    idx: array<u32, 8>,
    w: array<f32, 8>,
}

fn lv_index(c: vec3<u32>, dims: vec3<u32>) -> u32 {
    return c.x + dims.x * (c.y + dims.y * c.z);
}

// The eight elements and weights of the trilinear lookup at cell-space point `p`.
fn lv_taps(p: vec3<f32>, lo: vec3<f32>, cell: f32, dims: vec3<u32>) -> LvTaps {
    let top = vec3<f32>(dims - vec3<u32>(1u));
    var u = clamp((p - lo) / cell - vec3<f32>(0.5), vec3<f32>(0.0), top);
    u = select(u, vec3<f32>(0.0), u != u);
    let base = min(floor(u), max(top - vec3<f32>(1.0), vec3<f32>(0.0)));
    let f = u - base;
    let i0 = vec3<u32>(base);
    let i1 = min(i0 + vec3<u32>(1u), dims - vec3<u32>(1u));
    var t: LvTaps;
    for (var k = 0u; k < 8u; k++) {
        let hi = vec3<bool>((k & 1u) != 0u, (k & 2u) != 0u, (k & 4u) != 0u);
        let c = select(i0, i1, hi);
        let wv = select(vec3<f32>(1.0) - f, f, hi);
        t.idx[k] = lv_index(c, dims);
        t.w[k] = wv.x * wv.y * wv.z;
    }
    return t;
}

// `vdbcook_scene::octave_source`: single scattering `ph[0]·e^{−x}` plus octaves i ≥ 1,
// `a^i·ph[i]·(e^{−b^i·x} − e^{−x})`.
fn lv_octaves(x: f32, ms: vec3<f32>, octaves: u32, ph: ptr<function, array<f32, 8>>) -> f32 {
    let direct = exp(-x);
    var s = (*ph)[0] * direct;
    var ai = 1.0;
    var bi = 1.0;
    for (var i = 1u; i < min(octaves, LV_MAX_OCTAVES); i++) {
        ai *= ms.x;
        bi *= ms.y;
        s += ai * (*ph)[i] * (exp(-bi * x) - direct);
    }
    return s;
}
