//! Payloads for two or three channels (issue 14, item 2), measured: per-channel BC4 atlases (what
//! `cook --grids … --format bc4` writes), BC5 (density and temperature as the two BC4 halves of
//! one block, flame in BC4), BC7 with the channels in RGB, and unorm8/f16 per channel against
//! their RG8/RGBA8 and RG16F/RGBA16F textures (three channels pad to four). Bytes are the atlas
//! plus the leaf refs it needs; errors are per channel, relative to the channel's value range, over every voxel of every
//! stored brick, each decoded by the asset crate's decoders (BC5's halves are BC4 blocks by the
//! spec, so its errors are BC4's; the byte counts are what differ).
//!
//! `cargo bench -p vdbcook --bench channel_payloads -- [INPUT] [GRIDS] [OUT_DIR]`, by default
//! the fire fixture's three grids; writes `OUT_DIR/channel_payloads.{md,json,png}` when given.

use std::collections::BTreeSet;
use std::path::PathBuf;

use serde_json::json;
use vdbcook::bcenc::{encode_bc7, Bc7Quality};
use vdbcook::report::chart::{scatter_chart, Point, Series, PALETTE};
use vdbcook_asset::bc::decode_bc7_block;
use vdbcook_asset::payload::{decode_brick, dequantize, quantize, vox_index};
use vdbcook_asset::{Asset, PayloadFormat, BRICK_VOXELS, EMPTY, TILE_BIT};

/// One slot's value source for one channel.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
enum Src {
    Brick(u32),
    Const(u32),
}

/// Per-channel error accumulator (relative to the channel's range).
#[derive(Clone, Copy, Default)]
struct Err {
    max: f64,
    sq: f64,
    n: u64,
}

impl Err {
    fn add(&mut self, a: f32, b: f32) {
        let d = (a as f64 - b as f64).abs();
        self.max = self.max.max(d);
        self.sq += d * d;
        self.n += 1;
    }
    fn rel(&self, range: f64) -> (f64, f64) {
        let rmse = (self.sq / self.n.max(1) as f64).sqrt();
        (self.max / range, rmse / range)
    }
}

fn values(asset: &Asset, s: Src) -> [f32; BRICK_VOXELS] {
    match s {
        Src::Brick(b) => {
            let mut v = [0.0; BRICK_VOXELS];
            asset.decode_brick(b, &mut v);
            v
        }
        Src::Const(bits) => [f32::from_bits(bits); BRICK_VOXELS],
    }
}

fn range_of(v: &[f32]) -> (f32, f32) {
    v.iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), &x| {
            (l.min(x), h.max(x))
        })
}

/// A brick through the cook's BC4 encoder (its own range): the decoded values.
fn via_bc4(v: &[f32; BRICK_VOXELS]) -> [f32; BRICK_VOXELS] {
    let (lo, hi) = range_of(v);
    let mut out = [0.0; BRICK_VOXELS];
    decode_brick(
        PayloadFormat::Bc4,
        &vdbcook::bc4fit::encode_brick(v, lo, hi),
        [lo, hi],
        &mut out,
    );
    out
}

