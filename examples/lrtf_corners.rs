//! Values at a cell with blocked corners: trilinear over all eight corners (the continuation,
//! what the shader does) against renormalised weights over the valid corners only.
//!
//! cargo run --release --example lrtf_corners -- OUT_FILE RESOLUTIONS LENS...
//! e.g. `-- notebooks-out/lrtf/corners.md 32,64,128 dgauss-50mm fisheye-10mm telephoto-250mm`
use lensbake::lenses;
use lensbake::lrtf::Corners;
use lensbake::lrtf::bake::{BakeRequest, bake, first_order};
use lensbake::lrtf::measure::table_error_from;
use lensbake::output::write_bytes;
use lensbake::prescription::formats::LoadOptions;
use lensbake::trace::Tracer;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        return Err("usage: lrtf_corners OUT_FILE RESOLUTIONS LENS...".into());
    }
    let resolutions: Vec<usize> = args[2]
        .split(',')
        .map(|v| v.parse())
        .collect::<Result<_, _>>()?;
    let mut md = String::from(
        "| lens | N^3 | corners | image p99 / max px | position p99 / max um | validity agree % |\n|---|---|---|---|---|---|\n",
    );
    for spec in &args[3..] {
        let lens = lenses::load(spec, &LoadOptions::default())?;
        let name = lens.source.origin.name();
        let design = lens.system.at(lens.system.design_wavelength_nm());
        let tracer = Tracer::new(&design);
        let efl = first_order(&design, None)?.first_order.efl;
        for &n in &resolutions {
            let request = BakeRequest {
                resolution: [n, n, n],
                ..BakeRequest::default()
            };
            let table = bake(&lens.system, &request)?;
            for corners in [Corners::All, Corners::ValidOnly] {
                let e = table_error_from(&table, 0, &tracer, efl, 1920.0, 20_000, 0x5eed, corners);
                md += &format!(
                    "| {name} | {n} | {corners:?} | {:.4} / {:.4} | {:.2} / {:.2} | {:.3} |\n",
                    e.image_px.p99,
                    e.image_px.max,
                    e.position_um.p99,
                    e.position_um.max,
                    100.0 * (1.0 - e.validity_mismatch)
                );
            }
        }
    }
    print!("{md}");
    write_bytes(std::path::Path::new(&args[1]), md.as_bytes())?;
    Ok(())
}
