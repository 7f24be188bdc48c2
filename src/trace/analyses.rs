//! Real-ray analyses: the numbers and curves a designer reads off exact traces.
//!
//! All of them share one description of a field point and of the pupil:
//! - a field value is the half-field angle in degrees (y-z plane) for an object at infinity,
//!   and the object height in mm for a finite object (the object point is (0, h, -d));
//! - pupil coordinates (px, py) are fractions of the paraxial entrance-pupil radius on the
//!   paraxial entrance-pupil plane, measured from the axis; the rays of a field point pass
//!   through those points (collimated beams at infinity, from the object point otherwise).
//!   With real ray aiming ([`RealRays::aimed_at_stop`]) they are fractions of the radius the
//!   axial beam fills on the stop surface instead, and each ray is the real ray that crosses
//!   the stop there;
//! - the real chief ray is aimed to cross the stop surface at its centre;
//! - the image plane is the paraxial image plane of the conjugate analysed, unless
//!   [`RealRays::with_image_plane`] moves it (a sensor position, a defocus).
//!
//! Geometric properties of the design (distortion, spherical aberration, field curves) are
//! traced with apertures ignored, as design programs do; what the sensor receives (fans,
//! spots, illumination) is traced with every clear aperture and the stop's shape applied.

use super::{
    AimError, Apertures, Outcome, Ray, RaySource, StopAim, Tracer, Travel, Vec3, aim_at_stop,
};
use crate::paraxial::Paraxial;
use crate::system::SystemAt;
use serde::Serialize;

/// Why a real-ray analysis could not be done.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RealRayError {
    #[error("field {field}: the real chief ray cannot be aimed at the stop centre: {source}")]
    Aim { field: f64, source: AimError },
    #[error("field {field}: the real chief ray does not reach the image ({outcome})")]
    ChiefRay { field: f64, outcome: Outcome },
    #[error("relative pupil height {rho}: the ray does not reach the image ({outcome})")]
    PupilRay { rho: f64, outcome: Outcome },
    #[error("relative pupil height {rho}: the ray leaves the lens without crossing the axis")]
    NoAxisCrossing { rho: f64 },
    #[error("field {field}: the rays near the chief ray leave the lens parallel: no focus")]
    NoFocus { field: f64 },
    #[error("field {field}: no ray of the field passes the lens")]
    NoLight { field: f64 },
    #[error(
        "field {field} is not a field value (degrees below 90 at infinity, a finite object \
         height in mm otherwise)"
    )]
    InvalidField { field: f64 },
    #[error(
        "real ray aiming needs the radius the beam fills on the stop: the axial rim ray \
         {outcome}, and the stop has no clear aperture"
    )]
    NoStopRadius { outcome: Outcome },
    #[error("{what} needs {needs}")]
    Unsupported {
        what: &'static str,
        needs: &'static str,
    },
}

/// Distortion of the real chief ray at one field.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct DistortionPoint {
    pub field: f64,
    /// Height of the real chief ray in the paraxial image plane (mm).
    pub real_height: f64,
    /// The ideal image height: f tan(theta) at infinity (f the object-side focal length),
    /// m h for a finite object (m the paraxial magnification), mm.
    pub paraxial_height: f64,
    /// 100 (real - paraxial) / paraxial.
    pub percent: f64,
    /// Against the equidistant (fisheye) reference f theta; None for finite objects.
    pub percent_f_theta: Option<f64>,
}

/// Longitudinal spherical aberration of one meridional ray.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LsaPoint {
    /// Relative pupil height.
    pub rho: f64,
    /// Axial crossing minus paraxial focus (mm); negative = short of the focus.
    pub lsa: f64,
    /// Height of the ray in the paraxial image plane (mm).
    pub transverse: f64,
}

/// One ray of a fan: its pupil coordinate and its error against the pupil-centre ray in the
/// image plane, None when it does not reach the image.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FanPoint {
    pub rho: f64,
    pub outcome: Outcome,
    /// (x, y) error in mm.
    pub error: Option<[f64; 2]>,
}

/// Transverse ray aberrations of one field point.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RayFan {
    pub field: f64,
    /// Rays through (0, rho): the y error is the tangential aberration.
    pub tangential: Vec<FanPoint>,
    /// Rays through (rho, 0): the x error is the sagittal aberration.
    pub sagittal: Vec<FanPoint>,
}

/// A spot diagram in the paraxial image plane.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Spot {
    pub field: f64,
    /// Image-plane (x, y) of every ray that passed, mm.
    pub points: Vec<[f64; 2]>,
    pub rays_traced: usize,
    pub centroid: [f64; 2],
    /// Root-mean-square distance from the centroid, mm.
    pub rms_radius: f64,
    /// Largest distance from the centroid, mm.
    pub geometric_radius: f64,
}

