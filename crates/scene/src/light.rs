//! The light volume's grid (mode `Lit`): where its cells lie, how a point is looked up in it,
//! and the octave weights of the multiple-scattering approximation. Defined once, here, so the
//! CPU tracer (`vdbcook-trace`'s `lit` module) and the GPU pass (`shaders/light.wgsl`) build
//! and read the same volume.
//!
//! Layout of a light volume over `dims` cells: cell `(x, y, z)` is element
//! `x + dims[0]·(y + dims[1]·z)`; cell `c` covers the cell-space box
//! `lo + c·cell .. lo + (c + 1)·cell` and its value sits at the centre. Lookups are trilinear
//! between centres and clamp to the outermost centres (the medium outside the content box is
//! empty, so nothing is shaded there).

use crate::{length, normalize, Affine, LengthUnit};

/// The cell-space unit direction toward the light (world direction `light_dir` under `xf`) and
/// the length, in `unit`, of one cell-space unit along it; and that length along each axis.
/// What the light volume's sun and sky passes step by, on the CPU and the GPU alike.
pub fn light_dirs(
    xf: &Affine,
    light_dir: [f32; 3],
    unit: LengthUnit,
) -> (([f64; 3], f64), [f64; 3]) {
    let voxel = unit == LengthUnit::Voxel;
    let l = xf.dir_to_index(normalize(light_dir.map(|c| c as f64)));
    let n = length(l);
    let sun = (l.map(|c| c / n), if voxel { 1.0 } else { 1.0 / n });
    let axis = [0, 1, 2].map(|a| {
        if voxel {
            1.0
        } else {
            length([xf.a[0][a], xf.a[1][a], xf.a[2][a]])
        }
    });
    (sun, axis)
}

/// `HG(g, μ)`.
fn hg(g: f64, mu: f64) -> f64 {
    let d = 1.0 + g * g - 2.0 * g * mu;
    (1.0 - g * g) / (4.0 * std::f64::consts::PI * d * d.sqrt())
}

/// The settings' dual-lobe Henyey–Greenstein phase (per steradian) at scattering cosine `mu`.
pub fn phase(g: [f32; 2], w: f32, mu: f64) -> f64 {
    let w = w as f64;
    w * hg(g[0] as f64, mu) + (1.0 - w) * hg(g[1] as f64, mu)
}

/// The mean cosine `ḡ` of the dual-lobe phase `(g, w)`: `w·g₀ + (1 − w)·g₁`.
pub fn phase_mean_cos(g: [f32; 2], w: f32) -> f64 {
    let w = w as f64;
    w * g[0] as f64 + (1.0 - w) * g[1] as f64
}

/// Optical depth of one light-volume cell below which `Lit` reads the sun's depth from the
/// light volume alone (`RenderSettings::sun_near`; `vdbcook_trace::Tracer::sun_depth`, the
/// GPU's `lit_walks`): a medium that thin changes its depth little across a cell. The same
/// for cells of any width: the depth interpolated between cell centres errs within half a cell
/// of a face where the density jumps, which is what the eye sees of a medium optically thick
/// per cell, however narrow the cell (and under the trilinear filter a sample in the skin reads
/// a fraction of the density inside). Until 2026-11-27 cells no wider than a voxel walked only
/// from an optical depth of 2: a dense 48³ cube under the default 64 cells (1.2 per cell) read
/// 0.40 of the reference's single scattering, 0.85 walked (docs/rendering.md, "Small dense
/// effects"); a threshold of 1 walked it with the nearest filter only.
pub const LIT_NEAR_DEPTH: f64 = 0.25;

/// The extinction at which the light volume's sun pass stops walking a cell's ray, once the
/// optical depth reaches the density mode's opaque depth (20: a transmittance of 2·10⁻⁹), or 0
/// for no stop: the diffusion model reads the depth only through `e^{−σ·τ}`; the octaves model
/// also through `e^{−bⁱ·σ·τ}`, whose `bⁱ` may be near 0 (`RenderSettings::ms`), so it walks
/// to the grid's far side.
pub fn sun_pass_stop(ms_model: crate::MsModel, extinction: f64) -> f64 {
    match ms_model {
        crate::MsModel::Diffusion => extinction,
        crate::MsModel::Octaves => 0.0,
    }
}

