//! A `.plan` or `.waypoints` mission's items read as emplan's mission: the take-off gives the
//! origin's height; NAV_WAYPOINT, NAV_SPLINE_WAYPOINT and a NAV_LOITER_TIME at a place of its
//! own are waypoints; every other command belongs to the waypoint before it (to the start before
//! the first), in file order, as the autopilot runs it ([`super::actions`]): a NAV_DELAY, or a
//! NAV_LOITER_TIME where the waypoint already is, becomes a hold there. NAV_RETURN_TO_LAUNCH and
//! NAV_LAND end the flight (emplan writes its own ending). A command a reordered mission would
//! break is refused, naming the item.

use super::actions::{self, id, Command, Taken};
use super::{MissionError, Place, RawPosition, RawWaypoint, WaypointKind};

/// One mission item as a file gives it (latitude and longitude in degrees).
pub(super) struct Item {
    pub command: u64,
    pub frame: u64,
    pub params: [f64; 7],
    pub place: Place,
}

/// What the items hold.
pub(super) struct Sequence {
    pub height_above_home_m: Option<f64>,
    /// The waypoints, named by the caller.
    pub waypoints: Vec<RawWaypoint>,
    pub start_actions: Vec<(Command, Place)>,
}

/// A NAV_LOITER_TIME within this distance of the waypoint before it holds at that waypoint
/// (horizontally and vertically; the autopilots' acceptance radius is 2 m by default).
const SAME_PLACE_M: f64 = 1.0;

/// A navigation item's frame that emplan cannot place a waypoint in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
enum UnsupportedFrame {
    #[error("frame {0} (terrain-relative altitude) is not supported (allowed: 0, 3, 5, 6)")]
    Terrain(u64),
    #[error("frame {frame} is not supported for command {command} (allowed: 0, 3, 5, 6)")]
    Other { frame: u64, command: u64 },
}

/// The altitude above home of a navigation item's parameter 7 in `frame`.
fn altitude(command: u64, frame: u64, alt: f64, home_amsl_m: f64) -> Result<f64, UnsupportedFrame> {
    match frame {
        // MAV_FRAME_GLOBAL_RELATIVE_ALT (3) and its _INT twin (6).
        3 | 6 => Ok(alt),
        // MAV_FRAME_GLOBAL (0) and GLOBAL_INT (5): altitude above mean sea level.
        0 | 5 => Ok(alt - home_amsl_m),
        10 | 11 => Err(UnsupportedFrame::Terrain(frame)),
        _ => Err(UnsupportedFrame::Other { frame, command }),
    }
}

/// Reads `items` (home's altitude above mean sea level `home_amsl_m`).
pub(super) fn read(
    file: &str,
    items: Vec<Item>,
    home_amsl_m: f64,
) -> Result<Sequence, MissionError> {
    let bad = |place: &Place, problem: String| MissionError::invalid(file, place.clone(), problem);
    let mut height_above_home_m = None;
    let mut waypoints: Vec<RawWaypoint> = Vec::new();
    let mut start_actions = Vec::new();
    // Where the flight ended (RTL or LAND), if it did.
    let mut ended: Option<Place> = None;
    for item in items {
        let place = item.place;
        let command = u16::try_from(item.command).map_err(|_| {
            bad(
                &place,
                format!("command {} is not a MAV_CMD (at most 65535)", item.command),
            )
        })?;
        let p = item.params;
        let nav_alt = || altitude(item.command, item.frame, p[6], home_amsl_m);
        // What the item is: a waypoint of its own, or a command of the waypoint before it.
        let kind = match actions::take(command) {
            Taken::Refused(why) => {
                return Err(bad(
                    &place,
                    format!("command {command} is not supported: {why}"),
                ))
            }
            Taken::Navigation => match command {
                id::NAV_TAKEOFF => {
                    height_above_home_m = Some(nav_alt().map_err(|e| bad(&place, e.to_string()))?);
                    continue;
                }
                id::NAV_RETURN_TO_LAUNCH | id::NAV_LAND => {
                    ended.get_or_insert(place);
                    continue;
                }
                id::NAV_DELAY => None,
                id::NAV_LOITER_TIME => {
                    let at_last = match waypoints.last() {
                        _ if (p[4] == 0.0 && p[5] == 0.0) || p[4].is_nan() || p[5].is_nan() => true,
                        None => false,
                        Some(last) => {
                            let alt = nav_alt().map_err(|e| bad(&place, e.to_string()))?;
                            same_place(&last.position, p[4], p[5], alt)
                        }
                    };
                    (!at_last).then_some(WaypointKind::LoiterTime {
                        params: [p[1], p[2], p[3]],
                    })
                }
                id::NAV_SPLINE_WAYPOINT => Some(WaypointKind::Spline),
                _ => Some(WaypointKind::Waypoint),
            },
            Taken::Action | Taken::Unknown => {
                if matches!(item.frame, 10 | 11) {
                    return Err(bad(
                        &place,
                        format!(
                            "frame {} (terrain-relative altitude) is not supported (allowed: 0, 2, 3, 5, 6)",
                            item.frame
                        ),
                    ));
                }
                None
            }
        };
        if let Some(end) = &ended {
            let what = match kind {
                Some(_) => "a waypoint after the flight's end".to_string(),
                None => format!("command {command} after the flight's end"),
            };
            let never = if kind.is_some() { "flown" } else { "run" };
            return Err(bad(
                &place,
                format!("{what} ({}) is never {never}", describe(end)),
            ));
        }
        match kind {
            Some(kind) => {
                let alt = nav_alt().map_err(|e| bad(&place, e.to_string()))?;
                waypoints.push(waypoint(p, alt, kind, place));
            }
            None => {
                let frame = u8::try_from(item.frame)
                    .map_err(|_| bad(&place, format!("frame {} is not a MAV_FRAME", item.frame)))?;
                let c = Command {
                    command,
                    frame,
                    params: p,
                };
                match waypoints.last_mut() {
                    Some(w) => w.actions.push((c, place)),
                    None => start_actions.push((c, place)),
                }
            }
        }
    }
    Ok(Sequence {
        height_above_home_m,
        waypoints,
        start_actions,
    })
}

fn describe(place: &Place) -> String {
    match place {
        Place::File => "the file".into(),
        Place::Line(n) => format!("line {n}"),
        Place::Item(k) => format!("mission item {k}"),
        Place::Field(path) => path.clone(),
    }
}

fn waypoint(p: [f64; 7], alt_above_home_m: f64, kind: WaypointKind, place: Place) -> RawWaypoint {
    RawWaypoint {
        name: String::new(),
        position: RawPosition::Geodetic {
            lat_deg: p[4],
            lon_deg: p[5],
            alt_above_home_m,
        },
        hover_s: Some(if p[0].is_nan() { 0.0 } else { p[0] }),
        kind,
        actions: Vec::new(),
        place,
    }
}

/// Whether (lat, lon, alt above home) is within [`SAME_PLACE_M`] of a waypoint's position.
fn same_place(position: &RawPosition, lat_deg: f64, lon_deg: f64, alt_m: f64) -> bool {
    let RawPosition::Geodetic {
        lat_deg: a,
        lon_deg: b,
        alt_above_home_m: h,
    } = *position
    else {
        return false;
    };
    // A local flat-earth distance is exact enough at a metre.
    let north_m = (lat_deg - a) * 111_320.0;
    let east_m = (lon_deg - b) * 111_320.0 * a.to_radians().cos();
    north_m.hypot(east_m) <= SAME_PLACE_M && (alt_m - h).abs() <= SAME_PLACE_M
}
