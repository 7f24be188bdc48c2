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
use crate::lrtf::bake::{fit_film_pupil, rear_search_radius, stopped_down};
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
        // Pupils scale with the stop, as 1 / f-number.
        crate::limits::check_f_number(f_number, wide_open)?;
        let thick = thick_model(&paraxial, wide_open / f_number)?;
        let z = paraxial.entrance_pupil.z;
        let radius = paraxial.first_order.efl / (2.0 * f_number);
        let thin = ParaxialLens {
            focal_length_mm: paraxial.first_order.efl,
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

    /// These models at another wavelength, with the same stop: thick from the paraxial data at
    /// `wavelength_nm` (focal length, principal planes, pupils), thin keeping its plane and
    /// aperture with the focal length at `wavelength_nm` (an ideal thin lens has its stop in
    /// the lens, so only its power disperses).
    pub fn at_wavelength(
        &self,
        system: &LensSystem,
        wavelength_nm: f64,
    ) -> Result<FirstOrderModels, RenderError> {
        let at = system.at_checked(wavelength_nm).map_err(paraxial_error)?;
        let paraxial = Paraxial::new(&at, &ParaxialOptions::default()).map_err(paraxial_error)?;
        let thick = thick_model(&paraxial, self.wide_open_f_number / self.f_number)?;
        let thin = ParaxialLens {
            focal_length_mm: paraxial.first_order.efl,
            ..self.thin.clone()
        };
        Ok(FirstOrderModels {
            thin,
            thick,
            wide_open_f_number: self.wide_open_f_number,
            f_number: self.f_number,
        })
    }
}

/// The thick model of `paraxial` with its pupils scaled by `pupil_scale` (the stop's).
fn thick_model(paraxial: &Paraxial, pupil_scale: f64) -> Result<ParaxialLens, RenderError> {
    let exit = paraxial.exit_pupil.as_ref().ok_or_else(|| {
        RenderError::InvalidSetting(
            "lens: the exit pupil is at infinity; thick and thin models need a finite one".into(),
        )
    })?;
    let first = &paraxial.first_order;
    Ok(ParaxialLens {
        focal_length_mm: first.efl,
        front_principal_z: first.z_front_principal,
        rear_principal_z: first.z_rear_principal,
        entrance_pupil_z: paraxial.entrance_pupil.z,
        entrance_pupil_radius_mm: paraxial.entrance_pupil.diameter / 2.0 * pupil_scale,
        exit_pupil_z: exit.z,
        exit_pupil_radius_mm: exit.diameter / 2.0 * pupil_scale,
    })
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
            layer: 0,
            film_z,
        })
    }

    /// This lens reading the table's layer baked at `wavelength_nm` (see [`layer_at`]); a
    /// one-layer table keeps its only layer, whatever wavelength it was baked at.
    pub fn with_wavelength(self, wavelength_nm: f64) -> Result<BakedLens, RenderError> {
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
pub fn layer_at(table: &LrtfTable, wavelength_nm: f64) -> Result<usize, RenderError> {
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
            RenderError::InvalidSetting(format!(
                "the table has no layer at {wavelength_nm} nm (baked at {} nm); rebake with \
                 --wavelengths-nm",
                baked.join(", ")
            ))
        })
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

/// Most a pupil circle may be widened for film points off the plane it was fitted on, as the
/// growth factor m of [`OffPlaneBound`] (the radius grows by at least 1 / (1 - m)): a sensor
/// tilted further is refused rather than sampled through a bound this loose.
pub const MAX_PUPIL_BOUND_GROWTH: f64 = 0.5;

/// A conservative pupil for film points off the plane the circles were fitted on.
///
/// A ray from a film point P off that plane is the same line as the ray from the point Q where
/// it crosses the plane, so its rear-plane point R lies in the circle of Q. Q moves from P's
/// projection by k |R - P| with k = |z_P - z_film| / (z_P - z_rear); the circles' centre
/// vector and radius are Lipschitz in Q (constant `lipschitz`, the interpolated table's largest
/// slopes, plus `centre_slack` = 2 |centre at radius 0|, which a fit leaves within rounding of
/// the axis), so with m = lipschitz k < 1 every passing R lies within
/// (radius(P) + m |centre(P) - P| + slack) / (1 - m) of P's own centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OffPlaneBound {
    pub lipschitz: f64,
    pub centre_slack: f64,
}

impl OffPlaneBound {
    /// The growth factor m for a film point at z `point_z`, the circles fitted on the plane
    /// `film_plane_z`, samples on the plane `pupil_z`.
    pub fn growth(&self, point_z: f64, film_plane_z: f64, pupil_z: f64) -> f64 {
        self.lipschitz * (point_z - film_plane_z).abs() / (point_z - pupil_z)
    }
}

impl PupilSampling {
    /// The off-plane bound of these circles (zero for a single circle: a paraxial exit pupil
    /// is the aperture itself, the same for every film point).
    pub fn off_plane_bound(&self) -> OffPlaneBound {
        let table = &self.circles;
        let n = table.circles.len();
        if n < 2 || table.max_film_radius <= 0.0 {
            return OffPlaneBound {
                lipschitz: 0.0,
                centre_slack: 0.0,
            };
        }
        let spacing = table.max_film_radius / (n - 1) as f64;
        let slope = |value: fn(&PupilCircle) -> f64| {
            table
                .circles
                .windows(2)
                .map(|w| (value(&w[1]) - value(&w[0])).abs() / spacing)
                .fold(0.0, f64::max)
        };
        OffPlaneBound {
            lipschitz: slope(|c| c.radius) + slope(|c| c.centre_x),
            centre_slack: 2.0 * table.circles[0].centre_x.abs(),
        }
    }

    /// The disc lens samples for `film` are drawn from, on the plane `self.z`: its centre
    /// (lens-frame x, y) and radius. `film_plane_z` is the plane the circles were fitted on;
    /// off it the circle grows by `bound` (see [`OffPlaneBound`]).
    pub fn disc_for(
        &self,
        bound: &OffPlaneBound,
        film: [f64; 3],
        film_plane_z: f64,
    ) -> ([f64; 2], f64) {
        let film_radius = film[0].hypot(film[1]);
        let azimuth = if film_radius > 0.0 {
            [film[0] / film_radius, film[1] / film_radius]
        } else {
            [1.0, 0.0]
        };
        let circle = self.circles.circle_at(film_radius);
        let centre = azimuth.map(|a| a * circle.centre_x);
        if film[2] == film_plane_z {
            return (centre, circle.radius);
        }
        let m = bound.growth(film[2], film_plane_z, self.z);
        let drift = (centre[0] - film[0]).hypot(centre[1] - film[1]);
        (
            centre,
            (circle.radius + m * drift + bound.centre_slack) / (1.0 - m),
        )
    }
}

/// Largest film radius on the plane `film_z` that the effective pupil must cover for a sensor
/// reaching `corner_radius` from the axis and `off_plane` mm off that plane: rays from its
/// points towards the rear search disc cross the plane within this radius (see
/// [`OffPlaneBound`]).
pub fn pupil_film_radius(
    system: &SystemAt,
    film_z: f64,
    corner_radius: f64,
    off_plane: f64,
) -> f64 {
    let depth = film_z - system.last_vertex_z();
    // A sensor reaching the rear plane is refused by `Camera::new`; the nearest film points
    // are the worst case, k = off / (depth - off).
    if off_plane <= 0.0 || off_plane >= depth {
        return corner_radius;
    }
    let k = off_plane / (depth - off_plane);
    corner_radius + k * (corner_radius + rear_search_radius(system))
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
