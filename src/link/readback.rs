//! What each autopilot keeps of a mission item, so that a read-back is compared with what the
//! autopilot will fly rather than byte for byte: a verified upload means the vehicle holds what
//! was planned, and a real difference (a latitude off by 1 degE7, an altitude by 0.1 m, another
//! command, another hold time) is still caught.
//!
//! Every rule names its source:
//! - PX4: `src/modules/mavlink/mavlink_mission.cpp` (PX4-Autopilot commit 001bb4d7, PX4 main),
//!   `parse_mavlink_mission_item` (what is stored) and `format_mavlink_mission_item` (what a
//!   MISSION_REQUEST_INT is answered with); checked against PX4 SITL.
//! - ArduPilot: `libraries/AP_Mission/AP_Mission.cpp`, `mavlink_int_to_mission_cmd` (stored),
//!   `mission_cmd_to_mavlink_int` (answered), `read_cmd_from_storage` (item 0 is home); checked
//!   against ArduCopter SITL.
//! - Generic (MAVSDK's MissionRawServer and any other): stores the items as received.

use std::fmt;

use super::mav::{MavCmd, MavFrame, MavMissionType, MISSION_ITEM_INT_DATA};
use super::Flavour;

/// One field of one item that differs from what the autopilot should hold.
#[derive(Debug, Clone, PartialEq)]
pub struct Difference {
    pub seq: u16,
    pub field: &'static str,
    pub sent: String,
    /// What the autopilot should hold by its rule (equal to `sent` when it keeps the field).
    pub expected: String,
    pub read: String,
    /// The storage rule applied, when the autopilot does not keep the field as sent.
    pub rule: Option<&'static str>,
}

impl fmt::Display for Difference {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "item {} {} differs: sent {}, read back {}",
            self.seq, self.field, self.sent, self.read
        )?;
        if let Some(rule) = self.rule {
            write!(f, " (expected {}: {rule})", self.expected)?;
        }
        Ok(())
    }
}

/// What a read-back field must hold.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Want {
    /// Anything (the autopilot overwrites it).
    Any,
    Int(i64),
    /// A float within an absolute tolerance; NaN only matches NaN.
    Float(f32, f32),
    /// An angle in degrees, equal modulo 360 within a tolerance; NaN only matches NaN.
    Angle(f32, f32),
}

impl Want {
    fn holds(self, read: f64) -> bool {
        match self {
            Want::Any => true,
            Want::Int(v) => read == v as f64,
            Want::Float(v, tol) => {
                (v.is_nan() && read.is_nan()) || (f64::from(v) - read).abs() <= f64::from(tol)
            }
            Want::Angle(v, tol) => {
                if v.is_nan() || read.is_nan() {
                    return v.is_nan() && read.is_nan();
                }
                let d = (f64::from(v) - read).rem_euclid(360.0);
                d.min(360.0 - d) <= f64::from(tol)
            }
        }
    }

    fn show(self) -> String {
        match self {
            Want::Any => "anything".into(),
            Want::Int(v) => v.to_string(),
            Want::Float(v, _) | Want::Angle(v, _) => format!("{v}"),
        }
    }
}

/// A field's expectation and, when the autopilot changes it, the rule that says how.
#[derive(Debug, Clone, Copy)]
struct Field {
    want: Want,
    rule: Option<&'static str>,
}

fn kept(want: Want) -> Field {
    Field { want, rule: None }
}

fn ruled(want: Want, rule: &'static str) -> Field {
    Field {
        want,
        rule: Some(rule),
    }
}

/// What one read-back item must hold, field by field.
#[derive(Debug, Clone, Copy)]
struct Expect {
    frame: Field,
    command: Field,
    x: Field,
    y: Field,
    z: Field,
    params: [Field; 4],
    autocontinue: Field,
}

/// Float tolerance of an autopilot that stores what it receives: 1e-4 relative, as a float
/// passed through another implementation's serialisation must be.
fn relative(v: f32) -> Want {
    Want::Float(v, 1e-4 * v.abs().max(1.0))
}

fn generic(sent: &MISSION_ITEM_INT_DATA) -> Expect {
    let p = [sent.param1, sent.param2, sent.param3, sent.param4];
    Expect {
        frame: kept(Want::Int(sent.frame as i64)),
        command: kept(Want::Int(sent.command as i64)),
        x: kept(Want::Int(i64::from(sent.x))),
        y: kept(Want::Int(i64::from(sent.y))),
        z: kept(relative(sent.z)),
        params: p.map(|v| kept(relative(v))),
        autocontinue: kept(Want::Int(i64::from(sent.autocontinue))),
    }
}

/// The frame of a global item as PX4 answers MISSION_REQUEST_INT.
#[allow(deprecated)]
fn px4_frame(frame: MavFrame) -> Option<MavFrame> {
    use MavFrame::*;
    match frame {
        // parse_mavlink_mission_item keeps only `altitude_is_relative`; format_mavlink_mission_item
        // answers in int mode with MAV_FRAME_GLOBAL_RELATIVE_ALT_INT or MAV_FRAME_GLOBAL_INT.
        MAV_FRAME_GLOBAL_RELATIVE_ALT | MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => {
            Some(MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)
        }
        MAV_FRAME_GLOBAL | MAV_FRAME_GLOBAL_INT => Some(MAV_FRAME_GLOBAL_INT),
        _ => None,
    }
}

const PX4_FRAME: &str = "PX4 answers a global item in the _INT frame of its altitude reference \
                         (mavlink_mission.cpp format_mavlink_mission_item)";
const PX4_UNUSED: &str = "PX4 does not store this parameter for this command and answers 0 \
                          (mavlink_mission.cpp parse_/format_mavlink_mission_item)";
const PX4_YAW: &str = "PX4 stores yaw as radians wrapped to [0, 2pi) (wrap_2pi), answered in \
                       degrees; NaN stays NaN";
