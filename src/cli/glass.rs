//! `lensbake glass ...`: list the built-in glass catalogues and show one glass.

use anyhow::bail;
use clap::Subcommand;
use lensbake::glass::{CATALOGUES, CatalogGlass, Dispersion, catalog, lookup};
use std::fmt::Write as _;

#[derive(Subcommand, Debug)]
pub enum GlassCommand {
    /// List the catalogue glasses: name, catalogue, nd, vd.
    List {
        /// Only this catalogue (SCHOTT, OHARA, HOYA, CDGM, HIKARI, SUMITA, MISC).
        #[arg(long, value_name = "CATALOG")]
        catalog: Option<String>,
    },
    /// Show one glass: indices at the standard lines, Abbe number, formula and source. A maker
    /// suffix picks one catalogue (SK16_HIKARI).
    Show {
        /// The glass's name, as `glass list` prints it.
        #[arg(value_name = "NAME")]
        name: String,
    },
}

/// The Fraunhofer lines `show` prints, short to long.
const LINES: [(&str, f64); 5] = [
    ("g", 435.8343),
    ("F", lensbake::glass::F_LINE_NM),
    ("e", 546.074),
    ("d", lensbake::glass::D_LINE_NM),
    ("C", lensbake::glass::C_LINE_NM),
];

pub fn run(command: GlassCommand) -> anyhow::Result<()> {
    match command {
        GlassCommand::List { catalog: wanted } => {
            let wanted = wanted.map(|c| c.to_ascii_uppercase());
            if let Some(name) = &wanted
                && !CATALOGUES.contains(&name.as_str())
            {
                bail!(
                    "unknown catalogue `{name}`; the catalogues are {}",
                    CATALOGUES.join(", ")
                );
            }
            let mut out = String::new();
            for glass in catalog()
                .iter()
                .filter(|g| wanted.as_deref().is_none_or(|w| g.maker == w))
            {
                let _ = writeln!(
                    out,
                    "{:<16} {:<7} nd {:.6}  vd {:>6.2}{}",
                    glass.unambiguous_name(),
                    glass.maker,
                    glass.nd,
                    glass.vd,
                    if glass.withdrawn {
                        "  withdrawn (1980 catalogue fit)"
                    } else {
                        ""
                    }
                );
            }
            print!("{out}");
            Ok(())
        }
        GlassCommand::Show { name } => {
            print!("{}", describe(lookup(&name)?));
            Ok(())
        }
    }
}

fn describe(glass: &CatalogGlass) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{} ({}), glass code {}",
        glass.name,
        glass.maker,
        glass.glass_code()
    );
    let n = |nm: f64| glass.formula.checked_index(nm).ok();
    for (line, nm) in LINES {
        match n(nm) {
            Some(index) => {
                let _ = writeln!(out, "  n{line:<2} ({nm:>8.4} nm)  {index:.6}");
            }
            None => {
                let _ = writeln!(out, "  n{line:<2} ({nm:>8.4} nm)  outside the data");
            }
        }
    }
    let d = lensbake::glass::D_LINE_NM;
    if let (Some(nd), Some(nf), Some(nc)) = (
        n(d),
        n(lensbake::glass::F_LINE_NM),
        n(lensbake::glass::C_LINE_NM),
    ) {
        let _ = writeln!(
            out,
            "  Vd {:.3} from the formula; datasheet nd {}, Vd {}",
            (nd - 1.0) / (nf - nc),
            glass.nd,
            glass.vd
        );
    }
    let _ = writeln!(out, "  formula: {}", formula(&glass.formula));
    if let Some((low, high)) = glass.measured_nm {
        let _ = writeln!(out, "  index data from {low} to {high} nm");
    }
    let _ = writeln!(out, "  source: {}", glass.source);
    out
}

fn formula(dispersion: &Dispersion) -> String {
    let list = |values: &[f64]| {
        values
            .iter()
            .map(|v| format!("{v:e}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    match dispersion {
        Dispersion::Constant(n) => format!("constant n = {n}"),
        Dispersion::Sellmeier { b, c } => format!(
            "Sellmeier n² = 1 + Σ B l²/(l² - C), l in µm; B = [{}], C = [{}] µm²",
            list(b),
            list(c)
        ),
        Dispersion::Cauchy { a, b } => format!("Cauchy n = A + B/l², l in µm; A = {a}, B = {b}"),
        Dispersion::PowerSeries { a } => format!(
            "Schott power series n² = A0 + A1 l² + A2 l⁻² + ... + A5 l⁻⁸, l in µm; A = [{}]",
            list(a)
        ),
        Dispersion::ExtendedPowerSeries { a } => format!(
            "HIKARI power series n² = A0 + A1 l² + A2 l⁴ + A3 l⁻² + ... + A8 l⁻¹², l in µm; A = [{}]",
            list(a)
        ),
        Dispersion::Buchdahl { n0, nu } => format!(
            "Buchdahl quadratic n = n0 + ν1 ω + ν2 ω², ω = δl/(1 + 2.5 δl), δl = l - 0.574 µm; \
             n0 = {n0}, ν1 = {:e}, ν2 = {:e}",
            nu[0], nu[1]
        ),
        Dispersion::Tabulated { points, .. } => format!(
            "tabulated, {} points from {} to {} nm, natural cubic spline",
            points.len(),
            points[0].0,
            points[points.len() - 1].0
        ),
    }
}
