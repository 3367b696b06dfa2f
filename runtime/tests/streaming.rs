//! Streaming a window of frames under a byte budget (`StreamingVolume`): frames rendered through a
//! window are bit-identical to the full upload's in the same layout (density mode; every layout
//! the adapter offers, the native BC texture layouts included where it has the BC features;
//! checked against the CPU tracer too), moving the window writes exactly the bricks it newly
//! uses (counted here from the asset's leaves) and evicts those it no longer uses, and a budget
//! under one frame, or a window outside the sequence, is a clear error.

mod common;

use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;

use common::*;
use vdbcook_asset::{Asset, LeafRef, PayloadFormat};
use vdbcook_runtime::{
    GpuVolume, Layout, Readback, Renderer, RuntimeError, StreamingVolume, UploadOptions,
    VolumeDrawer,
};
use vdbcook_trace::{Integrator, Mode, Output, RenderSettings};

const W: u32 = 96;
const H: u32 = 64;
const FRAMES: usize = 6;

fn hash(vals: &[f32]) -> u64 {
    vals.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, v| {
        (h ^ v.to_bits() as u64).wrapping_mul(0x100_0000_01b3)
    })
}

/// Six random frames, each the previous one with about a third of its leaves' contents replaced (so
/// consecutive frames share bricks), every brick in a format picked from its values (so a shared
/// brick encodes identically), then the pool deduplicated in first use order per format.
fn shared_asset(formats: &[PayloadFormat]) -> Asset {
    let mut rng = XorShift(0x57ea_0001);
    let mut frames = vec![random_frame(&mut rng)];
    for _ in 1..FRAMES {
        let mut f = frames.last().unwrap().clone();
        let fresh: Vec<Leaf> = random_frame(&mut rng).leaves.into_values().collect();
        let mut fresh = fresh.into_iter().cycle();
        for leaf in f.leaves.values_mut() {
            if rng.f() < 0.35 {
                *leaf = fresh.next().unwrap();
            }
        }
        frames.push(f);
    }
    let built = vdbcook_asset::builder::AssetBuilder::new([2, 2, 1])
        .index_to_world(rotated(20.0, [0.5, 0.5, 0.5], [1.0, -2.0, 0.5]))
        .frames(frames)
        .build_with(|_, vals| {
            let h = hash(vals);
            let format = formats[(h % formats.len() as u64) as usize];
            test_brick(format, vals, &mut XorShift(h | 1))
        })
        .expect("valid");
    dedup(built)
}

/// Stores identical bricks (format, bytes, quantization range) once, keeping the first.
fn dedup(mut a: Asset) -> Asset {
    let mut key_of = HashMap::new();
    let mut new_index = Vec::new();
    let mut kept = Vec::new();
    for b in 0..a.brick_count() as u32 {
        let (f, bytes) = a.brick_bytes(b);
        let q = a.brick_quant[b as usize];
        let key = (f.rank(), bytes.to_vec(), q[0].to_bits(), q[1].to_bits());
        let n = *key_of.entry(key).or_insert_with(|| {
            kept.push(b);
            kept.len() as u32 - 1
        });
        new_index.push(n);
    }
    let mut payloads: [Vec<u8>; vdbcook_asset::FORMATS] = Default::default();
    let mut counts = [0u64; vdbcook_asset::FORMATS];
    for &b in &kept {
        let (f, bytes) = a.brick_bytes(b);
        payloads[f.rank()].extend_from_slice(bytes);
        counts[f.rank()] += 1;
    }
    a.brick_ranges = kept.iter().map(|&b| a.brick_ranges[b as usize]).collect();
    a.brick_quant = kept.iter().map(|&b| a.brick_quant[b as usize]).collect();
    a.payloads = payloads;
    a.header.brick_counts = counts;
    for r in a.l3_refs.iter_mut() {
        if *r & vdbcook_asset::TILE_BIT == 0 {
            *r = new_index[*r as usize];
        }
    }
    a.validate().expect("deduplicated asset is valid");
    a
}

/// The bricks frames `first..=last` use, from the asset's leaves (independent of the runtime).
fn bricks_of(asset: &Asset, first: usize, last: usize) -> BTreeSet<u32> {
    let mut s = BTreeSet::new();
    for f in first..=last {
        asset.for_each_leaf(f, |_, r, _| {
            if let LeafRef::Brick(b) = r {
                s.insert(b);
            }
        });
    }
    s
}

fn renderer(device: &wgpu::Device, vol: &GpuVolume) -> Renderer {
    Renderer::new(device, vol, wgpu::TextureFormat::Rgba8Unorm).expect("renderer")
}

fn render(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    vol: &GpuVolume,
    frame: usize,
    cam: &vdbcook_trace::Camera,
) -> Readback {
    render_with(device, queue, &renderer(device, vol), frame, cam)
}

fn render_with(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    r: &Renderer,
    frame: usize,
    cam: &vdbcook_trace::Camera,
) -> Readback {
    let target = r.buffer_target(device, W, H).unwrap();
    let s = settings(frame);
    let mut enc = device.create_command_encoder(&Default::default());
    r.render_to_buffer(queue, &mut enc, &target, frame, cam, &s)
        .expect("render");
    queue.submit([enc.finish()]);
    target.read(device, queue)
}

