//! What the mock's flavours store of a mission item and answer a read-back with, modelled on the
//! autopilots' own storage (not on `link::readback`, which checks it): PX4 parses an item into a
//! `mission_item_s` and formats it back (`mavlink_mission.cpp`, `parse_mavlink_mission_item`,
//! `format_mavlink_mission_item`); ArduPilot packs it into a `Mission_Command` and unpacks it
//! (`AP_Mission.cpp`, `mavlink_int_to_mission_cmd`, `mission_cmd_to_mavlink_int`), item 0 being
//! its home (`read_cmd_from_storage`); MAVSDK keeps the items as they came.

use crate::link::mav::{MavCmd, MavFrame, MISSION_ITEM_INT_DATA};
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
    speed_type: u8,
    target_ms: f32,
    throttle_pct: f32,
    jump_target: u16,
    jump_times: i16,
    delay_s: f32,
}

/// C's float to unsigned 16-bit conversion (truncation), clamped where C is undefined.
fn to_u16(v: f32) -> u16 {
    if v.is_nan() || v <= 0.0 {
        0
    } else {
        v.min(65_535.0) as u16
    }
}

#[allow(deprecated)]
fn ap_parse(item: &MISSION_ITEM_INT_DATA) -> ApCommand {
    use MavCmd::*;
    use MavFrame::*;
    let has_location = navigation(item.command);
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
        speed_type: 0,
        target_ms: 0.0,
        throttle_pct: 0.0,
        jump_target: 0,
        jump_times: 0,
        delay_s: 0.0,
    };
    match item.command {
        // Copter build: the hold time only.
        MAV_CMD_NAV_WAYPOINT | MAV_CMD_NAV_TAKEOFF => c.p1 = to_u16(item.param1),
        MAV_CMD_NAV_LAND => {
            c.p1 = to_u16(item.param1);
            if !item.param4.is_nan() {
                c.loiter_ccw = item.param4 < 0.0;
            }
        }
        MAV_CMD_NAV_LOITER_TIME => {
            c.p1 = to_u16(item.param1);
            c.loiter_ccw = item.param3 < 0.0;
            c.loiter_xtrack = item.param4 > 0.0;
        }
        MAV_CMD_NAV_LOITER_UNLIM => {
            c.p1 = to_u16(item.param3.abs());
            c.loiter_ccw = item.param3 < 0.0;
        }
        MAV_CMD_DO_CHANGE_SPEED => {
            c.speed_type = item.param1.clamp(0.0, 255.0) as u8;
            c.target_ms = item.param2;
            c.throttle_pct = item.param3;
        }
        MAV_CMD_DO_JUMP => {
            c.jump_target = to_u16(item.param1);
            c.jump_times = item.param2.clamp(-32_768.0, 32_767.0) as i16;
        }
        MAV_CMD_NAV_DELAY => c.delay_s = item.param1,
        _ => {}
    }
    if has_location {
        c.lat = item.x;
        c.lng = item.y;
        // `cmd.content.location.alt = packet.z * 100.0f;` (float to integer: truncation).
        c.alt_cm = (item.z * 100.0) as i32;
        c.relative_alt = matches!(
            item.frame,
            MAV_FRAME_GLOBAL_RELATIVE_ALT | MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        );
    }
    c
}

fn ap_format(c: &ApCommand, seq: u16) -> MISSION_ITEM_INT_DATA {
    use MavCmd::*;
    let mut out = MISSION_ITEM_INT_DATA {
        seq,
        command: c.id,
        frame: MavFrame::MAV_FRAME_GLOBAL,
        autocontinue: 1,
        ..Default::default()
    };
    match c.id {
        MAV_CMD_NAV_WAYPOINT | MAV_CMD_NAV_TAKEOFF => out.param1 = f32::from(c.p1),
        MAV_CMD_NAV_LAND => {
            out.param1 = f32::from(c.p1);
            out.param4 = if c.loiter_ccw { -1.0 } else { 1.0 };
        }
        MAV_CMD_NAV_LOITER_TIME => {
            out.param1 = f32::from(c.p1);
            out.param3 = if c.loiter_ccw { -1.0 } else { 1.0 };
            out.param4 = if c.loiter_xtrack { 1.0 } else { 0.0 };
        }
        MAV_CMD_NAV_LOITER_UNLIM => {
            out.param3 = f32::from(c.p1) * if c.loiter_ccw { -1.0 } else { 1.0 };
        }
        MAV_CMD_DO_CHANGE_SPEED => {
            out.param1 = f32::from(c.speed_type);
            out.param2 = c.target_ms;
            out.param3 = c.throttle_pct;
        }
        MAV_CMD_DO_JUMP => {
            out.param1 = f32::from(c.jump_target);
            out.param2 = f32::from(c.jump_times);
        }
        MAV_CMD_NAV_DELAY => out.param1 = c.delay_s,
        _ => {}
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
