//! The profile a flight was flown with, through the binary: `fly` keeps it in plan.json
//! (`priced_by`, with the vehicle); `calibrate --from-logs` fits with it, builds that
//! profile's table only and makes it the written vehicle's default, and refuses flights flown with two profiles (naming both) unless
//! `--profile` is given; `report --vehicle` re-prices with it, so a calibrated directory holding
//! only that table works; an onboard log (DataFlash, ULog) is priced with its autopilot's
//! profile, and a plan.json written before the profile was kept with its autopilot's, told by
//! the mission's layout; every report, text and JSON, says what priced it.
//!
//! The mock flights use the hvb profile (not the shipped vehicle's px4): its table builds in
//! seconds, and a fit or a report that fell back on the vehicle's profile shows.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::{emplan, json};

const SHIPPED_NAME: &str = "DJI S1000+ (Pixhawk 2.1, PX4)";
const ONBOARD: &str = "tests/fixtures/onboard";

/// Flies `mission` on the built-in mock with `profile` (and `extra`) into `logs`; returns the
/// flight directory.
fn fly(mission: &str, profile: &str, logs: &Path, extra: &[&str]) -> PathBuf {
    let mut args = vec![
        "fly",
        mission,
        "--profile",
        profile,
        "--log-dir",
        logs.to_str().unwrap(),
        "--speedup",
        "50",
        "--json",
    ];
    args.extend_from_slice(extra);
    let flown = json(&args);
    PathBuf::from(flown["log_dir"].as_str().expect("the flight directory"))
}

fn s(path: &Path) -> &str {
    path.to_str().expect("a UTF-8 path")
}

/// Every prediction of a report, in kJ: the take-off, each leg, the landing.
fn predictions(report: &Value) -> Vec<f64> {
    let kj = |part: &Value| part["predicted_kj"].as_f64().expect("predicted");
    let mut out = vec![kj(&report["takeoff"])];
    out.extend(report["legs"].as_array().unwrap().iter().map(kj));
    out.push(kj(&report["landing"]));
    out
}

#[test]
fn calibration_fits_with_the_profile_flown_builds_only_its_table_and_report_reprices_with_it() {
    let tmp = tempfile::tempdir().unwrap();
    let logs = tmp.path().join("logs");
    let flight = fly("missions/paper-sample-3wp.toml", "hvb", &logs, &[]);
    fly("missions/paper-sample-8wp.toml", "hvb", &logs, &[]);
    let plan: Value =
        serde_json::from_str(&std::fs::read_to_string(flight.join("plan.json")).unwrap()).unwrap();
    assert_eq!(
        plan["priced_by"],
        serde_json::json!({"vehicle": SHIPPED_NAME, "profile": "hvb"})
    );

    // No --profile, no --tables: the flights' profile, and its table alone.
    let out = tmp.path().join("calibrated");
    let c = json(&[
        "calibrate",
        "--from-logs",
        s(&logs),
        "--out",
        s(&out),
        "--json",
    ]);
    assert_eq!(c["profile"], "hvb");
    for f in c["flights"].as_array().unwrap() {
        assert_eq!(f["profile"], "hvb", "{f}");
    }
    assert_eq!(
        c["written"],
        serde_json::json!([s(&out.join("vehicle.toml")), s(&out.join("hvb.table"))])
    );
    assert_eq!(c["tables_left_out"], serde_json::json!([]));
    // It plans with that profile by default, its only table.
    let planned = json(&[
        "plan",
        "missions/paper-sample-3wp.toml",
        "--vehicle",
        s(&out),
        "--json",
    ]);
    assert_eq!(planned["profile"], "hvb");

    // The held-out flight re-priced with the calibrated directory, no --profile: its hvb.
    let repriced = json(&["report", s(&flight), "--vehicle", s(&out), "--json"]);
    assert_eq!(repriced["priced_with"]["profile"], "hvb");
    let calibrated_name = repriced["priced_with"]["vehicle"].as_str().unwrap();
    assert!(calibrated_name.contains("calibrated"), "{calibrated_name}");
    assert_eq!(
        repriced["priced_by"],
        serde_json::json!({"flight": repriced["flight"], "vehicle": calibrated_name,
            "dir": s(&out), "profile": "hvb", "wind": null})
    );
    // Its own prices, and the same flight's report says what priced them.
    let own = json(&["report", s(&flight), "--json"]);
    assert_eq!(
        own["priced_by"],
        serde_json::json!({"flight": own["flight"], "vehicle": SHIPPED_NAME, "dir": null,
            "profile": "hvb", "wind": null})
    );
    let (ok, text, stderr) = emplan(&["report", s(&flight)]);
    assert!(ok, "{stderr}");
    assert!(
        text.lines().next().unwrap().ends_with(&format!(
            "priced by the vehicle {SHIPPED_NAME}, the hvb profile, in still air"
        )),
        "{text}"
    );

    // A flight priced in wind says the wind, text and JSON.
    let windy = fly(
        "missions/paper-sample-3wp.toml",
        "hvb",
        &tmp.path().join("windy"),
        &["--wind", "3@270"],
    );
    let doc = json(&["report", s(&windy), "--json"]);
    assert_eq!(
        doc["priced_by"]["wind"],
        serde_json::json!({"speed_m_s": 3.0, "from_deg": 270.0})
    );
    let (ok, text, _) = emplan(&["replay", s(&windy.join("flight.tlog"))]);
    assert!(ok);
    assert!(
        text.lines()
            .next()
            .unwrap()
            .ends_with("the hvb profile, in a wind of 3.0 m/s from 270 deg"),
        "{text}"
    );
}

