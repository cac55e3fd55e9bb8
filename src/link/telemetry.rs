//! Telemetry at the MAVLink edge: the one place MAVLink units become SI ([`decode`]: cA, mV, degE7,
//! mm, cm/s, custom modes), the autopilot filter and vehicle clock in front of the flight log
//! ([`Telemetry`]: the same path live and in replay), raw frames to messages and back
//! ([`parse_frame`], [`frame_bytes`]), the inverse of `decode` for tests and simulations
//! ([`encode`]), and the stream-rate requests ([`StreamRequests`]: a sans-IO machine that sends
//! MAV_CMD_SET_MESSAGE_INTERVAL for each wanted message, one at a time, until COMMAND_ACK).
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
//! - HEARTBEAT of the autopilot only (not a GCS, camera or companion: `autopilot` INVALID or a
//!   ground-station type); armed = `MAV_MODE_FLAG_SAFETY_ARMED`; the mode from `custom_mode`: PX4
//!   main mode in byte 2, sub mode in byte 3; ArduCopter's mode numbers.

use std::path::Path;
use std::time::Duration;

use mavlink::{MavHeader, MavlinkReader, MavlinkVersion, MessageData};

use super::mav::{
    self, MavAutopilot, MavCmd, MavLandedState, MavMessage, MavModeFlag, MavResult, MavSeverity,
    MavType, MissionState as MavMissionState,
};
use super::Flavour;
use crate::flightlog::clock::VehicleClock;
use crate::flightlog::flight_plan::FlightPlan;
use crate::flightlog::recorder::{flight_name, PLAN_FILE, TLOG_FILE};
use crate::flightlog::report::FlightReport;
use crate::flightlog::segment::{SegmentConfig, Segmenter};
use crate::flightlog::telemetry::{
    Battery, BatterySource, FlightMode, LandedState, MissionState, Position, Reading, Stamped,
};
use crate::flightlog::tlog::{FrameCheck, TlogGap, TlogReader};
use crate::flightlog::FlightLogError;

/// Errors at the telemetry edge.
#[derive(Debug, thiserror::Error)]
pub enum TelemetryError {
    #[error("frame of {len} bytes: {reason}")]
    Frame { len: usize, reason: String },
    #[error(transparent)]
    Log(#[from] FlightLogError),
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

/// ArduCopter's mode numbers (ArduCopter `mode.h`, `enum class Number`).
fn arducopter_mode(custom_mode: u32) -> FlightMode {
    match custom_mode {
        0 | 1 | 2 | 11 | 13 | 16 | 22 => FlightMode::Manual,
        3 => FlightMode::Mission,
        4 | 20 => FlightMode::Guided,
        5 | 17 => FlightMode::Hold,
        6 | 21 | 27 => FlightMode::Rtl,
        9 => FlightMode::Land,
        7 => FlightMode::Other("circle".into()),
        n => FlightMode::Other(format!("arducopter {n}")),
    }
}

fn mode(hb: &mav::HEARTBEAT_DATA) -> FlightMode {
    match hb.autopilot {
        MavAutopilot::MAV_AUTOPILOT_PX4 => px4_mode(hb.custom_mode),
        MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA if is_copter(hb.mavtype) => {
            arducopter_mode(hb.custom_mode)
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
        _ => Decoded::NOTHING,
    }
}

/// [`decode`] behind a source filter: once an autopilot's HEARTBEAT is seen, only its system is
/// listened to, and only its component for everything but BATTERY_STATUS (a smart battery may be
/// a component of its own). Before that every message counts (a log may start mid-flight).
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
            let battery = matches!(message, MavMessage::BATTERY_STATUS(_));
            if header.system_id != system || (!battery && header.component_id != component) {
                return Decoded::NOTHING;
            }
        }
        decode(header, message)
    }
}

/// The path from the link to the flight log, the same live and in replay: source filter,
/// decode, vehicle clock.
#[derive(Debug, Clone, Default)]
pub struct Telemetry {
    decoder: TelemetryDecoder,
    clock: VehicleClock,
    undecodable: u64,
}

impl Telemetry {
    pub fn new() -> Telemetry {
        Telemetry::default()
    }

    /// With a known autopilot and clock settings.
    pub fn with(decoder: TelemetryDecoder, clock: VehicleClock) -> Telemetry {
        Telemetry {
            decoder,
            clock,
            undecodable: 0,
        }
    }

    pub fn clock(&self) -> &VehicleClock {
        &self.clock
    }

    pub fn autopilot(&self) -> Option<(u32, u8)> {
        self.decoder.autopilot()
    }

    /// Frames that were not a known MAVLink message (bad CRC, unknown id or enum value).
    pub fn undecodable(&self) -> u64 {
        self.undecodable
    }

    /// One message that arrived at `wall_us` (unix microseconds).
    pub fn message(
        &mut self,
        wall_us: u64,
        header: &MavHeader,
        message: &MavMessage,
    ) -> Option<Stamped> {
        let decoded = self.decoder.decode(header, message);
        if decoded.time_boot_ms.is_none() && decoded.reading.is_none() {
            return None;
        }
        let t_s = self.clock.stamp(wall_us, decoded.time_boot_ms);
        decoded.reading.map(|reading| Stamped {
            t_s,
            wall_us,
            reading,
        })
    }

