//! The assignment problem (AP) relaxation of the asymmetric TSP: every node gets exactly one
//! successor and one predecessor, subtours allowed. Its optimum is a lower bound on every tour
//! (a tour is an assignment), and its dual potentials give each arc a reduced cost
//! `c_ij - u_i - v_j >= 0` such that any tour costs at least `bound + sum of its arcs' reduced
//! costs`: arcs whose reduced cost exceeds `upper bound - bound` cannot be in a better tour and
//! are dropped before branch-and-cut (Carpaneto, Dell'Amico and Toth 1995; Fischetti, Lodi and
//! Toth 2002, "Exact methods for the ATSP", section 2).
//!
//! Solved by the Hungarian method with potentials (Kuhn 1955, Munkres 1957; the O(n^3)
//! shortest-augmenting-path form of Jonker and Volgenant 1987, as in e-maxx's "Hungarian
//! algorithm"). The diagonal (a node as its own successor) is forbidden.

use super::{CostMatrix, PlanError};

/// The optimal assignment and its duals.
#[derive(Debug, Clone, PartialEq)]
pub struct Assignment {
    /// `successor[i]`: the node after `i`.
    pub successor: Vec<usize>,
    /// The assignment's cost: a lower bound on every tour.
    pub cost: f64,
    /// Row potentials (one per tail node).
    pub u: Vec<f64>,
    /// Column potentials (one per head node).
    pub v: Vec<f64>,
}

impl Assignment {
    /// Reduced cost of arc `i -> j`, non-negative up to round-off.
    pub fn reduced_cost(&self, m: &CostMatrix, i: usize, j: usize) -> f64 {
        m.cost(i, j) - self.u[i] - self.v[j]
    }

    /// The subtours of the assignment, each as a list of nodes in order (the first contains
    /// node 0).
    pub fn cycles(&self) -> Vec<Vec<usize>> {
        let n = self.successor.len();
        let mut seen = vec![false; n];
        let mut cycles = Vec::new();
        for start in 0..n {
            if seen[start] {
                continue;
            }
            let mut cycle = Vec::new();
            let mut node = start;
            while !seen[node] {
                seen[node] = true;
                cycle.push(node);
                node = self.successor[node];
            }
            cycles.push(cycle);
        }
        cycles
    }
}

