//! LRTF cost: baking the bundled 50 mm double Gauss at 32^3, 64^3 and the 128^3 default, a
//! 64^3 table for the focus range infinity..1 m, and sampler lookups per second over the
//! renderer's ray distribution, one at a time and grouped as the renderer makes them.
//!
//! cargo bench --bench lrtf

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use lensbake::lenses;
use lensbake::lrtf::bake::{BakeRequest, bake};
use lensbake::lrtf::measure::renderer_rays;
use lensbake::lrtf::{Lookup, LrtfTable, Ray};
use lensbake::prescription::formats::LoadOptions;
use lensbake::system::LensSystem;
use std::hint::black_box;
use std::time::Duration;

fn dgauss() -> LensSystem {
    lenses::load("dgauss-50mm", &LoadOptions::default())
        .expect("bundled double Gauss")
        .system
}

fn baked(system: &LensSystem, n: usize) -> LrtfTable {
    let request = BakeRequest {
        resolution: [n, n, n],
        ..BakeRequest::default()
    };
    bake(system, &request).expect("the double Gauss bakes")
}

fn baked_for_range(system: &LensSystem, n: usize) -> LrtfTable {
    let request = BakeRequest {
        resolution: [n, n, n],
        focus_near_mm: Some(1000.0),
        ..BakeRequest::default()
    };
    bake(system, &request).expect("the double Gauss bakes for a range")
}

/// `count` rays drawn as the renderer draws them for layer 0 of `table`, and its stop radius.
fn renderer_rays_of(table: &LrtfTable, count: usize) -> (Vec<Ray>, f64) {
    let layer = &table.layers[0];
    let rays = renderer_rays(
        &layer.pupil,
        layer.frame.max_film_radius,
        layer.frame.film_plane_z,
        layer.frame.rear_plane_z,
        count,
        1,
    );
    (rays, layer.stop_semi_aperture)
}

/// The table sizes timed.
const SIZES: [usize; 3] = [32, 64, 128];

fn bench_bake(c: &mut Criterion) {
    let system = dgauss();
    let mut group = c.benchmark_group("lrtf_bake_dgauss");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(8));
    for n in SIZES {
        group.throughput(Throughput::Elements((n * n * n) as u64));
        group.bench_function(format!("{n}^3"), |b| b.iter(|| baked(&system, n)));
    }
    group.throughput(Throughput::Elements(64 * 64 * 64));
    group.bench_function("64^3 focus infinity..1000 mm", |b| {
        b.iter(|| baked_for_range(&system, 64))
    });
    group.finish();
}

fn bench_lookup(c: &mut Criterion) {
    let table = baked(&dgauss(), 64);
    let (rays, stop) = renderer_rays_of(&table, 10_000);
    let mut group = c.benchmark_group("lrtf_lookup_dgauss_64");
    group.throughput(Throughput::Elements(rays.len() as u64));
    group.bench_function("one_thread", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|ray| {
                    matches!(
                        table.lookup_layer(0, black_box(ray), stop),
                        Lookup::Passes(_)
                    )
                })
                .count()
        })
    });
    group.finish();
}

/// The grouped lookup the renderer uses, over a million rays in random order, by table size:
/// the larger tables outgrow the caches, and this measures what that costs per lookup.
fn bench_lookup_group(c: &mut Criterion) {
    let system = dgauss();
    let mut group = c.benchmark_group("lrtf_lookup_group_dgauss");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(5));
    for n in SIZES {
        let table = baked(&system, n);
        let (rays, stop) = renderer_rays_of(&table, 1_000_000);
        let mut out = vec![Lookup::OutsideDomain; rays.len()];
        group.throughput(Throughput::Elements(rays.len() as u64));
        group.bench_function(format!("{n}^3 one_thread"), |b| {
            b.iter(|| {
                table.lookup_group(0, black_box(&rays), stop, &mut out);
                out.iter()
                    .filter(|l| matches!(l, Lookup::Passes(_)))
                    .count()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_bake, bench_lookup, bench_lookup_group);
criterion_main!(benches);
