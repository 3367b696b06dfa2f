//! The hand-built test assets shared by the tracer's and the runtime's tests (the runtime's
//! `tests/common` includes this file by path): leaves and tiled regions placed by the test, so
//! every voxel value is known by construction (no cooker involved), bricks in any payload format
//! (mixed per brick if asked), the transforms the tests use, random content and a seeded
//! xorshift. The only place the tests spell out the asset's arrays: the format's internals
//! change under the tracers, the sampler API they read does not.
#![allow(dead_code)]

use std::collections::BTreeMap;

use vdbcook_asset::*;

/// What one 8³ leaf holds.
#[derive(Clone)]
pub enum Leaf {
    Tile(f32),
    /// 512 values, voxel (x, y, z) at 64x + 8y + z.
    Brick(Vec<f32>),
}

/// One frame: tiled 128³ regions (by region coordinate) and leaves (by leaf origin).
#[derive(Clone, Default)]
pub struct FrameSpec {
    pub regions: BTreeMap<[i64; 3], f32>,
    pub leaves: BTreeMap<[i64; 3], Leaf>,
}

/// Rotation by `deg` about Z after the scale `s`, then translation `t`.
pub fn rotated(deg: f64, s: [f64; 3], t: [f64; 3]) -> [[f64; 4]; 4] {
    let (sn, c) = deg.to_radians().sin_cos();
    [
        [c * s[0], -sn * s[1], 0.0, t[0]],
        [sn * s[0], c * s[1], 0.0, t[1]],
        [0.0, 0.0, s[2], t[2]],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// The bytes of one brick in `format` (values in voxel order) and its quantization range.
/// unorm8 goes through the asset's encoder; BC4/BC7 bricks are seeded byte noise (any 8/16 bytes
/// are a valid block; BC7 blocks are forced into mode 6) over the values' range: what they
/// decode to is the truth both tracers read.
fn brick_bytes(format: PayloadFormat, vals: &[f32], rng: &mut XorShift) -> (Vec<u8>, [f32; 2]) {
    let lo = vals.iter().cloned().fold(f32::INFINITY, f32::min);
    let hi = vals.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
    let mut out = Vec::new();
    match format {
        PayloadFormat::F32 | PayloadFormat::F16 => {
            payload::encode_float(format, vals, &mut out);
            return (out, [0.0, 0.0]);
        }
        PayloadFormat::Unorm8 => out.extend_from_slice(&payload::encode_unorm8(vals, lo, hi)),
        PayloadFormat::Bc4 => out.extend((0..256).map(|_| rng.next_u64() as u8)),
        PayloadFormat::Bc7 => {
            for _ in 0..8 {
                let mut block: Vec<u8> = (0..16).map(|_| rng.next_u64() as u8).collect();
                block[0] = (block[0] & 0x80) | 0x40;
                out.extend(block);
            }
        }
    }
    (out, [lo, hi])
}

/// Builds (and validates) an asset from frame specs, all bricks in one `format`.
pub fn build(
    root_dims: [u32; 3],
    index_to_world: [[f64; 4]; 4],
    background: f32,
    frames: &[FrameSpec],
    format: PayloadFormat,
) -> Asset {
    build_mixed(
        root_dims,
        index_to_world,
        background,
        frames,
        format,
        0x5eed_0000 + format.rank() as u64,
        |_| format,
    )
}

/// A brick of `build_mixed` before the pool is grouped: format, bytes, quantization range,
/// decoded range.
type PoolBrick = (PayloadFormat, Vec<u8>, [f32; 2], [f32; 2]);

/// Builds (and validates) an asset whose `i`-th brick (in the order the frame specs list them)
/// is stored in `format_of(i)`; the pool is then grouped by format as the asset requires.
pub fn build_mixed(
    root_dims: [u32; 3],
    index_to_world: [[f64; 4]; 4],
    background: f32,
    frames: &[FrameSpec],
    format: PayloadFormat,
    seed: u64,
    format_of: impl Fn(usize) -> PayloadFormat,
) -> Asset {
    let root_len = root_dims.iter().product::<u32>() as usize;
    let mut a = Asset {
        header: Header {
            tool: "test".into(),
            options: CookOptions {
                format,
                max_error: None,
                range: RangeMode::Brick,
                bc7_quality: "fast".into(),
                grid: None,
                replace_non_finite: None,
                allow_gaps: false,
            },
            grid_name: "density".into(),
            frames: (0..frames.len())
                .map(|i| FrameInfo {
                    number: Some(i as i64),
                    source: format!("f{i}.vdb"),
                    active_voxels: 0,
                })
                .collect(),
            index_offset: [0; 3],
            root_dims,
            index_to_world,
            source_map: "AffineMap".into(),
            voxel_size: [1.0; 3],
            background,
            brick_counts: [0; 5],
            sections: vec![],
            content_hash: 0,
        },
        roots: vec![],
        frame_ranges: vec![],
        l2_masks: vec![],
        l2_base: vec![],
        l2_prefix: vec![],
        l2_ranges: vec![],
        l3_refs: vec![],
        tiles: vec![],
        brick_ranges: vec![],
        brick_quant: vec![],
        payloads: Default::default(),
    };
    let mut noise = XorShift(seed);
    // Per brick in spec order.
    let mut pool: Vec<PoolBrick> = Vec::new();
    let d = root_dims.map(|x| x as i64);
    for f in frames {
        let mut roots = vec![EMPTY; root_len];
        let idx = |r: [i64; 3]| (r[0] + d[0] * (r[1] + d[1] * r[2])) as usize;
        let (mut flo, mut fhi) = (f32::INFINITY, f32::NEG_INFINITY);
        for (&r, &v) in &f.regions {
            roots[idx(r)] = TILE_BIT | a.tiles.len() as u32;
            a.tiles.push(v);
            flo = flo.min(v);
            fhi = fhi.max(v);
        }
        let mut by_region: BTreeMap<[i64; 3], BTreeMap<usize, &Leaf>> = BTreeMap::new();
        for (o, leaf) in &f.leaves {
            let r = o.map(|c| c.div_euclid(128));
            let l = o.map(|c| (c.rem_euclid(128) / 8) as usize);
            by_region
                .entry(r)
                .or_default()
                .insert(l[0] + 16 * (l[1] + 16 * l[2]), leaf);
        }
        for (r, slots) in by_region {
            let n = a.l2_base.len();
            roots[idx(r)] = n as u32;
            let mut mask = vec![0u64; L2_WORDS];
            a.l2_base.push(a.l3_refs.len() as u32);
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            if slots.len() < L2_SLOTS {
                lo = background;
                hi = background;
            }
            for (&s, leaf) in &slots {
                mask[s / 64] |= 1 << (s % 64);
                match leaf {
                    Leaf::Tile(v) => {
                        a.l3_refs.push(TILE_BIT | a.tiles.len() as u32);
                        a.tiles.push(*v);
                        lo = lo.min(*v);
                        hi = hi.max(*v);
                    }
                    Leaf::Brick(vals) => {
                        assert_eq!(vals.len(), BRICK_VOXELS);
                        // The spec-order index for now; remapped once the pool is grouped.
                        a.l3_refs.push(pool.len() as u32);
                        let format = format_of(pool.len());
                        let (bytes, quant) = brick_bytes(format, vals, &mut noise);
                        let mut dec = [0.0f32; BRICK_VOXELS];
                        payload::decode_brick(format, &bytes, quant, &mut dec);
                        let bl = dec.iter().cloned().fold(f32::INFINITY, f32::min);
                        let bh = dec.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
                        pool.push((format, bytes, quant, [bl, bh]));
                        lo = lo.min(bl);
                        hi = hi.max(bh);
                    }
                }
            }
            let mut count = 0u16;
            for word in &mask {
                a.l2_prefix.push(count);
                count += word.count_ones() as u16;
            }
            a.l2_masks.extend(mask);
            a.l2_ranges.push([lo, hi]);
            flo = flo.min(lo);
            fhi = fhi.max(hi);
        }
        if roots.contains(&EMPTY) || flo > fhi {
            flo = flo.min(background);
            fhi = fhi.max(background);
        }
        a.roots.extend(roots);
        a.frame_ranges.push([flo, fhi]);
    }
    // Group the pool by format (PayloadFormat::ORDER) and remap the brick refs.
    let mut new_index = vec![0u32; pool.len()];
    for f in PayloadFormat::ORDER {
        for (i, (bf, bytes, quant, range)) in pool.iter().enumerate() {
            if *bf == f {
                new_index[i] = a.brick_ranges.len() as u32;
                a.brick_ranges.push(*range);
                a.brick_quant.push(*quant);
                a.payloads[f.rank()].extend_from_slice(bytes);
                a.header.brick_counts[f.rank()] += 1;
            }
        }
    }
    for r in a.l3_refs.iter_mut() {
        if *r & TILE_BIT == 0 {
            *r = new_index[*r as usize];
        }
    }
    a.validate().expect("hand-built asset is valid");
    a
}

/// Uniform scale `s`, then translation `t`.
pub fn uniform_scale(s: f64, t: [f64; 3]) -> [[f64; 4]; 4] {
    [
        [s, 0.0, 0.0, t[0]],
        [0.0, s, 0.0, t[1]],
        [0.0, 0.0, s, t[2]],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// Xorshift64*, seeded.
pub struct XorShift(pub u64);

impl XorShift {
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    pub fn f(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.f()
    }
    /// A uniformly distributed unit vector.
    pub fn dir(&mut self) -> [f64; 3] {
        loop {
            let v = [0; 3].map(|_| self.range(-1.0, 1.0));
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if n > 0.1 && n <= 1.0 {
                return v.map(|c| c / n);
            }
        }
    }
}

/// Random content over a 2×2×1 root: 60 leaves in region (0,0,0), 20 in (1,1,0) — bricks of
/// random values (a third zero, a few negative) and constant tiles — and region (1,0,0) tiled.
pub fn random_frame(rng: &mut XorShift) -> FrameSpec {
    let mut f = FrameSpec::default();
    f.regions.insert([1, 0, 0], 0.1);
    for (region, n) in [([0i64, 0, 0], 60), ([1, 1, 0], 20)] {
        for _ in 0..n {
            let o = [0, 1, 2].map(|a| region[a] * 128 + 8 * (rng.next_u64() % 16) as i64);
            let leaf = if rng.f() < 0.75 {
                Leaf::Brick(
                    (0..BRICK_VOXELS)
                        .map(|_| match rng.f() {
                            x if x < 0.33 => 0.0,
                            x if x < 0.36 => -0.5,
                            _ => rng.range(0.05, 2.0) as f32,
                        })
                        .collect(),
                )
            } else {
                Leaf::Tile(rng.range(0.0, 1.0) as f32)
            };
            f.leaves.insert(o, leaf);
        }
    }
    f
}
