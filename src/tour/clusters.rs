//! Tours through stops that are points or blocks: a block is a cluster of the ways it may be
//! flown (forward, and reversed when reversible), each entered at one node and left at
//! another with its own inner cost, and a tour visits every stop once in one of its ways (a
//! generalised asymmetric TSP). The planner hands it the cost matrix of every node (node 0 the
//! origin) and the stops; this module chooses the order and the ways.
//!
//! Three solvers, chosen by size in [`solve`]:
//! - **Direction-aware Held-Karp** ([`MAX_DP_STATES`]): dynamic programming over (stops
//!   visited, last stop, the way it was flown), exact.
//! - **Noon-Bean transformation to an ATSP** solved by the branch-and-cut
//!   ([`super::branch_cut`]), started from the local search's tour: exact when the search
//!   finishes, else its best tour and the least bound of its open nodes. The transformation and
//!   its proof are on [`NoonBean`].
//! - **Local search** over the order and the ways (Or-opt, 2-opt with and without flipping the
//!   ways of the reversed stretch, the best ways for the order by dynamic programming, double
//!   bridge kicks; seeded), with the DFJ lower bound ([`super::bound::dfj_bound`]) of the
//!   Noon-Bean instance mapped back.
//!
//! Invariant: every answer carries a proven lower bound and is `optimal` only when it meets
//! it; a stop's nodes other than its entry and exit are never in the matrix's tour.

use std::time::{Duration, Instant};

use super::progress::{self, Event};
use super::solver::{Options, Solver, AUTO_BRANCH_CUT_MAX_NODES};
use super::{bound, branch_cut, held_karp, CostMatrix, PlanError};
use crate::rng::Rng;

/// One way to fly a stop: entered at node `entry`, left from node `exit`, costing `inner` in
/// between (0 for a point, whose entry and exit are its node).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Way {
    pub entry: usize,
    pub exit: usize,
    pub inner: f64,
}

/// A point (one way) or a block (one way, or two: forward then reversed).
#[derive(Debug, Clone, PartialEq)]
pub struct Stop {
    pub ways: Vec<Way>,
}

impl Stop {
    /// A single point at `node`.
    pub fn point(node: usize) -> Stop {
        Stop {
            ways: vec![Way {
                entry: node,
                exit: node,
                inner: 0.0,
            }],
        }
    }
}

/// A stop visited in one of its ways: indices into the stops and into that stop's ways.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Visit {
    pub stop: usize,
    pub way: usize,
}

/// A solved tour through the stops: the visits in order (origin excluded at both ends), its
/// cost (connecting arcs of `m` plus the inner costs), a lower bound and whether it is proven
/// optimal, with the solver that found it.
#[derive(Debug, Clone, PartialEq)]
pub struct StopTour {
    pub visits: Vec<Visit>,
    pub cost: f64,
    pub lower_bound: f64,
    pub optimal: bool,
    /// `held-karp` (the direction-aware dynamic programme),
    /// `branch-cut` (Noon-Bean) or `heuristic` (local search and the DFJ bound).
    pub solver: Solver,
    /// Relative gap between the cost and the lower bound, in percent (0 when optimal).
    pub gap_pct: f64,
    /// Wall-clock seconds of the solve.
    pub seconds: f64,
}

/// The cost of flying `visits` from the origin and back: each connecting arc of `m` from the
/// exit of one visit to the entry of the next, plus each visit's inner cost.
pub fn tour_cost(m: &CostMatrix, stops: &[Stop], visits: &[Visit]) -> f64 {
    let mut at = 0;
    let mut total = 0.0;
    for v in visits {
        let way = stops[v.stop].ways[v.way];
        total += m.cost(at, way.entry) + way.inner;
        at = way.exit;
    }
    total + m.cost(at, 0)
}

/// Largest number of two-way stops whose ways [`solve_by_ways`] enumerates.
#[cfg(test)]
const MAX_ENUMERATED_BLOCKS: usize = 10;

/// The optimal tour by trying every choice of ways (2^blocks of them) and solving each as an
/// ordinary ATSP over the stops with Held-Karp: exact, for at most [`held_karp::MAX_NODES`]
/// stops and [`MAX_ENUMERATED_BLOCKS`] two-way stops. A reference for [`solve`]'s solvers.
#[cfg(test)]
fn solve_by_ways(m: &CostMatrix, stops: &[Stop]) -> Result<StopTour, PlanError> {
    let started = Instant::now();
    let two_way: Vec<usize> = (0..stops.len())
        .filter(|&s| stops[s].ways.len() > 1)
        .collect();
    if two_way.len() > MAX_ENUMERATED_BLOCKS {
        return Err(PlanError::Infeasible(format!(
            "enumerating the ways of {} blocks (at most {MAX_ENUMERATED_BLOCKS})",
            two_way.len()
        )));
    }
    let mut best: Option<StopTour> = None;
    for choice in 0u32..(1u32 << two_way.len()) {
        let way_of = |s: usize| -> usize {
            two_way
                .iter()
                .position(|&t| t == s)
                .map_or(0, |bit| ((choice >> bit) & 1) as usize)
        };
        let ways: Vec<Way> = (0..stops.len()).map(|s| stops[s].ways[way_of(s)]).collect();
        let fixed = CostMatrix::from_fn(stops.len() + 1, |i, j| {
            let exit = if i == 0 { 0 } else { ways[i - 1].exit };
            match j {
                0 => m.cost(exit, 0),
                _ => m.cost(exit, ways[j - 1].entry) + ways[j - 1].inner,
            }
        });
        let super::Tour { order, cost, .. } = held_karp::solve(&fixed)?;
        if best.as_ref().is_none_or(|b| cost < b.cost) {
            best = Some(StopTour {
                visits: order
                    .iter()
                    .map(|&k| Visit {
                        stop: k - 1,
                        way: way_of(k - 1),
                    })
                    .collect(),
                cost,
                lower_bound: cost,
                optimal: true,
                solver: Solver::HeldKarp,
                gap_pct: 0.0,
                seconds: 0.0,
            });
        }
    }
    best.map(|b| StopTour {
        seconds: started.elapsed().as_secs_f64(),
        ..b
    })
    .ok_or_else(|| PlanError::Infeasible("no stops".into()))
}

