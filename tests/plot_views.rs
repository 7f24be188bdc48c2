//! The plot views draw the data they are given: checked on the drawn-data summary, the PNG
//! pixels and the SVG text. Data comes from the Cooke triplet truth file so the views are
//! exercised at realistic scales.
#![cfg(feature = "plot")]

mod common;

use lensbake::plot::{
    Drawn, FanCurve, FanField, Format, LayoutPlot, LsaPlot, RayFanPlot, SeidelBar, SeidelPlot,
    View, WavelengthCurve, render, write_plot,
};
use lensbake::system::LensSystem;

const COOKE: &str = "optiland_cooke_triplet";

/// Decodes a PNG and returns (width, height, RGB pixels).
fn decode_png(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut pixels).unwrap();
    pixels.truncate(info.buffer_size());
    assert_eq!(info.color_type, png::ColorType::Rgb);
    (info.width, info.height, pixels)
}

/// Checks the PNG has the view's size and draws something (text and lines, not only white), and
/// the SVG carries `title` as text. Writes both under $LENSBAKE_PLOT_PREVIEW when set, for eyes.
fn check_both_formats<V: View>(view: &V, title: &str, preview_name: &str) -> Drawn {
    let png = render(view, Format::Png).unwrap();
    let (width, height, pixels) = decode_png(&png.bytes);
    assert_eq!((width, height), view.size());
    let ink = pixels.chunks(3).filter(|p| p != &[255, 255, 255]).count();
    let dark = pixels
        .chunks(3)
        .filter(|p| p.iter().all(|&c| c < 80))
        .count();
    assert!(
        ink > 2000,
        "{preview_name}: only {ink} non-background pixels"
    );
    assert!(
        dark > 500,
        "{preview_name}: only {dark} dark pixels: text and axes missing?"
    );
    let svg = render(view, Format::Svg).unwrap();
    let text = String::from_utf8(svg.bytes.clone()).unwrap();
    assert!(
        text.contains(title),
        "{preview_name}: SVG lacks the title {title:?}"
    );
    assert!(text.contains("font-family=\"DejaVu Sans, sans-serif\""));
    // The font itself travels in the file: an @font-face rule right inside the root element
    // whose data URL holds the whole TrueType file (base64 of 0x00010000, the sfnt version).
    let root_end = text.find('>').unwrap() + 1;
    assert!(
        text[root_end..].starts_with(
            "<style>@font-face{font-family:\"DejaVu Sans\";src:url(data:font/ttf;base64,AAEAAA"
        ),
        "{preview_name}: SVG does not embed its font"
    );
    assert!(
        text.len() > 1_000_000,
        "{preview_name}: embedded font truncated"
    );
    assert_eq!(png.drawn, svg.drawn, "both backends draw the same data");
    if let Some(dir) = std::env::var_os("LENSBAKE_PLOT_PREVIEW") {
        let dir = std::path::PathBuf::from(dir);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(format!("{preview_name}.png")), &png.bytes).unwrap();
        std::fs::write(dir.join(format!("{preview_name}.svg")), &svg.bytes).unwrap();
    }
    png.drawn
}

#[test]
fn layout_draws_every_surface_within_its_clear_aperture() {
    let prescription = common::load_oracle(COOKE).prescription;
    let system = LensSystem::from_prescription(prescription.clone()).unwrap();
    let view = LayoutPlot::of_system("Cooke triplet", &system.at(587.56));
    let drawn = check_both_formats(&view, "Cooke triplet: layout", "layout");
    for (i, surface) in prescription.surfaces.iter().enumerate() {
        let label = format!("surface {}", i + 1);
        let series = drawn
            .series("layout", &label)
            .expect("every surface is drawn");
        let reach = series.points.iter().map(|p| p.1.abs()).fold(0.0, f64::max);
        let a = surface.semi_aperture;
        assert!(
            (reach - a).abs() <= 1e-12 * a,
            "{label}: drawn to {reach}, aperture {a}"
        );
        let vertex: f64 = prescription.surfaces[..i].iter().map(|s| s.thickness).sum();
        for &(z, y) in &series.points {
            let sag = surface.shape.sag(y.abs()).unwrap();
            assert!(
                (z - vertex - sag).abs() < 1e-12,
                "{label}: point off the surface"
            );
        }
    }
    assert_eq!(
        view.elements.len(),
        3,
        "three singlets: three shaded glass gaps"
    );
}

