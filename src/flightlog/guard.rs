//! The energy guard's arithmetic: will this battery get the vehicle home with its reserve?
//!
//! Pure numbers in, an assessment out; the live session feeds it what the recorder measured.
//! - [`Correction`] learns how far the real vehicle costs from the model: each part flown (the
//!   take-off, a leg, a stop at a point) gives `measured / predicted`; their logarithms, weighted
//!   by the part's predicted energy (a short leg says little), update a normal prior on
//!   `ln(ratio)` centred on the model (ratio 1). An observation far from what the others say is
//!   down-weighted (Huber), so one odd leg does not swing the estimate; the first part flown
//!   moves it from the prior by its weight.
//! - [`project`] turns the energy drawn so far, the plan's price of what is left and the
//!   correction into the energy left at landing with a band, and finds the point of no return:
//!   the last point of the plan from which home is still reached with the reserve.
//! - [`state_of_charge_from_rest`] reads a resting pack voltage through the pack's OCV curve, so
//!   a pack that was not full at take-off is known.

use serde::{Deserialize, Serialize};

/// What the guard may do (`--guard`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Policy {
    /// No guard.
    Off,
    /// Tell the user (terminal, service events, dashboard); never act.
    #[default]
    Warn,
    /// Tell the user, and send the vehicle home when continuing would land below the reserve.
    Rtl,
}

impl std::fmt::Display for Policy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Policy::Off => "off",
            Policy::Warn => "warn",
            Policy::Rtl => "rtl",
        })
    }
}

impl std::str::FromStr for Policy {
    type Err = crate::names::UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        crate::names::choose(
            "guard policy",
            s,
            &[
                ("warn", Policy::Warn),
                ("rtl", Policy::Rtl),
                ("off", Policy::Off),
            ],
        )
    }
}

/// What the guard is given with the plan: the policy, the pack as the vehicle file has it, and
/// the price of the autopilot's return from every point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GuardSetup {
    pub policy: Policy,
    /// The pack's usable energy when full (J).
    pub usable_j: f64,
    /// The reserve to land with (% of the usable energy).
    pub reserve_pct: f64,
    pub cells: u32,
    pub capacity_ah: f64,
    pub internal_resistance_ohm: f64,
    /// The cell's open-circuit voltage curve: state of charge ascending, volts per cell.
    pub ocv_soc: Vec<f64>,
    pub ocv_cell_v: Vec<f64>,
    /// Per point of the plan (its `points`, in order): the autopilot's return from it, home and
    /// landed (J).
    pub home_j: Vec<f64>,
    /// Per point of the plan: where the autopilot's return from it goes and lands ("home",
    /// "rally point 1": `mission::fence::ReturnRule`), when the setup was priced with it (absent
    /// from plans written before: home).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub return_to: Vec<String>,
    /// The rule that chose them, with its parameters and whether they were read from the
    /// autopilot or are its defaults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub return_rule: Option<String>,
    /// Per point of the plan: the return from each via point of the leg to it (J, in the
    /// leg's order; empty for a straight leg), so that the return from a leg round a fence
    /// zone is priced from where the way round has taken the vehicle. Empty when no leg has
    /// via points (absent from plan.json then, and from files written before it was kept).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub via_home_j: Vec<Vec<f64>>,
    /// What the guard starts from instead of the label and the bare model: the pack's capacity
    /// and the vehicle's correction learned in earlier flights (the ledger). Absent: the label
    /// and the prior (and in files written before it was kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<GuardStart>,
}

/// What earlier flights taught the guard before this one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GuardStart {
    /// The pack's capacity against its label, and the flights of that pack it was learned from
    /// (1 and 0: not known).
    pub capacity_ratio: f64,
    pub pack_flights: usize,
    /// The vehicle's measured over predicted, the standard deviation of its logarithm, and the
    /// flights it was learned from (1, the prior's and 0: not known).
    pub correction: f64,
    pub correction_sd_ln: f64,
    pub vehicle_flights: usize,
}

