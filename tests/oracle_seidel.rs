//! Seidel sums of the four oracle lenses against rayoptics and optiland: per-surface Welford
//! terms, their sums, transverse and wavefront forms, and the primary colour terms where the
//! table gives nF/nC.
//!
//! Tolerances: against optiland (a true infinite object) and against both programs at the
//! finite conjugate, 1e-10 relative: all compute the same exact paraxial algebra (measured
//! agreement ~1e-13), with an absolute floor of 1e-12 mm (1e-9 waves) for terms that vanish in
//! exact arithmetic (a plane stop in air, S_IV of a plane). Against rayoptics at infinity,
//! 1e-6 relative with an absolute floor of 1e-6 times the lens's largest surface term: its
//! object at 1e10 mm moves the chief ray by ~4e-8 relative, which shifts every term by up to
//! ~6e-8 mm, 2.7e-6 relative on small terms that are differences of large ones (measured
//! against optiland, not against us).

mod common;

use common::{ORACLE_LENSES, OracleLens, Tally, get, load_oracle, num, nums};
use lensbake::analysis::{AnalyzeOptions, analyze};
use lensbake::paraxial::{Aperture, Field, ObjectPosition, Paraxial, ParaxialOptions, StopChoice};
use lensbake::prescription::Medium;
use lensbake::seidel::{IndexDifferences, Seidel};
use lensbake::system::{LensSystem, SystemAt};

/// rayoptics at infinity.
const REL: f64 = 1e-6;
/// optiland, and rayoptics at the finite conjugate.
const REL_EXACT: f64 = 1e-10;
const ABS_MM: f64 = 1e-12;
const ABS_WAVES: f64 = 1e-9;

const CONJUGATES: [&str; 2] = ["infinite_conjugate", "finite_conjugate"];

fn system(oracle: &OracleLens) -> SystemAt {
    LensSystem::from_prescription(oracle.prescription.clone())
        .expect("oracle table validates")
        .at(oracle.wavelength_nm())
}

fn paraxial(oracle: &OracleLens, at: &SystemAt, conjugate: &str) -> Paraxial {
    let (object, field) = if conjugate == "infinite_conjugate" {
        (
            ObjectPosition::Infinite,
            Field::Angle {
                deg: oracle.max_field_angle_deg(),
            },
        )
    } else {
        let block = get(oracle.lens(), conjugate);
        (
            ObjectPosition::Finite {
                distance: num(get(block, "object_distance_from_surface1")),
            },
            Field::ObjectHeight {
                mm: num(get(block, "max_object_height")),
            },
        )
    };
    Paraxial::new(
        at,
        &ParaxialOptions {
            object,
            aperture: Aperture::EntrancePupilDiameter(oracle.epd_used()),
            field,
            stop: StopChoice::Marked,
        },
    )
    .expect("paraxial setup")
}

/// Index differences nF - nC from the table's columns.
fn table_colour(oracle: &OracleLens) -> Option<IndexDifferences> {
    oracle.lines.as_ref().map(|l| IndexDifferences {
        short_nm: l.f_nm,
        long_nm: l.c_nm,
        object: l.object_f - l.object_c,
        after: l.f.iter().zip(&l.c).map(|(f, c)| f - c).collect(),
    })
}

