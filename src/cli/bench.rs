//! `lensbake bench`: throughput measurements.

use super::lens::LensArgs;
use anyhow::Context;
use clap::Subcommand;
use lensbake::limits;
use lensbake::trace::{Apertures, FieldBundle, Tracer, Travel};
use std::time::Instant;

/// Seed of the bench ray bundle: fixed so that runs trace the same rays.
const BUNDLE_SEED: u64 = 20_240_601;
/// Rays traced once before timing, so thread start-up stays out of the measurement.
const WARM_UP_RAYS: usize = 10_000;

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Trace N forward rays (field uniform over the traceable field in the y-z plane, pupil
    /// point uniform over the entrance pupil, apertures on) and time the trace: once into new
    /// storage (`seconds_new_output`), then again into that storage (`seconds`).
    Trace {
        #[command(flatten)]
        lens: LensArgs,
        /// Number of rays.
        #[arg(long)]
        rays: usize,
        /// Worker threads (default: one per core).
        #[arg(long)]
        threads: Option<usize>,
        /// Print {"rays", "ray_surfaces", "seconds"} as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Render the demo scene with every lens model on each backend at several samples per
    /// pixel; time each frame and measure its error against the exact reference.
    Render(super::bench_render::RenderBenchArgs),
}

pub fn run(command: BenchCommand) -> anyhow::Result<()> {
    match command {
        BenchCommand::Trace {
            lens,
            rays,
            threads,
            json,
        } => bench_trace(&lens, rays, threads, json),
        BenchCommand::Render(args) => super::bench_render::run(args),
    }
}

fn bench_trace(
    lens: &LensArgs,
    n: usize,
    threads: Option<usize>,
    json: bool,
) -> anyhow::Result<()> {
    limits::check("--rays", n as u64, limits::MAX_RAYS)?;
    if let Some(threads) = threads {
        limits::check("--threads", threads as u64, limits::MAX_THREADS)?;
    }
    let system = lens.load()?.system;
    let tracer = Tracer::new(&system.at(system.design_wavelength_nm()));
    let bundle = FieldBundle::over_traceable_field(&tracer)?;
    let rays = bundle.sample(n, BUNDLE_SEED);
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(threads) = threads {
        anyhow::ensure!(threads > 0, "--threads must be at least 1");
        pool = pool.num_threads(threads);
    }
    let pool = pool.build().context("cannot start worker threads")?;
    // Timed twice: into new storage (whose pages the system maps as the trace first writes
    // them), then again into that storage, as a caller tracing batch after batch does.
    let (ray_surfaces, seconds_new_output, seconds) = pool.install(|| {
        let warm_up = bundle.sample(WARM_UP_RAYS.min(n), BUNDLE_SEED + 1);
        tracer.trace_batch(&warm_up, Travel::Forward, Apertures::Checked);
        let start = Instant::now();
        let mut traced = tracer.trace_batch(&rays, Travel::Forward, Apertures::Checked);
        let new_output = start.elapsed().as_secs_f64();
        let start = Instant::now();
        tracer.trace_batch_into(&rays, Travel::Forward, Apertures::Checked, &mut traced);
        (
            traced.ray_surfaces,
            new_output,
            start.elapsed().as_secs_f64(),
        )
    });
    if json {
        say!(
            "{}",
            serde_json::json!({
                "rays": n,
                "ray_surfaces": ray_surfaces,
                "seconds": seconds,
                "seconds_new_output": seconds_new_output,
                "bundle": {
                    "max_field_deg": bundle.max_field_deg,
                    "entrance_pupil_z": bundle.pupil.z,
                    "entrance_pupil_diameter": bundle.pupil.diameter,
                    "start_z": bundle.start_z,
                },
            })
        );
    } else {
        say!(
            "{n} rays (field 0..{:.4} deg, entrance pupil diameter {:.4} mm at z = {:.4} mm), \
             {ray_surfaces} ray-surface intersections in {seconds:.4} s on {} threads: \
             {:.1} M ray-surfaces/s ({seconds_new_output:.4} s into new storage)",
            bundle.max_field_deg,
            bundle.pupil.diameter,
            bundle.pupil.z,
            pool.current_num_threads(),
            ray_surfaces as f64 / seconds / 1e6,
        );
    }
    Ok(())
}