    /// One raw frame; frames that do not parse are counted and give nothing.
    pub fn frame(&mut self, wall_us: u64, frame: &[u8]) -> Option<Stamped> {
        match parse_frame(frame) {
            Ok((header, message)) => self.message(wall_us, &header, &message),
            Err(_) => {
                self.undecodable += 1;
                None
            }
        }
    }
}

/// A .tlog replayed through [`Telemetry`].
#[derive(Debug, Clone, Default)]
pub struct Replay {
    pub stamped: Vec<Stamped>,
    /// Records in the file.
    pub frames: u64,
    /// Frames that were not a known MAVLink message.
    pub undecodable: u64,
    /// Offset of a torn last record, skipped.
    pub torn_tail: Option<u64>,
    /// Spans of the file that were not records (corrupt), skipped: the replay went on from the
    /// next frame that checks. Their vehicle times are those of the readings either side.
    pub gaps: Vec<TlogGap>,
}

/// Judges a whole raw frame for [`TlogReader::resynchronising`]: its checksum with the
/// ardupilotmega dialect's CRC_EXTRA for its message id (mavlink.io, "Serialization: CRC_EXTRA").
pub fn check_frame(frame: &[u8]) -> FrameCheck {
    use mavlink::Message;
    // Where the message id is and where the checksummed bytes (after the start byte) end.
    let (id, crc_end) = match (frame.first(), frame.get(1), frame.get(2)) {
        (Some(0xFE), Some(&len), _) if frame.len() > 5 => {
            (u32::from(frame[5]), 6 + usize::from(len))
        }
        (Some(0xFD), Some(&len), Some(&flags)) => {
            let id_at = if flags & 0x02 != 0 { 10 } else { 7 };
            let Some(id) = frame.get(id_at..id_at + 3) else {
                return FrameCheck::BadCrc;
            };
            (
                u32::from_le_bytes([id[0], id[1], id[2], 0]),
                id_at + 3 + usize::from(len),
            )
        }
        _ => return FrameCheck::BadCrc,
    };
    let Some(crc) = frame.get(crc_end..crc_end + 2) else {
        return FrameCheck::BadCrc;
    };
    let extra = MavMessage::extra_crc(id);
    // The generated dialect answers 0 for an id it does not know.
    if extra == 0 && MavMessage::default_message_from_id(id).is_none() {
        return FrameCheck::UnknownMessage;
    }
    if mavlink::calculate_crc(&frame[1..crc_end], extra) == u16::from_le_bytes([crc[0], crc[1]]) {
        FrameCheck::Valid
    } else {
        FrameCheck::BadCrc
    }
}

/// Opens a .tlog to replay: corrupt spans skipped and kept as gaps (see [`check_frame`]).
pub fn open_tlog(path: &Path) -> Result<TlogReader<std::fs::File>, TelemetryError> {
    Ok(TlogReader::open(path)?.resynchronising(check_frame))
}

/// Replays a .tlog from the start: every stamped reading, in order, as the live run made them.
/// A torn tail ends the replay quietly; a corrupt span is skipped, the replay going on from the
/// next frame that checks, and kept in `gaps` with the vehicle times either side of it. A file
/// without a single record is an error.
pub fn replay_tlog(path: &Path) -> Result<Replay, TelemetryError> {
    let mut telemetry = Telemetry::new();
    let mut replay = Replay::default();
    let mut reader = open_tlog(path)?;
    // Gaps whose vehicle time after them is not known yet.
    let mut open_from = 0;
    while let Some(record) = reader.next() {
        let record = record?;
        replay.frames += 1;
        let before_s = replay.stamped.last().map(|s| s.t_s);
        for gap in &reader.gaps()[replay.gaps.len()..] {
            replay.gaps.push(TlogGap {
                from_s: before_s,
                ..gap.clone()
            });
        }
        if let Some(s) = telemetry.frame(record.wall_us, &record.frame) {
            for gap in &mut replay.gaps[open_from..] {
                gap.to_s = Some(s.t_s);
            }
            open_from = replay.gaps.len();
            replay.stamped.push(s);
        }
    }
    let before_s = replay.stamped.last().map(|s| s.t_s);
    for gap in &reader.gaps()[replay.gaps.len()..] {
        replay.gaps.push(TlogGap {
            from_s: before_s,
            ..gap.clone()
        });
    }
    replay.torn_tail = reader.torn_tail();
    replay.undecodable = telemetry.undecodable();
    Ok(replay)
}

/// A recorded flight replayed and measured against its plan.
#[derive(Debug, Clone)]
pub struct Analysis {
    pub report: FlightReport,
    /// The segments and the battery series (for plots and live views).
    pub segmenter: Segmenter,
    pub replay: Replay,
}

/// Replays a .tlog against `plan` and reports it as flight `name`.
pub fn analyse_tlog(
    tlog: &Path,
    plan: FlightPlan,
    name: &str,
    cfg: SegmentConfig,
) -> Result<Analysis, TelemetryError> {
    let replay = replay_tlog(tlog)?;
    let mut segmenter = Segmenter::run(plan, cfg, &replay.stamped)?;
    for gap in &replay.gaps {
        segmenter.log_gap(
            gap.from_s.unwrap_or(f64::NEG_INFINITY),
            gap.to_s.unwrap_or(f64::INFINITY),
        );
    }
    let mut report = FlightReport::build(name, &segmenter);
    report.log_gaps = replay.gaps.clone();
    Ok(Analysis {
        report,
        segmenter,
        replay,
    })
}

