//! Diffraction and geometric MTF: one field, through focus, across the field, polychromatic.

use super::fft::pupil_function;
use super::pupil::{PupilTrace, WaveLens, WavefrontMap};
use super::{Sampling, WaveError, finite};
use rustfft::num_complex::Complex;
use serde::Serialize;

/// Wavelengths with spectral weights; `reference` indexes the one whose paraxial image plane
/// and chief ray every wavelength is measured against.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Spectrum {
    pub wavelengths_nm: Vec<f64>,
    pub weights: Vec<f64>,
    pub reference: usize,
}

impl Spectrum {
    pub fn monochromatic(wavelength_nm: f64) -> Spectrum {
        Spectrum {
            wavelengths_nm: vec![wavelength_nm],
            weights: vec![1.0],
            reference: 0,
        }
    }

    /// `wavelengths_nm` (empty: `default_nm` alone) weighted by `weights` (empty: all 1), the
    /// first the reference, checked as [`Spectrum::new`] does.
    pub fn or_default(
        wavelengths_nm: &[f64],
        weights: &[f64],
        default_nm: f64,
    ) -> Result<Spectrum, WaveError> {
        let wavelengths = if wavelengths_nm.is_empty() {
            vec![default_nm]
        } else {
            wavelengths_nm.to_vec()
        };
        let weights = if weights.is_empty() {
            vec![1.0; wavelengths.len()]
        } else {
            weights.to_vec()
        };
        Spectrum::new(wavelengths, weights, 0)
    }

    /// Checks the weights (finite, not negative, one above zero) and the lengths.
    pub fn new(
        wavelengths_nm: Vec<f64>,
        weights: Vec<f64>,
        reference: usize,
    ) -> Result<Spectrum, WaveError> {
        for &w in &wavelengths_nm {
            crate::limits::check_wavelength(w)?;
        }
        for &w in &weights {
            if !(w.is_finite() && w >= 0.0) {
                return Err(WaveError::NoWeights);
            }
        }
        if weights.len() != wavelengths_nm.len()
            || !weights.iter().any(|&w| w > 0.0)
            || reference >= wavelengths_nm.len()
        {
            return Err(WaveError::NoWeights);
        }
        Ok(Spectrum {
            wavelengths_nm,
            weights,
            reference,
        })
    }

    pub fn reference_nm(&self) -> f64 {
        self.wavelengths_nm[self.reference]
    }
}

/// Tangential and sagittal modulation at a list of frequencies.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Mtf {
    pub field_deg: f64,
    pub frequencies_per_mm: Vec<f64>,
    pub tangential: Vec<f64>,
    pub sagittal: Vec<f64>,
    /// The aberration-free circular pupil of the same f-number (weighted over the spectrum).
    pub diffraction_limit: Vec<f64>,
    /// Diffraction cutoff 1 / (λ N_w) at the reference wavelength, cycles/mm.
    pub cutoff_per_mm: f64,
}

/// Modulation against defocus at one frequency.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ThroughFocus {
    pub field_deg: f64,
    pub frequency_per_mm: f64,
    pub defocus_mm: Vec<f64>,
    pub tangential: Vec<f64>,
    pub sagittal: Vec<f64>,
}

/// Tangential and sagittal modulation at each chosen frequency, one field.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MtfAtField {
    pub field_deg: f64,
    pub tangential: Vec<f64>,
    pub sagittal: Vec<f64>,
}

/// MTF across the field at chosen frequencies; fields whose analysis fails are listed apart.
#[derive(Clone, Debug, PartialEq)]
pub struct MtfAcrossField {
    pub frequencies_per_mm: Vec<f64>,
    pub fields: Vec<MtfAtField>,
    pub failed: Vec<(f64, WaveError)>,
}

/// The MTF of an aberration-free circular pupil at `nu` = frequency / cutoff:
/// (2/π) (acos ν - ν √(1 - ν²)), zero beyond the cutoff.
pub fn diffraction_limited_mtf(nu: f64) -> f64 {
    if nu <= 0.0 {
        return 1.0;
    }
    if nu >= 1.0 {
        return 0.0;
    }
    std::f64::consts::FRAC_2_PI * (nu.acos() - nu * (1.0 - nu * nu).sqrt())
}

/// `count` frequencies evenly spaced from 0 to `cutoff_per_mm`.
pub fn frequencies_to(cutoff_per_mm: f64, count: usize) -> Vec<f64> {
    let steps = count.max(2) - 1;
    (0..=steps)
        .map(|i| cutoff_per_mm * i as f64 / steps as f64)
        .collect()
}

/// The complex OTF of one wavelength's map, along one axis, at the given frequencies.
type OtfOfMap = dyn Fn(&WavefrontMap, usize, &[f64]) -> Vec<Complex<f64>>;

/// One field traced at every wavelength of a spectrum.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldTrace {
    pub field_deg: f64,
    pub spectrum: Spectrum,
    pub traces: Vec<PupilTrace>,
}

