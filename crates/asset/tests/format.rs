//! The asset format on a small hand-built asset whose values are known by construction:
//! round trip, the sampler against the intended values, validation of hostile indices, and a
//! seeded corruption harness over the file bytes (refused with an error, never a panic).

use vdbcook_asset::*;

/// Two frames over a 2×1×1 root. Frame 0: region 0 holds an L2 node with a brick at slot 0
/// (value = x + 10y + 100z) and a tile leaf (7.5) at slot 1; region 1 is a tile region (2.0).
/// Frame 1 shares the node (a DAG) and leaves region 1 empty.
fn sample_asset(format: PayloadFormat) -> (Asset, Vec<f32>) {
    let brick: Vec<f32> = (0..512)
        // Voxel (x, y, z) is at 64x + 8y + z and holds x + 10y + 100z.
        .map(|i| ((i / 64) + 10 * ((i / 8) % 8) + 100 * (i % 8)) as f32)
        .collect();
    let mut bytes = Vec::new();
    let quant = if format.is_quantized() {
        [0.0, 777.0]
    } else {
        [0.0, 0.0]
    };
    match format {
        PayloadFormat::Unorm8 => {
            bytes.extend_from_slice(&payload::encode_unorm8(&brick, 0.0, 777.0))
        }
        f if f.packed_bits().is_some() => bytes.extend(payload::encode_packed(
            &brick,
            f.packed_bits().unwrap(),
            0.0,
            777.0,
        )),
        f => payload::encode_float(f, &brick, &mut bytes),
    }
    let mut payloads: [Vec<u8>; FORMATS] = Default::default();
    payloads[format.rank()] = bytes;
    let mut brick_counts = [0u64; FORMATS];
    brick_counts[format.rank()] = 1;
    let mut mask = vec![0u64; L2_WORDS];
    mask[0] = 0b11;
    let mut prefix = vec![0u16; L2_WORDS];
    for p in prefix.iter_mut().skip(1) {
        *p = 2;
    }
    let asset = Asset {
        header: Header {
            tool: "test".into(),
            options: CookOptions {
                format,
                max_error: None,
                range: RangeMode::Brick,
                bc7_quality: "fast".into(),
                grid: None,
                replace_non_finite: None,
                allow_gaps: false,
            },
            grid_name: "density".into(),
            frames: vec![
                FrameInfo {
                    number: Some(1),
                    source: "a.vdb".into(),
                    active_voxels: 1000,
                },
                FrameInfo {
                    number: Some(2),
                    source: "b.vdb".into(),
                    active_voxels: 1000,
                },
            ],
            index_offset: [-128, 0, 256],
            root_dims: [2, 1, 1],
            index_to_world: [
                [0.5, 0.0, 0.0, 1.0],
                [0.0, 0.5, 0.0, 2.0],
                [0.0, 0.0, 0.5, 3.0],
                [0.0, 0.0, 0.0, 1.0],
            ],
            source_map: "UniformScaleTranslateMap".into(),
            voxel_size: [0.5; 3],
            background: 0.0,
            brick_counts,
            sections: vec![],
            content_hash: 0,
            channels: Vec::new(),
            lod_levels: 0,
            lod_first: 1,
            source: Default::default(),
        },
        roots: vec![0, TILE_BIT | 1, 0, EMPTY],
        frame_ranges: vec![[0.0, 777.0], [0.0, 777.0]],
        l2_masks: mask,
        l2_base: vec![0],
        l2_prefix: prefix,
        l2_ranges: vec![[0.0, 777.0]],
        l3_refs: vec![0, TILE_BIT],
        tiles: vec![7.5, 2.0],
        brick_ranges: vec![[0.0, 777.0]],
        brick_quant: vec![quant],
        payloads,
    };
    (asset, brick)
}

#[test]
fn round_trip_is_lossless_and_deterministic() {
    for f in [
        PayloadFormat::F32,
        PayloadFormat::F16,
        PayloadFormat::Unorm8,
    ] {
        let (a, _) = sample_asset(f);
        a.validate().unwrap();
        let (bytes, header) = a.to_bytes().unwrap();
        let (bytes2, _) = a.to_bytes().unwrap();
        assert_eq!(bytes, bytes2, "same asset, same bytes");
        let b = Asset::from_bytes(&bytes).unwrap();
        let mut expect = a.clone();
        expect.header = header;
        assert_eq!(b, expect);
    }
}

