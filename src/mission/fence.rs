//! The geofence and the rally points a mission carries: inclusion zones the vehicle must stay
//! inside (a field's boundary), exclusion zones it must stay out of (a house, a road), each a
//! polygon or a circle, and the rally points an autopilot may return to instead of home.
//!
//! They are kept as the file gives them, geodetic (a fence does not move when a mission is
//! re-homed), and seen by the planner in the mission's local frame ([`Zone::local`]), where
//! the plane geometry below answers "is this point inside?" and "does this straight line cross
//! the zone's boundary?". The model is QGroundControl's (`geoFence` with `polygons` and
//! `circles`, each with `inclusion`; `rallyPoints`), which is also what PX4 and ArduPilot hold
//! through the MAVLink mission protocol (`MAV_CMD_NAV_FENCE_*`, `MAV_CMD_NAV_RALLY_POINT`).

use super::{Enu, Geodetic, Origin};

/// A latitude and longitude (degrees, WGS84): a fence's vertices and centres have no height.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatLon {
    pub lat_deg: f64,
    pub lon_deg: f64,
}

/// The shape of one fence zone.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// A simple polygon, its vertices in order (either winding; not closed: the last vertex
    /// joins the first). At least 3 vertices.
    Polygon(Vec<LatLon>),
    /// A circle of `radius_m` metres around `center`.
    Circle { center: LatLon, radius_m: f64 },
}

/// One zone of a geofence.
#[derive(Debug, Clone, PartialEq)]
pub struct Zone {
    /// True: the vehicle must stay inside it. False: the vehicle must stay out of it.
    pub inclusion: bool,
    pub shape: Shape,
}

/// A mission's geofence: its zones, and where ArduPilot goes on a breach (QGroundControl's
/// `breachReturn`, ArduPilot's fence return point), if the file gives one. The breach return's
/// `alt_m` is its altitude above home (QGroundControl sends it in
/// `MAV_FRAME_GLOBAL_RELATIVE_ALT`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Fence {
    pub zones: Vec<Zone>,
    pub breach_return: Option<Geodetic>,
}

impl Fence {
    /// True when the fence has no zone.
    pub fn is_empty(&self) -> bool {
        self.zones.is_empty()
    }

    /// The first zone (its 0-based index) whose rule the point (east, north, in `origin`'s
    /// frame) breaks: outside an inclusion zone or inside an exclusion zone; None when the point
    /// keeps them all.
    ///
    /// With several inclusion zones the point must be inside every one of them. ArduPilot's
    /// `AC_PolyFence_loader::breached` (libraries/AC_Fence) counts a breach when the vehicle is
    /// outside any inclusion zone (their intersection) unless `FENCE_OPTIONS` asks for their
    /// union (`INCLUSION_UNION`); PX4's `Geofence::isInsidePolygonOrCircle`
    /// (src/modules/navigator/geofence.cpp) asks only for one (their union). Inside every
    /// inclusion zone is inside the fence on both autopilots, whatever their settings, so that
    /// is the rule emplan checks a mission against.
    pub fn zone_broken_by(&self, origin: &Origin, p: [f64; 2]) -> Option<usize> {
        self.zones
            .iter()
            .position(|zone| zone.local(origin).violated_by(p))
    }

    /// "1 inclusion polygon (7 vertices), 1 exclusion polygon (4 vertices)": what the fence
    /// holds, zones of a kind together in the order they first appear, and its breach return
    /// point if it has one ("none" for an empty fence).
    pub fn summary(&self) -> String {
        let mut kinds: Vec<(bool, bool, Vec<usize>)> = Vec::new();
        for zone in &self.zones {
            let (polygon, vertices) = match &zone.shape {
                Shape::Polygon(v) => (true, v.len()),
                Shape::Circle { .. } => (false, 0),
            };
            match kinds
                .iter_mut()
                .find(|(i, p, _)| *i == zone.inclusion && *p == polygon)
            {
                Some((_, _, counts)) => counts.push(vertices),
                None => kinds.push((zone.inclusion, polygon, vec![vertices])),
            }
        }
        let mut parts: Vec<String> = kinds
            .iter()
            .map(|(inclusion, polygon, counts)| {
                let kind = if *inclusion { "inclusion" } else { "exclusion" };
                let n = counts.len();
                let plural = if n == 1 { "" } else { "s" };
                if *polygon {
                    let listed: Vec<String> = counts.iter().map(usize::to_string).collect();
                    format!(
                        "{n} {kind} polygon{plural} ({} vertices)",
                        listed.join(", ")
                    )
                } else {
                    format!("{n} {kind} circle{plural}")
                }
            })
            .collect();
        if self.breach_return.is_some() {
            parts.push("a breach return point".to_string());
        }
        if parts.is_empty() {
            "none".to_string()
        } else {
            parts.join(", ")
        }
    }
}

/// "1 rally point", "3 rally points".
pub fn rally_summary(rally: &[RallyPoint]) -> String {
    let n = rally.len();
    format!("{n} rally point{}", if n == 1 { "" } else { "s" })
}

