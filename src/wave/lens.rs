//! Wave optics of a lens, the front door: one set of options with defaults, and the wavefront, MTF and PSF
//! of a real lens from it, as `lensbake wavefront`, `mtf` and `psf` compute them.

use super::{FieldTrace, Mtf, Psf, Sampling, Spectrum, WaveError, WaveLens, WavefrontMap};
use crate::paraxial::FirstOrder;
use crate::prescription::RayAiming;
use crate::system::LensSystem;

/// Frequencies of an MTF asked for without any: this many from 0 to the diffraction cutoff.
pub const DEFAULT_MTF_FREQUENCIES: usize = 41;

/// Field, aperture, spectrum, sampling and image plane of a wave-optics analysis. The default
/// is the axial field at the design wavelength, wide open, object at infinity, on the paraxial
/// image plane, with [`Sampling::default`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WaveOptions {
    /// Half-field angle in degrees (field in the y-z plane): for a finite object, the angle its
    /// point's chief ray makes at the entrance-pupil centre.
    pub field_deg: f64,
    /// Wavelengths, the first being the reference; empty: the lens's design wavelength.
    pub wavelengths_nm: Vec<f64>,
    /// Spectral weight of each wavelength; empty: all 1.
    pub weights: Vec<f64>,
    /// Entrance-pupil diameter (mm); None with no `f_number`: the stop filled.
    pub epd_mm: Option<f64>,
    /// f-number EFL / EPD at the reference wavelength (give this or `epd_mm`, not both).
    pub f_number: Option<f64>,
    /// Object distance in front of surface 1 (mm); None: infinity.
    pub object_distance_mm: Option<f64>,
    /// How a pupil coordinate becomes a real ray; None: the lens file's (Zemax `RAIM`), else
    /// paraxial.
    pub ray_aiming: Option<RayAiming>,
    pub sampling: Sampling,
    /// Image plane's distance beyond the paraxial image of the reference wavelength (mm).
    pub defocus_mm: f64,
}

impl WaveOptions {
    /// The wavelengths and weights, checked; the design wavelength when none is named.
    pub fn spectrum(&self, system: &LensSystem) -> Result<Spectrum, WaveError> {
        Spectrum::or_default(
            &self.wavelengths_nm,
            &self.weights,
            system.design_wavelength_nm(),
        )
    }

    /// `system` with this beam: the f-number turned into an entrance-pupil diameter at the
    /// reference wavelength, the ray aiming resolved, every number checked.
    pub fn lens<'a>(&self, system: &'a LensSystem) -> Result<WaveLens<'a>, WaveError> {
        if !(self.field_deg.is_finite() && self.field_deg.abs() < 90.0) {
            return Err(WaveError::Field {
                field_deg: self.field_deg,
            });
        }
        super::finite("defocus (mm)", self.defocus_mm)?;
        let object_distance_mm = self
            .object_distance_mm
            .map(|d| crate::limits::object_distance("the object distance (mm)", d))
            .transpose()?
            .flatten();
        let epd_mm = match (self.f_number, self.epd_mm) {
            (Some(_), Some(_)) => return Err(WaveError::PupilTwice),
            (Some(n), None) => {
                // f/0.5 is the fastest cone a lens in air can form.
                crate::limits::check_range("the f-number", n, 0.5, crate::limits::MAX_F_NUMBER)?;
                let at = system.at_checked(self.spectrum(system)?.reference_nm())?;
                Some(FirstOrder::of(&at)?.efl.abs() / n)
            }
            (None, Some(epd)) => {
                crate::limits::check_length("the entrance-pupil diameter (mm)", epd)?;
                Some(epd)
            }
            (None, None) => None,
        };
        let stated_aiming = || {
            let conditions = system.prescription.provenance.conditions.as_ref();
            conditions.and_then(|c| c.ray_aiming).unwrap_or_default()
        };
        Ok(WaveLens::Real {
            system,
            epd_mm,
            object_distance_mm,
            ray_aiming: self.ray_aiming.unwrap_or_else(stated_aiming),
        })
    }

    /// The pupil of the field traced at every wavelength.
    pub fn field_trace(&self, system: &LensSystem) -> Result<FieldTrace, WaveError> {
        FieldTrace::new(
            &self.lens(system)?,
            self.field_deg,
            &self.spectrum(system)?,
            self.sampling.checked()?,
        )
    }
}

