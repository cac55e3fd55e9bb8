//! emplan's own mission format (TOML), documented in docs/mission-files.md. Unknown keys are errors;
//! every error names its line.
//!
//! A waypoint's actions are written readably: keys on the waypoint (`photo = true`,
//! `gimbal_pitch_deg = -90`, `yaw_deg = 90`, `speed_m_s = 8`, `roi = "mast"`, ...) run in a fixed
//! order ([`SHORTHAND_ORDER`]), then its `[[waypoints.actions]]` in the order written, each one
//! readable key or a raw command (`command`, `frame`, `params`). `roi` names a `[[pois]]` point of
//! interest (`roi = "none"` clears it). The writer uses the shorthand keys when they say exactly
//! what the waypoint carries, else the ordered list: nothing is lost.
//!
//! The geofence is `[[fence.polygons]]` (`inclusion`, and `vertices_deg = [[lat, lon], ...]`
//! or `vertices_m = [[x, y], ...]` east and north of the origin), `[[fence.circles]]`
//! (`inclusion`, `radius_m`, a centre as `lat_deg`/`lon_deg` or `x_m`/`y_m`) and an optional
//! `[fence.breach_return]`; the rally points are `[[rally_points]]`; a point is placed as a
//! waypoint is. The writer gives them all geodetically, as the fence is kept.

use serde::{Deserialize, Serialize};
use toml::Spanned;

use super::actions::{id, Command, FRAME_GLOBAL_RELATIVE_ALT, FRAME_MISSION};
use super::blocks::BlockKind;
use super::fence::{LatLon, RallyPoint, Shape, Zone};
use super::{
    line_of, Enu, Geodetic, Mission, MissionError, Origin, Place, Poi, RawBlock, RawMission,
    RawPosition, RawWaypoint, RawZone, WaypointKind, DEFAULT_MIN_HEIGHT_ABOVE_HOME_M,
};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileMission {
    name: Option<String>,
    default_hover_s: Option<f64>,
    min_height_above_home_m: Option<f64>,
    origin: Spanned<FileOrigin>,
    #[serde(default)]
    start_actions: Vec<Spanned<FileAction>>,
    #[serde(default)]
    pois: Vec<Spanned<FilePoi>>,
    #[serde(default)]
    waypoints: Vec<Spanned<FileWaypoint>>,
    fence: Option<FileFence>,
    #[serde(default)]
    rally_points: Vec<Spanned<FilePoint>>,
    #[serde(default)]
    blocks: Vec<Spanned<FileBlock>>,
}

/// A block: the waypoints that name it (`block = "NAME"`, contiguous in the file) flown whole,
/// and, for a block read from a QGroundControl `.plan`, its complex item as JSON (`qgc`), kept
/// to write the survey or scan back as QGroundControl reads it.
#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct FileBlock {
    name: String,
    reversible: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    qgc: Option<String>,
}

/// The geofence: its polygons, its circles and where ArduPilot returns to on a breach.
#[derive(Deserialize, Serialize, Default)]
#[serde(deny_unknown_fields)]
struct FileFence {
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    polygons: Vec<Spanned<FilePolygon>>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    circles: Vec<Spanned<FileCircle>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    breach_return: Option<Spanned<FilePoint>>,
}

/// A fence polygon: its vertices as latitude and longitude, or east and north of the origin.
#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct FilePolygon {
    inclusion: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    vertices_deg: Option<Vec<[f64; 2]>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    vertices_m: Option<Vec<[f64; 2]>>,
}

/// A fence circle: its radius and its centre (latitude and longitude, or east and north).
#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct FileCircle {
    inclusion: bool,
    radius_m: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    lat_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    lon_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    x_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    y_m: Option<f64>,
}

/// A rally point or a breach return point, placed as a waypoint is.
#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct FilePoint {
    #[serde(skip_serializing_if = "Option::is_none")]
    x_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    y_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    z_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    lat_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    lon_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    alt_above_home_m: Option<f64>,
}

/// A point of interest: a name and a position (ENU metres or latitude, longitude, altitude
/// above home).
#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct FilePoi {
    name: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    x_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    y_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    z_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    lat_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    lon_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    alt_above_home_m: Option<f64>,
}

/// The readable action keys, in the order a waypoint's shorthand keys run (the gimbal and the
/// region of interest before the photo they aim).
pub(super) const SHORTHAND_ORDER: [&str; 7] = [
    "speed_m_s",
    "roi",
    "trigger_distance_m",
    "gimbal_pitch_deg",
    "yaw_deg",
    "photo",
    "delay_s",
];

