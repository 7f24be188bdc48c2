//! `analyze` of lenses placed off one axis (lensbake::analysis::placed): real-ray first-order
//! data, fans, spots and wavefronts about chief rays, against analytic identities (a centred lens
//! through this path equals its paraxial analysis; a flat fold mirror changes nothing; a tilted
//! plate displaces and splits the focus as Snell's law and Coddington's equations say).

mod common;

use lensbake::analysis::placed::{PlacedAnalysis, PlacedOptions, analyze_placed};
use lensbake::analysis::{Analysis, AnalyzeOptions, analyze};
use lensbake::prescription::formats::{Frame, PlacedLens};
use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
use lensbake::system::LensSystem;
use lensbake::trace::placed::PlacedTracer;
use lensbake::{LoadOptions, load_lens};

/// Rotation by `degrees` about x (right-handed), as a frame at `origin`.
fn tilted_x(degrees: f64, origin: [f64; 3]) -> Frame {
    let (s, c) = degrees.to_radians().sin_cos();
    Frame {
        linear: [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
        origin,
    }
}

fn at_z(z: f64) -> Frame {
    Frame {
        origin: [0.0, 0.0, z],
        ..Frame::IDENTITY
    }
}

/// `prescription` placed surface by surface on the axis, with `frames` where given, nothing
/// clipping (first-order data do not depend on apertures).
fn placed(prescription: Prescription, frames: Vec<Frame>, image: Frame) -> PlacedLens {
    let n = prescription.surfaces.len();
    PlacedLens {
        prescription,
        frames,
        image,
        clips: vec![false; n],
        outlines: vec![None; n],
        rotation_radii: vec![None; n],
    }
}

/// The vertices of a centred lens along z.
fn vertex_frames(p: &Prescription) -> Vec<Frame> {
    p.surfaces
        .iter()
        .scan(0.0, |z, s| {
            let frame = at_z(*z);
            *z += s.thickness;
            Some(frame)
        })
        .collect()
}

/// The paraxial analysis of a bundled lens at its design conditions, and the lens.
fn paraxial(name: &str) -> (LensSystem, Analysis) {
    let lens = load_lens(name, &LoadOptions::default()).unwrap();
    let analysis = analyze(&lens.system, &AnalyzeOptions::default()).unwrap();
    (lens.system, analysis)
}

fn real(lens: &PlacedLens, paraxial: &Analysis, fields: Vec<[f64; 2]>) -> PlacedAnalysis {
    let tracer = PlacedTracer::new(lens, paraxial.wavelength_nm).unwrap();
    let mut options = PlacedOptions::new(
        paraxial.wavelength_nm,
        fields,
        paraxial.first_order.entrance_pupil.diameter,
    );
    options.wave_samples = 32;
    analyze_placed(&tracer, &options).unwrap()
}

fn close(actual: f64, expected: f64, scale: f64, what: &str) {
    let error = (actual - expected).abs() / scale.abs();
    assert!(
        error <= 1e-9,
        "{what}: {actual} vs {expected} (relative {error:e})"
    );
}

/// Lenses without mirrors, run through the real-ray path with the image plane at the paraxial
/// rear focus: every first-order number equals the paraxial one to 1e-9 of the focal length.
#[test]
fn a_centred_lens_has_its_paraxial_first_order_data() {
    for name in [
        "cooke-triplet",
        "dgauss-50mm",
        "telephoto-250mm",
        "petzval",
        "tessar",
    ] {
        let (system, paraxial) = paraxial(name);
        let f = &paraxial.first_order;
        let p = system.prescription.clone();
        let frames = vertex_frames(&p);
        let lens = placed(p, frames, at_z(f.z_rear_focal));
        let a = real(&lens, &paraxial, vec![[0.0, 0.0]]);
        let r = &a.first_order;
        assert!(
            r.agreement < 1e-9,
            "{name}: differences agree to {}",
            r.agreement
        );
        let efl = f.efl;
        for section in 0..2 {
            let what = |q: &str| format!("{name} {q} section {section}");
            close(r.efl_mm[section].unwrap(), efl, efl, &what("EFL"));
            close(r.bfd_mm[section].unwrap(), f.bfl, efl, &what("BFD"));
            close(
                r.focus_from_image_mm[section].unwrap(),
                0.0,
                efl,
                &what("focus"),
            );
            close(
                r.image_scale_mm[section][section],
                efl,
                efl,
                &what("image scale"),
            );
            close(
                r.image_scale_mm[section][1 - section],
                0.0,
                efl,
                &what("image twist"),
            );
            let xp = f.exit_pupil.unwrap().z;
            close(
                a.axis_ray.exit_pupil_to_image_mm[section].unwrap(),
                f.z_rear_focal - xp,
                efl,
                &what("exit pupil"),
            );
        }
        // On the axis the lens is symmetric: the two sections' foci and fans agree.
        let field = &a.fields[0];
        let [fx, fy] = field.chief.focus_from_image_mm.map(Option::unwrap);
        close(fx, fy, efl, name);
        for (t, s) in field.fans.tangential.iter().zip(&field.fans.sagittal) {
            let (t, s) = (t.error_mm.unwrap()[1], s.error_mm.unwrap()[0]);
            assert!((t - s).abs() <= 1e-12 * efl, "{name}: fans {t} vs {s}");
        }
    }
}

/// The wavefront on the axis about the real chief ray equals the centred wave module's (which
/// takes the paraxial exit pupil and image plane): same rays, same sphere.
#[test]
fn the_axial_wavefront_is_the_centred_wave_modules() {
    for name in ["cooke-triplet", "dgauss-50mm"] {
        let (system, paraxial) = paraxial(name);
        let f = &paraxial.first_order;
        let p = system.prescription.clone();
        let frames = vertex_frames(&p);
        let lens = placed(p, frames, at_z(f.z_paraxial_image));
        let a = real(&lens, &paraxial, vec![[0.0, 0.0]]);
        let ours = a.fields[0].wave.as_ref().unwrap();
        let options = lensbake::wave::WaveOptions {
            field_deg: 0.0,
            wavelengths_nm: vec![paraxial.wavelength_nm],
            weights: vec![],
            epd_mm: Some(f.entrance_pupil.diameter),
            f_number: None,
            object_distance_mm: None,
            ray_aiming: None,
            sampling: lensbake::wave::Sampling {
                samples: 32,
                grid: 64,
            },
            defocus_mm: 0.0,
        };
        let theirs = lensbake::wave::lens::wavefront(&system, &options)
            .unwrap()
            .stats();
        assert_eq!(ours.stats.transmitted_samples, theirs.transmitted_samples);
        for (q, x, y) in [
            ("RMS", ours.stats.rms_waves, theirs.rms_waves),
            ("PV", ours.stats.pv_waves, theirs.pv_waves),
            ("Strehl", ours.stats.strehl, theirs.strehl),
        ] {
            assert!(
                // Measured: 4e-10 (the double Gauss's Strehl) and below.
                (x - y).abs() <= 1e-9 * y.abs().max(1e-3),
                "{name} {q}: {x} vs {y}"
            );
        }
    }
}

/// A flat mirror at 45 degrees between the Cooke triplet and its focus: EFL, BFD (from the
/// mirror, the last surface, as the unfolded lens counts it), foci, exit pupil, fans, spots and
/// wavefronts are the unfolded lens's, field by field, with the image plane's axes the unfolded
/// ones carried through the mirror.
#[test]
fn a_flat_fold_mirror_changes_nothing() {
    let (system, paraxial) = paraxial("cooke-triplet");
    let f = &paraxial.first_order;
    let fields = vec![[0.0, 0.0], [0.0, 10.0], [5.0, -8.0]];
    let p = system.prescription.clone();
    let frames = vertex_frames(&p);
    let mirror_z = f.z_last_vertex + f.bfl / 2.0;
    let to_focus = f.z_rear_focal - mirror_z;
    let mut unfolded_p = p.clone();
    unfolded_p
        .surfaces
        .push(Surface::open(Shape::Plane, to_focus, Medium::Air, 1e3));
    let mut unfolded_frames = frames.clone();
    unfolded_frames.push(at_z(mirror_z));
    let mut unfolded = placed(unfolded_p, unfolded_frames, at_z(f.z_rear_focal));
    // A plane that clips nothing would be passed over; the unfolded mirror is a surface the
    // beam meets (the last one, which the BFD counts from), as the centred reading keeps it.
    *unfolded.clips.last_mut().unwrap() = true;
    let mut folded_p = p;
    folded_p
        .surfaces
        .push(Surface::open(Shape::Plane, to_focus, Medium::Mirror, 1e3));
    let mut folded_frames = frames;
    folded_frames.push(tilted_x(45.0, [0.0, 0.0, mirror_z]));
    // The mirror sends the axis to +y; the image plane faces it, its y axis along +z (where the
    // unfolded y turns).
    let folded = placed(
        folded_p,
        folded_frames,
        tilted_x(90.0, [0.0, to_focus, mirror_z]),
    );
    let a = real(&unfolded, &paraxial, fields.clone());
    let b = real(&folded, &paraxial, fields);
    let efl = f.efl;
    let first = |x: &PlacedAnalysis| {
        let r = &x.first_order;
        let mut all: Vec<f64> = r
            .efl_mm
            .iter()
            .chain(&r.bfd_mm)
            .map(|v| v.unwrap())
            .collect();
        all.extend(r.image_scale_mm.iter().flatten());
        all
    };
    close(
        a.first_order.bfd_mm[1].unwrap(),
        to_focus,
        efl,
        "unfolded BFD from the plane",
    );
    for (x, y) in first(&a).into_iter().zip(first(&b)) {
        close(y, x, efl, "first order");
    }
    for (fa, fb) in a.fields.iter().zip(&b.fields) {
        let what = format!("field {:?}", fa.chief.field_deg);
        for k in 0..2 {
            close(
                fb.chief.image_point_mm[k],
                fa.chief.image_point_mm[k],
                efl,
                &what,
            );
            let focus = |x: &lensbake::analysis::placed::PlacedField| {
                x.chief.focus_from_image_mm[k].unwrap()
            };
            close(focus(fb), focus(fa), efl, &what);
        }
        for (ra, rb) in fa
            .fans
            .tangential
            .iter()
            .chain(&fa.fans.sagittal)
            .zip(fb.fans.tangential.iter().chain(&fb.fans.sagittal))
        {
            let (ea, eb) = (ra.error_mm.unwrap(), rb.error_mm.unwrap());
            for k in 0..2 {
                assert!(
                    (ea[k] - eb[k]).abs() <= 1e-12 * efl,
                    "{what}: fan {ea:?} vs {eb:?}"
                );
            }
        }
        close(
            fb.spot.rms_radius_about_chief_mm.unwrap(),
            fa.spot.rms_radius_about_chief_mm.unwrap(),
            fa.spot.rms_radius_about_chief_mm.unwrap(),
            &what,
        );
        let (wa, wb) = (fa.wave.as_ref().unwrap(), fb.wave.as_ref().unwrap());
        assert!(
            (wa.stats.rms_waves - wb.stats.rms_waves).abs() <= 1e-9 * wa.stats.rms_waves.max(1.0),
            "{what}: RMS {} vs {}",
            wa.stats.rms_waves,
            wb.stats.rms_waves
        );
    }
    // Off the axis the triplet has astigmatism: the sections' foci differ.
    let [x, y] = a.fields[1].chief.focus_from_image_mm.map(Option::unwrap);
    assert!((x - y).abs() > 1e-3, "{x} {y}");
}

/// A plate of thickness t and index n tilted by θ about x in the converging beam of an ideal
/// lens of focal length f (the stop), a behind it: the OAR leaves it
/// displaced by t sin θ (1 - cos θ / sqrt(n² - sin² θ)); the EFL stays f; and by Coddington's
/// equations for two parallel planes (L = t / cos θ' the path inside, θ' the refraction angle,
/// s = f - a the distance from the plate's first crossing to the lens's focus) the sagittal
/// focus lies s - L / n and the tangential one s - L cos² θ / (n cos² θ') beyond the second
/// crossing along the OAR: the BFDs.
#[test]
fn a_tilted_plate_displaces_the_axis_and_splits_the_focus_as_coddington_says() {
    let (f, a, t, n) = (100.0, 20.0, 10.0, 1.5);
    for degrees in [5.0_f64, 20.0, 45.0] {
        let theta = degrees.to_radians();
        let inside = (theta.sin() / n).asin();
        let prescription = Prescription {
            provenance: Provenance::default(),
            object_medium: Medium::Air,
            surfaces: vec![
                Surface {
                    stop: Some(StopShape::Circle),
                    ..Surface::open(Shape::IdealLens { focal_length: f }, a, Medium::Air, 10.0)
                },
                Surface::open(Shape::Plane, t, Medium::Index(n), 20.0),
                Surface::open(Shape::Plane, 50.0, Medium::Air, 20.0),
            ],
        };
        let front = tilted_x(degrees, [0.0, 0.0, a]);
        // The back face: t along the plate's normal from the front vertex.
        let normal = front.axis();
        let back = tilted_x(degrees, [0.0, t * normal[1], a + t * normal[2]]);
        let image = at_z(a + 60.0);
        let lens = placed(prescription, vec![at_z(0.0), front, back], image);
        let tracer = PlacedTracer::new(&lens, 587.56).unwrap();
        let options = PlacedOptions::new(587.56, vec![[0.0, 0.0]], 8.0);
        let r = analyze_placed(&tracer, &options).unwrap();
        let what = |q: &str| format!("{degrees} deg: {q}");
        // The OAR leaves the plate parallel to the axis, displaced towards -y, and the ideal
        // lens's beam about it focuses f - a beyond the plate's first crossing, along the axis.
        let displacement =
            t * theta.sin() * (1.0 - theta.cos() / (n * n - theta.sin().powi(2)).sqrt());
        let path = t / inside.cos();
        let s = f - a;
        let sagittal = s - path / n;
        let tangential = s - path * theta.cos().powi(2) / (n * inside.cos().powi(2));
        // The OAR (through the ideal lens's centre) runs along the axis, so the image plane
        // point is the displacement.
        close(
            r.axis_ray.image_point_mm[1],
            -displacement,
            t,
            &what("OAR displacement"),
        );
        close(r.axis_ray.image_point_mm[0], 0.0, t, &what("OAR x"));
        for k in 0..2 {
            close(r.first_order.efl_mm[k].unwrap(), f, f, &what("EFL"));
        }
        close(
            r.first_order.bfd_mm[0].unwrap(),
            sagittal,
            f,
            &what("sagittal BFD"),
        );
        close(
            r.first_order.bfd_mm[1].unwrap(),
            tangential,
            f,
            &what("tangential BFD"),
        );
    }
}

/// The eight corpus files that only the 3-D trace reads: `analyze` reports each, every field's
/// chief ray where `lens check` puts it, no number that is not finite; conditions the 3-D
/// trace does not take are one `error:` line, exit 2.
#[cfg(feature = "cli")]
#[test]
fn analyze_reports_every_lens_off_the_axis_in_the_corpus() {
    use serde_json::Value;
    fn finite_or_null(value: &Value, at: &str) {
        match value {
            Value::Number(n) => assert!(n.as_f64().unwrap().is_finite(), "{at}"),
            Value::Array(items) => items.iter().for_each(|v| finite_or_null(v, at)),
            Value::Object(map) => map.values().for_each(|v| finite_or_null(v, at)),
            _ => {}
        }
    }
    for name in [
        "optiland__complicated_fold_mirrors_setup_v2.zmx",
        "rayoptics__HoO-V2C18Ex46.zmx",
        "rayoptics__HoO-V2C18Ex66.zmx",
        "rayoptics__HoO-V2C18Ex66NEW.zmx",
        "rayoptics__US08011793-1.zmx",
        "rayoptics__CODV_35571.seq",
        "rayoptics__threemir.seq",
        "rayoptics__tilt_test.seq",
    ] {
        let file = format!("tests/data/corpus/{name}");
        let out = common::lensbake(&["analyze", &file, "--json"]);
        let text = String::from_utf8_lossy(&out.stdout);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let json: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(json["real_rays_only"], Value::Bool(true), "{name}");
        finite_or_null(&json, name);
        let check = common::lensbake(&["lens", "check", &file]);
        let listing = String::from_utf8_lossy(&check.stdout);
        // lens check prints each field's chief ray on the image plane (x, y) after the field.
        let chief_rows: Vec<Vec<f64>> = listing
            .lines()
            .skip_while(|l| !l.contains("chief ray x"))
            .skip(1)
            .map_while(|l| {
                let row: Vec<f64> = l
                    .split_whitespace()
                    .take(4)
                    .map_while(|v| v.parse().ok())
                    .collect();
                (row.len() == 4).then_some(row)
            })
            .collect();
        let fields = json["fields"].as_array().unwrap();
        assert_eq!(fields.len(), chief_rows.len(), "{name}: {listing}");
        for (field, row) in fields.iter().zip(&chief_rows) {
            let point = common::nums(&field["chief"]["image_point_mm"]);
            for k in 0..2 {
                assert!(
                    (point[k] - row[2 + k]).abs() <= 1e-6,
                    "{name}: {point:?} vs {row:?}"
                );
            }
        }
        let report = common::lensbake(&["analyze", &file]);
        let text = String::from_utf8_lossy(&report.stdout);
        assert!(
            !text.contains("NaN") && !text.contains("inf "),
            "{name}: {text}"
        );
        assert!(text.contains("Seidel sums: not given"), "{name}");
    }
    let file = "tests/data/corpus/rayoptics__threemir.seq";
    let out = common::lensbake(&["analyze", file, "--object-distance-mm", "1000"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(
        stderr.lines().filter(|l| l.starts_with("error:")).count(),
        1,
        "{stderr}"
    );
    assert!(stderr.contains("takes an object at infinity"), "{stderr}");
}

/// rayoptics 0.9.8's chief rays (through the stop's centre) and ray fans about them on the
/// image plane (tools/analyze_placed_peer.py: the chief ray aimed there by Newton steps on
/// rayoptics' trace) for a three-mirror telescope of off-axis segments and a decentred, tilted
/// image plane, at every field of the files: every point within 1e-9 mm (the first chief ray
/// agrees to 3e-13 mm).
#[test]
fn chief_rays_and_fans_are_where_rayoptics_traces_them() {
    use lensbake::prescription::Problem;
    use lensbake::prescription::formats::{LoadOptions, read_file};
    use lensbake::trace::placed::PlacedBeam;
    use serde_json::Value;
    let text =
        std::fs::read_to_string(common::test_data("corpus/analyze_placed_peers.json")).unwrap();
    let peers: Value = serde_json::from_str(&text).unwrap();
    let mut compared = 0;
    for (name, peer) in peers.as_object().unwrap() {
        let path = common::test_data(&format!("corpus/{name}"));
        let lens = match read_file(&path, &LoadOptions::default())
            .unwrap_err()
            .problem
        {
            Problem::NotRotationallySymmetric { lens, .. } => *lens,
            other => panic!("{name}: {other}"),
        };
        let wavelength = peer["wavelength_nm"].as_f64().unwrap();
        let tracer = PlacedTracer::new(&lens, wavelength).unwrap();
        let beam = PlacedBeam::of(&lens, &tracer).unwrap();
        let fields = peer["fields"].as_array().unwrap();
        let angles = fields
            .iter()
            .map(|f| {
                let v = common::nums(&f["field_deg"]);
                [v[0], v[1]]
            })
            .collect();
        let options = PlacedOptions::new(wavelength, angles, beam.pupil_diameter);
        let ours = analyze_placed(&tracer, &options).unwrap();
        // 21-ray fans: pupil -1, -0.5, 0.5, 1 are rays 0, 5, 15, 20.
        let rays = [0, 5, 15, 20];
        for (field, theirs) in ours.fields.iter().zip(fields) {
            let chief = common::nums(&theirs["chief"]);
            let mut pairs = vec![(field.chief.image_point_mm, [chief[0], chief[1]])];
            for (fan, key) in [
                (&field.fans.tangential, "tangential"),
                (&field.fans.sagittal, "sagittal"),
            ] {
                for (j, point) in common::nums_rows(&theirs[key]).iter().enumerate() {
                    let k = rays[j];
                    assert_eq!(fan[k].pupil, common::num(&peer["pupil"][j]));
                    pairs.push((fan[k].error_mm.unwrap(), [point[0], point[1]]));
                }
            }
            for (a, b) in pairs {
                for i in 0..2 {
                    assert!(
                        (a[i] - b[i]).abs() <= 1e-9,
                        "{name} {:?}: {a:?} vs {b:?}",
                        field.chief.field_deg
                    );
                }
                compared += 1;
            }
        }
    }
    assert_eq!(compared, 63);
}
