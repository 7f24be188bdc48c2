//! The LRTF commands end to end: `plot lrtf-error` draws exactly the measured numbers, and
//! `lrtf eval --lens` refuses a table baked from another prescription.
#![cfg(feature = "cli")]

mod common;

use common::lensbake;

use std::path::PathBuf;
use std::process::Output;

use lensbake::lrtf::measure::{IMAGE_ERROR_TARGET_PX, SweepRow};
use lensbake::plot::{Format, LrtfErrorPlot, TARGET_LABEL, render};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lensbake-lrtf-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
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
    // A lens's name, as every other plot kind takes, is told apart from a missing file.
    let o = lensbake(&[
        "plot",
        "lrtf-error",
        "dgauss-50mm",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).starts_with("error: dgauss-50mm is a bundled lens; lrtf-error plots an LRTF"),
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
    // A line per ray, as `trace` prints; `--json` (ignored before) gives the objects.
    let lines = String::from_utf8_lossy(&same.stdout).into_owned();
    assert!(lines.starts_with("ray 0: ok  position ["), "{lines}");
    let json = lensbake(&[
        "lrtf",
        "eval",
        table.to_str().unwrap(),
        "--rays",
        rays.to_str().unwrap(),
        "--json",
    ]);
    let rays_out: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    assert_eq!(rays_out[0]["status"], "ok", "{rays_out}");
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

/// A CODE V lens that states EPD 10, an object 2000 mm away and three wavelengths.
const STATED_CONDITIONS: &str = "EPD 10\nWL 656.2725 587.5618 486.1327\nREF 2\nSO 0 2000\n\
                                 S 50 5 N-BK7\nS -50 47\nSI 0 0\n";

/// Where no flag is given, a bake takes the lens file's aperture as its f-number and the file's
/// object distance as its focus, and says so; flags override both.
#[test]
fn bake_defaults_to_the_files_aperture_and_object_distance() {
    let dir = scratch("file-defaults");
    let lens = dir.join("stated.seq");
    std::fs::write(&lens, STATED_CONDITIONS).unwrap();
    let options = lensbake::prescription::formats::LoadOptions::default();
    let loaded = lensbake::lenses::load(lens.to_str().unwrap(), &options).unwrap();
    let efl = lensbake::analysis::analyze(
        &loaded.system,
        &lensbake::analysis::AnalyzeOptions::default(),
    )
    .unwrap()
    .first_order
    .efl;
    let out = dir.join("table");
    let bake = |extra: &[&str]| {
        let o = common::bake_small(&lens, &out, extra);
        assert!(o.status.success(), "{}", stderr(&o));
        (
            stderr(&o),
            lensbake::lrtf::io::read_sidecar(&out).unwrap().info,
        )
    };
    let (said, info) = bake(&[]);
    assert!(
        (info.f_number - efl / 10.0).abs() < 1e-12,
        "{}",
        info.f_number
    );
    assert_eq!(info.focus.far_mm, Some(2000.0));
    assert!(
        said.contains(&format!("f/{:.3} from the lens file", efl / 10.0)),
        "{said}"
    );
    assert!(
        said.contains("focus 2000.000 mm, the lens file's object distance"),
        "{said}"
    );

    let (said, info) = bake(&["--f-number", "8", "--focus-mm", "inf"]);
    assert_eq!((info.f_number, info.focus.far_mm), (8.0, None));
    assert!(!said.contains("from the lens file"), "{said}");
    let _ = std::fs::remove_dir_all(&dir);
}
