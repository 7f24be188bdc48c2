//! The lens prescription as the source describes it: surfaces in order, media, stop, provenance.
//!
//! Plain data, serialisable to the canonical RON format. Nothing here resolves glass names or
//! knows about wavelengths; [`crate::system::LensSystem`] does that after validation.

use super::{Location, PrescriptionError};
use serde::{Deserialize, Serialize};

/// A whole lens prescription: the surface table plus where it came from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Prescription {
    pub provenance: Provenance,
    /// Medium the object sits in (air for almost every camera lens).
    #[serde(default = "Medium::air")]
    pub object_medium: Medium,
    /// Surfaces 1..N in the order light meets them from the object side.
    pub surfaces: Vec<Surface>,
}

/// What the source says about the lens; kept so reports can cite it and compare against it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Provenance {
    pub title: String,
    /// Patent, book page or file the table was taken from.
    #[serde(default)]
    pub source: Option<String>,
    #[serde(default)]
    pub design_wavelength_nm: Option<f64>,
    /// Focal length the source claims (mm); compared with the computed EFL, never used for it.
    #[serde(default)]
    pub claimed_focal_length_mm: Option<f64>,
    #[serde(default)]
    pub claimed_f_number: Option<f64>,
    /// Half-field angle the source claims (degrees; a title's "22deg HFOV", half of a stated
    /// full field of view): the design field where the file states no fields.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub claimed_half_field_deg: Option<f64>,
    #[serde(default)]
    pub notes: Option<String>,
    /// The conditions the source analyses the lens under (Zemax and CODE V files state them);
    /// the defaults of `analyze` and the other commands where the user gives no flag.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub conditions: Option<Conditions>,
}

/// One of the conditions a file states, as an error about it names it (see
/// [`crate::prescription::SourceMap::condition_lines`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum StatedCondition {
    /// The object distance (Zemax's object `DISZ`, CODE V's `SO` thickness).
    Object,
    /// The aperture (`ENPD`/`FNUM`/`OBNA`, `EPD`/`FNO`/`NAO`).
    Aperture,
    /// The fields (`XFLN`/`YFLN`, `XAN`/`YAN`/`XOB`/`YOB`/...).
    Fields,
}

impl StatedCondition {
    pub const ALL: [StatedCondition; 3] = [
        StatedCondition::Object,
        StatedCondition::Aperture,
        StatedCondition::Fields,
    ];

    pub fn describe(self) -> &'static str {
        match self {
            StatedCondition::Object => "object distance",
            StatedCondition::Aperture => "aperture",
            StatedCondition::Fields => "fields",
        }
    }
}

/// Object, aperture, fields and wavelengths as the source file states them, in mm and nm.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Conditions {
    /// Distance from the object to surface 1; None for an object at infinity.
    #[serde(default)]
    pub object_distance_mm: Option<f64>,
    #[serde(default)]
    pub aperture: Option<ApertureSpec>,
    #[serde(default)]
    pub fields: Option<FieldSpec>,
    /// Wavelengths in nm with their weights (same length); `primary` indexes both.
    #[serde(default)]
    pub wavelengths_nm: Vec<f64>,
    #[serde(default)]
    pub wavelength_weights: Vec<f64>,
    #[serde(default)]
    pub primary: Option<usize>,
    /// How the source aims the rays of a pupil coordinate (Zemax `RAIM`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ray_aiming: Option<RayAiming>,
}

/// How a relative pupil coordinate (px, py) becomes a real ray.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum RayAiming {
    /// Towards (px, py) of the paraxial entrance pupil, as if the lens were not in the way
    /// (Zemax with ray aiming off or paraxial, optiland's default): quick, and exact where the
    /// pupil has no aberration.
    #[default]
    Paraxial,
    /// The real ray through (px, py) of the stop surface, scaled to the radius the axial beam
    /// fills there (Zemax's real ray aiming): the stop is filled at every field even where the
    /// entrance pupil is distorted or moves with the field (wide-angle lenses, high-NA
    /// objectives).
    Real,
}

impl RayAiming {
    pub fn name(self) -> &'static str {
        match self {
            RayAiming::Paraxial => "paraxial",
            RayAiming::Real => "real",
        }
    }
}

