//! Seidel bar chart: S_I..S_V per surface, then their sums.

use super::chart::{LABEL_SIZE, range_with_zero, tick_label};
use super::color::PALETTE;
use super::font::FONT_FAMILY;
use super::{Drawn, PanelDrawn, PlotError, SeriesDrawn, View, draw_error};
use plotters::coord::Shift;
use plotters::prelude::*;

/// The five Seidel sums of one surface (Welford convention, mm).
#[derive(Clone, Debug, PartialEq)]
pub struct SeidelBar {
    /// 1-based surface number.
    pub surface: usize,
    pub terms: [f64; 5],
}

#[derive(Clone, Debug, PartialEq)]
pub struct SeidelPlot {
    pub lens: String,
    pub wavelength_nm: f64,
    pub surfaces: Vec<SeidelBar>,
    pub sums: [f64; 5],
}

const TERM_NAMES: [&str; 5] = ["S_I", "S_II", "S_III", "S_IV", "S_V"];

impl View for SeidelPlot {
    fn size(&self) -> (u32, u32) {
        ((240 + 70 * (self.surfaces.len() as u32 + 1)).max(900), 720)
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let groups = self.surfaces.len() + 1;
        let values = self
            .surfaces
            .iter()
            .map(|s| s.terms)
            .chain([self.sums])
            .flat_map(|t| t.into_iter());
        let y_range = range_with_zero(values);
        let title = format!(
            "{}: Seidel sums per surface ({:.1} nm)",
            self.lens, self.wavelength_nm
        );
        let mut chart = ChartBuilder::on(area)
            .caption(&title, (FONT_FAMILY, 26))
            .margin(12)
            .x_label_area_size(48)
            .y_label_area_size(84)
            .build_cartesian_2d(-0.5..(groups as f64 - 0.5), y_range)
            .map_err(draw_error)?;
        let label_of = |x: f64| -> String {
            let i = x.round();
            if (x - i).abs() > 1e-6 || i < 0.0 || i as usize >= groups {
                String::new()
            } else if i as usize == groups - 1 {
                "sum".into()
            } else {
                self.surfaces[i as usize].surface.to_string()
            }
        };
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(groups)
            .x_label_formatter(&|x| label_of(*x))
            .y_label_formatter(&|y| tick_label(*y))
            .x_desc("surface")
            .y_desc("Seidel sum (mm)")
            .label_style((FONT_FAMILY, LABEL_SIZE))
            .axis_desc_style((FONT_FAMILY, LABEL_SIZE + 1))
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(205, 205, 205))
            .draw()
            .map_err(draw_error)?;
        chart
            .draw_series(LineSeries::new(
                [(-0.5, 0.0), (groups as f64 - 0.5, 0.0)],
                BLACK.stroke_width(1),
            ))
            .map_err(draw_error)?;
        // The sums group sits apart from the surfaces behind a divider.
        chart
            .draw_series(LineSeries::new(
                [
                    (groups as f64 - 1.5, chart.y_range().start),
                    (groups as f64 - 1.5, chart.y_range().end),
                ],
                BLACK.mix(0.4).stroke_width(1),
            ))
            .map_err(draw_error)?;
        let width = 0.8 / 5.0;
        let mut panel = PanelDrawn {
            title,
            ..PanelDrawn::default()
        };
        for (term, name) in TERM_NAMES.iter().enumerate() {
            let color = PALETTE[term];
            let bars: Vec<(f64, f64)> = self
                .surfaces
                .iter()
                .map(|s| s.terms[term])
                .chain([self.sums[term]])
                .enumerate()
                .map(|(group, value)| (group as f64, value))
                .collect();
            chart
                .draw_series(bars.iter().map(|&(group, value)| {
                    let left = group - 0.4 + width * term as f64;
                    Rectangle::new([(left, 0.0), (left + width, value)], color.filled())
                }))
                .map_err(draw_error)?
                .label(*name)
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 6), (x + 14, y + 6)], color.filled())
                });
            panel.series.push(SeriesDrawn {
                label: name.to_string(),
                points: bars,
            });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((FONT_FAMILY, LABEL_SIZE))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.5))
            .draw()
            .map_err(draw_error)?;
        Ok(Drawn {
            panels: vec![panel],
        })
    }
}
