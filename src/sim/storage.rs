//! What the mock's flavours store of a mission item and answer a read-back with, modelled on the
//! autopilots' own storage (not on `link::readback`, which checks it): PX4 parses an item into a
//! `mission_item_s` and formats it back (`mavlink_mission.cpp`, `parse_mavlink_mission_item`,
//! `format_mavlink_mission_item`); ArduPilot packs it into a `Mission_Command` and unpacks it
//! (`AP_Mission.cpp`, `mavlink_int_to_mission_cmd`, `mission_cmd_to_mavlink_int`), item 0 being
//! its home (`read_cmd_from_storage`); MAVSDK keeps the items as they came.

use crate::link::mav::{MavCmd, MavFrame, MavMissionResult, MISSION_ITEM_INT_DATA};
use crate::link::Flavour;

/// The vehicle's own home (what ArduPilot answers for item 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Home {
    pub lat_e7: i32,
    pub lon_e7: i32,
    /// Above mean sea level. ArduCopter SITL, started at the sample field's 16 m, reports
    /// 16.1 m: the default, so a mission's 16.0 differs as on the real thing.
    pub alt_m: f32,
}

impl Default for Home {
    fn default() -> Self {
        Home {
            lat_e7: 385_362_000,
            lon_e7: -1_217_875_000,
            alt_m: 16.1,
        }
    }
}

/// The navigation commands the mock accepts: each carries a position (PX4 requires one, ArduPilot
/// stores one: `AP_Mission::stored_in_location`).
pub fn navigation(command: MavCmd) -> bool {
    use MavCmd::*;
    matches!(
        command,
        MAV_CMD_NAV_WAYPOINT
            | MAV_CMD_NAV_TAKEOFF
            | MAV_CMD_NAV_LAND
            | MAV_CMD_NAV_LOITER_TIME
            | MAV_CMD_NAV_LOITER_UNLIM
    )
}

/// The commands ArduPilot stores a location for (`AP_Mission::stored_in_location`) among those
/// the mock takes: the navigation commands, the spline waypoint and the two regions of interest
/// at a location.
#[allow(deprecated)]
pub fn ardupilot_located(command: MavCmd) -> bool {
    use MavCmd::*;
    navigation(command)
        || matches!(
            command,
            MAV_CMD_NAV_SPLINE_WAYPOINT | MAV_CMD_DO_SET_ROI_LOCATION | MAV_CMD_DO_SET_ROI
        )
}

/// The action commands (camera, gimbal, payload, delay, speed) PX4 parses in MAV_FRAME_MISSION
/// (`parse_mavlink_mission_item`'s second switch) among those the mock takes.
#[allow(deprecated)]
pub fn px4_mission_frame(command: MavCmd) -> bool {
    use MavCmd::*;
    matches!(
        command,
        MAV_CMD_NAV_RETURN_TO_LAUNCH
            | MAV_CMD_DO_CHANGE_SPEED
            | MAV_CMD_NAV_DELAY
            | MAV_CMD_DO_JUMP
            | MAV_CMD_DO_DIGICAM_CONTROL
            | MAV_CMD_IMAGE_START_CAPTURE
            | MAV_CMD_IMAGE_STOP_CAPTURE
            | MAV_CMD_VIDEO_START_CAPTURE
            | MAV_CMD_VIDEO_STOP_CAPTURE
            | MAV_CMD_DO_SET_CAM_TRIGG_DIST
            | MAV_CMD_DO_MOUNT_CONTROL
            | MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW
            | MAV_CMD_DO_SET_ROI_NONE
            | MAV_CMD_DO_SET_ROI
            | MAV_CMD_DO_GRIPPER
            | MAV_CMD_DO_WINCH
    )
}

/// The commands PX4 parses only in a global frame among those the mock takes: the navigation
/// commands and the region of interest at a location (`parse_mavlink_mission_item`'s first
/// switch; DO_SET_ROI is in both).
#[allow(deprecated)]
pub fn px4_global_frame(command: MavCmd) -> bool {
    use MavCmd::*;
    navigation(command) || matches!(command, MAV_CMD_DO_SET_ROI_LOCATION | MAV_CMD_DO_SET_ROI)
}

