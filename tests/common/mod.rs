//! Shared helpers for the truth-data tests: locating tests/data/truth and turning an oracle
//! JSON lens table into a Prescription.
//!
//! Each integration test compiles this module on its own and uses only part of it.
#![allow(dead_code)]

use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
use serde_json::Value;
use std::path::PathBuf;

/// Truth data copied into the repo from established programs (provenance in its README.md).
pub fn testdata_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/truth")
}

/// A lens file of the truth data.
pub fn lens_file(name: &str) -> PathBuf {
    testdata_dir().join("lenses").join(name)
}

/// A file of this crate's own test data (tests/data).
pub fn test_data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// Longest a test waits for one command. Far longer than any command of the tests takes on a
/// loaded two-core machine: a command that reaches it hangs, and the test fails naming it
/// instead of holding CI until its own limit.
pub const COMMAND_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(600);

/// Runs `command` with `stdin` on its standard input (none: the null device) and `stdout` as
/// its standard output (None: captured into the output), its standard error captured; None
/// where it ran past `timeout` and was killed.
pub fn output_within(
    command: &mut std::process::Command,
    stdin: Option<&str>,
    stdout: Option<std::process::Stdio>,
    timeout: std::time::Duration,
) -> Option<std::process::Output> {
    use std::io::Write;
    use std::process::Stdio;
    let mut child = command
        .stdin(if stdin.is_some() {
            Stdio::piped()
        } else {
            Stdio::null()
        })
        .stdout(stdout.unwrap_or_else(Stdio::piped))
        .stderr(Stdio::piped())
        .spawn()
        .expect("the lensbake binary starts");
    if let (Some(text), Some(mut pipe)) = (stdin, child.stdin.take()) {
        let text = text.to_string();
        // A command that exits before reading its input closes the pipe: not the test's error.
        std::thread::spawn(move || pipe.write_all(text.as_bytes()));
    }
    let out = read_all(child.stdout.take());
    let err = read_all(child.stderr.take());
    let started = std::time::Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("the child's status") {
            break status;
        }
        if started.elapsed() > timeout {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    };
    Some(std::process::Output {
        status,
        stdout: out.join().expect("stdout reader"),
        stderr: err.join().expect("stderr reader"),
    })
}

/// Reads `pipe` to its end on a thread of its own, so that a child filling one pipe cannot
/// block on it while the other is read.
fn read_all(pipe: Option<impl std::io::Read + Send + 'static>) -> std::thread::JoinHandle<Vec<u8>> {
    std::thread::spawn(move || {
        let mut bytes = Vec::new();
        if let Some(mut pipe) = pipe {
            let _ = pipe.read_to_end(&mut bytes);
        }
        bytes
    })
}

/// `command` run to its end within [`COMMAND_TIMEOUT`], its output captured; a hang fails the
/// test with the command's arguments.
pub fn finished(command: &mut std::process::Command, stdin: Option<&str>) -> std::process::Output {
    let described = format!("{command:?}");
    output_within(command, stdin, None, COMMAND_TIMEOUT)
        .unwrap_or_else(|| panic!("{described} ran past {COMMAND_TIMEOUT:?}: it hangs"))
}

#[cfg(feature = "cli")]
/// This build's `lensbake` binary with `args`, run from the test's working directory (the
/// crate's root), within [`COMMAND_TIMEOUT`].
pub fn lensbake(args: &[&str]) -> std::process::Output {
    finished(
        std::process::Command::new(env!("CARGO_BIN_EXE_lensbake")).args(args),
        None,
    )
}

#[cfg(feature = "cli")]
/// `lensbake bake LENS --resolution 4 --out TABLE` with `extra` options: a table small enough
/// for a command-line test.
pub fn bake_small(
    lens: &std::path::Path,
    table: &std::path::Path,
    extra: &[&str],
) -> std::process::Output {
    let mut args = vec![
        "bake",
        lens.to_str().unwrap(),
        "--resolution",
        "4",
        "--out",
        table.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    lensbake(&args)
}

/// Relative difference, safe at zero.
pub fn relative(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / a.abs().max(b.abs())
    }
}

