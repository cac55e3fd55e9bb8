//! Which commands each autopilot takes in a mission, and the frame to send an action (a camera,
//! gimbal, region-of-interest, yaw, payload, delay or speed command after a waypoint) in, so an
//! upload carries only what the vehicle will store and in the frame it reads as meant.
//!
//! Sources, each rule checked against the SITLs with `sitl/probe_actions.py` (the answers are
//! `tests/fixtures/actions/`, the table docs/mavlink.md):
//! - PX4: `src/modules/mavlink/mavlink_mission.cpp`, `parse_mavlink_mission_item`: a global frame
//!   (0, 3, 5, 6) takes only the commands with a position, MAV_FRAME_MISSION (2) only those
//!   without; anything else is MAV_MISSION_UNSUPPORTED (CONDITION_YAW, DO_SET_SERVO,
//!   DO_SET_RELAY, NAV_SPLINE_WAYPOINT on PX4 SITL in either frame).
//! - ArduPilot: `libraries/AP_Mission/AP_Mission.cpp`, `mavlink_int_to_mission_cmd` (copter
//!   build): every command it has a case for, in any frame; the frame matters only to a command
//!   it stores a location for (`stored_in_location`), whose altitude MAV_FRAME_MISSION makes
//!   absolute (`relative_alt = 0`): ArduCopter SITL answered DO_SET_ROI_LOCATION sent in frame 2
//!   in MAV_FRAME_GLOBAL.
//! - Generic (MAVSDK's MissionRawServer and any other): stores whatever it receives.
//!
//! Whether an autopilot holds a geofence and rally points at all is what it declares in
//! AUTOPILOT_VERSION's capability bits (MAV_PROTOCOL_CAPABILITY_MISSION_FENCE and _RALLY; PX4
//! `MavlinkMain::send_autopilot_capabilities` sets both, ArduPilot `GCS_MAVLINK::capabilities`
//! each when its build has a fence or rally library), asked for by [`AskCapabilities`], a
//! sans-IO machine, and checked by [`Capabilities::check`] before anything is uploaded: a
//! mission with a fence is never flown by an autopilot that does not say it holds one.

use std::time::Duration;

use mavlink::MessageData;

use super::connection::Autopilot;
use super::mav::{
    MavCmd, MavFrame, MavMessage, MavProtocolCapability, MavResult, AUTOPILOT_VERSION_DATA,
    COMMAND_LONG_DATA,
};
use super::Flavour;

use MavCmd::*;

/// The commands PX4 takes in a global frame (`parse_mavlink_mission_item`'s first switch):
/// those with a position. NAV_LOITER_TURNS is not among them.
#[allow(deprecated)]
const PX4_GLOBAL: &[MavCmd] = &[
    MAV_CMD_NAV_WAYPOINT,
    MAV_CMD_NAV_LOITER_UNLIM,
    MAV_CMD_NAV_LOITER_TIME,
    MAV_CMD_NAV_LAND,
    MAV_CMD_NAV_TAKEOFF,
    MAV_CMD_NAV_LOITER_TO_ALT,
    MAV_CMD_NAV_ROI,
    MAV_CMD_DO_SET_ROI,
    MAV_CMD_DO_SET_ROI_LOCATION,
    MAV_CMD_NAV_VTOL_TAKEOFF,
    MAV_CMD_NAV_VTOL_LAND,
    MAV_CMD_CONDITION_GATE,
    MAV_CMD_NAV_FENCE_RETURN_POINT,
    MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
    MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
    MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION,
    MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
    MAV_CMD_NAV_RALLY_POINT,
];