/// A rally point: where an autopilot may return to instead of home (altitude above home).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RallyPoint {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_above_home_m: f64,
}

impl RallyPoint {
    /// The rally point in the mission's local frame.
    pub fn local(&self, origin: &Origin) -> Enu {
        origin.to_enu(Geodetic {
            lat_deg: self.lat_deg,
            lon_deg: self.lon_deg,
            alt_m: origin.home.alt_m + self.alt_above_home_m,
        })
    }
}

/// A zone's shape in the mission's local frame (east, north; metres).
#[derive(Debug, Clone, PartialEq)]
pub enum LocalShape {
    Polygon(Vec<[f64; 2]>),
    Circle { center: [f64; 2], radius_m: f64 },
}

/// A zone in the mission's local frame.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalZone {
    pub inclusion: bool,
    pub shape: LocalShape,
}

impl Zone {
    /// The zone in `origin`'s local frame, its vertices at the height of home (a fence is
    /// vertical: only east and north matter).
    pub fn local(&self, origin: &Origin) -> LocalZone {
        let xy = |p: &LatLon| {
            let e = origin.to_enu(Geodetic {
                lat_deg: p.lat_deg,
                lon_deg: p.lon_deg,
                alt_m: origin.home.alt_m,
            });
            [e.x_east_m, e.y_north_m]
        };
        let shape = match &self.shape {
            Shape::Polygon(vertices) => LocalShape::Polygon(vertices.iter().map(xy).collect()),
            Shape::Circle { center, radius_m } => LocalShape::Circle {
                center: xy(center),
                radius_m: *radius_m,
            },
        };
        LocalZone {
            inclusion: self.inclusion,
            shape,
        }
    }

    /// "inclusion polygon 2" or "exclusion circle 1": how errors and reports name a zone
    /// (`index` is its 1-based place among the fence's zones).
    pub fn describe(&self, index: usize) -> String {
        let kind = if self.inclusion {
            "inclusion"
        } else {
            "exclusion"
        };
        let shape = match self.shape {
            Shape::Polygon(_) => "polygon",
            Shape::Circle { .. } => "circle",
        };
        format!("{kind} {shape} {index}")
    }
}

impl LocalZone {
    /// The first two edges of a polygon that cross or touch, other than neighbours at the
    /// vertex they share: `(i, j)`, edge `i` running from vertex `i` to vertex `i + 1` (the last
    /// edge closes the polygon). None for a simple polygon and for a circle.
    pub fn crossing_edges(&self) -> Option<(usize, usize)> {
        let LocalShape::Polygon(v) = &self.shape else {
            return None;
        };
        let n = v.len();
        if n < 4 {
            return None;
        }
        let edge = |i: usize| (v[i], v[(i + 1) % n]);
        for i in 0..n {
            for j in i + 2..n {
                if i == 0 && j == n - 1 {
                    continue;
                }
                let ((a, b), (c, d)) = (edge(i), edge(j));
                if segment_segment_distance_m(a, b, c, d) <= 1e-9 {
                    return Some((i, j));
                }
            }
        }
        None
    }

    /// True when the point (east, north) lies inside the zone's shape (its boundary counts as
    /// inside). Polygons by the even-odd rule.
    pub fn contains(&self, p: [f64; 2]) -> bool {
        match &self.shape {
            LocalShape::Circle { center, radius_m } => {
                (p[0] - center[0]).hypot(p[1] - center[1]) <= *radius_m
            }
            LocalShape::Polygon(v) => {
                if v.len() < 3 {
                    return false;
                }
                let mut inside = false;
                let mut j = v.len() - 1;
                for i in 0..v.len() {
                    let (a, b) = (v[i], v[j]);
                    if on_segment(p, a, b) {
                        return true;
                    }
                    if (a[1] > p[1]) != (b[1] > p[1]) {
                        let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
                        if p[0] < x {
                            inside = !inside;
                        }
                    }
                    j = i;
                }
                inside
            }
        }
    }

    /// The least distance (m) from the point to the zone's boundary.
    pub fn distance_to_boundary_m(&self, p: [f64; 2]) -> f64 {
        match &self.shape {
            LocalShape::Circle { center, radius_m } => {
                ((p[0] - center[0]).hypot(p[1] - center[1]) - radius_m).abs()
            }
            LocalShape::Polygon(v) => (0..v.len())
                .map(|i| point_segment_distance_m(p, v[i], v[(i + 1) % v.len()]))
                .fold(f64::INFINITY, f64::min),
        }
    }

    /// True when the point breaks this zone's rule: outside an inclusion zone, or inside an
    /// exclusion zone.
    pub fn violated_by(&self, p: [f64; 2]) -> bool {
        self.contains(p) != self.inclusion
    }

