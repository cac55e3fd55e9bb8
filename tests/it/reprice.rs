//! `emplan report FLIGHT_DIR --vehicle DIR`: a flight recorded on the built-in mock, re-priced
//! with a heavier vehicle than the one it was planned with, gets that vehicle's (higher)
//! predictions on every leg, settle, the take-off and the landing, its measurement unchanged,
//! and the report names the vehicle (text and `"priced_with"` in the JSON); without `--vehicle`
//! the plan's own prices stay. Several flights combined are re-priced alike.
//!
//! The hvb profile: its table builds in seconds (the re-pricing is the same code for every
//! profile).

use std::path::Path;

use serde_json::Value;

use crate::{emplan, json};

const HEAVY_NAME: &str = "S1000 heavier by 30 percent";

/// The shipped vehicle 30% heavier, named [`HEAVY_NAME`], with its hvb table, in `dir`.
fn heavier_vehicle(dir: &Path) {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000/vehicle.toml"),
    )
    .expect("the shipped vehicle file");
    let mut out = String::new();
    for line in text.lines() {
        let mass = (line.strip_prefix("mass_kg"))
            .and_then(|r| r.trim_start().strip_prefix('='))
            .and_then(|r| r.split('#').next()?.trim().parse::<f64>().ok());
        match mass {
            Some(m) => out.push_str(&format!("mass_kg = {}", m * 1.3)),
            None if line.starts_with("name = ") => {
                out.push_str(&format!("name = \"{HEAVY_NAME}\""))
            }
            None => out.push_str(line),
        }
        out.push('\n');
    }
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("vehicle.toml"), out).unwrap();
    let (ok, _, stderr) = emplan(&[
        "table",
        "build",
        "--vehicle",
        dir.to_str().unwrap(),
        "--profile",
        "hvb",
        "-q",
    ]);
    assert!(ok, "{stderr}");
}

/// Every prediction of a report, in kJ: the take-off, each leg, each settle, the landing.
fn predictions(report: &Value) -> Vec<f64> {
    let kj = |part: &Value| part["predicted_kj"].as_f64().expect("predicted");
    let mut out = vec![kj(&report["takeoff"])];
    out.extend(report["legs"].as_array().unwrap().iter().map(kj));
    out.extend(report["settles"].as_array().unwrap().iter().map(kj));
    out.push(kj(&report["landing"]));
    out
}

fn measured(report: &Value) -> Vec<Option<f64>> {
    (report["legs"].as_array().unwrap().iter())
        .map(|l| l["measured_kj"].as_f64())
        .collect()
}

#[test]
fn a_mock_flight_repriced_with_a_heavier_vehicle_predicts_more_and_names_it() {
    let tmp = tempfile::tempdir().unwrap();
    let logs = tmp.path().join("logs");
    let flown = json(&[
        "fly",
        "missions/paper-sample-3wp.toml",
        "--profile",
        "hvb",
        "--log-dir",
        logs.to_str().unwrap(),
        "--speedup",
        "50",
        "--json",
    ]);
    let flight = flown["log_dir"].as_str().expect("the flight directory");
    let heavy = tmp.path().join("heavy");
    heavier_vehicle(&heavy);

    let own = json(&["report", flight, "--json"]);
    assert!(own.get("priced_with").is_none(), "{own}");
    let repriced = json(&[
        "report",
        flight,
        "--vehicle",
        heavy.to_str().unwrap(),
        "--profile",
        "hvb",
        "--json",
    ]);
    assert_eq!(
        repriced["priced_with"],
        serde_json::json!({"vehicle": HEAVY_NAME, "dir": heavy.to_str().unwrap(), "profile": "hvb"})
    );
    let (before, after) = (predictions(&own), predictions(&repriced));
    assert_eq!(before.len(), 1 + 4 + 4 + 1, "{own}");
    assert_eq!(before.len(), after.len());
    for (b, a) in before.iter().zip(&after) {
        assert!(
            *a > 1.05 * b,
            "re-priced {a} kJ not above {b} kJ: {after:?} vs {before:?}"
        );
    }
    assert_eq!(measured(&own), measured(&repriced));

    let (ok, text, stderr) = emplan(&[
        "report",
        flight,
        "--vehicle",
        heavy.to_str().unwrap(),
        "--profile",
        "hvb",
    ]);
    assert!(ok, "{stderr}");
    assert!(
        text.starts_with(&format!("re-priced with the vehicle {HEAVY_NAME}"))
            && text.contains(heavy.to_str().unwrap()),
        "{text}"
    );

    // Two flights combined: the combined report's predictions are the heavy vehicle's too.
    let combined = json(&[
        "report",
        flight,
        flight,
        "--vehicle",
        heavy.to_str().unwrap(),
        "--profile",
        "hvb",
        "--json",
    ]);
    assert_eq!(combined["priced_with"]["vehicle"], HEAVY_NAME);
    let first_leg = |doc: &Value| doc["legs"][0]["predicted_kj"].as_f64().expect("predicted");
    let own_combined = json(&["report", flight, flight, "--json"]);
    assert!(
        first_leg(&combined) > 1.05 * first_leg(&own_combined),
        "{combined}"
    );
}
