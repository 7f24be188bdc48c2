//! One set of design conditions per lens (docs/conditions.md): `analyze`, every plot and the
//! report header use the same fields and aperture; the file's conditions, the source's claims
//! and the rule come in that order; flags override all three everywhere alike.
#![cfg(feature = "plot")]

use lensbake::analysis::{
    AnalysisError, AnalyzeOptions, ConditionOverrides, DesignConditions, FileDefaults, FocusFrom,
    Origin, RULE_MAX_FIELD_DEG, analyze,
};
use lensbake::lenses;
use lensbake::paraxial::ParaxialError;
use lensbake::prescription::StatedCondition;
use lensbake::prescription::formats::LoadOptions;
use lensbake::prescription::formats::{Format, read_str};
use lensbake::report::{Figure, FigureOptions, PlotKind, figure, write_report};
use lensbake::system::LensSystem;
use lensbake::trace::{RaySource, Tracer, Travel, aim_at_stop};
use std::path::{Path, PathBuf};

fn system(spec: &str) -> LensSystem {
    lenses::load(spec, &LoadOptions::default())
        .unwrap_or_else(|e| panic!("{spec}: {e}"))
        .system
}

fn resolve(system: &LensSystem, overrides: &ConditionOverrides) -> DesignConditions {
    DesignConditions::resolve(system, overrides).unwrap()
}

/// The top field of each field-bearing plot kind, as the figure carries it.
fn plotted_top_fields(lens: &str, system: &LensSystem, options: &FigureOptions) -> Vec<f64> {
    let draw = |kind| figure(kind, lens, system, options).unwrap();
    let Figure::RayFan(fan) = draw(PlotKind::RayFan) else {
        panic!("ray fan")
    };
    let Figure::Spot(spot) = draw(PlotKind::Spot) else {
        panic!("spot")
    };
    let Figure::Layout(layout) = draw(PlotKind::Layout) else {
        panic!("layout")
    };
    let Figure::Distortion(distortion) = draw(PlotKind::Distortion) else {
        panic!("distortion")
    };
    let Figure::OpdFan(opd) = draw(PlotKind::OpdFan) else {
        panic!("OPD fan")
    };
    vec![
        fan.fields[0].field_deg,
        spot.fields[0].field_deg,
        layout.rays.iter().map(|r| r.field_deg).fold(0.0, f64::max),
        distortion.points.last().unwrap().0,
        opd.fields[0].field_deg,
    ]
}

fn report_readme(lens: &str, system: &LensSystem, options: &FigureOptions, tag: &str) -> String {
    let dir: PathBuf =
        std::env::temp_dir().join(format!("lensbake-conditions-{}-{tag}", std::process::id()));
    write_report(lens, system, options, &dir).unwrap();
    let text = std::fs::read_to_string(dir.join("README.md")).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    text
}

/// The header row of the report's conditions table for `name`.
fn header_row<'a>(readme: &'a str, name: &str) -> &'a str {
    readme
        .lines()
        .find(|l| l.starts_with(&format!("| {name} |")))
        .unwrap_or_else(|| panic!("no `{name}` row in the report header"))
}

#[test]
fn analyze_every_plot_and_the_report_header_use_one_field() {
    let lens = "dgauss-50mm";
    let system = system(lens);
    let analysis = analyze(&system, &AnalyzeOptions::default()).unwrap();
    // The pbrt file's title says "22deg HFOV"; the bundled RON carries that claim.
    assert_eq!(analysis.field_deg, 22.0);
    assert_eq!(analysis.conditions.field_from, Origin::Source);
    assert_eq!(analysis.conditions.fields_deg, [22.0, 0.7 * 22.0, 0.0]);
    for top in plotted_top_fields(lens, &system, &FigureOptions::default()) {
        assert!((top - 22.0).abs() < 1e-12, "a plot's top field is {top}");
    }
    let readme = report_readme(lens, &system, &FigureOptions::default(), "default");
    assert_eq!(
        header_row(&readme, "half fields"),
        "| half fields | 22.00, 15.40, 0.00 deg | source's claim |"
    );
    let epd = header_row(&readme, "entrance-pupil diameter");
    assert!(
        epd.contains(&format!(
            "{:.3} mm",
            analysis.first_order.entrance_pupil.diameter
        )),
        "{epd}"
    );
}

