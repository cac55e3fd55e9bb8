//! What a flight is measured against: the points flown in order (with the mission sequence
//! numbers the autopilot reports them by), the frame positions are compared in, and the
//! predictions. The lead's `fly` builds one from the planner's order and prediction (or from the
//! mission read back from the autopilot); the recorder writes it as plan.json so a replay can
//! always rebuild the report.
//!
//! Mission layout flown: `[ArduPilot: home at seq 0] NAV_TAKEOFF, NAV_WAYPOINT
//! x N (the planned order), NAV_WAYPOINT at the origin (the return leg), NAV_LAND`. Positions are
//! in the mission's own frame (`Mission::waypoints`: metres east, north, up from the origin hover
//! point at `origin_height_m` above home); the vehicle's GLOBAL_POSITION_INT is brought into it
//! with `mission::geodesy`, its height above the vehicle's home (as the uploaded items'
//! altitudes are): `alt` less HOME_POSITION's altitude when the autopilot sends it, else
//! `relative_alt` ([`FlightPlan::to_local`]). The segmenter measures positions from the first
//! home reported and lifts each point by how far the home had moved when the autopilot set it
//! as its target (PX4 SITL's home moves in flight).

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::telemetry::Position;
use super::FlightLogError;
use crate::mission::{Enu, Geodetic, Mission, Origin};

/// The name of the origin in legs' `from` and `to` (as the planner names it).
pub const ORIGIN_NAME: &str = "origin";

/// One point visited, in flying order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlannedPoint {
    /// Its mission item's sequence number (what MISSION_CURRENT and MISSION_ITEM_REACHED say).
    pub seq: u16,
    pub name: String,
    /// Position in the mission frame (east, north, up from the origin hover point).
    pub enu: Enu,
    /// Planned hover time at the point (its hover and its actions' holds).
    pub hold_s: f64,
    /// The photos the mission takes at the point (its photo actions: the autopilot runs them
    /// as it leaves the point for the next). A point whose photos the autopilot did not all
    /// report is not visited (`flightlog::resume`). Absent from plan.json when none (and from
    /// files written before it was kept).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub photos: u32,
    /// The points the leg to this point passes through without a hold on its way round a
    /// fence zone, in the order flown (empty: a straight leg). They are not points of the
    /// flight: the leg is measured from its departure to its arrival here, as one, against its
    /// price (the whole chain's). Absent from plan.json when none (and from files written
    /// before they were kept).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub via: Vec<ViaPoint>,
}

/// A point a leg passes through without a hold ([`PlannedPoint::via`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ViaPoint {
    /// Its mission item's sequence number: after the item of the point the leg leaves, before
    /// the item of the point it goes to.
    pub seq: u16,
    /// Position in the mission frame.
    pub enu: Enu,
}

fn is_zero(n: &u32) -> bool {
    *n == 0
}

/// The prediction of one leg (legs[k] ends at points[k]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PredictedLeg {
    /// From leaving hover to first within the arrival radius (the paper's operation energy).
    pub energy_j: f64,
    pub duration_s: f64,
    /// From the arrival radius to settled hover at the point.
    pub settle_energy_j: f64,
    pub settle_duration_s: f64,
}

/// Predicted energies of a flight.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Predicted {
    pub takeoff_j: f64,
    pub landing_j: f64,
    pub legs: Vec<PredictedLeg>,
    pub hover_power_w: f64,
}

/// The flight as planned and uploaded.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlightPlan {
    pub mission: String,
    /// Home (AMSL altitude); the origin is above it.
    pub home: Geodetic,
    /// Height of the origin hover point above home.
    pub origin_height_m: f64,
    /// Waypoints in flying order, then the origin (the return leg).
    pub points: Vec<PlannedPoint>,
    pub takeoff_seq: Option<u16>,
    pub land_seq: Option<u16>,
    pub predicted: Option<Predicted>,
    /// The flight this one resumes (`emplan fly --resume`: the name of its directory), flying
    /// the waypoints it did not reach (`flightlog::resume`). Absent from plans of other flights
    /// and from plan.json files written before it was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resumes: Option<String>,
    /// The energy guard's setup (policy, pack, return prices), when the flight is guarded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub guard: Option<crate::flightlog::guard::GuardSetup>,
    /// The steady wind the predictions are priced in (`--wind`, or the vehicle's own estimate
    /// with `--wind live`); absent in still air.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wind: Option<crate::mission::wind::Wind>,
    /// What was left of the flight priced again in a wind the vehicle estimated in flight
    /// (`fly --wind live`), in the order they took effect. Not in plan.json (written before the
    /// flight): the flight directory's repriced.jsonl, one line each as they were made.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub repricings: Vec<Repricing>,
    /// What priced the predictions: the vehicle and the profile the flight was planned with
    /// (and so flown with). Absent from plan.json files written before it was kept, and from a
    /// plan without predictions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub priced_by: Option<PricedBy>,
    /// The mission's blocks (surveys, scans) the flight flies, in flying order: which of its
    /// points each is and which way it is flown. Absent from plan.json when none (and from
    /// files written before they were kept).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub blocks: Vec<PlannedBlock>,
    /// The battery pack flown (`--pack`, or the one the autopilot names): absent when not
    /// known, and from files written before it was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pack: Option<PackUse>,
}

