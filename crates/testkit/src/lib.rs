//! The test kit: helpers the vdbcook crates' tests share, in one place instead of a copy per
//! crate (issue 17). Dev-only (`publish = false`, only ever a `[dev-dependencies]` entry):
//!
//! - [`XorShift`]: the seeded xorshift64* every test draws its random content from;
//! - [`repo_root`] / [`fixtures`]: where the repository and its `fixtures/` are;
//! - hand-built assets ([`build`], [`build_mixed`], [`random_frame`], [`blob_frame`],
//!   transforms) on top of [`vdbcook_asset::builder`], plus what only tests want: seeded
//!   BC4/BC7 noise bricks;
//! - with the `gpu` feature, [`gpu::open_device`]: a wgpu device on whatever adapter exists,
//!   honouring `VDBCOOK_REQUIRE_GPU`.

mod assets;
#[cfg(all(feature = "gpu29", not(feature = "gpu")))]
extern crate wgpu29 as wgpu;
#[cfg(any(feature = "gpu", feature = "gpu29"))]
pub mod gpu;
mod paths;
mod rng;

pub use assets::*;
pub use paths::*;
pub use rng::XorShift;
