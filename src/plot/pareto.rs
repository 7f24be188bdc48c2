//! Cost against error of lens models on log axes, each point labelled, with the Pareto front
//! (the models no other model beats on both) joined by a line.

use super::chart::{PanelDrawn, SeriesDrawn, tick_label};
use super::font::FONT_FAMILY;
use super::{Drawn, PlotError, View, draw_error};
use plotters::coord::Shift;
use plotters::prelude::*;

/// One model's point: `cost` and `error` must be positive to appear on log axes.
#[derive(Clone, Debug, PartialEq)]
pub struct ParetoPoint {
    pub label: String,
    /// Legend group (e.g. "baked f16").
    pub group: String,
    pub cost: f64,
    pub error: f64,
}

#[derive(Clone, Debug, PartialEq)]
pub struct ParetoPlot {
    pub title: String,
    pub cost_label: String,
    pub error_label: String,
    pub points: Vec<ParetoPoint>,
    /// Written under the plot (e.g. which models could not be placed on log axes).
    pub notes: Vec<String>,
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(214, 39, 40),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(31, 119, 180),
    RGBColor(148, 103, 189),
    RGBColor(90, 90, 90),
];

/// Indices of the points no other point beats on both cost and error, by increasing cost.
pub fn pareto_front(points: &[ParetoPoint]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| {
        points[a]
            .cost
            .total_cmp(&points[b].cost)
            .then(points[a].error.total_cmp(&points[b].error))
    });
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for k in order {
        if points[k].error < best {
            best = points[k].error;
            front.push(k);
        }
    }
    front
}

fn log_range(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (mut low, mut high) = (f64::INFINITY, 0.0f64);
    for v in values {
        low = low.min(v);
        high = high.max(v);
    }
    if !(low.is_finite() && high > 0.0) {
        return 0.1..10.0;
    }
    (low / 2.0)..(high * 2.0)
}

/// A log axis's tick label: only the 1, 2 and 5 of each decade are written, so the nine ticks
/// a decade gets never run into each other ("700.0800.0900.0").
fn log_tick_label(value: f64) -> String {
    if !(value.is_finite() && value > 0.0) {
        return String::new();
    }
    let mantissa = value / 10f64.powf(value.log10().floor());
    if [1.0, 2.0, 5.0, 10.0]
        .iter()
        .any(|m| (mantissa - m).abs() < 1e-6 * m)
    {
        tick_label(value)
    } else {
        String::new()
    }
}

/// A label's box in pixels: left, top, width, height.
type LabelBox = (i32, i32, i32, i32);

fn overlap(a: LabelBox, b: LabelBox) -> i64 {
    let w = (a.0 + a.2).min(b.0 + b.2) - a.0.max(b.0);
    let h = (a.1 + a.3).min(b.1 + b.3) - a.1.max(b.1);
    if w > 0 && h > 0 {
        w as i64 * h as i64
    } else {
        0
    }
}

/// Places each label (`size` in pixels) beside its point (`anchors`, pixels) in the first of
/// eight positions around it that overlaps no label placed before, no point marker and stays
/// inside `bounds` (left, top, width, height); where none is free, the least overlapping one.
/// Returns each label's top-left corner.
fn place_labels(anchors: &[(i32, i32)], sizes: &[(i32, i32)], bounds: LabelBox) -> Vec<(i32, i32)> {
    const GAP: i32 = 7;
    let markers: Vec<LabelBox> = anchors
        .iter()
        .map(|&(x, y)| {
            (
                x - MARKER_RADIUS,
                y - MARKER_RADIUS,
                2 * MARKER_RADIUS,
                2 * MARKER_RADIUS,
            )
        })
        .collect();
    let mut placed: Vec<LabelBox> = Vec::new();
    anchors
        .iter()
        .zip(sizes)
        .map(|(&(x, y), &(w, h))| {
            // Eight places around the point, then the same moved one, two, three label
            // heights further out, for crowded corners.
            let near = [
                (x + GAP, y - h - 2, -1),
                (x + GAP, y + 2, 1),
                (x - GAP - w, y - h - 2, -1),
                (x - GAP - w, y + 2, 1),
                (x - w / 2, y - h - GAP, -1),
                (x - w / 2, y + GAP, 1),
                (x + GAP, y - h / 2, 0),
                (x - GAP - w, y - h / 2, 0),
            ];
            let candidates: Vec<(i32, i32)> = (0..4)
                .flat_map(|ring| {
                    near.iter()
                        .filter(move |c| ring == 0 || c.2 != 0)
                        .map(move |&(left, top, away)| (left, top + away * ring * (h + 2)))
                })
                .collect();
            let cost = |&(left, top): &(i32, i32)| -> i64 {
                let own = (left, top, w, h);
                let outside = {
                    let inside = overlap(own, bounds);
                    (w as i64 * h as i64 - inside) * 4
                };
                placed
                    .iter()
                    .chain(&markers)
                    .map(|&b| overlap(own, b))
                    .sum::<i64>()
                    + outside
            };
            let best = candidates
                .iter()
                .copied()
                .enumerate()
                .min_by_key(|(i, c)| (cost(c), *i as i64))
                .map(|(_, c)| c)
                .unwrap_or((x, y));
            placed.push((best.0, best.1, w, h));
            best
        })
        .collect()
}

