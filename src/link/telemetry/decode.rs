//! Decoding: the one place MAVLink units become SI (cA, mV, degE7, mm, cm/s, custom modes),
//! and the filter that listens to the first autopilot only.
//!
//! Unit rules (MAVLink common.xml; PX4 `BATTERY_STATUS.hpp` for how PX4 fills them):
//! - BATTERY_STATUS `voltages[10]` mV with UINT16_MAX = no cell, `voltages_ext[4]` mV with 0 = no
//!   cell: the pack voltage is the sum of the cells present. This also covers cells unknown (pack
//!   in `voltages[0]`, the rest UINT16_MAX) and packs above 65534 mV (`voltages[0]` = 65534, the
//!   rest in `voltages[1]`). `current_battery` cA with -1 unknown; `current_consumed` mAh, -1
//!   unknown; `energy_consumed` hJ, -1 unknown; `battery_remaining` %, -1 unknown.
//! - PX4 SITL's battery simulator has no current sensor: it reports -100 cA (-1 A) with a charge
//!   consumed of zero or below. That is flagged `fake_current`, never integrated.
//! - SYS_STATUS `voltage_battery` mV (UINT16_MAX unknown), `current_battery` cA (-1 unknown).
//! - GLOBAL_POSITION_INT degE7, mm, cm/s (north, east, down); lat = lon = 0 is no fix.
//! - HOME_POSITION `altitude` mm AMSL; lat = lon = 0 is no home yet.
//! - CAMERA_FEEDBACK (ardupilotmega.xml) `lat`/`lng` degE7, `alt_msl`/`alt_rel` m, `time_usec` us
//!   (ArduPilot `AP_Camera_Backend::send_camera_feedback`), `img_idx` counting photos; a
//!   feedback flagged VIDEO is no photo. CAMERA_TRIGGER `time_usec` us and `seq` only.
//!   CAMERA_IMAGE_CAPTURED `lat`/`lon` degE7, `alt`/`relative_alt` mm, `time_boot_ms`,
//!   `image_index`, `capture_result` 1 captured (common.xml). A MAVLink camera is a component of
//!   its own, so photos are heard from every component of the autopilot's system.
//! - FENCE_STATUS `breach_status` 1 outside the fence, `breach_count` since boot, `breach_type`
//!   (FENCE_BREACH), `breach_time` ms since boot of the last breach (0: none). ArduPilot sends it
//!   while a fence is enabled; PX4 was not found to send it (its breaches come as STATUSTEXT).
//! - SMART_BATTERY_INFO (common.xml) `serial_number` char[16] and `device_name` char[50], ASCII,
//!   NUL-terminated, all NUL: not provided. The pack's name is the serial number, else the
//!   device name ([`pack_named`]); text that is not printable ASCII is no name.
//! - HEARTBEAT of the autopilot only (not a GCS, camera or companion: `autopilot` INVALID or a
//!   ground-station type); armed = `MAV_MODE_FLAG_SAFETY_ARMED`; the mode from `custom_mode`: PX4
//!   main mode in byte 2, sub mode in byte 3; ArduCopter's mode numbers.

use mavlink::MavHeader;

use crate::flightlog::telemetry::{
    Battery, BatterySource, BreachType, FenceStatus, FlightMode, LandedState, MissionState, Photo,
    PhotoMessage, PhotoPosition, Position, Reading,
};
use crate::link::mav::{
    self, CameraFeedbackFlags, MavAutopilot, MavLandedState, MavMessage, MavModeFlag, MavType,
    MissionState as MavMissionState,
};

/// The name a pack gives itself in SMART_BATTERY_INFO: its serial number, else its device
/// name; None when it gives neither (all NUL) or either is not printable ASCII. (The message
/// is marked superseded by BATTERY_INFO, see `link::pack`.)
#[allow(deprecated)]
pub fn pack_named(info: &mav::SMART_BATTERY_INFO_DATA) -> Option<String> {
    fn text(bytes: &[u8]) -> Option<String> {
        let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
        let used = &bytes[..end];
        if !used.iter().all(|b| (0x20..0x7f).contains(b)) {
            return None;
        }
        let name = std::str::from_utf8(used).ok()?.trim();
        (!name.is_empty()).then(|| name.to_string())
    }
    text(&info.serial_number[..]).or_else(|| text(&info.device_name[..]))
}

/// What one message gives the flight log: a reading, and the vehicle's boot time if the
/// message carries one (a clock anchor).
#[derive(Debug, Clone, PartialEq)]
pub struct Decoded {
    pub time_boot_ms: Option<u32>,
    pub reading: Option<Reading>,
}

impl Decoded {
    const NOTHING: Decoded = Decoded {
        time_boot_ms: None,
        reading: None,
    };

    fn reading(reading: Reading) -> Decoded {
        Decoded {
            time_boot_ms: None,
            reading: Some(reading),
        }
    }

    fn anchor(time_boot_ms: u32) -> Decoded {
        Decoded {
            time_boot_ms: Some(time_boot_ms),
            reading: None,
        }
    }
}

