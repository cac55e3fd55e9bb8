//! `emplan plan`: order a mission's waypoints by minimum energy and by the distance baselines,
//! report every order's metrics and energies (table or the JSON of DESIGN.md), and check the
//! mission against the battery.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use emplan::mission::Mission;
use emplan::physics::{hover_power_w, simulate_operation, EnergyTable, Profile, Vehicle};
use emplan::plan::energy::energy_matrix;
use emplan::plan::{cheapest, plan_orders, Geometry, LegReport, Objective, OrderReport};
use serde::Serialize;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Mission file: emplan .toml, QGroundControl .plan or .waypoints
    mission: PathBuf,
    #[command(flatten)]
    model: super::VehicleArgs,
    /// Print one JSON document instead of a table
    #[arg(long)]
    json: bool,
    /// Split the mission into sorties of least total energy, one battery each (a single sortie
    /// when one battery suffices)
    #[arg(long)]
    sorties: bool,
    /// Draw the energy order and the min-distance order (top and side views) to this SVG file
    #[arg(long, value_name = "FILE.svg")]
    plot: Option<PathBuf>,
    /// Write the energy cost matrix as a TSPLIB ATSP file (integer units of 0.1 J; node 1 is
    /// the origin), for other solvers
    #[arg(long, value_name = "FILE.atsp")]
    export_atsp: Option<PathBuf>,
    #[command(flatten)]
    solver: super::SolverArgs,
}

/// The mission flown in the energy order against the battery.
#[derive(Debug, Serialize)]
pub struct Battery {
    pub takeoff_kj: f64,
    pub legs_kj: f64,
    pub hover_kj: f64,
    pub landing_kj: f64,
    pub total_kj: f64,
    pub budget_kj: f64,
    pub reserve_pct: f64,
    pub feasible: bool,
    /// Energy over the budget (0 when feasible).
    pub excess_kj: f64,
}

#[derive(Serialize)]
struct PlanJson<'a> {
    mission: &'a str,
    profile: Profile,
    orders: &'a [OrderReport],
    battery: &'a Battery,
    #[serde(skip_serializing_if = "Option::is_none")]
    sorties: Option<&'a super::sorties::SortiesReport>,
}

/// A mission planned with a vehicle: every order, and the energy order against the battery.
pub struct Planned {
    pub vehicle: Vehicle,
    pub profile: Profile,
    pub orders: Vec<OrderReport>,
    pub battery: Battery,
    /// Energy of every leg (J), node 0 = origin.
    pub energy: emplan::plan::CostMatrix,
}

/// A mission's legs priced with a vehicle's energy table.
pub struct Priced {
    pub vehicle: Vehicle,
    pub profile: Profile,
    pub geometry: Geometry,
    /// `names[k]` names node `k`; node 0 is the origin.
    pub names: Vec<String>,
    /// Energy of every leg (J), node 0 = origin.
    pub energy: emplan::plan::CostMatrix,
}

/// Prices every leg of `mission` with the vehicle in `vehicle_dir` (its energy table for
/// `profile`, or the vehicle's default profile), start to settled hover: everything the battery
/// pays.
pub fn price_mission(
    mission: &Mission,
    vehicle_dir: &Path,
    profile: Option<Profile>,
) -> anyhow::Result<Priced> {
    let vehicle = Vehicle::load(vehicle_dir)?;
    let profile = profile.unwrap_or(vehicle.default_profile());
    let table = EnergyTable::load(vehicle_dir, profile, &vehicle)?;
    let geometry = Geometry::from_mission(mission);
    let names: Vec<String> = std::iter::once("origin".to_string())
        .chain(mission.waypoints.iter().map(|w| w.name.clone()))
        .collect();
    let energy = energy_matrix(&geometry, &names, |x, z| {
        table.lookup(x, z).map(|leg| leg.total_energy_j())
    })
    .with_context(|| format!("pricing the legs of mission {}", mission.name))?;
    Ok(Priced {
        vehicle,
        profile,
        geometry,
        names,
        energy,
    })
}

/// Plans `mission` with the vehicle in `vehicle_dir`. `orders[0]` is the energy order.
pub fn plan_mission(
    mission: &Mission,
    vehicle_dir: &Path,
    profile: Option<Profile>,
    solver: &emplan::plan::solver::Options,
) -> anyhow::Result<Planned> {
    plan_priced(
        mission,
        price_mission(mission, vehicle_dir, profile)?,
        solver,
    )
}