#[test]
fn flights_flown_with_two_profiles_are_refused_naming_both_unless_a_profile_is_given() {
    let tmp = tempfile::tempdir().unwrap();
    let logs = tmp.path().join("logs");
    let hvb = fly("missions/paper-sample-3wp.toml", "hvb", &logs, &[]);
    let ptf = fly("missions/paper-sample-3wp.toml", "ptf", &logs, &[]);
    let out = tmp.path().join("calibrated");
    let (ok, _, stderr) = emplan(&["calibrate", "--from-logs", s(&logs), "--out", s(&out)]);
    assert!(!ok);
    let first = stderr.lines().find(|l| l.contains("error")).unwrap_or("");
    assert!(
        first.contains(&format!("{} was flown with the hvb profile", s(&hvb)))
            && first.contains(&format!("{} with the ptf profile", s(&ptf)))
            && first.contains("--profile"),
        "{stderr}"
    );
    assert!(!out.exists(), "nothing written to {}", out.display());
    // Told which, it fits them with it.
    let c = json(&[
        "calibrate",
        "--from-logs",
        s(&logs),
        "--profile",
        "hvb",
        "--json",
    ]);
    assert_eq!(c["profile"], "hvb");
    assert_eq!(c["flights"].as_array().unwrap().len(), 2);
}

#[test]
fn an_onboard_log_is_priced_with_its_autopilots_profile_and_says_so() {
    let bin = format!("{ONBOARD}/arducopter-8wp.bin");
    let report = json(&["report", &bin, "--json"]);
    assert_eq!(
        report["priced_by"],
        serde_json::json!({"flight": "arducopter-8wp", "vehicle": SHIPPED_NAME, "dir": null,
            "profile": "ardupilot", "wind": null})
    );
    let ardupilot = json(&["report", &bin, "--profile", "ardupilot", "--json"]);
    let px4 = json(&["report", &bin, "--profile", "px4", "--json"]);
    assert_eq!(predictions(&report), predictions(&ardupilot));
    assert_ne!(predictions(&report), predictions(&px4));
    assert_eq!(px4["priced_by"]["profile"], "px4");
    let replayed = json(&["replay", &bin, "--json"]);
    assert_eq!(predictions(&replayed), predictions(&ardupilot));
    assert_eq!(replayed["priced_by"]["profile"], "ardupilot");
    let (ok, text, _) = emplan(&["report", &bin]);
    assert!(ok);
    assert!(
        text.starts_with(&format!(
            "flight arducopter-8wp priced by the vehicle {SHIPPED_NAME}, the ardupilot profile, in still air\n"
        )),
        "{text}"
    );

    // A ULog is PX4's, planned from the mission file.
    let tmp = tempfile::tempdir().unwrap();
    let ulg = tmp.path().join("px4-sih-8wp.ulg");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(ONBOARD)
            .join("px4-sih-8wp.ulg"),
        &ulg,
    )
    .unwrap();
    let ulog = json(&[
        "report",
        s(&ulg),
        "--mission",
        "missions/paper-sample-8wp.toml",
        "--json",
    ]);
    assert_eq!(ulog["priced_by"]["profile"], "px4");
}

#[test]
fn a_plan_that_does_not_say_its_profile_is_repriced_with_its_autopilots_and_says_it_does_not_say() {
    // Written before plan.json kept its profile: an ArduPilot's mission (take-off at item 1).
    let flight = format!("{ONBOARD}/arducopter-8wp-flight");
    let repriced = json(&["report", &flight, "--vehicle", "models/s1000", "--json"]);
    assert_eq!(repriced["priced_with"]["profile"], "ardupilot");
    assert_eq!(repriced["priced_by"]["profile"], "ardupilot");
    let (ok, text, stderr) = emplan(&["report", &flight]);
    assert!(ok, "{stderr}");
    assert!(
        text.starts_with(
            "flight arducopter-8wp-flight: its plan does not say which vehicle and profile priced it\n"
        ),
        "{text}"
    );
    let own = json(&["report", &flight, "--json"]);
    assert_eq!(own["priced_by"]["profile"], Value::Null);
    assert_eq!(own["priced_by"]["vehicle"], Value::Null);
}
