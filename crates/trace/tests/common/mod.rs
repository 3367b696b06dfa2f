//! Hand-built assets for the tracer tests: leaves and tiled regions placed by the test, so every
//! voxel value is known by construction (no cooker involved), plus a seeded xorshift.
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

/// One frame: tiled 128³ regions (by region coordinate) and leaves (by leaf origin, asset index).
#[derive(Clone, Default)]
pub struct FrameSpec {
    pub regions: BTreeMap<[i64; 3], f32>,
    pub leaves: BTreeMap<[i64; 3], Leaf>,
}

pub fn uniform_scale(s: f64, t: [f64; 3]) -> [[f64; 4]; 4] {
    [
        [s, 0.0, 0.0, t[0]],
        [0.0, s, 0.0, t[1]],
        [0.0, 0.0, s, t[2]],
        [0.0, 0.0, 0.0, 1.0],
    ]
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

/// Builds (and validates) an asset from frame specs, all bricks in one float `format`. The only
/// place the tests spell out the asset's arrays: the format's internals change under the
/// tracer, the sampler API it reads does not.
pub fn build(
    root_dims: [u32; 3],
    index_to_world: [[f64; 4]; 4],
    background: f32,
    frames: &[FrameSpec],
    format: PayloadFormat,
) -> Asset {
    let root_len = root_dims.iter().product::<u32>() as usize;
    let mut a = Asset {
        header: Header {
            tool: "trace-test".into(),
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
    assert!(!format.is_quantized(), "the tests build float bricks");
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
        // Leaves grouped by region, in slot order.
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
                        a.l3_refs.push(a.brick_ranges.len() as u32);
                        let bl = vals.iter().cloned().fold(f32::INFINITY, f32::min);
                        let bh = vals.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
                        a.brick_ranges.push([bl, bh]);
                        payload::encode_float(format, vals, &mut a.payloads[format.rank()]);
                        a.brick_quant.push([0.0, 0.0]);
                        a.header.brick_counts[format.rank()] += 1;
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
    a.validate().expect("hand-built asset is valid");
    a
}

/// Leaves covering the half-open index box `[lo, hi)` with density `v` (0 outside the box):
/// leaves entirely inside alternate between tile and constant brick (by leaf parity), partial
/// leaves are bricks.
pub fn box_leaves(lo: [i64; 3], hi: [i64; 3], v: f32, leaves: &mut BTreeMap<[i64; 3], Leaf>) {
    let l0 = lo.map(|c| c.div_euclid(8));
    let l1 = hi.map(|c| (c - 1).div_euclid(8));
    for lz in l0[2]..=l1[2] {
        for ly in l0[1]..=l1[1] {
            for lx in l0[0]..=l1[0] {
                let o = [lx * 8, ly * 8, lz * 8];
                let inside = (0..3).all(|a| o[a] >= lo[a] && o[a] + 8 <= hi[a]);
                let leaf = if inside && (lx + ly + lz) % 2 == 0 {
                    Leaf::Tile(v)
                } else {
                    let mut vals = vec![0.0f32; BRICK_VOXELS];
                    for (i, val) in vals.iter_mut().enumerate() {
                        let p = [
                            o[0] + (i / 64) as i64,
                            o[1] + (i / 8 % 8) as i64,
                            o[2] + (i % 8) as i64,
                        ];
                        if (0..3).all(|a| p[a] >= lo[a] && p[a] < hi[a]) {
                            *val = v;
                        }
                    }
                    Leaf::Brick(vals)
                };
                leaves.insert(o, leaf);
            }
        }
    }
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

/// `[lo, hi)` ∩ ray `o + t d` for `t ≥ 0`: the length of the parameter interval (0 if empty);
/// a zero direction component must have `lo ≤ o < hi`.
pub fn slab_length(o: [f64; 3], d: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> f64 {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] >= hi[a] {
                return 0.0;
            }
        } else {
            let u = (lo[a] - o[a]) / d[a];
            let v = (hi[a] - o[a]) / d[a];
            t0 = t0.max(u.min(v));
            t1 = t1.min(u.max(v));
        }
    }
    (t1 - t0).max(0.0)
}

/// `[lo, hi)` ∩ ray for `t ≥ 0` as a parameter interval, if not empty.
pub fn slab_interval(o: [f64; 3], d: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] >= hi[a] {
                return None;
            }
        } else {
            let u = (lo[a] - o[a]) / d[a];
            let v = (hi[a] - o[a]) / d[a];
            t0 = t0.max(u.min(v));
            t1 = t1.min(u.max(v));
        }
    }
    (t1 > t0).then_some((t0, t1))
}

/// index → world = R_z(deg) · diag(sc) · index + t, with its closed-form inverse.
#[derive(Clone, Copy)]
pub struct RotScale {
    pub deg: f64,
    pub sc: [f64; 3],
    pub t: [f64; 3],
}

impl RotScale {
    pub fn matrix(self) -> [[f64; 4]; 4] {
        rotated(self.deg, self.sc, self.t)
    }
    pub fn to_world(self, p: [f64; 3]) -> [f64; 3] {
        let (sn, c) = self.deg.to_radians().sin_cos();
        let q = [p[0] * self.sc[0], p[1] * self.sc[1], p[2] * self.sc[2]];
        [
            c * q[0] - sn * q[1] + self.t[0],
            sn * q[0] + c * q[1] + self.t[1],
            q[2] + self.t[2],
        ]
    }
    pub fn dir_to_index(self, d: [f64; 3]) -> [f64; 3] {
        let (sn, c) = self.deg.to_radians().sin_cos();
        [
            (c * d[0] + sn * d[1]) / self.sc[0],
            (-sn * d[0] + c * d[1]) / self.sc[1],
            d[2] / self.sc[2],
        ]
    }
    pub fn to_index(self, p: [f64; 3]) -> [f64; 3] {
        self.dir_to_index([p[0] - self.t[0], p[1] - self.t[1], p[2] - self.t[2]])
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