/// The prior's standard deviation of `ln(measured / predicted)`: wide enough that an airframe
/// costing twice the model (ArduCopter SITL's S1000-like frame against ours) is learned within a
/// leg or two, narrow enough that the first part does not throw the estimate past what it says.
pub const PRIOR_SD_LN: f64 = 0.7;
/// The scatter of one part's `ln(measured / predicted)` about the vehicle's true ratio, for a part
/// of typical energy: PX4 SITL's legs spread with a standard deviation of 1.5-6% about their mean
/// error (docs/px4-sitl.md), and a field flight's wind and gusts more; 10% is taken.
pub const PART_SD_LN: f64 = 0.10;
/// Huber's threshold, in standard deviations: a part further than this from the estimate of the
/// others counts with a weight that falls as its distance grows.
const HUBER_K: f64 = 2.0;

/// One part flown and measured: its predicted and measured energy (J).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observed {
    pub predicted_j: f64,
    pub measured_j: f64,
}

/// What has been learned of `measured / predicted` from the parts flown so far.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Correction {
    /// The estimate of `measured / predicted` (1 before any part is flown).
    pub ratio: f64,
    /// Standard deviation of `ln(ratio)`.
    pub sd_ln: f64,
    /// Parts that counted.
    pub parts: usize,
    /// Parts down-weighted as far from the others (an odd leg, a gust).
    pub outliers: usize,
}

impl Correction {
    /// The prior: the model as it is, with [`PRIOR_SD_LN`].
    pub fn prior() -> Correction {
        Correction {
            ratio: 1.0,
            sd_ln: PRIOR_SD_LN,
            parts: 0,
            outliers: 0,
        }
    }

    /// A prior centred on `ratio` with `sd_ln` (what earlier flights of the vehicle learned:
    /// the ledger's), no part flown yet. A ratio or spread that is not a positive finite number
    /// gives [`Correction::prior`].
    pub fn starting(ratio: f64, sd_ln: f64) -> Correction {
        if !(ratio.is_finite() && ratio > 0.0 && sd_ln.is_finite() && sd_ln > 0.0) {
            return Correction::prior();
        }
        Correction {
            ratio,
            sd_ln,
            parts: 0,
            outliers: 0,
        }
    }

    /// The correction learned from the parts flown, from [`Correction::prior`]; `typical_j` is
    /// the energy of a typical part of the plan (a part of that energy counts with weight 1, a
    /// shorter one less). Parts with a non-positive or non-finite energy are left out
    /// (unmeasured, or not a part at all).
    pub fn learn(parts: &[Observed], typical_j: f64) -> Correction {
        Correction::prior().learn_from(parts, typical_j)
    }

    /// [`Correction::learn`] from this correction as the prior (its ratio and `sd_ln`; the
    /// parts it counted are not counted again).
    pub fn learn_from(&self, parts: &[Observed], typical_j: f64) -> Correction {
        let typical_j = if typical_j.is_finite() && typical_j > 0.0 {
            typical_j
        } else {
            1.0
        };
        let obs: Vec<(f64, f64)> = parts
            .iter()
            .filter(|p| {
                p.predicted_j.is_finite()
                    && p.measured_j.is_finite()
                    && p.predicted_j > 0.0
                    && p.measured_j > 0.0
            })
            .map(|p| {
                let weight = (p.predicted_j / typical_j).min(2.0);
                ((p.measured_j / p.predicted_j).ln(), weight)
            })
            .collect();
        let prior = Correction::starting(self.ratio, self.sd_ln);
        if obs.is_empty() {
            return prior;
        }
        let prior_precision = prior.sd_ln.powi(-2);
        let prior_num = prior.ratio.ln() * prior_precision;
        let part_precision = PART_SD_LN.powi(-2);
        // Iteratively reweighted: the estimate, then each part's Huber weight against the
        // estimate of the others, until it settles.
        let mut huber = vec![1.0; obs.len()];
        let mut mean = prior.ratio.ln();
        let mut precision = prior_precision;
        for _ in 0..50 {
            let (mut num, mut prec) = (prior_num, prior_precision);
            for ((x, w), h) in obs.iter().zip(&huber) {
                num += x * w * h * part_precision;
                prec += w * h * part_precision;
            }
            let next = num / prec;
            precision = prec;
            for (k, (x, w)) in obs.iter().enumerate() {
                // The estimate without this part, so an outlier is judged by the others.
                let own = w * huber[k] * part_precision;
                let others_prec = prec - own;
                let others_mean = (num - x * own) / others_prec;
                let sd = (1.0 / (w * part_precision) + 1.0 / others_prec).sqrt();
                let z = (x - others_mean).abs() / sd;
                huber[k] = if z <= HUBER_K { 1.0 } else { HUBER_K / z };
            }
            let settled = (next - mean).abs() < 1e-9;
            mean = next;
            if settled {
                break;
            }
        }
        Correction {
            ratio: mean.exp(),
            sd_ln: precision.sqrt().recip(),
            parts: obs.len(),
            outliers: huber.iter().filter(|&&h| h < 1.0).count(),
        }
    }

