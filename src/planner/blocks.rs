//! A mission's blocks in a plan: each block's ways (forward, and reversed when reversible)
//! priced once as the profile flies them, the stops `tour::clusters` orders (the points one way
//! each, the blocks their ways), the solved stop tours expanded to every waypoint with the
//! blocks contiguous in flown order, and the contraction of the stops the sortie split works
//! on, so that no sortie splits a block.
//!
//! Node numbering as in the planner: node 0 is the origin, node `k + 1` waypoint `k`.
//!
//! Invariant: pure; the energy of a way is the sum of its inner legs' prices and of the turns
//! at their arrivals, so that an order's energy stays the sum of its legs.

use crate::mission::{Enu, Mission};
use crate::physics::ardupilot_chain::is_fast;
use crate::physics::{start_case, LegEnergy, PhysicsError, Pricing, Profile, Start};
use crate::tour::clusters::{self, Stop, StopTour, Visit, Way};
use crate::tour::orders::{Direction, Objective, Proof, SolvedOrder};
use crate::tour::{solver, CostMatrix, Geometry, PlanError};

use super::{detour, FlownBlock, VehicleModel};

/// One inner leg of a block flown one way, priced as the profile flies the whole block.
#[derive(Debug, Clone, PartialEq)]
pub struct InnerLeg {
    /// Node ids.
    pub from: usize,
    pub to: usize,
    pub predicted: LegEnergy,
    pub start: Start,
}

/// A block flown one way, its inner legs in flown order.
#[derive(Debug, Clone, PartialEq)]
pub struct PricedWay {
    pub legs: Vec<InnerLeg>,
    /// Its inner legs as the plan prices them and the turns at their arrivals (J): the way's
    /// inner cost in the energy order's stop tour.
    pub inner_j: f64,
}

/// Every block's ways, priced once per plan: `[forward, reversed]`, the reversed way None for
/// a block flown only as written.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BlockWays {
    pub ways: Vec<[Option<PricedWay>; 2]>,
}

impl BlockWays {
    /// Block `block` flown `reversed`, when it may be.
    pub fn get(&self, block: usize, reversed: bool) -> Option<&PricedWay> {
        self.ways.get(block)?[usize::from(reversed)].as_ref()
    }

    /// The inner leg from node `from` to node `to` when they are consecutive waypoints of one
    /// block, with the block's index.
    pub fn inner(&self, mission: &Mission, from: usize, to: usize) -> Option<(usize, &InnerLeg)> {
        if from == 0 || to == 0 || from.abs_diff(to) != 1 {
            return None;
        }
        let b = mission.block_of(from - 1)?;
        if mission.block_of(to - 1) != Some(b) {
            return None;
        }
        let way = self.get(b, to < from)?;
        way.legs
            .iter()
            .find(|l| l.from == from && l.to == to)
            .map(|l| (b, l))
    }
}

/// A leg the profile could not price: the nodes it joins and why.
pub type PriceFailure = (usize, usize, PhysicsError);

