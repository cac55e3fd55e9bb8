//! Brute-force enumeration of every tour: the test oracle for the exact solvers (m! tours, so
//! only for small m).

use super::{CostMatrix, PlanError, Tour};

/// Largest number of non-origin nodes enumerated (10! = 3.6 million tours).
pub const MAX_NODES: usize = 10;

/// The optimal tour by enumerating every permutation (Heap's algorithm).
pub fn solve(m: &CostMatrix) -> Result<Tour, PlanError> {
    let n = m.len().saturating_sub(1);
    if n > MAX_NODES {
        return Err(PlanError::TooManyForBruteForce { n, max: MAX_NODES });
    }
    let mut perm: Vec<usize> = (1..=n).collect();
    let mut best_order = perm.clone();
    let mut best = m.tour_cost(&perm);
    // Heap's algorithm, iterative form.
    let mut c = vec![0usize; n];
    let mut i = 0;
    while i < n {
        if c[i] < i {
            if i % 2 == 0 {
                perm.swap(0, i);
            } else {
                perm.swap(c[i], i);
            }
            let cost = m.tour_cost(&perm);
            if cost < best {
                best = cost;
                best_order.clone_from(&perm);
            }
            c[i] += 1;
            i = 0;
        } else {
            c[i] = 0;
            i += 1;
        }
    }
    Ok(Tour {
        order: best_order,
        cost: best,
        lower_bound: best,
        optimal: true,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn brute_force_visits_all_twenty_four_tours_of_four_waypoints() {
        // Only the tour 0 -> 4 -> 3 -> 2 -> 1 -> 0 is cheap: enumeration must reach it.
        let m = CostMatrix::from_fn(5, |i, j| {
            if (i, j) == (0, 4) || (i > 0 && j == i - 1) {
                1.0
            } else {
                7.0
            }
        });
        let tour = solve(&m).unwrap();
        assert_eq!(tour.order, vec![4, 3, 2, 1]);
        assert_eq!(tour.cost, 5.0);
    }
}
