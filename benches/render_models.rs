//! Frame time of the CPU twin per lens model on the demo scene (dgauss-50mm, 200x150 at 16
//! samples per pixel, focused at 2000 mm, wide open): the traced model against baked tables of
//! 16^3 to 128^3 nodes (f32, and the 128^3 table stored as f16), in one run, so the ratios
//! baked / traced per table size come from the same conditions. Each traced frame samples the
//! same pupil circles as its table (what `lensbake bench render` compares).
//!
//! RAYON_NUM_THREADS=1 cargo bench --bench render_models
//!
//! The clock is the process's CPU time where the platform has one (Unix), not wall time, which
//! also counts the time other processes hold the core; with one rayon thread the CPU time is
//! the frame's work (the calling thread sleeps). Other load still shows through caches and
//! clock frequency: on the 2-core development machine at a load of 3, two rounds of this bench
//! differed by up to 0.2 in a baked/traced ratio, so compare several rounds.

use criterion::{Criterion, criterion_group, criterion_main};
use lensbake::lenses;
use lensbake::lrtf::Precision;
use lensbake::lrtf::bake::{BakeRequest, bake};
use lensbake::model::{BakedLens, FirstOrderModels, LensModel, TracedLens};
use lensbake::prescription::formats::LoadOptions;
use lensbake::render::camera::{Camera, Film, Focus};
use lensbake::render::scene::Scene;
use lensbake::render::{Backend, RenderSettings, layer_view, render_layers};
use std::hint::black_box;
use std::time::Duration;

const SETTINGS: RenderSettings = RenderSettings {
    width: 200,
    height: 150,
    samples_per_pixel: 16,
    seed: 1,
    max_layers: 4,
};

const FOCUS_MM: f64 = 2000.0;

fn bench_models(c: &mut Criterion) {
    let lens = lenses::load("dgauss-50mm", &LoadOptions::default())
        .expect("bundled double Gauss")
        .system;
    let first = FirstOrderModels::of(&lens, None).expect("first-order models");
    let film = Film::full_frame_for(SETTINGS.width, SETTINGS.height);
    let scene = Scene::demo();
    let mut group = c.benchmark_group("render_cpu_dgauss_200x150_16spp");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(5));
    for (n, precision) in [
        (16, Precision::F32),
        (32, Precision::F32),
        (64, Precision::F32),
        (128, Precision::F32),
        (128, Precision::F16),
    ] {
        let request = BakeRequest {
            resolution: [n; 3],
            precision,
            focus_mm: Some(FOCUS_MM),
            max_film_radius: Some((film.width_mm / 2.0).hypot(film.height_mm / 2.0)),
            ..BakeRequest::default()
        };
        let table = bake(&lens, &request).expect("table");
        let pupil = table.layers[0].pupil.clone();
        let baked = BakedLens::new(table, &first, first.f_number).expect("baked lens");
        let film_z = baked.film_z();
        let traced = TracedLens::new(&lens, &first, first.f_number, pupil);
        let cameras = [
            ("traced", LensModel::Traced(Box::new(traced))),
            ("baked", LensModel::Baked(Box::new(baked))),
        ]
        .map(|(name, model)| {
            let camera = Camera::new(model, film, Focus::FilmZ(film_z)).expect("camera");
            (name, camera)
        });
        let nearest = scene.nearest_distance_mm().expect("scene depth") + cameras[0].1.eye_z();
        let ldi = scene.peel(
            layer_view(&cameras[0].1, &SETTINGS, nearest),
            SETTINGS.max_layers,
        );
        for (name, camera) in &cameras {
            let label = format!("{name} (table {n}^3 {})", precision.name());
            group.bench_function(label, |b| {
                b.iter_custom(|frames| {
                    let start = process_time();
                    for _ in 0..frames {
                        let frame = render_layers(camera, &ldi, &SETTINGS, Backend::Cpu, None);
                        black_box(frame.expect("CPU render"));
                    }
                    process_time() - start
                })
            });
        }
    }
    group.finish();
}

/// CPU time of this process (all its threads).
#[cfg(unix)]
fn process_time() -> Duration {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `now` is a valid timespec to write, and the process CPU-time clock exists on every
    // Unix the crate builds for.
    let status = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut now) };
    assert_eq!(status, 0, "clock_gettime(CLOCK_PROCESS_CPUTIME_ID)");
    Duration::new(now.tv_sec as u64, now.tv_nsec as u32)
}

/// Elsewhere, wall time since the first call.
#[cfg(not(unix))]
fn process_time() -> Duration {
    static START: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();
    START.get_or_init(std::time::Instant::now).elapsed()
}

criterion_group!(benches, bench_models);
criterion_main!(benches);
