//! Splitting a mission one battery cannot fly into sorties: each sortie is a closed tour
//! origin -> its waypoints -> origin flown on a fresh battery, and its energy (take-off and
//! landing, legs, hovering at its waypoints) must fit the battery's budget. The split minimises
//! the total energy over all sorties, with as many batteries as needed: the distance-constrained
//! vehicle routing problem (Laporte, Desrochers and Nobert 1984, "Two exact algorithms for the
//! distance-constrained vehicle routing problem", Networks 14) with asymmetric leg costs, an
//! unlimited fleet and a fixed cost per route.
//!
//! Pure: no IO. Energies in joules; node 0 of the matrix is the origin, waypoint k is node k.
//!
//! `exact.rs` splits exactly (set partition over Held-Karp subset tours), `heuristic.rs` beyond
//! (Prins' split of a giant tour plus local search); this file holds the problem, the answer and
//! the checks both share.

use serde::Serialize;

use super::CostMatrix;

mod exact;
mod heuristic;

pub use exact::exact;
pub use heuristic::heuristic;

/// Default largest number of waypoints split exactly. Measured on random 3-5 sortie instances
/// (release, one core of a shared 2-core machine): 12 waypoints take 2-10 ms, 14 take 16-21 ms,
/// 16 take 0.09-0.14 s, 18 take 0.5-0.7 s.
pub const EXACT_MAX_WAYPOINTS: usize = 16;

/// Hard cap of the exact method: its tables take 2^N (N + 2) words (18: 50 MB).
pub const EXACT_LIMIT: usize = 18;

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

#[cfg(test)]
pub(super) mod testing {
    //! Random sortie instances and a brute-force oracle for the tests of both methods.

    use super::*;
    use crate::rng::Rng;

    /// A random instance: waypoints in a 300 m x 300 m x 60 m box, legs priced like a
    /// multirotor (climbing dear, descending cheap, a fixed cost per stop), so asymmetric;
    /// hovers of 0-120 s at 640 W; a budget between the dearest lone waypoint and a single tour.
    pub struct Instance {
        pub energy: CostMatrix,
        pub hover_j: Vec<f64>,
        pub fixed_j: f64,
        pub budget_j: f64,
    }

    impl Instance {
        pub fn problem(&self) -> SortieProblem<'_> {
            SortieProblem {
                energy: &self.energy,
                hover_j: &self.hover_j,
                fixed_j: self.fixed_j,
                budget_j: self.budget_j,
            }
        }
    }

    /// `budget_factor`: the budget's range as multiples of the dearest lone waypoint.
    pub fn instance(rng: &mut Rng, waypoints: usize, budget_factor: (f64, f64)) -> Instance {
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
    pub fn brute_force_j(inst: &Instance) -> f64 {
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

    pub fn assert_valid(inst: &Instance, plan: &SortiePlan) {
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

    pub fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::testing::*;
    use super::*;
    use crate::rng::Rng;
    use crate::tour::held_karp;

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
