//! `lensbake render` as a user runs it: every focus mode with every lens model, three-point
//! focus and the errors for bad sensor settings (exit code 2); the Seidel model; and
//! `--error-budget-px`, which picks the cheapest model within a budget of this render's pixels
//! and says what it predicted and measured.
#![cfg(feature = "cli")]

mod common;

use common::lensbake;
use lensbake::job::{BackendChoice, FilmSize, ModelChoice, RenderJob, RenderLens};
use lensbake::model::ModelKind;
use lensbake::paraxial::{Field, Paraxial, ParaxialOptions};
use lensbake::prescription::formats::LoadOptions;
use lensbake::render::RenderSettings;
use lensbake::render::chromatic::ChromaticMode;
use lensbake::render::image::RgbImage;
use lensbake::trace::analyses::RealRays;
use lensbake::trace::{Tracer, traceable_field_deg};

use std::path::{Path, PathBuf};
use std::process::Output;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lensbake-render-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs a small CPU render with `extra` options; returns stdout, asserting success.
fn render(dir: &Path, name: &str, extra: &[&str]) -> String {
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

/// A file of the lens corpus (tests/data/corpus).
fn corpus(file: &str) -> String {
    format!("{}/tests/data/corpus/{file}", env!("CARGO_MANIFEST_DIR"))
}

/// A tiny CPU render of `lens` with `model` to `out`; the output whether it succeeded or not.
fn tiny_render(lens: &str, model: &str, out: &Path, extra: &[&str]) -> Output {
    tiny_render_choosing(lens, out, &[&["--model", model], extra].concat())
}

/// A tiny CPU render of `lens` to `out` whose model `choice` picks (`--model M` or
/// `--error-budget-px B`, with any other options).
fn tiny_render_choosing(lens: &str, out: &Path, choice: &[&str]) -> Output {
    let mut args = vec![
        "render",
        "--lens",
        lens,
        "--backend",
        "cpu",
        "--width",
        "32",
        "--height",
        "24",
        "--spp",
        "2",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(choice);
    lensbake(&args)
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
    for model in ["thin", "thick", "seidel", "traced", "baked"] {
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

/// A catadioptric lens whose image forms among its own surfaces (rayoptics' HoO-V2C18Ex27, a
/// Cassegrain) cannot take a sensor there; the message says where it must go and blames no
/// tilt, since none was asked for.
#[test]
fn a_sensor_inside_the_lens_is_refused_without_blaming_a_tilt() {
    let dir = temp_dir("inside");
    let out = dir.join("x.exr");
    let o = tiny_render(&corpus("rayoptics__HoO-V2C18Ex27.zmx"), "traced", &out, &[]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("error: the sensor at z = ") && !stderr.contains("tilt"),
        "{stderr}"
    );
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// A lithography lens whose rear focal point lies 197 mm inside it (embodiment 1 of EP 0770895
/// A2) images a far object among its own surfaces: every model that follows the surfaces refuses
/// the focus naming it, before any pupil is fitted on a plane no ray reaches (the traced model
/// said only that no ray from the film centre passed); the thin model, which has no surfaces,
/// renders; at the file's own object distance the traced model renders.
#[test]
fn a_far_focus_imaged_inside_the_lens_is_refused_by_every_model_that_traces_it() {
    let dir = temp_dir("image-inside");
    let out = dir.join("x.exr");
    let lens = corpus("patent2zmx__EP0770895A2-embodiment-1.zmx");
    // A budget measures every model against the exact trace, so it is refused the same way.
    for model in ["traced", "seidel", "baked", "budget"] {
        let choice = match model {
            "budget" => ["--error-budget-px", "1"],
            _ => ["--model", model],
        };
        let o = tiny_render_choosing(
            &lens,
            &out,
            &[&choice[..], &["--focus-mm", "50000"]].concat(),
        );
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{model}: {stderr}");
        assert!(
            stderr.starts_with("error: cannot focus at 50000 mm: its image plane z = ")
                && stderr.contains("is not behind the last vertex (z = 884.070000 mm)"),
            "{model}: {stderr}"
        );
        assert!(!out.exists());
    }
    let thin = tiny_render(&lens, "thin", &out, &["--focus-mm", "50000"]);
    assert!(
        thin.status.success(),
        "{}",
        String::from_utf8_lossy(&thin.stderr)
    );
    let near = tiny_render(&lens, "traced", &out, &["--focus-mm", "95.002"]);
    assert!(
        near.status.success(),
        "{}",
        String::from_utf8_lossy(&near.stderr)
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// A lens made for a phone-sized sensor (CODE V sample 65564 via rayoptics, EFL 1.5 mm) lights a
/// speck of a full frame: the film is the largest frame inside its image circle, so the scene
/// fills the image; asked for, the full frame comes back with its speck.
#[test]
fn a_small_format_lens_gets_a_film_inside_its_image_circle() {
    let lens = lensbake::lenses::load(
        &corpus("rayoptics__CODV_65564.seq"),
        &LoadOptions::default(),
    )
    .unwrap();
    let (width, height) = (64, 48);
    let render = |film_width_mm| {
        RenderJob {
            model: ModelChoice::Model(ModelKind::Traced),
            backend: BackendChoice::Cpu,
            settings: RenderSettings {
                width,
                height,
                samples_per_pixel: 4,
                seed: 1,
                max_layers: 4,
            },
            chromatic: ChromaticMode::Off,
            film_width_mm,
            ..RenderJob::new(RenderLens::Real(Box::new(lens.clone())))
        }
        .run()
        .unwrap()
    };
    let lit = |image: &RgbImage| {
        let lit = image
            .pixels
            .iter()
            .filter(|p| p.iter().any(|&v| v > 1e-3))
            .count();
        lit as f64 / image.pixels.len() as f64
    };
    let chosen = render(None);
    let FilmSize::ImageCircle { diameter_mm } = chosen.prepared.film_size else {
        panic!("{:?}", chosen.prepared.film_size)
    };
    // The circle the real chief ray draws in the focal plane at the largest field it passes,
    // found the analyses' way: the traceable field's real chief-ray height (1.289 mm across;
    // the paraxial 2 f tan(23.85 deg) is 1.325, this lens's distortion there -2.7 %).
    let at = lens.system.at(lens.system.design_wavelength_nm());
    let field_deg = traceable_field_deg(&Tracer::new(&at), 1.0);
    let paraxial = Paraxial::new(
        &at,
        &ParaxialOptions {
            field: Field::Angle { deg: field_deg },
            ..ParaxialOptions::default()
        },
    )
    .unwrap();
    let height = RealRays::new(&at, paraxial)
        .distortion(&[field_deg])
        .unwrap()[0]
        .real_height;
    assert!(
        (diameter_mm - 2.0 * height.abs()).abs() < 1e-6 * diameter_mm,
        "{diameter_mm} against {}",
        2.0 * height.abs()
    );
    let film = &chosen.prepared.camera.film;
    assert!((film.width_mm.hypot(film.height_mm) - diameter_mm).abs() < 1e-12);
    assert!((film.width_mm / film.height_mm - 4.0 / 3.0).abs() < 1e-12);
    assert!(lit(&chosen.image) > 0.9, "{}", lit(&chosen.image));
    let full = render(Some(36.0));
    assert_eq!(full.prepared.film_size, FilmSize::Asked);
    assert!(lit(&full.image) < 0.05, "{}", lit(&full.image));
}

/// A focus distance nobody asked for (render's 2000 mm, or the file's object distance) that the
/// lens cannot reach is refused naming where it came from and the flags that set another.
#[test]
fn an_unreachable_focus_nobody_asked_for_names_its_origin() {
    let dir = temp_dir("unasked");
    let out = dir.join("x.exr");
    for (file, origin) in [
        // A Ritchey-Chretien telescope: its front focal point is 31.7 m out.
        (
            "rayoptics__rc_f16.seq",
            "that distance is render's default focus: give --focus-mm farther than 31702.216 or \
             --sensor-mm",
        ),
        // A finite-conjugate lens whose thin model's front focal point lies beyond the object.
        (
            "rayoptics__US05831776-1.zmx",
            "that distance is the lens file's object distance: give --focus-mm farther than \
             129.381 or --sensor-mm",
        ),
    ] {
        let o = tiny_render(&corpus(file), "thin", &out, &[]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{file}: {stderr}");
        assert!(
            stderr.starts_with("error: cannot focus at ") && stderr.contains(origin),
            "{file}: {stderr}"
        );
        assert!(!out.exists());
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
        (vec!["--film-mm", "0"], "the film width (mm)"),
        (vec!["--film-mm", "NaN"], "the film width (mm)"),
        (
            vec!["--tilt-deg", "0,30", "--sensor-mm", "5"],
            "the tilted sensor's corner at z",
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

/// A film of 5 m behind a 50 mm lens sees nearly 180 degrees, which puts the whole demo scene
/// between the pixel centres of a tiny render: the render is refused after it baked its table,
/// and the table it baked goes with it, so the refused command leaves nothing (a table that was
/// there before stays).
#[test]
fn a_baked_render_refused_after_its_bake_removes_the_table_it_baked() {
    let dir = temp_dir("baked-refused");
    let out = dir.join("x.exr");
    // A tiny baked render with its table in `table`, and `extra` flags.
    let baked_render = |table: &Path, extra: &[&str]| {
        let table = ["--bake-resolution", "8", "--table", table.to_str().unwrap()];
        tiny_render("dgauss-50mm", "baked", &out, &[&table[..], extra].concat())
    };
    let refused = |table: &Path| {
        let o = baked_render(table, &["--film-mm", "5000"]);
        let stderr = text(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{stderr}");
        assert!(
            stderr.starts_with("error: no surface of the scene is in view")
                && stderr.contains("between its pixels"),
            "{stderr}"
        );
    };
    let table = dir.join("table");
    refused(&table);
    assert!(
        !table.exists(),
        "the table baked for the refused render is gone"
    );
    assert!(!out.exists());
    let kept = dir.join("kept");
    let baked = baked_render(&kept, &[]);
    assert!(baked.status.success(), "{}", text(&baked.stderr));
    std::fs::remove_file(&out).unwrap();
    std::fs::remove_file(out.with_extension("png")).ok();
    refused(&kept);
    assert!(
        kept.join("lrtf.ron").exists(),
        "a table found on disk stays"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// A small CPU render of the bundled double Gauss on the demo scene, focused at 2 m.
/// Returns the output whether it succeeded or not.
fn render_dgauss(out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "render",
        "--lens",
        "dgauss-50mm",
        "--backend",
        "cpu",
        "--width",
        "96",
        "--height",
        "64",
        "--spp",
        "4",
        "--focus-mm",
        "2000",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    lensbake(&args)
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
    let dir = temp_dir("seidel");
    let out = dir.join("seidel.exr");
    let o = render_dgauss(&out, &["--model", "seidel", "--f-number", "2.8"]);
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
    let dir = temp_dir("budget");
    let mut chosen = Vec::new();
    // From a budget every model meets to one only a table or the trace meets, at f/2.8.
    for budget in ["20", "0.02"] {
        let out = dir.join(format!("budget-{budget}.exr"));
        let o = render_dgauss(&out, &["--error-budget-px", budget, "--f-number", "2.8"]);
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
            stdout.contains(&format!("model {kind}, film centre at")),
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
    let dir = temp_dir("bad-budget");
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
        let o = render_dgauss(&out, &extra);
        let stderr = text(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(stderr.contains(says), "{extra:?}: {stderr}");
        assert!(!out.exists(), "{extra:?} wrote an image");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--backend auto` takes the GPU only when it is hardware; a software rasteriser (lavapipe in
/// CI) or no adapter gives the CPU twin, and the run says why.
#[test]
fn auto_backend_passes_over_a_software_rasteriser_and_says_why() {
    let dir = temp_dir("auto-backend");
    let out = dir.join("auto.exr");
    let o = lensbake(&[
        "render",
        "--lens",
        "dgauss-50mm",
        "--model",
        "thick",
        "--width",
        "32",
        "--height",
        "24",
        "--spp",
        "1",
        "--backend",
        "auto",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{stdout}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let line = stdout
        .lines()
        .find(|l| l.starts_with("backend: "))
        .unwrap_or_else(|| panic!("no backend line: {stdout}"));
    match lensbake::render::gpu::gpu_worth_using() {
        Ok(()) => assert!(line.starts_with("backend: gpu ("), "{line}"),
        Err(why) => assert_eq!(line, format!("backend: cpu ({why})")),
    }
    if std::env::var_os("CI").is_some() {
        // CI machines have lavapipe and no GPU: the twin, for that reason.
        assert!(line.contains("software rasteriser"), "{line}");
    }
}

/// Where no flag is given, a render takes the lens file's aperture, object distance (as the
/// focus) and three wavelengths (R, G, B, longest first), and says so; flags override each.
#[test]
fn render_defaults_to_the_files_stated_conditions() {
    let dir = temp_dir("file-defaults");
    let lens = dir.join("stated.seq");
    std::fs::write(
        &lens,
        "EPD 10\nWL 486.1327 587.5618 656.2725\nREF 2\nSO 0 2000\nS 50 5 N-BK7\nS -50 47\nSI 0 0\n",
    )
    .unwrap();
    let lens = lens.to_str().unwrap();
    let said = render(&dir, "file", &["--lens", lens, "--chromatic", "on"]);
    for line in [
        "lens file: focus 2000.000 mm: the lens file's object distance",
        "lens file: R/G/B wavelengths 656.3/587.6/486.1 nm from the lens file",
        "chromatic: on, R/G/B at 656.3/587.6/486.1 nm",
    ] {
        assert!(said.contains(line), "{line}\n{said}");
    }
    assert!(
        said.contains(" from the lens file\n") && said.contains("lens file: f/"),
        "{said}"
    );
    let flags = [
        "--lens",
        lens,
        "--focus-mm",
        "5000",
        "--f-number",
        "8",
        "--wavelengths-nm",
        "640,550,460",
        "--chromatic",
        "on",
    ];
    let said = render(&dir, "flags", &flags);
    assert!(!said.contains("lens file:"), "{said}");
    assert!(said.contains("R/G/B at 640.0/550.0/460.0 nm"), "{said}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `lensbake demo` twice gives the same page and images: what it commits under notebooks-out/
/// holds nothing that changes from run to run (the stage timings go to timings.json, which git
/// ignores), so a fresh clone stays clean after the Quick start's first command.
#[test]
fn the_demo_page_is_the_same_on_every_run() {
    let dir = temp_dir("demo-twice");
    let run = |out: &str| {
        let out = dir.join(out);
        let o = lensbake(&[
            "demo",
            "--width",
            "24",
            "--height",
            "16",
            "--spp",
            "2",
            "--bake-resolution",
            "6",
            "--backend",
            "cpu",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
        out
    };
    let (first, second) = (run("a"), run("b"));
    for file in ["README.md", "traced.png", "baked.png", "error-map.png"] {
        let read = |dir: &Path| std::fs::read(dir.join(file)).unwrap();
        assert!(read(&first) == read(&second), "{file} differs between two runs");
    }
    assert!(first.join("timings.json").is_file());
    // In a git checkout (not in a packaged crate, which has no .git).
    if Path::new(".git").exists() {
        let ignored = std::process::Command::new("git")
            .args(["check-ignore", "-q", "notebooks-out/demo/timings.json"])
            .status()
            .expect("git runs");
        assert!(ignored.success(), "git must ignore the demo's timings.json");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
