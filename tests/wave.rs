//! Wave optics against analytic identities: the ideal lens's MTF is the diffraction-limited
//! curve, its wavefront is flat and its Strehl ratio 1; defocus, Zernike fits, Maréchal, FFT
//! against Huygens, and typed errors for bad input.

use lensbake::lenses;
use lensbake::prescription::RayAiming;
use lensbake::prescription::formats::LoadOptions;
use lensbake::wave::{
    FieldTrace, PupilTrace, Sampling, Spectrum, WaveError, WaveLens, WavefrontMap, ZernikeOrdering,
    diffraction_limited_mtf, fft_assumptions, frequencies_to, huygens_psf, psf, zernike_fit,
};

const IDEAL: WaveLens = WaveLens::Ideal {
    efl_mm: 50.0,
    f_number: 4.0,
};
const WAVELENGTH_NM: f64 = 550.0;

fn ideal_trace(field_deg: f64, samples: usize) -> PupilTrace {
    PupilTrace::trace(
        &IDEAL,
        field_deg,
        WAVELENGTH_NM,
        WAVELENGTH_NM,
        Sampling {
            samples,
            grid: 2 * samples,
        },
    )
    .unwrap()
}

#[test]
fn ideal_lens_mtf_is_the_diffraction_limited_curve() {
    let spectrum = Spectrum::monochromatic(WAVELENGTH_NM);
    let sampling = Sampling {
        samples: 256,
        grid: 512,
    };
    for field_deg in [0.0, 15.0] {
        let trace = FieldTrace::new(&IDEAL, field_deg, &spectrum, sampling).unwrap();
        let cutoff = 1.0 / (WAVELENGTH_NM * 1e-6 * 4.0);
        assert!((trace.reference().cutoff_per_mm - cutoff).abs() < 1e-9 * cutoff);
        let frequencies = frequencies_to(cutoff, 101);
        let mtf = trace.mtf(0.0, &frequencies).unwrap();
        for (i, f) in frequencies.iter().enumerate() {
            let analytic = diffraction_limited_mtf(f / cutoff);
            assert!((mtf.diffraction_limit[i] - analytic).abs() < 1e-12);
            for (axis, value) in [("T", mtf.tangential[i]), ("S", mtf.sagittal[i])] {
                assert!(
                    (value - analytic).abs() < 0.005,
                    "{axis} at {f:.1} cycles/mm ({field_deg}°): {value} against {analytic}"
                );
            }
        }
    }
}

#[test]
fn ideal_lens_wavefront_is_flat_and_its_strehl_one() {
    let map = ideal_trace(10.0, 64).wavefront(0.0).unwrap();
    let stats = map.stats();
    assert!(stats.rms_waves < 1e-9 && stats.pv_waves < 1e-9, "{stats:?}");
    assert!((stats.strehl - 1.0).abs() < 1e-12);
    assert_eq!(stats.transmitted_samples, stats.pupil_samples);
    let image = psf(&map, 128).unwrap();
    assert!((image.peak() - 1.0).abs() < 1e-9, "peak {}", image.peak());
    assert!(fft_assumptions(&map, 128).is_empty());
}

#[test]
fn defocus_gives_the_spherical_path_difference() {
    // Moving the reference sphere's centre by dz along the axis changes each ray's path by
    // dz (1 - cos U) to first order in dz.
    let dz = 0.005;
    let trace = ideal_trace(0.0, 64);
    let map = trace.wavefront(dz).unwrap();
    let wavelength_mm = WAVELENGTH_NM * 1e-6;
    let expected: Vec<f64> = map
        .transmitted()
        .map(|(x, y, _)| {
            let sin_u = x.hypot(y) / (2.0 * 4.0);
            dz * (1.0 - (1.0 - sin_u * sin_u).sqrt()) / wavelength_mm
        })
        .collect();
    for ((_, _, w), e) in map.transmitted().zip(&expected) {
        // OPD = OPL(chief) - OPL(ray): the marginal rays are short of the shifted sphere.
        assert!((w - e).abs() < 2e-3 * e.abs().max(1e-3), "{w} against {e}");
    }
    // Through focus the ideal lens is symmetric about its focus, where it peaks.
    let spectrum = Spectrum::monochromatic(WAVELENGTH_NM);
    let field = FieldTrace::new(&IDEAL, 0.0, &spectrum, Sampling::default()).unwrap();
    let curve = field
        .through_focus(100.0, &[-0.04, -0.02, 0.0, 0.02, 0.04])
        .unwrap();
    assert!(
        (curve.tangential[0] - curve.tangential[4]).abs() < 2e-3,
        "{curve:?}"
    );
    assert!(
        (curve.tangential[1] - curve.tangential[3]).abs() < 2e-3,
        "{curve:?}"
    );
    assert!(curve.tangential[2] > curve.tangential[1]);
    assert!(curve.tangential[1] > curve.tangential[0]);
}

