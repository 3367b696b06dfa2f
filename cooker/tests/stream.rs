//! One uploader (issue 31): `GpuVolume::upload` is the streamed volume with the whole asset as
//! its window, so a multi-channel asset with levels of detail streams too. The fire fixture
//! cooked with three channels and `--lod all`, rendered lit with emission from its temperature
//! channel (the light volume reading the levels), through a two-frame window moved over the
//! sequence, is bit for bit the whole upload's image of the same frame.

mod common;

use std::sync::Arc;

use vdbcook_runtime::{Camera, GpuVolume, Readback, Renderer, StreamingVolume, UploadOptions};
use vdbcook_trace::{Emission, Integrator, Lighting, Medium, Mode, Output, RenderSettings};

fn render(
    gpu: &vdbcook::gpu::Gpu,
    volume: &GpuVolume,
    frame: usize,
    camera: &Camera,
    s: &RenderSettings,
) -> Readback {
    let (device, queue) = (gpu.device(), gpu.queue());
    let r = Renderer::with_emission(
        device,
        volume,
        vdbcook_runtime::wgpu::TextureFormat::Rgba8Unorm,
    )
    .unwrap();
    let target = r
        .buffer_target(device, s.output.width, s.output.height)
        .unwrap();
    let mut enc = device.create_command_encoder(&Default::default());
    r.render_to_buffer(queue, &mut enc, &target, frame, camera, s)
        .unwrap();
    queue.submit([enc.finish()]);
    target.read(device, queue)
}

#[test]
fn a_multi_channel_asset_with_levels_streams_as_it_uploads() {
    let gpu = match vdbcook::gpu::Gpu::open() {
        Ok(g) => g,
        Err(e) if !common::gpu_required() => {
            eprintln!("skipping: {e}");
            return;
        }
        Err(e) => panic!("{e}"),
    };
    let opts = vdbcook_cook::CookOptions {
        grids: vdbcook_cook::Grids::Several(vec![
            "density".into(),
            "temperature".into(),
            "flame".into(),
        ]),
        lod: Some(vdbcook_cook::Lod {
            levels: vdbcook_cook::Levels::All,
            first: 1,
        }),
        ..Default::default()
    };
    let fire = common::root().join("fixtures/seq/fire");
    let asset = vdbcook_cook::cook_inputs(
        &[fire.to_string_lossy().into_owned()],
        &opts,
        &vdbcook_cook::Context::quiet(),
    )
    .unwrap()
    .asset;
    assert_eq!(asset.channel_count(), 3);
    assert!(asset.header.lod_levels > 0);
    let s = |frame: usize| RenderSettings {
        output: Output {
            width: 64,
            height: 48,
            frame,
        },
        medium: Medium {
            emission: Some(Emission {
                range: [700.0, 1800.0],
                kelvin: [700.0, 1800.0],
                intensity: 1.0,
                channel: 1,
            }),
            ..Default::default()
        },
        lighting: Lighting {
            light_res: 16,
            ..Default::default()
        },
        integrator: Integrator {
            mode: Mode::Lit,
            ..Default::default()
        },
    };
    let camera = Camera::framing(&asset, 0, 64.0 / 48.0).unwrap();
    let (device, queue) = (gpu.device(), gpu.queue());
    let whole = GpuVolume::upload(device, queue, &asset).unwrap();
    let frames = asset.frame_count();
    let asset = Arc::new(asset);
    let mut stream = StreamingVolume::new(
        device,
        queue,
        asset.clone(),
        whole.gpu_bytes(),
        0..=1,
        UploadOptions {
            force: Some(whole.layout().layout),
        },
    )
    .unwrap();
    for f in 0..frames {
        if f > stream.window().1 {
            stream.advance(device, queue).unwrap();
        }
        let local = stream.local_frame(f).unwrap();
        let want = render(&gpu, &whole, f, &camera, &s(f));
        let got = render(&gpu, stream.volume(), local, &camera, &s(local));
        assert!(
            want.rgba.iter().any(|&v| v > 0.02),
            "frame {f}: a black image"
        );
        assert_eq!(got.rgba, want.rgba, "frame {f}");
    }
}
