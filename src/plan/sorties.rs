//! Splitting a mission one battery cannot fly into sorties: each sortie is a closed tour
//! origin -> its waypoints -> origin flown on a fresh battery, and its energy (take-off and
//! landing, legs, hovering at its waypoints) must fit the battery's budget. The split minimises
//! the total energy over all sorties, with as many batteries as needed: the distance-constrained
//! vehicle routing problem (Laporte, Desrochers and Nobert 1984, "Two exact algorithms for the
//! distance-constrained vehicle routing problem", Networks 14) with asymmetric leg costs, an
//! unlimited fleet and a fixed cost per route.
//!
//! Exact method (up to [`EXACT_MAX_WAYPOINTS`] waypoints by default): one Held-Karp DP (Held &
//! Karp 1962) over every subset gives every subset's optimal closed tour, then a set-partition
//! DP over subsets, f(mask) = min over feasible S containing mask's lowest waypoint of
//! tour(S) + f(mask \ S), picks the cheapest partition in O(3^N).
//!
//! Heuristic beyond: route first, cluster second. A giant tour (the min-energy order) is cut
//! optimally into feasible sorties by Prins' split (Prins 2004, "A simple and effective
//! evolutionary algorithm for the vehicle routing problem", Computers & Operations Research 31,
//! a Bellman shortest path over the giant tour's cut points), then improved by local search
//! (relocate, exchange, tail swap and merge between sorties; each changed sortie re-ordered
//! exactly by Held-Karp when small, by Or-opt otherwise), restarted from seeded perturbations
//! of the best giant tour. Deterministic for a seed.
//!
//! Pure: no IO. Energies in joules; node 0 of the matrix is the origin, waypoint k is node k.

use serde::Serialize;

use super::held_karp;
use super::{is_tour_order, CostMatrix};
use crate::rng::Rng;

/// Default largest number of waypoints split exactly. Measured on random 3-5 sortie instances
/// (release, one core of a shared 2-core machine): 12 waypoints take 2-10 ms, 14 take 16-21 ms,
/// 16 take 0.09-0.14 s, 18 take 0.5-0.7 s.
pub const EXACT_MAX_WAYPOINTS: usize = 16;

/// Hard cap of the exact method: its tables take 2^N (N + 2) words (18: 50 MB).
pub const EXACT_LIMIT: usize = 18;

/// Largest sortie re-ordered exactly (Held-Karp) inside the heuristic's local search.
const SUBTOUR_EXACT_MAX: usize = 12;

/// Largest mission whose giant tour the heuristic finds with Held-Karp itself.
const GIANT_TOUR_EXACT_MAX: usize = 16;

/// What to split: leg energies, hovering, and the battery.
#[derive(Debug, Clone, Copy)]
pub struct SortieProblem<'a> {
    /// Energy of every leg (J), start to settled hover; node 0 is the origin.
    pub energy: &'a CostMatrix,
    /// Energy of hovering at each waypoint (J): `hover_j[k - 1]` is node k's.
    pub hover_j: &'a [f64],
    /// Energy every sortie pays whatever it visits (J): take-off and landing.
    pub fixed_j: f64,
    /// Energy one battery may spend on a sortie (J), after its reserve.
    pub budget_j: f64,
}

/// How to split.
#[derive(Debug, Clone, PartialEq)]
pub struct SortieOptions {
    /// Split exactly up to this many waypoints (at most [`EXACT_LIMIT`]); heuristic beyond.
    pub exact_max_waypoints: usize,
    /// Seed of the heuristic's perturbations.
    pub seed: u64,
    /// Heuristic restarts from perturbed giant tours (the first is the giant tour itself).
    pub restarts: usize,
    /// A good single tour to start the heuristic from (node ids, origin excluded), e.g. the
    /// min-energy order; found by the heuristic itself when absent.
    pub giant_tour: Option<Vec<usize>>,
}

impl Default for SortieOptions {
    fn default() -> Self {
        SortieOptions {
            exact_max_waypoints: EXACT_MAX_WAYPOINTS,
            seed: 1,
            restarts: 64,
            giant_tour: None,
        }
    }
}

/// How a split was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Set-partition DP over Held-Karp subset tours: proven optimal.
    Exact,
    /// Prins' split of a giant tour plus local search: feasible, not proven optimal.
    Heuristic,
}

/// One sortie: a closed tour from the origin on one battery.
#[derive(Debug, Clone, PartialEq)]
pub struct Sortie {
    /// Waypoint node ids in flying order (origin excluded at both ends).
    pub order: Vec<usize>,
    /// Take-off and landing (J).
    pub fixed_j: f64,
    /// Legs origin -> ... -> origin (J).
    pub legs_j: f64,
    /// Hovering at its waypoints (J).
    pub hover_j: f64,
    /// Everything: fixed + legs + hover (J).
    pub total_j: f64,
}

