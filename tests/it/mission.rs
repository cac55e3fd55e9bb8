//! Mission files: the shipped examples load, every format round-trips within 1 cm, malformed
//! input gets an error naming the problem and its place, and no input makes a loader panic.

use std::path::{Path, PathBuf};

use emplan::mission::{self, Format, Mission};
use proptest::prelude::*;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn assert_same_positions(a: &Mission, b: &Mission, tolerance_m: f64) {
    assert_eq!(a.waypoints.len(), b.waypoints.len());
    assert!((a.origin.height_above_home_m - b.origin.height_above_home_m).abs() < tolerance_m);
    for (wa, wb) in a.waypoints.iter().zip(&b.waypoints) {
        let (pa, pb) = (wa.position, wb.position);
        let d = ((pa.x_east_m - pb.x_east_m).powi(2)
            + (pa.y_north_m - pb.y_north_m).powi(2)
            + (pa.z_up_m - pb.z_up_m).powi(2))
        .sqrt();
        assert!(d < tolerance_m, "{} moved {d} m", wa.name);
        assert_eq!(wa.hover_s, wb.hover_s);
    }
}

fn round_trip(m: &Mission, via: Format) -> Mission {
    let text = mission::to_string(m, via).unwrap();
    let back = mission::load_str(&text, via, None).unwrap();
    let toml = mission::to_string(&back, Format::Toml).unwrap();
    mission::load_str(&toml, Format::Toml, None).unwrap()
}

#[test]
fn the_shipped_missions_load_in_every_format() {
    for name in [
        "missions/paper-sample-8wp.toml",
        "missions/paper-sample-3wp.toml",
        "missions/davis-orchard-survey.toml",
        "missions/davis-orchard-survey.plan",
        "missions/davis-orchard-survey.waypoints",
    ] {
        let m = mission::load(&repo(name)).unwrap_or_else(|e| panic!("{e}"));
        assert!(!m.waypoints.is_empty(), "{name}");
    }
}

#[test]
fn the_exported_plan_and_waypoints_examples_match_their_toml_source() {
    let toml = mission::load(&repo("missions/davis-orchard-survey.toml")).unwrap();
    for name in [
        "missions/davis-orchard-survey.plan",
        "missions/davis-orchard-survey.waypoints",
    ] {
        let other = mission::load(&repo(name)).unwrap();
        assert_same_positions(&toml, &other, 0.01);
    }
}

#[test]
fn toml_to_plan_to_toml_and_toml_to_waypoints_to_toml_keep_every_waypoint_within_a_centimetre() {
    for name in [
        "missions/paper-sample-8wp.toml",
        "missions/paper-sample-3wp.toml",
    ] {
        let m = mission::load(&repo(name)).unwrap();
        for via in [Format::QgcPlan, Format::Wpl] {
            let back = round_trip(&m, via);
            assert_same_positions(&m, &back, 0.01);
        }
        let back = round_trip(&m, Format::QgcPlan);
        let names: Vec<_> = back.waypoints.iter().map(|w| w.name.as_str()).collect();
        let original: Vec<_> = m.waypoints.iter().map(|w| w.name.as_str()).collect();
        assert_eq!(names, original, "the .plan keeps waypoint names");
    }
}

#[test]
fn waypoints_kilometres_away_round_trip_within_a_centimetre() {
    let text = r#"
name = "far"
[origin]
lat_deg = 38.5362
lon_deg = -121.7875
home_alt_amsl_m = 16.0
height_above_home_m = 30.0
[[waypoints]]
name = "east"
x_m = 4321.123
y_m = -2999.987
z_m = 100.5
[[waypoints]]
name = "north"
x_m = -150.25
y_m = 5000.75
z_m = -20.125
"#;
    let m = mission::load_str(text, Format::Toml, None).unwrap();
    for via in [Format::QgcPlan, Format::Wpl] {
        assert_same_positions(&m, &round_trip(&m, via), 0.01);
    }
}

#[test]
fn geodetic_waypoints_land_where_their_coordinates_say() {
    let m = mission::load(&repo("missions/davis-orchard-survey.toml")).unwrap();
    let mast = m
        .waypoints
        .iter()
        .position(|w| w.name == "weather-mast")
        .unwrap();
    let (lat, lon, alt) = m.waypoint_relative(mast).unwrap();
    assert!((lat - 38.54222).abs() < 1e-9 && (lon + 121.81270).abs() < 1e-9);
    assert!((alt - 45.0).abs() < 1e-6, "{alt}");
}

