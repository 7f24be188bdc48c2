//! Third-order (Seidel) aberrations, surface by surface, from the paraxial marginal and chief
//! rays.
//!
//! Welford's sums in mm, with A = n i and Abar the refraction invariants of the marginal and
//! chief ray, H the Lagrange invariant and Δ(x) = x' - x across a surface:
//!
//! ```text
//! S_I   = -A^2 y Δ(u/n)          S_IV = -H^2 c Δ(1/n)
//! S_II  = -A Abar y Δ(u/n)       S_V  = -Abar [Abar^2 y Δ(1/n^2) - (H + Abar y) ybar c Δ(1/n)]
//! S_III = -Abar^2 y Δ(u/n)
//! ```
//!
//! Positive S_I is undercorrected spherical aberration. An aspheric surface adds
//! 8 a (n' - n) y^(4-j) ybar^j to S_I, S_II, S_III, S_V (j = 0, 1, 2, 3), where a is the r^4
//! sag coefficient beyond that of the vertex sphere. The colour terms (first order in the index
//! difference dn = n(short) - n(long)) are C_I = A y Δ(dn/n) and C_II = Abar y Δ(dn/n).

use crate::glass::{C_LINE_NM, F_LINE_NM};
use crate::paraxial::{Paraxial, ParaxialRay, paraxial_curvature};
use crate::prescription::Shape;
use crate::system::{LensSystem, SystemAt};
use serde::Serialize;
use std::iter::Sum;
use std::ops::Add;

/// The five Seidel sums (mm) of one surface or of the system.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SeidelTerms {
    /// Spherical aberration S_I.
    #[serde(rename = "S1")]
    pub spherical: f64,
    /// Coma S_II.
    #[serde(rename = "S2")]
    pub coma: f64,
    /// Astigmatism S_III.
    #[serde(rename = "S3")]
    pub astigmatism: f64,
    /// Petzval curvature S_IV.
    #[serde(rename = "S4")]
    pub petzval: f64,
    /// Distortion S_V.
    #[serde(rename = "S5")]
    pub distortion: f64,
}

impl SeidelTerms {
    pub fn as_array(&self) -> [f64; 5] {
        [
            self.spherical,
            self.coma,
            self.astigmatism,
            self.petzval,
            self.distortion,
        ]
    }

    /// Transverse forms in the image, for an image-space index `n_image` and marginal slope
    /// `u_image` (negative for a converging beam).
    pub fn transverse(&self, n_image: f64, u_image: f64) -> TransverseAberrations {
        let k = 1.0 / (2.0 * n_image * u_image);
        TransverseAberrations {
            tsa: k * self.spherical,
            tco: 3.0 * k * self.coma,
            tas: k * (3.0 * self.astigmatism + self.petzval),
            sas: k * (self.astigmatism + self.petzval),
            ptb: k * self.petzval,
            dst: k * self.distortion,
        }
    }

    /// Wavefront coefficients in waves of `wavelength_nm`.
    pub fn wavefront(&self, wavelength_nm: f64) -> WavefrontCoefficients {
        let per_wave = 1.0 / (wavelength_nm * 1e-6);
        WavefrontCoefficients {
            w040: self.spherical / 8.0 * per_wave,
            w131: self.coma / 2.0 * per_wave,
            w222: self.astigmatism / 2.0 * per_wave,
            w220: (self.petzval + self.astigmatism) / 4.0 * per_wave,
            w311: self.distortion / 2.0 * per_wave,
        }
    }
}

impl Add for SeidelTerms {
    type Output = SeidelTerms;
    fn add(self, o: SeidelTerms) -> SeidelTerms {
        SeidelTerms {
            spherical: self.spherical + o.spherical,
            coma: self.coma + o.coma,
            astigmatism: self.astigmatism + o.astigmatism,
            petzval: self.petzval + o.petzval,
            distortion: self.distortion + o.distortion,
        }
    }
}

impl Sum for SeidelTerms {
    fn sum<I: Iterator<Item = SeidelTerms>>(iter: I) -> SeidelTerms {
        iter.fold(SeidelTerms::default(), Add::add)
    }
}

/// Third-order aberrations as transverse ray errors in the paraxial image plane (mm), named
/// as CODE V prints them: spherical, tangential coma, tangential and sagittal astigmatic focus
/// (each including Petzval), Petzval blur and distortion.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "UPPERCASE")]
pub struct TransverseAberrations {
    pub tsa: f64,
    pub tco: f64,
    pub tas: f64,
    pub sas: f64,
    pub ptb: f64,
    pub dst: f64,
}

/// Wavefront aberration coefficients in waves, at the edge of pupil and field.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "UPPERCASE")]
pub struct WavefrontCoefficients {
    pub w040: f64,
    pub w131: f64,
    pub w222: f64,
    pub w220: f64,
    pub w311: f64,
}

/// Primary colour sums (mm).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ColourTerms {
    /// Axial colour C_I.
    #[serde(rename = "C1")]
    pub axial: f64,
    /// Lateral colour C_II.
    #[serde(rename = "C2")]
    pub lateral: f64,
}