/// The primary ray's transmittance below which `Lit` reads the sun's depth from the light volume
/// alone (`RenderSettings::sun_near`): what lies deeper adds at most this share of the pixel's
/// light (measured: no change to the lit images' error against the reference at 0.05, +0.001 on
/// the WDAS cloud at 0.1), and a dense cloud's rays walk toward the sun from a few samples
/// instead of every one.
pub const LIT_NEAR_TRANS: f64 = 0.05;

/// Longest near field toward the sun, in voxels (`RenderSettings::sun_near` cells are cut to
/// it): the GPU's walk is one bounded loop (`vdb_optical_depth_near`, 4096 voxel steps, more
/// than any path this long crosses).
pub const LIT_NEAR_MAX_VOXELS: f64 = 1024.0;

/// The levels of detail an asset stores (`cook --lod`, `--lod-from`): how many (full resolution
/// included) and the chain level the first coarser one is. What the light volume's density pass
/// and the primary rays choose from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LevelChain {
    /// Levels stored, full resolution included (`Asset::level_count`, ≥ 1).
    pub count: usize,
    /// The chain level of stored level 1 (`Header::lod_first`, ≥ 1).
    pub first: u32,
}

impl LevelChain {
    /// Full resolution only.
    pub const NONE: LevelChain = LevelChain { count: 1, first: 1 };

    /// What `asset` stores.
    pub fn of(asset: &vdbcook_asset::Asset) -> LevelChain {
        LevelChain {
            count: asset.level_count(),
            first: asset.header.lod_first,
        }
    }

    /// Stored level `level`'s shift: its voxels are `2^shift` full-resolution voxels wide
    /// (`Header::level_shift`).
    pub fn shift(&self, level: usize) -> u32 {
        if level == 0 {
            0
        } else {
            self.first + level as u32 - 1
        }
    }

    /// The stored levels from full resolution on that leave no level out (all of them for a
    /// chain from level 1, full resolution alone for one from a coarser level): what primary
    /// rays by pixel footprint read (`vdbcook_scene::level_start`, one level per octave).
    pub fn consecutive(&self) -> usize {
        if self.first == 1 {
            self.count.max(1)
        } else {
            1
        }
    }
}

/// Where a light volume's cells lie (cell space: voxel `i` is `[i, i + 1)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightGrid {
    /// Corner of cell `(0, 0, 0)`.
    pub lo: [f64; 3],
    /// Cell edge in voxels (cubic cells).
    pub cell: f64,
    /// Cells per axis, each `1..=res`.
    pub dims: [u32; 3],
}

/// Most density sample points per cell axis (`LightGrid::density_level`).
pub const MAX_SUB: u32 = 4;

impl LightGrid {
    /// `res` cells along the longest side of `content` (a `[lo, hi)` cell-space box; `None`:
    /// one unit cell at the origin, as nothing is drawn).
    pub fn new(content: Option<([f64; 3], [f64; 3])>, res: u32) -> LightGrid {
        let Some((lo, hi)) = content.filter(|(lo, hi)| (0..3).all(|a| hi[a] > lo[a])) else {
            return LightGrid {
                lo: [0.0; 3],
                cell: 1.0,
                dims: [1; 3],
            };
        };
        let res = res.max(1);
        let side = [0, 1, 2].map(|a| hi[a] - lo[a]);
        let cell = side.iter().fold(0.0f64, |m, &s| m.max(s)) / res as f64;
        let dims = side.map(|s| ((s / cell).ceil() as u32).clamp(1, res));
        LightGrid { lo, cell, dims }
    }

