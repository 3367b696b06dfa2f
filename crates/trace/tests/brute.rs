//! The voxel DDA against brute force on random content: density-mode optical depth equals a
//! fine fixed-step march of `Asset::value` (nearest voxel at each step's midpoint, by OpenVDB's
//! rule: the index rounded, so voxel `i` covers `[i − ½, i + ½)`) within the
//! march's own error bound (step × max density per voxel boundary crossed), under a rotated,
//! anisotropic transform; and the hierarchical walk takes far fewer steps than the voxels a
//! naive march visits.

mod common;

use common::*;
use vdbcook_asset::{Asset, PayloadFormat};
use vdbcook_trace::*;

const XF: RotScale = RotScale {
    deg: 20.0,
    sc: [0.3, 0.4, 0.35],
    t: [1.0, 2.0, 3.0],
};
const ABSORB: f32 = 0.02;
const EXTENT: [f64; 3] = [256.0, 256.0, 128.0];

/// The asset and its leaf origins (rays aim at them).
fn asset(seed: u64, format: PayloadFormat) -> (Asset, Vec<[i64; 3]>) {
    let mut rng = XorShift(seed);
    let f = random_frame(&mut rng);
    let leaves = f.leaves.keys().copied().collect();
    (build([2, 2, 1], XF.matrix(), 0.0, &[f], format), leaves)
}

struct Brute {
    tau: f64,
    /// Voxel boundaries crossed (changes of the voxel along the march).
    crossings: u64,
    /// Distinct voxels visited inside the extent.
    voxels: u64,
}

/// Fixed-step midpoint march of `max(value, 0)` in voxel units.
fn brute(a: &Asset, eye: [f64; 3], d: [f64; 3], h: f64) -> Brute {
    let o = XF.to_index(eye);
    let di = XF.dir_to_index(d);
    let per_t = (di[0] * di[0] + di[1] * di[1] + di[2] * di[2]).sqrt();
    let mut out = Brute {
        tau: 0.0,
        crossings: 0,
        voxels: 0,
    };
    // The root extent's voxels 0 ..= EXTENT − 1 cover [−½, EXTENT − ½) of index space.
    let Some((t0, t1)) = slab_interval(o, di, [-0.5; 3], EXTENT.map(|e| e - 0.5)) else {
        return out;
    };
    let n = ((t1 - t0) / h).ceil() as u64;
    let mut last = None;
    for k in 0..n {
        let ta = t0 + k as f64 * h;
        let tb = (ta + h).min(t1);
        let tm = 0.5 * (ta + tb);
        let cell = [0, 1, 2].map(|i| (o[i] + tm * di[i] + 0.5).floor() as i64);
        if last != Some(cell) {
            out.voxels += 1;
            if last.is_some() {
                out.crossings += 1;
            }
            last = Some(cell);
        }
        out.tau += (a.value(0, cell) as f64).max(0.0) * (tb - ta) * per_t;
    }
    out
}

fn density(a: &Asset, mode: Mode) -> Tracer<'_> {
    let cam = Camera {
        eye: [0.0; 3],
        look_at: [1.0, 0.0, 0.0],
        up: [0.0, 1.0, 0.0],
        fov_y_deg: 40.0,
    };
    let s = RenderSettings {
        medium: Medium {
            absorb: ABSORB,
            ..Default::default()
        },
        integrator: Integrator {
            mode,
            ..Default::default()
        },
        ..Default::default()
    };
    Tracer::new(a, &cam, &s).unwrap()
}

/// A random ray from outside through a random point of a stored leaf (every fourth ray: of the
/// tiled region).
fn random_ray(rng: &mut XorShift, leaves: &[[i64; 3]]) -> ([f64; 3], [f64; 3]) {
    let p = if rng.next_u64().is_multiple_of(4) {
        [
            128.0 + rng.range(0.0, 128.0),
            rng.range(0.0, 128.0),
            rng.range(0.0, 128.0),
        ]
    } else {
        let o = leaves[(rng.next_u64() % leaves.len() as u64) as usize];
        [0, 1, 2].map(|k| o[k] as f64 + rng.range(0.0, 8.0))
    };
    let d = rng.dir();
    let target = XF.to_world(p);
    ([0, 1, 2].map(|k| target[k] - 150.0 * d[k]), d)
}

