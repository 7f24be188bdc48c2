//! `lensbake bake` and `lensbake lrtf eval|info`.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

use lensbake::analysis::{FileDefaults, FocusFrom};
use lensbake::job::default_table_dir;
use lensbake::job::tables::DEFAULT_TABLES_ROOT;
use lensbake::lenses::LoadedLens;
use lensbake::lrtf::bake::{BakePlan, BakeRequest, first_order};
use lensbake::lrtf::io::{read_sidecar, read_table, write_table};
use lensbake::lrtf::measure::{SweepRow, table_error_focused};
use lensbake::lrtf::{Lookup, Parameterisation, Precision, Ray};
use lensbake::plot::{LrtfErrorPlot, write_plot};
use lensbake::trace::Tracer;

use super::lens::{LensArgs, ReadArgs};
use super::trace::RayOutput;

#[derive(Args, Debug)]
pub struct BakeArgs {
    #[command(flatten)]
    pub lens: LensArgs,
    /// N (N^3 nodes) or AxBxC.
    #[arg(long, default_value = "128")]
    pub resolution: String,
    #[arg(long, default_value = "f32", value_parser = ["f32", "f16", "u16"])]
    pub precision: String,
    #[arg(long, default_value = "pupil-planes", value_parser = ["pupil-planes", "spherical"])]
    pub parameterisation: String,
    /// One wavelength, or three (R,G,B) for chromatic aberration; default: design wavelength.
    #[arg(long, value_delimiter = ',')]
    pub wavelengths_nm: Vec<f64>,
    /// f-number to bake (default: wide open); the table serves this and every slower one.
    #[arg(long)]
    pub f_number: Option<f64>,
    /// Object distance in focus, mm in front of surface 1 (default: the lens file's object
    /// distance, else infinity), or a focus range
    /// FAR..NEAR (or FAR,NEAR; `inf` for infinity) that one table serves for every focus
    /// between, e.g. `inf..1000`.
    #[arg(long, value_name = "D | FAR..NEAR", value_parser = parse_focus)]
    pub focus_mm: Option<FocusArg>,
    /// Output directory (default: tables/<lens>/, tables/<lens>/focus-<D>mm/ or
    /// tables/<lens>/focus-<FAR>-<NEAR>mm/).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Bake the cheapest table keeping the scene's p99 image error (px at 1920 px) under this,
    /// or none when a first-order or Seidel model already does.
    #[arg(long)]
    pub error_budget_px: Option<f64>,
    #[command(flatten)]
    pub scene: super::tradeoff::SceneArgs,
}

#[derive(Subcommand, Debug)]
pub enum LrtfCommand {
    /// Propagate film-side rays (travelling -z) through a baked table.
    Eval {
        /// The table's directory (its lrtf.exr and lrtf.ron).
        table: PathBuf,
        /// JSON array of {"origin": [x,y,z], "direction": [dx,dy,dz]}; "-" reads stdin.
        #[arg(long)]
        rays: String,
        /// Print JSON (one object per input ray, in order) instead of a line per ray.
        #[arg(long)]
        json: bool,
        /// Stop down to this f-number (at or above the baked one).
        #[arg(long)]
        f_number: Option<f64>,
        /// The focus the rays are evaluated at (mm, `inf` for infinity; default: the table's
        /// far focus): refused outside the table's focus range; a ray crossing that focus's
        /// film plane beyond the table's film radius is outside the domain ("missed").
        #[arg(long, value_name = "D", value_parser = parse_focus)]
        focus_mm: Option<FocusArg>,
        /// The lens the table should belong to (file or bundled name): a table baked from a
        /// different prescription is refused.
        #[arg(long, value_name = "LENS")]
        lens: Option<String>,
        #[command(flatten)]
        read: ReadArgs,
    },
    /// Print a table's sidecar summary.
    Info {
        /// The table's directory (its lrtf.exr and lrtf.ron).
        table: PathBuf,
    },
}

/// `--focus-mm`: one object distance, or a range (far end first; None is infinity).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FocusArg {
    pub far_mm: Option<f64>,
    pub near_mm: Option<f64>,
}

