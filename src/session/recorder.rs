//! The flight recorder: logs every flight seen on a link, whoever started it, from arming to
//! disarming, into a flight directory of its own (`flightlog::recorder`), segments it against
//! the flight plan as it flies, and writes its report when it lands.
//!
//! One thread owns the files (blocking writes and fsyncs); a task forwards it every frame of
//! the link's tap (never dropped) and a 250 ms tick for the time-driven flush. The frames of
//! the last few seconds before arming are kept and written first, so a flight's log begins
//! before its take-off. Each flight decodes its frames with a fresh `link::telemetry::Telemetry`
//! from its first logged frame, exactly as `replay` will, so the live report and the replayed
//! one agree.
//!
//! Handles: `set_plan` (what the next flight, or the one in progress, is measured against: a
//! plan set mid-flight is applied to everything recorded so far; `set_plan_repriced` with a
//! [`Repricer`] that prices the rest again when the vehicle's wind estimate changes in flight,
//! each repricing kept in repriced.jsonl), `subscribe` (flight events:
//! started, each part completed, ended with its report), `live` (the latest state: vehicle,
//! battery, the part in progress), `close` (finishes an open flight cleanly).

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::time::Duration;

use tokio::sync::{broadcast, mpsc, oneshot, watch};

use crate::flightlog::flight_plan::{FlightPlan, Repricing};
use crate::flightlog::recorder::{flight_name, read_report, write_report, Recorder, TLOG_FILE};
use crate::flightlog::report::{FlightReport, PartReport, RepricedNote};
use crate::flightlog::segment::{SegmentConfig, SegmentKind, Segmenter};
use crate::flightlog::telemetry::{Reading, Stamped, VehicleState};
use crate::flightlog::tlog::read_tlog;
use crate::flightlog::watch::{GuardNote, GuardView};
use crate::ledger::LedgerSpec;
use crate::link::connection::{wall_us, Frame, Link};
use crate::link::telemetry::Telemetry;
use crate::mission::wind::Wind;

/// How the recorder works.
#[derive(Debug, Clone, PartialEq)]
pub struct RecorderConfig {
    /// Where flight directories are made.
    pub log_dir: PathBuf,
    pub segment: SegmentConfig,
    /// Frames kept from before arming, written at the start of a flight's log.
    pub preroll: Duration,
    /// Recording goes on this long (wall time) after the disarm.
    pub tail: Duration,
    /// Resume a flight whose recording was cut off (emplan killed or stopped mid-flight and
    /// started again): when the first heartbeat says the vehicle is armed, the newest flight
    /// directory is appended to instead of a new one made, if its log ends within this long
    /// (wall time) before now, its last heartbeat was armed, it comes from the same autopilot
    /// and it has no complete report. None: every flight seen gets a new directory.
    pub resume_within: Option<Duration>,
    /// The ledger every flight whose report is written goes to (`super::ledger`); None: none.
    pub ledger: Option<LedgerSpec>,
}

impl RecorderConfig {
    /// Flights made in `log_dir`, each written to the ledger beside them
    /// (`log_dir/ledger.sqlite`).
    pub fn new(log_dir: impl Into<PathBuf>) -> RecorderConfig {
        let log_dir = log_dir.into();
        RecorderConfig {
            ledger: Some(super::ledger::default_spec(&log_dir)),
            log_dir,
            segment: SegmentConfig::default(),
            preroll: Duration::from_secs(5),
            tail: Duration::from_millis(500),
            resume_within: None,
        }
    }

    /// The same, writing flights to `ledger` (None: the default beside them).
    pub fn with_ledger(self, ledger: Option<LedgerSpec>) -> RecorderConfig {
        match ledger {
            Some(spec) => RecorderConfig {
                ledger: Some(spec),
                ..self
            },
            None => self,
        }
    }
}

