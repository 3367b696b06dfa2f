// light_build.wgsl — the lit mode's light-volume passes (`vdbcook_trace::LightVolume::build` on
// the GPU), in this order: `lv_density_main` box-filters the frame's voxels into the coarse
// cells (and, after them in the scratch, each cell's transport density for the solve);
// `lv_sun_main` walks each cell's centre's voxels toward the sun (and, third in the scratch,
// keeps the depth where that walk leaves the cell); `lv_axis{0,1,2}_main` sum it
// along each axis's columns in both directions into τ_sky's accumulator; `lv_sky_main` turns
// that into τ_sky. Concatenated after `volume.wgsl` and `light.wgsl`; group 0 is the volume.
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
    // Level of detail the density pass reads (`LightGrid::density_level`); `frame_root` is that
    // level's root set.
    level: u32,
    // The asset of the volume set whose density it reads (`vdb_select`).
    asset: u32,
    // x: the extinction at which the sun pass stops a cell's walk at the opaque depth, 0 for
    // none (`vdbcook_scene::sun_pass_stop`).
    stop: vec4<f32>,
}

@group(1) @binding(0) var<uniform> lp: LightParams;
@group(1) @binding(1) var<storage, read_write> lv_density: array<f32>;
@group(1) @binding(2) var<storage, read_write> lv_tau: array<vec2<f32>>;

// Largest sky optical depth kept (`vdbcook_trace::LIT_MAX_SKY_DEPTH`).
const LV_MAX_SKY_DEPTH: f32 = 80.0;
// `vdbcook_scene::MAX_SUB`: density samples per cell axis at most, their count per cell and per
// axis's columns (the density pass keeps a cell's samples for `lv_transport`).
const LV_MAX_SUB: u32 = 4u;
const LV_MAX_SUB_SAMPLES: u32 = 64u;
const LV_MAX_SUB_COLUMNS: u32 = 16u;

@compute @workgroup_size(4, 4, 4)
fn lv_density_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    vdb_select(lp.asset);
    let dims = lp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let sub = lp.dims.w;
    let cell = lp.lo.w;
    var values: array<f32, LV_MAX_SUB_SAMPLES>;
    var sum = 0.0;
    for (var k = 0u; k < sub * sub * sub; k++) {
        let q = vec3<u32>(k % sub, (k / sub) % sub, k / (sub * sub));
        let f = (vec3<f32>(gid) + (vec3<f32>(q) + vec3<f32>(0.5)) / f32(sub)) * cell;
        let a = vec3<i32>(floor(lp.lo.xyz + f)) >> vec3<u32>(lp.level);
        var v = vdb_value(lp.frame_root, a);
        if (!(v > 0.0)) {
            v = 0.0;
        }
        values[k] = v;
        sum += v;
    }
    let i = lv_index(gid, dims);
    let mean = sum / f32(sub * sub * sub);
    lv_density[i] = mean;
    lv_density[dims.x * dims.y * dims.z + i] = lv_transport(&values, sub, mean);
}

// `vdbcook_scene::transport_density`: the density of a uniform cell as transparent across
// itself as the cell's `sub³` samples `values` (mean `mean`) are, the harmonic mean of the
// three axes' (the diffusion solve's face resistances take it; `ms_source_main`).
fn lv_transport(values: ptr<function, array<f32, LV_MAX_SUB_SAMPLES>>, sub: u32, mean: f32) -> f32 {
    let ext = lp.axis_len.w;
    if (sub <= 1u || sub > LV_MAX_SUB || !(mean > 0.0) || !(ext > 0.0)) {
        return mean;
    }
    var sum = 0.0;
    for (var a = 0u; a < 3u; a++) {
        let len = ext * lp.lo.w * lp.axis_len[a];
        if (!(len > 0.0)) {
            return mean;
        }
        let ua = (a + 1u) % 3u;
        let va = (a + 2u) % 3u;
        var taus: array<f32, LV_MAX_SUB_COLUMNS>;
        var least = 3.0e38;
        for (var k = 0u; k < sub * sub; k++) {
            var q = vec3<u32>(0u);
            q[ua] = k % sub;
            q[va] = k / sub;
            var t = 0.0;
            for (var s = 0u; s < sub; s++) {
                q[a] = s;
                t += (*values)[q.x + sub * (q.y + sub * q.z)];
            }
            taus[k] = t * len / f32(sub);
            least = min(least, taus[k]);
        }
        var m = 0.0;
        for (var k = 0u; k < sub * sub; k++) {
            m += exp(least - taus[k]);
        }
        m /= f32(sub * sub);
        sum += 1.0 / min((least - log(m)) / len, mean);
    }
    return 3.0 / sum;
}

