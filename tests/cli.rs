//! The `lensbake lens` commands as a user runs them: exit codes, stdout, stderr.
#![cfg(feature = "cli")]

mod common;

use common::{bake_small, lensbake};

use common::lens_file;
use std::path::Path;
use std::process::Output;

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("lensbake-cli-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn check_prints_a_summary() {
    let path = lens_file("dgauss.50mm.dat");
    let o = lensbake(&["lens", "check", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.starts_with("D-GAUSS F/2 22deg HFOV\n"), "{out}");
    assert!(
        out.contains("    6 STO          flat      4.5000 plane       air"),
        "{out}"
    );
    assert!(
        out.contains("stop:        surface 6 (circle), semi-aperture 8.5500 mm"),
        "{out}"
    );
    // 3.76 + 0.12 + 4.025 + 3.275 + 5.705 + 4.5 + 1.18 + 6.065 + 0.19 + 3.22 = 32.04
    assert!(out.contains("total track: 32.0400 mm"), "{out}");
    assert_eq!(
        out.lines()
            .filter(|l| l.trim_start().starts_with(char::is_numeric))
            .count(),
        11,
        "{out}"
    );
    assert!(stderr(&o).is_empty());
}

/// A glass whose formula does not reach the file's wavelength (B270's ends at 656 nm; the file
/// designs at 920 nm) has no index printed: its extrapolated value (1.517476) is a number no
/// analysis uses, since each refuses the wavelength, as the conditions line says.
#[test]
fn check_prints_no_index_outside_a_formula_range() {
    let dir = temp_dir("range");
    // The same B270 lens in air, and with its object in B270 too.
    let check = |name: &str, object: &str| -> String {
        let path = dir.join(name);
        std::fs::write(
            &path,
            format!(
                "MODE SEQ\nENPD 10\nWAVM 1 0.92 1\nSURF 0\n{object}SURF 1\n  STOP\n  CURV \
                 0.02\n  DISZ 4\n  GLAS B270\n  DIAM 8\nSURF 2\n  CURV -0.02\n  DISZ 45\n  \
                 DIAM 8\nSURF 3\n  DISZ 0\n"
            ),
        )
        .unwrap();
        let o = lensbake(&["lens", "check", path.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        stdout(&o)
    };
    let out = check("b270.zmx", "  DISZ INFINITY\n");
    let row = out
        .lines()
        .find(|l| l.trim_start().starts_with("1 STO"))
        .unwrap_or_else(|| panic!("{out}"));
    assert!(row.contains("B270") && row.contains("outside"), "{out}");
    assert!(out.contains("920 nm is outside the range"), "{out}");
    let out = check("immersed.zmx", "  DISZ 20\n  GLAS B270\n");
    assert!(out.contains("object:      B270 (n = outside)"), "{out}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_bad_file_exits_2_naming_file_and_line() {
    let dir = temp_dir("bad");
    let path = dir.join("bad.dat");
    std::fs::write(&path, "# a lens\n50 5 1.5 20\n0 2 zero 10\n").unwrap();
    let o = lensbake(&["lens", "check", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.starts_with(&format!(
            "error: {}:3, surface 2, field `index`: cannot parse `zero`",
            path.display()
        )),
        "{err}"
    );
    assert!(stdout(&o).is_empty());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_pbrt_hint_follows_the_error() {
    let path = lens_file("dgauss.dat");
    let o = lensbake(&["lens", "check", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.starts_with(&format!("error: {}:5, surface 1", path.display())),
        "{err}"
    );
    assert!(
        err.contains("\nnote: ") && err.contains("--pbrt-from-previous"),
        "{err}"
    );
    let o = lensbake(&[
        "lens",
        "check",
        path.to_str().unwrap(),
        "--pbrt-from-previous",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("total track: 64.0800 mm"));
}

#[test]
fn unknown_lens_names_list_the_bundled_ones() {
    let o = lensbake(&["lens", "check", "no-such-lens"]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.starts_with(
            "error: `no-such-lens` is neither a lens file nor a bundled lens; bundled lenses: "
        ),
        "{err}"
    );
    for lens in lensbake::lenses::BUNDLED {
        assert!(err.contains(lens.name), "{err}");
    }
}

#[test]
fn format_flag_overrides_the_extension() {
    let dir = temp_dir("format");
    let path = dir.join("kolb.lens.txt");
    std::fs::copy(lens_file("kolb_dgauss_1995_nobj1.dat"), &path).unwrap();
    // As a plain table, radius 0 is a plane and index 0 is not a stop's: refused.
    let o = lensbake(&["lens", "check", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("refractive index 0 is below vacuum's"),
        "{}",
        stderr(&o)
    );
    let o = lensbake(&["lens", "check", path.to_str().unwrap(), "--format", "pbrt"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = lensbake(&["lens", "check", path.to_str().unwrap(), "--format", "pdf"]);
    assert_eq!(o.status.code(), Some(2), "clap refuses an unknown format");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn convert_writes_ron_that_checks_the_same() {
    let dir = temp_dir("convert");
    let input = lens_file("kolb_dgauss_1995.dat");
    let output = dir.join("kolb.ron");
    let o = lensbake(&[
        "lens",
        "convert",
        input.to_str().unwrap(),
        output.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let before = stdout(&lensbake(&["lens", "check", input.to_str().unwrap()]));
    let after = stdout(&lensbake(&["lens", "check", output.to_str().unwrap()]));
    let table = |s: &str| {
        s.lines()
            .filter(|l| !l.contains("read from:"))
            .map(String::from)
            .collect::<Vec<_>>()
    };
    assert_eq!(table(&before), table(&after));
    // RON, Zemax and pbrt are written, CODE V is not; a refused conversion leaves no file.
    let wrong = dir.join("kolb.seq");
    let o = lensbake(&[
        "lens",
        "convert",
        input.to_str().unwrap(),
        wrong.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).starts_with("error: "), "{}", stderr(&o));
    assert!(!Path::new(&wrong).exists());
    // An invalid lens is not converted.
    let invalid = dir.join("invalid.ron");
    let o = lensbake(&[
        "lens",
        "convert",
        lens_file("dgauss.dat").to_str().unwrap(),
        invalid.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!invalid.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--indices-at-nm`: each glass written as its index there; a wavelength a glass's formula
/// does not reach is one error line naming the surface, and no file.
#[test]
fn convert_writes_constant_indices_at_a_wavelength() {
    let dir = temp_dir("convert-indices");
    let output = dir.join("triplet.ron");
    let out = output.to_str().unwrap();
    let o = lensbake(&[
        "lens",
        "convert",
        "cooke-triplet",
        out,
        "--indices-at-nm",
        "587.5618",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = std::fs::read_to_string(&output).unwrap();
    assert!(!text.contains("Glass("), "{text}");
    // Surfaces 1, 3 and 5 are SK16 (HIKARI), F2, SK16: their indices as `glass show` prints
    // them at the d line (6 decimals).
    let written: Vec<f64> = text
        .split("Index(")
        .skip(1)
        .map(|rest| rest[..rest.find(')').unwrap()].parse().unwrap())
        .collect();
    let shown = |glass: &str| -> f64 {
        let shown = stdout(&lensbake(&["glass", "show", glass]));
        let line = shown
            .lines()
            .find(|l| l.contains("nd  (587.5618 nm)"))
            .unwrap();
        line.split_whitespace().last().unwrap().parse().unwrap()
    };
    let (sk16, f2) = (shown("SK16_HIKARI"), shown("F2"));
    assert_eq!(written.len(), 3, "{text}");
    for (n, nd) in written.iter().zip([sk16, f2, sk16]) {
        assert!((n - nd).abs() <= 5e-7, "{n} against {nd}");
    }
    let o = lensbake(&["lens", "check", out]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));

    let refused = dir.join("refused.ron");
    let o = lensbake(&[
        "lens",
        "convert",
        "cooke-triplet",
        refused.to_str().unwrap(),
        "--indices-at-nm",
        "99000",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.starts_with("error: ") && err.lines().count() == 1,
        "{err}"
    );
    assert!(err.contains("surface 1") && err.contains("medium"), "{err}");
    assert!(!refused.exists());
    // Glass in object space: the file and the field, not a surface.
    let bundled =
        std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("lenses/cooke-triplet.ron");
    let triplet = std::fs::read_to_string(bundled).unwrap();
    let immersed = dir.join("immersed.ron");
    std::fs::write(
        &immersed,
        triplet.replace("object_medium: Air,", "object_medium: Glass(\"N-BK7\"),"),
    )
    .unwrap();
    let o = lensbake(&[
        "lens",
        "convert",
        immersed.to_str().unwrap(),
        refused.to_str().unwrap(),
        "--indices-at-nm",
        "99000",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(err.contains("immersed.ron, field `object_medium`"), "{err}");
    assert!(!refused.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn list_names_every_bundled_lens() {
    let o = lensbake(&["lens", "list"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    for lens in lensbake::lenses::BUNDLED {
        assert!(out.lines().any(|l| l.starts_with(lens.name)), "{out}");
        let o = lensbake(&["lens", "check", lens.name]);
        assert_eq!(o.status.code(), Some(0), "{}: {}", lens.name, stderr(&o));
    }
}

/// The Cooke triplet's Zemax file with SURF 0's `DISZ INFINITY` (line 32) replaced by
/// `DISZ {disz}` (unchanged for `INFINITY`), written into `dir`.
fn cooke_with_object(dir: &std::path::Path, disz: &str) -> std::path::PathBuf {
    let path = dir.join("cooke-object.zmx");
    let base = include_str!("../examples/lenses/cooke_triplet.zmx");
    let text = base.replacen("  DISZ INFINITY", &format!("  DISZ {disz}"), 1);
    assert!(text.contains(&format!("  DISZ {disz}\n")));
    std::fs::write(&path, text).unwrap();
    path
}

/// A virtual object in a file (DISZ -100: a beam converging 100 mm behind surface 1) is what
/// `analyze` analyses; a bake focuses on real objects only, so it bakes at infinity and says
/// why.
#[test]
fn a_virtual_object_in_a_file_is_analysed_and_not_baked_as_a_focus() {
    let dir = temp_dir("virtual");
    let path = cooke_with_object(&dir, "-100");
    let o = lensbake(&["analyze", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("object 100.0000 mm behind surface 1 (virtual)"),
        "{}",
        stdout(&o)
    );
    let o = bake_small(&path, &dir.join("table"), &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("100.000 mm behind surface 1 (virtual): a bake or a render focuses"),
        "{}",
        stderr(&o)
    );
    assert!(stdout(&o).contains("focus infinity"), "{}", stdout(&o));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A condition the file states that no analysis can use (here an object on the first vertex,
/// DISZ 0 on SURF 0) fails `lens check` as it fails `analyze`, on the keyword's line, and the report
/// writes nothing rather than a page of skipped plots; a bake refuses it only where no flag
/// replaces it.
#[test]
fn a_stated_condition_no_analysis_can_use_fails_check_and_report_on_its_line() {
    let dir = temp_dir("stated");
    let path = cooke_with_object(&dir, "0");
    let expected = format!(
        "error: {}:32, field `DISZ`: the lens file's object distance: object distance must be \
         finite and not zero",
        path.display()
    );
    let report = dir.join("report");
    for args in [
        vec!["lens", "check", path.to_str().unwrap()],
        vec!["analyze", path.to_str().unwrap()],
        vec![
            "report",
            path.to_str().unwrap(),
            "--out",
            report.to_str().unwrap(),
        ],
    ] {
        let o = lensbake(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let errors: Vec<&str> = std::str::from_utf8(&o.stderr)
            .unwrap()
            .lines()
            .filter(|l| l.starts_with("error:"))
            .collect();
        assert_eq!(errors.len(), 1, "{args:?}: {errors:?}");
        assert!(errors[0].starts_with(&expected), "{args:?}: {errors:?}");
        // The error is the first line; the reading's notes (skipped keywords) follow it.
        assert!(
            stderr(&o).starts_with("error: "),
            "{args:?}: {}",
            stderr(&o)
        );
        assert!(stderr(&o).contains("\nnote: "), "{args:?}: {}", stderr(&o));
        assert!(stdout(&o).is_empty(), "{args:?}");
    }
    assert!(!report.exists());
    // A bake uses the stated object as its focus: refused without a focus flag, baked with one.
    let table = dir.join("table");
    let bake = |extra: &[&str]| bake_small(&path, &table, extra);
    let o = bake(&[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains(&expected), "{}", stderr(&o));
    assert!(!table.exists());
    let o = bake(&["--focus-mm", "3000"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(table.join("lrtf.exr").exists());
    // So does a render, with each of its four focus flags.
    let image = dir.join("render.exr");
    let render = |extra: &[&str]| {
        let mut args = vec![
            "render",
            "--lens",
            path.to_str().unwrap(),
            "--model",
            "thick",
            "--width",
            "16",
            "--height",
            "12",
            "--spp",
            "1",
            "--out",
            image.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        lensbake(&args)
    };
    let o = render(&[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains(&expected), "{}", stderr(&o));
    assert!(!image.exists());
    for flag in [
        ["--focus-mm", "3000"],
        ["--focus-pixel", "8,6"],
        ["--sensor-mm", "60"],
        ["--focus-points", "2,2;14,2;8,10"],
    ] {
        let o = render(&flag);
        assert_eq!(o.status.code(), Some(0), "{flag:?}: {}", stderr(&o));
        std::fs::remove_file(&image).expect("the render wrote its image");
    }
    // The lens as written checks, and its summary lists the conditions it is analysed under.
    let path = cooke_with_object(&dir, "INFINITY");
    let o = lensbake(&["lens", "check", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("    entrance-pupil diameter  10.000 mm (f/5.00) (lens file)\n"),
        "{}",
        stdout(&o)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A bake or render refused for the lens itself (here a single mirror, which sends the light
/// back) prints its error line first, before the notes on what was read from the file: the
/// bake checks its request before it releases them, the render releases them only after the
/// job has run.
#[test]
fn a_refused_bake_or_render_prints_its_error_before_the_notes() {
    let dir = temp_dir("refused-first");
    let lens = "tests/data/corpus/optiland__mirror.seq";
    let (table, image) = (dir.join("table"), dir.join("image.exr"));
    let bake = [
        "bake",
        lens,
        "--resolution",
        "4",
        "--out",
        table.to_str().unwrap(),
    ];
    let render = [
        "render",
        "--lens",
        lens,
        "--width",
        "16",
        "--height",
        "12",
        "--spp",
        "1",
        "--out",
        image.to_str().unwrap(),
    ];
    for args in [&bake[..], &render[..]] {
        let o = lensbake(args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let err = stderr(&o);
        assert!(
            err.starts_with("error: ") && err.contains("an odd number of mirrors"),
            "{args:?}: {err}"
        );
        assert_eq!(err.matches("error: ").count(), 1, "{err}");
    }
    // The bake's notes (the file's f-number, its derived apertures) follow the error.
    assert!(stderr(&lensbake(&bake)).contains("\nnote: "));
    // So does a bake's refusal of a lens that passes no light at the film centre (the reflex
    // lens with its secondary mirror's aperture cut to a tenth, inside its obscuration): it is
    // found by one pupil fit before the bake, no longer while its progress runs.
    let reflex = include_str!("../lenses/reflex-1000mm-f7.5.ron");
    let dark = reflex.replacen(
        "semi_aperture: 55.9372836428",
        "semi_aperture: 5.59372836428",
        1,
    );
    assert_ne!(dark, reflex, "the bundled file changed; update this test");
    let dark_path = dir.join("dark.ron");
    std::fs::write(&dark_path, dark).unwrap();
    let o = lensbake(&[
        "bake",
        dark_path.to_str().unwrap(),
        "--resolution",
        "4",
        "--out",
        table.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o)
            .starts_with("error: no ray from the film at radius 0 mm passes the lens\nnote: "),
        "{}",
        stderr(&o)
    );
    assert!(!table.exists() && !image.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `lens convert IN IN` would drop the keywords lensbake skipped reading IN: refused (exit 2,
/// the file untouched) unless `--overwrite-input` says so, through another path to it too.
#[test]
fn convert_refuses_to_write_over_its_input_unless_told() {
    let dir = temp_dir("convert-over-input");
    let input = dir.join("lens.zmx");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/corpus/optiland__lens1.zmx"),
        &input,
    )
    .unwrap();
    let before = std::fs::read(&input).unwrap();
    let other_path = dir.join(".").join("lens.zmx");
    for output in [&input, &other_path] {
        let o = lensbake(&[
            "lens",
            "convert",
            input.to_str().unwrap(),
            output.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(
            stderr(&o).starts_with("error: ") && stderr(&o).contains("--overwrite-input"),
            "{}",
            stderr(&o)
        );
        assert_eq!(std::fs::read(&input).unwrap(), before);
    }
    let o = lensbake(&[
        "lens",
        "convert",
        input.to_str().unwrap(),
        input.to_str().unwrap(),
        "--overwrite-input",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_ne!(std::fs::read(&input).unwrap(), before);
    std::fs::remove_dir_all(&dir).unwrap();
}
