//! What each pack is now, from its flights' records: capacity and internal resistance, their
//! trend over its cycles with its uncertainty, charge and energy throughput, and warnings; and
//! what a vehicle's model is off by (the guard's correction over its flights).
//!
//! The model (docs/ledger.md, "What a pack is learned to be"): each flight with a pack fit
//! (`ledger::record`: `logfit::battery`'s pack fitted to that flight's voltage and current) is
//! one measurement of the pack's capacity, with its standard error from the fit, at the pack's
//! age in equivalent full cycles (the charge drawn over its flights so far against its label).
//! The capacity fades along a line in cycles over the pack's recent flights: weighted least
//! squares (weights 1 / sd^2) gives the line and its slope's standard error, both widened by
//! the Birge ratio sqrt(chi^2 / dof) when the flights scatter more than their standard errors
//! say. The capacity now is the line's value at the pack's last cycle once there are
//! [`MIN_TREND_FLIGHTS`] flights spread over [`MIN_SPREAD_CYCLES`], else the weighted mean of
//! its flights. The resistance is treated alike, weighted equally (a flight's resistance is
//! fitted far more tightly than it changes between flights, with the pack's temperature), its
//! standard error from the flights' scatter.

use serde::{Deserialize, Serialize};

use super::FlightRecord;
use crate::flightlog::guard::{Correction, Observed, PART_SD_LN};

/// An estimate with its standard error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    pub value: f64,
    pub sd: f64,
}

/// One pack, from its flights.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PackSummary {
    pub name: String,
    pub flights: usize,
    /// Equivalent full cycles: the charge drawn over all its flights against its label (0
    /// while no flight of it has a pack fit, which gives the label).
    pub cycles: f64,
    pub charge_throughput_ah: f64,
    pub energy_throughput_wh: f64,
    pub label_capacity_ah: Option<f64>,
    /// The capacity now (Ah) and against the label.
    pub capacity_ah: Option<Estimate>,
    pub capacity_ratio: Option<Estimate>,
    pub internal_resistance_ohm: Option<Estimate>,
    /// The capacity's change per equivalent full cycle (Ah).
    pub fade_ah_per_cycle: Option<Estimate>,
    pub first_flight: Option<String>,
    pub last_flight: Option<String>,
    pub warnings: Vec<String>,
}

/// What the next flight on a pack starts from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PackPrior {
    pub pack: String,
    /// Capacity against the label, and its standard error.
    pub capacity_ratio: f64,
    pub capacity_ratio_sd: f64,
    pub internal_resistance_ohm: Option<f64>,
    /// Flights it was learned from.
    pub flights: usize,
}

/// What a vehicle's model is off by, over its flights.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VehiclePrior {
    pub vehicle: String,
    /// Measured over predicted, and the standard deviation of its logarithm.
    pub correction: f64,
    pub correction_sd_ln: f64,
    pub flights: usize,
}

/// The pack's end of life: its capacity below 80% of its label. The replacement criterion of
/// IEEE Std 1188 (and IEEE Std 450) for stationary batteries, replace when the capacity falls
/// below 80% of rated, and the point lithium cell and LiPo pack makers rate their cycle life
/// to (capacity retention 80%); below it a LiPo's capacity and resistance worsen faster, and a
/// mission planned on its label is out by a fifth.
pub const END_OF_LIFE_RATIO: f64 = 0.80;
/// A pack fades faster than the team's other packs when its slope is below theirs, pooled, by
/// more than this many combined standard errors (two: about a 2.3% one-sided false alarm for
/// each pack when it fades like the others).
pub const FASTER_FADE_SD: f64 = 2.0;
/// Flights with a pack fit a trend needs (and each pack compared for fading).
pub const MIN_TREND_FLIGHTS: usize = 3;
/// The spread of cycles (first to last flight fitted) over which the trend, not the mean,
/// says what the pack is now: below one equivalent full cycle a LiPo's fade (of the order of
/// 0.1% of its capacity a cycle) is far inside one flight's error, and the line's value at its
/// end only adds the slope's noise to the mean.
pub const MIN_SPREAD_CYCLES: f64 = 1.0;
/// The pack's recent flights the estimate now is made from (a pack's fade is not a line over
/// its whole life: the last ones say what it is).
pub const RECENT_FLIGHTS: usize = 20;
/// A single flight's resistance is known to about this fraction ([assumed]: a LiPo's
/// internal resistance changes by a fifth or more with its temperature between a cold first
/// flight and a warm pack), until two or more flights show their own scatter.
const ONE_FLIGHT_RESISTANCE_SD: f64 = 0.2;
/// No flight's capacity counts as known better than this fraction of its label (the OCV curve
/// the fit reads through is the vehicle file's, good to a few millivolts a cell): one flight
/// never outweighs all the others.
const CAPACITY_SD_FLOOR: f64 = 0.002;

