//! Parsing of a float (or double) tree: root tiles and children, the two internal-node levels with
//! their tile values, leaf topology, then leaf buffers — the byte stream OpenVDB's
//! `Tree::readTopology` / `Tree::readBuffers` consume, including per-node mask compression
//! (`io::readCompressedValues` and its seven metadata codes), half floats, zlib and blosc.

use std::collections::HashSet;

use crate::cursor::Cursor;
use crate::error::{PResult, ParseError};
use crate::grid::{FloatGrid, Leaf, Tile, TileLevel, LEAF_VOXELS};
use crate::transform::Transform;

/// Per-grid compression flags (OpenVDB `io::COMPRESS_*`).
pub const COMPRESS_ZIP: u32 = 0x1;
pub const COMPRESS_ACTIVE_MASK: u32 = 0x2;
pub const COMPRESS_BLOSC: u32 = 0x4;

/// File format version that introduced per-node mask compression metadata.
pub const V_NODE_MASK_COMPRESSION: u32 = 222;

/// Largest number of leaves one grid may have (2 G voxels, 8 GiB of f32 values).
pub const MAX_LEAVES: usize = 4 << 20;

/// How the tree's values are stored.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TreeFormat {
    pub version: u32,
    pub compression: u32,
    /// Values stored as 16-bit halves (`_HalfFloat`).
    pub half: bool,
    /// Value type is double (8 bytes; converted to f32).
    pub double: bool,
}

impl TreeFormat {
    /// Bytes of one value in node buffers.
    fn stored_width(&self) -> usize {
        if self.half {
            2
        } else if self.double {
            8
        } else {
            4
        }
    }
    /// Bytes of one full-precision value (root background, root tiles, inactive values).
    fn full_width(&self) -> usize {
        if self.double {
            8
        } else {
            4
        }
    }
}

/// Counters for which per-node compression codes were seen (tests use this to prove coverage).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct CodeStats {
    pub metadata_codes: [u64; 7],
}

pub(crate) struct TreeReader<'a> {
    cur: Cursor<'a>,
    fmt: TreeFormat,
    background: f32,
    scratch: Vec<u8>,
    /// Active values of a mask-compressed node before they are scattered (reused).
    packed: Vec<f32>,
    /// Selection mask between two inactive values (reused).
    selection: Vec<u64>,
    zlib: flate2::Decompress,
    pub codes: CodeStats,
}

const L2_VALUES: usize = 32768; // InternalNode<5>: 32³ slots of 128³
const L1_VALUES: usize = 4096; // InternalNode<4>: 16³ slots of 8³

impl<'a> TreeReader<'a> {
    pub fn new(cur: Cursor<'a>, fmt: TreeFormat) -> Self {
        TreeReader {
            cur,
            fmt,
            background: 0.0,
            scratch: Vec::new(),
            packed: Vec::new(),
            selection: vec![0; L2_VALUES / 64],
            zlib: flate2::Decompress::new(true),
            codes: CodeStats::default(),
        }
    }

    pub fn end(&self) -> usize {
        self.cur.pos()
    }

    fn full_value(&mut self, what: &str) -> PResult<f32> {
        if self.fmt.double {
            Ok(self.cur.f64(what)? as f32)
        } else {
            self.cur.f32(what)
        }
    }

