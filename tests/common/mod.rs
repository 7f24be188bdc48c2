//! Shared test helpers: where the truth data lives, and lenses built from it.
#![allow(dead_code)]

use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
use std::path::PathBuf;

/// The shared test-data directory: beside the crate in CI, /work/shared in a worktree.
pub fn shared_dir() -> PathBuf {
    let beside = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared");
    if beside.join("testdata").is_dir() {
        beside
    } else {
        PathBuf::from("/work/shared")
    }
}

pub fn oracle(name: &str) -> serde_json::Value {
    let path = shared_dir().join("testdata/oracle").join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// The lens of an oracle file as a prescription with constant indices.
pub fn oracle_prescription(name: &str) -> Prescription {
    let json = oracle(name);
    let lens = &json["lenses"][0];
    let surfaces = lens["prescription"]["surfaces"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            let n = s["n"].as_f64().unwrap();
            Surface {
                shape: Shape::from_radius(s["radius"].as_f64().unwrap_or(0.0)),
                thickness: s["thickness"].as_f64().unwrap(),
                medium: if n == 1.0 {
                    Medium::Air
                } else {
                    Medium::Index(n)
                },
                semi_aperture: s["semi_aperture"].as_f64().unwrap(),
                stop: s["stop"].as_bool().unwrap().then_some(StopShape::Circle),
            }
        })
        .collect();
    Prescription {
        provenance: Provenance {
            title: lens["name"].as_str().unwrap().to_string(),
            ..Provenance::default()
        },
        object_medium: Medium::Air,
        surfaces,
    }
}
