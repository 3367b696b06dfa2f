//! Renders a `.vdbc` headless in a Bevy scene and writes a PNG: a ground plane, a red cube in
//! front of part of the volume, the volume lit by a directional light and the ambient light, an
//! HDR camera (ACES tonemapping, no LUT needed). The frame is pumped by hand (no window, no
//! event loop), as Bevy's `externally_driven_headless_renderer` example does; the tests reuse
//! `Headless` and `spawn_scene`.
//!
//! `cargo run --release -p vdbcook-bevy --example screenshot -- ASSET.vdbc OUT.png [--no-volume]
//! [--frame F] [--size WxH] [--sun LUX] [--sky CD_PER_M2] [--time FRAMES]` (make an asset with `vdbcook cook fixtures/seq/smoke5 -o smoke5.vdbc`).

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::{Arc, Mutex};

use bevy::app::SubApps;
use bevy::asset::RenderAssetUsages;
use bevy::camera::{Hdr, RenderTarget};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::image::Image;
use bevy::prelude::*;
use bevy::render::render_resource::{
    Extent3d, PollType, TextureDimension, TextureFormat, TextureUsages,
};
use bevy::render::renderer::RenderDevice;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::render::RenderPlugin;
use bevy::window::ExitCondition;
use vdbcook_bevy::{VdbAsset, VdbPlayback, VdbPlugin, VdbVolume, VolumeCamera};

/// A Bevy app driven frame by frame, with the plugin, rendering into images.
pub struct Headless(pub SubApps);

impl Headless {
    /// Bevy's default plugins without a window (pipelines compiled when first used, so the
    /// first frame that needs one has it), the plugin, and `configure` run before `finish`.
    pub fn new(configure: impl FnOnce(&mut App)) -> Headless {
        let mut app = App::new();
        app.add_plugins((
            DefaultPlugins
                .set(WindowPlugin {
                    primary_window: None,
                    exit_condition: ExitCondition::DontExit,
                    ..default()
                })
                .set(RenderPlugin {
                    synchronous_pipeline_compilation: true,
                    ..default()
                }),
            VdbPlugin,
        ));
        configure(&mut app);
        app.finish();
        app.cleanup();
        Headless(std::mem::take(app.sub_apps_mut()))
    }

    pub fn world(&mut self) -> &mut World {
        self.0.main.world_mut()
    }

    /// One frame, waiting for the GPU to finish it.
    pub fn update(&mut self) {
        self.0.update();
        self.0
            .main
            .world()
            .resource::<RenderDevice>()
            .wgpu_device()
            .poll(PollType::Wait {
                submission_index: None,
                timeout: None,
            })
            .expect("the device finished the frame");
    }

    /// An sRGB 8-bit image to render into.
    pub fn target(&mut self, (width, height): (u32, u32)) -> Handle<Image> {
        let mut image = Image::new_uninit(
            Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            TextureDimension::D2,
            TextureFormat::Rgba8UnormSrgb,
            RenderAssetUsages::RENDER_WORLD,
        );
        image.texture_descriptor.usage |=
            TextureUsages::RENDER_ATTACHMENT | TextureUsages::COPY_SRC;
        self.world().resource_mut::<Assets<Image>>().add(image)
    }

    /// Renders frames until a screenshot of `target` comes back (a few frames: the capture is
    /// copied out after the frame it was asked in).
    pub fn capture(&mut self, target: &Handle<Image>) -> Image {
        let got = Arc::new(Mutex::new(None));
        let slot = got.clone();
        self.world()
            .spawn(Screenshot::image(target.clone()))
            .observe(move |c: On<ScreenshotCaptured>| {
                *slot.lock().unwrap() = Some(c.image.clone());
            });
        for _ in 0..10 {
            self.update();
            if let Some(image) = got.lock().unwrap().take() {
                return image;
            }
        }
        panic!("no screenshot after 10 frames");
    }
}

/// What [`spawn_scene`] made.
pub struct SceneEntities {
    pub camera: Entity,
    pub volume: Entity,
    pub cube: Entity,
    pub eye: Vec3,
    pub look: Vec3,
    pub sun: Vec3,
}

/// How [`spawn_scene`] lights and shows the scene.
#[derive(Clone, Copy, Debug)]
pub struct SceneOptions {
    /// The image size in pixels.
    pub size: (u32, u32),
    /// The flip-book frame shown (paused there).
    pub frame: f32,
    pub tonemapping: Tonemapping,
    /// The sun's illuminance (lux) and the sky's brightness (cd/m²).
    pub sun_lux: f32,
    pub sky_nits: f32,
}

