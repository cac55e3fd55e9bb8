//! QGroundControl `.plan` (JSON) import and export (the QGC dev guide's plan file
//! format; docs/mission-files.md). `plannedHomePosition` is home; the items are read as
//! [`super::sequence`] reads them: NAV_TAKEOFF sets the origin's height above home, the
//! waypoints (param1 = hover time) carry the commands that follow them, RTL / LAND end the
//! mission. A `survey` or `CorridorScan` complex item is read from the items QGroundControl
//! generated for it (`TransectStyleComplexItem.Items`, through the same reader) as a block of
//! waypoints, the complex item kept to write it back; other complex items (a `StructureScan`
//! stores no generated items) are refused, naming the item.
//! Waypoint and point-of-interest names, which QGC has no field for, travel in a top-level
//! `emplan` object QGC ignores.
//!
//! The geofence and the rally points are QGroundControl's (`GeoFenceController`,
//! `QGCFencePolygon`, `QGCFenceCircle`, `QGCMapCircle`, `RallyPointController` and
//! `RallyPointManager` of its MissionManager): `geoFence` is `{"version": 2, "polygons":
//! [{"version": 1, "inclusion": bool, "polygon": [[lat, lon], ...]}], "circles": [{"version":
//! 1, "inclusion": bool, "circle": {"center": [lat, lon], "radius": m}}], "breachReturn":
//! [lat, lon, alt]}` (`breachReturn` optional), `rallyPoints` is `{"version": 2, "points":
//! [[lat, lon, alt], ...]}`. QGroundControl uploads rally points and the breach return point
//! in `MAV_FRAME_GLOBAL_RELATIVE_ALT`, so their altitudes are above home. Like QGroundControl,
//! a `geoFence` or `rallyPoints` of version 1 or none is the old format and is ignored, but
//! only when it holds nothing (emplan never drops a zone silently); any other version is
//! refused.

use serde_json::{json, Value};

use super::actions::{Command, FRAME_GLOBAL_RELATIVE_ALT, FRAME_MISSION};
use super::blocks::{Block, BlockKind};
use super::fence::{LatLon, RallyPoint, Shape, Zone};
use super::sequence::{self, Item};
use super::{
    Geodetic, Mission, MissionError, Place, Poi, RawBlock, RawMission, RawZone,
    DEFAULT_MIN_HEIGHT_ABOVE_HOME_M, DEFAULT_TAKEOFF_HEIGHT_M,
};

