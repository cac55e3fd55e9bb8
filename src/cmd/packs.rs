//! `emplan packs`: every pack the ledger's flights were flown on, as its flights show it now
//! (`emplan::ledger::packs`): cycles, capacity against its label, internal resistance, fade per
//! cycle, each with its standard error, and warnings; `--json` the summaries, `--plot` each
//! pack's capacity and resistance over its cycles with the trend.

use std::path::PathBuf;
use std::process::ExitCode;

use emplan::ledger::packs::{self, Estimate, PackSummary};
use emplan::ledger::FlightQuery;
use emplan::output::Output;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Print one JSON document instead of text
    #[arg(long)]
    json: bool,
    /// Draw each pack's capacity and internal resistance over its cycles, with the trend
    #[arg(long, value_name = "FILE.svg")]
    plot: Option<PathBuf>,
    /// Replace an existing --plot file (never the ledger nor a file inside a flight directory)
    #[arg(long, requires = "plot")]
    force: bool,
    #[command(flatten)]
    ledger: super::ledger::LedgerArgs,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let plot = args.plot.as_ref().map(|path| {
        let inputs = match args.ledger.spec() {
            emplan::ledger::LedgerSpec::Sqlite(file) => vec![file],
            emplan::ledger::LedgerSpec::Postgres(_) => Vec::new(),
        };
        Output::new(path, inputs, args.force)
    });
    if let Some(out) = &plot {
        out.check()?;
    }
    let mut ledger = args.ledger.open_existing()?;
    let flights = ledger.flights(&FlightQuery::default())?;
    let summaries = packs::summarise(&flights);
    if let Some(out) = &plot {
        let histories = emplan::session::ledger_read::pack_histories(&flights, &summaries);
        super::plot::packs_svg(out, &histories)?;
    }
    if args.json {
        let doc = serde_json::json!({ "packs": summaries });
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(ExitCode::SUCCESS);
    }
    print(&summaries, &args.ledger.name());
    if let Some(out) = &plot {
        println!("wrote {}", out.path.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// `value +- sd` scaled by `scale`, with `decimals`.
fn estimate(e: Option<Estimate>, scale: f64, decimals: usize) -> String {
    e.map_or("-".to_string(), |e| {
        format!(
            "{:.decimals$} ± {:.decimals$}",
            e.value * scale,
            e.sd * scale
        )
    })
}

fn print(summaries: &[PackSummary], ledger: &str) {
    println!(
        "{} pack{} in the ledger {ledger}",
        summaries.len(),
        if summaries.len() == 1 { "" } else { "s" }
    );
    if summaries.is_empty() {
        println!("(a flight names its pack with `fly --pack NAME`, or the autopilot's smart battery does)");
        return;
    }
    println!(
        "{:<12} {:>7} {:>7} {:>16} {:>14} {:>16} {:>18}",
        "pack",
        "flights",
        "cycles",
        "capacity_ah",
        "of_label_%",
        "resistance_mohm",
        "fade_mah_per_cycle"
    );
    for s in summaries {
        println!(
            "{:<12} {:>7} {:>7.2} {:>16} {:>14} {:>16} {:>18}",
            s.name,
            s.flights,
            s.cycles,
            estimate(s.capacity_ah, 1.0, 2),
            estimate(s.capacity_ratio, 100.0, 1),
            estimate(s.internal_resistance_ohm, 1000.0, 1),
            estimate(s.fade_ah_per_cycle, 1000.0, 1),
        );
    }
    println!(
        "± one standard error; cycles: the charge drawn over all its flights against its label"
    );
    for s in summaries {
        for w in &s.warnings {
            println!("warning: pack {}: {w}", s.name);
        }
    }
}
