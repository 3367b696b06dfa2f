//! Per-stream codec dispatch for the blosc decoder.
//!
//! Why this file exists: it wraps each codec so that one compressed stream
//! (the bytes after a stream's 4-byte size field) decodes into a slice of
//! exactly the expected length, mirroring c-blosc's checks:
//!
//! * blosclz: this crate's decoder ([`crate::blosclz`]);
//! * lz4 / lz4hc: raw LZ4 block format (`lz4_flex`, safe decoder);
//! * snappy: raw snappy format (`snap::raw`), length preamble must match;
//! * zlib: an RFC 1950 zlib stream (`flate2`), must end inside the output;
//! * zstd: one or more zstd frames (`zstd::bulk`) into the bounded output.
//!
//! Contexts for zlib and zstd are created lazily and reused across the
//! streams of one frame.

use crate::{blosclz, Codec};

/// Lazily created decoder contexts, reused across the streams of one frame.
pub(crate) struct Decoders {
    zlib: Option<flate2::Decompress>,
    zstd: Option<zstd::bulk::Decompressor<'static>>,
}

impl Decoders {
    pub(crate) fn new() -> Self {
        Decoders {
            zlib: None,
            zstd: None,
        }
    }

    /// Decodes one stream into `out`, which must come out exactly full.
    pub(crate) fn decode(
        &mut self,
        codec: Codec,
        input: &[u8],
        out: &mut [u8],
    ) -> Result<(), String> {
        let expected = out.len();
        let got = match codec {
            Codec::BloscLz => return blosclz::decompress(input, out),
            Codec::Lz4 => {
                lz4_flex::block::decompress_into(input, out).map_err(|e| e.to_string())?
            }
            Codec::Snappy => {
                let len = snap::raw::decompress_len(input).map_err(|e| e.to_string())?;
                if len != expected {
                    return Err(format!("snappy preamble announces {len} bytes"));
                }
                snap::raw::Decoder::new()
                    .decompress(input, out)
                    .map_err(|e| e.to_string())?
            }
            Codec::Zlib => {
                let z = self
                    .zlib
                    .get_or_insert_with(|| flate2::Decompress::new(true));
                z.reset(true);
                let status = z
                    .decompress(input, out, flate2::FlushDecompress::Finish)
                    .map_err(|e| e.to_string())?;
                if status != flate2::Status::StreamEnd {
                    return Err(format!(
                        "zlib stream did not end within the output ({} of {} input bytes read)",
                        z.total_in(),
                        input.len()
                    ));
                }
                z.total_out() as usize
            }
            Codec::Zstd => {
                let z = match &mut self.zstd {
                    Some(z) => z,
                    None => {
                        let z = zstd::bulk::Decompressor::new().map_err(|e| e.to_string())?;
                        self.zstd.insert(z)
                    }
                };
                z.decompress_to_buffer(input, out)
                    .map_err(|e| e.to_string())?
            }
        };
        if got != expected {
            return Err(format!("decoded {got} bytes"));
        }
        Ok(())
    }
}
