//! The plugin on a real adapter (lavapipe in CI): Bevy's frame against the runtime's own drawer
//! on the same view, built independently here from the camera and lights the test spawned; the
//! cube in front hiding the volume; playback moving the drawn frame. All in one test binary (one
//! link of Bevy); each test probes an adapter first and skips without one (fails under
//! `VDBCOOK_REQUIRE_GPU=1`, as CI sets), because Bevy panics without one.

#[allow(dead_code)]
#[path = "../examples/screenshot.rs"]
mod screenshot;

use std::sync::Arc;
use std::time::Duration;

use bevy::app::AppLabel;
use bevy::camera::Hdr;
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::view::{ViewDepthTexture, ViewTarget};
use bevy::render::RenderApp;
use bevy::time::TimeUpdateStrategy;
use screenshot::{spawn_scene, Headless, SceneOptions};
use vdbcook_asset::PayloadFormat;
use vdbcook_bevy::vdbcook_runtime::{
    glam as rt, wgpu, DrawTarget, Filter, GpuVolume, Instance, Integrator, Lighting, Shading, View,
    VolumeDrawer,
};
use vdbcook_bevy::{VdbAsset, VdbPass, VdbPlayback, VdbVolume};
use vdbcook_testkit::{blob_frame, build, uniform_scale};

/// An adapter exists (or the test is skipped; a failure under `VDBCOOK_REQUIRE_GPU=1`).
fn adapter(test: &str) -> bool {
    vdbcook_testkit::gpu::open_device(test, wgpu::Features::empty(), None).is_some()
}

/// Two frames of a smooth cloud (the second moved and denser), 2 cm voxels.
fn cloud() -> vdbcook_bevy::vdbcook_runtime::Asset {
    build(
        [2, 2, 2],
        uniform_scale(0.02, [-2.4, 0.0, -1.2]),
        0.0,
        &[
            blob_frame([120.0, 60.0, 60.0], 34.0, 0.25, None),
            blob_frame([132.0, 64.0, 60.0], 30.0, 0.6, None),
        ],
        PayloadFormat::F16,
    )
}

const SIZE: (u32, u32) = (160, 96);

/// sRGB 8-bit RGBA pixels of a captured image.
fn pixels(image: &Image) -> Vec<[u8; 4]> {
    let data = image.data.as_ref().expect("captured pixels");
    assert_eq!(data.len(), (SIZE.0 * SIZE.1 * 4) as usize);
    data.chunks_exact(4)
        .map(|p| [p[0], p[1], p[2], p[3]])
        .collect()
}

fn differs(a: &[u8; 4], b: &[u8; 4]) -> bool {
    a[..3] != b[..3]
}

/// Pixels whose colour differs between two pictures.
fn changed(a: &[[u8; 4]], b: &[[u8; 4]]) -> usize {
    a.iter().zip(b).filter(|(a, b)| differs(a, b)).count()
}

/// An app (`configure`d before it starts) rendering `asset` in the example's scene at
/// [`SIZE`], untonemapped, at `frame`: the app, its image target and what was spawned.
fn scene_app(
    asset: VdbAsset,
    frame: f32,
    configure: impl FnOnce(&mut App),
) -> (Headless, Handle<Image>, screenshot::SceneEntities) {
    let mut app = Headless::new(configure);
    let target = app.target(SIZE);
    let options = SceneOptions {
        size: SIZE,
        frame,
        tonemapping: Tonemapping::None,
        ..Default::default()
    };
    let scene = spawn_scene(app.world(), asset, target.clone(), options);
    (app, target, scene)
}

/// The volume is drawn, not flat, and hidden exactly where the cube in front covers it; the
/// cube and the ground where no volume is are the same pixels with and without the volume. On
/// an HDR camera (`Rgba16Float` main texture) and on an LDR one (the image's `Rgba8UnormSrgb`).
#[test]
fn volume_is_drawn_behind_the_cube() {
    if !adapter("volume_is_drawn_behind_the_cube") {
        return;
    }
    for hdr in [true, false] {
        drawn_behind_the_cube(hdr);
    }
}

