//! The thesis's Figure 19, measured: bricks before/after clustering, ratio, RMSE, max error and
//! seconds over k ∈ {100, 1000}, iterations ∈ {5, 10}, threshold ∈ {0.01, 0.1, 0.99}, for each
//! input (f32 payload, so all error comes from clustering). Prints a markdown table.
//! Usage: `cargo bench -p vdbcook --bench cluster_report -- INPUT...` (default: the stormscape
//! sequence and bench-data/cloud100 when present; see docs/clustering.md).

use std::path::PathBuf;
use std::process::Command;

use serde_json::Value;

fn cook(input: &str, extra: &[&str]) -> Value {
    let out = std::env::temp_dir().join(format!("vdbcook-cluster-{}.vdbc", std::process::id()));
    let o = Command::new(env!("CARGO_BIN_EXE_vdbcook"))
        .args(["cook", "--json", input, "-o"])
        .arg(&out)
        .args(extra)
        .output()
        .expect("vdbcook");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let _ = std::fs::remove_file(out);
    serde_json::from_slice(&o.stdout).expect("json")
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let inputs: Vec<String> = if args.is_empty() {
        [
            root.join("../shared/samples/stormscape-cloud-seq"),
            root.join("bench-data/cloud100"),
        ]
        .iter()
        .filter(|p| p.exists())
        .map(|p| p.display().to_string())
        .collect()
    } else {
        args
    };
    for input in &inputs {
        let base = cook(input, &[]);
        println!("\n### {input}\n");
        println!("{} frames, {} active voxels, {} source bricks, {} unique after exact dedup; unclustered f32 cook {:.2} s\n", base["frames"], base["active_voxels"], base["bricks"]["source"], base["bricks"]["unique"], base["seconds"]["total"].as_f64().unwrap_or(0.0));
        println!("| k | iterations | threshold | candidates | bricks before | after | ratio | RMSE | max error | cluster s | total s |");
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
        for k in ["100", "1000"] {
            for it in ["5", "10"] {
                for t in ["0.01", "0.1", "0.99"] {
                    let c = cook(
                        input,
                        &[
                            "--clusters",
                            k,
                            "--iterations",
                            it,
                            "--variance-threshold",
                            t,
                        ],
                    );
                    let before = c["bricks"]["unique"].as_f64().unwrap();
                    let after = c["bricks"]["after_clustering"].as_f64().unwrap();
                    println!(
                        "| {k} | {it} | {t} | {} | {before} | {after} | {:.3} | {:.3e} | {:.3e} | {:.2} | {:.2} |",
                        c["clustering"]["candidates"],
                        after / before,
                        c["error"]["rmse"].as_f64().unwrap_or(0.0),
                        c["error"]["max_abs"].as_f64().unwrap_or(0.0),
                        c["clustering"]["seconds"].as_f64().unwrap_or(0.0),
                        c["seconds"]["total"].as_f64().unwrap_or(0.0)
                    );
                }
            }
        }
    }
}
