//! Calibration against the paper's published operation energies (NOTES.md section 3): the
//! model-vs-paper comparison, and a Nelder-Mead fit of the few parameters the paper does not
//! publish. PTF fits the vehicle mass (the overall power level), the horizontal body drag
//! C_BD (growth of energy with Xf) and the PTF peak-speed limits (how fast the energy-optimal
//! trajectory may fly, which sets the descent and climb costs): research notes section 9.10.
//! HVB then fits its own speed and acceleration limits with the vehicle held fixed.

use serde::Serialize;

use super::operation::Model;
use super::vehicle::Vehicle;
use super::{PhysicsError, Profile};

/// One published operation energy.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Target {
    pub xf_m: f64,
    pub zf_m: f64,
    pub profile: Profile,
    pub energy_kj: f64,
}

const fn target(xf_m: f64, zf_m: f64, profile: Profile, energy_kj: f64) -> Target {
    Target {
        xf_m,
        zf_m,
        profile,
        energy_kj,
    }
}

/// The paper's simulated operation energies for the S1000+ (NOTES.md section 3).
pub const PAPER: [Target; 15] = [
    target(40.0, 25.0, Profile::Ptf, 7.04),
    target(40.0, 1.0, Profile::Ptf, 4.52),
    target(40.0, -1.0, Profile::Ptf, 4.36),
    target(40.0, -25.0, Profile::Ptf, 3.19),
    target(56.6, 0.0, Profile::Ptf, 5.74),
    target(0.0, -24.0, Profile::Ptf, 2.99),
    target(50.0, 30.0, Profile::Ptf, 8.2),
    target(0.0, 30.0, Profile::Ptf, 7.3),
    target(50.0, 0.0, Profile::Ptf, 5.2),
    target(40.0, 25.0, Profile::Hvb, 8.10),
    target(40.0, 1.0, Profile::Hvb, 5.67),
    target(40.0, -1.0, Profile::Hvb, 5.53),
    target(40.0, -25.0, Profile::Hvb, 4.77),
    target(56.6, 0.0, Profile::Hvb, 6.62),
    target(0.0, -24.0, Profile::Hvb, 4.97),
];

/// The model against one published value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Row {
    pub xf_m: f64,
    pub zf_m: f64,
    pub profile: Profile,
    pub paper_kj: f64,
    pub model_kj: f64,
    pub error_pct: f64,
}

/// The model against every published value of `profile`.
pub fn compare(vehicle: &Vehicle, profile: Profile) -> Result<Vec<Row>, PhysicsError> {
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
            })
        })
        .collect()
}

/// Marginal costs the paper's PTF table implies (research section 5.1), J/m: climbing at
/// X = 40 m (E(40,25) - E(40,1)) / 24, level flight (E(56.6,0) - mean E(40,+-1)) / 16.6,
/// descending (E(40,-1) - E(40,-25)) / 24 (energy saved per metre descended).
pub const PAPER_MARGINAL_J_M: [f64; 3] = [105.0, 78.3, 48.75];

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
    (rows.iter().map(|r| r.error_pct * r.error_pct).sum::<f64>() / rows.len().max(1) as f64).sqrt()
}

/// A fitted parameter: name (its key in vehicle.toml), value, and the range searched.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Fitted {
    pub key: &'static str,
    pub value: f64,
    pub low: f64,
    pub high: f64,
}

/// The model against the paper (what `emplan calibrate` reports), after an optional refit.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// The PTF operations, model vs paper.
    pub ptf: Vec<Row>,
    /// The HVB operations, model vs paper.
    pub hvb: Vec<Row>,
    /// PTF marginal costs (J/m): climbing, level, descending saves ([`marginal_costs`]).
    pub marginal_j_m: [f64; 3],
    pub hover_power_w: f64,
    pub min_power_speed_m_s: f64,
    /// The refitted parameters (empty without a refit).
    pub fitted: Vec<Fitted>,
}