pub fn oracle_dir() -> PathBuf {
    testdata_dir().join("oracle")
}

/// The four oracle lenses.
pub const ORACLE_LENSES: [&str; 4] = [
    "codev_ag_dblgauss",
    "kolb_dgauss_1995_nobj1",
    "optiland_cooke_triplet",
    "pbrt_dgauss_50mm",
];

/// Indices at the F and C lines of every medium, from the table's nF/nC columns.
#[derive(Clone, Debug, PartialEq)]
pub struct LineIndices {
    pub f_nm: f64,
    pub c_nm: f64,
    pub object_f: f64,
    pub object_c: f64,
    /// After each surface.
    pub f: Vec<f64>,
    pub c: Vec<f64>,
}

/// One oracle lens: its whole JSON file and the prescription built from `lenses[0]`.
pub struct OracleLens {
    pub name: String,
    pub json: Value,
    /// Constant indices at the lens wavelength (Medium::Index), stop marked as in the table.
    pub prescription: Prescription,
    /// Present when the table gives nF and nC for every medium.
    pub lines: Option<LineIndices>,
}

impl OracleLens {
    /// `lenses[0]` of the file.
    pub fn lens(&self) -> &Value {
        &self.json["lenses"][0]
    }

    pub fn wavelength_nm(&self) -> f64 {
        num(&self.lens()["wavelength_nm"])
    }

    pub fn epd_used(&self) -> f64 {
        num(&self.lens()["system"]["epd_used"])
    }

    pub fn max_field_angle_deg(&self) -> f64 {
        num(&self.lens()["system"]["max_field_angle_deg"])
    }
}

/// A JSON number (panics with the value when it is not one: test data is trusted to be).
pub fn num(value: &Value) -> f64 {
    value
        .as_f64()
        .unwrap_or_else(|| panic!("expected a number, found {value}"))
}

/// A JSON array of numbers.
pub fn nums(value: &Value) -> Vec<f64> {
    value
        .as_array()
        .unwrap_or_else(|| panic!("expected an array, found {value}"))
        .iter()
        .map(num)
        .collect()
}

/// An array of arrays of numbers, row by row.
pub fn nums_rows(value: &Value) -> Vec<Vec<f64>> {
    value
        .as_array()
        .unwrap_or_else(|| panic!("expected an array, found {value}"))
        .iter()
        .map(nums)
        .collect()
}

/// Reads `oracle/<name>.json`.
pub fn load_oracle(name: &str) -> OracleLens {
    let path = oracle_dir().join(format!("{name}.json"));
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let json: Value = serde_json::from_str(&text)
        .unwrap_or_else(|e| panic!("cannot parse {}: {e}", path.display()));
    let lens = &json["lenses"][0];
    let table = &lens["prescription"];
    let rows = table["surfaces"].as_array().expect("prescription.surfaces");
    let prescription = oracle_prescription(lens);
    let lines = line_indices(table, rows);
    OracleLens {
        name: name.to_string(),
        json,
        prescription,
        lines,
    }
}

fn line_indices(table: &Value, rows: &[Value]) -> Option<LineIndices> {
    let wavelengths = &table["index_wavelengths_nm"];
    let column = |key: &str| {
        rows.iter()
            .map(|r| r[key].as_f64())
            .collect::<Option<Vec<_>>>()
    };
    Some(LineIndices {
        f_nm: wavelengths["nF"].as_f64()?,
        c_nm: wavelengths["nC"].as_f64()?,
        object_f: table["object_space_index_F"].as_f64()?,
        object_c: table["object_space_index_C"].as_f64()?,
        f: column("nF")?,
        c: column("nC")?,
    })
}

/// |actual - expected| <= rel * |expected| + abs, with a message naming the quantity.
pub fn assert_close(actual: f64, expected: f64, rel: f64, abs: f64, what: &str) {
    let error = (actual - expected).abs();
    assert!(
        error <= rel * expected.abs() + abs,
        "{what}: got {actual:.15e}, expected {expected:.15e} (error {error:.3e}, allowed \
         {rel:e} relative + {abs:e} absolute)"
    );
}

