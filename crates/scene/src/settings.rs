//! What a render is asked to do, by what each setting is: the image (`Output`), what the volume
//! is made of (`Medium`: named after OpenVDB's `vdb_render` so images can be compared), the light
//! (`Lighting`: one definition for the CPU tracer, the GPU renderer and the engine drawer) and how
//! a pixel is computed (`Integrator`); and the checks that refuse settings which would make a
//! loop unbounded or a pixel NaN.

use std::fmt;

/// What a pixel shows. Exact definitions: the crate docs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mode {
    /// `1 - T` with `T = exp(-absorb · ∫σ ds)`, integrated exactly voxel by voxel.
    Density,
    /// Distance to the first voxel whose value exceeds `cutoff`.
    Depth,
    /// Value of the first voxel whose value exceeds `cutoff`.
    FirstHitDensity,
    /// Hue from the index of the brick holding the first hit.
    BrickHue,
    /// Traversal steps of the density walk, as a heat map.
    Steps,
    /// `vdb_render`'s single scattering: fixed steps, shadow rays toward one directional light.
    SingleScatter,
    /// The same single-scattering medium estimated without bias by delta tracking (seeded).
    DeltaTracking,
    /// The physically based reference: a path tracer with multiple scattering (delta tracking,
    /// a dual-lobe Henyey–Greenstein phase, the sun by ratio-tracked next-event estimation, a
    /// constant sky on escape), no `gain` hack. CPU only; what approximations are judged by.
    Reference,
    /// The game-speed approximation of `Reference` (same medium, sun, sky and phase): a
    /// fixed-step march with per-step energy-conserving integration whose sun and sky
    /// transmittances are read from a low-resolution light volume (optical depths toward the
    /// sun and toward the six axis directions, built once per frame and light), with multiple
    /// scattering approximated by `ms_octaves` octaves of attenuated extinction and phase.
    Lit,
}

impl Mode {
    pub const ALL: [Mode; 9] = [
        Mode::Density,
        Mode::Depth,
        Mode::FirstHitDensity,
        Mode::BrickHue,
        Mode::Steps,
        Mode::SingleScatter,
        Mode::DeltaTracking,
        Mode::Reference,
        Mode::Lit,
    ];
    /// The name the CLI uses.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Density => "density",
            Mode::Depth => "depth",
            Mode::FirstHitDensity => "first-hit",
            Mode::BrickHue => "brick-hue",
            Mode::Steps => "steps",
            Mode::SingleScatter => "scatter",
            Mode::DeltaTracking => "delta",
            Mode::Reference => "reference",
            Mode::Lit => "lit",
        }
    }
    pub fn parse(s: &str) -> Option<Mode> {
        Mode::ALL.into_iter().find(|m| m.name() == s)
    }
}

/// How `Lit` reads the density at a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Filter {
    /// The voxel holding the sample (the medium every other mode and the reference see).
    Nearest,
    /// Trilinear between the eight nearest voxel centres (each value `max(v, 0)`), read through
    /// the tree, so bricks join without seams; smooth up close, eight reads per sample.
    Trilinear,
}

impl Filter {
    pub fn name(self) -> &'static str {
        match self {
            Filter::Nearest => "nearest",
            Filter::Trilinear => "trilinear",
        }
    }
    pub fn parse(s: &str) -> Option<Filter> {
        [Filter::Nearest, Filter::Trilinear]
            .into_iter()
            .find(|f| f.name() == s)
    }
}

/// How `Lit` approximates the sun's multiple scattering (light scattered twice or more).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum MsModel {
    /// Closed-form octaves of the optical depth toward the sun at the sample
    /// (`crate::octave_source`, `RenderSettings::{ms, ms_octaves}`): no solve, the light
    /// volume's build is cheaper.
    Octaves,
    /// A flux-limited diffusion solve over the light volume's cells, fed by the sun's first
    /// scattering (`vdbcook_trace::diffusion`): light spreads between cells, leaks out of thin
    /// edges and is absorbed in thick cores. Closer to the reference on every cloud measured
    /// (`docs/rendering.md`).
    #[default]
    Diffusion,
}

