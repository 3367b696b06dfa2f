//! The integrators that sample: single scatter with no scattering is pure absorption (within
//! one step of path length of the analytic transmittance); delta tracking's escape fraction
//! converges to the exact density-mode transmittance (constant box and random bricks, where
//! null collisions happen), its radiance converges to single scatter's small-step limit, and its
//! progressive batches add up to one render.

mod common;

use common::*;
use vdbcook_asset::{Asset, PayloadFormat};
use vdbcook_trace::*;

const LO: [i64; 3] = [100, 6, 20];
const HI: [i64; 3] = [150, 37, 53];
const SIGMA: f32 = 1.5;

fn box_asset() -> Asset {
    let mut f = FrameSpec::default();
    box_leaves(LO, HI, SIGMA, &mut f.leaves);
    build(
        [2, 1, 1],
        uniform_scale(0.5, [1.0, 2.0, 3.0]),
        0.0,
        &[f],
        PayloadFormat::F32,
    )
}

fn world(p: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|k| p[k] * 0.5 + [1.0, 2.0, 3.0][k])
}

/// A camera looking at the box centre from outside, narrow enough that every pixel crosses it.
fn camera() -> Camera {
    Camera {
        eye: world([125.0 - 60.0, 21.5 + 25.0, 36.5 - 70.0]),
        look_at: world([125.0, 21.5, 36.5]),
        up: [0.0, 1.0, 0.0],
        fov_y_deg: 12.0,
    }
}

fn settings(mode: Mode) -> RenderSettings {
    RenderSettings {
        output: Output {
            width: 6,
            height: 4,
            ..Default::default()
        },
        integrator: Integrator {
            mode,
            cutoff: 0.0,
            ..Default::default()
        },
        ..Default::default()
    }
}

#[test]
fn single_scatter_without_scattering_is_pure_absorption() {
    let a = box_asset();
    let cam = camera();
    let (lo, hi) = (world(LO.map(|c| c as f64)), world(HI.map(|c| c as f64)));
    for step in [1.0f32, 0.37] {
        let absorb = 0.05f32;
        let s = {
            let base = settings(Mode::SingleScatter);
            RenderSettings {
                medium: Medium {
                    absorb,
                    scatter: 0.0,
                    ..base.medium
                },
                integrator: Integrator {
                    step,
                    ..base.integrator
                },
                ..base
            }
        };
        let img = render(&a, &cam, &s).unwrap();
        for j in 0..4 {
            for i in 0..6 {
                let d = cam.ray_dir(i, j, 6, 4).unwrap();
                // Voxel units: index length = world length / 0.5.
                let l = slab_length(cam.eye, d, lo, hi) / 0.5;
                assert!(l > 10.0, "pixel {i},{j} crosses the box");
                let want = 1.0 - (-(absorb as f64) * SIGMA as f64 * l).exp();
                let px = img.pixel(i, j);
                assert_eq!(&px[..3], &[0.0; 3], "no scattering, no light");
                // The march counts ⌈L/step⌉ or ⌊L/step⌋ samples: one step of path at most.
                let tol = absorb as f64 * SIGMA as f64 * step as f64 + 1e-6;
                assert!(
                    (px[3] as f64 - want).abs() <= tol,
                    "step {step} pixel {i},{j}: alpha {} vs {want}",
                    px[3]
                );
            }
        }
    }
}

/// Mean and per-pixel checks of delta tracking's escape fraction against Density's exact `T`.
fn check_escape(a: &Asset, cam: &Camera, absorb: f32, scatter: f32, spp: u32) {
    let exact = render(a, cam, &{
        let base = settings(Mode::Density);
        RenderSettings {
            medium: Medium {
                absorb: absorb + scatter,
                ..base.medium
            },
            ..base
        }
    })
    .unwrap();
    let s = {
        let base = settings(Mode::DeltaTracking);
        RenderSettings {
            medium: Medium {
                absorb,
                scatter,
                ..base.medium
            },
            integrator: Integrator {
                spp,
                seed: 42,
                ..base.integrator
            },
            ..base
        }
    };
    let img = render(a, cam, &s).unwrap();
    let (mut sum_got, mut sum_want) = (0.0, 0.0);
    for k in 0..img.value.len() {
        let (got, want) = (img.value[k] as f64, exact.value[k] as f64);
        assert!((img.rgba[4 * k + 3] as f64 - (1.0 - got)).abs() < 1e-6);
        // Binomial standard deviation of the escape fraction: 5σ per pixel.
        let sd = (want * (1.0 - want) / spp as f64).sqrt();
        assert!(
            (got - want).abs() <= 5.0 * sd + 1e-3,
            "pixel {k}: escaped {got} vs T {want} (σ {sd})"
        );
        sum_got += got;
        sum_want += want;
    }
    let n = img.value.len() as f64;
    assert!(
        ((sum_got - sum_want) / n).abs() < 0.01,
        "mean escape {} vs mean T {}",
        sum_got / n,
        sum_want / n
    );
}