#[test]
fn flags_override_the_analysis_the_plots_and_the_report_alike() {
    let lens = "codev-dgauss-f2";
    let system = system(lens);
    let analysis = analyze(
        &system,
        &AnalyzeOptions {
            field_deg: Some(5.0),
            epd_mm: Some(30.0),
            ..AnalyzeOptions::default()
        },
    )
    .unwrap();
    assert_eq!(analysis.field_deg, 5.0);
    assert_eq!(analysis.first_order.entrance_pupil.diameter, 30.0);
    assert_eq!(analysis.conditions.field_from, Origin::Flag);
    assert_eq!(analysis.conditions.aperture_from, Origin::Flag);
    let options = FigureOptions {
        field_deg: Some(5.0),
        epd_mm: Some(30.0),
        ..FigureOptions::default()
    };
    for top in plotted_top_fields(lens, &system, &options) {
        assert!((top - 5.0).abs() < 1e-12, "a plot's top field is {top}");
    }
    // The spot plot's Airy disc follows the working f-number of the flagged pupil.
    let Figure::Spot(spot) = figure(PlotKind::Spot, lens, &system, &options).unwrap() else {
        panic!("spot")
    };
    let airy = spot.fields[2].spots[0].airy_radius_mm;
    let expected = 1.21967 * spot.fields[2].spots[0].wavelength_nm * 1e-6 * 100.0 / 30.0;
    assert!((airy / expected - 1.0).abs() < 0.02, "{airy} vs {expected}");
    let readme = report_readme(lens, &system, &options, "flags");
    assert_eq!(
        header_row(&readme, "half fields"),
        "| half fields | 5.00, 3.50, 0.00 deg | flag |"
    );
    assert!(
        header_row(&readme, "entrance-pupil diameter")
            .starts_with("| entrance-pupil diameter | 30.000 mm")
    );
}

#[test]
fn a_code_v_file_with_fields_0_10_14_is_analysed_at_14_degrees_and_its_epd() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/truth/lenses/ag_dblgauss.seq");
    let system = system(path.to_str().unwrap());
    let conditions = resolve(&system, &ConditionOverrides::default());
    assert_eq!(conditions.field_from, Origin::File);
    let rounded: Vec<f64> = conditions
        .fields_deg
        .iter()
        .map(|f| (f * 1e6).round() / 1e6)
        .collect();
    assert_eq!(rounded, [14.0, 10.0, 0.0]);
    assert_eq!(conditions.epd_mm, 50.0);
    assert_eq!(conditions.aperture_from, Origin::File);
    // SO 0 9.9e11: stated, and beyond 1000 km, so at infinity as the file says; a lens that
    // states no conditions is at infinity by the rule.
    assert_eq!(
        (conditions.object_distance_mm, conditions.object_from),
        (None, Origin::File)
    );
    let unstated = resolve(&self::system("dgauss-50mm"), &ConditionOverrides::default());
    assert_eq!(unstated.object_from, Origin::Rule);
    assert_eq!(conditions.reference_nm, 587.6);
    assert_eq!(conditions.wavelengths_nm, [486.1, 587.6, 656.3]);
    let analysis = analyze(&system, &AnalyzeOptions::default()).unwrap();
    assert!((analysis.field_deg - 14.0).abs() < 1e-6);
    // The bundled RON of the same file states the same conditions.
    let bundled = resolve(
        &self::system("codev-dgauss-f2"),
        &ConditionOverrides::default(),
    );
    assert_eq!(bundled.fields_deg, conditions.fields_deg);
    assert_eq!(bundled.epd_mm, 50.0);
    // Every drawn wavelength's fan reaches the image at 14 degrees: none is dropped.
    let Figure::RayFan(fan) = figure(
        PlotKind::RayFan,
        "codev-dgauss-f2",
        &self::system("codev-dgauss-f2"),
        &FigureOptions::default(),
    )
    .unwrap() else {
        panic!("fan")
    };
    assert!(
        fan.fields
            .iter()
            .all(|f| f.dropped_nm.is_empty() && f.tangential.len() == 3)
    );
}

