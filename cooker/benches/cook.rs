//! Cook vs read, in one run: the time to merely read every frame of a sequence with the reader
//! (parallel, as the cooker reads), the time of `vdbcook cook` (f32 and f16) on the same files,
//! their ratio, and the cook's peak memory for the first 20 frames vs all of them (frames stream,
//! so memory should track the brick pool, not the frame count). Usage:
//! `cargo bench -p vdbcook --bench cook -- [INPUT_DIR] [RUNS]` (default: the stormscape sequence).

use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

use rayon::prelude::*;
use serde_json::Value;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

fn cook(args: &[String]) -> (f64, Value) {
    let t = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_vdbcook"))
        .args(args)
        .output()
        .expect("run vdbcook");
    let wall = t.elapsed().as_secs_f64();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (wall, serde_json::from_slice(&out.stdout).expect("json"))
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let input = args.first().cloned().unwrap_or_else(|| {
        root.join("../shared/samples/stormscape-cloud-seq")
            .display()
            .to_string()
    });
    let runs: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(5);
    if !std::path::Path::new(&input).exists() {
        eprintln!("skipping: {input} does not exist");
        return;
    }
    let frames = vdbcook_vdb::sequence::resolve_inputs(&[input.as_str()], false).expect("inputs");
    let threads = rayon::current_num_threads();
    let mut read_t = Vec::new();
    let mut voxels = 0u64;
    for _ in 0..runs {
        let t = Instant::now();
        let chunk = threads * 2;
        voxels = 0;
        for g in frames.chunks(chunk) {
            let n: Vec<u64> = g
                .par_iter()
                .map(|f| {
                    vdbcook_vdb::sequence::read_frame(f, None)
                        .expect("read")
                        .grid
                        .leaves
                        .len() as u64
                })
                .collect();
            voxels += n.iter().sum::<u64>();
        }
        read_t.push(t.elapsed().as_secs_f64());
    }
    let read = median(read_t);
    let out = std::env::temp_dir().join(format!("vdbcook-bench-{}.vdbc", std::process::id()));
    let mut rows = Vec::new();
    for fmt in ["f32", "f16"] {
        let mut walls = Vec::new();
        let mut last = Value::Null;
        for _ in 0..runs {
            let (w, j) = cook(&[
                "cook".into(),
                "--json".into(),
                input.clone(),
                "-o".into(),
                out.display().to_string(),
                "--format".into(),
                fmt.into(),
            ]);
            walls.push(w);
            last = j;
        }
        let c = median(walls);
        println!(
            "cook {fmt}: median {:.3} s over {runs} runs = {:.2}x the read time; stages (last run) {}; file {} bytes; peak memory {:.1} MiB",
            c,
            c / read,
            last["seconds"],
            last["bytes"]["file"],
            last["peak_memory_bytes"].as_f64().unwrap_or(0.0) / 1048576.0
        );
        rows.push((fmt, c, last));
    }
    println!(
        "read: median {read:.3} s over {runs} runs ({} frames, {} leaves, {threads} threads)",
        frames.len(),
        voxels
    );
    // Memory: the first 20 frames vs all frames.
    let first20: Vec<String> = frames
        .iter()
        .take(20)
        .map(|f| f.path.display().to_string())
        .collect();
    let mut a20 = vec![
        "cook".to_string(),
        "--json".into(),
        "-o".into(),
        out.display().to_string(),
    ];
    a20.extend(first20);
    let (_, j20) = cook(&a20);
    let (_, jall) = cook(&[
        "cook".into(),
        "--json".into(),
        input.clone(),
        "-o".into(),
        out.display().to_string(),
    ]);
    let mib = |j: &Value| j["peak_memory_bytes"].as_f64().unwrap_or(0.0) / 1048576.0;
    let pool = |j: &Value| j["bytes"]["atlas"].as_f64().unwrap_or(0.0) / 1048576.0;
    println!(
        "peak memory: {} frames {:.1} MiB (pool {:.1} MiB), {} frames {:.1} MiB (pool {:.1} MiB)",
        j20["frames"],
        mib(&j20),
        pool(&j20),
        jall["frames"],
        mib(&jall),
        pool(&jall)
    );
    println!(
        "{{\"bench\":\"cook\",\"frames\":{},\"read_s\":{read:.4},\"cook_f32_s\":{:.4},\"cook_f16_s\":{:.4},\"ratio_f32\":{:.3},\"peak_mib_20\":{:.1},\"peak_mib_all\":{:.1}}}",
        frames.len(), rows[0].1, rows[1].1, rows[0].1 / read, mib(&j20), mib(&jall)
    );
    let _ = std::fs::remove_file(out);
}
