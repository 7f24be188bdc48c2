//! Lens prescriptions: the data model, its validation, and the file formats that produce it.

mod error;
pub mod formats;
mod model;
mod validate;

pub use error::{Location, PrescriptionError, Problem};
pub use model::{
    DEFAULT_WAVELENGTH_NM, MAX_ASPHERE_TERMS, Medium, Prescription, Provenance, Shape, StopShape,
    Surface,
};
pub use validate::{SourceMap, validate};
