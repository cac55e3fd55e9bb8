//! Downloading (reading back) the autopilot's mission: MISSION_REQUEST_LIST -> MISSION_COUNT ->
//! MISSION_REQUEST_INT / MISSION_ITEM_INT per item, in order -> MISSION_ACK.
//!
//! The ground side drives a download, so its clock matters here:
//! - a request (or REQUEST_LIST) unanswered for one RTO (`Rto`, from the measured round trip)
//!   is sent again, backing off to at most 4x;
//! - an autopilot that keeps download state abandons it after a while (`Flavour::
//!   download_restart_after`): after that long without an answer a fresh REQUEST_LIST goes out
//!   beside the requests, and its COUNT starts the download again; the items already received
//!   are kept (an autopilot that must be walked from item 0 again, `download_in_order`, has them
//!   replaced as they come back);
//! - refusals pass or restart as the flavour says (`Flavour::download_refusal`);
//! - all of it within the time budget.

use std::time::Duration;

use super::rto::Rto;
use super::{Action, Spent, Stage, TransferConfig, TransferError, Waiting, MISSION};
use crate::link::flavour::Refusal;
use crate::link::mav::{
    MavMessage, MavMissionResult, MavMissionType, MISSION_ACK_DATA, MISSION_ITEM_INT_DATA,
    MISSION_REQUEST_INT_DATA, MISSION_REQUEST_LIST_DATA,
};

/// The pause after a transient refusal before asking again.
const REFUSAL_PAUSE: Duration = Duration::from_secs(1);

/// Counters of what a download saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DownloadStats {
    /// MISSION_REQUEST_LIST and MISSION_REQUEST_INT sent.
    pub requests_sent: u32,
    /// Fresh REQUEST_LISTs after the autopilot went silent or gave up.
    pub restarts: u32,
    /// Transient refusals waited out.
    pub refusals: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Listing,
    Items,
    Finished,
}

/// Downloading (reading back) the autopilot's mission.
#[derive(Debug, Clone)]
pub struct Download {
    /// Which of the autopilot's lists: mission, fence or rally.
    mission_type: MavMissionType,
    cfg: TransferConfig,
    rto: Rto,
    phase: Phase,
    count: u16,
    /// Items received; `items[k]` is item k for every k below its length.
    items: Vec<MISSION_ITEM_INT_DATA>,
    /// The item requested now.
    next: u16,
    started: Duration,
    ends: Duration,
    wake: Duration,
    attempt: u32,
    /// When the autopilot last answered (or the download last started).
    heard: Duration,
    /// When the current request (or REQUEST_LIST) was first sent, if it went only once.
    sent_once: Option<Duration>,
    /// A fresh REQUEST_LIST is out while the old download may still be alive: since when.
    probing: Option<Duration>,
    refusal: Option<MavMissionResult>,
    result: Option<Result<Vec<MISSION_ITEM_INT_DATA>, TransferError>>,
    pub stats: DownloadStats,
}

impl Download {
    /// A download of the configured target's mission, timing its requests with `rto`.
    pub fn new(cfg: TransferConfig, rto: Rto) -> Download {
        Download::of_type(MISSION, cfg, rto)
    }

    /// A download of the target's list of `mission_type` (MISSION_TYPE_MISSION, _FENCE or
    /// _RALLY): every message it sends and heeds is of that type.
    pub fn of_type(mission_type: MavMissionType, cfg: TransferConfig, rto: Rto) -> Download {
        Download {
            mission_type,
            cfg,
            rto,
            phase: Phase::Listing,
            count: 0,
            items: Vec::new(),
            next: 0,
            started: Duration::ZERO,
            ends: Duration::ZERO,
            wake: Duration::ZERO,
            attempt: 0,
            heard: Duration::ZERO,
            sent_once: None,
            probing: None,
            refusal: None,
            result: None,
            stats: DownloadStats::default(),
        }
    }

    /// The items, once finished.
    pub fn finished(&self) -> Option<&Result<Vec<MISSION_ITEM_INT_DATA>, TransferError>> {
        self.result.as_ref()
    }

