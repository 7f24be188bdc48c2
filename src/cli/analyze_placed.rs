//! `lensbake analyze` for a lens its file places off one common axis: the real-ray analysis of
//! [`lensbake::analysis::placed`] (chief rays, first-order data about the OAR, spots, fans and
//! wavefronts per field) as a report or JSON.

use super::analyze::AnalyzeArgs;
use super::lens::{placed_beam, printed_nm};
use lensbake::analysis::placed::{FanRay, PlacedAnalysis, PlacedOptions, analyze_placed};
use lensbake::lenses::LensOrigin;
use lensbake::prescription::formats::PlacedLens;
use lensbake::prescription::{DEFAULT_WAVELENGTH_NM, Location};
use lensbake::trace::placed::PlacedTracer;
use serde::Serialize;

/// The JSON `analyze --json` prints for a placed lens.
#[derive(Serialize)]
struct PlacedReport<'a> {
    lens: &'a str,
    /// What places the lens off one axis, and where the file says so.
    off_axis: String,
    /// Every number below comes from real rays; none is paraxial.
    real_rays_only: bool,
    #[serde(flatten)]
    analysis: &'a PlacedAnalysis,
}

pub fn run(
    args: &AnalyzeArgs,
    offence: &str,
    location: &Location,
    lens: &PlacedLens,
) -> anyhow::Result<()> {
    let spec = &args.lens.lens;
    // The 3-D trace aims every ray for real and takes the marked stop and an object at infinity.
    if args.object_distance_mm.is_some_and(f64::is_finite) {
        anyhow::bail!(
            "{spec}: {offence}, so it is analysed in three dimensions, which takes an object at \
             infinity; drop --object-distance-mm"
        );
    }
    if args.find_stop {
        anyhow::bail!(
            "{spec}: {offence}, so it is analysed in three dimensions, which takes the file's \
             stop; drop --find-stop"
        );
    }
    let wavelength = args.wavelength_nm.unwrap_or(
        lens.prescription
            .provenance
            .design_wavelength_nm
            .unwrap_or(DEFAULT_WAVELENGTH_NM),
    );
    let tracer = PlacedTracer::new(lens, wavelength).map_err(|e| anyhow::anyhow!("{spec}: {e}"))?;
    let (fields, pupil_diameter) = match (args.field_deg, args.epd_mm) {
        // Both given: the file's beam is not needed (nor need it be one the trace takes).
        (Some(field), Some(epd)) => (vec![[0.0, 0.0], [0.0, field]], epd),
        (field, epd) => {
            let beam = placed_beam(spec, offence, lens, &tracer)?;
            (
                field.map_or(beam.fields_deg, |f| vec![[0.0, 0.0], [0.0, f]]),
                epd.unwrap_or(beam.pupil_diameter),
            )
        }
    };
    let options = PlacedOptions::new(wavelength, fields, pupil_diameter);
    let analysis = analyze_placed(&tracer, &options).map_err(|e| anyhow::anyhow!("{spec}: {e}"))?;
    let name = LensOrigin::File(spec.into()).name();
    let off_axis = format!("{offence} at {location}");
    if args.json {
        let report = PlacedReport {
            lens: &name,
            off_axis,
            real_rays_only: true,
            analysis: &analysis,
        };
        say!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        say_raw!("{}", report(&name, &off_axis, &analysis));
    }
    Ok(())
}

/// A pair of optional lengths as `x / y`.
fn pair(values: [Option<f64>; 2], digits: usize) -> String {
    let one = |v: Option<f64>| v.map_or("infinite".to_string(), |v| format!("{v:.digits$}"));
    format!("{} / {}", one(values[0]), one(values[1]))
}

