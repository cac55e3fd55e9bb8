//! Sending the vehicle home in flight (the energy guard's `rtl` action), as a sans-IO machine
//! (`start(now)`, `handle(now, message)`, `tick(now)` return the messages to send):
//! MAV_CMD_NAV_RETURN_TO_LAUNCH, which PX4 (commander: AUTO.RTL) and ArduCopter
//! (`GCS_MAVLINK_Copter`: mode RTL) both accept from a ground station. The command is resent
//! every retry period until it is acknowledged ACCEPTED, or a heartbeat shows the autopilot in
//! its return mode (the ack was lost); DENIED, FAILED or UNSUPPORTED end it at once, with the
//! autopilot's last warning; nothing within the budget ends it as a timeout. Either way the
//! caller is told, loudly: a vehicle that was not sent home is still flying its mission.

use std::time::Duration;

use super::connection::Autopilot;
use super::flight::{ardupilot_mode, warning};
use super::mav::{MavAutopilot, MavCmd, MavMessage, MavModeFlag, MavResult, COMMAND_LONG_DATA};
use super::Flavour;

/// PX4's main mode AUTO and its sub-mode RTL (px4_custom_mode.h), as HEARTBEAT's custom_mode
/// carries them (main mode in bits 16-23, sub-mode in bits 24-31).
const PX4_AUTO: u32 = 4;
const PX4_AUTO_RTL: u32 = 5;

/// Timing of [`ReturnHome`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReturnConfig {
    /// Resend the command when no answer came within this.
    pub retry: Duration,
    /// Give up after this.
    pub budget: Duration,
}

impl Default for ReturnConfig {
    fn default() -> Self {
        ReturnConfig {
            retry: Duration::from_millis(500),
            budget: Duration::from_secs(10),
        }
    }
}

/// Why the vehicle could not be sent home.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReturnError {
    #[error("return to launch refused by the autopilot ({result:?}){}", suffix(.statustext))]
    Refused {
        result: MavResult,
        statustext: Option<String>,
    },
    #[error(
        "return to launch not acknowledged within {budget_s} s ({attempts} attempts){}",
        suffix(.statustext)
    )]
    Timeout {
        budget_s: f64,
        attempts: u32,
        statustext: Option<String>,
    },
}

fn suffix(text: &Option<String>) -> String {
    text.as_ref()
        .map_or_else(String::new, |t| format!(": the autopilot said \"{t}\""))
}

/// Whether a heartbeat's custom mode is `flavour`'s return mode.
pub fn is_return_mode(flavour: Flavour, custom_mode: u32) -> bool {
    match flavour {
        Flavour::ArduPilot => custom_mode == ardupilot_mode::RTL,
        Flavour::Px4 | Flavour::Generic => {
            (custom_mode >> 16) & 0xff == PX4_AUTO && (custom_mode >> 24) & 0xff == PX4_AUTO_RTL
        }
    }
}

/// Sends `target` home.
#[derive(Debug, Clone)]
pub struct ReturnHome {
    target: Autopilot,
    cfg: ReturnConfig,
    started: Duration,
    next_send: Duration,
    attempts: u32,
    statustext: Option<String>,
    result: Option<Result<(), ReturnError>>,
}

impl ReturnHome {
    pub fn new(target: Autopilot, cfg: ReturnConfig) -> ReturnHome {
        ReturnHome {
            target,
            cfg,
            started: Duration::ZERO,
            next_send: Duration::ZERO,
            attempts: 0,
            statustext: None,
            result: None,
        }
    }

    /// The outcome, once finished.
    pub fn finished(&self) -> Option<&Result<(), ReturnError>> {
        self.result.as_ref()
    }

