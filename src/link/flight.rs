//! Starting an uploaded mission the way each autopilot wants it, as a sans-IO machine
//! (`start(now)`, `handle(now, message)`, `tick(now)` return the messages to send):
//! - PX4: arm (MAV_CMD_COMPONENT_ARM_DISARM), then MAV_CMD_MISSION_START; PX4 switches to
//!   AUTO.MISSION, takes off and flies (as PX4 SITL does: sitl/README.md).
//! - ArduPilot: mode GUIDED (MAV_CMD_DO_SET_MODE, custom mode 4), arm, mode AUTO (custom mode
//!   3), MAV_CMD_MISSION_START (as ArduCopter SITL does: sitl/README.md; ArduCopter refuses to arm in
//!   AUTO: `Copter::ModeAuto::allows_arming` is false without AUTO_OPTIONS).
//!
//! Every command is resent until its COMMAND_ACK. An autopilot that is not ready yet is asked
//! again every retry period until the time budget runs out: TEMPORARILY_REJECTED at any step
//! (PX4's answer to an arming its pre-arm checks refuse, commander `handle_command`), and FAILED
//! before the vehicle is armed (ArduCopter's answer to a mode change or an arming while its
//! pre-arm checks fail after boot, GCS_Common.cpp), and DENIED of the mission start within a short
//! grace (PX4 checks a new mission asynchronously). DENIED, and FAILED once armed, are answers
//! that asking again does not change (PX4 "Mission start denied! No valid mission", ArduCopter
//! "Auto: Missing Takeoff Cmd"): the start fails at once. The warnings the autopilot sent
//! (STATUSTEXT of severity WARNING or worse: "PreArm: ...", "No valid mission") go into the
//! error. A step is done when it is acknowledged ACCEPTED, or when the autopilot's HEARTBEAT
//! already shows it (the ack was lost). The next step follows at once: PX4 disarms an armed
//! vehicle that has not taken off within COM_DISARM_PRFLT (10 s), and its HEARTBEAT comes once a
//! second, so waiting for the heartbeat to confirm the arming would spend a tenth of that; the
//! recorder sees the flight begin from the heartbeats anyway.
//!
//! A start that fails after it armed the vehicle disarms it (not forced: an autopilot refuses
//! to disarm in the air), resent until acknowledged or shown by a heartbeat, for at most
//! [`DISARM_BUDGET`]; the error says whether it did.

use std::time::Duration;

use super::connection::Autopilot;
use super::mav::{
    MavCmd, MavMessage, MavModeFlag, MavResult, MavSeverity, COMMAND_ACK_DATA, COMMAND_LONG_DATA,
    HEARTBEAT_DATA,
};
use super::Flavour;

/// ArduCopter's flight modes we use (`custom_mode` numbers, ArduCopter/mode.h `Mode::Number`).
pub mod ardupilot_mode {
    pub const AUTO: u32 = 3;
    pub const GUIDED: u32 = 4;
    pub const LAND: u32 = 9;
    pub const RTL: u32 = 6;
}

/// The text of an autopilot's warning (STATUSTEXT of severity WARNING or worse: "PreArm: ...",
/// "No valid mission"), None for its information ("Armed by ...") or an empty text.
pub(super) fn warning(text: &super::mav::STATUSTEXT_DATA) -> Option<String> {
    if text.severity as u8 > MavSeverity::MAV_SEVERITY_WARNING as u8 {
        return None;
    }
    let t = String::from_utf8_lossy(&text.text.to_vec())
        .trim_end_matches('\0')
        .to_string();
    (!t.is_empty()).then_some(t)
}

/// One step of starting a mission.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Step {
    /// ArduPilot: switch to GUIDED so that arming is allowed.
    Guided,
    Arm,
    /// ArduPilot: switch to AUTO.
    Auto,
    MissionStart,
}

impl std::fmt::Display for Step {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Step::Guided => "mode GUIDED",
            Step::Arm => "arming",
            Step::Auto => "mode AUTO",
            Step::MissionStart => "mission start",
        })
    }
}

/// The longest a failed start spends disarming the vehicle it armed.
pub const DISARM_BUDGET: Duration = Duration::from_secs(3);

