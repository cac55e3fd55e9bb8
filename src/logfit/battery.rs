//! The pack's internal resistance and capacity from the voltage and current samples of logged
//! flights (samples.csv), the battery part of `calibrate --from-logs`. Leg energies cannot show
//! them (the power module measures terminal energy); the terminal voltage can.
//!
//! Model (the physics model's lumped pack, `physics::powertrain`; the mock's `sim::battery`):
//! V = OCV(SOC) - R I with SOC = SOC0 - Q / C, Q the charge drawn since the flight's first
//! sample (trapezoid of the measured current over vehicle time). The pack (its label, its
//! resistance to start from and its OCV curve: [`PackModel`]) is the vehicle file's
//! (`battery.ocv_soc`, `ocv_cell_v`) for `calibrate`, or the one a flight was flown with (its
//! plan.json's guard setup) for the ledger's fit of one flight ([`fit_flight`], with standard
//! errors): the fit is as good as that curve. Each flight's starting state of charge SOC0 is
//! unknown (a pack is not always full) and fitted per flight by golden-section search; R and C
//! are shared and fitted by Nelder-Mead on the squared voltage residuals. Only the primary
//! battery's samples with a measured voltage and current count (not PX4 SITL's fake current).

use std::path::Path;

use serde::Serialize;

use super::{Fitted, LogFitError};
use crate::flightlog::csv::read_samples;
use crate::flightlog::recorder::SAMPLES_FILE;
use crate::flightlog::samples::PowerSample;
use crate::physics::minimise::{golden_section, nelder_mead};
use crate::physics::Vehicle;

/// Fewest usable samples for a flight to count.
const MIN_SAMPLES: usize = 50;

/// One flight's pack samples: current and terminal voltage against charge drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct PackSeries {
    /// Index of its flight.
    pub flight: usize,
    pub voltage_v: Vec<f64>,
    pub current_a: Vec<f64>,
    /// Charge drawn since the first sample, ampere-seconds.
    pub drawn_as: Vec<f64>,
    /// Each sample's log time (s) and whether the vehicle was armed then (None: not said).
    pub t_s: Vec<f64>,
    pub armed: Vec<Option<bool>>,
}

/// The most samples the joint search of one flight's fit runs on (`fit_flight`).
const SEARCH_SAMPLES: usize = 400;

impl PackSeries {
    /// Every `k`-th sample of the series, the first included (`k` of 0 or 1: all of them).
    pub fn every(&self, k: usize) -> PackSeries {
        let k = k.max(1);
        let pick = |v: &[f64]| v.iter().step_by(k).copied().collect::<Vec<f64>>();
        PackSeries {
            flight: self.flight,
            voltage_v: pick(&self.voltage_v),
            current_a: pick(&self.current_a),
            drawn_as: pick(&self.drawn_as),
            t_s: pick(&self.t_s),
            armed: self.armed.iter().step_by(k).copied().collect(),
        }
    }

    /// The series of flight `flight` from its samples in log order, each with whether the
    /// vehicle was armed: only the primary battery's samples with a measured, finite voltage
    /// and current count (not PX4 SITL's fake current); the charge drawn is the trapezoid of
    /// the current over log time (a time that goes back adds nothing).
    pub fn of_samples<'a>(
        flight: usize,
        samples: impl IntoIterator<Item = (&'a PowerSample, Option<bool>)>,
    ) -> PackSeries {
        let mut series = PackSeries {
            flight,
            voltage_v: Vec::new(),
            current_a: Vec::new(),
            drawn_as: Vec::new(),
            t_s: Vec::new(),
            armed: Vec::new(),
        };
        let mut last: Option<(f64, f64)> = None;
        for (sample, armed) in samples {
            let b = &sample.battery;
            let (Some(v), Some(i)) = (b.voltage_v, b.current_a) else {
                continue;
            };
            if !sample.primary || b.fake_current || !(v.is_finite() && i.is_finite() && v > 0.0) {
                continue;
            }
            let t = sample.t_s;
            let drawn = match (last, series.drawn_as.last()) {
                (Some((t0, i0)), Some(&q)) if t >= t0 => q + 0.5 * (i + i0) * (t - t0),
                (Some(_), Some(&q)) => q,
                _ => 0.0,
            };
            last = Some((t, i));
            series.voltage_v.push(v);
            series.current_a.push(i);
            series.drawn_as.push(drawn);
            series.t_s.push(t);
            series.armed.push(armed);
        }
        series
    }

