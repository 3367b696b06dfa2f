//! Pure-Rust, bounds-checked decoder for c-blosc 1.x frames.
//!
//! Why this crate exists: OpenVDB files written with `COMPRESS_BLOSC` store each
//! value buffer as one c-blosc 1.x frame (OpenVDB itself uses lz4 with byte
//! shuffle and `typesize = sizeof(value)`).  This crate decodes any frame that
//! c-blosc 1.x can write, in safe Rust, without panicking and without
//! allocating more than the caller has validated, whatever the input.
//!
//! # Frame layout (all integers little-endian)
//!
//! ```text
//! offset  size  field
//!  0      1     version      blosc format version (2 for c-blosc 1.x; 1 accepted too)
//!  1      1     versionlz    codec format version (1 for every codec)
//!  2      1     flags        bit 0 (0x01) byte shuffle
//!                            bit 1 (0x02) memcpyed: payload stored raw at offset 16
//!                            bit 2 (0x04) bit shuffle
//!                            bit 3 (0x08) reserved, must be 0
//!                            bit 4 (0x10) "don't split" (one stream per block)
//!                            bits 5-7     codec: 0 blosclz, 1 lz4/lz4hc, 2 snappy,
//!                                         3 zlib, 4 zstd
//!  3      1     typesize     bytes per element (1..=255)
//!  4      4     nbytes       uncompressed size (i32)
//!  8      4     blocksize    uncompressed bytes per block (i32)
//! 12      4     cbytes       total compressed size, header included (i32)
//! 16      4*n   bstarts      offset of block j's data from the frame start
//!                            (n = ceil(nbytes / blocksize); absent when memcpyed)
//! ```
//!
//! Each block is `blocksize` bytes of output (the last one, the "leftover"
//! block, may be shorter).  A block is stored as `nsplits` streams, each
//! preceded by its i32 compressed size; a stream whose compressed size equals
//! its uncompressed size (`blocksize / nsplits`) is stored raw.  `nsplits` is
//! `typesize` when the don't-split flag is clear, `typesize <= 16`,
//! `blocksize / typesize >= 128` and the block is not the leftover block;
//! otherwise it is 1.  (c-blosc's `BLOSC_SPLITMODE=ALWAYS` also splits blocks
//! outside those conditions, which c-blosc itself then fails to decode; this
//! decoder falls back to that layout when the single-stream reading fails.)
//! After decompression the block is unshuffled (byte or bit shuffle, see
//! `shuffle.rs`) into its place in the output; memcpyed frames hold the
//! `nbytes` raw bytes at offset 16 and `cbytes == nbytes + 16`.
//!
//! # API
//!
//! * [`parse_header`] reads and validates the 16-byte header without decoding.
//! * [`decompress_into`] decodes into a slice that is exactly `nbytes` long.
//! * [`decompress`] allocates the output after checking `nbytes <= max_len`.
#![forbid(unsafe_code)]

mod blosclz;
mod codecs;
mod error;
mod shuffle;

pub use error::BloscError;

use codecs::Decoders;

/// Size of the fixed c-blosc 1.x header.
pub const HEADER_LEN: usize = 16;
/// Largest `nbytes` c-blosc 1.x accepts (`INT32_MAX - 16`).
pub const MAX_BUFFERSIZE: usize = i32::MAX as usize - HEADER_LEN;
/// Largest `blocksize` c-blosc 1.x accepts (`(INT32_MAX - 255 * 4) / 3`).
pub const MAX_BLOCKSIZE: usize = (i32::MAX as usize - 255 * 4) / 3;
/// Largest typesize for which blocks may be split into per-byte streams.
const MAX_SPLITS: usize = 16;
/// Minimum elements per stream for c-blosc to consider splitting.
const MIN_BUFFERSIZE: usize = 128;

/// Header flag: byte shuffle.
pub const FLAG_SHUFFLE: u8 = 0x01;
/// Header flag: the payload is stored uncompressed after the header.
pub const FLAG_MEMCPYED: u8 = 0x02;
/// Header flag: bit shuffle.
pub const FLAG_BITSHUFFLE: u8 = 0x04;
/// Header flag bit that c-blosc 1.x reserves (frames with it set are rejected).
pub const FLAG_RESERVED: u8 = 0x08;
/// Header flag: blocks are not split into per-byte streams.
pub const FLAG_DONT_SPLIT: u8 = 0x10;