impl MsModel {
    pub fn name(self) -> &'static str {
        match self {
            MsModel::Octaves => "octaves",
            MsModel::Diffusion => "diffusion",
        }
    }
    pub fn parse(s: &str) -> Option<MsModel> {
        [MsModel::Octaves, MsModel::Diffusion]
            .into_iter()
            .find(|m| m.name() == s)
    }
    /// The `ms_sky` this model was measured best with against the reference on three clouds
    /// (`docs/rendering.md`): the sun's share of the image decides how much of the sky's
    /// scattered light the fit leaves.
    pub fn default_ms_sky(self) -> f32 {
        match self {
            MsModel::Octaves => 0.25,
            MsModel::Diffusion => 0.5,
        }
    }
}

/// Where `Lit`'s nearest-voxel march takes its samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum March {
    /// `Voxels` on a frame where one step through its densest voxel is optically thick (depth ≥
    /// [`LIT_VOXEL_DEPTH`]: a step's light would come mostly from its first part, which one
    /// sample misplaces), else `Steps` ([`March::resolve`]).
    #[default]
    Auto,
    /// Every `step` from the eye, offset per pixel by a jitter (a game's TAA averages the
    /// noise): `step` above a voxel trades accuracy for speed. Trilinear filtering always
    /// marches in steps (its density has no voxel faces to break at).
    Steps,
    /// Along the voxels the ray crosses: each voxel's segment (a constant tile's span) is
    /// integrated exactly for its density, cut into equal parts of at most `step` where the
    /// source is read; no jitter. Exact for the medium the reference sees; about 1.5 source
    /// reads per voxel crossed (`docs/rendering.md` has the cost).
    Voxels,
}

impl March {
    pub fn name(self) -> &'static str {
        match self {
            March::Auto => "auto",
            March::Voxels => "voxels",
            March::Steps => "steps",
        }
    }
    pub fn parse(s: &str) -> Option<March> {
        [March::Auto, March::Voxels, March::Steps]
            .into_iter()
            .find(|m| m.name() == s)
    }

    /// The march a render of `s` takes on a frame whose largest value is `frame_max`
    /// (`Steps` or `Voxels`; trilinear density always steps). The CPU tracer and the GPU
    /// renderer decide alike, in f64 from the same f32 settings and frame range.
    pub fn resolve(s: &RenderSettings, frame_max: f32) -> March {
        let (m, i) = (&s.medium, &s.integrator);
        if i.filter == Filter::Trilinear {
            return March::Steps;
        }
        match i.march {
            March::Auto => {
                let step_depth = (m.absorb as f64 + m.scatter as f64)
                    * frame_max.max(0.0) as f64
                    * i.step as f64;
                if step_depth >= LIT_VOXEL_DEPTH {
                    March::Voxels
                } else {
                    March::Steps
                }
            }
            m => m,
        }
    }
}

/// Optical depth of one `step` through a frame's densest voxel from which `March::Auto` follows
/// voxels: the step march reads each step's light at one point, and where a step is this thick
/// most of its light comes from its first part (measured against the reference: the WDAS cloud
/// 0.132 → 0.103, the smoke fixture 0.092 → 0.050 relative RMSE; the thin stormscape frame, 0.05
/// a step, 0.043 either way).
pub const LIT_VOXEL_DEPTH: f64 = 1.0;

/// The length that `absorb`, `scatter`, `step`, `shadow_step` and `gain` are measured in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LengthUnit {
    /// Index-space length (one voxel edge = 1), as `vdb_render` measures: a volume looks the same
    /// whatever its voxel size.
    Voxel,
    /// World-space length (the asset's `index_to_world`).
    World,
}

/// The image a render writes: its size and the frame it shows.
#[derive(Debug, Clone, PartialEq)]
pub struct Output {
    pub width: u32,
    pub height: u32,
    /// Frame index (0-based, into `asset.header.frames`).
    pub frame: usize,
}

