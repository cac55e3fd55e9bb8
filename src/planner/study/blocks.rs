//! The random-mission study with survey blocks (`emplan study --blocks K`): each random mission
//! of the study's points gains K random survey rectangles, each laid out as QGroundControl's
//! survey lays out its grid (parallel transects `spacing_m` apart across the rectangle, flown in
//! alternating directions, the camera triggering along them) and each a reversible block put at a
//! random place of the file among the points. For every mission, three orders over the points and
//! blocks, all priced in energy leg by leg as the study prices a leg (a block as the chain of its
//! lines):
//! - the minimum-energy order (`tour::clusters::solve` on the energy of every leg, each block
//!   entered at whichever end is cheaper overall);
//! - the min-distance order (the same solve on the 3D distances), in its better direction or in
//!   the solver's ([`BaselineDirection`]);
//! - the file's order: the points and blocks as generated, every block forward, "as
//!   QGroundControl would fly it";
//! - the blocks-forward order: the minimum-energy order with every block flown forward (what
//!   choosing each block's direction adds to ordering the stops).
//!
//! The summary says how often and how much the energy order saves over the other two (as a share
//! of their energy) and how often it flies a block reversed. Deterministic as the study: mission
//! `k` draws its points exactly as the plain study's mission `k` does, then its blocks from the
//! same stream, and results are collected in mission order.

use std::fmt::Display;
use std::ops::Range;
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use super::random::draw_points;
use super::vehicle::{check_envelope, StudyRunError};
use super::{study_error, waypoint_name, BaselineDirection, StudyError, StudySettings};
use crate::mission::Enu;
use crate::physics::{Pricing, Profile, VehicleModel};
use crate::rng::Rng;
use crate::tour::clusters::{self, Stop, StopTour, Visit, Way};
use crate::tour::energy::energy_matrix;
use crate::tour::{held_karp, solver, CostMatrix, Geometry};

/// Most survey blocks a mission of the study may have (each doubles the ways to choose from).
pub const MAX_BLOCKS: usize = 8;
/// Most transects one survey may have (the spacing is refused below XY / (this - 1)).
pub const MAX_LINES: usize = 20;
/// Transect spacing when none is given: a survey at 20-40 m with a typical mapping camera's
/// side overlap lays its lines about this far apart.
pub const DEFAULT_SPACING_M: f64 = 10.0;
/// A rectangle's sides are uniform in [this x XY, XY].
const MIN_SIDE_SHARE: f64 = 0.3;
/// A saving above this share of the baseline counts as one (%).
const SAVING_THRESHOLD_PCT: f64 = 1.0;

/// The survey blocks of every mission: `blocks` rectangles, transects `spacing_m` apart.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BlockSettings {
    pub blocks: usize,
    pub spacing_m: f64,
}

impl BlockSettings {
    /// Checks the blocks against the study's setting (the setting's own checks included); the
    /// error names the setting at fault.
    pub fn validate(&self, settings: &StudySettings) -> Result<(), StudyError> {
        settings.validate()?;
        let bad = |setting: &'static str, value: String, problem: String| {
            Err(StudyError::Setting {
                setting,
                value,
                problem,
            })
        };
        let room = held_karp::MAX_NODES.saturating_sub(settings.waypoints);
        let most = MAX_BLOCKS.min(room);
        if self.blocks == 0 || self.blocks > most {
            return bad(
                "blocks",
                self.blocks.to_string(),
                format!(
                    "allowed: 1 to {most} with {} waypoints (at most {MAX_BLOCKS}, and \
                     waypoints + blocks at most {}: the energy order is solved exactly)",
                    settings.waypoints,
                    held_karp::MAX_NODES
                ),
            );
        }
        // Finite and not negative: the setting's own checks passed.
        if settings.xy_m <= 0.0 {
            return bad(
                "xy_m",
                settings.xy_m.to_string(),
                "allowed with blocks: more than 0 m (the survey rectangles need room)".into(),
            );
        }
        let least_m = settings.xy_m / (MAX_LINES - 1) as f64;
        if !(self.spacing_m.is_finite() && self.spacing_m >= least_m) {
            return bad(
                "block_spacing_m",
                self.spacing_m.to_string(),
                format!(
                    "allowed: {least_m:.2} m or more with XY {} m (at most {MAX_LINES} lines a \
                     survey)",
                    settings.xy_m
                ),
            );
        }
        Ok(())
    }
}

