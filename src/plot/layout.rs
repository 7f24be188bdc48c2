//! Lens layout: the meridional cross-section drawn to scale, surfaces to their clear apertures,
//! glass shaded, the stop marked, ray bundles coloured by field.

use super::chart::{LABEL_SIZE, tick_label};
use super::color::PALETTE;
use super::font::FONT_FAMILY;
use super::{Drawn, PanelDrawn, PlotError, SeriesDrawn, View, draw_error};
use crate::prescription::Shape;
use crate::system::SystemAt;
use plotters::coord::Shift;
use plotters::prelude::*;

/// One surface's meridional profile, (z, y) in the lens frame from -semi_aperture to
/// +semi_aperture.
#[derive(Clone, Debug, PartialEq)]
pub struct LayoutSurface {
    /// 1-based surface number.
    pub number: usize,
    pub profile: Vec<(f64, f64)>,
    pub semi_aperture: f64,
    pub stop: bool,
}

/// Glass between two surfaces (0-based indices into `LayoutPlot::surfaces`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LayoutElement {
    pub front: usize,
    pub back: usize,
}

/// A ray's meridional path (z, y) from object space to the image plane, or to the surface that
/// stopped it.
#[derive(Clone, Debug, PartialEq)]
pub struct LayoutRay {
    pub field_deg: f64,
    pub path: Vec<(f64, f64)>,
    pub vignetted: bool,
}

#[derive(Clone, Debug, PartialEq)]
pub struct LayoutPlot {
    pub lens: String,
    pub surfaces: Vec<LayoutSurface>,
    pub elements: Vec<LayoutElement>,
    pub rays: Vec<LayoutRay>,
    /// z of the image plane and the half height drawn for it.
    pub image_z: f64,
    pub image_half_height: f64,
}

const PROFILE_SAMPLES: usize = 64;

impl LayoutSurface {
    /// Samples `shape` across its clear aperture; heights where the conic base is undefined are
    /// left out (validation rejects such apertures, so this only guards the drawing).
    pub fn sampled(
        number: usize,
        shape: &Shape,
        vertex_z: f64,
        semi_aperture: f64,
        stop: bool,
    ) -> LayoutSurface {
        let profile = (0..=PROFILE_SAMPLES)
            .filter_map(|i| {
                let y = semi_aperture * (2.0 * i as f64 / PROFILE_SAMPLES as f64 - 1.0);
                shape.sag(y.abs()).map(|sag| (vertex_z + sag, y))
            })
            .collect();
        LayoutSurface {
            number,
            profile,
            semi_aperture,
            stop,
        }
    }
}

impl LayoutPlot {
    /// Surfaces and glass of `system`, with no rays yet; the image plane at the paraxial
    /// focus of an object at infinity (at the prescription's last gap for an afocal lens).
    pub fn of_system(lens: &str, system: &SystemAt) -> LayoutPlot {
        let surfaces = system
            .surfaces
            .iter()
            .enumerate()
            .map(|(i, s)| {
                LayoutSurface::sampled(i + 1, &s.shape, s.vertex_z, s.semi_aperture, s.is_stop())
            })
            .collect();
        // A gap holds glass when its index differs from air's.
        let elements = system
            .surfaces
            .windows(2)
            .enumerate()
            .filter(|(_, pair)| (pair[0].index_after.abs() - 1.0).abs() > 1e-9)
            .map(|(i, _)| LayoutElement {
                front: i,
                back: i + 1,
            })
            .collect();
        // The paraxial image of a distant object; the prescription's last gap only where the
        // lens has no focus (pbrt files carry 0 there, which would put the film on the glass).
        let image_z = crate::paraxial::FirstOrder::of(system)
            .ok()
            .map(|first| first.z_rear_focal)
            .filter(|z| z.is_finite())
            .unwrap_or_else(|| {
                system
                    .surfaces
                    .last()
                    .map_or(0.0, |s| s.vertex_z + s.thickness)
            });
        let largest = system
            .surfaces
            .iter()
            .map(|s| s.semi_aperture)
            .fold(0.0, f64::max);
        LayoutPlot {
            lens: lens.to_string(),
            surfaces,
            elements,
            rays: Vec::new(),
            image_z,
            image_half_height: 0.5 * largest,
        }
    }

