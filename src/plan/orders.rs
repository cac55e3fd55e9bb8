//! The orders `emplan plan` reports: the minimum-energy order (when an energy cost matrix is
//! given) and the three distance baselines of the paper (notes section 4), min 3D distance D_M,
//! min horizontal distance X_M and min vertical distance Z_M with ties broken by X_M, each in both
//! directions, with per-leg metrics.

use serde::Serialize;

use super::held_karp::{self, Lexicographic};
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

/// One leg of an order.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LegReport {
    pub from: String,
    pub to: String,
    pub horizontal_m: f64,
    /// Signed vertical displacement (positive = climb).
    pub vertical_m: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy_kj: Option<f64>,
}

/// One visiting order and its metrics (the ORDER object of DESIGN.md).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OrderReport {
    pub objective: Objective,
    pub direction: Direction,
    /// Waypoint names in visiting order, origin excluded.
    pub sequence: Vec<String>,
    /// Node ids (1-based waypoint indices, 0 = origin) in visiting order.
    #[serde(skip)]
    pub nodes: Vec<usize>,
    pub distance_m: f64,
    pub horizontal_m: f64,
    /// Total absolute vertical distance.
    pub vertical_m: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy_kj: Option<f64>,
    pub legs: Vec<LegReport>,
    /// How the order was solved and what is proven about it (the order that minimises its
    /// objective; absent on reversed baselines, which are not solved for).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub proof: Option<Proof>,
}

/// What the solver proved about an order, in the objective's units (kJ for energy, metres for
/// the distance baselines).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Proof {
    pub solver: solver::Solver,
    pub optimal: bool,
    pub lower_bound: f64,
    pub gap_pct: f64,
    pub seconds: f64,
}

