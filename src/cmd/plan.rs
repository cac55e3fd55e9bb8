//! `emplan plan`: order a mission's waypoints and report every order's metrics, as a table or as
//! the JSON of DESIGN.md.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use emplan::plan::{plan_orders, Geometry, OrderReport};
use serde::Serialize;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Mission file: emplan .toml, QGroundControl .plan or .waypoints
    mission: PathBuf,
    /// Print one JSON document instead of a table
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct PlanJson<'a> {
    mission: &'a str,
    orders: &'a [OrderReport],
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mission = emplan::mission::load(&args.mission)?;
    let geometry = Geometry::from_mission(&mission);
    let names: Vec<String> = std::iter::once("origin".to_string())
        .chain(mission.waypoints.iter().map(|w| w.name.clone()))
        .collect();
    let orders = plan_orders(&geometry, &names, None)
        .with_context(|| format!("planning {}", args.mission.display()))?;
    if args.json {
        let doc = PlanJson {
            mission: &mission.name,
            orders: &orders,
        };
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        print_table(&mission.name, mission.waypoints.len(), &orders);
    }
    Ok(ExitCode::SUCCESS)
}

fn print_table(name: &str, waypoints: usize, orders: &[OrderReport]) {
    println!("mission {name}: {waypoints} waypoints, tours start and end at the origin");
    println!(
        "{:<10} {:<9} {:>10} {:>12} {:>10} {:>9}  sequence",
        "objective", "direction", "distance_m", "horizontal_m", "vertical_m", "energy_kj"
    );
    for o in orders {
        let energy = o
            .energy_kj
            .map_or_else(|| "-".to_string(), |e| format!("{e:.2}"));
        println!(
            "{:<10} {:<9} {:>10.1} {:>12.1} {:>10.1} {:>9}  {}",
            format!("{:?}", o.objective).to_lowercase(),
            format!("{:?}", o.direction).to_lowercase(),
            o.distance_m,
            o.horizontal_m,
            o.vertical_m,
            energy,
            o.sequence.join(" "),
        );
    }
}