// τ_sun per cell (`vdbcook_trace::lit::sun_depth_exact`): the exact optical depth from the
// cell's centre toward the light to the grid's far side, through the voxels of the level the
// density pass read (`vdb_optical_depth` in that level's cell space, stopping at the opaque
// depth where `lp.stop.x` says); τ_sky's accumulator cleared. For a volume that solves
// the diffusion model (`lp.stop.y`) the walk is split where the ray leaves the cell
// (`LightGrid::centre_exit`): the depth from there, where the sun's beam enters the cell, goes
// after the transport densities in the density scratch for `ms_source_main`.
@compute @workgroup_size(4, 4, 4)
fn lv_sun_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    vdb_select(lp.asset);
    let dims = lp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let cell = lp.lo.w;
    let lo = lp.lo.xyz;
    let p = lo + (vec3<f32>(gid) + vec3<f32>(0.5)) * cell;
    let l = lp.sun.xyz;
    // The grid's far side along the light (`LightGrid::exit`).
    let hi = lo + vec3<f32>(dims) * cell;
    var t_exit = 3.0e38;
    for (var a = 0; a < 3; a++) {
        if (l[a] > 0.0) {
            t_exit = min(t_exit, (hi[a] - p[a]) / l[a]);
        } else if (l[a] < 0.0) {
            t_exit = min(t_exit, (lo[a] - p[a]) / l[a]);
        }
    }
    t_exit = max(t_exit, 0.0);
    let scale = 1.0 / f32(1u << lp.level);
    var ray: VdbRay;
    ray.o = p * scale;
    ray.d = l * scale;
    ray.per_t = lp.sun.w;
    let i = lv_index(gid, dims);
    if (lp.stop.y == 0.0) {
        lv_tau[lp.base + i] = vec2<f32>(vdb_optical_depth(lp.frame_root, ray, 0.0, t_exit, lp.stop.x), 0.0);
        return;
    }
    var split = 3.0e38;
    for (var a = 0; a < 3; a++) {
        if (l[a] != 0.0) {
            split = min(split, 0.5 * cell / abs(l[a]));
        }
    }
    split = min(split, t_exit);
    let entry = vdb_optical_depth(lp.frame_root, ray, split, t_exit, lp.stop.x);
    // Within the cell (a few voxels): the flat walk, no opaque stop.
    let tau = vdb_optical_depth_near(lp.frame_root, ray, 0.0, split, 0.0) + entry;
    lv_tau[lp.base + i] = vec2<f32>(tau, 0.0);
    lv_density[2u * dims.x * dims.y * dims.z + i] = entry;
}

// One column along `axis` (one invocation per cell of the other two axes): the depths toward
// −axis and +axis of each of its cells, added to τ_sky's accumulator as the mean transmittance
// (extinction > 0) or the mean depth (`LightVolume::build`'s running sums).
fn lv_axis(gid: vec3<u32>, axis: u32) {
    let dims = lp.dims.xyz;
    let ua = (axis + 1u) % 3u;
    let va = (axis + 2u) % 3u;
    if (gid.x >= dims[ua] || gid.y >= dims[va]) {
        return;
    }
    var c = vec3<u32>(0u);
    c[ua] = gid.x;
    c[va] = gid.y;
    var total = 0.0;
    for (var k = 0u; k < dims[axis]; k++) {
        c[axis] = k;
        total += lv_density[lv_index(c, dims)];
    }
    let len = lp.lo.w * lp.axis_len[axis];
    let ext = lp.axis_len.w;
    var before = 0.0;
    for (var k = 0u; k < dims[axis]; k++) {
        c[axis] = k;
        let i = lp.base + lv_index(c, dims);
        let own = lv_density[lv_index(c, dims)];
        var acc = lv_tau[i].y;
        for (var s = 0u; s < 2u; s++) {
            let d = select(before + own / 2.0, total - before - own / 2.0, s == 1u);
            let t = max(d, 0.0) * len;
            acc += select(t, exp(-ext * t), ext > 0.0) / 6.0;
        }
        lv_tau[i].y = acc;
        before += own;
    }
}

@compute @workgroup_size(8, 8, 1)
fn lv_axis0_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    lv_axis(gid, 0u);
}
@compute @workgroup_size(8, 8, 1)
fn lv_axis1_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    lv_axis(gid, 1u);
}
@compute @workgroup_size(8, 8, 1)
fn lv_axis2_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    lv_axis(gid, 2u);
}

// τ_sky from its accumulator (`vdbcook_trace::sky_depth`).
@compute @workgroup_size(4, 4, 4)
fn lv_sky_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let dims = lp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let i = lp.base + lv_index(gid, dims);
    let ext = lp.axis_len.w;
    var tau_sky = lv_tau[i].y;
    if (ext > 0.0) {
        tau_sky = max(-log(max(tau_sky, exp(-LV_MAX_SKY_DEPTH))) / ext, 0.0);
    }
    lv_tau[i].y = tau_sky;
}

// ---- The diffusion model of multiple scattering (`vdbcook_trace::diffusion`) ---------------
// Two fields per cell: the sun's scattered light (source: the beam's first scattering, nothing
// comes in from outside) and the sky's light (no source, a uniform radiance of 1 comes in
// through the boundary: φ = 4π outside the medium). Run after the passes above for the same
// volume (they leave its cell densities, transport densities and the sun's entry depths in
// `lv_density`, τ_sun and τ_sky in `lv_tau`):
// `ms_source_main` fills level 0 and `ms_restrict_main` each coarser level from the finer one;
// `ms_paths_main` (from the coarsest level down to `MS_SHARED_PATHS`) and `ms_gather_main`
// gather level 0's once-scattered light through them and `ms_second_main`
// makes the light it scatters again the source (and its beams), `ms_restrict_main` each
// coarser level's again, the same two passes gather the light scattered twice and make its
// light scattered again the solve's source (the solve carries the light scattered three times
// and more), `ms_restrict_main` once more,
// then from the coarsest level down `ms_prolong_main` starts a level from its parent (the
// boundary's φ at the coarsest) and `ms_sweeps(level)` Jacobi sweeps of `ms_limit_main` +
// `ms_update_main` run there (an even number: the result ends in φ A); one more
// `ms_limit_main` on level 0's result, then `ms_store_main` writes per cell of level 0 into
// `lv_ms_out` (six words: ρ·φ_sun/4π, ρ·φ_sky/4π, ρ as f32, then J/φ per axis of both fields
// in 16 bits, `ms_store_main`; the sun's φ and J are the solve's plus the gathered ones),
// which the tracer and the drawer read density-weighted (`lv_diffuse_*` in `light.wgsl`).
// One `MsParams` record per level and sweep parity (bound with a dynamic offset).