/// A mission split into sorties.
#[derive(Debug, Clone, PartialEq)]
pub struct SortiePlan {
    /// The sorties, ordered by their lowest waypoint id.
    pub sorties: Vec<Sortie>,
    /// Sum of the sorties' energies (J).
    pub total_j: f64,
    /// Whether the total is proven minimal.
    pub optimal: bool,
    pub method: Method,
}

/// Errors from splitting into sorties.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SortieError {
    #[error("{hovers} hover energies given for {waypoints} waypoints")]
    HoverCount { waypoints: usize, hovers: usize },
    #[error("energy of leg {from} -> {to} is {energy_j} J: it must be finite and not negative")]
    BadLegEnergy {
        from: usize,
        to: usize,
        energy_j: f64,
    },
    #[error("hover energy of waypoint {node} is {energy_j} J: it must be finite and not negative")]
    BadHoverEnergy { node: usize, energy_j: f64 },
    #[error("the {what} is {energy_j} J: it must be finite and not negative")]
    BadEnergy { what: &'static str, energy_j: f64 },
    #[error(
        "waypoint {node} cannot be flown even alone: take-off, out, hover, back and landing need \
         {alone_j:.0} J but one battery allows {budget_j:.0} J"
    )]
    Unreachable {
        node: usize,
        alone_j: f64,
        budget_j: f64,
    },
    #[error("the exact sortie split handles at most {max} waypoints ({n} given)")]
    TooManyForExact { n: usize, max: usize },
    #[error("the giant tour must list every waypoint node 1..={n} exactly once")]
    NotATour { n: usize },
}

/// Splits the waypoints into sorties of least total energy: exactly when there are at most
/// `options.exact_max_waypoints` (capped at [`EXACT_LIMIT`]), heuristically otherwise.
pub fn split(problem: &SortieProblem, options: &SortieOptions) -> Result<SortiePlan, SortieError> {
    let waypoints = problem.energy.len().saturating_sub(1);
    if waypoints <= options.exact_max_waypoints.min(EXACT_LIMIT) {
        exact(problem)
    } else {
        heuristic(problem, options)
    }
}

/// Checked inputs: hover energy by node (0 for the origin).
struct Checked<'a> {
    m: &'a CostMatrix,
    hover_j: Vec<f64>,
    fixed_j: f64,
    budget_j: f64,
}

impl Checked<'_> {
    fn c(&self, from: usize, to: usize) -> f64 {
        self.m.cost(from, to)
    }

    fn sortie(&self, order: Vec<usize>) -> Sortie {
        let legs_j = self.m.tour_cost(&order);
        let hover_j: f64 = order.iter().map(|&k| self.hover_j[k]).sum();
        Sortie {
            total_j: self.fixed_j + legs_j + hover_j,
            order,
            fixed_j: self.fixed_j,
            legs_j,
            hover_j,
        }
    }

    fn plan(&self, orders: Vec<Vec<usize>>, method: Method) -> SortiePlan {
        let mut sorties: Vec<Sortie> = orders
            .into_iter()
            .filter(|o| !o.is_empty())
            .map(|o| self.sortie(o))
            .collect();
        sorties.sort_by_key(|s| s.order.iter().copied().min().unwrap_or(0));
        SortiePlan {
            total_j: sorties.iter().map(|s| s.total_j).sum(),
            sorties,
            optimal: method == Method::Exact,
            method,
        }
    }
}

fn check<'a>(p: &SortieProblem<'a>) -> Result<Checked<'a>, SortieError> {
    let n = p.energy.len();
    let waypoints = n.saturating_sub(1);
    if p.hover_j.len() != waypoints {
        return Err(SortieError::HoverCount {
            waypoints,
            hovers: p.hover_j.len(),
        });
    }
    let bad = |v: f64| !v.is_finite() || v < 0.0;
    for from in 0..n {
        for to in 0..n {
            let energy_j = p.energy.cost(from, to);
            if from != to && bad(energy_j) {
                return Err(SortieError::BadLegEnergy { from, to, energy_j });
            }
        }
    }
    for (k, &energy_j) in p.hover_j.iter().enumerate() {
        if bad(energy_j) {
            return Err(SortieError::BadHoverEnergy {
                node: k + 1,
                energy_j,
            });
        }
    }
    for (what, energy_j) in [
        ("fixed energy per sortie", p.fixed_j),
        ("budget per battery", p.budget_j),
    ] {
        if bad(energy_j) {
            return Err(SortieError::BadEnergy { what, energy_j });
        }
    }
    let checked = Checked {
        m: p.energy,
        hover_j: std::iter::once(0.0)
            .chain(p.hover_j.iter().copied())
            .collect(),
        fixed_j: p.fixed_j,
        budget_j: p.budget_j,
    };
    for node in 1..n {
        let alone_j = checked.sortie(vec![node]).total_j;
        if alone_j > p.budget_j {
            return Err(SortieError::Unreachable {
                node,
                alone_j,
                budget_j: p.budget_j,
            });
        }
    }
    Ok(checked)
}

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

