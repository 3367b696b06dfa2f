//! Headless use of the runtime, start to finish: load an asset file, upload it, render one frame
//! in density mode from the default view into a texture, read it back and write a PNG. Shows the
//! calls an engine makes (it owns the device, queue, encoder and texture).
//!
//! `cargo run -p vdbcook-runtime --example render_png -- ASSET.vdbc OUT.png [FRAME] [WxH]`

use std::process::ExitCode;

use vdbcook_runtime::{wgpu, Asset, Camera, GpuVolume, Renderer, Settings};

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("render_png: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        return Err("usage: render_png ASSET.vdbc OUT.png [FRAME] [WxH]".into());
    }
    let frame: usize = args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(0);
    let (w, h) = match args.get(4) {
        Some(s) => {
            let (a, b) = s.split_once('x').ok_or("size must be WxH")?;
            (a.parse::<u32>()?, b.parse::<u32>()?)
        }
        None => (640, 360),
    };
    let asset = Asset::load(&args[1]).map_err(|e| format!("{}: {e}", args[1]))?;

    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
    let adapter = pollster::block_on(instance.request_adapter(&Default::default()))
        .map_err(|e| format!("no GPU adapter ({e}); on Linux install mesa-vulkan-drivers"))?;
    eprintln!("adapter: {:?}", adapter.get_info().name);
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("render_png"),
        required_limits: adapter.limits(),
        // BC textures where the adapter has them (the upload falls back without).
        required_features: adapter.features() & vdbcook_runtime::OPTIONAL_FEATURES,
        ..Default::default()
    }))?;

    let volume = GpuVolume::upload(&device, &queue, &asset)?;
    eprintln!(
        "uploaded {} frames: {}",
        volume.frame_count(),
        volume.describe()
    );
    let format = wgpu::TextureFormat::Rgba8Unorm;
    let renderer = Renderer::new(&device, &volume, format)?;
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("render_png target"),
        size: wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let view = texture.create_view(&Default::default());
    let target = renderer.texture_target(&device, &texture, &view)?;
    if volume.frame_bbox(frame).is_none() {
        return Err(format!("frame {frame} stores nothing (or is not in the asset)").into());
    }
    // The default view, as `vdbcook render` frames it.
    let camera = Camera::framing(&asset, frame, w as f64 / h as f64)?;

    let row =
        (w * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("render_png readback"),
        size: row as u64 * h as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let start = std::time::Instant::now();
    let mut encoder = device.create_command_encoder(&Default::default());
    renderer.render(
        &queue,
        &mut encoder,
        &target,
        frame,
        &camera,
        &Settings::default(),
    )?;
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &readback,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: None,
            },
        },
        texture.size(),
    );
    queue.submit([encoder.finish()]);
    readback
        .slice(..)
        .map_async(wgpu::MapMode::Read, |r| r.expect("map readback"));
    device.poll(wgpu::PollType::wait_indefinitely())?;
    eprintln!(
        "rendered {w}x{h} in {:.1} ms",
        start.elapsed().as_secs_f64() * 1e3
    );
    let data =
        vdbcook_runtime::gpu_compat::mapped_range(&readback.slice(..)).ok_or("mapped range")?;
    let mut pixels = Vec::with_capacity((w * h * 4) as usize);
    for y in 0..h as usize {
        pixels.extend_from_slice(&data[y * row as usize..][..4 * w as usize]);
    }
    let file = std::io::BufWriter::new(std::fs::File::create(&args[2])?);
    let mut enc = png::Encoder::new(file, w, h);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()?.write_image_data(&pixels)?;
    eprintln!("wrote {}", args[2]);
    Ok(())
}
