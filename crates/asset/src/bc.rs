//! Block-compression decoders for the two GPU formats the asset's payload can use: BC4 (one
//! unsigned 8-bit channel per texel, 8 bytes per 4×4 block) and BC7 (RGBA8, 16 bytes per block).
//!
//! The cooker needs them to measure what its encoder actually produced (error reports, `eval`),
//! and the CPU sampler needs them to read compressed bricks exactly as a GPU would. They are
//! written here from the public format specifications (D3D11 functional spec / Khronos Data Format
//! spec) so that this crate stays pure Rust with no C dependency.
//!
//! Both decoders accept any bytes and never panic: BC7's reserved mode (first byte 0) decodes to
//! transparent black, as the specification requires.
//!
//! Texels come out row-major: texel `(x, y)` of the block is at index `y * 4 + x`.

/// One 8-byte BC4 (unsigned) block -> 16 texels, row-major (texel (x, y) at y*4 + x).
///
/// The specification defines the palette in real numbers (`r2 = (6·r0 + 1·r1) / 7`, …); a GPU
/// returns that value (up to its own rounding) as a float. Here each palette entry is that exact
/// value rounded to the nearest integer, so it is never more than 0.5/255 away from the spec.
pub fn decode_bc4_block(block: &[u8; 8]) -> [u8; 16] {
    let r0 = u32::from(block[0]);
    let r1 = u32::from(block[1]);
    let mut palette = [0u8; 8];
    palette[0] = r0 as u8;
    palette[1] = r1 as u8;
    if r0 > r1 {
        // Six interpolated values: ((7 - i)·r0 + i·r1) / 7 for i = 1..=6, rounded to nearest
        // (k / 7 is never exactly halfway between two integers, so `+ 3` rounds correctly).
        for i in 1..7u32 {
            palette[i as usize + 1] = (((7 - i) * r0 + i * r1 + 3) / 7) as u8;
        }
    } else {
        // Four interpolated values ((5 - i)·r0 + i·r1) / 5, then the constants 0 and 255.
        for i in 1..5u32 {
            palette[i as usize + 1] = (((5 - i) * r0 + i * r1 + 2) / 5) as u8;
        }
        palette[6] = 0;
        palette[7] = 255;
    }
    let mut bits = 0u64;
    for (i, &b) in block[2..].iter().enumerate() {
        bits |= u64::from(b) << (8 * i);
    }
    let mut out = [0u8; 16];
    for (i, texel) in out.iter_mut().enumerate() {
        *texel = palette[((bits >> (3 * i)) & 7) as usize];
    }
    out
}

/// The fixed layout of one BC7 mode.
struct Mode {
    /// Number of subsets (1–3).
    subsets: usize,
    partition_bits: u32,
    rotation_bits: u32,
    index_selection_bits: u32,
    color_bits: u32,
    /// 0 = the mode has no alpha endpoints (alpha is 255).
    alpha_bits: u32,
    /// One p-bit per endpoint.
    endpoint_pbits: bool,
    /// One p-bit per subset, shared by its two endpoints.
    shared_pbits: bool,
    index_bits: u32,
    /// Bits of the second index set (modes 4 and 5), 0 if none.
    index2_bits: u32,
}