/// Solves the assignment problem of `m` with the diagonal forbidden. Needs at least two nodes.
pub fn solve(m: &CostMatrix) -> Result<Assignment, PlanError> {
    let n = m.len();
    m.check_finite()?;
    if n < 2 {
        return Ok(Assignment {
            successor: vec![0; n],
            cost: 0.0,
            u: vec![0.0; n],
            v: vec![0.0; n],
        });
    }
    let cost = |i: usize, j: usize| {
        if i == j {
            f64::INFINITY
        } else {
            m.cost(i, j)
        }
    };
    // 1-based arrays as in the classic statement; index 0 is the virtual start column.
    let mut u = vec![0.0; n + 1];
    let mut v = vec![0.0; n + 1];
    let mut row_of_col = vec![0usize; n + 1];
    let mut way = vec![0usize; n + 1];
    let mut min_slack = vec![f64::INFINITY; n + 1];
    let mut used = vec![false; n + 1];
    for row in 1..=n {
        // Each row is O(n^2): at 2000 nodes a few ms between looks at the cancel token.
        super::cancel::check()?;
        row_of_col[0] = row;
        let mut col0 = 0usize;
        min_slack.fill(f64::INFINITY);
        used.fill(false);
        loop {
            used[col0] = true;
            let i0 = row_of_col[col0];
            let mut delta = f64::INFINITY;
            let mut col1 = 0usize;
            for j in 1..=n {
                if used[j] {
                    continue;
                }
                let slack = cost(i0 - 1, j - 1) - u[i0] - v[j];
                if slack < min_slack[j] {
                    min_slack[j] = slack;
                    way[j] = col0;
                }
                if min_slack[j] < delta {
                    delta = min_slack[j];
                    col1 = j;
                }
            }
            if col1 == 0 || !delta.is_finite() {
                // Only reachable with n < 2, excluded above; kept as an error, not a panic.
                return Err(PlanError::Infeasible(
                    "no assignment avoids the diagonal".to_string(),
                ));
            }
            for j in 0..=n {
                if used[j] {
                    u[row_of_col[j]] += delta;
                    v[j] -= delta;
                } else {
                    min_slack[j] -= delta;
                }
            }
            col0 = col1;
            if row_of_col[col0] == 0 {
                break;
            }
        }
        loop {
            let col1 = way[col0];
            row_of_col[col0] = row_of_col[col1];
            col0 = col1;
            if col0 == 0 {
                break;
            }
        }
    }
    let mut successor = vec![0usize; n];
    for j in 1..=n {
        successor[row_of_col[j] - 1] = j - 1;
    }
    let total: f64 = (0..n).map(|i| m.cost(i, successor[i])).sum();
    Ok(Assignment {
        successor,
        cost: total,
        u: u[1..].to_vec(),
        v: v[1..].to_vec(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// Every assignment by brute force over permutations without fixed points.
    fn brute(m: &CostMatrix) -> f64 {
        fn go(m: &CostMatrix, i: usize, used: &mut Vec<bool>, acc: f64, best: &mut f64) {
            let n = m.len();
            if i == n {
                *best = best.min(acc);
                return;
            }
            for j in 0..n {
                if j != i && !used[j] {
                    used[j] = true;
                    go(m, i + 1, used, acc + m.cost(i, j), best);
                    used[j] = false;
                }
            }
        }
        let mut best = f64::INFINITY;
        go(m, 0, &mut vec![false; m.len()], 0.0, &mut best);
        best
    }

    #[test]
    fn the_assignment_equals_brute_force_and_its_duals_are_feasible_and_tight() {
        let mut rng = Rng::new(3);
        for trial in 0..200 {
            let n = 2 + trial % 7;
            let m = CostMatrix::from_fn(n, |_, _| rng.below(100) as f64);
            let a = solve(&m).unwrap();
            assert_eq!(a.cost, brute(&m), "trial {trial}");
            let mut heads = a.successor.clone();
            heads.sort_unstable();
            assert_eq!(heads, (0..n).collect::<Vec<_>>());
            for i in 0..n {
                assert_ne!(a.successor[i], i);
                for j in 0..n {
                    if i != j {
                        assert!(a.reduced_cost(&m, i, j) >= -1e-9);
                    }
                }
                assert!(a.reduced_cost(&m, i, a.successor[i]).abs() < 1e-9);
            }
            let duals: f64 = a.u.iter().chain(a.v.iter()).sum();
            assert!((duals - a.cost).abs() < 1e-9);
        }
    }

    #[test]
    fn the_cycles_of_an_assignment_cover_every_node_once() {
        let m = CostMatrix::from_fn(5, |i, j| {
            // Two cheap cycles: 0 <-> 1 and 2 -> 3 -> 4 -> 2.
            let cheap = matches!((i, j), (0, 1) | (1, 0) | (2, 3) | (3, 4) | (4, 2));
            if cheap {
                1.0
            } else {
                50.0
            }
        });
        let a = solve(&m).unwrap();
        assert_eq!(a.cost, 5.0);
        let cycles = a.cycles();
        assert_eq!(cycles.len(), 2);
        assert_eq!(cycles.iter().map(Vec::len).sum::<usize>(), 5);
    }

    #[test]
    fn a_non_finite_cost_is_rejected_naming_the_arc() {
        let m = CostMatrix::from_fn(3, |i, j| if (i, j) == (2, 0) { f64::NAN } else { 1.0 });
        assert_eq!(solve(&m), Err(PlanError::NonFiniteCost { from: 2, to: 0 }));
    }
}
