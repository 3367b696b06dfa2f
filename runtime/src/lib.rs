//! `vdbcook-runtime`: the thin wgpu runtime of the flip-book asset. An engine owns the device,
//! the queue, the command encoder and the target; this crate uploads an [`Asset`] once
//! ([`GpuVolume::upload`]: every frame's tree and the whole brick pool; or a window of frames
//! under a byte budget with [`StreamingVolume`], which uploads only the bricks a moved window
//! newly uses), builds a [`Renderer`]
//! once (pipeline, bind groups), and then records one compute dispatch per render of
//! `(frame, camera, settings)` into the caller's encoder. Switching frames is one uniform
//! write: nothing is re-uploaded and no pipeline or bind group is created.
//!
//! The WGSL lives in `shaders/` (the one source) and is exposed here: [`VOLUME_WGSL`] (bindings,
//! tree access L1 → L2 → L3 → brick with the node masks, `vdb_value`, the bounded DDA) for an
//! engine's own shaders — [`volume_wgsl`] puts its bindings in the bind group the engine chooses,
//! and its `vdb_sample(world_to_index, world_pos, time)` ([`world_to_index`]) samples an instance
//! with a flip-book crossfade — and [`TRACE_WGSL`] (the tracer's compute entry point).
//!
//! The images are defined by the CPU reference tracer (`crates/trace`, its crate docs): the GPU
//! follows the same spaces, DDA rules, skip rules and colour maps in f32, and
//! `tests/gpu_vs_cpu.rs` compares the two. The camera, mode, length unit, settings (with their
//! validation), transform and framing are the tracer's own types, re-exported here. Every mode is
//! implemented ([`GPU_MODES`]): density, depth, first-hit density, brick hue, steps, single
//! scatter (the shadow march is a second bounded walk: WGSL has no recursion) and delta tracking
//! (the CPU's PCG stream per (seed, pixel, sample), so the images agree statistically; f32 free
//! flights make a few paths branch differently from the CPU's f64 ones), and lit (a light-volume
//! pass, `shaders/light_build.wgsl`, recorded ahead of the trace when the frame, the light or
//! the medium changed; the march reads it through group 3).
//!
//! Brick payload on the GPU (see [`PayloadLayout`], [`Layout`] and `upload.rs`): the quantized
//! formats stay quantized — BC4/BC7 bricks as BC textures (3D with
//! `TEXTURE_COMPRESSION_BC_SLICED_3D`, else 2D arrays with `TEXTURE_COMPRESSION_BC`), unorm8
//! bricks as `R8Unorm` textures — and the shader reads one texel per voxel (`textureLoad`, the
//! nearest voxel as on the CPU) and dequantizes it with the brick's `[lo, hi]`. Without BC
//! support the BC bricks are decoded at upload (the asset's decoder) into `R8Unorm` /
//! `Rgba8Unorm` textures; f16/f32 bricks live in storage buffers. [`GpuVolume::upload`] picks
//! the first layout the device's features and limits allow and logs it; request
//! [`OPTIONAL_FEATURES`] on the device to let it use BC; [`GpuVolume::upload_with`] can force one.
//! An engine's own pipelines over [`VOLUME_WGSL`] should pass [`GpuVolume::pipeline_constants`]
//! (the read paths the volume uses) so the others compile away.
//!
//! Engines: [`VolumeDrawer`] draws any number of [`Instance`]s of an uploaded volume into the
//! engine's own frame — its [`View`] (view and projection matrices), its depth buffer, blended
//! over its colour target — recording into its encoder; `docs/engine.md` walks through it.
//!
//! Submission rule (`Renderer` only; the drawer writes nothing through the queue): `render` writes the parameters with `Queue::write_buffer`, which takes
//! effect at the next `submit`; record at most one render per renderer per submission.

// `!(a > b)` refuses NaN along with the ordered case (as in the CPU tracer); keep that form.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

// The wgpu line: `wgpu30` (default, the dependency named `wgpu`) or `wgpu29` (renamed here).
#[cfg(all(feature = "wgpu29", not(feature = "wgpu30")))]
pub extern crate wgpu29 as wgpu;
#[cfg(not(any(feature = "wgpu29", feature = "wgpu30")))]
compile_error!("vdbcook-runtime needs feature `wgpu30` (default) or `wgpu29`");

