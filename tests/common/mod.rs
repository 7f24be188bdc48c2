//! Helpers shared by the integration tests.
#![allow(dead_code)] // each test crate uses its own subset

use std::path::{Path, PathBuf};

/// The shared data directory: `../shared` beside the crate (CI), else `/work/shared` (worktrees).
pub fn shared_dir() -> PathBuf {
    let beside = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared");
    if beside.is_dir() {
        beside
    } else {
        PathBuf::from("/work/shared")
    }
}

pub fn lens_file(name: &str) -> PathBuf {
    shared_dir().join("testdata/lenses").join(name)
}

pub fn oracle(name: &str) -> serde_json::Value {
    let path = shared_dir().join("testdata/oracle").join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The prescription table of an oracle file (`lenses[0].prescription`).
pub fn oracle_table(name: &str) -> serde_json::Value {
    oracle(name)["lenses"][0]["prescription"].clone()
}

/// Test files of this crate (tests/data).
pub fn test_data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// Relative difference, safe at zero.
pub fn relative(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / a.abs().max(b.abs())
    }
}