/// One action: one readable key (a gimbal may give its yaw with its pitch), or a raw command.
#[derive(Deserialize, Serialize, Default, Clone, PartialEq)]
#[serde(deny_unknown_fields)]
struct FileAction {
    #[serde(skip_serializing_if = "Option::is_none")]
    speed_m_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    roi: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    trigger_distance_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    gimbal_pitch_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    gimbal_yaw_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    yaw_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    photo: Option<bool>,
    #[serde(skip_serializing_if = "Option::is_none")]
    delay_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    command: Option<u16>,
    #[serde(skip_serializing_if = "Option::is_none")]
    frame: Option<u8>,
    #[serde(skip_serializing_if = "Option::is_none")]
    params: Option<Vec<f64>>,
}

#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct FileOrigin {
    lat_deg: f64,
    lon_deg: f64,
    home_alt_amsl_m: f64,
    height_above_home_m: f64,
}

#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct FileWaypoint {
    name: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    x_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    y_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    z_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    lat_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    lon_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    alt_above_home_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    hover_s: Option<f64>,
    /// `spline` (NAV_SPLINE_WAYPOINT) or `loiter` (NAV_LOITER_TIME); a plain waypoint by default.
    #[serde(skip_serializing_if = "Option::is_none")]
    kind: Option<String>,
    /// NAV_LOITER_TIME's parameters 2-4 (`kind = "loiter"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    loiter_params: Option<Vec<f64>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    speed_m_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    roi: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    trigger_distance_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    gimbal_pitch_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    gimbal_yaw_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    yaw_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    photo: Option<bool>,
    #[serde(skip_serializing_if = "Option::is_none")]
    delay_s: Option<f64>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    actions: Vec<FileAction>,
    /// The `[[blocks]]` block it belongs to.
    #[serde(skip_serializing_if = "Option::is_none")]
    block: Option<String>,
}