/// Whether a HEARTBEAT comes from an autopilot (not a ground station, camera, gimbal or
/// companion computer).
pub fn is_autopilot(hb: &mav::HEARTBEAT_DATA) -> bool {
    hb.autopilot != MavAutopilot::MAV_AUTOPILOT_INVALID
        && !matches!(
            hb.mavtype,
            MavType::MAV_TYPE_GCS
                | MavType::MAV_TYPE_ONBOARD_CONTROLLER
                | MavType::MAV_TYPE_GIMBAL
                | MavType::MAV_TYPE_CAMERA
                | MavType::MAV_TYPE_ADSB
                | MavType::MAV_TYPE_BATTERY
                | MavType::MAV_TYPE_SERVO
                | MavType::MAV_TYPE_ODID
                | MavType::MAV_TYPE_LOG
                | MavType::MAV_TYPE_OSD
                | MavType::MAV_TYPE_ANTENNA_TRACKER
        )
}

/// MAV_MODE_FLAG_SAFETY_ARMED.
fn armed(hb: &mav::HEARTBEAT_DATA) -> bool {
    hb.base_mode
        .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)
}

/// PX4's custom mode: main mode in byte 2, sub mode in byte 3 (PX4 `px4_custom_mode.h`).
fn px4_mode(custom_mode: u32) -> FlightMode {
    let main = (custom_mode >> 16) & 0xFF;
    let sub = (custom_mode >> 24) & 0xFF;
    match (main, sub) {
        (1 | 2 | 3 | 5 | 7 | 8, _) => FlightMode::Manual,
        (4, 4) => FlightMode::Mission,
        (4, 2 | 10) => FlightMode::Takeoff,
        (4, 3) => FlightMode::Hold,
        (4, 5) => FlightMode::Rtl,
        (4, 6 | 9) => FlightMode::Land,
        (4, 1) => FlightMode::Other("auto_ready".into()),
        (4, 8) => FlightMode::Other("follow_target".into()),
        (6, _) => FlightMode::Other("offboard".into()),
        (10, _) => FlightMode::Other("termination".into()),
        _ => FlightMode::Other(format!("px4 {main}.{sub}")),
    }
}

fn is_copter(t: MavType) -> bool {
    matches!(
        t,
        MavType::MAV_TYPE_QUADROTOR
            | MavType::MAV_TYPE_COAXIAL
            | MavType::MAV_TYPE_HELICOPTER
            | MavType::MAV_TYPE_HEXAROTOR
            | MavType::MAV_TYPE_OCTOROTOR
            | MavType::MAV_TYPE_TRICOPTER
            | MavType::MAV_TYPE_DODECAROTOR
            | MavType::MAV_TYPE_DECAROTOR
    )
}

fn mode(hb: &mav::HEARTBEAT_DATA) -> FlightMode {
    match hb.autopilot {
        MavAutopilot::MAV_AUTOPILOT_PX4 => px4_mode(hb.custom_mode),
        MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA if is_copter(hb.mavtype) => {
            FlightMode::arducopter(u64::from(hb.custom_mode))
        }
        _ => FlightMode::Other(format!("custom {}", hb.custom_mode)),
    }
}

fn known_i32(value: i32) -> Option<f64> {
    (value != -1).then_some(f64::from(value))
}

/// Pack voltage from BATTERY_STATUS cells (see the module doc).
fn pack_voltage_v(voltages: &[u16; 10], voltages_ext: &[u16; 4]) -> Option<f64> {
    let mv: u32 = voltages
        .iter()
        .filter(|&&v| v != u16::MAX)
        .chain(voltages_ext.iter().filter(|&&v| v != 0))
        .map(|&v| u32::from(v))
        .sum();
    (mv > 0).then_some(f64::from(mv) * 1e-3)
}

fn battery_status(b: &mav::BATTERY_STATUS_DATA, component: u8) -> Battery {
    let current_ca = b.current_battery;
    Battery {
        source: BatterySource::BatteryStatus {
            id: b.id,
            component,
        },
        voltage_v: pack_voltage_v(&b.voltages, &b.voltages_ext),
        current_a: (current_ca != -1).then_some(f64::from(current_ca) * 0.01),
        consumed_mah: known_i32(b.current_consumed),
        energy_consumed_j: known_i32(b.energy_consumed).map(|hj| hj * 100.0),
        remaining_pct: (b.battery_remaining != -1).then_some(f64::from(b.battery_remaining)),
        fake_current: current_ca == -100 && b.current_consumed <= 0,
    }
}

fn sys_status(s: &mav::SYS_STATUS_DATA) -> Battery {
    Battery {
        source: BatterySource::SysStatus,
        voltage_v: (s.voltage_battery != u16::MAX && s.voltage_battery != 0)
            .then_some(f64::from(s.voltage_battery) * 1e-3),
        current_a: (s.current_battery != -1).then_some(f64::from(s.current_battery) * 0.01),
        consumed_mah: None,
        energy_consumed_j: None,
        remaining_pct: (s.battery_remaining != -1).then_some(f64::from(s.battery_remaining)),
        fake_current: s.current_battery == -100,
    }
}

