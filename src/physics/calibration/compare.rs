//! The model against the paper: each published operation and mission-level energy simulated
//! directly and set beside its target, the paper's min-energy tour of sample mission 1 against
//! every order of its waypoints, and the marginal costs and root-mean-square errors that sum
//! them up.

use serde::Serialize;

use super::targets::{path_legs, Rank, PAPER, PAPER_MISSIONS, SAMPLE_1};
use crate::physics::power::Model;
use crate::physics::vehicle::Vehicle;
use crate::physics::{PhysicsError, Pricing, Profile};

/// The model against one published mission-level value.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MissionRow {
    pub mission: &'static str,
    pub label: &'static str,
    pub profile: Profile,
    /// The candidate path the value is (the `rank` one in the model).
    pub path: &'static str,
    pub paper_kj: f64,
    /// Sum of the legs' 4 m-rule energies (the paper's convention).
    pub model_kj: f64,
    pub error_pct: f64,
    /// The same path priced with the chosen convention (`settled` adds each leg's settle).
    pub priced_kj: f64,
}

/// The model against every published mission-level value, each leg simulated directly (each
/// distinct leg once). `pricing` sets `priced_kj`; `model_kj` is always the paper's convention.
pub fn compare_missions(
    vehicle: &Vehicle,
    pricing: Pricing,
) -> Result<Vec<MissionRow>, PhysicsError> {
    compare_missions_of(vehicle, pricing, None)
}

/// [`compare_missions`] for the targets of one profile only (`None`: all).
pub(super) fn compare_missions_of(
    vehicle: &Vehicle,
    pricing: Pricing,
    profile: Option<Profile>,
) -> Result<Vec<MissionRow>, PhysicsError> {
    let model = Model::new(vehicle);
    // (profile, Xf bits, Zf bits) -> (to the 4 m rule, to settled hover), J.
    type Key = (Profile, u64, u64);
    let mut cache: Vec<(Key, (f64, f64))> = Vec::new();
    let mut leg = |profile: Profile, xf: f64, zf: f64| -> Result<(f64, f64), PhysicsError> {
        let key = (profile, xf.to_bits(), zf.to_bits());
        if let Some((_, e)) = cache.iter().find(|(k, _)| *k == key) {
            return Ok(*e);
        }
        let op = model.operation(profile, xf, zf)?;
        let e = (op.energy_j, op.total_energy_j());
        cache.push((key, e));
        Ok(e)
    };
    let mut rows = Vec::new();
    for t in PAPER_MISSIONS
        .iter()
        .filter(|t| profile.is_none_or(|p| p == t.profile))
    {
        let mut priced: Vec<(&'static str, f64, f64)> = Vec::new();
        for path in t.paths {
            let legs = path_legs(t.mission, path).ok_or(PhysicsError::NotFinite {
                what: "mission target path",
                value: f64::NAN,
            })?;
            let (mut paper, mut settled) = (0.0, 0.0);
            for (xf, zf) in legs {
                // Rounded to 1e-9 m so that legs equal by symmetry share one simulation.
                let r = |v: f64| (v * 1e9).round() / 1e9;
                let (e, total) = leg(t.profile, r(xf), r(zf))?;
                paper += e;
                settled += total;
            }
            priced.push((path, paper, settled));
        }
        priced.sort_by(|a, b| a.1.total_cmp(&b.1));
        let chosen = match t.rank {
            Rank::Cheapest => priced.first(),
            Rank::Dearest => priced.last(),
        };
        let Some(&(path, paper_j, settled_j)) = chosen else {
            continue;
        };
        let model_kj = paper_j / 1000.0;
        rows.push(MissionRow {
            mission: t.mission,
            label: t.label,
            profile: t.profile,
            path,
            paper_kj: t.energy_kj,
            model_kj,
            error_pct: 100.0 * (model_kj / t.energy_kj - 1.0),
            priced_kj: match pricing {
                Pricing::Paper => model_kj,
                Pricing::Settled => settled_j / 1000.0,
            },
        });
    }
    Ok(rows)
}

/// How the paper's min-energy tour of sample mission 1 fares in the model (4 m-rule pricing):
/// its energy, the model's own min-energy tour (every order tried) and its energy.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TourCheck {
    pub paper_tour: &'static str,
    pub paper_tour_kj: f64,
    pub model_tour: String,
    pub model_tour_kj: f64,
    /// How much dearer the paper's tour is than the model's best (0 when it is the best).
    pub gap_pct: f64,
    /// How much cheaper the paper's tour is than the cheapest tour of another energy (tours
    /// of the same legs in another order, and the mirror image, cost the same); negative when
    /// it is dearer.
    pub margin_pct: f64,
}

