//! The paper's random-mission study, the one home of everything `emplan study` and `emplan
//! generate` compute: many random missions of N waypoints drawn uniformly in a box around the
//! origin (`random`); for each, the minimum-energy order and the three distance baselines (min 3D
//! distance, min horizontal, min vertical with ties broken by horizontal), each baseline flown in
//! its better direction or in the direction a solver returns without looking at energy
//! ([`BaselineDirection`]); then the energy increase of every baseline over the minimum-energy
//! order, summarised as mean, 90th percentile and maximum, and the share of missions whose
//! min-distance order differs from the energy order (`summary`, with the JSON view). `vehicle`
//! runs it with a vehicle's energy table.
//!
//! Pure and deterministic: mission `k` is drawn from its own stream `Rng::stream(seed, k)` and
//! the per-mission results are collected in mission order, so the study reproduces exactly from
//! its seed whatever the number of threads. [`run_study`] prices legs by a function passed in;
//! only `vehicle` knows the physics.

use std::fmt::Display;

use rayon::prelude::*;
use serde::Serialize;

use crate::tour::energy::energy_matrix;
use crate::tour::held_karp;
use crate::tour::orders::{solve_order, Objective};
use crate::tour::PlanError;

pub mod blocks;
mod random;
mod summary;
mod vehicle;
pub mod wind;

pub use random::{
    mission_geometry, random_mission, random_points, waypoint_name, Site, CLEARANCE_M,
    MAX_GENERATED_WAYPOINTS,
};
pub use summary::{study_document, MissionOutcome, Stats, StudyJson, Summary, Worst};
pub use vehicle::{check_envelope, run, StudyRun, StudyRunError};

/// Most missions one study runs (each keeps a small record for the statistics).
pub const MAX_MISSIONS: usize = 10_000_000;

/// The distance baselines, in the order the study reports them.
pub const BASELINES: [Objective; 3] = [
    Objective::Distance,
    Objective::Horizontal,
    Objective::Vertical,
];

/// Which direction of each baseline tour the study flies. A distance baseline is a symmetric
/// tour: a solver returns it in one direction, and the same tour flown backwards costs a
/// different energy (climbs become descents).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum BaselineDirection {
    /// The cheaper of the tour and its reverse: the fair comparison for a user.
    #[default]
    Better,
    /// The direction an energy-blind solver returns, made reproducible: the one whose first
    /// waypoint comes earlier in the mission file than its last (`emplan plan`'s "forward").
    Solver,
}

impl std::fmt::Display for BaselineDirection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            BaselineDirection::Better => "better",
            BaselineDirection::Solver => "solver",
        })
    }
}

/// One study setting: `waypoints` per mission, uniform in [-xy_m, xy_m]^2 horizontally and
/// [-z_m, z_m] vertically around the origin (0, 0, 0); `missions` missions from `seed`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StudySettings {
    pub waypoints: usize,
    pub xy_m: f64,
    pub z_m: f64,
    pub missions: usize,
    pub seed: u64,
}

/// The six settings (N, XY, Z) of the paper's study (the paper's Section on random missions).
pub const PAPER_SETTINGS: [(usize, f64, f64); 6] = [
    (6, 30.0, 25.0),
    (8, 20.0, 25.0),
    (8, 30.0, 25.0),
    (8, 40.0, 25.0),
    (8, 30.0, 15.0),
    (10, 30.0, 25.0),
];

impl StudySettings {
    /// The paper's six settings ([`PAPER_SETTINGS`]), each with `missions` missions from `seed`.
    pub fn paper(missions: usize, seed: u64) -> Vec<StudySettings> {
        PAPER_SETTINGS
            .iter()
            .map(|&(waypoints, xy_m, z_m)| StudySettings {
                waypoints,
                xy_m,
                z_m,
                missions,
                seed,
            })
            .collect()
    }

    /// Checks every setting; the error names the field at fault.
    pub fn validate(&self) -> Result<(), StudyError> {
        let bad = |setting: &'static str, value: String, problem: String| {
            Err(StudyError::Setting {
                setting,
                value,
                problem,
            })
        };
        if self.waypoints == 0 || self.waypoints > held_karp::MAX_NODES {
            return bad(
                "waypoints",
                self.waypoints.to_string(),
                format!(
                    "allowed: 1 to {} (the energy order is solved exactly)",
                    held_karp::MAX_NODES
                ),
            );
        }
        for (setting, value) in [("xy_m", self.xy_m), ("z_m", self.z_m)] {
            if !(value.is_finite() && value >= 0.0) {
                return bad(
                    setting,
                    value.to_string(),
                    "allowed: a finite half-width of 0 m or more".to_string(),
                );
            }
        }
        if self.missions == 0 || self.missions > MAX_MISSIONS {
            return bad(
                "missions",
                self.missions.to_string(),
                format!("allowed: 1 to {MAX_MISSIONS}"),
            );
        }
        Ok(())
    }

    /// The longest horizontal leg any mission can have: corner to opposite corner of the box.
    pub fn max_horizontal_leg_m(&self) -> f64 {
        2.0 * std::f64::consts::SQRT_2 * self.xy_m
    }

    /// The largest vertical displacement (climb or descent) any leg can have.
    pub fn max_vertical_leg_m(&self) -> f64 {
        2.0 * self.z_m
    }
}

