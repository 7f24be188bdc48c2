//! `lensbake plot` and `lensbake report` end to end: exit codes, files, report contents.
#![cfg(feature = "cli")]

mod common;

use common::lensbake;

use std::path::{Path, PathBuf};
use std::process::Output;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lensbake-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The Cooke triplet of the truth data as a native lens file.
fn cooke_file(dir: &Path) -> PathBuf {
    let prescription = common::load_oracle("optiland_cooke_triplet").prescription;
    let path = dir.join("cooke.ron");
    std::fs::write(
        &path,
        ron::ser::to_string_pretty(&prescription, Default::default()).unwrap(),
    )
    .unwrap();
    path
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn plot_writes_the_requested_format() {
    let dir = scratch("plot");
    let lens = cooke_file(&dir);
    for file in ["layout.png", "layout.svg"] {
        let out = dir.join(file);
        let output = lensbake(&[
            "plot",
            "layout",
            lens.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(output.status.success(), "{}", stderr(&output));
        let bytes = std::fs::read(&out).unwrap();
        if file.ends_with(".png") {
            assert_eq!(&bytes[1..4], b"PNG");
        } else {
            assert!(String::from_utf8(bytes).unwrap().contains("cooke: layout"));
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_requests_exit_2_with_a_clear_error_and_no_file() {
    let dir = scratch("bad");
    let lens = cooke_file(&dir);
    let lens = lens.to_str().unwrap();
    let jpg = dir.join("layout.jpg");
    let cases: [(Vec<&str>, &str); 6] = [
        (
            vec!["plot", "bokeh", lens, "--out", "x.png"],
            "unknown plot kind \"bokeh\"",
        ),
        (
            vec!["plot", "layout", lens, "--out", jpg.to_str().unwrap()],
            "layout.jpg",
        ),
        (
            vec!["plot", "layout", "no-such-lens", "--out", "x.png"],
            "no-such-lens",
        ),
        (
            vec!["plot", "layout", lens, "--out", "x.png", "--field-deg=-3"],
            "--field-deg",
        ),
        // A pupil slower than f/1000 (1 um across: about f/50000 here): an f/1e300 one had
        // hung the PSF plot in its axes' ticks.
        (
            vec!["plot", "psf", lens, "--out", "x.png", "--epd-mm", "1e-3"],
            "f-number",
        ),
        // A length no command takes, as the wave commands refuse it.
        (
            vec!["plot", "psf", lens, "--out", "x.png", "--epd-mm", "1e-290"],
            "--epd-mm is 1e-290",
        ),
    ];
    for (args, expected) in cases {
        let output = lensbake(&args);
        assert_eq!(
            output.status.code(),
            Some(2),
            "{args:?}: {}",
            stderr(&output)
        );
        let message = stderr(&output);
        assert!(
            message.starts_with("error: ") && message.contains(expected),
            "{args:?}: {message}"
        );
    }
    assert!(!jpg.exists() && !Path::new("x.png").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn report_lists_tables_and_every_plot_it_drew() {
    let dir = scratch("report");
    let lens = cooke_file(&dir);
    let out = dir.join("report");
    let output = lensbake(&[
        "report",
        lens.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let readme = std::fs::read_to_string(out.join("README.md")).unwrap();
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(readme.starts_with("# cooke\n"));
    assert!(
        readme.contains("| 4 | 20.2919 | 4.7504 | 1.000000 | air | 3.870 | stop |"),
        "{readme}"
    );
    let plots: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.ends_with(".png"))
        .collect();
    assert!(plots.contains(&"layout.png".to_string()));
    for plot in &plots {
        assert!(
            readme.contains(&format!("]({plot})")),
            "README misses {plot}"
        );
        assert!(
            html.contains(&format!("src=\"{plot}\"")),
            "index.html misses {plot}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `plot` and `report` read lens files as every other command does: an unscaled pbrt file
/// (thickness from the previous surface) is refused with the hint, and read with the flag.
#[test]
fn plot_and_report_take_the_reading_flags() {
    let dir = scratch("read-flags");
    let lens = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/lenses/dgauss.dat");
    let lens = lens.to_str().unwrap();
    let out = dir.join("layout.png");
    let plot = |extra: &[&str]| {
        let mut args = vec!["plot", "layout", lens, "--out", out.to_str().unwrap()];
        args.extend(extra);
        lensbake(&args)
    };
    let refused = plot(&[]);
    assert_eq!(refused.status.code(), Some(2), "{}", stderr(&refused));
    assert!(stderr(&refused).contains("--pbrt-from-previous"));
    assert!(!out.exists());
    let read = plot(&["--pbrt-from-previous"]);
    assert!(read.status.success(), "{}", stderr(&read));
    assert!(out.exists());
    let as_pbrt = plot(&["--format", "pbrt", "--pbrt-from-previous"]);
    assert!(as_pbrt.status.success(), "{}", stderr(&as_pbrt));
    let report = dir.join("report");
    let o = lensbake(&[
        "report",
        lens,
        "--pbrt-from-previous",
        "--out",
        report.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(report.join("layout.png").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