    /// Whether it has enough samples to fit.
    pub fn fittable(&self) -> bool {
        self.voltage_v.len() >= MIN_SAMPLES
    }

    /// The charge drawn while the vehicle was armed (Ah), when any sample says it was armed;
    /// else between log times `span` (the flight's first and last part), when given; else
    /// over the whole series. None without samples.
    pub fn charge_ah(&self, span: Option<(f64, f64)>) -> Option<f64> {
        if self.drawn_as.is_empty() {
            return None;
        }
        let step = |k: usize| self.drawn_as[k] - self.drawn_as[k - 1];
        let armed = self.armed.contains(&Some(true));
        let counts = |k: usize| -> bool {
            if armed {
                self.armed[k] == Some(true) && self.armed[k - 1] == Some(true)
            } else if let Some((t0, t1)) = span {
                self.t_s[k - 1] >= t0 && self.t_s[k] <= t1
            } else {
                true
            }
        };
        let drawn_as: f64 = (1..self.drawn_as.len())
            .filter(|&k| counts(k))
            .map(step)
            .sum();
        Some(drawn_as / 3600.0)
    }
}

/// The pack samples of the flight in `dir` (None when it has no samples.csv or too few usable
/// samples: the battery is then fitted from the other flights).
pub fn read_pack(dir: &Path, flight: usize) -> Result<Option<PackSeries>, LogFitError> {
    let path = dir.join(SAMPLES_FILE);
    if !path.is_file() {
        return Ok(None);
    }
    let rows = read_samples(&path).map_err(|source| LogFitError::Log {
        dir: dir.display().to_string(),
        source,
    })?;
    let series = PackSeries::of_samples(flight, rows.iter().map(|r| (&r.sample, r.armed)));
    Ok(series.fittable().then_some(series))
}

/// A pack as the fit knows it: its label (cells, capacity), its resistance and its cell's
/// open-circuit voltage curve. The vehicle file's (`battery`), or a flight's plan.json's guard
/// setup (what the flight was flown with).
#[derive(Debug, Clone, PartialEq)]
pub struct PackModel {
    pub cells: u32,
    pub capacity_ah: f64,
    pub internal_resistance_ohm: f64,
    /// State of charge ascending, volts per cell.
    pub ocv_soc: Vec<f64>,
    pub ocv_cell_v: Vec<f64>,
}

impl PackModel {
    /// The pack of `vehicle`'s file.
    pub fn of_vehicle(vehicle: &Vehicle) -> PackModel {
        let b = &vehicle.battery;
        PackModel {
            cells: b.cells,
            capacity_ah: b.capacity_ah,
            internal_resistance_ohm: b.internal_resistance_ohm,
            ocv_soc: b.ocv_soc.clone(),
            ocv_cell_v: b.ocv_cell_v.clone(),
        }
    }

    /// The pack if it can be fitted with: cells, a positive finite capacity and a
    /// non-negative finite resistance, and a curve of two or more finite points, its states of
    /// charge strictly ascending (a pack read from a file is checked, never trusted).
    pub fn checked(self) -> Option<PackModel> {
        let curve_ok = self.ocv_soc.len() >= 2
            && self.ocv_soc.len() == self.ocv_cell_v.len()
            && self
                .ocv_soc
                .iter()
                .chain(&self.ocv_cell_v)
                .all(|x| x.is_finite())
            && self.ocv_soc.windows(2).all(|w| w[1] > w[0]);
        let ok = curve_ok
            && self.cells > 0
            && self.capacity_ah.is_finite()
            && self.capacity_ah > 0.0
            && self.internal_resistance_ohm.is_finite()
            && self.internal_resistance_ohm >= 0.0;
        ok.then_some(self)
    }

