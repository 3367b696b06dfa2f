//! The render world's side of the plugin: what is extracted each frame (the instances, the sun
//! and sky, the shading, each volume camera's settings), the upload of each asset (a Bevy
//! render asset over the runtime's one uploader, `GpuVolume::upload`), and the depth usage the
//! drawer needs on volume cameras. The draw itself is in `draw.rs`.

use std::sync::Arc;

use bevy::asset::AssetId;
use bevy::ecs::query::QueryItem;
use bevy::ecs::system::lifetimeless::SRes;
use bevy::ecs::system::SystemParamItem;
use bevy::prelude::*;
use bevy::render::extract_component::ExtractComponent;
use bevy::render::render_asset::{PrepareAssetError, RenderAsset};
use bevy::render::render_resource::TextureUsages;
use bevy::render::renderer::{RenderDevice, RenderQueue};
use bevy::render::sync_component::SyncComponent;
use bevy::render::Extract;
use vdbcook_runtime::{fire_convention, glam as rt, Emission, GpuVolume};

use crate::asset::VdbAsset;
use crate::component::{VdbPlayback, VdbVolume, VolumeCamera, VolumeEmission, VolumeShading};
use crate::convert::{self, SceneLight};
use crate::playback::{drawn_time, playing};

/// One instance as the draw needs it, in the runtime's terms.
#[derive(Clone, Debug)]
pub struct ExtractedVolume {
    pub asset: AssetId<VdbAsset>,
    pub world_from_volume: rt::Affine3A,
    /// The drawn frame time (`playback::drawn_time`).
    pub time: f32,
    pub density_scale: f32,
    pub tint: rt::Vec3,
    pub emission: VolumeEmission,
    pub emission_scale: f32,
    /// Whether its flip-book moves (`playback::playing`): its light may then come from every
    /// n-th frame (`VolumeCamera::light_stride`).
    pub playing: bool,
}

/// This frame's visible instances (rebuilt every frame: instances cost no render entities).
#[derive(Resource, Default)]
pub struct ExtractedVolumes(pub Vec<ExtractedVolume>);

/// This frame's sun (the brightest visible `DirectionalLight`) and global ambient light.
#[derive(Resource, Default, Clone, Copy)]
pub struct ExtractedSceneLight(pub SceneLight);

/// The main world's [`VolumeShading`], copied each frame.
#[derive(Resource, Default, Clone)]
pub struct ExtractedShading(pub VolumeShading);

/// A volume camera's settings and its own ambient light (`AmbientLight` on the camera overrides
/// the global one), on the camera's render entity.
#[derive(Component, Clone, Debug)]
pub struct ExtractedVolumeCamera {
    pub settings: VolumeCamera,
    pub sky: Option<[f32; 3]>,
}

impl SyncComponent for VolumeCamera {
    type Target = ExtractedVolumeCamera;
}

impl ExtractComponent for VolumeCamera {
    type QueryData = (&'static VolumeCamera, Option<&'static AmbientLight>);
    type QueryFilter = ();
    type Out = ExtractedVolumeCamera;

    fn extract_component(
        (settings, ambient): QueryItem<'_, '_, Self::QueryData>,
    ) -> Option<Self::Out> {
        Some(ExtractedVolumeCamera {
            settings: *settings,
            sky: ambient.map(|a| convert::linear(a.color, a.brightness)),
        })
    }
}

/// Copies the instances whose entity is visible and whose asset is loaded.
pub fn extract_volumes(
    mut out: ResMut<ExtractedVolumes>,
    assets: Extract<Res<Assets<VdbAsset>>>,
    volumes: Extract<
        Query<(
            &VdbVolume,
            &VdbPlayback,
            &GlobalTransform,
            &InheritedVisibility,
        )>,
    >,
) {
    out.0.clear();
    for (volume, playback, transform, visible) in &volumes {
        if !visible.get() {
            continue;
        }
        let Some(asset) = assets.get(&volume.asset) else {
            continue;
        };
        let placed = if volume.upright {
            transform.mul_transform(Transform::from_rotation(asset.upright()))
        } else {
            *transform
        };
        out.0.push(ExtractedVolume {
            asset: volume.asset.id(),
            world_from_volume: convert::affine(&placed),
            time: drawn_time(playback, asset.frame_count()),
            density_scale: volume.density_scale,
            tint: rt::Vec3::from_array(volume.tint.to_array()),
            emission: volume.emission.clone(),
            emission_scale: volume.emission_scale,
            playing: playing(playback, asset.frame_count()),
        });
    }
}