impl Default for Output {
    /// 640×360, frame 0.
    fn default() -> Self {
        Output {
            width: 640,
            height: 360,
            frame: 0,
        }
    }
}

/// What the volume is made of: how its values absorb, scatter and glow. Named after OpenVDB's
/// `vdb_render` so images can be compared.
#[derive(Debug, Clone, PartialEq)]
pub struct Medium {
    /// Absorption coefficient per unit density per unit length.
    pub absorb: f32,
    /// Scattering coefficient per unit density per unit length.
    pub scatter: f32,
    /// The length `absorb`, `scatter` and the integrator's steps and `gain` are measured in.
    pub unit: LengthUnit,
    /// Dual-lobe Henyey–Greenstein phase: `w·HG(g₀) + (1 − w)·HG(g₁)`, each `g` in
    /// `[−MAX_PHASE_G, MAX_PHASE_G]` (positive: forward), `w = phase_w ∈ [0, 1]`.
    pub phase_g: [f32; 2],
    pub phase_w: f32,
    /// Blackbody emission of a channel, its values mapped to a Kelvin range (the shaded modes:
    /// `Density`, `SingleScatter`, `DeltaTracking`, `Reference`, `Lit`; `crate::fire_convention`
    /// picks one by a tool's conventions).
    pub emission: Option<crate::Emission>,
}

impl Default for Medium {
    /// `vdb_render`'s absorption and scattering per voxel, a forward-scattering dual lobe.
    fn default() -> Self {
        Medium {
            absorb: 0.1,
            scatter: 1.5,
            unit: LengthUnit::Voxel,
            phase_g: [0.6, -0.3],
            phase_w: 0.8,
            emission: None,
        }
    }
}

/// The light: a sun, a constant sky, and how the lit mode approximates their multiple
/// scattering. One definition for the CPU tracer, the GPU renderer and the engine drawer.
#[derive(Debug, Clone, PartialEq)]
pub struct Lighting {
    /// Direction *toward* the light (world space; normalized when used).
    pub light_dir: [f32; 3],
    pub light_color: [f32; 3],
    /// Constant sky radiance (linear RGB) seen by paths that scatter and then leave the volume
    /// (a primary ray that leaves unscattered counts in the transmittance instead, so the image
    /// composites as `L + T·background`).
    pub sky: [f32; 3],
    /// How `Lit` approximates the sun's multiple scattering (`ms_octaves` and `ms` are the
    /// octaves model's).
    pub ms_model: MsModel,
    /// Multiple-scattering octaves of `Lit` (1: single scattering through the light volume).
    pub ms_octaves: u32,
    /// Octave `i` of `Lit`'s sun scales the scattering by `a^i`, the extinction toward the sun
    /// by `b^i` and the phase asymmetry by `c^i`: `[a, b, c]`, each in `[0, 1]`.
    pub ms: [f32; 3],
    /// `MsModel::Octaves` only (the diffusion model solves the sky's light): scale of the
    /// diffusion attenuation of `Lit`'s multiply scattered sky light
    /// (`vdbcook_scene::sky_source`), in `[0, MAX_MS_SKY]`: 0 keeps all the sky light the medium
    /// scatters, 1 is diffusion theory's `√(3(1 − α)(1 − ḡα))`.
    pub ms_sky: f32,
    /// Light-volume resolution of `Lit`: cells along the longest side of the frame's content
    /// box (cubic cells; the other sides in proportion).
    pub light_res: u32,
    /// `Lit`'s near field toward the sun, in light-volume cells: from each sample the voxels
    /// of the first `sun_near` cells toward the sun are walked exactly (a voxel DDA through
    /// the tree), and only the depth beyond is looked up in the light volume, whose cells blur
    /// a dense cloud's lit skin (`docs/rendering.md`); where one cell is optically thin
    /// (`crate::LIT_NEAR_DEPTH`) or the ray's transmittance is below `LIT_NEAR_TRANS` the
    /// light volume alone. 0: the light volume alone everywhere (cheaper).
    pub sun_near: f32,
    /// `MsModel::Diffusion` where the near field was walked: the once-scattered sunlight the
    /// light volume's cells cannot hold, `near_scatter·α/4π·(e^{−σ·τ} − e^{−σ·τ_cells})` added
    /// to the solve's sun light (at least 0 in sum), `τ` the walked depth toward the sun and
    /// `τ_cells` the light volume's at the sample (what the solve's source saw). Light
    /// scattered once within a mean free path of a point reaches it with a fluence of `α·T`
    /// per unit irradiance for a locally uniform source deep inside, half that on a surface
    /// (`DEFAULT_NEAR_SCATTER`); in `[0, 1]`, 0 reads the cells' light alone
    /// (`docs/rendering.md`).
    pub near_scatter: f32,
    /// `MsModel::Diffusion`: how many orders of the sun's scattered light the light-volume
    /// build gathers exactly before the diffusion solve takes the rest
    /// (`vdbcook_trace::diffusion`): 2 (default) the light scattered once and twice, 1 once,
    /// 0 none (the solve carries all of it: cheaper to build, 2–11% dark in sunlight, WDAS 7%;
    /// `docs/rendering.md` charts error against build time). At most [`MAX_MS_GATHER`].
    pub ms_gather: u32,
}

