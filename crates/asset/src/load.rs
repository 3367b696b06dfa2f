//! Loading = read, decompress, validate. Every section's size is checked against the counts it
//! implies before decompressing (into exactly that size), hashes are compared, and every index is
//! checked to be in range, so a corrupt or hostile asset is refused before it reaches a GPU.

use crate::error::{bad, AssetError};
use crate::format::*;
use crate::Asset;

/// Largest raw section accepted (16 GiB).
const MAX_SECTION: u64 = 16 << 30;

fn u32s(b: &[u8]) -> Vec<u32> {
    b.chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}
fn u16s(b: &[u8]) -> Vec<u16> {
    b.chunks_exact(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect()
}
fn u64s(b: &[u8]) -> Vec<u64> {
    b.chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().expect("8")))
        .collect()
}
fn f32s(b: &[u8]) -> Vec<f32> {
    b.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}
fn pairs(b: &[u8]) -> Vec<[f32; 2]> {
    f32s(b).chunks_exact(2).map(|p| [p[0], p[1]]).collect()
}

impl Asset {
    /// Reads and validates an asset file.
    pub fn load(path: impl AsRef<std::path::Path>) -> Result<Asset, AssetError> {
        let path = path.as_ref();
        let bytes = std::fs::read(path)
            .map_err(|e| AssetError(format!("{}: cannot read: {e}", path.display())))?;
        Asset::from_bytes(&bytes).map_err(|e| AssetError(format!("{}: {}", path.display(), e.0)))
    }

