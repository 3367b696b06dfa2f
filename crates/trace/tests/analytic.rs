//! Density mode against closed forms: a box of constant density built from tiles, constant
//! bricks and partial bricks across two root regions. Transmittance must equal
//! `exp(−absorb·σ·L)` with `L` the ray's path length through the box from an independent slab
//! test — for axis-parallel, diagonal, grazing and random rays, a camera inside the box, and
//! rays along leaf, node and region boundaries.

mod common;

use common::*;
use vdbcook_asset::{Asset, PayloadFormat};
use vdbcook_trace::*;

const LO: [i64; 3] = [100, 6, 20];
const HI: [i64; 3] = [150, 37, 53];
const SIGMA: f32 = 1.5;
const ABSORB: f32 = 0.02;
/// index = (world − T) / S.
const S: f64 = 0.5;
const T: [f64; 3] = [1.0, 2.0, 3.0];

fn box_asset(xf: [[f64; 4]; 4], format: PayloadFormat) -> Asset {
    let mut f = FrameSpec::default();
    box_leaves(LO, HI, SIGMA, &mut f.leaves);
    build([2, 1, 1], xf, 0.0, &[f], format)
}

fn settings(unit: LengthUnit) -> RenderSettings {
    RenderSettings {
        medium: Medium {
            absorb: ABSORB,
            unit,
            ..Default::default()
        },
        integrator: Integrator {
            mode: Mode::Density,
            ..Default::default()
        },
        ..Default::default()
    }
}

fn any_camera() -> Camera {
    Camera {
        eye: [0.0, 0.0, -10.0],
        look_at: [0.0; 3],
        up: [0.0, 1.0, 0.0],
        fov_y_deg: 45.0,
    }
}

/// Cell point → world under the uniform transform. OpenVDB centres voxel `i` on index `i`, so
/// the voxels `LO ..= HI − 1` cover the index box `[LO − ½, HI − ½)`: in cells (index + ½) that
/// is `[LO, HI)`, and a cell point `p` is the index point `p − ½`.
fn w(p: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|a| (p[a] - 0.5) * S + T[a])
}

/// The box in world space (axis-aligned under the uniform transform).
fn world_box() -> ([f64; 3], [f64; 3]) {
    (w(LO.map(|c| c as f64)), w(HI.map(|c| c as f64)))
}

fn trace(asset: &Asset, s: &RenderSettings, eye: [f64; 3], dir: [f64; 3]) -> Sample {
    let tracer = Tracer::new(asset, &any_camera(), s).unwrap();
    tracer.trace(eye, dir, 0, &mut Scratch::default())
}

/// Checks one ray under the uniform transform in voxel units: L_voxel = L_world / S.
fn check(asset: &Asset, eye: [f64; 3], dir: [f64; 3], what: &str) -> f64 {
    let (lo, hi) = world_box();
    let n = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
    let d = dir.map(|c| c / n);
    let l = slab_length(eye, d, lo, hi) / S;
    let want = (-(ABSORB as f64) * SIGMA as f64 * l).exp();
    let got = trace(asset, &settings(LengthUnit::Voxel), eye, d);
    assert!(got.value.is_finite() && got.rgba.iter().all(|c| c.is_finite()));
    assert!(
        (got.value as f64 - want).abs() < 2e-6,
        "{what}: T = {} want {want} (L = {l} voxels)",
        got.value
    );
    assert!((got.rgba[0] as f64 - (1.0 - want)).abs() < 2e-6);
    l
}

#[test]
fn axis_parallel_rays_match_the_slab_length() {
    for format in [PayloadFormat::F32, PayloadFormat::F16] {
        let a = box_asset(uniform_scale(S, T), format);
        // Through generic interior points and exactly along leaf boundaries (y = 8, 16, 32;
        // z = 24, 40) and the lower faces (y = 6, z = 20: inside, cells are half-open).
        for &(y, z) in &[
            (10.3, 30.7),
            (8.0, 24.0),
            (16.0, 40.0),
            (6.0, 20.0),
            (32.0, 52.5),
        ] {
            for sign in [1.0, -1.0] {
                let eye = w([if sign > 0.0 { -20.0 } else { 300.0 }, y, z]);
                let l = check(&a, eye, [sign, 0.0, 0.0], &format!("x ray y={y} z={z}"));
                assert!((l - 50.0).abs() < 1e-9, "full width {l}");
            }
        }
        // Along y and z, including the region boundary plane x = 128.
        for &x in &[128.0, 100.0, 127.999, 149.5] {
            let l = check(
                &a,
                w([x, -5.0, 30.0]),
                [0.0, 1.0, 0.0],
                &format!("y ray x={x}"),
            );
            assert!((l - 31.0).abs() < 1e-9);
            let l = check(
                &a,
                w([x, 20.0, 500.0]),
                [0.0, 0.0, -1.0],
                &format!("z ray x={x}"),
            );
            assert!((l - 33.0).abs() < 1e-9);
        }
    }
}

