//! Direction-preserving iterated local search for large asymmetric tours (hundreds to
//! thousands of waypoints), where the exact solvers give up.
//!
//! The tour is a cycle through every node, the origin included, held as an array with
//! positions; nearly every move keeps the direction of travel, so it is evaluated in O(1)
//! whatever the asymmetry of the costs.
//!
//! - **Start**: the assignment relaxation (Hungarian method with shortest augmenting paths,
//!   Kuhn 1955; Jonker & Volgenant 1987) patched into one cycle by Karp's patching (Karp 1979;
//!   Glover, Gutin, Yeo & Zverovich 2001 found it among the best ATSP constructions), or nearest
//!   neighbour when the matrix is too large for the O(n^3) assignment or has non-finite costs.
//! - **Candidate lists**: the K cheapest out-arcs and in-arcs of every node, ranked by the
//!   reduced cost of the assignment dual when there is one (Helsgaun 2000 ranks by alpha-nearness
//!   for the same reason: raw cost is a poor guide on asymmetric instances), else by cost.
//! - **Moves**: Or-opt (Or 1976: move a segment of 1 to 3 nodes elsewhere, without reversing it)
//!   and the reversal-free 3-opt segment exchange ("or-3opt", move type a'; Johnson & McGeoch
//!   2002, "Experimental analysis of heuristics for the ATSP"), searched sequentially from each
//!   node with the positive-gain criterion of Lin & Kernighan (1973) over out-arcs and over
//!   in-arcs, first improvement, with don't-look bits kept as a FIFO queue of active nodes
//!   (Bentley 1992). One move does reverse: 2-opt (Croes 1958) on paths of at most
//!   `REVERSAL_MAX` nodes, whose cost both ways is summed while walking, O(1) per candidate;
//!   it matters on drone instances, where a reversed path swaps climbs for descents.
//! - **Iterated local search** (Lourenco, Martin & Stuetzle 2003; Martin, Otto & Felten 1991):
//!   a segment-reversal-free double-bridge kick `A B C D -> A D C B` on short segments (a
//!   "local" double bridge, as in Applegate, Cook & Rohe 2003 for chained Lin-Kernighan), local
//!   search from the eight touched nodes only, late acceptance (Burke & Bykov 2017: keep the
//!   new tour if it is no worse than the current one or than the current one a fixed number of
//!   kicks ago), and undo of a rejected kick from a log of the segment swaps and reversals
//!   it made. The best tour seen is returned.
//!
//! Costs are compared with a tolerance of 1e-9 of the mean arc cost of the start, so float noise
//! never counts as an improvement and the search cannot cycle.

use std::collections::VecDeque;
use std::time::Instant;

use super::progress::{self, Event};

use super::{is_tour_order, CostMatrix};
use crate::rng::Rng;

/// Settings of [`solve`].
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Seed of the kicks; the same seed and kick budget always give the same tour.
    pub seed: u64,
    /// Safety stop in wall-clock seconds. Reaching it makes the result depend on the machine's
    /// speed, so set `max_kicks` for reproducible runs and keep this as a guard.
    pub time_limit_s: f64,
    /// Number of kicks of the iterated local search; `None` is [`default_kicks`] of the size.
    pub max_kicks: Option<u64>,
    /// Length of the candidate lists (out-arcs and in-arcs per node).
    pub candidates: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            seed: 1,
            time_limit_s: 10.0,
            max_kicks: None,
            candidates: 10,
        }
    }
}

/// Why [`solve`] stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Stop {
    /// The kick budget was spent (the reproducible outcome).
    Kicks,
    /// The wall-clock safety limit was reached first.
    TimeLimit,
}

/// The best tour found and how the search went.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// Every node `1..n` once, in visiting order (origin excluded at both ends).
    pub order: Vec<usize>,
    /// `m.tour_cost(&order)`, recomputed exactly.
    pub cost: f64,
    /// Kicks performed.
    pub kicks: u64,
    /// Wall-clock time spent.
    pub seconds: f64,
    /// Why the search stopped.
    pub stop: Stop,
}

/// Default kick budget for `n` nodes (origin included).
pub fn default_kicks(n: usize) -> u64 {
    (n as u64).saturating_mul(100).max(10_000)
}

/// Largest matrix for which the O(n^3) assignment start is used (measured on drone instances:
/// 0.2 s at 1000 nodes, 1.6 s at 2000, 5 s at 3000; without it, nearest neighbour and raw-cost
/// candidates: still within 0.3 % on rbg323..443, but 0.4 % worse on the 1000-node drone).
const ASSIGNMENT_MAX_NODES: usize = 2000;

