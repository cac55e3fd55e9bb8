//! What the service tells its clients as it happens: the server-sent events (JSON objects with a
//! `type`), each serialised once and broadcast to every follower of `/api/events`, and the state
//! a page needs on arrival (the flight in progress with its parts so far, the battery over the
//! last minutes, the latest telemetry).
//!
//! Events: `telemetry` (at most 5 Hz: link, armed, mode, mission item, landed state, battery
//! V/I/P, position, the part in progress with its energy so far), `part` (a part of the flight
//! completed, predicted vs measured), `flight_started`, `flight_ended` (with the report),
//! `recording_failed`, `mission_planned`, `mission_error`, `mission_removed`, `link`, `upload`,
//! `start`, and `lagged` (to one follower that fell behind: it missed that many events).
//!
//! The recorder never waits for any of this: its events and its latest state reach this module
//! through a broadcast and a watch channel that drop or overwrite rather than block.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde::Serialize;
use tokio::sync::{broadcast, watch};

use super::vehicle::{LinkState, LinkStatus};
use crate::flightlog::report::{PartJson, PartReport, ReportJson};
use crate::flightlog::segment::SegmentKind;
use crate::link::connection::wall_us;
use crate::session::recorder::{BatteryNow, FlightEvent, Live};

/// How long the battery history reaches back.
pub const BATTERY_HISTORY: Duration = Duration::from_secs(600);

/// One event.
// An event is built, serialised once and dropped, a few a second: its size does not matter,
// and boxing its largest views only moves the lint to the next largest.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Event {
    Telemetry(TelemetryJson),
    Part(PartEventJson),
    FlightStarted {
        flight: String,
        dir: PathBuf,
        resumed: bool,
    },
    FlightEnded {
        flight: String,
        dir: PathBuf,
        /// None when nothing was known to measure the flight against.
        report: Option<ReportJson>,
    },
    RecordingFailed {
        flight: String,
        error: String,
    },
    MissionPlanned(serde_json::Value),
    MissionError(serde_json::Value),
    MissionRemoved {
        name: String,
    },
    Link(LinkStatus),
    /// An upload through the service ended: `result` is the upload document or the failure
    /// document (`ok` tells which).
    Upload {
        name: String,
        ok: bool,
        result: serde_json::Value,
    },
    /// A start through the service ended.
    Start {
        ok: bool,
        error: Option<String>,
    },
    /// Sent to one follower only: it fell behind and missed `missed` events.
    Lagged {
        missed: u64,
    },
}

/// The name of a part's kind and the index of its point (legs, settles, hovers).
pub fn kind_name(kind: SegmentKind) -> (&'static str, Option<usize>) {
    match kind {
        SegmentKind::Takeoff => ("takeoff", None),
        SegmentKind::Leg(k) => ("leg", Some(k)),
        SegmentKind::Settle(k) => ("settle", Some(k)),
        SegmentKind::Hover(k) => ("hover", Some(k)),
        SegmentKind::Landing => ("landing", None),
    }
}

/// A part of a flight: its kind (`takeoff`, `leg`, `settle`, `hover`, `landing`), the index of
/// the planned point it ends at, and the report's fields (kJ).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PartEventJson {
    pub flight: String,
    pub kind: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub index: Option<usize>,
    #[serde(flatten)]
    pub part: PartJson,
}

impl PartEventJson {
    pub fn new(flight: &str, kind: SegmentKind, part: &PartReport) -> PartEventJson {
        let (kind, index) = kind_name(kind);
        PartEventJson {
            flight: flight.to_string(),
            kind,
            index,
            part: PartJson::from(part),
        }
    }
}

/// Where the vehicle is.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PositionJson {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_amsl_m: f64,
    pub relative_alt_m: f64,
    pub speed_m_s: f64,
}

/// The flight being recorded, as a telemetry event carries it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LiveFlightJson {
    pub flight: String,
    /// Vehicle time since the flight's log began.
    pub t_s: f64,
    /// Parts completed.
    pub parts: usize,
    /// The part in progress, with its energy so far.
    pub in_progress: Option<PartEventJson>,
}

/// The latest state of link and vehicle.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TelemetryJson {
    /// When the service published it (unix ms).
    pub wall_ms: u64,
    pub link: LinkState,
    pub armed: Option<bool>,
    pub mode: Option<String>,
    pub mission_seq: Option<u16>,
    pub landed: Option<&'static str>,
    pub battery: Option<BatteryNow>,
    pub position: Option<PositionJson>,
    pub flight: Option<LiveFlightJson>,
    /// Frames received and sent on the link so far.
    pub frames: u64,
}

