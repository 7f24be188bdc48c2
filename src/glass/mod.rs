//! Optical media: dispersion formulas and the built-in glass catalogue.
//!
//! Wavelengths are in nm at every public function; the Sellmeier formula itself works in
//! micrometres, as the glass makers' datasheets do.

mod catalog;

pub use catalog::{CATALOGUES, CatalogGlass, catalog, lookup, lookup_in, suggestions};

use crate::prescription::{Medium, Problem};

/// Fraunhofer d line (helium), the reference for nd and the Abbe number.
pub const D_LINE_NM: f64 = 587.5618;
/// Fraunhofer F line (hydrogen).
pub const F_LINE_NM: f64 = 486.1327;
/// Fraunhofer C line (hydrogen).
pub const C_LINE_NM: f64 = 656.2725;

/// Base wavelength (µm) and constant of Buchdahl's chromatic coordinate as Robb and Mercado
/// chose them for the visible: w = (l - 0.574) / (1 + 2.5 (l - 0.574)).
const BUCHDAHL_BASE_UM: f64 = 0.574;
const BUCHDAHL_ALPHA: f64 = 2.5;

/// A medium with its dispersion resolved: index as a function of wavelength.
#[derive(Clone, Debug, PartialEq)]
pub enum Dispersion {
    Constant(f64),
    /// Sellmeier n^2 = 1 + sum B l^2 / (l^2 - C), l in micrometres: three terms for the glass
    /// makers' catalogues, four for crystals measured that finely (CaF2 after Daimon and
    /// Masumura).
    Sellmeier {
        b: Vec<f64>,
        c: Vec<f64>,
    },
    /// Two-term Cauchy n = A + B / l^2 (l in micrometres), fitted so that n(d) = nd and
    /// n(F) - n(C) = (nd - 1) / vd: the simplest formula that honours both numbers a model glass
    /// gives. It is smooth and monotonic over the visible range, which is all a model glass claims.
    Cauchy {
        a: f64,
        b: f64,
    },
    /// The Schott power series (Zemax "Schott" formula), l in micrometres:
    /// n^2 = A0 + A1 l^2 + A2 l^-2 + A3 l^-4 + A4 l^-6 + A5 l^-8. Older catalogues (HIKARI among
    /// them) publish their glasses in this form.
    PowerSeries {
        a: [f64; 6],
    },
    /// HIKARI's power series, l in micrometres:
    /// n^2 = A0 + A1 l^2 + A2 l^4 + A3 l^-2 + A4 l^-4 + ... + A8 l^-12.
    ExtendedPowerSeries {
        a: [f64; 9],
    },
    /// Buchdahl's quadratic model n = n0 + nu1 w + nu2 w^2 in the chromatic coordinate
    /// w = dl / (1 + 2.5 dl), dl = l - 0.574 (l in micrometres): the form in which Robb and
    /// Mercado (Appl. Opt. 22, 1198, 1983) fitted the 1980 catalogues over the visible, to a
    /// few 1e-5. Glasses withdrawn before the makers published Sellmeier data are held this way.
    Buchdahl {
        n0: f64,
        nu: [f64; 2],
    },
    /// Indices measured at listed wavelengths (nm, ascending), joined by a natural cubic spline
    /// that passes through every point; defined only between the first and last wavelength. A
    /// private glass given as a table (CODE V `PRV`, a datasheet without a formula) is this.
    Tabulated {
        points: Vec<(f64, f64)>,
        /// Second derivatives of the spline at the points.
        curvature: Vec<f64>,
    },
}

/// How far beyond its first and last wavelength a table is continued, as a fraction of the
/// span it covers: a table from 400 to 900 nm is read from 375 to 925 nm. OpticStudio and CODE V
/// both extrapolate a glass's index beyond the wavelengths its data cover (with a warning), and
/// the files that rely on it go a few nm past the end; far beyond, a continued table is no
/// measurement, so it is refused there.
pub const TABLE_EXTRAPOLATION: f64 = 0.05;