impl ColourTerms {
    /// Transverse forms (mm): axial colour as the marginal-ray height difference short minus
    /// long wavelength in the image plane, and lateral colour as the chief-ray height
    /// difference (CODE V AX and LAT).
    pub fn transverse(&self, n_image: f64, u_image: f64) -> TransverseColour {
        let k = 1.0 / (n_image * u_image);
        TransverseColour {
            ax: k * self.axial,
            lat: k * self.lateral,
        }
    }
}

impl Add for ColourTerms {
    type Output = ColourTerms;
    fn add(self, o: ColourTerms) -> ColourTerms {
        ColourTerms {
            axial: self.axial + o.axial,
            lateral: self.lateral + o.lateral,
        }
    }
}

impl Sum for ColourTerms {
    fn sum<I: Iterator<Item = ColourTerms>>(iter: I) -> ColourTerms {
        iter.fold(ColourTerms::default(), Add::add)
    }
}

/// Transverse primary colour (mm).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "UPPERCASE")]
pub struct TransverseColour {
    pub ax: f64,
    pub lat: f64,
}

/// Index differences dn = n(short) - n(long) of every medium, for the colour terms.
#[derive(Clone, Debug, PartialEq)]
pub struct IndexDifferences {
    pub short_nm: f64,
    pub long_nm: f64,
    /// Object space.
    pub object: f64,
    /// The medium after each surface.
    pub after: Vec<f64>,
}

impl IndexDifferences {
    /// Differences between the same lens frozen at a short and a long wavelength.
    pub fn between(short: &SystemAt, long: &SystemAt) -> IndexDifferences {
        IndexDifferences {
            short_nm: short.wavelength_nm,
            long_nm: long.wavelength_nm,
            object: short.object_index - long.object_index,
            after: short
                .surfaces
                .iter()
                .zip(&long.surfaces)
                .map(|(s, l)| s.index_after - l.index_after)
                .collect(),
        }
    }

    /// nF - nC for a lens whose media disperse; None when every index is constant.
    pub fn fraunhofer(system: &LensSystem) -> Option<IndexDifferences> {
        system
            .disperses()
            .then(|| IndexDifferences::between(&system.at(F_LINE_NM), &system.at(C_LINE_NM)))
    }

    fn before(&self, surface: usize) -> f64 {
        if surface == 0 {
            self.object
        } else {
            self.after[surface - 1]
        }
    }
}

/// One surface's contributions.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SurfaceSeidel {
    /// 1-based surface number.
    pub surface: usize,
    #[serde(flatten)]
    pub terms: SeidelTerms,
    /// The part of `terms` due to the aspheric departure (zero for spheres and planes).
    pub aspheric: SeidelTerms,
    pub transverse: TransverseAberrations,
    /// c Δ(1/n), 1/mm (CODE V PTZ); n' times the sum is the Petzval surface curvature.
    pub ptz: f64,
    pub colour: Option<ColourTerms>,
    pub transverse_colour: Option<TransverseColour>,
}

impl SurfaceSeidel {
    /// The contributions without their image-space forms.
    pub fn contributions(&self) -> SurfaceTerms {
        SurfaceTerms {
            surface: self.surface,
            terms: self.terms,
            aspheric: self.aspheric,
            ptz: self.ptz,
            colour: self.colour,
        }
    }
}

/// Seidel sums of a system for one paraxial setup.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Seidel {
    pub wavelength_nm: f64,
    pub surfaces: Vec<SurfaceSeidel>,
    pub sums: SeidelTerms,
    pub transverse: TransverseAberrations,
    pub wavefront: WavefrontCoefficients,
    /// Sum of the per-surface c Δ(1/n) (CODE V PTZ), 1/mm.
    pub ptz: f64,
    /// Present when index differences were given.
    pub colour: Option<ColourTerms>,
    pub transverse_colour: Option<TransverseColour>,
    /// Wavelengths (nm) the index differences were taken between, short then long.
    pub colour_wavelengths_nm: Option<[f64; 2]>,
}

/// One surface's third-order contributions, the same in a focal and an afocal system (the
/// image-space forms that divide by the image-space marginal slope are [`SurfaceSeidel`]'s).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SurfaceTerms {
    /// 1-based surface number.
    pub surface: usize,
    #[serde(flatten)]
    pub terms: SeidelTerms,
    /// The part of `terms` due to the aspheric departure (zero for spheres and planes).
    pub aspheric: SeidelTerms,
    /// c Δ(1/n), 1/mm (CODE V PTZ).
    pub ptz: f64,
    pub colour: Option<ColourTerms>,
}