/// The pack a flight flies on, and what its battery check started from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PackUse {
    pub name: String,
    pub source: PackSource,
    /// The pack's capacity against its label that the battery check and the guard started
    /// from (the ledger's estimate; None: the label).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub capacity_ratio: Option<f64>,
}

/// Who named the pack.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PackSource {
    /// The user (`--pack`).
    User,
    /// The autopilot (SMART_BATTERY_INFO's serial number or device name).
    Autopilot,
}

/// A block of the mission as the flight flies it: `points[first_point..=last_point]`, its inner
/// legs the legs to `points[first_point + 1..=last_point]` (the leg to its first point is the
/// connecting leg that enters it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlannedBlock {
    pub name: String,
    /// What made it (`survey`, `corridor scan`, `structure scan`, `block`).
    pub kind: String,
    /// Flown last waypoint first.
    pub reversed: bool,
    pub first_point: usize,
    pub last_point: usize,
    /// The camera trigger distance in force on its lines (the first line flown with one;
    /// None: the trigger is off on all of them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trigger_distance_m: Option<f64>,
    /// The length of its lines flown with the camera trigger on (m, 3D).
    #[serde(default, skip_serializing_if = "is_zero_f64")]
    pub triggered_m: f64,
}

impl PlannedBlock {
    /// Its inner legs, as indices of the legs to `points[k]`.
    pub fn legs(&self) -> std::ops::RangeInclusive<usize> {
        self.first_point + 1..=self.last_point
    }

    /// The photos its distance trigger takes along its lines, about: one each trigger
    /// distance (0 with the trigger off).
    pub fn photos_expected(&self) -> u32 {
        match self.trigger_distance_m {
            Some(d) if d > 0.0 => (self.triggered_m / d).round() as u32,
            _ => 0,
        }
    }
}

fn is_zero_f64(v: &f64) -> bool {
    *v == 0.0
}

/// The runs of `order` (indices into `mission`'s waypoints) that fly two or more waypoints of
/// one of its blocks in a row, forward or reversed, as the flight's blocks.
pub fn planned_blocks(mission: &Mission, order: &[usize]) -> Vec<PlannedBlock> {
    let states = mission.file_states();
    let mut out = Vec::new();
    let mut i = 0;
    while i < order.len() {
        let Some(block) = mission
            .block_of(order[i])
            .and_then(|b| mission.blocks.get(b))
        else {
            i += 1;
            continue;
        };
        let step = |a: usize, b: usize| -> Option<bool> {
            match () {
                _ if b == a + 1 => Some(false),
                _ if b + 1 == a => Some(true),
                _ => None,
            }
        };
        let reversed = order
            .get(i + 1)
            .and_then(|&n| step(order[i], n).filter(|_| block.contains(n)));
        let Some(reversed) = reversed else {
            i += 1;
            continue;
        };
        let mut j = i + 1;
        while j + 1 < order.len()
            && block.contains(order[j + 1])
            && step(order[j], order[j + 1]) == Some(reversed)
        {
            j += 1;
        }
        let (lo, hi) = (order[i].min(order[j]), order[i].max(order[j]));
        let mut trigger_distance_m = None;
        let mut triggered_m = 0.0;
        for line in lo..hi {
            let on = states.after[line]
                .get(crate::mission::actions::Setting::TriggerDistance)
                .map(|c| c.params[0])
                .filter(|d| d.is_finite() && *d > 0.0);
            if let Some(d) = on {
                let (a, b) = (
                    mission.waypoints[line].position,
                    mission.waypoints[line + 1].position,
                );
                triggered_m += (a.x_east_m - b.x_east_m)
                    .hypot(a.y_north_m - b.y_north_m)
                    .hypot(a.z_up_m - b.z_up_m);
                trigger_distance_m.get_or_insert(d);
            }
        }
        out.push(PlannedBlock {
            name: block.name.clone(),
            kind: block.kind.word().to_string(),
            reversed,
            first_point: i,
            last_point: j,
            trigger_distance_m,
            triggered_m,
        });
        i = j + 1;
    }
    out
}