    /// [`LightGrid::new`] for an asset with the levels of detail `chain` (`cook --lod`). Where
    /// cells are wider than [`MAX_SUB`] voxels and [`LightGrid::density_level`] picks a coarser
    /// level (`2^s` voxels wide), the grid snaps to that level's voxels: the corner down to a
    /// multiple of `2^s` voxels and the cell up to `m·2^s` (`m ≤ MAX_SUB`, computed for the
    /// content widened by one such voxel so the cells along the longest side stay `≤ res`):
    /// every cell is then exactly `m³` voxels of that level, each the box mean of `8^s`
    /// full-resolution voxels, and the density pass is the exact box filter of the cell in
    /// `m³ ≤ 64` reads (where [`LightGrid::new`]'s cells read one voxel in every
    /// `cell / MAX_SUB` per axis). Cells may come out up to 1.5× wider than `new`'s; the same as
    /// `new` without levels, with cells of at most `MAX_SUB` voxels, or where the only coarser
    /// level stored would widen them more (a chain from level `K > 1`).
    pub fn with_levels(
        content: Option<([f64; 3], [f64; 3])>,
        res: u32,
        chain: LevelChain,
    ) -> LightGrid {
        let g = LightGrid::new(content, res);
        let Some((lo, hi)) = content.filter(|(lo, hi)| (0..3).all(|a| hi[a] > lo[a])) else {
            return g;
        };
        let (k, s, _) = g.density_level(chain);
        if k == 0 {
            return g;
        }
        let span = f64::from(1u32 << s);
        let res = res.max(1);
        let side = (0..3).fold(0.0f64, |m, a| m.max(hi[a] - lo[a]));
        let wide = LightGrid {
            cell: (side + span) / res as f64,
            ..g
        };
        let (k, s, _) = wide.density_level(chain);
        if k == 0 {
            return g;
        }
        let span = f64::from(1u32 << s);
        let cell = (wide.cell / span).ceil() * span;
        let lo = lo.map(|v| (v / span).floor() * span);
        let dims = [0, 1, 2].map(|a| (((hi[a] - lo[a]) / cell).ceil() as u32).clamp(1, res));
        LightGrid { lo, cell, dims }
    }

    /// `Lit`'s near field toward the sun in voxels for `sun_near` cells (the CPU's
    /// `Tracer::sun_depth`, the renderer's and the drawer's walks), at most
    /// [`LIT_NEAR_MAX_VOXELS`]; cells narrower than a voxel walk less than one (a voxel dense
    /// enough to be optically thick within one cell still has its skin blurred between cell
    /// centres: [`LIT_NEAR_DEPTH`]).
    pub fn near_voxels(&self, sun_near: f32) -> f64 {
        (sun_near as f64 * self.cell).min(LIT_NEAR_MAX_VOXELS)
    }

    pub fn cells(&self) -> usize {
        self.dims.iter().map(|&d| d as usize).product()
    }

    /// The density pass on an asset with the levels `chain`: `(level, shift, sub)`, the stored
    /// level whose voxels (`2^shift` full-resolution voxels wide) are the finest that give a
    /// cell at most [`MAX_SUB`] of them per axis, and the sample points per cell axis there,
    /// `clamp(⌈cell / 2^shift⌉, 1, MAX_SUB)`. Each read of that level is a box mean over
    /// `8^shift` voxels, so a cell up to `MAX_SUB·2^shift` voxels wide is box-filtered exactly
    /// up to the cell's misalignment with the level's voxels, where full resolution alone reads
    /// one voxel in every `cell / MAX_SUB` (aliasing). Full resolution (`(0, 0, sub)`) without
    /// levels, and where the level found holds at most `MAX_SUB / 2` voxels per cell: only a
    /// chain that skips levels (`--lod-from`) gets there, and snapping to its voxels would widen
    /// the cells up to 2×.
    pub fn density_level(&self, chain: LevelChain) -> (usize, u32, u32) {
        let per = |s: u32| self.cell / f64::from(1u32 << s);
        let mut k = 0usize;
        while k + 1 < chain.count && per(chain.shift(k)) > MAX_SUB as f64 {
            k += 1;
        }
        if k > 0 && per(chain.shift(k)) <= f64::from(MAX_SUB / 2) {
            k = 0;
        }
        let s = chain.shift(k);
        let sub = (per(s).ceil() as u32).clamp(1, MAX_SUB);
        (k, s, sub)
    }

    /// The element of cell `c`.
    pub fn index(&self, c: [u32; 3]) -> usize {
        c[0] as usize
            + self.dims[0] as usize * (c[1] as usize + self.dims[1] as usize * c[2] as usize)
    }

    /// Centre of cell `c`.
    pub fn centre(&self, c: [u32; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| self.lo[a] + (c[a] as f64 + 0.5) * self.cell)
    }

    /// Along axis `a` at `p`: the two cells to interpolate between and the weight of the second
    /// (cell-centre coordinates clamped to the outermost centres; NaN reads the first cell).
    fn axis_lerp(&self, p: [f64; 3], a: usize) -> (u32, u32, f64) {
        let top = (self.dims[a] - 1) as f64;
        let u = ((p[a] - self.lo[a]) / self.cell - 0.5).clamp(0.0, top);
        let u = if u.is_nan() { 0.0 } else { u };
        let base = u.floor().min((top - 1.0).max(0.0));
        let i0 = base as u32;
        (i0, (i0 + 1).min(self.dims[a] - 1), u - base)
    }

