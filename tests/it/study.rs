//! The random-mission study, the generator and the plots through the `emplan` binary: the study
//! JSON of docs/json.md and its reproducibility, the SVG files, and generated missions that
//! `emplan plan` loads.

use serde_json::Value;

use crate::{emplan, json};

const STUDY: [&str; 13] = [
    "study",
    "--waypoints",
    "7",
    "--xy",
    "30",
    "--z",
    "25",
    "--missions",
    "50",
    "--seed",
    "4",
    "--json",
    "--profile=ptf",
];

fn pct(doc: &Value, key: &str) -> f64 {
    doc[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{key} is not a number in {doc}"))
}

#[test]
fn study_json_has_the_design_keys_and_ordered_statistics() {
    let doc = json(&STUDY);
    assert_eq!(doc["missions"], 50);
    for baseline in ["distance", "horizontal", "vertical"] {
        let stats = &doc[baseline];
        let (mean, p90, max) = (
            pct(stats, "mean_pct"),
            pct(stats, "p90_pct"),
            pct(stats, "max_pct"),
        );
        assert!(
            0.0 <= mean && mean <= p90 && p90 <= max,
            "{baseline}: {stats}"
        );
    }
    for share in [
        "distance_differs_pct",
        "vertical_beats_distance_pct",
        "horizontal_beats_distance_pct",
    ] {
        let v = pct(&doc, share);
        assert!((0.0..=100.0).contains(&v), "{share} = {v}");
        // 50 missions: every share is a whole number of 2% steps.
        assert!((v / 2.0 - (v / 2.0).round()).abs() < 1e-9, "{share} = {v}");
    }
    assert_eq!(doc["profile"], "ptf");
    assert_eq!(doc["waypoints"], 7);
    assert_eq!(doc["baseline_direction"], "better");
}

#[test]
fn the_same_seed_gives_the_same_study_and_another_seed_another() {
    let without_time = |mut doc: Value| {
        doc.as_object_mut().unwrap().remove("seconds");
        doc
    };
    let a = without_time(json(&STUDY));
    let b = without_time(json(&STUDY));
    assert_eq!(a, b);
    let mut other = STUDY;
    other[10] = "5";
    let c = without_time(json(&other));
    assert_ne!(a["distance"], c["distance"]);
}

#[test]
fn all_paper_settings_give_one_document_per_setting() {
    let docs = json(&[
        "study",
        "--all-paper-settings",
        "--missions",
        "10",
        "--json",
    ]);
    let docs = docs.as_array().expect("an array");
    let settings: Vec<(u64, f64, f64)> = docs
        .iter()
        .map(|d| {
            (
                d["waypoints"].as_u64().unwrap(),
                pct(d, "xy_m"),
                pct(d, "z_m"),
            )
        })
        .collect();
    assert_eq!(
        settings,
        vec![
            (6, 30.0, 25.0),
            (8, 20.0, 25.0),
            (8, 30.0, 25.0),
            (8, 40.0, 25.0),
            (8, 30.0, 15.0),
            (10, 30.0, 25.0)
        ]
    );
    assert!(docs.iter().all(|d| d["missions"] == 10));
}

#[test]
fn study_refuses_bad_settings_naming_the_option() {
    for (args, option) in [
        (
            ["--waypoints", "0", "--xy", "30", "--z", "25"],
            "--waypoints",
        ),
        (["--waypoints", "8", "--xy", "-1", "--z", "25"], "--xy"),
        // Legs from -Z to +Z would climb 90 m: beyond the table's +-60 m.
        (["--waypoints", "8", "--xy", "30", "--z", "45"], "--z"),
        (["--waypoints", "8", "--xy", "80", "--z", "25"], "--xy"),
    ] {
        let mut full = vec!["study", "--missions", "5"];
        full.extend(args);
        let (ok, _, stderr) = emplan(&full);
        assert!(!ok, "{full:?} succeeded");
        assert!(stderr.contains(option), "{full:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{full:?}: {stderr}");
    }
}

#[test]
fn study_histogram_is_an_svg_of_the_three_baselines() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ratios.svg");
    let (ok, _, stderr) = emplan(&[
        "study",
        "--waypoints",
        "6",
        "--xy",
        "30",
        "--z",
        "25",
        "--missions",
        "40",
        "--histogram",
        path.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    let svg = std::fs::read_to_string(&path).unwrap();
    assert!(svg.contains("<svg"));
    for label in ["min-D", "min-X", "min-Z", "energy / minimum energy"] {
        assert!(svg.contains(label), "no {label:?} in the histogram");
    }
}

/// The contents of every `<text>` element of an SVG, trimmed.
fn texts(svg: &str) -> Vec<&str> {
    svg.split("</text>")
        .filter_map(|chunk| chunk.rsplit_once('>').map(|(_, text)| text.trim()))
        .collect()
}

#[test]
fn plan_plot_draws_the_orders_with_every_waypoint_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("orders.svg");
    let (ok, stdout, stderr) = emplan(&[
        "plan",
        "missions/paper-sample-8wp.toml",
        "--json",
        "--plot",
        path.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    // --plot leaves stdout one JSON document.
    serde_json::from_str::<Value>(&stdout).expect("plan --json still prints JSON");
    let svg = std::fs::read_to_string(&path).unwrap();
    assert!(svg.contains("<svg"));
    let labels = texts(&svg);
    for name in ["origin", "A", "B", "C", "D", "E", "F", "G", "H"] {
        // Each point is labelled in each of the three views.
        let count = labels.iter().filter(|t| **t == name).count();
        assert_eq!(count, 3, "label {name} appears {count} times in {labels:?}");
    }
    for text in [
        "top view",
        "x east (m)",
        "z up (m)",
        "kJ",
        "minimum distance",
    ] {
        assert!(svg.contains(text), "no {text:?} in the plot");
    }
}

#[test]
fn generated_missions_load_in_plan_and_match_the_study_mission() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("random.toml");
    let (ok, _, stderr) = emplan(&[
        "generate",
        path.to_str().unwrap(),
        "--waypoints",
        "6",
        "--xy",
        "30",
        "--z",
        "25",
        "--seed",
        "4",
        "--mission",
        "2",
    ]);
    assert!(ok, "{stderr}");
    let plan = json(&["plan", path.to_str().unwrap(), "--json"]);
    let orders = plan["orders"].as_array().unwrap();
    assert_eq!(orders[0]["objective"], "energy");
    assert_eq!(orders[0]["sequence"].as_array().unwrap().len(), 6);
    let mission = emplan::mission::load(&path).unwrap();
    assert_eq!(mission.origin.height_above_home_m, 30.0);
    let names: Vec<&str> = mission.waypoints.iter().map(|w| w.name.as_str()).collect();
    assert_eq!(names, ["W1", "W2", "W3", "W4", "W5", "W6"]);
    // The file holds mission 2 of the study with the same seed, to full precision.
    let settings = emplan::planner::study::StudySettings {
        waypoints: 6,
        xy_m: 30.0,
        z_m: 25.0,
        missions: 1,
        seed: 4,
    };
    let points = emplan::planner::study::random_points(&settings, 2);
    for (w, p) in mission.waypoints.iter().zip(&points) {
        assert_eq!(w.position, *p);
    }
}

#[test]
fn a_thousand_waypoint_mission_is_generated_above_the_minimum_height() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.toml");
    let (ok, _, stderr) = emplan(&[
        "generate",
        path.to_str().unwrap(),
        "--waypoints",
        "1000",
        "--xy",
        "300",
        "--z",
        "40",
    ]);
    assert!(ok, "{stderr}");
    let mission = emplan::mission::load(&path).unwrap();
    assert_eq!(mission.waypoints.len(), 1000);
    for w in &mission.waypoints {
        let height = mission.origin.height_above_home_m(w.position);
        assert!(height >= 5.0 - 1e-6, "{} at {height} m above home", w.name);
    }
    let none = dir.path().join("none.toml");
    let (ok, _, stderr) = emplan(&[
        "generate",
        none.to_str().unwrap(),
        "--waypoints",
        "0",
        "--xy",
        "30",
        "--z",
        "25",
    ]);
    assert!(!ok && stderr.contains("--waypoints"), "{stderr}");
}

/// The energies `emplan plan --json` gives a generated mission: the energy order's, and the
/// min-distance tour's forward (first waypoint earlier in the file) and reverse directions, kJ.
fn planned_directions(path: &std::path::Path) -> (f64, f64, f64) {
    let plan = json(&["plan", path.to_str().unwrap(), "--json", "--profile=ptf"]);
    let energy_of = |objective: &str, direction: &str| {
        plan["orders"]
            .as_array()
            .unwrap()
            .iter()
            .find(|o| o["objective"] == objective && o["direction"] == direction)
            .and_then(|o| o["energy_kj"].as_f64())
            .unwrap_or_else(|| panic!("no {objective} {direction} order in {plan}"))
    };
    (
        energy_of("energy", "forward"),
        energy_of("distance", "forward"),
        energy_of("distance", "reverse"),
    )
}

#[test]
fn the_solver_direction_reports_the_file_order_tour_and_the_better_one_its_cheaper_reverse() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("random.toml");
    // The first of the study's one-mission seeds whose min-distance tour is cheaper reversed.
    let found = (1..=30).find_map(|seed: u64| {
        let seed_arg = seed.to_string();
        let (ok, _, stderr) = emplan(&[
            "generate",
            path.to_str().unwrap(),
            "--force",
            "--waypoints=6",
            "--xy=30",
            "--z=25",
            "--seed",
            &seed_arg,
            "--mission=0",
        ]);
        assert!(ok, "{stderr}");
        let (energy, forward, reverse) = planned_directions(&path);
        (reverse < forward).then_some((seed_arg, energy, forward, reverse))
    });
    let (seed, energy, forward, reverse) = found.expect("a tour cheaper reversed in 30 seeds");
    let study = |direction: &str| {
        json(&[
            "study",
            "--waypoints=6",
            "--xy=30",
            "--z=25",
            "--missions=1",
            "--seed",
            &seed,
            "--profile=ptf",
            "--baseline-direction",
            direction,
            "--json",
        ])
    };
    let solver = study("solver");
    let better = study("better");
    assert_eq!(solver["baseline_direction"], "solver");
    assert_eq!(better["baseline_direction"], "better");
    let increase = |kj: f64| 100.0 * (kj - energy) / energy;
    let mean = |doc: &Value| pct(&doc["distance"], "mean_pct");
    assert!(
        (mean(&solver) - increase(forward)).abs() < 1e-6,
        "seed {seed}: solver {} against the forward tour's {}",
        mean(&solver),
        increase(forward)
    );
    assert!(
        (mean(&better) - increase(reverse).max(0.0)).abs() < 1e-6,
        "seed {seed}: better {} against the reverse tour's {}",
        mean(&better),
        increase(reverse)
    );
    assert!(mean(&solver) > mean(&better));
    // Flown the dearer way round, the min-distance tour is never the energy order.
    assert_eq!(pct(&solver, "distance_differs_pct"), 100.0);
}

