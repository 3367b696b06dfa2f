//! `vdbcook eval`: decodes every stored voxel of every frame and compares it with the source
//! files — active voxels against their values, inactive ones against the background (a non-zero
//! inactive voxel is an error too), including tiles at every level. Frames stream in chunks.

use std::collections::HashSet;
use std::path::PathBuf;

use rayon::prelude::*;
use serde_json::{json, Value};
use vdbcook_asset::{Asset, LeafRef, BRICK_VOXELS, EMPTY, TILE_BIT};
use vdbcook_vdb::sequence;
use vdbcook_vdb::{ErrorKind, FloatGrid, TileLevel, VdbError};

use vdbcook_cook::nanovdb::NanoGrids;
use vdbcook_cook::report::NanoComparison;

use crate::errors::CliError;

#[derive(clap::Args)]
pub struct Args {
    /// The cooked asset.
    asset: PathBuf,
    /// The source VDB files (files, folder, pattern or glob), one per asset frame.
    #[arg(required = true, value_name = "INPUT")]
    inputs: Vec<String>,
    /// Grid to compare (default: the grid the asset was cooked from).
    #[arg(long)]
    grid: Option<String>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
    /// Accept gaps in the frame numbering.
    #[arg(long)]
    allow_gaps: bool,
    /// Compare even when the sources do not describe the asset's grid (different grid name,
    /// transform, active voxel count or bounds); by default that is an error.
    #[arg(long)]
    force: bool,
}

/// Channel `c`'s stored bounds in `frame`, in source index space, at leaf (or region)
/// granularity.
fn stored_bbox(asset: &Asset, frame: usize, c: usize) -> Option<([i64; 3], [i64; 3])> {
    let off = asset.header.index_offset;
    let mut lo = [i64::MAX; 3];
    let mut hi = [i64::MIN; 3];
    asset.for_each_leaf_c(frame, c, |o, _, region| {
        let span = if region { 128 } else { 8 };
        for i in 0..3 {
            lo[i] = lo[i].min(o[i] + off[i] as i64);
            hi[i] = hi[i].max(o[i] + off[i] as i64 + span - 1);
        }
    });
    (lo[0] != i64::MAX).then_some((lo, hi))
}

/// Why a source frame does not describe the asset's frame, if it does not: its transform
/// (index→world, to 1e-6 relative), its active voxel count, or active bounds disjoint from
/// what the asset stores (channel `c`).
fn mismatch(asset: &Asset, frame: usize, c: usize, grid: &FloatGrid) -> Option<String> {
    let h = &asset.header;
    let m = vdbcook_cook::assemble::asset_index_to_world(&grid.transform, h.index_offset);
    let scale = h
        .index_to_world
        .iter()
        .flatten()
        .fold(0f64, |a, v| a.max(v.abs()))
        .max(1e-30);
    let diff = m
        .iter()
        .flatten()
        .zip(h.index_to_world.iter().flatten())
        .fold(0f64, |a, (x, y)| a.max((x - y).abs()));
    if diff.is_nan() || diff > 1e-6 * scale {
        return Some(format!(
            "its transform (voxel size {:?}) is not the asset's (voxel size {:?})",
            grid.transform.voxel_size(),
            h.voxel_size
        ));
    }
    let st = grid.stats();
    let want = h.channel_active_voxels(c, frame);
    if st.active_voxels != want {
        return Some(format!(
            "it has {} active voxels, the asset's frame {frame} has {want}",
            st.active_voxels
        ));
    }
    // Bounds: the asset drops bricks whose values are all the background, so its stored box
    // may be smaller than the source's active box; the two must overlap, though.
    if let Some((lo, hi)) = st.bbox {
        let overlap = stored_bbox(asset, frame, c).is_some_and(|(alo, ahi)| {
            (0..3).all(|i| (lo[i] as i64) <= ahi[i] && (hi[i] as i64) >= alo[i])
        });
        if !overlap && want > 0 {
            return Some(format!(
                "its active bounds {lo:?}..{hi:?} do not overlap what the asset's frame {frame} stores"
            ));
        }
    }
    None
}

