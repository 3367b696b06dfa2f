//! Brick payload encodings and their CPU decoders. Float formats (f32, f16) keep OpenVDB's voxel
//! order `64·x + 8·y + z`; quantized formats (unorm8, BC4, BC7) are laid out as texture tiles
//! (slices along z of 8×8 texels) over a per-brick `[lo, hi]` range, value = lo + (hi − lo)·q/255.
//! Packed formats (1–7 bits a voxel) keep the voxel order as a bit stream, each code standing for
//! an 8-bit code ([`packed_code`]) read as unorm8 is.
//! BC encoding needs intel_tex_2 and lives in the cooker; decoding is here (pure Rust), so the
//! runtime, `eval` and the tests read every format.

use crate::bc;
use crate::format::{PayloadFormat, BRICK_VOXELS};

/// Largest finite f16 magnitude.
pub const F16_MAX: f32 = 65504.0;

/// Index of voxel (x, y, z) in a float brick (OpenVDB's leaf order).
#[inline]
pub fn vox_index(x: usize, y: usize, z: usize) -> usize {
    (x << 6) | (y << 3) | z
}

/// Index of voxel (x, y, z) in an unorm8 brick (texture order: slices of 8×8 texels).
#[inline]
pub fn tex_index(x: usize, y: usize, z: usize) -> usize {
    x + 8 * y + 64 * z
}