    /// The segment of the curve `soc` falls on (clamped to the curve's ends) and the clamped
    /// state of charge.
    fn segment(&self, soc: f64) -> (usize, f64) {
        let n = self.ocv_soc.len();
        let soc = soc.clamp(self.ocv_soc[0], self.ocv_soc[n - 1]);
        let k = self
            .ocv_soc
            .windows(2)
            .position(|w| soc <= w[1])
            .unwrap_or(n - 2);
        (k, soc)
    }

    /// Open-circuit pack voltage at a state of charge (linear interpolation of the cell curve,
    /// clamped at its ends: `Vehicle::open_circuit_voltage_v`'s arithmetic).
    pub fn open_circuit_voltage_v(&self, soc: f64) -> f64 {
        let (k, soc) = self.segment(soc);
        let (s0, s1) = (self.ocv_soc[k], self.ocv_soc[k + 1]);
        let (v0, v1) = (self.ocv_cell_v[k], self.ocv_cell_v[k + 1]);
        f64::from(self.cells) * (v0 + (v1 - v0) * (soc - s0) / (s1 - s0))
    }

    /// The curve's slope at a state of charge (pack volts per unit of charge; 0 past its
    /// ends, where it is held).
    fn slope_v(&self, soc: f64) -> f64 {
        let n = self.ocv_soc.len();
        if soc < self.ocv_soc[0] || soc > self.ocv_soc[n - 1] {
            return 0.0;
        }
        let (k, _) = self.segment(soc);
        let (s0, s1) = (self.ocv_soc[k], self.ocv_soc[k + 1]);
        let (v0, v1) = (self.ocv_cell_v[k], self.ocv_cell_v[k + 1]);
        f64::from(self.cells) * (v1 - v0) / (s1 - s0)
    }
}

/// The battery fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BatteryFit {
    /// `battery.internal_resistance_ohm`, `battery.capacity_ah`.
    pub fitted: Vec<Fitted>,
    /// Flights whose samples were used, and the samples.
    pub flights: usize,
    pub samples: usize,
    /// Terminal voltage residual, rms, with the vehicle file's pack (its SOC0 fitted too) and
    /// with the fitted one.
    pub before_voltage_rms_v: f64,
    pub voltage_rms_v: f64,
    /// Each flight's fitted starting state of charge.
    pub initial_soc: Vec<f64>,
}

/// Sum of squared voltage residuals of one flight at (R, C, SOC0).
fn residual(pack: &PackModel, s: &PackSeries, r_ohm: f64, capacity_as: f64, soc0: f64) -> f64 {
    s.voltage_v
        .iter()
        .zip(&s.current_a)
        .zip(&s.drawn_as)
        .map(|((v, i), q)| {
            let model = pack.open_circuit_voltage_v(soc0 - q / capacity_as) - r_ohm * i;
            (v - model).powi(2)
        })
        .sum()
}

/// The best starting state of charge of one flight (golden section on 0.02..1) and its
/// squared residual sum.
fn best_soc0(pack: &PackModel, s: &PackSeries, r_ohm: f64, capacity_as: f64) -> (f64, f64) {
    let f = |soc0: f64| residual(pack, s, r_ohm, capacity_as, soc0);
    let search = golden_section(&f, (0.02, 1.0), 0.0, 60);
    let soc0 = 0.5 * (search.low + search.high);
    (soc0, f(soc0))
}

/// Fits the pack's resistance and capacity to `packs` (None without any), from the vehicle
/// file's pack.
pub fn fit_battery(vehicle: &Vehicle, packs: &[PackSeries]) -> Option<BatteryFit> {
    fit_pack(&PackModel::of_vehicle(vehicle), packs)
}

