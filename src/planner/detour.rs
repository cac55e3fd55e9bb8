//! Detours: every leg the planner prices (node 0, the origin, included) that would enter an
//! exclusion zone, leave an inclusion zone or pass nearer than a margin to a zone's boundary
//! is routed round the zone(s) through points flown without a hold (`Leg::via`), the cheapest
//! way round in energy.
//!
//! The route: a visibility graph, built once per mission, over the zones' vertices pushed out
//! by the margin and the corner the autopilot cuts ([`LocalZone::offset_vertices`]: exclusion
//! zones grown, inclusion zones shrunk, circles as a circumscribed polygon), its edges the
//! lines between them clear of every zone by the margin, its shortest paths between every two
//! vertices found once. A leg's candidate paths are the shortest through each vertex its start
//! sees first (so both ways round each zone are among them), the [`CANDIDATES`] shortest of
//! those; each is priced as the chain of legs it is ([`price_chain`]) and the cheapest in
//! energy is flown. A pair whose straight line is clear costs what it costs without a fence:
//! only pairs near a zone are routed.
//!
//! A via point's height is interpolated between the leg's two ends along the path's
//! horizontal length: the path climbs or descends no more than the straight leg (its absolute
//! vertical distance is the leg's), at the straight leg's mean gradient, never above the
//! higher end (so never above the height limit the ends were checked against).
//!
//! A leg's end nearer to a zone's boundary than the margin (a waypoint placed near the edge of
//! its field) cannot be helped: such a leg keeps that zone no nearer than its end does. A pair
//! with no route is refused naming both ends and the zone.

use std::collections::HashMap;

use rayon::prelude::*;

use crate::mission::fence::LocalZone;
use crate::mission::{Enu, Mission};
use crate::physics::ardupilot_chain::ChainPoint;
use crate::physics::power::Model;
use crate::physics::{heading_deg, start_case, LegEnergy, PhysicsError, Profile, Start};

use super::VehicleModel;

/// How far every leg keeps from a fence zone's boundary (m). The sum of:
/// - 2 m: ArduPilot's FENCE_MARGIN default (`AC_FENCE_MARGIN_DEFAULT`, AC_Fence.cpp), the
///   distance the autopilot itself keeps from a fence before it counts a breach as near;
/// - 2.5 m: the horizontal error of the GNSS receivers these vehicles fly (u-blox M8, 2.5 m
///   CEP, its data sheet), the vehicle being where its estimate says within it half the time;
/// - 0.5 m: ArduCopter's and PX4's cross-track error tracking a straight line in calm air,
///   well under a metre in both SITLs' logs of the shipped missions.
pub const FENCE_MARGIN_M: f64 = 5.0;

/// How much further out a via point is placed than the margin (m): ArduCopter blends the turn
/// at a fast waypoint, its track passing within WPNAV_RADIUS (default 200 cm,
/// `WPNAV_WP_RADIUS_CM`, AC_WPNav.cpp) of the waypoint on the inside of the turn, which
/// round a zone is towards it; PX4's acceptance radius for a multicopter's waypoint (NAV_ACC_RAD
/// and the trajectory's corner) is no larger.
pub const CORNER_CUT_M: f64 = 2.0;

/// The candidate paths priced for each routed leg.
pub const CANDIDATES: usize = 4;

/// One leg routed round the fence.
#[derive(Debug, Clone, PartialEq)]
pub struct Detour {
    /// The points it passes through, in the mission's local frame.
    pub via: Vec<Enu>,
    /// The zones its straight line broke (0-based indices into the fence's zones).
    pub zones: Vec<usize>,
    /// The chain's price from rest (`Start::Behind`), as the energy matrix holds it.
    pub predicted: LegEnergy,
}

/// The legs of a mission routed round its fence, by (from, to) node.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Detours {
    pub legs: HashMap<(usize, usize), Detour>,
}

impl Detours {
    /// The detour of leg `from` -> `to`, if it has one.
    pub fn get(&self, from: usize, to: usize) -> Option<&Detour> {
        if self.legs.is_empty() {
            return None;
        }
        self.legs.get(&(from, to))
    }

    /// The via points of every routed leg (what `tour::Geometry::with_via` takes).
    pub fn via(&self) -> HashMap<(usize, usize), Vec<Enu>> {
        self.legs.iter().map(|(&k, d)| (k, d.via.clone())).collect()
    }
}

/// A leg the fence leaves no way round.
#[derive(Debug, Clone, PartialEq)]
pub struct NoRoute {
    pub from: usize,
    pub to: usize,
    /// The zone its straight line broke (0-based).
    pub zone: usize,
}