/// Compression codec of a frame (bits 5-7 of the flags byte).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Codec {
    /// BloscLZ (code 0), decoded by this crate's own decoder.
    BloscLz,
    /// LZ4 or LZ4HC (code 1: both write the LZ4 block format).
    Lz4,
    /// Snappy raw format (code 2).
    Snappy,
    /// zlib stream, RFC 1950 (code 3).
    Zlib,
    /// Zstandard frame(s) (code 4).
    Zstd,
}

impl Codec {
    /// Codec for the 3-bit format code stored in the flags byte.
    pub fn from_code(code: u8) -> Option<Codec> {
        match code {
            0 => Some(Codec::BloscLz),
            1 => Some(Codec::Lz4),
            2 => Some(Codec::Snappy),
            3 => Some(Codec::Zlib),
            4 => Some(Codec::Zstd),
            _ => None,
        }
    }

    /// Lower-case name, as c-blosc spells the library.
    pub fn name(self) -> &'static str {
        match self {
            Codec::BloscLz => "blosclz",
            Codec::Lz4 => "lz4",
            Codec::Snappy => "snappy",
            Codec::Zlib => "zlib",
            Codec::Zstd => "zstd",
        }
    }
}

impl std::fmt::Display for Codec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Shuffle filter applied to every block (as c-blosc decides it from the flags).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Shuffle {
    /// No filter.
    None,
    /// Byte shuffle: byte `j` of every element grouped together.
    Byte,
    /// Bit shuffle (bitshuffle's bit transpose).
    Bit,
}

/// The validated 16-byte frame header.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Header {
    /// Blosc format version (byte 0).
    pub version: u8,
    /// Codec format version (byte 1).
    pub versionlz: u8,
    /// Raw flags byte (byte 2); see the `FLAG_*` constants.
    pub flags: u8,
    /// Element size in bytes (byte 3), 1..=255.
    pub typesize: usize,
    /// Uncompressed size in bytes.
    pub nbytes: usize,
    /// Uncompressed bytes per block (`1..=nbytes`; unchecked when `nbytes == 0`).
    pub blocksize: usize,
    /// Total compressed size, header included.
    pub cbytes: usize,
    /// Codec used for the streams.
    pub codec: Codec,
}

impl Header {
    /// True when the payload is stored raw right after the header.
    pub fn memcpyed(&self) -> bool {
        self.flags & FLAG_MEMCPYED != 0
    }

    /// True when the don't-split flag is set.
    pub fn dont_split(&self) -> bool {
        self.flags & FLAG_DONT_SPLIT != 0
    }

    /// Shuffle filter named by the flags (byte shuffle wins when both bits are set).
    ///
    /// c-blosc skips byte shuffle for `typesize == 1` and bit shuffle for blocks
    /// shorter than `typesize`; the decoder applies those rules per block.
    pub fn shuffle(&self) -> Shuffle {
        if self.flags & FLAG_SHUFFLE != 0 {
            Shuffle::Byte
        } else if self.flags & FLAG_BITSHUFFLE != 0 {
            Shuffle::Bit
        } else {
            Shuffle::None
        }
    }

    /// Number of blocks, the leftover block included.
    pub fn nblocks(&self) -> usize {
        if self.blocksize == 0 {
            0
        } else {
            self.nbytes.div_ceil(self.blocksize)
        }
    }
}