impl Default for Lighting {
    /// `vdb_render`'s light, a pale sky, and the lit mode's measured defaults.
    fn default() -> Self {
        Lighting {
            light_dir: [0.3, 0.3, 0.0],
            light_color: [0.7, 0.7, 0.7],
            sky: [0.04, 0.05, 0.065],
            ms_model: MsModel::Diffusion,
            // Fitted against the reference (issue 13, `docs/rendering.md`): the worst relative
            // RMSE over the WDAS cloud, a stormscape frame and a generated smoke.
            ms_octaves: 8,
            ms: [0.98, 0.9, 0.6],
            ms_sky: MsModel::Diffusion.default_ms_sky(),
            light_res: 64,
            sun_near: DEFAULT_SUN_NEAR,
            near_scatter: DEFAULT_NEAR_SCATTER,
            ms_gather: MAX_MS_GATHER,
        }
    }
}

/// How a pixel is computed: the mode and how it samples.
#[derive(Debug, Clone, PartialEq)]
pub struct Integrator {
    pub mode: Mode,
    /// Primary-ray step of the marches (`SingleScatter`, `Lit`; the emission majorant of
    /// `DeltaTracking` and `Reference`), in the medium's `unit`.
    pub step: f32,
    /// Shadow-ray step of `SingleScatter`, in the medium's `unit`.
    pub shadow_step: f32,
    /// Density below which `SingleScatter` ignores a sample, and transmittance (squared, times
    /// three) below which it stops a ray; the first-hit threshold of the hit modes.
    pub cutoff: f32,
    /// Shadow attenuation falloff: shadow extinction at distance `s` is divided by `1 + gain·s`.
    pub gain: f32,
    /// Samples per pixel of `DeltaTracking` and `Reference`.
    pub spp: u32,
    /// Index of the first sample (progressive rendering: batches `[k, k + spp)` average to the
    /// image with `first_sample = 0` and the summed spp).
    pub first_sample: u32,
    pub seed: u32,
    /// Most scattering events of one `Reference` path (more is absorbed: the only bias).
    pub bounces: u32,
    /// How `Lit` reads the density (the other modes read the nearest voxel).
    pub filter: Filter,
    /// Where `Lit`'s nearest-voxel march takes its samples.
    pub march: March,
    /// Whether `Lit`'s primary rays read coarser levels of detail (an asset cooked with
    /// `--lod`) where a pixel spans more voxels (`crate::level_start`): level `k` where it
    /// spans `2^k` or more, with the step `2^k` times longer. No effect on an asset without
    /// levels or with levels from `K > 1` only (`LevelChain::consecutive`). Off by default: the
    /// mean density of a level makes a far pixel more opaque than the mean over the pixel of
    /// the full resolution's transmittance (Jensen's inequality).
    pub primary_lod: bool,
}

