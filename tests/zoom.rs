//! Zoom lenses: a CODE V zoom file read at each of its positions has the focal length of that
//! position's own lens data (an independent paraxial trace of the values the file writes), the
//! pickups of that position place its image, and a position the file lacks is one clear error.

mod common;

use common::test_data;
use lensbake::glass::lookup;
use lensbake::prescription::formats::{Format, LoadNote, LoadOptions, read_str};
use lensbake::{AnalyzeOptions, analyze, load_lens};

const ZOOM_FILE: &str = "zoom_two_group.seq";

/// The file's lens at each position, as its text writes it: radii (mm), the glass after each
/// surface, and the thicknesses; the front gap (S2) and the image distance (S5) zoom, the image
/// distance of positions 2 and 3 by its pickup of the front gap (-1.25 x gap + offset).
const RADII: [f64; 5] = [200.0, 30.0, 25.0, -20.0, -80.0];
const GLASSES: [Option<&str>; 5] = [Some("N-BK7"), None, Some("N-BK7"), Some("N-SF2"), None];
const FRONT_GAP: [f64; 3] = [45.0, 25.0, 10.0];
const IMAGE_DISTANCE: [f64; 3] = [71.291, -1.25 * 25.0 + 115.014, -1.25 * 10.0 + 115.381];
/// The file's reference wavelength (`WL 656.27 587.56 486.13`, `REF 2`).
const DESIGN_NM: f64 = 587.56;

fn at_position(k: usize) -> LoadOptions {
    LoadOptions {
        zoom_position: Some(k),
        ..LoadOptions::default()
    }
}

/// Effective focal length and back focal distance by a y-nu trace of a unit-height ray parallel
/// to the axis through the position's surfaces (written here from the file's numbers, not read
/// through lensbake).
fn efl_and_bfl(position: usize) -> (f64, f64) {
    let thickness = [3.0, FRONT_GAP[position], 6.0, 2.0];
    let (mut y, mut nu, mut n) = (1.0, 0.0, 1.0);
    for (i, (radius, glass)) in RADII.iter().zip(GLASSES).enumerate() {
        let n_after = glass.map_or(1.0, |g| lookup(g).unwrap().dispersion().index(DESIGN_NM));
        nu -= y * (n_after - n) / radius;
        n = n_after;
        if let Some(t) = thickness.get(i) {
            y += nu / n * t;
        }
    }
    (-1.0 / nu, -y / nu)
}

#[test]
fn each_zoom_position_has_the_focal_length_of_its_own_lens_data() {
    let path = test_data(ZOOM_FILE);
    let mut focal_lengths = Vec::new();
    for position in 0..3 {
        let lens = load_lens(path.to_str().unwrap(), &at_position(position + 1)).unwrap();
        let surfaces = &lens.system.prescription.surfaces;
        assert_eq!(surfaces[1].thickness, FRONT_GAP[position]);
        assert!((surfaces[4].thickness - IMAGE_DISTANCE[position]).abs() < 1e-12);
        let analysis = analyze(&lens.system, &AnalyzeOptions::default()).unwrap();
        assert_eq!(analysis.wavelength_nm, DESIGN_NM);
        let (efl, bfl) = efl_and_bfl(position);
        let first = &analysis.first_order;
        assert!(
            (first.efl - efl).abs() < 1e-9 * efl,
            "position {}: EFL {} against {efl}",
            position + 1,
            first.efl
        );
        assert!((first.bfl - bfl).abs() < 1e-9 * bfl, "{} {bfl}", first.bfl);
        // The file's image distances (the pickups' included) put the image at the paraxial focus
        // of each position, to the 0.001 mm the file rounds them to.
        assert!(
            (bfl - IMAGE_DISTANCE[position]).abs() < 1e-3,
            "position {}: focus {bfl} mm behind the last vertex, image {}",
            position + 1,
            IMAGE_DISTANCE[position]
        );
        // EPD and the outer field zoom with the position too (`ZOO EPD`, `ZOO YAN F3`).
        assert_eq!(analysis.conditions.epd_mm, [8.0, 11.0, 16.0][position]);
        let outer = analysis.conditions.fields_deg[0];
        assert!(
            (outer - [20.0, 15.0, 10.0][position]).abs() < 1e-12,
            "{outer}"
        );
        focal_lengths.push(first.efl);
    }
    // A zoom: 45.7, 64.5 and 93.3 mm (the trace above, by a second program while designing it).
    for (efl, expected) in focal_lengths.iter().zip([45.662, 64.476, 93.309]) {
        assert!((efl - expected).abs() < 1e-3, "{efl} against {expected}");
    }
}

/// Position 3's image distance comes from its pickup, whatever its `ZOO THI` value says; at
/// position 1, which has no pickup, the `ZOO THI` value is the lens.
#[test]
fn a_pickup_of_a_later_position_decides_that_position_only() {
    let text = std::fs::read_to_string(test_data(ZOOM_FILE)).unwrap();
    let changed = text.replace(
        "ZOO THI S5 71.291 83.764 102.881",
        "ZOO THI S5 70.0 0.5 0.5",
    );
    assert_ne!(changed, text);
    let image_distance = |k: usize| {
        let loaded = read_str(&changed, None, Format::CodeV, &at_position(k)).unwrap();
        loaded.prescription.surfaces[4].thickness
    };
    assert_eq!(image_distance(1), 70.0);
    assert!((image_distance(2) - IMAGE_DISTANCE[1]).abs() < 1e-12);
    assert!((image_distance(3) - IMAGE_DISTANCE[2]).abs() < 1e-12);
    let loaded = read_str(&text, None, Format::CodeV, &at_position(2)).unwrap();
    assert!(loaded.notes.contains(&LoadNote::ZoomPosition {
        position: 2,
        count: 3,
        as_written: vec!["TIT".into()],
    }));
}

#[cfg(feature = "cli")]
#[test]
fn the_command_line_reads_the_position_asked_and_refuses_one_the_file_lacks() {
    let path = test_data(ZOOM_FILE);
    let file = path.to_str().unwrap();
    let efl_line = |args: &[&str]| {
        let out = common::lensbake(args);
        let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(out.status.success(), "{args:?}: {stdout}");
        let line = stdout
            .lines()
            .find(|l| l.contains("EFL (image side"))
            .unwrap_or_else(|| panic!("no EFL line: {stdout}"))
            .to_string();
        line.split_whitespace()
            .find_map(|w| w.parse::<f64>().ok())
            .unwrap()
    };
    let tele = efl_line(&["analyze", file, "--zoom-position", "3"]);
    assert!((tele - efl_and_bfl(2).0).abs() < 1e-5, "{tele}");
    let wide = efl_line(&["analyze", file]);
    assert!((wide - efl_and_bfl(0).0).abs() < 1e-5, "{wide}");
    let out = common::lensbake(&["analyze", file, "--zoom-position", "4"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{stderr}");
    let zoo_line = std::fs::read_to_string(&path)
        .unwrap()
        .lines()
        .position(|l| l == "ZOO 3")
        .unwrap()
        + 1;
    assert!(
        errors[0].contains(&format!("{ZOOM_FILE}:{zoo_line}")) && errors[0].contains("ZOO"),
        "{stderr}"
    );
    assert!(errors[0].contains("zoom position 4"), "{stderr}");
}