/// How the source sizes the beam.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum ApertureSpec {
    /// Entrance-pupil diameter, mm (Zemax `ENPD`, CODE V `EPD`).
    EntrancePupilDiameter(f64),
    /// Image-space F-number EFL / EPD, the paraxial infinite-conjugate one at any object
    /// distance (Zemax `FNUM`, CODE V `FNO` with the object at infinity).
    FNumber(f64),
    /// Working F-number 1 / (2 n' u') of the paraxial marginal ray from the axial object point,
    /// at the file's object distance (CODE V `FNO` with a finite object, as rayoptics reads it).
    WorkingFNumber(f64),
    /// Object-space numerical aperture n sin u (Zemax `OBNA`, CODE V `NAO`).
    ObjectNumericalAperture(f64),
    /// The stop's own semi-aperture sets the beam (Zemax "float by stop size").
    FloatByStop,
}

/// What a field value measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum FieldKind {
    /// Object-space angle in degrees.
    AngleDeg,
    /// Object height, mm (finite objects).
    ObjectHeight,
    /// Paraxial image height, mm.
    ParaxialImageHeight,
    /// Real image height, mm.
    RealImageHeight,
}

/// The field points of the source: x and y components (same length) of one kind, with weights.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FieldSpec {
    pub kind: FieldKind,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    #[serde(default)]
    pub weights: Vec<f64>,
}

impl FieldSpec {
    /// The largest radial field value, hypot(x, y) over the points (0 for none).
    pub fn max_radial(&self) -> f64 {
        self.x
            .iter()
            .zip(&self.y)
            .map(|(x, y)| x.hypot(*y))
            .fold(0.0, f64::max)
    }
}

/// One refracting, reflecting (medium [`Medium::Mirror`]) or dummy surface and the gap after it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Surface {
    pub shape: Shape,
    /// Axial distance from this vertex to the next one (mm); for the last surface, to the film.
    /// Negative while light travels towards -z, after an odd number of mirrors (the sign
    /// convention of Zemax and CODE V files).
    pub thickness: f64,
    /// Medium after this surface.
    pub medium: Medium,
    /// Clear semi-aperture (mm). For the stop surface this is the stop radius wide open.
    pub semi_aperture: f64,
    /// Present when this surface is the aperture stop.
    #[serde(default)]
    pub stop: Option<StopShape>,
    /// Radius (mm) of a central obscuration: the surface blocks rays that meet it closer to
    /// the axis than this (a secondary mirror's shadow, a hole in a primary mirror).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub obscuration: Option<f64>,
}

impl Surface {
    /// A surface that is neither the stop nor obscured; mark the stop with struct update
    /// syntax, as in `Surface { stop: Some(StopShape::Circle), ..Surface::open(...) }`.
    pub fn open(shape: Shape, thickness: f64, medium: Medium, semi_aperture: f64) -> Surface {
        Surface {
            shape,
            thickness,
            medium,
            semi_aperture,
            stop: None,
            obscuration: None,
        }
    }
}

/// Surface profile. Curvature c = 1/R (plane: 0); positive when the centre of curvature lies at
/// larger z.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Shape {
    Plane,
    Sphere {
        curvature: f64,
    },
    /// Conic of revolution, conic constant k (k = 0 sphere, k = -1 paraboloid).
    Conic {
        curvature: f64,
        conic: f64,
    },
    /// Even asphere: conic base plus `coefficients[i] * r^(2i + 2)`, i.e. terms r^2 .. r^20.
    EvenAsphere {
        curvature: f64,
        conic: f64,
        coefficients: Vec<f64>,
    },
    /// Odd asphere (Zemax `ODDASPHE`): conic base plus `coefficients[i] * r^(i + 1)`, i.e.
    /// terms r, r^2, r^3, .. r^10. Terms of odd power make the sag a function of r that is not
    /// one of r^2: an r term puts a cone point on the vertex, and neither it nor the r^3 term has
    /// a counterpart in paraxial or third-order (Seidel) optics, which see only the r^2 and r^4
    /// terms; the exact trace follows the whole sag.
    OddAsphere {
        curvature: f64,
        conic: f64,
        coefficients: Vec<f64>,
    },
    /// A plane that images perfectly, an ideal thin lens of focal length `focal_length` (mm) in
    /// air (Zemax's paraxial surface): a ray meeting it at height (x, y) with direction
    /// tangents t = (dx/dz, dy/dz) along its travel leaves with t - (x, y) / f. The map is linear
    /// in height, so every object plane images onto a plane without aberration: its Seidel
    /// contributions are zero. It lies in air with air after it.
    IdealLens {
        focal_length: f64,
    },
}