fn report(name: &str, off_axis: &str, a: &PlacedAnalysis) -> String {
    let mut out = String::new();
    let mut line = |text: String| {
        out.push_str(&text);
        out.push('\n');
    };
    line(name.to_string());
    line(format!("off the axis: {off_axis}"));
    line(format!(
        "wavelength {} nm   entrance pupil {:.6} mm   object at infinity",
        printed_nm(a.wavelength_nm),
        a.pupil_diameter_mm
    ));
    line(
        "Every number below is from real rays of the 3-D trace, none paraxial (docs/analyze-placed.md)."
            .into(),
    );
    let f = &a.first_order;
    line(String::new());
    line("First order about the OAR (field 0, 0 through the stop's centre), x / y sections".into());
    let axis = &a.axis_ray;
    line(format!(
        "  {:<40} ({:.6}, {:.6}) mm",
        "OAR launch (z = 0)", axis.launch_mm[0], axis.launch_mm[1]
    ));
    line(format!(
        "  {:<40} ({:.6}, {:.6}) mm, {:.4} deg to the normal",
        "OAR on the image plane (its frame)",
        axis.image_point_mm[0],
        axis.image_point_mm[1],
        axis.incidence_on_image_deg
    ));
    for (label, values) in [
        ("EFL (real-ray)", f.efl_mm),
        ("BFD along the OAR (last surface to focus)", f.bfd_mm),
        ("focus beyond the image plane", f.focus_from_image_mm),
        (
            "exit pupil to image along the OAR",
            axis.exit_pupil_to_image_mm,
        ),
    ] {
        line(format!("  {label:<40} {} mm", pair(values, 6)));
    }
    let s = f.image_scale_mm;
    line(format!(
        "  {:<40} [[{:.6}, {:.6}], [{:.6}, {:.6}]] mm",
        "image scale d(image x, y)/d(tan field x, y)", s[0][0], s[0][1], s[1][0], s[1][1]
    ));
    line(format!(
        "  {:<40} none: the object is at infinity",
        "lateral magnification"
    ));
    line(format!(
        "  differences: steps {:.3e} mm and {:.0e} in field tangent, extrapolations agree to {:.1e}",
        f.steps[0], f.steps[1], f.agreement
    ));
    line(String::new());
    line("Fields (image-plane frame, mm about each chief ray)".into());
    for field in &a.fields {
        let c = &field.chief;
        line(format!(
            "  field ({:.4}, {:.4}) deg: chief ray at ({:.6}, {:.6}), {:.4} deg to the normal",
            c.field_deg[0],
            c.field_deg[1],
            c.image_point_mm[0],
            c.image_point_mm[1],
            c.incidence_on_image_deg
        ));
        let [fx, fy] = c.focus_from_image_mm;
        let astigmatism = match (fx, fy) {
            (Some(x), Some(y)) => format!(" (astigmatism {:.6} mm)", y - x),
            _ => String::new(),
        };
        line(format!(
            "    foci beyond the image plane x / y {} mm{astigmatism}",
            pair(c.focus_from_image_mm, 6)
        ));
        let sp = &field.spot;
        match (
            sp.rms_radius_about_chief_mm,
            sp.rms_radius_about_centroid_mm,
            sp.centroid_mm,
        ) {
            (Some(chief), Some(centroid), Some(c)) => line(format!(
                "    spot {}/{} rays: RMS {chief:.6} about the chief ray, {centroid:.6} about \
                 the centroid ({:.6}, {:.6}); largest {:.6}",
                sp.arrived,
                sp.launched,
                c[0],
                c[1],
                sp.max_radius_about_chief_mm.unwrap_or(0.0)
            )),
            _ => line(format!("    spot: none of {} rays arrives", sp.launched)),
        }
        let fan = |rays: &[FanRay], component: usize| {
            rays.iter()
                .map(|r| {
                    r.error_mm
                        .map_or("-".into(), |e| format!("{:.6}", e[component]))
                })
                .collect::<Vec<_>>()
                .join(" ")
        };
        let ends = |rays: &[FanRay]| {
            let (first, last) = (&rays[0], &rays[rays.len() - 1]);
            format!("pupil {:.1}..{:.1}", first.pupil, last.pupil)
        };
        line(format!(
            "    tangential fan (y error, {}): {}",
            ends(&field.fans.tangential),
            fan(&field.fans.tangential, 1)
        ));
        line(format!(
            "    sagittal fan (x error, {}): {}",
            ends(&field.fans.sagittal),
            fan(&field.fans.sagittal, 0)
        ));
        match (&field.wave, &field.wave_note) {
            (Some(w), _) => line(format!(
                "    wavefront ({} x {} pupil, sphere of radius {:.6} mm): RMS {:.6} PV {:.6} \
                 waves, Strehl {:.6} (Marechal {:.6})",
                w.samples,
                w.samples,
                w.reference_radius_mm,
                w.stats.rms_waves,
                w.stats.pv_waves,
                w.stats.strehl,
                w.marechal_strehl
            )),
            (None, Some(why)) => line(format!("    wavefront: none ({why})")),
            (None, None) => {}
        }
    }
    line(String::new());
    line(format!("Seidel sums: {}", a.seidel));
    out
}