/// The value as printed with `decimals` digits after the point matches `printed`.
pub fn assert_printed(actual: f64, printed: f64, decimals: i32, what: &str) {
    assert_printed_within(actual, printed, decimals, 0.0, what);
}

/// As [`assert_printed`], widened by `input_uncertainty`: what our value inherits from an input
/// that was itself only known to its printed digits.
pub fn assert_printed_within(
    actual: f64,
    printed: f64,
    decimals: i32,
    input_uncertainty: f64,
    what: &str,
) {
    // Half a unit in the last printed place, plus a hair for the printed value's own binary
    // representation.
    let half_unit = 0.5 * 10f64.powi(-decimals) * (1.0 + 1e-9);
    let allowed = half_unit + input_uncertainty;
    assert!(
        (actual - printed).abs() <= allowed,
        "{what}: got {actual:.10}, printed {printed} ({decimals} decimals, allowed {allowed:.2e})"
    );
}

/// Largest deviations seen per class of quantity, for the report the tests print.
#[derive(Default)]
pub struct Tally {
    worst: std::collections::BTreeMap<String, (f64, String)>,
}

impl Tally {
    /// Checks like [`assert_close`] and records the deviation under `class`: relative where
    /// |expected| >= 1e-3, absolute (in the quantity's unit) below that.
    pub fn check(
        &mut self,
        class: &str,
        actual: f64,
        expected: f64,
        rel: f64,
        abs: f64,
        what: &str,
    ) {
        assert_close(actual, expected, rel, abs, what);
        let error = (actual - expected).abs();
        let (key, measure) = if expected.abs() >= 1e-3 {
            (format!("{class} [relative]"), error / expected.abs())
        } else {
            (format!("{class} [absolute, |x| < 1e-3]"), error)
        };
        let entry = self.worst.entry(key).or_insert((0.0, String::new()));
        if measure >= entry.0 {
            *entry = (measure, what.to_string());
        }
    }

    /// Prints the table (visible with `cargo test -- --nocapture`).
    pub fn print(&self, title: &str) {
        eprintln!("largest deviations, {title}:");
        for (class, (measure, what)) in &self.worst {
            eprintln!("  {class:<58} {measure:.2e}  ({what})");
        }
    }
}

/// The value at a dotted path ("a.b.0.c"; numeric parts index arrays); panics naming the path
/// when it is missing.
pub fn get<'a>(value: &'a Value, path: &str) -> &'a Value {
    path.split('.').fold(value, |v, key| {
        let next = match key.parse::<usize>() {
            Ok(i) if v.is_array() => &v[i],
            _ => &v[key],
        };
        assert!(!next.is_null(), "missing {path} (at `{key}`)");
        next
    })
}

/// Parses one oracle file (name with extension) as JSON.
pub fn oracle_json(file: &str) -> Value {
    let path = oracle_dir().join(file);
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("bad JSON in {}: {e}", path.display()))
}

/// The prescription table of an oracle file (`lenses[0].prescription`).
pub fn oracle_table(file: &str) -> Value {
    oracle_json(file)["lenses"][0]["prescription"].clone()
}

/// The surfaces of the first lens of an oracle file.
pub fn oracle_surfaces(file: &str) -> Vec<Value> {
    oracle_json(file)["lenses"][0]["prescription"]["surfaces"]
        .as_array()
        .expect("oracle prescription has surfaces")
        .clone()
}

/// Every oracle file, parsed, with its file stem.
pub fn oracle_files() -> Vec<(String, Value)> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(oracle_dir())
        .expect("oracle directory is readable")
        .map(|entry| entry.expect("directory entry").path())
        .filter(|path| path.extension().is_some_and(|e| e == "json"))
        .collect();
    files.sort();
    assert!(
        !files.is_empty(),
        "no oracle files in {}",
        oracle_dir().display()
    );
    files
        .into_iter()
        .map(|path| {
            let text = std::fs::read_to_string(&path).expect("oracle file is readable");
            let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
            (
                stem,
                serde_json::from_str(&text).expect("oracle file is JSON"),
            )
        })
        .collect()
}

