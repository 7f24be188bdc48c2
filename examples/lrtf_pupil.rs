//! Effective-pupil tightness (issue 6 item 3): cargo run --release --example lrtf_pupil -- LENS
//! (LENS: a lens file or a bundled lens name)
use lensbake::lenses;
use lensbake::lrtf::bake::{BakeRequest, bake};
use lensbake::lrtf::measure::pupil_tightness;
use lensbake::prescription::formats::LoadOptions;
use lensbake::trace::{Ray, Tracer, Travel};

fn main() {
    let path = std::env::args().nth(1).unwrap();
    let system = lenses::load(&path, &LoadOptions::default()).unwrap().system;
    let design = system.at(system.design_wavelength_nm());
    let tracer = Tracer::new(&design);
    let table = bake(
        &system,
        &BakeRequest {
            resolution: [64, 2, 2],
            ..BakeRequest::default()
        },
    )
    .unwrap();
    let l = &table.layers[0];
    let (fz, rz) = (l.frame.film_plane_z, l.frame.rear_plane_z);
    let passes = |r: f64, q: [f64; 2]| {
        Ray::new([r, 0.0, fz], [q[0] - r, q[1], rz - fz])
            .is_ok_and(|ray| tracer.trace(ray, Travel::Backward).outcome.is_ok())
    };
    let t = pupil_tightness(
        &l.pupil,
        design.surfaces.last().unwrap().semi_aperture,
        &passes,
        200_000,
        3,
    );
    println!("{}", serde_json::to_string(&t).unwrap());
}
