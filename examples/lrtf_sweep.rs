//! Accuracy/cost sweep of LRTF tables (issue 6 item 8): every lens x resolution x
//! parameterisation x precision, bake time, bytes and error against the exact trace.
//!
//! cargo run --release --example lrtf_sweep -- OUT_DIR RESOLUTIONS LENS...
//! e.g. `-- notebooks-out/lrtf 16,32,64,128 dgauss-50mm fisheye-10mm telephoto-250mm`
//! (LENS: a bundled lens name or a lens file). Writes OUT_DIR/lrtf-error.{json,md,png}.
use lensbake::lenses;
use lensbake::lrtf::bake::{BakeRequest, bake, first_order};
use lensbake::lrtf::measure::{Stats, SweepRow, table_error};
use lensbake::lrtf::{Parameterisation, Precision};
use lensbake::output::write_bytes;
use lensbake::plot::{LrtfErrorPlot, write_plot};
use lensbake::prescription::formats::LoadOptions;
use lensbake::trace::Tracer;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        return Err("usage: lrtf_sweep OUT_DIR RESOLUTIONS LENS...".into());
    }
    let out = std::path::PathBuf::from(&args[1]);
    let resolutions: Vec<usize> = args[2]
        .split(',')
        .map(|v| v.parse())
        .collect::<Result<_, _>>()?;
    let mut rows = Vec::new();
    for spec in &args[3..] {
        let lens = lenses::load(spec, &LoadOptions::default())?;
        let name = lens.source.origin.name();
        let system = lens.system;
        let design = system.at(system.design_wavelength_nm());
        let tracer = Tracer::new(&design);
        let efl = first_order(&design, None)?.first_order.efl;
        for &n in &resolutions {
            for parameterisation in [Parameterisation::PupilPlanes, Parameterisation::Spherical] {
                let request = BakeRequest {
                    parameterisation,
                    resolution: [n, n, n],
                    ..BakeRequest::default()
                };
                let start = std::time::Instant::now();
                let table = bake(&system, &request)?;
                let bake_seconds = start.elapsed().as_secs_f64();
                for precision in [Precision::F32, Precision::F16] {
                    let t = table.to_precision(precision);
                    let error = table_error(&t, 0, &tracer, efl, 1920.0, 20_000, 0x5eed);
                    eprintln!(
                        "{name} {} {n}^3 {}: {bake_seconds:.2} s, p99 {:.3} px",
                        parameterisation.name(),
                        precision.name(),
                        error.image_px.p99
                    );
                    rows.push(SweepRow {
                        lens: name.clone(),
                        parameterisation: parameterisation.name().to_string(),
                        resolution: n,
                        precision: precision.name().to_string(),
                        bake_seconds,
                        bytes: t.entry_bytes(),
                        efl,
                        max_film_radius: t.layers[0].frame.max_film_radius,
                        error,
                    });
                }
            }
        }
    }
    std::fs::create_dir_all(&out)?;
    let stats =
        |x: &Stats, k: usize| format!("{:.*} / {:.*} / {:.*}", k, x.median, k, x.p99, k, x.max);
    let mut md = String::from(
        "| lens | param | N^3 | prec | bake s | bytes | dir p50/p99/max mrad | pos p50/p99/max um | image p50/p99/max px | validity agree % |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in &rows {
        md += &format!(
            "| {} | {} | {} | {} | {:.2} | {} | {} | {} | {} | {:.3} |\n",
            r.lens,
            r.parameterisation,
            r.resolution,
            r.precision,
            r.bake_seconds,
            r.bytes,
            stats(&r.error.direction_mrad, 4),
            stats(&r.error.position_um, 2),
            stats(&r.error.image_px, 3),
            100.0 * (1.0 - r.error.validity_mismatch)
        );
    }
    write_bytes(&out.join("lrtf-error.md"), md.as_bytes())?;
    write_bytes(
        &out.join("lrtf-error.json"),
        serde_json::to_string_pretty(&rows)?.as_bytes(),
    )?;
    write_plot(
        &LrtfErrorPlot::from_sweep(&rows),
        &out.join("lrtf-error.png"),
    )?;
    Ok(())
}
