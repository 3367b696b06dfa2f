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

use crate::cook;
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
        let mut a = cook::Args::defaults(back.clone(), scratch.join("rt.vdbc"));
        a.grid = select.map(str::to_string);
        a.allow_gaps = true;
        let rt = cook::cook(&a).ok()?.asset;
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

/// `vdb_render`'s arguments for single scatter with `camera` and `s` spelled out. Its `-fov` is
/// horizontal (the focal length comes from the horizontal 41.2 mm aperture); ours is vertical.
pub fn vdb_render_args(camera: &Camera, s: &RenderSettings, grid: &str) -> Vec<String> {
    let aspect = s.width as f64 / s.height as f64;
    let hfov = 2.0 * ((camera.fov_y_deg.to_radians() * 0.5).tan() * aspect).atan();
    let v3 = |v: [f64; 3]| format!("{},{},{}", v[0], v[1], v[2]);
    let g = |v: f32| format!("{v},{v},{v}");
    let (l, c) = (s.light_dir, s.light_color);
    let mut a: Vec<String> = vec![
        "-res".into(),
        format!("{}x{}", s.width, s.height),
        "-translate".into(),
        v3(camera.eye),
        "-lookat".into(),
        v3(camera.look_at),
        "-up".into(),
        v3(camera.up),
        "-fov".into(),
        format!("{}", hfov.to_degrees()),
        "-absorb".into(),
        g(s.absorb),
        "-scatter".into(),
        g(s.scatter),
        "-light".into(),
        format!("{},{},{},{},{},{}", l[0], l[1], l[2], c[0], c[1], c[2]),
        "-step".into(),
        format!("{}", s.step),
        "-shadowstep".into(),
        format!("{}", s.shadow_step),
        "-cutoff".into(),
        format!("{}", s.cutoff),
        "-gain".into(),
        format!("{}", s.gain),
        "-cpus".into(),
        "0".into(),
        "-v".into(),
    ];
    if let Some(g) = plain(grid) {
        a.extend(["-name".into(), g.to_string()]);
    }
    a
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
        // "…: ray-tracing …" then "…: ...completed in 1.13 sec".
        let t = text
            .lines()
            .skip_while(|l| !l.contains("ray-tracing"))
            .find_map(|l| {
                let rest = l.split("completed in ").nth(1)?;
                rest.trim_end_matches(" sec").trim().parse::<f64>().ok()
            })
            .ok_or("vdb_render -v printed no render time")?;
        ms.push(t * 1e3);
    }
    let bytes = std::fs::read(&out).map_err(|e| e.to_string())?;
    let rgb = read_ppm(&bytes).ok_or("vdb_render wrote no readable PPM")?;
    Ok(VdbRender { ms, rgb })
}

/// A binary PPM's (P6, maxval 255) RGB bytes.
fn read_ppm(bytes: &[u8]) -> Option<Vec<u8>> {
    let mut fields = Vec::new();
    let mut i = 0;
    while fields.len() < 4 {
        while bytes.get(i)?.is_ascii_whitespace() {
            i += 1;
        }
        if bytes[i] == b'#' {
            while *bytes.get(i)? != b'\n' {
                i += 1;
            }
            continue;
        }
        let start = i;
        while !bytes.get(i)?.is_ascii_whitespace() {
            i += 1;
        }
        fields.push(String::from_utf8_lossy(&bytes[start..i]).into_owned());
    }
    if fields[0] != "P6" || fields[3] != "255" {
        return None;
    }
    let (w, h): (usize, usize) = (fields[1].parse().ok()?, fields[2].parse().ok()?);
    let data = bytes.get(i + 1..)?;
    (data.len() == w * h * 3).then(|| data.to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ppm_reader_takes_comments_and_refuses_short_data() {
        let mut p = b"P6\n# c\n2 1\n255\n".to_vec();
        p.extend([1, 2, 3, 4, 5, 6]);
        assert_eq!(read_ppm(&p), Some(vec![1, 2, 3, 4, 5, 6]));
        p.pop();
        assert_eq!(read_ppm(&p), None);
        assert_eq!(read_ppm(b"P6 2"), None);
    }

    #[test]
    fn only_plain_grid_names_are_passed_on() {
        assert_eq!(plain("density"), Some("density"));
        assert_eq!(plain("#0"), None);
        assert_eq!(plain("density[1]"), None);
        assert_eq!(plain(""), None);
    }
}
