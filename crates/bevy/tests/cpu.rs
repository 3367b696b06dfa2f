//! The plugin without a GPU: the `.vdbc` loader through Bevy's asset server (a cooked file
//! loads, a truncated one fails with the asset's message and nothing panics) and playback
//! driven by Bevy's clock in a running app.

use std::time::Duration;

use bevy::asset::{AssetPlugin, LoadState};
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use vdbcook_asset::PayloadFormat;
use vdbcook_bevy::{PlayMode, VdbAsset, VdbPlayback, VdbPlugin, VdbVolume};
use vdbcook_testkit::{blob_frame, build, uniform_scale};

/// `frames` small frames (a moving blob).
fn flipbook(frames: usize) -> vdbcook_bevy::vdbcook_runtime::Asset {
    let specs: Vec<_> = (0..frames)
        .map(|f| blob_frame([20.0 + 2.0 * f as f64, 20.0, 20.0], 8.0, 1.0, None))
        .collect();
    build(
        [1, 1, 1],
        uniform_scale(0.1, [0.0; 3]),
        0.0,
        &specs,
        PayloadFormat::F16,
    )
}

fn app(dir: &std::path::Path) -> App {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        AssetPlugin {
            file_path: dir.display().to_string(),
            ..default()
        },
        VdbPlugin,
    ));
    app
}

#[test]
fn loader_reads_a_cooked_file_and_refuses_a_truncated_one() {
    let dir = tempfile::tempdir().unwrap();
    let asset = flipbook(3);
    let (bytes, _) = asset.to_bytes().unwrap();
    std::fs::write(dir.path().join("good.vdbc"), &bytes).unwrap();
    std::fs::write(dir.path().join("cut.vdbc"), &bytes[..bytes.len() / 2]).unwrap();
    let mut app = app(dir.path());
    let server = app.world().resource::<AssetServer>().clone();
    let good: Handle<VdbAsset> = server.load("good.vdbc");
    let cut: Handle<VdbAsset> = server.load("cut.vdbc");
    let state = |h: &Handle<VdbAsset>| server.load_state(h.id());
    for _ in 0..2000 {
        app.update();
        let done = |s: LoadState| s.is_loaded() || s.is_failed();
        if done(state(&good)) && done(state(&cut)) {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(state(&good).is_loaded(), "{:?}", state(&good));
    let loaded = app.world().resource::<Assets<VdbAsset>>();
    let got = loaded.get(&good).unwrap();
    assert_eq!(got.frame_count(), 3);
    assert_eq!(
        got.0.roots, asset.roots,
        "the loaded tree is the written one"
    );
    let LoadState::Failed(e) = state(&cut) else {
        panic!("truncated file: {:?}", state(&cut));
    };
    let message = e.to_string();
    assert!(message.contains("not a valid .vdbc"), "{message}");
}

#[test]
fn playback_follows_bevys_clock() {
    let dir = tempfile::tempdir().unwrap();
    let mut app = app(dir.path());
    app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
        1.0 / 24.0,
    )));
    let handle = app
        .world_mut()
        .resource_mut::<Assets<VdbAsset>>()
        .add(VdbAsset::new(flipbook(5)));
    let looping = app.world_mut().spawn(VdbVolume::new(handle.clone())).id();
    let bouncing = app
        .world_mut()
        .spawn((
            VdbVolume::new(handle),
            VdbPlayback {
                mode: PlayMode::PingPong,
                speed: 2.0,
                ..default()
            },
        ))
        .id();
    app.update();
    let time = |app: &App, e| app.world().get::<VdbPlayback>(e).unwrap().time;
    let (t0, b0) = (time(&app, looping), time(&app, bouncing));
    for _ in 0..7 {
        app.update();
    }
    // 7 frames at 24 fps on a 5-frame loop; twice as fast, bouncing between 0 and 4.
    let expect_loop = (t0 + 7.0).rem_euclid(5.0);
    assert!(
        (time(&app, looping) - expect_loop).abs() < 1e-3,
        "{} vs {expect_loop}",
        time(&app, looping)
    );
    // Bouncing: 14 frames of travel from b0 (heading up) on a 0..4 bounce unfold to
    // (b0 + 14) mod 8, mirrored on the way down.
    let m = (b0 + 14.0).rem_euclid(8.0);
    let expect_bounce = if m > 4.0 { 8.0 - m } else { m };
    let got = time(&app, bouncing);
    assert!(
        (got - expect_bounce).abs() < 1e-3,
        "{got} vs {expect_bounce}"
    );
}
