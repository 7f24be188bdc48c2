//! Accuracy/cost sweep of LRTF tables (issue 6 item 8). Usage:
//! cargo run --release --example lrtf_sweep -- OUT_DIR RESOLUTIONS LENS.ron...
//! e.g. notebooks-out/lrtf 16,32,64,128 lenses/dgauss-50mm.ron ...
use lensbake::lrtf::bake::{BakeRequest, bake, near_axial_first_order};
use lensbake::lrtf::measure::table_error;
use lensbake::lrtf::{Parameterisation, Precision};
use lensbake::prescription::Prescription;
use lensbake::system::LensSystem;
use lensbake::trace::Tracer;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let out = std::path::PathBuf::from(&args[1]);
    let resolutions: Vec<usize> = args[2].split(',').map(|v| v.parse().unwrap()).collect();
    let mut rows = Vec::new();
    let mut md = String::from(
        "| lens | param | N^3 | prec | bake s | bytes | dir p50/p99/max mrad | pos p50/p99/max um | image p50/p99/max px | validity agree % |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for path in &args[3..] {
        let name = std::path::Path::new(path)
            .file_stem()
            .unwrap()
            .to_string_lossy()
            .to_string();
        let p: Prescription = ron::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        let system = LensSystem::from_prescription(p).unwrap();
        let design = system.at(system.design_wavelength_nm());
        let tracer = Tracer::new(&design);
        let efl = near_axial_first_order(&tracer, &design, None).unwrap().efl;
        for &n in &resolutions {
            for param in [Parameterisation::PupilPlanes, Parameterisation::Spherical] {
                let request = BakeRequest {
                    parameterisation: param,
                    resolution: [n, n, n],
                    ..BakeRequest::default()
                };
                let start = std::time::Instant::now();
                let table = match bake(&system, &request, &|_| {}) {
                    Ok(t) => t,
                    Err(e) => {
                        eprintln!("{name} {n} {param:?}: {e}");
                        continue;
                    }
                };
                let seconds = start.elapsed().as_secs_f64();
                for precision in [Precision::F32, Precision::F16] {
                    let mut t = table.clone();
                    t.info.precision = precision;
                    for e in &mut t.layers[0].entries {
                        for v in e.iter_mut() {
                            *v = precision.round(*v);
                        }
                    }
                    let e = table_error(&t, 0, &tracer, efl, 1920.0, 20_000, 0x5eed);
                    let s = |x: &lensbake::lrtf::measure::Stats, k: usize| {
                        format!("{:.*} / {:.*} / {:.*}", k, x.median, k, x.p99, k, x.max)
                    };
                    md += &format!(
                        "| {name} | {} | {n} | {} | {seconds:.2} | {} | {} | {} | {} | {:.2} |\n",
                        param.name(),
                        precision.name(),
                        t.entry_bytes(),
                        s(&e.direction_mrad, 4),
                        s(&e.position_um, 2),
                        s(&e.image_px, 3),
                        100.0 * (1.0 - e.validity_mismatch)
                    );
                    rows.push(serde_json::json!({"lens": name, "parameterisation": param.name(), "resolution": n, "precision": precision.name(), "bake_seconds": seconds, "bytes": t.entry_bytes(), "efl": efl, "max_film_radius": t.layers[0].frame.max_film_radius, "error": e}));
                    eprintln!(
                        "{name} {} {n} {} {seconds:.2}s",
                        param.name(),
                        precision.name()
                    );
                }
            }
        }
    }
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("lrtf-error.md"), md).unwrap();
    std::fs::write(
        out.join("lrtf-error.json"),
        serde_json::to_string_pretty(&rows).unwrap(),
    )
    .unwrap();
}