/// The commands ArduPilot takes among those the mock knows (`mavlink_int_to_mission_cmd`'s
/// cases): every one PX4 takes, and CONDITION_YAW, DO_SET_SERVO, DO_SET_RELAY and
/// NAV_SPLINE_WAYPOINT, which PX4 refuses.
#[allow(deprecated)]
pub fn ardupilot_takes(command: MavCmd) -> bool {
    use MavCmd::*;
    px4_mission_frame(command)
        || ardupilot_located(command)
        || matches!(
            command,
            MAV_CMD_CONDITION_YAW | MAV_CMD_DO_SET_SERVO | MAV_CMD_DO_SET_RELAY
        )
}

/// PX4's `mission_item_s`, the fields the commands the mock accepts use.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Px4Item {
    nav_cmd: MavCmd,
    /// MAV_FRAME_MISSION for commands without a position; otherwise the frame received.
    mission_frame: bool,
    lat: f64,
    lon: f64,
    altitude: f32,
    altitude_is_relative: bool,
    time_inside: f32,
    acceptance_radius: f32,
    /// Radians, wrapped to [0, 2pi).
    yaw: f32,
    loiter_radius: f32,
    force_heading: bool,
    loiter_exit_xtrack: bool,
    land_precision: f32,
    /// params[0..7] of a MAV_FRAME_MISSION item (x and y as doubles).
    params: [f64; 7],
    autocontinue: u8,
}

fn wrap_2pi(rad: f32) -> f32 {
    let two_pi = std::f32::consts::TAU;
    if rad.is_nan() {
        return rad;
    }
    rad.rem_euclid(two_pi)
}

#[allow(deprecated)]
fn px4_parse(item: &MISSION_ITEM_INT_DATA) -> Px4Item {
    use MavCmd::*;
    use MavFrame::*;
    let mut p = Px4Item {
        nav_cmd: item.command,
        mission_frame: item.frame == MAV_FRAME_MISSION,
        lat: f64::from(item.x) * 1e-7,
        lon: f64::from(item.y) * 1e-7,
        altitude: item.z,
        altitude_is_relative: matches!(
            item.frame,
            MAV_FRAME_GLOBAL_RELATIVE_ALT | MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        ),
        time_inside: 0.0,
        acceptance_radius: 0.0,
        yaw: 0.0,
        loiter_radius: 0.0,
        force_heading: false,
        loiter_exit_xtrack: false,
        land_precision: 0.0,
        params: [0.0; 7],
        autocontinue: item.autocontinue,
    };
    if p.mission_frame {
        p.params = [
            f64::from(item.param1),
            f64::from(item.param2),
            f64::from(item.param3),
            f64::from(item.param4),
            f64::from(item.x),
            f64::from(item.y),
            f64::from(item.z),
        ];
        return p;
    }
    let yaw = wrap_2pi(item.param4.to_radians());
    match item.command {
        MAV_CMD_NAV_WAYPOINT => {
            p.time_inside = item.param1;
            p.acceptance_radius = item.param2;
            p.yaw = yaw;
        }
        MAV_CMD_NAV_LOITER_UNLIM => {
            p.loiter_radius = item.param3;
            p.yaw = yaw;
        }
        MAV_CMD_NAV_LOITER_TIME => {
            p.time_inside = item.param1;
            p.force_heading = item.param2 > 0.0;
            p.loiter_radius = item.param3;
            p.loiter_exit_xtrack = item.param4 > 0.0;
        }
        MAV_CMD_NAV_LAND => {
            p.yaw = yaw;
            p.land_precision = item.param2;
        }
        MAV_CMD_NAV_TAKEOFF => p.yaw = yaw,
        // The ROI mode and the altitude go to params[0] and params[6]; neither is answered.
        MAV_CMD_DO_SET_ROI => {
            p.params[0] = f64::from(item.param1.trunc());
            p.params[6] = f64::from(item.z);
        }
        MAV_CMD_DO_SET_ROI_LOCATION => p.params[6] = f64::from(item.z),
        _ => {}
    }
    p
}

