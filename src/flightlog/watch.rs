//! The energy guard, live: what the battery holds, what the rest of the plan and the way home
//! cost as learned from the parts flown, and what to do about it, updated as the flight's
//! readings arrive.
//!
//! The segmenter owns a [`Watch`] when its plan carries a [`GuardSetup`] (`fly`, the service
//! and `record` put one there; it is written to plan.json with the plan), so the guard's view is
//! a pure function of the log like everything else measured: a replay of the `.tlog` sees what
//! the live guard saw and decided, and the report records it.
//!
//! - The pack: its state of charge at take-off from the first voltage read (compensated for the
//!   current drawn through the pack's internal resistance) through its OCV curve, and its real
//!   capacity, learned in flight from the charge drawn against the fall of that state of charge
//!   (an aged or smaller pack is noticed once a tenth of it is spent; a pack is never assumed
//!   larger than its label). What earlier flights taught ([`GuardSetup`]'s `start`: the
//!   ledger's capacity of the pack and correction of the vehicle) is where both start, so the
//!   first legs are judged with them; a replay reads them from plan.json.
//! - The rest: the plan's price of every stage still ahead (take-off, each leg, settle and hover,
//!   the landing; the stage in progress by its share still to fly), and of the autopilot's
//!   return from each point ([`GuardSetup::home_j`]; on a leg round a fence zone, through the
//!   return from each of its via points, [`GuardSetup::via_home_j`]), times the correction
//!   learned from the parts flown (`guard::Correction`).
//! - The decision: `guard::project` and `guard::judge`; a note when the verdict changes, at the
//!   point of no return, and (policy `rtl`) the one decision to go home: when the plan cannot be
//!   finished with the reserve and the next point ahead cannot be reached and left for home
//!   with it at the dear end of the correction's band, or home from here is about to cost the
//!   reserve. It never decides on a battery it cannot measure.

use serde::{Deserialize, Serialize};

use super::energy::PowerSeries;
use super::flight_plan::FlightPlan;
use super::guard::{
    judge, project, state_of_charge_from_rest, Correction, Observed, Pack, PointAhead, Projection,
    Remaining, Verdict, BAND_SD, MAX_GAP_S,
};
pub use super::guard::{GuardSetup, Policy};
use super::part::{Segment, SegmentKind};

/// What a note is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NoteKind {
    /// The verdict changed (to `continue`, `at_risk`, `below_reserve` or `unmeasurable`).
    Verdict,
    /// The vehicle is at the point of no return: after it, home is no longer reached with the
    /// reserve.
    PointOfNoReturn,
    /// The guard decided to send the vehicle home (policy `rtl`).
    Return,
}

/// Something the guard saw or decided, at vehicle time `t_s`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GuardNote {
    pub t_s: f64,
    pub kind: NoteKind,
    /// The verdict then: `continue`, `at_risk`, `below_reserve`, `unmeasurable`.
    pub verdict: String,
    /// What it means, in a sentence for the user.
    pub message: String,
    /// Energy left at landing if the plan is flown to the end (kJ), and the reserve (kJ).
    pub left_at_landing_kj: f64,
    pub reserve_kj: f64,
    /// A `return` note's price of the way home from where the vehicle was sent (kJ, the model's
    /// before the correction: what the report measures the return against).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub home_kj: Option<f64>,
    /// A `return` note's destination: where the autopilot's return from there goes ("home",
    /// "rally point 1").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub return_to: Option<String>,
}

/// The guard's view now, for the live displays.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GuardView {
    pub policy: Policy,
    pub t_s: f64,
    pub verdict: String,
    /// Why the guard cannot judge, when it cannot.
    pub reason: Option<String>,
    pub drawn_kj: f64,
    /// The pack at take-off (kJ of usable energy), its state of charge then, and its capacity as
    /// learned against the label's.
    pub pack_kj: f64,
    pub state_of_charge_at_takeoff: f64,
    pub capacity_ratio: f64,
    pub left_at_landing_kj: f64,
    pub left_at_landing_band_kj: [f64; 2],
    pub left_if_home_now_kj: f64,
    pub reserve_kj: f64,
    /// `measured / predicted` learned so far, and its standard deviation in `ln`.
    pub correction: f64,
    pub correction_sd_ln: f64,
    pub parts_learned: usize,
    pub point_of_no_return: Option<String>,
    /// Whether the guard decided to send the vehicle home.
    pub returning: bool,
}

/// How often (vehicle time) the guard looks again between parts (s).
const UPDATE_EVERY_S: f64 = 0.5;
/// The share of the pack that must be spent before its capacity is learned, and the share at
/// which the learned value counts fully.
const CAPACITY_FROM_SOC: f64 = 0.10;
const CAPACITY_FULL_SOC: f64 = 0.30;
/// How long a better verdict must hold before it is said (s of vehicle time).
const BETTER_HOLD_S: f64 = 10.0;
/// Samples averaged for the state of charge now (voltage noise).
const SOC_WINDOW: usize = 20;

