//! The LRTF commands end to end: `plot lrtf-error` draws exactly the measured numbers, and
//! `lrtf eval --lens` refuses a table baked from another prescription.

use std::path::PathBuf;
use std::process::{Command, Output};

use lensbake::lrtf::measure::{IMAGE_ERROR_TARGET_PX, SweepRow};
use lensbake::plot::{Format, LrtfErrorPlot, TARGET_LABEL, render};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lensbake-lrtf-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn lensbake(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lensbake"))
        .args(args)
        .output()
        .expect("run lensbake")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn committed_measurements() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("notebooks-out/lrtf/lrtf-error.json")
}

#[test]
fn error_plot_draws_every_measured_p99_and_the_target() {
    let text = std::fs::read_to_string(committed_measurements()).unwrap();
    let rows: Vec<SweepRow> = serde_json::from_str(&text).unwrap();
    assert!(
        rows.len() >= 12,
        "the sweep covers 3 lenses x 2 parameterisations x 2 precisions"
    );
    let rendered = render(&LrtfErrorPlot::from_sweep(&rows), Format::Png).unwrap();
    let drawn = rendered.drawn;
    for row in &rows {
        let label = format!("{} {}", row.parameterisation, row.precision);
        let series = drawn
            .series(&row.lens, &label)
            .unwrap_or_else(|| panic!("no series {label} in the {} panel", row.lens));
        let expected = (row.resolution as f64, row.error.image_px.p99.log10());
        assert!(
            series.points.contains(&expected),
            "{} {label}: {expected:?} not in {:?}",
            row.lens,
            series.points
        );
        let target = drawn.series(&row.lens, TARGET_LABEL).unwrap();
        assert!(
            target
                .points
                .iter()
                .all(|p| p.1 == IMAGE_ERROR_TARGET_PX.log10())
        );
    }
    // Resolutions ascend along every curve, so the lines read left to right.
    for panel in &drawn.panels {
        for s in &panel.series {
            assert!(s.points.windows(2).all(|w| w[0].0 < w[1].0), "{s:?}");
        }
    }
}

#[test]
fn plot_lrtf_error_writes_a_png_and_rejects_other_json() {
    let dir = scratch("plot");
    let out = dir.join("lrtf-error.png");
    let measurements = committed_measurements();
    let o = lensbake(&[
        "plot",
        "lrtf-error",
        measurements.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::read(&out).unwrap().starts_with(b"\x89PNG"));
    let wrong = dir.join("wrong.json");
    std::fs::write(&wrong, "[{\"lens\": 3}]").unwrap();
    let o = lensbake(&[
        "plot",
        "lrtf-error",
        wrong.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("not an LRTF measurement table"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn eval_with_a_lens_checks_the_prescription_hash() {
    let dir = scratch("eval");
    let table = dir.join("dgauss");
    let o = lensbake(&[
        "bake",
        "dgauss-50mm",
        "--resolution",
        "6",
        "--out",
        table.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rays = dir.join("rays.json");
    std::fs::write(
        &rays,
        r#"[{"origin": [1.0, 0.0, 90.0], "direction": [0.0, 0.0, -1.0]}]"#,
    )
    .unwrap();
    let eval = |lens: &str| {
        lensbake(&[
            "lrtf",
            "eval",
            table.to_str().unwrap(),
            "--rays",
            rays.to_str().unwrap(),
            "--lens",
            lens,
        ])
    };
    let same = eval("dgauss-50mm");
    assert!(same.status.success(), "{}", stderr(&same));
    let other = eval("fisheye-10mm");
    assert_eq!(other.status.code(), Some(2));
    let message = stderr(&other);
    assert!(
        message.starts_with("error: ") && message.contains("different prescription"),
        "{message}"
    );
    assert!(
        message.contains("lensbake bake dgauss-50mm --out"),
        "{message}"
    );
}