/// A survey rectangle: its centre, its width across the transects and length along them, the
/// transects' heading (degrees clockwise from north) and the one altitude it is flown at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Survey {
    pub center_east_m: f64,
    pub center_north_m: f64,
    pub width_m: f64,
    pub length_m: f64,
    pub heading_deg: f64,
    pub z_up_m: f64,
}

impl Survey {
    /// A random rectangle inside the study's box: sides uniform in [0.3 XY, XY], heading
    /// uniform in [0, 180), altitude uniform in [-Z, Z), the centre uniform where the rectangle,
    /// whatever its heading, stays in [-XY, XY]^2.
    fn draw(xy_m: f64, z_m: f64, rng: &mut Rng) -> Survey {
        let width_m = rng.uniform(MIN_SIDE_SHARE * xy_m, xy_m);
        let length_m = rng.uniform(MIN_SIDE_SHARE * xy_m, xy_m);
        let heading_deg = rng.uniform(0.0, 180.0);
        let z_up_m = rng.uniform(-z_m, z_m);
        let free_m = xy_m - width_m.hypot(length_m) / 2.0;
        let center_east_m = rng.uniform(-free_m, free_m);
        let center_north_m = rng.uniform(-free_m, free_m);
        Survey {
            center_east_m,
            center_north_m,
            width_m,
            length_m,
            heading_deg,
            z_up_m,
        }
    }

    /// Its waypoints in the order QGroundControl's survey flies them: the two ends of each
    /// transect, transects `spacing_m` apart and centred across the width (floor(width /
    /// spacing) + 1 of them), the first flown along the heading, each next one back the other
    /// way.
    pub fn waypoints(&self, spacing_m: f64) -> Vec<Enu> {
        let lines = (self.width_m / spacing_m).floor() as usize + 1;
        let (sin, cos) = self.heading_deg.to_radians().sin_cos();
        // Along the transects: (east, north) = (sin, cos); across, 90 degrees clockwise.
        let at = |along_m: f64, across_m: f64| Enu {
            x_east_m: self.center_east_m + along_m * sin + across_m * cos,
            y_north_m: self.center_north_m + along_m * cos - across_m * sin,
            z_up_m: self.z_up_m,
        };
        let half_m = self.length_m / 2.0;
        (0..lines)
            .flat_map(|k| {
                let across_m = (k as f64 - (lines - 1) as f64 / 2.0) * spacing_m;
                let (start, end) = if k % 2 == 0 {
                    (-half_m, half_m)
                } else {
                    (half_m, -half_m)
                };
                [at(start, across_m), at(end, across_m)]
            })
            .collect()
    }
}

/// A stop of a mission with blocks, in file order: a point (one node) or a block (its nodes,
/// forward).
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    pub nodes: Range<usize>,
    /// The block (0-based: `S1` is 0), None for a point.
    pub block: Option<usize>,
}

/// Mission `k` of a study with blocks: node 0 the origin, then every stop's nodes in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockMission {
    pub geometry: Geometry,
    /// `names[node]`: "origin", the points `W1`.., a block's waypoints `S1.1`, `S1.2`..
    pub names: Vec<String>,
    /// The points and blocks in file order.
    pub items: Vec<Item>,
    pub surveys: Vec<Survey>,
}

/// The block name of block `b` (0-based).
pub fn block_name(b: usize) -> String {
    format!("S{}", b + 1)
}

impl BlockMission {
    /// Draws mission `mission`: the plain study's points (the same stream), then for each block
    /// the place in the file (before which point, uniform; after the last one too) and its
    /// rectangle.
    pub fn draw(settings: &StudySettings, blocks: &BlockSettings, mission: u64) -> BlockMission {
        let mut rng = Rng::stream(settings.seed, mission);
        let points = draw_points(settings, &mut rng);
        let drawn: Vec<(usize, Survey)> = (0..blocks.blocks)
            .map(|_| {
                let slot = rng.below(points.len() + 1);
                (slot, Survey::draw(settings.xy_m, settings.z_m, &mut rng))
            })
            .collect();
        let mut positions = vec![Enu::default()];
        let mut names = vec!["origin".to_string()];
        let mut items = Vec::new();
        for slot in 0..=points.len() {
            for (b, (_, survey)) in drawn.iter().enumerate().filter(|(_, d)| d.0 == slot) {
                let first = positions.len();
                for (k, p) in survey.waypoints(blocks.spacing_m).into_iter().enumerate() {
                    positions.push(p);
                    names.push(format!("{}.{}", block_name(b), k + 1));
                }
                items.push(Item {
                    nodes: first..positions.len(),
                    block: Some(b),
                });
            }
            if let Some(&p) = points.get(slot) {
                items.push(Item {
                    nodes: positions.len()..positions.len() + 1,
                    block: None,
                });
                positions.push(p);
                names.push(waypoint_name(slot));
            }
        }
        BlockMission {
            geometry: Geometry::from_points(positions),
            names,
            items,
            surveys: drawn.into_iter().map(|(_, s)| s).collect(),
        }
    }

