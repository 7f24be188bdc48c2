//! The built-in glass catalogue against independent truth: the SCHOTT/HIKARI indices the oracle
//! computed with the opticalglass package, the indices CODE V printed, and each datasheet's own
//! nd and vd.

mod common;

use lensbake::glass::{C_LINE_NM, CATALOG, D_LINE_NM, Dispersion, F_LINE_NM, lookup};
use lensbake::prescription::Problem;

fn index_of(glass: &str, nm: f64) -> f64 {
    lookup(glass)
        .unwrap_or_else(|e| panic!("{glass}: {e}"))
        .dispersion()
        .index(nm)
}

/// Compares every glass surface of an oracle lens (glass named in `note`) at the wavelengths the
/// oracle states for n, nF and nC. Both sides evaluate the same datasheet formula in f64, so they
/// agree to rounding; 1e-12 leaves room for evaluation order only.
fn check_oracle_indices(file: &str, expected_glasses: &[&str]) {
    let oracle = common::oracle_json(file);
    let prescription = &oracle["lenses"][0]["prescription"];
    let wavelengths = &prescription["index_wavelengths_nm"];
    let mut seen = Vec::new();
    for surface in prescription["surfaces"].as_array().unwrap() {
        let Some(glass) = surface["note"].as_str().filter(|g| *g != "air") else {
            continue;
        };
        for (key, wl) in [("n", "n"), ("nF", "nF"), ("nC", "nC")] {
            let nm = wavelengths[wl].as_f64().unwrap();
            let expected = surface[key].as_f64().unwrap();
            let got = index_of(glass, nm);
            assert!(
                (got - expected).abs() < 1e-12,
                "{file}: {glass} {key} at {nm} nm: {got} vs oracle {expected}"
            );
        }
        seen.push(glass.to_string());
    }
    for glass in expected_glasses {
        assert!(seen.iter().any(|g| g == glass), "{file} lacks {glass}");
    }
}

#[test]
fn codev_double_gauss_glasses_match_the_oracle() {
    check_oracle_indices(
        "codev_ag_dblgauss.json",
        &["N-SSK2", "N-SK2", "F5", "N-SK16"],
    );
}

#[test]
fn cooke_triplet_glasses_match_the_oracle() {
    // SK16 is HIKARI's (power-series formula), F2 is SCHOTT's (Sellmeier).
    check_oracle_indices("optiland_cooke_triplet.json", &["SK16", "F2"]);
}

/// The REFRACTIVE INDICES table of the CODE V listing, six decimals per entry.
#[test]
fn codev_listing_indices_match_to_printed_digits() {
    let path = common::testdata_dir().join("lenses/ag_dblgauss.lis");
    let listing = std::fs::read_to_string(&path).unwrap();
    let mut lines = listing
        .lines()
        .skip_while(|l| !l.contains("REFRACTIVE INDICES"))
        .skip(1);
    let header = lines.next().expect("glass code header");
    let wavelengths: Vec<f64> = header
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect();
    assert_eq!(wavelengths, [656.3, 587.6, 486.1]);
    let mut rows = 0;
    for line in lines.take_while(|l| !l.trim().is_empty()) {
        let mut words = line.split_whitespace();
        let glass = words.next().unwrap();
        let printed: Vec<f64> = words.map(|w| w.parse().unwrap()).collect();
        assert_eq!(printed.len(), 3, "{line}");
        for (nm, n) in wavelengths.iter().zip(&printed) {
            let got = index_of(glass, *nm);
            assert!(
                (got - n).abs() <= 0.5e-6,
                "{glass} at {nm} nm: {got} vs CODE V {n}"
            );
        }
        rows += 1;
    }
    assert_eq!(rows, 4, "the listing names four glasses");
}

