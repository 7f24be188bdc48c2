//! `lensbake export`, checked by programs lensbake did not write: every exported shader compiled
//! by an independent compiler, and the exported GLSL sampler and trace run by an independent
//! consumer (tools/engine_consumer.py: moderngl on Mesa's llvmpipe), ray by ray against
//! lensbake's own table lookup on baked tables of every kind and against its own GPU trace.
//! Outside CI a missing tool skips its check; with CI=true (.ci/engines.sh installs them) it
//! fails.
#![cfg(feature = "cli")]

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use lensbake::export::{Language, Shader, export_shader};
use lensbake::lrtf::io::{FORMAT_VERSION, read_table};
use lensbake::lrtf::table::{LRTF_BLOCKED, LRTF_OUTSIDE, LRTF_PASSES, LRTF_VERSION_MISMATCH};
use lensbake::lrtf::{Lookup, LrtfTable, Parameterisation, Ray};

fn in_ci() -> bool {
    std::env::var("CI").as_deref() == Ok("true")
}

/// `program` if it runs here; None (the check skipped) outside CI, a failure in CI.
fn available(program: &str, probe: &[&str], test: &str) -> Option<String> {
    let runs = Command::new(program)
        .args(probe)
        .output()
        .is_ok_and(|o| o.status.success());
    match (runs, in_ci()) {
        (true, _) => Some(program.to_string()),
        (false, false) => {
            eprintln!("SKIPPED {test}: `{program}` is missing (.ci/engines.sh installs it)");
            None
        }
        (false, true) => panic!("{test}: `{program}` is missing in CI"),
    }
}

/// The Python with moderngl the consumer runs under: $LENSBAKE_ENGINE_PYTHON, else python3.
fn consumer_python(test: &str) -> Option<String> {
    let python = std::env::var("LENSBAKE_ENGINE_PYTHON").unwrap_or_else(|_| "python3".into());
    available(&python, &["-c", "import moderngl"], test)
}

fn run_ok(command: &mut Command) -> String {
    let described = format!("{command:?}");
    let out = common::finished(command, None);
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{described} failed:\n{text}");
    text
}

fn entry_points(shader: Shader) -> Vec<String> {
    naga::front::wgsl::parse_str(shader.wgsl())
        .expect("the assembled WGSL parses")
        .entry_points
        .iter()
        .map(|e| e.name.clone())
        .collect()
}

#[test]
fn every_shader_exports_in_every_language() {
    for shader in Shader::ALL {
        for language in Language::ALL {
            let exported = export_shader(shader, language, None)
                .unwrap_or_else(|e| panic!("{} {}: {e}", shader.name(), language.name()));
            assert_eq!(exported.entry_point, entry_points(shader)[0]);
            if language == Language::Spirv {
                assert_eq!(exported.bytes[..4], 0x0723_0203u32.to_le_bytes());
                continue;
            }
            let text = String::from_utf8(exported.bytes).expect("text");
            let version = format!("format_version {}", lensbake::lrtf::io::FORMAT_VERSION);
            assert!(
                text.contains(&version),
                "{} {}",
                shader.name(),
                language.name()
            );
            // GLSL calls its one entry point main.
            let entry = match language {
                Language::Glsl => "void main()",
                _ => &exported.entry_point,
            };
            assert!(
                text.contains(entry),
                "{} {}",
                shader.name(),
                language.name()
            );
        }
    }
    let refused = export_shader(Shader::Sampler, Language::Glsl, Some("render")).unwrap_err();
    assert!(
        refused.to_string().contains("lrtf_sample_rays"),
        "{refused}"
    );
}