/// Fits `pack`'s resistance and capacity to `packs` (None without any).
pub fn fit_pack(pack: &PackModel, packs: &[PackSeries]) -> Option<BatteryFit> {
    if packs.is_empty() {
        return None;
    }
    let samples: usize = packs.iter().map(|p| p.voltage_v.len()).sum();
    let (r0, c0) = (pack.internal_resistance_ohm, pack.capacity_ah);
    let (ranges, best) = search_r_c(pack, packs, 60);
    let (r, c) = best;
    let total = |r_ohm: f64, capacity_ah: f64| -> f64 {
        packs
            .iter()
            .map(|p| best_soc0(pack, p, r_ohm, capacity_ah * 3600.0).1)
            .sum()
    };
    let rms = |sum: f64| (sum / samples.max(1) as f64).sqrt();
    Some(BatteryFit {
        fitted: vec![
            Fitted::new(
                "battery.internal_resistance_ohm",
                r0,
                r,
                ranges[0].1,
                ranges[0].2,
            ),
            Fitted::new("battery.capacity_ah", c0, c, ranges[1].1, ranges[1].2),
        ],
        flights: packs.len(),
        samples,
        before_voltage_rms_v: rms(total(r0, c0)),
        voltage_rms_v: rms(total(r, c)),
        initial_soc: packs
            .iter()
            .map(|p| best_soc0(pack, p, r, c * 3600.0).0)
            .collect(),
    })
}

/// The ranges searched, `(start, low, high)` for R and C, and the shared (R, C) that fits
/// `packs` best (each flight's SOC0 its own best): Nelder-Mead on the starting values' scale.
type Ranges = [(f64, f64, f64); 2];
fn search_r_c(pack: &PackModel, packs: &[PackSeries], iterations: usize) -> (Ranges, (f64, f64)) {
    let r0 = pack.internal_resistance_ohm;
    let c0 = pack.capacity_ah;
    let ranges = [(r0, 0.001, 0.5), (c0, 0.2 * c0, 5.0 * c0)];
    let values = |x: &[f64]| -> (f64, f64) {
        (
            (r0 * x[0]).clamp(ranges[0].1, ranges[0].2),
            (c0 * x[1]).clamp(ranges[1].1, ranges[1].2),
        )
    };
    let total = |r_ohm: f64, capacity_ah: f64| -> f64 {
        packs
            .iter()
            .map(|p| best_soc0(pack, p, r_ohm, capacity_ah * 3600.0).1)
            .sum()
    };
    let objective = |x: &[f64]| {
        let (r, c) = values(x);
        total(r, c)
    };
    let best = nelder_mead(&[1.0, 1.0], &[0.3, 0.2], iterations, &objective);
    (ranges, values(&best))
}

/// The pack as one flight shows it: [`fit_pack`] on that flight alone, refined and given
/// standard errors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FlightPackFit {
    pub capacity_ah: f64,
    /// Standard error of the capacity (Ah).
    pub capacity_sd_ah: f64,
    pub internal_resistance_ohm: f64,
    pub internal_resistance_sd_ohm: f64,
    pub state_of_charge_at_start: f64,
    pub samples: usize,
    pub voltage_rms_v: f64,
}