/// Length of the late-acceptance history, in kicks (measured: 100 to 300 beat plain
/// better-or-equal acceptance on ftv33..ftv170 and on 200- and 1000-node drone instances).
const LATE_ACCEPTANCE: usize = 300;

/// Longest path reversed by a 2-opt move.
const REVERSAL_MAX: usize = 30;

/// Longest segment of a double-bridge kick.
const KICK_SEGMENT_MAX: usize = 50;

/// Minimum-cost tour by iterated local search (see the module documentation). `initial`, when
/// it is a permutation of `1..n`, replaces the constructed start; otherwise it is ignored.
/// Never panics: `n` of 0 to 3 gives the trivial (or, for 3, the cheaper) tour, and non-finite
/// costs only weaken the search.
///
/// Deterministic: the same `opts.seed` and kick budget give the same tour on every run and
/// machine. `opts.time_limit_s` is only a safety stop; when it ends the search first
/// ([`Stop::TimeLimit`]), the tour depends on the machine's speed.
pub fn solve(m: &CostMatrix, initial: Option<&[usize]>, opts: &Options) -> Outcome {
    let started = Instant::now();
    let n = m.len();
    let trivial = |order: Vec<usize>| {
        let cost = if n == 0 { 0.0 } else { m.tour_cost(&order) };
        Outcome {
            order,
            cost,
            kicks: 0,
            seconds: started.elapsed().as_secs_f64(),
            stop: Stop::Kicks,
        }
    };
    match n {
        0 | 1 => return trivial(Vec::new()),
        2 => return trivial(vec![1]),
        3 => {
            let forward = m.tour_cost(&[1, 2]);
            let backward = m.tour_cost(&[2, 1]);
            return trivial(if backward < forward {
                vec![2, 1]
            } else {
                vec![1, 2]
            });
        }
        _ => {}
    }

    let finite = m.non_finite_arc().is_none();
    let assignment = if finite && n <= ASSIGNMENT_MAX_NODES {
        super::assignment::solve(m).ok()
    } else {
        None
    };
    let start: Vec<usize> = match initial.filter(|o| is_tour_order(n, o)) {
        Some(order) => std::iter::once(0).chain(order.iter().copied()).collect(),
        None => match &assignment {
            Some(ap) => patch(m, &ap.successor),
            None => nearest_neighbour(m),
        },
    };
    let k = opts.candidates.clamp(2, n - 1);
    let (out, inn) = match &assignment {
        Some(ap) => candidates(n, k, |i, j| m.cost(i, j) - ap.u[i] - ap.v[j]),
        _ => candidates(n, k, |i, j| m.cost(i, j)),
    };

    let mut s = Search::new(m, k, out, inn, start);
    let mut stop = Stop::Kicks;
    let deadline_s = opts.time_limit_s;
    let out_of_time = |started: &Instant| {
        started.elapsed().as_secs_f64() >= deadline_s || super::cancel::requested()
    };

    for v in 0..n {
        s.push(s.tour[v]);
    }
    if !s.local_search(&started, deadline_s) {
        stop = Stop::TimeLimit;
    }

    let mut best_cost = m_tour_cost(m, &s.tour);
    s.cost = best_cost;
    let mut best_tour = s.tour.clone();
    progress::report(Event::Incumbent(best_cost));
    let budget = opts.max_kicks.unwrap_or_else(|| default_kicks(n));
    let mut rng = Rng::new(opts.seed);
    let mut kicks = 0u64;
    // Late acceptance (Burke & Bykov 2017): a kicked tour is kept if it is no worse than the
    // current one or than the current one of `LATE_ACCEPTANCE` kicks ago.
    let mut history = vec![s.cost; LATE_ACCEPTANCE];
    while stop == Stop::Kicks && kicks < budget {
        if kicks.is_multiple_of(16) {
            if out_of_time(&started) {
                stop = Stop::TimeLimit;
                break;
            }
            progress::report(Event::Kicks {
                done: kicks,
                budget,
            });
        }
        let slot = (kicks % history.len() as u64) as usize;
        kicks += 1;
        let accepted_cost = s.cost;
        s.log.clear();
        s.double_bridge(&mut rng);
        if !s.local_search(&started, deadline_s) {
            stop = Stop::TimeLimit;
        }
        if s.cost <= accepted_cost + s.eps || s.cost <= history[slot] + s.eps {
            if s.cost < best_cost - s.eps {
                s.cost = m_tour_cost(m, &s.tour);
                best_cost = s.cost;
                best_tour.copy_from_slice(&s.tour);
                progress::report(Event::Incumbent(best_cost));
            }
        } else {
            s.undo();
            s.cost = accepted_cost;
        }
        history[slot] = s.cost;
    }

    let finish = |tour: &[usize]| -> Vec<usize> {
        let at = tour.iter().position(|&v| v == 0).unwrap_or(0);
        tour[at + 1..]
            .iter()
            .chain(&tour[..at])
            .copied()
            .collect::<Vec<usize>>()
    };
    let mut order = finish(&best_tour);
    let mut cost = m.tour_cost(&order);
    let last = finish(&s.tour);
    let last_cost = m.tour_cost(&last);
    if last_cost < cost {
        order = last;
        cost = last_cost;
    }
    Outcome {
        order,
        cost,
        kicks,
        seconds: started.elapsed().as_secs_f64(),
        stop,
    }
}

