//! Battery energy over a stretch of vehicle time: the trapezoidal integral of V*I over the valid
//! samples, with power interpolated linearly at the stretch's ends so that stretches cut from one
//! flight add up exactly to the whole. Invalid samples are left out, never integrated as zero:
//! unknown current (-1), PX4's fake current, unknown voltage, and voltage outliers (far from the
//! median of their neighbours). A stretch longer than the gap limit without a valid sample is a
//! `telemetry_gap`; a stretch less than half covered, or with no valid sample at all, is
//! `unmeasurable` (no energy). A stretch that overlaps vehicle time lost from the log (a corrupt
//! span of a replayed .tlog, between the readings either side of it) is a `log_gap`, the time
//! lost uncovered as in a telemetry gap. The autopilot's own charge counter cross-checks the integral:
//! consumed mAh x mean voltage, `consumed_mismatch` when they differ by more than 10% over
//! enough charge for the counter's 1 mAh resolution not to matter.

use serde::{Deserialize, Serialize};

use super::samples::PowerSample;
use super::telemetry::Battery;

/// Why a measurement should not be trusted as it is (snake_case names in the JSON).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Flag {
    TelemetryGap,
    CurrentUnknown,
    FakeCurrent,
    VoltageOutlier,
    Unmeasurable,
    ConsumedMismatch,
    /// The flight ended inside it.
    Incomplete,
    /// Overlaps a span of the .tlog that was not records (corrupt) and was skipped: readings of
    /// it may be missing.
    LogGap,
    /// A leg the autopilot finished before the vehicle came within the arrival radius (its
    /// acceptance radius is larger): the leg ends when the autopilot moved on.
    MissedRadius,
    /// A leg that began further than `report::FAR_START_M` from the point it was planned to
    /// leave (the vehicle took off elsewhere, or was flown there by hand): the model priced it
    /// from hover on that point.
    FarStart,
}

impl Flag {
    pub fn name(self) -> &'static str {
        match self {
            Flag::TelemetryGap => "telemetry_gap",
            Flag::CurrentUnknown => "current_unknown",
            Flag::FakeCurrent => "fake_current",
            Flag::VoltageOutlier => "voltage_outlier",
            Flag::Unmeasurable => "unmeasurable",
            Flag::ConsumedMismatch => "consumed_mismatch",
            Flag::Incomplete => "incomplete",
            Flag::LogGap => "log_gap",
            Flag::MissedRadius => "missed_radius",
            Flag::FarStart => "far_start",
        }
    }
    /// What the flag says of a part, in a few words for a report's legend.
    pub fn meaning(self) -> &'static str {
        match self {
            Flag::TelemetryGap => "battery readings missing for a while",
            Flag::CurrentUnknown => "no current reported: energy not measured",
            Flag::FakeCurrent => "the current is the autopilot's estimate, not a sensor's",
            Flag::VoltageOutlier => "a voltage reading out of line was left out",
            Flag::Unmeasurable => "too few battery readings to measure",
            Flag::ConsumedMismatch => "the autopilot's charge counter disagrees with V x I",
            Flag::Incomplete => "cut short: not compared with its prediction",
            Flag::LogGap => "overlaps a corrupt span of the log",
            Flag::MissedRadius => "the autopilot moved on before the arrival radius",
            Flag::FarStart => "began far from the point it was planned to leave",
        }
    }
}

/// Thresholds of the measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnergyConfig {
    /// Longest stretch of vehicle time without a valid sample that is not a gap.
    pub gap_s: f64,
    /// Neighbours on each side whose median judges a voltage.
    pub outlier_neighbours: usize,
    /// A voltage further than max(abs, rel x median) from its neighbours' median is an outlier.
    pub outlier_abs_v: f64,
    pub outlier_rel: f64,
    /// Least covered fraction for a measurement.
    pub min_coverage: f64,
    /// Least charge counted for the consumed cross-check (1 mAh resolution at both ends: 50 mAh
    /// keeps the rounding under 4%).
    pub consumed_min_mah: f64,
    pub consumed_tolerance: f64,
    /// Cross-check against the autopilot's energy counter instead of its charge counter when
    /// the readings carry one (an onboard log: ArduPilot's BAT `EnrgTot`). Off for MAVLink,
    /// whose BATTERY_STATUS counts energy in 100 J steps and is not filled by every autopilot.
    pub energy_counter: bool,
    /// Least energy counted for that cross-check (J): 2 kJ keeps a 100 J step under 5%.
    pub consumed_min_j: f64,
}

