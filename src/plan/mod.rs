//! Planning: legs between every ordered pair of points, cost matrices, exact and heuristic
//! solvers for the asymmetric travelling-salesman tour through the origin, the distance
//! baselines, and the random-mission study.
//!
//! Invariant: pure and deterministic (seeded); no IO, no tokio, no MAVLink.

pub mod assignment;
pub mod bound;
pub mod branch_cut;
pub mod brute;
pub mod energy;
pub mod geometry;
pub mod held_karp;
pub mod heuristic;
pub mod orders;
pub mod solver;
pub mod sorties;
pub mod study;
#[cfg(test)]
pub(crate) mod testing;
pub mod tsplib;

pub use geometry::Geometry;
pub use orders::{
    cheapest, order_waypoints, plan_orders, Direction, LegReport, Objective, OrderReport, Proof,
};

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
}