pub(super) fn parse(text: &str, file: &str) -> Result<RawMission, MissionError> {
    let parsed: FileMission = toml::from_str(text).map_err(|e| {
        let place = e
            .span()
            .map_or(Place::File, |s| Place::Line(line_of(text, s.start)));
        MissionError::invalid(file, place, e.message().trim().to_string())
    })?;
    let origin_place = Place::Line(line_of(text, parsed.origin.span().start));
    let origin = parsed.origin.into_inner();
    let frame = Origin {
        home: Geodetic {
            lat_deg: origin.lat_deg,
            lon_deg: origin.lon_deg,
            alt_m: origin.home_alt_amsl_m,
        },
        height_above_home_m: origin.height_above_home_m,
    };
    let mut pois = Vec::with_capacity(parsed.pois.len());
    for spanned in parsed.pois {
        let place = Place::Line(line_of(text, spanned.span().start));
        let p = spanned.into_inner();
        let what = format!("point of interest {:?}", p.name);
        let position = position(
            file,
            &place,
            &what,
            [p.x_m, p.y_m, p.z_m],
            [p.lat_deg, p.lon_deg, p.alt_above_home_m],
        )?;
        let (lat_deg, lon_deg, alt_above_home_m) = match position {
            RawPosition::Geodetic {
                lat_deg,
                lon_deg,
                alt_above_home_m,
            } => (lat_deg, lon_deg, alt_above_home_m),
            RawPosition::Enu(e) => {
                let g = frame.to_geodetic(e);
                (g.lat_deg, g.lon_deg, g.alt_m - frame.home.alt_m)
            }
        };
        if pois.iter().any(|q: &Poi| q.name == p.name) || p.name == "none" {
            return Err(MissionError::invalid(
                file,
                place,
                format!("{what}: the name is taken (names must be unique and not \"none\")"),
            ));
        }
        pois.push(Poi {
            name: p.name,
            lat_deg,
            lon_deg,
            alt_above_home_m,
        });
    }
    let mut start_actions = Vec::new();
    for spanned in parsed.start_actions {
        let place = Place::Line(line_of(text, spanned.span().start));
        let a = spanned.into_inner();
        start_actions.push((action(file, &place, "start_actions", &a, &pois)?, place));
    }
    let mut waypoints = Vec::with_capacity(parsed.waypoints.len());
    let mut block_names: Vec<Option<String>> = Vec::with_capacity(parsed.waypoints.len());
    for spanned in parsed.waypoints {
        let place = Place::Line(line_of(text, spanned.span().start));
        let w = spanned.into_inner();
        block_names.push(w.block.clone());
        let what = format!("waypoint {:?}", w.name);
        let mut actions = Vec::new();
        let keys = FileAction {
            speed_m_s: w.speed_m_s,
            roi: w.roi.clone(),
            trigger_distance_m: w.trigger_distance_m,
            gimbal_pitch_deg: w.gimbal_pitch_deg,
            gimbal_yaw_deg: w.gimbal_yaw_deg,
            yaw_deg: w.yaw_deg,
            photo: w.photo,
            delay_s: w.delay_s,
            ..FileAction::default()
        };
        for c in shorthand(file, &place, &what, &keys, &pois)? {
            actions.push((c, place.clone()));
        }
        for a in &w.actions {
            actions.push((action(file, &place, &what, a, &pois)?, place.clone()));
        }
        let kind = match (w.kind.as_deref(), &w.loiter_params) {
            (None | Some("waypoint"), None) => WaypointKind::Waypoint,
            (Some("spline"), None) => WaypointKind::Spline,
            (Some("loiter"), params) => {
                let p = params.clone().unwrap_or_default();
                if p.len() > 3 {
                    return Err(MissionError::invalid(
                        file,
                        place,
                        format!("{what}: loiter_params holds NAV_LOITER_TIME's params 2-4 (at most 3 numbers)"),
                    ));
                }
                let at = |k: usize| p.get(k).copied().unwrap_or(0.0);
                WaypointKind::LoiterTime {
                    params: [at(0), at(1), at(2)],
                }
            }
            (Some(other), None) if !matches!(other, "waypoint" | "spline" | "loiter") => {
                return Err(MissionError::invalid(
                    file,
                    place,
                    format!("{what}: kind {other:?} is not supported (allowed: \"waypoint\", \"spline\", \"loiter\")"),
                ));
            }
            _ => {
                return Err(MissionError::invalid(
                    file,
                    place,
                    format!("{what}: loiter_params needs kind = \"loiter\""),
                ));
            }
        };
        let position = position(
            file,
            &place,
            &what,
            [w.x_m, w.y_m, w.z_m],
            [w.lat_deg, w.lon_deg, w.alt_above_home_m],
        )?;
        waypoints.push(RawWaypoint {
            name: w.name,
            position,
            hover_s: w.hover_s,
            kind,
            actions,
            place,
        });
    }
    let fence = parsed.fence.unwrap_or_default();
    let mut zones = Vec::new();
    for spanned in fence.polygons {
        let place = Place::Line(line_of(text, spanned.span().start));
        let p = spanned.into_inner();
        let what = format!("fence polygon {}", zones.len() + 1);
        let (vertices, vertices_key) = match (p.vertices_deg, p.vertices_m) {
            (Some(deg), None) => (
                deg.iter()
                    .map(|&[lat_deg, lon_deg]| LatLon { lat_deg, lon_deg })
                    .collect(),
                "vertices_deg",
            ),
            (None, Some(m)) => {
                let mut vertices = Vec::with_capacity(m.len());
                for (k, &[x, y]) in m.iter().enumerate() {
                    vertices.push(local_lat_lon(
                        file,
                        &place,
                        &format!("{what} vertices_m[{k}]"),
                        &frame,
                        x,
                        y,
                    )?);
                }
                (vertices, "vertices_m")
            }
            _ => {
                return Err(MissionError::invalid(
                    file,
                    place,
                    format!("{what}: give exactly one of vertices_deg or vertices_m"),
                ))
            }
        };
        zones.push(RawZone {
            zone: Zone {
                inclusion: p.inclusion,
                shape: Shape::Polygon(vertices),
            },
            place,
            vertices_key,
        });
    }
    for spanned in fence.circles {
        let place = Place::Line(line_of(text, spanned.span().start));
        let c = spanned.into_inner();
        let what = format!("fence circle {}", zones.len() + 1);
        let center = match (c.lat_deg, c.lon_deg, c.x_m, c.y_m) {
            (Some(lat_deg), Some(lon_deg), None, None) => LatLon { lat_deg, lon_deg },
            (None, None, Some(x), Some(y)) => {
                local_lat_lon(file, &place, &format!("{what} center"), &frame, x, y)?
            }
            _ => {
                return Err(MissionError::invalid(
                    file,
                    place,
                    format!(
                        "{what}: its centre needs exactly one of (lat_deg, lon_deg) or (x_m, y_m)"
                    ),
                ))
            }
        };
        zones.push(RawZone {
            zone: Zone {
                inclusion: c.inclusion,
                shape: Shape::Circle {
                    center,
                    radius_m: c.radius_m,
                },
            },
            place,
            vertices_key: "vertices_deg",
        });
    }
    let breach_return = match fence.breach_return {
        Some(spanned) => {
            let place = Place::Line(line_of(text, spanned.span().start));
            let (lat_deg, lon_deg, alt_m) = point(
                file,
                &place,
                "fence breach_return",
                &frame,
                spanned.into_inner(),
            )?;
            Some((
                Geodetic {
                    lat_deg,
                    lon_deg,
                    alt_m,
                },
                place,
            ))
        }
        None => None,
    };
    let mut rally = Vec::with_capacity(parsed.rally_points.len());
    for spanned in parsed.rally_points {
        let place = Place::Line(line_of(text, spanned.span().start));
        let what = format!("rally point {}", rally.len() + 1);
        let (lat_deg, lon_deg, alt_above_home_m) =
            point(file, &place, &what, &frame, spanned.into_inner())?;
        rally.push((
            RallyPoint {
                lat_deg,
                lon_deg,
                alt_above_home_m,
            },
            place,
        ));
    }
    let blocks = blocks(file, text, parsed.blocks, &block_names, &waypoints)?;
    Ok(RawMission {
        blocks,
        name: parsed.name.unwrap_or_else(|| "mission".to_string()),
        home: Geodetic {
            lat_deg: origin.lat_deg,
            lon_deg: origin.lon_deg,
            alt_m: origin.home_alt_amsl_m,
        },
        height_above_home_m: origin.height_above_home_m,
        default_hover_s: parsed.default_hover_s.unwrap_or(0.0),
        min_height_above_home_m: parsed
            .min_height_above_home_m
            .unwrap_or(DEFAULT_MIN_HEIGHT_ABOVE_HOME_M),
        waypoints,
        start_actions,
        pois,
        zones,
        breach_return,
        rally,
        place: origin_place,
    })
}

