//! Which plots exist and how each is filled from the analyses of one lens.

use crate::analysis::{AnalysisError, AnalyzeOptions, analyze};
use crate::plot::{
    DistortionPlot, Drawn, FieldCurvesPlot, LateralColorPlot, LayoutPlot, LayoutRay, LsaPlot,
    PlotError, RayFanPlot, SeidelBar, SeidelPlot, SpotPlot, View, VignettingPlot,
};
use crate::system::{LensSystem, SystemAt};
use crate::trace::{Apertures, RaySource, Tracer, Travel, aim_at_stop, traceable_field_deg};
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
    Analysis(#[from] AnalysisError),
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
        PlotKind::Layout => {
            let at = system.at(wavelength_nm);
            let tracer = Tracer::new(&at);
            let max_field = max_field_deg(&tracer, options);
            let mut plot = LayoutPlot::of_system(lens, &at);
            for fraction in [0.0, 0.7, 1.0] {
                plot.rays.extend(layout_rays(
                    &tracer,
                    &at,
                    fraction * max_field,
                    plot.image_z,
                ));
            }
            // The image plane as tall as the bundles that reach it.
            let reached = plot
                .rays
                .iter()
                .filter(|r| !r.vignetted)
                .filter_map(|r| r.path.last())
                .map(|p| p.1.abs())
                .fold(0.0, f64::max);
            if reached > 0.0 {
                plot.image_half_height = 1.05 * reached;
            }
            Ok(Figure::Layout(plot))
        }
        PlotKind::Seidel => {
            let analysis = analyze(lens, system, &analyze_options(options, wavelength_nm))?;
            Ok(Figure::Seidel(SeidelPlot {
                lens: lens.to_string(),
                wavelength_nm: analysis.wavelength_nm,
                surfaces: analysis
                    .seidel
                    .surfaces
                    .iter()
                    .map(|s| SeidelBar {
                        surface: s.surface,
                        terms: s.terms.as_array(),
                    })
                    .collect(),
                sums: analysis.seidel.sums.as_array(),
            }))
        }
        _ => Err(FigureError::NotAvailable {
            kind,
            analysis: "real-ray analyses",
        }),
    }
}

/// The field the user asked for, else the largest whose real chief ray passes the lens.
fn max_field_deg(tracer: &Tracer, options: &FigureOptions) -> f64 {
    options
        .field_deg
        .unwrap_or_else(|| traceable_field_deg(tracer, FIELD_SCAN_DEG))
}

/// Step of the scan for the largest traceable field (degrees); bisection refines it.
const FIELD_SCAN_DEG: f64 = 1.0;

/// Where layout rays cross the stop, as fractions of its radius (meridional plane). Just inside
/// the rim, so the marginal rays are not lost to round-off at the stop's edge.
const LAYOUT_STOP_HEIGHTS: [f64; 5] = [-0.999, -0.5, 0.0, 0.5, 0.999];

/// The meridional rays of one field for the layout, from in front of the lens to the image
/// plane or to the surface that stops them. Rays that cannot be aimed are left out.
fn layout_rays(tracer: &Tracer, at: &SystemAt, field_deg: f64, image_z: f64) -> Vec<LayoutRay> {
    let angle = field_deg.to_radians();
    let source = RaySource::Collimated {
        direction: [0.0, angle.sin(), angle.cos()],
        start_z: tracer.front_start_z(),
    };
    let stop_radius = at.surfaces[at.stop].semi_aperture;
    let largest = at
        .surfaces
        .iter()
        .map(|s| s.semi_aperture)
        .fold(0.0, f64::max);
    // Incoming rays start 1.5 apertures in front of the lens, or later where a steep ray would
    // otherwise run far outside the lens's height and dwarf the drawing.
    let draw_from = |ray: &crate::trace::Ray| {
        let [_, y, z] = ray.position();
        let [_, dy, dz] = ray.direction();
        let earliest = at.surfaces[0].vertex_z - 1.5 * largest;
        if dy == 0.0 {
            return earliest;
        }
        let limit = 1.3 * largest * dy.signum();
        earliest.max(z + (-limit - y) * dz / dy)
    };
    LAYOUT_STOP_HEIGHTS
        .iter()
        .filter_map(|&h| aim_at_stop(tracer, &source, [0.0, h * stop_radius]).ok())
        .map(|ray| {
            let traced = tracer.trace_path(ray, Travel::Forward, Apertures::Checked);
            let mut path: Vec<(f64, f64)> = ray
                .point_at_z(draw_from(&ray))
                .into_iter()
                .chain(traced.crossings.iter().map(|c| c.point))
                .map(|p| (p[2], p[1]))
                .collect();
            let vignetted = !traced.traced.outcome.is_ok();
            if vignetted {
                let stopped = traced.traced.ray.position();
                path.push((stopped[2], stopped[1]));
            } else if let Some(end) = traced.traced.ray.point_at_z(image_z) {
                path.push((end[2], end[1]));
            }
            LayoutRay {
                field_deg,
                path,
                vignetted,
            }
        })
        .collect()
}

/// The paraxial analysis at the plotted wavelength and field.
pub(crate) fn analyze_options(options: &FigureOptions, wavelength_nm: f64) -> AnalyzeOptions {
    AnalyzeOptions {
        wavelength_nm: Some(wavelength_nm),
        field_deg: options.field_deg,
        ..AnalyzeOptions::default()
    }
}
