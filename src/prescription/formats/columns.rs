//! Four-column lens tables: pbrt `.dat` files and the plain tables printed in papers.
//!
//! Each data row is `radius thickness index aperture-diameter`, separated by spaces or tabs
//! (plain tables also accept commas). `#` starts a comment. The index is that of the medium after
//! the surface; 1 means air. The aperture column is a DIAMETER; the semi-aperture is half of it.
//!
//! | | pbrt | plain table |
//! |---|---|---|
//! | stop row | radius `0` (also `N/A`, as in the Kolb table) | radius `N/A`, `stop` or `STO` |
//! | radius `0`, `inf` | stop / plane | plane |
//! | index `0` | on the stop row: the medium of the gap the stop sits in | same |
//! | thickness | to the next vertex, or from the previous one if asked | to the next vertex |
//! | header row | no | one row of four non-numeric words is skipped |
//! | focal-length row | one number alone before the first surface | same |
//!
//! The focal-length row is how lens-simulation toolkits (ISET's pbrt-v3 lens files,
//! `# focal length (mm)` then `50.000`) head their tables: it becomes the lens's claimed focal
//! length, compared with the computed EFL and never used for it.
//! The stop is always a plane; its shape is a circle.

use super::{Format, LoadNote, Loaded, PbrtThickness, Source, finite, number};
use crate::prescription::error::{Location, PrescriptionError, Problem};
use crate::prescription::model::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
use crate::prescription::validate::SourceMap;

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Dialect {
    Pbrt(PbrtThickness),
    Table,
}

const COLUMNS: [&str; 4] = ["radius", "thickness", "index", "aperture"];

struct Row {
    line: usize,
    stop: bool,
    radius: f64,
    thickness: f64,
    index: f64,
    diameter: f64,
}

pub(super) fn read(
    text: &str,
    source: &Source,
    dialect: Dialect,
) -> Result<Loaded, PrescriptionError> {
    let mut comments: Vec<String> = Vec::new();
    let mut rows: Vec<Row> = Vec::new();
    let mut claimed_focal_length_mm: Option<f64> = None;
    for (number, raw) in text.lines().enumerate() {
        let line = number + 1;
        let (data, comment) = match raw.split_once('#') {
            Some((data, comment)) => (data, Some(comment)),
            None => (raw, None),
        };
        if let (Some(comment), true) = (comment, rows.is_empty()) {
            let comment = comment.trim();
            if !comment.is_empty() {
                comments.push(comment.to_string());
            }
        }
        let tokens: Vec<&str> = match dialect {
            Dialect::Pbrt(_) => data.split_whitespace().collect(),
            Dialect::Table => data
                .split(|c: char| c.is_whitespace() || c == ',')
                .filter(|t| !t.is_empty())
                .collect(),
        };
        if tokens.is_empty() {
            continue;
        }
        let at = |column: usize| {
            source
                .location(Some(line))
                .with_surface(rows.len() + 1)
                .with_field(COLUMNS[column])
        };
        if let ([focal_length], true, None) =
            (tokens.as_slice(), rows.is_empty(), claimed_focal_length_mm)
            && focal_length.parse::<f64>().is_ok()
        {
            claimed_focal_length_mm = Some(focal_length_row(focal_length, source, line)?);
            continue;
        }
        if tokens.len() != COLUMNS.len() {
            return Err(PrescriptionError::new(
                source.location(Some(line)).with_surface(rows.len() + 1),
                Problem::WrongColumnCount {
                    expected: "4 (radius, thickness, index, aperture diameter)".to_string(),
                    found: tokens.len(),
                },
            ));
        }
        if dialect == Dialect::Table && rows.is_empty() && is_header(&tokens) {
            continue;
        }
        super::check_surface_count(rows.len() + 1, source.location(Some(line)))?;
        let (stop, radius) = radius_column(tokens[0], dialect, &at(0))?;
        rows.push(Row {
            line,
            stop,
            radius,
            thickness: finite(tokens[1], &at(1))?,
            index: finite(tokens[2], &at(2))?,
            diameter: finite(tokens[3], &at(3))?,
        });
    }
    if rows.is_empty() {
        return Err(source.error(None, Problem::Empty));
    }

    let mut notes = Vec::new();
    let thicknesses: Vec<f64> = match dialect {
        Dialect::Pbrt(PbrtThickness::FromPrevious) => {
            let first = rows[0].thickness;
            if first != 0.0 {
                return Err(PrescriptionError::new(
                    first_thickness(source, &rows[0]),
                    Problem::FirstAxialPositionNotZero { value: first },
                ));
            }
            // Row k's value is the gap before it; the gap after the last surface is unknown.
            rows.iter()
                .skip(1)
                .map(|r| r.thickness)
                .chain([0.0])
                .collect()
        }
        Dialect::Pbrt(PbrtThickness::ToNext) => {
            if rows.len() > 1 && rows[0].thickness == 0.0 {
                notes.push(LoadNote::PbrtFirstThicknessZero);
            }
            rows.iter().map(|r| r.thickness).collect()
        }
        Dialect::Table => rows.iter().map(|r| r.thickness).collect(),
    };

    let mut surfaces = Vec::with_capacity(rows.len());
    let mut medium_before = Medium::Air;
    for (row, thickness) in rows.iter().zip(thicknesses) {
        let medium = if row.stop && row.index == 0.0 {
            medium_before.clone()
        } else if row.index == 1.0 {
            Medium::Air
        } else {
            Medium::Index(row.index)
        };
        medium_before = medium.clone();
        surfaces.push(Surface {
            shape: if row.stop {
                Shape::Plane
            } else {
                Shape::from_radius(row.radius)
            },
            thickness,
            medium,
            semi_aperture: row.diameter / 2.0,
            stop: row.stop.then_some(StopShape::Circle),
            obscuration: None,
        });
    }

    let mut comments = comments.into_iter();
    let provenance = Provenance {
        title: comments.next().unwrap_or_else(|| source.default_title()),
        source: source.file_name(),
        notes: Some(comments.collect::<Vec<_>>().join("\n")).filter(|n| !n.is_empty()),
        claimed_focal_length_mm,
        ..Provenance::default()
    };
    Ok(Loaded {
        prescription: Prescription {
            provenance,
            object_medium: Medium::Air,
            surfaces,
        },
        map: SourceMap {
            file: None,
            surface_lines: rows.iter().map(|r| Some(r.line)).collect(),
            ..SourceMap::default()
        },
        format: match dialect {
            Dialect::Pbrt(_) => Format::Pbrt,
            Dialect::Table => Format::Table,
        },
        notes,
    })
}

