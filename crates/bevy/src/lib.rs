//! `vdbcook-bevy`: vdbcook flip-book volumes (`.vdbc`) in a Bevy 3D scene. Add [`VdbPlugin`],
//! put [`VolumeCamera`] on the `Camera3d`s that should draw volumes, and spawn
//! [`VdbVolume`]s: they play with Bevy's clock, are drawn after Bevy's opaque pass against its
//! depth (reversed Z, TAA jitter followed), and are lit by the scene's brightest
//! `DirectionalLight` and its ambient light in Bevy's units and exposure. The march, the light
//! and the composite are `vdbcook_runtime`'s `VolumeDrawer`, on Bevy's own device.
//! `docs/bevy.md` walks through it.
//!
//! ```no_run
//! use bevy::prelude::*;
//! use vdbcook_bevy::{VdbPlugin, VdbVolume, VolumeCamera};
//!
//! fn setup(mut commands: Commands, assets: Res<AssetServer>) {
//!     commands.spawn((Camera3d::default(), bevy::camera::Hdr, VolumeCamera::default(),
//!                     Transform::from_xyz(0.0, 50.0, 200.0).looking_at(Vec3::ZERO, Vec3::Y)));
//!     commands.spawn(DirectionalLight::default());
//!     commands.spawn(VdbVolume::new(assets.load("smoke.vdbc")));
//! }
//! App::new().add_plugins((DefaultPlugins, VdbPlugin)).add_systems(Startup, setup).run();
//! ```
//!
//! The runtime is compiled against Bevy 0.19's wgpu (29): `docs/decisions.md` §12.

mod asset;
mod component;
mod convert;
mod draw;
mod playback;
mod render;

use bevy::core_pipeline::core_3d::prepare_core_3d_depth_textures;
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::prelude::*;
use bevy::render::extract_component::ExtractComponentPlugin;
use bevy::render::render_asset::RenderAssetPlugin;
use bevy::render::{ExtractSchedule, Render, RenderApp, RenderSystems};

pub use asset::{VdbAsset, VdbLoadError, VdbLoader, VdbLoaderSettings};
pub use component::{
    FrameBlend, PlayMode, VdbPlayback, VdbVolume, VolumeCamera, VolumeEmission, VolumeShading,
};
pub use convert::SceneLight;
pub use playback::{advance, drawn_time};
pub use render::GpuVdbVolume;
/// The runtime this plugin draws with (its `Medium`, `Lighting`, `Emission`, … configure
/// [`VolumeShading`] and [`VolumeEmission`]).
pub use vdbcook_runtime;

/// The plugin: the `.vdbc` loader, playback, extraction, upload and the volume pass.
#[derive(Default)]
pub struct VdbPlugin;

/// The plugin's systems in the main world (`Update`): playback advances here.
#[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub struct VdbSystems;

/// The volume pass in Bevy's `Core3d` schedule (after `Core3dSystems::MainPass`, before
/// `Core3dSystems::EarlyPostProcess`): order a pass of your own against it.
#[derive(SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub struct VdbPass;

impl Plugin for VdbPlugin {
    fn build(&self, app: &mut App) {
        app.init_asset::<VdbAsset>()
            .register_asset_loader(VdbLoader)
            .init_resource::<VolumeShading>()
            .add_plugins((
                ExtractComponentPlugin::<VolumeCamera>::default(),
                RenderAssetPlugin::<GpuVdbVolume>::default(),
            ))
            .add_systems(Update, playback::advance_playback.in_set(VdbSystems));

        let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
            return;
        };
        render_app
            .init_resource::<render::ExtractedVolumes>()
            .init_resource::<render::ExtractedSceneLight>()
            .init_resource::<render::ExtractedShading>()
            .init_resource::<draw::VolumeDrawers>()
            .init_resource::<draw::ViewVolumeDraws>()
            .add_systems(
                ExtractSchedule,
                (render::extract_volumes, render::extract_scene_light),
            )
            .add_systems(
                Render,
                (
                    render::configure_volume_depth
                        .in_set(RenderSystems::Prepare)
                        .before(prepare_core_3d_depth_textures),
                    draw::prepare_volume_draws.in_set(RenderSystems::PrepareBindGroups),
                ),
            )
            .add_systems(
                Core3d,
                draw::volume_pass
                    .in_set(VdbPass)
                    .after(Core3dSystems::MainPass)
                    .before(Core3dSystems::EarlyPostProcess),
            );
    }
}
