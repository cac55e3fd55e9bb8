//! `emplan calibrate --from-logs` through the binary: the built-in mock flies a perturbed vehicle
//! (mass +10%, body drag x1.3, a weaker battery) that the vehicle file does not describe; the
//! calibration from three logged flights brings the leave-one-flight-out per-leg error from
//! above 8% to under 3%, finds the pack's resistance and capacity from its voltage, and the
//! vehicle directory it writes (vehicle.toml and its rebuilt table)
//! predicts a fourth flight, of a mission not fitted, within 3% per leg. Bad input is refused
//! naming the directory or file.
//!
//! The flights use the hvb profile: its table rebuilds in seconds where px4's takes about a
//! minute, and the fit is the same code for every profile.

use std::path::Path;

use serde_json::Value;

use crate::{emplan, json};

/// The mock's default speed-up: at 50x a 2 ms tick of the mock is 0.1 s of flight, and under a
/// loaded machine the leg energies scattered enough to move the fitted mass over efficiency
/// 3.1% (against the 2% held below); at 20x an event's stamp is within 0.04 s.
const SPEEDUP: &str = "20";

/// The ESC efficiency of the shipped vehicle, which the perturbed one keeps
/// (models/s1000/vehicle.toml; checked by [`perturbed_vehicle`]).
const TRUE_ESC_EFFICIENCY: f64 = 0.95;

/// The value `calibrate --json` fitted for `key` in a `fitted` list.
fn fitted_value(fitted: &Value, key: &str) -> f64 {
    fitted
        .as_array()
        .expect("a fitted list")
        .iter()
        .find(|f| f["key"] == key)
        .and_then(|f| f["value"].as_f64())
        .unwrap_or_else(|| panic!("{key} not fitted: {fitted}"))
}

/// The shipped vehicle with mass +10%, body drag x1.3, a pack of 8 Ah instead of 10 and 35 mOhm
/// instead of 20, written to `dir`.
fn perturbed_vehicle(dir: &Path) -> (f64, f64) {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000/vehicle.toml"),
    )
    .expect("the shipped vehicle file");
    let mut out = String::new();
    let (mut mass, mut drag) = (f64::NAN, f64::NAN);
    let mut changed = 0;
    for line in text.lines() {
        let value = |key: &str| -> Option<f64> {
            let rest = line.strip_prefix(key)?.trim_start().strip_prefix('=')?;
            rest.split('#').next()?.trim().parse().ok()
        };
        let new = if let Some(m) = value("mass_kg") {
            mass = m * 1.1;
            format!("mass_kg = {mass}")
        } else if let Some(d) = value("drag_coefficient_n_s2_m2") {
            drag = d * 1.3;
            format!("drag_coefficient_n_s2_m2 = {drag}")
        } else if value("capacity_ah").is_some() {
            "capacity_ah = 8.0".to_string()
        } else if value("internal_resistance_ohm").is_some() {
            "internal_resistance_ohm = 0.035".to_string()
        } else {
            out.push_str(line);
            out.push('\n');
            continue;
        };
        changed += 1;
        out.push_str(&new);
        out.push('\n');
    }
    assert_eq!(changed, 4, "four lines perturbed");
    assert!(
        text.lines()
            .any(|l| l.split('#').next().unwrap().replace(' ', "")
                == format!("esc_efficiency={TRUE_ESC_EFFICIENCY}")),
        "the shipped vehicle's ESC efficiency is {TRUE_ESC_EFFICIENCY}"
    );
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("vehicle.toml"), out).unwrap();
    (mass, drag)
}

fn fly(mission: &str, logs: &Path, truth: &Path, extra: &[&str]) -> Value {
    let mut args = vec![
        "fly",
        mission,
        "--profile",
        "hvb",
        "--log-dir",
        logs.to_str().unwrap(),
        "--mock-vehicle",
        truth.to_str().unwrap(),
        "--speedup",
        SPEEDUP,
        "--json",
    ];
    args.extend_from_slice(extra);
    json(&args)
}

fn leg_errors(report: &Value) -> Vec<f64> {
    report["legs"]
        .as_array()
        .expect("legs")
        .iter()
        .map(|l| l["error_pct"].as_f64().expect("every leg measured"))
        .collect()
}

