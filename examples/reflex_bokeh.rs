//! Out-of-focus highlights through the bundled reflex lens: the exact trace and a baked table
//! show rings (the secondary mirror's shadow), the thin-lens model a full disc.
//!
//! cargo run --release --example reflex_bokeh -- OUT_DIR
//! e.g. `-- notebooks-out/reflex` writes traced.png, baked.png and thin.png there.
//! tests/reflex_bokeh.rs renders the same frames small and measures the rings.

use lensbake::lrtf::bake::{BakeRequest, bake};
use lensbake::model::{BakedLens, FirstOrderModels, LensModel, TracedLens};
use lensbake::render::camera::{Camera, Film, Focus};
use lensbake::render::image::{RgbImage, write_png};
use lensbake::render::scene::Scene;
use lensbake::render::{Backend, RenderSettings, layer_view, render_layers};
use std::path::PathBuf;

/// A square of film `film_mm` wide focused at infinity, one highlight 50 m out on the axis
/// (it blurs into a disc f^2 / (L N) = 2.7 mm across), rendered on the CPU twin through the
/// traced lens, a baked table of `table_nodes`^3 and the thin-lens model, in that order.
pub fn highlight_frames(
    settings: &RenderSettings,
    film_mm: f64,
    table_nodes: usize,
) -> Result<Vec<(&'static str, RgbImage)>, Box<dyn std::error::Error>> {
    let system = lensbake::lenses::load("reflex-1000mm-f7.5", &Default::default())?.system;
    let first = FirstOrderModels::of(&system, None)?;
    let film = Film {
        width_mm: film_mm,
        height_mm: film_mm,
        shift_mm: [0.0, 0.0],
        tilt_deg: [0.0, 0.0],
    };
    let request = BakeRequest {
        resolution: [table_nodes; 3],
        // The film's corner, and a little beyond.
        max_film_radius: Some(0.75 * film_mm),
        ..BakeRequest::default()
    };
    let table = bake(&system, &request)?;
    let pupil = table.layers[0].pupil.clone();
    let baked = BakedLens::new(table, &first, first.f_number)?;
    let film_z = baked.film_z();
    let traced = TracedLens::new(&system, &first, first.f_number, pupil);
    let thin_z = first.thin.rear_principal_z + first.thin.focal_length_mm;
    let scene = Scene::highlight(5e4, 5.0, 200.0);
    let mut frames = Vec::new();
    for (name, model, z) in [
        ("traced", LensModel::Traced(Box::new(traced)), film_z),
        ("baked", LensModel::Baked(Box::new(baked)), film_z),
        ("thin", LensModel::Thin(first.thin.clone()), thin_z),
    ] {
        let camera = Camera::new(model, film, Focus::FilmZ(z))?;
        let nearest = scene.nearest_distance_mm().ok_or("empty scene")? + camera.eye_z();
        let layers = scene.peel(layer_view(&camera, settings, nearest), settings.max_layers);
        frames.push((
            name,
            render_layers(&camera, &layers, settings, Backend::Cpu, None)?,
        ));
    }
    Ok(frames)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(
        std::env::args()
            .nth(1)
            .ok_or("usage: reflex_bokeh OUT_DIR")?,
    );
    let settings = RenderSettings {
        width: 256,
        height: 256,
        samples_per_pixel: 256,
        seed: 1,
        max_layers: 2,
    };
    for (name, image) in highlight_frames(&settings, 8.0, 32)? {
        write_png(&image, 1.0, &out.join(format!("{name}.png")))?;
    }
    Ok(())
}
