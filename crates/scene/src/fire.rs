//! Fire by convention: which channel of an asset glows and how its values map to blackbody
//! light, read from the channel's name and its stored value range (the asset keeps each
//! channel's range per frame), so that a cooked fire glows without the user knowing its units.
//!
//! Simulation tools store heat in their own units, not Kelvin (measured on real caches, see
//! `docs/rendering.md`):
//! - **Kelvin grids** (renderer-oriented exports; some tools write Kelvin, unmeasured here): a
//!   temperature-named channel whose maximum exceeds [`KELVIN_MIN_MAX`]. It glows from
//!   [`DRAPER_KELVIN`] (where a body starts to glow visibly) to its maximum, coloured by its own
//!   temperature.
//! - **A flame channel** (`flame`, `flames`, `fire`: Blender/Mantaflow and Houdini pyro write
//!   it normalised to about 0..1): Blender's fire material drives the blackbody intensity with
//!   `flame` and the colour with `temperature` × 1000 K; the flame channel glows from 0 to its
//!   maximum, coloured from [`FLAME_KELVIN`]`[0]` to 1000 K × the temperature channel's
//!   maximum (or [`FLAME_KELVIN`]`[1]` without one).
//! - **Houdini's `heat`** (its pyro's burn field, 0..1) glows as a flame channel does when the
//!   file says Houdini wrote it (`creator`; Blender's old smoke writes a `heat` that is its
//!   buoyancy temperature).
//! - **Simulation temperature alone** (a `temperature` of a few units and no flame: the
//!   buoyancy of a smoke simulation, not fire) does not glow by default; named with
//!   `--emission-grid`, it glows above a quarter of its maximum at 1000 K per unit (Blender's
//!   convention), at least [`FLAME_KELVIN`]`[0]`.
//!
//! The intensity is chosen so that a flame whose hottest part spans about a sixth of the
//! frame's longest side reaches about radiance [`FIRE_RADIANCE`] through it (`FIRE_RADIANCE ·
//! FIRE_DEPTH / longest side`, per voxel of length): brighter than sunlit smoke (about 1), as
//! fire is, alike at any resolution; exposure corrects the rest. A flame channel reaches full
//! brightness at [`FLAME_FULL`] of its maximum (a flame's core is a few voxels: most of its
//! voxels sit well below the peak, and the s⁴ rise would leave them dark).

use vdbcook_asset::Asset;

use crate::emission::Emission;

/// The maximum above which a temperature channel is taken as Kelvin.
pub const KELVIN_MIN_MAX: f32 = 200.0;
/// Where a Kelvin grid starts to glow: the Draper point, ~798 K.
pub const DRAPER_KELVIN: f32 = 798.0;
/// The colour range of a normalised flame channel without a temperature channel (and the
/// coolest colour of any simulation-unit convention).
pub const FLAME_KELVIN: [f32; 2] = [1500.0, 2800.0];
/// Kelvin per simulation unit of temperature (Blender's Principled Volume: temperature
/// attribute × 1000 K).
pub const KELVIN_PER_UNIT: f32 = 1000.0;
/// The hottest part of a flame spans a `1/FIRE_DEPTH` of the frame's longest side...
pub const FIRE_DEPTH: f32 = 6.0;
/// ...and adds this radiance through it.
pub const FIRE_RADIANCE: f32 = 5.0;
/// The share of a flame channel's maximum at which it glows at full brightness.
pub const FLAME_FULL: f32 = 0.6;

/// Names of channels that burn (normalised flame).
pub const FLAME_NAMES: [&str; 3] = ["flame", "flames", "fire"];
/// Names of channels that hold heat (Kelvin or simulation units).
pub const HEAT_NAMES: [&str; 4] = ["temperature", "temp", "heat", "temperature_k"];

/// The convention an emission was chosen by.
#[derive(Debug, Clone, PartialEq)]
pub struct FireConvention {
    /// `kelvin`, `flame` or `simulation-temperature`.
    pub name: &'static str,
    /// The emission it gives (before any override of the user's).
    pub emission: Emission,
    /// One sentence on why (the channel, its range, the rule).
    pub why: String,
}

/// The largest stored value of channel `c` over every frame, and the frame that holds it.
pub fn channel_max(asset: &Asset, c: usize) -> (f32, usize) {
    (0..asset.frame_count())
        .map(|f| (asset.frame_range(f, c)[1], f))
        .filter(|(m, _)| m.is_finite())
        .fold((f32::NEG_INFINITY, 0), |a, b| if b.0 > a.0 { b } else { a })
}

/// The channel named one of `names` (case-insensitive), first name first.
pub fn channel_named(asset: &Asset, names: &[&str]) -> Option<usize> {
    names.iter().find_map(|n| {
        (0..asset.channel_count()).find(|&c| asset.header.channel_name(c).eq_ignore_ascii_case(n))
    })
}

