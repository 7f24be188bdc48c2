//! A catadioptric lens bakes and renders, and its out-of-focus highlights are rings: the
//! secondary mirror's shadow takes the centre out of every beam, which the exact trace and the
//! baked table both show and no paraxial (thin) model can.
#![cfg(feature = "render")]

use lensbake::render::RenderSettings;
use lensbake::render::image::RgbImage;

/// The example's frames (examples/reflex_bokeh.rs renders them large for notebooks-out/reflex).
#[path = "../examples/reflex_bokeh.rs"]
#[allow(dead_code)]
mod reflex_bokeh;

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
    // A 6 mm square of film: the highlight's 2.7 mm disc is 28 px across, and the obscuration
    // (0.375 of the pupil's radius) darkens its centre over about 10 px.
    let settings = RenderSettings {
        width: SIZE,
        height: SIZE,
        samples_per_pixel: 64,
        seed: 11,
        max_layers: 2,
    };
    for (name, image) in reflex_bokeh::highlight_frames(&settings, 6.0, 16).unwrap() {
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