/// Fits `pack`'s capacity, resistance and starting state of charge to one flight's samples
/// (None with too few samples, or a pack that cannot be fitted with).
///
/// The joint search of [`fit_pack`] gives the start; Gauss-Newton on (R, C, SOC0) with the
/// model's own derivatives (dV/dR = -I, dV/dSOC0 = OCV', dV/dC = OCV' Q / C^2, the curve's
/// slope OCV' on its segment) refines it, and its covariance s^2 (J^T J)^-1, s^2 the residual
/// variance, gives the standard errors. A flight that draws little of its pack moves along a
/// short stretch of the curve, where the capacity only shows through the slope of a small
/// voltage change: its J^T J is small in C and its standard error large. The residuals of
/// neighbouring samples are correlated (the monitor's current filter, the model's lumped
/// pack), so the variance is inflated by (1 + rho) / (1 - rho), rho their lag-one
/// autocorrelation (the AR(1) factor for the variance of an estimate from n correlated
/// samples: G. E. P. Box, G. M. Jenkins, "Time Series Analysis", the effective sample size
/// n (1 - rho) / (1 + rho)).
pub fn fit_flight(pack: &PackModel, series: &PackSeries) -> Option<FlightPackFit> {
    if !series.fittable() {
        return None;
    }
    let n = series.voltage_v.len();
    // The joint search only finds where Gauss-Newton starts, so it runs on at most
    // SEARCH_SAMPLES samples spread over the flight (the charge drawn is cumulative, so every
    // k-th sample is the same curve, sparser); the refinement and its error use them all.
    let one = [series.every(n.div_ceil(SEARCH_SAMPLES))];
    let (ranges, (r_start, c_start)) = search_r_c(pack, &one, 200);
    let soc_start = best_soc0(pack, &one[0], r_start, c_start * 3600.0).0;
    let (soc_low, soc_high) = (pack.ocv_soc[0], pack.ocv_soc[pack.ocv_soc.len() - 1]);
    let clamp = |x: [f64; 3]| -> [f64; 3] {
        [
            x[0].clamp(0.0, ranges[0].2),
            x[1].clamp(ranges[1].1, ranges[1].2),
            x[2].clamp(soc_low, soc_high),
        ]
    };
    // x = (R ohm, C Ah, SOC0).
    let residuals = |x: [f64; 3]| -> Vec<f64> {
        let capacity_as = x[1] * 3600.0;
        (0..n)
            .map(|k| {
                let soc = x[2] - series.drawn_as[k] / capacity_as;
                series.voltage_v[k]
                    - (pack.open_circuit_voltage_v(soc) - x[0] * series.current_a[k])
            })
            .collect()
    };
    let sum = |r: &[f64]| r.iter().map(|e| e * e).sum::<f64>();
    // Normal equations J^T J and J^T e of the model's derivatives at x.
    let normal = |x: [f64; 3], e: &[f64]| -> ([[f64; 3]; 3], [f64; 3]) {
        let capacity_as = x[1] * 3600.0;
        let mut a = [[0.0; 3]; 3];
        let mut g = [0.0; 3];
        for ((&q, &i), &ek) in series.drawn_as.iter().zip(&series.current_a).zip(e) {
            let slope = pack.slope_v(x[2] - q / capacity_as);
            // Derivatives of the model voltage; C in Ah (q / C^2 with C in A s, times 3600).
            let j = [-i, slope * q / (capacity_as * x[1]), slope];
            for r in 0..3 {
                g[r] += j[r] * ek;
                for c in 0..3 {
                    a[r][c] += j[r] * j[c];
                }
            }
        }
        (a, g)
    };
    let mut x = clamp([r_start, c_start, soc_start]);
    let mut e = residuals(x);
    let mut cost = sum(&e);
    for _ in 0..30 {
        let (a, g) = normal(x, &e);
        let Some(step) = solve3(a, g) else {
            break;
        };
        // Damped: halve the step until the residual sum falls.
        let mut scale = 1.0;
        let mut moved = false;
        for _ in 0..20 {
            let trial = clamp([
                x[0] + scale * step[0],
                x[1] + scale * step[1],
                x[2] + scale * step[2],
            ]);
            let trial_e = residuals(trial);
            let trial_cost = sum(&trial_e);
            if trial_cost < cost {
                let gain = cost - trial_cost;
                x = trial;
                e = trial_e;
                cost = trial_cost;
                moved = gain > 1e-12 * cost.max(1e-12);
                break;
            }
            scale *= 0.5;
        }
        if !moved {
            break;
        }
    }
    let (a, _) = normal(x, &e);
    let inverse = invert3(a)?;
    let variance = cost / (n.saturating_sub(3).max(1)) as f64;
    let rho = lag_one_correlation(&e).clamp(0.0, 0.99);
    let inflated = variance * (1.0 + rho) / (1.0 - rho);
    let sd = |k: usize| (inflated * inverse[k][k]).max(0.0).sqrt();
    let fit = FlightPackFit {
        capacity_ah: x[1],
        capacity_sd_ah: sd(1),
        internal_resistance_ohm: x[0],
        internal_resistance_sd_ohm: sd(0),
        state_of_charge_at_start: x[2],
        samples: n,
        voltage_rms_v: (cost / n as f64).sqrt(),
    };
    let finite = [
        fit.capacity_ah,
        fit.capacity_sd_ah,
        fit.internal_resistance_ohm,
        fit.internal_resistance_sd_ohm,
        fit.state_of_charge_at_start,
        fit.voltage_rms_v,
    ]
    .iter()
    .all(|v| v.is_finite());
    finite.then_some(fit)
}