#[test]
fn seidel_terms_per_surface_and_sums() {
    let mut tally = Tally::default();
    for name in ORACLE_LENSES {
        let oracle = load_oracle(name);
        let at = system(&oracle);
        for conjugate in CONJUGATES {
            let p = paraxial(&oracle, &at, conjugate);
            let seidel = Seidel::new(&at, &p, None);
            let block = get(oracle.lens(), &format!("{conjugate}.seidel"));
            let largest_term = seidel
                .surfaces
                .iter()
                .flat_map(|s| s.terms.as_array())
                .fold(0.0f64, |m, v| m.max(v.abs()));
            let (rayoptics_rel, rayoptics_abs) = if conjugate == "infinite_conjugate" {
                (REL, REL * largest_term)
            } else {
                (REL_EXACT, ABS_MM)
            };
            let n_image = at.image_index();
            let u_image = p.marginal.image_slope();
            let optiland = get(block, "optiland.per_surface");
            for (k, surface) in seidel.surfaces.iter().enumerate() {
                assert_eq!(surface.surface, k + 1);
                let what = format!("{name} {conjugate} surface {}", k + 1);
                let expected = nums(get(block, &format!("rayoptics.per_surface.{}", k + 1)));
                for (j, (ours, theirs)) in
                    surface.terms.as_array().iter().zip(&expected).enumerate()
                {
                    let label = format!("{what} S{}", j + 1);
                    tally.check(
                        &format!("S per surface (rayoptics, {conjugate})"),
                        *ours,
                        *theirs,
                        rayoptics_rel,
                        rayoptics_abs,
                        &label,
                    );
                }
                // optiland's transverse coefficients: TAC is the pure astigmatism S_III/(2n'u').
                let t = &surface.transverse;
                let pure_astigmatism = surface.terms.astigmatism / (2.0 * n_image * u_image);
                for (ours, key) in [
                    (t.tsa, "TSC"),
                    (t.tco, "TCC"),
                    (pure_astigmatism, "TAC"),
                    (t.ptb, "TPC"),
                    (t.dst, "DC"),
                ] {
                    let theirs = nums(get(optiland, key))[k];
                    tally.check(
                        "transverse per surface (optiland)",
                        ours,
                        theirs,
                        REL_EXACT,
                        ABS_MM,
                        &format!("{what} {key}"),
                    );
                }
                let transverse = nums(get(
                    block,
                    &format!("rayoptics.transverse_mm.per_surface.{}", k + 1),
                ));
                for (ours, theirs) in [t.tsa, t.tco, t.tas, t.sas, t.ptb, t.dst]
                    .iter()
                    .zip(&transverse)
                {
                    tally.check(
                        &format!("transverse per surface (rayoptics, {conjugate})"),
                        *ours,
                        *theirs,
                        rayoptics_rel,
                        rayoptics_abs * (2.0 * n_image * u_image).abs().recip(),
                        &format!("{what} transverse"),
                    );
                }
            }
            let sums = seidel.sums.as_array();
            for (j, (ours, theirs)) in sums
                .iter()
                .zip(nums(get(block, "rayoptics.sum")))
                .enumerate()
            {
                tally.check(
                    &format!("S sums (rayoptics, {conjugate})"),
                    *ours,
                    theirs,
                    rayoptics_rel,
                    rayoptics_abs,
                    &format!("{name} {conjugate} S{}", j + 1),
                );
            }
            // optiland's seidels() are minus the Welford sums.
            for (j, (ours, theirs)) in sums
                .iter()
                .zip(nums(get(block, "optiland.seidels_S1_S5")))
                .enumerate()
            {
                tally.check(
                    "S sums (optiland)",
                    *ours,
                    -theirs,
                    REL_EXACT,
                    ABS_MM,
                    &format!("{name} {conjugate} S{}", j + 1),
                );
            }
            let t = &seidel.transverse;
            for (ours, theirs) in [t.tsa, t.tco, t.tas, t.sas, t.ptb, t.dst]
                .iter()
                .zip(nums(get(block, "rayoptics.transverse_mm.values")))
            {
                tally.check(
                    &format!("transverse sums (rayoptics, {conjugate})"),
                    *ours,
                    theirs,
                    rayoptics_rel,
                    rayoptics_abs * (2.0 * n_image * u_image).abs().recip(),
                    &format!("{name} {conjugate} transverse"),
                );
            }
            let w = &seidel.wavefront;
            for (ours, theirs) in [w.w040, w.w131, w.w222, w.w220, w.w311]
                .iter()
                .zip(nums(get(block, "rayoptics.wavefront_waves.values")))
            {
                tally.check(
                    &format!("wavefront sums (rayoptics, {conjugate})"),
                    *ours,
                    theirs,
                    rayoptics_rel,
                    ABS_WAVES.max(rayoptics_abs / (oracle.wavelength_nm() * 1e-6)),
                    &format!("{name} {conjugate} wavefront"),
                );
            }
            if conjugate == "infinite_conjugate" {
                let quick = nums(get(oracle.lens(), "quick_reference.seidel_sums_S1_S5"));
                for (ours, theirs) in sums.iter().zip(quick) {
                    tally.check(
                        "S sums (quick_reference)",
                        *ours,
                        theirs,
                        REL,
                        REL * largest_term,
                        &format!("{name} quick_reference"),
                    );
                }
            }
        }
    }
    tally.print("Seidel");
}

