//! The thin async driver of the sans-IO transfer machines: feeds them the target's messages and
//! a 20 ms tick, sends what they ask. A verified upload = the mission uploaded (ACCEPTED, or the
//! final ack lost) AND read back equal to what was sent.

use std::time::Duration;

use tokio::time::Instant;

use super::connection::{Autopilot, Link};
use super::mav::{MavMessage, MISSION_ITEM_INT_DATA};
use super::transfer::{verify, Action, Download, TransferConfig, TransferError, Upload};
use super::LinkError;

/// Why an upload or download did not complete.
#[derive(Debug, thiserror::Error)]
pub enum DriverError {
    #[error(transparent)]
    Link(#[from] LinkError),
    #[error(transparent)]
    Transfer(#[from] TransferError),
}

/// What an upload achieved.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
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
}

/// A transfer machine the driver can run.
pub trait Machine {
    type Output;
    fn start(&mut self, now: Duration) -> Vec<Action>;
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<Action>;
    fn tick(&mut self, now: Duration) -> Vec<Action>;
    fn outcome(&self) -> Option<Result<Self::Output, TransferError>>;
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
    fn outcome(&self) -> Option<Result<(), TransferError>> {
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
    fn outcome(&self) -> Option<Result<Self::Output, TransferError>> {
        self.finished().cloned()
    }
}

impl Machine for super::transfer::Command {
    type Output = ();
    fn start(&mut self, now: Duration) -> Vec<Action> {
        super::transfer::Command::start(self, now)
    }
    fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<Action> {
        super::transfer::Command::handle(self, now, message)
    }
    fn tick(&mut self, now: Duration) -> Vec<Action> {
        super::transfer::Command::tick(self, now)
    }
    fn outcome(&self) -> Option<Result<(), TransferError>> {
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
    let mut actions = machine.start(start.elapsed());
    let mut tick = tokio::time::interval(Duration::from_millis(20));
    loop {
        for action in actions.drain(..) {
            match action {
                Action::Send(message) => link.send(&message).await?,
                Action::Progress { done, total } => progress(done, total),
            }
        }
        if let Some(outcome) = machine.outcome() {
            return Ok(outcome?);
        }
        actions = tokio::select! {
            received = rx.recv() => match received {
                Ok((header, message)) if header.system_id == u32::from(target.system_id) => {
                    machine.handle(start.elapsed(), &message)
                }
                Ok(_) | Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => Vec::new(),
                Err(tokio::sync::broadcast::error::RecvError::Closed) => {
                    return Err(LinkError::Closed("the receive task ended".into()).into())
                }
            },
            _ = tick.tick() => machine.tick(start.elapsed()),
        };
    }
}

/// Uploads `items` and reads them back; Ok only when the read-back matches.
pub async fn upload_verified(
    link: &Link,
    target: &Autopilot,
    items: &[MISSION_ITEM_INT_DATA],
    cfg: TransferConfig,
    progress: impl FnMut(usize, usize),
) -> Result<UploadReport, DriverError> {
    let started = Instant::now();
    let mut upload = Upload::new(items.to_vec(), cfg);
    let acked = match run(link, target, &mut upload, progress).await {
        Ok(()) => true,
        // PX4 sends the final ack once: a lost ack is settled by reading the mission back.
        Err(DriverError::Transfer(TransferError::AckTimeout { .. })) => false,
        Err(e) => return Err(e),
    };
    let upload_s = started.elapsed().as_secs_f64();
    let read = download(link, target, cfg).await?;
    verify(items, &read)?;
    Ok(UploadReport {
        items: items.len(),
        acked,
        verified: true,
        upload_s,
        verify_s: started.elapsed().as_secs_f64() - upload_s,
        count_sent: upload.stats.count_sent,
        items_sent: upload.stats.items_sent,
    })
}

/// Reads the autopilot's mission.
pub async fn download(
    link: &Link,
    target: &Autopilot,
    cfg: TransferConfig,
) -> Result<Vec<MISSION_ITEM_INT_DATA>, DriverError> {
    run(link, target, &mut Download::new(cfg), |_, _| {}).await
}
