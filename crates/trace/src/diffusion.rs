//! `MsModel::Diffusion`: the sun's multiple scattering in `Mode::Lit` as a flux-limited
//! diffusion solve over the light volume's cells, instead of closed-form octaves of the depth
//! toward the sun at each sample. Light the sun's beam loses to scattering in one cell spreads
//! to its neighbours, leaks out where the medium is thin or ends, and is absorbed in thick
//! cores; the octaves cannot move light sideways (into a shadowed lobe) nor take it away (out
//! of a thin edge). Measured against the reference in `docs/rendering.md`.
//!
//! Per cell `i` of the light volume (cell-mean density `ρᵢ`, extinction `σᵢ = σ·ρᵢ` per unit
//! length, albedo `α`, the phase's mean cosine `ḡ`), `φ` the fluence of scattered sun light per
//! unit sun irradiance:
//! - **source**: what the beam loses to scattering in the cell, per unit volume: the beam
//!   enters at optical depth `e = max(σ·τ_sun − x/2, 0)` (`τ_sun` at the centre, `x = σᵢ·c` the
//!   cell's depth along the chord `c` the sun's ray crosses per cell slab along its major axis)
//!   and `qᵢ = α·e^{−e}·(1 − e^{−x})/c`;
//! - **balance** (finite volumes, Jacobi): `Σ_faces (φᵢ − φⱼ)/(h·R) + σᵢ(1 − α)·φᵢ = qᵢ`, `h` the
//!   cell edge along the face's axis. A face's resistance is the sum of two half-cell ones,
//!   `rᵢ = ½h·(3σᵢ(1 − ḡα) + |∇φ|/φ)`: diffusion's `h/(2D)` with the reduced extinction, plus
//!   Wilson's flux limiter (`|J| ≤ φ`: in optically thin cells diffusion's coefficient
//!   `1/(3σ)` would move light out faster than it can stream). Toward an empty cell or the grid's edge the far half is Marshak's
//!   vacuum boundary, resistance 2 (`J = φ/2` at the face); empty cells hold `φ = 0`.
//! - **solver**: the grid is coarsened by 2 (means of 8 cells, missing ones empty) until no
//!   side exceeds [`MS_COARSEST`] cells; from the coarsest (starting at 0) each level runs
//!   [`MS_ITERATIONS`] Jacobi sweeps ([`MS_FINE_SWEEPS`] on the light volume's own cells; the
//!   limiter from the sweep's input) and hands its `φ` to the next finer level as its start
//!   (each cell its parent's value). Thin clouds need the
//!   coarse levels: a sweep moves light one cell, and 16 sweeps of a 64-cell grid alone leave
//!   a thin stormscape frame at half its converged brightness.
//!
//! The march reads `φ/4π` (isotropic in-scattering of the diffuse light), density-weighted
//! trilinear (`Σ wρφ / Σ wρ`: empty cells, which hold 0, do not darken a sample next to them),
//! and adds it to the single scattering `p(μ)·e^{−σ·τ_sun}`.

#[cfg(feature = "parallel")]
use rayon::prelude::*;
use vdbcook_scene::{ms_levels, ms_sweeps, LightGrid};
pub use vdbcook_scene::{DiffusionInputs, MS_COARSEST, MS_FINE_SWEEPS, MS_ITERATIONS, MS_VACUUM};

/// One level of the solve: per cell the extinction, the reduced extinction and the source.
struct Level {
    dims: [usize; 3],
    h: [f64; 3],
    st: Vec<f64>,
    sr: Vec<f64>,
    q: Vec<f64>,
}

impl Level {
    fn cells(&self) -> usize {
        self.dims.iter().product()
    }

    /// The level 2× coarser: each value the mean of the (up to) 8 cells it covers.
    fn coarser(&self) -> Level {
        let d = self.dims;
        let cd = d.map(|v| v.div_ceil(2));
        let n = cd.iter().product();
        let mut out = Level {
            dims: cd,
            h: self.h.map(|v| 2.0 * v),
            st: vec![0.0; n],
            sr: vec![0.0; n],
            q: vec![0.0; n],
        };
        for z in 0..d[2] {
            for y in 0..d[1] {
                for x in 0..d[0] {
                    let i = x + d[0] * (y + d[1] * z);
                    let j = x / 2 + cd[0] * (y / 2 + cd[1] * (z / 2));
                    out.st[j] += self.st[i] / 8.0;
                    out.sr[j] += self.sr[i] / 8.0;
                    out.q[j] += self.q[i] / 8.0;
                }
            }
        }
        out
    }
}

