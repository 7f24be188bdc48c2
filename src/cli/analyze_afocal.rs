//! `lensbake analyze` of an afocal system: the report a telescope user reads (docs/analyze.md).

use lensbake::analysis::{AfocalAnalysis, AnalyzeOptions, analyze_afocal};
use lensbake::system::LensSystem;
use std::fmt::Write as _;

pub fn run(
    system: &LensSystem,
    options: &AnalyzeOptions,
    name: String,
    json: bool,
) -> anyhow::Result<()> {
    let mut analysis = analyze_afocal(system, options)?;
    analysis.lens = name;
    if json {
        say!("{}", serde_json::to_string_pretty(&analysis)?);
    } else {
        say_raw!("{}", report(&analysis));
    }
    Ok(())
}

fn report(a: &AfocalAnalysis) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "{}", a.lens);
    let _ = writeln!(
        out,
        "afocal system (zero power): object at infinity, image at infinity"
    );
    let _ = writeln!(out, "\nConditions");
    for (label, value, from) in [
        (
            "wavelength",
            format!("{} nm", super::lens::printed_nm(a.wavelength_nm)),
            a.wavelength_from,
        ),
        (
            "entrance-pupil diameter",
            format!("{:.6} mm", a.epd_mm),
            a.aperture_from,
        ),
        (
            "half field (object space)",
            format!("{:.4} deg", a.field_deg),
            a.field_from,
        ),
    ] {
        let _ = writeln!(
            out,
            "  {label:<26} {value:<24} from the {}",
            from.describe()
        );
    }
    for note in &a.notes {
        let _ = writeln!(out, "  note: {note}");
    }
    let _ = writeln!(
        out,
        "\nFirst order (z absolute from the vertex of surface 1)"
    );
    let mut row = |label: &str, value: String, unit: &str| {
        let _ = writeln!(out, "  {label:<40} {value:>16} {unit}");
    };
    row(
        "angular magnification n D / |n'|",
        format!("{:.9}", a.angular_magnification),
        if a.angular_magnification < 0.0 {
            "(inverted)"
        } else {
            "(erect)"
        },
    );
    row(
        "beam magnification A (exit/entrance)",
        format!("{:.9}", a.beam_magnification),
        "",
    );
    row(
        "residual power C",
        format!("{:.3e}", a.residual_power + 0.0),
        "1/mm",
    );
    row("stop surface", a.stop_surface.to_string(), "");
    row(
        "entrance pupil z",
        format!("{:.6}", a.entrance_pupil.z),
        "mm",
    );
    row(
        "entrance pupil diameter",
        format!("{:.6}", a.entrance_pupil.diameter),
        "mm",
    );
    match (a.exit_pupil, a.eye_relief) {
        (Some(xp), Some(relief)) => {
            row("exit pupil z", format!("{:.6}", xp.z), "mm");
            row("exit pupil diameter", format!("{:.6}", xp.diameter), "mm");
            row(
                "eye relief (last vertex to exit pupil)",
                format!("{relief:.6}"),
                if relief < 0.0 { "mm (virtual)" } else { "mm" },
            );
        }
        _ => row("exit pupil", "at infinity".into(), ""),
    }
    row("z last vertex", format!("{:.6}", a.z_last_vertex), "mm");
    row(
        "half field in object space",
        format!("{:.6}", a.field_deg),
        "deg",
    );
    row(
        "apparent half field (paraxial)",
        format!("{:.6}", a.apparent_field_deg),
        "deg",
    );
    let (value, unit) = super::analyze::max_field_text(a.max_field_deg_paraxial);
    row("max unvignetted half field (paraxial)", value, unit);
    row(
        "Lagrange invariant",
        format!("{:.8}", a.lagrange_invariant),
        "mm",
    );

    let s = &a.seidel;
    let _ = writeln!(
        out,
        "\nSeidel sums (Welford, mm; positive S1 = undercorrected spherical)"
    );
    super::analyze::write_seidel_table(&mut out, s.surfaces.iter().copied(), s.sums, s.colour);
    let g = &s.angular;
    let _ = writeln!(
        out,
        "\nAngular third-order aberrations in image space (mrad, pupil edge and full field)"
    );
    let _ = writeln!(
        out,
        "  spherical {:.6}  coma (tangential) {:.6}  astigmatic focus T {:.6} S {:.6}  Petzval {:.6}  distortion {:.6}",
        g.spherical,
        g.tangential_coma,
        g.tangential_astigmatism,
        g.sagittal_astigmatism,
        g.petzval,
        g.distortion
    );
    if let (Some(ax), Some(lat), Some([short, long])) =
        (g.axial_colour, g.lateral_colour, s.colour_wavelengths_nm)
    {
        let _ = writeln!(
            out,
            "  axial colour {ax:.6}  lateral colour {lat:.6}  ({short:.1} - {long:.1} nm)"
        );
    }
    let w = &s.wavefront;
    let _ = writeln!(
        out,
        "  wavefront (waves): W040 {:.4}  W131 {:.4}  W222 {:.4}  W220 {:.4}  W311 {:.4}",
        w.w040, w.w131, w.w222, w.w220, w.w311
    );

    let _ = writeln!(
        out,
        "\nReal chief rays (aimed at the stop centre): apparent field"
    );
    for p in &a.apparent_field {
        let _ = writeln!(
            out,
            "  field {:8.4} deg   apparent {:9.4} deg   paraxial {:9.4} deg   distortion {:>10.5} %",
            p.field_deg, p.apparent_deg, p.paraxial_apparent_deg, p.distortion_percent
        );
    }
    let _ = writeln!(
        out,
        "\nWave optics at infinity (OPD against a plane normal to the chief ray; MTF in cycles/mrad)"
    );
    for f in &a.wave {
        let _ = writeln!(
            out,
            "  field {:8.4} deg   RMS {:.5} waves   P-V {:.5} waves   Strehl {:.5}   RMS angular spot {:.5} mrad",
            f.field_deg, f.rms_waves, f.pv_waves, f.strehl, f.rms_angular_spot_mrad
        );
        let _ = write!(out, "    MTF T/S (diffraction limit) at");
        for (k, nu) in f.mtf.frequencies_per_mrad.iter().enumerate() {
            let _ = write!(
                out,
                "  {nu:.3}: {:.3}/{:.3} ({:.3})",
                f.mtf.tangential[k], f.mtf.sagittal[k], f.mtf.diffraction_limit[k]
            );
        }
        out.push('\n');
    }
    out
}
