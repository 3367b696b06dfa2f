//! The look of a render, one definition for `render` and `view`: the medium, the lights, the
//! emission, the lit mode's knobs and the colour pipeline, as flags (`LookArgs`, flattened into
//! both commands) and as the `RenderSettings` they give once resolved on the asset and the
//! starting camera (`resolve`): the sun placed from the camera, fire by its tool's convention
//! (`vdbcook_scene::fire_convention`), trilinear filtering where voxels cover pixels, the up
//! axis from the source. The same flags give the same picture in both commands.

use vdbcook_asset::Asset;
use vdbcook_trace::{
    Camera, Display, Emission, Filter, FireConvention, Integrator, LengthUnit, Lighting, March,
    Medium, Mode, MsModel, Output, RenderSettings, Tonemap,
};

use crate::errors::CliError;

/// The default sun's colour (and that of `--light DX,DY,DZ`): a warm white three times the
/// old default's 0.7, so lit smoke reads at exposure 0 under the default tone map.
pub const AUTO_SUN: [f32; 3] = [3.0, 2.9, 2.75];

fn other(m: impl Into<String>) -> CliError {
    CliError::Other(m.into())
}

/// Comma-separated finite numbers.
pub fn numbers(what: &str, s: &str) -> Result<Vec<f64>, CliError> {
    s.split(',')
        .map(|t| match t.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(other(format!("--{what}: {t:?} is not a finite number"))),
        })
        .collect()
}

