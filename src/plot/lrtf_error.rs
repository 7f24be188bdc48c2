//! LRTF table error against table size: one panel per lens, one series per parameterisation and
//! precision, the 99th-percentile image error on a log scale with the 0.5 px target.

use super::chart::{Panel, Series, draw_panel, titled_grid};
use super::color::PALETTE;
use super::{Drawn, PlotError, View};
use crate::lrtf::measure::{IMAGE_ERROR_TARGET_PX, SweepRow};
use plotters::coord::Shift;
use plotters::prelude::{BLACK, DrawingArea, DrawingBackend};

/// One table configuration's error at several resolutions: (nodes per axis, p99 image error in
/// pixels of a 1920-pixel-wide frame).
#[derive(Clone, Debug, PartialEq)]
pub struct LrtfErrorCurve {
    /// For example "pupil-planes f32".
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct LrtfErrorLens {
    pub lens: String,
    pub curves: Vec<LrtfErrorCurve>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct LrtfErrorPlot {
    pub lenses: Vec<LrtfErrorLens>,
    /// The image-error target drawn as a dashed line (px).
    pub target_px: f64,
}

impl LrtfErrorPlot {
    /// The `lrtf-error` plot of sweep rows: a panel per lens (in first-seen order), a curve per
    /// parameterisation and precision, points (resolution, p99 image error) sorted by resolution.
    pub fn from_sweep(rows: &[SweepRow]) -> LrtfErrorPlot {
        let mut lenses: Vec<LrtfErrorLens> = Vec::new();
        for row in rows {
            let lens = match lenses.iter().position(|l| l.lens == row.lens) {
                Some(k) => &mut lenses[k],
                None => {
                    lenses.push(LrtfErrorLens {
                        lens: row.lens.clone(),
                        curves: Vec::new(),
                    });
                    lenses.last_mut().expect("just pushed")
                }
            };
            let label = format!("{} {}", row.parameterisation, row.precision);
            let curve = match lens.curves.iter().position(|c| c.label == label) {
                Some(k) => &mut lens.curves[k],
                None => {
                    lens.curves.push(LrtfErrorCurve {
                        label,
                        points: Vec::new(),
                    });
                    lens.curves.last_mut().expect("just pushed")
                }
            };
            curve
                .points
                .push((row.resolution as f64, row.error.image_px.p99));
        }
        for curve in lenses.iter_mut().flat_map(|l| &mut l.curves) {
            curve.points.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        LrtfErrorPlot {
            lenses,
            target_px: IMAGE_ERROR_TARGET_PX,
        }
    }
}

/// Label of the target line's series.
pub const TARGET_LABEL: &str = "target";

const PANEL: (u32, u32) = (760, 620);

impl View for LrtfErrorPlot {
    fn size(&self) -> (u32, u32) {
        (PANEL.0 * self.lenses.len().max(1) as u32, PANEL.1 + 60)
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        let title = "LRTF table against the exact trace: p99 image error at 1920 px";
        let cells = titled_grid(area, title, 1, self.lenses.len())?;
        let mut drawn = Drawn::default();
        for (lens, cell) in self.lenses.iter().zip(&cells) {
            // Errors span four decades, so they are drawn as log10; a point <= 0 has no log and
            // is left out rather than faked.
            let mut series: Vec<Series> = lens
                .curves
                .iter()
                .enumerate()
                .map(|(k, curve)| Series {
                    label: curve.label.clone(),
                    color: PALETTE[k % PALETTE.len()],
                    dashed: curve.label.contains("f16"),
                    markers: true,
                    points: curve
                        .points
                        .iter()
                        .filter(|p| p.1 > 0.0)
                        .map(|&(n, px)| (n, px.log10()))
                        .collect(),
                })
                .collect();
            let max_n = lens
                .curves
                .iter()
                .flat_map(|c| c.points.iter().map(|p| p.0))
                .fold(0.0, f64::max);
            if max_n > 0.0 {
                series.push(Series {
                    label: TARGET_LABEL.into(),
                    color: BLACK,
                    dashed: true,
                    markers: false,
                    points: vec![
                        (0.0, self.target_px.log10()),
                        (max_n, self.target_px.log10()),
                    ],
                });
            }
            let panel = Panel {
                title: format!("{}: p99 image error", lens.lens),
                x_label: "nodes per table axis N (N^3 entries)",
                y_label: "log10 p99 image error (px at 1920 px)",
                series,
                empty_message: format!("No measurements for {}", lens.lens),
                x_range: Some(0.0..max_n.max(1.0) * 1.05),
                y_range: None,
                title_size: 22,
            };
            drawn.panels.push(draw_panel(cell, panel)?);
        }
        Ok(drawn)
    }
}
