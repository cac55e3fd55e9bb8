//! Held-Karp dynamic programming (Held & Karp 1962; Bellman 1962): the exact minimum-cost tour
//! from the origin through every other node and back, for any asymmetric cost, in
//! O(2^m m^2) time and O(2^m m) memory for m non-origin nodes.
//!
//! Generic over the cost type so that the min-vertical baseline can minimise the pair
//! (vertical, horizontal) lexicographically: exact tie-breaking, no weighted sum that could
//! misorder.

use super::{CostMatrix, PlanError, Tour};

/// Largest number of non-origin nodes solved (2^20 x 20 states: about 190 MB for `f64`).
pub const MAX_NODES: usize = 20;

/// A cost that can be summed along a path and compared.
pub trait PathCost: Copy {
    /// The cost of an empty path.
    fn zero() -> Self;
    /// The cost of a path that does not exist yet.
    fn unreached() -> Self;
    /// The cost of two consecutive path pieces.
    fn plus(self, other: Self) -> Self;
    /// Whether `self` is strictly better than `other`.
    fn better_than(self, other: Self) -> bool;
    /// Whether every component is finite.
    fn is_finite(self) -> bool;
}

impl PathCost for f64 {
    fn zero() -> Self {
        0.0
    }
    fn unreached() -> Self {
        f64::INFINITY
    }
    fn plus(self, other: Self) -> Self {
        self + other
    }
    fn better_than(self, other: Self) -> bool {
        self < other
    }
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
}

/// Two costs compared lexicographically: `primary` first, `secondary` only among ties.
/// Primaries within a relative 1e-9 of each other count as tied, so that sums of the same legs
/// taken in different orders (which may differ in the last bit) tie as they should.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lexicographic {
    pub primary: f64,
    pub secondary: f64,
}

impl PathCost for Lexicographic {
    fn zero() -> Self {
        Lexicographic {
            primary: 0.0,
            secondary: 0.0,
        }
    }
    fn unreached() -> Self {
        Lexicographic {
            primary: f64::INFINITY,
            secondary: f64::INFINITY,
        }
    }
    fn plus(self, other: Self) -> Self {
        Lexicographic {
            primary: self.primary + other.primary,
            secondary: self.secondary + other.secondary,
        }
    }
    fn better_than(self, other: Self) -> bool {
        let scale = self.primary.abs().max(other.primary.abs()).max(1.0);
        if (self.primary - other.primary).abs() <= 1e-9 * scale {
            self.secondary < other.secondary
        } else {
            self.primary < other.primary
        }
    }
    fn is_finite(self) -> bool {
        self.primary.is_finite() && self.secondary.is_finite()
    }
}

/// The optimal tour of a cost matrix (node 0 is the origin).
pub fn solve(m: &CostMatrix) -> Result<Tour, PlanError> {
    let (order, cost) = solve_with(m.len(), |i, j| m.cost(i, j))?;
    Ok(Tour {
        order,
        cost,
        lower_bound: cost,
        optimal: true,
    })
}

