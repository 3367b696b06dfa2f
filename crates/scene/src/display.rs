//! The colour pipeline from scene-referred radiance to what a screen shows: exposure (a power
//! of two), a tone map (Khronos PBR Neutral by default, the Narkowicz fit of ACES, or none: a
//! clamp), then the sRGB transfer curve. Every display output follows it — `render`'s PNG with
//! or without a plate, `view`'s window and screenshot — so one image has one brightness. PFM
//! and EXR stay linear (the radiance itself). The GPU's copy is `shaders/display.wgsl`; the
//! tests hold the two to each other and to the curves' published values.
//!
//! Only radiance goes through it: the density, scatter, delta, reference and lit modes. The
//! diagnostic modes (depth, first-hit, brick-hue, steps) write false colours, which are display
//! values already and are written as they are.

/// The tone map: how radiance above display white is brought into `[0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Tonemap {
    /// Khronos PBR Neutral (2024): an offset (at most 0.04, set by the darkest component) is
    /// taken from all three components; colours whose largest component is then under 0.76 (an
    /// input of about 0.8) pass as they are, brighter ones are compressed toward 1 along their
    /// hue and desaturated as they approach it. Keeps smoke's greys grey and fire's hues; the
    /// default.
    #[default]
    PbrNeutral,
    /// Narkowicz's 2015 fit of the ACES filmic curve (input scaled by 0.6, as the fit is
    /// published), per channel: more contrast, mid-grey 0.18 → 0.140, bright saturated
    /// colours run toward yellow and white.
    Aces,
    /// A clamp to `[0, 1]`: the linear values themselves (exact comparisons).
    None,
}

impl Tonemap {
    /// Names as the command line takes them.
    pub const NAMES: [&'static str; 3] = ["pbr-neutral", "aces", "none"];

    pub fn parse(s: &str) -> Option<Tonemap> {
        match s {
            "pbr-neutral" => Some(Tonemap::PbrNeutral),
            "aces" => Some(Tonemap::Aces),
            "none" => Some(Tonemap::None),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Tonemap::PbrNeutral => "pbr-neutral",
            Tonemap::Aces => "aces",
            Tonemap::None => "none",
        }
    }

    /// The shader's code for this curve (`display.wgsl`'s `display_map`).
    pub fn code(self) -> u32 {
        match self {
            Tonemap::None => 0,
            Tonemap::PbrNeutral => 1,
            Tonemap::Aces => 2,
        }
    }

    /// Maps linear radiance (already exposed) to display-linear values in `[0, 1]`: NaN and
    /// negatives read 0, +∞ and anything above [`DISPLAY_MAX`] read `DISPLAY_MAX` (white).
    pub fn apply(self, c: [f32; 3]) -> [f32; 3] {
        let c = c.map(clean);
        match self {
            Tonemap::None => c.map(|v| v.min(1.0)),
            Tonemap::Aces => c.map(|v| {
                let x = 0.6 * v;
                // Above 1, the same rational divided through by x² (no overflow toward +∞).
                let f = if x > 1.0 {
                    (2.51 + 0.03 / x) / (2.43 + 0.59 / x + 0.14 / (x * x))
                } else {
                    x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14)
                };
                f.clamp(0.0, 1.0)
            }),
            Tonemap::PbrNeutral => pbr_neutral(c),
        }
    }
}

/// The largest radiance the pipeline takes (above: white; an `Rgba16Float` image's overflow
/// to +∞ included).
pub const DISPLAY_MAX: f32 = 1.0e30;

/// NaN and negatives to 0, +∞ and beyond [`DISPLAY_MAX`] to it (the GPU's `display_map`).
fn clean(v: f32) -> f32 {
    if v >= 0.0 {
        v.min(DISPLAY_MAX)
    } else {
        0.0
    }
}

/// Where PBR Neutral's compression starts, after the offset (an input of about 0.8).
pub const PBR_NEUTRAL_START: f32 = 0.76;
/// PBR Neutral's desaturation speed.
pub const PBR_NEUTRAL_DESATURATION: f32 = 0.15;

/// The Khronos PBR Neutral tone map, written from its specification.
fn pbr_neutral(c: [f32; 3]) -> [f32; 3] {
    let x = c[0].min(c[1]).min(c[2]);
    let offset = if x < 0.08 { x - 6.25 * x * x } else { 0.04 };
    let c = c.map(|v| v - offset);
    let peak = c[0].max(c[1]).max(c[2]);
    if peak < PBR_NEUTRAL_START {
        return c;
    }
    let d = 1.0 - PBR_NEUTRAL_START;
    let new_peak = 1.0 - d * d / (peak + d - PBR_NEUTRAL_START);
    let c = c.map(|v| v * new_peak / peak);
    let g = 1.0 - 1.0 / (PBR_NEUTRAL_DESATURATION * (peak - new_peak) + 1.0);
    c.map(|v| (v + g * (new_peak - v)).clamp(0.0, 1.0))
}

/// Exposure and tone map: the part of the colour pipeline before the transfer curve.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Display {
    /// Exposure in stops: radiance is multiplied by `2^exposure_ev` first.
    pub exposure_ev: f32,
    pub tonemap: Tonemap,
}