const GOOD_HEAD: &str = "name = \"t\"\n[origin]\nlat_deg = 38.5\nlon_deg = -121.7\nhome_alt_amsl_m = 16.0\nheight_above_home_m = 30.0\n";

fn toml_error(body: &str) -> String {
    let text = format!("{GOOD_HEAD}{body}");
    mission::load_str(&text, Format::Toml, Some(Path::new("bad.toml")))
        .expect_err("must be rejected")
        .to_string()
}

fn assert_mentions(message: &str, parts: &[&str]) {
    for p in parts {
        assert!(message.contains(p), "{message:?} does not mention {p:?}");
    }
}

#[test]
fn malformed_toml_missions_are_rejected_naming_the_problem_and_its_line() {
    let wp = |extra: &str| format!("[[waypoints]]\nname = \"A\"\nx_m = 1.0\ny_m = 2.0\n{extra}");
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            wp("z_m = nan\n"),
            vec!["bad.toml", "line 7", "\"A\"", "z_m", "NaN", "finite"],
        ),
        (
            wp("z_m = \"high\"\n"),
            vec!["bad.toml", "line 11", "invalid type"],
        ),
        (
            wp("z_m = 3.0\ncolour = \"red\"\n"),
            vec!["line 12", "unknown field", "colour"],
        ),
        (
            wp("z_m = -29.0\n"),
            vec!["line 7", "\"A\"", "below the minimum"],
        ),
        (
            wp(""),
            vec!["line 7", "\"A\"", "exactly one of", "x_m, y_m"],
        ),
        (
            format!("{}{}", wp("z_m = 1.0\n"), wp("z_m = 2.0\n")),
            vec!["line 12", "\"A\"", "duplicate name"],
        ),
        (
            wp("z_m = 1.0\nhover_s = -3.0\n"),
            vec!["line 7", "hover_s", "negative"],
        ),
        (
            "[[waypoints]]\nname = \"A\"\nlat_deg = 95.0\nlon_deg = 0.0\nalt_above_home_m = 5.0\n"
                .to_string(),
            vec!["line 7", "lat_deg", "out of range", "-90 to 90"],
        ),
        (
            String::new(),
            vec!["bad.toml", "no waypoints", "at least 1"],
        ),
        (
            "[[waypoints]]\nx_m = 1.0\ny_m = 1.0\nz_m = 1.0\n".to_string(),
            vec!["line 7", "missing field", "name"],
        ),
    ];
    for (body, parts) in cases {
        let message = toml_error(&body);
        assert_mentions(&message, &parts);
    }
    // Truncated in the middle of a key/value pair; and a missing origin table.
    let truncated = &GOOD_HEAD[..GOOD_HEAD.len() - 6];
    let message = mission::load_str(truncated, Format::Toml, Some(Path::new("bad.toml")))
        .unwrap_err()
        .to_string();
    assert_mentions(&message, &["bad.toml", "line 6"]);
    let message = mission::load_str("name = \"x\"\n", Format::Toml, Some(Path::new("bad.toml")))
        .unwrap_err()
        .to_string();
    assert_mentions(&message, &["bad.toml", "missing field", "origin"]);
}

fn plan_with_items(items: &str) -> String {
    format!(
        r#"{{"fileType": "Plan", "version": 1, "mission": {{"version": 2,
        "plannedHomePosition": [38.5, -121.7, 16.0], "items": [{items}]}}}}"#
    )
}

const TAKEOFF: &str = r#"{"type": "SimpleItem", "command": 22, "frame": 3, "params": [0, 0, 0, null, 38.5, -121.7, 20]}"#;

