//! Figures: line plots with shaded bands (a task's stages), written as SVG or PNG with
//! `plotters`. The font (DejaVu Sans, see `DejaVuSans-LICENSE.txt`) is embedded, so a
//! plot needs no system fonts. Used by `gelgrip plot` and by the benches' plots. Tick
//! labels carry their unit and the decimals their step needs ([`axis`]).

use std::path::Path;
use std::sync::Once;

use anyhow::{Context, anyhow};
use plotters::coord::Shift;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

pub mod axis;

static FONT: &[u8] = include_bytes!("DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// One line; `None` values break it (a missing reading is not drawn as zero).
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend entry.
    pub name: String,
    /// (x, y) points, in x order.
    pub points: Vec<(f64, Option<f64>)>,
}

/// A shaded span of x with a label (a stage).
#[derive(Debug, Clone)]
pub struct Band {
    /// Start, in x units.
    pub from: f64,
    /// End, in x units.
    pub to: f64,
    /// Its label, written at the top.
    pub label: String,
}

/// A figure.
#[derive(Debug, Clone, Default)]
pub struct Figure {
    /// Title.
    pub title: String,
    /// X axis label, with units.
    pub x_label: String,
    /// Y axis label, with units.
    pub y_label: String,
    /// The unit on each x tick label (`s`, `Hz`), empty for none.
    pub x_unit: String,
    /// The unit on each y tick label (`mm³`, `%`), empty for none.
    pub y_unit: String,
    /// The lines.
    pub series: Vec<Series>,
    /// Shaded spans.
    pub bands: Vec<Band>,
    /// Mark each point as well as joining them (few points, as in a bench sweep).
    pub markers: bool,
    /// Where the legend goes (default upper right).
    pub legend: Option<SeriesLabelPosition>,
}

/// Image formats, chosen by the output file's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// `.svg`.
    Svg,
    /// `.png`.
    Png,
}

impl Format {
    /// The format of `path`, or a usage error naming the allowed extensions.
    pub fn of(path: &Path) -> anyhow::Result<Self> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("svg") => Ok(Self::Svg),
            Some("png") => Ok(Self::Png),
            _ => Err(crate::args::UsageError(format!(
                "{}: the figure's format comes from its extension: .svg or .png",
                path.display()
            ))
            .into()),
        }
    }
}

const WIDTH_PX: u32 = 1200;
const HEIGHT_PX: u32 = 600;
/// At most this many ticks along x, and along y.
const X_TICKS: usize = 10;
const Y_TICKS: usize = 8;

fn palette(i: usize) -> RGBColor {
    let c = Palette99::pick(i).to_rgba();
    RGBColor(c.0, c.1, c.2)
}

fn register_font() -> anyhow::Result<()> {
    let mut result = Ok(());
    REGISTER.call_once(|| {
        result = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
            .map_err(|_| anyhow!("the embedded font could not be loaded"));
    });
    result
}

/// Write `fig` to `out` (SVG or PNG by extension).
pub fn save(fig: &Figure, out: &Path) -> anyhow::Result<()> {
    let format = Format::of(out)?;
    register_font()?;
    let result = match format {
        Format::Svg => draw(
            fig,
            SVGBackend::new(out, (WIDTH_PX, HEIGHT_PX)).into_drawing_area(),
        ),
        Format::Png => draw(
            fig,
            BitMapBackend::new(out, (WIDTH_PX, HEIGHT_PX)).into_drawing_area(),
        ),
    };
    result.with_context(|| format!("drawing {}", out.display()))
}

/// An f64 axis whose ticks are [`axis::ticks`] (plotters' own steps are 1, 2 or 5 × 10^k;
/// its labels, Debug-formatted by default, are replaced by [`axis::tick_label`]).
struct Ticked {
    inner: RangedCoordf64,
    ticks: Vec<f64>,
}

impl Ticked {
    fn new(lo: f64, hi: f64, max_ticks: usize) -> Self {
        Self {
            inner: (lo..hi).into(),
            ticks: axis::ticks(lo, hi, max_ticks),
        }
    }
}

