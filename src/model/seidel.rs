//! The Seidel model: the thick lens plus the third-order transverse aberration of the plane in
//! focus (after Asberg, seed 001 section 3.10).

use super::{FirstOrderModels, ModelError, ParaxialLens};
use crate::paraxial::{Field, ObjectPosition, Paraxial, ParaxialError, ParaxialOptions};
use crate::seidel::{Seidel, SeidelTerms};
use crate::system::{LensSystem, SystemAt};

/// The paraxial setup for an object in focus at `focus_mm` (None: infinity), wide open, at the
/// largest unvignetted field: the conjugate a [`SeidelLens`] is built for. A lens whose clear
/// apertures set no largest field (its one surface is the stop) is set up at the field
/// `analyze`'s rule gives it: the polynomial's aberration at an image point does not depend on
/// the field it is normalised at, since each coefficient scales as the power of h it carries.
pub fn paraxial_for(system: &SystemAt, focus_mm: Option<f64>) -> Result<Paraxial, ParaxialError> {
    let options = ParaxialOptions {
        object: ObjectPosition::in_focus(focus_mm),
        ..ParaxialOptions::default()
    };
    match Paraxial::new(system, &options) {
        Err(ParaxialError::UnlimitedField) => Paraxial::new(
            system,
            &ParaxialOptions {
                field: Field::Angle {
                    deg: crate::analysis::rule_field_deg(system),
                },
                ..options
            },
        ),
        result => result,
    }
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

/// Factors on each Seidel sum of a [`SeidelLens`], for effect (seed 004 section 5.3 asks for
/// aberrations an artist can turn up or down; seed 001's Asberg parameters are the five sums):
/// 1 is the lens as designed, 0 removes that aberration, 2 doubles it. With every factor 0 the
/// model is the thick (paraxial) lens.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AberrationScale {
    /// S_I.
    pub spherical: f64,
    /// S_II.
    pub coma: f64,
    /// S_III.
    pub astigmatism: f64,
    /// S_IV (the field curvature with S_III).
    pub petzval: f64,
    /// S_V.
    pub distortion: f64,
}