mod camera;
mod draw;
mod error;
#[doc(hidden)]
pub mod gpu_compat;
#[cfg(test)]
mod layout_check;
mod light;
mod render;
mod shading;
mod timer;
mod upload;
mod wgsl;

pub use camera::{Camera, LengthUnit, Mode, Settings, GPU_MODES};
pub use draw::{
    DrawTarget, Instance, Interleave, LitCrossfade, MarchResolution, PreparedDraw, Shading,
    SunShadows, View, ViewRays, VolumeDrawer, COMPOSITE_WGSL, DRAW_COLOR_FORMATS,
    DRAW_DEPTH_FORMATS, DRAW_WGSL,
};
pub use error::RuntimeError;
/// The math types of [`View`] and [`Instance`], and the wgpu this crate records with: use these
/// to be sure of matching versions.
pub use glam;
pub use light::LightBuilds;
pub use render::{BufferTarget, Readback, Renderer, TextureTarget};
pub use timer::GpuTimer;
pub use upload::stream::{StreamingVolume, WindowStats};
pub use upload::{
    BufferLayout, GpuVolume, Layout, PayloadLayout, TextureGroup, UploadOptions, MAX_ASSETS,
    OPTIONAL_FEATURES,
};
pub use vdbcook_asset::{Asset, AssetError};
pub use vdbcook_scene::{
    fire_convention, Display, Emission, Filter, FireConvention, Integrator, Lighting, March,
    Medium, MsModel, Output, RenderSettings,
};
#[cfg(feature = "wgpu30")]
pub use wgpu;
pub use wgsl::{shadow_wgsl, volume_wgsl, world_to_index};

/// Bindings of an uploaded volume (group 0), tree access, sampling and the DDA.
pub const VOLUME_WGSL: &str = include_str!("../../shaders/volume.wgsl");
/// The tracer (groups 1, 2 and 3, entry point `trace_main`); needs [`VOLUME_WGSL`] and
/// [`LIGHT_WGSL`] before it.
pub const TRACE_WGSL: &str = include_str!("../../shaders/trace.wgsl");

/// The lit mode's light-volume lookup and octave source (no bindings); the tracer and the
/// light-volume pass include it.
pub const LIGHT_WGSL: &str = include_str!("../../shaders/light.wgsl");
/// The lit march's light, written once for the tracer and the drawer (`VdbShading`,
/// `VdbLitPlace`, `lit_scattered`); needs [`VOLUME_WGSL`] and [`LIGHT_WGSL`] before it, and its
/// `{{LIT_GROUP}}` and `{{SHADING}}` replaced by the includer.
pub const LIT_WGSL: &str = include_str!("../../shaders/lit.wgsl");
/// The lit mode's light-volume passes (group 0 the volume, group 1 their uniform and buffers;
/// entry points `lv_density_main`, `lv_sun_main`, `lv_axis0_main`, `lv_axis1_main`,
/// `lv_axis2_main`, `lv_sky_main`, in that order); needs [`VOLUME_WGSL`] and [`LIGHT_WGSL`]
/// before it.
pub const LIGHT_BUILD_WGSL: &str = include_str!("../../shaders/light_build.wgsl");

/// The colour pipeline (`vdbcook_scene::Display`) for an engine's or a viewer's final pass:
/// `display_map(radiance, scale, curve) -> vec3<f32>` (exposure already folded into `scale` =
/// `Display::scale()`, `curve` = `Tonemap::code()`), `display_srgb_encode`, `display_srgb_decode`.
pub const DISPLAY_WGSL: &str = include_str!("../../shaders/display.wgsl");
/// The sun's transmittance through a drawer's lit volumes for an engine's shaders (group 0,
/// `vdb_sun_transmittance`); use [`shadow_wgsl`], which puts [`LIGHT_WGSL`] before it.
pub const SHADOW_WGSL: &str = include_str!("../../shaders/shadow.wgsl");

/// Result of the runtime's calls.
pub type Result<T> = std::result::Result<T, RuntimeError>;