const PX4_BOOL: &str = "PX4 stores this parameter as a flag (> 0) and answers 0 or 1";

fn px4(sent: &MISSION_ITEM_INT_DATA) -> Expect {
    use MavCmd::*;
    let mut e = generic(sent);
    let Some(frame) = px4_frame(sent.frame) else {
        // MAV_FRAME_MISSION items keep params[0..6] as floats and doubles: as sent.
        return e;
    };
    e.frame = if frame == sent.frame {
        kept(Want::Int(frame as i64))
    } else {
        ruled(Want::Int(frame as i64), PX4_FRAME)
    };
    // `altitude` is a float; PX4 SITL answered 49.0 as 49.00006 (an AMSL round trip).
    e.z = kept(Want::Float(sent.z, 1e-3 + 1e-6 * sent.z.abs()));
    let zero = ruled(Want::Float(0.0, 0.0), PX4_UNUSED);
    let yaw = ruled(Want::Angle(sent.param4, 1e-3), PX4_YAW);
    let flag = |v: f32| ruled(Want::Float(if v > 0.0 { 1.0 } else { 0.0 }, 0.0), PX4_BOOL);
    let [p1, p2, p3, _] = e.params;
    e.params = match sent.command {
        // time_inside, acceptance_radius, yaw; the pass radius (param3) is not stored.
        MAV_CMD_NAV_WAYPOINT => [p1, p2, zero, yaw],
        MAV_CMD_NAV_TAKEOFF => [zero, zero, zero, yaw],
        // "TODO: abort alt param1"; land_precision; yaw.
        MAV_CMD_NAV_LAND => [zero, p2, zero, yaw],
        MAV_CMD_NAV_LOITER_TIME => [p1, flag(sent.param2), p3, flag(sent.param4)],
        MAV_CMD_NAV_LOITER_UNLIM => [zero, zero, p3, yaw],
        MAV_CMD_NAV_LOITER_TO_ALT => [flag(sent.param1), p2, zero, flag(sent.param4)],
        MAV_CMD_NAV_VTOL_TAKEOFF | MAV_CMD_NAV_VTOL_LAND => [zero, zero, zero, yaw],
        MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
        | MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
        | MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
        | MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION => [p1, zero, zero, zero],
        // Every other global command (DO_SET_ROI_LOCATION, DO_SET_ROI at a location, ...) is
        // answered with its four parameters 0: PX4 SITL answered DO_SET_ROI's mode 3 as 0.
        _ => [zero; 4],
    };
    e
}

const AP_HOME: &str =
    "ArduPilot answers item 0 with its own home (AP_Mission::read_cmd_from_storage)";
const AP_FRAME: &str = "ArduPilot keeps only whether an altitude is relative and answers \
                        MAV_FRAME_GLOBAL_RELATIVE_ALT or MAV_FRAME_GLOBAL, and MAV_FRAME_GLOBAL (0) \
                        for a command without a location (AP_Mission::mission_cmd_to_mavlink_int)";
const AP_ALT: &str = "ArduPilot stores altitude in whole centimetres (`packet.z * 100.0f` into \
                      an integer, AP_Mission::mavlink_int_to_mission_cmd)";
const AP_UNUSED: &str = "ArduPilot does not store this parameter for this command and answers 0 \
                         (AP_Mission::mavlink_int_to_mission_cmd, copter build)";
const AP_WHOLE: &str = "ArduPilot stores this parameter as a whole number (cmd.p1, uint16_t)";
const AP_SIGN: &str = "ArduPilot keeps only the direction (loiter_ccw) and answers -1 or 1";
const AP_NO_LOCATION: &str = "ArduPilot stores no location for a command without one and answers 0";
const AP_AUTOCONTINUE: &str = "ArduPilot answers autocontinue 1 (mission_cmd_to_mavlink_int)";

/// Whether ArduPilot stores a location for the command (AP_Mission::stored_in_location: the
/// navigation commands with a position; not RTL, not DO_ and CONDITION_ commands).
#[allow(deprecated)]
fn ap_location(command: MavCmd) -> bool {
    use MavCmd::*;
    matches!(
        command,
        MAV_CMD_NAV_WAYPOINT
            | MAV_CMD_NAV_LOITER_UNLIM
            | MAV_CMD_NAV_LOITER_TURNS
            | MAV_CMD_NAV_LOITER_TIME
            | MAV_CMD_NAV_LAND
            | MAV_CMD_NAV_TAKEOFF
            | MAV_CMD_NAV_CONTINUE_AND_CHANGE_ALT
            | MAV_CMD_NAV_LOITER_TO_ALT
            | MAV_CMD_NAV_SPLINE_WAYPOINT
            | MAV_CMD_NAV_VTOL_TAKEOFF
            | MAV_CMD_NAV_VTOL_LAND
            | MAV_CMD_NAV_PAYLOAD_PLACE
            | MAV_CMD_DO_SET_HOME
            | MAV_CMD_DO_LAND_START
            | MAV_CMD_DO_SET_ROI
            | MAV_CMD_DO_SET_ROI_LOCATION
    )
}

/// A float parameter stored in an unsigned 16-bit field, truncated as C converts.
fn whole(v: f32) -> f32 {
    if v.is_nan() || v <= 0.0 {
        0.0
    } else {
        v.trunc().min(65_535.0)
    }
}

/// How ArduPilot keeps one field of a command it packs into its `Mission_Command` content.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Packed {
    /// A float field: kept as sent.
    Float,
    /// An integer field of this range: the whole part, as C converts a float to it.
    Int(f32, f32, &'static str),
    /// Not stored: answered 0.
    Zero,
}

const U8: Packed = Packed::Int(0.0, 255.0, AP_U8);
const I8: Packed = Packed::Int(-128.0, 127.0, AP_I8);
const U16: Packed = Packed::Int(0.0, 65_535.0, AP_U16);
const I16: Packed = Packed::Int(-32_768.0, 32_767.0, AP_I16);
const F: Packed = Packed::Float;
const Z: Packed = Packed::Zero;

