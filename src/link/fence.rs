//! A mission's geofence and rally points as MAVLink mission items, and back: the fence goes up
//! as the autopilot's list of MAV_MISSION_TYPE_FENCE, the rally points as its list of
//! MAV_MISSION_TYPE_RALLY, each through the same transfer machines as the mission.
//!
//! The items are those of the MAVLink mission protocol (common.xml, `MAV_CMD_NAV_FENCE_*`,
//! `MAV_CMD_NAV_RALLY_POINT`), as QGroundControl sends them and PX4
//! (`mavlink_mission.cpp`, `parse_mavlink_mission_item`) and ArduPilot
//! (`MissionItemProtocol_Fence.cpp`, `MissionItemProtocol_Rally.cpp`) take them:
//! - a polygon is one item per vertex, in order, each MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
//!   (5001) or _EXCLUSION (5002) with param1 the polygon's vertex count; a circle one
//!   MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION (5003) or _EXCLUSION (5004) with param1 its radius (m);
//!   latitude and longitude in degE7, in MAV_FRAME_GLOBAL (a fence is vertical: z 0);
//! - the breach return point is MAV_CMD_NAV_FENCE_RETURN_POINT (5000) at its position, z its
//!   altitude (ArduPilot keeps no altitude of it);
//! - a rally point is MAV_CMD_NAV_RALLY_POINT (5100) in MAV_FRAME_GLOBAL_RELATIVE_ALT, the only
//!   frame ArduPilot takes for it (`convert_MISSION_ITEM_INT_to_RallyLocation`), z its altitude
//!   above home; ArduPilot stores that altitude as whole metres (`RallyLocation::alt`, int16),
//!   so it is sent rounded to the metre it will fly at.
//!
//! Invariant: degE7 is converted here and in `link::items`, once each way.

use super::items::{deg_e7, item};
use super::mav::{MavCmd, MavFrame, MavMissionType, MISSION_ITEM_INT_DATA};
use super::Flavour;
use crate::mission::fence::{Fence, LatLon, RallyPoint, Shape, Zone};
use crate::mission::Geodetic;

/// The mission type of a fence's items.
pub const FENCE: MavMissionType = MavMissionType::MAV_MISSION_TYPE_FENCE;
/// The mission type of rally points' items.
pub const RALLY: MavMissionType = MavMissionType::MAV_MISSION_TYPE_RALLY;

fn numbered(
    mission_type: MavMissionType,
    items: Vec<MISSION_ITEM_INT_DATA>,
) -> Vec<MISSION_ITEM_INT_DATA> {
    items
        .into_iter()
        .enumerate()
        .map(|(seq, it)| MISSION_ITEM_INT_DATA {
            seq: seq as u16,
            mission_type,
            // Neither autopilot keeps autocontinue for a fence or rally item: both answer 0.
            autocontinue: 0,
            ..it
        })
        .collect()
}

/// The items of `fence` (numbered from 0, mission type FENCE): the breach return point first
/// when there is one, then each zone in order.
pub fn fence_items(fence: &Fence) -> Vec<MISSION_ITEM_INT_DATA> {
    use MavCmd::*;
    let frame = MavFrame::MAV_FRAME_GLOBAL;
    let mut items = Vec::new();
    if let Some(r) = fence.breach_return {
        items.push(item(
            MAV_CMD_NAV_FENCE_RETURN_POINT,
            frame,
            [0.0; 4],
            deg_e7(r.lat_deg),
            deg_e7(r.lon_deg),
            r.alt_m as f32,
        ));
    }
    for zone in &fence.zones {
        match &zone.shape {
            Shape::Polygon(vertices) => {
                let command = if zone.inclusion {
                    MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
                } else {
                    MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
                };
                let n = vertices.len() as f32;
                items.extend(vertices.iter().map(|v| {
                    item(
                        command,
                        frame,
                        [n, 0.0, 0.0, 0.0],
                        deg_e7(v.lat_deg),
                        deg_e7(v.lon_deg),
                        0.0,
                    )
                }));
            }
            Shape::Circle { center, radius_m } => {
                let command = if zone.inclusion {
                    MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
                } else {
                    MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
                };
                items.push(item(
                    command,
                    frame,
                    [*radius_m as f32, 0.0, 0.0, 0.0],
                    deg_e7(center.lat_deg),
                    deg_e7(center.lon_deg),
                    0.0,
                ));
            }
        }
    }
    numbered(FENCE, items)
}

/// The altitude above home an autopilot of `flavour` holds of a rally point at `alt_m`:
/// ArduPilot whole metres (`RallyLocation::alt` is an int16 of metres), the others as sent.
pub fn rally_alt_m(flavour: Flavour, alt_m: f64) -> f64 {
    match flavour {
        Flavour::ArduPilot => alt_m.round(),
        Flavour::Px4 | Flavour::Generic => alt_m,
    }
}

