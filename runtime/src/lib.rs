//! `vdbcook-runtime`: the thin wgpu runtime of the flip-book asset. An engine owns the device,
//! the queue, the command encoder and the target; this crate uploads an [`Asset`] once
//! ([`GpuVolume::upload`]: every frame's tree and the whole brick pool), builds a [`Renderer`]
//! once (pipeline, bind groups), and then records one compute dispatch per render of
//! `(frame, camera, settings)` into the caller's encoder. Switching frames is one uniform
//! write: nothing is re-uploaded and no pipeline or bind group is created.
//!
//! The WGSL lives in `shaders/` (the one source) and is exposed here: [`VOLUME_WGSL`] (bindings,
//! tree access L1 → L2 → L3 → brick with the node masks, `vdb_value`, the bounded DDA) for an
//! engine's own shaders, and [`TRACE_WGSL`] (the tracer's compute entry point).
//!
//! The images are defined by the CPU reference tracer (`crates/trace`, its crate docs): the GPU
//! follows the same spaces, DDA rules, skip rules and colour maps in f32, and
//! `tests/gpu_vs_cpu.rs` compares the two. The camera, mode, length unit, settings (with their
//! validation), transform and framing are the tracer's own types, re-exported here. Every mode is
//! implemented ([`GPU_MODES`]): density, depth, first-hit density, brick hue, steps, single
//! scatter (the shadow march is a second bounded walk: WGSL has no recursion) and delta tracking
//! (the CPU's PCG stream per (seed, pixel, sample), so the images agree statistically; f32 free
//! flights make a few paths branch differently from the CPU's f64 ones).
//!
//! Brick payload on the GPU (see [`PayloadLayout`]): every brick is decoded on the CPU at upload
//! (`Asset::decode_brick`, so BC4/BC7/unorm8 bricks arrive exactly as the CPU sampler reads
//! them) into f32 storage buffers, or packed f16 pairs when every brick is f16 (bit exact) or
//! when f32 would not fit. Native BC / unorm8 textures are a later step.
//!
//! Submission rule: `render` writes the parameters with `Queue::write_buffer`, which takes
//! effect at the next `submit`; record at most one render per renderer per submission.

// `!(a > b)` refuses NaN along with the ordered case (as in the CPU tracer); keep that form.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod camera;
mod error;
mod render;
mod upload;

pub use camera::{Camera, LengthUnit, Mode, Settings, GPU_MODES};
pub use error::RuntimeError;
pub use render::{BufferTarget, Readback, Renderer, TextureTarget};
pub use upload::{GpuVolume, PayloadLayout};
pub use vdbcook_asset::Asset;

/// Bindings of an uploaded volume (group 0), tree access, sampling and the DDA.
pub const VOLUME_WGSL: &str = include_str!("../../shaders/volume.wgsl");
/// The tracer (groups 1 and 2, entry point `trace_main`); needs [`VOLUME_WGSL`] before it.
pub const TRACE_WGSL: &str = include_str!("../../shaders/trace.wgsl");

/// Result of the runtime's calls.
pub type Result<T> = std::result::Result<T, RuntimeError>;