#[test]
fn grazing_rays_on_upper_faces_and_outside_miss() {
    let a = box_asset(uniform_scale(S, T), PayloadFormat::F32);
    // Upper faces are outside the half-open box: y = 37 and z = 53 see nothing.
    assert_eq!(
        check(&a, w([-20.0, 37.0, 30.0]), [1.0, 0.0, 0.0], "y = 37 face"),
        0.0
    );
    assert_eq!(
        check(&a, w([-20.0, 20.0, 53.0]), [1.0, 0.0, 0.0], "z = 53 face"),
        0.0
    );
    // Along the lower edge (y = 6, z = 20): inside.
    assert_eq!(
        check(&a, w([-20.0, 6.0, 20.0]), [1.0, 0.0, 0.0], "edge"),
        50.0
    );
    // Along the extent's own faces and outside it.
    check(&a, w([-20.0, 0.0, 0.0]), [1.0, 0.0, 0.0], "extent face");
    check(
        &a,
        w([-20.0, 128.0, 30.0]),
        [1.0, 0.0, 0.0],
        "extent top face",
    );
    check(
        &a,
        w([-20.0, -3.0, 30.0]),
        [1.0, 0.0, 0.0],
        "below the extent",
    );
    // Pointing away from the box.
    check(&a, w([-20.0, 20.0, 30.0]), [-1.0, 0.0, 0.0], "away");
    // Nearly parallel to a face, crossing it over a long distance.
    check(
        &a,
        w([-20.0, 6.0 + 1e-3, 30.0]),
        [1.0, -1e-4, 0.0],
        "shallow exit",
    );
    check(
        &a,
        w([-20.0, 37.0 - 1e-3, 30.0]),
        [1.0, 2e-4, 1e-7],
        "shallow through top",
    );
}

#[test]
fn diagonal_and_random_rays_match_the_slab_length() {
    let a = box_asset(uniform_scale(S, T), PayloadFormat::F32);
    // Exact diagonals through box corners and the box centre.
    let c = [125.0, 21.5, 36.5];
    for d in [
        [1.0, 1.0, 1.0],
        [-1.0, 1.0, -1.0],
        [1.0, -1.0, 0.0],
        [0.0, 1.0, 1.0],
    ] {
        let eye = w([0, 1, 2].map(|i| c[i] - 80.0 * d[i]));
        check(&a, eye, d, &format!("diagonal {d:?}"));
    }
    // The exact corner diagonal (100, 6, 20) → passes through lattice points all the way.
    check(
        &a,
        w([90.0, -4.0, 10.0]),
        [1.0, 1.0, 1.0],
        "corner diagonal",
    );
    let mut rng = XorShift(0x1234_5678_9abc_def1);
    let mut hits = 0;
    for i in 0..400 {
        let p = [0, 1, 2].map(|k| rng.range(LO[k] as f64 - 5.0, HI[k] as f64 + 5.0));
        let d = rng.dir();
        let eye = w([0, 1, 2].map(|k| p[k] - 150.0 * d[k]));
        if check(&a, eye, d, &format!("random ray {i}")) > 0.0 {
            hits += 1;
        }
    }
    assert!(hits > 200, "most random rays cross the box ({hits})");
}

#[test]
fn camera_inside_the_box_sees_the_distance_to_the_exit() {
    let a = box_asset(uniform_scale(S, T), PayloadFormat::F32);
    let inside = w([120.25, 20.5, 33.75]);
    let cam = Camera {
        eye: inside,
        look_at: w([140.0, 30.0, 21.0]),
        up: [0.0, 1.0, 0.0],
        fov_y_deg: 100.0,
    };
    let s = {
        let base = settings(LengthUnit::Voxel);
        RenderSettings {
            output: Output {
                width: 24,
                height: 16,
                ..base.output
            },
            ..base
        }
    };
    let img = render(&a, &cam, &s).unwrap();
    let (lo, hi) = world_box();
    for j in 0..16 {
        for i in 0..24 {
            let d = cam.ray_dir(i, j, 24, 16).unwrap();
            let l = slab_length(inside, d, lo, hi) / S;
            assert!(l > 0.0, "inside: every ray crosses some density");
            let want = (-(ABSORB as f64) * SIGMA as f64 * l).exp();
            let got = img.value[(j * 24 + i) as usize] as f64;
            assert!((got - want).abs() < 2e-6, "pixel {i},{j}: {got} vs {want}");
        }
    }
    // Exact axis directions from inside too.
    for d in [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]] {
        check(&a, inside, d, "inside, axis");
    }
}