#[test]
fn sampler_returns_the_constructed_values() {
    let (a, brick) = sample_asset(PayloadFormat::F32);
    for z in 0..8 {
        for y in 0..8 {
            for x in 0..8 {
                let want = (x + 10 * y + 100 * z) as f32;
                assert_eq!(brick[(64 * x + 8 * y + z) as usize], want);
                assert_eq!(a.value(0, [x, y, z]), want);
                assert_eq!(a.value(1, [x, y, z]), want);
                assert_eq!(a.value(0, [8 + x, y, z]), 7.5, "tile leaf at slot 1");
            }
        }
    }
    assert_eq!(a.value(0, [16, 0, 0]), 0.0, "slot 2 is empty");
    assert_eq!(a.value(0, [8, 8, 0]), 0.0, "slot 17 is empty");
    assert_eq!(a.value(0, [200, 5, 5]), 2.0, "tiled region");
    assert_eq!(a.value(1, [200, 5, 5]), 0.0, "empty region in frame 1");
    assert_eq!(a.value(0, [-1, 0, 0]), 0.0, "outside the extent");
    assert_eq!(a.value(0, [256, 0, 0]), 0.0, "outside the extent");
    // Source coordinates go through the offset.
    assert_eq!(
        a.value_at_source(0, [-128 + 3, 2, 256 + 1]),
        3.0 + 20.0 + 100.0
    );
    let (h, _) = sample_asset(PayloadFormat::F16);
    assert_eq!(h.value(0, [7, 7, 7]), 777.0, "777 is exact in f16");
    // unorm8 over [0, 777]: every voxel within half a quantization step.
    let (u, _) = sample_asset(PayloadFormat::Unorm8);
    for z in 0..8 {
        for y in 0..8 {
            for x in 0..8 {
                let want = (x + 10 * y + 100 * z) as f32;
                assert!(
                    (u.value(0, [x, y, z]) - want).abs() <= 777.0 / 510.0 + 1e-3,
                    "{x},{y},{z}"
                );
            }
        }
    }
}

#[test]
fn validation_refuses_out_of_range_indices() {
    let cases: [fn(&mut Asset); 10] = [
        |a| a.roots[0] = 5,
        |a| a.roots[1] = TILE_BIT | 9,
        |a| a.l3_refs[0] = 3,
        |a| a.l3_refs[1] = TILE_BIT | 2,
        |a| a.l2_base[0] = 1,
        |a| a.l2_prefix[5] = 1,
        |a| a.l2_masks[0] = 0,
        |a| a.tiles[0] = f32::NAN,
        |a| a.brick_ranges[0] = [2.0, 1.0],
        |a| a.header.index_offset[0] = 5,
    ];
    let more: [fn(&mut Asset); 3] = [
        |a| a.header.brick_counts[4] += 1,
        |a| a.brick_quant[0] = [f32::NAN, 1.0],
        |a| {
            let r = a.header.options.format.rank();
            a.payloads[r].pop();
        },
    ];
    for (i, c) in cases.iter().chain(more.iter()).enumerate() {
        let (mut a, _) = sample_asset(PayloadFormat::F32);
        c(&mut a);
        assert!(a.validate().is_err(), "case {i} accepted");
        // Written and loaded: refused at load too.
        let (bytes, _) = a.to_bytes().unwrap();
        assert!(Asset::from_bytes(&bytes).is_err(), "case {i} loaded");
    }
}

#[test]
fn corrupt_and_truncated_files_are_refused_without_panic() {
    for f in [PayloadFormat::F16, PayloadFormat::Packed3] {
        corrupt_and_truncated_refused(f);
    }
}

fn corrupt_and_truncated_refused(format: PayloadFormat) {
    let (a, _) = sample_asset(format);
    let (bytes, _) = a.to_bytes().unwrap();
    for cut in 0..bytes.len() {
        assert!(
            Asset::from_bytes(&bytes[..cut]).is_err(),
            "truncated to {cut} accepted"
        );
    }
    let mut state = 0x9e3779b97f4a7c15u64;
    for pos in 0..bytes.len() {
        for _ in 0..3 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let mut d = bytes.clone();
            d[pos] ^= (state as u8) | 1;
            let r = std::panic::catch_unwind(|| Asset::from_bytes(&d).map(|x| x.validate()));
            let r = r.unwrap_or_else(|_| panic!("panic on a flipped byte at {pos}"));
            // A flip may only be accepted if it left the asset identical (e.g. unused zstd bits).
            if let Ok(Ok(())) = r {
                let b = Asset::from_bytes(&d).unwrap();
                let orig = Asset::from_bytes(&bytes).unwrap();
                assert_eq!(b, orig, "flip at {pos} accepted with different content");
            }
        }
    }
    assert!(Asset::from_bytes(b"not an asset at all").is_err());
}

