//! First-order data, pupils and paraxial rays of the four oracle lenses against rayoptics and
//! optiland (tests/data/truth/oracle), at infinity and at the finite conjugate.
//!
//! Tolerances: 1e-7 relative against rayoptics at infinity (it puts the object at 1e10 mm,
//! which moves its pupils and image by up to ~4e-8 relative: the two programs agree to about
//! 1e-8). Against optiland (a true infinite object) and against both programs at the finite
//! conjugate the computation is the same exact paraxial algebra, so the tolerance is 1e-11
//! relative: a wrong sign convention or reference plane shows up at 1e-3 or worse, rounding
//! at 1e-14. Values that vanish in exact arithmetic (the chief ray at the stop, ...) get an
//! absolute floor of 1e-9 mm.

mod common;

use common::{ORACLE_LENSES, OracleLens, Tally, get, load_oracle, num, nums};
use lensbake::paraxial::{
    Aperture, Field, ObjectPosition, Paraxial, ParaxialOptions, StopChoice, sensor_z,
};
use lensbake::system::{LensSystem, SystemAt};
use serde_json::Value;

/// rayoptics at infinity.
const REL: f64 = 1e-7;
/// optiland, and both programs at the finite conjugate.
const REL_EXACT: f64 = 1e-11;
const ABS_MM: f64 = 1e-9;

fn system(oracle: &OracleLens) -> SystemAt {
    LensSystem::from_prescription(oracle.prescription.clone())
        .expect("oracle table validates")
        .at(oracle.wavelength_nm())
}

fn infinite(oracle: &OracleLens, at: &SystemAt) -> Paraxial {
    Paraxial::new(
        at,
        &ParaxialOptions {
            object: ObjectPosition::Infinite,
            aperture: Aperture::EntrancePupilDiameter(oracle.epd_used()),
            field: Field::Angle {
                deg: oracle.max_field_angle_deg(),
            },
            stop: StopChoice::Marked,
        },
    )
    .expect("infinite conjugate")
}

fn finite(oracle: &OracleLens, at: &SystemAt) -> Paraxial {
    let conjugate = get(oracle.lens(), "finite_conjugate");
    Paraxial::new(
        at,
        &ParaxialOptions {
            object: ObjectPosition::Finite {
                distance: num(get(conjugate, "object_distance_from_surface1")),
            },
            aperture: Aperture::EntrancePupilDiameter(oracle.epd_used()),
            field: Field::ObjectHeight {
                mm: num(get(conjugate, "max_object_height")),
            },
            stop: StopChoice::Marked,
        },
    )
    .expect("finite conjugate")
}

/// Where the marginal ray crosses the axis after the last surface: the image found by tracing,
/// independent of the thick-lens equivalent that focusing uses.
fn marginal_focus(p: &Paraxial) -> f64 {
    p.first_order.z_last_vertex - p.marginal.last_height() / p.marginal.image_slope()
}

/// Checks `(ours, path under block)` pairs.
fn check_all(
    tally: &mut Tally,
    class: &str,
    rel: f64,
    name: &str,
    block: &Value,
    pairs: &[(f64, &str)],
) {
    for (ours, path) in pairs {
        tally.check(
            class,
            *ours,
            num(get(block, path)),
            rel,
            ABS_MM,
            &format!("{name} {path}"),
        );
    }
}

