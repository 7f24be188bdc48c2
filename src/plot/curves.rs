//! Single-panel curve plots: LSA, field curves, distortion, lateral colour, vignetting.

use super::chart::{Panel, Series, draw_panel, range_with_zero};
use super::color::{PALETTE, wavelength_color};
use super::{Drawn, PlotError, View};
use plotters::coord::Shift;
use plotters::prelude::{DrawingArea, DrawingBackend};

const SIZE: (u32, u32) = (1000, 720);
const TITLE_SIZE: u32 = 26;

/// A curve at one wavelength; what the two coordinates mean depends on the plot.
#[derive(Clone, Debug, PartialEq)]
pub struct WavelengthCurve {
    pub wavelength_nm: f64,
    pub points: Vec<(f64, f64)>,
}

fn wavelength_series(curve: &WavelengthCurve, flip: bool, scale_y: f64) -> Series {
    Series {
        label: format!("{:.1} nm", curve.wavelength_nm),
        color: wavelength_color(curve.wavelength_nm),
        dashed: false,
        markers: false,
        points: curve
            .points
            .iter()
            .map(|&(a, b)| {
                if flip {
                    (b * scale_y, a)
                } else {
                    (a, b * scale_y)
                }
            })
            .collect(),
    }
}

/// Longitudinal spherical aberration: `points` are (relative pupil height 0..1, LSA in mm), LSA
/// being the axial crossing of a meridional ray minus the paraxial focus. Drawn the way designers
/// read it: pupil height up, aberration across.
#[derive(Clone, Debug, PartialEq)]
pub struct LsaPlot {
    pub lens: String,
    pub curves: Vec<WavelengthCurve>,
}

impl View for LsaPlot {
    fn size(&self) -> (u32, u32) {
        SIZE
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let panel = Panel {
            title: format!("{}: longitudinal spherical aberration", self.lens),
            x_label: "longitudinal aberration (mm)",
            y_label: "relative pupil height",
            series: self
                .curves
                .iter()
                .map(|c| wavelength_series(c, true, 1.0))
                .collect(),
            empty_message: "No marginal ray passes the lens".into(),
            x_range: None,
            y_range: Some(0.0..1.05),
            title_size: TITLE_SIZE,
        };
        Ok(Drawn {
            panels: vec![draw_panel(area, panel)?],
        })
    }
}

/// Astigmatic field curves at one wavelength: (field angle in degrees, sagittal focus shift,
/// tangential focus shift), shifts in mm from the paraxial image plane.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldCurve {
    pub wavelength_nm: f64,
    pub points: Vec<(f64, f64, f64)>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct FieldCurvesPlot {
    pub lens: String,
    pub curves: Vec<FieldCurve>,
}

impl View for FieldCurvesPlot {
    fn size(&self) -> (u32, u32) {
        SIZE
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let mut series = Vec::new();
        for curve in &self.curves {
            let color = wavelength_color(curve.wavelength_nm);
            for (name, dashed, pick) in [("S", false, 1usize), ("T", true, 2usize)] {
                series.push(Series {
                    label: format!("{name} {:.1} nm", curve.wavelength_nm),
                    color,
                    dashed,
                    markers: false,
                    points: curve
                        .points
                        .iter()
                        .map(|&(field, s, t)| (if pick == 1 { s } else { t }, field))
                        .collect(),
                });
            }
        }
        let max_field = self
            .curves
            .iter()
            .flat_map(|c| c.points.iter().map(|p| p.0))
            .fold(0.0, f64::max);
        let panel = Panel {
            title: format!("{}: astigmatic field curves", self.lens),
            x_label: "focus shift from paraxial image (mm)",
            y_label: "field angle (deg)",
            series,
            empty_message: "All chief rays vignetted: no field curves".into(),
            x_range: None,
            y_range: Some(0.0..(max_field * 1.05).max(1e-3)),
            title_size: TITLE_SIZE,
        };
        Ok(Drawn {
            panels: vec![draw_panel(area, panel)?],
        })
    }
}