/// The commands PX4 takes in MAV_FRAME_MISSION (`parse_mavlink_mission_item`'s second switch):
/// those without a position (NAV_ROI and DO_SET_ROI only in the modes none, next waypoint and
/// waypoint index).
#[allow(deprecated)]
const PX4_MISSION: &[MavCmd] = &[
    MAV_CMD_DO_JUMP,
    MAV_CMD_NAV_ROI,
    MAV_CMD_DO_SET_ROI,
    MAV_CMD_DO_WINCH,
    MAV_CMD_DO_GRIPPER,
    MAV_CMD_DO_CHANGE_SPEED,
    MAV_CMD_DO_SET_HOME,
    MAV_CMD_DO_LAND_START,
    MAV_CMD_DO_TRIGGER_CONTROL,
    MAV_CMD_DO_DIGICAM_CONTROL,
    MAV_CMD_DO_MOUNT_CONFIGURE,
    MAV_CMD_DO_MOUNT_CONTROL,
    MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
    MAV_CMD_SET_CAMERA_FOCUS,
    MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE,
    MAV_CMD_IMAGE_START_CAPTURE,
    MAV_CMD_IMAGE_STOP_CAPTURE,
    MAV_CMD_VIDEO_START_CAPTURE,
    MAV_CMD_VIDEO_STOP_CAPTURE,
    MAV_CMD_DO_CONTROL_VIDEO,
    MAV_CMD_DO_SET_CAM_TRIGG_DIST,
    MAV_CMD_OBLIQUE_SURVEY,
    MAV_CMD_DO_SET_CAM_TRIGG_INTERVAL,
    MAV_CMD_SET_CAMERA_MODE,
    MAV_CMD_DO_VTOL_TRANSITION,
    MAV_CMD_NAV_DELAY,
    MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MAV_CMD_DO_SET_ROI_WPNEXT_OFFSET,
    MAV_CMD_DO_SET_ROI_NONE,
    MAV_CMD_CONDITION_DELAY,
    MAV_CMD_CONDITION_DISTANCE,
    MAV_CMD_DO_SET_ACTUATOR,
];

/// The commands ArduPilot takes in a mission: the cases of `mavlink_int_to_mission_cmd` (copter
/// build), and the camera and region-of-interest commands ArduCopter V4.8.0-dev SITL took
/// (IMAGE_START/STOP_CAPTURE, VIDEO_START/STOP_CAPTURE, DO_SET_ROI_LOCATION, DO_SET_ROI_NONE).
#[allow(deprecated)]
const ARDUPILOT: &[MavCmd] = &[
    MAV_CMD_NAV_WAYPOINT,
    MAV_CMD_NAV_LOITER_UNLIM,
    MAV_CMD_NAV_LOITER_TURNS,
    MAV_CMD_NAV_LOITER_TIME,
    MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MAV_CMD_NAV_LAND,
    MAV_CMD_NAV_TAKEOFF,
    MAV_CMD_NAV_CONTINUE_AND_CHANGE_ALT,
    MAV_CMD_NAV_LOITER_TO_ALT,
    MAV_CMD_NAV_SPLINE_WAYPOINT,
    MAV_CMD_NAV_ALTITUDE_WAIT,
    MAV_CMD_NAV_VTOL_TAKEOFF,
    MAV_CMD_NAV_VTOL_LAND,
    MAV_CMD_NAV_GUIDED_ENABLE,
    MAV_CMD_NAV_DELAY,
    MAV_CMD_NAV_PAYLOAD_PLACE,
    MAV_CMD_NAV_SET_YAW_SPEED,
    MAV_CMD_NAV_SCRIPT_TIME,
    MAV_CMD_NAV_ATTITUDE_TIME,
    MAV_CMD_CONDITION_DELAY,
    MAV_CMD_CONDITION_DISTANCE,
    MAV_CMD_CONDITION_YAW,
    MAV_CMD_DO_JUMP,
    MAV_CMD_DO_CHANGE_SPEED,
    MAV_CMD_DO_SET_HOME,
    MAV_CMD_DO_SET_RELAY,
    MAV_CMD_DO_REPEAT_RELAY,
    MAV_CMD_DO_SET_SERVO,
    MAV_CMD_DO_REPEAT_SERVO,
    MAV_CMD_DO_LAND_START,
    MAV_CMD_DO_GO_AROUND,
    MAV_CMD_DO_PAUSE_CONTINUE,
    MAV_CMD_DO_SET_REVERSE,
    MAV_CMD_DO_SET_ROI_LOCATION,
    MAV_CMD_DO_SET_ROI_NONE,
    MAV_CMD_DO_SET_ROI,
    MAV_CMD_DO_DIGICAM_CONFIGURE,
    MAV_CMD_DO_DIGICAM_CONTROL,
    MAV_CMD_DO_MOUNT_CONTROL,
    MAV_CMD_DO_SET_CAM_TRIGG_DIST,
    MAV_CMD_DO_FENCE_ENABLE,
    MAV_CMD_DO_PARACHUTE,
    MAV_CMD_DO_INVERTED_FLIGHT,
    MAV_CMD_DO_GRIPPER,
    MAV_CMD_DO_AUTOTUNE_ENABLE,
    MAV_CMD_DO_SET_RESUME_REPEAT_DIST,
    MAV_CMD_DO_SPRAYER,
    MAV_CMD_DO_SEND_SCRIPT_MESSAGE,
    MAV_CMD_DO_AUX_FUNCTION,
    MAV_CMD_DO_GUIDED_LIMITS,
    MAV_CMD_DO_ENGINE_CONTROL,
    MAV_CMD_DO_VTOL_TRANSITION,
    MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW,
    MAV_CMD_IMAGE_START_CAPTURE,
    MAV_CMD_IMAGE_STOP_CAPTURE,
    MAV_CMD_VIDEO_START_CAPTURE,
    MAV_CMD_VIDEO_STOP_CAPTURE,
    MAV_CMD_DO_WINCH,
];