    /// The eight elements and weights of the trilinear lookup at cell-space point `p`.
    pub fn taps(&self, p: [f64; 3]) -> [(usize, f64); 8] {
        let mut i0 = [0u32; 3];
        let mut i1 = [0u32; 3];
        let mut f = [0.0f64; 3];
        for a in 0..3 {
            (i0[a], i1[a], f[a]) = self.axis_lerp(p, a);
        }
        let mut out = [(0usize, 0.0f64); 8];
        for (k, o) in out.iter_mut().enumerate() {
            let pick = |a: usize| {
                if k >> a & 1 == 0 {
                    (i0[a], 1.0 - f[a])
                } else {
                    (i1[a], f[a])
                }
            };
            let (x, wx) = pick(0);
            let (y, wy) = pick(1);
            let (z, wz) = pick(2);
            *o = (self.index([x, y, z]), wx * wy * wz);
        }
        out
    }

    /// How far a ray along `d` (cell space) from a cell's centre runs before it leaves the
    /// cell: `min_a ½·cell/|d_a|`. The light volume's sun pass splits its walk there, so that
    /// the diffusion solve's source takes the sun's depth where the beam enters the cell
    /// (`vdbcook_trace::diffusion::solve`; the GPU's `lv_sun_main`).
    pub fn centre_exit(&self, d: [f64; 3]) -> f64 {
        d.iter()
            .filter(|c| **c != 0.0)
            .map(|c| 0.5 * self.cell / c.abs())
            .fold(f64::INFINITY, f64::min)
    }

    /// Distance along unit cell-space direction `d` from `p` (inside) to the grid's far side.
    pub fn exit(&self, p: [f64; 3], d: [f64; 3]) -> f64 {
        let mut t = f64::INFINITY;
        for a in 0..3 {
            let hi = self.lo[a] + self.dims[a] as f64 * self.cell;
            if d[a] > 0.0 {
                t = t.min((hi - p[a]) / d[a]);
            } else if d[a] < 0.0 {
                t = t.min((self.lo[a] - p[a]) / d[a]);
            }
        }
        t.max(0.0)
    }
}

/// `Lit`'s diffusion model where the near field toward the sun was walked: the once-scattered
/// sunlight below the light volume's cells, per unit sun irradiance,
/// `k·α/4π·(t − t_cells)` (`RenderSettings::near_scatter` `k`, albedo `α`, `t = e^{−x}` the
/// sun's transmittance over the walked optical depth `x`, `t_cells = e^{−x_cells}` over the
/// light volume's at the same point, both with the extinction; the lit march passes `t` as
/// its mean over a segment, `vdbcook_trace::lit::segment_sun`). The solve's source is each
/// cell's mean first scattering, so its light is the cell's; a point of a dense cloud's sunlit skin sees more of the beam than its
/// cell's mean (`x < x_cells`) and, as light scattered once within a mean free path of it
/// reaches it before scattering again, more once-scattered light, by the first flight's
/// fluence of the difference: `α·ΔT` per unit irradiance for a locally uniform source deep
/// inside, half that on a surface. 0 where no near field was walked (`x = x_cells`).
pub fn near_scatter_source(k: f64, albedo: f64, t: f64, t_cells: f64) -> f64 {
    k * albedo / (4.0 * std::f64::consts::PI) * (t - t_cells)
}

/// The multiple-scattering source of `Lit` for one light, relative to its single-scattering
/// term: octave 0 is single scattering, `phase[0]·e^{−x}`; octave `i ≥ 1` adds
/// `a^i·phase[i]·(e^{−b^i·x} − e^{−x})`, light the medium took out of the direct beam
/// (`1 − e^{−x}`) and brought back along a path whose extinction is scaled by `b^i`. At `x = 0`
/// only single scattering is left (a thin wisp is not brightened), and a thick core keeps the
/// light that octaves of reduced extinction bring in. `x` is the optical depth toward the
/// light (extinction included), `phase[i]` the phase of octave `i` (the sky's: 1).
pub fn octave_source(x: f64, ms: [f32; 3], octaves: u32, phase: impl Fn(u32) -> f64) -> f64 {
    let direct = (-x).exp();
    let mut s = phase(0) * direct;
    let (a, b) = (ms[0] as f64, ms[1] as f64);
    let (mut ai, mut bi) = (1.0f64, 1.0f64);
    for i in 1..octaves {
        ai *= a;
        bi *= b;
        s += ai * phase(i) * ((-bi * x).exp() - direct);
    }
    s
}

