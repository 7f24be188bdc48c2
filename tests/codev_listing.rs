//! The CODE V 10.8 listing of its "Double Gauss F/2" sample (tests/data/truth/lenses/
//! ag_dblgauss.lis), reproduced to every printed digit: first-order data, the paraxial ray
//! table (`fio`) and the third-order table (`tho`, transverse aberrations, colour and PTZ).
//!
//! The lens is the oracle's table of the same design (full-precision radii and indices at
//! 587.6 nm, nF/nC at 486.1/656.3 nm); EPD, field and the image defocus are read from the
//! listing itself. Each value must agree within half a unit of its last printed digit. The one
//! input known only to printed digits is the image defocus (-0.400269 mm, +-5e-7): heights in
//! the IMG row of `fio` carry that uncertainty times the ray slope on top of their own rounding.

mod common;

use common::{assert_printed, assert_printed_within, load_oracle, testdata_dir};
use lensbake::paraxial::{Aperture, Field, ObjectPosition, Paraxial, ParaxialOptions, StopChoice};
use lensbake::seidel::{IndexDifferences, Seidel};
use lensbake::system::LensSystem;
use std::collections::BTreeMap;

/// A number as printed: its value and how many digits follow the decimal point.
#[derive(Clone, Copy, Debug)]
struct Printed {
    value: f64,
    decimals: i32,
}

impl Printed {
    fn parse(token: &str) -> Option<Printed> {
        let value = token.parse::<f64>().ok()?;
        let decimals = token.split_once('.').map_or(0, |(_, d)| d.len() as i32);
        Some(Printed { value, decimals })
    }
}

/// The parts of the listing the tests compare against.
struct Listing {
    /// "EFL", "ENTRANCE PUPIL DIA", ... from the INFINITE CONJUGATES block.
    first_order: BTreeMap<String, Printed>,
    epd: f64,
    max_field_deg: f64,
    /// IMG thickness: the image surface's offset from the paraxial image (PIM solve).
    image_defocus: Printed,
    /// Row label ("EP", "1", "STO", "IMG", ...) to its numbers, in order.
    fio: Vec<(String, Vec<Printed>)>,
    tho: Vec<(String, Vec<Printed>)>,
}

fn numbers(tokens: &[&str]) -> Vec<Printed> {
    tokens.iter().filter_map(|t| Printed::parse(t)).collect()
}

/// Rows after the line containing `header` up to the first non-blank line that is not a row
/// label followed by numbers.
fn table(lines: &[&str], header: &str) -> Vec<(String, Vec<Printed>)> {
    let start = lines
        .iter()
        .position(|l| l.contains(header))
        .unwrap_or_else(|| panic!("listing has no `{header}` table"))
        + 1;
    lines[start..]
        .iter()
        .map(|l| l.split_whitespace().collect::<Vec<_>>())
        .filter(|t| !t.is_empty())
        .take_while(|t| t.len() > 1 && numbers(&t[1..]).len() == t.len() - 1)
        .map(|t| (t[0].to_string(), numbers(&t[1..])))
        .collect()
}

fn read_listing() -> Listing {
    let path = testdata_dir().join("lenses/ag_dblgauss.lis");
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let lines: Vec<&str> = text.lines().collect();
    let spec = |key: &str| -> Vec<f64> {
        let line = lines
            .iter()
            .find(|l| l.split_whitespace().next() == Some(key))
            .unwrap_or_else(|| panic!("listing has no {key} line"));
        line.split_whitespace()
            .skip(1)
            .filter_map(|t| t.parse().ok())
            .collect()
    };
    let image_row = lines
        .iter()
        .find(|l| l.trim_start().starts_with("IMG:"))
        .expect("IMG row of the surface table");
    let image_defocus = Printed::parse(image_row.split_whitespace().nth(2).unwrap()).unwrap();

    let start = lines
        .iter()
        .position(|l| l.contains("INFINITE CONJUGATES"))
        .expect("first-order block");
    let mut first_order = BTreeMap::new();
    let mut section = String::new();
    for line in &lines[start + 1..] {
        if line.starts_with("CODE V>") {
            break;
        }
        let tokens: Vec<&str> = line.split_whitespace().collect();
        match tokens.iter().position(|t| Printed::parse(t).is_some()) {
            None => section = tokens.join(" "),
            Some(at) => {
                let key = tokens[..at].join(" ");
                let key = if ["DIA", "THI", "HT", "ANG"].contains(&key.as_str()) {
                    format!("{section} {key}")
                } else {
                    key
                };
                first_order.insert(key, Printed::parse(tokens[at]).unwrap());
            }
        }
    }
    Listing {
        first_order,
        epd: spec("EPD")[0],
        max_field_deg: spec("YAN").into_iter().fold(0.0, f64::max),
        image_defocus,
        fio: table(&lines, "HMY"),
        tho: table(&lines, "SA         TCO"),
    }
}

