//! Where the minimum-energy order saves against the minimum-distance order flown in its cheaper
//! direction: the legs that differ, the climb avoided, how diagonal the climbs are, the steep
//! legs, and the costliest distance-order legs the energy order does without (the paper's
//! explanation, notes section 5: climbing is dear, so the energy order climbs less and more
//! diagonally).

use super::{Leg, Order};
use crate::tour::Direction;

/// How many of the distance order's dropped legs [`Saving::costliest_avoided`] lists.
const COSTLIEST: usize = 3;

/// A leg climbs more than this many times its horizontal length (at least 0.1 m) is steep.
const STEEP_RATIO: f64 = 2.0;

/// A leg climbing less than this does not count as a climb for the slope.
const CLIMB_MIN_M: f64 = 0.5;

/// The energy order's saving as a share of the distance order's energy, in percent: the one
/// convention every output states it in (0 when the distance order costs nothing).
pub fn saving_pct(energy_j: f64, distance_j: f64) -> f64 {
    if distance_j > 0.0 {
        100.0 * (distance_j - energy_j) / distance_j
    } else {
        0.0
    }
}

/// The saving as `emplan plan`'s text and its figure's title say it: "saves 16.20 kJ (23.9% of
/// the distance order's energy)".
pub fn saving_words(energy_j: f64, distance_j: f64) -> String {
    format!(
        "saves {:.2} kJ ({:.1}% of the distance order's energy)",
        (distance_j - energy_j) / 1000.0,
        saving_pct(energy_j, distance_j)
    )
}

/// The energy order against the distance order.
#[derive(Debug, Clone, PartialEq)]
pub struct Explanation {
    /// The direction of the distance order compared with (its cheaper one).
    pub distance_direction: Direction,
    /// `None` when the energy order costs no less: it is the distance order's.
    pub saving: Option<Saving>,
    /// The energy order's blocks in flown order: which end each is entered at, and what
    /// entering at the other end would have added (empty without blocks).
    pub blocks: Vec<BlockEntry>,
}

/// Which end the energy order enters a block at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockEntry {
    /// Index into the mission's blocks.
    pub block: usize,
    /// Entered at its last waypoint.
    pub reversed: bool,
    /// What flying it the other way, everything else as flown, would add (J; never negative
    /// when the order is proven optimal); None for a block flown only as written.
    pub other_end_j: Option<f64>,
}

/// Where the energy order saves; each pair is (energy order, distance order).
#[derive(Debug, Clone, PartialEq)]
pub struct Saving {
    pub saving_j: f64,
    /// Of the distance order's energy ([`saving_pct`]).
    pub saving_pct: f64,
    /// Legs of the energy order.
    pub legs: usize,
    /// Legs of the energy order the distance order does not fly.
    pub legs_differ: usize,
    /// How much further the energy order flies (3D).
    pub further_m: f64,
    /// Climbing, in all.
    pub climbed_m: (f64, f64),
    /// Horizontal metres flown per metre climbed, over the climbing legs (0 without climbs):
    /// how diagonal the climbs are.
    pub across_per_up: (f64, f64),
    /// Legs steeper than 2:1.
    pub steep_legs: (usize, usize),
    /// The distance order's costliest legs the energy order does not fly, dearest first.
    pub costliest_avoided: Vec<Leg>,
}

impl Explanation {
    /// Compares `energy` (the minimum-energy order) with `distance` (the minimum-distance order
    /// in its cheaper direction).
    pub fn of(energy: &Order, distance: &Order) -> Explanation {
        let (e, d) = (energy.energy_j, distance.energy_j);
        let saving = (d - e > 1e-9 * d.abs()).then(|| {
            let in_other = |l: &Leg, other: &Order| {
                other.legs.iter().any(|m| m.from == l.from && m.to == l.to)
            };
            let shared = energy.legs.iter().filter(|l| in_other(l, distance)).count();
            let mut dropped: Vec<Leg> = distance
                .legs
                .iter()
                .filter(|l| !in_other(l, energy))
                .cloned()
                .collect();
            dropped.sort_by(|a, b| b.energy_j().total_cmp(&a.energy_j()));
            dropped.truncate(COSTLIEST);
            Saving {
                saving_j: d - e,
                saving_pct: saving_pct(e, d),
                legs: energy.legs.len(),
                legs_differ: energy.legs.len() - shared,
                further_m: energy.distance_m - distance.distance_m,
                climbed_m: (climbed_m(energy), climbed_m(distance)),
                across_per_up: (across_per_up(energy), across_per_up(distance)),
                steep_legs: (steep_legs(energy), steep_legs(distance)),
                costliest_avoided: dropped,
            }
        });
        Explanation {
            distance_direction: distance.direction,
            saving,
            blocks: Vec::new(),
        }
    }
}