    /// Reads topology and buffers; returns the grid with the given transform.
    pub fn read(&mut self, transform: Transform) -> PResult<FloatGrid> {
        let at = self.cur.offset();
        let buffer_count = self.cur.i32("tree buffer count")?;
        if buffer_count < 1 {
            return Err(ParseError::corrupt(
                at,
                format!("tree buffer count {buffer_count} (expected 1)"),
            ));
        }
        self.background = self.full_value("background")?;
        let background = self.background;
        let at = self.cur.offset();
        let num_tiles = self.cur.u32("root tile count")? as u64;
        let num_children = self.cur.u32("root child count")? as u64;
        let fw = self.fmt.full_width() as u64;
        self.cur.check_count(num_tiles, 12 + fw + 1, "root tiles")?;
        self.cur
            .check_count(num_children, 12 + 2 * 4096, "root children")?;
        let mut grid = FloatGrid {
            background,
            leaves: Vec::new(),
            values: Vec::new(),
            tiles: Vec::new(),
            transform,
            converted_from_double: self.fmt.double,
        };
        let mut keys = HashSet::new();
        for _ in 0..num_tiles {
            let o_at = self.cur.offset();
            let origin = self.cur.coord("root tile origin")?;
            let value = self.full_value("root tile value")?;
            let active = self.cur.u8("root tile active flag")? != 0;
            check_root_key(origin, o_at, &mut keys)?;
            push_tile(&mut grid, origin, TileLevel::L4096, value, active);
        }
        let _ = at;
        let mut node_vals = vec![0f32; L2_VALUES];
        let mut child_mask = vec![0u64; L2_VALUES / 64];
        let mut value_mask = vec![0u64; L2_VALUES / 64];
        for _ in 0..num_children {
            let o_at = self.cur.offset();
            let origin = self.cur.coord("root child origin")?;
            check_root_key(origin, o_at, &mut keys)?;
            self.read_internal(
                &mut grid,
                origin,
                InternalLevel::Upper,
                &mut node_vals,
                &mut child_mask,
                &mut value_mask,
            )?;
        }
        // Buffers: one per leaf, in topology order.
        let n = grid.leaves.len();
        self.cur.check_count(n as u64, 64, "leaf buffers")?;
        if n > MAX_LEAVES {
            return Err(ParseError::unsupported(
                self.cur.offset(),
                format!("grid has {n} leaves, more than the limit of {MAX_LEAVES}"),
            ));
        }
        grid.values = vec![0f32; n * LEAF_VOXELS];
        for (li, leaf) in grid.leaves.iter_mut().enumerate() {
            let m_at = self.cur.offset();
            self.cur.mask_into(&mut leaf.mask, "leaf value mask")?;
            let mut num_buffers = 1i8;
            if self.fmt.version < V_NODE_MASK_COMPRESSION {
                let origin = self.cur.coord("leaf origin")?;
                if origin != leaf.origin {
                    return Err(ParseError::corrupt(
                        m_at,
                        format!(
                            "leaf buffer origin {origin:?} does not match topology {:?}",
                            leaf.origin
                        ),
                    ));
                }
                num_buffers = self.cur.u8("leaf buffer count")? as i8;
            }
            let mask = leaf.mask;
            let dst = &mut grid.values[li * LEAF_VOXELS..(li + 1) * LEAF_VOXELS];
            self.read_compressed_values(dst, &mask)?;
            // Auxiliary buffers of old files: read and discard (never mask-compressed).
            for _ in 1..num_buffers.max(1) {
                let mut tmp = [0f32; LEAF_VOXELS];
                let zip = self.fmt.compression & COMPRESS_ZIP;
                self.read_data(&mut tmp, zip)?;
            }
        }
        Ok(grid)
    }

