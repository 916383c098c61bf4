//! PNG plots of the validation cases, drawn with `plotters`' pure-Rust bitmap
//! backend. Text uses DejaVu Sans, bundled in `assets/` (licence beside it) and
//! registered with `plotters`' `ab_glyph` support, so plots render on headless
//! machines without any system font or C library.

use heml::{HemlError, Result};
use plotters::prelude::*;
use std::path::Path;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

fn register_font() -> Result<()> {
    static ONCE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *ONCE.get_or_init(|| plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err(HemlError::Invalid("the bundled plot font could not be loaded".into()))
    }
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    /// A solid line.
    Line,
    /// Circles at the points.
    Points,
    /// A line with circles at the points.
    LinePoints,
}

/// One data series of a [`Chart`].
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// (x, y) data, in data units (log axes take positive values).
    pub points: Vec<(f64, f64)>,
    /// How it is drawn.
    pub mark: Mark,
}

impl Series {
    /// A series from its label, points and mark.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>, mark: Mark) -> Self {
        Series {
            label: label.into(),
            points,
            mark,
        }
    }
}

/// What a chart shows.
#[derive(Debug, Clone)]
pub enum ChartKind {
    /// x–y series.
    Xy(Vec<Series>),
    /// Grouped bars: one group per category, one bar per series in each group.
    Bars {
        /// Category names (x axis).
        groups: Vec<String>,
        /// (legend text, one value per group).
        series: Vec<(String, Vec<f64>)>,
    },
}

/// One panel of a figure.
#[derive(Debug, Clone)]
pub struct Chart {
    /// Panel caption.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Logarithmic x axis (x–y charts).
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// The data.
    pub kind: ChartKind,
}

impl Chart {
    /// An x–y chart with linear axes.
    pub fn xy(title: &str, x_label: &str, y_label: &str, series: Vec<Series>) -> Self {
        Chart {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            log_x: false,
            log_y: false,
            kind: ChartKind::Xy(series),
        }
    }
    /// Makes both axes logarithmic.
    pub fn log_log(mut self) -> Self {
        self.log_x = true;
        self.log_y = true;
        self
    }
    /// Makes the y axis logarithmic.
    pub fn log_y(mut self) -> Self {
        self.log_y = true;
        self
    }
}

/// `n + 1` evenly spaced values from `lo` to `hi`: where a chart draws a closed form.
pub fn linspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..=n).map(|k| lo + (hi - lo) * k as f64 / n as f64).collect()
}

const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

/// The legend every chart uses: upper left, on a translucent white box.
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(ctx: &mut ChartContext<'a, DB, CT>) -> Result<()> {
    ctx.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .position(SeriesLabelPosition::UpperLeft)
        .draw()
        .map_err(plot_err)
}

fn plot_err(e: impl std::fmt::Display) -> HemlError {
    HemlError::Invalid(format!("plot: {e}"))
}

/// The height of every plot, pixels (a 40-pixel title above the 480-pixel panels).
const HEIGHT: u32 = 520;

/// Draws `charts` side by side into a PNG at `path` (each panel 640×480 pixels).
/// The picture is drawn in memory and written atomically ([`heml::io::atomic`]): a
/// plot is either the new complete file or left as it was.
pub fn draw(path: &Path, title: &str, charts: &[Chart]) -> Result<()> {
    register_font()?;
    let width = 640 * charts.len().max(1) as u32;
    let mut rgb = vec![0u8; width as usize * HEIGHT as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let root = root.titled(title, ("sans-serif", 22)).map_err(plot_err)?;
        let panels = root.split_evenly((1, charts.len().max(1)));
        for (chart, area) in charts.iter().zip(panels) {
            match &chart.kind {
                ChartKind::Xy(series) => draw_xy(&area, chart, series)?,
                ChartKind::Bars { groups, series } => draw_bars(&area, chart, groups, series)?,
            }
        }
        root.present().map_err(plot_err)?;
    }
    heml::io::atomic::write_atomic(path, |w| write_png(w, width, HEIGHT, &rgb))
}

/// Encodes an 8-bit RGB picture as PNG.
fn write_png(w: impl std::io::Write, width: u32, height: u32, rgb: &[u8]) -> std::io::Result<()> {
    let mut encoder = png::Encoder::new(w, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(std::io::Error::other)?;
    writer.write_image_data(rgb).map_err(std::io::Error::other)?;
    writer.finish().map_err(std::io::Error::other)
}

fn axis(v: f64, log: bool) -> f64 {
    if log {
        v.log10()
    } else {
        v
    }
}

fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = if hi > lo {
        0.05 * (hi - lo)
    } else {
        0.5 * lo.abs().max(1.0)
    };
    (lo - pad, hi + pad)
}