impl Display {
    /// Exposure that is finite and within ±32 stops.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.exposure_ev.abs() <= 32.0) {
            return Err(format!(
                "exposure {} EV (finite, within ±32 stops)",
                self.exposure_ev
            ));
        }
        Ok(())
    }

    /// The factor radiance is multiplied by.
    pub fn scale(&self) -> f32 {
        self.exposure_ev.exp2()
    }

    /// Radiance to display-linear values in `[0, 1]` (before the transfer curve).
    pub fn map(&self, rgb: [f32; 3]) -> [f32; 3] {
        let s = self.scale();
        self.tonemap.apply(rgb.map(|v| clean(v) * s))
    }

    /// Radiance to 8-bit sRGB codes.
    pub fn encode8(&self, rgb: [f32; 3]) -> [u8; 3] {
        self.map(rgb).map(linear_to_srgb8)
    }
}

/// The sRGB transfer function, decoding: a value in `[0, 1]` to linear light.
pub fn srgb_decode(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB transfer function, encoding: linear light in `[0, 1]` (clamped; non-finite → 0) to a
/// value in `[0, 1]`.
pub fn srgb_encode(x: f32) -> f32 {
    if !x.is_finite() {
        return 0.0;
    }
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// An 8-bit sRGB code to linear light.
pub fn srgb_to_linear(c: u8) -> f32 {
    srgb_decode(c as f32 / 255.0)
}

/// Linear light (clamped to `[0, 1]`; non-finite → 0) to an 8-bit sRGB code.
pub fn linear_to_srgb8(x: f32) -> u8 {
    (srgb_encode(x) * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    /// IEC 61966-2-1: mid-grey 0.18 encodes to 0.4614 (code 118), linear 0.5 to 0.7354 (188);
    /// black and white are fixed; decoding inverts encoding on every 8-bit code.
    #[test]
    fn srgb_transfer_matches_the_standard() {
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert!((srgb_encode(0.18) - 0.4614).abs() < 1e-3);
        assert_eq!(linear_to_srgb8(0.18), 118);
        assert_eq!(linear_to_srgb8(0.5), 188);
        for c in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb_to_linear(c)), c);
        }
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
    }

    /// PBR Neutral as its specification states it: below the compression start a colour only
    /// loses the offset (0.04 once its darkest component reaches 0.08; mid-grey 0.18 → 0.14);
    /// the compression curve meets the identity at 0.76 with slope 1; white 1.0 lands at
    /// 1 − 0.24²/0.44 before desaturation (grey has none to lose); any brightness stays ≤ 1
    /// and keeps increasing; hue is kept (ratios of a dim colour unchanged after the offset).
    #[test]
    fn pbr_neutral_follows_its_specification() {
        let t = Tonemap::PbrNeutral;
        let g = t.apply([0.18; 3]);
        assert!(g.iter().all(|v| (v - 0.14).abs() < 1e-6), "{g:?}");
        assert_eq!(t.apply([0.0; 3]), [0.0; 3]);
        let w = t.apply([1.0; 3]);
        let want = 1.0 - 0.24f32 * 0.24 / 0.44;
        assert!(w.iter().all(|v| (v - want).abs() < 1e-5), "{w:?} vs {want}");
        // Continuity and slope 1 at the start of the compression (grey 0.8 → peak 0.76).
        let below = t.apply([0.8 - 1e-4; 3])[0];
        let above = t.apply([0.8 + 1e-4; 3])[0];
        assert!(((above - below) / 2e-4 - 1.0).abs() < 0.01);
        let mut last = 0.0;
        for k in 0..2000 {
            let v = t.apply([k as f32 * 0.05; 3])[0];
            assert!(v >= last && v <= 1.0, "{k}: {v}");
            last = v;
        }
        assert!(last > 0.99);
        let c = t.apply([0.5, 0.3, 0.1]);
        assert!((c[0] / c[1] - 0.46 / 0.26).abs() < 1e-5, "{c:?}");
    }

    /// Narkowicz's ACES fit at its published constants: f(0) = 0, mid-grey 0.18 (0.108 after
    /// the 0.6 pre-scale) → 0.1401, 1.0 (0.6) → 0.6733, saturating to 1.
    #[test]
    fn aces_fit_at_known_points() {
        let f = |x: f32| Tonemap::Aces.apply([x; 3])[0];
        assert_eq!(f(0.0), 0.0);
        let want = |x: f64| {
            let x = 0.6 * x;
            x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14)
        };
        assert!((f(0.18) as f64 - want(0.18)).abs() < 1e-6);
        assert!((f(0.18) - 0.1401).abs() < 5e-4, "{}", f(0.18));
        assert!((f(1.0) - 0.6733).abs() < 5e-4, "{}", f(1.0));
        assert!(f(1e4) > 0.999 && f(1e4) <= 1.0);
    }

    #[test]
    fn exposure_scales_by_powers_of_two_and_none_clamps() {
        let d = Display {
            exposure_ev: 1.0,
            tonemap: Tonemap::None,
        };
        assert_eq!(d.map([0.25, 0.5, 2.0]), [0.5, 1.0, 1.0]);
        assert_eq!(d.map([f32::NAN, -1.0, f32::INFINITY]), [0.0, 0.0, 1.0]);
        for t in [Tonemap::PbrNeutral, Tonemap::Aces] {
            let w = t.apply([f32::INFINITY, f32::MAX, 1e38]);
            assert!(w.iter().all(|v| *v > 0.99 && *v <= 1.0), "{t:?}: {w:?}");
        }
        assert!(Display {
            exposure_ev: f32::NAN,
            ..d
        }
        .validate()
        .is_err());
        for n in Tonemap::NAMES {
            assert_eq!(Tonemap::parse(n).unwrap().name(), n);
        }
    }
}
