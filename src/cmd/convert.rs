//! `emplan convert IN OUT`: convert a mission between emplan TOML, QGroundControl `.plan` and
//! `QGC WPL 110` `.waypoints`, each chosen by its file extension.

use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Mission to read (.toml, .plan, .waypoints or .txt)
    input: PathBuf,
    /// File to write; its extension chooses the format
    output: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mission = emplan::mission::load(&args.input)?;
    emplan::mission::save(&mission, &args.output)?;
    println!(
        "wrote {} ({} waypoints, mission {:?}) from {}",
        args.output.display(),
        mission.waypoints.len(),
        mission.name,
        args.input.display()
    );
    Ok(ExitCode::SUCCESS)
}
