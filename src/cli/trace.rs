//! `lensbake trace`: exact rays through a lens, JSON in and out.

use super::lens::{LensArgs, Readable};
use anyhow::Context;
use clap::Args;
use lensbake::prescription::DEFAULT_WAVELENGTH_NM;
use lensbake::prescription::formats::PlacedLens;
use lensbake::trace::placed::PlacedTracer;
use lensbake::trace::{Ray, Tracer, Travel, check_start};
use serde::{Deserialize, Serialize};

#[derive(Args, Debug)]
pub struct TraceArgs {
    #[command(flatten)]
    pub lens: LensArgs,
    /// JSON array of {"origin": [x, y, z], "direction": [dx, dy, dz]} in the lens frame (mm);
    /// `-` reads standard input.
    #[arg(long)]
    pub rays: String,
    /// Trace from the film side towards the object (-z, surfaces N..1).
    #[arg(long)]
    pub backward: bool,
    /// Wavelength in nm (default: the lens's design wavelength).
    #[arg(long, allow_negative_numbers = true)]
    pub wavelength_nm: Option<f64>,
    /// Print JSON (one object per input ray, in order).
    #[arg(long)]
    pub json: bool,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RayInput {
    origin: [f64; 3],
    direction: [f64; 3],
}

/// One ray's result as `trace` and `lrtf eval` print it.
#[derive(Serialize)]
pub(super) struct RayOutput {
    pub status: &'static str,
    pub surface: Option<usize>,
    pub position: [f64; 3],
    pub direction: [f64; 3],
    /// A lens off the axis: where the ray meets the image plane, in the plane's own frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub image: Option<[f64; 2]>,
}

pub fn run(args: TraceArgs) -> anyhow::Result<()> {
    let system = match args.lens.load_or_placed()? {
        Readable::Centred(lens) => lens.system,
        Readable::Placed { lens, .. } => return run_placed(&args, &lens),
    };
    let wavelength_nm = args
        .wavelength_nm
        .unwrap_or_else(|| system.design_wavelength_nm());
    let at = system.at_checked(wavelength_nm)?;
    let tracer = Tracer::new(&at);
    let rays = read_rays(&args.rays)?;
    let travel = if args.backward {
        Travel::Backward
    } else {
        Travel::Forward
    };
    for (i, ray) in rays.iter().enumerate() {
        check_start(&at, ray, travel).with_context(|| format!("{}: ray {i}", args.rays))?;
    }
    let traced: Vec<RayOutput> = rays
        .into_iter()
        .map(|ray| {
            let traced = tracer.trace(ray, travel);
            RayOutput {
                status: traced.outcome.status(),
                surface: traced.outcome.surface(),
                position: traced.ray.position(),
                direction: traced.ray.direction(),
                image: None,
            }
        })
        .collect();
    print(args.json, &traced)
}

/// A lens placed off one axis: rays forward through every surface onto the image plane, in the
/// lens's global frame (the object side's axis is z, surface 1's frame before any decentre).
fn run_placed(args: &TraceArgs, lens: &PlacedLens) -> anyhow::Result<()> {
    if args.backward {
        anyhow::bail!(
            "{}: the lens is not rotationally symmetric; its 3-D trace runs forward only",
            args.lens.lens
        );
    }
    let wavelength_nm = args.wavelength_nm.unwrap_or_else(|| {
        lens.prescription
            .provenance
            .design_wavelength_nm
            .unwrap_or(DEFAULT_WAVELENGTH_NM)
    });
    let tracer = PlacedTracer::new(lens, wavelength_nm)?;
    let traced: Vec<RayOutput> = read_rays(&args.rays)?
        .into_iter()
        .map(|ray| {
            let traced = tracer.trace(ray.position(), ray.direction());
            RayOutput {
                status: traced.outcome.status(),
                surface: traced.outcome.surface(),
                position: traced.position,
                direction: traced.direction,
                image: traced
                    .outcome
                    .is_ok()
                    .then(|| tracer.image_coordinates(traced.position)),
            }
        })
        .collect();
    print(args.json, &traced)
}

/// The rays as JSON, or a line each.
pub(super) fn print(json: bool, traced: &[RayOutput]) -> anyhow::Result<()> {
    if json {
        say!("{}", serde_json::to_string_pretty(&traced)?);
    } else {
        for (i, t) in traced.iter().enumerate() {
            let surface = t
                .surface
                .map_or(String::new(), |s| format!(" at surface {s}"));
            say!(
                "ray {i}: {}{surface}  position {:?}  direction {:?}",
                t.status,
                t.position,
                t.direction
            );
        }
    }
    Ok(())
}

/// The rays of a JSON file (`-`: standard input), each checked and its direction normalised as
/// the tracer's own rays are.
pub(super) fn read_rays(source: &str) -> anyhow::Result<Vec<Ray>> {
    let (name, text) = if source == "-" {
        let text =
            lensbake::limits::read_stdin_text().context("cannot read rays from standard input")?;
        ("<stdin>".to_string(), text)
    } else {
        let text = lensbake::limits::read_input_text(std::path::Path::new(source))
            .with_context(|| format!("cannot read rays file {source}"))?;
        (source.to_string(), text)
    };
    let inputs: Vec<RayInput> = serde_json::from_str(&text).with_context(|| {
        format!("{name}: expected a JSON array of {{\"origin\": [x, y, z], \"direction\": [dx, dy, dz]}}")
    })?;
    inputs
        .into_iter()
        .enumerate()
        .map(|(i, r)| Ray::new(r.origin, r.direction).with_context(|| format!("{name}: ray {i}")))
        .collect()
}
