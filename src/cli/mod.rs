//! One module per subcommand; each turns parsed arguments into library calls and prints.

mod lens;

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
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Lens(command) => lens::run(command),
    }
}