/// `sample_asset` (F32) as channel 0 of a two-channel asset: channel 1 ("temperature",
/// background 300) holds the tile 1500 in slot 0 and is its background in slot 1, in both frames.
/// Region 1 of frame 0 (a tiled region in one channel) becomes a full node of tile refs, as
/// multi-channel assets have no tiled root entries.
fn two_channel_asset() -> Asset {
    let (mut a, _) = sample_asset(PayloadFormat::F32);
    a.header.channels = vec![
        ChannelInfo {
            name: "density".into(),
            background: 0.0,
            max_error: None,
            active_voxels: vec![1000, 1000],
        },
        ChannelInfo {
            name: "temperature".into(),
            background: 300.0,
            max_error: Some(5.0),
            active_voxels: vec![512, 512],
        },
    ];
    a.tiles.push(1500.0); // tile 2
                          // Node 0: slot 0 = (brick 0, tile 1500), slot 1 = (tile 7.5, EMPTY).
    a.l3_refs = vec![0, TILE_BIT | 2, TILE_BIT, EMPTY];
    // Node 1: every slot = (tile 2.0, EMPTY), for frame 0's region 1.
    a.l2_masks.extend([u64::MAX; L2_WORDS]);
    a.l2_base.push(2);
    a.l2_prefix.extend((0..L2_WORDS).map(|w| (64 * w) as u16));
    for _ in 0..L2_SLOTS {
        a.l3_refs.extend([TILE_BIT | 1, EMPTY]);
    }
    a.roots = vec![0, 1, 0, EMPTY];
    a.l2_ranges = vec![[0.0, 777.0], [300.0, 1500.0], [2.0, 2.0], [300.0, 300.0]];
    a.frame_ranges = vec![[0.0, 777.0], [300.0, 1500.0], [0.0, 777.0], [300.0, 1500.0]];
    a
}

#[test]
fn single_channel_assets_stay_version_2_and_multi_channel_ones_are_version_3() {
    let (a, _) = sample_asset(PayloadFormat::F32);
    let (bytes, _) = a.to_bytes().unwrap();
    assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()), 2);
    let m = two_channel_asset();
    m.validate().unwrap();
    let (mb, header) = m.to_bytes().unwrap();
    assert_eq!(u32::from_le_bytes(mb[8..12].try_into().unwrap()), 3);
    let back = Asset::from_bytes(&mb).unwrap();
    let mut expect = m.clone();
    expect.header = header;
    assert_eq!(back, expect, "v3 round trip");
    assert_eq!(m.to_bytes().unwrap().0, mb, "deterministic");
}

#[test]
fn channels_read_their_own_values_and_backgrounds() {
    let m = two_channel_asset();
    let (single, _) = sample_asset(PayloadFormat::F32);
    assert_eq!(m.channel_count(), 2);
    assert_eq!(m.header.channel_index("temperature"), Some(1));
    for f in 0..2 {
        for p in [[3, 2, 1], [9, 1, 1], [20, 3, 3], [200, 5, 5], [-1, 0, 0]] {
            // Channel 0 reads exactly what the single-channel asset holds.
            assert_eq!(m.value(f, p), single.value(f, p), "frame {f} {p:?}");
        }
        assert_eq!(m.value_c(f, [3, 2, 1], 1), 1500.0, "slot 0 tile");
        assert_eq!(m.value_c(f, [9, 1, 1], 1), 300.0, "EMPTY ref: background");
        assert_eq!(
            m.value_c(f, [40, 1, 1], 1),
            300.0,
            "missing slot: background"
        );
        assert_eq!(m.value_c(f, [-5, 1, 1], 1), 300.0, "outside: background");
    }
    assert_eq!(m.value_c(0, [200, 5, 5], 1), 300.0, "node of (tile, EMPTY)");
    assert_eq!(m.frame_range(0, 1), [300.0, 1500.0]);
    // Leaf walks skip EMPTY refs: channel 1 stores one leaf per frame.
    let mut n = 0;
    m.for_each_leaf_c(0, 1, |_, r, _| {
        assert_eq!(r, LeafRef::Tile(1500.0));
        n += 1;
    });
    assert_eq!(n, 1);
    let mut n0 = 0;
    m.for_each_leaf_c(0, 0, |_, _, _| n0 += 1);
    assert_eq!(
        n0,
        2 + L2_SLOTS,
        "channel 0: two leaves and the expanded tiled region"
    );
}

