//! Runs the `engine_scene` example's `render_scene` (the example file is included as a module, so
//! the test checks the code the example runs, not a copy) on a hand-built three-frame cloud and
//! checks its pictures against the scene's own geometry, ray by ray (`ViewRays`, f64): where the
//! opaque box is in front of every cloud, the composite is the scene pixel bit for bit (the
//! drawer clipped at the rasterized depth); where a cloud lies in front of the ground (through its core), or in
//! front of the part of the box inside it, the composite differs from the scene; where no ray
//! meets a cloud, nothing changed.

mod common;

#[allow(dead_code)]
#[path = "../examples/engine_scene.rs"]
mod engine_scene;

use common::*;
use vdbcook_asset::PayloadFormat;
use vdbcook_runtime::glam::Vec3;
use vdbcook_runtime::MarchResolution;

/// A hand-built three-frame cloud, 0.1 world units a voxel, moved off the origin.
fn three_frame_cloud() -> vdbcook_asset::Asset {
    build(
        [1, 1, 1],
        uniform_scale(0.1, [2.0, 1.0, -3.0]),
        0.0,
        &[
            blob_frame([64.0, 60.0, 64.0], 30.0, 1.0, None),
            blob_frame([66.0, 62.0, 64.0], 32.0, 1.2, None),
            blob_frame([68.0, 64.0, 62.0], 34.0, 1.4, None),
        ],
        PayloadFormat::F32,
    )
}

#[test]
fn engine_scene_clips_at_the_box_and_shows_over_the_ground() {
    let Some((device, queue)) = gpu("engine_scene_clips_at_the_box_and_shows_over_the_ground")
    else {
        return;
    };
    let asset = three_frame_cloud();
    let (w, h) = (240, 135);
    let img = engine_scene::render_scene(&device, &queue, &asset, (w, h)).unwrap();
    check_scene(&img, w, h, true);
}

/// The same scene with the drawer marching half and quarter as many rays per axis: where the box
/// hides the clouds the composite is still the scene pixel bit for bit (blocks at the box's
/// edges are marched per pixel, blocks behind it draw nothing), and the clouds still show over
/// the ground and the box; pixels whose rays meet no cloud box may take a little of an upsampled
/// silhouette, so they are not held to bit-equality.
#[test]
fn engine_scene_at_reduced_resolution_keeps_the_box_edges() {
    let Some((device, queue)) = gpu("engine_scene_at_reduced_resolution_keeps_the_box_edges")
    else {
        return;
    };
    let asset = three_frame_cloud();
    let (w, h) = (240, 135);
    for resolution in [MarchResolution::Half, MarchResolution::Quarter] {
        eprintln!("{resolution:?}:");
        let img =
            engine_scene::render_scene_at(&device, &queue, &asset, (w, h), resolution).unwrap();
        check_scene(&img, w, h, false);
    }
}