/// Why a mission could not be started.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StartError {
    #[error(
        "{step}: refused by the autopilot ({result:?}){}{}",
        statustext_suffix(.statustext),
        disarm_suffix(*.disarmed)
    )]
    Refused {
        step: Step,
        result: MavResult,
        /// The autopilot's last warning (STATUSTEXT), often the reason ("PreArm: ...").
        statustext: Option<String>,
        /// After the start had armed the vehicle: whether it disarmed again (None: the start
        /// had not armed it).
        disarmed: Option<bool>,
    },
    #[error(
        "{step}: not done within {budget_s:.0} s ({attempts} commands sent, last answer: {}){}{}",
        .last.map(|r| format!("{r:?}")).unwrap_or_else(|| "none".into()),
        statustext_suffix(.statustext),
        disarm_suffix(*.disarmed)
    )]
    Timeout {
        step: Step,
        budget_s: f64,
        attempts: u32,
        last: Option<MavResult>,
        statustext: Option<String>,
        disarmed: Option<bool>,
    },
}

impl StartError {
    /// Whether the start had armed the vehicle before it failed.
    pub fn armed(&self) -> bool {
        self.disarmed().is_some()
    }

    /// The autopilot's answer to the step that failed (its last one, for a timeout).
    pub fn result(&self) -> Option<MavResult> {
        match self {
            StartError::Refused { result, .. } => Some(*result),
            StartError::Timeout { last, .. } => *last,
        }
    }

    /// After the start had armed the vehicle: whether it disarmed again (None: it had not
    /// armed it).
    pub fn disarmed(&self) -> Option<bool> {
        match self {
            StartError::Refused { disarmed, .. } | StartError::Timeout { disarmed, .. } => {
                *disarmed
            }
        }
    }

    fn set_disarm(&mut self, done: bool, text: Option<String>) {
        let (StartError::Refused {
            disarmed,
            statustext,
            ..
        }
        | StartError::Timeout {
            disarmed,
            statustext,
            ..
        }) = self;
        *disarmed = Some(done);
        if text.is_some() {
            *statustext = text;
        }
    }
}

fn statustext_suffix(text: &Option<String>) -> String {
    text.as_ref()
        .map(|t| format!("; the autopilot said: {t:?}"))
        .unwrap_or_default()
}

fn disarm_suffix(disarmed: Option<bool>) -> &'static str {
    match disarmed {
        None => "",
        Some(true) => "; disarmed again",
        Some(false) => "; the disarm was not acknowledged: the vehicle may still be armed",
    }
}

/// Timing of [`Start`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StartConfig {
    /// Resend a command not acknowledged within this time.
    pub retry: Duration,
    /// Give up a step that is not done within this time (SITL pre-arm checks take seconds
    /// after boot).
    pub budget: Duration,
    /// A mission start DENIED this soon after its step began is asked again: PX4 checks a
    /// newly uploaded mission asynchronously (its navigator's feasibility check sets the
    /// commander's `auto_mission_available`), and until then answers MISSION_START with DENIED
    /// "No valid mission". Past it, DENIED is the answer.
    pub mission_start_grace: Duration,
}

impl Default for StartConfig {
    fn default() -> Self {
        StartConfig {
            // Short: PX4 disarms an armed vehicle that has not taken off after COM_DISARM_PRFLT
            // (10 s; a tenth of that in wall time for SITL at 10x, a twentieth on the mock at
            // 20x), so a lost MISSION_START must be sent again well within it. A handful of
            // commands, not a flood.
            retry: Duration::from_millis(100),
            budget: Duration::from_secs(60),
            // Seen on PX4 SITL at 10x: a start right after a verified upload DENIED, the same
            // start a moment later accepted. 3 s is many navigator cycles, even at 10x.
            mission_start_grace: Duration::from_secs(3),
        }
    }
}

/// A failed start disarming the vehicle it had armed.
#[derive(Debug, Clone)]
struct Disarming {
    error: StartError,
    since: Duration,
    /// A warning the autopilot sent since the failure (its reason often follows its ack).
    statustext: Option<String>,
}