    fn extent(&self) -> ((f64, f64), f64) {
        let points = self
            .surfaces
            .iter()
            .flat_map(|s| &s.profile)
            .chain(self.rays.iter().flat_map(|r| &r.path))
            .copied()
            .chain([(self.image_z, self.image_half_height)]);
        let (mut z0, mut z1, mut h) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
        for (z, y) in points {
            z0 = z0.min(z);
            z1 = z1.max(z);
            h = h.max(y.abs());
        }
        if !z0.is_finite() {
            return ((-1.0, 1.0), 1.0);
        }
        let stop_mark = self
            .surfaces
            .iter()
            .filter(|s| s.stop)
            .map(|s| s.semi_aperture * STOP_MARK)
            .fold(0.0, f64::max);
        ((z0, z1), h.max(stop_mark).max(1e-3))
    }
}

/// How far beyond its clear aperture the stop's marks reach.
const STOP_MARK: f64 = 1.3;
const WIDTH: u32 = 1400;

impl View for LayoutPlot {
    fn size(&self) -> (u32, u32) {
        let ((z0, z1), h) = self.extent();
        // Keep mm per pixel equal in z and y: the plot area's aspect follows the lens's.
        let plot_width = (WIDTH - 130) as f64;
        let plot_height = (plot_width * 2.2 * h / ((z1 - z0) * 1.08)).clamp(240.0, 1100.0);
        (WIDTH, plot_height as u32 + 130)
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let ((z0, z1), h) = self.extent();
        let (width, height) = area.dim_in_pixel();
        let (plot_width, plot_height) = (width as f64 - 130.0, height as f64 - 130.0);
        let mm_per_pixel = ((z1 - z0) * 1.08 / plot_width).max(2.2 * h / plot_height);
        let z_mid = 0.5 * (z0 + z1);
        let z_range =
            (z_mid - 0.5 * plot_width * mm_per_pixel)..(z_mid + 0.5 * plot_width * mm_per_pixel);
        let y_half = 0.5 * plot_height * mm_per_pixel;
        let title = format!("{}: layout", self.lens);
        let mut chart = ChartBuilder::on(area)
            .caption(&title, (FONT_FAMILY, 26))
            .margin(15)
            .x_label_area_size(50)
            .y_label_area_size(50)
            .build_cartesian_2d(z_range, -y_half..y_half)
            .map_err(draw_error)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("z (mm)")
            .y_desc("y (mm)")
            .x_label_formatter(&|v| tick_label(*v))
            .y_label_formatter(&|v| tick_label(*v))
            .label_style((FONT_FAMILY, LABEL_SIZE))
            .axis_desc_style((FONT_FAMILY, LABEL_SIZE + 1))
            .draw()
            .map_err(draw_error)?;
        let mut panel = PanelDrawn {
            title,
            ..PanelDrawn::default()
        };
        for element in &self.elements {
            let (front, back) = (&self.surfaces[element.front], &self.surfaces[element.back]);
            chart
                .draw_series([Polygon::new(
                    element_outline(front, back),
                    RGBColor(200, 222, 245).filled(),
                )])
                .map_err(draw_error)?;
            // Flat annuli join the rims where the two apertures differ.
            let rim = front.semi_aperture.max(back.semi_aperture);
            for surface in [front, back] {
                for (z, y) in [surface.profile.first(), surface.profile.last()]
                    .into_iter()
                    .flatten()
                {
                    chart
                        .draw_series(LineSeries::new(
                            [(*z, *y), (*z, y.signum() * rim)],
                            BLACK.stroke_width(1),
                        ))
                        .map_err(draw_error)?;
                }
            }
            let (f_top, b_top) = (front.profile.last(), back.profile.last());
            let (f_bottom, b_bottom) = (front.profile.first(), back.profile.first());
            if let (Some(ft), Some(bt), Some(fb), Some(bb)) = (f_top, b_top, f_bottom, b_bottom) {
                for (from, to) in [((ft.0, rim), (bt.0, rim)), ((fb.0, -rim), (bb.0, -rim))] {
                    chart
                        .draw_series(LineSeries::new([from, to], BLACK.stroke_width(1)))
                        .map_err(draw_error)?;
                }
            }
        }
        chart
            .draw_series(LineSeries::new(
                [(chart.x_range().start, 0.0), (chart.x_range().end, 0.0)],
                BLACK.mix(0.4).stroke_width(1),
            ))
            .map_err(draw_error)?;
        let mut fields: Vec<f64> = Vec::new();
        for ray in &self.rays {
            let index = match fields.iter().position(|f| *f == ray.field_deg) {
                Some(i) => i,
                None => {
                    fields.push(ray.field_deg);
                    fields.len() - 1
                }
            };
            let color = PALETTE[index % PALETTE.len()];
            let style = if ray.vignetted {
                color.mix(0.35).stroke_width(1)
            } else {
                color.stroke_width(1)
            };
            chart
                .draw_series(LineSeries::new(ray.path.iter().copied(), style))
                .map_err(draw_error)?;
            panel.series.push(SeriesDrawn {
                label: format!("ray at {:.2}°", ray.field_deg),
                points: ray.path.clone(),
            });
        }
        for (i, field) in fields.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            chart
                .draw_series(std::iter::empty::<PathElement<(f64, f64)>>())
                .map_err(draw_error)?
                .label(format!("field {field:.2}°"))
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 22, y)], color.stroke_width(2))
                });
        }
        if self.rays.iter().any(|r| r.vignetted) {
            let faint = BLACK.mix(0.35);
            let note = "faint: vignetted rays, to the last surface they cross";
            chart
                .draw_series(std::iter::empty::<PathElement<(f64, f64)>>())
                .map_err(draw_error)?
                .label(note)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 22, y)], faint.stroke_width(1))
                });
            panel.messages.push(note.to_string());
        }
        for surface in &self.surfaces {
            let style = if surface.stop {
                BLACK.stroke_width(3)
            } else {
                BLACK.stroke_width(2)
            };
            chart
                .draw_series(LineSeries::new(surface.profile.iter().copied(), style))
                .map_err(draw_error)?;
            panel.series.push(SeriesDrawn {
                label: format!("surface {}", surface.number),
                points: surface.profile.clone(),
            });
            if surface.stop {
                for (z, y) in [surface.profile.first(), surface.profile.last()]
                    .into_iter()
                    .flatten()
                {
                    chart
                        .draw_series(LineSeries::new(
                            [
                                (*z, *y),
                                (*z, y.signum() * surface.semi_aperture * STOP_MARK),
                            ],
                            BLACK.stroke_width(4),
                        ))
                        .map_err(draw_error)?;
                }
                let label_at = (
                    surface.profile.last().map_or(0.0, |p| p.0),
                    surface.semi_aperture * STOP_MARK,
                );
                chart
                    .draw_series([Text::new(
                        "stop",
                        label_at,
                        (FONT_FAMILY, LABEL_SIZE).into_font().color(&BLACK),
                    )])
                    .map_err(draw_error)?;
            }
        }
        chart
            .draw_series(LineSeries::new(
                [
                    (self.image_z, -self.image_half_height),
                    (self.image_z, self.image_half_height),
                ],
                RGBColor(120, 0, 0).stroke_width(2),
            ))
            .map_err(draw_error)?;
        chart
            .draw_series([Text::new(
                "image",
                (self.image_z, self.image_half_height),
                (FONT_FAMILY, LABEL_SIZE)
                    .into_font()
                    .color(&RGBColor(120, 0, 0)),
            )])
            .map_err(draw_error)?;
        if !fields.is_empty() {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerLeft)
                .label_font((FONT_FAMILY, LABEL_SIZE))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK.mix(0.5))
                .draw()
                .map_err(draw_error)?;
        }
        Ok(Drawn {
            panels: vec![panel],
        })
    }
}

