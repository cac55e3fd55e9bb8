//! Cutting a flight into contiguous segments against the plan that was flown, so the parts add
//! up to the whole flight's energy (the layout flown is `flight_plan`'s):
//! - `takeoff`: arming -> the vehicle leaves the origin hover for the first leg;
//! - `leg` k from P to Q = points[k]: leaves hover at P (MISSION_CURRENT names Q or a later
//!   item; departure from P as fallback) -> first within the arrival radius (4 m, 3D) of Q, the
//!   crossing time interpolated between position samples: the paper's operation energy. A leg
//!   round a fence zone is one leg through its via points (`FlightPlan`'s `via`): their
//!   MISSION_CURRENT and MISSION_ITEM_REACHED fall inside it, and it ends at Q;
//! - `settle` at Q: within the radius -> settled: stopped inside the radius (3D speed below
//!   `stop_speed_m_s` for `stop_hold_s`, the settle ending where the stop began), or
//!   MISSION_ITEM_REACHED of Q if that comes first. Both PX4 (`mission_block.cpp`: the item is
//!   "reached" once its hold time is over) and ArduCopter (`verify_nav_wp`: "Reached command"
//!   after the loiter time) report an item reached when they leave it, not on arrival, and PX4
//!   never reports the last waypoint before landing; so the stop is what ends a settle, as the
//!   model's settle ends in a settled hover;
//! - `hover` at Q: reached -> leaves for the next leg;
//! - `landing`: leaves the origin hover point after the return leg -> disarmed (or on the ground
//!   when the log ends before the disarm).
//!
//! Departure from a hover point by position: the last exit from `departure_m` around it before
//! the vehicle is `arrival_radius_m` away (so GPS wander inside that does not count); a
//! MISSION_CURRENT arriving up to `mission_current_lag_s` after such an exit (PX4 resends it once
//! a second, so a lost change arrives late) starts the leg at the exit. MISSION_ITEM_REACHED of
//! the point being left is the departure itself (both autopilots send it as they move on); a
//! MISSION_CURRENT (up to a second late on PX4) finding the vehicle already under way towards
//! the next point dates the departure back to where that motion began.
//!
//! Incremental: feed stamped readings one by one ([`Segmenter::push`]); the completed segments
//! and the one in progress can be asked for at any time, so the same code serves the live view
//! and the replay. The first disarm ends the flight; a later arming is not segmented. A log that
//! begins in flight (armed at its first heartbeat) starts at the leg MISSION_CURRENT names, that
//! first part marked incomplete.

use super::energy::{EnergyConfig, Measurement, PowerSeries};
use super::flight_plan::{FlightPlan, Target};
pub use super::part::{Segment, SegmentKind, StartState};
use super::photos::PhotoLog;
use super::samples::{BatteryFeed, FeedConfig};
use super::telemetry::{FlightMode, LandedState, Reading, Stamped, VehicleState};
use super::watch::{GuardNote, Watch};
use super::wind::WindTrack;
use super::FlightLogError;
use crate::mission::wind::Wind;
use crate::mission::Enu;

/// Thresholds of segmentation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentConfig {
    /// A leg ends when the vehicle first comes this close (3D) to its end point (paper: 4 m).
    pub arrival_radius_m: f64,
    /// Leaving a hover point by position: exiting this radius around it.
    pub departure_m: f64,
    /// Stopped: 3D speed below this for `stop_hold_s` (an overshoot's turning point is not a
    /// stop).
    pub stop_speed_m_s: f64,
    pub stop_hold_s: f64,
    /// How late a MISSION_CURRENT may be after a departure seen in the positions.
    pub mission_current_lag_s: f64,
    pub energy: EnergyConfig,
    pub feed: FeedConfig,
}