/// Most aspheric terms accepted: r^2 through r^20 on an even asphere, r through r^10 on an odd
/// one.
pub const MAX_ASPHERE_TERMS: usize = 10;

/// The lowest refractive index a medium may have. Indices are relative to air, as the glass
/// catalogues and the design programs give them, so a vacuum or helium space in a lens has an
/// index just below 1 (vacuum is 1/1.000293 = 0.999707 at the d line; a lithography patent
/// writes 0.999712); air's refractivity stays below 1e-3 at every wavelength a lens transmits,
/// so nothing real lies below 1 - 1e-3.
pub const MIN_INDEX: f64 = 0.999;

/// The highest refractive index a medium may have: above every optical material (germanium is
/// about 4.0 in the infrared, lead telluride about 5.6), so a larger one is a typo or an
/// exponent gone wrong, whose rays and Seidel sums would not be numbers.
pub const MAX_INDEX: f64 = 10.0;

/// The smallest Abbe number a model glass may have (0 stands for no dispersion). The model's
/// index falls by (nd - 1) / vd times 1.06 from the d line to 1 um, so below 1 it drops under
/// air's before the near infrared; the most dispersive optical materials have vd near 10 to 20,
/// and a tiny vd (a typo, an exponent gone wrong) makes the model's dispersion overflow, its
/// indices not numbers.
pub const MIN_ABBE_NUMBER: f64 = 1.0;

/// Wavelength used when a lens states no design wavelength (helium d line, nm).
pub const DEFAULT_WAVELENGTH_NM: f64 = 587.56;

impl Shape {
    /// A sphere from a radius as printed in a table; radius 0 or infinite means plane.
    pub fn from_radius(radius: f64) -> Shape {
        if radius == 0.0 || radius.is_infinite() {
            Shape::Plane
        } else {
            Shape::Sphere {
                curvature: 1.0 / radius,
            }
        }
    }

    pub fn curvature(&self) -> f64 {
        match self {
            Shape::Plane | Shape::IdealLens { .. } => 0.0,
            Shape::Sphere { curvature }
            | Shape::Conic { curvature, .. }
            | Shape::EvenAsphere { curvature, .. }
            | Shape::OddAsphere { curvature, .. } => *curvature,
        }
    }

    pub fn conic(&self) -> f64 {
        match self {
            Shape::Plane | Shape::Sphere { .. } | Shape::IdealLens { .. } => 0.0,
            Shape::Conic { conic, .. }
            | Shape::EvenAsphere { conic, .. }
            | Shape::OddAsphere { conic, .. } => *conic,
        }
    }

    /// The aspheric coefficients as stored, for an even asphere on r^2, r^4, ... and for an odd
    /// one on r, r^2, r^3, ... ([`Shape::power_of_term`] names each one's power); empty for all
    /// other shapes.
    pub fn aspheric_coefficients(&self) -> &[f64] {
        match self {
            Shape::EvenAsphere { coefficients, .. } | Shape::OddAsphere { coefficients, .. } => {
                coefficients
            }
            _ => &[],
        }
    }

    /// The power of r that aspheric coefficient `i` multiplies: 2i + 2 on an even asphere, i + 1
    /// on an odd one.
    pub fn power_of_term(&self, i: usize) -> i32 {
        match self {
            Shape::OddAsphere { .. } => i as i32 + 1,
            _ => 2 * i as i32 + 2,
        }
    }

