//! The pupil traced once per field and wavelength, and its wavefront against a reference sphere
//! in any image plane.

use super::{NM_TO_MM, Sampling, WaveError, positive};
use crate::limits::short;
use crate::paraxial::{Aperture, Field, ObjectPosition, Paraxial, ParaxialOptions};
use crate::prescription::RayAiming;
use crate::system::{LensSystem, SystemAt};
use crate::trace::analyses::{RealRayError, RealRays};
use crate::trace::{Apertures, Ray, Tracer, Travel, Vec3};
use rayon::prelude::*;
use serde::Serialize;

/// What is analysed: a lens from its prescription, or an ideal (aberration-free, aplanatic)
/// lens of a given focal length and f-number.
#[derive(Clone, Copy, Debug)]
pub enum WaveLens<'a> {
    /// A real lens. `epd_mm` sets the beam's diameter in the paraxial entrance pupil as a
    /// design program's EPD does: the stop keeps its clear aperture, so a beam wider than it is
    /// clipped and a narrower one passes whole. None fills the stop. The object lies
    /// `object_distance_mm` in front of surface 1, at infinity when None; its field points are
    /// named by the angle their chief ray makes at the entrance-pupil centre
    /// ([`crate::paraxial::Paraxial::field_at_angle`]), and the image plane is its conjugate.
    /// `ray_aiming` says where a pupil coordinate points ([`RealRays::aimed_at_stop`]); real
    /// aiming fills the stop radius of the reference wavelength.
    Real {
        system: &'a LensSystem,
        epd_mm: Option<f64>,
        object_distance_mm: Option<f64>,
        ray_aiming: RayAiming,
    },
    /// A perfect lens in air: every field point is imaged to a point by a spherical wave whose
    /// exit pupil is a sphere of radius `efl_mm` (the sine condition holds), so its numerical
    /// aperture is exactly 1 / (2 `f_number`).
    Ideal { efl_mm: f64, f_number: f64 },
}

/// One ray after the last surface, with the optical path from the incident wavefront.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ExitRay {
    pub(super) position: Vec3,
    pub(super) direction: Vec3,
    pub(super) optical_path: f64,
}

impl ExitRay {
    pub(super) fn at_z(&self, z: f64, image_index: f64) -> Option<(Vec3, f64)> {
        let t = (z - self.position[2]) / self.direction[2];
        t.is_finite().then(|| {
            (
                [
                    self.position[0] + t * self.direction[0],
                    self.position[1] + t * self.direction[1],
                    z,
                ],
                self.optical_path + image_index * t,
            )
        })
    }
}

/// The rays of one field point at one wavelength through a square grid over the pupil, traced
/// once; [`PupilTrace::wavefront`] measures them against a reference sphere in any image plane.
#[derive(Clone, Debug, PartialEq)]
pub struct PupilTrace {
    pub wavelength_nm: f64,
    pub field_deg: f64,
    pub samples: usize,
    /// The plane the analyses use unless told otherwise: the paraxial image plane of the
    /// reference wavelength (for an ideal lens, its focal plane).
    pub image_z: f64,
    /// Diffraction cutoff of the on-axis paraxial beam, 1 / (λ N_w), cycles/mm.
    pub cutoff_per_mm: f64,
    /// Image-space frequency of one pupil-sample lag, [tangential, sagittal], cycles/mm.
    pub lag_frequency_per_mm: [f64; 2],
    /// Whether exit directions fall as the pupil coordinate rises, [tangential, sagittal]: true
    /// for a real image (the top of the pupil sends its ray down).
    pub mirrored: [bool; 2],
    rays: Vec<Option<ExitRay>>,
    chief: ExitRay,
    exit_pupil: Vec3,
    image_index: f64,
}