    /// Parses and validates asset bytes.
    pub fn from_bytes(bytes: &[u8]) -> Result<Asset, AssetError> {
        if bytes.len() < 16 || bytes[..8] != MAGIC {
            return bad("not a vdbcook asset (magic number missing)");
        }
        let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4"));
        if !(FORMAT_VERSION_SINGLE..=FORMAT_VERSION).contains(&version) {
            return bad(format!(
                "asset format version {version}; this build reads versions \
                 {FORMAT_VERSION_SINGLE} to {FORMAT_VERSION}"
            ));
        }
        let hlen = u32::from_le_bytes(bytes[12..16].try_into().expect("4")) as usize;
        if hlen > MAX_HEADER_BYTES || 16 + hlen > bytes.len() {
            return bad(format!(
                "header length {hlen} does not fit the {}-byte file",
                bytes.len()
            ));
        }
        let config = bincode::config::standard().with_limit::<MAX_HEADER_BYTES>();
        let hbytes = &bytes[16..16 + hlen];
        let corrupt = |e: bincode::error::DecodeError| AssetError(format!("corrupt header: {e}"));
        let (header, used): (Header, usize) = if version == FORMAT_VERSION_SINGLE {
            let (h, used): (HeaderV2, usize) =
                bincode::serde::decode_from_slice(hbytes, config).map_err(corrupt)?;
            (h.into(), used)
        } else {
            let (h, used): (Header, usize) = if version == FORMAT_VERSION_CHANNELS {
                let (h, used): (HeaderV3, usize) =
                    bincode::serde::decode_from_slice(hbytes, config).map_err(corrupt)?;
                (h.into(), used)
            } else if version == FORMAT_VERSION_LOD {
                let (h, used): (HeaderV4, usize) =
                    bincode::serde::decode_from_slice(hbytes, config).map_err(corrupt)?;
                (h.into(), used)
            } else if version == FORMAT_VERSION_LOD_FROM {
                let (h, used): (HeaderV5, usize) =
                    bincode::serde::decode_from_slice(hbytes, config).map_err(corrupt)?;
                (h.into(), used)
            } else if version == FORMAT_VERSION_SOURCE {
                let (h, used): (HeaderV6, usize) =
                    bincode::serde::decode_from_slice(hbytes, config).map_err(corrupt)?;
                (h.into(), used)
            } else {
                bincode::serde::decode_from_slice(hbytes, config).map_err(corrupt)?
            };
            let lod_version = version == FORMAT_VERSION_LOD || version == FORMAT_VERSION_LOD_FROM;
            if (lod_version && h.lod_levels == 0) || h.lod_levels > MAX_LOD_LEVELS {
                return bad(format!(
                    "a version-{version} asset has 1..={MAX_LOD_LEVELS} coarser levels, this one {}",
                    h.lod_levels
                ));
            }
            if version == FORMAT_VERSION_LOD_FROM && h.lod_first < 2 {
                return bad(format!(
                    "a version-{version} asset's levels start at level 2 or coarser, this one's at {}",
                    h.lod_first
                ));
            }
            if h.lod_first < 1 || (h.lod_levels == 0 && h.lod_first != 1) {
                return bad(format!(
                    "a version-{version} asset with {} coarser levels cannot start them at level {}",
                    h.lod_levels, h.lod_first
                ));
            }
            if (version == FORMAT_VERSION_CHANNELS || !h.channels.is_empty())
                && (h.channels.len() < 2 || h.channels.len() > MAX_CHANNELS)
            {
                return bad(format!(
                    "a version-{version} asset has 2..={MAX_CHANNELS} channels, this one {}",
                    h.channels.len()
                ));
            }
            (h, used)
        };
        if used != hlen {
            return bad(format!("header is {used} bytes, the file says {hlen}"));
        }
        let body = &bytes[16 + hlen..];
        let nframes = header.frames.len();
        if nframes == 0 {
            return bad("asset has no frames");
        }
        if header.root_dims.iter().any(|&d| d == 0 || d > ROOT_DIM_MAX) {
            return bad(format!(
                "root dimensions {:?} out of range 1..={ROOT_DIM_MAX}",
                header.root_dims
            ));
        }
        let kinds = SectionKind::of_version(version);
        if header.sections.len() != kinds.len()
            || header.sections.iter().zip(kinds).any(|(s, k)| s.kind != *k)
        {
            return bad("section table does not list the expected sections in order");
        }
        let mut raw = Vec::with_capacity(kinds.len());
        for s in &header.sections {
            let name = s.kind.name();
            let end = s.offset.checked_add(s.compressed_len);
            if end.is_none_or(|e| e > body.len() as u64) {
                return bad(format!(
                    "section {name} ({} bytes at {}) lies outside the file",
                    s.compressed_len, s.offset
                ));
            }
            if s.raw_len > MAX_SECTION {
                return bad(format!(
                    "section {name} claims an absurd size of {} bytes",
                    s.raw_len
                ));
            }
            let src = &body[s.offset as usize..(s.offset + s.compressed_len) as usize];
            // The frame must state its content size, and it must match before we allocate.
            match zstd::zstd_safe::get_frame_content_size(src) {
                Ok(Some(n)) if n == s.raw_len => {}
                _ => {
                    return bad(format!(
                        "section {name}: compressed frame does not declare {} bytes",
                        s.raw_len
                    ))
                }
            }
            let data = zstd::bulk::decompress(src, s.raw_len as usize)
                .map_err(|e| AssetError(format!("section {name}: {e}")))?;
            if data.len() as u64 != s.raw_len {
                return bad(format!(
                    "section {name} decompressed to {} bytes, expected {}",
                    data.len(),
                    s.raw_len
                ));
            }
            if xxhash_rust::xxh3::xxh3_64(&data) != s.hash {
                return bad(format!("section {name} is corrupt (hash mismatch)"));
            }
            raw.push(data);
        }
        if crate::write::content_hash(&header, &raw)? != header.content_hash {
            return bad("content hash mismatch (header or sections corrupt)");
        }
        let root_len: usize = header.root_dims.iter().map(|&d| d as usize).product();
        let nch = header.channel_count();
        // Root sets: every frame at every level.
        let nsets = nframes * header.level_count();
        // Element counts implied by the sections, checked for consistency.
        let n_l2 = raw[3].len() / 4;
        let n_bricks = raw[8].len() / 8;
        if header
            .brick_counts
            .iter()
            .try_fold(0u64, |a, &n| a.checked_add(n))
            != Some(n_bricks as u64)
        {
            return bad(format!(
                "brick counts per format {:?} do not add up to the {n_bricks} bricks",
                header.brick_counts
            ));
        }
        let mut expect: Vec<(usize, u64)> = vec![
            (0, (nsets * root_len * 4) as u64),
            (1, (nsets * nch) as u64 * 8),
            (2, n_l2 as u64 * L2_WORDS as u64 * 8),
            (3, n_l2 as u64 * 4),
            (4, n_l2 as u64 * L2_WORDS as u64 * 2),
            (5, (n_l2 * nch) as u64 * 8),
            (6, raw[6].len() as u64 / (4 * nch as u64) * (4 * nch as u64)),
            (7, raw[7].len() as u64 / 4 * 4),
            (8, n_bricks as u64 * 8),
            (9, n_bricks as u64 * 8),
        ];
        for (i, f) in PayloadFormat::ORDER[..FORMATS_V6].iter().enumerate() {
            expect.push((10 + i, header.brick_counts[i] * f.bytes_per_brick() as u64));
        }
        let packed_bytes = |h: &Header| -> u64 {
            PayloadFormat::ORDER[FORMATS_V6..]
                .iter()
                .map(|f| h.brick_counts[f.rank()].saturating_mul(f.bytes_per_brick() as u64))
                .fold(0u64, u64::saturating_add)
        };
        if version >= FORMAT_VERSION {
            expect.push((15, packed_bytes(&header)));
        } else if packed_bytes(&header) != 0 {
            return bad(format!("a version-{version} asset holds no packed bricks"));
        }
        for (i, want) in expect {
            if raw[i].len() as u64 != want {
                return bad(format!(
                    "section {} has {} bytes, the counts imply {want}",
                    SectionKind::ALL[i].name(),
                    raw[i].len()
                ));
            }
        }
        let mut payloads: [Vec<u8>; FORMATS] = Default::default();
        for (i, p) in payloads[..FORMATS_V6].iter_mut().enumerate() {
            *p = std::mem::take(&mut raw[10 + i]);
        }
        if let Some(packed) = raw.get(15) {
            let mut at = 0;
            for f in &PayloadFormat::ORDER[FORMATS_V6..] {
                let n = (header.brick_counts[f.rank()] * f.bytes_per_brick() as u64) as usize;
                payloads[f.rank()] = packed[at..at + n].to_vec();
                at += n;
            }
        }
        let asset = Asset {
            roots: u32s(&raw[0]),
            frame_ranges: pairs(&raw[1]),
            l2_masks: u64s(&raw[2]),
            l2_base: u32s(&raw[3]),
            l2_prefix: u16s(&raw[4]),
            l2_ranges: pairs(&raw[5]),
            l3_refs: u32s(&raw[6]),
            tiles: f32s(&raw[7]),
            brick_ranges: pairs(&raw[8]),
            brick_quant: pairs(&raw[9]),
            payloads,
            header,
        };
        asset.validate()?;
        Ok(asset)
    }