/// Up to three channels' bricks through one BC7 brick with the channels in R, G, B (each on its
/// own range, A = 255): the decoded values per channel.
fn via_bc7_rgb(ch: &[[f32; BRICK_VOXELS]]) -> Vec<[f32; BRICK_VOXELS]> {
    let ranges: Vec<(f32, f32)> = ch.iter().map(|v| range_of(v)).collect();
    let mut surf = vec![255u8; 8 * 64 * 4];
    for z in 0..8 {
        for y in 0..8 {
            for x in 0..8 {
                let t = ((8 * z + y) * 8 + x) * 4;
                for (c, v) in ch.iter().enumerate() {
                    surf[t + c] = quantize(v[vox_index(x, y, z)], ranges[c].0, ranges[c].1);
                }
            }
        }
    }
    let blocks = encode_bc7(8, 64, &surf, Bc7Quality::Slow);
    let mut out = vec![[0.0f32; BRICK_VOXELS]; ch.len()];
    for (i, b) in blocks.chunks_exact(16).enumerate() {
        let t = decode_bc7_block(b.try_into().unwrap());
        let (bx, by) = (i % 2, i / 2);
        for (k, rgba) in t.iter().enumerate() {
            let (x, row) = (4 * bx + k % 4, 4 * by + k / 4);
            let (z, y) = (row / 8, row % 8);
            for (c, o) in out.iter_mut().enumerate() {
                o[vox_index(x, y, z)] = dequantize(rgba[c], ranges[c].0, ranges[c].1);
            }
        }
    }
    out
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let input = args.first().cloned().unwrap_or("fixtures/seq/fire".into());
    let grids: Vec<String> = args
        .get(1)
        .map(|g| g.split(',').map(String::from).collect())
        .unwrap_or(vec!["density".into(), "temperature".into(), "flame".into()]);
    // Relative paths are of the workspace root (cargo runs benches in the package's folder).
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let out_dir = args.get(2).map(|d| root.join(d));
    let input_path = if PathBuf::from(&input).exists() {
        PathBuf::from(&input)
    } else {
        root.join(&input)
    };
    let a = vdbcook_cook::CookOptions {
        grids: vdbcook_cook::Grids::Several(grids.clone()),
        keep_empty_channels: true,
        ..Default::default()
    };
    let asset = match vdbcook_cook::cook_inputs(
        &[input_path.display().to_string()],
        &a,
        &vdbcook_cook::Context::quiet(),
    ) {
        Ok(c) => c.asset,
        Err(e) => {
            eprintln!("channel_payloads: {e}");
            std::process::exit(1);
        }
    };
    let n = asset.channel_count();
    assert!(n >= 2, "several grids needed");
    // Every (node, slot) of the shared topology: one source per channel.
    let slots: Vec<Vec<Src>> = asset
        .l3_refs
        .chunks_exact(n)
        .map(|refs| {
            refs.iter()
                .enumerate()
                .map(|(c, &r)| {
                    if r == EMPTY {
                        Src::Const(asset.header.channel_background(c).to_bits())
                    } else if r & TILE_BIT != 0 {
                        Src::Const(asset.tiles[(r & !TILE_BIT) as usize].to_bits())
                    } else {
                        Src::Brick(r)
                    }
                })
                .collect()
        })
        .collect();
    let slot_count = slots.len() as u64;
    let has_brick = |t: &[Src]| t.iter().any(|s| matches!(s, Src::Brick(_)));
    let per_channel: Vec<BTreeSet<u32>> = (0..n)
        .map(|c| {
            slots
                .iter()
                .filter_map(|t| match t[c] {
                    Src::Brick(b) => Some(b),
                    _ => None,
                })
                .collect()
        })
        .collect();
    let tuples: BTreeSet<Vec<Src>> = slots.iter().filter(|t| has_brick(t)).cloned().collect();
    let pairs: BTreeSet<Vec<Src>> = slots
        .iter()
        .map(|t| t[..2].to_vec())
        .filter(|t| has_brick(t))
        .collect();
    let ranges: Vec<f64> = (0..n)
        .map(|c| {
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for f in 0..asset.frame_count() {
                let r = asset.frame_range(f, c);
                lo = lo.min(r[0]);
                hi = hi.max(r[1]);
            }
            ((hi - lo) as f64).max(f64::MIN_POSITIVE)
        })
        .collect();
    // Per-channel errors of the independent quantizers, over each channel's unique bricks.
    let (mut e_bc4, mut e_u8, mut e_f16) = (
        vec![Err::default(); n],
        vec![Err::default(); n],
        vec![Err::default(); n],
    );
    for c in 0..n {
        for &b in &per_channel[c] {
            let v = values(&asset, Src::Brick(b));
            let d = via_bc4(&v);
            let (lo, hi) = range_of(&v);
            for i in 0..BRICK_VOXELS {
                e_bc4[c].add(v[i], d[i]);
                e_u8[c].add(v[i], dequantize(quantize(v[i], lo, hi), lo, hi));
                e_f16[c].add(v[i], half::f16::from_f32(v[i]).to_f32());
            }
        }
    }
    // BC7 RGB over the unique tuples (only the first three channels fit RGB).
    let rgb = n.min(3);
    let mut e_bc7 = vec![Err::default(); n];
    for t in &tuples {
        let ch: Vec<[f32; BRICK_VOXELS]> = t[..rgb].iter().map(|&s| values(&asset, s)).collect();
        let d = via_bc7_rgb(&ch);
        for c in 0..rgb {
            if let Src::Brick(_) = t[c] {
                for i in 0..BRICK_VOXELS {
                    e_bc7[c].add(ch[c][i], d[c][i]);
                }
            }
        }
    }
    let bricks: Vec<u64> = per_channel.iter().map(|s| s.len() as u64).collect();
    let sum_bricks: u64 = bricks.iter().sum();
    let rest: u64 = bricks[2.min(n)..].iter().sum();
    let packed = if n == 2 { 2 } else { 4 };
    // (layout, atlas bytes, refs per slot, per-channel errors)
    let layouts: Vec<(&str, u64, u64, Vec<Err>)> = vec![
        ("bc4 per channel", 256 * sum_bricks, n as u64, e_bc4.clone()),
        (
            "bc5 (ch0+ch1) + bc4",
            512 * pairs.len() as u64 + 256 * rest,
            (n - 1) as u64,
            e_bc4.clone(),
        ),
        (
            "bc7 rgb",
            512 * tuples.len() as u64 + 256 * bricks[rgb..].iter().sum::<u64>(),
            1 + (n - rgb) as u64,
            e_bc7.clone(),
        ),
        (
            "unorm8 per channel",
            512 * sum_bricks,
            n as u64,
            e_u8.clone(),
        ),
        // wgpu has RG and RGBA texture formats, no RGB: three channels pad to four.
        (
            if n == 2 { "rg8" } else { "rgba8" },
            512 * packed * tuples.len() as u64,
            1,
            e_u8.clone(),
        ),
        (
            "f16 per channel",
            1024 * sum_bricks,
            n as u64,
            e_f16.clone(),
        ),
        (
            if n == 2 { "rg16f" } else { "rgba16f" },
            1024 * packed * tuples.len() as u64,
            1,
            e_f16.clone(),
        ),
    ];
    let names: Vec<String> = (0..n)
        .map(|c| asset.header.channel_name(c).to_string())
        .collect();
    let mut md = format!(
        "Input `{input}`, grids {}: {} slots, unique bricks per channel {:?}, {} unique brick \
         tuples, {} unique (ch0, ch1) pairs.\n\n| layout | atlas bytes | ref bytes | total |",
        names.join(","),
        slot_count,
        bricks,
        tuples.len(),
        pairs.len()
    );
    for nm in &names {
        md += &format!(" {nm} max/range | {nm} rmse/range |");
    }
    md += "\n|---|---|---|---|";
    md += &"---|---|".repeat(n);
    md += "\n";
    let mut rows = Vec::new();
    let mut points = Vec::new();
    for (k, (name, atlas, refs, errs)) in layouts.iter().enumerate() {
        let ref_bytes = 4 * refs * slot_count;
        md += &format!("| {name} | {atlas} | {ref_bytes} | {} |", atlas + ref_bytes);
        let mut ch = Vec::new();
        for c in 0..n {
            let (mx, rm) = errs[c].rel(ranges[c]);
            md += &format!(" {mx:.2e} | {rm:.2e} |");
            ch.push(json!({"name": names[c], "max_abs_rel": mx, "rmse_rel": rm}));
            points.push(Point {
                label: names[c].clone(),
                x: mx,
                y: (atlas + ref_bytes) as f64,
                series: k,
            });
        }
        md += "\n";
        rows.push(
            json!({"layout": name, "atlas_bytes": atlas, "ref_bytes": ref_bytes, "channels": ch}),
        );
    }
    println!("{md}");
    if let Some(dir) = out_dir {
        std::fs::create_dir_all(&dir).expect("out dir");
        let series: Vec<Series> = layouts
            .iter()
            .enumerate()
            .map(|(k, l)| {
                // A seventh colour: dark grey (the palette has six).
                let mut color = PALETTE[k % PALETTE.len()];
                if k >= PALETTE.len() {
                    (color.0, color.1, color.2) = (80, 80, 80);
                }
                Series {
                    name: l.0.to_string(),
                    color,
                }
            })
            .collect();
        let png = scatter_chart(
            "multi-channel payloads: bytes against per-channel error",
            "max abs error / channel range",
            "atlas + ref bytes",
            &series,
            &points,
        )
        .expect("chart");
        std::fs::write(dir.join("channel_payloads.png"), png).expect("png");
        std::fs::write(dir.join("channel_payloads.md"), &md).expect("md");
        let doc = json!({"input": input, "grids": names, "slots": slot_count, "bricks": bricks,
            "tuples": tuples.len(), "pairs": pairs.len(), "layouts": rows});
        std::fs::write(
            dir.join("channel_payloads.json"),
            serde_json::to_string_pretty(&doc).unwrap(),
        )
        .expect("json");
    }
}