/// The optical path difference over the pupil in one image plane.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WavefrontMap {
    pub wavelength_nm: f64,
    pub field_deg: f64,
    /// Pupil points per side; index k is at pupil coordinate -1 + 2k/(samples-1).
    pub samples: usize,
    /// OPD in waves, row-major with rows along pupil y; None outside the pupil or vignetted.
    pub opd_waves: Vec<Option<f64>>,
    /// Where each ray meets the image plane, relative to the reference point (mm).
    pub image_points_mm: Vec<Option<[f64; 2]>>,
    /// Each ray's exit direction cosines (x, y) times the image index.
    pub exit_directions: Vec<Option<[f64; 2]>>,
    /// Image-space frequency of one pupil-sample lag, [tangential, sagittal], cycles/mm.
    pub lag_frequency_per_mm: [f64; 2],
    /// Whether exit directions fall as the pupil coordinate rises, [tangential, sagittal].
    pub mirrored: [bool; 2],
    /// 1 / (λ N_w) of the on-axis paraxial beam, cycles/mm.
    pub cutoff_per_mm: f64,
    /// Centre of the reference sphere (the chief ray in the image plane), lens frame, mm.
    pub reference_point_mm: Vec3,
    /// Radius of the reference sphere, mm.
    pub reference_radius_mm: f64,
}

/// Summary numbers of a wavefront, all with piston removed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct WavefrontStats {
    /// Root-mean-square OPD about its mean over the transmitted samples, waves.
    pub rms_waves: f64,
    /// Largest minus smallest OPD, waves.
    pub pv_waves: f64,
    /// Peak of the PSF over the peak of the same pupil without aberration, with the tilt
    /// removed (the peak wherever it lands): |Σ exp(2πi (W - tilt))|² / N².
    pub strehl: f64,
    /// Pupil samples inside the unit circle, and how many of them are transmitted.
    pub pupil_samples: usize,
    pub transmitted_samples: usize,
}

/// Pupil coordinate of grid index `k` on a grid of `samples` points per side.
pub(crate) fn pupil_coordinate(samples: usize, k: usize) -> f64 {
    -1.0 + 2.0 * k as f64 / (samples - 1) as f64
}

/// Whether grid point (ix, iy) lies inside the unit pupil.
pub(crate) fn inside_pupil(samples: usize, ix: usize, iy: usize) -> bool {
    let (x, y) = (pupil_coordinate(samples, ix), pupil_coordinate(samples, iy));
    x * x + y * y <= 1.0 + 1e-12
}

impl PupilTrace {
    /// Traces `lens` at `field_deg` and `wavelength_nm`; the image plane is the paraxial image of
    /// `reference_nm` (the same plane for every wavelength of a polychromatic analysis).
    pub fn trace(
        lens: &WaveLens,
        field_deg: f64,
        wavelength_nm: f64,
        reference_nm: f64,
        sampling: Sampling,
    ) -> Result<PupilTrace, WaveError> {
        let sampling = sampling.checked()?;
        crate::limits::check_wavelength(wavelength_nm)?;
        crate::limits::check_wavelength(reference_nm)?;
        match *lens {
            WaveLens::Real { system, .. }
                if let Some(i) = system.prescription.surfaces.iter().position(|s| {
                    matches!(s.shape, crate::prescription::Shape::IdealLens { .. })
                }) =>
            {
                Err(WaveError::IdealLensPath { surface: i + 1 })
            }
            WaveLens::Real {
                system,
                epd_mm,
                object_distance_mm,
                ray_aiming,
            } => trace_real(
                RealLens {
                    system,
                    epd_mm,
                    object: ObjectPosition::in_focus(object_distance_mm),
                    ray_aiming,
                },
                field_deg,
                wavelength_nm,
                reference_nm,
                sampling.samples,
            ),
            WaveLens::Ideal { efl_mm, f_number } => {
                ideal(efl_mm, f_number, field_deg, wavelength_nm, sampling.samples)
            }
        }
    }

    /// Where the chief ray meets the plane `defocus_mm` beyond [`PupilTrace::image_z`].
    pub fn chief_point(&self, defocus_mm: f64) -> Option<[f64; 2]> {
        self.chief
            .at_z(self.image_z + defocus_mm, self.image_index)
            .map(|(p, _)| [p[0], p[1]])
    }

