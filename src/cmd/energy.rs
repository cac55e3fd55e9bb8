//! `emplan energy`: one hover-to-hover operation simulated directly (not from the table), in
//! still air or in a steady wind met on the leg's heading.

use std::process::ExitCode;

use anyhow::Context;
use emplan::physics::power::Model;
use emplan::physics::Wind;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Horizontal distance Xf (m)
    #[arg(long, allow_hyphen_values = true)]
    xf: f64,
    /// Signed vertical displacement Zf (m, positive = climb)
    #[arg(long, allow_hyphen_values = true)]
    zf: f64,
    /// A steady wind, SPEED@FROM_DEG: m/s and the direction it blows from, degrees clockwise
    /// from north (6@270: 6 m/s from the west); default still air
    #[arg(long, value_name = "SPEED@FROM_DEG", allow_hyphen_values = true)]
    wind: Option<Wind>,
    /// The leg's direction of travel, degrees clockwise from north (with --wind 6@0 a heading
    /// of 0 flies into the wind, 180 with it behind)
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    heading: f64,
    #[command(flatten)]
    model: super::VehicleArgs,
    /// Print one JSON document instead of text
    #[arg(long)]
    json: bool,
}

/// `--json`: the operation (DESIGN.md's fields), and with `--wind` the wind, the heading and
/// the hover power in that wind.
#[derive(serde::Serialize)]
struct Report {
    #[serde(flatten)]
    operation: emplan::physics::power::OperationJson,
    #[serde(skip_serializing_if = "Option::is_none")]
    wind: Option<Wind>,
    #[serde(skip_serializing_if = "Option::is_none")]
    heading_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    hover_power_w: Option<f64>,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if !args.heading.is_finite() {
        anyhow::bail!("--heading {}: expected degrees", args.heading);
    }
    let vehicle = args.model.vehicle()?;
    let profile = args.model.profile.unwrap_or(vehicle.default_profile());
    let wind = args.wind.unwrap_or(Wind::CALM);
    let model = Model::new(&vehicle).in_wind(wind.on_heading(args.heading));
    let op = model
        .operation(profile, args.xf, args.zf)
        .with_context(|| match args.wind {
            Some(w) => format!(
                "simulating Xf {} m, Zf {} m on heading {} deg in wind {w}",
                args.xf, args.zf, args.heading
            ),
            None => format!("simulating Xf {} m, Zf {} m", args.xf, args.zf),
        })?;
    let hover_power_w = match args.wind {
        Some(_) => Some(model.hover_power_w().context("the hover in that wind")?),
        None => None,
    };
    let report = Report {
        operation: op.to_json(args.xf, args.zf, profile),
        wind: args.wind,
        heading_deg: args.wind.map(|_| args.heading),
        hover_power_w,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        let o = &report.operation;
        println!(
            "{profile}: Xf {} m, Zf {} m: {:.3} kJ in {:.2} s to within 4 m; settling {:.3} kJ in {:.2} s more",
            args.xf, args.zf, o.energy_kj, op.duration_s, o.settle_energy_kj, op.settle_duration_s
        );
        if let (Some(w), Some(hover)) = (args.wind, hover_power_w) {
            println!(
                "in wind {} m/s from {} deg, heading {} deg; hover in that wind {hover:.1} W",
                w.speed_m_s, w.from_deg, args.heading
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