impl FocusArg {
    /// The single distance, or an error naming the range where one focus is needed.
    pub(super) fn single(self, what: &str) -> anyhow::Result<Option<f64>> {
        if self.far_mm != self.near_mm {
            bail!("{what} takes one focus distance, not a range");
        }
        Ok(self.far_mm)
    }

    /// Default table directory under tables/<lens>/ for this focus.
    fn table_dir(self, lens: &str) -> PathBuf {
        let text = |d: Option<f64>| d.map_or("inf".into(), |d| format!("{d}"));
        if self.far_mm == self.near_mm {
            default_table_dir(Path::new(DEFAULT_TABLES_ROOT), lens, self.far_mm)
        } else {
            default_table_dir(Path::new(DEFAULT_TABLES_ROOT), lens, None).join(format!(
                "focus-{}-{}mm",
                text(self.far_mm),
                text(self.near_mm)
            ))
        }
    }
}

/// Parses `D`, `A..B` or `A,B` (mm, `inf` for infinity); the farther distance becomes the far end.
pub(super) fn parse_focus(text: &str) -> Result<FocusArg, String> {
    let distance = |part: &str| -> Result<Option<f64>, String> {
        let part = part.trim();
        if part.eq_ignore_ascii_case("inf") || part.eq_ignore_ascii_case("infinity") {
            return Ok(None);
        }
        match part.parse::<f64>() {
            Ok(d) if d.is_finite() && d > 0.0 => Ok(Some(d)),
            _ => Err(format!(
                "`{part}` is not a positive distance in mm or `inf`"
            )),
        }
    };
    let parts: Vec<&str> = if text.contains("..") {
        text.split("..").collect()
    } else {
        text.split(',').collect()
    };
    let farther = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (None, _) | (_, None) => None,
        (Some(a), Some(b)) => Some(a.max(b)),
    };
    let nearer = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (None, other) | (other, None) => other,
        (Some(a), Some(b)) => Some(a.min(b)),
    };
    match parts[..] {
        [one] => {
            let d = distance(one)?;
            Ok(FocusArg {
                far_mm: d,
                near_mm: d,
            })
        }
        [a, b] => {
            let (a, b) = (distance(a)?, distance(b)?);
            Ok(FocusArg {
                far_mm: farther(a, b),
                near_mm: nearer(a, b),
            })
        }
        _ => Err(format!("`{text}`: expected D, FAR..NEAR or FAR,NEAR")),
    }
}

