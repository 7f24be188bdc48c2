//! One module per subcommand; each turns parsed arguments into library calls and prints.

mod lens;
mod lrtf;

use clap::{Parser, Subcommand};

#[derive(Parser, Debug)]
#[command(
    name = "lensbake",
    version,
    about = "Lens design analysis and LRTF precomputation"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Read, validate, convert and list lens prescriptions.
    #[command(subcommand)]
    Lens(lens::LensCommand),
    /// Bake a lens ray transfer function table and its effective-pupil bounds.
    Bake(lrtf::BakeArgs),
    /// Evaluate or describe baked LRTF tables.
    #[command(subcommand)]
    Lrtf(lrtf::LrtfCommand),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Lens(command) => lens::run(command),
        Command::Bake(args) => lrtf::run_bake(args),
        Command::Lrtf(command) => lrtf::run(command),
    }
}
