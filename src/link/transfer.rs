//! The mission protocol's ground side as sans-IO state machines (MAVLink mission microservice;
//! MAVSDK's `mavlink_mission_transfer_client` is the model): `start`, `handle(now, message)` and
//! `tick(now)` return the messages to send; the driver owns sockets and clocks, the tests a fake
//! clock. Upload: MISSION_COUNT -> MISSION_REQUEST_INT or MISSION_REQUEST (both answered, any
//! order, repeats answered again) -> MISSION_ITEM_INT -> MISSION_ACK. Download: REQUEST_LIST ->
//! COUNT -> REQUEST_INT / ITEM_INT per item -> ACK. Timeouts resend (COUNT, the current request)
//! up to a retry limit, configurable for slow radios; every MAV_MISSION_RESULT is surfaced by
//! name; messages of another mission type are ignored.

use std::time::Duration;

use super::mav::{
    MavMessage, MavMissionResult, MavMissionType, MISSION_ACK_DATA, MISSION_COUNT_DATA,
    MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA, MISSION_REQUEST_LIST_DATA,
};

/// Timing and addressing of a transfer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransferConfig {
    /// How long to wait for the autopilot before resending (MAVLink spec default 1.5 s).
    pub timeout: Duration,
    /// Resends before giving up (MAVLink spec: 5).
    pub retries: u32,
    pub target_system: u8,
    pub target_component: u8,
}

impl Default for TransferConfig {
    fn default() -> Self {
        TransferConfig {
            timeout: Duration::from_millis(1500),
            retries: 5,
            target_system: 1,
            target_component: 1,
        }
    }
}

/// Why a transfer failed; each names its stage.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TransferError {
    #[error("count: the autopilot never requested an item ({attempts} MISSION_COUNT sent)")]
    CountTimeout { attempts: u32 },
    #[error(
        "item {seq}: the autopilot stopped requesting items ({attempts} waits of the timeout)"
    )]
    ItemTimeout { seq: u16, attempts: u32 },
    #[error("ack: no MISSION_ACK after the last item ({attempts} waits of the timeout)")]
    AckTimeout { attempts: u32 },
    #[error("item {seq}: the autopilot rejected the mission: {result}")]
    Rejected { seq: u16, result: String },
    #[error("item {seq}: the autopilot requested item {seq} of a {count}-item mission")]
    BadRequest { seq: u16, count: usize },
    #[error("{stage}: no answer after {attempts} requests")]
    DownloadTimeout { stage: String, attempts: u32 },
    #[error("download: the autopilot refused: {result}")]
    DownloadRefused { result: String },
    #[error("verify: the autopilot holds {held} items, {sent} were sent")]
    CountMismatch { held: usize, sent: usize },
    #[error("verify: item {seq} read back differs from what was sent (sent {sent}, read {read})")]
    Mismatch {
        seq: u16,
        sent: String,
        read: String,
    },
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

/// The name MAVLink gives a result (e.g. `MAV_MISSION_UNSUPPORTED_FRAME`).
pub fn result_name(result: MavMissionResult) -> String {
    format!("{result:?}")
}

const MISSION: MavMissionType = MavMissionType::MAV_MISSION_TYPE_MISSION;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum UploadState {
    AwaitFirstRequest,
    Sending,
    AwaitAck,
    Finished,
}

/// Counters of what an upload saw (for reports and tests).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct UploadStats {
    pub items_sent: u32,
    pub count_sent: u32,
    pub ignored_other_mission_type: u32,
}

/// Uploading a mission.
#[derive(Debug, Clone)]
pub struct Upload {
    items: Vec<MISSION_ITEM_INT_DATA>,
    cfg: TransferConfig,
    state: UploadState,
    attempts: u32,
    deadline: Duration,
    highest: Option<u16>,
    last_sent: Option<u16>,
    result: Option<Result<(), TransferError>>,
    pub stats: UploadStats,
}

impl Upload {
    /// An upload of `items` (numbered 0..n).
    pub fn new(items: Vec<MISSION_ITEM_INT_DATA>, cfg: TransferConfig) -> Upload {
        Upload {
            items,
            cfg,
            state: UploadState::AwaitFirstRequest,
            attempts: 0,
            deadline: Duration::ZERO,
            highest: None,
            last_sent: None,
            result: None,
            stats: UploadStats::default(),
        }
    }