/// The optical path difference over the exit pupil (waves, piston kept; [`WavefrontMap::stats`]
/// gives RMS, peak-to-valley and Strehl) at one wavelength: a spectrum of several is refused.
///
/// ```
/// use lensbake::{LoadOptions, WaveOptions, load_lens, wavefront};
///
/// let lens = load_lens("dgauss-50mm", &LoadOptions::default())?;
/// let options = WaveOptions { field_deg: 10.0, f_number: Some(4.0), ..WaveOptions::default() };
/// let map = wavefront(&lens.system, &options)?;
/// assert_eq!(map.opd_waves.len(), 64 * 64);
/// // The field lies in the y-z plane, so the wavefront is mirror-symmetric in pupil x.
/// for row in map.opd_waves.chunks(64) {
///     for k in 0..32 {
///         match (row[k], row[63 - k]) {
///             (Some(a), Some(b)) => assert!((a - b).abs() < 1e-9),
///             (a, b) => assert_eq!(a.is_some(), b.is_some()),
///         }
///     }
/// }
/// let stats = map.stats();
/// assert!(stats.rms_waves > 0.0 && stats.strehl > 0.0 && stats.strehl <= 1.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn wavefront(system: &LensSystem, options: &WaveOptions) -> Result<WavefrontMap, WaveError> {
    let count = options.wavelengths_nm.len();
    if count > 1 {
        return Err(WaveError::Polychromatic { count });
    }
    let trace = options.field_trace(system)?;
    trace.reference().wavefront(options.defocus_mm)
}

/// The diffraction MTF, tangential and sagittal, over the spectrum, at `frequencies_per_mm`
/// (cycles/mm; empty: [`DEFAULT_MTF_FREQUENCIES`] from 0 to the cutoff).
///
/// ```
/// use lensbake::{LoadOptions, WaveOptions, load_lens, mtf};
///
/// let lens = load_lens("cooke-triplet", &LoadOptions::default())?;
/// let curve = mtf(&lens.system, &WaveOptions::default(), &[0.0, 20.0, 40.0])?;
/// assert!((curve.tangential[0] - 1.0).abs() < 1e-9);
/// // On the axis the lens is rotationally symmetric: tangential equals sagittal.
/// for (t, s) in curve.tangential.iter().zip(&curve.sagittal) {
///     assert!((t - s).abs() < 1e-9);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn mtf(
    system: &LensSystem,
    options: &WaveOptions,
    frequencies_per_mm: &[f64],
) -> Result<Mtf, WaveError> {
    for &f in frequencies_per_mm {
        if !(f.is_finite() && f >= 0.0) {
            return Err(WaveError::Frequency { value: f });
        }
    }
    let trace = options.field_trace(system)?;
    let default;
    let frequencies = if frequencies_per_mm.is_empty() {
        default = super::frequencies_to(trace.reference().cutoff_per_mm, DEFAULT_MTF_FREQUENCIES);
        &default
    } else {
        frequencies_per_mm
    };
    trace.mtf(options.defocus_mm, frequencies)
}

/// The point spread function on the FFT grid of `options.sampling` (1 = the aberration-free
/// peak), over the spectrum.
///
/// ```
/// use lensbake::{LoadOptions, WaveOptions, load_lens, psf};
///
/// let lens = load_lens("dgauss-50mm", &LoadOptions::default())?;
/// let image = psf(&lens.system, &WaveOptions::default())?;
/// assert_eq!(image.intensity.len(), image.size * image.size);
/// assert!(image.peak() > 0.0 && image.peak() <= 1.0 + 1e-9);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn psf(system: &LensSystem, options: &WaveOptions) -> Result<Psf, WaveError> {
    options
        .field_trace(system)?
        .psf(options.defocus_mm, options.sampling.grid)
}
