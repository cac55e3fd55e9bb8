//! Uploading a mission: MISSION_COUNT, then the autopilot drives (it requests each item, we
//! answer every request, repeats and the legacy MISSION_REQUEST included), then its MISSION_ACK.
//!
//! Timing, all from the measured round trip (`Rto`) and the flavour's known behaviour:
//! - COUNT is resent until the first request comes.
//! - An item is resent (at most twice, RTO apart) when the request for the next does not come:
//!   that covers a lost item at once. Then the upload waits for the autopilot's own re-request
//!   (it has its own clock: PX4 250 ms, MAVSDK 500 ms, ArduPilot 1 s); resending more would only
//!   hold off MAVSDK's re-request, which a repeated item postpones.
//! - When the autopilot stays silent longer than it keeps an upload (`Flavour::
//!   upload_restart_after`) or says it gave up (OPERATION_CANCELLED), the upload starts again
//!   from COUNT.
//! - A transient refusal (ArduPilot's NO_SPACE while its storage boots) is waited out.
//! - After the last item, the final ack is awaited (the last item resent twice, which PX4
//!   answers with its ack again); if none comes, `AckLost` lets the driver settle it by reading
//!   the mission back.
//! - All of it within the time budget.

use std::time::Duration;

use super::rto::Rto;
use super::{Action, Spent, Stage, TransferConfig, TransferError, Waiting, MISSION};
use crate::link::flavour::Refusal;
use crate::link::mav::{
    MavMessage, MavMissionResult, MavMissionType, MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA,
};

/// Resends of an item before waiting for the autopilot's own re-request.
const ITEM_RESENDS: u32 = 2;
/// The least wait for the final ack: ArduPilot defers it until its mission checksum is ready,
/// at least 0.5 s after the last change (`MissionItemProtocol::transfer_is_complete`,
/// `update_checksum`).
const ACK_WAIT_MIN: Duration = Duration::from_secs(2);
/// The pause after a transient refusal before MISSION_COUNT is tried again.
const REFUSAL_PAUSE: Duration = Duration::from_secs(1);

/// Counters of what an upload saw (for reports and tests).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct UploadStats {
    pub items_sent: u32,
    pub count_sent: u32,
    /// Fresh starts from MISSION_COUNT after the autopilot abandoned the upload.
    pub restarts: u32,
    /// Transient refusals waited out.
    pub refusals: u32,
    pub ignored_other_mission_type: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Count,
    Sending,
    AwaitAck,
    Finished,
}

/// The last message sent that an answer will time: COUNT or item `seq`, when, and whether it
/// went once (only those measure a round trip: Karn's rule).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Sent {
    item: Option<u16>,
    at: Duration,
    once: bool,
}

/// Uploading a mission, a fence or a rally list.
#[derive(Debug, Clone)]
pub struct Upload {
    /// Which of the autopilot's lists: mission, fence or rally.
    mission_type: MavMissionType,
    items: Vec<MISSION_ITEM_INT_DATA>,
    cfg: TransferConfig,
    rto: Rto,
    phase: Phase,
    started: Duration,
    ends: Duration,
    wake: Duration,
    /// Consecutive timeouts of the message last sent.
    attempt: u32,
    /// When the autopilot last asked for an item (or the upload last started).
    heard: Duration,
    highest: Option<u16>,
    sent: Option<Sent>,
    refusal: Option<MavMissionResult>,
    result: Option<Result<(), TransferError>>,
    pub stats: UploadStats,
}

impl Upload {
    /// An upload of the mission `items` (numbered 0..n), timing its resends with `rto`.
    pub fn new(items: Vec<MISSION_ITEM_INT_DATA>, cfg: TransferConfig, rto: Rto) -> Upload {
        Upload::of_type(MISSION, items, cfg, rto)
    }

    /// An upload of `items` (numbered 0..n) into the autopilot's list of `mission_type`
    /// (MISSION_TYPE_MISSION, _FENCE or _RALLY): every message it sends and heeds is of that
    /// type.
    pub fn of_type(
        mission_type: MavMissionType,
        items: Vec<MISSION_ITEM_INT_DATA>,
        cfg: TransferConfig,
        rto: Rto,
    ) -> Upload {
        let items = items
            .into_iter()
            .map(|mut item| {
                item.target_system = cfg.target_system;
                item.target_component = cfg.target_component;
                item.mission_type = mission_type;
                item
            })
            .collect();
        Upload {
            mission_type,
            items,
            cfg,
            rto,
            phase: Phase::Count,
            started: Duration::ZERO,
            ends: Duration::ZERO,
            wake: Duration::ZERO,
            attempt: 0,
            heard: Duration::ZERO,
            highest: None,
            sent: None,
            refusal: None,
            result: None,
            stats: UploadStats::default(),
        }
    }

