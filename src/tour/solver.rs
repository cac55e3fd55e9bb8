//! Solver selection for the asymmetric TSP through the origin: Held-Karp for small tours,
//! branch-and-cut (started from the heuristic's tour) up to a few hundred nodes, and the
//! iterated local search with the DFJ LP lower bound ([`bound::dfj_bound`]) beyond. Every
//! answer carries a proven lower bound; `optimal` is set only when the bound meets the tour.

use std::time::{Duration, Instant};

use serde::Serialize;

use super::progress::{self, Event};
use super::{bound, branch_cut, held_karp, heuristic, CostMatrix, PlanError, Tour};

/// Which solver to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Solver {
    /// Chosen by size: Held-Karp, then branch-and-cut, then the heuristic.
    Auto,
    /// Held-Karp dynamic programming (at most [`held_karp::MAX_NODES`] waypoints).
    HeldKarp,
    /// Branch-and-cut from the heuristic's tour.
    BranchCut,
    /// Iterated local search with the DFJ LP lower bound (at worst the assignment bound).
    Heuristic,
}

impl std::fmt::Display for Solver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Solver::Auto => "auto",
            Solver::HeldKarp => "held-karp",
            Solver::BranchCut => "branch-cut",
            Solver::Heuristic => "heuristic",
        })
    }
}

impl std::str::FromStr for Solver {
    type Err = crate::names::UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        crate::names::choose(
            "solver",
            s,
            &[
                ("auto", Solver::Auto),
                ("held-karp", Solver::HeldKarp),
                ("branch-cut", Solver::BranchCut),
                ("heuristic", Solver::Heuristic),
            ],
        )
    }
}

/// How to solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    pub solver: Solver,
    /// Wall-clock budget of the whole solve; a run cut short returns its best tour and bound.
    pub time_limit: Duration,
    /// Seed of the heuristic's kicks.
    pub seed: u64,
    /// The heuristic's kick budget (`None`: its default for the size). With a budget the
    /// heuristic is reproducible whatever the machine, unless the time limit stops it first.
    pub kicks: Option<u64>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            solver: Solver::Auto,
            time_limit: Duration::from_secs(60),
            seed: 1,
            kicks: None,
        }
    }
}

/// Waypoints (non-origin nodes) up to which `auto` runs Held-Karp: 2^12 x 12 states, well
/// under a millisecond, so the study's thousands of missions stay fast.
pub const AUTO_HELD_KARP_MAX: usize = 12;
/// Nodes up to which `auto` runs branch-and-cut after the heuristic. Beyond, the LP over the
/// arcs that survive reduced-cost elimination grows too large for microlp in minutes.
pub const AUTO_BRANCH_CUT_MAX_NODES: usize = 500;
/// Share of the time limit the heuristic may take before branch-and-cut.
const HEURISTIC_SHARE: f64 = 0.3;
/// Share of the time limit the heuristic may take before the DFJ lower bound
/// ([`bound::dfj_bound`]), which gets whatever the heuristic leaves. At 1000 nodes the bound's
/// first round takes 10-15 s and the heuristic's tour barely moves after 10 s, so a 30 s
/// limit splits 12 s / 18 s; a bound that converges early leaves the rest unused.
const HEURISTIC_SHARE_BEFORE_BOUND: f64 = 0.4;

/// A solved tour and how it was found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Solved {
    #[serde(skip)]
    pub tour: Tour,
    /// The solver that produced the answer (`auto` resolved).
    pub solver: Solver,
    /// The heuristic tour's cost, when the heuristic ran.
    pub heuristic_cost: Option<f64>,
    /// Branch-and-bound nodes, when branch-and-cut ran.
    pub nodes: Option<u64>,
    /// Relative gap between the tour and its lower bound (0 when optimal).
    pub gap_pct: f64,
    pub seconds: f64,
}