/// The intensity that makes a flame of the given frame glow about [`FIRE_RADIANCE`] across a
/// [`FIRE_DEPTH`]th of its longest side (per voxel of length; a world-unit caller divides by
/// the voxel size).
pub fn fire_intensity(asset: &Asset, frame: usize) -> f32 {
    let side = crate::stored_bbox(asset, frame)
        .map(|(lo, hi)| (0..3).map(|a| hi[a] - lo[a]).fold(1.0, f64::max))
        .unwrap_or(1.0);
    (FIRE_RADIANCE as f64 * FIRE_DEPTH as f64 / side) as f32
}

/// The emission an asset's channels call for, or `None` when no channel is named as heat or
/// flame (or the one that is never rises above zero). `channel` restricts the choice to that
/// channel (`--emission-grid`).
pub fn fire_convention(asset: &Asset, channel: Option<usize>) -> Option<FireConvention> {
    let name = |c: usize| asset.header.channel_name(c).to_string();
    let is = |c: usize, names: &[&str]| names.iter().any(|n| name(c).eq_ignore_ascii_case(n));
    let heat = match channel {
        Some(c) => is(c, &HEAT_NAMES).then_some(c),
        None => channel_named(asset, &HEAT_NAMES),
    };
    // Houdini's `heat` burns (Blender's old smoke writes a `heat` that is its buoyancy
    // temperature; a file that does not say who wrote it gets no glow from `heat`).
    let houdini = asset
        .header
        .source
        .creator
        .to_ascii_lowercase()
        .contains("houdini");
    let burns = |c: usize| is(c, &FLAME_NAMES) || (houdini && is(c, &["heat"]));
    let flame = match channel {
        Some(c) => burns(c).then_some(c),
        None => channel_named(asset, &FLAME_NAMES)
            .or_else(|| houdini.then(|| channel_named(asset, &["heat"])).flatten()),
    };
    let heat = match (heat, flame) {
        // The burning channel is not also the heat that colours it.
        (Some(h), Some(f)) if h == f => channel_named(asset, &["temperature", "temp"]),
        (h, _) => h,
    };
    // A Kelvin channel first: its own temperatures say its colour.
    if let Some(h) = heat {
        let (max, f) = channel_max(asset, h);
        if max > KELVIN_MIN_MAX {
            let lo = if max > 1.25 * DRAPER_KELVIN {
                DRAPER_KELVIN
            } else {
                0.5 * max
            };
            return Some(FireConvention {
                name: "kelvin",
                emission: Emission::of_kelvin([lo, max], fire_intensity(asset, f), h),
                why: format!(
                    "channel {} reaches {max} (> {KELVIN_MIN_MAX}): Kelvin, glowing from {lo} K",
                    name(h)
                ),
            });
        }
    }
    if let Some(fl) = flame {
        let (max, f) = channel_max(asset, fl);
        if max > 0.0 {
            // The colour from the temperature channel, whichever channel was named to glow.
            let heat = channel_named(asset, &["temperature", "temp"]).filter(|&h| h != fl);
            let t_max = heat.map(|h| channel_max(asset, h).0).filter(|m| *m > 0.0);
            let hot = t_max.map_or(FLAME_KELVIN[1], |t| {
                (t * KELVIN_PER_UNIT).max(FLAME_KELVIN[0])
            });
            return Some(FireConvention {
                name: "flame",
                emission: Emission {
                    range: [0.0, FLAME_FULL * max],
                    kelvin: [FLAME_KELVIN[0], hot],
                    intensity: fire_intensity(asset, f),
                    channel: fl,
                },
                why: match t_max {
                    Some(t) => format!(
                        "channel {} (0..{max}) glows, fully from {FLAME_FULL} of its maximum; its \
                         colour runs to {} × {KELVIN_PER_UNIT} K = {hot} K (channel {}'s maximum, \
                         simulation units)",
                        name(fl),
                        t,
                        name(heat.unwrap_or(0))
                    ),
                    None => format!(
                        "channel {} (0..{max}) glows, fully from {FLAME_FULL} of its maximum, \
                         {FLAME_KELVIN:?} K",
                        name(fl)
                    ),
                },
            });
        }
    }
    // Simulation temperature without a flame is a smoke's buoyancy: it glows only when named.
    if let (Some(h), Some(_)) = (heat, channel) {
        let (max, f) = channel_max(asset, h);
        if max > 0.0 {
            let lo = 0.25 * max;
            let kelvin = [
                (lo * KELVIN_PER_UNIT).max(FLAME_KELVIN[0]),
                (max * KELVIN_PER_UNIT).max(FLAME_KELVIN[0]),
            ];
            return Some(FireConvention {
                name: "simulation-temperature",
                emission: Emission {
                    range: [lo, max],
                    kelvin,
                    intensity: fire_intensity(asset, f),
                    channel: h,
                },
                why: format!(
                    "channel {} reaches {max} (≤ {KELVIN_MIN_MAX}: simulation units), glowing \
                     above {lo}, {KELVIN_PER_UNIT} K per unit",
                    name(h)
                ),
            });
        }
    }
    None
}
