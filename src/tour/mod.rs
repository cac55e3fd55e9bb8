//! Planning: legs between every ordered pair of points, cost matrices, exact and heuristic
//! solvers for the asymmetric travelling-salesman tour through the origin, the distance
//! baselines, and the sorties of a mission too large for one battery.
//!
//! Invariant: pure and deterministic (seeded); no IO, no tokio, no MAVLink.

pub mod assignment;
pub mod bound;
pub mod branch_cut;
pub mod brute;
pub mod cancel;
pub mod clusters;
pub mod energy;
pub mod geometry;
pub mod held_karp;
pub mod heuristic;
pub mod orders;
pub mod pairs;
pub mod progress;
pub mod solver;
pub mod sorties;
pub(crate) mod subtour;
#[cfg(test)]
pub(crate) mod testing;
pub mod tsplib;

pub use geometry::{Geometry, TourLength};
pub use orders::{order_waypoints, plan_orders, Direction, Objective, Proof, SolvedOrder};

/// A square matrix of leg costs between `n` nodes, row-major: `cost(i, j)` is the cost of flying
/// from node `i` to node `j`. Node 0 is the origin (depot); the diagonal is never used.
#[derive(Debug, Clone, PartialEq)]
pub struct CostMatrix {
    n: usize,
    costs: Vec<f64>,
}

impl CostMatrix {
    /// Builds an `n` x `n` matrix from `cost(i, j)`.
    pub fn from_fn(n: usize, mut cost: impl FnMut(usize, usize) -> f64) -> Self {
        let mut costs = Vec::with_capacity(n * n);
        for i in 0..n {
            for j in 0..n {
                costs.push(if i == j { 0.0 } else { cost(i, j) });
            }
        }
        CostMatrix { n, costs }
    }

    /// Number of nodes, the origin included.
    pub fn len(&self) -> usize {
        self.n
    }

    /// True when the matrix has no nodes.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Cost of the arc `from -> to`.
    #[inline]
    pub fn cost(&self, from: usize, to: usize) -> f64 {
        self.costs[from * self.n + to]
    }

    /// Cost of the closed tour `0 -> order[0] -> ... -> order[last] -> 0`, where `order` lists
    /// the non-origin nodes.
    pub fn tour_cost(&self, order: &[usize]) -> f64 {
        let mut prev = 0;
        let mut total = 0.0;
        for &node in order {
            total += self.cost(prev, node);
            prev = node;
        }
        total + self.cost(prev, 0)
    }

    /// The first arc, row by row, whose cost is not finite (the diagonal is never looked at).
    pub fn non_finite_arc(&self) -> Option<(usize, usize)> {
        (0..self.n)
            .flat_map(|i| (0..self.n).map(move |j| (i, j)))
            .find(|&(i, j)| i != j && !self.cost(i, j).is_finite())
    }

    /// Refuses a matrix with a cost that is not finite, naming the first such arc.
    pub fn check_finite(&self) -> Result<(), PlanError> {
        match self.non_finite_arc() {
            Some((from, to)) => Err(PlanError::NonFiniteCost { from, to }),
            None => Ok(()),
        }
    }

    /// Refuses an `order` that does not list every node but the origin exactly once.
    pub fn check_tour_order(&self, order: &[usize]) -> Result<(), PlanError> {
        if is_tour_order(self.n, order) {
            Ok(())
        } else {
            Err(PlanError::Infeasible(format!(
                "the starting tour is not a permutation of nodes 1..{}",
                self.n.saturating_sub(1)
            )))
        }
    }

    /// Whether every arc cost is an integer (TSPLIB), so bounds can be rounded up.
    pub fn has_integer_costs(&self) -> bool {
        (0..self.n).all(|i| {
            (0..self.n).all(|j| {
                let c = self.cost(i, j);
                i == j || (c.fract() == 0.0 && c.abs() < 1e15)
            })
        })
    }
}

/// Whether `order` lists each of the nodes `1..nodes` exactly once (the origin, node 0, is left
/// out of a tour's order).
pub fn is_tour_order(nodes: usize, order: &[usize]) -> bool {
    let mut seen = vec![false; nodes];
    order.len() + 1 == nodes.max(1)
        && order
            .iter()
            .all(|&k| k > 0 && k < nodes && !std::mem::replace(&mut seen[k], true))
}

/// A solved tour: the visiting order of the non-origin nodes (origin excluded at both ends),
/// its cost, a lower bound on the optimum, and whether optimality is proven.
#[derive(Debug, Clone, PartialEq)]
pub struct Tour {
    pub order: Vec<usize>,
    pub cost: f64,
    pub lower_bound: f64,
    pub optimal: bool,
}

/// Errors from planning and solving.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    #[error("held-karp solves at most {max} waypoints exactly ({n} given); use another solver")]
    TooManyForHeldKarp { n: usize, max: usize },
    #[error("brute force enumerates at most {max} waypoints ({n} given)")]
    TooManyForBruteForce { n: usize, max: usize },
    #[error("the pair-cost dynamic programme solves at most {max} waypoints exactly ({n} given)")]
    TooManyForPairs { n: usize, max: usize },
    #[error("cost of leg {from} -> {to} is not finite")]
    NonFiniteCost { from: usize, to: usize },
    #[error("no tour exists: {0}")]
    Infeasible(String),
    #[error("the LP solver failed: {0}")]
    Lp(String),
    #[error("the energy order needs an energy model (none was given)")]
    NoEnergyModel,
    #[error("energy of leg {from} -> {to} (Xf {xf_m:.2} m, Zf {zf_m:.2} m): {reason}")]
    LegEnergy {
        from: String,
        to: String,
        xf_m: f64,
        zf_m: f64,
        reason: String,
    },
    #[error("planning was cancelled before it finished")]
    Cancelled,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tour_order_lists_every_node_but_the_origin_exactly_once() {
        assert!(is_tour_order(4, &[2, 1, 3]));
        assert!(is_tour_order(1, &[]));
        for bad in [
            &[1, 2][..],
            &[1, 2, 2],
            &[0, 1, 2],
            &[1, 2, 4],
            &[1, 2, 3, 1],
        ] {
            assert!(!is_tour_order(4, bad), "{bad:?}");
        }
        let m = CostMatrix::from_fn(4, |i, j| (i + j) as f64);
        assert!(m.check_tour_order(&[3, 1, 2]).is_ok());
        assert_eq!(
            m.check_tour_order(&[3, 1]).unwrap_err().to_string(),
            "no tour exists: the starting tour is not a permutation of nodes 1..3"
        );
    }

    #[test]
    fn the_first_non_finite_arc_is_named_and_the_diagonal_is_ignored() {
        let m = CostMatrix::from_fn(3, |i, j| if (i, j) == (2, 1) { f64::NAN } else { 1.5 });
        assert_eq!(m.non_finite_arc(), Some((2, 1)));
        assert_eq!(
            m.check_finite(),
            Err(PlanError::NonFiniteCost { from: 2, to: 1 })
        );
        assert!(!m.has_integer_costs());
        let whole = CostMatrix::from_fn(3, |i, j| (i * 3 + j) as f64);
        assert!(whole.check_finite().is_ok() && whole.has_integer_costs());
    }
}