const AP_U8: &str = "ArduPilot stores this field in 8 bits and answers its whole part \
                     (AP_Mission::mavlink_int_to_mission_cmd, uint8_t)";
const AP_I8: &str = "ArduPilot stores this field in 8 signed bits and answers its whole part \
                     (AP_Mission::mavlink_int_to_mission_cmd, int8_t)";
const AP_U16: &str = "ArduPilot stores this field in 16 bits and answers its whole part \
                      (AP_Mission::mavlink_int_to_mission_cmd, uint16_t)";
const AP_I16: &str = "ArduPilot stores this field in 16 signed bits and answers its whole part \
                      (AP_Mission::mavlink_int_to_mission_cmd, int16_t)";

/// A float stored in an integer field of `[min, max]`: truncated toward zero, NaN as 0, clamped
/// where C is undefined.
pub(crate) fn packed_int(v: f32, min: f32, max: f32) -> f32 {
    if v.is_nan() {
        0.0
    } else {
        v.trunc().clamp(min, max)
    }
}

/// What ArduPilot keeps of an action command's param1..4 and (for one without a location) x, y,
/// z: its `Mission_Command` content (AP_Mission::mavlink_int_to_mission_cmd and
/// mission_cmd_to_mavlink_int, with the field types of AP_Mission.h), each checked against
/// ArduCopter SITL with fractions and x, y, z set (tests/fixtures/actions/ardupilot.txt).
#[allow(deprecated)]
fn ap_packed(command: MavCmd) -> Option<([Packed; 4], [Packed; 3])> {
    use MavCmd::*;
    const NONE: [Packed; 3] = [Z, Z, Z];
    Some(match command {
        // session, zoom_pos, zoom_step, focus_lock; shooting_cmd, cmd_id.
        MAV_CMD_DO_DIGICAM_CONTROL => ([U8, U8, I8, U8], [U8, U8, Z]),
        // instance, interval_s, total_num_images, start_seq_number.
        MAV_CMD_IMAGE_START_CAPTURE => ([U8, F, U16, U16], NONE),
        // cmd.p1: the camera instance.
        MAV_CMD_IMAGE_STOP_CAPTURE => ([U16, Z, Z, Z], NONE),
        // video_stream_id.
        MAV_CMD_VIDEO_START_CAPTURE | MAV_CMD_VIDEO_STOP_CAPTURE => ([U8, Z, Z, Z], NONE),
        // meters, trigger.
        MAV_CMD_DO_SET_CAM_TRIGG_DIST => ([F, Z, U8, Z], NONE),
        // pitch, roll, yaw; ArduCopter SITL also answered z (the mount mode) as sent.
        MAV_CMD_DO_MOUNT_CONTROL => ([F, F, F, Z], [Z, Z, F]),
        // pitch_angle_deg, yaw_angle_deg, pitch_rate_degs, yaw_rate_degs; flags, gimbal_id.
        MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW => ([I8, I16, I8, I8], [U8, Z, U8]),
        // cmd.p1 (the gimbal device).
        MAV_CMD_DO_SET_ROI_NONE | MAV_CMD_DO_SET_ROI_LOCATION => ([U16, Z, Z, Z], NONE),
        // cmd.p1: the ROI mode.
        MAV_CMD_DO_SET_ROI => ([U16, Z, Z, Z], NONE),
        // angle_deg, turn_rate_dps, direction, relative_angle.
        MAV_CMD_CONDITION_YAW => ([F, F, I8, U8], NONE),
        // channel, pwm.
        MAV_CMD_DO_SET_SERVO => ([U8, U16, Z, Z], NONE),
        // num, state.
        MAV_CMD_DO_SET_RELAY => ([U8, U8, Z, Z], NONE),
        // num, action.
        MAV_CMD_DO_GRIPPER => ([U8, U8, Z, Z], NONE),
        // num, action, release_length, release_rate.
        MAV_CMD_DO_WINCH => ([U8, U8, F, F], NONE),
        // seconds, hour_utc, min_utc, sec_utc.
        MAV_CMD_NAV_DELAY => ([F, I8, I8, I8], NONE),
        // speed_type, target_ms, throttle_pct.
        MAV_CMD_DO_CHANGE_SPEED => ([U8, F, F, Z], NONE),
        _ => return None,
    })
}

fn ap_field(packed: Packed, kept: Field, sent: f32) -> Field {
    match packed {
        Packed::Float => kept,
        Packed::Int(min, max, rule) => {
            let v = packed_int(sent, min, max);
            if v == sent {
                kept
            } else {
                ruled(Want::Float(v, 0.0), rule)
            }
        }
        Packed::Zero if sent == 0.0 => kept,
        Packed::Zero => ruled(Want::Float(0.0, 0.0), AP_UNUSED),
    }
}

