//! The lit mode's multiple-scattering models against the reference path tracer (issue 13's
//! accuracy target): on a generated smoke (the `smoke5` fixture's first frame) and, where the
//! samples are present, the WDAS cloud, `--ms-model diffusion` is closer to a converged
//! reference render than the octaves, and both keep the image's mean within bounds. The error
//! metric is `tools/lighting/`'s: relative RMSE of linear radiance (here the channel sum)
//! over the pixels where the reference shows the volume.

mod common;

use common::sample;
use vdbcook_trace::{
    render, Camera, Image, Integrator, Lighting, Mode, MsModel, Output, RenderSettings,
};

fn cook(input: &str) -> vdbcook_asset::Asset {
    let a = vdbcook_cook::CookOptions::default();
    vdbcook_cook::cook_inputs(&[input.to_string()], &a, &vdbcook_cook::Context::quiet())
        .unwrap()
        .asset
}

/// Relative RMSE and mean ratio of `a` against `truth` (channel sums) where the truth
/// exceeds 0.003.
fn score(a: &[f32], truth: &[f32]) -> (f64, f64) {
    let lum = |p: &[f32]| (p[0] + p[1] + p[2]) as f64;
    let (mut se, mut sa, mut st, mut n) = (0.0, 0.0, 0.0, 0usize);
    for (pa, pt) in a.chunks(4).zip(truth.chunks(4)) {
        let (x, t) = (lum(pa), lum(pt));
        if t > 0.003 {
            se += (x - t) * (x - t);
            sa += x;
            st += t;
            n += 1;
        }
    }
    assert!(n > 100, "the volume covers {n} pixels");
    let mean = st / n as f64;
    ((se / n as f64).sqrt() / mean, sa / st)
}

/// `score` of the CPU render of `asset` with settings `s` against `truth`.
fn error_of(
    asset: &vdbcook_asset::Asset,
    cam: &Camera,
    s: &RenderSettings,
    truth: &Image,
) -> (f64, f64) {
    let img = render(asset, cam, s).unwrap();
    score(&img.rgba, &truth.rgba)
}

/// `input` cooked, its default camera at 64×36, the lit mode's default settings there, and the
/// reference path tracer's image at 1024 spp (its own noise is about 0.03 of the errors below).
fn lit_scene(input: &str) -> (vdbcook_asset::Asset, Camera, RenderSettings, Image) {
    lit_scene_with(input, |_| {})
}

/// [`lit_scene`] with the settings changed by `tweak` (for both images).
fn lit_scene_with(
    input: &str,
    tweak: impl Fn(&mut RenderSettings),
) -> (vdbcook_asset::Asset, Camera, RenderSettings, Image) {
    let (w, h) = (64u32, 36u32);
    let asset = cook(input);
    let cam = Camera::framing(&asset, 0, w as f64 / h as f64).unwrap();
    let mut s = RenderSettings {
        output: Output {
            width: w,
            height: h,
            ..Default::default()
        },
        integrator: Integrator {
            mode: Mode::Lit,
            ..Default::default()
        },
        ..Default::default()
    };
    tweak(&mut s);
    let truth = render(
        &asset,
        &cam,
        &RenderSettings {
            integrator: Integrator {
                mode: Mode::Reference,
                spp: 1024,
                ..s.integrator.clone()
            },
            ..s.clone()
        },
    )
    .unwrap();
    (asset, cam, s, truth)
}

/// The smoke5 fixture's first frame and, where the samples are present, the WDAS cloud.
fn smoke5_and_wdas() -> Vec<String> {
    let mut inputs = vec![common::root()
        .join("fixtures/seq/smoke5/smoke.0001.vdb")
        .to_string_lossy()
        .into_owned()];
    inputs.extend(sample("wdas-cloud/wdas_cloud_sixteenth.vdb"));
    inputs
}

#[test]
fn diffusion_is_closer_to_the_reference_than_the_octaves() {
    for input in smoke5_and_wdas() {
        let (asset, cam, s, truth) = lit_scene(&input);
        let lit = |ms_model: MsModel| {
            let s = RenderSettings {
                lighting: Lighting {
                    ms_model,
                    ms_sky: ms_model.default_ms_sky(),
                    ..s.lighting.clone()
                },
                ..s.clone()
            };
            error_of(&asset, &cam, &s, &truth)
        };
        let (e_oct, r_oct) = lit(MsModel::Octaves);
        let (e_dif, r_dif) = lit(MsModel::Diffusion);
        eprintln!(
            "{input}: rel RMSE (mean ratio) against the reference: octaves {e_oct:.3} \
             ({r_oct:.3}), diffusion {e_dif:.3} ({r_dif:.3})"
        );
        assert!(
            e_dif < 0.85 * e_oct,
            "{input}: diffusion {e_dif:.3} is not clearly closer than the octaves {e_oct:.3}"
        );
        assert!(
            e_dif < 0.2 && (0.9..1.1).contains(&r_dif),
            "{input}: diffusion {e_dif:.3}, mean ratio {r_dif:.3}"
        );
    }
}

