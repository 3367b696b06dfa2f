//! Brick payload encodings: f32 (bit exact) and f16. The encoder stage is a function of the
//! format so later formats (unorm8, BC4, BC7) plug in beside these.

use crate::format::{PayloadFormat, BRICK_VOXELS};

/// Largest finite f16 magnitude.
pub const F16_MAX: f32 = 65504.0;

/// Appends `values` (a whole number of bricks) to `out` in `format`. Values must be
/// representable (see [`check_representable`]).
pub fn encode(format: PayloadFormat, values: &[f32], out: &mut Vec<u8>) {
    match format {
        PayloadFormat::F32 => {
            out.reserve(values.len() * 4);
            for v in values {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        PayloadFormat::F16 => {
            out.reserve(values.len() * 2);
            for v in values {
                out.extend_from_slice(&half::f16::from_f32(*v).to_bits().to_le_bytes());
            }
        }
    }
}

/// The first value that `format` cannot store (beyond f16's range), if any.
pub fn check_representable(format: PayloadFormat, values: &[f32]) -> Option<f32> {
    match format {
        PayloadFormat::F32 => None,
        // Values that round to infinity in f16 (≥ 65520 in magnitude).
        PayloadFormat::F16 => values
            .iter()
            .copied()
            .find(|v| half::f16::from_f32(*v).is_infinite()),
    }
}

/// Decodes brick `b` of a payload into `out`.
pub fn decode_brick(
    format: PayloadFormat,
    payload: &[u8],
    b: usize,
    out: &mut [f32; BRICK_VOXELS],
) {
    let bpv = format.bytes_per_voxel();
    let bytes = &payload[b * BRICK_VOXELS * bpv..(b + 1) * BRICK_VOXELS * bpv];
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
    }
}

/// Decodes voxel `v` of brick `b`.
pub fn decode_voxel(format: PayloadFormat, payload: &[u8], b: usize, v: usize) -> f32 {
    let bpv = format.bytes_per_voxel();
    let i = (b * BRICK_VOXELS + v) * bpv;
    match format {
        PayloadFormat::F32 => {
            f32::from_le_bytes([payload[i], payload[i + 1], payload[i + 2], payload[i + 3]])
        }
        PayloadFormat::F16 => {
            half::f16::from_bits(u16::from_le_bytes([payload[i], payload[i + 1]])).to_f32()
        }
    }
}
