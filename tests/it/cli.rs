//! The `emplan` binary end to end: the JSON contract of docs/json.md on the paper's sample missions
//! and on TSPLIB's br17, and clear failures on bad input.

use std::path::Path;

use serde_json::Value;

use crate::{emplan, json};

fn order<'a>(plan: &'a Value, objective: &str, direction: &str) -> &'a Value {
    plan["orders"]
        .as_array()
        .unwrap()
        .iter()
        .find(|o| o["objective"] == objective && o["direction"] == direction)
        .unwrap_or_else(|| panic!("no {objective} {direction} order"))
}

fn assert_metrics(o: &Value, d: f64, x: f64, z: f64) {
    for (key, want) in [("distance_m", d), ("horizontal_m", x), ("vertical_m", z)] {
        let got = o[key].as_f64().unwrap();
        assert!((got - want).abs() <= 0.05, "{key}: {got} vs {want} in {o}");
    }
}

#[test]
fn plan_json_of_the_eight_waypoint_sample_has_the_papers_baseline_metrics() {
    let plan = json(&["plan", "missions/paper-sample-8wp.toml", "--json"]);
    assert_eq!(plan["mission"], "paper-sample-8wp");
    for direction in ["forward", "reverse"] {
        assert_metrics(order(&plan, "distance", direction), 284.4, 189.5, 174.0);
        assert_metrics(order(&plan, "horizontal", direction), 311.6, 183.2, 240.0);
        assert_metrics(order(&plan, "vertical", direction), 321.4, 291.3, 76.0);
    }
    let d = order(&plan, "distance", "forward");
    assert_eq!(d["sequence"].as_array().unwrap().len(), 8);
    assert_eq!(d["legs"].as_array().unwrap().len(), 9);
    assert_eq!(d["legs"][0]["from"], "origin");
}

#[test]
fn plan_json_of_the_three_waypoint_sample_has_the_papers_distance_metrics() {
    let plan = json(&["plan", "missions/paper-sample-3wp.toml", "--json"]);
    assert_metrics(order(&plan, "distance", "forward"), 167.8, 136.6, 50.0);
}

#[test]
fn tsp_solves_tsplib_br17_to_its_known_optimum_of_39() {
    let br17 = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/tsplib/br17.atsp");
    let report = json(&["tsp", br17.to_str().unwrap(), "--json"]);
    assert_eq!(report["instance"], "br17");
    assert_eq!(report["dimension"], 17);
    assert_eq!(report["cost"], 39.0);
    assert_eq!(report["optimal"], true);
    assert_eq!(report["lower_bound"], 39.0);
    let mut tour: Vec<u64> = report["tour"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    assert_eq!(tour[0], 1);
    tour.sort_unstable();
    assert_eq!(tour, (1..=17).collect::<Vec<_>>());
    assert!(report["seconds"].as_f64().unwrap() >= 0.0);
}

#[test]
fn a_bad_mission_fails_with_a_message_naming_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.toml");
    std::fs::write(
        &path,
        "[origin]\nlat_deg = 1.0\nlon_deg = 2.0\nhome_alt_amsl_m = 0.0\nheight_above_home_m = 30.0\n\
         [[waypoints]]\nname = \"A\"\nx_m = 1.0\ny_m = 1.0\nz_m = 1.0\naltitude = 3\n",
    )
    .unwrap();
    let (ok, stdout, stderr) = emplan(&["plan", path.to_str().unwrap(), "--json"]);
    assert!(!ok);
    assert!(stdout.is_empty());
    assert!(
        stderr.contains("broken.toml") && stderr.contains("line 11") && stderr.contains("altitude"),
        "{stderr}"
    );
}

