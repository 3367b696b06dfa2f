//! `MsModel::Diffusion`: the sun's and the sky's multiple scattering in `Mode::Lit` as a
//! flux-limited diffusion solve over the light volume's cells, instead of closed forms of the
//! depths at each sample. Light the sun's beam loses to scattering in one cell spreads to its
//! neighbours, leaks out where the medium is thin or ends, and is absorbed in thick cores; the
//! sky's light enters through every surface of the medium and fades inward. Closed forms of
//! one point's depths cannot move light sideways (into a shadowed lobe) nor take it away (out
//! of a thin edge). Measured against the reference in `docs/rendering.md`.
//!
//! Per cell `i` of the light volume (cell-mean density `ρᵢ`, extinction `σᵢ = σ·ρᵢ` per unit
//! length, albedo `α`, the phase's mean cosine `ḡ`), two fields of fluence `φ`: the sun's
//! scattered light per unit sun irradiance, and all the sky's light per unit sky radiance.
//! - **source** of the sun's field: what the beam loses to scattering in the cell, per unit
//!   volume: the beam enters at optical depth `e = max(σ·τ_sun − x/2, 0)` (`τ_sun` at the
//!   centre, `x = σᵢ·c` the cell's depth along the chord `c` the sun's ray crosses per cell slab
//!   along its major axis) and `qᵢ = α·e^{−e}·(1 − e^{−x})/c`. The sky's field has no source:
//!   its light comes in through the boundary;
//! - **balance** (finite volumes, Jacobi): `Σ_faces (φᵢ − φⱼ)/(h·R) + σᵢ(1 − α)·φᵢ = qᵢ`, `h` the
//!   cell edge along the face's axis. A face's resistance is the sum of two half-cell ones,
//!   `rᵢ = ½h·(3σᵢ(1 − ḡα) + |∇φ|/φ)`: diffusion's `h/(2D)` with the reduced extinction, plus
//!   Wilson's flux limiter (`|J| ≤ φ`: in optically thin cells diffusion's coefficient
//!   `1/(3σ)` would move light out faster than it can stream). Toward an empty cell or the
//!   grid's edge the far half is Marshak's vacuum boundary, resistance 2 (the net flux out is
//!   `(φ − φ_out)/2` at the face), with `φ_out = 0` for the sun's field and `4π` for the sky's
//!   (a uniform incoming radiance of 1); empty cells hold `φ_out`. At albedo 1 the sky's field
//!   is `4π` everywhere, the start and a fixed point of the sweeps: the white furnace holds
//!   exactly, whatever the geometry.
//! - **solver**: the grid is coarsened by 2 (means of 8 cells, missing ones empty) until no
//!   side exceeds [`MS_COARSEST`] cells; from the coarsest (starting at `φ_out`) each level runs
//!   [`MS_ITERATIONS`] Jacobi sweeps ([`MS_FINE_SWEEPS`] on the light volume's own cells; the
//!   limiter from the sweep's input) and hands its `φ` to the next finer level as its start
//!   (each cell its parent's value). Thin clouds need the
//!   coarse levels: a sweep moves light one cell, and 16 sweeps of a 64-cell grid alone leave
//!   a thin stormscape frame at half its converged brightness.
//! - **flux**: after the last sweep, the net flux `J` at each cell centre, per axis the mean of
//!   its two faces' `(φᵢ − φⱼ)/(h·R)`, kept as the GPU keeps it: per axis `J/φ` rounded to 16
//!   bits over ±8 (`vdbcook_scene::ms_stored_flux`, a step of 2.4·10⁻⁴·φ), so a light volume
//!   holds 24 bytes a cell (φ of both fields and the density in f32, six 16-bit fluxes).
//!
//! The march reads both fields density-weighted trilinear (`Σ wρφ / Σ wρ`: empty cells, which
//! hold `φ_out`, do not bleed into a sample next to them) as first-order (P1) radiance: the light
//! scattered toward the eye, `ω` the direction from the sample to it, is
//! `φ/4π + 3ḡ·J·ω/4π` (`LightVolume::diffuse_at`). The sun's is added to its single scattering
//! `p(μ)·e^{−σ·τ_sun}`; the sky's is the sky's whole source.

