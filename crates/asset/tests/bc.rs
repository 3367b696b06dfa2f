//! Checks the BC4 and BC7 block decoders against the format specification, not against another
//! decoder: BC4 palettes are recomputed in floating point from the D3D formula, and BC7 blocks are
//! assembled bit by bit in this file with texels worked out by hand from the spec's tables
//! (endpoint expansion, p-bits, partitions, anchor indices, index selection, rotation).

use vdbcook_asset::bc::{decode_bc4_block, decode_bc7_block};
use vdbcook_testkit::XorShift;

// ---------------------------------------------------------------------------------------------
// BC4

/// Packs 16 three-bit indices (texel 0 in the lowest bits) behind the two endpoints.
fn bc4_block(r0: u8, r1: u8, indices: [u8; 16]) -> [u8; 8] {
    let mut bits = 0u64;
    for (i, &idx) in indices.iter().enumerate() {
        bits |= u64::from(idx & 7) << (3 * i);
    }
    let mut block = [0u8; 8];
    block[0] = r0;
    block[1] = r1;
    block[2..].copy_from_slice(&bits.to_le_bytes()[..6]);
    block
}

/// The D3D / Vulkan palette entry `index` as a real number (0..=255).
fn bc4_spec_value(r0: u8, r1: u8, index: u8) -> f64 {
    let (a, b) = (f64::from(r0), f64::from(r1));
    match (r0 > r1, index) {
        (_, 0) => a,
        (_, 1) => b,
        (true, i) => (f64::from(8 - i) * a + f64::from(i - 1) * b) / 7.0,
        (false, 6) => 0.0,
        (false, 7) => 255.0,
        (false, i) => (f64::from(6 - i) * a + f64::from(i - 1) * b) / 5.0,
    }
}

const ALL_INDICES: [u8; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 7, 6, 5, 4, 3, 2, 1, 0];

#[test]
fn bc4_index_bits_are_little_endian_three_bit_fields() {
    // Indices 0..7 for texels 0..7 pack to 0xFAC688: bytes 88 C6 FA, twice.
    let block = [200, 10, 0x88, 0xC6, 0xFA, 0x88, 0xC6, 0xFA];
    assert_eq!(
        block,
        bc4_block(200, 10, [0, 1, 2, 3, 4, 5, 6, 7, 0, 1, 2, 3, 4, 5, 6, 7])
    );
    // r0 > r1: 200, 10, then (6·200 + 10)/7 = 172.86, (5·200 + 20)/7 = 145.71, 118.57, 91.43,
    // 64.29, 37.14 — rounded to the nearest integer.
    let palette = [200, 10, 173, 146, 119, 91, 64, 37];
    let texels = decode_bc4_block(&block);
    for (t, &v) in texels.iter().enumerate() {
        assert_eq!(v, palette[t % 8], "texel {t}");
    }
}

#[test]
fn bc4_six_value_mode_hand_computed() {
    let texels = decode_bc4_block(&bc4_block(255, 0, ALL_INDICES));
    // 255·k/7 for k = 6..1: 218.57, 182.14, 145.71, 109.29, 72.86, 36.43.
    let palette = [255, 0, 219, 182, 146, 109, 73, 36];
    for (t, &v) in texels.iter().enumerate() {
        assert_eq!(v, palette[ALL_INDICES[t] as usize], "texel {t}");
    }
}

#[test]
fn bc4_four_value_mode_hand_computed() {
    let texels = decode_bc4_block(&bc4_block(10, 200, ALL_INDICES));
    // r0 <= r1: 10, 200, (4·10 + 200)/5 = 48, (30 + 400)/5 = 86, 124, 162, then 0 and 255.
    let palette = [10, 200, 48, 86, 124, 162, 0, 255];
    for (t, &v) in texels.iter().enumerate() {
        assert_eq!(v, palette[ALL_INDICES[t] as usize], "texel {t}");
    }
    // Equal endpoints take the four-value branch: interpolants equal r0, plus 0 and 255.
    let texels = decode_bc4_block(&bc4_block(100, 100, ALL_INDICES));
    let palette = [100, 100, 100, 100, 100, 100, 0, 255];
    for (t, &v) in texels.iter().enumerate() {
        assert_eq!(v, palette[ALL_INDICES[t] as usize], "texel {t}");
    }
}

