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

use super::mav::{MavCmd, MavFrame};
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
}
