//! Running the small command machines on a link: starting a mission (`flight::Start`) and asking
//! for telemetry rates (`telemetry::StreamRequests`). Both are sans-IO
//! (`start/handle/tick` return the messages to send); this feeds them the target autopilot's
//! messages and a 50 ms tick.

use std::time::Duration;

use tokio::sync::broadcast::error::RecvError;
use tokio::time::Instant;

use super::connection::{Autopilot, Identity, Link};
use super::flight::Start;
use super::mav::MavMessage;
use super::telemetry::{default_streams, RequestOutcome, StreamConfig, StreamRequests};
use super::LinkError;

/// A machine that talks to the autopilot in commands until it is done.
pub trait CommandMachine {
    fn start(&mut self, now: Duration) -> Vec<MavMessage>;
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage>;
    fn tick(&mut self, now: Duration) -> Vec<MavMessage>;
    fn done(&self) -> bool;
}

impl CommandMachine for Start {
    fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        Start::start(self, now)
    }
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        Start::handle(self, now, message)
    }
    fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        Start::tick(self, now)
    }
    fn done(&self) -> bool {
        self.finished().is_some()
    }
}

impl CommandMachine for StreamRequests {
    fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        StreamRequests::start(self, now)
    }
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        StreamRequests::handle(self, now, message)
    }
    fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        StreamRequests::tick(self, now)
    }
    fn done(&self) -> bool {
        self.finished()
    }
}

const TICK: Duration = Duration::from_millis(50);

/// Runs `machine` against `target` until it is done.
pub async fn drive<M: CommandMachine>(
    link: &Link,
    target: &Autopilot,
    machine: &mut M,
) -> Result<(), LinkError> {
    let mut rx = link.subscribe();
    let t0 = Instant::now();
    let mut out = machine.start(t0.elapsed());
    let mut tick = tokio::time::interval(TICK);
    loop {
        for message in out.drain(..) {
            link.send(&message).await?;
        }
        if machine.done() {
            return Ok(());
        }
        out = tokio::select! {
            received = rx.recv() => match received {
                Ok((header, message)) if header.system_id == u32::from(target.system_id) => {
                    machine.handle(t0.elapsed(), &message)
                }
                Ok(_) | Err(RecvError::Lagged(_)) => Vec::new(),
                Err(RecvError::Closed) => {
                    return Err(LinkError::Closed("the receive task ended".into()))
                }
            },
            _ = tick.tick() => machine.tick(t0.elapsed()),
        };
    }
}

/// Asks `target` for the telemetry the flight log needs (battery and position at 10 Hz,
/// mission progress and landed state at 2 Hz) and returns when every request has an answer (or
/// ran out of retries); the names of the ones not accepted are logged and returned.
pub async fn request_streams(link: &Link, target: &Autopilot) -> Result<Vec<String>, LinkError> {
    let identity = Identity::default();
    let cfg = StreamConfig {
        target_system: target.system_id,
        target_component: target.component_id,
        own_system: identity.system_id,
        own_component: identity.component_id,
        ..StreamConfig::default()
    };
    let mut requests = StreamRequests::new(cfg, default_streams());
    drive(link, target, &mut requests).await?;
    let refused: Vec<String> = requests
        .outcomes()
        .into_iter()
        .filter(|(_, outcome)| *outcome != RequestOutcome::Accepted)
        .map(|(request, outcome)| format!("{} ({outcome:?})", request.name))
        .collect();
    if refused.is_empty() {
        tracing::info!("telemetry rates accepted by the autopilot");
    } else {
        tracing::warn!(
            "telemetry rates not accepted: {}; recording what arrives",
            refused.join(", ")
        );
    }
    Ok(refused)
}

/// Asks for the telemetry again after every reconnect of the link (the first request is
/// [`request_streams`]'). Never returns unless the link fails: run it beside the work that needs
/// the streams (`tokio::select!`).
pub async fn keep_streams(link: &Link, target: &Autopilot) -> Result<(), LinkError> {
    let mut reconnects = link.reconnects();
    loop {
        if reconnects.changed().await.is_err() {
            // The link is gone; nothing more to ask.
            std::future::pending::<()>().await;
        }
        request_streams(link, target).await?;
    }
}
