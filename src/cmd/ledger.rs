//! `emplan ledger rebuild DIR...` and `emplan ledger import PATH...`: flights into the ledger
//! from their files (`emplan::session::import`), with a progress bar of the bytes read on a
//! terminal; and `--ledger`, the option of every command that touches the ledger.

use std::path::PathBuf;
use std::process::ExitCode;

use emplan::ledger::{Ledger, LedgerSpec};
use emplan::session::import::{self, ImportOptions, ImportSummary, Inputs};

/// `--ledger`: where the ledger is.
#[derive(Debug, Clone, clap::Args)]
pub struct LedgerArgs {
    /// The ledger: a SQLite file, or a team's PostgreSQL server (postgres://...) [default:
    /// flights/ledger.sqlite, beside the flights `fly` writes]
    #[arg(long, value_name = "FILE|URL")]
    pub ledger: Option<String>,
}

impl LedgerArgs {
    pub fn spec(&self) -> LedgerSpec {
        // None: beside the flights `fly` writes by default, as the session names it.
        self.ledger.as_deref().map_or_else(
            || emplan::session::ledger::default_spec(std::path::Path::new(super::DEFAULT_LOG_DIR)),
            LedgerSpec::parse,
        )
    }

    /// Opens the ledger, creating it if it is not there (commands that write flights).
    pub fn open(&self) -> anyhow::Result<Ledger> {
        Ok(Ledger::open(&self.spec())?)
    }

    /// Opens the ledger only if it exists (commands that only read it).
    pub fn open_existing(&self) -> anyhow::Result<Ledger> {
        Ok(Ledger::open_existing(&self.spec())?)
    }

    /// The ledger as said to the user: its file, or its server without the password.
    pub fn name(&self) -> String {
        self.spec().to_string()
    }
}

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, clap::Subcommand)]
enum Command {
    /// Write every flight directory given (or found directly inside a folder given) to the
    /// ledger: the same rows the flights wrote live; a flight written twice changes nothing
    Rebuild {
        /// Flight directories, or folders holding them (`fly --log-dir`)
        #[arg(required = true, value_name = "DIR")]
        dirs: Vec<PathBuf>,
        #[command(flatten)]
        ledger: LedgerArgs,
    },
    /// Import flight directories and the flight controller's own logs (PX4 .ulg, ArduPilot
    /// .bin, each measured alone as `emplan report LOG` measures it), in parallel
    Import {
        /// Flight directories, onboard logs, or folders holding them
        #[arg(required = true, value_name = "PATH")]
        paths: Vec<PathBuf>,
        #[command(flatten)]
        ledger: LedgerArgs,
        /// The vehicle (its vehicle file's name) of flights whose files do not say (an onboard
        /// log imported alone)
        #[arg(long, value_name = "NAME")]
        vehicle: Option<String>,
        /// The pack of flights whose files do not say
        #[arg(long, value_name = "NAME")]
        pack: Option<String>,
        /// Files measured at once [default: one per core]
        #[arg(long, value_name = "N")]
        jobs: Option<usize>,
    },
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let (found, ledger, options) = match args.command {
        Command::Rebuild { dirs, ledger } => (
            import::inputs(&dirs, false),
            ledger,
            ImportOptions::default(),
        ),
        Command::Import {
            paths,
            ledger,
            vehicle,
            pack,
            jobs,
        } => (
            import::inputs(&paths, true),
            ledger,
            ImportOptions {
                jobs,
                vehicle,
                pack,
            },
        ),
    };
    let Inputs { inputs, failed } = found;
    let mut store = ledger.open()?;
    let total: u64 = inputs.iter().map(|i| i.bytes).sum();
    let bar = super::progress::bar(
        total,
        "{prefix} [{bar:40}] {bytes}/{total_bytes} {bytes_per_sec}, {eta} left",
    );
    bar.set_prefix("importing");
    let summary = import::import(&inputs, &mut store, &options, &|bytes| bar.inc(bytes))?;
    bar.finish_and_clear();
    let summary = ImportSummary {
        failed: failed.into_iter().chain(summary.failed).collect(),
        ..summary
    };
    Ok(print(&summary, inputs.len(), &ledger.name()))
}

fn print(summary: &ImportSummary, read: usize, ledger: &str) -> ExitCode {
    for f in &summary.failed {
        eprintln!("error: {}: {}", f.path.display(), f.reason);
    }
    println!(
        "ledger {ledger}: {} inserted, {} unchanged, {} replaced ({read} flight{} found)",
        summary.inserted,
        summary.unchanged,
        summary.replaced,
        if read == 1 { "" } else { "s" }
    );
    if summary.failed.is_empty() {
        ExitCode::SUCCESS
    } else {
        println!(
            "{} path{} failed (named above)",
            summary.failed.len(),
            if summary.failed.len() == 1 { "" } else { "s" }
        );
        ExitCode::FAILURE
    }
}