#[test]
fn convert_writes_a_plan_that_plans_like_its_source() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.plan");
    let (ok, _, stderr) = emplan(&[
        "convert",
        "missions/paper-sample-8wp.toml",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    let plan = json(&["plan", out.to_str().unwrap(), "--json"]);
    assert_metrics(order(&plan, "distance", "forward"), 284.4, 189.5, 174.0);
}

#[test]
fn plan_json_includes_the_energy_order_once_and_it_beats_every_baseline_for_both_samples() {
    for mission in [
        "missions/paper-sample-8wp.toml",
        "missions/paper-sample-3wp.toml",
    ] {
        for profile in ["px4", "ptf", "hvb"] {
            let plan = json(&["plan", mission, "--profile", profile, "--json"]);
            assert_eq!(plan["profile"], profile);
            let orders = plan["orders"].as_array().unwrap();
            let energy: Vec<&Value> = orders
                .iter()
                .filter(|o| o["objective"] == "energy")
                .collect();
            assert_eq!(energy.len(), 1, "{mission}");
            assert_eq!(energy[0]["direction"], "forward");
            let best = energy[0]["energy_kj"].as_f64().unwrap();
            for o in orders {
                let e = o["energy_kj"].as_f64().unwrap();
                assert!(
                    e >= best - 1e-9,
                    "{mission} {profile}: {} {} {e} < {best}",
                    o["objective"],
                    o["direction"]
                );
                let legs: f64 = o["legs"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|l| l["energy_kj"].as_f64().unwrap())
                    .sum();
                assert!((legs - e).abs() < 1e-9);
            }
            assert_eq!(plan["battery"]["feasible"], true);
        }
    }
}

#[test]
fn the_energy_order_of_the_eight_waypoint_sample_differs_from_the_distance_order_and_climbs_less() {
    let plan = json(&["plan", "missions/paper-sample-8wp.toml", "--json"]);
    let climbed = |o: &Value| -> f64 {
        o["legs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|l| l["vertical_m"].as_f64().unwrap().max(0.0))
            .sum()
    };
    let energy = order(&plan, "energy", "forward");
    for direction in ["forward", "reverse"] {
        let distance = order(&plan, "distance", direction);
        assert_ne!(energy["sequence"], distance["sequence"]);
        assert!(climbed(energy) < climbed(distance));
        assert!(energy["energy_kj"].as_f64().unwrap() < distance["energy_kj"].as_f64().unwrap());
    }
}

#[test]
fn energy_json_has_the_design_keys_and_a_stale_or_missing_table_is_refused_by_plan() {
    let e = json(&[
        "energy",
        "--xf",
        "40",
        "--zf",
        "-25",
        "--profile",
        "ptf",
        "--json",
    ]);
    for key in ["xf_m", "zf_m", "profile", "energy_kj", "duration_s"] {
        assert!(e.get(key).is_some(), "{key} missing from {e}");
    }
    assert_eq!(e["zf_m"], -25.0);
    let dir = tempfile::tempdir().unwrap();
    let vehicle = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000/vehicle.toml"),
    )
    .unwrap()
    .replace("avionics_power_w = 10.0", "avionics_power_w = 12.0");
    std::fs::write(dir.path().join("vehicle.toml"), vehicle).unwrap();
    let (ok, _, stderr) = emplan(&[
        "plan",
        "missions/paper-sample-3wp.toml",
        "--vehicle",
        dir.path().to_str().unwrap(),
    ]);
    assert!(!ok && stderr.contains("px4.table"), "{stderr}");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000/px4.table"),
        dir.path().join("px4.table"),
    )
    .unwrap();
    let (ok, _, stderr) = emplan(&[
        "plan",
        "missions/paper-sample-3wp.toml",
        "--vehicle",
        dir.path().to_str().unwrap(),
    ]);
    assert!(
        !ok && stderr.contains("emplan table build --profile px4"),
        "{stderr}"
    );
}

#[test]
fn a_reader_that_closes_the_pipe_early_ends_emplan_without_a_panic() {
    use std::io::Read;
    let dir = tempfile::tempdir().unwrap();
    let m = crate::generated_mission(dir.path(), 60, 40, 20, 1);
    let m = m.as_str();
    // The plan JSON of 60 waypoints is far larger than a pipe's buffer.
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_emplan"))
        .args(["plan", m, "--json", "--time-limit", "5"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = [0u8; 16];
    child.stdout.take().unwrap().read_exact(&mut first).unwrap();
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
}