#[test]
fn malformed_plan_files_are_rejected_naming_the_item_or_line() {
    let complex = r#"{"type": "ComplexItem", "complexItemType": "StructureScan", "version": 3}"#;
    let survey = r#"{"type": "ComplexItem", "complexItemType": "survey", "version": 5}"#;
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            plan_with_items(&format!("{TAKEOFF}, {complex}")),
            vec![
                "bad.plan",
                "mission item 1",
                "complex item \"StructureScan\"",
            ],
        ),
        (
            plan_with_items(&format!("{TAKEOFF}, {survey}")),
            vec![
                "bad.plan",
                "mission.items[1].TransectStyleComplexItem",
                "generated items",
            ],
        ),
        (
            plan_with_items(&format!(
                r#"{TAKEOFF}, {{"type": "SimpleItem", "command": 84, "frame": 3, "params": [0,0,0,0,38.5,-121.7,20]}}"#
            )),
            vec!["mission item 1", "command 84", "not supported"],
        ),
        (
            plan_with_items(&format!(
                r#"{TAKEOFF}, {{"type": "SimpleItem", "command": 16, "frame": 10, "params": [0,0,0,0,38.5,-121.7,20]}}"#
            )),
            vec!["mission item 1", "frame 10", "terrain"],
        ),
        (
            plan_with_items(&format!(
                r#"{TAKEOFF}, {{"type": "SimpleItem", "command": 16, "frame": 3, "params": [0,0,0]}}"#
            )),
            vec!["mission item 1", "params", "7 numbers"],
        ),
        (
            plan_with_items(&format!(
                r#"{TAKEOFF}, {{"type": "SimpleItem", "command": "16", "frame": 3, "params": [0,0,0,0,38.5,-121.7,20]}}"#
            )),
            vec!["mission item 1", "\"command\"", "integer"],
        ),
        (plan_with_items(TAKEOFF), vec!["bad.plan", "no waypoints"]),
        (
            "{\"fileType\": \"Plan\", \"mission\": {\"items\": [".to_string(),
            vec!["bad.plan", "line 1", "invalid JSON"],
        ),
        (
            "{\"fileType\": \"Other\"}".to_string(),
            vec!["fileType", "Plan"],
        ),
    ];
    for (text, parts) in cases {
        let message = mission::load_str(&text, Format::QgcPlan, Some(Path::new("bad.plan")))
            .expect_err("must be rejected")
            .to_string();
        assert_mentions(&message, &parts);
    }
}

#[test]
fn malformed_waypoints_files_are_rejected_naming_the_line_and_column() {
    let home = "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t38.5\t-121.7\t16.0\t1\n";
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            format!("{home}1\t0\t3\t16\t0\t0\t0\t0\t38.5\tabc\t20\t1\n"),
            vec![
                "bad.waypoints",
                "line 3",
                "column 10 (longitude)",
                "\"abc\"",
                "not a number",
            ],
        ),
        (
            format!("{home}1\t0\t3\t16\t0\t0\t0\t38.5\t-121.7\t20\t1\n"),
            vec!["line 3", "11 columns", "12 expected"],
        ),
        (
            format!("{home}1\t0\t3.5\t16\t0\t0\t0\t0\t38.5\t-121.7\t20\t1\n"),
            vec!["line 3", "column 3 (frame)", "integer"],
        ),
        (
            format!("{home}1\t0\t3\t16\t0\t0\t0\t0\t38.5\t-121.7\tnan\t1\n"),
            vec!["line 3", "alt_above_home_m", "finite"],
        ),
        (
            format!("{home}1\t0\t3\t16\t0\t0\t0\t0\t38.5\t-121.7\t1\t1\n"),
            vec!["line 3", "below the minimum"],
        ),
        (
            "QGC WPL 120\n".to_string(),
            vec!["line 1", "not supported", "QGC WPL 110"],
        ),
        (String::new(), vec!["bad.waypoints", "empty file"]),
    ];
    for (text, parts) in cases {
        let message = mission::load_str(&text, Format::Wpl, Some(Path::new("bad.waypoints")))
            .expect_err("must be rejected")
            .to_string();
        assert_mentions(&message, &parts);
    }
}

#[test]
fn a_file_that_is_not_utf8_or_has_an_unknown_extension_is_rejected_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let garbage = dir.path().join("noise.toml");
    std::fs::write(&garbage, [0xff, 0xfe, 0x00, 0x41]).unwrap();
    let message = mission::load(&garbage).unwrap_err().to_string();
    assert_mentions(&message, &["noise.toml", "not UTF-8"]);
    let message = mission::load(Path::new("mission.kml"))
        .unwrap_err()
        .to_string();
    assert_mentions(&message, &["mission.kml", "unknown mission format"]);
    let message = mission::load(&dir.path().join("absent.toml"))
        .unwrap_err()
        .to_string();
    assert_mentions(&message, &["absent.toml"]);
}

proptest! {
    #[test]
    fn no_loader_panics_on_arbitrary_text(text in ".{0,400}") {
        for format in [Format::Toml, Format::QgcPlan, Format::Wpl] {
            let _ = mission::load_str(&text, format, None);
        }
    }

    #[test]
    fn no_loader_panics_on_mutated_valid_files(cut in 0usize..2000, byte in 0u8..128) {
        let m = mission::load(&repo("missions/paper-sample-3wp.toml")).unwrap();
        for format in [Format::Toml, Format::QgcPlan, Format::Wpl] {
            let mut text = mission::to_string(&m, format).unwrap().into_bytes();
            let at = cut % text.len();
            text[at] = byte;
            if let Ok(s) = String::from_utf8(text) {
                let _ = mission::load_str(&s, format, None);
            }
        }
    }
}