/// The blocks: each `[[blocks]]` entry with the run of waypoints that name it. A block's
/// waypoints are contiguous (a name used again after other waypoints is refused), and every
/// name a waypoint gives is declared.
fn blocks(
    file: &str,
    text: &str,
    declared: Vec<Spanned<FileBlock>>,
    names: &[Option<String>],
    waypoints: &[RawWaypoint],
) -> Result<Vec<RawBlock>, MissionError> {
    // The runs of waypoints naming a block, in file order: (name, first, len).
    let mut runs: Vec<(String, usize, usize)> = Vec::new();
    for (k, name) in names.iter().enumerate() {
        let Some(name) = name else { continue };
        let w = &waypoints[k];
        if !declared.iter().any(|d| d.get_ref().name == *name) {
            return Err(MissionError::invalid(
                file,
                w.place.clone(),
                format!(
                    "waypoint {:?}: block {name:?} is not declared (add [[blocks]] with name = \
                     {name:?} and reversible = true or false)",
                    w.name
                ),
            ));
        }
        match runs.last_mut() {
            Some((last, first, len)) if last == name && *first + *len == k => *len += 1,
            _ => {
                if runs.iter().any(|(r, _, _)| r == name) {
                    return Err(MissionError::invalid(
                        file,
                        w.place.clone(),
                        format!(
                            "waypoint {:?}: block {name:?} is used again after other waypoints \
                             (a block's waypoints must follow each other in the file)",
                            w.name
                        ),
                    ));
                }
                runs.push((name.clone(), k, 1));
            }
        }
    }
    let mut out = Vec::with_capacity(declared.len());
    for spanned in declared {
        let place = Place::Line(line_of(text, spanned.span().start));
        let b = spanned.into_inner();
        let what = format!("block {:?}", b.name);
        let Some(&(_, first, len)) = runs.iter().find(|(r, _, _)| *r == b.name) else {
            return Err(MissionError::invalid(
                file,
                place,
                format!(
                    "{what}: no waypoint belongs to it (give its waypoints block = {:?})",
                    b.name
                ),
            ));
        };
        let (kind, source) = match &b.qgc {
            None => (BlockKind::Listed, None),
            Some(json) => {
                let value: serde_json::Value = serde_json::from_str(json).map_err(|e| {
                    MissionError::invalid(
                        file,
                        place.clone(),
                        format!("{what}: qgc is not valid JSON ({e})"),
                    )
                })?;
                let kind = match value.get("complexItemType").and_then(|v| v.as_str()) {
                    Some("survey") => BlockKind::Survey,
                    Some("CorridorScan") => BlockKind::Corridor,
                    other => {
                        return Err(MissionError::invalid(
                            file,
                            place,
                            format!(
                                "{what}: qgc's complexItemType {} is not supported (allowed: \
                                 \"survey\", \"CorridorScan\")",
                                other.map_or_else(|| "(none)".to_string(), |o| format!("{o:?}"))
                            ),
                        ))
                    }
                };
                (kind, Some(value))
            }
        };
        out.push(RawBlock {
            name: b.name,
            kind,
            first,
            len,
            reversible: b.reversible,
            source,
            place,
        });
    }
    out.sort_by_key(|b| b.first);
    Ok(out)
}

/// The latitude and longitude of the point `x` east and `y` north of the origin, at the height
/// of home (where a fence's vertices are).
fn local_lat_lon(
    file: &str,
    place: &Place,
    what: &str,
    frame: &Origin,
    x: f64,
    y: f64,
) -> Result<LatLon, MissionError> {
    super::finite(file, place, &format!("{what} x"), x)?;
    super::finite(file, place, &format!("{what} y"), y)?;
    let g = frame.to_geodetic(Enu {
        x_east_m: x,
        y_north_m: y,
        z_up_m: -frame.height_above_home_m,
    });
    Ok(LatLon {
        lat_deg: g.lat_deg,
        lon_deg: g.lon_deg,
    })
}

