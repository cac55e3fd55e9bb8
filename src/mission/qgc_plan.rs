//! QGroundControl `.plan` (JSON) import and export (the QGC dev guide's plan file
//! format; docs/mission-files.md). `plannedHomePosition` is home; NAV_TAKEOFF sets the
//! origin's height above home; NAV_WAYPOINT items are the waypoints (param1 = hover time);
//! RTL / LAND end the mission and DO_CHANGE_SPEED is ignored (emplan's flight profile sets speed).
//! Complex items (surveys, scans) and any other command are rejected, naming the item.
//! Waypoint names, which QGC has no field for, travel in a top-level `emplan` object QGC ignores.

use serde_json::{json, Value};

use super::{
    Geodetic, Mission, MissionError, Place, RawMission, RawPosition, RawWaypoint,
    DEFAULT_MIN_HEIGHT_ABOVE_HOME_M, DEFAULT_TAKEOFF_HEIGHT_M,
};

/// MAV_CMD ids (common.xml).
pub(super) const NAV_WAYPOINT: u64 = 16;
pub(super) const NAV_RETURN_TO_LAUNCH: u64 = 20;
pub(super) const NAV_LAND: u64 = 21;
pub(super) const NAV_TAKEOFF: u64 = 22;
pub(super) const DO_CHANGE_SPEED: u64 = 178;

/// What a mission item means to emplan.
pub(super) enum ItemMeaning {
    /// A waypoint: latitude, longitude, altitude above home, hover time.
    Waypoint(f64, f64, f64, f64),
    /// A take-off to this height above home.
    Takeoff(f64),
    /// An item emplan does not need (end of mission, speed change).
    Ignored,
}

/// Interprets one mission item (shared by `.plan` and `.waypoints`): `params` are the seven
/// MISSION_ITEM params with latitude and longitude in degrees.
pub(super) fn interpret_item(
    command: u64,
    frame: u64,
    params: [f64; 7],
    home_amsl_m: f64,
) -> Result<ItemMeaning, String> {
    let altitude = |alt: f64| -> Result<f64, String> {
        match frame {
            // MAV_FRAME_GLOBAL_RELATIVE_ALT (3) and its _INT twin (6).
            3 | 6 => Ok(alt),
            // MAV_FRAME_GLOBAL (0) and GLOBAL_INT (5): altitude above mean sea level.
            0 | 5 => Ok(alt - home_amsl_m),
            10 | 11 => Err(format!(
                "frame {frame} (terrain-relative altitude) is not supported (allowed: 0, 3, 5, 6)"
            )),
            _ => Err(format!(
                "frame {frame} is not supported for command {command} (allowed: 0, 3, 5, 6)"
            )),
        }
    };
    match command {
        NAV_WAYPOINT => Ok(ItemMeaning::Waypoint(
            params[4],
            params[5],
            altitude(params[6])?,
            params[0],
        )),
        NAV_TAKEOFF => Ok(ItemMeaning::Takeoff(altitude(params[6])?)),
        NAV_RETURN_TO_LAUNCH | NAV_LAND | DO_CHANGE_SPEED => Ok(ItemMeaning::Ignored),
        _ => Err(format!(
            "command {command} is not supported (allowed: 16 NAV_WAYPOINT, 22 NAV_TAKEOFF, \
             20 NAV_RETURN_TO_LAUNCH, 21 NAV_LAND, 178 DO_CHANGE_SPEED)"
        )),
    }
}

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

    let mut height_above_home_m = None;
    let mut found = Vec::new();
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
        let params: [f64; 7] = [
            params[0], params[1], params[2], params[3], params[4], params[5], params[6],
        ];
        match interpret_item(command, frame, params, home[2]).map_err(|p| bad(place.clone(), p))? {
            ItemMeaning::Waypoint(lat, lon, alt, hover) => found.push((k, lat, lon, alt, hover)),
            ItemMeaning::Takeoff(h) => height_above_home_m = Some(h),
            ItemMeaning::Ignored => {}
        }
    }
    let use_names = names.len() == found.len();
    let waypoints = found
        .into_iter()
        .enumerate()
        .map(|(i, (k, lat, lon, alt, hover))| RawWaypoint {
            name: if use_names {
                names[i].clone()
            } else {
                format!("WP{}", i + 1)
            },
            position: RawPosition::Geodetic {
                lat_deg: lat,
                lon_deg: lon,
                alt_above_home_m: alt,
            },
            hover_s: Some(if hover.is_nan() { 0.0 } else { hover }),
            place: Place::Item(k),
        })
        .collect();
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
        height_above_home_m: height_above_home_m.unwrap_or(DEFAULT_TAKEOFF_HEIGHT_M),
        default_hover_s: extra_f64("default_hover_s").unwrap_or(0.0),
        min_height_above_home_m: extra_f64("min_height_above_home_m")
            .unwrap_or(DEFAULT_MIN_HEIGHT_ABOVE_HOME_M),
        waypoints,
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
    for (k, w) in mission.waypoints.iter().enumerate() {
        let g = mission.origin.to_geodetic(w.position);
        items.push(simple_item(
            k + 2,
            NAV_WAYPOINT,
            3,
            [
                json!(w.hover_s),
                json!(0),
                json!(0),
                Value::Null,
                json!(g.lat_deg),
                json!(g.lon_deg),
                json!(g.alt_m - home.alt_m),
            ],
        ));
    }
    items.push(simple_item(
        mission.waypoints.len() + 2,
        NAV_RETURN_TO_LAUNCH,
        2,
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
        },
    });
    let mut text = serde_json::to_string_pretty(&doc).unwrap_or_default();
    text.push('\n');
    text
}