/// A pack's flights in order, each flight with a pack fit a point of the trend.
struct History<'a> {
    flights: Vec<&'a FlightRecord>,
    label_ah: Option<f64>,
    charge_ah: f64,
    energy_wh: f64,
    /// (cycles at the flight's middle, capacity Ah, its sd, resistance ohm).
    points: Vec<(f64, f64, f64, f64)>,
}

fn finite_positive(v: Option<f64>) -> Option<f64> {
    v.filter(|v| v.is_finite() && *v > 0.0)
}

/// The flights of `pack`, oldest first (by start time; the undated first, in the order given).
fn flights_of<'a>(flights: &'a [FlightRecord], pack: &str) -> Vec<&'a FlightRecord> {
    let mut of: Vec<&FlightRecord> = flights
        .iter()
        .filter(|f| f.pack.as_deref() == Some(pack))
        .collect();
    of.sort_by(|a, b| a.started_at.cmp(&b.started_at));
    of
}

/// The pack's label: its last fitted flight's (the pack's own, as its flights were planned).
fn label_of(flights: &[&FlightRecord]) -> Option<f64> {
    flights
        .iter()
        .rev()
        .find_map(|f| f.pack_fit.as_ref())
        .and_then(|p| finite_positive(Some(p.label_capacity_ah)))
}

/// A flight of a pack and the pack's age at its middle, in equivalent full cycles (the charge
/// drawn by its flights before it and half its own, against the label; None without a label).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aged<'a> {
    pub flight: &'a FlightRecord,
    pub cycles: Option<f64>,
}

/// Every flight of `pack` in `flights`, oldest first, with the pack's age at its middle: where
/// the summary, the figure and the dashboard place each flight on the pack's cycles.
pub fn aged<'a>(flights: &'a [FlightRecord], pack: &str) -> Vec<Aged<'a>> {
    let flights = flights_of(flights, pack);
    let label_ah = label_of(&flights);
    let mut charge_ah = 0.0;
    flights
        .into_iter()
        .map(|flight| {
            let before = charge_ah;
            charge_ah += finite_positive(flight.charge_ah).unwrap_or(0.0);
            Aged {
                flight,
                cycles: label_ah.map(|label| 0.5 * (before + charge_ah) / label),
            }
        })
        .collect()
}