/// A finished study: its settings, the baselines' direction, every mission's outcome (in mission
/// order) and the summary.
#[derive(Debug, Clone, PartialEq)]
pub struct Study {
    pub settings: StudySettings,
    pub direction: BaselineDirection,
    pub outcomes: Vec<MissionOutcome>,
    pub summary: Summary,
}

impl Study {
    /// The mission number with the largest increase of `baseline` (the first one on ties).
    pub fn worst_mission(&self, baseline: Objective) -> Option<u64> {
        let mut worst: Option<(usize, f64)> = None;
        for (k, o) in self.outcomes.iter().enumerate() {
            let inc = o.increase_pct(baseline);
            if worst.is_none_or(|(_, w)| inc > w) {
                worst = Some((k, inc));
            }
        }
        worst.map(|(k, _)| k as u64)
    }
}

/// Everything the study can refuse.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StudyError {
    #[error("{setting} = {value}: {problem}")]
    Setting {
        setting: &'static str,
        value: String,
        problem: String,
    },
    #[error(
        "mission {mission}: energy of leg {from} -> {to} (Xf {xf_m:.2} m, Zf {zf_m:.2} m): {reason}"
    )]
    LegEnergy {
        mission: u64,
        from: String,
        to: String,
        xf_m: f64,
        zf_m: f64,
        reason: String,
    },
    #[error("mission {mission}: {source}")]
    Plan {
        mission: u64,
        #[source]
        source: PlanError,
    },
}

/// A pricing or planning failure of mission `mission`, a leg's named as the leg's.
fn study_error(mission: u64, e: PlanError) -> StudyError {
    match e {
        PlanError::LegEnergy {
            from,
            to,
            xf_m,
            zf_m,
            reason,
        } => StudyError::LegEnergy {
            mission,
            from,
            to,
            xf_m,
            zf_m,
            reason,
        },
        source => StudyError::Plan { mission, source },
    }
}

fn node_name(node: usize) -> String {
    if node == 0 {
        "origin".to_string()
    } else {
        waypoint_name(node - 1)
    }
}

/// Runs mission `mission` of a study: draws its waypoints, prices every leg with
/// `leg_energy_j(xf_m, zf_m)` (joules, take-off hover to settled hover), solves the energy order
/// and the three baselines, and prices each baseline in `direction`.
pub fn run_mission<E: Display + Send>(
    settings: &StudySettings,
    mission: u64,
    direction: BaselineDirection,
    leg_energy_j: &(impl Fn(f64, f64) -> Result<f64, E> + Sync + ?Sized),
) -> Result<MissionOutcome, StudyError> {
    let geometry = mission_geometry(settings, mission);
    let names: Vec<String> = (0..geometry.len()).map(node_name).collect();
    let energy =
        energy_matrix(&geometry, &names, leg_energy_j).map_err(|e| study_error(mission, e))?;
    let plan_err = |source| StudyError::Plan { mission, source };
    let energy_order =
        solve_order(&geometry, Objective::Energy, Some(&energy)).map_err(plan_err)?;
    let mut flown = [0.0; 3];
    let mut distance_differs = true;
    for (slot, baseline) in flown.iter_mut().zip(BASELINES) {
        // The baselines come back in their forward direction (the solver's, made reproducible).
        let forward = solve_order(&geometry, baseline, None).map_err(plan_err)?;
        let reverse: Vec<usize> = forward.iter().rev().copied().collect();
        let (cost, differs) = match direction {
            BaselineDirection::Better => (
                energy.tour_cost(&forward).min(energy.tour_cost(&reverse)),
                energy_order != forward && energy_order != reverse,
            ),
            BaselineDirection::Solver => (energy.tour_cost(&forward), energy_order != forward),
        };
        *slot = cost;
        if baseline == Objective::Distance {
            distance_differs = differs;
        }
    }
    Ok(MissionOutcome {
        energy_j: energy.tour_cost(&energy_order),
        distance_j: flown[0],
        horizontal_j: flown[1],
        vertical_j: flown[2],
        distance_differs,
    })
}