struct MsParams {
    // xyz: this level's cells per axis; w: the sweep's parity (0: φ in A → B, 1: B → A).
    dims: vec4<u32>,
    // x: this level's first element in `lv_ms`; y: its finer child's; z: its coarser
    // parent's; w: 1 when it has a parent.
    off: vec4<u32>,
    // xyz: the child's cells per axis; w: how many levels the solve has.
    child: vec4<u32>,
    // xyz: the parent's cells per axis; w: the orders gathered before the solve (0–2).
    parent: vec4<u32>,
    // xyz: the cell edge per axis (length unit); w: the albedo.
    h: vec4<f32>,
    // x: the phase's mean cosine; y: the sun's chord per cell slab; z: the extinction.
    medium: vec4<f32>,
    // The gather's 26 direction weights (`DiffusionInputs::gather`, in `ms_gather_dirs`'
    // order), four per element; the last two unused.
    gather: array<vec4<f32>, 7>,
    // xyz: the phase (g0, g1, the first lobe's weight); w unused.
    phase: vec4<f32>,
    // xyz: each direction's share of the sphere by how many axes it moves along
    // (`vdbcook_scene::MS_GATHER_WEIGHTS`); w unused.
    share: vec4<f32>,
    // Every level of the solve (`child.w` of them): xyz its cells per axis, w its first
    // element in `lv_ms` (the gather reads them all).
    levels: array<vec4<u32>, 8>,
    // x: this level's index (0: the light volume's cells).
    level: vec4<u32>,
    // Per level (four per element), the first element in `lv_ms` of its shared gather paths
    // (26 per cell, `ms_paths_main`), from level `MS_SHARED_PATHS` up; 0 below.
    paths: array<vec4<u32>, 2>,
}

// Per level at `off.x` over n cells: st [0, n), sr [n, 2n), q [2n, 3n), φ A [3n, 5n) and
// φ B [5n, 7n) (two per cell: sun, sky), the half-cell resistances [7n, 9n) (two per cell, one
// per field: `3·sr + |∇φ|/φ`, the resistance along axis a being ½·h_a times it), the sun's
// open faces [9n, 15n) (`ms_vacuum_main`: per axis the face's resistance less the cell's half
// and the far side's φ, six per cell). Before the solve the gather keeps each level's
// beam sources in the resistances' and open faces' place, [7n, 12n) (five per cell:
// `vdbcook_trace::diffusion`'s `Level::beam`), level 0's second-order φ in [12n, 13n) (both
// over before `ms_vacuum_main` writes there), and each level's shared gather paths
// (`ms_paths_main`, `mp.paths`)
// in the φ A and φ B place, [3n, 7n), of the level below where they fit (else after the
// levels); the gathered light of both orders (φ, then J per axis) waits in the first four of
// the cell's six output words in `lv_ms_out` (`ms_gathered`), which `ms_store_main` reads
// before it writes them.
@group(2) @binding(0) var<storage, read_write> lv_ms: array<f32>;
@group(2) @binding(1) var<uniform> mp: MsParams;
@group(2) @binding(2) var<storage, read_write> lv_ms_out: array<u32>;

// `vdbcook_trace::diffusion::MS_VACUUM`.
const MS_VACUUM: f32 = 2.0;
// `vdbcook_scene::MS_VACUUM_MAX_X`, `MS_VACUUM_MAX_Y`.
const MS_VACUUM_MAX_X: f32 = 40.0;
const MS_VACUUM_MAX_Y: f32 = 4.0;
// `vdbcook_scene::MS_VACUUM_FAR_X`.
const MS_VACUUM_FAR_X: f32 = 20.0;
// `vdbcook_scene::MS_GATHER_MIN_TRANS`.
const MS_GATHER_MIN_TRANS: f32 = 1e-3;
// `vdbcook_scene::MS_SHARED_PATHS`.
const MS_SHARED_PATHS: u32 = 1u;
// 4π: the sky field's φ outside the medium (`vdbcook_trace::diffusion`'s boundary).
const MS_FOUR_PI: f32 = 12.566370614359172;

fn ms_cells(d: vec3<u32>) -> u32 {
    return d.x * d.y * d.z;
}

// Field `f`'s φ outside the medium (0: the sun's, 1: the sky's).
fn ms_boundary(f: u32) -> f32 {
    return select(0.0, MS_FOUR_PI, f == 1u);
}

@compute @workgroup_size(4, 4, 4)
fn ms_source_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let dims = mp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let i = lv_index(gid, dims);
    let n = ms_cells(dims);
    let o = mp.off.x;
    let albedo = mp.h.w;
    let chord = mp.medium.y;
    let ext = mp.medium.z;
    let st = ext * max(lv_density[i], 0.0);
    let x = st * chord;
    // The sun's depth where its beam enters the cell (`lv_sun_main`).
    let entry = ext * lv_density[2u * n + i];
    lv_ms[o + i] = st;
    // The faces' resistances take the cell's transport density (`lv_transport`).
    let moves = select(0.0, ext * max(lv_density[n + i], 0.0), st > 0.0);
    lv_ms[o + n + i] = moves * (1.0 - mp.medium.x * albedo);
    lv_ms[o + 2u * n + i] = albedo * exp(-entry) * (1.0 - exp(-x)) / chord;
}

