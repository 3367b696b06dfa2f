//! The reference path tracer (`Mode::Reference`) against closed forms and conservation, on a box
//! of constant density (tiles, constant and partial bricks, across two root regions):
//! - **white furnace**: albedo 1, no sun, a uniform sky: every path leaves the box again, so
//!   every pixel is exactly the sky (`L + T·sky = sky`) however dense the medium and whatever
//!   the phase; with albedo 0.9 it must not be;
//! - **single scattering** (`bounces = 1`, no sky) along the box's axis with the sun straight
//!   behind the camera and straight ahead: `L = α·p(μ)·E·(1 − e^{−2κD})/2` and
//!   `L = α·p(μ)·E·κD·e^{−κD}` (κ extinction per voxel, D the depth in voxels), which also pins
//!   the phase function's direction convention (forward-peaked `g > 0` differs 27× between the
//!   two conventions at `g = 0.5`);
//! - the transmittance is the density march's exact one; batches add up (`stochastic.rs`);
//! - the settings it refuses.

mod common;

use common::*;
use vdbcook_asset::Asset;
use vdbcook_trace::*;

const LO: [i64; 3] = BOX_LO;
const HI: [i64; 3] = BOX_HI;
const SIGMA: f32 = 1.0;

fn box_asset() -> Asset {
    constant_box(SIGMA)
}

/// A camera in front of the box (−z side) looking at its centre.
fn camera() -> Camera {
    box_camera()
}

fn reference(absorb: f32, scatter: f32) -> RenderSettings {
    RenderSettings {
        output: Output {
            width: 24,
            height: 16,
            ..Default::default()
        },
        medium: Medium {
            absorb,
            scatter,
            phase_g: [0.7, -0.4],
            phase_w: 0.6,
            ..Default::default()
        },
        lighting: Lighting {
            light_color: [0.0; 3],
            sky: [0.3, 0.5, 0.9],
            ..Default::default()
        },
        integrator: Integrator {
            mode: Mode::Reference,
            bounces: MAX_BOUNCES,
            spp: 8,
            ..Default::default()
        },
    }
}

#[test]
fn white_furnace_the_medium_disappears_against_the_sky() {
    let asset = box_asset();
    // κ = 0.3 per voxel: 33 voxels deep is an optical depth of 10, the paths scatter ~100 times.
    let s = reference(0.0, 0.3);
    let img = render(&asset, &camera(), &s).unwrap();
    let mut covered = 0;
    for (k, px) in img.rgba.chunks_exact(4).enumerate() {
        let t = img.value[k];
        covered += (t < 0.5) as usize;
        for (c, (l, sky)) in px.iter().zip(s.lighting.sky).enumerate() {
            let total = l + t * sky;
            assert!(
                (total - sky).abs() <= 1e-5,
                "pixel {k} channel {c}: L + T·sky = {total}, sky {sky} (T {t})"
            );
        }
    }
    assert!(
        covered > 100,
        "the box covers the picture ({covered} pixels)"
    );

    // Not a test that cannot fail: absorb a tenth and the covered pixels darken.
    let dark = render(&asset, &camera(), &reference(0.03, 0.27)).unwrap();
    let lost = dark
        .rgba
        .chunks_exact(4)
        .zip(&dark.value)
        .filter(|(px, t)| **t < 0.5 && px[2] + **t * s.lighting.sky[2] < 0.8 * s.lighting.sky[2])
        .count();
    assert!(lost > 100, "albedo 0.9 should lose energy ({lost} pixels)");
}

/// The mean radiance of `4·spp` single-scattering paths along the box's axis with the sun
/// along `l` (toward the light) and one phase lobe `g`.
fn single(g: f32, l: [f32; 3], spp: u32) -> (f64, RenderSettings) {
    let asset = box_asset();
    let s = RenderSettings {
        medium: Medium {
            absorb: 0.01,
            scatter: 0.04,
            phase_g: [g, g],
            phase_w: 1.0,
            ..Default::default()
        },
        lighting: Lighting {
            light_dir: l,
            light_color: [2.0; 3],
            sky: [0.0; 3],
            ..Default::default()
        },
        integrator: Integrator {
            mode: Mode::Reference,
            bounces: 1,
            spp,
            ..Default::default()
        },
        ..Default::default()
    };
    let cam = camera();
    let tracer = Tracer::new(&asset, &cam, &s).unwrap();
    // Four pixels' random streams along the same ray: 4·spp paths.
    let mean = (0..4)
        .map(|pixel| {
            let px = tracer.trace(cam.eye, [0.0, 0.0, 1.0], pixel, &mut Scratch::default());
            px.rgba[0] as f64
        })
        .sum::<f64>()
        / 4.0;
    (mean, s)
}