const MODES: [Mode; 8] = [
    Mode {
        subsets: 3,
        partition_bits: 4,
        rotation_bits: 0,
        index_selection_bits: 0,
        color_bits: 4,
        alpha_bits: 0,
        endpoint_pbits: true,
        shared_pbits: false,
        index_bits: 3,
        index2_bits: 0,
    },
    Mode {
        subsets: 2,
        partition_bits: 6,
        rotation_bits: 0,
        index_selection_bits: 0,
        color_bits: 6,
        alpha_bits: 0,
        endpoint_pbits: false,
        shared_pbits: true,
        index_bits: 3,
        index2_bits: 0,
    },
    Mode {
        subsets: 3,
        partition_bits: 6,
        rotation_bits: 0,
        index_selection_bits: 0,
        color_bits: 5,
        alpha_bits: 0,
        endpoint_pbits: false,
        shared_pbits: false,
        index_bits: 2,
        index2_bits: 0,
    },
    Mode {
        subsets: 2,
        partition_bits: 6,
        rotation_bits: 0,
        index_selection_bits: 0,
        color_bits: 7,
        alpha_bits: 0,
        endpoint_pbits: true,
        shared_pbits: false,
        index_bits: 2,
        index2_bits: 0,
    },
    Mode {
        subsets: 1,
        partition_bits: 0,
        rotation_bits: 2,
        index_selection_bits: 1,
        color_bits: 5,
        alpha_bits: 6,
        endpoint_pbits: false,
        shared_pbits: false,
        index_bits: 2,
        index2_bits: 3,
    },
    Mode {
        subsets: 1,
        partition_bits: 0,
        rotation_bits: 2,
        index_selection_bits: 0,
        color_bits: 7,
        alpha_bits: 8,
        endpoint_pbits: false,
        shared_pbits: false,
        index_bits: 2,
        index2_bits: 2,
    },
    Mode {
        subsets: 1,
        partition_bits: 0,
        rotation_bits: 0,
        index_selection_bits: 0,
        color_bits: 7,
        alpha_bits: 7,
        endpoint_pbits: true,
        shared_pbits: false,
        index_bits: 4,
        index2_bits: 0,
    },
    Mode {
        subsets: 2,
        partition_bits: 6,
        rotation_bits: 0,
        index_selection_bits: 0,
        color_bits: 5,
        alpha_bits: 5,
        endpoint_pbits: true,
        shared_pbits: false,
        index_bits: 2,
        index2_bits: 0,
    },
];

/// Two-subset partitions: bit `i` is the subset of texel `i`.
const PARTITIONS2: [u16; 64] = [
    0xCCCC, 0x8888, 0xEEEE, 0xECC8, 0xC880, 0xFEEC, 0xFEC8, 0xEC80, //
    0xC800, 0xFFEC, 0xFE80, 0xE800, 0xFFE8, 0xFF00, 0xFFF0, 0xF000, //
    0xF710, 0x008E, 0x7100, 0x08CE, 0x008C, 0x7310, 0x3100, 0x8CCE, //
    0x088C, 0x3110, 0x6666, 0x366C, 0x17E8, 0x0FF0, 0x718E, 0x399C, //
    0xAAAA, 0xF0F0, 0x5A5A, 0x33CC, 0x3C3C, 0x55AA, 0x9696, 0xA55A, //
    0x73CE, 0x13C8, 0x324C, 0x3BDC, 0x6996, 0xC33C, 0x9966, 0x0660, //
    0x0272, 0x04E4, 0x4E40, 0x2720, 0xC936, 0x936C, 0x39C6, 0x639C, //
    0x9336, 0x9CC6, 0x817E, 0xE718, 0xCCF0, 0x0FCC, 0x7744, 0xEE22, //
];

/// Three-subset partitions: bits `2i..2i+2` are the subset of texel `i`.
const PARTITIONS3: [u32; 64] = [
    0xAA685050, 0x6A5A5040, 0x5A5A4200, 0x5450A0A8, //
    0xA5A50000, 0xA0A05050, 0x5555A0A0, 0x5A5A5050, //
    0xAA550000, 0xAA555500, 0xAAAA5500, 0x90909090, //
    0x94949494, 0xA4A4A4A4, 0xA9A59450, 0x2A0A4250, //
    0xA5945040, 0x0A425054, 0xA5A5A500, 0x55A0A0A0, //
    0xA8A85454, 0x6A6A4040, 0xA4A45000, 0x1A1A0500, //
    0x0050A4A4, 0xAAA59090, 0x14696914, 0x69691400, //
    0xA08585A0, 0xAA821414, 0x50A4A450, 0x6A5A0200, //
    0xA9A58000, 0x5090A0A8, 0xA8A09050, 0x24242424, //
    0x00AA5500, 0x24924924, 0x24499224, 0x50A50A50, //
    0x500AA550, 0xAAAA4444, 0x66660000, 0xA5A0A5A0, //
    0x50A050A0, 0x69286928, 0x44AAAA44, 0x66666600, //
    0xAA444444, 0x54A854A8, 0x95809580, 0x96969600, //
    0xA85454A8, 0x80959580, 0xAA141414, 0x96960000, //
    0xAAAA1414, 0xA05050A0, 0xA0A5A5A0, 0x96000000, //
    0x40804080, 0xA9A8A9A8, 0xAAAAAA44, 0x2A4A5254, //
];

