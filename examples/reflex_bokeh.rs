//! Out-of-focus highlights through the bundled reflex lens: the exact trace and a baked table
//! show rings (the secondary mirror's shadow), the thin-lens model a full disc.
//!
//! cargo run --release --example reflex_bokeh -- OUT_DIR
//! e.g. `-- notebooks-out/reflex` writes traced.png, baked.png and thin.png there.
use lensbake::lrtf::bake::{BakeRequest, bake};
use lensbake::model::{BakedLens, FirstOrderModels, LensModel, TracedLens};
use lensbake::render::camera::{Camera, Film, Focus};
use lensbake::render::image::write_png;
use lensbake::render::scene::Scene;
use lensbake::render::{Backend, RenderSettings, layer_view, render_layers};
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(
        std::env::args()
            .nth(1)
            .ok_or("usage: reflex_bokeh OUT_DIR")?,
    );
    let system = lensbake::lenses::load("reflex-1000mm-f7.5", &Default::default())?.system;
    let first = FirstOrderModels::of(&system, None)?;
    // 8 mm of film focused at infinity; highlights 50 m out blur into 2.7 mm discs.
    let film = Film {
        width_mm: 8.0,
        height_mm: 8.0,
        shift_mm: [0.0, 0.0],
        tilt_deg: [0.0, 0.0],
    };
    let request = BakeRequest {
        resolution: [32; 3],
        max_film_radius: Some(5.7),
        ..BakeRequest::default()
    };
    let table = bake(&system, &request, &|_| {})?;
    let pupil = table.layers[0].pupil.clone();
    let baked = BakedLens::new(table, &first, first.f_number)?;
    let film_z = baked.film_z();
    let traced = TracedLens::new(&system, &first, first.f_number, pupil);
    let thin_z = first.thin.rear_principal_z + first.thin.focal_length_mm;
    let settings = RenderSettings {
        width: 256,
        height: 256,
        samples_per_pixel: 256,
        seed: 1,
        max_layers: 2,
    };
    let scene = Scene::highlight(5e4, 5.0, 200.0);
    for (name, model, z) in [
        ("traced", LensModel::Traced(Box::new(traced)), film_z),
        ("baked", LensModel::Baked(Box::new(baked)), film_z),
        ("thin", LensModel::Thin(first.thin.clone()), thin_z),
    ] {
        let camera = Camera::new(model, film, Focus::FilmZ(z))?;
        let nearest = scene.nearest_distance_mm().ok_or("empty scene")? + camera.eye_z();
        let layers = scene.peel(layer_view(&camera, &settings, nearest), settings.max_layers);
        let image = render_layers(&camera, &layers, &settings, Backend::Cpu, None)?;
        write_png(&image, 1.0, &out.join(format!("{name}.png")))?;
    }
    Ok(())
}