/// Cost of a cyclic tour given as a rotation of all nodes.
fn m_tour_cost(m: &CostMatrix, tour: &[usize]) -> f64 {
    let mut total = 0.0;
    for w in tour.windows(2) {
        total += m.cost(w[0], w[1]);
    }
    match (tour.last(), tour.first()) {
        (Some(&last), Some(&first)) if tour.len() > 1 => total + m.cost(last, first),
        _ => total,
    }
}

/// Nearest-neighbour tour from the origin, as a rotation of all nodes starting at 0.
fn nearest_neighbour(m: &CostMatrix) -> Vec<usize> {
    let n = m.len();
    let mut visited = vec![false; n];
    let mut tour = Vec::with_capacity(n);
    let mut here = 0;
    visited[0] = true;
    tour.push(0);
    for _ in 1..n {
        let mut next = None;
        let mut next_cost = f64::INFINITY;
        for (j, &seen) in visited.iter().enumerate() {
            if !seen && (next.is_none() || m.cost(here, j) < next_cost) {
                next = Some(j);
                next_cost = m.cost(here, j);
            }
        }
        let Some(j) = next else { break };
        visited[j] = true;
        tour.push(j);
        here = j;
    }
    tour
}

/// Karp's patching (Karp 1979): merge the smallest cycle of the assignment into another one
/// by the cheapest exchange of two successors, until one cycle is left. Returns the tour as a
/// rotation of all nodes starting at 0.
fn patch(m: &CostMatrix, successor: &[usize]) -> Vec<usize> {
    let n = successor.len();
    let mut succ = successor.to_vec();
    let mut cycle = vec![usize::MAX; n];
    let mut members: Vec<Vec<usize>> = Vec::new();
    for s in 0..n {
        if cycle[s] != usize::MAX {
            continue;
        }
        let id = members.len();
        let mut nodes = Vec::new();
        let mut v = s;
        while cycle[v] == usize::MAX {
            cycle[v] = id;
            nodes.push(v);
            v = succ[v];
        }
        members.push(nodes);
    }
    let mut alive: Vec<usize> = (0..members.len()).collect();
    while alive.len() > 1 {
        let (slot, &small) = alive
            .iter()
            .enumerate()
            .min_by_key(|(_, &id)| members[id].len())
            .unwrap_or((0, &alive[0]));
        let mut best: Option<(f64, usize, usize)> = None;
        for &i in &members[small] {
            let si = succ[i];
            let ci = m.cost(i, si);
            for j in 0..n {
                if cycle[j] == small {
                    continue;
                }
                let sj = succ[j];
                let delta = m.cost(i, sj) + m.cost(j, si) - ci - m.cost(j, sj);
                if best.is_none_or(|(d, _, _)| delta < d) {
                    best = Some((delta, i, j));
                }
            }
        }
        let Some((_, i, j)) = best else { break };
        succ.swap(i, j);
        let big = cycle[j];
        let moved = std::mem::take(&mut members[small]);
        for &v in &moved {
            cycle[v] = big;
        }
        members[big].extend(moved);
        alive.swap_remove(slot);
    }
    let mut tour = Vec::with_capacity(n);
    let mut v = 0;
    for _ in 0..n {
        tour.push(v);
        v = succ[v];
    }
    tour
}