fn history<'a>(flights: &'a [FlightRecord], pack: &str) -> History<'a> {
    let aged = aged(flights, pack);
    let flights: Vec<&FlightRecord> = aged.iter().map(|a| a.flight).collect();
    let label_ah = label_of(&flights);
    let charge_ah = flights
        .iter()
        .map(|f| finite_positive(f.charge_ah).unwrap_or(0.0))
        .sum();
    let energy_wh = flights
        .iter()
        .map(|f| finite_positive(f.measured_j).unwrap_or(0.0) / 3600.0)
        .sum();
    let mut points = Vec::new();
    for a in &aged {
        let (Some(label), Some(cycles), Some(fit)) =
            (label_ah, a.cycles, a.flight.pack_fit.as_ref())
        else {
            continue;
        };
        let usable = fit.capacity_ah.is_finite()
            && fit.capacity_ah > 0.0
            && fit.capacity_sd_ah.is_finite()
            && fit.capacity_sd_ah >= 0.0
            && fit.internal_resistance_ohm.is_finite();
        if usable {
            let sd = fit.capacity_sd_ah.max(CAPACITY_SD_FLOOR * label);
            points.push((cycles, fit.capacity_ah, sd, fit.internal_resistance_ohm));
        }
    }
    History {
        flights,
        label_ah,
        charge_ah,
        energy_wh,
        points,
    }
}

/// How a fit's standard errors are scaled.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Scatter {
    /// The points' standard errors, widened by the Birge ratio when they scatter more.
    AtLeastStated,
    /// The points' own scatter about the fit (equal weights).
    Observed,
}

/// A weighted line y = a + b x through `points` (x, y, sd).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line {
    pub intercept: f64,
    pub slope: Estimate,
    /// Variances and covariance of (intercept, slope).
    var_a: f64,
    var_b: f64,
    cov_ab: f64,
}

impl Line {
    /// The line's value at `x`, with its standard error.
    pub fn at(&self, x: f64) -> Estimate {
        let var = self.var_a + x * x * self.var_b + 2.0 * x * self.cov_ab;
        Estimate {
            value: self.intercept + self.slope.value * x,
            sd: var.max(0.0).sqrt(),
        }
    }
}

/// Weighted least squares of y on x, weights 1 / sd^2 (None with fewer than 3 points or all at
/// one x).
fn fit_line(points: &[(f64, f64, f64)], scatter: Scatter) -> Option<Line> {
    let n = points.len();
    if n < 3 {
        return None;
    }
    let w = |sd: f64| match scatter {
        Scatter::AtLeastStated => 1.0 / (sd * sd),
        Scatter::Observed => 1.0,
    };
    let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(x, y, sd) in points {
        let wi = w(sd);
        sw += wi;
        sx += wi * x;
        sy += wi * y;
        sxx += wi * x * x;
        sxy += wi * x * y;
    }
    let delta = sw * sxx - sx * sx;
    if !(delta.is_finite() && delta > 1e-12 * sw * sxx.max(1e-300)) {
        return None;
    }
    let b = (sw * sxy - sx * sy) / delta;
    let a = (sxx * sy - sx * sxy) / delta;
    let chi2: f64 = points
        .iter()
        .map(|&(x, y, sd)| w(sd) * (y - a - b * x).powi(2))
        .sum();
    let reduced = chi2 / (n - 2) as f64;
    let scale = match scatter {
        Scatter::AtLeastStated => reduced.max(1.0),
        Scatter::Observed => reduced,
    };
    let line = Line {
        intercept: a,
        slope: Estimate {
            value: b,
            sd: (scale * sw / delta).sqrt(),
        },
        var_a: scale * sxx / delta,
        var_b: scale * sw / delta,
        cov_ab: -scale * sx / delta,
    };
    [line.intercept, line.slope.value, line.slope.sd]
        .iter()
        .all(|v| v.is_finite())
        .then_some(line)
}

