//! Tests of the geofence and the rally points in the mission files: how each format reads and
//! writes them, and the errors of `RawMission::build` that locate a bad zone, vertex or point and
//! name the waypoint and the zone it breaks.

use std::path::Path;

use super::fence::{Shape, Zone};
use super::{load, load_str, to_string, Format, Mission};

fn fenced() -> Mission {
    load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/orchard-fenced.plan"))
        .expect("the demo mission loads")
}

/// The demo mission's text with `edit` applied to its JSON.
fn edited_plan(edit: impl FnOnce(&mut serde_json::Value)) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/orchard-fenced.plan");
    let mut doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    edit(&mut doc);
    serde_json::to_string_pretty(&doc).unwrap()
}

fn plan_error(text: &str) -> String {
    load_str(text, Format::QgcPlan, Some(Path::new("f.plan")))
        .unwrap_err()
        .to_string()
}

fn toml_error(text: &str) -> String {
    load_str(text, Format::Toml, Some(Path::new("f.toml")))
        .unwrap_err()
        .to_string()
}

/// A TOML mission: waypoint A at (0, 40), B at (30, 40), and `extra` after them.
fn toml_mission(extra: &str) -> String {
    format!(
        r#"name = "fenced"
[origin]
lat_deg = 38.5362
lon_deg = -121.7875
home_alt_amsl_m = 16.0
height_above_home_m = 10.0

[[waypoints]]
name = "A"
x_m = 0.0
y_m = 40.0
z_m = 5.0

[[waypoints]]
name = "B"
x_m = 30.0
y_m = 40.0
z_m = 5.0
{extra}"#
    )
}

const FIELD: &str = r#"
[[fence.polygons]]
inclusion = true
vertices_m = [[-20.0, -20.0], [50.0, -20.0], [50.0, 60.0], [-20.0, 60.0]]
"#;

#[test]
fn a_plan_geofence_and_its_rally_points_are_read_as_qgroundcontrol_writes_them() {
    let m = fenced();
    assert_eq!(m.fence.zones.len(), 2);
    assert!(m.fence.zones[0].inclusion);
    assert!(!m.fence.zones[1].inclusion);
    let vertices = |z: &Zone| match &z.shape {
        Shape::Polygon(v) => v.len(),
        Shape::Circle { .. } => 0,
    };
    assert_eq!(
        (vertices(&m.fence.zones[0]), vertices(&m.fence.zones[1])),
        (7, 4)
    );
    assert_eq!(m.rally.len(), 1);
    assert_eq!(m.rally[0].alt_above_home_m, 20.0);
    assert_eq!(
        m.fence_line().as_deref(),
        Some("fence: 1 inclusion polygon (7 vertices), 1 exclusion polygon (4 vertices); 1 rally point")
    );
}

#[test]
fn a_plan_and_a_toml_written_give_back_the_same_fence_rally_points_and_breach_return() {
    let mut m = fenced();
    m.fence.zones.push(Zone {
        inclusion: false,
        shape: Shape::Circle {
            center: super::fence::LatLon {
                lat_deg: 38.5364,
                lon_deg: -121.7876,
            },
            radius_m: 4.5,
        },
    });
    m.fence.breach_return = Some(super::Geodetic {
        lat_deg: 38.5363,
        lon_deg: -121.7874,
        alt_m: 12.0,
    });
    for format in [Format::QgcPlan, Format::Toml] {
        let text = to_string(&m, format).unwrap();
        let back = load_str(&text, format, None).unwrap();
        assert_eq!(back.fence, m.fence, "{format:?}");
        assert_eq!(back.rally, m.rally, "{format:?}");
    }
}

#[test]
fn toml_vertices_in_metres_are_kept_where_the_local_frame_puts_them() {
    let m = load_str(&toml_mission(FIELD), Format::Toml, None).unwrap();
    let local = m.fence.zones[0].local(&m.origin);
    let super::fence::LocalShape::Polygon(v) = local.shape else {
        panic!("a polygon")
    };
    for (got, want) in v
        .iter()
        .zip([[-20.0, -20.0], [50.0, -20.0], [50.0, 60.0], [-20.0, 60.0]])
    {
        assert!(
            (got[0] - want[0]).abs() < 1e-6 && (got[1] - want[1]).abs() < 1e-6,
            "{got:?} {want:?}"
        );
    }
}

#[test]
fn a_plan_vertex_out_of_range_is_named_by_its_field_and_its_zone() {
    let text = edited_plan(|d| d["geoFence"]["polygons"][1]["polygon"][3][0] = 95.0.into());
    let e = plan_error(&text);
    assert_eq!(
        e,
        "f.plan: geoFence.polygons[1].polygon[3]: exclusion polygon 2 lat_deg: 95 is out of \
         range (allowed: -90 to 90)"
    );
}

#[test]
fn a_plan_zone_without_its_inclusion_or_of_another_version_is_refused_naming_the_field() {
    let text = edited_plan(|d| {
        d["geoFence"]["polygons"][0]
            .as_object_mut()
            .unwrap()
            .remove("inclusion");
    });
    assert_eq!(
        plan_error(&text),
        "f.plan: geoFence.polygons[0].inclusion: missing or not true or false"
    );
    let text = edited_plan(|d| d["geoFence"]["version"] = 1.into());
    assert!(
        plan_error(&text)
            .starts_with("f.plan: geoFence.version: version 1 is QGroundControl's old format"),
        "{}",
        plan_error(&text)
    );
    let text = edited_plan(|d| d["rallyPoints"]["points"][0] = serde_json::json!([38.5, -121.7]));
    assert_eq!(
        plan_error(&text),
        "f.plan: rallyPoints.points[0]: must be [lat_deg, lon_deg, alt_above_home_m]"
    );
}

