//! Hostile table files: truncated and corrupted EXR data, sidecars that disagree with the data
//! or the lens, missing files, directories where files belong, garbage RON, failed and
//! interrupted writes, and a bounded-time fuzz run over mutated tables. Every case must end in a
//! typed error or a usable table, never a panic, and a failed write must leave nothing behind.

mod common;

use common::Rng;
use lensbake::lrtf::bake::{BakeRequest, bake};
use lensbake::lrtf::io::{DATA_FILE, SIDECAR_FILE, TableError, read_table, write_table};
use lensbake::lrtf::{Lookup, LrtfTable, Ray as LrtfRay};
use lensbake::prescription::Prescription;
use lensbake::system::LensSystem;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};

const LENS: &str = "dgauss-50mm";

fn prescription() -> Prescription {
    ron::from_str(lensbake::lenses::find(LENS).unwrap().ron).unwrap()
}

/// The files of a small real table (double Gauss, 6 x 5 x 4 nodes), baked once per run.
struct Files {
    data: Vec<u8>,
    sidecar: String,
}

fn files() -> &'static Files {
    static FILES: OnceLock<Files> = OnceLock::new();
    FILES.get_or_init(|| {
        let system = LensSystem::from_prescription(prescription()).unwrap();
        let request = BakeRequest {
            resolution: [6, 5, 4],
            ..BakeRequest::default()
        };
        let table = bake(&system, &request, &|_| {}).unwrap();
        let dir = Scratch::new("original");
        write_table(&table, LENS, &prescription(), &dir.0).unwrap();
        Files {
            data: std::fs::read(dir.0.join(DATA_FILE)).unwrap(),
            sidecar: std::fs::read_to_string(dir.0.join(SIDECAR_FILE)).unwrap(),
        }
    })
}