/// Compares `vehicle` with the paper; with `refit`, first refits the calibrated parameters
/// (PTF: mass, drags, speed limits; HVB: its limits; 300 Nelder-Mead iterations each).
pub fn calibrate(vehicle: &Vehicle, refit: bool) -> Result<Calibration, PhysicsError> {
    let mut vehicle = vehicle.clone();
    let mut fitted = Vec::new();
    if refit {
        for profile in [Profile::Ptf, Profile::Hvb] {
            let (v, values) = fit(&vehicle, profile, 300);
            vehicle = v;
            fitted.extend(values);
        }
    }
    let ptf = compare(&vehicle, Profile::Ptf)?;
    let hvb = compare(&vehicle, Profile::Hvb)?;
    Ok(Calibration {
        marginal_j_m: marginal_costs(&ptf),
        ptf,
        hvb,
        hover_power_w: super::hover_power_w(&vehicle)?,
        min_power_speed_m_s: min_power_speed_m_s(&vehicle),
        fitted,
    })
}

impl Calibration {
    /// `emplan calibrate --json` (keys in alphabetical order).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "ptf": {"rows": self.ptf, "rms_pct": rms_pct(&self.ptf)},
            "hvb": {"rows": self.hvb, "rms_pct": rms_pct(&self.hvb)},
            "marginal_j_m": {"model": self.marginal_j_m, "paper": PAPER_MARGINAL_J_M},
            "hover_power_w": self.hover_power_w,
            "min_power_speed_m_s": self.min_power_speed_m_s,
            "fitted": self.fitted,
        })
    }
}

type Setter = fn(&mut Vehicle, f64);

fn knobs(profile: Profile) -> Vec<(&'static str, f64, f64, Setter)> {
    match profile {
        Profile::Ptf => vec![
            ("body.mass_kg", 5.5, 7.0, |v, x| v.body.mass_kg = x),
            ("rotor.drag_coefficient", 0.008, 0.025, |v, x| {
                v.rotor.drag_coefficient = x
            }),
            ("body.drag_coefficient_n_s2_m2", 0.05, 0.5, |v, x| {
                v.body.drag_coefficient_n_s2_m2 = x
            }),
            ("ptf.max_speed_xy_m_s", 4.0, 16.0, |v, x| {
                v.ptf.max_speed_xy_m_s = x
            }),
            ("ptf.max_speed_m_s", 3.0, 16.0, |v, x| {
                v.ptf.max_speed_m_s = x
            }),
            ("ptf.max_speed_up_m_s", 1.0, 10.0, |v, x| {
                v.ptf.max_speed_up_m_s = x
            }),
            ("ptf.max_speed_down_m_s", 1.0, 10.0, |v, x| {
                v.ptf.max_speed_down_m_s = x
            }),
        ],
        Profile::Hvb => vec![
            ("hvb.speed_xy_m_s", 2.0, 16.0, |v, x| v.hvb.speed_xy_m_s = x),
            ("hvb.speed_up_m_s", 0.5, 8.0, |v, x| v.hvb.speed_up_m_s = x),
            ("hvb.speed_down_m_s", 0.5, 8.0, |v, x| {
                v.hvb.speed_down_m_s = x
            }),
            ("hvb.acceleration_m_s2", 0.3, 8.0, |v, x| {
                v.hvb.acceleration_m_s2 = x
            }),
        ],
        Profile::Px4 => Vec::new(),
    }
}

