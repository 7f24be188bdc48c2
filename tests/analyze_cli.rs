//! `lensbake analyze` end to end: the JSON shape issue 3 specifies, its numbers against the
//! oracle, the text report, and exit status 2 with `error:` on bad input.
#![cfg(feature = "cli")]

mod common;

use common::lensbake;

use common::{assert_close, get, load_oracle, num};
use serde_json::Value;
use std::path::PathBuf;
use std::process::Output;

/// Writes `text` to a file in this test binary's scratch directory.
fn scratch_file(name: &str, text: &str) -> PathBuf {
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::write(&path, text).expect("write scratch file");
    path
}

/// The Cooke triplet as a RON lens file; each test writes its own copy (tests run in
/// parallel), under the same file stem so the report names it alike.
fn cooke_ron(test: &str) -> PathBuf {
    let oracle = load_oracle("optiland_cooke_triplet");
    let text = ron::ser::to_string_pretty(&oracle.prescription, Default::default()).unwrap();
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(test);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("cooke_triplet.ron");
    std::fs::write(&path, text).expect("write lens file");
    path
}

fn stdout_json(output: &Output) -> Value {
    assert!(
        output.status.success(),
        "lensbake failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).expect("stdout is one JSON object")
}

#[test]
fn json_has_the_issue_shape_and_the_oracle_numbers() {
    let lens = cooke_ron("json_has_the_issue_shape_and_the_oracle_numbers");
    let json = stdout_json(&lensbake(&[
        "analyze",
        lens.to_str().unwrap(),
        "--epd-mm",
        "10",
        "--field-deg",
        "20",
        "--json",
    ]));
    assert_eq!(json["lens"], "cooke_triplet");
    assert_eq!(
        num(&json["wavelength_nm"]),
        587.5618,
        "design wavelength by default"
    );
    assert_eq!(num(&json["field_deg"]), 20.0);
    assert!(json["object_distance_mm"].is_null());
    let first = &json["first_order"];
    for key in [
        "efl",
        "bfl",
        "ffl",
        "z_front_focal",
        "z_rear_focal",
        "z_front_principal",
        "z_rear_principal",
        "z_front_nodal",
        "z_rear_nodal",
        "z_paraxial_image",
        "entrance_pupil.z",
        "entrance_pupil.diameter",
        "exit_pupil.z",
        "exit_pupil.diameter",
        "f_number",
        "lagrange_invariant",
    ] {
        assert!(get(first, key).is_f64(), "first_order.{key} is a number");
    }
    assert_eq!(
        first["stop_surface"].as_u64(),
        Some(4),
        "1-based stop surface"
    );
    let oracle = load_oracle("optiland_cooke_triplet");
    let reference = get(
        oracle.lens(),
        "infinite_conjugate.first_order.optiland.lens_frame",
    );
    for (ours, theirs) in [
        ("z_rear_principal", "z_rear_principal_point"),
        ("z_front_focal", "z_front_focal_point"),
        ("exit_pupil.z", "z_exit_pupil"),
        ("exit_pupil.diameter", "exit_pupil_diameter"),
    ] {
        assert_close(
            num(get(first, ours)),
            num(get(reference, theirs)),
            1e-12,
            0.0,
            ours,
        );
    }
    let seidel = &json["seidel"];
    let expected_sums = get(oracle.lens(), "quick_reference.seidel_sums_S1_S5");
    for (j, key) in ["S1", "S2", "S3", "S4", "S5"].iter().enumerate() {
        // quick_reference is rayoptics (object at 1e10 mm): ~1e-7 relative.
        assert_close(
            num(&seidel["sums"][key]),
            num(&expected_sums[j]),
            1e-6,
            0.0,
            key,
        );
    }
    let surfaces = seidel["surfaces"].as_array().unwrap();
    assert_eq!(surfaces.len(), 6);
    for (k, surface) in surfaces.iter().enumerate() {
        assert_eq!(surface["surface"].as_u64(), Some(k as u64 + 1));
        for key in ["S1", "S2", "S3", "S4", "S5"] {
            assert!(surface[key].is_f64(), "surface {} {key}", k + 1);
        }
    }
}

#[test]
fn defaults_and_finite_object() {
    let lens = cooke_ron("defaults_and_finite_object");
    let lens = lens.to_str().unwrap();
    let json = stdout_json(&lensbake(&["analyze", lens, "--json"]));
    let first = &json["first_order"];
    // Default EPD: the stop's clear aperture (r = 3.87 mm) imaged to object space; default
    // field: the rule (largest passing real chief ray, at most 45 degrees; tests/conditions.rs).
    assert!(num(get(first, "entrance_pupil.diameter")) > 2.0 * 3.87);
    assert_eq!(json["conditions"]["field_from"], "rule");
    assert_eq!(json["conditions"]["aperture_from"], "rule");
    let field = num(&json["field_deg"]);
    assert!((field / num(&json["conditions"]["fields_deg"][0]) - 1.0).abs() < 1e-12);
    assert!(field > 20.0 && field <= 45.0);

    let json = stdout_json(&lensbake(&[
        "analyze",
        lens,
        "--object-distance-mm",
        "1000",
        "--epd-mm",
        "10",
        "--json",
    ]));
    assert_eq!(num(&json["object_distance_mm"]), 1000.0);
    let oracle = load_oracle("optiland_cooke_triplet");
    let conjugate = get(
        oracle.lens(),
        "finite_conjugate.first_order.rayoptics.raw_fod",
    );
    let first = &json["first_order"];
    assert_close(
        num(&first["magnification"]),
        num(get(conjugate, "m")),
        1e-12,
        0.0,
        "m",
    );
    assert_close(
        num(&first["working_f_number"]),
        num(get(conjugate, "fno")),
        1e-12,
        0.0,
        "fno",
    );
}

#[test]
fn text_report_has_tables_with_units() {
    let lens = cooke_ron("text_report_has_tables_with_units");
    let output = lensbake(&[
        "analyze",
        lens.to_str().unwrap(),
        "--epd-mm",
        "10",
        "--field-deg",
        "20",
    ]);
    assert!(output.status.success());
    let text = String::from_utf8(output.stdout).unwrap();
    for needle in [
        "EFL (image side, n'/power)                50.021597 mm",
        "entrance pupil z                          11.505797 mm",
        "   sum    0.0071438   -0.0012421   -0.0090385    0.0258274   -0.0017790",
        "TSA -0.035734",
        "W040 1.5198",
    ] {
        assert!(text.contains(needle), "report lacks `{needle}`:\n{text}");
    }
}

#[test]
fn bad_input_exits_2_with_an_error_line() {
    let lens = cooke_ron("bad_input_exits_2_with_an_error_line");
    let lens = lens.to_str().unwrap();
    let broken = scratch_file(
        "broken.ron",
        "(provenance: (title: \"x\"), surfaces: [ (shape: Plane, ",
    );
    let missing = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("no_such_lens.ron");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["analyze", missing.to_str().unwrap()],
            "no_such_lens.ron",
        ),
        (vec!["analyze", broken.to_str().unwrap()], "broken.ron"),
        (
            vec!["analyze", lens, "--epd-mm", "-3"],
            "entrance-pupil diameter",
        ),
        (
            vec!["analyze", lens, "--field-deg", "90"],
            "below 90 degrees",
        ),
        (vec!["analyze", lens, "--wavelength-nm", "0"], "wavelength"),
        (
            vec!["analyze", lens, "--object-distance-mm", "0"],
            "object distance",
        ),
    ];
    for (args, mention) in cases {
        let output = lensbake(&args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.starts_with("error: "), "{args:?}: {stderr}");
        assert!(
            stderr.contains(mention),
            "{args:?} should mention `{mention}`: {stderr}"
        );
        assert!(
            output.stdout.is_empty(),
            "{args:?} printed a partial report"
        );
    }
}

