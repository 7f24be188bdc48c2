//! Spot diagrams: one panel per field and wavelength, with the Airy disk and RMS radius.

use super::chart::{LABEL_SIZE, draw_notice, tick_label, titled_grid};
use super::color::wavelength_color;
use super::font::FONT_FAMILY;
use super::{Drawn, PanelDrawn, PlotError, SeriesDrawn, View, draw_error};
use plotters::coord::Shift;
use plotters::prelude::*;

/// The image-plane intersections of one ray bundle, in mm relative to the reference point (the
/// chief ray or the centroid, as the analysis chose), with its radii.
#[derive(Clone, Debug, PartialEq)]
pub struct Spot {
    pub wavelength_nm: f64,
    pub points: Vec<(f64, f64)>,
    pub rms_radius_mm: f64,
    pub geometric_radius_mm: f64,
    /// Radius of the Airy disk's first dark ring at this wavelength (1.22 λ N_w), mm.
    pub airy_radius_mm: f64,
}

#[derive(Clone, Debug, PartialEq)]
pub struct SpotField {
    /// The field angle in y (deg), and in x: 0 for a rotationally symmetric lens, whose fields
    /// are drawn in the meridional plane; a lens placed off one axis has its file's (x, y).
    pub field_deg: f64,
    pub field_x_deg: f64,
    pub spots: Vec<Spot>,
}

impl SpotField {
    /// The field as panel titles print it.
    fn label(&self) -> String {
        if self.field_x_deg == 0.0 {
            format!("{:.2}°", self.field_deg)
        } else {
            format!("({:.2}°, {:.2}°)", self.field_x_deg, self.field_deg)
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct SpotPlot {
    pub lens: String,
    pub fields: Vec<SpotField>,
}

const CELL: u32 = 330;
const MARGIN: u32 = 8;
const X_LABELS: u32 = 44;
const Y_LABELS: u32 = 54;

impl SpotPlot {
    fn columns(&self) -> usize {
        self.fields
            .iter()
            .map(|f| f.spots.len())
            .max()
            .unwrap_or(1)
            .max(1)
    }
}

impl View for SpotPlot {
    fn size(&self) -> (u32, u32) {
        (
            (CELL * self.columns() as u32).max(720),
            60 + (CELL + 40) * self.fields.len().max(1) as u32,
        )
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let columns = self.columns();
        let title = format!("{}: spot diagrams (µm)", self.lens);
        let cells = titled_grid(area, &title, self.fields.len(), columns)?;
        // One scale for every panel: the largest spot or Airy disk.
        let half = self
            .fields
            .iter()
            .flat_map(|f| &f.spots)
            .flat_map(|s| {
                s.points
                    .iter()
                    .map(|p| p.0.hypot(p.1))
                    .chain([s.airy_radius_mm])
            })
            .fold(0.0f64, f64::max)
            .max(1e-6)
            * 1000.0
            * 1.1;
        let mut drawn = Drawn::default();
        for (field, row) in self.fields.iter().zip(cells.chunks(columns)) {
            for (spot, cell) in field.spots.iter().zip(row) {
                let label = field.label();
                let title = format!("{label}, {:.1} nm", spot.wavelength_nm);
                drawn
                    .panels
                    .push(draw_spot(cell, title, &label, spot, half)?);
            }
        }
        Ok(drawn)
    }
}

fn draw_spot<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: String,
    field: &str,
    spot: &Spot,
    half: f64,
) -> Result<PanelDrawn, PlotError> {
    // Equal µm per pixel on both axes, so the Airy disk is drawn round: predict the plotting
    // area the way plotters lays it out (margins, caption, label areas) and widen one range.
    let caption = TextStyle::from((FONT_FAMILY, 18).into_font());
    let (_, text_height) = area
        .estimate_text_size(&title, &caption)
        .map_err(draw_error)?;
    let caption_height = text_height as f64 + 2.0 * (text_height as f64 / 2.0).min(5.0).floor();
    let (width, height) = area.dim_in_pixel();
    let plot_width = (width as f64 - 2.0 * MARGIN as f64 - Y_LABELS as f64).max(1.0);
    let plot_height =
        (height as f64 - 2.0 * MARGIN as f64 - X_LABELS as f64 - caption_height).max(1.0);
    let (x_half, y_half) = if plot_width > plot_height {
        (half * plot_width / plot_height, half)
    } else {
        (half, half * plot_height / plot_width)
    };
    let mut chart = ChartBuilder::on(area)
        .caption(&title, caption)
        .margin(MARGIN)
        .x_label_area_size(X_LABELS)
        .y_label_area_size(Y_LABELS)
        .build_cartesian_2d(-x_half..x_half, -y_half..y_half)
        .map_err(draw_error)?;
    chart
        .configure_mesh()
        .x_desc("x (µm)")
        .y_desc("y (µm)")
        .label_style((FONT_FAMILY, LABEL_SIZE - 3))
        .axis_desc_style((FONT_FAMILY, LABEL_SIZE - 2))
        .x_labels(5)
        .y_labels(5)
        .x_label_formatter(&|v| tick_label(*v))
        .y_label_formatter(&|v| tick_label(*v))
        .light_line_style(RGBColor(240, 240, 240))
        .bold_line_style(RGBColor(215, 215, 215))
        .draw()
        .map_err(draw_error)?;
    let mut drawn = PanelDrawn {
        title,
        ..PanelDrawn::default()
    };
    let airy = spot.airy_radius_mm * 1000.0;
    chart
        .draw_series(LineSeries::new(
            (0..=96).map(|i| {
                let a = i as f64 / 96.0 * std::f64::consts::TAU;
                (airy * a.cos(), airy * a.sin())
            }),
            BLACK.mix(0.7).stroke_width(1),
        ))
        .map_err(draw_error)?;
    if spot.points.is_empty() {
        let message = format!("All rays vignetted at {field}");
        draw_notice(area, &message)?;
        drawn.messages.push(message);
        return Ok(drawn);
    }
    let color = wavelength_color(spot.wavelength_nm);
    let points: Vec<(f64, f64)> = spot
        .points
        .iter()
        .map(|&(x, y)| (x * 1000.0, y * 1000.0))
        .collect();
    chart
        .draw_series(points.iter().map(|&p| Circle::new(p, 1, color.filled())))
        .map_err(draw_error)?;
    let note = format!(
        "RMS {:.2} µm  GEO {:.2} µm  Airy {:.2} µm",
        spot.rms_radius_mm * 1000.0,
        spot.geometric_radius_mm * 1000.0,
        airy
    );
    area.draw(&Text::new(
        note.clone(),
        (72, 36),
        (FONT_FAMILY, LABEL_SIZE - 4).into_font().color(&BLACK),
    ))
    .map_err(draw_error)?;
    drawn.messages.push(note);
    drawn.series.push(SeriesDrawn {
        label: format!("{:.1} nm", spot.wavelength_nm),
        points,
    });
    Ok(drawn)
}