#[cfg(feature = "parallel")]
use rayon::prelude::*;
use vdbcook_scene::{ms_levels, ms_stored_flux, ms_sweeps, LightGrid};
pub use vdbcook_scene::{DiffusionInputs, MS_COARSEST, MS_FINE_SWEEPS, MS_ITERATIONS, MS_VACUUM};

/// The two fields the solve carries per cell: the sun's scattered light and the sky's.
const FIELDS: usize = 2;
/// `φ` per cell of both fields.
type Phi = [f64; FIELDS];

/// One level of the solve: per cell the extinction, the reduced extinction and the sun's
/// source.
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

    /// The neighbour of cell `i` (at `c`) along axis `a` (`up`: +1), if inside the level.
    fn step(&self, i: usize, c: [usize; 3], a: usize, up: bool) -> Option<usize> {
        let stride = [1, self.dims[0], self.dims[0] * self.dims[1]];
        if up {
            (c[a] + 1 < self.dims[a]).then(|| i + stride[a])
        } else {
            (c[a] > 0).then(|| i - stride[a])
        }
    }

    fn coord(&self, i: usize) -> [usize; 3] {
        let [nx, ny, _] = self.dims;
        [i % nx, (i / nx) % ny, i / (nx * ny)]
    }

    /// Cell `i`'s half-cell resistances per field and axis, `½h·(3σ_r + |∇φ|/φ)`, from `phi`
    /// (a field's value outside the level and in empty cells is its boundary value).
    fn half(&self, i: usize, phi: &[Phi]) -> [[f64; 3]; FIELDS] {
        let c = self.coord(i);
        let mut out = [[0.0; 3]; FIELDS];
        for (f, o) in out.iter_mut().enumerate() {
            let mut g2 = 0.0;
            for a in 0..3 {
                let at = |up| self.step(i, c, a, up).map_or(BOUNDARY[f], |j| phi[j][f]);
                let d = (at(true) - at(false)) / (2.0 * self.h[a]);
                g2 += d * d;
            }
            let lim = if phi[i][f] > 0.0 {
                g2.sqrt() / phi[i][f]
            } else {
                0.0
            };
            *o = [0, 1, 2].map(|a| 0.5 * self.h[a] * (3.0 * self.sr[i] + lim));
        }
        out
    }
}

/// Each field's `φ` in empty cells and beyond the grid (Marshak's vacuum boundary): none of
/// the sun's scattered light comes in; the sky's comes in as a uniform radiance of 1, `φ = 4π`.
const BOUNDARY: Phi = [0.0, 4.0 * std::f64::consts::PI];

/// The diffusion model's light per cell, per unit sun irradiance and unit sky radiance.
#[derive(Debug, Clone, Default)]
pub struct Diffusion {
    /// `[φ_sun/4π, φ_sky/4π]` per cell (empty cells: `[0, 1]`).
    pub phi: Vec<[f32; 2]>,
    /// The net flux `J/4π` per cell of both fields, per axis (empty cells: 0): the mean of the
    /// cell's two faces' fluxes along each axis with the solve's resistances, as a light volume
    /// stores it: `J/φ` in 16 bits (`vdbcook_scene::ms_stored_flux`; the GPU's 24 bytes a
    /// cell).
    pub flux: Vec<[[f32; 3]; 2]>,
}

