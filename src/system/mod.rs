//! The validated lens system and its per-wavelength view.
//!
//! `LensSystem` owns a validated prescription with every medium resolved to a dispersion
//! formula. `SystemAt` freezes it at one wavelength into the flat numbers that paraxial,
//! third-order and real-ray code all read, so those analyses see the same lens by construction.

use crate::glass::Dispersion;
use crate::prescription::{
    Location, Medium, Prescription, PrescriptionError, Shape, SourceMap, StatedCondition,
    StopShape, validate,
};
use std::collections::BTreeMap;

pub use crate::prescription::DEFAULT_WAVELENGTH_NM;

/// A prescription that passed validation, with its media resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct LensSystem {
    pub prescription: Prescription,
    pub object_dispersion: Dispersion,
    /// Dispersion of the medium after each surface.
    pub dispersions: Vec<Dispersion>,
    /// 0-based index of the stop surface.
    pub stop: usize,
    /// Where the file states each of its conditions (file, line, keyword), so an analysis that
    /// finds one unusable names the line to edit.
    pub condition_locations: BTreeMap<StatedCondition, Location>,
}

impl LensSystem {
    /// Validates and resolves `prescription`; `map` locates surfaces in their source file.
    pub fn new(
        prescription: Prescription,
        map: &SourceMap,
    ) -> Result<LensSystem, PrescriptionError> {
        validate(&prescription, map)?;
        let object_dispersion = Dispersion::of(&prescription.object_medium).map_err(|problem| {
            PrescriptionError::new(
                Location {
                    file: map.file.clone(),
                    field: Some("object_medium".into()),
                    ..Location::default()
                },
                problem,
            )
        })?;
        // A mirror reflects back into the medium it was met in, so it takes that medium's
        // dispersion; the sign of travel lives in `SystemAt`, not here.
        let mut dispersions: Vec<Dispersion> = Vec::with_capacity(prescription.surfaces.len());
        for (i, s) in prescription.surfaces.iter().enumerate() {
            let dispersion = match s.medium {
                Medium::Mirror => dispersions.last().unwrap_or(&object_dispersion).clone(),
                _ => Dispersion::of(&s.medium)
                    .map_err(|problem| PrescriptionError::new(map.surface(i, "medium"), problem))?,
            };
            dispersions.push(dispersion);
        }
        let stop = prescription
            .stop_index()
            .expect("validate guarantees exactly one stop");
        let condition_locations = StatedCondition::ALL
            .into_iter()
            .map(|condition| (condition, map.condition(condition)))
            .collect();
        Ok(LensSystem {
            prescription,
            object_dispersion,
            dispersions,
            stop,
            condition_locations,
        })
    }

    /// Validates a prescription that has no source file (built in code or from a bundled lens).
    pub fn from_prescription(prescription: Prescription) -> Result<LensSystem, PrescriptionError> {
        LensSystem::new(prescription, &SourceMap::default())
    }

    /// The design wavelength, or the d line when the source states none.
    pub fn design_wavelength_nm(&self) -> f64 {
        self.prescription
            .provenance
            .design_wavelength_nm
            .unwrap_or(DEFAULT_WAVELENGTH_NM)
    }

    /// Whether any medium's index changes with wavelength.
    pub fn disperses(&self) -> bool {
        self.object_dispersion.disperses() || self.dispersions.iter().any(Dispersion::disperses)
    }

    /// The lens frozen at one wavelength, refused where a medium's dispersion formula gives no
    /// index of a transparent medium there ([`Dispersion::checked_index`]); the error names the
    /// surface whose medium it is (none for the object medium). [`LensSystem::at`] skips the
    /// check: a tracer built from such a view stops its rays with TIR at the first affected
    /// surface, and the paraxial code sees NaN.
    pub fn at_checked(&self, wavelength_nm: f64) -> Result<SystemAt, PrescriptionError> {
        // First: NaN or 1e30 nm is wrong for every medium, not a fault of the first one checked;
        // this also bounds constant indices, which accept any wavelength.
        crate::limits::check_wavelength(wavelength_nm)
            .map_err(|e| PrescriptionError::new(Location::default(), e.into()))?;
        self.object_dispersion
            .checked_index(wavelength_nm)
            .map_err(|problem| {
                PrescriptionError::new(
                    Location {
                        field: Some("object_medium".into()),
                        ..Location::default()
                    },
                    problem,
                )
            })?;
        for (i, dispersion) in self.dispersions.iter().enumerate() {
            dispersion.checked_index(wavelength_nm).map_err(|problem| {
                PrescriptionError::new(SourceMap::default().surface(i, "medium"), problem)
            })?;
        }
        Ok(self.at(wavelength_nm))
    }

