//! Survey blocks in the mission files through the binary: `emplan convert` carries the shipped
//! `missions/orchard-survey.plan` (two QGroundControl surveys and inspection points) to TOML and
//! back with each survey's complex item as it was, refuses a `.waypoints` file that would turn
//! the surveys into free points (naming them) and with `--lossy` writes the waypoints and says
//! the blocks are lost; a hand-written TOML block used twice apart is refused naming the line.

use std::path::Path;

use serde_json::Value;

use crate::emplan;

const SURVEY: &str = "missions/orchard-survey.plan";

fn s(path: &Path) -> &str {
    path.to_str().expect("a UTF-8 temp path")
}

fn complex_items(path: &str) -> Vec<Value> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join(path)).expect("readable");
    let doc: Value = serde_json::from_str(&text).expect("JSON");
    doc["mission"]["items"]
        .as_array()
        .expect("items")
        .iter()
        .filter(|i| i["type"] == "ComplexItem")
        .cloned()
        .collect()
}

#[test]
fn convert_carries_the_orchard_surveys_from_plan_to_toml_and_back_as_qgroundcontrol_wrote_them() {
    let dir = tempfile::tempdir().unwrap();
    let toml = dir.path().join("orchard.toml");
    let back = dir.path().join("orchard.plan");
    let (ok, stdout, stderr) = emplan(&["convert", SURVEY, s(&toml)]);
    assert!(ok, "{stderr}");
    assert!(!stdout.contains("lost"), "{stdout}");
    let text = std::fs::read_to_string(&toml).unwrap();
    assert_eq!(text.matches("[[blocks]]").count(), 2, "{text}");
    assert_eq!(text.matches("block = \"survey 1\"").count(), 24);
    let (ok, stdout, stderr) = emplan(&["convert", s(&toml), s(&back)]);
    assert!(ok, "{stderr}");
    assert!(!stdout.contains("lost"), "{stdout}");
    let original = complex_items(SURVEY);
    assert_eq!(original.len(), 2);
    assert_eq!(complex_items(s(&back)), original);
}

#[test]
fn a_survey_mission_is_not_converted_to_waypoints_unless_losses_are_allowed_and_then_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("orchard.waypoints");
    let (ok, _, stderr) = emplan(&["convert", SURVEY, s(&out)]);
    assert!(!ok);
    assert!(
        stderr.contains("block \"survey 1\": survey of waypoints WP3-WP26, reversible -> none")
            && stderr.contains("block \"survey 2\"")
            && stderr.contains("nothing written"),
        "{stderr}"
    );
    assert!(!out.exists());
    let (ok, stdout, stderr) = emplan(&["convert", "--lossy", SURVEY, s(&out)]);
    assert!(ok, "{stderr}");
    assert!(
        stdout.contains("lost block \"survey 1\"") && stdout.contains("lost block \"survey 2\""),
        "{stdout}"
    );
    // The waypoints are all there (after the header and home's line).
    let text = std::fs::read_to_string(&out).unwrap();
    let waypoints = text
        .lines()
        .skip(2)
        .filter(|l| l.split('\t').nth(3) == Some("16"));
    assert_eq!(waypoints.count(), 49);
}

#[test]
fn a_toml_block_used_twice_apart_is_refused_naming_the_file_the_line_and_the_block() {
    let dir = tempfile::tempdir().unwrap();
    let mission = dir.path().join("rows.toml");
    let wp = |name: &str, x: f64, block: &str| {
        format!("[[waypoints]]\nname = \"{name}\"\nx_m = {x}\ny_m = 0.0\nz_m = 10.0\n{block}")
    };
    let rows = "block = \"rows\"\n";
    let text = format!(
        "name = \"rows\"\n[origin]\nlat_deg = 38.5362\nlon_deg = -121.7875\n\
         home_alt_amsl_m = 16.0\nheight_above_home_m = 10.0\n{}{}{}{}\
         [[blocks]]\nname = \"rows\"\nreversible = true\n",
        wp("A", 10.0, rows),
        wp("B", 20.0, rows),
        wp("C", 30.0, ""),
        wp("D", 40.0, rows),
    );
    std::fs::write(&mission, &text).unwrap();
    let line = text.lines().position(|l| l == "name = \"D\"").unwrap();
    let (ok, _, stderr) = emplan(&["convert", s(&mission), s(&dir.path().join("rows.plan"))]);
    assert!(!ok);
    assert!(
        stderr.contains(&format!(
            "{}: line {line}: waypoint \"D\": block \"rows\" is used again after other waypoints",
            mission.display()
        )),
        "{stderr}"
    );
}
