//! `emplan fly`, `replay` and `report` through the binary on the built-in mock autopilot: every
//! leg measured against its prediction (the mock flies the model's own trajectories, so they
//! agree), also with a fifth of the datagrams lost; the replayed log gives the live report; a
//! recorder killed mid-flight leaves a log that replays up to about its last second.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::{emplan, json};

/// The mock's speed-up in these tests: 50x measures the legs as well as the default 20x (which
/// `.ci/run`'s mock flight keeps) in less than half the wall time.
const SPEEDUP: &str = "50";

fn fly(log_dir: &Path, extra: &[&str]) -> Value {
    let log = log_dir.to_str().expect("a UTF-8 temp path");
    let mut args = vec![
        "fly",
        "missions/paper-sample-8wp.toml",
        "--log-dir",
        log,
        "--json",
        "--speedup",
        SPEEDUP,
    ];
    args.extend_from_slice(extra);
    json(&args)
}

/// Every leg measured, each within `tolerance_pct` of its prediction; the legs of the plan in
/// order.
fn assert_legs_within(report: &Value, tolerance_pct: f64) {
    let legs = report["legs"].as_array().expect("legs");
    let names: Vec<(String, String)> = legs
        .iter()
        .map(|l| {
            (
                l["from"].as_str().unwrap_or("").to_string(),
                l["to"].as_str().unwrap_or("").to_string(),
            )
        })
        .collect();
    assert_eq!(legs.len(), 9, "{names:?}");
    assert_eq!(names[0].0, "origin");
    assert_eq!(names[8].1, "origin");
    for pair in names.windows(2) {
        assert_eq!(pair[0].1, pair[1].0, "legs chain: {names:?}");
    }
    for leg in legs {
        let measured = leg["measured_kj"].as_f64();
        let error = leg["error_pct"].as_f64();
        assert!(
            measured.is_some() && error.is_some_and(|e| e.abs() <= tolerance_pct),
            "leg {} -> {}: measured {measured:?}, error {error:?}% (flags {})",
            leg["from"],
            leg["to"],
            leg["flags"]
        );
    }
    assert_eq!(report["complete"], true);
}

#[test]
fn fly_on_the_built_in_mock_measures_every_leg_within_three_percent_of_its_prediction() {
    let dir = tempfile::tempdir().unwrap();
    let report = fly(dir.path(), &[]);
    assert_eq!(report["ok"], true);
    assert_legs_within(&report, 3.0);
    // The mock is a PX4 at the vehicle file's trajectory parameters: all 21 read, none differ.
    assert_eq!(report["px4_parameters"]["read"], 21);
    assert_eq!(report["px4_parameters"]["differing"], serde_json::json!([]));
    // The flight's directory holds its log, samples, plan and report.
    let flight = PathBuf::from(report["log_dir"].as_str().unwrap());
    assert!(flight.starts_with(dir.path()));
    for file in ["flight.tlog", "samples.csv", "plan.json", "report.json"] {
        assert!(
            flight.join(file).is_file(),
            "{file} in {}",
            flight.display()
        );
    }
}

#[test]
fn a_vertical_return_leg_onto_the_origin_is_measured_as_the_vertical_leg_it_was_priced() {
    // Sample 2 flown as listed ends C (above the origin) -> origin: a vertical descent, which
    // the mock once flew as a leg 8 cm long (slowed as a horizontal leg, +16%).
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().to_str().expect("a UTF-8 temp path");
    let report = json(&[
        "fly",
        "missions/paper-sample-3wp.toml",
        "--order",
        "listed",
        "--log-dir",
        log,
        "--json",
        "--speedup",
        SPEEDUP,
    ]);
    let legs = report["legs"].as_array().expect("legs");
    assert_eq!(legs.len(), 4);
    assert_eq!(legs[3]["from"], "C");
    assert_eq!(legs[3]["to"], "origin");
    for leg in legs {
        let error = leg["error_pct"].as_f64();
        assert!(
            error.is_some_and(|e| e.abs() <= 3.0),
            "leg {} -> {}: error {error:?}%",
            leg["from"],
            leg["to"]
        );
    }
}

#[test]
fn with_a_fifth_of_the_datagrams_lost_each_way_every_leg_is_still_within_three_percent() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().to_str().expect("a UTF-8 temp path");
    // At 10x, not the other tests' 50x: the mock disarms 10 s of vehicle time after arming
    // without a take-off (PX4's COM_DISARM_PRFLT), and emplan resends a lost start every
    // 250 ms of wall time; at 50x that window is 200 ms, shorter than one resend, so a single
    // lost start command disarmed the vehicle. At 10x it holds four resends, as a real
    // vehicle's 10 s hold forty.
    let report = json(&[
        "fly",
        "missions/paper-sample-8wp.toml",
        "--log-dir",
        log,
        "--json",
        "--speedup",
        "10",
        "--mock-loss",
        "0.2",
        "--mock-seed",
        "7",
    ]);
    assert_legs_within(&report, 3.0);
}