    /// Takes the finished outcome out (the items move, not copied).
    pub fn take_result(&mut self) -> Option<Result<Vec<MISSION_ITEM_INT_DATA>, TransferError>> {
        self.result.take()
    }

    /// The round-trip estimate as the download leaves it.
    pub fn rto(&self) -> Rto {
        self.rto
    }

    /// When `tick` is next due; None once finished.
    pub fn wake(&self) -> Option<Duration> {
        (self.phase != Phase::Finished).then(|| self.wake.min(self.ends))
    }

    fn list(&mut self) -> Action {
        self.stats.requests_sent += 1;
        Action::Send(MavMessage::MISSION_REQUEST_LIST(
            MISSION_REQUEST_LIST_DATA {
                target_system: self.cfg.target_system,
                target_component: self.cfg.target_component,
                mission_type: self.mission_type,
            },
        ))
    }

    fn request(&mut self) -> Action {
        self.stats.requests_sent += 1;
        Action::Send(MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq: self.next,
            target_system: self.cfg.target_system,
            target_component: self.cfg.target_component,
            mission_type: self.mission_type,
        }))
    }

    /// The current request, or REQUEST_LIST while listing.
    fn current(&mut self) -> Action {
        match self.phase {
            Phase::Items => self.request(),
            _ => self.list(),
        }
    }

    fn ack(&self) -> Action {
        Action::Send(MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: self.cfg.target_system,
            target_component: self.cfg.target_component,
            mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
            mission_type: self.mission_type,
            opaque_id: 0,
        }))
    }

    /// A fresh send of the current request (or REQUEST_LIST), timed from `now`.
    fn ask(&mut self, now: Duration) -> Vec<Action> {
        self.attempt = 0;
        self.sent_once = Some(now);
        self.wake = now + self.rto.timeout(0);
        vec![self.current()]
    }

    /// Sends MISSION_REQUEST_LIST.
    pub fn start(&mut self, now: Duration) -> Vec<Action> {
        self.started = now;
        self.ends = now + self.cfg.budget_for(usize::from(self.count));
        self.heard = now;
        self.phase = Phase::Listing;
        self.ask(now)
    }

    fn finish(&mut self, result: Result<Vec<MISSION_ITEM_INT_DATA>, TransferError>) {
        self.phase = Phase::Finished;
        self.result = Some(result);
    }

    fn measure(&mut self, now: Duration) {
        if let Some(at) = self.sent_once.take() {
            self.rto.sample(now.saturating_sub(at));
        }
    }

    /// Reacts to a message from the autopilot.
    pub fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<Action> {
        match message {
            MavMessage::MISSION_COUNT(c)
                if c.mission_type == self.mission_type
                    && (self.phase == Phase::Listing || self.probing.is_some()) =>
            {
                self.listed(now, c.count)
            }
            MavMessage::MISSION_ITEM_INT(item)
                if item.mission_type == self.mission_type
                    && self.phase == Phase::Items
                    && item.seq == self.next =>
            {
                self.received(now, item)
            }
            MavMessage::MISSION_ACK(a)
                if a.mission_type == self.mission_type && self.phase != Phase::Finished =>
            {
                self.refused(now, a.mavtype)
            }
            _ => Vec::new(),
        }
    }

    fn listed(&mut self, now: Duration, count: u16) -> Vec<Action> {
        if self.phase == Phase::Listing {
            self.measure(now);
        }
        if count != self.count {
            // Another mission than the one partly read: nothing kept is valid.
            self.items.clear();
        }
        self.count = count;
        self.heard = now;
        self.probing = None;
        if count == 0 {
            self.finish(Ok(Vec::new()));
            return vec![self.ack()];
        }
        self.next = if self.cfg.flavour.download_in_order() {
            0
        } else {
            self.items.len() as u16
        };
        if self.phase == Phase::Listing && self.stats.restarts == 0 {
            // The first COUNT fixes the budget: it grows with the mission.
            self.ends = self.started + self.cfg.budget_for(usize::from(count));
        }
        self.phase = Phase::Items;
        if usize::from(self.next) >= usize::from(count) {
            return self.complete();
        }
        self.ask(now)
    }

    fn received(&mut self, now: Duration, item: &MISSION_ITEM_INT_DATA) -> Vec<Action> {
        self.measure(now);
        let seq = usize::from(item.seq);
        if seq < self.items.len() {
            self.items[seq] = item.clone();
        } else {
            self.items.push(item.clone());
        }
        self.heard = now;
        self.probing = None;
        self.refusal = None;
        self.next += 1;
        let progress = Action::Progress {
            done: usize::from(self.next),
            total: usize::from(self.count),
        };
        if self.next == self.count {
            let mut out = self.complete();
            out.push(progress);
            return out;
        }
        let mut out = self.ask(now);
        out.push(progress);
        out
    }

    fn complete(&mut self) -> Vec<Action> {
        let mut items = std::mem::take(&mut self.items);
        items.truncate(usize::from(self.count));
        self.finish(Ok(items));
        vec![self.ack()]
    }

    fn refused(&mut self, now: Duration, result: MavMissionResult) -> Vec<Action> {
        match self.cfg.flavour.download_refusal(result) {
            Refusal::Ignore => Vec::new(),
            Refusal::Restart => {
                self.stats.restarts += 1;
                self.phase = Phase::Listing;
                self.probing = None;
                self.ask(now)
            }
            Refusal::Transient => {
                self.stats.refusals += 1;
                self.refusal = Some(result);
                self.sent_once = None;
                self.wake = now + REFUSAL_PAUSE.max(self.rto.base());
                Vec::new()
            }
            Refusal::Final => {
                let item = (self.phase == Phase::Items).then_some(self.next);
                self.finish(Err(TransferError::Refused {
                    stage: Stage::ReadBack,
                    item,
                    result,
                }));
                Vec::new()
            }
        }
    }

    /// Resends the current request, starts again or gives up, by the clock.
    pub fn tick(&mut self, now: Duration) -> Vec<Action> {
        if self.phase == Phase::Finished {
            return Vec::new();
        }
        if now >= self.ends {
            let (item, waiting) = match self.phase {
                Phase::Items => (Some(self.next), Waiting::Item(self.next)),
                _ => (None, Waiting::Count),
            };
            let spent = Spent {
                started: self.started,
                now,
                sent: self.stats.requests_sent,
                restarts: self.stats.restarts,
                refusal: self.refusal,
            };
            self.finish(Err(TransferError::out_of_time(
                Stage::ReadBack,
                item,
                waiting,
                spent,
            )));
            return Vec::new();
        }
        if now < self.wake {
            return Vec::new();
        }
        self.attempt += 1;
        self.sent_once = None;
        self.wake = now + self.rto.timeout(self.attempt);
        let mut out = vec![self.current()];
        if let (Phase::Items, Some(after)) = (self.phase, self.cfg.flavour.download_restart_after())
        {
            let silent = now.saturating_sub(self.heard) >= after;
            let probe_due = self
                .probing
                .is_none_or(|since| now.saturating_sub(since) >= after);
            if silent && probe_due {
                // The autopilot may have given the download up: ask for the list again beside
                // the request; whichever it answers goes on.
                self.stats.restarts += 1;
                self.probing = Some(now);
                out.push(self.list());
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::mav::MISSION_COUNT_DATA;
    use crate::link::testing::{ack, ms, waypoints};
    use crate::link::transfer::Timing;
    use crate::link::Flavour;

    fn count(n: u16) -> MavMessage {
        MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: n,
            mission_type: MISSION,
            ..Default::default()
        })
    }

    fn item(it: &MISSION_ITEM_INT_DATA) -> MavMessage {
        MavMessage::MISSION_ITEM_INT(it.clone())
    }

    fn requested(actions: &[Action]) -> Vec<u16> {
        actions
            .iter()
            .filter_map(|a| match a {
                Action::Send(MavMessage::MISSION_REQUEST_INT(r)) => Some(r.seq),
                _ => None,
            })
            .collect()
    }

    fn lists(actions: &[Action]) -> usize {
        actions
            .iter()
            .filter(|a| matches!(a, Action::Send(MavMessage::MISSION_REQUEST_LIST(_))))
            .count()
    }

    fn download(flavour: Flavour) -> Download {
        Download::new(
            TransferConfig {
                flavour,
                ..TransferConfig::default()
            },
            Rto::new(Timing::default()),
        )
    }

    #[test]
    fn download_reads_every_item_in_order_ignores_duplicates_and_acks() {
        let sent = waypoints(3);
        let mut down = download(Flavour::Px4);
        down.start(ms(0));
        assert_eq!(requested(&down.handle(ms(5), &count(3))), vec![0]);
        for (k, it) in sent.iter().enumerate() {
            if k > 0 {
                assert!(down.handle(ms(6), &item(&sent[k - 1])).is_empty());
            }
            down.handle(ms(10), &item(it));
        }
        assert_eq!(down.finished(), Some(&Ok(sent)));
    }

    #[test]
    fn download_re_requests_a_lost_item_after_the_measured_timeout() {
        let sent = waypoints(3);
        let mut down = download(Flavour::Px4);
        down.start(ms(0));
        down.handle(ms(40), &count(3));
        down.handle(ms(80), &item(&sent[0]));
        // Two round trips of 40 ms: SRTT 40, RTTVAR 20 -> 15; RTO = 40 + 60 = 100 ms.
        assert_eq!(down.rto().base(), ms(100));
        assert_eq!(down.wake(), Some(ms(180)));
        assert_eq!(requested(&down.tick(ms(180))), vec![1]);
        // Backing off: twice, then four times, never more.
        assert_eq!(down.wake(), Some(ms(380)));
        down.tick(ms(380));
        assert_eq!(down.wake(), Some(ms(780)));
        down.tick(ms(780));
        assert_eq!(down.wake(), Some(ms(1180)));
    }

    #[test]
    fn download_starts_again_with_a_fresh_list_when_the_autopilot_abandons_it() {
        // MAVSDK gives a download up after sending an item 5 times; it then ignores requests
        // but answers a new REQUEST_LIST, and must be walked from item 0 again.
        let sent = waypoints(4);
        let mut down = download(Flavour::Generic);
        down.start(ms(0));
        down.handle(ms(1), &count(4));
        down.handle(ms(2), &item(&sent[0]));
        down.handle(ms(3), &item(&sent[1]));
        let mut now = ms(3);
        let mut listed_at = None;
        while listed_at.is_none() {
            now = down.wake().unwrap();
            let out = down.tick(now);
            assert_eq!(
                requested(&out),
                vec![2],
                "the request goes on beside the probe"
            );
            if lists(&out) > 0 {
                listed_at = Some(now);
            }
        }
        // The first tick at least 1 s after the last answer.
        assert!(now >= ms(1003) && now < ms(1300), "{now:?}");
        assert_eq!(down.stats.restarts, 1);
        // The fresh COUNT restarts at item 0; what comes back replaces what was kept.
        assert_eq!(requested(&down.handle(now + ms(1), &count(4))), vec![0]);
        for it in &sent {
            down.handle(now + ms(2), &item(it));
        }
        assert_eq!(down.finished(), Some(&Ok(sent)));
    }

    #[test]
    fn ardupilot_is_never_asked_for_a_fresh_list_and_its_busy_refusal_is_waited_out() {
        let sent = waypoints(3);
        let mut down = download(Flavour::ArduPilot);
        down.start(ms(0));
        down.handle(ms(5), &count(3));
        // DENIED while its own upload's ack is deferred: wait and ask again.
        assert!(down
            .handle(ms(6), &ack(MavMissionResult::MAV_MISSION_DENIED))
            .is_empty());
        assert_eq!(down.wake(), Some(ms(1006)));
        let mut now = ms(6);
        while now < ms(20_000) {
            now = down.wake().unwrap();
            let out = down.tick(now);
            assert_eq!(lists(&out), 0);
        }
        for it in &sent {
            down.handle(now, &item(it));
        }
        assert_eq!(down.finished(), Some(&Ok(sent)));
    }

    #[test]
    fn a_restarted_ardupilot_download_resumes_where_it_stopped() {
        let sent = waypoints(3);
        let mut down = download(Flavour::ArduPilot);
        down.start(ms(0));
        down.handle(ms(5), &count(3));
        down.handle(ms(6), &item(&sent[0]));
        let out = down.handle(
            ms(7),
            &ack(MavMissionResult::MAV_MISSION_OPERATION_CANCELLED),
        );
        assert_eq!(lists(&out), 1);
        assert_eq!(requested(&down.handle(ms(8), &count(3))), vec![1]);
    }

    #[test]
    fn px4_aborting_the_download_starts_it_again_from_the_list() {
        let mut down = download(Flavour::Px4);
        down.start(ms(0));
        down.handle(ms(5), &count(3));
        let out = down.handle(ms(6), &ack(MavMissionResult::MAV_MISSION_ERROR));
        assert_eq!(lists(&out), 1);
        assert_eq!(down.stats.restarts, 1);
    }

    #[test]
    fn download_gives_up_when_the_budget_runs_out_naming_the_item() {
        let mut down = Download::new(
            TransferConfig {
                flavour: Flavour::Px4,
                budget: Some(ms(3000)),
                ..TransferConfig::default()
            },
            Rto::new(Timing::default()),
        );
        down.start(ms(0));
        down.handle(ms(5), &count(2));
        while down.finished().is_none() {
            let now = down.wake().unwrap();
            down.tick(now);
        }
        let err = down.finished().unwrap().clone().unwrap_err();
        assert_eq!(err.stage(), Stage::ReadBack);
        assert_eq!(err.item(), Some(0));
        assert!(
            err.to_string()
                .starts_with("read-back: gave up after 3.0 s (the time budget) waiting for item 0"),
            "{err}"
        );
    }

    #[test]
    fn a_final_refusal_ends_the_download_by_name() {
        let mut down = download(Flavour::Generic);
        down.start(ms(0));
        down.handle(ms(1), &ack(MavMissionResult::MAV_MISSION_UNSUPPORTED));
        assert_eq!(
            down.finished(),
            Some(&Err(TransferError::Refused {
                stage: Stage::ReadBack,
                item: None,
                result: MavMissionResult::MAV_MISSION_UNSUPPORTED
            }))
        );
    }

    #[test]
    fn a_rally_download_lists_and_requests_rally_items_and_skips_the_missions() {
        use crate::link::mav::MavMissionType;
        let rally = MavMissionType::MAV_MISSION_TYPE_RALLY;
        let mut down = Download::of_type(
            rally,
            TransferConfig {
                flavour: Flavour::Px4,
                ..TransferConfig::default()
            },
            Rto::new(Timing::default()),
        );
        let out = down.start(ms(0));
        assert!(matches!(
            out.first(),
            Some(Action::Send(MavMessage::MISSION_REQUEST_LIST(l))) if l.mission_type == rally
        ));
        // The mission's count is another list's.
        assert!(down.handle(ms(3), &count(5)).is_empty());
        let rally_count = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: 1,
            mission_type: rally,
            ..Default::default()
        });
        let out = down.handle(ms(5), &rally_count);
        assert!(matches!(
            out.first(),
            Some(Action::Send(MavMessage::MISSION_REQUEST_INT(r))) if r.seq == 0 && r.mission_type == rally
        ));
        let points = crate::link::fence::rally_items(&crate::link::testing::rally(), Flavour::Px4);
        let mut mission_item = points[0].clone();
        mission_item.mission_type = MISSION;
        assert!(down.handle(ms(8), &item(&mission_item)).is_empty());
        let out = down.handle(ms(10), &item(&points[0]));
        assert!(matches!(
            out.first(),
            Some(Action::Send(MavMessage::MISSION_ACK(a))) if a.mission_type == rally
        ));
        assert_eq!(down.finished(), Some(&Ok(points)));
    }
}
