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
    let read_once = || {
        let t = Instant::now();
        let mut leaves = 0u64;
        for g in frames.chunks(threads * 2) {
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
            leaves += n.iter().sum::<u64>();
        }
        (t.elapsed().as_secs_f64(), leaves)
    };
    let out = std::env::temp_dir().join(format!("vdbcook-bench-{}.vdbc", std::process::id()));
    // Read and cook runs alternate, so machine noise hits both alike; ratios are per pair.
    let mut leaves = 0;
    for fmt in ["f32", "f16"] {
        let (mut reads, mut cooks, mut internal, mut ratios) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut last = Value::Null;
        for _ in 0..runs {
            let (r, l) = read_once();
            leaves = l;
            let (w, j) = cook(&[
                "cook".into(),
                "--json".into(),
                input.clone(),
                "-o".into(),
                out.display().to_string(),
                "--format".into(),
                fmt.into(),
            ]);
            reads.push(r);
            cooks.push(w);
            internal.push(j["seconds"]["total"].as_f64().unwrap_or(w));
            ratios.push(w / r);
            last = j;
        }
        let (r, c, ci, ratio) = (
            median(reads),
            median(cooks),
            median(internal),
            median(ratios),
        );
        println!(
            "{fmt}: read median {r:.3} s, cook median {c:.3} s wall ({ci:.3} s inside the process) over {runs} alternating runs; median cook/read ratio {ratio:.2}x; stages (last run) {}; file {} bytes",
            last["seconds"], last["bytes"]["file"]
        );
        println!("{{\"bench\":\"cook\",\"format\":\"{fmt}\",\"frames\":{},\"read_s\":{r:.4},\"cook_s\":{c:.4},\"cook_internal_s\":{ci:.4},\"ratio\":{ratio:.3}}}", frames.len());
    }
    println!(
        "({} frames, {leaves} leaves, {threads} threads)",
        frames.len()
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
    // A static volume (the first frame repeated): memory must not grow with the frame count.
    let stat = |n: usize| {
        let mut a = vec![
            "cook".to_string(),
            "--json".into(),
            "-o".into(),
            out.display().to_string(),
        ];
        a.extend(std::iter::repeat_n(frames[0].path.display().to_string(), n));
        cook(&a).1
    };
    let (s20, s200) = (stat(20), stat(200));
    println!(
        "static volume: 20 frames {:.1} MiB peak, {} bytes; 200 frames {:.1} MiB peak, {} bytes ({:.0} bytes per extra frame)",
        mib(&s20), s20["bytes"]["file"], mib(&s200), s200["bytes"]["file"],
        (s200["bytes"]["file"].as_f64().unwrap_or(0.0) - s20["bytes"]["file"].as_f64().unwrap_or(0.0)) / 180.0
    );
    let _ = std::fs::remove_file(out);
}