    /// The stops for a cost matrix of every node: a point's one way, a block's forward way then
    /// its reversed one, each priced as the chain of its lines leg by leg.
    pub fn stops(&self, m: &CostMatrix) -> Vec<Stop> {
        self.items
            .iter()
            .map(|item| {
                if item.block.is_none() {
                    return Stop::point(item.nodes.start);
                }
                let (first, last) = (item.nodes.start, item.nodes.end - 1);
                let forward = (first..last).map(|k| m.cost(k, k + 1)).sum();
                let reversed = (first..last).map(|k| m.cost(k + 1, k)).sum();
                Stop {
                    ways: vec![
                        Way {
                            entry: first,
                            exit: last,
                            inner: forward,
                        },
                        Way {
                            entry: last,
                            exit: first,
                            inner: reversed,
                        },
                    ],
                }
            })
            .collect()
    }

    /// The file's order: every stop as generated, every block forward.
    pub fn file_order(&self) -> Vec<Visit> {
        (0..self.items.len())
            .map(|stop| Visit { stop, way: 0 })
            .collect()
    }

    /// Every node `visits` fly, origin excluded: a block's nodes contiguous, last to first when
    /// reversed.
    pub fn flown_nodes(&self, visits: &[Visit]) -> Vec<usize> {
        visits
            .iter()
            .flat_map(|v| {
                let nodes = self.items[v.stop].nodes.clone();
                let mut flown: Vec<usize> = nodes.collect();
                if v.way == 1 {
                    flown.reverse();
                }
                flown
            })
            .collect()
    }
}

/// The same tour flown the other way round: the visits last to first, each block reversed.
pub fn reversed(visits: &[Visit], stops: &[Stop]) -> Vec<Visit> {
    visits
        .iter()
        .rev()
        .map(|v| Visit {
            stop: v.stop,
            way: if stops[v.stop].ways.len() > 1 {
                1 - v.way
            } else {
                v.way
            },
        })
        .collect()
}

/// The three orders of one mission (visits into [`BlockMission::items`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BlockOrders {
    pub energy: StopTour,
    /// The min-distance order, in the direction flown.
    pub distance: Vec<Visit>,
    pub file: Vec<Visit>,
    /// The minimum-energy order with every block forward.
    pub forward: StopTour,
}

/// What one mission of the study with blocks found. Energies are whole tours (origin to origin).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockOutcome {
    /// The minimum-energy order.
    pub energy_j: f64,
    /// The min-distance order, in the direction flown.
    pub distance_j: f64,
    /// The file's order, every block forward.
    pub file_j: f64,
    /// The minimum-energy order with every block forward.
    pub forward_j: f64,
    /// Blocks the energy order flies reversed.
    pub reversed_blocks: usize,
    /// The min-distance order (in the direction flown; in neither, for the better direction)
    /// differs from the energy order in its order or a block's direction.
    pub distance_differs: bool,
    /// Whether the solver proved the energy order optimal.
    pub optimal: bool,
}

/// What the energy order saves over a baseline costing `baseline_j`, % of the baseline; a
/// difference below summation rounding (the same legs added in another order) is none.
fn saving_pct(energy_j: f64, baseline_j: f64) -> f64 {
    let pct = 100.0 * (baseline_j - energy_j) / baseline_j;
    if pct.abs() < 1e-9 {
        0.0
    } else {
        pct
    }
}

impl BlockOutcome {
    /// What the energy order saves over the file's order, % of the file order's energy.
    pub fn saving_over_file_pct(&self) -> f64 {
        saving_pct(self.energy_j, self.file_j)
    }

    /// What the energy order saves over the best order flying every block forward, % of the
    /// latter's energy: what choosing the blocks' directions saves.
    pub fn saving_over_forward_pct(&self) -> f64 {
        saving_pct(self.energy_j, self.forward_j)
    }