#[allow(deprecated)]
fn px4_format(p: &Px4Item, seq: u16) -> MISSION_ITEM_INT_DATA {
    use MavCmd::*;
    let mut out = MISSION_ITEM_INT_DATA {
        seq,
        command: p.nav_cmd,
        autocontinue: p.autocontinue,
        ..Default::default()
    };
    if p.mission_frame {
        out.frame = MavFrame::MAV_FRAME_MISSION;
        out.param1 = p.params[0] as f32;
        out.param2 = p.params[1] as f32;
        out.param3 = p.params[2] as f32;
        out.param4 = p.params[3] as f32;
        out.x = p.params[4].round() as i32;
        out.y = p.params[5].round() as i32;
        out.z = p.params[6] as f32;
        return out;
    }
    out.x = (p.lat * 1e7).round() as i32;
    out.y = (p.lon * 1e7).round() as i32;
    out.z = p.altitude;
    out.frame = if p.altitude_is_relative {
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    } else {
        MavFrame::MAV_FRAME_GLOBAL_INT
    };
    let yaw_deg = p.yaw.to_degrees();
    let flag = |b: bool| if b { 1.0 } else { 0.0 };
    match p.nav_cmd {
        MAV_CMD_NAV_WAYPOINT => {
            out.param1 = p.time_inside;
            out.param2 = p.acceptance_radius;
            out.param4 = yaw_deg;
        }
        MAV_CMD_NAV_LOITER_UNLIM => {
            out.param3 = p.loiter_radius;
            out.param4 = yaw_deg;
        }
        MAV_CMD_NAV_LOITER_TIME => {
            out.param1 = p.time_inside;
            out.param2 = flag(p.force_heading);
            out.param3 = p.loiter_radius;
            out.param4 = flag(p.loiter_exit_xtrack);
        }
        MAV_CMD_NAV_LAND => {
            out.param2 = p.land_precision;
            out.param4 = yaw_deg;
        }
        MAV_CMD_NAV_TAKEOFF => out.param4 = yaw_deg,
        _ => {}
    }
    out
}

/// ArduPilot's `Mission_Command`, the fields the commands the mock accepts use.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ApCommand {
    id: MavCmd,
    p1: u16,
    has_location: bool,
    lat: i32,
    lng: i32,
    alt_cm: i32,
    relative_alt: bool,
    loiter_ccw: bool,
    loiter_xtrack: bool,
    content: Content,
}

/// The `Mission_Command::content` union of ArduPilot (AP_Mission.h), the members the mock's
/// commands use, with their C field types.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Content {
    None,
    Speed {
        speed_type: u8,
        target_ms: f32,
        throttle_pct: f32,
    },
    Jump {
        target: u16,
        num_times: i16,
    },
    NavDelay {
        seconds: f32,
        hour_utc: i8,
        min_utc: i8,
        sec_utc: i8,
    },
    Yaw {
        angle_deg: f32,
        turn_rate_dps: f32,
        direction: i8,
        relative_angle: u8,
    },
    Relay {
        num: u8,
        state: u8,
    },
    Servo {
        channel: u8,
        pwm: u16,
    },
    Gripper {
        num: u8,
        action: u8,
    },
    Winch {
        num: u8,
        action: u8,
        release_length: f32,
        release_rate: f32,
    },
    DigicamControl {
        session: u8,
        zoom_pos: u8,
        zoom_step: i8,
        focus_lock: u8,
        shooting_cmd: u8,
        cmd_id: u8,
    },
    /// pitch, roll, yaw; and the z ArduCopter SITL answered as sent (the mount mode).
    MountControl {
        pitch: f32,
        roll: f32,
        yaw: f32,
        mode: f32,
    },
    CamTriggDist {
        meters: f32,
        trigger: u8,
    },
    GimbalPitchyaw {
        pitch_angle_deg: i8,
        yaw_angle_deg: i16,
        pitch_rate_degs: i8,
        yaw_rate_degs: i8,
        flags: u8,
        gimbal_id: u8,
    },
    ImageStartCapture {
        instance: u8,
        interval_s: f32,
        total_num_images: u16,
        start_seq_number: u16,
    },
    VideoCapture {
        video_stream_id: u8,
    },
}

