//! The `.vdbc` asset in Bevy's asset system: a loader that parses and validates the file on
//! Bevy's asset task pool (off the frame), and the loaded asset, shared by `Arc` so that the
//! render world's copy of it costs nothing.

use std::sync::Arc;

use bevy::asset::io::Reader;
use bevy::asset::{AssetLoader, LoadContext};
use bevy::prelude::*;
use serde::{Deserialize, Serialize};

/// A loaded flip-book asset (`vdbcook cook … -o NAME.vdbc`): every frame of every channel,
/// parsed and validated. Load it with `asset_server.load("smoke.vdbc")`, or add one built in
/// memory with `Assets<VdbAsset>::add(VdbAsset::new(asset))`.
#[derive(Asset, TypePath, Clone)]
pub struct VdbAsset(pub Arc<vdbcook_runtime::Asset>);

impl VdbAsset {
    /// Wraps an asset read or built elsewhere.
    pub fn new(asset: vdbcook_runtime::Asset) -> VdbAsset {
        VdbAsset(Arc::new(asset))
    }

    /// Frames in the flip-book.
    pub fn frame_count(&self) -> usize {
        self.0.frame_count()
    }

    /// The rotation that turns the source's up axis (its header's `up`: Z for Blender's
    /// caches, Y for Houdini's and most others) to Bevy's +Y, as glTF exporters do for meshes:
    /// Z-up is turned −90° about X, X-up +90° about Z.
    pub fn upright(&self) -> Quat {
        match vdbcook_scene::source_up(&self.0) {
            [_, _, 1.0] => Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2),
            [1.0, _, _] => Quat::from_rotation_z(std::f32::consts::FRAC_PI_2),
            _ => Quat::IDENTITY,
        }
    }

    /// The world box of what any frame stores, as an upright [`crate::VdbVolume`] places it
    /// before its entity's transform (the asset's own placement, then [`VdbAsset::upright`]),
    /// or `None` for an empty flip-book: to frame a camera or place a volume.
    pub fn world_bounds(&self) -> Option<(Vec3, Vec3)> {
        let up = self.upright();
        // Cell space (voxel i is the cell [i, i + 1)) to world, as the drawer maps it.
        let cells = vdbcook_scene::Affine::cells(&self.0.header.index_to_world).ok()?;
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for f in 0..self.frame_count() {
            let Some((a, b)) = vdbcook_scene::stored_bbox(&self.0, f) else {
                continue;
            };
            for corner in 0..8 {
                let p = [0, 1, 2].map(|i| if corner >> i & 1 == 0 { a[i] } else { b[i] });
                let w = up * Vec3::from_array(cells.world_of(p).map(|v| v as f32));
                lo = lo.min(w);
                hi = hi.max(w);
            }
        }
        lo.is_finite().then_some((lo, hi))
    }
}

/// Reads `.vdbc` files into [`VdbAsset`]s.
#[derive(Default, TypePath)]
pub struct VdbLoader;

/// The loader has no settings (a `.vdbc` is already cooked for the GPU).
#[derive(Debug, Default, Clone, Serialize, Deserialize)]
pub struct VdbLoaderSettings {}

/// Why a `.vdbc` did not load: the read failed, or the bytes are not a valid asset (truncated,
/// corrupt, a newer format): the asset's own message says which.
#[derive(Debug)]
pub enum VdbLoadError {
    Io(std::io::Error),
    Asset(vdbcook_runtime::AssetError),
}

impl std::fmt::Display for VdbLoadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            VdbLoadError::Io(e) => write!(f, "reading the .vdbc failed: {e}"),
            VdbLoadError::Asset(e) => write!(f, "not a valid .vdbc asset: {e}"),
        }
    }
}

impl std::error::Error for VdbLoadError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            VdbLoadError::Io(e) => Some(e),
            VdbLoadError::Asset(e) => Some(e),
        }
    }
}

impl AssetLoader for VdbLoader {
    type Asset = VdbAsset;
    type Settings = VdbLoaderSettings;
    type Error = VdbLoadError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &VdbLoaderSettings,
        _load_context: &mut LoadContext<'_>,
    ) -> Result<VdbAsset, VdbLoadError> {
        let mut bytes = Vec::new();
        reader
            .read_to_end(&mut bytes)
            .await
            .map_err(VdbLoadError::Io)?;
        let asset = vdbcook_runtime::Asset::from_bytes(&bytes).map_err(VdbLoadError::Asset)?;
        Ok(VdbAsset::new(asset))
    }

    fn extensions(&self) -> &[&str] {
        &["vdbc"]
    }
}
