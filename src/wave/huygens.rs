//! Where the FFT's assumptions fail, and the Huygens PSF that does not make them.

use super::fft::Psf;
use super::pupil::{WavefrontMap, pupil_coordinate};
use super::{MAX_GRID, NM_TO_MM, WaveError};
use rayon::prelude::*;
use serde::Serialize;

/// An assumption of the FFT PSF and MTF that a wavefront breaks, with the measured size.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "assumption", rename_all = "snake_case")]
pub enum FftAssumption {
    /// The FFT takes exit directions to be an affine function of the pupil grid; pupil
    /// aberration bends that map. `deviation` is the largest departure of a real exit direction
    /// from the best affine map, as a fraction of the beam's angular half-width (limit 0.02).
    AffinePupilMap { deviation: f64 },
    /// Neighbouring pupil samples differ by more than half a wave, so the sampled phase aliases
    /// (more pupil samples are needed). `step_waves` is the largest difference.
    PupilUndersampled { step_waves: f64 },
    /// Rays land outside the FFT's image window, so the PSF wraps around (a larger grid over
    /// the same pupil widens the window). Both in mm from the reference point.
    WindowTooSmall {
        spot_radius_mm: f64,
        window_half_width_mm: f64,
    },
    /// Image-space numerical aperture above 0.6: scalar, small-angle diffraction no longer
    /// describes the focus (polarisation and obliquity matter).
    HighAperture { numerical_aperture: f64 },
}

/// What was measured against which limit, and what to change (`--huygens`, `--samples` and
/// `--grid` are the wave commands' flags).
impl std::fmt::Display for FftAssumption {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            FftAssumption::AffinePupilMap { deviation } => write!(
                f,
                "exit directions depart from an affine map of the pupil by {:.1} % of the beam's \
                 half-width (limit {:.0} %); --huygens sums along the real directions",
                deviation * 100.0,
                AFFINE_LIMIT * 100.0
            ),
            FftAssumption::PupilUndersampled { step_waves } => write!(
                f,
                "neighbouring pupil samples differ by {step_waves:.2} waves (limit \
                 {STEP_LIMIT_WAVES}), so the phase aliases; raise --samples"
            ),
            FftAssumption::WindowTooSmall {
                spot_radius_mm,
                window_half_width_mm,
            } => write!(
                f,
                "rays land up to {:.2} um from the reference point, beyond the image window's \
                 {:.2} um, so the PSF wraps around; raise --grid",
                spot_radius_mm * 1e3,
                window_half_width_mm * 1e3
            ),
            FftAssumption::HighAperture { numerical_aperture } => write!(
                f,
                "image-space numerical aperture {numerical_aperture:.3} is above {NA_LIMIT}, \
                 where scalar diffraction no longer describes the focus"
            ),
        }
    }
}

/// Largest affine-map departure accepted, as a fraction of the beam's angular half-width.
const AFFINE_LIMIT: f64 = 0.02;
/// Largest OPD step between neighbouring samples for an unaliased pupil phase (Nyquist).
const STEP_LIMIT_WAVES: f64 = 0.5;
/// Numerical aperture above which scalar diffraction is not trusted.
const NA_LIMIT: f64 = 0.6;

/// Every assumption of the FFT PSF on a `grid` x `grid` FFT that `map` breaks; empty when the
/// FFT results can be trusted.
pub fn fft_assumptions(map: &WavefrontMap, grid: usize) -> Vec<FftAssumption> {
    let mut broken = Vec::new();
    let n = map.samples;
    let samples: Vec<(f64, f64, [f64; 2])> = map
        .exit_directions
        .iter()
        .enumerate()
        .filter_map(|(i, d)| d.map(|d| (pupil_coordinate(n, i % n), pupil_coordinate(n, i / n), d)))
        .collect();
    if let Some((deviation, half_width)) = affine_departure(&samples) {
        if deviation > AFFINE_LIMIT {
            broken.push(FftAssumption::AffinePupilMap { deviation });
        }
        if half_width > NA_LIMIT {
            broken.push(FftAssumption::HighAperture {
                numerical_aperture: half_width,
            });
        }
    }
    let step_waves = largest_step(map);
    if step_waves > STEP_LIMIT_WAVES {
        broken.push(FftAssumption::PupilUndersampled { step_waves });
    }
    let window_half_width_mm =
        0.5 * grid as f64 / map.lag_frequency_per_mm[0].max(map.lag_frequency_per_mm[1]);
    let spot_radius_mm = map
        .image_points_mm
        .iter()
        .flatten()
        .map(|p| p[0].abs().max(p[1].abs()))
        .fold(0.0, f64::max);
    if spot_radius_mm > window_half_width_mm {
        broken.push(FftAssumption::WindowTooSmall {
            spot_radius_mm,
            window_half_width_mm,
        });
    }
    broken
}

