//! The lens-model layer: the five ways the library turns a film-side ray into a scene ray, named
//! once ([`ModelKind`]) and built once ([`LensModel`]).
//!
//! Thin and thick come from [`crate::paraxial`] ([`FirstOrderModels`]), Seidel from
//! [`crate::seidel`] ([`SeidelLens`]), traced from [`crate::trace`] ([`TracedLens`]) and baked
//! from an [`LrtfTable`] ([`BakedLens`]). The CPU renderer, the GPU parameter packing
//! (`render::gpu_types`), focusing, the benches and the trade-off all take a [`LensModel`], so the
//! error the trade-off measures is the error a render shows.
//!
//! Traced and baked models draw lens samples on the effective-pupil circle of the rear vertex
//! plane, the thin, thick and Seidel models on their exit pupil; a [`PupilSampling`] states
//! which, so the kernels, the reference and the tests all sample the same way.
//!
//! The layer sits between the optics (paraxial, Seidel, trace, LRTF tables, pupils) and its users
//! (render, trade-off): it has its own error type and needs nothing from above it.

mod baked;
mod paraxial;
mod sampling;
mod seidel;
mod traced;

pub use baked::{BakedLens, WAVELENGTH_MATCH_NM, layer_at};
pub use paraxial::{FirstOrderModels, ParaxialLens};
pub use sampling::{MAX_PUPIL_BOUND_GROWTH, OffPlaneBound, PupilSampling, pupil_film_radius};
pub use seidel::{
    AberrationScale, SEIDEL_CONVERGED_MM, SEIDEL_INVERSE_STEPS, SEIDEL_SETTLED_MM, SeidelLens,
    TransverseCoefficients, paraxial_for,
};
pub use traced::{TracedLens, fit_effective_pupil};

use crate::lrtf::bake::exact_transfer;
use crate::lrtf::{FocusError, Lookup, LrtfTable, Ray};
use crate::paraxial::{CannotFocus, ImageInsideLens, ParaxialError};
use crate::prescription::PrescriptionError;
use serde::Serialize;

/// Why a lens model cannot be built or named. Wrapped errors are part of the message and not
/// reported again as its source.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    #[error("lens: {0}")]
    Paraxial(ParaxialError),
    #[error("lens: {0}")]
    Wavelength(PrescriptionError),
    #[error("focal length must be a positive number of mm, got {}", crate::limits::short(*.0))]
    FocalLength(f64),
    #[error("f-number must be positive, got {}", crate::limits::short(*.0))]
    FNumber(f64),
    #[error(transparent)]
    Limit(#[from] crate::limits::LimitError),
    #[error("f-number {} is faster than the lens wide open (f/{wide_open:.3})", crate::limits::short(*.f_number))]
    FasterThanLens { f_number: f64, wide_open: f64 },
    #[error("f-number {} is faster than the table's f/{table:.3}; rebake with --f-number", crate::limits::short(*.f_number))]
    FasterThanTable { f_number: f64, table: f64 },
    #[error(
        "lens: an odd number of mirrors sends the light back towards the object side; only a \
         lens that images behind its last surface can be rendered"
    )]
    ImageInFront,
    #[error("lens: the exit pupil is at infinity; thick and thin models need a finite one")]
    ExitPupilAtInfinity,
    #[error(transparent)]
    CannotFocus(CannotFocus),
    #[error(transparent)]
    ImageInsideLens(ImageInsideLens),
    #[error(
        "cannot image the point at z = {z:.3} mm: it lies inside the front focal length \
         ({front_focal_mm:.3} mm in front of the first vertex)"
    )]
    InsideFocalLength { z: f64, front_focal_mm: f64 },
    #[error("no ray from the film centre (z = {film_z:.3} mm) passes the lens")]
    NoRayFromFilmCentre { film_z: f64 },
    #[error("baked lens: {0}")]
    TableFocus(FocusError),
    #[error(
        "the table has no layer at {wavelength_nm} nm (baked at {baked} nm); rebake with \
         --wavelengths-nm"
    )]
    NoLayerAt { wavelength_nm: f64, baked: String },
    #[error(
        "lens: the Seidel model needs a field and a pupil of finite, nonzero size (chief image \
         height {chief_image_height} mm, marginal exit-pupil height {marginal_pupil_height} mm, \
         n'u' {n_u_image})"
    )]
    SeidelDegenerate {
        chief_image_height: f64,
        marginal_pupil_height: f64,
        n_u_image: f64,
    },
    #[error("the {name} factor must lie within -{max}..{max}, got {factor}")]
    AberrationScale {
        name: &'static str,
        factor: f64,
        max: f64,
    },
    #[error("unknown lens model `{0}`: expected one of {names}", names = ModelKind::NAMES.join(", "))]
    UnknownKind(String),
}

impl From<ParaxialError> for ModelError {
    fn from(error: ParaxialError) -> ModelError {
        ModelError::Paraxial(error)
    }
}

impl From<PrescriptionError> for ModelError {
    fn from(error: PrescriptionError) -> ModelError {
        ModelError::Wavelength(error)
    }
}