    /// The ratio `k` standard deviations above (positive) or below the estimate.
    pub fn ratio_at(&self, k: f64) -> f64 {
        (self.ratio.ln() + k * self.sd_ln).exp()
    }
}

/// What the plan says is left, priced by the model (J), from the vehicle's position now.
#[derive(Debug, Clone, PartialEq)]
pub struct Remaining {
    /// The rest of the plan: the legs, stops, return and landing not yet flown (J).
    pub rest_j: f64,
    /// Per point still ahead in the plan's order (the one flown to now first): the plan's price
    /// of getting there from here (J), and of going home from it and landing (J).
    pub ahead: Vec<PointAhead>,
    /// Going home from here, now, and landing (J).
    pub home_now_j: f64,
    /// Where the autopilot's return from here goes ("home", "rally point 1").
    pub return_to: String,
}

/// A point of the plan still ahead.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PointAhead {
    pub name: String,
    /// The plan's price of reaching it (and stopping there) from where the vehicle is (J).
    pub to_reach_j: f64,
    /// Home from it, and the landing (J).
    pub home_from_j: f64,
}

/// The battery: what it holds and what must stay in it (J).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Pack {
    /// Energy the pack held at take-off (J): its usable energy times its state of charge then.
    pub at_takeoff_j: f64,
    /// The reserve that must be left at landing (J).
    pub reserve_j: f64,
}

/// The band of a projection: `k` standard deviations of the correction each way.
pub const BAND_SD: f64 = 1.0;

/// The guard's view of the flight now.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Projection {
    /// Energy drawn since take-off, measured (J).
    pub drawn_j: f64,
    /// The correction it used.
    pub correction: Correction,
    /// Energy left at landing if the plan is flown to the end (J), with the correction.
    pub left_at_landing_j: f64,
    /// The same with the correction one band dearer and cheaper (J): `[low, high]`.
    pub left_at_landing_band_j: [f64; 2],
    /// Energy left at landing if the vehicle turns home now (J).
    pub left_if_home_now_j: f64,
    /// The reserve (J).
    pub reserve_j: f64,
    /// The last point ahead from which home is still reached with the reserve (None: not even
    /// the next one; then only going home now keeps it, if anything does).
    pub point_of_no_return: Option<String>,
    /// Whether every point ahead is before the point of no return: the plan can be finished.
    pub plan_finishes: bool,
}

impl Projection {
    /// Whether finishing the plan is projected to land below the reserve.
    pub fn below_reserve(&self) -> bool {
        self.left_at_landing_j < self.reserve_j
    }
}

/// The projection from the energy drawn so far, what is left and the correction learned.
pub fn project(
    drawn_j: f64,
    pack: Pack,
    remaining: &Remaining,
    correction: &Correction,
) -> Projection {
    let left = |ratio: f64| pack.at_takeoff_j - drawn_j - remaining.rest_j * ratio;
    let ratio = correction.ratio;
    let mut pnr = None;
    let mut all = true;
    for p in &remaining.ahead {
        let left_at_home = pack.at_takeoff_j - drawn_j - (p.to_reach_j + p.home_from_j) * ratio;
        if left_at_home >= pack.reserve_j {
            pnr = Some(p.name.clone());
        } else {
            all = false;
            break;
        }
    }
    Projection {
        drawn_j,
        correction: correction.clone(),
        left_at_landing_j: left(ratio),
        left_at_landing_band_j: [
            left(correction.ratio_at(BAND_SD)),
            left(correction.ratio_at(-BAND_SD)),
        ],
        left_if_home_now_j: pack.at_takeoff_j - drawn_j - remaining.home_now_j * ratio,
        reserve_j: pack.reserve_j,
        point_of_no_return: pnr,
        plan_finishes: all && left(ratio) >= pack.reserve_j,
    }
}