fn mission_state(s: MavMissionState) -> MissionState {
    match s {
        MavMissionState::MISSION_STATE_UNKNOWN => MissionState::Unknown,
        MavMissionState::MISSION_STATE_NO_MISSION => MissionState::NoMission,
        MavMissionState::MISSION_STATE_NOT_STARTED => MissionState::NotStarted,
        MavMissionState::MISSION_STATE_ACTIVE => MissionState::Active,
        MavMissionState::MISSION_STATE_PAUSED => MissionState::Paused,
        MavMissionState::MISSION_STATE_COMPLETE => MissionState::Complete,
    }
}

fn landed_state(s: MavLandedState) -> LandedState {
    match s {
        MavLandedState::MAV_LANDED_STATE_UNDEFINED => LandedState::Undefined,
        MavLandedState::MAV_LANDED_STATE_ON_GROUND => LandedState::OnGround,
        MavLandedState::MAV_LANDED_STATE_IN_AIR => LandedState::InAir,
        MavLandedState::MAV_LANDED_STATE_TAKEOFF => LandedState::Takeoff,
        MavLandedState::MAV_LANDED_STATE_LANDING => LandedState::Landing,
    }
}

fn camera_feedback(f: &mav::CAMERA_FEEDBACK_DATA) -> Option<Photo> {
    (f.flags != CameraFeedbackFlags::CAMERA_FEEDBACK_VIDEO).then(|| Photo {
        message: PhotoMessage::CameraFeedback,
        index: i64::from(f.img_idx),
        at: Some(PhotoPosition {
            lat_deg: f64::from(f.lat) * 1e-7,
            lon_deg: f64::from(f.lng) * 1e-7,
            alt_amsl_m: f64::from(f.alt_msl),
            relative_alt_m: f64::from(f.alt_rel),
        }),
        camera_time_s: (f.time_usec > 0).then_some(f.time_usec as f64 * 1e-6),
        captured: true,
    })
}

fn image_captured(c: &mav::CAMERA_IMAGE_CAPTURED_DATA) -> Photo {
    Photo {
        message: PhotoMessage::ImageCaptured,
        index: i64::from(c.image_index),
        at: (c.lat != 0 || c.lon != 0).then(|| PhotoPosition {
            lat_deg: f64::from(c.lat) * 1e-7,
            lon_deg: f64::from(c.lon) * 1e-7,
            alt_amsl_m: f64::from(c.alt) * 1e-3,
            relative_alt_m: f64::from(c.relative_alt) * 1e-3,
        }),
        camera_time_s: (c.time_boot_ms > 0).then_some(f64::from(c.time_boot_ms) * 1e-3),
        captured: c.capture_result == mav::MavBool::MAV_BOOL_TRUE,
    }
}

fn fence_status(f: &mav::FENCE_STATUS_DATA) -> FenceStatus {
    FenceStatus {
        breached: f.breach_status != 0,
        breach_count: f.breach_count,
        breach_type: match f.breach_type {
            mav::FenceBreach::FENCE_BREACH_NONE => BreachType::None,
            mav::FenceBreach::FENCE_BREACH_MINALT => BreachType::MinAltitude,
            mav::FenceBreach::FENCE_BREACH_MAXALT => BreachType::MaxAltitude,
            mav::FenceBreach::FENCE_BREACH_BOUNDARY => BreachType::Boundary,
        },
        last_breach_boot_s: (f.breach_count > 0 && f.breach_time > 0)
            .then_some(f64::from(f.breach_time) * 1e-3),
    }
}