fn settings(frame: usize) -> RenderSettings {
    RenderSettings {
        output: Output {
            width: W,
            height: H,
            frame,
        },
        integrator: Integrator {
            mode: Mode::Density,
            ..Default::default()
        },
        ..Default::default()
    }
}

/// Bytes the whole pool would take in a streamed pool under `layout` (slot bytes plus 16 bytes
/// of ranges per brick): native BC keeps a BC4 brick in 256 bytes and a BC7 brick (z in its
/// four channels) in 128, the decoded textures hold a quantized brick in 1 byte per voxel,
/// packed bricks keep their 64 bytes per bit (but under `Layout::Buffers`), and buffers hold f32
/// (the test assets always have f32 bricks, so the buffered pool is f32).
fn pool_bytes(asset: &Asset, layout: Layout) -> u64 {
    let native = matches!(layout, Layout::Bc3d | Layout::Bc2dArray);
    (0..asset.brick_count() as u32)
        .map(|b| {
            let f = asset.brick_format(b).0;
            16 + match f {
                _ if layout == Layout::Buffers || !f.is_quantized() => 2048,
                _ if f.packed_bits().is_some() => f.bytes_per_brick() as u64,
                PayloadFormat::Bc4 if native => 256,
                PayloadFormat::Bc7 if native => 128,
                _ => 512,
            }
        })
        .sum()
}

#[test]
fn streamed_frames_render_like_the_full_upload_in_every_layout() {
    let Some((device, queue)) = gpu("streamed_frames_render_like_the_full_upload_in_every_layout")
    else {
        return;
    };
    // Packed widths 3 and 6: some voxels' bits cross a word.
    let formats = [
        PayloadFormat::F32,
        PayloadFormat::F16,
        PayloadFormat::Unorm8,
        PayloadFormat::Bc4,
        PayloadFormat::Bc7,
        PayloadFormat::Packed3,
        PayloadFormat::Packed6,
    ];
    let asset = Arc::new(shared_asset(&formats));
    assert!(formats
        .iter()
        .all(|f| asset.header.brick_counts[f.rank()] > 0));
    let cam = vdbcook_trace::Camera::framing(&asset, 0, W as f64 / H as f64).unwrap();
    // Every layout this device can hold: the native BC ones need its BC features.
    let f = device.features();
    let bc = f.contains(wgpu::Features::TEXTURE_COMPRESSION_BC);
    let bc3d = bc && f.contains(wgpu::Features::TEXTURE_COMPRESSION_BC_SLICED_3D);
    let layouts: Vec<Layout> = Layout::ALL
        .into_iter()
        .filter(|l| match l {
            Layout::Bc3d => bc3d,
            Layout::Bc2dArray => bc,
            _ => true,
        })
        .collect();
    println!("layouts streamed: {layouts:?}");
    for layout in layouts {
        // Two thirds of the pool: a window of 2 frames fits, the whole sequence does not.
        let budget = pool_bytes(&asset, layout) * 2 / 3;
        let options = UploadOptions {
            force: Some(layout),
        };
        let full = GpuVolume::upload_with(&device, &queue, &asset, options).expect("upload");
        let mut s =
            StreamingVolume::new(&device, &queue, Arc::clone(&asset), budget, 0..=1, options)
                .expect("stream");
        assert!(
            s.slots().iter().map(|&c| c as usize).sum::<usize>() < asset.brick_count(),
            "{layout:?}: the budget should hold fewer slots than bricks: {:?}",
            s.slots()
        );
        // One renderer for the whole stream, rebound after each window change; the full
        // upload's layout differs (its pool holds every brick), so it cannot be swapped in.
        let mut streamed = renderer(&device, s.volume());
        assert!(matches!(
            streamed.rebind(&full),
            Err(RuntimeError::Rebind(_))
        ));
        // The engine drawer keeps the same binding (`rebind` is one shared implementation;
        // its pixels are the engine tests').
        let mut drawer =
            VolumeDrawer::new(&device, s.volume(), wgpu::TextureFormat::Rgba16Float).unwrap();
        assert!(matches!(drawer.rebind(&full), Err(RuntimeError::Rebind(_))));
        for k in 0..FRAMES {
            if k > 1 {
                s.advance(&device, &queue).expect("advance");
                streamed.rebind(s.volume()).expect("rebind");
                drawer.rebind(s.volume()).expect("drawer rebind");
            }
            let want = render(&device, &queue, &full, k, &cam);
            let local = s.local_frame(k).unwrap();
            let got = render_with(&device, &queue, &streamed, local, &cam);
            assert_eq!(
                got,
                want,
                "{layout:?}: frame {k} in window {:?}",
                s.window()
            );
            if layout == Layout::Buffers {
                let cpu = vdbcook_trace::render(&asset, &cam, &settings(k)).unwrap();
                let worst = cpu
                    .value
                    .iter()
                    .zip(&got.value)
                    .map(|(a, b)| (a - b).abs() / (1.0 + a.abs()))
                    .fold(0.0f32, f32::max);
                assert!(worst < 1e-3, "frame {k}: GPU vs CPU off by {worst}");
            }
        }
        assert!(s.local_frame(0).is_err());
    }
}

