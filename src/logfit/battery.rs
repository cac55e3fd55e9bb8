//! The pack's internal resistance and capacity from the voltage and current samples of logged
//! flights (samples.csv), the battery part of `calibrate --from-logs`. Leg energies cannot show
//! them (the power module measures terminal energy); the terminal voltage can.
//!
//! Model (the physics model's lumped pack, `physics::powertrain`; the mock's `sim::battery`):
//! V = OCV(SOC) - R I with SOC = SOC0 - Q / C, Q the charge drawn since the flight's first
//! sample (trapezoid of the measured current over vehicle time). The OCV curve is the vehicle
//! file's (`battery.ocv_soc`, `ocv_cell_v`): the fit is as good as that curve. Each flight's
//! starting state of charge SOC0 is unknown (a pack is not always full) and fitted per flight by
//! golden-section search; R and C are shared and fitted by Nelder-Mead on the squared voltage
//! residuals. Only the primary battery's samples with a measured voltage and current count (not
//! PX4 SITL's fake current).

use std::path::Path;

use serde::Serialize;

use super::{Fitted, LogFitError};
use crate::flightlog::csv::read_samples;
use crate::flightlog::recorder::SAMPLES_FILE;
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
    let mut series = PackSeries {
        flight,
        voltage_v: Vec::new(),
        current_a: Vec::new(),
        drawn_as: Vec::new(),
    };
    let mut last: Option<(f64, f64)> = None;
    for row in rows {
        let b = &row.sample.battery;
        let (Some(v), Some(i)) = (b.voltage_v, b.current_a) else {
            continue;
        };
        if !row.sample.primary || b.fake_current || !(v.is_finite() && i.is_finite() && v > 0.0) {
            continue;
        }
        let t = row.sample.t_s;
        let drawn = match (last, series.drawn_as.last()) {
            (Some((t0, i0)), Some(&q)) if t >= t0 => q + 0.5 * (i + i0) * (t - t0),
            (Some(_), Some(&q)) => q,
            _ => 0.0,
        };
        last = Some((t, i));
        series.voltage_v.push(v);
        series.current_a.push(i);
        series.drawn_as.push(drawn);
    }
    Ok((series.voltage_v.len() >= MIN_SAMPLES).then_some(series))
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
fn residual(vehicle: &Vehicle, s: &PackSeries, r_ohm: f64, capacity_as: f64, soc0: f64) -> f64 {
    s.voltage_v
        .iter()
        .zip(&s.current_a)
        .zip(&s.drawn_as)
        .map(|((v, i), q)| {
            let model = vehicle.open_circuit_voltage_v(soc0 - q / capacity_as) - r_ohm * i;
            (v - model).powi(2)
        })
        .sum()
}

/// The best starting state of charge of one flight (golden section on 0.02..1) and its
/// squared residual sum.
fn best_soc0(vehicle: &Vehicle, s: &PackSeries, r_ohm: f64, capacity_as: f64) -> (f64, f64) {
    let f = |soc0: f64| residual(vehicle, s, r_ohm, capacity_as, soc0);
    let search = golden_section(&f, (0.02, 1.0), 0.0, 60);
    let soc0 = 0.5 * (search.low + search.high);
    (soc0, f(soc0))
}

/// Fits the pack's resistance and capacity to `packs` (None without any).
pub fn fit_battery(vehicle: &Vehicle, packs: &[PackSeries]) -> Option<BatteryFit> {
    if packs.is_empty() {
        return None;
    }
    let samples: usize = packs.iter().map(|p| p.voltage_v.len()).sum();
    let r0 = vehicle.battery.internal_resistance_ohm;
    let c0 = vehicle.battery.capacity_ah;
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
            .map(|p| best_soc0(vehicle, p, r_ohm, capacity_ah * 3600.0).1)
            .sum()
    };
    let objective = |x: &[f64]| {
        let (r, c) = values(x);
        total(r, c)
    };
    let best = nelder_mead(&[1.0, 1.0], &[0.3, 0.2], 60, &objective);
    let (r, c) = values(&best);
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
            .map(|p| best_soc0(vehicle, p, r, c * 3600.0).0)
            .collect(),
    })
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
}