/// The sun's and the sky's scattered light per cell of `grid`, from the cells' mean densities
/// and the sun's depth at their centres (`tau_sun(i)`, in length units before the extinction).
pub fn solve(
    grid: &LightGrid,
    density: &[f32],
    tau_sun: impl Fn(usize) -> f64,
    m: &DiffusionInputs,
) -> Diffusion {
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
    let mut phi: Vec<Phi> = Vec::new();
    for li in (0..levels.len()).rev() {
        let l = &levels[li];
        let start = match levels.get(li + 1) {
            None => vec![BOUNDARY; l.cells()],
            Some(parent) => prolong(l.dims, parent.dims, &phi),
        };
        phi = relax(l, start, m.albedo, ms_sweeps(li));
    }
    let norm = 1.0 / (4.0 * std::f64::consts::PI);
    let flux = flux(&levels[0], &phi);
    let phi: Vec<[f32; 2]> = phi.iter().map(|p| p.map(|v| (v * norm) as f32)).collect();
    // Stored as the GPU stores it: per axis, J/φ in 16 bits (`ms_stored_flux`).
    let flux = flux
        .into_iter()
        .zip(&phi)
        .map(|(j, p)| [0, 1].map(|f| j[f].map(|c| ms_stored_flux((c * norm) as f32, p[f]))))
        .collect();
    Diffusion { phi, flux }
}