/// Whether the real chief ray of `deg`, aimed at the stop centre, passes every clear aperture.
fn chief_ray_passes(system: &LensSystem, deg: f64) -> bool {
    let tracer = Tracer::new(&system.at(system.design_wavelength_nm()));
    let source = RaySource::collimated(deg, tracer.front_start_z());
    aim_at_stop(&tracer, &source, [0.0, 0.0])
        .is_ok_and(|ray| tracer.trace(ray, Travel::Forward).outcome.is_ok())
}

#[test]
fn the_rule_is_the_last_passing_chief_ray_capped_well_below_90_degrees() {
    // The singlet's stop is its front surface: its chief ray passes almost to 90 degrees, and
    // the report once analysed it at 89.9 (spot axes of +-2e6 um). The cap holds it at 45.
    let singlet = system("biconvex-singlet");
    assert!(chief_ray_passes(&singlet, 80.0));
    let conditions = resolve(&singlet, &ConditionOverrides::default());
    assert_eq!(conditions.field_from, Origin::Rule);
    assert_eq!(conditions.field_deg(), RULE_MAX_FIELD_DEG);
    let Figure::Spot(spot) = figure(
        PlotKind::Spot,
        "biconvex-singlet",
        &singlet,
        &FigureOptions::default(),
    )
    .unwrap() else {
        panic!("spot")
    };
    assert_eq!(spot.fields[0].field_deg, 45.0);
    let extent = spot.fields[0].spots[0]
        .points
        .iter()
        .map(|p| p.0.hypot(p.1))
        .fold(0.0, f64::max);
    // At 89.9 degrees the blur ran to 2 m; at 45 it stays inside the image height f tan 45.
    assert!(extent < 0.6 * 51.72, "spot extends {extent} mm");

    // The telephoto states no field: the rule's field is where its chief ray stops passing.
    let telephoto = system("telephoto-250mm");
    let conditions = resolve(&telephoto, &ConditionOverrides::default());
    assert_eq!(conditions.field_from, Origin::Rule);
    let top = conditions.field_deg();
    assert!(top > 5.0 && top < RULE_MAX_FIELD_DEG, "{top}");
    assert!(chief_ray_passes(&telephoto, top));
    assert!(!chief_ray_passes(&telephoto, top + 1e-6));
}

/// For a finite object the rule traces each angle's chief ray from its object point: the
/// analytic relay 40 mm out passes up to 22.70 degrees at the entrance pupil (22.38 from
/// infinity), and the point just beyond is stopped.
#[test]
fn the_rule_for_a_finite_object_traces_from_its_points() {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/perfect_relay.ron"),
    )
    .unwrap();
    let relay = LensSystem::from_prescription(ron::from_str(&text).unwrap()).unwrap();
    let near = resolve(
        &relay,
        &ConditionOverrides {
            object_distance_mm: Some(40.0),
            ..ConditionOverrides::default()
        },
    );
    assert_eq!(near.field_from, Origin::Rule);
    let top = near.field_deg();
    let far = resolve(&relay, &ConditionOverrides::default()).field_deg();
    assert!((top - far).abs() > 0.1, "{top} against {far} from infinity");
    let at = relay.at(near.reference_nm);
    let paraxial = lensbake::paraxial::Paraxial::new(&at, &near.paraxial_options()).unwrap();
    let tracer = Tracer::new(&at);
    let passes = |deg: f64| {
        let source =
            RaySource::finite_object(40.0, paraxial.field_at_angle(deg), tracer.front_start_z());
        aim_at_stop(&tracer, &source, [0.0, 0.0])
            .is_ok_and(|ray| tracer.trace(ray, Travel::Forward).outcome.is_ok())
    };
    assert!(passes(top));
    assert!(!passes(top + 1e-6));
}