/// Dense clouds' sunlit skins are thinner than the light volume's cells: the diffusion solve's
/// source is each cell's mean first scattering, so where the near field sees more of the sun
/// than the cell's mean, the once-scattered light it adds (`near_scatter`, the first flight's
/// fluence at a surface) brings the image closer to the reference. On the WDAS cloud and
/// OpenVDB's smoke1 sample (where the samples are present; nothing to walk on the fixtures'
/// thin smoke), at 64×36 against 1024 spp, relative RMSE (mean ratio) without it and with the
/// default: WDAS 0.109 (0.953) → 0.093 (0.974), asserted clearly closer; smoke1 0.085 (0.999)
/// → 0.078 (1.003), asserted no farther. (Before the solve's source took the depth where the
/// beam enters each cell, 2026-11-28: WDAS 0.121 (0.941) → 0.101 (0.961), smoke1 0.082 (1.031)
/// → 0.082 (1.034).) (Before the sun pass walked voxels, 2026-11-27, the
/// cells' shadows were too deep and the term made up for part of that on smoke1 too: WDAS
/// 0.111 → 0.093, smoke1 0.087 → 0.077.)
#[test]
fn near_scatter_brings_dense_clouds_closer_to_the_reference() {
    let inputs: Vec<(String, bool)> = [
        ("wdas-cloud/wdas_cloud_sixteenth.vdb", true),
        ("openvdb-smoke1/smoke.vdb", false),
    ]
    .iter()
    .filter_map(|&(n, closer)| sample(n).map(|p| (p, closer)))
    .collect();
    if inputs.is_empty() {
        eprintln!("skipped: the WDAS and smoke1 samples are not present");
    }
    for (input, closer) in inputs {
        let (asset, cam, s, truth) = lit_scene(&input);
        let lit = |near_scatter: f32| {
            let s = RenderSettings {
                lighting: Lighting {
                    near_scatter,
                    ..s.lighting.clone()
                },
                ..s.clone()
            };
            error_of(&asset, &cam, &s, &truth)
        };
        let (e_off, r_off) = lit(0.0);
        let (e_on, r_on) = lit(vdbcook_trace::DEFAULT_NEAR_SCATTER);
        eprintln!(
            "{input}: rel RMSE (mean ratio) against the reference: near_scatter 0 {e_off:.3} \
             ({r_off:.3}), default {e_on:.3} ({r_on:.3})"
        );
        let bound = if closer { 0.93 } else { 1.02 };
        assert!(
            e_on < bound * e_off,
            "{input}: near_scatter {e_on:.3} against {e_off:.3} without (bound {bound}×)"
        );
        assert!(
            e_on < 0.11 && (0.95..1.05).contains(&r_on),
            "{input}: near_scatter {e_on:.3}, mean ratio {r_on:.3}"
        );
    }
}

/// Issue 34's bias: in sunlight alone (sky 0), with an isotropic phase, the lit mode's mean
/// over the volume's pixels must match the reference path tracer's. Before the gather of the
/// light scattered once and twice (`vdbcook_trace::diffusion`), the diffusion solve carried all
/// of it and lost 7% on the WDAS cloud (0.930 at 160×90, 8192 spp) and 2–7% on other real
/// volumes. Measured here at 64×36 (the reference at 1024 spp), mean ratio / relative RMSE:
/// WDAS 0.995 / 0.050 with the two orders gathered (the default), 0.936 / 0.091 with none
/// (`ms_gather` 0, asserted worse in both); the smoke5 fixture 0.993 / 0.087 and 0.941 / 0.120
/// (since the sun pass walks voxels; 0.997 / 0.049 and 0.992 / 0.087 with the gather before).
#[test]
fn lit_is_unbiased_in_sunlight() {
    for input in smoke5_and_wdas() {
        let (asset, cam, s, truth) = lit_scene_with(&input, |s| {
            s.lighting.sky = [0.0; 3];
            s.medium.phase_g = [0.0; 2];
            s.medium.phase_w = 1.0;
            // A thin medium: a mean free path of about 7 voxels at density 1.
            s.medium.absorb = 0.007;
            s.medium.scatter = 0.14;
        });
        let (e, r) = error_of(&asset, &cam, &s, &truth);
        let solve_alone = RenderSettings {
            lighting: Lighting {
                ms_gather: 0,
                ..s.lighting.clone()
            },
            ..s.clone()
        };
        let (e0, r0) = error_of(&asset, &cam, &solve_alone, &truth);
        eprintln!(
            "{input}: rel RMSE {e:.3}, mean ratio {r:.4}; without the gather {e0:.3}, {r0:.4}"
        );
        assert!(
            (0.97..1.03).contains(&r) && e < 0.1,
            "{input}: rel RMSE {e:.3}, mean ratio {r:.4}"
        );
        assert!(
            (r - 1.0).abs() < (r0 - 1.0).abs() && e < e0,
            "{input}: the gather ({r:.4}, {e:.3}) is not closer than the solve alone ({r0:.4}, {e0:.3})"
        );
    }
}
