//! The constants and inputs of `Lit`'s diffusion model of multiple scattering
//! (`MsModel::Diffusion`), defined once for the CPU solver (`vdbcook_trace::diffusion`, whose
//! module docs state the method) and the GPU passes (`shaders/light_build.wgsl`'s `ms_*`).

use crate::{light_dirs, phase, phase_mean_cos, Affine, LightGrid, RenderSettings};

/// Jacobi sweeps on each coarse level (all but the light volume's own cells).
pub const MS_ITERATIONS: usize = 16;
/// Jacobi sweeps on the light volume's own cells (level 0), which start from their parent's
/// converged light and only add the detail it lacks: 4 sweeps are a quarter of the solve's
/// cost of 16, and as close to the reference (WDAS 0.140, stormscape 0.036, smoke 0.093 rel
/// RMSE at 160×90, against 0.145 / 0.037 / 0.104 with 16).
pub const MS_FINE_SWEEPS: usize = 4;

/// The Jacobi sweeps of level `level` (0: the light volume's cells). Always even: the GPU's
/// sweeps alternate between two buffers and leave the result in the first.
pub fn ms_sweeps(level: usize) -> usize {
    if level == 0 {
        MS_FINE_SWEEPS
    } else {
        MS_ITERATIONS
    }
}
/// The coarsest level has no side longer than this (cells).
pub const MS_COARSEST: u32 = 6;
/// Resistance of the half-face toward empty space or the grid's edge (Marshak's vacuum
/// boundary: the net flux out is half the fluence) for the sky's field; the sun's crosses the
/// half cell by [`ms_vacuum_face`].
pub const MS_VACUUM: f64 = 2.0;

/// The sun's field's face toward empty space (a neighbour without medium, or the grid's edge),
/// as the solve's face terms `(R, φ_j)`: the face passes `(φᵢ − φ_j)/(h·R)` per unit volume.
///
/// A cell-centred solve puts a cell's source and its fluence at its centre, half a cell deep.
/// Where the cell is thick in transport mean free paths and its source lies near its open face
/// (a dense cloud's sunlit skin), the light leaves through the face from a shallower depth than
/// the centre: the plain vacuum face (`R = r + 2`, `φ_j = 0`) lets too little of it out, so the
/// cell holds too much (a uniform half-space at albedo 0.94 seen from above read 1.21 / 1.54 /
/// 1.79 for the solve's orders at 1 / 2 / 4 mean free paths a cell; docs/rendering.md).
///
/// Here the half cell between the centre and the face is solved as diffusion's 1D problem
/// along the face's axis: `−D·φ'' + σ_a·φ = q(s)` on `s ∈ [0, h/2]` (`s` the depth from the
/// face), Marshak's condition `φ(0) = 2D·φ'(0)` at the face and the cell's value at the
/// centre, with `D = 1/(3·σ_r)`, `σ_a = st·(1 − albedo)` and the source exponential in depth,
/// `q(s) ∝ e^{−κs}`, its mean over the cell `q0` and over the next cell inward `q_in`
/// (`κ = ln(q0/q_in)/h`, `|κh|` at most 8; uniform where there is no next cell). Its outflow
/// `J = (φᵢ + S)/(1/G)` gives `1/G = 2·cosh x + 1.5·h·σ_r·sinhc x` (`x = h/2·√(σ_a/D)`) and
/// the source's share `S = q_face·(h/2)²/D·F(x, y)` (`y = κh/2`, `q_face` the source at the
/// face, [`ms_vacuum_shape`]); the flux limiter's part of the half-cell resistance, `lim_r`
/// (`r − 1.5·h·σ_r`), is added in series. As the cell thins (`x, y → 0`) this is the plain
/// vacuum face `1.5·h·σ_r + 2` with `S → 0`.
pub fn ms_vacuum_face(
    h: f64,
    st: f64,
    sr: f64,
    albedo: f64,
    q0: f64,
    q_in: Option<f64>,
    lim_r: f64,
) -> (f64, f64) {
    let sa = (st * (1.0 - albedo)).max(0.0);
    let sr = sr.max(0.0);
    let x = 0.5 * h * (3.0 * sr * sa).sqrt();
    let xc = x.min(MS_VACUUM_MAX_X);
    let inv_g = 2.0 * xc.cosh() + 1.5 * h * sr * sinhc(xc);
    if !(q0 > 0.0) || !(sr > 0.0) {
        return (inv_g + lim_r, 0.0);
    }
    let y = match q_in {
        Some(q1) if q1 > 0.0 => 0.5 * (q0 / q1).ln(),
        Some(_) => MS_VACUUM_MAX_Y,
        None => 0.0,
    }
    .clamp(-MS_VACUUM_MAX_Y, MS_VACUUM_MAX_Y);
    let q_face = q0
        * if y.abs() < 1e-3 {
            1.0 + y
        } else {
            2.0 * y / -(-2.0 * y).exp_m1()
        };
    let s = if x <= MS_VACUUM_FAR_X {
        q_face * 0.75 * h * h * sr * ms_vacuum_shape(x, y)
    } else {
        // Far into the thick limit cosh and sinh are e^x/2 (their rest and e^{−y} below 10⁻⁷
        // of it): the source's share over the face's resistance, `q·¾h²σ_r/((x + y)(2x +
        // 1.5hσ_r))`, scaled back by the (clamped) resistance the face is given.
        q_face * 0.75 * h * h * sr / ((x + y) * (2.0 * x + 1.5 * h * sr)) * inv_g
    };
    (inv_g + lim_r, -s)
}

