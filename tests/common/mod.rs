//! Shared helpers for integration tests that read the reference data in ../shared.

#![allow(dead_code)]

use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
use serde_json::Value;
use std::path::PathBuf;

/// The oracle directory: `../shared/testdata/oracle` beside the crate (CI), else the shared
/// checkout at /work/shared (worktrees).
pub fn oracle_dir() -> PathBuf {
    let beside = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata/oracle");
    if beside.is_dir() {
        beside
    } else {
        PathBuf::from("/work/shared/testdata/oracle")
    }
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
        })
        .collect();
    Prescription {
        provenance: Provenance {
            title: lens["name"].as_str().unwrap_or("oracle lens").to_string(),
            design_wavelength_nm: lens["wavelength_nm"].as_f64(),
            ..Provenance::default()
        },
        object_medium: Medium::Index(num(&table["object_space_index"])),
        surfaces,
    }
}

pub fn num(v: &Value) -> f64 {
    v.as_f64()
        .unwrap_or_else(|| panic!("expected a number, found {v}"))
}

pub fn vec3(v: &Value) -> [f64; 3] {
    let a = v
        .as_array()
        .unwrap_or_else(|| panic!("expected a 3-vector, found {v}"));
    [num(&a[0]), num(&a[1]), num(&a[2])]
}