impl Default for EnergyConfig {
    fn default() -> Self {
        EnergyConfig {
            gap_s: 1.0,
            outlier_neighbours: 3,
            outlier_abs_v: 1.0,
            outlier_rel: 0.1,
            min_coverage: 0.5,
            consumed_min_mah: 50.0,
            consumed_tolerance: 0.1,
            energy_counter: false,
            consumed_min_j: 2000.0,
        }
    }
}

/// The energy of one stretch of the flight.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Measurement {
    /// None when unmeasurable.
    pub energy_j: Option<f64>,
    pub duration_s: f64,
    /// Fraction of the stretch within the gap limit of a valid sample.
    pub coverage: f64,
    /// The autopilot's charge counter x mean voltage, when it counted.
    pub consumed_j: Option<f64>,
    pub flags: Vec<Flag>,
}

/// The primary battery's samples of a flight, in time order, with their outlier judgement.
#[derive(Debug, Clone, Default)]
pub struct PowerSeries {
    cfg: EnergyConfig,
    samples: Vec<PowerSample>,
    /// Indices of samples with a known voltage.
    with_voltage: Vec<usize>,
    outlier: Vec<bool>,
    /// Stretches of vehicle time lost from the log, (from, to).
    lost: Vec<(f64, f64)>,
}

fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    Some(if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    })
}

/// Integral over [a, b] of the linear function through (t0, p0), (t1, p1).
fn trapezoid(t0: f64, p0: f64, t1: f64, p1: f64, a: f64, b: f64) -> f64 {
    let at = |t: f64| {
        if t1 > t0 {
            p0 + (p1 - p0) * (t - t0) / (t1 - t0)
        } else {
            0.5 * (p0 + p1)
        }
    };
    0.5 * (at(a) + at(b)) * (b - a)
}

impl PowerSeries {
    pub fn new(cfg: EnergyConfig) -> PowerSeries {
        PowerSeries {
            cfg,
            ..PowerSeries::default()
        }
    }

    pub fn config(&self) -> &EnergyConfig {
        &self.cfg
    }

    pub fn len(&self) -> usize {
        self.samples.len()
    }

    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// Adds a sample (non-primary samples are not part of the series). Times never go back.
    pub fn push(&mut self, sample: PowerSample) {
        if !sample.primary {
            return;
        }
        let t_s = self
            .samples
            .last()
            .map_or(sample.t_s, |last| sample.t_s.max(last.t_s));
        let index = self.samples.len();
        self.samples.push(PowerSample { t_s, ..sample });
        self.outlier.push(false);
        if sample.battery.voltage_v.is_some() {
            self.with_voltage.push(index);
            // A new neighbour changes the verdict on the last few voltages.
            let n = self.with_voltage.len();
            let from = n.saturating_sub(self.cfg.outlier_neighbours + 1);
            for p in from..n {
                let verdict = self.judge(p);
                self.outlier[self.with_voltage[p]] = verdict;
            }
        }
    }

    /// Marks vehicle time `from_s` to `to_s` as lost from the log (see [`Flag::LogGap`]).
    pub fn lose(&mut self, from_s: f64, to_s: f64) {
        self.lost.push((from_s.min(to_s), from_s.max(to_s)));
    }