/// A wavefront map from a function of the pupil coordinates.
fn synthetic(samples: usize, opd: impl Fn(f64, f64) -> f64) -> WavefrontMap {
    let mut map = ideal_trace(0.0, samples).wavefront(0.0).unwrap();
    let n = samples;
    for (i, w) in map.opd_waves.iter_mut().enumerate() {
        if w.is_some() {
            let x = -1.0 + 2.0 * (i % n) as f64 / (n - 1) as f64;
            let y = -1.0 + 2.0 * (i / n) as f64 / (n - 1) as f64;
            *w = Some(opd(x, y));
        }
    }
    map
}

#[test]
fn zernike_fit_recovers_the_terms_it_was_made_of() {
    let coefficients = [(4, 0.3), (7, -0.12), (9, 0.05), (12, 0.02)];
    for ordering in [ZernikeOrdering::Fringe, ZernikeOrdering::Standard] {
        let map = synthetic(64, |x, y| {
            coefficients
                .iter()
                .map(|&(j, c)| c * ordering.value(j, x.hypot(y), y.atan2(x)))
                .sum()
        });
        let fit = zernike_fit(&map, ordering, 37).unwrap();
        for term in &fit.terms {
            let expected = coefficients
                .iter()
                .find(|c| c.0 == term.j)
                .map_or(0.0, |c| c.1);
            assert!(
                (term.waves - expected).abs() < 1e-9,
                "{ordering:?} Z{}: {} against {expected}",
                term.j,
                term.waves
            );
        }
        assert!(fit.residual_rms_waves < 1e-9);
    }
    // Standard terms are RMS-normalised: one term alone has an RMS equal to its coefficient
    // (to the grid's quadrature error).
    let map = synthetic(128, |x, y| {
        0.1 * ZernikeOrdering::Standard.value(11, x.hypot(y), 0.0)
    });
    let rms = map.stats().rms_waves;
    assert!((rms - 0.1).abs() < 2e-3, "{rms}");
}

#[test]
fn strehl_follows_marechal_for_small_aberrations() {
    // Primary spherical of 0.05 waves RMS: Strehl ≈ exp(-(2π σ)²), within about 1 %.
    let map = synthetic(128, |x, y| {
        0.05 * ZernikeOrdering::Standard.value(11, x.hypot(y), y.atan2(x))
    });
    let stats = map.stats();
    let marechal = (-(std::f64::consts::TAU * stats.rms_waves).powi(2)).exp();
    assert!(
        (stats.strehl - marechal).abs() < 0.01,
        "Strehl {} against Maréchal {marechal}",
        stats.strehl
    );
    // The PSF peak is the same number when the peak falls on a pixel (no tilt).
    let image = psf(&map, 256).unwrap();
    assert!(
        (image.peak() - stats.strehl).abs() < 1e-9,
        "{}",
        image.peak()
    );
}

#[test]
fn fft_and_huygens_psf_agree_on_a_real_lens() {
    let system = lenses::load("cooke-triplet", &LoadOptions::default())
        .unwrap()
        .system;
    let wavelength = system.design_wavelength_nm();
    let lens = WaveLens::Real {
        system: &system,
        epd_mm: None,
        object_distance_mm: None,
        ray_aiming: RayAiming::Paraxial,
    };
    let trace = PupilTrace::trace(&lens, 5.0, wavelength, wavelength, Sampling::default()).unwrap();
    let map = trace.wavefront(0.0).unwrap();
    let fft = psf(&map, 256).unwrap();
    let direct = huygens_psf(&map, 256, fft.pixel_mm).unwrap();
    let peak = fft.peak();
    let worst = fft
        .intensity
        .iter()
        .zip(&direct.intensity)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        worst < 0.05 * peak,
        "largest difference {worst} of peak {peak}"
    );
    // Both put the light where the geometric rays land: same centroid within a pixel.
    let centroid = |p: &lensbake::wave::Psf| {
        let total: f64 = p.intensity.iter().sum();
        let mut c = [0.0; 2];
        for row in 0..p.size {
            for col in 0..p.size {
                let [x, y] = p.position(col, row);
                c[0] += x * p.intensity[row * p.size + col] / total;
                c[1] += y * p.intensity[row * p.size + col] / total;
            }
        }
        c
    };
    let (a, b) = (centroid(&fft), centroid(&direct));
    assert!((a[1] - b[1]).abs() < fft.pixel_mm[1], "{a:?} against {b:?}");
    let rays: Vec<[f64; 2]> = map.image_points_mm.iter().flatten().copied().collect();
    let ray_y = rays.iter().map(|p| p[1]).sum::<f64>() / rays.len() as f64;
    assert!(
        (a[1] - ray_y).abs() < 2.0 * fft.pixel_mm[1],
        "PSF {a:?}, rays {ray_y}"
    );
}

