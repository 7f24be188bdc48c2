//! `lensbake wavefront`, `mtf` and `psf` end to end: JSON keys, the ideal lens's diffraction
//! limit, written images, and one `error:` line with exit code 2 for bad input.
#![cfg(feature = "cli")]

mod common;

use common::lensbake;

use common::nums;
use lensbake::wave::diffraction_limited_mtf;
use serde_json::Value;

fn json(args: &[&str]) -> Value {
    let output = lensbake(args);
    assert!(
        output.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).unwrap()
}

#[test]
fn wavefront_json_has_the_numbers_a_designer_reads() {
    let value = json(&["wavefront", "cooke-triplet", "--field-deg", "10", "--json"]);
    let rms = value["rms_waves"].as_f64().unwrap();
    let pv = value["pv_waves"].as_f64().unwrap();
    let strehl = value["strehl"].as_f64().unwrap();
    assert!(rms > 0.0 && pv > rms, "rms {rms}, pv {pv}");
    assert!((0.0..=1.0).contains(&strehl));
    let terms = value["zernike"]["terms"].as_array().unwrap();
    assert_eq!(terms.len(), 37);
    assert_eq!(value["zernike"]["ordering"], "fringe");
}

/// The analytic relay (tests/data/perfect_relay.ron) images its object point 40 mm out
/// without aberration: its axial wavefront is flat there and far from flat from infinity.
#[test]
fn wavefront_takes_the_object_distance() {
    let relay = common::test_data("perfect_relay.ron");
    let rms = |distance: &[&str]| {
        let mut args = vec![
            "wavefront",
            relay.to_str().unwrap(),
            "--field-deg",
            "0",
            "--json",
        ];
        args.extend_from_slice(distance);
        json(&args)["rms_waves"].as_f64().unwrap()
    };
    let near = rms(&["--object-distance-mm", "40"]);
    assert!(near < 1e-6, "{near} waves");
    let far = rms(&[]);
    assert!(far > 1.0, "{far} waves");
}

#[test]
fn mtf_of_an_ideal_lens_is_the_diffraction_limit() {
    let value = json(&[
        "mtf",
        "ideal:50",
        "--field-deg",
        "0",
        "--f-number",
        "4",
        "--samples",
        "256",
        "--grid",
        "512",
        "--json",
    ]);
    let cutoff = value["cutoff_per_mm"].as_f64().unwrap();
    let frequencies = nums(&value["frequencies_per_mm"]);
    assert_eq!(frequencies.len(), 41);
    let limit = nums(&value["diffraction_limit"]);
    for key in ["tangential", "sagittal"] {
        for ((f, m), d) in frequencies.iter().zip(nums(&value[key])).zip(&limit) {
            let analytic = diffraction_limited_mtf(f / cutoff);
            assert!((d - analytic).abs() < 1e-12);
            assert!(
                (m - analytic).abs() < 0.005,
                "{key} at {f}: {m} against {analytic}"
            );
        }
    }
}

#[test]
fn psf_is_written_as_exr_and_png() {
    let dir = std::env::temp_dir().join(format!("lensbake-cli-psf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["psf.exr", "psf.png"] {
        let path = dir.join(name);
        let output = lensbake(&[
            "psf",
            "cooke-triplet",
            "--field-deg",
            "5",
            "--out",
            path.to_str().unwrap(),
        ]);
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        assert!(std::fs::metadata(&path).unwrap().len() > 1000);
    }
    let image = exr::prelude::read_first_flat_layer_from_file(dir.join("psf.exr")).unwrap();
    assert_eq!(image.layer_data.size.0, 256);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_input_is_one_error_line_and_exit_code_2() {
    for args in [
        &["mtf", "ideal:-3", "--field-deg", "0"][..],
        &["mtf", "cooke-triplet", "--field-deg", "95"],
        &[
            "wavefront",
            "cooke-triplet",
            "--field-deg",
            "0",
            "--samples",
            "4",
        ],
        &[
            "wavefront",
            "cooke-triplet",
            "--field-deg",
            "0",
            "--zernike",
            "fringe",
            "--terms",
            "40",
        ],
        &[
            "psf",
            "cooke-triplet",
            "--field-deg",
            "0",
            "--out",
            "psf.jpg",
        ],
        &[
            "mtf",
            "cooke-triplet",
            "--field-deg",
            "0",
            "--wavelength-nm",
            "500",
            "--weight",
            "1",
            "--weight",
            "2",
        ],
        // Beyond the documented limits (f/1e20 panicked in the MTF's lag interpolation).
        &[
            "mtf",
            "dgauss-50mm",
            "--field-deg",
            "5",
            "--f-number",
            "1e20",
        ],
        &[
            "mtf",
            "dgauss-50mm",
            "--field-deg",
            "5",
            "--f-number",
            "0.3",
        ],
        &[
            "psf",
            "dgauss-50mm",
            "--field-deg",
            "0",
            "--epd-mm",
            "1e-320",
        ],
        // A length every command takes, but a pupil slower than f/1000 (about f/50000).
        &["mtf", "dgauss-50mm", "--field-deg", "0", "--epd-mm", "1e-3"],
        // An ideal lens images infinity only; a distance must be a number.
        &[
            "wavefront",
            "ideal:50",
            "--field-deg",
            "0",
            "--object-distance-mm",
            "100",
        ],
        &[
            "wavefront",
            "cooke-triplet",
            "--field-deg",
            "0",
            "--object-distance-mm",
            "nan",
        ],
    ] {
        let output = lensbake(args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.starts_with("error: "), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

/// What the user reads is a sentence: a broken FFT assumption names the measured size, its
/// limit and the flag that mends it (it printed as a JSON object), and a stopped chief ray says
/// where it stopped (it printed as `Missed { surface: 9 }`).
#[test]
fn notes_and_errors_read_as_sentences() {
    let output = lensbake(&[
        "mtf",
        "dgauss-50mm",
        "--field-deg",
        "20",
        "--samples",
        "8",
        "--grid",
        "16",
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(0), "{stderr}");
    let note = stderr
        .lines()
        .find(|l| l.contains("pupil samples differ"))
        .unwrap_or_else(|| panic!("{stderr}"));
    assert!(
        note.starts_with(
            "note: the FFT's assumptions fail here: neighbouring pupil samples differ by "
        ) && note.ends_with(" waves (limit 0.5), so the phase aliases; raise --samples"),
        "{note}"
    );
    let unwritten =
        std::env::temp_dir().join(format!("lensbake-unwritten-{}.exr", std::process::id()));
    let output = lensbake(&[
        "psf",
        "fisheye-10mm",
        "--field-deg",
        "60",
        "--out",
        unwritten.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.starts_with("error: ")
            && stderr.contains("the real chief ray does not reach the image (missed surface 9)"),
        "{stderr}"
    );
    assert!(!unwritten.exists());
}
