//! An image's per-pixel error on a sequential colour scale, at its own pixel size, with a
//! colour bar that gives the scale and its unit (the demo's baked-against-traced map).

use super::chart::{PanelDrawn, SeriesDrawn};
use super::font::FONT_FAMILY;
use super::wave::{SEQUENTIAL, colour_at, draw_colour_bar};
use super::{Drawn, PlotError, View, draw_error};
use plotters::coord::Shift;
use plotters::prelude::*;

/// Room beside and above the image for the bar and the title, pixels.
const BAR_WIDTH: u32 = 170;
const TITLE_HEIGHT: u32 = 44;
const MARGIN: u32 = 10;

/// Per-pixel values (row-major, row 0 at the top) drawn one canvas pixel each; values above
/// `range.1` take the top colour and are counted in a message.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorMapPlot {
    pub title: String,
    pub width: usize,
    pub height: usize,
    pub values: Vec<f64>,
    pub range: (f64, f64),
    /// The colour bar's axis label, with the unit.
    pub bar_label: String,
}

impl View for ErrorMapPlot {
    fn size(&self) -> (u32, u32) {
        (
            self.width as u32 + BAR_WIDTH + 2 * MARGIN,
            (self.height as u32 + TITLE_HEIGHT + MARGIN).max(360),
        )
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        area.fill(&WHITE).map_err(draw_error)?;
        area.draw(&Text::new(
            self.title.clone(),
            (MARGIN as i32, 12),
            (FONT_FAMILY, 20).into_font().color(&BLACK),
        ))
        .map_err(draw_error)?;
        let span = (self.range.1 - self.range.0).max(f64::MIN_POSITIVE);
        let mut above = 0usize;
        for (i, &value) in self.values.iter().enumerate() {
            let (x, y) = ((i % self.width) as i32, (i / self.width) as i32);
            above += usize::from(value > self.range.1);
            let colour = colour_at(&SEQUENTIAL, (value - self.range.0) / span);
            area.draw_pixel((MARGIN as i32 + x, TITLE_HEIGHT as i32 + y), &colour)
                .map_err(draw_error)?;
        }
        let (width, height) = area.dim_in_pixel();
        let bar_area = area.margin(0, 0, width as i32 - BAR_WIDTH as i32, 0);
        let bar_height = (self.height as u32 + TITLE_HEIGHT).max(360).min(height);
        let bar_area = bar_area.shrink((0, 0), (BAR_WIDTH, bar_height));
        draw_colour_bar(&bar_area, self.range, &SEQUENTIAL, &self.bar_label)?;
        let mut panel = PanelDrawn {
            title: self.title.clone(),
            ..PanelDrawn::default()
        };
        panel.series.push(SeriesDrawn {
            label: format!("colour scale ({})", self.bar_label),
            points: vec![self.range],
        });
        if above > 0 {
            panel.messages.push(format!(
                "{above} pixels above {} drawn in the top colour",
                self.range.1
            ));
        }
        Ok(Drawn {
            panels: vec![panel],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_map_keeps_its_pixels_and_carries_its_scale() {
        let plot = ErrorMapPlot {
            title: "t".into(),
            width: 40,
            height: 30,
            values: (0..1200).map(|i| i as f64 / 1000.0).collect(),
            range: (0.0, 1.0),
            bar_label: "abs error (linear radiance)".into(),
        };
        assert_eq!(plot.size(), (40 + BAR_WIDTH + 2 * MARGIN, 360));
        let rendered = crate::plot::render(&plot, crate::plot::Format::Png).unwrap();
        let scale = rendered
            .drawn
            .series("t", "colour scale (abs error (linear radiance))")
            .unwrap();
        assert_eq!(scale.points, [(0.0, 1.0)]);
        let messages: Vec<&str> = rendered.drawn.messages().collect();
        assert_eq!(messages, ["199 pixels above 1 drawn in the top colour"]);
    }
}