impl Default for Integrator {
    /// Density, with `vdb_render`'s steps, cutoff and gain.
    fn default() -> Self {
        Integrator {
            mode: Mode::Density,
            step: 1.0,
            shadow_step: 3.0,
            cutoff: 0.005,
            gain: 0.2,
            spp: 16,
            first_sample: 0,
            seed: 1,
            bounces: 256,
            filter: Filter::Nearest,
            march: March::Auto,
            primary_lod: false,
        }
    }
}

/// Everything but the camera, by what each setting is: the image, the medium, the light and the
/// integrator.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RenderSettings {
    pub output: Output,
    pub medium: Medium,
    pub lighting: Lighting,
    pub integrator: Integrator,
}

/// Largest image side accepted.
pub const MAX_SIDE: u32 = 16384;
/// Smallest march step accepted, in `unit` (keeps fixed-step marches bounded).
pub const MIN_STEP: f32 = 1e-3;
/// Most samples per pixel accepted in one call.
pub const MAX_SPP: u32 = 1 << 16;
/// Largest `|g|` of a phase lobe (closer to 1 the lobe is a near-delta no sampler resolves).
pub const MAX_PHASE_G: f32 = 0.99;
/// Largest light-volume resolution accepted (cells along the longest side).
pub const MAX_LIGHT_RES: u32 = 256;
/// `Lit`'s default near field toward the sun, in light-volume cells
/// (`RenderSettings::sun_near`).
pub const DEFAULT_SUN_NEAR: f32 = 3.0;
/// `Lit`'s default `near_scatter`: the first-flight fluence of once-scattered light at the
/// surface of a medium with a locally uniform source, `α·T/2` per unit irradiance (half the
/// `α·T` deep inside: half the space around a surface point is empty). A dense cloud's
/// visible samples lie on its surface. Chosen for that reason, not fitted per scene: 1 and
/// 0.35 were measured beside it against the reference (`docs/rendering.md`).
pub const DEFAULT_NEAR_SCATTER: f32 = 0.5;
/// Most orders of scattered sunlight `Lighting::ms_gather` gathers (and its default).
pub const MAX_MS_GATHER: u32 = 2;
/// Longest near field toward the sun accepted, in light-volume cells (more than the longest
/// side of any light volume).
pub const MAX_SUN_NEAR: f32 = 512.0;
/// Largest `ms_sky` accepted.
pub const MAX_MS_SKY: f32 = 16.0;
/// Most multiple-scattering octaves accepted.
pub const MAX_MS_OCTAVES: u32 = 8;
/// Most scattering events per `Reference` path accepted.
pub const MAX_BOUNCES: u32 = 1 << 12;

/// Why a render was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum TraceError {
    /// The frame index is not in the asset.
    Frame { frame: usize, frames: usize },
    /// A setting out of its range (named).
    Setting(String),
    /// The asset's `index_to_world` cannot be inverted or is not affine.
    Transform(String),
    /// The camera is degenerate (non-finite, eye at the look-at point, fov out of (0, 180)).
    Camera(String),
}

impl fmt::Display for TraceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TraceError::Frame { frame, frames } => {
                write!(
                    f,
                    "frame {frame} is not in the asset ({frames} frames: 0..{frames})"
                )
            }
            TraceError::Setting(m) => write!(f, "bad render setting: {m}"),
            TraceError::Transform(m) => write!(f, "unusable index_to_world: {m}"),
            TraceError::Camera(m) => write!(f, "bad camera: {m}"),
        }
    }
}

impl std::error::Error for TraceError {}

fn bad<T>(m: String) -> Result<T, TraceError> {
    Err(TraceError::Setting(m))
}