/// Starts the uploaded mission on `target`.
#[derive(Debug, Clone)]
pub struct Start {
    target: Autopilot,
    cfg: StartConfig,
    steps: Vec<Step>,
    index: usize,
    step_started: Duration,
    next_send: Duration,
    attempts: u32,
    acked: bool,
    last_result: Option<MavResult>,
    statustext: Option<String>,
    armed: bool,
    mode: Option<u32>,
    /// The arming step is done: a failure from now on disarms.
    armed_by_start: bool,
    disarming: Option<Disarming>,
    result: Option<Result<(), StartError>>,
}

impl Start {
    /// The steps for `target`'s flavour (PX4 and unknown autopilots: arm, mission start).
    pub fn new(target: Autopilot, cfg: StartConfig) -> Start {
        let steps = match target.flavour {
            Flavour::ArduPilot => vec![Step::Guided, Step::Arm, Step::Auto, Step::MissionStart],
            Flavour::Px4 | Flavour::Generic => vec![Step::Arm, Step::MissionStart],
        };
        Start {
            target,
            cfg,
            steps,
            index: 0,
            step_started: Duration::ZERO,
            next_send: Duration::ZERO,
            attempts: 0,
            acked: false,
            last_result: None,
            statustext: None,
            armed: false,
            mode: None,
            armed_by_start: false,
            disarming: None,
            result: None,
        }
    }

    /// The outcome, once finished.
    pub fn finished(&self) -> Option<&Result<(), StartError>> {
        self.result.as_ref()
    }

    /// The step in progress (None when finished, or disarming after a failure).
    pub fn step(&self) -> Option<Step> {
        if self.result.is_some() || self.disarming.is_some() {
            None
        } else {
            self.steps.get(self.index).copied()
        }
    }