#[allow(deprecated)]
fn ardupilot(sent: &MISSION_ITEM_INT_DATA) -> Expect {
    use MavCmd::*;
    use MavFrame::*;
    let mut e = generic(sent);
    if sent.seq == 0 {
        let home = ruled(Want::Any, AP_HOME);
        return Expect {
            frame: home,
            command: kept(Want::Int(MAV_CMD_NAV_WAYPOINT as i64)),
            x: home,
            y: home,
            z: home,
            params: [home; 4],
            autocontinue: home,
        };
    }
    let zero = ruled(Want::Float(0.0, 0.0), AP_UNUSED);
    if ap_location(sent.command) {
        let frame = match sent.frame {
            MAV_FRAME_GLOBAL_RELATIVE_ALT | MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => {
                MAV_FRAME_GLOBAL_RELATIVE_ALT
            }
            MAV_FRAME_GLOBAL_TERRAIN_ALT | MAV_FRAME_GLOBAL_TERRAIN_ALT_INT => {
                MAV_FRAME_GLOBAL_TERRAIN_ALT
            }
            _ => MAV_FRAME_GLOBAL,
        };
        if frame != sent.frame {
            e.frame = ruled(Want::Int(frame as i64), AP_FRAME);
        }
        // Whole centimetres, truncated: at most 1 cm below what was sent, plus float error.
        e.z = ruled(
            Want::Float((sent.z * 100.0).trunc() / 100.0, 1.1e-2),
            AP_ALT,
        );
    } else {
        e.frame = ruled(Want::Int(MAV_FRAME_GLOBAL as i64), AP_FRAME);
        let none = ruled(Want::Int(0), AP_NO_LOCATION);
        e.x = none;
        e.y = none;
        e.z = ruled(Want::Float(0.0, 0.0), AP_NO_LOCATION);
    }
    let whole_p1 = if whole(sent.param1) == sent.param1 {
        e.params[0]
    } else {
        ruled(Want::Float(whole(sent.param1), 0.0), AP_WHOLE)
    };
    let sign = |v: f32| ruled(Want::Float(if v < 0.0 { -1.0 } else { 1.0 }, 0.0), AP_SIGN);
    e.params = match sent.command {
        // Copter: cmd.p1 = hold time; acceptance radius, pass radius and yaw are not stored.
        MAV_CMD_NAV_WAYPOINT | MAV_CMD_NAV_TAKEOFF | MAV_CMD_NAV_SPLINE_WAYPOINT => {
            [whole_p1, zero, zero, zero]
        }
        // cmd.p1 = abort altitude; loiter_ccw = is_negative(param4) when not NaN.
        MAV_CMD_NAV_LAND => [whole_p1, zero, zero, sign(sent.param4)],
        MAV_CMD_NAV_RETURN_TO_LAUNCH => [zero; 4],
        MAV_CMD_NAV_LOITER_TIME => [
            whole_p1,
            zero,
            sign(sent.param3),
            ruled(
                Want::Float(if sent.param4 > 0.0 { 1.0 } else { 0.0 }, 0.0),
                AP_SIGN,
            ),
        ],
        _ => e.params,
    };
    if let Some((params, xyz)) = ap_packed(sent.command) {
        let p = [sent.param1, sent.param2, sent.param3, sent.param4];
        for k in 0..4 {
            e.params[k] = ap_field(params[k], e.params[k], p[k]);
        }
        if !ap_location(sent.command) {
            // x and y are integers on the wire; z a float.
            let xy = |packed: Packed, v: i32| match packed {
                Packed::Int(min, max, rule) => {
                    let w = packed_int(v as f32, min, max);
                    if w == v as f32 {
                        kept(Want::Int(i64::from(v)))
                    } else {
                        ruled(Want::Int(w as i64), rule)
                    }
                }
                Packed::Float => kept(Want::Int(i64::from(v))),
                Packed::Zero => ruled(Want::Int(0), AP_NO_LOCATION),
            };
            e.x = xy(xyz[0], sent.x);
            e.y = xy(xyz[1], sent.y);
            e.z = match xyz[2] {
                Packed::Zero => ruled(Want::Float(0.0, 0.0), AP_NO_LOCATION),
                packed => ap_field(packed, kept(relative(sent.z)), sent.z),
            };
        }
    }
    if sent.autocontinue != 1 {
        e.autocontinue = ruled(Want::Int(1), AP_AUTOCONTINUE);
    }
    e
}

const AP_FENCE_FRAME: &str = "ArduPilot keeps no frame of a fence item and answers the frame \
                              of a zeroed item (MissionItemProtocol_Fence::get_item_as_mission_item)";
const AP_FENCE_ALT: &str = "ArduPilot keeps no altitude of a fence item and answers 0 \
                            (MissionItemProtocol_Fence::get_item_as_mission_item)";
const AP_FENCE_COUNT: &str = "ArduPilot keeps a polygon's vertex count as a whole number \
                              (AC_PolyFenceItem::vertex_count, uint8_t)";
const AP_RALLY_FRAME: &str = "ArduPilot answers a rally point in MAV_FRAME_GLOBAL_RELATIVE_ALT \
                              (MissionItemProtocol_Rally::get_item)";
const AP_RALLY_ALT: &str = "ArduPilot stores a rally point's altitude as whole metres \
                            (RallyLocation::alt, int16_t, from packet.z)";
const AP_UNKEPT: &str = "ArduPilot keeps no parameter of this fence or rally item and answers 0";

/// What ArduPilot holds of a fence or rally item: its own stores (`AC_PolyFenceItem`,
/// `RallyLocation`), not `AP_Mission`'s, and no home at item 0.
fn ardupilot_fence_rally(sent: &MISSION_ITEM_INT_DATA) -> Expect {
    use MavCmd::*;
    let mut e = generic(sent);
    let zero = ruled(Want::Float(0.0, 0.0), AP_UNKEPT);
    e.autocontinue = ruled(Want::Any, AP_UNKEPT);
    match sent.command {
        MAV_CMD_NAV_RALLY_POINT => {
            e.frame = ruled(
                Want::Int(MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT as i64),
                AP_RALLY_FRAME,
            );
            e.z = ruled(Want::Float(sent.z.trunc(), 0.0), AP_RALLY_ALT);
            e.params = [zero; 4];
        }
        _ => {
            e.frame = ruled(Want::Any, AP_FENCE_FRAME);
            e.z = ruled(Want::Float(0.0, 0.0), AP_FENCE_ALT);
            let p1 = match sent.command {
                MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
                | MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION => ruled(
                    Want::Float(whole(sent.param1).min(255.0), 0.0),
                    AP_FENCE_COUNT,
                ),
                MAV_CMD_NAV_FENCE_RETURN_POINT => zero,
                // The radius, a float (AC_PolyFenceItem::radius).
                _ => e.params[0],
            };
            e.params = [p1, zero, zero, zero];
        }
    }
    e
}