/// Above this half-cell optical width `x` [`ms_vacuum_face`] takes the source's share from its
/// thick limit (exact to 10⁻⁷ there), so that clamping `x` for the resistance
/// ([`MS_VACUUM_MAX_X`]) does not change how much of the source leaves.
pub const MS_VACUUM_FAR_X: f64 = 20.0;

/// The largest half-cell optical width `x` [`ms_vacuum_face`]'s resistance takes (beyond it the face passes
/// nothing of the centre's light either way; f32's `cosh` stays finite on the GPU).
pub const MS_VACUUM_MAX_X: f64 = 40.0;
/// The largest `|y| = |κ|·h/2` of [`ms_vacuum_face`]'s exponential source.
pub const MS_VACUUM_MAX_Y: f64 = 4.0;

/// `sinh(x)/x` (1 at 0).
fn sinhc(x: f64) -> f64 {
    if x.abs() < 0.1 {
        let t = x * x;
        1.0 + t / 6.0 + t * t / 120.0
    } else {
        x.sinh() / x
    }
}

/// `F(x, y) = (cosh x − e^{−y} − y·sinhc x)/(x² − y²)` of [`ms_vacuum_face`], written without
/// its removable singularities: `½·sinhc(u)·sinhc(v) − y·Δ`, `u, v = (x ± y)/2`, `Δ` the divided
/// difference of `s(t) = sinhc(√t)` between `t = x²` and `y²`.
pub fn ms_vacuum_shape(x: f64, y: f64) -> f64 {
    let (u, v) = (0.5 * (x + y), 0.5 * (x - y));
    let (t1, t2) = (x * x, y * y);
    let dd = if t1.max(t2) < 1.0 {
        // The series of s(t) = Σ tⁿ/(2n+1)!, divided term by term.
        let sq = t1 * t1 + t1 * t2 + t2 * t2;
        1.0 / 6.0 + (t1 + t2) / 120.0 + sq / 5040.0 + (t1 + t2) * (t1 * t1 + t2 * t2) / 362880.0
    } else if (t1 - t2).abs() > 0.01 * t1.max(t2) {
        (sinhc(x) - sinhc(y)) / (t1 - t2)
    } else {
        // s'(t) at the middle: (cosh √t − sinhc √t)/(2t).
        let m = 0.5 * (t1 + t2);
        let r = m.sqrt();
        (r.cosh() - sinhc(r)) / (2.0 * m)
    };
    0.5 * sinhc(u) * sinhc(v) - y * dd
}

/// Weights of the 26 directions toward a cell's neighbours (the 6 faces', the 12 edges', the 8
/// corners') in the gather of the sun's once-scattered light (`vdbcook_trace::diffusion`): the
/// share of the sphere's directions nearer to each than to any other (measured by sampling 4
/// million uniform directions: 0.04576, 0.03700, 0.03518; the corners' takes what the others
/// leave, so the 26 sum to 1 and a uniform medium gathers exactly `q/σ`).
pub const MS_GATHER_WEIGHTS: [f64; 3] =
    [0.04576, 0.037, (1.0 - 6.0 * 0.04576 - 12.0 * 0.037) / 8.0];
/// A gather ray stops once its transmittance falls below this (the light it leaves out is at
/// most this share of what it would add).
pub const MS_GATHER_MIN_TRANS: f64 = 1e-3;
/// The first level on which the gather's paths are shared (`vdbcook_trace::diffusion`'s
/// `gather`): each cell of level 0 walks its own two steps on level 0, then takes the light of
/// the path from the level-1 cell it reaches, one per cell of level 1 (and up) and direction
/// (`light_build.wgsl`'s `ms_paths_main`). Walking every cell's path alone (about 11 steps per
/// direction at light_res 64) made the build take twice as long on lavapipe (2.1 s against 1.05
/// s); sharing from level 2 kept the images closer to that (within 0.15% against 0.4%) but took
/// 1.3 s (measured 2026-11-27, `docs/rendering.md`).
pub const MS_SHARED_PATHS: usize = 1;

