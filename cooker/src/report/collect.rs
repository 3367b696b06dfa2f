//! `report`'s collect stage: cooks every configuration of the matrix, traces each (CPU always,
//! GPU when an adapter exists), measures sizes and errors, and runs the installed peers. Nothing
//! is written here; `figures` and `write` take what it returns.

use super::*;

/// What the collect stage measured: the rows, the peers' rows, the images, and what the
/// pictures and documents need to describe the run.
pub(super) struct Collected {
    pub(super) t_all: Instant,
    pub(super) rows: Vec<Row>,
    pub(super) peer_rows: Vec<PeerRow>,
    pub(super) images: Vec<Image>,
    pub(super) camera: Camera,
    pub(super) notes: Vec<String>,
    pub(super) gpu: Option<Gpu>,
    pub(super) gpu_layouts: Vec<String>,
    pub(super) vdbr_rgb: Option<Vec<u8>>,
    pub(super) tolerances: Vec<f64>,
    pub(super) configs: Vec<Config>,
    pub(super) value_range: f64,
    pub(super) active: u64,
    pub(super) grid_name: String,
    pub(super) frames: usize,
    pub(super) mode: Mode,
    pub(super) w: u32,
    pub(super) h: u32,
    pub(super) runs: usize,
    pub(super) progress: Progress,
    pub(super) nano: bool,
}