impl AberrationScale {
    /// The lens as designed.
    pub const AS_DESIGNED: AberrationScale = AberrationScale {
        spherical: 1.0,
        coma: 1.0,
        astigmatism: 1.0,
        petzval: 1.0,
        distortion: 1.0,
    };
    /// Every aberration removed: the paraxial lens.
    pub const NONE: AberrationScale = AberrationScale {
        spherical: 0.0,
        coma: 0.0,
        astigmatism: 0.0,
        petzval: 0.0,
        distortion: 0.0,
    };
    /// Names of the factors in the order of [`AberrationScale::from_array`].
    pub const NAMES: [&'static str; 5] =
        ["spherical", "coma", "astigmatism", "petzval", "distortion"];

    /// Largest factor accepted: beyond it the inverse map of the polynomial stops settling over
    /// most of the field of a fast lens.
    pub const MAX: f64 = 10.0;

    /// The factors in the order of [`AberrationScale::NAMES`]; refused unless each lies in
    /// -MAX..=MAX.
    ///
    /// ```
    /// use lensbake::model::AberrationScale;
    /// let scale = AberrationScale::from_array([2.0, 1.0, 1.0, 1.0, 0.0]).unwrap();
    /// assert_eq!(scale.spherical, 2.0);
    /// assert!(AberrationScale::from_array([f64::NAN, 1.0, 1.0, 1.0, 1.0]).is_err());
    /// ```
    pub fn from_array(factors: [f64; 5]) -> Result<AberrationScale, ModelError> {
        if let Some((name, bad)) = Self::NAMES
            .iter()
            .zip(factors)
            .find(|(_, f)| !(f.abs() <= Self::MAX))
        {
            return Err(ModelError::AberrationScale {
                name,
                factor: bad,
                max: Self::MAX,
            });
        }
        let [spherical, coma, astigmatism, petzval, distortion] = factors;
        Ok(AberrationScale {
            spherical,
            coma,
            astigmatism,
            petzval,
            distortion,
        })
    }

    pub fn to_array(self) -> [f64; 5] {
        [
            self.spherical,
            self.coma,
            self.astigmatism,
            self.petzval,
            self.distortion,
        ]
    }
}

impl Default for AberrationScale {
    fn default() -> AberrationScale {
        AberrationScale::AS_DESIGNED
    }
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
    /// Factors on the sums, for effect ([`AberrationScale::AS_DESIGNED`] from [`SeidelLens::new`]).
    pub scale: AberrationScale,
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
            scale: AberrationScale::AS_DESIGNED,
        }
    }

    /// This model with its sums scaled by `scale` (see [`AberrationScale`]).
    pub fn scaled(self, scale: AberrationScale) -> SeidelLens {
        SeidelLens { scale, ..self }
    }

    /// The model of `system` at its design wavelength for an object in focus at `focus_mm`
    /// (None: infinity), with `first_order`'s thick lens (its f-number).
    pub fn in_focus(
        system: &LensSystem,
        first_order: &FirstOrderModels,
        focus_mm: Option<f64>,
    ) -> Result<SeidelLens, ModelError> {
        let at = system.at(system.design_wavelength_nm());
        let paraxial = paraxial_for(&at, focus_mm)?;
        let lens = SeidelLens::new(&at, &paraxial, first_order.thick.clone());
        let usable = |v: f64| v.is_finite() && v != 0.0;
        if !(usable(lens.chief_image_height)
            && usable(lens.marginal_pupil_height)
            && usable(lens.n_u_image))
        {
            return Err(ModelError::SeidelDegenerate {
                chief_image_height: lens.chief_image_height,
                marginal_pupil_height: lens.marginal_pupil_height,
                n_u_image: lens.n_u_image,
            });
        }
        Ok(lens)
    }

    /// The polynomial's coefficients, from the sums times [`SeidelLens::scale`].
    pub fn coefficients(&self) -> TransverseCoefficients {
        let (s, f) = (&self.sums, &self.scale);
        let k = 1.0 / self.n_u_image;
        let astigmatism = f.astigmatism * s.astigmatism;
        let petzval = f.petzval * s.petzval;
        TransverseCoefficients {
            spherical: 0.5 * f.spherical * s.spherical * k,
            coma: 0.5 * f.coma * s.coma * k,
            sagittal: 0.5 * (astigmatism + petzval) * k,
            tangential: 0.5 * (3.0 * astigmatism + petzval) * k,
            distortion: 0.5 * f.distortion * s.distortion * k,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lenses;
    use crate::prescription::formats::LoadOptions;

    /// The double Gauss at its design wavelength, and its thick model wide open.
    fn dgauss() -> (SystemAt, ParaxialLens) {
        let lens = lenses::load("dgauss-50mm", &LoadOptions::default()).unwrap();
        let thick = FirstOrderModels::of(&lens.system, None).unwrap().thick;
        (lens.system.at(lens.system.design_wavelength_nm()), thick)
    }

    /// The double Gauss's Seidel model for an object at infinity, its transverse sums (the forms
    /// checked against CODE V) and the image point at the edge of its field.
    fn at_infinity() -> (SeidelLens, crate::seidel::TransverseAberrations, [f64; 2]) {
        let (at, thick) = dgauss();
        let paraxial = paraxial_for(&at, None).unwrap();
        let lens = SeidelLens::new(&at, &paraxial, thick);
        let edge = [0.0, lens.chief_image_height];
        (lens, Seidel::new(&at, &paraxial, None).transverse, edge)
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * (1.0 + b.abs())
    }

    #[test]
    fn seidel_aberration_reproduces_the_transverse_sums() {
        // At the pupil rim and the edge of the field, the polynomial must give back the transverse
        // forms already checked against CODE V: TSA on axis, TCO and TAS in the meridional plane
        // (their sum, since both act at y = 1), SAS across it, DST through the pupil centre.
        let (lens, t, edge) = at_infinity();
        assert!(close(lens.aberration([0.0, 0.0], [0.0, 1.0])[1], t.tsa));
        assert!(close(lens.aberration(edge, [0.0, 0.0])[1], t.dst));
        let meridional = lens.aberration(edge, [0.0, 1.0])[1];
        assert!(close(meridional, t.tsa + t.tco + t.tas + t.dst));
        let sagittal = lens.aberration(edge, [1.0, 0.0]);
        assert!(close(sagittal[0], t.tsa + t.sas));
        assert!(close(sagittal[1], t.tco / 3.0 + t.dst));
    }

    #[test]
    fn the_aberration_does_not_depend_on_the_field_it_is_normalised_at() {
        let (at, thick) = dgauss();
        let largest = paraxial_for(&at, None).unwrap();
        let at_largest = SeidelLens::new(&at, &largest, thick.clone());
        let small = Paraxial::new(
            &at,
            &ParaxialOptions {
                field: Field::Angle { deg: 3.0 },
                ..ParaxialOptions::default()
            },
        )
        .unwrap();
        let at_small = SeidelLens::new(&at, &small, thick);
        assert!(at_small.chief_image_height < 0.3 * at_largest.chief_image_height);
        let edge = at_largest.chief_image_height;
        for g in [
            [0.0, 0.0],
            [0.3 * edge, 0.0],
            [-0.2 * edge, 0.7 * edge],
            [0.0, edge],
        ] {
            for pupil in [[0.0, 1.0], [1.0, 0.0], [-0.6, 0.5], [0.0, 0.0]] {
                let a = at_largest.aberration(g, pupil);
                let b = at_small.aberration(g, pupil);
                for k in 0..2 {
                    assert!(
                        (a[k] - b[k]).abs() <= 1e-12 * (1.0 + a[k].abs()),
                        "{a:?} {b:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn each_factor_scales_its_own_transverse_sum_only() {
        // Doubling one sum doubles the transverse aberration it alone contributes (checked with
        // the terms the first test matches to CODE V) and leaves the others as they were.
        let (lens, t, edge) = at_infinity();
        let times = |k: usize, factor: f64| {
            let mut factors = [1.0; 5];
            factors[k] = factor;
            lens.clone()
                .scaled(AberrationScale::from_array(factors).unwrap())
        };
        assert!(close(
            times(0, 2.0).aberration([0.0, 0.0], [0.0, 1.0])[1],
            2.0 * t.tsa
        ));
        assert!(close(
            times(4, 2.0).aberration(edge, [0.0, 0.0])[1],
            2.0 * t.dst
        ));
        assert!(close(times(4, 0.0).aberration(edge, [0.0, 0.0])[1], 0.0));
        // Coma doubled: the meridional rim ray gains one more TCO, the rest unchanged.
        let meridional = times(1, 2.0).aberration(edge, [0.0, 1.0])[1];
        assert!(close(meridional, t.tsa + 2.0 * t.tco + t.tas + t.dst));
        // Astigmatism and Petzval off together: no field term in the sagittal fan.
        let flat = lens.clone().scaled(AberrationScale {
            astigmatism: 0.0,
            petzval: 0.0,
            ..AberrationScale::AS_DESIGNED
        });
        assert!(close(flat.aberration(edge, [1.0, 0.0])[0], t.tsa));
        // Factors of one are the lens as designed, bit for bit.
        let ones = lens.clone().scaled(AberrationScale::AS_DESIGNED);
        for g in [[0.0, 0.0], edge, [3.0, -2.0]] {
            for p in [[0.0, 1.0], [0.7, -0.2]] {
                assert_eq!(ones.aberration(g, p), lens.aberration(g, p));
            }
        }
    }

    #[test]
    fn with_every_factor_zero_the_model_is_the_thick_lens() {
        // Zero aberration: the inverse map returns the landing point itself, and the scene ray
        // is the thick model's for the same film-side ray (the film at the Gaussian image).
        let (at, thick) = dgauss();
        let paraxial = paraxial_for(&at, None).unwrap();
        let lens = SeidelLens::new(&at, &paraxial, thick.clone()).scaled(AberrationScale::NONE);
        for (film, pupil) in [
            ([0.0, 0.0], [3.0, 4.0]),
            ([12.0, -7.0], [-5.0, 2.0]),
            ([-15.0, 9.0], [0.5, -8.0]),
        ] {
            let film = [film[0], film[1], lens.image_z];
            let pupil = [pupil[0], pupil[1], thick.exit_pupil_z];
            let (origin, slope) = lens.object_ray(film, pupil).unwrap();
            let (thick_origin, thick_slope) = thick.object_ray(film, pupil);
            for k in 0..2 {
                assert!(
                    (slope[k] - thick_slope[k]).abs() < 1e-12,
                    "{slope:?} {thick_slope:?}"
                );
                assert!((origin[k] - thick_origin[k]).abs() < 1e-9, "{origin:?}");
            }
            let real = SeidelLens::new(&at, &paraxial, thick.clone())
                .object_ray(film, pupil)
                .unwrap()
                .1;
            assert!((real[0] - thick_slope[0]).abs() + (real[1] - thick_slope[1]).abs() > 1e-6);
        }
    }

    /// One refracting surface that is its own stop: no clear aperture limits the chief ray, so
    /// the lens has no largest field, yet it has a focal length, pupils and third-order sums.
    #[test]
    fn a_lens_whose_apertures_set_no_field_has_its_models() {
        let text = "(provenance: (title: \"one surface\", source: None, design_wavelength_nm: \
            None, claimed_focal_length_mm: None, claimed_f_number: None, notes: None), \
            object_medium: Air, surfaces: [(shape: Sphere(curvature: 0.02), thickness: 150.0, \
            medium: Index(1.5), semi_aperture: 10.0, stop: Some(Circle))])";
        let loaded = crate::prescription::formats::read_str(
            text,
            None,
            crate::prescription::formats::Format::Ron,
            &LoadOptions::default(),
        )
        .unwrap();
        let system = LensSystem::from_prescription(loaded.prescription).unwrap();
        let first_order = FirstOrderModels::of(&system, None).unwrap();
        // f' = n' / power = 1.5 / (0.5 * 0.02) = 150 mm; the stop at the vertex is both pupils.
        assert!((first_order.thick.focal_length_mm - 150.0).abs() < 1e-12);
        assert!((first_order.thick.exit_pupil_radius_mm - 10.0).abs() < 1e-12);
        let seidel = SeidelLens::in_focus(&system, &first_order, None).unwrap();
        assert!(seidel.chief_image_height != 0.0);
    }
}
