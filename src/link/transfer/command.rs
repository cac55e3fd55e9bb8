//! One-message commands that wait for their confirmation: MISSION_CLEAR_ALL (confirmed by a
//! MISSION_ACK; a refusal is surfaced by its result) and MISSION_SET_CURRENT (confirmed by
//! MISSION_CURRENT with that seq). Resent on the measured timeout until confirmed or out of
//! time.

use std::time::Duration;

use super::rto::Rto;
use super::{Action, Spent, Stage, TransferConfig, TransferError, Waiting, MISSION};
#[allow(deprecated)]
use crate::link::mav::{
    MavMessage, MavMissionResult, MavMissionType, MISSION_CLEAR_ALL_DATA, MISSION_SET_CURRENT_DATA,
};

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    /// Clears the list of this type.
    ClearAll(MavMissionType),
    SetCurrent(u16),
}

/// A command waiting for its confirmation.
#[derive(Debug, Clone)]
pub struct Command {
    cfg: TransferConfig,
    rto: Rto,
    kind: Kind,
    started: Duration,
    ends: Duration,
    wake: Duration,
    attempt: u32,
    sent: u32,
    result: Option<Result<(), TransferError>>,
}

impl Command {
    fn new(cfg: TransferConfig, rto: Rto, kind: Kind) -> Command {
        Command {
            cfg,
            rto,
            kind,
            started: Duration::ZERO,
            ends: Duration::ZERO,
            wake: Duration::ZERO,
            attempt: 0,
            sent: 0,
            result: None,
        }
    }

    /// Clears the autopilot's mission.
    pub fn clear_all(cfg: TransferConfig, rto: Rto) -> Command {
        Command::new(cfg, rto, Kind::ClearAll(MISSION))
    }

    /// Clears the autopilot's list of `mission_type` (its mission, fence or rally points).
    pub fn clear_type(mission_type: MavMissionType, cfg: TransferConfig, rto: Rto) -> Command {
        Command::new(cfg, rto, Kind::ClearAll(mission_type))
    }

    /// Makes item `seq` the current one.
    pub fn set_current(cfg: TransferConfig, rto: Rto, seq: u16) -> Command {
        Command::new(cfg, rto, Kind::SetCurrent(seq))
    }

    /// The outcome, once finished.
    pub fn finished(&self) -> Option<&Result<(), TransferError>> {
        self.result.as_ref()
    }

    /// When `tick` is next due; None once finished.
    pub fn wake(&self) -> Option<Duration> {
        self.result.is_none().then(|| self.wake.min(self.ends))
    }

    fn stage(&self) -> Stage {
        match self.kind {
            Kind::ClearAll(_) => Stage::Clear,
            Kind::SetCurrent(_) => Stage::SetCurrent,
        }
    }