    fn command_long(&self, command: MavCmd, param1: f32, param2: f32) -> MavMessage {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            param1,
            param2,
            command,
            target_system: self.target.system_id,
            target_component: self.target.component_id,
            confirmation: self.attempts.min(255) as u8,
            ..Default::default()
        })
    }

    fn command(&self, step: Step) -> MavMessage {
        let (command, param1, param2) = match step {
            Step::Guided => (
                MavCmd::MAV_CMD_DO_SET_MODE,
                MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits() as f32,
                ardupilot_mode::GUIDED as f32,
            ),
            Step::Auto => (
                MavCmd::MAV_CMD_DO_SET_MODE,
                MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits() as f32,
                ardupilot_mode::AUTO as f32,
            ),
            Step::Arm => (MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0, 0.0),
            // param1/param2 = 0: from the first item to the last.
            Step::MissionStart => (MavCmd::MAV_CMD_MISSION_START, 0.0, 0.0),
        };
        self.command_long(command, param1, param2)
    }

    fn command_of(step: Step) -> MavCmd {
        match step {
            Step::Guided | Step::Auto => MavCmd::MAV_CMD_DO_SET_MODE,
            Step::Arm => MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            Step::MissionStart => MavCmd::MAV_CMD_MISSION_START,
        }
    }

    /// Whether the heartbeat shows the step done (only steps whose effect a heartbeat shows).
    fn visible(&self, step: Step) -> bool {
        match step {
            Step::Guided => self.mode == Some(ardupilot_mode::GUIDED),
            Step::Auto => self.mode == Some(ardupilot_mode::AUTO),
            Step::Arm => self.armed,
            Step::MissionStart => true,
        }
    }

    fn send(&mut self, now: Duration) -> Vec<MavMessage> {
        let Some(step) = self.step() else {
            return Vec::new();
        };
        self.attempts += 1;
        self.next_send = now + self.cfg.retry;
        vec![self.command(step)]
    }

    fn begin_step(&mut self, now: Duration) -> Vec<MavMessage> {
        self.step_started = now;
        self.attempts = 0;
        self.acked = false;
        self.last_result = None;
        if self.index >= self.steps.len() {
            self.result = Some(Ok(()));
            return Vec::new();
        }
        self.send(now)
    }

    /// Sends the first command.
    pub fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        self.begin_step(now)
    }

    /// Moves on when the current step is acknowledged, or shown done by a heartbeat.
    fn advance(&mut self, now: Duration) -> Vec<MavMessage> {
        match self.step() {
            Some(step) if self.acked || (step != Step::MissionStart && self.visible(step)) => {
                if step == Step::Arm {
                    self.armed_by_start = true;
                }
                self.index += 1;
                self.begin_step(now)
            }
            _ => Vec::new(),
        }
    }

    /// The start failed: it ends now, or once the vehicle it armed is disarmed.
    fn fail(&mut self, now: Duration, error: StartError) -> Vec<MavMessage> {
        if !self.armed_by_start {
            self.result = Some(Err(error));
            return Vec::new();
        }
        self.disarming = Some(Disarming {
            error,
            since: now,
            statustext: None,
        });
        self.attempts = 0;
        self.send_disarm(now)
    }

    /// Not forced (param2 0): an autopilot refuses it in the air.
    fn send_disarm(&mut self, now: Duration) -> Vec<MavMessage> {
        self.attempts += 1;
        self.next_send = now + self.cfg.retry;
        vec![self.command_long(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 0.0, 0.0)]
    }

    fn disarm_done(&mut self, disarmed: bool) {
        if let Some(Disarming {
            mut error,
            statustext,
            ..
        }) = self.disarming.take()
        {
            error.set_disarm(disarmed, statustext);
            self.result = Some(Err(error));
        }
    }

    fn on_heartbeat(&mut self, hb: &HEARTBEAT_DATA) {
        self.armed = hb
            .base_mode
            .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
        if hb
            .base_mode
            .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
        {
            self.mode = Some(hb.custom_mode);
        }
    }

    fn on_ack(&mut self, now: Duration, ack: &COMMAND_ACK_DATA) -> Vec<MavMessage> {
        let Some(step) = self.step() else {
            return Vec::new();
        };
        if ack.command != Self::command_of(step) {
            return Vec::new();
        }
        self.last_result = Some(ack.result);
        match ack.result {
            MavResult::MAV_RESULT_ACCEPTED => self.acked = true,
            // Still working on it: wait without resending until the retry period again.
            MavResult::MAV_RESULT_IN_PROGRESS => self.next_send = now + self.cfg.retry,
            // Not ready yet (pre-arm checks, EKF settling after boot): asked again on the next
            // retry, within the budget.
            MavResult::MAV_RESULT_TEMPORARILY_REJECTED => {}
            MavResult::MAV_RESULT_FAILED if !self.armed_by_start => {}
            // The autopilot may not have checked the mission just uploaded yet.
            MavResult::MAV_RESULT_DENIED
                if step == Step::MissionStart
                    && now.saturating_sub(self.step_started) < self.cfg.mission_start_grace => {}
            // Never going to work (DENIED; FAILED once armed, when the pre-arm checks have
            // passed; UNSUPPORTED): stop now.
            other => {
                let error = StartError::Refused {
                    step,
                    result: other,
                    statustext: self.statustext.clone(),
                    disarmed: None,
                };
                return self.fail(now, error);
            }
        }
        Vec::new()
    }

    /// Keeps the autopilot's warnings (its reasons), not its information ("Armed by ...").
    fn on_statustext(&mut self, text: &super::mav::STATUSTEXT_DATA) {
        let Some(t) = warning(text) else {
            return;
        };
        if let Some(disarming) = self.disarming.as_mut() {
            disarming.statustext = Some(t.clone());
        }
        self.statustext = Some(t);
    }

    /// While disarming: done when a heartbeat shows the vehicle disarmed or the disarm is
    /// acknowledged; refused (in the air) or not answered, the vehicle may still be armed.
    fn handle_disarming(&mut self, message: &MavMessage) {
        match message {
            MavMessage::HEARTBEAT(hb)
                if hb.autopilot != super::mav::MavAutopilot::MAV_AUTOPILOT_INVALID =>
            {
                self.on_heartbeat(hb);
                if !self.armed {
                    self.disarm_done(true);
                }
            }
            MavMessage::COMMAND_ACK(ack) if ack.command == MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => {
                match ack.result {
                    MavResult::MAV_RESULT_ACCEPTED => self.disarm_done(true),
                    MavResult::MAV_RESULT_IN_PROGRESS
                    | MavResult::MAV_RESULT_TEMPORARILY_REJECTED => {}
                    _ => self.disarm_done(false),
                }
            }
            _ => {}
        }
    }

    /// Reacts to a message from the target autopilot (the driver filters other systems).
    pub fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        if self.result.is_some() {
            return Vec::new();
        }
        if let MavMessage::STATUSTEXT(text) = message {
            self.on_statustext(text);
        }
        if self.disarming.is_some() {
            self.handle_disarming(message);
            return Vec::new();
        }
        match message {
            MavMessage::HEARTBEAT(hb)
                if hb.autopilot != super::mav::MavAutopilot::MAV_AUTOPILOT_INVALID =>
            {
                self.on_heartbeat(hb)
            }
            MavMessage::COMMAND_ACK(ack) => {
                let out = self.on_ack(now, ack);
                if self.step().is_none() {
                    return out;
                }
            }
            _ => {}
        }
        self.advance(now)
    }

    /// Resends an unacknowledged command; gives up when the step's budget is spent.
    pub fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        if let Some(since) = self.disarming.as_ref().map(|d| d.since) {
            if now.saturating_sub(since) >= DISARM_BUDGET {
                self.disarm_done(false);
                return Vec::new();
            }
            if now >= self.next_send {
                return self.send_disarm(now);
            }
            return Vec::new();
        }
        let Some(step) = self.step() else {
            return Vec::new();
        };
        if now.saturating_sub(self.step_started) >= self.cfg.budget {
            let error = StartError::Timeout {
                step,
                budget_s: self.cfg.budget.as_secs_f64(),
                attempts: self.attempts,
                last: self.last_result,
                statustext: self.statustext.clone(),
                disarmed: None,
            };
            return self.fail(now, error);
        }
        let advanced = self.advance(now);
        if !advanced.is_empty() || self.step().is_none() {
            return advanced;
        }
        // Resent when the ack did not come (or said "not now").
        if now >= self.next_send && !self.acked {
            return self.send(now);
        }
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::mav::{MavAutopilot, MavSeverity, MavState, MavType, STATUSTEXT_DATA};

    use crate::link::testing::autopilot as target;
    use crate::link::testing::ms;

    fn commands(out: &[MavMessage]) -> Vec<(MavCmd, f32, f32)> {
        out.iter()
            .filter_map(|m| match m {
                MavMessage::COMMAND_LONG(c) => Some((c.command, c.param1, c.param2)),
                _ => None,
            })
            .collect()
    }

    fn ack(command: MavCmd, result: MavResult) -> MavMessage {
        MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command,
            result,
            ..Default::default()
        })
    }

    fn heartbeat(armed: bool, custom_mode: u32) -> MavMessage {
        let mut base_mode = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
        if armed {
            base_mode |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
        }
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode,
            mavtype: MavType::MAV_TYPE_OCTOROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            base_mode,
            system_status: MavState::MAV_STATE_STANDBY,
            mavlink_version: 3,
        })
    }

    const ARM: MavCmd = MavCmd::MAV_CMD_COMPONENT_ARM_DISARM;
    const START: MavCmd = MavCmd::MAV_CMD_MISSION_START;
    const MODE: MavCmd = MavCmd::MAV_CMD_DO_SET_MODE;
    const OK: MavResult = MavResult::MAV_RESULT_ACCEPTED;

    #[test]
    fn px4_is_armed_then_sent_mission_start_as_soon_as_the_arming_is_acked() {
        let mut s = Start::new(target(Flavour::Px4), StartConfig::default());
        assert_eq!(commands(&s.start(ms(0))), vec![(ARM, 1.0, 0.0)]);
        // No waiting for PX4's once-a-second heartbeat: COM_DISARM_PRFLT is running.
        assert_eq!(
            commands(&s.handle(ms(10), &ack(ARM, OK))),
            vec![(START, 0.0, 0.0)]
        );
        assert!(s.handle(ms(30), &ack(START, OK)).is_empty());
        assert_eq!(s.finished(), Some(&Ok(())));
    }

    #[test]
    fn a_lost_arming_ack_is_made_up_for_by_a_heartbeat_showing_the_vehicle_armed() {
        let mut s = Start::new(target(Flavour::Px4), StartConfig::default());
        s.start(ms(0));
        assert_eq!(
            commands(&s.handle(ms(20), &heartbeat(true, 0))),
            vec![(START, 0.0, 0.0)]
        );
    }

    #[test]
    fn ardupilot_is_put_in_guided_armed_put_in_auto_then_started() {
        let mut s = Start::new(target(Flavour::ArduPilot), StartConfig::default());
        let guided = ardupilot_mode::GUIDED as f32;
        let auto = ardupilot_mode::AUTO as f32;
        assert_eq!(commands(&s.start(ms(0))), vec![(MODE, 1.0, guided)]);
        assert_eq!(
            commands(&s.handle(ms(5), &ack(MODE, OK))),
            vec![(ARM, 1.0, 0.0)]
        );
        assert_eq!(
            commands(&s.handle(ms(7), &ack(ARM, OK))),
            vec![(MODE, 1.0, auto)]
        );
        assert_eq!(
            commands(&s.handle(ms(9), &ack(MODE, OK))),
            vec![(START, 0.0, 0.0)]
        );
        s.handle(ms(11), &ack(START, OK));
        assert_eq!(s.finished(), Some(&Ok(())));
    }

    #[test]
    fn an_unanswered_command_is_resent_every_retry_period() {
        let mut s = Start::new(target(Flavour::Px4), StartConfig::default());
        s.start(ms(0));
        assert!(s.tick(ms(90)).is_empty());
        assert_eq!(commands(&s.tick(ms(100))), vec![(ARM, 1.0, 0.0)]);
        assert_eq!(commands(&s.tick(ms(200))), vec![(ARM, 1.0, 0.0)]);
    }

    #[test]
    fn arming_refused_while_prearm_checks_fail_is_retried_until_they_pass() {
        let mut s = Start::new(target(Flavour::Px4), StartConfig::default());
        s.start(ms(0));
        let text = MavMessage::STATUSTEXT(STATUSTEXT_DATA {
            text: "PreArm: EKF not ready".into(),
            ..Default::default()
        });
        s.handle(ms(5), &text);
        s.handle(
            ms(10),
            &ack(ARM, MavResult::MAV_RESULT_TEMPORARILY_REJECTED),
        );
        assert!(s.finished().is_none());
        assert_eq!(commands(&s.tick(ms(100))), vec![(ARM, 1.0, 0.0)]);
        assert_eq!(
            commands(&s.handle(ms(110), &ack(ARM, OK))),
            vec![(START, 0.0, 0.0)]
        );
    }

    #[test]
    fn a_step_not_done_within_the_budget_fails_naming_the_step_and_the_autopilots_reason() {
        let cfg = StartConfig {
            retry: Duration::from_secs(1),
            budget: Duration::from_secs(3),
            ..StartConfig::default()
        };
        let mut s = Start::new(target(Flavour::Px4), cfg);
        s.start(ms(0));
        let text = MavMessage::STATUSTEXT(STATUSTEXT_DATA {
            text: "PreArm: GPS not healthy".into(),
            ..Default::default()
        });
        s.handle(ms(5), &text);
        s.handle(
            ms(10),
            &ack(ARM, MavResult::MAV_RESULT_TEMPORARILY_REJECTED),
        );
        for t in 1..=3 {
            s.tick(ms(1000 * t));
        }
        let err = s.finished().cloned().unwrap().unwrap_err();
        assert!(matches!(
            err,
            StartError::Timeout {
                step: Step::Arm,
                attempts: 3,
                ..
            }
        ));
        let text = err.to_string();
        assert!(
            text.contains("arming") && text.contains("PreArm: GPS not healthy"),
            "{text}"
        );
    }

    #[test]
    fn an_unsupported_command_fails_at_once() {
        let mut s = Start::new(target(Flavour::Px4), StartConfig::default());
        s.start(ms(0));
        s.handle(ms(5), &ack(ARM, OK));
        s.handle(ms(7), &ack(START, MavResult::MAV_RESULT_UNSUPPORTED));
        // Once the vehicle it armed is disarmed.
        s.handle(ms(9), &heartbeat(false, 0));
        assert!(matches!(
            s.finished(),
            Some(Err(StartError::Refused {
                step: Step::MissionStart,
                result: MavResult::MAV_RESULT_UNSUPPORTED,
                disarmed: Some(true),
                ..
            }))
        ));
    }

    #[test]
    fn an_ack_for_another_command_is_not_taken_for_this_step() {
        let mut s = Start::new(target(Flavour::Px4), StartConfig::default());
        s.start(ms(0));
        assert!(s
            .handle(ms(5), &ack(MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, OK))
            .is_empty());
        assert_eq!(s.step(), Some(Step::Arm));
    }

    fn statustext(severity: MavSeverity, text: &str) -> MavMessage {
        MavMessage::STATUSTEXT(STATUSTEXT_DATA {
            severity,
            text: text.into(),
            ..Default::default()
        })
    }

    const DISARM: (MavCmd, f32, f32) = (ARM, 0.0, 0.0);

    #[test]
    fn a_mission_start_denied_after_arming_disarms_and_fails_at_once_naming_the_reason() {
        let mut s = Start::new(target(Flavour::Px4), StartConfig::default());
        s.start(ms(0));
        s.handle(ms(10), &ack(ARM, OK));
        s.handle(
            ms(12),
            &statustext(MavSeverity::MAV_SEVERITY_INFO, "Armed by external command"),
        );
        s.handle(
            ms(15),
            &statustext(
                MavSeverity::MAV_SEVERITY_CRITICAL,
                "Mission start denied! No valid mission",
            ),
        );
        // No second MISSION_START: the disarm at once.
        assert_eq!(
            commands(&s.handle(ms(3020), &ack(START, MavResult::MAV_RESULT_DENIED))),
            vec![DISARM]
        );
        assert!(s.finished().is_none());
        assert_eq!(commands(&s.tick(ms(3120))), vec![DISARM]);
        s.handle(ms(3130), &heartbeat(false, 0));
        let err = s.finished().cloned().unwrap().unwrap_err();
        assert_eq!(
            err,
            StartError::Refused {
                step: Step::MissionStart,
                result: MavResult::MAV_RESULT_DENIED,
                statustext: Some("Mission start denied! No valid mission".into()),
                disarmed: Some(true),
            }
        );
        let text = err.to_string();
        assert!(
            text.contains("MAV_RESULT_DENIED")
                && text.contains("No valid mission")
                && text.contains("disarmed again"),
            "{text}"
        );
        assert!(s.tick(ms(8000)).is_empty());
    }

    #[test]
    fn a_mission_start_denied_just_after_the_upload_is_asked_again_within_the_grace() {
        // PX4 SITL: the first MISSION_START after a verified upload DENIED ("No valid mission"
        // until its navigator has checked the new mission), the next accepted.
        let mut s = Start::new(target(Flavour::Px4), StartConfig::default());
        s.start(ms(0));
        s.handle(ms(10), &ack(ARM, OK));
        assert!(s
            .handle(ms(20), &ack(START, MavResult::MAV_RESULT_DENIED))
            .is_empty());
        assert!(s.finished().is_none());
        assert_eq!(commands(&s.tick(ms(120))), vec![(START, 0.0, 0.0)]);
        s.handle(ms(130), &ack(START, OK));
        assert_eq!(s.finished(), Some(&Ok(())));
        // Still denied after the grace: the answer, the vehicle disarmed.
        let mut d = Start::new(target(Flavour::Px4), StartConfig::default());
        d.start(ms(0));
        d.handle(ms(10), &ack(ARM, OK));
        let mut t = 10;
        let mut starts = 0;
        loop {
            t += 100;
            let out = commands(&d.tick(ms(t)));
            starts += out.iter().filter(|c| **c == (START, 0.0, 0.0)).count();
            let answer = commands(&d.handle(ms(t + 5), &ack(START, MavResult::MAV_RESULT_DENIED)));
            if answer == vec![DISARM] {
                break;
            }
            assert!(t < 4000, "still asking at {t} ms");
        }
        assert!(t >= 3000 && starts <= 31, "{t} ms, {starts} starts");
    }

    #[test]
    fn the_reason_sent_after_the_refusal_is_taken_while_disarming() {
        let mut s = Start::new(target(Flavour::Px4), StartConfig::default());
        s.start(ms(0));
        s.handle(ms(10), &ack(ARM, OK));
        s.handle(ms(3020), &ack(START, MavResult::MAV_RESULT_DENIED));
        s.handle(
            ms(3025),
            &statustext(MavSeverity::MAV_SEVERITY_CRITICAL, "Mission start denied"),
        );
        s.handle(ms(3030), &ack(ARM, OK));
        assert!(matches!(
            s.finished(),
            Some(Err(StartError::Refused { statustext: Some(t), disarmed: Some(true), .. }))
                if t == "Mission start denied"
        ));
    }

    #[test]
    fn a_denied_arming_fails_at_once_and_sends_no_disarm() {
        let mut s = Start::new(target(Flavour::Px4), StartConfig::default());
        s.start(ms(0));
        assert!(s
            .handle(ms(10), &ack(ARM, MavResult::MAV_RESULT_DENIED))
            .is_empty());
        let err = s.finished().cloned().unwrap().unwrap_err();
        assert!(!err.armed());
        assert_eq!(err.result(), Some(MavResult::MAV_RESULT_DENIED));
        assert!(s.tick(ms(200)).is_empty());
    }

    #[test]
    fn arming_failed_while_ardupilots_prearm_checks_fail_is_retried() {
        let mut s = Start::new(target(Flavour::ArduPilot), StartConfig::default());
        s.start(ms(0));
        s.handle(ms(5), &ack(MODE, OK));
        s.handle(ms(10), &ack(ARM, MavResult::MAV_RESULT_FAILED));
        assert!(s.finished().is_none());
        assert_eq!(commands(&s.tick(ms(110))), vec![(ARM, 1.0, 0.0)]);
    }

    #[test]
    fn ardupilots_mode_auto_failed_once_armed_disarms_and_fails_at_once() {
        let mut s = Start::new(target(Flavour::ArduPilot), StartConfig::default());
        s.start(ms(0));
        s.handle(ms(5), &ack(MODE, OK));
        s.handle(ms(7), &ack(ARM, OK));
        s.handle(
            ms(8),
            &statustext(
                MavSeverity::MAV_SEVERITY_CRITICAL,
                "Auto: Missing Takeoff Cmd",
            ),
        );
        assert_eq!(
            commands(&s.handle(ms(9), &ack(MODE, MavResult::MAV_RESULT_FAILED))),
            vec![DISARM]
        );
        s.handle(ms(11), &ack(ARM, OK));
        let err = s.finished().cloned().unwrap().unwrap_err();
        assert!(matches!(
            err,
            StartError::Refused {
                step: Step::Auto,
                result: MavResult::MAV_RESULT_FAILED,
                disarmed: Some(true),
                ..
            }
        ));
        assert!(err.to_string().contains("Missing Takeoff Cmd"), "{err}");
    }

    #[test]
    fn a_disarm_not_confirmed_within_its_budget_says_the_vehicle_may_still_be_armed() {
        let mut s = Start::new(target(Flavour::Px4), StartConfig::default());
        s.start(ms(0));
        s.handle(ms(10), &ack(ARM, OK));
        s.handle(ms(3020), &ack(START, MavResult::MAV_RESULT_DENIED));
        let mut sent = 1;
        let mut t = 3020;
        while s.finished().is_none() {
            t += 50;
            sent += commands(&s.tick(ms(t))).len();
            s.handle(ms(t), &heartbeat(true, 0));
        }
        assert!(ms(t - 3020) >= DISARM_BUDGET);
        assert!(sent <= 31, "{sent} disarm commands");
        let err = s.finished().cloned().unwrap().unwrap_err();
        assert!(matches!(
            err,
            StartError::Refused {
                disarmed: Some(false),
                ..
            }
        ));
        assert!(err.to_string().contains("may still be armed"), "{err}");
    }

    #[test]
    fn a_mission_start_unanswered_within_the_budget_disarms_the_vehicle_it_armed() {
        let cfg = StartConfig {
            retry: Duration::from_secs(1),
            budget: Duration::from_secs(3),
            ..StartConfig::default()
        };
        let mut s = Start::new(target(Flavour::Px4), cfg);
        s.start(ms(0));
        s.handle(ms(10), &ack(ARM, OK));
        for t in 1..=3 {
            s.tick(ms(10 + 1000 * t));
        }
        assert!(s.finished().is_none());
        s.handle(ms(3100), &heartbeat(false, 0));
        assert!(matches!(
            s.finished(),
            Some(Err(StartError::Timeout {
                step: Step::MissionStart,
                disarmed: Some(true),
                ..
            }))
        ));
    }
}