#[test]
fn codev_first_order_paraxial_rays_and_third_order() {
    let listing = read_listing();
    let oracle = load_oracle("codev_ag_dblgauss");
    let at = LensSystem::from_prescription(oracle.prescription.clone())
        .expect("valid")
        .at(oracle.wavelength_nm());
    let p = Paraxial::new(
        &at,
        &ParaxialOptions {
            object: ObjectPosition::Infinite,
            aperture: Aperture::EntrancePupilDiameter(listing.epd),
            field: Field::Angle {
                deg: listing.max_field_deg,
            },
            stop: StopChoice::Marked,
        },
    )
    .expect("paraxial");
    let f = &p.first_order;
    let z_last = f.z_last_vertex;
    let xp = p.exit_pupil.expect("finite exit pupil");
    let z_image_surface = p.z_image + listing.image_defocus.value;
    let defocus_uncertainty = 0.5 * 10f64.powi(-listing.image_defocus.decimals);

    let expected_first_order = [
        ("EFL", f.efl),
        ("BFL", f.bfl),
        ("FFL", f.ffl),
        ("FNO", p.f_number),
        ("IMG DIS", z_image_surface - z_last),
        ("OAL", z_last),
        ("PARAXIAL IMAGE HT", p.image_height),
        ("PARAXIAL IMAGE ANG", p.field_angle_deg),
        ("ENTRANCE PUPIL DIA", p.entrance_pupil.diameter),
        ("ENTRANCE PUPIL THI", p.entrance_pupil.z),
        ("EXIT PUPIL DIA", xp.diameter),
        ("EXIT PUPIL THI", xp.z - z_last),
    ];
    assert_eq!(listing.first_order.len(), expected_first_order.len());
    for (key, ours) in expected_first_order {
        let printed = listing.first_order[key];
        assert_printed(ours, printed.value, printed.decimals, key);
    }

    // fio: HMY UMY N*IMY HCY UCY N*ICY; the EP and IMG rows have no angles of incidence.
    let (m, c) = (&p.marginal, &p.chief);
    let z_entrance = p.entrance_pupil.z;
    assert_eq!(listing.fio.len(), at.surfaces.len() + 2);
    for (row, (label, printed)) in listing.fio.iter().enumerate() {
        let ours: Vec<f64> = match label.as_str() {
            "EP" => vec![
                m.object_space_height(z_entrance),
                m.object_slope(),
                c.object_space_height(z_entrance),
                c.object_slope(),
            ],
            "IMG" => vec![
                m.image_space_height(z_image_surface),
                m.image_slope(),
                c.image_space_height(z_image_surface),
                c.image_slope(),
            ],
            _ => {
                let (ms, cs) = (&m.surfaces[row - 1], &c.surfaces[row - 1]);
                vec![
                    ms.y,
                    ms.u_after,
                    ms.incidence,
                    cs.y,
                    cs.u_after,
                    cs.incidence,
                ]
            }
        };
        assert_eq!(ours.len(), printed.len(), "fio row {label}");
        let inherited = match label.as_str() {
            "IMG" => {
                [m.image_slope(), 0.0, c.image_slope(), 0.0].map(|s| s.abs() * defocus_uncertainty)
            }
            _ => [0.0; 4],
        };
        for (k, (ours, printed)) in ours.iter().zip(printed).enumerate() {
            let extra = inherited.get(k).copied().unwrap_or(0.0);
            assert_printed_within(
                *ours,
                printed.value,
                printed.decimals,
                extra,
                &format!("fio {label} column {k}"),
            );
        }
    }

    // tho: SA TCO TAS SAS PTB DST AX LAT PTZ per surface and their sum.
    let lines = oracle.lines.as_ref().expect("nF/nC in the table");
    let colour = IndexDifferences {
        short_nm: lines.f_nm,
        long_nm: lines.c_nm,
        object: lines.object_f - lines.object_c,
        after: lines.f.iter().zip(&lines.c).map(|(f, c)| f - c).collect(),
    };
    let seidel = Seidel::new(&at, &p, Some(&colour));
    assert_eq!(listing.tho.len(), at.surfaces.len() + 1);
    for (row, (label, printed)) in listing.tho.iter().enumerate() {
        let (t, colour, ptz) = if label == "SUM" {
            (
                seidel.transverse,
                seidel.transverse_colour.unwrap(),
                seidel.ptz,
            )
        } else {
            let s = &seidel.surfaces[row];
            (s.transverse, s.transverse_colour.unwrap(), s.ptz)
        };
        let ours = [
            t.tsa, t.tco, t.tas, t.sas, t.ptb, t.dst, colour.ax, colour.lat, ptz,
        ];
        assert_eq!(printed.len(), ours.len(), "tho row {label}");
        for (column, (ours, printed)) in
            ["SA", "TCO", "TAS", "SAS", "PTB", "DST", "AX", "LAT", "PTZ"]
                .iter()
                .zip(ours.iter().zip(printed))
        {
            assert_printed(
                *ours,
                printed.value,
                printed.decimals,
                &format!("tho {label} {column}"),
            );
        }
    }
}