    /// Whether the voltage at position `p` of `with_voltage` is an outlier.
    fn judge(&self, p: usize) -> bool {
        let w = self.cfg.outlier_neighbours;
        let n = self.with_voltage.len();
        let voltage = |q: usize| {
            self.samples[self.with_voltage[q]]
                .battery
                .voltage_v
                .unwrap_or(0.0)
        };
        let mut neighbours: Vec<f64> = (p.saturating_sub(w)..p)
            .chain(p + 1..(p + 1 + w).min(n))
            .map(voltage)
            .collect();
        if neighbours.len() < 2 {
            return false;
        }
        let Some(m) = median(&mut neighbours) else {
            return false;
        };
        (voltage(p) - m).abs() > self.cfg.outlier_abs_v.max(self.cfg.outlier_rel * m.abs())
    }

    /// The samples, in time order.
    pub fn samples(&self) -> &[PowerSample] {
        &self.samples
    }

    /// Whether sample `i` is integrated.
    pub fn is_valid(&self, i: usize) -> bool {
        self.samples[i].power_w().is_some() && !self.outlier[i]
    }

    /// (t, power) of every valid sample: what the plots draw.
    pub fn valid_power(&self) -> Vec<(f64, f64)> {
        (0..self.samples.len())
            .filter(|&i| self.is_valid(i))
            .filter_map(|i| self.samples[i].power_w().map(|p| (self.samples[i].t_s, p)))
            .collect()
    }

    fn point(&self, i: usize) -> (f64, f64) {
        (
            self.samples[i].t_s,
            self.samples[i].power_w().unwrap_or(0.0),
        )
    }

