//! Wave-optics views: wavefront map, PSF, MTF, through-focus MTF and MTF across the field.

use super::chart::{LABEL_SIZE, Panel, Series, draw_notice, draw_panel, tick_label};
use super::color::PALETTE;
use super::font::FONT_FAMILY;
use super::{Drawn, PanelDrawn, PlotError, SeriesDrawn, View, draw_error};
use plotters::coord::Shift;
use plotters::prelude::*;

const CURVE_SIZE: (u32, u32) = (1000, 720);
const MAP_SIZE: (u32, u32) = (900, 760);
const TITLE_SIZE: u32 = 24;

/// A square grid of values over (x, y), row-major with rows along y, None where empty.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    pub size: usize,
    /// Centre of cell (0, 0) and the pitch, in the plotted units.
    pub origin: (f64, f64),
    pub pitch: (f64, f64),
    pub values: Vec<Option<f64>>,
}

/// OPD over the pupil at one field and wavelength, waves, on a diverging colour scale.
#[derive(Clone, Debug, PartialEq)]
pub struct WavefrontMapPlot {
    pub lens: String,
    pub field_deg: f64,
    pub wavelength_nm: f64,
    pub rms_waves: f64,
    pub pv_waves: f64,
    /// Over the relative pupil coordinates -1..1.
    pub opd: Grid,
}

/// A PSF around the reference point, µm, shown as log10 of intensity over the
/// aberration-free peak.
#[derive(Clone, Debug, PartialEq)]
pub struct PsfPlot {
    pub lens: String,
    pub field_deg: f64,
    pub wavelength_nm: f64,
    pub strehl: f64,
    pub intensity: Grid,
}

/// MTF curves of one field: frequency in cycles/mm against modulation.
#[derive(Clone, Debug, PartialEq)]
pub struct MtfField {
    pub field_deg: f64,
    pub frequencies_per_mm: Vec<f64>,
    pub tangential: Vec<f64>,
    pub sagittal: Vec<f64>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct MtfPlot {
    pub lens: String,
    /// What the curves are of ("587.6 nm", "F, d, C weighted 1:2:1").
    pub spectrum: String,
    pub fields: Vec<MtfField>,
    /// (cycles/mm, modulation) of the aberration-free pupil.
    pub diffraction_limit: Vec<(f64, f64)>,
}

/// Modulation curves against one variable: (variable, tangential, sagittal) samples.
pub type ModulationCurve = Vec<(f64, f64, f64)>;

/// Modulation at one frequency against the image-plane shift, per field.
#[derive(Clone, Debug, PartialEq)]
pub struct ThroughFocusPlot {
    pub lens: String,
    pub spectrum: String,
    pub frequency_per_mm: f64,
    /// (field, [(defocus mm, tangential, sagittal)]).
    pub fields: Vec<(f64, ModulationCurve)>,
}

/// Modulation against field angle, per frequency.
#[derive(Clone, Debug, PartialEq)]
pub struct MtfFieldPlot {
    pub lens: String,
    pub spectrum: String,
    /// (frequency, [(field deg, tangential, sagittal)]).
    pub frequencies: Vec<(f64, ModulationCurve)>,
}

/// One panel of modulation (0..1) curves.
fn modulation_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: String,
    x_label: &str,
    series: Vec<Series>,
    x_range: Option<std::ops::Range<f64>>,
) -> Result<Drawn, PlotError> {
    let panel = Panel {
        title,
        x_label,
        y_label: "modulation",
        series,
        empty_message: "No field reaches the image".into(),
        x_range,
        y_range: Some(0.0..1.02),
        title_size: TITLE_SIZE,
    };
    Ok(Drawn {
        panels: vec![draw_panel(area, panel)?],
    })
}

/// Tangential solid, sagittal dashed, one colour per curve set.
fn t_and_s(
    label: &str,
    colour_index: usize,
    points: impl Iterator<Item = (f64, f64, f64)> + Clone,
) -> [Series; 2] {
    let color = PALETTE[colour_index % PALETTE.len()];
    [
        Series {
            label: format!("T {label}"),
            color,
            dashed: false,
            markers: false,
            points: points.clone().map(|p| (p.0, p.1)).collect(),
        },
        Series {
            label: format!("S {label}"),
            color,
            dashed: true,
            markers: false,
            points: points.map(|p| (p.0, p.2)).collect(),
        },
    ]
}