/// Appends float bricks (`values`: whole bricks in voxel order) to `out`.
pub fn encode_float(format: PayloadFormat, values: &[f32], out: &mut Vec<u8>) {
    match format {
        PayloadFormat::F32 => {
            if cfg!(target_endian = "little") {
                out.extend_from_slice(bytemuck::cast_slice(values));
            } else {
                out.reserve(values.len() * 4);
                for v in values {
                    out.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        PayloadFormat::F16 => {
            out.reserve(values.len() * 2);
            for v in values {
                out.extend_from_slice(&half::f16::from_f32(*v).to_bits().to_le_bytes());
            }
        }
        other => panic!(
            "encode_float called with the quantized format {}",
            other.name()
        ),
    }
}

/// The first value that `format` cannot store (beyond f16's range), if any.
pub fn check_representable(format: PayloadFormat, values: &[f32]) -> Option<f32> {
    match format {
        PayloadFormat::F16 => values
            .iter()
            .copied()
            .find(|v| half::f16::from_f32(*v).is_infinite()),
        _ => None,
    }
}

/// How far a GPU's *native* read of a texel in `format` may be from this crate's CPU
/// decode, at most, in 8-bit codes of the brick's quantization range (`(hi − lo)/255` each): the
/// worst block of the format. The cooker checks every brick against its own blocks
/// ([`read_codes_per_voxel`]); the runtime's tests take their tolerance from the same model.
/// `GpuVolume::exact()` is false wherever this is not 0. Where it comes from (`docs/payloads.md`,
/// "What a GPU may read"):
/// - **BC4**: [`bc4_block_read_codes`] at the widest endpoint gap with an inexact palette.
/// - **BC7**: D3D11 requires bit-exact BC7 decoding; Vulkan's conformance tests accept 1/255.
///   1 code (both GPUs measured read it exactly).
/// - **unorm8**: `c/255` is an exact conversion on every API (and decoded-BC textures hold the
///   CPU decode's codes): 0. f16 and f32 are buffers read as written: 0.
pub fn native_read_codes(format: PayloadFormat) -> f32 {
    match format {
        PayloadFormat::Bc4 => BC4_NATIVE_CODES,
        PayloadFormat::Bc7 => BC7_NATIVE_CODES,
        // Packed codes are integers the shader unpacks itself, then read as unorm8: exact.
        _ => 0.0,
    }
}

/// The 8-bit code a `bits`-bit packed code `q` stands for: `round(255·q / (2^bits − 1))`
/// (halves up). Every packed level is an unorm8 level, so a packed voxel is dequantized exactly
/// as an unorm8 one ([`dequantize`]) on the CPU and on any GPU; widths 1, 2, 4 (and 8) are
/// uniform, the others within half a code of uniform.
#[inline]
pub fn packed_code(q: u32, bits: u32) -> u8 {
    let levels = (1u32 << bits) - 1;
    ((510 * q + levels) / (2 * levels)) as u8
}

/// The `bits`-bit code of voxel `n` (voxel order) in a packed brick's bytes: bits
/// `[bits·n, bits·n + bits)` of the stream, little-endian (bit `k` is bit `k % 8` of byte `k / 8`:
/// the little-endian u32 words the GPU reads).
#[inline]
pub fn packed_get(bytes: &[u8], bits: u32, n: usize) -> u32 {
    let at = bits as usize * n;
    let (byte, shift) = (at / 8, at % 8);
    let mut w = bytes[byte] as u32;
    if let Some(&next) = bytes.get(byte + 1) {
        w |= (next as u32) << 8;
    }
    (w >> shift) & ((1u32 << bits) - 1)
}

/// A packed brick of `bits` bits a voxel (64·bits bytes) from float values in voxel order, over
/// `[lo, hi]`: each voxel takes the code whose level ([`packed_code`], [`dequantize`]) is
/// nearest its value (ties to the lower code).
pub fn encode_packed(values: &[f32], bits: u32, lo: f32, hi: f32) -> Vec<u8> {
    let levels = (1u32 << bits) - 1;
    let mut out = vec![0u8; 64 * bits as usize];
    for (n, &v) in values.iter().enumerate().take(BRICK_VOXELS) {
        let q = if hi <= lo {
            0
        } else {
            let t = ((v as f64 - lo as f64) / (hi as f64 - lo as f64) * levels as f64)
                .clamp(0.0, levels as f64);
            let below = t.floor() as u32;
            let above = (below + 1).min(levels);
            let err = |q: u32| (dequantize(packed_code(q, bits), lo, hi) as f64 - v as f64).abs();
            if err(above) < err(below) {
                above
            } else {
                below
            }
        };
        let at = bits as usize * n;
        let (byte, shift) = (at / 8, at % 8);
        let w = q << shift;
        out[byte] |= w as u8;
        if w >> 8 != 0 {
            out[byte + 1] |= (w >> 8) as u8;
        }
    }
    out
}

/// D3D11.3 §19.5.2: a BC4 interpolant may be `0.03·|red_0 − red_1|/255` off the float formula.
pub const BC4_GAP_SHARE: f32 = 0.03;
/// D3D11.3 §19.5.2's absolute term, `1/65535`, in codes.
pub const BC4_FLOAT_CODES: f32 = 255.0 / 65535.0;
/// A decoder that returns 8-bit codes (Mesa's does) rounds the formula to an integer in either
/// direction: up to one code even where the formula gives an integer.
pub const BC4_ROUND_CODES: f32 = 1.0;
/// The CPU decode (`bcdec`) rounds the formula to 8 bits: half a code where a palette entry is
/// not an integer.
pub const BC4_CPU_ROUND_CODES: f32 = 0.5;

/// Whether every entry of a BC4 palette with endpoints `red_0`, `red_1` is an integer code, so
/// every decoder's formula and the CPU decode agree exactly: `red_0 > red_1` with the gap a
/// multiple of 7, or `red_0 ≤ red_1` with the gap a multiple of 5.
pub fn bc4_palette_exact(red_0: u8, red_1: u8) -> bool {
    if red_0 > red_1 {
        (red_0 - red_1).is_multiple_of(7)
    } else {
        (red_1 - red_0).is_multiple_of(5)
    }
}

/// How far a GPU's read of any texel of this BC4 block may be from the CPU decode (any GPU
/// "within the BC precision rules", as the docs and the CLI say: one that meets D3D's rule), in
/// codes: D3D's rule (`BC4_GAP_SHARE` of the endpoint gap plus `BC4_FLOAT_CODES`), one code of an
/// integer decoder's rounding, and half a code of the CPU's own rounding unless the palette is
/// exact ([`bc4_palette_exact`]). 1.0039 codes for an exact palette with equal endpoints, 9.15 at
/// most (gap 255, inexact). Vulkan's conformance tests accept 8/255 on any texel; this model is
/// tighter for narrow blocks and looser for wide ones (`docs/payloads.md` says why, and what
/// lavapipe and an H100 read).
pub fn bc4_block_read_codes(block: &[u8; 8]) -> f32 {
    let (r0, r1) = (block[0], block[1]);
    let gap = r0.abs_diff(r1) as f32;
    let cpu = if bc4_palette_exact(r0, r1) {
        0.0
    } else {
        BC4_CPU_ROUND_CODES
    };
    BC4_ROUND_CODES + BC4_GAP_SHARE * gap + BC4_FLOAT_CODES + cpu
}

/// BC4's [`native_read_codes`]: [`bc4_block_read_codes`] of the worst block.
pub const BC4_NATIVE_CODES: f32 =
    BC4_ROUND_CODES + BC4_GAP_SHARE * 255.0 + BC4_FLOAT_CODES + BC4_CPU_ROUND_CODES;
/// BC7's [`native_read_codes`].
pub const BC7_NATIVE_CODES: f32 = 1.0;

/// For every voxel of one brick's bytes (voxel order), how far a GPU's native read may
/// be from [`decode_brick`], in codes of the brick's range: per block for BC4
/// ([`bc4_block_read_codes`]), [`native_read_codes`] for the other formats.
pub fn read_codes_per_voxel(format: PayloadFormat, bytes: &[u8], out: &mut [f32; BRICK_VOXELS]) {
    match format {
        PayloadFormat::Bc4 => {
            for (bi, block) in bytes.chunks_exact(8).enumerate() {
                let codes = bc4_block_read_codes(block.try_into().expect("8"));
                let (z, by, bx) = (bi / 4, (bi / 2) % 2, bi % 2);
                for t in 0..16 {
                    out[vox_index(4 * bx + t % 4, 4 * by + t / 4, z)] = codes;
                }
            }
        }
        f => out.fill(native_read_codes(f)),
    }
}

/// The most a GPU's native read of any voxel of this brick may be from
/// [`decode_brick`], in value units of a brick quantized over `quant`.
pub fn brick_read_slack(format: PayloadFormat, bytes: &[u8], quant: [f32; 2]) -> f32 {
    let codes = match format {
        PayloadFormat::Bc4 => bytes
            .chunks_exact(8)
            .map(|b| bc4_block_read_codes(b.try_into().expect("8")))
            .fold(0.0, f32::max),
        f => native_read_codes(f),
    };
    codes_to_value(codes, quant)
}

/// `codes` 8-bit codes of a brick quantized over `quant`, in value units.
pub fn codes_to_value(codes: f32, quant: [f32; 2]) -> f32 {
    codes * (quant[1] - quant[0]).max(0.0) / 255.0
}

/// [`native_read_codes`] in value units for a brick quantized over `[lo, hi]`: the worst brick
/// of `format` (a bound for every brick of it; [`brick_read_slack`] is the brick's own).
pub fn native_read_slack(format: PayloadFormat, quant: [f32; 2]) -> f32 {
    codes_to_value(native_read_codes(format), quant)
}

/// `v` quantized to 8 bits over `[lo, hi]` (round to nearest, clamped).
#[inline]
pub fn quantize(v: f32, lo: f32, hi: f32) -> u8 {
    if hi <= lo {
        return 0;
    }
    let t = ((v as f64 - lo as f64) / (hi as f64 - lo as f64) * 255.0).round();
    t.clamp(0.0, 255.0) as u8
}

/// The value an 8-bit code stands for over `[lo, hi]` (the formula the GPU uses too).
#[inline]
pub fn dequantize(q: u8, lo: f32, hi: f32) -> f32 {
    lo + (hi - lo) * (q as f32 / 255.0)
}

/// An unorm8 brick in texture order from float values in voxel order.
pub fn encode_unorm8(values: &[f32], lo: f32, hi: f32) -> [u8; BRICK_VOXELS] {
    let mut out = [0u8; BRICK_VOXELS];
    for x in 0..8 {
        for y in 0..8 {
            for z in 0..8 {
                out[tex_index(x, y, z)] = quantize(values[vox_index(x, y, z)], lo, hi);
            }
        }
    }
    out
}

/// Decodes one brick's bytes into values in voxel order (`64·x + 8·y + z`).
pub fn decode_brick(
    format: PayloadFormat,
    bytes: &[u8],
    quant: [f32; 2],
    out: &mut [f32; BRICK_VOXELS],
) {
    let [lo, hi] = quant;
    match format {
        PayloadFormat::F32 => {
            for (o, c) in out.iter_mut().zip(bytes.chunks_exact(4)) {
                *o = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
            }
        }
        PayloadFormat::F16 => {
            for (o, c) in out.iter_mut().zip(bytes.chunks_exact(2)) {
                *o = half::f16::from_bits(u16::from_le_bytes([c[0], c[1]])).to_f32();
            }
        }
        PayloadFormat::Unorm8 => {
            for x in 0..8 {
                for y in 0..8 {
                    for z in 0..8 {
                        out[vox_index(x, y, z)] = dequantize(bytes[tex_index(x, y, z)], lo, hi);
                    }
                }
            }
        }
        PayloadFormat::Bc4 => {
            for (bi, block) in bytes.chunks_exact(8).enumerate() {
                let texels = bc::decode_bc4_block(block.try_into().expect("8"));
                let (z, by, bx) = (bi / 4, (bi / 2) % 2, bi % 2);
                for (t, &q) in texels.iter().enumerate() {
                    let (x, y) = (4 * bx + t % 4, 4 * by + t / 4);
                    out[vox_index(x, y, z)] = dequantize(q, lo, hi);
                }
            }
        }
        PayloadFormat::Bc7 => {
            for (bi, block) in bytes.chunks_exact(16).enumerate() {
                let texels = bc::decode_bc7_block(block.try_into().expect("16"));
                let (s, by, bx) = (bi / 4, (bi / 2) % 2, bi % 2);
                for (t, rgba) in texels.iter().enumerate() {
                    let (x, y) = (4 * bx + t % 4, 4 * by + t / 4);
                    for (c, &q) in rgba.iter().enumerate() {
                        out[vox_index(x, y, 4 * s + c)] = dequantize(q, lo, hi);
                    }
                }
            }
        }
        f => {
            let bits = f.packed_bits().expect("packed");
            for (n, o) in out.iter_mut().enumerate() {
                *o = dequantize(packed_code(packed_get(bytes, bits, n), bits), lo, hi);
            }
        }
    }
}

/// Decodes voxel (x, y, z) of one brick's bytes.
pub fn decode_voxel(
    format: PayloadFormat,
    bytes: &[u8],
    quant: [f32; 2],
    x: usize,
    y: usize,
    z: usize,
) -> f32 {
    let [lo, hi] = quant;
    match format {
        PayloadFormat::F32 => {
            let i = vox_index(x, y, z) * 4;
            f32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]])
        }
        PayloadFormat::F16 => {
            let i = vox_index(x, y, z) * 2;
            half::f16::from_bits(u16::from_le_bytes([bytes[i], bytes[i + 1]])).to_f32()
        }
        PayloadFormat::Unorm8 => dequantize(bytes[tex_index(x, y, z)], lo, hi),
        PayloadFormat::Bc4 => {
            let bi = z * 4 + (y / 4) * 2 + x / 4;
            let texels = bc::decode_bc4_block(bytes[bi * 8..bi * 8 + 8].try_into().expect("8"));
            dequantize(texels[(y % 4) * 4 + x % 4], lo, hi)
        }
        PayloadFormat::Bc7 => {
            let bi = (z / 4) * 4 + (y / 4) * 2 + x / 4;
            let texels = bc::decode_bc7_block(bytes[bi * 16..bi * 16 + 16].try_into().expect("16"));
            dequantize(texels[(y % 4) * 4 + x % 4][z % 4], lo, hi)
        }
        f => {
            let bits = f.packed_bits().expect("packed");
            let q = packed_get(bytes, bits, vox_index(x, y, z));
            dequantize(packed_code(q, bits), lo, hi)
        }
    }
}
