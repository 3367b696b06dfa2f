//! Building an [`Asset`] from leaves placed by hand, without the cooker: tests (and tools) say
//! what each 8³ leaf and each 128³ region of each frame holds, the builder lays out the arrays
//! (roots, L2 nodes, tiles, the brick pool grouped by format, every range) and validates the
//! result. It exists so that tests stop spelling out the format's internals in `Asset { .. }`
//! literals: those change under the tracers, what a voxel holds does not.
//!
//! ```
//! use vdbcook_asset::builder::{AssetBuilder, Frame, Leaf};
//! use vdbcook_asset::PayloadFormat;
//!
//! let mut f = Frame::default();
//! f.regions.insert([1, 0, 0], 0.25); // a tiled 128³ region
//! f.leaves.insert([0, 8, 16], Leaf::Tile(1.0)); // a constant leaf
//! f.leaves.insert([8, 0, 0], Leaf::Brick(vec![0.5; 512])); // a brick, voxel (x,y,z) at 64x+8y+z
//! let asset = AssetBuilder::new([2, 1, 1])
//!     .format(PayloadFormat::F16)
//!     .frame(f)
//!     .build()
//!     .unwrap();
//! assert_eq!(asset.value(0, [200, 3, 3]), 0.25);
//! assert_eq!(asset.value(0, [9, 1, 1]), 0.5);
//! assert_eq!(asset.value(0, [100, 100, 100]), 0.0);
//! ```

use std::collections::BTreeMap;

use crate::{
    payload, Asset, AssetError, CookOptions, FrameInfo, Header, PayloadFormat, RangeMode,
    BRICK_VOXELS, EMPTY, L2_SLOTS, L2_WORDS, TILE_BIT,
};

/// What one 8³ leaf holds.
#[derive(Debug, Clone, PartialEq)]
pub enum Leaf {
    /// Every voxel holds this value.
    Tile(f32),
    /// 512 values, voxel (x, y, z) at 64x + 8y + z ([`payload::vox_index`]); stored in the
    /// builder's format (or as [`AssetBuilder::build_with`]'s encoder says).
    Brick(Vec<f32>),
    /// A brick already encoded (e.g. BC4/BC7 blocks, which this crate decodes but does not
    /// encode): stored as given.
    Encoded(EncodedBrick),
}

/// One brick's payload bytes in a format, with the quantization range they decode over
/// (`[0, 0]` for float formats).
#[derive(Debug, Clone, PartialEq)]
pub struct EncodedBrick {
    pub format: PayloadFormat,
    /// `format.bytes_per_brick()` bytes.
    pub bytes: Vec<u8>,
    pub quant: [f32; 2],
}

impl EncodedBrick {
    /// `values` (512, voxel order) in a format this crate encodes: f32 and f16 exactly (as the
    /// format rounds), unorm8 over the values' own `[min, max]`. `None` for BC4/BC7.
    pub fn encode(format: PayloadFormat, values: &[f32]) -> Option<EncodedBrick> {
        let mut bytes = Vec::new();
        let quant = match format {
            PayloadFormat::F32 | PayloadFormat::F16 => {
                payload::encode_float(format, values, &mut bytes);
                [0.0, 0.0]
            }
            PayloadFormat::Bc4 | PayloadFormat::Bc7 => return None,
            f => {
                let lo = values.iter().cloned().fold(f32::INFINITY, f32::min);
                let hi = values.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
                match f.packed_bits() {
                    Some(bits) => bytes.extend(payload::encode_packed(values, bits, lo, hi)),
                    None => bytes.extend_from_slice(&payload::encode_unorm8(values, lo, hi)),
                }
                [lo, hi]
            }
        };
        Some(EncodedBrick {
            format,
            bytes,
            quant,
        })
    }
}

/// One frame: tiled 128³ regions (by region coordinate, index / 128) and leaves (by leaf
/// origin, a multiple of 8 per axis). A region listed in both is an error.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Frame {
    pub regions: BTreeMap<[i64; 3], f32>,
    pub leaves: BTreeMap<[i64; 3], Leaf>,
}

/// Builds a validated [`Asset`] frame by frame. Defaults: identity index-to-world transform,
/// background 0, f32 bricks, header fields of a plausible cook (`tool` "test", grid
/// "density", frame `i` numbered `i` from `f{i}.vdb`, no index offset).
#[derive(Debug, Clone)]
pub struct AssetBuilder {
    root_dims: [u32; 3],
    index_to_world: [[f64; 4]; 4],
    background: f32,
    format: PayloadFormat,
    tool: String,
    frames: Vec<Frame>,
}