/// Decodes one message from the vehicle into SI units (see the module doc for every rule).
pub fn decode(header: &MavHeader, message: &MavMessage) -> Decoded {
    match message {
        MavMessage::BATTERY_STATUS(b) => {
            Decoded::reading(Reading::Battery(battery_status(b, header.component_id)))
        }
        MavMessage::SYS_STATUS(s) => Decoded::reading(Reading::Battery(sys_status(s))),
        MavMessage::GLOBAL_POSITION_INT(p) => Decoded {
            time_boot_ms: Some(p.time_boot_ms),
            reading: (p.lat != 0 || p.lon != 0).then(|| {
                Reading::Position(Position {
                    time_boot_ms: p.time_boot_ms,
                    lat_deg: f64::from(p.lat) * 1e-7,
                    lon_deg: f64::from(p.lon) * 1e-7,
                    alt_amsl_m: f64::from(p.alt) * 1e-3,
                    relative_alt_m: f64::from(p.relative_alt) * 1e-3,
                    vn_m_s: f64::from(p.vx) * 0.01,
                    ve_m_s: f64::from(p.vy) * 0.01,
                    vd_m_s: f64::from(p.vz) * 0.01,
                })
            }),
        },
        MavMessage::LOCAL_POSITION_NED(p) => Decoded::anchor(p.time_boot_ms),
        MavMessage::ATTITUDE(a) => Decoded::anchor(a.time_boot_ms),
        MavMessage::ATTITUDE_QUATERNION(a) => Decoded::anchor(a.time_boot_ms),
        MavMessage::SYSTEM_TIME(s) if s.time_boot_ms != 0 => Decoded::anchor(s.time_boot_ms),
        MavMessage::HEARTBEAT(hb) if is_autopilot(hb) => Decoded::reading(Reading::Heartbeat {
            armed: armed(hb),
            mode: mode(hb),
        }),
        MavMessage::MISSION_CURRENT(m) => Decoded::reading(Reading::MissionCurrent {
            seq: m.seq,
            total: (m.total != u16::MAX).then_some(m.total),
            state: mission_state(m.mission_state),
        }),
        MavMessage::MISSION_ITEM_REACHED(m) => {
            Decoded::reading(Reading::ItemReached { seq: m.seq })
        }
        MavMessage::EXTENDED_SYS_STATE(s) => {
            Decoded::reading(Reading::Landed(landed_state(s.landed_state)))
        }
        // Untimed: its time_usec is when home was set, not when the message was sent.
        MavMessage::HOME_POSITION(h) if h.latitude != 0 || h.longitude != 0 => {
            Decoded::reading(Reading::Home {
                lat_deg: f64::from(h.latitude) * 1e-7,
                lon_deg: f64::from(h.longitude) * 1e-7,
                alt_amsl_m: f64::from(h.altitude) * 1e-3,
                set_boot_s: (h.time_usec > 0).then_some(h.time_usec as f64 * 1e-6),
            })
        }
        MavMessage::STATUSTEXT(s) => {
            let bytes: &[u8] = &s.text[..];
            let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
            Decoded::reading(Reading::StatusText {
                severity: s.severity as u8,
                text: String::from_utf8_lossy(&bytes[..end]).into_owned(),
            })
        }
        // Untimed: their times are the image's, not when the message was sent.
        MavMessage::CAMERA_FEEDBACK(f) => match camera_feedback(f) {
            Some(photo) => Decoded::reading(Reading::Photo(photo)),
            None => Decoded::NOTHING,
        },
        MavMessage::CAMERA_TRIGGER(t) => Decoded::reading(Reading::Photo(Photo {
            message: PhotoMessage::CameraTrigger,
            index: i64::from(t.seq),
            at: None,
            camera_time_s: (t.time_usec > 0).then_some(t.time_usec as f64 * 1e-6),
            captured: true,
        })),
        MavMessage::CAMERA_IMAGE_CAPTURED(c) => Decoded::reading(Reading::Photo(image_captured(c))),
        // ArduPilot streams it (EXTENDED_STATUS, GCS_Common.cpp `send_fence_status`) while a
        // fence is enabled; untimed: its breach_time is the breach's, not the message's.
        MavMessage::FENCE_STATUS(f) => Decoded::reading(Reading::Fence(fence_status(f))),
        MavMessage::WIND_COV(_) | MavMessage::WIND(_) => {
            match crate::link::wind::wind_of(message) {
                Some(wind) => Decoded::reading(Reading::Wind(wind)),
                None => Decoded::NOTHING,
            }
        }
        _ => Decoded::NOTHING,
    }
}

/// [`decode`] behind a source filter: once an autopilot's HEARTBEAT is seen, only its system is
/// listened to, and only its component for everything but BATTERY_STATUS and the camera's
/// messages (a smart battery, a MAVLink camera may be a component of its own). Before that every
/// message counts (a log may start mid-flight).
#[derive(Debug, Clone, Default)]
pub struct TelemetryDecoder {
    autopilot: Option<(u32, u8)>,
}

impl TelemetryDecoder {
    pub fn new() -> TelemetryDecoder {
        TelemetryDecoder::default()
    }

    /// A decoder that listens to a known autopilot (system, component) from the start.
    pub fn for_autopilot(system_id: u8, component_id: u8) -> TelemetryDecoder {
        TelemetryDecoder {
            autopilot: Some((u32::from(system_id), component_id)),
        }
    }

    /// The autopilot listened to.
    pub fn autopilot(&self) -> Option<(u32, u8)> {
        self.autopilot
    }

