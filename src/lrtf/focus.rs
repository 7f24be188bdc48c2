//! Focus ranges. Under unit focusing the lens stays put and the film moves, so a film-side ray is
//! a line whatever film plane it starts on: the pupil-planes table addresses it by where it
//! crosses the table's reference film plane (the far focus's) and the rear vertex plane, and one
//! transfer table serves every film plane of a range once its film-radius domain covers where the
//! range's rays cross the reference plane. Only the effective pupil depends on the film plane; it
//! is a 2D table over film radius and focus ([`crate::pupil::FocusPupilTable`]).

use serde::{Deserialize, Serialize};

use crate::paraxial::FirstOrder;

/// Relative tolerance on film-plane z when deciding whether a film plane lies in a focus range:
/// planes computed from the same focus distance by different paraxial routes (Newton's equation
/// here, the principal planes in the renderer's thick model) agree to ~1e-12.
pub const FILM_Z_TOLERANCE: f64 = 1e-9;

/// The object distances a table is focused over, and where the film sits for each.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FocusRange {
    /// Farthest object distance in focus, mm in front of surface 1; None for infinity. The
    /// table's reference film plane (its frame's `film_plane_z`) is this focus's.
    pub far_mm: Option<f64>,
    /// Nearest object distance in focus; equal to `far_mm` for a single-focus table.
    pub near_mm: Option<f64>,
    /// The lens's paraxial focus map at the design wavelength (Newton's x x' = f f'): an object
    /// d mm in front of surface 1 is in focus on the film plane
    /// z = rear_focal_z + focal_product / (front_focal_z + d), and at infinity on rear_focal_z.
    pub rear_focal_z: f64,
    pub front_focal_z: f64,
    /// Product of the object- and image-side focal lengths (mm^2; EFL^2 in air).
    pub focal_product: f64,
}

/// Why a focus is not served by a table.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FocusError {
    #[error(
        "focus {asked} lies outside the table's focus range {range} (film z {film_z:.4} mm, the \
         table serves {near_z:.4}..{far_z:.4} mm); rebake with --focus-mm covering it"
    )]
    OutsideRange {
        asked: String,
        range: String,
        film_z: f64,
        far_z: f64,
        near_z: f64,
    },
    #[error("focus distance {0} mm is not a positive number")]
    NotPositive(f64),
}

/// "infinity" or "1234.5 mm".
pub fn distance_text(distance: Option<f64>) -> String {
    distance.map_or("infinity".into(), |d| format!("{d} mm"))
}

impl FocusRange {
    /// The range from `far_mm` to `near_mm` (None: infinity) of a lens whose first-order data
    /// at the design wavelength is `first`.
    pub fn new(first: &FirstOrder, far_mm: Option<f64>, near_mm: Option<f64>) -> FocusRange {
        FocusRange {
            far_mm,
            near_mm,
            rear_focal_z: first.z_rear_focal,
            front_focal_z: first.z_front_focal,
            focal_product: first.fl_object * first.efl,
        }
    }

    pub fn is_single(&self) -> bool {
        self.far_mm == self.near_mm
    }

    /// Film plane (lens-frame z) in focus for an object `distance` mm in front of surface 1.
    pub fn film_z(&self, distance: Option<f64>) -> f64 {
        distance.map_or(self.rear_focal_z, |d| {
            self.rear_focal_z + self.focal_product / (self.front_focal_z + d)
        })
    }

    /// The film planes of the far and the near focus (the far one is nearer the lens).
    pub fn film_z_range(&self) -> [f64; 2] {
        [self.film_z(self.far_mm), self.film_z(self.near_mm)]
    }

    /// The range as text: "infinity", "2000 mm" or "infinity..1000 mm".
    pub fn text(&self) -> String {
        if self.is_single() {
            distance_text(self.far_mm)
        } else {
            let far = self.far_mm.map_or("infinity".into(), |d| d.to_string());
            format!("{far}..{}", distance_text(self.near_mm))
        }
    }

    /// Checks that the film plane `film_z` lies in the range (to [`FILM_Z_TOLERANCE`]);
    /// `asked` names the focus in the error.
    pub fn check_film_z(&self, film_z: f64, asked: &str) -> Result<(), FocusError> {
        let [far_z, near_z] = self.film_z_range();
        let slack = FILM_Z_TOLERANCE * near_z.abs().max(far_z.abs()).max(1.0);
        if film_z >= far_z.min(near_z) - slack && film_z <= far_z.max(near_z) + slack {
            Ok(())
        } else {
            Err(FocusError::OutsideRange {
                asked: asked.to_string(),
                range: self.text(),
                film_z,
                far_z,
                near_z,
            })
        }
    }

    /// The film plane of an object `distance` mm away (None: infinity), if the range covers it.
    pub fn film_z_for(&self, distance: Option<f64>) -> Result<f64, FocusError> {
        if let Some(d) = distance
            && !(d.is_finite() && d > 0.0)
        {
            return Err(FocusError::NotPositive(d));
        }
        let film_z = self.film_z(distance);
        self.check_film_z(film_z, &distance_text(distance))?;
        Ok(film_z)
    }
}
