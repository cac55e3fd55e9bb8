//! The commander: arming and disarming, MAV_CMD_MISSION_START and mode changes as PX4's
//! commander and ArduCopter handle them, and the automatic disarms (after a landing, armed on
//! the ground too long).

use mavlink::MessageData;

use super::mode::Mode;
use super::{SimVehicle, PREFLIGHT_DISARM_S};

#[allow(deprecated)]
use crate::link::mav::SMART_BATTERY_INFO_DATA;
use crate::link::mav::{MavCmd, MavMessage, MavModeFlag, MavResult, MavSeverity, STATUSTEXT_DATA};
use crate::link::Flavour;
use crate::sim::flight::Command;

impl<'v> SimVehicle<'v> {
    /// Arms and starts the stored mission the way a ground station would (`--autostart`):
    /// PX4 MISSION_START; ArduPilot GUIDED, arm, MISSION_START. Returns whether it flies.
    pub fn autostart(&mut self) -> bool {
        let ok = match self.flavour {
            Flavour::Px4 | Flavour::Generic => {
                self.mission_start(0.0, 0.0) == MavResult::MAV_RESULT_ACCEPTED
            }
            Flavour::ArduPilot => {
                self.set_mode(Mode::Guided);
                self.arm() == MavResult::MAV_RESULT_ACCEPTED
                    && self.mission_start(0.0, 0.0) == MavResult::MAV_RESULT_ACCEPTED
            }
        };
        ok && self.flight.current().is_some()
    }

    // SMART_BATTERY_INFO, superseded but the one asked for (`link::pack`).
    #[allow(deprecated)]
    pub(super) fn command(&mut self, command: MavCmd, p: [f32; 7]) -> MavResult {
        match command {
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => {
                if p[0] == 1.0 {
                    self.arm()
                } else if p[0] == 0.0 {
                    self.disarm(p[1] == 21196.0)
                } else {
                    MavResult::MAV_RESULT_DENIED
                }
            }
            MavCmd::MAV_CMD_MISSION_START => self.mission_start(p[0], p[1]),
            // PX4's commander and ArduCopter's GCS handler both take it as the mode change.
            MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => self.set_mode(Mode::Rtl),
            MavCmd::MAV_CMD_DO_SET_MODE => {
                if (p[0] as u32) & (MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits() as u32)
                    == 0
                {
                    return MavResult::MAV_RESULT_DENIED;
                }
                let custom = match self.flavour {
                    Flavour::Px4 | Flavour::Generic => {
                        ((p[1] as u32) << 16) | ((p[2] as u32) << 24)
                    }
                    Flavour::ArduPilot => p[1] as u32,
                };
                match Mode::from_custom(self.flavour, custom) {
                    Some(mode) => self.set_mode(mode),
                    None => MavResult::MAV_RESULT_DENIED,
                }
            }
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL => self.set_interval(p[0], p[1]),
            MavCmd::MAV_CMD_REQUEST_MESSAGE => {
                let id = p[0] as u32;
                if p[0].is_finite() && id == SMART_BATTERY_INFO_DATA::ID {
                    return self.smart_battery_info();
                }
                if p[0].is_finite() && self.streams.iter().any(|s| s.id == id) {
                    let t = self.now_s;
                    self.send_stream(id, t);
                    MavResult::MAV_RESULT_ACCEPTED
                } else {
                    MavResult::MAV_RESULT_FAILED
                }
            }
            _ => MavResult::MAV_RESULT_UNSUPPORTED,
        }
    }

    /// SMART_BATTERY_INFO asked for: its serial number (the rest not provided, as the
    /// message marks it), or FAILED without a smart battery. (Superseded by BATTERY_INFO; the
    /// one released autopilots send, see `link::pack`.)
    #[allow(deprecated)]
    fn smart_battery_info(&mut self) -> MavResult {
        let Some(serial) = self.config.pack_serial else {
            return MavResult::MAV_RESULT_FAILED;
        };
        self.out
            .push(MavMessage::SMART_BATTERY_INFO(SMART_BATTERY_INFO_DATA {
                serial_number: serial.to_string().as_str().into(),
                capacity_full_specification: -1,
                capacity_full: -1,
                cycle_count: u16::MAX,
                discharge_minimum_voltage: u16::MAX,
                charging_minimum_voltage: u16::MAX,
                resting_minimum_voltage: u16::MAX,
                ..Default::default()
            }));
        MavResult::MAV_RESULT_ACCEPTED
    }

