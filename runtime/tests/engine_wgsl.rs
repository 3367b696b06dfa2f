//! The volume WGSL in an engine's own shader (issue 12, item 5): an engine-style compute
//! pipeline with its own bind groups 0 and 1 includes `volume_wgsl(2)` and calls
//! `vdb_sample(world_to_index, world_pos, time)` for an instance placed by a rotated, scaled,
//! translated `world_from_volume`, at integer and fractional flip-book times. Every sample must
//! equal the CPU's: the asset's value at OpenVDB's nearest index (`round` of the inverse
//! transform, computed here in f64) of frames ⌊t⌋ and ⌊t⌋+1, mixed by the fraction. Points within
//! f32 rounding of a voxel boundary, where f32 and f64 may round to different voxels, are skipped.
//!
//! Also the short optical-depth walk the lit march and the drawer take toward the sun
//! (`vdb_optical_depth_near`, with and without a known first leaf) against the exact integral of
//! the piecewise-constant voxels along each segment, summed here between sorted plane crossings.

mod common;

use common::*;
use vdbcook_asset::{Asset, PayloadFormat};
use vdbcook_runtime::glam::{Affine3A, Quat, Vec3};
use vdbcook_runtime::{volume_wgsl, wgpu, world_to_index, GpuVolume};

const ENGINE_WGSL: &str = r#"
// The engine's own bindings (groups 0 and 1); the volume is at group 2.
struct Query { world_to_index: mat4x4<f32>, time: f32, count: u32, _p0: u32, _p1: u32 }
@group(0) @binding(0) var<uniform> query: Query;
@group(1) @binding(0) var<storage, read> points: array<vec4<f32>>;
@group(1) @binding(1) var<storage, read_write> samples: array<f32>;

@compute @workgroup_size(64)
fn sample_points(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= query.count) {
        return;
    }
    samples[id.x] = vdb_sample(query.world_to_index, points[id.x].xyz, query.time);
}
"#;

/// Three frames of blobs at different places, so crossfades mix different values.
fn asset() -> Asset {
    let frames = [
        blob_frame([20.0, 22.0, 18.0], 9.0, 1.0, None),
        blob_frame([24.0, 20.0, 20.0], 10.0, 0.8, None),
        blob_frame([18.0, 26.0, 22.0], 8.0, 1.2, None),
    ];
    vdbcook_testkit::build(
        [1, 1, 1],
        vdbcook_testkit::rotated(0.0, [1.0; 3], [0.0; 3]),
        0.0,
        &frames,
        PayloadFormat::F32,
    )
}

fn gpu_samples(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    vol: &GpuVolume,
    w2i: [f32; 16],
    time: f32,
    points: &[[f32; 4]],
) -> Vec<f32> {
    use wgpu::util::DeviceExt;
    let source = format!("{}\n{ENGINE_WGSL}", volume_wgsl(2));
    // Group 0: the engine's own uniform; group 1: points and results; group 2: the volume.
    let l0 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: None,
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }],
    });
    let mut q = Vec::with_capacity(20);
    q.extend(w2i.iter().map(|v| v.to_bits()));
    q.extend([time.to_bits(), points.len() as u32, 0, 0]);
    let qbuf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: None,
        contents: bytemuck::cast_slice(&q),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let g0 = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &l0,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: qbuf.as_entire_binding(),
        }],
    });
    let (vol_layout, vol_group) = vol.bind_group();
    vdbcook_testkit::gpu::eval_points(
        device,
        queue,
        &source,
        "sample_points",
        &vol.pipeline_constants(),
        &[(&l0, &g0), (vol_layout, vol_group)],
        1,
        points,
    )
}

#[test]
fn an_engine_shader_samples_an_instance_at_its_own_bind_group() {
    let Some((device, queue)) = gpu("an_engine_shader_samples_an_instance_at_its_own_bind_group")
    else {
        return;
    };
    let asset = asset();
    let vol = GpuVolume::upload(&device, &queue, &asset).unwrap();
    let world_from_volume = Affine3A::from_scale_rotation_translation(
        Vec3::new(0.5, 0.7, 0.6),
        Quat::from_euler(vdbcook_runtime::glam::EulerRot::XYZ, 0.4, -0.7, 0.25),
        Vec3::new(3.0, -2.0, 5.0),
    );
    let w2i = world_to_index(&vol, world_from_volume).expect("invertible");
    // The CPU's inverse, in f64: world → index.
    let inv = (vdbcook_runtime::glam::Mat4::from(world_from_volume).as_dmat4()).inverse();
    // Points: inside the blobs' region (index 5..40), in world space.
    let mut rng = vdbcook_testkit::XorShift(12);
    let mut points = Vec::new();
    let mut index = Vec::new();
    while points.len() < 4000 {
        let p = [0, 1, 2].map(|_| rng.range(5.0, 40.0));
        // Skip points within 1e-3 of a rounding boundary (i + ½).
        if p.iter().any(|c| ((c + 0.5).fract() - 0.5).abs() > 0.499) {
            continue;
        }
        let w =
            world_from_volume.transform_point3(Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32));
        // The index the CPU sees for this (f32) world point, from the f64 inverse.
        let back = inv.transform_point3(w.as_dvec3());
        if (0..3).any(|a| ((back[a] + 0.5).fract() - 0.5).abs() > 0.499) {
            continue;
        }
        points.push([w.x, w.y, w.z, 1.0]);
        index.push([0, 1, 2].map(|a| (back[a] + 0.5).floor() as i64));
    }
    let mut nonzero = 0;
    for time in [0.0f32, 1.0, 2.0, 0.25, 1.6, 7.0] {
        let got = gpu_samples(&device, &queue, &vol, w2i.to_cols_array(), time, &points);
        let t = time.clamp(0.0, 2.0);
        let (f0, a) = (t.floor() as usize, t - t.floor());
        let f1 = (f0 + 1).min(2);
        for (k, idx) in index.iter().enumerate() {
            let v0 = asset.value(f0, *idx);
            let want = if a > 0.0 {
                v0 + (asset.value(f1, *idx) - v0) * a
            } else {
                v0
            };
            nonzero += (want != 0.0) as usize;
            assert!(
                (got[k] - want).abs() <= 1e-6 * want.abs().max(1.0),
                "time {time}, point {k} (index {idx:?}): gpu {}, cpu {want}",
                got[k]
            );
        }
    }
    assert!(nonzero > 2000, "the points hit the blobs ({nonzero})");
}