/// The `k` best out-arcs and in-arcs of every node by `rank(i, j)`, flattened `n * k`.
fn candidates(n: usize, k: usize, rank: impl Fn(usize, usize) -> f64) -> (Vec<usize>, Vec<usize>) {
    let mut out = Vec::with_capacity(n * k);
    let mut inn = Vec::with_capacity(n * k);
    let mut row: Vec<(f64, usize)> = Vec::with_capacity(n);
    let pick = |row: &mut Vec<(f64, usize)>, into: &mut Vec<usize>| {
        let by = |a: &(f64, usize), b: &(f64, usize)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
        if row.len() > k {
            row.select_nth_unstable_by(k - 1, by);
            row.truncate(k);
        }
        row.sort_unstable_by(by);
        into.extend(row.iter().map(|&(_, j)| j));
    };
    for i in 0..n {
        row.clear();
        row.extend((0..n).filter(|&j| j != i).map(|j| (rank(i, j), j)));
        pick(&mut row, &mut out);
    }
    for j in 0..n {
        row.clear();
        row.extend((0..n).filter(|&i| i != j).map(|i| (rank(i, j), i)));
        pick(&mut row, &mut inn);
    }
    (out, inn)
}

/// A change of the tour array, kept to undo a rejected kick.
#[derive(Debug, Clone, Copy)]
enum Edit {
    /// Segments of lengths `lx` and `ly` from position `start` swapped: `X Y -> Y X`.
    Swap { start: usize, lx: usize, ly: usize },
    /// The `len` nodes from position `start` reversed.
    Reverse { start: usize, len: usize },
}

/// The tour as an array with positions, the candidate lists, the queue of active nodes (the
/// don't-look bits) and the log of segment swaps since the last accepted tour.
struct Search<'a> {
    m: &'a CostMatrix,
    n: usize,
    k: usize,
    out: Vec<usize>,
    inn: Vec<usize>,
    /// `cost(i, out[i k + x])` and `cost(inn[j k + x], j)`, to spare the matrix's cache misses.
    out_cost: Vec<f64>,
    in_cost: Vec<f64>,
    tour: Vec<usize>,
    pos: Vec<usize>,
    /// `cost(v, succ(v))` for every node `v`.
    next_cost: Vec<f64>,
    buf: Vec<usize>,
    queue: VecDeque<usize>,
    queued: Vec<bool>,
    /// Swaps `(start, lx, ly)` applied since the last accepted tour.
    log: Vec<Edit>,
    rmax: usize,
    /// Gains at or below this are float noise, not improvements.
    eps: f64,
    /// Cost of the current tour, kept up to date by the gains.
    cost: f64,
}

impl<'a> Search<'a> {
    fn new(
        m: &'a CostMatrix,
        k: usize,
        out: Vec<usize>,
        inn: Vec<usize>,
        tour: Vec<usize>,
    ) -> Self {
        let n = tour.len();
        let mut pos = vec![0; n];
        for (p, &v) in tour.iter().enumerate() {
            pos[v] = p;
        }
        let cost = m_tour_cost(m, &tour);
        let out_cost = (0..n * k).map(|e| m.cost(e / k, out[e])).collect();
        let in_cost = (0..n * k).map(|e| m.cost(inn[e], e / k)).collect();
        let mut next_cost = vec![0.0; n];
        for p in 0..n {
            next_cost[tour[p]] = m.cost(tour[p], tour[(p + 1) % n]);
        }
        // Tolerance: 1e-9 of the mean magnitude of the finite arcs of the start tour.
        let finite: Vec<f64> = next_cost
            .iter()
            .copied()
            .filter(|c| c.is_finite())
            .collect();
        let mean_arc = finite.iter().map(|c| c.abs()).sum::<f64>() / finite.len().max(1) as f64;
        let eps = 1e-9 * mean_arc;
        Search {
            m,
            n,
            k,
            out,
            inn,
            out_cost,
            in_cost,
            tour,
            pos,
            next_cost,
            buf: Vec::with_capacity(n),
            queue: VecDeque::with_capacity(n),
            queued: vec![false; n],
            log: Vec::new(),
            rmax: REVERSAL_MAX,
            eps,
            cost,
        }
    }

    /// Panics unless positions, successor costs and the running cost agree with the tour.
    #[cfg(test)]
    fn assert_consistent(&self) {
        for v in 0..self.n {
            assert_eq!(self.tour[self.pos[v]], v);
            assert_eq!(
                self.next_cost[v],
                self.c(v, self.succ(v)),
                "next_cost of {v}"
            );
        }
        let exact = m_tour_cost(self.m, &self.tour);
        assert!(
            (exact - self.cost).abs() < 1e-6 * exact.abs().max(1.0),
            "{exact} {}",
            self.cost
        );
    }

    #[inline]
    fn c(&self, i: usize, j: usize) -> f64 {
        self.m.cost(i, j)
    }

    #[inline]
    fn at(&self, p: usize) -> usize {
        self.tour[if p >= self.n { p - self.n } else { p }]
    }