    /// Checks every index and count (also used on freshly cooked assets in tests).
    pub fn validate(&self) -> Result<(), AssetError> {
        if self.header.lod_levels > MAX_LOD_LEVELS {
            return bad(format!(
                "{} coarser levels; an asset holds at most {MAX_LOD_LEVELS}",
                self.header.lod_levels
            ));
        }
        let (first, levels) = (self.header.lod_first, self.header.lod_levels);
        if first == 0
            || (levels > 0 && u64::from(first) + u64::from(levels) - 1 > MAX_LOD_LEVELS.into())
        {
            return bad(format!(
                "levels {first} to {} of detail; an asset holds levels 1 to {MAX_LOD_LEVELS}",
                u64::from(first) + u64::from(levels.max(1)) - 1
            ));
        }
        let n_l2 = self.l2_count();
        let n_tiles = self.tiles.len();
        let n_bricks = self.brick_count();
        let nch = self.channel_count();
        let n_refs = self.l3_refs.len() / nch;
        let ok_ref = |r: u32| {
            if r == EMPTY {
                nch > 1
            } else if r & TILE_BIT != 0 {
                ((r & !TILE_BIT) as usize) < n_tiles
            } else {
                (r as usize) < n_bricks
            }
        };
        if self.roots.len() != self.root_set_count() * self.root_len() {
            return bad(format!(
                "{} root entries for {} frame(s) at {} level(s) of {} regions",
                self.roots.len(),
                self.frame_count(),
                self.level_count(),
                self.root_len()
            ));
        }
        for (i, &e) in self.roots.iter().enumerate() {
            let fine = e == EMPTY
                || if e & TILE_BIT != 0 {
                    // A tiled region holds one value: multi-channel assets have none.
                    nch == 1 && ((e & !TILE_BIT) as usize) < n_tiles
                } else {
                    (e as usize) < n_l2
                };
            if !fine {
                return bad(format!(
                    "root entry {i} of {} points outside the node pools ({e:#x})",
                    self.roots.len()
                ));
            }
        }
        for n in 0..n_l2 {
            let mask = self.l2_mask(n);
            let mut count = 0usize;
            for (w, &word) in mask.iter().enumerate() {
                if self.l2_prefix[n * L2_WORDS + w] as usize != count {
                    return bad(format!(
                        "L2 node {n}: prefix count of word {w} is inconsistent with its mask"
                    ));
                }
                count += word.count_ones() as usize;
            }
            let base = self.l2_base[n] as usize;
            if base + count > n_refs {
                return bad(format!(
                    "L2 node {n}: children {base}..{} exceed the {n_refs} leaf refs",
                    base + count
                ));
            }
            if count == 0 {
                return bad(format!("L2 node {n} has no children"));
            }
        }
        if let Some(i) = self.l3_refs.iter().position(|&r| !ok_ref(r)) {
            return bad(format!(
                "leaf ref {i} ({:#x}) points outside the tiles/bricks",
                self.l3_refs[i]
            ));
        }
        if !self.l3_refs.len().is_multiple_of(nch)
            || self.l2_ranges.len() != n_l2 * nch
            || self.frame_ranges.len() != self.root_set_count() * nch
        {
            return bad(format!(
                "leaf refs, node or frame ranges are not {nch} per slot, node and frame"
            ));
        }
        let h = &self.header;
        if !h.channels.is_empty() {
            let c0 = &h.channels[0];
            if c0.name != h.grid_name || c0.background.to_bits() != h.background.to_bits() {
                return bad("channel 0 does not match the header's grid name and background");
            }
            for (i, c) in h.channels.iter().enumerate() {
                if !c.background.is_finite()
                    || c.active_voxels.len() != self.frame_count()
                    || c.max_error.is_some_and(|e| !(e.is_finite() && e > 0.0))
                    || h.channels[..i].iter().any(|o| o.name == c.name)
                {
                    return bad(format!(
                        "channel {i} ({:?}): non-finite background, a duplicate name, a bad \
                         error budget or not one voxel count per frame",
                        c.name
                    ));
                }
            }
        }
        let finite = |v: &f32| v.is_finite();
        if !self.tiles.iter().all(finite) || !self.header.background.is_finite() {
            return bad("non-finite tile or background value");
        }
        if self.brick_quant.len() != n_bricks
            || self.header.brick_counts.iter().sum::<u64>() != n_bricks as u64
        {
            return bad("per-brick quantization ranges or format counts do not match the bricks");
        }
        for (f, p) in PayloadFormat::ORDER.iter().zip(&self.payloads) {
            if p.len() as u64 != self.header.brick_counts[f.rank()] * f.bytes_per_brick() as u64 {
                return bad(format!(
                    "{} atlas has {} bytes for {} bricks",
                    f.name(),
                    p.len(),
                    self.header.brick_counts[f.rank()]
                ));
            }
        }
        for (what, r) in [
            ("frame", &self.frame_ranges),
            ("L2 node", &self.l2_ranges),
            ("brick", &self.brick_ranges),
            ("brick quantization", &self.brick_quant),
        ] {
            if let Some(i) = r
                .iter()
                .position(|p| !(p[0].is_finite() && p[1].is_finite() && p[0] <= p[1]))
            {
                return bad(format!("{what} {i} has an invalid value range {:?}", r[i]));
            }
        }
        if self.header.index_offset.iter().any(|o| o % L2_SPAN != 0) {
            return bad(format!(
                "index offset {:?} is not a multiple of {L2_SPAN}",
                self.header.index_offset
            ));
        }
        Ok(())
    }
}