/// glslangValidator (GLSL, and HLSL through its HLSL front end), spirv-val, and spirv-cross
/// translating the SPIR-V to HLSL and MSL. MSL has no independent compiler here (Apple's is
/// macOS-only); WGSL's only other compiler at hand is wgpu's, which the renderer tests run.
#[test]
fn independent_compilers_accept_every_export() {
    let test = "independent_compilers_accept_every_export";
    let Some(glslang) = available("glslangValidator", &["--version"], test) else {
        return;
    };
    let Some(spirv_val) = available("spirv-val", &["--version"], test) else {
        return;
    };
    let Some(spirv_cross) = available("spirv-cross", &["--help"], test) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    for shader in Shader::ALL {
        for entry in entry_points(shader) {
            let path = |language: Language| {
                dir.path().join(format!(
                    "{}-{entry}.{}",
                    shader.name(),
                    language.extension()
                ))
            };
            let write = |language: Language| {
                let exported = export_shader(shader, language, Some(&entry)).unwrap();
                std::fs::write(path(language), exported.bytes).unwrap();
                path(language)
            };
            run_ok(Command::new(&glslang).arg(write(Language::Glsl)));
            // glslang's HLSL front end compiles to SPIR-V, which spirv-val then checks too.
            let from_hlsl = dir
                .path()
                .join(format!("{}-{entry}-hlsl.spv", shader.name()));
            run_ok(
                Command::new(&glslang)
                    .args(["-V", "-D", "-S", "comp", "-e", &entry, "-o"])
                    .arg(&from_hlsl)
                    .arg(write(Language::Hlsl)),
            );
            run_ok(Command::new(&spirv_val).arg(&from_hlsl));
            let spv = write(Language::Spirv);
            run_ok(Command::new(&spirv_val).arg(&spv));
            run_ok(
                Command::new(&spirv_cross)
                    .arg(&spv)
                    .args(["--hlsl", "--shader-model", "51"]),
            );
            run_ok(Command::new(&spirv_cross).arg(&spv).args(["--msl"]));
        }
    }
}

/// Status code of the shader's `LrtfResult` for a CPU lookup.
fn status_of(lookup: &Lookup) -> u32 {
    match lookup {
        Lookup::Passes(_) => LRTF_PASSES,
        Lookup::Blocked => LRTF_BLOCKED,
        Lookup::OutsideDomain => LRTF_OUTSIDE,
    }
}

/// A deterministic uniform number in [0, 1).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `per_layer` film-side rays for each layer, starting on the film plane `film_z`: film radii
/// over the whole domain and 8 % beyond it (a third of them within 2 % of its edge), aimed at
/// rear-plane points out to 1.2 times the layer's coordinate pupil circle (a third of them
/// within 3 % of it). Each ray as the shader reads it: (origin, layer), (direction, block).
fn rays_for(table: &LrtfTable, film_z: f64, per_layer: usize, block: u32) -> Vec<[f32; 8]> {
    let mut random = Lcg(56);
    let mut rays = Vec::new();
    for (layer_index, layer) in table.layers.iter().enumerate() {
        let frame = &layer.frame;
        for k in 0..per_layer {
            let mut edge = |centre: f64, spread: f64, wide: f64| {
                if k % 3 == 0 {
                    centre + spread * (2.0 * random.next() - 1.0)
                } else {
                    wide * random.next()
                }
            };
            let film_radius = frame.max_film_radius * edge(1.0, 0.02, 1.08);
            let pupil_scale = edge(1.0, 0.03, 1.2);
            let azimuth = std::f64::consts::TAU * random.next();
            let angle = std::f64::consts::TAU * random.next();
            let circle = layer
                .pupil
                .circle_at(film_radius.min(frame.max_film_radius));
            let (c, s) = (azimuth.cos(), azimuth.sin());
            let local = [
                circle.centre_x + pupil_scale * circle.radius * angle.cos(),
                pupil_scale * circle.radius * angle.sin(),
            ];
            let origin = [film_radius * c, film_radius * s, film_z];
            let target = [
                c * local[0] - s * local[1],
                s * local[0] + c * local[1],
                frame.rear_plane_z,
            ];
            let d: Vec<f64> = (0..3).map(|i| target[i] - origin[i]).collect();
            let norm = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            rays.push([
                origin[0] as f32,
                origin[1] as f32,
                origin[2] as f32,
                layer_index as f32,
                (d[0] / norm) as f32,
                (d[1] / norm) as f32,
                (d[2] / norm) as f32,
                block as f32,
            ]);
        }
    }
    rays
}

fn floats_to_bytes(values: &[[f32; 8]]) -> Vec<u8> {
    values
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect()
}