/// The constant-index prescription of an oracle lens (`lenses[i]`), as the oracle used it.
pub fn oracle_prescription(lens: &Value) -> Prescription {
    let table = &lens["prescription"];
    let surfaces = table["surfaces"]
        .as_array()
        .expect("surfaces array")
        .iter()
        .map(|s| Surface {
            shape: match num(&s["curvature"]) {
                0.0 => Shape::Plane,
                curvature => Shape::Sphere { curvature },
            },
            thickness: num(&s["thickness"]),
            medium: Medium::Index(num(&s["n"])),
            semi_aperture: num(&s["semi_aperture"]),
            stop: s["stop"].as_bool().unwrap().then_some(StopShape::Circle),
            obscuration: None,
        })
        .collect();
    Prescription {
        provenance: Provenance {
            title: lens["name"].as_str().unwrap_or("oracle lens").to_string(),
            source: lens["source"].as_str().map(str::to_string),
            design_wavelength_nm: lens["wavelength_nm"].as_f64(),
            ..Provenance::default()
        },
        object_medium: Medium::Index(num(&table["object_space_index"])),
        surfaces,
    }
}

pub fn vec3(v: &Value) -> [f64; 3] {
    let a = v
        .as_array()
        .unwrap_or_else(|| panic!("expected a 3-vector, found {v}"));
    [num(&a[0]), num(&a[1]), num(&a[2])]
}

#[cfg(feature = "render")]
/// The GPU renderer, or None outside CI when this machine has no adapter. In CI a missing
/// adapter is a failure: CI installs lavapipe precisely so these tests run.
pub fn gpu_or_skip(test: &str) -> Option<lensbake::render::gpu::GpuRenderer> {
    use lensbake::render::RenderError;
    match lensbake::render::gpu::GpuRenderer::new() {
        Ok(gpu) => Some(gpu),
        Err(RenderError::NoAdapter(why)) if std::env::var("CI").as_deref() != Ok("true") => {
            eprintln!("SKIPPED {test}: no GPU adapter ({why}); install mesa-vulkan-drivers");
            None
        }
        Err(e) => panic!("{test}: GPU unavailable: {e}"),
    }
}

/// Asserts that the Rust struct `$ty` (shared with a shader) has the layout naga gives the WGSL
/// struct of the same name (or `$wgsl_name`) in `$source`: the same size, each listed field at
/// the same offset, and every WGSL member either listed or a `pad*`/`_pad*` word (Rust pads with
/// arrays where WGSL names each word), so a member added on one side only fails.
#[allow(unused_macros)]
macro_rules! assert_wgsl_layout {
    ($source:expr, $ty:ident { $($field:ident),* $(,)? }) => {
        $crate::common::assert_wgsl_layout!(@check $source, $ty, stringify!($ty), [$($field),*])
    };
    ($source:expr, $ty:ident as $wgsl_name:literal { $($field:ident),* $(,)? }) => {
        $crate::common::assert_wgsl_layout!(@check $source, $ty, $wgsl_name, [$($field),*])
    };
    (@check $source:expr, $ty:ident, $wgsl_name:expr, [$($field:ident),*]) => {{
        let name = $wgsl_name;
        let (members, span) = $crate::common::wgsl_struct($source, name);
        assert_eq!(span, std::mem::size_of::<$ty>(), "size of {name}");
        let rust = [$((stringify!($field), std::mem::offset_of!($ty, $field))),*];
        for (field, offset) in rust {
            let wgsl = members
                .iter()
                .find(|(member, _)| member == field)
                .unwrap_or_else(|| panic!("{name}.{field} missing from the WGSL struct"));
            assert_eq!(wgsl.1, offset, "{name}.{field}");
        }
        for (member, _) in &members {
            assert!(
                member.trim_start_matches('_').starts_with("pad")
                    || rust.iter().any(|(field, _)| field == member),
                "{name}.{member} is in the WGSL struct but not in the Rust one"
            );
        }
    }};
}
#[allow(unused_imports)]
pub(crate) use assert_wgsl_layout;

