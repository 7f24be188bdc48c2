//! include/lensbake_table.h and docs/lrtf-sidecar.schema.json describe the table lensbake
//! writes: the header compiled as strict C99 by the system's C compiler prints its numbers and
//! offsets, which must be lensbake's own; sidecars of every table kind validate against the
//! schema under Python's jsonschema (.ci/engines.sh installs it). Outside CI a missing tool
//! skips its check; with CI=true it fails.
#![cfg(feature = "render")]

mod common;

use std::path::PathBuf;
use std::process::Command;

use lensbake::lrtf::GpuParams;
use lensbake::lrtf::io::{FORMAT_VERSION, OLDEST_READ_FORMAT_VERSION, read_sidecar, write_table};
use lensbake::lrtf::param::{
    CHANNEL_NAMES, CHANNELS, PARAMETERISATION_PUPIL_PLANES, PARAMETERISATION_SPHERICAL,
};
use lensbake::lrtf::table::{LRTF_BLOCKED, LRTF_OUTSIDE, LRTF_PASSES, LRTF_VERSION_MISMATCH};
use lensbake::render::wgsl::lrtf_sample_shader;

fn repo(path: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn skip_or_fail(test: &str, why: &str) {
    if std::env::var("CI").as_deref() == Ok("true") {
        panic!("{test}: {why}");
    }
    eprintln!("SKIPPED {test}: {why}");
}

const PROGRAM: &str = r#"
#include <stdio.h>
#include "lensbake_table.h"
#define OFFSET(field) printf(#field " %u\n", (unsigned)offsetof(lensbake_lrtf_params, field))
int main(void) {
    static const char *const names[LENSBAKE_TABLE_CHANNELS] = LENSBAKE_CHANNEL_NAMES;
    const uint32_t dims[3] = {3, 4, 5};
    int c;
    printf("format_version %u\n", LENSBAKE_TABLE_FORMAT_VERSION);
    printf("oldest_format_version %u\n", LENSBAKE_TABLE_OLDEST_FORMAT_VERSION);
    printf("channels %d\n", LENSBAKE_TABLE_CHANNELS);
    for (c = 0; c < LENSBAKE_TABLE_CHANNELS; c++) printf("channel %d %s\n", c, names[c]);
    printf("channel_margin %d\n", (int)LENSBAKE_CHANNEL_MARGIN);
    printf("channel_exit_z %d\n", (int)LENSBAKE_CHANNEL_EXIT_Z);
    printf("texture1_first %d\n", (int)LENSBAKE_TEXTURE1_FIRST_CHANNEL);
    printf("spherical %u\n", LENSBAKE_PARAMETERISATION_SPHERICAL);
    printf("pupil_planes %u\n", LENSBAKE_PARAMETERISATION_PUPIL_PLANES);
    printf("passes %u\n", LENSBAKE_LRTF_PASSES);
    printf("blocked %u\n", LENSBAKE_LRTF_BLOCKED);
    printf("outside %u\n", LENSBAKE_LRTF_OUTSIDE);
    printf("version_mismatch %u\n", LENSBAKE_LRTF_VERSION_MISMATCH);
    printf("size %u\n", (unsigned)sizeof(lensbake_lrtf_params));
    printf("circle %u\n", (unsigned)sizeof(lensbake_pupil_circle));
    OFFSET(rear_plane_z); OFFSET(film_plane_z); OFFSET(max_film_radius);
    OFFSET(max_rear_radius); OFFSET(max_polar_angle); OFFSET(stop_radius_sq);
    OFFSET(parameterisation); OFFSET(pupil_count); OFFSET(dims); OFFSET(format_version);
    OFFSET(sampling_max_film_radius); OFFSET(sampling_count); OFFSET(focus_count);
    OFFSET(focus_coordinate);
    printf("node %u\n", (unsigned)lensbake_node_index(dims, 1, 2, 3, 4));
    return 0;
}
"#;

#[test]
fn the_c_header_states_lensbakes_layout() {
    let test = "the_c_header_states_lensbakes_layout";
    let dir = tempfile::tempdir().unwrap();
    let source = dir.path().join("layout.c");
    let program = dir.path().join("layout");
    std::fs::write(&source, PROGRAM).unwrap();
    let compiled = Command::new("cc")
        .args(["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(repo("include"))
        .arg(&source)
        .arg("-o")
        .arg(&program)
        .output();
    let compiled = match compiled {
        Ok(out) => out,
        Err(e) => return skip_or_fail(test, &format!("no C compiler `cc` ({e})")),
    };
    assert!(
        compiled.status.success(),
        "the header does not compile as C99:\n{}",
        String::from_utf8_lossy(&compiled.stderr)
    );
    let out = common::finished(&mut Command::new(&program), None);
    let printed = String::from_utf8(out.stdout).unwrap();
    let mut expected = vec![
        format!("format_version {FORMAT_VERSION}"),
        format!("oldest_format_version {OLDEST_READ_FORMAT_VERSION}"),
        format!("channels {CHANNELS}"),
    ];
    expected.extend(
        CHANNEL_NAMES
            .iter()
            .enumerate()
            .map(|(c, name)| format!("channel {c} {name}")),
    );
    let index = |name: &str| CHANNEL_NAMES.iter().position(|n| *n == name).unwrap();
    expected.extend([
        format!("channel_margin {}", lensbake::lrtf::param::MARGIN),
        format!("channel_exit_z {}", index("exit.z")),
        format!("texture1_first {}", index("margin")),
        format!("spherical {PARAMETERISATION_SPHERICAL}"),
        format!("pupil_planes {PARAMETERISATION_PUPIL_PLANES}"),
        format!("passes {LRTF_PASSES}"),
        format!("blocked {LRTF_BLOCKED}"),
        format!("outside {LRTF_OUTSIDE}"),
        format!("version_mismatch {LRTF_VERSION_MISMATCH}"),
        format!("size {}", std::mem::size_of::<GpuParams>()),
        format!("circle {}", std::mem::size_of::<[f32; 2]>()),
    ]);
    // The uniform block member by member as naga lays out the shader's struct (whose layout
    // tests/lrtf_wgsl.rs ties to the Rust one).
    let module = naga::front::wgsl::parse_str(lrtf_sample_shader()).unwrap();
    let params = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some("LrtfParams"))
        .expect("the sampler declares LrtfParams");
    let naga::TypeInner::Struct { members, span } = &params.1.inner else {
        panic!("LrtfParams is a struct");
    };
    assert_eq!(*span as usize, std::mem::size_of::<GpuParams>());
    expected.extend(
        members
            .iter()
            .map(|m| format!("{} {}", m.name.as_deref().unwrap_or("?"), m.offset)),
    );
    // Node (2, 3, 4) of layer 1 in 3 x 4 x 5 layers: x fastest, then y, then z, layers along z.
    expected.push(format!("node {}", 2 + 3 * (3 + 4 * (4 + 5))));
    assert_eq!(printed.lines().collect::<Vec<_>>(), expected);
}

#[test]
fn sidecars_of_every_kind_follow_the_json_schema() {
    let test = "sidecars_of_every_kind_follow_the_json_schema";
    let python = std::env::var("LENSBAKE_ENGINE_PYTHON").unwrap_or_else(|_| "python3".into());
    let has_jsonschema = Command::new(&python)
        .args(["-c", "import jsonschema"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_jsonschema {
        return skip_or_fail(test, &format!("`{python}` lacks jsonschema"));
    }
    let lens = lensbake::load_lens("cooke-triplet", &Default::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    use lensbake::lrtf::Precision;
    let kinds = [
        ("monochrome", vec![], None, Precision::F32),
        (
            "chromatic",
            vec![656.27, 587.56, 486.13],
            None,
            Precision::F32,
        ),
        ("focus-range", vec![], Some(1000.0), Precision::F32),
        // Its layers carry the quantisation that decodes the codes.
        ("u16", vec![], None, Precision::U16),
    ];
    let mut documents = Vec::new();
    for (name, wavelengths_nm, focus_near_mm, precision) in kinds {
        let request = lensbake::BakeRequest {
            resolution: [4, 4, 4],
            wavelengths_nm,
            focus_near_mm,
            precision,
            ..Default::default()
        };
        let table = lensbake::bake(&lens.system, &request).unwrap();
        let table_dir = dir.path().join(name);
        write_table(
            &table,
            "cooke-triplet",
            &lens.system.prescription,
            &table_dir,
        )
        .unwrap();
        documents.push(serde_json::to_value(read_sidecar(&table_dir).unwrap()).unwrap());
    }
    // A field that is not lensbake's must fail, or the check proves nothing.
    let mut altered = documents[0].clone();
    altered["info"]["focal_length"] = serde_json::json!(50.0);
    let script = r#"
import json, sys, jsonschema
schema = json.load(open(sys.argv[1]))
jsonschema.Draft202012Validator.check_schema(schema)
documents, altered = json.load(open(sys.argv[2]))
for d in documents:
    jsonschema.validate(d, schema, cls=jsonschema.Draft202012Validator)
try:
    jsonschema.validate(altered, schema, cls=jsonschema.Draft202012Validator)
    sys.exit("an unknown field passed")
except jsonschema.ValidationError:
    print(f"{len(documents)} sidecars valid")
"#;
    let documents_path = dir.path().join("sidecars.json");
    std::fs::write(
        &documents_path,
        serde_json::to_string(&serde_json::json!([documents, altered])).unwrap(),
    )
    .unwrap();
    let out = common::finished(
        Command::new(&python)
            .args(["-c", script])
            .arg(repo("docs/lrtf-sidecar.schema.json"))
            .arg(&documents_path),
        None,
    );
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
