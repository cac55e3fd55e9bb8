//! The stream-rate requests: a sans-IO machine that sends MAV_CMD_SET_MESSAGE_INTERVAL for
//! each wanted message, one at a time, until its COMMAND_ACK.

use std::time::Duration;

use mavlink::MessageData;

use crate::link::mav::{self, MavCmd, MavMessage, MavResult};

/// A message whose rate is requested.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamRequest {
    pub message_id: u32,
    pub name: &'static str,
    /// Interval between messages (MAV_CMD_SET_MESSAGE_INTERVAL param2).
    pub interval_us: u32,
}

impl StreamRequest {
    /// A request for message `M` at `rate_hz`.
    pub fn of<M: MessageData>(rate_hz: f64) -> StreamRequest {
        StreamRequest {
            message_id: M::ID,
            name: M::NAME,
            interval_us: (1e6 / rate_hz).round() as u32,
        }
    }
}

/// What emplan asks for on connect: battery and position at 10 Hz (for the integral and the
/// 4 m crossing), mission progress and landed state at 2 Hz. HEARTBEAT and MISSION_ITEM_REACHED
/// are not streams (sent at 1 Hz and on events) and are not requested.
pub fn default_streams() -> Vec<StreamRequest> {
    vec![
        StreamRequest::of::<mav::BATTERY_STATUS_DATA>(10.0),
        StreamRequest::of::<mav::SYS_STATUS_DATA>(10.0),
        StreamRequest::of::<mav::GLOBAL_POSITION_INT_DATA>(10.0),
        StreamRequest::of::<mav::LOCAL_POSITION_NED_DATA>(10.0),
        // 10 Hz: a leg begins when the item changes; a lost change is caught by the next one.
        StreamRequest::of::<mav::MISSION_CURRENT_DATA>(10.0),
        StreamRequest::of::<mav::EXTENDED_SYS_STATE_DATA>(2.0),
    ]
}

/// How a rate request ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RequestOutcome {
    Pending,
    Accepted,
    /// The autopilot answered with a refusal (DENIED, UNSUPPORTED, FAILED, ...), by name.
    Refused {
        result: String,
    },
    /// No COMMAND_ACK after every attempt.
    NoAck {
        attempts: u32,
    },
}

/// Timing and addressing of the rate requests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamConfig {
    pub target_system: u8,
    pub target_component: u8,
    /// Who we are: acks addressed to another ground station are not ours.
    pub own_system: u8,
    pub own_component: u8,
    /// Wait for an ack before resending.
    pub timeout: Duration,
    /// Resends after the first attempt before giving up on one message.
    pub retries: u32,
    /// After an ack, wait this long before the next request and ignore acks meanwhile: a
    /// COMMAND_ACK does not say which message it is for, so a duplicated ack must not be taken
    /// for the next request's.
    pub quiet: Duration,
}

impl Default for StreamConfig {
    fn default() -> Self {
        StreamConfig {
            target_system: 1,
            target_component: 1,
            own_system: 255,
            own_component: 190,
            timeout: Duration::from_secs(1),
            retries: 5,
            quiet: Duration::from_millis(200),
        }
    }
}

/// Counters of what the requests saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StreamStats {
    pub sent: u32,
    /// Acks that arrived while no request was outstanding (duplicates, late answers).
    pub ignored_acks: u32,
}

/// Requests stream rates with MAV_CMD_SET_MESSAGE_INTERVAL, one message at a time (an ack does
/// not name the message it answers), resending each until its COMMAND_ACK; a refusal is
/// recorded and the next message asked for. `restart` asks for all again (after a reconnect:
/// rates are per link and reset on reboot). Sans-IO: `start`, `handle`, `tick` return the
/// messages to send.
#[derive(Debug, Clone)]
pub struct StreamRequests {
    cfg: StreamConfig,
    wanted: Vec<StreamRequest>,
    outcomes: Vec<RequestOutcome>,
    /// The request outstanding, its attempts so far and resend deadline.
    current: Option<(usize, u32, Duration)>,
    /// The next request to send and when.
    next: Option<(usize, Duration)>,
    pub stats: StreamStats,
}