#[test]
fn polychromatic_psf_weights_energy_and_keeps_the_aberration_free_peak() {
    let sampling = Sampling {
        samples: 32,
        grid: 128,
    };
    let field = |wavelengths: Vec<f64>, weights: Vec<f64>| {
        FieldTrace::new(
            &IDEAL,
            0.0,
            &Spectrum::new(wavelengths, weights, 0).unwrap(),
            sampling,
        )
        .unwrap()
    };
    let energy =
        |p: &lensbake::wave::Psf| p.intensity.iter().sum::<f64>() * p.pixel_mm[0] * p.pixel_mm[1];
    // One wavelength given twice is that wavelength's PSF.
    let mono = field(vec![550.0], vec![1.0])
        .psf(0.0, sampling.grid)
        .unwrap();
    let twice = field(vec![550.0, 550.0], vec![1.0, 3.0])
        .psf(0.0, sampling.grid)
        .unwrap();
    assert_eq!(mono.pixel_mm, twice.pixel_mm);
    for (a, b) in mono.intensity.iter().zip(&twice.intensity) {
        assert!((a - b).abs() < 1e-12, "{a} {b}");
    }
    // Three wavelengths through an aberration-free lens: every one peaks at 1 on the shared
    // centre, so the sum does too; each brings energy in proportion to its weight.
    let (wavelengths, weights) = (vec![550.0, 450.0, 650.0], vec![2.0, 1.0, 1.0]);
    let poly = field(wavelengths.clone(), weights.clone())
        .psf(0.0, sampling.grid)
        .unwrap();
    let centre = poly.intensity[(poly.size / 2) * poly.size + poly.size / 2];
    assert!((centre - 1.0).abs() < 1e-9, "peak {centre}");
    let scales: f64 = wavelengths
        .iter()
        .zip(&weights)
        .map(|(nm, w)| w * (550.0 / nm).powi(2))
        .sum();
    let expected = energy(&mono) * weights.iter().sum::<f64>() / scales;
    let measured = energy(&poly);
    assert!(
        (measured / expected - 1.0).abs() < 0.02,
        "energy {measured}, expected {expected}"
    );
    // And it lies between the blue and the red PSF: broader than blue, narrower than red.
    let at = |p: &lensbake::wave::Psf, r_mm: f64| p.sample(r_mm, 0.0);
    let first_dark_550 = 1.22 * 550e-6 * 4.0;
    let blue = field(vec![450.0], vec![1.0])
        .psf(0.0, sampling.grid)
        .unwrap();
    let red = field(vec![650.0], vec![1.0])
        .psf(0.0, sampling.grid)
        .unwrap();
    let half = 0.5 * first_dark_550;
    assert!(at(&blue, half) < at(&poly, half) && at(&poly, half) < at(&red, half));
}

