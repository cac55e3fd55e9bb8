//! The exact sortie split (up to [`super::EXACT_MAX_WAYPOINTS`] waypoints by default): one
//! Held-Karp DP (Held & Karp 1962) over every subset gives every subset's optimal closed tour,
//! then a set-partition DP over subsets, f(mask) = min over feasible S containing mask's lowest
//! waypoint of tour(S) + f(mask \ S), picks the cheapest partition in O(3^N).

use super::{check, Method, SortieError, SortiePlan, SortieProblem, EXACT_LIMIT};

/// The optimal split: every subset's optimal closed tour from one Held-Karp DP over all masks
/// (Held & Karp 1962: `best[mask][j]` is the cheapest path from the origin through `mask`
/// ending at j, so tour(mask) = min_j best[mask][j] + cost(j, origin)), then the set-partition
/// DP over masks, O(2^N N^2 + 3^N) time. Errors beyond [`EXACT_LIMIT`] waypoints.
pub fn exact(problem: &SortieProblem) -> Result<SortiePlan, SortieError> {
    let p = check(problem)?;
    let m = p.m.len().saturating_sub(1);
    if m > EXACT_LIMIT {
        return Err(SortieError::TooManyForExact {
            n: m,
            max: EXACT_LIMIT,
        });
    }
    if m == 0 {
        return Ok(p.plan(Vec::new(), Method::Exact));
    }
    let states = 1usize << m;
    // Held-Karp over every mask; waypoint j of the DP is node j + 1.
    let mut best = vec![f64::INFINITY; states * m];
    let mut parent = vec![u8::MAX; states * m];
    for j in 0..m {
        best[(1 << j) * m + j] = p.c(0, j + 1);
    }
    for mask in 1..states {
        for j in 0..m {
            let here = best[mask * m + j];
            if mask & (1 << j) == 0 || !here.is_finite() {
                continue;
            }
            let mut rest = (states - 1) & !mask;
            while rest != 0 {
                let k = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                let slot = (mask | (1 << k)) * m + k;
                let candidate = here + p.c(j + 1, k + 1);
                if candidate < best[slot] {
                    best[slot] = candidate;
                    parent[slot] = j as u8;
                }
            }
        }
    }
    // Every subset as one sortie: its energy when it fits the battery, infinity otherwise.
    let mut sortie_j = vec![f64::INFINITY; states];
    let mut last = vec![0u8; states];
    let mut hover_j = vec![0.0; states];
    for mask in 1..states {
        let low = mask.trailing_zeros() as usize;
        hover_j[mask] = hover_j[mask & (mask - 1)] + p.hover_j[low + 1];
        let mut tour_j = f64::INFINITY;
        for j in 0..m {
            if mask & (1 << j) != 0 {
                let candidate = best[mask * m + j] + p.c(j + 1, 0);
                if candidate < tour_j {
                    tour_j = candidate;
                    last[mask] = j as u8;
                }
            }
        }
        let total_j = p.fixed_j + tour_j + hover_j[mask];
        if total_j <= p.budget_j {
            sortie_j[mask] = total_j;
        }
    }
    drop(hover_j);
    // Set partition: the sortie holding mask's lowest waypoint, plus the best of the rest.
    let mut f = vec![f64::INFINITY; states];
    let mut choice = vec![0u32; states];
    f[0] = 0.0;
    for mask in 1..states {
        let low = mask & mask.wrapping_neg();
        let rest = mask ^ low;
        let mut sub = rest;
        loop {
            let s = sub | low;
            let candidate = sortie_j[s] + f[mask ^ s];
            if candidate < f[mask] {
                f[mask] = candidate;
                choice[mask] = s as u32;
            }
            if sub == 0 {
                break;
            }
            sub = (sub - 1) & rest;
        }
    }
    let mut orders = Vec::new();
    let mut mask = states - 1;
    while mask != 0 {
        let s = choice[mask] as usize;
        if s == 0 {
            // Unreachable: every singleton fits (checked), so every mask has a partition.
            break;
        }
        orders.push(subset_order(&parent, m, s, usize::from(last[s])));
        mask ^= s;
    }
    Ok(p.plan(orders, Method::Exact))
}

/// The node order of subset `s`'s optimal tour ending at DP waypoint `last`.
fn subset_order(parent: &[u8], m: usize, s: usize, last: usize) -> Vec<usize> {
    let mut order = Vec::with_capacity(s.count_ones() as usize);
    let (mut mask, mut node) = (s, last);
    loop {
        order.push(node + 1);
        let prev = parent[mask * m + node];
        mask &= !(1 << node);
        if mask == 0 || prev == u8::MAX {
            break;
        }
        node = usize::from(prev);
    }
    order.reverse();
    order
}

#[cfg(test)]
mod tests {
    use super::super::testing::*;
    use super::*;
    use crate::rng::Rng;
    use crate::tour::CostMatrix;

    #[test]
    fn exact_equals_brute_force_over_every_partition_and_order_on_small_random_instances() {
        let mut rng = Rng::new(42);
        let mut multi = 0;
        for case in 0..150 {
            let m = 1 + case % 7;
            let inst = instance(&mut rng, m, (1.0, 3.0));
            let plan = exact(&inst.problem()).unwrap();
            assert_valid(&inst, &plan);
            let oracle = brute_force_j(&inst);
            assert!(
                close(plan.total_j, oracle),
                "case {case}: {plan:?} vs {oracle}"
            );
            assert!(plan.optimal && plan.method == Method::Exact);
            multi += usize::from(plan.sorties.len() > 1);
        }
        // The instances really exercise splitting.
        assert!(multi > 50, "only {multi} instances needed several sorties");
    }

    #[test]
    fn exact_equals_brute_force_on_random_non_metric_matrices() {
        let mut rng = Rng::new(7);
        for case in 0..100 {
            let m = 1 + case % 6;
            let energy = CostMatrix::from_fn(m + 1, |_, _| rng.uniform(0.0, 1000.0));
            let hover_j: Vec<f64> = (0..m).map(|_| rng.uniform(0.0, 500.0)).collect();
            let inst = Instance {
                energy,
                hover_j,
                fixed_j: rng.uniform(0.0, 300.0),
                budget_j: 2600.0,
            };
            let plan = exact(&inst.problem()).unwrap();
            assert_valid(&inst, &plan);
            assert!(close(plan.total_j, brute_force_j(&inst)), "case {case}");
        }
    }
}