impl View for MtfPlot {
    fn size(&self) -> (u32, u32) {
        CURVE_SIZE
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let mut series: Vec<Series> = self
            .fields
            .iter()
            .enumerate()
            .flat_map(|(i, f)| {
                let points = f
                    .frequencies_per_mm
                    .iter()
                    .zip(f.tangential.iter().zip(&f.sagittal))
                    .map(|(&x, (&t, &s))| (x, t, s));
                t_and_s(&format!("{:.2}°", f.field_deg), i, points)
            })
            .collect();
        series.push(Series {
            label: "diffraction limit".into(),
            color: BLACK,
            dashed: false,
            markers: false,
            points: self.diffraction_limit.clone(),
        });
        let max_frequency = self
            .diffraction_limit
            .iter()
            .map(|p| p.0)
            .chain(
                self.fields
                    .iter()
                    .flat_map(|f| f.frequencies_per_mm.iter().copied()),
            )
            .fold(0.0, f64::max);
        modulation_panel(
            area,
            format!("{}: diffraction MTF, {}", self.lens, self.spectrum),
            "spatial frequency (cycles/mm)",
            series,
            Some(0.0..max_frequency.max(1.0)),
        )
    }
}

impl View for ThroughFocusPlot {
    fn size(&self) -> (u32, u32) {
        CURVE_SIZE
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let series = self
            .fields
            .iter()
            .enumerate()
            .flat_map(|(i, (field, points))| {
                t_and_s(&format!("{field:.2}°"), i, points.iter().copied())
            })
            .collect();
        modulation_panel(
            area,
            format!(
                "{}: through-focus MTF at {} cycles/mm, {}",
                self.lens,
                tick_label(self.frequency_per_mm),
                self.spectrum
            ),
            "image plane shift from paraxial focus (mm)",
            series,
            None,
        )
    }
}

impl View for MtfFieldPlot {
    fn size(&self) -> (u32, u32) {
        CURVE_SIZE
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let series = self
            .frequencies
            .iter()
            .enumerate()
            .flat_map(|(i, (frequency, points))| {
                t_and_s(
                    &format!("{} cycles/mm", tick_label(*frequency)),
                    i,
                    points.iter().copied(),
                )
            })
            .collect();
        modulation_panel(
            area,
            format!("{}: MTF across the field, {}", self.lens, self.spectrum),
            "field angle (deg)",
            series,
            None,
        )
    }
}

impl View for WavefrontMapPlot {
    fn size(&self) -> (u32, u32) {
        MAP_SIZE
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let half = self
            .opd
            .values
            .iter()
            .flatten()
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .max(1e-6);
        let heat = Heatmap {
            title: format!(
                "{}: wavefront at {:.2}°, {:.1} nm (RMS {:.3}, P-V {:.3} waves)",
                self.lens, self.field_deg, self.wavelength_nm, self.rms_waves, self.pv_waves
            ),
            x_label: "relative pupil px",
            y_label: "relative pupil py",
            bar_label: "OPD (waves)",
            range: (-half, half),
            colours: &DIVERGING,
            grid: &self.opd,
            transform: &|v| v,
            empty_message: "All rays vignetted",
        };
        heat.draw(area)
    }
}

impl View for PsfPlot {
    fn size(&self) -> (u32, u32) {
        MAP_SIZE
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let heat = Heatmap {
            title: format!(
                "{}: PSF at {:.2}°, {:.1} nm (Strehl {:.3})",
                self.lens, self.field_deg, self.wavelength_nm, self.strehl
            ),
            x_label: "x from chief ray (µm)",
            y_label: "y from chief ray (µm)",
            bar_label: "log10 intensity / ideal peak",
            range: (PSF_FLOOR_LOG10, 0.0),
            colours: &SEQUENTIAL,
            grid: &self.intensity,
            transform: &|v| v.max(10f64.powf(PSF_FLOOR_LOG10)).log10(),
            empty_message: "No light reaches the image",
        };
        heat.draw(area)
    }
}

/// Lowest decade shown on the PSF's log scale.
const PSF_FLOOR_LOG10: f64 = -4.0;

/// Blue, white, red: zero OPD is white.
const DIVERGING: [(f64, (u8, u8, u8)); 5] = [
    (0.0, (33, 102, 172)),
    (0.25, (146, 197, 222)),
    (0.5, (247, 247, 247)),
    (0.75, (244, 165, 130)),
    (1.0, (178, 24, 43)),
];

/// Dark blue through green to yellow (viridis's anchors), monotonic in lightness.
pub(crate) const SEQUENTIAL: [(f64, (u8, u8, u8)); 5] = [
    (0.0, (68, 1, 84)),
    (0.25, (59, 82, 139)),
    (0.5, (33, 145, 140)),
    (0.75, (94, 201, 98)),
    (1.0, (253, 231, 37)),
];

