//! A catadioptric lens bakes and renders, and its out-of-focus highlights are rings: the
//! secondary mirror's shadow takes the centre out of every beam, which the exact trace and the
//! baked table both show and no paraxial (thin) model can.

use lensbake::lrtf::bake::{BakeRequest, bake};
use lensbake::model::{BakedLens, FirstOrderModels, LensModel, TracedLens};
use lensbake::render::camera::{Camera, Film, Focus};
use lensbake::render::image::RgbImage;
use lensbake::render::scene::Scene;
use lensbake::render::{Backend, RenderSettings, layer_view, render_layers};

const SIZE: u32 = 64;

/// Mean luminance in rings one pixel wide around the frame's centre, innermost first.
fn radial_profile(image: &RgbImage) -> Vec<f64> {
    let centre = f64::from(SIZE) / 2.0;
    let mut sums = vec![(0.0, 0usize); SIZE as usize / 2];
    for y in 0..SIZE {
        for x in 0..SIZE {
            let r = (f64::from(x) + 0.5 - centre).hypot(f64::from(y) + 0.5 - centre) as usize;
            if let Some(bin) = sums.get_mut(r) {
                let p = image.pixel(x, y);
                bin.0 += f64::from(p[0] + p[1] + p[2]) / 3.0;
                bin.1 += 1;
            }
        }
    }
    sums.into_iter().map(|(s, n)| s / n as f64).collect()
}

#[test]
fn the_reflex_lens_renders_defocused_highlights_as_rings() {
    let system = lensbake::lenses::load("reflex-1000mm-f7.5", &Default::default())
        .unwrap()
        .system;
    let first = FirstOrderModels::of(&system, None).unwrap();
    // A 6 mm square of film at the focus for infinity; a highlight 50 m out blurs into a disc
    // f^2 / (L N) = 2.7 mm (28 px) across, whose centre the obscuration (0.375 of the pupil's
    // radius) darkens over about 10 px.
    let film = Film {
        width_mm: 6.0,
        height_mm: 6.0,
        shift_mm: [0.0, 0.0],
        tilt_deg: [0.0, 0.0],
    };
    let request = BakeRequest {
        resolution: [16; 3],
        max_film_radius: Some(4.3),
        ..BakeRequest::default()
    };
    let table = bake(&system, &request, &|_| {}).unwrap();
    let pupil = table.layers[0].pupil.clone();
    let baked = BakedLens::new(table, &first, first.f_number).unwrap();
    let film_z = baked.film_z();
    let traced = TracedLens::new(&system, &first, first.f_number, pupil);
    let thin_z = first.thin.rear_principal_z + first.thin.focal_length_mm;
    let settings = RenderSettings {
        width: SIZE,
        height: SIZE,
        samples_per_pixel: 64,
        seed: 11,
        max_layers: 2,
    };
    let scene = Scene::highlight(5e4, 5.0, 200.0);
    for (name, model, z) in [
        ("traced", LensModel::Traced(Box::new(traced)), film_z),
        ("baked", LensModel::Baked(Box::new(baked)), film_z),
        ("thin", LensModel::Thin(first.thin.clone()), thin_z),
    ] {
        let camera = Camera::new(model, film, Focus::FilmZ(z)).unwrap();
        let nearest = scene.nearest_distance_mm().unwrap() + camera.eye_z();
        let layers = scene.peel(layer_view(&camera, &settings, nearest), settings.max_layers);
        let image = render_layers(&camera, &layers, &settings, Backend::Cpu, None).unwrap();
        let profile = radial_profile(&image);
        let peak = profile.iter().copied().fold(0.0, f64::max);
        let centre = (profile[0] + profile[1] + profile[2]) / 3.0;
        let ring = profile.iter().position(|&v| v == peak).unwrap();
        eprintln!("reflex lens, {name}: centre {centre:.3}, ring peak {peak:.3} at r = {ring} px");
        assert!(peak > 0.05, "{name}: nothing visible ({peak})");
        if name == "thin" {
            // A thin lens's pupil is a full disc: its bokeh is as bright in the middle as
            // anywhere (64 samples a pixel leave the few central pixels noisy).
            assert!(centre > 0.5 * peak, "{name}: centre {centre}, peak {peak}");
        } else {
            assert!(centre < 0.1 * peak, "{name}: centre {centre}, peak {peak}");
            assert!((5..14).contains(&ring), "{name}: ring at {ring} px");
        }
    }
}
