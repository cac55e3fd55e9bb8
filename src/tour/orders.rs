//! The orders `emplan plan` reports, solved: the minimum-energy order (when an energy cost matrix is
//! given) and the three distance baselines of the paper (notes section 4), min 3D distance D_M,
//! min horizontal distance X_M and min vertical distance Z_M with ties broken by X_M, each in both
//! directions. Pricing them (per-leg energy from a vehicle) is the planner's job.

use serde::Serialize;

use super::held_karp::{self, Lexicographic};
use super::progress::{self, Event};
use super::solver::{self, Solved};
use super::{CostMatrix, Geometry, PlanError};

/// What an order minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Objective {
    Energy,
    Distance,
    Horizontal,
    Vertical,
}

/// The direction a tour is flown in. For a distance baseline (symmetric costs) `Forward` is the
/// direction whose first waypoint comes earlier in the mission file than its last one, so the
/// labels are deterministic; `Reverse` is the same tour flown backwards.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Direction {
    Forward,
    Reverse,
}

/// A solved visiting order: which objective chose it, the direction it is flown in, its nodes
/// (1-based waypoint ids, the origin excluded at both ends) and what the solver proved.
#[derive(Debug, Clone, PartialEq)]
pub struct SolvedOrder {
    pub objective: Objective,
    pub direction: Direction,
    pub nodes: Vec<usize>,
    /// What the solver proved (the order that minimises its objective; absent on reversed
    /// baselines, which are not solved for).
    pub proof: Option<Proof>,
}

/// What the solver proved about an order, in the objective's units (J for energy, metres for
/// the distance baselines).
#[derive(Debug, Clone, PartialEq)]
pub struct Proof {
    pub solver: solver::Solver,
    pub optimal: bool,
    pub lower_bound: f64,
    pub gap_pct: f64,
    pub seconds: f64,
}

impl Proof {
    fn of(solved: &Solved) -> Proof {
        Proof {
            solver: solved.solver,
            optimal: solved.tour.optimal,
            lower_bound: solved.tour.lower_bound,
            gap_pct: solved.gap_pct,
            seconds: solved.seconds,
        }
    }
}

/// The optimal order of nodes (1-based waypoint ids) for one objective, with the default solver
/// options. The energy objective needs `energy` (joules per leg, node 0 = origin); the distance
/// objectives are canonicalised to their forward direction.
pub fn solve_order(
    geometry: &Geometry,
    objective: Objective,
    energy: Option<&CostMatrix>,
) -> Result<Vec<usize>, PlanError> {
    Ok(solve_order_with(geometry, objective, energy, &solver::Options::default())?.0)
}

/// [`solve_order`] with chosen solver options; also returns what the solver proved. Beyond
/// Held-Karp's size the min-vertical baseline minimises `|dz| + 1e-4 * horizontal` (its
/// lexicographic tie-break is exact only up to [`held_karp::MAX_NODES`] waypoints).
pub fn solve_order_with(
    geometry: &Geometry,
    objective: Objective,
    energy: Option<&CostMatrix>,
    options: &solver::Options,
) -> Result<(Vec<usize>, Solved), PlanError> {
    let n = geometry.len();
    let solved = match objective {
        Objective::Energy => {
            let m = energy.ok_or(PlanError::NoEnergyModel)?;
            let solved = solver::solve(m, options)?;
            return Ok((solved.tour.order.clone(), solved));
        }
        Objective::Distance => solver::solve(&geometry.distance_matrix(), options)?,
        Objective::Horizontal => solver::solve(&geometry.horizontal_matrix(), options)?,
        Objective::Vertical if n <= held_karp::MAX_NODES + 1 => {
            let started = std::time::Instant::now();
            let (order, cost) = held_karp::solve_with(n, |i, j| Lexicographic {
                primary: geometry.vertical_m(i, j).abs(),
                secondary: geometry.horizontal_m(i, j),
            })?;
            Solved {
                tour: super::Tour {
                    order,
                    cost: cost.primary,
                    lower_bound: cost.primary,
                    optimal: true,
                },
                solver: solver::Solver::HeldKarp,
                heuristic_cost: None,
                nodes: None,
                gap_pct: 0.0,
                seconds: started.elapsed().as_secs_f64(),
            }
        }
        Objective::Vertical => {
            let m = CostMatrix::from_fn(n, |i, j| {
                geometry.vertical_m(i, j).abs() + 1e-4 * geometry.horizontal_m(i, j)
            });
            solver::solve(&m, options)?
        }
    };
    let order = forward(solved.tour.order.clone());
    Ok((order, solved))
}