fn drawn_behind_the_cube(hdr: bool) {
    let (mut app, target, scene) = scene_app(VdbAsset::new(cloud()), 0.0, |_| {});
    if !hdr {
        app.world().entity_mut(scene.camera).remove::<Hdr>();
    }
    let shot = |app: &mut Headless, volume: bool, cube: bool| {
        let vis = |on| {
            if on {
                Visibility::Inherited
            } else {
                Visibility::Hidden
            }
        };
        app.world().entity_mut(scene.volume).insert(vis(volume));
        app.world().entity_mut(scene.cube).insert(vis(cube));
        // Meshes, materials and the volume's upload take a frame or two to reach the GPU.
        for _ in 0..3 {
            app.update();
        }
        let image = app.capture(&target);
        // VDBCOOK_TEST_OUT=DIR keeps the pictures, to look at.
        if let Ok(dir) = std::env::var("VDBCOOK_TEST_OUT") {
            let name = format!("{dir}/bevy_volume{}_cube{}.png", volume as u8, cube as u8);
            let _ = image
                .clone()
                .try_into_dynamic()
                .map(|i| i.to_rgb8().save(name));
        }
        pixels(&image)
    };
    let both = shot(&mut app, true, true);
    let cube_only = shot(&mut app, false, true);
    let nothing = shot(&mut app, false, false);
    let volume_only = shot(&mut app, true, false);

    let n = both.len();
    let cube: Vec<bool> = (0..n)
        .map(|i| differs(&cube_only[i], &nothing[i]))
        .collect();
    let volume: Vec<bool> = (0..n)
        .map(|i| differs(&volume_only[i], &nothing[i]))
        .collect();
    let covered = (0..n).filter(|&i| cube[i] && volume[i]).count();
    let cube_n = cube.iter().filter(|&&c| c).count();
    let volume_n = volume.iter().filter(|&&v| v).count();
    // The scene is what it claims: the volume covers a good part of the frame and the cube
    // stands in front of part of it.
    assert!(
        volume_n > n / 10,
        "hdr {hdr}: volume covers {volume_n}/{n} pixels"
    );
    assert!(
        covered > 50,
        "hdr {hdr}: the cube covers {covered} pixels of the volume ({cube_n} in all)"
    );
    // Occlusion: where the cube is, the volume adds nothing, bit for bit.
    let through = (0..n)
        .filter(|&i| cube[i] && differs(&both[i], &cube_only[i]))
        .count();
    assert_eq!(
        through, 0,
        "hdr {hdr}: {through} cube pixels changed by the volume behind it"
    );
    // Elsewhere the volume shows over the ground with the cube present too.
    let shown = (0..n)
        .filter(|&i| !cube[i] && differs(&both[i], &cube_only[i]))
        .count();
    assert!(
        shown > volume_n / 2,
        "hdr {hdr}: {shown} of {volume_n} volume pixels shown"
    );
    // Not flat: the lit volume's luminance varies across it.
    let lum: Vec<f64> = (0..n)
        .filter(|&i| volume[i] && !cube[i])
        .map(|i| volume_only[i][..3].iter().map(|&c| c as f64).sum::<f64>() / 3.0)
        .collect();
    let mean = lum.iter().sum::<f64>() / lum.len() as f64;
    let sd = (lum.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / lum.len() as f64).sqrt();
    assert!(
        sd > 8.0,
        "hdr {hdr}: volume luminance sd {sd:.1} (8-bit levels) over {} pixels",
        lum.len()
    );
}