    /// The wavefront in the plane `defocus_mm` beyond [`PupilTrace::image_z`], against the
    /// sphere centred on the chief ray there.
    pub fn wavefront(&self, defocus_mm: f64) -> Result<WavefrontMap, WaveError> {
        self.wavefront_about(defocus_mm, None)
    }

    /// The wavefront against a sphere centred on `centre` (x, y in the image plane): a
    /// polychromatic analysis centres every wavelength on the reference wavelength's chief ray,
    /// so lateral colour shows as tilt.
    pub fn wavefront_about(
        &self,
        defocus_mm: f64,
        centre: Option<[f64; 2]>,
    ) -> Result<WavefrontMap, WaveError> {
        let z = self.image_z + super::finite("defocus (mm)", defocus_mm)?;
        let no_light = WaveError::NoLight {
            field_deg: self.field_deg,
        };
        let (chief_point, _) = self
            .chief
            .at_z(z, self.image_index)
            .ok_or(no_light.clone())?;
        let [cx, cy] = centre.unwrap_or([chief_point[0], chief_point[1]]);
        let centre = [cx, cy, z];
        let radius = distance(centre, self.exit_pupil);
        let on_sphere = |ray: &ExitRay| -> Option<f64> {
            let (point, path) = ray.at_z(z, self.image_index)?;
            let back = back_to_sphere(point, ray.direction, centre, radius);
            Some(path - self.image_index * back)
        };
        let reference_path = on_sphere(&self.chief).ok_or(no_light.clone())?;
        let wavelength_mm = self.wavelength_nm * NM_TO_MM;
        let mut opd_waves = Vec::with_capacity(self.rays.len());
        let mut image_points_mm = Vec::with_capacity(self.rays.len());
        let mut exit_directions = Vec::with_capacity(self.rays.len());
        for ray in &self.rays {
            let measured = ray.and_then(|ray| {
                let (point, _) = ray.at_z(z, self.image_index)?;
                let opd = (reference_path - on_sphere(&ray)?) / wavelength_mm;
                opd.is_finite().then_some((
                    opd,
                    [point[0] - cx, point[1] - cy],
                    [
                        self.image_index * ray.direction[0],
                        self.image_index * ray.direction[1],
                    ],
                ))
            });
            opd_waves.push(measured.map(|m| m.0));
            image_points_mm.push(measured.map(|m| m.1));
            exit_directions.push(measured.map(|m| m.2));
        }
        if opd_waves.iter().all(Option::is_none) {
            return Err(no_light);
        }
        Ok(WavefrontMap {
            wavelength_nm: self.wavelength_nm,
            field_deg: self.field_deg,
            samples: self.samples,
            opd_waves,
            image_points_mm,
            exit_directions,
            lag_frequency_per_mm: self.lag_frequency_per_mm,
            mirrored: self.mirrored,
            cutoff_per_mm: self.cutoff_per_mm,
            reference_point_mm: centre,
            reference_radius_mm: radius,
        })
    }
}

/// How far back along `direction` from `point` the sphere (centre, radius) lies: the nearer
/// crossing behind the point, else the farther (optiland's choice, so both measure the same
/// path when the image point lies inside the sphere).
fn back_to_sphere(point: Vec3, direction: Vec3, centre: Vec3, radius: f64) -> f64 {
    let d = [
        point[0] - centre[0],
        point[1] - centre[1],
        point[2] - centre[2],
    ];
    let b = -2.0 * (direction[0] * d[0] + direction[1] * d[1] + direction[2] * d[2]);
    let c = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - radius * radius;
    let root = (b * b - 4.0 * c).max(0.0).sqrt();
    let near = 0.5 * (-b - root);
    if near < 0.0 { 0.5 * (-b + root) } else { near }
}

fn distance(a: Vec3, b: Vec3) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The fields of [`WaveLens::Real`], its object placed.
struct RealLens<'a> {
    system: &'a LensSystem,
    epd_mm: Option<f64>,
    object: ObjectPosition,
    ray_aiming: RayAiming,
}