impl Output {
    /// Refuses an empty or oversized image, or a frame the asset lacks.
    pub fn validate(&self, frames: usize) -> Result<(), TraceError> {
        if self.frame >= frames {
            return Err(TraceError::Frame {
                frame: self.frame,
                frames,
            });
        }
        if self.width == 0 || self.height == 0 || self.width > MAX_SIDE || self.height > MAX_SIDE {
            return bad(format!(
                "image {}x{} (each side 1..={MAX_SIDE})",
                self.width, self.height
            ));
        }
        Ok(())
    }
}

impl Medium {
    /// Extinction per unit density (`absorb + scatter`, in f64) and the single-scattering albedo
    /// (`scatter / extinction`; 0 without extinction).
    pub fn extinction_albedo(&self) -> (f64, f64) {
        let extinction = self.absorb as f64 + self.scatter as f64;
        let albedo = if extinction > 0.0 {
            self.scatter as f64 / extinction
        } else {
            0.0
        };
        (extinction, albedo)
    }

    /// Refuses coefficients, a phase or an emission that would put NaN into a pixel.
    pub fn validate(&self) -> Result<(), TraceError> {
        for (name, v) in [("absorb", self.absorb), ("scatter", self.scatter)] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{name} = {v} (must be finite and ≥ 0)"));
            }
        }
        if self.phase_g.iter().any(|g| !(g.abs() <= MAX_PHASE_G)) {
            return bad(format!(
                "phase g {:?} (each in -{MAX_PHASE_G}..={MAX_PHASE_G})",
                self.phase_g
            ));
        }
        if !(0.0..=1.0).contains(&self.phase_w) {
            return bad(format!("phase weight {} (0..=1)", self.phase_w));
        }
        if let Some(e) = self.emission {
            let [lo, hi] = e.range;
            if !(lo.is_finite() && hi.is_finite() && hi > lo) {
                return bad(format!("emission range {lo},{hi} (lo < hi, finite)"));
            }
            let [klo, khi] = e.kelvin;
            if !(klo.is_finite() && khi.is_finite() && klo >= 0.0 && khi >= klo) {
                return bad(format!(
                    "emission colour range {klo},{khi} K (0 ≤ lo ≤ hi, finite)"
                ));
            }
            if !(e.intensity.is_finite() && e.intensity >= 0.0) {
                return bad(format!(
                    "emission intensity {} (finite and ≥ 0)",
                    e.intensity
                ));
            }
        }
        Ok(())
    }
}

impl Lighting {
    /// Refuses a light without a direction, negative light, or approximation knobs out of range.
    pub fn validate(&self) -> Result<(), TraceError> {
        if self
            .light_color
            .iter()
            .any(|c| !(c.is_finite() && *c >= 0.0))
        {
            return bad(format!("light colour {:?}", self.light_color));
        }
        let l = self.light_dir;
        let n = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
        if !(n.is_finite() && n > 1e-6) {
            return bad(format!("light direction {l:?} has no direction"));
        }
        if self.sky.iter().any(|c| !(c.is_finite() && *c >= 0.0)) {
            return bad(format!("sky {:?} (finite and ≥ 0)", self.sky));
        }
        if !(2..=MAX_LIGHT_RES).contains(&self.light_res) {
            return bad(format!(
                "light-res = {} (2..={MAX_LIGHT_RES})",
                self.light_res
            ));
        }
        if !(1..=MAX_MS_OCTAVES).contains(&self.ms_octaves) {
            return bad(format!(
                "ms-octaves = {} (1..={MAX_MS_OCTAVES})",
                self.ms_octaves
            ));
        }
        if self.ms.iter().any(|v| !(0.0..=1.0).contains(v)) {
            return bad(format!("ms {:?} (each in 0..=1)", self.ms));
        }
        if !(0.0..=MAX_MS_SKY).contains(&self.ms_sky) {
            return bad(format!("ms-sky = {} (0..={MAX_MS_SKY})", self.ms_sky));
        }
        if !(0.0..=MAX_SUN_NEAR).contains(&self.sun_near) {
            return bad(format!(
                "sun-near = {} (0..={MAX_SUN_NEAR} light-volume cells)",
                self.sun_near
            ));
        }
        if !(0.0..=1.0).contains(&self.near_scatter) {
            return bad(format!("near-scatter = {} (0..=1)", self.near_scatter));
        }
        if self.ms_gather > MAX_MS_GATHER {
            return bad(format!(
                "ms-gather = {} (0..={MAX_MS_GATHER})",
                self.ms_gather
            ));
        }
        Ok(())
    }
}

