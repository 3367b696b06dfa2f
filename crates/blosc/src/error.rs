//! Error type of the blosc decoder.
//!
//! Why this file exists: every check the decoder makes has its own variant,
//! carrying the offending numbers, so a corrupt `.vdb` can be diagnosed from
//! the message alone.  Offsets in messages are byte offsets from the start of
//! the frame (header at 0..16, block starts table at 16..16+4*nblocks).

use crate::Codec;
use std::fmt;

/// Why a blosc frame could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum BloscError {
    /// Fewer than 16 bytes: no room for the header.
    HeaderTruncated { len: usize },
    /// Header byte 0 is not a c-blosc 1.x format version.
    UnsupportedVersion { version: u8 },
    /// Header byte 1 is not the codec format version this decoder knows.
    UnsupportedCodecVersion { codec: Codec, version: u8 },
    /// Flags bits 5-7 name no known codec.
    UnknownCodec { code: u8 },
    /// Flags bit 3 (reserved by c-blosc 1.x) is set.
    ReservedFlag { flags: u8 },
    /// Header byte 3 (typesize) is 0.
    ZeroTypesize,
    /// `nbytes` is negative or above c-blosc's maximum buffer size.
    BadNbytes { nbytes: i64 },
    /// `cbytes` is smaller than the header.
    BadCbytes { cbytes: i64 },
    /// `blocksize` is not in `1..=min(nbytes, MAX_BLOCKSIZE)`.
    BadBlocksize { blocksize: i64, nbytes: usize },
    /// `cbytes` claims more bytes than the buffer holds.
    FrameTruncated { cbytes: usize, len: usize },
    /// The destination slice is not exactly `nbytes` long.
    OutputSizeMismatch { nbytes: usize, dst_len: usize },
    /// `nbytes` exceeds the caller's limit.
    TooLarge { nbytes: usize, max_len: usize },
    /// A memcpyed frame whose `cbytes` is not `nbytes + 16`.
    MemcpyedSizeMismatch { nbytes: usize, cbytes: usize },
    /// The block starts table does not fit in `cbytes`.
    BstartsTruncated { nblocks: usize, cbytes: usize },
    /// A block start points outside the frame.
    BlockStartOutOfBounds {
        block: usize,
        start: i64,
        cbytes: usize,
    },
    /// A stream's size field, or the stream it announces, lies outside the frame.
    StreamOutOfBounds {
        block: usize,
        stream: usize,
        offset: usize,
        size: Option<i64>,
        cbytes: usize,
    },
    /// A split block whose size is not a multiple of the typesize.
    UnevenSplit {
        block: usize,
        bsize: usize,
        typesize: usize,
    },
    /// The codec rejected a stream or produced the wrong number of bytes.
    Codec {
        codec: Codec,
        block: usize,
        stream: usize,
        csize: usize,
        expected: usize,
        detail: String,
    },
}

impl fmt::Display for BloscError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use BloscError::*;
        match self {
            HeaderTruncated { len } => {
                write!(
                    f,
                    "blosc frame of {len} bytes is shorter than the 16-byte header"
                )
            }
            UnsupportedVersion { version } => {
                write!(
                    f,
                    "unsupported blosc format version {version} (expected 1 or 2)"
                )
            }
            UnsupportedCodecVersion { codec, version } => write!(
                f,
                "unsupported {codec} format version {version} in blosc header (expected 1)"
            ),
            UnknownCodec { code } => write!(f, "unknown blosc codec code {code} in header flags"),
            ReservedFlag { flags } => write!(
                f,
                "blosc header flags {flags:#04x} set the reserved bit 0x08"
            ),
            ZeroTypesize => write!(f, "blosc header typesize is 0"),
            BadNbytes { nbytes } => write!(
                f,
                "blosc header nbytes {nbytes} is outside 0..={}",
                crate::MAX_BUFFERSIZE
            ),
            BadCbytes { cbytes } => {
                write!(
                    f,
                    "blosc header cbytes {cbytes} is smaller than the 16-byte header"
                )
            }
            BadBlocksize { blocksize, nbytes } => write!(
                f,
                "blosc header blocksize {blocksize} is outside 1..=min(nbytes {nbytes}, {})",
                crate::MAX_BLOCKSIZE
            ),
            FrameTruncated { cbytes, len } => write!(
                f,
                "blosc header cbytes {cbytes} exceeds the {len} bytes available"
            ),
            OutputSizeMismatch { nbytes, dst_len } => write!(
                f,
                "blosc frame decodes to {nbytes} bytes but the destination holds {dst_len}"
            ),
            TooLarge { nbytes, max_len } => write!(
                f,
                "blosc frame decodes to {nbytes} bytes, more than the limit of {max_len}"
            ),
            MemcpyedSizeMismatch { nbytes, cbytes } => write!(
                f,
                "memcpyed blosc frame has cbytes {cbytes}, expected nbytes {nbytes} + 16"
            ),
            BstartsTruncated { nblocks, cbytes } => write!(
                f,
                "blosc block starts table for {nblocks} blocks does not fit in cbytes {cbytes}"
            ),
            BlockStartOutOfBounds {
                block,
                start,
                cbytes,
            } => write!(
                f,
                "blosc block {block} starts at offset {start}, outside the {cbytes}-byte frame"
            ),
            StreamOutOfBounds {
                block,
                stream,
                offset,
                size: None,
                cbytes,
            } => write!(
                f,
                "blosc block {block} stream {stream}: size field at offset {offset} \
                 runs past the {cbytes}-byte frame"
            ),
            StreamOutOfBounds {
                block,
                stream,
                offset,
                size: Some(size),
                cbytes,
            } => write!(
                f,
                "blosc block {block} stream {stream}: compressed size {size} (field at offset \
                 {offset}) runs past the {cbytes}-byte frame"
            ),
            UnevenSplit {
                block,
                bsize,
                typesize,
            } => write!(
                f,
                "blosc block {block} of {bsize} bytes cannot be split into {typesize} equal streams"
            ),
            Codec {
                codec,
                block,
                stream,
                csize,
                expected,
                detail,
            } => write!(
                f,
                "blosc block {block} stream {stream}: {codec} failed to decode {csize} bytes \
                 into {expected}: {detail}"
            ),
        }
    }
}

impl std::error::Error for BloscError {}
