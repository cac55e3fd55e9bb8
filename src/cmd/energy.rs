//! `emplan energy`: one hover-to-hover operation simulated directly (not from the table).

use std::process::ExitCode;

use anyhow::Context;
use emplan::physics::simulate_operation;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Horizontal distance Xf (m)
    #[arg(long, allow_hyphen_values = true)]
    xf: f64,
    /// Signed vertical displacement Zf (m, positive = climb)
    #[arg(long, allow_hyphen_values = true)]
    zf: f64,
    #[command(flatten)]
    model: super::VehicleArgs,
    /// Print one JSON document instead of text
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let vehicle = args.model.vehicle()?;
    let profile = args.model.profile.unwrap_or(vehicle.default_profile());
    let op = simulate_operation(&vehicle, profile, args.xf, args.zf)
        .with_context(|| format!("simulating Xf {} m, Zf {} m", args.xf, args.zf))?;
    let report = op.to_json(args.xf, args.zf, profile);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{profile}: Xf {} m, Zf {} m: {:.3} kJ in {:.2} s to within 4 m; settling {:.3} kJ in {:.2} s more",
            args.xf, args.zf, report.energy_kj, op.duration_s, report.settle_energy_kj, op.settle_duration_s
        );
    }
    Ok(ExitCode::SUCCESS)
}
