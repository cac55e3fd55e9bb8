//! The paper's random-mission study (shared/paper/NOTES.md section 4): many random missions of
//! N waypoints drawn uniformly in a box around the origin; for each, the minimum-energy order
//! and the three distance baselines (min 3D distance, min horizontal, min vertical with ties
//! broken by horizontal), each baseline flown in its better direction; then the energy increase
//! of every baseline over the minimum-energy order, summarised as mean, 90th percentile and
//! maximum, and the share of missions whose min-distance order differs from the energy order.
//!
//! Pure and deterministic: mission `k` is drawn from its own stream `Rng::stream(seed, k)` and
//! the per-mission results are collected in mission order, so the study reproduces exactly from
//! its seed whatever the number of threads. Legs are priced by a function passed in, so this
//! module knows nothing of the physics.

use std::fmt::Display;

use rayon::prelude::*;
use serde::Serialize;

use super::energy::energy_matrix;
use super::held_karp;
use super::orders::{solve_order, Objective};
use super::{Geometry, PlanError};
use crate::mission::{Enu, Geodetic, Mission, Origin, Waypoint};
use crate::rng::Rng;

/// Most missions one study runs (each keeps a small record for the statistics).
pub const MAX_MISSIONS: usize = 10_000_000;

/// The distance baselines, in the order the study reports them.
pub const BASELINES: [Objective; 3] = [
    Objective::Distance,
    Objective::Horizontal,
    Objective::Vertical,
];

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

/// The six settings (N, XY, Z) of the paper's study (NOTES.md section 4).
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

/// Name of waypoint `k` (0-based) of a random mission: `W1`, `W2`, ... (node 0 is `origin`).
pub fn waypoint_name(k: usize) -> String {
    format!("W{}", k + 1)
}

/// The waypoints (origin excluded) of random mission `mission` of a setting: each uniform in
/// [-xy_m, xy_m) x [-xy_m, xy_m) x [-z_m, z_m), drawn x, y, z in turn from
/// `Rng::stream(seed, mission)`. `settings.missions` is not used, so any mission number can be
/// regenerated on its own.
pub fn random_points(settings: &StudySettings, mission: u64) -> Vec<Enu> {
    let mut rng = Rng::stream(settings.seed, mission);
    let (xy, z) = (settings.xy_m, settings.z_m);
    (0..settings.waypoints)
        .map(|_| {
            let x_east_m = rng.uniform(-xy, xy);
            let y_north_m = rng.uniform(-xy, xy);
            let z_up_m = rng.uniform(-z, z);
            Enu {
                x_east_m,
                y_north_m,
                z_up_m,
            }
        })
        .collect()
}

/// Most waypoints one generated mission may have.
pub const MAX_GENERATED_WAYPOINTS: usize = 1_000_000;

/// How far the origin of a generated mission hovers above its lowest possible waypoint: the
/// origin's height above home is Z + this, so every waypoint is at least this high above home
/// (the mission minimum is 2 m).
pub const CLEARANCE_M: f64 = 5.0;

/// Where a generated mission flies from, and how it hovers.
#[derive(Debug, Clone, PartialEq)]
pub struct Site {
    /// Home: latitude, longitude and altitude above mean sea level.
    pub home: Geodetic,
    /// Hover time at every waypoint.
    pub hover_s: f64,
    /// The mission's name (default: `random-N-XY-Z-sS-K`).
    pub name: Option<String>,
}