    /// The outcome, once finished.
    pub fn finished(&self) -> Option<&Result<(), TransferError>> {
        self.result.as_ref()
    }

    /// The round-trip estimate as the upload leaves it (a read-back starts from it).
    pub fn rto(&self) -> Rto {
        self.rto
    }

    /// When `tick` is next due; None once finished.
    pub fn wake(&self) -> Option<Duration> {
        (self.phase != Phase::Finished).then(|| self.wake.min(self.ends))
    }

    fn finish(&mut self, result: Result<(), TransferError>) {
        self.phase = Phase::Finished;
        self.result = Some(result);
    }

    fn count(&mut self, now: Duration, once: bool) -> Action {
        self.stats.count_sent += 1;
        self.sent = Some(Sent {
            item: None,
            at: now,
            once,
        });
        Action::Send(MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: self.items.len() as u16,
            target_system: self.cfg.target_system,
            target_component: self.cfg.target_component,
            mission_type: self.mission_type,
            opaque_id: 0,
        }))
    }

    /// The list this upload fills.
    pub fn mission_type(&self) -> MavMissionType {
        self.mission_type
    }

    fn item(&mut self, now: Duration, seq: u16) -> Option<Action> {
        let item = self.items.get(usize::from(seq))?.clone();
        let again = matches!(self.sent, Some(Sent { item: Some(s), .. }) if s == seq);
        self.stats.items_sent += 1;
        self.sent = Some(Sent {
            item: Some(seq),
            at: now,
            once: !again,
        });
        Some(Action::Send(MavMessage::MISSION_ITEM_INT(item)))
    }

    /// Sends MISSION_COUNT.
    pub fn start(&mut self, now: Duration) -> Vec<Action> {
        self.started = now;
        self.ends = now + self.cfg.budget_for(self.items.len());
        self.heard = now;
        self.attempt = 0;
        self.wake = now + self.rto.timeout(0);
        vec![self.count(now, true)]
    }

    /// Starts again from MISSION_COUNT: the autopilot has abandoned the upload.
    fn restart(&mut self, now: Duration) -> Vec<Action> {
        self.stats.restarts += 1;
        self.phase = Phase::Count;
        self.highest = None;
        self.heard = now;
        self.attempt = 0;
        self.wake = now + self.rto.timeout(0);
        vec![self.count(now, true)]
    }

    /// Reacts to a message from the autopilot (the legacy MISSION_REQUEST included).
    #[allow(deprecated)]
    pub fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<Action> {
        if self.phase == Phase::Finished {
            return Vec::new();
        }
        let (seq, mission_type) = match message {
            MavMessage::MISSION_REQUEST_INT(r) => (Some(r.seq), r.mission_type),
            MavMessage::MISSION_REQUEST(r) => (Some(r.seq), r.mission_type),
            MavMessage::MISSION_ACK(a) => (None, a.mission_type),
            _ => return Vec::new(),
        };
        if mission_type != self.mission_type {
            self.stats.ignored_other_mission_type += 1;
            return Vec::new();
        }
        match (seq, message) {
            (Some(seq), _) => self.request(now, seq),
            (None, MavMessage::MISSION_ACK(ack)) => self.ack(now, ack.mavtype),
            _ => Vec::new(),
        }
    }

    fn request(&mut self, now: Duration, seq: u16) -> Vec<Action> {
        let total = self.items.len();
        if usize::from(seq) >= total {
            self.finish(Err(TransferError::BadRequest { seq, count: total }));
            return Vec::new();
        }
        // The answer to what was sent once measures a round trip, unless it came as late as
        // the autopilot's own repeat of a lost request would.
        if let Some(sent) = self.sent {
            let answers = match sent.item {
                None => seq == 0,
                Some(s) => seq == s.wrapping_add(1),
            };
            let rtt = now.saturating_sub(sent.at);
            if answers && sent.once && rtt < self.cfg.flavour.rerequest_period() {
                self.rto.sample(rtt);
            }
        }
        self.heard = now;
        self.attempt = 0;
        self.refusal = None;
        let highest = self.highest.map_or(seq, |h| h.max(seq));
        self.highest = Some(highest);
        // Monotonic: a late or reordered request for an earlier item is answered but does not
        // take the upload back from waiting for the final ack.
        self.phase = if usize::from(highest) + 1 == total {
            Phase::AwaitAck
        } else {
            Phase::Sending
        };
        self.wake = now + self.rto.timeout(0);
        let mut out = Vec::with_capacity(2);
        out.extend(self.item(now, seq));
        out.push(Action::Progress {
            done: usize::from(highest) + 1,
            total,
        });
        out
    }

    fn ack(&mut self, now: Duration, result: MavMissionResult) -> Vec<Action> {
        if result == MavMissionResult::MAV_MISSION_ACCEPTED {
            // An ACCEPTED before the last item was requested is a stale ack of an earlier
            // transfer: not ours.
            if self.items.is_empty() || self.phase == Phase::AwaitAck {
                self.finish(Ok(()));
            }
            return Vec::new();
        }
        match self.cfg.flavour.upload_refusal(result) {
            Refusal::Ignore => Vec::new(),
            Refusal::Restart => self.restart(now),
            Refusal::Transient => {
                self.stats.refusals += 1;
                self.refusal = Some(result);
                self.phase = Phase::Count;
                self.highest = None;
                self.attempt = 0;
                self.sent = None;
                self.wake = now + REFUSAL_PAUSE.max(self.rto.base());
                Vec::new()
            }
            Refusal::Final => {
                self.finish(Err(TransferError::Refused {
                    stage: Stage::Upload,
                    item: self.highest,
                    result,
                }));
                Vec::new()
            }
        }
    }

    /// Resends, starts again or gives up, by the clock.
    pub fn tick(&mut self, now: Duration) -> Vec<Action> {
        if self.phase == Phase::Finished {
            return Vec::new();
        }
        if now >= self.ends {
            let waiting = match (self.phase, self.highest) {
                (Phase::Sending, Some(sent)) => Waiting::NextRequest { sent },
                (Phase::AwaitAck, _) => Waiting::Ack,
                _ => Waiting::FirstRequest,
            };
            let spent = Spent {
                started: self.started,
                now,
                sent: self.stats.count_sent + self.stats.items_sent,
                restarts: self.stats.restarts,
                refusal: self.refusal,
            };
            let err = TransferError::out_of_time(Stage::Upload, self.highest, waiting, spent);
            self.finish(Err(err));
            return Vec::new();
        }
        if now < self.wake {
            return Vec::new();
        }
        match self.phase {
            Phase::Count => {
                // After a transient refusal the pause is over: a fresh COUNT, timed again.
                let fresh = self.sent.is_none();
                if !fresh {
                    self.attempt += 1;
                }
                self.wake = now + self.rto.timeout(self.attempt);
                vec![self.count(now, fresh)]
            }
            Phase::Sending | Phase::AwaitAck if self.attempt < ITEM_RESENDS => {
                self.attempt += 1;
                self.wake = now + self.rto.timeout(self.attempt);
                let last = self.sent.and_then(|s| s.item).or(self.highest);
                last.and_then(|seq| self.item(now, seq))
                    .into_iter()
                    .collect()
            }
            Phase::Sending => {
                let after = self.cfg.flavour.upload_restart_after();
                if now.saturating_sub(self.heard) >= after {
                    self.restart(now)
                } else {
                    self.wake = self.heard + after;
                    Vec::new()
                }
            }
            Phase::AwaitAck => {
                let wait = ACK_WAIT_MIN.max(self.rto.base() * 4);
                let waited = now.saturating_sub(self.heard);
                if waited >= wait {
                    self.finish(Err(TransferError::AckLost {
                        waited_s: waited.as_secs_f64(),
                    }));
                } else {
                    self.wake = self.heard + wait;
                }
                Vec::new()
            }
            Phase::Finished => Vec::new(),
        }
    }
}