/// The outline of the glass between two surfaces, stepping out to the larger rim.
fn element_outline(front: &LayoutSurface, back: &LayoutSurface) -> Vec<(f64, f64)> {
    let rim = front.semi_aperture.max(back.semi_aperture);
    let mut outline = Vec::with_capacity(front.profile.len() + back.profile.len() + 4);
    if let Some(&(z, _)) = front.profile.first() {
        outline.push((z, -rim));
    }
    outline.extend(front.profile.iter().copied());
    if let Some(&(z, _)) = front.profile.last() {
        outline.push((z, rim));
    }
    if let Some(&(z, _)) = back.profile.last() {
        outline.push((z, rim));
    }
    outline.extend(back.profile.iter().rev().copied());
    if let Some(&(z, _)) = back.profile.first() {
        outline.push((z, -rim));
    }
    outline
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lenses;
    use crate::prescription::formats::LoadOptions;

    #[test]
    fn the_image_plane_is_the_paraxial_focus_not_the_last_vertex() {
        // The pbrt double Gauss ends with a zero gap.
        let system = lenses::load("dgauss-50mm", &LoadOptions::default())
            .unwrap()
            .system
            .at(587.5618);
        let plot = LayoutPlot::of_system("dgauss-50mm", &system);
        let focus = crate::paraxial::FirstOrder::of(&system)
            .unwrap()
            .z_rear_focal;
        assert_eq!(plot.image_z, focus);
        assert!(plot.image_z > system.last_vertex_z() + 10.0);
    }
}
