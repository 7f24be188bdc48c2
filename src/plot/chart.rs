//! One Cartesian panel with line series: the shared piece of every curve plot.

use super::font::FONT_FAMILY;
use super::{PlotError, draw_error};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::ops::Range;

/// What one plot put on the canvas.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Drawn {
    pub panels: Vec<PanelDrawn>,
}

/// What one panel put on the canvas: its title, the series with their points, and any notice
/// written in place of data (for example "all rays vignetted").
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PanelDrawn {
    pub title: String,
    pub series: Vec<SeriesDrawn>,
    pub messages: Vec<String>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct SeriesDrawn {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

impl Drawn {
    /// Every message of every panel.
    pub fn messages(&self) -> impl Iterator<Item = &str> {
        self.panels
            .iter()
            .flat_map(|p| p.messages.iter().map(String::as_str))
    }

    /// The series with this label in the panel whose title contains `panel`.
    pub fn series(&self, panel: &str, label: &str) -> Option<&SeriesDrawn> {
        self.panels
            .iter()
            .filter(|p| p.title.contains(panel))
            .flat_map(|p| &p.series)
            .find(|s| s.label == label)
    }
}

/// A line (or marker) series in data coordinates.
#[derive(Clone, Debug)]
pub(crate) struct Series {
    pub label: String,
    pub color: RGBColor,
    pub dashed: bool,
    pub markers: bool,
    pub points: Vec<(f64, f64)>,
}

/// A panel to draw: title, axis labels with units, series; `empty_message` is written across the
/// panel when no series has a point.
pub(crate) struct Panel<'a> {
    pub title: String,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub series: Vec<Series>,
    pub empty_message: String,
    /// Fixed ranges where the quantity has natural bounds (pupil -1..1, fraction 0..1).
    pub x_range: Option<Range<f64>>,
    pub y_range: Option<Range<f64>>,
    pub title_size: u32,
}

pub(crate) const LABEL_SIZE: u32 = 16;

/// A range covering `values` with a margin; zero is always included because every aberration
/// curve is read against it. Degenerate data gets a small symmetric range.
pub(crate) fn range_with_zero(values: impl Iterator<Item = f64>) -> Range<f64> {
    let (mut low, mut high) = (0.0f64, 0.0f64);
    for v in values.filter(|v| v.is_finite()) {
        low = low.min(v);
        high = high.max(v);
    }
    let span = high - low;
    if span <= f64::EPSILON * (low.abs() + high.abs()).max(1e-300) || span == 0.0 {
        let half = (low.abs().max(high.abs()) * 0.1).max(1e-6);
        return (low - half)..(high + half);
    }
    let pad = 0.06 * span;
    (low - pad)..(high + pad)
}

/// A range symmetric about zero covering `values`.
pub(crate) fn symmetric_range(values: impl Iterator<Item = f64>) -> Range<f64> {
    let r = range_with_zero(values);
    let half = r.start.abs().max(r.end.abs());
    -half..half
}

pub(crate) fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: Panel,
) -> Result<PanelDrawn, PlotError> {
    let has_points = panel.series.iter().any(|s| !s.points.is_empty());
    // No data: the title and a note, not a frame whose made-up axes look like a result.
    if !has_points {
        let body = area
            .margin(8, 0, 0, 0)
            .titled(&panel.title, (FONT_FAMILY, panel.title_size))
            .map_err(draw_error)?;
        draw_notice(&body, &panel.empty_message)?;
        return Ok(PanelDrawn {
            title: panel.title.clone(),
            series: Vec::new(),
            messages: vec![panel.empty_message.clone()],
        });
    }
    let x_range = panel.x_range.clone().unwrap_or_else(|| {
        range_with_zero(
            panel
                .series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.0)),
        )
    });
    let y_range = panel.y_range.clone().unwrap_or_else(|| {
        range_with_zero(
            panel
                .series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.1)),
        )
    });
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, (FONT_FAMILY, panel.title_size))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(78)
        .build_cartesian_2d(x_range.clone(), y_range.clone())
        .map_err(draw_error)?;
    chart
        .configure_mesh()
        .x_desc(panel.x_label)
        .y_desc(panel.y_label)
        .label_style((FONT_FAMILY, LABEL_SIZE))
        .axis_desc_style((FONT_FAMILY, LABEL_SIZE + 1))
        .x_labels(7)
        .y_labels(7)
        .x_label_formatter(&|v| tick_label(*v))
        .y_label_formatter(&|v| tick_label(*v))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(205, 205, 205))
        .draw()
        .map_err(draw_error)?;
    let axis = BLACK.mix(0.6).stroke_width(1);
    if x_range.start < 0.0 && x_range.end > 0.0 {
        chart
            .draw_series(LineSeries::new(
                [(0.0, y_range.start), (0.0, y_range.end)],
                axis,
            ))
            .map_err(draw_error)?;
    }
    if y_range.start < 0.0 && y_range.end > 0.0 {
        chart
            .draw_series(LineSeries::new(
                [(x_range.start, 0.0), (x_range.end, 0.0)],
                axis,
            ))
            .map_err(draw_error)?;
    }
    let mut drawn = PanelDrawn {
        title: panel.title.clone(),
        ..PanelDrawn::default()
    };
    for series in &panel.series {
        if series.points.is_empty() {
            continue;
        }
        let style = series.color.stroke_width(2);
        let color = series.color;
        let dashed = series.dashed;
        let annotation = if series.dashed {
            chart
                .draw_series(DashedLineSeries::new(
                    series.points.iter().copied(),
                    8,
                    5,
                    style,
                ))
                .map_err(draw_error)?
        } else {
            chart
                .draw_series(LineSeries::new(series.points.iter().copied(), style))
                .map_err(draw_error)?
        };
        if !series.label.is_empty() {
            annotation.label(&series.label).legend(move |(x, y)| {
                if dashed {
                    PathElement::new(vec![(x, y), (x + 8, y)], color.stroke_width(2))
                } else {
                    PathElement::new(vec![(x, y), (x + 22, y)], color.stroke_width(2))
                }
            });
        }
        if series.markers {
            chart
                .draw_series(
                    series
                        .points
                        .iter()
                        .map(|&p| Circle::new(p, 3, color.filled())),
                )
                .map_err(draw_error)?;
        }
        drawn.series.push(SeriesDrawn {
            label: series.label.clone(),
            points: series.points.clone(),
        });
    }
    if panel.series.iter().any(|s| !s.label.is_empty()) {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((FONT_FAMILY, LABEL_SIZE))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.5))
            .draw()
            .map_err(draw_error)?;
    }
    Ok(drawn)
}

