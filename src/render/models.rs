//! The five lens models of a real prescription, built from the library's optics: thin and thick
//! from [`crate::paraxial`], Seidel from [`crate::seidel`], traced from [`crate::trace`], baked
//! from an [`LrtfTable`].
//!
//! Traced and baked models draw lens samples on the effective-pupil circle of the rear vertex
//! plane (issue 6), the thin, thick and Seidel models on their exit pupil; a [`PupilSampling`] states
//! which, so the kernels, the reference and the tests all sample the same way.

use super::RenderError;
use super::camera::ParaxialLens;
use crate::lrtf::LrtfTable;
use crate::lrtf::bake::{passes_from_film, rear_search_radius, stopped_down};
use crate::paraxial::{ObjectPosition, Paraxial, ParaxialError, ParaxialOptions};
use crate::pupil::{self, PupilCircle, PupilFitSettings, PupilTable};
use crate::seidel::{Seidel, SeidelTerms};
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
    let rear_z = system.last_vertex_z();
    let search = rear_search_radius(system);
    let settings = PupilFitSettings::default();
    let fit = |film_radius: f64| {
        let passes = |rear: [f64; 2]| passes_from_film(&tracer, film_radius, film_z, rear_z, rear);
        pupil::fit_pupil(&passes, search, &settings)
    };
    let table = pupil::build_table(&fit, max_film_radius, nodes, 2);
    if table.circles[0].radius <= 0.0 {
        return Err(RenderError::InvalidSetting(format!(
            "no ray from the film centre (z = {film_z:.3} mm) passes the lens"
        )));
    }
    Ok(table)
}

/// A baked table and the stop radius realising the render's f-number.
#[derive(Clone, Debug, PartialEq)]
pub struct BakedLens {
    pub paraxial: ParaxialLens,
    pub table: LrtfTable,
    pub stop_radius: f64,
}

impl BakedLens {
    pub fn new(
        table: LrtfTable,
        first_order: &FirstOrderModels,
        f_number: f64,
    ) -> Result<BakedLens, RenderError> {
        let stop_radius = table.stop_radius(0, f_number).ok_or_else(|| {
            RenderError::InvalidSetting(format!(
                "f-number {f_number} is faster than the table's f/{:.3}; rebake with --f-number",
                table.info.f_number
            ))
        })?;
        Ok(BakedLens {
            paraxial: first_order.thick.clone(),
            table,
            stop_radius,
        })
    }