    pub fn decode(&mut self, header: &MavHeader, message: &MavMessage) -> Decoded {
        if let MavMessage::HEARTBEAT(hb) = message {
            if self.autopilot.is_none() && is_autopilot(hb) {
                self.autopilot = Some((header.system_id, header.component_id));
            }
        }
        if let Some((system, component)) = self.autopilot {
            let own_component = matches!(
                message,
                MavMessage::BATTERY_STATUS(_)
                    | MavMessage::CAMERA_FEEDBACK(_)
                    | MavMessage::CAMERA_TRIGGER(_)
                    | MavMessage::CAMERA_IMAGE_CAPTURED(_)
            );
            if header.system_id != system || (!own_component && header.component_id != component) {
                return Decoded::NOTHING;
            }
        }
        decode(header, message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[allow(deprecated)]
    fn a_pack_is_named_by_its_serial_number_else_its_device_name() {
        let info = |serial: &str, name: &str| mav::SMART_BATTERY_INFO_DATA {
            serial_number: serial.into(),
            device_name: name.into(),
            ..Default::default()
        };
        assert_eq!(
            pack_named(&info("SN-0042", "Acme_6S")).as_deref(),
            Some("SN-0042")
        );
        assert_eq!(pack_named(&info("", "Acme_6S")).as_deref(), Some("Acme_6S"));
        assert_eq!(pack_named(&info("", "")), None);
        let mut garbled = info("", "");
        garbled.serial_number = [0xff; 16].into();
        assert_eq!(pack_named(&garbled), None);
        // A serial that fills all 16 bytes has no NUL.
        assert_eq!(
            pack_named(&info("0123456789abcdef", "")).as_deref(),
            Some("0123456789abcdef")
        );
    }
    use crate::flightlog::telemetry::{
        Battery, BatterySource, FlightMode, LandedState, MissionState, Photo, PhotoMessage,
        PhotoPosition, Reading,
    };
    use crate::link::mav::{
        self, CameraFeedbackFlags, MavAutopilot, MavLandedState, MavMessage, MavModeFlag, MavType,
        MissionState as MavMissionState,
    };
    use crate::link::telemetry::*;
    use crate::link::testing::autopilot_header as vehicle;
    use crate::link::Flavour;
    use mavlink::MavHeader;

    fn battery_status(
        voltages: [u16; 10],
        voltages_ext: [u16; 4],
        current_battery: i16,
        current_consumed: i32,
    ) -> Battery {
        let message = MavMessage::BATTERY_STATUS(mav::BATTERY_STATUS_DATA {
            voltages,
            voltages_ext,
            current_battery,
            current_consumed,
            energy_consumed: -1,
            battery_remaining: -1,
            ..Default::default()
        });
        match decode(&vehicle(), &message).reading {
            Some(Reading::Battery(b)) => b,
            other => panic!("not a battery reading: {other:?}"),
        }
    }

    const NONE10: [u16; 10] = [u16::MAX; 10];

    #[test]
    fn the_pack_voltage_is_the_sum_of_the_cells_present() {
        let mut cells = NONE10;
        cells[..6].copy_from_slice(&[4100, 4110, 4090, 4105, 4095, 4100]);
        let b = battery_status(cells, [0; 4], 4150, 1200);
        assert!((b.voltage_v.expect("known") - 24.6).abs() < 1e-9);
        assert_eq!(b.current_a, Some(41.5));
        assert_eq!(b.consumed_mah, Some(1200.0));
        assert_eq!(b.energy_consumed_j, None);
        assert!(!b.fake_current);
    }

    #[test]
    fn extension_cells_eleven_to_fourteen_add_to_the_pack() {
        let cells = [3900u16; 10];
        let b = battery_status(cells, [3900, 3900, 0, 0], 100, 5);
        assert!((b.voltage_v.expect("known") - 46.8).abs() < 1e-9);
    }

    #[test]
    fn voltages_zero_alone_is_the_pack_when_cells_are_unknown() {
        let mut cells = NONE10;
        cells[0] = 16_200;
        let b = battery_status(cells, [0; 4], 1250, 10);
        assert_eq!(b.voltage_v, Some(16.2));
    }

    #[test]
    fn a_pack_above_65534_mv_continues_in_the_next_cell() {
        let mut cells = NONE10;
        cells[0] = 65_534;
        cells[1] = 4_466;
        let b = battery_status(cells, [0; 4], 1250, 10);
        assert!((b.voltage_v.expect("known") - 70.0).abs() < 1e-9);
    }

    #[test]
    fn no_cells_at_all_is_an_unknown_voltage() {
        let b = battery_status(NONE10, [0; 4], 1250, 10);
        assert_eq!(b.voltage_v, None);
    }

    #[test]
    fn current_minus_one_is_unknown_never_zero() {
        let mut cells = NONE10;
        cells[0] = 22_000;
        let b = battery_status(cells, [0; 4], -1, -1);
        assert_eq!(b.current_a, None);
        assert_eq!(b.consumed_mah, None);
        assert!(!b.fake_current);
    }

    #[test]
    fn px4_simulated_battery_current_is_flagged_fake() {
        let mut cells = NONE10;
        cells[0] = 16_000;
        assert!(battery_status(cells, [0; 4], -100, -37).fake_current);
        assert!(battery_status(cells, [0; 4], -100, 0).fake_current);
        // A real pack that has delivered charge: not the simulator.
        assert!(!battery_status(cells, [0; 4], -100, 250).fake_current);
    }

    #[test]
    fn sys_status_gives_voltage_and_current_and_their_unknowns() {
        let known = MavMessage::SYS_STATUS(mav::SYS_STATUS_DATA {
            voltage_battery: 22_800,
            current_battery: 4_600,
            battery_remaining: 71,
            ..Default::default()
        });
        let Some(Reading::Battery(b)) = decode(&vehicle(), &known).reading else {
            panic!("battery reading expected");
        };
        assert_eq!(b.source, BatterySource::SysStatus);
        assert_eq!((b.voltage_v, b.current_a), (Some(22.8), Some(46.0)));
        assert_eq!(b.remaining_pct, Some(71.0));
        let unknown = MavMessage::SYS_STATUS(mav::SYS_STATUS_DATA {
            voltage_battery: u16::MAX,
            current_battery: -1,
            battery_remaining: -1,
            ..Default::default()
        });
        let Some(Reading::Battery(b)) = decode(&vehicle(), &unknown).reading else {
            panic!("battery reading expected");
        };
        assert_eq!(
            (b.voltage_v, b.current_a, b.remaining_pct),
            (None, None, None)
        );
    }

    #[test]
    fn global_position_int_converts_dege7_millimetres_and_centimetres_per_second() {
        let message = MavMessage::GLOBAL_POSITION_INT(mav::GLOBAL_POSITION_INT_DATA {
            time_boot_ms: 12_345,
            lat: 385_362_000,
            lon: -1_217_875_000,
            alt: 46_250,
            relative_alt: 30_250,
            vx: 150,
            vy: -200,
            vz: 50,
            hdg: 0,
        });
        let decoded = decode(&vehicle(), &message);
        assert_eq!(decoded.time_boot_ms, Some(12_345));
        let Some(Reading::Position(p)) = decoded.reading else {
            panic!("position expected");
        };
        assert!((p.lat_deg - 38.5362).abs() < 1e-9 && (p.lon_deg + 121.7875).abs() < 1e-9);
        assert!((p.alt_amsl_m - 46.25).abs() < 1e-9 && (p.relative_alt_m - 30.25).abs() < 1e-9);
        assert_eq!((p.vn_m_s, p.ve_m_s, p.vd_m_s), (1.5, -2.0, 0.5));
    }

    #[test]
    fn home_position_gives_home_altitude_in_metres_untimed_and_nothing_before_home_is_set() {
        let message = MavMessage::HOME_POSITION(mav::HOME_POSITION_DATA {
            latitude: 385_362_010,
            longitude: -1_217_874_959,
            altitude: 16_186,
            // When home was set, not when the message was sent: never a clock anchor.
            time_usec: 3_828_000,
            ..Default::default()
        });
        let decoded = decode(&vehicle(), &message);
        assert_eq!(decoded.time_boot_ms, None);
        let Some(
            reading @ Reading::Home {
                lat_deg,
                lon_deg,
                alt_amsl_m,
                set_boot_s,
            },
        ) = decoded.reading
        else {
            panic!("home expected");
        };
        assert!((lat_deg - 38.536_201).abs() < 1e-9 && (lon_deg + 121.787_495_9).abs() < 1e-9);
        assert!((alt_amsl_m - 16.186).abs() < 1e-9);
        assert_eq!(set_boot_s, Some(3.828));
        let unset = MavMessage::HOME_POSITION(mav::HOME_POSITION_DATA::default());
        assert_eq!(decode(&vehicle(), &unset), Decoded::NOTHING);
        assert_eq!(
            decode(&vehicle(), &encode(&reading, Flavour::Px4)).reading,
            Some(reading)
        );
    }

    #[test]
    fn a_position_without_a_fix_is_only_a_clock_anchor() {
        let message = MavMessage::GLOBAL_POSITION_INT(mav::GLOBAL_POSITION_INT_DATA {
            time_boot_ms: 500,
            ..Default::default()
        });
        let decoded = decode(&vehicle(), &message);
        assert_eq!(decoded, Decoded::anchor(500));
    }

    fn heartbeat(
        autopilot: MavAutopilot,
        mavtype: MavType,
        custom_mode: u32,
        armed: bool,
    ) -> MavMessage {
        let mut base_mode = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
        if armed {
            base_mode |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
        }
        MavMessage::HEARTBEAT(mav::HEARTBEAT_DATA {
            custom_mode,
            mavtype,
            autopilot,
            base_mode,
            system_status: mav::MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        })
    }

    fn mode_of(message: &MavMessage) -> Option<(bool, FlightMode)> {
        match decode(&vehicle(), message).reading {
            Some(Reading::Heartbeat { armed, mode }) => Some((armed, mode)),
            _ => None,
        }
    }

    #[test]
    fn px4_modes_come_from_the_main_and_sub_mode_bytes() {
        let px4 = |main: u32, sub: u32| {
            let hb = heartbeat(
                MavAutopilot::MAV_AUTOPILOT_PX4,
                MavType::MAV_TYPE_OCTOROTOR,
                (main << 16) | (sub << 24),
                true,
            );
            mode_of(&hb).expect("an autopilot heartbeat").1
        };
        assert_eq!(px4(4, 4), FlightMode::Mission);
        assert_eq!(px4(4, 2), FlightMode::Takeoff);
        assert_eq!(px4(4, 6), FlightMode::Land);
        assert_eq!(px4(4, 5), FlightMode::Rtl);
        assert_eq!(px4(4, 3), FlightMode::Hold);
        assert_eq!(px4(3, 0), FlightMode::Manual);
        assert_eq!(px4(6, 0), FlightMode::Other("offboard".into()));
    }

    #[test]
    fn arducopter_modes_come_from_its_mode_numbers() {
        let apm = |n: u32| {
            let hb = heartbeat(
                MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
                MavType::MAV_TYPE_OCTOROTOR,
                n,
                false,
            );
            mode_of(&hb).expect("an autopilot heartbeat").1
        };
        assert_eq!(apm(3), FlightMode::Mission);
        assert_eq!(apm(4), FlightMode::Guided);
        assert_eq!(apm(5), FlightMode::Hold);
        assert_eq!(apm(6), FlightMode::Rtl);
        assert_eq!(apm(9), FlightMode::Land);
        assert_eq!(apm(0), FlightMode::Manual);
        // ArduPlane numbers mean something else: not read as a copter's.
        let plane = heartbeat(
            MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            MavType::MAV_TYPE_FIXED_WING,
            10,
            false,
        );
        assert_eq!(
            mode_of(&plane).map(|m| m.1),
            Some(FlightMode::Other("custom 10".into()))
        );
    }

    #[test]
    fn armed_is_the_safety_armed_flag() {
        let on = heartbeat(
            MavAutopilot::MAV_AUTOPILOT_PX4,
            MavType::MAV_TYPE_QUADROTOR,
            0,
            true,
        );
        let off = heartbeat(
            MavAutopilot::MAV_AUTOPILOT_PX4,
            MavType::MAV_TYPE_QUADROTOR,
            0,
            false,
        );
        assert_eq!(mode_of(&on).map(|m| m.0), Some(true));
        assert_eq!(mode_of(&off).map(|m| m.0), Some(false));
    }

    #[test]
    fn heartbeats_of_ground_stations_and_peripherals_are_ignored() {
        let gcs = heartbeat(
            MavAutopilot::MAV_AUTOPILOT_INVALID,
            MavType::MAV_TYPE_GCS,
            0,
            false,
        );
        let camera = heartbeat(
            MavAutopilot::MAV_AUTOPILOT_INVALID,
            MavType::MAV_TYPE_CAMERA,
            0,
            false,
        );
        let companion = heartbeat(
            MavAutopilot::MAV_AUTOPILOT_PX4,
            MavType::MAV_TYPE_ONBOARD_CONTROLLER,
            0,
            true,
        );
        assert_eq!(mode_of(&gcs), None);
        assert_eq!(mode_of(&camera), None);
        assert_eq!(mode_of(&companion), None);
    }

    #[test]
    fn landed_states_and_mission_progress_are_decoded() {
        let landed = |s| {
            decode(
                &vehicle(),
                &MavMessage::EXTENDED_SYS_STATE(mav::EXTENDED_SYS_STATE_DATA {
                    landed_state: s,
                    ..Default::default()
                }),
            )
            .reading
        };
        assert_eq!(
            landed(MavLandedState::MAV_LANDED_STATE_ON_GROUND),
            Some(Reading::Landed(LandedState::OnGround))
        );
        assert_eq!(
            landed(MavLandedState::MAV_LANDED_STATE_TAKEOFF),
            Some(Reading::Landed(LandedState::Takeoff))
        );
        assert_eq!(
            landed(MavLandedState::MAV_LANDED_STATE_IN_AIR),
            Some(Reading::Landed(LandedState::InAir))
        );
        assert_eq!(
            landed(MavLandedState::MAV_LANDED_STATE_LANDING),
            Some(Reading::Landed(LandedState::Landing))
        );
        let current = MavMessage::MISSION_CURRENT(mav::MISSION_CURRENT_DATA {
            seq: 4,
            total: u16::MAX,
            mission_state: MavMissionState::MISSION_STATE_ACTIVE,
            ..Default::default()
        });
        assert_eq!(
            decode(&vehicle(), &current).reading,
            Some(Reading::MissionCurrent {
                seq: 4,
                total: None,
                state: MissionState::Active
            })
        );
    }

    #[test]
    fn the_decoder_listens_only_to_the_first_autopilot_once_it_is_known() {
        let mut decoder = TelemetryDecoder::new();
        let hb = heartbeat(
            MavAutopilot::MAV_AUTOPILOT_PX4,
            MavType::MAV_TYPE_OCTOROTOR,
            0,
            true,
        );
        assert!(decoder.decode(&vehicle(), &hb).reading.is_some());
        let other_vehicle = MavHeader {
            system_id: 2,
            ..vehicle()
        };
        let smart_battery = MavHeader {
            component_id: 180,
            ..vehicle()
        };
        let mut cells = NONE10;
        cells[0] = 22_000;
        let battery = MavMessage::BATTERY_STATUS(mav::BATTERY_STATUS_DATA {
            voltages: cells,
            ..Default::default()
        });
        assert!(decoder.decode(&other_vehicle, &battery).reading.is_none());
        assert!(decoder.decode(&smart_battery, &battery).reading.is_some());
        assert!(decoder.decode(&other_vehicle, &hb).reading.is_none());
        let camera_clock = MavMessage::ATTITUDE(mav::ATTITUDE_DATA {
            time_boot_ms: 99,
            ..Default::default()
        });
        let camera = MavHeader {
            component_id: 100,
            ..vehicle()
        };
        assert_eq!(decoder.decode(&camera, &camera_clock), Decoded::NOTHING);
    }

    fn photo_of(message: &MavMessage) -> Option<Photo> {
        let (header, back) = parse_frame(&frame_bytes(&vehicle(), message)).expect("a frame");
        match decode(&header, &back).reading {
            Some(Reading::Photo(photo)) => Some(photo),
            _ => None,
        }
    }

    #[test]
    fn camera_feedback_gives_a_photo_in_degrees_and_metres_and_a_video_frame_gives_none() {
        let feedback = mav::CAMERA_FEEDBACK_DATA {
            time_usec: 1_764_361_200_250_000,
            lat: 385_362_150,
            lng: -1_217_874_250,
            alt_msl: 46.25,
            alt_rel: 30.5,
            img_idx: 3,
            flags: CameraFeedbackFlags::CAMERA_FEEDBACK_PHOTO,
            ..Default::default()
        };
        let photo = photo_of(&MavMessage::CAMERA_FEEDBACK(feedback.clone())).expect("a photo");
        assert_eq!(photo.message, PhotoMessage::CameraFeedback);
        assert_eq!(photo.index, 3);
        assert!(photo.captured);
        let at = photo.at.expect("a position");
        assert!((at.lat_deg - 38.536_215).abs() < 1e-9, "{at:?}");
        assert!((at.lon_deg + 121.787_425).abs() < 1e-9, "{at:?}");
        assert_eq!((at.alt_amsl_m, at.relative_alt_m), (46.25, 30.5));
        assert!((photo.camera_time_s.expect("a time") - 1_764_361_200.25).abs() < 1e-6);
        // Untimed: never a clock anchor.
        let decoded = decode(&vehicle(), &MavMessage::CAMERA_FEEDBACK(feedback.clone()));
        assert_eq!(decoded.time_boot_ms, None);
        let video = mav::CAMERA_FEEDBACK_DATA {
            flags: CameraFeedbackFlags::CAMERA_FEEDBACK_VIDEO,
            ..feedback
        };
        assert_eq!(photo_of(&MavMessage::CAMERA_FEEDBACK(video)), None);
    }

    #[test]
    fn px4_camera_trigger_and_image_captured_give_photos_of_the_same_index() {
        let trigger = photo_of(&MavMessage::CAMERA_TRIGGER(mav::CAMERA_TRIGGER_DATA {
            time_usec: 61_500_000,
            seq: 2,
        }))
        .expect("a photo");
        assert_eq!(trigger.message, PhotoMessage::CameraTrigger);
        assert_eq!((trigger.index, trigger.at), (2, None));
        assert_eq!(trigger.camera_time_s, Some(61.5));
        let captured = photo_of(&MavMessage::CAMERA_IMAGE_CAPTURED(
            mav::CAMERA_IMAGE_CAPTURED_DATA {
                time_boot_ms: 61_520,
                lat: 385_362_000,
                lon: -1_217_875_000,
                alt: 46_250,
                relative_alt: 30_250,
                image_index: 2,
                capture_result: mav::MavBool::MAV_BOOL_TRUE,
                ..Default::default()
            },
        ))
        .expect("a photo");
        assert_eq!(captured.message, PhotoMessage::ImageCaptured);
        assert_eq!(captured.index, trigger.index);
        assert!(captured.captured);
        let at = captured.at.expect("a position");
        assert!((at.lat_deg - 38.5362).abs() < 1e-9 && (at.lon_deg + 121.7875).abs() < 1e-9);
        assert!((at.alt_amsl_m - 46.25).abs() < 1e-9 && (at.relative_alt_m - 30.25).abs() < 1e-9);
        assert_eq!(captured.camera_time_s, Some(61.52));
        let failed = photo_of(&MavMessage::CAMERA_IMAGE_CAPTURED(
            mav::CAMERA_IMAGE_CAPTURED_DATA {
                image_index: 3,
                capture_result: mav::MavBool::MAV_BOOL_FALSE,
                ..Default::default()
            },
        ))
        .expect("a photo");
        assert!(!failed.captured);
        assert_eq!(failed.at, None);
    }

    #[test]
    fn every_photo_reading_survives_encode_then_decode() {
        let at = Some(PhotoPosition {
            lat_deg: 38.536_215,
            lon_deg: -121.787_425,
            alt_amsl_m: 46.25,
            relative_alt_m: 30.5,
        });
        let photos = [
            Photo {
                message: PhotoMessage::CameraFeedback,
                index: 7,
                at,
                camera_time_s: Some(12.5),
                captured: true,
            },
            Photo {
                message: PhotoMessage::CameraTrigger,
                index: 7,
                at: None,
                camera_time_s: Some(12.5),
                captured: true,
            },
            Photo {
                message: PhotoMessage::ImageCaptured,
                index: 7,
                at,
                camera_time_s: Some(12.5),
                captured: true,
            },
        ];
        for photo in photos {
            let back = photo_of(&encode(&Reading::Photo(photo), Flavour::Px4)).expect("a photo");
            assert_eq!(back, photo);
        }
    }

    #[test]
    fn a_mavlink_camera_of_the_autopilots_system_is_heard_and_another_systems_is_not() {
        let mut decoder = TelemetryDecoder::new();
        let hb = heartbeat(
            MavAutopilot::MAV_AUTOPILOT_PX4,
            MavType::MAV_TYPE_QUADROTOR,
            0,
            true,
        );
        decoder.decode(&vehicle(), &hb);
        let captured = MavMessage::CAMERA_IMAGE_CAPTURED(mav::CAMERA_IMAGE_CAPTURED_DATA {
            image_index: 0,
            capture_result: mav::MavBool::MAV_BOOL_TRUE,
            ..Default::default()
        });
        let camera = MavHeader {
            component_id: 100,
            ..vehicle()
        };
        let other = MavHeader {
            system_id: 9,
            ..camera
        };
        assert!(matches!(
            decoder.decode(&camera, &captured).reading,
            Some(Reading::Photo(_))
        ));
        assert_eq!(decoder.decode(&other, &captured), Decoded::NOTHING);
    }
}