    /// The outcome, once finished.
    pub fn finished(&self) -> Option<&Result<(), TransferError>> {
        self.result.as_ref()
    }

    fn count(&mut self) -> Action {
        self.stats.count_sent += 1;
        Action::Send(MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: self.items.len() as u16,
            target_system: self.cfg.target_system,
            target_component: self.cfg.target_component,
            mission_type: MISSION,
            opaque_id: 0,
        }))
    }

    fn finish(&mut self, result: Result<(), TransferError>) {
        self.state = UploadState::Finished;
        self.result = Some(result);
    }

    /// Sends MISSION_COUNT.
    pub fn start(&mut self, now: Duration) -> Vec<Action> {
        self.deadline = now + self.cfg.timeout;
        vec![self.count()]
    }

    fn item(&mut self, seq: u16) -> Action {
        let mut item = self.items[seq as usize].clone();
        item.target_system = self.cfg.target_system;
        item.target_component = self.cfg.target_component;
        item.mission_type = MISSION;
        self.stats.items_sent += 1;
        self.last_sent = Some(seq);
        Action::Send(MavMessage::MISSION_ITEM_INT(item))
    }

    /// Reacts to a message from the autopilot (the legacy MISSION_REQUEST included).
    #[allow(deprecated)]
    pub fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<Action> {
        if self.state == UploadState::Finished {
            return Vec::new();
        }
        let (seq, mission_type) = match message {
            MavMessage::MISSION_REQUEST_INT(r) => (Some(r.seq), r.mission_type),
            MavMessage::MISSION_REQUEST(r) => (Some(r.seq), r.mission_type),
            MavMessage::MISSION_ACK(a) => (None, a.mission_type),
            _ => return Vec::new(),
        };
        if mission_type != MISSION {
            self.stats.ignored_other_mission_type += 1;
            return Vec::new();
        }
        match (seq, message) {
            (Some(seq), _) => {
                if seq as usize >= self.items.len() {
                    self.finish(Err(TransferError::BadRequest {
                        seq,
                        count: self.items.len(),
                    }));
                    return Vec::new();
                }
                self.attempts = 0;
                self.deadline = now + self.cfg.timeout;
                self.highest = Some(self.highest.map_or(seq, |h| h.max(seq)));
                // Monotonic: a late or reordered request for an earlier item is answered but
                // does not take the upload back from waiting for the final ack.
                self.state = if self.highest.map_or(0, |h| h as usize + 1) == self.items.len() {
                    UploadState::AwaitAck
                } else {
                    UploadState::Sending
                };
                let done = self.highest.map_or(0, |h| h as usize + 1);
                vec![
                    self.item(seq),
                    Action::Progress {
                        done,
                        total: self.items.len(),
                    },
                ]
            }
            (None, MavMessage::MISSION_ACK(ack)) => {
                if ack.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED {
                    // An ACCEPTED before the last item was requested is a stale ack of an
                    // earlier transfer: not ours.
                    if self.items.is_empty() || self.state == UploadState::AwaitAck {
                        self.finish(Ok(()));
                    }
                } else {
                    let seq = self.highest.unwrap_or(0);
                    self.finish(Err(TransferError::Rejected {
                        seq,
                        result: result_name(ack.mavtype),
                    }));
                }
                Vec::new()
            }
            _ => Vec::new(),
        }
    }

    /// Resends or gives up when the autopilot has been silent for the timeout.
    pub fn tick(&mut self, now: Duration) -> Vec<Action> {
        if self.state == UploadState::Finished || now < self.deadline {
            return Vec::new();
        }
        self.attempts += 1;
        self.deadline = now + self.cfg.timeout;
        if self.attempts > self.cfg.retries {
            let attempts = self.attempts;
            let err = match self.state {
                UploadState::AwaitFirstRequest => TransferError::CountTimeout { attempts },
                UploadState::Sending => TransferError::ItemTimeout {
                    seq: self.last_sent.unwrap_or(0),
                    attempts,
                },
                _ => TransferError::AckTimeout { attempts },
            };
            self.finish(Err(err));
            return Vec::new();
        }
        match self.state {
            UploadState::AwaitFirstRequest => vec![self.count()],
            // The autopilot re-requests what it misses; resending the last item covers a
            // lost item when it waits for it without re-requesting.
            UploadState::Sending => self
                .last_sent
                .map(|s| vec![self.item(s)])
                .unwrap_or_default(),
            _ => Vec::new(),
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
enum DownloadState {
    Listing,
    Items { count: u16 },
    Finished,
}

/// Downloading (reading back) the autopilot's mission.
#[derive(Debug, Clone)]
pub struct Download {
    cfg: TransferConfig,
    state: DownloadState,
    items: Vec<MISSION_ITEM_INT_DATA>,
    attempts: u32,
    deadline: Duration,
    result: Option<Result<Vec<MISSION_ITEM_INT_DATA>, TransferError>>,
}

impl Download {
    /// A download from the configured target.
    pub fn new(cfg: TransferConfig) -> Download {
        Download {
            cfg,
            state: DownloadState::Listing,
            items: Vec::new(),
            attempts: 0,
            deadline: Duration::ZERO,
            result: None,
        }
    }

    /// The items, once finished.
    pub fn finished(&self) -> Option<&Result<Vec<MISSION_ITEM_INT_DATA>, TransferError>> {
        self.result.as_ref()
    }

    fn list(&self) -> Action {
        Action::Send(MavMessage::MISSION_REQUEST_LIST(
            MISSION_REQUEST_LIST_DATA {
                target_system: self.cfg.target_system,
                target_component: self.cfg.target_component,
                mission_type: MISSION,
            },
        ))
    }

    fn request(&self, seq: u16) -> Action {
        Action::Send(MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: self.cfg.target_system,
            target_component: self.cfg.target_component,
            mission_type: MISSION,
        }))
    }

    fn ack(&self) -> Action {
        Action::Send(MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: self.cfg.target_system,
            target_component: self.cfg.target_component,
            mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
            mission_type: MISSION,
            opaque_id: 0,
        }))
    }

    /// Sends MISSION_REQUEST_LIST.
    pub fn start(&mut self, now: Duration) -> Vec<Action> {
        self.deadline = now + self.cfg.timeout;
        vec![self.list()]
    }

    /// Reacts to a message from the autopilot.
    pub fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<Action> {
        match (&self.state, message) {
            (DownloadState::Listing, MavMessage::MISSION_COUNT(c)) if c.mission_type == MISSION => {
                self.attempts = 0;
                self.deadline = now + self.cfg.timeout;
                if c.count == 0 {
                    self.state = DownloadState::Finished;
                    self.result = Some(Ok(Vec::new()));
                    return vec![self.ack()];
                }
                self.state = DownloadState::Items { count: c.count };
                vec![self.request(0)]
            }
            (DownloadState::Items { count }, MavMessage::MISSION_ITEM_INT(item))
                if item.mission_type == MISSION =>
            {
                let count = *count;
                if item.seq as usize != self.items.len() {
                    return Vec::new(); // a duplicate or an answer to an older request
                }
                self.items.push(item.clone());
                self.attempts = 0;
                self.deadline = now + self.cfg.timeout;
                let done = self.items.len();
                let progress = Action::Progress {
                    done,
                    total: count as usize,
                };
                if done == count as usize {
                    self.state = DownloadState::Finished;
                    self.result = Some(Ok(std::mem::take(&mut self.items)));
                    vec![self.ack(), progress]
                } else {
                    vec![self.request(done as u16), progress]
                }
            }
            (DownloadState::Listing | DownloadState::Items { .. }, MavMessage::MISSION_ACK(a))
                if a.mission_type == MISSION
                    && a.mavtype != MavMissionResult::MAV_MISSION_ACCEPTED =>
            {
                self.state = DownloadState::Finished;
                self.result = Some(Err(TransferError::DownloadRefused {
                    result: result_name(a.mavtype),
                }));
                Vec::new()
            }
            _ => Vec::new(),
        }
    }

    /// Resends the current request, or gives up.
    pub fn tick(&mut self, now: Duration) -> Vec<Action> {
        if self.state == DownloadState::Finished || now < self.deadline {
            return Vec::new();
        }
        self.attempts += 1;
        self.deadline = now + self.cfg.timeout;
        let stage = match self.state {
            DownloadState::Listing => "count".to_string(),
            _ => format!("item {}", self.items.len()),
        };
        if self.attempts > self.cfg.retries {
            self.state = DownloadState::Finished;
            self.result = Some(Err(TransferError::DownloadTimeout {
                stage,
                attempts: self.attempts,
            }));
            return Vec::new();
        }
        match self.state {
            DownloadState::Listing => vec![self.list()],
            _ => vec![self.request(self.items.len() as u16)],
        }
    }
}