fn climbed_m(o: &Order) -> f64 {
    o.legs.iter().map(|l| l.vertical_m.max(0.0)).sum()
}

fn across_per_up(o: &Order) -> f64 {
    let climbs = o.legs.iter().filter(|l| l.vertical_m > CLIMB_MIN_M);
    let (x, z) = climbs.fold((0.0, 0.0), |(x, z), l| {
        (x + l.horizontal_m, z + l.vertical_m)
    });
    if z > 0.0 {
        x / z
    } else {
        0.0
    }
}

fn steep_legs(o: &Order) -> usize {
    o.legs
        .iter()
        .filter(|l| l.vertical_m.abs() > STEEP_RATIO * l.horizontal_m.max(0.1))
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::LegEnergy;
    use crate::tour::Objective;

    /// An order through points (x, z) on a line, each leg priced `energy_j` per metre climbed
    /// plus one per metre across.
    fn order(points: &[(f64, f64)], direction: Direction) -> Order {
        let all: Vec<(f64, f64)> = std::iter::once((0.0, 0.0))
            .chain(points.iter().copied())
            .chain(std::iter::once((0.0, 0.0)))
            .collect();
        let node = |k: usize| if k == 0 || k == all.len() - 1 { 0 } else { k };
        let legs: Vec<Leg> = all
            .windows(2)
            .enumerate()
            .map(|(k, w)| {
                let (x, z) = ((w[1].0 - w[0].0).abs(), w[1].1 - w[0].1);
                Leg {
                    from: node(k),
                    to: node(k + 1),
                    horizontal_m: x,
                    vertical_m: z,
                    distance_m: x.hypot(z),
                    predicted: LegEnergy {
                        energy_j: x + 10.0 * z.max(0.0),
                        duration_s: 1.0,
                        settle_energy_j: 0.0,
                        settle_duration_s: 0.0,
                    },
                    pricing: crate::physics::Pricing::Settled,
                    start: crate::physics::Start::Behind,
                    via: Vec::new(),
                    detour: None,
                    block: None,
                }
            })
            .collect();
        Order {
            objective: Some(Objective::Energy),
            direction,
            nodes: (1..=points.len()).collect(),
            distance_m: legs.iter().map(|l| l.distance_m).sum(),
            horizontal_m: legs.iter().map(|l| l.horizontal_m).sum(),
            vertical_m: legs.iter().map(|l| l.vertical_m.abs()).sum(),
            energy_j: legs.iter().map(Leg::energy_j).sum(),
            actions_j: 0.0,
            duration_s: legs.len() as f64,
            legs,
            proof: None,
            blocks: Vec::new(),
        }
    }

    #[test]
    fn the_same_order_has_nothing_to_gain() {
        let o = order(&[(10.0, 5.0), (20.0, 0.0)], Direction::Forward);
        let e = Explanation::of(&o, &o);
        assert_eq!(e.saving, None);
        assert_eq!(e.distance_direction, Direction::Forward);
    }

    #[test]
    fn a_cheaper_order_saves_the_energy_difference_and_names_the_dearest_dropped_leg() {
        let energy = order(&[(10.0, 2.0), (20.0, 0.0)], Direction::Forward);
        let mut distance = order(&[(1.0, 8.0), (20.0, 0.0)], Direction::Reverse);
        // Different waypoints, so every leg of the distance order is dropped.
        distance.legs.iter_mut().for_each(|l| {
            l.from += 10 * usize::from(l.from != 0);
            l.to += 10 * usize::from(l.to != 0);
        });
        let e = Explanation::of(&energy, &distance);
        let s = e.saving.expect("the energy order is cheaper");
        assert_eq!(e.distance_direction, Direction::Reverse);
        assert!((s.saving_j - (distance.energy_j - energy.energy_j)).abs() < 1e-12);
        assert_eq!((s.legs, s.legs_differ), (3, 3));
        assert_eq!(s.climbed_m, (2.0, 8.0));
        assert_eq!(s.across_per_up, (5.0, 1.0 / 8.0));
        assert_eq!(s.steep_legs, (0, 1));
        assert_eq!(s.costliest_avoided.len(), 3);
        assert_eq!(s.costliest_avoided[0].vertical_m, 8.0);
    }
}