fn trace_real(
    lens: RealLens,
    field_deg: f64,
    wavelength_nm: f64,
    reference_nm: f64,
    samples: usize,
) -> Result<PupilTrace, WaveError> {
    let RealLens {
        system,
        epd_mm,
        object,
        ray_aiming,
    } = lens;
    let options = ParaxialOptions {
        object,
        aperture: epd_mm.map_or(Aperture::StopClearAperture, Aperture::EntrancePupilDiameter),
        field: Field::Angle { deg: field_deg },
        ..ParaxialOptions::default()
    };
    if let Some(epd_mm) = epd_mm {
        positive("entrance-pupil diameter (mm)", epd_mm)?;
    }
    let reference_at = system.at_checked(reference_nm)?;
    let reference = Paraxial::new(&reference_at, &options)?;
    let pupil = match epd_mm {
        Some(epd_mm) => format!("the f-number of a {} mm entrance pupil", short(epd_mm)),
        None => "the f-number wide open".to_string(),
    };
    check_f_number(&pupil, reference.f_number.abs())?;
    let at = system.at_checked(wavelength_nm)?;
    let paraxial = Paraxial::new(&at, &options)?;
    let exit_pupil_z = paraxial.exit_pupil.ok_or(WaveError::ExitPupilAtInfinity)?.z;
    let cutoff_per_mm = 1.0 / (wavelength_nm * NM_TO_MM * paraxial.working_f_number);
    let real = RealRays::new(&at, paraxial);
    let real = match ray_aiming {
        RayAiming::Paraxial => real,
        RayAiming::Real => real
            .aimed_at_stop(RealRays::new(&reference_at, reference.clone()).filled_stop_radius()?),
    };
    // Every wavelength starts from the reference wavelength's object point.
    let field = reference.field_at_angle(field_deg);
    // Optical paths weigh lengths by the physical index; the sign of the image-space index only
    // says which way light travels there.
    let image_index = at.image_index().abs();
    let field_rays = real.field_rays(field)?;
    let chief_start = field_rays.pupil_ray(0.0, 0.0)?;
    // A point on the incident wavefront: the chief ray's start on a collimated beam's plane, the
    // object point of a real or a virtual object.
    let wavefront_origin = match object {
        ObjectPosition::Infinite => chief_start.position(),
        ObjectPosition::Finite { distance } => [0.0, field, -distance],
    };
    let trace = |px: f64, py: f64, apertures: Apertures| -> Result<Option<ExitRay>, WaveError> {
        Ok(field_rays
            .launch(px, py)?
            .ok()
            .and_then(|ray| exit_ray(real.tracer(), &at, ray, wavefront_origin, apertures)))
    };
    let chief = trace(0.0, 0.0, Apertures::Ignored)?.ok_or(RealRayError::ChiefRay {
        field: field_deg,
        outcome: real
            .tracer()
            .trace_with(chief_start, Travel::Forward, Apertures::Ignored)
            .outcome,
    })?;
    // The pupil's frequency scale: the spread of exit directions between opposite pupil edges,
    // as optiland and OpticStudio calibrate it (apertures ignored, so a vignetted edge still
    // gives the geometry).
    let mut lag_frequency_per_mm = [0.0; 2];
    let mut mirrored = [false; 2];
    for (axis, (px, py)) in [(0.0, 1.0), (1.0, 0.0)].into_iter().enumerate() {
        let edge = |sign: f64| -> Result<ExitRay, WaveError> {
            trace(sign * px, sign * py, Apertures::Ignored)?.ok_or(WaveError::PupilEdge {
                field_deg,
                px: sign * px,
                py: sign * py,
            })
        };
        let (plus, minus) = (edge(1.0)?, edge(-1.0)?);
        let spread =
            (plus.direction[0] - minus.direction[0]).hypot(plus.direction[1] - minus.direction[1]);
        mirrored[axis] = plus.direction[1 - axis] < minus.direction[1 - axis];
        lag_frequency_per_mm[axis] =
            image_index * spread / ((samples - 1) as f64 * wavelength_nm * NM_TO_MM);
    }
    let rays = (0..samples * samples)
        .into_par_iter()
        .map(|i| {
            let (ix, iy) = (i % samples, i / samples);
            if !inside_pupil(samples, ix, iy) {
                return Ok(None);
            }
            let (px, py) = (pupil_coordinate(samples, ix), pupil_coordinate(samples, iy));
            trace(px, py, Apertures::Checked)
        })
        .collect::<Result<Vec<_>, WaveError>>()?;
    Ok(PupilTrace {
        wavelength_nm,
        field_deg,
        samples,
        image_z: reference.z_image,
        cutoff_per_mm,
        lag_frequency_per_mm,
        mirrored,
        rays,
        chief,
        exit_pupil: [0.0, 0.0, exit_pupil_z],
        image_index,
    })
}