/// The navigation commands with a position (ArduPilot's `stored_in_location` among them; PX4
/// parses those it takes only in a global frame): an altitude above home needs frame 3 even
/// when the caller's item has no latitude/longitude of its own.
const LOCATED_NAVIGATION: &[MavCmd] = &[
    MAV_CMD_NAV_WAYPOINT,
    MAV_CMD_NAV_LOITER_UNLIM,
    MAV_CMD_NAV_LOITER_TURNS,
    MAV_CMD_NAV_LOITER_TIME,
    MAV_CMD_NAV_LAND,
    MAV_CMD_NAV_TAKEOFF,
    MAV_CMD_NAV_CONTINUE_AND_CHANGE_ALT,
    MAV_CMD_NAV_LOITER_TO_ALT,
    MAV_CMD_NAV_SPLINE_WAYPOINT,
    MAV_CMD_NAV_VTOL_TAKEOFF,
    MAV_CMD_NAV_VTOL_LAND,
    MAV_CMD_NAV_PAYLOAD_PLACE,
];

fn listed(list: &[MavCmd], command: u16) -> bool {
    list.iter().any(|&c| c as u32 == u32::from(command))
}

fn px4_mission(command: u16) -> bool {
    listed(PX4_MISSION, command)
}

fn px4_global(command: u16) -> bool {
    listed(PX4_GLOBAL, command)
}

/// Whether an autopilot of `flavour` accepts `command` (a MAV_CMD id) as a mission item.
pub fn takes(flavour: Flavour, command: u16) -> bool {
    match flavour {
        Flavour::Px4 => px4_global(command) || px4_mission(command),
        Flavour::ArduPilot => listed(ARDUPILOT, command),
        Flavour::Generic => true,
    }
}

/// The frame to send action `command` in for `flavour` (has_position: the item carries a
/// latitude/longitude, e.g. DO_SET_ROI_LOCATION).
///
/// An item with a position goes in MAV_FRAME_GLOBAL_RELATIVE_ALT (3), like the waypoints: PX4
/// takes a positional command only in a global frame (DO_SET_ROI_LOCATION and NAV_LOITER_TIME
/// in frame 2: MAV_MISSION_UNSUPPORTED; DO_SET_ROI at a location in frame 2:
/// MAV_MISSION_INVALID_PARAM1), and ArduPilot would take its altitude in frame 2 as above sea
/// level. A navigation command with a position, and a command PX4 parses only in a global
/// frame, go there even when the caller says the item has none. Anything else goes in MAV_FRAME_MISSION (2), the only frame PX4 takes it in
/// (every other command in frame 3: MAV_MISSION_UNSUPPORTED) and the one QGroundControl uses;
/// ArduPilot does not look at the frame of a command without a location.
pub fn action_frame(flavour: Flavour, command: u16, has_position: bool) -> MavFrame {
    let global_only = flavour == Flavour::Px4 && px4_global(command) && !px4_mission(command);
    if has_position || global_only || listed(LOCATED_NAVIGATION, command) {
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
    } else {
        MavFrame::MAV_FRAME_MISSION
    }
}