/// Anchor texel of subset 1 in the two-subset partitions (subset 0's anchor is always texel 0).
const ANCHOR2: [u8; 64] = [
    15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, //
    15, 2, 8, 2, 2, 8, 8, 15, 2, 8, 2, 2, 8, 8, 2, 2, //
    15, 15, 6, 8, 2, 8, 15, 15, 2, 8, 2, 2, 2, 15, 15, 6, //
    6, 2, 6, 8, 15, 15, 2, 2, 15, 15, 15, 15, 15, 2, 2, 15, //
];

/// Anchor texel of subset 1 in the three-subset partitions.
const ANCHOR3_1: [u8; 64] = [
    3, 3, 15, 15, 8, 3, 15, 15, 8, 8, 6, 6, 6, 5, 3, 3, //
    3, 3, 8, 15, 3, 3, 6, 10, 5, 8, 8, 6, 8, 5, 15, 15, //
    8, 15, 3, 5, 6, 10, 8, 15, 15, 3, 15, 5, 15, 15, 15, 15, //
    3, 15, 5, 5, 5, 8, 5, 10, 5, 10, 8, 13, 15, 12, 3, 3, //
];

/// Anchor texel of subset 2 in the three-subset partitions.
const ANCHOR3_2: [u8; 64] = [
    15, 8, 8, 3, 15, 15, 3, 8, 15, 15, 15, 15, 15, 15, 15, 8, //
    15, 8, 15, 3, 15, 8, 15, 8, 3, 15, 6, 10, 15, 15, 10, 8, //
    15, 3, 15, 10, 10, 8, 9, 10, 6, 15, 8, 15, 3, 6, 6, 8, //
    15, 3, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 3, 15, 15, 8, //
];

const WEIGHTS2: [u32; 4] = [0, 21, 43, 64];
const WEIGHTS3: [u32; 8] = [0, 9, 18, 27, 37, 46, 55, 64];
const WEIGHTS4: [u32; 16] = [0, 4, 9, 13, 17, 21, 26, 30, 34, 38, 43, 47, 51, 55, 60, 64];

/// Reads the block's 128 bits from least significant upwards.
struct BitReader {
    bits: u128,
    pos: u32,
}

impl BitReader {
    fn read(&mut self, count: u32) -> u32 {
        // Every mode's fields add up to exactly 128 bits, so `pos + count <= 128` always holds;
        // the checked shift keeps this total even if that were ever violated.
        let value = self.bits.checked_shr(self.pos).unwrap_or(0);
        self.pos += count;
        (value & ((1u128 << count) - 1)) as u32
    }
}

/// Expands a `bits`-bit value (4..=8) to 8 bits by replicating its high bits into the low ones.
fn unquantize(value: u32, bits: u32) -> u8 {
    let v = value << (8 - bits);
    (v | (v >> bits)) as u8
}

fn interpolate(e0: u8, e1: u8, index: u32, index_bits: u32) -> u8 {
    let w = match index_bits {
        2 => WEIGHTS2[index as usize & 3],
        3 => WEIGHTS3[index as usize & 7],
        _ => WEIGHTS4[index as usize & 15],
    };
    (((64 - w) * u32::from(e0) + w * u32::from(e1) + 32) >> 6) as u8
}