/// What the guard makes of a projection.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "verdict", rename_all = "snake_case")]
pub enum Verdict {
    /// The plan finishes with the reserve.
    Continue,
    /// The plan finishes with the reserve on the estimate, but not at the dear end of its band
    /// (judged once a part has been flown: the prior alone says only what the plan's battery
    /// check said): the user is told, nothing is done.
    AtRisk,
    /// Finishing the plan is projected to land below the reserve: the user is told; the `rtl`
    /// policy sends the vehicle home.
    BelowReserve,
    /// The battery cannot be measured (unknown current, a telemetry gap): the guard cannot
    /// judge, and says so instead of acting.
    Unmeasurable { reason: String },
}

/// The longest gap in battery telemetry the guard judges across (s): a multirotor drawing 1 kW
/// spends 5 kJ in it, under 1% of an S1000-class pack; a longer gap suspends the guard.
pub const MAX_GAP_S: f64 = 5.0;

/// The verdict on a projection; `gap_s` is how long since the last valid battery sample.
pub fn judge(projection: &Projection, gap_s: f64, current_known: bool) -> Verdict {
    if !current_known {
        return Verdict::Unmeasurable {
            reason: "the autopilot does not report the battery current".into(),
        };
    }
    if gap_s.is_nan() || gap_s > MAX_GAP_S {
        return Verdict::Unmeasurable {
            reason: format!("no valid battery sample for {gap_s:.1} s (over {MAX_GAP_S} s)"),
        };
    }
    if projection.below_reserve() {
        Verdict::BelowReserve
    } else if projection.correction.parts > 0
        && projection.left_at_landing_band_j[0] < projection.reserve_j
    {
        Verdict::AtRisk
    } else {
        Verdict::Continue
    }
}

