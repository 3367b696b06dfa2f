//! What a render is asked to do — the pinhole camera, the mode and the medium settings — and the
//! CPU-side math that turns them into the tracer's uniform. The vocabulary and the math are
//! shared with the CPU reference tracer through `vdbcook_scene` (`Camera` with its basis and
//! default framing, `Mode`, `LengthUnit`, `RenderSettings` and its validation, `Affine`,
//! `depth_range`), so that there is one definition and the same camera and settings give the same image on
//! both. This module adds only what is the GPU's own: which modes it implements.

pub use vdbcook_scene::{Camera, LengthUnit, Mode};

use crate::RuntimeError;
use vdbcook_scene::Output;

/// Everything but the camera: `vdbcook_scene::RenderSettings`. The runtime ignores its `width`,
/// `height` and `frame`: the target gives the image size and each render call the frame.
pub type Settings = vdbcook_scene::RenderSettings;

/// The modes the GPU tracer implements (all of `Mode::ALL` but the CPU-only `Mode::Reference`,
/// which is refused with [`RuntimeError::Unsupported`]), in the order of the shader's mode
/// numbers.
pub const GPU_MODES: [Mode; 8] = [
    Mode::Density,
    Mode::Depth,
    Mode::FirstHitDensity,
    Mode::BrickHue,
    Mode::Steps,
    Mode::SingleScatter,
    Mode::DeltaTracking,
    Mode::Lit,
];

/// The shader's mode number (`None`: not implemented on the GPU).
fn mode_code(mode: Mode) -> Option<u32> {
    GPU_MODES.iter().position(|m| *m == mode).map(|i| i as u32)
}

/// Validates `settings` for a `width × height` render of `frame` out of `frames` (the CPU
/// tracer's rules, with the size and frame of this render), then refuses modes the GPU does not
/// implement; returns the shader's mode number.
pub(crate) fn validate(
    settings: &Settings,
    width: u32,
    height: u32,
    frame: usize,
    frames: usize,
) -> Result<u32, RuntimeError> {
    Settings {
        output: Output {
            width,
            height,
            frame,
        },
        ..settings.clone()
    }
    .validate(frames)?;
    mode_code(settings.integrator.mode).ok_or_else(|| {
        RuntimeError::Unsupported(format!(
            "mode {:?} (GPU modes: {GPU_MODES:?})",
            settings.integrator.mode
        ))
    })
}
