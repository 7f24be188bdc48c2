//! `lensbake analyze`: first-order data, pupils and Seidel sums as a readable report or JSON.

use super::lens::{AimingArg, LensArgs, Readable};
use anyhow::Context as _;
use clap::Args;
use lensbake::analysis::{Analysis, AnalysisError, AnalyzeOptions, analyze};
use lensbake::paraxial::StopChoice;
use lensbake::seidel::{ColourTerms, SeidelTerms, SurfaceSeidel, SurfaceTerms};
use std::fmt::Write as _;

#[derive(Args, Debug)]
pub struct AnalyzeArgs {
    #[command(flatten)]
    pub lens: LensArgs,
    /// Wavelength in nm [default: the lens's design wavelength, else 587.56].
    #[arg(long, allow_negative_numbers = true)]
    pub wavelength_nm: Option<f64>,
    /// Half-field angle in degrees [default: the lens file's largest field, else the source's
    /// claimed half field, else the largest whose real chief ray passes, at most 45].
    #[arg(long, allow_negative_numbers = true)]
    pub field_deg: Option<f64>,
    /// Entrance-pupil diameter in mm [default: the lens file's aperture (EPD, F-number or object
    /// NA), else the source's claimed f-number where the stop allows it, else the stop's clear
    /// aperture imaged to object space].
    #[arg(long, allow_negative_numbers = true)]
    pub epd_mm: Option<f64>,
    /// Object distance from the first vertex in mm [default: the lens file's, else infinity];
    /// negative for a virtual object (a beam converging on a point behind the first vertex).
    #[arg(long, allow_negative_numbers = true)]
    pub object_distance_mm: Option<f64>,
    /// Take as aperture stop the surface that limits the axial beam, not the marked one.
    #[arg(long)]
    pub find_stop: bool,
    /// How the real rays of distortion and LSA aim a pupil coordinate [default: the lens
    /// file's (Zemax RAIM), else paraxial].
    #[arg(long, value_enum)]
    pub ray_aiming: Option<AimingArg>,
    /// Print one JSON object instead of the report.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: AnalyzeArgs) -> anyhow::Result<()> {
    let lens = match args.lens.load_or_placed()? {
        Readable::Centred(lens) => *lens,
        Readable::Placed {
            offence,
            location,
            lens,
        } => return super::analyze_placed::run(&args, &offence, &location, &lens),
    };
    super::lens::note_reading(&lens.source);
    let name = lens.source.origin.name();
    let options = AnalyzeOptions {
        wavelength_nm: args.wavelength_nm,
        field_deg: args.field_deg,
        epd_mm: args.epd_mm,
        object_distance_mm: args.object_distance_mm,
        stop: if args.find_stop {
            StopChoice::LimitingAxialBeam
        } else {
            StopChoice::Marked
        },
        ray_aiming: args.ray_aiming.map(Into::into),
    };
    if lensbake::analysis::is_afocal_lens(&lens.system, &options)
        .with_context(|| format!("analysing {}", lens.source.origin))?
    {
        return super::analyze_afocal::run(&lens.system, &options, name, args.json)
            .with_context(|| format!("analysing {}", lens.source.origin));
    }
    let mut analysis = analyze(&lens.system, &options).map_err(|error| match error {
        // Located in the file already.
        AnalysisError::Stated { .. } => anyhow::Error::new(error),
        other => anyhow::Error::new(other).context(format!("analysing {}", lens.source.origin)),
    })?;
    analysis.lens = name;
    if args.json {
        say!("{}", serde_json::to_string_pretty(&analysis)?);
    } else {
        say_raw!("{}", report(&analysis));
    }
    Ok(())
}

