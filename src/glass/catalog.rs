//! Built-in glass catalogues: dispersion coefficients as the glass makers publish them.
//!
//! The data live in `src/glass/data/*.tsv` (one glass a row: name, formula, coefficients, the
//! datasheet's nd and vd, the span of wavelengths the maker measured), written from the makers'
//! own catalogue spreadsheets by `tools/glass_catalogs.py`; `src/glass/data/README.md` names each
//! file's origin and date. They are embedded in the binary and parsed once, on first use.
//!
//! Names repeat across makers (HIKARI and SCHOTT both once sold an SK16), so every glass belongs
//! to one catalogue, and a lookup says which catalogues it prefers: a lens file's own list (Zemax
//! `GCAT`), else [`CATALOGUES`] in order. A maker suffix (`SK16_HIKARI`) picks one catalogue.

use super::Dispersion;
use crate::prescription::Problem;
use std::sync::LazyLock;

/// One catalogue glass.
#[derive(Clone, Debug, PartialEq)]
pub struct CatalogGlass {
    pub name: &'static str,
    /// The catalogue it belongs to, as lens files name it ("SCHOTT", "OHARA", ..., "MISC").
    pub maker: &'static str,
    /// Where the coefficients come from (file, edition).
    pub source: &'static str,
    /// d-line index and Abbe number as the datasheet prints them.
    pub nd: f64,
    pub vd: f64,
    pub formula: Dispersion,
    /// Shortest and longest wavelength (nm) at which the maker lists a measured index, where
    /// the data file says.
    pub measured_nm: Option<(f64, f64)>,
    /// From a 1980 catalogue (a glass withdrawn before its maker published Sellmeier data): a
    /// name resolves to it only when no current catalogue holds that name, as a design program
    /// searching the makers' current catalogues would never find it.
    pub withdrawn: bool,
}

impl CatalogGlass {
    pub fn dispersion(&self) -> Dispersion {
        self.formula.clone()
    }

    /// The six-digit glass code: nd and vd to three digits each (1.51680, 64.17 -> "517642").
    pub fn glass_code(&self) -> String {
        let nd_digits = ((self.nd - 1.0) * 1000.0).round() as i64 % 1000;
        let vd_digits = (self.vd * 10.0).round() as i64;
        format!("{nd_digits:03}{vd_digits:03}")
    }

    /// Citation, e.g. "SCHOTT N-BK7 (517642), SCHOTT catalogue from the maker's spreadsheet ...".
    pub fn datasheet(&self) -> String {
        format!(
            "{} {} ({}), {}",
            self.maker,
            self.name,
            self.glass_code(),
            self.source
        )
    }

    /// The name that selects this glass whatever catalogues a lookup prefers: the bare name when
    /// no other catalogue has a glass of that name, else `NAME_MAKER`.
    pub fn unambiguous_name(&self) -> String {
        let key = glass_key(self.name).key;
        let homonyms = catalog()
            .iter()
            .filter(|g| g.maker != self.maker && glass_key(g.name).key == key)
            .count();
        if homonyms == 0 {
            self.name.to_string()
        } else {
            format!("{}_{}", self.name, self.maker)
        }
    }
}

/// The catalogues in the order a lookup searches them when the lens file states none.
pub const CATALOGUES: &[&str] = &[
    "SCHOTT", "OHARA", "HOYA", "CDGM", "HIKARI", "SUMITA", "MISC",
];