/// The weighted mean of `points` (x, y, sd) (None without any).
fn mean(points: &[(f64, f64, f64)], scatter: Scatter) -> Option<Estimate> {
    let n = points.len();
    if n == 0 {
        return None;
    }
    let w = |sd: f64| match scatter {
        Scatter::AtLeastStated => 1.0 / (sd * sd),
        Scatter::Observed => 1.0,
    };
    let sw: f64 = points.iter().map(|p| w(p.2)).sum();
    let m = points.iter().map(|p| w(p.2) * p.1).sum::<f64>() / sw;
    let chi2: f64 = points.iter().map(|p| w(p.2) * (p.1 - m).powi(2)).sum();
    let var = match (scatter, n) {
        (Scatter::AtLeastStated, 1) => 1.0 / sw,
        (Scatter::AtLeastStated, _) => (chi2 / (n - 1) as f64).max(1.0) / sw,
        (Scatter::Observed, 1) => (points[0].2).powi(2),
        (Scatter::Observed, _) => chi2 / (n - 1) as f64 / sw,
    };
    let e = Estimate {
        value: m,
        sd: var.max(0.0).sqrt(),
    };
    (e.value.is_finite() && e.sd.is_finite()).then_some(e)
}

/// The spread in x of `points`.
fn spread(points: &[(f64, f64, f64)]) -> f64 {
    let lo = points.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let hi = points.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    if hi >= lo {
        hi - lo
    } else {
        0.0
    }
}

/// What the pack's recent flights say now (at cycle `now`): the line's value there when
/// they are enough and spread, else their mean.
fn now_of(points: &[(f64, f64, f64)], now: f64, scatter: Scatter) -> Option<Estimate> {
    if points.len() >= MIN_TREND_FLIGHTS && spread(points) >= MIN_SPREAD_CYCLES {
        if let Some(line) = fit_line(points, scatter) {
            return Some(line.at(now));
        }
    }
    mean(points, scatter)
}

/// One pack's summary without the warning that compares it with the others.
fn summary_of(flights: &[FlightRecord], pack: &str) -> (PackSummary, Option<Line>) {
    let h = history(flights, pack);
    let recent = &h.points[h.points.len().saturating_sub(RECENT_FLIGHTS)..];
    let cycles = h.label_ah.map_or(0.0, |l| h.charge_ah / l);
    let capacity: Vec<(f64, f64, f64)> = recent.iter().map(|p| (p.0, p.1, p.2)).collect();
    let resistance: Vec<(f64, f64, f64)> = recent
        .iter()
        .map(|p| (p.0, p.3, ONE_FLIGHT_RESISTANCE_SD * p.3.abs()))
        .collect();
    let capacity_ah = now_of(&capacity, cycles, Scatter::AtLeastStated);
    let line = fit_line(&capacity, Scatter::AtLeastStated);
    let capacity_ratio = capacity_ah.zip(h.label_ah).map(|(c, l)| Estimate {
        value: c.value / l,
        sd: c.sd / l,
    });
    let internal_resistance_ohm = now_of(&resistance, cycles, Scatter::Observed);
    let mut warnings = Vec::new();
    if let Some(ratio) = capacity_ratio.filter(|r| r.value < END_OF_LIFE_RATIO) {
        warnings.push(format!(
            "capacity {:.0}% of its label (+-{:.0}%), below the {:.0}% end of life: retire it",
            ratio.value * 100.0,
            ratio.sd * 100.0,
            END_OF_LIFE_RATIO * 100.0
        ));
    }
    let summary = PackSummary {
        name: pack.to_string(),
        flights: h.flights.len(),
        cycles,
        charge_throughput_ah: h.charge_ah,
        energy_throughput_wh: h.energy_wh,
        label_capacity_ah: h.label_ah,
        capacity_ah,
        capacity_ratio,
        internal_resistance_ohm,
        fade_ah_per_cycle: line.map(|l| l.slope),
        first_flight: h.flights.first().map(|f| f.id.clone()),
        last_flight: h.flights.last().map(|f| f.id.clone()),
        warnings,
    };
    (summary, line)
}