/// A fresh directory under the system temp dir, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(name: &str) -> Scratch {
        static COUNT: AtomicUsize = AtomicUsize::new(0);
        let n = COUNT.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!(
            "lensbake-hostile-{}-{n}-{name}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }

    /// A directory holding the given table files.
    fn with(name: &str, data: &[u8], sidecar: &str) -> Scratch {
        let scratch = Scratch::new(name);
        std::fs::write(scratch.0.join(DATA_FILE), data).unwrap();
        std::fs::write(scratch.0.join(SIDECAR_FILE), sidecar).unwrap();
        scratch
    }

    fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Loads the table in `dir` against the lens, turning a panic into a test failure that names
/// the case.
fn load(dir: &Path, case: &str) -> Result<LrtfTable, TableError> {
    catch_unwind(AssertUnwindSafe(|| read_table(dir, Some(&prescription()))))
        .unwrap_or_else(|_| panic!("{case}: the loader panicked"))
}

/// Film-side rays over the table's film and pupil, for exercising a loaded table.
fn probe_rays(table: &LrtfTable) -> Vec<LrtfRay> {
    let frame = &table.layers[0].frame;
    let mut rays = Vec::new();
    for i in 0..5 {
        for j in 0..5 {
            let film = [frame.max_film_radius * i as f64 / 4.0, 0.0];
            let rear = [-8.0 + 4.0 * j as f64, 1.0];
            let d = [
                rear[0] - film[0],
                rear[1] - film[1],
                frame.rear_plane_z - frame.film_plane_z,
            ];
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            if n.is_finite() && n > 0.0 && frame.film_plane_z.is_finite() {
                rays.push(LrtfRay {
                    origin: [film[0], film[1], frame.film_plane_z],
                    direction: d.map(|v| v / n),
                });
            }
        }
    }
    rays
}

/// Every lookup on a loaded table answers without panicking, and a passing ray is finite.
fn exercise(table: &LrtfTable, case: &str) {
    let stop = table.layers[0].stop_semi_aperture;
    for ray in probe_rays(table) {
        let looked = catch_unwind(AssertUnwindSafe(|| table.lookup(0, &ray, stop)))
            .unwrap_or_else(|_| panic!("{case}: lookup panicked on {ray:?}"));
        if let Lookup::Passes(out) = looked {
            assert!(
                out.origin
                    .iter()
                    .chain(&out.direction)
                    .all(|v| v.is_finite()),
                "{case}: {out:?}"
            );
        }
    }
}

/// The sidecar with the value of the first `field:` (a one-line value, as the pretty RON
/// writer puts each scalar and tuple on its own line) replaced by `replacement`.
fn with_field(sidecar: &str, field: &str, replacement: &str) -> String {
    let start = sidecar
        .find(&format!("{field}: "))
        .unwrap_or_else(|| panic!("no {field} in the sidecar"));
    let value_start = start + field.len() + 2;
    let line_end = value_start + sidecar[value_start..].find('\n').expect("a line ends");
    let comma = if sidecar[..line_end].ends_with(',') {
        ","
    } else {
        ""
    };
    format!(
        "{}{replacement}{comma}{}",
        &sidecar[..value_start],
        &sidecar[line_end..]
    )
}

#[test]
fn a_sidecar_without_pupil_circles_never_panics_a_lookup() {
    // Found while probing: the loader accepts `circles: []`, and the first lookup then indexed
    // the empty list (a panic in PupilTable::circle_at; `lensbake lrtf eval` died with 101).
    let original = files();
    let start = original.sidecar.find("circles: [").unwrap();
    let end = start + original.sidecar[start..].find(']').unwrap() + 1;
    let sidecar = format!(
        "{}circles: []{}",
        &original.sidecar[..start],
        &original.sidecar[end..]
    );
    let dir = Scratch::with("no-circles", &original.data, &sidecar);
    if let Ok(table) = load(dir.path(), "no pupil circles") {
        exercise(&table, "no pupil circles");
        let pupil = &table.layers[0].pupil;
        assert_eq!(
            pupil.pdf(1.0, [0.0, 0.0]),
            0.0,
            "an empty pupil passes nothing"
        );
        assert_eq!(pupil.sample(1.0, [0.5, 0.5]).pdf, 0.0);
    }
}

/// Names in `dir` other than the two table files (temporary files a write left behind).
fn strays(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .filter(|name| name != DATA_FILE && name != SIDECAR_FILE)
                .collect()
        })
        .unwrap_or_default()
}

#[test]
fn the_original_files_load() {
    // The baseline every mutation below departs from.
    let original = files();
    let dir = Scratch::with("baseline", &original.data, &original.sidecar);
    let table = load(dir.path(), "baseline").expect("the written table loads");
    exercise(&table, "baseline");
}

#[test]
fn missing_files_and_directories_are_typed_errors_naming_the_path() {
    let original = files();
    let check = |dir: &Path, case: &str, expect_data: bool, expected_path: &Path| {
        let error = load(dir, case).expect_err(case);
        let is_data = matches!(error, TableError::Data { .. });
        let is_io = matches!(error, TableError::Io { .. });
        assert!(
            if expect_data { is_data } else { is_io },
            "{case}: {error:?}"
        );
        let message = error.to_string();
        assert!(
            message.contains(&expected_path.display().to_string()),
            "{case}: {message}"
        );
    };
    let dir = Scratch::new("no-sidecar");
    std::fs::write(dir.path().join(DATA_FILE), &original.data).unwrap();
    check(
        dir.path(),
        "sidecar missing",
        false,
        &dir.path().join(SIDECAR_FILE),
    );

    let dir = Scratch::new("no-data");
    std::fs::write(dir.path().join(SIDECAR_FILE), &original.sidecar).unwrap();
    check(dir.path(), "EXR missing", true, &dir.path().join(DATA_FILE));

    let dir = Scratch::new("gone");
    let missing = dir.path().join("no-such-table");
    check(&missing, "table directory missing", false, &missing);

    let dir = Scratch::new("file-as-dir");
    let file = dir.path().join("a-file");
    std::fs::write(&file, b"not a directory").unwrap();
    check(
        &file,
        "a file where the table directory belongs",
        false,
        &file,
    );

    let dir = Scratch::new("dir-as-sidecar");
    std::fs::write(dir.path().join(DATA_FILE), &original.data).unwrap();
    std::fs::create_dir(dir.path().join(SIDECAR_FILE)).unwrap();
    check(
        dir.path(),
        "a directory as the sidecar",
        false,
        &dir.path().join(SIDECAR_FILE),
    );

    let dir = Scratch::new("dir-as-data");
    std::fs::write(dir.path().join(SIDECAR_FILE), &original.sidecar).unwrap();
    std::fs::create_dir(dir.path().join(DATA_FILE)).unwrap();
    check(
        dir.path(),
        "a directory as the EXR",
        true,
        &dir.path().join(DATA_FILE),
    );
}