impl From<FocusError> for ModelError {
    fn from(error: FocusError) -> ModelError {
        ModelError::TableFocus(error)
    }
}

/// The five lens models, cheapest first (the order the trade-off walks them in). The one place a
/// model's name is spelled: [`ModelKind::name`], [`ModelKind::NAMES`] and [`std::str::FromStr`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    /// Ideal thin lens: one principal plane, aperture in it.
    Thin,
    /// First-order thick lens: separate principal planes and real pupil positions.
    Thick,
    /// The thick lens plus the third-order (Seidel) transverse aberration of the plane in focus.
    Seidel,
    /// A baked lens ray transfer function table.
    Baked,
    /// The exact sequential trace through every surface.
    Traced,
    /// The real-time tier: the gather post-process over the pinhole image, its taps weighted by
    /// the lens's defocus spots traced through the exact lens (`crate::realtime`). Its camera
    /// holds the traced model the spots come from.
    Postfx,
    /// The real-time tier's layered depth of field (seed 002): K depth layers and one peeled
    /// hidden layer, each blurred by the same lens kernels as `Postfx`, composited back to
    /// front (`crate::realtime::layered`).
    Layered,
}

impl ModelKind {
    pub const ALL: [ModelKind; 7] = [
        ModelKind::Thin,
        ModelKind::Thick,
        ModelKind::Seidel,
        ModelKind::Baked,
        ModelKind::Traced,
        ModelKind::Postfx,
        ModelKind::Layered,
    ];
    /// Every model's name, in the order of [`ModelKind::ALL`] (for help text and messages).
    pub const NAMES: [&'static str; 7] = [
        "thin", "thick", "seidel", "baked", "traced", "postfx", "layered",
    ];

    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    /// Whether the model needs the lens's surfaces (a traced or baked model of an ideal lens
    /// does not exist).
    pub fn needs_surfaces(self) -> bool {
        matches!(
            self,
            ModelKind::Traced | ModelKind::Baked | ModelKind::Postfx | ModelKind::Layered
        )
    }

    /// Whether the model is the real-time tier's: a filter over the layered depth image with
    /// lens kernels, not a sampler of the lens (CPU only, monochrome, no sample passes).
    pub fn is_realtime(self) -> bool {
        matches!(self, ModelKind::Postfx | ModelKind::Layered)
    }
}

impl std::fmt::Display for ModelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for ModelKind {
    type Err = ModelError;

    fn from_str(text: &str) -> Result<ModelKind, ModelError> {
        ModelKind::ALL
            .into_iter()
            .find(|kind| kind.name() == text)
            .ok_or_else(|| ModelError::UnknownKind(text.to_string()))
    }
}

/// One lens model, built: what turns film-side rays into scene rays.
#[derive(Clone, Debug, PartialEq)]
pub enum LensModel {
    /// Ideal thin lens: one principal plane, aperture in it.
    Thin(ParaxialLens),
    /// First-order thick lens: separate principal planes and real pupil positions.
    Thick(ParaxialLens),
    /// The exact sequential trace through every surface.
    Traced(Box<TracedLens>),
    /// A baked lens ray transfer function table.
    Baked(Box<BakedLens>),
    /// The thick lens plus the third-order (Seidel) transverse aberration of its conjugate.
    Seidel(Box<SeidelLens>),
}

impl LensModel {
    pub fn kind(&self) -> ModelKind {
        match self {
            LensModel::Thin(_) => ModelKind::Thin,
            LensModel::Thick(_) => ModelKind::Thick,
            LensModel::Traced(_) => ModelKind::Traced,
            LensModel::Baked(_) => ModelKind::Baked,
            LensModel::Seidel(_) => ModelKind::Seidel,
        }
    }

