//! The pictures of `vdbcook report`: log-log scatter charts (one labelled point per
//! configuration, one colour per series) and the side-by-side figure of renders with their error
//! images. Drawn with `plotters` into an in-memory RGB buffer and written as PNG by the `png`
//! crate; text uses a font bundled in the binary (`cooker/assets/report-sans.ttf`, an ASCII and
//! Greek subset of DejaVu Sans), so charts render on a machine with no system fonts and no GPU.

use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

static FONT: &[u8] = include_bytes!("../../assets/report-sans.ttf");
const FAMILY: &str = "sans-serif";

fn init_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are compiled in and parse (a unit test checks): nothing to recover from.
        let _ = register_font(FAMILY, FontStyle::Normal, FONT);
    });
}

/// One point: `x` and `y` in data units (`x` may be 0: drawn at the axis floor, marked exact).
pub struct Point {
    pub label: String,
    pub x: f64,
    pub y: f64,
    pub series: usize,
}

/// A named series and its colour.
pub struct Series {
    pub name: String,
    pub color: RGBColor,
}

/// The series colours, in order (colour-blind-safe Okabe–Ito palette).
pub const PALETTE: [RGBColor; 6] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
];

fn tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let e = v.abs().log10();
    if (-2.0..4.0).contains(&e) {
        let s = format!("{v:.3}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        format!("{v:.0e}")
    }
}

/// The log axis range covering `v` (positive values), a little padded.
fn log_range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for x in v.filter(|x| *x > 0.0 && x.is_finite()) {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    if !lo.is_finite() {
        return (0.1, 10.0);
    }
    if hi / lo < 3.0 {
        let m = (hi * lo).sqrt();
        lo = m / 1.8;
        hi = m * 1.8;
    }
    (lo / 1.5, hi * 1.5)
}

fn err<E: std::fmt::Display>(e: E) -> String {
    format!("chart: {e}")
}

/// A log-log scatter chart as PNG bytes. Points with `x == 0` (exact) sit at the left edge of
/// the x axis, which is labelled so; points with a non-positive or non-finite `y` are left out.
pub fn scatter_chart(
    title: &str,
    x_desc: &str,
    y_desc: &str,
    series: &[Series],
    points: &[Point],
) -> Result<Vec<u8>, String> {
    init_font();
    let (w, h) = (1100u32, 700u32);
    let pts: Vec<&Point> = points
        .iter()
        .filter(|p| p.y > 0.0 && p.y.is_finite() && p.x.is_finite() && p.x >= 0.0)
        .collect();
    let nonzero = pts.iter().map(|p| p.x).filter(|x| *x > 0.0);
    let (mut x0, x1) = log_range(nonzero);
    let any_exact = pts.iter().any(|p| p.x == 0.0);
    if any_exact {
        x0 /= 3.0;
    }
    let floor = x0 * 1.4;
    let (y0, y1) = log_range(pts.iter().map(|p| p.y));
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FAMILY, 26))
            .margin(18)
            .x_label_area_size(56)
            .y_label_area_size(84)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(err)?;
        let xf = |v: &f64| {
            if any_exact && *v <= floor * 1.001 {
                "exact".to_string()
            } else {
                tick(*v)
            }
        };
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .x_label_formatter(&xf)
            .y_label_formatter(&|v| tick(*v))
            .label_style((FAMILY, 15))
            .axis_desc_style((FAMILY, 18))
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(205, 205, 205))
            .draw()
            .map_err(err)?;
        // Labels: greedy placement in pixel space — each label takes the first of eight spots
        // around its point that overlaps no point and no label placed before it.
        let px: Vec<(i32, i32)> = pts
            .iter()
            .map(|p| chart.backend_coord(&(if p.x == 0.0 { floor } else { p.x }, p.y)))
            .collect();
        let plot = chart.plotting_area().get_pixel_range();
        let mut taken: Vec<[i32; 4]> = px
            .iter()
            .map(|&(x, y)| [x - 7, y - 7, x + 7, y + 7])
            .collect();
        let mut placed: Vec<(String, (i32, i32), bool)> = Vec::new();
        for (p, &(x, y)) in pts.iter().zip(&px) {
            let label = if p.x == 0.0 {
                format!("{} (exact)", p.label)
            } else {
                p.label.clone()
            };
            let tw = (label.chars().count() as f64 * 7.6) as i32 + 4;
            let th = 16;
            let spots = [
                (9, -16, false),
                (9, 2, false),
                (-9, -16, true),
                (-9, 2, true),
                (-tw / 2, -26, false),
                (-tw / 2, 10, false),
                (9, -30, false),
                (9, 16, false),
            ];
            let rect = |(dx, dy, left): (i32, i32, bool)| {
                let x0 = if left { x + dx - tw } else { x + dx };
                [x0, y + dy, x0 + tw, y + dy + th]
            };
            let inside = |r: &[i32; 4]| {
                r[0] >= plot.0.start
                    && r[2] <= plot.0.end
                    && r[1] >= plot.1.start
                    && r[3] <= plot.1.end
            };
            let free = |r: &[i32; 4]| {
                taken
                    .iter()
                    .all(|t| r[2] <= t[0] || t[2] <= r[0] || r[3] <= t[1] || t[3] <= r[1])
            };
            let pick = spots
                .iter()
                .copied()
                .find(|&sp| inside(&rect(sp)) && free(&rect(sp)))
                .or_else(|| spots.iter().copied().find(|&sp| inside(&rect(sp))))
                .unwrap_or(spots[0]);
            let r = rect(pick);
            taken.push(r);
            placed.push((label, (r[0], r[1]), false));
        }
        for (si, s) in series.iter().enumerate() {
            let color = s.color;
            let mine: Vec<&&Point> = pts.iter().filter(|p| p.series == si).collect();
            if mine.is_empty() {
                continue;
            }
            chart
                .draw_series(mine.iter().map(|p| {
                    let x = if p.x == 0.0 { floor } else { p.x };
                    EmptyElement::at((x, p.y)) + Circle::new((0, 0), 6, color.filled())
                }))
                .map_err(err)?
                .label(s.name.clone())
                .legend(move |(x, y)| Circle::new((x + 8, y), 6, color.filled()));
        }
        for (label, at, _) in &placed {
            root.draw(&Text::new(
                label.clone(),
                *at,
                (FAMILY, 14).into_font().color(&RGBColor(40, 40, 40)),
            ))
            .map_err(err)?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.9))
            .border_style(RGBColor(160, 160, 160))
            .label_font((FAMILY, 15))
            .position(legend_corner(&pts, (x0, x1), (y0, y1), floor))
            .draw()
            .map_err(err)?;
        root.present().map_err(err)?;
    }
    png_rgb(w, h, &buf)
}

