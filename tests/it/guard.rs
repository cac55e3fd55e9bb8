//! The energy guard on the built-in mock (`emplan fly --guard`): a vehicle heavier than the
//! plan's, with a smaller pack, flying a mission the plan's vehicle flies with its reserve; with
//! `rtl` it is sent home and lands with the reserve, with `off` it lands below it; the nominal
//! vehicle is never sent home on a shipped mission.

use std::path::Path;

use serde_json::Value;

use super::emplan;
use super::service::root;

/// The mission: the long survey with a minute's hover at each waypoint, about 369 kJ for the
/// plan's vehicle against its 576 kJ after the reserve.
pub(crate) fn mission(dir: &Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string(root().join("missions/long-survey.toml")).expect("mission");
    let path = dir.join("long-survey-hover.toml");
    std::fs::write(
        &path,
        text.replace("default_hover_s = 5.0", "default_hover_s = 60.0"),
    )
    .expect("written");
    path
}

/// The truth: the shipped S1000 25% heavier, with a 15% smaller pack (8.5 Ah, 170 Wh usable).
pub(crate) fn heavier_vehicle(dir: &Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string(root().join("models/s1000/vehicle.toml")).expect("vehicle");
    let changed: Vec<String> = text
        .lines()
        .map(|line| {
            let key = line.split('=').next().unwrap_or("").trim();
            let value = |v: f64| format!("{key} = {v}");
            match key {
                "mass_kg" => value(5.8069 * 1.25),
                "capacity_ah" => value(10.0 * 0.85),
                "usable_energy_wh" => value(200.0 * 0.85),
                _ => line.to_string(),
            }
        })
        .collect();
    assert!(text.contains("mass_kg = 5.8069") && text.contains("capacity_ah = 10.0"));
    let vehicle = dir.join("heavier");
    std::fs::create_dir_all(&vehicle).expect("dir");
    std::fs::write(vehicle.join("vehicle.toml"), changed.join("\n")).expect("written");
    vehicle
}

fn fly(mission: &Path, log_dir: &Path, guard: &str, truth: Option<&Path>) -> Value {
    let mut args = vec![
        "fly",
        mission.to_str().unwrap(),
        "--log-dir",
        log_dir.to_str().unwrap(),
        "--guard",
        guard,
        "--speedup",
        "50",
        "--json",
    ];
    if let Some(truth) = truth {
        args.extend(["--mock-vehicle", truth.to_str().unwrap()]);
    }
    let (ok, out, err) = emplan(&args);
    assert!(ok, "{err}");
    serde_json::from_str(&out).expect("one JSON document")
}

/// The energy left at landing in the truth's pack (J): its usable energy less what the
/// telemetry measured drawn from arming to disarming.
fn left_j(report: &Value) -> f64 {
    170.0 * 3600.0 - report["total"]["measured_kj"].as_f64().expect("measured") * 1e3
}

fn notes_of(report: &Value, kind: &str) -> usize {
    report["guard"]["notes"]
        .as_array()
        .map_or(0, |n| n.iter().filter(|n| n["kind"] == kind).count())
}

#[test]
fn a_heavier_vehicle_with_a_smaller_pack_is_sent_home_with_its_reserve_and_unguarded_lands_below_it(
) {
    let work = tempfile::tempdir().expect("temp dir");
    let mission = mission(work.path());
    let truth = heavier_vehicle(work.path());
    let reserve_j = 0.2 * 170.0 * 3600.0;

    let guarded = fly(&mission, &work.path().join("rtl"), "rtl", Some(&truth));
    assert_eq!(guarded["guard"]["returned"], true, "{}", guarded["guard"]);
    assert_eq!(notes_of(&guarded, "return"), 1, "{}", guarded["guard"]);
    assert!(
        left_j(&guarded) >= reserve_j,
        "landed with {:.0} kJ against a {:.0} kJ reserve",
        left_j(&guarded) / 1e3,
        reserve_j / 1e3
    );
    // It learned what the truth is: dearer than the model, and a smaller pack.
    let g = &guarded["guard"];
    assert!(g["correction"].as_f64().unwrap() > 1.2, "{g}");
    let capacity = g["capacity_ratio"].as_f64().unwrap();
    assert!((0.8..0.9).contains(&capacity), "{g}");
    // Not every waypoint was reached: the flight was cut short.
    let legs = guarded["legs"].as_array().expect("legs").len();

    let unguarded = fly(&mission, &work.path().join("off"), "off", Some(&truth));
    assert!(unguarded.get("guard").is_none_or(Value::is_null));
    assert_eq!(unguarded["complete"], true);
    assert!(
        left_j(&unguarded) < reserve_j,
        "unguarded landed with {:.0} kJ, not below the {:.0} kJ reserve",
        left_j(&unguarded) / 1e3,
        reserve_j / 1e3
    );
    assert!(legs < unguarded["legs"].as_array().unwrap().len());
}

#[test]
fn the_nominal_vehicle_is_never_sent_home_on_a_shipped_mission() {
    let work = tempfile::tempdir().expect("temp dir");
    for name in [
        "paper-sample-3wp.toml",
        "paper-sample-8wp.toml",
        "davis-orchard-survey.toml",
        "long-survey.toml",
    ] {
        let report = fly(
            &root().join("missions").join(name),
            &work.path().join(name),
            "rtl",
            None,
        );
        let g = &report["guard"];
        assert_eq!(g["returned"], false, "{name}: {g}");
        assert_eq!(notes_of(&report, "return"), 0, "{name}: {g}");
        let worst: Vec<&Value> = g["notes"]
            .as_array()
            .expect("notes")
            .iter()
            .filter(|n| n["verdict"] != "continue")
            .collect();
        assert!(worst.is_empty(), "{name}: {worst:?}");
        assert_eq!(report["complete"], true, "{name}");
    }
}