/// Playback follows Bevy's clock: at 24 fps, one update of 1/24 s is one frame, and the drawn
/// picture changes with the frame.
#[test]
fn playback_advances_with_time() {
    if !adapter("playback_advances_with_time") {
        return;
    }
    let (mut app, target, scene) = scene_app(VdbAsset::new(cloud()), 0.0, |app| {
        app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
            1.0 / 24.0,
        )));
    });
    for _ in 0..3 {
        app.update();
    }
    let first = pixels(&app.capture(&target));
    let time = |app: &mut Headless| app.world().get::<VdbPlayback>(scene.volume).unwrap().time;
    let mut playback = app.world().get_mut::<VdbPlayback>(scene.volume).unwrap();
    playback.paused = false;
    playback.time = 0.0;
    // Loop over the two frames: one update is one frame.
    app.update();
    let one = time(&mut app);
    assert!((one - 1.0).abs() < 1e-4, "after one update: {one}");
    app.update();
    let two = time(&mut app);
    assert!(
        two.abs() < 1e-4 || (two - 2.0).abs() < 1e-4,
        "after two: {two}"
    );
    // Frame 1, held there: the picture differs from frame 0's.
    let mut playback = app.world().get_mut::<VdbPlayback>(scene.volume).unwrap();
    playback.paused = true;
    playback.time = 1.0;
    for _ in 0..2 {
        app.update();
    }
    let last = pixels(&app.capture(&target));
    let changed = changed(&first, &last);
    assert!(
        changed > 200,
        "{changed} pixels changed between frame 0 and frame 1"
    );
}

/// Several instances of two assets in one frame (one draw per asset, composited far first):
/// every instance is drawn — hiding any one of them changes the picture.
#[test]
fn many_instances_of_two_assets() {
    if !adapter("many_instances_of_two_assets") {
        return;
    }
    let first = VdbAsset::new(cloud());
    let (lo, hi) = first.world_bounds().unwrap();
    let extent = hi - lo;
    let (mut app, target, scene) = scene_app(first, 0.0, |_| {});
    let world = app.world();
    let cloud_handle = world.get::<VdbVolume>(scene.volume).unwrap().asset.clone();
    // A second asset: one small dense puff.
    let puff = build(
        [1, 1, 1],
        uniform_scale(0.02, [0.0; 3]),
        0.0,
        &[blob_frame([30.0, 30.0, 30.0], 14.0, 1.5, None)],
        PayloadFormat::F16,
    );
    let puff_handle = world
        .resource_mut::<Assets<VdbAsset>>()
        .add(VdbAsset::new(puff));
    let mut instances = vec![scene.volume];
    for (i, (handle, x, time)) in [
        (cloud_handle.clone(), -0.45, 1.0),
        (cloud_handle, 0.45, 0.5),
        (puff_handle.clone(), -0.3, 0.0),
        (puff_handle, 0.3, 0.0),
    ]
    .into_iter()
    .enumerate()
    {
        let at = Vec3::new(x * extent.x, 0.1 * i as f32 * extent.y, -0.3 * extent.z);
        let placed = if i >= 2 { at + 0.5 * (lo + hi) } else { at };
        let e = world
            .spawn((
                VdbVolume::new(handle),
                VdbPlayback {
                    time,
                    paused: true,
                    ..default()
                },
                Transform::from_translation(placed),
            ))
            .id();
        instances.push(e);
    }
    for _ in 0..3 {
        app.update();
    }
    let all = pixels(&app.capture(&target));
    for (k, &e) in instances.iter().enumerate() {
        app.world().entity_mut(e).insert(Visibility::Hidden);
        for _ in 0..2 {
            app.update();
        }
        let without = pixels(&app.capture(&target));
        app.world().entity_mut(e).insert(Visibility::Inherited);
        let changed = changed(&all, &without);
        assert!(
            changed > 20,
            "instance {k}: hiding it changed {changed} pixels"
        );
    }
}

/// What the runtime's drawer draws for the reference, built by the test (not by the plugin):
/// recorded in the render world onto a copy of the main texture taken before the volume pass.
#[derive(Resource, Clone)]
struct Reference {
    asset: Arc<vdbcook_bevy::vdbcook_runtime::Asset>,
    view: View,
    shading: Shading,
    instances: Vec<Instance>,
}

/// The main texture (Bevy's opaque scene) copied before the volume pass, and the read-back
/// buffers: before, Bevy's after, the reference.
#[derive(Resource, Default)]
struct Before(Option<(wgpu::Texture, [wgpu::Buffer; 3])>);

fn texture_bytes(w: u32, h: u32) -> u64 {
    (w * 8 * h) as u64
}

