//! The thin async driver of the sans-IO transfer machines: feeds them the target's messages,
//! wakes them when their clock says (no fixed tick), sends what they ask. A verified upload =
//! the mission uploaded (ACCEPTED, or the final ack lost) AND read back holding what was sent,
//! by what the autopilot keeps (`link::readback`), all within one time budget. When the final
//! ack was lost and the read-back differs, the upload may not have reached the autopilot: it is
//! tried again while time remains.

use std::time::Duration;

use tokio::time::Instant;

use super::connection::{Autopilot, Link};
use super::mav::{MavMessage, MavMissionResult, MavMissionType, MISSION_ITEM_INT_DATA};
use super::readback::{self, ReadbackError};
use super::transfer::{
    Action, Command, Download, Rto, Stage, TransferConfig, TransferError, Upload, MISSION,
};
use super::LinkError;

/// Why a machine did not complete.
#[derive(Debug, thiserror::Error)]
pub enum DriverError {
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error(transparent)]
    Transfer(#[from] TransferError),
    #[error(transparent)]
    Readback(#[from] ReadbackError),
}

/// Why a verified upload failed: the stage, whether the autopilot had accepted the mission,
/// the item concerned and the autopilot's refusal, if any.
#[derive(Debug, thiserror::Error)]
pub struct UploadError {
    /// Which list failed: "mission", "fence" or "rally points" (`list_name`).
    pub list: &'static str,
    pub stage: Stage,
    /// The autopilot's ACCEPTED ack of this mission arrived.
    pub accepted: bool,
    pub item: Option<u16>,
    pub refusal: Option<MavMissionResult>,
    /// Whole uploads tried (more than one when a read-back showed an unacknowledged upload
    /// had not arrived).
    pub attempts: u32,
    /// What went wrong (its message is this error's: not repeated as a source).
    pub cause: DriverError,
}

impl std::fmt::Display for UploadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.list != list_name(MISSION) {
            write!(f, "{}: ", self.list)?;
        }
        match &self.cause {
            DriverError::Transfer(e) => write!(f, "{e}")?,
            DriverError::Readback(e) => write!(f, "{e}")?,
            DriverError::Link(e) => write!(f, "{}: {e}", self.stage)?,
        }
        match (self.stage, self.accepted) {
            (Stage::Upload, _) => Ok(()),
            (_, true) => write!(f, " (the autopilot had accepted the {})", self.list),
            (_, false) => write!(
                f,
                " (no MISSION_ACK came: the autopilot may not hold the {})",
                self.list
            ),
        }
    }
}

/// How errors and reports name the autopilot's list of `mission_type`.
pub fn list_name(mission_type: MavMissionType) -> &'static str {
    match mission_type {
        MavMissionType::MAV_MISSION_TYPE_FENCE => "fence",
        MavMissionType::MAV_MISSION_TYPE_RALLY => "rally points",
        _ => "mission",
    }
}

/// What an upload achieved.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct UploadReport {
    pub items: usize,
    /// The autopilot's ACCEPTED ack arrived (PX4 sends it once: it may be lost).
    pub acked: bool,
    /// The read-back matched what was sent.
    pub verified: bool,
    pub upload_s: f64,
    pub verify_s: f64,
    pub count_sent: u32,
    pub items_sent: u32,
    /// Fresh starts after the autopilot abandoned a transfer (upload and read-back).
    #[serde(skip)]
    pub restarts: u32,
    /// Transient refusals waited out (ArduPilot's NO_SPACE at boot).
    #[serde(skip)]
    pub refusals: u32,
    /// The smoothed round-trip time measured, if any.
    #[serde(skip)]
    pub rtt_ms: Option<f64>,
}

/// A transfer machine the driver can run.
pub trait Machine {
    type Output;
    fn start(&mut self, now: Duration) -> Vec<Action>;
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<Action>;
    fn tick(&mut self, now: Duration) -> Vec<Action>;
    /// When `tick` is next due; None once finished.
    fn wake(&self) -> Option<Duration>;
    /// The outcome, once finished (taken: called once).
    fn outcome(&mut self) -> Option<Result<Self::Output, TransferError>>;
}