/// Replays a flight directory (its flight.tlog against its plan.json), named by the directory.
pub fn analyse_flight_dir(dir: &Path, cfg: SegmentConfig) -> Result<Analysis, TelemetryError> {
    let plan = FlightPlan::read_json(&dir.join(PLAN_FILE))?;
    analyse_tlog(&dir.join(TLOG_FILE), plan, &flight_name(dir), cfg)
}

/// The last complete mission (every item of the latest MISSION_COUNT, in either direction) in a
/// .tlog, and the flavour of the autopilot that flew it.
pub fn mission_in_tlog(
    path: &Path,
) -> Result<(Option<Vec<mav::MISSION_ITEM_INT_DATA>>, Flavour), TelemetryError> {
    let mut flavour = Flavour::Generic;
    let mut count: Option<u16> = None;
    let mut items: Vec<Option<mav::MISSION_ITEM_INT_DATA>> = Vec::new();
    let mut complete: Option<Vec<mav::MISSION_ITEM_INT_DATA>> = None;
    for record in open_tlog(path)? {
        let record = record?;
        let Ok((_, message)) = parse_frame(&record.frame) else {
            continue;
        };
        match message {
            MavMessage::HEARTBEAT(hb) if is_autopilot(&hb) => {
                flavour = Flavour::from_autopilot(hb.autopilot)
            }
            MavMessage::MISSION_COUNT(c)
                if c.mission_type == mav::MavMissionType::MAV_MISSION_TYPE_MISSION =>
            {
                count = Some(c.count);
                items = vec![None; usize::from(c.count)];
            }
            MavMessage::MISSION_ITEM_INT(item)
                if item.mission_type == mav::MavMissionType::MAV_MISSION_TYPE_MISSION =>
            {
                if let Some(slot) = items.get_mut(usize::from(item.seq)) {
                    *slot = Some(item);
                }
                if count.is_some() && items.iter().all(Option::is_some) {
                    complete = Some(items.iter().flatten().cloned().collect());
                }
            }
            _ => {}
        }
    }
    Ok((complete, flavour))
}

/// Parses one raw MAVLink 1 or 2 frame (signed frames included; the signature is not checked
/// here, the link did that on receipt).
pub fn parse_frame(frame: &[u8]) -> Result<(MavHeader, MavMessage), TelemetryError> {
    let mut reader = MavlinkReader::with_capacity(0, frame);
    reader
        .read_any_message::<MavMessage>()
        .map_err(|e| TelemetryError::Frame {
            len: frame.len(),
            reason: e.to_string(),
        })
}

/// Serialises a message as one MAVLink 2 frame (unsigned), as it would go over the link.
pub fn frame_bytes(header: &MavHeader, message: &MavMessage) -> Vec<u8> {
    let mut raw = mavlink::MAVLinkV2MessageRaw::new();
    raw.serialize_message(*header, message);
    raw.raw_bytes().to_vec()
}

/// Serialises a message in the given protocol version (MAVLink 1 drops extension fields and
/// message ids above 255: those give None).
pub fn frame_bytes_versioned(
    header: &MavHeader,
    message: &MavMessage,
    version: MavlinkVersion,
) -> Option<Vec<u8>> {
    let mut out = Vec::new();
    mavlink::write_versioned_msg(&mut out, version, *header, message)
        .ok()
        .map(|_| out)
}

fn px4_custom_mode(mode: &FlightMode) -> u32 {
    let (main, sub) = match mode {
        FlightMode::Mission => (4, 4),
        FlightMode::Takeoff => (4, 2),
        FlightMode::Hold => (4, 3),
        FlightMode::Rtl => (4, 5),
        FlightMode::Land => (4, 6),
        FlightMode::Manual => (3, 0),
        FlightMode::Guided => (6, 0),
        FlightMode::Other(_) => (4, 1),
    };
    (main << 16) | (sub << 24)
}

fn arducopter_custom_mode(mode: &FlightMode) -> u32 {
    match mode {
        FlightMode::Mission => 3,
        FlightMode::Guided | FlightMode::Takeoff => 4,
        FlightMode::Hold => 5,
        FlightMode::Rtl => 6,
        FlightMode::Land => 9,
        FlightMode::Manual | FlightMode::Other(_) => 0,
    }
}