impl Default for SegmentConfig {
    fn default() -> Self {
        SegmentConfig {
            arrival_radius_m: 4.0,
            departure_m: 2.0,
            stop_speed_m_s: 0.3,
            stop_hold_s: 1.0,
            mission_current_lag_s: 1.5,
            energy: EnergyConfig::default(),
            feed: FeedConfig::default(),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    Idle,
    Active(SegmentKind),
    Done,
}

/// Segments a flight as its readings arrive.
#[derive(Debug, Clone)]
pub struct Segmenter {
    plan: FlightPlan,
    cfg: SegmentConfig,
    feed: BatteryFeed,
    series: PowerSeries,
    state: VehicleState,
    phase: Phase,
    open_start_s: f64,
    segments: Vec<Segment>,
    flight_start_s: Option<f64>,
    flight_end_s: Option<f64>,
    now_s: f64,
    /// The latest positions (the last one last), for when and where a departure began.
    recent: std::collections::VecDeque<Sample>,
    /// The open leg's vehicle at its start.
    open_start_state: Option<StartState>,
    /// Departure tracking around the current hover point.
    inside_departure: bool,
    exit_s: Option<f64>,
    /// Start of the current stop inside the radius during a settle.
    stop_s: Option<f64>,
    /// On the ground during landing.
    landed_s: Option<f64>,
    /// A disarmed HEARTBEAT was seen before arming (else the log began in flight).
    seen_disarmed: bool,
    /// The open segment began before the log did.
    open_partial: bool,
    /// Every home the autopilot reported: (when it was set, autopilot boot s, if said; its
    /// altitude above mean sea level), in arrival order.
    homes: Vec<(Option<f64>, f64)>,
    /// The altitude positions' heights are measured from: the first home reported.
    frame_home_m: Option<f64>,
    /// Flight time less autopilot boot time, from the latest position.
    boot_offset_s: Option<f64>,
    /// Per hover point (the take-off's origin first, then the plan's points): when the
    /// autopilot made it its target (boot s, if known) and the home it was set from.
    point_homes: Vec<Option<(Option<f64>, f64)>>,
    /// The energy guard, when the plan carries its setup.
    watch: Option<Watch>,
    /// The completed parts with their energy as measured when they completed (the guard's).
    measured: Vec<(Segment, Option<f64>)>,
    /// Notes the guard made that the caller has not taken yet.
    fresh_notes: Vec<GuardNote>,
    /// The vehicle's wind estimate, and how many of the plan's repricings the guard has.
    wind: WindTrack,
    repricings_applied: usize,
    /// The photos the autopilot reported, where they were taken.
    photos: PhotoLog,
    /// The fence breaches the autopilot's FENCE_STATUS told.
    breaches: super::breach::Breaches,
}

/// One position of the vehicle in the mission frame.
#[derive(Debug, Clone, Copy)]
struct Sample {
    t_s: f64,
    at: Enu,
    /// East, north, up (m/s).
    velocity: [f64; 3],
}

impl Sample {
    fn speed_m_s(&self) -> f64 {
        dot(self.velocity, self.velocity).sqrt()
    }
}

/// How many recent positions are kept.
const RECENT_SAMPLES: usize = 64;

/// A leg moving less than this horizontally leaves its hover point vertically.
const VERTICAL_DEPARTURE_M: f64 = 1.0;

/// How a departure reached the recorder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Announcement {
    /// MISSION_ITEM_REACHED of the item being left: PX4 (`mavlink_mission.cpp`, on the mission
    /// result's update) and ArduCopter (`verify_nav_wp`) send it the moment they move on, so
    /// it is the departure itself. A vehicle already moving then is adjusting its hover, not
    /// leaving (PX4 SITL's rose at 0.6 m/s at one point as its setpoint rose 0.35 m): on PX4
    /// SITL, dating such a departure back by the motion started legs up to 0.6 s before PX4 set
    /// the next target.
    Prompt,
    /// MISSION_CURRENT (PX4 streams it once a second: it arrives up to 1 s after the change),
    /// a mode or a landed state: the motion may have begun before.
    Streamed,
}

/// How much later than a target's start a home may say it was set and still count (the boot
/// clock's milliseconds against a start interpolated between samples).
const HOME_SET_SLACK_S: f64 = 0.05;

fn sub(a: Enu, b: Enu) -> [f64; 3] {
    [
        a.x_east_m - b.x_east_m,
        a.y_north_m - b.y_north_m,
        a.z_up_m - b.z_up_m,
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn distance(a: Enu, b: Enu) -> f64 {
    dot(sub(a, b), sub(a, b)).sqrt()
}

/// Where on the straight line from `a` to `b` (0..1) the distance to `center` crosses `r`:
/// the first crossing going in (`entering`), the last going out.
fn crossing(a: Enu, b: Enu, center: Enu, r: f64, entering: bool) -> f64 {
    let d0 = sub(a, center);
    let v = sub(b, a);
    let vv = dot(v, v);
    if vv <= 0.0 {
        return 1.0;
    }
    let half_b = dot(d0, v);
    let c = dot(d0, d0) - r * r;
    let disc = (half_b * half_b - vv * c).max(0.0).sqrt();
    let s = if entering {
        (-half_b - disc) / vv
    } else {
        (-half_b + disc) / vv
    };
    s.clamp(0.0, 1.0)
}

impl Segmenter {
    /// A segmenter for a flight of `plan`.
    pub fn new(plan: FlightPlan, cfg: SegmentConfig) -> Result<Segmenter, FlightLogError> {
        plan.validate()?;
        let plan_points = plan.points.len();
        let watch = Watch::new(&plan);
        Ok(Segmenter {
            watch,
            measured: Vec::new(),
            fresh_notes: Vec::new(),
            wind: WindTrack::new(),
            repricings_applied: 0,
            photos: PhotoLog::new(),
            breaches: super::breach::Breaches::default(),
            plan,
            feed: BatteryFeed::new(cfg.feed),
            series: PowerSeries::new(cfg.energy),
            cfg,
            state: VehicleState::default(),
            phase: Phase::Idle,
            open_start_s: 0.0,
            segments: Vec::new(),
            flight_start_s: None,
            flight_end_s: None,
            now_s: 0.0,
            recent: std::collections::VecDeque::new(),
            open_start_state: None,
            inside_departure: false,
            exit_s: None,
            stop_s: None,
            landed_s: None,
            seen_disarmed: false,
            open_partial: false,
            homes: Vec::new(),
            frame_home_m: None,
            boot_offset_s: None,
            point_homes: vec![None; plan_points + 1],
        })
    }

    /// The home the autopilot held at `boot_s`: the last reported that says it was set by then
    /// (or says nothing of when), else the latest.
    fn home_at(&self, boot_s: Option<f64>) -> Option<f64> {
        let held = |set: &Option<f64>| match (set, boot_s) {
            (Some(set), Some(b)) => *set <= b + HOME_SET_SLACK_S,
            _ => true,
        };
        self.homes
            .iter()
            .rev()
            .find(|(set, _)| held(set))
            .or(self.homes.last())
            .map(|&(_, alt)| alt)
    }

    /// Hover point `i` (0 the take-off's origin, k + 1 the plan's point k) became the
    /// autopilot's target at flight time `t_s`: it sent it there from the home it held then.
    /// PX4 (navigator `get_absolute_altitude_for_item`) adds the home altitude to a relative
    /// item's altitude when it sets the item, and PX4 SITL's home moves by up to 2.5 m in flight
    /// (HOME_POSITION every 2 s or so), so a point sits where its own home put it.
    fn target_set(&mut self, i: usize, t_s: f64) {
        let boot_s = self.boot_offset_s.map(|o| t_s - o);
        self.set_point_home(i, boot_s);
    }

    /// Hover point `i` was set at `boot_s`: the home it was set from, as far as known now.
    fn set_point_home(&mut self, i: usize, boot_s: Option<f64>) {
        let home = self.home_at(boot_s);
        if let Some(slot) = self.point_homes.get_mut(i) {
            *slot = home.map(|h| (boot_s, h));
        }
    }

    /// A home arrived: the frame's first, and the current target's if it was set by then.
    fn on_home(&mut self, alt_amsl_m: f64, set_boot_s: Option<f64>) {
        self.homes.push((set_boot_s, alt_amsl_m));
        self.frame_home_m.get_or_insert(alt_amsl_m);
        if let Some(i) = self.point_index() {
            match self.point_homes.get(i) {
                Some(Some((boot_s, _))) => self.set_point_home(i, *boot_s),
                _ => self.target_set(i, self.now_s),
            }
        }
    }

    /// Hover point `i` in the frame positions are measured in.
    fn hover_point_at(&self, i: usize) -> Option<Enu> {
        let base = match i {
            0 => Enu::default(),
            _ => self.plan.points.get(i - 1)?.enu,
        };
        let lift = match (self.point_homes.get(i), self.frame_home_m) {
            (Some(Some((_, home))), Some(frame)) => home - frame,
            _ => 0.0,
        };
        Some(Enu {
            z_up_m: base.z_up_m + lift,
            ..base
        })
    }

    /// Segments a whole recorded flight (replay).
    pub fn run<'a>(
        plan: FlightPlan,
        cfg: SegmentConfig,
        stamped: impl IntoIterator<Item = &'a Stamped>,
    ) -> Result<Segmenter, FlightLogError> {
        let mut s = Segmenter::new(plan, cfg)?;
        for reading in stamped {
            s.push(reading);
        }
        s.finish();
        Ok(s)
    }

    pub fn plan(&self) -> &FlightPlan {
        &self.plan
    }

    pub fn config(&self) -> &SegmentConfig {
        &self.cfg
    }

    /// The primary battery's samples so far.
    pub fn series(&self) -> &PowerSeries {
        &self.series
    }

    /// The photos the autopilot reported so far.
    pub fn photos(&self) -> &PhotoLog {
        &self.photos
    }

    /// The fence breaches so far.
    pub fn breaches(&self) -> &[super::breach::Breach] {
        self.breaches.list()
    }

    /// The vehicle's latest state.
    pub fn state(&self) -> &VehicleState {
        &self.state
    }

    /// Vehicle time of the latest reading.
    pub fn now_s(&self) -> f64 {
        self.now_s
    }

    /// The segments that have ended.
    pub fn completed(&self) -> &[Segment] {
        &self.segments
    }

    /// The segment the vehicle is in, up to now.
    pub fn in_progress(&self) -> Option<Segment> {
        match self.phase {
            Phase::Active(kind) => Some(Segment {
                kind,
                start_s: self.open_start_s,
                end_s: self.now_s.max(self.open_start_s),
                complete: false,
                missed_radius: false,
                start_state: self.open_start_state,
            }),
            Phase::Idle | Phase::Done => None,
        }
    }

    /// Completed segments and the one in progress.
    pub fn segments(&self) -> Vec<Segment> {
        let mut all = self.segments.clone();
        all.extend(self.in_progress());
        all
    }

    /// Arming to disarming (to now while flying); None before arming.
    pub fn flight_span(&self) -> Option<(f64, f64)> {
        let start = self.flight_start_s?;
        Some((start, self.flight_end_s.unwrap_or(self.now_s.max(start))))
    }

    /// Whether the flight has ended (disarmed, or `finish` was called).
    pub fn is_finished(&self) -> bool {
        self.phase == Phase::Done
    }

    /// Marks vehicle time `from_s` to `to_s` as lost from the log (a corrupt span of a replayed
    /// .tlog): the parts it touches are flagged `log_gap` and count it uncovered.
    pub fn log_gap(&mut self, from_s: f64, to_s: f64) {
        self.series.lose(from_s, to_s);
    }

    /// The energy of a segment (or any stretch) from the samples so far.
    pub fn measure(&self, segment: &Segment) -> Measurement {
        self.series.measure(segment.start_s, segment.end_s)
    }

    fn close(&mut self, end_s: f64, complete: bool, missed_radius: bool) {
        if let Phase::Active(kind) = self.phase {
            let end_s = end_s.max(self.open_start_s);
            self.segments.push(Segment {
                kind,
                start_s: self.open_start_s,
                end_s,
                complete: complete && !self.open_partial,
                missed_radius,
                start_state: self.open_start_state.take(),
            });
            self.open_start_s = end_s;
            self.open_partial = false;
        }
    }

    fn open(&mut self, kind: SegmentKind, start_s: f64) {
        match kind {
            SegmentKind::Takeoff => self.target_set(0, start_s),
            SegmentKind::Leg(k) => self.target_set(k + 1, start_s),
            _ => {}
        }
        self.open_start_state = match kind {
            SegmentKind::Leg(k) => self.vehicle_at(start_s, k),
            _ => None,
        };
        self.phase = Phase::Active(kind);
        self.open_start_s = start_s;
        self.stop_s = None;
        self.exit_s = None;
        self.inside_departure = match (self.hover_point(), self.recent.back()) {
            (Some(center), Some(last)) => distance(last.at, center) <= self.cfg.departure_m,
            _ => false,
        };
    }

    fn end_flight(&mut self, t_s: f64, complete: bool) {
        self.close(t_s, complete, false);
        self.flight_end_s = Some(t_s.max(self.flight_start_s.unwrap_or(t_s)));
        self.phase = Phase::Done;
    }

    /// Ends the flight where the log ends: a landing on the ground by then is complete, any other
    /// segment is cut off (`incomplete`).
    pub fn finish(&mut self) {
        match self.phase {
            Phase::Active(SegmentKind::Landing) if self.landed_s.is_some() => {
                let t = self.landed_s.unwrap_or(self.now_s);
                self.end_flight(t, true);
            }
            Phase::Active(_) => self.end_flight(self.now_s, false),
            Phase::Idle | Phase::Done => {}
        }
    }

    fn last_index(&self) -> usize {
        self.plan.points.len().saturating_sub(1)
    }

    /// The point the current phase is about (`hover_point_at`'s index): the take-off's origin,
    /// a leg's end, the point settled or hovered at.
    fn point_index(&self) -> Option<usize> {
        match self.phase {
            Phase::Active(SegmentKind::Takeoff) => Some(0),
            Phase::Active(SegmentKind::Leg(k) | SegmentKind::Settle(k) | SegmentKind::Hover(k)) => {
                Some(k + 1)
            }
            _ => None,
        }
    }

    /// The index of the hover point the vehicle leaves from in the current phase.
    fn hover_index(&self) -> Option<usize> {
        match self.phase {
            Phase::Active(SegmentKind::Leg(_)) => None,
            _ => self.point_index(),
        }
    }

    /// The hover point the vehicle leaves from in the current phase.
    fn hover_point(&self) -> Option<Enu> {
        self.hover_point_at(self.hover_index()?)
    }

    /// The last position sampled by `t_s`.
    fn sample_by(&self, t_s: f64) -> Option<&Sample> {
        self.recent.iter().rev().find(|s| s.t_s <= t_s + 1e-9)
    }

    /// The recent positions' (time, speed).
    fn speeds(&self) -> impl DoubleEndedIterator<Item = (f64, f64)> + '_ {
        self.recent.iter().map(|s| (s.t_s, s.speed_m_s()))
    }

    /// The vehicle at `t_s` (the last position sampled by then) against hover point `i`, the
    /// one a leg leaves.
    fn vehicle_at(&self, t_s: f64, i: usize) -> Option<StartState> {
        let sample = self.sample_by(t_s)?;
        Some(StartState {
            offset_m: distance(sample.at, self.hover_point_at(i)?),
            speed_m_s: sample.speed_m_s(),
        })
    }

    /// Velocity `v`'s component along the way out of the current hover point: towards the next
    /// point (or the next leg's first via point) horizontally (a leg that is mostly horizontal starts horizontally), else vertically
    /// (straight up or down to it, or down to land after the last point).
    fn speed_towards_next_m_s(&self, v: [f64; 3]) -> f64 {
        let Some(i) = self.hover_index() else {
            return f64::INFINITY;
        };
        let Some(from) = self.hover_point_at(i) else {
            return f64::INFINITY;
        };
        // A leg round a fence zone heads for its first via point.
        let first_via = (self.plan.points.get(i))
            .and_then(|p| p.via.first())
            .map(|v| v.enu);
        let d = match first_via.or_else(|| self.hover_point_at(i + 1)) {
            Some(to) => sub(to, from),
            // After the last point: down to land.
            None => [0.0, 0.0, -1.0],
        };
        let horizontal = d[0].hypot(d[1]);
        if horizontal >= VERTICAL_DEPARTURE_M {
            (v[0] * d[0] + v[1] * d[1]) / horizontal
        } else if d[2] != 0.0 {
            v[2] * d[2].signum()
        } else {
            f64::INFINITY
        }
    }

    fn next_after(&self, k: Option<usize>) -> SegmentKind {
        let next = k.map_or(0, |k| k + 1);
        if next < self.plan.points.len() {
            SegmentKind::Leg(next)
        } else {
            SegmentKind::Landing
        }
    }

    /// Leaves the current hover (take-off, settle or hover) at `t_s` for the next segment.
    fn depart(&mut self, t_s: f64) {
        let t_s = t_s.max(self.open_start_s);
        let next = match self.phase {
            Phase::Active(SegmentKind::Takeoff) => {
                self.close(t_s, true, false);
                self.next_after(None)
            }
            Phase::Active(SegmentKind::Settle(k)) => {
                let settled = self.stop_s.filter(|&s| s <= t_s).unwrap_or(t_s);
                self.close(settled, true, false);
                self.phase = Phase::Active(SegmentKind::Hover(k));
                self.close(t_s, true, false);
                self.next_after(Some(k))
            }
            Phase::Active(SegmentKind::Hover(k)) => {
                self.close(t_s, true, false);
                self.next_after(Some(k))
            }
            _ => return,
        };
        self.open(next, t_s);
    }

    /// The autopilot moved past the leg's end before the vehicle came within the radius.
    fn leg_cut_short(&mut self, k: usize, t_s: f64, reached: bool) {
        self.close(t_s, true, true);
        self.phase = Phase::Active(SegmentKind::Settle(k));
        self.close(t_s, true, false);
        self.open(SegmentKind::Hover(k), t_s);
        if !reached {
            self.depart(t_s);
        }
    }

    /// When a departure the autopilot announced at `t_s` really began: at the exit from the
    /// hover point seen in the positions when that came first (the announcement was late: a
    /// repeat after the change was lost); else, for an announcement that may be late
    /// (`Announcement::Streamed`) when the vehicle is already under way at `t_s` (faster than
    /// `stop_speed_m_s`), where its motion began (a late announcement before the exit); else
    /// `t_s`.
    fn departure_time(&self, t_s: f64, announcement: Announcement) -> f64 {
        let lag = self.cfg.mission_current_lag_s;
        if let Some(e) = self.exit_s {
            if !self.inside_departure && e <= t_s && t_s - e <= lag {
                return e;
            }
        }
        if announcement == Announcement::Prompt {
            return t_s;
        }
        let rest = self.rest_speed_m_s(t_s);
        // Moving before `t_s`: two moving samples by then, or one taken before it (a sample at
        // the announcement's own time says nothing about when the motion began).
        let run: Vec<f64> = self
            .speeds()
            .rev()
            .filter(|&(t, _)| t <= t_s + 1e-9)
            .take_while(|&(_, v)| v > rest)
            .map(|(t, _)| t)
            .collect();
        let moving = run.len() >= 2 || run.first().is_some_and(|&t| t < t_s - 1e-3);
        // Late only if the vehicle is clearly under way by then, towards where it is going:
        // one still creeping about its hover point (PX4 SITL's SIH holds at 0.1-0.2 m/s) or
        // rising or sinking there left when it was told to.
        let under_way = self.sample_by(t_s).is_some_and(|s| {
            s.speed_m_s() > self.cfg.stop_speed_m_s
                && self.speed_towards_next_m_s(s.velocity) > self.cfg.stop_speed_m_s
        });
        if moving && under_way {
            let start = self.motion_start(t_s, rest);
            if start < t_s && t_s - start <= lag {
                return start;
            }
        }
        t_s
    }

    /// The speed below which the vehicle counts as hovering: what it showed while hovering
    /// here before (GPS velocity noise on a real vehicle), at least 0.05 m/s.
    fn rest_speed_m_s(&self, t_s: f64) -> f64 {
        let noise = self
            .speeds()
            .filter(|&(t, _)| t >= self.open_start_s && t < t_s - self.cfg.mission_current_lag_s)
            .map(|(_, v)| v)
            .fold(0.0, f64::max);
        (1.5 * noise).max(0.05)
    }

    fn on_target(&mut self, t_s: f64, target: Target) {
        match self.phase {
            Phase::Active(SegmentKind::Takeoff) if target == Target::Leg(0) => {
                let t = self.departure_time(t_s, Announcement::Streamed);
                self.depart(t);
            }
            // The log began in flight (armed at the first heartbeat), past the first leg: what
            // was flying when it began is cut off at its start.
            Phase::Active(SegmentKind::Takeoff)
                if target > Target::Leg(0) && !self.seen_disarmed =>
            {
                self.close(t_s, false, false);
                let kind = match target {
                    Target::Leg(k) => SegmentKind::Leg(k),
                    _ => SegmentKind::Landing,
                };
                self.open(kind, t_s);
                self.open_partial = true;
            }
            Phase::Active(SegmentKind::Leg(k)) if target > Target::Leg(k) => {
                self.leg_cut_short(k, t_s, false);
            }
            Phase::Active(SegmentKind::Settle(k) | SegmentKind::Hover(k))
                if target > Target::Leg(k) =>
            {
                let t = self.departure_time(t_s, Announcement::Streamed);
                self.depart(t);
            }
            _ => {}
        }
    }

    /// The vehicle is heading down (landing mode or state) while at the last point.
    fn on_landing(&mut self, t_s: f64) {
        match self.phase {
            Phase::Active(SegmentKind::Settle(k) | SegmentKind::Hover(k))
                if k == self.last_index() =>
            {
                let t = self.departure_time(t_s, Announcement::Streamed);
                self.depart(t);
            }
            // Landing or RTL before the plan is done: the flight is cut short.
            Phase::Active(kind) if kind != SegmentKind::Landing => {
                self.close(t_s, false, false);
                self.open(SegmentKind::Landing, t_s);
            }
            _ => {}
        }
    }

    fn on_position(&mut self, sample: Sample) {
        let (t_s, p, speed_m_s) = (sample.t_s, sample.at, sample.speed_m_s());
        let previous = self.recent.back().map(|s| (s.t_s, s.at));
        self.recent.push_back(sample);
        while self.recent.len() > RECENT_SAMPLES {
            self.recent.pop_front();
        }
        let r = self.cfg.arrival_radius_m;
        match self.phase {
            Phase::Active(SegmentKind::Leg(k)) => {
                let Some(q) = self.hover_point_at(k + 1) else {
                    return;
                };
                if distance(p, q) > r {
                    return;
                }
                let t = match previous {
                    Some((t0, p0)) if distance(p0, q) > r => {
                        t0 + crossing(p0, p, q, r, true) * (t_s - t0)
                    }
                    _ => t_s,
                };
                self.close(t, true, false);
                self.open(SegmentKind::Settle(k), t.max(self.open_start_s));
                self.settle_step(t_s, p, speed_m_s, k, previous);
            }
            Phase::Active(SegmentKind::Settle(k)) => {
                self.settle_step(t_s, p, speed_m_s, k, previous);
            }
            Phase::Active(SegmentKind::Takeoff | SegmentKind::Hover(_)) => {
                self.on_position_in_hover(t_s, p, previous);
            }
            _ => {}
        }
    }

    /// A position during a settle: a stop long enough ends it (where the stop began).
    fn settle_step(
        &mut self,
        t_s: f64,
        p: Enu,
        speed_m_s: f64,
        k: usize,
        previous: Option<(f64, Enu)>,
    ) {
        let inside = self
            .hover_point_at(k + 1)
            .is_some_and(|x| distance(p, x) <= self.cfg.arrival_radius_m);
        if inside && speed_m_s < self.cfg.stop_speed_m_s {
            let start = *self.stop_s.get_or_insert(t_s);
            if t_s - start >= self.cfg.stop_hold_s {
                self.close(start, true, false);
                self.open(SegmentKind::Hover(k), start);
            }
        } else {
            self.stop_s = None;
        }
        self.on_position_in_hover(t_s, p, previous);
    }

    /// When the motion that left the hover point by `exit_s` began: speed grows from rest as
    /// (t - t0)^2 under a jerk-limited start (PX4's S-curve, the quintic), so sqrt(speed) is
    /// linear in time; extrapolated back from the first two moving samples, and bounded by the
    /// last sample at rest before them. Without such samples, the exit itself.
    fn motion_start(&self, exit_s: f64, rest_m_s: f64) -> f64 {
        let before: Vec<(f64, f64)> = self.speeds().filter(|&(t, _)| t <= exit_s + 1e-9).collect();
        // The last sample at rest, and the moving samples after it.
        let rest = before.iter().rposition(|&(_, v)| v <= rest_m_s);
        let moving: Vec<(f64, f64)> = match rest {
            Some(i) => before[i + 1..].to_vec(),
            None => before.clone(),
        };
        let lower = rest.map(|i| before[i].0);
        let estimate = match moving.as_slice() {
            [(t1, v1), (t2, v2), ..] if v2 > v1 && t2 > t1 => {
                let (a, b) = (v1.sqrt(), v2.sqrt());
                Some(t1 - a * (t2 - t1) / (b - a))
            }
            [(t1, _), ..] => Some(lower.map_or(*t1, |l| 0.5 * (l + t1))),
            [] => lower,
        };
        let upper = moving.first().map_or(exit_s, |m| m.0).min(exit_s);
        match (estimate, lower) {
            (Some(e), Some(l)) => e.clamp(l, upper),
            (Some(e), None) => e.min(upper),
            (None, _) => exit_s,
        }
    }

    /// Departure by position from the current hover point.
    fn on_position_in_hover(&mut self, t_s: f64, p: Enu, previous: Option<(f64, Enu)>) {
        let Some(center) = self.hover_point() else {
            return;
        };
        let d = distance(p, center);
        if d <= self.cfg.departure_m {
            self.inside_departure = true;
            self.exit_s = None;
            return;
        }
        if self.inside_departure {
            self.inside_departure = false;
            let exit = match previous {
                Some((t0, p0)) => {
                    t0 + crossing(p0, p, center, self.cfg.departure_m, false) * (t_s - t0)
                }
                None => t_s,
            };
            let rest = self.rest_speed_m_s(exit);
            self.exit_s = Some(self.motion_start(exit, rest));
        }
        if d > self.cfg.arrival_radius_m {
            if let Some(exit) = self.exit_s {
                self.depart(exit);
            }
        }
    }

    /// The energy guard, when the plan is guarded.
    pub fn watch(&self) -> Option<&Watch> {
        self.watch.as_ref()
    }

    /// The guard's notes made since the last call.
    pub fn take_guard_notes(&mut self) -> Vec<GuardNote> {
        std::mem::take(&mut self.fresh_notes)
    }

    /// Lets the guard look again at the flight so far.
    fn guard(&mut self) {
        let (Some(watch), Some(start_s)) = (self.watch.as_mut(), self.flight_start_s) else {
            return;
        };
        if self.flight_end_s.is_some() {
            return;
        }
        while self.measured.len() < self.segments.len() {
            let segment = self.segments[self.measured.len()];
            let energy = self.series.measure(segment.start_s, segment.end_s).energy_j;
            self.measured.push((segment, energy));
        }
        let in_progress = match self.phase {
            Phase::Active(kind) => Some((kind, self.open_start_s)),
            _ => None,
        };
        let notes = watch.update(
            self.now_s,
            start_s,
            &self.series,
            &self.measured,
            in_progress,
        );
        self.fresh_notes.extend(notes);
    }

    /// Takes in one stamped reading (in time order).
    pub fn push(&mut self, stamped: &Stamped) {
        self.push_reading(stamped);
        self.guard();
        // A replay: the plan's repricings reach the guard when the live one's did, after the
        // reading they were made on.
        while let Some(r) = self.plan.repricings.get(self.repricings_applied) {
            if r.t_s > self.now_s {
                break;
            }
            if let Some(watch) = self.watch.as_mut() {
                watch.reprice(r);
            }
            self.repricings_applied += 1;
        }
    }

    /// The wind the rest of the flight is priced in now: the latest repricing's, else the
    /// plan's (still air when it has none).
    pub fn priced_wind(&self) -> Wind {
        match self.plan.repricings.last() {
            Some(r) => r.wind,
            None => self.plan.wind.unwrap_or(Wind::CALM),
        }
    }

    /// When the vehicle's wind estimate has moved far enough from [`Self::priced_wind`] in
    /// flight (`flightlog::wind`): the estimate and the first point whose leg has not begun,
    /// for the caller to price the rest again in it ([`Self::reprice`]). Taken: the next one
    /// comes after `wind::MIN_APART_S` at the earliest.
    pub fn take_reprice_due(&mut self) -> Option<(Wind, usize)> {
        if self.flight_start_s.is_none() || self.flight_end_s.is_some() {
            return None;
        }
        let from_point = match self.phase {
            Phase::Active(SegmentKind::Takeoff) => 0,
            Phase::Active(SegmentKind::Leg(k) | SegmentKind::Settle(k) | SegmentKind::Hover(k)) => {
                k + 1
            }
            Phase::Active(SegmentKind::Landing) | Phase::Idle | Phase::Done => return None,
        };
        if from_point >= self.plan.points.len() {
            return None;
        }
        let priced = self.priced_wind();
        let wind = self.wind.take_due(self.now_s, priced)?;
        Some((wind, from_point))
    }

    /// The rest of the flight priced again (made live by the caller on
    /// [`Self::take_reprice_due`]): the parts from its point on are measured against it, and
    /// the guard sees it from now. Refused (false) when it does not fit the plan.
    pub fn reprice(&mut self, r: super::flight_plan::Repricing) -> bool {
        if !r.fits(self.plan.points.len()) || self.plan.predicted.is_none() {
            return false;
        }
        if let Some(watch) = self.watch.as_mut() {
            watch.reprice(&r);
        }
        self.plan.repricings.push(r);
        self.repricings_applied = self.plan.repricings.len();
        true
    }

    fn push_reading(&mut self, stamped: &Stamped) {
        let t_s = stamped.t_s.max(self.now_s);
        self.now_s = t_s;
        self.state.update(&stamped.reading);
        match &stamped.reading {
            Reading::Battery(b) => {
                if let Some(sample) = self.feed.push(t_s, stamped.wall_us, b) {
                    self.series.push(sample);
                }
            }
            Reading::Heartbeat { armed, mode } => {
                if !*armed && self.phase == Phase::Idle {
                    self.seen_disarmed = true;
                }
                if *armed && self.phase == Phase::Idle {
                    self.flight_start_s = Some(t_s);
                    self.open(SegmentKind::Takeoff, t_s);
                } else if !*armed && matches!(self.phase, Phase::Active(_)) {
                    let landed = self.phase == Phase::Active(SegmentKind::Landing);
                    self.end_flight(t_s, landed);
                } else if matches!(mode, FlightMode::Land | FlightMode::Rtl) {
                    self.on_landing(t_s);
                }
            }
            Reading::MissionCurrent { seq, .. } => {
                let target = self.plan.target_of(*seq);
                self.on_target(t_s, target);
            }
            // PX4 (mission_block.cpp) and ArduCopter (verify_nav_wp) report an item reached
            // when they leave it, after its hold: for the item being hovered at (or the
            // take-off) it is the departure, sent at the same instant as MISSION_CURRENT moves
            // on, so either one arriving marks it.
            Reading::ItemReached { seq } => match self.phase {
                Phase::Active(SegmentKind::Settle(k) | SegmentKind::Hover(k))
                    if self.plan.points.get(k).is_some_and(|p| p.seq == *seq) =>
                {
                    let t = self.departure_time(t_s, Announcement::Prompt);
                    self.depart(t);
                }
                Phase::Active(SegmentKind::Takeoff) if self.plan.takeoff_seq == Some(*seq) => {
                    let t = self.departure_time(t_s, Announcement::Prompt);
                    self.depart(t);
                }
                Phase::Active(SegmentKind::Leg(k))
                    if self.plan.points.get(k).is_some_and(|p| p.seq == *seq) =>
                {
                    self.leg_cut_short(k, t_s, false);
                }
                _ => {}
            },
            Reading::Landed(state) => match state {
                LandedState::OnGround if self.phase == Phase::Active(SegmentKind::Landing) => {
                    self.landed_s.get_or_insert(t_s);
                }
                LandedState::Landing => self.on_landing(t_s),
                _ => {}
            },
            Reading::Position(p) => {
                self.boot_offset_s = Some(t_s - f64::from(p.time_boot_ms) * 1e-3);
                self.on_position(Sample {
                    t_s,
                    at: self.plan.to_local(p, self.frame_home_m),
                    velocity: [p.ve_m_s, p.vn_m_s, -p.vd_m_s],
                });
            }
            Reading::Home {
                alt_amsl_m,
                set_boot_s,
                ..
            } => self.on_home(*alt_amsl_m, *set_boot_s),
            Reading::StatusText { .. } => {}
            Reading::Wind(wind) => self.wind.push(t_s, *wind),
            Reading::Photo(photo) => {
                let vehicle = (self.state.position).zip(self.recent.back().map(|s| s.at));
                self.photos
                    .push(t_s, photo, &self.plan, self.frame_home_m, vehicle);
            }
            Reading::Fence(status) => {
                let at = (self.recent.back()).map(|s| [s.at.x_east_m, s.at.y_north_m, s.at.z_up_m]);
                let position = self.state.position.as_ref();
                (self.breaches).push(t_s, status, self.flight_start_s, position, at);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::energy::Flag;
    use crate::flightlog::report::FlightReport;
    use crate::flightlog::synthetic::{square_plan, SyntheticConfig, SyntheticFlight};
    use crate::flightlog::telemetry::{Battery, Position};

    fn fly() -> (SyntheticFlight, Segmenter) {
        let flight = SyntheticFlight::fly(&square_plan(), &SyntheticConfig::default());
        let s = Segmenter::run(square_plan(), SegmentConfig::default(), &flight.stamped())
            .expect("a valid plan");
        (flight, s)
    }

    /// How far a part's measured ends may be from the true ones: leg ends are interpolated 4 m
    /// crossings (exact but for the braking curve between two samples), a settle ends at the
    /// first stopped sample (speed under 0.3 m/s about 0.1 s before the true stop, then up to a
    /// sample period), the rest are message times.
    fn boundary_s(kind: SegmentKind) -> (f64, f64) {
        match kind {
            SegmentKind::Settle(_) => (0.01, 0.15),
            SegmentKind::Hover(_) => (0.15, 0.01),
            _ => (0.01, 0.01),
        }
    }

    /// The most a part's measured energy can be off: at each end the power step is smeared over
    /// one battery sample interval (0.1 s), and an end off by d moves d x power out of the part.
    fn tolerance_j(flight: &SyntheticFlight, kind: SegmentKind) -> f64 {
        let cfg = SyntheticConfig::default();
        let k = flight
            .parts
            .iter()
            .position(|p| p.kind == kind)
            .expect("a true part");
        let p = flight.parts[k].power_w;
        let before = k
            .checked_sub(1)
            .map_or(cfg.idle_power_w, |i| flight.parts[i].power_w);
        let after = flight
            .parts
            .get(k + 1)
            .map_or(cfg.idle_power_w, |x| x.power_w);
        let (d0, d1) = boundary_s(kind);
        ((p - before).abs() + (p - after).abs()) * 0.1 + p * (d0 + d1)
    }

    #[test]
    fn a_synthetic_flight_is_cut_into_its_true_parts_with_their_energies() {
        let (flight, s) = fly();
        let segments = s.completed();
        let kinds: Vec<SegmentKind> = segments.iter().map(|x| x.kind).collect();
        let truth: Vec<SegmentKind> = flight.parts.iter().map(|p| p.kind).collect();
        assert_eq!(kinds, truth);
        for (seg, part) in segments.iter().zip(&flight.parts) {
            let (d0, d1) = boundary_s(part.kind);
            assert!(
                (seg.start_s - part.start_s).abs() <= d0 && (seg.end_s - part.end_s).abs() <= d1,
                "{:?}: measured {}..{}, true {}..{}",
                part.kind,
                seg.start_s,
                seg.end_s,
                part.start_s,
                part.end_s
            );
            assert!(seg.complete && !seg.missed_radius);
            let m = s.measure(seg);
            let e = m.energy_j.expect("measured");
            let tol = tolerance_j(&flight, part.kind);
            assert!(
                (e - part.energy_j()).abs() <= tol,
                "{:?}: {e} J vs true {} J (tolerance {tol})",
                part.kind,
                part.energy_j()
            );
            assert!(m.flags.is_empty(), "{:?}: {:?}", part.kind, m.flags);
        }
        assert!(s.is_finished());
        assert_eq!(s.flight_span(), Some((flight.arm_s, flight.disarm_s)));
    }

    /// The square with its second leg round a zone through one via point and its return leg
    /// through two: take-off 0, A 1, via 2, B 3, C 4, via 5 and 6, origin 7, land 8.
    fn detoured_plan() -> FlightPlan {
        let enu = |x: f64, y: f64, z: f64| Enu {
            x_east_m: x,
            y_north_m: y,
            z_up_m: z,
        };
        let via = [
            vec![],
            vec![enu(85.0, 30.0, 5.0)],
            vec![],
            vec![enu(-20.0, 50.0, -5.0), enu(-20.0, 10.0, 0.0)],
        ];
        let seqs = [vec![], vec![2], vec![], vec![5, 6]];
        square_plan()
            .renumbered(Some(0), &[1, 3, 4, 7], 8)
            .and_then(|p| p.routed(&via, &seqs))
            .expect("a valid detoured plan")
    }

    #[test]
    fn a_leg_through_via_points_is_one_leg_from_its_departure_to_its_arrival() {
        let plan = detoured_plan();
        let flight = SyntheticFlight::fly(&plan, &SyntheticConfig::default());
        // The via points are reported reached and made current as the vehicle passes them.
        let said = |seq: u16| {
            flight
                .messages
                .iter()
                .any(|m| matches!(m.reading, Reading::ItemReached { seq: s } if s == seq))
                && flight.messages.iter().any(
                    |m| matches!(m.reading, Reading::MissionCurrent { seq: s, .. } if s == seq),
                )
        };
        assert!(said(2) && said(5) && said(6));
        let s = Segmenter::run(plan.clone(), SegmentConfig::default(), &flight.stamped())
            .expect("a valid plan");
        let segments = s.completed();
        let kinds: Vec<SegmentKind> = segments.iter().map(|x| x.kind).collect();
        let truth: Vec<SegmentKind> = flight.parts.iter().map(|p| p.kind).collect();
        assert_eq!(kinds, truth);
        assert_eq!(kinds.len(), 1 + 3 * 4 + 1);
        for (seg, part) in segments.iter().zip(&flight.parts) {
            let (d0, d1) = boundary_s(part.kind);
            assert!(
                (seg.start_s - part.start_s).abs() <= d0 && (seg.end_s - part.end_s).abs() <= d1,
                "{:?}: measured {}..{}, true {}..{}",
                part.kind,
                seg.start_s,
                seg.end_s,
                part.start_s,
                part.end_s
            );
            assert!(seg.complete && !seg.missed_radius, "{:?}", part.kind);
            let e = s.measure(seg).energy_j.expect("measured");
            let tol = tolerance_j(&flight, part.kind);
            assert!(
                (e - part.energy_j()).abs() <= tol,
                "{:?}: {e} J vs true {} J (tolerance {tol})",
                part.kind,
                part.energy_j()
            );
        }
        // The detoured legs are longer than straight ones: the truth says so, and so do they.
        let leg = |k: usize| flight.part(SegmentKind::Leg(k)).expect("a leg");
        let straight_b = 60.0f64.hypot(10.0) - 4.0;
        let flown_b = (leg(1).end_s - leg(1).start_s) * SyntheticConfig::default().speed_m_s;
        assert!(flown_b > straight_b + 10.0, "{flown_b} m vs {straight_b} m");
        // The report shows each as one leg, naming its ends and how many via points it passed.
        let report = FlightReport::build("square", &s);
        let legs: Vec<(&str, &str, usize)> = (report.legs.iter())
            .map(|l| (l.from.as_str(), l.to.as_str(), l.via_points))
            .collect();
        assert_eq!(
            legs,
            [
                ("origin", "A", 0),
                ("A", "B", 1),
                ("B", "C", 0),
                ("C", "origin", 2)
            ]
        );
        assert!(report.complete && report.waypoints_left.is_empty());
    }

    #[test]
    fn the_parts_add_up_to_the_whole_flight() {
        let (flight, s) = fly();
        let report = FlightReport::build("square", &s);
        let parts: f64 = report
            .parts()
            .map(|p| p.measured_j.expect("measured"))
            .sum();
        let whole = report.measured_j.expect("measured");
        assert!((parts - whole).abs() < 1e-9 * whole, "{parts} vs {whole}");
        // And the whole is the truth up to the smearing at arming and disarming.
        assert!((whole - flight.total_j()).abs() < 0.002 * flight.total_j());
        assert!(
            report.complete && report.flags.is_empty(),
            "{:?}",
            report.flags
        );
        assert_eq!(report.legs.len(), 4);
        assert_eq!(report.legs[3].to, "origin");
        let err = report.legs[0].error_pct().expect("predicted and measured");
        let expected = (report.legs[0].measured_j.expect("m") - 25_000.0) / 25_000.0 * 100.0;
        assert!((err - expected).abs() < 1e-9);
    }

    #[test]
    fn a_leg_ends_at_the_interpolated_crossing_of_the_radius_between_position_samples() {
        // Positions once a second at 3 m/s straight along x towards A at (60, 0, 0): the 4 m
        // sphere is crossed at x = 56, t = 56/3 s, between the samples at 18 s and 19 s.
        let mut s = Segmenter::new(square_plan(), SegmentConfig::default()).expect("valid");
        approach(&mut s, 20.0, 1.0);
        let leg = s
            .completed()
            .iter()
            .find(|x| x.kind == SegmentKind::Leg(0))
            .copied();
        let leg = leg.expect("leg 0 ended");
        assert!((leg.end_s - 56.0 / 3.0).abs() < 1e-6, "{}", leg.end_s);
        assert_eq!(
            s.in_progress().map(|x| x.kind),
            Some(SegmentKind::Settle(0))
        );
    }

    #[test]
    fn crossing_finds_the_first_entry_and_the_last_exit_of_a_sphere() {
        let e = |x: f64| Enu {
            x_east_m: x,
            ..Enu::default()
        };
        // From -10 to +10 through a sphere of radius 4 at 0: in at -4 (s = 0.3), out at +4.
        assert!((crossing(e(-10.0), e(10.0), e(0.0), 4.0, true) - 0.3).abs() < 1e-12);
        assert!((crossing(e(-10.0), e(10.0), e(0.0), 4.0, false) - 0.7).abs() < 1e-12);
        assert_eq!(crossing(e(1.0), e(1.0), e(0.0), 4.0, true), 1.0);
    }

    #[test]
    fn a_log_cut_mid_leg_keeps_the_parts_flown_and_marks_the_leg_incomplete() {
        let (flight, _) = fly();
        let leg2 = flight.part(SegmentKind::Leg(2)).copied().expect("leg 2");
        let cut = 0.5 * (leg2.start_s + leg2.end_s);
        let stamped: Vec<Stamped> = flight
            .stamped()
            .into_iter()
            .filter(|m| m.t_s < cut)
            .collect();
        let s = Segmenter::run(square_plan(), SegmentConfig::default(), &stamped).expect("valid");
        let report = FlightReport::build("cut", &s);
        assert_eq!(report.legs.len(), 3);
        assert!(report.legs[..2]
            .iter()
            .all(|l| !l.flags.contains(&Flag::Incomplete)));
        assert!(report.legs[2].flags.contains(&Flag::Incomplete));
        assert_eq!(report.legs[2].error_pct(), None);
        assert!(report.landing.is_none() && !report.complete);
        assert!(report.flags.contains(&Flag::Incomplete));
        let so_far = report.legs[2].measured_j.expect("measured so far");
        let expected = leg2.power_w * (s.now_s() - leg2.start_s);
        assert!(
            (so_far - expected).abs() < 0.01 * expected,
            "{so_far} vs {expected}"
        );
    }

    #[test]
    fn live_the_completed_parts_and_the_leg_in_progress_are_known_at_any_time() {
        let (flight, _) = fly();
        let leg1 = flight.part(SegmentKind::Leg(1)).copied().expect("leg 1");
        let mut s = Segmenter::new(square_plan(), SegmentConfig::default()).expect("valid");
        let mut checked = false;
        for m in flight.stamped() {
            s.push(&m);
            if !checked && m.t_s > leg1.start_s + 5.0 {
                checked = true;
                let kinds: Vec<SegmentKind> = s.completed().iter().map(|x| x.kind).collect();
                assert_eq!(
                    kinds,
                    [
                        SegmentKind::Takeoff,
                        SegmentKind::Leg(0),
                        SegmentKind::Settle(0),
                        SegmentKind::Hover(0)
                    ]
                );
                let now = s.in_progress().expect("flying");
                assert_eq!(now.kind, SegmentKind::Leg(1));
                let e = s.measure(&now).energy_j.expect("measured");
                let expected = leg1.power_w * (now.end_s - leg1.start_s);
                assert!((e - expected).abs() < 0.01 * expected, "{e} vs {expected}");
            }
        }
        assert!(checked);
    }

    #[test]
    fn with_the_autopilots_home_a_jumpy_relative_altitude_moves_no_boundary() {
        let (flight, _) = fly();
        let plan = square_plan();
        let bounds = |stamped: &[Stamped]| -> Vec<(SegmentKind, f64, f64)> {
            let s =
                Segmenter::run(square_plan(), SegmentConfig::default(), stamped).expect("valid");
            s.completed()
                .iter()
                .map(|x| (x.kind, x.start_s, x.end_s))
                .collect()
        };
        let clean = bounds(&flight.stamped());
        // PX4 SITL: relative_alt off by metres in most GLOBAL_POSITION_INT, alt exact.
        let mut n = 0;
        let jumpy: Vec<Stamped> = flight
            .stamped()
            .into_iter()
            .map(|mut m| {
                if let Reading::Position(p) = &mut m.reading {
                    n += 1;
                    p.relative_alt_m += [2.5, -1.5, 0.0][n % 3];
                }
                m
            })
            .collect();
        assert_ne!(bounds(&jumpy), clean, "the jumps must matter without home");
        let mut with_home = vec![Stamped {
            t_s: 0.0,
            wall_us: 0,
            reading: Reading::Home {
                lat_deg: plan.home.lat_deg,
                lon_deg: plan.home.lon_deg,
                alt_amsl_m: plan.home.alt_m,
                set_boot_s: None,
            },
        }];
        with_home.extend(jumpy);
        assert_eq!(bounds(&with_home), clean);
    }

    #[test]
    fn a_target_is_measured_from_the_home_the_autopilot_held_when_it_set_it() {
        // PX4 SITL's home moves in flight, and PX4 adds the home it holds when it sets an item
        // to the item's relative altitude. Home rises 1.5 m during leg 1 (A -> B), said 2 s
        // late: B stays where the old home put it, and the points after it are flown 1.5 m
        // higher from leg 2 on.
        let (flight, _) = fly();
        let plan = square_plan();
        let bounds = |stamped: &[Stamped]| -> Vec<(SegmentKind, f64, f64)> {
            Segmenter::run(square_plan(), SegmentConfig::default(), stamped)
                .expect("valid")
                .completed()
                .iter()
                .map(|x| (x.kind, x.start_s, x.end_s))
                .collect()
        };
        let home = |t_s: f64, alt_amsl_m: f64, set_boot_s: f64| Stamped {
            t_s,
            wall_us: 0,
            reading: Reading::Home {
                lat_deg: plan.home.lat_deg,
                lon_deg: plan.home.lon_deg,
                alt_amsl_m,
                set_boot_s: Some(set_boot_s),
            },
        };
        let leg1 = flight.part(SegmentKind::Leg(1)).copied().expect("leg 1");
        let leg2 = flight.part(SegmentKind::Leg(2)).copied().expect("leg 2");
        // Flight time less boot time, from the positions.
        let offset_s = flight
            .stamped()
            .iter()
            .find_map(|m| match &m.reading {
                Reading::Position(p) => Some(m.t_s - f64::from(p.time_boot_ms) * 1e-3),
                _ => None,
            })
            .expect("positions");
        let risen_s = leg1.start_s + 1.0;
        assert!(
            risen_s + 2.0 < leg1.end_s,
            "the news must come before B is reached"
        );
        let mut clean = vec![home(0.0, plan.home.alt_m, 0.0)];
        clean.extend(flight.stamped());
        let mut moved = clean.clone();
        for m in &mut moved {
            if let Reading::Position(p) = &mut m.reading {
                if m.t_s >= leg2.start_s {
                    p.alt_amsl_m += 1.5;
                }
            }
        }
        let at = moved.partition_point(|m| m.t_s <= risen_s + 2.0);
        moved.insert(
            at,
            home(risen_s + 2.0, plan.home.alt_m + 1.5, risen_s - offset_s),
        );
        let (want, got) = (bounds(&clean), bounds(&moved));
        assert_eq!(want.len(), got.len());
        for (w, g) in want.iter().zip(&got) {
            assert_eq!(w.0, g.0);
            assert!(
                (w.1 - g.1).abs() < 0.05 && (w.2 - g.2).abs() < 0.05,
                "{w:?} against {g:?}"
            );
        }
    }

    #[test]
    fn a_lost_mission_current_change_is_recovered_from_the_departure_seen_in_positions() {
        let (flight, _) = fly();
        let leg2 = flight.part(SegmentKind::Leg(2)).copied().expect("leg 2");
        let leg_start = |stamped: &[Stamped]| {
            let s =
                Segmenter::run(square_plan(), SegmentConfig::default(), stamped).expect("valid");
            s.completed()
                .iter()
                .find(|x| x.kind == SegmentKind::Leg(2))
                .copied()
                .expect("leg 2")
                .start_s
        };
        // Every MISSION_CURRENT naming C is lost (the change and PX4's 1 Hz repeats): the
        // reached message of B, sent as the vehicle leaves it, marks the departure.
        let no_current: Vec<Stamped> = flight
            .stamped()
            .into_iter()
            .filter(|m| !matches!(m.reading, Reading::MissionCurrent { seq: 3, .. }))
            .collect();
        let start = leg_start(&no_current);
        assert!(
            (start - leg2.start_s).abs() < 0.01,
            "start {start} vs true {}",
            leg2.start_s
        );
        // Both lost: the departure is found in the positions, back where the motion began
        // (within a position sample, 0.1 s), not where the vehicle left the 2 m radius.
        let no_message: Vec<Stamped> = no_current
            .into_iter()
            .filter(|m| !matches!(m.reading, Reading::ItemReached { seq: 2 }))
            .collect();
        let start = leg_start(&no_message);
        assert!(
            (start - leg2.start_s).abs() < 0.1,
            "start {start} vs true {}",
            leg2.start_s
        );
    }

    #[test]
    fn a_hover_adjustment_before_the_reached_message_is_not_taken_for_the_departure() {
        let (flight, _) = fly();
        let leg2 = flight.part(SegmentKind::Leg(2)).copied().expect("leg 2");
        // The vehicle rises at 0.6 m/s for the last 0.6 s of its hold at B (as PX4 SITL's did at
        // one point of one flight), then leaves when B is reported reached.
        let adjusted: Vec<Stamped> = flight
            .stamped()
            .into_iter()
            .map(|mut m| {
                if let Reading::Position(p) = &mut m.reading {
                    if m.t_s >= leg2.start_s - 0.6 && m.t_s < leg2.start_s {
                        p.vd_m_s = -0.6;
                    }
                }
                m
            })
            .collect();
        let s = Segmenter::run(square_plan(), SegmentConfig::default(), &adjusted).expect("valid");
        let found = *s
            .completed()
            .iter()
            .find(|x| x.kind == SegmentKind::Leg(2))
            .expect("leg 2");
        assert!(
            (found.start_s - leg2.start_s).abs() < 0.01,
            "start {} vs true {}",
            found.start_s,
            leg2.start_s
        );
        // The leg says how it began: still rising at 0.6 m/s, on its point.
        let began = found.start_state.expect("positions were known");
        assert!((began.speed_m_s - 0.6).abs() < 0.05, "{began:?}");
        assert!(began.offset_m < 0.3, "{began:?}");
        // The same leg of the unchanged flight began at rest on its point.
        let (_, clean) = fly();
        let began = clean
            .completed()
            .iter()
            .find(|x| x.kind == SegmentKind::Leg(2))
            .and_then(|x| x.start_state)
            .expect("leg 2 with its start");
        assert!(began.speed_m_s < 0.05 && began.offset_m < 0.3, "{began:?}");
    }

    fn with_battery(
        flight: &SyntheticFlight,
        f: impl Fn(f64, &mut Battery) -> bool,
    ) -> Vec<Stamped> {
        flight
            .stamped()
            .into_iter()
            .filter_map(|mut m| {
                if let Reading::Battery(b) = &mut m.reading {
                    if !f(m.t_s, b) {
                        return None;
                    }
                }
                Some(m)
            })
            .collect()
    }

    fn report_of(stamped: &[Stamped]) -> FlightReport {
        let s = Segmenter::run(square_plan(), SegmentConfig::default(), stamped).expect("valid");
        FlightReport::build("faulty", &s)
    }

    #[test]
    fn a_telemetry_gap_flags_only_the_leg_it_falls_in() {
        let (flight, _) = fly();
        let leg1 = flight.part(SegmentKind::Leg(1)).copied().expect("leg 1");
        let gap = (leg1.start_s + 3.0, leg1.start_s + 5.0);
        let report = report_of(&with_battery(&flight, |t, _| !(gap.0..gap.1).contains(&t)));
        assert!(
            report.legs[1].flags.contains(&Flag::TelemetryGap),
            "{:?}",
            report.legs[1].flags
        );
        for k in [0, 2, 3] {
            assert!(
                report.legs[k].flags.is_empty(),
                "leg {k}: {:?}",
                report.legs[k].flags
            );
        }
        // Constant power inside the leg: interpolated across, the energy is still right.
        let e = report.legs[1].measured_j.expect("measured");
        assert!((e - leg1.energy_j()).abs() < 0.01 * leg1.energy_j());
    }

    #[test]
    fn unknown_current_and_voltage_outliers_flag_their_parts() {
        let (flight, _) = fly();
        let leg2 = flight.part(SegmentKind::Leg(2)).copied().expect("leg 2");
        let hover0 = flight
            .part(SegmentKind::Hover(0))
            .copied()
            .expect("hover 0");
        let stamped = with_battery(&flight, |t, b| {
            if (leg2.start_s + 2.0..leg2.start_s + 2.5).contains(&t) {
                b.current_a = None;
            }
            if (t - (hover0.start_s + 1.05)).abs() < 0.04 {
                b.voltage_v = Some(3.2);
            }
            true
        });
        let report = report_of(&stamped);
        assert_eq!(report.legs[2].flags, vec![Flag::CurrentUnknown]);
        assert_eq!(report.hovers[0].flags, vec![Flag::VoltageOutlier]);
        assert!(report.legs[0].flags.is_empty() && report.hovers[1].flags.is_empty());
        let e = report.hovers[0].measured_j.expect("measured");
        assert!(
            (e - hover0.energy_j()).abs() < 0.05 * hover0.energy_j(),
            "{e}"
        );
    }

    #[test]
    fn px4_fake_current_makes_every_part_unmeasurable_and_says_why() {
        let (flight, _) = fly();
        let stamped = with_battery(&flight, |_, b| {
            b.current_a = Some(-1.0);
            b.fake_current = true;
            true
        });
        let report = report_of(&stamped);
        assert_eq!(report.measured_j, None);
        for p in report.parts() {
            assert_eq!(p.measured_j, None);
            assert!(p.flags.contains(&Flag::FakeCurrent) && p.flags.contains(&Flag::Unmeasurable));
        }
        // The segmentation itself does not need the battery.
        assert_eq!(report.legs.len(), 4);
        assert!(report.complete);
    }

    /// Hand-fed readings: arming at 0, the vehicle on the line from the origin towards A
    /// (60, 0, 0) at 3 m/s, a position every `period_s`.
    fn approach(s: &mut Segmenter, until_s: f64, period_s: f64) {
        let plan = square_plan();
        let origin = plan.origin();
        let stamp = |t_s: f64, reading: Reading| Stamped {
            t_s,
            wall_us: 0,
            reading,
        };
        s.push(&stamp(
            0.0,
            Reading::Heartbeat {
                armed: true,
                mode: FlightMode::Mission,
            },
        ));
        s.push(&stamp(
            0.0,
            Reading::MissionCurrent {
                seq: 1,
                total: None,
                state: crate::flightlog::telemetry::MissionState::Active,
            },
        ));
        let mut k = 0u32;
        while f64::from(k) * period_s <= until_s + 1e-9 {
            let t = f64::from(k) * period_s;
            let g = origin.to_geodetic(Enu {
                x_east_m: 3.0 * t,
                ..Enu::default()
            });
            s.push(&stamp(
                t,
                Reading::Position(Position {
                    time_boot_ms: 0,
                    lat_deg: g.lat_deg,
                    lon_deg: g.lon_deg,
                    alt_amsl_m: g.alt_m,
                    relative_alt_m: g.alt_m - plan.home.alt_m,
                    vn_m_s: 0.0,
                    ve_m_s: 3.0,
                    vd_m_s: 0.0,
                }),
            ));
            k += 1;
        }
    }

    #[test]
    fn a_leg_the_autopilot_ends_outside_the_radius_is_flagged_missed_radius() {
        // An acceptance radius of 6 m: at x = 54 (t = 18 s) the autopilot moves on to B.
        let mut s = Segmenter::new(square_plan(), SegmentConfig::default()).expect("valid");
        approach(&mut s, 18.0, 0.1);
        s.push(&Stamped {
            t_s: 18.0,
            wall_us: 0,
            reading: Reading::MissionCurrent {
                seq: 2,
                total: None,
                state: crate::flightlog::telemetry::MissionState::Active,
            },
        });
        let kinds: Vec<(SegmentKind, f64, f64, bool)> = s
            .completed()
            .iter()
            .map(|x| (x.kind, x.start_s, x.end_s, x.missed_radius))
            .collect();
        assert_eq!(
            kinds[1..],
            [
                (SegmentKind::Leg(0), 0.0, 18.0, true),
                (SegmentKind::Settle(0), 18.0, 18.0, false),
                (SegmentKind::Hover(0), 18.0, 18.0, false),
            ]
        );
        assert_eq!(s.in_progress().map(|x| x.kind), Some(SegmentKind::Leg(1)));
        let report = FlightReport::build("missed", &s);
        assert!(report.legs[0].flags.contains(&Flag::MissedRadius));
    }

    #[test]
    fn an_rtl_in_the_middle_of_the_mission_cuts_the_leg_short_and_starts_the_landing() {
        let mut s = Segmenter::new(square_plan(), SegmentConfig::default()).expect("valid");
        approach(&mut s, 10.0, 0.1);
        s.push(&Stamped {
            t_s: 10.05,
            wall_us: 0,
            reading: Reading::Heartbeat {
                armed: true,
                mode: FlightMode::Rtl,
            },
        });
        let last = s.completed().last().copied().expect("a segment");
        assert_eq!((last.kind, last.complete), (SegmentKind::Leg(0), false));
        assert_eq!(s.in_progress().map(|x| x.kind), Some(SegmentKind::Landing));
        s.push(&Stamped {
            t_s: 40.0,
            wall_us: 0,
            reading: Reading::Heartbeat {
                armed: false,
                mode: FlightMode::Rtl,
            },
        });
        assert!(s.is_finished());
        let report = FlightReport::build("rtl", &s);
        assert!(report.legs[0].flags.contains(&Flag::Incomplete));
        assert_eq!(s.flight_span(), Some((0.0, 40.0)));
    }

    #[test]
    fn a_log_that_begins_in_flight_starts_at_the_leg_being_flown() {
        let (flight, _) = fly();
        let leg1 = flight.part(SegmentKind::Leg(1)).copied().expect("leg 1");
        let join = leg1.start_s + 3.0;
        let stamped: Vec<Stamped> = flight
            .stamped()
            .into_iter()
            .filter(|m| m.t_s >= join)
            .collect();
        let s = Segmenter::run(square_plan(), SegmentConfig::default(), &stamped).expect("valid");
        let report = FlightReport::build("joined", &s);
        let names: Vec<(String, String)> = report
            .legs
            .iter()
            .map(|l| (l.from.clone(), l.to.clone()))
            .collect();
        assert_eq!(names[0], ("A".to_string(), "B".to_string()));
        assert_eq!(report.legs.len(), 3);
        assert!(report.legs[0].flags.contains(&Flag::Incomplete));
        assert!(
            report.legs[1..].iter().all(|l| l.flags.is_empty()),
            "{:?}",
            report.legs
        );
        assert!(report
            .takeoff
            .as_ref()
            .is_some_and(|t| t.flags.contains(&Flag::Incomplete)));
        let leg2 = flight.part(SegmentKind::Leg(2)).copied().expect("leg 2");
        let e = report.legs[1].measured_j.expect("measured");
        assert!((e - leg2.energy_j()).abs() < 0.01 * leg2.energy_j());
    }
}