fn read_i32(src: &[u8], at: usize) -> Option<i32> {
    let b = src.get(at..at.checked_add(4)?)?;
    Some(i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Reads and validates the 16-byte header, without looking past it.
///
/// Checks the versions, reserved flag, codec, typesize and that `nbytes`,
/// `blocksize` and `cbytes` are within c-blosc 1.x's limits and mutually
/// consistent.  It does not check `cbytes` against `src.len()` (so a caller may
/// peek at a header before reading the rest of the frame); [`decompress_into`]
/// does.
pub fn parse_header(src: &[u8]) -> Result<Header, BloscError> {
    if src.len() < HEADER_LEN {
        return Err(BloscError::HeaderTruncated { len: src.len() });
    }
    let version = src[0];
    let versionlz = src[1];
    let flags = src[2];
    let typesize = src[3] as usize;
    let nbytes = read_i32(src, 4).unwrap_or(-1);
    let blocksize = read_i32(src, 8).unwrap_or(-1);
    let cbytes = read_i32(src, 12).unwrap_or(-1);

    if !(1..=2).contains(&version) {
        return Err(BloscError::UnsupportedVersion { version });
    }
    if flags & FLAG_RESERVED != 0 {
        return Err(BloscError::ReservedFlag { flags });
    }
    let code = flags >> 5;
    let codec = Codec::from_code(code).ok_or(BloscError::UnknownCodec { code })?;
    if flags & FLAG_MEMCPYED == 0 && versionlz != 1 {
        return Err(BloscError::UnsupportedCodecVersion {
            codec,
            version: versionlz,
        });
    }
    if typesize == 0 {
        return Err(BloscError::ZeroTypesize);
    }
    if nbytes < 0 || nbytes as usize > MAX_BUFFERSIZE {
        return Err(BloscError::BadNbytes {
            nbytes: nbytes as i64,
        });
    }
    let nbytes = nbytes as usize;
    if cbytes < HEADER_LEN as i32 {
        return Err(BloscError::BadCbytes {
            cbytes: cbytes as i64,
        });
    }
    let cbytes = cbytes as usize;
    let blocksize = if nbytes == 0 {
        // c-blosc returns before looking at the block size of an empty frame.
        blocksize.clamp(0, i32::MAX) as usize
    } else {
        if blocksize <= 0 || blocksize as usize > MAX_BLOCKSIZE || blocksize as usize > nbytes {
            return Err(BloscError::BadBlocksize {
                blocksize: blocksize as i64,
                nbytes,
            });
        }
        blocksize as usize
    };
    Ok(Header {
        version,
        versionlz,
        flags,
        typesize,
        nbytes,
        blocksize,
        cbytes,
        codec,
    })
}

/// Decompresses the frame `src` into `dst`, which must be exactly `nbytes` long.
///
/// Bytes of `src` past the header's `cbytes` are ignored.  On error the
/// contents of `dst` are unspecified (but only `dst` is written).
pub fn decompress_into(src: &[u8], dst: &mut [u8]) -> Result<(), BloscError> {
    let h = parse_header(src)?;
    if dst.len() != h.nbytes {
        return Err(BloscError::OutputSizeMismatch {
            nbytes: h.nbytes,
            dst_len: dst.len(),
        });
    }
    if h.cbytes > src.len() {
        return Err(BloscError::FrameTruncated {
            cbytes: h.cbytes,
            len: src.len(),
        });
    }
    if h.nbytes == 0 {
        return Ok(());
    }
    let src = &src[..h.cbytes];

    if h.memcpyed() {
        if h.cbytes != h.nbytes + HEADER_LEN {
            return Err(BloscError::MemcpyedSizeMismatch {
                nbytes: h.nbytes,
                cbytes: h.cbytes,
            });
        }
        dst.copy_from_slice(&src[HEADER_LEN..]);
        return Ok(());
    }

    let nblocks = h.nblocks();
    if nblocks > (h.cbytes - HEADER_LEN) / 4 {
        return Err(BloscError::BstartsTruncated {
            nblocks,
            cbytes: h.cbytes,
        });
    }

    let mut decoders = Decoders::new();
    // Scratch for the shuffled block; blocksize <= nbytes == dst.len() was validated.
    let mut tmp: Vec<u8> = Vec::new();
    if h.flags & (FLAG_SHUFFLE | FLAG_BITSHUFFLE) != 0 {
        tmp.resize(h.blocksize, 0);
    }

    for (j, out) in dst.chunks_mut(h.blocksize).enumerate() {
        let start = read_i32(src, HEADER_LEN + 4 * j).unwrap_or(-1);
        let leftover = out.len() < h.blocksize;
        decode_block(&h, src, j, start, leftover, out, &mut tmp, &mut decoders)?;
    }
    Ok(())
}

/// Decompresses the frame `src` into a new vector, refusing frames whose
/// `nbytes` exceeds `max_len` before allocating anything.
pub fn decompress(src: &[u8], max_len: usize) -> Result<Vec<u8>, BloscError> {
    let h = parse_header(src)?;
    if h.nbytes > max_len {
        return Err(BloscError::TooLarge {
            nbytes: h.nbytes,
            max_len,
        });
    }
    if h.cbytes > src.len() {
        return Err(BloscError::FrameTruncated {
            cbytes: h.cbytes,
            len: src.len(),
        });
    }
    let mut out = vec![0u8; h.nbytes];
    decompress_into(src, &mut out)?;
    Ok(out)
}

/// Decodes block `j` (whose output slice is `out`) starting at frame offset `start`.
#[allow(clippy::too_many_arguments)]
fn decode_block(
    h: &Header,
    src: &[u8],
    j: usize,
    start: i32,
    leftover: bool,
    out: &mut [u8],
    tmp: &mut [u8],
    decoders: &mut Decoders,
) -> Result<(), BloscError> {
    let bsize = out.len();
    let ts = h.typesize;
    let doshuffle = h.flags & FLAG_SHUFFLE != 0 && ts > 1;
    let dobitshuffle = !doshuffle && h.flags & FLAG_BITSHUFFLE != 0 && bsize >= ts;

    // c-blosc's decoder splits only under the pre-split-flag conditions too.
    let blosc_split =
        !h.dont_split() && ts <= MAX_SPLITS && bsize / ts >= MIN_BUFFERSIZE && !leftover;
    let nsplits = if blosc_split { ts } else { 1 };

    let target: &mut [u8] = if doshuffle || dobitshuffle {
        &mut tmp[..bsize]
    } else {
        &mut *out
    };

    let res = decode_streams(h, src, j, start, nsplits, target, decoders);
    if let Err(first) = res {
        // c-blosc's BLOSC_SPLITMODE=ALWAYS writes split blocks even where its own
        // decoder assumes a single stream (small blocks, typesize > 16).  Try
        // that layout before giving up; report the first error if it fails too.
        let alt =
            !h.dont_split() && !blosc_split && !leftover && ts > 1 && bsize.is_multiple_of(ts);
        if !alt || decode_streams(h, src, j, start, ts, target, decoders).is_err() {
            return Err(first);
        }
    }

    if doshuffle {
        shuffle::unshuffle(ts, &tmp[..bsize], out);
    } else if dobitshuffle {
        shuffle::bitunshuffle(ts, &tmp[..bsize], out);
    }
    Ok(())
}

/// Decodes the `nsplits` streams of one block into `target` (the block's bytes).
fn decode_streams(
    h: &Header,
    src: &[u8],
    block: usize,
    start: i32,
    nsplits: usize,
    target: &mut [u8],
    decoders: &mut Decoders,
) -> Result<(), BloscError> {
    let cbytes = src.len();
    let bsize = target.len();
    let neblock = bsize / nsplits;
    if neblock * nsplits != bsize {
        return Err(BloscError::UnevenSplit {
            block,
            bsize,
            typesize: h.typesize,
        });
    }
    if start < 0 || start as usize > cbytes.saturating_sub(4) {
        return Err(BloscError::BlockStartOutOfBounds {
            block,
            start: start as i64,
            cbytes,
        });
    }
    let mut off = start as usize;
    for (s, chunk) in target.chunks_exact_mut(neblock.max(1)).enumerate() {
        let size = match read_i32(src, off) {
            Some(v) => v,
            None => {
                return Err(BloscError::StreamOutOfBounds {
                    block,
                    stream: s,
                    offset: off,
                    size: None,
                    cbytes,
                })
            }
        };
        off += 4;
        if size < 0 || size as usize > cbytes - off {
            return Err(BloscError::StreamOutOfBounds {
                block,
                stream: s,
                offset: off - 4,
                size: Some(size as i64),
                cbytes,
            });
        }
        let size = size as usize;
        let input = &src[off..off + size];
        if size == neblock {
            chunk.copy_from_slice(input);
        } else {
            decoders
                .decode(h.codec, input, chunk)
                .map_err(|detail| BloscError::Codec {
                    codec: h.codec,
                    block,
                    stream: s,
                    csize: size,
                    expected: neblock,
                    detail,
                })?;
        }
        off += size;
    }
    Ok(())
}
