//! The `emplan` command line: parses arguments (clap) and hands each subcommand to its module
//! under `src/cmd/`. The binary is the only place that knows clap and anyhow.

mod cmd;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Minimum-energy mission planning for multirotors.
#[derive(Debug, Parser)]
#[command(name = "emplan", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Order a mission's waypoints and report every order's metrics.
    Plan(cmd::plan::Args),
    /// Convert a mission between emplan TOML, QGroundControl .plan and .waypoints.
    Convert(cmd::convert::Args),
    /// Solve a TSPLIB asymmetric TSP instance.
    Tsp(cmd::tsp::Args),
    /// Simulate one hover-to-hover operation with the physics model.
    Energy(cmd::energy::Args),
    /// Build the precomputed energy tables.
    Table(cmd::table::Args),
    /// Compare the model with the paper's published energies (and refit with --fit).
    Calibrate(cmd::calibrate::Args),
    /// Upload a planned mission to the autopilot and verify it by reading it back.
    Upload(cmd::upload::Args),
    /// Read the autopilot's mission.
    Download(cmd::download::Args),
    /// Plan, upload, fly (arming only with --arm), record the battery telemetry and report
    /// every leg's energy against its prediction; without --connect the built-in mock flies it.
    Fly(cmd::fly::Args),
    /// Record a flight flown from any ground station until it lands (or Ctrl-C).
    Record(cmd::record::Args),
    /// Replay a recorded flight log and report it.
    Replay(cmd::replay::Args),
    /// Report recorded flights: per-leg predicted vs measured energy; several flights combined.
    Report(cmd::report::Args),
    /// Run the built-in mock autopilot.
    MockAutopilot(cmd::mock_autopilot::Args),
    /// The paper's random-mission study: energy order vs distance orders over many missions.
    ///
    /// Each mission has N waypoints uniform in [-XY, XY] m east and north and [-Z, Z] m up around
    /// the origin. For each, the minimum-energy order (exact) is compared with the min-distance
    /// (D), min-horizontal (X) and min-vertical (Z, ties by X) orders, each in its better
    /// direction. Reported per baseline: the energy increase over the minimum-energy order, mean,
    /// 90th percentile (nearest rank: the ceil(0.9 K)-th smallest of K missions) and maximum; and
    /// the shares of missions where the min-D order differs from the energy order and where min-Z
    /// or min-X beats min-D. Mission K of a study is
    /// `emplan generate --waypoints N --xy XY --z Z --seed S --mission K`.
    Study(cmd::study::Args),
    /// Write one random mission (the study's distribution) as a mission file.
    ///
    /// Waypoints W1..WN uniform in [-XY, XY] m east and north and [-Z, Z] m up around the origin,
    /// written in local x_m/y_m/z_m. The origin hovers Z + 5 m above home, so every waypoint is
    /// at least 5 m above home (the mission minimum is 2 m). With the same N, XY, Z and seed,
    /// `--mission K` writes mission K of `emplan study`.
    Generate(cmd::generate::Args),
}

fn main() -> ExitCode {
    // A reader that closes the pipe early (`emplan plan ... | head`) ends the process quietly, as
    // for other command-line tools, instead of a panic on the next print: Rust ignores SIGPIPE
    // by default.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE at start-up, before any thread
    // exists, has no other effect.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Plan(args) => cmd::plan::run(args),
        Command::Convert(args) => cmd::convert::run(args),
        Command::Tsp(args) => cmd::tsp::run(args),
        Command::Energy(args) => cmd::energy::run(args),
        Command::Table(args) => cmd::table::run(args),
        Command::Calibrate(args) => cmd::calibrate::run(args),
        Command::Upload(args) => cmd::upload::run(args),
        Command::Download(args) => cmd::download::run(args),
        Command::Fly(args) => cmd::fly::run(args),
        Command::Record(args) => cmd::record::run(args),
        Command::Replay(args) => cmd::replay::run(args),
        Command::Report(args) => cmd::report::run(args),
        Command::MockAutopilot(args) => cmd::mock_autopilot::run(args),
        Command::Study(args) => cmd::study::run(args),
        Command::Generate(args) => cmd::generate::run(args),
    };
    match result {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}
