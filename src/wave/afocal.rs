//! Wave optics at infinity: an afocal system sends a collimated beam out, so its wavefront is
//! measured against a plane normal to the chief ray (not a sphere about an image point), its
//! image is angular, and the PSF and MTF are in angle: the MTF in cycles per milliradian.
//!
//! A plane is the sphere of [`super::PupilTrace::wavefront`] with its centre at infinity. The
//! plane passes through the chief ray's crossing of the paraxial exit pupil, where an eye (or
//! the next instrument) sits; OPD = OPL(chief) - OPL(ray) to that plane, in waves, positive
//! where the ray's wavefront leads, piston removed from every statistic, tilt kept (it is the
//! chief ray's reference, so a field's mean tilt is what distortion adds).
//!
//! In the far field a pupil shift s (mm, across the beam in a medium of index n') is a spatial
//! frequency n' s / λ cycles per radian, so a beam of diameter D cuts off at n' D / λ.

use super::mtf::{diffraction_limited_mtf, otf_at};
use super::pupil::{ExitRay, exit_ray, inside_pupil, pupil_coordinate, wavefront_stats};
use super::{NM_TO_MM, Sampling, WaveError, WavefrontStats};
use crate::paraxial::AfocalParaxial;
use crate::system::SystemAt;
use crate::trace::{Apertures, Ray, Tracer, Vec3, dot};
use serde::Serialize;

/// Milliradians per radian.
const MRAD_PER_RAD: f64 = 1e3;

/// The collimated output of one field point at one wavelength against a plane.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AfocalWavefront {
    pub wavelength_nm: f64,
    pub field_deg: f64,
    /// Pupil points per side; index k is at pupil coordinate -1 + 2k/(samples-1).
    pub samples: usize,
    /// OPD in waves against the plane, row-major with rows along pupil y; None outside the
    /// pupil or vignetted.
    pub opd_waves: Vec<Option<f64>>,
    /// Each ray's angle from the chief ray, (x, y) tangents in milliradians, y in the plane of
    /// the field (turned with the beam after mirrors).
    pub angular_errors_mrad: Vec<Option<[f64; 2]>>,
    /// Unit direction of the chief ray leaving the system: the reference plane's normal.
    pub chief_direction: Vec3,
    /// Where the reference plane meets the chief ray, lens frame, mm.
    pub reference_point_mm: Vec3,
    /// Angular frequency of one pupil-sample lag, [tangential, sagittal], cycles/mrad.
    pub lag_frequency_per_mrad: [f64; 2],
    /// Diffraction cutoff n' D / λ of the paraxial exit beam of diameter D, cycles/mrad.
    pub cutoff_per_mrad: f64,
    pub stats: WavefrontStats,
    /// RMS angle of the rays from their mean direction, mrad (the geometric angular spot).
    pub rms_angular_spot_mrad: f64,
}

/// Diffraction MTF of a collimated beam in angular frequency.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AngularMtf {
    pub field_deg: f64,
    pub frequencies_per_mrad: Vec<f64>,
    pub tangential: Vec<f64>,
    pub sagittal: Vec<f64>,
    /// The aberration-free circular beam of the same diameter.
    pub diffraction_limit: Vec<f64>,
    pub cutoff_per_mrad: f64,
}

