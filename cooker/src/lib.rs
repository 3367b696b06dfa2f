//! The `vdbcook` library: the cooker that the `vdbcook` CLI (`main.rs`), its benches and tests,
//! and build tools call. Data flows one way through its stages — read (`vdbcook_vdb`), build
//! (`build`), dedup (`pool`), cluster (`cluster`), encode (`encode`, `bcenc`), write (`cook`,
//! `output`) — and each subcommand has its module (`cook`, `info`, `eval`, `inspect`, `render`,
//! `report`, `view`; `manifest`: batch cooking with a content-addressed cache). `docs/architecture.md` maps the crates and the invariants each keeps.
//!
//! Entry points for programs: [`cook::cook`] (a cook held in memory: the asset, its bytes and the
//! typed [`cook_report::CookReport`] that `cook --json` prints) with [`cook::Args`] (`Args::defaults` for the plain options). Errors are
//! [`errors::CliError`] values whose kind matches their cause.

pub mod bcenc;
pub mod build;
pub mod cluster;
pub mod cook;
pub mod cook_report;
pub mod encode;
pub mod errors;
pub mod eval;
pub mod gpu;
pub mod grid_pick;
pub mod info;
pub mod inspect;
pub mod lod;
pub mod manifest;
pub mod multi;
pub mod output;
pub mod pool;
pub mod progress;
pub mod render;
pub mod report;
pub mod size_budget;
pub mod view;