    #[inline]
    fn succ(&self, v: usize) -> usize {
        self.at(self.pos[v] + 1)
    }

    #[inline]
    fn pred(&self, v: usize) -> usize {
        self.at(self.pos[v] + self.n - 1)
    }

    /// Number of steps forward from `from` to `to`.
    #[inline]
    fn offset(&self, from: usize, to: usize) -> usize {
        let (a, b) = (self.pos[from], self.pos[to]);
        if b >= a {
            b - a
        } else {
            b + self.n - a
        }
    }

    fn push(&mut self, v: usize) {
        if !self.queued[v] {
            self.queued[v] = true;
            self.queue.push_back(v);
        }
    }

    /// Swaps the adjacent segments of lengths `lx` and `ly` starting at position `start`
    /// (cyclically): `X Y -> Y X`. Logged for [`Search::undo`].
    fn swap(&mut self, start: usize, lx: usize, ly: usize) {
        self.swap_unlogged(start, lx, ly);
        self.log.push(Edit::Swap { start, lx, ly });
    }

    fn swap_unlogged(&mut self, start: usize, lx: usize, ly: usize) {
        let n = self.n;
        self.buf.clear();
        for t in lx..lx + ly {
            self.buf.push(self.at(start + t));
        }
        for t in 0..lx {
            self.buf.push(self.at(start + t));
        }
        for t in 0..lx + ly {
            let p = if start + t >= n {
                start + t - n
            } else {
                start + t
            };
            let v = self.buf[t];
            self.tour[p] = v;
            self.pos[v] = p;
        }
        // Only the nodes before the two segments and at their ends have new successors.
        for p in [start + n - 1, start + ly - 1, start + lx + ly - 1] {
            let v = self.at(p);
            self.next_cost[v] = self.c(v, self.succ(v));
        }
    }

    /// Reverses the `len` nodes from position `start` (cyclically). Logged for
    /// [`Search::undo`].
    fn reverse(&mut self, start: usize, len: usize) {
        self.reverse_unlogged(start, len);
        self.log.push(Edit::Reverse { start, len });
    }

    fn reverse_unlogged(&mut self, start: usize, len: usize) {
        let n = self.n;
        let wrap = |p: usize| if p >= n { p - n } else { p };
        for t in 0..len / 2 {
            let (i, j) = (wrap(start + t), wrap(start + len - 1 - t));
            let (u, w) = (self.tour[i], self.tour[j]);
            self.tour[i] = w;
            self.tour[j] = u;
            self.pos[w] = i;
            self.pos[u] = j;
        }
        // The node before the segment and every node in it have new successors.
        for t in 0..=len {
            let v = self.tour[(start + n - 1 + t) % n];
            self.next_cost[v] = self.c(v, self.succ(v));
        }
    }

    /// Reverts every logged edit, newest first.
    fn undo(&mut self) {
        while let Some(edit) = self.log.pop() {
            match edit {
                Edit::Swap { start, lx, ly } => self.swap_unlogged(start, ly, lx),
                Edit::Reverse { start, len } => self.reverse_unlogged(start, len),
            }
        }
    }

    /// The reversal-free 3-opt segment exchange: with `a, b, c` in tour order, replaces the
    /// arcs `a->a'`, `b->b'`, `c->c'` by `a->b'`, `b->c'`, `c->a'` (primes are successors),
    /// i.e. swaps the segments `a'..b` and `b'..c`. Moves the two shortest of the three
    /// segments.
    fn exchange(&mut self, a: usize, b: usize, c: usize, gain: f64) {
        let (a1, b1, c1) = (self.succ(a), self.succ(b), self.succ(c));
        let l1 = self.offset(a1, b) + 1;
        let l2 = self.offset(b1, c) + 1;
        let l3 = self.n - l1 - l2;
        if l3 >= l1 && l3 >= l2 {
            self.swap(self.pos[a1], l1, l2);
        } else if l1 >= l2 {
            self.swap(self.pos[b1], l2, l3);
        } else {
            self.swap(self.pos[c1], l3, l1);
        }
        self.cost -= gain;
        for v in [a, a1, b, b1, c, c1] {
            self.push(v);
        }
    }

    /// Runs the local search until no active node is left; false if the time limit stopped it.
    fn local_search(&mut self, started: &Instant, deadline_s: f64) -> bool {
        let mut pops = 0u32;
        while let Some(v) = self.queue.pop_front() {
            self.queued[v] = false;
            pops = pops.wrapping_add(1);
            if pops.is_multiple_of(1024)
                && (started.elapsed().as_secs_f64() >= deadline_s || super::cancel::requested())
            {
                self.queue.clear();
                self.queued.fill(false);
                return false;
            }
            while self.improve(v) {}
        }
        true
    }

