//! The peers of `vdbcook report`, run on the same input in the same run when installed:
//! NanoVDB's `nanovdb_convert` (Fp4, Fp8, Fp16 and FpN at the report's tolerances: bytes, and
//! the voxel error measured by converting the `.nvdb` back to VDB and comparing every source
//! voxel, as `eval` does) and OpenVDB's `vdb_render` (single-scatter time at the same camera,
//! image size and medium). A missing tool is a note, not an error.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use vdbcook_trace::{Camera, RenderSettings};
use vdbcook_vdb::sequence::{self, Frame};

use crate::eval::{compare_frame, ErrStats};

/// One NanoVDB configuration's figures.
pub struct NanoRow {
    pub config: String,
    pub bytes: u64,
    pub seconds: f64,
    /// Error over the source's active voxels, when the round trip could be read.
    pub err: Option<ErrStats>,
}

/// Whether `tool` runs at all.
pub fn available(tool: &str) -> bool {
    Command::new(tool)
        .arg("--version")
        .output()
        .map(|_| true)
        .unwrap_or(false)
}

/// A grid name `nanovdb_convert -g` / `vdb_render -name` can take (not `#N` or `name[N]`).
fn plain(grid: &str) -> Option<&str> {
    (!grid.is_empty() && !grid.contains(['#', '[', ' '])).then_some(grid)
}

/// A scratch folder removed when dropped.
pub struct Scratch(pub PathBuf);

impl Scratch {
    pub fn new(what: &str) -> std::io::Result<Scratch> {
        let p = std::env::temp_dir().join(format!("vdbcook-{what}-{}", std::process::id()));
        std::fs::create_dir_all(&p)?;
        Ok(Scratch(p))
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn run(cmd: &mut Command) -> Result<String, String> {
    let o = cmd.output().map_err(|e| format!("{cmd:?}: {e}"))?;
    if !o.status.success() {
        return Err(format!(
            "{:?} failed: {}{}",
            cmd.get_program(),
            String::from_utf8_lossy(&o.stdout).trim(),
            String::from_utf8_lossy(&o.stderr).trim()
        ));
    }
    Ok(String::from_utf8_lossy(&o.stdout).into_owned())
}

/// Converts every frame with `opts`; sums bytes and seconds; measures the error of the round
/// trip against the sources (`select`: the grid option the cook had; `grid`: the name it found).
pub fn nanovdb(
    frames: &[Frame],
    select: Option<&str>,
    grid: &str,
    config: &str,
    opts: &[String],
    scratch: &Path,
) -> Result<NanoRow, String> {
    let mut bytes = 0u64;
    let mut seconds = 0.0;
    let mut back = Vec::new();
    for (i, f) in frames.iter().enumerate() {
        let nvdb = scratch.join(format!("f{i:05}.nvdb"));
        let vdb = scratch.join(format!("rt.{i:05}.vdb"));
        let mut c = Command::new("nanovdb_convert");
        c.arg("-f");
        if let Some(g) = plain(grid) {
            c.args(["-g", g]);
        }
        c.args(opts).arg(&f.path).arg(&nvdb);
        let t = Instant::now();
        run(&mut c)?;
        seconds += t.elapsed().as_secs_f64();
        bytes += std::fs::metadata(&nvdb).map_err(|e| e.to_string())?.len();
        run(Command::new("nanovdb_convert")
            .arg("-f")
            .arg(&nvdb)
            .arg(&vdb))?;
        let _ = std::fs::remove_file(&nvdb);
        back.push(vdb.to_string_lossy().into_owned());
    }
    // The round trip, cooked losslessly, compared with each source frame.
    let err = (|| -> Option<ErrStats> {
        let a = vdbcook_cook::CookOptions {
            grids: select.map_or(vdbcook_cook::Grids::Default, |g| {
                vdbcook_cook::Grids::One(g.to_string())
            }),
            allow_gaps: true,
            ..Default::default()
        };
        let rt = vdbcook_cook::cook_inputs(&back, &a, &vdbcook_cook::Context::quiet())
            .ok()?
            .asset;
        if rt.frame_count() != frames.len() {
            return None;
        }
        let mut total: Option<ErrStats> = None;
        for (fi, f) in frames.iter().enumerate() {
            let src = sequence::read_frame(f, select).ok()?;
            let s = compare_frame(&rt, fi, &src.grid);
            match &mut total {
                None => total = Some(s),
                Some(t) => t.merge(&s),
            }
        }
        total
    })();
    for b in &back {
        let _ = std::fs::remove_file(b);
    }
    Ok(NanoRow {
        config: config.to_string(),
        bytes,
        seconds,
        err,
    })
}

/// `vdb_render`'s arguments for the report's camera and settings (`vdbcook_trace::vdb_render`),
/// naming the grid when its name is one `-name` can take.
pub fn vdb_render_args(camera: &Camera, s: &RenderSettings, grid: &str) -> Vec<String> {
    vdbcook_trace::vdb_render::args(camera, s, plain(grid))
}

/// `vdb_render`'s run: its own render times (ms, from `-v`) and its last image (RGB8).
pub struct VdbRender {
    pub ms: Vec<f64>,
    pub rgb: Vec<u8>,
}

/// Renders `src` `runs` times with `args`.
pub fn vdb_render(
    src: &Path,
    args: &[String],
    runs: usize,
    scratch: &Path,
) -> Result<VdbRender, String> {
    let out = scratch.join("vdb_render.ppm");
    let mut ms = Vec::new();
    for _ in 0..runs.max(1) {
        let text = run(Command::new("vdb_render").arg(src).arg(&out).args(args))?;
        let t = vdbcook_trace::vdb_render::render_seconds(&text)
            .ok_or("vdb_render -v printed no render time")?;
        ms.push(t * 1e3);
    }
    // Some `vdb_render` builds drop the `.ppm` extension when they save.
    let bare = out.with_extension("");
    let bytes = std::fs::read(&out)
        .or_else(|_| std::fs::read(&bare))
        .map_err(|e| e.to_string())?;
    let (_, _, rgb) =
        vdbcook_trace::vdb_render::read_ppm(&bytes).ok_or("vdb_render wrote no readable PPM")?;
    Ok(VdbRender { ms, rgb })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_plain_grid_names_are_passed_on() {
        assert_eq!(plain("density"), Some("density"));
        assert_eq!(plain("#0"), None);
        assert_eq!(plain("density[1]"), None);
        assert_eq!(plain(""), None);
    }
}
