//! Traces, bakes, looks up and computes an MTF through lensbake's root items alone, with the
//! optics core only (`default-features = false`): what the README's "Use as a library" promises.

use lensbake::{
    Apertures, BakeRequest, LoadOptions, Lookup, Outcome, Ray, RayBatch, Tracer, Travel,
    WaveOptions, analyze, bake, load_lens, mtf, read_table, write_table,
};

/// The double Gauss's first-order data, a near-axial ray traced one at a time and in a batch,
/// and that ray's focus agreeing with the paraxial rear focal point to the lens's spherical
/// aberration at 1 mm of its 12.5 mm semi-aperture (the aberration falls as the height squared:
/// 0.0022 mm measured).
#[test]
fn trace_through_the_root() {
    let lens = load_lens("dgauss-50mm", &LoadOptions::default()).unwrap();
    let report = analyze(&lens.system, &Default::default()).unwrap();
    let first = &report.first_order;
    assert!((first.efl - 50.0).abs() < 1.0, "EFL {}", first.efl);

    let tracer = Tracer::new(&lens.system.at(lens.system.design_wavelength_nm()));
    let near_axis = Ray::new([0.0, 1.0, -10.0], [0.0, 0.0, 1.0]).unwrap();
    let one = tracer.trace(near_axis, Travel::Forward);
    assert_eq!(one.outcome, Outcome::Ok);
    let mut batch = RayBatch::new();
    batch.push(near_axis);
    batch.push(Ray::new([0.0, 400.0, -10.0], [0.0, 0.0, 1.0]).unwrap());
    let traced = tracer.trace_batch(&batch, Travel::Forward, Apertures::Checked);
    assert_eq!(traced.rays.get(0), Some(one.ray));
    assert!(
        !traced.outcomes[1].is_ok(),
        "a ray 400 mm off axis misses the lens"
    );

    // A near-axial ray parallel to the axis crosses it at the rear focal point (paraxially):
    // its height over its slope after the lens is the distance to that crossing.
    let out = one.ray;
    let [_, y, z] = out.position();
    let [_, dy, dz] = out.direction();
    let crossing_z = z - y * dz / dy;
    let rear_focus_z = first.z_rear_focal;
    assert!(
        (crossing_z - rear_focus_z).abs() < 0.01,
        "a 1 mm ray crosses the axis at z = {crossing_z}, the rear focal point is at {rear_focus_z}"
    );
}

/// A table baked, written and read back looks a film-side ray up the way the exact trace
/// carries it, to the table's accuracy at 16^3: within a tenth of a pixel of a 1920-pixel
/// full frame (1.9e-3 mm) 20 mm in front of the lens and 3e-5 rad in direction (a near-axial
/// ray: 1.9e-4 mm and 3.0e-6 rad measured; a wrong frame or channel errs by millimetres); a ray
/// far outside the pupil is blocked.
#[test]
fn bake_write_read_and_look_up_through_the_root() {
    let lens = load_lens("dgauss-50mm", &LoadOptions::default()).unwrap();
    let request = BakeRequest {
        resolution: [16; 3],
        focus_mm: Some(2000.0),
        ..BakeRequest::default()
    };
    let table = bake(&lens.system, &request).unwrap();
    let dir = std::env::temp_dir().join(format!("lensbake-consumer-{}", std::process::id()));
    write_table(&table, "dgauss-50mm", &lens.system.prescription, &dir).unwrap();
    let read = read_table(&dir, Some(&lens.system.prescription)).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();

    let focused = read.focused(Some(2000.0), None).unwrap();
    let film_z = focused.film_z();
    let ray = Ray::new([0.5, 1.0, film_z], [0.0, -0.02, -1.0]).unwrap();
    let looked_up = focused
        .lookup(&ray)
        .passed()
        .expect("a near-axial ray passes");

    let tracer = Tracer::new(&lens.system.at(lens.system.design_wavelength_nm()));
    let exact = tracer.trace(ray, Travel::Backward);
    assert_eq!(exact.outcome, Outcome::Ok);
    // Both on one plane in front of the lens before comparing positions.
    let [ax, ay, _] = looked_up.point_at_z(-20.0).unwrap();
    let [bx, by, _] = exact.ray.point_at_z(-20.0).unwrap();
    let miss = (ax - bx).hypot(ay - by);
    assert!(
        miss < 1.9e-3,
        "table and trace differ by {miss} mm at z = -20"
    );
    let angle = {
        let (a, b) = (looked_up.direction(), exact.ray.direction());
        (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).min(1.0).acos()
    };
    assert!(angle < 3e-5, "directions differ by {angle} rad");

    let outside = Ray::new([0.0, 0.0, film_z], [0.0, -0.9, -0.3]).unwrap();
    assert!(!matches!(focused.lookup(&outside), Lookup::Passes(_)));
    assert_eq!(
        read.lookup(&ray, Some(2000.0), None).unwrap(),
        focused.lookup(&ray)
    );
}

/// The MTF of a real lens through the root: 1 at zero frequency, never above the diffraction
/// limit of its own pupil, whose value at half the cutoff frequency is that of a circular pupil,
/// (2/pi)(acos(1/2) - (1/2) sqrt(3/4)) = 0.3910.
#[test]
fn mtf_through_the_root() {
    let lens = load_lens("cooke-triplet", &LoadOptions::default()).unwrap();
    let options = WaveOptions {
        field_deg: 0.0,
        f_number: Some(8.0),
        ..WaveOptions::default()
    };
    let probe = mtf(&lens.system, &options, &[]).unwrap();
    let half_cutoff = 0.5 * probe.cutoff_per_mm;
    let curve = mtf(&lens.system, &options, &[0.0, half_cutoff]).unwrap();
    for series in [&curve.tangential, &curve.sagittal] {
        assert!((series[0] - 1.0).abs() < 1e-9, "MTF(0) = {}", series[0]);
        assert!(series[1] <= curve.diffraction_limit[1] + 1e-6, "{series:?}");
        assert!(series[1] > 0.0);
    }
    let circular = 2.0 / std::f64::consts::PI * ((0.5f64).acos() - 0.5 * (0.75f64).sqrt());
    assert!(
        (curve.diffraction_limit[1] - circular).abs() < 1e-6,
        "diffraction limit at half the cutoff {}, circular pupil {circular}",
        curve.diffraction_limit[1]
    );
}