    fn read_internal(
        &mut self,
        grid: &mut FloatGrid,
        origin: [i32; 3],
        level: InternalLevel,
        vals: &mut [f32],
        child_mask: &mut [u64],
        value_mask: &mut [u64],
    ) -> PResult<()> {
        let (nvals, log2, child_dim, tile_level) = match level {
            InternalLevel::Upper => (L2_VALUES, 5u32, 128i32, TileLevel::L128),
            InternalLevel::Lower => (L1_VALUES, 4u32, 8i32, TileLevel::L8),
        };
        let words = nvals / 64;
        let (cm, vm) = (&mut child_mask[..words], &mut value_mask[..words]);
        self.cur.mask_into(cm, "internal node child mask")?;
        self.cur.mask_into(vm, "internal node value mask")?;
        let vals = &mut vals[..nvals];
        if self.fmt.version < V_NODE_MASK_COMPRESSION {
            // Old files store only the non-child slots, in order, with no per-node metadata.
            let n_off = nvals - cm.iter().map(|w| w.count_ones() as usize).sum::<usize>();
            let mut packed = vec![0f32; n_off];
            let flags = self.fmt.compression;
            self.read_data(&mut packed, flags)?;
            let mut it = packed.into_iter();
            for (i, v) in vals.iter_mut().enumerate() {
                if !bit(cm, i) {
                    *v = it.next().unwrap_or(self.background);
                }
            }
        } else {
            self.read_compressed_values(vals, vm)?;
        }
        let bg = self.background;
        let mask_at = |i: usize| -> [i32; 3] {
            let n = 1usize << log2;
            let x = (i >> (2 * log2)) & (n - 1);
            let y = (i >> log2) & (n - 1);
            let z = i & (n - 1);
            [
                origin[0] + x as i32 * child_dim,
                origin[1] + y as i32 * child_dim,
                origin[2] + z as i32 * child_dim,
            ]
        };
        for (i, &v) in vals.iter().enumerate() {
            if bit(cm, i) {
                continue;
            }
            let active = bit(vm, i);
            if active || v != bg {
                push_tile(grid, mask_at(i), tile_level, v, active);
            }
        }
        // Children, in mask order.
        let children: Vec<usize> = (0..nvals).filter(|&i| bit(cm, i)).collect();
        match level {
            InternalLevel::Upper => {
                let mut v2 = vec![0f32; L1_VALUES];
                let mut c2 = vec![0u64; L1_VALUES / 64];
                let mut m2 = vec![0u64; L1_VALUES / 64];
                for i in children {
                    self.read_internal(
                        grid,
                        mask_at(i),
                        InternalLevel::Lower,
                        &mut v2,
                        &mut c2,
                        &mut m2,
                    )?;
                }
            }
            InternalLevel::Lower => {
                self.cur
                    .check_count(children.len() as u64, 64, "leaf topology")?;
                for i in children {
                    let mut leaf = Leaf {
                        origin: mask_at(i),
                        mask: [0; 8],
                    };
                    self.cur.mask_into(&mut leaf.mask, "leaf topology mask")?;
                    grid.leaves.push(leaf);
                    if grid.leaves.len() > MAX_LEAVES {
                        return Err(ParseError::unsupported(
                            self.cur.offset(),
                            format!("grid has more than the limit of {MAX_LEAVES} leaves"),
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// OpenVDB `io::readCompressedValues`: `dst.len()` values of a node whose active mask is
    /// `value_mask`; inactive values may be omitted and rebuilt from the metadata code.
    fn read_compressed_values(&mut self, dst: &mut [f32], value_mask: &[u64]) -> PResult<()> {
        let n = dst.len();
        let mask_compressed = self.fmt.compression & COMPRESS_ACTIVE_MASK != 0;
        let mut code = 6u8; // NO_MASK_AND_ALL_VALS
        if self.fmt.version >= V_NODE_MASK_COMPRESSION {
            let at = self.cur.offset();
            code = self.cur.u8("node compression code")?;
            if code > 6 {
                return Err(ParseError::corrupt(
                    at,
                    format!("invalid per-node compression code {code} (expected 0..=6)"),
                ));
            }
        }
        self.codes.metadata_codes[code as usize] += 1;
        let bg = self.background;
        let mut inactive1 = bg;
        let mut inactive0 = if code == 0 { bg } else { -bg };
        if matches!(code, 2 | 4 | 5) {
            inactive0 = self.full_value("inactive value")?;
            if code == 5 {
                inactive1 = self.full_value("second inactive value")?;
            }
        }
        let words = n / 64;
        if matches!(code, 3..=5) {
            let mut sel = std::mem::take(&mut self.selection);
            let r = self
                .cur
                .mask_into(&mut sel[..words], "inactive value selection mask");
            self.selection = sel;
            r?;
        } else {
            self.selection[..words].fill(0);
        }
        let count = if mask_compressed && code != 6 && self.fmt.version >= V_NODE_MASK_COMPRESSION {
            value_mask.iter().map(|w| w.count_ones() as usize).sum()
        } else {
            n
        };
        if count == n {
            return self.read_data(dst, self.fmt.compression);
        }
        let mut packed = std::mem::take(&mut self.packed);
        packed.resize(count, 0.0);
        let r = self.read_data(&mut packed, self.fmt.compression);
        if r.is_ok() {
            let selection = &self.selection[..words];
            let mut t = 0;
            for (i, d) in dst.iter_mut().enumerate() {
                if bit(value_mask, i) {
                    *d = packed[t];
                    t += 1;
                } else {
                    *d = if bit(selection, i) {
                        inactive1
                    } else {
                        inactive0
                    };
                }
            }
        }
        self.packed = packed;
        r
    }

    /// OpenVDB `io::readData` / `HalfReader::read`: `dst.len()` values, raw or compressed.
    fn read_data(&mut self, dst: &mut [f32], compression: u32) -> PResult<()> {
        let count = dst.len();
        if count == 0 && self.fmt.half {
            // OpenVDB writes nothing at all for an empty half array.
            return Ok(());
        }
        let width = self.fmt.stored_width();
        let nbytes = count * width;
        let bytes: &[u8] = if compression & (COMPRESS_BLOSC | COMPRESS_ZIP) != 0 {
            let at = self.cur.offset();
            let size = self.cur.i64("compressed chunk size")?;
            if size <= 0 {
                let raw = size.unsigned_abs();
                if raw != nbytes as u64 {
                    return Err(ParseError::corrupt(
                        at,
                        format!("expected a {nbytes}-byte chunk, found one of {raw} bytes"),
                    ));
                }
                self.cur.take(nbytes, "uncompressed chunk")?
            } else {
                if size as u64 > self.cur.remaining() as u64 {
                    return Err(ParseError::corrupt(
                        at,
                        format!(
                            "compressed chunk of {size} bytes, but only {} remain",
                            self.cur.remaining()
                        ),
                    ));
                }
                let src = self.cur.take(size as usize, "compressed chunk")?;
                if nbytes == 0 {
                    // OpenVDB writes a header-only blosc frame for an empty array: nothing to decode.
                    return Ok(());
                }
                if width == 4 && cfg!(target_endian = "little") {
                    // f32 on a little-endian machine: decompress straight into the values.
                    let out: &mut [u8] = bytemuck::cast_slice_mut(dst);
                    return if compression & COMPRESS_BLOSC != 0 {
                        vdbcook_blosc::decompress_into(src, out).map_err(|e| {
                            ParseError::corrupt(at, format!("blosc chunk of {nbytes} bytes: {e}"))
                        })
                    } else {
                        inflate(&mut self.zlib, src, out)
                            .map_err(|m| ParseError::corrupt(at, format!("zlib chunk: {m}")))
                    };
                }
                if self.scratch.len() < nbytes {
                    self.scratch.resize(nbytes, 0);
                }
                let out = &mut self.scratch[..nbytes];
                if compression & COMPRESS_BLOSC != 0 {
                    vdbcook_blosc::decompress_into(src, out).map_err(|e| {
                        ParseError::corrupt(at, format!("blosc chunk of {nbytes} bytes: {e}"))
                    })?;
                } else {
                    inflate(&mut self.zlib, src, out)
                        .map_err(|m| ParseError::corrupt(at, format!("zlib chunk: {m}")))?;
                }
                &self.scratch[..nbytes]
            }
        } else {
            self.cur.take(nbytes, "node values")?
        };
        convert(bytes, width, dst);
        Ok(())
    }
}

#[derive(Clone, Copy)]
enum InternalLevel {
    Upper,
    Lower,
}

#[inline]
fn bit(mask: &[u64], i: usize) -> bool {
    mask[i >> 6] >> (i & 63) & 1 == 1
}

fn push_tile(grid: &mut FloatGrid, origin: [i32; 3], level: TileLevel, value: f32, active: bool) {
    let bg = grid.background;
    if active || value != bg {
        grid.tiles.push(Tile {
            origin,
            level,
            value,
            active,
        });
    }
}

fn check_root_key(origin: [i32; 3], at: u64, keys: &mut HashSet<[i32; 3]>) -> PResult<()> {
    if origin.iter().any(|c| c & 4095 != 0) {
        return Err(ParseError::corrupt(
            at,
            format!("root entry origin {origin:?} is not a multiple of 4096"),
        ));
    }
    if !keys.insert(origin) {
        return Err(ParseError::corrupt(
            at,
            format!("duplicate root entry at {origin:?}"),
        ));
    }
    Ok(())
}

/// zlib-inflates `src` into exactly `out.len()` bytes.
fn inflate(z: &mut flate2::Decompress, src: &[u8], out: &mut [u8]) -> Result<(), String> {
    z.reset(true);
    match z.decompress(src, out, flate2::FlushDecompress::Finish) {
        Ok(flate2::Status::StreamEnd) if z.total_out() as usize == out.len() => Ok(()),
        Ok(_) => Err(format!(
            "does not inflate to the expected {} bytes",
            out.len()
        )),
        Err(e) => Err(e.to_string()),
    }
}

/// Little-endian f16 / f32 / f64 bytes → f32 values.
fn convert(bytes: &[u8], width: usize, dst: &mut [f32]) {
    match width {
        4 => {
            for (d, c) in dst.iter_mut().zip(bytes.chunks_exact(4)) {
                *d = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
            }
        }
        2 => {
            for (d, c) in dst.iter_mut().zip(bytes.chunks_exact(2)) {
                *d = half::f16::from_bits(u16::from_le_bytes([c[0], c[1]])).to_f32();
            }
        }
        _ => {
            for (d, c) in dst.iter_mut().zip(bytes.chunks_exact(8)) {
                *d = f64::from_le_bytes(c.try_into().expect("8 bytes")) as f32;
            }
        }
    }
}