#[cfg(test)]
#[allow(deprecated)]
mod tests {
    use super::*;
    use crate::link::mav::{MavMissionType, MISSION_ACK_DATA, MISSION_REQUEST_DATA};
    use crate::link::testing::{ack, ms, request, sent_items, waypoints};
    use crate::link::transfer::Timing;
    use crate::link::Flavour;

    fn config(flavour: Flavour) -> TransferConfig {
        TransferConfig {
            flavour,
            ..TransferConfig::default()
        }
    }

    fn upload(n: u16, flavour: Flavour) -> Upload {
        Upload::new(waypoints(n), config(flavour), Rto::new(Timing::default()))
    }

    fn is_count(actions: &[Action]) -> bool {
        matches!(
            actions.first(),
            Some(Action::Send(MavMessage::MISSION_COUNT(_)))
        )
    }

    #[test]
    fn upload_resends_count_when_the_first_request_times_out() {
        let mut up = upload(3, Flavour::Px4);
        assert!(is_count(&up.start(ms(0))));
        // Nothing measured yet: the initial timeout of 1 s.
        assert_eq!(up.wake(), Some(ms(1000)));
        assert!(up.tick(ms(999)).is_empty());
        assert!(is_count(&up.tick(ms(1000))));
        // Backed off: twice the timeout, at most the 1.5 s bound.
        assert_eq!(up.wake(), Some(ms(2500)));
        assert_eq!(up.stats.count_sent, 2);
        assert_eq!(sent_items(&up.handle(ms(1100), &request(0))), vec![0]);
    }