impl FieldTrace {
    pub fn new(
        lens: &WaveLens,
        field_deg: f64,
        spectrum: &Spectrum,
        sampling: Sampling,
    ) -> Result<FieldTrace, WaveError> {
        let traces = spectrum
            .wavelengths_nm
            .iter()
            .map(|&nm| PupilTrace::trace(lens, field_deg, nm, spectrum.reference_nm(), sampling))
            .collect::<Result<_, _>>()?;
        Ok(FieldTrace {
            field_deg,
            spectrum: spectrum.clone(),
            traces,
        })
    }

    pub fn reference(&self) -> &PupilTrace {
        &self.traces[self.spectrum.reference]
    }

    /// Every wavelength's wavefront `defocus_mm` beyond the image plane, all centred on the
    /// reference wavelength's chief ray (lateral colour becomes tilt), with its weight.
    /// Wavelengths whose rays all miss the image are left out.
    pub fn wavefronts(&self, defocus_mm: f64) -> Result<Vec<(WavefrontMap, f64)>, WaveError> {
        let centre = self.reference().chief_point(defocus_mm);
        let maps: Vec<(WavefrontMap, f64)> = self
            .traces
            .iter()
            .zip(&self.spectrum.weights)
            .filter(|(_, w)| **w > 0.0)
            .filter_map(|(trace, &w)| Some((trace.wavefront_about(defocus_mm, centre).ok()?, w)))
            .collect();
        if maps.is_empty() {
            return Err(WaveError::NoLight {
                field_deg: self.field_deg,
            });
        }
        Ok(maps)
    }

    /// The PSF `defocus_mm` beyond the image plane on a `grid` x `grid` FFT, over the whole
    /// spectrum ([`super::polychromatic_psf`]); one wavelength gives its monochromatic PSF.
    pub fn psf(&self, defocus_mm: f64, grid: usize) -> Result<super::Psf, WaveError> {
        let maps = self.wavefronts(defocus_mm)?;
        super::polychromatic_psf(&maps, self.spectrum.reference_nm(), grid)
    }

    /// Diffraction MTF `defocus_mm` beyond the image plane.
    pub fn mtf(&self, defocus_mm: f64, frequencies_per_mm: &[f64]) -> Result<Mtf, WaveError> {
        let maps = self.wavefronts(defocus_mm)?;
        Ok(self.combine(&maps, frequencies_per_mm, &|map, axis, f| {
            diffraction_otf(map, axis, f)
        }))
    }

    /// Geometric MTF (the Fourier transform of the spot diagram's line spread), same planes
    /// and weights as [`FieldTrace::mtf`].
    pub fn geometric_mtf(
        &self,
        defocus_mm: f64,
        frequencies_per_mm: &[f64],
    ) -> Result<Mtf, WaveError> {
        let maps = self.wavefronts(defocus_mm)?;
        Ok(self.combine(&maps, frequencies_per_mm, &geometric_otf))
    }

    /// Diffraction MTF at one frequency in each plane of `defocus_mm`.
    pub fn through_focus(
        &self,
        frequency_per_mm: f64,
        defocus_mm: &[f64],
    ) -> Result<ThroughFocus, WaveError> {
        finite("frequency (cycles/mm)", frequency_per_mm)?;
        let mut tangential = Vec::with_capacity(defocus_mm.len());
        let mut sagittal = Vec::with_capacity(defocus_mm.len());
        for &dz in defocus_mm {
            let mtf = self.mtf(dz, &[frequency_per_mm])?;
            tangential.push(mtf.tangential[0]);
            sagittal.push(mtf.sagittal[0]);
        }
        Ok(ThroughFocus {
            field_deg: self.field_deg,
            frequency_per_mm,
            defocus_mm: defocus_mm.to_vec(),
            tangential,
            sagittal,
        })
    }

    /// The weighted sum of each wavelength's complex OTF, normalised, in modulus.
    fn combine(
        &self,
        maps: &[(WavefrontMap, f64)],
        frequencies_per_mm: &[f64],
        otf: &OtfOfMap,
    ) -> Mtf {
        let total: f64 = maps.iter().map(|m| m.1).sum();
        let mut axes = [
            vec![Complex::new(0.0, 0.0); frequencies_per_mm.len()],
            vec![Complex::new(0.0, 0.0); frequencies_per_mm.len()],
        ];
        let mut diffraction_limit = vec![0.0; frequencies_per_mm.len()];
        for (map, weight) in maps {
            for (axis, sum) in axes.iter_mut().enumerate() {
                for (s, v) in sum.iter_mut().zip(otf(map, axis, frequencies_per_mm)) {
                    *s += v * (weight / total);
                }
            }
            for (d, f) in diffraction_limit.iter_mut().zip(frequencies_per_mm) {
                *d += weight / total * diffraction_limited_mtf(f / map.cutoff_per_mm);
            }
        }
        let [tangential, sagittal] = axes.map(|a| a.iter().map(|v| v.norm().min(1.0)).collect());
        Mtf {
            field_deg: self.field_deg,
            frequencies_per_mm: frequencies_per_mm.to_vec(),
            tangential,
            sagittal,
            diffraction_limit,
            cutoff_per_mm: self.reference().cutoff_per_mm,
        }
    }
}