/// Prices block `block` of `mission` flown `reversed`: the lines between speed changes each as
/// one chain from rest at its first waypoint to rest at its last (`detour::chain_parts`: the
/// `ardupilot` profile flies the zero-hold waypoints between as ArduCopter's fast waypoints,
/// the other profiles leg by leg after the leg before, the first behind), each line at the
/// speed the file flies it at (`line_speed(a, b)` of nodes a < b, whichever way it is
/// flown), then the turns at the inner arrivals (`turn_j(from, to)`).
#[allow(clippy::too_many_arguments)]
pub fn price_way<'a>(
    mission: &Mission,
    block: usize,
    reversed: bool,
    points: &[Enu],
    line_speed: &(dyn Fn(usize, usize) -> Option<f64> + Sync),
    model_at: &(dyn Fn(Option<f64>) -> &'a VehicleModel + Sync),
    turn_j: &(dyn Fn(usize, usize) -> f64 + Sync),
    pricing: Pricing,
) -> Result<PricedWay, PriceFailure> {
    let nodes: Vec<usize> = mission.blocks[block]
        .flown(reversed)
        .into_iter()
        .map(|k| k + 1)
        .collect();
    let speed = |k: usize| line_speed(nodes[k].min(nodes[k + 1]), nodes[k].max(nodes[k + 1]));
    let mut legs = Vec::with_capacity(nodes.len().saturating_sub(1));
    let mut first = 0;
    while first + 1 < nodes.len() {
        // The lines flown at one speed: one chain.
        let mut last = first + 1;
        while last + 1 < nodes.len() && speed(last) == speed(first) {
            last += 1;
        }
        let model = model_at(speed(first));
        let chain: Vec<Enu> = nodes[first + 1..=last].iter().map(|&n| points[n]).collect();
        let fast: Vec<bool> = nodes[first + 1..=last]
            .iter()
            .map(|&n| is_fast(mission.waypoints[n - 1].hold_s(), true))
            .collect();
        let parts = detour::chain_parts(model, points[nodes[first]], &chain, &fast, Start::Behind)
            .map_err(|e| (nodes[first], nodes[last], e))?;
        let mut previous: Option<(f64, f64)> = None;
        for (k, part) in parts.into_iter().enumerate() {
            let (from, to) = (nodes[first + k], nodes[first + k + 1]);
            let heading = (
                points[to].x_east_m - points[from].x_east_m,
                points[to].y_north_m - points[from].y_north_m,
            );
            let ardupilot = model.profile == Profile::Ardupilot;
            let start = match previous {
                Some(p) if !ardupilot => start_case(Some(p), heading),
                _ => Start::Behind,
            };
            previous = Some(heading);
            // A waypoint flown through: the leg's run past the 4 m rule until the next leg
            // takes over is flight, not a settle the paper's pricing leaves out.
            let through = ardupilot && k + 1 < chain.len() && fast[k];
            let predicted = if through {
                LegEnergy {
                    energy_j: part.total_energy_j(),
                    duration_s: part.total_duration_s(),
                    settle_energy_j: 0.0,
                    settle_duration_s: 0.0,
                }
            } else {
                part
            };
            legs.push(InnerLeg {
                from,
                to,
                predicted,
                start,
            });
        }
        first = last;
    }
    let inner_j = legs
        .iter()
        .map(|l| l.predicted.priced_energy_j(pricing) + turn_j(l.from, l.to))
        .sum();
    Ok(PricedWay { legs, inner_j })
}

/// The stops of a mission with blocks: the points not in a block (one way each) and the
/// blocks (forward, then reversed when reversible), in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct StopSet {
    pub stops: Vec<Stop>,
    /// The block of each stop (None: a point).
    pub block: Vec<Option<usize>>,
}

impl StopSet {
    /// The stops of `mission`, each block's way costing `inner(block, reversed)`; the blocks
    /// in `broken` count as their waypoints, each a point.
    pub fn new(mission: &Mission, broken: &[usize], inner: impl Fn(usize, bool) -> f64) -> Self {
        let mut stops = Vec::new();
        let mut block = Vec::new();
        for k in 0..mission.waypoints.len() {
            match mission.block_of(k).filter(|b| !broken.contains(b)) {
                Some(b) => {
                    let blk = &mission.blocks[b];
                    if k != blk.first {
                        continue;
                    }
                    let way = |reversed: bool| Way {
                        entry: blk.entry(reversed) + 1,
                        exit: blk.exit(reversed) + 1,
                        inner: inner(b, reversed),
                    };
                    let mut ways = vec![way(false)];
                    if blk.reversible {
                        ways.push(way(true));
                    }
                    stops.push(Stop { ways });
                    block.push(Some(b));
                }
                None => {
                    stops.push(Stop::point(k + 1));
                    block.push(None);
                }
            }
        }
        StopSet { stops, block }
    }

