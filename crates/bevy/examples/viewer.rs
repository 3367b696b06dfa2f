//! An interactive window on a `.vdbc` in a Bevy scene (ground, a box, sun, sky), loaded through
//! Bevy's asset server with the plugin's loader.
//!
//! `cargo run --release -p vdbcook-bevy --features viewer --example viewer -- ASSET.vdbc`
//!
//! Mouse: drag to orbit, wheel to zoom. Keys: Space play/pause, Up/Down speed ×2/÷2,
//! L lit/flat, M march resolution (full, half, quarter), T TAA on/off, H hold/crossfade frames.

use std::path::PathBuf;

use bevy::anti_alias::taa::TemporalAntiAliasing;
use bevy::camera::Hdr;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll};
use bevy::prelude::*;
use vdbcook_bevy::vdbcook_runtime::MarchResolution;
use vdbcook_bevy::{
    FrameBlend, VdbAsset, VdbPlayback, VdbPlugin, VdbVolume, VolumeCamera, VolumeShading,
};

#[derive(Resource)]
struct Viewer {
    asset: Handle<VdbAsset>,
    framed: bool,
    /// Orbit: yaw and pitch (radians) and distance around `centre`.
    yaw: f32,
    pitch: f32,
    distance: f32,
    centre: Vec3,
}

fn main() {
    let Some(path) = std::env::args().nth(1).map(PathBuf::from) else {
        eprintln!("usage: viewer ASSET.vdbc");
        std::process::exit(2);
    };
    let path = std::fs::canonicalize(&path).unwrap_or_else(|e| {
        eprintln!("{}: {e}", path.display());
        std::process::exit(1);
    });
    let dir = path.parent().unwrap().display().to_string();
    let file = path.file_name().unwrap().to_string_lossy().into_owned();
    App::new()
        .add_plugins((
            DefaultPlugins
                .set(AssetPlugin {
                    file_path: dir,
                    ..default()
                })
                .set(WindowPlugin {
                    primary_window: Some(Window {
                        title: format!("vdbcook viewer: {file}"),
                        ..default()
                    }),
                    ..default()
                }),
            VdbPlugin,
        ))
        .insert_resource(ClearColor(Color::srgb(0.6, 0.7, 0.9)))
        .insert_resource(GlobalAmbientLight {
            color: Color::srgb(0.6, 0.7, 0.9),
            brightness: 400.0,
            ..default()
        })
        .add_systems(
            Startup,
            move |mut commands: Commands, server: Res<AssetServer>| {
                commands.insert_resource(Viewer {
                    asset: server.load(file.clone()),
                    framed: false,
                    yaw: 0.25,
                    pitch: 0.33,
                    distance: 10.0,
                    centre: Vec3::ZERO,
                });
                commands.spawn((
                    Camera3d::default(),
                    Hdr,
                    Tonemapping::AcesFitted,
                    VolumeCamera::default(),
                    Transform::from_xyz(0.0, 3.0, 10.0).looking_at(Vec3::ZERO, Vec3::Y),
                ));
                commands.spawn((
                    DirectionalLight {
                        illuminance: 10_000.0,
                        ..default()
                    },
                    Transform::from_xyz(0.4, 0.8, 0.3).looking_at(Vec3::ZERO, Vec3::Y),
                ));
            },
        )
        .add_systems(Update, (frame_when_loaded, orbit, keys))
        .run();
}

/// Once the asset is loaded: the volume, a ground under it, a box beside it, the camera around it.
fn frame_when_loaded(
    mut commands: Commands,
    mut viewer: ResMut<Viewer>,
    assets: Res<Assets<VdbAsset>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    if viewer.framed {
        return;
    }
    let Some(asset) = assets.get(&viewer.asset) else {
        return;
    };
    viewer.framed = true;
    let (lo, hi) = asset
        .world_bounds()
        .unwrap_or((Vec3::splat(-1.0), Vec3::ONE));
    let (centre, extent) = (0.5 * (lo + hi), hi - lo);
    let radius = 0.5 * extent.length();
    viewer.centre = centre;
    viewer.distance = 2.5 * radius;
    commands.spawn(VdbVolume::new(viewer.asset.clone()));
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(20.0 * radius, 20.0 * radius))),
        MeshMaterial3d(materials.add(Color::srgb(0.42, 0.45, 0.38))),
        Transform::from_xyz(centre.x, lo.y - 0.02 * extent.y, centre.z),
    ));
    let side = 0.3 * radius;
    commands.spawn((
        Mesh3d(meshes.add(Cuboid::new(side, side, side))),
        MeshMaterial3d(materials.add(Color::srgb(0.62, 0.2, 0.16))),
        Transform::from_xyz(
            centre.x + 0.8 * radius,
            lo.y + 0.5 * side,
            centre.z + 0.5 * radius,
        ),
    ));
}

fn orbit(
    mut viewer: ResMut<Viewer>,
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    mut cameras: Query<&mut Transform, With<VolumeCamera>>,
) {
    if buttons.pressed(MouseButton::Left) {
        viewer.yaw -= 0.005 * motion.delta.x;
        viewer.pitch = (viewer.pitch + 0.005 * motion.delta.y).clamp(-1.4, 1.4);
    }
    viewer.distance *= (1.0 - 0.1 * scroll.delta.y).clamp(0.5, 2.0);
    let v = &*viewer;
    let dir = Vec3::new(
        v.yaw.sin() * v.pitch.cos(),
        v.pitch.sin(),
        v.yaw.cos() * v.pitch.cos(),
    );
    for mut t in &mut cameras {
        *t = Transform::from_translation(v.centre + dir * v.distance).looking_at(v.centre, Vec3::Y);
    }
}

fn keys(
    mut commands: Commands,
    keys: Res<ButtonInput<KeyCode>>,
    mut shading: ResMut<VolumeShading>,
    mut playback: Query<&mut VdbPlayback>,
    mut cameras: Query<(Entity, &mut VolumeCamera, Has<TemporalAntiAliasing>)>,
) {
    for mut p in &mut playback {
        if keys.just_pressed(KeyCode::Space) {
            p.paused = !p.paused;
        }
        if keys.just_pressed(KeyCode::ArrowUp) {
            p.speed *= 2.0;
        }
        if keys.just_pressed(KeyCode::ArrowDown) {
            p.speed *= 0.5;
        }
        if keys.just_pressed(KeyCode::KeyH) {
            p.blend = match p.blend {
                FrameBlend::Crossfade => FrameBlend::Hold,
                FrameBlend::Hold => FrameBlend::Crossfade,
            };
        }
    }
    if keys.just_pressed(KeyCode::KeyL) {
        shading.lit = !shading.lit;
    }
    for (e, mut camera, taa) in &mut cameras {
        if keys.just_pressed(KeyCode::KeyM) {
            camera.march_resolution = match camera.march_resolution {
                MarchResolution::Full => MarchResolution::Half,
                MarchResolution::Half => MarchResolution::Quarter,
                MarchResolution::Quarter => MarchResolution::Full,
            };
        }
        if keys.just_pressed(KeyCode::KeyT) {
            if taa {
                commands.entity(e).remove::<TemporalAntiAliasing>();
            } else {
                commands.entity(e).insert(TemporalAntiAliasing::default());
            }
        }
    }
}