#[derive(clap::Args, Clone, Debug)]
pub struct LookArgs {
    /// Absorption per unit density per unit length.
    #[arg(long, default_value_t = 0.1)]
    pub absorb: f32,
    /// Scattering per unit density per unit length (scatter and delta modes).
    #[arg(long, default_value_t = 1.5)]
    pub scatter: f32,
    /// The sun: `auto` (a key light from above the camera's right shoulder, colour
    /// 3.0,2.9,2.75: placed from the starting view, so it stays put while `view` orbits), or
    /// the world direction toward it and optionally its colour, DX,DY,DZ[,R,G,B] (colour
    /// default 3.0,2.9,2.75).
    #[arg(long, default_value = "auto", allow_hyphen_values = true)]
    pub light: String,
    /// Primary-ray step of the scatter and lit marches (in --units) [default: one voxel: 1 with
    /// --units voxel, the smallest voxel edge with --units world].
    #[arg(long)]
    pub step: Option<f32>,
    /// Shadow-ray step of the scatter mode (in --units) [default: three voxels].
    #[arg(long)]
    pub shadow_step: Option<f32>,
    /// Density and transmittance cutoff (scatter), first-hit threshold (depth, first-hit,
    /// brick-hue).
    #[arg(long, default_value_t = 0.005)]
    pub cutoff: f32,
    /// Shadow falloff: shadow extinction at distance s is divided by 1 + gain·s.
    #[arg(long, default_value_t = 0.2)]
    pub gain: f32,
    /// Samples per pixel (delta, reference).
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// Constant sky radiance R,G,B: the lit and reference modes' fill light (paths that scatter
    /// and leave see it), and the background of the shaded modes' images (--transparent: none).
    /// The default is a clear sky to the default sun (about a fifth of its irradiance).
    #[arg(long, default_value = "0.16,0.2,0.28", allow_hyphen_values = true)]
    pub sky: String,
    /// Henyey–Greenstein phase of the reference mode: G (one lobe) or G0,G1,W (W·HG(G0) +
    /// (1 − W)·HG(G1)); each G in -0.99..=0.99, positive forward.
    #[arg(long, default_value = "0.6,-0.3,0.8", allow_hyphen_values = true)]
    pub phase: String,
    /// Most scattering events per reference path (more count as absorbed).
    #[arg(long, default_value_t = 256)]
    pub bounces: u32,
    /// Light-volume resolution of the lit mode: cells along the longest side of the frame's
    /// content box (2..=256). Coarser is faster to build and blurs shadows.
    #[arg(long, default_value_t = 64)]
    pub light_res: u32,
    /// Multiple-scattering octaves of the lit mode's sun with --ms-model octaves (1 = single
    /// scattering, up to 8).
    #[arg(long, default_value_t = 8)]
    pub ms_octaves: u32,
    /// With --ms-model octaves, the diffusion scale of the lit mode's multiply scattered sky
    /// light: 0 keeps all the sky light the medium scatters, 1 attenuates it as diffusion
    /// theory does (default 0.25, fitted to the reference). The diffusion model solves the
    /// sky's light instead and refuses this option.
    #[arg(long)]
    pub ms_sky: Option<f32>,
    /// Multiple scattering of the lit mode's sun and sky: diffusion (a flux-limited diffusion
    /// solve over the light volume: the sun's scattered light spreads sideways and leaks out
    /// of thin edges, the sky's enters through every surface; closer to the reference) or
    /// octaves (closed forms of the depths toward the sun and the sky, --ms, --ms-octaves and
    /// --ms-sky; a cheaper light-volume build). docs/rendering.md has the figures.
    #[arg(long, default_value = "diffusion", value_parser = ["diffusion", "octaves"])]
    pub ms_model: String,
    /// How the lit mode reads the density and another channel's emission: nearest (the voxel
    /// holding the sample, the medium the reference sees: voxels show as cubes up close),
    /// trilinear (smooth, no seams between bricks; eight reads per sample; another channel's
    /// emission is then read trilinearly in every mode), or auto: trilinear in the lit mode
    /// where the content's nearest voxel covers a pixel or more, else nearest.
    #[arg(long, default_value = "auto", value_parser = ["auto", "nearest", "trilinear"])]
    pub filter: String,
    /// Where the lit mode's nearest-voxel march samples: steps (every --step from the eye,
    /// jittered per pixel: a --step above 1 trades accuracy for speed), voxels (each voxel the
    /// ray crosses integrated exactly, cut into parts of at most --step where the light is read;
    /// no noise, closer to the reference, slower), or auto: voxels on a frame where one step
    /// through its densest voxel is optically thick (≥ 1), else steps. --filter trilinear always
    /// marches in steps.
    #[arg(long, default_value = "auto", value_parser = ["auto", "steps", "voxels"])]
    pub march: String,
    /// Lit mode: light-volume cells toward the sun whose voxels are walked exactly from each
    /// sample before the light volume's depth takes over, where a cell is optically thick
    /// (0 = the light volume alone: cheaper, but a dense cloud's sunlit skin, thinner than
    /// the light volume's cells, comes out too dark).
    #[arg(long, default_value_t = vdbcook_trace::DEFAULT_SUN_NEAR, value_name = "CELLS")]
    pub sun_near: f32,
    /// Lit mode, diffusion model: where the near field was walked, add the once-scattered
    /// sunlight the light volume's cells cannot hold (a dense cloud's sunlit skin sees more of
    /// the sun than its cell's mean), scaled by this: 0.5 is the first-flight fluence at a
    /// surface, 1 deep inside, 0 the cells' light alone (a dense cloud comes out darker).
    #[arg(long, default_value_t = vdbcook_trace::DEFAULT_NEAR_SCATTER, value_name = "K")]
    pub near_scatter: f32,
    /// Lit mode, diffusion model: orders of the sun's scattered light the light volume gathers
    /// exactly before the diffusion solve takes the rest: 2 (once and twice scattered; the
    /// closest to the reference), 1, or 0 (the solve alone: a cheaper light-volume build,
    /// 2–11% dark in sunlight, WDAS 7%). docs/rendering.md charts the error against the build
    /// time.
    #[arg(long, default_value_t = vdbcook_trace::MAX_MS_GATHER, value_name = "ORDERS")]
    pub ms_gather: u32,
    /// Lit mode on an asset cooked with --lod: read level k where a pixel spans 2^k voxels or
    /// more, stepping 2^k voxels (mip-mapping along the ray, for far or low-resolution views).
    /// Off by default: averaging density before the exponential makes far pixels slightly
    /// more opaque than the pixel-area mean (docs/rendering.md has the figures). An asset cooked
    /// with --lod-from K > 1 skips level 1, so its primary rays read full resolution only.
    #[arg(long)]
    pub primary_lod: bool,
    /// Octave falloff of --ms-model octaves A,B,C: octave i scales the
    /// scattering by A^i, the extinction toward the lights by B^i and the phase's g by C^i
    /// (the default is fitted to the reference mode on three clouds: docs/rendering.md).
    #[arg(long, default_value = "0.98,0.9,0.6", value_name = "A,B,C")]
    pub ms: String,
    /// Blackbody emission (density, scatter, delta, reference and lit modes): auto (by the
    /// conventions of Houdini, Blender/Mantaflow, EmberGen and Kelvin grids: a `flame`,
    /// `temperature` or `heat` channel glows, mapped from its name and stored range — see
    /// docs/rendering.md; nothing glows without one), off, or LO,HI: the emitting channel's
    /// values over which the glow rises as ((v − LO)/(HI − LO))⁴ to full brightness (none at or
    /// below LO), e.g. `--emission 800,2000` on a Kelvin grid. `render --json` states the
    /// mapping used.
    #[arg(long, value_name = "auto|off|LO,HI", default_value = "auto")]
    pub emission: String,
    /// The blackbody colours LO,HI in Kelvin that the emission's value range spans (default:
    /// the convention's; for --emission LO,HI above 200, the values themselves; below, 1000 K
    /// per unit, Blender's convention).
    #[arg(long, value_name = "LO,HI")]
    pub emission_kelvin: Option<String>,
    /// Brightness of the emission at the top of its range (radiance per unit length in
    /// --units; default: the convention's, about radiance 1 through a sixth of the fire's
    /// size; 1 with --emission LO,HI).
    #[arg(long)]
    pub emission_intensity: Option<f32>,
    /// The channel that glows, when the convention's pick is not wanted: a channel of a
    /// multi-channel asset, or for VDB input a second grid cooked with --grid.
    #[arg(long, value_name = "NAME")]
    pub emission_grid: Option<String>,
    /// Random seed (delta, reference).
    #[arg(long, default_value_t = 1)]
    pub seed: u32,
    /// Length unit of absorb, scatter, step, shadow-step and gain: voxel (as vdb_render) or world.
    #[arg(long, default_value = "voxel", value_parser = ["voxel", "world"])]
    pub units: String,
    /// Exposure in stops (EV): radiance is multiplied by 2^EV before the tone map.
    #[arg(
        long,
        default_value_t = 0.0,
        allow_hyphen_values = true,
        value_name = "EV"
    )]
    pub exposure: f32,
    /// The tone map from radiance to the display (PNG, `view`): pbr-neutral (Khronos PBR
    /// Neutral: colours under 0.76 kept, highlights rolled off along their hue), aces
    /// (Narkowicz's ACES fit: more contrast, bright fire toward yellow-white), none (a clamp),
    /// or auto: pbr-neutral, but none over a --background plate (the plate is display-referred
    /// already: it comes back unchanged where nothing covers it). The sRGB transfer curve
    /// follows every one; PFM and EXR stay linear radiance.
    #[arg(long, default_value = "auto", value_parser = ["auto", "pbr-neutral", "aces", "none"])]
    pub tonemap: String,
    /// The world's up axis for the default camera and the default sun: auto (from the source:
    /// Z for Blender's files, else Y), or x, y, z, -x, -y, -z.
    #[arg(long, default_value = "auto", allow_hyphen_values = true,
          value_parser = ["auto", "x", "y", "z", "-x", "-y", "-z"])]
    pub up: String,
    /// Shaded modes: no sky behind the volume; the PNG's alpha is the volume's opacity (colour
    /// straight, not premultiplied) and EXR holds premultiplied RGBA, for compositing.
    #[arg(long)]
    pub transparent: bool,
}