/// MAV_CMD ids (common.xml) of the items emplan writes itself.
pub(super) const NAV_WAYPOINT: u64 = 16;
pub(super) const NAV_RETURN_TO_LAUNCH: u64 = 20;
pub(super) const NAV_TAKEOFF: u64 = 22;
const NAV_LAND: u64 = 21;
const NAV_DO_JUMP: u64 = 177;

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
    // The complex items read as blocks: their item index, kind and JSON.
    let mut complex: Vec<(usize, BlockKind, Value)> = Vec::new();
    for (k, item) in items.iter().enumerate() {
        let place = Place::Item(k);
        let kind = item.get("type").and_then(Value::as_str).unwrap_or("");
        if kind == "ComplexItem" {
            let (block_kind, generated) = complex_item(item, k, file)?;
            let group = complex.len();
            for (i, g) in generated.iter().enumerate() {
                let path = format!("mission.items[{k}].TransectStyleComplexItem.Items[{i}]");
                let one = simple(g, Place::Field(path.clone()), file, Some(group))?;
                if matches!(
                    one.command,
                    NAV_TAKEOFF | NAV_RETURN_TO_LAUNCH | NAV_LAND | NAV_DO_JUMP
                ) {
                    return Err(at(
                        file,
                        &format!("{path}.command"),
                        format!(
                            "{} in a complex item is not supported (a block flies waypoints and \
                             their commands)",
                            one.command
                        ),
                    ));
                }
                read.push(one);
            }
            complex.push((k, block_kind, item.clone()));
            continue;
        }
        if kind != "SimpleItem" {
            return Err(bad(
                place,
                format!(
                    "field \"type\": {kind:?} is not supported (allowed: \"SimpleItem\", \
                     \"ComplexItem\")"
                ),
            ));
        }
        read.push(simple(item, place, file, None)?);
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
    let listed: Vec<&Value> = extra
        .and_then(|e| e.get("blocks"))
        .and_then(Value::as_array)
        .map(|a| a.iter().collect())
        .unwrap_or_default();
    let use_listed = listed.len() == complex.len();
    let mut blocks = Vec::with_capacity(complex.len());
    for (group, (k, kind, source)) in complex.into_iter().enumerate() {
        let mine: Vec<usize> = (0..seq.groups.len())
            .filter(|&i| seq.groups[i] == Some(group))
            .collect();
        let nth = blocks.iter().filter(|b: &&RawBlock| b.kind == kind).count() + 1;
        let given = use_listed.then(|| listed[group]);
        let name = given
            .and_then(|b| b.get("name"))
            .and_then(Value::as_str)
            .map_or_else(|| format!("{} {nth}", kind.word()), String::from);
        let reversible = given
            .and_then(|b| b.get("reversible"))
            .and_then(Value::as_bool)
            .unwrap_or(kind != BlockKind::Structure);
        blocks.push(RawBlock {
            name,
            kind,
            first: mine.first().copied().unwrap_or(0),
            len: mine.len(),
            reversible,
            source: Some(source),
            place: Place::Item(k),
        });
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
    let (zones, breach_return) = geofence(root.get("geoFence"), file)?;
    let rally = rally_points(root.get("rallyPoints"), file)?;
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
        zones,
        breach_return,
        rally,
        blocks,
        place: Place::File,
    })
}

