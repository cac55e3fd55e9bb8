//! `emplan fly`, `replay` and `report` through the binary on the built-in mock autopilot: every
//! leg measured against its prediction (the mock flies the model's own trajectories, so they
//! agree), also with a fifth of the datagrams lost; the replayed log gives the live report; a
//! recorder killed mid-flight leaves a log that replays up to about its last second.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::{emplan, json};

fn fly(log_dir: &Path, extra: &[&str]) -> Value {
    let log = log_dir.to_str().expect("a UTF-8 temp path");
    let mut args = vec![
        "fly",
        "missions/paper-sample-8wp.toml",
        "--log-dir",
        log,
        "--json",
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
fn with_a_fifth_of_the_datagrams_lost_each_way_every_leg_is_still_within_three_percent() {
    let dir = tempfile::tempdir().unwrap();
    let report = fly(dir.path(), &["--mock-loss", "0.2", "--mock-seed", "7"]);
    assert_legs_within(&report, 3.0);
}

#[test]
fn replaying_the_log_gives_the_report_the_live_flight_gave() {
    let dir = tempfile::tempdir().unwrap();
    let live = fly(dir.path(), &[]);
    let flight = PathBuf::from(live["log_dir"].as_str().unwrap());
    let tlog = flight.join("flight.tlog");
    let replayed = json(&["replay", tlog.to_str().unwrap(), "--json"]);
    for key in ["legs", "settles", "hovers", "takeoff", "landing", "total"] {
        assert_eq!(live[key], replayed[key], "{key}");
    }
    // And from the directory, as `report` reads it.
    let reported = json(&["report", flight.to_str().unwrap(), "--json"]);
    assert_eq!(live["legs"], reported["legs"]);
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