impl TelemetryJson {
    pub fn new(live: &Live, link: LinkState) -> TelemetryJson {
        let v = &live.vehicle;
        TelemetryJson {
            wall_ms: wall_us() / 1000,
            link,
            armed: v.armed,
            mode: v.mode.as_ref().map(|m| m.name().to_string()),
            mission_seq: v.mission_seq,
            landed: v.landed.map(|l| l.name()),
            battery: live.battery,
            position: v.position.map(|p| PositionJson {
                lat_deg: p.lat_deg,
                lon_deg: p.lon_deg,
                alt_amsl_m: p.alt_amsl_m,
                relative_alt_m: p.relative_alt_m,
                speed_m_s: p.speed_m_s(),
            }),
            flight: live.flight.as_ref().map(|f| LiveFlightJson {
                flight: f.flight.clone(),
                t_s: f.t_s,
                parts: f.parts,
                in_progress: f
                    .in_progress
                    .as_ref()
                    .map(|(kind, part)| PartEventJson::new(&f.flight, *kind, part)),
            }),
            frames: live.frames,
        }
    }
}

/// One point of the battery history.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BatteryPoint {
    pub wall_ms: u64,
    pub voltage_v: Option<f64>,
    pub current_a: Option<f64>,
    pub power_w: Option<f64>,
}

/// The flight in progress (or the last one), with the parts completed so far.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FlightView {
    pub flight: String,
    pub dir: PathBuf,
    pub resumed: bool,
    pub recording: bool,
    pub parts: Vec<PartEventJson>,
}

#[derive(Debug, Default)]
struct HubState {
    battery: VecDeque<BatteryPoint>,
    flight: Option<FlightView>,
    telemetry: Option<TelemetryJson>,
}

/// The events and the state behind them, shared by the service's tasks and handlers (the lock
/// is held only to copy in or out, never across an await).
#[derive(Debug)]
pub struct Hub {
    tx: broadcast::Sender<Arc<str>>,
    state: Mutex<HubState>,
}

impl Default for Hub {
    fn default() -> Self {
        Hub::new()
    }
}

impl Hub {
    pub fn new() -> Hub {
        Hub {
            tx: broadcast::channel(4096).0,
            state: Mutex::new(HubState::default()),
        }
    }

    /// Sends `event` to every follower (serialised once).
    pub fn publish(&self, event: &Event) {
        match serde_json::to_string(event) {
            Ok(text) => {
                let _ = self.tx.send(Arc::from(text));
            }
            Err(e) => tracing::error!("event not serialised: {e}"),
        }
    }

    /// The events from now on, as JSON text.
    pub fn subscribe(&self) -> broadcast::Receiver<Arc<str>> {
        self.tx.subscribe()
    }

    fn with<T>(&self, f: impl FnOnce(&mut HubState) -> T) -> T {
        match self.state.lock() {
            Ok(mut state) => f(&mut state),
            Err(poisoned) => f(&mut poisoned.into_inner()),
        }
    }

    /// The battery since `since_ms` (unix ms; None: all kept, the last ten minutes).
    pub fn battery_history(&self, since_ms: Option<u64>) -> Vec<BatteryPoint> {
        self.with(|s| {
            s.battery
                .iter()
                .filter(|p| since_ms.is_none_or(|t| p.wall_ms > t))
                .copied()
                .collect()
        })
    }

    /// The flight in progress, or the last one flown since the service started.
    pub fn flight(&self) -> Option<FlightView> {
        self.with(|s| s.flight.clone())
    }

    /// The latest telemetry.
    pub fn telemetry(&self) -> Option<TelemetryJson> {
        self.with(|s| s.telemetry.clone())
    }

    fn telemetry_in(&self, telemetry: TelemetryJson) {
        let event = Event::Telemetry(telemetry.clone());
        self.with(|s| {
            if let Some(b) = telemetry.battery {
                s.battery.push_back(BatteryPoint {
                    wall_ms: telemetry.wall_ms,
                    voltage_v: b.voltage_v,
                    current_a: b.current_a,
                    power_w: b.power_w,
                });
                let keep_ms = BATTERY_HISTORY.as_millis() as u64;
                while s
                    .battery
                    .front()
                    .is_some_and(|p| telemetry.wall_ms.saturating_sub(p.wall_ms) > keep_ms)
                {
                    s.battery.pop_front();
                }
            }
            s.telemetry = Some(telemetry);
        });
        self.publish(&event);
    }