/// Fits d = a + B (x, y) to the exit directions and returns the largest residual over the
/// beam's angular half-width, with that half-width; None for fewer than three samples.
fn affine_departure(samples: &[(f64, f64, [f64; 2])]) -> Option<(f64, f64)> {
    if samples.len() < 3 {
        return None;
    }
    let mut normal = nalgebra::Matrix3::<f64>::zeros();
    let mut rhs = nalgebra::Matrix3x2::<f64>::zeros();
    for &(x, y, d) in samples {
        let row = nalgebra::Vector3::new(1.0, x, y);
        normal += row * row.transpose();
        rhs += row * nalgebra::RowVector2::new(d[0], d[1]);
    }
    let coefficients = normal.try_inverse()? * rhs;
    let mut largest = 0.0f64;
    for &(x, y, d) in samples {
        let fit = nalgebra::RowVector3::new(1.0, x, y) * coefficients;
        largest = largest.max((d[0] - fit[0]).hypot(d[1] - fit[1]));
    }
    // The angular half-width: how far the unit pupil edge moves the direction, the larger axis.
    let half_width = coefficients.row(1).norm().max(coefficients.row(2).norm());
    (half_width > 0.0).then(|| (largest / half_width, half_width))
}

/// The largest OPD difference between horizontally or vertically adjacent transmitted samples.
fn largest_step(map: &WavefrontMap) -> f64 {
    let n = map.samples;
    let at = |ix: usize, iy: usize| map.opd_waves[iy * n + ix];
    let mut largest = 0.0f64;
    for iy in 0..n {
        for ix in 0..n {
            let Some(w) = at(ix, iy) else { continue };
            for (jx, jy) in [(ix + 1, iy), (ix, iy + 1)] {
                if jx < n
                    && jy < n
                    && let Some(v) = at(jx, jy)
                {
                    largest = largest.max((w - v).abs());
                }
            }
        }
    }
    largest
}

/// The PSF by direct summation of one wavelet per pupil sample, each travelling along its real
/// exit direction: no affine pupil map and no periodic window, at a cost of pupil samples ×
/// pixels. Same scaling and pixel layout as [`super::psf`]: `size` pixels per side at pitch
/// `pixel_mm` (x, y), centred on the reference point.
pub fn huygens_psf(map: &WavefrontMap, size: usize, pixel_mm: [f64; 2]) -> Result<Psf, WaveError> {
    if size == 0 || size > MAX_GRID {
        return Err(WaveError::Grid {
            grid: size,
            samples: map.samples,
        });
    }
    for pitch in pixel_mm {
        super::positive("pixel pitch (mm)", pitch)?;
    }
    let wavenumber = std::f64::consts::TAU / (map.wavelength_nm * NM_TO_MM);
    let wavelets: Vec<(f64, [f64; 2])> = map
        .opd_waves
        .iter()
        .zip(&map.exit_directions)
        .filter_map(|(w, d)| Some((-std::f64::consts::TAU * (*w)?, (*d)?)))
        .collect();
    let count = wavelets.len() as f64;
    let half = (size / 2) as f64;
    let intensity = (0..size * size)
        .into_par_iter()
        .map(|i| {
            let x = ((i % size) as f64 - half) * pixel_mm[0];
            let y = ((i / size) as f64 - half) * pixel_mm[1];
            let (mut re, mut im) = (0.0, 0.0);
            for &(phase, d) in &wavelets {
                let total = phase + wavenumber * (d[0] * x + d[1] * y);
                re += total.cos();
                im += total.sin();
            }
            (re * re + im * im) / (count * count)
        })
        .collect();
    Ok(Psf {
        wavelength_nm: map.wavelength_nm,
        field_deg: map.field_deg,
        size,
        pixel_mm,
        intensity,
    })
}