/// Mission `mission` of the study `settings` as a mission file would hold it: waypoints W1..WN
/// in local x/y/z around an origin `Z + CLEARANCE_M` above `site.home`. Up to
/// [`MAX_GENERATED_WAYPOINTS`] waypoints (`settings.missions` is not used); errors name the
/// setting (`waypoints`, `xy_m`, `z_m`, `lat_deg`, `lon_deg`, `home_alt_amsl_m`, `hover_s`).
pub fn random_mission(
    settings: &StudySettings,
    mission: u64,
    site: &Site,
) -> Result<Mission, StudyError> {
    let bad = |setting: &'static str, value: String, problem: &str| {
        Err(StudyError::Setting {
            setting,
            value,
            problem: problem.to_string(),
        })
    };
    if settings.waypoints == 0 || settings.waypoints > MAX_GENERATED_WAYPOINTS {
        return bad(
            "waypoints",
            settings.waypoints.to_string(),
            &format!("allowed: 1 to {MAX_GENERATED_WAYPOINTS}"),
        );
    }
    for (setting, value) in [("xy_m", settings.xy_m), ("z_m", settings.z_m)] {
        if !(value.is_finite() && value >= 0.0) {
            return bad(
                setting,
                value.to_string(),
                "allowed: a finite half-width of 0 m or more",
            );
        }
    }
    let home = site.home;
    if !(home.lat_deg.is_finite() && (-90.0..=90.0).contains(&home.lat_deg)) {
        return bad("lat_deg", home.lat_deg.to_string(), "allowed: -90 to 90");
    }
    if !(home.lon_deg.is_finite() && (-180.0..=180.0).contains(&home.lon_deg)) {
        return bad("lon_deg", home.lon_deg.to_string(), "allowed: -180 to 180");
    }
    if !home.alt_m.is_finite() {
        return bad(
            "home_alt_amsl_m",
            home.alt_m.to_string(),
            "a finite altitude is required",
        );
    }
    if !(site.hover_s.is_finite() && site.hover_s >= 0.0) {
        return bad("hover_s", site.hover_s.to_string(), "allowed: 0 s or more");
    }
    let name = site.name.clone().unwrap_or_else(|| {
        format!(
            "random-{}-{}-{}-s{}-{}",
            settings.waypoints, settings.xy_m, settings.z_m, settings.seed, mission
        )
    });
    Ok(Mission {
        name,
        origin: Origin {
            home,
            height_above_home_m: settings.z_m + CLEARANCE_M,
        },
        waypoints: random_points(settings, mission)
            .into_iter()
            .enumerate()
            .map(|(k, position)| Waypoint {
                name: waypoint_name(k),
                position,
                hover_s: site.hover_s,
            })
            .collect(),
        default_hover_s: site.hover_s,
        min_height_above_home_m: crate::mission::DEFAULT_MIN_HEIGHT_ABOVE_HOME_M,
        source: None,
    })
}

/// Mission `mission` of a study as legs: the origin (node 0) and its random waypoints.
pub fn mission_geometry(settings: &StudySettings, mission: u64) -> Geometry {
    Geometry::from_points(
        std::iter::once(Enu::default())
            .chain(random_points(settings, mission))
            .collect(),
    )
}

/// What one mission of the study found. Energies are whole tours (origin to origin), each
/// baseline in its better direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissionOutcome {
    pub energy_j: f64,
    pub distance_j: f64,
    pub horizontal_j: f64,
    pub vertical_j: f64,
    /// The min-distance tour, in neither direction, is the minimum-energy order.
    pub distance_differs: bool,
}

impl MissionOutcome {
    /// Tour energy of an objective's order (a baseline's better direction).
    pub fn energy_of(&self, objective: Objective) -> f64 {
        match objective {
            Objective::Energy => self.energy_j,
            Objective::Distance => self.distance_j,
            Objective::Horizontal => self.horizontal_j,
            Objective::Vertical => self.vertical_j,
        }
    }

    /// Energy increase of a baseline over the minimum-energy order, in percent (>= 0).
    pub fn increase_pct(&self, baseline: Objective) -> f64 {
        // Held-Karp is exact, so a baseline never truly beats the energy order; a negative
        // difference can only be summation rounding (the same legs added in another order).
        (100.0 * (self.energy_of(baseline) - self.energy_j) / self.energy_j).max(0.0)
    }

    /// Baseline energy over minimum energy (>= 1).
    pub fn ratio(&self, baseline: Objective) -> f64 {
        1.0 + self.increase_pct(baseline) / 100.0
    }

    /// Whether `baseline`'s better direction needs strictly less energy than min-distance's
    /// (by more than a relative 1e-9, so the same tour found twice is not a win).
    pub fn beats_distance(&self, baseline: Objective) -> bool {
        self.energy_of(baseline) < self.distance_j * (1.0 - 1e-9)
    }
}

/// Mean, 90th percentile and maximum of one baseline's increase over the minimum-energy order
/// (the STATS object of DESIGN.md). The percentile is the nearest-rank one: the
/// ceil(0.9 K)-th smallest of the K increases, an increase some mission actually had.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Stats {
    pub mean_pct: f64,
    pub p90_pct: f64,
    pub max_pct: f64,
}

impl Stats {
    /// Statistics of `values` (not empty; the order does not matter).
    pub fn of(values: &[f64]) -> Stats {
        if values.is_empty() {
            return Stats {
                mean_pct: 0.0,
                p90_pct: 0.0,
                max_pct: 0.0,
            };
        }
        let mean_pct = values.iter().sum::<f64>() / values.len() as f64;
        let mut sorted = values.to_vec();
        sorted.sort_by(f64::total_cmp);
        let rank = (0.9 * sorted.len() as f64).ceil() as usize;
        Stats {
            mean_pct,
            p90_pct: sorted[rank.clamp(1, sorted.len()) - 1],
            max_pct: sorted[sorted.len() - 1],
        }
    }
}