// (1 − e^{−x})/x given `ex` = e^{−x} (one `exp` serves it and the transmittance), without f32's
// cancellation at small x: below 0.05 the series to x³ (truncation under 6·10⁻⁸ relative;
// `1 − e^{−x}` in f32 would lose up to 10⁻⁴ there), above it directly (the CPU's `exp_m1`
// agrees to f32 rounding).
fn ms_one_minus_over(x: f32, ex: f32) -> f32 {
    var v = (1.0 - ex) / x;
    if (x < 0.05) {
        v = 1.0 - x * (0.5 - x * (1.0 / 6.0 - x / 24.0));
    }
    return v;
}

// `vdbcook_scene::ms_own_cell`: the own cell's light per unit source and length and the
// transmittance to the next step, both averaged over the cell's points along the direction.
fn ms_own_cell(x: f32) -> vec2<f32> {
    if (x < 0.5) {
        let own = 0.5 - x * (1.0 / 6.0 - x * (1.0 / 24.0 - x * (1.0 / 120.0
            - x * (1.0 / 720.0 - x * (1.0 / 5040.0 - x / 40320.0)))));
        return vec2<f32>(own, 1.0 - x * own);
    }
    let t = ms_one_minus_over(x, exp(-x));
    return vec2<f32>((1.0 - t) / x, t);
}

// Level 0, after `ms_restrict_main` on every coarser level: the sun's light scattered once
// (parity 0: the sources `ms_source_main` wrote, weights `mp.gather`; into the gathered sum,
// `ms_gathered`) or twice (parity 1: the sources and beams `ms_second_main` wrote, weights
// `mp.share`, the beams by the phase; its φ into [12n, 13n), all of it added to the sum),
// gathered along the 26 directions toward each cell's neighbours, the steps widening through
// the coarser levels and taking the shared paths' light from level `MS_SHARED_PATHS` on
// (`ms_paths_main`, run on every level from the coarsest down to that one first;
// `vdbcook_trace::diffusion`'s `gather`, which states the method: the same cells in the same
// order, in integers): φ, and J (that light flows back along each direction).
@compute @workgroup_size(4, 4, 4)
fn ms_gather_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let dims = mp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let i = lv_index(gid, dims);
    let n = ms_cells(dims);
    let o = mp.off.x;
    let twice = mp.dims.w == 1u;
    let st0 = lv_ms[o + i];
    var out = vec4<f32>(0.0);
    let top = mp.child.w - 1u;
    if (st0 > 0.0) {
        for (var d = 0u; d < 26u; d++) {
            let e = ms_gather_dir(d);
            var w = mp.gather[d / 4u][d % 4u];
            if (twice) {
                w = ms_share(e);
            }
            let v = vec3<f32>(e) * mp.h.xyz;
            let len = length(v);
            let u = v / len;
            let own = ms_own_cell(st0 * len);
            var r = ms_emit(0u, i, n, u, twice) * len * own.x;
            var t = own.y;
            // Level by level: two steps on each (from level 0), on the coarsest until the grid
            // ends, and from level `MS_SHARED_PATHS` the shared path of the cell reached. The
            // first step of level k starts `m = 2^(k+1) − 2` whole cells past the own cell
            // (0 on level 0) and reads the cell of its level that holds its middle, twice of
            // which in level-0 cells is `2g + 1 + e·(2m + 1 + 2^k)`: a shift by k + 1 finds it
            // (an arithmetic shift floors: a middle before the grid is a negative cell); the
            // next step is the next cell along `e`.
            var k = 0u;
            var walking = true;
            loop {
                let level = mp.levels[k];
                let step = 1u << k;
                let m = select(2u * step - 2u, 0u, k == 0u);
                let p2 = 2 * vec3<i32>(gid) + vec3<i32>(1) + e * i32(2u * m + 1u + step);
                var x = p2 >> vec3<u32>(k + 1u);
                let along = f32(step) * len;
                var left = select(2u, 0xffffffffu, k == top);
                loop {
                    if (any(x < vec3<i32>(0)) || any(vec3<u32>(x) >= level.xyz)) {
                        walking = false;
                        break;
                    }
                    let j = lv_index(vec3<u32>(x), level.xyz);
                    if (k == MS_SHARED_PATHS) {
                        // The rest is the path from this cell (`ms_paths_main`).
                        r += t * lv_ms[ms_path_at(k, j) + d];
                        walking = false;
                        break;
                    }
                    let s = ms_step(k, j, ms_cells(level.xyz), u, along, twice);
                    r += t * s.x;
                    t *= s.y;
                    if (t < MS_GATHER_MIN_TRANS) {
                        walking = false;
                        break;
                    }
                    left -= 1u;
                    if (left == 0u) {
                        break;
                    }
                    x += e;
                }
                if (!walking || k == top) {
                    break;
                }
                k += 1u;
            }
            out += w * r * vec4<f32>(1.0, -u);
        }
    }
    let at = ms_gathered(i);
    if (twice) {
        lv_ms[o + 12u * n + i] = out.x;
        for (var c = 0u; c < 4u; c++) {
            lv_ms_out[at + c] = bitcast<u32>(bitcast<f32>(lv_ms_out[at + c]) + out[c]);
        }
    } else {
        for (var c = 0u; c < 4u; c++) {
            lv_ms_out[at + c] = bitcast<u32>(out[c]);
        }
    }
}

// Cell `j` of level `k` (`n` cells) as one gather step of length `along` toward −u: the light
// it sends to the step's start, `q(1 − e^{−σL})/σ` (before the transmittance to it), and its
// transmittance `e^{−σL}`; (0, 1) where the cell is empty. One return (lavapipe and early
// returns: `ms_emit`).
fn ms_step(k: u32, j: u32, n: u32, u: vec3<f32>, along: f32, twice: bool) -> vec2<f32> {
    let st = lv_ms[mp.levels[k].w + j];
    var out = vec2<f32>(0.0, 1.0);
    if (st > 0.0) {
        let x = st * along;
        let t = exp(-x);
        out = vec2<f32>(ms_emit(k, j, n, u, twice) * along * ms_one_minus_over(x, t), t);
    }
    return out;
}

