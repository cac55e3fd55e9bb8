//! A leg round a fence zone flown and measured as the one leg it is: the planner's leg with a
//! via point (set here, priced as ArduCopter's chain through it, as the planner prices it) goes
//! up as a waypoint without a hold between the leg's two waypoints, the built-in mock flies it
//! through at its default speed-up with the `ardupilot` profile, and the report (live, and
//! `emplan report` replaying the flight directory) measures the leg from its departure to its
//! arrival against its chain price, within the bounds of the fast waypoint tests, saying how
//! many via points it passed.

use std::time::Duration;

use emplan::flightlog::flight_plan::FlightPlan;
use emplan::mission::{Enu, Mission};
use emplan::physics::ardupilot_chain::{is_fast, ChainPoint};
use emplan::physics::power::Model;
use emplan::physics::{Profile, VehicleModel, VehicleSource};
use emplan::planner::{FlightChoice, FlownOrder};

use super::service::{ground_station, root};
use crate::json;

fn mission() -> Mission {
    emplan::mission::load(&root().join("missions/paper-sample-3wp.toml")).expect("mission")
}

/// The leg from `from` (held at) through `via` to `to` (held at) as ArduCopter flies it: the
/// chain's legs through the via points and to the end, as one (to the arrival at the end,
/// then its settle).
fn chain_price(model: &Model, from: Enu, via: &[Enu], to: Enu) -> (f64, f64, f64, f64) {
    let at = |e: &Enu| [e.x_east_m, e.y_north_m, e.z_up_m];
    let points: Vec<ChainPoint> = (via.iter().map(|v| (v, true)))
        .chain(std::iter::once((&to, false)))
        .map(|(e, through)| ChainPoint {
            enu_m: at(e),
            fast: through && is_fast(0.0, true),
        })
        .collect();
    let ops = model.ardupilot_chain(at(&from), &points).expect("a chain");
    let (last, before) = ops.split_last().expect("a leg");
    let energy_j: f64 = before.iter().map(|o| o.total_energy_j()).sum();
    let duration_s: f64 = before.iter().map(|o| o.total_duration_s()).sum();
    (
        energy_j + last.energy_j,
        duration_s + last.duration_s,
        last.settle_energy_j,
        last.settle_duration_s,
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_detoured_leg_is_flown_through_its_via_point_and_measured_as_one_leg() {
    let work = tempfile::tempdir().unwrap();
    let mission = mission();
    let model =
        VehicleModel::open(&VehicleSource::BuiltIn, Some(Profile::Ardupilot)).expect("model");
    let choice = FlightChoice {
        order: FlownOrder::Listed,
        ..Default::default()
    };
    let mut plan = choice
        .plan(&mission, &model, Default::default())
        .expect("plan");
    // The listed order: origin, A (0, 40), B (40, 0), C, origin. The leg A -> B goes round a
    // zone on its straight line through (35, 35), 21 m off it.
    let a = mission.waypoints[0].position;
    let b = mission.waypoints[1].position;
    let via = Enu {
        x_east_m: 35.0,
        y_north_m: 35.0,
        z_up_m: a.z_up_m,
    };
    let straight = plan.orders[plan.flown].legs[1].clone();
    assert_eq!((straight.from, straight.to), (1, 2));
    let (energy_j, duration_s, settle_energy_j, settle_duration_s) =
        chain_price(&Model::new(&model.vehicle), a, &[via], b);
    {
        let leg = &mut plan.orders[plan.flown].legs[1];
        leg.via = vec![via];
        leg.predicted.energy_j = energy_j;
        leg.predicted.duration_s = duration_s;
        leg.predicted.settle_energy_j = settle_energy_j;
        leg.predicted.settle_duration_s = settle_duration_s;
    }
    assert!(duration_s > straight.predicted.duration_s + 3.0);
    let flight = choice.flight(&plan).expect("feasible");

    let mock = emplan::sim::MockAutopilot::spawn(
        "udpin:127.0.0.1:0",
        emplan::sim::MockConfig {
            flight: Some(emplan::sim::FlightConfig {
                profile: Some(plan.profile),
                home: mission.origin.home,
                ..Default::default()
            }),
            // The mock's default speed-up: at 50x, timing noise is ~3% of a leg.
            speedup: 20.0,
            ..Default::default()
        },
    )
    .await
    .expect("mock");
    let (link, target, cfg) = ground_station(&mock).await;
    let recorder = emplan::session::spawn_recorder(
        &link,
        emplan::session::RecorderConfig::new(work.path().join("logs")),
    );
    let load = emplan::session::Load {
        mission: &mission,
        plan: &plan,
        flight: &flight,
        acceptance_radius_m: 2.0,
        vehicle: &model.vehicle,
        guard: emplan::flightlog::watch::Policy::Off,
        resumes: None,
        if_home_unknown: Default::default(),
        live_wind: None,
        pack: None,
        guard_start: None,
        ledger: None,
    };
    let options = emplan::session::FlyOptions {
        arm: true,
        timeout: Duration::from_secs(600),
        ..Default::default()
    };
    let flown = emplan::session::fly(
        &link,
        &target,
        cfg,
        &recorder,
        &load,
        &options,
        |_| {},
        |_| {},
    )
    .await
    .expect("flown and landed");
    recorder.close().await;
    let dir = flown.dir.clone();
    let (report, _) = flown.reported().expect("a report");

    // What it was measured against: the via point between A and B, at the item it went up as.
    let measured_against = FlightPlan::read_json(&dir.join("plan.json")).expect("plan.json");
    let b_point = &measured_against.points[1];
    assert_eq!(b_point.name, "B");
    assert_eq!(b_point.via.len(), 1);
    let v = b_point.via[0];
    assert!(measured_against.points[0].seq < v.seq && v.seq < b_point.seq);
    assert!((v.enu.x_east_m - 35.0).abs() < 1e-9 && (v.enu.y_north_m - 35.0).abs() < 1e-9);
    assert!(measured_against
        .points
        .iter()
        .all(|p| p.name == "B" || p.via.is_empty()));

    // The legs: four, the detoured one as one, priced as the chain through its via point.
    let legs: Vec<(&str, &str, usize)> = (report.legs.iter())
        .map(|l| (l.from.as_str(), l.to.as_str(), l.via_points))
        .collect();
    assert_eq!(
        legs,
        [
            ("origin", "A", 0),
            ("A", "B", 1),
            ("B", "C", 0),
            ("C", "origin", 0)
        ]
    );
    let detoured = &report.legs[1];
    let predicted_j = detoured.predicted_j.expect("priced");
    assert!(
        (predicted_j - energy_j).abs() < 0.01 * energy_j,
        "{predicted_j} J flown against, {energy_j} J the chain"
    );
    assert!(
        report.complete && report.waypoints_left.is_empty(),
        "{report:?}"
    );
    // The mock flew the way round: the leg took as long as the chain, not the straight leg.
    assert!(
        detoured.duration_s > straight.predicted.duration_s + 3.0,
        "{} s flown, {} s straight",
        detoured.duration_s,
        straight.predicted.duration_s
    );
    // Every leg within the fast waypoint tests' 3% of its price.
    for leg in &report.legs {
        let e = leg.error_pct().expect("measured and priced");
        eprintln!(
            "{} -> {} via {}: predicted {:.3} kJ, measured {:.3} kJ, {e:+.2}%, {:.1} s",
            leg.from,
            leg.to,
            leg.via_points,
            leg.predicted_j.unwrap_or(f64::NAN) / 1e3,
            leg.measured_j.unwrap_or(f64::NAN) / 1e3,
            leg.duration_s
        );
        assert!(e.abs() < 3.0, "{} -> {}: {e:+.2}%", leg.from, leg.to);
    }

    // Replayed from its directory, the same leg, said the same way, in JSON and in text.
    let dir = dir.to_str().expect("a path");
    let replayed = json(&["report", dir, "--json"]);
    let legs = replayed["legs"].as_array().expect("legs");
    assert_eq!(legs[1]["via_points"], 1, "{replayed}");
    assert!(legs
        .iter()
        .enumerate()
        .all(|(k, l)| k == 1 || l.get("via_points").is_none()));
    let (ok, text, stderr) = crate::emplan(&["report", dir]);
    assert!(ok, "{stderr}");
    assert!(text.contains("leg 2: A -> B via 1 point "), "{text}");
}