/// C's float to unsigned 16-bit conversion (truncation), clamped where C is undefined.
fn to_u16(v: f32) -> u16 {
    if v.is_nan() || v <= 0.0 {
        0
    } else {
        v.min(65_535.0) as u16
    }
}

/// C's float to 8-bit conversions (truncation toward zero), clamped where C is undefined.
fn to_u8(v: f32) -> u8 {
    if v.is_nan() {
        0
    } else {
        v.clamp(0.0, 255.0) as u8
    }
}

fn to_i8(v: f32) -> i8 {
    if v.is_nan() {
        0
    } else {
        v.clamp(-128.0, 127.0) as i8
    }
}

fn to_i16(v: f32) -> i16 {
    if v.is_nan() {
        0
    } else {
        v.clamp(-32_768.0, 32_767.0) as i16
    }
}

#[allow(deprecated)]
fn ap_parse(item: &MISSION_ITEM_INT_DATA) -> ApCommand {
    use MavCmd::*;
    use MavFrame::*;
    let has_location = ardupilot_located(item.command);
    let mut c = ApCommand {
        id: item.command,
        p1: 0,
        has_location,
        lat: 0,
        lng: 0,
        alt_cm: 0,
        relative_alt: false,
        loiter_ccw: false,
        loiter_xtrack: false,
        content: Content::None,
    };
    let (p1, p2, p3, p4) = (item.param1, item.param2, item.param3, item.param4);
    match item.command {
        // Copter build: the hold time only.
        MAV_CMD_NAV_WAYPOINT | MAV_CMD_NAV_TAKEOFF | MAV_CMD_NAV_SPLINE_WAYPOINT => {
            c.p1 = to_u16(p1)
        }
        MAV_CMD_NAV_LAND => {
            c.p1 = to_u16(p1);
            if !p4.is_nan() {
                c.loiter_ccw = p4 < 0.0;
            }
        }
        MAV_CMD_NAV_LOITER_TIME => {
            c.p1 = to_u16(p1);
            c.loiter_ccw = p3 < 0.0;
            c.loiter_xtrack = p4 > 0.0;
        }
        MAV_CMD_NAV_LOITER_UNLIM => {
            c.p1 = to_u16(p3.abs());
            c.loiter_ccw = p3 < 0.0;
        }
        MAV_CMD_DO_CHANGE_SPEED => {
            c.content = Content::Speed {
                speed_type: to_u8(p1),
                target_ms: p2,
                throttle_pct: p3,
            }
        }
        MAV_CMD_DO_JUMP => {
            c.content = Content::Jump {
                target: to_u16(p1),
                num_times: to_i16(p2),
            }
        }
        MAV_CMD_NAV_DELAY => {
            c.content = Content::NavDelay {
                seconds: p1,
                hour_utc: to_i8(p2),
                min_utc: to_i8(p3),
                sec_utc: to_i8(p4),
            }
        }
        MAV_CMD_CONDITION_YAW => {
            c.content = Content::Yaw {
                angle_deg: p1,
                turn_rate_dps: p2,
                direction: to_i8(p3),
                relative_angle: to_u8(p4),
            }
        }
        MAV_CMD_DO_SET_RELAY => {
            c.content = Content::Relay {
                num: to_u8(p1),
                state: to_u8(p2),
            }
        }
        MAV_CMD_DO_SET_SERVO => {
            c.content = Content::Servo {
                channel: to_u8(p1),
                pwm: to_u16(p2),
            }
        }
        MAV_CMD_DO_GRIPPER => {
            c.content = Content::Gripper {
                num: to_u8(p1),
                action: to_u8(p2),
            }
        }
        MAV_CMD_DO_WINCH => {
            c.content = Content::Winch {
                num: to_u8(p1),
                action: to_u8(p2),
                release_length: p3,
                release_rate: p4,
            }
        }
        MAV_CMD_DO_DIGICAM_CONTROL => {
            c.content = Content::DigicamControl {
                session: to_u8(p1),
                zoom_pos: to_u8(p2),
                zoom_step: to_i8(p3),
                focus_lock: to_u8(p4),
                shooting_cmd: to_u8(item.x as f32),
                cmd_id: to_u8(item.y as f32),
            }
        }
        MAV_CMD_DO_MOUNT_CONTROL => {
            c.content = Content::MountControl {
                pitch: p1,
                roll: p2,
                yaw: p3,
                mode: item.z,
            }
        }
        MAV_CMD_DO_SET_CAM_TRIGG_DIST => {
            c.content = Content::CamTriggDist {
                meters: p1,
                trigger: to_u8(p3),
            }
        }
        MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW => {
            c.content = Content::GimbalPitchyaw {
                pitch_angle_deg: to_i8(p1),
                yaw_angle_deg: to_i16(p2),
                pitch_rate_degs: to_i8(p3),
                yaw_rate_degs: to_i8(p4),
                flags: to_u8(item.x as f32),
                gimbal_id: to_u8(item.z),
            }
        }
        MAV_CMD_IMAGE_START_CAPTURE => {
            c.content = Content::ImageStartCapture {
                instance: to_u8(p1),
                interval_s: p2,
                total_num_images: to_u16(p3),
                start_seq_number: to_u16(p4),
            }
        }
        MAV_CMD_VIDEO_START_CAPTURE | MAV_CMD_VIDEO_STOP_CAPTURE => {
            c.content = Content::VideoCapture {
                video_stream_id: to_u8(p1),
            }
        }
        // cmd.p1: the camera instance, the gimbal device, the ROI mode.
        MAV_CMD_IMAGE_STOP_CAPTURE
        | MAV_CMD_DO_SET_ROI_NONE
        | MAV_CMD_DO_SET_ROI_LOCATION
        | MAV_CMD_DO_SET_ROI => c.p1 = to_u16(p1),
        _ => {}
    }
    if has_location {
        c.lat = item.x;
        c.lng = item.y;
        // `cmd.content.location.alt = packet.z * 100.0f;` (float to integer: truncation).
        c.alt_cm = (item.z * 100.0) as i32;
        // MAV_FRAME_MISSION and the global frames: above sea level.
        c.relative_alt = matches!(
            item.frame,
            MAV_FRAME_GLOBAL_RELATIVE_ALT | MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        );
    }
    c
}