#[test]
fn seidel_bars_are_the_per_surface_terms_and_their_sums() {
    let json = common::load_oracle(COOKE).json;
    let seidel = &json["lenses"][0]["infinite_conjugate"]["seidel"]["rayoptics"];
    let terms =
        |v: &serde_json::Value| -> [f64; 5] { std::array::from_fn(|k| v[k].as_f64().unwrap()) };
    let surfaces: Vec<SeidelBar> = (1..=6)
        .map(|s| SeidelBar {
            surface: s,
            terms: terms(&seidel["per_surface"][s.to_string()]),
        })
        .collect();
    let sums = terms(&seidel["sum"]);
    let view = SeidelPlot {
        lens: "Cooke triplet".into(),
        wavelength_nm: 587.56,
        surfaces: surfaces.clone(),
        sums,
    };
    let drawn = check_both_formats(&view, "Cooke triplet: Seidel sums", "seidel");
    for (k, name) in ["S_I", "S_II", "S_III", "S_IV", "S_V"].iter().enumerate() {
        let bars = &drawn.series("Seidel", name).unwrap().points;
        assert_eq!(bars.len(), 7, "six surfaces and the sum");
        assert_eq!(bars[6].1, sums[k]);
        let total: f64 = bars[..6].iter().map(|b| b.1).sum();
        assert!(
            (total - sums[k]).abs() < 1e-9,
            "{name}: bars add up to the sum bar"
        );
    }
}

#[test]
fn lsa_is_drawn_with_pupil_height_up() {
    let json = common::load_oracle(COOKE).json;
    let points: Vec<(f64, f64)> = json["lenses"][0]["quick_reference"]["lsa"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| (p[0].as_f64().unwrap(), p[1].as_f64().unwrap()))
        .collect();
    let view = LsaPlot {
        lens: "Cooke triplet".into(),
        curves: vec![WavelengthCurve {
            wavelength_nm: 587.56,
            points: points.clone(),
        }],
    };
    let drawn = check_both_formats(&view, "Cooke triplet: longitudinal spherical", "lsa");
    let series = drawn.series("spherical", "587.6 nm").unwrap();
    for (drawn, given) in series.points.iter().zip(&points) {
        assert_eq!((drawn.1, drawn.0), *given);
    }
}

#[test]
fn a_field_whose_rays_all_vignette_says_so() {
    let fan = |k: f64| FanCurve {
        wavelength_nm: 587.56,
        points: (-10..=10)
            .map(|i| i as f64 / 10.0)
            .map(|p| (p, k * p * p * p))
            .collect(),
    };
    let view = RayFanPlot {
        lens: "Test lens".into(),
        fields: vec![
            FanField {
                field_deg: 40.0,
                tangential: vec![FanCurve {
                    wavelength_nm: 587.56,
                    points: vec![],
                }],
                sagittal: vec![],
                dropped_nm: vec![],
            },
            FanField {
                field_deg: 0.0,
                tangential: vec![fan(0.01)],
                sagittal: vec![fan(0.01)],
                dropped_nm: vec![486.13],
            },
        ],
    };
    let drawn = check_both_formats(
        &view,
        "Test lens: transverse ray aberration",
        "fan-vignetted",
    );
    let messages: Vec<&str> = drawn.messages().collect();
    let dropped = "not drawn: 486.1 nm (pupil-centre ray vignetted)";
    assert_eq!(
        messages,
        [
            "All rays vignetted at 40.00°",
            "All rays vignetted at 40.00°",
            dropped,
            dropped
        ]
    );
    let svg = render(&view, Format::Svg).unwrap();
    assert!(
        String::from_utf8(svg.bytes)
            .unwrap()
            .contains("All rays vignetted at 40.00°")
    );
    assert_eq!(drawn.panels.len(), 4);
    assert_eq!(
        drawn.panels[2].series.len(),
        1,
        "the on-axis fans have data"
    );
}