impl Machine for Upload {
    type Output = ();
    fn start(&mut self, now: Duration) -> Vec<Action> {
        Upload::start(self, now)
    }
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<Action> {
        Upload::handle(self, now, message)
    }
    fn tick(&mut self, now: Duration) -> Vec<Action> {
        Upload::tick(self, now)
    }
    fn wake(&self) -> Option<Duration> {
        Upload::wake(self)
    }
    fn outcome(&mut self) -> Option<Result<(), TransferError>> {
        self.finished().cloned()
    }
}

impl Machine for Download {
    type Output = Vec<MISSION_ITEM_INT_DATA>;
    fn start(&mut self, now: Duration) -> Vec<Action> {
        Download::start(self, now)
    }
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<Action> {
        Download::handle(self, now, message)
    }
    fn tick(&mut self, now: Duration) -> Vec<Action> {
        Download::tick(self, now)
    }
    fn wake(&self) -> Option<Duration> {
        Download::wake(self)
    }
    fn outcome(&mut self) -> Option<Result<Self::Output, TransferError>> {
        self.take_result()
    }
}

impl Machine for Command {
    type Output = ();
    fn start(&mut self, now: Duration) -> Vec<Action> {
        Command::start(self, now)
    }
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<Action> {
        Command::handle(self, now, message)
    }
    fn tick(&mut self, now: Duration) -> Vec<Action> {
        Command::tick(self, now)
    }
    fn wake(&self) -> Option<Duration> {
        Command::wake(self)
    }
    fn outcome(&mut self) -> Option<Result<(), TransferError>> {
        self.finished().cloned()
    }
}

/// Runs a machine against the autopilot `target` until it finishes.
pub async fn run<M: Machine>(
    link: &Link,
    target: &Autopilot,
    machine: &mut M,
    mut progress: impl FnMut(usize, usize),
) -> Result<M::Output, DriverError> {
    let mut rx = link.subscribe();
    let start = Instant::now();
    let mut actions = machine.start(Duration::ZERO);
    let timer = tokio::time::sleep_until(start);
    tokio::pin!(timer);
    let mut armed = None;
    loop {
        for action in actions.drain(..) {
            match action {
                Action::Send(message) => {
                    tracing::trace!(t = ?start.elapsed(), "sent {message:?}");
                    link.send(&message).await?
                }
                Action::Progress { done, total } => progress(done, total),
            }
        }
        if let Some(outcome) = machine.outcome() {
            return Ok(outcome?);
        }
        let wake = machine.wake().unwrap_or(Duration::from_secs(3600));
        if armed != Some(wake) {
            // Re-armed only when the machine's clock moved: no timer churn per message.
            timer.as_mut().reset(start + wake);
            armed = Some(wake);
        }
        actions = tokio::select! {
            biased;
            received = rx.recv() => match received {
                Ok((header, message)) if header.system_id == u32::from(target.system_id) => {
                    tracing::trace!(t = ?start.elapsed(), "received {message:?}");
                    machine.handle(start.elapsed(), &message)
                }
                Ok(_) | Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => Vec::new(),
                Err(tokio::sync::broadcast::error::RecvError::Closed) => {
                    return Err(LinkError::Closed("the receive task ended".into()).into())
                }
            },
            _ = &mut timer => {
                tracing::trace!(t = ?start.elapsed(), "tick");
                machine.tick(start.elapsed())
            }
        };
    }
}

fn remaining(budget: Duration, started: Instant) -> Duration {
    budget.saturating_sub(started.elapsed())
}

/// Uploads the mission `items` and reads them back; Ok only when the autopilot holds what was
/// sent, as its flavour stores it. One time budget (`cfg.budget_for(items)`) covers it all.
pub async fn upload_verified(
    link: &Link,
    target: &Autopilot,
    items: &[MISSION_ITEM_INT_DATA],
    cfg: TransferConfig,
    progress: impl FnMut(usize, usize),
) -> Result<UploadReport, UploadError> {
    upload_verified_of(MISSION, link, target, items, cfg, progress).await
}