    /// The coefficient of r^`power` in the aspheric polynomial (0 where it has none).
    pub fn aspheric_term(&self, power: i32) -> f64 {
        let terms = self.aspheric_coefficients();
        (0..terms.len())
            .find(|&i| self.power_of_term(i) == power)
            .map_or(0.0, |i| terms[i])
    }

    /// The same kind of profile with its curvature and aspheric coefficients (each given with
    /// the power of r it multiplies) mapped; the conic constant, a ratio, is kept. An ideal
    /// lens's power 1/f, a reciprocal length like a curvature, is mapped as one.
    pub fn map_terms(
        &self,
        curvature: impl Fn(f64) -> f64,
        coefficient: impl Fn(i32, f64) -> f64,
    ) -> Shape {
        let mut mapped = self.clone();
        match &mut mapped {
            Shape::Plane => {}
            Shape::Sphere { curvature: c } | Shape::Conic { curvature: c, .. } => {
                *c = curvature(*c);
            }
            Shape::EvenAsphere {
                curvature: c,
                coefficients,
                ..
            }
            | Shape::OddAsphere {
                curvature: c,
                coefficients,
                ..
            } => {
                *c = curvature(*c);
                for (i, a) in coefficients.iter_mut().enumerate() {
                    *a = coefficient(self.power_of_term(i), *a);
                }
            }
            Shape::IdealLens { focal_length } => {
                *focal_length = 1.0 / curvature(1.0 / *focal_length);
            }
        }
        mapped
    }

    /// The same profile seen from its other side (reflected through its vertex plane): every
    /// sag negated, so the curvature and every aspheric coefficient change sign. An ideal lens
    /// converges (or diverges) from either side, so it stays as it is.
    pub fn mirrored(&self) -> Shape {
        match self {
            Shape::IdealLens { .. } => self.clone(),
            _ => self.map_terms(|c| -c, |_, a| -a),
        }
    }

    /// Power 1/f of an ideal lens (1/mm); 0 for every surface whose power comes from its
    /// curvature and the indices around it.
    pub fn ideal_power(&self) -> f64 {
        match self {
            Shape::IdealLens { focal_length } => 1.0 / focal_length,
            _ => 0.0,
        }
    }

    /// Radius of curvature; infinite for a plane.
    pub fn radius(&self) -> f64 {
        let c = self.curvature();
        if c == 0.0 { f64::INFINITY } else { 1.0 / c }
    }

    /// The height (mm) where the conic base ends, where [`Shape::sag`] stops being defined: a
    /// sphere at |R|, an ellipsoid (k > -1) at 1 / (|c| sqrt(1 + k)). None for a surface that
    /// goes on at every height (a plane, a paraboloid, a hyperboloid).
    ///
    /// ```
    /// use lensbake::prescription::Shape;
    ///
    /// assert_eq!(Shape::from_radius(-25.0).rim_radius(), Some(25.0));
    /// assert_eq!(Shape::Plane.rim_radius(), None);
    /// ```
    pub fn rim_radius(&self) -> Option<f64> {
        let rim_sq = (1.0 + self.conic()) * self.curvature().powi(2);
        (rim_sq > 0.0).then(|| 1.0 / rim_sq.sqrt())
    }

    /// Sag z(r) at radial height r, or None where the conic base is undefined (beyond its rim).
    pub fn sag(&self, r: f64) -> Option<f64> {
        let c = self.curvature();
        let r2 = r * r;
        let k = self.conic();
        let disc = 1.0 - (1.0 + k) * c * c * r2;
        if disc < 0.0 {
            return None;
        }
        // c r^2 / (1 + sqrt(...)) avoids the cancellation of (1 - sqrt(...)) / c near the axis.
        let base = c * r2 / (1.0 + disc.sqrt());
        let poly: f64 = (self.aspheric_coefficients().iter().enumerate())
            .map(|(i, a)| a * r.abs().powi(self.power_of_term(i)))
            .sum();
        Some(base + poly)
    }