/// The fence in the mission's local frame, with its visibility graph.
#[derive(Debug, Clone)]
pub struct Router {
    zones: Vec<LocalZone>,
    margin_m: f64,
    /// The graph's vertices: the zones' offset vertices clear of every zone.
    vertices: Vec<[f64; 2]>,
    /// Shortest path lengths between vertices (row-major, infinite when none) and the next
    /// vertex on each.
    dist: Vec<f64>,
    next: Vec<usize>,
}

impl Router {
    /// The graph of `zones` for legs kept `margin_m` from them.
    pub fn new(zones: Vec<LocalZone>, margin_m: f64) -> Router {
        let mut router = Router {
            zones,
            margin_m,
            vertices: Vec::new(),
            dist: Vec::new(),
            next: Vec::new(),
        };
        let offset_m = margin_m + CORNER_CUT_M;
        let vertices: Vec<[f64; 2]> = router
            .zones
            .iter()
            .flat_map(|z| z.offset_vertices(offset_m))
            .filter(|&p| router.point_clear(p))
            .collect();
        let n = vertices.len();
        let mut dist = vec![f64::INFINITY; n * n];
        let mut next = vec![usize::MAX; n * n];
        let rows: Vec<Vec<(usize, f64)>> = (0..n)
            .into_par_iter()
            .map(|u| {
                ((u + 1)..n)
                    .filter(|&v| router.blocking(vertices[u], vertices[v]).is_empty())
                    .map(|v| (v, length(vertices[u], vertices[v])))
                    .collect()
            })
            .collect();
        for u in 0..n {
            dist[u * n + u] = 0.0;
            next[u * n + u] = u;
        }
        for (u, row) in rows.into_iter().enumerate() {
            for (v, d) in row {
                dist[u * n + v] = d;
                dist[v * n + u] = d;
                next[u * n + v] = v;
                next[v * n + u] = u;
            }
        }
        // Floyd-Warshall: the graph has a few points a zone.
        for k in 0..n {
            for i in 0..n {
                let dik = dist[i * n + k];
                if !dik.is_finite() {
                    continue;
                }
                for j in 0..n {
                    let through = dik + dist[k * n + j];
                    if through < dist[i * n + j] {
                        dist[i * n + j] = through;
                        next[i * n + j] = next[i * n + k];
                    }
                }
            }
        }
        router.vertices = vertices;
        router.dist = dist;
        router.next = next;
        router
    }

    /// The margin legs keep (m).
    pub fn margin_m(&self) -> f64 {
        self.margin_m
    }

    /// True when the point breaks no zone and is at least the margin from every boundary.
    fn point_clear(&self, p: [f64; 2]) -> bool {
        self.zones
            .iter()
            .all(|z| !z.violated_by(p) && z.distance_to_boundary_m(p) >= self.margin_m)
    }

    /// The zones (0-based) the straight line `a`-`b` breaks: it enters an exclusion zone,
    /// leaves an inclusion zone, or passes nearer than the margin to a boundary (or than its
    /// nearer end is, when an end is nearer than the margin).
    pub fn blocking(&self, a: [f64; 2], b: [f64; 2]) -> Vec<usize> {
        (0..self.zones.len())
            .filter(|&k| zone_blocks(&self.zones[k], a, b, self.margin_m))
            .collect()
    }

    /// The graph's vertices the point sees: the line to each is clear.
    pub fn visible(&self, p: [f64; 2]) -> Vec<usize> {
        (0..self.vertices.len())
            .filter(|&v| self.blocking(p, self.vertices[v]).is_empty())
            .collect()
    }

    /// Up to `k` paths from `a` to `b` round the zones (their inner points, the ends left
    /// out), shortest first: for each vertex `a` sees (`seen_a`, from [`Router::visible`]),
    /// the shortest path through it to a vertex `b` sees.
    pub fn candidates(
        &self,
        a: [f64; 2],
        seen_a: &[usize],
        b: [f64; 2],
        seen_b: &[usize],
        k: usize,
    ) -> Vec<Vec<[f64; 2]>> {
        let n = self.vertices.len();
        let mut firsts: Vec<(f64, usize, usize)> = seen_a
            .iter()
            .filter_map(|&u| {
                seen_b
                    .iter()
                    .map(|&v| {
                        let d = length(a, self.vertices[u])
                            + self.dist[u * n + v]
                            + length(self.vertices[v], b);
                        (d, u, v)
                    })
                    .filter(|(d, _, _)| d.is_finite())
                    .min_by(|x, y| x.0.total_cmp(&y.0))
            })
            .collect();
        firsts.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mut paths: Vec<Vec<[f64; 2]>> = Vec::new();
        for (_, u, v) in firsts {
            if paths.len() >= k {
                break;
            }
            let mut hops = vec![u];
            let mut at = u;
            while at != v && hops.len() <= n {
                at = self.next[at * n + v];
                hops.push(at);
            }
            let path: Vec<[f64; 2]> = hops.iter().map(|&h| self.vertices[h]).collect();
            if !paths.contains(&path) {
                paths.push(path);
            }
        }
        paths
    }
}

