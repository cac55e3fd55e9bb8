//! The energy guard on the built-in mock (`emplan fly --guard`): a vehicle heavier than the
//! plan's, with a smaller pack, flying a mission the plan's vehicle flies with its reserve; with
//! `rtl` it is sent home and lands with the reserve, with `off` it lands below it; the nominal
//! vehicle is never sent home on a shipped mission.

use std::path::Path;

use serde_json::Value;

use super::service::root;

/// The mission: the shipped demo (`missions/long-survey-hover.toml`, the long survey with a
/// minute's hover at each waypoint, about 369 kJ for the plan's vehicle against its 576 kJ after
/// the reserve), copied into `dir`.
pub(crate) fn mission(dir: &Path) -> std::path::PathBuf {
    let path = dir.join("long-survey-hover.toml");
    std::fs::copy(root().join("missions/long-survey-hover.toml"), &path).expect("copied");
    path
}

/// The truth: the shipped demo vehicle (`models/s1000-heavier`), the S1000 25% heavier with a
/// 15% smaller pack (8.5 Ah, 170 Wh usable). `_dir` is kept for the callers' symmetry.
pub(crate) fn heavier_vehicle(_dir: &Path) -> std::path::PathBuf {
    let vehicle = root().join("models/s1000-heavier");
    let text = std::fs::read_to_string(vehicle.join("vehicle.toml")).expect("vehicle");
    let shipped = std::fs::read_to_string(root().join("models/s1000/vehicle.toml")).unwrap();
    // The demo's three values, each 25% or 15% off the shipped S1000's.
    let value = |text: &str, key: &str| -> f64 {
        let line = (text.lines())
            .find(|l| l.trim_start().starts_with(&format!("{key} ")))
            .unwrap_or_else(|| panic!("{key}"));
        let v = line.split('=').nth(1).unwrap().split('#').next().unwrap();
        v.trim().parse().unwrap()
    };
    for (key, ratio) in [
        ("mass_kg", 1.25),
        ("capacity_ah", 0.85),
        ("usable_energy_wh", 0.85),
    ] {
        let (demo, base) = (value(&text, key), value(&shipped, key));
        assert!(
            (demo / base - ratio).abs() < 1e-4,
            "{key}: {demo} vs {base}"
        );
    }
    vehicle
}

/// Runs `emplan` from the crate root: (exit code, stdout, stderr).
fn run(args: &[&str]) -> (Option<i32>, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_emplan"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("emplan runs");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A flight's `fly --json` document; its exit code is 3 when it left waypoints, else 0.
pub(crate) fn fly(mission: &Path, log_dir: &Path, guard: &str, truth: Option<&Path>) -> Value {
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
    let (code, out, err) = run(&args);
    let doc: Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}{err}"));
    let left = doc["incomplete"] == true;
    assert_eq!(code, Some(if left { 3 } else { 0 }), "{err}");
    doc
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
    // The way home is its own part, priced as the guard priced it, in place of the landing;
    // the mission is incomplete, and says which waypoints are left.
    let home_kj = (g["notes"].as_array().unwrap().iter())
        .find(|n| n["kind"] == "return")
        .map(|n| n["home_kj"].as_f64().expect("the return's price"))
        .unwrap();
    let back = &guarded["return"];
    assert_eq!(back["predicted_kj"].as_f64(), Some(home_kj), "{back}");
    assert!(back["measured_kj"].as_f64().unwrap() > 0.0, "{back}");
    assert_eq!(back["to"], "ground");
    assert!(guarded["landing"].is_null(), "{}", guarded["landing"]);
    assert_eq!(guarded["incomplete"], true);
    let left = guarded["waypoints_left"]
        .as_array()
        .expect("waypoints_left");
    assert!(!left.is_empty() && left.contains(&back["from"]), "{left:?}");
    assert!(guarded["total"]["error_pct"].is_null());

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
    assert_eq!(unguarded["incomplete"], false);
    assert_eq!(unguarded["waypoints_left"], serde_json::json!([]));
    assert!(unguarded.get("return").is_none());
}

