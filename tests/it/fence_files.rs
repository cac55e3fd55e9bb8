//! The geofence and the rally points through the binary: `emplan plan` shows what the demo
//! mission `missions/orchard-fenced.plan` carries (text, JSON and SVG), `emplan convert` carries
//! them from `.plan` to TOML and back and refuses a `.waypoints` file that would drop them, and a
//! waypoint inside an exclusion zone is refused naming the waypoint and the zone.

use std::path::Path;

use crate::{emplan, json};

const FENCED: &str = "missions/orchard-fenced.plan";
const PLAIN: &str = "missions/orchard-inspection.plan";

fn s(path: &Path) -> &str {
    path.to_str().expect("a UTF-8 temp path")
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("readable")).expect("JSON")
}

#[test]
fn the_plan_of_the_fenced_orchard_says_what_fence_and_rally_point_it_carries() {
    let (ok, stdout, stderr) = emplan(&["plan", FENCED, "--order", "energy"]);
    assert!(ok, "{stderr}");
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(
        lines.get(1).copied(),
        Some("fence: 1 inclusion polygon (7 vertices), 1 exclusion polygon (4 vertices); 1 rally point"),
        "{stdout}"
    );
    let (ok, plain, _) = emplan(&["plan", PLAIN, "--order", "energy"]);
    assert!(ok);
    assert!(!plain.contains("fence:"), "{plain}");

    let doc = json(&["plan", FENCED, "--order", "energy", "--json"]);
    let zones = doc["fence"]["zones"].as_array().expect("zones");
    assert_eq!(zones.len(), 2, "{doc}");
    assert_eq!(zones[0]["name"], "inclusion polygon 1");
    assert_eq!(zones[1]["name"], "exclusion polygon 2");
    assert_eq!(zones[1]["inclusion"], false);
    let square = zones[1]["vertices"].as_array().expect("vertices");
    assert_eq!(square.len(), 4);
    // The square's side, from its local east/north corners: 14 m.
    let side_m = (square[1]["x_east_m"].as_f64().unwrap()
        - square[0]["x_east_m"].as_f64().unwrap())
    .hypot(square[1]["y_north_m"].as_f64().unwrap() - square[0]["y_north_m"].as_f64().unwrap());
    assert!((side_m - 14.0).abs() < 0.05, "{side_m}");
    let file = read_json(&Path::new(env!("CARGO_MANIFEST_DIR")).join(FENCED));
    assert_eq!(
        square[3]["lat_deg"], file["geoFence"]["polygons"][1]["polygon"][3][0],
        "{doc}"
    );
    let rally = doc["rally_points"].as_array().expect("rally_points");
    assert_eq!(rally.len(), 1);
    assert_eq!(rally[0]["alt_above_home_m"], 20.0);
    let plain = json(&["plan", PLAIN, "--order", "energy", "--json"]);
    assert!(plain.get("fence").is_none() && plain.get("rally_points").is_none());
}

#[test]
fn the_plot_of_the_fenced_orchard_draws_its_zones_and_its_rally_point() {
    let dir = tempfile::tempdir().unwrap();
    let plot = dir.path().join("fenced.svg");
    let (ok, _, stderr) = emplan(&["plan", FENCED, "--plot", s(&plot)]);
    assert!(ok, "{stderr}");
    let svg = std::fs::read_to_string(&plot).unwrap();
    let plain_plot = dir.path().join("plain.svg");
    let (ok, _, stderr) = emplan(&["plan", PLAIN, "--plot", s(&plain_plot)]);
    assert!(ok, "{stderr}");
    let plain = std::fs::read_to_string(&plain_plot).unwrap();
    for (colour, what) in [
        ("#2E8B57", "inclusion outline"),
        ("#C01C28", "exclusion fill and outline"),
        ("#813D9C", "rally point"),
    ] {
        assert!(svg.contains(colour), "no {what} ({colour}) in the plot");
        assert!(
            !plain.contains(colour),
            "a {what} in the plot of a mission without one"
        );
    }
    // Labelled in each of the three views.
    assert_eq!(
        svg.matches("R1").count(),
        3,
        "the rally point is not labelled"
    );
    assert!(!plain.contains("R1"));
}

#[test]
fn convert_carries_the_fence_and_the_rally_point_from_plan_to_toml_and_back() {
    let dir = tempfile::tempdir().unwrap();
    let toml = dir.path().join("fenced.toml");
    let back = dir.path().join("fenced.plan");
    let (ok, stdout, stderr) = emplan(&["convert", FENCED, s(&toml)]);
    assert!(ok, "{stderr}");
    assert!(!stdout.contains("lost"), "{stdout}");
    let text = std::fs::read_to_string(&toml).unwrap();
    assert!(
        text.contains("[[fence.polygons]]") && text.contains("[[rally_points]]"),
        "{text}"
    );
    let (ok, stdout, stderr) = emplan(&["convert", s(&toml), s(&back)]);
    assert!(ok, "{stderr}");
    assert!(!stdout.contains("lost"), "{stdout}");
    let original = read_json(&Path::new(env!("CARGO_MANIFEST_DIR")).join(FENCED));
    let returned = read_json(&back);
    assert_eq!(returned["geoFence"], original["geoFence"]);
    assert_eq!(returned["rallyPoints"], original["rallyPoints"]);
}

#[test]
fn a_waypoint_inside_the_exclusion_square_is_refused_naming_the_waypoint_and_the_square() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = read_json(&Path::new(env!("CARGO_MANIFEST_DIR")).join(FENCED));
    // Move the square onto WP7: its centre to WP7's place (items: take-off, then WP1 and its
    // actions, ...; WP7 is the seventh NAV_WAYPOINT).
    let wp7 = doc["mission"]["items"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|i| i["command"] == 16)
        .nth(6)
        .expect("WP7")["params"]
        .clone();
    let square = doc["geoFence"]["polygons"][1]["polygon"]
        .as_array()
        .unwrap()
        .clone();
    let centre = |k: usize| square.iter().map(|v| v[k].as_f64().unwrap()).sum::<f64>() / 4.0;
    let shift = [
        wp7[4].as_f64().unwrap() - centre(0),
        wp7[5].as_f64().unwrap() - centre(1),
    ];
    let moved: Vec<serde_json::Value> = square
        .iter()
        .map(|v| {
            serde_json::json!([
                v[0].as_f64().unwrap() + shift[0],
                v[1].as_f64().unwrap() + shift[1]
            ])
        })
        .collect();
    doc["geoFence"]["polygons"][1]["polygon"] = moved.into();
    let path = dir.path().join("blocked.plan");
    std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    let (ok, _, stderr) = emplan(&["plan", s(&path)]);
    assert!(!ok);
    assert!(
        stderr.contains(&format!(
            "{}: mission item 23: waypoint \"WP7\" lies inside exclusion polygon 2 of the geofence (it must be outside every exclusion zone)",
            path.display()
        )),
        "{stderr}"
    );
}

#[test]
fn a_fenced_mission_is_not_converted_to_waypoints_even_when_losses_are_allowed() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fenced.waypoints");
    for extra in [None, Some("--lossy")] {
        let mut args = vec!["convert", FENCED, s(&out)];
        args.extend(extra);
        let (ok, _, stderr) = emplan(&args);
        assert!(!ok, "{args:?}");
        assert!(
            stderr.contains(&format!(
                "{}: a .waypoints file (QGC WPL 110) cannot hold a geofence (1 inclusion polygon \
                 (7 vertices), 1 exclusion polygon (4 vertices)) or 1 rally point",
                out.display()
            )),
            "{stderr}"
        );
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    }
}