/// States (stops visited x the way last flown) up to which the direction-aware Held-Karp runs
/// when asked for: the plain Held-Karp's largest instance ([`held_karp::MAX_NODES`] = 20
/// waypoints, 2^20 x 20 states of 8 + 2 bytes, about 210 MB and half a second). Twenty points,
/// or sixteen stops of which half are two-way blocks (2^16 x 24 states), fit.
pub const MAX_DP_STATES: usize = (1 << held_karp::MAX_NODES) * held_karp::MAX_NODES;

/// States up to which `auto` runs the direction-aware Held-Karp: 2^21, about 20 MB and a few
/// hundredths of a second, so the study's thousands of missions stay fast (ten points and
/// three blocks are 2^13 x 16 states; twelve points and four blocks 2^16 x 20).
pub const AUTO_DP_STATES: usize = 1 << 21;

/// Share of the time limit the local search may take before branch-and-cut.
const SEARCH_SHARE_BEFORE_BRANCH_CUT: f64 = 0.3;
/// Share of the time limit the local search may take before the DFJ lower bound.
const SEARCH_SHARE_BEFORE_BOUND: f64 = 0.4;

/// The minimum-cost tour through `stops` (node 0 of `m` the origin), as `options` ask: exact
/// where it can be proven, else the best found with its proven lower bound.
///
/// `auto` runs the direction-aware Held-Karp up to [`AUTO_DP_STATES`] states, the local search
/// then branch-and-cut on the Noon-Bean instance up to
/// [`AUTO_BRANCH_CUT_MAX_NODES`] ways, and the local search with the DFJ bound beyond; each
/// named solver runs as named (`held-karp` refuses more than [`MAX_DP_STATES`] states).
/// Never past the thread's cancel token ([`super::cancel`]): a cancelled run returns its best
/// tour and bound so far.
pub fn solve(m: &CostMatrix, stops: &[Stop], options: &Options) -> Result<StopTour, PlanError> {
    let started = Instant::now();
    let options = &Options {
        time_limit: super::cancel::limit(options.time_limit),
        ..*options
    };
    let flat = Flat::new(m, stops)?;
    let states = flat.dp_states();
    let solver = match options.solver {
        Solver::Auto if states.is_some_and(|s| s <= AUTO_DP_STATES) => Solver::HeldKarp,
        Solver::Auto if flat.ways() < AUTO_BRANCH_CUT_MAX_NODES => Solver::BranchCut,
        Solver::Auto => Solver::Heuristic,
        chosen => chosen,
    };
    let budget = |share: f64| options.time_limit.mul_f64(share);
    let left = || options.time_limit.saturating_sub(started.elapsed());
    let (ids, lower_bound, proven) = match solver {
        Solver::HeldKarp => {
            progress::report(Event::Phase("Held-Karp"));
            let (ids, cost) = held_karp_ways(&flat)?;
            (ids, cost, true)
        }
        Solver::BranchCut => {
            let found = local_search(&flat, options, budget(SEARCH_SHARE_BEFORE_BRANCH_CUT));
            progress::report(Event::Phase("branch-and-cut"));
            let nb = NoonBean::new(&flat, found.cost);
            let time_limit = left();
            let out = nb.translated(|| {
                branch_cut::solve(
                    &nb.matrix,
                    &nb.image(&found.ids),
                    &branch_cut::Options {
                        time_limit,
                        ..Default::default()
                    },
                )
            })?;
            let mapped = nb.map_back(&out.tour.order);
            let mut ids = found.ids;
            if let Some(better) = &mapped {
                if flat.cost(better) < flat.cost(&ids) {
                    ids.clone_from(better);
                }
            }
            let cost = flat.cost(&ids);
            let optimal = out.tour.optimal && mapped.is_some();
            let lower_bound = if optimal {
                cost
            } else {
                nb.bound(out.tour.lower_bound).min(cost)
            };
            (ids, lower_bound, optimal)
        }
        Solver::Heuristic | Solver::Auto => {
            let found = local_search(&flat, options, budget(SEARCH_SHARE_BEFORE_BOUND));
            progress::report(Event::Phase("lower bound"));
            let nb = NoonBean::new(&flat, found.cost);
            let proof = bound::dfj_bound(&nb.matrix, &nb.image(&found.ids), left())?;
            let lower_bound = nb
                .bound(proof.lower_bound.max(proof.assignment_bound))
                .min(found.cost);
            progress::report(Event::Bound(lower_bound));
            (found.ids, lower_bound, lower_bound >= found.cost)
        }
    };
    let visits: Vec<Visit> = ids.iter().map(|&id| flat.visit(id)).collect();
    let cost = tour_cost(m, stops, &visits);
    let optimal = proven || lower_bound >= cost;
    let lower_bound = if optimal { cost } else { lower_bound };
    let gap_pct = if optimal || cost == 0.0 {
        0.0
    } else {
        100.0 * (cost - lower_bound) / cost.abs()
    };
    Ok(StopTour {
        visits,
        cost,
        lower_bound,
        optimal,
        solver,
        gap_pct,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// The stops' ways numbered 1..=W in stop order (0 is the origin), with the cost of flying
/// each way after another: `link.cost(a, b)` is the arc of `m` from way `a`'s exit to way
/// `b`'s entry plus `b`'s inner cost (0 between two ways of one stop, never flown).
struct Flat {
    /// Ways of stop `s` are ids `first[s]..first[s + 1]`.
    first: Vec<usize>,
    /// The stop of each id (the origin's entry unused).
    stop_of: Vec<usize>,
    link: CostMatrix,
}

impl Flat {
    /// Numbers the ways, refusing a stop without ways, a node outside `m` or the origin, and
    /// a cost that is not finite on an arc a tour may fly.
    fn new(m: &CostMatrix, stops: &[Stop]) -> Result<Flat, PlanError> {
        let mut first = vec![1];
        let mut stop_of = vec![usize::MAX];
        let mut ways = vec![Way {
            entry: 0,
            exit: 0,
            inner: 0.0,
        }];
        for (s, stop) in stops.iter().enumerate() {
            if stop.ways.is_empty() {
                return Err(PlanError::Infeasible(format!(
                    "stop {s} has no way to fly it"
                )));
            }
            for (w, way) in stop.ways.iter().enumerate() {
                for node in [way.entry, way.exit] {
                    if node == 0 || node >= m.len() {
                        return Err(PlanError::Infeasible(format!(
                            "way {w} of stop {s} names node {node}, not a waypoint of the \
                             {}-node cost matrix",
                            m.len()
                        )));
                    }
                }
                if !way.inner.is_finite() {
                    return Err(PlanError::Infeasible(format!(
                        "the inner cost of way {w} of stop {s} is not finite"
                    )));
                }
                ways.push(*way);
                stop_of.push(s);
            }
            first.push(ways.len());
        }
        for (a, from) in ways.iter().enumerate() {
            for (b, to) in ways.iter().enumerate() {
                if a != b && (a == 0 || b == 0 || stop_of[a] != stop_of[b]) {
                    let (i, j) = (from.exit, to.entry);
                    if !m.cost(i, j).is_finite() {
                        return Err(PlanError::NonFiniteCost { from: i, to: j });
                    }
                }
            }
        }
        let link = CostMatrix::from_fn(ways.len(), |a, b| {
            if a != 0 && b != 0 && stop_of[a] == stop_of[b] {
                0.0
            } else {
                m.cost(ways[a].exit, ways[b].entry) + ways[b].inner
            }
        });
        Ok(Flat {
            first,
            stop_of,
            link,
        })
    }

    fn stops(&self) -> usize {
        self.first.len() - 1
    }

    fn ways(&self) -> usize {
        self.stop_of.len() - 1
    }

    /// The ids of the ways of stop `s`.
    fn ways_of(&self, s: usize) -> std::ops::Range<usize> {
        self.first[s]..self.first[s + 1]
    }

    fn visit(&self, id: usize) -> Visit {
        let stop = self.stop_of[id];
        Visit {
            stop,
            way: id - self.first[stop],
        }
    }

    /// The next way of the same stop, cyclically (the way itself for a one-way stop).
    fn next_way(&self, id: usize) -> usize {
        if id == 0 {
            return 0;
        }
        let ways = self.ways_of(self.stop_of[id]);
        if id + 1 < ways.end {
            id + 1
        } else {
            ways.start
        }
    }

    /// The cost of flying the ways `ids` (one per stop) in order from the origin and back.
    fn cost(&self, ids: &[usize]) -> f64 {
        self.link.tour_cost(ids)
    }

    /// Direction-aware Held-Karp states, `None` when they overflow.
    fn dp_states(&self) -> Option<usize> {
        1usize
            .checked_shl(u32::try_from(self.stops()).ok()?)
            .filter(|_| self.stops() < usize::BITS as usize - 1)?
            .checked_mul(self.ways())
            .filter(|_| self.ways() < usize::from(u16::MAX))
    }
}

/// The optimal ways and their cost by dynamic programming over (stops visited, last way
/// flown): `best(S, a)` is the cheapest path from the origin through the stops of `S` ending
/// with way `a` (of a stop in `S`); `best(S + t, b) = min_a best(S, a) + link(a, b)` for each way
/// `b` of a stop `t` outside `S`, and the tour closes with the cheapest `best(all, a) + link(a,
/// origin)`. Every tour flies each stop once in one way, so this is exact.
fn held_karp_ways(flat: &Flat) -> Result<(Vec<usize>, f64), PlanError> {
    let n = flat.stops();
    let w = flat.ways();
    if n == 0 {
        return Ok((Vec::new(), 0.0));
    }
    let states = flat.dp_states().filter(|&s| s <= MAX_DP_STATES);
    let Some(states) = states else {
        let two_way = (0..n).filter(|&s| flat.ways_of(s).len() > 1).count();
        let max = (1..n)
            .take_while(|&k| (1usize << k) * (k + two_way.min(k)) <= MAX_DP_STATES)
            .last()
            .unwrap_or(0);
        return Err(PlanError::TooManyForHeldKarp { n, max });
    };
    let masks = states / w;
    let full = masks - 1;
    let mut best = vec![f64::INFINITY; states];
    let mut parent = vec![u16::MAX; states];
    for b in 1..=w {
        best[(1 << flat.stop_of[b]) * w + b - 1] = flat.link.cost(0, b);
    }
    for mask in 1..masks {
        for a in 1..=w {
            if mask & (1 << flat.stop_of[a]) == 0 {
                continue;
            }
            let here = best[mask * w + a - 1];
            if !here.is_finite() {
                continue;
            }
            let mut rest = full & !mask;
            while rest != 0 {
                let t = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                let next = (mask | (1 << t)) * w;
                for b in flat.ways_of(t) {
                    let candidate = here + flat.link.cost(a, b);
                    if candidate < best[next + b - 1] {
                        best[next + b - 1] = candidate;
                        parent[next + b - 1] = (a - 1) as u16;
                    }
                }
            }
        }
    }
    let mut total = f64::INFINITY;
    let mut last = 0;
    for a in 1..=w {
        let candidate = best[full * w + a - 1] + flat.link.cost(a, 0);
        if candidate < total {
            total = candidate;
            last = a;
        }
    }
    let mut ids = Vec::with_capacity(n);
    let mut mask = full;
    let mut at = last;
    loop {
        ids.push(at);
        let before = parent[mask * w + at - 1];
        mask &= !(1 << flat.stop_of[at]);
        if mask == 0 {
            break;
        }
        at = usize::from(before) + 1;
    }
    ids.reverse();
    Ok((ids, total))
}

/// The Noon-Bean transformation of the stops' generalised ATSP into an ordinary ATSP (Noon and
/// Bean 1993, "An efficient transformation of the generalized traveling salesman problem",
/// INFOR 31(1)), on which branch-and-cut and the DFJ bound run unchanged.
///
/// Nodes: the origin (node 0) and every way (ids 1..=W of [`Flat`]); the ways of a stop form
/// its cluster, the origin a cluster of its own; `K` stops make `K + 1` clusters. The ways of
/// each cluster are joined in a cycle `a -> next(a)` of zero-cost arcs (two ways: both arcs
/// between them at zero). Every other arc `a -> b` is an *M-arc* costing
/// `M + link(next(a), b)`: each way's outgoing arcs are moved to its predecessor on the cycle.
///
/// **Tours that visit each cluster in one run are the stops' tours, at `(K + 1) M` more.** A
/// run entering a cluster at way `e` and leaving it once passes its other ways on the zero
/// cycle, `e -> next(e) -> ... -> prev(e)`, and leaves from `prev(e)` at `M + link(e, b)`:
/// exactly the arc of flying way `e` then way `b`, and it entered `e` at `M + link(a', e)`,
/// the arc of flying `a'` then `e`. So the tour flying way `e` of each stop in the runs' order
/// costs the ATSP tour minus `(K + 1) M`, and every stop tour arises so.
///
/// **Every other tour is dearer than the incumbent's image.** Each cluster is left by at least
/// one M-arc; a tour not in one run per cluster leaves some cluster twice (or uses an M-arc
/// inside a cluster of three or more ways), so has at least `K + 2` M-arcs, each costing at
/// least `M + g` where `g` is the least `link` priced on an M-arc, and zero-cost arcs
/// elsewhere: it costs at least `(K + 2)(M + g)` once `M + g >= 0`. The incumbent stop tour
/// of cost `U` maps to an ATSP tour of `(K + 1) M + U`. With `M > U - (K + 2) g` (and `M >=
/// -g`), every ATSP tour no dearer than the incumbent's image, the optimum among them, is a
/// stop tour. Branch-and-cut, started from that image, only ever returns such a tour.
///
/// **Bounds map back whatever `M`.** The ATSP optimum is at most the image of the optimal stop
/// tour, `(K + 1) M + OPT`, so any lower bound `L` of the ATSP gives `L - (K + 1) M <= OPT`.
///
/// **Conditioning.** `M` is the least the argument allows, rounded up to a whole number (so
/// integer costs stay integer and branch-and-cut may round its bounds): about the incumbent's
/// cost less the cheapest arcs, not an arbitrary "big M". The arcs then differ from one another
/// by the stop tour's own costs on a common offset of one tour's size: a few decimal digits of
/// the LP's sixteen, well within its tolerances (branch-and-cut calls a tour optimal within
/// 1e-7 of the ATSP's value, so within about `1e-7 (K + 1) M / OPT` of the stop tour's; the
/// study's and the bench's instances prove at a few 1e-6 relative at worst).
struct NoonBean {
    matrix: CostMatrix,
    /// `M`.
    big_m: f64,
    /// `K + 1`.
    clusters: usize,
    /// The stop of each node (origin: `usize::MAX`).
    stop_of: Vec<usize>,
    /// The next node on each node's cluster cycle.
    next: Vec<usize>,
}

impl NoonBean {
    /// The transformation of `flat`, its `M` chosen against an incumbent costing `upper`.
    fn new(flat: &Flat, upper: f64) -> NoonBean {
        let n = flat.ways() + 1;
        let on_cycle = |a: usize, b: usize| a != 0 && b == flat.next_way(a) && a != b;
        let mut least = f64::INFINITY;
        for a in 0..n {
            for b in 0..n {
                if a != b && !on_cycle(a, b) {
                    least = least.min(flat.link.cost(flat.next_way(a), b));
                }
            }
        }
        if !least.is_finite() {
            least = 0.0;
        }
        let clusters = flat.stops() + 1;
        let bound = (upper - (clusters + 1) as f64 * least).max(-least);
        let big_m = (bound + 1.0 + 1e-9 * bound.abs()).ceil().max(1.0);
        let matrix = CostMatrix::from_fn(n, |a, b| {
            if on_cycle(a, b) {
                0.0
            } else {
                big_m + flat.link.cost(flat.next_way(a), b)
            }
        });
        NoonBean {
            matrix,
            big_m,
            clusters,
            stop_of: flat.stop_of.clone(),
            next: (0..n).map(|a| flat.next_way(a)).collect(),
        }
    }

    /// The ATSP tour of the stop tour flying ways `ids`: each way followed by the rest of its
    /// cluster's cycle.
    fn image(&self, ids: &[usize]) -> Vec<usize> {
        let mut order = Vec::with_capacity(self.matrix.len().saturating_sub(1));
        for &entry in ids {
            let mut at = entry;
            loop {
                order.push(at);
                at = self.next[at];
                if at == entry {
                    break;
                }
            }
        }
        order
    }

    /// The ways flown by an ATSP tour that visits each cluster in one run along its cycle (the
    /// entry of each run), `None` for any other tour.
    fn map_back(&self, order: &[usize]) -> Option<Vec<usize>> {
        let mut ids = Vec::with_capacity(self.clusters - 1);
        let mut i = 0;
        while i < order.len() {
            let entry = order[i];
            let mut at = entry;
            i += 1;
            loop {
                let next = self.next[at];
                if next == entry {
                    break;
                }
                if order.get(i) != Some(&next) {
                    return None;
                }
                at = next;
                i += 1;
            }
            ids.push(entry);
        }
        let mut seen = vec![false; self.clusters - 1];
        ids.iter()
            .all(|&id| !std::mem::replace(&mut seen[self.stop_of[id]], true))
            .then_some(ids)
    }

    /// A lower bound of the stop tours from one of the ATSP.
    fn bound(&self, atsp_bound: f64) -> f64 {
        atsp_bound - self.clusters as f64 * self.big_m
    }

    /// Runs `work` with its progress events told in the stop tour's terms (less `(K + 1) M`).
    fn translated<R>(&self, work: impl FnOnce() -> R) -> R {
        let offset = self.clusters as f64 * self.big_m;
        progress::translated(
            move |e| match e {
                Event::Incumbent(c) => Some(Event::Incumbent(c - offset)),
                Event::Bound(b) => Some(Event::Bound(b - offset)),
                other => Some(other),
            },
            work,
        )
    }
}

/// The local search's best tour (one way id per stop) and its cost.
struct Found {
    ids: Vec<usize>,
    cost: f64,
}

/// Default kick budget of the local search for `n` stops.
pub fn default_kicks(n: usize) -> u64 {
    (n as u64).saturating_mul(50).max(1000)
}

/// Longest stretch of stops a 2-opt move reverses.
const REVERSAL_MAX: usize = 40;
/// Longest stretch an Or-opt move carries.
const SEGMENT_MAX: usize = 3;

/// Iterated local search over the order and the ways, within `time_limit` and
/// `options.kicks` (else [`default_kicks`]), deterministic for `options.seed` when the kicks
/// end it: from the better of the nearest-neighbour tour and the stops in the given order,
/// descents by Or-opt (one to three stops moved elsewhere, a single stop in whichever way is
/// cheapest there), 2-opt (a stretch flown backwards, its stops' ways kept or each flipped to
/// the next way: a block reversed with the stretch, the costs summed afresh so asymmetry is
/// priced exactly) and the optimal ways for the order (a shortest path through the stops'
/// ways, the "cluster optimisation" of Fischetti, Salazar-Gonzalez and Toth 1997), each until
/// none improves; then double-bridge kicks (segments `A B C D -> A C B D`), a kicked tour
/// kept when no dearer. Stops early at the time limit or when the thread's cancel token asks.
fn local_search(flat: &Flat, options: &Options, time_limit: Duration) -> Found {
    progress::report(Event::Phase("heuristic"));
    let started = Instant::now();
    let n = flat.stops();
    let out_of_time = || started.elapsed() >= time_limit || super::cancel::requested();
    let mean = {
        let w = flat.ways() + 1;
        let total: f64 = (0..w)
            .flat_map(|a| (0..w).map(move |b| (a, b)))
            .map(|(a, b)| flat.link.cost(a, b).abs())
            .sum();
        total / (w * w) as f64
    };
    let eps = 1e-9 * mean.max(f64::MIN_POSITIVE);
    let listed: Vec<usize> = (0..n).map(|s| flat.first[s]).collect();
    let mut tour = nearest_neighbour(flat);
    if flat.cost(&listed) < flat.cost(&tour) {
        tour = listed;
    }
    descend(flat, &mut tour, eps);
    let mut cost = flat.cost(&tour);
    let mut best = Found {
        ids: tour.clone(),
        cost,
    };
    progress::report(Event::Incumbent(cost));
    let budget = options.kicks.unwrap_or_else(|| default_kicks(n));
    let mut rng = Rng::new(options.seed);
    let mut kicks = 0;
    while n >= 4 && kicks < budget {
        if kicks.is_multiple_of(16) {
            if out_of_time() {
                break;
            }
            progress::report(Event::Kicks {
                done: kicks,
                budget,
            });
        }
        kicks += 1;
        let before = tour.clone();
        double_bridge(&mut tour, &mut rng);
        descend(flat, &mut tour, eps);
        let kicked = flat.cost(&tour);
        if kicked <= cost + eps {
            cost = kicked;
            if cost < best.cost - eps {
                best = Found {
                    ids: tour.clone(),
                    cost,
                };
                progress::report(Event::Incumbent(cost));
            }
        } else {
            tour = before;
        }
    }
    best.cost = flat.cost(&best.ids);
    best
}

/// From the origin, always the cheapest way of a stop not yet visited (ties to the lower id).
fn nearest_neighbour(flat: &Flat) -> Vec<usize> {
    let n = flat.stops();
    let mut visited = vec![false; n];
    let mut at = 0;
    let mut tour = Vec::with_capacity(n);
    for _ in 0..n {
        let mut next = None;
        let mut cheapest = f64::INFINITY;
        for b in 1..=flat.ways() {
            if !visited[flat.stop_of[b]] && (next.is_none() || flat.link.cost(at, b) < cheapest) {
                cheapest = flat.link.cost(at, b);
                next = Some(b);
            }
        }
        let Some(b) = next else { break };
        visited[flat.stop_of[b]] = true;
        tour.push(b);
        at = b;
    }
    tour
}

/// Swaps two consecutive random stretches of the tour (`A B C D -> A C B D`).
fn double_bridge(tour: &mut [usize], rng: &mut Rng) {
    let n = tour.len();
    let mut cuts = [
        1 + rng.below(n - 1),
        1 + rng.below(n - 1),
        1 + rng.below(n - 1),
    ];
    cuts.sort_unstable();
    let [a, b, c] = cuts;
    if a < b && b < c {
        tour[a..c].rotate_left(b - a);
    } else {
        // Degenerate cuts: swap two random stops instead.
        let (i, j) = (rng.below(n), rng.below(n));
        tour.swap(i, j);
    }
}

/// Local descent until no move improves by more than `eps`.
fn descend(flat: &Flat, tour: &mut Vec<usize>, eps: f64) {
    loop {
        let mut improved = best_ways(flat, tour, eps);
        improved |= or_opt(flat, tour, eps);
        improved |= two_opt(flat, tour, eps);
        if !improved {
            break;
        }
    }
}

/// The cheapest ways for the tour's order of stops (a shortest path through the layers of
/// ways); true when it improves by more than `eps`.
fn best_ways(flat: &Flat, tour: &mut [usize], eps: f64) -> bool {
    let n = tour.len();
    if n == 0 {
        return false;
    }
    let w = flat.ways() + 1;
    let mut dist = vec![f64::INFINITY; w];
    let mut from = vec![vec![0usize; 0]; n];
    let mut layer: Vec<usize> = flat.ways_of(flat.stop_of[tour[0]]).collect();
    for &b in &layer {
        dist[b] = flat.link.cost(0, b);
    }
    for (k, &id) in tour.iter().enumerate().skip(1) {
        let next: Vec<usize> = flat.ways_of(flat.stop_of[id]).collect();
        let mut choice = Vec::with_capacity(next.len());
        let mut next_dist = Vec::with_capacity(next.len());
        for &b in &next {
            let (arg, d) = layer
                .iter()
                .map(|&a| (a, dist[a] + flat.link.cost(a, b)))
                .fold(
                    (layer[0], f64::INFINITY),
                    |acc, x| if x.1 < acc.1 { x } else { acc },
                );
            choice.push(arg);
            next_dist.push(d);
        }
        for (&b, d) in next.iter().zip(next_dist) {
            dist[b] = d;
        }
        from[k] = choice;
        layer = next;
    }
    let (mut at, total) = layer
        .iter()
        .map(|&a| (a, dist[a] + flat.link.cost(a, 0)))
        .fold(
            (layer[0], f64::INFINITY),
            |acc, x| if x.1 < acc.1 { x } else { acc },
        );
    if total >= flat.cost(tour) - eps {
        return false;
    }
    for k in (0..n).rev() {
        tour[k] = at;
        if k > 0 {
            let first = flat.first[flat.stop_of[at]];
            at = from[k][at - first];
        }
    }
    true
}

/// One pass of Or-opt (first improvement): a stretch of one to [`SEGMENT_MAX`] stops moved
/// between two others, its ways kept (a single stop in its cheapest way there).
fn or_opt(flat: &Flat, tour: &mut Vec<usize>, eps: f64) -> bool {
    let n = tour.len();
    let at = |t: &[usize], k: usize| if k == 0 || k > n { 0 } else { t[k - 1] };
    let link = |a: usize, b: usize| flat.link.cost(a, b);
    let mut improved = false;
    for len in 1..=SEGMENT_MAX.min(n.saturating_sub(1)) {
        let mut i = 1;
        while i + len <= n + 1 {
            // The stretch is positions i..i+len (1-based, 0 and n+1 the origin).
            let (prev, head, tail, next) = (
                at(tour, i - 1),
                at(tour, i),
                at(tour, i + len - 1),
                at(tour, i + len),
            );
            let removal = link(prev, head) + link(tail, next) - link(prev, next);
            let ways: Vec<usize> = if len == 1 {
                flat.ways_of(flat.stop_of[head]).collect()
            } else {
                vec![head]
            };
            let mut moved = None;
            'search: for j in 0..=n {
                // Between positions j and j + 1, both outside the stretch.
                if j + 1 >= i && j < i + len {
                    continue;
                }
                let (p, q) = (at(tour, j), at(tour, j + 1));
                for &h in &ways {
                    let t = if len == 1 { h } else { tail };
                    let gain = removal - (link(p, h) + link(t, q) - link(p, q));
                    if gain > eps {
                        moved = Some((j, h));
                        break 'search;
                    }
                }
            }
            if let Some((j, h)) = moved {
                let mut segment: Vec<usize> = tour.drain(i - 1..i - 1 + len).collect();
                segment[0] = if len == 1 { h } else { segment[0] };
                let to = if j < i { j } else { j - len };
                tour.splice(to..to, segment);
                improved = true;
            } else {
                i += 1;
            }
        }
    }
    improved
}

/// One pass of 2-opt (first improvement): a stretch of at most [`REVERSAL_MAX`] stops flown
/// backwards, its ways kept or each turned to the next way of its stop, priced by summing the
/// reversed stretch's arcs afresh.
fn two_opt(flat: &Flat, tour: &mut [usize], eps: f64) -> bool {
    let n = tour.len();
    let at = |t: &[usize], k: usize| if k == 0 || k > n { 0 } else { t[k - 1] };
    let link = |a: usize, b: usize| flat.link.cost(a, b);
    let turn = |a: usize| flat.next_way(a);
    let mut improved = false;
    for i in 1..n {
        let prev = at(tour, i - 1);
        let (mut forward, mut kept, mut turned) = (0.0, 0.0, 0.0);
        for j in i + 1..=n.min(i + REVERSAL_MAX - 1) {
            let (a, b) = (at(tour, j - 1), at(tour, j));
            forward += link(a, b);
            kept += link(b, a);
            turned += link(turn(b), turn(a));
            let next = at(tour, j + 1);
            let old = link(prev, at(tour, i)) + forward + link(b, next);
            let plain = link(prev, b) + kept + link(at(tour, i), next);
            let flipped = link(prev, turn(b)) + turned + link(turn(at(tour, i)), next);
            if plain < old - eps || flipped < old - eps {
                let flip = flipped < plain;
                tour[i - 1..j].reverse();
                if flip {
                    for id in &mut tour[i - 1..j] {
                        *id = turn(*id);
                    }
                }
                improved = true;
                break;
            }
        }
    }
    improved
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use crate::tour::cancel;
    use proptest::prelude::*;
    use std::cell::RefCell;
    use std::rc::Rc;

    /// The optimal cost by enumerating every order of the stops and every way of each (the
    /// test oracle; at most nine stops).
    fn brute_force(m: &CostMatrix, stops: &[Stop]) -> f64 {
        fn go(
            m: &CostMatrix,
            stops: &[Stop],
            used: &mut Vec<bool>,
            at: usize,
            so_far: f64,
            best: &mut f64,
        ) {
            if used.iter().all(|&u| u) {
                *best = best.min(so_far + m.cost(at, 0));
                return;
            }
            for s in 0..stops.len() {
                if used[s] {
                    continue;
                }
                used[s] = true;
                for way in &stops[s].ways {
                    let cost = so_far + m.cost(at, way.entry) + way.inner;
                    go(m, stops, used, way.exit, cost, best);
                }
                used[s] = false;
            }
        }
        assert!(stops.len() <= 9);
        let mut best = f64::INFINITY;
        go(m, stops, &mut vec![false; stops.len()], 0, 0.0, &mut best);
        best
    }

    /// A random instance: `points` points and `blocks` blocks of 2 to 4 waypoints in 3D,
    /// climbs dearer than descents, each block's inner cost its legs in the flown direction;
    /// `one_way` blocks (the first ones) keep only their forward way.
    fn instance(
        points: usize,
        blocks: usize,
        one_way: usize,
        seed: u64,
    ) -> (CostMatrix, Vec<Stop>) {
        let mut rng = Rng::new(seed);
        let mut xyz = vec![[0.0; 3]];
        let mut stops = Vec::new();
        for _ in 0..points {
            xyz.push([
                rng.uniform(-50.0, 50.0),
                rng.uniform(-50.0, 50.0),
                rng.uniform(0.0, 40.0),
            ]);
            stops.push(xyz.len() - 1);
        }
        let mut runs = Vec::new();
        for _ in 0..blocks {
            let len = 2 + rng.below(3);
            let start = xyz.len();
            for _ in 0..len {
                xyz.push([
                    rng.uniform(-50.0, 50.0),
                    rng.uniform(-50.0, 50.0),
                    rng.uniform(0.0, 40.0),
                ]);
            }
            runs.push(start..start + len);
        }
        let m = CostMatrix::from_fn(xyz.len(), |i, j| {
            let (a, b) = (xyz[i], xyz[j]);
            let dz = b[2] - a[2];
            (b[0] - a[0]).hypot(b[1] - a[1]) + 8.0 * dz.max(0.0) + 0.5 * (-dz).max(0.0)
        });
        let inner = |nodes: &mut dyn Iterator<Item = usize>| {
            let nodes: Vec<usize> = nodes.collect();
            nodes.windows(2).map(|w| m.cost(w[0], w[1])).sum::<f64>()
        };
        let mut all: Vec<Stop> = stops.into_iter().map(Stop::point).collect();
        for (k, run) in runs.into_iter().enumerate() {
            let forward = Way {
                entry: run.start,
                exit: run.end - 1,
                inner: inner(&mut run.clone()),
            };
            let reversed = Way {
                entry: run.end - 1,
                exit: run.start,
                inner: inner(&mut run.clone().rev()),
            };
            let ways = if k < one_way {
                vec![forward]
            } else {
                vec![forward, reversed]
            };
            all.push(Stop { ways });
        }
        (m, all)
    }

    fn with(solver: Solver) -> Options {
        Options {
            solver,
            ..Default::default()
        }
    }

    /// The answer is a tour of every stop once in one of its ways, priced as `tour_cost`
    /// prices it, its bound below it and `optimal` only when they meet.
    fn check_answer(m: &CostMatrix, stops: &[Stop], out: &StopTour) {
        let mut seen = vec![false; stops.len()];
        for v in &out.visits {
            assert!(v.way < stops[v.stop].ways.len(), "{v:?}");
            assert!(!std::mem::replace(&mut seen[v.stop], true), "{v:?} twice");
        }
        assert!(seen.iter().all(|&s| s), "{:?}", out.visits);
        assert_eq!(out.cost, tour_cost(m, stops, &out.visits));
        assert!(out.lower_bound <= out.cost, "{out:?}");
        assert_eq!(out.optimal, out.lower_bound == out.cost, "{out:?}");
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * a.abs().max(1.0)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn every_solver_equals_the_brute_force_over_orders_and_ways(
            points in 0usize..=6,
            blocks in 0usize..=3,
            one_way in 0usize..=3,
            seed in 0u64..1_000_000,
        ) {
            let (m, stops) = instance(points, blocks, one_way.min(blocks), seed);
            prop_assume!(!stops.is_empty());
            let oracle = brute_force(&m, &stops);
            for solver in [Solver::Auto, Solver::HeldKarp, Solver::BranchCut] {
                let out = solve(&m, &stops, &with(solver)).unwrap();
                check_answer(&m, &stops, &out);
                prop_assert!(out.optimal, "{solver}: {out:?}");
                prop_assert!(close(out.cost, oracle), "{solver}: {} vs {oracle}", out.cost);
            }
            let out = solve(&m, &stops, &with(Solver::Heuristic)).unwrap();
            check_answer(&m, &stops, &out);
            prop_assert!(out.lower_bound <= oracle + 1e-9 * oracle && out.cost >= oracle - 1e-9 * oracle);
        }
    }

    #[test]
    fn ten_points_and_three_blocks_are_solved_exactly_as_enumerating_the_ways() {
        for seed in 0..12 {
            let (m, stops) = instance(10, 3, (seed % 3) as usize, seed);
            let reference = solve_by_ways(&m, &stops).unwrap();
            for solver in [Solver::Auto, Solver::BranchCut] {
                let out = solve(&m, &stops, &with(solver)).unwrap();
                check_answer(&m, &stops, &out);
                assert!(out.optimal, "seed {seed} {solver}: {out:?}");
                assert!(
                    close(out.cost, reference.cost),
                    "seed {seed} {solver}: {} vs {}",
                    out.cost,
                    reference.cost
                );
            }
        }
    }

    #[test]
    fn a_block_whose_reversed_way_is_cheaper_is_flown_reversed_and_a_one_way_block_never() {
        // Origin at 0; block A is nodes 1..=2, block B nodes 3..=4; point 5. Arcs cost 10,
        // except 0 -> 2 (A's reversed entry) and 1 -> 5 (its reversed exit to the point), and
        // 5 -> 4 (B's reversed entry), 3 -> 0 (its reversed exit) costing 1. B is one-way.
        let cheap = [(0, 2), (1, 5), (5, 4), (3, 0)];
        let m = CostMatrix::from_fn(6, |i, j| if cheap.contains(&(i, j)) { 1.0 } else { 10.0 });
        let block = |a: usize, b: usize, reversible: bool| Stop {
            ways: std::iter::once(Way {
                entry: a,
                exit: b,
                inner: 3.0,
            })
            .chain(reversible.then_some(Way {
                entry: b,
                exit: a,
                inner: 3.0,
            }))
            .collect(),
        };
        let two_way = [block(1, 2, true), block(3, 4, true), Stop::point(5)];
        let out = solve(&m, &two_way, &Options::default()).unwrap();
        assert_eq!(
            out.visits,
            [
                Visit { stop: 0, way: 1 },
                Visit { stop: 2, way: 0 },
                Visit { stop: 1, way: 1 }
            ]
        );
        assert_eq!(out.cost, 1.0 + 3.0 + 1.0 + 1.0 + 3.0 + 1.0);
        let one_way = [block(1, 2, true), block(3, 4, false), Stop::point(5)];
        for solver in [Solver::Auto, Solver::BranchCut, Solver::Heuristic] {
            let out = solve(&m, &one_way, &with(solver)).unwrap();
            check_answer(&m, &one_way, &out);
            assert!(out.visits.contains(&Visit { stop: 0, way: 1 }), "{out:?}");
            assert!(out.visits.contains(&Visit { stop: 1, way: 0 }), "{out:?}");
            assert_eq!(out.cost, brute_force(&m, &one_way));
        }
    }

    #[test]
    fn a_block_whose_reversed_lines_cost_less_is_flown_reversed() {
        // Every connecting arc costs 5; the block's lines cost 50 forward, 20 reversed.
        let m = CostMatrix::from_fn(4, |_, _| 5.0);
        let stops = [
            Stop::point(3),
            Stop {
                ways: vec![
                    Way {
                        entry: 1,
                        exit: 2,
                        inner: 50.0,
                    },
                    Way {
                        entry: 2,
                        exit: 1,
                        inner: 20.0,
                    },
                ],
            },
        ];
        for solver in [Solver::Auto, Solver::BranchCut, Solver::Heuristic] {
            let out = solve(&m, &stops, &with(solver)).unwrap();
            assert!(out.visits.contains(&Visit { stop: 1, way: 1 }), "{solver}");
            assert_eq!(out.cost, 35.0, "{solver}");
        }
    }

    #[test]
    fn the_heuristic_is_never_below_the_optimum_its_bound_never_above_and_it_repeats() {
        for seed in 0..6 {
            let (m, stops) = instance(9, 3, 1, 100 + seed);
            let exact = solve(&m, &stops, &with(Solver::HeldKarp)).unwrap();
            let options = Options {
                solver: Solver::Heuristic,
                kicks: Some(200),
                seed,
                ..Default::default()
            };
            let out = solve(&m, &stops, &options).unwrap();
            check_answer(&m, &stops, &out);
            assert_eq!(out.solver, Solver::Heuristic);
            assert!(out.cost >= exact.cost - 1e-9 * exact.cost, "seed {seed}");
            assert!(
                out.lower_bound <= exact.cost + 1e-9 * exact.cost,
                "seed {seed}"
            );
            assert_eq!(solve(&m, &stops, &options).unwrap().visits, out.visits);
        }
    }

    #[test]
    fn forty_points_and_eight_blocks_get_a_tour_with_a_proven_bound() {
        let (m, stops) = instance(40, 8, 2, 7);
        let options = Options {
            time_limit: Duration::from_secs(20),
            ..Default::default()
        };
        let out = solve(&m, &stops, &options).unwrap();
        check_answer(&m, &stops, &out);
        assert_eq!(out.solver, Solver::BranchCut);
        let heuristic = solve(&m, &stops, &with(Solver::Heuristic)).unwrap();
        check_answer(&m, &stops, &heuristic);
        assert!(heuristic.lower_bound <= out.cost * (1.0 + 1e-9));
        assert!(out.lower_bound <= heuristic.cost * (1.0 + 1e-9));
    }

    #[test]
    fn the_noon_bean_image_maps_back_and_costs_the_tour_plus_m_per_cluster() {
        let (m, stops) = instance(4, 3, 1, 3);
        let flat = Flat::new(&m, &stops).unwrap();
        let ids = nearest_neighbour(&flat);
        let nb = NoonBean::new(&flat, flat.cost(&ids));
        let image = nb.image(&ids);
        assert_eq!(image.len(), flat.ways());
        assert_eq!(nb.map_back(&image), Some(ids.clone()));
        let expected = flat.cost(&ids) + nb.clusters as f64 * nb.big_m;
        assert!(close(nb.matrix.tour_cost(&image), expected));
        // A tour splitting a block's two ways maps back to nothing.
        let two_way = (0..stops.len())
            .find(|&s| stops[s].ways.len() == 2)
            .unwrap();
        let split: Vec<usize> = image
            .iter()
            .copied()
            .filter(|&a| a != flat.first[two_way] + 1)
            .chain([flat.first[two_way] + 1])
            .collect();
        if split != image {
            assert_eq!(nb.map_back(&split), None);
            assert!(nb.matrix.tour_cost(&split) > nb.matrix.tour_cost(&image));
        }
    }

    #[test]
    fn held_karp_refuses_too_many_stops_and_bad_stops_are_named() {
        let (m, stops) = instance(30, 0, 0, 1);
        assert!(matches!(
            solve(&m, &stops, &with(Solver::HeldKarp)),
            Err(PlanError::TooManyForHeldKarp { n: 30, max: 20 })
        ));
        let empty = [Stop { ways: vec![] }];
        assert_eq!(
            solve(&m, &empty, &Options::default())
                .unwrap_err()
                .to_string(),
            "no tour exists: stop 0 has no way to fly it"
        );
        let outside = [Stop::point(99)];
        assert_eq!(
            solve(&m, &outside, &Options::default()).unwrap_err().to_string(),
            "no tour exists: way 0 of stop 0 names node 99, not a waypoint of the 31-node cost matrix"
        );
        let bad = CostMatrix::from_fn(3, |i, j| if (i, j) == (1, 2) { f64::NAN } else { 1.0 });
        assert_eq!(
            solve(&bad, &[Stop::point(1), Stop::point(2)], &Options::default()),
            Err(PlanError::NonFiniteCost { from: 1, to: 2 })
        );
        let none = solve(&m, &[], &Options::default()).unwrap();
        assert_eq!((none.visits.len(), none.cost, none.optimal), (0, 0.0, true));
    }

    #[test]
    fn a_cancelled_solve_stops_with_the_cancelled_error_as_the_other_solvers_do() {
        let (m, stops) = instance(40, 8, 0, 11);
        let token = cancel::Cancel::new();
        token.cancel();
        for solver in [Solver::Auto, Solver::BranchCut, Solver::Heuristic] {
            let out = cancel::within(&token, || solve(&m, &stops, &with(solver)));
            assert_eq!(out, Err(PlanError::Cancelled), "{solver}");
        }
    }

    #[test]
    fn progress_is_told_in_the_stop_tours_terms() {
        let (m, stops) = instance(12, 4, 0, 5);
        let heard = Rc::new(RefCell::new(Vec::new()));
        let h = Rc::clone(&heard);
        let out = progress::listen(
            move |e| h.borrow_mut().push(e),
            || solve(&m, &stops, &with(Solver::BranchCut)),
        )
        .unwrap();
        let heard = heard.borrow();
        assert!(heard.contains(&Event::Phase("heuristic")), "{heard:?}");
        assert!(heard.contains(&Event::Phase("branch-and-cut")), "{heard:?}");
        for e in heard.iter() {
            if let Event::Incumbent(c) = e {
                assert!(
                    *c >= out.cost - 1e-9 * out.cost && *c < 2.0 * out.cost,
                    "{e:?}"
                );
            }
        }
    }
}