/// xorshift64*: small and seeded, so a failing case can be replayed by its seed and index.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// The members (name, byte offset) and the size of struct `name` in WGSL `source`, as naga lays
/// them out: what a Rust struct shared with the shader must match.
pub fn wgsl_struct(source: &str, name: &str) -> (Vec<(String, usize)>, usize) {
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(source)));
    module
        .types
        .iter()
        .find_map(|(_, ty)| match (&ty.name, &ty.inner) {
            (Some(found), naga::TypeInner::Struct { members, span }) if found == name => Some((
                members
                    .iter()
                    .map(|m| (m.name.clone().unwrap_or_default(), m.offset as usize))
                    .collect(),
                *span as usize,
            )),
            _ => None,
        })
        .unwrap_or_else(|| panic!("no struct {name} in the WGSL source"))
}

/// The double Gauss at the design wavelength, wide open, with its first-order models.
pub fn dgauss() -> (
    lensbake::lenses::LoadedLens,
    lensbake::model::FirstOrderModels,
) {
    let lens = lensbake::lenses::load("dgauss-50mm", &Default::default()).unwrap();
    let first = lensbake::model::FirstOrderModels::of(&lens.system, None).unwrap();
    (lens, first)
}

#[cfg(feature = "render")]
/// Traced and baked cameras for the double Gauss wide open, a full-frame sensor tilted by
/// `tilt_deg` centred on the 2 m focus (the demo scene's chart): a 32^3 table baked for that
/// focus and for the film radii the sensor's rays cross its film plane at (small so the tests
/// stay fast), and the traced model sampling the table's pupil circles, so both draw identical
/// lens samples.
pub fn dgauss_cameras(
    width: u32,
    height: u32,
    tilt_deg: [f64; 2],
) -> (
    lensbake::render::camera::Camera,
    lensbake::render::camera::Camera,
) {
    dgauss_cameras_focused(width, height, tilt_deg, 2000.0)
}

#[cfg(feature = "render")]
/// [`dgauss_cameras`] focused at `focus_mm` in front of the lens, the table baked for it.
pub fn dgauss_cameras_focused(
    width: u32,
    height: u32,
    tilt_deg: [f64; 2],
    focus_mm: f64,
) -> (
    lensbake::render::camera::Camera,
    lensbake::render::camera::Camera,
) {
    use lensbake::lrtf::bake::{BakeRequest, bake};
    use lensbake::model::LensModel;
    use lensbake::model::{BakedLens, TracedLens, pupil_film_radius};
    use lensbake::render::camera::{Camera, Film, Focus};
    let (lens, first) = dgauss();
    let film = Film {
        tilt_deg,
        ..Film::full_frame_for(width, height)
    };
    let design = lens.system.at(lens.system.design_wavelength_nm());
    let thick = LensModel::Thick(first.thick.clone());
    let focused = Camera::new(thick, film, Focus::ObjectDistance(focus_mm)).unwrap();
    let request = BakeRequest {
        resolution: [32; 3],
        focus_mm: Some(focus_mm),
        max_film_radius: Some(pupil_film_radius(
            &design,
            focused.film_z,
            focused.film_corner_radius(),
            focused.film_off_plane(),
        )),
        ..BakeRequest::default()
    };
    let table = bake(&lens.system, &request).unwrap();
    let pupil = table.layers[0].pupil.clone();
    let baked = BakedLens::new(table, &first, first.f_number).unwrap();
    let film_z = baked.film_z();
    let traced = TracedLens::new(&lens.system, &first, first.f_number, pupil);
    let camera = |model| Camera::new(model, film, Focus::FilmZ(film_z)).unwrap();
    (
        camera(LensModel::Traced(Box::new(traced))),
        camera(LensModel::Baked(Box::new(baked))),
    )
}

#[cfg(feature = "render")]
/// How many channels of two renders differ beyond f32 rounding (1e-3 relative), and the mean
/// absolute difference over the other channels.
pub fn channel_differences(
    a: &lensbake::render::image::RgbImage,
    b: &lensbake::render::image::RgbImage,
) -> (usize, f64) {
    let (mut large, mut total_abs) = (0usize, 0.0f64);
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let d = (p[c] - q[c]).abs();
            if d > 1e-3 * (1.0 + p[c].abs()) {
                large += 1;
            } else {
                total_abs += d as f64;
            }
        }
    }
    let agreeing = (3 * a.pixels.len() - large).max(1);
    (large, total_abs / agreeing as f64)
}