// The first of the 26 shared gather paths (one per direction) of cell `j` of level `k`.
fn ms_path_at(k: u32, j: u32) -> u32 {
    return mp.paths[k / 4u][k % 4u] + 26u * j;
}

// Level `mp.level.x` ≥ `MS_SHARED_PATHS`, coarsest first, before `ms_gather_main` of the same
// parity: per cell and gather direction, the light arriving along the path that starts at the
// cell's centre (`vdbcook_trace::diffusion`'s `gather`): the cell and the next along `e`, then
// the path of the coarser level's cell holding the point 2½ cells past this one's centre
// (`ms_next_cell`: ⌊(2f + 1 + 5e)/4⌋); on the coarsest level, cells along `e` until the grid
// ends. No transmittance cut-off: a path's light is the same whichever cell's path goes on
// with it.
@compute @workgroup_size(4, 4, 4)
fn ms_paths_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let dims = mp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let k = mp.level.x;
    let n = ms_cells(dims);
    let twice = mp.dims.w == 1u;
    let top = mp.child.w - 1u;
    let at = ms_path_at(k, lv_index(gid, dims));
    for (var d = 0u; d < 26u; d++) {
        let e = ms_gather_dir(d);
        // `mp.h` is this level's cell edge: a step's length.
        let v = vec3<f32>(e) * mp.h.xyz;
        let along = length(v);
        let u = v / along;
        var x = vec3<i32>(gid);
        var sum = 0.0;
        var t = 1.0;
        var left = select(2u, 0xffffffffu, k == top);
        var inside = true;
        loop {
            let s = ms_step(k, lv_index(vec3<u32>(x), dims), n, u, along, twice);
            sum += t * s.x;
            t *= s.y;
            left -= 1u;
            if (left == 0u) {
                break;
            }
            x += e;
            if (any(x < vec3<i32>(0)) || any(vec3<u32>(x) >= dims)) {
                inside = false;
                break;
            }
        }
        if (inside && k < top) {
            let g = (2 * vec3<i32>(gid) + vec3<i32>(1) + 5 * e) >> vec3<u32>(2u);
            let pd = mp.parent.xyz;
            if (all(g >= vec3<i32>(0)) && all(vec3<u32>(g) < pd)) {
                sum += t * lv_ms[ms_path_at(k + 1u, lv_index(vec3<u32>(g), pd)) + d];
            }
        }
        lv_ms[at + d] = sum;
    }
}

// Where level-0 cell `i`'s gathered light (φ, J per axis; f32 bits) waits until
// `ms_store_main`: the first four of its output words.
fn ms_gathered(i: u32) -> u32 {
    return 6u * (lp.base + i);
}

// Gather direction `d` of 26 (`vdbcook_scene::ms_gather_dirs`: the cell offsets in
// {−1, 0, 1}³, x fastest, 0 left out). Written without a `continue` over 27 offsets: lavapipe
// computed a wrong sum from such a loop in `ms_beam_norm` (GPU 4% darker than the CPU on a
// third of the pixels at one sun and phase; measured 2026-11-27), which this form does not.
fn ms_gather_dir(d: u32) -> vec3<i32> {
    let k = d + u32(d >= 13u);
    return vec3<i32>(i32(k % 3u), i32((k / 3u) % 3u), i32(k / 9u)) - vec3<i32>(1);
}

// Direction `e`'s share of the sphere, by how many axes it moves along (`mp.share`).
fn ms_share(e: vec3<i32>) -> f32 {
    return mp.share[u32(dot(abs(e), vec3<i32>(1))) - 1u];
}

// The source of cell `j` of level `lk` (`n` cells) toward −u (times 4π per unit solid angle):
// `q`, and for the second order `q − A + B·4π·p(ĵ·(−u))` with its beam (`Level::beam`).
// One return at the end: with early returns lavapipe gave a drawer's frame no second order at
// all (its gathered light a quarter short of the CPU's; measured 2026-11-27).
fn ms_emit(lk: u32, j: u32, n: u32, u: vec3<f32>, twice: bool) -> f32 {
    let o = mp.levels[lk].w;
    let q = lv_ms[o + 2u * n + j];
    var e = q;
    if (twice) {
        let b = o + 7u * n + 5u * j;
        let a = lv_ms[b + 3u];
        let s = vec3<f32>(lv_ms[b], lv_ms[b + 1u], lv_ms[b + 2u]);
        let sn = length(s);
        if (a > 0.0 && sn > 0.0) {
            let mu = clamp(-dot(s, u) / sn, -1.0, 1.0);
            e = q - a + lv_ms[b + 4u] * MS_FOUR_PI * lv_phase(mp.phase.xyz, 1.0, mu);
        }
    }
    return e;
}

// `vdbcook_scene::ms_beam_norm`: the 26 directions' quadrature of a beam along `dir` scattered
// by the phase.
fn ms_beam_norm(dir: vec3<f32>) -> f32 {
    var sum = 0.0;
    for (var d = 0u; d < 26u; d++) {
        let e = ms_gather_dir(d);
        let v = vec3<f32>(e) * mp.h.xyz;
        let mu = clamp(dot(dir, v) / length(v), -1.0, 1.0);
        sum += ms_share(e) * MS_FOUR_PI * lv_phase(mp.phase.xyz, 1.0, mu);
    }
    return sum;
}

