//! `emplan plan`: order a mission's waypoints by minimum energy and by the distance baselines
//! (`emplan::planner::plan_mission`), and print every order's metrics and energies (a table, or
//! the JSON of docs/json.md), where the energy order saves, and the mission against the battery.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use emplan::output::Output;
use emplan::planner::explain::saving_words;
use emplan::planner::json::{mission_document, BatteryJson, PlanJson};
use emplan::planner::{plan_mission, Explanation, Orders, Plan, PlanOptions};
use emplan::tour::Objective;

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
    /// Replace an existing --plot or --export-atsp file (never the mission nor a flight's file)
    #[arg(long)]
    force: bool,
    /// What a leg's energy counts: settled (leaving hover to settled hover at the next point,
    /// what the battery pays) or paper (to the paper's 4 m rule, its own convention); the
    /// battery check always counts everything
    #[arg(long, default_value = "settled")]
    pricing: emplan::physics::Pricing,
    /// Only this order: energy, distance (both directions) or listed (the mission file's own,
    /// nothing solved; each leg priced after the one before). Default: the energy order and
    /// every distance baseline both ways
    #[arg(long, value_enum)]
    order: Option<super::OrderArg>,
    #[command(flatten)]
    solver: super::SolverArgs,
    /// Plan in a steady wind, SPEED@FROM_DEG: m/s and the direction it blows from, degrees
    /// clockwise from north (6@270: 6 m/s from the west). Every leg, hover, take-off and
    /// landing is priced in it, and the still-air energy order is priced beside the wind-aware
    /// one
    #[arg(long, value_name = "SPEED@FROM_DEG", allow_hyphen_values = true)]
    wind: Option<emplan::physics::Wind>,
    #[command(flatten)]
    pack: super::pack::PackArgs,
}