#[test]
fn validation_refuses_hostile_multi_channel_assets() {
    let cases: [fn(&mut Asset); 8] = [
        // A tiled root entry: one value cannot stand for several channels.
        |a| a.roots[1] = TILE_BIT | 1,
        // Refs not a whole number per slot.
        |a| {
            a.l3_refs.pop();
        },
        // Ranges not one per channel.
        |a| {
            a.l2_ranges.pop();
        },
        |a| {
            a.frame_ranges.pop();
        },
        // Channel 0 disagrees with the header's grid.
        |a| a.header.channels[0].name = "smoke".into(),
        // Duplicate channel names.
        |a| a.header.channels[1].name = "density".into(),
        // A voxel count per frame missing; a bad budget.
        |a| {
            a.header.channels[1].active_voxels.pop();
        },
        |a| a.header.channels[1].max_error = Some(-1.0),
    ];
    for (i, c) in cases.iter().enumerate() {
        let mut a = two_channel_asset();
        c(&mut a);
        assert!(a.validate().is_err(), "case {i} accepted");
        if let Ok((bytes, _)) = a.to_bytes() {
            assert!(Asset::from_bytes(&bytes).is_err(), "case {i} loaded");
        }
    }
    // One channel in a version-3 file, and EMPTY leaf refs in a version-2 file.
    let mut one = two_channel_asset();
    one.header.channels.truncate(1);
    let (bytes, _) = one.to_bytes().unwrap();
    assert!(Asset::from_bytes(&bytes).is_err());
    let (mut v2, _) = sample_asset(PayloadFormat::F32);
    v2.l3_refs[1] = EMPTY;
    assert!(v2.validate().is_err());
}

/// Flips one byte at every position of `bytes` (by a seeded xorshift): each flip is refused
/// with an error, never a panic, or leaves the asset identical (e.g. unused zstd bits).
fn flips_are_refused(bytes: &[u8], seed: u64) {
    let orig = Asset::from_bytes(bytes).unwrap();
    let mut state = seed;
    for pos in 0..bytes.len() {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let mut d = bytes.to_vec();
        d[pos] ^= (state as u8) | 1;
        let r = std::panic::catch_unwind(|| Asset::from_bytes(&d).map(|x| x.validate()));
        let r = r.unwrap_or_else(|_| panic!("panic on a flipped byte at {pos}"));
        if let Ok(Ok(())) = r {
            assert_eq!(Asset::from_bytes(&d).unwrap(), orig, "flip at {pos}");
        }
    }
}

#[test]
fn corrupt_multi_channel_files_are_refused_without_panic() {
    let (bytes, _) = two_channel_asset().to_bytes().unwrap();
    flips_are_refused(&bytes, 0x2545f4914f6cdd1d);
    for cut in (0..bytes.len()).step_by(7) {
        assert!(Asset::from_bytes(&bytes[..cut]).is_err(), "cut {cut}");
    }
}

/// `two_channel_asset` read as one frame with one coarser level: its second frame's roots
/// become the level's root set (the format does not check that a level is a box filter; the
/// cooker's tests do).
fn lod_asset() -> Asset {
    let mut a = two_channel_asset();
    a.header.frames.truncate(1);
    for c in &mut a.header.channels {
        c.active_voxels.truncate(1);
    }
    a.header.lod_levels = 1;
    a
}