    /// Applies the first improving move found around `v`; false if there is none.
    fn improve(&mut self, v: usize) -> bool {
        self.three_opt_out(v) || self.three_opt_in(v) || self.or_opt(v) || self.two_opt(v)
    }

    /// 2-opt with reversal: replaces `a -> a'` and `b -> b'` by `a -> b` and `a' -> b'`,
    /// reversing the path `a' .. b` of at most `REVERSAL_MAX` nodes. The path's cost both ways
    /// is summed while `b` walks forward, so each `b` costs O(1).
    fn two_opt(&mut self, a: usize) -> bool {
        let n = self.n;
        let a1 = self.succ(a);
        let base = self.next_cost[a];
        let mut reversal = 0.0; // cost of a' .. b backwards minus forwards
        let mut b = a1;
        for len in 2..=self.rmax.min(n - 2) {
            let next = self.succ(b);
            reversal += self.c(next, b) - self.next_cost[b];
            b = next;
            let b1 = self.succ(b);
            let gain = base + self.next_cost[b] - self.c(a, b) - self.c(a1, b1) - reversal;
            if gain > self.eps {
                self.reverse(self.pos[a1], len);
                self.cost -= gain;
                for v in [a, a1, b, b1] {
                    self.push(v);
                }
                return true;
            }
        }
        false
    }

    /// Segment exchange searched from the removed arc `a -> a'` over the out-candidates:
    /// add `a -> b'`, remove `b -> b'`, add `b -> c'`, remove `c -> c'`, close with `c -> a'`.
    fn three_opt_out(&mut self, a: usize) -> bool {
        let k = self.k;
        let a1 = self.succ(a);
        let g0 = self.next_cost[a];
        for x in 0..k {
            let b1 = self.out[a * k + x];
            let g1 = g0 - self.out_cost[a * k + x];
            if g1 <= self.eps || b1 == a1 {
                continue;
            }
            let b = self.pred(b1);
            let ob = self.offset(a1, b);
            let g1 = g1 + self.next_cost[b];
            for y in 0..k {
                let c1 = self.out[b * k + y];
                let g2 = g1 - self.out_cost[b * k + y];
                if g2 <= self.eps || self.offset(a1, c1) < ob + 2 {
                    continue;
                }
                let c = self.pred(c1);
                let gain = g2 + self.next_cost[c] - self.c(c, a1);
                if gain > self.eps {
                    self.exchange(a, b, c, gain);
                    return true;
                }
            }
        }
        false
    }

    /// Segment exchange searched from the removed arc `a -> a'` backwards over the
    /// in-candidates: add `c -> a'`, remove `c -> c'`, add `b -> c'`, remove `b -> b'`, close
    /// with `a -> b'`.
    fn three_opt_in(&mut self, a1: usize) -> bool {
        let k = self.k;
        let a = self.pred(a1);
        let g0 = self.next_cost[a];
        for x in 0..k {
            let c = self.inn[a1 * k + x];
            let g1 = g0 - self.in_cost[a1 * k + x];
            if g1 <= self.eps || c == a {
                continue;
            }
            let c1 = self.succ(c);
            let oc = self.offset(a1, c);
            let g1 = g1 + self.next_cost[c];
            for y in 0..k {
                let b = self.inn[c1 * k + y];
                let g2 = g1 - self.in_cost[c1 * k + y];
                if g2 <= self.eps || self.offset(a1, b) >= oc {
                    continue;
                }
                let b1 = self.succ(b);
                let gain = g2 + self.next_cost[b] - self.c(a, b1);
                if gain > self.eps {
                    self.exchange(a, b, c, gain);
                    return true;
                }
            }
        }
        false
    }

    /// Or-opt: moves a segment of 1 to 3 nodes that starts or ends at `v` next to a candidate
    /// neighbour of its first node (before it) or of its last node (after it).
    fn or_opt(&mut self, v: usize) -> bool {
        let n = self.n;
        for len in 1..=3usize.min(n - 2) {
            for first_offset in [0, len - 1] {
                let s1 = self.at(self.pos[v] + n - first_offset);
                let sk = self.at(self.pos[s1] + len - 1);
                if self.try_move_segment(s1, sk, len) {
                    return true;
                }
                if len == 1 {
                    break;
                }
            }
        }
        false
    }