#[test]
fn single_scattering_matches_the_closed_forms_and_the_phase_convention() {
    let depth = (HI[2] - LO[2]) as f64; // voxels along z
    let spp = MAX_SPP;
    for g in [0.0f32, 0.5, -0.5] {
        // Sun behind the camera (light travels along +z with the view): the scattering cosine
        // d·l is −1 and the shadow path from depth s is s.
        let (got, s) = single(g, [0.0, 0.0, -1.0], spp);
        let kappa = (s.medium.absorb + s.medium.scatter) as f64 * SIGMA as f64;
        let albedo = s.medium.scatter as f64 / (s.medium.absorb + s.medium.scatter) as f64;
        let e = s.lighting.light_color[0] as f64;
        let [want, want_ahead] = single_scatter_closed_forms(g as f64, albedo, e, kappa, depth);
        assert!(
            (got - want).abs() < 0.02 * want,
            "g {g}, sun behind: {got} want {want}"
        );
        // Sun ahead: cosine +1, shadow path D − s.
        let (got, _) = single(g, [0.0, 0.0, 1.0], spp);
        let want = want_ahead;
        assert!(
            (got - want).abs() < 0.02 * want,
            "g {g}, sun ahead: {got} want {want}"
        );
    }
}

#[test]
fn reference_settings_out_of_range_are_refused() {
    let asset = box_asset();
    let ok = reference(0.0, 0.3);
    for bad in [
        RenderSettings {
            medium: Medium {
                phase_g: [1.0, 0.0],
                ..ok.medium.clone()
            },
            ..ok.clone()
        },
        RenderSettings {
            medium: Medium {
                phase_w: 1.5,
                ..ok.medium.clone()
            },
            ..ok.clone()
        },
        RenderSettings {
            integrator: Integrator {
                bounces: 0,
                ..ok.integrator.clone()
            },
            ..ok.clone()
        },
        RenderSettings {
            lighting: Lighting {
                sky: [f32::NAN, 0.0, 0.0],
                ..ok.lighting.clone()
            },
            ..ok.clone()
        },
    ] {
        let e = render(&asset, &camera(), &bad).unwrap_err();
        assert!(matches!(e, TraceError::Setting(_)), "{e}");
    }
}

/// The reference's transmittance (the fraction of primary rays that leave unscattered) is the
/// density march's exact `exp(−(absorb+scatter)·∫σ)`, per pixel within 5 binomial σ.
#[test]
fn primary_escape_is_the_exact_transmittance() {
    let asset = box_asset();
    let s = {
        let base = reference(0.0, 0.0);
        RenderSettings {
            medium: Medium {
                absorb: 0.01,
                scatter: 0.05,
                ..base.medium
            },
            integrator: Integrator {
                spp: 256,
                ..base.integrator
            },
            ..base
        }
    };
    let exact = render(
        &asset,
        &camera(),
        &RenderSettings {
            medium: Medium {
                absorb: s.medium.absorb + s.medium.scatter,
                ..s.medium.clone()
            },
            integrator: Integrator {
                mode: Mode::Density,
                ..s.integrator.clone()
            },
            ..s.clone()
        },
    )
    .unwrap();
    let img = render(&asset, &camera(), &s).unwrap();
    let mut partial = 0;
    for (k, (&got, &want)) in img.value.iter().zip(&exact.value).enumerate() {
        let (got, want) = (got as f64, want as f64);
        partial += (want > 0.05 && want < 0.95) as usize;
        let sd = (want * (1.0 - want) / s.integrator.spp as f64).sqrt();
        assert!(
            (got - want).abs() <= 5.0 * sd + 1e-3,
            "pixel {k}: escaped {got} vs T {want}"
        );
        assert!((img.rgba[4 * k + 3] as f64 - (1.0 - got)).abs() < 1e-6);
    }
    assert!(partial > 50, "pixels with partial transmittance: {partial}");
}