    /// The film plane the table was baked for: the render's film must sit there.
    pub fn film_z(&self) -> f64 {
        self.table.layers[0].frame.film_plane_z
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

/// The paraxial setup for an object in focus at `focus_mm` (None: infinity), wide open, at the
/// largest unvignetted field: the conjugate a [`SeidelLens`] is built for.
pub fn paraxial_for(system: &SystemAt, focus_mm: Option<f64>) -> Result<Paraxial, ParaxialError> {
    let object = ObjectPosition::in_focus(focus_mm);
    Paraxial::new(
        system,
        &ParaxialOptions {
            object,
            ..ParaxialOptions::default()
        },
    )
}

/// The third-order transverse aberration polynomial of a [`SeidelLens`], as coefficients (mm in
/// the Gaussian image plane) of the monomials in normalised field h and pupil (px across the
/// field direction, py along it, rho^2 = px^2 + py^2):
///
/// eps_x = spherical rho^2 px + 2 coma h px py + sagittal h^2 px,
/// eps_y = spherical rho^2 py + coma h (rho^2 + 2 py^2) + tangential h^2 py + distortion h^3.
///
/// From W = S_I/8 rho^4 + S_II/2 h y rho^2 + S_III/2 h^2 y^2 + (S_III + S_IV)/4 h^2 rho^2
/// + S_V/2 h^3 y and eps = grad W / (n' u').
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TransverseCoefficients {
    pub spherical: f64,
    pub coma: f64,
    pub sagittal: f64,
    pub tangential: f64,
    pub distortion: f64,
}

/// The thick-lens map plus the third-order transverse aberration of the Seidel sums, for one
/// object conjugate (the one the sums were computed for), after Asberg (seed 001 section 3.10).
///
/// Forward, a ray from the object point whose Gaussian image is G through normalised exit-pupil
/// point p lands at G + eps(G, p) in the Gaussian image plane ([`TransverseCoefficients`]; the
/// convention of [`crate::seidel::SeidelTerms::transverse`], which it reproduces: TSA, TCO, TAS,
/// SAS and DST). The film-to-scene map inverts that: it solves G + eps(G, p) = L for the
/// film-side ray's landing point L by fixed-point iteration, then sends the paraxial ray from G
/// through the same exit-pupil point into the scene. Where the iteration does not settle (far
/// outside the field the polynomial describes) the model has no ray and says so.
#[derive(Clone, Debug, PartialEq)]
pub struct SeidelLens {
    pub thick: ParaxialLens,
    pub sums: SeidelTerms,
    /// z of the Gaussian image plane of the conjugate.
    pub image_z: f64,
    /// Signed chief-ray height in the image plane at normalised field H = 1.
    pub chief_image_height: f64,
    /// Signed marginal-ray height in the exit-pupil plane (normalised pupil coordinate 1) wide
    /// open; a stopped-down `thick` samples a smaller pupil of the same polynomial.
    pub marginal_pupil_height: f64,
    /// n' u' of the marginal ray in image space.
    pub n_u_image: f64,
}

/// Fixed-point steps of the inverse map. Eps changes by a fraction of a change in G; at f/0.95
/// with strong coma that fraction reaches one half, and sixteen steps still settle to well under
/// [`SEIDEL_SETTLED_MM`] from a millimetre of aberration (four did not). Most rays stop early,
/// at [`SEIDEL_CONVERGED_MM`].
pub const SEIDEL_INVERSE_STEPS: u32 = 16;
/// A step this small (10 nm, 1/2000 of a pixel of a 1920 px full-frame image, and above f32
/// rounding of image heights) ends the iteration.
pub const SEIDEL_CONVERGED_MM: f64 = 1e-5;
/// The last fixed-point step may move G by at most this (mm): beyond it the iteration has not
/// converged and the model gives no ray (about 1/20 of a pixel of a 1920 px full-frame image).
pub const SEIDEL_SETTLED_MM: f64 = 1e-3;

impl SeidelLens {
    /// From the paraxial setup the sums belong to (pupils wide open, `paraxial`'s field as H = 1)
    /// and the thick model at the f-number used.
    pub fn new(system: &SystemAt, paraxial: &Paraxial, thick: ParaxialLens) -> SeidelLens {
        let seidel = Seidel::new(system, paraxial, None);
        SeidelLens {
            marginal_pupil_height: paraxial.marginal.image_space_height(thick.exit_pupil_z),
            thick,
            sums: seidel.sums,
            image_z: paraxial.z_image,
            chief_image_height: paraxial.image_height,
            n_u_image: system.image_index() * paraxial.marginal.image_slope(),
        }
    }

    /// The model of `system` at its design wavelength for an object in focus at `focus_mm`
    /// (None: infinity), with `first_order`'s thick lens (its f-number).
    pub fn in_focus(
        system: &LensSystem,
        first_order: &FirstOrderModels,
        focus_mm: Option<f64>,
    ) -> Result<SeidelLens, RenderError> {
        let at = system.at(system.design_wavelength_nm());
        let paraxial = paraxial_for(&at, focus_mm).map_err(paraxial_error)?;
        let lens = SeidelLens::new(&at, &paraxial, first_order.thick.clone());
        let usable = |v: f64| v.is_finite() && v != 0.0;
        if !(usable(lens.chief_image_height)
            && usable(lens.marginal_pupil_height)
            && usable(lens.n_u_image))
        {
            return Err(RenderError::InvalidSetting(format!(
                "lens: the Seidel model needs a field and a pupil of finite, nonzero size (chief \
                 image height {} mm, marginal exit-pupil height {} mm, n'u' {})",
                lens.chief_image_height, lens.marginal_pupil_height, lens.n_u_image
            )));
        }
        Ok(lens)
    }

    pub fn coefficients(&self) -> TransverseCoefficients {
        let s = &self.sums;
        let k = 1.0 / self.n_u_image;
        TransverseCoefficients {
            spherical: 0.5 * s.spherical * k,
            coma: 0.5 * s.coma * k,
            sagittal: 0.5 * (s.astigmatism + s.petzval) * k,
            tangential: 0.5 * (3.0 * s.astigmatism + s.petzval) * k,
            distortion: 0.5 * s.distortion * k,
        }
    }

    /// Transverse aberration (mm, image plane) of the ray to Gaussian image point `g` through
    /// normalised exit-pupil point `pupil` (both in the lens's x, y).
    pub fn aberration(&self, g: [f64; 2], pupil: [f64; 2]) -> [f64; 2] {
        let radius = g[0].hypot(g[1]);
        // Meridional frame: y along the field direction (any direction on the axis).
        let u = if radius > 0.0 {
            [g[0] / radius, g[1] / radius]
        } else {
            [1.0, 0.0]
        };
        let v = [-u[1], u[0]];
        let h = radius / self.chief_image_height;
        let py = pupil[0] * u[0] + pupil[1] * u[1];
        let px = pupil[0] * v[0] + pupil[1] * v[1];
        let rho2 = px * px + py * py;
        let c = self.coefficients();
        let ex = c.spherical * rho2 * px + 2.0 * c.coma * h * px * py + c.sagittal * h * h * px;
        let ey = c.spherical * rho2 * py
            + c.coma * h * (rho2 + 2.0 * py * py)
            + c.tangential * h * h * py
            + c.distortion * h * h * h;
        [ey * u[0] + ex * v[0], ey * u[1] + ex * v[1]]
    }

    /// The object-space ray for the film-side ray from `film` towards `pupil` (lens-frame
    /// points): a point on it and its slopes dx/dz, dy/dz, as [`ParaxialLens::object_ray`]; None
    /// where the inverse map does not settle. The f64 statement of the shader's
    /// `seidel_lens_ray`.
    pub fn object_ray(&self, film: [f64; 3], pupil: [f64; 3]) -> Option<([f64; 3], [f64; 2])> {
        let at = |z: f64| {
            let t = (z - film[2]) / (pupil[2] - film[2]);
            [
                film[0] + t * (pupil[0] - film[0]),
                film[1] + t * (pupil[1] - film[1]),
            ]
        };
        let exit = at(self.thick.exit_pupil_z);
        let landing = at(self.image_z);
        let p = exit.map(|v| v / self.marginal_pupil_height);
        let mut g = landing;
        let mut step = 0.0;
        for _ in 0..SEIDEL_INVERSE_STEPS {
            let eps = self.aberration(g, p);
            let next = [landing[0] - eps[0], landing[1] - eps[1]];
            step = (next[0] - g[0]).hypot(next[1] - g[1]);
            g = next;
            if step <= SEIDEL_CONVERGED_MM {
                break;
            }
        }
        // Written so that NaN fails the test too.
        (step <= SEIDEL_SETTLED_MM).then(|| {
            self.thick.object_ray(
                [g[0], g[1], self.image_z],
                [exit[0], exit[1], self.thick.exit_pupil_z],
            )
        })
    }
}