#[test]
fn first_order_at_infinity() {
    let mut tally = Tally::default();
    for name in ORACLE_LENSES {
        let oracle = load_oracle(name);
        let at = system(&oracle);
        let p = infinite(&oracle, &at);
        let f = &p.first_order;
        let xp = p.exit_pupil.expect("exit pupil at a finite distance");
        let z_last = f.z_last_vertex;
        let optiland = get(oracle.lens(), "infinite_conjugate.first_order.optiland");
        check_all(
            &mut tally,
            "cardinal points (optiland)",
            REL_EXACT,
            name,
            optiland,
            &[
                (f.z_front_focal, "lens_frame.z_front_focal_point"),
                (f.z_rear_focal, "lens_frame.z_rear_focal_point"),
                (f.z_front_principal, "lens_frame.z_front_principal_point"),
                (f.z_rear_principal, "lens_frame.z_rear_principal_point"),
                (f.z_front_nodal, "lens_frame.z_front_nodal_point"),
                (f.z_rear_nodal, "lens_frame.z_rear_nodal_point"),
                (f.efl, "raw.f2"),
                (-f.fl_object, "raw.f1"),
            ],
        );
        check_all(
            &mut tally,
            "pupils (optiland)",
            REL_EXACT,
            name,
            optiland,
            &[
                (p.entrance_pupil.z, "lens_frame.z_entrance_pupil"),
                (
                    p.entrance_pupil.diameter,
                    "lens_frame.entrance_pupil_diameter",
                ),
                (xp.z, "lens_frame.z_exit_pupil"),
                (xp.diameter, "lens_frame.exit_pupil_diameter"),
                (p.f_number, "raw.FNO"),
                // optiland's invariant has the opposite sign to rayoptics' opt_inv.
                (-p.lagrange_invariant, "raw.invariant"),
            ],
        );
        let rayoptics = get(
            oracle.lens(),
            "infinite_conjugate.first_order.rayoptics.raw_fod",
        );
        check_all(
            &mut tally,
            "cardinal points (rayoptics)",
            REL,
            name,
            rayoptics,
            &[
                (f.power, "power"),
                (f.efl, "efl"),
                (f.fl_object, "fl_obj"),
                (f.bfl, "bfl"),
                (f.ffl, "ffl"),
                (f.z_front_principal, "pp1"),
                (f.z_rear_principal - z_last, "ppk"),
                (p.z_image - z_last, "img_dist"),
            ],
        );
        check_all(
            &mut tally,
            "pupils (rayoptics)",
            REL,
            name,
            rayoptics,
            &[
                (p.entrance_pupil.z, "enp_dist"),
                (p.entrance_pupil.diameter / 2.0, "enp_radius"),
                (xp.diameter / 2.0, "exp_radius"),
                (p.working_f_number, "fno"),
                (p.lagrange_invariant, "opt_inv"),
                (p.image_height, "img_ht"),
            ],
        );
        let quick = get(oracle.lens(), "quick_reference");
        check_all(
            &mut tally,
            "quick_reference",
            REL,
            name,
            quick,
            &[
                (f.efl, "efl_image_side"),
                (f.fl_object, "fl_object_side"),
                (f.bfl, "bfl"),
                (f.ffl, "ffl"),
                (f.z_front_focal, "z_F"),
                (f.z_front_principal, "z_P"),
                (f.z_rear_principal, "z_P_prime"),
                (f.z_rear_focal, "z_F_prime"),
                (p.working_f_number, "fno_rayoptics"),
                (p.f_number, "fno_optiland"),
                (p.entrance_pupil.diameter, "epd"),
                (p.entrance_pupil.z, "z_entrance_pupil"),
                (xp.diameter, "exit_pupil_diameter"),
                (xp.z, "z_exit_pupil"),
                (p.z_image - z_last, "paraxial_image_distance"),
            ],
        );
        assert_eq!(
            p.stop_surface() as f64,
            num(get(quick, "stop_surface")),
            "{name} stop"
        );
        let sensor = sensor_z(&at, ObjectPosition::Infinite).expect("real image");
        tally.check(
            "focus vs marginal ray",
            sensor,
            marginal_focus(&p),
            1e-12,
            0.0,
            &format!("{name} sensor"),
        );
    }
    tally.print("first order, object at infinity");
}

