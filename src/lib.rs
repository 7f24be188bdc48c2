//! lensbake: lens prescriptions in; first-order and third-order analysis, exact ray traces,
//! aberration plots, baked lens ray transfer function (LRTF) tables and depth-of-field renders out.
//!
//! Data flows one way: file -> [`prescription::Prescription`] -> [`system::LensSystem`] ->
//! [`system::SystemAt`] (one wavelength) -> analyses, trace, bake, render. The library never
//! prints; every failure is a typed error.

pub mod analysis;
pub mod glass;
pub mod lenses;
pub mod lrtf;
pub mod paraxial;
#[cfg(feature = "plot")]
pub mod plot;
pub mod prescription;
pub mod pupil;
#[cfg(feature = "render")]
pub mod render;
#[cfg(feature = "plot")]
pub mod report;
pub mod seidel;
pub mod system;
pub mod trace;
#[cfg(feature = "render")]
pub mod tradeoff;
pub mod wave;
