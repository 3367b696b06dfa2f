//! Shared helpers for the reader's tests: locating fixtures and samples, comparing the reader
//! with the ground truth OpenVDB computed (the `.truth.json` files written by fixtures/gen).

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use serde_json::Value;
use vdbcook_vdb::{CodeStats, VdbFile};

pub use vdbcook_testkit::{fixtures, repo_root};

#[path = "support/samples.rs"]
mod samples_support;
#[allow(unused_imports)]
pub use samples_support::sample;

/// The real samples (`$VDBCOOK_SAMPLES` or `../shared/samples`; a failure under CI when missing).
pub fn samples() -> Option<PathBuf> {
    samples_support::samples_dir(&repo_root())
}

/// Every `*.truth.json` below `dir`, sorted.
pub fn truth_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(rd) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.to_string_lossy().ends_with(".truth.json") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

fn num(v: &Value) -> Option<f64> {
    match v {
        Value::Number(n) => n.as_f64(),
        Value::String(s) if s.eq_ignore_ascii_case("nan") => Some(f64::NAN),
        Value::String(s) if s.eq_ignore_ascii_case("inf") => Some(f64::INFINITY),
        Value::String(s) if s.eq_ignore_ascii_case("-inf") => Some(f64::NEG_INFINITY),
        _ => None,
    }
}

fn close(a: f64, b: f64, rel: f64, abs: f64) -> bool {
    (a.is_nan() && b.is_nan()) || a == b || (a - b).abs() <= abs + rel * a.abs().max(b.abs())
}

fn coord(v: &Value) -> Option<[i32; 3]> {
    let a = v.as_array()?;
    Some([
        a[0].as_i64()? as i32,
        a[1].as_i64()? as i32,
        a[2].as_i64()? as i32,
    ])
}

/// Weight used by the truth's `weighted_sum` to catch permuted voxels.
pub fn weight(ijk: [i32; 3]) -> f64 {
    let h = (ijk[0] as u32).wrapping_mul(73856093)
        ^ (ijk[1] as u32).wrapping_mul(19349663)
        ^ (ijk[2] as u32).wrapping_mul(83492791);
    (h % 1024) as f64 / 1024.0
}