/// A feasible split of any size: Prins' split of a giant tour, local search between sorties,
/// seeded restarts. Deterministic for `options.seed`.
pub fn heuristic(
    problem: &SortieProblem,
    options: &SortieOptions,
) -> Result<SortiePlan, SortieError> {
    let p = check(problem)?;
    let m = p.m.len().saturating_sub(1);
    let giant = match &options.giant_tour {
        Some(tour) if is_tour_order(m + 1, tour) => tour.clone(),
        Some(_) => return Err(SortieError::NotATour { n: m }),
        None => giant_tour(&p),
    };
    let mut best = improve(&p, prins_split(&p, &giant));
    let mut best_j = solution_j(&p, &best);
    let mut rng = Rng::new(options.seed);
    for _ in 1..options.restarts {
        let mut sorties = best.clone();
        for k in (1..sorties.len()).rev() {
            sorties.swap(k, rng.below(k + 1));
        }
        let mut giant: Vec<usize> = sorties.into_iter().flatten().collect();
        kick(&mut giant, &mut rng);
        let candidate = improve(&p, prins_split(&p, &giant));
        let candidate_j = solution_j(&p, &candidate);
        if candidate_j < best_j - eps(best_j) {
            best = candidate;
            best_j = candidate_j;
        }
    }
    Ok(p.plan(best, Method::Heuristic))
}

fn eps(scale_j: f64) -> f64 {
    1e-9 * scale_j.abs().max(1.0)
}

fn solution_j(p: &Checked, sorties: &[Vec<usize>]) -> f64 {
    sorties.iter().map(|o| p.sortie(o.clone()).total_j).sum()
}

/// The single min-energy tour: Held-Karp when small, nearest neighbour plus Or-opt otherwise.
fn giant_tour(p: &Checked) -> Vec<usize> {
    let m = p.m.len().saturating_sub(1);
    if m <= GIANT_TOUR_EXACT_MAX {
        if let Ok(tour) = held_karp::solve(p.m) {
            return tour.order;
        }
    }
    let mut tour = Vec::with_capacity(m);
    let mut left: Vec<usize> = (1..=m).collect();
    let mut here = 0;
    while !left.is_empty() {
        let mut pick = 0;
        for (i, &k) in left.iter().enumerate() {
            if p.c(here, k) < p.c(here, left[pick]) {
                pick = i;
            }
        }
        here = left.remove(pick);
        tour.push(here);
    }
    or_opt(p, &mut tour);
    tour
}

/// Prins' split (Prins 2004): the optimal cutting of `giant` into consecutive feasible
/// sorties, as a shortest path over the cut points 0..=len (Bellman on a DAG, O(len^2)).
fn prins_split(p: &Checked, giant: &[usize]) -> Vec<Vec<usize>> {
    let len = giant.len();
    let mut v = vec![f64::INFINITY; len + 1];
    let mut pred = vec![0usize; len + 1];
    v[0] = 0.0;
    for i in 0..len {
        if !v[i].is_finite() {
            continue;
        }
        // Energy of origin -> giant[i..=j] before flying home; it only grows with j, so once it
        // exceeds the budget no longer sortie from cut i fits.
        let mut outbound_j = p.fixed_j;
        for j in i..len {
            let from = if j == i { 0 } else { giant[j - 1] };
            outbound_j += p.c(from, giant[j]) + p.hover_j[giant[j]];
            if outbound_j > p.budget_j {
                break;
            }
            let total_j = outbound_j + p.c(giant[j], 0);
            if total_j <= p.budget_j && v[i] + total_j < v[j + 1] {
                v[j + 1] = v[i] + total_j;
                pred[j + 1] = i;
            }
        }
    }
    let mut sorties = Vec::new();
    let mut j = len;
    while j > 0 {
        let i = pred[j];
        sorties.push(giant[i..j].to_vec());
        j = i;
    }
    sorties.reverse();
    sorties
}

