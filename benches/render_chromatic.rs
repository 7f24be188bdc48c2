//! Cost of chromatic rendering (one lens ray per colour channel) against the monochrome render:
//! the CODE V double Gauss (catalogue glasses) on the demo scene, 160x120 at 16 samples per
//! pixel, thick, traced and baked (32^3 table holding C, d, F), on the CPU twin and, where an
//! adapter exists, the GPU.
//!
//! cargo bench --bench render_chromatic

use criterion::{Criterion, criterion_group, criterion_main};
use lensbake::lenses;
use lensbake::lrtf::bake::{BakeRequest, bake};
use lensbake::model::LensModel;
use lensbake::model::{BakedLens, FirstOrderModels, TracedLens};
use lensbake::prescription::formats::LoadOptions;
use lensbake::render::camera::{Camera, Film, Focus};
use lensbake::render::chromatic::{Chromatic, default_wavelengths};
use lensbake::render::gpu::GpuRenderer;
use lensbake::render::layers::LayeredDepthImage;
use lensbake::render::scene::Scene;
use lensbake::render::{Backend, RenderSettings, layer_view, render_layers};
use std::hint::black_box;
use std::time::Duration;

const SETTINGS: RenderSettings = RenderSettings {
    width: 160,
    height: 120,
    samples_per_pixel: 16,
    seed: 1,
    max_layers: 8,
};

/// (model name, monochrome camera, chromatic camera) for thick, traced and baked.
fn cameras() -> Vec<(&'static str, Camera, Camera)> {
    let lens = lenses::load("codev-dgauss-f2", &LoadOptions::default())
        .expect("bundled CODE V double Gauss")
        .system;
    let first = FirstOrderModels::of(&lens, None).expect("first-order models");
    let film = Film::full_frame_for(SETTINGS.width, SETTINGS.height);
    let thick = Camera::new(
        LensModel::Thick(first.thick.clone()),
        film,
        Focus::ObjectDistance(2000.0),
    )
    .expect("thick camera");
    let (corner, film_z) = (thick.film_corner_radius(), thick.film_z);
    let traced =
        TracedLens::fitted(&lens, &first, first.f_number, film_z, corner, 32).expect("traced lens");
    let request = BakeRequest {
        resolution: [32; 3],
        focus_mm: Some(2000.0),
        max_film_radius: Some(corner),
        wavelengths_nm: default_wavelengths(&lens).to_vec(),
        ..BakeRequest::default()
    };
    let table = bake(&lens, &request).expect("table");
    let baked = BakedLens::new(table, &first, first.f_number)
        .and_then(|b| b.with_wavelength(lens.design_wavelength_nm()))
        .expect("baked lens");
    let baked_z = baked.film_z();
    let models = [
        ("thick", thick),
        (
            "traced",
            Camera::new(
                LensModel::Traced(Box::new(traced)),
                film,
                Focus::FilmZ(film_z),
            )
            .expect("traced camera"),
        ),
        (
            "baked",
            Camera::new(
                LensModel::Baked(Box::new(baked)),
                film,
                Focus::FilmZ(baked_z),
            )
            .expect("baked camera"),
        ),
    ];
    models
        .into_iter()
        .map(|(name, mono)| {
            let chromatic =
                Chromatic::for_camera(&mono, &lens, &first, default_wavelengths(&lens), 32)
                    .expect("chromatic channels");
            let colour = mono
                .clone()
                .with_chromatic(chromatic)
                .expect("chromatic camera");
            (name, mono, colour)
        })
        .collect()
}

fn layers(camera: &Camera) -> LayeredDepthImage {
    let scene = Scene::demo();
    let view = layer_view(camera, &SETTINGS, scene.nearest_distance_mm().unwrap());
    scene.peel(view, SETTINGS.max_layers)
}

fn bench_render(c: &mut Criterion) {
    let gpu = GpuRenderer::new().ok();
    if let Some(gpu) = &gpu {
        gpu.prepare_chromatic().expect("chromatic pipeline");
    }
    for (name, mono, colour) in cameras() {
        let ldi = layers(&mono);
        let mut group = c.benchmark_group(format!("render_{name}"));
        group
            .sample_size(10)
            .measurement_time(Duration::from_secs(6));
        for (label, camera) in [("mono", &mono), ("chromatic", &colour)] {
            group.bench_function(format!("cpu_{label}"), |b| {
                b.iter(|| black_box(render_layers(camera, &ldi, &SETTINGS, Backend::Cpu, None)))
            });
            if let Some(gpu) = &gpu {
                group.bench_function(format!("gpu_{label}"), |b| {
                    b.iter(|| {
                        black_box(render_layers(
                            camera,
                            &ldi,
                            &SETTINGS,
                            Backend::Gpu,
                            Some(gpu),
                        ))
                    })
                });
            }
        }
        group.finish();
    }
}

criterion_group!(benches, bench_render);
criterion_main!(benches);