    fn send(&mut self, now: Duration) -> Vec<MavMessage> {
        self.attempts += 1;
        self.next_send = now + self.cfg.retry;
        vec![MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH,
            target_system: self.target.system_id,
            target_component: self.target.component_id,
            confirmation: (self.attempts - 1).min(255) as u8,
            ..Default::default()
        })]
    }

    /// Sends the command.
    pub fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        self.started = now;
        self.send(now)
    }

    /// Reacts to a message from the target autopilot.
    pub fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        if self.result.is_some() {
            return Vec::new();
        }
        match message {
            MavMessage::HEARTBEAT(hb)
                if hb.autopilot != MavAutopilot::MAV_AUTOPILOT_INVALID
                    && hb
                        .base_mode
                        .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
                    && is_return_mode(self.target.flavour, hb.custom_mode) =>
            {
                self.result = Some(Ok(()));
            }
            MavMessage::COMMAND_ACK(ack) if ack.command == MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => {
                match ack.result {
                    MavResult::MAV_RESULT_ACCEPTED => self.result = Some(Ok(())),
                    MavResult::MAV_RESULT_IN_PROGRESS => self.next_send = now + self.cfg.retry,
                    MavResult::MAV_RESULT_TEMPORARILY_REJECTED => {}
                    other => {
                        self.result = Some(Err(ReturnError::Refused {
                            result: other,
                            statustext: self.statustext.clone(),
                        }))
                    }
                }
            }
            MavMessage::STATUSTEXT(text) => {
                if let Some(t) = warning(text) {
                    self.statustext = Some(t);
                }
            }
            _ => {}
        }
        Vec::new()
    }

    /// Resends the command; gives up when the budget is spent.
    pub fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        if self.result.is_some() {
            return Vec::new();
        }
        if now.saturating_sub(self.started) >= self.cfg.budget {
            self.result = Some(Err(ReturnError::Timeout {
                budget_s: self.cfg.budget.as_secs_f64(),
                attempts: self.attempts,
                statustext: self.statustext.clone(),
            }));
            return Vec::new();
        }
        if now >= self.next_send {
            return self.send(now);
        }
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::mav::{
        MavSeverity, MavState, MavType, COMMAND_ACK_DATA, HEARTBEAT_DATA, STATUSTEXT_DATA,
    };
    use crate::link::testing::ms;

    use crate::link::testing::autopilot as target;

    fn sent(out: &[MavMessage]) -> usize {
        out.iter()
            .filter(|m| {
                matches!(m, MavMessage::COMMAND_LONG(c)
                    if c.command == MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH
                        && c.target_system == 1)
            })
            .count()
    }

    fn ack(result: MavResult) -> MavMessage {
        MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH,
            result,
            ..Default::default()
        })
    }

    fn heartbeat(custom_mode: u32) -> MavMessage {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode,
            mavtype: MavType::MAV_TYPE_OCTOROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            base_mode: MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
                | MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED,
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        })
    }

    #[test]
    fn the_command_is_resent_until_acknowledged() {
        let mut m = ReturnHome::new(target(Flavour::Px4), ReturnConfig::default());
        assert_eq!(sent(&m.start(ms(0))), 1);
        assert!(m.tick(ms(200)).is_empty());
        assert_eq!(sent(&m.tick(ms(500))), 1);
        assert!(m
            .handle(ms(600), &ack(MavResult::MAV_RESULT_ACCEPTED))
            .is_empty());
        assert_eq!(m.finished(), Some(&Ok(())));
        assert!(m.tick(ms(2000)).is_empty());
    }

    #[test]
    fn a_heartbeat_in_the_return_mode_stands_for_a_lost_ack() {
        // PX4: AUTO.MISSION (sub-mode 4) is not RTL; AUTO.RTL is.
        let mut m = ReturnHome::new(target(Flavour::Px4), ReturnConfig::default());
        m.start(ms(0));
        m.handle(ms(100), &heartbeat((4 << 16) | (4 << 24)));
        assert_eq!(m.finished(), None);
        m.handle(ms(200), &heartbeat((4 << 16) | (5 << 24)));
        assert_eq!(m.finished(), Some(&Ok(())));
        // ArduCopter: AUTO (3) is not RTL (6).
        let mut a = ReturnHome::new(target(Flavour::ArduPilot), ReturnConfig::default());
        a.start(ms(0));
        a.handle(ms(100), &heartbeat(3));
        assert_eq!(a.finished(), None);
        a.handle(ms(100), &heartbeat(6));
        assert_eq!(a.finished(), Some(&Ok(())));
    }

    #[test]
    fn a_refusal_ends_it_at_once_naming_the_autopilots_warning() {
        let mut m = ReturnHome::new(target(Flavour::ArduPilot), ReturnConfig::default());
        m.start(ms(0));
        let mut text = [0u8; 50];
        text[..16].copy_from_slice(b"RTL: no position");
        m.handle(
            ms(50),
            &MavMessage::STATUSTEXT(STATUSTEXT_DATA {
                severity: MavSeverity::MAV_SEVERITY_WARNING,
                text: text.into(),
                ..Default::default()
            }),
        );
        m.handle(ms(60), &ack(MavResult::MAV_RESULT_FAILED));
        let err = m.finished().unwrap().clone().unwrap_err();
        assert!(
            err.to_string().contains("MAV_RESULT_FAILED")
                && err.to_string().contains("RTL: no position"),
            "{err}"
        );
    }

    #[test]
    fn no_answer_within_the_budget_is_a_timeout() {
        let cfg = ReturnConfig {
            retry: ms(500),
            budget: ms(2000),
        };
        let mut m = ReturnHome::new(target(Flavour::Px4), cfg);
        let mut n = sent(&m.start(ms(0)));
        let mut t = 0;
        while m.finished().is_none() {
            t += 50;
            n += sent(&m.tick(ms(t)));
        }
        assert_eq!(n, 4);
        assert!(matches!(
            m.finished(),
            Some(Err(ReturnError::Timeout { attempts: 4, .. }))
        ));
    }
}
