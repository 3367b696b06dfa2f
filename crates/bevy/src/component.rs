//! What a Bevy app spawns and sets: a volume instance ([`VdbVolume`] with its [`VdbPlayback`]),
//! the cameras that draw volumes ([`VolumeCamera`]), and the shading every volume shares
//! ([`VolumeShading`]). Plain data, read by the plugin's systems.

use bevy::ecs::lifecycle::HookContext;
use bevy::ecs::world::DeferredWorld;
use bevy::prelude::*;
use vdbcook_runtime::{
    Emission, Filter, Integrator, Interleave, Lighting, LitCrossfade, MarchResolution, Medium,
};

use crate::asset::VdbAsset;

/// One instance of a flip-book in the scene, placed by its entity's `Transform` (applied to the
/// asset's own world placement, its `index_to_world`). Any number of instances may share an
/// asset; they are drawn in one pass per asset and camera, ordered and mixed per pixel.
#[derive(Component, Clone, Debug)]
#[require(Transform, Visibility, VdbPlayback)]
pub struct VdbVolume {
    pub asset: Handle<VdbAsset>,
    /// Multiplies the medium's extinction (≥ 0): 2 is twice as opaque.
    pub density_scale: f32,
    /// Linear RGB multiplier of the volume's radiance (≥ 0).
    pub tint: Vec3,
    /// The glow of fire and explosions.
    pub emission: VolumeEmission,
    /// Multiplies the glow (≥ 0): fire under a bright sun may want more than its cooked look.
    pub emission_scale: f32,
    /// Stand the volume up in Bevy's Y-up world: its source's up axis (Blender's Z) becomes +Y
    /// (`VdbAsset::upright`) before the entity's transform. On by default; off places the
    /// asset's own coordinates unchanged.
    pub upright: bool,
}

impl VdbVolume {
    /// An instance of `asset`: density scale 1, white, emission chosen from its channels,
    /// upright.
    pub fn new(asset: Handle<VdbAsset>) -> VdbVolume {
        VdbVolume {
            asset,
            density_scale: 1.0,
            tint: Vec3::ONE,
            emission: VolumeEmission::Auto,
            emission_scale: 1.0,
            upright: true,
        }
    }
}

/// Whether and how a volume glows. The glow is radiance in Bevy's units (cd/m², as
/// `StandardMaterial::emissive`), multiplied by the camera's exposure as the scene's lights
/// are: a brighter exposure dims fire as it dims everything.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum VolumeEmission {
    /// As the cooker's renders do: a channel named as heat or flame (`temperature`, `flame`,
    /// Houdini's `heat`) glows by its blackbody convention (`vdbcook_runtime::fire_convention`),
    /// as bright at Bevy's default exposure (EV100 9.7) as in `vdbcook render`; smoke without
    /// such a channel does not glow.
    #[default]
    Auto,
    /// No glow.
    Off,
    /// This emission (channel, value range, blackbody temperatures; `intensity` in cd/m²).
    Custom(Emission),
}

/// How an instance moves through its flip-book. `time` is in frames; the plugin advances it by
/// `Time::delta_secs() · fps · speed` every update unless `paused` (and with `Time<Virtual>`:
/// pausing or slowing Bevy's clock pauses or slows the volumes).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct VdbPlayback {
    /// The current frame (fractional between two frames).
    pub time: f32,
    /// Frames per second of the flip-book (the simulation's rate; 24 by default).
    pub fps: f32,
    /// Multiplies `fps` (1: real time; negative plays backwards).
    pub speed: f32,
    pub mode: PlayMode,
    pub blend: FrameBlend,
    pub paused: bool,
}

impl Default for VdbPlayback {
    fn default() -> Self {
        VdbPlayback {
            time: 0.0,
            fps: 24.0,
            speed: 1.0,
            mode: PlayMode::Loop,
            blend: FrameBlend::Crossfade,
            paused: false,
        }
    }
}

/// What happens at the end of the flip-book.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PlayMode {
    /// Start again at frame 0.
    #[default]
    Loop,
    /// Stop on the last frame (or the first, backwards).
    Once,
    /// Turn around at either end.
    PingPong,
}

