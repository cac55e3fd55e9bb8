//! Where the vehicle stands against where the plan starts: the distance from a vehicle's home to
//! a mission's origin, the check before arming, and the mission planned again from the
//! vehicle's home (`--origin vehicle`).
//!
//! An uploaded mission is flown at each waypoint's latitude and longitude, at its height above
//! the vehicle's home (MAVLink's relative-altitude frame). So a vehicle standing elsewhere flies
//! the same places at the same heights above its own home: re-homing keeps each waypoint's
//! geographic position and height above home, and re-expresses it in the new origin's frame.

use super::geodesy::geodesic_distance_m;
use super::{Geodetic, Mission, Origin, Waypoint};

/// How far a vehicle's home may be from the mission's origin before a flight is refused (m,
/// horizontal). A home fix of a consumer GNSS receiver is good to a few metres; a team may set
/// the vehicle down a few paces from the planned spot. Beyond 20 m the first and last legs,
/// which the plan prices from the origin, change by more than about 1.6 kJ each (the model's
/// level marginal cost is 78 J/m), several percent of a sample mission: the plan no longer
/// describes the flight.
pub const ORIGIN_TOLERANCE_M: f64 = 20.0;

/// A vehicle's home against a mission's origin.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct HomeOffset {
    /// The vehicle's home.
    pub vehicle_home: Geodetic,
    /// The mission's home (its origin on the ground).
    pub mission_home: Geodetic,
    /// Horizontal distance between them (m).
    pub horizontal_m: f64,
    /// The vehicle's home above the mission's (m; AMSL altitudes as each reports them).
    pub vertical_m: f64,
}

impl HomeOffset {
    /// The offset of `vehicle_home` from `mission`'s home: the horizontal distance along the
    /// ellipsoid (`geodesy::geodesic_distance_m`), true however far apart they are.
    pub fn of(mission: &Mission, vehicle_home: Geodetic) -> HomeOffset {
        HomeOffset {
            vehicle_home,
            mission_home: mission.origin.home,
            horizontal_m: geodesic_distance_m(mission.origin.home, vehicle_home),
            vertical_m: vehicle_home.alt_m - mission.origin.home.alt_m,
        }
    }

    /// Whether the vehicle stands within `tolerance_m` of the mission's origin.
    pub fn within(&self, tolerance_m: f64) -> bool {
        self.horizontal_m <= tolerance_m
    }

    /// A sentence naming both positions and the distance.
    pub fn describe(&self) -> String {
        format!(
            "the vehicle's home ({:.6}, {:.6}) is {:.0} m from the mission's origin ({:.6}, {:.6})",
            self.vehicle_home.lat_deg,
            self.vehicle_home.lon_deg,
            self.horizontal_m,
            self.mission_home.lat_deg,
            self.mission_home.lon_deg
        )
    }
}