    /// A bound on |[`Shape::sag`]| at every height up to `rim`: the conic part's magnitude
    /// grows with the height for every conic constant, and each polynomial term is at most its
    /// coefficient's magnitude times the rim's power. None where the conic part is undefined
    /// before the rim (there is no finite bound to give).
    pub fn sag_bound(&self, rim: f64) -> Option<f64> {
        let c = self.curvature();
        let r2 = rim * rim;
        let disc = 1.0 - (1.0 + self.conic()) * c * c * r2;
        if disc < 0.0 {
            return None;
        }
        let base = (c * r2 / (1.0 + disc.sqrt())).abs();
        let poly: f64 = (self.aspheric_coefficients().iter().enumerate())
            .map(|(i, a)| a.abs() * rim.abs().powi(self.power_of_term(i)))
            .sum();
        Some(base + poly).filter(|bound| bound.is_finite())
    }
}

/// Shape of the aperture stop's opening, for bokeh. Its size is the stop surface's semi-aperture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum StopShape {
    Circle,
    /// A polygonal diaphragm of `count` blades. `blade_curvature` bends each edge outward
    /// (0 = straight edges, 1 = edges on the circumscribed circle, i.e. a circle again).
    Blades {
        count: u32,
        rotation_deg: f64,
        blade_curvature: f64,
    },
}

/// Optical medium after a surface (or around the object).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Medium {
    /// Index exactly 1 at every wavelength (optical-design convention: indices relative to air).
    Air,
    /// A constant index, non-dispersive.
    Index(f64),
    /// A glass from the built-in catalogue, by name (e.g. "N-BK7").
    Glass(String),
    /// Sellmeier coefficients, wavelengths in micrometres: n^2 = 1 + sum B_i l^2 / (l^2 - C_i).
    Sellmeier { b: [f64; 3], c: [f64; 3] },
    /// The Laurent power series of SCHOTT's former catalogue, wavelengths in micrometres:
    /// n^2 = a0 + a1 l^2 + a2 / l^2 + a3 / l^4 + a4 / l^6 + a5 / l^8 (CODE V `LAU` private glasses).
    PowerSeries { a: [f64; 6] },
    /// A model glass from its d-line index and Abbe number (see [`crate::glass`] for the formula).
    Model { nd: f64, vd: f64 },
    /// Indices at listed wavelengths (nm, ascending), interpolated by a cubic spline and defined
    /// only between the first and last: a private glass (CODE V `PRV`).
    Table {
        wavelengths_nm: Vec<f64>,
        indices: Vec<f64>,
    },
    /// The surface reflects: light turns back into the medium it came from (Zemax `GLAS
    /// MIRROR`, CODE V `REFL`).
    Mirror,
}

impl Medium {
    pub fn air() -> Medium {
        Medium::Air
    }

    /// Whether the medium is air or an index of exactly 1 (used to describe the lens, not for optics).
    /// A mirror is not: what lies after it is the medium before it.
    pub fn is_air(&self) -> bool {
        matches!(self, Medium::Air) || matches!(self, Medium::Index(n) if *n == 1.0)
    }

    /// A short name for tables and listings: "air", "N-BK7", "n = 1.5", "mirror".
    pub fn describe(&self) -> String {
        match self {
            _ if self.is_air() => "air".into(),
            Medium::Air => "air".into(),
            Medium::Index(n) => format!("n = {n}"),
            Medium::Glass(name) => name.clone(),
            Medium::Sellmeier { .. } => "Sellmeier".into(),
            Medium::PowerSeries { .. } => "Laurent power series".into(),
            Medium::Model { nd, vd } => format!("model {nd}/{vd}"),
            Medium::Table { wavelengths_nm, .. } => format!(
                "table of {} indices, {}-{} nm",
                wavelengths_nm.len(),
                wavelengths_nm.first().copied().unwrap_or_default(),
                wavelengths_nm.last().copied().unwrap_or_default()
            ),
            Medium::Mirror => "mirror".into(),
        }
    }
}

impl Prescription {
    /// 0-based index of the stop surface, if exactly one surface is marked as stop.
    pub fn stop_index(&self) -> Option<usize> {
        let mut stops = self
            .surfaces
            .iter()
            .enumerate()
            .filter(|(_, s)| s.stop.is_some());
        match (stops.next(), stops.next()) {
            (Some((i, _)), None) => Some(i),
            _ => None,
        }
    }