#[test]
fn optical_depth_matches_a_fine_brute_force_march() {
    for (seed, format) in [(11u64, PayloadFormat::F32), (12, PayloadFormat::F16)] {
        let (a, leaves) = asset(seed, format);
        let tracer = density(&a, Mode::Density);
        let mut scratch = Scratch::default();
        let mut rng = XorShift(seed * 7919);
        let h = 2e-3;
        let mut crossed_bricks = 0;
        for i in 0..40 {
            let (eye, d) = random_ray(&mut rng, &leaves);
            let b = brute(&a, eye, d, h);
            let got = tracer.trace(eye, d, 0, &mut scratch);
            let tau = -(got.value as f64).ln() / ABSORB as f64;
            // Midpoint error: at most one step's worth of the largest jump (≤ 2.5) per crossing,
            // plus f32 rounding of T.
            let tol = b.crossings as f64 * h * 2.5 * 0.5 + 1e-5 * b.tau.max(1.0);
            assert!(
                (tau - b.tau).abs() <= tol,
                "{format:?} ray {i}: DDA τ {tau} vs brute {} (tol {tol})",
                b.tau
            );
            crossed_bricks += (b.tau > 0.5) as u32;
        }
        assert!(
            crossed_bricks > 30,
            "rays crossed content ({crossed_bricks})"
        );
    }
}

#[test]
fn axis_parallel_rays_on_boundaries_match_brute_force() {
    // Identity-rotation transform so index-space axes are world axes exactly.
    let mut rng = XorShift(99);
    let f = random_frame(&mut rng);
    let a = build(
        [2, 2, 1],
        uniform_scale(1.0, [0.0; 3]),
        0.0,
        &[f],
        PayloadFormat::F32,
    );
    let tracer = density(&a, Mode::Density);
    let mut scratch = Scratch::default();
    // Voxel boundaries (k − ½ in index space: node, leaf and region faces) and a few centres.
    for y in [-0.5f64, 7.5, 63.5, 126.5, 127.5, 200.0] {
        for z in [-0.5f64, 15.5, 40.0, 127.49] {
            for (eye, d) in [
                ([-5.0, y, z], [1.0, 0.0, 0.0]),
                ([300.0, y, z], [-1.0, 0.0, 0.0]),
                ([y, -5.0, z], [0.0, 1.0, 0.0]),
                ([y, z, 200.0], [0.0, 0.0, -1.0]),
            ] {
                // Exact per-voxel sum along the axis: every voxel is crossed over length 1.
                let axis = d.iter().position(|c| *c != 0.0).unwrap();
                let mut want = 0.0f64;
                for k in 0..EXTENT[axis] as i64 {
                    let mut cell = eye.map(|c| (c + 0.5).floor() as i64);
                    cell[axis] = k;
                    want += (a.value(0, cell) as f64).max(0.0);
                }
                let got = tracer.trace(eye, d, 0, &mut scratch);
                let tau = -(got.value as f64).ln() / ABSORB as f64;
                assert!(
                    (tau - want).abs() <= 1e-5 * want.max(1.0),
                    "axis ray {eye:?} {d:?}: {tau} vs {want}"
                );
            }
        }
    }
}

#[test]
fn hierarchical_walk_takes_fewer_steps_than_a_naive_march() {
    // Sparse content: one brick in a 3×3×3-region extent.
    let mut f = FrameSpec::default();
    f.leaves.insert(
        [136, 200, 64],
        Leaf::Brick(vec![0.5; vdbcook_asset::BRICK_VOXELS]),
    );
    let xf = uniform_scale(1.0, [0.0; 3]);
    let a = build([3, 3, 3], xf, 0.0, &[f], PayloadFormat::F32);
    let tracer = density(&a, Mode::Steps);
    let mut scratch = Scratch::default();
    let mut rng = XorShift(5);
    let (mut ours, mut naive) = (0u64, 0u64);
    for _ in 0..50 {
        let p = [0, 1, 2].map(|_| rng.range(0.0, 8.0));
        let d = rng.dir();
        let target = [136.0 + p[0], 200.0 + p[1], 64.0 + p[2]];
        let eye = [0, 1, 2].map(|k| target[k] - 1000.0 * d[k]);
        let got = tracer.trace(eye, d, 0, &mut scratch);
        assert_eq!(got.value, got.steps as f32, "Steps mode reports the count");
        // Naive: one step per voxel of the extent along the ray.
        let o = eye;
        let mut n = 0u64;
        if let Some((t0, t1)) = slab_interval(o, d, [0.0; 3], [384.0; 3]) {
            let mut last = None;
            let k_max = ((t1 - t0) / 0.01).ceil() as u64;
            for k in 0..k_max {
                let t = t0 + (k as f64 + 0.5) * 0.01;
                let c = [0, 1, 2].map(|i| (o[i] + t * d[i]).floor() as i64);
                if last != Some(c) {
                    n += 1;
                    last = Some(c);
                }
            }
        }
        assert!(n > 100, "the ray crosses the extent");
        assert!(got.steps as u64 * 4 < n, "steps {} vs naive {n}", got.steps);
        ours += got.steps as u64;
        naive += n;
    }
    assert!(ours * 8 < naive, "total {ours} vs naive {naive}");
}