/// Every pack in `flights`, by name.
pub fn summarise(flights: &[FlightRecord]) -> Vec<PackSummary> {
    let mut names: Vec<&str> = flights.iter().filter_map(|f| f.pack.as_deref()).collect();
    names.sort_unstable();
    names.dedup();
    let packs: Vec<(PackSummary, Option<Line>)> =
        names.iter().map(|n| summary_of(flights, n)).collect();
    // Each pack's fade against its label per cycle, to compare packs of different labels.
    let relative: Vec<Option<Estimate>> = packs
        .iter()
        .map(|(s, line)| {
            let label = s.label_capacity_ah?;
            let line = line.as_ref()?;
            Some(Estimate {
                value: line.slope.value / label,
                sd: line.slope.sd / label,
            })
        })
        .collect();
    packs
        .into_iter()
        .enumerate()
        .map(|(k, (mut summary, _))| {
            if let Some(own) = relative[k] {
                let others: Vec<(f64, f64, f64)> = (relative.iter().enumerate())
                    .filter(|(j, _)| *j != k)
                    .filter_map(|(_, r)| *r)
                    .filter(|r| r.sd > 0.0)
                    .map(|r| (0.0, r.value, r.sd))
                    .collect();
                if let Some(pooled) = mean(&others, Scatter::AtLeastStated) {
                    let combined = own.sd.hypot(pooled.sd);
                    if own.value < pooled.value - FASTER_FADE_SD * combined {
                        summary.warnings.push(format!(
                            "fading faster than the team's other packs: {:.2}% of its label a cycle against their {:.2}% (+-{:.2}%)",
                            -own.value * 100.0,
                            -pooled.value * 100.0,
                            combined * 100.0
                        ));
                    }
                }
            }
            summary
        })
        .collect()
}

/// What a flight on `pack` starts from (None before any flight measured it).
pub fn pack_prior(flights: &[FlightRecord], pack: &str) -> Option<PackPrior> {
    let (summary, _) = summary_of(flights, pack);
    let ratio = summary.capacity_ratio?;
    let fitted = history(flights, pack).points.len();
    Some(PackPrior {
        pack: pack.to_string(),
        capacity_ratio: ratio.value,
        capacity_ratio_sd: ratio.sd,
        internal_resistance_ohm: summary.internal_resistance_ohm.map(|r| r.value),
        flights: fitted,
    })
}

/// What `vehicle`'s model is off by (None before any guarded flight of it).
///
/// Each guarded flight says ln(correction), its standard error the guard's own (its
/// `Correction` learned again from the flight's parts, without the prior's pull); the flights
/// are pooled as a random-effects mean (R. DerSimonian, N. Laird, "Meta-analysis in clinical
/// trials", 1986): weights 1 / (sd^2 + tau^2), tau^2 the flight-to-flight scatter beyond their
/// standard errors (wind, payload, the pack's state) estimated from three flights on, and
/// taken as [`PART_SD_LN`] before.
pub fn vehicle_prior(flights: &[FlightRecord], vehicle: &str) -> Option<VehiclePrior> {
    let obs: Vec<(f64, f64)> = flights
        .iter()
        .filter(|f| f.vehicle.as_deref() == Some(vehicle))
        .filter_map(|f| {
            let g = f.guard.as_ref()?;
            let c = finite_positive(Some(g.correction))?;
            Some((c.ln(), flight_correction_sd_ln(f)))
        })
        .collect();
    if obs.is_empty() {
        return None;
    }
    let k = obs.len();
    let fixed_w: Vec<f64> = obs.iter().map(|(_, sd)| 1.0 / (sd * sd)).collect();
    let sw: f64 = fixed_w.iter().sum();
    let fixed_mean = obs
        .iter()
        .zip(&fixed_w)
        .map(|((x, _), w)| w * x)
        .sum::<f64>()
        / sw;
    let tau2 = if k >= 3 {
        let q: f64 = (obs.iter().zip(&fixed_w))
            .map(|((x, _), w)| w * (x - fixed_mean).powi(2))
            .sum();
        let sw2: f64 = fixed_w.iter().map(|w| w * w).sum();
        ((q - (k - 1) as f64) / (sw - sw2 / sw)).max(0.0)
    } else {
        PART_SD_LN * PART_SD_LN
    };
    let w: Vec<f64> = obs.iter().map(|(_, sd)| 1.0 / (sd * sd + tau2)).collect();
    let sw: f64 = w.iter().sum();
    let m = obs.iter().zip(&w).map(|((x, _), w)| w * x).sum::<f64>() / sw;
    let sd = (1.0 / sw).sqrt();
    (m.is_finite() && sd.is_finite()).then(|| VehiclePrior {
        vehicle: vehicle.to_string(),
        correction: m.exp(),
        correction_sd_ln: sd,
        flights: k,
    })
}

