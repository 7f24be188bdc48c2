//! The trade-off measurement and the error-budget choice on the bundled double Gauss.
#![cfg(feature = "cli")]

mod common;

use std::path::Path;
use std::sync::OnceLock;

use lensbake::lenses;
use lensbake::model::ModelKind;
use lensbake::prescription::formats::LoadOptions;
use lensbake::system::LensSystem;
use lensbake::tradeoff::choose::choose_model;
use lensbake::tradeoff::render::RenderBench;
use lensbake::tradeoff::{Measured, RaySet, SceneRequirements, model_error, tradeoff};

fn dgauss() -> LensSystem {
    lenses::load("dgauss-50mm", &LoadOptions::default())
        .unwrap()
        .system
}

/// A frame small enough for tests; rendering is deterministic for a seed, timing is not.
fn small_frame() -> RenderBench {
    RenderBench {
        width: 64,
        height: 48,
        samples_per_pixel: 4,
        frames: 1,
        seed: 1,
    }
}

/// One default-domain trade-off, shared by the tests (it bakes eight tables).
fn default_run() -> &'static Vec<Measured> {
    static RUN: OnceLock<Vec<Measured>> = OnceLock::new();
    RUN.get_or_init(|| {
        tradeoff(
            &dgauss(),
            &SceneRequirements::default(),
            6000,
            3,
            &small_frame(),
        )
        .unwrap()
        .1
    })
}

fn find<'a>(run: &'a [Measured], label: &str) -> &'a Measured {
    run.iter().find(|m| m.label == label).unwrap()
}

#[test]
fn every_number_is_finite_and_the_trace_is_the_zero_reference() {
    let run = default_run();
    assert_eq!(run.len(), 3 + 8 + 1);
    for m in run {
        let e = &m.entry;
        assert!(
            e.bake_seconds.is_finite() && e.bake_seconds >= 0.0,
            "{}",
            m.label
        );
        assert!(e.ray_error_p99_mrad.is_finite() && e.image_error_px_p99.is_finite());
        // About 45 % of the renderer's rays pass the double Gauss wide open (cat's-eye
        // vignetting inside the pupil bound); every model is compared on most of those.
        assert!(
            m.error.compared > 2400,
            "{}: {} rays compared",
            m.label,
            m.error.compared
        );
    }
    let traced = run.last().unwrap();
    assert_eq!(traced.entry.model, ModelKind::Traced);
    assert_eq!(traced.entry.ray_error_p99_mrad, 0.0);
    assert_eq!(traced.error.image_px.max, 0.0);
    assert_eq!(traced.error.validity_mismatch, 0.0);
}

#[test]
fn baked_error_falls_with_resolution_and_f16_never_beats_f32() {
    let run = default_run();
    let p99 = |label: String| find(run, &label).entry.image_error_px_p99;
    for pair in [16, 32, 64, 128].windows(2) {
        let (coarse, fine) = (pair[0], pair[1]);
        assert!(
            p99(format!("baked {fine}^3 f32")) < 0.9 * p99(format!("baked {coarse}^3 f32")),
            "{coarse} -> {fine}"
        );
    }
    for n in [16, 32, 64, 128] {
        let (half, single) = (
            p99(format!("baked {n}^3 f16")),
            p99(format!("baked {n}^3 f32")),
        );
        // Rounding adds error; at coarse resolutions interpolation dominates and the two agree
        // to sampling noise of the p99.
        assert!(half >= 0.98 * single, "{n}: f16 {half} < f32 {single}");
    }
    // Halving the entry size halves the bytes.
    assert_eq!(
        2 * find(run, "baked 64^3 f16").entry.table_bytes,
        find(run, "baked 64^3 f32").entry.table_bytes
    );
}

#[test]
fn first_order_models_are_ordered_as_the_physics_says() {
    // At infinity focus and a far scene only directions count, and a film point's rays leave a
    // paraxial lens parallel whatever its principal planes: thin and thick agree.
    let run = default_run();
    let thin = find(run, "thin").entry.image_error_px_p99;
    let thick = find(run, "thick").entry.image_error_px_p99;
    assert!(thin >= thick * (1.0 - 1e-9));
    // The Seidel model adds the third-order aberrations (distortion above all) to thick.
    assert!(find(run, "seidel").entry.image_error_px_p99 < thick);
    // With a near scene in focus, where the thin lens misplaces its principal planes by the
    // double Gauss's thickness, thin is strictly worse than thick.
    let near = SceneRequirements {
        focus_mm: Some(800.0),
        nearest_mm: Some(500.0),
        ..SceneRequirements::default()
    };
    let (_, run) = tradeoff(&dgauss(), &near, 3000, 5, &small_frame()).unwrap();
    let thin = find(&run, "thin").entry.image_error_px_p99;
    let thick = find(&run, "thick").entry.image_error_px_p99;
    assert!(thin > 1.05 * thick, "thin {thin} px, thick {thick} px");
}

