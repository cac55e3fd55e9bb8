//! What the service tells its clients as it happens: the server-sent events (JSON objects with a
//! `type`), each serialised once and broadcast to every follower of `/api/events`, and the state
//! a page needs on arrival (the flight in progress with its parts so far, the battery over the
//! last minutes, the latest telemetry).
//!
//! The events themselves (their types and JSON) are in `wire`.
//!
//! The recorder never waits for any of this: its events and its latest state reach this module
//! through a broadcast and a watch channel that drop or overwrite rather than block.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::sync::{broadcast, watch};

pub use super::wire::{
    kind_name, BatteryPoint, Event, FlightView, LinkState, LinkStatus, PartEventJson, TelemetryJson,
};
use crate::session::recorder::{FlightEvent, Live};

/// How long the battery history reaches back.
pub const BATTERY_HISTORY: Duration = Duration::from_secs(600);

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
                        guard_notes: Vec::new(),
                    })
                });
                Event::FlightStarted {
                    flight,
                    dir,
                    resumed,
                }
            }
            FlightEvent::Guard { flight, note } => {
                self.with(|s| {
                    if let Some(view) = s.flight.as_mut().filter(|v| v.flight == flight) {
                        view.guard_notes.push(note.clone());
                    }
                });
                Event::Guard { flight, note }
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
            FlightEvent::Repriced { flight, repriced } => Event::Repriced { flight, repriced },
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
                    part = name.name(),
                    from = %super::escape_controls(&part.from),
                    to = %super::escape_controls(&part.to),
                    predicted_kj = part.predicted_j.map(|j| j / 1000.0),
                    measured_kj = part.measured_j.map(|j| j / 1000.0),
                    duration_s = part.duration_s,
                    "part done"
                )
            });
        }
        FlightEvent::Guard { note, .. } => {
            let s = span.clone().unwrap_or_else(tracing::Span::none);
            s.in_scope(
                || tracing::warn!(verdict = %note.verdict, "energy guard: {}", note.message),
            );
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
        FlightEvent::Repriced { repriced, .. } => {
            let s = span.clone().unwrap_or_else(tracing::Span::none);
            s.in_scope(|| tracing::info!("{}", crate::flightlog::report::repriced_line(repriced)));
        }
    }
}
