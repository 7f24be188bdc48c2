//! Which plots exist and how each is filled from the analyses of one lens.

use super::wave_figures::{
    mtf_field_plot, mtf_plot, opd_fan_plot, psf_plot, through_focus_plot, wavefront_map_plot,
};
use crate::analysis::{
    AnalysisError, AnalyzeOptions, ConditionOverrides, DesignConditions, analyze,
};
use crate::paraxial::{Aperture, Paraxial, ParaxialOptions};
use crate::plot::{
    DistortionPlot, Drawn, FanCurve, FanField, FieldCurve, FieldCurvesPlot, LateralColorPlot,
    LayoutPlot, LayoutRay, LsaPlot, MtfFieldPlot, MtfPlot, OpdFanPlot, PlotError, PsfPlot,
    RayFanPlot, SeidelBar, SeidelPlot, Spot, SpotField, SpotPlot, ThroughFocusPlot, View,
    VignettingPlot, WavefrontMapPlot, WavelengthCurve,
};
use crate::prescription::RayAiming;
use crate::prescription::formats::PlacedLens;
use crate::system::{LensSystem, SystemAt};
use crate::trace::analyses::{FanPoint, RealRayError, RealRays};
use crate::trace::placed::{PlacedBeam, PlacedBeamError, PlacedTracer, SPOT_GRID};
use crate::trace::{Apertures, RaySource, StopAim, Tracer, Travel};
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
    OpdFan,
    WavefrontMap,
    Psf,
    Mtf,
    ThroughFocusMtf,
    MtfField,
}

impl PlotKind {
    pub const ALL: [PlotKind; 15] = [
        PlotKind::Layout,
        PlotKind::RayFan,
        PlotKind::Spot,
        PlotKind::Lsa,
        PlotKind::FieldCurves,
        PlotKind::Distortion,
        PlotKind::LateralColor,
        PlotKind::Vignetting,
        PlotKind::Seidel,
        PlotKind::OpdFan,
        PlotKind::WavefrontMap,
        PlotKind::Psf,
        PlotKind::Mtf,
        PlotKind::ThroughFocusMtf,
        PlotKind::MtfField,
    ];

    /// Every kind's command-line name, comma separated.
    pub fn names() -> String {
        PlotKind::ALL.map(PlotKind::name).join(", ")
    }

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
            PlotKind::OpdFan => "opd-fan",
            PlotKind::WavefrontMap => "wavefront-map",
            PlotKind::Psf => "psf",
            PlotKind::Mtf => "mtf",
            PlotKind::ThroughFocusMtf => "through-focus-mtf",
            PlotKind::MtfField => "mtf-field",
        }
    }

    /// A caption for reports.
    pub fn describe(self) -> &'static str {
        match self {
            PlotKind::Layout => "Cross-section with ray bundles at the design fields",
            PlotKind::RayFan => "Transverse ray aberration fans (tangential and sagittal)",
            PlotKind::Spot => "Spot diagrams with RMS radius and Airy disk",
            PlotKind::Lsa => "Longitudinal spherical aberration",
            PlotKind::FieldCurves => "Astigmatic field curves",
            PlotKind::Distortion => "Distortion",
            PlotKind::LateralColor => "Lateral colour",
            PlotKind::Vignetting => "Relative illumination and vignetting",
            PlotKind::Seidel => "Seidel sums per surface",
            PlotKind::OpdFan => "Optical path difference fans (tangential and sagittal)",
            PlotKind::WavefrontMap => "Wavefront error over the pupil at the top design field",
            PlotKind::Psf => "Point spread function (FFT) at the top design field",
            PlotKind::Mtf => "Diffraction MTF with the diffraction limit",
            PlotKind::ThroughFocusMtf => "MTF through focus",
            PlotKind::MtfField => "MTF across the field",
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

/// What the user asked to see; `None` and empty take the lens's design conditions
/// ([`DesignConditions`]), the same ones `analyze` uses.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FigureOptions {
    /// Top half-field angle plotted (default: the design field).
    pub field_deg: Option<f64>,
    /// Wavelengths drawn, the first the reference (default: the file's, else F, d, C when the
    /// lens disperses, else its design wavelength).
    pub wavelengths_nm: Vec<f64>,
    /// Entrance-pupil diameter (default: the design aperture).
    pub epd_mm: Option<f64>,
    /// Object distance from the first vertex, mm (default: the lens file's, else infinity).
    pub object_distance_mm: Option<f64>,
    /// How a relative pupil coordinate becomes a real ray (default: the lens file's, else
    /// paraxial).
    pub ray_aiming: Option<RayAiming>,
}