/// `φ/4π` per cell of `grid` (per unit sun irradiance; 0 in empty cells), from the cells'
/// mean densities and the sun's depth at their centres (`tau_sun(i)`, in length units before
/// the extinction).
pub fn solve(
    grid: &LightGrid,
    density: &[f32],
    tau_sun: impl Fn(usize) -> f64,
    m: &DiffusionInputs,
) -> Vec<f32> {
    let n = grid.cells();
    let st: Vec<f64> = density
        .iter()
        .map(|&d| m.extinction * d.max(0.0) as f64)
        .collect();
    let sr = st
        .iter()
        .map(|&t| t * (1.0 - m.mean_cos * m.albedo))
        .collect();
    let q = (0..n)
        .map(|i| {
            let x = st[i] * m.chord;
            let entry = (m.extinction * tau_sun(i) - 0.5 * x).max(0.0);
            m.albedo * (-entry).exp() * -(-x).exp_m1() / m.chord
        })
        .collect();
    let dims = ms_levels(grid.dims);
    let mut levels = vec![Level {
        dims: dims[0].map(|d| d as usize),
        h: m.h,
        st,
        sr,
        q,
    }];
    for d in &dims[1..] {
        let c = levels[levels.len() - 1].coarser();
        debug_assert_eq!(c.dims, d.map(|v| v as usize));
        levels.push(c);
    }
    let mut phi: Vec<f64> = Vec::new();
    for li in (0..levels.len()).rev() {
        let l = &levels[li];
        let start = match levels.get(li + 1) {
            None => vec![0.0; l.cells()],
            Some(parent) => prolong(l.dims, parent.dims, &phi),
        };
        phi = relax(l, start, m.albedo, ms_sweeps(li));
    }
    let norm = 1.0 / (4.0 * std::f64::consts::PI);
    phi.iter().map(|&p| (p * norm) as f32).collect()
}

/// Each cell of a level of `dims` takes its parent's value (`parent` over `pd` cells).
fn prolong(dims: [usize; 3], pd: [usize; 3], parent: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(dims.iter().product());
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                out.push(parent[x / 2 + pd[0] * (y / 2 + pd[1] * (z / 2))]);
            }
        }
    }
    out
}

