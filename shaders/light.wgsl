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

// `vdbcook_trace::lit::exp_piece`: ∫₀^l e^{−E(v)} dv for E linear from `a` to `b` over `l`
// (the series of sinh(g/2)/(g/2) where the difference would cancel).
fn lv_exp_piece(a: f32, b: f32, l: f32) -> f32 {
    let g = b - a;
    let series = l * exp(-0.5 * (a + b)) * (1.0 + g * g / 24.0);
    return select(l * (exp(-a) - exp(-b)) / g, series, abs(g) < 1e-2);
}

// `vdbcook_trace::lit::segment_sun`: the sun's direct light a segment of optical depth `x`
// (`ex` = e^{−x}) scatters per unit of its 1 − e^{−x}, from the sun's optical depths `d` walked
// at its entry, at its mean scattering depth (fraction `m`) and at its exit, linear between.
fn lv_segment_sun(x: f32, ex: f32, m: f32, d: vec3<f32>) -> f32 {
    let em = x * m + d.y;
    return (lv_exp_piece(d.x, em, m) + lv_exp_piece(em, x + d.z, 1.0 - m)) / lv_phi(x, ex);
}

// `vdbcook_trace::SEGMENT_JOIN`: how close (a fraction of its length) a segment must start to
// the last one's end to reuse the sun's depth walked there.
const LV_SEGMENT_JOIN: f32 = 1e-3;
// `vdbcook_trace::SEGMENT_END`: where a segment's ends are walked, a fraction from each end.
const LV_SEGMENT_END: f32 = 1e-3;

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

// `vdbcook_trace::exact::phi`: `(1 − e^{−x})/x`, the weight of a step's emission absorbed within
// the step, `e = e^{−x}` given (its series below 10⁻³, where the quotient cancels).
fn lv_phi(x: f32, e: f32) -> f32 {
    return select((1.0 - e) / x, 1.0 - x / 2.0 + x * x / 6.0, x < 1e-3);
}

// The sun's phase for each octave at cosine `mu`: the dual-lobe phase (g0, g1, weight) with both
// g scaled by `c^i` for octave i.
fn lv_sun_phases(phase: vec3<f32>, c: f32, mu: f32) -> array<f32, 8> {
    var ph: array<f32, 8>;
    var ci = 1.0;
    for (var i = 0u; i < LV_MAX_OCTAVES; i++) {
        ph[i] = lv_phase(phase, ci, mu);
        ci *= c;
    }
    return ph;
}

// `vdbcook_scene::near_scatter_source`: the once-scattered sunlight below the light volume's
// cells, `k·α/4π·(T − T_cells)`, from the walked transmittance toward the sun `t` and the light
// volume's `t_cells` at the same point.
fn lv_near_scatter(k: f32, albedo: f32, t: f32, t_cells: f32) -> f32 {
    return k * albedo * 0.07957747154594767 * (t - t_cells);
}

// `vdbcook_scene::sky_source`: the sky's source at sky optical depth y, diffusion attenuation k.
fn lv_sky_source(y: f32, k: f32) -> f32 {
    let direct = exp(-y);
    return direct + (1.0 - direct) * exp(-k * y);
}

// The diffusion model's light (`vdbcook_trace::LightVolume::diffuse_at`), summed over the
// eight taps of a light volume's cells (six words per cell: `light_build.wgsl`'s
// `ms_store_main`, density-premultiplied) by `lv_diffuse_add`, then read toward the eye by
// `lv_diffuse_read`.
struct LvDiffuse {
    // Σ w·(ρ·φ_sun/4π, ρ·φ_sky/4π, ρ).
    phi: vec3<f32>,
    // Σ w·ρ·J/4π of the sun's field and of the sky's.
    j_sun: vec3<f32>,
    j_sky: vec3<f32>,
}

// `vdbcook_scene::MS_FLUX_RATIO`: the largest |J|/φ per axis a light volume stores.
const MS_FLUX_RATIO: f32 = 8.0;

// One cell's six words, read as three pairs (ρ·φ_sun/4π, ρ·φ_sky/4π), (ρ, J_sun.xy), (J_sun.z
// and J_sky.x, J_sky.yz): the f32s as bits, each flux as J/φ in 16 bits; added with weight `w`.
fn lv_diffuse_add(acc: ptr<function, LvDiffuse>, w: f32, a: vec2<u32>, b: vec2<u32>, c: vec2<u32>) {
    let phi = vec3<f32>(bitcast<vec2<f32>>(a), bitcast<f32>(b.x));
    let s = unpack2x16snorm(b.y);
    let m = unpack2x16snorm(c.x);
    let k = unpack2x16snorm(c.y);
    (*acc).phi += w * phi;
    (*acc).j_sun += (w * MS_FLUX_RATIO * phi.x) * vec3<f32>(s, m.x);
    (*acc).j_sky += (w * MS_FLUX_RATIO * phi.y) * vec3<f32>(m.y, k);
}