#[test]
fn a_px4_holding_other_trajectory_parameters_is_warned_of_by_name_and_measured_against_its_own() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().to_str().unwrap();
    let (ok, stdout, stderr) = crate::emplan(&[
        "fly",
        "missions/paper-sample-8wp.toml",
        "--log-dir",
        log,
        "--json",
        "--speedup",
        SPEEDUP,
        "--mock-param",
        "MPC_XY_CRUISE=8",
        "--mock-param",
        "MPC_ACC_HOR=2",
    ]);
    assert!(ok, "{stderr}");
    let report: Value = serde_json::from_str(&stdout).unwrap();
    let differing: Vec<(&str, f64, f64)> = report["px4_parameters"]["differing"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| {
            (
                d["name"].as_str().unwrap(),
                d["vehicle_file"].as_f64().unwrap(),
                d["autopilot"].as_f64().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        differing,
        [("MPC_XY_CRUISE", 5.0, 8.0), ("MPC_ACC_HOR", 3.0, 2.0)]
    );
    for name in ["MPC_XY_CRUISE", "MPC_ACC_HOR"] {
        assert!(
            stderr.contains(&format!("warning: PX4 parameter {name} is")),
            "{stderr}"
        );
    }
    // The legs are priced as this PX4 flies them, so they still agree; the table's prices of
    // the vehicle file's parameters are not what was measured against.
    assert_legs_within(&report, 3.0);
    let table = fly(&dir.path().join("table"), &[]);
    let predicted = |r: &Value| -> Vec<f64> {
        r["legs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l["predicted_kj"].as_f64().unwrap())
            .collect()
    };
    let moved = predicted(&report)
        .iter()
        .zip(predicted(&table))
        .filter(|(a, b)| (*a - b).abs() > 0.02 * b)
        .count();
    assert!(
        moved >= 5,
        "{:?} {:?}",
        predicted(&report),
        predicted(&table)
    );
}

#[test]
fn replaying_the_log_gives_the_report_the_live_flight_gave() {
    let dir = tempfile::tempdir().unwrap();
    let live = fly(dir.path(), &[]);
    let flight = PathBuf::from(live["log_dir"].as_str().unwrap());
    let tlog = flight.join("flight.tlog");
    let replayed = json(&["replay", tlog.to_str().unwrap(), "--json"]);
    for key in ["legs", "settles", "hovers", "takeoff", "landing", "total"] {
        assert!(
            same_report(&live[key], &replayed[key]),
            "{key}: {} {}",
            live[key],
            replayed[key]
        );
    }
    // And from the directory, as `report` reads it.
    let reported = json(&["report", flight.to_str().unwrap(), "--json"]);
    assert!(same_report(&live["legs"], &reported["legs"]));
}

/// Equal JSON, numbers equal to float round-off (the live recorder and replay sum the same
/// samples in another order: a last-bit difference in joules, which an error of a few
/// thousandths of a percent shows at 1e-14).
fn same_report(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (
                x.as_f64().unwrap_or(f64::NAN),
                y.as_f64().unwrap_or(f64::NAN),
            );
            x == y || (x - y).abs() <= 1e-9 + 1e-12 * x.abs().max(y.abs())
        }
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(p, q)| same_report(p, q))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len()
                && x.iter()
                    .all(|(k, v)| y.get(k).is_some_and(|w| same_report(v, w)))
        }
        _ => a == b,
    }
}