/// Sagittal and tangential focus of the beam around the real chief ray.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FieldFocus {
    pub field: f64,
    /// Axial position of the sagittal focus minus the paraxial image plane (mm).
    pub sagittal: f64,
    /// Axial position of the tangential focus minus the paraxial image plane (mm).
    pub tangential: f64,
}

/// Light reaching one image point, relative to the axis.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Illumination {
    pub field: f64,
    /// Image illuminance over its value on the axis (includes the cos^4-like falloff, pupil
    /// distortion, the image mapping and vignetting).
    pub relative: f64,
    /// Share of the beam the stop alone would pass that the other clear apertures block.
    pub vignetted_fraction: f64,
}

/// Relative pupil offset of the rays beside the chief ray that locate its foci.
const FOCUS_PROBE: f64 = 1e-5;
/// Subdivisions per side of the pupil cells on the edge of a beam.
const EDGE_SUBDIVISION: usize = 8;
/// Relative field step for the derivative of image height in relative illumination.
const MAPPING_STEP: f64 = 1e-4;

/// A lens at one wavelength and conjugate, ready for real-ray analyses.
#[derive(Clone, Debug, PartialEq)]
pub struct RealRays {
    system: SystemAt,
    tracer: Tracer,
    paraxial: Paraxial,
    start_z: f64,
    z_image: f64,
    aim: PupilAim,
}

/// Where a relative pupil coordinate points.
#[derive(Clone, Copy, Debug, PartialEq)]
enum PupilAim {
    /// The paraxial entrance pupil, by a straight line from the source.
    EntrancePupil,
    /// The stop surface, by a real ray; coordinates scale by `radius` (mm).
    Stop { radius: f64 },
}

/// The rays of one field point of a [`RealRays`] ([`RealRays::field_rays`]).
pub(crate) struct FieldRays<'a> {
    real: &'a RealRays,
    field: f64,
    source: RaySource,
    aim: FieldAim<'a>,
}

enum FieldAim<'a> {
    EntrancePupil,
    Stop { radius: f64, aim: StopAim<'a> },
}

impl FieldRays<'_> {
    /// [`RealRays::pupil_ray`] of this field.
    pub(crate) fn pupil_ray(&self, px: f64, py: f64) -> Result<Ray, RealRayError> {
        self.launch(px, py)?
            .map_err(|outcome| RealRayError::PupilRay {
                rho: px.hypot(py),
                outcome,
            })
    }

    /// The ray at the relative pupil coordinates (px, py) ([`RealRays::pupil_ray`]), with a
    /// coordinate that real aiming cannot reach told apart from an invalid one: the inner error
    /// is how the nearest try ended.
    pub(crate) fn launch(&self, px: f64, py: f64) -> Result<Result<Ray, Outcome>, RealRayError> {
        match &self.aim {
            FieldAim::EntrancePupil => self
                .real
                .entrance_pupil_ray_of(&self.source, self.field, px, py)
                .map(Ok),
            FieldAim::Stop { radius, aim } => {
                Ok(aim
                    .aim([px * radius, py * radius])
                    .map_err(|error| match error {
                        AimError::NoStartingRay(outcome) => outcome,
                        _ => Outcome::Missed {
                            surface: self.real.tracer.stop + 1,
                        },
                    }))
            }
        }
    }
}

impl RealRays {
    /// `paraxial` must have been computed from `system` (it fixes the object, the pupil size
    /// and the image plane).
    pub fn new(system: &SystemAt, paraxial: Paraxial) -> RealRays {
        let tracer = Tracer::new(system);
        RealRays {
            start_z: tracer.front_start_z(),
            z_image: paraxial.z_image,
            system: system.clone(),
            tracer,
            paraxial,
            aim: PupilAim::EntrancePupil,
        }
    }

