//! Built-in glass catalogue: Sellmeier coefficients as published in the makers' datasheets.

use super::Dispersion;
use crate::prescription::Problem;

/// One catalogue glass.
#[derive(Clone, Debug, PartialEq)]
pub struct CatalogGlass {
    pub name: &'static str,
    pub maker: &'static str,
    /// Datasheet the coefficients come from.
    pub datasheet: &'static str,
    /// Sellmeier B1..B3 and C1..C3 (C in um^2).
    pub b: [f64; 3],
    pub c: [f64; 3],
}

impl CatalogGlass {
    pub fn dispersion(&self) -> Dispersion {
        Dispersion::Sellmeier {
            b: self.b,
            c: self.c,
        }
    }
}

/// The catalogue, sorted by name.
pub const CATALOG: &[CatalogGlass] = &[CatalogGlass {
    name: "N-BK7",
    maker: "Schott",
    datasheet: "SCHOTT optical glass datasheet N-BK7 (517642.251)",
    b: [1.03961212, 0.231792344, 1.01046945],
    c: [0.00600069867, 0.0200179144, 103.560653],
}];

/// Canonical key: upper case, maker suffix and punctuation removed ("NSSK2_SCHOTT" -> "NSSK2").
fn key(name: &str) -> String {
    let upper = name.trim().to_ascii_uppercase();
    let stem = upper
        .split(['_', ':', ' '])
        .next()
        .unwrap_or_default()
        .to_string();
    let stem = if ["SCHOTT", "OHARA", "HOYA", "CDGM"]
        .iter()
        .any(|m| upper.ends_with(m))
        && stem != upper
    {
        stem
    } else {
        upper
    };
    stem.chars().filter(|c| c.is_ascii_alphanumeric()).collect()
}

/// Finds a glass by name, tolerant of case, dashes and a maker suffix.
pub fn lookup(name: &str) -> Result<&'static CatalogGlass, Problem> {
    let wanted = key(name);
    CATALOG
        .iter()
        .find(|g| key(g.name) == wanted)
        .ok_or_else(|| Problem::UnknownGlass {
            name: name.to_string(),
            suggestions: suggestions(name),
        })
}

/// Up to three catalogue names closest to `name` by edit distance.
pub fn suggestions(name: &str) -> Vec<String> {
    let wanted = key(name);
    let mut scored: Vec<(usize, &str)> = CATALOG
        .iter()
        .map(|g| (edit_distance(&key(g.name), &wanted), g.name))
        .collect();
    scored.sort();
    scored
        .into_iter()
        .take_while(|(d, _)| *d <= 3)
        .take(3)
        .map(|(_, n)| n.to_string())
        .collect()
}

fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for j in 0..b.len() {
            let cur = row[j + 1];
            row[j + 1] = if ca == b[j] {
                prev
            } else {
                1 + prev.min(row[j]).min(row[j + 1])
            };
            prev = cur;
        }
    }
    row[b.len()]
}
