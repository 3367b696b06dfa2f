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
//!   volume: the beam enters at optical depth `e = σ·τ_entry` (`τ_entry` walked from where the
//!   ray from the cell's centre toward the sun leaves the cell, `LightGrid::centre_exit`),
//!   `x = σᵢ·c` is the cell's depth along the chord `c` the sun's ray crosses per cell slab
//!   along its major axis, and `qᵢ = α·e^{−e}·(1 − e^{−x})/c`. The entry walked, not taken
//!   as the centre's depth less `x/2`: where the centre's own half path is denser or thinner
//!   than the cell's mean (a dense cell's sunlit skin) that guess put the beam's loss at the
//!   wrong depth (smoke1 1.033 → 1.004 of the reference's sunlit image; docs/rendering.md).
//!   The sky's field has no source: its light comes in through the boundary;
//! - **gathered orders**: the sun's light scattered once and twice is not diffused but
//!   gathered (`gather`: along 26 directions, the steps widening through the coarser levels like
//!   the cone each direction stands for, the sun's phase in the first order's weights and the
//!   once-scattered light's beam-like share scattered by the phase in the second's), and the
//!   solve's source is the light scattered twice scattering again, `α·σᵢ·φ₂`: diffusion carries
//!   only the light scattered three times and more. Diffusing all of it lost 7–11% of the light
//!   scattered more than once on wispy clouds (WDAS 0.89 of the reference's), the second order
//!   as much as the rest; gathered, the sunlit images are within 1% on WDAS (docs/rendering.md);
//! - **balance** (finite volumes, Jacobi): `Σ_faces (φᵢ − φⱼ)/(h·R) + σᵢ(1 − α)·φᵢ = qᵢ`, `h` the
//!   cell edge along the face's axis. A face's resistance is the sum of two half-cell ones,
//!   `rᵢ = ½h·(3σ'ᵢ(1 − ḡα) + |∇φ|/φ)`: diffusion's `h/(2D)` with the reduced extinction, plus
//!   Wilson's flux limiter (`|J| ≤ φ`: in optically thin cells diffusion's coefficient
//!   `1/(3σ)` would move light out faster than it can stream). `σ'ᵢ` is the extinction of the
//!   cell's transport density (`vdbcook_scene::transport_density`: as transparent across the
//!   cell as its voxels' columns are), at most `σᵢ`: light crosses a cell through its thin
//!   columns, which the mean density hides (with the mean, the dense scenes' multiple
//!   scattering read 5–9% bright under 64 cells; docs/rendering.md). Absorption and sources keep
//!   the mean. Toward an empty cell or the grid's edge the far half is Marshak's vacuum
//!   boundary, resistance 2 (the net flux out is `(φ − φ_out)/2` at the face), with
//!   `φ_out = 0` for the sun's field and `4π` for the sky's
//!   (a uniform incoming radiance of 1); empty cells hold `φ_out`. At albedo 1 the sky's field
//!   is `4π` everywhere, the start and a fixed point of the sweeps: the white furnace holds
//!   exactly, whatever the geometry. The sun's field, whose source lies near the faces it
//!   leaves by, crosses the half cell toward an open face by that half cell's own 1D diffusion
//!   problem instead (`vdbcook_scene::ms_vacuum_face`, `Level::face`: Marshak at the face, the
//!   source exponential in depth from this cell's and the next inward cell's): the plain face
//!   treated a thick cell's sunlit skin as half a cell deep and let out too little of its light
//!   (a uniform half-space's fourth-and-up orders 1.21 / 1.54 / 1.79 at 1 / 2 / 4 mean free paths
//!   a cell; now 1.07 / 1.23 / 1.24, docs/rendering.md).
//! - **solver**: the grid is coarsened by 2 (means of 8 cells, missing ones empty) until no
//!   side exceeds [`MS_COARSEST`] cells; from the coarsest (starting at `φ_out`) each level runs
//!   [`MS_ITERATIONS`] Jacobi sweeps ([`MS_FINE_SWEEPS`] on the light volume's own cells; the
//!   limiter from the sweep's input) and hands its `φ` to the next finer level as its start
//!   (each cell its parent's value). Thin clouds need the
//!   coarse levels: a sweep moves light one cell, and 16 sweeps of a 64-cell grid alone leave
//!   a thin stormscape frame at half its converged brightness.
//! - **flux**: after the last sweep, the net flux `J` at each cell centre, per axis the mean of
//!   its two faces' `(φᵢ − φⱼ)/R`, kept as the GPU keeps it: per axis `J/φ` rounded to 16
//!   bits over ±8 (`vdbcook_scene::ms_stored_flux`, a step of 2.4·10⁻⁴·φ), so a light volume
//!   holds 24 bytes a cell (φ of both fields and the density in f32, six 16-bit fluxes).
//!
//! The march reads both fields density-weighted trilinear (`Σ wρφ / Σ wρ`: empty cells, which
//! hold `φ_out`, do not bleed into a sample next to them) as first-order (P1) radiance: the light
//! scattered toward the eye, `ω` the direction from the sample to it, is
//! `φ/4π + 3ḡ·J·ω/4π` (`LightVolume::diffuse_at`), `φ` and `J` of the sun's field the solve's
//! plus the gathered orders'. The sun's is added to its single scattering
//! `p(μ)·e^{−σ·τ_sun}`; the sky's is the sky's whole source.