/// The mission planned from `home` instead of its own origin: every waypoint at the same latitude
/// and longitude and the same height above home, the origin hover at the same height above the
/// new home. The minimum height above home still holds (heights above home are kept).
pub fn rehomed(mission: &Mission, home: Geodetic) -> Mission {
    let origin = Origin {
        home,
        height_above_home_m: mission.origin.height_above_home_m,
    };
    let waypoints = mission
        .waypoints
        .iter()
        .map(|w| {
            let g = mission.origin.to_geodetic(w.position);
            let above_home_m = g.alt_m - mission.origin.home.alt_m;
            Waypoint {
                position: origin.to_enu(Geodetic {
                    alt_m: home.alt_m + above_home_m,
                    ..g
                }),
                ..w.clone()
            }
        })
        .collect();
    Mission {
        origin,
        waypoints,
        ..mission.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::{load_str, Format};

    fn sample() -> Mission {
        let text = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/paper-sample-8wp.toml"),
        )
        .unwrap();
        load_str(&text, Format::Toml, None).unwrap()
    }

    #[test]
    fn the_offset_of_a_home_is_its_distance_from_the_origin() {
        let m = sample();
        let same = HomeOffset::of(&m, m.origin.home);
        assert!(same.horizontal_m < 1e-6 && same.vertical_m == 0.0);
        assert!(same.within(ORIGIN_TOLERANCE_M));
        // 0.02 degrees of latitude north: about 2.22 km.
        let far = Geodetic {
            lat_deg: m.origin.home.lat_deg + 0.02,
            alt_m: m.origin.home.alt_m + 3.0,
            ..m.origin.home
        };
        let off = HomeOffset::of(&m, far);
        assert!((off.horizontal_m - 2220.0).abs() < 10.0, "{off:?}");
        assert_eq!(off.vertical_m, 3.0);
        assert!(!off.within(ORIGIN_TOLERANCE_M));
        assert!(off.describe().contains("2220 m") || off.describe().contains("2221 m"));
    }

    #[test]
    fn a_home_near_the_pole_is_its_distance_along_the_earth_from_the_origin() {
        let m = sample();
        let pole = Geodetic {
            lat_deg: 89.99,
            lon_deg: 10.0,
            alt_m: 0.0,
        };
        let off = HomeOffset::of(&m, pole);
        // From the sample's field (38.5362 N) to 0.01 deg (1.1 km) short of the pole on another
        // meridian: at least the meridian arc from 38.5362 deg to the pole, 5 734 949 m (the
        // quadrant, 10 001 966 m, less the 4 267 017 m from the equator, both integrated from
        // the meridian radius of curvature), and at most 1.12 km more; the plane tangent at the
        // origin made it 4 994 km.
        let arc_m = 5_734_949.0;
        assert!(
            off.horizontal_m > arc_m && off.horizontal_m < arc_m + 1_120.0,
            "{off:?}"
        );
        // Within the tolerance the plane and the ellipsoid agree.
        let near = Geodetic {
            lat_deg: m.origin.home.lat_deg + 0.0001,
            lon_deg: m.origin.home.lon_deg + 0.0001,
            ..m.origin.home
        };
        let flat = Origin {
            home: m.origin.home,
            height_above_home_m: 0.0,
        }
        .to_enu(near);
        let plane_m = flat.x_east_m.hypot(flat.y_north_m);
        assert!((HomeOffset::of(&m, near).horizontal_m - plane_m).abs() < 1e-3);
    }

    #[test]
    fn a_rehomed_mission_flies_the_same_places_at_the_same_heights_above_home() {
        let m = sample();
        let home = Geodetic {
            lat_deg: m.origin.home.lat_deg + 0.001,
            lon_deg: m.origin.home.lon_deg - 0.002,
            alt_m: m.origin.home.alt_m + 7.0,
        };
        let r = rehomed(&m, home);
        assert_eq!(r.origin.home, home);
        assert_eq!(r.origin.height_above_home_m, m.origin.height_above_home_m);
        for k in 0..m.waypoints.len() {
            let (lat0, lon0, h0) = m.waypoint_relative(k).unwrap();
            let (lat1, lon1, h1) = r.waypoint_relative(k).unwrap();
            assert!((lat0 - lat1).abs() < 1e-9 && (lon0 - lon1).abs() < 1e-9);
            assert!((h0 - h1).abs() < 1e-6, "{h0} {h1}");
            assert_eq!(r.waypoints[k].name, m.waypoints[k].name);
        }
        // About 111 m north and 174 m west of the old origin, so the waypoints move south-east.
        let dx = r.waypoints[0].position.x_east_m - m.waypoints[0].position.x_east_m;
        let dy = r.waypoints[0].position.y_north_m - m.waypoints[0].position.y_north_m;
        assert!(
            (dx - 174.0).abs() < 2.0 && (dy + 111.0).abs() < 2.0,
            "{dx} {dy}"
        );
        // At its own home, a mission is itself.
        let same = rehomed(&m, m.origin.home);
        for (a, b) in same.waypoints.iter().zip(&m.waypoints) {
            assert!((a.position.x_east_m - b.position.x_east_m).abs() < 1e-6);
            assert!((a.position.z_up_m - b.position.z_up_m).abs() < 1e-6);
        }
    }
}
