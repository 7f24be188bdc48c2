//! Wave optics from the exact trace: optical path difference over the exit pupil, RMS and
//! peak-to-valley wavefront error, Zernike fits, Strehl ratio, PSF (FFT and Huygens), and
//! diffraction and geometric MTF (through focus, across the field, polychromatic).
//!
//! Conventions (docs/wave.md has the whole story):
//! - The pupil is sampled on a square grid of `samples` points per side spanning the paraxial
//!   entrance pupil, coordinates `-1 + 2k/(samples-1)`; points outside the unit circle are
//!   outside the pupil, points whose ray is blocked are vignetted. Row index = pupil y.
//! - The chief ray is the ray through the centre of the paraxial entrance pupil. The reference
//!   sphere is centred where it meets the image plane and passes through the paraxial exit-pupil
//!   centre on the axis; OPD = OPL(chief) - OPL(ray), both measured to that sphere, in waves
//!   of the analysed wavelength (positive: the ray's wavefront leads). Tilt is kept; piston is
//!   removed from every statistic (RMS about the mean, peak-to-valley).
//! - For a collimated object the optical path starts on the plane through the chief ray's start
//!   point normal to the beam, so the incident wavefront carries no tilt.
//! - Tangential means along pupil y and image y (the field lies in the y-z plane), sagittal
//!   along x.
//!
//! Nothing here draws or prints; every failure is a [`WaveError`].

mod afocal;
mod fft;
mod huygens;
pub mod lens;
mod mtf;
mod pupil;
mod zernike;

pub use afocal::{AfocalWavefront, AngularMtf, afocal_wavefront};
pub use fft::{Psf, polychromatic_psf, psf};
pub use huygens::{FftAssumption, fft_assumptions, huygens_psf};
pub use lens::{DEFAULT_MTF_FREQUENCIES, WaveOptions};
pub use mtf::{
    FieldTrace, Mtf, MtfAcrossField, MtfAtField, Spectrum, ThroughFocus, diffraction_limited_mtf,
    frequencies_to, mtf_across_field,
};
pub use pupil::{PupilTrace, WaveLens, WavefrontMap, WavefrontStats};
pub(crate) use pupil::{inside_pupil, pupil_coordinate};
pub use zernike::{FRINGE_TERMS, ZernikeFit, ZernikeOrdering, ZernikeTerm, zernike_fit};

use crate::paraxial::ParaxialError;
use crate::prescription::PrescriptionError;
use crate::trace::analyses::RealRayError;

/// The smallest and largest pupil grids (points per side).
pub const MIN_SAMPLES: usize = 8;
pub const MAX_SAMPLES: usize = 1024;
/// The largest FFT grid per side: 2048² complex numbers are 64 MiB.
pub const MAX_GRID: usize = 2048;
/// Default pupil sampling and FFT grid: optiland's and OpticStudio's 64 rays across a 256 grid
/// (4x padding), enough for MTF within 0.01 of a 256-sample pupil on the bundled lenses.
pub const DEFAULT_SAMPLES: usize = 64;
pub const DEFAULT_GRID: usize = 256;

/// How finely the pupil and the image are sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Sampling {
    /// Pupil points per side.
    pub samples: usize,
    /// FFT grid per side (at least twice `samples`, so the pupil's autocorrelation does not wrap).
    pub grid: usize,
}

impl Default for Sampling {
    fn default() -> Sampling {
        Sampling {
            samples: DEFAULT_SAMPLES,
            grid: DEFAULT_GRID,
        }
    }
}

impl Sampling {
    /// Checks the sizes before anything is allocated.
    pub fn checked(self) -> Result<Sampling, WaveError> {
        if !(MIN_SAMPLES..=MAX_SAMPLES).contains(&self.samples) {
            return Err(WaveError::Samples {
                samples: self.samples,
            });
        }
        if self.grid < 2 * self.samples || self.grid > MAX_GRID {
            return Err(WaveError::Grid {
                grid: self.grid,
                samples: self.samples,
            });
        }
        Ok(self)
    }
}

/// Why a wave-optics quantity could not be computed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum WaveError {
    #[error(transparent)]
    Prescription(#[from] PrescriptionError),
    #[error(transparent)]
    Paraxial(#[from] ParaxialError),
    #[error(transparent)]
    Ray(#[from] RealRayError),
    #[error(transparent)]
    Limit(#[from] crate::limits::LimitError),
    #[error(
        "the exit pupil lies at infinity (image-space telecentric): there is no reference sphere \
         centred on the image"
    )]
    ExitPupilAtInfinity,
    #[error("pupil sampling {samples} is outside {MIN_SAMPLES}..={MAX_SAMPLES} points per side")]
    Samples { samples: usize },
    #[error(
        "FFT grid {grid} must be at least twice the pupil sampling ({samples}) and at most \
         {MAX_GRID}"
    )]
    Grid { grid: usize, samples: usize },
    #[error("field {field_deg}°: no ray of the pupil grid reaches the image")]
    NoLight { field_deg: f64 },
    #[error(
        "field {field_deg}°: the pupil-edge ray at ({px}, {py}) does not reach the image plane, \
         so the pupil's frequency scale is unknown"
    )]
    PupilEdge { field_deg: f64, px: f64, py: f64 },
    #[error("{what} must be a finite number greater than zero; got {}", crate::limits::short(*.value))]
    NotPositive { what: &'static str, value: f64 },
    #[error("{what} must be finite; got {}", crate::limits::short(*.value))]
    NotFinite { what: &'static str, value: f64 },
    #[error("field {field_deg}° must be an angle below 90 degrees")]
    Field { field_deg: f64 },
    #[error("give the beam as an f-number or as an entrance-pupil diameter, not both")]
    PupilTwice,
    #[error("a wavefront is of one wavelength; {count} were given (the MTF and PSF take several)")]
    Polychromatic { count: usize },
    #[error("frequency {value} cycles/mm must be zero or positive")]
    Frequency { value: f64 },
    #[error("polychromatic analysis needs at least one wavelength with a positive weight")]
    NoWeights,
    #[error("a Zernike fit needs at least {terms} pupil samples; the pupil has {valid}")]
    TooFewSamples { terms: usize, valid: usize },
    #[error("Zernike term count {terms} is outside 1..={max}")]
    ZernikeTerms { terms: usize, max: usize },
    #[error(
        "surface {surface} is an ideal lens (Zemax paraxial surface), whose optical path is not \
         defined by its rays: no path length makes its imaging perfect at every conjugate, and \
         lensbake does not pick one of OpticStudio's approximations; wave optics needs a real lens"
    )]
    IdealLensPath { surface: usize },
}

/// `value` when it is finite and above zero.
pub(crate) fn positive(what: &'static str, value: f64) -> Result<f64, WaveError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(WaveError::NotPositive { what, value })
    }
}

/// `value` when it is finite.
pub(crate) fn finite(what: &'static str, value: f64) -> Result<f64, WaveError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(WaveError::NotFinite { what, value })
    }
}

/// Millimetres per nanometre.
pub(crate) const NM_TO_MM: f64 = 1e-6;