/// What happens to flights.
#[derive(Debug, Clone)]
pub enum FlightEvent {
    /// A flight directory was opened (at arming, or at once when the vehicle was already
    /// flying), or reopened to go on recording a flight cut off (`resumed`).
    Started {
        flight: String,
        dir: PathBuf,
        resumed: bool,
    },
    /// A part of the flight is complete (take-off, a leg, a settle, a hover, the landing).
    Part {
        flight: String,
        kind: SegmentKind,
        part: PartReport,
    },
    /// The flight ended (disarmed, or the recorder closed); its files are complete. The report
    /// is absent when no flight plan was ever set.
    Ended {
        flight: String,
        dir: PathBuf,
        report: Option<Box<FlightReport>>,
    },
    /// The recorder could not write; the flight's files hold what was written before. Before
    /// any `Started` of its flight: its directory could not be made, nothing of it is recorded.
    Failed { flight: String, error: String },
    /// The energy guard saw or decided something (a `Return` note: it decided to send the
    /// vehicle home; the flight's session does).
    Guard { flight: String, note: GuardNote },
    /// The rest of the flight was priced again in the wind the vehicle estimated in flight
    /// (`fly --wind live`).
    Repriced {
        flight: String,
        repriced: RepricedNote,
    },
}

/// Prices the rest of a flight again in a wind heard in flight: the plan as priced so far, the
/// vehicle's wind estimate and the first point whose leg has not begun (`fly --wind live`).
/// Its `t_s` is the recorder's to set.
pub type Repricer = Box<dyn Fn(&FlightPlan, Wind, usize) -> Result<Repricing, RepriceError> + Send>;

/// Why the rest of a flight could not be priced again in the wind heard.
#[derive(Debug, thiserror::Error)]
pub enum RepriceError {
    /// The legs, settles, hovers or landing in that wind.
    #[error(transparent)]
    Legs(#[from] super::predict::FlightItemsError),
    /// The energy guard's way home from every point in that wind.
    #[error("the guard's return prices: {0}")]
    Guard(#[from] crate::physics::PhysicsError),
}

/// The latest battery sample.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BatteryNow {
    pub voltage_v: Option<f64>,
    pub current_a: Option<f64>,
    pub power_w: Option<f64>,
    pub consumed_mah: Option<f64>,
    pub remaining_pct: Option<f64>,
}

/// The flight being recorded.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveFlight {
    pub flight: String,
    pub dir: PathBuf,
    /// Vehicle time since the flight's first logged frame.
    pub t_s: f64,
    /// The part in progress with its energy so far (measured) and its prediction.
    pub in_progress: Option<(SegmentKind, PartReport)>,
    /// Parts completed so far.
    pub parts: usize,
    /// The energy guard's view, when the flight is guarded.
    pub guard: Option<GuardView>,
}

/// The latest state the recorder knows.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Live {
    pub vehicle: VehicleState,
    pub battery: Option<BatteryNow>,
    pub flight: Option<LiveFlight>,
    /// Frames seen on the link.
    pub frames: u64,
}

enum Input {
    Frame(Frame),
    Tick(u64),
    Plan(Box<FlightPlan>, Option<Repricer>),
    Close(oneshot::Sender<()>),
}