impl Integrator {
    /// Refuses steps, samples or thresholds that would leave a loop unbounded.
    pub fn validate(&self) -> Result<(), TraceError> {
        for (name, v) in [("cutoff", self.cutoff), ("gain", self.gain)] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{name} = {v} (must be finite and ≥ 0)"));
            }
        }
        for (name, v) in [("step", self.step), ("shadow-step", self.shadow_step)] {
            if !(v.is_finite() && v >= MIN_STEP) {
                return bad(format!("{name} = {v} (must be ≥ {MIN_STEP})"));
            }
        }
        if self.bounces == 0 || self.bounces > MAX_BOUNCES {
            return bad(format!("bounces = {} (1..={MAX_BOUNCES})", self.bounces));
        }
        if self.spp == 0 || self.spp > MAX_SPP {
            return bad(format!("spp = {} (1..={MAX_SPP})", self.spp));
        }
        Ok(())
    }
}

impl RenderSettings {
    /// Refuses settings that would leave a loop unbounded or put NaN into a pixel: each group's
    /// own checks, then what crosses groups (emission is drawn by the shaded modes).
    pub fn validate(&self, frames: usize) -> Result<(), TraceError> {
        self.output.validate(frames)?;
        self.medium.validate()?;
        self.lighting.validate()?;
        self.integrator.validate()?;
        let mode = self.integrator.mode;
        if self.medium.emission.is_some()
            && !matches!(
                mode,
                Mode::Density
                    | Mode::SingleScatter
                    | Mode::DeltaTracking
                    | Mode::Reference
                    | Mode::Lit
            )
        {
            return bad(format!(
                "emission is drawn by the shaded modes (density, scatter, delta, reference, lit), not {}",
                mode.name()
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `March::Auto` follows voxels where one step through the frame's densest voxel is
    /// optically thick (≥ `LIT_VOXEL_DEPTH`), steps where it is thin; an explicit march stays,
    /// and trilinear density always steps.
    #[test]
    fn auto_march_follows_voxels_where_a_step_is_thick() {
        let s = RenderSettings::default(); // absorb 0.1 + scatter 1.5, step 1
        assert_eq!(March::resolve(&s, 1.0), March::Voxels); // depth 1.6
        assert_eq!(March::resolve(&s, 0.625), March::Voxels); // depth 1.0
        assert_eq!(March::resolve(&s, 0.6), March::Steps); // depth 0.96
        assert_eq!(March::resolve(&s, -3.0), March::Steps);
        let half = RenderSettings {
            integrator: Integrator {
                step: 0.5,
                ..s.integrator.clone()
            },
            ..s.clone()
        };
        assert_eq!(March::resolve(&half, 1.0), March::Steps); // depth 0.8
        let voxels = RenderSettings {
            integrator: Integrator {
                march: March::Voxels,
                ..s.integrator.clone()
            },
            ..s.clone()
        };
        assert_eq!(March::resolve(&voxels, 0.0), March::Voxels);
        let steps = RenderSettings {
            integrator: Integrator {
                march: March::Steps,
                ..s.integrator.clone()
            },
            ..s.clone()
        };
        assert_eq!(March::resolve(&steps, 1.0), March::Steps);
        let trilinear = RenderSettings {
            integrator: Integrator {
                filter: Filter::Trilinear,
                ..voxels.integrator
            },
            ..voxels
        };
        assert_eq!(March::resolve(&trilinear, 1.0), March::Steps);
    }
}