/// A one-message command that waits for its confirmation: MISSION_CLEAR_ALL (confirmed by an
/// ACK; a refusal is surfaced by name) or MISSION_SET_CURRENT (confirmed by MISSION_CURRENT with
/// that seq). Resent on timeout up to the retry limit.
#[derive(Debug, Clone)]
pub struct Command {
    cfg: TransferConfig,
    kind: CommandKind,
    attempts: u32,
    deadline: Duration,
    result: Option<Result<(), TransferError>>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum CommandKind {
    ClearAll,
    SetCurrent(u16),
}

impl Command {
    /// Clears the autopilot's mission.
    pub fn clear_all(cfg: TransferConfig) -> Command {
        Command {
            cfg,
            kind: CommandKind::ClearAll,
            attempts: 0,
            deadline: Duration::ZERO,
            result: None,
        }
    }

    /// Makes item `seq` the current one.
    pub fn set_current(cfg: TransferConfig, seq: u16) -> Command {
        Command {
            cfg,
            kind: CommandKind::SetCurrent(seq),
            attempts: 0,
            deadline: Duration::ZERO,
            result: None,
        }
    }

    /// The outcome, once finished.
    pub fn finished(&self) -> Option<&Result<(), TransferError>> {
        self.result.as_ref()
    }

    // MISSION_SET_CURRENT is superseded by MAV_CMD_DO_SET_MISSION_CURRENT (2022) but PX4 and
    // ArduPilot still answer it with MISSION_CURRENT, and older firmware knows only it.
    #[allow(deprecated)]
    fn message(&self) -> Action {
        let (target_system, target_component) = (self.cfg.target_system, self.cfg.target_component);
        Action::Send(match self.kind {
            CommandKind::ClearAll => {
                MavMessage::MISSION_CLEAR_ALL(super::mav::MISSION_CLEAR_ALL_DATA {
                    target_system,
                    target_component,
                    mission_type: MISSION,
                })
            }
            CommandKind::SetCurrent(seq) => {
                MavMessage::MISSION_SET_CURRENT(super::mav::MISSION_SET_CURRENT_DATA {
                    seq,
                    target_system,
                    target_component,
                })
            }
        })
    }