// (sun, sky): each `φ/4π + 3ḡ·J·ω/4π` (at least 0), `eye` the unit direction toward the eye in
// the solve's metric (`lv_eye_dir`); the light outside the medium, (0, 1), where all eight
// cells are empty.
fn lv_diffuse_read(acc: LvDiffuse, eye: vec3<f32>, mean_cos: f32) -> vec2<f32> {
    let den = acc.phi.z;
    if (!(den > 0.0)) {
        return vec2<f32>(0.0, 1.0);
    }
    let jw = vec2<f32>(dot(acc.j_sun, eye), dot(acc.j_sky, eye));
    return max((acc.phi.xy + 3.0 * mean_cos * jw) / den, vec2<f32>(0.0));
}

// `vdbcook_trace::LightVolume::eye_dir`: the unit direction toward the eye of a ray along
// cell-space `d`, in length units per axis (`axis_len`).
fn lv_eye_dir(d: vec3<f32>, axis_len: vec3<f32>) -> vec3<f32> {
    return normalize(-d * axis_len);
}

// Where the ray from cell-space point `p` along `l` enters the light volume's box (corner
// `lo.xyz`, cell edge `lo.w`, `dims` cells): its parameter (0 when `p` is inside), or −1 when
// it misses (`vdbcook_trace::LightVolume::sun_depth_at`).
fn lv_box_entry(lo: vec4<f32>, dims: vec3<u32>, p: vec3<f32>, l: vec3<f32>) -> f32 {
    let hi = lo.xyz + vec3<f32>(dims) * lo.w;
    var t0 = 0.0;
    var t1 = 3.0e38;
    for (var a = 0; a < 3; a++) {
        if (l[a] == 0.0) {
            if (!(p[a] >= lo[a] && p[a] <= hi[a])) {
                return -1.0;
            }
        } else {
            let u = (lo[a] - p[a]) / l[a];
            let v = (hi[a] - p[a]) / l[a];
            t0 = max(t0, min(u, v));
            t1 = min(t1, max(u, v));
        }
    }
    return select(-1.0, t0, t1 >= t0);
}

// Optical depth of one light-volume cell below which a lit march reads the sun's depth from the
// light volume alone, whatever the cells' width (`vdbcook_scene::LIT_NEAR_DEPTH`).
const LV_NEAR_DEPTH: f32 = 0.25;
// The primary ray's transmittance below which it does not walk (`vdbcook_trace::LIT_NEAR_TRANS`).
const LV_NEAR_TRANS: f32 = 0.05;
// Longest near field, in voxels (`vdbcook_trace::LIT_NEAR_MAX_VOXELS`).
const LV_NEAR_MAX_VOXELS: f32 = 1024.0;

// Transmittance below which a lit march stops (`vdbcook_trace::LIT_MIN_TRANS`).
const LV_MIN_TRANS: f32 = 1e-4;

// `vdbcook_trace::pcg_hash`.
fn pcg_hash(x: u32) -> u32 {
    let state = x * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// `vdbcook_trace::lit_jitter`: the per-pixel offset of the lit march's samples, in [0, 1).
fn lv_jitter(seed: u32, pixel: u32) -> f32 {
    return f32(pcg_hash(seed ^ pcg_hash(pixel)) >> 8u) / 16777216.0;
}

// `vdbcook_trace::lit::mean_depth`: where in a step of optical depth x light is scattered on
// average, as a fraction of the step.
fn lv_mean_depth(x: f32, ex: f32) -> f32 {
    // Below ½ the series: the closed form cancels in f32 for thin steps. Above it
    // `1/(eˣ − 1) = e^{−x}/(1 − e^{−x})` from the caller's `ex` = e^{−x} (no overflow either).
    let x2 = x * x;
    let series = 0.5 - x / 12.0 + x * x2 / 720.0 - x * x2 * x2 / 30240.0;
    return select(1.0 / x - ex / (1.0 - ex), series, x < 0.5);
}

fn lv_hg(g: f32, mu: f32) -> f32 {
    let d = 1.0 + g * g - 2.0 * g * mu;
    return (1.0 - g * g) / (12.566370614359172 * d * sqrt(d));
}

// The dual-lobe phase (g0, g1, weight) with both g scaled by `scale`, at cosine `mu`.
fn lv_phase(phase: vec3<f32>, scale: f32, mu: f32) -> f32 {
    return phase.z * lv_hg(phase.x * scale, mu) + (1.0 - phase.z) * lv_hg(phase.y * scale, mu);
}

// Where a value `v` falls in the blackbody table of emission `e` (x, y: the channel's value
// range, z: intensity; the table spans the emission's Kelvin range): (index i, fraction f, brightness b), the radiance being
// `b · mix(table[i], table[i + 1], f)` (`vdbcook_scene::Emission::radiance`); b = 0 at or below
// the range. The caller reads its own table (a uniform array cannot be passed by pointer).
fn lv_emission_at(v: f32, e: vec4<f32>) -> vec3<f32> {
    if (!(v > e.x)) {
        return vec3<f32>(0.0);
    }
    let s = min((v - e.x) / (e.y - e.x), 1.0);
    let x = s * 31.0;
    let i = min(floor(x), 30.0);
    return vec3<f32>(i, x - i, e.z * s * s * s * s);
}