/// The focal length a table's header row states: a finite number, not zero (a diverging
/// lens's is negative).
fn focal_length_row(token: &str, source: &Source, line: usize) -> Result<f64, PrescriptionError> {
    let at = source.location(Some(line)).with_field("focal length");
    let focal_length = finite(token, &at)?;
    if focal_length == 0.0 {
        return Err(PrescriptionError::new(
            at,
            Problem::Syntax(
                "a focal length of 0 before the surface rows; a table's header row states the \
                 lens's focal length"
                    .into(),
            ),
        ));
    }
    Ok(focal_length)
}

fn first_thickness(source: &Source, row: &Row) -> Location {
    source
        .location(Some(row.line))
        .with_surface(1)
        .with_field("thickness")
}

/// Reads the radius column: (is the stop, radius). A plane has radius 0 or infinity.
fn radius_column(
    token: &str,
    dialect: Dialect,
    at: &Location,
) -> Result<(bool, f64), PrescriptionError> {
    let word = token.to_ascii_lowercase();
    let stop_word = match dialect {
        Dialect::Pbrt(_) => word == "n/a",
        Dialect::Table => matches!(word.as_str(), "n/a" | "stop" | "sto"),
    };
    if stop_word {
        return Ok((true, 0.0));
    }
    let radius = number(token, at)?;
    if radius.is_nan() {
        return Err(PrescriptionError::new(
            at.clone(),
            Problem::NonFinite { value: radius },
        ));
    }
    let pbrt_stop = matches!(dialect, Dialect::Pbrt(_)) && radius == 0.0;
    Ok((pbrt_stop, radius))
}

/// A header row: four words, none of them a number or a stop marker.
fn is_header(tokens: &[&str]) -> bool {
    tokens.iter().all(|t| {
        t.parse::<f64>().is_err()
            && !matches!(t.to_ascii_lowercase().as_str(), "n/a" | "stop" | "sto")
    })
}