/// The live guard of one flight.
#[derive(Debug, Clone)]
pub struct Watch {
    setup: GuardSetup,
    /// The plan's points' names.
    names: Vec<String>,
    /// Per stage (take-off, then leg, settle, hover of each point, then the landing): its
    /// predicted energy (J) and duration (s, 0 when unknown).
    stages: Vec<(f64, f64)>,
    /// `after[i]`: the energy of the stages after stage i.
    after: Vec<f64>,
    /// Per point, the leg to it round a fence zone: where along the way (share of its length)
    /// each via point is, and the return from there (empty for a straight leg).
    via_homes: Vec<Vec<(f64, f64)>>,
    typical_j: f64,
    /// Valid power samples integrated so far.
    integrated: usize,
    last_valid: Option<(f64, f64, f64)>,
    drawn_j: f64,
    charge_as: f64,
    soc0: Option<f64>,
    recent_soc: std::collections::VecDeque<f64>,
    capacity_ratio: f64,
    /// The capacity ratio the guard starts from (the ledger's for the pack, else 1), which the
    /// capacity measured in flight moves from.
    start_capacity_ratio: f64,
    /// The correction before any part is flown (the vehicle's from earlier flights, else the
    /// model's).
    prior: Correction,
    correction: Correction,
    learned_parts: usize,
    last_update_s: f64,
    verdict: Option<String>,
    /// A better verdict than the one said, and since when it holds.
    better_since: Option<(String, f64)>,
    pnr_noted: bool,
    returning: bool,
    current_known: bool,
    /// Samples since the last valid one have come with a voltage but no current: what the
    /// guard misses is the current, not the battery.
    current_lost: bool,
    notes: Vec<GuardNote>,
    view: Option<GuardView>,
}

/// What the guard made of a flight, for its report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GuardReport {
    pub policy: Policy,
    pub notes: Vec<GuardNote>,
    /// The correction learned by the end, and the pack's capacity against its label.
    pub correction: f64,
    pub capacity_ratio: f64,
    pub state_of_charge_at_takeoff: Option<f64>,
    /// Whether the guard decided to send the vehicle home.
    pub returned: bool,
}

/// `after[i]`: the energy of the stages after stage i.
fn stages_after(stages: &[(f64, f64)]) -> Vec<f64> {
    let mut after = vec![0.0; stages.len()];
    for i in (0..stages.len().saturating_sub(1)).rev() {
        after[i] = after[i + 1] + stages[i + 1].0;
    }
    after
}

/// Where along the leg to points[k] (share of its length through its via points) each via
/// point is, with the return from it as `setup` prices it; empty for a straight leg or a setup
/// without those prices.
fn via_homes(plan: &FlightPlan, setup: &GuardSetup, k: usize) -> Vec<(f64, f64)> {
    let Some(homes) = setup.via_home_j.get(k) else {
        return Vec::new();
    };
    let path = plan.leg_path(k);
    if homes.is_empty() || homes.len() + 2 != path.len() {
        return Vec::new();
    }
    let mut run = vec![0.0];
    for w in path.windows(2) {
        let d = (w[1].x_east_m - w[0].x_east_m)
            .hypot(w[1].y_north_m - w[0].y_north_m)
            .hypot(w[1].z_up_m - w[0].z_up_m);
        run.push(run.last().copied().unwrap_or(0.0) + d);
    }
    let total = run.last().copied().unwrap_or(0.0);
    if total <= 0.0 {
        return Vec::new();
    }
    homes
        .iter()
        .enumerate()
        .map(|(j, &home_j)| (run[j + 1] / total, home_j))
        .collect()
}

/// The value at `share` (0..1) of the straight pieces through `knots` (share, value), in order.
fn along(knots: &[(f64, f64)], share: f64) -> f64 {
    for w in knots.windows(2) {
        let ((s0, v0), (s1, v1)) = (w[0], w[1]);
        if share <= s1 {
            let t = if s1 > s0 {
                ((share - s0) / (s1 - s0)).clamp(0.0, 1.0)
            } else {
                1.0
            };
            return v0 + (v1 - v0) * t;
        }
    }
    knots.last().map_or(0.0, |k| k.1)
}

fn stage_of(kind: SegmentKind) -> usize {
    match kind {
        SegmentKind::Takeoff => 0,
        SegmentKind::Leg(k) => 1 + 3 * k,
        SegmentKind::Settle(k) => 2 + 3 * k,
        SegmentKind::Hover(k) => 3 + 3 * k,
        SegmentKind::Landing => usize::MAX,
    }
}

impl Watch {
    /// The guard of `plan`, when it carries a setup with a policy other than off, a prediction
    /// and a return price for every point.
    pub fn new(plan: &FlightPlan) -> Option<Watch> {
        let setup = plan.guard.clone()?;
        let predicted = plan.predicted.as_ref()?;
        if setup.policy == Policy::Off
            || setup.home_j.len() != plan.points.len()
            || predicted.legs.len() != plan.points.len()
            || !(setup.usable_j.is_finite() && setup.usable_j > 0.0)
        {
            return None;
        }
        let mut stages = vec![(predicted.takeoff_j, 0.0)];
        for (leg, point) in predicted.legs.iter().zip(&plan.points) {
            stages.push((leg.energy_j, leg.duration_s));
            stages.push((leg.settle_energy_j, leg.settle_duration_s));
            stages.push((point.hold_s * predicted.hover_power_w, point.hold_s));
        }
        stages.push((predicted.landing_j, 0.0));
        let after = stages_after(&stages);
        let energies: Vec<f64> = stages.iter().map(|s| s.0).filter(|e| *e > 0.0).collect();
        let typical_j = if energies.is_empty() {
            1.0
        } else {
            energies.iter().sum::<f64>() / energies.len() as f64
        };
        let via_homes = (0..plan.points.len())
            .map(|k| via_homes(plan, &setup, k))
            .collect();
        // What earlier flights taught: the pack's capacity (never above its label) and the
        // vehicle's correction.
        let start_capacity_ratio = (setup.start.as_ref())
            .map(|s| s.capacity_ratio)
            .filter(|r| r.is_finite() && *r > 0.0)
            .map_or(1.0, |r| r.min(1.0));
        let prior = match &setup.start {
            Some(s) if s.vehicle_flights > 0 => {
                Correction::starting(s.correction, s.correction_sd_ln)
            }
            _ => Correction::prior(),
        };
        Some(Watch {
            via_homes,
            setup,
            names: plan.points.iter().map(|p| p.name.clone()).collect(),
            stages,
            after,
            typical_j,
            integrated: 0,
            last_valid: None,
            drawn_j: 0.0,
            charge_as: 0.0,
            soc0: None,
            recent_soc: Default::default(),
            capacity_ratio: start_capacity_ratio,
            start_capacity_ratio,
            correction: prior.clone(),
            prior,
            learned_parts: 0,
            last_update_s: f64::NEG_INFINITY,
            verdict: None,
            better_since: None,
            pnr_noted: false,
            returning: false,
            current_known: false,
            current_lost: false,
            notes: Vec::new(),
            view: None,
        })
    }

