//! The mission protocol's ground side as sans-IO state machines (MAVLink mission microservice;
//! MAVSDK's `mavlink_mission_transfer_client` is the model): `start`, `handle(now, message)` and
//! `tick(now)` return what to send; `wake()` says when `tick` is next due. The driver owns
//! sockets and clocks, the tests a fake clock.
//!
//! - `upload`: MISSION_COUNT -> MISSION_REQUEST_INT / MISSION_REQUEST (answered in any order,
//!   repeats answered again) -> MISSION_ITEM_INT -> MISSION_ACK; started again from COUNT when
//!   the autopilot has abandoned it.
//! - `download`: REQUEST_LIST -> COUNT -> REQUEST_INT / ITEM_INT per item -> ACK; started again
//!   with a fresh REQUEST_LIST when the autopilot has abandoned it, keeping what arrived.
//! - `command`: MISSION_CLEAR_ALL and MISSION_SET_CURRENT, each resent until confirmed.
//!
//! Resends follow the link: the round-trip time of every request/answer pair sent once (Karn's
//! rule) feeds a smoothed RTT and its variance as TCP does (RFC 6298), bounded below and above
//! (`Timing`). A transfer ends when done, refused, or out of its time budget, never after a
//! fixed count of retries. Each machine moves one list of the autopilot, its mission, its fence
//! or its rally points (MAV_MISSION_TYPE_*, `of_type`); messages of another type are ignored.

mod command;
mod download;
mod rto;
mod upload;

pub use command::Command;
pub use download::{Download, DownloadStats};
pub use rto::{Rto, Timing};
pub use upload::{Upload, UploadStats};

use std::fmt;
use std::time::Duration;

use super::mav::{MavMessage, MavMissionResult, MavMissionType};
use super::Flavour;

pub(crate) const MISSION: MavMissionType = MavMissionType::MAV_MISSION_TYPE_MISSION;
/// The mission type of a mission's items (the fence's and the rally points' are `link::fence`'s).
pub const MISSION_TYPE: MavMissionType = MISSION;

/// Addressing and timing of a transfer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransferConfig {
    pub target_system: u8,
    pub target_component: u8,
    /// Which autopilot answers: when it abandons a transfer, which refusals pass.
    pub flavour: Flavour,
    pub timing: Timing,
    /// Time allowed for the whole transfer; None: `default_budget` of its item count.
    pub budget: Option<Duration>,
}

impl Default for TransferConfig {
    fn default() -> Self {
        TransferConfig {
            target_system: 1,
            target_component: 1,
            flavour: Flavour::Generic,
            timing: Timing::default(),
            budget: None,
        }
    }
}

impl TransferConfig {
    /// The time allowed for a transfer of `items` items.
    pub fn budget_for(&self, items: usize) -> Duration {
        self.budget
            .unwrap_or_else(|| default_budget(self.flavour, items))
    }
}

/// The default time budget of a transfer of `items` items to `flavour`: 30 s, enough to wait
/// out ArduPilot's boot refusal (about 10 s on SITL) and an abandoned transfer or two, plus two
/// of the autopilot's re-request periods per item (a lost request costs one period, as the
/// autopilot drives an upload on its own clock: PX4 0.5 s, MAVSDK 1 s, ArduPilot 2 s an item).
pub fn default_budget(flavour: Flavour, items: usize) -> Duration {
    Duration::from_secs(30) + flavour.rerequest_period() * 2 * items.min(65_535) as u32
}

/// The stage of an upload a failure happened in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stage {
    /// Sending the mission (MISSION_COUNT to the final MISSION_ACK).
    Upload,
    /// Reading the mission back (REQUEST_LIST to the last item).
    ReadBack,
    /// Comparing what was read back with what was sent.
    Verify,
    Clear,
    SetCurrent,
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Stage::Upload => "upload",
            Stage::ReadBack => "read-back",
            Stage::Verify => "verify",
            Stage::Clear => "clear",
            Stage::SetCurrent => "set-current",
        })
    }
}

