//! The film-to-scene ray map of every lens model, behind one interface so that their errors are
//! measured on the same rays: thin and thick (the renderer's [`ParaxialLens`] from
//! [`crate::render::models::FirstOrderModels`]), the Seidel model
//! (the thick map plus third-order transverse aberration, after Asberg, seed 001 section 3.10),
//! a baked table ([`LrtfTable::lookup`]) and the exact trace (the reference).

use crate::lrtf::bake::exact_transfer;
use crate::lrtf::{Lookup, LrtfTable, Ray};
use crate::paraxial::{ObjectPosition, Paraxial, ParaxialError, ParaxialOptions};
use crate::render::camera::ParaxialLens;
use crate::seidel::{Seidel, SeidelTerms};
use crate::system::SystemAt;
use crate::trace::Tracer;
use serde::Serialize;

/// Which kind of model (the `model` field of a trade-off entry).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    Thin,
    Thick,
    Seidel,
    Baked,
    Traced,
}

impl ModelKind {
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Thin => "thin",
            ModelKind::Thick => "thick",
            ModelKind::Seidel => "seidel",
            ModelKind::Baked => "baked",
            ModelKind::Traced => "traced",
        }
    }
}

/// The thick-lens map plus the third-order transverse aberration of the Seidel sums, for one
/// object conjugate (the one the sums were computed for).
///
/// Forward, a ray from the object point whose Gaussian image is G through normalised pupil
/// point p lands at G + eps(G, p) in the Gaussian image plane, with eps = grad W / (n' u') and
/// W = S_I/8 rho^4 + S_II/2 H y rho^2 + S_III/2 H^2 y^2 + (S_III + S_IV)/4 H^2 rho^2
/// + S_V/2 H^3 y (the convention of [`SeidelTerms::transverse`], which it reproduces: TSA, TCO,
/// TAS, SAS and DST). The film-to-scene map inverts that: it solves G + eps(G, p) = L for the
/// film-side ray's landing point L by fixed-point iteration, then sends the paraxial ray from G
/// through the same exit-pupil point into the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SeidelLens {
    pub thick: ParaxialLens,
    pub sums: SeidelTerms,
    /// z of the Gaussian image plane of the conjugate.
    pub image_z: f64,
    /// Signed chief-ray height in the image plane at normalised field H = 1.
    pub chief_image_height: f64,
    /// Signed marginal-ray height in the exit-pupil plane (normalised pupil coordinate 1).
    pub marginal_pupil_height: f64,
    /// n' u' of the marginal ray in image space.
    pub n_u_image: f64,
}

impl SeidelLens {
    /// From the paraxial setup the sums belong to (pupils wide open, `paraxial`'s field as H = 1).
    pub fn new(system: &SystemAt, paraxial: &Paraxial, thick: ParaxialLens) -> SeidelLens {
        let seidel = Seidel::new(system, paraxial, None);
        SeidelLens {
            marginal_pupil_height: paraxial.marginal.image_space_height(thick.exit_pupil_z),
            thick,
            sums: seidel.sums,
            image_z: paraxial.z_image,
            chief_image_height: paraxial.image_height,
            n_u_image: system.image_index() * paraxial.marginal.image_slope(),
        }
    }