    /// The same analyses with real ray aiming: the pupil coordinate (px, py) is the real ray
    /// that crosses the stop surface at (px, py) `stop_radius`, found by iteration from the
    /// field's chief ray ([`StopAim`]). A coordinate no real ray reaches (a ray totally reflected or missing a
    /// surface before the stop) is a ray that does not pass. Give every wavelength the reference
    /// wavelength's radius ([`RealRays::filled_stop_radius`]), as a design program fills the stop
    /// once for all of them.
    ///
    /// ```
    /// use lensbake::analysis::{ConditionOverrides, DesignConditions};
    /// use lensbake::paraxial::Paraxial;
    /// use lensbake::prescription::RayAiming;
    /// use lensbake::trace::analyses::RealRays;
    /// use lensbake::{LoadOptions, load_lens};
    ///
    /// let lens = load_lens("dgauss-50mm", &LoadOptions::default())?;
    /// let overrides = ConditionOverrides {
    ///     ray_aiming: Some(RayAiming::Real),
    ///     ..ConditionOverrides::default()
    /// };
    /// let conditions = DesignConditions::resolve(&lens.system, &overrides)?;
    /// let at = lens.system.at(conditions.reference_nm);
    /// let real = RealRays::new(&at, Paraxial::new(&at, &conditions.paraxial_options())?);
    /// // Used wide open, the lens fills its stop to the rim.
    /// let radius = conditions.aiming_stop_radius(&real)?.expect("real aiming asked for");
    /// let fan = real.aimed_at_stop(radius).ray_fan(15.0, 21)?;
    /// assert_eq!(fan.tangential.len(), 21);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn aimed_at_stop(mut self, stop_radius: f64) -> RealRays {
        self.aim = PupilAim::Stop {
            radius: stop_radius,
        };
        self
    }

    /// The radius the axial beam fills on the stop surface: the stop's clear semi-aperture when
    /// the paraxial entrance pupil is the stop's own image (a lens used wide open), else the
    /// height at which the real axial ray through the rim of the paraxial entrance pupil crosses
    /// the stop, so that real aiming keeps the axial beam the aperture states (its rim ray is the
    /// same). Where that ray cannot reach the stop (an aperture wider than the lens passes), the
    /// stop is filled as well.
    pub fn filled_stop_radius(&self) -> Result<f64, RealRayError> {
        let stop = self.tracer.stop;
        let semi_aperture = self.tracer.surfaces[stop].semi_aperture;
        let rim_outcome = if self.stop_sets_beam() {
            Outcome::Ok
        } else {
            let rim = self.entrance_pupil_ray(0.0, 0.0, 1.0)?;
            let at_stop = self
                .tracer
                .trace_to(rim, Travel::Forward, stop + 1, Apertures::Ignored);
            if at_stop.outcome.is_ok() {
                let p = at_stop.ray.position();
                return Ok(p[0].hypot(p[1]));
            }
            at_stop.outcome
        };
        if semi_aperture.is_finite() && semi_aperture > 0.0 {
            Ok(semi_aperture)
        } else {
            Err(RealRayError::NoStopRadius {
                outcome: rim_outcome,
            })
        }
    }

    /// Whether the paraxial entrance pupil is the stop's clear aperture imaged into object
    /// space: the beam of a lens used wide open, whatever set its diameter (the design
    /// conditions' rule, or no pupil given to the wave optics).
    fn stop_sets_beam(&self) -> bool {
        let semi_aperture = self.tracer.surfaces[self.tracer.stop].semi_aperture;
        self.tracer.stop_image.is_some_and(|image| {
            let own = 2.0 * (semi_aperture / image.scale.abs());
            (self.paraxial.entrance_pupil.diameter - own).abs() <= 1e-12 * own
        })
    }

    /// The same analyses in the plane z = `z_image` (lens frame) instead of the paraxial image
    /// plane: a sensor position or a defocus. Distortion keeps its ideal reference heights.
    pub fn with_image_plane(mut self, z_image: f64) -> RealRays {
        self.z_image = z_image;
        self
    }

    pub fn tracer(&self) -> &Tracer {
        &self.tracer
    }

    pub fn paraxial(&self) -> &Paraxial {
        &self.paraxial
    }

    fn pupil_radius(&self) -> f64 {
        0.5 * self.paraxial.entrance_pupil.diameter
    }

    fn z_image(&self) -> f64 {
        self.z_image
    }

    fn source(&self, field: f64) -> Result<RaySource, RealRayError> {
        let distance = self.paraxial.object_distance;
        if !(field.is_finite() && (distance.is_some() || field.abs() < 90.0)) {
            return Err(RealRayError::InvalidField { field });
        }
        Ok(RaySource::of_field(distance, field, self.start_z))
    }

    /// The ray of `field` at the relative pupil coordinates (px, py): through that point of the
    /// paraxial entrance pupil, or with real ray aiming, through that point of the stop; an
    /// error where no real ray reaches it.
    pub fn pupil_ray(&self, field: f64, px: f64, py: f64) -> Result<Ray, RealRayError> {
        self.field_rays(field)?.pupil_ray(px, py)
    }

    /// The rays of `field`, to be launched pupil point by pupil point: with real aiming, the
    /// field's chief ray is aimed once here for all of them.
    pub(crate) fn field_rays(&self, field: f64) -> Result<FieldRays<'_>, RealRayError> {
        let source = self.source(field)?;
        let aim = match self.aim {
            PupilAim::EntrancePupil => FieldAim::EntrancePupil,
            PupilAim::Stop { radius } => FieldAim::Stop {
                radius,
                aim: StopAim::new(&self.tracer, source),
            },
        };
        Ok(FieldRays {
            real: self,
            field,
            source,
            aim,
        })
    }

    /// The ray of `field` through the point (px, py) of the paraxial entrance pupil (relative
    /// coordinates), whatever the aiming.
    fn entrance_pupil_ray(&self, field: f64, px: f64, py: f64) -> Result<Ray, RealRayError> {
        self.entrance_pupil_ray_of(&self.source(field)?, field, px, py)
    }

    fn entrance_pupil_ray_of(
        &self,
        source: &RaySource,
        field: f64,
        px: f64,
        py: f64,
    ) -> Result<Ray, RealRayError> {
        let r = self.pupil_radius();
        // Paraxial::new refuses an object in the pupil plane, so only absurd pupil
        // coordinates can fail here.
        source
            .ray(source.unknowns_through([px * r, py * r, self.paraxial.entrance_pupil.z]))
            .ok_or(RealRayError::InvalidField { field })
    }

    /// The real chief ray of `field`, aimed at the stop centre (apertures ignored).
    pub fn chief_ray(&self, field: f64) -> Result<Ray, RealRayError> {
        aim_at_stop(&self.tracer, &self.source(field)?, [0.0, 0.0])
            .map_err(|source| RealRayError::Aim { field, source })
    }

    /// Where `ray` meets the paraxial image plane, or how it ended.
    fn image_point(&self, ray: Ray, apertures: Apertures) -> Result<Vec3, Outcome> {
        self.image_point_through(&self.tracer, ray, apertures)
    }

    fn image_point_through(
        &self,
        tracer: &Tracer,
        ray: Ray,
        apertures: Apertures,
    ) -> Result<Vec3, Outcome> {
        let traced = tracer.trace_with(ray, Travel::Forward, apertures);
        if !traced.outcome.is_ok() {
            return Err(traced.outcome);
        }
        // A ray leaving parallel to the image plane never reaches it: report it as missing
        // the image (surface N + 1).
        traced
            .ray
            .point_at_z(self.z_image())
            .ok_or(Outcome::Missed {
                surface: self.tracer.surface_count() + 1,
            })
    }

    /// The ideal image height of `field`: f tan(theta) at infinity, m h for a finite object
    /// (the paraxial chief ray's height in the paraxial image plane).
    fn ideal_height(&self, field: f64) -> Result<f64, RealRayError> {
        match (self.paraxial.object_distance, self.paraxial.magnification) {
            (None, _) => Ok(self.paraxial.first_order.fl_object * field.to_radians().tan()),
            (Some(_), Some(m)) => Ok(m * field),
            (Some(_), None) => Err(RealRayError::Unsupported {
                what: "distortion",
                needs: "the paraxial magnification of the finite object",
            }),
        }
    }

    /// Image height of the real chief ray of `field` (apertures ignored).
    fn chief_height(&self, field: f64) -> Result<f64, RealRayError> {
        let chief = self.chief_ray(field)?;
        self.image_point(chief, Apertures::Ignored)
            .map(|p| p[1])
            .map_err(|outcome| RealRayError::ChiefRay { field, outcome })
    }

    /// Distortion at each field: the real chief ray's height in the image plane against the
    /// ideal height (f tan theta at infinity, m h for a finite object); at infinity also
    /// against the equidistant f theta.
    pub fn distortion(&self, fields: &[f64]) -> Result<Vec<DistortionPoint>, RealRayError> {
        let f = self.paraxial.first_order.fl_object;
        fields
            .iter()
            .map(|&field| {
                let real_height = self.chief_height(field)?;
                let paraxial_height = self.ideal_height(field)?;
                if field == 0.0 {
                    // On axis both heights are zero and distortion, the limit of their relative
                    // difference, is zero by definition (the ratio itself would be 0/0).
                    return Ok(DistortionPoint {
                        field,
                        real_height,
                        paraxial_height,
                        percent: 0.0,
                        percent_f_theta: self.paraxial.object_distance.is_none().then_some(0.0),
                    });
                }
                let percent_f_theta = self.paraxial.object_distance.is_none().then(|| {
                    let theta = field.to_radians();
                    let reference = (f * theta).copysign(paraxial_height);
                    100.0 * (real_height - reference) / reference
                });
                Ok(DistortionPoint {
                    field,
                    real_height,
                    paraxial_height,
                    percent: 100.0 * (real_height - paraxial_height) / paraxial_height,
                    percent_f_theta,
                })
            })
            .collect()
    }

    /// Longitudinal spherical aberration of the meridional ray through (0, rho) of the
    /// entrance pupil (axis-parallel at infinity, from the axial object point otherwise).
    pub fn lsa(&self, rhos: &[f64]) -> Result<Vec<LsaPoint>, RealRayError> {
        let axial = self.field_rays(0.0)?;
        rhos.iter()
            .map(|&rho| {
                let ray = axial.pupil_ray(0.0, rho)?;
                let traced = self
                    .tracer
                    .trace_with(ray, Travel::Forward, Apertures::Ignored);
                if !traced.outcome.is_ok() {
                    return Err(RealRayError::PupilRay {
                        rho,
                        outcome: traced.outcome,
                    });
                }
                let (p, d) = (traced.ray.position(), traced.ray.direction());
                let z_axis = p[2] - p[1] * d[2] / d[1];
                if !z_axis.is_finite() {
                    return Err(RealRayError::NoAxisCrossing { rho });
                }
                let transverse = p[1] + (self.z_image() - p[2]) * d[1] / d[2];
                Ok(LsaPoint {
                    rho,
                    lsa: z_axis - self.z_image(),
                    transverse,
                })
            })
            .collect()
    }

    /// Tangential and sagittal ray fans of `field`, `samples` rays each from rho = -1 to 1,
    /// with apertures applied. Errors are measured from the ray through the pupil centre.
    pub fn ray_fan(&self, field: f64, samples: usize) -> Result<RayFan, RealRayError> {
        let rays = self.field_rays(field)?;
        let centre = self
            // The ray through the pupil centre is the fan's axis, not a ray that must reach
            // the image: central obscurations do not stop it.
            .image_point_through(
                &self.tracer.unobscured(),
                rays.pupil_ray(0.0, 0.0)?,
                Apertures::Checked,
            )
            .map_err(|outcome| RealRayError::PupilRay { rho: 0.0, outcome })?;
        let rhos: Vec<f64> = (0..samples)
            .map(|i| {
                if samples == 1 {
                    0.0
                } else {
                    -1.0 + 2.0 * i as f64 / (samples - 1) as f64
                }
            })
            .collect();
        let fan = |pupil: &dyn Fn(f64) -> (f64, f64)| -> Result<Vec<FanPoint>, RealRayError> {
            rhos.iter()
                .map(|&rho| {
                    let (px, py) = pupil(rho);
                    let reached = rays
                        .launch(px, py)?
                        .and_then(|ray| self.image_point(ray, Apertures::Checked));
                    Ok(match reached {
                        Ok(p) => FanPoint {
                            rho,
                            outcome: Outcome::Ok,
                            error: Some([p[0] - centre[0], p[1] - centre[1]]),
                        },
                        Err(outcome) => FanPoint {
                            rho,
                            outcome,
                            error: None,
                        },
                    })
                })
                .collect()
        };
        Ok(RayFan {
            field,
            tangential: fan(&|rho| (0.0, rho))?,
            sagittal: fan(&|rho| (rho, 0.0))?,
        })
    }

    /// Spot diagram of `field`: a hexapolar pattern over the entrance pupil (`rings` rings,
    /// 6 k rays on ring k, so the rays sample the pupil area evenly), apertures applied.
    pub fn spot(&self, field: f64, rings: usize) -> Result<Spot, RealRayError> {
        let mut pupil = vec![(0.0, 0.0)];
        for k in 1..=rings {
            let r = k as f64 / rings as f64;
            for j in 0..6 * k {
                let a = std::f64::consts::TAU * j as f64 / (6 * k) as f64;
                pupil.push((r * a.cos(), r * a.sin()));
            }
        }
        let rays = self.field_rays(field)?;
        let mut points = Vec::with_capacity(pupil.len());
        for &(px, py) in &pupil {
            let reached = rays
                .launch(px, py)?
                .and_then(|ray| self.image_point(ray, Apertures::Checked));
            if let Ok(p) = reached {
                points.push([p[0], p[1]]);
            }
        }
        let (centroid, rms_radius, geometric_radius) =
            spot_statistics(&points).ok_or(RealRayError::NoLight { field })?;
        Ok(Spot {
            field,
            points,
            rays_traced: pupil.len(),
            centroid,
            rms_radius,
            geometric_radius,
        })
    }

    /// Sagittal and tangential foci around the real chief ray of each field (astigmatic field
    /// curves), from pairs of rays a small pupil step to either side of the chief ray:
    /// the tangential pair meets in the meridional plane, the sagittal pair on it.
    pub fn field_curves(&self, fields: &[f64]) -> Result<Vec<FieldFocus>, RealRayError> {
        fields
            .iter()
            .map(|&field| {
                let chief = self.chief_ray(field)?;
                let step = FOCUS_PROBE * self.pupil_radius();
                let source = self.source(field)?;
                let leaving = |offset: [f64; 2]| -> Result<Ray, RealRayError> {
                    let ray = self.shifted(chief, &source, offset);
                    let traced = self
                        .tracer
                        .trace_with(ray, Travel::Forward, Apertures::Ignored);
                    if traced.outcome.is_ok() {
                        Ok(traced.ray)
                    } else {
                        Err(RealRayError::ChiefRay {
                            field,
                            outcome: traced.outcome,
                        })
                    }
                };
                let (up, down) = (leaving([0.0, step])?, leaving([0.0, -step])?);
                let side = leaving([step, 0.0])?;
                let tangential = meeting_z(up, down).ok_or(RealRayError::NoFocus { field })?;
                let (p, d) = (side.position(), side.direction());
                let sagittal = p[2] - p[0] * d[2] / d[0];
                if !sagittal.is_finite() {
                    return Err(RealRayError::NoFocus { field });
                }
                Ok(FieldFocus {
                    field,
                    sagittal: sagittal - self.z_image(),
                    tangential: tangential - self.z_image(),
                })
            })
            .collect()
    }

    /// `chief` moved sideways by `offset` (mm) in the entrance pupil: the ray of `source` through
    /// the point where the chief ray crosses the entrance-pupil plane, shifted by `offset`.
    fn shifted(&self, chief: Ray, source: &RaySource, offset: [f64; 2]) -> Ray {
        let (p, d) = (chief.position(), chief.direction());
        let pupil_z = self.paraxial.entrance_pupil.z;
        let reach = (pupil_z - p[2]) / d[2];
        source
            .ray(source.unknowns_through([
                p[0] + d[0] * reach + offset[0],
                p[1] + d[1] * reach + offset[1],
                pupil_z,
            ]))
            .expect("a small shift of a valid ray is a valid ray")
    }

    /// Relative illumination and vignetted fraction at each field (at infinity: field angles).
    ///
    /// The beam of each field is sampled on a `grid` x `grid` lattice of the entrance-pupil
    /// plane centred on the real chief ray and widened until no passing ray touches its rim.
    /// Illuminance in the image is the beam's projected solid angle at the object over the
    /// image area per unit object area: at infinity E ~ A cos(theta) sin(theta) / (y y'), with
    /// A the passing area on the pupil plane and y(theta) the real chief-ray image height; for
    /// a finite object the projected solid angle sums cell area cos^4 / D^2 and the mapping is
    /// y y' / h. Both are divided by their limit on the axis.
    pub fn illumination(
        &self,
        fields: &[f64],
        grid: usize,
    ) -> Result<Vec<Illumination>, RealRayError> {
        let axis = self.beam(0.0, grid)?;
        if axis.passed == 0.0 {
            return Err(RealRayError::NoLight { field: 0.0 });
        }
        let on_axis_mapping = match (self.paraxial.object_distance, self.paraxial.magnification) {
            (None, _) => self.paraxial.first_order.fl_object.powi(2),
            (Some(_), Some(m)) => m * m,
            (Some(_), None) => {
                return Err(RealRayError::Unsupported {
                    what: "relative illumination",
                    needs: "the paraxial magnification of the finite object",
                });
            }
        };
        fields
            .iter()
            .map(|&field| {
                let beam = self.beam(field, grid)?;
                let vignetted_fraction = if beam.stop_only > 0.0 {
                    1.0 - beam.passed / beam.stop_only
                } else {
                    1.0
                };
                let relative = if field == 0.0 {
                    1.0
                } else {
                    let h = MAPPING_STEP * field.abs().max(1e-3);
                    let y = self.chief_height(field)?;
                    let slope =
                        (self.chief_height(field + h)? - self.chief_height(field - h)?) / (2.0 * h);
                    let mapping = match self.paraxial.object_distance {
                        // dy/dtheta with theta in radians.
                        None => y * slope.to_degrees() / field.to_radians().sin(),
                        Some(_) => y * slope / field,
                    };
                    (beam.passed / axis.passed) * on_axis_mapping / mapping
                };
                Ok(Illumination {
                    field,
                    relative,
                    vignetted_fraction,
                })
            })
            .collect()
    }

    /// The beam of `field` through the lens: its projected solid angle (or projected area at
    /// infinity) with every aperture, and with the stop alone. Cells on the edge of either
    /// region are subdivided [`EDGE_SUBDIVISION`] times each way, so the estimate converges
    /// much faster than cell counting (error ~1e-4 instead of ~1e-2 at grid 64).
    fn beam(&self, field: f64, grid: usize) -> Result<Beam, RealRayError> {
        let chief = self.chief_ray(field)?;
        let z_pupil = self.paraxial.entrance_pupil.z;
        let centre = chief
            .point_at_z(z_pupil)
            .ok_or(RealRayError::NoLight { field })?;
        let stop = self.tracer.stop_surface();
        let r = self.pupil_radius();
        let source = self.source(field)?;
        // Whether a pupil point's ray passes every aperture and the stop alone, and its weight
        // per unit pupil area.
        let sample = |x: f64, y: f64| -> Result<(bool, bool, f64), RealRayError> {
            let ray = self.entrance_pupil_ray_of(&source, field, x / r, y / r)?;
            let at_stop = self
                .tracer
                .trace_to(ray, Travel::Forward, stop, Apertures::Ignored);
            let q = at_stop.ray.position();
            let by_stop = at_stop.outcome.is_ok() && self.tracer.stop_admits(q[0], q[1]);
            let by_all = by_stop && self.tracer.trace(ray, Travel::Forward).outcome.is_ok();
            Ok((by_all, by_stop, self.projected_weight(ray, 1.0)))
        };
        let grid = grid.max(4);
        let mut half_width = 1.25 * r;
        for _ in 0..6 {
            let cell = 2.0 * half_width / grid as f64;
            let at = |i: usize, j: usize| {
                [
                    centre[0] - half_width + (i as f64 + 0.5) * cell,
                    centre[1] - half_width + (j as f64 + 0.5) * cell,
                ]
            };
            let mut flags = Vec::with_capacity(grid * grid);
            for i in 0..grid {
                for j in 0..grid {
                    let [x, y] = at(i, j);
                    flags.push(sample(x, y)?);
                }
            }
            let flag = |i: usize, j: usize| flags[i * grid + j];
            let on_rim = (0..grid).any(|k| {
                flag(0, k).1 || flag(grid - 1, k).1 || flag(k, 0).1 || flag(k, grid - 1).1
            });
            if on_rim {
                half_width *= 2.0;
                continue;
            }
            let mut beam = Beam {
                passed: 0.0,
                stop_only: 0.0,
            };
            for i in 0..grid {
                for j in 0..grid {
                    let (all, by_stop, weight) = flag(i, j);
                    let neighbours = [
                        (i > 0).then(|| flag(i - 1, j)),
                        (i + 1 < grid).then(|| flag(i + 1, j)),
                        (j > 0).then(|| flag(i, j - 1)),
                        (j + 1 < grid).then(|| flag(i, j + 1)),
                    ];
                    let edge_all = neighbours.iter().flatten().any(|n| n.0 != all);
                    let edge_stop = neighbours.iter().flatten().any(|n| n.1 != by_stop);
                    if !edge_all && !edge_stop {
                        beam.passed += f64::from(u8::from(all)) * weight * cell * cell;
                        beam.stop_only += f64::from(u8::from(by_stop)) * weight * cell * cell;
                        continue;
                    }
                    let [x, y] = at(i, j);
                    let sub = cell / EDGE_SUBDIVISION as f64;
                    let (mut sub_all, mut sub_stop) = (0.0, 0.0);
                    for a in 0..EDGE_SUBDIVISION {
                        for b in 0..EDGE_SUBDIVISION {
                            let xs = x - 0.5 * cell + (a as f64 + 0.5) * sub;
                            let ys = y - 0.5 * cell + (b as f64 + 0.5) * sub;
                            let (all, by_stop, weight) = sample(xs, ys)?;
                            sub_all += f64::from(u8::from(all)) * weight * sub * sub;
                            sub_stop += f64::from(u8::from(by_stop)) * weight * sub * sub;
                        }
                    }
                    beam.passed += if edge_all {
                        sub_all
                    } else {
                        f64::from(u8::from(all)) * weight * cell * cell
                    };
                    beam.stop_only += if edge_stop {
                        sub_stop
                    } else {
                        f64::from(u8::from(by_stop)) * weight * cell * cell
                    };
                }
            }
            return Ok(beam);
        }
        Err(RealRayError::Unsupported {
            what: "relative illumination",
            needs: "a beam no wider than 80 entrance-pupil radii",
        })
    }

    /// A pupil cell's contribution: projected area at infinity (the cell seen along the beam),
    /// projected solid angle from a finite object point (area cos^4 / D^2).
    fn projected_weight(&self, ray: Ray, area: f64) -> f64 {
        let cos = ray.direction()[2];
        match self.paraxial.object_distance {
            None => area * cos,
            Some(distance) => {
                let depth = self.paraxial.entrance_pupil.z + distance;
                area * cos.powi(4) / (depth * depth)
            }
        }
    }
}