/// A running recorder.
pub struct RecorderHandle {
    input: mpsc::UnboundedSender<Input>,
    events: broadcast::Sender<FlightEvent>,
    live: watch::Receiver<Live>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl RecorderHandle {
    /// The plan the flight in progress is measured against (everything recorded so far is
    /// measured again when it replaces another one, and its parts announced again), or the
    /// next flight's when none is in progress (or the one in progress has disarmed). A flight
    /// uses up the plan: the one after it starts without one unless another is set.
    pub fn set_plan(&self, plan: FlightPlan) {
        let _ = self.input.send(Input::Plan(Box::new(plan), None));
    }

    /// [`Self::set_plan`], with the rest of the flight priced again by `repricer` whenever the
    /// vehicle's wind estimate moves far enough from the wind it is priced in
    /// (`flightlog::wind`): each repricing is appended to the flight directory's
    /// repriced.jsonl and announced (`FlightEvent::Repriced`).
    pub fn set_plan_repriced(&self, plan: FlightPlan, repricer: Repricer) {
        let _ = self.input.send(Input::Plan(Box::new(plan), Some(repricer)));
    }

    /// Flight events from now on.
    pub fn subscribe(&self) -> broadcast::Receiver<FlightEvent> {
        self.events.subscribe()
    }

    /// The latest state.
    pub fn live(&self) -> watch::Receiver<Live> {
        self.live.clone()
    }

    /// Finishes the flight in progress (its report marked incomplete) and stops.
    pub async fn close(mut self) {
        let (done, wait) = oneshot::channel();
        if self.input.send(Input::Close(done)).is_ok() {
            let _ = wait.await;
        }
        if let Some(thread) = self.thread.take() {
            let _ = tokio::task::spawn_blocking(move || thread.join()).await;
        }
    }
}

/// Starts recording every flight on `link`.
pub fn spawn_recorder(link: &Link, cfg: RecorderConfig) -> RecorderHandle {
    let (input, mut inputs) = mpsc::unbounded_channel();
    let (events, _) = broadcast::channel(1024);
    let (live_tx, live) = watch::channel(Live::default());
    let mut tap = link.tap();
    let forward = input.clone();
    tokio::spawn(async move {
        let mut tick = tokio::time::interval(Duration::from_millis(250));
        loop {
            let sent = tokio::select! {
                frame = tap.recv() => match frame {
                    Some(frame) => forward.send(Input::Frame(frame)),
                    None => return,
                },
                _ = tick.tick() => forward.send(Input::Tick(wall_us())),
            };
            if sent.is_err() {
                return;
            }
        }
    });
    let thread_events = events.clone();
    let thread = std::thread::Builder::new()
        .name("flight-recorder".into())
        .spawn(move || {
            let mut state = State::new(cfg, thread_events, live_tx);
            while let Some(input) = inputs.blocking_recv() {
                match input {
                    Input::Frame(frame) => state.frame(frame),
                    Input::Tick(now_us) => state.tick(now_us),
                    Input::Plan(plan, repricer) => state.set_plan(*plan, repricer),
                    Input::Close(done) => {
                        state.end_flight(wall_us());
                        let _ = done.send(());
                        return;
                    }
                }
            }
            state.end_flight(wall_us());
        })
        .ok();
    RecorderHandle {
        input,
        events,
        live,
        thread,
    }
}

/// A flight being recorded.
struct Open {
    name: String,
    recorder: Recorder,
    telemetry: Telemetry,
    /// Every reading so far (a plan set mid-flight is applied to all of them).
    stamped: Vec<Stamped>,
    segmenter: Option<Segmenter>,
    /// Parts already announced.
    announced: usize,
    /// When the flight ends (wall time), once it has disarmed.
    ends_at_us: Option<u64>,
    failed: bool,
    /// Prices the rest again when the wind changes in flight.
    repricer: Option<Repricer>,
}

struct State {
    cfg: RecorderConfig,
    events: broadcast::Sender<FlightEvent>,
    live_tx: watch::Sender<Live>,
    live: Live,
    /// Decodes everything, for the vehicle's state between flights.
    watch: Telemetry,
    preroll: VecDeque<Frame>,
    plan: Option<FlightPlan>,
    repricer: Option<Repricer>,
    open: Option<Open>,
    was_armed: Option<bool>,
    last_live_us: u64,
}

impl State {
    fn new(
        cfg: RecorderConfig,
        events: broadcast::Sender<FlightEvent>,
        live_tx: watch::Sender<Live>,
    ) -> State {
        State {
            cfg,
            events,
            live_tx,
            live: Live::default(),
            watch: Telemetry::new(),
            preroll: VecDeque::new(),
            plan: None,
            repricer: None,
            open: None,
            was_armed: None,
            last_live_us: 0,
        }
    }

    fn frame(&mut self, frame: Frame) {
        self.live.frames += 1;
        let now_us = frame.wall_us;
        let mut armed_now = None;
        if let Some(s) = self.watch.frame(frame.wall_us, &frame.bytes) {
            self.live.vehicle.update(&s.reading);
            match &s.reading {
                Reading::Heartbeat { armed, .. } => armed_now = Some(*armed),
                Reading::Battery(b) => {
                    self.live.battery = Some(BatteryNow {
                        voltage_v: b.voltage_v,
                        current_a: b.current_a,
                        power_w: b.voltage_v.zip(b.current_a).map(|(v, i)| v * i),
                        consumed_mah: b.consumed_mah,
                        remaining_pct: b.remaining_pct,
                    })
                }
                _ => {}
            }
        }
        if let Some(open) = self.open.as_mut() {
            record(open, &self.events, &frame);
        } else {
            self.preroll.push_back(frame);
            let keep_us = self.cfg.preroll.as_micros() as u64;
            while self
                .preroll
                .front()
                .is_some_and(|f| now_us.saturating_sub(f.wall_us) > keep_us)
            {
                self.preroll.pop_front();
            }
        }
        if let Some(armed) = armed_now {
            // A new flight at arming, or at once when the first heartbeat says it is flying.
            let rising = armed && self.was_armed != Some(true);
            if rising {
                if self.open.as_ref().is_some_and(|o| o.ends_at_us.is_some()) {
                    self.end_flight(now_us);
                }
                if self.open.is_none() && !(self.was_armed.is_none() && self.resume(now_us)) {
                    self.start_flight(now_us);
                }
            }
            if !armed && self.was_armed == Some(true) {
                if let Some(open) = self.open.as_mut() {
                    open.ends_at_us
                        .get_or_insert(now_us + self.cfg.tail.as_micros() as u64);
                }
            }
            self.was_armed = Some(armed);
        }
        self.tick(now_us);
    }

