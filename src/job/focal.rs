//! A focal surface as a job asks for it: focus points on output pixels whose distance is given,
//! taken from the scene under the pixel, or deliberately off it (a defocus point), and the text
//! form `render --focal-surface` and the viewer's `focal-surface` line share.

use crate::render::RenderError;
use crate::render::focal_surface::{DEFAULT_BETA, FocalSurface, FocusPoint};

/// What a focus point asks to be sharp at its pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FocusTarget {
    /// This object distance (mm in front of the first vertex).
    Distance(f64),
    /// Whatever surface of the scene lies under the pixel.
    Scene,
    /// The surface under the pixel, defocused by this many dioptres (positive: focus nearer).
    Defocus(f64),
}

/// One focus point of a job.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FocusPointSpec {
    pub pixel: [u32; 2],
    pub target: FocusTarget,
    /// Importance alpha (see [`FocusPoint::weight`]).
    pub weight: f64,
}

/// A job's focal surface: its points and the falloff beta of their weights.
#[derive(Clone, Debug, PartialEq)]
pub struct FocalSurfaceSpec {
    pub points: Vec<FocusPointSpec>,
    pub beta: f64,
}

impl FocalSurfaceSpec {
    /// Reads `X,Y[,TARGET[,ALPHA]];...`: TARGET is a distance in mm, `scene` (the surface under
    /// the pixel, also when TARGET is left out) or a defocus of that surface in dioptres
    /// (`+0.5dpt` focuses half a dioptre nearer); ALPHA the point's weight (default 1).
    ///
    /// ```
    /// use lensbake::job::{FocalSurfaceSpec, FocusTarget};
    /// let spec = FocalSurfaceSpec::parse("10,20,1500;30,40;50,60,-0.5dpt,2", 3.0).unwrap();
    /// assert_eq!(spec.points[0].target, FocusTarget::Distance(1500.0));
    /// assert_eq!(spec.points[1].target, FocusTarget::Scene);
    /// assert_eq!(spec.points[2].target, FocusTarget::Defocus(-0.5));
    /// assert_eq!(spec.points[2].weight, 2.0);
    /// assert!(FocalSurfaceSpec::parse("10,20,far", 3.0).is_err());
    /// ```
    pub fn parse(text: &str, beta: f64) -> Result<FocalSurfaceSpec, String> {
        let mut points = Vec::new();
        for (i, item) in text.split(';').map(str::trim).enumerate() {
            if item.is_empty() {
                continue;
            }
            let n = i + 1;
            let fields: Vec<&str> = item.split(',').map(str::trim).collect();
            if !(2..=4).contains(&fields.len()) {
                return Err(format!(
                    "focus point {n} `{item}`: expected X,Y[,MM|scene|DPTdpt[,ALPHA]]"
                ));
            }
            let pixel = |word: &str, what: &str| {
                word.parse::<u32>().map_err(|_| {
                    format!("focus point {n}: {what} `{word}` is not a whole number of pixels")
                })
            };
            let number = |word: &str, what: &str| {
                word.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| format!("focus point {n}: {what} `{word}` is not a number"))
            };
            let target = match fields.get(2).copied() {
                None | Some("scene") => FocusTarget::Scene,
                Some(word) => match word.strip_suffix("dpt") {
                    Some(dioptres) => FocusTarget::Defocus(number(dioptres, "the defocus")?),
                    None => {
                        let mm = number(word, "the distance (mm, `scene` or N`dpt`)")?;
                        if mm <= 0.0 {
                            return Err(format!(
                                "focus point {n}: the distance must be positive, got {mm}"
                            ));
                        }
                        FocusTarget::Distance(mm)
                    }
                },
            };
            let weight = match fields.get(3) {
                Some(word) => number(word, "the weight")?,
                None => 1.0,
            };
            points.push(FocusPointSpec {
                pixel: [pixel(fields[0], "x")?, pixel(fields[1], "y")?],
                target,
                weight,
            });
        }
        if points.is_empty() {
            return Err("a focal surface needs at least one focus point".into());
        }
        Ok(FocalSurfaceSpec { points, beta })
    }

    /// Reads the text with the seed's default falloff ([`DEFAULT_BETA`]).
    pub fn parse_default(text: &str) -> Result<FocalSurfaceSpec, String> {
        FocalSurfaceSpec::parse(text, DEFAULT_BETA)
    }

    /// The surface, with `scene_distance_mm(pixel)` giving the distance of the surface under a
    /// pixel for the points that ask for it.
    pub fn resolve(
        &self,
        mut scene_distance_mm: impl FnMut([u32; 2]) -> Result<f64, RenderError>,
    ) -> Result<FocalSurface, RenderError> {
        let mut points = Vec::with_capacity(self.points.len());
        for spec in &self.points {
            let centre = spec.pixel.map(|v| v as f64 + 0.5);
            points.push(match spec.target {
                FocusTarget::Distance(distance_mm) => FocusPoint {
                    pixel: centre,
                    distance_mm,
                    weight: spec.weight,
                },
                FocusTarget::Scene => FocusPoint {
                    pixel: centre,
                    distance_mm: scene_distance_mm(spec.pixel)?,
                    weight: spec.weight,
                },
                FocusTarget::Defocus(dioptres) => FocusPoint::defocused(
                    centre,
                    scene_distance_mm(spec.pixel)?,
                    dioptres,
                    spec.weight,
                )?,
            });
        }
        FocalSurface::new(points, self.beta)
    }
}