/// The gather's own cell along one direction as a mean over the cell (`vdbcook_trace::diffusion`'s
/// `gather`, `light_build.wgsl`'s `ms_gather_main`), for `x = σ·L`, `L` the step's length:
/// `(own, T)` with `own·L·q` the light the cell's own source `q` sends along the direction, and `T`
/// the transmittance to the next step, both averaged over the points of a segment of length `L`
/// (`T = (1 − e^{−x})/x`, `own = (1 − T)/x`). The gather's value stands for the cell's mean
/// fluence (it is the next order's and the solve's source, a cell mean); the centre's own half
/// cell, `(1 − e^{−x/2})/x` and `e^{−x/2}`, made a thick cell's sunlit skin light its far half
/// (a uniform half-space at 4 mean free paths a cell: the solve's orders 1.24 → 1.17 of the
/// reference with the mean; docs/rendering.md). Both pairs sum to the exact `q/σ` in a uniform
/// medium; as `x → 0` they agree to first order.
pub fn ms_own_cell(x: f64) -> (f64, f64) {
    if x < 0.5 {
        // The series of (1 − T)/x = Σ (−x)ⁿ/(n + 2)! (to x⁶: within 10⁻⁷ here, where the
        // closed form loses digits in f32), and T = 1 − x·own.
        let own = 0.5
            - x * (1.0 / 6.0
                - x * (1.0 / 24.0
                    - x * (1.0 / 120.0 - x * (1.0 / 720.0 - x * (1.0 / 5040.0 - x / 40320.0)))));
        (own, 1.0 - x * own)
    } else {
        let t = -(-x).exp_m1() / x;
        ((1.0 - t) / x, t)
    }
}

/// The 26 gather directions: each cell offset `e ∈ {−1, 0, 1}³ \ 0` (x fastest) with its weight
/// from [`MS_GATHER_WEIGHTS`] by how many axes it moves along.
pub fn ms_gather_dirs() -> impl Iterator<Item = ([i32; 3], f64)> {
    (0..27).filter(|&k| k != 13).map(|k| {
        let e = [k % 3 - 1, (k / 3) % 3 - 1, k / 9 - 1];
        let n = e.iter().filter(|&&v| v != 0).count();
        (e, MS_GATHER_WEIGHTS[n - 1])
    })
}

/// [`DiffusionInputs::gather`] for cells of edges `h` (length per cell along each axis), the sun
/// along `sun` (toward it, in the same lengths; any length) and the dual-lobe phase `(g, w)`.
pub fn ms_gather_weights(h: [f64; 3], sun: [f64; 3], phase: ([f32; 2], f32)) -> [f64; 26] {
    let n = sun.iter().map(|v| v * v).sum::<f64>().sqrt();
    let sun = if n > 0.0 {
        sun.map(|v| v / n)
    } else {
        [0.0, 0.0, 1.0]
    };
    let terms = ms_beam_terms(h, sun, phase);
    let total: f64 = terms.iter().sum();
    terms.map(|v| v / total)
}

/// Per gather direction `u_d` (of [`ms_gather_dirs`], in the metric of cells of edges `h`),
/// `share_d·4π·p(ĵ·u_d)`: a beam along unit `dir` scattered by the dual-lobe phase `(g, w)`
/// toward `u_d` (or, as the 26 are symmetric, light from `u_d` scattered along `dir`).
fn ms_beam_terms(h: [f64; 3], dir: [f64; 3], (g, w): ([f32; 2], f32)) -> [f64; 26] {
    ms_gather_steps(h).map(|s| {
        let mu = (0..3)
            .map(|a| dir[a] * s.unit[a])
            .sum::<f64>()
            .clamp(-1.0, 1.0);
        s.share * 4.0 * std::f64::consts::PI * phase(g, w, mu)
    })
}

/// One of the 26 gather directions (`ms_gather_dirs`, in order) in the metric of cells of
/// edges `h`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GatherStep {
    /// The cell offset `e ∈ {−1, 0, 1}³`.
    pub e: [i32; 3],
    /// Its share of the sphere (`MS_GATHER_WEIGHTS`).
    pub share: f64,
    /// The length of one step `|e·h|`.
    pub len: f64,
    /// The unit direction `e·h / |e·h|`.
    pub unit: [f64; 3],
}

/// The 26 gather directions over cells of edges `h` (what the CPU's gather walks and
/// [`ms_beam_norm`] sums over; `light_build.wgsl` computes the same from `mp.h`).
pub fn ms_gather_steps(h: [f64; 3]) -> [GatherStep; 26] {
    let mut dirs = ms_gather_dirs();
    std::array::from_fn(|_| {
        let (e, share) = dirs.next().expect("26 directions");
        let v = [0, 1, 2].map(|a| e[a] as f64 * h[a]);
        let len = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        GatherStep {
            e,
            share,
            len,
            unit: v.map(|x| x / len),
        }
    })
}

/// `N(ĵ)`: the gather's quadrature of a beam along unit `dir` scattered by the dual-lobe phase
/// (the sum of [`ms_beam_terms`]: 1 for an isotropic phase; for g = 0.6 it ranges 0.95–1.08
/// with the beam's direction). Dividing a beam's scattered source by it keeps the gathered
/// energy exact.
pub fn ms_beam_norm(h: [f64; 3], dir: [f64; 3], phase: ([f32; 2], f32)) -> f64 {
    ms_beam_terms(h, dir, phase).iter().sum()
}

/// Largest `|J|/φ` per axis a light volume stores (`ms_stored_flux`): the flux is stored as
/// that ratio, a 16-bit signed normalized integer over `±MS_FLUX_RATIO` (WGSL's
/// `pack2x16snorm`), a step of `2.4e-4·φ`. The flux limiter keeps `|J|` near or below `φ`:
/// measured at most 1.64 φ on the WDAS cloud, a stormscape frame, the smoke fixture, OpenVDB's
/// smoke1 and the dragon sample (`light_res` 16–128). A fog dense as a surface (Arnold's
/// torus01, density 100) exceeds it in cells whose light is negligible beside their
/// neighbours' (up to 37 φ for the sky): clamped, its image is unchanged to four digits.
pub const MS_FLUX_RATIO: f32 = 8.0;