/// What passes of one field's beam (projected area or solid angle).
struct Beam {
    passed: f64,
    stop_only: f64,
}

/// Fractions of the field at which `lensbake analyze` reports distortion.
pub const REPORT_FIELD_FRACTIONS: [f64; 4] = [0.25, 0.5, 0.75, 1.0];
/// Relative pupil heights at which `lensbake analyze` reports longitudinal spherical aberration.
/// 0.7071 is the zone as design programs print and tabulate it (CODE V's listings), so it is
/// written as they write it, not as 1/sqrt(2).
#[allow(clippy::approx_constant)]
pub const REPORT_PUPIL_HEIGHTS: [f64; 5] = [0.25, 0.5, 0.7071, 0.85, 1.0];

/// The real-ray block of `lensbake analyze`: distortion as [field_deg, percent] and LSA as
/// [rho, mm]. A point the real rays cannot reach is left out and explained in `notes`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RealReport {
    pub distortion_percent: Vec<[f64; 2]>,
    pub lsa: Vec<[f64; 2]>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
}

impl RealReport {
    /// Distortion at [`REPORT_FIELD_FRACTIONS`] of the analysed field (of its angle at
    /// infinity, of its object height for a finite object, reported as the paraxial chief
    /// ray's angle) and LSA at [`REPORT_PUPIL_HEIGHTS`], all in the paraxial image plane.
    pub fn new(real: &RealRays) -> RealReport {
        let paraxial = real.paraxial();
        let mut report = RealReport::default();
        for fraction in REPORT_FIELD_FRACTIONS {
            let (field, field_deg) = match paraxial.object_height {
                None => (
                    fraction * paraxial.field_angle_deg,
                    fraction * paraxial.field_angle_deg,
                ),
                Some(height) => {
                    let tan = fraction * paraxial.field_angle_deg.to_radians().tan();
                    (fraction * height, tan.atan().to_degrees())
                }
            };
            match real.distortion(&[field]) {
                Ok(points) => report
                    .distortion_percent
                    .push([field_deg, points[0].percent]),
                Err(error) => report.notes.push(format!("distortion: {error}")),
            }
        }
        for rho in REPORT_PUPIL_HEIGHTS {
            match real.lsa(&[rho]) {
                Ok(points) => report.lsa.push([rho, points[0].lsa]),
                Err(error) => report.notes.push(format!("lsa: {error}")),
            }
        }
        report
    }
}