/// The study's summary: the JSON document of DESIGN.md (`emplan study --json`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Summary {
    pub missions: usize,
    pub distance: Stats,
    pub horizontal: Stats,
    pub vertical: Stats,
    pub distance_differs_pct: f64,
    pub vertical_beats_distance_pct: f64,
    pub horizontal_beats_distance_pct: f64,
}

impl Summary {
    /// Aggregates per-mission outcomes.
    pub fn of(outcomes: &[MissionOutcome]) -> Summary {
        let stats = |baseline: Objective| {
            let values: Vec<f64> = outcomes.iter().map(|o| o.increase_pct(baseline)).collect();
            Stats::of(&values)
        };
        let share = |pred: &dyn Fn(&MissionOutcome) -> bool| {
            let count = outcomes.iter().filter(|o| pred(o)).count();
            100.0 * count as f64 / outcomes.len().max(1) as f64
        };
        Summary {
            missions: outcomes.len(),
            distance: stats(Objective::Distance),
            horizontal: stats(Objective::Horizontal),
            vertical: stats(Objective::Vertical),
            distance_differs_pct: share(&|o| o.distance_differs),
            vertical_beats_distance_pct: share(&|o| o.beats_distance(Objective::Vertical)),
            horizontal_beats_distance_pct: share(&|o| o.beats_distance(Objective::Horizontal)),
        }
    }
}

