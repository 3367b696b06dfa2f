//! Why the runtime refused something: a frame out of range, settings or a camera that would make
//! a loop unbounded or a pixel NaN, a transform it cannot invert, an asset beyond the adapter's
//! limits, a target it cannot draw into, a mode not implemented on the GPU yet, a budget too small, or a
//! volume swapped into pipelines built for another layout.

use std::fmt;

#[derive(Debug, Clone, PartialEq)]
pub enum RuntimeError {
    /// The frame index is not in the asset.
    Frame { frame: usize, frames: usize },
    /// A setting out of its range (named).
    Setting(String),
    /// The camera is degenerate.
    Camera(String),
    /// `index_to_world` is not affine or cannot be inverted.
    Transform(String),
    /// The asset does not fit the device's limits.
    Limits(String),
    /// The target does not suit this renderer.
    Target(String),
    /// The mode is not implemented on the GPU yet.
    Unsupported(String),
    /// A streaming byte budget too small for what was asked (one frame, or a window).
    Budget(String),
    /// `rebind` was given a volume the renderer's pipelines cannot read.
    Rebind(String),
}

impl fmt::Display for RuntimeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RuntimeError::Frame { frame, frames } => {
                write!(
                    f,
                    "frame {frame} is not in the asset ({frames} frames: 0..{frames})"
                )
            }
            RuntimeError::Setting(m) => write!(f, "bad render setting: {m}"),
            RuntimeError::Camera(m) => write!(f, "bad camera: {m}"),
            RuntimeError::Transform(m) => write!(f, "unusable index_to_world: {m}"),
            RuntimeError::Limits(m) => write!(f, "asset exceeds the device limits: {m}"),
            RuntimeError::Target(m) => write!(f, "bad render target: {m}"),
            RuntimeError::Unsupported(m) => write!(f, "not supported by the GPU runtime: {m}"),
            RuntimeError::Budget(m) => write!(f, "streaming budget too small: {m}"),
            RuntimeError::Rebind(m) => write!(f, "cannot rebind: {m}"),
        }
    }
}

impl std::error::Error for RuntimeError {}

/// The CPU tracer's refusals (settings, camera, transform, frame) are the runtime's too.
impl From<vdbcook_scene::TraceError> for RuntimeError {
    fn from(e: vdbcook_scene::TraceError) -> Self {
        use vdbcook_scene::TraceError as T;
        match e {
            T::Frame { frame, frames } => RuntimeError::Frame { frame, frames },
            T::Setting(m) => RuntimeError::Setting(m),
            T::Transform(m) => RuntimeError::Transform(m),
            T::Camera(m) => RuntimeError::Camera(m),
        }
    }
}
