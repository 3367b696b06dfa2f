//! `report`'s write stage: the JSON, CSV and Markdown documents and the PNGs, into DIR only
//! after everything was computed, then the summary on stdout.

use super::*;

/// Write: the documents (JSON, CSV, Markdown) and the PNGs into DIR, then the summary.
pub(super) fn write(a: &Args, c: &Collected, f: &Figures) -> Result<(), CliError> {
    let (w, h, mode, runs, value_range, active, frames) =
        (c.w, c.h, c.mode, c.runs, c.value_range, c.active, c.frames);
    let Collected {
        t_all,
        rows,
        peer_rows,
        camera,
        notes,
        gpu,
        gpu_layouts,
        tolerances,
        grid_name,
        ..
    } = c;
    let Figures {
        size_png,
        cook_png,
        trace_png,
        fig_png,
    } = f;
    // Documents.
    let meta = json!({
        "inputs": a.inputs,
        "grid": grid_name,
        "frames": frames,
        "active_voxels": active,
        "value_range": value_range,
        "render": {"mode": mode.name(), "width": w, "height": h, "frame": a.frame, "runs": runs,
                    "camera": {"eye": camera.eye, "look_at": camera.look_at, "fov_y_deg": camera.fov_y_deg}},
        "tolerances": tolerances,
        "machine": machine(),
        "gpu": gpu.as_ref().map(|g| g.describe()),
        "gpu_timing": gpu.as_ref().map(|_| "timestamp queries when the adapter has them, else submit-to-idle wall time"),
        "vdbcook": env!("CARGO_PKG_VERSION"),
        "seconds": t_all.elapsed().as_secs_f64(),
    });
    let doc = json!({"rows": rows, "peers": peer_rows, "notes": notes, "meta": meta,
                     "files": ["report.md", "report.json", "report.csv", "size_vs_error.png",
                               "cook_time_vs_error.png", "trace_time_vs_error.png", "renders.png"]});
    let md = markdown(a, rows, peer_rows, notes, &meta, gpu_layouts);
    std::fs::create_dir_all(&a.output)
        .map_err(|e| other(format!("{}: cannot create: {e}", a.output.display())))?;
    write_file(&a.output, "size_vs_error.png", size_png)?;
    write_file(&a.output, "cook_time_vs_error.png", cook_png)?;
    write_file(&a.output, "trace_time_vs_error.png", trace_png)?;
    write_file(&a.output, "renders.png", fig_png)?;
    write_file(&a.output, "report.csv", to_csv(rows).as_bytes())?;
    write_file(
        &a.output,
        "report.json",
        serde_json::to_string_pretty(&doc).expect("json").as_bytes(),
    )?;
    write_file(&a.output, "report.md", md.as_bytes())?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&doc).expect("json"));
    } else {
        println!("{}", table(rows));
        for n in notes {
            println!("note: {n}");
        }
        println!(
            "wrote {} (report.md, report.json, report.csv, 4 PNGs) in {:.1} s",
            a.output.display(),
            t_all.elapsed().as_secs_f64()
        );
    }
    Ok(())
}
