//! Every mode on hand-built assets: an empty frame renders all-zero colour, a bad frame or bad
//! setting is an error, first-hit depth / density / brick equal the box's analytic entry point
//! and the sampler's answer there, no mode produces a NaN from any camera (inside, on node
//! boundaries, axis-aligned), and the default camera frames the stored box.

mod common;

use common::*;
use vdbcook_asset::{Asset, LeafRef, PayloadFormat};
use vdbcook_trace::*;

const LO: [i64; 3] = [100, 6, 20];
const HI: [i64; 3] = [150, 37, 53];
const SIGMA: f32 = 1.5;

/// Frame 0: the box; frame 1: nothing.
fn two_frames() -> Asset {
    let mut f = FrameSpec::default();
    box_leaves(LO, HI, SIGMA, &mut f.leaves);
    build(
        [2, 1, 1],
        uniform_scale(0.5, [1.0, 2.0, 3.0]),
        0.0,
        &[f, FrameSpec::default()],
        PayloadFormat::F32,
    )
}

fn small(mode: Mode, frame: usize) -> RenderSettings {
    RenderSettings {
        output: Output {
            width: 32,
            height: 24,
            frame,
        },
        integrator: Integrator {
            mode,
            spp: 4,
            ..Default::default()
        },
        ..Default::default()
    }
}

#[test]
fn empty_frame_renders_zero_colour_in_every_mode() {
    let a = two_frames();
    let cam = Camera::framing(&a, 1, 32.0 / 24.0).unwrap();
    for mode in Mode::ALL {
        let img = render(&a, &cam, &small(mode, 1)).unwrap();
        assert!(img.all_finite(), "{mode:?}");
        assert_eq!(img.rgba.len(), 32 * 24 * 4);
        if mode == Mode::Steps {
            // Only root regions are visited (two along x), nothing below them.
            assert!(img.value.iter().all(|&n| n <= 2.0), "{mode:?}");
            continue;
        }
        for px in img.rgba.chunks(4) {
            assert_eq!(&px[..3], &[0.0; 3], "{mode:?}: colour on an empty frame");
        }
    }
    // The same camera sees the box in frame 0.
    let img = render(&a, &cam, &small(Mode::Density, 0)).unwrap();
    assert!(img.rgba.chunks(4).any(|p| p[0] > 0.0));
}

#[test]
fn bad_frame_and_bad_settings_are_errors() {
    let a = two_frames();
    let cam = Camera::framing(&a, 0, 1.0).unwrap();
    assert_eq!(
        render(&a, &cam, &small(Mode::Density, 2)).unwrap_err(),
        TraceError::Frame {
            frame: 2,
            frames: 2
        }
    );
    assert!(Camera::framing(&a, 7, 1.0).is_err());
    let bad: [fn(&mut RenderSettings); 8] = [
        |s| s.integrator.step = 0.0,
        |s| s.integrator.shadow_step = f32::NAN,
        |s| s.medium.absorb = -1.0,
        |s| s.output.width = 0,
        |s| s.integrator.spp = 0,
        |s| s.lighting.light_dir = [0.0; 3],
        |s| s.integrator.gain = f32::INFINITY,
        |s| s.lighting.light_color = [1.0, f32::NAN, 0.0],
    ];
    for (i, f) in bad.iter().enumerate() {
        let mut s = small(Mode::SingleScatter, 0);
        f(&mut s);
        assert!(
            matches!(render(&a, &cam, &s), Err(TraceError::Setting(_))),
            "case {i}"
        );
    }
    let mut c = cam;
    c.look_at = c.eye;
    assert!(matches!(
        render(&a, &c, &small(Mode::Density, 0)),
        Err(TraceError::Camera(_))
    ));
    let mut singular = a.clone();
    singular.header.index_to_world[1] = [0.0, 0.0, 0.0, 1.0];
    assert!(matches!(
        render(&singular, &cam, &small(Mode::Density, 0)),
        Err(TraceError::Transform(_))
    ));
}

