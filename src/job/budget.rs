//! `--error-budget-px` for a render: the cheapest model whose image error stays under a budget in
//! pixels of this render, for the scene this render sees.

use super::{JobError, focus_of_film};
use crate::lenses::LoadedLens;
use crate::lrtf::measure::pixel_pitch;
use crate::render::camera::Camera;
use crate::render::layers::LayeredDepthImage;
use crate::tradeoff::choose::{Choice, choose_model};
use crate::tradeoff::{Domain, SceneRequirements};

/// The model an error budget chose for a render, with the scene it was chosen for.
#[derive(Clone, Debug)]
pub struct BudgetChoice {
    pub choice: Choice,
    /// Object distance in focus (mm; None: infinity).
    pub focus_mm: Option<f64>,
    /// Nearest scene surface (mm in front of surface 1; None: none in front of the lens).
    pub nearest_mm: Option<f64>,
    /// Largest distance of a film point from the axis.
    pub film_corner_mm: f64,
    /// The real chief ray's film radius at the largest traceable field: the budget covers the
    /// film up to here.
    pub full_film_radius_mm: f64,
}

/// The cheapest model whose image error stays under `budget_px` pixels of this render for its
/// scene: the focus of `camera`'s film, the nearest surface of `layers`, the film area the frame
/// uses, the f-number, at this render's pixel pitch, in one wavelength (the renderer's).
pub fn choose_for_render(
    lens: &LoadedLens,
    camera: &Camera,
    layers: &LayeredDepthImage,
    width: u32,
    f_number: f64,
    budget_px: f64,
) -> Result<BudgetChoice, JobError> {
    let focus_mm = focus_of_film(lens, camera.film_z)?;
    let whole_field = SceneRequirements {
        focus_mm,
        f_number: Some(f_number),
        ..SceneRequirements::default()
    };
    let full_film_radius = Domain::of(&lens.system, &whole_field)?.full_film_radius;
    let corner = camera.film_corner_radius();
    let film_radius = corner.min(full_film_radius);
    let nearest_mm = layers
        .depth_range()
        .map(|range| f64::from(range[0]) - camera.eye_z())
        .filter(|d| *d > 0.0);
    let req = SceneRequirements {
        nearest_mm,
        film_fraction: film_radius / full_film_radius,
        // The width of the 3:2 frame in that image circle, counted in this render's pixels.
        pixels: pixel_pitch(film_radius, 1.0) / (camera.film.width_mm / f64::from(width)),
        monochrome: true,
        ..whole_field
    };
    let choice = choose_model(&lens.system, &req, budget_px)?;
    Ok(BudgetChoice {
        choice,
        focus_mm,
        nearest_mm,
        film_corner_mm: corner,
        full_film_radius_mm: full_film_radius,
    })
}