impl LookArgs {
    /// The colour pipeline the flags ask for; `over_plate`: the image is composited over a
    /// display-referred plate (`auto` then takes no tone map).
    pub fn display(&self, over_plate: bool) -> Display {
        Display {
            exposure_ev: self.exposure,
            tonemap: match Tonemap::parse(&self.tonemap) {
                Some(t) => t,
                None if over_plate => Tonemap::None,
                None => Tonemap::PbrNeutral,
            },
        }
    }

    /// The up axis: the flag, else the source's convention (`vdbcook_scene::source_up`).
    pub fn up_axis(&self, asset: &Asset) -> [f64; 3] {
        match self.up.as_str() {
            "x" => [1.0, 0.0, 0.0],
            "-x" => [-1.0, 0.0, 0.0],
            "y" => [0.0, 1.0, 0.0],
            "-y" => [0.0, -1.0, 0.0],
            "z" => [0.0, 0.0, 1.0],
            "-z" => [0.0, 0.0, -1.0],
            _ => vdbcook_trace::source_up(asset),
        }
    }

    /// The emission's channel as `--emission-grid` names it, checked on `asset`.
    fn emission_channel(&self, asset: &Asset) -> Result<Option<usize>, CliError> {
        let Some(g) = &self.emission_grid else {
            return Ok(None);
        };
        let h = &asset.header;
        h.channel_index(g).map(Some).ok_or_else(|| {
            other(format!(
                "--emission-grid {g}: the asset has no such channel (channels: {})",
                (0..asset.channel_count())
                    .map(|c| h.channel_name(c).to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        })
    }
}

/// What `resolve` decided, for `render --json`.
#[derive(Debug, Clone, Default)]
pub struct Resolved {
    /// The fire convention the emission follows (`None`: none, or `--emission LO,HI` given).
    pub convention: Option<FireConvention>,
    /// Whether the sun was placed from the camera (`--light auto`).
    pub light_auto: bool,
    /// Whether the filter was chosen by the voxels' footprint (`--filter auto`).
    pub filter_auto: bool,
    /// The up axis used.
    pub up: [f64; 3],
}

/// Settles what depends on the asset and the starting camera: the emission (convention or
/// given range), the sun's direction (`auto`), the filter (`auto`).
pub fn resolve(
    a: &LookArgs,
    s: &mut RenderSettings,
    asset: &Asset,
    camera: &Camera,
) -> Result<Resolved, CliError> {
    let mut r = Resolved {
        up: a.up_axis(asset),
        ..Default::default()
    };
    let world = s.medium.unit == LengthUnit::World;
    // Steps not given are a voxel (three for shadows) whatever the unit: under world units, a
    // world unit is arbitrary (a 0.1-unit voxel grid stepped 10 voxels at a time read single
    // scattering 1.37× the reference on a real dragon; one voxel: 0.986).
    if world {
        let voxel = min_voxel(asset) as f32;
        if a.step.is_none() && voxel.is_finite() && voxel > 0.0 {
            s.integrator.step = voxel;
        }
        if a.shadow_step.is_none() && voxel.is_finite() && voxel > 0.0 {
            s.integrator.shadow_step = 3.0 * voxel;
        }
    }
    // Emission.
    let channel = a.emission_channel(asset)?;
    let per_length = |i: f32| {
        if world {
            // The convention's intensity is per voxel: per world unit, over the (smallest)
            // voxel size, as `voxel_pixels` measures voxels.
            i / min_voxel(asset).max(1e-30) as f32
        } else {
            i
        }
    };
    let kelvin = match &a.emission_kelvin {
        None => None,
        Some(k) => match numbers("emission-kelvin", k)?[..] {
            [lo, hi] => Some([lo as f32, hi as f32]),
            ref v => {
                return Err(CliError::Usage(format!(
                    "--emission-kelvin takes LO,HI, got {} numbers",
                    v.len()
                )))
            }
        },
    };
    s.medium.emission = match a.emission.as_str() {
        "off" => None,
        "auto" => match vdbcook_trace::fire_convention(asset, channel) {
            Some(c) => {
                let mut e = c.emission;
                e.intensity = a.emission_intensity.unwrap_or(per_length(e.intensity));
                if let Some(k) = kelvin {
                    e.kelvin = k;
                }
                r.convention = Some(FireConvention { emission: e, ..c });
                Some(e)
            }
            None if channel.is_some() => {
                return Err(CliError::Usage(format!(
                    "--emission-grid {}: no convention maps the channel (it is not named as a \
                     flame, temperature or heat, or never rises above zero); give its range with \
                     --emission LO,HI",
                    a.emission_grid.as_deref().unwrap_or_default()
                )))
            }
            None => None,
        },
        range => match numbers("emission", range)?[..] {
            [lo, hi] => {
                let (lo, hi) = (lo as f32, hi as f32);
                let channel = channel
                    .or_else(|| {
                        vdbcook_trace::fire_convention(asset, None).map(|c| c.emission.channel)
                    })
                    .or_else(|| vdbcook_trace::channel_named(asset, &vdbcook_trace::HEAT_NAMES))
                    .unwrap_or(0);
                let kelvin = kelvin.unwrap_or(if hi > vdbcook_trace::KELVIN_MIN_MAX {
                    [lo, hi]
                } else {
                    [lo, hi].map(|v| (v * vdbcook_trace::KELVIN_PER_UNIT).max(0.0))
                });
                Some(Emission {
                    range: [lo, hi],
                    kelvin,
                    intensity: a.emission_intensity.unwrap_or(1.0),
                    channel,
                })
            }
            ref v => {
                return Err(other(format!(
                    "--emission takes auto, off or LO,HI, got {} numbers",
                    v.len()
                )))
            }
        },
    };
    // The sun from above the camera's right shoulder.
    if a.light == "auto" {
        r.light_auto = true;
        let b = camera.basis(1, 1).map_err(|e| other(e.to_string()))?;
        let f = vdbcook_trace::normalize(b.forward);
        let right = vdbcook_trace::normalize(b.right);
        let d = [0, 1, 2].map(|i| -0.45 * f[i] + 0.35 * right[i] + 0.8 * r.up[i]);
        let d = vdbcook_trace::normalize(d);
        s.lighting.light_dir = d.map(|v| v as f32);
    }
    // Trilinear in the lit mode where the nearest content voxel spans a pixel or more (the
    // other modes march voxels exactly, their emission too).
    if a.filter == "auto" {
        r.filter_auto = true;
        s.integrator.filter =
            if s.integrator.mode == Mode::Lit && voxel_pixels(asset, camera, s) >= 1.0 {
                Filter::Trilinear
            } else {
                Filter::Nearest
            };
    }
    Ok(r)
}

/// The smallest side of a voxel in world units.
fn min_voxel(asset: &Asset) -> f64 {
    asset
        .header
        .voxel_size
        .iter()
        .map(|v| v.abs())
        .fold(f64::INFINITY, f64::min)
}

/// How many pixels the frame's nearest stored voxel spans (its size over the pixel's footprint
/// at the nearest point of the frame's stored box; infinite with the eye inside it).
pub fn voxel_pixels(asset: &Asset, camera: &Camera, s: &RenderSettings) -> f64 {
    let Some((lo, hi)) = vdbcook_trace::stored_bbox(asset, s.output.frame) else {
        return 0.0;
    };
    let m = &asset.header.index_to_world;
    // The world box of the stored box's corners (cell space is index + ½).
    let (mut wlo, mut whi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for c in 0..8 {
        let p = [0, 1, 2].map(|a| (if c >> a & 1 == 0 { lo[a] } else { hi[a] }) - 0.5);
        for i in 0..3 {
            let w = m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3];
            wlo[i] = wlo[i].min(w);
            whi[i] = whi[i].max(w);
        }
    }
    let d2: f64 = (0..3)
        .map(|i| {
            let e = camera.eye[i];
            let d = (wlo[i] - e).max(0.0).max(e - whi[i]);
            d * d
        })
        .sum();
    let voxel = min_voxel(asset);
    let px = d2.sqrt() * vdbcook_trace::pixel_angle(camera.fov_y_deg, s.output.height);
    if px <= 0.0 {
        f64::INFINITY
    } else {
        voxel / px
    }
}

pub fn settings(a: &LookArgs, output: Output, mode: Mode) -> Result<RenderSettings, CliError> {
    // `auto`: placed by `resolve` once the camera is known.
    let (dir, color) = if a.light == "auto" {
        ([0.0, 1.0, 0.0], AUTO_SUN)
    } else {
        let light = numbers("light", &a.light)?;
        match light[..] {
            [x, y, z] => ([x, y, z], AUTO_SUN),
            [x, y, z, r, g, b] => ([x, y, z], [r as f32, g as f32, b as f32]),
            _ => {
                return Err(other(format!(
                    "--light takes auto, or 3 or 6 numbers, got {}",
                    light.len()
                )))
            }
        }
    };
    let sky = match numbers("sky", &a.sky)?[..] {
        [r, g, b] => [r as f32, g as f32, b as f32],
        ref v => return Err(other(format!("--sky takes 3 numbers, got {}", v.len()))),
    };
    let ms_model = MsModel::parse(&a.ms_model).expect("clap checked");
    if a.ms_sky.is_some() && ms_model == MsModel::Diffusion {
        return Err(CliError::Usage(
            "--ms-sky sets the octaves model's sky (--ms-model octaves); the diffusion model \
             solves the sky's light"
                .into(),
        ));
    }
    let ms = match numbers("ms", &a.ms)?[..] {
        [x, y, z] => [x as f32, y as f32, z as f32],
        ref v => return Err(other(format!("--ms takes A,B,C, got {} numbers", v.len()))),
    };
    let (phase_g, phase_w) = match numbers("phase", &a.phase)?[..] {
        [g] => ([g as f32; 2], 1.0),
        [g0, g1, w] => ([g0 as f32, g1 as f32], w as f32),
        ref v => {
            return Err(other(format!(
                "--phase takes 1 or 3 numbers, got {}",
                v.len()
            )))
        }
    };
    Ok(RenderSettings {
        output,
        medium: Medium {
            absorb: a.absorb,
            scatter: a.scatter,
            unit: if a.units == "world" {
                LengthUnit::World
            } else {
                LengthUnit::Voxel
            },
            phase_g,
            phase_w,
            // Resolved on the asset by `resolve`.
            emission: None,
        },
        lighting: Lighting {
            light_dir: [dir[0] as f32, dir[1] as f32, dir[2] as f32],
            light_color: color,
            sky,
            light_res: a.light_res,
            ms_octaves: a.ms_octaves,
            ms,
            ms_sky: a.ms_sky.unwrap_or(ms_model.default_ms_sky()),
            ms_model,
            sun_near: a.sun_near,
            near_scatter: a.near_scatter,
            ms_gather: a.ms_gather,
        },
        integrator: Integrator {
            mode,
            // In voxels until `resolve` knows the voxel size (world units).
            step: a.step.unwrap_or(1.0),
            shadow_step: a.shadow_step.unwrap_or(3.0),
            cutoff: a.cutoff,
            gain: a.gain,
            spp: a.spp,
            first_sample: 0,
            seed: a.seed,
            bounces: a.bounces,
            // `auto` is resolved on the camera by `resolve`.
            filter: Filter::parse(&a.filter).unwrap_or(Filter::Nearest),
            march: March::parse(&a.march).expect("clap checked"),
            primary_lod: a.primary_lod,
        },
    })
}