/// The words of a POSIX shell command line of plain words, single-quoted ones and
/// backslash-escaped characters.
fn shell_words(line: &str) -> Vec<String> {
    let (mut words, mut word, mut quoted, mut any) = (Vec::new(), String::new(), false, false);
    let mut chars = line.chars();
    while let Some(c) = chars.next() {
        match c {
            '\'' => (quoted, any) = (!quoted, true),
            '\\' if !quoted => {
                word.extend(chars.next());
                any = true;
            }
            ' ' if !quoted => {
                if any {
                    words.push(std::mem::take(&mut word));
                }
                any = false;
            }
            c => {
                word.push(c);
                any = true;
            }
        }
    }
    if any {
        words.push(word);
    }
    words
}

/// The guard's demo command in docs/guard.md (the `emplan fly` line of its shell block), as
/// its words after `emplan`.
fn demo_command() -> Vec<String> {
    let doc = std::fs::read_to_string(root().join("docs/guard.md")).expect("docs/guard.md");
    let line = (doc.lines())
        .find(|l| l.starts_with("emplan fly ") && l.contains("--guard rtl"))
        .expect("docs/guard.md gives the demo's command");
    shell_words(line).into_iter().skip(1).collect()
}

#[test]
fn the_guard_docs_demo_sends_the_vehicle_home_and_its_report_books_the_return_and_prints_the_resume_that_flies_the_rest(
) {
    let work = tempfile::tempdir().expect("temp dir");
    // A log folder whose name a shell must have quoted.
    let log_dir = work.path().join("field day's flights");
    let mut args = demo_command();
    assert!(args.contains(&"--mock-vehicle".to_string()), "{args:?}");
    args.extend(["--speedup".into(), "50".into(), "--log-dir".into()]);
    args.push(log_dir.to_str().unwrap().into());
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let (code, out, err) = run(&args);
    assert_eq!(code, Some(3), "{out}{err}");
    let rows: Vec<&str> = out.lines().collect();
    // The way home is its own row, in place of the landing's.
    let back = (rows.iter())
        .find(|l| l.starts_with("return: ") && l.contains(" -> home "))
        .unwrap_or_else(|| panic!("no return row: {out}"));
    assert!(!rows.iter().any(|l| l.starts_with("landing ")), "{out}");
    // The total is not compared with the whole plan's price when the mission was cut short.
    let total: Vec<&str> = (rows.iter())
        .find(|l| l.starts_with("total "))
        .expect("total")
        .split_whitespace()
        .collect();
    assert_eq!(total.get(3), Some(&"-"), "{out}");
    let said = (rows.iter())
        .find_map(|l| l.strip_prefix("mission incomplete: "))
        .unwrap_or_else(|| panic!("not said incomplete: {out}"));
    let left: Vec<&str> = said
        .split_once(" left: ")
        .expect("named")
        .1
        .split(", ")
        .collect();
    let from = back["return: ".len()..].split(" -> ").next().unwrap();
    assert!(left.contains(&from), "{left:?} {back}");
    // What the user reads holds no log line of the tracing kind (a timestamp, WARN).
    for line in out.lines().chain(err.lines()) {
        assert!(
            !line.contains("WARN") && !line.contains("emplan::"),
            "a log line among the report: {line}"
        );
    }
    // The command printed flies exactly what was left, and finishes the mission.
    let next = (rows.iter())
        .find_map(|l| l.strip_prefix("next: "))
        .unwrap_or_else(|| panic!("no next step: {out}"));
    let words = shell_words(next.split_once(" with: ").expect("a command").1);
    assert_eq!(&words[..2], ["emplan", "fly"], "{next}");
    assert!(words.contains(&"--resume".to_string()), "{next}");
    let mut resume: Vec<&str> = words[1..].iter().map(String::as_str).collect();
    resume.extend(["--speedup", "50", "--json"]);
    let (code, out, err) = run(&resume);
    assert_eq!(code, Some(0), "{next}: {err}");
    let resumed: Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(resumed["incomplete"], false, "{resumed}");
    let flown: Vec<&str> = (resumed["legs"].as_array().unwrap().iter())
        .map(|l| l["to"].as_str().unwrap())
        .filter(|to| *to != "origin")
        .collect();
    let (mut flown, mut left) = (flown, left);
    flown.sort_unstable();
    left.sort_unstable();
    assert_eq!(flown, left, "{next}");
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
