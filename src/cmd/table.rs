//! `emplan table build`: rebuild a vehicle's energy tables in parallel, with a progress bar.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use emplan::output::Output;
use emplan::physics::table::{DEFAULT_XF, DEFAULT_ZF};
use emplan::physics::{EnergyTable, Profile, Vehicle};

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: TableCommand,
}

#[derive(Debug, clap::Subcommand)]
enum TableCommand {
    /// Simulate every grid point and write <vehicle>/<profile>.table
    Build {
        /// Vehicle directory holding vehicle.toml
        #[arg(long, default_value = "models/s1000")]
        vehicle: PathBuf,
        /// ptf, hvb, px4, ardupilot or all (default: all)
        #[arg(long, default_value = "all")]
        profile: String,
    },
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let TableCommand::Build {
        vehicle: dir,
        profile,
    } = args.command;
    let vehicle = Vehicle::load(&dir)?;
    let profiles: Vec<Profile> = if profile == "all" {
        Profile::ALL.to_vec()
    } else {
        vec![profile.parse().map_err(anyhow::Error::msg)?]
    };
    for profile in profiles {
        let bar = indicatif::ProgressBar::new((DEFAULT_XF.count * DEFAULT_ZF.count) as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{prefix} [{bar:40}] {pos}/{len} cells, {eta} left",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar.set_prefix(profile.to_string());
        let started = Instant::now();
        let table = EnergyTable::build(&vehicle, profile, DEFAULT_XF, DEFAULT_ZF, |done, _| {
            bar.set_position(done as u64)
        })
        .with_context(|| format!("building the {profile} table"))?;
        bar.finish_and_clear();
        let path = EnergyTable::path(&dir, profile);
        // Rebuilding the vehicle's tables in place is what the command is for: forced, but
        // never over vehicle.toml or into a flight directory, and atomic.
        Output::new(&path, vec![dir.join("vehicle.toml")], true)
            .write(table.to_text().as_bytes())?;
        eprintln!(
            "{profile}: {} cells in {:.1} s -> {}",
            DEFAULT_XF.count * DEFAULT_ZF.count,
            started.elapsed().as_secs_f64(),
            path.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}
