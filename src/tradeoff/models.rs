//! The film-to-scene ray map of every lens model, behind one interface so that their errors are
//! measured on the same rays: thin and thick (the renderer's [`ParaxialLens`] from
//! [`crate::render::models::FirstOrderModels`]), the Seidel model ([`SeidelLens`]: the thick map
//! plus third-order transverse aberration, after Asberg, seed 001 section 3.10),
//! a baked table ([`LrtfTable::lookup`]) and the exact trace (the reference).

use crate::lrtf::bake::exact_transfer;
use crate::lrtf::{Lookup, LrtfTable, Ray};
use crate::render::camera::ParaxialLens;
pub use crate::render::models::{SeidelLens, paraxial_for};
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

/// The scene-side ray through `origin` with slopes dx/dz, dy/dz, travelling into the scene (-z),
/// as the exact backward trace reports it.
fn scene_ray((origin, slope): ([f64; 3], [f64; 2])) -> Ray {
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
    /// None when the model says it is blocked. First-order and Seidel models have no apertures;
    /// the Seidel model gives no ray where its inverse map does not settle.
    pub fn map(&self, ray: &Ray) -> Option<Ray> {
        match self {
            RayModel::Paraxial { lens, film_z, .. } => {
                let film = [ray.origin[0], ray.origin[1], *film_z];
                let toward = [
                    film[0] + ray.direction[0],
                    film[1] + ray.direction[1],
                    film[2] + ray.direction[2],
                ];
                Some(scene_ray(lens.object_ray(film, toward)))
            }
            RayModel::Seidel(lens) => {
                let toward = std::array::from_fn(|k| ray.origin[k] + ray.direction[k]);
                lens.object_ray(ray.origin, toward).map(scene_ray)
            }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lenses;
    use crate::prescription::formats::LoadOptions;
    use crate::render::models::FirstOrderModels;
    use crate::seidel::Seidel;
    use crate::system::SystemAt;

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