fn parse_resolution(text: &str) -> anyhow::Result<[usize; 3]> {
    let parts: Vec<usize> = text
        .split('x')
        .map(|p| p.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--resolution {text}: expected N or AxBxC"))?;
    match parts[..] {
        [n] => Ok([n, n, n]),
        [a, b, c] => Ok([a, b, c]),
        _ => bail!("--resolution {text}: expected N or AxBxC"),
    }
}

/// The f-number and the focus (None: infinity) a bake or a tradeoff uses where no flag gives
/// them: the lens file's stated aperture and real object distance, each choice noted.
pub(super) fn stated_choices(
    lens: &LoadedLens,
    f_number_flag: Option<f64>,
    focus_flag_given: bool,
) -> anyhow::Result<(Option<f64>, Option<f64>)> {
    let focus_from = if focus_flag_given {
        FocusFrom::Flag
    } else {
        FocusFrom::File
    };
    let defaults = FileDefaults::of(&lens.system, focus_from)?;
    for note in &defaults.notes {
        note!("{}: {note}", lens.source.origin);
    }
    if let (None, Some(f)) = (f_number_flag, defaults.f_number) {
        note!("{}: f/{f:.3} from the lens file", lens.source.origin);
    }
    if let Some(d) = defaults.focus_mm {
        note!(
            "{}: focus {d:.3} mm, the lens file's object distance",
            lens.source.origin
        );
    }
    Ok((f_number_flag.or(defaults.f_number), defaults.focus_mm))
}

pub fn run_bake(args: BakeArgs) -> anyhow::Result<()> {
    let lens = args.lens.load()?;
    let (f_number, file_focus) = stated_choices(&lens, args.f_number, args.focus_mm.is_some())?;
    let focus = args.focus_mm.unwrap_or(FocusArg {
        far_mm: file_focus,
        near_mm: None,
    });
    if args.error_budget_px.is_none() && args.scene.any() {
        anyhow::bail!(
            "--scene, --nearest-mm and --film-fraction describe what a --error-budget-px bake \
             must serve; without a budget they would be ignored"
        );
    }
    if let Some(budget) = args.error_budget_px {
        return super::tradeoff::bake_within_budget(
            &lens,
            budget,
            &args.scene,
            focus.single("--error-budget-px")?,
            f_number,
            args.out,
        );
    }
    super::lens::note_reading(&lens.source);
    let name = lens.source.origin.name();
    let system = &lens.system;
    let request = BakeRequest {
        parameterisation: Parameterisation::from_name(&args.parameterisation)
            .expect("clap restricts the names"),
        resolution: parse_resolution(&args.resolution)?,
        precision: Precision::from_name(&args.precision).expect("clap restricts the names"),
        wavelengths_nm: args.wavelengths_nm,
        f_number,
        focus_mm: focus.far_mm,
        focus_near_mm: focus.near_mm,
        ..BakeRequest::default()
    };
    let out = args.out.unwrap_or_else(|| focus.table_dir(&name));
    // A request the bake refuses is refused here, so that its error line comes first; what the
    // bake takes from the file is then said before the bake's progress.
    let plan = BakePlan::new(system, &request)?;
    super::notes::release();
    let bar = ProgressBar::new(1);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {percent}% {elapsed}")
            .expect("valid template"),
    );
    bar.set_message(format!("baking {name}"));
    let start = std::time::Instant::now();
    let table = plan.bake(&|p| {
        bar.set_length(p.total as u64);
        bar.set_position(p.done as u64);
    })?;
    let seconds = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    write_table(&table, &args.lens.lens, &system.prescription, &out)?;
    let bytes: u64 = ["lrtf.exr", "lrtf.ron"]
        .iter()
        .filter_map(|f| std::fs::metadata(out.join(f)).ok())
        .map(|m| m.len())
        .sum();
    say!(
        "baked {name}: {} {}x{}x{} {} focus {} in {seconds:.2} s, {bytes} bytes in {}",
        table.info.parameterisation.name(),
        table.info.resolution[0],
        table.info.resolution[1],
        table.info.resolution[2],
        table.info.precision.name(),
        table.info.focus.text(),
        out.display()
    );
    // A range is measured at both ends and halfway between its film planes.
    let [far_z, near_z] = table.info.focus.film_z_range();
    let planes = if table.info.focus.is_single() {
        vec![far_z]
    } else {
        vec![far_z, 0.5 * (far_z + near_z), near_z]
    };
    for (k, layer) in table.layers.iter().enumerate() {
        let at = system.at(layer.wavelength_nm);
        let tracer = Tracer::new(&at.stopped_down(layer.stop_semi_aperture));
        let efl = first_order(&at, request.focus_mm)?.first_order.efl;
        for &film_z in &planes {
            let e = table_error_focused(&table, k, film_z, &tracer, efl, 1920.0, 20_000, 7);
            let on = if planes.len() > 1 {
                format!(" film z {film_z:.3} mm:")
            } else {
                String::new()
            };
            say!(
                "  {:.2} nm:{on} image error p99 {:.3} px (max {:.3}) at 1920 px, direction p99 {:.4} mrad, position p99 {:.2} um, validity agreement {:.3} %",
                layer.wavelength_nm,
                e.image_px.p99,
                e.image_px.max,
                e.direction_mrad.p99,
                e.position_um.p99,
                100.0 * (1.0 - e.validity_mismatch)
            );
        }
    }
    Ok(())
}