#[test]
fn advancing_uploads_exactly_the_newly_used_bricks_and_evicts_the_rest() {
    let Some((device, queue)) =
        gpu("advancing_uploads_exactly_the_newly_used_bricks_and_evicts_the_rest")
    else {
        return;
    };
    let asset = Arc::new(shared_asset(&[PayloadFormat::F32, PayloadFormat::Unorm8]));
    let options = UploadOptions {
        force: Some(Layout::Buffers),
    };
    let budget = pool_bytes(&asset, Layout::Buffers) * 3 / 4;
    let mut s = StreamingVolume::new(&device, &queue, Arc::clone(&asset), budget, 0..=2, options)
        .expect("stream");
    let first = bricks_of(&asset, 0, 2);
    let st = s.stats().clone();
    assert_eq!(st.uploaded_bricks, first.len());
    assert_eq!(st.resident_bricks, first.len());
    assert_eq!(st.uploaded_bytes, first.len() as u64 * 2048);
    assert_eq!(st.evicted, 0);
    let mut shared_seen = 0;
    let mut old = first;
    for a in 1..=FRAMES - 3 {
        let st = s.advance(&device, &queue).expect("advance");
        let new = bricks_of(&asset, a, a + 2);
        let added = new.difference(&old).count();
        let gone = old.difference(&new).count();
        assert_eq!(st.window, (a, a + 2));
        assert_eq!(st.uploaded_bricks, added, "window {a}: uploaded");
        assert_eq!(st.uploaded_bytes, added as u64 * 2048, "window {a}: bytes");
        assert_eq!(st.evicted, gone, "window {a}: evicted");
        assert_eq!(st.resident_bricks, new.len());
        // The frame entering the window shares bricks with the frames before it.
        shared_seen += bricks_of(&asset, a + 2, a + 2).len() - added;
        old = new;
    }
    assert!(shared_seen > 0, "the test asset shares no bricks");
    // Past the end: an error, and the window is unchanged.
    let err = s.advance(&device, &queue).unwrap_err();
    assert!(matches!(err, RuntimeError::Frame { .. }), "{err}");
    assert_eq!(s.window(), (FRAMES - 3, FRAMES - 1));
    // Jumping back re-uploads what the new window uses and is not resident.
    let st = s.set_window(&device, &queue, 0..=0).expect("jump");
    let want = bricks_of(&asset, 0, 0)
        .difference(&bricks_of(&asset, FRAMES - 3, FRAMES - 1))
        .count();
    assert_eq!(st.uploaded_bricks, want);
}

#[test]
fn a_budget_under_one_frame_or_a_bad_window_is_a_clear_error() {
    let Some((device, queue)) = gpu("a_budget_under_one_frame_or_a_bad_window_is_a_clear_error")
    else {
        return;
    };
    let asset = Arc::new(shared_asset(&[PayloadFormat::F32]));
    let options = UploadOptions {
        force: Some(Layout::Buffers),
    };
    let largest = (0..FRAMES)
        .map(|f| bricks_of(&asset, f, f).len())
        .max()
        .unwrap() as u64;
    let budget = largest * 2048;
    let err = StreamingVolume::new(&device, &queue, Arc::clone(&asset), budget, 0..=0, options)
        .err()
        .expect("a budget under one frame is refused");
    let msg = err.to_string();
    let frame_bytes = largest * (2048 + 16);
    assert!(matches!(err, RuntimeError::Budget(_)), "{msg}");
    assert!(
        msg.contains(&budget.to_string()) && msg.contains(&frame_bytes.to_string()),
        "the error names the budget ({budget}) and one frame's bytes ({frame_bytes}): {msg}"
    );
    // A window outside the sequence, and an empty one.
    let err = StreamingVolume::new(&device, &queue, Arc::clone(&asset), 1 << 30, 4..=6, options)
        .err()
        .expect("outside");
    assert!(
        matches!(
            err,
            RuntimeError::Frame {
                frame: 6,
                frames: 6
            }
        ),
        "{err}"
    );
    #[allow(clippy::reversed_empty_ranges)]
    let err = StreamingVolume::new(&device, &queue, Arc::clone(&asset), 1 << 30, 3..=2, options)
        .err()
        .expect("empty");
    assert!(matches!(err, RuntimeError::Setting(_)), "{err}");
    // A budget for one frame (and its topology) refuses a window of every frame.
    let mut s = StreamingVolume::new(
        &device,
        &queue,
        Arc::clone(&asset),
        frame_bytes + (1 << 16),
        0..=0,
        options,
    )
    .expect("one frame fits");
    let err = s.set_window(&device, &queue, 0..=FRAMES - 1).unwrap_err();
    assert!(matches!(err, RuntimeError::Budget(_)), "{err}");
    assert_eq!(s.window(), (0, 0));
}
