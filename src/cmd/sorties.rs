//! `emplan plan --sorties`: split a mission one battery cannot fly into sorties (one battery
//! each, least total energy; `plan::sorties` does the splitting), report them as text or as
//! the `"sorties"` object of the plan JSON, and warn about a mission over budget when the split
//! was not asked for.

use std::path::Path;

use anyhow::Context;
use emplan::mission::Mission;
use emplan::physics::hover_power_w;
use emplan::plan::orders::report;
use emplan::plan::sorties::{split, Method, SortieError, SortieOptions, SortieProblem};
use emplan::plan::{Direction, Geometry, LegReport, Objective};
use serde::Serialize;

use super::plan::{Battery, Planned};

/// The `"sorties"` object of `emplan plan --sorties --json`.
#[derive(Debug, Serialize)]
pub struct SortiesReport {
    /// Number of sorties, one battery each.
    pub batteries: usize,
    /// Energy of all sorties together.
    pub total_kj: f64,
    /// Whether the total is proven minimal (exact split).
    pub optimal: bool,
    pub method: Method,
    /// Energy one battery may spend on a sortie, after its reserve.
    pub budget_kj: f64,
    /// The whole mission flown as one tour (the energy order), for comparison.
    pub single_tour_kj: f64,
    pub sorties: Vec<SortieReport>,
}

/// One sortie: origin -> `sequence` -> origin on a fresh battery.
#[derive(Debug, Serialize)]
pub struct SortieReport {
    /// Waypoint names in flying order, origin excluded.
    pub sequence: Vec<String>,
    pub takeoff_kj: f64,
    pub legs_kj: f64,
    pub hover_kj: f64,
    pub landing_kj: f64,
    pub total_kj: f64,
    /// Share of the battery's budget this sortie uses.
    pub budget_pct: f64,
    pub legs: Vec<LegReport>,
}

/// Splits `mission`, planned by [`super::plan::plan_mission`], into sorties. The energy order seeds the heuristic when the mission is too
/// large to split exactly.
pub fn split_mission(mission: &Mission, planned: &Planned) -> anyhow::Result<SortiesReport> {
    let hover_w = hover_power_w(&planned.vehicle).context("pricing the hover")?;
    let hover_j: Vec<f64> = mission
        .waypoints
        .iter()
        .map(|w| hover_w * w.hover_s)
        .collect();
    let battery = &planned.battery;
    let budget_j = battery.budget_kj * 1000.0;
    let problem = SortieProblem {
        energy: &planned.energy,
        hover_j: &hover_j,
        fixed_j: (battery.takeoff_kj + battery.landing_kj) * 1000.0,
        budget_j,
    };
    let options = SortieOptions {
        giant_tour: planned.orders.first().map(|o| o.nodes.clone()),
        ..SortieOptions::default()
    };
    let plan = split(&problem, &options).map_err(|err| match err {
        SortieError::Unreachable { node, alone_j, .. } => {
            let (name, hover_s) = node
                .checked_sub(1)
                .and_then(|k| mission.waypoints.get(k))
                .map_or((format!("node {node}"), 0.0), |w| (w.name.clone(), w.hover_s));
            anyhow::anyhow!(
            "waypoint {name} cannot be flown even on a battery of its own: take-off, flying out, \
             hovering {hover_s:.0} s, flying back and landing need {:.1} kJ but one battery has {:.1} kJ \
             usable after its {}% reserve",
            alone_j / 1000.0,
            battery.budget_kj,
            battery.reserve_pct
        )
        }
        other => anyhow::Error::new(other)
            .context(format!("splitting mission {} into sorties", mission.name)),
    })?;
    let geometry = Geometry::from_mission(mission);
    let names: Vec<String> = std::iter::once("origin".to_string())
        .chain(mission.waypoints.iter().map(|w| w.name.clone()))
        .collect();
    let sorties = plan
        .sorties
        .into_iter()
        .map(|s| {
            let order = report(
                &geometry,
                &names,
                Some(&planned.energy),
                Objective::Energy,
                Direction::Forward,
                s.order,
            );
            SortieReport {
                sequence: order.sequence,
                takeoff_kj: battery.takeoff_kj,
                legs_kj: s.legs_j / 1000.0,
                hover_kj: s.hover_j / 1000.0,
                landing_kj: battery.landing_kj,
                total_kj: s.total_j / 1000.0,
                budget_pct: 100.0 * s.total_j / budget_j,
                legs: order.legs,
            }
        })
        .collect::<Vec<_>>();
    Ok(SortiesReport {
        batteries: sorties.len(),
        total_kj: plan.total_j / 1000.0,
        optimal: plan.optimal,
        method: plan.method,
        budget_kj: battery.budget_kj,
        single_tour_kj: battery.total_kj,
        sorties,
    })
}

/// The sorties as text, after the plan's table.
pub fn print(report: &SortiesReport) {
    println!(
        "sorties: {} {}, {:.1} kJ in total ({}) against {:.1} kJ for the mission as one tour; a battery has {:.1} kJ usable",
        report.batteries,
        if report.batteries == 1 { "battery" } else { "batteries" },
        report.total_kj,
        match report.method {
            Method::Exact => "proven optimal: exact split",
            Method::Heuristic => "heuristic split, not proven optimal",
        },
        report.single_tour_kj,
        report.budget_kj,
    );
    for (k, s) in report.sorties.iter().enumerate() {
        println!(
            "  sortie {}: take-off {:.1} + legs {:.1} + hovering {:.1} + landing {:.1} = {:.1} kJ ({:.0}% of the budget)",
            k + 1,
            s.takeoff_kj,
            s.legs_kj,
            s.hover_kj,
            s.landing_kj,
            s.total_kj,
            s.budget_pct
        );
        println!("    origin -> {} -> origin", s.sequence.join(" -> "));
    }
}

/// Warns on stderr that the mission does not fit one battery and how to split it.
pub fn warn_if_over_budget(mission_path: &Path, battery: &Battery) {
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