#[allow(deprecated)]
fn ap_format(c: &ApCommand, seq: u16) -> MISSION_ITEM_INT_DATA {
    use MavCmd::*;
    let mut out = MISSION_ITEM_INT_DATA {
        seq,
        command: c.id,
        frame: MavFrame::MAV_FRAME_GLOBAL,
        autocontinue: 1,
        ..Default::default()
    };
    let ccw = |ccw: bool| if ccw { -1.0 } else { 1.0 };
    match c.id {
        MAV_CMD_NAV_WAYPOINT
        | MAV_CMD_NAV_TAKEOFF
        | MAV_CMD_NAV_SPLINE_WAYPOINT
        | MAV_CMD_IMAGE_STOP_CAPTURE
        | MAV_CMD_DO_SET_ROI_NONE
        | MAV_CMD_DO_SET_ROI_LOCATION
        | MAV_CMD_DO_SET_ROI => out.param1 = f32::from(c.p1),
        MAV_CMD_NAV_LAND => {
            out.param1 = f32::from(c.p1);
            out.param4 = ccw(c.loiter_ccw);
        }
        MAV_CMD_NAV_LOITER_TIME => {
            out.param1 = f32::from(c.p1);
            out.param3 = ccw(c.loiter_ccw);
            out.param4 = if c.loiter_xtrack { 1.0 } else { 0.0 };
        }
        MAV_CMD_NAV_LOITER_UNLIM => out.param3 = f32::from(c.p1) * ccw(c.loiter_ccw),
        _ => {}
    }
    let mut params = |p: [f32; 4]| {
        (out.param1, out.param2, out.param3, out.param4) = (p[0], p[1], p[2], p[3]);
    };
    match c.content {
        Content::None => {}
        Content::Speed {
            speed_type,
            target_ms,
            throttle_pct,
        } => params([f32::from(speed_type), target_ms, throttle_pct, 0.0]),
        Content::Jump { target, num_times } => {
            params([f32::from(target), f32::from(num_times), 0.0, 0.0])
        }
        Content::NavDelay {
            seconds,
            hour_utc,
            min_utc,
            sec_utc,
        } => params([
            seconds,
            f32::from(hour_utc),
            f32::from(min_utc),
            f32::from(sec_utc),
        ]),
        Content::Yaw {
            angle_deg,
            turn_rate_dps,
            direction,
            relative_angle,
        } => params([
            angle_deg,
            turn_rate_dps,
            f32::from(direction),
            f32::from(relative_angle),
        ]),
        Content::Relay { num, state } => params([f32::from(num), f32::from(state), 0.0, 0.0]),
        Content::Servo { channel, pwm } => params([f32::from(channel), f32::from(pwm), 0.0, 0.0]),
        Content::Gripper { num, action } => params([f32::from(num), f32::from(action), 0.0, 0.0]),
        Content::Winch {
            num,
            action,
            release_length,
            release_rate,
        } => params([
            f32::from(num),
            f32::from(action),
            release_length,
            release_rate,
        ]),
        Content::DigicamControl {
            session,
            zoom_pos,
            zoom_step,
            focus_lock,
            shooting_cmd,
            cmd_id,
        } => {
            params([
                f32::from(session),
                f32::from(zoom_pos),
                f32::from(zoom_step),
                f32::from(focus_lock),
            ]);
            (out.x, out.y) = (i32::from(shooting_cmd), i32::from(cmd_id));
        }
        Content::MountControl {
            pitch,
            roll,
            yaw,
            mode,
        } => {
            params([pitch, roll, yaw, 0.0]);
            out.z = mode;
        }
        Content::CamTriggDist { meters, trigger } => params([meters, 0.0, f32::from(trigger), 0.0]),
        Content::GimbalPitchyaw {
            pitch_angle_deg,
            yaw_angle_deg,
            pitch_rate_degs,
            yaw_rate_degs,
            flags,
            gimbal_id,
        } => {
            params([
                f32::from(pitch_angle_deg),
                f32::from(yaw_angle_deg),
                f32::from(pitch_rate_degs),
                f32::from(yaw_rate_degs),
            ]);
            (out.x, out.z) = (i32::from(flags), f32::from(gimbal_id));
        }
        Content::ImageStartCapture {
            instance,
            interval_s,
            total_num_images,
            start_seq_number,
        } => params([
            f32::from(instance),
            interval_s,
            f32::from(total_num_images),
            f32::from(start_seq_number),
        ]),
        Content::VideoCapture { video_stream_id } => {
            params([f32::from(video_stream_id), 0.0, 0.0, 0.0])
        }
    }
    if c.has_location {
        out.x = c.lat;
        out.y = c.lng;
        out.z = c.alt_cm as f32 * 0.01;
        if c.relative_alt {
            out.frame = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT;
        }
    }
    out
}