/// Runs tools/engine_consumer.py on `shader` bound to `binding` with the rays of the file
/// `rays`; returns the floats it wrote to `out` and what it said.
fn run_consumer(
    python: &str,
    shader: &str,
    binding: &str,
    rays: &str,
    out: &str,
) -> (Vec<f32>, String) {
    let consumer = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tools/engine_consumer.py");
    let said = run_ok(
        Command::new(python)
            .arg(consumer)
            .args([shader, binding, rays, out]),
    );
    let floats = std::fs::read(out)
        .unwrap()
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    (floats, said)
}

/// One table kind through the documented steps (docs/engines.md): bake, export the GLSL
/// sampler and the binding, run the consumer, compare every ray with `LrtfTable::lookup`.
fn consumer_matches(kind: &str, bake: &[&str], binding: &[&str]) {
    let test = format!("consumer_matches_{kind}");
    let Some(python) = consumer_python(&test) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let (table_dir, shader, binding_dir) =
        (path("table"), path("lrtf_sample.comp"), path("binding"));
    let lensbake = env!("CARGO_BIN_EXE_lensbake");
    run_ok(
        Command::new(lensbake)
            .args([
                "bake",
                "dgauss-50mm",
                "--resolution",
                "24",
                "--out",
                &table_dir,
            ])
            .args(bake),
    );
    run_ok(Command::new(lensbake).args(["export", "shader", "--lang", "glsl", "--out", &shader]));
    run_ok(
        Command::new(lensbake)
            .args(["export", "binding", &table_dir, "--out", &binding_dir])
            .args(binding),
    );
    let table = read_table(Path::new(&table_dir), None).unwrap();
    let description: serde_json::Value =
        serde_json::from_slice(&std::fs::read(path("binding/binding.json")).unwrap()).unwrap();
    let film_z = description["film_z_mm"].as_f64().unwrap();
    let stop_radius = description["stop_radius_mm"].as_f64().unwrap();
    let block = description["sampling_block"].as_u64().unwrap() as u32;
    let per_layer = 12_000_usize.div_ceil(table.layers.len());
    let rays = rays_for(&table, film_z, per_layer, block);
    std::fs::write(path("rays.f32"), floats_to_bytes(&rays)).unwrap();
    let (out, said) = run_consumer(
        &python,
        &shader,
        &binding_dir,
        &path("rays.f32"),
        &path("out.f32"),
    );
    assert_eq!(out.len(), 12 * rays.len(), "{said}");

    let mut counts = [0usize; 3];
    let (mut worst_position, mut worst_direction, mut worst_circle) = (0.0f64, 0.0f64, 0.0f64);
    let mut near_edge = 0;
    for (k, ray) in rays.iter().enumerate() {
        let layer = ray[3] as usize;
        let cpu_ray = Ray {
            origin: [ray[0] as f64, ray[1] as f64, ray[2] as f64],
            direction: [ray[4] as f64, ray[5] as f64, ray[6] as f64],
        };
        let lookup = table.lookup_layer(layer, &cpu_ray, stop_radius);
        let gl = &out[12 * k..12 * k + 12];
        let status = status_of(&lookup);
        assert_eq!(
            gl[3] as u32, status,
            "{kind}: ray {k} {cpu_ray:?} (layer {layer}): GL status {} against lensbake's {lookup:?}",
            gl[3]
        );
        counts[status as usize] += 1;
        let film_radius = cpu_ray.origin[0].hypot(cpu_ray.origin[1]);
        if (film_radius / table.layers[layer].frame.max_film_radius - 1.0).abs() < 0.02 {
            near_edge += 1;
        }
        if let Lookup::Passes(exit) = lookup {
            for i in 0..3 {
                worst_position = worst_position.max((gl[i] as f64 - exit.origin[i]).abs());
                worst_direction = worst_direction.max((gl[4 + i] as f64 - exit.direction[i]).abs());
            }
        }
        let circle = table.layers[0].sampling.circle_at(film_radius, film_z);
        worst_circle = worst_circle
            .max((gl[8] as f64 - circle.centre_x).abs())
            .max((gl[9] as f64 - circle.radius).abs());
    }
    eprintln!(
        "{kind}: {} rays ({} pass, {} blocked, {} outside; {near_edge} within 2 % of the film edge): \
         worst position {worst_position:.2e} mm, direction {worst_direction:.2e}, sampling circle \
         {worst_circle:.2e} mm; {said}",
        rays.len(),
        counts[0],
        counts[1],
        counts[2]
    );
    assert!(rays.len() >= 10_000);
    // Every outcome represented (a spherical table's domain has no film edge: its rays are
    // outside only when they travel away from the lens), and a quarter of the rays at the
    // film's edge.
    let outcomes = match table.info.parameterisation {
        Parameterisation::Spherical => &counts[..2],
        Parameterisation::PupilPlanes => &counts[..],
    };
    assert!(
        outcomes.iter().all(|&c| c >= rays.len() / 50),
        "{kind}: {counts:?}"
    );
    assert!(
        near_edge >= rays.len() / 4,
        "{kind}: {near_edge} rays near the edge"
    );
    assert!(
        worst_position <= 1e-4,
        "{kind}: position off by {worst_position} mm"
    );
    assert!(
        worst_direction <= 2e-6,
        "{kind}: direction off by {worst_direction}"
    );
    assert!(
        worst_circle <= 1e-4,
        "{kind}: sampling circle off by {worst_circle} mm"
    );

    // The same shader bound to a uniform block of another table format refuses every ray.
    let params = path("binding/lrtf_params.bin");
    let mut block = std::fs::read(&params).unwrap();
    let at = std::mem::offset_of!(lensbake::lrtf::GpuParams, format_version);
    block[at..at + 4].copy_from_slice(&(FORMAT_VERSION - 1).to_le_bytes());
    std::fs::write(&params, block).unwrap();
    let (refused, _) = run_consumer(
        &python,
        &shader,
        &binding_dir,
        &path("rays.f32"),
        &path("out.f32"),
    );
    for k in 0..rays.len() {
        assert_eq!(
            refused[12 * k + 3] as u32,
            LRTF_VERSION_MISMATCH,
            "{kind}: ray {k} under a block of format {}",
            FORMAT_VERSION - 1
        );
    }
}