/// One 16-byte BC7 block -> 16 RGBA texels, row-major.
pub fn decode_bc7_block(block: &[u8; 16]) -> [[u8; 4]; 16] {
    let mode_number = block[0].trailing_zeros() as usize;
    if mode_number >= 8 {
        // Reserved mode: the specification says such a block decodes to 0 in every channel.
        return [[0; 4]; 16];
    }
    let mode = &MODES[mode_number];
    let mut r = BitReader {
        bits: u128::from_le_bytes(*block),
        pos: mode_number as u32 + 1,
    };
    let partition = r.read(mode.partition_bits) as usize;
    let rotation = r.read(mode.rotation_bits);
    let index_selection = r.read(mode.index_selection_bits);

    // endpoints[2 * subset + end][channel], still quantized.
    let endpoint_count = 2 * mode.subsets;
    let mut raw = [[0u32; 4]; 6];
    for channel in 0..3 {
        for endpoint in raw.iter_mut().take(endpoint_count) {
            endpoint[channel] = r.read(mode.color_bits);
        }
    }
    if mode.alpha_bits > 0 {
        for endpoint in raw.iter_mut().take(endpoint_count) {
            endpoint[3] = r.read(mode.alpha_bits);
        }
    }
    let mut pbits = [0u32; 6];
    if mode.endpoint_pbits {
        for p in pbits.iter_mut().take(endpoint_count) {
            *p = r.read(1);
        }
    } else if mode.shared_pbits {
        for subset in 0..mode.subsets {
            let p = r.read(1);
            pbits[2 * subset] = p;
            pbits[2 * subset + 1] = p;
        }
    }
    let has_pbit = u32::from(mode.endpoint_pbits || mode.shared_pbits);
    let mut endpoints = [[0u8; 4]; 6];
    for e in 0..endpoint_count {
        for channel in 0..3 {
            let v = (raw[e][channel] << has_pbit) | pbits[e];
            endpoints[e][channel] = unquantize(v, mode.color_bits + has_pbit);
        }
        endpoints[e][3] = if mode.alpha_bits > 0 {
            let v = (raw[e][3] << has_pbit) | pbits[e];
            unquantize(v, mode.alpha_bits + has_pbit)
        } else {
            255
        };
    }

    let subset_of = |texel: usize| -> usize {
        match mode.subsets {
            1 => 0,
            2 => usize::from((PARTITIONS2[partition] >> texel) & 1 == 1),
            _ => ((PARTITIONS3[partition] >> (2 * texel)) & 3) as usize,
        }
    };
    let is_anchor = |texel: usize| -> bool {
        texel == 0
            || match mode.subsets {
                2 => usize::from(ANCHOR2[partition]) == texel,
                3 => {
                    usize::from(ANCHOR3_1[partition]) == texel
                        || usize::from(ANCHOR3_2[partition]) == texel
                }
                _ => false,
            }
    };

    // Anchor texels store their index with one bit fewer (its top bit is implied 0).
    let mut indices = [0u32; 16];
    for (texel, index) in indices.iter_mut().enumerate() {
        *index = r.read(mode.index_bits - u32::from(is_anchor(texel)));
    }
    let mut indices2 = [0u32; 16];
    if mode.index2_bits > 0 {
        for (texel, index) in indices2.iter_mut().enumerate() {
            *index = r.read(mode.index2_bits - u32::from(texel == 0));
        }
    }

    let mut out = [[0u8; 4]; 16];
    for (texel, rgba) in out.iter_mut().enumerate() {
        let subset = subset_of(texel);
        let (e0, e1) = (endpoints[2 * subset], endpoints[2 * subset + 1]);
        // Which index set (and width) drives colour and alpha.
        let (color_index, color_bits, alpha_index, alpha_bits) = if mode.index2_bits == 0 {
            (
                indices[texel],
                mode.index_bits,
                indices[texel],
                mode.index_bits,
            )
        } else if index_selection == 0 {
            (
                indices[texel],
                mode.index_bits,
                indices2[texel],
                mode.index2_bits,
            )
        } else {
            (
                indices2[texel],
                mode.index2_bits,
                indices[texel],
                mode.index_bits,
            )
        };
        for channel in 0..3 {
            rgba[channel] = interpolate(e0[channel], e1[channel], color_index, color_bits);
        }
        rgba[3] = interpolate(e0[3], e1[3], alpha_index, alpha_bits);
        match rotation {
            1 => rgba.swap(0, 3),
            2 => rgba.swap(1, 3),
            3 => rgba.swap(2, 3),
            _ => {}
        }
    }
    out
}
