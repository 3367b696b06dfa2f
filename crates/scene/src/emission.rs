//! Emission of hot media: the blackbody colour of a temperature (Planck's law through the CIE
//! 1931 observer to linear sRGB) and the emitted radiance of a voxel value, whose range maps to
//! a Kelvin range (a Kelvin grid's own values, or a simulation's units by `crate::fire`). The
//! CPU tracer and the GPU runtime both evaluate emission from the same table
//! ([`blackbody_table`], uploaded as is), so their images agree to f32 rounding.
//!
//! The CIE 1931 2° colour-matching functions are the multi-lobe Gaussian fit of Wyman, Sloan
//! and Shirley (JCGT 2013), accurate to a few 10⁻³ in chromaticity; the XYZ → linear sRGB (D65)
//! matrix is IEC 61966-2-1's.

/// Entries of the blackbody table over `[lo, hi]` Kelvin.
pub const BLACKBODY_TABLE_LEN: usize = 32;

/// Emission settings: the emitting channel's value `v` (in the channel's own units: Kelvin, or a
/// simulation's temperature, heat or flame) glows above `range[0]`: the radiance is `intensity ·
/// s⁴ · rgb(K)`, `s = min((v − lo)/(hi − lo), 1)`, `rgb(K)` the blackbody colour (luminance 1)
/// at `K = kelvin[0] + s·(kelvin[1] − kelvin[0])`. A Kelvin grid has `kelvin == range`; the
/// conventions of simulation tools (`crate::fire`) map their units onto a Kelvin range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Emission {
    /// The channel's values over which the glow rises (nothing at or below `range[0]`).
    pub range: [f32; 2],
    /// The blackbody temperatures that range spans (the colour at `range[0]` and `range[1]`).
    pub kelvin: [f32; 2],
    pub intensity: f32,
    /// The channel whose values are the temperature: 0, the rendered grid itself (its values
    /// absorb and emit), or a later channel of a multi-channel asset (fire: `density` absorbs,
    /// `temperature` emits), drawn in every shaded mode.
    pub channel: usize,
}

/// Half-Gaussian with separate widths below and above the mean (the Wyman et al. lobes).
fn lobe(l: f64, mu: f64, s1: f64, s2: f64) -> f64 {
    let t = (l - mu) / if l < mu { s1 } else { s2 };
    (-0.5 * t * t).exp()
}

/// CIE 1931 2° colour-matching functions at wavelength `l` nm.
fn cmf(l: f64) -> [f64; 3] {
    [
        1.056 * lobe(l, 599.8, 37.9, 31.0) + 0.362 * lobe(l, 442.0, 16.0, 26.7)
            - 0.065 * lobe(l, 501.1, 20.4, 26.2),
        0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1),
        1.217 * lobe(l, 437.0, 11.8, 36.0) + 0.681 * lobe(l, 459.0, 26.0, 13.8),
    ]
}

/// CIE XYZ of a blackbody at `kelvin` (relative: Planck's law integrated over 360–830 nm in
/// 1 nm steps).
pub fn blackbody_xyz(kelvin: f64) -> [f64; 3] {
    const C2: f64 = 1.438_776_9e7; // second radiation constant, nm·K
    let mut xyz = [0.0; 3];
    for i in 0..=470 {
        let l = 360.0 + i as f64;
        let b = l.powi(-5) / (C2 / (l * kelvin)).exp_m1();
        let c = cmf(l);
        for a in 0..3 {
            xyz[a] += b * c[a];
        }
    }
    xyz
}

/// Coolest temperature given its own colour: below it, Planck's law underflows in f64 over the
/// visible range (and such a body does not glow visibly anyway); cooler values take its colour.
pub const MIN_COLOUR_KELVIN: f64 = 400.0;

/// Linear sRGB (D65) of a blackbody at `kelvin` (at least [`MIN_COLOUR_KELVIN`]), scaled to
/// luminance `Y = 1`, negative components (outside the sRGB gamut) clamped to 0.
pub fn blackbody_rgb(kelvin: f64) -> [f64; 3] {
    let [x, y, z] = blackbody_xyz(kelvin.max(MIN_COLOUR_KELVIN));
    let (x, z) = (x / y, z / y);
    [
        3.2406 * x - 1.5372 - 0.4986 * z,
        -0.9689 * x + 1.8758 + 0.0415 * z,
        0.0557 * x - 0.2040 + 1.0570 * z,
    ]
    .map(|c| c.max(0.0))
}

/// The blackbody colours at `BLACKBODY_TABLE_LEN` temperatures evenly spaced over `[lo, hi]` Kelvin
/// (rgb, and 0 in the fourth component: the GPU's vec4 layout).
pub fn blackbody_table(range: [f32; 2]) -> [[f32; 4]; BLACKBODY_TABLE_LEN] {
    let (lo, hi) = (range[0] as f64, range[1] as f64);
    std::array::from_fn(|i| {
        let t = lo + (hi - lo) * i as f64 / (BLACKBODY_TABLE_LEN - 1) as f64;
        let c = blackbody_rgb(t);
        [c[0] as f32, c[1] as f32, c[2] as f32, 0.0]
    })
}