    /// Prices the stages from `r.from_point` on (leg, settle and hover of each point, the
    /// landing) and the return from every point as `r` says: the rest of the flight priced
    /// again in a wind heard in flight. The take-off and the parts already begun keep their
    /// price, and the correction learned so far stays (it is measured against the old prices
    /// of the parts flown).
    pub fn reprice(&mut self, r: &super::flight_plan::Repricing) {
        for (i, leg) in r.legs.iter().enumerate() {
            let k = r.from_point + i;
            let hover = 3 + 3 * k;
            if hover >= self.stages.len() {
                break;
            }
            self.stages[1 + 3 * k] = (leg.energy_j, leg.duration_s);
            self.stages[2 + 3 * k] = (leg.settle_energy_j, leg.settle_duration_s);
            let hold_s = self.stages[hover].1;
            self.stages[hover] = (hold_s * r.hover_power_w, hold_s);
        }
        if let Some(landing) = self.stages.last_mut() {
            landing.0 = r.landing_j;
        }
        self.after = stages_after(&self.stages);
        if r.home_j.len() == self.setup.home_j.len() {
            self.setup.home_j.clone_from(&r.home_j);
        }
    }

    /// Every note so far.
    pub fn notes(&self) -> &[GuardNote] {
        &self.notes
    }

    /// The latest view (None before the flight began).
    pub fn view(&self) -> Option<&GuardView> {
        self.view.as_ref()
    }

    /// The report's record.
    pub fn report(&self) -> GuardReport {
        GuardReport {
            policy: self.setup.policy,
            notes: self.notes.clone(),
            correction: self.correction.ratio,
            capacity_ratio: self.capacity_ratio,
            state_of_charge_at_takeoff: self.soc0,
            returned: self.returning,
        }
    }

    fn soc_of(&self, voltage_v: f64, current_a: f64) -> Option<f64> {
        let s = &self.setup;
        let rest_v = voltage_v + current_a.max(0.0) * s.internal_resistance_ohm;
        state_of_charge_from_rest(rest_v, s.cells, &s.ocv_soc, &s.ocv_cell_v)
    }

    /// Integrates the valid samples from `flight_start_s` on that arrived since the last call.
    fn integrate(&mut self, series: &PowerSeries, flight_start_s: f64) {
        let samples = series.samples();
        while self.integrated < samples.len() {
            let i = self.integrated;
            self.integrated += 1;
            let s = &samples[i];
            if s.power_w().is_some() {
                self.current_known = true;
            }
            if s.t_s >= flight_start_s
                && s.battery.voltage_v.is_some()
                && s.battery.current_a.is_none()
            {
                self.current_lost = true;
            }
            if !series.is_valid(i) || s.t_s < flight_start_s {
                continue;
            }
            let (Some(v), Some(a)) = (s.battery.voltage_v, s.battery.current_a) else {
                continue;
            };
            self.current_lost = false;
            if let Some((t0, p0, a0)) = self.last_valid {
                let dt = (s.t_s - t0).max(0.0);
                self.drawn_j += 0.5 * (p0 + v * a) * dt;
                self.charge_as += 0.5 * (a0 + a) * dt;
            }
            self.last_valid = Some((s.t_s, v * a, a));
            if let Some(soc) = self.soc_of(v, a) {
                self.soc0.get_or_insert(soc);
                self.recent_soc.push_back(soc);
                if self.recent_soc.len() > SOC_WINDOW {
                    self.recent_soc.pop_front();
                }
            }
        }
    }

    /// The pack's capacity against its label, from the charge drawn and the fall of the state
    /// of charge; what it started from (1, or the ledger's) until a tenth of the pack is spent,
    /// never above 1.
    fn learn_capacity(&mut self) {
        let (Some(soc0), false) = (self.soc0, self.recent_soc.is_empty()) else {
            return;
        };
        let now = self.recent_soc.iter().sum::<f64>() / self.recent_soc.len() as f64;
        let spent = soc0 - now;
        if spent < CAPACITY_FROM_SOC || self.setup.capacity_ah <= 0.0 {
            return;
        }
        let measured = self.charge_as / 3600.0 / spent / self.setup.capacity_ah;
        if !measured.is_finite() || measured <= 0.0 {
            return;
        }
        let w = ((spent - CAPACITY_FROM_SOC) / (CAPACITY_FULL_SOC - CAPACITY_FROM_SOC))
            .clamp(0.0, 1.0)
            .max(0.5);
        self.capacity_ratio = ((1.0 - w) * self.start_capacity_ratio + w * measured).min(1.0);
    }