#[test]
fn rotated_anisotropic_transform_in_world_units() {
    // index → world: rotate 30° about Z after scaling (0.5, 0.25, 1), then translate.
    let (deg, sc, t) = (30.0f64, [0.5, 0.25, 1.0], [4.0, -3.0, 2.0]);
    let a = box_asset(rotated(deg, sc, t), PayloadFormat::F32);
    let (sn, c) = deg.to_radians().sin_cos();
    // Closed-form inverse: index = S⁻¹ Rᵀ (world − t).
    let to_index = |p: [f64; 3]| {
        let q = [p[0] - t[0], p[1] - t[1], p[2] - t[2]];
        [
            (c * q[0] + sn * q[1]) / sc[0],
            (-sn * q[0] + c * q[1]) / sc[1],
            q[2] / sc[2],
        ]
    };
    let dir_to_index = |d: [f64; 3]| {
        [
            (c * d[0] + sn * d[1]) / sc[0],
            (-sn * d[0] + c * d[1]) / sc[1],
            d[2] / sc[2],
        ]
    };
    let to_world = |p: [f64; 3]| {
        let q = [p[0] * sc[0], p[1] * sc[1], p[2] * sc[2]];
        [
            c * q[0] - sn * q[1] + t[0],
            sn * q[0] + c * q[1] + t[1],
            q[2] + t[2],
        ]
    };
    let mut rng = XorShift(77);
    for unit in [LengthUnit::World, LengthUnit::Voxel] {
        for i in 0..300 {
            let p = [0, 1, 2].map(|k| rng.range(LO[k] as f64 - 3.0, HI[k] as f64 + 3.0));
            let d = rng.dir();
            let target = to_world(p);
            let eye = [0, 1, 2].map(|k| target[k] - 60.0 * d[k]);
            // The world direction is unit length: the index parameter is world distance.
            let di = dir_to_index(d);
            // Voxels LO ..= HI − 1 cover [LO − ½, HI − ½) of index space (OpenVDB's centres).
            let l_world = slab_length(
                to_index(eye),
                di,
                LO.map(|v| v as f64 - 0.5),
                HI.map(|v| v as f64 - 0.5),
            );
            let l = match unit {
                LengthUnit::World => l_world,
                LengthUnit::Voxel => {
                    l_world * (di[0] * di[0] + di[1] * di[1] + di[2] * di[2]).sqrt()
                }
            };
            let want = (-(ABSORB as f64) * SIGMA as f64 * l).exp();
            let got = trace(&a, &settings(unit), eye, d).value as f64;
            assert!(
                (got - want).abs() < 2e-6,
                "{unit:?} ray {i}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn tiled_regions_and_opaque_rays() {
    // One whole 128³ region tiled at 0.25 (frame 0) — a ray through it crosses 128 voxels.
    let mut f = FrameSpec::default();
    f.regions.insert([1, 0, 0], 0.25);
    let a = build(
        [2, 1, 1],
        uniform_scale(1.0, [0.0; 3]),
        0.0,
        &[f],
        PayloadFormat::F32,
    );
    let s = {
        let base = settings(LengthUnit::Voxel);
        RenderSettings {
            medium: Medium {
                absorb: 0.05,
                ..base.medium
            },
            ..base
        }
    };
    let got = trace(&a, &s, [-10.0, 64.5, 3.0], [1.0, 0.0, 0.0]).value as f64;
    assert!((got - (-0.05f64 * 0.25 * 128.0).exp()).abs() < 1e-6);
    // A dense enough medium stops the ray (T below 2e-9) without NaN.
    let s = RenderSettings {
        medium: Medium {
            absorb: 5.0,
            ..s.medium
        },
        ..s
    };
    let got = trace(&a, &s, [-10.0, 64.5, 3.0], [1.0, 0.0, 0.0]);
    assert!(got.value < 3e-9 && got.rgba[0] == 1.0);
}
