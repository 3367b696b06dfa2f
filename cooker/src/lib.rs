//! The `vdbcook` CLI as a library: clap's flags, the batch manifest and one module per
//! subcommand (`cook`, `info`, `eval`, `inspect`, `render`, `report`, `view`; `manifest`: batch
//! cooking with a content-addressed cache; `output`: writing without losing data; `spell`: how
//! flags spell cook options). The cooking itself is the `vdbcook_cook` library — programs that
//! cook call `vdbcook_cook::cook` with typed `CookOptions` — and the GPU runtime is
//! `vdbcook_runtime`. `docs/architecture.md` maps the crates and the invariants each keeps.
//! Errors are [`errors::CliError`] values whose kind matches their cause.

pub mod bench;
pub mod cook;
pub mod errors;
pub mod eval;
pub mod gpu;
pub mod info;
pub mod inspect;
pub mod look;
pub mod manifest;
pub mod output;
pub mod render;
pub mod report;
pub mod spell;
pub mod view;

/// The cooking library's stages, under the names this crate's modules had before they moved
/// there (benches and tools use them).
pub use vdbcook_cook::{
    bc4fit, bcenc, build, cluster, encode, grid_pick, lod, pool, progress, report as cook_report,
};