#[test]
fn first_hit_modes_report_the_analytic_entry() {
    let a = two_frames();
    // Cell point (index + ½: OpenVDB centres voxel i on index i, so voxels LO ..= HI − 1 are the
    // cells [LO, HI)) → world.
    let to_world = |p: [f64; 3]| [0, 1, 2].map(|k| (p[k] - 0.5) * 0.5 + [1.0, 2.0, 3.0][k]);
    let (lo, hi) = (
        to_world(LO.map(|c| c as f64)),
        to_world(HI.map(|c| c as f64)),
    );
    let cam = Camera::framing(&a, 0, 1.0).unwrap();
    let mut rng = XorShift(3);
    let mut seen_tile = false;
    let mut seen_brick = false;
    for i in 0..300 {
        let p = [0, 1, 2].map(|k| rng.range(LO[k] as f64, HI[k] as f64));
        let d = rng.dir();
        let target = to_world(p);
        let eye = [0, 1, 2].map(|k| target[k] - 40.0 * d[k]);
        let (t0, _) = slab_interval(eye, d, lo, hi).expect("aimed at the box");
        let trace = |mode| {
            let s = small(mode, 0);
            Tracer::new(&a, &cam, &s)
                .unwrap()
                .trace(eye, d, 0, &mut Scratch::default())
        };
        let depth = trace(Mode::Depth);
        assert!(
            (depth.value as f64 - t0).abs() < 1e-4,
            "ray {i}: {} vs {t0}",
            depth.value
        );
        assert_eq!(depth.rgba[3], 1.0);
        assert_eq!(trace(Mode::FirstHitDensity).value, SIGMA);
        // Brick hue: the leaf just inside the entry point, per the sampler.
        let q = [0, 1, 2].map(|k| ((eye[k] + (t0 + 1e-6) * d[k]) - [1.0, 2.0, 3.0][k]) / 0.5);
        let leaf = a.leaf_at(0, q.map(|c| (c + 0.5).floor() as i64));
        let hue = trace(Mode::BrickHue);
        match leaf {
            LeafRef::Brick(b) => {
                seen_brick = true;
                assert_eq!(hue.value, b as f32, "ray {i}");
                assert_eq!(&hue.rgba[..3], &brick_color(b));
            }
            LeafRef::Tile(_) => {
                seen_tile = true;
                assert_eq!(hue.value, -2.0, "ray {i}");
            }
            LeafRef::Empty => panic!("entry point outside the stored leaves"),
        }
    }
    assert!(seen_brick);
    // From inside a tile leaf (index (108, 12, 36): leaf (13, 1, 4), fully inside, even parity):
    // the hit is at distance 0 in a tile.
    let eye = to_world([108.0, 12.0, 36.0]);
    assert_eq!(a.leaf_at(0, [108, 12, 36]), LeafRef::Tile(SIGMA));
    for d in [[1.0, 0.0, 0.0], [0.0, -0.6, 0.8]] {
        let trace = |mode| {
            Tracer::new(&a, &cam, &small(mode, 0)).unwrap().trace(
                eye,
                d,
                0,
                &mut Scratch::default(),
            )
        };
        assert_eq!(trace(Mode::Depth).value, 0.0);
        assert_eq!(trace(Mode::BrickHue).value, -2.0);
        seen_tile = true;
    }
    assert!(seen_tile);
    // A miss: value −1, alpha 0.
    let miss = Tracer::new(&a, &cam, &small(Mode::Depth, 0))
        .unwrap()
        .trace(
            [0.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            0,
            &mut Scratch::default(),
        );
    assert_eq!((miss.value, miss.rgba), (-1.0, [0.0; 4]));
}

#[test]
fn no_mode_produces_nan_from_awkward_cameras() {
    let mut rng = XorShift(17);
    let f = random_frame(&mut rng);
    let a = build(
        [2, 2, 1],
        rotated(0.0, [1.0; 3], [0.0; 3]),
        0.0,
        &[f],
        PayloadFormat::F16,
    );
    let cams = [
        // Inside the volume, looking along +x exactly (rows of axis-parallel-ish rays).
        ([64.0, 64.0, 64.0], [200.0, 64.0, 64.0]),
        // On a region corner.
        ([128.0, 128.0, 0.0], [0.0, 0.0, 128.0]),
        // Straight down an axis from outside, eye on node boundaries.
        ([136.0, 300.0, 64.0], [136.0, 0.0, 64.0]),
        // Far away, grazing the extent's face.
        ([-50.0, 0.0, 64.0], [300.0, 0.0, 64.0]),
    ];
    for (eye, look) in cams {
        let cam = Camera {
            eye,
            look_at: look,
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 60.0,
        };
        for mode in Mode::ALL {
            let s = RenderSettings {
                output: Output {
                    width: 17,
                    height: 9,
                    ..Default::default()
                },
                integrator: Integrator {
                    mode,
                    spp: 2,
                    step: 2.0,
                    shadow_step: 4.0,
                    ..Default::default()
                },
                ..Default::default()
            };
            let img = render(&a, &cam, &s).unwrap();
            assert!(img.all_finite(), "{mode:?} from {eye:?}");
            assert!(
                img.rgba.iter().all(|c| *c >= 0.0),
                "{mode:?}: negative colour"
            );
        }
    }
}

#[test]
fn default_camera_frames_the_stored_box() {
    let a = two_frames();
    let (w, h) = (64u32, 36u32);
    let cam = Camera::framing(&a, 0, w as f64 / h as f64).unwrap();
    let s = RenderSettings {
        output: Output {
            width: w,
            height: h,
            ..Default::default()
        },
        integrator: Integrator {
            mode: Mode::Depth,
            ..Default::default()
        },
        ..Default::default()
    };
    let img = render(&a, &cam, &s).unwrap();
    let (mut i0, mut i1, mut j0, mut j1, mut n) = (w, 0, h, 0, 0);
    for j in 0..h {
        for i in 0..w {
            if img.pixel(i, j)[3] > 0.0 {
                n += 1;
                (i0, i1, j0, j1) = (i0.min(i), i1.max(i), j0.min(j), j1.max(j));
            }
        }
    }
    let frac = n as f64 / (w * h) as f64;
    assert!(frac > 0.08 && frac < 0.8, "covered fraction {frac}");
    assert!(
        i0 > 0 && j0 > 0 && i1 < w - 1 && j1 < h - 1,
        "box touches the border"
    );
    assert!(
        (j1 - j0) as f64 > 0.4 * h as f64,
        "box spans {}..{} of {h} rows",
        j0,
        j1
    );
}

#[test]
fn optical_depth_is_the_density_sum_cut_at_t_max() {
    // The box holds SIGMA everywhere: τ over [0, t_max] is SIGMA · (voxel length of the part of
    // the box before t_max), and with t_max = ∞ it is the Density mode's T.
    let a = two_frames();
    let to_world = |p: [f64; 3]| [0, 1, 2].map(|k| (p[k] - 0.5) * 0.5 + [1.0, 2.0, 3.0][k]);
    let (lo, hi) = (
        to_world(LO.map(|c| c as f64)),
        to_world(HI.map(|c| c as f64)),
    );
    let cam = Camera::framing(&a, 0, 1.0).unwrap();
    let s = {
        let base = small(Mode::Density, 0);
        RenderSettings {
            medium: Medium {
                absorb: 0.01,
                ..base.medium
            },
            ..base
        }
    };
    let tracer = Tracer::new(&a, &cam, &s).unwrap();
    let mut rng = XorShift(5);
    let mut scratch = Scratch::default();
    for i in 0..100 {
        let p = [0, 1, 2].map(|k| rng.range(LO[k] as f64, HI[k] as f64));
        let d = rng.dir();
        let target = to_world(p);
        let eye = [0, 1, 2].map(|k| target[k] - 40.0 * d[k]);
        let (t0, t1) = slab_interval(eye, d, lo, hi).expect("aimed at the box");
        let full = tracer.optical_depth(eye, d, f64::INFINITY, &mut scratch);
        let density = tracer.trace(eye, d, 0, &mut scratch).value as f64;
        assert!(((-0.01 * full).exp() - density).abs() < 1e-6, "ray {i}");
        // Voxel units: a world length ℓ is 2ℓ voxels (voxel size 0.5).
        let cut = 0.5 * (t0 + t1);
        let half = tracer.optical_depth(eye, d, cut, &mut scratch);
        let want = SIGMA as f64 * 2.0 * (cut - t0);
        assert!(
            (half - want).abs() < 1e-6 * (1.0 + want),
            "ray {i}: {half} vs {want}"
        );
        assert_eq!(tracer.optical_depth(eye, d, t0 * 0.9, &mut scratch), 0.0);
    }
}
