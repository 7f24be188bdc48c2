//! Helpers shared by the integration tests.

use std::path::PathBuf;

/// The shared test data directory: `../shared/testdata` beside the crate (CI), or
/// `/work/shared/testdata` (inside a helper worktree, where the relative path does not exist).
pub fn testdata_dir() -> PathBuf {
    let beside = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/testdata");
    if beside.is_dir() {
        return beside;
    }
    let fixed = PathBuf::from("/work/shared/testdata");
    assert!(
        fixed.is_dir(),
        "shared test data not found at {} or {}",
        beside.display(),
        fixed.display()
    );
    fixed
}

/// Parses one file of the shared test data as JSON.
#[allow(dead_code)]
pub fn oracle_json(name: &str) -> serde_json::Value {
    let path = testdata_dir().join("oracle").join(name);
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("bad JSON in {}: {e}", path.display()))
}

/// The surfaces of the first lens of an oracle file.
#[allow(dead_code)]
pub fn oracle_surfaces(name: &str) -> Vec<serde_json::Value> {
    oracle_json(name)["lenses"][0]["prescription"]["surfaces"]
        .as_array()
        .expect("oracle prescription has surfaces")
        .clone()
}