/// The paper's min-energy tour of sample mission 1 against every order of its waypoints.
pub fn sample_1_tour(vehicle: &Vehicle) -> Result<TourCheck, PhysicsError> {
    let model = Model::new(vehicle);
    let points: Vec<[f64; 3]> = std::iter::once([0.0; 3])
        .chain(SAMPLE_1.iter().map(|(_, p)| *p))
        .collect();
    let n = points.len();
    let mut cost = vec![vec![0.0; n]; n];
    let mut cache: Vec<((u64, u64), f64)> = Vec::new();
    for i in 0..n {
        for j in 0..n {
            if i == j {
                continue;
            }
            let r = |v: f64| (v * 1e9).round() / 1e9;
            let (a, b) = (points[i], points[j]);
            let (xf, zf) = (r((b[0] - a[0]).hypot(b[1] - a[1])), r(b[2] - a[2]));
            let key = (xf.to_bits(), zf.to_bits());
            cost[i][j] = match cache.iter().find(|(k, _)| *k == key) {
                Some((_, e)) => *e,
                None => {
                    let e = model.operation(Profile::Ptf, xf, zf)?.energy_j;
                    cache.push((key, e));
                    e
                }
            };
        }
    }
    let tour_j = |order: &[usize]| -> f64 {
        let mut total = cost[0][order[0]] + cost[order[order.len() - 1]][0];
        for w in order.windows(2) {
            total += cost[w[0]][w[1]];
        }
        total
    };
    let paper_tour = PAPER_MISSIONS[0].paths[0];
    let index = |ch: char| SAMPLE_1.iter().position(|(n, _)| *n == ch).map(|k| k + 1);
    let paper_order: Vec<usize> = paper_tour
        .chars()
        .filter(|&ch| ch != 'O')
        .filter_map(index)
        .collect();
    let paper_j = tour_j(&paper_order);
    let same = |e: f64| (e - paper_j).abs() <= 1e-9 * paper_j;
    // Heap's algorithm over the 8! orders.
    let mut order: Vec<usize> = (1..n).collect();
    let mut best = (tour_j(&order), order.clone());
    let mut other = if same(best.0) { f64::INFINITY } else { best.0 };
    let mut c = vec![0usize; order.len()];
    let mut i = 0;
    while i < order.len() {
        if c[i] < i {
            if i % 2 == 0 {
                order.swap(0, i);
            } else {
                order.swap(c[i], i);
            }
            let e = tour_j(&order);
            if e < best.0 {
                best = (e, order.clone());
            }
            if e < other && !same(e) {
                other = e;
            }
            c[i] += 1;
            i = 0;
        } else {
            c[i] = 0;
            i += 1;
        }
    }
    let name = |k: usize| SAMPLE_1[k - 1].0;
    Ok(TourCheck {
        paper_tour,
        paper_tour_kj: paper_j / 1000.0,
        model_tour: std::iter::once('O')
            .chain(best.1.iter().map(|&k| name(k)))
            .chain(std::iter::once('O'))
            .collect(),
        model_tour_kj: best.0 / 1000.0,
        gap_pct: 100.0 * (paper_j / best.0 - 1.0),
        margin_pct: 100.0 * (other / paper_j - 1.0),
    })
}

/// The model against one published value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Row {
    pub xf_m: f64,
    pub zf_m: f64,
    pub profile: Profile,
    pub paper_kj: f64,
    /// The model to the 4 m rule (the paper's convention: what `error_pct` compares).
    pub model_kj: f64,
    pub error_pct: f64,
    /// The model priced with the chosen convention (`settled` adds the settle).
    pub priced_kj: f64,
}

/// The model against every published value of `profile` (in the paper's convention).
pub fn compare(vehicle: &Vehicle, profile: Profile) -> Result<Vec<Row>, PhysicsError> {
    compare_priced(vehicle, profile, Pricing::Paper)
}

/// [`compare`], each row also priced with `pricing` (`priced_kj`).
pub fn compare_priced(
    vehicle: &Vehicle,
    profile: Profile,
    pricing: Pricing,
) -> Result<Vec<Row>, PhysicsError> {
    let model = Model::new(vehicle);
    PAPER
        .iter()
        .filter(|t| t.profile == profile)
        .map(|t| {
            let op = model.operation(profile, t.xf_m, t.zf_m)?;
            let model_kj = op.energy_j / 1000.0;
            Ok(Row {
                xf_m: t.xf_m,
                zf_m: t.zf_m,
                profile,
                paper_kj: t.energy_kj,
                model_kj,
                error_pct: 100.0 * (model_kj / t.energy_kj - 1.0),
                priced_kj: match pricing {
                    Pricing::Paper => model_kj,
                    Pricing::Settled => op.total_energy_j() / 1000.0,
                },
            })
        })
        .collect()
}

/// The same marginal costs from PTF comparison rows (in the order of [`PAPER`]).
pub fn marginal_costs(rows: &[Row]) -> [f64; 3] {
    let e = |x: f64, z: f64| {
        rows.iter()
            .find(|r| r.xf_m == x && r.zf_m == z)
            .map_or(f64::NAN, |r| r.model_kj * 1000.0)
    };
    [
        (e(40.0, 25.0) - e(40.0, 1.0)) / 24.0,
        (e(56.6, 0.0) - 0.5 * (e(40.0, 1.0) + e(40.0, -1.0))) / 16.6,
        (e(40.0, -1.0) - e(40.0, -25.0)) / 24.0,
    ]
}

/// The level-flight speed of least power (0.25 m/s grid up to 15 m/s; infeasible speeds skipped).
pub fn min_power_speed_m_s(vehicle: &Vehicle) -> f64 {
    let model = Model::new(vehicle);
    (0..=60)
        .map(|k| 0.25 * k as f64)
        .filter_map(|v| model.power_w(v, 0.0, 0.0, 0.0).ok().map(|(p, _)| (v, p)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(0.0, |(v, _)| v)
}

/// Root-mean-square of the relative errors, in percent.
pub fn rms_pct(rows: &[Row]) -> f64 {
    rms(&rows.iter().map(|r| r.error_pct).collect::<Vec<_>>())
}

/// Root-mean-square of `errors`.
pub fn rms(errors: &[f64]) -> f64 {
    (errors.iter().map(|e| e * e).sum::<f64>() / errors.len().max(1) as f64).sqrt()
}