const BLOCK_STUDY: [&str; 14] = [
    "study",
    "--waypoints",
    "6",
    "--xy",
    "30",
    "--z",
    "25",
    "--missions",
    "20",
    "--seed",
    "3",
    "--blocks",
    "2",
    "--json",
];

#[test]
fn study_with_blocks_reports_savings_over_the_file_and_distance_orders_and_reproduces() {
    let without_time = |mut doc: Value| {
        doc.as_object_mut().unwrap().remove("seconds");
        doc
    };
    let doc = without_time(json(&BLOCK_STUDY));
    assert_eq!(doc, without_time(json(&BLOCK_STUDY)));
    assert_eq!(doc["missions"], 20);
    assert_eq!(doc["blocks"], 2);
    assert_eq!(doc["waypoints"], 6);
    assert_eq!(pct(&doc, "block_spacing_m"), 10.0);
    assert_eq!(doc["unproven_missions"], 0);
    for baseline in [
        "saving_over_file",
        "saving_over_distance",
        "saving_over_forward_blocks",
    ] {
        let stats = &doc[baseline];
        let (mean, median, max) = (
            pct(stats, "mean_pct"),
            pct(stats, "median_pct"),
            pct(stats, "max_pct"),
        );
        // The energy order is exact: it never costs more than either baseline.
        assert!(
            0.0 <= mean && mean <= max && 0.0 <= median && median <= max,
            "{baseline}: {stats}"
        );
        let over = pct(stats, "over_1pct_missions_pct");
        // 20 missions: a whole number of 5% steps.
        assert!((over / 5.0 - (over / 5.0).round()).abs() < 1e-9, "{over}");
    }
    // The file's order flies every block forward wherever the generator put it: ordering saves.
    assert!(pct(&doc["saving_over_file"], "mean_pct") > 0.0, "{doc}");
    for share in [
        "reverses_a_block_pct",
        "blocks_reversed_pct",
        "distance_differs_pct",
    ] {
        assert!((0.0..=100.0).contains(&pct(&doc, share)), "{share}");
    }
    let mut other = BLOCK_STUDY;
    other[10] = "4";
    assert_ne!(doc["saving_over_file"], json(&other)["saving_over_file"]);
    // Its table says what it compared.
    let (ok, table, stderr) = emplan(&BLOCK_STUDY[..13]);
    assert!(ok, "{stderr}");
    assert!(table.contains("survey blocks"), "{table}");
    assert!(table.contains("over file order"), "{table}");
}

#[test]
fn study_with_blocks_refuses_bad_blocks_naming_the_option() {
    for (args, option) in [
        (vec!["--blocks", "0"], "--blocks"),
        (vec!["--blocks", "9"], "--blocks"),
        (
            vec!["--blocks", "2", "--block-spacing", "0"],
            "--block-spacing",
        ),
        (vec!["--blocks", "2", "--wind", "4@270"], "--wind"),
        (vec!["--block-spacing", "5"], "--blocks"),
    ] {
        let mut full = vec![
            "study",
            "--missions",
            "3",
            "--waypoints",
            "6",
            "--xy",
            "30",
            "--z",
            "25",
        ];
        full.extend(args);
        let (ok, _, stderr) = emplan(&full);
        assert!(!ok, "{full:?} succeeded");
        assert!(stderr.contains(option), "{full:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{full:?}: {stderr}");
    }
}