/// The sky's source in `Lit`, relative to the sky's radiance, at sky optical depth `y`
/// (extinction included): the light that reaches the point unscattered, `e^{−y}`, plus the part
/// taken out of it, `1 − e^{−y}`, brought back by multiple scattering with the attenuation
/// `e^{−k·y}` of diffusion, `k = scale·√(3(1 − α)(1 − ḡα))` (`α` the albedo, `ḡ` the phase's mean
/// cosine; [`sky_diffusion`]). At albedo 1, `k = 0` and the source is the sky itself: the
/// medium disappears against a uniform sky (white furnace) at any depth.
pub fn sky_source(y: f64, k: f64) -> f64 {
    let direct = (-y).exp();
    direct + (1.0 - direct) * (-k * y).exp()
}

/// `k` of [`sky_source`] for albedo `albedo`, the dual-lobe phase `(g, w)` (mean cosine
/// `w·g₀ + (1 − w)·g₁`) and the fitted `scale` (`RenderSettings::ms_sky`).
pub fn sky_diffusion(albedo: f64, g: [f32; 2], w: f32, scale: f32) -> f64 {
    let mean = w as f64 * g[0] as f64 + (1.0 - w as f64) * g[1] as f64;
    let d = 3.0 * (1.0 - albedo).max(0.0) * (1.0 - mean * albedo).max(0.0);
    scale as f64 * d.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(c: f64) -> LightGrid {
        LightGrid {
            lo: [0.0; 3],
            cell: c,
            dims: [4; 3],
        }
    }

    /// The level a cell reads: the finest with at most 4 of its voxels per cell axis; a chain
    /// that skips levels falls back to full resolution where its first level would hold 2 or
    /// fewer (snapping would widen the cells up to 2×).
    #[test]
    fn density_level_follows_the_stored_chain() {
        let all = LevelChain { count: 6, first: 1 };
        let from3 = LevelChain { count: 3, first: 3 };
        // cell, chain → (stored level, shift, reads per axis)
        for (c, chain, want) in [
            (3.0, all, (0, 0, 3)),
            (3.0, LevelChain::NONE, (0, 0, 3)),
            (9.5, all, (2, 2, 3)),
            (9.5, LevelChain::NONE, (0, 0, 4)),
            (38.0, all, (4, 4, 3)),
            // From level 3: 9.5 voxels are 1.2 level-3 voxels, so full resolution, point reads.
            (9.5, from3, (0, 0, 4)),
            (20.0, from3, (1, 3, 3)),
            (38.0, from3, (2, 4, 3)),
            // Past the top stored level: the top, with at most 4 reads.
            (500.0, from3, (2, 4, 4)),
        ] {
            assert_eq!(cell(c).density_level(chain), want, "cell {c}, {chain:?}");
        }
        assert_eq!(from3.consecutive(), 1);
        assert_eq!(all.consecutive(), 6);
        assert_eq!((from3.shift(0), from3.shift(1), from3.shift(2)), (0, 3, 4));
    }

    /// Snapped grids put every cell on whole voxels of the level read, and skipped levels never
    /// widen a cell by more than 1.5×. Content 157 voxels wide: cells of 39 to 2.5 voxels.
    #[test]
    fn grids_snap_to_the_level_they_read() {
        let content = Some(([3.0, 5.0, 7.0], [160.0, 100.0, 60.0]));
        for chain in [
            LevelChain { count: 5, first: 1 },
            LevelChain { count: 3, first: 2 },
            LevelChain { count: 2, first: 3 },
        ] {
            for res in [4u32, 8, 16, 32, 64] {
                let plain = LightGrid::new(content, res);
                let g = LightGrid::with_levels(content, res, chain);
                let (k, s, sub) = g.density_level(chain);
                assert!(g.cell <= 1.5 * plain.cell + 1e-9, "{chain:?} res {res}");
                assert!(g.dims.iter().all(|&d| d <= res));
                if k > 0 {
                    let span = f64::from(1u32 << s);
                    assert_eq!(g.cell % span, 0.0, "{chain:?} res {res}");
                    assert!(g.lo.iter().all(|v| v % span == 0.0));
                    // Whole voxels per cell, all read (past the top stored level: 4 of them).
                    assert_eq!(((g.cell / span) as u32).min(MAX_SUB), sub);
                } else {
                    assert_eq!(g, plain, "{chain:?} res {res}");
                }
            }
        }
    }
}