/// Traces the beam of `field_deg` through the entrance pupil of `paraxial` (which must come from
/// `system`) on a square grid of `sampling.samples` points per side, and measures it against the
/// plane normal to its chief ray.
///
/// ```
/// use lensbake::paraxial::{AfocalParaxial, StopChoice};
/// use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
/// use lensbake::system::LensSystem;
/// use lensbake::wave::{Sampling, afocal_wavefront};
///
/// // A flat window: a plane wave leaves it as a plane wave.
/// let window = Prescription {
///     surfaces: vec![
///         Surface { stop: Some(StopShape::Circle), ..Surface::open(Shape::Plane, 5.0, Medium::Index(1.5), 10.0) },
///         Surface::open(Shape::Plane, 10.0, Medium::Air, 10.0),
///     ],
///     provenance: Provenance::default(),
///     object_medium: Medium::Air,
/// };
/// let at = LensSystem::from_prescription(window)?.at(550.0);
/// let paraxial = AfocalParaxial::new(&at, Some(10.0), 5.0, StopChoice::Marked)?;
/// let wave = afocal_wavefront(&at, &paraxial, 5.0, Sampling::default())?;
/// assert!(wave.stats.rms_waves < 1e-9);
/// assert!((paraxial.angular_magnification - 1.0).abs() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn afocal_wavefront(
    system: &SystemAt,
    paraxial: &AfocalParaxial,
    field_deg: f64,
    sampling: Sampling,
) -> Result<AfocalWavefront, WaveError> {
    let samples = sampling.checked()?.samples;
    if let Some(i) = system
        .surfaces
        .iter()
        .position(|s| matches!(s.shape, crate::prescription::Shape::IdealLens { .. }))
    {
        return Err(WaveError::IdealLensPath { surface: i + 1 });
    }
    if !(field_deg.is_finite() && field_deg.abs() < 90.0) {
        return Err(WaveError::Field { field_deg });
    }
    let tracer = Tracer::new(system);
    let angle = field_deg.to_radians();
    let beam = [0.0, angle.sin(), angle.cos()];
    let radius = paraxial.entrance_pupil.diameter / 2.0;
    let z_pupil = paraxial.entrance_pupil.z;
    let start_z = tracer.front_start_z();
    // The ray of the collimated beam through (px, py) of the paraxial entrance pupil.
    let launch = |px: f64, py: f64| -> Option<Ray> {
        let back = (z_pupil - start_z) / beam[2];
        Ray::new(
            [
                px * radius - back * beam[0],
                py * radius - back * beam[1],
                start_z,
            ],
            beam,
        )
        .ok()
    };
    let no_light = WaveError::NoLight { field_deg };
    let origin = launch(0.0, 0.0).ok_or(no_light.clone())?.position();
    let trace = |px: f64, py: f64, apertures: Apertures| -> Option<ExitRay> {
        exit_ray(&tracer, system, launch(px, py)?, origin, apertures)
    };
    let chief = trace(0.0, 0.0, Apertures::Ignored).ok_or(no_light.clone())?;
    let image_index = system.image_index().abs();
    let normal = chief.direction;
    let reference_point = paraxial
        .exit_pupil
        .and_then(|pupil| chief.at_z(pupil.z, image_index))
        .map_or(chief.position, |(point, _)| point);
    // Axes of the reference plane: x stays x; y is the field direction turned with the beam.
    let axis_x = [1.0, 0.0, 0.0];
    let axis_y = [0.0, normal[2], -normal[1]];
    // Optical path to the plane, and where the ray crosses it.
    let on_plane = |ray: &ExitRay| -> Option<(f64, Vec3)> {
        let along = dot(ray.direction, normal);
        let offset = [
            reference_point[0] - ray.position[0],
            reference_point[1] - ray.position[1],
            reference_point[2] - ray.position[2],
        ];
        let t = dot(offset, normal) / along;
        let point = [
            ray.position[0] + t * ray.direction[0],
            ray.position[1] + t * ray.direction[1],
            ray.position[2] + t * ray.direction[2],
        ];
        (t.is_finite() && along > 0.0).then_some((ray.optical_path + image_index * t, point))
    };
    let (chief_path, _) = on_plane(&chief).ok_or(no_light.clone())?;
    let wavelength_mm = system.wavelength_nm * NM_TO_MM;

    let mut lag_frequency_per_mrad = [0.0; 2];
    for (axis, (px, py)) in [(0.0, 1.0), (1.0, 0.0)].into_iter().enumerate() {
        let edge = |sign: f64| {
            trace(sign * px, sign * py, Apertures::Ignored)
                .and_then(|ray| on_plane(&ray))
                .ok_or(WaveError::PupilEdge {
                    field_deg,
                    px: sign * px,
                    py: sign * py,
                })
        };
        let ((_, plus), (_, minus)) = (edge(1.0)?, edge(-1.0)?);
        let span = ((plus[0] - minus[0]).powi(2)
            + (plus[1] - minus[1]).powi(2)
            + (plus[2] - minus[2]).powi(2))
        .sqrt();
        lag_frequency_per_mrad[axis] =
            image_index * span / ((samples - 1) as f64 * wavelength_mm * MRAD_PER_RAD);
    }

    let mut opd_waves = Vec::with_capacity(samples * samples);
    let mut angular_errors_mrad = Vec::with_capacity(samples * samples);
    for i in 0..samples * samples {
        let (ix, iy) = (i % samples, i / samples);
        let measured = inside_pupil(samples, ix, iy)
            .then(|| {
                let ray = trace(
                    pupil_coordinate(samples, ix),
                    pupil_coordinate(samples, iy),
                    Apertures::Checked,
                )?;
                let (path, _) = on_plane(&ray)?;
                let along = dot(ray.direction, normal);
                let tangents = [
                    dot(ray.direction, axis_x) / along * MRAD_PER_RAD,
                    dot(ray.direction, axis_y) / along * MRAD_PER_RAD,
                ];
                let opd = (chief_path - path) / wavelength_mm;
                opd.is_finite().then_some((opd, tangents))
            })
            .flatten();
        opd_waves.push(measured.map(|m| m.0));
        angular_errors_mrad.push(measured.map(|m| m.1));
    }
    let stats = wavefront_stats(samples, &opd_waves);
    if stats.transmitted_samples == 0 {
        return Err(no_light);
    }
    let exit_diameter = paraxial.exit_beam_radius() * 2.0;
    Ok(AfocalWavefront {
        wavelength_nm: system.wavelength_nm,
        field_deg,
        samples,
        rms_angular_spot_mrad: rms_spread(angular_errors_mrad.iter().flatten()),
        opd_waves,
        angular_errors_mrad,
        chief_direction: normal,
        reference_point_mm: reference_point,
        lag_frequency_per_mrad,
        cutoff_per_mrad: image_index * exit_diameter / (wavelength_mm * MRAD_PER_RAD),
        stats,
    })
}