impl AssetBuilder {
    /// An asset of `root_dims` 128³ regions per axis, covering index `[0, 128·root_dims)`.
    pub fn new(root_dims: [u32; 3]) -> AssetBuilder {
        AssetBuilder {
            root_dims,
            index_to_world: [
                [1.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, 1.0, 0.0],
                [0.0, 0.0, 0.0, 1.0],
            ],
            background: 0.0,
            format: PayloadFormat::F32,
            tool: "test".into(),
            frames: Vec::new(),
        }
    }

    /// Index → world, row-major, column vectors (as [`Header::index_to_world`]).
    pub fn index_to_world(mut self, m: [[f64; 4]; 4]) -> AssetBuilder {
        self.index_to_world = m;
        self
    }

    /// The value of every voxel no leaf or region holds.
    pub fn background(mut self, v: f32) -> AssetBuilder {
        self.background = v;
        self
    }

    /// The format [`Leaf::Brick`] values are stored in by [`build`](Self::build), and the
    /// header's `options.format`.
    pub fn format(mut self, f: PayloadFormat) -> AssetBuilder {
        self.format = f;
        self
    }

    /// The header's `tool`.
    pub fn tool(mut self, tool: impl Into<String>) -> AssetBuilder {
        self.tool = tool.into();
        self
    }

    /// Appends a frame.
    pub fn frame(mut self, f: Frame) -> AssetBuilder {
        self.frames.push(f);
        self
    }

    /// Appends frames.
    pub fn frames(mut self, f: impl IntoIterator<Item = Frame>) -> AssetBuilder {
        self.frames.extend(f);
        self
    }

    /// Builds and validates the asset, [`Leaf::Brick`]s encoded in the builder's format
    /// ([`EncodedBrick::encode`]; an error for BC4/BC7, which need [`Leaf::Encoded`] or
    /// [`build_with`](Self::build_with)).
    pub fn build(self) -> Result<Asset, AssetError> {
        let format = self.format;
        let mut unencodable = false;
        let a = self.build_with(|_, vals| {
            EncodedBrick::encode(format, vals).unwrap_or_else(|| {
                unencodable = true;
                EncodedBrick::encode(PayloadFormat::F32, vals).expect("f32 encodes")
            })
        });
        if unencodable {
            return Err(AssetError(format!(
                "the builder cannot encode {format:?} bricks from values: give them as Leaf::Encoded \
                 or use build_with"
            )));
        }
        a
    }

