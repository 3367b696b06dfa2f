//! Hand-built test assets shared by the tracer's and the runtime's tests: the test-specific
//! layer over [`vdbcook_asset::builder`] — the transforms the tests use, random content, and
//! BC4/BC7 bricks as seeded byte noise (the asset crate decodes BC but does not encode it).
//! Every voxel value is known by construction, no cooker involved.

use vdbcook_asset::builder::{AssetBuilder, EncodedBrick};
use vdbcook_asset::{Asset, PayloadFormat, BRICK_VOXELS};

use crate::XorShift;

/// One frame: tiled 128³ regions and leaves (see [`vdbcook_asset::builder::Frame`]).
pub use vdbcook_asset::builder::Frame as FrameSpec;
/// What one 8³ leaf holds (see [`vdbcook_asset::builder::Leaf`]).
pub use vdbcook_asset::builder::Leaf;

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

/// Uniform scale `s`, then translation `t`.
pub fn uniform_scale(s: f64, t: [f64; 3]) -> [[f64; 4]; 4] {
    [
        [s, 0.0, 0.0, t[0]],
        [0.0, s, 0.0, t[1]],
        [0.0, 0.0, s, t[2]],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// One brick in `format`: f32/f16/unorm8 through the asset's encoder; BC4/BC7 as seeded byte
/// noise (any 8/16 bytes are a valid block; BC7 blocks are forced into mode 6) over the values'
/// range: what they decode to is the truth both tracers read.
pub fn test_brick(format: PayloadFormat, vals: &[f32], rng: &mut XorShift) -> EncodedBrick {
    if let Some(b) = EncodedBrick::encode(format, vals) {
        return b;
    }
    let lo = vals.iter().cloned().fold(f32::INFINITY, f32::min);
    let hi = vals.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
    let mut bytes = Vec::new();
    match format {
        PayloadFormat::Bc4 => bytes.extend((0..256).map(|_| rng.next_u64() as u8)),
        _ => {
            for _ in 0..8 {
                let mut block: Vec<u8> = (0..16).map(|_| rng.next_u64() as u8).collect();
                block[0] = (block[0] & 0x80) | 0x40;
                bytes.extend(block);
            }
        }
    }
    EncodedBrick {
        format,
        bytes,
        quant: [lo, hi],
    }
}

/// Builds (and validates) an asset from frame specs, all bricks in one `format` (BC noise
/// seeded by the format).
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

/// Builds (and validates) an asset whose `i`-th brick (in the builder's order, see
/// [`AssetBuilder::build_with`]) is stored in `format_of(i)`; `format` is the header's, `seed`
/// seeds the BC noise.
pub fn build_mixed(
    root_dims: [u32; 3],
    index_to_world: [[f64; 4]; 4],
    background: f32,
    frames: &[FrameSpec],
    format: PayloadFormat,
    seed: u64,
    format_of: impl Fn(usize) -> PayloadFormat,
) -> Asset {
    let mut noise = XorShift(seed);
    AssetBuilder::new(root_dims)
        .index_to_world(index_to_world)
        .background(background)
        .format(format)
        .frames(frames.iter().cloned())
        .build_with(|i, vals| test_brick(format_of(i), vals, &mut noise))
        .expect("hand-built asset is valid")
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

/// A smooth blob (a cloud-like ball of radius `r` around `c`, density up to `peak`, 0 outside)
/// as bricks, with fully inside leaves of near-constant density turned into tiles, plus one
/// tiled 128³ region at `tiled_region` (if any) — what a cooked smoke frame looks like.
pub fn blob_frame(c: [f64; 3], r: f64, peak: f32, tiled_region: Option<[i64; 3]>) -> FrameSpec {
    let mut f = FrameSpec::default();
    if let Some(t) = tiled_region {
        f.regions.insert(t, 0.05);
    }
    let lo = c.map(|x| ((x - r).floor() as i64).div_euclid(8));
    let hi = c.map(|x| ((x + r).ceil() as i64).div_euclid(8));
    for lz in lo[2]..=hi[2] {
        for ly in lo[1]..=hi[1] {
            for lx in lo[0]..=hi[0] {
                let o = [lx * 8, ly * 8, lz * 8];
                let vals: Vec<f32> = (0..BRICK_VOXELS)
                    .map(|i| {
                        let p = [
                            (o[0] + (i / 64) as i64) as f64 + 0.5,
                            (o[1] + (i / 8 % 8) as i64) as f64 + 0.5,
                            (o[2] + (i % 8) as i64) as f64 + 0.5,
                        ];
                        let d2: f64 = (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f64>() / (r * r);
                        let ripple = 0.8 + 0.2 * (p[0] * 0.7).sin() * (p[1] * 0.5).cos();
                        if d2 < 1.0 {
                            (peak as f64 * (1.0 - d2) * ripple) as f32
                        } else {
                            0.0
                        }
                    })
                    .collect();
                if vals.iter().all(|&v| v == 0.0) {
                    continue;
                }
                let leaf = if (lx + ly + lz) % 7 == 0 {
                    Leaf::Tile(vals.iter().sum::<f32>() / BRICK_VOXELS as f32)
                } else {
                    Leaf::Brick(vals)
                };
                f.leaves.insert(o, leaf);
            }
        }
    }
    f
}
