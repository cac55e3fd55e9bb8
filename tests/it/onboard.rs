//! The flight controller's own logs through the binary: `report` and `replay` of a real
//! ArduCopter SITL `.bin` (the mission from its CMD records) and a real PX4 SITL `.ulg` (the
//! mission planned as `fly` plans it, or refused without one), `report FLIGHT_DIR --onboard` with
//! the same ArduCopter flight's `.tlog` (every leg within 3%), a log torn mid-flight measured up
//! to the tear, and files of neither format refused naming them.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::{emplan, json};

const DIR: &str = "tests/fixtures/onboard";

fn fixture(name: &str) -> String {
    format!("{DIR}/{name}")
}

/// `name` copied alone into a temporary directory (no plan.json beside it).
fn alone(name: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join(name);
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join(fixture(name)),
        &path,
    )
    .expect("copied");
    (dir, path)
}

fn legs(report: &Value) -> &Vec<Value> {
    report["legs"].as_array().expect("legs")
}

fn every_leg_measured(report: &Value, n: usize) {
    assert_eq!(legs(report).len(), n, "{report}");
    for leg in legs(report) {
        assert!(
            leg["measured_kj"].as_f64().is_some_and(|e| e > 0.0),
            "{leg}"
        );
    }
}

#[test]
fn a_dataflash_log_is_measured_against_the_mission_it_holds() {
    let report = json(&["report", &fixture("arducopter-8wp.bin"), "--json"]);
    every_leg_measured(&report, 9);
    assert_eq!(report["source"]["format"], "dataflash");
    let hz = report["source"]["battery_hz"].as_f64().expect("a rate");
    assert!((9.5..=10.5).contains(&hz), "{hz}");
    assert_eq!(report["complete"], true);
    assert!(report["source"].get("tear").is_none(), "{report}");
    // Named after the mission file's waypoints when one is given.
    let named = json(&[
        "replay",
        &fixture("arducopter-8wp.bin"),
        "--mission",
        "missions/paper-sample-8wp.toml",
        "--json",
    ]);
    let names: Vec<&str> = legs(&named)
        .iter()
        .filter_map(|l| l["to"].as_str())
        .collect();
    assert_eq!(names, ["F", "H", "E", "G", "B", "D", "A", "C", "origin"]);
    let (ok, stdout, _) = emplan(&["report", &fixture("arducopter-8wp.bin")]);
    assert!(ok);
    assert!(
        stdout.contains("measured from its dataflash (battery 10.0 Hz)"),
        "{stdout}"
    );
}

#[test]
fn a_ulog_is_measured_against_a_mission_planned_as_fly_plans_it_or_refused_without_one() {
    let (_dir, ulg) = alone("px4-sih-8wp.ulg");
    let ulg = ulg.to_str().expect("UTF-8");
    let (ok, _, stderr) = emplan(&["report", ulg]);
    assert!(!ok);
    assert!(
        stderr.contains("px4-sih-8wp.ulg: no plan.json beside it and no mission in the log"),
        "{stderr}"
    );
    let report = json(&[
        "report",
        ulg,
        "--mission",
        "missions/paper-sample-8wp.toml",
        "--json",
    ]);
    every_leg_measured(&report, 9);
    assert_eq!(report["source"]["format"], "ulog");
    let hz = report["source"]["battery_hz"].as_f64().expect("a rate");
    assert!((4.5..=5.5).contains(&hz), "{hz}");
    // The same against the plan the flight was flown with.
    let planned = json(&[
        "report",
        ulg,
        "--plan",
        &fixture("px4-sih-8wp.plan.json"),
        "--json",
    ]);
    for (a, b) in legs(&report).iter().zip(legs(&planned)) {
        assert_eq!(a["to"], b["to"]);
        assert_eq!(a["measured_kj"], b["measured_kj"]);
    }
}

#[test]
fn one_flight_measured_from_its_tlog_and_its_dataflash_log_agrees_leg_by_leg() {
    let doc = json(&[
        "report",
        &fixture("arducopter-8wp-flight"),
        "--onboard",
        &fixture("arducopter-8wp.bin"),
        "--json",
    ]);
    assert_eq!(doc["tlog"]["source"]["format"], "tlog");
    assert_eq!(doc["onboard"]["source"]["format"], "dataflash");
    let legs = doc["legs"].as_array().expect("legs");
    assert_eq!(legs.len(), 9);
    for leg in legs {
        let d = leg["difference_pct"].as_f64().expect("both measured");
        assert!(d.abs() <= 3.0, "{leg}");
    }
    // Only one flight at a time.
    let (ok, _, stderr) = emplan(&[
        "report",
        &fixture("arducopter-8wp-flight"),
        &fixture("arducopter-8wp-flight"),
        "--onboard",
        &fixture("arducopter-8wp.bin"),
    ]);
    assert!(!ok);
    assert!(stderr.contains("--onboard compares one flight"), "{stderr}");
}

#[test]
fn a_log_torn_mid_flight_is_measured_up_to_the_tear_and_says_where() {
    let dir = tempfile::tempdir().expect("temp dir");
    let bytes = std::fs::read(fixture("arducopter-8wp.bin")).expect("fixture");
    let cut = bytes.len() * 6 / 10 + 7;
    let torn = dir.path().join("torn.bin");
    std::fs::write(&torn, &bytes[..cut]).expect("written");
    let torn = torn.to_str().expect("UTF-8");
    let (ok, stdout, stderr) = emplan(&["report", torn, "--json"]);
    assert!(ok, "{stderr}");
    assert!(
        stderr.contains("torn.bin: the log tore at byte"),
        "{stderr}"
    );
    let report: Value = serde_json::from_str(&stdout).expect("JSON");
    let tear = &report["source"]["tear"];
    let offset = tear["offset"].as_u64().expect("an offset");
    assert!(offset <= cut as u64 && offset > (cut as u64) / 2, "{tear}");
    assert_eq!(report["complete"], false);
    let measured = legs(&report)
        .iter()
        .filter(|l| l["measured_kj"].as_f64().is_some() && l["flags"] == serde_json::json!([]))
        .count();
    assert!((2..9).contains(&measured), "{measured} legs: {report}");
}

#[test]
fn a_file_of_neither_format_is_refused_naming_it() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut rng = emplan::rng::Rng::new(7);
    let noise: Vec<u8> = (0..4096).map(|_| (rng.next_u64() & 0xff) as u8).collect();
    for name in ["noise.bin", "noise.ulg"] {
        let path = dir.path().join(name);
        std::fs::write(&path, &noise).expect("written");
        let path = path.to_str().expect("UTF-8");
        for command in ["report", "replay"] {
            let (ok, _, stderr) = emplan(&[command, path]);
            assert!(!ok);
            assert!(
                stderr.contains(&format!(
                    "{name}: neither a PX4 ULog nor an ArduPilot DataFlash log"
                )),
                "{command}: {stderr}"
            );
        }
    }
}