    #[test]
    fn upload_resends_on_a_timeout_derived_from_the_measured_round_trip() {
        let mut up = upload(5, Flavour::Px4);
        up.start(ms(0));
        // Each request comes 100 ms after what it answers: the round trip is 100 ms.
        for seq in 0..3u16 {
            up.handle(ms(100 * (u64::from(seq) + 1)), &request(seq));
        }
        assert_eq!(up.rto().srtt(), Some(ms(100)));
        // Three samples of 100 ms: RTTVAR 50 -> 37.5 -> 28.1 ms, RTO = 100 + 4 x 28.1.
        let rto = up.rto().base();
        assert!(rto > ms(200) && rto < ms(230), "{rto:?}");
        // The request for item 3 does not come: item 2 is resent after one RTO, not 1.5 s.
        assert_eq!(up.wake(), Some(ms(300) + rto));
        assert_eq!(sent_items(&up.tick(ms(300) + rto)), vec![2]);
        // A resent item measures nothing (Karn): the estimate stays.
        up.handle(ms(900), &request(3));
        assert_eq!(up.rto().base(), rto);
    }

    #[test]
    fn a_request_as_late_as_the_autopilots_own_repeat_does_not_count_as_a_round_trip() {
        let mut up = upload(4, Flavour::Px4);
        up.start(ms(0));
        up.handle(ms(20), &request(0));
        up.handle(ms(40), &request(1));
        let before = up.rto();
        // The request for item 2 was lost; PX4 repeats it 250 ms later.
        up.handle(ms(295), &request(2));
        assert_eq!(up.rto(), before);
        up.handle(ms(315), &request(3));
        assert_eq!(up.rto().samples(), before.samples() + 1);
    }

    #[test]
    fn upload_answers_every_item_request_and_finishes_on_accepted() {
        let mut up = upload(3, Flavour::Generic);
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
        assert_eq!(up.wake(), None);
    }