#[test]
fn consumer_matches_a_monochrome_table_stopped_down() {
    consumer_matches("monochrome", &[], &["--f-number", "2.8"]);
}

/// A u16 table's codes are decoded into the texels the sampler reads, so the consumer's
/// lookups match lensbake's ray by ray as for an f32 table.
#[test]
fn consumer_matches_a_u16_table() {
    consumer_matches("u16", &["--precision", "u16"], &[]);
}

#[test]
fn consumer_matches_a_spherical_table() {
    consumer_matches("spherical", &["--parameterisation", "spherical"], &[]);
}

#[test]
fn consumer_matches_a_chromatic_table() {
    consumer_matches(
        "chromatic",
        &["--wavelengths-nm", "656.27,587.56,486.13"],
        &[],
    );
}

#[test]
fn consumer_matches_a_focus_range_table() {
    consumer_matches(
        "focus range",
        &["--focus-mm", "inf..1000"],
        &["--focus-mm", "2000"],
    );
}

/// The fenced block after `marker` in docs/engines.md.
fn docs_block(docs: &str, marker: &str) -> String {
    let after = &docs[docs
        .find(marker)
        .unwrap_or_else(|| panic!("{marker} is in the docs"))..];
    let start = after.find("```").unwrap();
    let body = &after[start..];
    let body = &body[body.find('\n').unwrap() + 1..];
    body[..body.find("```").unwrap()].to_string()
}