/// The items of `rally` for an autopilot of `flavour` (numbered from 0, mission type RALLY).
pub fn rally_items(rally: &[RallyPoint], flavour: Flavour) -> Vec<MISSION_ITEM_INT_DATA> {
    let items = rally
        .iter()
        .map(|p| {
            item(
                MavCmd::MAV_CMD_NAV_RALLY_POINT,
                MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
                [0.0; 4],
                deg_e7(p.lat_deg),
                deg_e7(p.lon_deg),
                rally_alt_m(flavour, p.alt_above_home_m) as f32,
            )
        })
        .collect();
    numbered(RALLY, items)
}

/// Why items read from an autopilot are not a fence or rally points.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FenceItemsError {
    #[error("{list} item {seq}: {what}")]
    Item {
        list: &'static str,
        seq: u16,
        what: String,
    },
}

fn degrees(e7: i32) -> f64 {
    f64::from(e7) / 1e7
}

fn lat_lon(it: &MISSION_ITEM_INT_DATA) -> LatLon {
    LatLon {
        lat_deg: degrees(it.x),
        lon_deg: degrees(it.y),
    }
}

fn fence_error(seq: u16, what: String) -> FenceItemsError {
    FenceItemsError::Item {
        list: "fence",
        seq,
        what,
    }
}

/// The fence `items` hold (as downloaded: numbered 0..n): each run of polygon vertices of one
/// kind is a polygon of as many vertices as its param1 says; each circle item a circle.
pub fn fence_of_items(items: &[MISSION_ITEM_INT_DATA]) -> Result<Fence, FenceItemsError> {
    use MavCmd::*;
    let mut fence = Fence::default();
    let mut k = 0;
    while let Some(it) = items.get(k) {
        match it.command {
            MAV_CMD_NAV_FENCE_RETURN_POINT => {
                fence.breach_return = Some(Geodetic {
                    lat_deg: degrees(it.x),
                    lon_deg: degrees(it.y),
                    alt_m: f64::from(it.z),
                });
                k += 1;
            }
            MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
            | MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION => {
                let n = it.param1;
                if !(n.is_finite() && n >= 3.0 && n.fract() == 0.0) {
                    return Err(fence_error(
                        it.seq,
                        format!("a polygon vertex with a vertex count (param1) of {n}, not a whole number of at least 3"),
                    ));
                }
                let n = n as usize;
                let Some(run) = items.get(k..k + n) else {
                    return Err(fence_error(
                        it.seq,
                        format!(
                            "a polygon of {n} vertices but only {} items follow",
                            items.len() - k
                        ),
                    ));
                };
                if let Some(odd) = run
                    .iter()
                    .find(|v| v.command != it.command || v.param1 != it.param1)
                {
                    return Err(fence_error(
                        odd.seq,
                        format!(
                            "expected vertex {} of the {n}-vertex polygon from item {}",
                            odd.seq - it.seq + 1,
                            it.seq
                        ),
                    ));
                }
                fence.zones.push(Zone {
                    inclusion: it.command == MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                    shape: Shape::Polygon(run.iter().map(lat_lon).collect()),
                });
                k += n;
            }
            MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION | MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION => {
                let radius_m = f64::from(it.param1);
                if !(radius_m.is_finite() && radius_m > 0.0) {
                    return Err(fence_error(
                        it.seq,
                        format!("a circle of radius (param1) {radius_m} m"),
                    ));
                }
                fence.zones.push(Zone {
                    inclusion: it.command == MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
                    shape: Shape::Circle {
                        center: lat_lon(it),
                        radius_m,
                    },
                });
                k += 1;
            }
            other => {
                return Err(fence_error(
                    it.seq,
                    format!("command {} is no fence item", other as u32),
                ))
            }
        }
    }
    Ok(fence)
}

