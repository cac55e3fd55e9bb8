//! The pack the autopilot names: SMART_BATTERY_INFO asked for with MAV_CMD_REQUEST_MESSAGE
//! (message 370) before a flight, its serial number (else its device name) taken as the pack's
//! name (`telemetry::pack_named`). A sans-IO machine: `start`, `handle`, `tick` return the
//! messages to send.
//!
//! An autopilot with a smart battery (PX4 with a battery driver that reports a serial,
//! ArduPilot with a smart-battery monitor) answers with the message; one without refuses the
//! request (PX4's `MavlinkReceiver` answers MAV_RESULT_FAILED when the stream has nothing to
//! send) or says nothing, and the machine gives up at once on a refusal, else after its budget:
//! the flight goes on without a pack named.
//!
//! SMART_BATTERY_INFO is marked superseded (2024-02) by BATTERY_INFO (372); it is the one the
//! released PX4 and ArduPilot send for a smart battery, so it is the one asked for here.

// The superseded message is the one asked for (above).
#![allow(deprecated)]

use std::time::Duration;

use mavlink::MessageData;

use super::connection::Autopilot;
use super::mav::{MavCmd, MavMessage, MavResult, SMART_BATTERY_INFO_DATA};

/// Timing of [`AskPack`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AskPackConfig {
    /// Ask again when no answer came within this.
    pub retry: Duration,
    /// Give up (no pack named) after this.
    pub budget: Duration,
}

impl Default for AskPackConfig {
    fn default() -> Self {
        // Both autopilots answer a request within a round trip; three tries over a lossy radio,
        // and a vehicle without a smart battery costs a flight at most this.
        AskPackConfig {
            retry: Duration::from_millis(700),
            budget: Duration::from_secs(2),
        }
    }
}

/// Asks the autopilot for SMART_BATTERY_INFO until it comes, is refused, or the budget runs
/// out.
#[derive(Debug, Clone)]
pub struct AskPack {
    target: Autopilot,
    cfg: AskPackConfig,
    started: Duration,
    next_send: Duration,
    requests: u32,
    /// Finished: the name the pack gave (None: none, refused or not answered).
    result: Option<Option<String>>,
}

impl AskPack {
    pub fn new(target: Autopilot, cfg: AskPackConfig) -> AskPack {
        AskPack {
            target,
            cfg,
            started: Duration::ZERO,
            next_send: Duration::ZERO,
            requests: 0,
            result: None,
        }
    }

    /// Once finished: the pack's name, None when the autopilot named none.
    pub fn finished(&self) -> Option<Option<String>> {
        self.result.clone()
    }

    /// Requests sent so far.
    pub fn requests(&self) -> u32 {
        self.requests
    }

    fn request(&mut self, now: Duration) -> Vec<MavMessage> {
        self.requests += 1;
        self.next_send = now + self.cfg.retry;
        vec![super::request_message(
            &self.target,
            SMART_BATTERY_INFO_DATA::ID,
        )]
    }

    pub fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        self.started = now;
        self.request(now)
    }

    pub fn handle(&mut self, _now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        if self.result.is_some() {
            return Vec::new();
        }
        match message {
            MavMessage::SMART_BATTERY_INFO(info) => {
                self.result = Some(super::telemetry::pack_named(info));
            }
            MavMessage::COMMAND_ACK(a)
                if a.command == MavCmd::MAV_CMD_REQUEST_MESSAGE
                    && !matches!(
                        a.result,
                        MavResult::MAV_RESULT_ACCEPTED
                            | MavResult::MAV_RESULT_IN_PROGRESS
                            | MavResult::MAV_RESULT_TEMPORARILY_REJECTED
                    ) =>
            {
                self.result = Some(None);
            }
            _ => {}
        }
        Vec::new()
    }

    pub fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        if self.result.is_some() {
            return Vec::new();
        }
        if now.saturating_sub(self.started) >= self.cfg.budget {
            self.result = Some(None);
            return Vec::new();
        }
        if now >= self.next_send {
            return self.request(now);
        }
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::mav::COMMAND_ACK_DATA;
    use crate::link::Flavour;

    fn ms(t: u64) -> Duration {
        Duration::from_millis(t)
    }

    fn ask() -> AskPack {
        let target = Autopilot {
            system_id: 1,
            component_id: 1,
            flavour: Flavour::Px4,
        };
        AskPack::new(target, AskPackConfig::default())
    }

    fn ack(result: MavResult) -> MavMessage {
        MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_REQUEST_MESSAGE,
            result,
            ..Default::default()
        })
    }

    #[test]
    fn the_pack_is_the_serial_the_autopilot_answers_with() {
        let mut a = ask();
        let sent = a.start(ms(0));
        assert!(matches!(&sent[..], [MavMessage::COMMAND_LONG(c)]
            if c.command == MavCmd::MAV_CMD_REQUEST_MESSAGE && c.param1 == 370.0));
        a.handle(ms(10), &ack(MavResult::MAV_RESULT_ACCEPTED));
        assert_eq!(a.finished(), None);
        let info = MavMessage::SMART_BATTERY_INFO(SMART_BATTERY_INFO_DATA {
            serial_number: "P-7".into(),
            ..Default::default()
        });
        a.handle(ms(20), &info);
        assert_eq!(a.finished(), Some(Some("P-7".to_string())));
    }

    #[test]
    fn a_refused_request_ends_at_once_without_a_pack() {
        let mut a = ask();
        a.start(ms(0));
        a.handle(ms(5), &ack(MavResult::MAV_RESULT_FAILED));
        assert_eq!(a.finished(), Some(None));
        assert!(a.tick(ms(800)).is_empty());
    }

    #[test]
    fn an_unanswered_request_is_resent_then_given_up_after_the_budget() {
        let mut a = ask();
        a.start(ms(0));
        assert!(a.tick(ms(500)).is_empty());
        assert_eq!(a.tick(ms(700)).len(), 1);
        assert_eq!(a.tick(ms(1400)).len(), 1);
        assert!(a.tick(ms(2000)).is_empty());
        assert_eq!((a.finished(), a.requests()), (Some(None), 3));
    }
}