/// A seeded perturbation of a giant tour: a double bridge (segments A B C D -> A C B D, which
/// keeps every segment's direction, as asymmetric costs need) and one random relocation.
fn kick(giant: &mut Vec<usize>, rng: &mut Rng) {
    let len = giant.len();
    if len >= 4 {
        let mut cuts = [
            1 + rng.below(len - 1),
            1 + rng.below(len - 1),
            1 + rng.below(len - 1),
        ];
        cuts.sort_unstable();
        let [a, b, c] = cuts;
        let mut next = giant[..a].to_vec();
        next.extend_from_slice(&giant[b..c]);
        next.extend_from_slice(&giant[a..b]);
        next.extend_from_slice(&giant[c..]);
        *giant = next;
    }
    if len >= 2 {
        let node = giant.remove(rng.below(len));
        giant.insert(rng.below(len), node);
    }
}

/// One sortie in the local search.
#[derive(Debug, Clone)]
struct Route {
    order: Vec<usize>,
    legs_j: f64,
    hover_j: f64,
}

impl Route {
    fn new(p: &Checked, order: Vec<usize>) -> Route {
        let mut route = Route {
            legs_j: p.m.tour_cost(&order),
            hover_j: order.iter().map(|&k| p.hover_j[k]).sum(),
            order,
        };
        reorder(p, &mut route);
        route
    }

    fn total_j(&self, p: &Checked) -> f64 {
        p.fixed_j + self.legs_j + self.hover_j
    }

    /// Node before and after position `i` (the origin at the ends).
    fn around(&self, i: usize) -> (usize, usize) {
        let prev = if i == 0 { 0 } else { self.order[i - 1] };
        let next = self.order.get(i + 1).copied().unwrap_or(0);
        (prev, next)
    }
}

/// Re-orders a sortie optimally (Held-Karp on its nodes) when small, by Or-opt otherwise.
fn reorder(p: &Checked, route: &mut Route) {
    let len = route.order.len();
    if len <= 2 {
        // One node has one order; two nodes: keep the cheaper direction.
        if len == 2 {
            let flipped = [route.order[1], route.order[0]];
            let flipped_j = p.m.tour_cost(&flipped);
            if flipped_j < route.legs_j {
                route.order = flipped.to_vec();
                route.legs_j = flipped_j;
            }
        }
        return;
    }
    if len <= SUBTOUR_EXACT_MAX {
        let nodes: Vec<usize> = std::iter::once(0)
            .chain(route.order.iter().copied())
            .collect();
        if let Ok((order, legs_j)) =
            held_karp::solve_with(nodes.len(), |i, j| p.c(nodes[i], nodes[j]))
        {
            if legs_j < route.legs_j {
                route.order = order.into_iter().map(|i| nodes[i]).collect();
                route.legs_j = legs_j;
            }
        }
    } else {
        or_opt(p, &mut route.order);
        route.legs_j = p.m.tour_cost(&route.order);
    }
}

/// Or-opt (Or 1976): move segments of 1 to 3 consecutive nodes elsewhere in the tour, keeping
/// their direction, while that lowers the tour's cost (first improvement).
fn or_opt(p: &Checked, tour: &mut Vec<usize>) {
    let mut cost_j = p.m.tour_cost(tour);
    let mut improved = true;
    while improved {
        improved = false;
        'search: for seg in 1..=3usize {
            for start in 0..tour.len().saturating_sub(seg - 1) {
                let segment: Vec<usize> = tour[start..start + seg].to_vec();
                let mut rest = tour.clone();
                rest.drain(start..start + seg);
                for at in 0..=rest.len() {
                    if at == start {
                        continue;
                    }
                    let mut candidate = rest.clone();
                    candidate.splice(at..at, segment.iter().copied());
                    let candidate_j = p.m.tour_cost(&candidate);
                    if candidate_j < cost_j - eps(cost_j) {
                        *tour = candidate;
                        cost_j = candidate_j;
                        improved = true;
                        break 'search;
                    }
                }
            }
        }
    }
}

/// Local search between sorties until no move lowers the total energy: merge two sorties,
/// relocate a waypoint, exchange two waypoints, swap two sorties' tails (2-opt*). Every
/// accepted move keeps every sortie within the budget and strictly lowers the total.
fn improve(p: &Checked, sorties: Vec<Vec<usize>>) -> Vec<Vec<usize>> {
    let mut routes: Vec<Route> = sorties.into_iter().map(|o| Route::new(p, o)).collect();
    // Each move lowers the total by more than eps, so this bound is never the reason to stop
    // in practice; it only guarantees termination.
    for _ in 0..100_000 {
        let moved = merge(p, &mut routes)
            || relocate(p, &mut routes)
            || exchange(p, &mut routes)
            || swap_tails(p, &mut routes);
        routes.retain(|r| !r.order.is_empty());
        if !moved {
            break;
        }
    }
    routes.into_iter().map(|r| r.order).collect()
}

