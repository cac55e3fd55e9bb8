//! What the study found: each mission's outcome, the statistics of the baselines' increases over
//! the minimum-energy order, and `emplan study --json`'s document.

use serde::Serialize;

use super::vehicle::StudyRun;
use super::BaselineDirection;
use crate::physics::{Pricing, Profile};
use crate::tour::Objective;

/// What one mission of the study found. Energies are whole tours (origin to origin), each
/// baseline in the study's direction (its better one, or the solver's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissionOutcome {
    pub energy_j: f64,
    pub distance_j: f64,
    pub horizontal_j: f64,
    pub vertical_j: f64,
    /// The min-distance tour, in the direction flown (in neither, for the better direction), is
    /// not the minimum-energy order.
    pub distance_differs: bool,
}

impl MissionOutcome {
    /// Tour energy of an objective's order (a baseline in the direction flown).
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

    /// Whether `baseline`, in the direction flown, needs strictly less energy than min-distance
    /// (by more than a relative 1e-9, so the same tour found twice is not a win).
    pub fn beats_distance(&self, baseline: Objective) -> bool {
        self.energy_of(baseline) < self.distance_j * (1.0 - 1e-9)
    }
}

/// Mean, 90th percentile and maximum of one baseline's increase over the minimum-energy order
/// (the `STATS` object of docs/json.md). The percentile is the nearest-rank one: the
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

/// The study's summary: flattened into `emplan study --json`.
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

/// Which mission of the study had the largest increase, per baseline.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Worst {
    pub distance: Option<u64>,
    pub horizontal: Option<u64>,
    pub vertical: Option<u64>,
}

/// `emplan study --json`: the summary, flattened, plus the setting, the
/// profile, the worst missions and the wall time.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudyJson {
    pub waypoints: usize,
    pub xy_m: f64,
    pub z_m: f64,
    pub seed: u64,
    pub profile: Profile,
    /// What each leg's energy counted: "settled" or "paper" (to the 4 m rule).
    pub pricing: Pricing,
    /// Which direction of each baseline tour was flown: "better" or "solver".
    pub baseline_direction: BaselineDirection,
    #[serde(flatten)]
    pub summary: Summary,
    pub worst_mission: Worst,
    pub seconds: f64,
}

/// The JSON view of a study run.
pub fn study_document(run: &StudyRun) -> StudyJson {
    let s = &run.study.settings;
    StudyJson {
        waypoints: s.waypoints,
        xy_m: s.xy_m,
        z_m: s.z_m,
        seed: s.seed,
        profile: run.profile,
        pricing: run.pricing,
        baseline_direction: run.study.direction,
        summary: run.study.summary,
        worst_mission: Worst {
            distance: run.study.worst_mission(Objective::Distance),
            horizontal: run.study.worst_mission(Objective::Horizontal),
            vertical: run.study.worst_mission(Objective::Vertical),
        },
        seconds: run.seconds,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn p90_is_the_nearest_rank_value() {
        let values: Vec<f64> = (1..=20).rev().map(f64::from).collect();
        let s = Stats::of(&values);
        assert_eq!((s.mean_pct, s.p90_pct, s.max_pct), (10.5, 18.0, 20.0));
        assert_eq!(Stats::of(&[4.0]).p90_pct, 4.0);
    }
}