/// docs/engines.md's steps, run as written (lensbake and python3 on PATH, in a fresh directory
/// holding tools/), give the agreement it states and the uniform values it prints.
#[test]
fn docs_engines_steps_run_as_written() {
    let test = "docs_engines_steps_run_as_written";
    let Some(python) = consumer_python(test) else {
        return;
    };
    let docs =
        std::fs::read_to_string(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("docs/engines.md"))
            .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let bin = dir.path().join("bin");
    std::fs::create_dir(&bin).unwrap();
    std::os::unix::fs::symlink(env!("CARGO_BIN_EXE_lensbake"), bin.join("lensbake")).unwrap();
    // A wrapper, not a link: a virtual environment's Python finds its packages from the path it
    // was started by.
    let wrapper = bin.join("python3");
    std::fs::write(&wrapper, format!("#!/bin/sh\nexec '{python}' \"$@\"\n")).unwrap();
    std::fs::set_permissions(
        &wrapper,
        std::os::unix::fs::PermissionsExt::from_mode(0o755),
    )
    .unwrap();
    std::os::unix::fs::symlink(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tools"),
        dir.path().join("tools"),
    )
    .unwrap();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    run_ok(
        Command::new("bash")
            .args(["-e", "-c", &docs_block(&docs, "<!-- tested: steps -->")])
            .current_dir(dir.path())
            .env("PATH", path),
    );
    let read = |name: &str| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(dir.path().join("engine").join(name)).unwrap())
            .unwrap()
    };
    let (gl, lensbake) = (read("gl.json"), read("lensbake.json"));
    let (gl, lensbake) = (gl.as_array().unwrap(), lensbake.as_array().unwrap());
    assert_eq!(gl.len(), lensbake.len());
    let mut statuses = Vec::new();
    for (ours, theirs) in gl.iter().zip(lensbake) {
        assert_eq!(ours["status"], theirs["status"]);
        statuses.push(theirs["status"].as_str().unwrap().to_string());
        if theirs["status"] == "ok" {
            for (key, tolerance) in [("position", 1e-4), ("direction", 2e-6)] {
                let (a, b) = (common::vec3(&ours[key]), common::vec3(&theirs[key]));
                for i in 0..3 {
                    assert!(
                        (a[i] - b[i]).abs() <= tolerance,
                        "{key}: {a:?} against {b:?}"
                    );
                }
            }
        }
    }
    // The example shows every outcome.
    for status in ["ok", "vignetted", "missed"] {
        assert!(statuses.iter().any(|s| s == status), "{statuses:?}");
    }
    let printed: serde_json::Value =
        serde_json::from_str(&docs_block(&docs, "<!-- tested: params -->")).unwrap();
    assert_eq!(printed, read("binding/binding.json")["params"]);
}

/// Bad requests end in one `error:` line naming what is wrong, exit code 2, and no output.
#[test]
fn export_refusals_are_one_error_line_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("table");
    let out = dir.path().join("out");
    let (table, out) = (table.to_str().unwrap(), out.to_str().unwrap());
    let baked = common::lensbake(&["bake", "cooke-triplet", "--resolution", "4", "--out", table]);
    assert!(baked.status.success());
    for (args, says) in [
        (
            vec!["export", "shader", "--lang", "spirv"],
            "name a file with --out",
        ),
        (
            vec![
                "export", "shader", "--lang", "glsl", "--entry", "main", "--out", out,
            ],
            "has no entry point `main` (it has: lrtf_sample_rays)",
        ),
        (
            vec!["export", "binding", table, "--f-number", "1", "--out", out],
            "f-number 1 is faster than the table's",
        ),
        (
            vec![
                "export",
                "binding",
                table,
                "--focus-mm",
                "500",
                "--out",
                out,
            ],
            "500",
        ),
        (
            vec!["export", "binding", "no-such-table", "--out", out],
            "no-such-table/lrtf.ron",
        ),
        (
            vec!["export", "lens", "no-such-lens", "--out", out],
            "`no-such-lens` is neither a lens file nor a bundled lens",
        ),
    ] {
        let run = common::lensbake(&args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
        let first = stderr.lines().next().unwrap_or_default();
        assert!(
            first.starts_with("error: ") && first.contains(says),
            "{args:?}: {stderr}"
        );
        assert!(!Path::new(out).exists(), "{args:?} wrote {out}");
    }
}