    /// Every waypoint node the visits fly, a block's in its flown order.
    pub fn nodes(&self, mission: &Mission, visits: &[Visit]) -> Vec<usize> {
        visits
            .iter()
            .flat_map(|v| match self.block[v.stop] {
                Some(b) => mission.blocks[b]
                    .flown(v.way == 1)
                    .into_iter()
                    .map(|k| k + 1)
                    .collect(),
                None => vec![self.stops[v.stop].ways[0].entry],
            })
            .collect()
    }

    /// The visits flown backwards, each block the other way; None when a block in them may
    /// only be flown as written.
    pub fn reversed(&self, visits: &[Visit]) -> Option<Vec<Visit>> {
        visits
            .iter()
            .rev()
            .map(|v| match self.stops[v.stop].ways.len() {
                1 if self.block[v.stop].is_some() => None,
                1 => Some(*v),
                _ => Some(Visit {
                    stop: v.stop,
                    way: 1 - v.way,
                }),
            })
            .collect()
    }

    /// The visits of an order's `nodes` (every waypoint, each block contiguous).
    pub fn visits(&self, mission: &Mission, nodes: &[usize]) -> Vec<Visit> {
        let mut visits: Vec<Visit> = Vec::new();
        for &node in nodes {
            let Some(stop) = self.stops.iter().position(|s| {
                s.ways
                    .iter()
                    .any(|w| (w.entry.min(w.exit)..=w.entry.max(w.exit)).contains(&node))
            }) else {
                continue;
            };
            if visits.last().is_some_and(|v| v.stop == stop) {
                continue;
            }
            let way = match self.block[stop] {
                Some(b) => usize::from(
                    mission.blocks[b].len > 1 && node - 1 == mission.blocks[b].entry(true),
                ),
                None => 0,
            };
            visits.push(Visit { stop, way });
        }
        visits
    }
}

/// The blocks `nodes` fly, in order, each with its direction (entered at its last waypoint:
/// reversed).
pub fn flown_blocks(mission: &Mission, nodes: &[usize]) -> Vec<FlownBlock> {
    let mut flown: Vec<FlownBlock> = Vec::new();
    for &node in nodes {
        let Some(b) = node.checked_sub(1).and_then(|k| mission.block_of(k)) else {
            continue;
        };
        if flown.iter().any(|f| f.block == b) {
            continue;
        }
        flown.push(FlownBlock {
            block: b,
            reversed: node - 1 == mission.blocks[b].entry(true),
        });
    }
    flown
}

/// The cost of block `block`'s inner lines flown either way by a per-line `cost(a, b)`.
fn inner_by(mission: &Mission, block: usize, cost: &dyn Fn(usize, usize) -> f64) -> f64 {
    let nodes: Vec<usize> = mission.blocks[block].waypoints().map(|k| k + 1).collect();
    nodes.windows(2).map(|w| cost(w[0], w[1])).sum()
}

