//! Least-squares Zernike fits of a wavefront over the unit pupil.

use super::WaveError;
use super::pupil::WavefrontMap;
use serde::Serialize;

/// How terms are numbered and normalised.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ZernikeOrdering {
    /// University of Arizona "fringe" order (OpticStudio's Zernike Fringe), terms 1..=37:
    /// grouped by (n + |m|) / 2, then by falling |m|, cosine before sine, and term 37 the
    /// twelfth-order spherical. Unnormalised: each term peaks at 1 on the pupil edge.
    Fringe,
    /// Noll's order (OpticStudio's Zernike Standard): by n, then by rising |m|, even j the
    /// cosine, odd j the sine. Normalised to unit RMS over the pupil, so each coefficient is
    /// that term's RMS contribution.
    Standard,
}

/// The largest term index fitted in Noll's order (radial orders up to 20).
pub const MAX_TERMS: usize = 231;
/// The fringe set's size.
pub const FRINGE_TERMS: usize = 37;

/// One fitted term: its index in the chosen ordering, radial order n, azimuthal frequency m
/// (negative for the sine terms) and coefficient in waves.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ZernikeTerm {
    pub j: usize,
    pub n: u32,
    pub m: i32,
    pub waves: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ZernikeFit {
    pub ordering: ZernikeOrdering,
    pub terms: Vec<ZernikeTerm>,
    /// RMS of the wavefront minus the fit over the transmitted samples, waves.
    pub residual_rms_waves: f64,
}

impl ZernikeOrdering {
    /// (n, m) of term `j` (1-based), m < 0 for a sine term.
    pub fn indices(self, j: usize) -> (u32, i32) {
        match self {
            ZernikeOrdering::Fringe => fringe_indices(j),
            ZernikeOrdering::Standard => noll_indices(j),
        }
    }

    /// Term `j` at polar pupil point (rho, theta), theta from the x axis.
    pub fn value(self, j: usize, rho: f64, theta: f64) -> f64 {
        let (n, m) = self.indices(j);
        let radial = radial(n, m.unsigned_abs(), rho);
        let angular = match m.cmp(&0) {
            std::cmp::Ordering::Greater => (m as f64 * theta).cos(),
            std::cmp::Ordering::Less => (-m as f64 * theta).sin(),
            std::cmp::Ordering::Equal => 1.0,
        };
        let norm = match self {
            ZernikeOrdering::Fringe => 1.0,
            ZernikeOrdering::Standard => {
                let factor = if m == 0 { 1.0 } else { 2.0 };
                (factor * (n as f64 + 1.0)).sqrt()
            }
        };
        norm * radial * angular
    }
}

fn fringe_indices(j: usize) -> (u32, i32) {
    // The 37th term closes the printed set with twelfth-order spherical, out of the pattern.
    if j == FRINGE_TERMS {
        return (12, 0);
    }
    // Group k holds the 2k + 1 terms with (n + |m|) / 2 = k; groups 0..k-1 hold k² terms.
    let k = ((j - 1) as f64).sqrt().floor() as usize;
    let within = j - 1 - k * k;
    let abs_m = if within == 2 * k { 0 } else { k - within / 2 };
    (
        (2 * k - abs_m) as u32,
        signed_m(abs_m, within.is_multiple_of(2)),
    )
}

/// m with its sign: positive for the cosine term, negative for the sine.
fn signed_m(abs_m: usize, cosine: bool) -> i32 {
    match (abs_m, cosine) {
        (0, _) => 0,
        (m, true) => m as i32,
        (m, false) => -(m as i32),
    }
}

fn noll_indices(j: usize) -> (u32, i32) {
    let mut n = 0usize;
    while (n + 1) * (n + 2) / 2 < j {
        n += 1;
    }
    let k = j - n * (n + 1) / 2 - 1;
    let abs_m = if n.is_multiple_of(2) {
        2 * k.div_ceil(2)
    } else {
        2 * (k / 2) + 1
    };
    (n as u32, signed_m(abs_m, j.is_multiple_of(2)))
}

/// The radial polynomial R_n^m(rho).
fn radial(n: u32, m: u32, rho: f64) -> f64 {
    if (n - m) % 2 == 1 {
        return 0.0;
    }
    let factorial = |v: u32| (1..=v).map(f64::from).product::<f64>();
    (0..=(n - m) / 2)
        .map(|s| {
            let sign = if s % 2 == 0 { 1.0 } else { -1.0 };
            sign * factorial(n - s)
                / (factorial(s) * factorial((n + m) / 2 - s) * factorial((n - m) / 2 - s))
                * rho.powi((n - 2 * s) as i32)
        })
        .sum()
}

