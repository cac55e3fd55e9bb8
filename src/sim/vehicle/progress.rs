//! Mission progress as the navigator and PX4's mavlink mission manager report it: the stored
//! mission and where it resumes, the flight's events turned into MISSION_CURRENT (with
//! mission_state and mission_mode) and MISSION_ITEM_REACHED (PX4: repeated at 1 Hz; ArduPilot:
//! with "Reached command #N").

use mavlink::MessageData;

use super::mode::Mode;
use super::streams::steps;
use super::SimVehicle;

use crate::link::mav::{
    MavMessage, MavSeverity, MissionState, MISSION_CURRENT_DATA, MISSION_ITEM_INT_DATA,
    MISSION_ITEM_REACHED_DATA,
};
use crate::link::Flavour;
use crate::sim::flight::{commands, Command, Event};

impl<'v> SimVehicle<'v> {
    /// The mission server holds `items` with current item `current` (call it whenever they may
    /// have changed). A new mission resets the mission state; a new current item (a
    /// MISSION_SET_CURRENT) is where the mission starts or resumes; the mission being flown is
    /// not changed mid-flight.
    pub fn set_mission(&mut self, items: &[MISSION_ITEM_INT_DATA], current: u16) {
        let same = items.len() == self.mission.len()
            && items
                .iter()
                .zip(&self.mission)
                .all(|(a, b)| identical(a, b));
        if !same {
            self.mission = items.to_vec();
            self.mission_finished = false;
            self.seq_reached = None;
            self.reached_sent = None;
            self.mission_current = current;
            self.mission_state = MissionState::MISSION_STATE_NOT_STARTED;
        } else if current != self.server_current && self.flight.current().is_none() {
            self.mission_current = current;
        }
        self.server_current = current;
    }

    /// The stored mission as commands, if it is one this vehicle can fly.
    pub(super) fn commands(&self) -> Option<Vec<Command>> {
        let home_at_zero = self.flavour == Flavour::ArduPilot;
        let commands = commands(&self.mission, self.config.home, home_at_zero).ok()?;
        commands
            .iter()
            .any(|c| {
                !matches!(
                    c,
                    Command::Skip
                        | Command::ChangeSpeed { .. }
                        | Command::Jump { .. }
                        | Command::Photo { .. }
                )
            })
            .then_some(commands)
    }

    /// Messages and state changes for flight events at the current time.
    pub(super) fn events(&mut self, events: &[Event]) {
        for event in events {
            match *event {
                Event::Current(seq) => {
                    self.mission_current = seq;
                    self.send_stream(MISSION_CURRENT_DATA::ID, self.now_s);
                }
                Event::Reached(seq) => self.reached(seq),
                Event::Landed => self.landed_s = Some(self.now_s),
                Event::Touchdown => {}
                Event::Complete => {
                    self.mission_finished = true;
                    let returns = self
                        .commands()
                        .and_then(|c| c.iter().rev().find(|c| c.is_navigation()).copied())
                        == Some(Command::ReturnToLaunch);
                    if self.flavour == Flavour::Px4 && returns && !self.flight.on_ground() {
                        // The RTL item done, PX4 returns in RTL mode (navigator RTL).
                        self.mode = Mode::Rtl;
                        let events = self.flight.land(true);
                        self.events(&events);
                    }
                }
                Event::Liftoff => {}
                Event::Photo => self.photo(),
            }
        }
    }

    pub(super) fn reached(&mut self, seq: u16) {
        let command = self
            .commands()
            .and_then(|c| c.get(usize::from(seq)).copied());
        match self.flavour {
            Flavour::Px4 | Flavour::Generic => {
                self.seq_reached = Some(seq);
                if self.silent_reached == Some(seq) {
                    return;
                }
                self.reached_sent = Some(seq);
                self.reached_repeats = 0;
                self.out.push(MavMessage::MISSION_ITEM_REACHED(
                    MISSION_ITEM_REACHED_DATA { seq },
                ));
            }
            Flavour::ArduPilot => {
                if matches!(command, Some(Command::Land { .. })) {
                    return; // disarmed on landing before verify_land reports it
                }
                if matches!(
                    command,
                    Some(Command::Waypoint { .. } | Command::Loiter { .. })
                ) {
                    self.statustext(
                        MavSeverity::MAV_SEVERITY_INFO,
                        &format!("Reached command #{seq}"),
                    );
                }
                self.out.push(MavMessage::MISSION_ITEM_REACHED(
                    MISSION_ITEM_REACHED_DATA { seq },
                ));
            }
        }
    }