#[test]
fn first_order_at_finite_conjugate() {
    let mut tally = Tally::default();
    for name in ORACLE_LENSES {
        let oracle = load_oracle(name);
        let at = system(&oracle);
        let p = finite(&oracle, &at);
        let xp = p.exit_pupil.expect("exit pupil at a finite distance");
        let z_last = p.first_order.z_last_vertex;
        let conjugate = get(oracle.lens(), "finite_conjugate");
        let rayoptics = get(conjugate, "first_order.rayoptics.raw_fod");
        check_all(
            &mut tally,
            "finite conjugate (rayoptics)",
            REL_EXACT,
            name,
            rayoptics,
            &[
                (p.z_image - z_last, "img_dist"),
                (p.image_height, "img_ht"),
                (p.magnification.expect("finite object"), "m"),
                (p.working_f_number, "fno"),
                (p.lagrange_invariant, "opt_inv"),
                (p.entrance_pupil.z, "enp_dist"),
                (p.entrance_pupil.diameter / 2.0, "enp_radius"),
                (xp.z - z_last, "exp_dist"),
                (xp.diameter / 2.0, "exp_radius"),
                (p.field_angle_deg, "obj_ang"),
            ],
        );
        let optiland = get(conjugate, "first_order.optiland");
        check_all(
            &mut tally,
            "finite conjugate (optiland)",
            REL_EXACT,
            name,
            optiland,
            &[
                (p.magnification.unwrap(), "raw.magnification"),
                (-p.lagrange_invariant, "raw.invariant"),
                (p.entrance_pupil.z, "lens_frame.z_entrance_pupil"),
                (xp.z, "lens_frame.z_exit_pupil"),
                (xp.diameter, "lens_frame.exit_pupil_diameter"),
            ],
        );
        tally.check(
            "finite conjugate (rayoptics)",
            p.z_image,
            num(get(conjugate, "image_plane.z")),
            REL_EXACT,
            ABS_MM,
            &format!("{name} image_plane.z"),
        );
        let distance = p.object_distance.unwrap();
        let sensor = sensor_z(&at, ObjectPosition::Finite { distance }).expect("real image");
        tally.check(
            "focus vs marginal ray",
            sensor,
            marginal_focus(&p),
            1e-12,
            0.0,
            &format!("{name} sensor"),
        );
    }
    tally.print("first order, finite conjugate");
}

/// Paraxial marginal and chief rays surface by surface: height and slope after each surface
/// (optiland), angle of incidence after refraction (rayoptics `aoi` = A / n'), and the chief
/// ray in the image plane the oracle used.
#[test]
fn paraxial_rays_at_every_surface() {
    let mut tally = Tally::default();
    for name in ORACLE_LENSES {
        let oracle = load_oracle(name);
        let at = system(&oracle);
        for (conjugate, p) in [
            ("infinite_conjugate", infinite(&oracle, &at)),
            ("finite_conjugate", finite(&oracle, &at)),
        ] {
            let block = get(oracle.lens(), &format!("{conjugate}.paraxial_rays"));
            for (which, ray) in [("marginal", &p.marginal), ("chief", &p.chief)] {
                let optiland = get(block, &format!("optiland.{which}")).as_array().unwrap();
                let rayoptics = get(block, &format!("rayoptics.{which}"))
                    .as_array()
                    .unwrap();
                for (k, ours) in ray.surfaces.iter().enumerate() {
                    let row = nums(&optiland[k + 1]);
                    let what = format!("{name} {conjugate} {which} surface {}", k + 1);
                    tally.check(
                        "ray heights",
                        ours.y,
                        row[0],
                        REL_EXACT,
                        ABS_MM,
                        &format!("{what} y"),
                    );
                    tally.check(
                        "ray slopes",
                        ours.u_after,
                        row[1],
                        REL_EXACT,
                        ABS_MM,
                        &format!("{what} u'"),
                    );
                    // rayoptics is exact only at the finite conjugate (see the module doc).
                    if conjugate == "finite_conjugate" {
                        let aoi = nums(&rayoptics[k + 1])[2];
                        let ours_aoi = ours.incidence / at.surfaces[k].index_after;
                        tally.check(
                            "ray incidence",
                            ours_aoi,
                            aoi,
                            REL_EXACT,
                            ABS_MM,
                            &format!("{what} aoi"),
                        );
                    }
                }
                let z_image_used = num(get(
                    oracle.lens(),
                    &format!("{conjugate}.first_order.optiland.lens_frame.z_image_surface_used"),
                ));
                let image_row = nums(&optiland[ray.surfaces.len() + 1]);
                tally.check(
                    "ray heights",
                    ray.image_space_height(z_image_used),
                    image_row[0],
                    REL_EXACT,
                    ABS_MM,
                    &format!("{name} {conjugate} {which} image plane y"),
                );
            }
        }
    }
    tally.print("paraxial rays");
}