/// What a transfer was waiting for when its time ran out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Waiting {
    /// The autopilot's first item request after MISSION_COUNT.
    FirstRequest,
    /// The autopilot's request for the item after `sent`.
    NextRequest { sent: u16 },
    /// The final MISSION_ACK.
    Ack,
    /// MISSION_COUNT after MISSION_REQUEST_LIST.
    Count,
    /// Item `seq` of a download.
    Item(u16),
    /// The confirmation of a command.
    Confirmation,
}

impl fmt::Display for Waiting {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Waiting::FirstRequest => write!(f, "the autopilot's first item request"),
            Waiting::NextRequest { sent } => {
                write!(f, "the autopilot's request for the item after item {sent}")
            }
            Waiting::Ack => write!(f, "the final MISSION_ACK"),
            Waiting::Count => write!(f, "MISSION_COUNT"),
            Waiting::Item(seq) => write!(f, "item {seq}"),
            Waiting::Confirmation => write!(f, "the confirmation"),
        }
    }
}

/// The name MAVLink gives a result (e.g. `MAV_MISSION_UNSUPPORTED_FRAME`).
pub fn result_name(result: MavMissionResult) -> String {
    format!("{result:?}")
}

fn at_item(item: &Option<u16>) -> String {
    item.map(|seq| format!(" at item {seq}"))
        .unwrap_or_default()
}

fn last_refusal(refusal: &Option<MavMissionResult>) -> String {
    refusal
        .map(|r| format!("; the autopilot last refused with {r:?}"))
        .unwrap_or_default()
}

/// Why a transfer failed; each names its stage and, where there is one, the item.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TransferError {
    #[error("{stage}: the autopilot refused{}: {result:?}", at_item(item))]
    Refused {
        stage: Stage,
        item: Option<u16>,
        result: MavMissionResult,
    },
    #[error("upload: the autopilot requested item {seq} of a {count}-item mission")]
    BadRequest { seq: u16, count: usize },
    #[error(
        "{stage}: gave up after {elapsed_s:.1} s (the time budget) waiting for {waiting}; \
         {sent} messages sent, {restarts} fresh starts{}",
        last_refusal(refusal)
    )]
    OutOfTime {
        stage: Stage,
        item: Option<u16>,
        waiting: Waiting,
        elapsed_s: f64,
        sent: u32,
        restarts: u32,
        refusal: Option<MavMissionResult>,
    },
    #[error("upload: every item was sent but no MISSION_ACK came in {waited_s:.1} s")]
    AckLost { waited_s: f64 },
}

/// What a transfer did before its time ran out (for `TransferError::OutOfTime`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Spent {
    pub started: Duration,
    pub now: Duration,
    pub sent: u32,
    pub restarts: u32,
    pub refusal: Option<MavMissionResult>,
}

impl TransferError {
    pub(crate) fn out_of_time(
        stage: Stage,
        item: Option<u16>,
        waiting: Waiting,
        spent: Spent,
    ) -> TransferError {
        TransferError::OutOfTime {
            stage,
            item,
            waiting,
            elapsed_s: spent.now.saturating_sub(spent.started).as_secs_f64(),
            sent: spent.sent,
            restarts: spent.restarts,
            refusal: spent.refusal,
        }
    }

    /// The stage the failure happened in.
    pub fn stage(&self) -> Stage {
        match self {
            TransferError::Refused { stage, .. } | TransferError::OutOfTime { stage, .. } => *stage,
            TransferError::BadRequest { .. } | TransferError::AckLost { .. } => Stage::Upload,
        }
    }

    /// The item the failure concerns, if one.
    pub fn item(&self) -> Option<u16> {
        match self {
            TransferError::Refused { item, .. } | TransferError::OutOfTime { item, .. } => *item,
            TransferError::BadRequest { seq, .. } => Some(*seq),
            TransferError::AckLost { .. } => None,
        }
    }

    /// The autopilot's refusal behind the failure, if one.
    pub fn refusal(&self) -> Option<MavMissionResult> {
        match self {
            TransferError::Refused { result, .. } => Some(*result),
            TransferError::OutOfTime { refusal, .. } => *refusal,
            _ => None,
        }
    }
}

/// What a machine asks its driver to do (short-lived: the size of a message is fine here).
#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum Action {
    Send(MavMessage),
    /// Items transferred so far, of the total.
    Progress {
        done: usize,
        total: usize,
    },
}