/// The vehicle and the profile a flight's predictions were priced with. The profile is its
/// name (`ptf`, `hvb`, `px4`, `ardupilot`): this module knows no physics.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct PricedBy {
    /// The vehicle file's `name`.
    pub vehicle: String,
    pub profile: String,
}

/// The rest of a flight priced again, from `from_point` on, in a wind heard in flight.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Repricing {
    /// Flight-log time it took effect (s).
    pub t_s: f64,
    /// The wind the rest is priced in (the vehicle's estimate, averaged).
    pub wind: crate::mission::wind::Wind,
    /// The first point whose leg is priced again (legs before it had begun).
    pub from_point: usize,
    /// The legs to points `from_point..` (their settles too).
    pub legs: Vec<PredictedLeg>,
    /// The hover power at those points, and the landing.
    pub hover_power_w: f64,
    pub landing_j: f64,
    /// The guard's price of the autopilot's return from every point, in this wind (empty when
    /// the flight is not guarded).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub home_j: Vec<f64>,
    /// What the stages from `from_point` on (legs, settles, hovers, the landing) were priced at
    /// before, and are now.
    pub rest_before_j: f64,
    pub rest_after_j: f64,
}

/// What a mission sequence number means for the flight.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Target {
    /// Take-off or anything before the first leg.
    BeforeLegs,
    /// The leg to points[k] (or an item on the way to it).
    Leg(usize),
    /// Landing (or anything after the last point).
    Landing,
}

fn plan_error(reason: impl Into<String>) -> FlightLogError {
    FlightLogError::Plan {
        reason: reason.into(),
    }
}

impl Repricing {
    /// Whether it prices a leg for each of a plan of `points` points from its own on.
    pub fn fits(&self, points: usize) -> bool {
        from_point_fits(self.from_point, self.legs.len(), points)
    }
}

fn from_point_fits(from_point: usize, legs: usize, points: usize) -> bool {
    from_point < points && legs == points - from_point
}

impl FlightPlan {
    /// The plan with its points, take-off and landing numbered as the items uploaded hold them
    /// (a mission with actions has commands between its navigation items): `point_seqs` for
    /// the points in flying order (the origin last).
    pub fn renumbered(
        mut self,
        takeoff_seq: Option<u16>,
        point_seqs: &[u16],
        land_seq: u16,
    ) -> Result<FlightPlan, FlightLogError> {
        if point_seqs.len() != self.points.len() {
            return Err(plan_error(format!(
                "{} item numbers for {} points",
                point_seqs.len(),
                self.points.len()
            )));
        }
        for (point, &seq) in self.points.iter_mut().zip(point_seqs) {
            point.seq = seq;
        }
        self.takeoff_seq = takeoff_seq;
        self.land_seq = Some(land_seq);
        Ok(self)
    }

    /// The plan with each leg's via points (`via[k]`, the leg to points[k]; missing lists
    /// are straight legs) at the items `via_seqs[k]` the upload holds them in.
    pub fn routed(
        mut self,
        via: &[Vec<Enu>],
        via_seqs: &[Vec<u16>],
    ) -> Result<FlightPlan, FlightLogError> {
        if via.len() > self.points.len() {
            return Err(plan_error(format!(
                "via points for {} legs of {}",
                via.len(),
                self.points.len()
            )));
        }
        for (k, (point, enus)) in self.points.iter_mut().zip(via).enumerate() {
            let seqs = via_seqs.get(k).map_or(&[][..], Vec::as_slice);
            if seqs.len() != enus.len() {
                return Err(plan_error(format!(
                    "{} item numbers for the {} via points of the leg to {}",
                    seqs.len(),
                    enus.len(),
                    point.name
                )));
            }
            point.via = seqs
                .iter()
                .zip(enus)
                .map(|(&seq, &enu)| ViaPoint { seq, enu })
                .collect();
        }
        self.validate()?;
        Ok(self)
    }