/// Most points a tabulated medium may list; bounds the allocation a corrupt file can cause.
pub const MAX_TABULATED_POINTS: usize = 256;

impl Dispersion {
    /// Resolves a medium, looking up catalogue glasses by name.
    pub fn of(medium: &Medium) -> Result<Dispersion, Problem> {
        Ok(match medium {
            Medium::Air => Dispersion::Constant(1.0),
            Medium::Index(n) => Dispersion::Constant(*n),
            Medium::Glass(name) => lookup(name)?.dispersion(),
            Medium::Sellmeier { b, c } => Dispersion::Sellmeier {
                b: b.to_vec(),
                c: c.to_vec(),
            },
            Medium::PowerSeries { a } => Dispersion::PowerSeries { a: *a },
            Medium::Model { nd, vd } => Dispersion::model(*nd, *vd),
            Medium::Table {
                wavelengths_nm,
                indices,
            } => Dispersion::tabulated(
                wavelengths_nm
                    .iter()
                    .copied()
                    .zip(indices.iter().copied())
                    .collect(),
            )?,
            // LensSystem gives a mirror the medium before it; only an object space that is a
            // mirror gets here.
            Medium::Mirror => {
                return Err(Problem::Unsupported(
                    "a mirror has no index of its own; it reflects back into the medium before it"
                        .into(),
                ));
            }
        })
    }

    /// A tabulated medium from (wavelength nm, index) points. Refused unless the wavelengths are
    /// finite, positive and strictly ascending and every index is finite and at least 1.
    pub fn tabulated(points: Vec<(f64, f64)>) -> Result<Dispersion, Problem> {
        let bad = |reason: String| Err(Problem::BadIndexTable { reason });
        if points.is_empty() || points.len() > MAX_TABULATED_POINTS {
            return bad(format!(
                "{} points; between 1 and {MAX_TABULATED_POINTS} are needed",
                points.len()
            ));
        }
        for (nm, n) in &points {
            if !(nm.is_finite() && *nm > 0.0 && n.is_finite() && *n >= 1.0) {
                return bad(format!(
                    "point ({nm} nm, {n}) is not a wavelength and an index"
                ));
            }
        }
        if points.windows(2).any(|w| w[1].0 <= w[0].0) {
            return bad("the wavelengths must strictly ascend".into());
        }
        let curvature = natural_spline(&points);
        Ok(Dispersion::Tabulated { points, curvature })
    }

    /// The model glass for (nd, vd); a vd of zero or infinity means no dispersion.
    pub fn model(nd: f64, vd: f64) -> Dispersion {
        if !(vd.is_finite() && vd > 0.0) {
            return Dispersion::Constant(nd);
        }
        let inv_sq = |nm: f64| 1.0 / (nm * 1e-3).powi(2);
        let b = (nd - 1.0) / vd / (inv_sq(F_LINE_NM) - inv_sq(C_LINE_NM));
        Dispersion::Cauchy {
            a: nd - b * inv_sq(D_LINE_NM),
            b,
        }
    }

    /// Refractive index at `wavelength_nm`.
    pub fn index(&self, wavelength_nm: f64) -> f64 {
        let l2 = (wavelength_nm * 1e-3).powi(2);
        match self {
            Dispersion::Constant(n) => *n,
            Dispersion::Sellmeier { b, c } => {
                let sum: f64 = b.iter().zip(c).map(|(b, c)| b * l2 / (l2 - c)).sum();
                (1.0 + sum).sqrt()
            }
            Dispersion::Cauchy { a, b } => a + b / l2,
            Dispersion::PowerSeries { a } => {
                let inv = 1.0 / l2;
                let n2 = a[0] + a[1] * l2 + inv * (a[2] + inv * (a[3] + inv * (a[4] + inv * a[5])));
                n2.sqrt()
            }
            Dispersion::ExtendedPowerSeries { a } => {
                let inv = 1.0 / l2;
                let falling = a[3..]
                    .iter()
                    .rev()
                    .fold(0.0, |acc, coefficient| inv * (coefficient + acc));
                (a[0] + l2 * (a[1] + l2 * a[2]) + falling).sqrt()
            }
            Dispersion::Buchdahl { n0, nu } => {
                let shift_um = wavelength_nm * 1e-3 - BUCHDAHL_BASE_UM;
                let w = shift_um / (1.0 + BUCHDAHL_ALPHA * shift_um);
                n0 + w * (nu[0] + w * nu[1])
            }
            Dispersion::Tabulated { points, curvature } => {
                spline_value(points, curvature, wavelength_nm)
            }
        }
    }

