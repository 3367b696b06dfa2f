//! `vdbcook inspect`: lists every grid of every input file with what OpenVDB would report —
//! type, class, storage, transform, active voxels (tiles counted by size), bbox and value range
//! — and which grids a multi-channel cook would pick (`grid_pick`, `cook --grids auto`).

use rayon::prelude::*;
use serde_json::{json, Value};
use vdbcook_vdb::{sequence, GridInfo, VdbFile};

use crate::errors::CliError;

#[derive(clap::Args)]
pub struct Args {
    /// VDB files, folders, frame patterns (smoke.####.vdb, smoke.%04d.vdb) or globs.
    #[arg(required = true, value_name = "INPUT")]
    inputs: Vec<String>,
    /// Print one JSON document on stdout instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Accept gaps in the frame numbering of folders and patterns.
    #[arg(long)]
    allow_gaps: bool,
}

pub fn run(a: &Args) -> Result<(), CliError> {
    let frames = sequence::resolve_inputs(&a.inputs, a.allow_gaps)?;
    let docs: Vec<Result<Value, CliError>> =
        frames.par_iter().map(|f| inspect_file(&f.path)).collect();
    let docs = docs.into_iter().collect::<Result<Vec<_>, _>>()?;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({ "files": docs })).expect("json")
        );
    } else {
        for d in &docs {
            print_table(d);
        }
    }
    Ok(())
}

fn inspect_file(path: &std::path::Path) -> Result<Value, CliError> {
    let file = VdbFile::open(path)?;
    let mut grids = Vec::new();
    for (i, g) in file.grids.iter().enumerate() {
        grids.push(grid_json(&file, i, g)?);
    }
    let pick = crate::grid_pick::suggest(&file);
    let skipped: Vec<Value> = pick
        .skipped
        .iter()
        .map(|(name, why)| json!({"name": name, "why": why}))
        .collect();
    Ok(json!({
        "file": path.display().to_string(),
        "file_version": file.file_version,
        "library_version": [file.library_version.0, file.library_version.1],
        "bytes": file.len_bytes(),
        "grids": grids,
        "suggested_grids": pick.grids,
        "suggested_skipped": skipped,
    }))
}

fn grid_json(file: &VdbFile, idx: usize, g: &GridInfo) -> Result<Value, CliError> {
    let t = &g.transform;
    let mut transform = json!({
        "kind": t.kind.type_name(),
        "voxel_size": t.voxel_size(),
        "translation": t.translation(),
        "matrix": t.index_to_world,
    });
    if let Some(f) = &t.frustum {
        transform["frustum"] = json!({"bbox_min": f.bbox_min, "bbox_max": f.bbox_max, "taper": f.taper, "depth": f.depth});
    }
    let mut v = json!({
        "name": g.label,
        "value_type": g.value_type,
        "grid_type": g.grid_type,
        "class": g.class(),
        "half_float": g.half_float,
        "compression": g.compression_name(),
        "transform": transform,
    });
    if let Some(p) = &g.instance_parent {
        v["instance_of"] = json!(p.replace('\u{1e}', "#"));
    }
    if !g.is_float() {
        v["note"] = json!("not a float grid: listed only, cannot be cooked");
        return Ok(v);
    }
    let grid = file.read_float_grid(idx)?;
    let s = grid.stats();
    v["background"] = json!(grid.background);
    v["active_voxels"] = json!(s.active_voxels);
    v["tiles"] = json!(s.active_tiles);
    v["tiles_by_level"] = json!({"8": s.active_tiles_by_level[0], "128": s.active_tiles_by_level[1], "4096": s.active_tiles_by_level[2]});
    v["leaves"] = json!(s.leaf_count);
    v["bbox_min"] = json!(s.bbox.map(|b| b.0));
    v["bbox_max"] = json!(s.bbox.map(|b| b.1));
    v["value_min"] = json!(s.value_min);
    v["value_max"] = json!(s.value_max);
    v["value_sum"] = json!(s.value_sum);
    v["non_finite"] = json!(s.non_finite);
    if grid.converted_from_double {
        v["converted_from_double"] = json!(true);
    }
    Ok(v)
}