/// A cell's flux along one axis, `j`, as the light volume stores it next to its fluence `phi`
/// (`light_build.wgsl`'s `ms_store_main`, 24 bytes a cell): `j/φ` clamped to
/// `±MS_FLUX_RATIO` and rounded to 16 bits as `pack2x16snorm` does, times `phi`; 0 where
/// `phi ≤ 0`. The CPU stores the same so both render one model.
pub fn ms_stored_flux(j: f32, phi: f32) -> f32 {
    if !(phi > 0.0) {
        return 0.0;
    }
    let e = (j / phi / MS_FLUX_RATIO).clamp(-1.0, 1.0);
    let q = (0.5 + 32767.0 * e).floor();
    (q / 32767.0).max(-1.0) * MS_FLUX_RATIO * phi
}

/// The cells per axis of each level of the solve over `dims`: `dims` itself, then each next
/// one 2× coarser (rounded up) until no side exceeds [`MS_COARSEST`].
pub fn ms_levels(dims: [u32; 3]) -> Vec<[u32; 3]> {
    let mut out = vec![dims];
    while let Some(d) = out.last().filter(|d| d.iter().any(|&v| v > MS_COARSEST)) {
        let c = d.map(|v| v.div_ceil(2));
        out.push(c);
    }
    out
}

/// A light-volume cell's **transport density**: the density of a uniform cell as transparent
/// across itself as the cell's own voxels are, which the diffusion solve's face resistances take
/// (its absorption and sources keep the mean density). `values` are the density pass's
/// `sub³` samples (x fastest, at least 0), `h` the cell's edge per axis in length units. Per axis
/// `a`, each of the `sub²` columns along it has optical depth `τ = σ·Σ v·h_a/sub`, and the axis's
/// density is `−ln(mean e^{−τ})/(σ·h_a)`; the cell's is the three axes' harmonic mean (the one
/// scalar whose diffusion coefficient, `∝ 1/density`, is the mean of the axes'; the solve
/// keeps one per cell). A uniform cell gives its density; any other less than its mean
/// (`mean e^{−τ} ≥ e^{−mean τ}`): light crosses a cell
/// through its thin columns, which the mean density of a cloud's unresolved voxels hides (the
/// sun pass's reason to walk the voxels, for the light scattered more than once). The mean where
/// `extinction·h` is not positive. Computed around the smallest column's depth, so nothing
/// underflows (the GPU's `lv_transport` in `light_build.wgsl` is the same in f32).
pub fn transport_density(values: &[f64], sub: usize, h: [f64; 3], extinction: f64) -> f64 {
    let n = values.len().max(1) as f64;
    let mean = values.iter().sum::<f64>() / n;
    if sub <= 1
        || sub > crate::MAX_SUB as usize
        || !(mean > 0.0)
        || !(extinction > 0.0)
        || values.len() != sub * sub * sub
    {
        return mean;
    }
    let at = |q: [usize; 3]| values[q[0] + sub * (q[1] + sub * q[2])];
    let mut sum = 0.0;
    for a in 0..3 {
        let len = extinction * h[a];
        if !(len > 0.0) {
            return mean;
        }
        let (ua, va) = ((a + 1) % 3, (a + 2) % 3);
        let mut taus = [0.0f64; MAX_SUB_COLUMNS];
        for (k, t) in taus.iter_mut().take(sub * sub).enumerate() {
            let mut q = [0usize; 3];
            (q[ua], q[va]) = (k % sub, k / sub);
            *t = (0..sub)
                .map(|s| {
                    q[a] = s;
                    at(q)
                })
                .sum::<f64>()
                * len
                / sub as f64;
        }
        let taus = &taus[..sub * sub];
        let least = taus.iter().fold(f64::INFINITY, |m, &t| m.min(t));
        let m = taus.iter().map(|&t| (least - t).exp()).sum::<f64>() / taus.len() as f64;
        sum += 1.0 / ((least - m.ln()) / len).min(mean);
    }
    3.0 / sum
}

/// Columns per axis of the largest density pass (`crate::MAX_SUB`²).
const MAX_SUB_COLUMNS: usize = (crate::MAX_SUB * crate::MAX_SUB) as usize;

/// The medium and the sun as the solve sees them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiffusionInputs {
    /// Extinction per unit density per unit length.
    pub extinction: f64,
    pub albedo: f64,
    /// Length (in the settings' unit) of one cell edge along each axis.
    pub h: [f64; 3],
    /// Length of the sun's ray across one cell slab along its major axis.
    pub chord: f64,
    /// The gather's weight of each of the 26 directions of [`ms_gather_dirs`] for the sun's
    /// once-scattered light: its share of the sphere ([`MS_GATHER_WEIGHTS`]) times `4π·p(μ)`,
    /// `μ` the cosine between the sun's direction and the direction toward that neighbour
    /// (light scattered there flows back along it, so `μ` is its scattering angle's cosine),
    /// scaled so the 26 sum to 1: the quadrature of the phase keeps the scattered energy.
    pub gather: [f64; 26],
    /// The dual-lobe phase `(g, w)`.
    pub phase: ([f32; 2], f32),
    /// Orders of the sun's scattered light gathered before the solve (`Lighting::ms_gather`;
    /// read through [`DiffusionInputs::gathered_orders`]).
    pub orders: u32,
}

