use clap::Subcommand;

#[derive(Subcommand, Debug)]
pub enum LensCommand {
    /// List the bundled lenses.
    List,
}

pub fn run(command: LensCommand) -> anyhow::Result<()> {
    match command {
        LensCommand::List => Ok(()),
    }
}
