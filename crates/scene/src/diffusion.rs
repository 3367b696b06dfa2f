//! The constants and inputs of `Lit`'s diffusion model of multiple scattering
//! (`MsModel::Diffusion`), defined once for the CPU solver (`vdbcook_trace::diffusion`, whose
//! module docs state the method) and the GPU passes (`shaders/light_build.wgsl`'s `ms_*`).

use crate::{light_dirs, Affine, LightGrid, RenderSettings};

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
/// boundary: the net flux out is half the fluence).
pub const MS_VACUUM: f64 = 2.0;

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

/// The medium and the sun as the solve sees them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiffusionInputs {
    /// Extinction per unit density per unit length.
    pub extinction: f64,
    pub albedo: f64,
    /// The phase's mean cosine `ḡ`.
    pub mean_cos: f64,
    /// Length (in the settings' unit) of one cell edge along each axis.
    pub h: [f64; 3],
    /// Length of the sun's ray across one cell slab along its major axis.
    pub chord: f64,
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
        )
    }

    /// The inputs over `grid` for the sun `(l, len)` and axis lengths of
    /// [`crate::light_dirs`], `extinction` per unit density per length, `albedo` and the
    /// dual-lobe phase `(g, w)`.
    pub fn new(
        grid: &LightGrid,
        ((l, sun_len), axis_len): (([f64; 3], f64), [f64; 3]),
        extinction: f64,
        albedo: f64,
        (g, w): ([f32; 2], f32),
    ) -> DiffusionInputs {
        let m = (0..3)
            .max_by(|&a, &b| l[a].abs().total_cmp(&l[b].abs()))
            .unwrap_or(0);
        let w = w as f64;
        DiffusionInputs {
            extinction,
            albedo,
            mean_cos: w * g[0] as f64 + (1.0 - w) * g[1] as f64,
            h: axis_len.map(|a| a * grid.cell),
            chord: grid.cell / l[m].abs() * sun_len,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