/// Distortion: (field angle in degrees, percent) against the reference mapping named in
/// `reference` (for example "f·tan θ").
#[derive(Clone, Debug, PartialEq)]
pub struct DistortionPlot {
    pub lens: String,
    pub wavelength_nm: f64,
    pub reference: String,
    pub points: Vec<(f64, f64)>,
}

impl View for DistortionPlot {
    fn size(&self) -> (u32, u32) {
        SIZE
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let max_field = self.points.iter().map(|p| p.0).fold(0.0, f64::max);
        let panel = Panel {
            title: format!("{}: distortion", self.lens),
            x_label: "distortion (%)",
            y_label: "field angle (deg)",
            series: vec![Series {
                label: format!("{:.1} nm, against {}", self.wavelength_nm, self.reference),
                color: wavelength_color(self.wavelength_nm),
                dashed: false,
                markers: false,
                points: self.points.iter().map(|&(f, d)| (d, f)).collect(),
            }],
            empty_message: "All chief rays vignetted: no distortion curve".into(),
            x_range: None,
            y_range: Some(0.0..(max_field * 1.05).max(1e-3)),
            title_size: TITLE_SIZE,
        };
        Ok(Drawn {
            panels: vec![draw_panel(area, panel)?],
        })
    }
}

/// Lateral colour: per wavelength, (field angle in degrees, chief-ray image height minus that of
/// `reference_nm`, in mm). Drawn in micrometres.
#[derive(Clone, Debug, PartialEq)]
pub struct LateralColorPlot {
    pub lens: String,
    pub reference_nm: f64,
    /// False for a lens of constant indices: it has no colour, and the panel says so rather
    /// than drawing zeros.
    pub disperses: bool,
    pub curves: Vec<WavelengthCurve>,
}

impl View for LateralColorPlot {
    fn size(&self) -> (u32, u32) {
        SIZE
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let panel = Panel {
            title: format!(
                "{}: lateral colour (reference {:.1} nm)",
                self.lens, self.reference_nm
            ),
            x_label: "field angle (deg)",
            y_label: "image height difference (µm)",
            series: self
                .curves
                .iter()
                .map(|c| wavelength_series(c, false, 1000.0))
                .collect(),
            empty_message: if self.disperses {
                "No chief ray reaches the image at a second wavelength: no lateral colour".into()
            } else {
                "Constant refractive indices: the lens has no lateral colour".into()
            },
            x_range: None,
            y_range: None,
            title_size: TITLE_SIZE,
        };
        Ok(Drawn {
            panels: vec![draw_panel(area, panel)?],
        })
    }
}

/// Relative illumination and unvignetted fraction of the entrance pupil against field:
/// (field angle in degrees, relative illumination 0..1, unvignetted fraction 0..1).
#[derive(Clone, Debug, PartialEq)]
pub struct VignettingPlot {
    pub lens: String,
    pub points: Vec<(f64, f64, f64)>,
}

impl View for VignettingPlot {
    fn size(&self) -> (u32, u32) {
        SIZE
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let series = vec![
            Series {
                label: "relative illumination".into(),
                color: PALETTE[0],
                dashed: false,
                markers: true,
                points: self.points.iter().map(|&(f, ri, _)| (f, ri)).collect(),
            },
            Series {
                label: "unvignetted fraction".into(),
                color: PALETTE[1],
                dashed: true,
                markers: true,
                points: self.points.iter().map(|&(f, _, u)| (f, u)).collect(),
            },
        ];
        let panel = Panel {
            title: format!("{}: relative illumination and vignetting", self.lens),
            x_label: "field angle (deg)",
            y_label: "fraction of on-axis value",
            x_range: Some(range_with_zero(self.points.iter().map(|p| p.0))),
            series,
            empty_message: "No field sampled".into(),
            y_range: Some(0.0..1.08),
            title_size: TITLE_SIZE,
        };
        Ok(Drawn {
            panels: vec![draw_panel(area, panel)?],
        })
    }
}