fn merge(p: &Checked, routes: &mut Vec<Route>) -> bool {
    for a in 0..routes.len() {
        for b in a + 1..routes.len() {
            if routes[a].hover_j + routes[b].hover_j + p.fixed_j > p.budget_j {
                continue;
            }
            let before_j = routes[a].total_j(p) + routes[b].total_j(p);
            let joined: Vec<usize> = routes[a]
                .order
                .iter()
                .chain(&routes[b].order)
                .copied()
                .collect();
            let route = Route::new(p, joined);
            let after_j = route.total_j(p);
            if after_j <= p.budget_j && after_j < before_j - eps(before_j) {
                routes[a] = route;
                routes.remove(b);
                return true;
            }
        }
    }
    false
}

fn relocate(p: &Checked, routes: &mut [Route]) -> bool {
    for a in 0..routes.len() {
        for i in 0..routes[a].order.len() {
            let v = routes[a].order[i];
            let (prev, next) = routes[a].around(i);
            let emptied = routes[a].order.len() == 1;
            // Change of sortie a's energy when v leaves it.
            let leave_j = if emptied {
                -routes[a].total_j(p)
            } else {
                p.c(prev, next) - p.c(prev, v) - p.c(v, next) - p.hover_j[v]
            };
            if !emptied && routes[a].total_j(p) + leave_j > p.budget_j {
                continue;
            }
            for b in 0..routes.len() {
                if b == a {
                    continue;
                }
                let route_b = &routes[b];
                let mut best: Option<(usize, f64)> = None;
                for at in 0..=route_b.order.len() {
                    let before = if at == 0 { 0 } else { route_b.order[at - 1] };
                    let after = route_b.order.get(at).copied().unwrap_or(0);
                    let enter_j =
                        p.c(before, v) + p.c(v, after) - p.c(before, after) + p.hover_j[v];
                    if best.is_none_or(|(_, e)| enter_j < e) {
                        best = Some((at, enter_j));
                    }
                }
                let Some((at, enter_j)) = best else { continue };
                let total_j = route_b.total_j(p);
                if total_j + enter_j > p.budget_j || leave_j + enter_j >= -eps(total_j) {
                    continue;
                }
                let mut order_a = routes[a].order.clone();
                order_a.remove(i);
                let mut order_b = routes[b].order.clone();
                order_b.insert(at, v);
                routes[a] = Route::new(p, order_a);
                routes[b] = Route::new(p, order_b);
                return true;
            }
        }
    }
    false
}

fn exchange(p: &Checked, routes: &mut [Route]) -> bool {
    for a in 0..routes.len() {
        for b in a + 1..routes.len() {
            for i in 0..routes[a].order.len() {
                for j in 0..routes[b].order.len() {
                    let (u, v) = (routes[a].order[i], routes[b].order[j]);
                    let (pa, na) = routes[a].around(i);
                    let (pb, nb) = routes[b].around(j);
                    let delta_a = p.c(pa, v) + p.c(v, na) - p.c(pa, u) - p.c(u, na) + p.hover_j[v]
                        - p.hover_j[u];
                    let delta_b = p.c(pb, u) + p.c(u, nb) - p.c(pb, v) - p.c(v, nb) + p.hover_j[u]
                        - p.hover_j[v];
                    let (ta, tb) = (routes[a].total_j(p), routes[b].total_j(p));
                    if ta + delta_a > p.budget_j
                        || tb + delta_b > p.budget_j
                        || delta_a + delta_b >= -eps(ta + tb)
                    {
                        continue;
                    }
                    let mut order_a = routes[a].order.clone();
                    let mut order_b = routes[b].order.clone();
                    order_a[i] = v;
                    order_b[j] = u;
                    routes[a] = Route::new(p, order_a);
                    routes[b] = Route::new(p, order_b);
                    return true;
                }
            }
        }
    }
    false
}

