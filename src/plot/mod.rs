//! Plots: plotters views over plain result structs, written as PNG or SVG.
//!
//! Each view (`LayoutPlot`, `RayFanPlot`, ...) is plain data that an analysis fills in; this
//! module only draws it. Drawing returns a [`Drawn`] summary of what actually reached the canvas
//! (series, points, messages) so tests can check the plotted data and not just the file.
//!
//! Text is set in DejaVu Sans, embedded in the binary (see [`font`]), so a PNG looks the same on
//! a machine without fonts. SVG keeps text as `<text>` elements in the family "DejaVu Sans" and
//! carries the font file itself in an `@font-face` rule.

mod canvas;
mod chart;
mod color;
mod curves;
mod error_map;
mod fan;
pub mod font;
mod layout;
mod lrtf_error;
mod pareto;
mod seidel;
mod spot;
mod wave;

pub use canvas::{Format, Rendered, render, write_plot};
pub use chart::{Drawn, PanelDrawn, SeriesDrawn};
pub use color::wavelength_color;
pub use curves::{
    DistortionPlot, FieldCurve, FieldCurvesPlot, LateralColorPlot, LsaPlot, VignettingPlot,
    WavelengthCurve,
};
pub use error_map::ErrorMapPlot;
pub use fan::{FanCurve, FanField, OpdFanPlot, RayFanPlot};
pub use layout::{LayoutElement, LayoutPlot, LayoutRay, LayoutSurface};
pub use lrtf_error::{LrtfErrorCurve, LrtfErrorLens, LrtfErrorPlot, TARGET_LABEL};
pub use pareto::{ParetoPlot, ParetoPoint, pareto_front};
pub use seidel::{SeidelBar, SeidelPlot};
pub use spot::{Spot, SpotField, SpotPlot};
pub use wave::{
    Grid, MtfField, MtfFieldPlot, MtfPlot, PsfPlot, ThroughFocusPlot, WavefrontMapPlot,
};

use plotters::coord::Shift;
use plotters::prelude::{DrawingArea, DrawingBackend};

/// Everything that can go wrong while drawing or writing a plot.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("{path}: unknown plot format (use a .png or .svg file name)")]
    UnknownFormat { path: String },
    #[error("the embedded plot font could not be loaded")]
    Font,
    #[error("drawing failed: {0}")]
    Draw(String),
    #[error("PNG encoding failed: {0}")]
    Encode(String),
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
}

/// A plot that can draw itself on any plotters backend.
pub trait View {
    /// Canvas size in pixels (width, height).
    fn size(&self) -> (u32, u32);
    /// Draws the whole plot on `area` and reports what it drew.
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError>;
}

/// Converts any plotters drawing error into ours (plotters' error types are backend generic).
pub(crate) fn draw_error<E: std::fmt::Display>(error: E) -> PlotError {
    PlotError::Draw(error.to_string())
}
