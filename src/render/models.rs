//! The four lens models of a real prescription, built from the library's optics: thin and thick
//! from [`crate::paraxial`], traced from [`crate::trace`], baked from an [`LrtfTable`].
//!
//! Traced and baked models draw lens samples on the effective-pupil circle of the rear vertex
//! plane (issue 6), the thin and thick models on their exit pupil; a [`PupilSampling`] states
//! which, so the kernels, the reference and the tests all sample the same way.

use super::RenderError;
use super::camera::ParaxialLens;
use crate::lrtf::LrtfTable;
use crate::lrtf::bake::{fit_film_pupil, rear_search_radius, stopped_down};
use crate::paraxial::{Paraxial, ParaxialOptions};
use crate::pupil::{self, PupilCircle, PupilFitSettings, PupilTable};
use crate::system::{LensSystem, SystemAt};
use crate::trace::Tracer;

/// The first-order models of a lens at its design wavelength, stopped down to `f_number`.
#[derive(Clone, Debug, PartialEq)]
pub struct FirstOrderModels {
    /// Focal length EFL, one plane at the entrance pupil holding both principal planes and both
    /// pupils (radius EFL / 2N).
    pub thin: ParaxialLens,
    /// Principal planes and real pupil positions and sizes.
    pub thick: ParaxialLens,
    /// f-number of the lens wide open (paraxial, object at infinity).
    pub wide_open_f_number: f64,
    /// The f-number the models are stopped down to.
    pub f_number: f64,
}

fn paraxial_error(e: impl std::fmt::Display) -> RenderError {
    RenderError::InvalidSetting(format!("lens: {e}"))
}

impl FirstOrderModels {
    /// The models at `f_number`, wide open when None.
    pub fn of(system: &LensSystem, f_number: Option<f64>) -> Result<FirstOrderModels, RenderError> {
        let at = system.at(system.design_wavelength_nm());
        let paraxial = Paraxial::new(&at, &ParaxialOptions::default()).map_err(paraxial_error)?;
        let wide_open = paraxial.f_number;
        let f_number = f_number.unwrap_or(wide_open);
        if !(f_number.is_finite() && f_number >= wide_open * (1.0 - 1e-9)) {
            return Err(RenderError::InvalidSetting(format!(
                "f-number {f_number} is faster than the lens wide open (f/{wide_open:.3})"
            )));
        }
        let exit = paraxial.exit_pupil.ok_or_else(|| {
            RenderError::InvalidSetting(
                "lens: the exit pupil is at infinity; thick and thin models need a finite one"
                    .into(),
            )
        })?;
        // Pupils scale with the stop, as 1 / f-number.
        let scale = wide_open / f_number;
        let first = &paraxial.first_order;
        let thick = ParaxialLens {
            focal_length_mm: first.efl,
            front_principal_z: first.z_front_principal,
            rear_principal_z: first.z_rear_principal,
            entrance_pupil_z: paraxial.entrance_pupil.z,
            entrance_pupil_radius_mm: paraxial.entrance_pupil.diameter / 2.0 * scale,
            exit_pupil_z: exit.z,
            exit_pupil_radius_mm: exit.diameter / 2.0 * scale,
        };
        let z = paraxial.entrance_pupil.z;
        let radius = first.efl / (2.0 * f_number);
        let thin = ParaxialLens {
            focal_length_mm: first.efl,
            front_principal_z: z,
            rear_principal_z: z,
            entrance_pupil_z: z,
            entrance_pupil_radius_mm: radius,
            exit_pupil_z: z,
            exit_pupil_radius_mm: radius,
        };
        Ok(FirstOrderModels {
            thin,
            thick,
            wide_open_f_number: wide_open,
            f_number,
        })
    }
}

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
        let design = system.at(system.design_wavelength_nm());
        let stop_semi_aperture =
            design.surfaces[design.stop].semi_aperture * first_order.wide_open_f_number / f_number;
        let stopped = stopped_down(system, system.design_wavelength_nm(), stop_semi_aperture);
        TracedLens {
            paraxial: first_order.thick.clone(),
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
    ) -> Result<TracedLens, RenderError> {
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
) -> Result<PupilTable, RenderError> {
    let tracer = Tracer::new(system);
    let search = rear_search_radius(system);
    let settings = PupilFitSettings::default();
    let fit = |film_radius: f64| fit_film_pupil(&tracer, film_z, search, &settings, film_radius);
    let table = pupil::build_table(&fit, max_film_radius, nodes, 2);
    if table.circles[0].radius <= 0.0 {
        return Err(RenderError::InvalidSetting(format!(
            "no ray from the film centre (z = {film_z:.3} mm) passes the lens"
        )));
    }
    Ok(table)
}

/// A baked table, the stop radius realising the render's f-number and the film plane the render
/// focuses on (any plane of the table's focus range).
#[derive(Clone, Debug, PartialEq)]
pub struct BakedLens {
    pub paraxial: ParaxialLens,
    pub table: LrtfTable,
    pub stop_radius: f64,
    film_z: f64,
}

impl BakedLens {
    /// The table with the film on its reference plane (the far end of its focus range).
    pub fn new(
        table: LrtfTable,
        first_order: &FirstOrderModels,
        f_number: f64,
    ) -> Result<BakedLens, RenderError> {
        let film_z = table.layers[0].frame.film_plane_z;
        BakedLens::focused(table, first_order, f_number, film_z)
    }

    /// The table with the film on the plane `film_z`, which its focus range must cover.
    pub fn focused(
        table: LrtfTable,
        first_order: &FirstOrderModels,
        f_number: f64,
        film_z: f64,
    ) -> Result<BakedLens, RenderError> {
        let stop_radius = table.stop_radius(0, f_number).ok_or_else(|| {
            RenderError::InvalidSetting(format!(
                "f-number {f_number} is faster than the table's f/{:.3}; rebake with --f-number",
                table.info.f_number
            ))
        })?;
        let asked = format!("of the film at z = {film_z:.4} mm");
        table
            .info
            .focus
            .check_film_z(film_z, &asked)
            .map_err(|e| RenderError::InvalidSetting(format!("baked lens: {e}")))?;
        Ok(BakedLens {
            paraxial: first_order.thick.clone(),
            table,
            stop_radius,
            film_z,
        })
    }

    /// The film plane the render focuses on: the camera's film must sit there.
    pub fn film_z(&self) -> f64 {
        self.film_z
    }

    /// The sampling pupil's circles on this lens's film plane.
    pub fn pupil(&self) -> PupilTable {
        self.table.layers[0].sampling.at_film_z(self.film_z)
    }
}

/// Where lens samples are drawn: uniformly over a circle on the plane `z`, the circle looked up
/// by film radius in `circles` (film point rotated onto +x).
#[derive(Clone, Debug, PartialEq)]
pub struct PupilSampling {
    pub z: f64,
    pub circles: PupilTable,
}

impl PupilSampling {
    /// One circle, centred on the axis, for every film point: a paraxial exit pupil.
    pub fn disc(z: f64, radius: f64) -> PupilSampling {
        PupilSampling {
            z,
            circles: PupilTable {
                max_film_radius: 0.0,
                circles: vec![PupilCircle {
                    centre_x: 0.0,
                    radius,
                }],
            },
        }
    }
}