fn expect(flavour: Flavour, sent: &MISSION_ITEM_INT_DATA) -> Expect {
    let mission = sent.mission_type == MavMissionType::MAV_MISSION_TYPE_MISSION;
    match flavour {
        Flavour::ArduPilot if !mission => ardupilot_fence_rally(sent),
        Flavour::Px4 => px4(sent),
        Flavour::ArduPilot => ardupilot(sent),
        Flavour::Generic => generic(sent),
    }
}

/// Checks one read-back item against what `flavour` should hold of the item sent.
pub fn check(
    flavour: Flavour,
    sent: &MISSION_ITEM_INT_DATA,
    read: &MISSION_ITEM_INT_DATA,
) -> Result<(), Box<Difference>> {
    let e = expect(flavour, sent);
    let fields: [(&'static str, Field, f64, f64); 10] = [
        (
            "command",
            e.command,
            sent.command as u32 as f64,
            read.command as u32 as f64,
        ),
        (
            "frame",
            e.frame,
            sent.frame as u32 as f64,
            read.frame as u32 as f64,
        ),
        (
            "x (latitude, degE7)",
            e.x,
            f64::from(sent.x),
            f64::from(read.x),
        ),
        (
            "y (longitude, degE7)",
            e.y,
            f64::from(sent.y),
            f64::from(read.y),
        ),
        ("z (altitude, m)", e.z, f64::from(sent.z), f64::from(read.z)),
        (
            "param1",
            e.params[0],
            f64::from(sent.param1),
            f64::from(read.param1),
        ),
        (
            "param2",
            e.params[1],
            f64::from(sent.param2),
            f64::from(read.param2),
        ),
        (
            "param3",
            e.params[2],
            f64::from(sent.param3),
            f64::from(read.param3),
        ),
        (
            "param4",
            e.params[3],
            f64::from(sent.param4),
            f64::from(read.param4),
        ),
        (
            "autocontinue",
            e.autocontinue,
            f64::from(sent.autocontinue),
            f64::from(read.autocontinue),
        ),
    ];
    if read.seq != sent.seq {
        return Err(Box::new(Difference {
            seq: sent.seq,
            field: "seq",
            sent: sent.seq.to_string(),
            expected: sent.seq.to_string(),
            read: read.seq.to_string(),
            rule: None,
        }));
    }
    for (field, f, sent_value, read_value) in fields {
        if !f.want.holds(read_value) {
            return Err(Box::new(Difference {
                seq: sent.seq,
                field,
                sent: format!("{sent_value}"),
                expected: f.want.show(),
                read: format!("{read_value}"),
                rule: f.rule,
            }));
        }
    }
    Ok(())
}

/// Why a read-back does not hold what was sent (the upload's `verify` stage).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReadbackError {
    #[error("verify: the autopilot holds {held} items, {sent} were sent")]
    CountMismatch { held: usize, sent: usize },
    #[error("verify: {0}")]
    Mismatch(Box<Difference>),
}

impl ReadbackError {
    /// The item the difference concerns, if one.
    pub fn item(&self) -> Option<u16> {
        match self {
            ReadbackError::Mismatch(d) => Some(d.seq),
            ReadbackError::CountMismatch { .. } => None,
        }
    }
}

/// Compares a read-back with what was sent, by what `flavour` keeps of each item.
pub fn verify(
    flavour: Flavour,
    sent: &[MISSION_ITEM_INT_DATA],
    read: &[MISSION_ITEM_INT_DATA],
) -> Result<(), ReadbackError> {
    if sent.len() != read.len() {
        return Err(ReadbackError::CountMismatch {
            held: read.len(),
            sent: sent.len(),
        });
    }
    for (a, b) in sent.iter().zip(read) {
        check(flavour, a, b).map_err(ReadbackError::Mismatch)?;
    }
    Ok(())
}

/// The SITLs' answers measured by `sitl/probe_actions.py` (tests/fixtures/actions/), for the
/// tests of `link` and `sim`.
#[cfg(test)]
pub(crate) mod fixtures {
    use num_traits::FromPrimitive;

    use super::super::mav::{MavCmd, MavFrame, MISSION_ITEM_INT_DATA};
    use super::super::Flavour;

    /// One upload of take-off, a waypoint and one action command (ArduPilot: home first).
    #[derive(Debug, Clone)]
    pub struct Case {
        pub command: u16,
        /// The frame the action was sent in.
        pub frame: u8,
        /// The MISSION_ACK type (0 accepted; -1 no answer).
        pub ack: i32,
        pub label: String,
        pub sent: Vec<MISSION_ITEM_INT_DATA>,
        /// Empty when the upload was refused.
        pub read: Vec<MISSION_ITEM_INT_DATA>,
    }

    impl Case {
        pub fn accepted(&self) -> bool {
            self.ack == 0
        }
    }

    fn item(fields: &[&str], at: &str) -> MISSION_ITEM_INT_DATA {
        assert_eq!(fields.len(), 11, "{at}");
        let f = |k: usize| {
            fields[k]
                .parse::<f32>()
                .unwrap_or_else(|e| panic!("{at}: {e}"))
        };
        let i = |k: usize| {
            fields[k]
                .parse::<i64>()
                .unwrap_or_else(|e| panic!("{at}: {e}"))
        };
        MISSION_ITEM_INT_DATA {
            seq: i(0) as u16,
            frame: MavFrame::from_i64(i(1)).unwrap_or_else(|| panic!("{at}: frame")),
            command: MavCmd::from_i64(i(2)).unwrap_or_else(|| panic!("{at}: command")),
            param1: f(3),
            param2: f(4),
            param3: f(5),
            param4: f(6),
            x: i(7) as i32,
            y: i(8) as i32,
            z: f(9),
            autocontinue: i(10) as u8,
            ..Default::default()
        }
    }

