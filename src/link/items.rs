//! Mission items from a mission and a visiting order: optional NAV_TAKEOFF to the origin height,
//! one NAV_WAYPOINT per waypoint (latitude/longitude as degE7, altitude relative to home, param1
//! hover seconds, param2 acceptance radius), optional DO_CHANGE_SPEED, and the ending: by
//! default a NAV_WAYPOINT back at the origin hover point, then NAV_LAND there (the return leg
//! and the landing the plan priced: PX4's RTL would first climb to RTL_RETURN_ALT, which is not
//! the planned leg); NAV_RETURN_TO_LAUNCH or a bare NAV_LAND on request. Frames PX4 accepts: GLOBAL_RELATIVE_ALT (3) for navigation items,
//! MISSION (2) for commands (PX4's mission item checks; docs/mavlink.md). ArduPilot
//! gets its home item at seq 0.

use super::mav::{MavCmd, MavFrame, MavMissionType, MISSION_ITEM_INT_DATA};
use super::Flavour;
use crate::mission::{Enu, Geodetic, Mission, Origin};

/// How a mission ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ending {
    /// Fly the return leg to the origin hover point as a waypoint (hold 0), then land there:
    /// what the plan prices (the return leg, then the landing (0, -h)).
    ReturnAndLand,
    ReturnToLaunch,
    Land,
}

/// Options for building items.
#[derive(Debug, Clone, PartialEq)]
pub struct ItemOptions {
    pub flavour: Flavour,
    pub takeoff: bool,
    pub acceptance_radius_m: f32,
    /// Cruise speed to command with DO_CHANGE_SPEED before the first waypoint, if any.
    pub cruise_speed_m_s: Option<f32>,
    pub ending: Ending,
}

impl Default for ItemOptions {
    fn default() -> Self {
        ItemOptions {
            flavour: Flavour::Px4,
            takeoff: true,
            acceptance_radius_m: 2.0,
            cruise_speed_m_s: None,
            ending: Ending::ReturnAndLand,
        }
    }
}

/// Degrees to MAVLink's degE7 integers (round to nearest).
pub fn deg_e7(deg: f64) -> i32 {
    (deg * 1e7).round() as i32
}

/// One mission item (seq 0, autocontinue, mission type MISSION; numbered by the caller).
pub fn item(
    command: MavCmd,
    frame: MavFrame,
    params: [f32; 4],
    x: i32,
    y: i32,
    z: f32,
) -> MISSION_ITEM_INT_DATA {
    MISSION_ITEM_INT_DATA {
        param1: params[0],
        param2: params[1],
        param3: params[2],
        param4: params[3],
        x,
        y,
        z,
        seq: 0,
        command,
        target_system: 0,
        target_component: 0,
        frame,
        current: 0,
        autocontinue: 1,
        mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
    }
}

/// A mission item from the numbers a flight controller logs of it (ArduPilot's CMD records:
/// MAV_CMD, MAV_FRAME, the four parameters, degrees and metres as the frame gives them); None for
/// a command or frame this MAVLink dialect does not know.
pub fn item_from_numbers(
    seq: u16,
    command: u16,
    frame: u8,
    params: [f32; 4],
    lat_deg: f64,
    lon_deg: f64,
    alt_m: f64,
) -> Option<MISSION_ITEM_INT_DATA> {
    use num_traits::FromPrimitive;
    let e7 = |deg: f64| {
        let v = (deg * 1e7).round();
        (v.is_finite() && v.abs() <= f64::from(i32::MAX)).then_some(v as i32)
    };
    Some(MISSION_ITEM_INT_DATA {
        seq,
        ..item(
            MavCmd::from_u16(command)?,
            MavFrame::from_u8(frame)?,
            params,
            e7(lat_deg)?,
            e7(lon_deg)?,
            alt_m as f32,
        )
    })
}