    pub fn name(&self) -> &'static str {
        self.kind().name()
    }

    /// The first-order description: the model itself for thin and thick, the thick model of the
    /// lens for Seidel, traced and baked (it places the eye and sizes the field and layer
    /// margins).
    pub fn paraxial(&self) -> &ParaxialLens {
        match self {
            LensModel::Thin(lens) | LensModel::Thick(lens) => lens,
            LensModel::Traced(lens) => &lens.paraxial,
            LensModel::Baked(lens) => &lens.paraxial,
            LensModel::Seidel(lens) => &lens.thick,
        }
    }

    /// Where lens samples are drawn: the exit pupil for thin, thick and Seidel, the effective
    /// pupil on the rear vertex plane for traced and baked.
    pub fn pupil_sampling(&self) -> PupilSampling {
        match self {
            LensModel::Thin(lens) | LensModel::Thick(lens) => {
                PupilSampling::disc(lens.exit_pupil_z, lens.exit_pupil_radius_mm)
            }
            LensModel::Seidel(lens) => {
                PupilSampling::disc(lens.thick.exit_pupil_z, lens.thick.exit_pupil_radius_mm)
            }
            LensModel::Traced(lens) => PupilSampling {
                z: lens.rear_plane_z,
                circles: lens.pupil.clone(),
            },
            LensModel::Baked(lens) => lens.pupil(lens.layer),
        }
    }

    /// The scene-side ray for a film-side ray (travelling -z), or None where the model blocks
    /// it. `film_z` is the film plane the model is focused on: thin and thick image planes onto
    /// planes without aberration, so they take the ray's film point (x, y) on that plane, each
    /// in its own focus; Seidel, traced and baked map the ray from where it starts. First-order
    /// and Seidel models have no apertures; the Seidel model gives no ray where its inverse map
    /// does not settle. The f64 statement of what the renderer's kernels compute per sample.
    pub fn scene_ray(&self, ray: &Ray, film_z: f64) -> Option<Ray> {
        let towards = |film: [f64; 3]| std::array::from_fn(|k| film[k] + ray.direction[k]);
        match self {
            LensModel::Thin(lens) | LensModel::Thick(lens) => {
                let film = [ray.origin[0], ray.origin[1], film_z];
                Some(scene_ray_of(lens.object_ray(film, towards(film))))
            }
            LensModel::Seidel(lens) => lens
                .object_ray(ray.origin, towards(ray.origin))
                .map(scene_ray_of),
            LensModel::Baked(lens) => {
                match lens.table.lookup_layer(lens.layer, ray, lens.stop_radius) {
                    Lookup::Passes(out) => Some(out),
                    Lookup::Blocked | Lookup::OutsideDomain => None,
                }
            }
            LensModel::Traced(lens) => match exact_transfer(&lens.tracer, ray) {
                (Some(t), true) => Some(Ray {
                    origin: t.exit_point,
                    direction: t.exit_direction,
                }),
                _ => None,
            },
        }
    }

    /// Bytes of the model's own data as held in memory (table entries for a baked table, the
    /// surface records for traced).
    pub fn data_bytes(&self) -> usize {
        match self {
            LensModel::Thin(lens) | LensModel::Thick(lens) => std::mem::size_of_val(lens),
            LensModel::Seidel(lens) => std::mem::size_of_val(lens.as_ref()),
            LensModel::Baked(lens) => lens.table.entry_bytes(),
            LensModel::Traced(lens) => std::mem::size_of_val(lens.system.surfaces.as_slice()),
        }
    }

    /// The table of a baked model.
    pub fn table(&self) -> Option<&LrtfTable> {
        match self {
            LensModel::Baked(lens) => Some(&lens.table),
            _ => None,
        }
    }
}

/// The scene-side ray through `origin` with slopes dx/dz, dy/dz, travelling into the scene (-z),
/// as the exact backward trace reports it.
fn scene_ray_of((origin, slope): ([f64; 3], [f64; 2])) -> Ray {
    let n = (slope[0] * slope[0] + slope[1] * slope[1] + 1.0).sqrt();
    Ray {
        origin,
        direction: [-slope[0] / n, -slope[1] / n, -1.0 / n],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lenses;
    use crate::prescription::formats::LoadOptions;
    use crate::system::SystemAt;
    use crate::trace::Tracer;

    fn dgauss() -> (SystemAt, ParaxialLens) {
        let lens = lenses::load("dgauss-50mm", &LoadOptions::default()).unwrap();
        let thick = FirstOrderModels::of(&lens.system, None).unwrap().thick;
        (lens.system.at(lens.system.design_wavelength_nm()), thick)
    }

    #[test]
    fn model_names_parse_back_to_their_kind() {
        for kind in ModelKind::ALL {
            assert_eq!(kind.name().parse::<ModelKind>().unwrap(), kind);
        }
        let err = "pinhole".parse::<ModelKind>().unwrap_err().to_string();
        assert!(
            err.contains("pinhole")
                && err.contains("thin, thick, seidel, baked, traced, postfx, layered")
        );
    }

    #[test]
    fn near_axial_rays_agree_with_the_exact_trace_for_every_model() {
        // Close to the axis every model is the paraxial limit of the real lens, so the scene-side
        // directions must agree to the size of the third-order terms (tiny at 0.05 mm).
        let (at, thick) = dgauss();
        let paraxial = paraxial_for(&at, None).unwrap();
        let film_z = paraxial.z_image;
        let exact = LensModel::Traced(Box::new(TracedLens {
            paraxial: thick.clone(),
            tracer: Tracer::new(&at),
            rear_plane_z: at.last_vertex_z(),
            system: at.clone(),
            pupil: PupilSampling::disc(0.0, 0.0).circles,
        }));
        let models = [
            (
                LensModel::Thick(thick.clone()),
                thick.rear_principal_z + thick.focal_length_mm,
            ),
            (
                LensModel::Seidel(Box::new(SeidelLens::new(&at, &paraxial, thick))),
                film_z,
            ),
        ];
        let ray = Ray {
            origin: [0.05, -0.03, film_z],
            direction: {
                let d: [f64; 3] = [0.001, 0.002, -1.0];
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                d.map(|v| v / n)
            },
        };
        let reference = exact.scene_ray(&ray, film_z).unwrap();
        for (model, own_film_z) in &models {
            let out = model.scene_ray(&ray, *own_film_z).unwrap();
            let angle = crate::lrtf::measure::angle_between(out.direction, reference.direction);
            assert!(angle < 1e-6, "{}: {angle} rad", model.name());
        }
    }
}