    /// The way leg `k` flies: from the point it leaves (the origin for the first) through its
    /// via points to points[k].
    pub fn leg_path(&self, k: usize) -> Vec<Enu> {
        let from = match k {
            0 => Enu::default(),
            _ => self.points.get(k - 1).map_or_else(Enu::default, |p| p.enu),
        };
        let Some(to) = self.points.get(k) else {
            return vec![from];
        };
        std::iter::once(from)
            .chain(to.via.iter().map(|v| v.enu))
            .chain(std::iter::once(to.enu))
            .collect()
    }

    /// The plan `fly` uploads for `mission` visited in `order` (indices into its waypoints):
    /// take-off at `first_seq` (1 for ArduPilot, whose seq 0 is home; 0 for PX4), the
    /// waypoints, the origin, landing.
    pub fn for_mission(
        mission: &Mission,
        order: &[usize],
        first_seq: u16,
        predicted: Option<Predicted>,
    ) -> Result<FlightPlan, FlightLogError> {
        let mut points = Vec::with_capacity(order.len() + 1);
        for (k, &w) in order.iter().enumerate() {
            let waypoint = mission.waypoints.get(w).ok_or_else(|| {
                plan_error(format!(
                    "order names waypoint {w}, of {}",
                    mission.waypoints.len()
                ))
            })?;
            points.push(PlannedPoint {
                seq: seq_at(first_seq, k + 1)?,
                name: waypoint.name.clone(),
                enu: waypoint.position,
                hold_s: waypoint.hold_s(),
                photos: waypoint.photos(),
                via: Vec::new(),
            });
        }
        points.push(PlannedPoint {
            seq: seq_at(first_seq, order.len() + 1)?,
            name: ORIGIN_NAME.to_string(),
            enu: Enu::default(),
            hold_s: 0.0,
            photos: 0,
            via: Vec::new(),
        });
        let plan = FlightPlan {
            mission: mission.name.clone(),
            home: mission.origin.home,
            origin_height_m: mission.origin.height_above_home_m,
            points,
            takeoff_seq: Some(first_seq),
            land_seq: Some(seq_at(first_seq, order.len() + 2)?),
            predicted,
            resumes: None,
            guard: None,
            wind: None,
            repricings: Vec::new(),
            priced_by: None,
            blocks: planned_blocks(mission, order),
            pack: None,
        };
        plan.validate()?;
        Ok(plan)
    }

    /// Checks what segmentation relies on: at least one point, increasing sequence numbers,
    /// finite positions, one prediction per leg.
    pub fn validate(&self) -> Result<(), FlightLogError> {
        if self.points.is_empty() {
            return Err(plan_error("no points to fly"));
        }
        for (k, pair) in self.points.windows(2).enumerate() {
            if pair[1].seq <= pair[0].seq {
                return Err(plan_error(format!(
                    "point {} ({}) has seq {} after seq {}",
                    k + 1,
                    pair[1].name,
                    pair[1].seq,
                    pair[0].seq
                )));
            }
        }
        let finite =
            |e: &Enu| e.x_east_m.is_finite() && e.y_north_m.is_finite() && e.z_up_m.is_finite();
        for (k, p) in self.points.iter().enumerate() {
            if !finite(&p.enu) {
                return Err(plan_error(format!(
                    "point {} has a non-finite position",
                    p.name
                )));
            }
            // Via points sit between the point left (or the take-off) and this one.
            let mut after = match k {
                0 => self.takeoff_seq,
                _ => Some(self.points[k - 1].seq),
            };
            for (j, v) in p.via.iter().enumerate() {
                if after.is_some_and(|a| v.seq <= a) || v.seq >= p.seq {
                    return Err(plan_error(format!(
                        "via point {} of the leg to {} has seq {}, not between seq {} and seq {}",
                        j + 1,
                        p.name,
                        v.seq,
                        after.map_or_else(|| "-".to_string(), |a| a.to_string()),
                        p.seq
                    )));
                }
                if !finite(&v.enu) {
                    return Err(plan_error(format!(
                        "via point {} of the leg to {} has a non-finite position",
                        j + 1,
                        p.name
                    )));
                }
                after = Some(v.seq);
            }
        }
        if let (Some(t), Some(first)) = (self.takeoff_seq, self.points.first()) {
            if t >= first.seq {
                return Err(plan_error(format!(
                    "take-off seq {t} is not before the first point's {}",
                    first.seq
                )));
            }
        }
        if let (Some(l), Some(last)) = (self.land_seq, self.points.last()) {
            if l <= last.seq {
                return Err(plan_error(format!(
                    "land seq {l} is not after the last point's {}",
                    last.seq
                )));
            }
        }
        for r in &self.repricings {
            if !r.fits(self.points.len()) {
                return Err(plan_error(format!(
                    "a repricing at {:.1} s has {} legs from point {} of {}",
                    r.t_s,
                    r.legs.len(),
                    r.from_point,
                    self.points.len()
                )));
            }
        }
        if let Some(p) = &self.predicted {
            if p.legs.len() != self.points.len() {
                return Err(plan_error(format!(
                    "{} predicted legs for {} points",
                    p.legs.len(),
                    self.points.len()
                )));
            }
        }
        for b in &self.blocks {
            // The origin (the last point) is in no block.
            if b.first_point >= b.last_point || b.last_point + 1 >= self.points.len() {
                return Err(plan_error(format!(
                    "block {} has points {} to {} of {}",
                    b.name,
                    b.first_point,
                    b.last_point,
                    self.points.len()
                )));
            }
        }
        Ok(())
    }