    /// Builds and validates the asset, each [`Leaf::Brick`] stored as `encode(i, values)` says,
    /// `i` counting the bricks (encoded ones included) in build order: frames in order, then
    /// 128³ regions in the order of their coordinates (`[x, y, z]` compared lexicographically),
    /// then slots within a region (x fastest, then y, then z). The brick pool is then grouped by
    /// format as the asset requires ([`PayloadFormat::ORDER`]); every range is the decoded one.
    pub fn build_with(
        self,
        mut encode: impl FnMut(usize, &[f32]) -> EncodedBrick,
    ) -> Result<Asset, AssetError> {
        let root_dims = self.root_dims;
        let background = self.background;
        let root_len = root_dims.iter().map(|&d| d as usize).product::<usize>();
        let mut a = Asset {
            header: Header {
                tool: self.tool,
                options: CookOptions {
                    format: self.format,
                    max_error: None,
                    range: RangeMode::Brick,
                    bc7_quality: "fast".into(),
                    grid: None,
                    replace_non_finite: None,
                    allow_gaps: false,
                },
                grid_name: "density".into(),
                frames: (0..self.frames.len())
                    .map(|i| FrameInfo {
                        number: Some(i as i64),
                        source: format!("f{i}.vdb"),
                        active_voxels: 0,
                    })
                    .collect(),
                index_offset: [0; 3],
                root_dims,
                index_to_world: self.index_to_world,
                source_map: "AffineMap".into(),
                voxel_size: [1.0; 3],
                background,
                brick_counts: [0; crate::FORMATS],
                sections: vec![],
                content_hash: 0,
                channels: Vec::new(),
                lod_levels: 0,
                lod_first: 1,
                source: Default::default(),
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
        // Per brick in build order: the encoded brick and its decoded range.
        let mut pool: Vec<(EncodedBrick, [f32; 2])> = Vec::new();
        let d = root_dims.map(|x| x as i64);
        let region_index = |r: [i64; 3]| -> Result<usize, AssetError> {
            if (0..3).any(|a| r[a] < 0 || r[a] >= d[a]) {
                return Err(AssetError(format!(
                    "region {r:?} is outside the root {root_dims:?}"
                )));
            }
            Ok((r[0] + d[0] * (r[1] + d[1] * r[2])) as usize)
        };
        for (fi, f) in self.frames.iter().enumerate() {
            let mut roots = vec![EMPTY; root_len];
            let (mut flo, mut fhi) = (f32::INFINITY, f32::NEG_INFINITY);
            for (&r, &v) in &f.regions {
                roots[region_index(r)?] = TILE_BIT | a.tiles.len() as u32;
                a.tiles.push(v);
                flo = flo.min(v);
                fhi = fhi.max(v);
            }
            let mut by_region: BTreeMap<[i64; 3], BTreeMap<usize, &Leaf>> = BTreeMap::new();
            for (o, leaf) in &f.leaves {
                if o.iter().any(|c| c.rem_euclid(8) != 0) {
                    return Err(AssetError(format!(
                        "frame {fi}: leaf origin {o:?} is not a multiple of 8"
                    )));
                }
                let r = o.map(|c| c.div_euclid(128));
                let l = o.map(|c| (c.rem_euclid(128) / 8) as usize);
                by_region
                    .entry(r)
                    .or_default()
                    .insert(l[0] + 16 * (l[1] + 16 * l[2]), leaf);
            }
            for (r, slots) in by_region {
                let ri = region_index(r)?;
                if roots[ri] != EMPTY {
                    return Err(AssetError(format!(
                        "frame {fi}: region {r:?} is both tiled and holds leaves"
                    )));
                }
                roots[ri] = a.l2_base.len() as u32;
                let mut mask = vec![0u64; L2_WORDS];
                a.l2_base.push(a.l3_refs.len() as u32);
                let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                if slots.len() < L2_SLOTS {
                    lo = background;
                    hi = background;
                }
                for (&s, leaf) in &slots {
                    mask[s / 64] |= 1 << (s % 64);
                    let brick = match leaf {
                        Leaf::Tile(v) => {
                            a.l3_refs.push(TILE_BIT | a.tiles.len() as u32);
                            a.tiles.push(*v);
                            lo = lo.min(*v);
                            hi = hi.max(*v);
                            continue;
                        }
                        Leaf::Brick(vals) => {
                            if vals.len() != BRICK_VOXELS {
                                return Err(AssetError(format!(
                                    "frame {fi}: a brick in region {r:?} has {} values, not {BRICK_VOXELS}",
                                    vals.len()
                                )));
                            }
                            encode(pool.len(), vals)
                        }
                        Leaf::Encoded(b) => b.clone(),
                    };
                    if brick.bytes.len() != brick.format.bytes_per_brick() {
                        return Err(AssetError(format!(
                            "frame {fi}: a {:?} brick in region {r:?} has {} bytes, not {}",
                            brick.format,
                            brick.bytes.len(),
                            brick.format.bytes_per_brick()
                        )));
                    }
                    // The build-order index for now; remapped once the pool is grouped.
                    a.l3_refs.push(pool.len() as u32);
                    let mut dec = [0.0f32; BRICK_VOXELS];
                    payload::decode_brick(brick.format, &brick.bytes, brick.quant, &mut dec);
                    let bl = dec.iter().cloned().fold(f32::INFINITY, f32::min);
                    let bh = dec.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
                    pool.push((brick, [bl, bh]));
                    lo = lo.min(bl);
                    hi = hi.max(bh);
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
        // Group the pool by format and remap the brick refs.
        let mut new_index = vec![0u32; pool.len()];
        for f in PayloadFormat::ORDER {
            for (i, (b, range)) in pool.iter().enumerate() {
                if b.format == f {
                    new_index[i] = a.brick_ranges.len() as u32;
                    a.brick_ranges.push(*range);
                    a.brick_quant.push(b.quant);
                    a.payloads[f.rank()].extend_from_slice(&b.bytes);
                    a.header.brick_counts[f.rank()] += 1;
                }
            }
        }
        for r in a.l3_refs.iter_mut() {
            if *r & TILE_BIT == 0 {
                *r = new_index[*r as usize];
            }
        }
        a.validate()?;
        Ok(a)
    }
}