/// The standard error of one flight's ln(correction): the guard's, from the flight's parts
/// measured (the take-off, legs, settles and hovers; not the landing, as the guard learns),
/// less the prior's share; the prior's own when no part was measured.
fn flight_correction_sd_ln(f: &FlightRecord) -> f64 {
    let observed: Vec<Observed> = f
        .parts
        .iter()
        .filter(|p| matches!(p.kind.as_str(), "takeoff" | "leg" | "settle" | "hover"))
        .filter_map(|p| {
            Some(Observed {
                predicted_j: p.predicted_j?,
                measured_j: p.measured_j?,
            })
        })
        .collect();
    let energies: Vec<f64> = observed
        .iter()
        .map(|o| o.predicted_j)
        .filter(|e| e.is_finite() && *e > 0.0)
        .collect();
    if energies.is_empty() {
        return crate::flightlog::guard::PRIOR_SD_LN;
    }
    let typical_j = energies.iter().sum::<f64>() / energies.len() as f64;
    let learned = Correction::learn(&observed, typical_j);
    // Posterior precision less the prior's: what the flight itself says.
    let precision = learned.sd_ln.powi(-2) - crate::flightlog::guard::PRIOR_SD_LN.powi(-2);
    if precision.is_finite() && precision > 0.0 {
        precision.powf(-0.5)
    } else {
        crate::flightlog::guard::PRIOR_SD_LN
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ledger::{FlightSource, GuardLearned, Outcome, PackFit, PartRecord};

    /// A flight on `pack` on day `day` drawing `charge_ah` of a 10 Ah label, its fit `capacity_ah`
    /// +- `sd_ah` and `r_ohm`.
    fn flight(pack: &str, day: u32, charge_ah: f64, fit: Option<(f64, f64, f64)>) -> FlightRecord {
        FlightRecord {
            id: format!("{pack}-{day}"),
            source: FlightSource::Directory,
            path: String::new(),
            vehicle: Some("s1000".into()),
            pack: Some(pack.into()),
            mission: "m".into(),
            profile: Some("px4".into()),
            wind_m_s: None,
            wind_from_deg: None,
            autopilot: Some("px4".into()),
            started_at: Some(format!(
                "2026-{:02}-{:02}T10:00:00Z",
                1 + day / 28,
                1 + day % 28
            )),
            outcome: Outcome::Completed,
            duration_s: 600.0,
            predicted_j: Some(500e3),
            measured_j: Some(520e3),
            charge_ah: Some(charge_ah),
            parts: Vec::new(),
            guard: None,
            pack_fit: fit.map(|(c, sd, r)| PackFit {
                capacity_ah: c,
                label_capacity_ah: 10.0,
                capacity_sd_ah: sd,
                internal_resistance_ohm: r,
                state_of_charge_at_takeoff: 1.0,
                samples: 6000,
                voltage_rms_v: 0.02,
            }),
        }
    }

    /// `n` flights on `pack`, each drawing 8 Ah of its 10, capacity `c0 + fade * cycles` with a
    /// deterministic wobble of +-`wobble` Ah, sd `sd`.
    fn pack_flights(pack: &str, n: u32, c0: f64, fade: f64, wobble: f64) -> Vec<FlightRecord> {
        (0..n)
            .map(|k| {
                let cycles = 0.8 * (f64::from(k) + 0.5);
                let w = wobble * [1.0, -1.0, 0.5, -0.5][k as usize % 4];
                flight(pack, k, 8.0, Some((c0 + fade * cycles + w, 0.05, 0.02)))
            })
            .collect()
    }

    #[test]
    fn the_trend_recovers_a_known_fade_and_the_capacity_at_the_last_cycle() {
        let flights = pack_flights("p1", 30, 10.0, -0.02, 0.03);
        let s = &summarise(&flights)[0];
        assert_eq!(s.flights, 30);
        assert!((s.cycles - 24.0).abs() < 1e-9, "{s:?}");
        assert!((s.charge_throughput_ah - 240.0).abs() < 1e-9, "{s:?}");
        assert!((s.energy_throughput_wh - 30.0 * 520e3 / 3600.0).abs() < 1e-6);
        let fade = s.fade_ah_per_cycle.expect("a trend");
        assert!((fade.value + 0.02).abs() < 2.0 * fade.sd, "{fade:?}");
        assert!(fade.sd < 0.005, "{fade:?}");
        // Now: the line at cycle 24, over the recent 20 flights.
        let now = s.capacity_ah.expect("capacity");
        assert!((now.value - (10.0 - 0.02 * 24.0)).abs() < 0.05, "{now:?}");
        let ratio = s.capacity_ratio.unwrap();
        assert!((ratio.value - now.value / 10.0).abs() < 1e-12);
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        assert_eq!(s.first_flight.as_deref(), Some("p1-0"));
        assert_eq!(s.last_flight.as_deref(), Some("p1-29"));
    }

    #[test]
    fn a_pack_below_eighty_percent_is_warned_and_a_healthy_one_is_not() {
        let mut flights = pack_flights("worn", 4, 7.6, 0.0, 0.02);
        flights.extend(pack_flights("healthy", 4, 9.4, 0.0, 0.02));
        let s = summarise(&flights);
        let worn = s.iter().find(|s| s.name == "worn").unwrap();
        let healthy = s.iter().find(|s| s.name == "healthy").unwrap();
        assert_eq!(worn.warnings.len(), 1, "{worn:?}");
        assert!(worn.warnings[0].contains("below the 80% end of life"));
        assert!(healthy.warnings.is_empty(), "{healthy:?}");
    }

    #[test]
    fn a_pack_fading_faster_than_the_others_is_found_and_they_are_not() {
        let mut flights = pack_flights("a", 12, 10.0, -0.005, 0.02);
        flights.extend(pack_flights("b", 12, 10.0, -0.006, 0.02));
        flights.extend(pack_flights("c", 12, 10.0, -0.004, 0.02));
        flights.extend(pack_flights("fading", 12, 10.0, -0.08, 0.02));
        let s = summarise(&flights);
        for p in &s {
            let warned = p.warnings.iter().any(|w| w.contains("fading faster"));
            assert_eq!(warned, p.name == "fading", "{p:?}");
        }
        // Alone, a pack is compared with nobody.
        let alone = summarise(&pack_flights("fading", 12, 10.0, -0.08, 0.02));
        assert!(alone[0].warnings.iter().all(|w| !w.contains("fading")));
    }

    #[test]
    fn few_flights_give_the_weighted_mean_and_a_short_flight_counts_for_little() {
        // Two flights: one deep (sd 0.05 Ah) at 8.5 Ah, one shallow (sd 0.5 Ah) at 9.5 Ah.
        let flights = vec![
            flight("p", 0, 6.0, Some((8.5, 0.05, 0.02))),
            flight("p", 1, 0.5, Some((9.5, 0.5, 0.02))),
        ];
        let s = &summarise(&flights)[0];
        let c = s.capacity_ah.unwrap();
        let w = [1.0 / 0.05f64.powi(2), 1.0 / 0.5f64.powi(2)];
        let expected = (w[0] * 8.5 + w[1] * 9.5) / (w[0] + w[1]);
        assert!((c.value - expected).abs() < 1e-9, "{c:?}");
        assert!(c.value < 8.52, "{c:?}");
        assert!(s.fade_ah_per_cycle.is_none());
        let prior = pack_prior(&flights, "p").expect("a prior");
        assert!((prior.capacity_ratio - expected / 10.0).abs() < 1e-9);
        assert!(prior.capacity_ratio_sd > 0.0 && prior.capacity_ratio_sd < 0.05);
        assert_eq!(prior.flights, 2);
        assert_eq!(prior.internal_resistance_ohm, Some(0.02));
    }

    #[test]
    fn no_prior_before_a_pack_fit_and_for_another_pack() {
        let flights = vec![flight("p", 0, 6.0, None)];
        assert_eq!(pack_prior(&flights, "p"), None);
        assert_eq!(pack_prior(&flights, "q"), None);
        let s = &summarise(&flights)[0];
        assert_eq!((s.flights, s.capacity_ah), (1, None));
        assert!(summarise(&[]).is_empty());
    }

    fn guarded(
        vehicle: &str,
        day: u32,
        correction: f64,
        measured_over_predicted: f64,
    ) -> FlightRecord {
        let mut f = flight("p", day, 6.0, None);
        f.vehicle = Some(vehicle.into());
        f.guard = Some(GuardLearned {
            correction,
            capacity_ratio: 1.0,
            state_of_charge_at_takeoff: Some(1.0),
            returned: false,
        });
        f.parts = (0..12)
            .map(|k| PartRecord {
                index: k,
                kind: "leg".into(),
                name: format!("W{k}"),
                predicted_j: Some(10e3),
                measured_j: Some(10e3 * measured_over_predicted),
                duration_s: Some(20.0),
            })
            .collect();
        f
    }

    #[test]
    fn the_vehicle_prior_pools_the_guards_corrections_with_their_scatter() {
        assert_eq!(vehicle_prior(&[], "s1000"), None);
        assert_eq!(vehicle_prior(&[flight("p", 0, 6.0, None)], "s1000"), None);
        let one = vehicle_prior(&[guarded("s1000", 0, 1.1, 1.1)], "s1000").expect("prior");
        assert!(
            (one.correction - 1.1).abs() < 1e-9 && one.flights == 1,
            "{one:?}"
        );
        // One flight: its own error and the assumed scatter between flights.
        assert!(one.correction_sd_ln > PART_SD_LN * 0.99, "{one:?}");
        // Flights that agree: the mean, tighter.
        let agree: Vec<FlightRecord> = (0..6).map(|d| guarded("s1000", d, 1.1, 1.1)).collect();
        let p = vehicle_prior(&agree, "s1000").unwrap();
        assert!((p.correction - 1.1).abs() < 1e-9, "{p:?}");
        assert!(p.correction_sd_ln < one.correction_sd_ln / 2.0, "{p:?}");
        // Flights that scatter: the scatter shows in the sd.
        let scatter: Vec<FlightRecord> = [0.8, 1.3, 0.9, 1.25, 1.0, 1.2]
            .iter()
            .enumerate()
            .map(|(d, c)| guarded("s1000", d as u32, *c, *c))
            .collect();
        let q = vehicle_prior(&scatter, "s1000").unwrap();
        assert!(q.correction_sd_ln > 2.0 * p.correction_sd_ln, "{q:?} {p:?}");
        let geometric = ([0.8f64, 1.3, 0.9, 1.25, 1.0, 1.2]
            .iter()
            .map(|c| c.ln())
            .sum::<f64>()
            / 6.0)
            .exp();
        assert!((q.correction - geometric).abs() < 1e-6, "{q:?}");
        assert_eq!(vehicle_prior(&scatter, "other"), None);
    }
}