    fn try_move_segment(&mut self, s1: usize, sk: usize, len: usize) -> bool {
        let k = self.k;
        let p = self.pred(s1);
        let q = self.succ(sk);
        let removal = self.next_cost[p] + self.next_cost[sk] - self.c(p, q);
        if removal <= self.eps {
            return false;
        }
        for e in 0..k {
            // Insert between `before` and its successor `y`: before -> s1 .. sk -> y.
            let before = self.inn[s1 * k + e];
            if before != p && self.offset(s1, before) >= len {
                let y = self.succ(before);
                let gain =
                    removal - self.in_cost[s1 * k + e] - self.c(sk, y) + self.next_cost[before];
                if gain > self.eps {
                    self.exchange(p, sk, before, gain);
                    return true;
                }
            }
            // Insert between the predecessor `x` of `after` and `after`: x -> s1 .. sk -> after.
            let after = self.out[sk * k + e];
            if after != q && self.offset(s1, after) >= len {
                let x = self.pred(after);
                let gain = removal - self.c(x, s1) - self.out_cost[sk * k + e] + self.next_cost[x];
                if gain > self.eps {
                    self.exchange(p, sk, x, gain);
                    return true;
                }
            }
        }
        false
    }

    /// Segment-reversal-free double bridge `A B C D -> A D C B` on three short segments
    /// starting at a random position; activates the eight nodes around the new arcs.
    fn double_bridge(&mut self, rng: &mut Rng) {
        let n = self.n;
        let longest = KICK_SEGMENT_MAX.min((n - 1) / 3).max(1);
        let lb = 1 + rng.below(longest);
        let lc = 1 + rng.below(longest);
        let ld = 1 + rng.below(longest);
        let start = rng.below(n);
        let a = self.at(start + n - 1);
        let b0 = self.at(start);
        let b1 = self.at(start + lb - 1);
        let c0 = self.at(start + lb);
        let c1 = self.at(start + lb + lc - 1);
        let d0 = self.at(start + lb + lc);
        let d1 = self.at(start + lb + lc + ld - 1);
        let e = self.at(start + lb + lc + ld);
        let delta = self.c(a, d0) + self.c(d1, c0) + self.c(c1, b0) + self.c(b1, e)
            - self.c(a, b0)
            - self.c(b1, c0)
            - self.c(c1, d0)
            - self.c(d1, e);
        // B C D -> C D B -> D C B.
        self.swap(start, lb, lc + ld);
        self.swap(start, lc, ld);
        self.cost += delta;
        for v in [a, b0, b1, c0, c1, d0, d1, e] {
            self.push(v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tour::held_karp;
    use crate::tour::testing::{drone, tsplib_instance};

    fn random_matrix(n: usize, rng: &mut Rng) -> CostMatrix {
        let costs: Vec<f64> = (0..n * n).map(|_| rng.uniform(1.0, 100.0)).collect();
        CostMatrix::from_fn(n, |i, j| costs[i * n + j])
    }

    fn budget(kicks: u64) -> Options {
        Options {
            max_kicks: Some(kicks),
            time_limit_s: 60.0,
            ..Options::default()
        }
    }

    fn assert_valid(order: &[usize], n: usize) {
        assert!(
            is_tour_order(n, order),
            "not a permutation of 1..{n}: {order:?}"
        );
    }

    #[test]
    fn the_heuristic_finds_the_held_karp_optimum_on_small_random_instances() {
        let mut rng = Rng::new(42);
        let mut optimal = 0;
        let trials = 90;
        for trial in 0..trials {
            let n = 4 + trial % 10; // 3 to 12 waypoints
            let m = if trial % 3 == 2 {
                drone(n, trial as u64)
            } else {
                random_matrix(n, &mut rng)
            };
            let exact = held_karp::solve(&m).expect("small enough for held-karp");
            let found = solve(&m, None, &budget(300));
            assert_valid(&found.order, n);
            assert_eq!(found.cost, m.tour_cost(&found.order));
            assert!(
                found.cost >= exact.cost - 1e-9,
                "below the optimum on trial {trial}"
            );
            let is_optimal = found.cost <= exact.cost + 1e-9;
            if n - 1 <= 8 {
                assert!(
                    is_optimal,
                    "trial {trial}: {} vs {}",
                    found.cost, exact.cost
                );
            }
            optimal += usize::from(is_optimal);
        }
        assert!(
            optimal * 10 >= trials * 9,
            "optimal on {optimal} of {trials}"
        );
    }

    #[test]
    fn the_same_seed_and_kick_budget_give_the_same_tour() {
        let m = drone(150, 7);
        let first = solve(&m, None, &budget(1500));
        let second = solve(&m, None, &budget(1500));
        assert_eq!(first.order, second.order);
        assert_eq!(first.cost, second.cost);
        assert_eq!((first.kicks, first.stop), (1500, Stop::Kicks));
    }

    #[test]
    fn the_heuristic_takes_the_cheap_direction_of_a_one_way_street() {
        // Around the ring 0 -> 1 -> ... -> n-1 -> 0 every leg costs 1; against it, 100;
        // any other leg, 50.
        let n = 40;
        let m = CostMatrix::from_fn(n, |i, j| {
            if j == (i + 1) % n {
                1.0
            } else if i == (j + 1) % n {
                100.0
            } else {
                50.0
            }
        });
        let reversed: Vec<usize> = (1..n).rev().collect();
        let found = solve(&m, Some(&reversed), &budget(200));
        assert_eq!(found.order, (1..n).collect::<Vec<_>>());
        assert_eq!(found.cost, n as f64);
    }

    #[test]
    fn tiny_instances_and_a_bad_initial_order_do_not_panic() {
        for n in 0..=5 {
            let m = CostMatrix::from_fn(n, |i, j| (3 * i + 7 * j) as f64 % 5.0 + 1.0);
            let found = solve(&m, None, &budget(20));
            assert_valid(&found.order, n.max(1));
            if n >= 2 {
                let exact = held_karp::solve(&m).expect("tiny");
                assert_eq!(found.cost, exact.cost, "n = {n}");
            }
        }
        let m = drone(6, 3);
        let bad: [&[usize]; 5] = [
            &[],
            &[1, 2, 3, 4, 4],
            &[0, 1, 2, 3, 4],
            &[1, 2, 3, 4, 9],
            &[5, 4],
        ];
        for initial in bad {
            let found = solve(&m, Some(initial), &budget(50));
            assert_valid(&found.order, 6);
        }
    }

    #[test]
    fn non_finite_costs_and_odd_options_still_give_a_valid_tour() {
        let n = 12;
        let m = CostMatrix::from_fn(n, |i, j| match (i + j) % 7 {
            0 => f64::NAN,
            1 => f64::INFINITY,
            _ => (i * j) as f64,
        });
        let odd = Options {
            seed: 0,
            time_limit_s: f64::NAN,
            max_kicks: Some(100),
            candidates: 0,
        };
        assert_valid(&solve(&m, None, &odd).order, n);
        let stopped = solve(
            &drone(50, 1),
            None,
            &Options {
                time_limit_s: -1.0,
                ..budget(100)
            },
        );
        assert_valid(&stopped.order, 50);
        assert_eq!((stopped.kicks, stopped.stop), (0, Stop::TimeLimit));
    }

    #[test]
    fn a_valid_initial_order_is_never_made_worse() {
        let m = drone(80, 5);
        let initial: Vec<usize> = (1..80).collect();
        let found = solve(&m, Some(&initial), &budget(0));
        assert_valid(&found.order, 80);
        assert!(found.cost <= m.tour_cost(&initial));
    }

    #[test]
    fn br17_and_ftv33_come_within_two_percent_of_their_optimum() {
        for (name, optimum) in [("br17", 39.0), ("ftv33", 1286.0)] {
            let m = tsplib_instance(name);
            let found = solve(&m, None, &budget(2000));
            assert_valid(&found.order, m.len());
            assert!(
                found.cost >= optimum,
                "{name}: {} is below the optimum",
                found.cost
            );
            assert!(
                found.cost <= 1.02 * optimum,
                "{name}: {} vs {optimum}",
                found.cost
            );
        }
    }

    #[test]
    fn running_costs_stay_equal_to_recomputed_ones_through_moves_kicks_and_undos() {
        let m = drone(120, 11);
        let n = m.len();
        let (out, inn) = candidates(n, 8, |i, j| m.cost(i, j));
        let mut s = Search::new(&m, 8, out, inn, nearest_neighbour(&m));
        let started = Instant::now();
        for v in 0..n {
            s.push(v);
        }
        assert!(s.local_search(&started, f64::INFINITY));
        s.assert_consistent();
        let mut rng = Rng::new(9);
        for kick in 0..300 {
            let before = s.cost;
            s.log.clear();
            s.double_bridge(&mut rng);
            s.assert_consistent();
            assert!(s.local_search(&started, f64::INFINITY));
            s.assert_consistent();
            if kick % 2 == 0 {
                s.undo();
                s.cost = before;
                s.assert_consistent();
            }
        }
    }
}