    /// The latest repricing that covers point `k` (made before its leg began).
    fn repriced_at(&self, k: usize) -> Option<&Repricing> {
        self.repricings.iter().rev().find(|r| r.from_point <= k)
    }

    /// The prediction of leg `k` (and its settle) as last priced: a repricing's when one covers
    /// it, else the plan's.
    pub fn predicted_leg(&self, k: usize) -> Option<PredictedLeg> {
        match self.repriced_at(k) {
            Some(r) => r.legs.get(k - r.from_point).copied(),
            None => self.predicted.as_ref()?.legs.get(k).copied(),
        }
    }

    /// The predicted hover power at point `k` as last priced.
    pub fn predicted_hover_power_w(&self, k: usize) -> Option<f64> {
        match self.repriced_at(k) {
            Some(r) => Some(r.hover_power_w),
            None => Some(self.predicted.as_ref()?.hover_power_w),
        }
    }

    /// The predicted landing as last priced.
    pub fn predicted_landing_j(&self) -> Option<f64> {
        match self.repricings.last() {
            Some(r) => Some(r.landing_j),
            None => Some(self.predicted.as_ref()?.landing_j),
        }
    }

    /// The whole flight as last priced: the take-off, each leg, settle and hover, the landing.
    pub fn predicted_total_j(&self) -> Option<f64> {
        Some(self.predicted.as_ref()?.takeoff_j + self.predicted_rest_j(0)?)
    }

    /// What the stages from point `from` on (legs, settles, hovers, the landing) are priced at
    /// now.
    pub fn predicted_rest_j(&self, from: usize) -> Option<f64> {
        let mut rest = self.predicted_landing_j()?;
        for (k, point) in self.points.iter().enumerate().skip(from) {
            let leg = self.predicted_leg(k)?;
            rest += leg.energy_j
                + leg.settle_energy_j
                + point.hold_s * self.predicted_hover_power_w(k)?;
        }
        Some(rest)
    }

    /// The origin: home and the hover height above it.
    pub fn origin(&self) -> Origin {
        Origin {
            home: self.home,
            height_above_home_m: self.origin_height_m,
        }
    }

    /// A vehicle position in the mission frame. Its height above home is `alt_amsl_m` less the
    /// home altitude `home_alt_amsl_m` the autopilot reported (HOME_POSITION), else its
    /// `relative_alt_m`. The two
    /// agree on a healthy autopilot (relative_alt = alt - home alt, MAVLink common.xml), but PX4
    /// SITL's relative_alt jumps by 1-3 m in over half its GLOBAL_POSITION_INT in flight while
    /// alt follows LOCAL_POSITION_NED to 1 mm (one flight's tlog), and a metre of false height
    /// moves the 4 m arrival and the departure from hover.
    pub fn to_local(&self, p: &Position, home_alt_amsl_m: Option<f64>) -> Enu {
        let height_m = match home_alt_amsl_m {
            Some(home) => p.alt_amsl_m - home,
            None => p.relative_alt_m,
        };
        self.origin().to_enu(Geodetic {
            lat_deg: p.lat_deg,
            lon_deg: p.lon_deg,
            alt_m: self.home.alt_m + height_m,
        })
    }

    /// The leg a mission sequence number belongs to: a via point's is its leg's (the vehicle
    /// passes it on the way to the leg's end).
    pub fn target_of(&self, seq: u16) -> Target {
        if self.takeoff_seq.is_some_and(|t| seq <= t) {
            return Target::BeforeLegs;
        }
        if self.land_seq.is_some_and(|l| seq >= l) {
            return Target::Landing;
        }
        match self.points.iter().position(|p| p.seq >= seq) {
            Some(k) => Target::Leg(k),
            None => Target::Landing,
        }
    }