/// The order minimising `objective` over the stops of `mission`: the energy order on
/// `energy` with each way's priced inner cost (`ways`), a distance baseline on `geometry`'s
/// matrix with each block's inner lines measured straight (`straight`) the same way; a
/// baseline forward, then reversed (each block the other way) when every block in it may be.
pub fn stop_orders(
    mission: &Mission,
    geometry: &Geometry,
    straight: &Geometry,
    energy: Option<(&CostMatrix, &BlockWays)>,
    objective: Objective,
    options: &solver::Options,
) -> Result<Vec<SolvedOrder>, PlanError> {
    let started = std::time::Instant::now();
    let vertical =
        |g: &Geometry, i: usize, j: usize| g.vertical_m(i, j).abs() + 1e-4 * g.horizontal_m(i, j);
    let (matrix, set) = match objective {
        Objective::Energy => {
            let (m, ways) = energy.ok_or(PlanError::NoEnergyModel)?;
            let set = StopSet::new(mission, &[], |b, r| {
                ways.get(b, r).map_or(f64::INFINITY, |w| w.inner_j)
            });
            (m.clone(), set)
        }
        Objective::Distance => (
            geometry.distance_matrix(),
            StopSet::new(mission, &[], |b, _| {
                inner_by(mission, b, &|i, j| straight.distance_m(i, j))
            }),
        ),
        Objective::Horizontal => (
            geometry.horizontal_matrix(),
            StopSet::new(mission, &[], |b, _| {
                inner_by(mission, b, &|i, j| straight.horizontal_m(i, j))
            }),
        ),
        Objective::Vertical => (
            CostMatrix::from_fn(geometry.len(), |i, j| vertical(geometry, i, j)),
            StopSet::new(mission, &[], |b, _| {
                inner_by(mission, b, &|i, j| vertical(straight, i, j))
            }),
        ),
    };
    let tour: StopTour = clusters::solve(&matrix, &set.stops, options)?;
    let proof = Proof {
        solver: tour.solver,
        optimal: tour.optimal,
        lower_bound: tour.lower_bound,
        gap_pct: tour.gap_pct,
        seconds: started.elapsed().as_secs_f64(),
    };
    if objective == Objective::Energy {
        return Ok(vec![SolvedOrder {
            objective,
            direction: Direction::Forward,
            nodes: set.nodes(mission, &tour.visits),
            proof: Some(proof),
        }]);
    }
    let mut forward = tour.visits;
    let mut reverse = set.reversed(&forward);
    // Forward: the direction whose first waypoint comes earlier in the file than its last.
    if let Some(r) = &reverse {
        let nodes = set.nodes(mission, &forward);
        if nodes.first() > nodes.last() {
            let r = r.clone();
            reverse = Some(std::mem::replace(&mut forward, r));
        }
    }
    let mut orders = vec![SolvedOrder {
        objective,
        direction: Direction::Forward,
        nodes: set.nodes(mission, &forward),
        proof: Some(proof),
    }];
    if let Some(r) = reverse {
        orders.push(SolvedOrder {
            objective,
            direction: Direction::Reverse,
            nodes: set.nodes(mission, &r),
            proof: None,
        });
    }
    Ok(orders)
}

/// The sortie problem on stops: one node per stop (node `s + 1` is stop `s`), each block in
/// the way `way[s]` chosen for it; an arc into a stop costs the connecting leg and the stop's
/// inner cost, a stop's hover is its waypoints'.
pub struct Contracted {
    pub energy: CostMatrix,
    pub hover_j: Vec<f64>,
}

/// [`Contracted`] of `set` on the plan's `energy` matrix, `hover_j` per waypoint (file order).
pub fn contract(energy: &CostMatrix, set: &StopSet, way: &[usize], hover_j: &[f64]) -> Contracted {
    let ways: Vec<Way> = set
        .stops
        .iter()
        .zip(way)
        .map(|(s, &w)| s.ways[w.min(s.ways.len() - 1)])
        .collect();
    let n = ways.len() + 1;
    let matrix = CostMatrix::from_fn(n, |i, j| {
        if i == j {
            return 0.0;
        }
        let exit = if i == 0 { 0 } else { ways[i - 1].exit };
        match j {
            0 => energy.cost(exit, 0),
            _ => energy.cost(exit, ways[j - 1].entry) + ways[j - 1].inner,
        }
    });
    let hover = ways
        .iter()
        .map(|w| {
            let (a, b) = (w.entry.min(w.exit), w.entry.max(w.exit));
            (a..=b).map(|node| hover_j[node - 1]).sum()
        })
        .collect();
    Contracted {
        energy: matrix,
        hover_j: hover,
    }
}