/// One simple item (a `SimpleItem` of `mission.items` or of a complex item's `Items`).
fn simple(
    item: &Value,
    place: Place,
    file: &str,
    group: Option<usize>,
) -> Result<Item, MissionError> {
    let bad = |problem: String| MissionError::invalid(file, place.clone(), problem);
    if group.is_some() && item.get("type").and_then(Value::as_str) != Some("SimpleItem") {
        return Err(bad(
            "field \"type\": must be \"SimpleItem\" (a complex item's generated items are \
             simple items)"
                .into(),
        ));
    }
    let field_u64 = |key: &str| {
        item.get(key).and_then(Value::as_u64).ok_or_else(|| {
            bad(format!(
                "field {key:?}: missing or not a non-negative integer"
            ))
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
        .ok_or_else(|| bad("field \"params\": must be an array of 7 numbers or nulls".into()))?;
    Ok(Item {
        command,
        frame,
        params: [
            params[0], params[1], params[2], params[3], params[4], params[5], params[6],
        ],
        place,
        group,
    })
}

/// A complex item's kind and its generated items (`TransectStyleComplexItem.Items`):
/// QGroundControl's `survey` (versions 3 to 5) and `CorridorScan` (version 3) store them; a
/// `StructureScan` stores none (QGroundControl rebuilds them from its polygon on loading), nor
/// does any other complex item emplan knows of, and those are refused.
fn complex_item<'a>(
    item: &'a Value,
    k: usize,
    file: &str,
) -> Result<(BlockKind, &'a [Value]), MissionError> {
    let what = item
        .get("complexItemType")
        .and_then(Value::as_str)
        .unwrap_or("unknown");
    let kind = match what {
        "survey" => BlockKind::Survey,
        "CorridorScan" => BlockKind::Corridor,
        "StructureScan" => {
            return Err(MissionError::invalid(
                file,
                Place::Item(k),
                "complex item \"StructureScan\" is not supported: QGroundControl stores no \
                 generated items for a structure scan (it rebuilds them from the structure's \
                 polygon when it loads the plan); convert the structure scan to waypoints in \
                 QGroundControl first",
            ))
        }
        _ => {
            return Err(MissionError::invalid(
                file,
                Place::Item(k),
                format!(
                    "complex item \"{what}\" is not supported (only simple items, \"survey\" \
                     and \"CorridorScan\": convert it to waypoints in QGroundControl first)"
                ),
            ))
        }
    };
    let version = item.get("version").and_then(Value::as_u64);
    if !matches!(version, Some(3..=5)) {
        let given = item
            .get("version")
            .map_or_else(|| "none".to_string(), Value::to_string);
        return Err(at(
            file,
            &format!("mission.items[{k}].version"),
            format!("{given} is not supported for complex item \"{what}\" (allowed: 3 to 5)"),
        ));
    }
    let inner = item
        .get("TransectStyleComplexItem")
        .filter(|v| v.is_object())
        .ok_or_else(|| {
            at(
                file,
                &format!("mission.items[{k}].TransectStyleComplexItem"),
                format!(
                    "missing or not an object (where QGroundControl keeps a {}'s generated \
                     items; a {what} of version {} without it stores none: open and save the \
                     plan in QGroundControl 4 first)",
                    kind.word(),
                    version.unwrap_or(0)
                ),
            )
        })?;
    let generated = inner
        .get("Items")
        .and_then(Value::as_array)
        .ok_or_else(|| {
            at(
                file,
                &format!("mission.items[{k}].TransectStyleComplexItem.Items"),
                "missing or not an array (the complex item's generated items)",
            )
        })?;
    Ok((kind, generated.as_slice()))
}

/// The error at `.plan` field `path`.
fn at(file: &str, path: &str, problem: impl Into<String>) -> MissionError {
    MissionError::invalid(file, Place::Field(path.to_string()), problem)
}

/// Whether a `geoFence` or `rallyPoints` object is in the current format (version 2); an old
/// one (version 1 or none) may be ignored only when it holds nothing.
fn current(object: &Value, key: &str, lists: &[&str], file: &str) -> Result<bool, MissionError> {
    match object.get("version") {
        Some(v) if v.as_u64() == Some(2) => Ok(true),
        None => old(object, key, "none", lists, file),
        Some(v) if v.as_u64() == Some(1) => old(object, key, "1", lists, file),
        Some(v) => Err(at(
            file,
            &format!("{key}.version"),
            format!("{v} is not supported (allowed: 2, QGroundControl's)"),
        )),
    }
}

fn old(
    object: &Value,
    key: &str,
    version: &str,
    lists: &[&str],
    file: &str,
) -> Result<bool, MissionError> {
    let holds = lists.iter().any(|list| {
        object
            .get(*list)
            .and_then(Value::as_array)
            .is_some_and(|a| !a.is_empty())
    });
    if holds {
        Err(at(
            file,
            &format!("{key}.version"),
            format!(
                "version {version} is QGroundControl's old format, which it ignores; this one \
                 holds {}, so it is refused rather than dropped (allowed: version 2)",
                lists.join(" or ")
            ),
        ))
    } else {
        Ok(false)
    }
}

/// `[lat, lon]` or `[lat, lon, alt]` (QGroundControl's coordinate arrays; JSON null is NaN,
/// refused by validation); `with_alt` asks for the altitude.
fn coordinate(value: Option<&Value>, with_alt: bool) -> Option<[f64; 3]> {
    let a = value?.as_array()?;
    let allowed = if with_alt { 3..=3 } else { 2..=3 };
    if !allowed.contains(&a.len()) {
        return None;
    }
    let n = |k: usize| a.get(k).map_or(Some(0.0), number);
    Some([n(0)?, n(1)?, n(2)?])
}

/// The array at `object[key]` (required).
fn array<'a>(
    object: &'a Value,
    key: &str,
    path: &str,
    file: &str,
) -> Result<&'a [Value], MissionError> {
    object
        .get(key)
        .and_then(Value::as_array)
        .map(Vec::as_slice)
        .ok_or_else(|| at(file, &format!("{path}.{key}"), "missing or not an array"))
}

