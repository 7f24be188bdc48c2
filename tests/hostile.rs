//! Hostile table files: truncated and corrupted EXR data, sidecars that disagree with the data
//! or the lens, missing files, directories where files belong, garbage RON, failed and
//! interrupted writes, and a bounded-time fuzz run over mutated tables. Every case must end in a
//! typed error or a usable table, never a panic, and a failed write must leave nothing behind.

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
