//! `vdbcook info`: what an asset holds — header, cook options, frames with their node counts and
//! bounds, the brick pool, bytes per section (raw = GPU, and compressed in the file), topology bits
//! per active voxel, and the fixed cost of each extra frame.

use std::path::PathBuf;

use serde_json::json;
use vdbcook_asset::{LeafRef, EMPTY, TILE_BIT};

use crate::errors::CliError;
use vdbcook_cook::assemble::{section_sizes, topology_and_atlas};

#[derive(clap::Args)]
pub struct Args {
    /// The cooked asset.
    asset: PathBuf,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

/// What one channel of one frame stores.
#[derive(Clone)]
struct LeafStats {
    bricks: u64,
    tiles: u64,
    lo: [i64; 3],
    hi: [i64; 3],
}

impl Default for LeafStats {
    fn default() -> Self {
        LeafStats {
            bricks: 0,
            tiles: 0,
            lo: [i64::MAX; 3],
            hi: [i64::MIN; 3],
        }
    }
}

fn bricks_by_format(asset: &vdbcook_asset::Asset) -> serde_json::Value {
    let mut m = serde_json::Map::new();
    for (f, n) in vdbcook_asset::PayloadFormat::ORDER
        .iter()
        .zip(asset.header.brick_counts)
    {
        m.insert(f.name().to_string(), json!(n));
    }
    serde_json::Value::Object(m)
}

pub fn run(a: &Args) -> Result<(), CliError> {
    let asset = crate::cook::load_asset(&a.asset)?;
    let h = &asset.header;
    let file_bytes = std::fs::metadata(&a.asset).map(|m| m.len()).unwrap_or(0);
    let sizes = section_sizes(&asset);
    let (topology, atlas) = topology_and_atlas(&sizes);
    let active: u64 = h.frames.iter().map(|f| f.active_voxels).sum();
    let nch = asset.channel_count();
    // Per (frame, channel): stored bricks, tile leaves and the box of the leaves it stores.
    let mut stats = vec![LeafStats::default(); h.frames.len() * nch];
    let mut channel_bricks = vec![std::collections::BTreeSet::new(); nch];
    for fi in 0..h.frames.len() {
        for (c, set) in channel_bricks.iter_mut().enumerate() {
            let st = &mut stats[fi * nch + c];
            asset.for_each_leaf_c(fi, c, |o, r, region| {
                match r {
                    LeafRef::Brick(b) => {
                        st.bricks += 1;
                        set.insert(b);
                    }
                    _ => st.tiles += 1,
                }
                let span = if region { 128 } else { 8 };
                let s = [0, 1, 2].map(|i| o[i] + h.index_offset[i] as i64);
                st.lo = [0, 1, 2].map(|i| st.lo[i].min(s[i]));
                st.hi = [0, 1, 2].map(|i| st.hi[i].max(s[i] + span - 1));
            });
        }
    }
    let bbox = |s: &LeafStats| (s.lo[0] != i64::MAX).then_some((s.lo, s.hi));
    let mut frames = Vec::new();
    for (fi, f) in h.frames.iter().enumerate() {
        let roots = asset.frame_roots(fi);
        let nodes = roots
            .iter()
            .filter(|&&e| e != EMPTY && e & TILE_BIT == 0)
            .count();
        let mut all = LeafStats::default();
        for s in &stats[fi * nch..(fi + 1) * nch] {
            all.bricks += s.bricks;
            all.tiles += s.tiles;
            for i in 0..3 {
                all.lo[i] = all.lo[i].min(s.lo[i]);
                all.hi[i] = all.hi[i].max(s.hi[i]);
            }
        }
        let b = bbox(&all);
        frames.push(json!({
            "frame": fi, "number": f.number, "source": f.source, "active_voxels": f.active_voxels,
            "l2_nodes": nodes, "bricks": all.bricks, "tile_leaves": all.tiles,
            "bbox_min": b.map(|b| b.0), "bbox_max": b.map(|b| b.1),
            "value_range": asset.frame_range(fi, 0),
        }));
    }
    let channels: Vec<_> = (0..nch)
        .map(|c| {
            let active = |fi: usize| h.channel_active_voxels(c, fi);
            let per_frame: Vec<_> = (0..h.frames.len())
                .map(|fi| {
                    let s = &stats[fi * nch + c];
                    let b = bbox(s);
                    json!({"frame": fi, "active_voxels": active(fi), "bricks": s.bricks,
                           "tile_leaves": s.tiles, "value_range": asset.frame_range(fi, c),
                           "bbox_min": b.map(|b| b.0), "bbox_max": b.map(|b| b.1)})
                })
                .collect();
            let bricks = &channel_bricks[c];
            json!({
                "name": h.channel_name(c),
                "background": h.channel_background(c),
                "max_error": h.channels.get(c).map_or(h.options.max_error, |ch| ch.max_error),
                "active_voxels": (0..h.frames.len()).map(active).sum::<u64>(),
                "bricks": bricks.len(),
                "atlas_bytes": bricks.iter().map(|&b| asset.brick_format(b).0.bytes_per_brick() as u64).sum::<u64>(),
                "frames": per_frame,
            })
        })
        .collect();
    let per_frame_bytes = asset.root_len() as u64 * 4 + 8 * nch as u64;
    let levels: Vec<_> = crate::lod::per_level(&asset)
        .iter()
        .enumerate()
        .map(|(k, l)| {
            // `level`: the chain's (voxels 2^level wide); `stored`: the index among the asset's
            // levels (`Asset::lod_set`). The same unless cooked with --lod-from.
            json!({"level": asset.level_shift(k), "stored": k,
                   "voxel_span": 1u64 << asset.level_shift(k), "bricks": l.bricks,
                   "new_bricks": l.new_bricks, "new_atlas_bytes": l.new_atlas_bytes})
        })
        .collect();
    let bpv = |b: u64| {
        if active > 0 {
            b as f64 * 8.0 / active as f64
        } else {
            0.0
        }
    };
    let sections: Vec<_> = h
        .sections
        .iter()
        .zip(&sizes)
        .map(|(s, (name, raw))| json!({"name": name, "raw_bytes": raw, "file_bytes": s.compressed_len}))
        .collect();
    let doc = json!({
        "asset": a.asset.display().to_string(),
        "tool": h.tool,
        "format_version": h.format_version(),
        "content_hash": format!("{:016x}", h.content_hash),
        "options": {"format": h.options.format.name(), "max_error": h.options.max_error, "grid": h.options.grid, "replace_non_finite": h.options.replace_non_finite, "allow_gaps": h.options.allow_gaps},
        "grid": h.grid_name,
        "frame_count": asset.frame_count(),
        "active_voxels": active,
        "background": h.background,
        "index_offset": h.index_offset,
        "root_dims": h.root_dims,
        "extent_voxels": h.root_dims.map(|d| d * 128),
        "transform": {"source_map": h.source_map, "voxel_size": h.voxel_size, "matrix": h.index_to_world},
        "pool": {"format": h.options.format.name(), "bricks": asset.brick_count(), "tiles": asset.tiles.len(), "l2_nodes": asset.l2_count(), "leaf_refs": asset.l3_refs.len(), "bytes": asset.payload_bytes(), "bricks_by_format": bricks_by_format(&asset)},
        "bytes": {"file": file_bytes, "topology": topology, "atlas": atlas, "gpu": topology + atlas},
        "sections": sections,
        "topology_bits_per_active_voxel": bpv(topology),
        "bits_per_active_voxel": bpv(file_bytes),
        "bits_per_active_voxel_gpu": bpv(topology + atlas),
        "bytes_per_extra_static_frame": per_frame_bytes,
        "frames": frames,
        "channels": channels,
        "lod_levels": h.lod_levels,
        "lod_first": h.lod_first,
        "levels": levels,
    });
    if a.json {
        println!("{}", serde_json::to_string_pretty(&doc).expect("json"));
        return Ok(());
    }
    println!(
        "{}  ({}, asset format {}, content {})",
        a.asset.display(),
        h.tool,
        h.format_version(),
        doc["content_hash"].as_str().unwrap_or("")
    );
    println!(
        "  grid '{}', {} frame(s), {} active voxels, background {}",
        h.grid_name,
        asset.frame_count(),
        active,
        h.background
    );
    println!(
        "  pool: {} bricks ({}), {} tile values, {} L2 nodes, {} leaf refs",
        asset.brick_count(),
        bricks_by_format(&asset),
        asset.tiles.len(),
        asset.l2_count(),
        asset.l3_refs.len()
    );
    if nch > 1 {
        println!("  channels (one topology, the union of their active regions):");
        for c in &channels {
            println!(
                "    {:<14} background {}, {} active voxels, {} bricks ({} atlas bytes), budget {}",
                c["name"].as_str().unwrap_or(""),
                c["background"],
                c["active_voxels"],
                c["bricks"],
                c["atlas_bytes"],
                c["max_error"]
                    .as_f64()
                    .map_or("none (lossless)".into(), |e| format!("{}", e as f32))
            );
        }
    }
    match h.options.max_error {
        Some(e) => println!(
            "  error budget: every voxel within {e:e} of its source, as a GPU within the BC precision rules reads it"
        ),
        None if nch > 1 => {}
        None if asset.brick_count() as u64
            == h.brick_counts[vdbcook_asset::PayloadFormat::F32.rank()] =>
        {
            println!("  error budget: none (f32 payload, lossless)")
        }
        None => println!("  error budget: none recorded (a lossy cook by an older vdbcook)"),
    }
    println!(
        "  extent {:?} voxels from source index {:?}; {} map, voxel size {:?}",
        h.root_dims.map(|d| d * 128),
        h.index_offset,
        h.source_map,
        h.voxel_size
    );
    println!(
        "  GPU {} bytes, {:.3} bit/active voxel (topology {topology}, atlas {atlas}); file {file_bytes} bytes, {:.3} bit/active voxel",
        topology + atlas,
        bpv(topology + atlas),
        bpv(file_bytes)
    );
    println!("  topology {:.3} bit per active voxel; each extra frame of a static volume costs {per_frame_bytes} bytes", bpv(topology));
    if h.lod_levels > 0 {
        let from = if h.lod_first > 1 {
            format!(", from level {} (--lod-from)", h.lod_first)
        } else {
            String::new()
        };
        println!(
            "  levels of detail ({} coarser{from}; bricks over all frames, new = used by no finer level):",
            h.lod_levels
        );
        for l in &levels {
            println!(
                "    level {} ({:>4}^3 voxels per voxel) {:>8} bricks, {:>8} new ({} atlas bytes)",
                l["level"], l["voxel_span"], l["bricks"], l["new_bricks"], l["new_atlas_bytes"]
            );
        }
    }
    println!("  sections (raw / in file):");
    for s in &sections {
        println!(
            "    {:<13} {:>12} / {:>12}",
            s["name"].as_str().unwrap_or(""),
            s["raw_bytes"],
            s["file_bytes"]
        );
    }
    println!("  frames:");
    for f in &frames {
        println!(
            "    {:>4} {:<40} {:>10} voxels  {:>4} nodes {:>7} bricks {:>5} tiles  bbox {} .. {}",
            f["frame"],
            f["source"].as_str().unwrap_or(""),
            f["active_voxels"],
            f["l2_nodes"],
            f["bricks"],
            f["tile_leaves"],
            f["bbox_min"],
            f["bbox_max"]
        );
    }
    Ok(())
}