#[test]
fn a_claimed_f_number_sets_the_pupil_only_where_the_stop_allows_it() {
    // The telephoto claims f/5.6; its stop opens to f/5.42, so f/5.6 is used.
    let telephoto = resolve(&system("telephoto-250mm"), &ConditionOverrides::default());
    assert_eq!(telephoto.aperture_from, Origin::Source);
    assert!(
        (telephoto.f_number - 5.6).abs() < 1e-6,
        "{}",
        telephoto.f_number
    );
    // The pbrt double Gauss claims f/2 but opens to f/2.03: wide open, with a note.
    let dgauss = resolve(&system("dgauss-50mm"), &ConditionOverrides::default());
    assert_eq!(dgauss.aperture_from, Origin::Rule);
    assert!(dgauss.notes.iter().any(|n| n.contains("claimed f/2")));
    assert!((dgauss.f_number - 2.03).abs() < 0.01);
}

/// A requested or stated pupil wider than the stop opens is used as given (the paraxial data
/// are for it, as OpticStudio takes a file's ENPD), with a note that the stop cuts it; one the
/// stop passes gets none.
#[test]
fn a_pupil_wider_than_the_stop_is_used_with_a_note() {
    let dgauss = system("dgauss-50mm");
    let with_epd = |epd_mm: f64| {
        resolve(
            &dgauss,
            &ConditionOverrides {
                epd_mm: Some(epd_mm),
                ..ConditionOverrides::default()
            },
        )
    };
    let wide = with_epd(30.0);
    assert_eq!((wide.epd_mm, wide.aperture_from), (30.0, Origin::Flag));
    assert!(
        wide.notes
            .iter()
            .any(|n| n.contains("30.000 mm entrance pupil is larger than the stop's 24.805 mm")),
        "{:?}",
        wide.notes
    );
    let inside = with_epd(20.0);
    assert!(
        !inside
            .notes
            .iter()
            .any(|n| n.contains("larger than the stop")),
        "{:?}",
        inside.notes
    );
}

/// A stated condition no analysis can use is refused naming the line and keyword that state
/// it; a flag that replaces it lets the lens be analysed.
#[test]
fn unusable_stated_conditions_are_located_where_the_file_states_them() {
    let zemax = include_str!("../examples/lenses/cooke_triplet.zmx");
    let codev = include_str!("../examples/lenses/ag_dblgauss.seq");
    let cases = [
        // An object on the first vertex (SURF 0's DISZ, line 32).
        (
            zemax,
            Format::Zemax,
            "  DISZ INFINITY",
            "  DISZ 0",
            StatedCondition::Object,
            32,
            "DISZ",
        ),
        // A field at 90 degrees (line 14).
        (
            zemax,
            Format::Zemax,
            "YFLN 0 14 20",
            "YFLN 0 14 90",
            StatedCondition::Fields,
            14,
            "YFLN",
        ),
        // 95 degrees, whose tangent is that of -85 degrees: it must not pass as 85.
        (
            codev,
            Format::CodeV,
            "YAN   0.0 10.0000000023 14.0000000032",
            "YAN 0 10 95",
            StatedCondition::Fields,
            10,
            "YAN",
        ),
        (
            codev,
            Format::CodeV,
            "SO    0.0 993938392063.0",
            "SO 0 0",
            StatedCondition::Object,
            14,
            "SO",
        ),
        // Object heights (FTYP 1) with the object at infinity, as OpticStudio refuses them:
        // the fields on line 14.
        (
            zemax,
            Format::Zemax,
            "FTYP 0 0 3 3 0 0 0",
            "FTYP 1 0 3 3 0 0 0",
            StatedCondition::Fields,
            14,
            "YFLN",
        ),
        // An aperture beyond the length limit, as an EPD (line 6) and as an F-number.
        (
            zemax,
            Format::Zemax,
            "ENPD 10",
            "ENPD 1e300",
            StatedCondition::Aperture,
            6,
            "ENPD",
        ),
        (
            codev,
            Format::CodeV,
            "EPD   50.0",
            "FNO 1e-300",
            StatedCondition::Aperture,
            3,
            "FNO",
        ),
    ];
    for (base, format, written, changed, condition, line, keyword) in cases {
        let text = base.replacen(written, changed, 1);
        assert_ne!(text, base, "{changed}");
        let loaded = read_str(
            &text,
            Some(Path::new("lens.txt")),
            format,
            &LoadOptions::default(),
        )
        .unwrap();
        let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
        match DesignConditions::resolve(&system, &ConditionOverrides::default()) {
            Err(AnalysisError::Stated {
                condition: refused,
                at,
                error,
            }) => {
                assert_eq!(refused, condition, "{changed}");
                assert_eq!(at.file.as_deref(), Some(Path::new("lens.txt")));
                assert_eq!((at.line, at.field.as_deref()), (Some(line), Some(keyword)));
                let expected = match condition {
                    StatedCondition::Object => {
                        matches!(
                            *error,
                            AnalysisError::Paraxial(ParaxialError::InvalidObjectDistance { .. })
                        )
                    }
                    StatedCondition::Fields => matches!(
                        *error,
                        AnalysisError::Paraxial(
                            ParaxialError::InvalidFieldAngle { .. }
                                | ParaxialError::ObjectHeightAtInfinity
                        )
                    ),
                    StatedCondition::Aperture => matches!(*error, AnalysisError::Limit(_)),
                };
                assert!(expected, "{changed}: {error}");
            }
            other => panic!("{changed}: {other:?}"),
        }
        // A bake's and a render's defaults take no field from the file: its fields cannot
        // fail them; its object distance (their default focus) can, unless a flag sets the
        // focus.
        let defaults = FileDefaults::of(&system, FocusFrom::File);
        let with_focus_flag = FileDefaults::of(&system, FocusFrom::Flag);
        match condition {
            StatedCondition::Fields => assert!(defaults.is_ok(), "{changed}: {defaults:?}"),
            StatedCondition::Object => {
                assert!(
                    matches!(defaults, Err(AnalysisError::Stated { .. })),
                    "{changed}: {defaults:?}"
                );
                let chosen = with_focus_flag.unwrap();
                assert_eq!(chosen.focus_mm, None, "{changed}");
            }
            StatedCondition::Aperture => assert!(
                matches!(with_focus_flag, Err(AnalysisError::Stated { .. })),
                "{changed}: {with_focus_flag:?}"
            ),
        }
        let flags = ConditionOverrides {
            field_deg: Some(10.0),
            epd_mm: Some(10.0),
            object_distance_mm: Some(5000.0),
            ..ConditionOverrides::default()
        };
        DesignConditions::resolve(&system, &flags).unwrap();
    }
}