/// The items that fly `mission` in `order` (indices into `mission.waypoints`), numbered from 0.
/// Returns None when `order` names a waypoint the mission does not have.
pub fn mission_items(
    mission: &Mission,
    order: &[usize],
    opts: &ItemOptions,
) -> Option<Vec<MISSION_ITEM_INT_DATA>> {
    let home = mission.origin.home;
    let (lat, lon) = (deg_e7(home.lat_deg), deg_e7(home.lon_deg));
    let relative = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT;
    let mut items = Vec::new();
    if opts.flavour == Flavour::ArduPilot {
        // ArduPilot's seq 0 is home (AMSL), overwritten by the vehicle's own home.
        items.push(item(
            MavCmd::MAV_CMD_NAV_WAYPOINT,
            MavFrame::MAV_FRAME_GLOBAL,
            [0.0; 4],
            lat,
            lon,
            home.alt_m as f32,
        ));
    }
    if opts.takeoff {
        items.push(item(
            MavCmd::MAV_CMD_NAV_TAKEOFF,
            relative,
            [0.0, 0.0, 0.0, f32::NAN],
            lat,
            lon,
            mission.origin.height_above_home_m as f32,
        ));
    }
    if let Some(speed) = opts.cruise_speed_m_s {
        // param1 1 = ground speed, param2 speed, param3 -1 = no throttle change.
        items.push(item(
            MavCmd::MAV_CMD_DO_CHANGE_SPEED,
            MavFrame::MAV_FRAME_MISSION,
            [1.0, speed, -1.0, 0.0],
            0,
            0,
            0.0,
        ));
    }
    for &k in order {
        let (wlat, wlon, alt) = mission.waypoint_relative(k)?;
        let hover = mission.waypoints[k].hover_s as f32;
        items.push(item(
            MavCmd::MAV_CMD_NAV_WAYPOINT,
            relative,
            [hover, opts.acceptance_radius_m, 0.0, f32::NAN],
            deg_e7(wlat),
            deg_e7(wlon),
            alt as f32,
        ));
    }
    if opts.ending == Ending::ReturnAndLand {
        items.push(item(
            MavCmd::MAV_CMD_NAV_WAYPOINT,
            relative,
            [0.0, opts.acceptance_radius_m, 0.0, f32::NAN],
            lat,
            lon,
            mission.origin.height_above_home_m as f32,
        ));
    }
    items.push(match opts.ending {
        Ending::ReturnToLaunch => item(
            MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH,
            MavFrame::MAV_FRAME_MISSION,
            [0.0; 4],
            0,
            0,
            0.0,
        ),
        Ending::Land | Ending::ReturnAndLand => item(
            MavCmd::MAV_CMD_NAV_LAND,
            relative,
            [0.0, 0.0, 0.0, f32::NAN],
            lat,
            lon,
            0.0,
        ),
    });
    for (seq, it) in items.iter_mut().enumerate() {
        it.seq = seq as u16;
    }
    Some(items)
}

/// An item as JSON: MISSION_ITEM_INT fields, frame and command as MAVLink numbers, x/y in
/// degE7, NaN params as null (what `upload --json` and `download` write).
pub fn item_json(item: &MISSION_ITEM_INT_DATA) -> serde_json::Value {
    serde_json::json!({
        "seq": item.seq,
        "frame": item.frame as u32,
        "command": item.command as u32,
        "current": item.current,
        "autocontinue": item.autocontinue,
        "param1": item.param1,
        "param2": item.param2,
        "param3": item.param3,
        "param4": item.param4,
        "x": item.x,
        "y": item.y,
        "z": item.z,
    })
}

/// Why mission items could not be read as a flight.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReadItemsError {
    #[error("the mission has no NAV_TAKEOFF: emplan measures flights that take off from the origin (items {0})")]
    NoTakeoff(String),
    #[error("the mission visits no waypoint after its take-off")]
    NoWaypoints,
    #[error("item {seq}: {what}")]
    Item { seq: u16, what: String },
}

/// A mission as the autopilot holds it, read as a flight.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightItems {
    pub home: Geodetic,
    pub origin_height_m: f64,
    pub takeoff_seq: u16,
    /// (seq, position in the origin frame, hold s) of every waypoint after the take-off.
    pub points: Vec<(u16, Enu, f64)>,
    /// The photos each point takes (one per point, in `points`' order): the photo commands
    /// that follow its waypoint item before the next navigation item (see [`read_flight`]).
    pub photos: Vec<u32>,
    pub land_seq: Option<u16>,
}

fn degrees(e7: i32) -> f64 {
    f64::from(e7) / 1e7
}