    /// The open wavelength interval (nm) in which the formula can describe the medium it was
    /// fitted to. Each Sellmeier term B l^2 / (l^2 - C) is an absorption resonance with a pole at
    /// l = sqrt(C); across a pole the formula swings through infinity and no longer describes the
    /// glass (short of the pole it may even give a plausible-looking index), so its range is the
    /// gap between the resonances that holds the d line. The other formulas have no pole: (0, inf).
    pub fn resonance_window_nm(&self) -> (f64, f64) {
        if let Dispersion::Tabulated { points, .. } = self {
            let last = points.len() - 1;
            return (points[0].0, points[last].0);
        }
        let Dispersion::Sellmeier { b, c } = self else {
            return (0.0, f64::INFINITY);
        };
        let d_line_sq = (D_LINE_NM * 1e-3).powi(2);
        let mut window = (0.0, f64::INFINITY);
        for (b, c) in b.iter().zip(c) {
            if *b == 0.0 || !(*c > 0.0) {
                continue;
            }
            let pole_nm = c.sqrt() * 1e3;
            if *c < d_line_sq {
                window.0 = f64::max(window.0, pole_nm);
            } else {
                window.1 = f64::min(window.1, pole_nm);
            }
        }
        window
    }

    /// The wavelengths (nm) at which a table's index is its end segments continued (outside its
    /// points, within [`TABLE_EXTRAPOLATION`] of its span beyond each end): `Some(table's first
    /// and last wavelength)` there, `None` inside the table, beyond the margin, and for every
    /// formula that is not a table.
    pub fn extrapolated_range_nm(&self, wavelength_nm: f64) -> Option<(f64, f64)> {
        let Dispersion::Tabulated { points, .. } = self else {
            return None;
        };
        let (low, high) = (points[0].0, points[points.len() - 1].0);
        let margin = TABLE_EXTRAPOLATION * (high - low);
        let beyond = (low - margin..low).contains(&wavelength_nm)
            || (wavelength_nm > high && wavelength_nm <= high + margin);
        beyond.then_some((low, high))
    }

    /// Refractive index at `wavelength_nm`, or [`Problem::WavelengthOutOfRange`] where the
    /// formula does not describe a transparent medium there: outside
    /// [`Dispersion::resonance_window_nm`] (a table: outside its points by more than
    /// [`TABLE_EXTRAPOLATION`] of its span; see [`Dispersion::extrapolated_range_nm`]), or an
    /// index that is not finite or is below vacuum's ([`crate::prescription::MIN_INDEX`]:
    /// indices are relative to air).
    ///
    /// The catalogue stores no datasheet validity range, so a wavelength inside the window may
    /// still lie beyond what the maker measured; every catalogue glass is tested to give a normal
    /// glass index over 380-780 nm.
    ///
    /// ```
    /// use lensbake::glass::Dispersion;
    ///
    /// // A table from 400 to 900 nm is continued 25 nm (5% of its span) beyond each end.
    /// let table = Dispersion::tabulated(vec![(400.0, 1.53), (650.0, 1.52), (900.0, 1.515)]).unwrap();
    /// assert!(table.checked_index(920.0).is_ok());
    /// assert_eq!(table.extrapolated_range_nm(920.0), Some((400.0, 900.0)));
    /// assert!(table.checked_index(930.0).is_err());
    /// ```
    pub fn checked_index(&self, wavelength_nm: f64) -> Result<f64, Problem> {
        let (low, high) = self.resonance_window_nm();
        let n = self.index(wavelength_nm);
        // A table's window is closed: its end points are measurements, not poles.
        let inside = match self {
            Dispersion::Tabulated { .. } => {
                (wavelength_nm >= low && wavelength_nm <= high)
                    || self.extrapolated_range_nm(wavelength_nm).is_some()
            }
            _ => wavelength_nm > low && wavelength_nm < high,
        };
        if inside && (crate::prescription::MIN_INDEX..=crate::prescription::MAX_INDEX).contains(&n)
        {
            Ok(n)
        } else {
            Err(Problem::WavelengthOutOfRange { nm: wavelength_nm })
        }
    }

