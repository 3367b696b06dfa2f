//! CPU render time per mode at 640×360 on a cooked asset, from the default camera, median of
//! RUNS renders (after one warm-up), with rays per second and mean traversal steps per ray.
//! Usage (cook first; the trace crate does not depend on the cooker):
//! `vdbcook cook fixtures/seq/smoke5 -o /tmp/smoke5.vdbc`
//! `cargo bench -p vdbcook-trace --bench trace -- /tmp/smoke5.vdbc [RUNS] [FRAME]`

use std::time::Instant;

use vdbcook_asset::Asset;
use vdbcook_trace::{render, Camera, Integrator, Mode, Output, RenderSettings};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let Some(path) = args.first() else {
        eprintln!("skipping: give a cooked asset (vdbcook cook … -o x.vdbc; then -- x.vdbc)");
        return;
    };
    let runs: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(5).max(1);
    let bytes = std::fs::read(path).expect("read the asset");
    let asset = Asset::from_bytes(&bytes).expect("a valid asset");
    let frame: usize = args
        .get(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(asset.frame_count() / 2);
    let (w, h) = (640u32, 360u32);
    let camera = Camera::framing(&asset, frame, w as f64 / h as f64).expect("camera");
    println!(
        "{path}: frame {frame} of {}, {w}x{h}, {} threads, median of {runs}",
        asset.frame_count(),
        rayon::current_num_threads()
    );
    println!(
        "{:<12} {:>10} {:>12} {:>12}",
        "mode", "ms", "Mrays/s", "steps/ray"
    );
    for mode in Mode::ALL {
        let s = RenderSettings {
            output: Output {
                width: w,
                height: h,
                frame,
            },
            integrator: Integrator {
                mode,
                spp: 16,
                ..Default::default()
            },
            ..Default::default()
        };
        let _ = render(&asset, &camera, &s).expect("render");
        let times: Vec<f64> = (0..runs)
            .map(|_| {
                let t = Instant::now();
                let img = render(&asset, &camera, &s).expect("render");
                assert!(img.all_finite());
                t.elapsed().as_secs_f64()
            })
            .collect();
        let t = median(times);
        let rays = (w * h) as f64
            * if matches!(mode, Mode::DeltaTracking | Mode::Reference) {
                s.integrator.spp as f64 // one primary path per sample
            } else {
                1.0
            };
        let steps = if mode == Mode::Steps {
            let img = render(&asset, &camera, &s).expect("render");
            format!(
                "{:.1}",
                img.value.iter().map(|&v| v as f64).sum::<f64>() / (w * h) as f64
            )
        } else {
            String::new()
        };
        println!(
            "{:<12} {:>10.1} {:>12.2} {:>12}",
            mode.name(),
            t * 1e3,
            rays / t / 1e6,
            steps
        );
    }
}