/// What flying block `block` the other way would have added to a tour of `visits` on `m`
/// (connecting arcs and inner costs; J): None for a block flown only as written, or not in
/// the tour.
pub fn other_end_j(m: &CostMatrix, set: &StopSet, visits: &[Visit], block: usize) -> Option<f64> {
    let at = visits
        .iter()
        .position(|v| set.block[v.stop] == Some(block))?;
    if set.stops[visits[at].stop].ways.len() < 2 {
        return None;
    }
    let mut flipped = visits.to_vec();
    flipped[at].way = 1 - flipped[at].way;
    Some(clusters::tour_cost(m, &set.stops, &flipped) - clusters::tour_cost(m, &set.stops, visits))
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::mission::blocks::{Block, BlockKind};
    use crate::planner::json::plan_document;
    use crate::planner::{plan_mission, Leg, Order, Orders, Plan, PlanOptions};

    /// Three points (5 s hover) and two survey-like blocks of zero-hold waypoints, "north"
    /// (waypoints 2-5) and "south" (7-10), each a lawnmower of three lines written west to
    /// east: flown as written, the mission crosses the field three times; with one block
    /// reversed, twice.
    fn mission(reversible: bool) -> Mission {
        let mut text = String::from(
            "name = \"blocks\"\ndefault_hover_s = 5.0\nmin_height_above_home_m = 2.0\n\
             [origin]\nlat_deg = 38.5362\nlon_deg = -121.7875\nhome_alt_amsl_m = 16.0\n\
             height_above_home_m = 30.0\n",
        );
        let points: [(&str, f64, f64, f64, bool); 11] = [
            ("P1", 10.0, 15.0, 5.0, false),
            ("n1", -80.0, 40.0, 0.0, true),
            ("n2", -80.0, 50.0, 2.0, true),
            ("n3", 80.0, 50.0, 2.0, true),
            ("n4", 80.0, 40.0, 4.0, true),
            ("P2", -10.0, -15.0, -5.0, false),
            ("s1", -80.0, -40.0, 0.0, true),
            ("s2", -80.0, -50.0, -2.0, true),
            ("s3", 80.0, -50.0, -2.0, true),
            ("s4", 80.0, -40.0, -4.0, true),
            ("P3", 100.0, 0.0, 3.0, false),
        ];
        for (name, x, y, z, in_block) in points {
            text += &format!("[[waypoints]]\nname = \"{name}\"\nx_m = {x}\ny_m = {y}\nz_m = {z}\n");
            if in_block {
                text += "hover_s = 0.0\n";
            }
        }
        let mut m = crate::mission::load_str(&text, crate::mission::Format::Toml, None).unwrap();
        for (name, first, len) in [("north", 1, 4), ("south", 6, 4)] {
            m.blocks.push(Block {
                name: name.into(),
                kind: BlockKind::Survey,
                first,
                len,
                reversible,
                source: None,
            });
        }
        m
    }

    fn model(profile: Profile) -> VehicleModel {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000");
        VehicleModel::load(&dir, Some(profile)).unwrap()
    }

    fn plan(m: &Mission, model: &VehicleModel, orders: Orders) -> Plan {
        let options = PlanOptions {
            orders,
            ..PlanOptions::default()
        };
        plan_mission(m, model, &options).unwrap()
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0)
    }

    /// Every block of `order` is flown whole and contiguous, its lines carry the block, every
    /// other leg none, and the order's energy is the sum of its legs and turns.
    fn assert_blocks_whole(m: &Mission, order: &Order) {
        let mut seen = vec![false; m.blocks.len()];
        for f in &order.blocks {
            let b = &m.blocks[f.block];
            let at = order
                .nodes
                .iter()
                .position(|&n| n - 1 == b.entry(f.reversed))
                .unwrap();
            let flown: Vec<usize> = order.nodes[at..at + b.len].iter().map(|n| n - 1).collect();
            assert_eq!(flown, b.flown(f.reversed), "{}", b.name);
            seen[f.block] = true;
        }
        assert!(seen.iter().all(|&s| s), "every block flown");
        for leg in &order.legs {
            let inner = leg.from > 0
                && leg.to > 0
                && leg.from.abs_diff(leg.to) == 1
                && m.block_of(leg.from - 1).is_some()
                && m.block_of(leg.from - 1) == m.block_of(leg.to - 1);
            assert_eq!(leg.block.is_some(), inner, "{} -> {}", leg.from, leg.to);
        }
        let legs_j: f64 = order.legs.iter().map(Leg::energy_j).sum();
        assert!(close(order.energy_j, legs_j + order.actions_j));
        let mut sorted = order.nodes.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (1..=m.waypoints.len()).collect::<Vec<_>>());
    }

    /// The least cost over every order of the stops and every way of each block, by brute
    /// force on the plan's matrix and its blocks' priced ways.
    fn brute_force_j(m: &Mission, plan: &Plan) -> f64 {
        let set = StopSet::new(m, &[], |b, r| {
            plan.block_ways
                .get(b, r)
                .map_or(f64::INFINITY, |w| w.inner_j)
        });
        let n = set.stops.len();
        let mut best = f64::INFINITY;
        let mut order: Vec<usize> = (0..n).collect();
        let mut permute = |order: &[usize]| {
            let ways: Vec<usize> = order.iter().map(|&s| set.stops[s].ways.len()).collect();
            let choices: usize = ways.iter().product();
            for c in 0..choices {
                let mut rest = c;
                let visits: Vec<Visit> = order
                    .iter()
                    .zip(&ways)
                    .map(|(&stop, &k)| {
                        let way = rest % k;
                        rest /= k;
                        Visit { stop, way }
                    })
                    .collect();
                best = best.min(clusters::tour_cost(&plan.energy, &set.stops, &visits));
            }
        };
        heap_permutations(&mut order, n, &mut permute);
        best
    }

    fn heap_permutations(a: &mut Vec<usize>, k: usize, f: &mut impl FnMut(&[usize])) {
        if k <= 1 {
            f(a);
            return;
        }
        for i in 0..k {
            heap_permutations(a, k - 1, f);
            let j = if k.is_multiple_of(2) { i } else { 0 };
            a.swap(j, k - 1);
        }
    }

    #[test]
    fn the_energy_order_flies_each_block_whole_in_its_cheaper_direction_at_least_cost() {
        let m = mission(true);
        for profile in [Profile::Px4, Profile::Ptf, Profile::Ardupilot] {
            let plan = plan(&m, &model(profile), Orders::Energy);
            let order = plan.flown();
            assert_blocks_whole(&m, order);
            // The least of every order and direction (the turns are none here; the px4
            // profile's legs are priced after the turn into them, which the solve leaves out).
            let best = brute_force_j(&m, &plan);
            let proof = order.proof.as_ref().unwrap();
            assert!(proof.optimal && close(proof.lower_bound, best));
            if profile != Profile::Px4 {
                assert!(
                    close(order.energy_j, best),
                    "{profile:?}: {} vs {best}",
                    order.energy_j
                );
            } else {
                assert_eq!(plan.notes.len(), 1);
            }
            // One block reversed: the field crossed twice, not three times as the file flies.
            let reversed = order.blocks.iter().filter(|f| f.reversed).count();
            assert_eq!(reversed, 1, "{profile:?}");
            let file = plan_mission(
                &m,
                &model(profile),
                &PlanOptions {
                    orders: Orders::Listed,
                    ..PlanOptions::default()
                },
            )
            .unwrap();
            assert!(order.energy_j < 0.95 * file.flown().energy_j, "{profile:?}");
        }
    }

    #[test]
    fn a_block_is_priced_as_the_profile_flies_it_from_its_entry_to_its_exit() {
        let m = mission(true);
        for profile in [Profile::Px4, Profile::Ardupilot] {
            let model = model(profile);
            let plan = plan(&m, &model, Orders::Energy);
            let points = Geometry::from_mission(&m).points().to_vec();
            for (b, block) in m.blocks.iter().enumerate() {
                for reversed in [false, true] {
                    let nodes: Vec<usize> =
                        block.flown(reversed).into_iter().map(|k| k + 1).collect();
                    let way = plan.block_ways.get(b, reversed).unwrap();
                    let chain: Vec<Enu> = nodes[1..].iter().map(|&n| points[n]).collect();
                    // One chain, entry at rest to exit at rest, the lines between flown
                    // through (ArduCopter's fast waypoints).
                    let whole = detour::price_chain(
                        &model,
                        points[nodes[0]],
                        &chain[..chain.len() - 1],
                        chain[chain.len() - 1],
                        Start::Behind,
                    )
                    .unwrap();
                    let parts: f64 = way.legs.iter().map(|l| l.predicted.total_energy_j()).sum();
                    assert!(close(parts, whole.total_energy_j()), "{profile:?} {b}");
                    assert!(close(way.inner_j, parts));
                }
            }
            // The ardupilot profile flies the lines through: cheaper than rest to rest.
            if profile == Profile::Ardupilot {
                let way = plan.block_ways.get(0, false).unwrap();
                let rest_to_rest: f64 = way
                    .legs
                    .iter()
                    .map(|l| plan.energy.cost(l.from, l.to))
                    .sum();
                assert!(way.inner_j < rest_to_rest);
            }
        }
    }

    #[test]
    fn every_order_of_all_flies_blocks_whole_the_file_order_last_and_the_json_shows_them() {
        let m = mission(true);
        let plan = plan(&m, &model(Profile::Px4), Orders::All);
        // Energy, then each baseline both ways, then the file's order.
        assert_eq!(plan.orders.len(), 8);
        for order in &plan.orders {
            assert_blocks_whole(&m, order);
        }
        let file = plan.orders.last().unwrap();
        assert_eq!(file.objective, None);
        assert_eq!(file.nodes, (1..=m.waypoints.len()).collect::<Vec<_>>());
        assert!(file.blocks.iter().all(|f| !f.reversed));
        assert!(plan.flown().energy_j <= file.energy_j);
        for pair in plan.orders[1..7].chunks(2) {
            let (forward, reverse) = (&pair[0], &pair[1]);
            let mut back = forward.nodes.clone();
            back.reverse();
            assert_eq!(reverse.nodes, back);
            for f in &reverse.blocks {
                let there = forward.blocks.iter().find(|g| g.block == f.block).unwrap();
                assert_eq!(f.reversed, !there.reversed);
            }
        }
        let doc = serde_json::to_value(plan_document(&plan)).unwrap();
        let orders = doc["orders"].as_array().unwrap();
        assert_eq!(orders[7]["objective"], "file");
        assert_eq!(doc["blocks"][0]["name"], "north");
        assert_eq!(doc["blocks"][0]["waypoints"].as_array().unwrap().len(), 4);
        for (o, order) in orders.iter().zip(&plan.orders) {
            let blocks = o["blocks"].as_array().unwrap();
            assert_eq!(blocks.len(), 2);
            for (bj, f) in blocks.iter().zip(&order.blocks) {
                let b = &m.blocks[f.block];
                assert_eq!(bj["name"], b.name.as_str());
                assert_eq!(bj["reversed"], f.reversed);
                assert_eq!(bj["entry"], m.waypoints[b.entry(f.reversed)].name.as_str());
                let lines = o["legs"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .filter(|l| l["block"] == b.name.as_str());
                assert_eq!(lines.count(), b.len - 1);
            }
        }
        // The energy order says what entering each block at its other end would add.
        let energy_blocks = orders[0]["blocks"].as_array().unwrap();
        assert!(energy_blocks
            .iter()
            .all(|b| b["other_end_kj"].as_f64().unwrap() >= 0.0));
        assert!(orders[7]["blocks"][0].get("other_end_kj").is_none());
    }

    #[test]
    fn a_one_way_block_is_flown_only_as_written_and_its_baselines_one_way() {
        let m = mission(false);
        let plan = plan(&m, &model(Profile::Ptf), Orders::All);
        // Energy, each baseline forward only, the file's order.
        assert_eq!(plan.orders.len(), 5);
        for order in &plan.orders {
            assert_blocks_whole(&m, order);
            assert!(order.blocks.iter().all(|f| !f.reversed));
            assert!(order.direction == Direction::Forward);
        }
        assert!(plan.block_ways.get(0, true).is_none());
    }

    #[test]
    fn sorties_never_split_a_block_one_battery_can_fly() {
        let m = mission(true);
        let mut model = model(Profile::Ptf);
        let whole = plan(&m, &model, Orders::Energy).battery.total_j;
        // A battery of 60% of the mission: two or more sorties.
        model.vehicle.planning.usable_energy_wh =
            0.6 * whole / 3600.0 / (1.0 - model.vehicle.planning.reserve_pct / 100.0);
        let options = PlanOptions {
            orders: Orders::Energy,
            sorties: true,
            ..PlanOptions::default()
        };
        let plan = plan_mission(&m, &model, &options).unwrap();
        let sorties = plan.sorties.as_ref().unwrap();
        assert!(sorties.sorties.len() >= 2);
        assert!(plan.notes.is_empty());
        let mut all: Vec<usize> = Vec::new();
        for s in &sorties.sorties {
            assert!(s.battery.feasible);
            all.extend(&s.nodes);
            for (b, block) in m.blocks.iter().enumerate() {
                let inside = s
                    .nodes
                    .iter()
                    .filter(|&&n| m.block_of(n - 1) == Some(b))
                    .count();
                assert!(inside == 0 || inside == block.len, "{} split", block.name);
            }
            let lines = s.legs.iter().filter(|l| l.block.is_some()).count();
            let blocks = m
                .blocks
                .iter()
                .filter(|b| s.nodes.contains(&(b.first + 1)))
                .map(|b| b.len - 1)
                .sum::<usize>();
            assert_eq!(lines, blocks);
        }
        all.sort_unstable();
        assert_eq!(all, (1..=m.waypoints.len()).collect::<Vec<_>>());
    }

    #[test]
    fn a_block_one_battery_cannot_fly_is_split_among_the_sorties_and_named() {
        let m = mission(true);
        let mut model = model(Profile::Ptf);
        let plan = plan(&m, &model, Orders::Energy);
        let fixed_j = plan.budget.fixed_j();
        // A battery that flies out to any one waypoint and back, but not round the north
        // block.
        let alone_j = |k: usize| {
            fixed_j + plan.energy.cost(0, k + 1) + plan.energy.cost(k + 1, 0) + plan.hover_j(k)
        };
        let farthest_j = (0..m.waypoints.len()).map(alone_j).fold(0.0, f64::max);
        let north = &m.blocks[0];
        let north_j = fixed_j
            + plan.energy.cost(0, north.first + 1)
            + plan.block_ways.get(0, false).unwrap().inner_j
            + plan.energy.cost(north.first + north.len, 0);
        let usable_j = 1.05 * farthest_j;
        assert!(usable_j < north_j);
        let reserve = 1.0 - model.vehicle.planning.reserve_pct / 100.0;
        model.vehicle.planning.usable_energy_wh = usable_j / 3600.0 / reserve;
        let options = PlanOptions {
            orders: Orders::Energy,
            sorties: true,
            ..PlanOptions::default()
        };
        let plan = plan_mission(&m, &model, &options).unwrap();
        assert!(plan
            .notes
            .iter()
            .any(|n| n.contains("block north cannot be flown whole")));
        let mut all: Vec<usize> = plan
            .sorties
            .as_ref()
            .unwrap()
            .sorties
            .iter()
            .flat_map(|s| s.nodes.clone())
            .collect();
        all.sort_unstable();
        assert_eq!(all, (1..=m.waypoints.len()).collect::<Vec<_>>());
        let doc = serde_json::to_value(plan_document(&plan)).unwrap();
        assert!(doc["notes"][0].as_str().unwrap().contains("north"));
    }
}