/// The state of charge (0..1) of a pack at rest from its voltage, through the cell OCV curve
/// (`soc` ascending, `cell_v` the voltage at each); None when the voltage or the curve is not
/// usable. Outside the curve it is clamped to its ends.
pub fn state_of_charge_from_rest(
    pack_v: f64,
    cells: u32,
    soc: &[f64],
    cell_v: &[f64],
) -> Option<f64> {
    if cells == 0 || soc.len() < 2 || soc.len() != cell_v.len() || !pack_v.is_finite() {
        return None;
    }
    if !cell_v.windows(2).all(|w| w[0] < w[1]) {
        return None;
    }
    let v = pack_v / f64::from(cells);
    if v <= cell_v[0] {
        return Some(soc[0]);
    }
    let last = cell_v.len() - 1;
    if v >= cell_v[last] {
        return Some(soc[last]);
    }
    let k = cell_v.windows(2).position(|w| v <= w[1])?;
    let t = (v - cell_v[k]) / (cell_v[k + 1] - cell_v[k]);
    Some(soc[k] + t * (soc[k + 1] - soc[k]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parts(ratios: &[f64], predicted_j: f64) -> Vec<Observed> {
        ratios
            .iter()
            .map(|r| Observed {
                predicted_j,
                measured_j: predicted_j * r,
            })
            .collect()
    }

    #[test]
    fn the_correction_starts_from_the_prior_and_converges_to_the_truth_ratio() {
        assert_eq!(Correction::learn(&[], 4000.0), Correction::prior());
        // A vehicle costing 2.1 times the model, its parts scattered by 6%.
        let scatter = [1.03, 0.95, 1.06, 0.98, 1.01, 0.97, 1.04, 0.99, 1.02];
        let truth = 2.1;
        let mut last_err = f64::INFINITY;
        for n in 1..=scatter.len() {
            let seen: Vec<f64> = scatter[..n].iter().map(|s| s * truth).collect();
            let c = Correction::learn(&parts(&seen, 4000.0), 4000.0);
            let err = (c.ratio / truth).ln().abs();
            if n == 1 {
                // One part moves it most of the way: the prior is wide.
                assert!(c.ratio > 1.9 && c.ratio < 2.3, "{c:?}");
            }
            if n >= 4 {
                assert!(err < 0.04, "after {n} parts: {c:?}");
            }
            assert!(c.sd_ln < PRIOR_SD_LN);
            last_err = err;
        }
        assert!(last_err < 0.02, "{last_err}");
        let c = Correction::learn(&parts(&scatter.map(|s| s * truth), 4000.0), 4000.0);
        assert!(c.sd_ln < 0.04, "{c:?}");
        assert_eq!(c.outliers, 0);
    }

    #[test]
    fn a_correction_learned_before_is_the_prior_the_parts_move_from() {
        // Earlier flights: the vehicle costs 1.3 times the model, known to 5%.
        let before = Correction::starting(1.3, 0.05);
        assert_eq!(before.learn_from(&[], 4000.0), before);
        // One part at the model's price moves it less than it moves the wide prior.
        let one = parts(&[1.0], 4000.0);
        let from_before = before.learn_from(&one, 4000.0);
        let from_prior = Correction::learn(&one, 4000.0);
        assert!(
            from_before.ratio > 1.15 && from_before.ratio < 1.3,
            "{from_before:?}"
        );
        assert!(from_prior.ratio < 1.02, "{from_prior:?}");
        assert!(from_before.sd_ln < 0.05);
        // Many parts at 1.0 outweigh it.
        let many = before.learn_from(&parts(&[1.0; 40], 4000.0), 4000.0);
        assert!(many.ratio < 1.05, "{many:?}");
        // The bare prior is the model's, and nonsense is not a prior.
        assert_eq!(Correction::prior().learn_from(&one, 4000.0), from_prior);
        assert_eq!(Correction::starting(f64::NAN, 0.1), Correction::prior());
        assert_eq!(Correction::starting(1.2, 0.0), Correction::prior());
    }

    #[test]
    fn one_odd_leg_does_not_swing_the_correction() {
        let mut seen = vec![1.0, 1.02, 0.98, 1.01, 0.99];
        let before = Correction::learn(&parts(&seen, 4000.0), 4000.0);
        seen.push(1.8);
        let after = Correction::learn(&parts(&seen, 4000.0), 4000.0);
        assert_eq!(after.outliers, 1, "{after:?}");
        assert!(after.ratio < before.ratio * 1.05, "{before:?} -> {after:?}");
        // Without the down-weighting it would have moved by about 10%.
        let mean_ln: f64 = seen.iter().map(|r| r.ln()).sum::<f64>() / seen.len() as f64;
        assert!(mean_ln.exp() > before.ratio * 1.09);
    }

    #[test]
    fn a_short_leg_counts_less_than_a_long_one() {
        let base = parts(&[1.0, 1.0, 1.0], 4000.0);
        let mut short = base.clone();
        short.push(Observed {
            predicted_j: 200.0,
            measured_j: 260.0,
        });
        let mut long = base;
        long.push(Observed {
            predicted_j: 4000.0,
            measured_j: 5200.0,
        });
        let (s, l) = (
            Correction::learn(&short, 4000.0),
            Correction::learn(&long, 4000.0),
        );
        assert!(s.ratio < l.ratio, "{s:?} {l:?}");
        assert!(s.ratio < 1.02, "{s:?}");
    }

    #[test]
    fn unmeasured_parts_are_left_out() {
        let c = Correction::learn(
            &[
                Observed {
                    predicted_j: 1000.0,
                    measured_j: f64::NAN,
                },
                Observed {
                    predicted_j: 0.0,
                    measured_j: 50.0,
                },
            ],
            1000.0,
        );
        assert_eq!(c, Correction::prior());
    }

    fn remaining() -> Remaining {
        // Three points ahead; each 10 kJ further; home from each costs 8 kJ.
        Remaining {
            rest_j: 40_000.0,
            ahead: (1..=3)
                .map(|k| PointAhead {
                    name: format!("P{k}"),
                    to_reach_j: 10_000.0 * k as f64,
                    home_from_j: 8_000.0,
                })
                .collect(),
            home_now_j: 8_000.0,
            return_to: "home".to_string(),
        }
    }

    #[test]
    fn the_projection_and_the_point_of_no_return_follow_the_correction() {
        let pack = Pack {
            at_takeoff_j: 200_000.0,
            reserve_j: 40_000.0,
        };
        let nominal = project(100_000.0, pack, &remaining(), &Correction::prior());
        assert_eq!(nominal.left_at_landing_j, 60_000.0);
        assert!(nominal.plan_finishes);
        assert_eq!(nominal.point_of_no_return.as_deref(), Some("P3"));
        assert!(nominal.left_at_landing_band_j[0] < 60_000.0);
        assert!(nominal.left_at_landing_band_j[1] > 60_000.0);
        assert_eq!(nominal.left_if_home_now_j, 92_000.0);
        // Costing 1.8 times the model: finishing lands below the reserve (28 kJ left); P2 is the
        // last point from which home keeps it (100 + 1.8 x 28 = 150.4 kJ drawn of the 160 kJ
        // allowed; from P3 100 + 1.8 x 38 = 168.4).
        let dear = Correction {
            ratio: 1.8,
            sd_ln: 0.05,
            parts: 6,
            outliers: 0,
        };
        let p = project(100_000.0, pack, &remaining(), &dear);
        assert!(p.below_reserve());
        assert!(!p.plan_finishes);
        assert_eq!(p.point_of_no_return.as_deref(), Some("P2"));
        assert_eq!(judge(&p, 0.1, true), Verdict::BelowReserve);
        assert_eq!(judge(&nominal, 0.1, true), Verdict::Continue);
        // Uncertain: the estimate finishes, its dear end does not.
        let unsure = Correction {
            ratio: 1.0,
            sd_ln: 0.5,
            parts: 1,
            outliers: 0,
        };
        let u = project(100_000.0, pack, &remaining(), &unsure);
        assert!(!u.below_reserve());
        assert_eq!(judge(&u, 0.1, true), Verdict::AtRisk);
    }

    #[test]
    fn a_measurement_gap_or_an_unknown_current_suspends_the_guard() {
        let pack = Pack {
            at_takeoff_j: 100_000.0,
            reserve_j: 40_000.0,
        };
        let p = project(90_000.0, pack, &remaining(), &Correction::prior());
        assert!(p.below_reserve());
        assert!(matches!(judge(&p, 6.0, true), Verdict::Unmeasurable { .. }));
        assert!(matches!(
            judge(&p, f64::NAN, true),
            Verdict::Unmeasurable { .. }
        ));
        assert!(matches!(
            judge(&p, 0.5, false),
            Verdict::Unmeasurable { .. }
        ));
        assert_eq!(judge(&p, 0.5, true), Verdict::BelowReserve);
    }

    #[test]
    fn the_state_of_charge_at_rest_comes_through_the_ocv_curve() {
        let soc = [0.0, 0.5, 1.0];
        let cell_v = [3.3, 3.8, 4.2];
        let at = |v| state_of_charge_from_rest(v, 6, &soc, &cell_v);
        assert_eq!(at(6.0 * 4.2), Some(1.0));
        assert_eq!(at(6.0 * 4.3), Some(1.0));
        assert_eq!(at(6.0 * 3.0), Some(0.0));
        assert!((at(6.0 * 4.0).unwrap() - 0.75).abs() < 1e-12);
        assert!((at(6.0 * 3.55).unwrap() - 0.25).abs() < 1e-12);
        assert_eq!(at(f64::NAN), None);
        assert_eq!(state_of_charge_from_rest(24.0, 0, &soc, &cell_v), None);
        assert_eq!(
            state_of_charge_from_rest(24.0, 6, &soc, &[4.2, 3.8, 3.3]),
            None
        );
    }
}
