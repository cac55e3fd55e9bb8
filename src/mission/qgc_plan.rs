//! QGroundControl `.plan` (JSON) import and export (the QGC dev guide's plan file
//! format; docs/mission-files.md). `plannedHomePosition` is home; the items are read as
//! [`super::sequence`] reads them: NAV_TAKEOFF sets the origin's height above home, the
//! waypoints (param1 = hover time) carry the commands that follow them, RTL / LAND end the
//! mission. Complex items (surveys, scans) are rejected, naming the item.
//! Waypoint and point-of-interest names, which QGC has no field for, travel in a top-level
//! `emplan` object QGC ignores.

use serde_json::{json, Value};

use super::actions::{Command, FRAME_GLOBAL_RELATIVE_ALT, FRAME_MISSION};
use super::sequence::{self, Item};
use super::{
    Geodetic, Mission, MissionError, Place, Poi, RawMission, DEFAULT_MIN_HEIGHT_ABOVE_HOME_M,
    DEFAULT_TAKEOFF_HEIGHT_M,
};

/// MAV_CMD ids (common.xml) of the items emplan writes itself.
pub(super) const NAV_WAYPOINT: u64 = 16;
pub(super) const NAV_RETURN_TO_LAUNCH: u64 = 20;
pub(super) const NAV_TAKEOFF: u64 = 22;

fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Null => Some(f64::NAN),
        Value::Number(n) => n.as_f64(),
        _ => None,
    }
}

pub(super) fn parse(text: &str, file: &str, stem: &str) -> Result<RawMission, MissionError> {
    let bad = |place: Place, problem: String| MissionError::invalid(file, place, problem);
    let root: Value = serde_json::from_str(text)
        .map_err(|e| bad(Place::Line(e.line()), format!("invalid JSON: {e}")))?;
    if root.get("fileType").and_then(Value::as_str) != Some("Plan") {
        return Err(bad(
            Place::File,
            "field \"fileType\": must be \"Plan\" (a QGroundControl plan file)".into(),
        ));
    }
    let mission = root
        .get("mission")
        .and_then(Value::as_object)
        .ok_or_else(|| {
            bad(
                Place::File,
                "field \"mission\": missing or not an object".into(),
            )
        })?;
    let home = mission
        .get("plannedHomePosition")
        .and_then(Value::as_array)
        .filter(|a| a.len() == 3)
        .and_then(|a| Some([number(&a[0])?, number(&a[1])?, number(&a[2])?]))
        .ok_or_else(|| {
            bad(
                Place::File,
                "field \"mission.plannedHomePosition\": must be [lat_deg, lon_deg, alt_amsl_m]"
                    .into(),
            )
        })?;
    let items = mission
        .get("items")
        .and_then(Value::as_array)
        .ok_or_else(|| {
            bad(
                Place::File,
                "field \"mission.items\": missing or not an array".into(),
            )
        })?;
    let extra = root.get("emplan");
    let names: Vec<String> = extra
        .and_then(|e| e.get("waypoint_names"))
        .and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .filter_map(|v| v.as_str().map(String::from))
                .collect()
        })
        .unwrap_or_default();

    let mut read = Vec::with_capacity(items.len());
    for (k, item) in items.iter().enumerate() {
        let place = Place::Item(k);
        let kind = item.get("type").and_then(Value::as_str).unwrap_or("");
        if kind == "ComplexItem" {
            let what = item
                .get("complexItemType")
                .and_then(Value::as_str)
                .unwrap_or("unknown");
            return Err(bad(
                place,
                format!(
                    "complex item \"{what}\" is not supported (only simple items: convert the \
                     survey to waypoints in QGroundControl first)"
                ),
            ));
        }
        if kind != "SimpleItem" {
            return Err(bad(
                place,
                format!("field \"type\": {kind:?} is not supported (allowed: \"SimpleItem\")"),
            ));
        }
        let field_u64 = |key: &str| {
            item.get(key).and_then(Value::as_u64).ok_or_else(|| {
                bad(
                    place.clone(),
                    format!("field {key:?}: missing or not a non-negative integer"),
                )
            })
        };
        let command = field_u64("command")?;
        let frame = field_u64("frame")?;
        let params: Vec<f64> = item
            .get("params")
            .and_then(Value::as_array)
            .filter(|a| a.len() == 7)
            .map(|a| a.iter().map(number).collect::<Option<Vec<f64>>>())
            .unwrap_or(None)
            .ok_or_else(|| {
                bad(
                    place.clone(),
                    "field \"params\": must be an array of 7 numbers or nulls".into(),
                )
            })?;
        read.push(Item {
            command,
            frame,
            params: [
                params[0], params[1], params[2], params[3], params[4], params[5], params[6],
            ],
            place,
        });
    }
    let mut seq = sequence::read(file, read, home[2])?;
    let use_names = names.len() == seq.waypoints.len();
    for (i, w) in seq.waypoints.iter_mut().enumerate() {
        w.name = if use_names {
            names[i].clone()
        } else {
            format!("WP{}", i + 1)
        };
    }
    let pois = extra
        .and_then(|e| e.get("pois"))
        .and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .filter_map(|p| {
                    Some(Poi {
                        name: p.get("name")?.as_str()?.to_string(),
                        lat_deg: p.get("lat_deg")?.as_f64()?,
                        lon_deg: p.get("lon_deg")?.as_f64()?,
                        alt_above_home_m: p.get("alt_above_home_m")?.as_f64()?,
                    })
                })
                .collect()
        })
        .unwrap_or_default();
    let extra_f64 = |key: &str| extra.and_then(|e| e.get(key)).and_then(Value::as_f64);
    Ok(RawMission {
        name: extra
            .and_then(|e| e.get("name"))
            .and_then(Value::as_str)
            .unwrap_or(stem)
            .to_string(),
        home: Geodetic {
            lat_deg: home[0],
            lon_deg: home[1],
            alt_m: home[2],
        },
        height_above_home_m: seq.height_above_home_m.unwrap_or(DEFAULT_TAKEOFF_HEIGHT_M),
        default_hover_s: extra_f64("default_hover_s").unwrap_or(0.0),
        min_height_above_home_m: extra_f64("min_height_above_home_m")
            .unwrap_or(DEFAULT_MIN_HEIGHT_ABOVE_HOME_M),
        waypoints: seq.waypoints,
        start_actions: seq.start_actions,
        pois,
        fence: Default::default(),
        rally: Vec::new(),
        place: Place::File,
    })
}