#[test]
fn assets_with_levels_are_version_4_and_round_trip() {
    let a = lod_asset();
    a.validate().unwrap();
    assert_eq!(
        (a.frame_count(), a.level_count(), a.root_set_count()),
        (1, 2, 2)
    );
    assert_eq!(a.lod_set(0, 1), 1);
    let (bytes, header) = a.to_bytes().unwrap();
    assert_eq!(
        u32::from_le_bytes(bytes[8..12].try_into().unwrap()),
        FORMAT_VERSION_LOD
    );
    let mut expect = a.clone();
    expect.header = header;
    assert_eq!(Asset::from_bytes(&bytes).unwrap(), expect, "v4 round trip");
    // Level 1 reads what the second root set holds (frame 1 of the two-channel asset).
    let two = two_channel_asset();
    for p in [[0i64, 0, 0], [9, 1, 1], [130, 3, 3]] {
        for c in 0..2 {
            assert_eq!(a.value_c(a.lod_set(0, 1), p, c), two.value_c(1, p, c));
        }
    }
    // A single channel with levels is version 4 too.
    let (mut s, _) = sample_asset(PayloadFormat::F32);
    s.roots.extend_from_within(..);
    s.frame_ranges.extend_from_within(..);
    s.header.lod_levels = 1;
    s.validate().unwrap();
    let (sb, _) = s.to_bytes().unwrap();
    assert_eq!(
        u32::from_le_bytes(sb[8..12].try_into().unwrap()),
        FORMAT_VERSION_LOD
    );
    assert_eq!(Asset::from_bytes(&sb).unwrap().level_count(), 2);
    assert_eq!(Asset::from_bytes(&sb).unwrap().level_shift(1), 1);
}

/// `cook --lod-from K`: the same root sets, the first stored level named `K`. Version 5, which
/// differs from version 4 only by the header's last field; the shift follows it.
#[test]
fn levels_from_a_coarser_level_are_version_5_and_round_trip() {
    let v4 = lod_asset();
    let mut a = lod_asset();
    a.header.lod_first = 3;
    a.validate().unwrap();
    assert_eq!((a.level_shift(0), a.level_shift(1)), (0, 3));
    let (bytes, header) = a.to_bytes().unwrap();
    assert_eq!(
        u32::from_le_bytes(bytes[8..12].try_into().unwrap()),
        FORMAT_VERSION_LOD_FROM
    );
    let mut expect = a.clone();
    expect.header = header;
    let back = Asset::from_bytes(&bytes).unwrap();
    assert_eq!(back, expect, "v5 round trip");
    assert_eq!(back.level_shift(1), 3);
    // Version 4 assets read as a chain from level 1, and stay version 4 byte for byte.
    let (b4, _) = v4.to_bytes().unwrap();
    assert_eq!(Asset::from_bytes(&b4).unwrap().header.lod_first, 1);
    assert_eq!(
        b4.len() + 1,
        bytes.len(),
        "version 5 adds one varint to the header"
    );
    // A version-5 file whose chain starts at level 1 (that is version 4) is refused: the
    // header's last byte is `lod_first` (one varint byte).
    let hlen = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    assert_eq!(bytes[16 + hlen - 1], 3);
    let mut forged = bytes.clone();
    forged[16 + hlen - 1] = 1;
    let e = Asset::from_bytes(&forged).unwrap_err().0;
    assert!(e.contains("start at level 2"), "{e}");
    // A chain past level 12 is refused, written or in memory; so is a first level of 0.
    let mut far = a.clone();
    far.header.lod_first = MAX_LOD_LEVELS + 1;
    assert!(far.validate().unwrap_err().0.contains("levels 1 to"));
    let (fb, _) = far.to_bytes().unwrap();
    assert!(Asset::from_bytes(&fb)
        .unwrap_err()
        .0
        .contains("levels 1 to"));
    let mut z = a.clone();
    z.header.lod_first = 0;
    assert!(z.validate().unwrap_err().0.contains("levels 0 to"));
}

/// What the source says of itself (writer, class, up axis) makes a version-6 asset that round
/// trips, with or without levels; an asset whose source says nothing stays at its old version
/// byte for byte.
#[test]
fn source_info_is_version_6_and_round_trips() {
    const FORMAT_VERSION: u32 = FORMAT_VERSION_SOURCE;
    for mut a in [lod_asset(), {
        let mut b = lod_asset();
        b.header.lod_first = 3;
        b
    }] {
        let (old, _) = a.to_bytes().unwrap();
        let old_version = u32::from_le_bytes(old[8..12].try_into().unwrap());
        assert!(old_version < FORMAT_VERSION);
        a.header.source = SourceInfo {
            creator: "Blender/Smoke".into(),
            grid_class: "fog volume".into(),
            up: "z".into(),
        };
        let (bytes, header) = a.to_bytes().unwrap();
        assert_eq!(
            u32::from_le_bytes(bytes[8..12].try_into().unwrap()),
            FORMAT_VERSION
        );
        let mut expect = a.clone();
        expect.header = header;
        let back = Asset::from_bytes(&bytes).unwrap();
        assert_eq!(back, expect);
        assert_eq!(back.header.source.up, "z");
        // Truncating the source's strings is refused (never read past the header).
        let hlen = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let mut cut = bytes.clone();
        cut[12..16].copy_from_slice(&(hlen as u32 - 2).to_le_bytes());
        assert!(Asset::from_bytes(&cut).is_err());
    }
}