/// The message an autopilot of `flavour` sends for `reading`: the inverse of [`decode`], with
/// PX4's battery encoding (pack in `voltages[0]`, split above 65534 mV). For tests, benches and
/// simulated vehicles.
pub fn encode(reading: &Reading, flavour: Flavour) -> MavMessage {
    let centi = |a: Option<f64>| a.map_or(-1, |a| (a * 100.0).round() as i16);
    match reading {
        Reading::Battery(b) => {
            let current = if b.fake_current {
                -100
            } else {
                centi(b.current_a)
            };
            let remaining = b.remaining_pct.map_or(-1, |r| r.round() as i8);
            match b.source {
                BatterySource::BatteryStatus { id, .. } => {
                    let mut voltages = [u16::MAX; 10];
                    if let Some(v) = b.voltage_v {
                        let mut mv = (v * 1000.0).round().max(0.0) as u32;
                        for cell in voltages.iter_mut() {
                            let part = mv.min(65534);
                            *cell = part as u16;
                            mv -= part;
                            if mv == 0 {
                                break;
                            }
                        }
                    }
                    MavMessage::BATTERY_STATUS(mav::BATTERY_STATUS_DATA {
                        current_consumed: b.consumed_mah.map_or(-1, |c| c.round() as i32),
                        energy_consumed: b
                            .energy_consumed_j
                            .map_or(-1, |e| (e / 100.0).round() as i32),
                        temperature: i16::MAX,
                        voltages,
                        current_battery: current,
                        id,
                        battery_remaining: remaining,
                        ..Default::default()
                    })
                }
                BatterySource::SysStatus => MavMessage::SYS_STATUS(mav::SYS_STATUS_DATA {
                    voltage_battery: b
                        .voltage_v
                        .map_or(u16::MAX, |v| (v * 1000.0).round() as u16),
                    current_battery: current,
                    battery_remaining: remaining,
                    ..Default::default()
                }),
            }
        }
        Reading::Position(p) => MavMessage::GLOBAL_POSITION_INT(mav::GLOBAL_POSITION_INT_DATA {
            time_boot_ms: p.time_boot_ms,
            lat: (p.lat_deg * 1e7).round() as i32,
            lon: (p.lon_deg * 1e7).round() as i32,
            alt: (p.alt_amsl_m * 1000.0).round() as i32,
            relative_alt: (p.relative_alt_m * 1000.0).round() as i32,
            vx: (p.vn_m_s * 100.0).round() as i16,
            vy: (p.ve_m_s * 100.0).round() as i16,
            vz: (p.vd_m_s * 100.0).round() as i16,
            hdg: u16::MAX,
        }),
        Reading::MissionCurrent { seq, total, state } => {
            MavMessage::MISSION_CURRENT(mav::MISSION_CURRENT_DATA {
                seq: *seq,
                total: total.unwrap_or(u16::MAX),
                mission_state: match state {
                    MissionState::Unknown => MavMissionState::MISSION_STATE_UNKNOWN,
                    MissionState::NoMission => MavMissionState::MISSION_STATE_NO_MISSION,
                    MissionState::NotStarted => MavMissionState::MISSION_STATE_NOT_STARTED,
                    MissionState::Active => MavMissionState::MISSION_STATE_ACTIVE,
                    MissionState::Paused => MavMissionState::MISSION_STATE_PAUSED,
                    MissionState::Complete => MavMissionState::MISSION_STATE_COMPLETE,
                },
                ..Default::default()
            })
        }
        Reading::ItemReached { seq } => {
            MavMessage::MISSION_ITEM_REACHED(mav::MISSION_ITEM_REACHED_DATA { seq: *seq })
        }
        Reading::Heartbeat { armed, mode } => {
            let (autopilot, custom_mode) = match flavour {
                Flavour::ArduPilot => (
                    MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
                    arducopter_custom_mode(mode),
                ),
                Flavour::Px4 | Flavour::Generic => {
                    (MavAutopilot::MAV_AUTOPILOT_PX4, px4_custom_mode(mode))
                }
            };
            let mut base_mode = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
            if *armed {
                base_mode |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
            }
            MavMessage::HEARTBEAT(mav::HEARTBEAT_DATA {
                custom_mode,
                mavtype: MavType::MAV_TYPE_OCTOROTOR,
                autopilot,
                base_mode,
                system_status: mav::MavState::MAV_STATE_ACTIVE,
                mavlink_version: 3,
            })
        }
        Reading::Landed(state) => MavMessage::EXTENDED_SYS_STATE(mav::EXTENDED_SYS_STATE_DATA {
            landed_state: match state {
                LandedState::Undefined => MavLandedState::MAV_LANDED_STATE_UNDEFINED,
                LandedState::OnGround => MavLandedState::MAV_LANDED_STATE_ON_GROUND,
                LandedState::InAir => MavLandedState::MAV_LANDED_STATE_IN_AIR,
                LandedState::Takeoff => MavLandedState::MAV_LANDED_STATE_TAKEOFF,
                LandedState::Landing => MavLandedState::MAV_LANDED_STATE_LANDING,
            },
            ..Default::default()
        }),
        Reading::Home {
            lat_deg,
            lon_deg,
            alt_amsl_m,
            set_boot_s,
        } => MavMessage::HOME_POSITION(mav::HOME_POSITION_DATA {
            latitude: (lat_deg * 1e7).round() as i32,
            longitude: (lon_deg * 1e7).round() as i32,
            altitude: (alt_amsl_m * 1000.0).round() as i32,
            q: [1.0, 0.0, 0.0, 0.0],
            time_usec: set_boot_s.map_or(0, |s| (s * 1e6).round() as u64),
            ..Default::default()
        }),
        Reading::StatusText { severity, text } => {
            let mut bytes = [0u8; 50];
            for (slot, b) in bytes.iter_mut().zip(text.bytes()) {
                *slot = b;
            }
            MavMessage::STATUSTEXT(mav::STATUSTEXT_DATA {
                severity: severity_from(*severity),
                text: bytes.into(),
                ..Default::default()
            })
        }
    }
}