fn copy_to_buffer(
    encoder: &mut wgpu::CommandEncoder,
    texture: &wgpu::Texture,
    buffer: &wgpu::Buffer,
) {
    let w = texture.width();
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(w * 8),
                rows_per_image: None,
            },
        },
        texture.size(),
    );
}

fn capture_before(
    view: ViewQuery<&ViewTarget>,
    device: Res<RenderDevice>,
    mut before: ResMut<Before>,
    mut ctx: RenderContext,
) {
    let target = view.into_inner();
    let main: &wgpu::Texture = target.main_texture();
    let device = device.wgpu_device();
    let (texture, _) = before.0.get_or_insert_with(|| {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("test: before the volumes"),
            size: main.size(),
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: main.format(),
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::COPY_DST
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let buffer = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: texture_bytes(main.width(), main.height()),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            })
        };
        let buffers = [
            buffer("test: before"),
            buffer("test: after"),
            buffer("test: reference"),
        ];
        (texture, buffers)
    });
    ctx.command_encoder().copy_texture_to_texture(
        main.as_image_copy(),
        texture.as_image_copy(),
        main.size(),
    );
}

#[allow(clippy::too_many_arguments)]
fn capture_after(
    view: ViewQuery<(&ViewTarget, &ViewDepthTexture)>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    reference: Res<Reference>,
    before: Res<Before>,
    mut drawer: Local<Option<(GpuVolume, VolumeDrawer)>>,
    mut kept: Local<Option<vdbcook_bevy::vdbcook_runtime::PreparedDraw>>,
    mut ctx: RenderContext,
) {
    let (target, depth) = view.into_inner();
    let Some((texture, [before_buf, after, reference_buf])) = &before.0 else {
        return;
    };
    let device = device.wgpu_device();
    let queue: &wgpu::Queue = &queue;
    let (_, d) = drawer.get_or_insert_with(|| {
        let volume = GpuVolume::upload(device, queue, &reference.asset).expect("upload");
        let d = VolumeDrawer::new(device, &volume, texture.format()).expect("drawer");
        (volume, d)
    });
    let color = texture.create_view(&Default::default());
    let draw = d
        .prepare(
            device,
            queue,
            &DrawTarget {
                color: &color,
                depth: Some(depth.view()),
            },
            &reference.view,
            &reference.instances,
            &reference.shading,
        )
        .expect("the reference draw");
    let encoder = ctx.command_encoder();
    copy_to_buffer(encoder, texture, before_buf);
    copy_to_buffer(encoder, target.main_texture(), after);
    d.record(encoder, &draw);
    copy_to_buffer(encoder, texture, reference_buf);
    // The draw's buffers must outlive the submission (Bevy submits after the schedule): kept
    // until the next frame's.
    *kept = Some(draw);
}

/// The half floats of `buffer` as their bits.
fn read_half(device: &wgpu::Device, buffer: &wgpu::Buffer) -> Vec<u16> {
    let slice = buffer.slice(..);
    slice.map_async(wgpu::MapMode::Read, |r| r.expect("map"));
    device
        .poll(wgpu::PollType::Wait {
            submission_index: None,
            timeout: None,
        })
        .unwrap();
    let v: Vec<u16> = slice
        .get_mapped_range()
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    buffer.unmap();
    v
}

