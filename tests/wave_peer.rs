//! Wavefront RMS and FFT MTF against optiland 0.6.3 on the truth-data lenses
//! (tests/data/wave/optiland_wave.json, written by benches/peer/peer_wave.py), at the same
//! sampling: 64 pupil samples per side (optiland's FFTMTF num_rays=128, its OPD on a 64-point
//! uniform grid).

mod common;

use common::{nums, oracle_json, oracle_prescription, test_data};
use lensbake::prescription::RayAiming;
use lensbake::system::LensSystem;
use lensbake::wave::{FieldTrace, PupilTrace, Sampling, Spectrum, WaveLens};
use serde_json::Value;

/// RMS wavefront error: relative tolerance.
const RMS_RELATIVE: f64 = 0.03;
/// The lens whose MTF table the test prints (run with --nocapture).
const TABLE_LENS: &str = "optiland_cooke_triplet";
/// MTF: absolute tolerance.
const MTF_ABSOLUTE: f64 = 0.02;

fn peer() -> Value {
    let path = test_data("wave/optiland_wave.json");
    let text = std::fs::read_to_string(&path).expect("peer data is readable");
    serde_json::from_str(&text).expect("peer data is JSON")
}

fn sampling(peer: &Value) -> Sampling {
    Sampling {
        samples: peer["opd_samples"].as_u64().unwrap() as usize,
        grid: 4 * peer["opd_samples"].as_u64().unwrap() as usize,
    }
}

fn system(record: &Value) -> LensSystem {
    let oracle = oracle_json(record["oracle"].as_str().unwrap());
    LensSystem::from_prescription(oracle_prescription(&oracle["lenses"][0])).unwrap()
}

/// Calls `check(lens name, system, EPD, wavelength, field, expected)` for every peer field.
fn each_field(mut check: impl FnMut(&str, &LensSystem, f64, f64, f64, &Value)) {
    let peer = peer();
    for record in peer["lenses"].as_array().unwrap() {
        let name = record["lens"].as_str().unwrap();
        let system = system(record);
        let epd_mm = record["epd_mm"].as_f64().unwrap();
        let wavelength_nm = record["wavelength_nm"].as_f64().unwrap();
        for field in record["fields"].as_array().unwrap() {
            let field_deg = field["field_deg"].as_f64().unwrap();
            check(name, &system, epd_mm, wavelength_nm, field_deg, field);
        }
    }
}

#[test]
fn rms_wavefront_error_matches_optiland_within_three_percent() {
    let peer = peer();
    let sampling = sampling(&peer);
    let mut worst: f64 = 0.0;
    each_field(|name, system, epd_mm, wavelength_nm, field_deg, expected| {
        let lens = WaveLens::Real {
            system,
            epd_mm: Some(epd_mm),
            object_distance_mm: None,
            ray_aiming: RayAiming::Paraxial,
        };
        let trace = PupilTrace::trace(&lens, field_deg, wavelength_nm, wavelength_nm, sampling)
            .unwrap_or_else(|e| panic!("{name} at {field_deg}°: {e}"));
        let stats = trace.wavefront(0.0).unwrap().stats();
        let theirs = expected["rms_waves_piston_removed"].as_f64().unwrap();
        let error = (stats.rms_waves - theirs).abs() / theirs;
        worst = worst.max(error);
        assert!(
            error <= RMS_RELATIVE,
            "{name} at {field_deg}°: RMS {} waves, optiland {theirs}",
            stats.rms_waves
        );
        assert_eq!(
            stats.transmitted_samples as u64,
            expected["transmitted_samples"].as_u64().unwrap(),
            "{name} at {field_deg}°: vignetting differs"
        );
    });
    eprintln!("largest relative RMS difference: {worst:.2e}");
}

#[test]
fn fft_mtf_matches_optiland_within_0_02() {
    let peer = peer();
    let sampling = sampling(&peer);
    let mut worst: f64 = 0.0;
    for record in peer["lenses"].as_array().unwrap() {
        let name = record["lens"].as_str().unwrap();
        let system = system(record);
        let lens = WaveLens::Real {
            system: &system,
            epd_mm: record["epd_mm"].as_f64(),
            object_distance_mm: None,
            ray_aiming: RayAiming::Paraxial,
        };
        let spectrum = Spectrum::monochromatic(record["wavelength_nm"].as_f64().unwrap());
        for field in record["fields"].as_array().unwrap() {
            let field_deg = field["field_deg"].as_f64().unwrap();
            let trace = FieldTrace::new(&lens, field_deg, &spectrum, sampling).unwrap();
            for axis in ["tangential", "sagittal"] {
                // optiland's own frequency samples (whole pupil lags): no interpolation on
                // either side.
                let frequencies = nums(&field["mtf"][axis]["frequencies_per_mm"]);
                let theirs = nums(&field["mtf"][axis]["mtf"]);
                let mtf = trace.mtf(0.0, &frequencies).unwrap();
                let ours = if axis == "tangential" {
                    &mtf.tangential
                } else {
                    &mtf.sagittal
                };
                for ((f, a), b) in frequencies.iter().zip(ours).zip(&theirs) {
                    worst = worst.max((a - b).abs());
                    if name == TABLE_LENS {
                        eprintln!(
                            "{name} {field_deg:.1}° {axis} {f:.2} cycles/mm: lensbake {a:.5}, optiland {b:.5}"
                        );
                    }
                    assert!(
                        (a - b).abs() <= MTF_ABSOLUTE,
                        "{name} at {field_deg}°, {axis} at {f} cycles/mm: {a} against optiland {b}"
                    );
                }
            }
        }
    }
    eprintln!("largest MTF difference: {worst:.2e}");
}
