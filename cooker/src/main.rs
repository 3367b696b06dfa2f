//! `vdbcook`: the command-line front end over the `vdbcook` library (`lib.rs`). Each subcommand
//! lives in its own library module; this file parses arguments, sets up the thread pool, and
//! turns errors into one-line messages (or one JSON document under `--json`) with a non-zero
//! exit code.

use clap::{Parser, Subcommand};
use vdbcook::{
    bench, cook, errors, eval, gpu, info, inspect, output, progress, render, report, view,
};

/// Largest `--threads`.
const MAX_THREADS: usize = 1024;

#[derive(Parser)]
#[command(
    name = "vdbcook",
    version,
    about = "Cook OpenVDB sequences into compact flip-book volume assets for games",
    after_help = "Examples:\n  vdbcook inspect smoke.vdb\n  vdbcook inspect 'cache/smoke.####.vdb' --json\n  vdbcook inspect cache/ --allow-gaps"
)]
struct Cli {
    /// Worker threads, 1 to 1024 (default: all cores).
    #[arg(long, global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List the grids of VDB files: types, transforms, active voxels, bounds and value ranges.
    #[command(
        after_help = "INPUT may be files, a folder (all .vdb inside, in frame order), a frame \
pattern (smoke.####.vdb, smoke.%04d.vdb) or a glob ('smoke.*.vdb').\n\nExamples:\n  vdbcook inspect smoke.vdb\n  vdbcook inspect 'cache/smoke.####.vdb' --json"
    )]
    Inspect(inspect::Args),
    /// Cook a VDB sequence into one flip-book asset.
    #[command(
        after_help = "Every lossy cook keeps every voxel within an error budget as any GPU reads it \
whose BC decoding meets D3D's precision rule (docs/payloads.md): --max-error E, or by default \
10% of the value range (a guard against artefacts), or the smallest bound that fits --max-bytes.\n\nExamples:\n  vdbcook cook 'cache/smoke.####.vdb' -o smoke.vdbc\n  \
vdbcook cook cache/ -o smoke.vdbc --format f16 --json\n  vdbcook cook cache/ -o smoke.vdbc --max-error 0.01\n  \
vdbcook cook cache/ -o smoke.vdbc --max-bytes 4MiB --frames 10..90\n  vdbcook cook fire.vdb -o fire.vdbc --grid temperature\n  \
vdbcook cook --manifest volumes.toml --json    (batch, with a cache: docs/cli.md)"
    )]
    Cook(cook::Args),
    /// Describe an asset: header, frames, node counts, bytes by section.
    #[command(
        after_help = "Examples:\n  vdbcook info smoke.vdbc\n  vdbcook info smoke.vdbc --json"
    )]
    Info(info::Args),
    /// Compare an asset with its source files, voxel by voxel (RMSE, PSNR, max error).
    #[command(
        after_help = "Examples:\n  vdbcook eval smoke.vdbc 'cache/smoke.####.vdb'\n  vdbcook eval smoke.vdbc cache/ --json"
    )]
    Eval(eval::Args),
    /// Render one frame of an asset (or of VDB sources, cooked in memory) to a PNG (tone-mapped
    /// sRGB), a linear PFM or a linear EXR, on the CPU reference tracer or the GPU runtime,
    /// optionally over a background plate with scene depth.
    #[command(
        after_help = "MODE: density (1 − transmittance, plus emission), depth, first-hit, brick-hue, \
steps (false colours), scatter (vdb_render's single scattering), delta (delta tracking), reference \
(the CPU path tracer), lit (sun and sky with multiple scattering: the production look).\n\n\
By default fire glows by its tool's convention (--emission auto), the sun sits over the camera's \
shoulder (--light auto), the up axis follows the source (--up auto: Z for Blender), voxels are \
smoothed where they cover pixels (--filter auto) and PNGs are tone-mapped (--tonemap auto: PBR Neutral, none over a plate; \
--exposure 0).\n\nExamples:\n  vdbcook render smoke.vdbc -o smoke.png --mode lit\n  \
vdbcook render fire_cache/ -o fire.png --mode lit --exposure 0.5\n  \
vdbcook render smoke.vdbc -o f10.exr --frame 10 --mode lit --transparent --width 1280 --height 720\n  \
vdbcook render smoke.vdbc -o d.png --mode delta --spp 64 --camera 20,15,30,0,5,0,40 --json\n  \
vdbcook render smoke.vdbc -o comp.pfm --background plate.png --depth depth.pfm   (density over a scene)"
    )]
    Render(render::Args),
    /// Cook an input across formats, clustering and error bounds; chart size, cook time and
    /// trace time against error, with NanoVDB and vdb_render in the same run when installed.
    #[command(
        after_help = "Writes DIR/report.md (embedding the charts), report.json, report.csv, \
size_vs_error.png, cook_time_vs_error.png, trace_time_vs_error.png and renders.png.\n\n\
Examples:\n  vdbcook report fixtures/seq/smoke5 -o report/ --quick\n  \
vdbcook report wdas_cloud.vdb -o wdas-report/ --json\n  \
vdbcook report 'cache/smoke.####.vdb' -o r/ --tolerances 0.001,0.01 --mode density"
    )]
    Report(report::Args),
    /// Interactive viewer of an asset (or of VDB sources, cooked in memory) on the GPU runtime:
    /// orbit camera, flip-book playback, mode switch, frame time in the title; headless with
    /// --frames N --screenshot OUT.png.
    #[command(
        after_help = "Controls: left-drag orbits, wheel zooms, space plays/pauses (--fps), left/right arrows step a frame, m cycles modes (density, depth, first-hit, brick-hue, steps, scatter, delta, lit), r resets the camera, Esc quits.\n\nExamples:\n  vdbcook view smoke.vdbc\n  vdbcook view 'cache/smoke.####.vdb' --mode lit --fps 30 --exposure 0.5\n  vdbcook view smoke.vdbc --frames 5 --screenshot shot.png --json   (headless, no window)"
    )]
    View(view::Args),
    /// What an effect costs in a game on this GPU: the runtime's engine drawer, N instances,
    /// density and lit, static and playing (the flip-book at --fps under --display-fps), median
    /// GPU ms per displayed frame by timestamp queries, and the playing path's image error.
    #[command(
        after_help = "Takes render's look flags (--light, --emission, --filter, ...).\n\nExamples:\n  \
vdbcook bench smoke.vdbc\n  vdbcook bench cloud.vdbc --width 1920 --height 1080 --instances 1,8,64 --json\n  \
vdbcook bench fire.vdbc --modes lit --fps 30 --display-fps 120"
    )]
    Bench(bench::Args),
}