    /// Whether the index changes with wavelength.
    pub fn disperses(&self) -> bool {
        match self {
            Dispersion::Constant(_) => false,
            Dispersion::Tabulated { points, .. } => points.windows(2).any(|w| w[0].1 != w[1].1),
            _ => true,
        }
    }
}

/// Second derivatives of the natural cubic spline through `points` (zero at both ends).
fn natural_spline(points: &[(f64, f64)]) -> Vec<f64> {
    let n = points.len();
    let mut second = vec![0.0; n];
    if n < 3 {
        return second;
    }
    // Tridiagonal system for the interior second derivatives (Thomas algorithm).
    let mut diagonal = vec![0.0; n];
    let mut rhs = vec![0.0; n];
    for i in 1..n - 1 {
        let (h0, h1) = (points[i].0 - points[i - 1].0, points[i + 1].0 - points[i].0);
        let slope_change =
            (points[i + 1].1 - points[i].1) / h1 - (points[i].1 - points[i - 1].1) / h0;
        diagonal[i] = 2.0 * (h0 + h1);
        rhs[i] = 6.0 * slope_change;
        if i > 1 {
            let factor = h0 / diagonal[i - 1];
            diagonal[i] -= factor * h0;
            rhs[i] -= factor * rhs[i - 1];
        }
    }
    for i in (1..n - 1).rev() {
        let h1 = points[i + 1].0 - points[i].0;
        second[i] = (rhs[i] - h1 * second[i + 1]) / diagonal[i];
    }
    second
}

/// The spline through `points` at `x`; outside the table, the straight line that continues it
/// (a natural spline's second derivative is zero at its ends, so the line meets it smoothly).
/// Callers that need the range use [`Dispersion::checked_index`].
fn spline_value(points: &[(f64, f64)], second: &[f64], x: f64) -> f64 {
    let last = points.len() - 1;
    if last == 0 {
        return points[0].1;
    }
    if x < points[0].0 || x > points[last].0 {
        let (end, other) = if x < points[0].0 {
            (0, 1)
        } else {
            (last, last - 1)
        };
        let (lower, upper) = (end.min(other), end.max(other));
        let h = points[upper].0 - points[lower].0;
        let chord = (points[upper].1 - points[lower].1) / h;
        // S' at the lower end (M = 0 there) and at the upper end (M = 0 there).
        let slope = if end == lower {
            chord - h * second[upper] / 6.0
        } else {
            chord + h * second[lower] / 6.0
        };
        return points[end].1 + slope * (x - points[end].0);
    }
    let upper = points.iter().position(|p| p.0 >= x).unwrap_or(last).max(1);
    let lower = upper - 1;
    let h = points[upper].0 - points[lower].0;
    let a = (points[upper].0 - x) / h;
    let b = 1.0 - a;
    a * points[lower].1
        + b * points[upper].1
        + ((a * a * a - a) * second[lower] + (b * b * b - b) * second[upper]) * h * h / 6.0
}
