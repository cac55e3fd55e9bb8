//! Running the small command machines on a link: starting a mission (`flight::Start`), asking
//! for telemetry rates (`telemetry::StreamRequests`) and reading parameters by name
//! (`params::ParamReads`), sending the vehicle home (`home::ReturnHome`), learning where it is
//! (`locate::Locate`). All are sans-IO
//! (`start/handle/tick` return the messages to send); this feeds them the target autopilot's
//! messages and a 50 ms tick. [`heartbeats`] follows the autopilot's heartbeat (who, armed,
//! when last heard) for a process that holds a link all day.

use std::time::Duration;

use tokio::sync::broadcast::error::RecvError;
use tokio::time::Instant;

use super::connection::{Autopilot, Identity, Link};
use super::flavour::Flavour;
use super::flight::Start;
use super::home::{ReturnConfig, ReturnError, ReturnHome};
use super::locate::{Locate, LocateConfig, LocateError, Located};
use super::mav::MavMessage;
use super::params::{ParamConfig, ParamReads};
use super::telemetry::{
    default_streams, is_autopilot, RequestOutcome, StreamConfig, StreamRequest, StreamRequests,
};
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

impl CommandMachine for ReturnHome {
    fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        ReturnHome::start(self, now)
    }
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        ReturnHome::handle(self, now, message)
    }
    fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        ReturnHome::tick(self, now)
    }
    fn done(&self) -> bool {
        self.finished().is_some()
    }
}

impl CommandMachine for Locate {
    fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        Locate::start(self, now)
    }
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        Locate::handle(self, now, message)
    }
    fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        Locate::tick(self, now)
    }
    fn done(&self) -> bool {
        self.finished().is_some()
    }
}

impl CommandMachine for super::support::AskCapabilities {
    fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        super::support::AskCapabilities::start(self, now)
    }
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        super::support::AskCapabilities::handle(self, now, message)
    }
    fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        super::support::AskCapabilities::tick(self, now)
    }
    fn done(&self) -> bool {
        self.finished().is_some()
    }
}

/// What `target` declares it holds besides a mission (its AUTOPILOT_VERSION capability bits;
/// nothing when it sends none within `cfg`'s budget).
pub async fn capabilities(
    link: &Link,
    target: &Autopilot,
    cfg: super::support::AskConfig,
) -> Result<super::support::Capabilities, LinkError> {
    let mut machine = super::support::AskCapabilities::new(*target, cfg);
    drive(link, target, &mut machine).await?;
    Ok(machine
        .finished()
        .unwrap_or_else(super::support::Capabilities::undeclared))
}

impl CommandMachine for super::pack::AskPack {
    fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        super::pack::AskPack::start(self, now)
    }
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        super::pack::AskPack::handle(self, now, message)
    }
    fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        super::pack::AskPack::tick(self, now)
    }
    fn done(&self) -> bool {
        self.finished().is_some()
    }
}

/// The name `target`'s pack gives itself (SMART_BATTERY_INFO's serial number, else its device
/// name), None when it names none within `cfg`'s budget ([`super::pack`]).
pub async fn pack_named(
    link: &Link,
    target: &Autopilot,
    cfg: super::pack::AskPackConfig,
) -> Result<Option<String>, LinkError> {
    let mut machine = super::pack::AskPack::new(*target, cfg);
    drive(link, target, &mut machine).await?;
    Ok(machine.finished().flatten())
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

impl CommandMachine for ParamReads {
    fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        ParamReads::start(self, now)
    }
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        ParamReads::handle(self, now, message)
    }
    fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        ParamReads::tick(self, now)
    }
    fn done(&self) -> bool {
        self.finished()
    }
}

impl CommandMachine for super::wind::ListenWind {
    fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        super::wind::ListenWind::start(self, now)
    }
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        super::wind::ListenWind::handle(self, now, message)
    }
    fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        super::wind::ListenWind::tick(self, now)
    }
    fn done(&self) -> bool {
        super::wind::ListenWind::done(self)
    }
}