    /// Every case measured on the SITL of `flavour` (PX4 or ArduPilot).
    pub fn cases(flavour: Flavour) -> Vec<Case> {
        let (name, text) = match flavour {
            Flavour::Px4 => ("px4", include_str!("../../tests/fixtures/actions/px4.txt")),
            _ => (
                "ardupilot",
                include_str!("../../tests/fixtures/actions/ardupilot.txt"),
            ),
        };
        let mut cases: Vec<Case> = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let at = format!("{name}.txt line {}", n + 1);
            let fields: Vec<&str> = line.split_whitespace().collect();
            match fields.first().copied() {
                Some("case") => cases.push(Case {
                    command: fields[1].parse().unwrap(),
                    frame: fields[2].parse().unwrap(),
                    ack: fields[3].parse().unwrap(),
                    label: fields[4..].join(" "),
                    sent: Vec::new(),
                    read: Vec::new(),
                }),
                Some("sent") => cases.last_mut().unwrap().sent.push(item(&fields[1..], &at)),
                Some("read") => cases.last_mut().unwrap().read.push(item(&fields[1..], &at)),
                _ => {}
            }
        }
        cases
    }
}

#[cfg(test)]
#[allow(deprecated)]
mod tests {
    use super::*;
    use crate::link::items::{mission_items, ItemOptions};
    use MavCmd::*;
    use MavFrame::*;

    fn item(
        seq: u16,
        frame: MavFrame,
        command: MavCmd,
        p: [f32; 4],
        x: i32,
        y: i32,
        z: f32,
    ) -> MISSION_ITEM_INT_DATA {
        MISSION_ITEM_INT_DATA {
            param1: p[0],
            param2: p[1],
            param3: p[2],
            param4: p[3],
            x,
            y,
            z,
            seq,
            command,
            frame,
            autocontinue: 1,
            ..Default::default()
        }
    }

    const NAN: f32 = f32::NAN;

    /// What was sent to the SITLs (`/tmp/probe`-style pymavlink uploads, see sitl/README.md)...
    fn probe_sent() -> Vec<MISSION_ITEM_INT_DATA> {
        vec![
            item(
                0,
                MAV_FRAME_GLOBAL,
                MAV_CMD_NAV_WAYPOINT,
                [0.0, 0.0, 0.0, NAN],
                385362001,
                -1217875000,
                16.0,
            ),
            item(
                1,
                MAV_FRAME_GLOBAL_RELATIVE_ALT,
                MAV_CMD_NAV_TAKEOFF,
                [0.0, 0.0, 0.0, NAN],
                385362000,
                -1217875000,
                30.0,
            ),
            item(
                2,
                MAV_FRAME_MISSION,
                MAV_CMD_DO_CHANGE_SPEED,
                [1.0, 5.0, -1.0, 0.0],
                0,
                0,
                0.0,
            ),
            item(
                3,
                MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                MAV_CMD_NAV_WAYPOINT,
                [2.5, 2.0, 0.0, NAN],
                385363802,
                -1217877294,
                54.123,
            ),
            item(
                4,
                MAV_FRAME_GLOBAL_RELATIVE_ALT,
                MAV_CMD_NAV_WAYPOINT,
                [7.9, 2.0, 1.0, -90.0],
                385363803,
                -1217877294,
                12.345,
            ),
            item(
                5,
                MAV_FRAME_MISSION,
                MAV_CMD_NAV_RETURN_TO_LAUNCH,
                [0.0; 4],
                0,
                0,
                0.0,
            ),
        ]
    }

    /// ... and what PX4 SITL answered, field for field.
    fn px4_read() -> Vec<MISSION_ITEM_INT_DATA> {
        vec![
            item(
                0,
                MAV_FRAME_GLOBAL_INT,
                MAV_CMD_NAV_WAYPOINT,
                [0.0, 0.0, 0.0, NAN],
                385362001,
                -1217875000,
                16.0,
            ),
            item(
                1,
                MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                MAV_CMD_NAV_TAKEOFF,
                [0.0, 0.0, 0.0, NAN],
                385362000,
                -1217875000,
                30.0,
            ),
            item(
                2,
                MAV_FRAME_MISSION,
                MAV_CMD_DO_CHANGE_SPEED,
                [1.0, 5.0, -1.0, 0.0],
                0,
                0,
                0.0,
            ),
            item(
                3,
                MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                MAV_CMD_NAV_WAYPOINT,
                [2.5, 2.0, 0.0, NAN],
                385363802,
                -1217877294,
                54.123,
            ),
            item(
                4,
                MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                MAV_CMD_NAV_WAYPOINT,
                [7.9, 2.0, 0.0, 270.0],
                385363803,
                -1217877294,
                12.345,
            ),
            item(
                5,
                MAV_FRAME_MISSION,
                MAV_CMD_NAV_RETURN_TO_LAUNCH,
                [0.0; 4],
                0,
                0,
                0.0,
            ),
        ]
    }

    /// ... and what ArduCopter SITL answered (item 0: its own home, 16.1 m).
    fn ardupilot_read() -> Vec<MISSION_ITEM_INT_DATA> {
        vec![
            item(
                0,
                MAV_FRAME_GLOBAL,
                MAV_CMD_NAV_WAYPOINT,
                [0.0; 4],
                385362000,
                -1217875000,
                16.1,
            ),
            item(
                1,
                MAV_FRAME_GLOBAL_RELATIVE_ALT,
                MAV_CMD_NAV_TAKEOFF,
                [0.0; 4],
                385362000,
                -1217875000,
                30.0,
            ),
            item(
                2,
                MAV_FRAME_GLOBAL,
                MAV_CMD_DO_CHANGE_SPEED,
                [1.0, 5.0, -1.0, 0.0],
                0,
                0,
                0.0,
            ),
            item(
                3,
                MAV_FRAME_GLOBAL_RELATIVE_ALT,
                MAV_CMD_NAV_WAYPOINT,
                [2.0, 0.0, 0.0, 0.0],
                385363802,
                -1217877294,
                54.12,
            ),
            item(
                4,
                MAV_FRAME_GLOBAL_RELATIVE_ALT,
                MAV_CMD_NAV_WAYPOINT,
                [7.0, 0.0, 0.0, 0.0],
                385363803,
                -1217877294,
                12.34,
            ),
            item(
                5,
                MAV_FRAME_GLOBAL,
                MAV_CMD_NAV_RETURN_TO_LAUNCH,
                [0.0; 4],
                0,
                0,
                0.0,
            ),
        ]
    }