impl Default for SceneOptions {
    fn default() -> Self {
        SceneOptions {
            size: (960, 540),
            frame: 0.0,
            tonemapping: Tonemapping::AcesFitted,
            // Bevy's default sun (`lux::AMBIENT_DAYLIGHT`) and a sky fill five times Bevy's
            // default ambient (80 cd/m²): at Bevy's default exposure a lit cloud reads as in
            // `vdbcook render`, and fire still glows over it.
            sun_lux: 10_000.0,
            sky_nits: 400.0,
        }
    }
}

/// The scene around `asset`: camera (HDR, `VolumeCamera`) framing the volume's world box from
/// the front and above, a ground plane under it, a box ("the cube") between the camera and the
/// lower right part of the volume, a sun and the ambient light; the volume paused at `o.frame`.
pub fn spawn_scene(
    world: &mut World,
    asset: VdbAsset,
    target: Handle<Image>,
    o: SceneOptions,
) -> SceneEntities {
    let SceneOptions {
        size,
        frame,
        tonemapping,
        sun_lux,
        sky_nits,
    } = o;
    let (lo, hi) = asset
        .world_bounds()
        .unwrap_or((Vec3::splat(-1.0), Vec3::ONE));
    let (centre, extent) = (0.5 * (lo + hi), hi - lo);
    let radius = 0.5 * extent.length();
    let fov = 40f32.to_radians();
    let look = centre;
    let dir = Vec3::new(0.25, 0.35, 1.0).normalize();
    let eye = look + dir * (radius / (0.5 * fov).tan() * 0.9);
    let asset = world.resource_mut::<Assets<VdbAsset>>().add(asset);
    let mesh = |world: &mut World, m: Mesh| world.resource_mut::<Assets<Mesh>>().add(m);
    let material = |world: &mut World, c: Color| {
        world
            .resource_mut::<Assets<StandardMaterial>>()
            .add(StandardMaterial {
                base_color: c,
                perceptual_roughness: 0.9,
                ..default()
            })
    };
    let ground_y = lo.y - 0.02 * extent.y;
    let (plane, grey) = (
        mesh(
            world,
            Plane3d::default()
                .mesh()
                .size(20.0 * radius, 20.0 * radius)
                .build(),
        ),
        material(world, Color::srgb(0.42, 0.45, 0.38)),
    );
    world.spawn((
        Mesh3d(plane),
        MeshMaterial3d(grey),
        Transform::from_xyz(centre.x, ground_y, centre.z),
    ));
    // The cube: a red box standing on the ground between the camera and the volume (outside
    // the volume's bounding sphere, so nothing of the volume is in front of it), a little to
    // the right, tall enough (the camera looks down on it) to hide the lower right part.
    let side = 0.15 * extent.x.min(extent.z).max(1e-3);
    let height = centre.y - ground_y + 0.35 * radius;
    let (cube_mesh, red) = (
        mesh(world, Cuboid::new(side, height, side).into()),
        material(world, Color::srgb(0.62, 0.2, 0.16)),
    );
    let flat = Vec3::new(dir.x, 0.0, dir.z).normalize();
    let right = flat.cross(Vec3::NEG_Y).normalize();
    let at = centre + flat * (radius + side) + right * (0.2 * radius);
    let cube = world
        .spawn((
            Mesh3d(cube_mesh),
            MeshMaterial3d(red),
            Transform::from_xyz(at.x, ground_y + 0.5 * height, at.z),
        ))
        .id();
    let sun = Vec3::new(0.4, 0.8, 0.3).normalize();
    world.spawn((
        DirectionalLight {
            illuminance: sun_lux,
            shadow_maps_enabled: false,
            ..default()
        },
        Transform::from_translation(sun).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    // A pale blue sky: the ambient light the meshes and the volume receive, and the background.
    let sky = Color::srgb(0.6, 0.7, 0.9);
    world.insert_resource(GlobalAmbientLight {
        color: sky,
        brightness: sky_nits,
        ..default()
    });
    world.insert_resource(ClearColor(sky));
    let camera = world
        .spawn((
            Camera3d::default(),
            Hdr,
            tonemapping,
            VolumeCamera::default(),
            RenderTarget::from(target),
            Projection::Perspective(PerspectiveProjection {
                fov,
                near: 0.01 * radius,
                aspect_ratio: size.0 as f32 / size.1 as f32,
                ..default()
            }),
            Transform::from_translation(eye).looking_at(look, Vec3::Y),
        ))
        .id();
    let volume = world
        .spawn((
            VdbVolume::new(asset),
            VdbPlayback {
                time: frame,
                paused: true,
                ..default()
            },
        ))
        .id();
    SceneEntities {
        camera,
        volume,
        cube,
        eye,
        look,
        sun,
    }
}

struct Args {
    asset: PathBuf,
    out: PathBuf,
    volume: bool,
    scene: SceneOptions,
    /// Frames to time with and without the volume after the capture (0: none).
    time: usize,
}

fn args() -> Result<Args, String> {
    let usage = "usage: screenshot ASSET.vdbc OUT.png [--no-volume] [--frame F] [--size WxH] \
                 [--sun LUX] [--sky CD_PER_M2] [--time FRAMES]";
    let mut it = std::env::args().skip(1);
    let (mut paths, mut volume, mut scene) = (Vec::new(), true, SceneOptions::default());
    let mut time = 0;
    let number = |it: &mut std::iter::Skip<std::env::Args>, what: &str| {
        it.next()
            .and_then(|f| f.parse::<f32>().ok())
            .filter(|f| f.is_finite() && *f >= 0.0)
            .ok_or(format!("{what} needs a number ≥ 0"))
    };
    while let Some(a) = it.next() {
        match a.as_str() {
            "--no-volume" => volume = false,
            "--frame" => scene.frame = number(&mut it, "--frame")?,
            "--sun" => scene.sun_lux = number(&mut it, "--sun")?,
            "--sky" => scene.sky_nits = number(&mut it, "--sky")?,
            "--time" => time = number(&mut it, "--time")? as usize,
            "--size" => {
                let s = it.next().ok_or("--size needs WxH")?;
                let (w, h) = s.split_once('x').ok_or("--size needs WxH")?;
                scene.size = (
                    w.parse().map_err(|_| "bad width")?,
                    h.parse().map_err(|_| "bad height")?,
                );
            }
            "-h" | "--help" => return Err(usage.into()),
            _ => paths.push(PathBuf::from(a)),
        }
    }
    let [asset, out] = <[PathBuf; 2]>::try_from(paths).map_err(|_| usage.to_string())?;
    Ok(Args {
        asset,
        out,
        volume,
        scene,
        time,
    })
}

/// Median wall time of a whole Bevy frame (update and GPU wait) without the volume, with it
/// still, and with it playing (at its 24 fps under Bevy's clock: a frame change rebuilds the
/// light volumes), `frames` each after a warm-up: what the volume adds to this machine's frame.
fn time_frames(app: &mut Headless, volume: Entity, frames: usize) {
    let median = |app: &mut Headless, visible: Visibility, playing: bool| {
        app.world().entity_mut(volume).insert(visible);
        app.world().get_mut::<VdbPlayback>(volume).unwrap().paused = !playing;
        for _ in 0..3 {
            app.update();
        }
        let mut ms: Vec<f64> = (0..frames)
            .map(|_| {
                let t = std::time::Instant::now();
                app.update();
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        ms.sort_by(f64::total_cmp);
        ms[ms.len() / 2]
    };
    let without = median(app, Visibility::Hidden, false);
    let still = median(app, Visibility::Inherited, false);
    let playing = median(app, Visibility::Inherited, true);
    println!(
        "frame (median of {frames}): {without:.1} ms without the volume, {still:.1} ms with it \
         still (+{:.1}), {playing:.1} ms playing (+{:.1})",
        still - without,
        playing - without
    );
}

fn main() -> ExitCode {
    let a = match args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
    };
    let asset = match vdbcook_bevy::vdbcook_runtime::Asset::load(&a.asset) {
        Ok(x) => VdbAsset::new(x),
        Err(e) => {
            eprintln!("{}: {e}", a.asset.display());
            return ExitCode::FAILURE;
        }
    };
    let mut app = Headless::new(|_| {});
    let target = app.target(a.scene.size);
    let scene = spawn_scene(app.world(), asset, target.clone(), a.scene);
    if !a.volume {
        app.world()
            .entity_mut(scene.volume)
            .insert(Visibility::Hidden);
    }
    // A few frames for the upload and the pipelines, then the capture.
    for _ in 0..3 {
        app.update();
    }
    let image = app.capture(&target);
    let saved = image
        .try_into_dynamic()
        .map_err(|e| e.to_string())
        .and_then(|i| i.to_rgb8().save(&a.out).map_err(|e| e.to_string()));
    match saved {
        Ok(()) => {
            println!("wrote {}", a.out.display());
            if a.time > 0 {
                time_frames(&mut app, scene.volume, a.time);
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("{}: {e}", a.out.display());
            ExitCode::FAILURE
        }
    }
}
