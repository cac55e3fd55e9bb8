//! The `emplan` command line: parses arguments (clap) and hands each subcommand to its module
//! under `src/cmd/`. The binary is the only place that knows clap and anyhow.

mod cmd;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// The version and the git revision it was built from.
const VERSION: &str = concat!(
    env!("CARGO_PKG_VERSION"),
    " (",
    env!("EMPLAN_GIT_REVISION"),
    ")"
);

/// Minimum-energy mission planning for multirotors.
#[derive(Debug, Parser)]
#[command(name = "emplan", version = VERSION, about)]
struct Cli {
    /// No progress lines on stderr (they are drawn only on a terminal anyway)
    #[arg(long, short, global = true)]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
    /// Diagnostics on stderr as text, or as one JSON object a line (for log collectors)
    #[arg(long, global = true, value_enum, default_value = "text")]
    log_format: LogFormat,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum LogFormat {
    Text,
    Json,
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
    /// Flights into the ledger from their files: `rebuild` flight directories, `import` them and
    /// the flight controller's own logs.
    Ledger(cmd::ledger::Args),
    /// The flights the ledger knows, by vehicle, pack, mission and date.
    Flights(cmd::flights::Args),
    /// Every pack the ledger knows: capacity, resistance and their trend over its cycles.
    Packs(cmd::packs::Args),
    /// The field-day service: hold the vehicle link, plan every mission in a folder, upload
    /// on request, record and report every flight; an HTTP API on loopback.
    Serve(cmd::serve::Args),
    /// Run the built-in mock autopilot.
    MockAutopilot(cmd::mock_autopilot::Args),
    /// A physical battery for PX4 SITL (started with SIM_BAT_ENABLE=0): follows the vehicle's
    /// motion on its onboard link and reports the vehicle model's battery as a smart battery.
    BatterySim(cmd::battery_sim::Args),
    /// The paper's random-mission study: energy order vs distance orders over many missions.
    ///
    /// Each mission has N waypoints uniform in [-XY, XY] m east and north and [-Z, Z] m up around
    /// the origin. For each, the minimum-energy order (exact) is compared with the min-distance
    /// (D), min-horizontal (X) and min-vertical (Z, ties by X) orders, each in its better
    /// direction (or, with --baseline-direction solver, in the direction a solver returns).
    /// Reported per baseline: the energy increase over the minimum-energy order, mean,
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
    /// Print a shell completion script: `emplan completions bash > ~/.local/share/bash-completion/completions/emplan`.
    Completions {
        /// bash, zsh, fish, elvish or powershell
        shell: clap_complete::Shell,
    },
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
    let cli = Cli::parse();
    cmd::progress::set_quiet(cli.quiet);
    // The service reports what it does (flights, uploads) by default; other commands only
    // warnings. RUST_LOG overrides.
    let level = if matches!(cli.command, Command::Serve(_)) {
        "info"
    } else {
        "warn"
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(level));
    let logs = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    match cli.log_format {
        LogFormat::Text => logs.with_ansi(colour()).init(),
        LogFormat::Json => logs.json().init(),
    }
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
        Command::Ledger(args) => cmd::ledger::run(args),
        Command::Flights(args) => cmd::flights::run(args),
        Command::Packs(args) => cmd::packs::run(args),
        Command::Serve(args) => cmd::serve::run(args),
        Command::MockAutopilot(args) => cmd::mock_autopilot::run(args),
        Command::BatterySim(args) => cmd::battery_sim::run(args),
        Command::Study(args) => cmd::study::run(args),
        Command::Generate(args) => cmd::generate::run(args),
        Command::Completions { shell } => {
            use clap::CommandFactory;
            clap_complete::generate(shell, &mut Cli::command(), "emplan", &mut std::io::stdout());
            Ok(ExitCode::SUCCESS)
        }
    };
    match result {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {}", error_text(&err));
            ExitCode::FAILURE
        }
    }
}

/// Whether stderr may carry colour: a terminal, and no `NO_COLOR` set (https://no-color.org).
/// clap and indicatif read `NO_COLOR` themselves.
fn colour() -> bool {
    use std::io::IsTerminal;
    std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty())
}

/// An error and its causes joined by ": ", each said once: a cause whose text its parent
/// already carries (an OS error quoted in a file error) is not repeated.
fn error_text(err: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in err.chain() {
        let message = cause.to_string();
        if text.contains(&message) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&message);
    }
    text
}
