//! Tests of the planning pipeline on the shipped vehicle and missions.

use std::path::{Path, PathBuf};

use super::json::{kj, plan_document, upload_document};
use super::*;
use crate::physics::Vehicle;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn model() -> VehicleModel {
    VehicleModel::load(&repo("models/s1000"), None).unwrap()
}

fn mission(name: &str) -> Mission {
    crate::mission::load(&repo(&format!("missions/{name}"))).unwrap()
}

fn options(orders: Orders, sorties: bool) -> PlanOptions {
    PlanOptions {
        orders,
        sorties,
        ..PlanOptions::default()
    }
}

#[test]
fn every_leg_of_every_order_is_priced_from_the_table_in_two_parts_that_add_up_to_the_matrix() {
    let m = model();
    let plan = plan_mission(
        &mission("paper-sample-8wp.toml"),
        &m,
        &PlanOptions::default(),
    )
    .unwrap();
    assert_eq!(plan.orders.len(), 7);
    for order in &plan.orders {
        assert_eq!(order.legs.len(), order.nodes.len() + 1);
        assert_eq!(order.legs[0].from, 0);
        assert_eq!(order.legs[order.legs.len() - 1].to, 0);
        for (k, leg) in order.legs.iter().enumerate() {
            // Each leg after the one before (the px4 profile: ahead or behind PX4's
            // trajectory); the first one behind, as the matrix prices every leg.
            let table = m
                .leg_from(leg.horizontal_m, leg.vertical_m, leg.start)
                .unwrap();
            assert_eq!(leg.predicted, table);
            assert!(leg.predicted.energy_j > 0.0 && leg.predicted.settle_energy_j >= 0.0);
            if leg.start == crate::physics::Start::Behind {
                assert_eq!(leg.energy_j(), plan.energy.cost(leg.from, leg.to));
            }
            if k == 0 {
                assert_eq!(leg.start, crate::physics::Start::Behind);
            }
        }
        let pair_priced: f64 = order.legs.iter().map(Leg::energy_j).sum();
        assert_eq!(order.energy_j, pair_priced);
        let duration: f64 = order.legs.iter().map(|l| l.duration_s()).sum();
        assert_eq!(order.duration_s, duration);
    }
    // The energy order is flown, and no order costs less.
    assert_eq!(plan.flown().objective, Some(Objective::Energy));
    assert!(plan
        .orders
        .iter()
        .all(|o| o.energy_j >= plan.flown().energy_j));
}

#[test]
fn the_battery_check_adds_take_off_legs_hovering_and_landing_of_the_flown_order() {
    let m = model();
    let mission = mission("paper-sample-8wp.toml");
    let plan = plan_mission(&mission, &m, &PlanOptions::default()).unwrap();
    let budget = Budget::new(&m.vehicle, m.profile, mission.origin.height_above_home_m).unwrap();
    let hover_s: f64 = mission.waypoints.iter().map(|w| w.hover_s).sum();
    let b = plan.battery;
    assert_eq!(
        b,
        budget.check(plan.flown().energy_j, budget.hover_j(hover_s))
    );
    assert!(b.feasible);
    assert_eq!(
        b.usable_j,
        Vehicle::load(&repo("models/s1000"))
            .unwrap()
            .mission_budget_j()
    );
    let doc = plan_document(&plan).battery;
    let parts = doc.takeoff_kj + doc.legs_kj + doc.hover_kj + doc.landing_kj;
    assert_eq!(doc.total_kj, parts);
    assert!((doc.total_kj - kj(b.total_j)).abs() < 1e-9);
    assert_eq!(
        plan.hover_j(0),
        budget.hover_j(mission.waypoints[0].hover_s)
    );
}

#[test]
fn the_listed_order_is_priced_and_checked_without_solving_anything() {
    let mission = mission("paper-sample-8wp.toml");
    let plan = plan_mission(&mission, &model(), &options(Orders::Listed, false)).unwrap();
    assert_eq!(plan.orders.len(), 1);
    let listed = plan.flown();
    assert_eq!(listed.objective, None);
    assert_eq!(listed.proof, None);
    assert_eq!(
        listed.waypoints(),
        (0..mission.waypoints.len()).collect::<Vec<_>>()
    );
    assert_eq!(plan.battery.legs_j, plan.energy.tour_cost(&listed.nodes));
    assert!(plan.explanation.is_none() && plan.sorties.is_none());
    let flight = plan.flight(None).unwrap();
    assert_eq!(flight.waypoints(), listed.waypoints());
    let up = upload_document(&plan, &flight);
    assert_eq!(up.sequence[0], mission.waypoints[0].name);
    assert_eq!(
        up.predicted_mission_kj,
        plan_document(&plan).battery.total_kj
    );
}

#[test]
fn the_distance_order_alone_flies_its_cheaper_direction_and_the_same_tour_as_the_full_plan() {
    let mission = mission("paper-sample-8wp.toml");
    let m = model();
    let plan = plan_mission(&mission, &m, &options(Orders::Distance, false)).unwrap();
    assert_eq!(plan.orders.len(), 2);
    assert!(plan
        .orders
        .iter()
        .all(|o| o.objective == Some(Objective::Distance)));
    let flown = plan.flown();
    assert!(plan.orders.iter().all(|o| o.energy_j >= flown.energy_j));
    let full = plan_mission(&mission, &m, &PlanOptions::default()).unwrap();
    assert_eq!(
        flown.nodes,
        full.cheapest(Objective::Distance).unwrap().nodes
    );
    // The saving the full plan explains is the energy the distance order costs more.
    let saving = full.explanation.as_ref().unwrap().saving.as_ref().unwrap();
    assert!((saving.saving_j - (flown.energy_j - full.flown().energy_j)).abs() < 1e-6);
}