    /// What the energy order saves over the min-distance order, % of the latter's energy.
    pub fn saving_over_distance_pct(&self) -> f64 {
        saving_pct(self.energy_j, self.distance_j)
    }
}

/// Solves mission `mission` with blocks: prices every leg with `leg_energy_j(xf_m, zf_m)` (the
/// energy matrix, returned), then the energy order, the min-distance order (flown in `direction`)
/// and the file's order.
pub fn solve_block_mission<E: Display + Send>(
    settings: &StudySettings,
    blocks: &BlockSettings,
    mission: u64,
    direction: BaselineDirection,
    leg_energy_j: &(impl Fn(f64, f64) -> Result<f64, E> + Sync + ?Sized),
) -> Result<(BlockMission, CostMatrix, BlockOrders), StudyError> {
    let drawn = BlockMission::draw(settings, blocks, mission);
    let energy = energy_matrix(&drawn.geometry, &drawn.names, leg_energy_j)
        .map_err(|e| study_error(mission, e))?;
    let plan_err = |source| StudyError::Plan { mission, source };
    let options = solver::Options::default();
    let energy_stops = drawn.stops(&energy);
    let energy_tour = clusters::solve(&energy, &energy_stops, &options).map_err(plan_err)?;
    let distances = drawn.geometry.distance_matrix();
    let distance_stops = drawn.stops(&distances);
    let forward = clusters::solve(&distances, &distance_stops, &options)
        .map_err(plan_err)?
        .visits;
    let backward = reversed(&forward, &distance_stops);
    let price = |visits: &[Visit]| clusters::tour_cost(&energy, &energy_stops, visits);
    let distance = match direction {
        BaselineDirection::Better if price(&backward) < price(&forward) => backward,
        BaselineDirection::Better => forward,
        // The solver's direction made reproducible: the first stop earlier in the file than the
        // last.
        BaselineDirection::Solver => match (forward.first(), forward.last()) {
            (Some(a), Some(b)) if a.stop > b.stop => backward,
            _ => forward,
        },
    };
    let file = drawn.file_order();
    let forward_stops: Vec<Stop> = energy_stops
        .iter()
        .map(|stop| Stop {
            ways: stop.ways[..1].to_vec(),
        })
        .collect();
    let forward_blocks = clusters::solve(&energy, &forward_stops, &options).map_err(plan_err)?;
    Ok((
        drawn,
        energy,
        BlockOrders {
            energy: energy_tour,
            distance,
            file,
            forward: forward_blocks,
        },
    ))
}

/// Runs mission `mission` of a study with blocks: its three orders priced in energy.
pub fn run_block_mission<E: Display + Send>(
    settings: &StudySettings,
    blocks: &BlockSettings,
    mission: u64,
    direction: BaselineDirection,
    leg_energy_j: &(impl Fn(f64, f64) -> Result<f64, E> + Sync + ?Sized),
) -> Result<BlockOutcome, StudyError> {
    let (drawn, energy, orders) =
        solve_block_mission(settings, blocks, mission, direction, leg_energy_j)?;
    // Every order priced by the same sum (the solver's cost is the same legs).
    let stops = drawn.stops(&energy);
    let price = |visits: &[Visit]| clusters::tour_cost(&energy, &stops, visits);
    let same_tour = |visits: &[Visit]| visits == orders.energy.visits.as_slice();
    let distance_differs = match direction {
        BaselineDirection::Better => {
            !same_tour(&orders.distance) && !same_tour(&reversed(&orders.distance, &stops))
        }
        BaselineDirection::Solver => !same_tour(&orders.distance),
    };
    Ok(BlockOutcome {
        energy_j: price(&orders.energy.visits),
        distance_j: price(&orders.distance),
        file_j: price(&orders.file),
        forward_j: price(&orders.forward.visits),
        reversed_blocks: orders.energy.visits.iter().filter(|v| v.way == 1).count(),
        distance_differs,
        optimal: orders.energy.optimal,
    })
}

/// Mean, median and maximum of what the energy order saves over one baseline, % of the
/// baseline's energy, and the share of missions saving more than 1% (`over_1pct_missions_pct`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SavingStats {
    pub mean_pct: f64,
    /// The middle saving (the mean of the two middle ones for an even count).
    pub median_pct: f64,
    pub max_pct: f64,
    pub over_1pct_missions_pct: f64,
}