#[cfg(feature = "parallel")]
use rayon::prelude::*;
use vdbcook_scene::{
    ms_beam_norm, ms_gather_steps, ms_levels, ms_stored_flux, ms_sweeps, LightGrid,
    MS_GATHER_MIN_TRANS, MS_SHARED_PATHS,
};
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
    /// The part of `q` scattered out of a beam, for the gather's second order (0 before it):
    /// `[s·ĵ, A, B]` per cell, the source `A = b·q` of the once-scattered light's beam-like share
    /// `b = min(|J₁|/φ₁, 1)` arriving along `ĵ = J₁/|J₁|`, and `B = A/N(ĵ)`
    /// (`vdbcook_scene::ms_beam_norm`); the emission toward `ω` is `(q − A + B·4π·p(ĵ·ω))/4π`
    /// (the rest, `q − A`, isotropic). Coarser levels hold the means.
    beam: Vec<[f64; 5]>,
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
            beam: vec![[0.0; 5]; n],
        };
        for z in 0..d[2] {
            for y in 0..d[1] {
                for x in 0..d[0] {
                    let i = x + d[0] * (y + d[1] * z);
                    let j = x / 2 + cd[0] * (y / 2 + cd[1] * (z / 2));
                    out.st[j] += self.st[i] / 8.0;
                    out.sr[j] += self.sr[i] / 8.0;
                    out.q[j] += self.q[i] / 8.0;
                    for (o, v) in out.beam[j].iter_mut().zip(&self.beam[i]) {
                        *o += v / 8.0;
                    }
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

    /// Cell `i`'s (at `c`) face along axis `a` (`up`: +1) for field `f`: its resistance `R`
    /// and the far side's `φ_j` (the face passes `(φᵢ − φ_j)/(h·R)` per unit volume), from the
    /// half-cell resistances `half` and the sweep's `phi`. Toward an empty cell or the level's
    /// edge, Marshak's vacuum boundary: the sky's field as a plain resistance 2 toward its
    /// boundary value, the sun's through the half cell's own diffusion problem
    /// (`vdbcook_scene::ms_vacuum_face`: the source toward the face leaves from nearer it).
    #[allow(clippy::too_many_arguments)]
    fn face(
        &self,
        i: usize,
        c: [usize; 3],
        a: usize,
        up: bool,
        f: usize,
        half: &[[[f64; 3]; FIELDS]],
        phi: &[Phi],
        albedo: f64,
    ) -> (f64, f64) {
        let hi = half[i][f][a];
        if let Some(j) = self.step(i, c, a, up).filter(|&j| self.st[j] > 0.0) {
            return (hi + half[j][f][a], phi[j][f]);
        }
        if f != 0 {
            return (hi + MS_VACUUM, BOUNDARY[f]);
        }
        let h = self.h[a];
        let inward = self.step(i, c, a, !up).filter(|&j| self.st[j] > 0.0);
        vdbcook_scene::ms_vacuum_face(
            h,
            self.st[i],
            self.sr[i],
            albedo,
            self.q[i],
            inward.map(|j| self.q[j]),
            hi - 1.5 * h * self.sr[i],
        )
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

/// The sun's and the sky's scattered light per cell of `grid`, from the cells' mean densities,
/// their transport densities (`vdbcook_scene::transport_density`: the faces' resistances) and
/// the sun's depth where its beam enters them (`sun_entry(i)`, in length units before the
/// extinction: from where the ray from the cell's centre toward the sun leaves the cell,
/// `LightGrid::centre_exit`).
pub fn solve(
    grid: &LightGrid,
    density: &[f32],
    transport: &[f32],
    sun_entry: impl Fn(usize) -> f64,
    m: &DiffusionInputs,
) -> Diffusion {
    let n = grid.cells();
    let st: Vec<f64> = density
        .iter()
        .map(|&d| m.extinction * d.max(0.0) as f64)
        .collect();
    let sr = st
        .iter()
        .zip(transport)
        .map(|(&t, &d)| {
            let moves = if t > 0.0 {
                m.extinction * d.max(0.0) as f64
            } else {
                0.0
            };
            moves * (1.0 - m.mean_cos() * m.albedo)
        })
        .collect();
    let q = (0..n)
        .map(|i| {
            let x = st[i] * m.chord;
            m.albedo * (-m.extinction * sun_entry(i)).exp() * -(-x).exp_m1() / m.chord
        })
        .collect();
    let dims = ms_levels(grid.dims);
    let fine = Level {
        dims: dims[0].map(|d| d as usize),
        h: m.h,
        st,
        sr,
        q,
        beam: vec![[0.0; 5]; n],
    };
    let mut levels = vec![fine];
    for d in &dims[1..] {
        let c = levels[levels.len() - 1].coarser();
        debug_assert_eq!(c.dims, d.map(|v| v as usize));
        levels.push(c);
    }
    // The light scattered once and twice gathered (`gather`, `m.orders` of them); the solve
    // carries the rest, from the last gathered order's light scattering again.
    let cells = levels[0].cells();
    let mut gathered = vec![[0.0f64; 4]; cells];
    let shares = ms_gather_steps(m.h).map(|s| s.share);
    let orders = m.gathered_orders();
    for order in 0..orders {
        let got = if order == 0 {
            gather(&levels, &m.gather, None)
        } else {
            gather(&levels, &shares, Some(m.phase))
        };
        let f = &mut levels[0];
        for i in 0..cells {
            let q = m.albedo * f.st[i] * got[i][0];
            f.q[i] = q;
            // The beams of the light just gathered, where a next order will gather them.
            let j = [got[i][1], got[i][2], got[i][3]];
            let jn = (j[0] * j[0] + j[1] * j[1] + j[2] * j[2]).sqrt();
            f.beam[i] = if order + 1 < orders && q > 0.0 && jn > 0.0 {
                let a = q * (jn / got[i][0]).min(1.0);
                let dir = j.map(|v| v / jn);
                let norm = ms_beam_norm(m.h, dir, m.phase);
                [dir[0] * a, dir[1] * a, dir[2] * a, a, a / norm]
            } else {
                [0.0; 5]
            };
            for (s, v) in gathered[i].iter_mut().zip(&got[i]) {
                *s += v;
            }
        }
        coarsen_sources(&mut levels);
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
    let mut flux = flux(&levels[0], &phi, m.albedo);
    for ((p, j), o) in phi.iter_mut().zip(&mut flux).zip(&gathered) {
        p[0] += o[0];
        for a in 0..3 {
            j[0][a] += o[1 + a];
        }
    }
    let phi: Vec<[f32; 2]> = phi.iter().map(|p| p.map(|v| (v * norm) as f32)).collect();
    // Stored as the GPU stores it: per axis, J/φ in 16 bits (`ms_stored_flux`).
    let flux = flux
        .into_iter()
        .zip(&phi)
        .map(|(j, p)| [0, 1].map(|f| j[f].map(|c| ms_stored_flux((c * norm) as f32, p[f]))))
        .collect();
    Diffusion { phi, flux }
}

/// The sun's once-scattered light per cell of level 0: `[φ₁, J₁]` (fluence and net flux, per
/// unit sun irradiance; 0 in empty cells), gathered along the 26 directions toward a cell's
/// neighbours (`vdbcook_scene::ms_gather_dirs`, weighted by `DiffusionInputs::gather`: each
/// direction's share of the sphere times the phase toward it). Along direction `e` (length
/// `L` per cell step) the light arriving at the cell is `q₀·L·own` from its own cell, then from
/// each step `s` of `n` cells `T_s·q_s(1 − e^{−σ_s·nL})/σ_s` (a constant source and extinction
/// per step, integrated exactly), `T_s` the transmittance to it (out of the own cell `T₀`; `own`
/// and `T₀` are means over the cell's points along the direction, `vdbcook_scene::ms_own_cell`:
/// the gather's value is the cell's mean fluence), until the grid ends; that light flows back
/// along `−e`. The steps widen with the distance, as the cone of directions `e` stands for (26
/// of them: a half-angle of about 23°) does: `m` cells past the own cell a step reads level
/// `k = ⌊log₂(m + 2)⌋ − 1` (at most the coarsest) and is `2^k` cells long — two steps of one
/// cell, two of two cells on level 1, two of four on level 2, … — reading the cell of its level that holds the step's middle (the
/// levels' means of extinction and source; integer arithmetic, so the GPU's `ms_gather_main`
/// reads the same cells), until `T` falls below `MS_GATHER_MIN_TRANS`.
///
/// From level [`MS_SHARED_PATHS`] on, cells share their paths: a path whose first step on that
/// level reads cell `F` goes on as the path that starts at `F`'s centre (`paths`, per cell of
/// each level from there up and direction, computed coarsest first: two steps, then the path of
/// the next level's cell `ms_next_cell`; on the coarsest, steps until the grid ends, with no
/// transmittance cut-off). Walking each cell's path alone (until 2026-11-27) made the build take
/// twice as long; sharing moves a distant step's cell by up to a quarter of it, which one cell
/// alone may see (a thin ball's cells read up to 8% more or less of its light, their mean as
/// close as before: `a_thin_ball_holds_the_once_scattered_fluence`), and the images moved by at
/// most 0.4% on real volumes (docs/rendering.md).
///
/// A uniform medium gathers `q/σ` exactly.
fn gather(levels: &[Level], weights: &[f64; 26], beam: Option<([f32; 2], f32)>) -> Vec<[f64; 4]> {
    let l = &levels[0];
    let steps = ms_gather_steps(l.h);
    let top = levels.len() - 1;
    // The source toward `−u` (per unit solid angle, times 4π): with `beam`'s phase, its
    // beam-like part by the phase (`Level::beam`).
    let emit = |q: f64, b: &[f64; 5], u: [f64; 3]| match beam {
        Some((g, w)) if b[3] > 0.0 => {
            let n = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
            if !(n > 0.0) {
                return q;
            }
            let mu = (-(0..3).map(|a| b[a] * u[a]).sum::<f64>() / n).clamp(-1.0, 1.0);
            q - b[3] + b[4] * 4.0 * std::f64::consts::PI * vdbcook_scene::phase(g, w, mu)
        }
        _ => q,
    };
    // Cell `j` of level `k` as one step along direction `d`: the light it sends to the path's
    // start (before the transmittance to it) and its transmittance.
    let step = |k: usize, j: usize, d: usize| {
        let lk = &levels[k];
        let st = lk.st[j];
        if st > 0.0 {
            let s = &steps[d];
            let along = (1u64 << k) as f64 * s.len;
            let q = emit(lk.q[j], &lk.beam[j], s.unit);
            (q * -(-st * along).exp_m1() / st, (-st * along).exp())
        } else {
            (0.0, 1.0)
        }
    };
    let index = |k: usize, f: [i64; 3]| {
        let d = levels[k].dims;
        (0..3)
            .all(|a| f[a] >= 0 && (f[a] as usize) < d[a])
            .then(|| f[0] as usize + d[0] * (f[1] as usize + d[1] * f[2] as usize))
    };
    // `paths[k][j][d]`: the light gathered along direction `d` by a path whose steps on level
    // `k` start at its cell `j` (levels `MS_SHARED_PATHS` to the coarsest).
    let mut paths: Vec<Vec<[f64; 26]>> = vec![Vec::new(); levels.len()];
    // The light of the path along `d` from cell `f` of level `k` on (0 outside the level).
    let path = |paths: &[Vec<[f64; 26]>], k: usize, f: [i64; 3], d: usize| -> f64 {
        let Some(j) = index(k, f) else {
            return 0.0;
        };
        let e = steps[d].e;
        if k == top {
            let (mut sum, mut tr, mut at) = (0.0, 1.0, j);
            let mut f = f;
            loop {
                let (c, t) = step(k, at, d);
                sum += tr * c;
                tr *= t;
                f = [0, 1, 2].map(|a| f[a] + e[a] as i64);
                match index(k, f) {
                    Some(next) => at = next,
                    None => return sum,
                }
            }
        }
        let (c1, t1) = step(k, j, d);
        let Some(j2) = index(k, [0, 1, 2].map(|a| f[a] + e[a] as i64)) else {
            return c1;
        };
        let (c2, t2) = step(k, j2, d);
        let g = ms_next_cell(f, e);
        let rest = index(k + 1, g).map_or(0.0, |p| paths[k + 1][p][d]);
        c1 + t1 * (c2 + t2 * rest)
    };
    for k in (MS_SHARED_PATHS.min(levels.len())..levels.len()).rev() {
        let lk = &levels[k];
        let row = |j: usize| -> [f64; 26] {
            let c = lk.coord(j).map(|v| v as i64);
            std::array::from_fn(|d| path(&paths, k, c, d))
        };
        #[cfg(feature = "parallel")]
        let rows = (0..lk.cells()).into_par_iter().map(row).collect();
        #[cfg(not(feature = "parallel"))]
        let rows = (0..lk.cells()).map(row).collect();
        paths[k] = rows;
    }
    let cell = |i: usize| {
        let c = l.coord(i);
        let mut out = [0.0; 4];
        if l.st[i] <= 0.0 {
            return out;
        }
        let st = l.st[i];
        for (d, (s, &w)) in steps.iter().zip(weights).enumerate() {
            let (e, len, u) = (s.e, s.len, s.unit);
            let (own, mut tr) = vdbcook_scene::ms_own_cell(st * len);
            let mut r = emit(l.q[i], &l.beam[i], u) * own * len;
            // Whole cells walked past the own cell.
            let mut m = 0u64;
            'walk: loop {
                let k = ((m + 2).ilog2() as usize - 1).min(top);
                let n = 1u64 << k;
                let lk = &levels[k];
                let mut x = [0i64; 3];
                for a in 0..3 {
                    // Twice the step's middle, in level-0 cells: an integer.
                    let p2 = 2 * c[a] as i64 + 1 + e[a] as i64 * (2 * m + 1 + n) as i64;
                    if p2 < 0 || p2 as u64 / (2 * n) >= lk.dims[a] as u64 {
                        break 'walk;
                    }
                    x[a] = (p2 as u64 / (2 * n)) as i64;
                }
                let j = index(k, x).expect("inside");
                if k >= MS_SHARED_PATHS {
                    r += tr * paths[k][j][d];
                    break;
                }
                let (cj, t) = step(k, j, d);
                r += tr * cj;
                tr *= t;
                if tr < MS_GATHER_MIN_TRANS {
                    break;
                }
                m += n;
            }
            out[0] += w * r;
            for a in 0..3 {
                out[1 + a] -= w * r * u[a];
            }
        }
        out
    };
    #[cfg(feature = "parallel")]
    return (0..l.cells()).into_par_iter().map(cell).collect();
    #[cfg(not(feature = "parallel"))]
    (0..l.cells()).map(cell).collect()
}

/// Where a shared gather path whose two steps on a level start at its cell `f` goes on, moving
/// along `e`: the cell of the next coarser level holding the point `2½` cells past `f`'s centre
/// (where the middle of the next step lies when the path passes `f`'s centre), `⌊(2f + 1 +
/// 5e)/4⌋` per axis (may lie outside the level: the path ends).
fn ms_next_cell(f: [i64; 3], e: [i32; 3]) -> [i64; 3] {
    [0, 1, 2].map(|a| (2 * f[a] + 1 + 5 * e[a] as i64).div_euclid(4))
}

/// Each coarser level's sources (`q`, `beam`) again from level 0's (their means).
fn coarsen_sources(levels: &mut [Level]) {
    for k in 1..levels.len() {
        let c = levels[k - 1].coarser();
        levels[k].q = c.q;
        levels[k].beam = c.beam;
    }
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
                for (f, vf) in v.iter_mut().enumerate() {
                    let (mut diag, mut off) = (l.st[i] * (1.0 - albedo), 0.0);
                    for a in 0..3 {
                        for up in [false, true] {
                            let (r, pj) = l.face(i, c, a, up, f, &half, &phi, albedo);
                            let g = 1.0 / (l.h[a] * r);
                            diag += g;
                            off += g * pj;
                        }
                    }
                    let q = if f == 0 { l.q[i] } else { 0.0 };
                    *vf = (q + off) / diag;
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
/// of the fluxes through the cell's two faces along each axis, `(φᵢ − φⱼ)/R` with the
/// resistances of the final `phi` (as the last sweep would compute them).
fn flux(l: &Level, phi: &[Phi], albedo: f64) -> Vec<[[f64; 3]; FIELDS]> {
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
                            let (r, pj) = l.face(i, c, a, up, f, &half, phi, albedo);
                            // Along +a: out of the upper face, into the lower one; a face's
                            // flux is its fluence difference over its (optical) resistance.
                            let d = if up { phi[i][f] - pj } else { pj - phi[i][f] };
                            0.5 * d / r
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
            h: [1.0; 3],
            chord: 1.0,
            gather: vdbcook_scene::ms_gather_weights([1.0; 3], [0.0, 0.0, 1.0], ([0.0; 2], 1.0)),
            phase: ([0.0; 2], 1.0),
            orders: vdbcook_scene::MAX_MS_GATHER,
        };
        (vec![density; grid.cells()], inputs, grid)
    }

    /// `φ` (not `/4π`) at the centre cell.
    fn centre(side: u32, density: f32, albedo: f64) -> (f64, f64) {
        let (density, m, grid) = cube(side, density, albedo);
        let phi = solve(&grid, &density, &density, |_| 0.0, &m);
        let c = side / 2;
        let x = density[0] as f64;
        // The source of a cell entered at depth 0 (every cell's, with the sun's depth 0).
        let q = albedo * -(-x).exp_m1();
        (
            phi.phi[grid.index([c, c, c])][0] as f64 * 4.0 * std::f64::consts::PI,
            q,
        )
    }

    /// A thick slab (24 transport mean free paths deep and wide, albedo 0.94, isotropic) lit
    /// straight from above, in cells of 1, 2 and 4 mean free paths: the sun's scattered light
    /// absorbed in the middle column, `σ_a·∫φ dz` per unit irradiance, against the half-space's
    /// by discrete ordinates (`tools/lighting/halfspace1d.py`: 0.06 · 7.247 = 0.4348; its
    /// reflectance by order matches the path tracer's to three digits, docs/rendering.md). What
    /// a face lets out of a thick cell decides how much stays to be absorbed: with the plain
    /// vacuum face (`R = r + 2`, until 2026-11-28) the solve's cells held the light of their
    /// sunlit skins at their centres and absorbed 12% / 32% / 43% too much at 1 / 2 / 4 mean
    /// free paths a cell; through the half cell's diffusion problem (`Level::face`) 2.6% / 9.5%
    /// / 8.7%, and with the gather's own cell as a cell mean (`vdbcook_scene::ms_own_cell`) 1.8%
    /// / 7.4% / 10.7%: the rest the gathered orders' and diffusion's own.
    #[test]
    fn a_thick_slab_absorbs_alike_at_any_cell_width() {
        let want = 0.06 * 7.247;
        let mut got = Vec::new();
        for h in [1u32, 2, 4] {
            let (side, deep) = (24 / h, 24 / h);
            let grid = LightGrid {
                lo: [0.0; 3],
                cell: 1.0,
                dims: [side, side, deep],
            };
            let rho = h as f32;
            let m = DiffusionInputs {
                extinction: 1.0,
                albedo: 0.94,
                h: [1.0; 3],
                chord: 1.0,
                gather: vdbcook_scene::ms_gather_weights(
                    [1.0; 3],
                    [0.0, 0.0, 1.0],
                    ([0.0; 2], 1.0),
                ),
                phase: ([0.0; 2], 1.0),
                orders: vdbcook_scene::MAX_MS_GATHER,
            };
            let density = vec![rho; grid.cells()];
            let top = |i: usize| (deep - 1 - (i / (side * side) as usize) as u32) as f64;
            let d = solve(&grid, &density, &density, |i| rho as f64 * top(i), &m);
            let c = side / 2;
            let phi: f64 = (0..deep)
                .map(|z| d.phi[grid.index([c, c, z])][0] as f64 * 4.0 * std::f64::consts::PI)
                .sum();
            got.push(0.06 * rho as f64 * phi / want);
        }
        assert!(got.iter().all(|g| (0.95..1.12).contains(g)), "{got:?}");
    }

    /// Deep inside a thick medium light neither arrives nor leaves: the fluence balances the
    /// source against absorption, `σ(1 − α)·φ = q`.
    #[test]
    fn a_thick_uniform_medium_balances_source_and_absorption() {
        let (phi, q) = centre(40, 2.0, 0.9);
        let want = q / (2.0 * (1.0 - 0.9));
        assert!((phi / want - 1.0).abs() < 1e-3, "{phi} against {want}");
    }

    /// In an optically thin ball (radius 16 cells, 0.16 mean free paths) light scattered once
    /// mostly streams out: its fluence at a cell is `q·∫ e^{−σr} dV/(4πr²)` over the ball's cells
    /// (a sum over 4³ points per cell within 3 cells of it, 2³ further), which the gather must
    /// give where little is scattered again (albedo 0.01), here at every third cell of the ball
    /// in each axis (619 cells: the distant steps' coarse cells make one cell alone miss by up to
    /// 8%). Measured: a mean of 0.994 and an RMS deviation of 0.047 with the shared paths (the
    /// same with the own cell as a mean over it, 2026-11-28: second order in a cell this thin);
    /// 0.988 and 0.044 when each cell walked its own path (until 2026-11-27); before the gather the
    /// diffusion solve carried this light too and gave 0.59 of it in a thin cube. At albedo 0.9
    /// the light scattered more than once adds to it, a little in a ball this thin (about
    /// `α·σ·R` more, 0.14 at most; measured 1.100).
    #[test]
    fn a_thin_ball_holds_the_once_scattered_fluence() {
        let side = 33u32;
        let c = 16.5f64;
        let sigma = 0.01f64;
        let inside = |i: [u32; 3]| {
            let r2: f64 = (0..3).map(|a| (i[a] as f64 + 0.5 - c).powi(2)).sum();
            r2 <= 16.0 * 16.0
        };
        let grid = LightGrid {
            lo: [0.0; 3],
            cell: 1.0,
            dims: [side; 3],
        };
        let mut density = vec![0.0f32; grid.cells()];
        let mut ball = Vec::new();
        for i in 0..grid.cells() {
            let v = [
                i as u32 % side,
                (i as u32 / side) % side,
                i as u32 / (side * side),
            ];
            if inside(v) {
                density[grid.index(v)] = sigma as f32;
                ball.push(v);
            }
        }
        // The once-scattered fluence at cell `t` per unit source.
        let exact = |t: [u32; 3]| {
            let mut sum = 0.0;
            for v in &ball {
                let near = (0..3).all(|a| v[a].abs_diff(t[a]) <= 3);
                let k = if near { 4 } else { 2 };
                let dv = 1.0 / (k * k * k) as f64;
                for s in 0..k * k * k {
                    let o = [s % k, (s / k) % k, s / (k * k)];
                    let r2: f64 = (0..3)
                        .map(|a| v[a] as f64 + (o[a] as f64 + 0.5) / k as f64 - t[a] as f64 - 0.5)
                        .map(|d| d * d)
                        .sum();
                    sum += dv * (-sigma * r2.sqrt()).exp() / (4.0 * std::f64::consts::PI * r2);
                }
            }
            sum
        };
        let targets: Vec<[u32; 3]> = ball
            .iter()
            .copied()
            .filter(|v| v.iter().all(|&x| x % 3 == 1))
            .collect();
        let truth: Vec<f64> = targets.iter().map(|&t| exact(t)).collect();
        for (albedo, range, spread) in [(0.01, 0.98..1.03, 0.06), (0.9, 1.02..1.16, 0.08)] {
            let (_, m, _) = cube(side, 0.0, albedo);
            let out = solve(&grid, &density, &density, |_| 0.0, &m);
            let q = albedo * -(-sigma).exp_m1();
            let ratios: Vec<f64> = targets
                .iter()
                .zip(&truth)
                .map(|(&t, &x)| {
                    out.phi[grid.index(t)][0] as f64 * 4.0 * std::f64::consts::PI / (q * x)
                })
                .collect();
            let n = ratios.len() as f64;
            let mean = ratios.iter().sum::<f64>() / n;
            let rms = (ratios.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / n).sqrt();
            eprintln!("albedo {albedo}: {n} cells, mean ratio {mean:.4}, RMS deviation {rms:.4}");
            assert!(
                range.contains(&mean) && rms < spread,
                "albedo {albedo}: mean ratio {mean} (RMS deviation {rms}) over {n} cells"
            );
        }
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
        let out = solve(&grid, &density, &density, |_| 0.0, &m);
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
        let out = solve(&grid, &density, &density, |_| 0.0, &m);
        let c = grid.index([6, 6, 6]);
        assert!(out.phi[c][1] < 0.1, "sky at the centre {}", out.phi[c][1]);
    }

    /// The sky's light entering a thick absorbing medium through a face decays as diffusion
    /// theory says: with the flux limiter (`D = 1/(3σ_tr + κ)`) the fluence falls as `e^{−κz}`,
    /// `κ = (σ_a + √(σ_a² + 12σ_a·σ_tr))/2` (0.6 per cell for σ = 1 per cell, albedo 0.9,
    /// isotropic), and the flux flows inward at `J = D·κ·φ`, whatever length a cell is (here 1
    /// and 2.5 units, the extinction per unit scaled to match: the flux is a length over a
    /// length; until 2026-11-27 it came out divided by the cell's edge). Measured along the
    /// central axis from the −z face, where the other faces are 20 cells away.
    #[test]
    fn the_sky_fades_into_a_thick_medium_as_diffusion_theory_says() {
        for h in [1.0f64, 2.5] {
            let (density, mut m, grid) = cube(40, 1.0, 0.9);
            m.extinction = 1.0 / h;
            m.h = [h; 3];
            let out = solve(&grid, &density, &density, |_| 0.0, &m);
            let (sa, st) = (0.1f64, 1.0f64);
            let kappa = (sa + (sa * sa + 12.0 * sa * st).sqrt()) / 2.0;
            let at = |z: u32| out.phi[grid.index([20, 20, z])][1] as f64;
            let rate = (at(2) / at(6)).ln() / 4.0;
            assert!(
                (rate / kappa - 1.0).abs() < 0.05,
                "h {h}: decay {rate} per cell, theory {kappa}"
            );
            let i = grid.index([20, 20, 4]);
            let j_over_phi = out.flux[i][1][2] as f64 / out.phi[i][1] as f64;
            let want = kappa / (3.0 * st + kappa);
            assert!(
                (j_over_phi / want - 1.0).abs() < 0.05,
                "h {h}: J/φ {j_over_phi}, theory {want}"
            );
        }
    }
}