/// Each entry's formula reproduces the datasheet's nd (5 decimals) and vd (2 decimals): a
/// mistyped coefficient would move one of them.
#[test]
fn every_catalogue_glass_reproduces_its_datasheet_nd_and_vd() {
    for glass in CATALOG {
        let d = glass.formula.index(D_LINE_NM);
        let f = glass.formula.index(F_LINE_NM);
        let c = glass.formula.index(C_LINE_NM);
        let vd = (d - 1.0) / (f - c);
        assert!(
            (d - glass.nd).abs() <= 5e-6,
            "{}: n(d) {d} vs datasheet {}",
            glass.name,
            glass.nd
        );
        assert!(
            (vd - glass.vd).abs() <= 5e-3,
            "{}: vd {vd} vs datasheet {}",
            glass.name,
            glass.vd
        );
        // The glass code starts with nd and vd rounded to three digits each (nd 1.51680,
        // vd 64.17 -> "517642"; nd 2.022 -> "022"); makers round halves either way.
        let code_nd: f64 = glass.glass_code[0..3].parse().unwrap();
        let code_vd: f64 = glass.glass_code[3..6].parse().unwrap();
        let nd_digits = ((glass.nd - 1.0) * 1000.0) % 1000.0;
        assert!(
            (code_nd - nd_digits).abs() <= 0.5 + 1e-9
                && (code_vd - glass.vd * 10.0).abs() <= 0.5 + 1e-9,
            "{}: code {} vs nd {} vd {}",
            glass.name,
            glass.glass_code,
            glass.nd,
            glass.vd
        );
    }
}

#[test]
fn catalogue_is_sorted_with_unique_names() {
    for pair in CATALOG.windows(2) {
        assert!(
            pair[0].name < pair[1].name,
            "{} before {}",
            pair[0].name,
            pair[1].name
        );
    }
    for glass in CATALOG {
        assert_eq!(lookup(glass.name).unwrap().name, glass.name);
        assert!(!glass.catalogue.is_empty() && !glass.glass_code.is_empty());
    }
}

#[test]
fn catalogue_covers_the_common_schott_glasses() {
    for name in [
        "N-BK7", "N-SK2", "N-SK16", "N-SSK2", "N-SSK8", "F2", "F5", "SF5", "N-SF5", "SF2",
        "N-LAK9", "N-LAK22", "N-LASF9", "N-BAF10", "N-BAK4", "N-KF9", "N-F2", "N-SF6", "N-SF11",
        "K10", "N-SK15", "N-LAK12", "SF4", "LF5",
    ] {
        assert_eq!(lookup(name).unwrap().maker, "Schott", "{name}");
    }
}

#[test]
fn names_resolve_despite_case_dashes_and_maker_suffix() {
    assert_eq!(lookup("NSSK2_SCHOTT").unwrap().name, "N-SSK2");
    assert_eq!(lookup("n-bk7").unwrap().name, "N-BK7");
    assert_eq!(lookup("SK16_HIKARI").unwrap().name, "SK16");
    assert_eq!(lookup("F5 schott").unwrap().name, "F5");
}

#[test]
fn maker_suffix_must_match_the_entry() {
    // The catalogue's SK16 is HIKARI's; SCHOTT's old SK16 has other coefficients.
    assert!(matches!(
        lookup("SK16_SCHOTT"),
        Err(Problem::UnknownGlass { .. })
    ));
}

#[test]
fn unknown_glass_names_it_and_suggests_neighbours() {
    match lookup("N-BK8") {
        Err(Problem::UnknownGlass { name, suggestions }) => {
            assert_eq!(name, "N-BK8");
            assert_eq!(suggestions.first().map(String::as_str), Some("N-BK7"));
            let message = Problem::UnknownGlass { name, suggestions }.to_string();
            assert!(
                message.contains("`N-BK8`") && message.contains("N-BK7"),
                "{message}"
            );
        }
        other => panic!("expected UnknownGlass, got {other:?}"),
    }
    match lookup("UNOBTAINIUM") {
        Err(Problem::UnknownGlass { suggestions, .. }) => assert!(suggestions.is_empty()),
        other => panic!("expected UnknownGlass, got {other:?}"),
    }
}

/// The model glass honours both numbers it is given: n(d) = nd and (nd - 1)/(nF - nC) = vd.
#[test]
fn model_glass_reproduces_nd_and_vd() {
    for (nd, vd) in [
        (1.5168, 64.17),
        (1.62004, 36.37),
        (1.883, 40.8),
        (1.4585, 67.8),
    ] {
        let model = Dispersion::model(nd, vd);
        let d = model.index(D_LINE_NM);
        let abbe = (d - 1.0) / (model.index(F_LINE_NM) - model.index(C_LINE_NM));
        assert!((d - nd).abs() <= 1e-12, "n(d) {d} vs {nd}");
        assert!((abbe - vd).abs() <= 1e-12 * vd, "vd {abbe} vs {vd}");
        // Normal dispersion: blue bends more than red.
        assert!(model.index(F_LINE_NM) > d && d > model.index(C_LINE_NM));
    }
    assert_eq!(Dispersion::model(1.5, 0.0), Dispersion::Constant(1.5));
}