/// The optimal tour over `n` nodes (node 0 is the origin) for any [`PathCost`]; returns the
/// order of nodes `1..n` and its cost.
pub fn solve_with<C: PathCost>(
    n: usize,
    cost: impl Fn(usize, usize) -> C,
) -> Result<(Vec<usize>, C), PlanError> {
    if n <= 1 {
        return Ok((Vec::new(), C::zero()));
    }
    let m = n - 1;
    if m > MAX_NODES {
        return Err(PlanError::TooManyForHeldKarp {
            n: m,
            max: MAX_NODES,
        });
    }
    for i in 0..n {
        for j in 0..n {
            if i != j && !cost(i, j).is_finite() {
                return Err(PlanError::NonFiniteCost { from: i, to: j });
            }
        }
    }
    // Legs between nodes 1..n, indexed 0..m here, plus from and to the origin.
    let mut legs = Vec::with_capacity(m * m);
    for i in 1..n {
        for j in 1..n {
            legs.push(if i == j { C::zero() } else { cost(i, j) });
        }
    }
    let from_origin: Vec<C> = (1..n).map(|j| cost(0, j)).collect();
    let to_origin: Vec<C> = (1..n).map(|j| cost(j, 0)).collect();

    let states = 1usize << m;
    let mut best = vec![C::unreached(); states * m];
    let mut parent = vec![u8::MAX; states * m];
    for j in 0..m {
        best[(1 << j) * m + j] = from_origin[j];
    }
    for mask in 1..states {
        for j in 0..m {
            if mask & (1 << j) == 0 {
                continue;
            }
            let here = best[mask * m + j];
            if !here.is_finite() {
                continue;
            }
            let row = &legs[j * m..(j + 1) * m];
            let mut rest = (states - 1) & !mask;
            while rest != 0 {
                let k = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                let next = mask | (1 << k);
                let candidate = here.plus(row[k]);
                let slot = next * m + k;
                if candidate.better_than(best[slot]) {
                    best[slot] = candidate;
                    parent[slot] = j as u8;
                }
            }
        }
    }

    let full = states - 1;
    let mut last = 0;
    let mut total = C::unreached();
    for j in 0..m {
        let candidate = best[full * m + j].plus(to_origin[j]);
        if candidate.better_than(total) {
            total = candidate;
            last = j;
        }
    }
    let mut order = Vec::with_capacity(m);
    let mut mask = full;
    let mut node = last;
    loop {
        order.push(node + 1);
        let prev = parent[mask * m + node];
        mask &= !(1 << node);
        if mask == 0 {
            break;
        }
        node = prev as usize;
    }
    order.reverse();
    Ok((order, total))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tour::brute;
    use proptest::prelude::*;

    fn matrix(n: usize, costs: &[u32]) -> CostMatrix {
        CostMatrix::from_fn(n, |i, j| f64::from(costs[i * n + j]))
    }

    proptest! {
        #[test]
        fn held_karp_equals_brute_force_on_random_asymmetric_matrices(
            n in 1usize..=9,
            costs in proptest::collection::vec(0u32..1000, 81),
        ) {
            let m = matrix(n, &costs);
            let hk = solve(&m).unwrap();
            let bf = brute::solve(&m).unwrap();
            prop_assert_eq!(hk.cost, bf.cost);
            let mut seen = hk.order.clone();
            seen.sort_unstable();
            prop_assert_eq!(seen, (1..n).collect::<Vec<_>>());
            prop_assert_eq!(m.tour_cost(&hk.order), hk.cost);
            prop_assert!(hk.optimal);
        }
    }

    #[test]
    fn a_one_way_street_forces_the_only_cheap_direction() {
        // 0 -> 1 -> 2 -> 3 -> 0 costs 4; every other arc costs 10.
        let m = CostMatrix::from_fn(4, |i, j| if j == (i + 1) % 4 { 1.0 } else { 10.0 });
        let tour = solve(&m).unwrap();
        assert_eq!(tour.order, vec![1, 2, 3]);
        assert_eq!(tour.cost, 4.0);
    }

    #[test]
    fn lexicographic_costs_break_primary_ties_by_the_secondary_only() {
        // The two tours tie on the primary (vertical) cost: the secondary decides.
        let primary = [[0.0, 1.0, 1.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        let secondary = [[0.0, 5.0, 1.0], [1.0, 0.0, 1.0], [5.0, 1.0, 0.0]];
        let (order, cost) = solve_with(3, |i, j| Lexicographic {
            primary: primary[i][j],
            secondary: secondary[i][j],
        })
        .unwrap();
        assert_eq!(order, vec![2, 1]);
        assert_eq!(cost.primary, 2.0);
        assert_eq!(cost.secondary, 3.0);
    }

    #[test]
    fn lexicographic_costs_let_a_smaller_primary_win_whatever_the_secondary() {
        // Tour [1, 2] has primary 2 and secondary 3000; tour [2, 1] primary 3 and secondary 3.
        let primary = [[0.0, 1.0, 1.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]];
        let secondary = [[0.0, 1000.0, 1.0], [1.0, 0.0, 1000.0], [1000.0, 1.0, 0.0]];
        let (order, cost) = solve_with(3, |i, j| Lexicographic {
            primary: primary[i][j],
            secondary: secondary[i][j],
        })
        .unwrap();
        assert_eq!(order, vec![1, 2]);
        assert_eq!((cost.primary, cost.secondary), (2.0, 3000.0));
    }

    #[test]
    fn more_than_twenty_waypoints_are_refused_with_a_typed_error() {
        let m = CostMatrix::from_fn(22, |_, _| 1.0);
        assert_eq!(
            solve(&m),
            Err(PlanError::TooManyForHeldKarp { n: 21, max: 20 })
        );
    }

    #[test]
    fn a_non_finite_leg_cost_is_rejected() {
        let m = CostMatrix::from_fn(3, |i, j| if (i, j) == (1, 2) { f64::NAN } else { 1.0 });
        assert!(matches!(
            solve(&m),
            Err(PlanError::NonFiniteCost { from: 1, to: 2, .. })
        ));
    }
}