    /// The energy over [t0, t1] of vehicle time.
    pub fn measure(&self, t0: f64, t1: f64) -> Measurement {
        let t1 = t1.max(t0);
        let duration_s = t1 - t0;
        let mut flags = Vec::new();
        let lo = self.samples.partition_point(|s| s.t_s < t0);
        let hi = self.samples.partition_point(|s| s.t_s <= t1);
        for i in lo..hi {
            let s = &self.samples[i];
            if s.battery.fake_current {
                flags.push(Flag::FakeCurrent);
            } else if s.battery.current_a.is_none() {
                flags.push(Flag::CurrentUnknown);
            }
            if self.outlier[i] {
                flags.push(Flag::VoltageOutlier);
            }
        }
        let before = (0..lo).rev().find(|&i| self.is_valid(i));
        let after = (hi..self.samples.len()).find(|&i| self.is_valid(i));
        let mut points: Vec<(f64, f64)> = before.map(|i| self.point(i)).into_iter().collect();
        points.extend(
            (lo..hi)
                .filter(|&i| self.is_valid(i))
                .map(|i| self.point(i)),
        );
        points.extend(after.map(|i| self.point(i)));

        // Coverage: the stretches between consecutive valid samples (or the ends of the
        // interval where there is no valid sample beyond them) longer than the gap limit.
        let mut times: Vec<f64> = Vec::with_capacity(points.len() + 2);
        if before.is_none() {
            times.push(t0);
        }
        times.extend(points.iter().map(|p| p.0));
        if after.is_none() {
            times.push(t1);
        }
        let mut uncovered_s = 0.0;
        let mut uncovered = Vec::new();
        for pair in times.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            if b - a > self.cfg.gap_s {
                let overlap = b.min(t1) - a.max(t0);
                if overlap > 0.0 || (duration_s == 0.0 && a <= t0 && t0 <= b) {
                    flags.push(Flag::TelemetryGap);
                    uncovered_s += overlap.max(0.0);
                    uncovered.push((a.max(t0), b.min(t1)));
                }
            }
        }
        let lost: Vec<(f64, f64)> = self
            .lost
            .iter()
            .filter(|&&(a, b)| (a < t1 && b > t0) || (duration_s == 0.0 && a <= t0 && t0 <= b))
            .map(|&(a, b)| (a.max(t0), b.min(t1)))
            .collect();
        if !lost.is_empty() {
            flags.push(Flag::LogGap);
            uncovered.extend(lost);
            uncovered_s = union_length(&mut uncovered);
        }
        let coverage = if duration_s > 0.0 {
            (1.0 - uncovered_s / duration_s).clamp(0.0, 1.0)
        } else if flags.contains(&Flag::TelemetryGap)
            || flags.contains(&Flag::LogGap)
            || points.is_empty()
        {
            0.0
        } else {
            1.0
        };
        let energy_j = if points.is_empty() || coverage < self.cfg.min_coverage {
            flags.push(Flag::Unmeasurable);
            None
        } else {
            Some(integrate(&points, t0, t1))
        };
        let counted_j = self
            .cfg
            .energy_counter
            .then(|| self.counted(t0, t1, |b| b.energy_consumed_j))
            .flatten();
        let consumed_j = match counted_j {
            Some(j) => Some((j, j >= self.cfg.consumed_min_j)),
            None => (self.consumed_j(t0, t1, &points))
                .map(|(j, mah)| (j, mah >= self.cfg.consumed_min_mah)),
        };
        if let (Some(e), Some((c, enough))) = (energy_j, consumed_j) {
            if enough && (e - c).abs() > self.cfg.consumed_tolerance * c.abs() {
                flags.push(Flag::ConsumedMismatch);
            }
        }
        flags.sort();
        flags.dedup();
        Measurement {
            energy_j,
            duration_s,
            coverage,
            consumed_j: consumed_j.map(|(c, _)| c),
            flags,
        }
    }

    /// How much a counter of the autopilot's (`count` of a reading) rose over [t0, t1],
    /// interpolated between its readings, when they bracket both ends.
    fn counted(&self, t0: f64, t1: f64, count: impl Fn(&Battery) -> Option<f64>) -> Option<f64> {
        let counted: Vec<(f64, f64)> = self
            .samples
            .iter()
            .filter(|s| !s.battery.fake_current)
            .filter_map(|s| count(&s.battery).map(|c| (s.t_s, c)))
            .collect();
        let at = |t: f64| -> Option<f64> {
            let k = counted.partition_point(|c| c.0 < t);
            let hi = counted.get(k)?;
            if hi.0 == t || k == 0 {
                return (hi.0 == t).then_some(hi.1);
            }
            let lo = counted[k - 1];
            Some(lo.1 + (hi.1 - lo.1) * (t - lo.0) / (hi.0 - lo.0))
        };
        Some(at(t1)? - at(t0)?)
    }

    /// The charge counter's energy over [t0, t1]: (J, mAh), when it brackets both ends.
    fn consumed_j(&self, t0: f64, t1: f64, points: &[(f64, f64)]) -> Option<(f64, f64)> {
        let mah = self.counted(t0, t1, |b| b.consumed_mah)?;
        let voltages: Vec<f64> = points
            .iter()
            .filter_map(|&(t, _)| {
                let i = self.samples.partition_point(|s| s.t_s < t);
                self.samples.get(i).and_then(|s| s.battery.voltage_v)
            })
            .collect();
        if voltages.is_empty() {
            return None;
        }
        let mean_v = voltages.iter().sum::<f64>() / voltages.len() as f64;
        // 1 mAh = 3.6 C.
        Some((mah * 3.6 * mean_v, mah))
    }
}

/// Total length of the union of the intervals (a, b), a <= b.
fn union_length(intervals: &mut [(f64, f64)]) -> f64 {
    intervals.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut total = 0.0;
    let mut current: Option<(f64, f64)> = None;
    for &(a, b) in intervals.iter() {
        match current {
            Some((ca, cb)) if a <= cb => current = Some((ca, cb.max(b))),
            _ => {
                if let Some((ca, cb)) = current {
                    total += cb - ca;
                }
                current = Some((a, b));
            }
        }
    }
    total + current.map_or(0.0, |(a, b)| b - a)
}