fn severity_from(n: u8) -> MavSeverity {
    use MavSeverity::*;
    [
        MAV_SEVERITY_EMERGENCY,
        MAV_SEVERITY_ALERT,
        MAV_SEVERITY_CRITICAL,
        MAV_SEVERITY_ERROR,
        MAV_SEVERITY_WARNING,
        MAV_SEVERITY_NOTICE,
        MAV_SEVERITY_INFO,
        MAV_SEVERITY_DEBUG,
    ]
    .get(usize::from(n))
    .copied()
    .unwrap_or(MAV_SEVERITY_INFO)
}

/// A message whose rate is requested.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamRequest {
    pub message_id: u32,
    pub name: &'static str,
    /// Interval between messages (MAV_CMD_SET_MESSAGE_INTERVAL param2).
    pub interval_us: u32,
}

impl StreamRequest {
    /// A request for message `M` at `rate_hz`.
    pub fn of<M: MessageData>(rate_hz: f64) -> StreamRequest {
        StreamRequest {
            message_id: M::ID,
            name: M::NAME,
            interval_us: (1e6 / rate_hz).round() as u32,
        }
    }
}

/// What emplan asks for on connect: battery and position at 10 Hz (for the integral and the
/// 4 m crossing), mission progress and landed state at 2 Hz. HEARTBEAT and MISSION_ITEM_REACHED
/// are not streams (sent at 1 Hz and on events) and are not requested.
pub fn default_streams() -> Vec<StreamRequest> {
    vec![
        StreamRequest::of::<mav::BATTERY_STATUS_DATA>(10.0),
        StreamRequest::of::<mav::SYS_STATUS_DATA>(10.0),
        StreamRequest::of::<mav::GLOBAL_POSITION_INT_DATA>(10.0),
        StreamRequest::of::<mav::LOCAL_POSITION_NED_DATA>(10.0),
        // 10 Hz: a leg begins when the item changes; a lost change is caught by the next one.
        StreamRequest::of::<mav::MISSION_CURRENT_DATA>(10.0),
        StreamRequest::of::<mav::EXTENDED_SYS_STATE_DATA>(2.0),
    ]
}

/// How a rate request ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RequestOutcome {
    Pending,
    Accepted,
    /// The autopilot answered with a refusal (DENIED, UNSUPPORTED, FAILED, ...), by name.
    Refused {
        result: String,
    },
    /// No COMMAND_ACK after every attempt.
    NoAck {
        attempts: u32,
    },
}

/// Timing and addressing of the rate requests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamConfig {
    pub target_system: u8,
    pub target_component: u8,
    /// Who we are: acks addressed to another ground station are not ours.
    pub own_system: u8,
    pub own_component: u8,
    /// Wait for an ack before resending.
    pub timeout: Duration,
    /// Resends after the first attempt before giving up on one message.
    pub retries: u32,
    /// After an ack, wait this long before the next request and ignore acks meanwhile: a
    /// COMMAND_ACK does not say which message it is for, so a duplicated ack must not be taken
    /// for the next request's.
    pub quiet: Duration,
}

impl Default for StreamConfig {
    fn default() -> Self {
        StreamConfig {
            target_system: 1,
            target_component: 1,
            own_system: 255,
            own_component: 190,
            timeout: Duration::from_secs(1),
            retries: 5,
            quiet: Duration::from_millis(200),
        }
    }
}

/// Counters of what the requests saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StreamStats {
    pub sent: u32,
    /// Acks that arrived while no request was outstanding (duplicates, late answers).
    pub ignored_acks: u32,
}

/// Requests stream rates with MAV_CMD_SET_MESSAGE_INTERVAL, one message at a time (an ack does
/// not name the message it answers), resending each until its COMMAND_ACK; a refusal is
/// recorded and the next message asked for. `restart` asks for all again (after a reconnect:
/// rates are per link and reset on reboot). Sans-IO: `start`, `handle`, `tick` return the
/// messages to send.
#[derive(Debug, Clone)]
pub struct StreamRequests {
    cfg: StreamConfig,
    wanted: Vec<StreamRequest>,
    outcomes: Vec<RequestOutcome>,
    /// The request outstanding, its attempts so far and resend deadline.
    current: Option<(usize, u32, Duration)>,
    /// The next request to send and when.
    next: Option<(usize, Duration)>,
    pub stats: StreamStats,
}

impl StreamRequests {
    pub fn new(cfg: StreamConfig, wanted: Vec<StreamRequest>) -> StreamRequests {
        let outcomes = vec![RequestOutcome::Pending; wanted.len()];
        StreamRequests {
            cfg,
            wanted,
            outcomes,
            current: None,
            next: None,
            stats: StreamStats::default(),
        }
    }

    /// Every request with its outcome so far.
    pub fn outcomes(&self) -> Vec<(StreamRequest, RequestOutcome)> {
        self.wanted
            .iter()
            .copied()
            .zip(self.outcomes.iter().cloned())
            .collect()
    }