/// Whether the line `a`-`b` breaks `zone` with `margin_m` (less where an end is nearer).
fn zone_blocks(zone: &LocalZone, a: [f64; 2], b: [f64; 2], margin_m: f64) -> bool {
    if zone.violated_by(a) || zone.violated_by(b) {
        return true;
    }
    // An end nearer than the margin: the leg may come as near as that end, no nearer (a
    // hair less, so that the end itself, at exactly its own distance, does not count).
    let ends_m = zone
        .distance_to_boundary_m(a)
        .min(zone.distance_to_boundary_m(b));
    let margin_m = margin_m.min(ends_m * (1.0 - 1e-9));
    zone.segment_violates(a, b, margin_m)
}

fn length(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

fn xy(p: Enu) -> [f64; 2] {
    [p.x_east_m, p.y_north_m]
}

/// The via points of a path from `from` to `to` through `inner` (east, north), each at the
/// height interpolated along the path's horizontal length.
pub fn with_heights(from: Enu, inner: &[[f64; 2]], to: Enu) -> Vec<Enu> {
    let mut along = Vec::with_capacity(inner.len());
    let mut at = xy(from);
    let mut run = 0.0;
    for &p in inner {
        run += length(at, p);
        along.push(run);
        at = p;
    }
    let total = run + length(at, xy(to));
    inner
        .iter()
        .zip(along)
        .map(|(p, s)| Enu {
            x_east_m: p[0],
            y_north_m: p[1],
            z_up_m: if total > 0.0 {
                from.z_up_m + (to.z_up_m - from.z_up_m) * s / total
            } else {
                from.z_up_m
            },
        })
        .collect()
}

/// The chain of legs `from` -> `via`... -> `to`, the via points flown through without a hold
/// and `to` reached at rest, priced as `model` prices such a chain, which is how the flight is
/// measured: with the `ardupilot` profile ArduCopter's chain of fast waypoints, corners blended
/// (`physics::ardupilot_chain`, as `session::predict` prices a flown order with fast
/// waypoints); with the others each leg rest to rest from the table (or simulated, in wind or
/// at a set speed) after the leg before it (`physics::start_case`, which only the `px4`
/// profile's price depends on), the first starting `start`. Its energy to the 4 m rule is
/// everything up to the 4 m rule of `to`; its settle is the last leg's.
pub fn price_chain(
    model: &VehicleModel,
    from: Enu,
    via: &[Enu],
    to: Enu,
    start: Start,
) -> Result<LegEnergy, PhysicsError> {
    let points: Vec<Enu> = via.iter().copied().chain(std::iter::once(to)).collect();
    let fast: Vec<bool> = (0..points.len()).map(|k| k + 1 < points.len()).collect();
    Ok(joined(&chain_parts(model, from, &points, &fast, start)?))
}

/// The legs of the chain `from` -> `points`... one by one, as [`price_chain`] prices them:
/// with the `ardupilot` profile ArduCopter's chain, the points with `fast[k]` flown through
/// (the last one never is); with the others each leg rest to rest after the leg before, the
/// first starting `start`.
pub fn chain_parts(
    model: &VehicleModel,
    from: Enu,
    points: &[Enu],
    fast: &[bool],
    start: Start,
) -> Result<Vec<LegEnergy>, PhysicsError> {
    if model.profile == Profile::Ardupilot {
        let vehicle = match model.speed_m_s {
            Some(v) => model.vehicle.at_speed(v),
            None => model.vehicle.clone(),
        };
        let chain: Vec<ChainPoint> = points
            .iter()
            .enumerate()
            .map(|(k, p)| ChainPoint {
                enu_m: [p.x_east_m, p.y_north_m, p.z_up_m],
                fast: k + 1 < points.len() && fast.get(k).copied().unwrap_or(false),
            })
            .collect();
        return Ok(Model::new(&vehicle)
            .ardupilot_chain_in_wind(
                [from.x_east_m, from.y_north_m, from.z_up_m],
                &chain,
                model.wind,
            )?
            .iter()
            .map(LegEnergy::from)
            .collect());
    }
    let mut parts = Vec::with_capacity(points.len());
    let mut previous = None;
    let mut a = from;
    for (k, &b) in points.iter().enumerate() {
        let (dx, dy) = (b.x_east_m - a.x_east_m, b.y_north_m - a.y_north_m);
        let s = if k == 0 {
            start
        } else {
            start_case(previous, (dx, dy))
        };
        parts.push(model.leg_on_heading(
            dx.hypot(dy),
            b.z_up_m - a.z_up_m,
            s,
            heading_deg(dx, dy),
        )?);
        previous = Some((dx, dy));
        a = b;
    }
    Ok(parts)
}

/// The legs of a chain as one leg: everything before the last leg's 4 m rule, then its settle.
pub fn joined(parts: &[LegEnergy]) -> LegEnergy {
    let Some((last, before)) = parts.split_last() else {
        return LegEnergy {
            energy_j: 0.0,
            duration_s: 0.0,
            settle_energy_j: 0.0,
            settle_duration_s: 0.0,
        };
    };
    LegEnergy {
        energy_j: before.iter().map(LegEnergy::total_energy_j).sum::<f64>() + last.energy_j,
        duration_s: before.iter().map(LegEnergy::total_duration_s).sum::<f64>() + last.duration_s,
        settle_energy_j: last.settle_energy_j,
        settle_duration_s: last.settle_duration_s,
    }
}

/// A leg and its detour.
type RoutedLeg = ((usize, usize), Detour);

/// Why routing stopped.
#[derive(Debug)]
pub enum RouteError<E> {
    NoRoute(NoRoute),
    /// The pricing of a candidate failed.
    Price(E),
}

/// Routes every pair of `points` (node 0 the origin) whose straight line breaks a zone of
/// `mission`'s fence, `margin_m` from every zone, choosing among the candidates the one of
/// least `score` of its price by `price(from, to, via)`.
pub fn route<E: Send>(
    mission: &Mission,
    points: &[Enu],
    margin_m: f64,
    price: impl Fn(usize, usize, &[Enu]) -> Result<LegEnergy, E> + Sync,
    score: impl Fn(&LegEnergy) -> f64 + Sync,
) -> Result<Detours, RouteError<E>> {
    if mission.fence.is_empty() {
        return Ok(Detours::default());
    }
    let zones: Vec<LocalZone> = mission
        .fence
        .zones
        .iter()
        .map(|z| z.local(&mission.origin))
        .collect();
    let router = Router::new(zones, margin_m);
    route_with(&router, points, price, score)
}

/// [`route`] with a router already built.
pub fn route_with<E: Send>(
    router: &Router,
    points: &[Enu],
    price: impl Fn(usize, usize, &[Enu]) -> Result<LegEnergy, E> + Sync,
    score: impl Fn(&LegEnergy) -> f64 + Sync,
) -> Result<Detours, RouteError<E>> {
    let n = points.len();
    // The pairs whose straight line breaks a zone (the line is the same both ways).
    let blocked: Vec<(usize, usize, Vec<usize>)> = (0..n)
        .into_par_iter()
        .flat_map_iter(|i| {
            ((i + 1)..n).filter_map(move |j| {
                let zones = router.blocking(xy(points[i]), xy(points[j]));
                (!zones.is_empty()).then_some((i, j, zones))
            })
        })
        .collect();
    if blocked.is_empty() {
        return Ok(Detours::default());
    }
    let mut involved: Vec<usize> = blocked.iter().flat_map(|(i, j, _)| [*i, *j]).collect();
    involved.sort_unstable();
    involved.dedup();
    let seen: HashMap<usize, Vec<usize>> = involved
        .par_iter()
        .map(|&p| (p, router.visible(xy(points[p]))))
        .collect();
    let routed: Vec<Result<Vec<RoutedLeg>, RouteError<E>>> = blocked
        .into_par_iter()
        .map(|(i, j, zones)| {
            let (a, b) = (xy(points[i]), xy(points[j]));
            let paths = router.candidates(a, &seen[&i], b, &seen[&j], CANDIDATES);
            if paths.is_empty() {
                return Err(RouteError::NoRoute(NoRoute {
                    from: i,
                    to: j,
                    zone: zones[0],
                }));
            }
            let mut both = Vec::with_capacity(2);
            for (from, to) in [(i, j), (j, i)] {
                let mut best: Option<(f64, Vec<Enu>, LegEnergy)> = None;
                for path in &paths {
                    let inner: Vec<[f64; 2]> = if from == i {
                        path.clone()
                    } else {
                        path.iter().rev().copied().collect()
                    };
                    let via = with_heights(points[from], &inner, points[to]);
                    let priced = price(from, to, &via).map_err(RouteError::Price)?;
                    let s = score(&priced);
                    if best.as_ref().is_none_or(|(b, _, _)| s < *b) {
                        best = Some((s, via, priced));
                    }
                }
                if let Some((_, via, predicted)) = best {
                    both.push((
                        (from, to),
                        Detour {
                            via,
                            zones: zones.clone(),
                            predicted,
                        },
                    ));
                }
            }
            Ok(both)
        })
        .collect();
    let mut legs = HashMap::new();
    for r in routed {
        legs.extend(r?);
    }
    Ok(Detours { legs })
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::mission::fence::{LatLon, LocalShape, Shape, Zone};
    use crate::physics::VehicleModel;
    use crate::planner::{plan_mission, Orders, Plan, PlanOptions, PlannerError};

    fn model(profile: Profile) -> VehicleModel {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000");
        VehicleModel::load(&dir, Some(profile)).unwrap()
    }

    fn base() -> Mission {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/paper-sample-8wp.toml");
        crate::mission::load(&path).unwrap()
    }

    fn enu(x: f64, y: f64, z: f64) -> Enu {
        Enu {
            x_east_m: x,
            y_north_m: y,
            z_up_m: z,
        }
    }

    /// `mission` with its waypoints at `points` (local frame), no actions.
    fn at(mut mission: Mission, points: &[Enu]) -> Mission {
        let template = mission.waypoints[0].clone();
        mission.waypoints = points
            .iter()
            .enumerate()
            .map(|(k, &p)| crate::mission::Waypoint {
                name: format!("W{}", k + 1),
                position: p,
                actions: Vec::new(),
                ..template.clone()
            })
            .collect();
        mission.start_actions.clear();
        mission
    }

    /// A zone of `mission` from its local shape.
    fn zone(mission: &Mission, inclusion: bool, shape: &LocalShape) -> Zone {
        let ll = |p: [f64; 2]| {
            let g = mission.origin.to_geodetic(enu(p[0], p[1], 0.0));
            LatLon {
                lat_deg: g.lat_deg,
                lon_deg: g.lon_deg,
            }
        };
        Zone {
            inclusion,
            shape: match shape {
                LocalShape::Polygon(v) => Shape::Polygon(v.iter().map(|&p| ll(p)).collect()),
                LocalShape::Circle { center, radius_m } => Shape::Circle {
                    center: ll(*center),
                    radius_m: *radius_m,
                },
            },
        }
    }

    fn square(x0: f64, y0: f64, x1: f64, y1: f64) -> LocalShape {
        LocalShape::Polygon(vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    }

    /// Every point of leg `from` -> `to` of `plan`, its ends included.
    fn path(mission: &Mission, leg: &crate::planner::Leg) -> Vec<Enu> {
        let p = |n: usize| {
            if n == 0 {
                Enu::default()
            } else {
                mission.waypoints[n - 1].position
            }
        };
        std::iter::once(p(leg.from))
            .chain(leg.via.iter().copied())
            .chain(std::iter::once(p(leg.to)))
            .collect()
    }

    /// The 8-waypoint sample with an exclusion square across the middle of its field, which
    /// many of its legs cross or pass within the margin of.
    fn fenced_sample() -> Mission {
        let mut mission = base();
        let z = zone(&mission, false, &square(-4.0, 6.0, 4.0, 14.0));
        mission.fence.zones.push(z);
        mission
    }

    #[test]
    fn a_detour_is_priced_as_the_chain_of_its_legs_priced_one_by_one() {
        for profile in [Profile::Px4, Profile::Ptf, Profile::Ardupilot] {
            let model = model(profile);
            let mission = fenced_sample();
            let plan = plan_mission(&mission, &model, &PlanOptions::default()).unwrap();
            let mut detours = 0;
            let across = |a: Enu, b: Enu| {
                [
                    b.x_east_m - a.x_east_m,
                    b.y_north_m - a.y_north_m,
                    b.z_up_m - a.z_up_m,
                ]
            };
            for order in &plan.orders {
                let mut previous: Option<[f64; 3]> = None;
                for leg in &order.legs {
                    let points = path(&mission, leg);
                    if !leg.via.is_empty() {
                        detours += 1;
                        let parts: Vec<LegEnergy> = if profile == Profile::Ardupilot {
                            let chain: Vec<ChainPoint> = points[1..]
                                .iter()
                                .enumerate()
                                .map(|(k, p)| ChainPoint {
                                    enu_m: [p.x_east_m, p.y_north_m, p.z_up_m],
                                    fast: k + 2 < points.len(),
                                })
                                .collect();
                            let p0 = points[0];
                            Model::new(&model.vehicle)
                                .ardupilot_chain([p0.x_east_m, p0.y_north_m, p0.z_up_m], &chain)
                                .unwrap()
                                .iter()
                                .map(LegEnergy::from)
                                .collect()
                        } else {
                            let arr = |p: Enu| [p.x_east_m, p.y_north_m, p.z_up_m];
                            (1..points.len())
                                .map(|k| {
                                    // `leg_after` takes the leg before as its
                                    // displacement.
                                    let before = if k == 1 {
                                        previous
                                    } else {
                                        Some(across(points[k - 2], points[k - 1]))
                                    };
                                    model
                                        .leg_after(before, arr(points[k - 1]), arr(points[k]))
                                        .unwrap()
                                })
                                .collect()
                        };
                        let total: f64 = parts.iter().map(LegEnergy::total_energy_j).sum();
                        let to_rule: f64 = parts.iter().map(LegEnergy::total_energy_j).sum::<f64>()
                            - parts.last().unwrap().settle_energy_j;
                        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1.0);
                        assert!(
                            close(leg.predicted.total_energy_j(), total),
                            "{profile}: {} J against the chain's {total} J",
                            leg.predicted.total_energy_j()
                        );
                        assert!(close(leg.predicted.energy_j, to_rule));
                        let duration: f64 = parts.iter().map(LegEnergy::total_duration_s).sum();
                        assert!(close(leg.predicted.total_duration_s(), duration));
                        // The matrix the solvers see holds the same price (from rest).
                        if leg.start == Start::Behind {
                            assert!(close(plan.energy.cost(leg.from, leg.to), leg.energy_j()));
                        }
                        // Its length is the path's.
                        let length: f64 = points
                            .windows(2)
                            .map(|w| {
                                (w[1].x_east_m - w[0].x_east_m)
                                    .hypot(w[1].y_north_m - w[0].y_north_m)
                                    .hypot(w[1].z_up_m - w[0].z_up_m)
                            })
                            .sum();
                        assert!(close(leg.distance_m, length));
                    }
                    previous = Some(across(points[points.len() - 2], points[points.len() - 1]));
                }
            }
            assert!(detours > 0, "{profile}: the square on a leg made no detour");
        }
    }

    #[test]
    fn the_cheapest_detour_in_energy_is_not_the_shortest() {
        // A wall across the straight line from W1 to W2, and a pole well north of it: round
        // the wall is two turns (at its corners) and 104 m; over the pole's south side one
        // turn and 110 m. Each turn of the px4 profile is a stop: the longer way is cheaper.
        let model = model(Profile::Px4);
        let mut mission = at(base(), &[enu(0.0, 0.0, 5.0), enu(100.0, 0.0, 5.0)]);
        let wall = zone(&mission, false, &square(30.0, -3.0, 70.0, 3.0));
        let pole = zone(
            &mission,
            false,
            &LocalShape::Circle {
                center: [50.0, 33.0],
                radius_m: 3.0,
            },
        );
        mission.fence.zones = vec![wall, pole];
        let zones: Vec<LocalZone> = mission
            .fence
            .zones
            .iter()
            .map(|z| z.local(&mission.origin))
            .collect();
        let router = Router::new(zones, FENCE_MARGIN_M);
        let (a, b) = (mission.waypoints[0].position, mission.waypoints[1].position);
        let paths = router.candidates(
            xy(a),
            &router.visible(xy(a)),
            xy(b),
            &router.visible(xy(b)),
            CANDIDATES,
        );
        let priced: Vec<(f64, f64, usize)> = paths
            .iter()
            .map(|inner| {
                let via = with_heights(a, inner, b);
                let length: f64 = std::iter::once(a)
                    .chain(via.iter().copied())
                    .chain(std::iter::once(b))
                    .collect::<Vec<_>>()
                    .windows(2)
                    .map(|w| (w[1].x_east_m - w[0].x_east_m).hypot(w[1].y_north_m - w[0].y_north_m))
                    .sum();
                let energy = price_chain(&model, a, &via, b, Start::Behind)
                    .unwrap()
                    .total_energy_j();
                (length, energy, via.len())
            })
            .collect();
        let shortest = priced
            .iter()
            .min_by(|x, y| x.0.total_cmp(&y.0))
            .copied()
            .unwrap();
        let cheapest = priced
            .iter()
            .min_by(|x, y| x.1.total_cmp(&y.1))
            .copied()
            .unwrap();
        eprintln!("candidates (m, J, via points): {priced:?}");
        assert_eq!(
            (shortest.2, cheapest.2),
            (2, 1),
            "candidates (m, J, points): {priced:?}"
        );
        assert!(
            cheapest.0 > shortest.0 + 3.0 && cheapest.1 < shortest.1 - 500.0,
            "candidates (m, J, points): {priced:?}"
        );
        // The plan flies the cheapest, the solvers and every order see it.
        let plan = plan_mission(&mission, &model, &PlanOptions::default()).unwrap();
        let leg = plan
            .flown()
            .legs
            .iter()
            .find(|l| (l.from, l.to) == (1, 2) || (l.from, l.to) == (2, 1))
            .unwrap();
        assert_eq!(leg.via.len(), 1, "{:?}", leg.via);
        assert!((leg.horizontal_m - cheapest.0).abs() < 1e-6);
    }

    /// The `plan`'s legs, each checked clear of every zone of `mission` by the margin (or by
    /// what its ends allow); the number of legs with via points.
    fn assert_clear(mission: &Mission, plan: &Plan) -> usize {
        let zones: Vec<LocalZone> = mission
            .fence
            .zones
            .iter()
            .map(|z| z.local(&mission.origin))
            .collect();
        let mut routed = 0;
        let orders = plan.orders.iter().chain(
            plan.sorties
                .iter()
                .flat_map(|s| s.sorties.iter())
                .map(|_| &plan.orders[0]),
        );
        for order in orders {
            for leg in &order.legs {
                routed += usize::from(!leg.via.is_empty());
                let points = path(mission, leg);
                let last = points.len() - 1;
                for (k, w) in points.windows(2).enumerate() {
                    let (a, b) = (xy(w[0]), xy(w[1]));
                    for (z, zone) in zones.iter().enumerate() {
                        // Only a waypoint's own nearness to the zone excuses a nearer leg.
                        let mut margin = FENCE_MARGIN_M;
                        if k == 0 {
                            margin = margin.min(zone.distance_to_boundary_m(a));
                        }
                        if k + 1 == last {
                            margin = margin.min(zone.distance_to_boundary_m(b));
                        }
                        let clearance = zone.segment_distance_to_boundary_m(a, b);
                        assert!(
                            !zone.violated_by(a)
                                && !zone.violated_by(b)
                                && clearance >= margin - 1e-6,
                            "{:?}: leg {} -> {} part {k} is {clearance} m from zone {z}",
                            order.objective,
                            plan.name(leg.from),
                            plan.name(leg.to)
                        );
                    }
                }
            }
        }
        routed
    }

    #[test]
    fn every_leg_of_every_order_keeps_the_margin_from_every_zone_of_random_fenced_missions() {
        let model = model(Profile::Ptf);
        let mut rng = crate::rng::Rng::new(45);
        let (mut planned, mut routed) = (0, 0);
        for _ in 0..40 {
            let mut mission = base();
            let mut shapes: Vec<(bool, LocalShape)> = Vec::new();
            // A field (sometimes), and one to three exclusion zones inside it.
            if rng.chance(0.5) {
                shapes.push((
                    true,
                    LocalShape::Polygon(vec![
                        [-70.0, -70.0],
                        [70.0, -70.0],
                        [70.0, 10.0],
                        [rng.uniform(-10.0, 10.0), rng.uniform(10.0, 30.0)],
                        [10.0, 70.0],
                        [-70.0, 70.0],
                    ]),
                ));
            }
            for _ in 0..1 + rng.below(3) {
                let (cx, cy) = (rng.uniform(-40.0, 40.0), rng.uniform(-40.0, 40.0));
                let shape = if rng.chance(0.5) {
                    LocalShape::Circle {
                        center: [cx, cy],
                        radius_m: rng.uniform(2.0, 12.0),
                    }
                } else {
                    let (w, h) = (rng.uniform(2.0, 25.0), rng.uniform(2.0, 25.0));
                    square(cx - w, cy - h, cx + w, cy + h)
                };
                shapes.push((false, shape));
            }
            let local: Vec<LocalZone> = shapes
                .iter()
                .map(|(inclusion, shape)| LocalZone {
                    inclusion: *inclusion,
                    shape: shape.clone(),
                })
                .collect();
            let mut points = Vec::new();
            while points.len() < 3 + rng.below(5) {
                let p = enu(
                    rng.uniform(-60.0, 60.0),
                    rng.uniform(-60.0, 60.0),
                    rng.uniform(-5.0, 20.0),
                );
                if local.iter().all(|z| !z.violated_by(xy(p))) {
                    points.push(p);
                }
            }
            mission = at(mission, &points);
            mission.fence.zones = shapes
                .iter()
                .map(|(inclusion, shape)| zone(&mission, *inclusion, shape))
                .collect();
            let options = PlanOptions::default();
            match plan_mission(&mission, &model, &options) {
                Ok(plan) => {
                    planned += 1;
                    routed += assert_clear(&mission, &plan);
                    assert_eq!(plan.orders.len(), 7);
                }
                // A waypoint the zones box in, or the origin outside the field: refused,
                // naming the leg and the zone.
                Err(PlannerError::NoDetour { zone, .. }) => {
                    assert!(zone.contains("polygon") || zone.contains("circle"));
                }
                Err(other) => panic!("{other}"),
            }
            let listed = PlanOptions {
                orders: Orders::Listed,
                ..PlanOptions::default()
            };
            if let Ok(plan) = plan_mission(&mission, &model, &listed) {
                assert_clear(&mission, &plan);
            }
        }
        assert!(
            planned >= 20 && routed >= 20,
            "{planned} planned, {routed} legs routed"
        );
    }

    #[test]
    fn a_waypoint_boxed_in_by_exclusion_zones_is_refused_naming_both_ends_and_the_zone() {
        let model = model(Profile::Ptf);
        let mut mission = at(base(), &[enu(50.0, 50.0, 5.0), enu(-30.0, 10.0, 5.0)]);
        mission.fence.zones = [
            square(30.0, 30.0, 70.0, 34.0),
            square(30.0, 66.0, 70.0, 70.0),
            square(30.0, 30.0, 34.0, 70.0),
            square(66.0, 30.0, 70.0, 70.0),
        ]
        .iter()
        .map(|s| zone(&mission, false, s))
        .collect();
        let err = plan_mission(&mission, &model, &PlanOptions::default()).unwrap_err();
        let text = err.to_string();
        assert!(
            text.starts_with("leg origin -> W1: no way round exclusion polygon ")
                || text.starts_with("leg W1 -> W2: no way round exclusion polygon "),
            "{text}"
        );
        assert!(text.contains("keeping 5 m from every fence zone"), "{text}");
    }

    #[test]
    fn a_mission_without_a_fence_or_clear_of_it_is_planned_as_before() {
        let model = model(Profile::Px4);
        let plain = base();
        let before = plan_mission(&plain, &model, &PlanOptions::default()).unwrap();
        let mut far = plain.clone();
        far.fence
            .zones
            .push(zone(&far, false, &square(500.0, 500.0, 520.0, 520.0)));
        let after = plan_mission(&far, &model, &PlanOptions::default()).unwrap();
        for (b, a) in before.orders.iter().zip(&after.orders) {
            assert_eq!((&b.nodes, &b.legs), (&a.nodes, &a.legs));
        }
        assert_eq!(before.energy, after.energy);
        assert!(after
            .orders
            .iter()
            .flat_map(|o| &o.legs)
            .all(|l| l.via.is_empty()));
    }

    #[test]
    fn the_plan_document_shows_each_detour_with_its_points_and_zone() {
        let model = model(Profile::Px4);
        let mission = fenced_sample();
        let plan = plan_mission(&mission, &model, &PlanOptions::default()).unwrap();
        let doc = serde_json::to_value(crate::planner::json::plan_document(&plan)).unwrap();
        let legs: Vec<&serde_json::Value> = doc["orders"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|o| o["legs"].as_array().unwrap())
            .filter(|l| l.get("via").is_some())
            .collect();
        assert!(!legs.is_empty());
        for leg in legs {
            assert_eq!(leg["round"], serde_json::json!(["exclusion polygon 1"]));
            assert!(leg["detour_m"].as_f64().unwrap() > 0.0);
            assert!(leg["detour_kj"].as_f64().is_some());
            for p in leg["via"].as_array().unwrap() {
                let back = mission.origin.to_enu(crate::mission::Geodetic {
                    lat_deg: p["lat_deg"].as_f64().unwrap(),
                    lon_deg: p["lon_deg"].as_f64().unwrap(),
                    alt_m: p["alt_amsl_m"].as_f64().unwrap(),
                });
                assert!((back.x_east_m - p["e_m"].as_f64().unwrap()).abs() < 1e-3);
                assert!((back.y_north_m - p["n_m"].as_f64().unwrap()).abs() < 1e-3);
                assert!((back.z_up_m - p["u_m"].as_f64().unwrap()).abs() < 1e-3);
            }
        }
        // A straight leg carries none of the keys.
        let straight = &doc["orders"][0]["legs"]
            .as_array()
            .unwrap()
            .iter()
            .find(|l| l.get("via").is_none())
            .cloned()
            .unwrap();
        assert!(straight.get("round").is_none() && straight.get("detour_kj").is_none());
    }
}