    fn tick(&mut self, now_us: u64) {
        if let Some(open) = self.open.as_mut() {
            if !open.failed {
                if let Err(e) = open.recorder.tick(now_us) {
                    fail(open, &self.events, e.to_string());
                }
            }
            if open.ends_at_us.is_some_and(|at| now_us >= at) {
                self.end_flight(now_us);
            }
        }
        if now_us.saturating_sub(self.last_live_us) >= 200_000 {
            self.last_live_us = now_us;
            self.publish();
        }
    }

    fn publish(&mut self) {
        self.live.flight = self.open.as_ref().map(|open| {
            let (t_s, in_progress, parts) = match &open.segmenter {
                Some(seg) => {
                    let in_progress = seg.in_progress().and_then(|segment| {
                        let report = FlightReport::build(&open.name, seg);
                        let part = report
                            .parts()
                            .find(|p| p.start_s == segment.start_s)
                            .cloned();
                        part.map(|p| (segment.kind, p))
                    });
                    (seg.now_s(), in_progress, seg.completed().len())
                }
                None => (open.stamped.last().map_or(0.0, |s| s.t_s), None, 0),
            };
            LiveFlight {
                flight: open.name.clone(),
                dir: open.recorder.dir().to_path_buf(),
                t_s,
                in_progress,
                parts,
                guard: open
                    .segmenter
                    .as_ref()
                    .and_then(|s| s.watch())
                    .and_then(|w| w.view().cloned()),
            }
        });
        let _ = self.live_tx.send(self.live.clone());
    }

    fn set_plan(&mut self, mut plan: FlightPlan, repricer: Option<Repricer>) {
        if self.open.as_ref().is_some_and(|o| o.ends_at_us.is_some()) {
            // The flight in progress has disarmed: the plan is the next one's.
            self.end_flight(wall_us());
        }
        let Some(open) = self.open.as_mut() else {
            self.plan = Some(plan);
            self.repricer = repricer;
            return;
        };
        open.repricer = repricer;
        // What was priced again in flight stays (applied again in the replay below).
        if let Some(seg) = &open.segmenter {
            if plan.repricings.is_empty() {
                plan.repricings.clone_from(&seg.plan().repricings);
            }
        }
        if open.segmenter.as_ref().is_some_and(|s| *s.plan() == plan) {
            return;
        }
        if let Err(e) = open.recorder.write_plan(&plan) {
            fail(open, &self.events, e.to_string());
        }
        match Segmenter::new(plan, self.cfg.segment) {
            Ok(mut seg) => {
                for s in &open.stamped {
                    seg.push(s);
                }
                open.segmenter = Some(seg);
                open.announced = 0;
                announce(open, &self.events);
            }
            Err(e) => fail(open, &self.events, e.to_string()),
        }
    }