/// The bits of voxel codes `q` (voxel order) at `bits` each, packed by hand: bit `k` of the
/// stream is bit `k % 8` of byte `k / 8` (the format's rule, written independently of the crate).
fn pack_by_hand(q: &[u32], bits: u32) -> Vec<u8> {
    let stream: Vec<bool> = q
        .iter()
        .flat_map(|&v| (0..bits).map(move |i| (v >> i) & 1 == 1))
        .collect();
    stream
        .chunks(8)
        .map(|c| c.iter().enumerate().map(|(i, &b)| (b as u8) << i).sum())
        .collect()
}

#[test]
fn packed_bricks_are_version_7_round_trip_and_read_each_voxel_within_half_a_level() {
    for (w, f) in PayloadFormat::PACKED.into_iter().enumerate() {
        let bits = w as u32 + 1;
        assert_eq!(f.packed_bits(), Some(bits));
        assert_eq!(f.bytes_per_brick(), 64 * bits as usize);
        let (a, brick) = sample_asset(f);
        a.validate().unwrap();
        let (bytes, header) = a.to_bytes().unwrap();
        assert_eq!(
            u32::from_le_bytes(bytes[8..12].try_into().unwrap()),
            FORMAT_VERSION,
            "{}",
            f.name()
        );
        assert_eq!(a.to_bytes().unwrap().0, bytes, "deterministic");
        let back = Asset::from_bytes(&bytes).unwrap();
        let mut expect = a.clone();
        expect.header = header;
        assert_eq!(back, expect);
        // The levels are the 8-bit codes round(255·q/(2^b − 1)); the widest gap between two
        // of them, over [0, 777], bounds every voxel's error at half of it.
        let levels = (1u32 << bits) - 1;
        let code = |q: u32| ((255.0 * q as f64 / levels as f64) + 0.5).floor();
        let gap = (0..levels)
            .map(|q| code(q + 1) - code(q))
            .fold(0.0, f64::max);
        let bound = gap / 2.0 * 777.0 / 255.0 + 1e-3;
        for (i, &want) in brick.iter().enumerate() {
            let (x, y, z) = (i / 64, (i / 8) % 8, i % 8);
            let got = back.value(0, [x as i64, y as i64, z as i64]);
            assert!(
                ((got - want) as f64).abs() <= bound,
                "{} voxel {x},{y},{z}: {got} for {want} (bound {bound})",
                f.name()
            );
        }
        // Decoding reads the bit stream as written by hand.
        let q: Vec<u32> = (0..512)
            .map(|i| (i as u32 * 7 + 3) % (levels + 1))
            .collect();
        let hand = pack_by_hand(&q, bits);
        let mut out = [0f32; 512];
        payload::decode_brick(f, &hand, [0.0, 255.0], &mut out);
        for (i, (&o, &qi)) in out.iter().zip(&q).enumerate() {
            assert_eq!(o, code(qi) as f32, "{} voxel {i}", f.name());
            assert_eq!(payload::packed_get(&hand, bits, i), qi);
        }
    }
    // An asset without packed bricks keeps its older version.
    let (a, _) = sample_asset(PayloadFormat::Unorm8);
    let (bytes, _) = a.to_bytes().unwrap();
    assert!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()) < FORMAT_VERSION);
}

#[test]
fn level_counts_that_do_not_match_the_roots_are_refused() {
    for (levels, why) in [(2u32, "root entries"), (MAX_LOD_LEVELS + 1, "at most")] {
        let mut a = lod_asset();
        a.header.lod_levels = levels;
        let e = a.validate().unwrap_err().0;
        assert!(e.contains(why), "{levels}: {e}");
        // Written anyway (the writer does not validate), the loader refuses the file.
        if let Ok((bytes, _)) = a.to_bytes() {
            assert!(Asset::from_bytes(&bytes).is_err());
        }
    }
    let (bytes, _) = lod_asset().to_bytes().unwrap();
    flips_are_refused(&bytes, 0x517cc1b727220a95);
}