/// Centroid, RMS and largest distance from the centroid; None for no points.
pub fn spot_statistics(points: &[[f64; 2]]) -> Option<([f64; 2], f64, f64)> {
    if points.is_empty() {
        return None;
    }
    let n = points.len() as f64;
    let centroid = [
        points.iter().map(|p| p[0]).sum::<f64>() / n,
        points.iter().map(|p| p[1]).sum::<f64>() / n,
    ];
    let distances_sq = points
        .iter()
        .map(|p| (p[0] - centroid[0]).powi(2) + (p[1] - centroid[1]).powi(2));
    let (sum, max) = distances_sq.fold((0.0, 0.0f64), |(s, m), d| (s + d, m.max(d)));
    Some((centroid, (sum / n).sqrt(), max.sqrt()))
}

/// Axial position where two rays of the meridional plane cross; None when they are parallel.
fn meeting_z(a: Ray, b: Ray) -> Option<f64> {
    let (pa, da) = (a.position(), a.direction());
    let (pb, db) = (b.position(), b.direction());
    // y_a(z) = pa.y + (z - pa.z) ta and likewise for b, with t = dy/dz.
    let (ta, tb) = (da[1] / da[2], db[1] / db[2]);
    let z = (pb[1] - pa[1] + pa[2] * ta - pb[2] * tb) / (ta - tb);
    z.is_finite().then_some(z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spot_statistics_of_a_square() {
        let points = [[1.0, 1.0], [3.0, 1.0], [1.0, 3.0], [3.0, 3.0]];
        let (centroid, rms, geometric) = spot_statistics(&points).unwrap();
        assert_eq!(centroid, [2.0, 2.0]);
        assert!((rms - 2f64.sqrt()).abs() < 1e-15);
        assert!((geometric - 2f64.sqrt()).abs() < 1e-15);
        assert!(spot_statistics(&[]).is_none());
    }

    #[test]
    fn meeting_point_of_two_lines() {
        let a = Ray::new([0.0, 1.0, 0.0], [0.0, -1.0, 1.0]).unwrap();
        let b = Ray::new([0.0, -2.0, 0.0], [0.0, 1.0, 1.0]).unwrap();
        assert!((meeting_z(a, b).unwrap() - 1.5).abs() < 1e-15);
        assert!(meeting_z(a, a).is_none());
    }
}
