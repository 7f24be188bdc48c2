//! `lensbake bench render` as a user runs it: one row per model, backend and sample count, each
//! measured against the exact reference, accumulating across runs of the same frame.
#![cfg(feature = "cli")]

mod common;

use common::lensbake;

use std::process::Command;

fn rows(dir: &std::path::Path) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(dir.join("timings.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["rows"].as_array().unwrap().clone()
}

#[test]
fn bench_render_measures_every_model_against_the_reference_and_accumulates() {
    let dir = std::env::temp_dir().join(format!("lensbake-bench-render-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let table = dir.join("table");
    let out = dir.join("out");
    let common = [
        "bench",
        "render",
        "--width",
        "40",
        "--height",
        "30",
        "--backends",
        "cpu",
        "--bake-resolution",
        "16",
        "--table",
        table.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    let first = lensbake(&[&common[..], &["--spp", "4"]].concat());
    assert_eq!(
        first.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let measured = rows(&out);
    // A reference row plus four models at one sample count.
    assert_eq!(measured.len(), 5, "{measured:?}");
    let psnr = |model: &str| {
        let row = measured
            .iter()
            .find(|r| r["model"] == model && r["backend"] == "cpu")
            .unwrap();
        assert!(row["seconds"].as_f64().unwrap() >= 0.0, "{row}");
        row["psnr_vs_reference_db"].as_f64().unwrap()
    };
    let reference = measured
        .iter()
        .find(|r| r["backend"] == "reference")
        .unwrap();
    assert!(reference["psnr_vs_reference_db"].is_null());
    // Traced and baked draw the reference's own lens samples, so what separates them from it is
    // the 40x30 layers (shared by both) and, for baked, the 16^3 table: the two stay within a
    // decibel of each other. Thin and thick miss the real lens's focus and distortion: below both.
    let (traced, baked) = (psnr("traced"), psnr("baked"));
    assert!(traced.is_finite() && traced > 10.0, "traced {traced} dB");
    assert!(
        (traced - baked).abs() < 1.0,
        "traced {traced} dB, baked {baked} dB"
    );
    for first_order in ["thin", "thick"] {
        let db = psnr(first_order);
        assert!(
            db > 5.0 && db < traced,
            "{first_order} {db} dB, traced {traced} dB"
        );
    }
    let second = lensbake(&[&common[..], &["--spp", "8", "--models", "baked"]].concat());
    assert_eq!(second.status.code(), Some(0));
    let accumulated = rows(&out);
    assert_eq!(accumulated.len(), 7, "{accumulated:?}");
    let markdown = std::fs::read_to_string(out.join("timings.md")).unwrap();
    assert!(markdown.contains("| cpu | 8 | baked |"), "{markdown}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn concurrent_runs_into_one_directory_keep_every_row() {
    let dir = std::env::temp_dir().join(format!(
        "lensbake-bench-render-concurrent-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    let table = dir.join("table");
    let out = dir.join("out");
    let run = |spp: &str| {
        Command::new(env!("CARGO_BIN_EXE_lensbake"))
            .args([
                "bench",
                "render",
                "--width",
                "24",
                "--height",
                "16",
                "--backends",
                "cpu",
                "--models",
                "thin,thick",
                "--bake-resolution",
                "8",
                "--table",
                table.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--spp",
                spp,
            ])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("run lensbake")
    };
    // Six runs at once, each a different sample count: every one's rows must survive.
    let sample_counts = ["1", "2", "3", "4", "5", "6"];
    let children: Vec<_> = sample_counts.iter().map(|spp| run(spp)).collect();
    for child in children {
        let output = child.wait_with_output().unwrap();
        assert_eq!(
            output.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let measured = rows(&out);
    for spp in sample_counts {
        let spp: u64 = spp.parse().unwrap();
        // The reference row and the two models at each sample count.
        let at = measured
            .iter()
            .filter(|r| r["samples_per_pixel"].as_u64() == Some(spp))
            .count();
        assert_eq!(at, 3, "{spp} spp: {measured:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Settings are checked before anything is loaded, baked or written: a bad sample count, layer
/// cap, backend or lens leaves neither a table nor an output folder behind.
#[test]
fn bad_settings_are_refused_before_any_table_or_file() {
    let dir = std::env::temp_dir().join(format!("lensbake-bench-bad-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (table, out) = (dir.join("table"), dir.join("out"));
    for (flag, value, expected) in [
        ("--spp", "1,0", "must be positive"),
        ("--spp", "65537", "over the limit"),
        ("--max-layers", "0", "must be positive"),
        ("--backends", "cpu,tpu", "`tpu` is not cpu or gpu"),
        // Found after the output folder is made: the folder goes again.
        (
            "--lens",
            "no-such-lens",
            "neither a lens file nor a bundled lens",
        ),
    ] {
        let output = lensbake(&[
            "bench",
            "render",
            "--width",
            "16",
            "--height",
            "12",
            "--backends",
            "cpu",
            "--spp",
            "1",
            "--table",
            table.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            flag,
            value,
        ]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{flag} {value}: {stderr}");
        assert!(
            stderr.starts_with("error: ") && stderr.contains(expected),
            "{flag} {value}: {stderr}"
        );
        assert!(!table.exists() && !out.exists(), "{flag} {value}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