/// The rally points `items` hold (as downloaded), altitudes above home.
pub fn rally_of_items(items: &[MISSION_ITEM_INT_DATA]) -> Result<Vec<RallyPoint>, FenceItemsError> {
    items
        .iter()
        .map(|it| {
            if it.command != MavCmd::MAV_CMD_NAV_RALLY_POINT {
                return Err(FenceItemsError::Item {
                    list: "rally",
                    seq: it.seq,
                    what: format!("command {} is no rally point", it.command as u32),
                });
            }
            Ok(RallyPoint {
                lat_deg: degrees(it.x),
                lon_deg: degrees(it.y),
                alt_above_home_m: f64::from(it.z),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(lat: f64, lon: f64, side_deg: f64) -> Vec<LatLon> {
        [(0.0, 0.0), (0.0, 1.0), (1.0, 1.0), (1.0, 0.0)]
            .iter()
            .map(|(a, b)| LatLon {
                lat_deg: lat + a * side_deg,
                lon_deg: lon + b * side_deg,
            })
            .collect()
    }

    #[test]
    fn a_fence_goes_up_as_vertex_circle_and_return_point_items_and_reads_back_the_same() {
        let fence = crate::link::testing::fence();
        let items = fence_items(&fence);
        let commands: Vec<u32> = items.iter().map(|i| i.command as u32).collect();
        assert_eq!(
            commands,
            vec![5000, 5001, 5001, 5001, 5001, 5001, 5002, 5002, 5002, 5002, 5004]
        );
        assert!(items.iter().enumerate().all(|(k, i)| i.seq == k as u16
            && i.mission_type == FENCE
            && i.frame == MavFrame::MAV_FRAME_GLOBAL));
        assert_eq!(items[1].param1, 5.0);
        assert_eq!(items[6].param1, 4.0);
        assert_eq!(items[10].param1, 12.5);
        assert_eq!((items[1].x, items[1].y), (385_360_000, -1_217_890_000));
        let back = fence_of_items(&items).unwrap();
        assert_eq!(back.zones.len(), 3);
        assert_eq!(back.breach_return, fence.breach_return);
        for (a, b) in back.zones.iter().zip(&fence.zones) {
            assert_eq!(a.inclusion, b.inclusion);
            match (&a.shape, &b.shape) {
                (Shape::Polygon(p), Shape::Polygon(q)) => {
                    assert_eq!(p.len(), q.len());
                    for (u, v) in p.iter().zip(q) {
                        assert!((u.lat_deg - v.lat_deg).abs() < 1e-7);
                        assert!((u.lon_deg - v.lon_deg).abs() < 1e-7);
                    }
                }
                (Shape::Circle { radius_m: r, .. }, Shape::Circle { radius_m: s, .. }) => {
                    assert_eq!(r, s)
                }
                _ => panic!("zone shapes differ"),
            }
        }
    }

    #[test]
    fn two_polygons_of_one_kind_side_by_side_are_told_apart_by_their_vertex_count() {
        let fence = Fence {
            zones: vec![
                Zone {
                    inclusion: false,
                    shape: Shape::Polygon(square(38.5, -121.7, 0.001)),
                },
                Zone {
                    inclusion: false,
                    shape: Shape::Polygon(square(38.6, -121.7, 0.001)[..3].to_vec()),
                },
            ],
            breach_return: None,
        };
        let back = fence_of_items(&fence_items(&fence)).unwrap();
        assert_eq!(back.zones.len(), 2);
        assert!(matches!(&back.zones[1].shape, Shape::Polygon(p) if p.len() == 3));
    }

    #[test]
    fn a_truncated_polygon_or_a_foreign_command_is_refused_naming_the_item() {
        let items = fence_items(&crate::link::testing::fence());
        let err = fence_of_items(&items[..4]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "fence item 1: a polygon of 5 vertices but only 3 items follow"
        );
        let mut odd = items.clone();
        odd[3].command = MavCmd::MAV_CMD_NAV_WAYPOINT;
        let err = fence_of_items(&odd).unwrap_err();
        assert_eq!(
            err.to_string(),
            "fence item 3: expected vertex 3 of the 5-vertex polygon from item 1"
        );
        let mut nan = items;
        nan[1].param1 = f32::NAN;
        assert!(fence_of_items(&nan).is_err());
    }

    #[test]
    fn rally_points_go_up_relative_to_home_rounded_to_the_metre_for_ardupilot() {
        let rally = [RallyPoint {
            lat_deg: 38.5366,
            lon_deg: -121.7880,
            alt_above_home_m: 25.4,
        }];
        let ap = rally_items(&rally, Flavour::ArduPilot);
        assert_eq!(ap[0].command, MavCmd::MAV_CMD_NAV_RALLY_POINT);
        assert_eq!(ap[0].frame, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT);
        assert_eq!(ap[0].mission_type, RALLY);
        assert_eq!(ap[0].z, 25.0);
        let px4 = rally_items(&rally, Flavour::Px4);
        assert_eq!(px4[0].z, 25.4);
        let back = rally_of_items(&px4).unwrap();
        assert!((back[0].lat_deg - 38.5366).abs() < 1e-7);
        assert!((back[0].alt_above_home_m - 25.4).abs() < 1e-5);
        let mut wrong = px4;
        wrong[0].command = MavCmd::MAV_CMD_NAV_WAYPOINT;
        assert_eq!(
            rally_of_items(&wrong).unwrap_err().to_string(),
            "rally item 0: command 16 is no rally point"
        );
    }
}
