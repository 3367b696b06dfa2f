//! Payload sizes side by side with NanoVDB's quantization at the same absolute tolerance:
//! `nanovdb_convert --fpN -a E` (Debian `libnanovdb-tools`; skipped with a note when missing) vs
//! `vdbcook cook --max-error E`, file bytes, plus NanoVDB Fp4/Fp8/Fp16 and vdbcook per format,
//! and vdbcook's cook time. Sequences are converted frame by frame for NanoVDB (one file each)
//! and summed. Usage: `cargo bench -p vdbcook --bench peers -- INPUT...` (files or folders;
//! default: the wdas cloud and smoke1 from ../shared/samples and bench-data/smoke100 if present).

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

fn vdb_files(input: &Path) -> Vec<PathBuf> {
    if input.is_dir() {
        let mut v: Vec<PathBuf> = std::fs::read_dir(input)
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "vdb"))
            .collect();
        v.sort();
        v
    } else {
        vec![input.to_path_buf()]
    }
}

/// Total NanoVDB bytes for `files` with `opts`, or None when the tool is missing or fails.
fn nano(files: &[PathBuf], opts: &[&str], tmp: &Path) -> Option<u64> {
    let mut total = 0;
    for f in files {
        let out = tmp.join("x.nvdb");
        let st = Command::new("nanovdb_convert")
            .arg("-f")
            .args(opts)
            .arg(f)
            .arg(&out)
            .output()
            .ok()?;
        if !st.status.success() {
            return None;
        }
        total += std::fs::metadata(&out).ok()?.len();
    }
    Some(total)
}

fn cook(input: &Path, args: &[&str], tmp: &Path) -> Value {
    let out = tmp.join("x.vdbc");
    let o = Command::new(env!("CARGO_BIN_EXE_vdbcook"))
        .arg("cook")
        .arg("--json")
        .arg(input)
        .arg("-o")
        .arg(&out)
        .args(args)
        .output()
        .expect("vdbcook");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let args: Vec<PathBuf> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .map(PathBuf::from)
        .collect();
    let inputs: Vec<PathBuf> = if args.is_empty() {
        [
            root.join("../shared/samples/wdas-cloud/wdas_cloud_sixteenth.vdb"),
            root.join("../shared/samples/openvdb-smoke1/smoke.vdb"),
            root.join("bench-data/smoke100"),
        ]
        .into_iter()
        .filter(|p| p.exists())
        .collect()
    } else {
        args
    };
    let have_nano = Command::new("nanovdb_convert")
        .arg("--version")
        .output()
        .is_ok();
    if !have_nano {
        println!("note: nanovdb_convert not installed (apt-get install libnanovdb-tools): NanoVDB columns skipped");
    }
    let tmp = tempfile_dir();
    for input in &inputs {
        let files = vdb_files(input);
        println!("\n## {} ({} file(s))", input.display(), files.len());
        if have_nano {
            let sizes: Vec<String> = [
                ("Fp4", vec!["--fp4"]),
                ("Fp8", vec!["--fp8"]),
                ("Fp16", vec!["--fp16"]),
                ("float", vec![]),
            ]
            .iter()
            .map(|(n, o)| {
                format!(
                    "{n} {}",
                    nano(&files, o, &tmp)
                        .map(|b| b.to_string())
                        .unwrap_or("-".into())
                )
            })
            .collect();
            println!("NanoVDB bytes: {}", sizes.join(", "));
        }
        let per_format: Vec<String> = ["f32", "f16", "unorm8", "bc4", "bc7"]
            .iter()
            .map(|f| {
                let c = cook(input, &["--format", f], &tmp);
                format!(
                    "{f} {} (max err {:.2e}, cook {:.2} s)",
                    c["bytes"]["file"],
                    c["error"]["max_abs"].as_f64().unwrap_or(0.0),
                    c["seconds"]["total"].as_f64().unwrap_or(0.0)
                )
            })
            .collect();
        println!("vdbcook bytes: {}", per_format.join(", "));
        println!("| E | NanoVDB FpN bytes | vdbcook --max-error bytes | ratio | vdbcook max error | representations |");
        println!("|---|---|---|---|---|---|");
        for e in ["0.001", "0.01", "0.05"] {
            let n = if have_nano {
                nano(&files, &["--fpN", "-a", e], &tmp)
            } else {
                None
            };
            let c = cook(input, &["--max-error", e], &tmp);
            let ours = c["bytes"]["file"].as_u64().unwrap();
            let ratio = n
                .map(|n| format!("{:.3}", ours as f64 / n as f64))
                .unwrap_or("-".into());
            println!(
                "| {e} | {} | {ours} | {ratio} | {:.2e} | {} |",
                n.map(|b| b.to_string()).unwrap_or("-".into()),
                c["error"]["max_abs"].as_f64().unwrap_or(0.0),
                c["representations"]
            );
        }
    }
    let _ = std::fs::remove_dir_all(&tmp);
}

fn tempfile_dir() -> PathBuf {
    let p = std::env::temp_dir().join(format!("vdbcook-peers-{}", std::process::id()));
    std::fs::create_dir_all(&p).unwrap();
    p
}