/// The checks of both tests on one rendered scene; `exact_outside`: pixels whose rays meet no
/// cloud box are the scene's bit for bit.
fn check_scene(img: &engine_scene::SceneImages, w: u32, h: u32, exact_outside: bool) {
    assert_eq!((img.width, img.height), (w, h));
    assert_eq!(img.scene.len(), (w * h * 4) as usize);
    assert_eq!(img.composite.len(), img.scene.len());
    assert_eq!(img.clouds.len(), 2);
    assert_eq!(img.instances.len(), 2);

    // The box shrunk by 2 % of its size: rays that meet it hit the box well inside its
    // silhouette (no disagreement between f64 rays and the rasterizer at the edges).
    let margin = 0.02 * (img.block.hi - img.block.lo);
    let inner = engine_scene::Aabb {
        lo: img.block.lo + margin,
        hi: img.block.hi - margin,
    };
    // The middle 40 % of the first (untransformed) cloud's box: inside the blob.
    let (c0, s0) = (
        0.5 * (img.clouds[0].lo + img.clouds[0].hi),
        img.clouds[0].hi - img.clouds[0].lo,
    );
    let core = engine_scene::Aabb {
        lo: c0 - 0.2 * s0,
        hi: c0 + 0.2 * s0,
    };
    let rays = img.view.rays().unwrap();
    let (mut box_hides_cloud, mut cloud_over_ground, mut cloud_over_box) = (0, [0, 0], [0, 0]);
    let mut untouched = 0;
    for py in 0..h {
        for px in 0..w {
            let (o, d) = rays.ray(px, py);
            let (o, d) = (o.as_vec3(), d.as_vec3());
            let k = 4 * (py * w + px) as usize;
            let (scene, comp) = (&img.scene[k..k + 4], &img.composite[k..k + 4]);
            let ground = if d.y < 0.0 {
                (img.ground_y - o.y) / d.y
            } else {
                f32::INFINITY
            };
            let block = img.block.hit(o, d).map(|t| t.0);
            let block_inner = inner.hit(o, d).map(|t| t.0);
            let clouds: Vec<_> = img.clouds.iter().filter_map(|c| c.hit(o, d)).collect();
            let nearest_cloud = clouds.iter().map(|c| c.0).fold(f32::INFINITY, f32::min);
            if clouds.is_empty() {
                if exact_outside {
                    assert_eq!(scene, comp, "pixel ({px}, {py}) meets no cloud");
                }
                untouched += 1;
                continue;
            }
            // The box hides every cloud: the drawer's march ends before any content.
            if let Some(tb) = block_inner {
                if tb < ground && tb < 0.999 * nearest_cloud {
                    assert_eq!(scene, comp, "pixel ({px}, {py}): the box is in front");
                    box_hides_cloud += 1;
                    continue;
                }
                // The box's surface is inside the first cloud's box: smoke in front of it.
                if img.clouds[0].hit(o, d).is_some_and(|c| c.0 < 0.9 * tb) {
                    cloud_over_box[(scene != comp) as usize] += 1;
                }
                continue;
            }
            // The ground behind the first cloud's core (no box on the ray).
            if block.is_none() && core.hit(o, d).is_some_and(|c| c.1 < ground) {
                cloud_over_ground[(scene != comp) as usize] += 1;
            }
        }
    }
    eprintln!(
        "untouched {untouched}, box in front {box_hides_cloud}, cloud over ground (same, \
         changed) {cloud_over_ground:?}, cloud over box {cloud_over_box:?}"
    );
    assert!(untouched > (w * h / 4) as usize, "{untouched}");
    assert!(
        box_hides_cloud > 100,
        "{box_hides_cloud} box pixels hide a cloud"
    );
    assert!(
        // (a ray grazing a corner of the core crosses little smoke: a few may round away)
        cloud_over_ground[1] > 200 && cloud_over_ground[0] * 20 < cloud_over_ground[1],
        "{cloud_over_ground:?}"
    );
    assert!(cloud_over_box[1] > 20, "{cloud_over_box:?}");
    // Smoke is mostly lighter than the ground and the box under it (white and warm tints). Not
    // everywhere: this blob is dense (optical depth ~50 through it), and since the sky's light
    // is solved by diffusion (not a closed form that returned 1.3× too much of it on the WDAS
    // cloud) its shaded side comes out darker than the sunlit ground in about a pixel in nine
    // (measured 3,765 of 4,245 lighter).
    let brighter = (0..(w * h) as usize)
        .filter(|&i| {
            let s: u32 = img.scene[4 * i..4 * i + 3].iter().map(|&v| v as u32).sum();
            let c: u32 = img.composite[4 * i..4 * i + 3]
                .iter()
                .map(|&v| v as u32)
                .sum();
            c > s
        })
        .count();
    let changed = (0..(w * h) as usize)
        .filter(|&i| img.scene[4 * i..4 * i + 4] != img.composite[4 * i..4 * i + 4])
        .count();
    assert!(brighter * 5 >= changed * 4, "{brighter} of {changed}");
    // The smoke's shadow on the ground (the scene shader reads `vdb_sun_transmittance`): ground
    // points whose ray toward the sun crosses a cloud's core are darker than every ground point
    // whose ray toward the sun meets no cloud at all (the ground's Lambert term is constant, so
    // unshadowed ground pixels take one of the two checker colours).
    let sun = Vec3::new(0.4, 0.8, 0.3).normalize();
    let luminance = |k: usize| img.scene[k..k + 3].iter().map(|&v| v as u32).sum::<u32>();
    let (mut lit_min, mut shadowed) = (u32::MAX, Vec::new());
    for py in 0..h {
        for px in 0..w {
            let (o, d) = rays.ray(px, py);
            let (o, d) = (o.as_vec3(), d.as_vec3());
            if d.y >= 0.0 || img.block.hit(o, d).is_some() {
                continue;
            }
            let g = o + d * ((img.ground_y - o.y) / d.y);
            let k = 4 * (py * w + px) as usize;
            let cores = img.clouds.iter().any(|c| {
                let (mid, size) = (0.5 * (c.lo + c.hi), c.hi - c.lo);
                let core = engine_scene::Aabb {
                    lo: mid - 0.2 * size,
                    hi: mid + 0.2 * size,
                };
                core.hit(g, sun).is_some()
            });
            if cores {
                shadowed.push(luminance(k));
            } else if img.clouds.iter().all(|c| c.hit(g, sun).is_none())
                && img.block.hit(g, sun).is_none()
            {
                lit_min = lit_min.min(luminance(k));
            }
        }
    }
    let darker = shadowed.iter().filter(|&&l| l < lit_min).count();
    eprintln!(
        "shadowed ground pixels {}, darker than any lit one: {darker}; lit min {lit_min}",
        shadowed.len()
    );
    assert!(
        shadowed.len() > 50 && darker * 10 >= shadowed.len() * 9,
        "{darker} of {}",
        shadowed.len()
    );
    // Alpha is the scene's (opaque) everywhere.
    assert!(img.composite.chunks(4).all(|p| p[3] == 255));
}