/// Solves the tour of `m` (node 0 = origin) as `options` ask.
pub fn solve(m: &CostMatrix, options: &Options) -> Result<Solved, PlanError> {
    let started = Instant::now();
    // Never past the thread's cancel token's deadline (see `cancel`).
    let options = &Options {
        time_limit: super::cancel::limit(options.time_limit),
        ..*options
    };
    let waypoints = m.len().saturating_sub(1);
    let solver = match options.solver {
        Solver::Auto if waypoints <= AUTO_HELD_KARP_MAX => Solver::HeldKarp,
        Solver::Auto if m.len() <= AUTO_BRANCH_CUT_MAX_NODES => Solver::BranchCut,
        Solver::Auto => Solver::Heuristic,
        chosen => chosen,
    };
    let finish = |tour: Tour, heuristic_cost, nodes| {
        let gap_pct = if tour.optimal || tour.cost == 0.0 {
            0.0
        } else {
            100.0 * (tour.cost - tour.lower_bound) / tour.cost.abs()
        };
        Solved {
            tour,
            solver,
            heuristic_cost,
            nodes,
            gap_pct,
            seconds: started.elapsed().as_secs_f64(),
        }
    };
    match solver {
        Solver::HeldKarp => {
            progress::report(Event::Phase("Held-Karp"));
            Ok(finish(held_karp::solve(m)?, None, None))
        }
        Solver::BranchCut => {
            let ils = run_heuristic(m, options, options.time_limit.mul_f64(HEURISTIC_SHARE))?;
            let left = options.time_limit.saturating_sub(started.elapsed());
            progress::report(Event::Phase("branch-and-cut"));
            let out = branch_cut::solve(
                m,
                &ils.order,
                &branch_cut::Options {
                    time_limit: left,
                    ..Default::default()
                },
            )?;
            Ok(finish(out.tour, Some(ils.cost), Some(out.nodes)))
        }
        Solver::Heuristic | Solver::Auto => {
            let ils = run_heuristic(
                m,
                options,
                options.time_limit.mul_f64(HEURISTIC_SHARE_BEFORE_BOUND),
            )?;
            // The DFJ bound always includes the assignment bound, even with no time left.
            let left = options.time_limit.saturating_sub(started.elapsed());
            progress::report(Event::Phase("lower bound"));
            let proof = bound::dfj_bound(m, &ils.order, left)?;
            progress::report(Event::Bound(proof.lower_bound.max(proof.assignment_bound)));
            tracing::info!(
                lower_bound = proof.lower_bound,
                assignment_bound = proof.assignment_bound,
                cuts = proof.cuts,
                arcs = proof.arcs,
                rounds = proof.rounds,
                stop = ?proof.stop,
                seconds = proof.seconds,
                "dfj lower bound"
            );
            let lower_bound = proof.lower_bound.max(proof.assignment_bound).min(ils.cost);
            let optimal = lower_bound >= ils.cost;
            let tour = Tour {
                order: ils.order,
                cost: ils.cost,
                lower_bound,
                optimal,
            };
            Ok(finish(tour, Some(ils.cost), None))
        }
    }
}

fn run_heuristic(
    m: &CostMatrix,
    options: &Options,
    budget: Duration,
) -> Result<heuristic::Outcome, PlanError> {
    progress::report(Event::Phase("heuristic"));
    m.check_finite()?;
    Ok(heuristic::solve(
        m,
        None,
        &heuristic::Options {
            seed: options.seed,
            time_limit_s: budget.as_secs_f64(),
            max_kicks: options.kicks,
            ..Default::default()
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tour::testing::drone;

    #[test]
    fn every_solver_agrees_with_held_karp_on_random_missions_up_to_fifteen_waypoints() {
        for (k, n) in (5..=16).enumerate() {
            let m = drone(n, k as u64);
            let exact = held_karp::solve(&m).unwrap();
            for solver in [Solver::Auto, Solver::BranchCut] {
                let out = solve(
                    &m,
                    &Options {
                        solver,
                        ..Default::default()
                    },
                )
                .unwrap();
                assert!(out.tour.optimal, "{solver} n={n}");
                assert!((out.tour.cost - exact.cost).abs() <= 1e-6 * exact.cost);
            }
            let ils = solve(
                &m,
                &Options {
                    solver: Solver::Heuristic,
                    ..Default::default()
                },
            )
            .unwrap();
            assert!(ils.tour.lower_bound <= exact.cost + 1e-9);
            assert!(ils.tour.cost >= exact.cost - 1e-9);
        }
    }

    #[test]
    fn auto_picks_held_karp_when_small_and_branch_and_cut_above() {
        let small = solve(&drone(10, 1), &Options::default()).unwrap();
        assert_eq!(small.solver, Solver::HeldKarp);
        let medium = solve(&drone(30, 1), &Options::default()).unwrap();
        assert_eq!(medium.solver, Solver::BranchCut);
        assert!(medium.tour.optimal);
        assert_eq!(medium.gap_pct, 0.0);
    }

    #[test]
    fn held_karp_forced_beyond_its_size_is_a_typed_error() {
        let out = solve(
            &drone(25, 1),
            &Options {
                solver: Solver::HeldKarp,
                ..Default::default()
            },
        );
        assert!(matches!(out, Err(PlanError::TooManyForHeldKarp { .. })));
    }

    #[test]
    fn solver_names_round_trip() {
        for s in [
            Solver::Auto,
            Solver::HeldKarp,
            Solver::BranchCut,
            Solver::Heuristic,
        ] {
            assert_eq!(s.to_string().parse::<Solver>(), Ok(s));
        }
        assert!("simplex".parse::<Solver>().is_err());
    }
}
