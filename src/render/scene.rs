//! Scenes made of flat panels facing the lens, the built-in demo scene, and depth peeling.
//!
//! Panels are perpendicular to the optical axis, so their true geometry is exact for the
//! reference renderer and a pinhole view of them is exact depth peeling: every panel crossed by
//! a pixel's central ray is one layer of that pixel.

use super::layers::{LayeredDepthImage, Surfel, View};
use rayon::prelude::*;

/// Outline of a panel in its plane (mm, x right and y up as seen from the lens).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Outline {
    Rect { min: [f64; 2], max: [f64; 2] },
    Disc { centre: [f64; 2], radius: f64 },
}

impl Outline {
    fn contains(&self, p: [f64; 2]) -> bool {
        match *self {
            Outline::Rect { min, max } => {
                p[0] >= min[0] && p[0] < max[0] && p[1] >= min[1] && p[1] < max[1]
            }
            Outline::Disc { centre, radius } => {
                let d = [p[0] - centre[0], p[1] - centre[1]];
                d[0] * d[0] + d[1] * d[1] < radius * radius
            }
        }
    }
}

/// Emitted linear RGB radiance over a panel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Texture {
    Solid([f32; 3]),
    Checker {
        a: [f32; 3],
        b: [f32; 3],
        period_mm: f64,
    },
}

impl Texture {
    fn radiance(&self, p: [f64; 2]) -> [f32; 3] {
        match *self {
            Texture::Solid(c) => c,
            Texture::Checker { a, b, period_mm } => {
                let parity = (p[0] / period_mm).floor() as i64 + (p[1] / period_mm).floor() as i64;
                if parity.rem_euclid(2) == 0 { a } else { b }
            }
        }
    }
}

/// A flat, self-emitting panel `distance_mm` in front of the lens's first vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Panel {
    pub distance_mm: f64,
    pub outline: Outline,
    pub texture: Texture,
}

/// The lens `lensbake demo` renders the demo scene through by default: a 50 mm of real
/// (model) glasses, so the main job shows lateral and axial colour.
pub const DEMO_LENS: &str = "asph-50mm-f1.8";

/// The demo's emitters: (distance in front of the lens, radius, centre, all mm; linear RGB
/// radiance).
pub const DEMO_EMITTERS: [(f64, f64, [f64; 2], [f32; 3]); 8] = [
    (5000.0, 12.0, [1500.0, 800.0], [8.0, 6.0, 2.4]),
    (5000.0, 12.0, [1400.0, -900.0], [2.4, 6.0, 9.0]),
    (5000.0, 12.0, [-1500.0, 950.0], [9.0, 2.4, 6.0]),
    (5000.0, 12.0, [-1600.0, -950.0], [7.0, 7.0, 7.0]),
    (1200.0, 4.0, [-350.0, 250.0], [6.0, 5.5, 4.0]),
    (300.0, 3.0, [-75.0, 45.0], [40.0, 32.0, 20.0]),
    (300.0, 3.0, [55.0, -42.0], [20.0, 32.0, 44.0]),
    (300.0, 3.0, [80.0, 50.0], [36.0, 36.0, 36.0]),
];

/// The demo's default frame (pixels): the largest 4:3 frame whose chromatic traced and baked
/// renders take about a minute together on the 2-core CPU twin / lavapipe (docs in README).
pub const DEMO_SIZE: (u32, u32) = (320, 240);

#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    pub panels: Vec<Panel>,
}

impl Scene {
    /// The built-in demo: a checkered back wall, a striped panel near the focus distance, a dark
    /// red foreground post and bar whose blurred edges show partial occlusion, and small bright
    /// emitters near and far for bokeh. Meant for a ~50 mm lens on a full-frame film focused at
    /// about 2 m.
    pub fn demo() -> Scene {
        let wall = Panel {
            distance_mm: 6000.0,
            outline: Outline::Rect {
                min: [-6000.0, -4000.0],
                max: [6000.0, 4000.0],
            },
            texture: Texture::Checker {
                a: [0.05, 0.08, 0.20],
                b: [0.60, 0.62, 0.65],
                period_mm: 300.0,
            },
        };
        let chart = Panel {
            distance_mm: 2000.0,
            outline: Outline::Rect {
                min: [-450.0, -250.0],
                max: [300.0, 250.0],
            },
            texture: Texture::Checker {
                a: [0.80, 0.75, 0.55],
                b: [0.10, 0.10, 0.10],
                period_mm: 40.0,
            },
        };
        let post = Panel {
            distance_mm: 900.0,
            outline: Outline::Rect {
                min: [100.0, -1000.0],
                max: [170.0, 1000.0],
            },
            texture: Texture::Solid([0.35, 0.04, 0.03]),
        };
        let bar = Panel {
            distance_mm: 1100.0,
            outline: Outline::Rect {
                min: [-1000.0, -260.0],
                max: [-150.0, -215.0],
            },
            texture: Texture::Solid([0.08, 0.30, 0.06]),
        };
        let mut panels = vec![wall, chart, post, bar];
        // Emitters are HDR: small discs whose light spreads over a defocus disc many times their
        // image, so each disc's radiance times (image radius / blur radius)^2 lands near
        // 1 to 8, bright but not clipped white by the tone curve x / (1 + x). Far lights (5 m)
        // blur a little behind the chart; near lights (0.3 m) into discs over 30 px wide in
        // the default frame for a 50 mm f/1.8 focused at 2 m (tested below).
        for (distance_mm, radius, centre, colour) in DEMO_EMITTERS {
            panels.push(Panel {
                distance_mm,
                outline: Outline::Disc { centre, radius },
                texture: Texture::Solid(colour),
            });
        }
        Scene { panels }
    }