/// RMS distance of `points` from their centroid.
fn rms_spread<'a>(points: impl Iterator<Item = &'a [f64; 2]> + Clone) -> f64 {
    let count = points.clone().count() as f64;
    let [mx, my] = points
        .clone()
        .fold([0.0, 0.0], |[x, y], p| [x + p[0] / count, y + p[1] / count]);
    (points
        .map(|p| (p[0] - mx).powi(2) + (p[1] - my).powi(2))
        .sum::<f64>()
        / count)
        .sqrt()
}

impl AfocalWavefront {
    /// Diffraction MTF at `frequencies_per_mrad` (each zero or positive).
    pub fn mtf(&self, frequencies_per_mrad: &[f64]) -> Result<AngularMtf, WaveError> {
        if let Some(&value) = frequencies_per_mrad
            .iter()
            .find(|f| !(f.is_finite() && **f >= 0.0))
        {
            return Err(WaveError::NotFinite {
                what: "an MTF frequency (cycles/mrad, zero or positive)",
                value,
            });
        }
        let [tangential, sagittal] = [0, 1].map(|axis| {
            otf_at(
                self.samples,
                &self.opd_waves,
                axis,
                self.lag_frequency_per_mrad[axis],
                frequencies_per_mrad,
            )
            .iter()
            .map(|v| v.norm().min(1.0))
            .collect()
        });
        Ok(AngularMtf {
            field_deg: self.field_deg,
            frequencies_per_mrad: frequencies_per_mrad.to_vec(),
            tangential,
            sagittal,
            diffraction_limit: frequencies_per_mrad
                .iter()
                .map(|f| diffraction_limited_mtf(f / self.cutoff_per_mrad))
                .collect(),
            cutoff_per_mrad: self.cutoff_per_mrad,
        })
    }
}