/// The human-readable report: conditions, first-order table, rays and Seidel table.
fn report(a: &Analysis) -> String {
    let f = &a.first_order;
    let s = &a.seidel;
    let mut out = String::new();
    let object = a.object_distance_mm.map_or("at infinity".to_string(), |d| {
        lensbake::limits::object_place(d, 4)
    });
    let _ = writeln!(out, "{}", a.lens);
    let _ = writeln!(
        out,
        "wavelength {} nm   half field {:.4} deg   object {object}",
        super::lens::printed_nm(a.wavelength_nm),
        // The field as the conditions below give it: the paraxial angle of a finite object's
        // height is negative by the sign convention (`field_deg` in the JSON keeps it).
        a.conditions.field_deg()
    );
    let _ = writeln!(out, "\nDesign conditions (docs/conditions.md)");
    for (name, value, from) in a.conditions.summary_rows() {
        let _ = writeln!(out, "  {name:<26} {value:<40} from the {from}");
    }
    for note in &a.conditions.notes {
        let _ = writeln!(out, "  note: {note}");
    }
    let _ = writeln!(
        out,
        "\nFirst order (z absolute from the vertex of surface 1)"
    );
    let mut row = |label: &str, value: String, unit: &str| {
        let _ = writeln!(out, "  {label:<34} {value:>16} {unit}");
    };
    row("power", format!("{:.9}", f.power), "1/mm");
    for (label, value) in [
        ("EFL (image side, n'/power)", f.efl),
        ("object-side focal length", f.fl_object),
        ("BFL (last vertex to F')", f.bfl),
        ("FFL (first vertex to F)", f.ffl),
        ("z front focal point F", f.z_front_focal),
        ("z rear focal point F'", f.z_rear_focal),
        ("z front principal point P", f.z_front_principal),
        ("z rear principal point P'", f.z_rear_principal),
        ("z front nodal point N", f.z_front_nodal),
        ("z rear nodal point N'", f.z_rear_nodal),
        ("z last vertex", f.z_last_vertex),
    ] {
        row(label, format!("{value:.6}"), "mm");
    }
    let virtual_image = if (f.z_paraxial_image - f.z_last_vertex) * f.image_index.signum() <= 0.0 {
        "mm (virtual)"
    } else {
        "mm"
    };
    row(
        "z paraxial image",
        format!("{:.6}", f.z_paraxial_image),
        virtual_image,
    );
    row(
        "paraxial image height",
        format!("{:.6}", f.image_height),
        "mm",
    );
    if let (Some(m), Some(h)) = (f.magnification, f.object_height) {
        row("object height", format!("{h:.6}"), "mm");
        row("lateral magnification", format!("{m:.8}"), "");
    }
    row("stop surface", f.stop_surface.to_string(), "");
    row(
        "entrance pupil z",
        format!("{:.6}", f.entrance_pupil.z),
        "mm",
    );
    row(
        "entrance pupil diameter",
        format!("{:.6}", f.entrance_pupil.diameter),
        "mm",
    );
    match f.exit_pupil {
        Some(xp) => {
            row("exit pupil z", format!("{:.6}", xp.z), "mm");
            row("exit pupil diameter", format!("{:.6}", xp.diameter), "mm");
        }
        None => row("exit pupil", "at infinity".into(), "(telecentric)"),
    }
    row("f-number (EFL / EPD)", format!("{:.6}", f.f_number), "");
    row(
        "working f-number 1/(2 n' |u'|)",
        format!("{:.6}", f.working_f_number),
        "",
    );
    row(
        "Lagrange invariant",
        format!("{:.8}", f.lagrange_invariant),
        "mm",
    );
    let (value, unit) = max_field_text(f.max_field_deg_paraxial);
    row("max unvignetted half field (paraxial)", value, unit);

    let _ = writeln!(
        out,
        "\nParaxial rays (y in mm; u' = slope after the surface; A = n i)"
    );
    let _ = writeln!(
        out,
        "  {:>4} {:>12} {:>11} {:>11} {:>12} {:>11} {:>11}",
        "surf", "marginal y", "u'", "A", "chief y", "u'", "A"
    );
    for (k, (m, c)) in a
        .paraxial_rays
        .marginal
        .iter()
        .zip(&a.paraxial_rays.chief)
        .enumerate()
    {
        let label = if k + 1 == f.stop_surface {
            "STO".to_string()
        } else {
            (k + 1).to_string()
        };
        let _ = writeln!(
            out,
            "  {label:>4} {:>12.6} {:>11.6} {:>11.6} {:>12.6} {:>11.6} {:>11.6}",
            m.y, m.u_after, m.incidence, c.y, c.u_after, c.incidence
        );
    }

    let _ = writeln!(
        out,
        "\nSeidel sums (Welford, mm; positive S1 = undercorrected spherical)"
    );
    write_seidel_table(
        &mut out,
        s.surfaces.iter().map(SurfaceSeidel::contributions),
        s.sums,
        s.colour,
    );

    let t = &s.transverse;
    let _ = writeln!(
        out,
        "\nTransverse third-order aberrations in the image (mm)"
    );
    let _ = writeln!(
        out,
        "  TSA {:.6}  TCO {:.6}  TAS {:.6}  SAS {:.6}  PTB {:.6}  DST {:.6}",
        t.tsa, t.tco, t.tas, t.sas, t.ptb, t.dst
    );
    if let (Some(tc), Some([short, long])) = (s.transverse_colour, s.colour_wavelengths_nm) {
        let _ = writeln!(
            out,
            "  axial colour AX {:.6}  lateral colour LAT {:.6}  ({short:.1} - {long:.1} nm)",
            tc.ax, tc.lat
        );
    }
    let _ = writeln!(
        out,
        "\nReal rays (paraxial image plane; chief ray aimed at the stop centre)"
    );
    for [deg, percent] in &a.real.distortion_percent {
        let _ = writeln!(out, "  distortion at {deg:8.4} deg   {percent:>12.6} %");
    }
    for [rho, lsa] in &a.real.lsa {
        let _ = writeln!(out, "  LSA at rho {rho:6.4}          {lsa:>12.6} mm");
    }
    for note in &a.real.notes {
        let _ = writeln!(out, "  note: {note}");
    }
    let w = &s.wavefront;
    let _ = writeln!(
        out,
        "\nWavefront coefficients (waves at {} nm)",
        a.wavelength_nm
    );
    let _ = writeln!(
        out,
        "  W040 {:.4}  W131 {:.4}  W222 {:.4}  W220 {:.4}  W311 {:.4}",
        w.w040, w.w131, w.w222, w.w220, w.w311
    );
    out
}

