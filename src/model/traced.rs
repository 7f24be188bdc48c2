//! The exact lens as a model: the sequential trace through every surface, sampled on its
//! effective pupil.

use super::{FirstOrderModels, ModelError, ParaxialLens, PupilSampling};
use crate::lrtf::bake::{fit_film_pupil, rear_search_radius, stopped_down};
use crate::pupil::{self, PupilFitSettings, PupilTable};
use crate::system::{LensSystem, SystemAt};
use crate::trace::Tracer;

/// The exact lens at its design wavelength, stopped down, with the effective pupil of its film
/// plane.
#[derive(Clone, Debug, PartialEq)]
pub struct TracedLens {
    /// The thick model: where the eye sits, the field of view and the layer margins.
    pub paraxial: ParaxialLens,
    /// The stopped-down lens the tracer was built from (the GPU's copy is made from it).
    pub system: SystemAt,
    pub tracer: Tracer,
    pub pupil: PupilTable,
    pub rear_plane_z: f64,
}

impl TracedLens {
    /// `pupil` must bound the passing rays of this lens, f-number and film plane (from
    /// [`fit_effective_pupil`], or a baked table's for the same domain).
    pub fn new(
        system: &LensSystem,
        first_order: &FirstOrderModels,
        f_number: f64,
        pupil: PupilTable,
    ) -> TracedLens {
        TracedLens::at_wavelength(
            system,
            first_order,
            f_number,
            system.design_wavelength_nm(),
            pupil,
        )
    }

    /// The lens traced at `wavelength_nm` (the caller checks that every medium has an index
    /// there), with the stop closed as at the design wavelength: the aperture is one physical
    /// opening whatever the colour. `paraxial` stays the design wavelength's thick model.
    pub fn at_wavelength(
        system: &LensSystem,
        first_order: &FirstOrderModels,
        f_number: f64,
        wavelength_nm: f64,
        pupil: PupilTable,
    ) -> TracedLens {
        let design = system.at(system.design_wavelength_nm());
        let stop_semi_aperture =
            design.surfaces[design.stop].semi_aperture * first_order.wide_open_f_number / f_number;
        let stopped = stopped_down(system, wavelength_nm, stop_semi_aperture);
        TracedLens::from_stopped(first_order.thick.clone(), stopped, pupil)
    }

    /// The lens `stopped` (already stopped down) traced, with `paraxial` its thick model.
    pub fn from_stopped(
        paraxial: ParaxialLens,
        stopped: SystemAt,
        pupil: PupilTable,
    ) -> TracedLens {
        TracedLens {
            paraxial,
            tracer: Tracer::new(&stopped),
            rear_plane_z: stopped.last_vertex_z(),
            system: stopped,
            pupil,
        }
    }
}

impl TracedLens {
    /// The traced lens with its effective pupil fitted for the film plane `film_z`, film radii up
    /// to `max_film_radius`, at `nodes` film radii.
    pub fn fitted(
        system: &LensSystem,
        first_order: &FirstOrderModels,
        f_number: f64,
        film_z: f64,
        max_film_radius: f64,
        nodes: usize,
    ) -> Result<TracedLens, ModelError> {
        let placeholder = PupilSampling::disc(0.0, 0.0).circles;
        let mut lens = TracedLens::new(system, first_order, f_number, placeholder);
        lens.pupil = fit_effective_pupil(&lens.system, film_z, max_film_radius, nodes)?;
        Ok(lens)
    }
}

/// Effective-pupil circles on the rear vertex plane for film points up to `max_film_radius` on
/// the plane `film_z`, fitted with the same probe as the bake (`nodes` film radii).
pub fn fit_effective_pupil(
    system: &SystemAt,
    film_z: f64,
    max_film_radius: f64,
    nodes: usize,
) -> Result<PupilTable, ModelError> {
    let tracer = Tracer::new(system);
    let search = rear_search_radius(system);
    let settings = PupilFitSettings::default();
    let fit = |film_radius: f64| fit_film_pupil(&tracer, film_z, search, &settings, film_radius);
    let table = pupil::build_table(&fit, max_film_radius, nodes, 2);
    if table.circles[0].radius <= 0.0 {
        return Err(ModelError::NoRayFromFilmCentre { film_z });
    }
    Ok(table)
}
