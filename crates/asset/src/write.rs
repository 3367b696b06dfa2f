//! Serializing an asset: header (bincode 2) followed by zstd-compressed little-endian sections.
//! The output depends only on the asset's contents (no timestamps, fixed zstd level, one thread),
//! so the same cook gives byte-identical files.

use crate::format::*;
use crate::Asset;

/// zstd level for sections (level 3 ≈ 1 GB/s here, both ways).
const ZSTD_LEVEL: i32 = 1;

fn le_u32(v: &[u32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}
fn le_u16(v: &[u16]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}
fn le_u64(v: &[u64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}
fn le_f32(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}
fn le_pairs(v: &[[f32; 2]]) -> Vec<u8> {
    v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect()
}

impl Asset {
    /// Raw (uncompressed) bytes of each section, in the order of
    /// [`SectionKind::of_version`] for the header's version; the payload is borrowed, not
    /// copied (the packed atlases are joined into one section).
    pub fn raw_sections(&self) -> Vec<(SectionKind, std::borrow::Cow<'_, [u8]>)> {
        use std::borrow::Cow;
        SectionKind::of_version(self.header.format_version())
            .iter()
            .map(|&k| {
                let bytes: Cow<'_, [u8]> = match k {
                    SectionKind::Roots => Cow::Owned(le_u32(&self.roots)),
                    SectionKind::FrameRanges => Cow::Owned(le_pairs(&self.frame_ranges)),
                    SectionKind::L2Masks => Cow::Owned(le_u64(&self.l2_masks)),
                    SectionKind::L2Base => Cow::Owned(le_u32(&self.l2_base)),
                    SectionKind::L2Prefix => Cow::Owned(le_u16(&self.l2_prefix)),
                    SectionKind::L2Ranges => Cow::Owned(le_pairs(&self.l2_ranges)),
                    SectionKind::L3Refs => Cow::Owned(le_u32(&self.l3_refs)),
                    SectionKind::Tiles => Cow::Owned(le_f32(&self.tiles)),
                    SectionKind::BrickRanges => Cow::Owned(le_pairs(&self.brick_ranges)),
                    SectionKind::BrickQuant => Cow::Owned(le_pairs(&self.brick_quant)),
                    SectionKind::PayloadBc7 => Cow::Borrowed(&self.payloads[0][..]),
                    SectionKind::PayloadBc4 => Cow::Borrowed(&self.payloads[1][..]),
                    SectionKind::PayloadUnorm8 => Cow::Borrowed(&self.payloads[2][..]),
                    SectionKind::PayloadF16 => Cow::Borrowed(&self.payloads[3][..]),
                    SectionKind::PayloadF32 => Cow::Borrowed(&self.payloads[4][..]),
                    SectionKind::PayloadPacked => Cow::Owned(self.payloads[FORMATS_V6..].concat()),
                };
                (k, bytes)
            })
            .collect()
    }

    /// The file bytes. Also returns the header as written (with sections and hash filled in).
    pub fn to_bytes(&self) -> Result<(Vec<u8>, Header), crate::AssetError> {
        let mut header = self.header.clone();
        header.sections.clear();
        let mut body = Vec::new();
        let mut raws = Vec::new();
        for (kind, raw) in self.raw_sections() {
            let compressed = zstd::bulk::compress(&raw, ZSTD_LEVEL).map_err(|e| {
                crate::AssetError(format!("zstd failed on section {}: {e}", kind.name()))
            })?;
            header.sections.push(SectionInfo {
                kind,
                offset: body.len() as u64,
                compressed_len: compressed.len() as u64,
                raw_len: raw.len() as u64,
                hash: xxhash_rust::xxh3::xxh3_64(&raw),
            });
            body.extend_from_slice(&compressed);
            raws.push(raw);
        }
        header.content_hash = content_hash(&header, &raws)?;
        drop(raws);
        let hbytes = header.encode()?;
        let mut out = Vec::with_capacity(16 + hbytes.len() + body.len());
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&header.format_version().to_le_bytes());
        out.extend_from_slice(&(hbytes.len() as u32).to_le_bytes());
        out.extend_from_slice(&hbytes);
        out.extend_from_slice(&body);
        Ok((out, header))
    }
}

/// xxh3-64 over the header (with `content_hash` zeroed) and every raw section in order.
pub(crate) fn content_hash<T: AsRef<[u8]>>(
    header: &Header,
    raws: &[T],
) -> Result<u64, crate::AssetError> {
    let mut h = header.clone();
    h.content_hash = 0;
    let hb = h.encode()?;
    let mut all = xxhash_rust::xxh3::Xxh3::new();
    all.update(&hb);
    for r in raws {
        all.update(r.as_ref());
    }
    Ok(all.digest())
}
