//! `lens convert` never writes a file its readers refuse, and loses no first-order data: every
//! lens file of the test corpus that loads (bundled lenses, tests/data, its corpus and lens
//! tables, the truth data) is written in each format lensbake writes, read back, and compared
//! by the paraxial matrices that fix every first-order quantity (system, vertex 1 to the stop,
//! stop to the last vertex) to 1e-12 relative.

use lensbake::lenses::{WriteLensError, write_lens};
use lensbake::paraxial::{from_vertex, system_matrix, to_vertex};
use lensbake::prescription::formats::{LoadOptions, read_file};
use lensbake::system::LensSystem;
use std::path::{Path, PathBuf};

fn manifest() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every lens file of the repository's test corpus.
fn corpus_files() -> Vec<PathBuf> {
    let mut files = Vec::new();
    for dir in [
        "lenses",
        "tests/data",
        "tests/data/corpus",
        "tests/data/lens-tables",
        "tests/data/truth/lenses",
    ] {
        let Ok(entries) = std::fs::read_dir(manifest().join(dir)) else {
            continue;
        };
        for entry in entries {
            let path = entry.unwrap().path();
            let extension = path
                .extension()
                .map(|e| e.to_string_lossy().to_ascii_lowercase());
            if matches!(extension.as_deref(), Some("ron" | "zmx" | "seq" | "dat")) {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

fn loaded(path: &Path) -> Option<LensSystem> {
    let loaded = read_file(path, &LoadOptions::default()).ok()?;
    LensSystem::new(loaded.prescription, &loaded.map).ok()
}

/// The entries of the three matrices that fix the lens's first-order data at `nm`, with the
/// media at both ends.
fn first_order(system: &LensSystem, nm: f64) -> Vec<f64> {
    let at = system.at(nm);
    let mut numbers = vec![at.object_index, at.image_index(), at.last_vertex_z()];
    for m in [
        system_matrix(&at),
        to_vertex(&at, system.stop),
        from_vertex(&at, system.stop),
    ] {
        numbers.extend(m.iter().copied());
    }
    numbers
}

#[test]
fn every_written_corpus_file_reads_back_with_the_same_first_order_data() {
    let scratch = std::env::temp_dir().join(format!("lensbake-round-trip-{}", std::process::id()));
    std::fs::create_dir_all(&scratch).unwrap();
    let (mut lenses, mut written, mut unholdable) = (0, 0, 0);
    let mut failures = Vec::new();
    for path in corpus_files() {
        let Some(original) = loaded(&path) else {
            continue;
        };
        lenses += 1;
        let nm = original.design_wavelength_nm();
        for extension in ["ron", "zmx", "dat"] {
            let out = scratch.join(format!("lens.{extension}"));
            let _ = std::fs::remove_file(&out);
            let what = format!("{} -> .{extension}", path.display());
            match write_lens(&original, &out) {
                Ok(_) => written += 1,
                // What the format cannot hold (pbrt: aspheres, mirrors, ...) is refused by name.
                Err(WriteLensError::Cannot { .. }) => {
                    unholdable += 1;
                    assert!(!out.exists(), "{what}: refused but written");
                    continue;
                }
                Err(error) => {
                    failures.push(format!("{what}: {error}"));
                    continue;
                }
            }
            let Some(back) = loaded(&out) else {
                failures.push(format!("{what}: written but not read back"));
                continue;
            };
            let (a, b) = (first_order(&original, nm), first_order(&back, nm));
            for (k, (p, q)) in a.iter().zip(&b).enumerate() {
                if (p - q).abs() > 1e-12 * p.abs().max(q.abs()) && (p - q).abs() > 1e-300 {
                    failures.push(format!("{what}: first-order number {k}: {p} vs {q}"));
                }
            }
        }
    }
    std::fs::remove_dir_all(&scratch).unwrap();
    println!(
        "round trip | {lenses} corpus lenses | {written} files written and read back | \
         {unholdable} refused as beyond the format"
    );
    assert!(lenses >= 70, "only {lenses} corpus lenses loaded");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