#[test]
fn a_self_crossing_polygon_names_the_edges_that_cross() {
    let bowtie = r#"
[[fence.polygons]]
inclusion = false
vertices_m = [[60.0, 0.0], [70.0, 10.0], [70.0, 0.0], [60.0, 10.0]]
"#;
    let e = toml_error(&toml_mission(bowtie));
    assert!(
        e.ends_with(
            "exclusion polygon 1: its edge vertices_m[0]-vertices_m[1] crosses its edge \
             vertices_m[2]-vertices_m[3] (a fence polygon must not cross itself)"
        ),
        "{e}"
    );
    assert!(e.starts_with("f.toml: line 20:"), "{e}");
}

#[test]
fn a_polygon_of_two_vertices_and_a_circle_of_no_radius_are_refused() {
    let two = "\n[[fence.polygons]]\ninclusion = false\nvertices_m = [[60.0, 0.0], [70.0, 10.0]]\n";
    assert!(
        toml_error(&toml_mission(two))
            .ends_with("exclusion polygon 1: 2 vertices (a polygon needs at least 3)"),
        "{}",
        toml_error(&toml_mission(two))
    );
    let flat = "\n[[fence.circles]]\ninclusion = false\nradius_m = 0.0\nx_m = 60.0\ny_m = 0.0\n";
    assert!(
        toml_error(&toml_mission(flat)).ends_with(
            "exclusion circle 1: radius_m 0 is not allowed (a positive number is required)"
        ),
        "{}",
        toml_error(&toml_mission(flat))
    );
}

#[test]
fn a_waypoint_inside_an_exclusion_zone_is_refused_naming_the_waypoint_and_the_zone() {
    let house = format!(
        "{FIELD}\n[[fence.circles]]\ninclusion = false\nradius_m = 5.0\nx_m = 31.0\ny_m = 41.0\n"
    );
    assert_eq!(
        toml_error(&toml_mission(&house)),
        "f.toml: line 14: waypoint \"B\" lies inside exclusion circle 2 of the geofence (it must \
         be outside every exclusion zone)"
    );
}

#[test]
fn a_waypoint_outside_one_of_two_inclusion_zones_is_refused_as_both_autopilots_allow() {
    // B (30, 40) is inside the field but not inside the second inclusion zone round A: inside
    // every inclusion zone is the rule (ArduPilot's default; PX4 asks for one).
    let two = format!(
        "{FIELD}\n[[fence.circles]]\ninclusion = true\nradius_m = 40.0\nx_m = 0.0\ny_m = 10.0\n"
    );
    assert_eq!(
        toml_error(&toml_mission(&two)),
        "f.toml: line 14: waypoint \"B\" lies outside inclusion circle 2 of the geofence (it must \
         be inside every inclusion zone)"
    );
}

#[test]
fn the_take_off_point_and_a_rally_point_must_keep_the_fence_too() {
    let off = "\n[[fence.polygons]]\ninclusion = true\nvertices_m = [[-10.0, 20.0], [50.0, 20.0], [50.0, 60.0], [-10.0, 60.0]]\n";
    assert_eq!(
        toml_error(&toml_mission(off)),
        "f.toml: line 2: the take-off point above home lies outside inclusion polygon 1 of the \
         geofence (it must be inside every inclusion zone)"
    );
    let rally = format!(
        "{FIELD}\n[[fence.polygons]]\ninclusion = false\nvertices_m = [[10.0, 0.0], [20.0, 0.0], [20.0, 10.0]]\n\n[[rally_points]]\nx_m = 18.0\ny_m = 2.0\nz_m = 0.0\n"
    );
    let e = toml_error(&toml_mission(&rally));
    assert!(
        e.ends_with(
            "rally point 1 lies inside exclusion polygon 2 of the geofence (it must be outside \
             every exclusion zone)"
        ),
        "{e}"
    );
}

#[test]
fn a_mission_with_a_fence_or_rally_points_is_not_written_as_waypoints() {
    let m = fenced();
    let e = to_string(&m, Format::Wpl).unwrap_err().to_string();
    assert!(
        e.contains("a .waypoints file (QGC WPL 110) cannot hold a geofence (1 inclusion polygon (7 vertices), 1 exclusion polygon (4 vertices)) or 1 rally point"),
        "{e}"
    );
    let mut rally_only = m.clone();
    rally_only.fence = Default::default();
    assert!(to_string(&rally_only, Format::Wpl).is_err());
    rally_only.rally.clear();
    assert!(to_string(&rally_only, Format::Wpl).is_ok());
}

#[test]
fn a_moved_fence_vertex_or_rally_point_is_a_loss_naming_it() {
    let m = fenced();
    let mut other = m.clone();
    if let Shape::Polygon(v) = &mut other.fence.zones[1].shape {
        v[2].lat_deg += 1e-5;
    }
    other.rally[0].alt_above_home_m += 2.0;
    let said: Vec<String> = super::convert::losses(&m, &other)
        .iter()
        .map(ToString::to_string)
        .collect();
    assert_eq!(said.len(), 2, "{said:?}");
    assert!(
        said[0].starts_with("exclusion polygon 2 vertex 3 (moved, m): 0 -> 1.1"),
        "{said:?}"
    );
    assert!(
        said[1].starts_with("rally point 1 (moved, m): 0 -> "),
        "{said:?}"
    );
}