/// A rally or breach return point: latitude, longitude and altitude above home.
fn point(
    file: &str,
    place: &Place,
    what: &str,
    frame: &Origin,
    p: FilePoint,
) -> Result<(f64, f64, f64), MissionError> {
    match position(
        file,
        place,
        what,
        [p.x_m, p.y_m, p.z_m],
        [p.lat_deg, p.lon_deg, p.alt_above_home_m],
    )? {
        RawPosition::Geodetic {
            lat_deg,
            lon_deg,
            alt_above_home_m,
        } => Ok((lat_deg, lon_deg, alt_above_home_m)),
        RawPosition::Enu(e) => {
            super::finite(file, place, &format!("{what} x_m"), e.x_east_m)?;
            super::finite(file, place, &format!("{what} y_m"), e.y_north_m)?;
            super::finite(file, place, &format!("{what} z_m"), e.z_up_m)?;
            let g = frame.to_geodetic(e);
            Ok((g.lat_deg, g.lon_deg, g.alt_m - frame.home.alt_m))
        }
    }
}

/// A point as the writer gives it: geodetic.
fn file_point(lat_deg: f64, lon_deg: f64, alt_above_home_m: f64) -> FilePoint {
    FilePoint {
        x_m: None,
        y_m: None,
        z_m: None,
        lat_deg: Some(lat_deg),
        lon_deg: Some(lon_deg),
        alt_above_home_m: Some(alt_above_home_m),
    }
}

/// The fence as written: polygons and circles geodetically (None for no fence).
fn file_fence(mission: &Mission) -> Option<FileFence> {
    let fence = &mission.fence;
    if fence.is_empty() && fence.breach_return.is_none() {
        return None;
    }
    let mut out = FileFence::default();
    for zone in &fence.zones {
        match &zone.shape {
            Shape::Polygon(vertices) => out.polygons.push(Spanned::new(
                0..0,
                FilePolygon {
                    inclusion: zone.inclusion,
                    vertices_deg: Some(vertices.iter().map(|v| [v.lat_deg, v.lon_deg]).collect()),
                    vertices_m: None,
                },
            )),
            Shape::Circle { center, radius_m } => out.circles.push(Spanned::new(
                0..0,
                FileCircle {
                    inclusion: zone.inclusion,
                    radius_m: *radius_m,
                    lat_deg: Some(center.lat_deg),
                    lon_deg: Some(center.lon_deg),
                    x_m: None,
                    y_m: None,
                },
            )),
        }
    }
    out.breach_return = fence
        .breach_return
        .map(|g| Spanned::new(0..0, file_point(g.lat_deg, g.lon_deg, g.alt_m)));
    Some(out)
}

/// A position given as exactly one of (x_m, y_m, z_m) or (lat_deg, lon_deg, alt_above_home_m).
fn position(
    file: &str,
    place: &Place,
    what: &str,
    enu: [Option<f64>; 3],
    geo: [Option<f64>; 3],
) -> Result<RawPosition, MissionError> {
    match (enu, geo) {
        ([Some(x), Some(y), Some(z)], [None, None, None]) => Ok(RawPosition::Enu(Enu {
            x_east_m: x,
            y_north_m: y,
            z_up_m: z,
        })),
        ([None, None, None], [Some(lat_deg), Some(lon_deg), Some(alt_above_home_m)]) => {
            Ok(RawPosition::Geodetic {
                lat_deg,
                lon_deg,
                alt_above_home_m,
            })
        }
        _ => {
            let given: Vec<&str> = [
                "x_m",
                "y_m",
                "z_m",
                "lat_deg",
                "lon_deg",
                "alt_above_home_m",
            ]
            .into_iter()
            .zip(enu.iter().chain(geo.iter()))
            .filter(|(_, v)| v.is_some())
            .map(|(k, _)| k)
            .collect();
            Err(MissionError::invalid(
                file,
                place.clone(),
                format!(
                    "{what}: position needs exactly one of (x_m, y_m, z_m) or \
                     (lat_deg, lon_deg, alt_above_home_m); given: [{}]",
                    given.join(", ")
                ),
            ))
        }
    }
}