/// A singlet that images an axial object at infinity perfectly: the front surface is the
/// Cartesian ellipsoid of index `n` (conic -1/n^2, vertex radius `radius`), which focuses every
/// parallel ray at f = n R / (n - 1) behind its vertex, and the rear surface is a sphere centred
/// on that focus, which every converging ray meets at normal incidence. The stop is the front
/// surface. `as_asphere` writes the ellipsoid as an even asphere (Newton intersection) instead
/// of a conic (closed-form intersection).
pub fn cartesian_singlet(
    n: f64,
    radius: f64,
    thickness: f64,
    semi_aperture: f64,
    as_asphere: bool,
) -> lensbake::system::LensSystem {
    let focus = n * radius / (n - 1.0);
    let rear_radius = focus - thickness;
    let (curvature, conic) = (1.0 / radius, -1.0 / (n * n));
    lensbake::system::LensSystem::from_prescription(Prescription {
        provenance: Provenance {
            title: "Cartesian aspheric singlet".into(),
            ..Provenance::default()
        },
        object_medium: Medium::Air,
        surfaces: vec![
            Surface {
                shape: if as_asphere {
                    Shape::EvenAsphere {
                        curvature,
                        conic,
                        coefficients: vec![0.0; 3],
                    }
                } else {
                    Shape::Conic { curvature, conic }
                },
                thickness,
                medium: Medium::Index(n),
                semi_aperture,
                stop: Some(StopShape::Circle),
                obscuration: None,
            },
            Surface {
                shape: Shape::Sphere {
                    curvature: 1.0 / rear_radius,
                },
                thickness: rear_radius,
                medium: Medium::Air,
                semi_aperture: semi_aperture.min(rear_radius),
                stop: None,
                obscuration: None,
            },
        ],
    })
    .expect("a valid singlet")
}

/// The f/0.95 Cartesian singlet: n = 1.8, R = 20 mm gives f = 45 mm behind the front vertex,
/// EFL 45 mm; a 23.7 mm semi-aperture is f/0.949, inside the ellipsoid's rim at 24.06 mm.
pub fn f095_singlet(as_asphere: bool) -> lensbake::system::LensSystem {
    cartesian_singlet(1.8, 20.0, 20.0, 23.7, as_asphere)
}

/// A table sidecar's text with its fields' checksum recomputed, as a faulty writer would have
/// sealed it, so a test reaches the checks behind the checksum.
pub fn sealed(text: &str) -> String {
    let mut sidecar: lensbake::lrtf::io::Sidecar = ron::from_str(text).unwrap();
    sidecar.sidecar_crc32 = Some(sidecar.fields_checksum());
    ron::ser::to_string_pretty(&sidecar, ron::ser::PrettyConfig::default()).unwrap()
}

/// Traces `batch` forward both as a batch and ray by ray, asserts the two agree bit for bit
/// (outcome and ray), and returns how many rays passed.
pub fn batch_matches_one_ray(
    tracer: &lensbake::trace::Tracer,
    batch: &lensbake::trace::RayBatch,
) -> usize {
    batch_matches_one_ray_going(tracer, batch, lensbake::trace::Travel::Forward)
}

/// [`batch_matches_one_ray`] for rays travelling `travel`.
pub fn batch_matches_one_ray_going(
    tracer: &lensbake::trace::Tracer,
    batch: &lensbake::trace::RayBatch,
    travel: lensbake::trace::Travel,
) -> usize {
    let traced = tracer.trace_batch(batch, travel, lensbake::trace::Apertures::Checked);
    let mut passed = 0;
    for (i, ray) in batch.iter().enumerate() {
        let one = tracer.trace(ray, travel);
        assert_eq!(traced.outcomes[i], one.outcome, "{travel:?} ray {i}");
        assert_eq!(traced.rays.get(i).unwrap(), one.ray, "{travel:?} ray {i}");
        passed += usize::from(one.outcome.is_ok());
    }
    passed
}