pub fn run(command: LrtfCommand) -> anyhow::Result<()> {
    match command {
        LrtfCommand::Info { table } => {
            // The whole table verifies (data and every sidecar field) before any of it is shown.
            read_table(&table, None)?;
            let sidecar = read_sidecar(&table)?;
            let [far_z, near_z] = sidecar.info.focus.film_z_range();
            let focus_nodes = sidecar
                .layers
                .first()
                .map_or(0, |l| l.sampling_pupil.nodes.len());
            say!(
                "focus {} (film z {far_z:.4}..{near_z:.4} mm, {focus_nodes} pupil focus nodes)",
                sidecar.info.focus.text()
            );
            say!(
                "{}",
                ron::ser::to_string_pretty(&sidecar, ron::ser::PrettyConfig::default())?
            );
            Ok(())
        }
        LrtfCommand::Eval {
            table,
            rays,
            json,
            f_number,
            focus_mm,
            lens,
            read,
        } => {
            let lens = lens
                .map(|lens| LensArgs { lens, read }.load())
                .transpose()?;
            let loaded = read_table(&table, lens.as_ref().map(|l| &l.system.prescription))?;
            let input = super::trace::read_rays(&rays)?;
            let f = f_number.unwrap_or(loaded.info.f_number);
            let stop = loaded.stop_radius(0, f).with_context(|| {
                format!(
                    "f-number {f} is faster than the table's f/{}",
                    loaded.info.f_number
                )
            })?;
            let film_z = match focus_mm {
                Some(focus) => loaded
                    .info
                    .focus
                    .film_z_for(focus.single("lrtf eval --focus-mm")?)
                    .with_context(|| format!("table {}", table.display()))?,
                None => loaded.layers[0].frame.film_plane_z,
            };
            // With the lens at hand a ray is checked against the last surface at its height,
            // as `trace` checks it; a table alone knows only the last vertex plane.
            let lens_at = lens
                .as_ref()
                .map(|l| l.system.at_checked(loaded.layers[0].wavelength_nm))
                .transpose()?;
            let mut output = Vec::with_capacity(input.len());
            for (k, checked) in input.iter().enumerate() {
                if let Some(at) = &lens_at {
                    lensbake::trace::check_start(at, checked, lensbake::trace::Travel::Backward)
                        .with_context(|| format!("{rays}: ray {k}"))?;
                }
                let rear_plane_z = loaded.layers[0].frame.rear_plane_z;
                let start_z = checked.position()[2];
                if start_z < rear_plane_z {
                    bail!(
                        "{rays}: ray {k} starts at z = {start_z} mm, in front of the lens's last \
                         vertex plane (z = {rear_plane_z} mm): a film-side ray must start behind it"
                    );
                }
                let ray = Ray {
                    origin: checked.position(),
                    direction: checked.direction(),
                };
                output.push(match loaded.lookup_focused(0, &ray, stop, film_z) {
                    Lookup::Passes(out) => RayOutput {
                        status: "ok",
                        surface: None,
                        position: out.origin,
                        direction: out.direction,
                        image: None,
                    },
                    // Blocked rays have no surface: the table does not know which one.
                    Lookup::Blocked => RayOutput {
                        status: "vignetted",
                        surface: None,
                        position: ray.origin,
                        direction: ray.direction,
                        image: None,
                    },
                    Lookup::OutsideDomain => RayOutput {
                        status: "missed",
                        surface: None,
                        position: ray.origin,
                        direction: ray.direction,
                        image: None,
                    },
                });
            }
            super::trace::print(json, &output)
        }
    }
}

/// `lensbake plot lrtf-error MEASUREMENTS.json --out FILE`: the error-against-size plot of a
/// measurement sweep.
pub fn plot_error(measurements: &Path, out: &Path) -> anyhow::Result<()> {
    let name = measurements.display();
    let text =
        lensbake::limits::read_input_text(measurements).with_context(|| {
            match measurements.to_str().and_then(lensbake::lenses::find) {
                Some(_) if !measurements.exists() => format!(
                    "{name} is a bundled lens; lrtf-error plots an LRTF measurement table (the \
                 lrtf-error.json the lrtf_sweep example writes), not a lens"
                ),
                _ => format!("reading {name}"),
            }
        })?;
    let rows: Vec<SweepRow> = serde_json::from_str(&text).with_context(|| {
        format!(
            "{}: not an LRTF measurement table (the lrtf-error.json the lrtf_sweep example writes)",
            measurements.display()
        )
    })?;
    if rows.is_empty() {
        bail!(
            "{}: the measurement table has no rows",
            measurements.display()
        );
    }
    write_plot(&LrtfErrorPlot::from_sweep(&rows), out)?;
    say!("{}", out.display());
    Ok(())
}