impl Emission {
    /// A grid of Kelvin: the colour is the value's own temperature.
    pub fn of_kelvin(range: [f32; 2], intensity: f32, channel: usize) -> Emission {
        Emission {
            range,
            kelvin: range,
            intensity,
            channel,
        }
    }

    /// The blackbody colours across [`Emission::kelvin`] (what both tracers interpolate).
    pub fn table(&self) -> [[f32; 4]; BLACKBODY_TABLE_LEN] {
        blackbody_table(self.kelvin)
    }

    /// The radiance emitted per unit length by value `v`, from this emission's
    /// [`Emission::table`]: the definition both tracers follow, in f32.
    pub fn radiance(&self, table: &[[f32; 4]; BLACKBODY_TABLE_LEN], v: f32) -> [f32; 3] {
        let [lo, hi] = self.range;
        if !(v > lo) {
            return [0.0; 3];
        }
        let s = ((v - lo) / (hi - lo)).min(1.0);
        let x = s * (BLACKBODY_TABLE_LEN - 1) as f32;
        let i = (x as usize).min(BLACKBODY_TABLE_LEN - 2);
        let f = x - i as f32;
        let b = self.intensity * s * s * s * s;
        [0, 1, 2].map(|c| b * (table[i][c] + f * (table[i + 1][c] - table[i][c])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn xy(k: f64) -> (f64, f64) {
        let [x, y, z] = blackbody_xyz(k);
        (x / (x + y + z), y / (x + y + z))
    }

    /// Chromaticities of the Planckian locus: illuminant A (a 2856 K blackbody) is x 0.44757,
    /// y 0.40745 (CIE 15:2004); at 2000 K and 4000 K, Kim et al.'s published cubic fit of the
    /// locus (US patent 7024034; accurate to ~10⁻³ over 1667–25000 K) gives (0.5269, 0.4133)
    /// and (0.3805, 0.3768).
    #[test]
    fn planckian_locus_matches_published_chromaticities() {
        for (k, want) in [
            (2856.0, (0.44757, 0.40745)),
            (2000.0, (0.5269, 0.4133)),
            (4000.0, (0.3805, 0.3768)),
        ] {
            let got = xy(k);
            assert!(
                (got.0 - want.0).abs() < 3e-3 && (got.1 - want.1).abs() < 3e-3,
                "{k} K: xy {got:?}, published {want:?}"
            );
        }
    }

    /// Luminance 1, red at low temperatures, near white around 6500 K, bluer above.
    #[test]
    fn blackbody_colours_run_from_red_to_blue() {
        let lum = |c: [f64; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        let warm = blackbody_rgb(1500.0);
        assert!(warm[0] > warm[1] && warm[1] > warm[2], "{warm:?}");
        let white = blackbody_rgb(6500.0);
        assert!(white.iter().all(|c| (c - 1.0).abs() < 0.08), "{white:?}");
        let cool = blackbody_rgb(12000.0);
        assert!(cool[2] > cool[0], "{cool:?}");
        for k in [1000.0, 3000.0, 6500.0] {
            assert!((lum(blackbody_rgb(k)) - 1.0).abs() < 0.02, "{k} K");
        }
    }

    #[test]
    fn cold_and_absurd_temperatures_give_finite_colours() {
        for k in [0.0, 1.0, 399.0, 1e6, f64::MAX] {
            let c = blackbody_rgb(k);
            assert!(c.iter().all(|v| v.is_finite() && *v >= 0.0), "{k} K: {c:?}");
        }
        assert!(blackbody_table([0.0, 1.0])
            .iter()
            .flatten()
            .all(|v| v.is_finite()));
    }

    #[test]
    fn radiance_is_zero_at_lo_and_the_table_colour_at_hi() {
        let e = Emission {
            range: [800.0, 2000.0],
            kelvin: [800.0, 2000.0],
            intensity: 3.0,
            channel: 0,
        };
        let t = e.table();
        assert_eq!(e.radiance(&t, 800.0), [0.0; 3]);
        assert_eq!(e.radiance(&t, 100.0), [0.0; 3]);
        let hot = e.radiance(&t, 5000.0);
        for c in 0..3 {
            assert!((hot[c] - 3.0 * t[BLACKBODY_TABLE_LEN - 1][c]).abs() < 1e-6);
        }
        let mid = e.radiance(&t, 1400.0);
        assert!(
            mid[0] > 0.0 && mid[0] < hot[0] / 10.0,
            "s⁴ falloff: {mid:?}"
        );
    }
}
