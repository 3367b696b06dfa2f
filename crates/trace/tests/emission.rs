//! Emission in the density march against its closed form: a box of constant temperature `V`
//! (Kelvin) with absorption `a` per unit value per voxel; along a ray crossing `L` voxels of it
//! the emitted light reaching the eye is `E(V) · (1 − e^{−aVL}) / (aV)` (`E(V)·L` without
//! absorption), `E` the blackbody radiance of the settings (its colours are checked against the
//! CIE's Planckian locus in `vdbcook-scene`). Rays that miss the box, and a box at or below the
//! range's low end, emit nothing; the transmittance is unchanged by emission.

mod common;

use common::*;
use vdbcook_trace::*;

const LO: [i64; 3] = BOX_LO;
const HI: [i64; 3] = BOX_HI;
const S: f64 = BOX_S;

fn box_asset(v: f32) -> vdbcook_asset::Asset {
    constant_box(v)
}

fn w(p: [f64; 3]) -> [f64; 3] {
    box_world(p)
}

fn settings(absorb: f32) -> RenderSettings {
    RenderSettings {
        medium: Medium {
            absorb,
            emission: Some(Emission {
                range: [800.0, 2000.0],
                kelvin: [800.0, 2000.0],
                intensity: 2.0,
                channel: 0,
            }),
            ..Default::default()
        },
        integrator: Integrator {
            mode: Mode::Density,
            ..Default::default()
        },
        ..Default::default()
    }
}

fn camera() -> Camera {
    Camera {
        eye: [0.0, 0.0, -10.0],
        look_at: [0.0; 3],
        up: [0.0, 1.0, 0.0],
        fov_y_deg: 45.0,
    }
}

#[test]
fn emitted_light_matches_the_closed_form() {
    let value = 1500.0f32;
    let asset = box_asset(value);
    let (lo, hi) = (w(LO.map(|c| c as f64)), w(HI.map(|c| c as f64)));
    // The box spans world (50.75, 4.75, 12.75) .. (75.75, 20.25, 29.25).
    let rays = [
        ([60.0, 12.0, -5.0], [0.0, 0.0, 1.0]),  // along z
        ([40.0, 11.0, 20.0], [1.0, 0.1, 0.05]), // mostly along x, across two root regions
        ([70.0, 0.0, 14.0], [-0.3, 0.8, 0.2]),  // oblique
        ([20.0, 12.0, -5.0], [0.0, 1.0, 0.0]),  // misses the box
    ];
    let mut hits = 0;
    for absorb in [0.0f32, 2e-4, 2e-3] {
        let s = settings(absorb);
        let e = s.medium.emission.unwrap();
        let radiance = e.radiance(&e.table(), value);
        let tracer = Tracer::new(&asset, &camera(), &s).unwrap();
        for (eye, dir) in rays {
            let n: f64 = dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2];
            let d = dir.map(|c| c / n.sqrt());
            let len = slab_length(eye, d, lo, hi) / S; // voxels
            let x = absorb as f64 * value as f64 * len;
            let gain = if x > 0.0 {
                (1.0 - (-x).exp()) / (absorb as f64 * value as f64)
            } else {
                len
            };
            let px = tracer.trace(eye, d, 0, &mut Scratch::default());
            let t = (-x).exp();
            assert!(
                (px.value as f64 - t).abs() < 1e-6,
                "T {} want {t}",
                px.value
            );
            for (c, r) in radiance.iter().enumerate() {
                let want = *r as f64 * gain + (1.0 - t);
                assert!(
                    (px.rgba[c] as f64 - want).abs() <= 1e-5 * want.max(1.0),
                    "absorb {absorb}, ray {eye:?}: channel {c} {} want {want} (L = {len} voxels)",
                    px.rgba[c]
                );
            }
            if len == 0.0 {
                assert_eq!(&px.rgba[..3], &[0.0; 3]);
            } else {
                hits += 1;
            }
        }
    }
    assert_eq!(
        hits, 9,
        "three rays hit the box, for each of three absorptions"
    );
    // At the range's low end the box emits nothing.
    let cold = box_asset(800.0);
    let tracer = Tracer::new(&cold, &camera(), &settings(0.0)).unwrap();
    let px = tracer.trace(
        [20.0, 12.0, -5.0],
        [0.0, 0.0, 1.0],
        0,
        &mut Scratch::default(),
    );
    assert_eq!(&px.rgba[..3], &[0.0; 3]);
}

#[test]
fn emission_outside_the_shaded_modes_or_out_of_range_is_refused() {
    let asset = box_asset(1000.0);
    for bad in [
        {
            let base = settings(0.1);
            RenderSettings {
                integrator: Integrator {
                    mode: Mode::Steps,
                    ..base.integrator
                },
                ..base
            }
        },
        {
            let base = settings(0.1);
            RenderSettings {
                medium: Medium {
                    emission: Some(Emission {
                        range: [2000.0, 800.0],
                        kelvin: [2000.0, 800.0],
                        intensity: 1.0,
                        channel: 0,
                    }),
                    ..base.medium
                },
                ..base
            }
        },
        {
            let base = settings(0.1);
            RenderSettings {
                medium: Medium {
                    emission: Some(Emission {
                        range: [800.0, 2000.0],
                        kelvin: [800.0, 2000.0],
                        intensity: f32::NAN,
                        channel: 0,
                    }),
                    ..base.medium
                },
                ..base
            }
        },
    ] {
        let e = render(&asset, &camera(), &bad).unwrap_err();
        assert!(matches!(e, TraceError::Setting(_)), "{e}");
    }
}