    /// Transverse aberration (mm, image plane) of the ray to Gaussian image point `g` through
    /// normalised exit-pupil point `pupil` (both in the lens's x, y).
    pub fn aberration(&self, g: [f64; 2], pupil: [f64; 2]) -> [f64; 2] {
        let radius = g[0].hypot(g[1]);
        // Meridional frame: y along the field direction (any direction on the axis).
        let u = if radius > 0.0 {
            [g[0] / radius, g[1] / radius]
        } else {
            [1.0, 0.0]
        };
        let v = [-u[1], u[0]];
        let h = radius / self.chief_image_height;
        let py = pupil[0] * u[0] + pupil[1] * u[1];
        let px = pupil[0] * v[0] + pupil[1] * v[1];
        let rho2 = px * px + py * py;
        let s = &self.sums;
        let (a, b, c, d, e) = (
            s.spherical / 8.0,
            s.coma / 2.0,
            s.astigmatism / 2.0,
            (s.astigmatism + s.petzval) / 4.0,
            s.distortion / 2.0,
        );
        let k = 1.0 / self.n_u_image;
        let ex = k * (4.0 * a * rho2 * px + 2.0 * b * h * px * py + 2.0 * d * h * h * px);
        let ey = k
            * (4.0 * a * rho2 * py
                + b * h * (rho2 + 2.0 * py * py)
                + 2.0 * (c + d) * h * h * py
                + e * h * h * h);
        [ey * u[0] + ex * v[0], ey * u[1] + ex * v[1]]
    }

    fn map(&self, ray: &Ray) -> Option<Ray> {
        let at = |z: f64| {
            let t = (z - ray.origin[2]) / ray.direction[2];
            [
                ray.origin[0] + t * ray.direction[0],
                ray.origin[1] + t * ray.direction[1],
            ]
        };
        let pupil = at(self.thick.exit_pupil_z);
        let landing = at(self.image_z);
        let p = [
            pupil[0] / self.marginal_pupil_height,
            pupil[1] / self.marginal_pupil_height,
        ];
        let mut g = landing;
        // Contraction: eps changes by a small fraction of a change in G, so a few steps settle.
        for _ in 0..4 {
            let eps = self.aberration(g, p);
            g = [landing[0] - eps[0], landing[1] - eps[1]];
        }
        Some(paraxial_object_ray(
            &self.thick,
            [g[0], g[1], self.image_z],
            [pupil[0], pupil[1], self.thick.exit_pupil_z],
        ))
    }
}

/// The scene-side ray of a paraxial lens for the image-side ray through `film` and `pupil`,
/// travelling into the scene (-z), as the exact backward trace reports it.
fn paraxial_object_ray(lens: &ParaxialLens, film: [f64; 3], pupil: [f64; 3]) -> Ray {
    let (origin, slope) = lens.object_ray(film, pupil);
    let n = (slope[0] * slope[0] + slope[1] * slope[1] + 1.0).sqrt();
    Ray {
        origin,
        direction: [-slope[0] / n, -slope[1] / n, -1.0 / n],
    }
}

/// One model's film-to-scene map.
#[derive(Clone, Debug)]
pub enum RayModel {
    /// A first-order lens with its own film plane at `film_z` (in focus for the scene's focus
    /// distance): a film-side ray keeps its film point and direction, moved onto that plane.
    Paraxial {
        kind: ModelKind,
        lens: ParaxialLens,
        film_z: f64,
    },
    Seidel(Box<SeidelLens>),
    /// Layer `layer` of a table, through a stop of radius `stop_radius`.
    Baked {
        table: Box<LrtfTable>,
        layer: usize,
        stop_radius: f64,
    },
    Traced(Box<Tracer>),
}

impl RayModel {
    pub fn kind(&self) -> ModelKind {
        match self {
            RayModel::Paraxial { kind, .. } => *kind,
            RayModel::Seidel(_) => ModelKind::Seidel,
            RayModel::Baked { .. } => ModelKind::Baked,
            RayModel::Traced(_) => ModelKind::Traced,
        }
    }

    /// The scene-side ray for a film-side ray (travelling -z from the domain's film plane), or
    /// None when the model says it is blocked. First-order and Seidel models have no apertures.
    pub fn map(&self, ray: &Ray) -> Option<Ray> {
        match self {
            RayModel::Paraxial { lens, film_z, .. } => {
                let film = [ray.origin[0], ray.origin[1], *film_z];
                let toward = [
                    film[0] + ray.direction[0],
                    film[1] + ray.direction[1],
                    film[2] + ray.direction[2],
                ];
                Some(paraxial_object_ray(lens, film, toward))
            }
            RayModel::Seidel(lens) => lens.map(ray),
            RayModel::Baked {
                table,
                layer,
                stop_radius,
            } => match table.lookup(*layer, ray, *stop_radius) {
                Lookup::Passes(out) => Some(out),
                Lookup::Blocked | Lookup::OutsideDomain => None,
            },
            RayModel::Traced(tracer) => match exact_transfer(tracer, ray) {
                (Some(t), true) => Some(Ray {
                    origin: t.exit_point,
                    direction: t.exit_direction,
                }),
                _ => None,
            },
        }
    }
}

