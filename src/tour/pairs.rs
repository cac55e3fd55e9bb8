//! Orders whose leg costs depend on the leg before: an autopilot that leaves a hold offset
//! along the way it came prices a leg by the turn into it (the `px4` profile). The caller hands
//! a pair cost `cost(previous, from, to)` (`previous` None for the first leg out of the origin;
//! node 0 is the origin), so this module knows nothing of the physics that makes it.
//!
//! - [`exact`]: dynamic programming over (visited set, last node, node before it), Held-Karp
//!   with one more index; exact up to [`EXACT_MAX_WAYPOINTS`] waypoints.
//! - [`improve`]: local search on the true pair costs (moving a segment of one to three nodes,
//!   reversing a stretch), from a seed (the order chosen on pair-independent costs), up to
//!   [`IMPROVE_MAX_WAYPOINTS`] waypoints; beyond, the seed is kept and priced.
//! - [`arc_minima`]: each arc's cheapest cost over every leg that may come before it. Any
//!   tour costs at least the sum of its arcs' minima, so the optimum of the ordinary tour
//!   problem on those minima (or any lower bound of it) bounds the pair-cost optimum from below;
//!   [`solve`] calls a tour optimal only when it meets that bound or came from [`exact`].

use super::{cancel, CostMatrix, PlanError};

/// The most waypoints [`exact`] takes: 2^m m (m + 1) states, each tried with up to m next
/// nodes (12: 640 000 states, 5 MB of values; a whole plan of 12 waypoints takes 16 ms,
/// `cargo bench --bench pairs`).
pub const EXACT_MAX_WAYPOINTS: usize = 12;

/// The most waypoints [`improve`] searches (each pass tries about 4 m^2 moves, each priced
/// over the whole tour).
pub const IMPROVE_MAX_WAYPOINTS: usize = 150;

/// How the pair-cost order was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// [`exact`]'s dynamic programming.
    Exact,
    /// [`improve`]'s local search from the seed.
    LocalSearch,
    /// Too many waypoints to search: the seed, priced.
    Seed,
}

/// An order priced on pair costs, with what is proved about it.
#[derive(Debug, Clone, PartialEq)]
pub struct PairTour {
    /// Waypoint nodes in flying order (the origin excluded at both ends).
    pub order: Vec<usize>,
    /// Its pair cost, origin to origin.
    pub cost: f64,
    /// A proven lower bound on every order's pair cost.
    pub lower_bound: f64,
    /// Proven optimal on the pair costs.
    pub optimal: bool,
    pub method: Method,
}

/// The pair cost of flying origin -> `order` -> origin.
pub fn tour_cost(order: &[usize], cost: &impl Fn(Option<usize>, usize, usize) -> f64) -> f64 {
    let stops: Vec<usize> = std::iter::once(0)
        .chain(order.iter().copied())
        .chain(std::iter::once(0))
        .collect();
    stops
        .windows(2)
        .enumerate()
        .map(|(k, w)| cost(k.checked_sub(1).map(|p| stops[p]), w[0], w[1]))
        .sum()
}

/// Each arc's cheapest pair cost over every node that may fly before it (the first leg out of
/// the origin has none; no arc comes back into the origin before the end).
pub fn arc_minima(n: usize, cost: &impl Fn(Option<usize>, usize, usize) -> f64) -> CostMatrix {
    CostMatrix::from_fn(n, |i, j| {
        if i == j {
            return 0.0;
        }
        if i == 0 {
            return cost(None, 0, j);
        }
        (0..n)
            .filter(|&p| p != i && p != j)
            .map(|p| cost(Some(p), i, j))
            .fold(f64::INFINITY, f64::min)
    })
}