/// The scatter mode's emission: at each grid sample `s = k·step` inside the box, `T · E · step ·
/// φ(x)` with `x = (absorb + scatter)·V·step`, which sums over the `n` samples to
/// `E · (1 − e^{−x·n}) / ((absorb + scatter)·V)` — the closed form over `n` steps.
#[test]
fn scatter_mode_emission_sums_to_the_closed_form_over_its_samples() {
    let value = 1500.0f32;
    let asset = box_asset(value);
    let (lo, hi) = (w(LO.map(|c| c as f64)), w(HI.map(|c| c as f64)));
    // Absorptions that keep `3T²` above the cutoff through the box (the march stops there).
    for (absorb, step) in [(0.0f32, 1.0f32), (1e-5, 0.7), (3e-5, 1.3)] {
        let s = {
            let base = settings(absorb);
            RenderSettings {
                medium: Medium {
                    absorb,
                    scatter: 0.0,
                    ..base.medium
                },
                lighting: Lighting {
                    light_color: [0.0; 3],
                    ..base.lighting
                },
                integrator: Integrator {
                    mode: Mode::SingleScatter,
                    step,
                    ..base.integrator
                },
                ..base
            }
        };
        let e = s.medium.emission.unwrap();
        let radiance = e.radiance(&e.table(), value);
        let tracer = Tracer::new(&asset, &camera(), &s).unwrap();
        for (eye, dir) in [
            ([60.0, 12.0, -5.0], [0.0, 0.0, 1.0]),
            ([40.0, 11.0, 20.0], [1.0, 0.1, 0.05]),
        ] {
            let n: f64 = dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2];
            let d = dir.map(|c| c / n.sqrt());
            let (t0, t1) = slab_interval(eye, d, lo, hi).unwrap();
            // Samples at k·step (voxel lengths from the eye) inside [t0, t1) / S.
            let count = ((t1 / S) / step as f64).ceil() - ((t0 / S) / step as f64).ceil();
            let kappa = absorb as f64 * value as f64;
            let gain = if kappa > 0.0 {
                (1.0 - (-kappa * step as f64 * count).exp()) / kappa
            } else {
                step as f64 * count
            };
            let px = tracer.trace(eye, d, 0, &mut Scratch::default());
            for (c, r) in radiance.iter().enumerate() {
                let want = *r as f64 * gain;
                assert!(
                    (px.rgba[c] as f64 - want).abs() <= 1e-5 * want.max(1.0),
                    "absorb {absorb} step {step}: channel {c} {} want {want} ({count} samples)",
                    px.rgba[c]
                );
            }
        }
    }
}

/// The reference path tracer and delta tracking gather emission by a collision estimator;
/// without scattering its mean is the density march's emitted light (the same `∫ T E ds`), for
/// a purely emitting box (no absorption: only the majorant floor samples it) and for absorbing
/// ones.
#[test]
fn stochastic_emission_converges_to_the_density_march() {
    let value = 1500.0f32;
    let asset = box_asset(value);
    let rays = [
        ([60.0, 12.0, -5.0], [0.0, 0.0, 1.0]),
        ([40.0, 11.0, 20.0], [1.0, 0.1, 0.05]),
    ];
    for (mode, absorb) in [0.0f32, 2e-4, 2e-3]
        .into_iter()
        .flat_map(|a| [(Mode::Reference, a), (Mode::DeltaTracking, a)])
    {
        let dens = settings(absorb);
        let refs = RenderSettings {
            medium: Medium {
                scatter: 0.0,
                ..dens.medium.clone()
            },
            lighting: Lighting {
                light_color: [0.0; 3],
                sky: [0.0; 3],
                ..dens.lighting.clone()
            },
            integrator: Integrator {
                mode,
                spp: MAX_SPP,
                ..dens.integrator.clone()
            },
            ..dens.clone()
        };
        let td = Tracer::new(&asset, &camera(), &dens).unwrap();
        let tr = Tracer::new(&asset, &camera(), &refs).unwrap();
        for (eye, dir) in rays {
            let n: f64 = dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2];
            let d = dir.map(|c| c / n.sqrt());
            let px = td.trace(eye, d, 0, &mut Scratch::default());
            let want: Vec<f64> = (0..3)
                .map(|c| px.rgba[c] as f64 - (1.0 - px.value as f64))
                .collect();
            assert!(want[0] > 0.1, "the ray crosses the glowing box: {want:?}");
            let got: Vec<f64> = (0..3)
                .map(|c| {
                    (0..4)
                        .map(|pixel| {
                            tr.trace(eye, d, pixel, &mut Scratch::default()).rgba[c] as f64
                        })
                        .sum::<f64>()
                        / 4.0
                })
                .collect();
            for c in 0..3 {
                assert!(
                    (got[c] - want[c]).abs() <= 0.01 * want[c] + 1e-6,
                    "{mode:?}, absorb {absorb}, ray {eye:?}, channel {c}: {} vs density {}",
                    got[c],
                    want[c]
                );
            }
        }
    }
}