fn simple_item(id: usize, command: u64, frame: u64, params: [Value; 7]) -> Value {
    let mut item = json!({
        "type": "SimpleItem",
        "command": command,
        "frame": frame,
        "params": params,
        "autoContinue": true,
        "doJumpId": id,
    });
    if frame == 3 {
        item["AltitudeMode"] = json!(1);
        item["Altitude"] = params[6].clone();
        item["AMSLAltAboveTerrain"] = Value::Null;
    }
    item
}

/// A parameter as QGroundControl writes it: NaN as null.
fn param(v: f64) -> Value {
    if v.is_nan() {
        Value::Null
    } else {
        json!(v)
    }
}

/// A command as a simple item, its parameters as they are.
fn command_item(id: usize, c: &Command) -> Value {
    simple_item(
        id,
        u64::from(c.command),
        u64::from(c.frame),
        c.params.map(param),
    )
}

/// The mission as a QGroundControl plan: take-off to the origin, the waypoints in file order,
/// return to launch. Altitudes relative to home (frame 3).
pub(super) fn write(mission: &Mission) -> String {
    let home = mission.origin.home;
    let mut items = vec![simple_item(
        1,
        NAV_TAKEOFF,
        3,
        [
            json!(0),
            json!(0),
            json!(0),
            Value::Null,
            json!(home.lat_deg),
            json!(home.lon_deg),
            json!(mission.origin.height_above_home_m),
        ],
    )];
    for c in &mission.start_actions {
        items.push(command_item(items.len() + 1, c));
    }
    for w in &mission.waypoints {
        let g = mission.origin.to_geodetic(w.position);
        let [p2, p3, p4] = match w.kind {
            super::WaypointKind::LoiterTime { params } => params.map(param),
            _ => [json!(0), json!(0), Value::Null],
        };
        items.push(simple_item(
            items.len() + 1,
            u64::from(w.kind.command()),
            u64::from(FRAME_GLOBAL_RELATIVE_ALT),
            [
                json!(w.hover_s),
                p2,
                p3,
                p4,
                json!(g.lat_deg),
                json!(g.lon_deg),
                json!(g.alt_m - home.alt_m),
            ],
        ));
        for c in &w.actions {
            items.push(command_item(items.len() + 1, c));
        }
    }
    items.push(simple_item(
        items.len() + 1,
        NAV_RETURN_TO_LAUNCH,
        u64::from(FRAME_MISSION),
        [
            json!(0),
            json!(0),
            json!(0),
            json!(0),
            json!(0),
            json!(0),
            json!(0),
        ],
    ));
    let doc = json!({
        "fileType": "Plan",
        "version": 1,
        "groundStation": "emplan",
        "mission": {
            "version": 2,
            "firmwareType": 12,
            "vehicleType": 14,
            "cruiseSpeed": 5,
            "hoverSpeed": 5,
            "globalPlanAltitudeMode": 1,
            "plannedHomePosition": [home.lat_deg, home.lon_deg, home.alt_m],
            "items": items,
        },
        "geoFence": { "version": 2, "circles": [], "polygons": [] },
        "rallyPoints": { "version": 2, "points": [] },
        "emplan": {
            "name": mission.name,
            "default_hover_s": mission.default_hover_s,
            "min_height_above_home_m": mission.min_height_above_home_m,
            "waypoint_names": mission.waypoints.iter().map(|w| w.name.clone()).collect::<Vec<_>>(),
            "pois": mission.pois.iter().map(|p| json!({
                "name": p.name,
                "lat_deg": p.lat_deg,
                "lon_deg": p.lon_deg,
                "alt_above_home_m": p.alt_above_home_m,
            })).collect::<Vec<_>>(),
        },
    });
    let mut text = serde_json::to_string_pretty(&doc).unwrap_or_default();
    text.push('\n');
    text
}