/// Writes `message` centred on `area`, in a box so it cannot be mistaken for data.
pub(crate) fn draw_notice<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    message: &str,
) -> Result<(), PlotError> {
    let (width, height) = area.dim_in_pixel();
    let red = RGBColor(160, 0, 0);
    let style = TextStyle::from((FONT_FAMILY, 22).into_font()).color(&red);
    let (text_width, text_height) = area
        .estimate_text_size(message, &style)
        .map_err(draw_error)?;
    let (cx, cy) = (width as i32 / 2, height as i32 / 2);
    let (half_width, half_height) = (text_width as i32 / 2 + 16, text_height as i32 / 2 + 12);
    let corners = [
        (cx - half_width, cy - half_height),
        (cx + half_width, cy + half_height),
    ];
    area.draw(&Rectangle::new(corners, WHITE.filled()))
        .map_err(draw_error)?;
    area.draw(&Rectangle::new(corners, red.stroke_width(2)))
        .map_err(draw_error)?;
    let top_left = (cx - text_width as i32 / 2, cy - text_height as i32 / 2);
    area.draw(&Text::new(message.to_string(), top_left, style))
        .map_err(draw_error)?;
    Ok(())
}

/// Writes a short note in the bottom-left corner of `area`, below the axis labels' baseline:
/// what a panel leaves out and why.
pub(crate) fn draw_footnote<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    note: &str,
) -> Result<(), PlotError> {
    let (_, height) = area.dim_in_pixel();
    let style =
        TextStyle::from((FONT_FAMILY, LABEL_SIZE - 3).into_font()).color(&RGBColor(160, 0, 0));
    area.draw(&Text::new(note.to_string(), (6, height as i32 - 16), style))
        .map_err(draw_error)
}

/// Tick labels with few significant digits and no float noise ("0.1", "-2e-4", "0").
pub(crate) fn tick_label(value: f64) -> String {
    if value == 0.0 || value.abs() < 1e-12 {
        return "0".into();
    }
    let magnitude = value.abs();
    if (1e-3..1e5).contains(&magnitude) {
        let decimals = (3 - magnitude.log10().floor() as i32).clamp(0, 6) as usize;
        let text = format!("{value:.decimals$}");

        if text.contains('.') {
            text.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            text
        }
    } else {
        format!("{value:.2e}")
    }
}

/// Writes a figure title across the top of `area` and splits the rest into a rows x cols grid,
/// returned row by row.
pub(crate) fn titled_grid<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    rows: usize,
    cols: usize,
) -> Result<Vec<DrawingArea<DB, Shift>>, PlotError> {
    let body = area
        .margin(8, 0, 0, 0)
        .titled(title, (FONT_FAMILY, 28))
        .map_err(draw_error)?;
    Ok(body.split_evenly((rows.max(1), cols.max(1))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_include_zero_and_the_data() {
        let r = range_with_zero([1.0, 3.0].into_iter());
        assert!(r.start <= 0.0 && r.end >= 3.0);
        let s = symmetric_range([-0.5, 2.0].into_iter());
        assert_eq!(s.start, -s.end);
        assert!(s.end >= 2.0);
        let flat = range_with_zero([0.0, 0.0].into_iter());
        assert!(flat.end > flat.start);
    }

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick_label(0.0), "0");
        assert_eq!(tick_label(0.1 + 0.2), "0.3");
        assert_eq!(tick_label(-25.0), "-25");
        assert_eq!(tick_label(1.5e-5), "1.50e-5");
    }
}
