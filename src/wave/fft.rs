//! The point spread function by FFT of the pupil function.

use super::pupil::WavefrontMap;
use super::{MAX_GRID, WaveError};
use rustfft::FftPlanner;
use rustfft::num_complex::Complex;
use serde::Serialize;

/// A sampled PSF centred on the reference point (the chief ray in the image plane).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Psf {
    /// The wavelength whose pixel grid this is (of a polychromatic PSF: its reference).
    pub wavelength_nm: f64,
    pub field_deg: f64,
    /// Pixels per side.
    pub size: usize,
    /// Pixel pitch (x, y) in mm; pixel (size/2, size/2) is the reference point.
    pub pixel_mm: [f64; 2],
    /// Row-major intensity, rows along image y (row 0 at the most negative y), scaled so that
    /// the same pupil without aberration peaks at 1: the peak of this PSF is its Strehl ratio
    /// (to within the pixel grid).
    pub intensity: Vec<f64>,
}

impl Psf {
    pub fn peak(&self) -> f64 {
        self.intensity.iter().copied().fold(0.0, f64::max)
    }

    /// The image-plane position (x, y) of pixel (column, row), mm from the reference point.
    pub fn position(&self, column: usize, row: usize) -> [f64; 2] {
        let half = (self.size / 2) as f64;
        [
            (column as f64 - half) * self.pixel_mm[0],
            (row as f64 - half) * self.pixel_mm[1],
        ]
    }
}

impl Psf {
    /// The intensity at image point (x, y) mm from the reference point, bilinear between pixel
    /// centres; zero beyond the outermost pixel centres.
    pub fn sample(&self, x: f64, y: f64) -> f64 {
        let half = (self.size / 2) as f64;
        let last = (self.size - 1) as f64;
        let (u, v) = (x / self.pixel_mm[0] + half, y / self.pixel_mm[1] + half);
        if !((0.0..=last).contains(&u) && (0.0..=last).contains(&v)) {
            return 0.0;
        }
        // The far neighbour is clamped, so a point on the last row or column is that pixel.
        let (c, r) = (u.floor() as usize, v.floor() as usize);
        let (c1, r1) = ((c + 1).min(self.size - 1), (r + 1).min(self.size - 1));
        let (fu, fv) = (u - c as f64, v - r as f64);
        let at = |col: usize, row: usize| self.intensity[row * self.size + col];
        (1.0 - fv) * ((1.0 - fu) * at(c, r) + fu * at(c1, r))
            + fv * ((1.0 - fu) * at(c, r1) + fu * at(c1, r1))
    }
}

/// The polychromatic PSF of `maps` (wavefront, spectral weight), all centred on one reference
/// point, on the pixel grid of the one at `reference_nm` (else the first): every wavelength's
/// FFT PSF resampled (bilinear) onto that grid and summed. A monochromatic PSF here peaks at 1
/// without aberration, so its energy grows as λ²; each is scaled by weight × (λ_ref / λ)², so a
/// wavelength brings energy in proportion to its weight, and the sum is divided by the scales'
/// sum, so an aberration-free lens still peaks at 1.
pub fn polychromatic_psf(
    maps: &[(WavefrontMap, f64)],
    reference_nm: f64,
    grid: usize,
) -> Result<Psf, WaveError> {
    let reference = maps
        .iter()
        .position(|(map, _)| map.wavelength_nm == reference_nm)
        .unwrap_or(0);
    let Some((reference_map, _)) = maps.get(reference) else {
        return Err(WaveError::NoWeights);
    };
    let mut sum = psf(reference_map, grid)?;
    let grid_nm = sum.wavelength_nm;
    let mut total = vec![0.0; sum.intensity.len()];
    let mut scales = 0.0;
    for (k, (map, weight)) in maps.iter().enumerate() {
        let scale = weight * (grid_nm / map.wavelength_nm).powi(2);
        if !(scale > 0.0) {
            continue;
        }
        scales += scale;
        if k == reference {
            // Already on the grid: no second FFT, no resampling.
            for (t, v) in total.iter_mut().zip(&sum.intensity) {
                *t += scale * v;
            }
            continue;
        }
        let mono = psf(map, grid)?;
        for row in 0..sum.size {
            for col in 0..sum.size {
                let [x, y] = sum.position(col, row);
                total[row * sum.size + col] += scale * mono.sample(x, y);
            }
        }
    }
    if !(scales > 0.0) {
        return Err(WaveError::NoWeights);
    }
    sum.intensity = total.into_iter().map(|v| v / scales).collect();
    Ok(sum)
}

/// The pupil function exp(-2πi W) on the transmitted samples, zero elsewhere, row-major.
pub(crate) fn pupil_function(opd_waves: &[Option<f64>]) -> Vec<Complex<f64>> {
    opd_waves
        .iter()
        .map(|w| match w {
            Some(w) => Complex::from_polar(1.0, -std::f64::consts::TAU * w),
            None => Complex::new(0.0, 0.0),
        })
        .collect()
}

/// The PSF of `map` on a `grid` x `grid` FFT (grid at least twice the pupil sampling): pixel
/// pitch 1 / (grid × lag frequency), so a larger grid gives finer pixels over the same window.
///
/// Each transmitted sample is a plane wave whose direction grows linearly with its pupil
/// index (the affine pupil-to-direction map that [`super::fft_assumptions`] checks), so the
/// image field is an inverse DFT of the pupil function.
pub fn psf(map: &WavefrontMap, grid: usize) -> Result<Psf, WaveError> {
    let n = map.samples;
    if grid < 2 * n || grid > MAX_GRID {
        return Err(WaveError::Grid { grid, samples: n });
    }
    let pupil = pupil_function(&map.opd_waves);
    let transmitted = pupil.iter().filter(|p| p.norm_sqr() > 0.0).count() as f64;
    let mut field = vec![Complex::new(0.0, 0.0); grid * grid];
    for iy in 0..n {
        for ix in 0..n {
            field[iy * grid + ix] = pupil[iy * n + ix];
        }
    }
    let mut planner = FftPlanner::<f64>::new();
    let fft = planner.plan_fft_inverse(grid);
    for row in field.chunks_exact_mut(grid) {
        fft.process(row);
    }
    let mut column = vec![Complex::new(0.0, 0.0); grid];
    for ix in 0..grid {
        for (iy, value) in column.iter_mut().enumerate() {
            *value = field[iy * grid + ix];
        }
        fft.process(&mut column);
        for (iy, value) in column.iter().enumerate() {
            field[iy * grid + ix] = *value;
        }
    }
    // Shift the zero frequency (the reference point) to the centre pixel, mirrored where the
    // exit directions fall along the pupil axis.
    let half = grid / 2;
    let index = |pixel: usize, mirrored: bool| {
        let shifted = (pixel + grid - half) % grid;
        if mirrored {
            (grid - shifted) % grid
        } else {
            shifted
        }
    };
    let [mirror_y, mirror_x] = map.mirrored;
    let scale = 1.0 / (transmitted * transmitted);
    let mut intensity = vec![0.0; grid * grid];
    for row in 0..grid {
        for col in 0..grid {
            let source = index(row, mirror_y) * grid + index(col, mirror_x);
            intensity[row * grid + col] = field[source].norm_sqr() * scale;
        }
    }
    Ok(Psf {
        wavelength_nm: map.wavelength_nm,
        field_deg: map.field_deg,
        size: grid,
        pixel_mm: [
            1.0 / (grid as f64 * map.lag_frequency_per_mm[1]),
            1.0 / (grid as f64 * map.lag_frequency_per_mm[0]),
        ],
        intensity,
    })
}