/// What `flavour` answers a read-back of `item` (received as item `item.seq`) with.
pub fn stored(
    flavour: Flavour,
    item: &MISSION_ITEM_INT_DATA,
    home: &Home,
) -> MISSION_ITEM_INT_DATA {
    match flavour {
        Flavour::Px4 => px4_format(&px4_parse(item), item.seq),
        Flavour::ArduPilot if item.seq == 0 => MISSION_ITEM_INT_DATA {
            seq: 0,
            command: MavCmd::MAV_CMD_NAV_WAYPOINT,
            frame: MavFrame::MAV_FRAME_GLOBAL,
            x: home.lat_e7,
            y: home.lon_e7,
            z: home.alt_m,
            autocontinue: 1,
            ..Default::default()
        },
        Flavour::ArduPilot => ap_format(&ap_parse(item), item.seq),
        Flavour::Generic => MISSION_ITEM_INT_DATA {
            target_system: 0,
            target_component: 0,
            ..item.clone()
        },
    }
}

/// Whether `flavour` takes `item` into its fence or rally list (`rally`), and if not the
/// MISSION_ACK it refuses it with:
/// - PX4 (`parse_mavlink_mission_item`): a global frame, and a fence command in the fence, the
///   rally point in the rally list (a polygon of fewer than 3 vertices refused);
/// - ArduPilot: a fence item in a global frame (`convert_MISSION_ITEM_INT_to_AC_PolyFenceItem`),
///   a rally point only in MAV_FRAME_GLOBAL_RELATIVE_ALT(_INT) and with an altitude that fits
///   its int16 (`convert_MISSION_ITEM_INT_to_RallyLocation`).
#[allow(deprecated)]
pub fn fence_rally_supported(
    flavour: Flavour,
    rally: bool,
    item: &MISSION_ITEM_INT_DATA,
) -> Result<(), MavMissionResult> {
    use MavCmd::*;
    use MavFrame::*;
    use MavMissionResult::*;
    let global = matches!(
        item.frame,
        MAV_FRAME_GLOBAL
            | MAV_FRAME_GLOBAL_RELATIVE_ALT
            | MAV_FRAME_GLOBAL_INT
            | MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    );
    let fence_command = matches!(
        item.command,
        MAV_CMD_NAV_FENCE_RETURN_POINT
            | MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
            | MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
            | MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
            | MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
    );
    let vertex = matches!(
        item.command,
        MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION | MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
    );
    let takes = if rally {
        item.command == MAV_CMD_NAV_RALLY_POINT
    } else {
        fence_command
    };
    if !takes {
        return Err(MAV_MISSION_UNSUPPORTED);
    }
    match flavour {
        Flavour::ArduPilot if rally => {
            if !matches!(
                item.frame,
                MAV_FRAME_GLOBAL_RELATIVE_ALT | MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
            ) {
                return Err(MAV_MISSION_UNSUPPORTED_FRAME);
            }
            if !(item.z >= f32::from(i16::MIN) && item.z <= f32::from(i16::MAX)) {
                return Err(MAV_MISSION_INVALID_PARAM7);
            }
        }
        _ if !global => return Err(MAV_MISSION_UNSUPPORTED_FRAME),
        // PX4: "Fence: too few vertices".
        Flavour::Px4 if vertex && (item.param1.is_nan() || item.param1 < 3.0) => {
            return Err(MAV_MISSION_ERROR)
        }
        _ => {}
    }
    Ok(())
}