/// The exact minimum pair-cost tour over nodes 0..n (0 the origin): dynamic programming over
/// (visited set, last, previous). Refuses more than [`EXACT_MAX_WAYPOINTS`] waypoints; stops
/// when the [`cancel`] token asks.
pub fn exact(
    n: usize,
    cost: &impl Fn(Option<usize>, usize, usize) -> f64,
) -> Result<(Vec<usize>, f64), PlanError> {
    let m = n.saturating_sub(1);
    if m > EXACT_MAX_WAYPOINTS {
        return Err(PlanError::TooManyForPairs {
            n: m,
            max: EXACT_MAX_WAYPOINTS,
        });
    }
    if m == 0 {
        return Ok((Vec::new(), 0.0));
    }
    if m == 1 {
        return Ok((vec![1], tour_cost(&[1], cost)));
    }
    // Dense costs: first[j] out of the origin, pair[(p * n + i) * n + j] after p.
    let first: Vec<f64> = (0..n)
        .map(|j| if j == 0 { 0.0 } else { cost(None, 0, j) })
        .collect();
    let mut pair = vec![f64::INFINITY; n * n * n];
    for p in 0..n {
        for i in 1..n {
            for j in 0..n {
                if p != i && j != i {
                    pair[(p * n + i) * n + j] = cost(Some(p), i, j);
                }
            }
        }
    }
    // State (set over waypoints 1..=m as bits 0..m, last in 1..=m, previous in 0..=m).
    let idx = |set: usize, last: usize, prev: usize| (set * m + (last - 1)) * n + prev;
    let states = (1usize << m) * m * n;
    let mut value = vec![f64::INFINITY; states];
    let mut parent = vec![u8::MAX; states];
    for j in 1..=m {
        value[idx(1 << (j - 1), j, 0)] = first[j];
    }
    for set in 1usize..(1 << m) {
        if set.is_power_of_two() {
            cancel::check()?;
        }
        for last in 1..=m {
            if set & (1 << (last - 1)) == 0 {
                continue;
            }
            for prev in 0..=m {
                let here = value[idx(set, last, prev)];
                if !here.is_finite() {
                    continue;
                }
                for next in 1..=m {
                    if set & (1 << (next - 1)) != 0 {
                        continue;
                    }
                    let to = idx(set | (1 << (next - 1)), next, last);
                    let through = here + pair[(prev * n + last) * n + next];
                    if through < value[to] {
                        value[to] = through;
                        parent[to] = prev as u8;
                    }
                }
            }
        }
    }
    let full = (1usize << m) - 1;
    let mut best = (f64::INFINITY, 0, 0);
    for last in 1..=m {
        for prev in 0..=m {
            let total = value[idx(full, last, prev)] + pair[(prev * n + last) * n];
            if total < best.0 {
                best = (total, last, prev);
            }
        }
    }
    let (total, mut last, mut prev) = best;
    if !total.is_finite() {
        return Err(PlanError::Infeasible(
            "every pair-cost tour is infinite".into(),
        ));
    }
    let mut set = full;
    let mut order = vec![last];
    while prev != 0 {
        let before = parent[idx(set, last, prev)] as usize;
        set &= !(1 << (last - 1));
        order.push(prev);
        (last, prev) = (prev, before);
    }
    order.reverse();
    Ok((order, total))
}

/// Local search on the pair costs from `seed`: moves a segment of one to three nodes elsewhere
/// (either way round) or reverses a stretch, taking the first move that saves, until none does
/// (or the [`cancel`] token asks). Returns the order and its cost.
pub fn improve(
    seed: Vec<usize>,
    cost: &impl Fn(Option<usize>, usize, usize) -> f64,
) -> (Vec<usize>, f64) {
    let mut best = seed;
    let mut best_cost = tour_cost(&best, cost);
    let m = best.len();
    if !(2..=IMPROVE_MAX_WAYPOINTS).contains(&m) {
        return (best, best_cost);
    }
    let saves = |c: f64, best: f64| c < best - 1e-9 * best.abs().max(1.0);
    'passes: loop {
        if cancel::requested() {
            break;
        }
        // Reverse best[i..=j].
        for i in 0..m {
            for j in i + 1..m {
                let mut t = best.clone();
                t[i..=j].reverse();
                let c = tour_cost(&t, cost);
                if saves(c, best_cost) {
                    (best, best_cost) = (t, c);
                    continue 'passes;
                }
            }
        }
        // Move best[i..i + len] (either way round) to another place.
        for len in 1..=3.min(m - 1) {
            for i in 0..=m - len {
                let segment: Vec<usize> = best[i..i + len].to_vec();
                let mut rest = best.clone();
                rest.drain(i..i + len);
                for at in 0..=rest.len() {
                    if at == i {
                        continue;
                    }
                    for reversed in [false, true] {
                        let mut t = rest.clone();
                        let mut s = segment.clone();
                        if reversed {
                            s.reverse();
                        }
                        t.splice(at..at, s);
                        let c = tour_cost(&t, cost);
                        if saves(c, best_cost) {
                            (best, best_cost) = (t, c);
                            continue 'passes;
                        }
                    }
                }
            }
        }
        break;
    }
    (best, best_cost)
}