/// The corner of the plot with the fewest points near it, for the legend.
fn legend_corner(
    pts: &[&Point],
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
    floor: f64,
) -> SeriesLabelPosition {
    let unit = |v: f64, a: f64, b: f64| (v.ln() - a.ln()) / (b.ln() - a.ln());
    let mut count = [0usize; 4];
    for p in pts {
        let u = unit(if p.x == 0.0 { floor } else { p.x }, x0, x1);
        let v = unit(p.y, y0, y1);
        let right = u > 0.45;
        let top = v > 0.6;
        let near_bottom = v < 0.4;
        if top {
            count[if right { 1 } else { 0 }] += 1;
        }
        if near_bottom {
            count[if right { 3 } else { 2 }] += 1;
        }
    }
    let best = (0..4)
        .min_by_key(|&i| (count[i], [1, 0, 3, 2][i]))
        .unwrap_or(1);
    match best {
        0 => SeriesLabelPosition::UpperLeft,
        1 => SeriesLabelPosition::UpperRight,
        2 => SeriesLabelPosition::LowerLeft,
        _ => SeriesLabelPosition::LowerRight,
    }
}

/// One tile of the side-by-side figure: a render and its error image (RGB, same size).
pub struct Tile {
    pub title: String,
    pub subtitle: String,
    pub render: Vec<u8>,
    pub error: Option<Vec<u8>>,
}

/// Renders in a row, error images under them, titles above; `w × h` is each image's size.
pub fn side_by_side(
    caption: &str,
    tiles: &[Tile],
    w: u32,
    h: u32,
    footer: &str,
) -> Result<Vec<u8>, String> {
    init_font();
    let pad = 12u32;
    let head = 64u32;
    let top = 44u32;
    let bottom = 34u32;
    let cols = tiles.len().max(1) as u32;
    let fw = cols * (w + pad) + pad;
    let fh = top + head + 2 * h + pad * 2 + bottom;
    let mut buf = vec![255u8; (fw * fh * 3) as usize];
    for (c, t) in tiles.iter().enumerate() {
        let x0 = pad + c as u32 * (w + pad);
        blit(&mut buf, fw, &t.render, w, h, x0, top + head);
        if let Some(e) = &t.error {
            blit(&mut buf, fw, e, w, h, x0, top + head + h + pad);
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut buf, (fw, fh)).into_drawing_area();
        text(&root, caption, (pad as i32, 10), 22)?;
        for (c, t) in tiles.iter().enumerate() {
            let x0 = (pad + c as u32 * (w + pad)) as i32;
            text(&root, &t.title, (x0, (top + 4) as i32), 18)?;
            text(&root, &t.subtitle, (x0, (top + 30) as i32), 14)?;
            if t.error.is_none() {
                text(
                    &root,
                    "(reference)",
                    (x0 + 8, (top + head + h + pad + 8) as i32),
                    14,
                )?;
            }
        }
        text(&root, footer, (pad as i32, (fh - bottom + 10) as i32), 14)?;
        root.present().map_err(err)?;
    }
    png_rgb(fw, fh, &buf)
}