    pub(super) fn statustext(&mut self, severity: MavSeverity, text: &str) {
        self.out.push(MavMessage::STATUSTEXT(STATUSTEXT_DATA {
            severity,
            text: text.into(),
            id: 0,
            chunk_seq: 0,
        }));
    }

    pub(super) fn arm(&mut self) -> MavResult {
        if self.flight.armed() {
            return MavResult::MAV_RESULT_ACCEPTED;
        }
        if self.flavour == Flavour::ArduPilot
            && matches!(self.mode, Mode::Mission | Mode::Rtl | Mode::Land)
        {
            // AP_Arming_Copter: the mode must allow arming (`Mode::allows_arming`).
            self.statustext(MavSeverity::MAV_SEVERITY_CRITICAL, "Arm: Mode not armable");
            return MavResult::MAV_RESULT_FAILED;
        }
        self.flight.arm();
        self.arms += 1;
        self.first_armed_s.get_or_insert(self.now_s);
        self.idle_since_s = Some(self.now_s);
        self.landed_s = None;
        self.maybe_fly();
        MavResult::MAV_RESULT_ACCEPTED
    }

    pub(super) fn disarm(&mut self, forced: bool) -> MavResult {
        if !self.flight.on_ground() && !forced {
            // Commander: "Disarming denied: not landed"; ArduCopter refuses it in flight too.
            return match self.flavour {
                Flavour::Px4 | Flavour::Generic => MavResult::MAV_RESULT_DENIED,
                Flavour::ArduPilot => MavResult::MAV_RESULT_FAILED,
            };
        }
        self.do_disarm();
        MavResult::MAV_RESULT_ACCEPTED
    }

    pub(super) fn do_disarm(&mut self) {
        if let Some(seq) = self.flight.current() {
            self.mission_current = seq;
        }
        self.flight.disarm();
        self.auto_armed = false;
        self.idle_since_s = None;
        self.landed_s = None;
    }

    pub(super) fn mission_start(&mut self, first: f32, last: f32) -> MavResult {
        match self.flavour {
            Flavour::Px4 | Flavour::Generic => {
                // Commander VEHICLE_CMD_MISSION_START: DENIED without a valid mission or with
                // a first item out of range; else AUTO_MISSION and arm.
                let total = self.mission.len() as f32;
                if self.commands().is_none()
                    || !(first.is_finite() && first >= -1.0 && first < total)
                {
                    self.statustext(
                        MavSeverity::MAV_SEVERITY_CRITICAL,
                        "Mission start denied! No valid mission",
                    );
                    return MavResult::MAV_RESULT_DENIED;
                }
                if self.set_mode(Mode::Mission) != MavResult::MAV_RESULT_ACCEPTED {
                    return MavResult::MAV_RESULT_TEMPORARILY_REJECTED;
                }
                self.arm()
            }
            Flavour::ArduPilot => {
                if first != 0.0 || last != 0.0 {
                    return MavResult::MAV_RESULT_DENIED;
                }
                if self.set_mode(Mode::Mission) != MavResult::MAV_RESULT_ACCEPTED {
                    return MavResult::MAV_RESULT_FAILED;
                }
                self.auto_armed = true;
                self.maybe_fly();
                MavResult::MAV_RESULT_ACCEPTED
            }
        }
    }