fn tick(v: f64, log: bool) -> String {
    if log {
        format!("{:.0e}", 10f64.powf(v))
    } else if v != 0.0 && (v.abs() >= 1e4 || v.abs() < 1e-2) {
        format!("{v:.1e}")
    } else {
        format!("{v:.3}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    }
}

fn draw_xy(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    chart: &Chart,
    series: &[Series],
) -> Result<()> {
    let tx = |v: f64| axis(v, chart.log_x);
    let ty = |v: f64| axis(v, chart.log_y);
    let (x0, x1) = range(series.iter().flat_map(|s| s.points.iter().map(|p| tx(p.0))));
    let (y0, y1) = range(series.iter().flat_map(|s| s.points.iter().map(|p| ty(p.1))));
    let mut ctx = ChartBuilder::on(area)
        .caption(&chart.title, ("sans-serif", 17))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(plot_err)?;
    let (lx, ly) = (chart.log_x, chart.log_y);
    ctx.configure_mesh()
        .x_desc(&chart.x_label)
        .y_desc(&chart.y_label)
        .x_label_formatter(&|v| tick(*v, lx))
        .y_label_formatter(&|v| tick(*v, ly))
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(plot_err)?;
    for (k, s) in series.iter().enumerate() {
        let color = COLORS[k % COLORS.len()];
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .map(|p| (tx(p.0), ty(p.1)))
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .collect();
        let style = ShapeStyle::from(&color).stroke_width(2);
        match s.mark {
            Mark::Line => {
                ctx.draw_series(LineSeries::new(pts, style))
                    .map_err(plot_err)?
                    .label(&s.label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
            }
            Mark::Points => {
                ctx.draw_series(pts.iter().map(|&p| Circle::new(p, 4, style)))
                    .map_err(plot_err)?
                    .label(&s.label)
                    .legend(move |(x, y)| Circle::new((x + 9, y), 4, style));
            }
            Mark::LinePoints => {
                ctx.draw_series(LineSeries::new(pts.clone(), style))
                    .map_err(plot_err)?
                    .label(&s.label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
                ctx.draw_series(pts.iter().map(|&p| Circle::new(p, 3, style.filled())))
                    .map_err(plot_err)?;
            }
        }
    }
    draw_legend(&mut ctx)
}

fn draw_bars(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    chart: &Chart,
    groups: &[String],
    series: &[(String, Vec<f64>)],
) -> Result<()> {
    let ty = |v: f64| axis(v, chart.log_y);
    let vals = series.iter().flat_map(|s| s.1.iter().map(|v| ty(*v)));
    let (_, y1) = range(vals.clone());
    let y0 = if chart.log_y { range(vals).0.floor() } else { 0.0 };
    let n = groups.len() as f64;
    let mut ctx = ChartBuilder::on(area)
        .caption(&chart.title, ("sans-serif", 17))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(70)
        .build_cartesian_2d(-0.5..n - 0.5, y0..y1 * 1.1)
        .map_err(plot_err)?;
    let ly = chart.log_y;
    let names = groups.to_vec();
    ctx.configure_mesh()
        .disable_x_mesh()
        .x_labels(groups.len().max(1))
        .x_desc(&chart.x_label)
        .y_desc(&chart.y_label)
        .x_label_formatter(&move |v| {
            let i = v.round();
            if (v - i).abs() < 0.01 && i >= 0.0 && (i as usize) < names.len() {
                names[i as usize].clone()
            } else {
                String::new()
            }
        })
        .y_label_formatter(&|v| tick(*v, ly))
        .label_style(("sans-serif", 12))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(plot_err)?;
    let width = 0.8 / series.len().max(1) as f64;
    for (k, (label, values)) in series.iter().enumerate() {
        let color = COLORS[k % COLORS.len()];
        let bars = values.iter().enumerate().map(move |(g, v)| {
            let left = g as f64 - 0.4 + k as f64 * width;
            Rectangle::new([(left, y0), (left + width, ty(*v))], color.filled())
        });
        ctx.draw_series(bars)
            .map_err(plot_err)?
            .label(label)
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], color.filled()));
    }
    draw_legend(&mut ctx)
}