#[test]
fn delta_tracking_converges_to_the_density_transmittance() {
    let a = box_asset();
    check_escape(&a, &camera(), 0.03, 0.0, 4096);
    check_escape(&a, &camera(), 0.01, 0.02, 4096);
    // Random bricks: majorants are brick maxima, so most tentative collisions are null.
    let mut rng = XorShift(8);
    let f = random_frame(&mut rng);
    let r = build(
        [2, 2, 1],
        uniform_scale(1.0, [0.0; 3]),
        0.0,
        &[f],
        PayloadFormat::F32,
    );
    let cam = Camera {
        eye: [-60.0, 70.0, -90.0],
        look_at: [64.0, 64.0, 64.0],
        up: [0.0, 1.0, 0.0],
        fov_y_deg: 50.0,
    };
    check_escape(&r, &cam, 0.02, 0.0, 4096);
}

#[test]
fn delta_tracking_radiance_converges_to_small_step_single_scatter() {
    let a = box_asset();
    let cam = camera();
    let base = {
        let base = settings(Mode::SingleScatter);
        RenderSettings {
            medium: Medium {
                absorb: 0.01,
                scatter: 0.04,
                ..base.medium
            },
            lighting: Lighting {
                light_dir: [0.3, 0.8, -0.2],
                ..base.lighting
            },
            integrator: Integrator {
                gain: 0.1,
                ..base.integrator
            },
            ..base
        }
    };
    let fine = render(
        &a,
        &cam,
        &RenderSettings {
            integrator: Integrator {
                step: 0.05,
                shadow_step: 0.05,
                ..base.integrator.clone()
            },
            ..base.clone()
        },
    )
    .unwrap();
    let dt = render(
        &a,
        &cam,
        &RenderSettings {
            integrator: Integrator {
                mode: Mode::DeltaTracking,
                spp: 8192,
                seed: 7,
                ..base.integrator
            },
            ..base
        },
    )
    .unwrap();
    let (mut sf, mut sd) = (0.0, 0.0);
    for k in 0..24 {
        let (f, d) = (fine.rgba[4 * k] as f64, dt.rgba[4 * k] as f64);
        assert!(f > 0.01, "lit pixel {k}");
        assert!(
            (f - d).abs() < 0.08 * f,
            "pixel {k}: single scatter {f} vs delta {d}"
        );
        sf += f;
        sd += d;
    }
    assert!((sf - sd).abs() < 0.025 * sf, "means {sf} vs {sd}");
}

#[test]
fn progressive_batches_add_up_to_one_render() {
    // Both stochastic modes: delta tracking and the reference path tracer.
    for mode in [Mode::DeltaTracking, Mode::Reference] {
        let a = box_asset();
        let cam = camera();
        let s = {
            let base = settings(mode);
            RenderSettings {
                medium: Medium {
                    absorb: 0.01,
                    scatter: 0.04,
                    ..base.medium
                },
                integrator: Integrator {
                    spp: 64,
                    seed: 3,
                    ..base.integrator
                },
                ..base
            }
        };
        let all = render(&a, &cam, &s).unwrap();
        assert!(
            all.rgba.chunks(4).all(|p| p[0] > 0.0 && p[3] > 0.5),
            "{mode:?}: a lit, dense image"
        );
        let first = render(
            &a,
            &cam,
            &RenderSettings {
                integrator: Integrator {
                    spp: 24,
                    ..s.integrator.clone()
                },
                ..s.clone()
            },
        )
        .unwrap();
        let rest = render(
            &a,
            &cam,
            &RenderSettings {
                integrator: Integrator {
                    spp: 40,
                    first_sample: 24,
                    ..s.integrator.clone()
                },
                ..s.clone()
            },
        )
        .unwrap();
        for k in 0..all.rgba.len() {
            let merged = (24.0 * first.rgba[k] as f64 + 40.0 * rest.rgba[k] as f64) / 64.0;
            assert!(
                (merged - all.rgba[k] as f64).abs() < 1e-5,
                "{mode:?}: channel {k}"
            );
        }
        // Another seed gives another image; the same seed the same one.
        let again = render(&a, &cam, &s).unwrap();
        assert_eq!(again, all);
        let other = render(
            &a,
            &cam,
            &RenderSettings {
                integrator: Integrator {
                    seed: 4,
                    ..s.integrator
                },
                ..s
            },
        )
        .unwrap();
        assert_ne!(other, all);
    }
}