/// The lag-one autocorrelation of `e` about its mean (0 for fewer than 3 values or none
/// varying).
fn lag_one_correlation(e: &[f64]) -> f64 {
    if e.len() < 3 {
        return 0.0;
    }
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    let var: f64 = e.iter().map(|x| (x - mean).powi(2)).sum();
    if var <= 0.0 {
        return 0.0;
    }
    let cov: f64 = e.windows(2).map(|w| (w[0] - mean) * (w[1] - mean)).sum();
    cov / var
}

fn det3(a: &[[f64; 3]; 3]) -> f64 {
    a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
}

/// The inverse of a 3x3 matrix by cofactors (None when singular).
fn invert3(a: [[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let det = det3(&a);
    let scale = a.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
    if !det.is_finite() || det.abs() <= 1e-300 || det.abs() <= 1e-14 * scale.powi(3) {
        return None;
    }
    let mut inv = [[0.0; 3]; 3];
    for (r, row) in inv.iter_mut().enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            // The cofactor of a[c][r] (the adjugate is the cofactors transposed).
            let (r1, r2) = ((c + 1) % 3, (c + 2) % 3);
            let (c1, c2) = ((r + 1) % 3, (r + 2) % 3);
            *v = (a[r1][c1] * a[r2][c2] - a[r1][c2] * a[r2][c1]) / det;
        }
    }
    Some(inv)
}

