//! The real-time tier: depth of field from the pinhole colour and depth by filtering, with
//! kernels that are the lens's own defocus spots rather than discs sized by a thin-lens circle
//! of confusion (issue 55).
//!
//! It sits above the renderer's scene input and layers ([`crate::render`]) and the lens-model
//! layer ([`crate::model`]) and imports only downwards: [`kernels`] traces the kernel set
//! through the exact lens, [`postfx`] gathers with it.

pub mod kernels;
pub mod postfx;

pub use kernels::{KernelSettings, LensKernels};
pub use postfx::postfx;