/// (catalogue, embedded data file, whether its glasses are withdrawn ones from 1980). A
/// catalogue may span several files.
const DATA: &[(&str, &str, bool)] = &[
    ("SCHOTT", include_str!("data/schott.tsv"), false),
    ("SCHOTT", include_str!("data/schott-legacy.tsv"), false),
    ("SCHOTT", include_str!("data/schott-1980.tsv"), true),
    ("OHARA", include_str!("data/ohara.tsv"), false),
    ("OHARA", include_str!("data/ohara-low-tg.tsv"), false),
    ("OHARA", include_str!("data/ohara-1980.tsv"), true),
    ("HOYA", include_str!("data/hoya.tsv"), false),
    ("HOYA", include_str!("data/hoya-1980.tsv"), true),
    ("CDGM", include_str!("data/cdgm.tsv"), false),
    ("HIKARI", include_str!("data/hikari.tsv"), false),
    ("HIKARI", include_str!("data/hikari-legacy.tsv"), false),
    ("SUMITA", include_str!("data/sumita.tsv"), false),
    ("MISC", include_str!("data/misc.tsv"), false),
];

static CATALOG: LazyLock<Vec<CatalogGlass>> = LazyLock::new(|| {
    let mut glasses = Vec::new();
    for (maker, text, withdrawn) in DATA {
        parse_file(maker, text, *withdrawn, &mut glasses)
            .unwrap_or_else(|e| panic!("embedded glass data for {maker}: {e}"));
    }
    glasses.sort_by(|a, b| {
        (glass_key(a.name).key, a.withdrawn, rank(a.maker)).cmp(&(
            glass_key(b.name).key,
            b.withdrawn,
            rank(b.maker),
        ))
    });
    glasses
});

/// Every catalogue glass, sorted by name; homonyms current before withdrawn, then in [`CATALOGUES`] order.
pub fn catalog() -> &'static [CatalogGlass] {
    &CATALOG
}

fn rank(maker: &str) -> usize {
    CATALOGUES
        .iter()
        .position(|m| *m == maker)
        .unwrap_or(CATALOGUES.len())
}

/// Parses one data file: a first comment line that names the source, a column header, then
/// `name formula coefficients nd vd min_nm max_nm [source]` separated by tabs.
fn parse_file(
    maker: &'static str,
    text: &'static str,
    withdrawn: bool,
    out: &mut Vec<CatalogGlass>,
) -> Result<(), String> {
    let mut lines = text.lines();
    let source = lines
        .next()
        .and_then(|l| l.strip_prefix("# "))
        .ok_or("the first line must be `# <source>`")?;
    for line in lines.filter(|l| !l.starts_with('#') && !l.trim().is_empty()) {
        let columns: Vec<&'static str> = line.split('\t').collect();
        if !(7..=8).contains(&columns.len()) {
            return Err(format!("expected 7 or 8 columns: {line}"));
        }
        let number = |text: &str| {
            text.trim()
                .parse::<f64>()
                .map_err(|_| format!("`{text}` is not a number in: {line}"))
        };
        let coefficients = columns[2]
            .split_whitespace()
            .map(number)
            .collect::<Result<Vec<f64>, String>>()?;
        let formula = formula(columns[1], &coefficients).ok_or_else(|| {
            format!(
                "formula `{}` with {} coefficients in: {line}",
                columns[1],
                coefficients.len()
            )
        })?;
        let measured_nm = match (columns[5].trim(), columns[6].trim()) {
            ("", "") => None,
            (low, high) => Some((number(low)?, number(high)?)),
        };
        out.push(CatalogGlass {
            name: columns[0],
            maker,
            source: columns.get(7).copied().unwrap_or(source),
            nd: number(columns[3])?,
            vd: number(columns[4])?,
            formula,
            measured_nm,
            withdrawn,
        });
    }
    Ok(())
}

fn formula(kind: &str, c: &[f64]) -> Option<Dispersion> {
    Some(match (kind, c.len()) {
        ("sellmeier3", 6) | ("sellmeier4", 8) => {
            let (b, c) = c.split_at(c.len() / 2);
            Dispersion::Sellmeier {
                b: b.to_vec(),
                c: c.to_vec(),
            }
        }
        ("schott6", 6) => Dispersion::PowerSeries {
            a: c.try_into().ok()?,
        },
        ("hikari9", 9) => Dispersion::ExtendedPowerSeries {
            a: c.try_into().ok()?,
        },
        ("buchdahl2", 3) => Dispersion::Buchdahl {
            n0: c[0],
            nu: [c[1], c[2]],
        },
        ("tabulated", n) if n >= 4 && n % 2 == 0 => {
            Dispersion::tabulated(c.chunks(2).map(|p| (p[0], p[1])).collect()).ok()?
        }
        _ => return None,
    })
}