/// The best order on the pair costs over nodes 0..n: [`exact`] up to
/// [`EXACT_MAX_WAYPOINTS`] waypoints, else [`improve`] from `seed` (the order chosen on
/// pair-independent costs, which must list every waypoint once). `bound` is a proven lower bound
/// of the tour problem on [`arc_minima`]; the answer is optimal when exact or when it meets the
/// bound.
pub fn solve(
    n: usize,
    cost: &impl Fn(Option<usize>, usize, usize) -> f64,
    seed: Vec<usize>,
    bound: f64,
) -> Result<PairTour, PlanError> {
    let m = n.saturating_sub(1);
    if m <= EXACT_MAX_WAYPOINTS {
        let (order, cost) = exact(n, cost)?;
        return Ok(PairTour {
            order,
            cost,
            lower_bound: cost,
            optimal: true,
            method: Method::Exact,
        });
    }
    let method = if m <= IMPROVE_MAX_WAYPOINTS {
        Method::LocalSearch
    } else {
        Method::Seed
    };
    let (order, cost) = improve(seed, cost);
    let lower_bound = bound.min(cost);
    Ok(PairTour {
        optimal: cost <= bound + 1e-9 * bound.abs().max(1.0),
        order,
        cost,
        lower_bound,
        method,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every order of waypoints 1..=m.
    fn permutations(m: usize) -> Vec<Vec<usize>> {
        if m == 0 {
            return vec![Vec::new()];
        }
        let mut all = Vec::new();
        for shorter in permutations(m - 1) {
            for at in 0..=shorter.len() {
                let mut o = shorter.clone();
                o.insert(at, m);
                all.push(o);
            }
        }
        all
    }

    /// A pair cost from points on a plane: the distance, plus a charge when the leg turns by
    /// 90 degrees or more from the one before (as the px4 profile charges a leg that starts
    /// behind its trajectory), or a rebate when it goes on straight-ish.
    fn turning(points: &[(f64, f64)]) -> impl Fn(Option<usize>, usize, usize) -> f64 + '_ {
        move |prev, i, j| {
            let (a, b) = (points[i], points[j]);
            let d = (b.0 - a.0).hypot(b.1 - a.1);
            let Some(p) = prev else {
                return d + 3.0;
            };
            let u = (a.0 - points[p].0, a.1 - points[p].1);
            let v = (b.0 - a.0, b.1 - a.1);
            if u.0 * v.0 + u.1 * v.1 > 0.0 {
                d
            } else {
                d + 3.0 + 0.1 * d
            }
        }
    }

    fn points(seed: u64, m: usize) -> Vec<(f64, f64)> {
        let mut state = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) as f64 / (1u64 << 31) as f64) * 40.0 - 20.0
        };
        (0..=m)
            .map(|k| if k == 0 { (0.0, 0.0) } else { (next(), next()) })
            .collect()
    }

    #[test]
    fn the_pair_cost_dynamic_programme_finds_the_brute_force_optimum() {
        for seed in 0..12 {
            for m in 1..=6 {
                let pts = points(seed, m);
                let cost = turning(&pts);
                let (order, value) = exact(m + 1, &cost).unwrap();
                assert!((tour_cost(&order, &cost) - value).abs() < 1e-9);
                let mut sorted = order.clone();
                sorted.sort();
                assert_eq!(sorted, (1..=m).collect::<Vec<_>>());
                let best = permutations(m)
                    .into_iter()
                    .map(|o| tour_cost(&o, &cost))
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    (value - best).abs() < 1e-9,
                    "seed {seed}, {m}: {value} against {best}"
                );
            }
        }
    }

    #[test]
    fn pair_costs_can_change_the_best_order_and_the_arc_minima_bound_it_from_below() {
        let mut changed = 0;
        for seed in 0..20 {
            let m = 7;
            let pts = points(seed, m);
            let cost = turning(&pts);
            let minima = arc_minima(m + 1, &cost);
            let (_, value) = exact(m + 1, &cost).unwrap();
            // The tour problem on the arc minima, brute force: a lower bound of every order.
            let bound = permutations(m)
                .into_iter()
                .map(|o| minima.tour_cost(&o))
                .fold(f64::INFINITY, f64::min);
            assert!(bound <= value + 1e-9, "seed {seed}: {bound} > {value}");
            // The order chosen on pair-independent costs (the first-leg charge everywhere).
            let independent =
                CostMatrix::from_fn(m + 1, |i, j| if i == j { 0.0 } else { cost(None, i, j) });
            let seed_order = permutations(m)
                .into_iter()
                .min_by(|a, b| {
                    independent
                        .tour_cost(a)
                        .total_cmp(&independent.tour_cost(b))
                })
                .unwrap();
            let seeded = tour_cost(&seed_order, &cost);
            assert!(value <= seeded + 1e-9);
            if value < seeded - 1e-6 {
                changed += 1;
            }
            // Local search never makes the seed worse, and is called optimal only at the bound.
            let (_, improved) = improve(seed_order.clone(), &cost);
            assert!(improved <= seeded + 1e-9 && improved >= value - 1e-9);
        }
        assert!(changed > 0, "the pair costs never changed the order");
    }

    #[test]
    fn beyond_the_exact_size_a_tour_is_optimal_only_when_it_meets_the_bound() {
        let m = EXACT_MAX_WAYPOINTS + 2;
        let pts = points(3, m);
        let cost = turning(&pts);
        let seed: Vec<usize> = (1..=m).collect();
        let seeded = tour_cost(&seed, &cost);
        let loose = solve(m + 1, &cost, seed.clone(), 0.0).unwrap();
        assert_eq!(loose.method, Method::LocalSearch);
        assert!(!loose.optimal && loose.cost <= seeded && loose.lower_bound == 0.0);
        // A bound at the tour's own cost proves it.
        let met = solve(m + 1, &cost, loose.order.clone(), loose.cost).unwrap();
        assert!(met.optimal && (met.cost - loose.cost).abs() < 1e-9);
        assert!(exact(m + 1, &cost).is_err());
    }
}