    /// Names of the messages whose rate the autopilot accepted.
    pub fn accepted(&self) -> Vec<&'static str> {
        self.outcomes()
            .into_iter()
            .filter(|(_, o)| *o == RequestOutcome::Accepted)
            .map(|(r, _)| r.name)
            .collect()
    }

    /// Whether every request has an outcome.
    pub fn finished(&self) -> bool {
        self.current.is_none() && self.next.is_none()
    }

    fn command(&self, index: usize, confirmation: u32) -> MavMessage {
        let request = self.wanted[index];
        MavMessage::COMMAND_LONG(mav::COMMAND_LONG_DATA {
            param1: request.message_id as f32,
            param2: request.interval_us as f32,
            // param7 0: the flight stack's default target (MAVLink SET_MESSAGE_INTERVAL).
            command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            target_system: self.cfg.target_system,
            target_component: self.cfg.target_component,
            confirmation: confirmation.min(255) as u8,
            ..Default::default()
        })
    }

    fn send(&mut self, now: Duration, index: usize, attempts: u32) -> Vec<MavMessage> {
        self.current = Some((index, attempts + 1, now + self.cfg.timeout));
        self.stats.sent += 1;
        vec![self.command(index, attempts)]
    }

    /// Sends the first request.
    pub fn start(&mut self, now: Duration) -> Vec<MavMessage> {
        self.current = None;
        self.next = None;
        if self.wanted.is_empty() {
            return Vec::new();
        }
        self.send(now, 0, 0)
    }

    /// Forgets every outcome and asks for all again (after a reconnect).
    pub fn restart(&mut self, now: Duration) -> Vec<MavMessage> {
        self.outcomes = vec![RequestOutcome::Pending; self.wanted.len()];
        self.start(now)
    }

    fn settle(&mut self, now: Duration, index: usize, outcome: RequestOutcome) -> Vec<MavMessage> {
        self.outcomes[index] = outcome;
        self.current = None;
        self.next = (index + 1 < self.wanted.len()).then_some((index + 1, now + self.cfg.quiet));
        self.tick(now)
    }

    /// Takes in a message from the autopilot; only COMMAND_ACKs of SET_MESSAGE_INTERVAL matter.
    pub fn handle(&mut self, now: Duration, message: &MavMessage) -> Vec<MavMessage> {
        let MavMessage::COMMAND_ACK(ack) = message else {
            return Vec::new();
        };
        if ack.command != MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL {
            return Vec::new();
        }
        let for_other = (ack.target_system != 0 && ack.target_system != self.cfg.own_system)
            || (ack.target_component != 0 && ack.target_component != self.cfg.own_component);
        if for_other {
            return Vec::new();
        }
        let Some((index, attempts, _)) = self.current else {
            self.stats.ignored_acks += 1;
            return Vec::new();
        };
        match ack.result {
            MavResult::MAV_RESULT_ACCEPTED => self.settle(now, index, RequestOutcome::Accepted),
            MavResult::MAV_RESULT_IN_PROGRESS => {
                self.current = Some((index, attempts, now + self.cfg.timeout));
                Vec::new()
            }
            // Try again at the deadline.
            MavResult::MAV_RESULT_TEMPORARILY_REJECTED => Vec::new(),
            refused => self.settle(
                now,
                index,
                RequestOutcome::Refused {
                    result: format!("{refused:?}"),
                },
            ),
        }
    }

    /// Resends on timeout, gives up after the retries, and sends the next request when its
    /// quiet time has passed.
    pub fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        if let Some((index, attempts, deadline)) = self.current {
            if now < deadline {
                return Vec::new();
            }
            if attempts <= self.cfg.retries {
                return self.send(now, index, attempts);
            }
            return self.settle(now, index, RequestOutcome::NoAck { attempts });
        }
        match self.next {
            Some((index, at)) if now >= at => {
                self.next = None;
                self.send(now, index, 0)
            }
            _ => Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vehicle() -> MavHeader {
        MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: 0,
        }
    }

    #[test]
    fn check_frame_passes_whole_frames_fails_a_flipped_byte_and_knows_no_foreign_id() {
        let message = MavMessage::HEARTBEAT(mav::HEARTBEAT_DATA::default());
        let v2 = frame_bytes(&vehicle(), &message);
        assert_eq!(check_frame(&v2), FrameCheck::Valid);
        let v1 = frame_bytes_versioned(&vehicle(), &message, MavlinkVersion::V1).expect("v1");
        assert_eq!(check_frame(&v1), FrameCheck::Valid);
        for frame in [&v2, &v1] {
            for k in 1..frame.len() {
                let mut flipped = frame.clone();
                flipped[k] ^= 0x10;
                assert_ne!(check_frame(&flipped), FrameCheck::Valid, "byte {k}");
            }
        }
        // A message id no dialect here defines (0xABCDEF): its checksum cannot be judged.
        let mut foreign = v2.clone();
        foreign[7..10].copy_from_slice(&[0xEF, 0xCD, 0xAB]);
        assert_eq!(check_frame(&foreign), FrameCheck::UnknownMessage);
        // Too short to hold its own checksum: never a panic.
        assert_eq!(check_frame(&v2[..5]), FrameCheck::BadCrc);
        assert_eq!(check_frame(&[]), FrameCheck::BadCrc);
    }

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

    #[test]
    fn encode_then_decode_gives_the_reading_back() {
        let readings = [
            Reading::Battery(Battery {
                source: BatterySource::BatteryStatus {
                    id: 0,
                    component: 1,
                },
                voltage_v: Some(71.234),
                current_a: Some(123.45),
                consumed_mah: Some(3210.0),
                energy_consumed_j: Some(45_600.0),
                remaining_pct: Some(64.0),
                fake_current: false,
            }),
            Reading::Battery(Battery {
                source: BatterySource::SysStatus,
                voltage_v: Some(22.8),
                current_a: None,
                consumed_mah: None,
                energy_consumed_j: None,
                remaining_pct: None,
                fake_current: false,
            }),
            Reading::MissionCurrent {
                seq: 3,
                total: Some(12),
                state: MissionState::Active,
            },
            Reading::ItemReached { seq: 3 },
            Reading::Heartbeat {
                armed: true,
                mode: FlightMode::Land,
            },
            Reading::Landed(LandedState::Landing),
            Reading::StatusText {
                severity: 6,
                text: "Reached command #3".into(),
            },
        ];
        for flavour in [Flavour::Px4, Flavour::ArduPilot] {
            for r in &readings {
                let frame = frame_bytes(&vehicle(), &encode(r, flavour));
                let (header, message) = parse_frame(&frame).expect("a frame");
                let back = decode(&header, &message).reading.expect("a reading");
                assert_eq!(&back, r, "{flavour:?}");
            }
        }
    }

    #[test]
    fn mavlink_1_and_signed_mavlink_2_frames_parse_like_plain_ones() {
        let message = encode(&Reading::ItemReached { seq: 7 }, Flavour::Px4);
        let v1 = frame_bytes_versioned(&vehicle(), &message, MavlinkVersion::V1).expect("v1");
        assert_eq!(v1[0], 0xFE);
        let (_, back) = parse_frame(&v1).expect("v1 parses");
        assert_eq!(back, message);
        let signing = mavlink::SigningData::from_config(mavlink::SigningConfig::new(
            [7u8; 32], 0, true, false,
        ));
        let mut signed = Vec::new();
        mavlink::write_v2_msg_signed(&mut signed, vehicle(), &message, Some(&signing))
            .expect("signed");
        assert_eq!(signed[2] & 1, 1, "signed flag set");
        let (_, back) = parse_frame(&signed).expect("signed parses");
        assert_eq!(back, message);
        let mut broken = frame_bytes(&vehicle(), &message);
        let last = broken.len() - 1;
        broken[last] ^= 0xFF;
        assert!(parse_frame(&broken).is_err(), "a bad checksum is refused");
    }

    #[test]
    fn the_pipeline_stamps_battery_readings_with_vehicle_time_between_positions() {
        let mut telemetry = Telemetry::new();
        let start = 1_700_000_000_000_000u64;
        let mut cells = NONE10;
        cells[0] = 22_000;
        let battery = MavMessage::BATTERY_STATUS(mav::BATTERY_STATUS_DATA {
            voltages: cells,
            current_battery: 4000,
            ..Default::default()
        });
        let mut last = None;
        for k in 0..40u32 {
            // 10x speed-up: 100 ms of vehicle time every 10 ms of wall time.
            let wall = start + u64::from(k) * 10_000;
            let position = MavMessage::GLOBAL_POSITION_INT(mav::GLOBAL_POSITION_INT_DATA {
                time_boot_ms: 60_000 + k * 100,
                lat: 385_362_000,
                lon: -1_217_875_000,
                ..Default::default()
            });
            telemetry.message(wall, &vehicle(), &position);
            last = telemetry.message(wall + 5_000, &vehicle(), &battery);
        }
        let last = last.expect("a stamped battery reading");
        assert!((last.t_s - 3.95).abs() < 0.01, "t {}", last.t_s);
        assert!(matches!(last.reading, Reading::Battery(_)));
    }

    fn ack(result: MavResult) -> MavMessage {
        MavMessage::COMMAND_ACK(mav::COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            result,
            target_system: 255,
            target_component: 190,
            ..Default::default()
        })
    }

    fn requested(messages: &[MavMessage]) -> Vec<(u32, u8)> {
        messages
            .iter()
            .filter_map(|m| match m {
                MavMessage::COMMAND_LONG(c)
                    if c.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL =>
                {
                    Some((c.param1 as u32, c.confirmation))
                }
                _ => None,
            })
            .collect()
    }

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn requests_go_one_at_a_time_each_after_the_previous_ack_and_a_quiet_time() {
        let wanted = default_streams();
        let mut m = StreamRequests::new(StreamConfig::default(), wanted.clone());
        let first = m.start(Duration::ZERO);
        assert_eq!(requested(&first), vec![(147, 0)]);
        let MavMessage::COMMAND_LONG(c) = &first[0] else {
            panic!("a command");
        };
        assert_eq!(
            (c.param2, c.target_system, c.target_component),
            (100_000.0, 1, 1)
        );
        let mut now = Duration::ZERO;
        let mut sent = vec![147];
        for _ in 1..wanted.len() {
            now += 5 * MS;
            assert!(m
                .handle(now, &ack(MavResult::MAV_RESULT_ACCEPTED))
                .is_empty());
            assert!(m.tick(now + 199 * MS).is_empty(), "still quiet");
            now += 200 * MS;
            let next = requested(&m.tick(now));
            assert_eq!(next.len(), 1);
            sent.push(next[0].0);
        }
        m.handle(now + MS, &ack(MavResult::MAV_RESULT_ACCEPTED));
        assert!(m.finished());
        assert_eq!(
            sent,
            wanted.iter().map(|w| w.message_id).collect::<Vec<_>>()
        );
        assert_eq!(m.accepted().len(), wanted.len());
    }

    #[test]
    fn a_request_without_ack_is_resent_with_a_higher_confirmation_then_given_up() {
        let wanted = default_streams();
        let mut m = StreamRequests::new(StreamConfig::default(), wanted[..2].to_vec());
        m.start(Duration::ZERO);
        let mut confirmations = vec![0];
        for k in 1..=5u64 {
            let again = requested(&m.tick(Duration::from_secs(k)));
            assert_eq!(again.len(), 1);
            assert_eq!(again[0].0, 147);
            confirmations.push(again[0].1);
        }
        assert_eq!(confirmations, vec![0, 1, 2, 3, 4, 5]);
        // The sixth wait ends it: no ack after six attempts; the next message is asked for.
        assert!(m.tick(Duration::from_secs(6)).is_empty());
        assert_eq!(m.outcomes()[0].1, RequestOutcome::NoAck { attempts: 6 });
        let next = requested(&m.tick(Duration::from_secs(6) + 200 * MS));
        assert_eq!(next, vec![(1, 0)]);
    }

    #[test]
    fn a_refused_request_is_recorded_and_the_next_one_is_asked_for() {
        let mut m = StreamRequests::new(StreamConfig::default(), default_streams());
        m.start(Duration::ZERO);
        m.handle(MS, &ack(MavResult::MAV_RESULT_UNSUPPORTED));
        assert_eq!(
            m.outcomes()[0].1,
            RequestOutcome::Refused {
                result: "MAV_RESULT_UNSUPPORTED".into()
            }
        );
        assert_eq!(requested(&m.tick(300 * MS)), vec![(1, 0)]);
        m.handle(301 * MS, &ack(MavResult::MAV_RESULT_DENIED));
        assert!(matches!(m.outcomes()[1].1, RequestOutcome::Refused { .. }));
        assert!(m.accepted().is_empty());
    }

    #[test]
    fn a_duplicated_ack_is_not_taken_for_the_next_requests_answer() {
        let mut m = StreamRequests::new(StreamConfig::default(), default_streams());
        m.start(Duration::ZERO);
        m.handle(2 * MS, &ack(MavResult::MAV_RESULT_ACCEPTED));
        // The transport duplicates the ack; it arrives in the quiet time and is ignored.
        m.handle(3 * MS, &ack(MavResult::MAV_RESULT_ACCEPTED));
        assert_eq!(m.stats.ignored_acks, 1);
        assert_eq!(requested(&m.tick(205 * MS)), vec![(1, 0)]);
        // SYS_STATUS is refused by its own ack.
        m.handle(207 * MS, &ack(MavResult::MAV_RESULT_UNSUPPORTED));
        let outcomes = m.outcomes();
        assert_eq!(outcomes[0].1, RequestOutcome::Accepted);
        assert!(matches!(outcomes[1].1, RequestOutcome::Refused { .. }));
    }

    #[test]
    fn acks_of_other_commands_or_for_another_station_are_ignored() {
        let mut m = StreamRequests::new(StreamConfig::default(), default_streams());
        m.start(Duration::ZERO);
        let other_command = MavMessage::COMMAND_ACK(mav::COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            result: MavResult::MAV_RESULT_ACCEPTED,
            ..Default::default()
        });
        let other_station = MavMessage::COMMAND_ACK(mav::COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            result: MavResult::MAV_RESULT_ACCEPTED,
            target_system: 254,
            ..Default::default()
        });
        m.handle(MS, &other_command);
        m.handle(MS, &other_station);
        assert_eq!(m.outcomes()[0].1, RequestOutcome::Pending);
        assert_eq!(requested(&m.tick(Duration::from_secs(1))), vec![(147, 1)]);
    }

    #[test]
    fn in_progress_extends_the_wait_and_temporarily_rejected_retries_at_the_deadline() {
        let mut m = StreamRequests::new(StreamConfig::default(), default_streams());
        m.start(Duration::ZERO);
        m.handle(900 * MS, &ack(MavResult::MAV_RESULT_IN_PROGRESS));
        assert!(
            m.tick(Duration::from_millis(1500)).is_empty(),
            "still waiting"
        );
        m.handle(1600 * MS, &ack(MavResult::MAV_RESULT_TEMPORARILY_REJECTED));
        assert_eq!(
            requested(&m.tick(Duration::from_millis(1900))),
            vec![(147, 1)]
        );
        m.handle(1950 * MS, &ack(MavResult::MAV_RESULT_ACCEPTED));
        assert_eq!(m.outcomes()[0].1, RequestOutcome::Accepted);
    }

    #[test]
    fn restart_asks_for_every_stream_again() {
        let mut m = StreamRequests::new(StreamConfig::default(), default_streams()[..2].to_vec());
        m.start(Duration::ZERO);
        m.handle(MS, &ack(MavResult::MAV_RESULT_ACCEPTED));
        m.tick(300 * MS);
        m.handle(301 * MS, &ack(MavResult::MAV_RESULT_ACCEPTED));
        assert!(m.finished() && m.accepted().len() == 2);
        let again = m.restart(Duration::from_secs(10));
        assert_eq!(requested(&again), vec![(147, 0)]);
        assert!(!m.finished());
        assert!(m
            .outcomes()
            .iter()
            .all(|(_, o)| *o != RequestOutcome::Accepted));
    }
}