fn print_table(d: &Value) {
    let f = |v: &Value| -> String {
        match v {
            Value::Null => "-".into(),
            Value::String(s) => s.clone(),
            Value::Number(n) => n.as_f64().map(fmt_num).unwrap_or_else(|| n.to_string()),
            other => other.to_string(),
        }
    };
    println!(
        "{}  (file format {}, written by OpenVDB {}.{}, {} bytes)",
        f(&d["file"]),
        d["file_version"],
        d["library_version"][0],
        d["library_version"][1],
        d["bytes"]
    );
    let header = [
        "grid",
        "type",
        "class",
        "storage",
        "transform",
        "voxel size",
        "active voxels",
        "tiles",
        "bbox (index, inclusive)",
        "values",
    ];
    let mut rows: Vec<Vec<String>> = vec![header.iter().map(|s| s.to_string()).collect()];
    for g in d["grids"].as_array().into_iter().flatten() {
        let name = match g["name"].as_str() {
            Some("") => "(unnamed)".to_string(),
            Some(n) => n.to_string(),
            None => "-".into(),
        };
        let ty = match (
            g["value_type"].as_str(),
            g["converted_from_double"].as_bool(),
        ) {
            (Some(t), Some(true)) => format!("{t} (read as f32)"),
            (Some(t), _) => t.to_string(),
            _ => "-".into(),
        };
        let storage = format!(
            "{}{}",
            if g["half_float"] == true {
                "half, "
            } else {
                ""
            },
            f(&g["compression"])
        );
        let vs = g["transform"]["voxel_size"].as_array().map(|a| {
            let v: Vec<f64> = a.iter().filter_map(|x| x.as_f64()).collect();
            if v.iter().all(|x| (x - v[0]).abs() <= 1e-12 * v[0].abs()) {
                fmt_num(v[0])
            } else {
                v.iter().map(|x| fmt_num(*x)).collect::<Vec<_>>().join("x")
            }
        });
        let bbox = match (g["bbox_min"].as_array(), g["bbox_max"].as_array()) {
            (Some(a), Some(b)) => format!("{a:?}..{b:?}")
                .replace("Number(", "")
                .replace(')', ""),
            _ if g["active_voxels"].is_null() => "-".into(),
            _ => "empty".into(),
        };
        let values = if g["active_voxels"].is_null() {
            "not a float grid".into()
        } else {
            let mut s = format!(
                "{} .. {} (sum {})",
                f(&g["value_min"]),
                f(&g["value_max"]),
                f(&g["value_sum"])
            );
            if g["non_finite"].as_u64().unwrap_or(0) > 0 {
                s += &format!(", {} NaN/Inf", g["non_finite"]);
            }
            s
        };
        rows.push(vec![
            name,
            ty,
            f(&g["class"]),
            storage,
            f(&g["transform"]["kind"]),
            vs.unwrap_or_default(),
            g["active_voxels"]
                .as_u64()
                .map(group_digits)
                .unwrap_or_else(|| "-".into()),
            f(&g["tiles"]),
            bbox,
            values,
        ]);
    }
    let widths: Vec<usize> = (0..header.len())
        .map(|c| rows.iter().map(|r| r[c].chars().count()).max().unwrap_or(0))
        .collect();
    for r in rows {
        let line: Vec<String> = r
            .iter()
            .zip(&widths)
            .map(|(s, w)| format!("{s:<w$}"))
            .collect();
        println!("  {}", line.join("  ").trim_end());
    }
    let picked: Vec<&str> = d["suggested_grids"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|g| g.as_str())
        .collect();
    if picked.len() > 1 {
        println!(
            "  suggested channels: --grids {} (what `cook --grids auto` cooks)",
            picked.join(",")
        );
    }
    for s in d["suggested_skipped"].as_array().into_iter().flatten() {
        println!("  not suggested: {}: {}", f(&s["name"]), f(&s["why"]));
    }
    println!();
}

fn fmt_num(x: f64) -> String {
    if x == x.trunc() && x.abs() < 1e15 {
        format!("{x:.0}")
    } else if x.abs() >= 1e-3 && x.abs() < 1e6 {
        let s = format!("{x:.6}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{x:.4e}")
    }
}

fn group_digits(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}
