//! `emplan flights`: the flights the ledger knows, by vehicle, pack, mission and date, as a table
//! (predicted against measured energy, the pack's capacity fitted) or `--json` (the ledger's
//! records).

use std::process::ExitCode;

use emplan::ledger::{FlightQuery, FlightRecord, Outcome};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Only the flights of this vehicle (its vehicle file's name)
    #[arg(long, value_name = "NAME")]
    vehicle: Option<String>,
    /// Only the flights on this pack
    #[arg(long, value_name = "NAME")]
    pack: Option<String>,
    /// Only the flights of this mission
    #[arg(long, value_name = "NAME")]
    mission: Option<String>,
    /// Only the flights started on or after this date (YYYY-MM-DD, UTC, or
    /// YYYY-MM-DDTHH:MM:SSZ)
    #[arg(long, value_name = "DATE")]
    since: Option<String>,
    /// Only the flights started before this date (YYYY-MM-DD, UTC, or YYYY-MM-DDTHH:MM:SSZ)
    #[arg(long, value_name = "DATE")]
    until: Option<String>,
    /// Print one JSON document instead of text
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    ledger: super::ledger::LedgerArgs,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mut ledger = args.ledger.open_existing()?;
    let flights = ledger.flights(&FlightQuery {
        vehicle: args.vehicle,
        pack: args.pack,
        mission: args.mission,
        since: args.since,
        until: args.until,
    })?;
    if args.json {
        let doc = serde_json::json!({ "flights": flights });
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(ExitCode::SUCCESS);
    }
    print(&flights, &args.ledger.name());
    Ok(ExitCode::SUCCESS)
}

fn outcome(o: Outcome) -> &'static str {
    match o {
        Outcome::Completed => "completed",
        Outcome::Returned => "returned",
        Outcome::Incomplete => "incomplete",
        Outcome::CutOff => "cut off",
    }
}

fn print(flights: &[FlightRecord], ledger: &str) {
    println!(
        "{} flight{} in the ledger {ledger}",
        flights.len(),
        if flights.len() == 1 { "" } else { "s" }
    );
    if flights.is_empty() {
        return;
    }
    let kj = |j: Option<f64>| j.map_or("-".to_string(), |j| format!("{:.1}", j / 1000.0));
    let text = |s: &Option<String>| s.clone().unwrap_or_else(|| "-".into());
    let header = [
        "date",
        "mission",
        "vehicle",
        "pack",
        "profile",
        "outcome",
        "predicted_kj",
        "measured_kj",
        "error",
        "capacity",
    ]
    .map(String::from);
    let mut rows = vec![header];
    for f in flights {
        let date = f.started_at.as_deref().map_or("-".to_string(), |s| {
            s.trim_end_matches('Z')
                .replacen('T', " ", 1)
                .chars()
                .take(16)
                .collect()
        });
        let error = match (f.outcome, f.predicted_j, f.measured_j) {
            (Outcome::Completed, Some(p), Some(m)) if p > 0.0 => {
                format!("{:+.1}%", (m - p) / p * 100.0)
            }
            _ => "-".into(),
        };
        let capacity = f
            .pack_fit
            .as_ref()
            .filter(|p| p.label_capacity_ah > 0.0)
            .map_or("-".to_string(), |p| {
                format!("{:.0}%", 100.0 * p.capacity_ah / p.label_capacity_ah)
            });
        rows.push([
            date,
            f.mission.clone(),
            text(&f.vehicle),
            text(&f.pack),
            text(&f.profile),
            outcome(f.outcome).to_string(),
            kj(f.predicted_j),
            kj(f.measured_j),
            error,
            capacity,
        ]);
    }
    // Each column as wide as its widest cell; text left, numbers right.
    let mut widths = [0usize; 10];
    for row in &rows {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    for row in &rows {
        let cells: Vec<String> = (row.iter().zip(widths).enumerate())
            .map(|(k, (cell, w))| {
                if k < 6 {
                    format!("{cell:<w$}")
                } else {
                    format!("{cell:>w$}")
                }
            })
            .collect();
        println!("{}", cells.join("  ").trim_end());
    }
    println!("error: measured against predicted, for completed flights; capacity: the pack's capacity fitted to the flight's voltage and current, against its label");
}
