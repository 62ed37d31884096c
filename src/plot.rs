//! Log–log line plots of convergence data, as PNG and SVG (plotters). The PNG is drawn into
//! an RGB buffer and encoded by the film module, so both files are written atomically and no
//! image crate is needed; text uses a bundled DejaVu Sans (assets/, its license beside it).
use crate::film::write_atomically;
use crate::{Error, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::io::Write;
use std::path::Path;
use std::sync::Once;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static REGISTER_FONT: Once = Once::new();

fn register() {
    // The bundled font is valid; if registering failed, text would be missing, not wrong.
    let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
}

/// One line: points `(x, y)` with a standard error on y (drawn as a vertical bar).
#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64, f64)>,
}

const COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];
const SIZE: (u32, u32) = (900, 600);

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| Error::InvalidOption(format!("plot: {e}"));
    let all = series.iter().flat_map(|s| s.points.iter()).filter(|p| p.0 > 0.0 && p.1 > 0.0);
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in all {
        (x0, x1, y0, y1) = (x0.min(p.0), x1.max(p.0), y0.min((p.1 - p.2).max(p.1 * 0.5)), y1.max(p.1 + p.2));
    }
    if x0 >= x1 {
        (x0, x1) = (x0.min(1.0) * 0.5, x1.max(1.0) * 2.0);
    }
    if y0 >= y1 {
        (y0, y1) = (y0.min(1.0) * 0.5, y1.max(1.0) * 2.0);
    }
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 24))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(80)
        .build_cartesian_2d((x0 * 0.9..x1 * 1.1).log_scale(), (y0 * 0.8..y1 * 1.25).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style(("sans-serif", 15))
        .light_line_style(WHITE)
        .bold_line_style(RGBColor(225, 225, 225))
        .x_labels(12)
        .y_labels(10)
        .x_label_formatter(&|x| compact(*x))
        .y_label_formatter(&|y| compact(*y))
        .draw()
        .map_err(err)?;
    for (k, s) in series.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let pts: Vec<(f64, f64)> = s.points.iter().filter(|p| p.0 > 0.0 && p.1 > 0.0).map(|p| (p.0, p.1)).collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(2)))
            .map_err(err)?
            .label(s.name.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled()))).map_err(err)?;
        chart
            .draw_series(
                s.points
                    .iter()
                    .filter(|p| p.0 > 0.0 && p.1 - p.2 > 0.0 && p.2 > 0.0)
                    .map(|p| PathElement::new(vec![(p.0, p.1 - p.2), (p.0, p.1 + p.2)], colour.stroke_width(1))),
            )
            .map_err(err)?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .draw()
        .map_err(err)?;
    root.present().map_err(err)
}

/// A short axis label: integers as such, other values to three significant digits.
fn compact(v: f64) -> String {
    if (1.0..1e5).contains(&v) && (v - v.round()).abs() < 1e-9 {
        format!("{}", v.round() as i64)
    } else if (1e-2..1e5).contains(&v.abs()) {
        format!("{:.3}", v).trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.1e}")
    }
}

/// Writes `stem.png` and `stem.svg`.
pub fn log_log(stem: &Path, title: &str, x_label: &str, y_label: &str, series: &[Series]) -> Result<()> {
    REGISTER_FONT.call_once(register);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        draw(&root, title, x_label, y_label, series)?;
    }
    let svg_path = stem.with_extension("svg");
    write_atomically(&svg_path, |w| w.write_all(svg.as_bytes()).map_err(|e| Error::io(&svg_path, e)))?;
    let mut rgb = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
        draw(&root, title, x_label, y_label, series)?;
    }
    crate::film::write_rgb8_png(&stem.with_extension("png"), SIZE.0, SIZE.1, &rgb)
}

/// Writes the images side by side, each under its caption (lines split at `\n`), as one PNG.
pub fn side_by_side(path: &Path, images: &[(String, &crate::film::Image)]) -> Result<()> {
    REGISTER_FONT.call_once(register);
    let (w, h) = images.first().map_or((1, 1), |(_, i)| (i.width, i.height));
    if images.iter().any(|(_, i)| (i.width, i.height) != (w, h)) {
        return Err(Error::InvalidOption("side-by-side images must share one size".into()));
    }
    let lines = images.iter().map(|(c, _)| c.lines().count()).max().unwrap_or(1) as u32;
    let header = 8 + 17 * lines;
    let (width, height) = (w * images.len().max(1) as u32, h + header);
    let mut rgb = vec![255u8; (width * height * 3) as usize];
    for (k, (_, image)) in images.iter().enumerate() {
        let src = crate::film::to_srgb8(image, 0.0);
        for y in 0..h {
            let dst = (((y + header) * width + k as u32 * w) * 3) as usize;
            let row = (y * w * 3) as usize;
            rgb[dst..dst + (w * 3) as usize].copy_from_slice(&src[row..row + (w * 3) as usize]);
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        let err = |e: DrawingAreaErrorKind<_>| Error::InvalidOption(format!("plot: {e}"));
        for (k, (caption, _)) in images.iter().enumerate() {
            for (l, line) in caption.lines().enumerate() {
                let at = (k as i32 * w as i32 + 6, 4 + 17 * l as i32);
                root.draw(&Text::new(line.to_string(), at, ("sans-serif", 14).into_font().color(&BLACK)))
                    .map_err(err)?;
            }
        }
        root.present().map_err(err)?;
    }
    crate::film::write_rgb8_png(path, width, height, &rgb)
}