/// Fits the calibrated parameters of `profile` (none for px4, which uses PX4's own parameters)
/// to the paper's energies by Nelder-Mead on the sum of squared relative errors, parameters
/// clamped to physical ranges. Returns the fitted vehicle and the values.
pub fn fit(vehicle: &Vehicle, profile: Profile, iterations: usize) -> (Vehicle, Vec<Fitted>) {
    let knobs = knobs(profile);
    let apply = |x: &[f64]| {
        let mut v = vehicle.clone();
        for ((_, lo, hi, set), &value) in knobs.iter().zip(x) {
            set(&mut v, value.clamp(*lo, *hi));
        }
        v
    };
    let objective = |x: &[f64]| -> f64 {
        match compare(&apply(x), profile) {
            Ok(rows) => {
                let mut sum: f64 = rows.iter().map(|r| (r.error_pct / 100.0).powi(2)).sum();
                if profile == Profile::Ptf {
                    // Multirotor forward-flight power has its minimum near 8 m/s (research
                    // section 5.3): a fit below 5.5 m/s is paying drag the vehicle does not have.
                    let v_min = min_power_speed_m_s(&apply(x));
                    sum += (5.5 - v_min).max(0.0).powi(2);
                    // The physics the table implies, not just its numbers: marginal costs of
                    // climbing, level flight and descending (research section 5.1), weighted a
                    // fifth of a published point each.
                    for (model, paper) in marginal_costs(&rows).iter().zip(PAPER_MARGINAL_J_M) {
                        sum += 0.2 * (model / paper - 1.0).powi(2);
                    }
                }
                sum
            }
            Err(_) => f64::INFINITY,
        }
    };
    // Multi-start: the current values, then the ranges' quarter, middle and three-quarter
    // points (the HVB and PTF objectives have local minima at the speed limits).
    let step: Vec<f64> = knobs.iter().map(|k| 0.1 * (k.2 - k.1)).collect();
    let mut starts = vec![knobs
        .iter()
        .map(|(key, lo, hi, _)| current(vehicle, key).clamp(*lo, *hi))
        .collect::<Vec<f64>>()];
    for fraction in [0.25, 0.5, 0.75] {
        starts.push(knobs.iter().map(|k| k.1 + fraction * (k.2 - k.1)).collect());
    }
    let best = starts
        .iter()
        .map(|start| {
            let x = nelder_mead(start, &step, iterations, &objective);
            let fx = objective(&x);
            (x, fx)
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(x, _)| x)
        .unwrap_or_default();
    let fitted = knobs
        .iter()
        .zip(&best)
        .map(|((key, lo, hi, _), &value)| Fitted {
            key,
            value: value.clamp(*lo, *hi),
            low: *lo,
            high: *hi,
        })
        .collect();
    (apply(&best), fitted)
}

fn current(v: &Vehicle, key: &str) -> f64 {
    match key {
        "body.mass_kg" => v.body.mass_kg,
        "rotor.drag_coefficient" => v.rotor.drag_coefficient,
        "body.drag_coefficient_n_s2_m2" => v.body.drag_coefficient_n_s2_m2,
        "ptf.max_speed_xy_m_s" => v.ptf.max_speed_xy_m_s,
        "ptf.max_speed_m_s" => v.ptf.max_speed_m_s,
        "ptf.max_speed_up_m_s" => v.ptf.max_speed_up_m_s,
        "ptf.max_speed_down_m_s" => v.ptf.max_speed_down_m_s,
        "hvb.speed_xy_m_s" => v.hvb.speed_xy_m_s,
        "hvb.speed_up_m_s" => v.hvb.speed_up_m_s,
        "hvb.speed_down_m_s" => v.hvb.speed_down_m_s,
        "hvb.acceleration_m_s2" => v.hvb.acceleration_m_s2,
        _ => f64::NAN,
    }
}

/// Nelder-Mead simplex minimisation (Nelder & Mead 1965; standard coefficients 1, 2, 0.5, 0.5).
pub(crate) fn nelder_mead(
    start: &[f64],
    step: &[f64],
    iterations: usize,
    f: &impl Fn(&[f64]) -> f64,
) -> Vec<f64> {
    let n = start.len();
    let mut simplex: Vec<(Vec<f64>, f64)> = (0..=n)
        .map(|k| {
            let mut x = start.to_vec();
            if k > 0 {
                x[k - 1] += step[k - 1];
            }
            let fx = f(&x);
            (x, fx)
        })
        .collect();
    for _ in 0..iterations {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let centroid: Vec<f64> = (0..n)
            .map(|i| simplex[..n].iter().map(|(x, _)| x[i]).sum::<f64>() / n as f64)
            .collect();
        let toward = |t: f64| -> Vec<f64> {
            centroid
                .iter()
                .zip(&simplex[n].0)
                .map(|(c, w)| c + t * (w - c))
                .collect()
        };
        let reflected = toward(-1.0);
        let fr = f(&reflected);
        if fr < simplex[0].1 {
            let expanded = toward(-2.0);
            let fe = f(&expanded);
            simplex[n] = if fe < fr {
                (expanded, fe)
            } else {
                (reflected, fr)
            };
        } else if fr < simplex[n - 1].1 {
            simplex[n] = (reflected, fr);
        } else {
            let contracted = toward(0.5);
            let fc = f(&contracted);
            if fc < simplex[n].1 {
                simplex[n] = (contracted, fc);
            } else {
                let best = simplex[0].0.clone();
                for entry in simplex.iter_mut().skip(1) {
                    let x: Vec<f64> = best
                        .iter()
                        .zip(&entry.0)
                        .map(|(b, x)| b + 0.5 * (x - b))
                        .collect();
                    let fx = f(&x);
                    *entry = (x, fx);
                }
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    simplex.swap_remove(0).0
}
