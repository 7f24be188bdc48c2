//! Lens prescriptions: the data model, its validation, and the file formats that produce it.

mod error;
pub mod formats;
mod model;
mod validate;

pub use error::{Location, PrescriptionError, Problem, RadiusModeContradiction};
pub use model::{
    ApertureSpec, Conditions, DEFAULT_WAVELENGTH_NM, FieldKind, FieldSpec, MAX_ASPHERE_TERMS,
    MAX_INDEX, MIN_INDEX, Medium, Prescription, Provenance, RayAiming, Shape, StatedCondition,
    StopShape, Surface,
};
pub use validate::{CROSSING_TOLERANCE_MM, SourceMap, validate};
