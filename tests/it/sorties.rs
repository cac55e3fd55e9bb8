//! Sorties through the `emplan` binary: a mission one battery cannot fly is flagged, split into
//! sorties that each fit a battery and together visit every waypoint once, and refused by
//! upload; a smaller battery (planning parameters are outside the tables' hash) splits a sample.

use std::path::Path;

use serde_json::Value;

use crate::{emplan, json};

const LONG: &str = "missions/long-inspection.toml";

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// Checks the sorties object of a plan: every sortie within the budget and consistent, every
/// waypoint of the energy order flown exactly once; returns the number of batteries.
fn assert_sorties_cover_the_mission(plan: &Value) -> usize {
    let sorties = &plan["sorties"];
    let budget_kj = f(&sorties["budget_kj"]);
    assert_eq!(budget_kj, f(&plan["battery"]["budget_kj"]));
    let list = sorties["sorties"].as_array().unwrap();
    assert_eq!(sorties["batteries"].as_u64().unwrap() as usize, list.len());
    let mut flown: Vec<String> = Vec::new();
    let mut total = 0.0;
    for s in list {
        let t = f(&s["total_kj"]);
        assert!(t <= budget_kj, "sortie over budget: {s}");
        let parts =
            f(&s["takeoff_kj"]) + f(&s["legs_kj"]) + f(&s["hover_kj"]) + f(&s["landing_kj"]);
        assert!((parts - t).abs() < 1e-6, "{s}");
        let legs = s["legs"].as_array().unwrap();
        let seq = s["sequence"].as_array().unwrap();
        assert_eq!(legs.len(), seq.len() + 1);
        assert_eq!(legs[0]["from"], "origin");
        assert_eq!(legs[legs.len() - 1]["to"], "origin");
        let legs_kj: f64 = legs.iter().map(|l| f(&l["energy_kj"])).sum();
        assert!((legs_kj - f(&s["legs_kj"])).abs() < 1e-6, "{s}");
        flown.extend(seq.iter().map(|n| n.as_str().unwrap().to_string()));
        total += t;
    }
    assert!((total - f(&sorties["total_kj"])).abs() < 1e-6);
    let mut want: Vec<String> = plan["orders"][0]["sequence"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap().to_string())
        .collect();
    want.sort();
    flown.sort();
    assert_eq!(flown, want, "every waypoint exactly once");
    list.len()
}

#[test]
fn the_long_inspection_mission_is_flagged_over_budget_without_sorties() {
    let plan = json(&["plan", LONG, "--json"]);
    let battery = &plan["battery"];
    assert_eq!(battery["feasible"], false);
    let excess = f(&battery["excess_kj"]);
    assert!(excess > 0.0);
    assert!((excess - (f(&battery["total_kj"]) - f(&battery["budget_kj"]))).abs() < 1e-9);
    assert!(plan.get("sorties").is_none(), "sorties only when asked");
    let (ok, stdout, stderr) = emplan(&["plan", LONG]);
    assert!(ok, "{stderr}");
    assert!(stdout.contains("NOT FEASIBLE on one battery"), "{stdout}");
    assert!(
        stderr.starts_with("warning")
            && stderr.contains(&format!("{excess:.1} kJ ("))
            && stderr.contains("over budget")
            && stderr.contains(&format!("emplan plan {LONG} --sorties")),
        "{stderr}"
    );
    assert!(!stdout.contains("sortie 1"));
}

#[test]
fn sorties_of_the_long_mission_fit_one_battery_each_and_visit_every_waypoint_once() {
    let plan = json(&["plan", LONG, "--sorties", "--json"]);
    let batteries = assert_sorties_cover_the_mission(&plan);
    assert!(batteries >= 2, "{}", plan["sorties"]);
    let sorties = &plan["sorties"];
    // Each extra sortie pays another take-off and landing and flies out and back again.
    assert!(f(&sorties["total_kj"]) >= f(&plan["battery"]["total_kj"]));
    assert_eq!(
        f(&sorties["single_tour_kj"]),
        f(&plan["battery"]["total_kj"])
    );
    assert_eq!(sorties["optimal"], true);
    assert_eq!(sorties["method"], "exact");
    let (ok, stdout, stderr) = emplan(&["plan", LONG, "--sorties"]);
    assert!(ok, "{stderr}");
    assert!(
        stdout.contains(&format!("sorties: {batteries} batteries"))
            && stdout.contains("sortie 2: take-off"),
        "{stdout}"
    );
}

