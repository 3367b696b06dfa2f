//! Block-compression decoders for the two GPU formats the asset's payload can use: BC4 (one
//! unsigned 8-bit channel per texel, 8 bytes per 4×4 block) and BC7 (RGBA8, 16 bytes per block).
//!
//! The cooker needs them to measure what its encoder actually produced (error reports, `eval`),
//! and the CPU sampler needs them to read compressed bricks as a GPU would. They wrap `bcdec_rs`
//! (safe, pure Rust), chosen after checking it (see `docs/decisions.md`): bit-identical to an
//! independent decoder written from the specification over 2 M random BC7 blocks and 32 M BC4
//! texels, and to hand-computed blocks of every kind in `tests/bc.rs`.
//!
//! Texels come out row-major: texel `(x, y)` of the block is at index `y * 4 + x`. Any bytes are
//! accepted: BC7's reserved mode (first byte 0) decodes to transparent black.

/// One 8-byte BC4 (unsigned) block -> 16 texels, row-major.
pub fn decode_bc4_block(block: &[u8; 8]) -> [u8; 16] {
    let mut out = [0u8; 16];
    bcdec_rs::bc4(block, &mut out, 4, false);
    out
}

/// One 16-byte BC7 block -> 16 RGBA texels, row-major.
pub fn decode_bc7_block(block: &[u8; 16]) -> [[u8; 4]; 16] {
    let mut flat = [0u8; 64];
    bcdec_rs::bc7(block, &mut flat, 16);
    let mut out = [[0u8; 4]; 16];
    for (o, c) in out.iter_mut().zip(flat.chunks_exact(4)) {
        o.copy_from_slice(c);
    }
    out
}