impl DiffusionInputs {
    /// The inputs over `grid` for a render of `s` in the cell space of `xf` (extinction
    /// `absorb + scatter`, albedo `scatter / extinction`, 0 without extinction): what the CPU
    /// tracer and the GPU renderer solve alike.
    pub fn of_settings(grid: &LightGrid, xf: &Affine, s: &RenderSettings) -> DiffusionInputs {
        let (extinction, albedo) = s.medium.extinction_albedo();
        DiffusionInputs::new(
            grid,
            light_dirs(xf, s.lighting.light_dir, s.medium.unit),
            extinction,
            albedo,
            (s.medium.phase_g, s.medium.phase_w),
            s.lighting.ms_gather,
        )
    }

    /// The inputs over `grid` for the sun `(l, len)` and axis lengths of
    /// [`crate::light_dirs`], `extinction` per unit density per length, `albedo`, the
    /// dual-lobe phase `(g, w)` and the gathered `orders` (`Lighting::ms_gather`).
    pub fn new(
        grid: &LightGrid,
        ((l, sun_len), axis_len): (([f64; 3], f64), [f64; 3]),
        extinction: f64,
        albedo: f64,
        (g, w): ([f32; 2], f32),
        orders: u32,
    ) -> DiffusionInputs {
        let m = (0..3)
            .max_by(|&a, &b| l[a].abs().total_cmp(&l[b].abs()))
            .unwrap_or(0);
        let h = axis_len.map(|a| a * grid.cell);
        DiffusionInputs {
            extinction,
            albedo,
            h,
            chord: grid.cell / l[m].abs() * sun_len,
            gather: ms_gather_weights(h, [0, 1, 2].map(|a| l[a] * axis_len[a]), (g, w)),
            phase: (g, w),
            orders,
        }
    }

    /// The orders gathered: `orders`, at most `MAX_MS_GATHER` (what the CPU's solve and the
    /// GPU's passes, whose records hold one parity per order, both run).
    pub fn gathered_orders(&self) -> u32 {
        self.orders.min(crate::MAX_MS_GATHER)
    }