fn text(
    root: &DrawingArea<BitMapBackend<'_>, Shift>,
    s: &str,
    at: (i32, i32),
    size: u32,
) -> Result<(), String> {
    root.draw(&Text::new(
        s.to_string(),
        at,
        (FAMILY, size).into_font().color(&RGBColor(30, 30, 30)),
    ))
    .map_err(err)
}

fn blit(dst: &mut [u8], dw: u32, src: &[u8], w: u32, h: u32, x0: u32, y0: u32) {
    for y in 0..h {
        let d = (((y0 + y) * dw + x0) * 3) as usize;
        let s = (y * w * 3) as usize;
        dst[d..d + (w * 3) as usize].copy_from_slice(&src[s..s + (w * 3) as usize]);
    }
}

/// RGB8 bytes as a PNG file's bytes.
pub fn png_rgb(w: u32, h: u32, rgb: &[u8]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        // Charts are flat colour: the best deflate level and per-row filters keep them small
        // enough to commit under docs/.
        enc.set_compression(png::Compression::Best);
        enc.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
        let mut wr = enc.write_header().map_err(err)?;
        wr.write_image_data(rgb).map_err(err)?;
        wr.finish().map_err(err)?;
    }
    Ok(out)
}

/// A render's display RGB (linear RGBA, alpha = opacity) over black (as `vdb_render`), RGB8.
pub fn display_rgb(rgba: &[f32]) -> Vec<u8> {
    let bg = 0.0f32;
    rgba.chunks_exact(4)
        .flat_map(|p| {
            let a = p[3].clamp(0.0, 1.0);
            [0, 1, 2].map(|c| {
                let v = if p[c].is_finite() { p[c] } else { 0.0 } + (1.0 - a) * bg;
                (v.clamp(0.0, 1.0) * 255.0).round() as u8
            })
        })
        .collect()
}

/// |Δ| per pixel (largest RGB channel) times `gain`, through a black-red-yellow-white ramp.
pub fn error_rgb(a: &[f32], b: &[f32], gain: f32) -> Vec<u8> {
    a.chunks_exact(4)
        .zip(b.chunks_exact(4))
        .flat_map(|(p, q)| {
            let d = (0..3).fold(0.0f32, |m, c| m.max((p[c] - q[c]).abs()));
            heat((d * gain).clamp(0.0, 1.0))
        })
        .collect()
}

fn heat(t: f32) -> [u8; 3] {
    let r = (t * 3.0).clamp(0.0, 1.0);
    let g = (t * 3.0 - 1.0).clamp(0.0, 1.0);
    let b = (t * 3.0 - 2.0).clamp(0.0, 1.0);
    [r, g, b].map(|v| (v * 255.0).round() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bundled_font_parses_and_draws_text() {
        assert!(register_font("probe", FontStyle::Normal, FONT).is_ok());
        // Text must put ink on the page: an all-white chart would mean the font is missing.
        let png = side_by_side("Ag", &[], 8, 8, "").unwrap();
        let dec = png::Decoder::new(std::io::Cursor::new(png));
        let mut r = dec.read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size()];
        let info = r.next_frame(&mut buf).unwrap();
        assert!(buf[..info.buffer_size()].iter().any(|&v| v < 128));
    }

    #[test]
    fn charts_place_exact_points_and_skip_bad_ones() {
        let s = [Series {
            name: "a".into(),
            color: PALETTE[0],
        }];
        let p = |x, y| Point {
            label: "p".into(),
            x,
            y,
            series: 0,
        };
        let png = scatter_chart(
            "t",
            "x",
            "y",
            &s,
            &[p(0.0, 32.0), p(1e-3, 4.0), p(f64::NAN, 1.0), p(1e-2, 0.0)],
        )
        .unwrap();
        assert!(png.starts_with(&[0x89, b'P', b'N', b'G']));
    }

    #[test]
    fn error_ramp_is_black_at_zero_and_white_at_full_scale() {
        let a = [0.5f32, 0.5, 0.5, 1.0, 0.0, 0.0, 0.0, 1.0];
        let b = [0.5f32, 0.5, 0.5, 1.0, 1.0, 0.0, 0.0, 1.0];
        assert_eq!(error_rgb(&a, &b, 1.0), vec![0, 0, 0, 255, 255, 255]);
    }
}