/// C_I and C_II in their transverse forms (optiland TAchC and TchC, the CODE V AX and LAT),
/// from index differences taken straight from the table's nF and nC columns.
#[test]
fn colour_terms_from_table_indices() {
    let mut tally = Tally::default();
    let mut lenses_with_colour = 0;
    for name in ORACLE_LENSES {
        let oracle = load_oracle(name);
        let Some(colour) = table_colour(&oracle) else {
            continue;
        };
        lenses_with_colour += 1;
        let at = system(&oracle);
        let p = paraxial(&oracle, &at, "infinite_conjugate");
        let seidel = Seidel::new(&at, &p, Some(&colour));
        let block = get(
            oracle.lens(),
            "infinite_conjugate.chromatic.optiland_first_order_colour",
        );
        let axial = nums(get(block, "per_surface.TAchC"));
        let lateral = nums(get(block, "per_surface.TchC"));
        for (k, surface) in seidel.surfaces.iter().enumerate() {
            let t = surface.transverse_colour.expect("colour requested");
            let what = format!("{name} surface {}", k + 1);
            tally.check(
                "colour per surface (optiland)",
                t.ax,
                axial[k],
                REL_EXACT,
                ABS_MM,
                &format!("{what} TAchC"),
            );
            tally.check(
                "colour per surface (optiland)",
                t.lat,
                lateral[k],
                REL_EXACT,
                ABS_MM,
                &format!("{what} TchC"),
            );
        }
        let sums = seidel.transverse_colour.expect("colour requested");
        tally.check(
            "colour sums (optiland)",
            sums.ax,
            num(get(block, "sum.TAchC")),
            REL_EXACT,
            ABS_MM,
            &format!("{name} TAchC"),
        );
        tally.check(
            "colour sums (optiland)",
            sums.lat,
            num(get(block, "sum.TchC")),
            REL_EXACT,
            ABS_MM,
            &format!("{name} TchC"),
        );
        // Longitudinal axial colour -AX/u'.
        let longitudinal = -sums.ax / p.marginal.image_slope();
        tally.check(
            "colour sums (optiland)",
            longitudinal,
            num(get(block, "sum.LchC")),
            REL_EXACT,
            ABS_MM,
            &format!("{name} LchC"),
        );
    }
    assert_eq!(
        lenses_with_colour, 2,
        "CODE V double Gauss and Cooke triplet carry nF/nC"
    );
    tally.print("colour");
}

/// The library path `lensbake analyze` takes: a LensSystem whose media disperse, colour from
/// its own indices at the F and C lines. The Cooke triplet's glasses become model glasses with
/// nd = n and vd = (n - 1) / (nF - nC), which reproduce the table's n at the d line (the lens
/// wavelength) and its nF - nC exactly.
#[test]
fn analysis_of_a_dispersive_lens_system_matches_the_oracle() {
    let oracle = load_oracle("optiland_cooke_triplet");
    let lines = oracle.lines.as_ref().expect("Cooke triplet has nF/nC");
    let mut prescription = oracle.prescription.clone();
    for (k, surface) in prescription.surfaces.iter_mut().enumerate() {
        let Medium::Index(nd) = surface.medium else {
            unreachable!("the loader builds constant indices")
        };
        let dn = lines.f[k] - lines.c[k];
        surface.medium = if dn == 0.0 {
            Medium::Air
        } else {
            Medium::Model {
                nd,
                vd: (nd - 1.0) / dn,
            }
        };
    }
    prescription.object_medium = Medium::Air;
    let system = LensSystem::from_prescription(prescription).expect("valid");
    assert!(system.disperses());
    let analysis = analyze(
        &system,
        &AnalyzeOptions {
            wavelength_nm: Some(oracle.wavelength_nm()),
            field_deg: Some(oracle.max_field_angle_deg()),
            epd_mm: Some(oracle.epd_used()),
            ..AnalyzeOptions::default()
        },
    )
    .expect("analysis");

    let mut tally = Tally::default();
    let block = get(oracle.lens(), "infinite_conjugate");
    for (ours, theirs) in analysis
        .seidel
        .sums
        .as_array()
        .iter()
        .zip(nums(get(block, "seidel.optiland.seidels_S1_S5")))
    {
        tally.check(
            "analysis S sums (optiland)",
            *ours,
            -theirs,
            REL_EXACT,
            ABS_MM,
            "Cooke S sum",
        );
    }
    let colour = get(block, "chromatic.optiland_first_order_colour");
    let t = analysis
        .seidel
        .transverse_colour
        .expect("the lens disperses");
    // The model glass reproduces nF - nC to rounding (~1e-16 of an index difference ~1e-2).
    tally.check(
        "analysis colour (optiland)",
        t.ax,
        num(get(colour, "sum.TAchC")),
        1e-12,
        ABS_MM,
        "Cooke TAchC",
    );
    tally.check(
        "analysis colour (optiland)",
        t.lat,
        num(get(colour, "sum.TchC")),
        1e-12,
        ABS_MM,
        "Cooke TchC",
    );
    let lens_frame = get(block, "first_order.optiland.lens_frame");
    tally.check(
        "analysis first order",
        analysis.first_order.efl,
        num(get(block, "first_order.optiland.raw.f2")),
        1e-12,
        0.0,
        "Cooke EFL",
    );
    tally.check(
        "analysis first order",
        analysis.first_order.entrance_pupil.z,
        num(get(lens_frame, "z_entrance_pupil")),
        1e-12,
        0.0,
        "Cooke EP z",
    );
    tally.print("analysis of a dispersive LensSystem");
}