/// The largest paraxially unvignetted half field as printed, with its unit.
pub(super) fn max_field_text(deg: Option<f64>) -> (String, &'static str) {
    match deg {
        Some(deg) => (format!("{deg:.4}"), "deg"),
        None => ("unlimited".into(), ""),
    }
}

/// One row per surface and the sums: S1..S5, and C1, C2 where the colour terms exist.
pub(super) fn write_seidel_table(
    out: &mut String,
    surfaces: impl Iterator<Item = SurfaceTerms>,
    sums: SeidelTerms,
    colour_sums: Option<ColourTerms>,
) {
    let _ = write!(
        out,
        "  {:>4} {:>12} {:>12} {:>12} {:>12} {:>12}",
        "surf", "S1", "S2", "S3", "S4", "S5"
    );
    if colour_sums.is_some() {
        let _ = write!(out, " {:>12} {:>12}", "C1", "C2");
    }
    out.push('\n');
    let rows = surfaces
        .map(|s| (s.surface.to_string(), s.terms, s.colour))
        .chain(std::iter::once(("sum".to_string(), sums, colour_sums)));
    for (label, terms, colour) in rows {
        let _ = write!(out, "  {label:>4}");
        let colour = colour.map(|c| [c.axial, c.lateral]);
        for v in terms.as_array().iter().chain(colour.iter().flatten()) {
            let _ = write!(out, " {v:>12.7}");
        }
        out.push('\n');
    }
}