// Level 0, after `ms_gather_main` of the same parity: the light it gathered scattered again
// becomes the source, `α·σ·φ`; after the first order (parity 0) also its beam (`Level::beam`:
// `A = min(|J|/φ, 1)·q` along `ĵ = J/|J|`, `B = A/N(ĵ)`), for the second order to gather; after
// the second (parity 1) the source is the solve's, which carries the light scattered three
// times and more.
@compute @workgroup_size(4, 4, 4)
fn ms_second_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let dims = mp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let i = lv_index(gid, dims);
    let n = ms_cells(dims);
    let o = mp.off.x;
    // The order just gathered: the first alone is in the gathered sum; of the second only its
    // φ is read, which `ms_gather_main` left at [12n, 13n) (the open faces' place later).
    var g = vec4<f32>(0.0);
    if (mp.dims.w == 1u) {
        g.x = lv_ms[o + 12u * n + i];
    } else {
        let at = ms_gathered(i);
        g = bitcast<vec4<f32>>(vec4<u32>(
            lv_ms_out[at], lv_ms_out[at + 1u], lv_ms_out[at + 2u], lv_ms_out[at + 3u]
        ));
    }
    let phi = g.x;
    let q = mp.h.w * lv_ms[o + i] * phi;
    lv_ms[o + 2u * n + i] = q;
    // The beams only where a second order will gather them.
    if (mp.dims.w == 0u && mp.parent.w > 1u) {
        let j = g.yzw;
        let jn = length(j);
        var beam = array<f32, 5>(0.0, 0.0, 0.0, 0.0, 0.0);
        if (q > 0.0 && jn > 0.0) {
            let a = q * min(jn / phi, 1.0);
            let dir = j / jn;
            let s = dir * a;
            beam = array<f32, 5>(s.x, s.y, s.z, a, a / ms_beam_norm(dir));
        }
        let b = o + 7u * n + 5u * i;
        for (var c = 0u; c < 5u; c++) {
            lv_ms[b + c] = beam[c];
        }
    }
}

// A coarse cell: the means of the (up to) 8 finer cells it covers (missing ones count 0).
@compute @workgroup_size(4, 4, 4)
fn ms_restrict_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let dims = mp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let cd = mp.child.xyz;
    let cn = ms_cells(cd);
    let co = mp.off.y;
    var acc = vec3<f32>(0.0);
    // The gather's beams too (before the solve they sit in the resistances' and open faces'
    // place, which the solve's `ms_vacuum_main` and `ms_limit_main` write before they are read).
    var beam = array<f32, 5>(0.0, 0.0, 0.0, 0.0, 0.0);
    for (var k = 0u; k < 8u; k++) {
        let c = 2u * gid + vec3<u32>(k & 1u, (k >> 1u) & 1u, (k >> 2u) & 1u);
        if (all(c < cd)) {
            let j = lv_index(c, cd);
            acc += vec3<f32>(lv_ms[co + j], lv_ms[co + cn + j], lv_ms[co + 2u * cn + j]) / 8.0;
            for (var b = 0u; b < 5u; b++) {
                beam[b] += lv_ms[co + 7u * cn + 5u * j + b] / 8.0;
            }
        }
    }
    let i = lv_index(gid, dims);
    let n = ms_cells(dims);
    let o = mp.off.x;
    lv_ms[o + i] = acc.x;
    lv_ms[o + n + i] = acc.y;
    lv_ms[o + 2u * n + i] = acc.z;
    for (var b = 0u; b < 5u; b++) {
        lv_ms[o + 7u * n + 5u * i + b] = beam[b];
    }
}

// φ A of a level from its parent's φ A (each cell its parent's value), the boundary's at the
// coarsest.
@compute @workgroup_size(4, 4, 4)
fn ms_prolong_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let dims = mp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let n = ms_cells(dims);
    var v = vec2<f32>(ms_boundary(0u), ms_boundary(1u));
    if (mp.off.w != 0u) {
        let pd = mp.parent.xyz;
        let j = mp.off.z + 3u * ms_cells(pd) + 2u * lv_index(gid / 2u, pd);
        v = vec2<f32>(lv_ms[j], lv_ms[j + 1u]);
    }
    let i = mp.off.x + 3u * n + 2u * lv_index(gid, dims);
    lv_ms[i] = v.x;
    lv_ms[i + 1u] = v.y;
}

// The sweep's input φ of field `f` of cell `c` (the boundary's outside the level).
fn ms_phi(c: vec3<i32>, f: u32) -> f32 {
    let dims = mp.dims.xyz;
    if (any(c < vec3<i32>(0)) || any(vec3<u32>(c) >= dims)) {
        return ms_boundary(f);
    }
    let n = ms_cells(dims);
    return lv_ms[mp.off.x + (3u + 2u * mp.dims.w) * n + 2u * lv_index(vec3<u32>(c), dims) + f];
}

// The half-cell resistances of a cell per field: ½h·(3·sr + |∇φ|/φ) (Wilson's flux limiter).
@compute @workgroup_size(4, 4, 4)
fn ms_limit_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let dims = mp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let i = lv_index(gid, dims);
    let n = ms_cells(dims);
    let o = mp.off.x;
    if (!(lv_ms[o + i] > 0.0)) {
        return;
    }
    let c = vec3<i32>(gid);
    let sr = lv_ms[o + n + i];
    for (var f = 0u; f < 2u; f++) {
        var g2 = 0.0;
        for (var a = 0u; a < 3u; a++) {
            var e = vec3<i32>(0);
            e[a] = 1;
            let d = (ms_phi(c + e, f) - ms_phi(c - e, f)) / (2.0 * mp.h[a]);
            g2 += d * d;
        }
        let phi = ms_phi(c, f);
        var lim = 0.0;
        if (phi > 0.0) {
            lim = sqrt(g2) / phi;
        }
        lv_ms[o + 7u * n + 2u * i + f] = 3.0 * sr + lim;
    }
}