impl SavingStats {
    /// Statistics of `values` (the order does not matter; none gives zeros).
    pub fn of(values: &[f64]) -> SavingStats {
        if values.is_empty() {
            return SavingStats {
                mean_pct: 0.0,
                median_pct: 0.0,
                max_pct: 0.0,
                over_1pct_missions_pct: 0.0,
            };
        }
        let n = values.len();
        let mut sorted = values.to_vec();
        sorted.sort_by(f64::total_cmp);
        let median_pct = if n % 2 == 1 {
            sorted[n / 2]
        } else {
            (sorted[n / 2 - 1] + sorted[n / 2]) / 2.0
        };
        let over = values.iter().filter(|&&v| v > SAVING_THRESHOLD_PCT).count();
        SavingStats {
            mean_pct: values.iter().sum::<f64>() / n as f64,
            median_pct,
            max_pct: sorted[n - 1],
            over_1pct_missions_pct: 100.0 * over as f64 / n as f64,
        }
    }
}

/// The summary of a study with blocks: flattened into `emplan study --blocks K --json`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BlockSummary {
    pub missions: usize,
    /// The energy order against the file's order (every block forward).
    pub saving_over_file: SavingStats,
    /// The energy order against the min-distance order in the direction flown.
    pub saving_over_distance: SavingStats,
    /// The energy order against the best order flying every block forward.
    pub saving_over_forward_blocks: SavingStats,
    /// Share of missions whose energy order flies at least one block reversed (%).
    pub reverses_a_block_pct: f64,
    /// Share of all blocks of all missions the energy order flies reversed (%).
    pub blocks_reversed_pct: f64,
    /// Share of missions whose min-distance order is not the energy order (%).
    pub distance_differs_pct: f64,
    /// Missions whose energy order the solver could not prove optimal.
    pub unproven_missions: usize,
}

impl BlockSummary {
    /// Aggregates per-mission outcomes of missions with `blocks` blocks each.
    pub fn of(outcomes: &[BlockOutcome], blocks: usize) -> BlockSummary {
        let n = outcomes.len().max(1) as f64;
        let share = |count: usize| 100.0 * count as f64 / n;
        let over_file: Vec<f64> = outcomes.iter().map(|o| o.saving_over_file_pct()).collect();
        let over_distance: Vec<f64> = outcomes
            .iter()
            .map(|o| o.saving_over_distance_pct())
            .collect();
        let over_forward: Vec<f64> = outcomes
            .iter()
            .map(|o| o.saving_over_forward_pct())
            .collect();
        let reversed: usize = outcomes.iter().map(|o| o.reversed_blocks).sum();
        BlockSummary {
            missions: outcomes.len(),
            saving_over_file: SavingStats::of(&over_file),
            saving_over_distance: SavingStats::of(&over_distance),
            saving_over_forward_blocks: SavingStats::of(&over_forward),
            reverses_a_block_pct: share(outcomes.iter().filter(|o| o.reversed_blocks > 0).count()),
            blocks_reversed_pct: 100.0 * reversed as f64 / (n * blocks.max(1) as f64),
            distance_differs_pct: share(outcomes.iter().filter(|o| o.distance_differs).count()),
            unproven_missions: outcomes.iter().filter(|o| !o.optimal).count(),
        }
    }
}

/// A finished study with blocks.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockStudy {
    pub settings: StudySettings,
    pub blocks: BlockSettings,
    pub direction: BaselineDirection,
    pub outcomes: Vec<BlockOutcome>,
    pub summary: BlockSummary,
}

impl BlockStudy {
    /// The mission number where the energy order saves most over a baseline (the first on
    /// ties).
    fn best_saving(&self, saving: impl Fn(&BlockOutcome) -> f64) -> Option<u64> {
        let mut best: Option<(usize, f64)> = None;
        for (k, o) in self.outcomes.iter().enumerate() {
            let s = saving(o);
            if best.is_none_or(|(_, b)| s > b) {
                best = Some((k, s));
            }
        }
        best.map(|(k, _)| k as u64)
    }
}

/// Runs a whole study with blocks in parallel (rayon's current pool); `progress` is called once
/// per finished mission, from any thread. On failure, the lowest-numbered failing mission's error.
pub fn run_block_study<E: Display + Send>(
    settings: &StudySettings,
    blocks: &BlockSettings,
    direction: BaselineDirection,
    leg_energy_j: impl Fn(f64, f64) -> Result<f64, E> + Sync,
    progress: &(dyn Fn() + Sync),
) -> Result<BlockStudy, StudyError> {
    blocks.validate(settings)?;
    let results: Vec<Result<BlockOutcome, StudyError>> = (0..settings.missions as u64)
        .into_par_iter()
        .map(|k| {
            let outcome = run_block_mission(settings, blocks, k, direction, &leg_energy_j);
            progress();
            outcome
        })
        .collect();
    let outcomes = results.into_iter().collect::<Result<Vec<_>, _>>()?;
    let summary = BlockSummary::of(&outcomes, blocks.blocks);
    Ok(BlockStudy {
        settings: *settings,
        blocks: *blocks,
        direction,
        outcomes,
        summary,
    })
}

