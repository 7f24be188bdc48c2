//! Ray-surface intersections per second of the exact trace, on one core and on all cores, for
//! the oracle's 50 mm double Gauss (11 surfaces) with the `lensbake bench trace` ray bundle.
//! Criterion's throughput line reads "elements/s" = ray-surface intersections per second.
//! `one_core` and `all_cores` trace into one reused result (`Tracer::trace_batch_into`, as a
//! caller tracing batch after batch does); `one_core_new_output` allocates the result every
//! call (`Tracer::trace_batch`), so its fresh pages are part of the time. `one_core_rows` traces
//! the same rays given as rows (`Tracer::trace_rows_into`, the path Python's `Lens.trace`
//! takes: rows normalised and start-checked, results written as rows) into reused storage.
//!
//! `trace_asph50` traces the same kind of bundle through the bundled Canon RF 50 mm f/1.8
//! (`asph-50mm-f1.8`, two even aspheres among 12 surfaces) on one core: the batch trace, which
//! meets the aspheres in vector lanes, against one ray at a time (`Tracer::trace`).
//! `trace_reflex1000` does the same for the bundled catadioptric 1000 mm f/7.5
//! (`reflex-1000mm-f7.5`: two Mangin mirrors and a centrally obscured surface among 24).
//!
//! `aim_fisheye_top_field` aims a 17 x 17 grid of stop points at the fisheye's top field (77.95
//! degrees, where the paraxial pupil misses the lens): each point alone from the paraxial guess
//! (`aim_at_stop`, a ring search where that guess fails) against the field's points started
//! from its chief ray (`StopAim`), as the real-aiming analyses launch a field's rays.

#[path = "../tests/common/mod.rs"]
mod common;

use common::load_oracle;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use lensbake::system::LensSystem;
use lensbake::trace::{
    Apertures, BatchTrace, FieldBundle, RayBatch, RaySource, RowResults, StartCheck, StopAim,
    Tracer, Travel, Vec3, aim_at_stop,
};

const RAYS: usize = 100_000;

/// [`RAYS`] rays of the `bench trace` bundle through `tracer`'s lens, and the ray-surface
/// intersections they make.
fn bundle(tracer: &Tracer) -> (RayBatch, u64) {
    let rays = FieldBundle::over_traceable_field(tracer)
        .unwrap()
        .sample(RAYS, 1);
    let ray_surfaces = tracer
        .trace_batch(&rays, Travel::Forward, Apertures::Checked)
        .ray_surfaces;
    (rays, ray_surfaces)
}

fn threads(count: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(count)
        .build()
        .unwrap()
}

fn trace(c: &mut Criterion) {
    let system =
        LensSystem::from_prescription(load_oracle("pbrt_dgauss_50mm").prescription).unwrap();
    let at = system.at(system.design_wavelength_nm());
    let tracer = Tracer::new(&at);
    let (rays, ray_surfaces) = bundle(&tracer);

    let mut group = c.benchmark_group("trace_dgauss50");
    group.throughput(Throughput::Elements(ray_surfaces));
    group.sample_size(20);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    for (name, count) in [("one_core", 1), ("all_cores", cores)] {
        let pool = threads(count);
        let mut out = BatchTrace::default();
        group.bench_function(name, |b| {
            b.iter(|| {
                pool.install(|| {
                    tracer.trace_batch_into(&rays, Travel::Forward, Apertures::Checked, &mut out)
                })
            })
        });
    }
    let one = threads(1);
    group.bench_function("one_core_new_output", |b| {
        b.iter(|| one.install(|| tracer.trace_batch(&rays, Travel::Forward, Apertures::Checked)))
    });
    let positions: Vec<Vec3> = rays.iter().map(|ray| ray.position()).collect();
    let directions: Vec<Vec3> = rays.iter().map(|ray| ray.direction()).collect();
    let (mut ends, mut headings) = (vec![[0.0; 3]; RAYS], vec![[0.0; 3]; RAYS]);
    let (mut kinds, mut surfaces) = (vec![0; RAYS], vec![0; RAYS]);
    let starts = StartCheck::new(&at, Travel::Forward);
    group.bench_function("one_core_rows", |b| {
        b.iter(|| {
            let out = RowResults {
                positions: &mut ends,
                directions: &mut headings,
                outcome_kinds: &mut kinds,
                outcome_surfaces: &mut surfaces,
            };
            one.install(|| {
                tracer.trace_rows_into(
                    &positions,
                    &directions,
                    Travel::Forward,
                    Apertures::Checked,
                    &starts,
                    out,
                )
            })
        })
    });
    group.finish();
}

/// The batch trace of the bundled lens `name` on one core against one ray at a time.
fn batch_against_one_ray(c: &mut Criterion, group: &str, name: &str) {
    let lens = lensbake::lenses::load(name, &Default::default()).unwrap();
    let tracer = Tracer::new(&lens.system.at(lens.system.design_wavelength_nm()));
    let (rays, ray_surfaces) = bundle(&tracer);
    let one = threads(1);
    let mut group = c.benchmark_group(group);
    group.throughput(Throughput::Elements(ray_surfaces));
    group.sample_size(20);
    let mut out = BatchTrace::default();
    group.bench_function("one_core", |b| {
        b.iter(|| {
            one.install(|| {
                tracer.trace_batch_into(&rays, Travel::Forward, Apertures::Checked, &mut out)
            })
        })
    });
    group.bench_function("one_ray_at_a_time", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|&ray| tracer.trace(ray, Travel::Forward).outcome.is_ok())
                .count()
        })
    });
    group.finish();
}

fn trace_aspheric(c: &mut Criterion) {
    batch_against_one_ray(c, "trace_asph50", "asph-50mm-f1.8");
}

fn trace_catadioptric(c: &mut Criterion) {
    batch_against_one_ray(c, "trace_reflex1000", "reflex-1000mm-f7.5");
}

fn aim(c: &mut Criterion) {
    let lens = lensbake::lenses::load("fisheye-10mm", &Default::default()).unwrap();
    let at = lens.system.at(lens.system.design_wavelength_nm());
    let tracer = Tracer::new(&at);
    let source = RaySource::collimated(77.95, tracer.front_start_z());
    let radius = at.surfaces[tracer.stop_surface() - 1].semi_aperture;
    let targets: Vec<[f64; 2]> = (0..17 * 17)
        .map(|k| [(k % 17) as f64 / 8.0 - 1.0, (k / 17) as f64 / 8.0 - 1.0].map(|t| t * radius))
        .collect();
    let mut group = c.benchmark_group("aim_fisheye_top_field");
    group.throughput(Throughput::Elements(targets.len() as u64));
    group.sample_size(10);
    group.bench_function("each_point_alone", |b| {
        b.iter(|| {
            targets
                .iter()
                .filter(|&&t| aim_at_stop(&tracer, &source, t).is_ok())
                .count()
        })
    });
    group.bench_function("from_the_chief_ray", |b| {
        b.iter(|| {
            let field = StopAim::new(&tracer, source);
            targets.iter().filter(|&&t| field.aim(t).is_ok()).count()
        })
    });
    group.finish();
}

criterion_group!(benches, trace, trace_aspheric, trace_catadioptric, aim);
criterion_main!(benches);