#[test]
fn truncated_data_files_are_refused() {
    let original = files();
    let len = original.data.len();
    for keep in [
        0,
        1,
        3,
        4,
        8,
        16,
        64,
        300,
        len / 2,
        len - 100,
        len - 8,
        len - 1,
    ] {
        let case = format!("EXR truncated to {keep} of {len} bytes");
        let dir = Scratch::with("truncated", &original.data[..keep], &original.sidecar);
        let error = load(dir.path(), &case).expect_err(&case);
        assert!(
            matches!(error, TableError::Data { .. }),
            "{case}: {error:?}"
        );
    }
}

#[test]
fn corrupted_data_files_are_refused() {
    // OpenEXR carries no checksum, so a flipped bit inside the pixel data can decode to other
    // finite numbers; the sidecar's CRC-32 of the data file catches those (CRC-32 detects every
    // single-bit error). The decoder still runs first, so a header it cannot read keeps its
    // precise message.
    let original = files();
    let (mut by_decoder, mut by_checksum) = (0, 0);
    // Every byte of the header (attributes, offset table), every 5th byte of the pixel data.
    let header = 400.min(original.data.len());
    let positions = (0..header).chain((header..original.data.len()).step_by(5));
    for at in positions {
        let mut data = original.data.clone();
        data[at] ^= 0x10;
        let case = format!("bit 4 of byte {at} flipped");
        let dir = Scratch::with("corrupted", &data, &original.sidecar);
        match load(dir.path(), &case) {
            Err(TableError::Data { .. }) => by_decoder += 1,
            Err(TableError::DataMismatch { .. }) => by_checksum += 1,
            Err(other) => panic!("{case}: {other:?}"),
            Ok(_) => panic!("{case}: loaded"),
        }
    }
    eprintln!(
        "single bit flips in a {} byte EXR: {by_decoder} refused by the decoder, \
         {by_checksum} by the checksum",
        original.data.len()
    );
    assert!(by_decoder > 0 && by_checksum > 0);
}