    // MISSION_SET_CURRENT is superseded by MAV_CMD_DO_SET_MISSION_CURRENT (2022) but PX4 and
    // ArduPilot still answer it with MISSION_CURRENT, and older firmware knows only it.
    #[allow(deprecated)]
    fn message(&mut self) -> Action {
        self.sent += 1;
        let (target_system, target_component) = (self.cfg.target_system, self.cfg.target_component);
        Action::Send(match self.kind {
            Kind::ClearAll(mission_type) => MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
                target_system,
                target_component,
                mission_type,
            }),
            Kind::SetCurrent(seq) => MavMessage::MISSION_SET_CURRENT(MISSION_SET_CURRENT_DATA {
                seq,
                target_system,
                target_component,
            }),
        })
    }

    /// Sends the command.
    pub fn start(&mut self, now: Duration) -> Vec<Action> {
        self.started = now;
        self.ends = now + self.cfg.budget_for(0);
        self.wake = now + self.rto.timeout(0);
        vec![self.message()]
    }

    /// Reacts to the autopilot's answer.
    pub fn handle(&mut self, _now: Duration, message: &MavMessage) -> Vec<Action> {
        if self.result.is_some() {
            return Vec::new();
        }
        match (self.kind, message) {
            (Kind::ClearAll(kind), MavMessage::MISSION_ACK(a)) if a.mission_type == kind => {
                self.result = Some(if a.mavtype == MavMissionResult::MAV_MISSION_ACCEPTED {
                    Ok(())
                } else {
                    Err(TransferError::Refused {
                        stage: Stage::Clear,
                        item: None,
                        result: a.mavtype,
                    })
                });
            }
            (Kind::SetCurrent(seq), MavMessage::MISSION_CURRENT(c)) if c.seq == seq => {
                self.result = Some(Ok(()))
            }
            _ => {}
        }
        Vec::new()
    }

    /// Resends, or gives up when out of time.
    pub fn tick(&mut self, now: Duration) -> Vec<Action> {
        if self.result.is_some() || now < self.wake.min(self.ends) {
            return Vec::new();
        }
        if now >= self.ends {
            let item = match self.kind {
                Kind::SetCurrent(seq) => Some(seq),
                Kind::ClearAll(_) => None,
            };
            let spent = Spent {
                started: self.started,
                now,
                sent: self.sent,
                restarts: 0,
                refusal: None,
            };
            let err = TransferError::out_of_time(self.stage(), item, Waiting::Confirmation, spent);
            self.result = Some(Err(err));
            return Vec::new();
        }
        self.attempt += 1;
        self.wake = now + self.rto.timeout(self.attempt);
        vec![self.message()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::testing::{ack, ms};
    use crate::link::transfer::Timing;

    fn rto() -> Rto {
        Rto::new(Timing::default())
    }

    #[test]
    fn clear_all_resends_until_acked_and_surfaces_a_refusal_by_name() {
        let mut clear = Command::clear_all(TransferConfig::default(), rto());
        assert!(matches!(
            clear.start(ms(0)).as_slice(),
            [Action::Send(MavMessage::MISSION_CLEAR_ALL(_))]
        ));
        assert!(matches!(
            clear.tick(ms(1000)).as_slice(),
            [Action::Send(MavMessage::MISSION_CLEAR_ALL(_))]
        ));
        clear.handle(ms(1100), &ack(MavMissionResult::MAV_MISSION_ACCEPTED));
        assert_eq!(clear.finished(), Some(&Ok(())));
        let mut refused = Command::clear_all(TransferConfig::default(), rto());
        refused.start(ms(0));
        refused.handle(ms(5), &ack(MavMissionResult::MAV_MISSION_DENIED));
        assert!(matches!(
            refused.finished(),
            Some(Err(TransferError::Refused {
                stage: Stage::Clear,
                result: MavMissionResult::MAV_MISSION_DENIED,
                ..
            }))
        ));
    }

    #[test]
    fn set_current_waits_for_mission_current_with_that_seq_within_its_budget() {
        let cfg = TransferConfig {
            budget: Some(ms(2500)),
            ..TransferConfig::default()
        };
        let mut set = Command::set_current(cfg, rto(), 3);
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
        let mut lost = Command::set_current(cfg, rto(), 3);
        lost.start(ms(0));
        while lost.finished().is_none() {
            let now = lost.wake().unwrap();
            lost.tick(now);
        }
        assert_eq!(
            lost.finished().unwrap().clone().unwrap_err().to_string(),
            "set-current: gave up after 2.5 s (the time budget) waiting for the confirmation; \
             2 messages sent, 0 fresh starts"
        );
    }

    #[test]
    fn clearing_the_fence_sends_a_fence_clear_and_waits_for_the_fence_ack() {
        use crate::link::mav::{MavMissionType, MISSION_ACK_DATA};
        let fence = MavMissionType::MAV_MISSION_TYPE_FENCE;
        let mut clear = Command::clear_type(fence, TransferConfig::default(), rto());
        assert!(matches!(
            clear.start(ms(0)).first(),
            Some(Action::Send(MavMessage::MISSION_CLEAR_ALL(c))) if c.mission_type == fence
        ));
        let ack_of = |mission_type| {
            MavMessage::MISSION_ACK(MISSION_ACK_DATA {
                mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
                mission_type,
                ..Default::default()
            })
        };
        clear.handle(ms(5), &ack_of(MISSION));
        assert!(clear.finished().is_none());
        clear.handle(ms(6), &ack_of(fence));
        assert_eq!(clear.finished(), Some(&Ok(())));
    }
}