    /// The least distance (m) from the straight segment `a`-`b` to the zone's boundary (0 when
    /// it crosses it).
    pub fn segment_distance_to_boundary_m(&self, a: [f64; 2], b: [f64; 2]) -> f64 {
        match &self.shape {
            LocalShape::Circle { center, radius_m } => {
                let near = point_segment_distance_m(*center, a, b);
                let far = (a[0] - center[0])
                    .hypot(a[1] - center[1])
                    .max((b[0] - center[0]).hypot(b[1] - center[1]));
                if near <= *radius_m && far >= *radius_m {
                    0.0
                } else if far < *radius_m {
                    radius_m - far
                } else {
                    near - radius_m
                }
            }
            LocalShape::Polygon(v) => (0..v.len())
                .map(|i| segment_segment_distance_m(a, b, v[i], v[(i + 1) % v.len()]))
                .fold(f64::INFINITY, f64::min),
        }
    }

    /// True when flying the straight segment `a`-`b` breaks this zone's rule or comes within
    /// `margin_m` of its boundary (touching it counts): for an exclusion zone, the segment enters it or passes
    /// nearer than the margin; for an inclusion zone, it leaves it or passes nearer than the
    /// margin to its edge.
    pub fn segment_violates(&self, a: [f64; 2], b: [f64; 2], margin_m: f64) -> bool {
        let clearance_m = self.segment_distance_to_boundary_m(a, b);
        self.violated_by(a) || self.violated_by(b) || clearance_m <= 0.0 || clearance_m < margin_m
    }
}

/// The least distance between the segments `a`-`b` and `c`-`d` (0 when they cross).
pub fn segment_segment_distance_m(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> f64 {
    let cross = |o: [f64; 2], p: [f64; 2], q: [f64; 2]| {
        (p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0])
    };
    let (d1, d2, d3, d4) = (
        cross(c, d, a),
        cross(c, d, b),
        cross(a, b, c),
        cross(a, b, d),
    );
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return 0.0;
    }
    point_segment_distance_m(a, c, d)
        .min(point_segment_distance_m(b, c, d))
        .min(point_segment_distance_m(c, a, b))
        .min(point_segment_distance_m(d, a, b))
}

/// The least distance from `p` to the segment `a`-`b` (m).
pub fn point_segment_distance_m(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - (a[0] + t * dx)).hypot(p[1] - (a[1] + t * dy))
}

fn on_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> bool {
    point_segment_distance_m(p, a, b) <= 1e-9
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(inclusion: bool) -> LocalZone {
        LocalZone {
            inclusion,
            shape: LocalShape::Polygon(vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]),
        }
    }

    #[test]
    fn a_point_is_inside_a_polygon_by_the_even_odd_rule_and_on_its_boundary() {
        let z = square(true);
        assert!(z.contains([5.0, 5.0]));
        assert!(z.contains([0.0, 5.0]));
        assert!(!z.contains([10.5, 5.0]));
        assert!(!z.contains([-1.0, -1.0]));
        assert!(!square(false).violated_by([11.0, 5.0]));
        assert!(square(false).violated_by([1.0, 5.0]));
        assert!((z.distance_to_boundary_m([5.0, 2.0]) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn a_segment_through_or_near_a_zone_violates_it_and_one_clear_of_it_does_not() {
        let house = square(false);
        assert!(house.segment_violates([-5.0, 5.0], [15.0, 5.0], 0.0));
        assert!(!house.segment_violates([-5.0, 12.0], [15.0, 12.0], 1.0));
        assert!(house.segment_violates([-5.0, 12.0], [15.0, 12.0], 3.0));
        let field = square(true);
        assert!(!field.segment_violates([2.0, 2.0], [8.0, 8.0], 1.0));
        assert!(field.segment_violates([2.0, 2.0], [8.0, 8.0], 3.0));
        assert!(field.segment_violates([2.0, 2.0], [12.0, 8.0], 0.0));
        let pond = LocalZone {
            inclusion: false,
            shape: LocalShape::Circle {
                center: [0.0, 0.0],
                radius_m: 5.0,
            },
        };
        assert!(pond.segment_violates([-10.0, 1.0], [10.0, 1.0], 0.0));
        assert!(!pond.segment_violates([-10.0, 7.0], [10.0, 7.0], 1.0));
        assert!(pond.segment_violates([-10.0, 7.0], [10.0, 7.0], 2.5));
        assert!(pond.segment_violates([-1.0, 0.0], [1.0, 0.0], 0.0));
    }

    #[test]
    fn a_circle_zone_holds_its_radius_and_a_local_zone_keeps_its_size() {
        let origin = Origin {
            home: Geodetic {
                lat_deg: 47.397742,
                lon_deg: 8.545594,
                alt_m: 488.0,
            },
            height_above_home_m: 10.0,
        };
        let east = origin.to_geodetic(Enu {
            x_east_m: 30.0,
            y_north_m: 0.0,
            z_up_m: -10.0,
        });
        let zone = Zone {
            inclusion: false,
            shape: Shape::Circle {
                center: LatLon {
                    lat_deg: east.lat_deg,
                    lon_deg: east.lon_deg,
                },
                radius_m: 5.0,
            },
        };
        let local = zone.local(&origin);
        assert!(local.contains([33.0, 0.0]));
        assert!(!local.contains([24.0, 0.0]));
        assert_eq!(zone.describe(2), "exclusion circle 2");
    }
}
