//! `report`'s chart stage: the size, cook-time and trace-time charts against error, and the
//! side-by-side renders with error images, encoded as PNGs in memory (drawing primitives:
//! `chart`).

use super::*;

/// The four PNGs, encoded in memory.
pub(super) struct Figures {
    pub(super) size_png: Vec<u8>,
    pub(super) cook_png: Vec<u8>,
    pub(super) trace_png: Vec<u8>,
    pub(super) fig_png: Vec<u8>,
}

/// Chart: the three speed/accuracy charts and the renders figure.
pub(super) fn figures(a: &Args, c: &mut Collected) -> Result<Figures, CliError> {
    let (w, h, mode, nano) = (c.w, c.h, c.mode, c.nano);
    let Collected {
        rows,
        peer_rows,
        images,
        gpu,
        vdbr_rgb,
        tolerances,
        configs,
        progress,
        ..
    } = c;
    let reference = &images[0];
    // Pictures.
    progress.step("charts");
    let gpu_name = gpu.as_ref().map(|g| g.describe());
    let cook_series = |peer: bool| {
        let mut s = vec![
            Series {
                name: "vdbcook --format".into(),
                color: PALETTE[0],
            },
            Series {
                name: "vdbcook --clusters".into(),
                color: PALETTE[2],
            },
            Series {
                name: "vdbcook --max-error (fraction r of the value range)".into(),
                color: PALETTE[1],
            },
        ];
        if peer {
            s.push(Series {
                name: "NanoVDB (nanovdb_convert)".into(),
                color: PALETTE[3],
            });
        }
        s
    };
    let series_of = |r: &Row| {
        configs
            .iter()
            .find(|c| c.label == r.label)
            .map(|c| c.series)
            .unwrap_or(0)
    };
    let nano_points = |y: &dyn Fn(&PeerRow) -> Option<f64>| -> Vec<Point> {
        peer_rows
            .iter()
            .filter(|p| p.tool == "nanovdb")
            .filter_map(|p| {
                Some(Point {
                    label: p.config.clone(),
                    x: p.rmse?,
                    y: y(p)?,
                    series: 3,
                })
            })
            .collect()
    };
    let mut size_pts: Vec<Point> = rows
        .iter()
        .map(|r| Point {
            label: r.label.clone(),
            x: r.rmse,
            y: r.bits_per_active_voxel_gpu,
            series: series_of(r),
        })
        .collect();
    size_pts.extend(nano_points(&|p| p.bits_per_active_voxel_gpu));
    let mut cook_pts: Vec<Point> = rows
        .iter()
        .map(|r| Point {
            label: r.label.clone(),
            x: r.rmse,
            y: r.cook_seconds,
            series: series_of(r),
        })
        .collect();
    cook_pts.extend(nano_points(&|p| p.cook_seconds));
    let src = a.inputs.join(" ");
    let size_png = chart::scatter_chart(
        &format!("Size vs voxel error: {src}"),
        "voxel RMSE (source units, log)",
        "GPU bits per active voxel (log)",
        &cook_series(nano),
        &size_pts,
    )
    .map_err(other)?;
    let cook_png = chart::scatter_chart(
        &format!("Cook time vs voxel error: {src}"),
        "voxel RMSE (source units, log)",
        "seconds (log; NanoVDB: nanovdb_convert time)",
        &cook_series(nano),
        &cook_pts,
    )
    .map_err(other)?;
    let mut trace_series = vec![Series {
        name: format!(
            "CPU reference tracer ({} threads)",
            rayon::current_num_threads()
        ),
        color: PALETTE[0],
    }];
    let mut trace_pts: Vec<Point> = rows
        .iter()
        .map(|r| Point {
            label: r.label.clone(),
            x: r.image_rmse,
            y: r.trace_ms_cpu,
            series: 0,
        })
        .collect();
    if let Some(g) = &gpu_name {
        trace_series.push(Series {
            name: format!("GPU: {g}"),
            color: PALETTE[1],
        });
        trace_pts.extend(rows.iter().filter_map(|r| {
            Some(Point {
                label: r.label.clone(),
                x: r.image_rmse,
                y: r.trace_ms_gpu?,
                series: 1,
            })
        }));
    }
    if let Some(p) = peer_rows.iter().find(|p| p.tool == "vdb_render") {
        let si = trace_series.len();
        trace_series.push(Series {
            name: "vdb_render (source VDB; x: vs our f32 image, 8-bit)".into(),
            color: PALETTE[3],
        });
        trace_pts.push(Point {
            label: "vdb_render".into(),
            x: p.image_rmse.unwrap_or(f64::NAN),
            y: p.trace_ms_cpu.unwrap_or(f64::NAN),
            series: si,
        });
    }
    let trace_png = chart::scatter_chart(
        &format!(
            "Trace time vs image error ({}, {w}×{h}, frame {})",
            mode.name(),
            a.frame
        ),
        "image RMSE vs the f32 render (linear RGB, log)",
        "ms per frame (median, log)",
        &trace_series,
        &trace_pts,
    )
    .map_err(other)?;
    // Side by side: each format and the middle tolerance, |error| under each, scaled so the
    // largest error shown is near white (the gain is a round number, printed in the caption).
    let mut tiles = Vec::new();
    let mut fig_w = 0;
    let mut fig_h = 0;
    // Each format, and the middle tolerance without clustering.
    let middle = tolerances.get(tolerances.len() / 2).copied();
    let shown: Vec<usize> = (0..configs.len())
        .filter(|&i| {
            let c = &configs[i];
            c.series == 0
                || (c.clusters.is_none() && c.tolerance.is_some() && c.tolerance == middle)
        })
        .collect();
    // The f32 reference (row 0) has no error image; the rows already hold each image's max |Δ|.
    let worst = shown
        .iter()
        .filter(|&&i| i != 0)
        .map(|&i| rows[i].image_max_abs)
        .fold(0.0f64, f64::max);
    let gain = nice_gain(worst);
    for &i in &shown {
        let (r, img) = (&rows[i], &images[i]);
        let (rgb, tw, th) = shrink(chart::display_rgb(&img.rgba), w, h, 420);
        let error = (i != 0).then(|| {
            shrink(
                chart::error_rgb(&img.rgba, &reference.rgba, gain as f32),
                w,
                h,
                420,
            )
            .0
        });
        (fig_w, fig_h) = (tw, th);
        tiles.push(Tile {
            title: r.label.clone(),
            subtitle: format!(
                "{:.2} bit/vox GPU · image RMSE {}",
                r.bits_per_active_voxel_gpu,
                sci(r.image_rmse)
            ),
            render: rgb,
            error,
        });
    }
    if let Some(rgb) = &vdbr_rgb {
        let (rgb, _, _) = shrink(rgb.clone(), w, h, 420);
        tiles.push(Tile {
            title: "vdb_render (source)".into(),
            subtitle: "OpenVDB, trilinear, for comparison".into(),
            render: rgb,
            error: None,
        });
    }
    let fig_png = chart::side_by_side(
        &format!(
            "{} of frame {} ({src}): renders (top), |error| ×{gain} vs f32 (bottom)",
            mode.name(),
            a.frame
        ),
        &tiles,
        fig_w,
        fig_h,
        "CPU reference tracer, nearest-voxel sampling; error colour ramp black → red → yellow → white.",
    )
    .map_err(other)?;
    progress.finish();
    Ok(Figures {
        size_png,
        cook_png,
        trace_png,
        fig_png,
    })
}
