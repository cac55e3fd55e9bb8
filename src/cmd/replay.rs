//! `emplan replay FILE`: a recorded log through the same decoding, clock and segmentation as the
//! live run, measured against the flight's plan (plan.json beside the log, or the mission found
//! in it, priced with the vehicle model), and the report printed. The log is a ground station's
//! .tlog or the flight controller's own (PX4 .ulg, ArduPilot .bin).

use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// A flight log: .tlog (QGC/MAVProxy format), PX4 .ulg or ArduPilot .bin
    tlog: PathBuf,
    /// Mission file naming the waypoints, for logs without plan.json beside them (a ULog,
    /// which holds no mission, is measured against it planned as `fly` plans it)
    #[arg(long)]
    mission: Option<PathBuf>,
    /// The plan.json an onboard log is measured against
    #[arg(long, value_name = "PLAN_JSON")]
    plan: Option<PathBuf>,
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
    // --profile, else the profile the flight was flown with (its plan's, else its autopilot's).
    let profile = match args.model.profile {
        Some(profile) => Some(profile),
        None => emplan::session::flown_profile(&args.tlog, args.plan.as_deref())?,
    };
    let model = super::VehicleArgs {
        vehicle: args.model.vehicle.clone(),
        profile,
    }
    .model()?;
    let from = emplan::session::PlanFrom {
        plan: args.plan.as_deref(),
        mission: mission.as_ref(),
        model: Some(&model),
        price_with: None,
    };
    let analysis = super::report::measure(&args.tlog, from)?;
    let priced_by = super::report::PricedBy::of(&analysis, None);
    if args.json {
        super::report::print_json(&analysis.report.json(), None, &priced_by)?;
    } else {
        println!("{}", priced_by.line());
        super::report::print(&analysis.report);
    }
    Ok(ExitCode::SUCCESS)
}
