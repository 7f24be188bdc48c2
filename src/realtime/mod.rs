//! The real-time tier: depth of field from the pinhole colour and depth by filtering, with
//! kernels that are the lens's own defocus spots rather than discs sized by a thin-lens circle
//! of confusion (issue 55).
//!
//! It sits above the renderer's scene input and layers ([`crate::render`]) and the lens-model
//! layer ([`crate::model`]) and imports only downwards: [`kernels`] traces the kernel set
//! through the exact lens and [`store`] keeps it on disk; [`mod@postfx`] gathers with it at full
//! resolution, tap by tap (the accuracy statement), [`fast`] at half resolution with kernels
//! fitted once per texel (the real-time path, and the default).

pub mod fast;
pub mod kernels;
pub mod layered;
pub mod postfx;
pub mod store;

pub use fast::postfx_fast;
pub use kernels::{KernelSettings, LensKernels};
pub use layered::{LayeredSettings, layered};
pub use postfx::postfx;
pub use store::{KernelKey, KernelStoreError};

use crate::render::RenderError;
use crate::render::camera::Camera;
use crate::render::image::RgbImage;
use crate::render::layers::LayeredDepthImage;
use std::path::{Path, PathBuf};

/// Which statement of the gather renders a `postfx` frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PostfxPath {
    /// Half resolution, at most 81 taps a pass, kernels fitted once per texel ([`postfx_fast`]).
    #[default]
    Fast,
    /// Full resolution, each tap's kernel fitted on the fly ([`postfx()`]).
    Exact,
}

impl PostfxPath {
    pub fn name(self) -> &'static str {
        match self {
            PostfxPath::Fast => "fast",
            PostfxPath::Exact => "exact",
        }
    }

    /// Renders the pinhole layer of `ldi` at `width` x `height` through `kernels`.
    pub fn render(
        self,
        camera: &Camera,
        ldi: &LayeredDepthImage,
        kernels: &LensKernels,
        width: u32,
        height: u32,
    ) -> Result<RgbImage, RenderError> {
        match self {
            PostfxPath::Fast => postfx_fast(camera, ldi, kernels, width, height),
            PostfxPath::Exact => postfx(camera, ldi, kernels, width, height),
        }
    }
}

/// Where a kernel set came from.
#[derive(Clone, Debug, PartialEq)]
pub enum KernelOrigin {
    /// Read from this file.
    Stored(PathBuf),
    /// Traced now. `refused`: why a stored set was not used (None where there was none);
    /// `saved`: the file it was written to, or why it could not be.
    Traced {
        refused: Option<String>,
        saved: Result<PathBuf, String>,
    },
}

/// The kernel set for `key`: read from `folder` where a valid one is stored there, else traced
/// by `trace` and stored. A stored set of another key or format version, or a damaged one, is
/// traced again and replaced.
pub fn stored_or_traced(
    key: &KernelKey,
    folder: &Path,
    trace: impl FnOnce() -> Result<LensKernels, RenderError>,
) -> Result<(LensKernels, KernelOrigin), RenderError> {
    let path = key.path_in(folder);
    let refused = match store::read(&path, key) {
        Ok(kernels) => return Ok((kernels, KernelOrigin::Stored(path))),
        Err(KernelStoreError::Read { error, .. })
            if error.kind() == std::io::ErrorKind::NotFound =>
        {
            None
        }
        Err(other) => Some(other.to_string()),
    };
    let kernels = trace()?;
    let saved = std::fs::create_dir_all(folder)
        .map_err(|e| format!("{}: {e}", folder.display()))
        .and_then(|()| store::write(&path, key, &kernels).map_err(|e| e.to_string()))
        .map(|()| path);
    Ok((kernels, KernelOrigin::Traced { refused, saved }))
}