    /// One small round emitter on the axis, `distance_mm` in front of the lens, on black: a
    /// highlight whose defocused image is the lens's bokeh, the shape of its effective pupil.
    pub fn highlight(distance_mm: f64, radius_mm: f64, radiance: f32) -> Scene {
        Scene {
            panels: vec![Panel {
                distance_mm,
                outline: Outline::Disc {
                    centre: [0.0, 0.0],
                    radius: radius_mm,
                },
                texture: Texture::Solid([radiance; 3]),
            }],
        }
    }

    /// Nearest panel distance in front of the first vertex.
    pub fn nearest_distance_mm(&self) -> Option<f64> {
        self.panels.iter().map(|p| p.distance_mm).reduce(f64::min)
    }

    /// Every panel hit by the line from the eye with tangents `tan`: (distance from the eye,
    /// radiance). The reference renderer and depth peeling share this.
    pub fn hits_along(&self, eye_z: f64, tan: [f64; 2]) -> Vec<Surfel> {
        self.panels
            .iter()
            .filter_map(|panel| {
                let depth = eye_z + panel.distance_mm;
                let p = [tan[0] * depth, tan[1] * depth];
                (depth > 0.0 && panel.outline.contains(p)).then(|| Surfel {
                    depth_mm: depth as f32,
                    radiance: panel.texture.radiance(p),
                })
            })
            .collect()
    }

    /// The radiance seen along a general object-space ray travelling towards the lens: the
    /// first panel it crosses when followed back into the scene. `origin` is a lens-frame point
    /// and `direction` has positive z.
    pub fn radiance_along(&self, origin: [f64; 3], direction: [f64; 3]) -> [f32; 3] {
        let mut best: Option<(f64, [f32; 3])> = None;
        for panel in &self.panels {
            let t = (-panel.distance_mm - origin[2]) / direction[2];
            if t >= 0.0 {
                continue;
            }
            let p = [origin[0] + t * direction[0], origin[1] + t * direction[1]];
            if panel.outline.contains(p) && best.is_none_or(|(bt, _)| t > bt) {
                best = Some((t, panel.texture.radiance(p)));
            }
        }
        best.map_or([0.0; 3], |(_, c)| c)
    }

    /// Depth-peels the scene from the eye of `view`: one layer per panel crossed by each pixel's
    /// central ray, nearest first, at most `max_layers`.
    pub fn peel(&self, view: View, max_layers: usize) -> LayeredDepthImage {
        let pixels: Vec<Vec<Surfel>> = (0..view.width * view.height)
            .into_par_iter()
            .map(|i| {
                self.hits_along(
                    view.eye_z,
                    view.pixel_tangents(i % view.width, i / view.width),
                )
            })
            .collect();
        LayeredDepthImage::from_pixel_lists(view, pixels, max_layers)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The demo's bokeh is judged on a 50 mm f/1.8 focused at 2 m, the default frame's width
    /// across a 36 mm film (thin lens): every emitter is HDR (above 1), the near ones blur into discs at least 30 px
    /// wide, and each disc's level (radiance times the emitter's image area over the blur
    /// disc's) sits between 1 and 8, bright after the tone curve x / (1 + x) but not white.
    #[test]
    fn the_demo_lens_disperses() {
        let lens = crate::lenses::load(DEMO_LENS, &Default::default()).unwrap();
        assert!(lens.system.disperses());
        let index = |nm: f64| lens.system.at(nm).surfaces[0].index_after;
        assert!(
            index(486.13) - index(656.27) > 1e-3,
            "no dispersion in the first element"
        );
    }

    #[test]
    fn demo_emitters_are_hdr_and_blur_into_visible_unclipped_discs() {
        let (f, aperture, focus) = (50.0, 50.0 / 1.8, 2000.0);
        let px_per_mm = DEMO_SIZE.0 as f64 / 36.0;
        let image = |d: f64| f * d / (d - f);
        let mut near_discs = 0;
        for (distance, radius, _, colour) in DEMO_EMITTERS {
            let brightest = colour.iter().copied().fold(0.0f32, f32::max) as f64;
            assert!(colour.iter().all(|&c| c > 1.0), "{colour:?} is not HDR");
            let blur_mm = aperture * (image(distance) - image(focus)).abs() / image(distance);
            let image_radius = radius * image(focus) / distance;
            let level = brightest * (image_radius / (0.5 * blur_mm)).powi(2);
            assert!(
                (1.0..8.0).contains(&level),
                "emitter at {distance} mm: disc level {level}"
            );
            if blur_mm * px_per_mm >= 30.0 {
                near_discs += 1;
            }
        }
        assert!(near_discs >= 3, "{near_discs} discs of 30 px or more");
    }

    #[test]
    fn peeled_layers_are_ordered_and_dense() {
        let view = View {
            eye_z: 0.0,
            tan_half: [0.4, 0.27],
            width: 64,
            height: 48,
        };
        let ldi = Scene::demo().peel(view, 8);
        assert!(
            ldi.layer_count() >= 3,
            "the post over the chart over the wall gives 3 layers"
        );
        for pixel in 0..(64 * 48) {
            let mut previous = 0.0;
            let mut ended = false;
            for layer in ldi.layers() {
                match layer.get(pixel) {
                    Some(s) => {
                        assert!(!ended && s.depth_mm > previous);
                        previous = s.depth_mm;
                    }
                    None => ended = true,
                }
            }
            assert!(ldi.surfel(0, pixel).is_some(), "the wall covers the view");
        }
    }
}