/// A zone's `version` (1) and `inclusion`.
fn zone_header(zone: &Value, path: &str, file: &str) -> Result<bool, MissionError> {
    if !zone.is_object() {
        return Err(at(file, path, "not an object"));
    }
    match zone.get("version").and_then(Value::as_u64) {
        Some(1) => {}
        _ => {
            return Err(at(
                file,
                &format!("{path}.version"),
                "missing or not 1 (QGroundControl's fence zones are version 1)",
            ))
        }
    }
    zone.get("inclusion")
        .and_then(Value::as_bool)
        .ok_or_else(|| {
            at(
                file,
                &format!("{path}.inclusion"),
                "missing or not true or false",
            )
        })
}

/// The zones (polygons, then circles) and the breach return point of a `geoFence` object.
#[allow(clippy::type_complexity)]
fn geofence(
    fence: Option<&Value>,
    file: &str,
) -> Result<(Vec<RawZone>, Option<(Geodetic, Place)>), MissionError> {
    let Some(fence) = fence else {
        return Ok((Vec::new(), None));
    };
    if !fence.is_object() {
        return Err(at(file, "geoFence", "not an object"));
    }
    if !current(fence, "geoFence", &["polygons", "circles"], file)? {
        return Ok((Vec::new(), None));
    }
    let mut zones = Vec::new();
    for (k, polygon) in array(fence, "polygons", "geoFence", file)?
        .iter()
        .enumerate()
    {
        let path = format!("geoFence.polygons[{k}]");
        let inclusion = zone_header(polygon, &path, file)?;
        let mut vertices = Vec::new();
        for (i, v) in array(polygon, "polygon", &path, file)?.iter().enumerate() {
            let [lat_deg, lon_deg, _] = coordinate(Some(v), false).ok_or_else(|| {
                at(
                    file,
                    &format!("{path}.polygon[{i}]"),
                    "must be [lat_deg, lon_deg]",
                )
            })?;
            vertices.push(LatLon { lat_deg, lon_deg });
        }
        zones.push(RawZone {
            zone: Zone {
                inclusion,
                shape: Shape::Polygon(vertices),
            },
            place: Place::Field(path),
            vertices_key: "polygon",
        });
    }
    for (k, circle) in array(fence, "circles", "geoFence", file)?
        .iter()
        .enumerate()
    {
        let path = format!("geoFence.circles[{k}]");
        let inclusion = zone_header(circle, &path, file)?;
        let shape = circle
            .get("circle")
            .filter(|c| c.is_object())
            .ok_or_else(|| at(file, &format!("{path}.circle"), "missing or not an object"))?;
        let [lat_deg, lon_deg, _] = coordinate(shape.get("center"), false).ok_or_else(|| {
            at(
                file,
                &format!("{path}.circle.center"),
                "missing or not [lat_deg, lon_deg]",
            )
        })?;
        let radius_m = shape.get("radius").and_then(number).ok_or_else(|| {
            at(
                file,
                &format!("{path}.circle.radius"),
                "missing or not a number (metres)",
            )
        })?;
        zones.push(RawZone {
            zone: Zone {
                inclusion,
                shape: Shape::Circle {
                    center: LatLon { lat_deg, lon_deg },
                    radius_m,
                },
            },
            place: Place::Field(path),
            vertices_key: "polygon",
        });
    }
    let breach_return = match fence.get("breachReturn") {
        None => None,
        Some(v) => {
            let [lat_deg, lon_deg, alt_m] = coordinate(Some(v), true).ok_or_else(|| {
                at(
                    file,
                    "geoFence.breachReturn",
                    "must be [lat_deg, lon_deg, alt_above_home_m]",
                )
            })?;
            Some((
                Geodetic {
                    lat_deg,
                    lon_deg,
                    alt_m,
                },
                Place::Field("geoFence.breachReturn".into()),
            ))
        }
    };
    Ok((zones, breach_return))
}