#[test]
fn a_small_battery_splits_the_sample_into_sorties_each_uploadable_by_number() {
    let mut m = model();
    // 25 Wh usable, 20 % reserve: 72 kJ per battery against the sample's 107 kJ.
    m.vehicle.planning.usable_energy_wh = 25.0;
    let mission = mission("paper-sample-8wp.toml");
    let plan = plan_mission(&mission, &m, &options(Orders::Energy, true)).unwrap();
    assert!(!plan.battery.feasible);
    let sorties = plan.sorties.as_ref().unwrap();
    assert!(sorties.sorties.len() >= 2);
    let mut flown: Vec<usize> = Vec::new();
    for (k, s) in sorties.sorties.iter().enumerate() {
        assert!(s.battery.feasible && s.battery.total_j <= 72_000.0);
        let legs_j: f64 = s.legs.iter().map(Leg::settled_energy_j).sum();
        assert_eq!(s.battery.legs_j, legs_j);
        let flight = plan.flight(Some(k + 1)).unwrap();
        assert_eq!(flight.nodes, &s.nodes[..]);
        assert!(flight.require_feasible().is_ok());
        flown.extend(flight.waypoints());
    }
    flown.sort_unstable();
    assert_eq!(flown, (0..8).collect::<Vec<_>>());
    let total: f64 = sorties.sorties.iter().map(|s| s.battery.total_j).sum();
    assert!((total - sorties.total_j).abs() < 1e-6);
    let beyond = sorties.sorties.len() + 1;
    assert_eq!(
        plan.flight(Some(beyond)),
        Err(PlannerError::NoSuchSortie {
            sortie: beyond,
            count: beyond - 1
        })
    );
    assert!(matches!(
        plan.flight(None).unwrap().require_feasible(),
        Err(PlannerError::OverBudget { .. })
    ));
}

#[test]
fn a_waypoint_no_battery_can_reach_is_an_error_naming_it() {
    let mut m = model();
    m.vehicle.planning.usable_energy_wh = 5.0;
    let err = plan_mission(
        &mission("paper-sample-8wp.toml"),
        &m,
        &options(Orders::Energy, true),
    )
    .unwrap_err();
    assert!(
        matches!(&err, PlannerError::Unreachable { waypoint, usable_j, .. }
            if waypoint == "A" && *usable_j == 14_400.0),
        "{err:?}"
    );
    assert!(err
        .to_string()
        .contains("14.4 kJ usable after its 20% reserve"));
}

#[test]
fn sorties_without_the_energy_order_are_refused() {
    let err = plan_mission(
        &mission("paper-sample-3wp.toml"),
        &model(),
        &options(Orders::Listed, true),
    )
    .unwrap_err();
    assert!(
        matches!(err, PlannerError::SortiesNeedTheEnergyOrder { .. }),
        "{err}"
    );
}

#[test]
fn a_leg_beyond_the_table_is_composed_with_px4_simulated_with_ptf_and_beyond_reach_refused_by_name()
{
    let mut far = mission("paper-sample-3wp.toml");
    far.waypoints[1].position.x_east_m = 400.0;
    let name = far.waypoints[1].name.clone();
    // px4 cruises: the leg is a table leg plus steady cruise.
    let plan = plan_mission(&far, &model(), &PlanOptions::default()).unwrap();
    assert!(plan
        .orders
        .iter()
        .flat_map(|o| &o.legs)
        .any(|l| l.horizontal_m > 150.0));
    // ptf's quintic never cruises: its long legs are simulated directly.
    let ptf =
        VehicleModel::load(&repo("models/s1000"), Some(crate::physics::Profile::Ptf)).unwrap();
    let plan = plan_mission(&far, &ptf, &PlanOptions::default()).unwrap();
    assert!(plan
        .orders
        .iter()
        .flat_map(|o| &o.legs)
        .any(|l| l.horizontal_m > 150.0));
    // Beyond the vehicle's reach (planning.max_leg_m): refused, naming the leg.
    far.waypoints[1].position.x_east_m = 1200.0;
    let err = plan_mission(&far, &model(), &PlanOptions::default()).unwrap_err();
    let text = err.to_string();
    assert!(text.contains(&name) && text.contains("max_leg_m"), "{text}");
}

#[test]
fn a_plan_whose_cancel_token_is_raised_answers_cancelled_whatever_its_phase() {
    let m = model();
    let sample = mission("paper-sample-8wp.toml");
    let options = options(Orders::All, true);
    let before = crate::tour::cancel::Cancel::new();
    before.cancel();
    let out = crate::tour::cancel::within(&before, || plan_mission(&sample, &m, &options));
    assert_eq!(
        out,
        Err(PlannerError::Cancelled {
            mission: "paper-sample-8wp".into()
        })
    );
    // Raised by the solver's first event: after pricing, while the orders are solved.
    let during = crate::tour::cancel::Cancel::new();
    let raise = during.clone();
    let out = crate::tour::cancel::within(&during, || {
        crate::tour::progress::listen(
            move |_| raise.cancel(),
            || plan_mission(&sample, &m, &options),
        )
    });
    assert!(
        matches!(out, Err(PlannerError::Cancelled { .. })),
        "{out:?}"
    );
    // Without a token the same plan goes through.
    assert!(plan_mission(&sample, &m, &options).is_ok());
}