const MARKER_RADIUS: i32 = 5;
const LABEL_FONT_SIZE: u32 = 13;

/// The label of point `k`, joined with those of the points drawn at the same place; None for a
/// point whose place an earlier point already labels.
fn joined_label(points: &[ParetoPoint], k: usize) -> Option<String> {
    // Equal to plotting precision (thin and thick differ in the last bits at infinity focus).
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs());
    let same = |a: &ParetoPoint, b: &ParetoPoint| close(a.cost, b.cost) && close(a.error, b.error);
    if points[..k].iter().any(|p| same(p, &points[k])) {
        return None;
    }
    let labels: Vec<&str> = points
        .iter()
        .filter(|p| same(p, &points[k]))
        .map(|p| p.label.as_str())
        .collect();
    Some(labels.join(" = "))
}

impl View for ParetoPlot {
    fn size(&self) -> (u32, u32) {
        (1000, 700)
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<Drawn, PlotError> {
        area.fill(&WHITE).map_err(draw_error)?;
        let placed: Vec<ParetoPoint> = self
            .points
            .iter()
            .filter(|p| p.cost > 0.0 && p.error > 0.0 && p.cost.is_finite() && p.error.is_finite())
            .cloned()
            .collect();
        let (plot_area, notes_area) = area.split_vertically(700 - 22 * self.notes.len() as u32);
        // Room on the right for the last point's label.
        let x_range = log_range(placed.iter().map(|p| p.cost));
        let x_range = x_range.start..x_range.end * 4.0;
        let y_range = log_range(placed.iter().map(|p| p.error));
        let mut chart = ChartBuilder::on(&plot_area)
            .caption(&self.title, (FONT_FAMILY, 22))
            .margin(14)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(x_range.log_scale(), y_range.log_scale())
            .map_err(draw_error)?;
        chart
            .configure_mesh()
            .x_desc(&self.cost_label)
            .y_desc(&self.error_label)
            .label_style((FONT_FAMILY, 15))
            .axis_desc_style((FONT_FAMILY, 17))
            .x_label_formatter(&|v| log_tick_label(*v))
            .y_label_formatter(&|v| log_tick_label(*v))
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(205, 205, 205))
            .draw()
            .map_err(draw_error)?;
        let mut panel = PanelDrawn {
            title: self.title.clone(),
            ..PanelDrawn::default()
        };
        let front: Vec<(f64, f64)> = pareto_front(&placed)
            .into_iter()
            .map(|k| (placed[k].cost, placed[k].error))
            .collect();
        if front.len() > 1 {
            let grey = RGBColor(120, 120, 120);
            chart
                .draw_series(DashedLineSeries::new(
                    front.iter().copied(),
                    8,
                    5,
                    grey.stroke_width(1),
                ))
                .map_err(draw_error)?
                .label("Pareto front")
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], grey));
        }
        panel.series.push(SeriesDrawn {
            label: "Pareto front".into(),
            points: front,
        });
        let mut groups: Vec<&str> = Vec::new();
        for p in &placed {
            if !groups.contains(&p.group.as_str()) {
                groups.push(&p.group);
            }
        }
        for (g, group) in groups.iter().enumerate() {
            let color = PALETTE[g % PALETTE.len()];
            let members: Vec<&ParetoPoint> = placed.iter().filter(|p| p.group == *group).collect();
            chart
                .draw_series(
                    members
                        .iter()
                        .map(|p| Circle::new((p.cost, p.error), MARKER_RADIUS, color.filled())),
                )
                .map_err(draw_error)?
                .label(*group)
                .legend(move |(x, y)| Circle::new((x + 10, y), 5, color.filled()));
            panel.series.push(SeriesDrawn {
                label: group.to_string(),
                points: members.iter().map(|p| (p.cost, p.error)).collect(),
            });
        }
        let font = (FONT_FAMILY, LABEL_FONT_SIZE).into_font().color(&BLACK);
        let labels: Vec<(usize, String)> = (0..placed.len())
            .filter_map(|k| joined_label(&placed, k).map(|label| (k, label)))
            .collect();
        let anchors: Vec<(i32, i32)> = labels
            .iter()
            .map(|(k, _)| chart.backend_coord(&(placed[*k].cost, placed[*k].error)))
            .collect();
        let sizes = labels
            .iter()
            .map(|(_, label)| {
                plot_area
                    .estimate_text_size(label, &font)
                    .map(|(w, h)| (w as i32, h as i32))
                    .map_err(draw_error)
            })
            .collect::<Result<Vec<_>, _>>()?;
        let (x_pixels, y_pixels) = chart.plotting_area().get_pixel_range();
        let bounds = (
            x_pixels.start,
            y_pixels.start,
            x_pixels.end - x_pixels.start,
            y_pixels.end - y_pixels.start,
        );
        for ((_, label), corner) in labels.iter().zip(place_labels(&anchors, &sizes, bounds)) {
            plot_area
                .draw(&Text::new(label.clone(), corner, font.clone()))
                .map_err(draw_error)?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.4))
            .label_font((FONT_FAMILY, 15))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(draw_error)?;
        for (k, note) in self.notes.iter().enumerate() {
            notes_area
                .draw(&Text::new(
                    note.clone(),
                    (16, 2 + 22 * k as i32),
                    (FONT_FAMILY, 14).into_font().color(&BLACK),
                ))
                .map_err(draw_error)?;
            panel.messages.push(note.clone());
        }
        Ok(Drawn {
            panels: vec![panel],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(cost: f64, error: f64) -> ParetoPoint {
        ParetoPoint {
            label: format!("{cost}"),
            group: "g".into(),
            cost,
            error,
        }
    }

    #[test]
    fn the_front_keeps_only_undominated_points() {
        let points = [
            point(1.0, 10.0),
            point(2.0, 12.0),
            point(3.0, 1.0),
            point(4.0, 1.0),
        ];
        assert_eq!(pareto_front(&points), vec![0, 2]);
    }

    #[test]
    fn log_ticks_keep_one_two_and_five_of_each_decade() {
        let written: Vec<String> = [
            100.0, 200.0, 300.0, 500.0, 700.0, 800.0, 900.0, 1000.0, 0.02,
        ]
        .map(log_tick_label)
        .to_vec();
        assert_eq!(
            written,
            ["100", "200", "", "500", "", "", "", "1000", "0.02"]
        );
    }

    #[test]
    fn labels_of_crowded_points_do_not_overlap() {
        // The trade-off's crowded corner: five points within a few pixels of each other.
        let anchors = [(300, 300), (304, 302), (310, 298), (300, 310), (296, 305)];
        let sizes = [(110, 16); 5];
        let corners = place_labels(&anchors, &sizes, (0, 0, 1000, 700));
        let boxes: Vec<LabelBox> = corners
            .iter()
            .zip(&sizes)
            .map(|(&(x, y), &(w, h))| (x, y, w, h))
            .collect();
        for i in 0..boxes.len() {
            for j in 0..i {
                assert_eq!(overlap(boxes[i], boxes[j]), 0, "labels {i} and {j} overlap");
            }
        }
        // An isolated point keeps the first position: up and to the right.
        assert_eq!(
            place_labels(&[(500, 400)], &[(60, 16)], (0, 0, 1000, 700)),
            [(507, 382)]
        );
    }

    #[test]
    fn coincident_points_share_one_label() {
        let mut points = vec![point(1.0, 2.0), point(1.0, 2.0), point(3.0, 1.0)];
        points[1].label = "twin".into();
        assert_eq!(joined_label(&points, 0).as_deref(), Some("1 = twin"));
        assert_eq!(joined_label(&points, 1), None);
        assert_eq!(joined_label(&points, 2).as_deref(), Some("3"));
    }

    #[test]
    fn points_off_the_log_axes_are_left_out_and_the_rest_drawn() {
        let plot = ParetoPlot {
            title: "t".into(),
            cost_label: "bytes".into(),
            error_label: "px".into(),
            points: vec![point(10.0, 1.0), point(100.0, 0.0), point(1000.0, 0.1)],
            notes: vec!["traced: the reference (zero error)".into()],
        };
        let drawn = crate::plot::render(&plot, crate::plot::Format::Svg)
            .unwrap()
            .drawn;
        assert_eq!(
            drawn.series("t", "g").unwrap().points,
            vec![(10.0, 1.0), (1000.0, 0.1)]
        );
        assert_eq!(drawn.messages().count(), 1);
    }
}