    /// Sends the command.
    pub fn start(&mut self, now: Duration) -> Vec<Action> {
        self.deadline = now + self.cfg.timeout;
        vec![self.message()]
    }

    /// Reacts to the autopilot's answer.
    pub fn handle(&mut self, _now: Duration, message: &MavMessage) -> Vec<Action> {
        if self.result.is_some() {
            return Vec::new();
        }
        match (self.kind, message) {
            (CommandKind::ClearAll, MavMessage::MISSION_ACK(a)) if a.mission_type == MISSION => {
                self.result = Some(if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED {
                    Ok(())
                } else {
                    Err(TransferError::Rejected {
                        seq: 0,
                        result: result_name(a.mavtype),
                    })
                });
            }
            (CommandKind::SetCurrent(seq), MavMessage::MISSION_CURRENT(c)) if c.seq == seq => {
                self.result = Some(Ok(()))
            }
            _ => {}
        }
        Vec::new()
    }

    /// Resends, or gives up.
    pub fn tick(&mut self, now: Duration) -> Vec<Action> {
        if self.result.is_some() || now < self.deadline {
            return Vec::new();
        }
        self.attempts += 1;
        self.deadline = now + self.cfg.timeout;
        if self.attempts > self.cfg.retries {
            let stage = match self.kind {
                CommandKind::ClearAll => "clear".to_string(),
                CommandKind::SetCurrent(seq) => format!("set current {seq}"),
            };
            self.result = Some(Err(TransferError::DownloadTimeout {
                stage,
                attempts: self.attempts,
            }));
            return Vec::new();
        }
        vec![self.message()]
    }
}

/// Compares a read-back with what was sent.
pub fn verify(
    sent: &[MISSION_ITEM_INT_DATA],
    read: &[MISSION_ITEM_INT_DATA],
) -> Result<(), TransferError> {
    if sent.len() != read.len() {
        return Err(TransferError::CountMismatch {
            held: read.len(),
            sent: sent.len(),
        });
    }
    for (a, b) in sent.iter().zip(read) {
        if !super::items::same_item(a, b) {
            return Err(TransferError::Mismatch {
                seq: a.seq,
                sent: format!("{a:?}"),
                read: format!("{b:?}"),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
#[allow(deprecated)]
mod tests {
    use super::*;
    use crate::link::mav::{MavCmd, MavFrame, MISSION_REQUEST_DATA};

    fn items(n: u16) -> Vec<MISSION_ITEM_INT_DATA> {
        (0..n)
            .map(|seq| MISSION_ITEM_INT_DATA {
                seq,
                command: MavCmd::MAV_CMD_NAV_WAYPOINT,
                frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
                x: 385_000_000 + i32::from(seq),
                y: -1_217_000_000,
                z: 30.0,
                autocontinue: 1,
                ..Default::default()
            })
            .collect()
    }

    fn ms(t: u64) -> Duration {
        Duration::from_millis(t)
    }

    fn request(seq: u16) -> MavMessage {
        MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: 255,
            target_component: 190,
            mission_type: MISSION,
        })
    }

    fn ack(result: MavMissionResult) -> MavMessage {
        MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: 255,
            target_component: 190,
            mavtype: result,
            mission_type: MISSION,
            opaque_id: 0,
        })
    }

    fn sent_items(actions: &[Action]) -> Vec<u16> {
        actions
            .iter()
            .filter_map(|a| match a {
                Action::Send(MavMessage::MISSION_ITEM_INT(i)) => Some(i.seq),
                _ => None,
            })
            .collect()
    }

    fn is_count(actions: &[Action]) -> bool {
        matches!(actions.first(), Some(Action::Send(MavMessage::MISSION_COUNT(c))) if c.count == 3)
    }

    #[test]
    fn upload_resends_count_when_the_first_request_times_out() {
        let mut up = Upload::new(items(3), TransferConfig::default());
        assert!(is_count(&up.start(ms(0))));
        assert!(up.tick(ms(1000)).is_empty());
        assert!(is_count(&up.tick(ms(1500))));
        assert_eq!(up.stats.count_sent, 2);
        assert_eq!(sent_items(&up.handle(ms(1600), &request(0))), vec![0]);
    }

    #[test]
    fn upload_answers_every_item_request_and_finishes_on_accepted() {
        let mut up = Upload::new(items(3), TransferConfig::default());
        up.start(ms(0));
        for seq in 0..3 {
            assert_eq!(
                sent_items(&up.handle(ms(10 * u64::from(seq)), &request(seq))),
                vec![seq]
            );
        }
        assert!(up.finished().is_none());
        up.handle(ms(50), &ack(MavMissionResult::MAV_MISSION_ACCEPTED));
        assert_eq!(up.finished(), Some(&Ok(())));
    }

    #[test]
    fn upload_answers_a_lost_item_request_when_the_autopilot_asks_again() {
        let mut up = Upload::new(items(3), TransferConfig::default());
        up.start(ms(0));
        up.handle(ms(10), &request(0));
        // The item (or the next request) was lost: the autopilot re-requests item 0.
        assert_eq!(sent_items(&up.handle(ms(260), &request(0))), vec![0]);
        assert_eq!(sent_items(&up.handle(ms(300), &request(1))), vec![1]);
    }

    #[test]
    fn upload_answers_duplicate_requests_idempotently() {
        let mut up = Upload::new(items(3), TransferConfig::default());
        up.start(ms(0));
        let first = up.handle(ms(10), &request(1));
        let again = up.handle(ms(11), &request(1));
        assert_eq!(sent_items(&first), sent_items(&again));
        assert!(up.finished().is_none());
    }

    #[test]
    fn upload_answers_a_request_for_a_later_seq_in_any_order() {
        let mut up = Upload::new(items(3), TransferConfig::default());
        up.start(ms(0));
        assert_eq!(sent_items(&up.handle(ms(10), &request(2))), vec![2]);
        assert_eq!(sent_items(&up.handle(ms(20), &request(0))), vec![0]);
        let beyond = up.handle(ms(30), &request(3));
        assert!(beyond.is_empty());
        assert_eq!(
            up.finished(),
            Some(&Err(TransferError::BadRequest { seq: 3, count: 3 }))
        );
    }

    #[test]
    fn upload_answers_the_legacy_mission_request_too() {
        let mut up = Upload::new(items(3), TransferConfig::default());
        up.start(ms(0));
        let legacy = MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
            seq: 0,
            target_system: 255,
            target_component: 190,
            mission_type: MISSION,
        });
        assert_eq!(sent_items(&up.handle(ms(10), &legacy)), vec![0]);
    }