pub(crate) fn colour_at(colours: &[(f64, (u8, u8, u8))], t: f64) -> RGBColor {
    let t = t.clamp(0.0, 1.0);
    let upper = colours
        .iter()
        .position(|c| c.0 >= t)
        .unwrap_or(colours.len() - 1)
        .max(1);
    let (a, b) = (colours[upper - 1], colours[upper]);
    let s = (t - a.0) / (b.0 - a.0);
    let mix = |x: u8, y: u8| (x as f64 + (y as f64 - x as f64) * s).round() as u8;
    RGBColor(mix(a.1.0, b.1.0), mix(a.1.1, b.1.1), mix(a.1.2, b.1.2))
}

/// A grid drawn as coloured cells with a colour bar.
struct Heatmap<'a> {
    title: String,
    x_label: &'a str,
    y_label: &'a str,
    bar_label: &'a str,
    range: (f64, f64),
    colours: &'a [(f64, (u8, u8, u8))],
    grid: &'a Grid,
    transform: &'a dyn Fn(f64) -> f64,
    empty_message: &'a str,
}

impl Heatmap<'_> {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let (width, _) = area.dim_in_pixel();
        let (plot_area, bar_area) = area.split_horizontally(width as i32 - 150);
        let g = self.grid;
        let half_cell = (0.5 * g.pitch.0, 0.5 * g.pitch.1);
        let x_range = (g.origin.0 - half_cell.0)..(g.origin.0 + (g.size as f64 - 0.5) * g.pitch.0);
        let y_range = (g.origin.1 - half_cell.1)..(g.origin.1 + (g.size as f64 - 0.5) * g.pitch.1);
        let mut chart = ChartBuilder::on(&plot_area)
            .caption(&self.title, (FONT_FAMILY, 20))
            .margin(12)
            .x_label_area_size(48)
            .y_label_area_size(70)
            .build_cartesian_2d(x_range, y_range)
            .map_err(draw_error)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc(self.x_label)
            .y_desc(self.y_label)
            .label_style((FONT_FAMILY, LABEL_SIZE))
            .axis_desc_style((FONT_FAMILY, LABEL_SIZE + 1))
            .x_label_formatter(&|v| tick_label(*v))
            .y_label_formatter(&|v| tick_label(*v))
            .draw()
            .map_err(draw_error)?;
        let span = (self.range.1 - self.range.0).max(f64::MIN_POSITIVE);
        let mut cells = 0usize;
        let mut shown = (f64::INFINITY, f64::NEG_INFINITY);
        for (i, value) in g.values.iter().enumerate() {
            let Some(value) = value else { continue };
            let v = (self.transform)(*value);
            shown = (shown.0.min(*value), shown.1.max(*value));
            let (x, y) = (
                g.origin.0 + (i % g.size) as f64 * g.pitch.0,
                g.origin.1 + (i / g.size) as f64 * g.pitch.1,
            );
            let colour = colour_at(self.colours, (v - self.range.0) / span);
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [
                        (x - half_cell.0, y - half_cell.1),
                        (x + half_cell.0, y + half_cell.1),
                    ],
                    colour.filled(),
                )))
                .map_err(draw_error)?;
            cells += 1;
        }
        let mut panel = PanelDrawn {
            title: self.title.clone(),
            ..PanelDrawn::default()
        };
        if cells == 0 {
            draw_notice(area, self.empty_message)?;
            panel.messages.push(self.empty_message.to_string());
        } else {
            panel.series.push(SeriesDrawn {
                label: format!("{cells} cells, values {} to {}", shown.0, shown.1),
                points: vec![shown],
            });
        }
        self.draw_bar(&bar_area)?;
        Ok(Drawn {
            panels: vec![panel],
        })
    }

    fn draw_bar<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        draw_colour_bar(area, self.range, self.colours, self.bar_label)
    }
}

/// A vertical colour bar for `range` on `colours`, its axis labelled `label` (with units).
pub(crate) fn draw_colour_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    range: (f64, f64),
    colours: &[(f64, (u8, u8, u8))],
    label: &str,
) -> Result<(), PlotError> {
    let mut bar = ChartBuilder::on(area)
        .margin_top(60)
        .margin_bottom(60)
        .margin_right(10)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..1.0, range.0..range.1)
        .map_err(draw_error)?;
    bar.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(label)
        .label_style((FONT_FAMILY, LABEL_SIZE))
        .axis_desc_style((FONT_FAMILY, LABEL_SIZE))
        .y_label_formatter(&|v| tick_label(*v))
        .draw()
        .map_err(draw_error)?;
    const STEPS: usize = 100;
    let span = range.1 - range.0;
    bar.draw_series((0..STEPS).map(|k| {
        let (a, b) = (k as f64 / STEPS as f64, (k + 1) as f64 / STEPS as f64);
        Rectangle::new(
            [(0.0, range.0 + a * span), (1.0, range.0 + b * span)],
            colour_at(colours, 0.5 * (a + b)).filled(),
        )
    }))
    .map_err(draw_error)?;
    Ok(())
}