#[test]
fn files_are_written_whole_and_the_format_follows_the_extension() {
    let dir = std::env::temp_dir().join(format!("lensbake-plot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let view = LsaPlot {
        lens: "Flat".into(),
        curves: vec![],
    };
    let png = dir.join("lsa.png");
    let drawn = write_plot(&view, &png).unwrap();
    assert_eq!(
        drawn.messages().count(),
        1,
        "an empty plot says why it is empty"
    );
    assert_eq!(&std::fs::read(&png).unwrap()[..8], b"\x89PNG\r\n\x1a\n");
    let svg = dir.join("lsa.SVG");
    write_plot(&view, &svg).unwrap();
    assert!(std::fs::read_to_string(&svg).unwrap().starts_with("<svg"));
    let error = write_plot(&view, &dir.join("lsa.jpg")).unwrap_err();
    assert!(error.to_string().contains("lsa.jpg"), "{error}");
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn curve_views_draw_their_data_with_labelled_series() {
    use lensbake::plot::{
        DistortionPlot, FieldCurve, FieldCurvesPlot, LateralColorPlot, Spot, SpotField, SpotPlot,
        VignettingPlot,
    };
    let json = common::load_oracle(COOKE).json;
    let distortion: Vec<(f64, f64)> = json["lenses"][0]["quick_reference"]["distortion_percent"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| (p[0].as_f64().unwrap(), p[1].as_f64().unwrap()))
        .collect();
    let view = DistortionPlot {
        lens: "Cooke triplet".into(),
        wavelength_nm: 587.56,
        reference: "f·tan θ".into(),
        points: distortion.clone(),
    };
    let drawn = check_both_formats(&view, "Cooke triplet: distortion", "distortion");
    let series = &drawn.panels[0].series[0];
    assert_eq!(series.label, "587.6 nm, against f·tan θ");
    let swapped: Vec<(f64, f64)> = distortion.iter().map(|&(f, d)| (d, f)).collect();
    assert_eq!(series.points, swapped, "percent across, field up");

    let fields = [0.0, 10.0, 20.0];
    let view = FieldCurvesPlot {
        lens: "Cooke triplet".into(),
        curves: [486.13, 587.56, 656.27]
            .iter()
            .map(|&w| FieldCurve {
                wavelength_nm: w,
                points: fields
                    .iter()
                    .map(|&f: &f64| (f, -0.001 * f * f, 0.002 * f * f))
                    .collect(),
            })
            .collect(),
    };
    let drawn = check_both_formats(&view, "astigmatic field curves", "field-curves");
    assert_eq!(
        drawn.panels[0].series.len(),
        6,
        "S and T at three wavelengths"
    );
    assert_eq!(
        drawn.series("field", "T 587.6 nm").unwrap().points[2],
        (0.8, 20.0)
    );

    let view = LateralColorPlot {
        lens: "Cooke triplet".into(),
        reference_nm: 587.56,
        disperses: true,
        curves: vec![WavelengthCurve {
            wavelength_nm: 486.13,
            points: vec![(0.0, 0.0), (10.0, 0.002), (20.0, 0.005)],
        }],
    };
    let drawn = check_both_formats(&view, "lateral colour", "lateral-color");
    assert_eq!(
        drawn.series("lateral", "486.1 nm").unwrap().points[2],
        (20.0, 5.0),
        "µm"
    );

    let view = VignettingPlot {
        lens: "Cooke triplet".into(),
        points: vec![(0.0, 1.0, 1.0), (10.0, 0.93, 1.0), (20.0, 0.7, 0.82)],
    };
    let drawn = check_both_formats(&view, "relative illumination", "vignetting");
    assert_eq!(drawn.panels[0].series.len(), 2);

    let ring = |r: f64| -> Vec<(f64, f64)> {
        (0..200)
            .map(|i| i as f64 * 0.1)
            .map(|a| (r * a.cos(), r * a.sin()))
            .collect()
    };
    let view = SpotPlot {
        lens: "Cooke triplet".into(),
        fields: vec![
            SpotField {
                field_deg: 20.0,
                field_x_deg: 0.0,
                spots: vec![Spot {
                    wavelength_nm: 587.56,
                    points: vec![],
                    rms_radius_mm: 0.0,
                    geometric_radius_mm: 0.0,
                    airy_radius_mm: 0.0036,
                }],
            },
            SpotField {
                field_deg: 0.0,
                field_x_deg: 0.0,
                spots: vec![Spot {
                    wavelength_nm: 587.56,
                    points: ring(0.01),
                    rms_radius_mm: 0.01,
                    geometric_radius_mm: 0.01,
                    airy_radius_mm: 0.0036,
                }],
            },
        ],
    };
    let drawn = check_both_formats(&view, "spot diagrams", "spot");
    assert_eq!(drawn.panels[0].messages, ["All rays vignetted at 20.00°"]);
    assert!(drawn.panels[1].messages[0].starts_with("RMS 10.00 µm"));
    let far = drawn.panels[1].series[0]
        .points
        .iter()
        .map(|p| p.0.hypot(p.1))
        .fold(0.0, f64::max);
    assert!((far - 10.0).abs() < 1e-9, "spots are drawn in µm");
}