    #[test]
    fn upload_reports_a_nack_on_item_k_by_its_result_name() {
        let mut up = Upload::new(items(3), TransferConfig::default());
        up.start(ms(0));
        up.handle(ms(10), &request(0));
        up.handle(ms(20), &request(1));
        up.handle(
            ms(30),
            &ack(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME),
        );
        let err = up.finished().unwrap().clone().unwrap_err();
        assert_eq!(
            err,
            TransferError::Rejected {
                seq: 1,
                result: "MAV_MISSION_UNSUPPORTED_FRAME".into()
            }
        );
        assert_eq!(
            err.to_string(),
            "item 1: the autopilot rejected the mission: MAV_MISSION_UNSUPPORTED_FRAME"
        );
    }

    #[test]
    fn upload_reports_a_lost_final_ack_as_an_ack_timeout_for_read_back_to_decide() {
        let cfg = TransferConfig {
            retries: 2,
            ..TransferConfig::default()
        };
        let mut up = Upload::new(items(2), cfg);
        up.start(ms(0));
        up.handle(ms(10), &request(0));
        up.handle(ms(20), &request(1));
        for t in [1600, 3200, 4800] {
            up.tick(ms(t));
        }
        assert_eq!(
            up.finished(),
            Some(&Err(TransferError::AckTimeout { attempts: 3 }))
        );
    }