/// Fits terms 1..=`terms` of `ordering` to the transmitted samples of `map` by least squares
/// (singular value decomposition, so a vignetted pupil that makes terms alike still fits).
pub fn zernike_fit(
    map: &WavefrontMap,
    ordering: ZernikeOrdering,
    terms: usize,
) -> Result<ZernikeFit, WaveError> {
    let max = match ordering {
        ZernikeOrdering::Fringe => FRINGE_TERMS,
        ZernikeOrdering::Standard => MAX_TERMS,
    };
    if !(1..=max).contains(&terms) {
        return Err(WaveError::ZernikeTerms { terms, max });
    }
    let samples: Vec<(f64, f64, f64)> = map.transmitted().collect();
    if samples.len() < terms {
        return Err(WaveError::TooFewSamples {
            terms,
            valid: samples.len(),
        });
    }
    let design = nalgebra::DMatrix::from_fn(samples.len(), terms, |row, column| {
        let (x, y, _) = samples[row];
        ordering.value(column + 1, x.hypot(y), y.atan2(x))
    });
    let values = nalgebra::DVector::from_iterator(samples.len(), samples.iter().map(|s| s.2));
    let coefficients = design
        .clone()
        .svd(true, true)
        .solve(&values, 1e-12)
        .map_err(|_| WaveError::TooFewSamples {
            terms,
            valid: samples.len(),
        })?;
    let residual = values - design * &coefficients;
    Ok(ZernikeFit {
        ordering,
        terms: coefficients
            .iter()
            .enumerate()
            .map(|(i, &waves)| {
                let (n, m) = ordering.indices(i + 1);
                ZernikeTerm {
                    j: i + 1,
                    n,
                    m,
                    waves,
                }
            })
            .collect(),
        residual_rms_waves: (residual.norm_squared() / samples.len() as f64).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fringe_order_matches_the_printed_table() {
        let expected = [
            (0, 0),
            (1, 1),
            (1, -1),
            (2, 0),
            (2, 2),
            (2, -2),
            (3, 1),
            (3, -1),
            (4, 0),
            (3, 3),
            (3, -3),
            (4, 2),
            (4, -2),
            (5, 1),
            (5, -1),
            (6, 0),
        ];
        for (j, nm) in expected.into_iter().enumerate() {
            assert_eq!(fringe_indices(j + 1), nm, "fringe term {}", j + 1);
        }
        assert_eq!(fringe_indices(26), (5, 5));
        assert_eq!(fringe_indices(35), (9, -1));
        assert_eq!(fringe_indices(36), (10, 0));
        assert_eq!(fringe_indices(37), (12, 0));
    }

    #[test]
    fn noll_order_matches_nolls_table() {
        let expected = [
            (0, 0),
            (1, 1),
            (1, -1),
            (2, 0),
            (2, -2),
            (2, 2),
            (3, -1),
            (3, 1),
            (3, -3),
            (3, 3),
            (4, 0),
        ];
        for (j, nm) in expected.into_iter().enumerate() {
            assert_eq!(noll_indices(j + 1), nm, "Noll term {}", j + 1);
        }
    }

    #[test]
    fn standard_terms_have_unit_rms_and_are_orthogonal() {
        // Midpoint rule on a fine polar grid over the unit disk.
        let (rings, spokes) = (400, 256);
        let mut gram = [[0.0; 6]; 6];
        let mut area = 0.0;
        for i in 0..rings {
            let rho = (i as f64 + 0.5) / rings as f64;
            for k in 0..spokes {
                let theta = std::f64::consts::TAU * (k as f64 + 0.5) / spokes as f64;
                let weight = rho;
                area += weight;
                let z: Vec<f64> = (1..=6)
                    .map(|j| ZernikeOrdering::Standard.value(j + 5, rho, theta))
                    .collect();
                for a in 0..6 {
                    for b in 0..6 {
                        gram[a][b] += weight * z[a] * z[b];
                    }
                }
            }
        }
        for (a, row) in gram.iter().enumerate() {
            for (b, value) in row.iter().enumerate() {
                let expected = if a == b { 1.0 } else { 0.0 };
                assert!(
                    (value / area - expected).abs() < 1e-4,
                    "<Z{},Z{}>",
                    a + 6,
                    b + 6
                );
            }
        }
    }
}
