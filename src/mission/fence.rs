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

use serde::{Deserialize, Serialize};

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

impl LocalZone {
    /// The points a path round this zone may turn at, the zone pushed out by `distance_m`
    /// (an exclusion zone grown, an inclusion zone shrunk), in the mission's local frame: the
    /// vertices of the offset polygon, each corner the offset turns round replaced by the
    /// circumscribed polyline of its arc (one point for a turn of up to 120 degrees, at most
    /// twice `distance_m` from the corner, two beyond), so that every straight line between
    /// two consecutive points stays at least `distance_m` from the zone. A circle exclusion
    /// zone is its circumscribed 16-gon of radius `radius_m + distance_m`; an inclusion
    /// circle gives none (a disc is convex: a straight line between two points inside it far
    /// enough from its edge stays as far from it, so a path inside it never needs to turn).
    pub fn offset_vertices(&self, distance_m: f64) -> Vec<[f64; 2]> {
        match &self.shape {
            LocalShape::Circle { center, radius_m } => {
                if self.inclusion {
                    return Vec::new();
                }
                let sides = CIRCLE_SIDES as f64;
                let r = (radius_m + distance_m) / (std::f64::consts::PI / sides).cos();
                (0..CIRCLE_SIDES)
                    .map(|k| {
                        let a = 2.0 * std::f64::consts::PI * k as f64 / sides;
                        [center[0] + r * a.cos(), center[1] + r * a.sin()]
                    })
                    .collect()
            }
            LocalShape::Polygon(v) => offset_polygon(v, distance_m, !self.inclusion),
        }
    }
}

/// The sides of the polygon a circle zone is routed round as ([`LocalZone::offset_vertices`]):
/// 16 keeps the polygon within 2% of the circle's radius (1 / cos(pi / 16) = 1.0196).
const CIRCLE_SIDES: usize = 16;