/// Solves `a x = b` (None when `a` is singular).
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let inv = invert3(a)?;
    let mut x = [0.0; 3];
    for (r, xr) in x.iter_mut().enumerate() {
        *xr = (0..3).map(|c| inv[r][c] * b[c]).sum();
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flight of `truth`'s pack from `soc0`: current steps between 5 and 60 A, 10 Hz, with
    /// deterministic noise of about 10 mV.
    fn flight(truth: &Vehicle, soc0: f64, flight: usize) -> PackSeries {
        let c_as = truth.battery.capacity_ah * 3600.0;
        let r = truth.battery.internal_resistance_ohm;
        let mut s = PackSeries {
            flight,
            voltage_v: Vec::new(),
            current_a: Vec::new(),
            drawn_as: Vec::new(),
            t_s: Vec::new(),
            armed: Vec::new(),
        };
        let mut q = 0.0;
        for k in 0..3000 {
            let i = if (k / 100) % 3 == 0 {
                5.0
            } else {
                40.0 + 20.0 * ((k / 50) % 2) as f64
            };
            let noise = 0.01 * ((k * 7919 % 200) as f64 / 100.0 - 1.0);
            s.current_a.push(i);
            s.drawn_as.push(q);
            s.t_s.push(k as f64 * 0.1);
            s.armed.push(Some(true));
            s.voltage_v
                .push(truth.open_circuit_voltage_v(soc0 - q / c_as) - r * i + noise);
            q += i * 0.1;
        }
        s
    }

    #[test]
    fn a_weaker_pack_is_found_from_its_voltage_under_load() {
        let given = Vehicle::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000"))
            .expect("the shipped vehicle");
        let mut truth = given.clone();
        truth.battery.capacity_ah = 8.0;
        truth.battery.internal_resistance_ohm = 0.035;
        let packs = [flight(&truth, 1.0, 0), flight(&truth, 0.9, 1)];
        let fit = fit_battery(&given, &packs).expect("fitted");
        let (r, c) = (fit.fitted[0].value, fit.fitted[1].value);
        assert!((r - 0.035).abs() < 0.002, "{fit:?}");
        assert!((c - 8.0).abs() < 0.3, "{fit:?}");
        assert!((fit.initial_soc[1] - 0.9).abs() < 0.02, "{fit:?}");
        assert!(
            fit.voltage_rms_v < 0.02 && fit.before_voltage_rms_v > 0.1,
            "{fit:?}"
        );
        assert!(fit_battery(&given, &[]).is_none());
    }

    /// A flight of `truth`'s pack from full drawing `share` of it: 45 A with 5 A rests, 10 Hz,
    /// about 20 mV of deterministic noise.
    fn drawing(truth: &Vehicle, share: f64) -> PackSeries {
        let c_as = truth.battery.capacity_ah * 3600.0;
        let r = truth.battery.internal_resistance_ohm;
        let samples: Vec<(f64, f64)> = {
            let mut out = Vec::new();
            let mut q = 0.0;
            let mut k = 0usize;
            while q < share * c_as {
                let i = if (k / 150).is_multiple_of(4) {
                    5.0
                } else {
                    45.0
                };
                out.push((q, i));
                q += i * 0.1;
                k += 1;
            }
            out
        };
        let mut s = PackSeries::of_samples(0, std::iter::empty());
        for (k, (q, i)) in samples.into_iter().enumerate() {
            let noise = 0.02 * ((k * 7919 % 200) as f64 / 100.0 - 1.0);
            s.voltage_v
                .push(truth.open_circuit_voltage_v(1.0 - q / c_as) - r * i + noise);
            s.current_a.push(i);
            s.drawn_as.push(q);
            s.t_s.push(k as f64 * 0.1);
            s.armed.push(Some(true));
        }
        s
    }

    #[test]
    fn one_flight_gives_the_capacity_and_a_shallow_flight_a_wider_error() {
        let given = Vehicle::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000"))
            .expect("the shipped vehicle");
        let mut truth = given.clone();
        truth.battery.capacity_ah = 8.5;
        let pack = PackModel::of_vehicle(&given);
        let deep = fit_flight(&pack, &drawing(&truth, 0.4)).expect("fitted");
        let shallow = fit_flight(&pack, &drawing(&truth, 0.05)).expect("fitted");
        for fit in [&deep, &shallow] {
            assert!(
                (fit.capacity_ah - 8.5).abs() < 3.0 * fit.capacity_sd_ah + 0.02,
                "{fit:?}"
            );
            assert!(
                (fit.internal_resistance_ohm - 0.02).abs() < 0.001,
                "{fit:?}"
            );
            assert!((fit.state_of_charge_at_start - 1.0).abs() < 0.01, "{fit:?}");
        }
        assert!((deep.capacity_ah - 8.5).abs() < 0.1, "{deep:?}");
        // A twentieth of the pack says much less of its capacity than two fifths.
        assert!(
            shallow.capacity_sd_ah > 5.0 * deep.capacity_sd_ah,
            "{shallow:?} {deep:?}"
        );
        // Too few samples, or a pack curve that cannot be fitted with: no fit.
        let mut few = drawing(&truth, 0.4);
        few.voltage_v.truncate(10);
        assert_eq!(fit_flight(&pack, &few), None);
        let broken = PackModel {
            ocv_soc: vec![0.0, 0.0],
            ocv_cell_v: vec![3.5, 4.2],
            ..pack.clone()
        };
        assert_eq!(broken.checked(), None);
        assert!(pack.clone().checked().is_some());
    }

    #[test]
    fn the_charge_drawn_counts_the_armed_samples_only() {
        let sample = |t_s: f64, current_a: f64| PowerSample {
            t_s,
            wall_us: 0,
            battery: crate::flightlog::telemetry::Battery {
                source: crate::flightlog::telemetry::BatterySource::SysStatus,
                voltage_v: Some(24.0),
                current_a: Some(current_a),
                consumed_mah: None,
                energy_consumed_j: None,
                remaining_pct: None,
                fake_current: false,
            },
            primary: true,
        };
        let samples = [
            (sample(0.0, 1.0), Some(false)),
            (sample(10.0, 36.0), Some(true)),
            (sample(20.0, 36.0), Some(true)),
            (sample(30.0, 1.0), Some(false)),
        ];
        let s = PackSeries::of_samples(0, samples.iter().map(|(s, a)| (s, *a)));
        // 36 A for the 10 s armed: 0.1 Ah.
        assert!((s.charge_ah(None).unwrap() - 0.1).abs() < 1e-12);
        // Without arming said: the span given, else everything.
        let unsaid = PackSeries::of_samples(0, samples.iter().map(|(s, _)| (s, None)));
        assert!((unsaid.charge_ah(Some((10.0, 20.0))).unwrap() - 0.1).abs() < 1e-12);
        let all = (0.5 * 37.0 * 10.0 * 2.0 + 36.0 * 10.0) / 3600.0;
        assert!((unsaid.charge_ah(None).unwrap() - all).abs() < 1e-12);
        assert_eq!(
            PackSeries::of_samples(0, std::iter::empty()).charge_ah(None),
            None
        );
    }
}