    fn flight_event(&self, event: FlightEvent) {
        let out = match event {
            FlightEvent::Started {
                flight,
                dir,
                resumed,
            } => {
                self.with(|s| {
                    s.flight = Some(FlightView {
                        flight: flight.clone(),
                        dir: dir.clone(),
                        resumed,
                        recording: true,
                        parts: Vec::new(),
                    })
                });
                Event::FlightStarted {
                    flight,
                    dir,
                    resumed,
                }
            }
            FlightEvent::Part { flight, kind, part } => {
                let part = PartEventJson::new(&flight, kind, &part);
                self.with(|s| {
                    if let Some(view) = s.flight.as_mut().filter(|v| v.flight == flight) {
                        // A plan set mid-flight announces every part again, measured anew.
                        view.parts
                            .retain(|p| (p.kind, p.index) != (part.kind, part.index));
                        view.parts.push(part.clone());
                    }
                });
                Event::Part(part)
            }
            FlightEvent::Ended {
                flight,
                dir,
                report,
            } => {
                self.with(|s| {
                    if let Some(view) = s.flight.as_mut().filter(|v| v.flight == flight) {
                        view.recording = false;
                    }
                });
                Event::FlightEnded {
                    flight,
                    dir,
                    report: report.map(|r| r.json()),
                }
            }
            FlightEvent::Failed { flight, error } => Event::RecordingFailed { flight, error },
        };
        self.publish(&out);
    }
}

/// Forwards the recorder's flight events and its latest state (at most 5 Hz, the rate it
/// publishes at) to the hub until `stop`, logging each flight in a span of its own.
pub async fn forward(
    hub: Arc<Hub>,
    mut flights: broadcast::Receiver<FlightEvent>,
    mut live: watch::Receiver<Live>,
    mut link: watch::Receiver<LinkStatus>,
    mut stop: watch::Receiver<bool>,
) {
    let mut span: Option<tracing::Span> = None;
    let mut last_state = link.borrow().state;
    loop {
        tokio::select! {
            _ = stop.changed() => return,
            event = flights.recv() => match event {
                Ok(event) => {
                    log_flight_event(&mut span, &event);
                    hub.flight_event(event);
                }
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    tracing::warn!("{n} flight events missed by the event stream")
                }
                Err(broadcast::error::RecvError::Closed) => return,
            },
            changed = live.changed() => {
                if changed.is_err() {
                    return;
                }
                let telemetry = TelemetryJson::new(&live.borrow_and_update(), last_state);
                hub.telemetry_in(telemetry);
            }
            changed = link.changed() => {
                if changed.is_err() {
                    return;
                }
                let status = link.borrow_and_update().clone();
                last_state = status.state;
                hub.publish(&Event::Link(status));
            }
        }
    }
}

fn log_flight_event(span: &mut Option<tracing::Span>, event: &FlightEvent) {
    match event {
        FlightEvent::Started {
            flight,
            dir,
            resumed,
        } => {
            let s = tracing::info_span!("flight", flight = %flight);
            s.in_scope(|| {
                tracing::info!(
                    resumed = *resumed,
                    "recording{} to {}",
                    if *resumed { " again" } else { "" },
                    dir.display()
                )
            });
            *span = Some(s);
        }
        FlightEvent::Part { kind, part, .. } => {
            let (name, _) = kind_name(*kind);
            let s = span.clone().unwrap_or_else(tracing::Span::none);
            s.in_scope(|| {
                tracing::info!(
                    part = name,
                    from = %super::escape_controls(&part.from),
                    to = %super::escape_controls(&part.to),
                    predicted_kj = part.predicted_j.map(|j| j / 1000.0),
                    measured_kj = part.measured_j.map(|j| j / 1000.0),
                    duration_s = part.duration_s,
                    "part done"
                )
            });
        }
        FlightEvent::Ended { report, dir, .. } => {
            let s = span.take().unwrap_or_else(tracing::Span::none);
            s.in_scope(|| match report {
                Some(r) => tracing::info!(
                    complete = r.complete,
                    legs = r.legs.len(),
                    predicted_kj = r.predicted_j.map(|j| j / 1000.0),
                    measured_kj = r.measured_j.map(|j| j / 1000.0),
                    "flight ended; report in {}",
                    dir.display()
                ),
                None => tracing::info!(
                    "flight ended without a plan to measure it against; log in {}",
                    dir.display()
                ),
            });
        }
        FlightEvent::Failed { error, .. } => {
            let s = span.clone().unwrap_or_else(tracing::Span::none);
            s.in_scope(|| tracing::error!("recording failed: {error}"));
        }
    }
}