    fn start_flight(&mut self, now_us: u64) {
        let start_us = self.preroll.front().map_or(now_us, |f| f.wall_us);
        let mission = self
            .plan
            .as_ref()
            .map_or_else(|| "flight".to_string(), |p| p.mission.clone());
        let recorder = match Recorder::create(&self.cfg.log_dir, &mission, start_us) {
            Ok(r) => r,
            Err(e) => {
                // Sent before any Started: `fly` ends on it (this flight is not recorded).
                let _ = self.events.send(FlightEvent::Failed {
                    flight: mission,
                    error: e.to_string(),
                });
                return;
            }
        };
        let name = flight_name(recorder.dir());
        let _ = self.events.send(FlightEvent::Started {
            flight: name.clone(),
            dir: recorder.dir().to_path_buf(),
            resumed: false,
        });
        let mut open = Open {
            name,
            recorder,
            telemetry: Telemetry::new(),
            stamped: Vec::new(),
            segmenter: None,
            announced: 0,
            ends_at_us: None,
            failed: false,
            repricer: self.repricer.take(),
        };
        if let Some(plan) = &self.plan {
            if let Err(e) = open.recorder.write_plan(plan) {
                fail(&mut open, &self.events, e.to_string());
            }
            match Segmenter::new(plan.clone(), self.cfg.segment) {
                Ok(seg) => open.segmenter = Some(seg),
                Err(e) => fail(&mut open, &self.events, e.to_string()),
            }
        }
        for frame in std::mem::take(&mut self.preroll) {
            record(&mut open, &self.events, &frame);
        }
        self.open = Some(open);
    }

    /// Goes on recording into the newest flight directory when its recording was cut off in
    /// flight (see [`RecorderConfig::resume_within`]); returns whether it did. The frames
    /// already logged go through a fresh decoder and segmenter, as in a replay of the whole
    /// log, so the report at the end is the replay's.
    fn resume(&mut self, now_us: u64) -> bool {
        let Some(within) = self.cfg.resume_within else {
            return false;
        };
        let Some(dir) = flight_dirs(&self.cfg.log_dir)
            .ok()
            .and_then(|dirs| dirs.last().cloned())
        else {
            return false;
        };
        if read_report(&dir).is_ok_and(|r| r.complete) {
            return false;
        }
        let Ok(log) = read_tlog(&dir.join(TLOG_FILE)) else {
            return false;
        };
        let mut telemetry = Telemetry::new();
        let mut stamped = Vec::new();
        let mut state = VehicleState::default();
        for record in &log.records {
            if let Some(s) = telemetry.frame(record.wall_us, &record.frame) {
                state.update(&s.reading);
                stamped.push(s);
            }
        }
        let recent = log
            .records
            .last()
            .is_some_and(|r| now_us.saturating_sub(r.wall_us) <= within.as_micros() as u64);
        let same_vehicle =
            telemetry.autopilot().is_some() && telemetry.autopilot() == self.watch.autopilot();
        if !(recent && same_vehicle && state.armed == Some(true)) {
            return false;
        }
        let (mut recorder, _) = match Recorder::resume(&dir, now_us, Default::default()) {
            Ok(r) => r,
            Err(e) => {
                tracing::warn!("not resuming {}: {e}", dir.display());
                return false;
            }
        };
        for s in &stamped {
            recorder.restore(s);
        }
        let name = flight_name(&dir);
        let plan = crate::flightlog::recorder::read_flight_plan(&dir)
            .ok()
            .or_else(|| self.plan.clone());
        let mut open = Open {
            name: name.clone(),
            recorder,
            telemetry,
            stamped,
            segmenter: None,
            announced: 0,
            ends_at_us: None,
            failed: false,
            repricer: None,
        };
        if let Some(plan) = plan {
            match Segmenter::new(plan, self.cfg.segment) {
                Ok(mut seg) => {
                    for s in &open.stamped {
                        seg.push(s);
                    }
                    // Parts completed and guard notes made before the cut were announced by
                    // the run that recorded them.
                    open.announced = seg.completed().len();
                    seg.take_guard_notes();
                    open.segmenter = Some(seg);
                }
                Err(e) => fail(&mut open, &self.events, e.to_string()),
            }
        }
        tracing::info!(
            "resuming the recording of flight {name} ({} frames already logged)",
            log.records.len()
        );
        let _ = self.events.send(FlightEvent::Started {
            flight: name,
            dir,
            resumed: true,
        });
        for frame in std::mem::take(&mut self.preroll) {
            record(&mut open, &self.events, &frame);
        }
        self.open = Some(open);
        true
    }