/// The command each readable key stands for (and back: [`readable`]).
fn photo() -> Command {
    // DO_DIGICAM_CONTROL, shoot (param5) 1: as QGroundControl writes "take photo" for ArduPilot.
    Command::new(id::DO_DIGICAM_CONTROL, [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
}
fn speed(v: f64) -> Command {
    // Speed type 1 (ground speed), no throttle change (-1).
    Command::new(id::DO_CHANGE_SPEED, [1.0, v, -1.0, 0.0, 0.0, 0.0, 0.0])
}
fn gimbal(pitch_deg: f64, yaw_deg: f64) -> Command {
    // Pitch, roll 0, yaw, MAV_MOUNT_MODE_MAVLINK_TARGETING (2) in param7: QGroundControl's form.
    Command::new(
        id::DO_MOUNT_CONTROL,
        [pitch_deg, 0.0, yaw_deg, 0.0, 0.0, 0.0, 2.0],
    )
}
fn yaw(deg: f64) -> Command {
    // Absolute heading, the autopilot's rate (0), the shortest way (0).
    Command::new(id::CONDITION_YAW, [deg, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
}
fn trigger(m: f64) -> Command {
    Command::new(id::DO_SET_CAM_TRIGG_DIST, [m, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
}
fn delay(s: f64) -> Command {
    // Hour, minute and second of day unused (-1).
    Command::new(id::NAV_DELAY, [s, -1.0, -1.0, -1.0, 0.0, 0.0, 0.0])
}
fn roi_none() -> Command {
    Command::new(id::DO_SET_ROI_NONE, [0.0; 7])
}
fn roi_at(p: &Poi) -> Command {
    Command {
        command: id::DO_SET_ROI_LOCATION,
        frame: FRAME_GLOBAL_RELATIVE_ALT,
        params: [0.0, 0.0, 0.0, 0.0, p.lat_deg, p.lon_deg, p.alt_above_home_m],
    }
}

/// The commands of a waypoint's shorthand keys, in [`SHORTHAND_ORDER`].
fn shorthand(
    file: &str,
    place: &Place,
    what: &str,
    a: &FileAction,
    pois: &[Poi],
) -> Result<Vec<Command>, MissionError> {
    if a.command.is_some() || a.frame.is_some() || a.params.is_some() {
        return Err(MissionError::invalid(
            file,
            place.clone(),
            format!("{what}: a raw command goes in [[waypoints.actions]] (command, frame, params)"),
        ));
    }
    if a.gimbal_yaw_deg.is_some() && a.gimbal_pitch_deg.is_none() {
        return Err(MissionError::invalid(
            file,
            place.clone(),
            format!("{what}: gimbal_yaw_deg needs gimbal_pitch_deg"),
        ));
    }
    let mut out = Vec::new();
    if let Some(v) = a.speed_m_s {
        out.push(speed(positive(file, place, what, "speed_m_s", v)?));
    }
    if let Some(name) = &a.roi {
        out.push(roi(file, place, what, name, pois)?);
    }
    if let Some(m) = a.trigger_distance_m {
        out.push(trigger(non_negative(
            file,
            place,
            what,
            "trigger_distance_m",
            m,
        )?));
    }
    if let Some(p) = a.gimbal_pitch_deg {
        out.push(gimbal(p, a.gimbal_yaw_deg.unwrap_or(0.0)));
    }
    if let Some(d) = a.yaw_deg {
        out.push(yaw(d));
    }
    if a.photo == Some(true) {
        out.push(photo());
    }
    if let Some(s) = a.delay_s {
        out.push(delay(non_negative(file, place, what, "delay_s", s)?));
    }
    Ok(out)
}

fn positive(file: &str, place: &Place, what: &str, key: &str, v: f64) -> Result<f64, MissionError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(MissionError::invalid(
            file,
            place.clone(),
            format!("{what}: {key} {v} is not allowed (a positive number is required)"),
        ))
    }
}

fn non_negative(
    file: &str,
    place: &Place,
    what: &str,
    key: &str,
    v: f64,
) -> Result<f64, MissionError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(MissionError::invalid(
            file,
            place.clone(),
            format!("{what}: {key} {v} is not allowed (0 or more is required)"),
        ))
    }
}

fn roi(
    file: &str,
    place: &Place,
    what: &str,
    name: &str,
    pois: &[Poi],
) -> Result<Command, MissionError> {
    if name == "none" {
        return Ok(roi_none());
    }
    pois.iter().find(|p| p.name == name).map(roi_at).ok_or_else(|| {
        let known: Vec<&str> = pois.iter().map(|p| p.name.as_str()).collect();
        MissionError::invalid(
            file,
            place.clone(),
            format!(
                "{what}: roi {name:?} names no point of interest (defined in [[pois]]: [{}]; \"none\" clears it)",
                known.join(", ")
            ),
        )
    })
}

/// One `[[...actions]]` entry: exactly one action.
fn action(
    file: &str,
    place: &Place,
    what: &str,
    a: &FileAction,
    pois: &[Poi],
) -> Result<Command, MissionError> {
    if let Some(command) = a.command {
        let readable = FileAction {
            command: None,
            frame: None,
            params: None,
            ..a.clone()
        };
        if readable != FileAction::default() {
            return Err(MissionError::invalid(
                file,
                place.clone(),
                format!("{what}: an action is one readable key or one raw command, not both"),
            ));
        }
        let given = a.params.clone().unwrap_or_default();
        if given.len() > 7 {
            return Err(MissionError::invalid(
                file,
                place.clone(),
                format!("{what}: command {command} params: at most 7 numbers"),
            ));
        }
        let mut params = [0.0; 7];
        params[..given.len()].copy_from_slice(&given);
        return Ok(Command {
            command,
            frame: a.frame.unwrap_or(FRAME_MISSION),
            params,
        });
    }
    if a.frame.is_some() || a.params.is_some() {
        return Err(MissionError::invalid(
            file,
            place.clone(),
            format!("{what}: frame and params belong to a raw command (command = N)"),
        ));
    }
    let mut commands = shorthand(file, place, what, a, pois)?;
    match (commands.pop(), commands.is_empty()) {
        (Some(c), true) => Ok(c),
        (None, _) => Err(MissionError::invalid(
            file,
            place.clone(),
            format!(
                "{what}: an empty action (give one of {} or command)",
                SHORTHAND_ORDER.join(", ")
            ),
        )),
        (Some(_), false) => Err(MissionError::invalid(
            file,
            place.clone(),
            format!("{what}: one action per [[...actions]] entry (list them in order)"),
        )),
    }
}

/// The readable key a command is written as, when it is exactly that key's command.
fn readable(c: &Command, pois: &[Poi]) -> Option<(&'static str, FileAction)> {
    let p = &c.params;
    let candidates: [(&str, Option<FileAction>); 7] = [
        (
            "speed_m_s",
            (*c == speed(p[1])).then(|| FileAction {
                speed_m_s: Some(p[1]),
                ..FileAction::default()
            }),
        ),
        ("roi", {
            let named = pois
                .iter()
                .find(|poi| roi_at(poi) == *c)
                .map(|poi| poi.name.clone());
            let none = (*c == roi_none()).then(|| "none".to_string());
            named.or(none).map(|name| FileAction {
                roi: Some(name),
                ..FileAction::default()
            })
        }),
        (
            "trigger_distance_m",
            (*c == trigger(p[0])).then(|| FileAction {
                trigger_distance_m: Some(p[0]),
                ..FileAction::default()
            }),
        ),
        (
            "gimbal_pitch_deg",
            (*c == gimbal(p[0], p[2])).then(|| FileAction {
                gimbal_pitch_deg: Some(p[0]),
                gimbal_yaw_deg: (p[2] != 0.0).then_some(p[2]),
                ..FileAction::default()
            }),
        ),
        (
            "yaw_deg",
            (*c == yaw(p[0])).then(|| FileAction {
                yaw_deg: Some(p[0]),
                ..FileAction::default()
            }),
        ),
        (
            "photo",
            (*c == photo()).then(|| FileAction {
                photo: Some(true),
                ..FileAction::default()
            }),
        ),
        (
            "delay_s",
            (*c == delay(p[0])).then(|| FileAction {
                delay_s: Some(p[0]),
                ..FileAction::default()
            }),
        ),
    ];
    candidates
        .into_iter()
        .find_map(|(key, a)| a.map(|a| (key, a)))
}

/// A command as an `[[...actions]]` entry: its readable key, else raw.
fn file_action(c: &Command, pois: &[Poi]) -> FileAction {
    readable(c, pois).map_or_else(
        || FileAction {
            command: Some(c.command),
            frame: Some(c.frame),
            params: Some(c.params.to_vec()),
            ..FileAction::default()
        },
        |(_, a)| a,
    )
}

/// The waypoint's actions as shorthand keys, when they are each a readable key, at most once
/// each, in [`SHORTHAND_ORDER`]: read back, they give the same commands in the same order.
fn as_shorthand(actions: &[Command], pois: &[Poi]) -> Option<FileAction> {
    let mut merged = FileAction::default();
    let mut last = None;
    for c in actions {
        let (key, a) = readable(c, pois)?;
        let rank = SHORTHAND_ORDER.iter().position(|k| *k == key)?;
        if last.is_some_and(|l| rank <= l) {
            return None;
        }
        last = Some(rank);
        merged = FileAction {
            speed_m_s: merged.speed_m_s.or(a.speed_m_s),
            roi: merged.roi.or(a.roi),
            trigger_distance_m: merged.trigger_distance_m.or(a.trigger_distance_m),
            gimbal_pitch_deg: merged.gimbal_pitch_deg.or(a.gimbal_pitch_deg),
            gimbal_yaw_deg: merged.gimbal_yaw_deg.or(a.gimbal_yaw_deg),
            yaw_deg: merged.yaw_deg.or(a.yaw_deg),
            photo: merged.photo.or(a.photo),
            delay_s: merged.delay_s.or(a.delay_s),
            ..FileAction::default()
        };
    }
    Some(merged)
}

/// Names for the regions of interest the actions look at that no point of interest names yet
/// (`roi1`, `roi2`, ...), so that the TOML says `roi = "roi1"` rather than a raw command.
fn named_pois(mission: &Mission) -> Vec<Poi> {
    let mut pois = mission.pois.clone();
    let all = mission
        .start_actions
        .iter()
        .chain(mission.waypoints.iter().flat_map(|w| w.actions.iter()));
    for c in all {
        let p = &c.params;
        let candidate = |name: String| Poi {
            name,
            lat_deg: p[4],
            lon_deg: p[5],
            alt_above_home_m: p[6],
        };
        if roi_at(&candidate(String::new())) != *c || pois.iter().any(|q| roi_at(q) == *c) {
            continue;
        }
        let mut k = pois.len() + 1;
        while pois.iter().any(|q| q.name == format!("roi{k}")) {
            k += 1;
        }
        pois.push(candidate(format!("roi{k}")));
    }
    pois
}

#[derive(Serialize)]
struct WriteMission<'a> {
    name: &'a str,
    default_hover_s: f64,
    min_height_above_home_m: f64,
    origin: FileOrigin,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    start_actions: Vec<FileAction>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pois: Vec<FilePoi>,
    waypoints: Vec<FileWaypoint>,
    #[serde(skip_serializing_if = "Option::is_none")]
    fence: Option<FileFence>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    rally_points: Vec<FilePoint>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    blocks: Vec<FileBlock>,
}

/// The mission as emplan TOML, waypoints in local ENU metres (full precision).
pub(super) fn write(mission: &Mission) -> Result<String, MissionError> {
    let pois = named_pois(mission);
    let doc = WriteMission {
        name: &mission.name,
        default_hover_s: mission.default_hover_s,
        min_height_above_home_m: mission.min_height_above_home_m,
        origin: FileOrigin {
            lat_deg: mission.origin.home.lat_deg,
            lon_deg: mission.origin.home.lon_deg,
            home_alt_amsl_m: mission.origin.home.alt_m,
            height_above_home_m: mission.origin.height_above_home_m,
        },
        start_actions: mission
            .start_actions
            .iter()
            .map(|c| file_action(c, &pois))
            .collect(),
        pois: pois
            .iter()
            .map(|p| FilePoi {
                name: p.name.clone(),
                x_m: None,
                y_m: None,
                z_m: None,
                lat_deg: Some(p.lat_deg),
                lon_deg: Some(p.lon_deg),
                alt_above_home_m: Some(p.alt_above_home_m),
            })
            .collect(),
        waypoints: mission
            .waypoints
            .iter()
            .enumerate()
            .map(|(k, w)| {
                let (shorthand, actions) = match as_shorthand(&w.actions, &pois) {
                    Some(s) => (s, Vec::new()),
                    None => (
                        FileAction::default(),
                        w.actions.iter().map(|c| file_action(c, &pois)).collect(),
                    ),
                };
                let (kind, loiter_params) = match w.kind {
                    WaypointKind::Waypoint => (None, None),
                    WaypointKind::Spline => (Some("spline".to_string()), None),
                    WaypointKind::LoiterTime { params } => {
                        (Some("loiter".to_string()), Some(params.to_vec()))
                    }
                };
                FileWaypoint {
                    name: w.name.clone(),
                    x_m: Some(w.position.x_east_m),
                    y_m: Some(w.position.y_north_m),
                    z_m: Some(w.position.z_up_m),
                    lat_deg: None,
                    lon_deg: None,
                    alt_above_home_m: None,
                    hover_s: Some(w.hover_s),
                    kind,
                    loiter_params,
                    speed_m_s: shorthand.speed_m_s,
                    roi: shorthand.roi,
                    trigger_distance_m: shorthand.trigger_distance_m,
                    gimbal_pitch_deg: shorthand.gimbal_pitch_deg,
                    gimbal_yaw_deg: shorthand.gimbal_yaw_deg,
                    yaw_deg: shorthand.yaw_deg,
                    photo: shorthand.photo,
                    delay_s: shorthand.delay_s,
                    actions,
                    block: mission.block_of(k).map(|b| mission.blocks[b].name.clone()),
                }
            })
            .collect(),
        fence: file_fence(mission),
        rally_points: mission
            .rally
            .iter()
            .map(|r| file_point(r.lat_deg, r.lon_deg, r.alt_above_home_m))
            .collect(),
        blocks: mission
            .blocks
            .iter()
            .map(|b| FileBlock {
                name: b.name.clone(),
                reversible: b.reversible,
                qgc: b
                    .source
                    .as_ref()
                    .and_then(|v| serde_json::to_string_pretty(v).ok()),
            })
            .collect(),
    };
    toml::to_string(&doc).map_err(|e| {
        MissionError::invalid(
            &mission.name,
            Place::File,
            format!("cannot be written as TOML: {e}"),
        )
    })
}