/// `sweeps` Jacobi sweeps of the balance (module docs) from `phi`.
fn relax(l: &Level, mut phi: Vec<f64>, albedo: f64, sweeps: usize) -> Vec<f64> {
    let [nx, ny, _] = l.dims;
    let slab = nx * ny;
    let stride = [1, nx, slab];
    let n = l.cells();
    let mut next = vec![0.0f64; n];
    let mut half = vec![[0.0f64; 3]; n];
    let coord = |i: usize| [i % nx, (i / nx) % ny, i / slab];
    // The neighbour of `i` along axis `a` (`up`: +1), if inside the grid.
    let step = |i: usize, c: [usize; 3], a: usize, up: bool| {
        if up {
            (c[a] + 1 < l.dims[a]).then(|| i + stride[a])
        } else {
            (c[a] > 0).then(|| i - stride[a])
        }
    };
    for _ in 0..sweeps {
        let limit = |(z, out): (usize, &mut [[f64; 3]])| {
            for (k, r) in out.iter_mut().enumerate() {
                let i = z * slab + k;
                if l.st[i] <= 0.0 {
                    continue;
                }
                let c = coord(i);
                let mut g2 = 0.0;
                for a in 0..3 {
                    let at = |up| step(i, c, a, up).map_or(0.0, |j| phi[j]);
                    let d = (at(true) - at(false)) / (2.0 * l.h[a]);
                    g2 += d * d;
                }
                let lim = if phi[i] > 0.0 {
                    g2.sqrt() / phi[i]
                } else {
                    0.0
                };
                *r = [0, 1, 2].map(|a| 0.5 * l.h[a] * (3.0 * l.sr[i] + lim));
            }
        };
        #[cfg(feature = "parallel")]
        half.par_chunks_mut(slab).enumerate().for_each(limit);
        #[cfg(not(feature = "parallel"))]
        half.chunks_mut(slab).enumerate().for_each(limit);

        let update = |(z, out): (usize, &mut [f64])| {
            for (k, v) in out.iter_mut().enumerate() {
                let i = z * slab + k;
                if l.st[i] <= 0.0 {
                    *v = 0.0;
                    continue;
                }
                let c = coord(i);
                let (mut diag, mut off) = (l.st[i] * (1.0 - albedo), 0.0);
                for (a, &hi) in half[i].iter().enumerate() {
                    for up in [false, true] {
                        let (r, pj) = match step(i, c, a, up).filter(|&j| l.st[j] > 0.0) {
                            Some(j) => (hi + half[j][a], phi[j]),
                            None => (hi + MS_VACUUM, 0.0),
                        };
                        let g = 1.0 / (l.h[a] * r);
                        diag += g;
                        off += g * pj;
                    }
                }
                *v = (l.q[i] + off) / diag;
            }
        };
        #[cfg(feature = "parallel")]
        next.par_chunks_mut(slab).enumerate().for_each(update);
        #[cfg(not(feature = "parallel"))]
        next.chunks_mut(slab).enumerate().for_each(update);
        std::mem::swap(&mut phi, &mut next);
    }
    phi
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cube of `side` cells of unit edge and uniform density, its cells' sun depth 0.
    fn cube(side: u32, density: f32, albedo: f64) -> (Vec<f32>, DiffusionInputs, LightGrid) {
        let grid = LightGrid {
            lo: [0.0; 3],
            cell: 1.0,
            dims: [side; 3],
        };
        let inputs = DiffusionInputs {
            extinction: 1.0,
            albedo,
            mean_cos: 0.0,
            h: [1.0; 3],
            chord: 1.0,
        };
        (vec![density; grid.cells()], inputs, grid)
    }

    /// `φ` (not `/4π`) at the centre cell.
    fn centre(side: u32, density: f32, albedo: f64) -> (f64, f64) {
        let (density, m, grid) = cube(side, density, albedo);
        let phi = solve(&grid, &density, |_| 0.0, &m);
        let c = side / 2;
        let x = density[0] as f64;
        // The source of a cell entered at depth 0 (every cell's, with the sun's depth 0).
        let q = albedo * -(-x).exp_m1();
        (
            phi[grid.index([c, c, c])] as f64 * 4.0 * std::f64::consts::PI,
            q,
        )
    }

    /// Deep inside a thick medium light neither arrives nor leaves: the fluence balances the
    /// source against absorption, `σ(1 − α)·φ = q`.
    #[test]
    fn a_thick_uniform_medium_balances_source_and_absorption() {
        let (phi, q) = centre(40, 2.0, 0.9);
        let want = q / (2.0 * (1.0 - 0.9));
        assert!((phi / want - 1.0).abs() < 1e-3, "{phi} against {want}");
    }

    /// In an optically thin cube (side 0.32 mean free paths) light streams out unscattered:
    /// the fluence at the centre is about the free-streaming one, `q·∫ dV/(4πr²)` over the
    /// cube (a sum over 64³ points here); measured 0.59 of it. The flux limiter and the vacuum
    /// boundary keep it there: without the limiter diffusion drains the cube faster than
    /// light streams (0.33), and so does a leakier boundary (resistance ½: 0.41).
    #[test]
    fn a_thin_cube_holds_about_the_free_streaming_fluence() {
        let side = 32u32;
        let (phi, q) = centre(side, 0.01, 0.9);
        // The centre cell's centre is at side/2 + 1/2 in cell units.
        let c = side as f64 / 2.0 + 0.5;
        let k = 64usize;
        let d = side as f64 / k as f64;
        let mut sum = 0.0;
        for z in 0..k {
            for y in 0..k {
                for x in 0..k {
                    let p = [x, y, z].map(|i| (i as f64 + 0.5) * d);
                    let r2: f64 = (0..3).map(|a| (p[a] - c) * (p[a] - c)).sum();
                    sum += d * d * d / (4.0 * std::f64::consts::PI * r2);
                }
            }
        }
        let free = q * sum;
        let ratio = phi / free;
        assert!(
            (0.5..1.0).contains(&ratio),
            "{phi} against {free} (ratio {ratio})"
        );
    }
}
