//! `lensbake bake` and `lensbake lrtf eval|info`.

use std::io::Read;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use serde::{Deserialize, Serialize};

use lensbake::lrtf::bake::{BakeRequest, bake, first_order};
use lensbake::lrtf::io::{read_sidecar, read_table, write_table};
use lensbake::lrtf::measure::{SweepRow, error_plot, table_error};
use lensbake::lrtf::{Lookup, Parameterisation, Precision, Ray};
use lensbake::plot::write_plot;
use lensbake::trace::Tracer;

use super::lens::{LensArgs, ReadArgs};

#[derive(Args, Debug)]
pub struct BakeArgs {
    #[command(flatten)]
    pub lens: LensArgs,
    /// N (N^3 nodes) or AxBxC.
    #[arg(long, default_value = "128")]
    pub resolution: String,
    #[arg(long, default_value = "f32", value_parser = ["f32", "f16"])]
    pub precision: String,
    #[arg(long, default_value = "pupil-planes", value_parser = ["pupil-planes", "spherical"])]
    pub parameterisation: String,
    /// One wavelength, or three (R,G,B) for chromatic aberration; default: design wavelength.
    #[arg(long, value_delimiter = ',')]
    pub wavelengths_nm: Vec<f64>,
    /// f-number to bake (default: wide open); the table serves this and every slower one.
    #[arg(long)]
    pub f_number: Option<f64>,
    /// Object distance in focus, mm in front of surface 1 (default: infinity).
    #[arg(long)]
    pub focus_mm: Option<f64>,
    /// Output directory (default: tables/<lens>/).
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
        table: PathBuf,
        /// JSON array of {"origin": [x,y,z], "direction": [dx,dy,dz]}; "-" reads stdin.
        #[arg(long)]
        rays: String,
        #[arg(long)]
        json: bool,
        /// Stop down to this f-number (at or above the baked one).
        #[arg(long)]
        f_number: Option<f64>,
        /// The lens the table should belong to (file or bundled name): a table baked from a
        /// different prescription is refused.
        #[arg(long, value_name = "LENS")]
        lens: Option<String>,
        #[command(flatten)]
        read: ReadArgs,
    },
    /// Print a table's sidecar summary.
    Info { table: PathBuf },
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