/// The pupil's autocorrelation at integer lags along one axis (0 tangential = pupil y,
/// 1 sagittal = pupil x), normalised to 1 at lag 0: the OTF at lag × lag frequency. This is
/// what the FFT of the FFT PSF gives on a grid at least twice the pupil, computed directly.
fn autocorrelation(samples: usize, opd_waves: &[Option<f64>], axis: usize) -> Vec<Complex<f64>> {
    let n = samples;
    let pupil = pupil_function(opd_waves);
    let energy: f64 = pupil.iter().map(|p| p.norm_sqr()).sum();
    let at = |ix: usize, iy: usize| pupil[iy * n + ix];
    (0..n)
        .map(|lag| {
            let mut sum = Complex::new(0.0, 0.0);
            for iy in 0..n {
                for ix in 0..n {
                    let (jx, jy) = if axis == 0 {
                        (ix, iy + lag)
                    } else {
                        (ix + lag, iy)
                    };
                    if jx < n && jy < n {
                        sum += at(jx, jy) * at(ix, iy).conj();
                    }
                }
            }
            sum / energy
        })
        .collect()
}

/// The diffraction OTF of `map` along `axis` at each frequency, linear between lags.
fn diffraction_otf(map: &WavefrontMap, axis: usize, frequencies: &[f64]) -> Vec<Complex<f64>> {
    otf_at(
        map.samples,
        &map.opd_waves,
        axis,
        map.lag_frequency_per_mm[axis],
        frequencies,
    )
}

/// The diffraction OTF of an OPD grid along `axis` at each frequency, linear between lags of
/// frequency `step` (in whatever unit the frequencies are: cycles/mm in an image plane,
/// cycles/mrad at infinity).
pub(super) fn otf_at(
    samples: usize,
    opd_waves: &[Option<f64>],
    axis: usize,
    step: f64,
    frequencies: &[f64],
) -> Vec<Complex<f64>> {
    let lags = autocorrelation(samples, opd_waves, axis);
    frequencies
        .iter()
        .map(|f| {
            let position = f.abs() / step;
            // Compared as floats: a frequency far beyond the cut-off (a tiny lag step at an
            // extreme f-number) is past any whole number of lags, NaN too.
            let Some(last) = lags.len().checked_sub(1) else {
                return Complex::new(0.0, 0.0);
            };
            if !(position < last as f64) {
                return if position == last as f64 {
                    lags[last]
                } else {
                    Complex::new(0.0, 0.0)
                };
            }
            let below = position as usize;
            let t = position - below as f64;
            lags[below] * (1.0 - t) + lags[below + 1] * t
        })
        .collect()
}

/// The geometric OTF along `axis`: the mean of exp(-2πi f y) over the rays' image points (y
/// for tangential, x for sagittal).
fn geometric_otf(map: &WavefrontMap, axis: usize, frequencies: &[f64]) -> Vec<Complex<f64>> {
    let coordinate = if axis == 0 { 1 } else { 0 };
    let points: Vec<f64> = map
        .image_points_mm
        .iter()
        .flatten()
        .map(|p| p[coordinate])
        .collect();
    let count = points.len() as f64;
    frequencies
        .iter()
        .map(|f| {
            points
                .iter()
                .map(|&y| Complex::from_polar(1.0, -std::f64::consts::TAU * f * y))
                .sum::<Complex<f64>>()
                / count
        })
        .collect()
}

/// Diffraction MTF at `frequencies_per_mm` for every field of `fields_deg` (at the image
/// plane), keeping the fields that fail apart.
pub fn mtf_across_field(
    lens: &WaveLens,
    fields_deg: &[f64],
    spectrum: &Spectrum,
    sampling: Sampling,
    frequencies_per_mm: &[f64],
) -> MtfAcrossField {
    let mut fields = Vec::new();
    let mut failed = Vec::new();
    for &field_deg in fields_deg {
        match FieldTrace::new(lens, field_deg, spectrum, sampling)
            .and_then(|trace| trace.mtf(0.0, frequencies_per_mm))
        {
            Ok(mtf) => fields.push(MtfAtField {
                field_deg,
                tangential: mtf.tangential,
                sagittal: mtf.sagittal,
            }),
            Err(error) => failed.push((field_deg, error)),
        }
    }
    MtfAcrossField {
        frequencies_per_mm: frequencies_per_mm.to_vec(),
        fields,
        failed,
    }
}