/// Every surface's contributions for a `marginal` and a `chief` paraxial ray of `system` whose
/// Lagrange invariant is `lagrange_invariant`; `colour` adds C_I and C_II.
pub fn surface_terms(
    system: &SystemAt,
    marginal: &ParaxialRay,
    chief: &ParaxialRay,
    lagrange_invariant: f64,
    colour: Option<&IndexDifferences>,
) -> Vec<SurfaceTerms> {
    let h = lagrange_invariant;
    system
        .path()
        .zip(marginal.surfaces.iter().zip(&chief.surfaces))
        .map(|((i, surface, n, n_after), (m, c))| {
            let curvature = paraxial_curvature(&surface.shape);
            let delta_u_n = m.u_after / n_after - m.u_before / n;
            let delta_inv_n = 1.0 / n_after - 1.0 / n;
            let delta_inv_n2 = 1.0 / (n_after * n_after) - 1.0 / (n * n);
            let (a, abar, y, ybar) = (m.incidence, c.incidence, m.y, c.y);
            let aspheric = aspheric_terms(&surface.shape, n_after - n, y, ybar);
            // An ideal lens images every plane perfectly (Shape::IdealLens): no aberration.
            let terms = if matches!(surface.shape, Shape::IdealLens { .. }) {
                SeidelTerms::default()
            } else {
                SeidelTerms {
                    spherical: -a * a * y * delta_u_n,
                    coma: -a * abar * y * delta_u_n,
                    astigmatism: -abar * abar * y * delta_u_n,
                    petzval: -h * h * curvature * delta_inv_n,
                    distortion: -abar
                        * (abar * abar * delta_inv_n2 * y
                            - (h + abar * y) * ybar * curvature * delta_inv_n),
                } + aspheric
            };
            let colour = colour.map(|dn| {
                let delta_dn_n = dn.after[i] / n_after - dn.before(i) / n;
                ColourTerms {
                    axial: a * y * delta_dn_n,
                    lateral: abar * y * delta_dn_n,
                }
            });
            SurfaceTerms {
                surface: i + 1,
                terms,
                aspheric,
                ptz: curvature * delta_inv_n,
                colour,
            }
        })
        .collect()
}

impl Seidel {
    /// Surface contributions and sums for the marginal and chief rays of `paraxial`, which
    /// must come from `system`. `colour` adds C_I and C_II.
    pub fn new(
        system: &SystemAt,
        paraxial: &Paraxial,
        colour: Option<&IndexDifferences>,
    ) -> Seidel {
        let n_image = system.image_index();
        let u_image = paraxial.marginal.image_slope();
        let surfaces: Vec<SurfaceSeidel> = surface_terms(
            system,
            &paraxial.marginal,
            &paraxial.chief,
            paraxial.lagrange_invariant,
            colour,
        )
        .into_iter()
        .map(|s| SurfaceSeidel {
            surface: s.surface,
            terms: s.terms,
            aspheric: s.aspheric,
            transverse: s.terms.transverse(n_image, u_image),
            ptz: s.ptz,
            colour: s.colour,
            transverse_colour: s.colour.map(|c| c.transverse(n_image, u_image)),
        })
        .collect();
        let sums: SeidelTerms = surfaces.iter().map(|s| s.terms).sum();
        let colour_sums: Option<ColourTerms> =
            colour.map(|_| surfaces.iter().filter_map(|s| s.colour).sum());
        Seidel {
            wavelength_nm: system.wavelength_nm,
            sums,
            transverse: sums.transverse(n_image, u_image),
            wavefront: sums.wavefront(system.wavelength_nm),
            ptz: surfaces.iter().map(|s| s.ptz).sum(),
            colour: colour_sums,
            transverse_colour: colour_sums.map(|c| c.transverse(n_image, u_image)),
            colour_wavelengths_nm: colour.map(|dn| [dn.short_nm, dn.long_nm]),
            surfaces,
        }
    }
}

/// r^4 sag coefficient beyond the vertex sphere's: the conic adds k c^3 / 8 and an asphere its
/// r^4 term, while an r^2 term changes the vertex sphere itself (c + 2 a1). An odd asphere's r
/// and r^3 terms make the wavefront odd in the aperture, which no third-order term describes:
/// they are left out here and only the exact trace sees them.
pub fn aspheric_r4_departure(shape: &Shape) -> f64 {
    match shape {
        Shape::Plane | Shape::Sphere { .. } | Shape::IdealLens { .. } => 0.0,
        Shape::Conic { .. } | Shape::EvenAsphere { .. } | Shape::OddAsphere { .. } => {
            let c = shape.curvature();
            let vertex = paraxial_curvature(shape);
            (1.0 + shape.conic()) * c.powi(3) / 8.0 + shape.aspheric_term(4) - vertex.powi(3) / 8.0
        }
    }
}

fn aspheric_terms(shape: &Shape, delta_n: f64, y: f64, ybar: f64) -> SeidelTerms {
    let g = 8.0 * aspheric_r4_departure(shape) * delta_n;
    if g == 0.0 {
        return SeidelTerms::default();
    }
    SeidelTerms {
        spherical: g * y.powi(4),
        coma: g * y.powi(3) * ybar,
        astigmatism: g * y * y * ybar * ybar,
        petzval: 0.0,
        distortion: g * y * ybar.powi(3),
    }
}