/// What an autopilot declared it holds besides a mission.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Capabilities {
    /// MAV_PROTOCOL_CAPABILITY_MISSION_FENCE.
    pub fence: bool,
    /// MAV_PROTOCOL_CAPABILITY_MISSION_RALLY.
    pub rally: bool,
    /// AUTOPILOT_VERSION arrived (false: nothing was declared, so nothing is held).
    pub declared: bool,
}

/// A mission the autopilot cannot hold all of.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SupportError {
    #[error(
        "the mission has {what} but the autopilot ({autopilot}) {how}: it would fly without it; \
         refused"
    )]
    Cannot {
        what: &'static str,
        autopilot: String,
        how: String,
    },
}

impl Capabilities {
    /// The capabilities an AUTOPILOT_VERSION declares.
    pub fn from_bits(bits: MavProtocolCapability) -> Capabilities {
        Capabilities {
            fence: bits.contains(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_FENCE),
            rally: bits.contains(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_RALLY),
            declared: true,
        }
    }

    /// An autopilot that never said what it holds.
    pub fn undeclared() -> Capabilities {
        Capabilities {
            fence: false,
            rally: false,
            declared: false,
        }
    }

    /// Refuses a mission with a fence (`fence`) or rally points (`rally`) for an autopilot
    /// (`autopilot`, its name in the error) that does not declare it holds them.
    pub fn check(&self, autopilot: &str, fence: bool, rally: bool) -> Result<(), SupportError> {
        let how = |bit: &str| {
            if self.declared {
                format!("does not declare {bit} in its AUTOPILOT_VERSION")
            } else {
                format!("sent no AUTOPILOT_VERSION, so it does not declare {bit}")
            }
        };
        if fence && !self.fence {
            return Err(SupportError::Cannot {
                what: "a geofence",
                autopilot: autopilot.to_string(),
                how: how("MAV_PROTOCOL_CAPABILITY_MISSION_FENCE"),
            });
        }
        if rally && !self.rally {
            return Err(SupportError::Cannot {
                what: "rally points",
                autopilot: autopilot.to_string(),
                how: how("MAV_PROTOCOL_CAPABILITY_MISSION_RALLY"),
            });
        }
        Ok(())
    }
}

/// Timing of [`AskCapabilities`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AskConfig {
    /// Ask again when no answer came within this.
    pub retry: Duration,
    /// Give up (nothing declared) after this.
    pub budget: Duration,
}

impl Default for AskConfig {
    fn default() -> Self {
        // Both autopilots answer within a round trip; five requests over a lossy radio.
        AskConfig {
            retry: Duration::from_secs(1),
            budget: Duration::from_secs(5),
        }
    }
}

/// Asks the autopilot for AUTOPILOT_VERSION (MAV_CMD_REQUEST_MESSAGE 148, which PX4 and
/// ArduPilot answer; an autopilot that answers UNSUPPORTED is asked with the older
/// MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES) until it comes or the budget runs out.
#[derive(Debug, Clone)]
pub struct AskCapabilities {
    target: Autopilot,
    cfg: AskConfig,
    started: Duration,
    next_send: Duration,
    legacy: bool,
    requests: u32,
    result: Option<Capabilities>,
}

impl AskCapabilities {
    pub fn new(target: Autopilot, cfg: AskConfig) -> AskCapabilities {
        AskCapabilities {
            target,
            cfg,
            started: Duration::ZERO,
            next_send: Duration::ZERO,
            legacy: false,
            requests: 0,
            result: None,
        }
    }

    /// What the autopilot declared, once finished (undeclared when it never answered).
    pub fn finished(&self) -> Option<Capabilities> {
        self.result
    }