/// Integral over [t0, t1] of the piecewise-linear function through `points` (held constant
/// beyond its ends).
fn integrate(points: &[(f64, f64)], t0: f64, t1: f64) -> f64 {
    let (Some(&first), Some(&last)) = (points.first(), points.last()) else {
        return 0.0;
    };
    let mut total = 0.0;
    if t0 < first.0 {
        total += first.1 * (t1.min(first.0) - t0);
    }
    if t1 > last.0 {
        total += last.1 * (t1 - t0.max(last.0));
    }
    for pair in points.windows(2) {
        let ((a, pa), (b, pb)) = (pair[0], pair[1]);
        let (lo, hi) = (a.max(t0), b.min(t1));
        if hi > lo {
            total += trapezoid(a, pa, b, pb, lo, hi);
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::telemetry::{Battery, BatterySource};

    fn sample(t_s: f64, voltage_v: Option<f64>, current_a: Option<f64>) -> PowerSample {
        PowerSample {
            t_s,
            wall_us: 0,
            battery: Battery {
                source: BatterySource::BatteryStatus {
                    id: 0,
                    component: 1,
                },
                voltage_v,
                current_a,
                consumed_mah: None,
                energy_consumed_j: None,
                remaining_pct: None,
                fake_current: false,
            },
            primary: true,
        }
    }

    /// 10 Hz samples of a constant 20 V from 0 to `end_s`, current `amps(t)`.
    fn series(end_s: f64, amps: impl Fn(f64) -> Option<f64>) -> PowerSeries {
        let mut s = PowerSeries::new(EnergyConfig::default());
        let n = (end_s * 10.0).round() as usize;
        for k in 0..=n {
            let t = k as f64 * 0.1;
            s.push(sample(t, Some(20.0), amps(t)));
        }
        s
    }

    #[test]
    fn a_linear_power_ramp_integrates_exactly_including_interpolated_ends() {
        // P(t) = 20 V x (10 + 2t) A = 200 + 40 t W; integral over [1.23, 7.89] by hand:
        // 200 (6.66) + 20 (7.89^2 - 1.23^2) = 1332 + 20 (62.2521 - 1.5129) = 2546.784 J.
        let s = series(10.0, |t| Some(10.0 + 2.0 * t));
        let m = s.measure(1.23, 7.89);
        let e = m.energy_j.expect("measured");
        assert!((e - 2546.784).abs() < 1e-9, "{e}");
        assert!(m.flags.is_empty(), "{:?}", m.flags);
        assert_eq!(m.coverage, 1.0);
    }

    #[test]
    fn parts_of_a_flight_add_up_to_the_whole() {
        let s = series(30.0, |t| Some(40.0 + 10.0 * (t * 0.7).sin()));
        let cuts = [0.0, 2.37, 2.37, 9.05, 9.111, 17.5, 29.99, 30.0];
        let parts: f64 = cuts
            .windows(2)
            .map(|c| s.measure(c[0], c[1]).energy_j.expect("measured"))
            .sum();
        let whole = s.measure(0.0, 30.0).energy_j.expect("measured");
        assert!((parts - whole).abs() < 1e-9 * whole, "{parts} vs {whole}");
    }

    #[test]
    fn a_stretch_without_samples_is_flagged_a_gap_and_interpolated_across() {
        let mut s = PowerSeries::new(EnergyConfig::default());
        for k in 0..=100 {
            let t = f64::from(k) * 0.1;
            if !(4.0..6.0).contains(&t) {
                s.push(sample(t, Some(20.0), Some(10.0)));
            }
        }
        let m = s.measure(3.0, 8.0);
        assert!(m.flags.contains(&Flag::TelemetryGap), "{:?}", m.flags);
        // 200 W throughout: interpolating across the gap still gives 1000 J; 2.1 s of 5 s is
        // uncovered (3.9 .. 6.0).
        assert!((m.energy_j.expect("measured") - 1000.0).abs() < 1e-9);
        assert!(
            (m.coverage - (1.0 - 2.1 / 5.0)).abs() < 1e-9,
            "{}",
            m.coverage
        );
        // A stretch inside the gap is unmeasurable.
        let inside = s.measure(4.2, 5.8);
        assert_eq!(inside.energy_j, None);
        assert!(inside.flags.contains(&Flag::Unmeasurable));
        // Away from the gap: clean.
        assert!(s.measure(0.5, 3.5).flags.is_empty());
    }

    #[test]
    fn a_stretch_overlapping_time_lost_from_the_log_is_flagged_and_counts_it_uncovered() {
        let mut s = series(10.0, |_| Some(10.0));
        s.lose(4.0, 4.3);
        let m = s.measure(3.0, 8.0);
        assert!(m.flags.contains(&Flag::LogGap), "{:?}", m.flags);
        assert!(!m.flags.contains(&Flag::TelemetryGap));
        assert!(
            (m.coverage - (1.0 - 0.3 / 5.0)).abs() < 1e-9,
            "{}",
            m.coverage
        );
        // Interpolated across, as a telemetry gap is: 200 W throughout.
        assert!((m.energy_j.expect("measured") - 1000.0).abs() < 1e-9);
        // Away from it: clean.
        assert!(s.measure(0.0, 3.9).flags.is_empty());
        assert!(s.measure(4.4, 9.0).flags.is_empty());
        // Mostly lost: unmeasurable.
        s.lose(5.0, 7.9);
        let lost = s.measure(4.5, 8.0);
        assert_eq!(lost.energy_j, None);
        assert!(lost.flags.contains(&Flag::Unmeasurable));
    }

    #[test]
    fn lost_time_inside_a_telemetry_gap_is_not_counted_twice() {
        let mut s = PowerSeries::new(EnergyConfig::default());
        for k in 0..=100 {
            let t = f64::from(k) * 0.1;
            if !(4.0..6.0).contains(&t) {
                s.push(sample(t, Some(20.0), Some(10.0)));
            }
        }
        s.lose(4.5, 6.5);
        let m = s.measure(3.0, 8.0);
        assert!(m.flags.contains(&Flag::TelemetryGap) && m.flags.contains(&Flag::LogGap));
        // 3.9 .. 6.0 without samples and 4.5 .. 6.5 lost: 3.9 .. 6.5 uncovered.
        assert!(
            (m.coverage - (1.0 - 2.6 / 5.0)).abs() < 1e-9,
            "{}",
            m.coverage
        );
    }

    #[test]
    fn current_minus_one_samples_are_flagged_and_not_integrated_as_zero() {
        // Unknown current between 2 s and 2.5 s: the integral interpolates over them at 200 W.
        let s = series(5.0, |t| {
            if (2.0..2.55).contains(&t) {
                None
            } else {
                Some(10.0)
            }
        });
        let m = s.measure(1.0, 4.0);
        assert!(m.flags.contains(&Flag::CurrentUnknown), "{:?}", m.flags);
        assert!(
            !m.flags.contains(&Flag::TelemetryGap),
            "0.7 s is within the gap limit"
        );
        assert!((m.energy_j.expect("measured") - 600.0).abs() < 1e-9);
        // All unknown: nothing to integrate.
        let none = series(5.0, |_| None).measure(1.0, 4.0);
        assert_eq!(none.energy_j, None);
        assert!(
            none.flags.contains(&Flag::Unmeasurable) && none.flags.contains(&Flag::CurrentUnknown)
        );
    }

    #[test]
    fn fake_current_is_flagged_and_never_integrated() {
        let mut s = PowerSeries::new(EnergyConfig::default());
        for k in 0..50 {
            let mut x = sample(f64::from(k) * 0.1, Some(16.0), Some(-1.0));
            x.battery.fake_current = true;
            s.push(x);
        }
        let m = s.measure(0.0, 4.9);
        assert_eq!(m.energy_j, None);
        assert!(m.flags.contains(&Flag::FakeCurrent) && m.flags.contains(&Flag::Unmeasurable));
    }

    #[test]
    fn a_voltage_spike_is_an_outlier_flagged_and_left_out() {
        let mut s = PowerSeries::new(EnergyConfig::default());
        for k in 0..=50 {
            let t = f64::from(k) * 0.1;
            let v = if k == 20 {
                65.0
            } else if k == 30 {
                0.7
            } else {
                22.0
            };
            s.push(sample(t, Some(v), Some(10.0)));
        }
        let m = s.measure(1.0, 4.0);
        assert!(m.flags.contains(&Flag::VoltageOutlier), "{:?}", m.flags);
        assert!(
            (m.energy_j.expect("measured") - 660.0).abs() < 1e-9,
            "{:?}",
            m.energy_j
        );
        assert!(s.measure(0.0, 1.5).flags.is_empty());
    }

    #[test]
    fn a_voltage_sag_under_load_is_not_an_outlier() {
        // The pack sags 1.5 V in one sample as the motors spool up, then stays there.
        let mut s = PowerSeries::new(EnergyConfig::default());
        for k in 0..=40 {
            let v = if k < 20 { 25.2 } else { 23.7 };
            s.push(sample(f64::from(k) * 0.1, Some(v), Some(40.0)));
        }
        assert!(s.measure(0.0, 4.0).flags.is_empty());
    }

    #[test]
    fn the_charge_counter_cross_checks_the_integral() {
        // 20 V, 36 A for 10 s: 7200 J and 100 mAh.
        let build = |mah_per_s: f64| {
            let mut s = PowerSeries::new(EnergyConfig::default());
            for k in 0..=100 {
                let t = f64::from(k) * 0.1;
                let mut x = sample(t, Some(20.0), Some(36.0));
                x.battery.consumed_mah = Some((t * mah_per_s).round());
                s.push(x);
            }
            s
        };
        let agree = build(10.0).measure(0.0, 10.0);
        assert!((agree.consumed_j.expect("counted") - 7200.0).abs() < 1.0);
        assert!(!agree.flags.contains(&Flag::ConsumedMismatch));
        let disagree = build(13.0).measure(0.0, 10.0);
        assert!(
            disagree.flags.contains(&Flag::ConsumedMismatch),
            "{:?}",
            disagree.flags
        );
        // Too little charge for the counter's resolution: no verdict.
        assert!(!build(13.0)
            .measure(0.0, 2.0)
            .flags
            .contains(&Flag::ConsumedMismatch));
    }

    #[test]
    fn the_energy_counter_cross_checks_the_integral_when_asked() {
        // 20 V, 36 A for 10 s: 7200 J; the counter says `j_per_s` x t, the charge counter
        // agrees with the integral.
        let build = |j_per_s: f64, energy_counter: bool| {
            let mut s = PowerSeries::new(EnergyConfig {
                energy_counter,
                ..EnergyConfig::default()
            });
            for k in 0..=100 {
                let t = f64::from(k) * 0.1;
                let mut x = sample(t, Some(20.0), Some(36.0));
                x.battery.consumed_mah = Some((t * 10.0).round());
                x.battery.energy_consumed_j = Some(t * j_per_s);
                s.push(x);
            }
            s
        };
        let agree = build(720.0, true).measure(0.0, 10.0);
        assert!((agree.consumed_j.expect("counted") - 7200.0).abs() < 1e-6);
        assert!(!agree.flags.contains(&Flag::ConsumedMismatch));
        let disagree = build(900.0, true).measure(0.0, 10.0);
        assert!((disagree.consumed_j.expect("counted") - 9000.0).abs() < 1e-6);
        assert!(disagree.flags.contains(&Flag::ConsumedMismatch));
        // Not asked (a .tlog): the charge counter, which agrees.
        let unasked = build(900.0, false).measure(0.0, 10.0);
        assert!((unasked.consumed_j.expect("counted") - 7200.0).abs() < 1.0);
        assert!(!unasked.flags.contains(&Flag::ConsumedMismatch));
        // Under 2 kJ counted: no verdict.
        assert!(!build(900.0, true)
            .measure(0.0, 2.0)
            .flags
            .contains(&Flag::ConsumedMismatch));
    }
}
