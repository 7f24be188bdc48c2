//! A baked LRTF table as a model: one texture fetch per ray, through a stop realising the
//! render's f-number, on a film plane of the table's focus range.

use std::sync::Arc;

use super::{FirstOrderModels, ModelError, ParaxialLens, PupilSampling};
use crate::lrtf::LrtfTable;

/// A baked table, the stop radius realising the render's f-number and the film plane the render
/// focuses on (any plane of the table's focus range).
#[derive(Clone, Debug, PartialEq)]
pub struct BakedLens {
    pub paraxial: ParaxialLens,
    /// Shared, not copied, by clones: a render's camera is a clone of the one it was built
    /// from, and a 128^3 f32 table is 64 MiB.
    pub table: Arc<LrtfTable>,
    pub stop_radius: f64,
    /// The table layer a monochrome render reads: 0 from [`BakedLens::new`], the design
    /// wavelength's after [`BakedLens::with_wavelength`] (a three-wavelength table lists its
    /// layers R, G, B or C, d, F, so layer 0 is rarely the design one).
    pub layer: usize,
    film_z: f64,
}

impl BakedLens {
    /// The table with the film on its reference plane (the far end of its focus range).
    pub fn new(
        table: LrtfTable,
        first_order: &FirstOrderModels,
        f_number: f64,
    ) -> Result<BakedLens, ModelError> {
        let film_z = table.layers[0].frame.film_plane_z;
        BakedLens::focused(table, first_order, f_number, film_z)
    }

    /// The table with the film on the plane `film_z`, which its focus range must cover.
    pub fn focused(
        table: LrtfTable,
        first_order: &FirstOrderModels,
        f_number: f64,
        film_z: f64,
    ) -> Result<BakedLens, ModelError> {
        let stop_radius = table
            .stop_radius(0, f_number)
            .ok_or(ModelError::FasterThanTable {
                f_number,
                table: table.info.f_number,
            })?;
        let asked = format!("of the film at z = {film_z:.4} mm");
        table.info.focus.check_film_z(film_z, &asked)?;
        Ok(BakedLens {
            paraxial: first_order.thick.clone(),
            table: Arc::new(table),
            stop_radius,
            layer: 0,
            film_z,
        })
    }

    /// This lens reading the table's layer baked at `wavelength_nm` (see [`layer_at`]); a
    /// one-layer table keeps its only layer, whatever wavelength it was baked at.
    pub fn with_wavelength(self, wavelength_nm: f64) -> Result<BakedLens, ModelError> {
        if self.table.layers.len() == 1 {
            return Ok(self);
        }
        let layer = layer_at(&self.table, wavelength_nm)?;
        Ok(BakedLens { layer, ..self })
    }

    /// The film plane the render focuses on: the camera's film must sit there.
    pub fn film_z(&self) -> f64 {
        self.film_z
    }

    /// The sampling pupil of layer `layer` on this lens's film plane.
    pub fn pupil(&self, layer: usize) -> PupilSampling {
        let layer = &self.table.layers[layer];
        PupilSampling {
            z: layer.frame.rear_plane_z,
            circles: layer.sampling.at_film_z(self.film_z),
        }
    }
}

/// Largest difference between an asked wavelength and a table layer's that still selects the
/// layer (nm). Tables record wavelengths as typed (656.3 or 656.2725 for the C line); half a
/// nanometre changes a glass index by about 1e-5, below anything a render shows.
pub const WAVELENGTH_MATCH_NM: f64 = 0.5;

/// The layer of `table` baked at `wavelength_nm` (within [`WAVELENGTH_MATCH_NM`]).
pub fn layer_at(table: &LrtfTable, wavelength_nm: f64) -> Result<usize, ModelError> {
    let distance = |k: usize| (table.layers[k].wavelength_nm - wavelength_nm).abs();
    (0..table.layers.len())
        .min_by(|&a, &b| distance(a).total_cmp(&distance(b)))
        .filter(|&k| distance(k) <= WAVELENGTH_MATCH_NM)
        .ok_or_else(|| {
            let baked: Vec<String> = table
                .layers
                .iter()
                .map(|l| format!("{}", l.wavelength_nm))
                .collect();
            ModelError::NoLayerAt {
                wavelength_nm,
                baked: baked.join(", "),
            }
        })
}