    /// Requests sent so far.
    pub fn requests(&self) -> u32 {
        self.requests
    }

    // MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES is superseded by MAV_CMD_REQUEST_MESSAGE, but an
    // autopilot that does not know the latter knows only it.
    #[allow(deprecated)]
    fn request(&mut self, now: Duration) -> Vec<MavMessage> {
        self.requests += 1;
        self.next_send = now + self.cfg.retry;
        let (command, param1) = if self.legacy {
            (MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1.0)
        } else {
            (
                MavCmd::MAV_CMD_REQUEST_MESSAGE,
                AUTOPILOT_VERSION_DATA::ID as f32,
            )
        };
        vec![MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command,
            param1,
            target_system: self.target.system_id,
            target_component: self.target.component_id,
            ..Default::default()
        })]
    }

    pub fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        self.started = now;
        self.request(now)
    }

    pub fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        if self.result.is_some() {
            return Vec::new();
        }
        match message {
            MavMessage::AUTOPILOT_VERSION(v) => {
                self.result = Some(Capabilities::from_bits(v.capabilities));
                Vec::new()
            }
            MavMessage::COMMAND_ACK(a)
                if a.command == MavCmd::MAV_CMD_REQUEST_MESSAGE
                    && a.result == MavResult::MAV_RESULT_UNSUPPORTED
                    && !self.legacy =>
            {
                self.legacy = true;
                self.request(now)
            }
            _ => Vec::new(),
        }
    }

    pub fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        if self.result.is_some() {
            return Vec::new();
        }
        if now.saturating_sub(self.started) >= self.cfg.budget {
            self.result = Some(Capabilities::undeclared());
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
    use crate::link::readback::fixtures::{cases, Case};

    const ACTIONS: [u16; 20] = [
        203, 2000, 2001, 2500, 2501, 206, 205, 1000, 195, 197, 201, 115, 183, 181, 211, 42600, 93,
        19, 178, 82,
    ];

    /// What each SITL accepted, per command and frame, is what `takes` and `action_frame` say:
    /// a command is taken when the SITL accepted it in some frame, and the frame `action_frame`
    /// picks is one the SITL accepted it in.
    #[test]
    fn takes_and_the_action_frame_are_what_each_sitl_accepted() {
        for flavour in [Flavour::Px4, Flavour::ArduPilot] {
            let measured = cases(flavour);
            for command in ACTIONS {
                let of: Vec<&Case> = measured.iter().filter(|c| c.command == command).collect();
                assert!(!of.is_empty(), "{flavour:?} {command}: not measured");
                let accepted_in = |frame: u8| {
                    let sent_in: Vec<_> = of.iter().filter(|c| c.frame == frame).collect();
                    !sent_in.is_empty() && sent_in.iter().all(|c| c.accepted())
                };
                let any = of.iter().any(|c| c.accepted());
                assert_eq!(takes(flavour, command), any, "{flavour:?} {command}");
                if any {
                    // The probe sent these at a location near the waypoint.
                    let positional = matches!(command, 195 | 201 | 19 | 82);
                    let frame = action_frame(flavour, command, positional) as u8;
                    assert!(accepted_in(frame), "{flavour:?} {command} in frame {frame}");
                }
            }
        }
    }

    #[test]
    fn px4_refuses_yaw_servo_relay_and_spline_and_ardupilot_takes_them() {
        for command in [115, 183, 181, 82] {
            assert!(!takes(Flavour::Px4, command), "{command}");
            assert!(takes(Flavour::ArduPilot, command), "{command}");
            assert!(takes(Flavour::Generic, command), "{command}");
        }
        assert!(!takes(Flavour::ArduPilot, 65_000));
        assert!(takes(Flavour::Generic, 65_000));
    }

    #[test]
    fn a_located_action_goes_in_the_relative_frame_and_the_rest_in_the_mission_frame() {
        for flavour in [Flavour::Px4, Flavour::ArduPilot, Flavour::Generic] {
            assert_eq!(
                action_frame(flavour, 195, true),
                MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
            );
            assert_eq!(
                action_frame(flavour, 205, false),
                MavFrame::MAV_FRAME_MISSION
            );
            assert_eq!(
                action_frame(flavour, 178, false),
                MavFrame::MAV_FRAME_MISSION
            );
        }
        // DO_SET_ROI without a location (next waypoint) is a mission-frame item on PX4.
        assert_eq!(
            action_frame(Flavour::Px4, 201, false),
            MavFrame::MAV_FRAME_MISSION
        );
        // A loiter at the vehicle's own position still has an altitude above home.
        for flavour in [Flavour::Px4, Flavour::ArduPilot, Flavour::Generic] {
            assert_eq!(
                action_frame(flavour, 19, false),
                MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
            );
        }
    }

    fn version(bits: MavProtocolCapability) -> MavMessage {
        MavMessage::AUTOPILOT_VERSION(AUTOPILOT_VERSION_DATA {
            capabilities: bits,
            ..Default::default()
        })
    }

    fn asks(out: &[MavMessage]) -> Vec<(MavCmd, f32)> {
        out.iter()
            .filter_map(|m| match m {
                MavMessage::COMMAND_LONG(c) => Some((c.command, c.param1)),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn the_capabilities_are_asked_for_again_until_autopilot_version_comes() {
        use crate::link::testing::{autopilot, ms};
        let mut ask = AskCapabilities::new(autopilot(Flavour::Px4), AskConfig::default());
        assert_eq!(
            asks(&ask.start(ms(0))),
            vec![(MavCmd::MAV_CMD_REQUEST_MESSAGE, 148.0)]
        );
        assert!(ask.tick(ms(999)).is_empty());
        assert_eq!(asks(&ask.tick(ms(1000))).len(), 1);
        let bits = MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
            | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_INT;
        ask.handle(ms(1100), &version(bits));
        assert_eq!(
            ask.finished(),
            Some(Capabilities {
                fence: true,
                rally: false,
                declared: true
            })
        );
        assert!(ask.tick(ms(2000)).is_empty());
    }

    #[test]
    #[allow(deprecated)]
    fn an_autopilot_that_never_answers_declares_nothing_and_an_unsupported_request_falls_back() {
        use crate::link::mav::COMMAND_ACK_DATA;
        use crate::link::testing::{autopilot, ms};
        let mut ask = AskCapabilities::new(autopilot(Flavour::Generic), AskConfig::default());
        ask.start(ms(0));
        let unsupported = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_REQUEST_MESSAGE,
            result: MavResult::MAV_RESULT_UNSUPPORTED,
            ..Default::default()
        });
        assert_eq!(
            asks(&ask.handle(ms(10), &unsupported)),
            vec![(MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1.0)]
        );
        let mut now = ms(0);
        while ask.finished().is_none() {
            now += ms(100);
            ask.tick(now);
        }
        assert_eq!(now, ms(5000));
        assert_eq!(ask.finished(), Some(Capabilities::undeclared()));
    }

    #[test]
    fn a_fence_is_refused_for_an_autopilot_that_does_not_declare_it_naming_the_bit() {
        let none =
            Capabilities::from_bits(MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_INT);
        let err = none
            .check("MAVSDK (generic MAVLink)", true, false)
            .unwrap_err();
        assert_eq!(
            err.to_string(),
            "the mission has a geofence but the autopilot (MAVSDK (generic MAVLink)) does not \
             declare MAV_PROTOCOL_CAPABILITY_MISSION_FENCE in its AUTOPILOT_VERSION: it would fly \
             without it; refused"
        );
        assert!(none
            .check("x", false, true)
            .unwrap_err()
            .to_string()
            .contains("rally points"));
        assert!(none.check("x", false, false).is_ok());
        let silent = Capabilities::undeclared()
            .check("x", true, false)
            .unwrap_err();
        assert!(
            silent.to_string().contains("sent no AUTOPILOT_VERSION"),
            "{silent}"
        );
        let both = Capabilities::from_bits(
            MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
                | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_RALLY,
        );
        assert!(both.check("PX4", true, true).is_ok());
    }
}