#[test]
fn calibration_from_logs_of_a_perturbed_vehicle_brings_held_out_leg_error_under_three_percent() {
    let tmp = tempfile::tempdir().unwrap();
    let truth = tmp.path().join("truth");
    let (true_mass, true_drag) = perturbed_vehicle(&truth);
    let logs = tmp.path().join("logs");
    for mission in [
        "missions/paper-sample-8wp.toml",
        "missions/paper-sample-3wp.toml",
        "missions/davis-orchard-survey.toml",
    ] {
        let report = fly(mission, &logs, &truth, &[]);
        // The shipped vehicle under-predicts every leg of the heavier, draggier one.
        assert!(
            leg_errors(&report).iter().all(|e| *e > 8.0),
            "{mission}: {:?}",
            leg_errors(&report)
        );
    }
    let out = tmp.path().join("calibrated");
    let c = json(&[
        "calibrate",
        "--from-logs",
        logs.to_str().unwrap(),
        "--profile",
        "hvb",
        "--out",
        out.to_str().unwrap(),
        "--tables",
        "hvb",
        "--json",
    ]);
    assert_eq!(c["profile"], "hvb");
    assert_eq!(c["flights"].as_array().unwrap().len(), 3);
    let legs = c["legs"].as_array().unwrap().len();
    assert_eq!(legs, 9 + 4 + 13);
    let stat = |key: &str, what: &str| c[key][what].as_f64().unwrap();
    assert!(stat("before", "rms_pct") > 8.0, "{}", c["before"]);
    assert!(stat("held_out", "rms_pct") < 3.0, "{}", c["held_out"]);
    assert!(stat("after", "rms_pct") < 3.0, "{}", c["after"]);
    assert_eq!(c["held_out"]["legs"].as_u64(), Some(legs as u64));
    for left_out in c["leave_one_out"].as_array().unwrap() {
        assert!(
            left_out["errors"]["rms_pct"].as_f64().unwrap() < 3.0,
            "{left_out}"
        );
    }
    // What the energies identify is the truth's, near enough: the work of lifting the vehicle,
    // mass over the powertrain's efficiency (a climb's m g v / eta), within 2%. The mass alone
    // is identified only loosely, so it is held to 10%: energies see it through the induced
    // power's m^1.5 (which the induced power factor also moves) and the accelerations. Measured
    // on two sets of these three flights (the mock's legs scatter about 0.5% on the truth):
    // mass -0.7% and -5.5%, mass over efficiency +0.1% and +0.4%, the second fit's objective
    // below the truth's own.
    let mass = fitted_value(&c["fitted"], "body.mass_kg");
    let efficiency = fitted_value(&c["fitted"], "motor.esc_efficiency");
    let drag = fitted_value(&c["fitted"], "body.drag_coefficient_n_s2_m2");
    let lift = (mass / efficiency) / (true_mass / TRUE_ESC_EFFICIENCY);
    assert!(
        (lift - 1.0).abs() < 0.02 && (mass / true_mass - 1.0).abs() < 0.10,
        "mass {mass} vs {true_mass}, mass/efficiency {lift} of the truth's: {} (envelope bound: {})",
        c["fitted"],
        c["envelope_bound"]
    );
    // The body drag is not held to the truth: the refitted S1000's horizontal drag is small
    // (0.05 N s^2/m^2) beside the rotors' own losses, so these legs pin it loosely and the fit
    // trades it against mass (0.028 to 0.085 for a true 0.065 in three runs); it stays a fitted,
    // finite value inside its search range.
    assert!(drag.is_finite() && drag > 0.0, "{drag} vs {true_drag}");
    // The weaker pack, from the voltage and current in samples.csv.
    let resistance = fitted_value(&c["battery"]["fitted"], "battery.internal_resistance_ohm");
    let capacity = fitted_value(&c["battery"]["fitted"], "battery.capacity_ah");
    assert!((resistance - 0.035).abs() < 0.003, "{}", c["battery"]);
    assert!((capacity - 8.0).abs() < 0.4, "{}", c["battery"]);
    let written = std::fs::read_to_string(out.join("vehicle.toml")).unwrap();
    assert!(
        written.contains(&format!("mass_kg = {mass:.4}"))
            && written.contains(&format!("capacity_ah = {capacity:.4}")),
        "{written}"
    );
    assert_eq!(
        c["written"],
        serde_json::json!([
            out.join("vehicle.toml").to_str().unwrap(),
            out.join("hvb.table").to_str().unwrap()
        ])
    );

    // The written vehicle plans and predicts a flight of a mission it was not fitted to.
    let fresh = crate::generated_mission(tmp.path(), 6, 60, 25, 11);
    let report = fly(
        &fresh,
        &tmp.path().join("check"),
        &truth,
        &["--vehicle", out.to_str().unwrap()],
    );
    let errors = leg_errors(&report);
    assert!(errors.iter().all(|e| e.abs() < 3.0), "{errors:?}");

    // Writing over a directory that holds something is refused, naming it.
    let (ok, _, stderr) = emplan(&[
        "calibrate",
        "--from-logs",
        logs.to_str().unwrap(),
        "--profile",
        "hvb",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(
        stderr.contains(out.to_str().unwrap()) && stderr.contains("not empty"),
        "{stderr}"
    );

    // Given the weighed mass, the fit keeps it and fits the rest around it.
    let weighed = tmp.path().join("weighed");
    let mass_arg = format!("{true_mass}");
    let w = json(&[
        "calibrate",
        "--from-logs",
        logs.to_str().unwrap(),
        "--profile",
        "hvb",
        "--mass-kg",
        &mass_arg,
        "--out",
        weighed.to_str().unwrap(),
        "--tables",
        "none",
        "--json",
    ]);
    let given: Vec<&Value> = (w["fitted"].as_array().unwrap().iter())
        .filter(|f| f["given"] == true)
        .collect();
    assert_eq!(given.len(), 1, "{}", w["fitted"]);
    assert_eq!(given[0]["key"], "body.mass_kg");
    assert_eq!(given[0]["value"].as_f64(), Some(true_mass));
    // With the mass weighed, the powertrain's efficiency is pinned: the truth's within 2%.
    let weighed_efficiency = fitted_value(&w["fitted"], "motor.esc_efficiency");
    assert!(
        (weighed_efficiency / TRUE_ESC_EFFICIENCY - 1.0).abs() < 0.02,
        "{}",
        w["fitted"]
    );
    assert!(
        w["after"]["rms_pct"].as_f64().unwrap() < 3.0,
        "{}",
        w["after"]
    );
    let written = std::fs::read_to_string(weighed.join("vehicle.toml")).unwrap();
    let line = written
        .lines()
        .find(|l| l.starts_with("mass_kg = "))
        .unwrap();
    assert!(line.contains("weighed"), "{line}");
    // A mass no airframe has is refused, naming the flag and the key.
    let (ok, _, stderr) = emplan(&[
        "calibrate",
        "--from-logs",
        logs.to_str().unwrap(),
        "--mass-kg",
        "0.01",
    ]);
    assert!(!ok);
    assert!(
        stderr.contains("--mass-kg") && stderr.contains("body.mass_kg"),
        "{stderr}"
    );
}

#[test]
fn logs_that_are_not_flights_are_refused_naming_the_directory_or_file() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("nowhere");
    let (ok, _, stderr) = emplan(&["calibrate", "--from-logs", missing.to_str().unwrap()]);
    assert!(!ok);
    assert!(stderr.contains(missing.to_str().unwrap()), "{stderr}");

    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let (ok, _, stderr) = emplan(&["calibrate", "--from-logs", empty.to_str().unwrap()]);
    assert!(!ok);
    assert!(
        stderr.contains(empty.to_str().unwrap()) && stderr.contains("no flight directory"),
        "{stderr}"
    );

    // A flight directory whose report.json is torn: the file is named.
    let flight = tmp.path().join("flight");
    std::fs::create_dir_all(&flight).unwrap();
    let plan = r#"{"mission": "m", "home": {"lat_deg": 38.5, "lon_deg": -121.7, "alt_m": 16.0},
        "origin_height_m": 20.0, "points": [{"seq": 1, "name": "origin",
        "enu": {"x_east_m": 0.0, "y_north_m": 0.0, "z_up_m": 0.0}, "hold_s": 0.0}],
        "takeoff_seq": 0, "land_seq": 2, "predicted": null}"#;
    std::fs::write(flight.join("plan.json"), plan).unwrap();
    std::fs::write(flight.join("report.json"), "{\"flight\": ").unwrap();
    let (ok, _, stderr) = emplan(&["calibrate", "--from-logs", flight.to_str().unwrap()]);
    assert!(!ok);
    assert!(
        stderr.contains(flight.join("report.json").to_str().unwrap()),
        "{stderr}"
    );
}