pub fn run_bake(args: BakeArgs) -> anyhow::Result<()> {
    let lens = args.lens.load()?;
    if let Some(budget) = args.error_budget_px {
        return super::tradeoff::bake_within_budget(
            &lens,
            budget,
            &args.scene,
            args.focus_mm,
            args.f_number,
            args.out,
        );
    }
    for note in &lens.source.loaded.notes {
        eprintln!("note: {}: {note}", lens.source.origin);
    }
    let name = lens.source.origin.name();
    let system = &lens.system;
    let request = BakeRequest {
        parameterisation: Parameterisation::from_name(&args.parameterisation)
            .expect("clap restricts the names"),
        resolution: parse_resolution(&args.resolution)?,
        precision: Precision::from_name(&args.precision).expect("clap restricts the names"),
        wavelengths_nm: args.wavelengths_nm,
        f_number: args.f_number,
        focus_mm: args.focus_mm,
        ..BakeRequest::default()
    };
    let out = args
        .out
        .unwrap_or_else(|| PathBuf::from("tables").join(&name));
    let bar = ProgressBar::new(1);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {percent}% {elapsed}")
            .expect("valid template"),
    );
    bar.set_message(format!("baking {name}"));
    let start = std::time::Instant::now();
    let table = bake(system, &request, &|p| {
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
    println!(
        "baked {name}: {} {}x{}x{} {} in {seconds:.2} s, {bytes} bytes in {}",
        table.info.parameterisation.name(),
        table.info.resolution[0],
        table.info.resolution[1],
        table.info.resolution[2],
        table.info.precision.name(),
        out.display()
    );
    for (k, layer) in table.layers.iter().enumerate() {
        let at = system.at(layer.wavelength_nm);
        let tracer = Tracer::new(&at.stopped_down(layer.stop_semi_aperture));
        let efl = first_order(&at, request.focus_mm)?.first_order.efl;
        let e = table_error(&table, k, &tracer, efl, 1920.0, 20_000, 7);
        println!(
            "  {:.2} nm: image error p99 {:.3} px (max {:.3}) at 1920 px, direction p99 {:.4} mrad, position p99 {:.2} um, validity agreement {:.2} %",
            layer.wavelength_nm,
            e.image_px.p99,
            e.image_px.max,
            e.direction_mrad.p99,
            e.position_um.p99,
            100.0 * (1.0 - e.validity_mismatch)
        );
    }
    Ok(())
}

#[derive(Deserialize)]
struct InputRay {
    origin: [f64; 3],
    direction: [f64; 3],
}

#[derive(Serialize)]
struct OutputRay {
    status: &'static str,
    surface: Option<usize>,
    position: [f64; 3],
    direction: [f64; 3],
}

pub fn run(command: LrtfCommand) -> anyhow::Result<()> {
    match command {
        LrtfCommand::Info { table } => {
            let sidecar = read_sidecar(&table)?;
            println!(
                "{}",
                ron::ser::to_string_pretty(&sidecar, ron::ser::PrettyConfig::default())?
            );
            Ok(())
        }
        LrtfCommand::Eval {
            table,
            rays,
            json: _,
            f_number,
            lens,
            read,
        } => {
            let lens = lens
                .map(|lens| LensArgs { lens, read }.load())
                .transpose()?;
            let loaded = read_table(&table, lens.as_ref().map(|l| &l.system.prescription))?;
            let text = if rays == "-" {
                let mut s = String::new();
                std::io::stdin().read_to_string(&mut s)?;
                s
            } else {
                std::fs::read_to_string(&rays).with_context(|| format!("reading {rays}"))?
            };
            let input: Vec<InputRay> = serde_json::from_str(&text)
                .with_context(|| format!("{rays}: not a JSON ray array"))?;
            let f = f_number.unwrap_or(loaded.info.f_number);
            let stop = loaded.stop_radius(0, f).with_context(|| {
                format!(
                    "f-number {f} is faster than the table's f/{}",
                    loaded.info.f_number
                )
            })?;
            let mut output = Vec::with_capacity(input.len());
            for (k, r) in input.iter().enumerate() {
                let n = r.direction.iter().map(|v| v * v).sum::<f64>().sqrt();
                if !(n > 0.0 && n.is_finite()) || !r.origin.iter().all(|v| v.is_finite()) {
                    bail!("{rays}: ray {k} has a non-finite origin or a zero direction");
                }
                let ray = Ray {
                    origin: r.origin,
                    direction: r.direction.map(|v| v / n),
                };
                output.push(match loaded.lookup(0, &ray, stop) {
                    Lookup::Passes(out) => OutputRay {
                        status: "ok",
                        surface: None,
                        position: out.origin,
                        direction: out.direction,
                    },
                    // Blocked rays have no surface: the table does not know which one.
                    Lookup::Blocked => OutputRay {
                        status: "vignetted",
                        surface: None,
                        position: ray.origin,
                        direction: ray.direction,
                    },
                    Lookup::OutsideDomain => OutputRay {
                        status: "missed",
                        surface: None,
                        position: ray.origin,
                        direction: ray.direction,
                    },
                });
            }
            println!("{}", serde_json::to_string(&output)?);
            Ok(())
        }
    }
}

/// `lensbake plot lrtf-error MEASUREMENTS.json --out FILE`: the error-against-size plot of a
/// measurement sweep.
pub fn plot_error(measurements: &Path, out: &Path) -> anyhow::Result<()> {
    let text = std::fs::read_to_string(measurements)
        .with_context(|| format!("reading {}", measurements.display()))?;
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
    write_plot(&error_plot(&rows), out)?;
    println!("{}", out.display());
    Ok(())
}