/// Compares `vdb` with its truth document; returns the mismatches (empty = equal) and which
/// per-node compression codes the file used.
pub fn compare_with_truth(vdb: &Path, truth: &Value) -> (Vec<String>, CodeStats) {
    let mut errs = Vec::new();
    let mut codes = CodeStats::default();
    let file = match VdbFile::open(vdb) {
        Ok(f) => f,
        Err(e) => return (vec![format!("open failed: {e}")], codes),
    };
    if truth["file_version"].as_u64() != Some(file.file_version as u64) {
        errs.push(format!(
            "file_version {} vs truth {}",
            file.file_version, truth["file_version"]
        ));
    }
    let tg = truth["grids"].as_array().cloned().unwrap_or_default();
    if tg.len() != file.grids.len() {
        errs.push(format!("{} grids vs truth {}", file.grids.len(), tg.len()));
        return (errs, codes);
    }
    for (i, (g, t)) in file.grids.iter().zip(&tg).enumerate() {
        let ctx = format!("grid #{i} '{}'", g.label);
        let mut err = |m: String| errs.push(format!("{ctx}: {m}"));
        if t["name"].as_str() != Some(g.name.as_str()) {
            err(format!("name '{}' vs truth {}", g.name, t["name"]));
        }
        if let Some(vt) = t["value_type"].as_str() {
            // OpenVDB calls a MaskGrid's values "bool"; its tree type says "mask".
            if vt != g.value_type && !(vt == "bool" && g.value_type == "mask") {
                err(format!("value_type {} vs truth {vt}", g.value_type));
            }
        }
        if let Some(c) = t["class"].as_str() {
            if c != g.class() {
                err(format!("class {} vs truth {c}", g.class()));
            }
        }
        if let Some(h) = t["half_float"].as_bool() {
            if h != g.half_float {
                err(format!("half_float {} vs truth {h}", g.half_float));
            }
        }
        let tt = &t["transform"];
        if let Some(mt) = tt["map_type"].as_str() {
            if mt != g.transform.kind.type_name() {
                err(format!(
                    "map type {} vs truth {mt}",
                    g.transform.kind.type_name()
                ));
            }
        }
        if g.transform.kind.is_linear() {
            if let Some(vs) = tt["voxel_size"].as_array() {
                let ours = g.transform.voxel_size();
                for a in 0..3 {
                    let tv = num(&vs[a]).unwrap_or(f64::NAN);
                    if !close(ours[a], tv, 1e-9, 1e-12) {
                        err(format!("voxel_size {ours:?} vs truth {vs:?}"));
                        break;
                    }
                }
            }
            for p in tt["index_to_world_probes"].as_array().into_iter().flatten() {
                let ijk: Vec<f64> = p[0].as_array().unwrap().iter().filter_map(num).collect();
                let w: Vec<f64> = p[1].as_array().unwrap().iter().filter_map(num).collect();
                let ours = g.transform.index_to_world([ijk[0], ijk[1], ijk[2]]);
                let scale = w.iter().fold(1.0f64, |m, x| m.max(x.abs()));
                if (0..3).any(|a| (ours[a] - w[a]).abs() > 1e-9 * scale) {
                    err(format!("index_to_world({ijk:?}) = {ours:?}, truth {w:?}"));
                }
            }
        }
        if !g.is_float() {
            if t["is_float"].as_bool() == Some(true) {
                err("truth says float, reader says not".into());
            }
            continue;
        }
        let (grid, c) = match file.read_float_grid_with_stats(i) {
            Ok(x) => x,
            Err(e) => {
                err(format!("read failed: {e}"));
                continue;
            }
        };
        for (total, n) in codes.metadata_codes.iter_mut().zip(c.metadata_codes) {
            *total += n;
        }
        let double = g.value_type == "double";
        let s = grid.stats();
        let bg = num(&t["background"]).unwrap_or(f64::NAN);
        if !close(
            grid.background as f64,
            bg,
            if double { 1e-7 } else { 0.0 },
            0.0,
        ) {
            err(format!("background {} vs truth {bg}", grid.background));
        }
        let checks: [(&str, u64); 3] = [
            ("active_voxels", s.active_voxels),
            ("active_tiles", s.active_tiles),
            ("leaf_count", s.leaf_count),
        ];
        for (k, ours) in checks {
            if let Some(tv) = t[k].as_u64() {
                if tv != ours {
                    err(format!("{k} {ours} vs truth {tv}"));
                }
            }
        }
        if let Some(by) = t["active_tiles_by_level"].as_array() {
            let tv: Vec<u64> = by.iter().filter_map(|x| x.as_u64()).collect();
            if tv != s.active_tiles_by_level {
                err(format!(
                    "active_tiles_by_level {:?} vs truth {tv:?}",
                    s.active_tiles_by_level
                ));
            }
        }
        let tb = (coord(&t["bbox_min"]), coord(&t["bbox_max"]));
        let ob = s.bbox;
        match (tb, ob) {
            ((Some(a), Some(b)), Some((c, d))) if a == c && b == d => {}
            ((None, None), None) => {}
            _ => err(format!(
                "bbox {ob:?} vs truth {:?}..{:?}",
                t["bbox_min"], t["bbox_max"]
            )),
        }
        let tol = if double { 1e-6 } else { 0.0 };
        for (k, ours) in [("value_min", s.value_min), ("value_max", s.value_max)] {
            match (num(&t[k]), ours) {
                (Some(tv), Some(o)) if double && close(o as f64, tv, tol, 0.0) => {}
                (Some(tv), Some(o)) if !double && o == tv as f32 => {}
                // The truth lets ±inf into min/max; ours keeps them apart in `non_finite`.
                (Some(tv), _) if tv.is_infinite() && s.non_finite > 0 => {}
                (None, None) => {}
                (tv, o) => err(format!("{k} {o:?} vs truth {tv:?}")),
            }
        }
        let n = s.active_voxels.max(1) as f64;
        let sum_tol = if double { 1e-6 } else { 1e-9 };
        for (k, ours) in [("value_sum", s.value_sum), ("value_sum_sq", s.value_sum_sq)] {
            if let Some(tv) = num(&t[k]).filter(|v| v.is_finite()) {
                if !close(ours, tv, sum_tol, 1e-12 * n) {
                    err(format!("{k} {ours} vs truth {tv}"));
                }
            }
        }
        if let Some(nan) = t["nan_count"].as_u64() {
            // Our non_finite count includes infinities; the truth counts NaN only.
            let mut nans = 0u64;
            grid.for_each_active_leaf_voxel(|_, v| nans += v.is_nan() as u64);
            nans += grid
                .tiles
                .iter()
                .filter(|t| t.active && t.value.is_nan())
                .map(|t| t.level.voxels())
                .sum::<u64>();
            if nans != nan {
                err(format!("nan_count {nans} vs truth {nan}"));
            }
        }
        if let Some(tw) = num(&t["weighted_sum"]).filter(|v| v.is_finite()) {
            let mut w = 0.0f64;
            grid.for_each_active_leaf_voxel(|ijk, v| {
                if v.is_finite() {
                    w += v as f64 * weight(ijk)
                }
            });
            if !close(w, tw, sum_tol, 1e-12 * n) {
                err(format!("weighted_sum {w} vs truth {tw}"));
            }
        }
        let lookup = grid.lookup();
        let mut bad_probes = 0;
        for p in t["probes"].as_array().into_iter().flatten() {
            let a = p.as_array().unwrap();
            let ijk = [
                a[0].as_i64().unwrap() as i32,
                a[1].as_i64().unwrap() as i32,
                a[2].as_i64().unwrap() as i32,
            ];
            let tv = num(&a[3]).unwrap_or(f64::NAN);
            let ta = a[4].as_bool().unwrap_or(a[4].as_i64() == Some(1));
            let (v, act) = lookup.value_at(ijk);
            let same = if double {
                close(v as f64, tv, tol, 0.0)
            } else {
                (v.is_nan() && tv.is_nan()) || v == tv as f32
            };
            if !same || act != ta {
                bad_probes += 1;
                if bad_probes <= 3 {
                    err(format!("probe {ijk:?}: ({v}, {act}) vs truth ({tv}, {ta})"));
                }
            }
        }
        if bad_probes > 3 {
            err(format!("{bad_probes} probes differ in all"));
        }
    }
    (errs, codes)
}
