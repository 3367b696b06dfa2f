//! Reader throughput: read a file and visit every active voxel, with vdbcook's reader and with
//! vdb-rs on the same file, one thread each. Prints medians over several runs, the spread, and
//! the ratio, in M active voxels per second. Usage:
//! `cargo bench -p vdbcook-vdb --bench read -- FILE.vdb [RUNS]` (see `just bench`).

use std::time::Instant;

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

fn ours(path: &str) -> (u64, f64) {
    let f = vdbcook_vdb::VdbFile::open(path).expect("open");
    let idx = f.select(None).expect("grid");
    let g = f.read_float_grid(idx).expect("read");
    let mut n = 0u64;
    let mut sum = 0.0f64;
    g.for_each_active_leaf_voxel(|_, v| {
        n += 1;
        sum += v as f64;
    });
    for t in g.tiles.iter().filter(|t| t.active) {
        n += t.level.voxels();
        sum += t.value as f64 * t.level.voxels() as f64;
    }
    (n, sum)
}

fn theirs(path: &str) -> (u64, f64) {
    let file = std::io::BufReader::new(std::fs::File::open(path).expect("open"));
    let mut r = vdb_rs::VdbReader::new(file).expect("vdb-rs open");
    let g = r.read_grid::<f32>("density").expect("vdb-rs read");
    let mut n = 0u64;
    let mut sum = 0.0f64;
    for (_, v, level) in g.iter() {
        let s = level.scale() as u64;
        let k = s * s * s;
        n += k;
        sum += v as f64 * k as f64;
    }
    (n, sum)
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let Some(path) = args.first() else {
        eprintln!("usage: read FILE.vdb [RUNS]   (generate one with `just bench`)");
        return;
    };
    let runs: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(7);
    let info = vdbcook_vdb::VdbFile::open(path).expect("open");
    let g = &info.grids[info.select(None).expect("grid")];
    println!(
        "file {path}: {} bytes, grid '{}' {}{}",
        info.len_bytes(),
        g.label,
        g.compression_name(),
        if g.half_float { ", half" } else { "" }
    );
    let mut results = Vec::new();
    for (name, f) in [
        ("vdbcook", ours as fn(&str) -> (u64, f64)),
        ("vdb-rs", theirs),
    ] {
        let mut times = Vec::new();
        let mut last = (0, 0.0);
        for _ in 0..runs {
            let t = Instant::now();
            last = std::hint::black_box(f(path));
            times.push(t.elapsed().as_secs_f64());
        }
        let (min, max) = (
            times.iter().cloned().fold(f64::MAX, f64::min),
            times.iter().cloned().fold(0.0, f64::max),
        );
        let med = median(&mut times);
        let mvps = last.0 as f64 / med / 1e6;
        println!("{name:>8}: {} active voxels, sum {:.6e}; median {:.1} ms (min {:.1}, max {:.1}, {runs} runs) = {mvps:.0} M active voxels/s", last.0, last.1, med * 1e3, min * 1e3, max * 1e3);
        results.push((name, med, mvps, last));
    }
    let (a, b) = (&results[0], &results[1]);
    println!(
        "speedup vdbcook / vdb-rs: {:.2}x (same voxel count: {}, sums differ by {:.2e})",
        b.1 / a.1,
        a.3 .0 == b.3 .0,
        (a.3 .1 - b.3 .1).abs()
    );
    println!("{{\"bench\":\"read\",\"file\":\"{path}\",\"active_voxels\":{},\"vdbcook_ms\":{:.3},\"vdb_rs_ms\":{:.3},\"vdbcook_mvox_s\":{:.1},\"vdb_rs_mvox_s\":{:.1}}}", a.3 .0, a.1 * 1e3, b.1 * 1e3, a.2, b.2);
}