    #[test]
    fn upload_gives_up_with_the_stage_when_retries_are_exhausted() {
        let cfg = TransferConfig {
            retries: 3,
            ..TransferConfig::default()
        };
        let mut up = Upload::new(items(3), cfg);
        up.start(ms(0));
        let mut counts = 1;
        for k in 1..=4 {
            if is_count(&up.tick(ms(1500 * k))) {
                counts += 1;
            }
        }
        assert_eq!(counts, 4);
        assert_eq!(
            up.finished(),
            Some(&Err(TransferError::CountTimeout { attempts: 4 }))
        );
        let mut up = Upload::new(items(3), cfg);
        up.start(ms(0));
        up.handle(ms(10), &request(0));
        for k in 1..=4 {
            up.tick(ms(10 + 1500 * k));
        }
        assert_eq!(
            up.finished(),
            Some(&Err(TransferError::ItemTimeout {
                seq: 0,
                attempts: 4
            }))
        );
    }

    #[test]
    fn upload_ignores_messages_of_another_mission_type() {
        let mut up = Upload::new(items(3), TransferConfig::default());
        up.start(ms(0));
        let fence = MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq: 0,
            target_system: 255,
            target_component: 190,
            mission_type: MavMissionType::MAV_MISSION_TYPE_FENCE,
        });
        assert!(up.handle(ms(10), &fence).is_empty());
        let fence_ack = MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            mavtype: MavMissionResult::MAV_MISSION_ERROR,
            mission_type: MavMissionType::MAV_MISSION_TYPE_RALLY,
            ..Default::default()
        });
        assert!(up.handle(ms(11), &fence_ack).is_empty());
        assert!(up.finished().is_none());
        assert_eq!(up.stats.ignored_other_mission_type, 2);
    }

    #[test]
    fn a_reordered_request_for_an_earlier_item_after_the_last_does_not_lose_the_final_ack() {
        let mut up = Upload::new(items(3), TransferConfig::default());
        up.start(ms(0));
        for seq in [0, 1, 2] {
            up.handle(ms(10), &request(seq));
        }
        assert_eq!(sent_items(&up.handle(ms(20), &request(1))), vec![1]);
        up.handle(ms(30), &ack(MavMissionResult::MAV_MISSION_ACCEPTED));
        assert_eq!(up.finished(), Some(&Ok(())));
    }

    #[test]
    fn upload_ignores_a_stale_accepted_ack_before_the_last_item() {
        let mut up = Upload::new(items(3), TransferConfig::default());
        up.start(ms(0));
        up.handle(ms(10), &request(0));
        up.handle(ms(20), &ack(MavMissionResult::MAV_MISSION_ACCEPTED));
        assert!(up.finished().is_none());
    }

    #[test]
    fn clear_all_resends_until_acked_and_surfaces_a_refusal_by_name() {
        let mut clear = Command::clear_all(TransferConfig::default());
        assert!(matches!(
            clear.start(ms(0)).as_slice(),
            [Action::Send(MavMessage::MISSION_CLEAR_ALL(_))]
        ));
        assert!(matches!(
            clear.tick(ms(1500)).as_slice(),
            [Action::Send(MavMessage::MISSION_CLEAR_ALL(_))]
        ));
        clear.handle(ms(1600), &ack(MavMissionResult::MAV_MISSION_ACCEPTED));
        assert_eq!(clear.finished(), Some(&Ok(())));
        let mut refused = Command::clear_all(TransferConfig::default());
        refused.start(ms(0));
        refused.handle(ms(5), &ack(MavMissionResult::MAV_MISSION_DENIED));
        assert!(
            matches!(refused.finished(), Some(Err(TransferError::Rejected { result, .. })) if result == "MAV_MISSION_DENIED")
        );
    }

    #[test]
    fn set_current_waits_for_mission_current_with_that_seq() {
        let cfg = TransferConfig {
            retries: 1,
            ..TransferConfig::default()
        };
        let mut set = Command::set_current(cfg, 3);
        set.start(ms(0));
        let current = |seq| {
            MavMessage::MISSION_CURRENT(crate::link::mav::MISSION_CURRENT_DATA {
                seq,
                ..Default::default()
            })
        };
        set.handle(ms(5), &current(2));
        assert!(set.finished().is_none());
        set.handle(ms(6), &current(3));
        assert_eq!(set.finished(), Some(&Ok(())));
        let mut lost = Command::set_current(cfg, 3);
        lost.start(ms(0));
        lost.tick(ms(1500));
        lost.tick(ms(3000));
        assert_eq!(
            lost.finished().unwrap().clone().unwrap_err().to_string(),
            "set current 3: no answer after 2 requests"
        );
    }

    #[test]
    fn download_reads_every_item_in_order_and_acks() {
        let sent = items(3);
        let mut down = Download::new(TransferConfig::default());
        down.start(ms(0));
        let count = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: 3,
            mission_type: MISSION,
            ..Default::default()
        });
        down.handle(ms(5), &count);
        for (k, it) in sent.iter().enumerate() {
            // A duplicate of the previous item is ignored.
            if k > 0 {
                down.handle(ms(6), &MavMessage::MISSION_ITEM_INT(sent[k - 1].clone()));
            }
            down.handle(ms(10), &MavMessage::MISSION_ITEM_INT(it.clone()));
        }
        let read = down.finished().unwrap().clone().unwrap();
        assert_eq!(verify(&sent, &read), Ok(()));
        let mut changed = read.clone();
        changed[1].x += 1;
        assert!(matches!(
            verify(&sent, &changed),
            Err(TransferError::Mismatch { seq: 1, .. })
        ));
        assert!(matches!(
            verify(&sent, &read[..2]),
            Err(TransferError::CountMismatch { held: 2, sent: 3 })
        ));
    }

    #[test]
    fn download_re_requests_a_lost_item_then_gives_up_naming_it() {
        let cfg = TransferConfig {
            retries: 1,
            ..TransferConfig::default()
        };
        let mut down = Download::new(cfg);
        down.start(ms(0));
        let count = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: 2,
            mission_type: MISSION,
            ..Default::default()
        });
        down.handle(ms(5), &count);
        let again = down.tick(ms(1600));
        assert!(
            matches!(again.as_slice(), [Action::Send(MavMessage::MISSION_REQUEST_INT(r))] if r.seq == 0)
        );
        down.tick(ms(3200));
        assert_eq!(
            down.finished(),
            Some(&Err(TransferError::DownloadTimeout {
                stage: "item 0".into(),
                attempts: 2
            }))
        );
    }
}
