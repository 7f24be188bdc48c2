//! One module per subcommand; each turns parsed arguments into library calls and prints.

mod bench;
mod lens;
mod trace;

use clap::{Parser, Subcommand};

#[derive(Parser, Debug)]
#[command(name = "lensbake", version, about = "Lens design analysis and LRTF precomputation")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Read, validate, convert and list lens prescriptions.
    #[command(subcommand)]
    Lens(lens::LensCommand),
    /// Trace exact rays through a lens (JSON in, JSON out).
    Trace(trace::TraceArgs),
    /// Measure throughput.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Lens(command) => lens::run(command),
        Command::Trace(args) => trace::run(args),
        Command::Bench(command) => bench::run(command),
    }
}