/// Traces `ray` and sums its optical path: from the incident wavefront through `origin` (a plane
/// normal to a collimated beam, or a sphere about the object point)
/// to the last surface.
pub(super) fn exit_ray(
    tracer: &Tracer,
    at: &SystemAt,
    ray: Ray,
    origin: Vec3,
    apertures: Apertures,
) -> Option<ExitRay> {
    let path = tracer.trace_path(ray, Travel::Forward, apertures);
    if !path.traced.outcome.is_ok() {
        return None;
    }
    let start = ray.position();
    let launch = ray.direction();
    // Collimated rays start on one plane z = const, which is not a wavefront when the beam is
    // oblique: add the incident path from the plane normal to the beam through the chief's
    // start. A real point object's rays share their start, so this term is zero for them; a
    // virtual object's start on a plane before the lens, short of the point they converge on
    // by the (negative) path this term adds.
    let mut optical_path = at.object_index
        * ((start[0] - origin[0]) * launch[0]
            + (start[1] - origin[1]) * launch[1]
            + (start[2] - origin[2]) * launch[2]);
    let mut previous = start;
    for (crossing, (_, _, index_before, _)) in path.crossings.iter().zip(at.path()) {
        optical_path += index_before.abs() * distance(crossing.point, previous);
        previous = crossing.point;
    }
    Some(ExitRay {
        position: previous,
        direction: path.traced.ray.direction(),
        optical_path,
    })
}

/// Refuses a pupil slower than the slowest f-number any command takes (docs/limits.md): the
/// PSF's scale grows with the f-number, and at f/1e300 a PSF plot's axes spanned 1e297 mm and
/// plotters never finished their ticks. An afocal lens's f-number is not finite; it has no image
/// to scale and fails on its exit pupil instead.
fn check_f_number(what: &str, f_number: f64) -> Result<(), WaveError> {
    if f_number.is_finite() {
        crate::limits::check_range(what, f_number, 0.0, crate::limits::MAX_F_NUMBER)?;
    }
    Ok(())
}

/// The ideal lens: rays leave a spherical exit pupil of radius f centred on the image point,
/// their direction cosines linear in the pupil coordinates (sin U' = ρ / 2N), all on one
/// wavefront. Its image of field θ lies at f tan θ; the pupil is the same at every field.
fn ideal(
    efl_mm: f64,
    f_number: f64,
    field_deg: f64,
    wavelength_nm: f64,
    samples: usize,
) -> Result<PupilTrace, WaveError> {
    positive("focal length (mm)", efl_mm)?;
    positive("f-number", f_number)?;
    if f_number <= 0.5 {
        return Err(WaveError::NotPositive {
            what: "f-number minus 0.5 (an aplanatic lens has NA = 1/2N < 1)",
            value: f_number - 0.5,
        });
    }
    check_f_number("the f-number", f_number)?;
    if !(field_deg.is_finite() && field_deg.abs() < 90.0) {
        return Err(RealRayError::InvalidField { field: field_deg }.into());
    }
    let aperture = 1.0 / (2.0 * f_number);
    let focus = [0.0, efl_mm * field_deg.to_radians().tan(), efl_mm];
    let ray_at = |px: f64, py: f64| {
        // A real image: the top of the pupil sends its ray down.
        let (l, m) = (-px * aperture, -py * aperture);
        let direction = [l, m, (1.0 - l * l - m * m).sqrt()];
        ExitRay {
            position: [
                focus[0] - efl_mm * direction[0],
                focus[1] - efl_mm * direction[1],
                focus[2] - efl_mm * direction[2],
            ],
            direction,
            optical_path: 0.0,
        }
    };
    let rays = (0..samples * samples)
        .map(|i| {
            let (ix, iy) = (i % samples, i / samples);
            inside_pupil(samples, ix, iy)
                .then(|| ray_at(pupil_coordinate(samples, ix), pupil_coordinate(samples, iy)))
        })
        .collect();
    let lag = 2.0 * aperture / ((samples - 1) as f64 * wavelength_nm * NM_TO_MM);
    Ok(PupilTrace {
        wavelength_nm,
        field_deg,
        samples,
        image_z: efl_mm,
        cutoff_per_mm: 1.0 / (wavelength_nm * NM_TO_MM * f_number),
        lag_frequency_per_mm: [lag, lag],
        mirrored: [true, true],
        rays,
        chief: ray_at(0.0, 0.0),
        exit_pupil: [focus[0], focus[1], 0.0],
        image_index: 1.0,
    })
}