    /// Whether 0-based surface `i` is a reference plane: a plane between equal media that is not
    /// a mirror, the stop or obscured. It bends and blocks no ray beyond its clear aperture, and
    /// the tracer meets it as a line meets a plane, wherever it lies along the ray, as
    /// OpticStudio traces a dummy surface; so it may sit inside a curved neighbour.
    pub fn is_reference_plane(&self, i: usize) -> bool {
        let s = &self.surfaces[i];
        let before = match i {
            0 => &self.object_medium,
            _ => &self.surfaces[i - 1].medium,
        };
        s.shape == Shape::Plane
            && s.medium != Medium::Mirror
            && s.medium == *before
            && s.stop.is_none()
            && s.obscuration.is_none()
    }

    /// The medium light travels in as it meets 0-based surface `i`: the one after the surface
    /// before, or, after a mirror, the one light met the mirror in.
    pub fn medium_before(&self, i: usize) -> &Medium {
        self.surfaces[..i]
            .iter()
            .rev()
            .map(|s| &s.medium)
            .find(|m| **m != Medium::Mirror)
            .unwrap_or(&self.object_medium)
    }

    /// Vertex z of every surface in the lens frame (surface 1 at z = 0).
    pub fn vertex_z(&self) -> Vec<f64> {
        let mut z = 0.0;
        self.surfaces
            .iter()
            .map(|s| {
                let here = z;
                z += s.thickness;
                here
            })
            .collect()
    }

    /// The sense along z (+1 or -1) in which light travels after each surface: -1 after an odd
    /// number of mirrors. The one place the turn at a mirror is counted.
    pub fn travel_after(&self) -> Vec<f64> {
        let mut sense = 1.0;
        self.surfaces
            .iter()
            .map(|s| {
                if s.medium == Medium::Mirror {
                    sense = -sense;
                }
                sense
            })
            .collect()
    }

    /// The same lens with each medium's index at `wavelength_nm` as a constant index (air and
    /// mirrors stay as they are), and that wavelength its design wavelength: the lens a
    /// monochromatic renderer, pbrt's file or a program without the glass catalogue takes. A
    /// medium without an index there is an error naming its surface (or the object space).
    ///
    /// ```
    /// use lensbake::prescription::Medium;
    ///
    /// let options = lensbake::prescription::formats::LoadOptions::default();
    /// let lens = lensbake::lenses::load("cooke-triplet", &options).unwrap();
    /// let at_d = lens.system.prescription.with_indices_at(587.5618).unwrap();
    /// assert!(matches!(at_d.surfaces[0].medium, Medium::Index(n) if (n - 1.6204).abs() < 1e-4));
    /// assert_eq!(at_d.provenance.design_wavelength_nm, Some(587.5618));
    /// ```
    pub fn with_indices_at(&self, wavelength_nm: f64) -> Result<Prescription, PrescriptionError> {
        crate::limits::check_wavelength(wavelength_nm)
            .map_err(|e| PrescriptionError::new(Location::default(), e.into()))?;
        let constant = |medium: &Medium, location: Location| match medium {
            Medium::Air | Medium::Index(_) | Medium::Mirror => Ok(medium.clone()),
            _ => crate::glass::Dispersion::of(medium)
                .and_then(|dispersion| dispersion.checked_index(wavelength_nm))
                .map(Medium::Index)
                .map_err(|problem| PrescriptionError::new(location, problem)),
        };
        let mut frozen = self.clone();
        frozen.object_medium = constant(
            &self.object_medium,
            Location::default().with_field("object_medium"),
        )?;
        for (i, surface) in frozen.surfaces.iter_mut().enumerate() {
            let location = Location::default().with_surface(i + 1).with_field("medium");
            surface.medium = constant(&surface.medium, location)?;
        }
        frozen.provenance.design_wavelength_nm = Some(wavelength_nm);
        Ok(frozen)
    }

    /// Distance from the first to the last vertex (excludes the gap to the film).
    pub fn total_track(&self) -> f64 {
        let n = self.surfaces.len();
        if n < 2 {
            return 0.0;
        }
        self.surfaces[..n - 1].iter().map(|s| s.thickness).sum()
    }
}