/// Plans a priced mission: every order, and the energy order against the battery.
pub fn plan_priced(
    mission: &Mission,
    priced: Priced,
    solver: &emplan::plan::solver::Options,
) -> anyhow::Result<Planned> {
    let Priced {
        vehicle,
        profile,
        geometry,
        names,
        energy,
    } = priced;
    let orders = plan_orders(&geometry, &names, Some(&energy), solver)
        .with_context(|| format!("planning mission {}", mission.name))?;
    let battery = battery(mission, &vehicle, profile, &orders[0])?;
    Ok(Planned {
        vehicle,
        profile,
        orders,
        battery,
        energy,
    })
}

/// TSPLIB export scale: costs in units of 0.1 J, so that a tour of thousands of legs stays
/// well inside the 32-bit integers some TSPLIB solvers use.
const ATSP_UNITS_PER_J: f64 = 10.0;

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mission = emplan::mission::load(&args.mission)?;
    let priced = price_mission(&mission, &args.model.vehicle, args.model.profile)?;
    if let Some(path) = &args.export_atsp {
        let text = emplan::plan::tsplib::to_text(&mission.name, &priced.energy, ATSP_UNITS_PER_J)
            .with_context(|| format!("exporting {}", path.display()))?;
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    let planned = plan_priced(&mission, priced, &args.solver.options()?)?;
    let sorties = if args.sorties {
        Some(super::sorties::split_mission(&mission, &planned)?)
    } else {
        super::sorties::warn_if_over_budget(&args.mission, &planned.battery);
        None
    };
    let Planned {
        profile,
        orders,
        battery,
        ..
    } = planned;
    if let Some(path) = &args.plot {
        super::plot::plan_svg(path, &mission, profile, &orders)?;
        eprintln!("wrote {}", path.display());
    }
    if args.json {
        let doc = PlanJson {
            mission: &mission.name,
            profile,
            orders: &orders,
            battery: &battery,
            sorties: sorties.as_ref(),
        };
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        print_table(&mission, profile, &orders, &battery);
        if let Some(sorties) = &sorties {
            super::sorties::print(sorties);
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn battery(
    mission: &Mission,
    vehicle: &Vehicle,
    profile: Profile,
    energy_order: &OrderReport,
) -> anyhow::Result<Battery> {
    let h = mission.origin.height_above_home_m;
    let takeoff = simulate_operation(vehicle, profile, 0.0, h).context("pricing the take-off")?;
    let landing = simulate_operation(vehicle, profile, 0.0, -h).context("pricing the landing")?;
    let hover_s: f64 = mission.waypoints.iter().map(|w| w.hover_s).sum();
    let hover_j = hover_power_w(vehicle)? * hover_s;
    let legs_kj = energy_order.energy_kj.unwrap_or(0.0);
    let total_kj = takeoff.total_energy_j() / 1000.0
        + legs_kj
        + hover_j / 1000.0
        + landing.total_energy_j() / 1000.0;
    let budget_kj = vehicle.mission_budget_j() / 1000.0;
    Ok(Battery {
        takeoff_kj: takeoff.total_energy_j() / 1000.0,
        legs_kj,
        hover_kj: hover_j / 1000.0,
        landing_kj: landing.total_energy_j() / 1000.0,
        total_kj,
        budget_kj,
        reserve_pct: vehicle.planning.reserve_pct,
        feasible: total_kj <= budget_kj,
        excess_kj: (total_kj - budget_kj).max(0.0),
    })
}

fn print_table(mission: &Mission, profile: Profile, orders: &[OrderReport], battery: &Battery) {
    println!(
        "mission {}: {} waypoints, legs priced with the {profile} profile (start to settled hover)",
        mission.name,
        mission.waypoints.len()
    );
    println!(
        "{:<10} {:<9} {:>10} {:>12} {:>10} {:>9}  sequence",
        "objective", "direction", "distance_m", "horizontal_m", "vertical_m", "energy_kj"
    );
    for o in orders {
        println!(
            "{:<10} {:<9} {:>10.1} {:>12.1} {:>10.1} {:>9.2}  {}",
            format!("{:?}", o.objective).to_lowercase(),
            format!("{:?}", o.direction).to_lowercase(),
            o.distance_m,
            o.horizontal_m,
            o.vertical_m,
            o.energy_kj.unwrap_or(f64::NAN),
            o.sequence.join(" "),
        );
    }
    if let Some(proof) = &orders[0].proof {
        if proof.optimal {
            println!(
                "the energy order is proven optimal ({}, {:.3} s)",
                proof.solver, proof.seconds
            );
        } else {
            println!(
                "the energy order is the best found ({}, {:.1} s): at least {:.2} kJ is needed, gap {:.2}%",
                proof.solver, proof.seconds, proof.lower_bound, proof.gap_pct
            );
        }
    }
    explain(orders);
    println!(
        "battery: take-off {:.1} + legs {:.1} + hovering {:.1} + landing {:.1} = {:.1} kJ of {:.1} kJ usable after the {}% reserve: {}",
        battery.takeoff_kj,
        battery.legs_kj,
        battery.hover_kj,
        battery.landing_kj,
        battery.total_kj,
        battery.budget_kj,
        battery.reserve_pct,
        if battery.feasible { "feasible" } else { "NOT FEASIBLE on one battery" }
    );
}

/// Where the energy order saves against the better direction of the distance order.
fn explain(orders: &[OrderReport]) {
    let energy = &orders[0];
    let Some(distance) = cheapest(orders, Objective::Distance) else {
        return;
    };
    let (e, d) = (
        energy.energy_kj.unwrap_or(0.0),
        distance.energy_kj.unwrap_or(0.0),
    );
    if d - e <= 1e-9 * d.abs() {
        println!(
            "the minimum-energy order is the minimum-distance order flown {:?}: nothing to gain",
            distance.direction
        );
        return;
    }
    let climbed = |o: &OrderReport| o.legs.iter().map(|l| l.vertical_m.max(0.0)).sum::<f64>();
    // Horizontal metres flown per metre climbed, over the climbing legs: how diagonal the climbs are.
    let slope = |o: &OrderReport| {
        let climbs = o.legs.iter().filter(|l| l.vertical_m > 0.5);
        let (x, z) = climbs.fold((0.0, 0.0), |(x, z), l| {
            (x + l.horizontal_m, z + l.vertical_m)
        });
        if z > 0.0 {
            x / z
        } else {
            0.0
        }
    };
    let steep = |o: &OrderReport| {
        o.legs
            .iter()
            .filter(|l| l.vertical_m.abs() > 2.0 * l.horizontal_m.max(0.1))
            .count()
    };
    let in_other = |l: &LegReport, other: &OrderReport| {
        other.legs.iter().any(|m| m.from == l.from && m.to == l.to)
    };
    let shared = energy.legs.iter().filter(|l| in_other(l, distance)).count();
    println!(
        "the energy order saves {:.2} kJ ({:.1}%) against the distance order flown {}: {} of its {} legs differ, \
         flying {:.1} m further",
        d - e,
        100.0 * (d - e) / d,
        format!("{:?}", distance.direction).to_lowercase(),
        energy.legs.len() - shared,
        energy.legs.len(),
        energy.distance_m - distance.distance_m,
    );
    println!(
        "  climbing: {:.0} m in all against {:.0} m ({:.0} m of climb avoided); climbs are flown \
         {:.1} m across per metre up against {:.1} m (more diagonal is cheaper); steep legs (over \
         2:1) {} against {}",
        climbed(energy),
        climbed(distance),
        climbed(distance) - climbed(energy),
        slope(energy),
        slope(distance),
        steep(energy),
        steep(distance),
    );
    let mut dropped: Vec<&LegReport> = distance
        .legs
        .iter()
        .filter(|l| !in_other(l, energy))
        .collect();
    dropped.sort_by(|a, b| {
        b.energy_kj
            .unwrap_or(0.0)
            .total_cmp(&a.energy_kj.unwrap_or(0.0))
    });
    let costliest: Vec<String> = dropped
        .iter()
        .take(3)
        .map(|l| {
            format!(
                "{} -> {} ({:+.0} m over {:.0} m, {:.2} kJ)",
                l.from,
                l.to,
                l.vertical_m,
                l.horizontal_m,
                l.energy_kj.unwrap_or(0.0)
            )
        })
        .collect();
    if !costliest.is_empty() {
        println!(
            "  costliest distance-order legs the energy order avoids: {}",
            costliest.join(", ")
        );
    }
}