#[test]
fn a_mission_one_battery_can_fly_is_one_sortie_in_the_energy_order() {
    let plan = json(&[
        "plan",
        "missions/paper-sample-8wp.toml",
        "--sorties",
        "--json",
    ]);
    assert_eq!(assert_sorties_cover_the_mission(&plan), 1);
    let sortie = &plan["sorties"]["sorties"][0];
    assert_eq!(sortie["sequence"], plan["orders"][0]["sequence"]);
    assert!((f(&sortie["total_kj"]) - f(&plan["battery"]["total_kj"])).abs() < 1e-6);
    assert_eq!(plan["battery"]["excess_kj"], 0.0);
}

/// A copy of the shipped vehicle with a smaller battery: [planning] is not in the tables'
/// parameter hash, so the shipped px4 table still serves it.
fn small_battery(dir: &Path, usable_energy_wh: f64) {
    let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000");
    let vehicle = std::fs::read_to_string(models.join("vehicle.toml")).unwrap();
    assert!(vehicle.contains("usable_energy_wh = 200.0"));
    let vehicle = vehicle.replace(
        "usable_energy_wh = 200.0",
        &format!("usable_energy_wh = {usable_energy_wh:.1}"),
    );
    std::fs::write(dir.join("vehicle.toml"), vehicle).unwrap();
    std::fs::copy(models.join("px4.table"), dir.join("px4.table")).unwrap();
}

#[test]
fn a_smaller_battery_splits_the_eight_waypoint_sample_without_rebuilding_its_tables() {
    let dir = tempfile::tempdir().unwrap();
    // 25 Wh usable, 20 % reserve: 72 kJ per battery against the sample's 107 kJ.
    small_battery(dir.path(), 25.0);
    let vehicle = dir.path().to_str().unwrap();
    let plan = json(&[
        "plan",
        "missions/paper-sample-8wp.toml",
        "--vehicle",
        vehicle,
        "--sorties",
        "--json",
    ]);
    assert_eq!(plan["battery"]["feasible"], false);
    assert_eq!(f(&plan["battery"]["budget_kj"]), 72.0);
    assert!(assert_sorties_cover_the_mission(&plan) >= 2);
}

#[test]
fn a_waypoint_no_battery_can_reach_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    // 5 Wh usable: 14.4 kJ, less than taking off, flying to any waypoint and back.
    small_battery(dir.path(), 5.0);
    let (ok, stdout, stderr) = emplan(&[
        "plan",
        "missions/paper-sample-8wp.toml",
        "--vehicle",
        dir.path().to_str().unwrap(),
        "--sorties",
    ]);
    assert!(!ok);
    assert!(stdout.is_empty(), "{stdout}");
    assert!(
        stderr.contains("waypoint A cannot be flown even on a battery of its own")
            && stderr.contains("14.4 kJ"),
        "{stderr}"
    );
}

#[test]
fn upload_refuses_the_long_mission_before_connecting() {
    // The battery check comes before the link opens, so no autopilot is needed: nothing
    // listens on the discard port.
    let (ok, stdout, stderr) = emplan(&[
        "upload",
        LONG,
        "--connect",
        "udpout:127.0.0.1:9",
        "--discover-s",
        "2",
    ]);
    assert!(!ok);
    assert!(stdout.is_empty(), "{stdout}");
    assert!(
        stderr.contains("not uploaded") && stderr.contains("--sorties"),
        "{stderr}"
    );
}

#[test]
fn each_sortie_of_the_long_mission_uploads_to_the_built_in_mock_and_verifies() {
    let split = json(&["plan", LONG, "--sorties", "--json"]);
    let sorties = split["sorties"]["sorties"].as_array().unwrap();
    for (k, sortie) in sorties.iter().enumerate() {
        let number = (k + 1).to_string();
        let up = json(&["upload", LONG, "--sortie", &number, "--json"]);
        assert_eq!(up["report"]["verified"], true, "{up}");
        assert_eq!(up["sequence"], sortie["sequence"], "sortie {number}");
        let predicted = up["predicted_mission_kj"].as_f64().unwrap();
        assert!((predicted - sortie["total_kj"].as_f64().unwrap()).abs() < 1e-9);
        assert!(predicted <= up["budget_kj"].as_f64().unwrap());
    }
    let beyond = (sorties.len() + 1).to_string();
    let (ok, _, stderr) = emplan(&["upload", LONG, "--sortie", &beyond]);
    assert!(!ok);
    assert!(stderr.contains(&format!("--sortie {beyond}")), "{stderr}");
}