/// `target`'s own wind estimate (WIND_COV or WIND, asked for at 1 Hz first), or None when it sends none within
/// `budget` (see [`super::wind`]).
pub async fn listen_wind(
    link: &Link,
    target: &Autopilot,
    budget: Duration,
) -> Result<Option<crate::physics::Wind>, LinkError> {
    request_wind_stream(link, target).await?;
    let mut machine = super::wind::ListenWind::new(budget);
    drive(link, target, &mut machine).await?;
    Ok(machine.finished())
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

/// Sends `target` home (MAV_CMD_NAV_RETURN_TO_LAUNCH) and returns once it is acknowledged or
/// the autopilot shows its return mode; the outer error is the link's, the inner the autopilot's
/// answer.
pub async fn return_home(
    link: &Link,
    target: &Autopilot,
) -> Result<Result<(), ReturnError>, LinkError> {
    let mut machine = ReturnHome::new(*target, ReturnConfig::default());
    drive(link, target, &mut machine).await?;
    Ok(machine
        .finished()
        .cloned()
        .unwrap_or(Err(ReturnError::Timeout {
            budget_s: ReturnConfig::default().budget.as_secs_f64(),
            attempts: 0,
            statustext: None,
        })))
}

/// Learns where `target` is: its home, else its position (see [`Locate`]); the outer error is
/// the link's, the inner says that neither came within `cfg`'s budget.
pub async fn locate(
    link: &Link,
    target: &Autopilot,
    cfg: LocateConfig,
) -> Result<Result<Located, LocateError>, LinkError> {
    let mut machine = Locate::new(*target, cfg);
    drive(link, target, &mut machine).await?;
    Ok(machine
        .finished()
        .cloned()
        .unwrap_or(Err(LocateError::Timeout {
            budget_s: cfg.budget.as_secs_f64(),
            requests: 0,
            answer: None,
        })))
}

/// Asks `target` for the telemetry the flight log needs (battery and position at 10 Hz,
/// mission progress and landed state at 2 Hz) and returns when every request has an answer (or
/// ran out of retries); the names of the ones not accepted are logged and returned.
pub async fn request_streams(link: &Link, target: &Autopilot) -> Result<Vec<String>, LinkError> {
    request(link, target, default_streams()).await
}

/// Asks `target` for its wind estimate at 1 Hz (PX4: WIND_COV; ArduPilot: WIND; nothing of an
/// autopilot of neither kind); a refusal is a warning, as in [`request_streams`].
async fn request_wind_stream(link: &Link, target: &Autopilot) -> Result<Vec<String>, LinkError> {
    use super::mav::{WIND_COV_DATA, WIND_DATA};
    let wind = match target.flavour {
        Flavour::Px4 => StreamRequest::of::<WIND_COV_DATA>(1.0),
        Flavour::ArduPilot => StreamRequest::of::<WIND_DATA>(1.0),
        Flavour::Generic => return Ok(Vec::new()),
    };
    request(link, target, vec![wind]).await
}

/// Asks `target` for `wanted` at their rates (MAV_CMD_SET_MESSAGE_INTERVAL, one at a time):
/// the ones it did not accept, by name, each logged.
async fn request(
    link: &Link,
    target: &Autopilot,
    wanted: Vec<StreamRequest>,
) -> Result<Vec<String>, LinkError> {
    let identity = Identity::default();
    let cfg = StreamConfig {
        target_system: target.system_id,
        target_component: target.component_id,
        own_system: identity.system_id,
        own_component: identity.component_id,
        ..StreamConfig::default()
    };
    let mut requests = StreamRequests::new(cfg, wanted);
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

/// Reads the parameters `names` from `target` (PARAM_REQUEST_READ by name, resent until
/// answered or given up): every name with its value, None when the autopilot never answered
/// (it has no such parameter, or the link lost every try).
pub async fn read_params(
    link: &Link,
    target: &Autopilot,
    names: &[&str],
) -> Result<Vec<(String, Option<f64>)>, LinkError> {
    let cfg = ParamConfig {
        target_system: target.system_id,
        target_component: target.component_id,
        flavour: target.flavour,
        ..ParamConfig::default()
    };
    let mut reads = ParamReads::new(cfg, names);
    drive(link, target, &mut reads).await?;
    Ok(reads.values())
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

/// An autopilot's heartbeat, as last heard.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Heard {
    pub autopilot: Autopilot,
    /// When it arrived.
    pub at: Instant,
    pub armed: bool,
}

/// Follows the autopilots' heartbeats on `link` (not a ground station's or another
/// component's): the latest in the returned watch, until the link closes or the task is
/// aborted.
pub fn heartbeats(
    link: &Link,
) -> (
    tokio::sync::watch::Receiver<Option<Heard>>,
    tokio::task::JoinHandle<()>,
) {
    let (tx, heard) = tokio::sync::watch::channel(None);
    let mut rx = link.subscribe();
    let task = tokio::spawn(async move {
        loop {
            match rx.recv().await {
                Ok((header, MavMessage::HEARTBEAT(hb))) if is_autopilot(&hb) => {
                    let autopilot = Autopilot {
                        system_id: u8::try_from(header.system_id).unwrap_or(u8::MAX),
                        component_id: header.component_id,
                        flavour: Flavour::from_autopilot(hb.autopilot),
                    };
                    tx.send_replace(Some(Heard {
                        autopilot,
                        at: Instant::now(),
                        armed: hb
                            .base_mode
                            .contains(super::mav::MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED),
                    }));
                }
                Ok(_) | Err(RecvError::Lagged(_)) => {}
                Err(RecvError::Closed) => return,
            }
        }
    });
    (heard, task)
}