/// Collect: cooks every configuration, traces it, and runs the peers (nothing is written).
pub(super) fn collect(a: &Args) -> Result<Collected, CliError> {
    let t_all = Instant::now();
    let quick = a.quick;
    let (w, h) = (
        a.width.unwrap_or(if quick { 320 } else { 640 }),
        a.height.unwrap_or(if quick { 180 } else { 360 }),
    );
    let runs = a.runs.unwrap_or(if quick { 1 } else { 3 }).max(1);
    let tolerances = a.tolerances.clone().unwrap_or_else(|| {
        if quick {
            vec![0.01]
        } else {
            vec![0.002, 0.01, 0.05]
        }
    });
    if let Some(t) = tolerances.iter().find(|t| !(t.is_finite() && **t > 0.0)) {
        return Err(other(format!(
            "--tolerances: {t} is not a positive fraction of the value range"
        )));
    }
    if a.output.exists() && !a.output.is_dir() {
        return Err(other(format!(
            "{}: exists and is not a folder",
            a.output.display()
        )));
    }
    let frames = sequence::resolve_inputs(&a.inputs, a.allow_gaps)?;
    // The folder takes files (or can be made where it is missing) before minutes of cooks and
    // traces go into it; nothing is created until they succeed.
    if a.output.is_dir() {
        crate::output::check_writable(&a.output.join("report.json"), "report")?;
    } else {
        crate::output::check_writable(&a.output, "report folder")?;
    }
    if a.frame >= frames.len() {
        return Err(other(format!(
            "--frame {} is out of range: the input has {} frame(s)",
            a.frame,
            frames.len()
        )));
    }
    let mode = Mode::parse(&a.mode).expect("clap checked");
    let settings = RenderSettings {
        output: Output {
            width: w,
            height: h,
            frame: a.frame,
        },
        integrator: Integrator {
            mode,
            ..Default::default()
        },
        ..Default::default()
    };
    settings
        .validate(frames.len())
        .map_err(|e| other(format!("render settings: {e}")))?;
    let configs = matrix(quick, &tolerances);

    // Peers and GPU: decided up front so the progress total is right.
    let mut notes: Vec<String> = Vec::new();
    let gpu = if a.no_gpu {
        notes.push("GPU trace times: skipped (--no-gpu).".into());
        None
    } else {
        match Gpu::open() {
            Ok(g) => Some(g),
            Err(e) => {
                notes.push(format!("GPU trace times: skipped ({e})."));
                None
            }
        }
    };
    let nano = !a.no_peers && peers::available("nanovdb_convert");
    let vdbr = !a.no_peers && mode == Mode::SingleScatter && peers::available("vdb_render");
    if a.no_peers {
        notes.push("Peers: skipped (--no-peers).".into());
    } else {
        if !nano {
            notes.push(
                "NanoVDB: skipped (nanovdb_convert not found; Debian: libnanovdb-tools).".into(),
            );
        }
        if mode != Mode::SingleScatter {
            notes.push("vdb_render: skipped (it draws single scatter; use --mode scatter).".into());
        } else if !vdbr {
            notes.push("vdb_render: skipped (not found; Debian: libopenvdb-tools).".into());
        }
    }
    let nano_cfgs: Vec<(String, Vec<String>, Option<f64>)> = if nano {
        let mut v: Vec<(String, Vec<String>, Option<f64>)> = ["fp4", "fp8", "fp16"]
            .iter()
            .map(|f| (f.replace("fp", "Fp"), vec![format!("--{f}")], None))
            .collect();
        for &t in &tolerances {
            v.push((format!("FpN E={t}r"), vec!["--fpN".into()], Some(t)));
        }
        v
    } else {
        Vec::new()
    };
    let mut progress = Progress::new(configs.len() + nano_cfgs.len() + vdbr as usize + 1, a.json);

    // The f32 cook is the reference: its render is what image errors are measured against.
    let mut rows: Vec<Row> = Vec::new();
    let mut images: Vec<Image> = Vec::new();
    let mut camera: Option<Camera> = None;
    let mut value_range = 0.0f64;
    let mut active = 0u64;
    let mut grid_name = String::new();
    let mut gpu_layouts = Vec::new();
    for c in &configs {
        progress.step(&format!("cook + trace {}", c.label));
        let max_error = c.tolerance.map(|t| t * value_range);
        let ca = vdbcook_cook::CookOptions {
            grids: a
                .grid
                .clone()
                .map_or(vdbcook_cook::Grids::Default, vdbcook_cook::Grids::One),
            allow_gaps: a.allow_gaps,
            format: c
                .format
                .map(|f| vdbcook_asset::PayloadFormat::parse(f).expect("known format")),
            // A format's series is that format under its guard (BC falling back to unorm8 as
            // before); the max-error series take the cheapest representation, packed included.
            packed: c.format.is_none(),
            clustering: c.clusters.map(|(k, t)| vdbcook_cook::Clustering {
                variance_threshold: t,
                ..vdbcook_cook::Clustering::new(k)
            }),
            budget: match max_error {
                Some(e) => vdbcook_cook::Budget::MaxError {
                    all: Some(e as f32),
                    per: Vec::new(),
                },
                None => vdbcook_cook::Budget::Default,
            },
            ..Default::default()
        };
        let cx = vdbcook_cook::Context {
            hint_non_finite: false,
            ..vdbcook_cook::Context::quiet()
        };
        let cooked = vdbcook_cook::cook_inputs(&a.inputs, &ca, &cx)?;
        let d = &cooked.report;
        if camera.is_none() {
            // The reference (f32) cook.
            let r = cooked
                .asset
                .frame_ranges
                .iter()
                .fold([f32::INFINITY, f32::NEG_INFINITY], |m, r| {
                    [m[0].min(r[0]), m[1].max(r[1])]
                });
            value_range = if r[1] > r[0] {
                (r[1] - r[0]) as f64
            } else {
                1.0
            };
            active = d.active_voxels;
            grid_name = cooked.asset.header.grid_name.clone();
            // Its renders would march a level set as a fog: refused as `render` refuses it.
            crate::render::refuse_unshowable(
                &cooked.asset,
                std::path::Path::new(&a.inputs[0]),
                mode,
            )?;
            camera = Some(
                Camera::framing_up(
                    &cooked.asset,
                    a.frame,
                    w as f64 / h as f64,
                    vdbcook_trace::source_up(&cooked.asset),
                )
                .map_err(|e| other(format!("{}: {e}", a.inputs[0])))?,
            );
        }
        let cam = camera.as_ref().expect("set by the first cook");
        let (cpu_ms, img) = cpu_trace(&cooked.asset, cam, &settings, runs)?;
        let (mut gpu_ms, mut up_bytes, mut layout) = (None, None, None);
        if let Some(g) = &gpu {
            let up = g
                .upload(&cooked.asset)
                .map_err(|e| other(format!("{}: {e}", c.label)))?;
            let r = g
                .render(&up, cam, &settings, runs)
                .map_err(|e| other(format!("{}: {e}", c.label)))?;
            gpu_ms = Some(if r.gpu_ms.is_empty() {
                median(r.wall_ms)
            } else {
                median(r.gpu_ms)
            });
            up_bytes = Some(up.gpu_bytes());
            layout = Some(up.layout());
            gpu_layouts.push(format!("{}: {}", c.label, up.layout()));
        }
        let (im_rmse, im_max) = match images.first() {
            Some(reference) => image_error(&img, reference),
            None => (0.0, 0.0),
        };
        let s = &d.seconds;
        rows.push(Row {
            format: c.format.unwrap_or("auto").to_string(),
            clusters: d.clustering.as_ref().map(|c| c.clusters),
            max_error,
            bytes_gpu: d.bytes.topology + d.bytes.atlas,
            bytes_file: d.bytes.file,
            bits_per_active_voxel: d.bits_per_active_voxel,
            rmse: d.error.rmse,
            psnr_db: d.error.psnr_db,
            max_abs: d.error.max_abs,
            image_rmse: im_rmse,
            cook_seconds: s.total,
            trace_ms_cpu: cpu_ms,
            trace_ms_gpu: gpu_ms,
            label: c.label.clone(),
            variance_threshold: c.clusters.map(|(_, t)| t),
            bits_per_active_voxel_gpu: d.bits_per_active_voxel_gpu,
            image_max_abs: im_max,
            cook_stages: json!({"read": s.read, "build": s.build, "dedup": s.dedup,
                                "cluster": s.cluster, "encode": s.encode}),
            representations: d.representations.clone(),
            gpu_upload_bytes: up_bytes,
            gpu_layout: layout,
            nanovdb_bits_per_active_voxel: d.nanovdb.as_ref().map(|n| n.bits_per_active_voxel),
        });
        images.push(img);
    }
    let camera = camera.expect("at least one configuration");
    let reference = &images[0];

    // Peers.
    let scratch = peers::Scratch::new("report").map_err(|e| other(format!("temp dir: {e}")))?;
    let mut peer_rows: Vec<PeerRow> = Vec::new();
    let bpv = |b: u64| {
        if active > 0 {
            b as f64 * 8.0 / active as f64
        } else {
            f64::NAN
        }
    };
    for (name, opts, tol) in &nano_cfgs {
        progress.step(&format!("nanovdb_convert {name}"));
        let mut o = opts.clone();
        if let Some(t) = tol {
            o.push("-a".into());
            o.push(format!("{}", t * value_range));
        }
        match peers::nanovdb(&frames, a.grid.as_deref(), &grid_name, name, &o, &scratch.0) {
            Ok(r) => {
                if r.err.is_none() {
                    notes.push(format!(
                        "NanoVDB {name}: the round trip (nvdb → vdb) could not be compared with the source; no error figure."
                    ));
                }
                peer_rows.push(PeerRow {
                    tool: "nanovdb".into(),
                    config: r.config,
                    bytes_file: Some(r.bytes),
                    bytes_gpu: Some(r.bytes),
                    bits_per_active_voxel: Some(bpv(r.bytes)),
                    bits_per_active_voxel_gpu: Some(bpv(r.bytes)),
                    rmse: r.err.map(|e| e.rmse()),
                    psnr_db: r.err.and_then(|e| e.psnr_db()),
                    max_abs: r.err.map(|e| e.max_abs),
                    image_rmse: None,
                    cook_seconds: Some(r.seconds),
                    trace_ms_cpu: None,
                });
            }
            Err(e) => notes.push(format!("NanoVDB {name}: failed ({e}).")),
        }
    }
    let mut vdbr_rgb = None;
    if vdbr {
        progress.step("vdb_render");
        let args = peers::vdb_render_args(&camera, &settings, &grid_name);
        match peers::vdb_render(&frames[a.frame].path, &args, runs, &scratch.0) {
            Ok(r) => {
                // Against our f32 render as 8-bit RGB (vdb_render writes 8-bit PPM).
                let ours = reference.to_rgba8();
                let (mut sum, mut n) = (0.0f64, 0u64);
                for (p, q) in ours.chunks_exact(4).zip(r.rgb.chunks_exact(3)) {
                    for c in 0..3 {
                        let d = (p[c] as f64 - q[c] as f64) / 255.0;
                        sum += d * d;
                        n += 1;
                    }
                }
                peer_rows.push(PeerRow {
                    tool: "vdb_render".into(),
                    config: "source VDB, single scatter".into(),
                    bytes_file: None,
                    bytes_gpu: None,
                    bits_per_active_voxel: None,
                    bits_per_active_voxel_gpu: None,
                    rmse: Some(0.0),
                    psnr_db: None,
                    max_abs: Some(0.0),
                    image_rmse: Some((sum / n.max(1) as f64).sqrt()),
                    cook_seconds: None,
                    trace_ms_cpu: Some(median(r.ms)),
                });
                vdbr_rgb = Some(r.rgb);
            }
            Err(e) => notes.push(format!("vdb_render: failed ({e}).")),
        }
    }
    drop(scratch);
    Ok(Collected {
        t_all,
        rows,
        peer_rows,
        images,
        camera,
        notes,
        gpu,
        gpu_layouts,
        vdbr_rgb,
        tolerances,
        configs,
        value_range,
        active,
        grid_name,
        frames: frames.len(),
        mode,
        w,
        h,
        runs,
        progress,
        nano,
    })
}