/// Bevy's frame equals the runtime drawer's on the same view, with the view, light and
/// instance built here from what the test spawned (eye, target, field of view, the sun's
/// direction and lux, the ambient light, Bevy's default exposure), not from the plugin's
/// conversions: the plugin's mapping of Bevy's camera (reversed Z), units and depth is checked.
#[test]
fn plugin_matches_the_runtime_drawer() {
    if !adapter("plugin_matches_the_runtime_drawer") {
        return;
    }
    // A Z-up source (as Blender writes) on a turned and moved entity: the plugin stands it up
    // and places it; the reference instance is built here from the same numbers.
    let mut zup = cloud();
    zup.header.source.up = "z".into();
    let asset = Arc::new(zup);
    let frame = 0.5;
    let (mut app, _target, scene) = scene_app(VdbAsset(asset.clone()), frame, |app| {
        app.sub_app_mut(RenderApp)
            .init_resource::<Before>()
            .add_systems(
                Core3d,
                (
                    capture_before
                        .after(Core3dSystems::MainPass)
                        .before(VdbPass),
                    capture_after
                        .after(VdbPass)
                        .before(Core3dSystems::EarlyPostProcess),
                ),
            );
    });
    let options = SceneOptions::default();
    let (turn, shift) = (0.4f32, Vec3::new(0.05, 0.1, -0.08));
    app.world()
        .entity_mut(scene.volume)
        .insert(Transform::from_translation(shift).with_rotation(Quat::from_rotation_y(turn)));
    // The reference, from the scene's numbers: Bevy's default exposure (EV100 9.7), the sun
    // (white) and the ambient light (sRGB (0.6, 0.7, 0.9) → linear) at the scene's lux and cd/m².
    let exposure = 2f32.powf(-9.7) / 1.2;
    let srgb = |c: f32| ((c + 0.055) / 1.055).powf(2.4);
    let v = |x: Vec3| rt::Vec3::from_array(x.to_array());
    let lighting = Lighting {
        light_dir: scene.sun.to_array(),
        light_color: [options.sun_lux * exposure; 3],
        sky: [0.6, 0.7, 0.9].map(|c| srgb(c) * options.sky_nits * exposure),
        ..Default::default()
    };
    let reference = Reference {
        asset: asset.clone(),
        view: View::look_at(
            v(scene.eye),
            v(scene.look),
            rt::Vec3::Y,
            40f32.to_radians(),
            SIZE.0 as f32 / SIZE.1 as f32,
            0.01 * 0.5 * {
                let (lo, hi) = VdbAsset(asset.clone()).world_bounds().unwrap();
                (hi - lo).length()
            },
            SIZE,
        )
        .unwrap(),
        // The plugin's documented default shading: the runtime's medium, trilinear density.
        shading: Shading {
            lighting: Some(lighting),
            integrator: Integrator {
                filter: Filter::Trilinear,
                ..Default::default()
            },
            ..Default::default()
        },
        instances: vec![Instance {
            world_from_volume: rt::Affine3A::from_translation(v(shift))
                * rt::Affine3A::from_rotation_y(turn)
                * rt::Affine3A::from_rotation_x(-std::f32::consts::FRAC_PI_2),
            time: frame,
            ..Default::default()
        }],
    };
    app.0
        .sub_apps
        .get_mut(&RenderApp.intern())
        .unwrap()
        .world_mut()
        .insert_resource(reference);
    for _ in 0..3 {
        app.update();
    }
    let render = app.0.sub_apps.get(&RenderApp.intern()).unwrap().world();
    let device = render.resource::<RenderDevice>().wgpu_device().clone();
    let (_, buffers) = render.resource::<Before>().0.as_ref().unwrap();
    let [before, bevy, ours] = buffers.each_ref().map(|b| read_half(&device, b));
    // Same device, shaders and inputs: what is left is the two views' matrices, built two ways
    // in f32, and the half-float main texture: four half-float steps (2^-10 relative each).
    let tolerance = 4.0 * 2f32.powi(-10);
    let n = bevy.len() / 4;
    let mut worst = 0f32;
    for i in 0..n {
        for c in 0..3 {
            let half = |bits| half::f16::from_bits(bits).to_f32();
            let (a, b) = (half(bevy[4 * i + c]), half(ours[4 * i + c]));
            worst = worst.max((a - b).abs() / b.abs().max(2f32.powi(-14)));
        }
    }
    // The comparison is not vacuous: the volume changed a good part of the frame.
    let drawn = (0..n)
        .filter(|&i| (0..3).any(|c| before[4 * i + c] != bevy[4 * i + c]))
        .count();
    eprintln!("bevy vs runtime drawer: {drawn}/{n} pixels drawn, worst relative {worst:.2e}");
    assert!(drawn > n / 10, "the volume changed {drawn}/{n} pixels");
    assert!(
        worst <= tolerance,
        "worst relative difference {worst:.2e} > {tolerance:.2e}"
    );
}