// Cell `i`'s half-cell resistance along axis `a` for field `f` (`ms_limit_main`'s).
fn ms_half_r(i: u32, a: u32, f: u32) -> f32 {
    return 0.5 * mp.h[a] * lv_ms[mp.off.x + 7u * ms_cells(mp.dims.xyz) + 2u * i + f];
}

// Once per level before its sweeps (the sources are final then, and the gather's use of the
// resistances' place is over): per filled cell and axis with an open face, the sun's field
// through the half cell's diffusion problem (`ms_vacuum_face`, without the flux limiter's
// share, which `ms_face` adds each sweep): the face's resistance less the cell's plain half
// and the far side's φ. Both faces of an axis open means no inward cell for either, so one
// pair serves the axis. Nothing in it changes between sweeps: computed here, it costs one
// pass instead of a share of every sweep's.
@compute @workgroup_size(4, 4, 4)
fn ms_vacuum_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let dims = mp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let i = lv_index(gid, dims);
    let n = ms_cells(dims);
    let o = mp.off.x;
    let st = lv_ms[o + i];
    if (!(st > 0.0)) {
        return;
    }
    let c = vec3<i32>(gid);
    let sr = lv_ms[o + n + i];
    for (var a = 0u; a < 3u; a++) {
        var e = vec3<i32>(0);
        e[a] = 1;
        let up = ms_filled(c + e);
        let down = ms_filled(c - e);
        var v = vec2<f32>(0.0);
        if (up < 0 || down < 0) {
            // The inward cell of the open face (none when both are open).
            var q_in = -1.0;
            let inward = max(up, down);
            if (inward >= 0) {
                q_in = lv_ms[o + 2u * n + u32(inward)];
            }
            let h = mp.h[a];
            v = ms_vacuum_face(h, st, sr, lv_ms[o + 2u * n + i], q_in, -1.5 * h * sr);
        }
        lv_ms[o + 9u * n + 6u * i + 2u * a] = v.x;
        lv_ms[o + 9u * n + 6u * i + 2u * a + 1u] = v.y;
    }
}

// Cell `c`'s index when it lies in the level and is filled, else −1.
fn ms_filled(c: vec3<i32>) -> i32 {
    let dims = mp.dims.xyz;
    if (all(c >= vec3<i32>(0)) && all(vec3<u32>(c) < dims)) {
        let k = lv_index(vec3<u32>(c), dims);
        if (lv_ms[mp.off.x + k] > 0.0) {
            return i32(k);
        }
    }
    return -1;
}

// Cell `i`'s (at `c`) neighbour along axis `a` on side `s` (1: +1) for field `f`: the face's
// conductance 1/(h·R) and the neighbour's φ (the vacuum boundary toward an empty cell or the
// level's edge).
fn ms_face(i: u32, c: vec3<i32>, a: u32, s: u32, f: u32) -> vec2<f32> {
    let dims = mp.dims.xyz;
    let n = ms_cells(dims);
    let o = mp.off.x;
    var e = vec3<i32>(0);
    e[a] = select(-1, 1, s == 1u);
    let cj = c + e;
    let hi = ms_half_r(i, a, f);
    let j = ms_filled(cj);
    if (j >= 0) {
        let r = hi + ms_half_r(u32(j), a, f);
        return vec2<f32>(1.0 / (mp.h[a] * r), ms_phi(cj, f));
    }
    if (f == 1u) {
        return vec2<f32>(1.0 / (mp.h[a] * (hi + MS_VACUUM)), ms_boundary(f));
    }
    // The sun's field through the half cell's own diffusion problem, its source exponential
    // in depth from this cell's and the next inward cell's (`ms_vacuum_face`, computed once
    // by `ms_vacuum_main`; the flux limiter's share, `hi` less the plain half, added here).
    let v = o + 9u * n + 6u * i + 2u * a;
    let r = lv_ms[v] + hi;
    return vec2<f32>(1.0 / (mp.h[a] * r), lv_ms[v + 1u]);
}

// `sinh(x)/x` (`vdbcook_scene`'s `sinhc`).
fn ms_sinhc(x: f32) -> f32 {
    if (abs(x) < 0.1) {
        let t = x * x;
        return 1.0 + t / 6.0 + t * t / 120.0;
    }
    return sinh(x) / x;
}

// `vdbcook_scene::ms_vacuum_shape`.
fn ms_vacuum_shape(x: f32, y: f32) -> f32 {
    let t1 = x * x;
    let t2 = y * y;
    var dd: f32;
    if (max(t1, t2) < 1.0) {
        let sq = t1 * t1 + t1 * t2 + t2 * t2;
        dd = 1.0 / 6.0 + (t1 + t2) / 120.0 + sq / 5040.0 + (t1 + t2) * (t1 * t1 + t2 * t2) / 362880.0;
    } else if (abs(t1 - t2) > 0.01 * max(t1, t2)) {
        dd = (ms_sinhc(x) - ms_sinhc(y)) / (t1 - t2);
    } else {
        let m = 0.5 * (t1 + t2);
        let r = sqrt(m);
        dd = (cosh(r) - ms_sinhc(r)) / (2.0 * m);
    }
    return 0.5 * ms_sinhc(0.5 * (x + y)) * ms_sinhc(0.5 * (x - y)) - y * dd;
}