impl StreamRequests {
    pub fn new(cfg: StreamConfig, wanted: Vec<StreamRequest>) -> StreamRequests {
        let outcomes = vec![RequestOutcome::Pending; wanted.len()];
        StreamRequests {
            cfg,
            wanted,
            outcomes,
            current: None,
            next: None,
            stats: StreamStats::default(),
        }
    }

    /// Every request with its outcome so far.
    pub fn outcomes(&self) -> Vec<(StreamRequest, RequestOutcome)> {
        self.wanted
            .iter()
            .copied()
            .zip(self.outcomes.iter().cloned())
            .collect()
    }

    /// Names of the messages whose rate the autopilot accepted.
    pub fn accepted(&self) -> Vec<&'static str> {
        self.outcomes()
            .into_iter()
            .filter(|(_, o)| *o == RequestOutcome::Accepted)
            .map(|(r, _)| r.name)
            .collect()
    }

    /// Whether every request has an outcome.
    pub fn finished(&self) -> bool {
        self.current.is_none() && self.next.is_none()
    }

    fn command(&self, index: usize, confirmation: u32) -> MavMessage {
        let request = self.wanted[index];
        MavMessage::COMMAND_LONG(mav::COMMAND_LONG_DATA {
            param1: request.message_id as f32,
            param2: request.interval_us as f32,
            // param7 0: the flight stack's default target (MAVLink SET_MESSAGE_INTERVAL).
            command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            target_system: self.cfg.target_system,
            target_component: self.cfg.target_component,
            confirmation: confirmation.min(255) as u8,
            ..Default::default()
        })
    }

    fn send(&mut self, now: Duration, index: usize, attempts: u32) -> Vec<MavMessage> {
        self.current = Some((index, attempts + 1, now + self.cfg.timeout));
        self.stats.sent += 1;
        vec![self.command(index, attempts)]
    }

    /// Sends the first request.
    pub fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        self.current = None;
        self.next = None;
        if self.wanted.is_empty() {
            return Vec::new();
        }
        self.send(now, 0, 0)
    }

    /// Forgets every outcome and asks for all again (after a reconnect).
    pub fn restart(&mut self, now: Duration) -> Vec<MavMessage> {
        self.outcomes = vec![RequestOutcome::Pending; self.wanted.len()];
        self.start(now)
    }

    fn settle(&mut self, now: Duration, index: usize, outcome: RequestOutcome) -> Vec<MavMessage> {
        self.outcomes[index] = outcome;
        self.current = None;
        self.next = (index + 1 < self.wanted.len()).then_some((index + 1, now + self.cfg.quiet));
        self.tick(now)
    }

    /// Takes in a message from the autopilot; only COMMAND_ACKs of SET_MESSAGE_INTERVAL matter.
    pub fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        let MavMessage::COMMAND_ACK(ack) = message else {
            return Vec::new();
        };
        if ack.command != MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL {
            return Vec::new();
        }
        let for_other = (ack.target_system != 0 && ack.target_system != self.cfg.own_system)
            || (ack.target_component != 0 && ack.target_component != self.cfg.own_component);
        if for_other {
            return Vec::new();
        }
        let Some((index, attempts, _)) = self.current else {
            self.stats.ignored_acks += 1;
            return Vec::new();
        };
        match ack.result {
            MavResult::MAV_RESULT_ACCEPTED => self.settle(now, index, RequestOutcome::Accepted),
            MavResult::MAV_RESULT_IN_PROGRESS => {
                self.current = Some((index, attempts, now + self.cfg.timeout));
                Vec::new()
            }
            // Try again at the deadline.
            MavResult::MAV_RESULT_TEMPORARILY_REJECTED => Vec::new(),
            refused => self.settle(
                now,
                index,
                RequestOutcome::Refused {
                    result: format!("{refused:?}"),
                },
            ),
        }
    }

    /// Resends on timeout, gives up after the retries, and sends the next request when its
    /// quiet time has passed.
    pub fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        if let Some((index, attempts, deadline)) = self.current {
            if now < deadline {
                return Vec::new();
            }
            if attempts <= self.cfg.retries {
                return self.send(now, index, attempts);
            }
            return self.settle(now, index, RequestOutcome::NoAck { attempts });
        }
        match self.next {
            Some((index, at)) if now >= at => {
                self.next = None;
                self.send(now, index, 0)
            }
            _ => Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::link::mav::{self, MavCmd, MavMessage, MavResult};

    fn ack(result: MavResult) -> MavMessage {
        MavMessage::COMMAND_ACK(mav::COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            result,
            target_system: 255,
            target_component: 190,
            ..Default::default()
        })
    }

    fn requested(messages: &[MavMessage]) -> Vec<(u32, u8)> {
        messages
            .iter()
            .filter_map(|m| match m {
                MavMessage::COMMAND_LONG(c)
                    if c.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL =>
                {
                    Some((c.param1 as u32, c.confirmation))
                }
                _ => None,
            })
            .collect()
    }

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn requests_go_one_at_a_time_each_after_the_previous_ack_and_a_quiet_time() {
        let wanted = default_streams();
        let mut m = StreamRequests::new(StreamConfig::default(), wanted.clone());
        let first = m.start(Duration::ZERO);
        assert_eq!(requested(&first), vec![(147, 0)]);
        let MavMessage::COMMAND_LONG(c) = &first[0] else {
            panic!("a command");
        };
        assert_eq!(
            (c.param2, c.target_system, c.target_component),
            (100_000.0, 1, 1)
        );
        let mut now = Duration::ZERO;
        let mut sent = vec![147];
        for _ in 1..wanted.len() {
            now += 5 * MS;
            assert!(m
                .handle(now, &ack(MavResult::MAV_RESULT_ACCEPTED))
                .is_empty());
            assert!(m.tick(now + 199 * MS).is_empty(), "still quiet");
            now += 200 * MS;
            let next = requested(&m.tick(now));
            assert_eq!(next.len(), 1);
            sent.push(next[0].0);
        }
        m.handle(now + MS, &ack(MavResult::MAV_RESULT_ACCEPTED));
        assert!(m.finished());
        assert_eq!(
            sent,
            wanted.iter().map(|w| w.message_id).collect::<Vec<_>>()
        );
        assert_eq!(m.accepted().len(), wanted.len());
    }

    #[test]
    fn a_request_without_ack_is_resent_with_a_higher_confirmation_then_given_up() {
        let wanted = default_streams();
        let mut m = StreamRequests::new(StreamConfig::default(), wanted[..2].to_vec());
        m.start(Duration::ZERO);
        let mut confirmations = vec![0];
        for k in 1..=5u64 {
            let again = requested(&m.tick(Duration::from_secs(k)));
            assert_eq!(again.len(), 1);
            assert_eq!(again[0].0, 147);
            confirmations.push(again[0].1);
        }
        assert_eq!(confirmations, vec![0, 1, 2, 3, 4, 5]);
        // The sixth wait ends it: no ack after six attempts; the next message is asked for.
        assert!(m.tick(Duration::from_secs(6)).is_empty());
        assert_eq!(m.outcomes()[0].1, RequestOutcome::NoAck { attempts: 6 });
        let next = requested(&m.tick(Duration::from_secs(6) + 200 * MS));
        assert_eq!(next, vec![(1, 0)]);
    }

    #[test]
    fn a_refused_request_is_recorded_and_the_next_one_is_asked_for() {
        let mut m = StreamRequests::new(StreamConfig::default(), default_streams());
        m.start(Duration::ZERO);
        m.handle(MS, &ack(MavResult::MAV_RESULT_UNSUPPORTED));
        assert_eq!(
            m.outcomes()[0].1,
            RequestOutcome::Refused {
                result: "MAV_RESULT_UNSUPPORTED".into()
            }
        );
        assert_eq!(requested(&m.tick(300 * MS)), vec![(1, 0)]);
        m.handle(301 * MS, &ack(MavResult::MAV_RESULT_DENIED));
        assert!(matches!(m.outcomes()[1].1, RequestOutcome::Refused { .. }));
        assert!(m.accepted().is_empty());
    }

    #[test]
    fn a_duplicated_ack_is_not_taken_for_the_next_requests_answer() {
        let mut m = StreamRequests::new(StreamConfig::default(), default_streams());
        m.start(Duration::ZERO);
        m.handle(2 * MS, &ack(MavResult::MAV_RESULT_ACCEPTED));
        // The transport duplicates the ack; it arrives in the quiet time and is ignored.
        m.handle(3 * MS, &ack(MavResult::MAV_RESULT_ACCEPTED));
        assert_eq!(m.stats.ignored_acks, 1);
        assert_eq!(requested(&m.tick(205 * MS)), vec![(1, 0)]);
        // SYS_STATUS is refused by its own ack.
        m.handle(207 * MS, &ack(MavResult::MAV_RESULT_UNSUPPORTED));
        let outcomes = m.outcomes();
        assert_eq!(outcomes[0].1, RequestOutcome::Accepted);
        assert!(matches!(outcomes[1].1, RequestOutcome::Refused { .. }));
    }

    #[test]
    fn acks_of_other_commands_or_for_another_station_are_ignored() {
        let mut m = StreamRequests::new(StreamConfig::default(), default_streams());
        m.start(Duration::ZERO);
        let other_command = MavMessage::COMMAND_ACK(mav::COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            result: MavResult::MAV_RESULT_ACCEPTED,
            ..Default::default()
        });
        let other_station = MavMessage::COMMAND_ACK(mav::COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            result: MavResult::MAV_RESULT_ACCEPTED,
            target_system: 254,
            ..Default::default()
        });
        m.handle(MS, &other_command);
        m.handle(MS, &other_station);
        assert_eq!(m.outcomes()[0].1, RequestOutcome::Pending);
        assert_eq!(requested(&m.tick(Duration::from_secs(1))), vec![(147, 1)]);
    }

    #[test]
    fn in_progress_extends_the_wait_and_temporarily_rejected_retries_at_the_deadline() {
        let mut m = StreamRequests::new(StreamConfig::default(), default_streams());
        m.start(Duration::ZERO);
        m.handle(900 * MS, &ack(MavResult::MAV_RESULT_IN_PROGRESS));
        assert!(
            m.tick(Duration::from_millis(1500)).is_empty(),
            "still waiting"
        );
        m.handle(1600 * MS, &ack(MavResult::MAV_RESULT_TEMPORARILY_REJECTED));
        assert_eq!(
            requested(&m.tick(Duration::from_millis(1900))),
            vec![(147, 1)]
        );
        m.handle(1950 * MS, &ack(MavResult::MAV_RESULT_ACCEPTED));
        assert_eq!(m.outcomes()[0].1, RequestOutcome::Accepted);
    }

    #[test]
    fn restart_asks_for_every_stream_again() {
        let mut m = StreamRequests::new(StreamConfig::default(), default_streams()[..2].to_vec());
        m.start(Duration::ZERO);
        m.handle(MS, &ack(MavResult::MAV_RESULT_ACCEPTED));
        m.tick(300 * MS);
        m.handle(301 * MS, &ack(MavResult::MAV_RESULT_ACCEPTED));
        assert!(m.finished() && m.accepted().len() == 2);
        let again = m.restart(Duration::from_secs(10));
        assert_eq!(requested(&again), vec![(147, 0)]);
        assert!(!m.finished());
        assert!(m
            .outcomes()
            .iter()
            .all(|(_, o)| *o != RequestOutcome::Accepted));
    }
}
