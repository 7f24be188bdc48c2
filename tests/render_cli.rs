//! `lensbake render` from the command line: the Seidel model, and `--error-budget-px`, which
//! picks the cheapest model within a budget of this render's pixels and says what it predicted
//! and measured.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn scratch(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("lensbake-render-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A small CPU render of the bundled double Gauss on the demo scene, focused at 2 m.
fn render(out: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lensbake"))
        .args([
            "render",
            "--lens",
            "dgauss-50mm",
            "--backend",
            "cpu",
            "--width",
            "96",
        ])
        .args([
            "--height",
            "64",
            "--spp",
            "4",
            "--focus-mm",
            "2000",
            "--out",
        ])
        .arg(out)
        .args(extra)
        .output()
        .expect("the binary runs")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Every channel of every pixel of the EXR at `path`, in reading order.
fn exr_channels(path: &Path) -> Vec<f32> {
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| vec![0.0f32; size.width() * size.height() * 3],
        |pixels: &mut Vec<f32>, position, (r, g, b, _): (f32, f32, f32, f32)| {
            let at = 3 * (position.y() * 96 + position.x());
            pixels[at..at + 3].copy_from_slice(&[r, g, b]);
        },
    )
    .unwrap();
    image.layer_data.channel_data.pixels
}

/// The number after `label` on the line that starts with it.
fn number_after(stdout: &str, label: &str) -> f64 {
    let line = stdout
        .lines()
        .find(|l| l.starts_with(label))
        .unwrap_or_else(|| panic!("no `{label}` line in\n{stdout}"));
    line[label.len()..]
        .split_whitespace()
        .next()
        .and_then(|w| w.parse().ok())
        .unwrap_or_else(|| panic!("no number in `{line}`"))
}

#[test]
fn the_seidel_model_renders_finite_non_negative_pixels() {
    let dir = scratch("seidel");
    let out = dir.join("seidel.exr");
    let o = render(&out, &["--model", "seidel", "--f-number", "2.8"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        text(&o.stdout).contains("model seidel"),
        "{}",
        text(&o.stdout)
    );
    let channels = exr_channels(&out);
    assert!(channels.iter().all(|v| v.is_finite() && *v >= 0.0));
    assert!(channels.iter().any(|v| *v > 0.0));
    assert!(dir.join("seidel.png").is_file());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn an_error_budget_picks_a_model_that_meets_it_and_renders_with_it() {
    let dir = scratch("budget");
    let mut chosen = Vec::new();
    // From a budget every model meets to one only a table or the trace meets, at f/2.8.
    for budget in ["20", "0.02"] {
        let out = dir.join(format!("budget-{budget}.exr"));
        let o = render(&out, &["--error-budget-px", budget, "--f-number", "2.8"]);
        let stdout = text(&o.stdout);
        assert!(o.status.success(), "{budget}: {}", text(&o.stderr));
        let budget: f64 = budget.parse().unwrap();
        let predicted = number_after(&stdout, "predicted error:");
        let measured = number_after(&stdout, "measured error:");
        assert!(
            predicted <= budget && measured <= budget,
            "{budget}: {stdout}"
        );
        // The model line names the choice; the render line says the render used it.
        let model_line = stdout.lines().find(|l| l.starts_with("model: ")).unwrap();
        let label = model_line["model: ".len()..].split(" (").next().unwrap();
        let kind = label.split_whitespace().next().unwrap();
        assert!(
            stdout.contains(&format!("model {kind}, film at")),
            "{stdout}"
        );
        assert!(
            exr_channels(&out)
                .iter()
                .all(|v| v.is_finite() && *v >= 0.0)
        );
        chosen.push(kind.to_string());
    }
    // 20 px of a 96 px frame: the thin lens (the cheapest) is within it. 0.02 px: no model
    // without the lens's real rays is (thick misses by ~1 px here).
    assert_eq!(chosen[0], "thin", "{chosen:?}");
    assert!(
        matches!(chosen[1].as_str(), "baked" | "traced"),
        "{chosen:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_bad_error_budget_is_refused_with_status_2() {
    let dir = scratch("bad-budget");
    let out = dir.join("x.exr");
    for (extra, says) in [
        (vec!["--error-budget-px", "0"], "budget"),
        (vec!["--error-budget-px=-1"], "budget"),
        (vec!["--error-budget-px", "NaN"], "budget"),
        (
            vec!["--error-budget-px", "1", "--model", "baked"],
            "--model",
        ),
        (vec!["--error-budget-px", "1", "--table", "t"], "--table"),
    ] {
        let o = render(&out, &extra);
        let stderr = text(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(stderr.contains(says), "{extra:?}: {stderr}");
        assert!(!out.exists(), "{extra:?} wrote an image");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