#[test]
fn an_object_1000_km_away_or_farther_is_at_infinity_and_nan_is_refused() {
    let image_z = |distance: Option<&str>| {
        let mut args = vec!["analyze", "dgauss-50mm", "--json"];
        if let Some(d) = distance {
            args.extend(["--object-distance-mm", d]);
        }
        let json = stdout_json(&lensbake(&args));
        (
            json["object_distance_mm"].clone(),
            json["first_order"]["z_paraxial_image"].as_f64().unwrap(),
        )
    };
    let (none, at_infinity) = image_z(None);
    assert!(none.is_null());
    for beyond in ["1e9", "1e12", "-1e30", "inf"] {
        assert_eq!(
            image_z(Some(beyond)),
            (Value::Null, at_infinity),
            "{beyond}"
        );
    }
    // Just inside the limit the object is finite, and its image lies behind the focus by
    // about f^2 / d (Newton): 50^2 / 5e8 mm = 5e-6 mm.
    let (distance, near_image) = image_z(Some("5e8"));
    assert_eq!(distance.as_f64(), Some(5e8));
    let newton = near_image - at_infinity;
    assert!((newton - 5e-6).abs() < 5e-7, "{newton}");
    let refused = lensbake(&["analyze", "dgauss-50mm", "--object-distance-mm", "NaN"]);
    assert_eq!(refused.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        stderr.contains("the object distance (mm) is NaN, not a number"),
        "{stderr}"
    );
}

/// The text report's first line gives the wavelength as the file writes it (0.5875618 um is
/// 587.5618000000001 nm in f64) and the half field as the conditions table does: positive for a
/// finite object's height, whose paraxial angle is negative by the sign convention (the JSON's
/// `field_deg` keeps that sign).
#[test]
fn the_report_header_prints_what_a_reader_wrote() {
    let path = scratch_file(
        "finite.zmx",
        "MODE SEQ\nENPD 10\nFTYP 1 0 2 1 0 0 0\nXFLN 0 0\nYFLN 0 8\nWAVM 1 0.5875618 1\n\
         SURF 0\n  DISZ 100\nSURF 1\n  STOP\n  CURV 0.02\n  DISZ 4\n  GLAS N-BK7\n  DIAM 8\n\
         SURF 2\n  CURV -0.02\n  DISZ 60\n  DIAM 8\nSURF 3\n  DISZ 0\n",
    );
    let lens = path.to_str().unwrap();
    let output = lensbake(&["analyze", lens]);
    assert_eq!(output.status.code(), Some(0));
    let text = String::from_utf8_lossy(&output.stdout).into_owned();
    let json = stdout_json(&lensbake(&["analyze", lens, "--json"]));
    let field = num(&json["field_deg"]);
    assert!(field < 0.0, "{field}");
    let header = format!(
        "wavelength 587.5618 nm   half field {:.4} deg   object 100.0000 mm before surface 1",
        -field
    );
    assert_eq!(text.lines().nth(1), Some(header.as_str()), "{text}");
}