#[test]
fn report_combines_repeated_flights_of_the_same_legs_and_draws_them() {
    let dir = tempfile::tempdir().unwrap();
    fly(dir.path(), &["--mock-seed", "1"]);
    fly(dir.path(), &["--mock-seed", "2"]);
    let plot = dir.path().join("flights.svg");
    let combined = json(&[
        "report",
        dir.path().to_str().unwrap(),
        "--json",
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert_eq!(combined["flights"].as_array().map(Vec::len), Some(2));
    for leg in combined["legs"].as_array().unwrap() {
        let stats = &leg["measured_stats_kj"];
        assert_eq!(stats["n"], 2, "{leg}");
        assert!(stats["min"].as_f64() <= stats["max"].as_f64());
    }
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.contains("<svg") && svg.contains("battery power"));
}

#[test]
fn a_recorder_killed_mid_flight_leaves_a_log_that_replays_the_legs_flown_so_far() {
    let dir = tempfile::tempdir().unwrap();
    let log_dir = dir.path().to_str().unwrap().to_string();
    // Slow enough (4x) that the kill lands mid-flight.
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_emplan"))
        .args([
            "fly",
            "missions/paper-sample-8wp.toml",
            "--log-dir",
            &log_dir,
            "--speedup",
            "4",
            "--json",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("emplan runs");
    // Wait for the flight's directory, then until it has flown some legs (a CSV row every
    // 0.1 s of flight: take-off about 14 s, a leg and hover about 12 s).
    let started = Instant::now();
    let samples = loop {
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "no flight began"
        );
        let found = std::fs::read_dir(dir.path())
            .unwrap()
            .filter_map(|e| e.ok())
            .map(|e| e.path().join("samples.csv"))
            .find(|p| p.is_file());
        if let Some(p) = found {
            break p;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    loop {
        assert!(
            started.elapsed() < Duration::from_secs(90),
            "the flight did not go on"
        );
        let rows = std::fs::read_to_string(&samples).map_or(0, |t| t.lines().count());
        if rows > 700 {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    child.kill().expect("SIGKILL");
    let killed_at = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_micros() as u64;
    child.wait().unwrap();
    let flight = samples.parent().unwrap();
    assert!(
        !flight.join("report.json").exists(),
        "killed before the end"
    );
    // The CSV reads whole, and its last row is at most about a second old.
    let text = std::fs::read_to_string(&samples).unwrap();
    let last = text
        .lines()
        .rev()
        .find_map(|l| {
            let cols: Vec<&str> = l.split(',').collect();
            cols.get(1)?.parse::<u64>().ok()
        })
        .expect("a complete row");
    let lost_s = killed_at.saturating_sub(last) as f64 / 1e6;
    assert!(lost_s < 1.5, "the last {lost_s:.2} s were lost");
    // Replay reports the legs flown so far, the one in progress marked incomplete.
    let tlog = flight.join("flight.tlog");
    let replayed = json(&["replay", tlog.to_str().unwrap(), "--json"]);
    let legs = replayed["legs"].as_array().unwrap();
    assert!(legs.len() >= 2, "{replayed}");
    let measured = legs
        .iter()
        .filter(|l| l["measured_kj"].as_f64().is_some())
        .count();
    assert!(measured >= 2);
    assert_eq!(replayed["complete"], false);
    let (ok, _, stderr) = emplan(&["replay", tlog.to_str().unwrap()]);
    assert!(ok, "{stderr}");
}

/// Every message of a flight directory's tlog, in order: (sent by emplan, message).
fn tlog_messages(flight: &Path) -> Vec<(bool, emplan::link::mav::MavMessage)> {
    let tlog = emplan::flightlog::tlog::read_tlog(&flight.join("flight.tlog")).unwrap();
    tlog.records
        .iter()
        .filter_map(|r| emplan::link::telemetry::parse_frame(&r.frame).ok())
        .map(|(header, m)| (header.system_id == 255, m))
        .collect()
}

#[test]
fn on_px4_fly_arms_then_starts_follows_repeated_reached_messages_and_ends_landed_and_disarmed() {
    use emplan::link::mav::{MavCmd, MavLandedState, MavMessage, MavModeFlag};
    let dir = tempfile::tempdir().unwrap();
    let report = fly(dir.path(), &[]);
    let flight = PathBuf::from(report["log_dir"].as_str().unwrap());
    let messages = tlog_messages(&flight);
    // Started the PX4 way: arm, then MAV_CMD_MISSION_START, and no mode change.
    let commands: Vec<(MavCmd, f32)> = messages
        .iter()
        .filter_map(|(sent, m)| match m {
            MavMessage::COMMAND_LONG(c) if *sent => Some((c.command, c.param1)),
            _ => None,
        })
        .filter(|(c, _)| *c != MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL)
        .collect();
    let arm = commands
        .iter()
        .position(|&c| c == (MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0))
        .expect("armed");
    let start = commands
        .iter()
        .position(|&(c, _)| c == MavCmd::MAV_CMD_MISSION_START)
        .expect("started");
    assert!(arm < start, "{commands:?}");
    assert!(!commands
        .iter()
        .any(|&(c, _)| c == MavCmd::MAV_CMD_DO_SET_MODE));
    // PX4 repeats MISSION_ITEM_REACHED about once a second (PX4 SITL: 11 times per item when
    // the mission ends in NAV_LAND; the last waypoint before an RTL is never reported, see
    // sim::vehicle's and flightlog::segment's tests)...
    let mut reached = [0usize; 11];
    for (_, m) in &messages {
        if let MavMessage::MISSION_ITEM_REACHED(r) = m {
            reached[usize::from(r.seq)] += 1;
        }
    }
    assert!(reached[1..=9].iter().all(|&n| n >= 2), "{reached:?}");
    // ...yet every point has one settle and one hover, and the legs are measured.
    assert_legs_within(&report, 3.0);
    for key in ["settles", "hovers"] {
        let parts = report[key].as_array().unwrap();
        assert_eq!(parts.len(), 9, "{key}");
        assert_eq!(parts[8]["to"], "origin", "{key}");
        assert!(parts.iter().all(|p| p["measured_kj"].is_number()), "{key}");
    }
    // Landed states from EXTENDED_SYS_STATE: on the ground, taking off, in the air, landing, on
    // the ground; the flight ended with the vehicle landed and disarmed, and the landing part
    // runs to the disarm.
    let mut states: Vec<MavLandedState> = Vec::new();
    let mut disarmed_after_landing = false;
    for (sent, m) in &messages {
        match m {
            MavMessage::EXTENDED_SYS_STATE(e) if states.last() != Some(&e.landed_state) => {
                states.push(e.landed_state)
            }
            MavMessage::HEARTBEAT(h) if !*sent && states.len() >= 5 => {
                disarmed_after_landing |= !h
                    .base_mode
                    .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)
            }
            _ => {}
        }
    }
    use MavLandedState::*;
    assert_eq!(
        states,
        [
            MAV_LANDED_STATE_ON_GROUND,
            MAV_LANDED_STATE_TAKEOFF,
            MAV_LANDED_STATE_IN_AIR,
            MAV_LANDED_STATE_LANDING,
            MAV_LANDED_STATE_ON_GROUND
        ]
    );
    assert!(disarmed_after_landing);
    assert_eq!(report["complete"], true);
    assert!(report["landing"]["measured_kj"].is_number());
}

#[test]
fn the_first_fly_says_the_order_flown_and_its_saving_the_battery_left_and_the_next_step_and_explains_its_rows(
) {
    let work = tempfile::tempdir().expect("temp dir");
    let log = work.path().to_str().expect("a UTF-8 temp path");
    // README's first command, at the tests' speed-up.
    let (ok, out, err) = emplan(&[
        "fly",
        "missions/paper-sample-8wp.toml",
        "--log-dir",
        log,
        "--speedup",
        SPEEDUP,
    ]);
    assert!(ok, "{err}");
    let line = |prefix: &str| -> &str {
        (out.lines())
            .find_map(|l| l.strip_prefix(prefix))
            .unwrap_or_else(|| panic!("no line `{prefix}`: {out}"))
    };
    // The order flown and what the plan predicts it saves against the distance order.
    let plan = json(&["plan", "missions/paper-sample-8wp.toml", "--json"]);
    let orders = plan["orders"].as_array().expect("orders");
    let energy_of = |objective: &str| {
        (orders.iter())
            .filter(|o| o["objective"] == objective)
            .map(|o| o["energy_kj"].as_f64().unwrap())
            .fold(f64::INFINITY, f64::min)
    };
    let saving_kj = energy_of("distance") - energy_of("energy");
    let order = line("order flown: ");
    assert!(order.starts_with("the energy order"), "{order}");
    assert!(
        order.contains(&format!("save {saving_kj:.2} kJ")) && order.contains("distance order"),
        "{order}"
    );
    // The battery left at landing against the reserve.
    let battery = line("battery: ");
    assert!(
        battery.contains("left at landing against the") && battery.contains("reserve"),
        "{battery}"
    );
    // The next step names the flight just flown.
    let dir = line("log: ");
    assert_eq!(line("next: ").split_whitespace().nth(2), Some(dir), "{out}");
    // "settle + hover (N)" is explained, and a flags column only comes with its legend.
    let points = line("settle + hover (").split(')').next().unwrap();
    assert!(
        out.lines()
            .any(|l| l.starts_with(&format!("settle + hover ({points}): "))),
        "{out}"
    );
    let header = out
        .lines()
        .find(|l| l.starts_with("part "))
        .expect("header");
    assert!(
        !header.contains("flags") || out.lines().any(|l| l.starts_with("flags: ")),
        "{out}"
    );
    // No enum's debug name in what the user reads.
    assert!(err.contains("on PX4 autopilot"), "{err}");
    for text in [&out, &err] {
        for debug in ["Px4", "Forward", "Reverse"] {
            assert!(!text.contains(debug), "{debug}: {text}");
        }
    }
    let (ok, planned, err) = emplan(&["plan", "missions/long-survey.toml"]);
    assert!(ok, "{err}");
    assert!(
        !planned.contains("Forward") && !planned.contains("Reverse"),
        "{planned}"
    );
}