/// A study with blocks run with a vehicle.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockStudyRun {
    pub study: BlockStudy,
    pub profile: Profile,
    pub pricing: Pricing,
    pub seconds: f64,
}

/// Runs the study with blocks with `model`'s energy table (the settings checked against it
/// first), each leg priced as `pricing` says.
pub fn run_blocks(
    settings: &StudySettings,
    blocks: &BlockSettings,
    model: &VehicleModel,
    pricing: Pricing,
    direction: BaselineDirection,
    progress: &(dyn Fn() + Sync),
) -> Result<BlockStudyRun, StudyRunError> {
    // The rectangles lie inside the box, so the box's reach bounds every leg.
    check_envelope(settings, &model.table)?;
    let started = Instant::now();
    let leg_energy_j =
        |xf_m: f64, zf_m: f64| model.leg(xf_m, zf_m).map(|l| l.priced_energy_j(pricing));
    let study =
        run_block_study(settings, blocks, direction, leg_energy_j, progress).map_err(|cause| {
            StudyRunError::Run {
                settings: *settings,
                profile: model.profile,
                cause: Box::new(cause),
            }
        })?;
    Ok(BlockStudyRun {
        study,
        profile: model.profile,
        pricing,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// Where the energy order saved most, per baseline.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BestSaving {
    pub file: Option<u64>,
    pub distance: Option<u64>,
}

/// `emplan study --blocks K --json`: the setting, the blocks, the summary (flattened), the
/// missions where the energy order saved most, and the wall time.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BlockStudyJson {
    pub waypoints: usize,
    pub blocks: usize,
    pub block_spacing_m: f64,
    pub xy_m: f64,
    pub z_m: f64,
    pub seed: u64,
    pub profile: Profile,
    pub pricing: Pricing,
    pub baseline_direction: BaselineDirection,
    #[serde(flatten)]
    pub summary: BlockSummary,
    pub best_mission: BestSaving,
    pub seconds: f64,
}

/// The JSON view of a study with blocks.
pub fn block_study_document(run: &BlockStudyRun) -> BlockStudyJson {
    let study = &run.study;
    let s = &study.settings;
    BlockStudyJson {
        waypoints: s.waypoints,
        blocks: study.blocks.blocks,
        block_spacing_m: study.blocks.spacing_m,
        xy_m: s.xy_m,
        z_m: s.z_m,
        seed: s.seed,
        profile: run.profile,
        pricing: run.pricing,
        baseline_direction: study.direction,
        summary: study.summary,
        best_mission: BestSaving {
            file: study.best_saving(BlockOutcome::saving_over_file_pct),
            distance: study.best_saving(BlockOutcome::saving_over_distance_pct),
        },
        seconds: run.seconds,
    }
}

#[cfg(test)]
mod tests {
    use super::super::random_points;
    use super::super::tests::settings;
    use super::*;

    /// Horizontal metres plus 8 J per metre climbed and 0.5 J per metre descended (x 100).
    fn climb_averse(xf_m: f64, zf_m: f64) -> Result<f64, std::convert::Infallible> {
        Ok(100.0 * (xf_m + 8.0 * zf_m.max(0.0) + 0.5 * (-zf_m).max(0.0)))
    }

    fn two_blocks() -> BlockSettings {
        BlockSettings {
            blocks: 2,
            spacing_m: DEFAULT_SPACING_M,
        }
    }

    #[test]
    fn a_survey_is_parallel_transects_at_the_spacing_flown_back_and_forth_inside_the_box() {
        let s = settings(6, 1, 3);
        for mission in 0..50 {
            let drawn = BlockMission::draw(&s, &two_blocks(), mission);
            for item in &drawn.items {
                let Some(block) = item.block else { continue };
                let survey = &drawn.surveys[block];
                let p: Vec<Enu> = item
                    .nodes
                    .clone()
                    .map(|n| drawn.geometry.points()[n])
                    .collect();
                let lines = (survey.width_m / DEFAULT_SPACING_M).floor() as usize + 1;
                assert_eq!(p.len(), 2 * lines, "mission {mission}");
                for w in &p {
                    assert!(w.x_east_m.abs() <= s.xy_m && w.y_north_m.abs() <= s.xy_m);
                    assert_eq!(w.z_up_m, survey.z_up_m);
                }
                let (sin, cos) = survey.heading_deg.to_radians().sin_cos();
                let along = |a: &Enu, b: &Enu| {
                    (b.x_east_m - a.x_east_m) * sin + (b.y_north_m - a.y_north_m) * cos
                };
                for k in 0..lines {
                    let (a, b) = (&p[2 * k], &p[2 * k + 1]);
                    // Each transect runs the rectangle's length along the heading, alternately.
                    let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
                    assert!((along(a, b) - sign * survey.length_m).abs() < 1e-9);
                    if k > 0 {
                        // The next transect starts one spacing across from where the last ended.
                        let (e, n) = (
                            a.x_east_m - p[2 * k - 1].x_east_m,
                            a.y_north_m - p[2 * k - 1].y_north_m,
                        );
                        assert!((e.hypot(n) - DEFAULT_SPACING_M).abs() < 1e-9);
                    }
                }
            }
        }
    }

    #[test]
    fn a_mission_with_blocks_keeps_the_plain_studys_points_in_file_order() {
        let s = settings(7, 1, 11);
        let drawn = BlockMission::draw(&s, &two_blocks(), 4);
        let points: Vec<Enu> = drawn
            .items
            .iter()
            .filter(|i| i.block.is_none())
            .map(|i| drawn.geometry.points()[i.nodes.start])
            .collect();
        assert_eq!(points, random_points(&s, 4));
        // Every node but the origin belongs to exactly one item, in file order.
        let nodes: Vec<usize> = drawn.items.iter().flat_map(|i| i.nodes.clone()).collect();
        assert_eq!(nodes, (1..drawn.geometry.len()).collect::<Vec<_>>());
        let blocks: Vec<usize> = drawn.items.iter().filter_map(|i| i.block).collect();
        assert_eq!(blocks, vec![0, 1]);
        assert_eq!(
            drawn.names[drawn
                .items
                .iter()
                .find(|i| i.block == Some(1))
                .unwrap()
                .nodes
                .start],
            "S2.1"
        );
    }

    #[test]
    fn a_small_study_with_blocks_reproduces_and_its_energy_orders_beat_both_baselines() {
        let s = settings(6, 24, 5);
        let run = |seed| {
            run_block_study(
                &StudySettings { seed, ..s },
                &two_blocks(),
                BaselineDirection::Better,
                climb_averse,
                &|| {},
            )
            .unwrap()
        };
        let study = run(5);
        assert_eq!(study, run(5));
        assert_ne!(study.summary, run(6).summary);
        assert_eq!(study.summary.missions, 24);
        assert_eq!(study.summary.unproven_missions, 0);
        for (k, o) in study.outcomes.iter().enumerate() {
            assert!(o.energy_j <= o.file_j * (1.0 + 1e-12), "mission {k}: {o:?}");
            assert!(
                o.energy_j <= o.forward_j * (1.0 + 1e-12),
                "mission {k}: {o:?}"
            );
            // Ordering the stops with the blocks forward is never worse than the file's order.
            assert!(
                o.forward_j <= o.file_j * (1.0 + 1e-12),
                "mission {k}: {o:?}"
            );
            if o.reversed_blocks == 0 {
                assert!(o.saving_over_forward_pct() < 1e-6, "mission {k}: {o:?}");
            }
            assert!(
                o.energy_j <= o.distance_j * (1.0 + 1e-12),
                "mission {k}: {o:?}"
            );
            assert!(o.saving_over_file_pct() >= 0.0 && o.saving_over_distance_pct() >= 0.0);
        }
        // A climb-averse vehicle gains from ordering: the file's order is not the best one.
        let sum = study.summary;
        assert!(sum.saving_over_file.mean_pct > 1.0, "{sum:?}");
        assert!(sum.saving_over_file.median_pct <= sum.saving_over_file.max_pct);
        assert!(sum.saving_over_distance.mean_pct <= sum.saving_over_distance.max_pct);
        assert!(sum.reverses_a_block_pct > 0.0 && sum.reverses_a_block_pct <= 100.0);
        assert!(sum.blocks_reversed_pct <= sum.reverses_a_block_pct);
    }

    #[test]
    fn every_order_flies_each_block_whole_forward_or_reversed_and_every_node_once() {
        let s = settings(5, 1, 8);
        for direction in [BaselineDirection::Better, BaselineDirection::Solver] {
            for mission in 0..12 {
                let (drawn, _, orders) =
                    solve_block_mission(&s, &two_blocks(), mission, direction, &climb_averse)
                        .unwrap();
                assert!(orders.forward.visits.iter().all(|v| v.way == 0));
                for visits in [
                    &orders.energy.visits,
                    &orders.distance,
                    &orders.file,
                    &orders.forward.visits,
                ] {
                    let mut seen: Vec<usize> = visits.iter().map(|v| v.stop).collect();
                    seen.sort_unstable();
                    assert_eq!(seen, (0..drawn.items.len()).collect::<Vec<_>>());
                    let flown = drawn.flown_nodes(visits);
                    let mut all = flown.clone();
                    all.sort_unstable();
                    assert_eq!(all, (1..drawn.geometry.len()).collect::<Vec<_>>());
                    for item in drawn.items.iter().filter(|i| i.block.is_some()) {
                        let at = flown.iter().position(|&n| item.nodes.contains(&n)).unwrap();
                        let run = &flown[at..at + item.nodes.len()];
                        let forward: Vec<usize> = item.nodes.clone().collect();
                        let backward: Vec<usize> = item.nodes.clone().rev().collect();
                        assert!(
                            run == forward || run == backward,
                            "mission {mission}: {flown:?}"
                        );
                    }
                }
                // The file's order flies every block forward, in file order.
                assert_eq!(
                    drawn.flown_nodes(&orders.file),
                    (1..drawn.geometry.len()).collect::<Vec<_>>()
                );
            }
        }
    }

    #[test]
    fn with_a_cost_proportional_to_distance_the_energy_order_saves_nothing_over_the_distance_order()
    {
        // Priced by 3D distance, the energy order is a min-distance order: nothing to save.
        let study = run_block_study(
            &settings(6, 20, 2),
            &two_blocks(),
            BaselineDirection::Better,
            |x: f64, z: f64| Ok::<f64, String>(250.0 * x.hypot(z)),
            &|| {},
        )
        .unwrap();
        assert!(
            study.summary.saving_over_distance.max_pct < 1e-6,
            "{:?}",
            study.summary
        );
        assert!(study.summary.saving_over_file.mean_pct > 0.0);
    }

    #[test]
    fn bad_block_settings_are_errors_naming_the_setting() {
        let err = |s: StudySettings, b: BlockSettings| match b.validate(&s) {
            Err(StudyError::Setting { setting, .. }) => setting,
            other => panic!("{other:?}"),
        };
        let s = settings(8, 10, 1);
        assert_eq!(
            err(
                s,
                BlockSettings {
                    blocks: 0,
                    ..two_blocks()
                }
            ),
            "blocks"
        );
        assert_eq!(
            err(
                s,
                BlockSettings {
                    blocks: MAX_BLOCKS + 1,
                    ..two_blocks()
                }
            ),
            "blocks"
        );
        assert_eq!(
            err(
                settings(18, 10, 1),
                BlockSettings {
                    blocks: 3,
                    ..two_blocks()
                }
            ),
            "blocks"
        );
        assert_eq!(
            err(
                s,
                BlockSettings {
                    spacing_m: 0.5,
                    ..two_blocks()
                }
            ),
            "block_spacing_m"
        );
        assert_eq!(
            err(
                s,
                BlockSettings {
                    spacing_m: f64::NAN,
                    ..two_blocks()
                }
            ),
            "block_spacing_m"
        );
        assert_eq!(err(StudySettings { xy_m: 0.0, ..s }, two_blocks()), "xy_m");
        assert_eq!(err(settings(0, 10, 1), two_blocks()), "waypoints");
        assert!(two_blocks().validate(&s).is_ok());
    }

    #[test]
    fn saving_statistics_have_the_middle_value_as_median() {
        let s = SavingStats::of(&[4.0, 0.0, 2.0, 0.5]);
        assert_eq!((s.mean_pct, s.median_pct, s.max_pct), (1.625, 1.25, 4.0));
        assert_eq!(s.over_1pct_missions_pct, 50.0);
        assert_eq!(SavingStats::of(&[3.0, 1.0, 2.0]).median_pct, 2.0);
    }
}