/// The optimal visiting order of a mission's waypoints for one objective, as 0-based indices into
/// `mission.waypoints` (what an upload needs).
pub fn order_waypoints(
    mission: &crate::mission::Mission,
    objective: Objective,
    energy: Option<&CostMatrix>,
) -> Result<Vec<usize>, PlanError> {
    let geometry = Geometry::from_mission(mission);
    Ok(solve_order(&geometry, objective, energy)?
        .into_iter()
        .map(|node| node - 1)
        .collect())
}

fn forward(mut order: Vec<usize>) -> Vec<usize> {
    if order.first() > order.last() {
        order.reverse();
    }
    order
}

/// The minimum-energy order of `energy` (joules per leg, node 0 = origin), its solve's progress
/// reported on this thread.
pub fn energy_order(
    geometry: &Geometry,
    energy: &CostMatrix,
    options: &solver::Options,
) -> Result<SolvedOrder, PlanError> {
    progress::report(Event::Order(objective_name(Objective::Energy)));
    let (nodes, solved) = solve_order_with(geometry, Objective::Energy, Some(energy), options)?;
    Ok(SolvedOrder {
        objective: Objective::Energy,
        direction: Direction::Forward,
        nodes,
        proof: Some(Proof::of(&solved)),
    })
}

/// A distance baseline (`objective` other than energy) flown forward, then reverse.
pub fn baseline(
    geometry: &Geometry,
    objective: Objective,
    options: &solver::Options,
) -> Result<[SolvedOrder; 2], PlanError> {
    let (nodes, solved) = solve_order_with(geometry, objective, None, options)?;
    let reversed: Vec<usize> = nodes.iter().rev().copied().collect();
    Ok([
        SolvedOrder {
            objective,
            direction: Direction::Forward,
            nodes,
            proof: Some(Proof::of(&solved)),
        },
        SolvedOrder {
            objective,
            direction: Direction::Reverse,
            nodes: reversed,
            proof: None,
        },
    ])
}

/// Every order `emplan plan` reports: the energy order (if `energy` is given) once, then each
/// distance baseline forward and reverse. `options.time_limit` bounds all the solves together:
/// each gets its share of the time left (the energy order twice a baseline's), and what a solve
/// leaves unused goes to the ones after it.
pub fn plan_orders(
    geometry: &Geometry,
    energy: Option<&CostMatrix>,
    options: &solver::Options,
) -> Result<Vec<SolvedOrder>, PlanError> {
    let deadline = std::time::Instant::now() + options.time_limit.min(YEAR);
    let baselines = [
        Objective::Distance,
        Objective::Horizontal,
        Objective::Vertical,
    ];
    let mut weight_left = baselines.len() as f64 + if energy.is_some() { 2.0 } else { 0.0 };
    let mut share = |weight: f64| {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        let limit = left.mul_f64(weight / weight_left);
        weight_left -= weight;
        solver::Options {
            time_limit: limit,
            ..*options
        }
    };
    let mut orders = Vec::new();
    if let Some(energy) = energy {
        orders.push(energy_order(geometry, energy, &share(2.0))?);
    }
    for objective in baselines {
        progress::report(Event::Order(objective_name(objective)));
        orders.extend(baseline(geometry, objective, &share(1.0))?);
    }
    Ok(orders)
}