/// A glass name reduced for matching: upper case, punctuation dropped, maker suffix split off.
struct GlassKey {
    key: String,
    maker: Option<&'static str>,
}

/// The suffix lens files add to a moulding glass's name (`L-TIM28_MOLD`) for the glass as a
/// moulded lens has it. None of the catalogues held here publishes data of its own for such a
/// variant (moulding's cooling shifts the index a little, by an amount the moulder sets), so the
/// name reads as its base glass, whose data are the maker's measurements of the block.
const MOULDED_SUFFIX: &str = "_MOLD";

fn glass_key(name: &str) -> GlassKey {
    let mut upper = name.trim().to_ascii_uppercase();
    if let Some(base) = upper.strip_suffix(MOULDED_SUFFIX).filter(|b| !b.is_empty()) {
        upper = base.to_string();
    }
    let (stem, maker) = match upper.rsplit_once(['_', ':', ' ']) {
        Some((stem, suffix)) => match CATALOGUES.iter().find(|m| **m == suffix) {
            Some(maker) => (stem, Some(*maker)),
            None => (upper.as_str(), None),
        },
        None => (upper.as_str(), None),
    };
    GlassKey {
        key: stem.chars().filter(char::is_ascii_alphanumeric).collect(),
        maker,
    }
}

/// Finds a glass by name in the default catalogue order; see [`lookup_in`].
pub fn lookup(name: &str) -> Result<&'static CatalogGlass, Problem> {
    lookup_in(name, &[])
}

/// Finds a glass by name, tolerant of case, dashes, a maker suffix and a moulding suffix
/// (`_MOLD`, read as the base glass). A maker suffix must match
/// the glass's catalogue, so "SK16_SCHOTT" never resolves to HIKARI SK16. Among glasses of one
/// name, a current glass wins over a withdrawn 1980 one, then the first catalogue of `preferred`
/// (case-insensitive) that holds one, then [`CATALOGUES`] order. A name holding a control
/// character names no glass: the key's tolerance is for spelling, not for bytes a terminal acts on.
pub fn lookup_in(name: &str, preferred: &[String]) -> Result<&'static CatalogGlass, Problem> {
    if name.chars().any(char::is_control) {
        return Err(Problem::UnknownGlass {
            name: name.to_string(),
            suggestions: Vec::new(),
        });
    }
    let wanted = glass_key(name);
    let preference = |g: &CatalogGlass| {
        preferred
            .iter()
            .position(|p| p.eq_ignore_ascii_case(g.maker))
            .unwrap_or(preferred.len())
    };
    catalog()
        .iter()
        .filter(|g| {
            glass_key(g.name).key == wanted.key && wanted.maker.is_none_or(|m| g.maker == m)
        })
        .min_by_key(|g| (g.withdrawn, preference(g), rank(g.maker)))
        .ok_or_else(|| Problem::UnknownGlass {
            name: name.to_string(),
            suggestions: suggestions(name),
        })
}

/// Up to three catalogue names closest to `name` by edit distance (at most 3 edits), from every
/// catalogue, each spelt so that it selects that glass.
pub fn suggestions(name: &str) -> Vec<String> {
    let wanted = glass_key(name).key;
    let mut scored: Vec<(usize, usize, &CatalogGlass)> = catalog()
        .iter()
        .map(|g| {
            (
                edit_distance(&glass_key(g.name).key, &wanted),
                rank(g.maker),
                g,
            )
        })
        .filter(|(d, _, _)| *d <= 3)
        .collect();
    scored.sort_by_key(|(d, r, g)| (*d, *r, g.name));
    scored
        .into_iter()
        .take(3)
        .map(|(_, _, g)| g.unambiguous_name())
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