/// Reads `items` (held by an autopilot of `flavour`) as a flight: the layout [`mission_items`]
/// uploads ([home at seq 0 on ArduPilot] NAV_TAKEOFF to the origin height, the waypoints, a
/// NAV_WAYPOINT back at the origin, NAV_LAND) or any other read as far as it goes: the take-off's
/// position and altitude give the origin, every NAV_WAYPOINT after it is a point, the first
/// landing or RTL ends the flight. The home altitude (AMSL) is
/// ArduPilot's home item when there is one, else `home_alt_m` (what only the geometry of the
/// positions needs: altitudes are relative to home).
///
/// The photo commands after a waypoint item, up to the next navigation item (a MAV_CMD below
/// MAV_CMD_NAV_LAST, 95: ArduPilot `AP_Mission::is_nav_cmd`), are its photos, taken as the
/// autopilot leaves it: DO_DIGICAM_CONTROL with its shoot parameter (param5, MISSION_ITEM_INT
/// `x`, read as an integer by ArduPilot `AP_Mission::mavlink_int_to_mission_cmd` and PX4) 1,
/// one photo; IMAGE_START_CAPTURE with no interval (param2 0) and a number of images (param3)
/// of one or more, that many. A capture at an interval is a series in time, not photos of the
/// point, and is not counted.
pub fn read_flight(
    items: &[MISSION_ITEM_INT_DATA],
    flavour: Flavour,
    home_alt_m: f64,
) -> Result<FlightItems, ReadItemsError> {
    let summary = || {
        items
            .iter()
            .map(|i| format!("{}:{:?}", i.seq, i.command))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let takeoff = items
        .iter()
        .find(|i| i.command == MavCmd::MAV_CMD_NAV_TAKEOFF)
        .ok_or_else(|| ReadItemsError::NoTakeoff(summary()))?;
    let home_item = (flavour == Flavour::ArduPilot)
        .then(|| items.iter().find(|i| i.seq == 0))
        .flatten();
    let home = Geodetic {
        lat_deg: degrees(takeoff.x),
        lon_deg: degrees(takeoff.y),
        alt_m: home_item.map_or(home_alt_m, |h| f64::from(h.z)),
    };
    #[allow(deprecated)]
    let relative = |i: &MISSION_ITEM_INT_DATA| {
        matches!(
            i.frame,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        )
    };
    if !relative(takeoff) {
        return Err(ReadItemsError::Item {
            seq: takeoff.seq,
            what: format!(
                "take-off in frame {:?}: only altitudes relative to home are read",
                takeoff.frame
            ),
        });
    }
    let origin = Origin {
        home,
        height_above_home_m: f64::from(takeoff.z),
    };
    let mut points = Vec::new();
    let mut photos: Vec<u32> = Vec::new();
    // The point the photo commands seen now belong to: the last waypoint, until another
    // navigation item.
    let mut photos_of: Option<usize> = None;
    let mut land_seq = None;
    for item in items.iter().filter(|i| i.seq > takeoff.seq) {
        let taken = match item.command {
            MavCmd::MAV_CMD_DO_DIGICAM_CONTROL => u32::from(item.x == 1),
            MavCmd::MAV_CMD_IMAGE_START_CAPTURE
                if item.param2 == 0.0 && item.param3 >= 1.0 && item.param3.is_finite() =>
            {
                item.param3.min(u32::MAX as f32) as u32
            }
            _ => 0,
        };
        if let Some(count) = photos_of.and_then(|k| photos.get_mut(k)) {
            *count = count.saturating_add(taken);
        }
        if (item.command as u32) < MavCmd::MAV_CMD_NAV_LAST as u32 {
            photos_of = None;
        }
        match item.command {
            MavCmd::MAV_CMD_NAV_WAYPOINT => {
                if !relative(item) {
                    return Err(ReadItemsError::Item {
                        seq: item.seq,
                        what: format!(
                            "waypoint in frame {:?}: only altitudes relative to home are read",
                            item.frame
                        ),
                    });
                }
                let enu = origin.to_enu(Geodetic {
                    lat_deg: degrees(item.x),
                    lon_deg: degrees(item.y),
                    alt_m: home.alt_m + f64::from(item.z),
                });
                points.push((item.seq, enu, f64::from(item.param1.max(0.0))));
                photos.push(0);
                photos_of = Some(points.len() - 1);
            }
            MavCmd::MAV_CMD_NAV_LAND | MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => {
                land_seq = Some(item.seq);
                break;
            }
            _ => {}
        }
    }
    if points.is_empty() {
        return Err(ReadItemsError::NoWaypoints);
    }
    Ok(FlightItems {
        home,
        origin_height_m: origin.height_above_home_m,
        takeoff_seq: takeoff.seq,
        points,
        photos,
        land_seq,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::{load, Format};

    fn sample() -> Mission {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/paper-sample-3wp.toml");
        let _ = Format::Toml;
        load(&path).unwrap()
    }

    #[test]
    fn px4_items_are_takeoff_waypoints_in_order_then_the_origin_and_a_landing_there() {
        let m = sample();
        let items = mission_items(&m, &[2, 0, 1], &ItemOptions::default()).unwrap();
        assert_eq!(items.len(), 6);
        assert_eq!(items[0].command, MavCmd::MAV_CMD_NAV_TAKEOFF);
        assert_eq!(items[0].z, 30.0);
        let (lat, lon, alt) = m.waypoint_relative(2).unwrap();
        assert_eq!((items[1].x, items[1].y), (deg_e7(lat), deg_e7(lon)));
        assert!((items[1].z as f64 - alt).abs() < 1e-3 && (alt - 54.0).abs() < 0.01);
        assert_eq!(items[1].param1, 5.0);
        // The return leg ends at the origin hover point (hold 0), then the landing there.
        let home = m.origin.home;
        assert_eq!(items[4].command, MavCmd::MAV_CMD_NAV_WAYPOINT);
        assert_eq!(
            (items[4].x, items[4].y, items[4].z, items[4].param1),
            (deg_e7(home.lat_deg), deg_e7(home.lon_deg), 30.0, 0.0)
        );
        assert_eq!(items[5].command, MavCmd::MAV_CMD_NAV_LAND);
        assert_eq!((items[5].x, items[5].y), (items[4].x, items[4].y));
        assert!(items.iter().enumerate().all(|(k, it)| it.seq as usize == k));
        assert!(items
            .iter()
            .all(|it| it.frame == MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT));
    }

    #[test]
    fn return_to_launch_ends_with_one_rtl_item_in_the_mission_frame() {
        let opts = ItemOptions {
            ending: Ending::ReturnToLaunch,
            ..ItemOptions::default()
        };
        let items = mission_items(&sample(), &[2, 0, 1], &opts).unwrap();
        assert_eq!(items.len(), 5);
        assert_eq!(items[4].command, MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH);
        assert_eq!(items[4].frame, MavFrame::MAV_FRAME_MISSION);
    }

    #[test]
    fn ardupilot_gets_its_home_item_at_seq_zero() {
        let m = sample();
        let opts = ItemOptions {
            flavour: Flavour::ArduPilot,
            cruise_speed_m_s: Some(5.0),
            ending: Ending::Land,
            ..ItemOptions::default()
        };
        let items = mission_items(&m, &[0, 1, 2], &opts).unwrap();
        assert_eq!(items[0].frame, MavFrame::MAV_FRAME_GLOBAL);
        assert_eq!(items[0].z, 16.0);
        assert_eq!(items[1].command, MavCmd::MAV_CMD_NAV_TAKEOFF);
        assert_eq!(items[2].command, MavCmd::MAV_CMD_DO_CHANGE_SPEED);
        assert_eq!(items.last().unwrap().command, MavCmd::MAV_CMD_NAV_LAND);
        assert_eq!(items.len(), 7);
    }

    #[test]
    fn the_photo_commands_after_a_waypoint_up_to_the_next_navigation_item_are_its_photos() {
        let m = sample();
        let items = mission_items(&m, &[0, 1, 2], &ItemOptions::default()).unwrap();
        let command = |command: MavCmd, params: [f32; 4], x: i32| {
            item(command, MavFrame::MAV_FRAME_MISSION, params, x, 0, 0.0)
        };
        let digicam = |shoot: i32| command(MavCmd::MAV_CMD_DO_DIGICAM_CONTROL, [0.0; 4], shoot);
        let capture = |interval_s: f32, images: f32| {
            command(
                MavCmd::MAV_CMD_IMAGE_START_CAPTURE,
                [0.0, interval_s, images, 0.0],
                0,
            )
        };
        let delay = command(MavCmd::MAV_CMD_NAV_DELAY, [2.0, -1.0, -1.0, -1.0], 0);
        // take-off, A, a photo; B, a photo, a capture of one image, a shoot 0; C, a delay, a
        // photo (after the delay: not C's); the origin, a capture of 3 images at once and a
        // series at an interval (no photo of the point); the landing.
        let mut with = vec![items[0].clone(), items[1].clone(), digicam(1)];
        with.extend([items[2].clone(), digicam(1), capture(0.0, 1.0), digicam(0)]);
        with.extend([items[3].clone(), delay, digicam(1)]);
        with.extend([items[4].clone(), capture(0.0, 3.0), capture(2.0, 5.0)]);
        with.push(items[5].clone());
        for (seq, it) in with.iter_mut().enumerate() {
            it.seq = seq as u16;
        }
        let read = read_flight(&with, Flavour::Px4, m.origin.home.alt_m).unwrap();
        assert_eq!(read.points.len(), 4);
        assert_eq!(read.photos, [1, 2, 0, 3]);
        // Without photo commands, none.
        let plain = read_flight(&items, Flavour::Px4, m.origin.home.alt_m).unwrap();
        assert_eq!(plain.photos, [0, 0, 0, 0]);
    }

    #[test]
    fn degrees_become_rounded_e7_integers_and_a_bad_order_is_refused() {
        assert_eq!(deg_e7(38.536_200_04), 385_362_000);
        assert_eq!(deg_e7(-121.787_500_06), -1_217_875_001);
        assert!(mission_items(&sample(), &[0, 7], &ItemOptions::default()).is_none());
    }
}
