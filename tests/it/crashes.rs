//! Crashes and wrong numbers, through the binary: a mission too large to plan is
//! refused with its file, line and the limit (not an abort on a 59 GB allocation); two
//! waypoints a metre apart give no negative leg (and `plan --sorties` plans them); `fly`'s text
//! compares a point's settle and hover as one part; `plan`'s text and figure state the saving
//! in one convention.

use std::fmt::Write as _;

use crate::emplan;

/// One more waypoint than a mission may have, and far more (the reported file had 86 129).
const HUGE_WAYPOINTS: usize = 90_000;

#[test]
fn a_mission_too_large_to_plan_is_refused_with_its_file_line_and_the_limit_not_aborted() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("huge.waypoints");
    // Home on line 2, waypoint k (1-based) on line k + 2.
    let mut text =
        String::from("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t38.5362\t-121.7875\t16\t1\n");
    for k in 1..=HUGE_WAYPOINTS {
        let (row, col) = ((k / 300) as f64, (k % 300) as f64);
        let _ = writeln!(
            text,
            "{k}\t0\t3\t16\t0\t0\t0\t0\t{:.7}\t{:.7}\t20\t1",
            38.5362 + row * 1e-5,
            -121.7875 + col * 1e-5
        );
    }
    std::fs::write(&path, text).expect("written");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_emplan"))
        .args(["plan", path.to_str().expect("a UTF-8 temp path")])
        .output()
        .expect("emplan runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    // An exit code, not a signal (the abort was SIGABRT).
    assert_eq!(out.status.code(), Some(1), "{:?}: {stderr}", out.status);
    let limit = emplan::mission::MAX_WAYPOINTS;
    assert!(
        stderr.contains(&format!(
            "huge.waypoints: line {}: waypoint {} of {HUGE_WAYPOINTS}: a mission may have at most \
             {limit} waypoints",
            limit + 3,
            limit + 1
        )),
        "{stderr}"
    );
    // The largest mission allowed loads.
    let text = std::fs::read_to_string(&path).expect("read");
    let head: Vec<&str> = text.lines().take(limit + 2).collect();
    let largest =
        emplan::mission::load_str(&head.join("\n"), emplan::mission::Format::Wpl, Some(&path))
            .expect("the largest mission allowed loads");
    assert_eq!(largest.waypoints.len(), limit);
}

/// A mission of two waypoints `apart_m` apart, `climb_m` between them, 20 m from the origin.
fn two_close_waypoints(dir: &std::path::Path, apart_m: f64, climb_m: f64) -> String {
    let path = dir.join(format!("close-{apart_m}-{climb_m}.toml"));
    std::fs::write(
        &path,
        format!(
            "name = \"close\"\ndefault_hover_s = 5.0\n[origin]\nlat_deg = 38.5362\n\
             lon_deg = -121.7875\nhome_alt_amsl_m = 16.0\nheight_above_home_m = 30.0\n\
             [[waypoints]]\nname = \"A\"\nx_m = 20.0\ny_m = 0.0\nz_m = 0.0\n\
             [[waypoints]]\nname = \"B\"\nx_m = {}\ny_m = 0.0\nz_m = {climb_m}\n",
            20.0 + apart_m
        ),
    )
    .expect("written");
    path.to_str().expect("a UTF-8 temp path").to_string()
}

#[test]
fn two_waypoints_a_metre_apart_give_no_negative_leg_and_split_into_sorties() {
    let dir = tempfile::tempdir().expect("temp dir");
    for (apart_m, climb_m) in [(1.24, 0.0), (1.24, -0.3), (1.7, -0.45), (0.3, 0.0)] {
        let mission = two_close_waypoints(dir.path(), apart_m, climb_m);
        for profile in ["px4", "hvb", "ptf"] {
            let plan = crate::json(&["plan", &mission, "--json", "--profile", profile]);
            for order in plan["orders"].as_array().expect("orders") {
                for leg in order["legs"].as_array().expect("legs") {
                    let kj = leg["energy_kj"].as_f64().expect("energy_kj");
                    assert!(kj >= 0.0, "{profile} {apart_m} m: {leg}");
                }
            }
            let (ok, stdout, stderr) =
                emplan(&["plan", &mission, "--sorties", "--profile", profile]);
            assert!(ok, "{profile} {apart_m} m: {stderr}");
            assert!(stdout.contains("sortie 1:"), "{stdout}");
        }
    }
}

#[test]
fn fly_text_compares_a_points_settle_and_hover_as_one_part() {
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().to_str().expect("a UTF-8 temp path");
    let (ok, stdout, stderr) = emplan(&[
        "fly",
        "missions/paper-sample-8wp.toml",
        "--log-dir",
        log,
        "--speedup",
        "50",
    ]);
    assert!(ok, "{stderr}");
    // The model and the measurement cut a point's time at different moments: apart, the
    // settles were +140% and the hovers -45%.
    assert!(
        !stdout.contains("settles (") && !stdout.contains("hovers ("),
        "{stdout}"
    );
    let row = stdout
        .lines()
        .find(|l| l.starts_with("settle + hover (9)"))
        .unwrap_or_else(|| panic!("no settle + hover row: {stdout}"));
    let error_pct: f64 = row
        .split_whitespace()
        .find_map(|w| w.strip_suffix('%'))
        .and_then(|e| e.parse().ok())
        .unwrap_or_else(|| panic!("no error in {row:?}"));
    assert!(error_pct.abs() < 3.0, "{row}");
}

#[test]
fn plan_text_and_figure_state_the_saving_in_one_convention() {
    let dir = tempfile::tempdir().expect("temp dir");
    let svg = dir.path().join("plan.svg");
    let (ok, stdout, stderr) = emplan(&[
        "plan",
        "missions/paper-sample-8wp.toml",
        "--plot",
        svg.to_str().expect("a UTF-8 temp path"),
    ]);
    assert!(ok, "{stderr}");
    let plan = crate::json(&["plan", "missions/paper-sample-8wp.toml", "--json"]);
    let kj = |objective: &str| {
        plan["orders"]
            .as_array()
            .expect("orders")
            .iter()
            .filter(|o| o["objective"] == objective)
            .filter_map(|o| o["energy_kj"].as_f64())
            .fold(f64::INFINITY, f64::min)
    };
    let (energy_kj, distance_kj) = (kj("energy"), kj("distance"));
    let words = format!(
        "saves {:.2} kJ ({:.1}% of the distance order's energy)",
        distance_kj - energy_kj,
        100.0 * (distance_kj - energy_kj) / distance_kj
    );
    assert!(
        stdout.contains(&format!("the energy order {words} against")),
        "{words}\n{stdout}"
    );
    let figure = std::fs::read_to_string(&svg)
        .expect("svg")
        .replace("&apos;", "'");
    assert!(
        figure.contains(&format!("the energy order {words}")),
        "{words}"
    );
    assert!(!figure.contains("over minimum energy"));
}
