//! Test fixtures shared by the link and sim unit tests, the integration tests and the benches:
//! the mission items every protocol test uses, defined once, and the small message builders of
//! the machine tests.

use std::time::Duration;

use mavlink::MavHeader;

use super::connection::Autopilot;
use super::mav::{
    MavCmd, MavFrame, MavMessage, MavMissionResult, MavMissionType, MISSION_ACK_DATA,
    MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA,
};
use super::transfer::Action;
use super::Flavour;
use crate::mission::fence::{Fence, LatLon, RallyPoint, Shape, Zone};
use crate::mission::Geodetic;

const MISSION: MavMissionType = MavMissionType::MAV_MISSION_TYPE_MISSION;

fn item(seq: u16, command: MavCmd, frame: MavFrame, p: [f32; 4], z: f32) -> MISSION_ITEM_INT_DATA {
    // Distinct positions 1 degE7 (about 1 cm) apart, north of the sample field.
    let x = 385_362_000 + i32::from(seq);
    MISSION_ITEM_INT_DATA {
        seq,
        ..super::items::item(command, frame, p, x, -1_217_875_000, z)
    }
}

/// `n` NAV_WAYPOINT items numbered 0..n at 30 m relative altitude, each at its own latitude,
/// with a 5 s hold and no other parameter.
pub fn waypoints(n: u16) -> Vec<MISSION_ITEM_INT_DATA> {
    (0..n)
        .map(|seq| {
            item(
                seq,
                MavCmd::MAV_CMD_NAV_WAYPOINT,
                MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
                [5.0, 0.0, 0.0, 0.0],
                30.0,
            )
        })
        .collect()
}

/// A mission of `n` items (at least 3) as emplan builds them for `flavour`: ArduPilot's home at
/// item 0, NAV_TAKEOFF, NAV_WAYPOINTs (hold 5 s, acceptance radius 2 m, yaw NaN) and
/// NAV_RETURN_TO_LAUNCH.
pub fn mission(flavour: Flavour, n: u16) -> Vec<MISSION_ITEM_INT_DATA> {
    let relative = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT;
    let n = n.max(3);
    (0..n)
        .map(|seq| {
            let first = if flavour == Flavour::ArduPilot { 1 } else { 0 };
            if flavour == Flavour::ArduPilot && seq == 0 {
                item(
                    seq,
                    MavCmd::MAV_CMD_NAV_WAYPOINT,
                    MavFrame::MAV_FRAME_GLOBAL,
                    [0.0; 4],
                    16.0,
                )
            } else if seq == first {
                item(
                    seq,
                    MavCmd::MAV_CMD_NAV_TAKEOFF,
                    relative,
                    [0.0, 0.0, 0.0, f32::NAN],
                    30.0,
                )
            } else if seq == n - 1 {
                let mut rtl = item(
                    seq,
                    MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH,
                    MavFrame::MAV_FRAME_MISSION,
                    [0.0; 4],
                    0.0,
                );
                (rtl.x, rtl.y) = (0, 0);
                rtl
            } else {
                item(
                    seq,
                    MavCmd::MAV_CMD_NAV_WAYPOINT,
                    relative,
                    [5.0, 2.0, 0.0, f32::NAN],
                    40.0,
                )
            }
        })
        .collect()
}

/// Milliseconds of the fake clock.
pub fn ms(t: u64) -> Duration {
    Duration::from_millis(t)
}

/// The autopilot's request for item `seq`.
pub fn request(seq: u16) -> MavMessage {
    MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
        seq,
        target_system: 255,
        target_component: 190,
        mission_type: MISSION,
    })
}

/// A MISSION_ACK with `result`.
pub fn ack(result: MavMissionResult) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: 255,
        target_component: 190,
        mavtype: result,
        mission_type: MISSION,
        opaque_id: 0,
    })
}

/// The items a machine's actions send, by seq.
pub fn sent_items(actions: &[Action]) -> Vec<u16> {
    actions
        .iter()
        .filter_map(|a| match a {
            Action::Send(MavMessage::MISSION_ITEM_INT(i)) => Some(i.seq),
            _ => None,
        })
        .collect()
}

/// The header of a message from the autopilot (system 1, component 1).
pub fn autopilot_header() -> MavHeader {
    MavHeader {
        system_id: 1,
        component_id: 1,
        sequence: 0,
    }
}

/// The autopilot the machine tests talk to: system 1, component 1, of `flavour`.
pub fn autopilot(flavour: Flavour) -> Autopilot {
    Autopilot {
        system_id: 1,
        component_id: 1,
        flavour,
    }
}

fn square(lat_deg: f64, lon_deg: f64, side_deg: f64) -> Vec<LatLon> {
    [(0.0, 0.0), (0.0, 1.0), (1.0, 1.0), (1.0, 0.0)]
        .iter()
        .map(|(a, b)| LatLon {
            lat_deg: lat_deg + a * side_deg,
            lon_deg: lon_deg + b * side_deg,
        })
        .collect()
}

/// A fence round the sample field: an inclusion pentagon, an exclusion square (about 17 m a
/// side), an exclusion circle of 12.5 m and a breach return point at 30 m.
pub fn fence() -> Fence {
    let ll = |lat_deg, lon_deg| LatLon { lat_deg, lon_deg };
    Fence {
        zones: vec![
            Zone {
                inclusion: true,
                shape: Shape::Polygon(vec![
                    ll(38.5360, -121.7890),
                    ll(38.5370, -121.7890),
                    ll(38.5370, -121.7860),
                    ll(38.5365, -121.7855),
                    ll(38.5360, -121.7860),
                ]),
            },
            Zone {
                inclusion: false,
                shape: Shape::Polygon(square(38.5364, -121.7888, 0.0002)),
            },
            Zone {
                inclusion: false,
                shape: Shape::Circle {
                    center: ll(38.5368, -121.7865),
                    radius_m: 12.5,
                },
            },
        ],
        breach_return: Some(Geodetic {
            lat_deg: 38.5362,
            lon_deg: -121.7875,
            alt_m: 30.0,
        }),
    }
}

/// One rally point on the sample field, 25.4 m above home (ArduPilot holds 25 m of it).
pub fn rally() -> Vec<RallyPoint> {
    vec![RallyPoint {
        lat_deg: 38.5366,
        lon_deg: -121.7880,
        alt_above_home_m: 25.4,
    }]
}