impl FigureOptions {
    /// These choices as overrides of the design conditions.
    pub fn overrides(&self) -> ConditionOverrides {
        ConditionOverrides {
            wavelengths_nm: self.wavelengths_nm.clone(),
            field_deg: self.field_deg,
            epd_mm: self.epd_mm,
            object_distance_mm: self.object_distance_mm,
            ray_aiming: self.ray_aiming,
            ..ConditionOverrides::default()
        }
    }

    /// The paraxial analysis under the same choices.
    pub fn analyze_options(&self) -> AnalyzeOptions {
        AnalyzeOptions {
            wavelength_nm: self.wavelengths_nm.first().copied(),
            field_deg: self.field_deg,
            epd_mm: self.epd_mm,
            object_distance_mm: self.object_distance_mm,
            ray_aiming: self.ray_aiming,
            ..AnalyzeOptions::default()
        }
    }

    /// The design conditions of `system` under these choices.
    pub fn conditions(&self, system: &LensSystem) -> Result<DesignConditions, FigureError> {
        Ok(DesignConditions::resolve(system, &self.overrides())?)
    }
}

#[derive(Debug, thiserror::Error)]
pub enum FigureError {
    #[error("unknown plot kind {0:?}; expected one of {names}", names = PlotKind::names())]
    UnknownKind(String),
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
    #[error(transparent)]
    Plot(#[from] PlotError),
    #[error(transparent)]
    Wave(crate::wave::WaveError),
    #[error(transparent)]
    Lens(#[from] crate::prescription::PrescriptionError),
    #[error(transparent)]
    PlacedBeam(#[from] PlacedBeamError),
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
    OpdFan(OpdFanPlot),
    WavefrontMap(WavefrontMapPlot),
    Psf(PsfPlot),
    Mtf(MtfPlot),
    ThroughFocusMtf(ThroughFocusPlot),
    MtfField(MtfFieldPlot),
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
            Figure::OpdFan(v) => v.size(),
            Figure::WavefrontMap(v) => v.size(),
            Figure::Psf(v) => v.size(),
            Figure::Mtf(v) => v.size(),
            Figure::ThroughFocusMtf(v) => v.size(),
            Figure::MtfField(v) => v.size(),
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
            Figure::OpdFan(v) => v.draw(area),
            Figure::WavefrontMap(v) => v.draw(area),
            Figure::Psf(v) => v.draw(area),
            Figure::Mtf(v) => v.draw(area),
            Figure::ThroughFocusMtf(v) => v.draw(area),
            Figure::MtfField(v) => v.draw(area),
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
    // The same check `analyze`, `trace` and `bake` apply: a formula outside its range would
    // draw a plausible-looking plot of nothing.
    for &nm in &options.wavelengths_nm {
        system.at_checked(nm).map_err(AnalysisError::Wavelength)?;
    }
    match kind {
        PlotKind::Layout => Ok(Figure::Layout(layout_plot(lens, system, options)?)),
        PlotKind::Seidel => {
            let analysis = analyze(system, &options.analyze_options())?;
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
        PlotKind::RayFan => Ok(Figure::RayFan(ray_fan_plot(lens, system, options)?)),
        PlotKind::Spot => Ok(Figure::Spot(spot_plot(lens, system, options)?)),
        PlotKind::Lsa => Ok(Figure::Lsa(lsa_plot(lens, system, options)?)),
        PlotKind::FieldCurves => Ok(Figure::FieldCurves(field_curves_plot(
            lens, system, options,
        )?)),
        PlotKind::Distortion => Ok(Figure::Distortion(distortion_plot(lens, system, options)?)),
        PlotKind::LateralColor => Ok(Figure::LateralColor(lateral_color_plot(
            lens, system, options,
        )?)),
        PlotKind::Vignetting => Ok(Figure::Vignetting(vignetting_plot(lens, system, options)?)),
        PlotKind::OpdFan => Ok(Figure::OpdFan(opd_fan_plot(lens, system, options)?)),
        PlotKind::WavefrontMap => Ok(Figure::WavefrontMap(wavefront_map_plot(
            lens, system, options,
        )?)),
        PlotKind::Psf => Ok(Figure::Psf(psf_plot(lens, system, options)?)),
        PlotKind::Mtf => Ok(Figure::Mtf(mtf_plot(lens, system, options)?)),
        PlotKind::ThroughFocusMtf => Ok(Figure::ThroughFocusMtf(through_focus_plot(
            lens, system, options,
        )?)),
        PlotKind::MtfField => Ok(Figure::MtfField(mtf_field_plot(lens, system, options)?)),
    }
}

/// Points along the field axis of the curve plots (axis and edge included).
const CURVE_FIELD_STEPS: usize = 24;
/// Rays per fan, across the whole pupil (odd, so the pupil centre is one of them).
const FAN_SAMPLES: usize = 81;
/// Hexapolar rings of a spot diagram.
const SPOT_RINGS: usize = 12;
/// Pupil heights of the LSA curve.
const LSA_STEPS: usize = 40;
/// Pupil lattice per side for relative illumination.
const ILLUMINATION_GRID: usize = 32;
/// Where distortion and LSA start, as a fraction of the largest field or pupil height: both are
/// ratios (of image heights, of a ray's height to its slope), undefined on the axis itself.
const NEAR_AXIS: f64 = 1e-3;

/// The wavelengths one plot draws, and the one whose paraxial image plane and pupil every
/// wavelength is measured in.
pub(super) struct Spectrum {
    pub(super) reference_nm: f64,
    pub(super) drawn_nm: Vec<f64>,
}

impl Spectrum {
    /// The wavelengths of the design conditions.
    pub(super) fn of(conditions: &DesignConditions) -> Spectrum {
        Spectrum {
            reference_nm: conditions.reference_nm,
            drawn_nm: conditions.wavelengths_nm.clone(),
        }
    }
}

/// The real-ray analyses of `system` at each drawn wavelength, all in the paraxial image plane
/// of the reference wavelength, with the largest field to plot. Fields are the angles chief
/// rays make at the entrance-pupil centre; a finite object is traced from its own points, the
/// same points at every wavelength ([`RealSet::traced`]).
struct RealSet {
    conditions: DesignConditions,
    reference: RealRays,
    by_wavelength: Vec<(f64, RealRays)>,
}

impl RealSet {
    fn new(system: &LensSystem, options: &FigureOptions) -> Result<RealSet, FigureError> {
        let conditions = options.conditions(system)?;
        let spectrum = Spectrum::of(&conditions);
        let paraxial_options = conditions.paraxial_options();
        let real_at = |wavelength_nm: f64| -> Result<RealRays, FigureError> {
            let at = system.at(wavelength_nm);
            let paraxial = Paraxial::new(&at, &paraxial_options).map_err(AnalysisError::from)?;
            Ok(RealRays::new(&at, paraxial))
        };
        let reference = real_at(spectrum.reference_nm)?;
        // Every wavelength fills the reference wavelength's stop radius.
        let stop_radius = conditions
            .aiming_stop_radius(&reference)
            .map_err(AnalysisError::from)?;
        let aimed = |real: RealRays| match stop_radius {
            Some(radius) => real.aimed_at_stop(radius),
            None => real,
        };
        let reference = aimed(reference);
        let z_image = reference.paraxial().z_image;
        let by_wavelength = spectrum
            .drawn_nm
            .iter()
            .map(|&w| Ok((w, aimed(real_at(w)?.with_image_plane(z_image)))))
            .collect::<Result<_, FigureError>>()?;
        Ok(RealSet {
            conditions,
            reference,
            by_wavelength,
        })
    }

    /// The design fields of the fan and spot plots, top first.
    fn grid_fields(&self) -> Vec<f64> {
        self.conditions.fields_deg.clone()
    }

    /// The field value the analyses trace for the field angle `field_deg`: the angle at
    /// infinity, the object height of the reference wavelength's chief ray otherwise, so that
    /// every wavelength starts from the same object point.
    fn traced(&self, field_deg: f64) -> f64 {
        self.reference.paraxial().field_at_angle(field_deg)
    }

    /// Evenly spaced fields from the axis to the design field; the axis is moved out to
    /// `first`.
    fn curve_fields(&self, first: f64) -> Vec<f64> {
        (0..=CURVE_FIELD_STEPS)
            .map(|i| (i as f64 / CURVE_FIELD_STEPS as f64).max(first) * self.conditions.field_deg())
            .collect()
    }
}

/// The results of `analyse` at the samples (fields or pupil heights) where it succeeds; a sample
/// whose ray fails is left out, so one bad field does not hide the others.
fn where_traceable<T>(samples: &[f64], analyse: impl Fn(f64) -> Result<T, RealRayError>) -> Vec<T> {
    samples.iter().filter_map(|&f| analyse(f).ok()).collect()
}

fn ray_fan_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<RayFanPlot, FigureError> {
    let set = RealSet::new(system, options)?;
    let fields = set
        .grid_fields()
        .into_iter()
        .map(|field_deg| {
            let mut field = FanField {
                field_deg,
                tangential: Vec::new(),
                sagittal: Vec::new(),
                dropped_nm: Vec::new(),
            };
            for (wavelength_nm, real) in &set.by_wavelength {
                // A wavelength whose centre ray is blocked gets no curve: the panel says so.
                let Ok(fan) = real.ray_fan(set.traced(field_deg), FAN_SAMPLES) else {
                    field.dropped_nm.push(*wavelength_nm);
                    continue;
                };
                let curve = |points: &[FanPoint], axis: usize| FanCurve {
                    wavelength_nm: *wavelength_nm,
                    points: points
                        .iter()
                        .filter_map(|p| p.error.map(|e| (p.rho, e[axis])))
                        .collect(),
                };
                field.tangential.push(curve(&fan.tangential, 1));
                field.sagittal.push(curve(&fan.sagittal, 0));
            }
            field
        })
        .collect();
    Ok(RayFanPlot {
        lens: lens.to_string(),
        fields,
    })
}

fn spot_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<SpotPlot, FigureError> {
    let set = RealSet::new(system, options)?;
    let fields = set
        .grid_fields()
        .into_iter()
        .map(|field_deg| {
            // Every colour is drawn around the reference colour's centroid, so lateral colour
            // shows as an offset.
            let field = set.traced(field_deg);
            let centre = set
                .reference
                .spot(field, SPOT_RINGS)
                .map(|s| s.centroid)
                .ok();
            let spots = set
                .by_wavelength
                .iter()
                .filter_map(|(wavelength_nm, real)| {
                    let airy_radius_mm = AIRY_FIRST_ZERO
                        * wavelength_nm
                        * NM_TO_MM
                        * real.paraxial().working_f_number;
                    let spot = match real.spot(field, SPOT_RINGS) {
                        Ok(spot) => spot,
                        // A panel that says every ray is vignetted, not an empty row.
                        Err(RealRayError::NoLight { .. }) => {
                            return Some(Spot {
                                wavelength_nm: *wavelength_nm,
                                points: Vec::new(),
                                rms_radius_mm: 0.0,
                                geometric_radius_mm: 0.0,
                                airy_radius_mm,
                            });
                        }
                        Err(_) => return None,
                    };
                    let [cx, cy] = centre.unwrap_or(spot.centroid);
                    Some(Spot {
                        wavelength_nm: *wavelength_nm,
                        points: spot.points.iter().map(|p| (p[0] - cx, p[1] - cy)).collect(),
                        rms_radius_mm: spot.rms_radius,
                        geometric_radius_mm: spot.geometric_radius,
                        airy_radius_mm,
                    })
                })
                .collect();
            SpotField {
                field_deg,
                field_x_deg: 0.0,
                spots,
            }
        })
        .collect();
    Ok(SpotPlot {
        lens: lens.to_string(),
        fields,
    })
}

/// Spot diagrams of a lens placed off one axis ([`PlacedLens`]), from the exact 3-D trace: one
/// row per field of the file, (x, y) angles of an object at infinity, and one panel per
/// wavelength (`options.wavelengths_nm`, else the file's, else its design wavelength). Points
/// are in the image plane's own frame, relative to the first wavelength's centroid, so lateral
/// colour shows as an offset; the Airy disk is 0.61 λ / NA for the beam's numerical aperture
/// about its chief ray. `options.field_deg` replaces the file's fields by the one field
/// (0, θ); `options.epd_mm` replaces the pupil the file states.
pub fn placed_spot_plot(
    lens_name: &str,
    lens: &PlacedLens,
    options: &FigureOptions,
) -> Result<SpotPlot, FigureError> {
    let p = &lens.prescription;
    let design = p
        .provenance
        .design_wavelength_nm
        .unwrap_or(crate::prescription::DEFAULT_WAVELENGTH_NM);
    let mut beam = PlacedBeam::of(lens, &PlacedTracer::new(lens, design)?)?;
    if let Some(field) = options.field_deg {
        beam.fields_deg = vec![[0.0, field]];
    }
    if let Some(epd) = options.epd_mm {
        beam.pupil_diameter = epd;
    }
    let file_wavelengths = p
        .provenance
        .conditions
        .as_ref()
        .map(|c| c.wavelengths_nm.clone())
        .unwrap_or_default();
    let wavelengths = [
        options.wavelengths_nm.clone(),
        file_wavelengths,
        vec![design],
    ]
    .into_iter()
    .find(|w| !w.is_empty())
    .unwrap_or_default();
    let tracers = wavelengths
        .iter()
        .map(|&nm| PlacedTracer::new(lens, nm).map(|t| (nm, t)))
        .collect::<Result<Vec<_>, _>>()?;
    let fields = beam
        .fields_deg
        .iter()
        .map(|&field| {
            let beams = tracers
                .iter()
                .map(|(nm, tracer)| {
                    tracer
                        .collimated_spot(field, beam.pupil_diameter, SPOT_GRID)
                        .map(|spot| (*nm, spot))
                })
                .collect::<Result<Vec<_>, _>>()?;
            let centre = beams.first().and_then(|(_, s)| s.centroid);
            let spots = beams
                .into_iter()
                .map(|(wavelength_nm, spot)| {
                    let [cx, cy] = centre.or(spot.centroid).unwrap_or(spot.chief);
                    let own = spot.centroid.unwrap_or(spot.chief);
                    let geometric = spot
                        .points
                        .iter()
                        .map(|q| (q[0] - own[0]).hypot(q[1] - own[1]))
                        .fold(0.0, f64::max);
                    Spot {
                        wavelength_nm,
                        points: spot.points.iter().map(|q| (q[0] - cx, q[1] - cy)).collect(),
                        rms_radius_mm: spot.rms_radius.unwrap_or(0.0),
                        geometric_radius_mm: geometric,
                        airy_radius_mm: if spot.image_numerical_aperture > 0.0 {
                            0.5 * AIRY_FIRST_ZERO * wavelength_nm * NM_TO_MM
                                / spot.image_numerical_aperture
                        } else {
                            0.0
                        },
                    }
                })
                .collect();
            Ok(SpotField {
                field_deg: field[1],
                field_x_deg: field[0],
                spots,
            })
        })
        .collect::<Result<Vec<_>, FigureError>>()?;
    Ok(SpotPlot {
        lens: lens_name.to_string(),
        fields,
    })
}

/// Radius of the Airy disk's first dark ring in units of wavelength times working f-number.
const AIRY_FIRST_ZERO: f64 = 1.219_67;
const NM_TO_MM: f64 = 1e-6;

fn lsa_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<LsaPlot, FigureError> {
    let set = RealSet::new(system, options)?;
    let rhos: Vec<f64> = (0..=LSA_STEPS)
        .map(|i| (i as f64 / LSA_STEPS as f64).max(NEAR_AXIS))
        .collect();
    let curves = set
        .by_wavelength
        .iter()
        .map(|(wavelength_nm, real)| WavelengthCurve {
            wavelength_nm: *wavelength_nm,
            points: where_traceable(&rhos, |rho| real.lsa(&[rho]))
                .into_iter()
                .flatten()
                .map(|p| (p.rho, p.lsa))
                .collect(),
        })
        .collect();
    Ok(LsaPlot {
        lens: lens.to_string(),
        curves,
    })
}

fn field_curves_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<FieldCurvesPlot, FigureError> {
    let set = RealSet::new(system, options)?;
    let fields = set.curve_fields(0.0);
    let curves = set
        .by_wavelength
        .iter()
        .map(|(wavelength_nm, real)| FieldCurve {
            wavelength_nm: *wavelength_nm,
            points: where_traceable(&fields, |f| {
                let focus = real.field_curves(&[set.traced(f)])?;
                Ok((f, focus[0].sagittal, focus[0].tangential))
            }),
        })
        .collect();
    Ok(FieldCurvesPlot {
        lens: lens.to_string(),
        curves,
    })
}

fn distortion_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<DistortionPlot, FigureError> {
    let set = RealSet::new(system, options)?;
    let fields = set.curve_fields(NEAR_AXIS);
    let points = where_traceable(&fields, |f| {
        Ok((f, set.reference.distortion(&[set.traced(f)])?[0].percent))
    });
    let reference = match set.conditions.object_distance_mm {
        None => "f·tan θ",
        Some(_) => "m·h",
    };
    Ok(DistortionPlot {
        lens: lens.to_string(),
        wavelength_nm: set.reference.paraxial().wavelength_nm,
        reference: reference.into(),
        points,
    })
}

/// Each drawn wavelength's real chief-ray image height minus the reference wavelength's, in
/// the reference's paraxial image plane.
fn lateral_color_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<LateralColorPlot, FigureError> {
    let set = RealSet::new(system, options)?;
    let reference_nm = set.reference.paraxial().wavelength_nm;
    let fields = set.curve_fields(0.0);
    let height = |real: &RealRays, field_deg: f64| -> Result<f64, RealRayError> {
        Ok(real.distortion(&[set.traced(field_deg)])?[0].real_height)
    };
    let curves = if system.disperses() {
        set.by_wavelength
            .iter()
            .filter(|(wavelength_nm, _)| *wavelength_nm != reference_nm)
            .map(|(wavelength_nm, real)| WavelengthCurve {
                wavelength_nm: *wavelength_nm,
                points: where_traceable(&fields, |f| {
                    Ok((f, height(real, f)? - height(&set.reference, f)?))
                }),
            })
            .collect()
    } else {
        Vec::new()
    };
    Ok(LateralColorPlot {
        lens: lens.to_string(),
        reference_nm,
        disperses: system.disperses(),
        curves,
    })
}

fn vignetting_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<VignettingPlot, FigureError> {
    let set = RealSet::new(system, options)?;
    let fields = set.curve_fields(0.0);
    let points = where_traceable(&fields, |f| {
        let lit = &set
            .reference
            .illumination(&[set.traced(f)], ILLUMINATION_GRID)?[0];
        Ok((f, lit.relative, 1.0 - lit.vignetted_fraction))
    });
    Ok(VignettingPlot {
        lens: lens.to_string(),
        points,
    })
}

/// Where layout rays cross the stop, as fractions of its radius (meridional plane). Just inside
/// the rim, so the marginal rays are not lost to round-off at the stop's edge.
const LAYOUT_STOP_HEIGHTS: [f64; 5] = [-0.999, -0.5, 0.0, 0.5, 0.999];

/// The cross-section with ray bundles at the design fields, in the design aperture.
fn layout_plot(
    lens: &str,
    system: &LensSystem,
    options: &FigureOptions,
) -> Result<LayoutPlot, FigureError> {
    let conditions = options.conditions(system)?;
    let at = system.at(conditions.reference_nm);
    let tracer = Tracer::new(&at);
    // The bundles fill the design entrance pupil, a fraction of the stop wide open.
    let wide_open = Paraxial::new(
        &at,
        &ParaxialOptions {
            aperture: Aperture::StopClearAperture,
            ..conditions.paraxial_options()
        },
    )
    .map_err(AnalysisError::from)?;
    let fill = (conditions.epd_mm / wide_open.entrance_pupil.diameter).min(1.0);
    let mut plot = LayoutPlot::of_system(lens, &at);
    if wide_open.object_distance.is_some() {
        plot.image_z = wide_open.z_image;
    }
    let mut fields = conditions.fields_deg.clone();
    fields.reverse();
    for field_deg in fields {
        let source = RaySource::of_field(
            wide_open.object_distance,
            wide_open.field_at_angle(field_deg),
            tracer.front_start_z(),
        );
        plot.rays.extend(layout_rays(
            &tracer,
            &at,
            field_deg,
            &source,
            fill,
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
    Ok(plot)
}

/// The meridional rays of one field, leaving `source`, for the layout: from in front of the lens
/// (a near object's point itself) to the image plane or to the surface that stops them,
/// crossing the stop at `fill` of its radius at most. Rays that cannot be aimed, and vignetted
/// rays that never enter the lens (they would float as fragments in front of it), are left out.
fn layout_rays(
    tracer: &Tracer,
    at: &SystemAt,
    field_deg: f64,
    source: &RaySource,
    fill: f64,
    image_z: f64,
) -> Vec<LayoutRay> {
    let stop_radius = at.surfaces[at.stop].semi_aperture * fill;
    let largest = at
        .surfaces
        .iter()
        .map(|s| s.semi_aperture)
        .fold(0.0, f64::max);
    // Rays from an object no farther in front of the lens than the image lies behind its first
    // vertex start at the object point, as a finite-conjugate layout is drawn; others start 1.5
    // apertures in front of the lens, or later where a steep ray would otherwise run far
    // outside the lens's height and dwarf the drawing, and never before the object.
    let first_vertex = at.surfaces[0].vertex_z;
    let object_z = match source {
        RaySource::Point { position } => position[2],
        RaySource::Collimated { .. } | RaySource::Converging { .. } => f64::NEG_INFINITY,
    };
    let near_object = object_z >= first_vertex - (image_z - first_vertex).abs();
    let draw_from = |ray: &crate::trace::Ray| {
        if near_object {
            return object_z;
        }
        let [_, y, z] = ray.position();
        let [_, dy, dz] = ray.direction();
        let earliest = (first_vertex - 1.5 * largest).max(object_z);
        if dy == 0.0 {
            return earliest;
        }
        let limit = 1.3 * largest * dy.signum();
        earliest.max(z + (-limit - y) * dz / dy)
    };
    let aim = StopAim::new(tracer, *source);
    LAYOUT_STOP_HEIGHTS
        .iter()
        .filter_map(|&h| aim.aim([0.0, h * stop_radius]).ok())
        .filter_map(|ray| {
            let traced = tracer.trace_path(ray, Travel::Forward, Apertures::Checked);
            let start = ray.point_at_z(draw_from(&ray))?;
            let first = traced.crossings.first()?;
            if start[2] >= first.point[2] {
                return None;
            }
            let mut path: Vec<(f64, f64)> = std::iter::once(start)
                .chain(traced.crossings.iter().map(|c| c.point))
                .map(|p| (p[2], p[1]))
                .collect();
            let vignetted = !traced.traced.outcome.is_ok();
            if vignetted {
                let stopped = traced.traced.ray.position();
                path.push((stopped[2], stopped[1]));
            } else {
                let end = traced.traced.ray.point_at_z(image_z)?;
                path.push((end[2], end[1]));
            }
            Some(LayoutRay {
                field_deg,
                path,
                vignetted,
            })
        })
        .collect()
}