#[test]
fn every_renderer_model_renders_and_its_frame_approaches_the_traced_one() {
    let run = default_run();
    for m in run {
        let ms = m.entry.render_ms_per_frame;
        assert!(ms.is_finite() && ms > 0.0, "{}: {ms}", m.label);
        assert_eq!(m.render.ms_per_frame, ms);
        // Every frame but the reference's own has a PSNR against it.
        assert_eq!(
            m.render.psnr_db.is_none(),
            m.entry.model == ModelKind::Traced,
            "{}",
            m.label
        );
    }
    let psnr = |label: &str| find(run, label).render.psnr_db.unwrap();
    // Traced and baked frames share every lens sample, so the frames differ only by the table's
    // interpolation error, which falls with resolution (rendering is deterministic per seed).
    let f32_psnr: Vec<f64> = [16, 32, 64, 128]
        .iter()
        .map(|n| psnr(&format!("baked {n}^3 f32")))
        .collect();
    assert!(
        f32_psnr.windows(2).all(|w| w[1] > w[0] + 0.5),
        "{f32_psnr:?}"
    );
    // The first-order models miss the double Gauss's aberrations and vignetting: even the
    // coarsest table is far closer to the traced frame.
    for first_order in ["thin", "thick"] {
        let db = psnr(first_order);
        assert!(
            db.is_finite() && db + 10.0 < f32_psnr[0],
            "{first_order} {db} dB"
        );
    }
}

#[test]
fn the_chosen_model_meets_the_budget_on_fresh_rays() {
    let system = dgauss();
    for budget in [0.3, 3.0, 200.0] {
        let req = SceneRequirements {
            film_fraction: 0.7,
            ..SceneRequirements::default()
        };
        let choice = choose_model(&system, &req, budget).unwrap();
        assert!(
            choice.measured_px <= budget,
            "{budget}: {}",
            choice.measured_px
        );
        assert!((choice.domain.film_radius / choice.domain.full_film_radius - 0.7).abs() < 1e-12);
        if let Some(table) = &choice.table {
            // The baked domain is the scene's, not the default one.
            let frame = &table.layers[0].frame;
            assert!((frame.max_film_radius - choice.domain.film_radius).abs() < 1e-12);
            // Re-measure on rays the choice never saw.
            let built =
                lensbake::tradeoff::baked_model(&system, table.clone(), &choice.domain, 0.0)
                    .unwrap();
            let traced = lensbake::tradeoff::analytic_models(&system, &choice.domain)
                .unwrap()
                .pop()
                .unwrap();
            let set = RaySet::new(table, &traced, &choice.domain, 4000, 99);
            let fresh = model_error(&built, &set, &choice.domain).image_px.p99;
            assert!(fresh <= 1.15 * budget, "{budget}: fresh rays {fresh} px");
        }
        if budget >= 200.0 {
            assert_eq!(
                choice.model,
                ModelKind::Thin,
                "a loose budget takes the cheapest"
            );
        }
    }
}

/// `lensbake tradeoff LENS` with `rays` rays and one small frame per model, written to `out`.
fn small_tradeoff(lens: &str, rays: &str, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "tradeoff",
        lens,
        "--rays",
        rays,
        "--render-width",
        "32",
        "--render-height",
        "24",
        "--render-spp",
        "2",
        "--render-frames",
        "1",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    common::lensbake(&args)
}

#[test]
fn tradeoff_json_has_exactly_the_documented_shape() {
    let dir = std::env::temp_dir().join(format!("lensbake-tradeoff-{}", std::process::id()));
    let out = small_tradeoff("biconvex-singlet", "800", &dir, &["--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let value: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let object = value.as_object().unwrap();
    assert_eq!(object.keys().collect::<Vec<_>>(), vec!["entries"]);
    let entries = object["entries"].as_array().unwrap();
    let mut models = Vec::new();
    for e in entries {
        let e = e.as_object().unwrap();
        let mut keys: Vec<&str> = e.keys().map(String::as_str).collect();
        keys.sort();
        assert_eq!(
            keys,
            [
                "bake_seconds",
                "image_error_px_p99",
                "model",
                "precision",
                "ray_error_p99_mrad",
                "render_ms_per_frame",
                "resolution",
                "table_bytes"
            ]
        );
        models.push(e["model"].as_str().unwrap().to_string());
        for k in ["bake_seconds", "ray_error_p99_mrad", "image_error_px_p99"] {
            assert!(e[k].as_f64().unwrap().is_finite());
        }
        assert!(e["table_bytes"].as_u64().is_some());
        // Every model rendered a frame: the field is a number, as the schema says.
        let rendered = e["render_ms_per_frame"].as_f64();
        assert!(
            rendered.is_some_and(|ms| ms.is_finite() && ms > 0.0),
            "{e:?}"
        );
        let baked = e["model"] == "baked";
        assert_eq!(e["resolution"].is_u64(), baked);
        assert_eq!(e["precision"].is_string(), baked);
    }
    for m in ["thin", "thick", "seidel", "baked", "traced"] {
        assert!(models.iter().any(|x| x == m), "{m} missing");
    }
    for f in ["tradeoff.json", "tradeoff.md", "pareto.png"] {
        assert!(dir.join(f).is_file(), "{f}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Like `bake` and `render`, `tradeoff` measures a finite-conjugate lens where its file puts the
/// object (DeepLens's double Gauss, 100 mm out), not at infinity, and says so.
#[test]
fn tradeoff_takes_the_lens_files_object_distance() {
    let dir = std::env::temp_dir().join(format!("lensbake-tradeoff-file-{}", std::process::id()));
    let lens = format!(
        "{}/tests/data/corpus/deeplens__zemax_double_gaussian.zmx",
        env!("CARGO_MANIFEST_DIR")
    );
    let out = small_tradeoff(&lens, "200", &dir, &[]);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("focus 100.000 mm, the lens file's object distance"),
        "{stderr}"
    );
    assert!(stdout.contains("focus 100 mm,"), "{stdout}");
    std::fs::remove_dir_all(&dir).unwrap();
}