/// 2-opt* (Potvin and Rousseau 1995): sorties a = a1 a2 and b = b1 b2 become a1 b2 and b1 a2.
fn swap_tails(p: &Checked, routes: &mut [Route]) -> bool {
    for a in 0..routes.len() {
        for b in a + 1..routes.len() {
            let before_j = routes[a].total_j(p) + routes[b].total_j(p);
            for i in 0..=routes[a].order.len() {
                for j in 0..=routes[b].order.len() {
                    let (oa, ob) = (&routes[a].order, &routes[b].order);
                    if (i == 0 && j == 0) || (i == oa.len() && j == ob.len()) {
                        continue;
                    }
                    let new_a: Vec<usize> = oa[..i].iter().chain(&ob[j..]).copied().collect();
                    let new_b: Vec<usize> = ob[..j].iter().chain(&oa[i..]).copied().collect();
                    let total = |order: &[usize]| {
                        if order.is_empty() {
                            0.0
                        } else {
                            p.fixed_j
                                + p.m.tour_cost(order)
                                + order.iter().map(|&k| p.hover_j[k]).sum::<f64>()
                        }
                    };
                    let (ta, tb) = (total(&new_a), total(&new_b));
                    if ta > p.budget_j || tb > p.budget_j || ta + tb >= before_j - eps(before_j) {
                        continue;
                    }
                    routes[a] = Route::new(p, new_a);
                    routes[b] = Route::new(p, new_b);
                    return true;
                }
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random instance: waypoints in a 300 m x 300 m x 60 m box, legs priced like a
    /// multirotor (climbing dear, descending cheap, a fixed cost per stop), so asymmetric;
    /// hovers of 0-120 s at 640 W; a budget between the dearest lone waypoint and a single tour.
    struct Instance {
        energy: CostMatrix,
        hover_j: Vec<f64>,
        fixed_j: f64,
        budget_j: f64,
    }

    impl Instance {
        fn problem(&self) -> SortieProblem<'_> {
            SortieProblem {
                energy: &self.energy,
                hover_j: &self.hover_j,
                fixed_j: self.fixed_j,
                budget_j: self.budget_j,
            }
        }
    }

    /// `budget_factor`: the budget's range as multiples of the dearest lone waypoint.
    fn instance(rng: &mut Rng, waypoints: usize, budget_factor: (f64, f64)) -> Instance {
        let budget_factor = rng.uniform(budget_factor.0, budget_factor.1 + 1e-12);
        let pts: Vec<[f64; 3]> = std::iter::once([0.0; 3])
            .chain((0..waypoints).map(|_| {
                [
                    rng.uniform(-150.0, 150.0),
                    rng.uniform(-150.0, 150.0),
                    rng.uniform(-30.0, 30.0),
                ]
            }))
            .collect();
        let energy = CostMatrix::from_fn(waypoints + 1, |i, j| {
            let (a, b) = (pts[i], pts[j]);
            let h = (b[0] - a[0]).hypot(b[1] - a[1]);
            let dz = b[2] - a[2];
            let vertical_j = if dz > 0.0 { 250.0 * dz } else { -50.0 * dz };
            1500.0 + 100.0 * h + vertical_j
        });
        let hover_j: Vec<f64> = (0..waypoints)
            .map(|_| 640.0 * rng.uniform(0.0, 120.0))
            .collect();
        let fixed_j = 20_000.0;
        let alone = (1..=waypoints)
            .map(|k| fixed_j + energy.cost(0, k) + energy.cost(k, 0) + hover_j[k - 1])
            .fold(0.0, f64::max);
        let budget_j = alone * budget_factor;
        Instance {
            energy,
            hover_j,
            fixed_j,
            budget_j,
        }
    }

    /// The oracle: every permutation of the waypoints cut in every way into consecutive runs
    /// enumerates every partition into sorties with every flying order.
    fn brute_force_j(inst: &Instance) -> f64 {
        let m = inst.energy.len() - 1;
        let mut perm: Vec<usize> = (1..=m).collect();
        let mut best = f64::INFINITY;
        let mut visit = |perm: &[usize]| {
            for cuts in 0..(1u32 << m.saturating_sub(1)) {
                let mut total = 0.0;
                let mut start = 0;
                for end in 1..=m {
                    if end == m || cuts & (1 << (end - 1)) != 0 {
                        let run = &perm[start..end];
                        let sortie = inst.fixed_j
                            + inst.energy.tour_cost(run)
                            + run.iter().map(|&k| inst.hover_j[k - 1]).sum::<f64>();
                        if sortie > inst.budget_j {
                            total = f64::INFINITY;
                            break;
                        }
                        total += sortie;
                        start = end;
                    }
                }
                best = best.min(total);
            }
        };
        // Heap's algorithm.
        visit(&perm);
        let mut c = vec![0usize; m];
        let mut i = 0;
        while i < m {
            if c[i] < i {
                if i % 2 == 0 {
                    perm.swap(0, i);
                } else {
                    perm.swap(c[i], i);
                }
                visit(&perm);
                c[i] += 1;
                i = 0;
            } else {
                c[i] = 0;
                i += 1;
            }
        }
        best
    }

    fn assert_valid(inst: &Instance, plan: &SortiePlan) {
        let m = inst.energy.len() - 1;
        let mut seen: Vec<usize> = plan.sorties.iter().flat_map(|s| s.order.clone()).collect();
        seen.sort_unstable();
        assert_eq!(seen, (1..=m).collect::<Vec<_>>(), "{plan:?}");
        let mut total = 0.0;
        for s in &plan.sorties {
            assert!(!s.order.is_empty());
            assert!(s.total_j <= inst.budget_j, "{s:?} over {}", inst.budget_j);
            let legs = inst.energy.tour_cost(&s.order);
            let hover: f64 = s.order.iter().map(|&k| inst.hover_j[k - 1]).sum();
            assert!((s.legs_j - legs).abs() < 1e-6 && (s.hover_j - hover).abs() < 1e-6);
            assert!((s.total_j - (inst.fixed_j + legs + hover)).abs() < 1e-6);
            total += s.total_j;
        }
        assert!((plan.total_j - total).abs() < 1e-6);
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0)
    }

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

    #[test]
    fn every_sortie_fits_the_budget_and_every_waypoint_is_flown_exactly_once() {
        let mut rng = Rng::new(3);
        for case in 0..40 {
            let m = 2 + case % 12;
            let inst = instance(&mut rng, m, (1.0, 2.5));
            assert_valid(&inst, &exact(&inst.problem()).unwrap());
            let options = SortieOptions {
                restarts: 8,
                ..SortieOptions::default()
            };
            assert_valid(&inst, &heuristic(&inst.problem(), &options).unwrap());
        }
    }

    #[test]
    fn one_battery_that_suffices_gives_one_sortie_equal_to_the_held_karp_tour() {
        let mut rng = Rng::new(11);
        for m in [1, 5, 9, 12] {
            let inst = instance(&mut rng, m, (100.0, 100.0));
            let tour = held_karp::solve(&inst.energy).unwrap();
            for plan in [
                exact(&inst.problem()).unwrap(),
                heuristic(&inst.problem(), &SortieOptions::default()).unwrap(),
            ] {
                assert_eq!(plan.sorties.len(), 1, "{plan:?}");
                assert_eq!(plan.sorties[0].order, tour.order);
                assert!(close(plan.sorties[0].legs_j, tour.cost));
            }
        }
    }

    #[test]
    fn a_waypoint_too_far_to_reach_alone_is_an_error_naming_it() {
        let mut rng = Rng::new(5);
        let mut inst = instance(&mut rng, 6, (1.5, 1.5));
        inst.hover_j[3] = inst.budget_j; // node 4 hovers a whole battery
        let err = exact(&inst.problem()).unwrap_err();
        assert!(
            matches!(err, SortieError::Unreachable { node: 4, alone_j, budget_j }
                if alone_j > budget_j && budget_j == inst.budget_j),
            "{err:?}"
        );
        assert!(err
            .to_string()
            .contains("waypoint 4 cannot be flown even alone"));
        assert_eq!(
            heuristic(&inst.problem(), &SortieOptions::default()).unwrap_err(),
            err
        );
    }

    #[test]
    fn non_finite_or_negative_energies_and_mismatched_hovers_are_errors() {
        let mut rng = Rng::new(6);
        let inst = instance(&mut rng, 4, (1.5, 1.5));
        let nan = CostMatrix::from_fn(5, |i, j| {
            if (i, j) == (2, 3) {
                f64::NAN
            } else {
                inst.energy.cost(i, j)
            }
        });
        let problem = SortieProblem {
            energy: &nan,
            ..inst.problem()
        };
        assert!(matches!(
            exact(&problem),
            Err(SortieError::BadLegEnergy { from: 2, to: 3, .. })
        ));
        let hovers = [1.0, f64::INFINITY, 1.0, 1.0];
        let problem = SortieProblem {
            hover_j: &hovers,
            ..inst.problem()
        };
        assert!(matches!(
            exact(&problem),
            Err(SortieError::BadHoverEnergy { node: 2, .. })
        ));
        let problem = SortieProblem {
            budget_j: f64::NAN,
            ..inst.problem()
        };
        assert!(matches!(
            heuristic(&problem, &SortieOptions::default()),
            Err(SortieError::BadEnergy { .. })
        ));
        let problem = SortieProblem {
            fixed_j: -1.0,
            ..inst.problem()
        };
        assert!(matches!(
            exact(&problem),
            Err(SortieError::BadEnergy { .. })
        ));
        let problem = SortieProblem {
            hover_j: &hovers[..3],
            ..inst.problem()
        };
        assert_eq!(
            exact(&problem),
            Err(SortieError::HoverCount {
                waypoints: 4,
                hovers: 3
            })
        );
    }

    #[test]
    fn a_mission_without_waypoints_needs_no_sortie() {
        let energy = CostMatrix::from_fn(1, |_, _| 0.0);
        let problem = SortieProblem {
            energy: &energy,
            hover_j: &[],
            fixed_j: 10.0,
            budget_j: 100.0,
        };
        for plan in [
            exact(&problem).unwrap(),
            heuristic(&problem, &SortieOptions::default()).unwrap(),
        ] {
            assert!(plan.sorties.is_empty());
            assert_eq!(plan.total_j, 0.0);
        }
    }

    #[test]
    fn prins_split_cuts_a_giant_tour_optimally_among_all_its_cuttings() {
        let mut rng = Rng::new(8);
        for case in 0..60 {
            let m = 1 + case % 9;
            let inst = instance(&mut rng, m, (1.0, 3.0));
            let p = check(&inst.problem()).unwrap();
            let giant: Vec<usize> = (1..=m).collect();
            let sorties = prins_split(&p, &giant);
            assert_eq!(sorties.concat(), giant);
            let got = solution_j(&p, &sorties);
            let mut best = f64::INFINITY;
            for cuts in 0..(1u32 << (m - 1)) {
                let mut runs = vec![vec![giant[0]]];
                for (k, &node) in giant.iter().enumerate().skip(1) {
                    if cuts & (1 << (k - 1)) != 0 {
                        runs.push(Vec::new());
                    }
                    runs.last_mut().unwrap().push(node);
                }
                if runs
                    .iter()
                    .all(|r| p.sortie(r.clone()).total_j <= inst.budget_j)
                {
                    best = best.min(solution_j(&p, &runs));
                }
            }
            assert!(close(got, best), "case {case}: {got} vs {best}");
        }
    }

    #[test]
    fn the_heuristic_stays_within_two_percent_of_the_exact_split_on_medium_instances() {
        let mut rng = Rng::new(2024);
        let mut worst_gap = 0.0f64;
        let mut gaps = 0.0;
        let cases = 30;
        for case in 0..cases {
            let m = 10 + case % 3;
            let inst = instance(&mut rng, m, (1.0, 2.0));
            let opt = exact(&inst.problem()).unwrap();
            let heur = heuristic(&inst.problem(), &SortieOptions::default()).unwrap();
            assert_valid(&inst, &heur);
            assert!(!heur.optimal && heur.method == Method::Heuristic);
            assert!(heur.total_j >= opt.total_j - 1e-6);
            let gap = heur.total_j / opt.total_j - 1.0;
            worst_gap = worst_gap.max(gap);
            gaps += gap;
        }
        eprintln!(
            "heuristic vs exact on {cases} instances of 10-12 waypoints: mean gap {:.3}%, worst {:.3}%",
            100.0 * gaps / cases as f64,
            100.0 * worst_gap
        );
        assert!(worst_gap < 0.02, "worst gap {worst_gap}");
    }

    #[test]
    fn the_heuristic_splits_forty_waypoints_feasibly_where_the_exact_method_refuses() {
        let mut rng = Rng::new(40);
        let inst = instance(&mut rng, 40, (1.5, 1.5));
        assert_eq!(
            exact(&inst.problem()),
            Err(SortieError::TooManyForExact {
                n: 40,
                max: EXACT_LIMIT
            })
        );
        let plan = split(&inst.problem(), &SortieOptions::default()).unwrap();
        assert_eq!(plan.method, Method::Heuristic);
        assert!(plan.sorties.len() > 1);
        assert_valid(&inst, &plan);
    }

    #[test]
    fn a_given_giant_tour_must_list_every_waypoint_once() {
        let mut rng = Rng::new(9);
        let inst = instance(&mut rng, 4, (1.5, 1.5));
        for tour in [
            vec![1, 2, 3],
            vec![1, 2, 3, 3],
            vec![0, 1, 2, 3],
            vec![1, 2, 3, 5],
        ] {
            let options = SortieOptions {
                giant_tour: Some(tour),
                ..SortieOptions::default()
            };
            assert_eq!(
                heuristic(&inst.problem(), &options),
                Err(SortieError::NotATour { n: 4 })
            );
        }
    }

    #[test]
    fn the_same_seed_gives_the_same_split_and_split_picks_exact_when_small() {
        let mut rng = Rng::new(12);
        let inst = instance(&mut rng, 24, (1.4, 1.4));
        let options = SortieOptions {
            seed: 99,
            restarts: 16,
            ..SortieOptions::default()
        };
        let a = heuristic(&inst.problem(), &options).unwrap();
        let b = heuristic(&inst.problem(), &options).unwrap();
        assert_eq!(a, b);
        let small = instance(&mut rng, 9, (1.4, 1.4));
        let a = split(&small.problem(), &SortieOptions::default()).unwrap();
        assert_eq!(a.method, Method::Exact);
        assert_eq!(a, exact(&small.problem()).unwrap());
    }
}