#[test]
fn bc4_every_endpoint_pair_is_within_half_a_unit_of_the_spec() {
    for r0 in 0..=255u8 {
        for r1 in 0..=255u8 {
            let texels = decode_bc4_block(&bc4_block(r0, r1, ALL_INDICES));
            for (t, &v) in texels.iter().enumerate() {
                let exact = bc4_spec_value(r0, r1, ALL_INDICES[t]);
                assert!(
                    (f64::from(v) - exact).abs() <= 0.5,
                    "r0 {r0} r1 {r1} index {}: {v} vs {exact}",
                    ALL_INDICES[t]
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// BC7

/// Assembles a block from fields, least significant bit first (the spec's bit order).
#[derive(Default)]
struct BlockWriter {
    bits: u128,
    len: u32,
}

impl BlockWriter {
    fn put(&mut self, value: u32, count: u32) -> &mut Self {
        assert!(value < (1 << count), "{value} does not fit {count} bits");
        self.bits |= u128::from(value) << self.len;
        self.len += count;
        self
    }
    fn finish(&self) -> [u8; 16] {
        assert_eq!(self.len, 128, "block layout must fill 128 bits");
        self.bits.to_le_bytes()
    }
}

/// `((64 - w)·e0 + w·e1 + 32) >> 6`, the spec's interpolation.
fn lerp(e0: u8, e1: u8, w: u32) -> u8 {
    (((64 - w) * u32::from(e0) + w * u32::from(e1) + 32) >> 6) as u8
}

const W2: [u32; 4] = [0, 21, 43, 64];
const W3: [u32; 8] = [0, 9, 18, 27, 37, 46, 55, 64];
const W4: [u32; 16] = [0, 4, 9, 13, 17, 21, 26, 30, 34, 38, 43, 47, 51, 55, 60, 64];

fn mode6_block() -> [u8; 16] {
    let mut w = BlockWriter::default();
    w.put(1 << 6, 7);
    // R0 R1 G0 G1 B0 B1 A0 A1 (7 bits), P0 P1.
    for v in [64, 127, 0, 100, 10, 20, 127, 0] {
        w.put(v, 7);
    }
    w.put(1, 1).put(0, 1);
    // Index of texel t is t; texel 0 is the anchor (3 bits).
    w.put(0, 3);
    for t in 1..16 {
        w.put(t, 4);
    }
    w.finish()
}

#[test]
fn bc7_mode6_hand_computed() {
    let block = mode6_block();
    // Layout check by hand: mode bit 6 -> 0x40; byte 1 = R0 >> 1 (0x20) | low 2 bits of R1 << 6.
    assert_eq!(block[0], 0x40);
    assert_eq!(block[1], 0xE0);
    let texels = decode_bc7_block(&block);
    // Endpoints with p-bits: (v << 1 | p): R 129/254, G 1/200, B 21/40, A 255/0.
    assert_eq!(texels[0], [129, 1, 21, 255]);
    assert_eq!(texels[15], [254, 200, 40, 0]);
    // Texel 5, weight 21: R (43·129 + 21·254 + 32) >> 6 = 170, G 66, B 27, A 171.
    assert_eq!(texels[5], [170, 66, 27, 171]);
    // Texel 8, weight 34: R (30·129 + 34·254 + 32) >> 6 = 195, G 107, B 31, A 120.
    assert_eq!(texels[8], [195, 107, 31, 120]);
    let (e0, e1) = ([129, 1, 21, 255], [254, 200, 40, 0]);
    for (t, texel) in texels.iter().enumerate() {
        for c in 0..4 {
            assert_eq!(texel[c], lerp(e0[c], e1[c], W4[t]), "texel {t} channel {c}");
        }
    }
}

fn mode5_block(rotation: u32) -> [u8; 16] {
    let mut w = BlockWriter::default();
    w.put(1 << 5, 6).put(rotation, 2);
    for v in [127, 0, 64, 32, 1, 100] {
        w.put(v, 7);
    }
    w.put(200, 8).put(50, 8);
    // Colour index of texel t: t % 4; alpha index: t / 4 (texel 0: one bit each).
    w.put(0, 1);
    for t in 1..16 {
        w.put(t % 4, 2);
    }
    w.put(0, 1);
    for t in 1..16 {
        w.put(t / 4, 2);
    }
    w.finish()
}

#[test]
fn bc7_mode5_hand_computed_with_rotation() {
    // Endpoints: 7-bit colour v -> (v << 1) | (v >> 6): R 255/0, G 129/64, B 2/201; alpha 200/50.
    let texels = decode_bc7_block(&mode5_block(0));
    assert_eq!(texels[0], [255, 129, 2, 200]);
    assert_eq!(texels[15], [0, 64, 201, 50]);
    // Texel 6: colour index 2 (weight 43), alpha index 1 (weight 21).
    assert_eq!(texels[6], [84, 85, 136, 151]);
    let (e0, e1) = ([255, 129, 2, 200], [0, 64, 201, 50]);
    for (t, texel) in texels.iter().enumerate() {
        for c in 0..3 {
            assert_eq!(
                texel[c],
                lerp(e0[c], e1[c], W2[t % 4]),
                "texel {t} channel {c}"
            );
        }
        assert_eq!(texel[3], lerp(e0[3], e1[3], W2[t / 4]), "texel {t} alpha");
    }
    // Rotation 1 swaps red and alpha after interpolation.
    let rotated = decode_bc7_block(&mode5_block(1));
    for (a, b) in texels.iter().zip(&rotated) {
        assert_eq!(*b, [a[3], a[1], a[2], a[0]]);
    }
}

#[test]
fn bc7_mode4_index_selection_and_rotation_hand_computed() {
    let mut w = BlockWriter::default();
    // Mode 4, rotation 2 (swap green and alpha), index selection 1.
    w.put(1 << 4, 5).put(2, 2).put(1, 1);
    for v in [31, 0, 16, 8, 3, 29] {
        w.put(v, 5);
    }
    w.put(63, 6).put(10, 6);
    // First set (2 bits): t % 4; second set (3 bits): t / 2. Texel 0 drops one bit in each.
    w.put(0, 1);
    for t in 1..16 {
        w.put(t % 4, 2);
    }
    w.put(0, 2);
    for t in 1..16 {
        w.put(t / 2, 3);
    }
    let texels = decode_bc7_block(&w.finish());
    // Endpoints: 5-bit v -> (v << 3) | (v >> 2): R 255/0, G 132/66, B 24/239; 6-bit alpha 255/40.
    // Index selection 1: colour uses the 3-bit set, alpha the 2-bit set.
    // Texel 9: colour index 4 (weight 37) -> R 108, G 94, B 148; alpha index 1 (21) -> 184.
    // Rotation 2 then swaps G and A.
    assert_eq!(texels[9], [108, 184, 148, 94]);
    assert_eq!(texels[0], [255, 255, 24, 132]);
    let (e0, e1) = ([255, 132, 24, 255], [0, 66, 239, 40]);
    for (t, texel) in texels.iter().enumerate() {
        let w3 = W3[t / 2];
        let w2 = W2[t % 4];
        let expect = [
            lerp(e0[0], e1[0], w3),
            lerp(e0[3], e1[3], w2),
            lerp(e0[2], e1[2], w3),
            lerp(e0[1], e1[1], w3),
        ];
        assert_eq!(*texel, expect, "texel {t}");
    }
}

#[test]
fn bc7_mode1_partition_and_anchor_hand_computed() {
    // Partition 17 of the two-subset table (spec figure):
    //   0 1 1 1
    //   0 0 0 1
    //   0 0 0 0
    //   0 0 0 0
    // and the anchor of subset 1 is texel 2 (stored with 2 bits, like texel 0).
    let subset = [0, 1, 1, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0];
    let indices = [3u32, 7, 1, 5, 0, 6, 2, 4, 7, 3, 5, 1, 6, 0, 4, 2];
    let mut w = BlockWriter::default();
    w.put(1 << 1, 2).put(17, 6);
    // R0..R3, G0..G3, B0..B3 (6 bits), then one shared p-bit per subset.
    for v in [10, 50, 63, 0, 20, 40, 0, 63, 5, 60, 30, 30] {
        w.put(v, 6);
    }
    w.put(1, 1).put(0, 1);
    for (t, &idx) in indices.iter().enumerate() {
        w.put(idx, if t == 0 || t == 2 { 2 } else { 3 });
    }
    let texels = decode_bc7_block(&w.finish());
    // 7-bit endpoints (v << 1 | p) expanded: subset 0 (p = 1): R 42/203, G 82/163, B 22/243;
    // subset 1 (p = 0): R 253/0, G 0/253, B 120/120.
    assert_eq!(texels[0], [110, 116, 115, 255]);
    assert_eq!(texels[1], [0, 253, 120, 255]);
    assert_eq!(texels[2], [217, 36, 120, 255]);
    assert_eq!(texels[5], [180, 152, 212, 255]);
    assert_eq!(texels[7], [107, 146, 120, 255]);
    let ends = [
        ([42, 82, 22], [203, 163, 243]),
        ([253, 0, 120], [0, 253, 120]),
    ];
    for (t, texel) in texels.iter().enumerate() {
        let (e0, e1) = ends[subset[t]];
        for c in 0..3 {
            assert_eq!(
                texel[c],
                lerp(e0[c], e1[c], W3[indices[t] as usize]),
                "texel {t}"
            );
        }
        assert_eq!(texel[3], 255);
    }
}

#[test]
fn bc7_mode2_three_subsets_hand_computed() {
    // Partition 0 of the three-subset table:
    //   0 0 1 1
    //   0 0 1 1
    //   0 2 2 1
    //   2 2 2 2
    // anchors: texel 0, texel 3 (subset 1), texel 15 (subset 2).
    let subset = [0, 0, 1, 1, 0, 0, 1, 1, 0, 2, 2, 1, 2, 2, 2, 2];
    let indices = [0u32, 1, 2, 1, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 1];
    let mut w = BlockWriter::default();
    w.put(1 << 2, 3).put(0, 6);
    for v in [
        31, 0, 10, 20, 5, 25, 0, 31, 15, 15, 1, 2, 16, 16, 31, 0, 7, 9,
    ] {
        w.put(v, 5);
    }
    for (t, &idx) in indices.iter().enumerate() {
        w.put(idx, if [0, 3, 15].contains(&t) { 1 } else { 2 });
    }
    let texels = decode_bc7_block(&w.finish());
    // 5-bit endpoints expanded ((v << 3) | (v >> 2)):
    // subset 0: R 255/0, G 0/255, B 132/132; subset 1: R 82/165, G 123/123, B 255/0;
    // subset 2: R 41/206, G 8/16, B 57/74.
    assert_eq!(texels[1], [171, 84, 132, 255]);
    assert_eq!(texels[3], [109, 123, 171, 255]);
    assert_eq!(texels[6], [138, 123, 84, 255]);
    assert_eq!(texels[9], [95, 11, 63, 255]);
    assert_eq!(texels[15], [95, 11, 63, 255]);
    let ends = [
        ([255, 0, 132], [0, 255, 132]),
        ([82, 123, 255], [165, 123, 0]),
        ([41, 8, 57], [206, 16, 74]),
    ];
    for (t, texel) in texels.iter().enumerate() {
        let (e0, e1) = ends[subset[t]];
        for c in 0..3 {
            assert_eq!(
                texel[c],
                lerp(e0[c], e1[c], W2[indices[t] as usize]),
                "texel {t}"
            );
        }
        assert_eq!(texel[3], 255);
    }
}

#[test]
fn bc7_reserved_mode_is_transparent_black() {
    let mut block = [0xA5u8; 16];
    block[0] = 0;
    assert_eq!(decode_bc7_block(&block), [[0; 4]; 16]);
    assert_eq!(decode_bc7_block(&[0; 16]), [[0; 4]; 16]);
}

#[test]
fn decoders_never_panic_on_arbitrary_bytes() {
    let mut rng = XorShift(0x9E37_79B9_7F4A_7C15);
    for i in 0..200_000u32 {
        let mut bc7 = [0u8; 16];
        bc7[..8].copy_from_slice(&rng.next_u64().to_le_bytes());
        bc7[8..].copy_from_slice(&rng.next_u64().to_le_bytes());
        // Force every mode (and the reserved one) to come up often.
        bc7[0] = (bc7[0] | 1).checked_shl(i % 9).unwrap_or(0);
        let texels = decode_bc7_block(&bc7);
        if bc7[0] == 0 {
            assert_eq!(texels, [[0; 4]; 16]);
        }
        let bc4: [u8; 8] = rng.next_u64().to_le_bytes();
        decode_bc4_block(&bc4);
    }
    for fill in [0x00, 0xFF, 0x80, 0x01] {
        decode_bc7_block(&[fill; 16]);
        decode_bc4_block(&[fill; 8]);
    }
    for mode in 0..8 {
        let mut block = [0xFFu8; 16];
        block[0] = 0xFF << mode;
        decode_bc7_block(&block);
    }
}

#[test]
fn bc7_opaque_modes_have_full_alpha() {
    // Modes 0-3 carry no alpha: every texel decodes with alpha 255 whatever the other bits.
    let mut rng = XorShift(7);
    for mode in 0..4 {
        for _ in 0..1000 {
            let mut block = [0u8; 16];
            block[..8].copy_from_slice(&rng.next_u64().to_le_bytes());
            block[8..].copy_from_slice(&rng.next_u64().to_le_bytes());
            block[0] = (block[0] | 1) << mode;
            for texel in decode_bc7_block(&block) {
                assert_eq!(texel[3], 255, "mode {mode}");
            }
        }
    }
}