fn main() {
    // Piping into `head` must end the program quietly, not panic on a broken pipe.
    #[cfg(unix)]
    // SAFETY: restoring the default SIGPIPE action before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    output::install_signal_handlers();
    progress::hook_block_compressor();
    let cli = Cli::parse();
    let json = match &cli.command {
        Command::Inspect(a) => a.json,
        Command::Cook(a) => a.json,
        Command::Info(a) => a.json,
        Command::Eval(a) => a.json,
        Command::Render(a) => a.json,
        Command::Report(a) => a.json,
        Command::View(a) => a.json,
        Command::Bench(a) => a.json,
    };
    if matches!(
        cli.command,
        Command::Render(_) | Command::Report(_) | Command::View(_) | Command::Bench(_)
    ) {
        gpu::private_runtime_dir();
    }
    if let Some(n) = cli.threads {
        // Thousands of threads exhaust memory maps and hang the pool's start-up: refuse them.
        if !(1..=MAX_THREADS).contains(&n) {
            errors::fail(
                json,
                &errors::CliError::Usage(format!(
                    "--threads {n} is out of range: N must be 1 to {MAX_THREADS}"
                )),
            );
        }
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
        {
            errors::fail(
                json,
                &errors::CliError::Other(format!("cannot start {n} worker threads: {e}")),
            );
        }
    }
    let result = match &cli.command {
        Command::Inspect(a) => inspect::run(a),
        Command::Cook(a) => cook::run(a),
        Command::Info(a) => info::run(a),
        Command::Eval(a) => eval::run(a),
        Command::Render(a) => render::run(a),
        Command::Report(a) => report::run(a),
        Command::View(a) => view::run(a),
        Command::Bench(a) => bench::run(a),
    };
    if let Err(e) = result {
        errors::fail(json, &e);
    }
}
