//! `vdbcook-scene`: the view and parameter maths that the CPU reference tracer (`vdbcook-trace`)
//! and the GPU runtime (`vdbcook-runtime`) share, and nothing else: the pinhole camera and its
//! default framing, the render settings and the checks that refuse unusable ones, the map from
//! world to the walks' cell space (OpenVDB's voxel-centre convention), the depth range, and the
//! stored and content boxes of a frame. It depends on the asset crate only (no thread pool, no
//! GPU), so an engine that links the runtime pulls in these definitions and not the tracer.
//!
//! The exact meaning of every mode and setting is `vdbcook-trace`'s crate documentation: the
//! GPU shaders follow the same definitions.

// `!(a > b)` is how this crate refuses NaN along with the ordered case; keep that form.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod camera;
mod content;
mod diffusion;
mod display;
mod emission;
mod fire;
mod footprint;
mod light;
mod settings;
mod space;

pub use camera::{from_up_frame, source_up, stored_bbox, stored_boxes, up_frame, Basis, Camera};
pub use content::{
    box_union, content_box, content_box_above, for_each_slot_max, for_each_slot_max_c, light_span,
};
pub use diffusion::{
    ms_beam_norm, ms_gather_dirs, ms_gather_steps, ms_gather_weights, ms_levels, ms_own_cell,
    ms_stored_flux, ms_sweeps, ms_vacuum_face, ms_vacuum_shape, transport_density, DiffusionInputs,
    GatherStep, MS_COARSEST, MS_FINE_SWEEPS, MS_FLUX_RATIO, MS_GATHER_MIN_TRANS, MS_GATHER_WEIGHTS,
    MS_ITERATIONS, MS_SHARED_PATHS, MS_VACUUM,
};
pub use display::{
    linear_to_srgb8, srgb_decode, srgb_encode, srgb_to_linear, Display, Tonemap,
    PBR_NEUTRAL_DESATURATION, PBR_NEUTRAL_START,
};
pub use emission::{blackbody_rgb, blackbody_table, blackbody_xyz, Emission, BLACKBODY_TABLE_LEN};
pub use fire::{
    channel_max, channel_named, fire_convention, fire_intensity, FireConvention, DRAPER_KELVIN,
    FIRE_DEPTH, FIRE_RADIANCE, FLAME_FULL, FLAME_KELVIN, FLAME_NAMES, HEAT_NAMES, KELVIN_MIN_MAX,
    KELVIN_PER_UNIT,
};
pub use footprint::{level_start, pixel_angle};
pub use light::{
    light_dirs, near_scatter_source, octave_source, phase, phase_mean_cos, sky_diffusion,
    sky_source, sun_pass_stop, LevelChain, LightGrid, LIT_NEAR_DEPTH, LIT_NEAR_MAX_VOXELS,
    LIT_NEAR_TRANS, MAX_SUB,
};
pub use settings::{
    Filter, Integrator, LengthUnit, Lighting, March, Medium, Mode, MsModel, Output, RenderSettings,
    TraceError, DEFAULT_NEAR_SCATTER, DEFAULT_SUN_NEAR, LIT_VOXEL_DEPTH, MAX_BOUNCES,
    MAX_LIGHT_RES, MAX_MS_GATHER, MAX_MS_OCTAVES, MAX_MS_SKY, MAX_PHASE_G, MAX_SIDE, MAX_SPP,
    MAX_SUN_NEAR, MIN_STEP,
};
pub use space::{depth_range, length, mul3, normalize, Affine};