/// The vertices of polygon `v` offset by `distance_m` outwards (`outward`) or inwards, each
/// corner the offset turns round (a convex corner outwards, a reflex one inwards) rounded by
/// the circumscribed polyline of its arc; the other corners at their miter point.
fn offset_polygon(v: &[[f64; 2]], distance_m: f64, outward: bool) -> Vec<[f64; 2]> {
    let n = v.len();
    if n < 3 {
        return Vec::new();
    }
    // Signed area: positive for a counter-clockwise polygon, whose outward normal of an edge
    // a -> b is (dy, -dx) / |ab|.
    let area2: f64 = (0..n)
        .map(|i| {
            let (a, b) = (v[i], v[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum();
    let side = if (area2 > 0.0) == outward { 1.0 } else { -1.0 };
    // The unit normal of edge i (v[i] -> v[i + 1]) on the side the offset goes.
    let normal = |i: usize| -> Option<[f64; 2]> {
        let (a, b) = (v[i], v[(i + 1) % n]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = dx.hypot(dy);
        (len > 1e-9).then(|| [side * dy / len, -side * dx / len])
    };
    let mut out = Vec::new();
    for i in 0..n {
        let (Some(m1), Some(m2)) = (normal((i + n - 1) % n), normal(i)) else {
            continue;
        };
        let p = v[i];
        // The turn from one offset side to the next, and whether the offset opens a gap
        // there (the corner is round the outside of the offset) or overlaps (miter inside).
        let a1 = m1[1].atan2(m1[0]);
        let mut turn = m2[1].atan2(m2[0]) - a1;
        while turn > std::f64::consts::PI {
            turn -= 2.0 * std::f64::consts::PI;
        }
        while turn < -std::f64::consts::PI {
            turn += 2.0 * std::f64::consts::PI;
        }
        let (e1, e2) = (
            [p[0] - v[(i + n - 1) % n][0], p[1] - v[(i + n - 1) % n][1]],
            [v[(i + 1) % n][0] - p[0], v[(i + 1) % n][1] - p[1]],
        );
        let cross = e1[0] * e2[1] - e1[1] * e2[0];
        // An offset to the left of the edges opens a gap at a corner turning right, and the
        // other way round.
        let left_normal = m1[0] * -e1[1] + m1[1] * e1[0] > 0.0;
        let opens = if left_normal {
            cross < 0.0
        } else {
            cross > 0.0
        };
        if opens && turn.abs() > 1e-9 {
            let pieces = if turn.abs() <= 2.0 * std::f64::consts::PI / 3.0 + 1e-9 {
                1
            } else {
                2
            };
            let step = turn / pieces as f64;
            let r = distance_m / (step / 2.0).cos();
            for k in 0..pieces {
                let a = a1 + step * (k as f64 + 0.5);
                out.push([p[0] + r * a.cos(), p[1] + r * a.sin()]);
            }
        } else {
            // The miter point: where the two offset edges' lines meet.
            let bisector = [m1[0] + m2[0], m1[1] + m2[1]];
            let len = bisector[0].hypot(bisector[1]);
            if len < 1e-9 {
                continue;
            }
            let r = distance_m / (turn / 2.0).cos().max(1e-3);
            out.push([p[0] + r * bisector[0] / len, p[1] + r * bisector[1] / len]);
        }
    }
    out
}

/// How an autopilot chooses where its return (RTL) goes, with the parameters that decide it.
///
/// ArduCopter (`AP_Rally::calc_best_rally_or_home_location`, libraries/AP_Rally/AP_Rally.cpp):
/// the nearest rally point from where the vehicle is; home instead when there is none, when
/// `RALLY_LIMIT_KM` is above 0 and the nearest is further than it, or when `RALLY_INCL_HOME` is
/// set and the rally point is not strictly nearer than home (Copter defaults: 0.3 km and 1).
/// ArduCopter's RTL (ArduCopter/mode_rtl.cpp) then climbs to RTL_ALT (or the rally point's
/// altitude, if higher), flies straight to it, descends and lands there.
///
/// PX4 (`RTL::findRtlDestinationForType`, src/modules/navigator/rtl.cpp), for a multicopter and
/// a mission without a landing (emplan's missions have none): `RTL_TYPE` 0 (its default) and 3
/// take the nearest of home and the safe (rally) points, a safe point only when it is more than
/// 2 m (`MIN_DIST_THRESHOLD`) nearer than home and more than 10 m from home
/// (`MAX_DIST_FROM_HOME_FOR_LAND_APPROACHES`); 1 prefers the nearest safe point more than 10 m
/// from home, home only when there is none; 5 takes the nearest safe point, else lands where it
/// is; 2 (and the route types 4 and 6) fly the mission's path back, which is not priced here:
/// the straight return home stands for it ([`ReturnRule::approximate`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "autopilot", rename_all = "lowercase")]
pub enum ReturnRule {
    /// ArduPilot's rally rule: `RALLY_LIMIT_KM` (km; 0: no limit) and `RALLY_INCL_HOME`.
    Ardupilot { limit_km: f64, include_home: bool },
    /// PX4's RTL_TYPE.
    Px4 { rtl_type: i32 },
    /// An autopilot without rally points: always home.
    Home,
}

/// ArduCopter's defaults (AP_Rally.cpp, `APM_BUILD_ArduCopter`): RALLY_LIMIT_KM 0.3 km,
/// RALLY_INCL_HOME 1.
pub const ARDUCOPTER_RALLY_LIMIT_KM: f64 = 0.3;
pub const ARDUCOPTER_RALLY_INCL_HOME: bool = true;
/// PX4's default RTL_TYPE (rtl_params.yaml): 0, the nearest of home and the safe points.
pub const PX4_RTL_TYPE: i32 = 0;
/// PX4 takes a safe point only when it is this much nearer than home (rtl.cpp
/// `MIN_DIST_THRESHOLD`, m).
const PX4_MIN_DIST_THRESHOLD_M: f64 = 2.0;
/// PX4 ignores a safe point this near home when home is a choice (rtl.cpp
/// `MAX_DIST_FROM_HOME_FOR_LAND_APPROACHES`, m).
const PX4_SAFE_POINT_MIN_FROM_HOME_M: f64 = 10.0;

/// Where a return goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Destination {
    Home,
    /// The rally point of this index (0-based) among the mission's.
    Rally(usize),
    /// Where the vehicle is (PX4 RTL_TYPE 5 without a safe point: it lands there).
    Here,
}

impl Destination {
    /// "home", "rally point 2" (1-based) or "where it was": how texts and reports name it.
    pub fn describe(self) -> String {
        match self {
            Destination::Home => "home".to_string(),
            Destination::Rally(k) => format!("rally point {}", k + 1),
            Destination::Here => "where it was".to_string(),
        }
    }

    /// The destination's east and north (m) given home's, the rally points' and the vehicle's.
    pub fn at(self, home: [f64; 2], rally: &[[f64; 2]], from: [f64; 2]) -> [f64; 2] {
        match self {
            Destination::Home => home,
            Destination::Rally(k) => rally.get(k).copied().unwrap_or(home),
            Destination::Here => from,
        }
    }
}

impl ReturnRule {
    /// The autopilot's defaults: ArduCopter's rally rule, PX4's RTL_TYPE 0, or home.
    pub fn default_for(autopilot: &str) -> ReturnRule {
        match autopilot {
            "ardupilot" => ReturnRule::Ardupilot {
                limit_km: ARDUCOPTER_RALLY_LIMIT_KM,
                include_home: ARDUCOPTER_RALLY_INCL_HOME,
            },
            "px4" => ReturnRule::Px4 {
                rtl_type: PX4_RTL_TYPE,
            },
            _ => ReturnRule::Home,
        }
    }

    /// The rule with each parameter `value` answers (by the autopilot's name: RALLY_LIMIT_KM,
    /// RALLY_INCL_HOME, RTL_TYPE) in place of its own.
    pub fn with_params(self, value: &dyn Fn(&str) -> Option<f64>) -> ReturnRule {
        match self {
            ReturnRule::Ardupilot {
                limit_km,
                include_home,
            } => ReturnRule::Ardupilot {
                limit_km: value("RALLY_LIMIT_KM")
                    .filter(|v| v.is_finite() && *v >= 0.0)
                    .unwrap_or(limit_km),
                include_home: value("RALLY_INCL_HOME").map_or(include_home, |v| v != 0.0),
            },
            ReturnRule::Px4 { rtl_type } => ReturnRule::Px4 {
                rtl_type: value("RTL_TYPE")
                    .filter(|v| v.is_finite() && v.abs() < 1e6)
                    .map_or(rtl_type, |v| v.round() as i32),
            },
            ReturnRule::Home => ReturnRule::Home,
        }
    }

    /// The parameters that decide it on an autopilot of this rule.
    pub fn param_names(&self) -> &'static [&'static str] {
        match self {
            ReturnRule::Ardupilot { .. } => &["RALLY_LIMIT_KM", "RALLY_INCL_HOME"],
            ReturnRule::Px4 { .. } => &["RTL_TYPE"],
            ReturnRule::Home => &[],
        }
    }

    /// Whether [`ReturnRule::destination`] only stands in for the way the autopilot returns
    /// (PX4's RTL_TYPE 2, 4 and 6 fly the mission's path back, not priced here).
    pub fn approximate(&self) -> bool {
        matches!(self, ReturnRule::Px4 { rtl_type } if !matches!(rtl_type, 0 | 1 | 3 | 5))
    }

    /// "RALLY_LIMIT_KM 0.3, RALLY_INCL_HOME 1" or "RTL_TYPE 0": the parameters, for texts.
    pub fn describe(&self) -> String {
        match self {
            ReturnRule::Ardupilot {
                limit_km,
                include_home,
            } => format!(
                "RALLY_LIMIT_KM {limit_km}, RALLY_INCL_HOME {}",
                u8::from(*include_home)
            ),
            ReturnRule::Px4 { rtl_type } => format!("RTL_TYPE {rtl_type}"),
            ReturnRule::Home => "home only".to_string(),
        }
    }

    /// Where the autopilot's return goes from `from`, given `home` and the mission's `rally`
    /// points (east, north; m: the autopilots measure the horizontal distance).
    pub fn destination(&self, home: [f64; 2], rally: &[[f64; 2]], from: [f64; 2]) -> Destination {
        let dist = |p: [f64; 2]| (p[0] - from[0]).hypot(p[1] - from[1]);
        let home_m = dist(home);
        match *self {
            ReturnRule::Home => Destination::Home,
            ReturnRule::Ardupilot {
                limit_km,
                include_home,
            } => {
                // The nearest rally point, the first of equals (a strict `<`).
                let mut nearest: Option<(usize, f64)> = None;
                for (k, p) in rally.iter().enumerate() {
                    let d = dist(*p);
                    if d.is_finite() && nearest.is_none_or(|(_, m)| d < m) {
                        nearest = Some((k, d));
                    }
                }
                match nearest {
                    None => Destination::Home,
                    Some((_, m)) if limit_km > 0.0 && m > limit_km * 1000.0 => Destination::Home,
                    Some((_, m)) if include_home && m >= home_m => Destination::Home,
                    Some((k, _)) => Destination::Rally(k),
                }
            }
            ReturnRule::Px4 { rtl_type } => {
                let safe_only = rtl_type == 5;
                let home_first = matches!(rtl_type, 0 | 3);
                if !(safe_only || home_first || rtl_type == 1) {
                    return Destination::Home;
                }
                let mut min_m = if home_first { home_m } else { f64::INFINITY };
                let mut chosen = None;
                for (k, p) in rally.iter().enumerate() {
                    let from_home_m = (p[0] - home[0]).hypot(p[1] - home[1]);
                    if !(safe_only || from_home_m > PX4_SAFE_POINT_MIN_FROM_HOME_M) {
                        continue;
                    }
                    let d = dist(*p);
                    if d + PX4_MIN_DIST_THRESHOLD_M < min_m {
                        min_m = d;
                        chosen = Some(k);
                    }
                }
                match (chosen, safe_only) {
                    (Some(k), _) => Destination::Rally(k),
                    (None, true) => Destination::Here,
                    (None, false) => Destination::Home,
                }
            }
        }
    }
}

/// The exclusion zones (1-based indices among `zones`, as [`Zone::describe`] counts them) that
/// the straight line `a`-`b` enters or passes within `margin_m` of.
pub fn exclusions_crossed(
    zones: &[LocalZone],
    a: [f64; 2],
    b: [f64; 2],
    margin_m: f64,
) -> Vec<usize> {
    zones
        .iter()
        .enumerate()
        .filter(|(_, z)| !z.inclusion && z.segment_violates(a, b, margin_m))
        .map(|(k, _)| k + 1)
        .collect()
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

    #[test]
    fn a_zone_pushed_out_keeps_every_line_between_its_points_clear_of_it_by_the_distance() {
        let round = |p: &[[f64; 2]]| -> Vec<[i64; 2]> {
            p.iter()
                .map(|q| [(q[0] * 1e6).round() as i64, (q[1] * 1e6).round() as i64])
                .collect()
        };
        // A square's right-angle corners: one point each, on the diagonal, d * sqrt(2) out.
        assert_eq!(
            round(&square(false).offset_vertices(2.0)),
            round(&[[-2.0, -2.0], [12.0, -2.0], [12.0, 12.0], [-2.0, 12.0]])
        );
        // Shrunk: the miter points, d in from both sides; either winding.
        let mut cw = square(true);
        if let LocalShape::Polygon(v) = &mut cw.shape {
            v.reverse();
        }
        assert_eq!(
            round(&cw.offset_vertices(2.0)),
            round(&[[2.0, 8.0], [8.0, 8.0], [8.0, 2.0], [2.0, 2.0]])
        );
        // A sharp triangle and an L-shaped field: every line between consecutive points of
        // the offset is at least d from the zone.
        let zones = [
            LocalZone {
                inclusion: false,
                shape: LocalShape::Polygon(vec![[0.0, 0.0], [40.0, 0.0], [20.0, 3.0]]),
            },
            LocalZone {
                inclusion: true,
                shape: LocalShape::Polygon(vec![
                    [0.0, 0.0],
                    [60.0, 0.0],
                    [60.0, 20.0],
                    [20.0, 20.0],
                    [20.0, 60.0],
                    [0.0, 60.0],
                ]),
            },
            LocalZone {
                inclusion: false,
                shape: LocalShape::Circle {
                    center: [5.0, 5.0],
                    radius_m: 10.0,
                },
            },
        ];
        for zone in &zones {
            let p = zone.offset_vertices(3.0);
            assert!(p.len() >= 3);
            for i in 0..p.len() {
                let (a, b) = (p[i], p[(i + 1) % p.len()]);
                assert!(!zone.segment_violates(a, b, 3.0 - 1e-9), "{a:?} {b:?}");
            }
        }
        let field = LocalZone {
            inclusion: true,
            shape: LocalShape::Circle {
                center: [0.0, 0.0],
                radius_m: 10.0,
            },
        };
        assert!(field.offset_vertices(3.0).is_empty());
    }

    fn rally_rule_cases() -> (ReturnRule, ReturnRule) {
        (
            ReturnRule::default_for("ardupilot"),
            ReturnRule::default_for("px4"),
        )
    }

    #[test]
    fn arducopter_returns_to_the_nearest_rally_point_only_when_it_is_nearer_than_home() {
        let (ap, _) = rally_rule_cases();
        let home = [0.0, 0.0];
        let rally = [[100.0, 0.0], [0.0, 60.0]];
        // Near the second rally point: it, not the first, nor home.
        assert_eq!(
            ap.destination(home, &rally, [10.0, 70.0]),
            Destination::Rally(1)
        );
        assert_eq!(
            ap.destination(home, &rally, [90.0, 0.0]),
            Destination::Rally(0)
        );
        // Home nearer than every rally point: home (RALLY_INCL_HOME 1).
        assert_eq!(ap.destination(home, &rally, [5.0, 5.0]), Destination::Home);
        // Without home included, the nearest rally point even when home is nearer.
        let no_home = ReturnRule::Ardupilot {
            limit_km: 0.3,
            include_home: false,
        };
        assert_eq!(
            no_home.destination(home, &rally, [5.0, 5.0]),
            Destination::Rally(1)
        );
        // Beyond RALLY_LIMIT_KM: home, even when the rally point is nearer.
        let far = [[1000.0, 0.0]];
        assert_eq!(ap.destination(home, &far, [690.0, 0.0]), Destination::Home);
        let unlimited = ReturnRule::Ardupilot {
            limit_km: 0.0,
            include_home: true,
        };
        assert_eq!(
            unlimited.destination(home, &far, [690.0, 0.0]),
            Destination::Rally(0)
        );
        assert_eq!(ap.destination(home, &[], [690.0, 0.0]), Destination::Home);
    }

    #[test]
    fn px4_returns_to_a_safe_point_by_its_rtl_type() {
        let (_, px4) = rally_rule_cases();
        let home = [0.0, 0.0];
        let rally = [[100.0, 0.0], [5.0, 0.0]];
        assert_eq!(
            px4.destination(home, &rally, [80.0, 0.0]),
            Destination::Rally(0)
        );
        assert_eq!(
            px4.destination(home, &rally, [20.0, 0.0]),
            Destination::Home
        );
        // Within 2 m of home's distance: home.
        assert_eq!(
            px4.destination(home, &rally, [51.0, 0.0]),
            Destination::Home
        );
        // A safe point within 10 m of home is never taken while home is a choice.
        assert_eq!(
            px4.destination(home, &[[5.0, 0.0]], [5.0, 1.0]),
            Destination::Home
        );
        let prefer_safe = ReturnRule::Px4 { rtl_type: 1 };
        assert_eq!(
            prefer_safe.destination(home, &rally, [20.0, 0.0]),
            Destination::Rally(0)
        );
        assert_eq!(
            prefer_safe.destination(home, &[], [20.0, 0.0]),
            Destination::Home
        );
        let safe_only = ReturnRule::Px4 { rtl_type: 5 };
        assert_eq!(
            safe_only.destination(home, &rally, [2.0, 0.0]),
            Destination::Rally(1)
        );
        assert_eq!(
            safe_only.destination(home, &[], [2.0, 0.0]),
            Destination::Here
        );
        let mission_path = ReturnRule::Px4 { rtl_type: 2 };
        assert!(mission_path.approximate() && !px4.approximate());
        assert_eq!(
            mission_path.destination(home, &rally, [99.0, 0.0]),
            Destination::Home
        );
        assert_eq!(
            ReturnRule::Home.destination(home, &rally, [99.0, 0.0]),
            Destination::Home
        );
    }

    #[test]
    fn a_straight_return_through_an_exclusion_zone_names_it() {
        let zones = [square(true), square(false)];
        assert_eq!(
            exclusions_crossed(&zones, [-5.0, 5.0], [15.0, 5.0], 0.0),
            vec![2]
        );
        assert!(exclusions_crossed(&zones, [-5.0, 15.0], [15.0, 15.0], 1.0).is_empty());
    }
}