#[test]
fn polychromatic_mtf_of_one_repeated_wavelength_is_the_monochromatic_one() {
    let system = lenses::load("cooke-triplet", &LoadOptions::default())
        .unwrap()
        .system;
    let lens = WaveLens::Real {
        system: &system,
        epd_mm: None,
        object_distance_mm: None,
        ray_aiming: RayAiming::Paraxial,
    };
    let frequencies = [10.0, 40.0, 80.0];
    let mono = FieldTrace::new(
        &lens,
        10.0,
        &Spectrum::monochromatic(550.0),
        Sampling::default(),
    )
    .unwrap()
    .mtf(0.0, &frequencies)
    .unwrap();
    let spectrum = Spectrum::new(vec![550.0, 550.0], vec![1.0, 3.0], 0).unwrap();
    let poly = FieldTrace::new(&lens, 10.0, &spectrum, Sampling::default())
        .unwrap()
        .mtf(0.0, &frequencies)
        .unwrap();
    for i in 0..frequencies.len() {
        assert!((mono.tangential[i] - poly.tangential[i]).abs() < 1e-12);
        assert!((mono.sagittal[i] - poly.sagittal[i]).abs() < 1e-12);
    }
    // Colour can only lower the weighted OTF's modulus below the best channel's.
    let spectrum = Spectrum::new(vec![550.0, 486.1, 656.3], vec![2.0, 1.0, 1.0], 0).unwrap();
    let colour = FieldTrace::new(&lens, 10.0, &spectrum, Sampling::default())
        .unwrap()
        .mtf(0.0, &frequencies)
        .unwrap();
    assert!(colour.tangential.iter().all(|v| (0.0..=1.0).contains(v)));
}

#[test]
fn geometric_mtf_of_a_perfect_focus_is_one() {
    let field = FieldTrace::new(
        &IDEAL,
        0.0,
        &Spectrum::monochromatic(WAVELENGTH_NM),
        Sampling::default(),
    )
    .unwrap();
    let mtf = field.geometric_mtf(0.0, &[10.0, 100.0, 400.0]).unwrap();
    assert!(
        mtf.tangential
            .iter()
            .chain(&mtf.sagittal)
            .all(|v| (v - 1.0).abs() < 1e-9)
    );
}

#[test]
fn bad_input_is_a_typed_error() {
    let trace = |lens: &WaveLens, field: f64, sampling: Sampling| {
        PupilTrace::trace(lens, field, WAVELENGTH_NM, WAVELENGTH_NM, sampling)
    };
    assert!(matches!(
        trace(
            &IDEAL,
            0.0,
            Sampling {
                samples: 4,
                grid: 8
            }
        ),
        Err(WaveError::Samples { .. })
    ));
    assert!(matches!(
        trace(
            &IDEAL,
            0.0,
            Sampling {
                samples: 64,
                grid: 100
            }
        ),
        Err(WaveError::Grid { .. })
    ));
    assert!(trace(&IDEAL, 95.0, Sampling::default()).is_err());
    let too_fast = WaveLens::Ideal {
        efl_mm: 50.0,
        f_number: 0.4,
    };
    assert!(matches!(
        trace(&too_fast, 0.0, Sampling::default()),
        Err(WaveError::NotPositive { .. })
    ));
    let system = lenses::load("cooke-triplet", &LoadOptions::default())
        .unwrap()
        .system;
    let wide = WaveLens::Real {
        system: &system,
        epd_mm: Some(-1.0),
        object_distance_mm: None,
        ray_aiming: RayAiming::Paraxial,
    };
    assert!(matches!(
        trace(&wide, 0.0, Sampling::default()),
        Err(WaveError::NotPositive { .. })
    ));
    // A pupil slower than f/1000, given as an f-number or as a diameter (1 um on a 50 mm lens:
    // f/50000), is refused as a limit; f/1000 itself traces.
    let slow_ideal = |f_number| WaveLens::Ideal {
        efl_mm: 50.0,
        f_number,
    };
    assert!(matches!(
        trace(&slow_ideal(1000.5), 0.0, Sampling::default()),
        Err(WaveError::Limit(_))
    ));
    assert!(trace(&slow_ideal(1000.0), 0.0, Sampling::default()).is_ok());
    let dgauss = lenses::load("dgauss-50mm", &LoadOptions::default())
        .unwrap()
        .system;
    let pinhole = |epd_mm| WaveLens::Real {
        system: &dgauss,
        epd_mm: Some(epd_mm),
        object_distance_mm: None,
        ray_aiming: RayAiming::Paraxial,
    };
    assert!(matches!(
        trace(&pinhole(1e-3), 0.0, Sampling::default()),
        Err(WaveError::Limit(_))
    ));
    assert!(trace(&pinhole(0.06), 0.0, Sampling::default()).is_ok());
    assert!(Spectrum::new(vec![550.0], vec![0.0], 0).is_err());
    assert!(Spectrum::new(vec![550.0], vec![f64::NAN], 0).is_err());
}