/// Error accumulator.
#[derive(Default, Clone, Copy)]
pub struct ErrStats {
    pub compared: u64,
    pub active: u64,
    pub sum_sq: f64,
    pub max_abs: f64,
    pub inactive_errors: u64,
    pub lo: f32,
    pub hi: f32,
}

impl ErrStats {
    fn new() -> Self {
        ErrStats {
            lo: f32::INFINITY,
            hi: f32::NEG_INFINITY,
            ..Default::default()
        }
    }
    #[inline]
    fn active(&mut self, asset: f32, src: f32) {
        let e = (asset as f64 - src as f64).abs();
        self.compared += 1;
        self.active += 1;
        self.sum_sq += e * e;
        self.max_abs = self.max_abs.max(if e.is_nan() { f64::INFINITY } else { e });
        if src.is_finite() {
            self.lo = self.lo.min(src);
            self.hi = self.hi.max(src);
        }
    }
    /// `n` active voxels with the same pair of values.
    fn active_n(&mut self, asset: f32, src: f32, n: u64) {
        let e = (asset as f64 - src as f64).abs();
        self.compared += n;
        self.active += n;
        self.sum_sq += e * e * n as f64;
        self.max_abs = self.max_abs.max(if e.is_nan() { f64::INFINITY } else { e });
        if src.is_finite() {
            self.lo = self.lo.min(src);
            self.hi = self.hi.max(src);
        }
    }
    #[inline]
    fn inactive(&mut self, asset: f32, bg: f32) {
        self.compared += 1;
        if asset.to_bits() != bg.to_bits() && asset != bg {
            let e = (asset as f64 - bg as f64).abs();
            self.inactive_errors += 1;
            self.sum_sq += e * e;
            self.max_abs = self.max_abs.max(e);
        }
    }
    pub fn merge(&mut self, o: &ErrStats) {
        self.compared += o.compared;
        self.active += o.active;
        self.sum_sq += o.sum_sq;
        self.max_abs = self.max_abs.max(o.max_abs);
        self.inactive_errors += o.inactive_errors;
        self.lo = self.lo.min(o.lo);
        self.hi = self.hi.max(o.hi);
    }
    pub fn rmse(&self) -> f64 {
        if self.active == 0 {
            0.0
        } else {
            (self.sum_sq / self.active as f64).sqrt()
        }
    }
    pub fn psnr_db(&self) -> Option<f64> {
        let peak = (self.hi - self.lo) as f64;
        let r = self.rmse();
        (r > 0.0 && peak > 0.0).then(|| 20.0 * (peak / r).log10())
    }
    pub fn to_json(self) -> Value {
        json!({"rmse": self.rmse(), "psnr_db": self.psnr_db(), "max_abs": self.max_abs, "active_voxels": self.active, "voxels_compared": self.compared, "inactive_errors": self.inactive_errors, "exact": self.max_abs == 0.0})
    }
}

fn leaf_values(asset: &Asset, frame: usize, c: usize, a: [i64; 3], out: &mut [f32; BRICK_VOXELS]) {
    match asset.leaf_at_c(frame, a, c) {
        LeafRef::Empty => out.fill(asset.header.channel_background(c)),
        LeafRef::Tile(v) => out.fill(v),
        LeafRef::Brick(b) => asset.decode_brick(b, out),
    }
}

/// Compares one frame of the asset with its source grid.
pub fn compare_frame(asset: &Asset, frame: usize, grid: &FloatGrid) -> ErrStats {
    compare_frame_c(asset, frame, 0, grid)
}