    /// The lens frozen at one wavelength.
    pub fn at(&self, wavelength_nm: f64) -> SystemAt {
        let mut z = 0.0;
        let surfaces = self
            .prescription
            .surfaces
            .iter()
            .zip(&self.dispersions)
            .zip(self.prescription.travel_after())
            .map(|((s, d), travel)| {
                let vertex_z = z;
                z += s.thickness;
                SurfaceAt {
                    vertex_z,
                    thickness: s.thickness,
                    index_after: travel * d.index(wavelength_nm),
                    semi_aperture: s.semi_aperture,
                    geometric_semi_aperture: s.semi_aperture,
                    stop: s.stop.clone(),
                    shape: s.shape.clone(),
                    mirror: s.medium == Medium::Mirror,
                    obscuration: s.obscuration,
                }
            })
            .collect();
        SystemAt {
            wavelength_nm,
            object_index: self.object_dispersion.index(wavelength_nm),
            surfaces,
            stop: self.stop,
        }
    }

    /// Whether light leaves the last surface travelling +z, towards a film behind the lens: true
    /// for refracting lenses and for an even number of mirrors (a reflex lens).
    pub fn images_behind(&self) -> bool {
        self.prescription
            .travel_after()
            .last()
            .is_none_or(|&sense| sense > 0.0)
    }
}

/// One surface at one wavelength, in the lens frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceAt {
    pub shape: Shape,
    /// z of the vertex in the lens frame (surface 1 at 0).
    pub vertex_z: f64,
    /// Distance to the next vertex (for the last surface: to the film as the source gives it).
    pub thickness: f64,
    /// Refractive index after the surface, signed: negative while light travels -z (after an
    /// odd number of mirrors). With this convention (Welford's, and CODE V's) every paraxial
    /// and third-order formula holds for mirrors unchanged, a mirror being a surface with
    /// n' = -n; code that needs the physical index takes the absolute value.
    pub index_after: f64,
    /// Radius beyond which rays are blocked: the clear semi-aperture, or for the stop the radius
    /// it is closed to ([`SystemAt::stopped_down`]).
    pub semi_aperture: f64,
    /// Radius out to which the surface's shape is defined (the prescription's clear
    /// semi-aperture). Stopping down never changes it: the glass is still there, so a ray traced
    /// with apertures ignored meets the same surface whatever the f-number.
    pub geometric_semi_aperture: f64,
    pub stop: Option<StopShape>,
    /// Whether the surface reflects.
    pub mirror: bool,
    /// Radius inside which the surface blocks rays (mm).
    pub obscuration: Option<f64>,
}

impl SurfaceAt {
    pub fn curvature(&self) -> f64 {
        self.shape.curvature()
    }

    pub fn is_stop(&self) -> bool {
        self.stop.is_some()
    }
}

/// The lens at one wavelength: the one description every analysis iterates over.
#[derive(Clone, Debug, PartialEq)]
pub struct SystemAt {
    pub wavelength_nm: f64,
    pub object_index: f64,
    pub surfaces: Vec<SurfaceAt>,
    /// 0-based index of the stop surface.
    pub stop: usize,
}

impl SystemAt {
    /// Signed index of the medium before surface `i` (0-based); see [`SurfaceAt::index_after`].
    pub fn index_before(&self, i: usize) -> f64 {
        if i == 0 {
            self.object_index
        } else {
            self.surfaces[i - 1].index_after
        }
    }

    /// Signed index of image space (after the last surface): negative when the image lies
    /// towards -z.
    pub fn image_index(&self) -> f64 {
        self.surfaces
            .last()
            .map_or(self.object_index, |s| s.index_after)
    }

    /// z of the last vertex.
    pub fn last_vertex_z(&self) -> f64 {
        self.surfaces.last().map_or(0.0, |s| s.vertex_z)
    }

    /// The lens with its stop closed (or opened) to `stop_semi_aperture`: only the limiting radius
    /// changes, never the stop surface's geometry.
    pub fn stopped_down(&self, stop_semi_aperture: f64) -> SystemAt {
        let mut stopped = self.clone();
        stopped.surfaces[self.stop].semi_aperture = stop_semi_aperture;
        stopped
    }

    /// Each surface with the (signed) indices on both sides: the path every analysis walks.
    pub fn path(&self) -> impl Iterator<Item = (usize, &SurfaceAt, f64, f64)> + '_ {
        self.surfaces
            .iter()
            .enumerate()
            .map(|(i, s)| (i, s, self.index_before(i), s.index_after))
    }
}