#[test]
fn sidecars_that_disagree_with_the_data_or_the_lens_are_refused() {
    let original = files();
    let sidecar = &original.sidecar;
    let cases: Vec<(&str, String, fn(&TableError) -> bool)> = vec![
        (
            "the previous format version",
            with_field(sidecar, "format_version", "2"),
            |e| matches!(e, TableError::Version { found: 2, .. }),
        ),
        (
            "an older format version",
            with_field(sidecar, "format_version", "1"),
            |e| matches!(e, TableError::Version { found: 1, .. }),
        ),
        (
            "another parameterisation version",
            with_field(sidecar, "parameterisation_version", "7"),
            |e| matches!(e, TableError::Version { found: 7, .. }),
        ),
        (
            "another prescription",
            with_field(sidecar, "prescription_hash", "\"0123456789abcdef\""),
            |e| matches!(e, TableError::StaleHash { .. }),
        ),
        (
            "more nodes than the data holds",
            with_field(sidecar, "resolution", "(6, 5, 5)"),
            |e| matches!(e, TableError::Data { .. }) && e.to_string().contains("needs 6x25"),
        ),
        (
            "fewer nodes than the data holds",
            with_field(sidecar, "resolution", "(3, 5, 4)"),
            |e| matches!(e, TableError::Data { .. }),
        ),
        (
            "a single node on an axis",
            with_field(sidecar, "resolution", "(6, 1, 20)"),
            |e| matches!(e, TableError::Sidecar { .. }),
        ),
        (
            "node counts whose product overflows",
            with_field(sidecar, "resolution", "(6, 4294967296, 4294967296)"),
            |e| matches!(e, TableError::Data { .. } | TableError::Sidecar { .. }),
        ),
        (
            "a wavelength layer the data lacks",
            with_field(sidecar, "exr_layer", "\"wl1\""),
            |e| matches!(e, TableError::Data { .. }) && e.to_string().contains("wl1"),
        ),
        (
            "no wavelength layers",
            {
                let start = sidecar.find("layers: [").unwrap();
                format!("{}layers: [],\n)", &sidecar[..start])
            },
            |e| matches!(e, TableError::Sidecar { .. }),
        ),
        (
            "three wavelengths listed, one stored",
            {
                let start = sidecar.find("layers: [").unwrap() + "layers: [".len();
                let end = sidecar.rfind(']').unwrap();
                let layer = sidecar[start..end].trim().trim_end_matches(',');
                let renamed = |k: usize| layer.replacen("\"wl0\"", &format!("\"wl{k}\""), 1);
                format!(
                    "{}\n{layer},\n{},\n{},\n{}",
                    &sidecar[..start],
                    renamed(1),
                    renamed(2),
                    &sidecar[end..]
                )
            },
            |e| matches!(e, TableError::Data { .. }) && e.to_string().contains("wl1"),
        ),
    ];
    for (case, text, expected) in cases {
        let dir = Scratch::with("mismatch", &original.data, &text);
        let error = load(dir.path(), case).expect_err(case);
        assert!(expected(&error), "{case}: {error:?}");
        assert!(
            error
                .to_string()
                .contains(&dir.path().display().to_string()),
            "{case}: the message names the table: {error}"
        );
    }
}

#[test]
fn sidecar_numbers_that_cannot_describe_a_table_are_refused() {
    // Each used to load and yield a table whose wavelength, f-number, frame or pupil is NaN,
    // negative or zero: a renderer then traced at NaN nm or divided by a zero radius.
    let original = files();
    let sidecar = &original.sidecar;
    let cases = [
        (
            "wavelength NaN",
            with_field(sidecar, "wavelength_nm", "NaN"),
        ),
        (
            "negative wavelength",
            with_field(sidecar, "wavelength_nm", "-5.0"),
        ),
        ("f-number NaN", with_field(sidecar, "f_number", "NaN")),
        ("zero f-number", with_field(sidecar, "f_number", "0.0")),
        ("film plane NaN", with_field(sidecar, "film_plane_z", "NaN")),
        (
            "infinite film radius",
            with_field(sidecar, "max_film_radius", "inf"),
        ),
        (
            "negative stop",
            with_field(sidecar, "stop_semi_aperture", "-1.0"),
        ),
        (
            "negative pupil radius",
            with_field(sidecar, "radius", "-9.0"),
        ),
        ("pupil centre NaN", with_field(sidecar, "centre_x", "NaN")),
        (
            "focal product NaN",
            with_field(sidecar, "focal_product", "NaN"),
        ),
        (
            "focus map moved off the film plane",
            with_field(sidecar, "rear_focal_z", "0.0"),
        ),
        (
            "finite far focus with the near one at infinity",
            with_field(sidecar, "far_mm", "Some(100.0)"),
        ),
        ("no pupil circles", {
            let start = sidecar.find("circles: [").unwrap();
            let end = start + sidecar[start..].find(']').unwrap() + 1;
            format!("{}circles: []{}", &sidecar[..start], &sidecar[end..])
        }),
    ];
    for (case, text) in cases {
        let dir = Scratch::with("bad-number", &original.data, &text);
        let Err(error) = load(dir.path(), case) else {
            panic!("{case}: loaded");
        };
        assert!(
            matches!(error, TableError::Sidecar { .. }),
            "{case}: {error:?}"
        );
    }
}