/// A finished study: its settings, every mission's outcome (in mission order) and the summary.
#[derive(Debug, Clone, PartialEq)]
pub struct Study {
    pub settings: StudySettings,
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

fn node_name(node: usize) -> String {
    if node == 0 {
        "origin".to_string()
    } else {
        waypoint_name(node - 1)
    }
}

/// Runs mission `mission` of a study: draws its waypoints, prices every leg with
/// `leg_energy_j(xf_m, zf_m)` (joules, take-off hover to settled hover), solves the energy order
/// and the three baselines, and prices both directions of each baseline.
pub fn run_mission<E: Display>(
    settings: &StudySettings,
    mission: u64,
    leg_energy_j: &(impl Fn(f64, f64) -> Result<f64, E> + ?Sized),
) -> Result<MissionOutcome, StudyError> {
    let geometry = mission_geometry(settings, mission);
    let names: Vec<String> = (0..geometry.len()).map(node_name).collect();
    let energy = energy_matrix(&geometry, &names, leg_energy_j).map_err(|e| match e {
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
    })?;
    let plan_err = |source| StudyError::Plan { mission, source };
    let energy_order =
        solve_order(&geometry, Objective::Energy, Some(&energy)).map_err(plan_err)?;
    let mut better = [0.0; 3];
    let mut distance_differs = true;
    for (slot, baseline) in better.iter_mut().zip(BASELINES) {
        let forward = solve_order(&geometry, baseline, None).map_err(plan_err)?;
        let reverse: Vec<usize> = forward.iter().rev().copied().collect();
        *slot = energy.tour_cost(&forward).min(energy.tour_cost(&reverse));
        if baseline == Objective::Distance {
            distance_differs = energy_order != forward && energy_order != reverse;
        }
    }
    Ok(MissionOutcome {
        energy_j: energy.tour_cost(&energy_order),
        distance_j: better[0],
        horizontal_j: better[1],
        vertical_j: better[2],
        distance_differs,
    })
}

/// Runs a whole study in parallel (rayon's current pool) and summarises it. `progress` is called
/// once per finished mission, from any thread. On failure the error is that of the lowest-numbered
/// failing mission, so errors reproduce too.
pub fn run_study<E: Display>(
    settings: &StudySettings,
    leg_energy_j: impl Fn(f64, f64) -> Result<f64, E> + Sync,
    progress: &(dyn Fn() + Sync),
) -> Result<Study, StudyError> {
    settings.validate()?;
    let results: Vec<Result<MissionOutcome, StudyError>> = (0..settings.missions as u64)
        .into_par_iter()
        .map(|k| {
            let outcome = run_mission(settings, k, &leg_energy_j);
            progress();
            outcome
        })
        .collect();
    let outcomes = results.into_iter().collect::<Result<Vec<_>, _>>()?;
    let summary = Summary::of(&outcomes);
    Ok(Study {
        settings: *settings,
        outcomes,
        summary,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(waypoints: usize, missions: usize, seed: u64) -> StudySettings {
        StudySettings {
            waypoints,
            xy_m: 30.0,
            z_m: 25.0,
            missions,
            seed,
        }
    }

    /// Horizontal metres plus 8 J per metre climbed and 0.5 J per metre descended (x 100).
    fn climb_averse(xf_m: f64, zf_m: f64) -> Result<f64, String> {
        Ok(100.0 * (xf_m + 8.0 * zf_m.max(0.0) + 0.5 * (-zf_m).max(0.0)))
    }

    fn no_progress() {}

    #[test]
    fn the_study_reproduces_from_its_seed_whatever_the_thread_count() {
        let s = settings(7, 60, 42);
        let one_thread = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| run_study(&s, climb_averse, &no_progress).unwrap());
        let default = run_study(&s, climb_averse, &no_progress).unwrap();
        let three_threads = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap()
            .install(|| run_study(&s, climb_averse, &no_progress).unwrap());
        assert_eq!(one_thread, default);
        assert_eq!(one_thread, three_threads);
        let other_seed = run_study(&settings(7, 60, 43), climb_averse, &no_progress).unwrap();
        assert_ne!(other_seed.summary, default.summary);
    }

    #[test]
    fn with_a_cost_proportional_to_distance_the_energy_order_is_the_distance_order() {
        let s = settings(8, 80, 5);
        let study = run_study(
            &s,
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
        let study = run_study(&settings(8, 200, 9), climb_averse, &no_progress).unwrap();
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
    fn random_points_stay_inside_the_box_and_fill_it() {
        let s = StudySettings {
            waypoints: 500,
            xy_m: 40.0,
            z_m: 15.0,
            missions: 1,
            seed: 3,
        };
        let points = random_points(&s, 7);
        assert_eq!(points.len(), 500);
        for p in &points {
            assert!(p.x_east_m.abs() <= 40.0 && p.y_north_m.abs() <= 40.0);
            assert!(p.z_up_m.abs() <= 15.0);
        }
        let max_z = points.iter().map(|p| p.z_up_m).fold(f64::MIN, f64::max);
        let min_x = points.iter().map(|p| p.x_east_m).fold(f64::MAX, f64::min);
        assert!(max_z > 14.0 && min_x < -38.0);
        assert_eq!(points, random_points(&s, 7));
        assert_ne!(points, random_points(&s, 8));
    }

    #[test]
    fn progress_is_reported_once_per_mission() {
        let done = std::sync::atomic::AtomicUsize::new(0);
        let count = || {
            done.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        };
        run_study(&settings(5, 37, 2), climb_averse, &count).unwrap();
        assert_eq!(done.into_inner(), 37);
    }

    #[test]
    fn a_generated_mission_is_the_study_mission_above_home_and_bad_settings_are_named() {
        let s = settings(6, 1, 4);
        let site = Site {
            home: Geodetic {
                lat_deg: 38.5,
                lon_deg: -121.7,
                alt_m: 16.0,
            },
            hover_s: 3.0,
            name: None,
        };
        let m = random_mission(&s, 2, &site).unwrap();
        assert_eq!(m.name, format!("random-6-{}-{}-s4-2", s.xy_m, s.z_m));
        assert_eq!(m.origin.height_above_home_m, s.z_m + CLEARANCE_M);
        let points: Vec<Enu> = m.waypoints.iter().map(|w| w.position).collect();
        assert_eq!(points, random_points(&s, 2));
        assert!(m.waypoints.iter().all(|w| w.hover_s == 3.0));
        assert_eq!(m.waypoints[5].name, "W6");
        let refused = |s: &StudySettings, site: &Site| match random_mission(s, 0, site) {
            Err(StudyError::Setting { setting, .. }) => setting,
            other => panic!("{other:?}"),
        };
        assert_eq!(refused(&settings(0, 1, 1), &site), "waypoints");
        let mut far = site.clone();
        far.home.lat_deg = 91.0;
        assert_eq!(refused(&s, &far), "lat_deg");
        let mut negative = site.clone();
        negative.hover_s = -1.0;
        assert_eq!(refused(&s, &negative), "hover_s");
    }

    #[test]
    fn p90_is_the_nearest_rank_value() {
        let values: Vec<f64> = (1..=20).rev().map(f64::from).collect();
        let s = Stats::of(&values);
        assert_eq!((s.mean_pct, s.p90_pct, s.max_pct), (10.5, 18.0, 20.0));
        assert_eq!(Stats::of(&[4.0]).p90_pct, 4.0);
    }

    #[test]
    fn bad_settings_are_errors_naming_the_setting() {
        let err = |s: StudySettings| run_study(&s, climb_averse, &no_progress).unwrap_err();
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
        let e = run_study(&s, capped, &no_progress).unwrap_err();
        let StudyError::LegEnergy { mission, zf_m, .. } = &e else {
            panic!("unexpected error {e}");
        };
        assert!(*zf_m > 45.0);
        // The lowest-numbered failing mission is reported, and it really fails.
        assert!(run_mission(&s, *mission, &capped).is_err());
        for k in 0..*mission {
            assert!(run_mission(&s, k, &capped).is_ok());
        }
        assert!(e
            .to_string()
            .starts_with(&format!("mission {mission}: energy of leg ")));
    }
}
