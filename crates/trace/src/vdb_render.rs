//! OpenVDB's `vdb_render`, the peer the tracer is measured against: its command line for a
//! tracer camera and settings (so both draw the same single-scatter picture), the render time it
//! prints under `-v`, and its PPM output. Used by the `vs_vdb_render` bench and by
//! `vdbcook report`; nothing here runs the program.

use crate::{Camera, RenderSettings};

/// `vdb_render`'s arguments for single scatter with `camera` and `s` spelled out, on all CPUs,
/// verbose (for the render time), reading grid `grid` (its first float grid when `None`). Its
/// `-fov` is horizontal (the focal length comes from the horizontal 41.2 mm aperture), the
/// tracer's vertical.
pub fn args(camera: &Camera, s: &RenderSettings, grid: Option<&str>) -> Vec<String> {
    let aspect = s.output.width as f64 / s.output.height as f64;
    let hfov = 2.0 * ((camera.fov_y_deg.to_radians() * 0.5).tan() * aspect).atan();
    let v3 = |v: [f64; 3]| format!("{},{},{}", v[0], v[1], v[2]);
    let g = |v: f32| format!("{v},{v},{v}");
    let (l, c) = (s.lighting.light_dir, s.lighting.light_color);
    let mut a: Vec<String> = vec![
        "-res".into(),
        format!("{}x{}", s.output.width, s.output.height),
        "-translate".into(),
        v3(camera.eye),
        "-lookat".into(),
        v3(camera.look_at),
        "-up".into(),
        v3(camera.up),
        "-fov".into(),
        format!("{}", hfov.to_degrees()),
        "-absorb".into(),
        g(s.medium.absorb),
        "-scatter".into(),
        g(s.medium.scatter),
        "-light".into(),
        format!("{},{},{},{},{},{}", l[0], l[1], l[2], c[0], c[1], c[2]),
        "-step".into(),
        format!("{}", s.integrator.step),
        "-shadowstep".into(),
        format!("{}", s.integrator.shadow_step),
        "-cutoff".into(),
        format!("{}", s.integrator.cutoff),
        "-gain".into(),
        format!("{}", s.integrator.gain),
        "-cpus".into(),
        "0".into(),
        "-v".into(),
    ];
    if let Some(g) = grid {
        a.extend(["-name".into(), g.to_string()]);
    }
    a
}

/// The ray-tracing time in seconds from `vdb_render -v`'s output ("…: ray-tracing …" then
/// "…: ...completed in 1.13 sec").
pub fn render_seconds(stdout: &str) -> Option<f64> {
    stdout
        .lines()
        .skip_while(|l| !l.contains("ray-tracing"))
        .find_map(|l| {
            let rest = l.split("completed in ").nth(1)?;
            rest.trim_end_matches(" sec").trim().parse::<f64>().ok()
        })
}

/// Width, height and RGB bytes of a binary PPM (P6, maxval 255), or `None` if it is not one.
pub fn read_ppm(bytes: &[u8]) -> Option<(u32, u32, Vec<u8>)> {
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
    let (w, h): (u32, u32) = (fields[1].parse().ok()?, fields[2].parse().ok()?);
    let data = bytes.get(i + 1..)?;
    (data.len() == w as usize * h as usize * 3).then(|| (w, h, data.to_vec()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ppm_reader_takes_comments_and_refuses_short_data() {
        let mut p = b"P6\n# c\n2 1\n255\n".to_vec();
        p.extend([1, 2, 3, 4, 5, 6]);
        assert_eq!(read_ppm(&p), Some((2, 1, vec![1, 2, 3, 4, 5, 6])));
        p.pop();
        assert_eq!(read_ppm(&p), None);
        assert_eq!(read_ppm(b"P6 2"), None);
        assert_eq!(read_ppm(b"P3\n1 1\n255\n1 2 3"), None);
    }

    #[test]
    fn render_time_is_read_after_the_ray_tracing_line() {
        let out = "a: loading...completed in 0.5 sec\nb: ray-tracing density\nb: ...completed in 1.13 sec\n";
        assert_eq!(render_seconds(out), Some(1.13));
        assert_eq!(render_seconds("x: ...completed in 2 sec"), None);
    }

    #[test]
    fn horizontal_fov_and_grid_name_are_spelled_out() {
        let cam = Camera {
            eye: [1.0, 2.0, 3.0],
            look_at: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 40.0,
        };
        let s = RenderSettings::default(); // 640×360
        let a = args(&cam, &s, Some("density"));
        let fov: f64 = a[a.iter().position(|x| x == "-fov").unwrap() + 1]
            .parse()
            .unwrap();
        // tan(h/2) = tan(20°)·16/9.
        assert!((fov - 65.81043501721129).abs() < 1e-9, "{fov}");
        assert_eq!(
            a[a.len() - 2..],
            ["-name".to_string(), "density".to_string()]
        );
        assert!(!args(&cam, &s, None).contains(&"-name".to_string()));
    }
}
