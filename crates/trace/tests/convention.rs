//! A voxel sits where OpenVDB puts it (issue 18): the value of voxel `ijk` belongs to the world
//! position of index `ijk` (OpenVDB's `indexToWorld(ijk)`; its point sampler rounds to the
//! nearest index), so a lone voxel renders centred on that point, in every mode and under any
//! transform. The fixture-based check against values OpenVDB computed is
//! `cooker/tests/convention.rs`; these are the closed-form cases.

mod common;

use common::*;
use vdbcook_asset::{Asset, PayloadFormat, BRICK_VOXELS};
use vdbcook_trace::*;

/// One voxel of value 1 at asset index `v` (inside the first leaf), nothing else.
fn lone_voxel(v: [usize; 3], xf: [[f64; 4]; 4]) -> Asset {
    let mut vals = vec![0.0f32; BRICK_VOXELS];
    vals[64 * v[0] + 8 * v[1] + v[2]] = 1.0;
    let mut f = FrameSpec::default();
    f.leaves.insert([0, 0, 0], Leaf::Brick(vals));
    build([1, 1, 1], xf, 0.0, &[f], PayloadFormat::F32)
}

/// The image centroid (in pixels, continuous: pixel `i` spans `[i, i+1)`) of the weight `w`.
fn centroid(img: &Image, w: impl Fn([f32; 4]) -> f64) -> [f64; 2] {
    let (mut s, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for j in 0..img.height {
        for i in 0..img.width {
            let a = w(img.pixel(i, j));
            s += a;
            sx += a * (i as f64 + 0.5);
            sy += a * (j as f64 + 0.5);
        }
    }
    assert!(s > 0.0, "the voxel is not in the picture");
    [sx / s, sy / s]
}

fn world(xf: &[[f64; 4]; 4], p: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|r| xf[r][0] * p[0] + xf[r][1] * p[1] + xf[r][2] * p[2] + xf[r][3])
}

/// A camera on the +z side of `centre` looking at it; 101² pixels, the voxel ≈ 20 px across.
fn camera_at(centre: [f64; 3], dist: f64) -> Camera {
    Camera {
        eye: [centre[0], centre[1], centre[2] + dist],
        look_at: centre,
        up: [0.0, 1.0, 0.0],
        fov_y_deg: 2.0 * (2.525 / dist).atan().to_degrees(),
    }
}

fn settings(mode: Mode) -> RenderSettings {
    RenderSettings {
        output: Output {
            width: 101,
            height: 101,
            ..Default::default()
        },
        medium: Medium {
            absorb: 1.0,
            ..Default::default()
        },
        integrator: Integrator {
            mode,
            ..Default::default()
        },
        ..Default::default()
    }
}

#[test]
fn a_lone_voxel_renders_centred_on_its_index() {
    // The measurement: voxel (0, 0, 0), identity transform, camera on +z. The old cell
    // convention put the footprint's centre at (+0.5, +0.5) voxel = 10 px right and 10 px up.
    let id = rotated(0.0, [1.0; 3], [0.0; 3]);
    let asset = lone_voxel([0, 0, 0], id);
    let cam = camera_at([0.0; 3], 20.0);
    for mode in [Mode::Density, Mode::Depth, Mode::FirstHitDensity] {
        let img = render(&asset, &cam, &settings(mode)).unwrap();
        let c = centroid(&img, |p| {
            if mode == Mode::Density {
                p[0] as f64
            } else {
                p[3] as f64
            }
        });
        for (axis, v) in c.into_iter().enumerate() {
            assert!(
                (v - 50.5).abs() < 0.02,
                "{mode:?}: centroid {c:?} px, want (50.5, 50.5) (axis {axis})"
            );
        }
    }
}

#[test]
fn a_lone_voxel_sits_at_its_world_position_under_any_transform() {
    // Rotation about z, non-uniform scale, translation; a voxel inside the leaf. Its world
    // centre is the transform of its index: the camera looks straight at that point, so the
    // footprint is centred whatever the shape of the voxel's (rotated) projection.
    for (deg, s, t, v) in [
        (30.0, [0.5, 0.8, 0.3], [1.0, -2.0, 3.0], [3, 5, 2]),
        (-75.0, [2.0, 1.0, 1.5], [-10.0, 4.0, 0.5], [7, 0, 6]),
    ] {
        let xf = rotated(deg, s, t);
        let asset = lone_voxel(v, xf);
        let centre = world(&xf, v.map(|c| c as f64));
        // About 20 px across: the voxel's largest world extent is ≤ 2 units here.
        let cam = camera_at(centre, 40.0);
        let img = render(&asset, &cam, &settings(Mode::Density)).unwrap();
        let c = centroid(&img, |p| p[0] as f64);
        assert!(
            (c[0] - 50.5).abs() < 0.05 && (c[1] - 50.5).abs() < 0.05,
            "rotation {deg}°, voxel {v:?}: centroid {c:?} px, want (50.5, 50.5)"
        );
    }
}

#[test]
fn first_hit_depth_is_the_voxel_face_half_a_voxel_before_its_centre() {
    // Identity transform, voxel (2, 3, 4): the ray down the voxel's centre line enters it at
    // world z = 4.5, so from an eye at z = 14.5 the depth is exactly 10.
    let asset = lone_voxel([2, 3, 4], rotated(0.0, [1.0; 3], [0.0; 3]));
    let cam = camera_at([2.0, 3.0, 4.0], 10.5);
    let s = settings(Mode::Depth);
    let tracer = Tracer::new(&asset, &cam, &s).unwrap();
    let hit = tracer.trace(
        [2.0, 3.0, 14.5],
        [0.0, 0.0, -1.0],
        0,
        &mut Scratch::default(),
    );
    assert_eq!(hit.value, 10.0);
    // Just inside and just outside the voxel's lower x face at x = 1.5.
    let inside = tracer.trace(
        [1.51, 3.0, 14.5],
        [0.0, 0.0, -1.0],
        0,
        &mut Scratch::default(),
    );
    let outside = tracer.trace(
        [1.49, 3.0, 14.5],
        [0.0, 0.0, -1.0],
        0,
        &mut Scratch::default(),
    );
    assert_eq!(inside.value, 10.0);
    assert_eq!(outside.value, -1.0);
}
