//! The return as the autopilot flies it and the fence's breaches: the plan's returns from every
//! waypoint of the flown order (where each goes by the autopilot's rally rule, its price against
//! the battery, the exclusion zones its straight line crosses), and a FENCE_STATUS breach in a
//! flight's log flagged by the report with where and when, through the binary.

use std::path::Path;

use emplan::flightlog::synthetic::{
    square_plan, SyntheticConfig, SyntheticFlight, SyntheticMessage,
};
use emplan::flightlog::telemetry::{BreachType, FenceStatus, Reading};
use emplan::mission::fence::{LatLon, RallyPoint, Shape, Zone};
use emplan::mission::{Enu, Mission};
use emplan::physics::{Profile, VehicleModel};
use emplan::planner::{plan_mission, PlanOptions};

use crate::{emplan, json};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn mission() -> Mission {
    emplan::mission::load(&root().join("missions/paper-sample-8wp.toml")).expect("mission")
}

fn latlon(m: &Mission, x_east_m: f64, y_north_m: f64) -> LatLon {
    let g = m.origin.to_geodetic(Enu {
        x_east_m,
        y_north_m,
        z_up_m: 0.0,
    });
    LatLon {
        lat_deg: g.lat_deg,
        lon_deg: g.lon_deg,
    }
}

#[test]
fn the_plan_prices_each_return_to_where_the_autopilot_goes_and_warns_of_one_across_a_zone() {
    let model = VehicleModel::load(&root().join("models/s1000"), Some(Profile::Ardupilot))
        .expect("the s1000");
    let plain = mission();
    let options = PlanOptions::default();
    let without = plan_mission(&plain, &model, &options).expect("planned");
    assert!(without.returns.is_none(), "no fence, no rally: nothing new");
    // A rally point beyond the farthest waypoint, and an exclusion square across the straight
    // line home from it.
    let far = (plain.waypoints.iter())
        .max_by(|a, b| {
            let d = |w: &emplan::mission::Waypoint| w.position.x_east_m.hypot(w.position.y_north_m);
            d(a).total_cmp(&d(b))
        })
        .expect("a waypoint")
        .clone();
    let (x, y) = (far.position.x_east_m, far.position.y_north_m);
    let mut fenced = plain.clone();
    let rally = latlon(&plain, x * 1.1, y * 1.1);
    fenced.rally = vec![RallyPoint {
        lat_deg: rally.lat_deg,
        lon_deg: rally.lon_deg,
        // At ArduCopter's return altitude (RTL_ALT 15 m): the returns differ by their way
        // across alone (a higher rally point costs its longer descent, hovering).
        alt_above_home_m: 15.0,
    }];
    let plan = plan_mission(&fenced, &model, &options).expect("planned");
    let returns = plan.returns.as_ref().expect("returns with a rally point");
    assert!(returns.rule.contains("RALLY_LIMIT_KM 0.3") && returns.rule.contains("defaults"));
    let from_far = (returns.from.iter())
        .find(|r| r.from == far.name)
        .expect("the far waypoint's return");
    assert_eq!(from_far.to, "rally point 1");
    assert!(returns.from.iter().any(|r| r.to == "home"), "{returns:?}");
    assert!(returns.warnings.is_empty(), "{:?}", returns.warnings);
    // Home's return from there costs more than the rally point's.
    let mut home_only = plain.clone();
    home_only.fence.zones.push(Zone {
        inclusion: true,
        shape: Shape::Circle {
            center: latlon(&plain, 0.0, 0.0),
            radius_m: 10_000.0,
        },
    });
    let home_plan = plan_mission(&home_only, &model, &options).expect("planned");
    let home_far = (home_plan
        .returns
        .as_ref()
        .expect("returns with a fence")
        .from
        .iter())
    .find(|r| r.from == far.name)
    .expect("the far waypoint's return")
    .clone();
    assert_eq!(home_far.to, "home");
    assert!(
        from_far.energy_j < home_far.energy_j,
        "{from_far:?} {home_far:?}"
    );
    // A 2 m exclusion square across the line home from the far waypoint, clear of every
    // waypoint.
    let (cx, cy) = (x * 0.45, y * 0.45);
    assert!(plain
        .waypoints
        .iter()
        .all(|w| { (w.position.x_east_m - cx).hypot(w.position.y_north_m - cy) > 3.0 }));
    let mut house = home_only.clone();
    house.fence.zones.push(Zone {
        inclusion: false,
        shape: Shape::Polygon(vec![
            latlon(&plain, cx - 1.0, cy - 1.0),
            latlon(&plain, cx + 1.0, cy - 1.0),
            latlon(&plain, cx + 1.0, cy + 1.0),
            latlon(&plain, cx - 1.0, cy + 1.0),
        ]),
    });
    let warned = plan_mission(&house, &model, &options).expect("planned");
    let r = warned.returns.as_ref().expect("returns");
    let crossing = r.from.iter().find(|f| f.from == far.name).expect("far");
    assert_eq!(crossing.crosses, ["exclusion polygon 2"]);
    assert!(
        r.warnings.iter().any(|w| w
            == &format!(
                "the autopilot's return from {} to home flies straight across exclusion polygon 2",
                far.name
            )),
        "{:?}",
        r.warnings
    );
    let doc = emplan::planner::json::plan_document(&warned);
    let value = serde_json::to_value(&doc).expect("json");
    assert!(value["returns"]["warnings"]
        .as_array()
        .is_some_and(|w| !w.is_empty()));
    assert!(
        serde_json::to_value(emplan::planner::json::plan_document(&without))
            .expect("json")
            .get("returns")
            .is_none()
    );
}