    #[test]
    fn what_px4_sitl_answered_verifies_as_px4_and_not_as_sent() {
        assert_eq!(verify(Flavour::Px4, &probe_sent(), &px4_read()), Ok(()));
        let err = verify(Flavour::Generic, &probe_sent(), &px4_read()).unwrap_err();
        assert!(err.to_string().contains("item 0 frame differs"), "{err}");
    }

    #[test]
    fn what_ardupilot_sitl_answered_verifies_as_ardupilot_and_not_as_sent() {
        assert_eq!(
            verify(Flavour::ArduPilot, &probe_sent(), &ardupilot_read()),
            Ok(())
        );
        assert!(verify(Flavour::Px4, &probe_sent(), &ardupilot_read()).is_err());
    }

    #[test]
    fn the_generic_flavour_wants_every_field_as_sent() {
        let sent = probe_sent();
        assert_eq!(verify(Flavour::Generic, &sent, &sent), Ok(()));
    }

    /// Each real difference, applied to the read-back of every flavour, is caught and named.
    #[test]
    fn a_real_difference_is_caught_for_every_flavour() {
        type Change = (&'static str, fn(&mut MISSION_ITEM_INT_DATA));
        let changes: [Change; 5] = [
            ("x (latitude, degE7)", |it| it.x += 1),
            ("z (altitude, m)", |it| it.z += 0.1),
            ("command", |it| it.command = MAV_CMD_NAV_LOITER_UNLIM),
            ("param1", |it| it.param1 += 1.0),
            ("y (longitude, degE7)", |it| it.y -= 1),
        ];
        let reads = [
            (Flavour::Px4, px4_read()),
            (Flavour::ArduPilot, ardupilot_read()),
            (Flavour::Generic, probe_sent()),
        ];
        for (flavour, read) in reads {
            // Item 3 is a waypoint with a hold time every flavour keeps.
            for (field, change) in changes {
                let mut bad = read.clone();
                change(&mut bad[3]);
                match verify(flavour, &probe_sent(), &bad) {
                    Err(ReadbackError::Mismatch(d)) => {
                        assert_eq!((d.seq, d.field), (3, field), "{flavour:?}: {d}")
                    }
                    other => panic!("{flavour:?} {field}: {other:?}"),
                }
            }
        }
    }

    use super::fixtures::{cases, Case};

    fn accepted(flavour: Flavour) -> Vec<Case> {
        let all: Vec<Case> = cases(flavour).into_iter().filter(Case::accepted).collect();
        assert!(all.len() >= 30, "{flavour:?}: {} accepted cases", all.len());
        all
    }

    fn case_named(flavour: Flavour, command: u16, label: &str) -> Case {
        accepted(flavour)
            .into_iter()
            .find(|c| c.command == command && c.label == label)
            .unwrap_or_else(|| panic!("{flavour:?} {command} {label}: not measured"))
    }

    /// Every action each SITL accepted (tests/fixtures/actions) verifies as that autopilot.
    #[test]
    fn what_each_sitl_answered_of_every_action_verifies_as_that_autopilot() {
        for flavour in [Flavour::Px4, Flavour::ArduPilot] {
            for case in accepted(flavour) {
                assert_eq!(
                    verify(flavour, &case.sent, &case.read),
                    Ok(()),
                    "{flavour:?} {} in frame {}",
                    case.label,
                    case.frame
                );
            }
        }
    }

    /// The SITLs change what they store: compared as sent, their answers would fail.
    #[test]
    fn what_the_sitls_answered_of_actions_does_not_verify_as_sent() {
        let gimbal = case_named(Flavour::ArduPilot, 1000, "DO_GIMBAL_MANAGER_PITCHYAW");
        let mut read = gimbal.read[3].clone();
        let d = check(Flavour::Generic, &gimbal.sent[3], &read).unwrap_err();
        assert_eq!(d.field, "frame");
        read.frame = gimbal.sent[3].frame;
        let d = check(Flavour::Generic, &gimbal.sent[3], &read).unwrap_err();
        assert_eq!(
            d.to_string(),
            "item 3 param1 differs: sent -45.5, read back -45"
        );
        let roi = case_named(Flavour::Px4, 201, "DO_SET_ROI location");
        let err = verify(Flavour::Generic, &roi.sent, &roi.read).unwrap_err();
        assert!(err.to_string().contains("item 0 frame differs"), "{err}");
        // Not as the other autopilot either.
        assert!(verify(Flavour::Px4, &gimbal.sent, &gimbal.read).is_err());
        assert!(verify(Flavour::ArduPilot, &roi.sent, &roi.read).is_err());
    }

    /// A vehicle holding another command, another value of any field the autopilot answers
    /// (another pitch, speed, shutter count, location) or another frame is caught, and the
    /// error names the field: every field of every action each SITL accepted, changed.
    #[test]
    fn a_real_difference_in_any_field_of_an_action_is_caught() {
        type Change = (&'static str, fn(&mut MISSION_ITEM_INT_DATA));
        let changes: [Change; 9] = [
            ("command", |it| {
                it.command = if it.command == MAV_CMD_DO_SET_SERVO {
                    MAV_CMD_DO_SET_RELAY
                } else {
                    MAV_CMD_DO_SET_SERVO
                }
            }),
            ("frame", |it| {
                it.frame = if it.frame == MAV_FRAME_GLOBAL_INT {
                    MAV_FRAME_GLOBAL_TERRAIN_ALT
                } else {
                    MAV_FRAME_GLOBAL_INT
                }
            }),
            ("param1", |it| it.param1 += 1.0),
            ("param2", |it| it.param2 -= 1.0),
            ("param3", |it| it.param3 += 1.0),
            ("param4", |it| it.param4 -= 1.0),
            ("x (latitude, degE7)", |it| it.x += 1),
            ("y (longitude, degE7)", |it| it.y -= 1),
            ("z (altitude, m)", |it| it.z += 0.1),
        ];
        for flavour in [Flavour::Px4, Flavour::ArduPilot] {
            for case in accepted(flavour) {
                let last = case.read.len() - 1;
                for (field, change) in changes {
                    let mut bad = case.read.clone();
                    change(&mut bad[last]);
                    match verify(flavour, &case.sent, &bad) {
                        Err(ReadbackError::Mismatch(d)) => assert_eq!(
                            (usize::from(d.seq), d.field),
                            (last, field),
                            "{flavour:?} {}: {d}",
                            case.label
                        ),
                        other => panic!("{flavour:?} {} {field}: {other:?}", case.label),
                    }
                }
            }
        }
    }

    #[test]
    fn ardupilot_answers_a_gimbal_pitch_in_whole_degrees_and_the_error_says_so() {
        let case = case_named(Flavour::ArduPilot, 1000, "DO_GIMBAL_MANAGER_PITCHYAW");
        let (sent, mut read) = (case.sent[3].clone(), case.read[3].clone());
        assert_eq!((sent.param1, read.param1), (-45.5, -45.0));
        assert!(check(Flavour::ArduPilot, &sent, &read).is_ok());
        read.param1 = -45.5;
        assert_eq!(
            check(Flavour::ArduPilot, &sent, &read)
                .unwrap_err()
                .to_string(),
            "item 3 param1 differs: sent -45.5, read back -45.5 (expected -45: ArduPilot stores \
             this field in 8 signed bits and answers its whole part \
             (AP_Mission::mavlink_int_to_mission_cmd, int8_t))"
        );
    }

    #[test]
    fn ardupilot_keeps_a_region_of_interest_sent_in_the_mission_frame_above_sea_level() {
        let case = accepted(Flavour::ArduPilot)
            .into_iter()
            .find(|c| c.command == 195 && c.frame == 2)
            .unwrap();
        assert_eq!(case.read[3].frame, MAV_FRAME_GLOBAL);
        assert!(check(Flavour::ArduPilot, &case.sent[3], &case.read[3]).is_ok());
        let mut relative = case.read[3].clone();
        relative.frame = MAV_FRAME_GLOBAL_RELATIVE_ALT;
        assert_eq!(
            check(Flavour::ArduPilot, &case.sent[3], &relative)
                .unwrap_err()
                .field,
            "frame"
        );
    }

    #[test]
    fn ardupilot_truncates_hold_time_and_altitude_and_the_error_says_so() {
        let sent = probe_sent()[3].clone();
        let mut read = ardupilot_read()[3].clone();
        // The altitude truncated to whole centimetres is ArduPilot's; a hold of 2.5 s is not.
        assert!(check(Flavour::ArduPilot, &sent, &read).is_ok());
        read.param1 = 2.5;
        let d = check(Flavour::ArduPilot, &sent, &read).unwrap_err();
        assert_eq!(d.field, "param1");
        assert_eq!(
            d.to_string(),
            "item 3 param1 differs: sent 2.5, read back 2.5 (expected 2: ArduPilot stores this \
             parameter as a whole number (cmd.p1, uint16_t))"
        );
    }

    #[test]
    fn px4s_altitude_round_trip_error_passes_and_a_tenth_of_a_metre_does_not() {
        let sent = item(
            1,
            MAV_FRAME_GLOBAL_RELATIVE_ALT,
            MAV_CMD_NAV_WAYPOINT,
            [5.0, 2.0, 0.0, NAN],
            385363802,
            -1217877294,
            49.0,
        );
        let mut read = sent.clone();
        read.frame = MAV_FRAME_GLOBAL_RELATIVE_ALT_INT;
        // PX4 SITL's answer for the 8-waypoint sample's 49 m waypoint.
        read.z = 49.000_06;
        assert!(check(Flavour::Px4, &sent, &read).is_ok());
        read.z = 49.1;
        let d = check(Flavour::Px4, &sent, &read).unwrap_err();
        assert_eq!(d.field, "z (altitude, m)");
    }

    #[test]
    fn px4_yaw_is_compared_modulo_a_turn_and_nan_only_with_nan() {
        let sent = item(
            1,
            MAV_FRAME_GLOBAL_RELATIVE_ALT,
            MAV_CMD_NAV_WAYPOINT,
            [0.0, 2.0, 0.0, -90.0],
            1,
            1,
            30.0,
        );
        let mut read = sent.clone();
        read.frame = MAV_FRAME_GLOBAL_RELATIVE_ALT_INT;
        read.param4 = 270.0;
        assert!(check(Flavour::Px4, &sent, &read).is_ok());
        read.param4 = 271.0;
        assert!(check(Flavour::Px4, &sent, &read).is_err());
        read.param4 = NAN;
        assert!(check(Flavour::Px4, &sent, &read).is_err());
    }

    #[test]
    fn emplans_own_items_verify_against_each_flavours_storage_of_them() {
        let mission = crate::mission::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("missions/paper-sample-8wp.toml"),
        )
        .unwrap();
        let order: Vec<usize> = (0..mission.waypoints.len()).collect();
        for flavour in [Flavour::Px4, Flavour::ArduPilot] {
            let opts = ItemOptions {
                flavour,
                ..ItemOptions::default()
            };
            let sent = mission_items(&mission, &order, &opts).unwrap();
            let stored: Vec<_> = sent
                .iter()
                .map(|it| {
                    crate::sim::storage::stored(flavour, it, &crate::sim::storage::Home::default())
                })
                .collect();
            assert_eq!(verify(flavour, &sent, &stored), Ok(()), "{flavour:?}");
        }
    }
}