/// What `flavour` answers a read-back of fence or rally (`rally`) item `item` with:
/// - PX4 (`send_mission_item`, `format_mavlink_mission_item`): a fence point keeps its command,
///   position, altitude, vertex count or radius, nothing else (answered in MAV_FRAME_GLOBAL_INT,
///   autocontinue 0); a rally point is kept as a parsed mission item (its frame's _INT form);
/// - ArduPilot (`MissionItemProtocol_Fence::get_item_as_mission_item`,
///   `MissionItemProtocol_Rally::get_item`): a fence point its command, position and vertex
///   count (uint8) or radius, z 0, in a zeroed item's frame (MAV_FRAME_GLOBAL); a rally point
///   its position and altitude in whole metres (int16, truncated as C converts), in
///   MAV_FRAME_GLOBAL_RELATIVE_ALT;
/// - Generic (MAVSDK): as received.
#[allow(deprecated)]
pub fn stored_fence_rally(
    flavour: Flavour,
    rally: bool,
    item: &MISSION_ITEM_INT_DATA,
) -> MISSION_ITEM_INT_DATA {
    use MavCmd::*;
    let base = MISSION_ITEM_INT_DATA {
        seq: item.seq,
        command: item.command,
        x: item.x,
        y: item.y,
        ..Default::default()
    };
    let vertex = matches!(
        item.command,
        MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION | MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
    );
    let circle = matches!(
        item.command,
        MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION | MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
    );
    match flavour {
        Flavour::Px4 if rally => {
            let relative = matches!(
                item.frame,
                MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
                    | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
            );
            MISSION_ITEM_INT_DATA {
                frame: if relative {
                    MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
                } else {
                    MavFrame::MAV_FRAME_GLOBAL_INT
                },
                z: item.z,
                autocontinue: item.autocontinue,
                ..base
            }
        }
        Flavour::Px4 => MISSION_ITEM_INT_DATA {
            frame: MavFrame::MAV_FRAME_GLOBAL_INT,
            z: item.z,
            param1: if vertex {
                f32::from(to_u16(item.param1))
            } else if circle {
                item.param1
            } else {
                0.0
            },
            ..base
        },
        Flavour::ArduPilot if rally => MISSION_ITEM_INT_DATA {
            frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
            z: f32::from(to_i16(item.z)),
            ..base
        },
        Flavour::ArduPilot => MISSION_ITEM_INT_DATA {
            frame: MavFrame::MAV_FRAME_GLOBAL,
            param1: if vertex {
                f32::from(to_u8(item.param1))
            } else if circle {
                item.param1
            } else {
                0.0
            },
            ..base
        },
        Flavour::Generic => MISSION_ITEM_INT_DATA {
            target_system: 0,
            target_component: 0,
            ..item.clone()
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::testing::mission;

    #[test]
    fn px4_answers_relative_items_in_the_int_frame_and_drops_the_pass_radius() {
        let sent = &mission(Flavour::Px4, 3)[1];
        let mut with_pass = sent.clone();
        with_pass.param3 = 3.0;
        with_pass.param4 = -90.0;
        let read = stored(Flavour::Px4, &with_pass, &Home::default());
        #[allow(deprecated)]
        let frame = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT;
        assert_eq!(read.frame, frame);
        assert_eq!((read.x, read.y, read.z), (sent.x, sent.y, sent.z));
        assert_eq!((read.param1, read.param2, read.param3), (5.0, 2.0, 0.0));
        assert!((read.param4 - 270.0).abs() < 1e-3, "{}", read.param4);
    }

    #[test]
    fn ardupilot_answers_its_home_at_item_0_and_zeroes_what_it_does_not_store() {
        let items = mission(Flavour::ArduPilot, 4);
        let home = Home::default();
        let read: Vec<_> = items
            .iter()
            .map(|it| stored(Flavour::ArduPilot, it, &home))
            .collect();
        assert_eq!(read[0].z, 16.1);
        // Takeoff: NaN yaw answered 0.
        assert_eq!(read[1].param4, 0.0);
        // Waypoint: hold kept, acceptance radius and NaN yaw answered 0.
        assert_eq!(
            (read[2].param1, read[2].param2, read[2].param4),
            (5.0, 0.0, 0.0)
        );
        // RTL sent in MAV_FRAME_MISSION answered in MAV_FRAME_GLOBAL.
        assert_eq!(read[3].frame, MavFrame::MAV_FRAME_GLOBAL);
        let mut odd = items[2].clone();
        (odd.z, odd.param1) = (54.123, 2.5);
        let read = stored(Flavour::ArduPilot, &odd, &home);
        assert!((read.z - 54.12).abs() < 1e-4, "{}", read.z);
        assert_eq!(read.param1, 2.0);
    }
}