/// An object-space NA gives a pupil only for a finite object and below the object space's
/// index; otherwise the file's aperture is refused on its line (it had fallen silently to the
/// stop's own aperture, shown as the rule's).
#[test]
fn an_object_space_na_that_gives_no_beam_is_refused_on_its_line() {
    let base = include_str!("../examples/lenses/cooke_triplet.zmx");
    let with = |na: &str, object: &str| {
        let text = base.replacen("ENPD 10", &format!("OBNA {na}"), 1).replacen(
            "  DISZ INFINITY",
            &format!("  DISZ {object}"),
            1,
        );
        let loaded = read_str(
            &text,
            Some(Path::new("na.zmx")),
            Format::Zemax,
            &LoadOptions::default(),
        )
        .unwrap();
        let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
        DesignConditions::resolve(&system, &ConditionOverrides::default())
    };
    let usable = with("0.05", "100").unwrap();
    assert_eq!(usable.aperture_from, Origin::File);
    for (na, object, says) in [
        (
            "1.5",
            "100",
            "needs an object-space index above it (n = 1.000000)",
        ),
        (
            "0.05",
            "INFINITY",
            "needs an object at a finite distance, and the object is at infinity",
        ),
    ] {
        match with(na, object) {
            Err(AnalysisError::Stated {
                condition,
                at,
                error,
            }) => {
                assert_eq!(condition, StatedCondition::Aperture);
                assert_eq!((at.line, at.field.as_deref()), (Some(6), Some("OBNA")));
                assert!(
                    matches!(*error, AnalysisError::UnusableAperture { .. }),
                    "{error}"
                );
                // One message, one space between its words.
                assert!(error.to_string().contains(says), "{error}");
            }
            other => panic!("OBNA {na}, DISZ {object}: {other:?}"),
        }
    }
}

