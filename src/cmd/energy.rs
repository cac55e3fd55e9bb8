//! `emplan energy`: one hover-to-hover operation simulated directly (not from the table).

use std::process::ExitCode;

use anyhow::Context;
use emplan::physics::{simulate_operation, Profile, Vehicle};
use serde::Serialize;

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

/// The JSON of DESIGN.md, plus the settle phase the 4 m rule leaves out.
#[derive(Serialize)]
struct EnergyJson {
    xf_m: f64,
    zf_m: f64,
    profile: Profile,
    energy_kj: f64,
    duration_s: f64,
    settle_energy_kj: f64,
    settle_duration_s: f64,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let vehicle = Vehicle::load(&args.model.vehicle)?;
    let profile = args.model.profile.unwrap_or(vehicle.default_profile());
    let op = simulate_operation(&vehicle, profile, args.xf, args.zf)
        .with_context(|| format!("simulating Xf {} m, Zf {} m", args.xf, args.zf))?;
    let report = EnergyJson {
        xf_m: args.xf,
        zf_m: args.zf,
        profile,
        energy_kj: op.energy_j / 1000.0,
        duration_s: op.duration_s,
        settle_energy_kj: op.settle_energy_j / 1000.0,
        settle_duration_s: op.settle_duration_s,
    };
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