/// The rally points of a `rallyPoints` object (altitudes above home).
fn rally_points(
    rally: Option<&Value>,
    file: &str,
) -> Result<Vec<(RallyPoint, Place)>, MissionError> {
    let Some(rally) = rally else {
        return Ok(Vec::new());
    };
    if !rally.is_object() {
        return Err(at(file, "rallyPoints", "not an object"));
    }
    if !current(rally, "rallyPoints", &["points"], file)? {
        return Ok(Vec::new());
    }
    let mut out = Vec::new();
    for (k, p) in array(rally, "points", "rallyPoints", file)?
        .iter()
        .enumerate()
    {
        let path = format!("rallyPoints.points[{k}]");
        let [lat_deg, lon_deg, alt_above_home_m] = coordinate(Some(p), true)
            .ok_or_else(|| at(file, &path, "must be [lat_deg, lon_deg, alt_above_home_m]"))?;
        out.push((
            RallyPoint {
                lat_deg,
                lon_deg,
                alt_above_home_m,
            },
            Place::Field(path),
        ));
    }
    Ok(out)
}

/// The `geoFence` object of a mission: polygons and circles in the fence's order.
fn geofence_json(mission: &Mission) -> Value {
    let lat_lon = |p: &LatLon| json!([p.lat_deg, p.lon_deg]);
    let mut polygons = Vec::new();
    let mut circles = Vec::new();
    for zone in &mission.fence.zones {
        match &zone.shape {
            Shape::Polygon(vertices) => polygons.push(json!({
                "version": 1,
                "inclusion": zone.inclusion,
                "polygon": vertices.iter().map(lat_lon).collect::<Vec<_>>(),
            })),
            Shape::Circle { center, radius_m } => circles.push(json!({
                "version": 1,
                "inclusion": zone.inclusion,
                "circle": { "center": lat_lon(center), "radius": radius_m },
            })),
        }
    }
    let mut fence = json!({ "version": 2, "circles": circles, "polygons": polygons });
    if let Some(g) = mission.fence.breach_return {
        fence["breachReturn"] = json!([g.lat_deg, g.lon_deg, g.alt_m]);
    }
    fence
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

/// Waypoint `k` as simple items (its navigation item, then its commands), numbered from `id`.
fn waypoint_items(mission: &Mission, k: usize, id: usize) -> Vec<Value> {
    let home = mission.origin.home;
    let w = &mission.waypoints[k];
    let g = mission.origin.to_geodetic(w.position);
    let [p2, p3, p4] = match w.kind {
        super::WaypointKind::LoiterTime { params } => params.map(param),
        _ => [json!(0), json!(0), Value::Null],
    };
    let mut out = vec![simple_item(
        id,
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
    )];
    for c in &w.actions {
        out.push(command_item(id + out.len(), c));
    }
    out
}

/// A block's waypoints as the generated items of its complex item (`Items`), numbered from
/// `id`: QGroundControl's `MissionItem` keys, without a simple item's altitude keys.
fn block_items(mission: &Mission, block: &Block, id: usize) -> Vec<Value> {
    let mut out: Vec<Value> = Vec::new();
    for k in block.waypoints() {
        for mut item in waypoint_items(mission, k, id + out.len()) {
            if let Some(o) = item.as_object_mut() {
                for key in ["AltitudeMode", "Altitude", "AMSLAltAboveTerrain"] {
                    o.remove(key);
                }
            }
            out.push(item);
        }
    }
    out
}

/// Whether a block's complex item still generates the mission's waypoints for it (positions
/// to a millimetre, holds, kinds and commands as they are): then it is written back exactly as
/// it was read, else its `Items` are rewritten from the waypoints (moved by a new home, say).
fn unchanged(mission: &Mission, block: &Block, source: &Value) -> bool {
    let Some(generated) = source
        .get("TransectStyleComplexItem")
        .and_then(|t| t.get("Items"))
        .and_then(Value::as_array)
    else {
        return false;
    };
    let home = mission.origin.home;
    let read: Option<Vec<Item>> = generated
        .iter()
        .map(|g| simple(g, Place::File, "", Some(0)).ok())
        .collect();
    let Some(seq) = read.and_then(|items| sequence::read("", items, home.alt_m).ok()) else {
        return false;
    };
    if seq.waypoints.len() != block.len || !seq.start_actions.is_empty() {
        return false;
    }
    let same_params = |a: &[f64; 7], b: &[f64; 7]| {
        a.iter()
            .zip(b)
            .all(|(p, q)| (p.is_nan() && q.is_nan()) || (p - q).abs() <= 1e-9 * p.abs().max(1.0))
    };
    seq.waypoints
        .iter()
        .zip(&mission.waypoints[block.waypoints()])
        .all(|(r, w)| {
            let super::RawPosition::Geodetic {
                lat_deg,
                lon_deg,
                alt_above_home_m,
            } = r.position
            else {
                return false;
            };
            let p = mission.origin.to_enu(Geodetic {
                lat_deg,
                lon_deg,
                alt_m: home.alt_m + alt_above_home_m,
            });
            let moved_m = ((p.x_east_m - w.position.x_east_m).powi(2)
                + (p.y_north_m - w.position.y_north_m).powi(2)
                + (p.z_up_m - w.position.z_up_m).powi(2))
            .sqrt();
            moved_m <= 1e-3
                && r.hover_s.is_some_and(|h| (h - w.hover_s).abs() <= 1e-3)
                && r.kind == w.kind
                && r.actions.len() == w.actions.len()
                && r.actions.iter().zip(&w.actions).all(|((c, _), d)| {
                    c.command == d.command
                        && c.frame == d.frame
                        && same_params(&c.params, &d.params)
                })
        })
}

/// The mission as a QGroundControl plan: take-off to the origin, the waypoints in file order,
/// return to launch. Altitudes relative to home (frame 3). A block read from a complex item is
/// written as that complex item (its `Items` rewritten only when its waypoints changed); a
/// block written by hand in TOML has no complex item and is written as simple items.
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
    let mut id = 2;
    for c in &mission.start_actions {
        items.push(command_item(id, c));
        id += 1;
    }
    let mut k = 0;
    while k < mission.waypoints.len() {
        let complex = mission
            .block_of(k)
            .map(|b| &mission.blocks[b])
            .filter(|b| b.first == k)
            .and_then(|b| Some((b, b.source.as_ref()?)));
        if let Some((block, source)) = complex {
            let mut item = source.clone();
            let generated = block_items(mission, block, id);
            id += generated.len();
            if !unchanged(mission, block, source) {
                item["TransectStyleComplexItem"]["Items"] = Value::Array(generated);
            }
            items.push(item);
            k += block.len;
            continue;
        }
        for item in waypoint_items(mission, k, id) {
            items.push(item);
            id += 1;
        }
        k += 1;
    }
    items.push(simple_item(
        id,
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
    let mut doc = json!({
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
        "geoFence": geofence_json(mission),
        "rallyPoints": {
            "version": 2,
            "points": mission.rally.iter().map(|r| json!([r.lat_deg, r.lon_deg, r.alt_above_home_m])).collect::<Vec<_>>(),
        },
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
    let complex: Vec<Value> = mission
        .blocks
        .iter()
        .filter(|b| b.source.is_some())
        .map(|b| json!({ "name": b.name, "reversible": b.reversible }))
        .collect();
    if !complex.is_empty() {
        // The blocks written as complex items, in order: their names and directions.
        doc["emplan"]["blocks"] = Value::Array(complex);
    }
    let mut text = serde_json::to_string_pretty(&doc).unwrap_or_default();
    text.push('\n');
    text
}