/// The exported GLSL trace run by the consumer on lenses packed by `export lens` traces as
/// lensbake's own wgpu trace does (which tests/shader_twins.rs holds to the f64 tracer): the
/// same status and stopping surface per ray, the same rays to f32 precision. Lenses: spheres
/// (double Gauss), even aspheres, mirrors with a central obscuration (reflex), an odd asphere.
#[test]
fn consumer_traces_like_lensbakes_gpu_trace() {
    let test = "consumer_traces_like_lensbakes_gpu_trace";
    let Some(python) = consumer_python(test) else {
        return;
    };
    let Some(gpu) = common::gpu_or_skip(test) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let lensbake = env!("CARGO_BIN_EXE_lensbake");
    let shader = path("trace.comp");
    run_ok(Command::new(lensbake).args([
        "export", "shader", "--shader", "trace", "--lang", "glsl", "--out", &shader,
    ]));
    let odd_asphere = common::test_data("odd_asphere_singlet.zmx");
    let lenses = [
        "dgauss-50mm",
        "asph-50mm-f1.8",
        "reflex-1000mm-f7.5",
        odd_asphere.to_str().unwrap(),
    ];
    for (k, lens) in lenses.into_iter().enumerate() {
        let packed = path(&format!("lens-{k}"));
        run_ok(Command::new(lensbake).args(["export", "lens", lens, "--out", &packed]));
        let loaded = lensbake::load_lens(lens, &Default::default()).unwrap();
        let at = loaded.system.at(loaded.system.design_wavelength_nm());
        let (params, surfaces) = lensbake::render::gpu_types::lens_surfaces(&at);
        // Film-side rays from 20 mm behind the last surface to points of its vertex plane out
        // to 1.3 times its semi-aperture, so some pass, some are vignetted and some miss.
        let last = at.surfaces.last().unwrap();
        let reach = 1.3 * last.semi_aperture;
        let mut random = Lcg(k as u64 + 1);
        let mut disc = || {
            let (r, a) = (
                reach * random.next().sqrt(),
                std::f64::consts::TAU * random.next(),
            );
            [r * a.cos(), r * a.sin()]
        };
        let rays: Vec<[[f32; 3]; 2]> = (0..40_000)
            .map(|_| {
                let (from, to) = (disc(), disc());
                let origin = [from[0], from[1], last.vertex_z + 20.0];
                let d = [to[0] - from[0], to[1] - from[1], -20.0];
                let norm = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                [origin.map(|v| v as f32), d.map(|v| (v / norm) as f32)]
            })
            .collect();
        let input: Vec<[f32; 8]> = rays
            .iter()
            .map(|[o, d]| [o[0], o[1], o[2], 0.0, d[0], d[1], d[2], 0.0])
            .collect();
        std::fs::write(path("trace-rays.f32"), floats_to_bytes(&input)).unwrap();
        let (gl, _) = run_consumer(
            &python,
            &shader,
            &packed,
            &path("trace-rays.f32"),
            &path("trace-out.f32"),
        );
        let own = gpu.trace_rays(&params, &surfaces, &rays).unwrap();
        assert_eq!(gl.len(), 8 * own.len());
        let mut passing = 0;
        // f32 precision at the lens's size: 1e-4 mm, or 16 units in the last place of its
        // largest coordinate where that is more (the reflex lens spans hundreds of mm).
        let size = at
            .surfaces
            .iter()
            .map(|s| s.vertex_z.abs().max(s.semi_aperture))
            .fold(0.0f64, f64::max);
        let position_tolerance = 1e-4f32.max(16.0 * f32::EPSILON * size as f32);
        let (mut worst_position, mut worst_direction) = (0.0f32, 0.0f32);
        for (i, [head, tail]) in own.iter().enumerate() {
            let theirs = &gl[8 * i..8 * i + 8];
            assert_eq!(
                (theirs[3], theirs[7]),
                (head[3], tail[3]),
                "{lens}: ray {i} {:?}: GL (status, surface) against wgpu's",
                rays[i]
            );
            if head[3] as u32 == 0 {
                passing += 1;
                for c in 0..3 {
                    worst_position = worst_position.max((theirs[c] - head[c]).abs());
                    worst_direction = worst_direction.max((theirs[4 + c] - tail[c]).abs());
                }
            }
        }
        eprintln!(
            "{lens}: {passing} of {} rays pass; worst position {worst_position:.2e} mm (allowed \
             {position_tolerance:.1e}), direction {worst_direction:.2e}",
            rays.len()
        );
        // The reflex lens's obscured annulus passes the fewest (about 0.5 %).
        assert!(passing >= 100 && passing < rays.len(), "{lens}: {passing}");
        assert!(
            worst_position <= position_tolerance,
            "{lens}: position off by {worst_position} mm"
        );
        assert!(
            worst_direction <= 2e-6,
            "{lens}: direction off by {worst_direction}"
        );
    }
}