    /// Ends the flight in progress, if any: the segmenter finished, report.json written, files
    /// closed; the plan it used is used up.
    fn end_flight(&mut self, now_us: u64) {
        let Some(mut open) = self.open.take() else {
            return;
        };
        self.plan = None;
        self.repricer = None;
        let report = open.segmenter.as_mut().map(|seg| {
            seg.finish();
            FlightReport::build(&open.name, seg)
        });
        announce(&mut open, &self.events);
        let dir = open.recorder.dir().to_path_buf();
        if let Some(report) = &report {
            if let Err(e) = write_report(&dir, report) {
                fail(&mut open, &self.events, e.to_string());
            }
        }
        let _ = open.recorder.tick(now_us);
        if let Err(e) = open.recorder.close() {
            let _ = self.events.send(FlightEvent::Failed {
                flight: open.name.clone(),
                error: e.to_string(),
            });
        }
        // Written before the end is announced: whoever sees it sees the flight in the ledger.
        // This is the recorder's own thread, never the async runtime's.
        if let (Some(spec), Some(_)) = (&self.cfg.ledger, &report) {
            super::ledger::write_flight_or_warn(spec, &dir);
        }
        let _ = self.events.send(FlightEvent::Ended {
            flight: open.name,
            dir,
            report: report.map(Box::new),
        });
        self.publish();
    }
}

/// Logs one frame of the open flight and feeds its reading to the segmenter.
fn record(open: &mut Open, events: &broadcast::Sender<FlightEvent>, frame: &Frame) {
    let stamped = open.telemetry.frame(frame.wall_us, &frame.bytes);
    if !open.failed {
        if let Err(e) = open
            .recorder
            .record(frame.wall_us, &frame.bytes, stamped.as_ref())
        {
            fail(open, events, e.to_string());
        }
    }
    if let Some(s) = stamped {
        if let Some(seg) = open.segmenter.as_mut() {
            seg.push(&s);
        }
        if matches!(s.reading, Reading::Wind(_)) {
            reprice(open, events);
        }
        open.stamped.push(s);
        announce(open, events);
    }
}

/// Prices the rest of the flight again when the wind estimate says so (and a repricer was
/// given with the plan): the segmenter and its guard take it, repriced.jsonl keeps it for the
/// replay, and it is announced. A rest that cannot be priced (a wind the vehicle cannot fly in)
/// keeps its old prices, with a warning.
fn reprice(open: &mut Open, events: &broadcast::Sender<FlightEvent>) {
    let (Some(seg), Some(repricer)) = (open.segmenter.as_mut(), open.repricer.as_ref()) else {
        return;
    };
    let Some((wind, from_point)) = seg.take_reprice_due() else {
        return;
    };
    let mut repricing = match repricer(seg.plan(), wind, from_point) {
        Ok(r) => r,
        Err(e) => {
            tracing::warn!(
                "flight {}: the wind is now {:.1} m/s from {:.0} deg and the rest of the flight could not be priced in it ({e}): its old prices stay",
                open.name,
                wind.speed_m_s,
                wind.from_deg
            );
            return;
        }
    };
    repricing.t_s = seg.now_s();
    if !seg.reprice(repricing.clone()) {
        tracing::warn!(
            "flight {}: a repricing that does not fit the plan",
            open.name
        );
        return;
    }
    let note = RepricedNote::of(seg.plan(), &repricing);
    if !open.failed {
        if let Err(e) = open.recorder.append_repricing(&repricing) {
            fail(open, events, e.to_string());
        }
    }
    let _ = events.send(FlightEvent::Repriced {
        flight: open.name.clone(),
        repriced: note,
    });
}

/// Sends an event for every guard note and every part completed since the last call.
fn announce(open: &mut Open, events: &broadcast::Sender<FlightEvent>) {
    let Some(seg) = open.segmenter.as_mut() else {
        return;
    };
    for note in seg.take_guard_notes() {
        let _ = events.send(FlightEvent::Guard {
            flight: open.name.clone(),
            note,
        });
    }
    let completed = seg.completed();
    if completed.len() <= open.announced {
        return;
    }
    let report = FlightReport::build(&open.name, seg);
    for segment in &completed[open.announced..] {
        if let Some(part) = report
            .parts()
            .find(|p| p.start_s == segment.start_s && p.end_s == segment.end_s)
        {
            let _ = events.send(FlightEvent::Part {
                flight: open.name.clone(),
                kind: segment.kind,
                part: part.clone(),
            });
        }
    }
    open.announced = completed.len();
}

fn fail(open: &mut Open, events: &broadcast::Sender<FlightEvent>, error: String) {
    tracing::error!("flight {}: recording failed: {error}", open.name);
    open.failed = true;
    let _ = events.send(FlightEvent::Failed {
        flight: open.name.clone(),
        error,
    });
}

/// The flight directories under `log_dir`, oldest first (by name: they start with their UTC
/// start time).
pub fn flight_dirs(log_dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(log_dir)?
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| crate::flightlog::recorder::is_flight_dir(p))
        .collect();
    dirs.sort();
    Ok(dirs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::energy::Flag;
    use crate::flightlog::segment::SegmentKind;
    use crate::flightlog::synthetic::{square_plan, SyntheticConfig, SyntheticFlight};
    use crate::link::telemetry::{analyse_flight_dir, encode, frame_bytes};
    use crate::link::Flavour;

    /// The frames PX4 would send of the scripted flight (each message at its wall time).
    fn frames(flight: &SyntheticFlight) -> Vec<Frame> {
        flight
            .messages
            .iter()
            .enumerate()
            .map(|(k, m)| Frame {
                wall_us: m.wall_us,
                outgoing: false,
                bytes: frame_bytes(
                    &mavlink::MavHeader {
                        system_id: 1,
                        component_id: 1,
                        sequence: k as u8,
                    },
                    &encode(&m.reading, Flavour::Px4),
                ),
            })
            .collect()
    }

    fn state(log_dir: &Path, resume: bool) -> (State, broadcast::Receiver<FlightEvent>) {
        let (events, rx) = broadcast::channel(4096);
        let (live_tx, _) = watch::channel(Live::default());
        let cfg = RecorderConfig {
            resume_within: resume.then(|| Duration::from_secs(60)),
            ..RecorderConfig::new(log_dir)
        };
        (State::new(cfg, events, live_tx), rx)
    }

    fn drain(rx: &mut broadcast::Receiver<FlightEvent>) -> Vec<FlightEvent> {
        std::iter::from_fn(|| rx.try_recv().ok()).collect()
    }

    #[test]
    fn a_recorder_restarted_mid_flight_goes_on_in_the_same_directory_and_reports_as_a_replay() {
        let log = tempfile::tempdir().expect("temp dir");
        let plan = square_plan();
        let flight = SyntheticFlight::fly(&plan, &SyntheticConfig::default());
        let frames = frames(&flight);
        let leg1 = flight.part(SegmentKind::Leg(1)).copied().expect("leg 1");
        let cut_s = leg1.start_s + 0.5 * (leg1.end_s - leg1.start_s);
        let cut = flight
            .messages
            .iter()
            .position(|m| m.t_s >= cut_s)
            .expect("cut inside the flight");
        // The first run records up to the cut and dies without closing anything (as SIGKILL:
        // nothing flushed by a destructor either).
        let (mut first, mut rx) = state(log.path(), false);
        first.set_plan(plan.clone(), None);
        for frame in &frames[..cut] {
            first.frame(frame.clone());
        }
        let started = drain(&mut rx);
        assert!(matches!(
            started.first(),
            Some(FlightEvent::Started { resumed: false, .. })
        ));
        std::mem::forget(first);
        // Two seconds of telemetry are lost while emplan restarts.
        let restart = flight
            .messages
            .iter()
            .position(|m| m.t_s >= cut_s + 2.0)
            .expect("restart inside the flight");
        let (mut second, mut rx) = state(log.path(), true);
        for frame in &frames[restart..] {
            second.frame(frame.clone());
        }
        second.end_flight(frames.last().expect("frames").wall_us + 1_000_000);
        let events = drain(&mut rx);
        let Some(FlightEvent::Started { dir, resumed, .. }) = events.first() else {
            panic!("no start: {events:?}");
        };
        assert!(*resumed);
        let dirs = flight_dirs(log.path()).expect("log dir");
        assert_eq!(dirs, vec![dir.clone()], "one flight directory");
        let Some(FlightEvent::Ended {
            report: Some(report),
            ..
        }) = events.last()
        else {
            panic!("no report: {events:?}");
        };
        assert!(report.complete, "{:?}", report.flags);
        assert_eq!(report.legs.len(), plan.points.len());
        // Parts finished before the cut were announced by the first run only.
        let parts = events
            .iter()
            .filter(|e| matches!(e, FlightEvent::Part { .. }))
            .count();
        assert!(parts > 0 && parts < report.parts().count(), "{parts}");
        // The gap is in leg 1, flagged; the report is what a replay of the whole log gives.
        assert!(report.legs[1].flags.contains(&Flag::TelemetryGap));
        let replayed = analyse_flight_dir(dir, SegmentConfig::default()).expect("replays");
        assert_eq!(replayed.report, **report);
        let on_disk = crate::flightlog::recorder::read_report(dir).expect("report.json");
        assert!(on_disk.complete);
    }

    /// Records the whole square flight with `cfg`: its events.
    fn record_square(cfg: RecorderConfig) -> Vec<FlightEvent> {
        let flight = SyntheticFlight::fly(&square_plan(), &SyntheticConfig::default());
        let frames = frames(&flight);
        let (events, mut rx) = broadcast::channel(4096);
        let (live_tx, _) = watch::channel(Live::default());
        let mut state = State::new(cfg, events, live_tx);
        state.set_plan(square_plan(), None);
        for frame in &frames {
            state.frame(frame.clone());
        }
        state.end_flight(frames.last().expect("frames").wall_us + 1_000_000);
        drain(&mut rx)
    }

    #[test]
    fn a_flight_with_its_report_is_in_the_ledger_beside_it_when_its_end_is_announced() {
        let log = tempfile::tempdir().expect("temp dir");
        let events = record_square(RecorderConfig::new(log.path()));
        let Some(FlightEvent::Ended { dir, .. }) = events.last() else {
            panic!("no end: {events:?}");
        };
        let spec = super::super::ledger::default_spec(log.path());
        let mut ledger = crate::ledger::Ledger::open_existing(&spec).expect("made beside it");
        let records = ledger.flights(&Default::default()).expect("listed");
        assert_eq!(records.len(), 1);
        assert_eq!(
            records[0].id,
            crate::ledger::record::from_dir(dir).unwrap().id
        );
    }

    #[test]
    fn a_ledger_that_cannot_be_written_loses_nothing_of_the_flight() {
        let log = tempfile::tempdir().expect("temp dir");
        // A directory where the ledger's file should be: it cannot be opened.
        let blocked = log.path().join("blocked.sqlite");
        std::fs::create_dir(&blocked).expect("made");
        let cfg = RecorderConfig::new(log.path().join("flights"))
            .with_ledger(Some(LedgerSpec::Sqlite(blocked.clone())));
        let events = record_square(cfg);
        let Some(FlightEvent::Ended {
            dir,
            report: Some(report),
            ..
        }) = events.last()
        else {
            panic!("no report: {events:?}");
        };
        assert!(report.complete);
        assert!(crate::flightlog::recorder::read_report(dir).is_ok_and(|r| r.complete));
        assert!(blocked.is_dir(), "nothing written in its place");
        assert!(!log.path().join("flights").join("ledger.sqlite").exists());
    }

    #[test]
    fn a_flight_that_ended_or_a_log_too_old_is_not_resumed() {
        let log = tempfile::tempdir().expect("temp dir");
        let flight = SyntheticFlight::fly(&square_plan(), &SyntheticConfig::default());
        let frames = frames(&flight);
        let (mut first, _rx) = state(log.path(), false);
        first.set_plan(square_plan(), None);
        for frame in &frames {
            first.frame(frame.clone());
        }
        first.end_flight(frames.last().expect("frames").wall_us + 1_000_000);
        let mid = frames.len() / 2;
        // Armed at the first heartbeat, but the newest flight has its complete report.
        let (mut second, mut rx) = state(log.path(), true);
        for frame in &frames[mid..mid + 50] {
            second.frame(frame.clone());
        }
        assert!(matches!(
            drain(&mut rx).first(),
            Some(FlightEvent::Started { resumed: false, .. })
        ));
        std::mem::forget(second);
        assert_eq!(flight_dirs(log.path()).expect("log dir").len(), 2);
        // The newest one was cut off, but an hour ago.
        let (mut third, mut rx) = state(log.path(), true);
        for frame in &frames[mid..mid + 50] {
            let mut frame = frame.clone();
            frame.wall_us += 3_600_000_000;
            third.frame(frame);
        }
        assert!(matches!(
            drain(&mut rx).first(),
            Some(FlightEvent::Started { resumed: false, .. })
        ));
        std::mem::forget(third);
        assert_eq!(flight_dirs(log.path()).expect("log dir").len(), 3);
    }
}
