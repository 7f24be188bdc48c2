//! Which plots exist and how each is filled from the analyses of one lens.

use crate::plot::{
    DistortionPlot, Drawn, FieldCurvesPlot, LateralColorPlot, LayoutPlot, LsaPlot, PlotError,
    RayFanPlot, SeidelPlot, SpotPlot, View, VignettingPlot,
};
use crate::system::LensSystem;
use plotters::coord::Shift;
use plotters::prelude::{DrawingArea, DrawingBackend};
use std::fmt;
use std::str::FromStr;

/// The plots `lensbake plot` draws, in report order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PlotKind {
    Layout,
    RayFan,
    Spot,
    Lsa,
    FieldCurves,
    Distortion,
    LateralColor,
    Vignetting,
    Seidel,
}

impl PlotKind {
    pub const ALL: [PlotKind; 9] = [
        PlotKind::Layout,
        PlotKind::RayFan,
        PlotKind::Spot,
        PlotKind::Lsa,
        PlotKind::FieldCurves,
        PlotKind::Distortion,
        PlotKind::LateralColor,
        PlotKind::Vignetting,
        PlotKind::Seidel,
    ];

    /// The command-line name, also the report's file stem.
    pub fn name(self) -> &'static str {
        match self {
            PlotKind::Layout => "layout",
            PlotKind::RayFan => "ray-fan",
            PlotKind::Spot => "spot",
            PlotKind::Lsa => "lsa",
            PlotKind::FieldCurves => "field-curves",
            PlotKind::Distortion => "distortion",
            PlotKind::LateralColor => "lateral-color",
            PlotKind::Vignetting => "vignetting",
            PlotKind::Seidel => "seidel",
        }
    }

    /// A caption for reports.
    pub fn describe(self) -> &'static str {
        match self {
            PlotKind::Layout => "Cross-section with ray bundles for three fields",
            PlotKind::RayFan => "Transverse ray aberration fans (tangential and sagittal)",
            PlotKind::Spot => "Spot diagrams with RMS radius and Airy disk",
            PlotKind::Lsa => "Longitudinal spherical aberration",
            PlotKind::FieldCurves => "Astigmatic field curves",
            PlotKind::Distortion => "Distortion",
            PlotKind::LateralColor => "Lateral colour",
            PlotKind::Vignetting => "Relative illumination and vignetting",
            PlotKind::Seidel => "Seidel sums per surface",
        }
    }
}

impl fmt::Display for PlotKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for PlotKind {
    type Err = FigureError;

    fn from_str(text: &str) -> Result<PlotKind, FigureError> {
        PlotKind::ALL
            .into_iter()
            .find(|k| k.name() == text)
            .ok_or_else(|| FigureError::UnknownKind(text.to_string()))
    }
}

/// What the user asked to see; `None` and empty pick the lens's defaults.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FigureOptions {
    /// Largest half-field angle plotted (default: the largest traceable field).
    pub field_deg: Option<f64>,
    /// Wavelengths drawn (default: F, d, C when the lens disperses, else its design wavelength).
    pub wavelengths_nm: Vec<f64>,
}

#[derive(Debug, thiserror::Error)]
pub enum FigureError {
    #[error("unknown plot kind {0:?}; expected one of {names}", names = PlotKind::ALL.map(PlotKind::name).join(", "))]
    UnknownKind(String),
    #[error("{kind} plots need the {analysis}, which this build does not have yet")]
    NotAvailable {
        kind: PlotKind,
        analysis: &'static str,
    },
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// Any one plot, ready to draw.
#[derive(Clone, Debug, PartialEq)]
pub enum Figure {
    Layout(LayoutPlot),
    RayFan(RayFanPlot),
    Spot(SpotPlot),
    Lsa(LsaPlot),
    FieldCurves(FieldCurvesPlot),
    Distortion(DistortionPlot),
    LateralColor(LateralColorPlot),
    Vignetting(VignettingPlot),
    Seidel(SeidelPlot),
}

impl View for Figure {
    fn size(&self) -> (u32, u32) {
        match self {
            Figure::Layout(v) => v.size(),
            Figure::RayFan(v) => v.size(),
            Figure::Spot(v) => v.size(),
            Figure::Lsa(v) => v.size(),
            Figure::FieldCurves(v) => v.size(),
            Figure::Distortion(v) => v.size(),
            Figure::LateralColor(v) => v.size(),
            Figure::Vignetting(v) => v.size(),
            Figure::Seidel(v) => v.size(),
        }
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        match self {
            Figure::Layout(v) => v.draw(area),
            Figure::RayFan(v) => v.draw(area),
            Figure::Spot(v) => v.draw(area),
            Figure::Lsa(v) => v.draw(area),
            Figure::FieldCurves(v) => v.draw(area),
            Figure::Distortion(v) => v.draw(area),
            Figure::LateralColor(v) => v.draw(area),
            Figure::Vignetting(v) => v.draw(area),
            Figure::Seidel(v) => v.draw(area),
        }
    }
}

/// Builds the `kind` plot of `system`; `lens` names it in the title.
pub fn figure(
    kind: PlotKind,
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<Figure, FigureError> {
    let wavelength_nm = options
        .wavelengths_nm
        .first()
        .copied()
        .unwrap_or_else(|| system.design_wavelength_nm());
    match kind {
        PlotKind::Layout => Ok(Figure::Layout(LayoutPlot::of_system(
            lens,
            &system.at(wavelength_nm),
        ))),
        PlotKind::Seidel => Err(FigureError::NotAvailable {
            kind,
            analysis: "paraxial analysis",
        }),
        _ => Err(FigureError::NotAvailable {
            kind,
            analysis: "real-ray analyses",
        }),
    }
}