/// What is drawn between two frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FrameBlend {
    /// The two frames' densities blended (smooth; a lit volume builds light for both).
    #[default]
    Crossfade,
    /// The earlier whole frame (the runtime's cheapest case: one light volume per frame).
    Hold,
}

/// Put on a camera (`Camera3d`) that should draw volumes. It must render with `Msaa::Off` (the
/// drawer reads a single-sampled depth; use TAA, FXAA or SMAA instead): adding this component
/// sets the camera's `Msaa` to `Off` (Bevy's `Camera` requires `Msaa::Sample4`, which would
/// otherwise win over a requirement of this component). HDR cameras (`Hdr`) are the supported path: on LDR cameras Bevy tonemaps inside
/// the mesh shaders, so volumes match the scene there only with `Tonemapping::None`.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq)]
#[component(on_add = single_sampled)]
pub struct VolumeCamera {
    /// One ray per pixel, or per 2×2 / 4×4 block away from depth edges (cheaper, upsampled).
    pub march_resolution: MarchResolution,
    /// When overlapping instances are mixed along each ray.
    pub interleave: Interleave,
    /// How a lit volume between two frames is marched: both frames lerped per sample (`Lerp`,
    /// the default: no grain, about 1.6–2× the lit march of a whole frame) or each sample from one
    /// frame (`Dither`: about a whole frame's cost, a per-pixel grain where neighbouring frames
    /// differ, for cameras with TAA: on a camera with TAA jitter the plugin varies the
    /// integrator's seed with the jitter, so the grain changes every frame and TAA averages it).
    pub lit_crossfade: LitCrossfade,
    /// Builds each lit volume's next flip-book frame's light ahead over this many rendered
    /// frames (0, the default: built in the frame that reaches it). The same light, the
    /// build's cost spread over the frames before it (`VolumeDrawer::set_light_ahead`): 2 suits
    /// a 24-fps effect on a 60-Hz display.
    pub light_ahead: u32,
    /// While a lit volume plays, lights its flip-book's frames in spans of this many frames,
    /// one light volume each, built from the span's middle frame (0, the default, or 1: every
    /// frame its own light). A volume whose `VdbPlayback` is paused, still or stopped gets its
    /// frame's exact light (a paused `Time<Virtual>` alone does not count: pause the playback
    /// too). 2 halves the light builds of a playing effect, for light that lags or leads by up
    /// to a frame (`Instance::light_stride`; `vdbcook bench --light-stride N` states the image
    /// error).
    pub light_stride: u32,
}

/// [`VolumeCamera`]'s hook: the camera draws single-sampled.
fn single_sampled(mut world: DeferredWorld<'_>, context: HookContext) {
    world.commands().entity(context.entity).insert(Msaa::Off);
}

/// The shading every volume shares: its medium (absorption and scattering per unit density,
/// phase function), how its light is integrated, and whether it is lit by the scene's sun and
/// sky (the brightest visible `DirectionalLight` and the ambient light, in Bevy's units, exposed
/// by the camera's exposure as Bevy's meshes are) or drawn flat (`lit: false`: `tint·(1 − T)`,
/// the cheapest). `lighting`'s sun and sky are overwritten each frame from the scene; its other
/// fields (light-volume resolution, multiple-scattering model) are used as set.
#[derive(Resource, Clone, Debug, PartialEq)]
pub struct VolumeShading {
    pub medium: Medium,
    pub integrator: Integrator,
    pub lighting: Lighting,
    pub lit: bool,
}

impl Default for VolumeShading {
    /// The runtime's medium and lighting defaults, lit, with trilinear density (a game camera
    /// comes close enough to see nearest-voxel cubes; trilinear reads eight voxels per sample).
    fn default() -> Self {
        VolumeShading {
            medium: Medium::default(),
            integrator: Integrator {
                filter: Filter::Trilinear,
                ..Default::default()
            },
            lighting: Lighting::default(),
            lit: true,
        }
    }
}
