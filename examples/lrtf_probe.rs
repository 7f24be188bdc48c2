use lensbake::lrtf::bake::{BakeRequest, bake, near_axial_first_order};
use lensbake::lrtf::measure::table_error;
use lensbake::lrtf::{Parameterisation, Precision};
use lensbake::prescription::Prescription;
use lensbake::system::LensSystem;
use lensbake::trace::Tracer;

fn main() {
    let path = std::env::args().nth(1).unwrap();
    let n: usize = std::env::args().nth(2).unwrap().parse().unwrap();
    let p: Prescription = ron::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let system = LensSystem::from_prescription(p).unwrap();
    let design = system.at(system.design_wavelength_nm());
    let tracer = Tracer::new(&design);
    let first = near_axial_first_order(&tracer, &design, None).unwrap();
    println!("{first:?}");
    for param in [Parameterisation::PupilPlanes, Parameterisation::Spherical] {
        let request = BakeRequest {
            parameterisation: param,
            resolution: [
                n,
                std::env::args().nth(3).map_or(n, |v| v.parse().unwrap()),
                std::env::args().nth(3).map_or(n, |v| v.parse().unwrap()),
            ],
            precision: Precision::F32,
            ..BakeRequest::default()
        };
        let t0 = std::time::Instant::now();
        let table = bake(&system, &request, &|_| {}).unwrap();
        let secs = t0.elapsed().as_secs_f64();
        let e = table_error(&table, 0, &tracer, first.efl, 1920.0, 20000, 1);
        println!(
            "{param:?} {n}: {secs:.2}s frame {:?}\n  {e:?}",
            table.layers[0].frame
        );
    }
}