    /// The phase's mean cosine `ḡ` (the solve's reduced extinction, the march's P1 read).
    pub fn mean_cos(&self) -> f64 {
        phase_mean_cos(self.phase.0, self.phase.1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cell of `sub³` samples, `v(x, y, z)` each.
    fn cell_of(sub: usize, v: impl Fn(usize, usize, usize) -> f64) -> Vec<f64> {
        (0..sub * sub * sub)
            .map(|k| v(k % sub, (k / sub) % sub, k / (sub * sub)))
            .collect()
    }

    #[test]
    fn a_uniform_cell_moves_light_as_its_density() {
        for sub in 1..=4 {
            let values = cell_of(sub, |_, _, _| 0.7);
            let d = transport_density(&values, sub, [2.0, 3.0, 2.5], 1.3);
            assert!((d - 0.7).abs() < 1e-12, "sub {sub}: {d}");
        }
    }

    /// Half a cell full (the samples with `x < sub/2`): along x every column crosses the full
    /// half, `τ = σ·v·h/2`, the mean; along y and z half the columns are full and half empty,
    /// `−ln((1 + e^{−σ·v·h})/2)/(σ·h)`. The three averaged, at depths from thin to opaque (an
    /// exponential that underflows included: two full halves of different densities, 10⁴ and
    /// 2·10⁴ per unit, where `e^{−τ}` is 0 in f64 for every column).
    #[test]
    fn a_half_empty_cell_moves_light_through_its_empty_half() {
        let (sub, h, ext) = (4, 2.0, 0.5);
        for v in [0.01, 1.0, 10.0, 1e4] {
            let values = cell_of(sub, |x, _, _| if x < sub / 2 { v } else { 0.0 });
            let across = -((1.0 + (-ext * v * h).exp()) / 2.0).ln() / (ext * h);
            let want = 3.0 / (2.0 / v + 2.0 / across);
            let got = transport_density(&values, sub, [h; 3], ext);
            assert!(
                (got - want).abs() <= 1e-9 * want,
                "v {v}: {got} against {want}"
            );
            assert!(got < v / 2.0, "v {v}: {got} not below the mean");
        }
        let values = cell_of(sub, |x, _, _| if x < sub / 2 { 1e4 } else { 2e4 });
        let across = 1e4 + std::f64::consts::LN_2 / (ext * h);
        let want = 3.0 / (1.0 / 1.5e4 + 2.0 / across);
        let got = transport_density(&values, sub, [h; 3], ext);
        assert!((got - want).abs() <= 1e-9 * want, "{got} against {want}");
    }

    /// Never above the mean nor below 0, on cells of hashed samples; the mean where nothing
    /// moves the light (no extinction, one sample, no density).
    #[test]
    fn the_transport_density_is_at_most_the_mean() {
        for seed in 0..200u64 {
            let hash = |k: usize| {
                let h = (seed * 1000 + k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
                if h.is_multiple_of(3) {
                    0.0
                } else {
                    (h % 1000) as f64 / 100.0
                }
            };
            let values = cell_of(3, |x, y, z| hash(x + 3 * (y + 3 * z)));
            let mean = values.iter().sum::<f64>() / 27.0;
            let d = transport_density(&values, 3, [1.0, 2.0, 1.5], 0.8);
            assert!(
                (0.0..=mean * (1.0 + 1e-12)).contains(&d),
                "seed {seed}: {d} mean {mean}"
            );
            assert_eq!(transport_density(&values, 3, [1.0; 3], 0.0), mean);
        }
        assert_eq!(transport_density(&[2.5], 1, [1.0; 3], 1.0), 2.5);
        assert_eq!(transport_density(&[0.0; 8], 2, [1.0; 3], 1.0), 0.0);
    }

    /// The stored flux is `J` to half a 16-bit step of `8φ` within `±8φ`, clamped beyond, 0
    /// without light; the steps are WGSL's `pack2x16snorm`'s (`⌊0.5 + 32767·e⌋`, `e` clamped
    /// to ±1), so the GPU's light volume holds the same values.
    #[test]
    fn stored_flux_is_the_flux_to_16_bits_of_its_ratio() {
        let step = MS_FLUX_RATIO / 32767.0;
        for phi in [1e-6f32, 0.3, 1.0, 250.0] {
            for k in -1000..=1000 {
                let j = phi * MS_FLUX_RATIO * k as f32 / 1000.0;
                let got = ms_stored_flux(j, phi);
                assert!(
                    // Half a step, and f32 rounding of the products.
                    (got - j).abs() <= 0.5 * step * phi + 4.0 * f32::EPSILON * j.abs(),
                    "φ {phi} j {j}: {got}"
                );
            }
            assert_eq!(ms_stored_flux(20.0 * phi, phi), MS_FLUX_RATIO * phi);
            assert_eq!(ms_stored_flux(-20.0 * phi, phi), -MS_FLUX_RATIO * phi);
        }
        // Exact steps: 1 (j/φ = 8/32767) and the half step rounds up, as pack2x16snorm does.
        assert_eq!(ms_stored_flux(step, 1.0), step);
        assert_eq!(ms_stored_flux(0.5 * step, 1.0), step);
        assert_eq!(ms_stored_flux(0.49 * step, 1.0), 0.0);
        for phi in [0.0f32, -1.0, f32::NAN] {
            assert_eq!(ms_stored_flux(1.0, phi), 0.0, "φ {phi}");
        }
    }

    /// The 26 shares are the sphere's: they sum to 1, and sampling uniform directions and
    /// counting the nearest of the 26 gives each its share (a million here, within 0.001).
    #[test]
    fn gather_shares_are_the_sphere_nearest_each_direction() {
        let total: f64 = ms_gather_dirs().map(|(_, w)| w).sum();
        assert!((total - 1.0).abs() < 1e-12, "{total}");
        let dirs: Vec<([f64; 3], f64)> = ms_gather_dirs()
            .map(|(e, w)| {
                let n = ((e[0] * e[0] + e[1] * e[1] + e[2] * e[2]) as f64).sqrt();
                (e.map(|v| v as f64 / n), w)
            })
            .collect();
        let mut hits = [0usize; 26];
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut unit = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        let n = 1_000_000;
        for _ in 0..n {
            // A uniform direction: z uniform in [−1, 1], azimuth uniform.
            let z = 2.0 * unit() - 1.0;
            let a = 2.0 * std::f64::consts::PI * unit();
            let r = (1.0 - z * z).sqrt();
            let d = [r * a.cos(), r * a.sin(), z];
            let best = (0..26)
                .max_by(|&i, &j| {
                    let dot = |k: usize| (0..3).map(|c| d[c] * dirs[k].0[c]).sum::<f64>();
                    dot(i).total_cmp(&dot(j))
                })
                .unwrap();
            hits[best] += 1;
        }
        for (k, h) in hits.iter().enumerate() {
            let got = *h as f64 / n as f64;
            assert!(
                (got - dirs[k].1).abs() < 1e-3,
                "direction {k}: {got} vs {}",
                dirs[k].1
            );
        }
    }

    /// The sun's weights are the shares with an isotropic phase; with a forward phase the
    /// direction toward the sun weighs most and one away from it least, and they always sum to 1.
    #[test]
    fn gather_weights_follow_the_phase_and_keep_the_energy() {
        let h = [1.0, 1.0, 2.0];
        let iso = ms_gather_weights(h, [0.0, 0.0, 1.0], ([0.0; 2], 1.0));
        let share: Vec<f64> = ms_gather_dirs().map(|(_, w)| w).collect();
        for (a, b) in iso.iter().zip(&share) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        let fwd = ms_gather_weights(h, [0.0, 0.0, 3.0], ([0.6; 2], 1.0));
        let total: f64 = fwd.iter().sum();
        assert!((total - 1.0).abs() < 1e-12, "{total}");
        // +z is direction 21 (x fastest, the 27 offsets' 13th skipped), −z direction 4.
        let dirs: Vec<[i32; 3]> = ms_gather_dirs().map(|(e, _)| e).collect();
        assert_eq!((dirs[21], dirs[4]), ([0, 0, 1], [0, 0, -1]));
        let max = fwd.iter().cloned().fold(0.0, f64::max);
        let min = (0..26).min_by(|&a, &b| fwd[a].total_cmp(&fwd[b])).unwrap();
        assert_eq!(fwd[21], max);
        assert_eq!(dirs[min][2], -1, "least weight toward {:?}", dirs[min]);
        assert!(fwd[4] < 0.2 * max, "{} vs {max}", fwd[4]);
        assert!((ms_beam_norm(h, [0.0, 0.0, 1.0], ([0.0; 2], 1.0)) - 1.0).abs() < 1e-12);
        let n = ms_beam_norm([1.0; 3], [0.0, 0.6, 0.8], ([0.6; 2], 1.0));
        assert!((0.9..1.1).contains(&n), "{n}");
    }

    #[test]
    fn the_own_cell_is_the_mean_over_the_cell() {
        for x in [1e-6, 0.01, 0.3, 0.4999, 0.5, 0.5001, 2.0, 30.0] {
            let (own, t) = ms_own_cell(x);
            // The closed forms (f64 keeps their digits here).
            let want_t = -(-x).exp_m1() / x;
            assert!((t - want_t).abs() < 1e-7, "{x}: T {t} vs {want_t}");
            if x > 1e-3 {
                let want = (1.0 - want_t) / x;
                assert!((own - want).abs() < 1e-7 * want, "{x}: {own} vs {want}");
            }
            // A uniform medium: the own cell's light and the rest's, q/σ each, sum to q/σ.
            assert!((own * x + t - 1.0).abs() < 1e-12, "{x}");
            // The means over the segment by quadrature: (1 − e^{−σs})/σ and e^{−σs}, s ∈ [0, L].
            let m = 20000;
            let (mut a, mut b) = (0.0, 0.0);
            for k in 0..m {
                let s = (k as f64 + 0.5) / m as f64 * x;
                a += -(-s).exp_m1() / x / m as f64;
                b += (-s).exp() / m as f64;
            }
            assert!(
                (own - a).abs() < 1e-6 * a.max(1e-9) + 1e-12,
                "{x}: {own} vs {a}"
            );
            assert!((t - b).abs() < 1e-6, "{x}: {t} vs {b}");
        }
    }

    #[test]
    fn sweeps_are_even() {
        assert!((0..8).all(|l| ms_sweeps(l).is_multiple_of(2) && ms_sweeps(l) > 0));
    }

    #[test]
    fn levels_halve_rounding_up_until_the_coarsest() {
        assert_eq!(ms_levels([4, 6, 1]), vec![[4, 6, 1]]);
        assert_eq!(
            ms_levels([54, 41, 64]),
            vec![
                [54, 41, 64],
                [27, 21, 32],
                [14, 11, 16],
                [7, 6, 8],
                [4, 3, 4]
            ]
        );
    }

    /// The half cell's diffusion problem solved by finite differences (`m` steps, second
    /// order): `−D·φ'' + σ_a·φ = q(s)` on `[0, h/2]`, `φ(0) = 2D·φ'(0)`, `φ(h/2) = φ_c`; the
    /// outflow `D·φ'(0)`. An independent check of [`ms_vacuum_face`]'s closed form.
    fn half_cell_outflow(h: f64, d: f64, sa: f64, q: impl Fn(f64) -> f64, phi_c: f64) -> f64 {
        let m = 4000;
        let ds = 0.5 * h / m as f64;
        // Unknowns φ_0 … φ_{m−1} (φ_m = φ_c); Thomas algorithm.
        let (mut a, mut b, mut c, mut r) = (vec![0.0; m], vec![0.0; m], vec![0.0; m], vec![0.0; m]);
        // The face: a ghost node from the second-order boundary condition, φ_{−1} = φ_1 −
        // 2·ds·φ_0/(2D), in the half-weighted balance of the first node.
        b[0] = d / (ds * ds) * 2.0 + sa + 2.0 * d / (ds * ds) * ds / (2.0 * d);
        c[0] = -2.0 * d / (ds * ds);
        r[0] = q(0.0);
        for k in 1..m {
            a[k] = -d / (ds * ds);
            b[k] = 2.0 * d / (ds * ds) + sa;
            c[k] = -d / (ds * ds);
            r[k] = q(k as f64 * ds);
        }
        r[m - 1] -= c[m - 1] * phi_c;
        for k in 1..m {
            let w = a[k] / b[k - 1];
            b[k] -= w * c[k - 1];
            r[k] -= w * r[k - 1];
        }
        let mut phi = vec![0.0; m];
        phi[m - 1] = r[m - 1] / b[m - 1];
        for k in (0..m - 1).rev() {
            phi[k] = (r[k] - c[k] * phi[k + 1]) / b[k];
        }
        // φ(0) = 2D·φ'(0): the outflow is half the face's fluence.
        0.5 * phi[0]
    }

    #[test]
    fn the_vacuum_face_matches_the_half_cells_diffusion_problem() {
        // (h, st, sr, albedo, q0, q_in): thin and thick cells, sources falling and rising
        // inward, none inward, no absorption.
        let cases = [
            (0.5, 1.0, 1.0, 0.94, 0.3, Some(0.2)),
            (2.0, 1.0, 1.0, 0.94, 0.3, Some(0.1)),
            (4.0, 1.0, 1.0, 0.94, 0.3, Some(0.01)),
            (4.0, 1.0, 0.7, 0.8, 0.1, Some(0.3)),
            (3.0, 2.0, 1.5, 0.5, 1.0, None),
            (2.0, 1.0, 1.0, 1.0, 0.5, Some(0.25)),
            (8.0, 3.0, 3.0, 0.99, 0.2, Some(0.19)),
            // Past the thick limit's switch (x ≈ 31 and 61) and the resistance's clamp.
            (100.0, 1.0, 1.0, 0.9, 0.4, Some(0.1)),
            (100.0, 1.0, 1.0, 0.5, 0.4, None),
        ];
        for (h, st, sr, albedo, q0, q_in) in cases {
            let (r, pj) = ms_vacuum_face(h, st, sr, albedo, q0, q_in, 0.0);
            let d = 1.0 / (3.0 * sr);
            let sa = st * (1.0 - albedo);
            let y: f64 = match q_in {
                Some(q1) => (0.5 * (q0 / q1).ln()).clamp(-MS_VACUUM_MAX_Y, MS_VACUUM_MAX_Y),
                None => 0.0,
            };
            let kappa = 2.0 * y / h;
            // The exponential source whose mean over the cell is q0.
            let qs = if kappa == 0.0 {
                q0
            } else {
                q0 * kappa * h / -(-kappa * h).exp_m1()
            };
            for phi_c in [0.0, 1.0, 5.0] {
                let want = half_cell_outflow(h, d, sa, |s| qs * (-kappa * s).exp(), phi_c);
                let got = (phi_c - pj) / r;
                assert!(
                    (got - want).abs() <= 1e-4 * want.abs().max(1e-3),
                    "h {h} st {st} sr {sr} albedo {albedo} q {q0} {q_in:?} φ_c {phi_c}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn the_vacuum_face_is_marshaks_in_thin_cells() {
        // Cells thin in mean free paths: the plain vacuum face, 1.5·h·σ_r + 2 (and the
        // limiter's part) toward 0, the source's share vanishing with h².
        for h in [1e-3, 1e-2] {
            let (r, pj) = ms_vacuum_face(h, 1.0, 0.8, 0.9, 1.0, Some(0.5), 0.25);
            let plain = 1.5 * h * 0.8 + 2.0 + 0.25;
            assert!((r - plain).abs() < 2.0 * h * h, "{h}: {r} vs {plain}");
            assert!(pj <= 0.0 && -pj < h * h, "{h}: {pj}");
        }
        // No source: no share; no medium to diffuse through: the plain face.
        assert_eq!(
            ms_vacuum_face(2.0, 1.0, 1.0, 0.9, 0.0, Some(1.0), 0.0).1,
            0.0
        );
        assert_eq!(
            ms_vacuum_face(2.0, 1.0, 0.0, 0.9, 1.0, None, 0.5),
            (2.5, 0.0)
        );
    }

    #[test]
    fn the_vacuum_shape_is_its_formula_without_seams() {
        let direct = |x: f64, y: f64| {
            (
                (x.cosh() - (-y).exp() - y * x.sinh() / x) / (x * x - y * y),
                x,
                y,
            )
        };
        for (x, y) in [(0.3, 2.0), (2.0, -1.0), (3.0, 0.5), (0.7, -3.5), (5.0, 4.0)] {
            let (want, ..) = direct(x, y);
            let got = ms_vacuum_shape(x, y);
            assert!(
                (got - want).abs() < 1e-9 * want.abs(),
                "{x} {y}: {got} vs {want}"
            );
        }
        // Across each branch's border (the series below t = 1, the derivative where x² ≈ y²)
        // and through the removable singularities x = ±y.
        for (x, y) in [
            (1.0, 0.2),
            (0.2, 1.0),
            (2.0, 2.0 * 0.99f64.sqrt()),
            (1.5, 1.5),
            (1.5, -1.5),
        ] {
            let e = 1e-7;
            let (a, b) = (ms_vacuum_shape(x - e, y), ms_vacuum_shape(x + e, y));
            assert!((a - b).abs() < 1e-6 * a.abs(), "{x} {y}: {a} vs {b}");
        }
        let (near, ..) = direct(1.5 + 1e-4, 1.5);
        assert!((ms_vacuum_shape(1.5, 1.5) - near).abs() < 1e-3 * near);
        assert!((ms_vacuum_shape(0.0, 0.0) - 0.5).abs() < 1e-15);
    }
}