#[test]
fn garbage_sidecars_are_typed_errors() {
    let original = files();
    let sidecar = &original.sidecar;
    let mut cases: Vec<(String, Vec<u8>)> = vec![
        ("empty".into(), Vec::new()),
        ("not RON".into(), b"not ron at all (".to_vec()),
        ("binary".into(), (0..=255u8).cycle().take(3000).collect()),
        ("invalid UTF-8".into(), vec![0xff, 0xfe, b'(', 0xc3]),
        ("JSON".into(), br#"{"format_version": 1}"#.to_vec()),
        (
            "a string where a number belongs".into(),
            with_field(sidecar, "format_version", "\"one\"").into_bytes(),
        ),
        (
            "a negative node count".into(),
            with_field(sidecar, "resolution", "(6, -5, 4)").into_bytes(),
        ),
        (
            "an unknown parameterisation".into(),
            with_field(sidecar, "parameterisation", "Polar").into_bytes(),
        ),
        ("deeply nested".into(), "(".repeat(100_000).into_bytes()),
        (
            "deeply nested list".into(),
            format!("(layers: {})", "[".repeat(100_000)).into_bytes(),
        ),
    ];
    // Every prefix cut at a line end, and a few inside tokens.
    for cut in (0..sidecar.len()).step_by(97) {
        cases.push((
            format!("cut at byte {cut}"),
            sidecar.as_bytes()[..cut].to_vec(),
        ));
    }
    for (case, bytes) in cases {
        let dir = Scratch::new("garbage");
        std::fs::write(dir.path().join(DATA_FILE), &original.data).unwrap();
        std::fs::write(dir.path().join(SIDECAR_FILE), &bytes).unwrap();
        let error = load(dir.path(), &case).expect_err(&case);
        assert!(
            matches!(error, TableError::Sidecar { .. } | TableError::Io { .. }),
            "{case}: {error:?}"
        );
        assert!(
            error.to_string().contains(SIDECAR_FILE),
            "{case}: names the sidecar: {error}"
        );
    }
}

/// A second table of the same lens and size (baked at f/4): what a rebake writes over the
/// first.
fn rebaked_at_f4() -> LrtfTable {
    let system = LensSystem::from_prescription(prescription()).unwrap();
    let request = BakeRequest {
        resolution: [6, 5, 4],
        f_number: Some(4.0),
        ..BakeRequest::default()
    };
    bake(&system, &request, &|_| {}).unwrap()
}

#[test]
fn failed_writes_leave_no_temporary_files_and_typed_errors() {
    let original = files();
    let table = rebaked_at_f4();

    // The target is a file, not a directory.
    let dir = Scratch::new("target-is-file");
    let file = dir.path().join("table");
    std::fs::write(&file, b"keep me").unwrap();
    let error = write_table(&table, LENS, &prescription(), &file).unwrap_err();
    assert!(matches!(error, TableError::Io { .. }), "{error:?}");
    assert_eq!(std::fs::read(&file).unwrap(), b"keep me");
    assert_eq!(strays(dir.path()), vec!["table".to_string()]);

    // The data file's name is taken by a directory: the write fails before the sidecar, which
    // keeps describing the old data.
    let dir = Scratch::with("data-is-dir", &original.data, &original.sidecar);
    std::fs::remove_file(dir.path().join(DATA_FILE)).unwrap();
    std::fs::create_dir(dir.path().join(DATA_FILE)).unwrap();
    std::fs::write(dir.path().join(DATA_FILE).join("occupant"), b"x").unwrap();
    let error = write_table(&table, LENS, &prescription(), dir.path()).unwrap_err();
    assert!(
        matches!(error, TableError::Data { .. } | TableError::Io { .. }),
        "{error:?}"
    );
    assert!(strays(dir.path()).is_empty(), "{:?}", strays(dir.path()));
    assert_eq!(
        std::fs::read_to_string(dir.path().join(SIDECAR_FILE)).unwrap(),
        original.sidecar
    );

    // The sidecar's name is taken by a directory: the data is replaced, the sidecar cannot
    // be, and the table then refuses to load rather than pair the new data with anything.
    let dir = Scratch::with("sidecar-is-dir", &original.data, &original.sidecar);
    std::fs::remove_file(dir.path().join(SIDECAR_FILE)).unwrap();
    std::fs::create_dir(dir.path().join(SIDECAR_FILE)).unwrap();
    std::fs::write(dir.path().join(SIDECAR_FILE).join("occupant"), b"x").unwrap();
    let error = write_table(&table, LENS, &prescription(), dir.path()).unwrap_err();
    assert!(matches!(error, TableError::Io { .. }), "{error:?}");
    assert!(strays(dir.path()).is_empty(), "{:?}", strays(dir.path()));
    let error = load(dir.path(), "sidecar is a directory").unwrap_err();
    assert!(matches!(error, TableError::Io { .. }), "{error:?}");
}

#[test]
fn a_temporary_file_left_by_a_killed_writer_does_not_disturb_reads_or_writes() {
    // A writer killed mid-write leaves its `.lrtf.exr.tmp-<pid>`; the final names are never
    // half-written. Documented behaviour: the next write does not sweep such leftovers.
    let original = files();
    let dir = Scratch::with("leftover", &original.data, &original.sidecar);
    let leftover = dir.path().join(format!(".{DATA_FILE}.tmp-4242"));
    std::fs::write(&leftover, &original.data[..100]).unwrap();
    load(dir.path(), "with a leftover temporary file").expect("loads");
    write_table(&rebaked_at_f4(), LENS, &prescription(), dir.path()).unwrap();
    let table = load(dir.path(), "rewritten").expect("loads");
    assert_eq!(table.info.f_number, 4.0);
}

#[test]
fn data_and_sidecar_from_different_bakes_are_refused() {
    // write_table renames the new EXR into place, then the new sidecar. A process killed
    // between the two renames, while rebaking the same lens at f/4 over an f/2 table, leaves
    // the f/4 entries under the f/2 sidecar (same lens hash, same resolution): without the
    // sidecar's checksum of the data file that pair loaded as an f/2 table with the wrong
    // pupil and stop. Both directions of the mix are refused, naming the data file and the
    // command that rebakes the table.
    let original = files();
    let dir = Scratch::new("rebake-f4");
    write_table(&rebaked_at_f4(), LENS, &prescription(), dir.path()).unwrap();
    let rebaked_data = std::fs::read(dir.path().join(DATA_FILE)).unwrap();
    let rebaked_sidecar = std::fs::read_to_string(dir.path().join(SIDECAR_FILE)).unwrap();
    load(dir.path(), "the f/4 pair").expect("a pair written together loads");
    for (case, data, sidecar) in [
        (
            "f/4 data under the f/2 sidecar",
            &rebaked_data,
            &original.sidecar,
        ),
        (
            "f/2 data under the f/4 sidecar",
            &original.data,
            &rebaked_sidecar,
        ),
    ] {
        let mixed = Scratch::with("mixed", data, sidecar);
        let error = load(mixed.path(), case).expect_err(case);
        assert!(
            matches!(error, TableError::DataMismatch { .. }),
            "{case}: {error:?}"
        );
        let message = error.to_string();
        assert!(
            message.contains(&mixed.path().join(DATA_FILE).display().to_string())
                && message.contains(&format!("lensbake bake {LENS} --out")),
            "{case}: {message}"
        );
    }
}

#[test]
fn an_interrupted_bake_leaves_a_complete_table_or_a_typed_error() {
    // `lensbake bake` killed at moments spread over its run: whatever it left must load as a
    // whole table or fail with a typed error, never a half-written file read as data.
    let binary = env!("CARGO_BIN_EXE_lensbake");
    let run = |dir: &Path| {
        std::process::Command::new(binary)
            .args(["bake", LENS, "--resolution", "12", "--out"])
            .arg(dir)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("the binary starts")
    };
    let full = Scratch::new("bake-full");
    let started = std::time::Instant::now();
    assert!(run(full.path()).wait().unwrap().success());
    let duration = started.elapsed();
    load(full.path(), "a complete bake").expect("a full run writes a loadable table");
    let mut leftovers = Vec::new();
    for step in 1..=8 {
        let dir = Scratch::new("bake-killed");
        let mut child = run(dir.path());
        std::thread::sleep(duration * step / 9);
        let _ = child.kill();
        let _ = child.wait();
        let present = |name| dir.path().join(name).exists();
        match load(dir.path(), "after a kill") {
            Ok(table) => exercise(&table, "after a kill"),
            Err(error) => assert!(
                !(present(DATA_FILE) && present(SIDECAR_FILE)),
                "both files present after a kill, yet refused: {error}"
            ),
        }
        leftovers.extend(strays(dir.path()));
    }
    if !leftovers.is_empty() {
        eprintln!("temporary files left by killed bakes: {leftovers:?}");
    }
}

/// 32-bit values that hit the corners of EXR header fields (sizes, offsets, counts).
const EXTREME_WORDS: [u32; 8] = [
    0,
    1,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_ffff,
    0x0001_0000,
    0x4000_0000,
    0xfffe_0000,
];

/// Values that hit the corners of the sidecar's numbers.
const EXTREME_NUMBERS: [&str; 12] = [
    "NaN",
    "inf",
    "-inf",
    "-1",
    "0",
    "1e308",
    "-1e-308",
    "18446744073709551615",
    "4294967296",
    "2",
    "0.0",
    "-0.0",
];

fn mutate_data(rng: &mut Rng, input: &[u8]) -> Vec<u8> {
    let mut out = input.to_vec();
    for _ in 0..1 + rng.below(3) {
        if out.is_empty() {
            break;
        }
        let at = rng.below(out.len());
        match rng.below(6) {
            0 => out[at] ^= 1 << rng.below(8),
            1 => out[at] = rng.next() as u8,
            2 => out.truncate(at),
            3 => {
                let end = (at + 1 + rng.below(64)).min(out.len());
                out.drain(at..end);
            }
            4 => {
                let word = EXTREME_WORDS[rng.below(EXTREME_WORDS.len())].to_le_bytes();
                let end = (at + 4).min(out.len());
                out[at..end].copy_from_slice(&word[..end - at]);
            }
            _ => {
                let end = (at + 1 + rng.below(64)).min(out.len());
                let copy = out[at..end].to_vec();
                let to = rng.below(out.len());
                out.splice(to..to, copy);
            }
        }
    }
    out
}

fn mutate_sidecar(rng: &mut Rng, input: &str) -> String {
    let mut lines: Vec<String> = input.lines().map(str::to_string).collect();
    for _ in 0..1 + rng.below(3) {
        let at = rng.below(lines.len());
        match rng.below(4) {
            0 | 1 => {
                // Replace the number on a `field: number` line.
                let line = &lines[at];
                if let Some(colon) = line.find(": ") {
                    let comma = if line.ends_with(',') { "," } else { "" };
                    let number = EXTREME_NUMBERS[rng.below(EXTREME_NUMBERS.len())];
                    lines[at] = format!("{}: {number}{comma}", &line[..colon]);
                }
            }
            2 => {
                lines.remove(at);
            }
            _ => {
                let copy = lines[at].clone();
                lines.insert(rng.below(lines.len()), copy);
            }
        }
        if lines.is_empty() {
            break;
        }
    }
    lines.join("\n")
}

#[test]
fn fuzz_the_table_loader() {
    let original = files();
    let seed = 0x5EED_7AB1_E000_0001;
    let mut rng = Rng(seed);
    let dir = Scratch::new("fuzz");
    // A fixed number of seeded cases, so every run (and every machine) tests the same tables.
    let cases = 400;
    let mut loaded = 0usize;
    for case in 0..cases {
        let (data, sidecar) = match rng.below(3) {
            0 => (
                mutate_data(&mut rng, &original.data),
                original.sidecar.clone(),
            ),
            1 => (
                original.data.clone(),
                mutate_sidecar(&mut rng, &original.sidecar),
            ),
            _ => (
                mutate_data(&mut rng, &original.data),
                mutate_sidecar(&mut rng, &original.sidecar),
            ),
        };
        std::fs::write(dir.path().join(DATA_FILE), &data).unwrap();
        std::fs::write(dir.path().join(SIDECAR_FILE), &sidecar).unwrap();
        let case = format!("fuzz case {case} (seed {seed:#x})");
        if let Ok(table) = load(dir.path(), &case) {
            exercise(&table, &case);
            loaded += 1;
        }
    }
    eprintln!("table loader fuzz: {cases} mutated tables, {loaded} loaded");
    // Both paths run: most mutations must be refused (the CRC and the sidecar checks), and some
    // (a sidecar's whitespace, a number rewritten to its own value) must still load.
    assert!(
        loaded > 0 && loaded < cases / 2,
        "{loaded} of {cases} loaded"
    );
}

#[test]
fn the_command_line_reports_hostile_tables_as_errors() {
    // `lensbake lrtf info` and `lrtf eval` on broken tables: exit status 2 and `error: ...`
    // naming the file, never a panic (status 101).
    let binary = env!("CARGO_BIN_EXE_lensbake");
    let original = files();
    let rays = Scratch::new("cli-rays");
    let rays_file = rays.path().join("rays.json");
    std::fs::write(
        &rays_file,
        r#"[{"origin": [1.0, 0.0, 68.0], "direction": [0.0, 0.0, -1.0]}]"#,
    )
    .unwrap();
    let no_circles = {
        let sidecar = &original.sidecar;
        let start = sidecar.find("circles: [").unwrap();
        let end = start + sidecar[start..].find(']').unwrap() + 1;
        format!("{}circles: []{}", &sidecar[..start], &sidecar[end..])
    };
    let cases: Vec<(&str, Scratch, Option<&str>)> = vec![
        (
            "truncated EXR",
            Scratch::with("cli-truncated", &original.data[..1000], &original.sidecar),
            Some(DATA_FILE),
        ),
        (
            "garbage sidecar",
            Scratch::with("cli-garbage", &original.data, "(((("),
            Some(SIDECAR_FILE),
        ),
        (
            "missing table",
            Scratch::new("cli-empty"),
            Some(SIDECAR_FILE),
        ),
        // The loader accepts this one today (see the ignored test above); the lookup must
        // still answer.
        (
            "no pupil circles",
            Scratch::with("cli-no-circles", &original.data, &no_circles),
            None,
        ),
    ];
    for (case, dir, names) in &cases {
        for args in [vec!["lrtf", "info"], vec!["lrtf", "eval"]] {
            let mut command = std::process::Command::new(binary);
            command.args(&args).arg(dir.path());
            if args[1] == "eval" {
                command.arg("--rays").arg(&rays_file);
            }
            let output = command.output().expect("the binary runs");
            let stderr = String::from_utf8_lossy(&output.stderr);
            let status = output.status.code();
            assert!(!stderr.contains("panicked"), "{case} {args:?}: {stderr}");
            match names {
                Some(name) if !(args[1] == "info" && *name == DATA_FILE) => {
                    assert_eq!(status, Some(2), "{case} {args:?}: {stderr}");
                    assert!(
                        stderr.starts_with("error: ") && stderr.contains(name),
                        "{case} {args:?}: {stderr}"
                    );
                }
                _ => assert!(
                    matches!(status, Some(0) | Some(2)),
                    "{case} {args:?}: status {status:?}, {stderr}"
                ),
            }
        }
    }
}
