//! The `lensbake trace` and `lensbake bench trace` commands, end to end.
#![cfg(feature = "cli")]

mod common;

use common::{load_oracle, vec3};
use lensbake::system::LensSystem;
use lensbake::trace::{Ray, Tracer, Travel};
use serde_json::Value;
use std::path::PathBuf;
use std::process::{Command, Output};

/// The oracle's 50 mm double Gauss written as a RON lens file in a fresh temporary directory.
fn lens_file(tag: &str) -> (PathBuf, Value) {
    let oracle = load_oracle("pbrt_dgauss_50mm");
    let dir = std::env::temp_dir().join(format!("lensbake-cli-trace-{}-{tag}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("dgauss50.ron");
    std::fs::write(&path, ron::to_string(&oracle.prescription).unwrap()).unwrap();
    (path, oracle.lens().clone())
}

fn lensbake(args: &[&str], stdin: Option<&str>) -> Output {
    common::finished(
        Command::new(env!("CARGO_BIN_EXE_lensbake")).args(args),
        stdin,
    )
}

#[test]
fn trace_json_matches_library_forward_and_backward() {
    let (path, lens) = lens_file("both");
    let system =
        LensSystem::from_prescription(load_oracle("pbrt_dgauss_50mm").prescription).unwrap();
    let tracer = Tracer::new(&system.at(system.design_wavelength_nm()));
    for (travel, key, start) in [
        (Travel::Forward, "infinite_conjugate", "start_point"),
        (Travel::Backward, "sensor_side_rays", "sensor_point"),
    ] {
        let records = match travel {
            Travel::Forward => lens[key]["real_rays"]["rays"].as_array().unwrap(),
            Travel::Backward => lens[key]["rays"].as_array().unwrap(),
        };
        let rays: Vec<Ray> = records
            .iter()
            .map(|r| Ray::new(vec3(&r[start]), vec3(&r["start_dir"])).unwrap())
            .collect();
        // The oracle's numbers as they are: the command must build the same rays from them.
        let input: Vec<Value> = records
            .iter()
            .map(|r| serde_json::json!({"origin": r[start], "direction": r["start_dir"]}))
            .collect();
        let mut args = vec!["trace", path.to_str().unwrap(), "--rays", "-", "--json"];
        if travel == Travel::Backward {
            args.push("--backward");
        }
        let out = lensbake(&args, Some(&Value::from(input).to_string()));
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let printed: Vec<Value> = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(printed.len(), rays.len());
        let mut statuses = std::collections::HashSet::new();
        for (ray, object) in rays.iter().zip(&printed) {
            let traced = tracer.trace(*ray, travel);
            assert_eq!(object["status"], traced.outcome.status());
            statuses.insert(traced.outcome.status());
            match traced.outcome.surface() {
                Some(s) => assert_eq!(object["surface"], s),
                None => assert!(object["surface"].is_null()),
            }
            // JSON numbers round-trip f64 exactly.
            assert_eq!(vec3(&object["position"]), traced.ray.position());
            assert_eq!(vec3(&object["direction"]), traced.ray.direction());
        }
        assert!(statuses.len() >= 2, "{travel:?}: several outcomes covered");
    }
}

#[test]
fn trace_rejects_bad_rays_with_exit_2() {
    let (path, _) = lens_file("bad");
    let path = path.to_str().unwrap();
    for (input, expected) in [
        (
            r#"[{"origin": [0, 0, -5], "direction": [0, 0, 0]}]"#,
            "ray 0",
        ),
        (r#"[{"origin": [0, 0, -5]}]"#, "direction"),
        ("not json", "<stdin>"),
    ] {
        let out = lensbake(&["trace", path, "--rays", "-", "--json"], Some(input));
        assert_eq!(out.status.code(), Some(2));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.starts_with("error: ") && stderr.contains(expected),
            "{stderr}"
        );
        assert!(out.stdout.is_empty());
    }
    let out = lensbake(
        &["trace", path, "--rays", "-", "--wavelength-nm", "-3"],
        Some("[]"),
    );
    assert_eq!(out.status.code(), Some(2));
    let out = lensbake(
        &["trace", "/nonexistent/lens.ron", "--rays", "-"],
        Some("[]"),
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/lens.ron"));
}

#[test]
fn bench_trace_reports_rays_and_intersections() {
    let (path, lens) = lens_file("bench");
    let out = lensbake(
        &[
            "bench",
            "trace",
            path.to_str().unwrap(),
            "--rays",
            "20000",
            "--threads",
            "1",
            "--json",
        ],
        None,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["rays"], 20000);
    let surfaces = report["ray_surfaces"].as_u64().unwrap();
    // Every ray meets surface 1; none meets more than all 11.
    assert!((20_000..=220_000).contains(&surfaces), "{surfaces}");
    assert!(report["seconds"].as_f64().unwrap() > 0.0);
    assert!(report["seconds_new_output"].as_f64().unwrap() > 0.0);
    // The bundle it drew from, for side-by-side scripts to draw the same: the oracle's paraxial
    // entrance pupil (measured within 7e-15 mm), the start plane one semi-aperture and 1 mm
    // before surface 1, and the traceable field (between the last field the oracle traced and
    // the first it could not).
    let bundle = &report["bundle"];
    let quick = &lens["quick_reference"];
    let number = |value: &Value| value.as_f64().unwrap();
    let close = |key: &str, truth: f64| {
        let value = number(&bundle[key]);
        assert!(
            (value - truth).abs() <= 1e-12,
            "{key}: {value} against {truth}"
        );
    };
    close("entrance_pupil_z", number(&quick["z_entrance_pupil"]));
    close("entrance_pupil_diameter", number(&quick["epd"]));
    let field = &lens["infinite_conjugate"]["max_field_with_traceable_chief_ray"]["with_apertures"];
    let max_field = number(&bundle["max_field_deg"]);
    assert!(
        (number(&field["last_ok_deg"])..=number(&field["first_fail_deg"])).contains(&max_field),
        "{max_field}"
    );
    let first = &lens["prescription"]["surfaces"][0];
    close(
        "start_z",
        number(&first["vertex_z"]) - number(&first["semi_aperture"]) - 1.0,
    );
}

/// Standard input is held to the input limit (1 GiB) like a file: an endless stream is refused
/// with one error line instead of filling the memory.
#[cfg(unix)]
#[test]
fn an_endless_standard_input_is_refused_at_the_input_limit() {
    let zeros = std::fs::File::open("/dev/zero").unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_lensbake"))
        .args(["trace", "dgauss-50mm", "--rays", "-"])
        .stdin(zeros)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.starts_with("error: cannot read rays from standard input")
            && stderr.contains("input limit"),
        "{stderr}"
    );
}