    #[test]
    fn upload_answers_duplicate_and_out_of_order_requests_and_the_legacy_request() {
        let mut up = upload(3, Flavour::Px4);
        up.start(ms(0));
        let first = up.handle(ms(10), &request(1));
        let again = up.handle(ms(11), &request(1));
        assert_eq!(sent_items(&first), sent_items(&again));
        assert_eq!(sent_items(&up.handle(ms(20), &request(0))), vec![0]);
        let legacy = MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
            seq: 2,
            target_system: 255,
            target_component: 190,
            mission_type: MISSION,
        });
        assert_eq!(sent_items(&up.handle(ms(30), &legacy)), vec![2]);
        assert!(up.handle(ms(40), &request(3)).is_empty());
        assert_eq!(
            up.finished(),
            Some(&Err(TransferError::BadRequest { seq: 3, count: 3 }))
        );
    }

    #[test]
    fn upload_reports_a_nack_by_its_result_and_item() {
        let mut up = upload(3, Flavour::Px4);
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
            TransferError::Refused {
                stage: Stage::Upload,
                item: Some(1),
                result: MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME
            }
        );
        assert_eq!(
            err.to_string(),
            "upload: the autopilot refused at item 1: MAV_MISSION_UNSUPPORTED_FRAME"
        );
    }

    #[test]
    fn upload_resends_the_last_item_twice_then_reports_a_lost_final_ack() {
        let mut up = upload(2, Flavour::Px4);
        up.start(ms(0));
        up.handle(ms(10), &request(0));
        up.handle(ms(20), &request(1));
        let mut resent = Vec::new();
        let mut now = ms(20);
        while up.finished().is_none() {
            now = up.wake().unwrap();
            resent.extend(sent_items(&up.tick(now)));
        }
        assert_eq!(resent, vec![1, 1]);
        // Waited the least ack wait (2 s) after the last request.
        assert_eq!(now, ms(2020));
        assert!(matches!(
            up.finished(),
            Some(Err(TransferError::AckLost { .. }))
        ));
    }

    #[test]
    fn upload_starts_again_from_count_when_the_autopilot_has_abandoned_it() {
        // MAVSDK's server gives up after 2.5 s without progress and says nothing.
        let mut up = upload(4, Flavour::Generic);
        up.start(ms(0));
        up.handle(ms(10), &request(0));
        up.handle(ms(20), &request(1));
        let mut now = ms(20);
        let mut restarted_at = None;
        while restarted_at.is_none() {
            now = up.wake().unwrap();
            if is_count(&up.tick(now)) {
                restarted_at = Some(now);
            }
        }
        assert_eq!(restarted_at, Some(ms(20) + ms(2500)));
        assert_eq!(up.stats.restarts, 1);
        // The fresh transfer starts at item 0 and runs to the end.
        for seq in 0..4 {
            assert_eq!(
                sent_items(&up.handle(now + ms(5), &request(seq))),
                vec![seq]
            );
        }
        up.handle(now + ms(6), &ack(MavMissionResult::MAV_MISSION_ACCEPTED));
        assert_eq!(up.finished(), Some(&Ok(())));
    }

    #[test]
    fn upload_starts_again_at_once_when_the_autopilot_cancels() {
        let mut up = upload(3, Flavour::ArduPilot);
        up.start(ms(0));
        up.handle(ms(10), &request(0));
        let out = up.handle(
            ms(8000),
            &ack(MavMissionResult::MAV_MISSION_OPERATION_CANCELLED),
        );
        assert!(is_count(&out));
        assert_eq!(up.stats.restarts, 1);
    }

    #[test]
    fn px4_is_not_asked_to_start_again_before_its_five_second_timeout() {
        let mut up = upload(4, Flavour::Px4);
        up.start(ms(0));
        up.handle(ms(10), &request(0));
        loop {
            let now = up.wake().unwrap();
            if now >= ms(5000) {
                assert_eq!(now, ms(10) + ms(5500));
                assert!(is_count(&up.tick(now)));
                break;
            }
            assert!(!is_count(&up.tick(now)), "COUNT at {now:?}");
        }
        assert_eq!(up.stats.restarts, 1);
    }

    #[test]
    fn a_transient_refusal_at_boot_is_waited_out_and_named_if_time_runs_out() {
        let cfg = TransferConfig {
            flavour: Flavour::ArduPilot,
            budget: Some(ms(10_000)),
            ..TransferConfig::default()
        };
        let mut up = Upload::new(waypoints(3), cfg, Rto::new(Timing::default()));
        up.start(ms(0));
        let no_space = ack(MavMissionResult::MAV_MISSION_NO_SPACE);
        assert!(up.handle(ms(5), &no_space).is_empty());
        assert!(up.finished().is_none());
        // COUNT again after the pause.
        assert_eq!(up.wake(), Some(ms(1005)));
        assert!(is_count(&up.tick(ms(1005))));
        // Storage ready: the upload proceeds.
        assert_eq!(sent_items(&up.handle(ms(1010), &request(0))), vec![0]);
        // Another upload refused until the budget runs out names the refusal.
        let mut refused = Upload::new(waypoints(3), cfg, Rto::new(Timing::default()));
        refused.start(ms(0));
        let mut now = ms(0);
        while refused.finished().is_none() {
            now = refused.wake().unwrap();
            if is_count(&refused.tick(now)) {
                refused.handle(now + ms(5), &no_space);
            }
        }
        let err = refused.finished().unwrap().clone().unwrap_err();
        assert_eq!(err.refusal(), Some(MavMissionResult::MAV_MISSION_NO_SPACE));
        assert!(err.to_string().contains("MAV_MISSION_NO_SPACE"), "{err}");
        assert_eq!(now, ms(10_000));
    }

    #[test]
    fn ardupilots_invalid_sequence_answer_to_a_repeated_item_does_not_end_the_upload() {
        let mut up = upload(3, Flavour::ArduPilot);
        up.start(ms(0));
        up.handle(ms(10), &request(0));
        up.handle(ms(20), &ack(MavMissionResult::MAV_MISSION_INVALID_SEQUENCE));
        assert!(up.finished().is_none());
        assert_eq!(sent_items(&up.handle(ms(30), &request(1))), vec![1]);
    }

    #[test]
    fn upload_gives_up_when_the_time_budget_runs_out_naming_what_it_waited_for() {
        let cfg = TransferConfig {
            budget: Some(ms(4000)),
            ..config(Flavour::Px4)
        };
        let mut up = Upload::new(waypoints(3), cfg, Rto::new(Timing::default()));
        up.start(ms(0));
        while up.finished().is_none() {
            let now = up.wake().unwrap();
            up.tick(now);
        }
        let err = up.finished().unwrap().clone().unwrap_err();
        assert!(matches!(
            err,
            TransferError::OutOfTime {
                stage: Stage::Upload,
                waiting: Waiting::FirstRequest,
                ..
            }
        ));
        assert!(
            err.to_string()
                .starts_with("upload: gave up after 4.0 s (the time budget) waiting for the autopilot's first item request"),
            "{err}"
        );
    }

    #[test]
    fn upload_ignores_messages_of_another_mission_type_and_a_stale_accepted() {
        let mut up = upload(3, Flavour::Px4);
        up.start(ms(0));
        let fence = MavMessage::MISSION_REQUEST_INT(crate::link::mav::MISSION_REQUEST_INT_DATA {
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
        assert_eq!(up.stats.ignored_other_mission_type, 2);
        up.handle(ms(12), &request(0));
        up.handle(ms(20), &ack(MavMissionResult::MAV_MISSION_ACCEPTED));
        assert!(up.finished().is_none());
        // A reordered request for an earlier item after the last does not lose the final ack.
        up.handle(ms(30), &request(1));
        up.handle(ms(31), &request(2));
        assert_eq!(sent_items(&up.handle(ms(32), &request(1))), vec![1]);
        up.handle(ms(40), &ack(MavMissionResult::MAV_MISSION_ACCEPTED));
        assert_eq!(up.finished(), Some(&Ok(())));
    }

    #[test]
    fn a_fence_upload_sends_its_count_and_items_as_fence_and_ignores_mission_requests() {
        let fence = MavMissionType::MAV_MISSION_TYPE_FENCE;
        let items = crate::link::fence::fence_items(&crate::link::testing::fence());
        let n = items.len();
        let mut up = Upload::of_type(
            fence,
            items,
            config(Flavour::ArduPilot),
            Rto::new(Timing::default()),
        );
        let first = up.start(ms(0));
        assert!(matches!(
            first.first(),
            Some(Action::Send(MavMessage::MISSION_COUNT(c))) if c.mission_type == fence && usize::from(c.count) == n
        ));
        // A request of the mission (another transfer) is not answered with a fence item.
        assert!(up.handle(ms(5), &request(0)).is_empty());
        let of_fence = |seq: u16| {
            MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
                seq,
                target_system: 255,
                target_component: 190,
                mission_type: fence,
            })
        };
        for seq in 0..n as u16 {
            let out = up.handle(ms(10 + u64::from(seq)), &of_fence(seq));
            assert!(matches!(
                out.first(),
                Some(Action::Send(MavMessage::MISSION_ITEM_INT(i))) if i.seq == seq && i.mission_type == fence
            ));
        }
        // The mission's ACCEPTED is not the fence's.
        up.handle(ms(50), &ack(MavMissionResult::MAV_MISSION_ACCEPTED));
        assert!(up.finished().is_none());
        up.handle(
            ms(60),
            &MavMessage::MISSION_ACK(MISSION_ACK_DATA {
                mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
                mission_type: fence,
                ..Default::default()
            }),
        );
        assert_eq!(up.finished(), Some(&Ok(())));
    }

    #[test]
    fn an_empty_rally_upload_is_a_count_of_zero_finished_by_the_rally_ack() {
        let rally = MavMissionType::MAV_MISSION_TYPE_RALLY;
        let mut up = Upload::of_type(
            rally,
            Vec::new(),
            config(Flavour::Px4),
            Rto::new(Timing::default()),
        );
        assert!(matches!(
            up.start(ms(0)).first(),
            Some(Action::Send(MavMessage::MISSION_COUNT(c))) if c.mission_type == rally && c.count == 0
        ));
        up.handle(
            ms(10),
            &MavMessage::MISSION_ACK(MISSION_ACK_DATA {
                mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
                mission_type: rally,
                ..Default::default()
            }),
        );
        assert_eq!(up.finished(), Some(&Ok(())));
    }
}