impl Proof {
    fn of(solved: &Solved, scale: f64) -> Proof {
        Proof {
            solver: solved.solver,
            optimal: solved.tour.optimal,
            lower_bound: solved.tour.lower_bound * scale,
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

/// Every order `emplan plan` reports: the energy order (if `energy` is given) once, then each
/// distance baseline forward and reverse. `names[k]` names node `k` (`names[0]` the origin).
pub fn plan_orders(
    geometry: &Geometry,
    names: &[String],
    energy: Option<&CostMatrix>,
    options: &solver::Options,
) -> Result<Vec<OrderReport>, PlanError> {
    let mut reports = Vec::new();
    if energy.is_some() {
        let (order, solved) = solve_order_with(geometry, Objective::Energy, energy, options)?;
        let mut r = report(
            geometry,
            names,
            energy,
            Objective::Energy,
            Direction::Forward,
            order,
        );
        r.proof = Some(Proof::of(&solved, 1e-3));
        reports.push(r);
    }
    for objective in [
        Objective::Distance,
        Objective::Horizontal,
        Objective::Vertical,
    ] {
        let (order, solved) = solve_order_with(geometry, objective, energy, options)?;
        let reversed: Vec<usize> = order.iter().rev().copied().collect();
        let mut forward = report(
            geometry,
            names,
            energy,
            objective,
            Direction::Forward,
            order,
        );
        forward.proof = Some(Proof::of(&solved, 1.0));
        reports.push(forward);
        reports.push(report(
            geometry,
            names,
            energy,
            objective,
            Direction::Reverse,
            reversed,
        ));
    }
    Ok(reports)
}

/// The order of `objective` with the least energy (the better direction of a baseline).
pub fn cheapest(orders: &[OrderReport], objective: Objective) -> Option<&OrderReport> {
    orders
        .iter()
        .filter(|o| o.objective == objective)
        .min_by(|a, b| {
            let energy = |o: &OrderReport| o.energy_kj.unwrap_or(f64::INFINITY);
            energy(a).total_cmp(&energy(b))
        })
}

/// Metrics of the closed tour `0 -> nodes... -> 0`.
pub fn report(
    geometry: &Geometry,
    names: &[String],
    energy: Option<&CostMatrix>,
    objective: Objective,
    direction: Direction,
    nodes: Vec<usize>,
) -> OrderReport {
    let stops: Vec<usize> = std::iter::once(0)
        .chain(nodes.iter().copied())
        .chain(std::iter::once(0))
        .collect();
    let legs: Vec<LegReport> = stops
        .windows(2)
        .map(|w| LegReport {
            from: names[w[0]].clone(),
            to: names[w[1]].clone(),
            horizontal_m: geometry.horizontal_m(w[0], w[1]),
            vertical_m: geometry.vertical_m(w[0], w[1]),
            energy_kj: energy.map(|e| e.cost(w[0], w[1]) / 1000.0),
        })
        .collect();
    OrderReport {
        objective,
        direction,
        sequence: nodes.iter().map(|&k| names[k].clone()).collect(),
        distance_m: stops
            .windows(2)
            .map(|w| geometry.distance_m(w[0], w[1]))
            .sum(),
        horizontal_m: legs.iter().map(|l| l.horizontal_m).sum(),
        vertical_m: legs.iter().map(|l| l.vertical_m.abs()).sum(),
        energy_kj: energy.map(|_| legs.iter().filter_map(|l| l.energy_kj).sum()),
        legs,
        nodes,
        proof: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::Enu;

    /// Sample mission 1 of the paper notes (section 5): exact published metrics.
    fn sample_8wp() -> (Geometry, Vec<String>) {
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
        let names = ["origin", "A", "B", "C", "D", "E", "F", "G", "H"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        (Geometry::from_points(points), names)
    }

    fn metrics(r: &OrderReport) -> (f64, f64, f64) {
        let round = |v: f64| (v * 10.0).round() / 10.0;
        (
            round(r.distance_m),
            round(r.horizontal_m),
            round(r.vertical_m),
        )
    }

    #[test]
    fn the_paper_sample_mission_baselines_have_the_published_metrics() {
        let (g, names) = sample_8wp();
        let orders = plan_orders(&g, &names, None, &solver::Options::default()).unwrap();
        assert_eq!(orders.len(), 6);
        let find = |o: Objective| orders.iter().find(|r| r.objective == o).unwrap();
        assert_eq!(metrics(find(Objective::Distance)), (284.4, 189.5, 174.0));
        assert_eq!(metrics(find(Objective::Horizontal)), (311.6, 183.2, 240.0));
        assert_eq!(metrics(find(Objective::Vertical)), (321.4, 291.3, 76.0));
    }

    #[test]
    fn reverse_baselines_fly_the_same_tour_backwards_with_mirrored_legs() {
        let (g, names) = sample_8wp();
        let orders = plan_orders(&g, &names, None, &solver::Options::default()).unwrap();
        let fwd = &orders[0];
        let rev = &orders[1];
        assert_eq!(rev.direction, Direction::Reverse);
        let mut back = fwd.sequence.clone();
        back.reverse();
        assert_eq!(rev.sequence, back);
        assert_eq!(rev.legs[0].vertical_m, -fwd.legs.last().unwrap().vertical_m);
        assert!(fwd.nodes.first() < fwd.nodes.last());
    }

    #[test]
    fn the_energy_order_minimises_the_given_energy_matrix_and_reports_it_per_leg() {
        let (g, names) = sample_8wp();
        // A climb-averse cost: climbing costs 10 per metre, descending 1, horizontal 1.
        let e = CostMatrix::from_fn(g.len(), |i, j| {
            let dz = g.vertical_m(i, j);
            1000.0 * (g.horizontal_m(i, j) + if dz > 0.0 { 10.0 * dz } else { -dz })
        });
        let orders = plan_orders(&g, &names, Some(&e), &solver::Options::default()).unwrap();
        assert_eq!(orders.len(), 7);
        let energy = &orders[0];
        assert_eq!(energy.objective, Objective::Energy);
        let best = energy.energy_kj.unwrap();
        for other in &orders[1..] {
            assert!(other.energy_kj.unwrap() >= best - 1e-9);
        }
        let sum: f64 = energy.legs.iter().map(|l| l.energy_kj.unwrap()).sum();
        assert!((sum - best).abs() < 1e-9);
        assert!((best * 1000.0 - e.tour_cost(&energy.nodes)).abs() < 1e-6);
    }
}