    /// The names of leg k's ends.
    pub fn leg_names(&self, k: usize) -> (String, String) {
        let from = match k {
            0 => ORIGIN_NAME.to_string(),
            _ => self
                .points
                .get(k - 1)
                .map_or_else(String::new, |p| p.name.clone()),
        };
        let to = self
            .points
            .get(k)
            .map_or_else(String::new, |p| p.name.clone());
        (from, to)
    }

    /// Writes plan.json.
    pub fn write_json(&self, path: &Path) -> Result<(), FlightLogError> {
        let text = serde_json::to_string_pretty(self).map_err(|e| FlightLogError::Json {
            file: path.display().to_string(),
            reason: e.to_string(),
        })?;
        super::write_synced(path, text.as_bytes())
    }

    /// Reads and validates plan.json.
    pub fn read_json(path: &Path) -> Result<FlightPlan, FlightLogError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| FlightLogError::Io {
            file: file.clone(),
            source,
        })?;
        let plan: FlightPlan = serde_json::from_str(&text).map_err(|e| FlightLogError::Json {
            file: file.clone(),
            reason: e.to_string(),
        })?;
        plan.validate().map_err(|e| FlightLogError::Json {
            file,
            reason: e.to_string(),
        })?;
        Ok(plan)
    }
}

fn seq_at(first: u16, k: usize) -> Result<u16, FlightLogError> {
    u16::try_from(usize::from(first) + k)
        .map_err(|_| plan_error("more mission items than MAVLink can number"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::Waypoint;

    pub(crate) fn mission() -> Mission {
        let wp = |name: &str, x: f64, y: f64, z: f64| Waypoint {
            name: name.into(),
            position: Enu {
                x_east_m: x,
                y_north_m: y,
                z_up_m: z,
            },
            hover_s: 5.0,
            ..Default::default()
        };
        Mission {
            name: "square".into(),
            origin: Origin {
                home: Geodetic {
                    lat_deg: 38.5362,
                    lon_deg: -121.7875,
                    alt_m: 16.0,
                },
                height_above_home_m: 20.0,
            },
            waypoints: vec![
                wp("A", 50.0, 0.0, 0.0),
                wp("B", 50.0, 50.0, 10.0),
                wp("C", 0.0, 50.0, -5.0),
            ],
            default_hover_s: 5.0,
            min_height_above_home_m: 2.0,
            source: None,
            start_actions: Vec::new(),
            pois: Vec::new(),
            fence: Default::default(),
            rally: Vec::new(),
            blocks: Vec::new(),
        }
    }

    fn plan_with_prediction() -> FlightPlan {
        let leg = PredictedLeg {
            energy_j: 10_000.0,
            duration_s: 12.0,
            settle_energy_j: 2_000.0,
            settle_duration_s: 2.5,
        };
        FlightPlan::for_mission(
            &mission(),
            &[0, 1, 2],
            0,
            Some(Predicted {
                takeoff_j: 30_000.0,
                landing_j: 20_000.0,
                legs: vec![leg; 4],
                hover_power_w: 800.0,
            }),
        )
        .expect("valid")
    }

    #[test]
    fn a_repricing_prices_its_points_and_the_landing_and_leaves_the_legs_before_it() {
        let mut plan = plan_with_prediction();
        let p = plan.predicted.clone().unwrap();
        let n = plan.points.len();
        let before = plan.predicted_total_j().unwrap();
        let leg = PredictedLeg {
            energy_j: 1_000.0,
            duration_s: 5.0,
            settle_energy_j: 100.0,
            settle_duration_s: 1.0,
        };
        plan.repricings.push(Repricing {
            t_s: 10.0,
            wind: crate::mission::wind::Wind::new(5.0, 90.0).unwrap(),
            from_point: 1,
            legs: vec![leg; n - 1],
            hover_power_w: 2.0 * p.hover_power_w,
            landing_j: 7.0,
            home_j: Vec::new(),
            rest_before_j: 0.0,
            rest_after_j: 0.0,
        });
        plan.validate().expect("fits");
        assert_eq!(plan.predicted_leg(0), Some(p.legs[0]));
        assert_eq!(plan.predicted_leg(1), Some(leg));
        assert_eq!(plan.predicted_hover_power_w(0), Some(p.hover_power_w));
        assert_eq!(plan.predicted_hover_power_w(1), Some(2.0 * p.hover_power_w));
        assert_eq!(plan.predicted_landing_j(), Some(7.0));
        let hover_after: f64 =
            plan.points[1..].iter().map(|x| x.hold_s).sum::<f64>() * 2.0 * p.hover_power_w;
        let rest = plan.predicted_rest_j(1).unwrap();
        assert!((rest - (7.0 + 1_100.0 * (n - 1) as f64 + hover_after)).abs() < 1e-9);
        assert!(plan.predicted_total_j().unwrap() != before);
        // One leg short of the points left is refused.
        plan.repricings[0].legs.pop();
        assert!(plan.validate().is_err());
    }

    #[test]
    fn the_layout_numbers_take_off_waypoints_origin_and_landing() {
        let plan = FlightPlan::for_mission(&mission(), &[2, 0, 1], 1, None).expect("valid");
        let names: Vec<&str> = plan.points.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["C", "A", "B", "origin"]);
        let seqs: Vec<u16> = plan.points.iter().map(|p| p.seq).collect();
        assert_eq!(seqs, [2, 3, 4, 5]);
        assert_eq!((plan.takeoff_seq, plan.land_seq), (Some(1), Some(6)));
        assert_eq!(plan.target_of(0), Target::BeforeLegs);
        assert_eq!(plan.target_of(1), Target::BeforeLegs);
        assert_eq!(plan.target_of(3), Target::Leg(1));
        assert_eq!(plan.target_of(5), Target::Leg(3));
        assert_eq!(plan.target_of(6), Target::Landing);
        assert_eq!(plan.leg_names(0), ("origin".into(), "C".into()));
        assert_eq!(plan.leg_names(3), ("B".into(), "origin".into()));
    }

    fn enu(x: f64, y: f64, z: f64) -> Enu {
        Enu {
            x_east_m: x,
            y_north_m: y,
            z_up_m: z,
        }
    }

    /// C, A, B, origin with two via points on the leg to A: take-off 0, C 1, via 2 and 3, A 4,
    /// B 5, origin 6, land 7.
    fn routed_plan() -> FlightPlan {
        FlightPlan::for_mission(&mission(), &[2, 0, 1], 0, None)
            .and_then(|p| p.renumbered(Some(0), &[1, 4, 5, 6], 7))
            .and_then(|p| {
                p.routed(
                    &[vec![], vec![enu(10.0, 40.0, 0.0), enu(30.0, 20.0, 0.0)]],
                    &[vec![], vec![2, 3]],
                )
            })
            .expect("valid")
    }

    #[test]
    fn a_via_points_item_belongs_to_its_leg_and_the_leg_runs_through_it() {
        let plan = routed_plan();
        assert_eq!(plan.target_of(1), Target::Leg(0));
        assert_eq!(plan.target_of(2), Target::Leg(1));
        assert_eq!(plan.target_of(3), Target::Leg(1));
        assert_eq!(plan.target_of(4), Target::Leg(1));
        assert_eq!(plan.target_of(5), Target::Leg(2));
        assert_eq!(plan.leg_names(1), ("C".into(), "A".into()));
        let c = plan.points[0].enu;
        let a = plan.points[1].enu;
        assert_eq!(
            plan.leg_path(1),
            [c, enu(10.0, 40.0, 0.0), enu(30.0, 20.0, 0.0), a]
        );
        assert_eq!(plan.leg_path(2), [a, plan.points[2].enu]);
        assert_eq!(plan.leg_path(0), [Enu::default(), c]);
    }

    #[test]
    fn via_points_survive_plan_json_and_a_plan_json_without_them_reads_as_straight_legs() {
        let plan = routed_plan();
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("plan.json");
        plan.write_json(&path).expect("written");
        let text = std::fs::read_to_string(&path).expect("read");
        assert_eq!(text.matches("\"via\"").count(), 1, "{text}");
        assert_eq!(FlightPlan::read_json(&path).expect("read"), plan);
        // A plan.json of straight legs (as written before via points were kept) has no such
        // key and reads as straight legs.
        let straight = FlightPlan::for_mission(&mission(), &[2, 0, 1], 0, None).expect("valid");
        straight.write_json(&path).expect("written");
        assert!(!std::fs::read_to_string(&path)
            .expect("read")
            .contains("via"));
        let back = FlightPlan::read_json(&path).expect("read");
        assert!(back.points.iter().all(|p| p.via.is_empty()));
        assert_eq!(back, straight);
    }

    #[test]
    fn a_via_point_out_of_its_legs_items_is_refused_naming_it() {
        let base = || {
            FlightPlan::for_mission(&mission(), &[2, 0, 1], 0, None)
                .and_then(|p| p.renumbered(Some(0), &[1, 4, 5, 6], 7))
                .expect("valid")
        };
        let err = base()
            .routed(&[vec![], vec![enu(1.0, 2.0, 0.0)]], &[vec![], vec![5]])
            .expect_err("after its leg's end");
        assert!(
            err.to_string()
                .contains("via point 1 of the leg to A has seq 5, not between seq 1 and seq 4"),
            "{err}"
        );
        let err = base()
            .routed(&[vec![], vec![enu(1.0, 2.0, 0.0)]], &[vec![], vec![]])
            .expect_err("no item");
        assert!(
            err.to_string()
                .contains("0 item numbers for the 1 via points of the leg to A"),
            "{err}"
        );
        let err = base()
            .routed(&[vec![], vec![enu(f64::NAN, 2.0, 0.0)]], &[vec![], vec![2]])
            .expect_err("not finite");
        assert!(err.to_string().contains("non-finite"), "{err}");
    }

    #[test]
    fn a_position_above_a_waypoint_maps_back_onto_it_in_the_mission_frame() {
        let m = mission();
        let plan = FlightPlan::for_mission(&m, &[0, 1, 2], 0, None).expect("valid");
        let b = m.waypoints[1].position;
        let g = m.origin.to_geodetic(b);
        let p = Position {
            time_boot_ms: 0,
            lat_deg: g.lat_deg,
            lon_deg: g.lon_deg,
            alt_amsl_m: g.alt_m + 3.0,
            relative_alt_m: g.alt_m - m.origin.home.alt_m,
            vn_m_s: 0.0,
            ve_m_s: 0.0,
            vd_m_s: 0.0,
        };
        let back = plan.to_local(&p, None);
        assert!((back.x_east_m - b.x_east_m).abs() < 1e-6, "{back:?}");
        assert!((back.y_north_m - b.y_north_m).abs() < 1e-6, "{back:?}");
        assert!((back.z_up_m - b.z_up_m).abs() < 1e-6, "{back:?}");
        // With the autopilot's home: the height is alt less home's altitude, whatever
        // relative_alt says (PX4 SITL's jumps by metres).
        let home = m.origin.home.alt_m + 3.0;
        let jumpy = Position {
            relative_alt_m: p.relative_alt_m + 2.5,
            ..p
        };
        let back = plan.to_local(&jumpy, Some(home));
        assert!((back.z_up_m - b.z_up_m).abs() < 1e-6, "{back:?}");
        assert!((plan.to_local(&jumpy, None).z_up_m - b.z_up_m - 2.5).abs() < 1e-6);
    }

    #[test]
    fn a_points_photos_survive_plan_json_and_a_plan_json_without_them_reads_as_none() {
        let mut plan = plan_with_prediction();
        plan.points[1].photos = 2;
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("plan.json");
        plan.write_json(&path).expect("written");
        let text = std::fs::read_to_string(&path).expect("read");
        assert_eq!(text.matches("\"photos\"").count(), 1, "{text}");
        assert_eq!(FlightPlan::read_json(&path).expect("read"), plan);
        // A plan.json written before photos were kept.
        plan.points[1].photos = 0;
        plan.write_json(&path).expect("written");
        assert!(!std::fs::read_to_string(&path)
            .expect("read")
            .contains("photos"));
        let back = FlightPlan::read_json(&path).expect("read");
        assert!(back.points.iter().all(|p| p.photos == 0));
    }

    #[test]
    fn a_plan_with_a_prediction_per_leg_survives_plan_json() {
        let plan = plan_with_prediction();
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("plan.json");
        plan.write_json(&path).expect("written");
        assert_eq!(FlightPlan::read_json(&path).expect("read"), plan);
    }

    #[test]
    fn a_prediction_that_does_not_match_the_legs_is_refused_naming_the_counts() {
        let err = FlightPlan::for_mission(
            &mission(),
            &[0, 1, 2],
            0,
            Some(Predicted {
                takeoff_j: 0.0,
                landing_j: 0.0,
                legs: vec![],
                hover_power_w: 0.0,
            }),
        )
        .expect_err("invalid");
        assert!(
            err.to_string().contains("0 predicted legs for 4 points"),
            "{err}"
        );
    }
}