/// Each cell of a level of `dims` takes its parent's value (`parent` over `pd` cells).
fn prolong(dims: [usize; 3], pd: [usize; 3], parent: &[Phi]) -> Vec<Phi> {
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

/// `sweeps` Jacobi sweeps of the balance (module docs) from `phi`, both fields.
fn relax(l: &Level, mut phi: Vec<Phi>, albedo: f64, sweeps: usize) -> Vec<Phi> {
    let slab = l.dims[0] * l.dims[1];
    let n = l.cells();
    let mut next = vec![[0.0f64; FIELDS]; n];
    let mut half = vec![[[0.0f64; 3]; FIELDS]; n];
    for _ in 0..sweeps {
        let limit = |(z, out): (usize, &mut [[[f64; 3]; FIELDS]])| {
            for (k, r) in out.iter_mut().enumerate() {
                let i = z * slab + k;
                if l.st[i] > 0.0 {
                    *r = l.half(i, &phi);
                }
            }
        };
        #[cfg(feature = "parallel")]
        half.par_chunks_mut(slab).enumerate().for_each(limit);
        #[cfg(not(feature = "parallel"))]
        half.chunks_mut(slab).enumerate().for_each(limit);

        let update = |(z, out): (usize, &mut [Phi])| {
            for (k, v) in out.iter_mut().enumerate() {
                let i = z * slab + k;
                if l.st[i] <= 0.0 {
                    *v = BOUNDARY;
                    continue;
                }
                let c = l.coord(i);
                for f in 0..FIELDS {
                    let (mut diag, mut off) = (l.st[i] * (1.0 - albedo), 0.0);
                    for (a, &hi) in half[i][f].iter().enumerate() {
                        for up in [false, true] {
                            let (r, pj) = match l.step(i, c, a, up).filter(|&j| l.st[j] > 0.0) {
                                Some(j) => (hi + half[j][f][a], phi[j][f]),
                                None => (hi + MS_VACUUM, BOUNDARY[f]),
                            };
                            let g = 1.0 / (l.h[a] * r);
                            diag += g;
                            off += g * pj;
                        }
                    }
                    let q = if f == 0 { l.q[i] } else { 0.0 };
                    v[f] = (q + off) / diag;
                }
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

/// The net flux `J` per cell of the level (per field, per axis; 0 in empty cells): the mean
/// of the fluxes through the cell's two faces along each axis, `(φᵢ − φⱼ)/(h·R)` with the
/// resistances of the final `phi` (as the last sweep would compute them).
fn flux(l: &Level, phi: &[Phi]) -> Vec<[[f64; 3]; FIELDS]> {
    let n = l.cells();
    let half: Vec<[[f64; 3]; FIELDS]> = (0..n)
        .map(|i| {
            if l.st[i] > 0.0 {
                l.half(i, phi)
            } else {
                [[0.0; 3]; FIELDS]
            }
        })
        .collect();
    (0..n)
        .map(|i| {
            let mut out = [[0.0; 3]; FIELDS];
            if l.st[i] <= 0.0 {
                return out;
            }
            let c = l.coord(i);
            for (f, o) in out.iter_mut().enumerate() {
                *o = [0, 1, 2].map(|a| {
                    [false, true]
                        .into_iter()
                        .map(|up| {
                            let (r, pj) = match l.step(i, c, a, up).filter(|&j| l.st[j] > 0.0) {
                                Some(j) => (half[i][f][a] + half[j][f][a], phi[j][f]),
                                None => (half[i][f][a] + MS_VACUUM, BOUNDARY[f]),
                            };
                            // Along +a: out of the upper face, into the lower one.
                            let d = if up { phi[i][f] - pj } else { pj - phi[i][f] };
                            0.5 * d / (l.h[a] * r)
                        })
                        .sum()
                });
            }
            out
        })
        .collect()
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
            phi.phi[grid.index([c, c, c])][0] as f64 * 4.0 * std::f64::consts::PI,
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

    /// White furnace of the sky's field: at albedo 1 no light is lost, and a uniform sky
    /// radiance of 1 outside means `φ/4π = 1` everywhere inside, with no net flux, however
    /// thick and uneven the medium (the sweeps' start and fixed point).
    #[test]
    fn the_sky_field_is_the_sky_at_albedo_one() {
        let (mut density, m, grid) = cube(12, 3.0, 1.0);
        for (i, d) in density.iter_mut().enumerate() {
            *d = [0.0, 0.05, 1.0, 7.0][i % 4];
        }
        let out = solve(&grid, &density, |_| 0.0, &m);
        for (i, (p, j)) in out.phi.iter().zip(&out.flux).enumerate() {
            assert!((p[1] - 1.0).abs() < 1e-6, "cell {i}: sky {}", p[1]);
            assert!(
                j[1].iter().all(|v| v.abs() < 1e-6),
                "cell {i}: flux {:?}",
                j[1]
            );
        }
        // Not a test that cannot fail: with absorption the sky fades inside.
        let (density, m, grid) = cube(12, 3.0, 0.9);
        let out = solve(&grid, &density, |_| 0.0, &m);
        let c = grid.index([6, 6, 6]);
        assert!(out.phi[c][1] < 0.1, "sky at the centre {}", out.phi[c][1]);
    }

    /// The sky's light entering a thick absorbing medium through a face decays as diffusion
    /// theory says: with the flux limiter (`D = 1/(3σ_tr + κ)`) the fluence falls as `e^{−κz}`,
    /// `κ = (σ_a + √(σ_a² + 12σ_a·σ_tr))/2` (0.6 per cell for σ = 1, albedo 0.9, isotropic),
    /// and the flux flows inward at `J = D·κ·φ`. Measured along the central axis from the
    /// −z face, where the other faces are 20 cells away.
    #[test]
    fn the_sky_fades_into_a_thick_medium_as_diffusion_theory_says() {
        let (density, m, grid) = cube(40, 1.0, 0.9);
        let out = solve(&grid, &density, |_| 0.0, &m);
        let (sa, st) = (0.1f64, 1.0f64);
        let kappa = (sa + (sa * sa + 12.0 * sa * st).sqrt()) / 2.0;
        let at = |z: u32| out.phi[grid.index([20, 20, z])][1] as f64;
        let rate = (at(2) / at(6)).ln() / 4.0;
        assert!(
            (rate / kappa - 1.0).abs() < 0.05,
            "decay {rate} per cell, theory {kappa}"
        );
        let i = grid.index([20, 20, 4]);
        let j_over_phi = out.flux[i][1][2] as f64 / out.phi[i][1] as f64;
        let want = kappa / (3.0 * st + kappa);
        assert!(
            (j_over_phi / want - 1.0).abs() < 0.05,
            "J/φ {j_over_phi}, theory {want}"
        );
    }
}
