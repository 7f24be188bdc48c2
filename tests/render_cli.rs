//! `lensbake render` focus, shift and tilt options as a user runs them: every focus mode with
//! every lens model, three-point focus, and the errors for bad sensor settings (exit code 2).

use std::path::PathBuf;
use std::process::{Command, Output};

fn lensbake(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lensbake"))
        .args(args)
        .output()
        .expect("run lensbake")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lensbake-render-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs a small CPU render with `extra` options; returns stdout, asserting success.
fn render(dir: &std::path::Path, name: &str, extra: &[&str]) -> String {
    let out = dir.join(format!("{name}.exr"));
    let mut args = vec![
        "render",
        "--width",
        "64",
        "--height",
        "48",
        "--spp",
        "2",
        "--backend",
        "cpu",
        "--out",
    ];
    args.push(out.to_str().unwrap());
    args.extend_from_slice(extra);
    let o = lensbake(&args);
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{extra:?}: {stdout}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        out.exists() && out.with_extension("png").exists(),
        "{extra:?}"
    );
    stdout
}

/// The sensor centre z and tilt the render reports.
fn placement(stdout: &str) -> (f64, [f64; 2]) {
    let line = stdout
        .lines()
        .find(|l| l.starts_with("model "))
        .unwrap_or_else(|| panic!("no model line in {stdout}"));
    let after = |key: &str| line.split(key).nth(1).unwrap().trim_start();
    let z: f64 = after("film centre at z = ")
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    let tilt = after("tilt (").split(')').next().unwrap();
    let (x, y) = tilt.split_once(", ").unwrap();
    (z, [x.parse().unwrap(), y.parse().unwrap()])
}

#[test]
fn every_focus_mode_runs_with_every_model_and_keeps_the_sensor_tilt() {
    let dir = temp_dir("modes");
    let lens = ["--lens", "dgauss-50mm"];
    let mut sensor_z = Vec::new();
    let mut focus_z = Vec::new();
    for model in ["thin", "thick", "traced", "baked"] {
        for (mode, focus) in [
            ("sensor", vec!["--sensor-mm", "70.5"]),
            ("distance", vec!["--focus-mm", "1500"]),
            ("pixel", vec!["--focus-pixel", "40,20"]),
        ] {
            let table = dir.join(format!("table-{mode}"));
            let mut args = vec![
                "--model",
                model,
                "--tilt-deg",
                "2.5,-1.5",
                "--shift-mm",
                "1,-0.5",
            ];
            args.extend_from_slice(&lens);
            args.extend_from_slice(&focus);
            args.extend_from_slice(&["--table", table.to_str().unwrap(), "--bake-resolution", "8"]);
            let stdout = render(&dir, &format!("{model}-{mode}"), &args);
            let (z, tilt) = placement(&stdout);
            assert_eq!(tilt, [2.5, -1.5], "{model} {mode}: {stdout}");
            match mode {
                "sensor" => sensor_z.push(z),
                "distance" if model != "thin" => focus_z.push(z),
                _ => {}
            }
        }
    }
    // --sensor-mm puts every model's sensor centre there (baked through its table's focus);
    // --focus-mm gives the thick model's focus to thick, traced and baked alike.
    assert!(
        sensor_z.iter().all(|z| (z - 70.5).abs() < 1e-3),
        "{sensor_z:?}"
    );
    assert!(
        focus_z.iter().all(|z| (z - focus_z[0]).abs() < 1e-3),
        "{focus_z:?}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn three_point_focus_prints_the_tilt_and_sensor_distance() {
    let dir = temp_dir("points");
    // In the demo scene at 64 x 48: the foreground post, the chart and the back wall.
    let points = ["--focus-points", "47,40;24,24;8,8"];
    let thin = render(
        &dir,
        "thin",
        &[&["--lens", "ideal:50", "--model", "thin"][..], &points[..]].concat(),
    );
    let (z, tilt) = placement(&thin);
    assert!(
        thin.contains(&format!("sensor centre {z:.3} mm behind the first vertex")),
        "{thin}"
    );
    assert!(tilt.iter().all(|t| t.abs() > 0.5), "{thin}");
    let traced = render(
        &dir,
        "traced",
        &[
            &["--lens", "dgauss-50mm", "--model", "traced"][..],
            &points[..],
        ]
        .concat(),
    );
    for line in [
        "real-ray focus plane: tilt (",
        "paraxial focus plane: tilt (",
    ] {
        assert!(traced.contains(line), "{traced}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_sensor_settings_exit_with_code_2_and_say_why() {
    let dir = temp_dir("bad");
    let out = dir.join("x.exr");
    for (extra, says) in [
        (vec!["--focus-points", "5,5;10,5;15,5"], "one line"),
        (vec!["--focus-points", "5,5;10,5"], "three pixels"),
        (
            vec!["--focus-points", "5,5;10,5;15,9", "--tilt-deg", "1,0"],
            "cannot be used",
        ),
        (vec!["--tilt-deg=-50,0"], "within +-45"),
        (
            vec!["--tilt-deg", "0,30", "--sensor-mm", "5"],
            "reaches the lens",
        ),
    ] {
        let mut args = vec![
            "render",
            "--lens",
            "ideal:50",
            "--model",
            "thin",
            "--width",
            "64",
            "--height",
            "48",
            "--backend",
            "cpu",
            "--out",
        ];
        args.push(out.to_str().unwrap());
        args.extend_from_slice(&extra);
        let o = lensbake(&args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(stderr.contains(says), "{extra:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
    assert!(!out.exists(), "no image is written for bad settings");
    std::fs::remove_dir_all(&dir).ok();
}