/// Copies the brightest visible sun, the global ambient light and the shading.
pub fn extract_scene_light(
    mut light: ResMut<ExtractedSceneLight>,
    mut shading: ResMut<ExtractedShading>,
    suns: Extract<Query<(&DirectionalLight, &GlobalTransform, &ViewVisibility)>>,
    ambient: Extract<Option<Res<GlobalAmbientLight>>>,
    main_shading: Extract<Res<VolumeShading>>,
) {
    let sun = suns
        .iter()
        .filter(|(_, _, v)| v.get())
        .map(|(l, t, _)| (t.back().to_array(), convert::linear(l.color, l.illuminance)))
        .max_by(|a, b| {
            let sum = |c: &[f32; 3]| c.iter().sum::<f32>();
            sum(&a.1).total_cmp(&sum(&b.1))
        });
    let sky = ambient
        .as_ref()
        .map_or([0.0; 3], |a| convert::linear(a.color, a.brightness));
    light.0 = SceneLight { sun, sky };
    if shading.0 != **main_shading {
        shading.0 = (**main_shading).clone();
    }
}

/// Volume cameras' depth gets `TEXTURE_BINDING` (the drawer reads it), as Bevy does for its own
/// passes that read depth; runs before Bevy makes the depth textures.
pub fn configure_volume_depth(mut cameras: Query<&mut Camera3d, With<ExtractedVolumeCamera>>) {
    for mut camera in &mut cameras {
        camera.depth_texture_usages.0 |= TextureUsages::TEXTURE_BINDING.bits();
    }
}

/// An uploaded asset: the runtime's volume (or why the upload failed: the error is logged once
/// and the asset is not drawn, rather than retried every frame), the emission its channels call
/// for, and a generation that tells a re-upload (a reloaded file) from the volume before it.
pub struct GpuVdbVolume {
    pub volume: Result<Arc<GpuVolume>, String>,
    pub auto_emission: Option<Emission>,
    pub generation: u64,
    /// Per frame, the centre of what it stores in the asset's world (the draws' far-to-near
    /// order between assets).
    pub centres: Vec<rt::Vec3>,
}

impl GpuVdbVolume {
    /// The content centre of the frame shown at `time` (the asset's world; its origin where
    /// the frame is empty or unknown).
    pub fn content_centre(&self, time: f32) -> rt::Vec3 {
        let f = (time.max(0.0) as usize).min(self.centres.len().saturating_sub(1));
        self.centres.get(f).copied().unwrap_or(rt::Vec3::ZERO)
    }
}

impl RenderAsset for GpuVdbVolume {
    type SourceAsset = VdbAsset;
    type Param = (SRes<RenderDevice>, SRes<RenderQueue>);

    fn byte_len(asset: &VdbAsset) -> Option<usize> {
        Some(asset.0.payloads.iter().map(Vec::len).sum())
    }

    fn prepare_asset(
        asset: VdbAsset,
        _id: AssetId<VdbAsset>,
        (device, queue): &mut SystemParamItem<Self::Param>,
        _previous: Option<&Self>,
    ) -> Result<Self, PrepareAssetError<VdbAsset>> {
        use std::sync::atomic::{AtomicU64, Ordering};
        static GENERATION: AtomicU64 = AtomicU64::new(0);
        let volume = GpuVolume::upload(device.wgpu_device(), queue, &asset.0)
            .map(Arc::new)
            .map_err(|e| {
                log::error!("vdbcook: the volume could not be uploaded, it will not be drawn: {e}");
                e.to_string()
            });
        let cells = vdbcook_scene::Affine::cells(&asset.0.header.index_to_world).ok();
        let centres = match (&volume, cells) {
            (Ok(v), Some(cells)) => (0..v.frame_count())
                .map(|f| {
                    v.frame_bbox(f).map_or(rt::Vec3::ZERO, |(lo, hi)| {
                        let c = cells.world_of([0, 1, 2].map(|i| 0.5 * (lo[i] + hi[i])));
                        rt::Vec3::from_array(c.map(|x| x as f32))
                    })
                })
                .collect(),
            _ => Vec::new(),
        };
        Ok(GpuVdbVolume {
            volume,
            auto_emission: fire_convention(&asset.0, None).map(|f| f.emission),
            generation: GENERATION.fetch_add(1, Ordering::Relaxed),
            centres,
        })
    }
}