/// Compares channel `c` of one frame of the asset with its source grid.
pub fn compare_frame_c(asset: &Asset, frame: usize, c: usize, grid: &FloatGrid) -> ErrStats {
    let bg = asset.header.channel_background(c);
    let mut s = ErrStats::new();
    let mut seen: HashSet<[i64; 3]> = HashSet::new();
    let mut vals = [0f32; BRICK_VOXELS];
    for (li, leaf) in grid.leaves.iter().enumerate() {
        let a = asset.header.to_asset_index(leaf.origin);
        leaf_values(asset, frame, c, a, &mut vals);
        seen.insert(a);
        let src = grid.leaf_values(li);
        for (n, &sv) in src.iter().enumerate() {
            let av = vals[n];
            if leaf.is_active(n) {
                s.active(av, sv);
            } else {
                s.inactive(av, bg);
            }
        }
    }
    let mut seen_regions: HashSet<[i64; 3]> = HashSet::new();
    for t in grid.tiles.iter().filter(|t| t.active) {
        let o = asset.header.to_asset_index(t.origin);
        // Large tiles are compared region by region (a tiled region once, weighted by its size).
        let (step, n) = if t.level == TileLevel::L8 {
            (8i64, 1i64)
        } else {
            (128, (t.level.dim() / 128) as i64)
        };
        for x in 0..n {
            for y in 0..n {
                for z in 0..n {
                    let r = [o[0] + step * x, o[1] + step * y, o[2] + step * z];
                    if step == 128 {
                        let e = asset.root_entry(frame, r);
                        if e != EMPTY && e & TILE_BIT != 0 {
                            seen_regions.insert(r);
                            s.active_n(
                                asset.tiles[(e & !TILE_BIT) as usize],
                                t.value,
                                128 * 128 * 128,
                            );
                            continue;
                        }
                    }
                    let leaves = step / 8;
                    for lx in 0..leaves {
                        for ly in 0..leaves {
                            for lz in 0..leaves {
                                let a = [r[0] + 8 * lx, r[1] + 8 * ly, r[2] + 8 * lz];
                                seen.insert(a);
                                match asset.leaf_at_c(frame, a, c) {
                                    LeafRef::Brick(b) => {
                                        asset.decode_brick(b, &mut vals);
                                        for &av in vals.iter() {
                                            s.active(av, t.value);
                                        }
                                    }
                                    LeafRef::Tile(v) => s.active_n(v, t.value, 512),
                                    LeafRef::Empty => s.active_n(bg, t.value, 512),
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    // Whatever else the asset stores must be background.
    asset.for_each_leaf_c(frame, c, |origin, r, region| {
        if region && seen_regions.contains(&origin) {
            return;
        }
        let leaves = if region { 16 } else { 1 };
        for x in 0..leaves {
            for y in 0..leaves {
                for z in 0..leaves {
                    let a = [origin[0] + 8 * x, origin[1] + 8 * y, origin[2] + 8 * z];
                    if seen.contains(&a) {
                        continue;
                    }
                    let mut v = [0f32; BRICK_VOXELS];
                    match r {
                        LeafRef::Brick(b) => asset.decode_brick(b, &mut v),
                        LeafRef::Tile(t) => v.fill(t),
                        LeafRef::Empty => v.fill(bg),
                    }
                    for &av in v.iter() {
                        s.inactive(av, bg);
                    }
                }
            }
        }
    });
    s
}

pub fn run(a: &Args) -> Result<(), CliError> {
    let asset = crate::cook::load_asset(&a.asset)?;
    let frames = sequence::resolve_inputs(&a.inputs, a.allow_gaps)?;
    if frames.len() != asset.frame_count() {
        return Err(CliError::Vdb(VdbError::new(
            ErrorKind::Sequence,
            &a.asset,
            format!(
                "the asset has {} frames but {} source files were given",
                asset.frame_count(),
                frames.len()
            ),
        )));
    }
    // The grids the asset was cooked from, in every frame (or --grid, which must name one).
    let h = &asset.header;
    let cooked: Vec<String> = (0..asset.channel_count())
        .map(|c| h.channel_name(c).to_string())
        .collect();
    let refuse = |path: &std::path::Path, m: String| {
        CliError::Vdb(VdbError::new(
            ErrorKind::Sequence,
            path,
            format!(
                "{m}; these sources do not describe the asset (pass --force to compare anyway)"
            ),
        ))
    };
    // (channel, source grid name) pairs to compare.
    let compared: Vec<(usize, String)> = match &a.grid {
        None => cooked.iter().cloned().enumerate().collect(),
        Some(g) => match h.channel_index(g) {
            Some(c) => vec![(c, g.clone())],
            None if a.force => vec![(0, g.clone())],
            None => {
                return Err(refuse(
                    &a.asset,
                    format!("--grid {g} is not the asset's grid ({})", cooked.join(", ")),
                ))
            }
        },
    };
    let how = format!(
        "one of the asset's grids; {} was cooked from {}",
        a.asset.display(),
        cooked.join(", ")
    );
    let mut per_frame = Vec::with_capacity(frames.len());
    let mut total = ErrStats::new();
    let mut per_channel = vec![ErrStats::new(); compared.len()];
    let mut forced = Vec::new();
    let chunk = (rayon::current_num_threads() * 2).max(2);
    // The source frames as NanoVDB grids, per compared channel (`vdbcook_cook::nanovdb`), at
    // the channel's recorded budget (measured for FpN only where there is one).
    let budget = |c: usize| {
        h.channels
            .get(c)
            .map_or(h.options.max_error, |ch| ch.max_error)
    };
    let mut nano = vec![NanoGrids::default(); compared.len()];
    type FrameResult = Result<Vec<(ErrStats, Option<String>, NanoGrids)>, VdbError>;
    for (ci, group) in frames.chunks(chunk).enumerate() {
        let res: Vec<FrameResult> = group
            .par_iter()
            .enumerate()
            .map(|(k, f)| {
                let fi = ci * chunk + k;
                let file = vdbcook_vdb::VdbFile::open(&f.path)?;
                let mut out = Vec::with_capacity(compared.len());
                for (c, name) in &compared {
                    // A channel cooked empty for want of its grid (--allow-missing-grid)
                    // compares as empty.
                    let empty = h.channel_active_voxels(*c, fi) == 0;
                    out.push(
                        match vdbcook_cook::frames::read_named_in(
                            &file, f, name, &how, empty, false,
                        )? {
                            None => (ErrStats::new(), None, NanoGrids::default()),
                            Some(l) => {
                                let mut n = NanoGrids::default();
                                n.add_grid(&l.grid, budget(*c).is_some());
                                (
                                    compare_frame_c(&asset, fi, *c, &l.grid),
                                    mismatch(&asset, fi, *c, &l.grid)
                                        .map(|m| format!("grid '{name}': {m}")),
                                    n,
                                )
                            }
                        },
                    );
                }
                Ok(out)
            })
            .collect();
        for (k, r) in res.into_iter().enumerate() {
            let f = &group[k];
            let mut frame_stats = ErrStats::new();
            for (i, (s, bad, n)) in r?.into_iter().enumerate() {
                nano[i].merge(n);
                if let Some(m) = bad {
                    if !a.force {
                        return Err(refuse(&f.path, m));
                    }
                    eprintln!(
                        "warning: {}: {m} (compared anyway: --force)",
                        f.path.display()
                    );
                    forced.push(f.path.display().to_string());
                }
                frame_stats.merge(&s);
                per_channel[i].merge(&s);
            }
            total.merge(&frame_stats);
            let mut j = frame_stats.to_json();
            j["frame"] = json!(ci * chunk + k);
            j["number"] = json!(f.number);
            j["source"] = json!(f.path.display().to_string());
            per_frame.push(j);
        }
    }
    forced.dedup();
    let grid = compared[0].1.clone();
    let channels: Vec<Value> = compared
        .iter()
        .zip(&per_channel)
        .map(|((_, name), s)| {
            let mut j = s.to_json();
            j["name"] = json!(name);
            j
        })
        .collect();
    let file_bytes = std::fs::metadata(&a.asset).map(|m| m.len()).unwrap_or(0);
    let gpu: u64 = vdbcook_cook::assemble::section_sizes(&asset)
        .iter()
        .map(|(_, n)| n)
        .sum();
    let bpv = |b: u64| {
        if total.active > 0 {
            b as f64 * 8.0 / total.active as f64
        } else {
            0.0
        }
    };
    let mut doc = total.to_json();
    doc["asset"] = json!(a.asset.display().to_string());
    doc["format"] = json!(asset.header.options.format.name());
    doc["bits_per_active_voxel"] = json!(bpv(file_bytes));
    doc["bits_per_active_voxel_gpu"] = json!(bpv(gpu));
    doc["bytes"] = json!({"file": file_bytes, "gpu": gpu});
    // NanoVDB at the asset's budget per compared channel (float grids for a lossless one); the
    // ratio only when every channel was compared (the asset's GPU bytes are all of them).
    let whole = compared.len() == asset.header.channel_count();
    let nano_doc = NanoComparison::of(
        compared
            .iter()
            .zip(&nano)
            .map(|((c, _), n)| (n, budget(*c))),
        total.active,
        whole.then_some(gpu),
    );
    doc["nanovdb"] = json!(nano_doc);
    doc["frames"] = json!(per_frame);
    doc["grid"] = json!(grid);
    doc["mismatched_frames"] = json!(forced);
    if compared.len() > 1 {
        // Units differ between channels: the merged figures' PSNR is the worst channel's.
        doc["psnr_db"] = json!(per_channel
            .iter()
            .filter_map(|s| s.psnr_db())
            .reduce(f64::min));
    }
    doc["channels"] = json!(channels);
    if a.json {
        println!("{}", serde_json::to_string_pretty(&doc).expect("json"));
    } else {
        println!(
            "{} ({}) against {} source frame(s):",
            a.asset.display(),
            asset.header.options.format.name(),
            frames.len()
        );
        println!(
            "  active voxels {}, compared {}",
            total.active, total.compared
        );
        println!(
            "  rmse {:.3e}, max abs {:.3e}, psnr {}, inactive voxels not background: {}",
            total.rmse(),
            total.max_abs,
            doc["psnr_db"]
                .as_f64()
                .map(|p| format!("{p:.1} dB"))
                .unwrap_or_else(|| if total.max_abs == 0.0 {
                    "exact".into()
                } else {
                    "-".into()
                }),
            total.inactive_errors
        );
        println!("  GPU {gpu} bytes, {:.3} bit/active voxel", bpv(gpu));
        if let Some(n) = &nano_doc {
            println!(
                "  NanoVDB {} of the same frames at the same {}: {} bytes, {:.3} bit/active voxel{}",
                n.format,
                if n.format == "float" { "exactness" } else { "bound" },
                n.gpu_bytes,
                n.bits_per_active_voxel,
                n.ratio.map_or_else(
                    || format!(
                        " (channels {} only)",
                        compared
                            .iter()
                            .map(|(_, n)| n.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                    |r| format!("; this asset is {r:.3}x")
                )
            );
        }
        println!(
            "  file {file_bytes} bytes, {:.3} bit/active voxel",
            bpv(file_bytes)
        );
        if compared.len() > 1 {
            for ((_, name), s) in compared.iter().zip(&per_channel) {
                println!(
                    "  {name:<14} rmse {:.3e}, max abs {:.3e}, psnr {}, {} active voxels",
                    s.rmse(),
                    s.max_abs,
                    s.psnr_db()
                        .map(|p| format!("{p:.1} dB"))
                        .unwrap_or_else(|| "exact".into()),
                    s.active
                );
            }
        }
    }
    Ok(())
}