/// A FENCE_STATUS at `t_s` of `flight` (the messages kept in time order).
fn insert_fence(flight: &mut SyntheticFlight, t_s: f64, status: FenceStatus) {
    let first = &flight.messages[0];
    let wall_us = first.wall_us + ((t_s - first.t_s) * 1e6).round() as u64;
    let at = flight.messages.partition_point(|m| m.t_s <= t_s);
    flight.messages.insert(
        at,
        SyntheticMessage {
            t_s,
            wall_us,
            time_boot_ms: None,
            reading: Reading::Fence(status),
        },
    );
}

#[test]
fn a_fence_breach_in_the_log_is_flagged_by_the_report_with_where_and_when() {
    let plan = square_plan();
    let mut flight = SyntheticFlight::fly(&plan, &SyntheticConfig::default());
    let leg = *(flight.parts.iter())
        .find(|p| p.kind == emplan::flightlog::segment::SegmentKind::Leg(1))
        .expect("leg 1");
    let t_breach = (leg.start_s + leg.end_s) / 2.0;
    let quiet = FenceStatus {
        breached: false,
        breach_count: 0,
        breach_type: BreachType::None,
        last_breach_boot_s: None,
    };
    let out = FenceStatus {
        breached: true,
        breach_count: 1,
        breach_type: BreachType::Boundary,
        last_breach_boot_s: Some(t_breach),
    };
    for t in [flight.arm_s + 1.0, leg.start_s] {
        insert_fence(&mut flight, t, quiet);
    }
    insert_fence(&mut flight, t_breach, out);
    insert_fence(&mut flight, t_breach + 1.0, out);
    insert_fence(
        &mut flight,
        t_breach + 2.0,
        FenceStatus {
            breached: false,
            ..out
        },
    );
    let mut tlog = Vec::new();
    for (wall_us, frame) in crate::flightlog::frames(&flight) {
        tlog.extend_from_slice(&wall_us.to_be_bytes());
        tlog.extend_from_slice(&frame);
    }
    let work = tempfile::tempdir().unwrap();
    let dir = work.path().join("flight");
    std::fs::create_dir_all(&dir).unwrap();
    plan.write_json(&dir.join("plan.json")).expect("plan.json");
    std::fs::write(dir.join("flight.tlog"), &tlog).unwrap();
    let dir_s = dir.to_str().unwrap();
    let report = json(&["report", dir_s, "--json"]);
    let breaches = report["breaches"].as_array().expect("breaches");
    assert_eq!(breaches.len(), 1, "{breaches:?}");
    let b = &breaches[0];
    assert_eq!(b["type"], "boundary");
    let since = b["since_takeoff_s"].as_f64().expect("since take-off");
    assert!(
        (since - (t_breach - flight.arm_s)).abs() < 0.6,
        "{since} vs {}",
        t_breach - flight.arm_s
    );
    // Halfway along leg 1 of the square, (60, 0) to (60, 60): east 60, north about 30.
    let (e, n) = (
        b["east_m"].as_f64().unwrap(),
        b["north_m"].as_f64().unwrap(),
    );
    assert!((e - 60.0).abs() < 3.0 && (n - 30.0).abs() < 15.0, "{e} {n}");
    assert!(b["lat_deg"].as_f64().is_some() && b["lon_deg"].as_f64().is_some());
    let (ok, text, stderr) = emplan(&["report", dir_s]);
    assert!(ok, "{stderr}");
    assert!(
        text.lines()
            .any(|l| l.starts_with("FLAG fence breach (boundary) ")
                && l.contains("after take-off at ")),
        "{text}"
    );
    // Without a breach, no key: report.json files keep their shape.
    let clean = SyntheticFlight::fly(&plan, &SyntheticConfig::default());
    let mut tlog = Vec::new();
    for (wall_us, frame) in crate::flightlog::frames(&clean) {
        tlog.extend_from_slice(&wall_us.to_be_bytes());
        tlog.extend_from_slice(&frame);
    }
    let dir = work.path().join("clean");
    std::fs::create_dir_all(&dir).unwrap();
    plan.write_json(&dir.join("plan.json")).expect("plan.json");
    std::fs::write(dir.join("flight.tlog"), &tlog).unwrap();
    let report = json(&["report", dir.to_str().unwrap(), "--json"]);
    assert!(report.get("breaches").is_none(), "{report}");
}