/// The paraxial setup for an object in focus at `focus_mm` (None: infinity), wide open, at the
/// largest unvignetted field.
pub fn paraxial_for(system: &SystemAt, focus_mm: Option<f64>) -> Result<Paraxial, ParaxialError> {
    let object = ObjectPosition::in_focus(focus_mm);
    Paraxial::new(
        system,
        &ParaxialOptions {
            object,
            ..ParaxialOptions::default()
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lenses;
    use crate::prescription::formats::LoadOptions;
    use crate::render::models::FirstOrderModels;

    fn dgauss() -> (SystemAt, ParaxialLens) {
        let lens = lenses::load("dgauss-50mm", &LoadOptions::default()).unwrap();
        let thick = FirstOrderModels::of(&lens.system, None).unwrap().thick;
        (lens.system.at(lens.system.design_wavelength_nm()), thick)
    }

    #[test]
    fn seidel_aberration_reproduces_the_transverse_sums() {
        // At the pupil rim and the edge of the field, the polynomial must give back the transverse
        // forms already checked against CODE V: TSA on axis, TCO and TAS in the meridional plane
        // (their sum, since both act at y = 1), SAS across it, DST through the pupil centre.
        let (at, thick) = dgauss();
        let paraxial = paraxial_for(&at, None).unwrap();
        let lens = SeidelLens::new(&at, &paraxial, thick);
        let t = Seidel::new(&at, &paraxial, None).transverse;
        let edge = [0.0, lens.chief_image_height];
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * (1.0 + b.abs());
        assert!(close(lens.aberration([0.0, 0.0], [0.0, 1.0])[1], t.tsa));
        assert!(close(lens.aberration(edge, [0.0, 0.0])[1], t.dst));
        let meridional = lens.aberration(edge, [0.0, 1.0])[1];
        assert!(close(meridional, t.tsa + t.tco + t.tas + t.dst));
        let sagittal = lens.aberration(edge, [1.0, 0.0]);
        assert!(close(sagittal[0], t.tsa + t.sas));
        assert!(close(sagittal[1], t.tco / 3.0 + t.dst));
    }

    #[test]
    fn near_axial_rays_agree_with_the_exact_trace_for_every_model() {
        // Close to the axis every model is the paraxial limit of the real lens, so the scene-side
        // directions must agree to the size of the third-order terms (tiny at 0.05 mm).
        let (at, thick) = dgauss();
        let paraxial = paraxial_for(&at, None).unwrap();
        let film_z = paraxial.z_image;
        let exact = RayModel::Traced(Box::new(Tracer::new(&at)));
        let models = [
            RayModel::Paraxial {
                kind: ModelKind::Thick,
                lens: thick.clone(),
                film_z: thick.rear_principal_z + thick.focal_length_mm,
            },
            RayModel::Seidel(Box::new(SeidelLens::new(&at, &paraxial, thick))),
        ];
        let ray = Ray {
            origin: [0.05, -0.03, film_z],
            direction: {
                let d: [f64; 3] = [0.001, 0.002, -1.0];
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                d.map(|v| v / n)
            },
        };
        let reference = exact.map(&ray).unwrap();
        for model in &models {
            let out = model.map(&ray).unwrap();
            let angle = crate::lrtf::measure::angle_between(out.direction, reference.direction);
            assert!(angle < 1e-6, "{:?}: {angle} rad", model.kind());
        }
    }
}