impl WavefrontMap {
    /// Pupil coordinates (x, y) and OPD of every transmitted sample.
    pub fn transmitted(&self) -> impl Iterator<Item = (f64, f64, f64)> + '_ {
        transmitted(self.samples, &self.opd_waves)
    }

    /// RMS, peak-to-valley and Strehl ratio (see [`WavefrontStats`]).
    pub fn stats(&self) -> WavefrontStats {
        wavefront_stats(self.samples, &self.opd_waves)
    }
}

/// [`WavefrontStats`] of an OPD grid of `samples` points per side (row-major, None where no
/// ray passes).
pub(super) fn wavefront_stats(samples: usize, opd_waves: &[Option<f64>]) -> WavefrontStats {
    let n = samples;
    let pupil_samples = (0..n * n).filter(|i| inside_pupil(n, i % n, i / n)).count();
    let values: Vec<(f64, f64, f64)> = transmitted(n, opd_waves).collect();
    let count = values.len() as f64;
    let mean = values.iter().map(|v| v.2).sum::<f64>() / count;
    let rms_waves = (values.iter().map(|v| (v.2 - mean).powi(2)).sum::<f64>() / count).sqrt();
    let (low, high) = values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v.2), hi.max(v.2))
        });
    let [a, b, c] = plane_fit(&values);
    let (mut re, mut im) = (0.0, 0.0);
    for &(x, y, w) in &values {
        let phase = std::f64::consts::TAU * (w - a - b * x - c * y);
        re += phase.cos();
        im += phase.sin();
    }
    WavefrontStats {
        rms_waves,
        pv_waves: high - low,
        strehl: (re * re + im * im) / (count * count),
        pupil_samples,
        transmitted_samples: values.len(),
    }
}

/// Pupil coordinates (x, y) and OPD of every transmitted sample of a grid.
pub(super) fn transmitted(
    samples: usize,
    opd_waves: &[Option<f64>],
) -> impl Iterator<Item = (f64, f64, f64)> + '_ {
    opd_waves.iter().enumerate().filter_map(move |(i, w)| {
        w.map(|w| {
            (
                pupil_coordinate(samples, i % samples),
                pupil_coordinate(samples, i / samples),
                w,
            )
        })
    })
}

/// Least-squares plane w = a + b x + c y through (x, y, w).
fn plane_fit(values: &[(f64, f64, f64)]) -> [f64; 3] {
    let mut normal = nalgebra::Matrix3::<f64>::zeros();
    let mut rhs = nalgebra::Vector3::<f64>::zeros();
    for &(x, y, w) in values {
        let row = nalgebra::Vector3::new(1.0, x, y);
        normal += row * row.transpose();
        rhs += row * w;
    }
    // A pupil reduced to a line (or a point) has no unique plane: keep the piston alone.
    match normal.try_inverse() {
        Some(inverse) => {
            let s = inverse * rhs;
            [s[0], s[1], s[2]]
        }
        None => [rhs[0] / normal[(0, 0)].max(1.0), 0.0, 0.0],
    }
}