// `vdbcook_scene::ms_vacuum_face` for the sun's field (albedo `mp.h.w`; `q_in` < 0: no next
// cell inward): the face's resistance R and the far side's φ.
fn ms_vacuum_face(h: f32, st: f32, sr_in: f32, q0: f32, q_in: f32, lim_r: f32) -> vec2<f32> {
    let sa = max(st * (1.0 - mp.h.w), 0.0);
    let sr = max(sr_in, 0.0);
    let x = 0.5 * h * sqrt(3.0 * sr * sa);
    let xc = min(x, MS_VACUUM_MAX_X);
    let inv_g = 2.0 * cosh(xc) + 1.5 * h * sr * ms_sinhc(xc);
    if (!(q0 > 0.0) || !(sr > 0.0)) {
        return vec2<f32>(inv_g + lim_r, 0.0);
    }
    var y = 0.0;
    if (q_in > 0.0) {
        y = 0.5 * log(q0 / q_in);
    } else if (q_in == 0.0) {
        y = MS_VACUUM_MAX_Y;
    }
    y = clamp(y, -MS_VACUUM_MAX_Y, MS_VACUUM_MAX_Y);
    var q_face = q0 * (1.0 + y);
    if (abs(y) >= 1e-3) {
        q_face = q0 * 2.0 * y / (1.0 - exp(-2.0 * y));
    }
    let scale = q_face * 0.75 * h * h * sr;
    var s: f32;
    if (x <= MS_VACUUM_FAR_X) {
        s = scale * ms_vacuum_shape(x, y);
    } else {
        s = scale / ((x + y) * (2.0 * x + 1.5 * h * sr)) * inv_g;
    }
    return vec2<f32>(inv_g + lim_r, -s);
}

// One Jacobi sweep of the balance per field: φ ← (q + Σ φ_j/(h·R)) / (σ(1 − α) + Σ 1/(h·R)).
@compute @workgroup_size(4, 4, 4)
fn ms_update_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let dims = mp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let i = lv_index(gid, dims);
    let n = ms_cells(dims);
    let o = mp.off.x;
    let out = o + (5u - 2u * mp.dims.w) * n + 2u * i;
    let st = lv_ms[o + i];
    if (!(st > 0.0)) {
        lv_ms[out] = ms_boundary(0u);
        lv_ms[out + 1u] = ms_boundary(1u);
        return;
    }
    let c = vec3<i32>(gid);
    for (var f = 0u; f < 2u; f++) {
        var diag = st * (1.0 - mp.h.w);
        var off = 0.0;
        for (var a = 0u; a < 3u; a++) {
            for (var s = 0u; s < 2u; s++) {
                let g = ms_face(i, c, a, s, f);
                diag += g.x;
                off += g.x * g.y;
            }
        }
        let q = select(0.0, lv_ms[o + 2u * n + i], f == 0u);
        lv_ms[out + f] = (q + off) / diag;
    }
}

// Level 0's result for the tracer and the drawer, per cell (φ A, after `ms_limit_main` on
// it), six words (`vdbcook_scene::ms_stored_flux`; `lv_diffuse_add` in `light.wgsl` reads them):
// ρ·φ_sun/4π, ρ·φ_sky/4π and ρ as f32 bits; then each field's net flux J per axis (the mean of
// the cell's two faces' fluxes (φᵢ − φⱼ)/R along it) as J/φ over ±MS_FLUX_RATIO in 16 bits
// (`pack2x16snorm`): (J_sun.x, J_sun.y), (J_sun.z, J_sky.x), (J_sky.y, J_sky.z).
@compute @workgroup_size(4, 4, 4)
fn ms_store_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let dims = mp.dims.xyz;
    if (any(gid >= dims)) {
        return;
    }
    let i = lv_index(gid, dims);
    let rho = lv_density[i];
    let out = 6u * (lp.base + i);
    var r = array<vec3<f32>, 2>(vec3<f32>(0.0), vec3<f32>(0.0));
    let c = vec3<i32>(gid);
    let filled = lv_ms[mp.off.x + i] > 0.0;
    // The solve's light plus the gathered light of the first two orders (the sun's field).
    let at = ms_gathered(i);
    var gathered = vec4<f32>(0.0);
    if (mp.parent.w > 0u) {
        gathered = bitcast<vec4<f32>>(vec4<u32>(
            lv_ms_out[at], lv_ms_out[at + 1u], lv_ms_out[at + 2u], lv_ms_out[at + 3u]
        ));
    }
    let solved = vec2<f32>(ms_phi(c, 0u), ms_phi(c, 1u));
    var phi = solved;
    if (filled) {
        phi.x += gathered.x;
        for (var f = 0u; f < 2u; f++) {
            if (phi[f] > 0.0) {
                for (var a = 0u; a < 3u; a++) {
                    let lo = ms_face(i, c, a, 0u, f);
                    let up = ms_face(i, c, a, 1u, f);
                    // A face's flux is its fluence difference over its resistance R
                    // (`ms_face` gives 1/(h·R)).
                    var j = 0.5 * mp.h[a] * ((lo.y - solved[f]) * lo.x + (solved[f] - up.y) * up.x);
                    if (f == 0u) {
                        j += gathered[1u + a];
                    }
                    r[f][a] = j / phi[f] / MS_FLUX_RATIO;
                }
            }
        }
    }
    let w = rho / MS_FOUR_PI;
    lv_ms_out[out] = bitcast<u32>(w * phi.x);
    lv_ms_out[out + 1u] = bitcast<u32>(w * phi.y);
    lv_ms_out[out + 2u] = bitcast<u32>(rho);
    lv_ms_out[out + 3u] = pack2x16snorm(r[0].xy);
    lv_ms_out[out + 4u] = pack2x16snorm(vec2<f32>(r[0].z, r[1].x));
    lv_ms_out[out + 5u] = pack2x16snorm(r[1].yz);
}
