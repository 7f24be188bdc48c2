//! Transverse ray aberration fans: tangential and sagittal, per field, all wavelengths.

use super::chart::{Panel, Series, draw_footnote, draw_panel, symmetric_range, titled_grid};
use super::color::wavelength_color;
use super::{Drawn, PlotError, View};
use plotters::coord::Shift;
use plotters::prelude::{DrawingArea, DrawingBackend};

/// One fan at one wavelength: (relative pupil coordinate -1..1, the aberration: transverse in mm
/// at the image plane for a ray fan, OPD in waves for an OPD fan, relative to the chief ray).
/// Vignetted rays are simply absent.
#[derive(Clone, Debug, PartialEq)]
pub struct FanCurve {
    pub wavelength_nm: f64,
    pub points: Vec<(f64, f64)>,
}

/// The tangential (y error against pupil y) and sagittal (x error against pupil x) fans at one
/// field angle.
#[derive(Clone, Debug, PartialEq)]
pub struct FanField {
    pub field_deg: f64,
    pub tangential: Vec<FanCurve>,
    pub sagittal: Vec<FanCurve>,
    /// Wavelengths (nm) with no curve at this field, because their pupil-centre ray (the
    /// fan's reference) does not reach the image: each panel says so.
    pub dropped_nm: Vec<f64>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct RayFanPlot {
    pub lens: String,
    /// Drawn top to bottom in the order given (designers put the largest field on top).
    pub fields: Vec<FanField>,
}

/// Optical path difference fans: the same layout as [`RayFanPlot`], OPD in waves against the
/// chief ray along the tangential (py) and sagittal (px) pupil cuts.
#[derive(Clone, Debug, PartialEq)]
pub struct OpdFanPlot {
    pub lens: String,
    /// Drawn top to bottom in the order given.
    pub fields: Vec<FanField>,
}

impl View for RayFanPlot {
    fn size(&self) -> (u32, u32) {
        fan_grid_size(&self.fields)
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let title = format!("{}: transverse ray aberration", self.lens);
        draw_fan_grid(area, &title, &self.fields, ["ey (mm)", "ex (mm)"])
    }
}

impl View for OpdFanPlot {
    fn size(&self) -> (u32, u32) {
        fan_grid_size(&self.fields)
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let title = format!("{}: optical path difference", self.lens);
        draw_fan_grid(area, &title, &self.fields, ["OPD (waves)", "OPD (waves)"])
    }
}

fn fan_grid_size(fields: &[FanField]) -> (u32, u32) {
    (1200, 60 + 330 * fields.len().max(1) as u32)
}

/// One row per field, tangential left and sagittal right, on one vertical scale; `y_labels`
/// name the tangential and sagittal quantity with its unit.
fn draw_fan_grid<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    fields: &[FanField],
    y_labels: [&str; 2],
) -> Result<Drawn, PlotError> {
    let cells = titled_grid(area, title, fields.len(), 2)?;
    // One scale for every panel, so fields compare at a glance.
    let scale = symmetric_range(
        fields
            .iter()
            .flat_map(|f| f.tangential.iter().chain(&f.sagittal))
            .flat_map(|c| c.points.iter().map(|p| p.1)),
    );
    let mut drawn = Drawn::default();
    for (field, row) in fields.iter().zip(cells.chunks(2)) {
        for (cell, (name, y_label, x_label, curves)) in row.iter().zip([
            (
                "tangential",
                y_labels[0],
                "relative pupil py",
                &field.tangential,
            ),
            (
                "sagittal",
                y_labels[1],
                "relative pupil px",
                &field.sagittal,
            ),
        ]) {
            let panel = Panel {
                title: format!("{name}, field {:.2}°", field.field_deg),
                x_label,
                y_label,
                series: curves
                    .iter()
                    .map(|c| Series {
                        label: format!("{:.1} nm", c.wavelength_nm),
                        color: wavelength_color(c.wavelength_nm),
                        dashed: false,
                        markers: false,
                        points: c.points.clone(),
                    })
                    .collect(),
                empty_message: format!("All rays vignetted at {:.2}°", field.field_deg),
                x_range: Some(-1.05..1.05),
                y_range: Some(scale.clone()),
                title_size: 20,
            };
            let mut panel_drawn = draw_panel(cell, panel)?;
            if !field.dropped_nm.is_empty() && !curves.is_empty() {
                let note = format!(
                    "not drawn: {} nm (pupil-centre ray vignetted)",
                    field
                        .dropped_nm
                        .iter()
                        .map(|w| format!("{w:.1}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                );
                draw_footnote(cell, &note)?;
                panel_drawn.messages.push(note);
            }
            drawn.panels.push(panel_drawn);
        }
    }
    Ok(drawn)
}