    /// Changes the flight mode and what the flight does about it.
    pub(super) fn set_mode(&mut self, mode: Mode) -> MavResult {
        if mode == Mode::Mission {
            match self.commands() {
                None => {
                    // PX4: "mission not available"; ArduCopter: AUTO needs a mission.
                    return match self.flavour {
                        Flavour::Px4 | Flavour::Generic => {
                            MavResult::MAV_RESULT_TEMPORARILY_REJECTED
                        }
                        Flavour::ArduPilot => MavResult::MAV_RESULT_FAILED,
                    };
                }
                Some(commands) => {
                    let takeoff_first = commands
                        .iter()
                        .find(|c| c.is_navigation())
                        .is_some_and(|c| matches!(c, Command::Takeoff { .. }));
                    if self.flavour == Flavour::ArduPilot
                        && self.flight.armed()
                        && self.flight.on_ground()
                        && !takeoff_first
                    {
                        self.statustext(
                            MavSeverity::MAV_SEVERITY_CRITICAL,
                            "Auto: Missing Takeoff Cmd",
                        );
                        return MavResult::MAV_RESULT_FAILED;
                    }
                }
            }
        }
        let previous = self.mode;
        self.mode = mode;
        if previous == Mode::Mission && mode != Mode::Mission {
            // Leaving the mission pauses it (PX4 MissionBase::on_inactivation).
            if let Some(seq) = self.flight.current() {
                self.mission_current = seq;
            }
            self.seq_reached = None;
            self.auto_armed = self.auto_armed && self.flavour == Flavour::ArduPilot;
        }
        let flying = !self.flight.on_ground();
        match mode {
            Mode::Mission => self.maybe_fly(),
            Mode::Land if flying => {
                let events = self.flight.land(false);
                self.events(&events);
            }
            Mode::Rtl if flying => {
                // Home or a rally point, as its autopilot chooses (AP_Rally, PX4 rtl.cpp).
                let events = match self.return_destination() {
                    (crate::mission::fence::Destination::Home, _) => self.flight.land(true),
                    (crate::mission::fence::Destination::Here, _) => self.flight.land(false),
                    (_, at) => self.flight.land_at(at),
                };
                self.events(&events);
            }
            _ if flying && previous != mode => self.flight.hold(),
            _ => {}
        }
        MavResult::MAV_RESULT_ACCEPTED
    }

    /// Starts (or resumes) the mission when armed in mission mode (ArduPilot: and auto-armed).
    pub(super) fn maybe_fly(&mut self) {
        let ready = self.flight.armed()
            && self.mode == Mode::Mission
            && (self.flavour == Flavour::Px4 || self.auto_armed)
            && self.flight.current().is_none();
        if !ready {
            return;
        }
        let Some(commands) = self.commands() else {
            return;
        };
        if self.mission_finished && self.flight.on_ground() {
            // A finished mission restarts from the beginning (PX4 checkMissionRestart).
            self.mission_finished = false;
            self.mission_current = 0;
            self.seq_reached = None;
        }
        self.silent_reached = self.never_reported(&commands);
        let spool_up_s = match self.flavour {
            Flavour::Px4 | Flavour::Generic => 1.0, // COM_SPOOLUP_TIME
            Flavour::ArduPilot => 0.5,              // MOT_SPOOL_TIME
        };
        self.idle_since_s = None;
        let first = match self.flavour {
            Flavour::ArduPilot => self.mission_current.max(1),
            Flavour::Px4 | Flavour::Generic => self.mission_current,
        };
        let events = self.flight.start(commands, first, spool_up_s);
        self.events(&events);
    }

    /// Automatic disarms: after a landing, and armed on the ground too long without flying.
    pub(super) fn timers(&mut self, t: f64) {
        let after_landed_s = match self.flavour {
            // Measured on PX4 SITL: 0.3 and 0.6 s after the confirmed landing (COM_DISARM_LAND
            // counts from the land detector's earlier stages).
            Flavour::Px4 | Flavour::Generic => 0.5,
            // ArduCopter disarms as soon as the land detector says landed (mode_auto.cpp
            // `verify_land`, mode_land.cpp).
            Flavour::ArduPilot => 0.0,
        };
        if let Some(landed) = self.landed_s {
            if self.flight.armed() && t >= landed + after_landed_s {
                self.do_disarm();
            }
        }
        if self.flight.armed() && self.flight.on_ground() && self.flight.current().is_none() {
            let since = *self.idle_since_s.get_or_insert(t);
            if t >= since + PREFLIGHT_DISARM_S {
                self.do_disarm();
            }
        }
    }
}