    /// MISSION_CURRENT with PX4's mission_state and mission_mode (mavlink_mission.cpp
    /// `update_mission_state`).
    pub(super) fn mission_current_message(&mut self) -> MavMessage {
        let count = self.mission.len();
        let valid = self.commands().is_some();
        let active = matches!(self.mode, Mode::Mission | Mode::Takeoff | Mode::Land);
        let seq = self.flight.current().unwrap_or(self.mission_current);
        self.mission_state = if count == 0 || !valid {
            MissionState::MISSION_STATE_NO_MISSION
        } else if self.mission_finished {
            MissionState::MISSION_STATE_COMPLETE
        } else if active {
            MissionState::MISSION_STATE_ACTIVE
        } else if self.seq_reached.is_some() {
            MissionState::MISSION_STATE_PAUSED
        } else if seq < 1 {
            MissionState::MISSION_STATE_NOT_STARTED
        } else {
            self.mission_state
        };
        let total = match self.flavour {
            Flavour::Px4 | Flavour::Generic if count == 0 => u16::MAX,
            Flavour::Px4 | Flavour::Generic => count as u16,
            // ArduPilot leaves home (seq 0) out of the total.
            Flavour::ArduPilot => count.saturating_sub(1) as u16,
        };
        MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA {
            seq,
            total,
            mission_state: self.mission_state,
            mission_mode: if active { 1 } else { 2 },
            ..Default::default()
        })
    }

    /// The waypoint of `commands` this flavour never reports reached (PX4: the last before an
    /// RTL item).
    pub(super) fn never_reported(&self, commands: &[Command]) -> Option<u16> {
        match self.flavour {
            Flavour::Px4 | Flavour::Generic => last_waypoint_before_rtl(commands),
            Flavour::ArduPilot => None,
        }
    }

    /// PX4's mission manager at 1 Hz (mavlink_mission.cpp `_slow_rate_limiter`): the last
    /// reached item again, up to 10 more times.
    pub(super) fn repeat_reached(&mut self, step: u64) {
        if self.flavour == Flavour::Px4 && step >= self.slow_next_step {
            self.slow_next_step = step + steps(1.0);
            // mavlink_mission.cpp: the last reached item again, up to 10 more times.
            if let Some(seq) = self.reached_sent {
                if self.reached_repeats < 10 && !self.mission.is_empty() {
                    self.reached_repeats += 1;
                    self.out.push(MavMessage::MISSION_ITEM_REACHED(
                        MISSION_ITEM_REACHED_DATA { seq },
                    ));
                }
            }
        }
    }
}

/// The last waypoint before the first RTL item (PX4 never reports it reached: the RTL item
/// completes at once and its mission result replaces the waypoint's before the mavlink mission
/// manager sends it).
fn last_waypoint_before_rtl(commands: &[Command]) -> Option<u16> {
    let ending = commands.iter().position(Command::lands)?;
    if commands.get(ending) != Some(&Command::ReturnToLaunch) {
        return None;
    }
    let before = commands
        .get(..ending)?
        .iter()
        .rposition(Command::is_navigation)?;
    matches!(
        commands.get(before),
        Some(Command::Waypoint { .. } | Command::Loiter { .. })
    )
    .then(|| before as u16)
}

/// Whether two stored items are the same bit for bit (NaN params included, which `==` never
/// finds equal).
fn identical(a: &MISSION_ITEM_INT_DATA, b: &MISSION_ITEM_INT_DATA) -> bool {
    let floats =
        |i: &MISSION_ITEM_INT_DATA| [i.param1, i.param2, i.param3, i.param4, i.z].map(f32::to_bits);
    floats(a) == floats(b)
        && (
            a.seq,
            a.command,
            a.frame,
            a.x,
            a.y,
            a.current,
            a.autocontinue,
        ) == (
            b.seq,
            b.command,
            b.frame,
            b.x,
            b.y,
            b.current,
            b.autocontinue,
        )
}