/// Uploads `items` into the autopilot's list of `mission_type` (its mission, fence or rally
/// points) and reads them back, as [`upload_verified`] does the mission. No items: the list is
/// emptied (a MISSION_COUNT of 0) and read back empty.
pub async fn upload_verified_of(
    mission_type: MavMissionType,
    link: &Link,
    target: &Autopilot,
    items: &[MISSION_ITEM_INT_DATA],
    cfg: TransferConfig,
    mut progress: impl FnMut(usize, usize),
) -> Result<UploadReport, UploadError> {
    let items: Vec<MISSION_ITEM_INT_DATA> = items
        .iter()
        .map(|it| MISSION_ITEM_INT_DATA {
            mission_type,
            ..it.clone()
        })
        .collect();
    let items = &items[..];
    let cfg = TransferConfig {
        flavour: target.flavour,
        ..cfg
    };
    let budget = cfg.budget_for(items.len());
    let started = Instant::now();
    let mut rto = Rto::new(cfg.timing);
    let mut attempts = 0;
    let (mut count_sent, mut items_sent, mut restarts, mut refusals) = (0, 0, 0, 0);
    loop {
        attempts += 1;
        let fail = |stage: Stage, accepted: bool, cause: DriverError| {
            let (item, refusal) = match &cause {
                DriverError::Transfer(e) => (e.item(), e.refusal()),
                DriverError::Readback(e) => (e.item(), None),
                DriverError::Link(_) => (None, None),
            };
            UploadError {
                list: list_name(mission_type),
                stage,
                accepted,
                item,
                refusal,
                attempts,
                cause,
            }
        };
        let stage_cfg = TransferConfig {
            budget: Some(remaining(budget, started)),
            ..cfg
        };
        let mut upload = Upload::of_type(mission_type, items.to_vec(), stage_cfg, rto);
        let outcome = run(link, target, &mut upload, &mut progress).await;
        rto = upload.rto();
        count_sent += upload.stats.count_sent;
        items_sent += upload.stats.items_sent;
        restarts += upload.stats.restarts;
        refusals += upload.stats.refusals;
        let acked = match outcome {
            Ok(()) => true,
            // PX4 sends the final ack once: a lost ack is settled by reading the mission back.
            Err(DriverError::Transfer(TransferError::AckLost { .. })) => false,
            Err(e) => return Err(fail(Stage::Upload, false, e)),
        };
        let upload_s = started.elapsed().as_secs_f64();
        let stage_cfg = TransferConfig {
            budget: Some(remaining(budget, started)),
            ..cfg
        };
        let mut down = Download::of_type(mission_type, stage_cfg, rto);
        let read = run(link, target, &mut down, |_, _| {}).await;
        rto = down.rto();
        restarts += down.stats.restarts;
        refusals += down.stats.refusals;
        let read = read.map_err(|e| fail(Stage::ReadBack, acked, e))?;
        match readback::verify(cfg.flavour, items, &read) {
            Ok(()) => {
                return Ok(UploadReport {
                    items: items.len(),
                    acked,
                    verified: true,
                    upload_s,
                    verify_s: started.elapsed().as_secs_f64() - upload_s,
                    count_sent,
                    items_sent,
                    restarts,
                    refusals,
                    rtt_ms: rto.srtt().map(|d| d.as_secs_f64() * 1e3),
                })
            }
            // Without the final ack the upload may never have completed: try it again.
            Err(_) if !acked && remaining(budget, started) > Duration::ZERO => {
                tracing::warn!("read-back differs after a lost final ack: uploading again");
            }
            Err(e) => return Err(fail(Stage::Verify, acked, e.into())),
        }
    }
}

/// Reads the autopilot's mission.
pub async fn download(
    link: &Link,
    target: &Autopilot,
    cfg: TransferConfig,
) -> Result<Vec<MISSION_ITEM_INT_DATA>, DriverError> {
    download_of(MISSION, link, target, cfg).await
}

/// Reads the autopilot's list of `mission_type` (its mission, fence or rally points).
pub async fn download_of(
    mission_type: MavMissionType,
    link: &Link,
    target: &Autopilot,
    cfg: TransferConfig,
) -> Result<Vec<MISSION_ITEM_INT_DATA>, DriverError> {
    let cfg = TransferConfig {
        flavour: target.flavour,
        ..cfg
    };
    run(
        link,
        target,
        &mut Download::of_type(mission_type, cfg, Rto::new(cfg.timing)),
        |_, _| {},
    )
    .await
}

/// Runs a command (clear all, set current) until confirmed.
pub async fn command(
    link: &Link,
    target: &Autopilot,
    mut command: Command,
) -> Result<(), DriverError> {
    run(link, target, &mut command, |_, _| {}).await
}