    /// Looks again after a reading: `completed` are the parts flown so far with their measured
    /// energy (J, None when unmeasured), `in_progress` the part being flown. Returns the notes
    /// it made now (the last a `Return` when it decided to send the vehicle home).
    pub fn update(
        &mut self,
        now_s: f64,
        flight_start_s: f64,
        series: &PowerSeries,
        completed: &[(Segment, Option<f64>)],
        in_progress: Option<(SegmentKind, f64)>,
    ) -> Vec<GuardNote> {
        self.integrate(series, flight_start_s);
        let new_part = completed.len() != self.learned_parts;
        if !new_part && now_s - self.last_update_s < UPDATE_EVERY_S {
            return Vec::new();
        }
        self.last_update_s = now_s;
        if new_part {
            self.learned_parts = completed.len();
            let observed: Vec<Observed> = completed
                .iter()
                .filter(|(s, _)| s.complete && s.kind != SegmentKind::Landing)
                .filter_map(|(s, m)| {
                    let predicted_j = self.stages.get(stage_of(s.kind))?.0;
                    Some(Observed {
                        predicted_j,
                        measured_j: (*m)?,
                    })
                })
                .collect();
            self.correction = self.prior.learn_from(&observed, self.typical_j);
        }
        self.learn_capacity();
        let Some((kind, started_s)) = in_progress else {
            return Vec::new();
        };
        if kind == SegmentKind::Landing {
            return Vec::new();
        }
        let remaining = self.remaining(kind, now_s - started_s);
        let scale = self.capacity_ratio;
        let soc0 = self.soc0.unwrap_or(1.0);
        let pack = Pack {
            at_takeoff_j: self.setup.usable_j * scale * soc0,
            reserve_j: self.setup.usable_j * scale * self.setup.reserve_pct / 100.0,
        };
        let projection = project(self.drawn_j, pack, &remaining, &self.correction);
        // Before the first sample of the flight, the gap runs from its start.
        let gap_s = (now_s - self.last_valid.map_or(flight_start_s, |(t, _, _)| t)).max(0.0);
        // A gap in which the battery still sent its voltage is the current missing.
        let current_known = self.current_known && !(self.current_lost && gap_s > MAX_GAP_S);
        let verdict = judge(&projection, gap_s, current_known);
        let mut notes = Vec::new();
        let (name, reason) = match &verdict {
            Verdict::Continue => ("continue", None),
            Verdict::AtRisk => ("at_risk", None),
            Verdict::BelowReserve => ("below_reserve", None),
            Verdict::Unmeasurable { reason } => ("unmeasurable", Some(reason.clone())),
        };
        // A worse verdict is said at once; a better one once it has held for a while, so a
        // projection near a threshold does not chatter.
        let rank = |v: &str| match v {
            "continue" => 0,
            "at_risk" => 1,
            "below_reserve" => 2,
            _ => 3,
        };
        if self.verdict.as_deref() == Some(name) {
            self.better_since = None;
        } else {
            let worse = self.verdict.as_deref().is_none_or(|v| rank(name) > rank(v));
            let since = match &self.better_since {
                Some((v, t)) if v == name => *t,
                _ => {
                    self.better_since = Some((name.to_string(), now_s));
                    now_s
                }
            };
            if worse || now_s - since >= BETTER_HOLD_S {
                let first = self.verdict.is_none();
                self.verdict = Some(name.to_string());
                self.better_since = None;
                if !(first && name == "continue") {
                    notes.push(self.note(
                        now_s,
                        NoteKind::Verdict,
                        name,
                        &projection,
                        reason.clone(),
                    ));
                }
            }
        }
        let measurable = !matches!(verdict, Verdict::Unmeasurable { .. });
        let next = remaining.ahead.first();
        // At the point of no return: the next point is the last from which home is still
        // reached with the reserve, and the plan goes on past it.
        let at_pnr = next.is_some_and(|n| {
            projection.point_of_no_return.as_deref() == Some(n.name.as_str())
                && remaining.ahead.len() > 1
        }) && !projection.plan_finishes;
        if measurable && at_pnr && !self.pnr_noted && !self.returning {
            self.pnr_noted = true;
            notes.push(self.note(now_s, NoteKind::PointOfNoReturn, name, &projection, None));
        }
        if self.setup.policy == Policy::Rtl
            && measurable
            && !self.returning
            && self.learned_parts > 0
            && self.should_return(&projection, &remaining, pack)
        {
            self.returning = true;
            let mut note = self.note(now_s, NoteKind::Return, name, &projection, None);
            note.home_kj = Some(remaining.home_now_j / 1e3);
            note.return_to = Some(remaining.return_to.clone());
            note.message = format!("{} (to {})", note.message, remaining.return_to);
            notes.push(note);
        }
        self.view = Some(GuardView {
            policy: self.setup.policy,
            t_s: now_s,
            verdict: name.to_string(),
            reason,
            drawn_kj: self.drawn_j / 1e3,
            pack_kj: pack.at_takeoff_j / 1e3,
            state_of_charge_at_takeoff: soc0,
            capacity_ratio: scale,
            left_at_landing_kj: projection.left_at_landing_j / 1e3,
            left_at_landing_band_kj: projection.left_at_landing_band_j.map(|j| j / 1e3),
            left_if_home_now_kj: projection.left_if_home_now_j / 1e3,
            reserve_kj: pack.reserve_j / 1e3,
            correction: self.correction.ratio,
            correction_sd_ln: self.correction.sd_ln,
            parts_learned: self.correction.parts,
            point_of_no_return: projection.point_of_no_return.clone(),
            returning: self.returning,
        });
        self.notes.extend(notes.iter().cloned());
        notes
    }

    /// Home now, when the plan cannot be finished with the reserve and either the next point
    /// ahead cannot be reached and left for home with it at the dear end of the band, or home
    /// from here at the dear end would land within a tenth of the reserve of it.
    fn should_return(&self, projection: &Projection, remaining: &Remaining, pack: Pack) -> bool {
        if !projection.below_reserve() {
            return false;
        }
        let dear = self.correction.ratio_at(BAND_SD);
        let left_after = |cost_j: f64| pack.at_takeoff_j - self.drawn_j - cost_j * dear;
        if left_after(remaining.home_now_j) < pack.reserve_j * 1.1 {
            return true;
        }
        match remaining.ahead.first() {
            Some(next) => left_after(next.to_reach_j + next.home_from_j) < pack.reserve_j,
            None => false,
        }
    }

