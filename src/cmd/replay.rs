//! `emplan replay FILE.tlog`: the recorded log through the same decoding, clock and
//! segmentation as the live run, measured against the flight's plan (plan.json beside the log,
//! or the mission items found in it, priced with the vehicle model), and the report printed.

use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// A flight log (.tlog, QGC/MAVProxy format)
    tlog: PathBuf,
    /// Mission file naming the waypoints, for logs without plan.json beside them
    #[arg(long)]
    mission: Option<PathBuf>,
    #[command(flatten)]
    model: super::VehicleArgs,
    /// Print one JSON document (the report) instead of text
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mission = args
        .mission
        .as_deref()
        .map(emplan::mission::load)
        .transpose()?;
    let model = args.model.model()?;
    let analysis = super::report::analyse(&args.tlog, mission.as_ref(), Some(&model))?;
    super::report::warn_skipped(&args.tlog, &analysis.replay);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&analysis.report.json())?);
    } else {
        super::report::print(&analysis.report);
    }
    Ok(ExitCode::SUCCESS)
}