impl Ranged for Ticked {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.inner.map(value, limit)
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        // Grid lines at the ticks only (no light lines between them).
        if hint.weight().allow_light_points() {
            Vec::new()
        } else {
            self.ticks.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.inner.range()
    }
}

fn bounds(fig: &Figure) -> ((f64, f64), (f64, f64)) {
    let xs = fig
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.0))
        .chain(fig.bands.iter().flat_map(|b| [b.from, b.to]))
        .filter(|v| v.is_finite());
    let (x0, x1) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    let ys = fig
        .series
        .iter()
        .flat_map(|s| s.points.iter().filter_map(|p| p.1))
        .filter(|v| v.is_finite());
    let (y0, y1) = ys.fold((0.0f64, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    let (x0, x1) = if x0.is_finite() && x1 > x0 {
        (x0, x1)
    } else {
        (0.0, 1.0)
    };
    let y1 = if y1.is_finite() && y1 > y0 {
        y1 + 0.12 * (y1 - y0)
    } else {
        y0 + 1.0
    };
    (axis::range(x0, x1), axis::range(y0, y1))
}

fn draw<DB: DrawingBackend>(fig: &Figure, root: DrawingArea<DB, Shift>) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("{e:?}");
    root.fill(&WHITE).map_err(err)?;
    let ((x0, x1), (y0, y1)) = bounds(fig);
    let (x_step, y_step) = (axis::step(x0, x1, X_TICKS), axis::step(y0, y1, Y_TICKS));
    let mut chart = ChartBuilder::on(&root)
        .caption(&fig.title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(100)
        .build_cartesian_2d(Ticked::new(x0, x1, X_TICKS), Ticked::new(y0, y1, Y_TICKS))
        .map_err(err)?;
    let x_tick = |v: &f64| axis::tick_label(*v, x_step, &fig.x_unit);
    let y_tick = |v: &f64| axis::tick_label(*v, y_step, &fig.y_unit);
    chart
        .configure_mesh()
        .x_desc(&fig.x_label)
        .y_desc(&fig.y_label)
        .x_label_formatter(&x_tick)
        .y_label_formatter(&y_tick)
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    for (i, band) in fig.bands.iter().enumerate() {
        let shade = if i % 2 == 0 {
            RGBColor(70, 110, 200)
        } else {
            RGBColor(220, 140, 40)
        };
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(band.from, y0), (band.to, y1)],
                shade.mix(0.10).filled(),
            )))
            .map_err(err)?;
        // Labels alternate between two rows, so short neighbouring bands stay readable.
        let row = if i % 2 == 0 { 0.03 } else { 0.08 };
        chart
            .draw_series(std::iter::once(Text::new(
                band.label.clone(),
                (band.from + 0.005 * (x1 - x0), y1 - row * (y1 - y0)),
                ("sans-serif", 13).into_font().color(&BLACK),
            )))
            .map_err(err)?;
    }
    for (i, s) in fig.series.iter().enumerate() {
        let color = palette(i);
        let mut segments: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
        for (x, y) in &s.points {
            match y.filter(|v| v.is_finite()) {
                Some(y) => segments
                    .last_mut()
                    .map(|seg| seg.push((*x, y)))
                    .unwrap_or(()),
                None => segments.push(Vec::new()),
            }
        }
        let mut labelled = false;
        for seg in segments.into_iter().filter(|s| !s.is_empty()) {
            if fig.markers {
                chart
                    .draw_series(seg.iter().map(|p| Circle::new(*p, 4, color.filled())))
                    .map_err(err)?;
            }
            let drawn = chart
                .draw_series(LineSeries::new(seg, color.stroke_width(2)))
                .map_err(err)?;
            if !labelled {
                drawn.label(s.name.clone()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
                labelled = true;
            }
        }
    }
    if !fig.series.is_empty() {
        chart
            .configure_series_labels()
            .position(
                fig.legend
                    .clone()
                    .unwrap_or(SeriesLabelPosition::UpperRight),
            )
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

#[cfg(test)]
mod tests;