    /// What the plan says is left from `kind`, `elapsed_s` into it.
    fn remaining(&self, kind: SegmentKind, elapsed_s: f64) -> Remaining {
        let i = stage_of(kind).min(self.stages.len() - 1);
        let (energy, duration) = self.stages[i];
        let share_left = if duration > 0.0 {
            (1.0 - elapsed_s / duration).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let this_left = energy * share_left;
        let rest_j = this_left + self.after[i];
        let points = self.setup.home_j.len();
        // The point being flown to (or stopped at) and the one before it.
        let from = match kind {
            SegmentKind::Takeoff | SegmentKind::Landing | SegmentKind::Leg(0) => None,
            SegmentKind::Leg(k) => Some(k - 1),
            SegmentKind::Settle(k) | SegmentKind::Hover(k) => Some(k),
        };
        let landing_j = self.stages.last().map_or(0.0, |s| s.0);
        let home_of = |k: Option<usize>| match k {
            Some(k) => self.setup.home_j.get(k).copied().unwrap_or(landing_j),
            None => landing_j,
        };
        let home_now_j = match kind {
            // Along the leg (through its via points, each with its own return) as far as its
            // time has run.
            SegmentKind::Leg(k) => {
                let done = 1.0 - share_left;
                let mut knots = vec![(0.0, home_of(from))];
                knots.extend(self.via_homes.get(k).into_iter().flatten().copied());
                knots.push((1.0, home_of(Some(k))));
                along(&knots, done)
            }
            _ => home_of(from),
        };
        // Where the return goes from here: the destination of the point the vehicle is nearer.
        let nearer = match kind {
            SegmentKind::Leg(k) if share_left < 0.5 => Some(k),
            _ => from,
        };
        let return_to = nearer
            .and_then(|k| self.setup.return_to.get(k).cloned())
            .unwrap_or_else(|| "home".to_string());
        // The waypoints still ahead (the origin, last, is home itself): reaching each and
        // stopping there (the end of its hover), then home.
        let ahead = (0..points.saturating_sub(1))
            .filter(|&k| stage_of(SegmentKind::Hover(k)) > i)
            .map(|k| PointAhead {
                name: self.names[k].clone(),
                to_reach_j: this_left + self.after[i] - self.after[stage_of(SegmentKind::Hover(k))],
                home_from_j: self.setup.home_j[k],
            })
            .collect();
        Remaining {
            rest_j,
            ahead,
            home_now_j,
            return_to,
        }
    }

    fn note(
        &self,
        t_s: f64,
        kind: NoteKind,
        verdict: &str,
        p: &Projection,
        reason: Option<String>,
    ) -> GuardNote {
        let kj = |j: f64| j / 1e3;
        let message = match (kind, verdict) {
            (NoteKind::Return, _) => format!(
                "sending the vehicle home: finishing the plan would land with {:.0} kJ against a {:.0} kJ reserve (correction x{:.2}); home from here lands with {:.0} kJ",
                kj(p.left_at_landing_j), kj(p.reserve_j), p.correction.ratio, kj(p.left_if_home_now_j)
            ),
            (NoteKind::PointOfNoReturn, _) => format!(
                "point of no return: after {}, home is no longer reached with the {:.0} kJ reserve",
                p.point_of_no_return.as_deref().unwrap_or("here"),
                kj(p.reserve_j)
            ),
            (NoteKind::Verdict, "unmeasurable") => format!(
                "the guard cannot judge: {}; it will not act until the battery is measured again",
                reason.as_deref().unwrap_or("the battery is not measured")
            ),
            (NoteKind::Verdict, "below_reserve") => format!(
                "finishing the plan is projected to land with {:.0} kJ, below the {:.0} kJ reserve (correction x{:.2})",
                kj(p.left_at_landing_j), kj(p.reserve_j), p.correction.ratio
            ),
            (NoteKind::Verdict, "at_risk") => format!(
                "the plan finishes with {:.0} kJ left but may not keep the {:.0} kJ reserve (band {:.0}..{:.0} kJ, correction x{:.2})",
                kj(p.left_at_landing_j), kj(p.reserve_j), kj(p.left_at_landing_band_j[0]), kj(p.left_at_landing_band_j[1]), p.correction.ratio
            ),
            _ => format!(
                "the plan finishes with {:.0} kJ left, above the {:.0} kJ reserve",
                kj(p.left_at_landing_j), kj(p.reserve_j)
            ),
        };
        GuardNote {
            t_s,
            kind,
            verdict: verdict.to_string(),
            message,
            left_at_landing_kj: kj(p.left_at_landing_j),
            reserve_kj: kj(p.reserve_j),
            home_kj: None,
            return_to: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::flight_plan::{Predicted, PredictedLeg};
    use crate::flightlog::guard::PRIOR_SD_LN;
    use crate::flightlog::segment::{SegmentConfig, Segmenter};
    use crate::flightlog::synthetic::{square_plan, SyntheticConfig, SyntheticFlight};
    use crate::flightlog::telemetry::{Reading, Stamped};

    /// The square plan priced exactly as the nominal synthetic flight flies it, guarded with
    /// `policy` on a pack of `usable_j`.
    fn plan(usable_j: f64, policy: Policy) -> crate::flightlog::flight_plan::FlightPlan {
        guarded(square_plan(), usable_j, policy)
    }

    /// `plan` priced exactly as the nominal synthetic flight flies it, guarded with `policy` on
    /// a pack of `usable_j`.
    fn guarded(
        mut plan: crate::flightlog::flight_plan::FlightPlan,
        usable_j: f64,
        policy: Policy,
    ) -> crate::flightlog::flight_plan::FlightPlan {
        let truth = SyntheticFlight::fly(&plan, &SyntheticConfig::default());
        let energy = |kind: SegmentKind| {
            let p = truth.parts.iter().find(|p| p.kind == kind).expect("a part");
            (p.energy_j(), p.end_s - p.start_s)
        };
        let n = plan.points.len();
        plan.predicted = Some(Predicted {
            takeoff_j: energy(SegmentKind::Takeoff).0,
            landing_j: energy(SegmentKind::Landing).0,
            legs: (0..n)
                .map(|k| {
                    let (e, d) = energy(SegmentKind::Leg(k));
                    let (se, sd) = energy(SegmentKind::Settle(k));
                    PredictedLeg {
                        energy_j: e,
                        duration_s: d,
                        settle_energy_j: se,
                        settle_duration_s: sd,
                    }
                })
                .collect(),
            hover_power_w: SyntheticConfig::default().hover_power_w,
        });
        plan.guard = Some(GuardSetup {
            policy,
            usable_j,
            reserve_pct: 20.0,
            cells: 6,
            capacity_ah: 10.0,
            internal_resistance_ohm: 0.0,
            ocv_soc: vec![0.0, 1.0],
            ocv_cell_v: vec![3.5, 4.2],
            // Home from each point: a 60 m leg and the landing.
            home_j: vec![60_000.0; n],
            return_to: Vec::new(),
            return_rule: None,
            via_home_j: Vec::new(),
            start: None,
        });
        plan
    }

    /// Flies `plan` with every power `scale` times the nominal, then `edit` on the readings.
    fn flown(
        plan: &crate::flightlog::flight_plan::FlightPlan,
        scale: f64,
        edit: impl Fn(&mut Vec<Stamped>, &SyntheticFlight),
    ) -> Segmenter {
        let d = SyntheticConfig::default();
        let cfg = SyntheticConfig {
            takeoff_power_w: d.takeoff_power_w * scale,
            leg_power_w: d.leg_power_w * scale,
            settle_power_w: d.settle_power_w * scale,
            hover_power_w: d.hover_power_w * scale,
            landing_power_w: d.landing_power_w * scale,
            ..d
        };
        let flight = SyntheticFlight::fly(plan, &cfg);
        let mut stamped = flight.stamped();
        edit(&mut stamped, &flight);
        Segmenter::run(plan.clone(), SegmentConfig::default(), &stamped).expect("a valid plan")
    }

    /// The energy the nominal flight draws, start to end of its log.
    fn nominal_total_j() -> f64 {
        let nominal = flown(&plan(2_000_000.0, Policy::Warn), 1.0, |_, _| {});
        let measured = nominal.series().measure(0.0, nominal.now_s()).energy_j;
        measured.expect("the nominal flight is measured")
    }

    fn notes(s: &Segmenter, kind: NoteKind) -> Vec<GuardNote> {
        let w = s.watch().expect("guarded");
        w.notes()
            .iter()
            .filter(|n| n.kind == kind)
            .cloned()
            .collect()
    }

    /// The guard's view after the readings up to `until_s` of `flight`, measured against `plan`.
    fn view_at(
        plan: &crate::flightlog::flight_plan::FlightPlan,
        flight: &SyntheticFlight,
        until_s: f64,
    ) -> GuardView {
        let mut s = Segmenter::new(plan.clone(), SegmentConfig::default()).expect("valid");
        for r in flight.stamped().iter().filter(|r| r.t_s <= until_s) {
            s.push(r);
        }
        s.watch().and_then(|w| w.view().cloned()).expect("a view")
    }

    #[test]
    fn the_way_home_from_a_leg_round_a_zone_is_priced_through_its_via_points() {
        use crate::flightlog::telemetry::Reading;
        // The square's leg A -> B round a zone through (85, 30, 5): take-off 0, A 1, via 2, B 3,
        // C 4, origin 5, land 6.
        let via = crate::mission::Enu {
            x_east_m: 85.0,
            y_north_m: 30.0,
            z_up_m: 5.0,
        };
        let routed = square_plan()
            .renumbered(Some(0), &[1, 3, 4, 5], 6)
            .and_then(|p| p.routed(&[vec![], vec![via]], &[vec![], vec![2]]))
            .expect("valid");
        let without = guarded(routed, 2_000_000.0, Policy::Warn);
        // Home from the via point is dearer than from either end of the leg.
        let mut with = without.clone();
        if let Some(g) = with.guard.as_mut() {
            g.via_home_j = vec![vec![], vec![200_000.0], vec![], vec![]];
        }
        let flight = SyntheticFlight::fly(&with, &SyntheticConfig::default());
        let passed = (flight.messages.iter())
            .find(|m| matches!(m.reading, Reading::ItemReached { seq: 2 }))
            .map(|m| m.t_s)
            .expect("the via point passed");
        let (a, b) = (
            view_at(&with, &flight, passed),
            view_at(&without, &flight, passed),
        );
        // 140 kJ dearer at the via point, less what the leg's time share misses of it.
        let dearer_kj = b.left_if_home_now_kj - a.left_if_home_now_kj;
        assert!(dearer_kj > 100.0 && dearer_kj < 150.0, "{dearer_kj} kJ");
        // Before the leg, the same.
        let leg = flight.part(SegmentKind::Leg(1)).expect("leg 1");
        let (a, b) = (
            view_at(&with, &flight, leg.start_s - 0.5),
            view_at(&without, &flight, leg.start_s - 0.5),
        );
        assert!((a.left_if_home_now_kj - b.left_if_home_now_kj).abs() < 1e-9);
        // plan.json keeps the via points' returns.
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("plan.json");
        with.write_json(&path).expect("written");
        let back = crate::flightlog::flight_plan::FlightPlan::read_json(&path).expect("read");
        let via_homes = |p: &crate::flightlog::flight_plan::FlightPlan| {
            p.guard.as_ref().map(|g| g.via_home_j.clone())
        };
        assert_eq!(via_homes(&back), via_homes(&with));
    }

    #[test]
    fn a_repricing_reaches_the_guard_when_its_time_comes_with_the_rest_at_its_new_price() {
        use crate::flightlog::flight_plan::Repricing;
        let base = plan(2_000_000.0, Policy::Warn);
        let flight = SyntheticFlight::fly(&base, &SyntheticConfig::default());
        let leg1 = (flight.parts.iter())
            .find(|p| p.kind == SegmentKind::Leg(1))
            .expect("leg 1");
        let t_s = leg1.start_s - 1.0;
        let predicted = base.predicted.clone().expect("priced");
        let dearer: Vec<PredictedLeg> = (predicted.legs[1..].iter())
            .map(|l| PredictedLeg {
                energy_j: 2.0 * l.energy_j,
                ..*l
            })
            .collect();
        let extra_j: f64 = predicted.legs[1..].iter().map(|l| l.energy_j).sum();
        let mut repriced = base.clone();
        repriced.repricings.push(Repricing {
            t_s,
            wind: crate::mission::wind::Wind::new(8.0, 270.0).expect("a wind"),
            from_point: 1,
            legs: dearer,
            hover_power_w: predicted.hover_power_w,
            landing_j: predicted.landing_j,
            home_j: vec![90_000.0; base.points.len()],
            rest_before_j: 0.0,
            rest_after_j: 0.0,
        });
        // Before its time the two guards see the same; after it, the rest costs the extra.
        let before = (
            view_at(&base, &flight, t_s - 0.6),
            view_at(&repriced, &flight, t_s - 0.6),
        );
        assert_eq!(before.0, before.1);
        let after = (
            view_at(&base, &flight, t_s + 0.6),
            view_at(&repriced, &flight, t_s + 0.6),
        );
        let less_kj = after.0.left_at_landing_kj - after.1.left_at_landing_kj;
        assert!(
            (less_kj / (extra_j / 1e3) / after.1.correction - 1.0).abs() < 1e-6,
            "{less_kj} kJ less, the rest {extra_j} J dearer"
        );
        assert!(after.1.left_if_home_now_kj < after.0.left_if_home_now_kj);
    }

    /// `plan` starting from what earlier flights taught: a pack of `capacity_ratio` and a
    /// vehicle costing `correction` times the model (known to `sd_ln`; 0 vehicle flights
    /// when `correction` is None).
    fn started(
        mut plan: crate::flightlog::flight_plan::FlightPlan,
        capacity_ratio: f64,
        correction: Option<(f64, f64)>,
    ) -> crate::flightlog::flight_plan::FlightPlan {
        let (c, sd, flights) = correction.map_or((1.0, 0.7, 0), |(c, sd)| (c, sd, 4));
        if let Some(g) = plan.guard.as_mut() {
            g.start = Some(crate::flightlog::guard::GuardStart {
                capacity_ratio,
                pack_flights: 3,
                correction: c,
                correction_sd_ln: sd,
                vehicle_flights: flights,
            });
        }
        plan
    }

    #[test]
    fn a_guard_starting_from_a_pack_of_085_judges_its_first_verdict_with_it() {
        let label = plan(2_000_000.0, Policy::Warn);
        let aged = started(label.clone(), 0.85, None);
        let flight = SyntheticFlight::fly(&label, &SyntheticConfig::default());
        let takeoff = flight.part(SegmentKind::Takeoff).expect("a take-off");
        // The first view, early in the take-off: far less than a tenth of the pack spent.
        let t_s = takeoff.start_s + 1.0;
        let (l, a) = (view_at(&label, &flight, t_s), view_at(&aged, &flight, t_s));
        assert!(l.drawn_kj < 0.1 * l.pack_kj, "{l:?}");
        assert_eq!((l.capacity_ratio, a.capacity_ratio), (1.0, 0.85));
        assert!((a.pack_kj / l.pack_kj - 0.85).abs() < 1e-9, "{a:?} {l:?}");
        assert!((a.reserve_kj / l.reserve_kj - 0.85).abs() < 1e-9);
        assert!(a.left_at_landing_kj < l.left_at_landing_kj);
        // No vehicle learned: the model's prior.
        assert_eq!((a.correction, a.correction_sd_ln), (1.0, PRIOR_SD_LN));
        // The report keeps the capacity it measured from there: never above the label.
        let s = flown(&aged, 1.0, |_, _| {});
        let report = s.watch().expect("guarded").report();
        assert!(report.capacity_ratio <= 1.0, "{report:?}");
    }

    #[test]
    fn a_guard_starting_from_the_vehicles_correction_warns_before_any_part_is_flown() {
        // A pack on which the plan lands with about a third left at the model's price: at 1.6
        // times it, below the reserve.
        let total = nominal_total_j();
        let tight = plan(total * 1.5, Policy::Warn);
        let learned = started(tight.clone(), 1.0, Some((1.6, 0.05)));
        let flight = SyntheticFlight::fly(&tight, &SyntheticConfig::default());
        let takeoff = flight.part(SegmentKind::Takeoff).expect("a take-off");
        let t_s = takeoff.start_s + 1.0;
        let (bare, start) = (
            view_at(&tight, &flight, t_s),
            view_at(&learned, &flight, t_s),
        );
        assert_eq!((bare.parts_learned, start.parts_learned), (0, 0));
        assert_eq!(bare.verdict, "continue");
        assert_eq!(start.verdict, "below_reserve", "{start:?}");
        assert_eq!((start.correction, start.correction_sd_ln), (1.6, 0.05));
    }

    #[test]
    fn the_correction_learned_in_flight_converges_to_the_truth_ratio() {
        let plan = plan(2_000_000.0, Policy::Warn);
        for truth in [1.0, 1.6] {
            let s = flown(&plan, truth, |_, _| {});
            let report = s.watch().expect("guarded").report();
            assert!(
                (report.correction / truth - 1.0).abs() < 0.03,
                "truth x{truth}: learned x{:.3}",
                report.correction
            );
        }
    }

    #[test]
    fn a_flight_dearer_than_its_plan_on_a_tight_pack_is_sent_home_once_and_warned_of_first() {
        // The plan lands with about a third of the pack; at 1.6 times its price it cannot.
        let total = nominal_total_j();
        let tight = plan(total * 1.5, Policy::Rtl);
        let s = flown(&tight, 1.0, |_, _| {});
        assert!(notes(&s, NoteKind::Return).is_empty(), "nominal sent home");
        let s = flown(&tight, 1.6, |_, _| {});
        let below: Vec<GuardNote> = notes(&s, NoteKind::Verdict)
            .into_iter()
            .filter(|n| n.verdict == "below_reserve")
            .collect();
        let home = notes(&s, NoteKind::Return);
        assert_eq!(home.len(), 1, "{:?}", s.watch().unwrap().notes());
        assert!(!below.is_empty() && below[0].t_s <= home[0].t_s);
        // The warn policy says the same and never decides.
        let warned = flown(&plan(total * 1.5, Policy::Warn), 1.6, |_, _| {});
        assert!(notes(&warned, NoteKind::Return).is_empty());
        assert!(notes(&warned, NoteKind::Verdict)
            .iter()
            .any(|n| n.verdict == "below_reserve"));
    }

    #[test]
    fn the_guard_says_where_its_return_goes_as_priced_for_the_point_it_left() {
        let total = nominal_total_j();
        let mut tight = plan(total * 1.5, Policy::Rtl);
        let n = tight.points.len();
        if let Some(g) = tight.guard.as_mut() {
            g.return_to = (0..n)
                .map(|k| format!("rally point {}", k % 2 + 1))
                .collect();
        }
        let s = flown(&tight, 1.6, |_, _| {});
        let home = notes(&s, NoteKind::Return);
        assert_eq!(home.len(), 1, "{:?}", s.watch().unwrap().notes());
        let to = home[0].return_to.as_deref().expect("a destination");
        assert!(to.starts_with("rally point "), "{to}");
        assert!(
            home[0].message.ends_with(&format!("(to {to})")),
            "{}",
            home[0].message
        );
        // A setup priced before destinations were kept returns home.
        let old = flown(&plan(total * 1.5, Policy::Rtl), 1.6, |_, _| {});
        assert_eq!(
            notes(&old, NoteKind::Return)[0].return_to.as_deref(),
            Some("home")
        );
    }

    #[test]
    fn one_odd_leg_does_not_send_the_vehicle_home() {
        let total = nominal_total_j();
        // A pack the plan fits with room: one leg at three times its price does not change that.
        let plan = plan(total * 2.2, Policy::Rtl);
        let s = flown(&plan, 1.0, |stamped, flight| {
            let odd = flight
                .parts
                .iter()
                .find(|p| p.kind == SegmentKind::Leg(1))
                .expect("leg 1");
            for s in stamped.iter_mut() {
                if let Reading::Battery(b) = &mut s.reading {
                    if (odd.start_s..odd.end_s).contains(&s.t_s) {
                        b.current_a = b.current_a.map(|a| a * 3.0);
                    }
                }
            }
        });
        let w = s.watch().expect("guarded");
        assert!(notes(&s, NoteKind::Return).is_empty(), "{:?}", w.notes());
        assert!(w.report().correction < 1.2, "{:?}", w.report());
    }

    #[test]
    fn a_measurement_gap_suspends_the_guard_with_a_warning_and_it_judges_again_after() {
        let total = nominal_total_j();
        // A pack too small to finish at 1.6 times the price: without the gap the guard would
        // act as the take-off ends.
        let plan = plan(total * 1.5, Policy::Rtl);
        let s = flown(&plan, 1.6, |stamped, flight| {
            // No battery reading for 20 s from 6 s before the take-off's end.
            let from = flight.parts[0].end_s - 6.0;
            stamped.retain(|s| {
                !(matches!(s.reading, Reading::Battery(_)) && (from..from + 20.0).contains(&s.t_s))
            });
        });
        let w = s.watch().expect("guarded");
        let unmeasurable: Vec<GuardNote> = notes(&s, NoteKind::Verdict)
            .into_iter()
            .filter(|n| n.verdict == "unmeasurable")
            .collect();
        assert!(!unmeasurable.is_empty(), "{:?}", w.notes());
        assert!(unmeasurable[0].message.contains("cannot judge"));
        // Not sent home while it could not measure; judged again (and sent home) after.
        let home = notes(&s, NoteKind::Return);
        assert_eq!(home.len(), 1, "{:?}", w.notes());
        assert!(home[0].t_s > unmeasurable[0].t_s + 15.0, "{:?}", w.notes());
    }

    #[test]
    fn a_battery_that_keeps_its_voltage_but_loses_its_current_is_said_to_lack_the_current() {
        let total = nominal_total_j();
        let plan = plan(total * 1.5, Policy::Rtl);
        let s = flown(&plan, 1.6, |stamped, flight| {
            // The current unknown (-1) for 20 s from 6 s before the take-off's end; the
            // voltage still arrives.
            let from = flight.parts[0].end_s - 6.0;
            for s in stamped.iter_mut() {
                if let Reading::Battery(b) = &mut s.reading {
                    if (from..from + 20.0).contains(&s.t_s) {
                        b.current_a = None;
                    }
                }
            }
        });
        let w = s.watch().expect("guarded");
        let unmeasurable: Vec<GuardNote> = notes(&s, NoteKind::Verdict)
            .into_iter()
            .filter(|n| n.verdict == "unmeasurable")
            .collect();
        assert!(!unmeasurable.is_empty(), "{:?}", w.notes());
        let message = &unmeasurable[0].message;
        assert!(message.contains("battery current"), "{message}");
        assert!(!message.contains("no valid battery sample"), "{message}");
    }
}