/// A lens that fails whatever the file states (an afocal test file) is not blamed on the
/// file's object, and `lens check` still checks it (the conditions line says none resolve).
#[test]
fn a_failure_of_the_lens_itself_is_not_blamed_on_a_stated_condition() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/corpus/rayoptics__dec_test.seq");
    let system = system(path.to_str().unwrap());
    assert!(system.prescription.provenance.conditions.is_some());
    match DesignConditions::resolve(&system, &ConditionOverrides::default()) {
        Err(AnalysisError::Paraxial(ParaxialError::Afocal)) => {}
        other => panic!("{other:?}"),
    }
}

/// Field components just below 90 degrees are accepted, and combine below 90 (the check is on
/// the components alone).
#[test]
fn field_components_one_ulp_below_90_degrees_combine_below_90() {
    let below = 90f64.next_down();
    let text = include_str!("../examples/lenses/cooke_triplet.zmx")
        .replacen("XFLN 0 0 0", &format!("XFLN 0 0 {below:?}"), 1)
        .replacen("YFLN 0 14 20", &format!("YFLN 0 14 {below:?}"), 1);
    let loaded = read_str(
        &text,
        Some(Path::new("wide.zmx")),
        Format::Zemax,
        &LoadOptions::default(),
    )
    .unwrap();
    let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    let resolved = resolve(&system, &ConditionOverrides::default());
    assert_eq!(resolved.field_from, Origin::File);
    let top = resolved.fields_deg[0];
    assert!(top < 90.0 && top > 89.9, "{top}");
}

/// An object at 5e9 mm is at infinity to the readers as it is to the analysis (1e9 mm and
/// beyond): a CODE V `FNO` there is the image-space f-number. The readers had drawn the line at
/// 1e10, read the `FNO` as a working f-number of a finite object, and the analysis then put the
/// object at infinity; a Zemax copy of the lens analysed with a pupil 2e-8 larger.
#[test]
fn an_object_beyond_the_length_limit_is_at_infinity_to_the_readers_too() {
    let text = "FNO 4.0\nWL 550.0\nREF 1\nXAN 0.0 0.0\nYAN 0.0 5.0\nSO 0.0 5e9\n\
                S 100.0 10.0 1.5168:64.17\nSTO\nS -100.0 95.0\nSI 0.0 0.0\n";
    let loaded = read_str(text, None, Format::CodeV, &LoadOptions::default()).unwrap();
    let conditions = loaded.prescription.provenance.conditions.clone().unwrap();
    assert_eq!(conditions.object_distance_mm, None);
    assert_eq!(
        conditions.aperture,
        Some(lensbake::prescription::ApertureSpec::FNumber(4.0))
    );
    let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    let resolved = resolve(&system, &ConditionOverrides::default());
    assert_eq!(resolved.object_distance_mm, None);
    assert_eq!(resolved.f_number, 4.0);
}

/// A working f-number after an odd number of mirrors: the paraboloid of 200 mm focal length at
/// FNO 8 with its object 1e8 mm away fills a 25 mm pupil. The image-space index is negative
/// there, and the pupil came out as -25 mm and was refused.
#[test]
fn a_working_f_number_after_a_mirror_gives_a_positive_pupil() {
    let text = "dim m\nrdm y\nso 0. 100000000.0\ns -400 -200 refl\ncon\nk -1\nsi 0 0\n\
                fno 8.0; wl 550\nyim 0 10. 20. 30.\n";
    let loaded = read_str(text, None, Format::CodeV, &LoadOptions::default()).unwrap();
    let conditions = loaded.prescription.provenance.conditions.clone().unwrap();
    assert_eq!(
        conditions.aperture,
        Some(lensbake::prescription::ApertureSpec::WorkingFNumber(8.0))
    );
    let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    let resolved = resolve(&system, &ConditionOverrides::default());
    // Paraxially the marginal ray from 1e8 mm converges at 1 / (2 u') = 8 for a pupil of
    // 25 (1 + 200 / 1e8) mm.
    let expected = 25.0 * (1.0 + 200.0 / 1e8);
    assert!(
        (resolved.epd_mm - expected).abs() < 1e-9 * expected,
        "{} against {expected}",
        resolved.epd_mm
    );
}
