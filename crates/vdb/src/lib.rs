//! `vdbcook-vdb`: reads OpenVDB files exactly as OpenVDB does, for float (and double) grids.
//!
//! Written for vdbcook because vdb-rs 0.6 aborts on common files, drops root tiles and misreads
//! inactive values (see `docs/decisions.md`). Every length taken from a file is checked against
//! the bytes that remain before anything is allocated, so bad input is an error, never a panic.
//!
//! ```no_run
//! let file = vdbcook_vdb::VdbFile::open("smoke.vdb")?;
//! let idx = file.select(None)?; // `density`, else the only float grid
//! let grid = file.read_float_grid(idx)?;
//! println!("{} active voxels", grid.stats().active_voxels);
//! # Ok::<(), vdbcook_vdb::VdbError>(())
//! ```

mod cursor;
mod error;
mod file;
mod grid;
mod metadata;
pub mod sequence;
mod transform;
mod tree;

pub use error::{ErrorKind, VdbError};
pub use file::{compression_name, GridInfo, VdbFile, MAX_VERSION, MIN_VERSION};
pub use grid::{
    leaf_offset, leaf_voxel, FloatGrid, GridLookup, GridStats, Leaf, Tile, TileLevel, LEAF_DIM,
    LEAF_VOXELS,
};
pub use metadata::{MetaMap, MetaValue};
pub use transform::{Frustum, MapKind, Transform};
pub use tree::{CodeStats, COMPRESS_ACTIVE_MASK, COMPRESS_BLOSC, COMPRESS_ZIP, MAX_LEAVES};