/// A time limit past any solve (keeps `Instant` arithmetic from overflowing).
const YEAR: std::time::Duration = std::time::Duration::from_secs(365 * 24 * 3600);

fn objective_name(objective: Objective) -> &'static str {
    match objective {
        Objective::Energy => "energy order",
        Objective::Distance => "min-distance order",
        Objective::Horizontal => "min-horizontal order",
        Objective::Vertical => "min-vertical order",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::Enu;

    /// Sample mission 1 of the paper notes (section 5): exact published metrics.
    fn sample_8wp() -> Geometry {
        let pts = [
            (-20.0, 20.0, 19.0),
            (20.0, -20.0, 19.0),
            (-12.0, -12.0, 11.0),
            (12.0, 12.0, 11.0),
            (-12.0, 12.0, -11.0),
            (12.0, -12.0, -11.0),
            (-20.0, -20.0, -19.0),
            (20.0, 20.0, -19.0),
        ];
        let points = std::iter::once(Enu::default())
            .chain(pts.iter().map(|&(x, y, z)| Enu {
                x_east_m: x,
                y_north_m: y,
                z_up_m: z,
            }))
            .collect();
        Geometry::from_points(points)
    }

    fn metrics(g: &Geometry, r: &SolvedOrder) -> (f64, f64, f64) {
        let round = |v: f64| (v * 10.0).round() / 10.0;
        let t = g.tour_length(&r.nodes);
        (
            round(t.distance_m),
            round(t.horizontal_m),
            round(t.vertical_m),
        )
    }

    #[test]
    fn the_paper_sample_mission_baselines_have_the_published_metrics() {
        let g = sample_8wp();
        let orders = plan_orders(&g, None, &solver::Options::default()).unwrap();
        assert_eq!(orders.len(), 6);
        let find = |o: Objective| orders.iter().find(|r| r.objective == o).unwrap();
        assert_eq!(
            metrics(&g, find(Objective::Distance)),
            (284.4, 189.5, 174.0)
        );
        assert_eq!(
            metrics(&g, find(Objective::Horizontal)),
            (311.6, 183.2, 240.0)
        );
        assert_eq!(metrics(&g, find(Objective::Vertical)), (321.4, 291.3, 76.0));
    }

    #[test]
    fn reverse_baselines_fly_the_same_tour_backwards_with_mirrored_legs() {
        let g = sample_8wp();
        let orders = plan_orders(&g, None, &solver::Options::default()).unwrap();
        let fwd = &orders[0];
        let rev = &orders[1];
        assert_eq!(rev.direction, Direction::Reverse);
        assert!(fwd.proof.is_some() && rev.proof.is_none());
        let mut back = fwd.nodes.clone();
        back.reverse();
        assert_eq!(rev.nodes, back);
        let (first, last) = (rev.nodes[0], fwd.nodes[fwd.nodes.len() - 1]);
        assert_eq!(first, last);
        assert_eq!(g.vertical_m(0, first), -g.vertical_m(last, 0));
        assert!(fwd.nodes.first() < fwd.nodes.last());
    }

    #[test]
    fn the_energy_order_minimises_the_given_energy_matrix_and_reports_it_per_leg() {
        let g = sample_8wp();
        // A climb-averse cost: climbing costs 10 per metre, descending 1, horizontal 1.
        let e = CostMatrix::from_fn(g.len(), |i, j| {
            let dz = g.vertical_m(i, j);
            1000.0 * (g.horizontal_m(i, j) + if dz > 0.0 { 10.0 * dz } else { -dz })
        });
        let orders = plan_orders(&g, Some(&e), &solver::Options::default()).unwrap();
        assert_eq!(orders.len(), 7);
        let energy = &orders[0];
        assert_eq!(energy.objective, Objective::Energy);
        let best = e.tour_cost(&energy.nodes);
        for other in &orders[1..] {
            assert!(e.tour_cost(&other.nodes) >= best - 1e-9);
        }
        let proof = energy.proof.as_ref().unwrap();
        assert!(proof.optimal && proof.lower_bound == best);
    }
}