/// TSPLIB export scale: costs in units of 0.1 J, so that a tour of thousands of legs stays
/// well inside the 32-bit integers some TSPLIB solvers use.
const ATSP_UNITS_PER_J: f64 = 10.0;

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mission = emplan::mission::load(&args.mission)?;
    if let Some(warning) = mission.unknown_warning() {
        eprintln!("warning: {warning}");
    }
    // Each output is checked before planning: never the mission, the vehicle's files or the
    // other output.
    let output = |path: &PathBuf, other: &Option<PathBuf>| {
        let mut inputs = vec![args.mission.clone()];
        inputs.extend(args.model.files());
        inputs.extend(other.iter().cloned());
        let out = Output::new(path, inputs, args.force);
        out.check().map(|()| out)
    };
    let atsp = args
        .export_atsp
        .as_ref()
        .map(|p| output(p, &args.plot))
        .transpose()?;
    let plot = args
        .plot
        .as_ref()
        .map(|p| output(p, &args.export_atsp))
        .transpose()?;
    let mut model = args
        .model
        .model()?
        .with_wind(args.wind.unwrap_or(emplan::physics::Wind::CALM));
    // The battery checked on the pack named, as the ledger learned it (`fly`'s default log
    // directory's ledger unless --ledger).
    let log_dir = std::path::Path::new(super::DEFAULT_LOG_DIR);
    let pack = args.pack.learned(log_dir, &model.vehicle.name)?;
    if let Some(pack) = &pack {
        model.vehicle = pack.learned.on_pack(&model.vehicle);
    }
    let options = PlanOptions {
        orders: match args.order {
            None => Orders::All,
            Some(super::OrderArg::Energy) => Orders::Energy,
            Some(super::OrderArg::Distance) => Orders::Distance,
            Some(super::OrderArg::Listed) => Orders::Listed,
        },
        solver: args.solver.options()?,
        sorties: args.sorties,
        pricing: args.pricing,
    };
    let plan = super::progress::solving(&format!("planning {}", mission.name), || {
        plan_mission(&mission, &model, &options)
    })?;
    if let Some(out) = &atsp {
        let text = emplan::tour::tsplib::to_text(&mission.name, &plan.energy, ATSP_UNITS_PER_J)
            .with_context(|| format!("exporting {}", out.path.display()))?;
        out.write(text.as_bytes())?;
        eprintln!("wrote {}", out.path.display());
    }
    let mut doc = mission_document(&plan, &mission);
    if let Some(pack) = &pack {
        doc.battery = pack.battery(doc.battery);
    }
    if !args.sorties {
        warn_if_over_budget(&args.mission, &doc.battery);
    }
    for warning in plan.returns.iter().flat_map(|r| &r.warnings) {
        eprintln!("warning: {warning}");
    }
    if let Some(out) = &plot {
        super::plot::plan_svg(out, &mission, &plan)?;
        eprintln!("wrote {}", out.path.display());
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        print_table(&plan, &doc, &mission);
        if let Some(pack) = &pack {
            println!("{}", pack.line());
        }
        if let Some(r) = &plan.returns {
            let to: Vec<String> = r
                .from
                .iter()
                .map(|f| format!("{} -> {}", f.from, f.to))
                .collect();
            println!("return (RTL, {}): {}", r.rule, to.join(", "));
        }
        if let Some(sorties) = &doc.sorties {
            super::sorties::print(sorties);
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Warns on stderr that the mission does not fit one battery and how to split it.
fn warn_if_over_budget(mission_path: &std::path::Path, battery: &BatteryJson) {
    if battery.feasible {
        return;
    }
    eprintln!(
        "warning: the mission needs {:.1} kJ but one battery has {:.1} kJ usable after its {}% reserve: \
         {:.1} kJ ({:.0}%) over budget; split it into sorties with `emplan plan {} --sorties`",
        battery.total_kj,
        battery.budget_kj,
        battery.reserve_pct,
        battery.excess_kj,
        100.0 * battery.excess_kj / battery.budget_kj,
        mission_path.display()
    );
}

fn print_table(plan: &Plan, doc: &PlanJson, mission: &emplan::mission::Mission) {
    let waypoints = mission.waypoints.len();
    let convention = match doc.pricing {
        emplan::physics::Pricing::Settled => "start to settled hover",
        emplan::physics::Pricing::Paper => "paper pricing: start to the 4 m rule",
    };
    println!(
        "mission {}: {waypoints} waypoints, legs priced with the {} profile ({convention})",
        doc.mission, doc.profile
    );
    if let Some(line) = mission.fence_line() {
        println!("{line}");
    }
    println!(
        "{:<10} {:<9} {:>10} {:>12} {:>10} {:>9}  sequence",
        "objective", "direction", "distance_m", "horizontal_m", "vertical_m", "energy_kj"
    );
    for o in &doc.orders {
        println!(
            "{:<10} {:<9} {:>10.1} {:>12.1} {:>10.1} {:>9.2}  {}",
            o.objective,
            format!("{:?}", o.direction).to_lowercase(),
            o.distance_m,
            o.horizontal_m,
            o.vertical_m,
            o.energy_kj,
            o.sequence.join(" "),
        );
    }
    if let Some(proof) = doc.orders.first().and_then(|o| o.proof.as_ref()) {
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
    print_blocks(plan, doc);
    if let Some(explanation) = &plan.explanation {
        explain(plan, explanation);
    }
    for note in &doc.notes {
        println!("note: {note}");
    }
    if let Some(w) = &doc.wind {
        print_wind(w);
    }
    print_actions(&doc.actions);
    print_detours(plan, doc);
    let battery = &doc.battery;
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

/// The flown order's blocks, each with its direction, ends, lines and energy, and the legs
/// that connect them with the points.
fn print_blocks(plan: &Plan, doc: &PlanJson) {
    let Some(flown) = doc.orders.get(plan.flown) else {
        return;
    };
    if flown.blocks.is_empty() {
        return;
    }
    println!("blocks in the flown order ({}):", flown.objective);
    for b in &flown.blocks {
        println!(
            "  {} {:?} {}: {} -> {}, {} waypoints, {:.0} m of lines, {:.2} kJ{}",
            b.kind.word(),
            b.name,
            if b.reversed { "reversed" } else { "forward" },
            b.entry,
            b.exit,
            b.waypoints,
            b.distance_m,
            b.energy_kj,
            b.other_end_kj
                .map(|k| format!(" (entering at the other end: {k:+.2} kJ)"))
                .unwrap_or_default(),
        );
    }
    let connecting: Vec<String> = flown
        .legs
        .iter()
        .filter(|l| l.block.is_none())
        .map(|l| format!("{} -> {} {:.2} kJ", l.from, l.to, l.energy_kj))
        .collect();
    println!(
        "  connecting legs ({}): {}",
        connecting.len(),
        connecting.join(", ")
    );
}

/// The flown order's legs routed round the fence, and how many the other orders have.
fn print_detours(plan: &Plan, doc: &PlanJson) {
    let round =
        |o: &emplan::planner::json::OrderJson| o.legs.iter().filter(|l| !l.via.is_empty()).count();
    let Some(flown) = doc.orders.get(plan.flown) else {
        return;
    };
    let others: usize = doc
        .orders
        .iter()
        .enumerate()
        .filter(|(k, _)| *k != plan.flown)
        .map(|(_, o)| round(o))
        .sum();
    if round(flown) == 0 && others == 0 {
        return;
    }
    println!(
        "detours round the fence (every leg keeps {} m from its zones):",
        plan.fence_margin_m
    );
    for leg in flown.legs.iter().filter(|l| !l.via.is_empty()) {
        let points = leg.via.len();
        println!(
            "  {} -> {} round {} via {points} point{}, {:+.0} m, {}",
            leg.from,
            leg.to,
            leg.round.join(" and "),
            if points == 1 { "" } else { "s" },
            leg.detour_m.unwrap_or(0.0),
            leg.detour_kj.map_or(
                "its straight line beyond the model".to_string(),
                |kj| format!("{kj:+.1} kJ")
            ),
        );
    }
    if others > 0 {
        println!("  the other orders fly {others} legs round the fence");
    }
}

/// The flown order's actions, place by place, and what emplan inserts to keep the file's
/// settings.
fn print_actions(actions: &[emplan::planner::json::ActionsAtJson]) {
    if actions.is_empty() {
        return;
    }
    println!("actions in the flown order (hold or turn in hover, its energy):");
    for at in actions {
        if at.commands.is_empty() && at.inserted.is_empty() {
            continue;
        }
        let commands: Vec<String> = at
            .commands
            .iter()
            .map(|c| {
                if c.hold_s > 0.0 {
                    format!("{} ({:.1} s, {:.2} kJ)", c.what, c.hold_s, c.energy_kj)
                } else {
                    c.what.clone()
                }
            })
            .collect();
        println!("  {:<12} {}", at.at, commands.join("; "));
        for i in &at.inserted {
            println!(
                "  {:<12}   + inserted {} ({}) to restore the file's {}",
                "", i.command, i.what, i.restores
            );
        }
    }
}

/// The wind, and the still-air energy order flown in it against the wind-aware one.
fn print_wind(w: &emplan::planner::json::WindJson) {
    println!(
        "in wind {} m/s from {} deg: every leg, hover, take-off and landing priced in it",
        w.speed_m_s, w.from_deg
    );
    if let (Some(still), Some(calm_kj), Some(saving_kj), Some(saving_pct)) = (
        &w.still_air_order,
        w.still_air_order_calm_kj,
        w.saving_kj,
        w.saving_pct,
    ) {
        println!(
            "  the still-air energy order {} ({calm_kj:.2} kJ in still air) costs {:.2} kJ in this wind",
            still.sequence.join(" "),
            still.energy_kj
        );
        if w.order_changed == Some(true) {
            println!(
                "  the wind-aware energy order saves {saving_kj:.2} kJ ({saving_pct:.1}%) against it"
            );
        } else {
            println!("  the wind does not change the energy order");
        }
    }
}

/// Where the energy order saves against the better direction of the distance order.
fn explain(plan: &Plan, explanation: &Explanation) {
    let direction = format!("{:?}", explanation.distance_direction).to_lowercase();
    let Some(s) = &explanation.saving else {
        println!(
            "the minimum-energy order is the minimum-distance order flown {direction}: nothing to gain"
        );
        return;
    };
    // The orders the explanation compared: the energy order, the cheaper distance direction.
    let energy_j = |objective| plan.cheapest(objective).map_or(0.0, |o| o.energy_j);
    println!(
        "the energy order {} against the distance order flown {direction}: {} of its {} legs \
         differ, flying {:.1} m further",
        saving_words(energy_j(Objective::Energy), energy_j(Objective::Distance)),
        s.legs_differ,
        s.legs,
        s.further_m,
    );
    println!(
        "  climbing: {:.0} m in all against {:.0} m ({:.0} m of climb avoided); climbs are flown \
         {:.1} m across per metre up against {:.1} m (more diagonal is cheaper); steep legs (over \
         2:1) {} against {}",
        s.climbed_m.0,
        s.climbed_m.1,
        s.climbed_m.1 - s.climbed_m.0,
        s.across_per_up.0,
        s.across_per_up.1,
        s.steep_legs.0,
        s.steep_legs.1,
    );
    let costliest: Vec<String> = s
        .costliest_avoided
        .iter()
        .map(|l| {
            format!(
                "{} -> {} ({:+.0} m over {:.0} m, {:.2} kJ)",
                plan.name(l.from),
                plan.name(l.to),
                l.vertical_m,
                l.horizontal_m,
                l.energy_j() / 1000.0
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