const NEAR_WGSL: &str = r#"
@group(0) @binding(0) var<storage, read> points: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> samples: array<f32>;

// Invocation i walks segment i / 2 (points 2j: origin, length; 2j + 1: direction): even i
// without a known leaf, odd i with the holder of the leaf its origin is in.
@compute @workgroup_size(64)
fn near_depths(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= arrayLength(&points)) {
        return;
    }
    let j = id.x & ~1u;
    var ray: VdbRay;
    ray.o = points[j].xyz;
    ray.d = points[j + 1u].xyz;
    ray.per_t = 1.0;
    let len = points[j].w;
    if ((id.x & 1u) == 0u) {
        samples[id.x] = vdb_optical_depth_near(0u, ray, 0.0, len, 0.0);
    } else {
        let cell = vec3<i32>(floor(ray.o));
        samples[id.x] = vdb_optical_depth_near_from(0u, ray, 0.0, len, 0.0, cell >> vec3<u32>(3u), vdb_holder(0u, cell));
    }
}
"#;

/// The exact optical depth of frame 0 along `o + t·d`, `t ∈ [0, len]`: the voxel values
/// (cell `floor(p)` holds `Asset::value` of that index) times the lengths between the sorted
/// crossings of integer planes, in f64.
fn exact_depth(asset: &Asset, o: [f64; 3], d: [f64; 3], len: f64) -> f64 {
    let mut ts = vec![0.0, len];
    for a in 0..3 {
        if d[a] == 0.0 {
            continue;
        }
        let (lo, hi) = (o[a].min(o[a] + len * d[a]), o[a].max(o[a] + len * d[a]));
        let mut k = lo.ceil();
        while k <= hi {
            let t = (k - o[a]) / d[a];
            if t > 0.0 && t < len {
                ts.push(t);
            }
            k += 1.0;
        }
    }
    ts.sort_by(f64::total_cmp);
    ts.windows(2)
        .map(|w| {
            let m = 0.5 * (w[0] + w[1]);
            let cell = [0, 1, 2].map(|a| (o[a] + m * d[a]).floor() as i64);
            (w[1] - w[0]) * asset.value(0, cell).max(0.0) as f64
        })
        .sum()
}

/// `vdb_optical_depth_near` (and `_from` with the origin's leaf known) equal the exact
/// integral on 3000 segments of 0.5–12 voxels through the blob: random directions, directions
/// along one or two axes (the DDA's zero steps and ties), origins on voxel planes.
#[test]
fn the_near_walk_integrates_the_voxels_exactly() {
    let Some((device, queue)) = gpu("the_near_walk_integrates_the_voxels_exactly") else {
        return;
    };
    let asset = asset();
    let vol = GpuVolume::upload(&device, &queue, &asset).unwrap();
    let mut rng = vdbcook_testkit::XorShift(31);
    let mut points = Vec::new();
    let mut segments = Vec::new();
    for k in 0..3000 {
        let mut o = [0, 1, 2].map(|_| rng.range(8.0, 32.0) as f32);
        if k % 7 == 0 {
            o[k % 3] = o[k % 3].floor();
        }
        let mut d = [0, 1, 2].map(|_| rng.range(-1.0, 1.0) as f32);
        match k % 5 {
            0 => d[k % 3] = 0.0,
            1 => {
                d = [0.0; 3];
                d[k % 3] = if k % 2 == 0 { 1.0 } else { -1.0 };
            }
            2 => d = [0.6, -0.6, 0.0],
            _ => {}
        }
        let n = d.iter().map(|c| c * c).sum::<f32>().sqrt();
        if n < 0.1 {
            continue;
        }
        let d = d.map(|c| c / n);
        let len = rng.range(0.5, 12.0) as f32;
        points.push([o[0], o[1], o[2], len]);
        points.push([d[0], d[1], d[2], 0.0]);
        segments.push((o.map(f64::from), d.map(f64::from), len as f64));
    }
    let source = format!("{}\n{NEAR_WGSL}", volume_wgsl(1));
    let (vol_layout, vol_group) = vol.bind_group();
    let got = vdbcook_testkit::gpu::eval_points(
        &device,
        &queue,
        &source,
        "near_depths",
        &vol.pipeline_constants(),
        &[(vol_layout, vol_group)],
        0,
        &points,
    );
    let mut dense = 0;
    for (j, (o, d, len)) in segments.iter().enumerate() {
        let want = exact_depth(&asset, *o, *d, *len);
        dense += (want > 1.0) as usize;
        for (k, what) in [(2 * j, "walk"), (2 * j + 1, "walk from a known leaf")] {
            // f32 crossings of planes up to 40 voxels from the origin: ~1e-5 each.
            assert!(
                (got[k] as f64 - want).abs() <= 1e-4 * (1.0 + want),
                "segment {j} ({what}): o {o:?} d {d:?} len {len}: gpu {}, exact {want}",
                got[k]
            );
        }
    }
    assert!(dense > 300, "segments through the blob: {dense}");
}
