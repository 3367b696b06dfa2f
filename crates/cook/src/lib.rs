//! `vdbcook-cook`, the cooking library: OpenVDB sequences in, one flip-book asset out, through
//! one pipeline of stages — read and build (`build`), pool (`pool`, with `ingest` streaming the
//! frames through both), levels of detail (`lod`), cluster (`cluster`), budget (`budget`),
//! encode (`encode`, `bc4fit`, `bcenc`), assemble (`assemble`) and report (`report`) — where a single grid
//! is the one-channel case of several, so every option composes with every other.
//!
//! A program fills in [`CookOptions`] (typed: enums and numbers, no flags to parse), resolves its
//! inputs to frames ([`frames::resolve_frames`]) and calls [`cook`]; stages and notes go to the
//! [`ProgressSink`] of its [`Context`]; failures are [`CookError`] values whose kind says whose
//! fault they are. The `vdbcook` CLI, its batch manifest and its subcommands are one such
//! program. This crate depends on no CLI, GPU or windowing crate.

pub mod assemble;
pub mod bc4fit;
pub mod bcenc;
pub mod budget;
pub mod build;
pub mod cluster;
pub mod encode;
pub mod error;
pub mod frames;
pub mod grid_pick;
pub mod ingest;
pub mod lod;
pub mod nanovdb;
pub mod options;
pub mod pipeline;
pub mod pool;
pub mod progress;
pub mod report;

pub use bcenc::Bc7Quality;
pub use error::CookError;
pub use options::{Budget, Clustering, CookOptions, FrameRange, Grids, Levels, Lod};
pub use pipeline::{cook, cook_inputs, Context, Cooked};
pub use progress::ProgressSink;
pub use report::CookReport;