/// Runs a whole study in parallel (rayon's current pool) and summarises it. `progress` is called
/// once per finished mission, from any thread. On failure the error is that of the lowest-numbered
/// failing mission, so errors reproduce too.
pub fn run_study<E: Display + Send>(
    settings: &StudySettings,
    direction: BaselineDirection,
    leg_energy_j: impl Fn(f64, f64) -> Result<f64, E> + Sync,
    progress: &(dyn Fn() + Sync),
) -> Result<Study, StudyError> {
    settings.validate()?;
    let results: Vec<Result<MissionOutcome, StudyError>> = (0..settings.missions as u64)
        .into_par_iter()
        .map(|k| {
            let outcome = run_mission(settings, k, direction, &leg_energy_j);
            progress();
            outcome
        })
        .collect();
    let outcomes = results.into_iter().collect::<Result<Vec<_>, _>>()?;
    let summary = Summary::of(&outcomes);
    Ok(Study {
        settings: *settings,
        direction,
        outcomes,
        summary,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(super) fn settings(waypoints: usize, missions: usize, seed: u64) -> StudySettings {
        StudySettings {
            waypoints,
            xy_m: 30.0,
            z_m: 25.0,
            missions,
            seed,
        }
    }

    /// Horizontal metres plus 8 J per metre climbed and 0.5 J per metre descended (x 100).
    fn climb_averse(xf_m: f64, zf_m: f64) -> Result<f64, std::convert::Infallible> {
        Ok(100.0 * (xf_m + 8.0 * zf_m.max(0.0) + 0.5 * (-zf_m).max(0.0)))
    }

    fn no_progress() {}

    /// Climbs priced by the square of their height: a closed tour climbs as much as it descends,
    /// so a cost linear in the climb would price a tour and its reverse alike.
    fn steep_climbs_dear(xf_m: f64, zf_m: f64) -> Result<f64, std::convert::Infallible> {
        Ok(100.0 * (xf_m + 0.5 * zf_m.max(0.0).powi(2) + 0.5 * (-zf_m).max(0.0)))
    }

    #[test]
    fn the_study_reproduces_from_its_seed_whatever_the_thread_count() {
        let s = settings(7, 60, 42);
        let one_thread = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| {
                run_study(&s, BaselineDirection::Better, climb_averse, &no_progress).unwrap()
            });
        let default = run_study(&s, BaselineDirection::Better, climb_averse, &no_progress).unwrap();
        let three_threads = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap()
            .install(|| {
                run_study(&s, BaselineDirection::Better, climb_averse, &no_progress).unwrap()
            });
        assert_eq!(one_thread, default);
        assert_eq!(one_thread, three_threads);
        let other_seed = run_study(
            &settings(7, 60, 43),
            BaselineDirection::Better,
            climb_averse,
            &no_progress,
        )
        .unwrap();
        assert_ne!(other_seed.summary, default.summary);
    }

    #[test]
    fn with_a_cost_proportional_to_distance_the_energy_order_is_the_distance_order() {
        let s = settings(8, 80, 5);
        let study = run_study(
            &s,
            BaselineDirection::Better,
            |x: f64, z: f64| Ok::<f64, String>(250.0 * x.hypot(z)),
            &no_progress,
        )
        .unwrap();
        let sum = study.summary;
        assert_eq!(sum.missions, 80);
        assert!(sum.distance.max_pct < 1e-9, "{sum:?}");
        assert_eq!(sum.distance_differs_pct, 0.0);
        // Nothing beats the order that minimises the very cost being paid.
        assert_eq!(sum.vertical_beats_distance_pct, 0.0);
        assert_eq!(sum.horizontal_beats_distance_pct, 0.0);
        assert!(sum.vertical.mean_pct > 0.0 && sum.horizontal.mean_pct > 0.0);
    }

    #[test]
    fn with_a_climb_averse_cost_the_increases_are_positive_and_ordered() {
        let study = run_study(
            &settings(8, 200, 9),
            BaselineDirection::Better,
            climb_averse,
            &no_progress,
        )
        .unwrap();
        let sum = study.summary;
        for stats in [sum.distance, sum.horizontal, sum.vertical] {
            assert!(stats.mean_pct > 0.0, "{sum:?}");
            assert!(stats.mean_pct <= stats.p90_pct && stats.p90_pct <= stats.max_pct);
        }
        assert!(sum.distance_differs_pct > 0.0 && sum.distance_differs_pct <= 100.0);
        // A mission whose min-distance order is the energy order has no increase.
        for o in &study.outcomes {
            if !o.distance_differs {
                assert!(o.increase_pct(Objective::Distance) < 1e-9);
            }
        }
        let worst = study.worst_mission(Objective::Distance).unwrap() as usize;
        assert_eq!(
            study.outcomes[worst].increase_pct(Objective::Distance),
            sum.distance.max_pct
        );
    }

    #[test]
    fn the_solver_direction_flies_the_forward_tour_and_the_better_one_the_cheaper_direction() {
        let s = settings(7, 120, 17);
        let run = |direction| run_study(&s, direction, steep_climbs_dear, &no_progress).unwrap();
        let (better, solver) = (
            run(BaselineDirection::Better),
            run(BaselineDirection::Solver),
        );
        assert_eq!(solver.direction, BaselineDirection::Solver);
        let mut dearer = 0;
        for (k, (b, f)) in better.outcomes.iter().zip(&solver.outcomes).enumerate() {
            assert_eq!(
                b.energy_j, f.energy_j,
                "mission {k}: the energy order is the same"
            );
            // Priced here from the mission's own geometry: the forward min-distance tour.
            let geometry = mission_geometry(&s, k as u64);
            let names: Vec<String> = (0..geometry.len()).map(node_name).collect();
            let energy = energy_matrix(&geometry, &names, steep_climbs_dear).unwrap();
            let forward = solve_order(&geometry, Objective::Distance, None).unwrap();
            let reverse: Vec<usize> = forward.iter().rev().copied().collect();
            assert!(forward.first() < forward.last(), "mission {k}: {forward:?}");
            assert_eq!(f.distance_j, energy.tour_cost(&forward), "mission {k}");
            assert_eq!(
                b.distance_j,
                energy.tour_cost(&forward).min(energy.tour_cost(&reverse)),
                "mission {k}"
            );
            if f.distance_j > b.distance_j * (1.0 + 1e-9) {
                dearer += 1;
                // Flown the dearer way round, the tour cannot be the energy order.
                assert!(f.distance_differs, "mission {k}");
            }
            assert!(f.distance_differs || !b.distance_differs, "mission {k}");
        }
        // The file order is blind to energy: about half the tours are the dearer way round.
        assert!((20..=100).contains(&dearer), "{dearer} of 120 dearer");
        assert!(solver.summary.distance.mean_pct > better.summary.distance.mean_pct);
        assert!(solver.summary.distance_differs_pct > better.summary.distance_differs_pct);
    }

    #[test]
    fn progress_is_reported_once_per_mission() {
        let done = std::sync::atomic::AtomicUsize::new(0);
        let count = || {
            done.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        };
        run_study(
            &settings(5, 37, 2),
            BaselineDirection::Better,
            climb_averse,
            &count,
        )
        .unwrap();
        assert_eq!(done.into_inner(), 37);
    }

    #[test]
    fn bad_settings_are_errors_naming_the_setting() {
        let err = |s: StudySettings| {
            run_study(&s, BaselineDirection::Better, climb_averse, &no_progress).unwrap_err()
        };
        let zero = err(settings(0, 10, 1));
        assert!(
            matches!(
                zero,
                StudyError::Setting {
                    setting: "waypoints",
                    ..
                }
            ),
            "{zero}"
        );
        let negative = err(StudySettings {
            xy_m: -1.0,
            ..settings(5, 10, 1)
        });
        assert_eq!(
            negative.to_string(),
            "xy_m = -1: allowed: a finite half-width of 0 m or more"
        );
        let none = err(settings(5, 0, 1));
        assert!(none.to_string().starts_with("missions = 0"), "{none}");
    }

    #[test]
    fn a_leg_outside_the_model_is_an_error_naming_the_mission_and_leg() {
        let s = settings(6, 40, 11);
        let capped = |x: f64, z: f64| {
            if z > 45.0 {
                Err("outside the table")
            } else {
                Ok(x + z.abs())
            }
        };
        let e = run_study(&s, BaselineDirection::Better, capped, &no_progress).unwrap_err();
        let StudyError::LegEnergy { mission, zf_m, .. } = &e else {
            panic!("unexpected error {e}");
        };
        assert!(*zf_m > 45.0);
        // The lowest-numbered failing mission is reported, and it really fails.
        assert!(run_mission(&s, *mission, BaselineDirection::Better, &capped).is_err());
        for k in 0..*mission {
            assert!(run_mission(&s, k, BaselineDirection::Better, &capped).is_ok());
        }
        assert!(e
            .to_string()
            .starts_with(&format!("mission {mission}: energy of leg ")));
    }
}
