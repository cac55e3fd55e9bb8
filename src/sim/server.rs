//! The mission protocol's vehicle side as a sans-IO state machine that behaves as the autopilot
//! of its flavour does, never kinder (the mock autopilot must be as strict as PX4):
//!
//! - PX4 (`mavlink_mission.cpp`): requests items with MISSION_REQUEST_INT, re-requests every
//!   250 ms, abandons a transfer after 5 s without hearing from the ground (no ack); an upload is
//!   atomic (a failed one leaves the previous mission); the final ack is sent once, and again
//!   only when the last item arrives again; a COUNT during an upload is refused with
//!   MAV_MISSION_ERROR; a download must request the items in order (else MAV_MISSION_ERROR and
//!   the download ends) and lives until acked or 5 s of silence; read-backs answer global items
//!   in the `_INT` frames; unsupported commands and frames are NACKed.
//! - ArduPilot (`MissionItemProtocol.cpp`, `AP_Mission.cpp`): requests with the legacy
//!   MISSION_REQUEST every second, cancels an upload after 8 s without an item
//!   (MAV_MISSION_OPERATION_CANCELLED), answers an out-of-order item with
//!   MAV_MISSION_INVALID_SEQUENCE, writes items as they arrive (not atomic), defers the final
//!   ack 0.5 s (its mission checksum) and refuses read-backs meanwhile (MAV_MISSION_DENIED),
//!   answers any read-back request from storage, item 0 being its own home, and refuses uploads
//!   with MAV_MISSION_NO_SPACE while its storage boots.
//! - Generic, as MAVSDK's MissionRawServer (`mavlink_mission_transfer_server.cpp`): requests
//!   every 0.5 s and gives up silently after 5 requests; a download sends each item at most 5
//!   times and is given up after 5 half-second timeouts; requests beyond the next item, a COUNT
//!   during an upload and a REQUEST_LIST during a download are ignored; items kept as received.
//!
//! Beside the mission each flavour holds a fence and rally points as PX4 and ArduPilot do,
//! through the same protocol with MISSION_TYPE_FENCE and _RALLY (PX4 `MavlinkMissionManager`,
//! one transfer of one type at a time; ArduPilot `MissionItemProtocol_Fence`, `_Rally`): they
//! declare it in AUTOPILOT_VERSION (MAV_PROTOCOL_CAPABILITY_MISSION_FENCE and _RALLY), which
//! the server answers a request for. The generic flavour, like MAVSDK's MissionRawServer,
//! holds only a mission and declares neither. ArduPilot's deferred final ack (its mission
//! checksum) and its item 0 being home are the mission's only.
//!
//! What each flavour stores of an item is `sim::storage`.

use std::time::Duration;

use mavlink::MessageData;

use super::storage::{fence_rally_supported, stored, stored_fence_rally, Home};
#[allow(deprecated)]
use crate::link::mav::{
    MavCmd, MavFrame, MavMessage, MavMissionResult, MavMissionType, MavProtocolCapability,
    MavResult, AUTOPILOT_VERSION_DATA, COMMAND_ACK_DATA, MISSION_ACK_DATA, MISSION_COUNT_DATA,
    MISSION_CURRENT_DATA, MISSION_ITEM_INT_DATA, MISSION_REQUEST_DATA, MISSION_REQUEST_INT_DATA,
};
use crate::link::Flavour;

/// Most items stored (PX4's dataman holds thousands; a bound keeps hostile counts out).
pub const MAX_ITEMS: u16 = 2000;

const MISSION: MavMissionType = MavMissionType::MAV_MISSION_TYPE_MISSION;
const FENCE: MavMissionType = MavMissionType::MAV_MISSION_TYPE_FENCE;
const RALLY: MavMissionType = MavMissionType::MAV_MISSION_TYPE_RALLY;

/// PX4 gives up a transfer after 5 s without hearing from the ground
/// (`MAVLINK_MISSION_PROTOCOL_TIMEOUT_DEFAULT`).
const PX4_ABANDON: Duration = Duration::from_secs(5);
/// ArduPilot cancels an upload 8 s after the last item (`upload_timeout_ms = 8000`).
const ARDUPILOT_ABANDON: Duration = Duration::from_secs(8);
/// ArduPilot's final ack waits for its mission checksum, computed once the mission has been
/// unchanged for 500 ms (`MissionItemProtocol::update_checksum`).
const ARDUPILOT_ACK_DELAY: Duration = Duration::from_millis(500);
/// MAVSDK's transfers try 5 times (`retries = 5`).
const MAVSDK_RETRIES: u32 = 5;

/// Injected protocol faults (transport faults live in the async shell).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ProtocolFaults {
    /// NACK the upload when this item arrives.
    pub nack_item: Option<u16>,
    /// The result that NACK carries.
    pub nack_result: Option<MavMissionResult>,
    /// Never send the final ACCEPTED ack.
    pub drop_final_ack: bool,
    /// Lose the transfer state (a reboot) when this item arrives; the stored mission survives.
    pub reboot_at_item: Option<u16>,
    /// Answer read-backs of this item with its latitude 1 degE7 off (a vehicle holding
    /// something else than was sent).
    pub corrupt_readback: Option<u16>,
}

/// How the server behaves beyond its flavour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServerConfig {
    pub faults: ProtocolFaults,
    /// The vehicle's home (ArduPilot answers it for item 0).
    pub home: Home,
    /// ArduPilot refuses uploads with MAV_MISSION_NO_SPACE this long after boot (its storage
    /// is not ready: about 10 s on ArduCopter SITL).
    pub boot: Duration,
}

impl Default for ServerConfig {
    fn default() -> Self {
        ServerConfig {
            faults: ProtocolFaults::default(),
            home: Home::default(),
            boot: Duration::ZERO,
        }
    }
}

#[derive(Debug, Clone)]
struct Receiving {
    mission_type: MavMissionType,
    count: u16,
    items: Vec<MISSION_ITEM_INT_DATA>,
    last_request: Duration,
    /// PX4: anything received; ArduPilot: the last item accepted.
    last_progress: Duration,
    /// MAVSDK: requests sent for the current item.
    requests: u32,
}

#[derive(Debug, Clone, Copy)]
struct Sending {
    mission_type: MavMissionType,
    count: u16,
    /// PX4 `_transfer_seq`, MAVSDK `_next_sequence`: the item after the last one sent.
    next: u16,
    last_heard: Duration,
    /// MAVSDK: sends of the current item, timeouts included (`_retries_done`).
    retries: u32,
    first_request_seen: bool,
}

/// What the server has done (for tests and reports).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ServerStats {
    /// Missions stored (fence and rally uploads are not counted: a ground station that starts
    /// each newly stored mission must not start it again for its fence).
    pub uploads_accepted: u32,
    pub uploads_rejected: u32,
    pub uploads_abandoned: u32,
    pub downloads_abandoned: u32,
    pub rerequests: u32,
    pub reboots: u32,
    /// Uploads refused while booting (ArduPilot's MAV_MISSION_NO_SPACE).
    pub boot_refusals: u32,
}

/// ArduPilot's fence check of the vehicle's position (`AC_Fence::check`, the polygon and
/// circle zones of `AC_PolyFence_loader::breached`: outside any inclusion zone or inside any
/// exclusion zone is a breach) and what it reports of it in FENCE_STATUS
/// (`GCS_MAVLINK::send_fence_status`: sent only while a fence is enabled, in the extended
/// status stream). The mock's fence is enabled whenever it holds a zone (ArduPilot also needs
/// FENCE_ENABLE). PX4 streams no FENCE_STATUS (its mavlink module has no such stream), so the
/// PX4 and generic flavours report nothing.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FenceMonitor {
    breached: bool,
    count: u16,
    breach_time_ms: u32,
}

/// The vehicle side of the mission protocol.
#[derive(Debug, Clone)]
pub struct MissionServer {
    flavour: Flavour,
    cfg: ServerConfig,
    /// The mission as received (what it answers is `storage::stored` of it).
    mission: Vec<MISSION_ITEM_INT_DATA>,
    /// The fence and the rally points as received (answered as `storage::stored_fence_rally`).
    fence: Vec<MISSION_ITEM_INT_DATA>,
    rally: Vec<MISSION_ITEM_INT_DATA>,
    revision: u64,
    receiving: Option<Receiving>,
    sending: Option<Sending>,
    /// ArduPilot: when the deferred final ack goes out.
    pending_ack: Option<Duration>,
    /// PX4: the type and item count of the upload completed last (a repeat of its last item is
    /// acked).
    completed: Option<(MavMissionType, u16)>,
    /// (system, component) of the ground station being answered.
    gcs: (u8, u8),
    /// The fence check's state (ArduPilot's breach count and time).
    fence_monitor: FenceMonitor,
    /// The current item (MISSION_SET_CURRENT), where a flight would resume.
    current: u16,
    pub stats: ServerStats,
}

/// Whether the flavour takes `item`, and if not the MISSION_ACK it refuses it with.
/// - PX4 (`parse_mavlink_mission_item`): a global frame takes the commands with a position, and
///   DO_SET_ROI only in the modes none and location; MAV_FRAME_MISSION the commands without
///   one, and DO_SET_ROI only in the modes none, next waypoint and waypoint index
///   (MAV_MISSION_INVALID_PARAM1 otherwise); another command in either is
///   MAV_MISSION_UNSUPPORTED (CONDITION_YAW, DO_SET_SERVO, DO_SET_RELAY, NAV_SPLINE_WAYPOINT
///   always), another frame MAV_MISSION_UNSUPPORTED_FRAME.
/// - ArduPilot (`mavlink_int_to_mission_cmd`): every command it has a case for; the frame is
///   checked only for one it stores a location for (global frames and MAV_FRAME_MISSION).
/// - Generic (MAVSDK's MissionRawServer): any command, in a global frame or MAV_FRAME_MISSION.
#[allow(deprecated)]
fn supported(flavour: Flavour, item: &MISSION_ITEM_INT_DATA) -> Result<(), MavMissionResult> {
    use super::storage::{ardupilot_located, ardupilot_takes, px4_global_frame, px4_mission_frame};
    use MavCmd::*;
    use MavFrame::*;
    use MavMissionResult::*;
    let navigation = super::storage::navigation(item.command);
    let global = matches!(
        item.frame,
        MAV_FRAME_GLOBAL
            | MAV_FRAME_GLOBAL_RELATIVE_ALT
            | MAV_FRAME_GLOBAL_INT
            | MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    );
    let mission_frame = item.frame == MAV_FRAME_MISSION;
    let ardupilot_home = flavour == Flavour::ArduPilot && item.seq == 0;
    let roi_mode = item.param1 as i32;
    match flavour {
        Flavour::Px4 if global => {
            if !px4_global_frame(item.command) {
                return Err(MAV_MISSION_UNSUPPORTED);
            }
            // MAV_ROI_NONE 0, MAV_ROI_LOCATION 3.
            if item.command == MAV_CMD_DO_SET_ROI && !matches!(roi_mode, 0 | 3) {
                return Err(MAV_MISSION_INVALID_PARAM1);
            }
        }
        Flavour::Px4 if mission_frame => {
            if !px4_mission_frame(item.command) {
                return Err(MAV_MISSION_UNSUPPORTED);
            }
            // MAV_ROI_NONE 0, MAV_ROI_WPNEXT 1, MAV_ROI_WPINDEX 2.
            if item.command == MAV_CMD_DO_SET_ROI && !matches!(roi_mode, 0..=2) {
                return Err(MAV_MISSION_INVALID_PARAM1);
            }
        }
        Flavour::Px4 => return Err(MAV_MISSION_UNSUPPORTED_FRAME),
        Flavour::ArduPilot => {
            if !ardupilot_takes(item.command) {
                return Err(MAV_MISSION_UNSUPPORTED);
            }
            if ardupilot_located(item.command) && !(global || mission_frame || ardupilot_home) {
                return Err(MAV_MISSION_UNSUPPORTED_FRAME);
            }
        }
        Flavour::Generic if !(global || mission_frame) => {
            return Err(MAV_MISSION_UNSUPPORTED_FRAME)
        }
        Flavour::Generic => {}
    }
    if navigation
        && (item.x == 0 && item.y == 0)
        && item.command != MAV_CMD_NAV_LAND
        && item.command != MAV_CMD_NAV_TAKEOFF
    {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM5_X);
    }
    if !item.z.is_finite() {
        return Err(MavMissionResult::MAV_MISSION_INVALID_PARAM7);
    }
    // ArduPilot refuses NaN except in param4 of waypoints, takeoffs and landings
    // (AP_Mission::sanity_check_params).
    if flavour == Flavour::ArduPilot {
        let nan4_ok = matches!(
            item.command,
            MAV_CMD_NAV_WAYPOINT | MAV_CMD_NAV_TAKEOFF | MAV_CMD_NAV_LAND
        );
        let p = [item.param1, item.param2, item.param3, item.param4];
        let results = [
            MavMissionResult::MAV_MISSION_INVALID_PARAM1,
            MavMissionResult::MAV_MISSION_INVALID_PARAM2,
            MavMissionResult::MAV_MISSION_INVALID_PARAM3,
            MavMissionResult::MAV_MISSION_INVALID_PARAM4,
        ];
        for (k, v) in p.iter().enumerate() {
            if v.is_infinite() || (v.is_nan() && !(k == 3 && nan4_ok)) {
                return Err(results[k]);
            }
        }
    }
    Ok(())
}

impl MissionServer {
    /// A server of `flavour` with an empty mission.
    pub fn new(flavour: Flavour, cfg: ServerConfig) -> MissionServer {
        MissionServer {
            flavour,
            cfg,
            mission: Vec::new(),
            fence: Vec::new(),
            rally: Vec::new(),
            revision: 0,
            receiving: None,
            sending: None,
            pending_ack: None,
            completed: None,
            gcs: (255, 190),
            fence_monitor: FenceMonitor::default(),
            current: 0,
            stats: ServerStats::default(),
        }
    }

    /// The current item (where a flight would resume).
    pub fn current(&self) -> u16 {
        self.current
    }

    /// The stored mission, as received.
    pub fn mission(&self) -> &[MISSION_ITEM_INT_DATA] {
        &self.mission
    }

    /// The stored fence, as received.
    pub fn fence(&self) -> &[MISSION_ITEM_INT_DATA] {
        &self.fence
    }

    /// The stored rally points, as received.
    pub fn rally(&self) -> &[MISSION_ITEM_INT_DATA] {
        &self.rally
    }

    /// The rally points the vehicle holds, as its flavour stores them (ArduPilot: whole metres),
    /// for the simulated vehicle's return.
    pub fn rally_points(&self) -> Vec<crate::mission::fence::RallyPoint> {
        let held: Vec<MISSION_ITEM_INT_DATA> = self
            .rally
            .iter()
            .map(|it| stored_fence_rally(self.flavour, true, it))
            .collect();
        crate::link::fence::rally_of_items(&held).unwrap_or_default()
    }

    /// The fence the vehicle holds (its zones and breach return), for the simulated vehicle's
    /// fence check.
    pub fn fence_zones(&self) -> crate::mission::fence::Fence {
        crate::link::fence::fence_of_items(&self.fence).unwrap_or_default()
    }

    /// The FENCE_STATUS an ArduPilot holding this fence sends with the vehicle `east_north_m`
    /// from `home` at `time_boot_ms` (None: no fence enabled, or a flavour that sends none).
    pub fn fence_status(
        &mut self,
        time_boot_ms: u32,
        home: crate::mission::Geodetic,
        east_north_m: [f64; 2],
    ) -> Option<MavMessage> {
        use crate::link::mav::{FenceBreach, FenceMitigate, FENCE_STATUS_DATA};
        if self.flavour != Flavour::ArduPilot {
            return None;
        }
        let fence = self.fence_zones();
        if fence.is_empty() {
            return None;
        }
        let origin = crate::mission::Origin {
            home,
            height_above_home_m: 0.0,
        };
        let breached = (fence.zones.iter()).any(|z| z.local(&origin).violated_by(east_north_m));
        let m = &mut self.fence_monitor;
        if breached && !m.breached {
            m.count = m.count.saturating_add(1);
            m.breach_time_ms = time_boot_ms;
        }
        m.breached = breached;
        Some(MavMessage::FENCE_STATUS(FENCE_STATUS_DATA {
            breach_time: m.breach_time_ms,
            breach_count: m.count,
            breach_status: u8::from(breached),
            breach_type: if m.count > 0 {
                FenceBreach::FENCE_BREACH_BOUNDARY
            } else {
                FenceBreach::FENCE_BREACH_NONE
            },
            breach_mitigation: FenceMitigate::FENCE_MITIGATE_UNKNOWN,
        }))
    }

    /// Changes whenever a stored list (mission, fence, rally points) does.
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// Whether this flavour holds a list of `mission_type`.
    fn holds(&self, mission_type: MavMissionType) -> bool {
        match mission_type {
            MISSION => true,
            FENCE | RALLY => self.flavour != Flavour::Generic,
            _ => false,
        }
    }

    fn list(&self, mission_type: MavMissionType) -> &Vec<MISSION_ITEM_INT_DATA> {
        match mission_type {
            FENCE => &self.fence,
            RALLY => &self.rally,
            _ => &self.mission,
        }
    }

    fn list_mut(&mut self, mission_type: MavMissionType) -> &mut Vec<MISSION_ITEM_INT_DATA> {
        match mission_type {
            FENCE => &mut self.fence,
            RALLY => &mut self.rally,
            _ => &mut self.mission,
        }
    }

    /// The capabilities this flavour declares in AUTOPILOT_VERSION (PX4
    /// `send_autopilot_capabilities`, ArduPilot `GCS_MAVLINK::capabilities`: fence and rally in
    /// a copter build; MAVSDK's server: a mission in MISSION_ITEM_INT only).
    pub fn capabilities(&self) -> MavProtocolCapability {
        let mut bits = MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_INT
            | MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MAVLINK2;
        if self.holds(FENCE) {
            bits |= MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_FENCE;
        }
        if self.holds(RALLY) {
            bits |= MavProtocolCapability::MAV_PROTOCOL_CAPABILITY_MISSION_RALLY;
        }
        bits
    }

    /// The answer to a request for AUTOPILOT_VERSION (MAV_CMD_REQUEST_MESSAGE 148 or
    /// MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES): the ack, then the message.
    #[allow(deprecated)]
    fn version_answer(&self, from: (u8, u8), message: &MavMessage) -> Option<Vec<MavMessage>> {
        let MavMessage::COMMAND_LONG(c) = message else {
            return None;
        };
        let asked = (c.command == MavCmd::MAV_CMD_REQUEST_MESSAGE
            && c.param1 == AUTOPILOT_VERSION_DATA::ID as f32)
            || c.command == MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES;
        if !asked {
            return None;
        }
        Some(vec![
            MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                command: c.command,
                result: MavResult::MAV_RESULT_ACCEPTED,
                target_system: from.0,
                target_component: from.1,
                ..Default::default()
            }),
            MavMessage::AUTOPILOT_VERSION(AUTOPILOT_VERSION_DATA {
                capabilities: self.capabilities(),
                ..Default::default()
            }),
        ])
    }

    /// Whether `message` is a request for AUTOPILOT_VERSION, which this server answers (the
    /// simulated vehicle beside it leaves it alone).
    #[allow(deprecated)]
    pub fn answers_version_request(message: &MavMessage) -> bool {
        matches!(message, MavMessage::COMMAND_LONG(c)
            if (c.command == MavCmd::MAV_CMD_REQUEST_MESSAGE
                && c.param1 == AUTOPILOT_VERSION_DATA::ID as f32)
                || c.command == MavCmd::MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES)
    }

    fn ack(&self, result: MavMissionResult, mission_type: MavMissionType) -> MavMessage {
        MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: self.gcs.0,
            target_component: self.gcs.1,
            mavtype: result,
            mission_type,
            opaque_id: 0,
        })
    }

    fn count(&self, mission_type: MavMissionType) -> MavMessage {
        MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: self.list(mission_type).len() as u16,
            target_system: self.gcs.0,
            target_component: self.gcs.1,
            mission_type,
            opaque_id: 0,
        })
    }

    #[allow(deprecated)]
    fn request(&self, seq: u16, mission_type: MavMissionType) -> MavMessage {
        if self.flavour == Flavour::ArduPilot {
            // ArduPilot still requests with the legacy MISSION_REQUEST (queued_request_send).
            return MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
                seq,
                target_system: self.gcs.0,
                target_component: self.gcs.1,
                mission_type,
            });
        }
        MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: self.gcs.0,
            target_component: self.gcs.1,
            mission_type,
        })
    }

    /// Item `seq` as this flavour answers a read-back of it.
    fn item(&self, seq: u16, mission_type: MavMissionType) -> Option<MavMessage> {
        let held = self.list(mission_type).get(usize::from(seq))?;
        let mut item = match mission_type {
            MISSION => stored(self.flavour, held, &self.cfg.home),
            _ => stored_fence_rally(self.flavour, mission_type == RALLY, held),
        };
        if self.cfg.faults.corrupt_readback == Some(seq) {
            item.x = item.x.wrapping_add(1);
        }
        item.target_system = self.gcs.0;
        item.target_component = self.gcs.1;
        item.mission_type = mission_type;
        Some(MavMessage::MISSION_ITEM_INT(item))
    }

    fn store(&mut self, mission_type: MavMissionType, items: Vec<MISSION_ITEM_INT_DATA>) {
        *self.list_mut(mission_type) = items;
        self.revision += 1;
    }

    fn reject(
        &mut self,
        result: MavMissionResult,
        mission_type: MavMissionType,
    ) -> Vec<MavMessage> {
        self.receiving = None;
        self.stats.uploads_rejected += 1;
        vec![self.ack(result, mission_type)]
    }

    /// Reacts to a message from the ground station `(system, component)`.
    #[allow(deprecated)]
    pub fn handle(
        &mut self,
        now: Duration,
        from: (u8, u8),
        message: &MavMessage,
    ) -> Vec<MavMessage> {
        if let Some(answer) = self.version_answer(from, message) {
            return answer;
        }
        match message {
            MavMessage::MISSION_COUNT(c) => {
                self.gcs = from;
                if !self.holds(c.mission_type) {
                    return vec![
                        self.ack(MavMissionResult::MAV_MISSION_UNSUPPORTED, c.mission_type)
                    ];
                }
                self.count_received(now, c.count, c.mission_type)
            }
            MavMessage::MISSION_ITEM_INT(item) => self.item_received(now, item),
            MavMessage::MISSION_REQUEST_LIST(r) => {
                self.gcs = from;
                if !self.holds(r.mission_type) {
                    return vec![
                        self.ack(MavMissionResult::MAV_MISSION_UNSUPPORTED, r.mission_type)
                    ];
                }
                self.list_requested(now, r.mission_type)
            }
            MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                seq, mission_type, ..
            })
            | MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
                seq, mission_type, ..
            }) => {
                self.gcs = from;
                if !self.holds(*mission_type) {
                    return vec![self.ack(MavMissionResult::MAV_MISSION_UNSUPPORTED, *mission_type)];
                }
                self.item_requested(now, *seq, *mission_type)
            }
            MavMessage::MISSION_ACK(a)
                if self
                    .sending
                    .is_some_and(|tx| tx.mission_type == a.mission_type) =>
            {
                // The ground station's ack ends a download (PX4 `handle_mission_ack`, MAVSDK
                // `process_mission_ack`).
                self.sending = None;
                Vec::new()
            }
            MavMessage::MISSION_SET_CURRENT(c) => {
                self.gcs = from;
                if (c.seq as usize) < self.mission.len() {
                    self.current = c.seq;
                    vec![MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA {
                        seq: c.seq,
                        total: self.mission.len() as u16,
                        ..Default::default()
                    })]
                } else {
                    vec![self.ack(MavMissionResult::MAV_MISSION_INVALID_SEQUENCE, MISSION)]
                }
            }
            MavMessage::MISSION_CLEAR_ALL(c) => {
                self.gcs = from;
                let all = c.mission_type == MavMissionType::MAV_MISSION_TYPE_ALL;
                if all || self.holds(c.mission_type) {
                    for t in [MISSION, FENCE, RALLY] {
                        if (all && self.holds(t)) || t == c.mission_type {
                            self.store(t, Vec::new());
                        }
                    }
                    self.receiving = None;
                    self.sending = None;
                    vec![self.ack(MavMissionResult::MAV_MISSION_ACCEPTED, c.mission_type)]
                } else {
                    vec![self.ack(MavMissionResult::MAV_MISSION_UNSUPPORTED, c.mission_type)]
                }
            }
            _ => Vec::new(),
        }
    }

    fn count_received(
        &mut self,
        now: Duration,
        count: u16,
        mission_type: MavMissionType,
    ) -> Vec<MavMessage> {
        if self.flavour == Flavour::ArduPilot && now < self.cfg.boot {
            self.stats.boot_refusals += 1;
            return vec![self.ack(MavMissionResult::MAV_MISSION_NO_SPACE, mission_type)];
        }
        if let Some(rx) = self.receiving.as_mut() {
            match self.flavour {
                Flavour::Px4 if rx.items.is_empty() && rx.mission_type == mission_type => {
                    // "looks like our MISSION_REQUEST was lost, try again"
                    rx.last_progress = now;
                    rx.last_request = now;
                    return vec![self.request(0, mission_type)];
                }
                Flavour::Px4 => {
                    return vec![self.ack(MavMissionResult::MAV_MISSION_ERROR, mission_type)]
                }
                Flavour::Generic => return Vec::new(),
                Flavour::ArduPilot => self.receiving = None, // the same ground station restarts
            }
        }
        if self.sending.is_some() {
            match self.flavour {
                Flavour::Px4 => {
                    return vec![self.ack(MavMissionResult::MAV_MISSION_ERROR, mission_type)]
                }
                _ => return Vec::new(),
            }
        }
        if count > MAX_ITEMS {
            return self.reject(MavMissionResult::MAV_MISSION_NO_SPACE, mission_type);
        }
        if count == 0 {
            self.store(mission_type, Vec::new());
            self.stats.uploads_accepted += u32::from(mission_type == MISSION);
            return vec![self.ack(MavMissionResult::MAV_MISSION_ACCEPTED, mission_type)];
        }
        if self.flavour == Flavour::ArduPilot && mission_type == MISSION {
            let mut kept = std::mem::take(&mut self.mission);
            kept.truncate(usize::from(count));
            self.store(MISSION, kept);
        }
        self.completed = None;
        self.receiving = Some(Receiving {
            mission_type,
            count,
            items: Vec::with_capacity(usize::from(count)),
            last_request: now,
            last_progress: now,
            requests: 1,
        });
        vec![self.request(0, mission_type)]
    }

    fn item_received(&mut self, now: Duration, item: &MISSION_ITEM_INT_DATA) -> Vec<MavMessage> {
        let mission_type = item.mission_type;
        let Some(rx) = self
            .receiving
            .as_mut()
            .filter(|rx| rx.mission_type == mission_type)
        else {
            return match self.flavour {
                // The last item again after the upload completed: PX4 acks it again
                // ("the GCS did not receive the last ack and sent the same item again").
                Flavour::Px4
                    if self.completed == Some((mission_type, item.seq.wrapping_add(1))) =>
                {
                    if self.cfg.faults.drop_final_ack {
                        Vec::new()
                    } else {
                        vec![self.ack(MavMissionResult::MAV_MISSION_ACCEPTED, mission_type)]
                    }
                }
                Flavour::ArduPilot if self.pending_ack.is_some() && mission_type == MISSION => {
                    vec![self.ack(MavMissionResult::MAV_MISSION_INVALID_SEQUENCE, MISSION)]
                }
                _ => Vec::new(),
            };
        };
        if usize::from(item.seq) != rx.items.len() {
            return match self.flavour {
                Flavour::Px4 => {
                    rx.last_progress = now;
                    Vec::new()
                }
                // MAVSDK refreshes its timeout on any item, in order or not.
                Flavour::Generic => {
                    rx.last_request = now;
                    Vec::new()
                }
                Flavour::ArduPilot => {
                    vec![self.ack(MavMissionResult::MAV_MISSION_INVALID_SEQUENCE, mission_type)]
                }
            };
        }
        if self.cfg.faults.reboot_at_item == Some(item.seq) {
            self.cfg.faults.reboot_at_item = None;
            self.receiving = None;
            self.stats.reboots += 1;
            return Vec::new();
        }
        if self.cfg.faults.nack_item == Some(item.seq) {
            let result = self
                .cfg
                .faults
                .nack_result
                .unwrap_or(MavMissionResult::MAV_MISSION_ERROR);
            return self.reject(result, mission_type);
        }
        let taken = match mission_type {
            MISSION => supported(self.flavour, item),
            _ => fence_rally_supported(self.flavour, mission_type == RALLY, item),
        };
        if let Err(result) = taken {
            return self.reject(result, mission_type);
        }
        let mut item = item.clone();
        item.target_system = 0;
        item.target_component = 0;
        rx.items.push(item.clone());
        rx.last_progress = now;
        rx.last_request = now;
        rx.requests = 1;
        let (received, count) = (rx.items.len(), rx.count);
        if self.flavour == Flavour::ArduPilot && mission_type == MISSION {
            // Not atomic: each item is written as it arrives.
            let seq = usize::from(item.seq);
            if seq < self.mission.len() {
                self.mission[seq] = item;
            } else {
                self.mission.push(item);
            }
            self.revision += 1;
        }
        if received < usize::from(count) {
            return vec![self.request(received as u16, mission_type)];
        }
        let items = self.receiving.take().map(|r| r.items).unwrap_or_default();
        self.store(mission_type, items);
        self.stats.uploads_accepted += u32::from(mission_type == MISSION);
        self.completed = Some((mission_type, count));
        if self.flavour == Flavour::ArduPilot && mission_type == MISSION {
            self.pending_ack = Some(now + ARDUPILOT_ACK_DELAY);
            return Vec::new();
        }
        if self.cfg.faults.drop_final_ack {
            return Vec::new();
        }
        vec![self.ack(MavMissionResult::MAV_MISSION_ACCEPTED, mission_type)]
    }

    fn list_requested(&mut self, now: Duration, mission_type: MavMissionType) -> Vec<MavMessage> {
        let count = self.list(mission_type).len() as u16;
        match self.flavour {
            Flavour::ArduPilot => {
                if self.receiving.is_some() || self.pending_ack.is_some() {
                    return vec![self.ack(MavMissionResult::MAV_MISSION_DENIED, mission_type)];
                }
                vec![self.count(mission_type)]
            }
            Flavour::Px4 => {
                if self.receiving.is_some() {
                    // "Mission download request ignored, already active"
                    return Vec::new();
                }
                // A new REQUEST_LIST restarts the download at item 0.
                self.sending = (count > 0).then_some(Sending {
                    mission_type,
                    count,
                    next: 0,
                    last_heard: now,
                    retries: 0,
                    first_request_seen: false,
                });
                vec![self.count(mission_type)]
            }
            Flavour::Generic => {
                if self.sending.is_some() || self.receiving.is_some() {
                    return Vec::new(); // Busy
                }
                self.sending = (count > 0).then_some(Sending {
                    mission_type,
                    count,
                    next: 0,
                    last_heard: now,
                    retries: 1,
                    first_request_seen: false,
                });
                vec![self.count(mission_type)]
            }
        }
    }

    fn item_requested(
        &mut self,
        now: Duration,
        seq: u16,
        mission_type: MavMissionType,
    ) -> Vec<MavMessage> {
        match self.flavour {
            Flavour::ArduPilot => {
                if self.receiving.is_some() || self.pending_ack.is_some() {
                    return vec![self.ack(MavMissionResult::MAV_MISSION_DENIED, mission_type)];
                }
                match self.item(seq, mission_type) {
                    Some(item) => vec![item],
                    None => vec![
                        self.count(mission_type),
                        self.ack(MavMissionResult::MAV_MISSION_INVALID_SEQUENCE, mission_type),
                    ],
                }
            }
            Flavour::Px4 => {
                // "WPM: Unexpected mission type": a request of another type is ignored.
                let Some(tx) = self
                    .sending
                    .as_mut()
                    .filter(|tx| tx.mission_type == mission_type)
                else {
                    return Vec::new(); // no transfer: silently ignored
                };
                tx.last_heard = now;
                if seq == tx.next && tx.next < tx.count {
                    tx.next += 1;
                } else if seq.wrapping_add(1) != tx.next {
                    // "REJ. CMD: Req. WP was unexpected": the download ends.
                    self.sending = None;
                    self.stats.downloads_abandoned += 1;
                    return vec![self.ack(MavMissionResult::MAV_MISSION_ERROR, mission_type)];
                }
                self.item(seq, mission_type).into_iter().collect()
            }
            Flavour::Generic => {
                let Some(tx) = self
                    .sending
                    .as_mut()
                    .filter(|tx| tx.mission_type == mission_type)
                else {
                    return Vec::new();
                };
                tx.first_request_seen = true;
                if seq > tx.next {
                    return Vec::new(); // "sequence incorrect"
                }
                if seq == tx.next {
                    tx.retries = 0;
                } else if tx.retries >= MAVSDK_RETRIES {
                    // "retries exceeded"
                    self.sending = None;
                    self.stats.downloads_abandoned += 1;
                    return Vec::new();
                }
                tx.retries += 1;
                tx.next = seq + 1;
                tx.last_heard = now;
                self.item(seq, mission_type).into_iter().collect()
            }
        }
    }

    /// Re-requests, abandons, sends what was deferred, by the clock.
    pub fn tick(&mut self, now: Duration) -> Vec<MavMessage> {
        let mut out = Vec::new();
        if let Some(at) = self.pending_ack {
            if now >= at {
                self.pending_ack = None;
                if !self.cfg.faults.drop_final_ack {
                    out.push(self.ack(MavMissionResult::MAV_MISSION_ACCEPTED, MISSION));
                }
            }
        }
        self.tick_sending(now, &mut out);
        let period = self.flavour.rerequest_period();
        let Some(rx) = self.receiving.as_mut() else {
            return out;
        };
        let mission_type = rx.mission_type;
        let abandoned = match self.flavour {
            Flavour::Px4 => now.saturating_sub(rx.last_progress) >= PX4_ABANDON,
            Flavour::ArduPilot => now.saturating_sub(rx.last_progress) >= ARDUPILOT_ABANDON,
            Flavour::Generic => {
                rx.requests >= MAVSDK_RETRIES && now.saturating_sub(rx.last_request) >= period
            }
        };
        if abandoned {
            self.receiving = None;
            self.stats.uploads_abandoned += 1;
            if self.flavour == Flavour::ArduPilot {
                out.push(self.ack(
                    MavMissionResult::MAV_MISSION_OPERATION_CANCELLED,
                    mission_type,
                ));
            }
            return out;
        }
        if now.saturating_sub(rx.last_request) >= period {
            rx.last_request = now;
            rx.requests += 1;
            let seq = rx.items.len() as u16;
            self.stats.rerequests += 1;
            out.push(self.request(seq, mission_type));
        }
        out
    }

    fn tick_sending(&mut self, now: Duration, out: &mut Vec<MavMessage>) {
        let Some(tx) = self.sending.as_mut() else {
            return;
        };
        match self.flavour {
            Flavour::Px4 => {
                if now.saturating_sub(tx.last_heard) >= PX4_ABANDON {
                    self.sending = None;
                    self.stats.downloads_abandoned += 1;
                }
            }
            Flavour::Generic => {
                if now.saturating_sub(tx.last_heard) >= self.flavour.rerequest_period() {
                    tx.last_heard = now;
                    if tx.retries >= MAVSDK_RETRIES {
                        self.sending = None;
                        self.stats.downloads_abandoned += 1;
                        return;
                    }
                    tx.retries += 1;
                    if !tx.first_request_seen {
                        let mission_type = tx.mission_type;
                        out.push(self.count(mission_type));
                    }
                }
            }
            Flavour::ArduPilot => self.sending = None,
        }
    }
}

#[cfg(test)]
#[allow(deprecated)]
mod tests {
    use super::*;
    use crate::link::mav::{MISSION_CLEAR_ALL_DATA, MISSION_REQUEST_LIST_DATA};
    use crate::link::testing::{mission, ms, waypoints};

    const GCS: (u8, u8) = (255, 190);

    fn server(flavour: Flavour) -> MissionServer {
        MissionServer::new(flavour, ServerConfig::default())
    }

    fn count(n: u16) -> MavMessage {
        MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: n,
            target_system: 1,
            target_component: 1,
            mission_type: MISSION,
            opaque_id: 0,
        })
    }

    fn list() -> MavMessage {
        MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
            mission_type: MISSION,
            ..Default::default()
        })
    }

    fn req(seq: u16) -> MavMessage {
        MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            mission_type: MISSION,
            ..Default::default()
        })
    }

    fn acks(out: &[MavMessage]) -> Vec<MavMissionResult> {
        out.iter()
            .filter_map(|m| match m {
                MavMessage::MISSION_ACK(a) => Some(a.mavtype),
                _ => None,
            })
            .collect()
    }

    fn requested(out: &[MavMessage]) -> Option<u16> {
        out.iter().find_map(|m| match m {
            MavMessage::MISSION_REQUEST_INT(r) => Some(r.seq),
            MavMessage::MISSION_REQUEST(r) => Some(r.seq),
            _ => None,
        })
    }

    fn answered(out: &[MavMessage]) -> Option<MISSION_ITEM_INT_DATA> {
        out.iter().find_map(|m| match m {
            MavMessage::MISSION_ITEM_INT(i) => Some(i.clone()),
            _ => None,
        })
    }

    fn upload(
        server: &mut MissionServer,
        now: Duration,
        list: &[MISSION_ITEM_INT_DATA],
    ) -> Vec<MavMessage> {
        let mut out = server.handle(now, GCS, &count(list.len() as u16));
        for it in list {
            out.extend(server.handle(now, GCS, &MavMessage::MISSION_ITEM_INT(it.clone())));
        }
        out
    }

    fn item(it: &MISSION_ITEM_INT_DATA) -> MavMessage {
        MavMessage::MISSION_ITEM_INT(it.clone())
    }

    /// The mission as a ground station reads it back (REQUEST_LIST, then each item in order).
    fn read_back(server: &mut MissionServer, now: Duration) -> Vec<MISSION_ITEM_INT_DATA> {
        let out = server.handle(now, GCS, &list());
        let count = out
            .iter()
            .find_map(|m| match m {
                MavMessage::MISSION_COUNT(c) => Some(c.count),
                _ => None,
            })
            .expect("a count");
        (0..count)
            .map(|seq| answered(&server.handle(now, GCS, &req(seq))).expect("an item"))
            .collect()
    }

    /// Equal as the SITL answered it: integers exactly, floats to 1e-4, NaN only as NaN.
    fn assert_same_item(mock: &MISSION_ITEM_INT_DATA, sitl: &MISSION_ITEM_INT_DATA, at: &str) {
        let ints = |i: &MISSION_ITEM_INT_DATA| {
            (
                i.seq,
                i.frame as u32,
                i.command as u32,
                i.x,
                i.y,
                i.autocontinue,
            )
        };
        assert_eq!(ints(mock), ints(sitl), "{at} item {}", sitl.seq);
        let floats = |i: &MISSION_ITEM_INT_DATA| [i.param1, i.param2, i.param3, i.param4, i.z];
        for (k, (a, b)) in floats(mock).into_iter().zip(floats(sitl)).enumerate() {
            let same = (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-4;
            assert!(same, "{at} item {} field {k}: mock {a}, SITL {b}", sitl.seq);
        }
    }

    /// The mock takes what each SITL took (the same MISSION_ACK) and answers the read-back of
    /// every action as the SITL did, field for field (tests/fixtures/actions).
    #[test]
    fn each_flavour_takes_and_answers_every_action_as_its_sitl_did() {
        use crate::link::readback::{fixtures::cases, verify};
        for flavour in [Flavour::Px4, Flavour::ArduPilot] {
            let all = cases(flavour);
            assert!(all.len() >= 80, "{flavour:?}: {} cases", all.len());
            for case in all {
                let at = format!(
                    "{flavour:?} {} ({}) in frame {}",
                    case.label, case.command, case.frame
                );
                let mut s = server(flavour);
                let mut out = upload(&mut s, ms(0), &case.sent);
                out.extend(s.tick(ms(600)));
                let ack = acks(&out).first().map(|a| *a as i32);
                assert_eq!(ack, Some(case.ack), "{at}");
                if !case.accepted() {
                    continue;
                }
                let read = read_back(&mut s, ms(700));
                assert_eq!(read.len(), case.read.len(), "{at}");
                for (mock, sitl) in read.iter().zip(&case.read) {
                    assert_same_item(mock, sitl, &at);
                }
                // And the upload's verification passes on the mock's answer.
                assert_eq!(verify(flavour, &case.sent, &read), Ok(()), "{at}");
            }
        }
    }

    #[test]
    fn px4_refuses_a_do_item_in_a_global_frame_and_a_located_one_in_the_mission_frame() {
        let mut s = server(Flavour::Px4);
        let mut speed = mission(Flavour::Px4, 3);
        speed[1] = MISSION_ITEM_INT_DATA {
            command: MavCmd::MAV_CMD_DO_CHANGE_SPEED,
            frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
            param1: 1.0,
            param2: 8.5,
            ..speed[1].clone()
        };
        assert_eq!(
            acks(&upload(&mut s, ms(0), &speed)),
            vec![MavMissionResult::MAV_MISSION_UNSUPPORTED]
        );
        let mut roi = mission(Flavour::Px4, 3);
        roi[1].command = MavCmd::MAV_CMD_DO_SET_ROI_LOCATION;
        roi[1].frame = MavFrame::MAV_FRAME_MISSION;
        assert_eq!(
            acks(&upload(&mut s, ms(10_000), &roi)),
            vec![MavMissionResult::MAV_MISSION_UNSUPPORTED]
        );
        assert!(s.mission().is_empty());
    }

    #[test]
    fn a_complete_upload_is_stored_and_acknowledged_once_and_px4_acks_a_repeated_last_item() {
        for flavour in [Flavour::Px4, Flavour::Generic] {
            let mut s = server(flavour);
            let out = upload(&mut s, ms(0), &waypoints(3));
            assert_eq!(acks(&out), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
            assert_eq!(s.mission().len(), 3);
            let again = s.handle(ms(2), GCS, &item(&waypoints(3)[2]));
            let expected = match flavour {
                Flavour::Px4 => vec![MavMissionResult::MAV_MISSION_ACCEPTED],
                _ => vec![],
            };
            assert_eq!(acks(&again), expected, "{flavour:?}");
        }
    }

    #[test]
    fn each_flavour_re_requests_a_missing_item_on_its_own_clock() {
        for (flavour, period) in [
            (Flavour::Px4, 250),
            (Flavour::ArduPilot, 1000),
            (Flavour::Generic, 500),
        ] {
            let mut s = server(flavour);
            assert_eq!(requested(&s.handle(ms(0), GCS, &count(2))), Some(0));
            assert!(s.tick(ms(period - 1)).is_empty());
            assert_eq!(requested(&s.tick(ms(period))), Some(0), "{flavour:?}");
        }
    }

    #[test]
    fn an_abandoned_px4_upload_after_five_seconds_keeps_the_previous_mission() {
        let mut s = server(Flavour::Px4);
        upload(&mut s, ms(0), &waypoints(2));
        s.handle(ms(10), GCS, &count(3));
        s.handle(ms(20), GCS, &item(&waypoints(3)[0]));
        assert!(s
            .tick(ms(5019))
            .iter()
            .all(|m| !matches!(m, MavMessage::MISSION_ACK(_))));
        s.tick(ms(5020));
        assert_eq!(s.stats.uploads_abandoned, 1);
        assert_eq!(s.mission(), &waypoints(2)[..]);
    }

    #[test]
    fn mavsdk_gives_an_upload_up_silently_after_five_requests() {
        let mut s = server(Flavour::Generic);
        s.handle(ms(0), GCS, &count(2));
        let mut requests = 1;
        let mut t = 0;
        while s.stats.uploads_abandoned == 0 {
            t += 500;
            let out = s.tick(ms(t));
            assert!(acks(&out).is_empty());
            requests += usize::from(requested(&out).is_some());
        }
        assert_eq!((requests, t), (5, 2500));
        // A repeated item refreshes its clock (its timeout handler), holding the re-request off.
        let mut s = server(Flavour::Generic);
        s.handle(ms(0), GCS, &count(2));
        s.handle(ms(1), GCS, &item(&waypoints(2)[0]));
        s.handle(ms(400), GCS, &item(&waypoints(2)[0]));
        assert!(requested(&s.tick(ms(501))).is_none());
        assert_eq!(requested(&s.tick(ms(900))), Some(1));
    }

    #[test]
    fn ardupilot_cancels_an_upload_after_eight_seconds_and_answers_an_early_item_with_invalid_sequence(
    ) {
        let mut s = server(Flavour::ArduPilot);
        s.handle(ms(0), GCS, &count(3));
        let early = s.handle(ms(10), GCS, &item(&mission(Flavour::ArduPilot, 3)[1]));
        assert_eq!(
            acks(&early),
            vec![MavMissionResult::MAV_MISSION_INVALID_SEQUENCE]
        );
        let out = s.tick(ms(8000));
        assert_eq!(
            acks(&out),
            vec![MavMissionResult::MAV_MISSION_OPERATION_CANCELLED]
        );
    }

    #[test]
    fn px4_refuses_a_count_during_an_upload_but_repeats_its_first_request() {
        let mut s = server(Flavour::Px4);
        s.handle(ms(0), GCS, &count(3));
        assert_eq!(requested(&s.handle(ms(5), GCS, &count(3))), Some(0));
        s.handle(ms(10), GCS, &item(&waypoints(3)[0]));
        assert_eq!(
            acks(&s.handle(ms(20), GCS, &count(3))),
            vec![MavMissionResult::MAV_MISSION_ERROR]
        );
        // The upload goes on.
        s.handle(ms(30), GCS, &item(&waypoints(3)[1]));
        let out = s.handle(ms(40), GCS, &item(&waypoints(3)[2]));
        assert_eq!(acks(&out), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
    }

    #[test]
    fn ardupilot_refuses_uploads_while_booting_with_no_space() {
        let cfg = ServerConfig {
            boot: ms(3000),
            ..ServerConfig::default()
        };
        let mut s = MissionServer::new(Flavour::ArduPilot, cfg);
        assert_eq!(
            acks(&s.handle(ms(2999), GCS, &count(3))),
            vec![MavMissionResult::MAV_MISSION_NO_SPACE]
        );
        assert_eq!(requested(&s.handle(ms(3000), GCS, &count(3))), Some(0));
        assert_eq!(s.stats.boot_refusals, 1);
    }

    #[test]
    fn ardupilot_defers_its_final_ack_refusing_read_backs_meanwhile() {
        let mut s = server(Flavour::ArduPilot);
        let out = upload(&mut s, ms(0), &mission(Flavour::ArduPilot, 3));
        assert!(acks(&out).is_empty());
        assert_eq!(
            acks(&s.handle(ms(100), GCS, &list())),
            vec![MavMissionResult::MAV_MISSION_DENIED]
        );
        assert_eq!(
            acks(&s.tick(ms(500))),
            vec![MavMissionResult::MAV_MISSION_ACCEPTED]
        );
        assert!(matches!(
            s.handle(ms(600), GCS, &list()).as_slice(),
            [MavMessage::MISSION_COUNT(c)] if c.count == 3
        ));
        // Any item, in any order, from storage: item 0 is its home.
        let home = answered(&s.handle(ms(700), GCS, &req(0))).unwrap();
        assert_eq!(home.z, 16.1);
        assert_eq!(answered(&s.handle(ms(700), GCS, &req(2))).unwrap().seq, 2);
    }

    #[test]
    fn a_px4_download_must_go_in_order_and_a_skip_ends_it() {
        let mut s = server(Flavour::Px4);
        upload(&mut s, ms(0), &waypoints(3));
        // Without REQUEST_LIST there is no download: a request is silently ignored.
        assert!(s.handle(ms(1), GCS, &req(0)).is_empty());
        s.handle(ms(2), GCS, &list());
        let first = answered(&s.handle(ms(3), GCS, &req(0))).unwrap();
        assert_eq!(first.frame, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT);
        // The same again is fine; a skip is not.
        assert!(answered(&s.handle(ms(4), GCS, &req(0))).is_some());
        assert_eq!(
            acks(&s.handle(ms(5), GCS, &req(2))),
            vec![MavMissionResult::MAV_MISSION_ERROR]
        );
        assert!(s.handle(ms(6), GCS, &req(1)).is_empty());
    }

    #[test]
    fn mavsdk_sends_a_download_item_at_most_five_times() {
        let mut s = server(Flavour::Generic);
        upload(&mut s, ms(0), &waypoints(3));
        s.handle(ms(1), GCS, &list());
        assert!(answered(&s.handle(ms(2), GCS, &req(0))).is_some());
        assert!(
            s.handle(ms(3), GCS, &req(2)).is_empty(),
            "beyond the next: ignored"
        );
        for k in 0..4 {
            assert!(answered(&s.handle(ms(4 + k), GCS, &req(0))).is_some());
        }
        assert!(s.handle(ms(10), GCS, &req(0)).is_empty());
        assert_eq!(s.stats.downloads_abandoned, 1);
        // Given up: a fresh list is answered.
        assert!(matches!(
            s.handle(ms(11), GCS, &list()).as_slice(),
            [MavMessage::MISSION_COUNT(_)]
        ));
    }

    #[test]
    fn a_wrong_mission_type_or_frame_or_an_injected_nack_is_refused_and_the_old_mission_stays() {
        let mut s = server(Flavour::Px4);
        // PX4 holds a mission, a fence and rally points: a list of any other type is refused.
        let fence = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: 2,
            mission_type: MavMissionType::MAV_MISSION_TYPE_ALL,
            ..Default::default()
        });
        assert_eq!(
            acks(&s.handle(ms(0), GCS, &fence)),
            vec![MavMissionResult::MAV_MISSION_UNSUPPORTED]
        );
        upload(&mut s, ms(0), &waypoints(1));
        let mut bad = waypoints(2);
        bad[1].frame = MavFrame::MAV_FRAME_LOCAL_NED;
        assert_eq!(
            acks(&upload(&mut s, ms(10), &bad)),
            vec![MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME]
        );
        let cfg = ServerConfig {
            faults: ProtocolFaults {
                nack_item: Some(1),
                nack_result: Some(MavMissionResult::MAV_MISSION_DENIED),
                ..Default::default()
            },
            ..ServerConfig::default()
        };
        let mut nacking = MissionServer::new(Flavour::Px4, cfg);
        assert_eq!(
            acks(&upload(&mut nacking, ms(0), &waypoints(3))),
            vec![MavMissionResult::MAV_MISSION_DENIED]
        );
        assert!(nacking.mission().is_empty());
        assert_eq!(s.mission().len(), 1);
    }

    #[test]
    fn a_reboot_mid_upload_forgets_the_transfer_but_not_the_stored_mission() {
        let cfg = ServerConfig {
            faults: ProtocolFaults {
                reboot_at_item: Some(1),
                ..Default::default()
            },
            ..ServerConfig::default()
        };
        let mut s = MissionServer::new(Flavour::Px4, cfg);
        upload(&mut s, ms(0), &waypoints(3));
        assert_eq!(s.stats.reboots, 1);
        assert!(s.mission().is_empty() && s.tick(ms(300)).is_empty());
        upload(&mut s, ms(400), &waypoints(3));
        assert_eq!(s.mission().len(), 3);
    }

    #[test]
    fn ardupilot_writes_items_as_they_arrive() {
        let mut s = server(Flavour::ArduPilot);
        let list = mission(Flavour::ArduPilot, 3);
        upload(&mut s, ms(0), &list);
        s.tick(ms(600));
        let mut other = list.clone();
        other[1].z = 50.0;
        s.handle(ms(1000), GCS, &count(3));
        s.handle(ms(1001), GCS, &item(&other[0]));
        s.handle(ms(1002), GCS, &item(&other[1]));
        // Abandoned after two items: not atomic, item 1 was already replaced.
        s.tick(ms(9002));
        assert_eq!(s.mission()[1].z, 50.0);
    }

    #[test]
    fn a_corrupting_mock_answers_one_item_off_by_one_degree_e7() {
        let cfg = ServerConfig {
            faults: ProtocolFaults {
                corrupt_readback: Some(1),
                ..Default::default()
            },
            ..ServerConfig::default()
        };
        let mut s = MissionServer::new(Flavour::Generic, cfg);
        let sent = waypoints(3);
        upload(&mut s, ms(0), &sent);
        s.handle(ms(1), GCS, &list());
        assert_eq!(
            answered(&s.handle(ms(2), GCS, &req(0))).unwrap().x,
            sent[0].x
        );
        assert_eq!(
            answered(&s.handle(ms(3), GCS, &req(1))).unwrap().x,
            sent[1].x + 1
        );
    }

    #[test]
    fn clear_all_empties_the_mission() {
        let mut s = server(Flavour::Px4);
        upload(&mut s, ms(0), &waypoints(2));
        let clear = MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
            mission_type: MISSION,
            ..Default::default()
        });
        assert_eq!(
            acks(&s.handle(ms(0), GCS, &clear)),
            vec![MavMissionResult::MAV_MISSION_ACCEPTED]
        );
        assert!(s.mission().is_empty());
    }

    fn typed(mission_type: MavMissionType, message: MavMessage) -> MavMessage {
        match message {
            MavMessage::MISSION_COUNT(c) => {
                MavMessage::MISSION_COUNT(MISSION_COUNT_DATA { mission_type, ..c })
            }
            MavMessage::MISSION_REQUEST_LIST(l) => {
                MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA { mission_type, ..l })
            }
            MavMessage::MISSION_REQUEST_INT(r) => {
                MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA { mission_type, ..r })
            }
            other => other,
        }
    }

    /// Uploads `list` as the autopilot's list of its items' mission type, then reads it back.
    fn round_trip(
        server: &mut MissionServer,
        list: &[MISSION_ITEM_INT_DATA],
    ) -> (Vec<MavMessage>, Vec<MISSION_ITEM_INT_DATA>) {
        let t = list[0].mission_type;
        let mut out = server.handle(ms(0), GCS, &typed(t, count(list.len() as u16)));
        for it in list {
            out.extend(server.handle(ms(1), GCS, &item(it)));
        }
        let listed = server.handle(ms(2), GCS, &typed(t, super::tests::list()));
        let n = listed
            .iter()
            .find_map(|m| match m {
                MavMessage::MISSION_COUNT(c) if c.mission_type == t => Some(c.count),
                _ => None,
            })
            .unwrap_or(0);
        let read = (0..n)
            .filter_map(|seq| answered(&server.handle(ms(3), GCS, &typed(t, req(seq)))))
            .collect();
        // The ground station's ack ends the download (PX4 refuses another transfer meanwhile).
        let done = MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            mavtype: MavMissionResult::MAV_MISSION_ACCEPTED,
            mission_type: t,
            ..Default::default()
        });
        server.handle(ms(4), GCS, &done);
        (out, read)
    }

    #[test]
    fn px4_and_ardupilot_hold_a_fence_and_rally_points_beside_the_mission_as_they_store_them() {
        use crate::link::fence::{fence_items, rally_items};
        use crate::link::readback::verify;
        let fence = fence_items(&crate::link::testing::fence());
        for flavour in [Flavour::Px4, Flavour::ArduPilot] {
            let mut server = server(flavour);
            upload(&mut server, ms(0), &mission(flavour, 5));
            server.tick(ms(600));
            let positions = |items: &[MISSION_ITEM_INT_DATA]| -> Vec<(u32, i32, i32)> {
                items.iter().map(|i| (i.command as u32, i.x, i.y)).collect()
            };
            let before = positions(server.mission());
            let (out, read) = round_trip(&mut server, &fence);
            assert_eq!(acks(&out), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
            assert!(out
                .iter()
                .all(|m| !matches!(m, MavMessage::MISSION_ACK(a) if a.mission_type != FENCE)));
            assert_eq!(server.fence().len(), 11);
            assert_eq!(
                positions(server.mission()),
                before,
                "{flavour:?}: the mission stays"
            );
            // What link::readback expects of the flavour is what the mock answers.
            verify(flavour, &fence, &read).unwrap_or_else(|e| panic!("{flavour:?}: {e}"));
            let rally = rally_items(&crate::link::testing::rally(), flavour);
            let (_, read) = round_trip(&mut server, &rally);
            verify(flavour, &rally, &read).unwrap_or_else(|e| panic!("{flavour:?}: {e}"));
            assert_eq!(server.rally_points().len(), 1);
            assert_eq!(server.fence_zones().zones.len(), 3);
        }
        // ArduPilot answers a fence item without its altitude, a rally point's in whole metres.
        let mut ap = server(Flavour::ArduPilot);
        let (_, read) = round_trip(&mut ap, &fence);
        assert_eq!(read[0].command, MavCmd::MAV_CMD_NAV_FENCE_RETURN_POINT);
        assert_eq!(read[0].z, 0.0);
        let mut rally = rally_items(&crate::link::testing::rally(), Flavour::Px4);
        rally[0].z = 25.7;
        let (_, read) = round_trip(&mut ap, &rally);
        assert_eq!(read[0].z, 25.0);
        assert_eq!(read[0].frame, MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT);
    }

    #[test]
    fn the_generic_flavour_holds_no_fence_and_each_flavour_declares_what_it_holds() {
        let fence = crate::link::fence::fence_items(&crate::link::testing::fence());
        let mut mavsdk = server(Flavour::Generic);
        let out = mavsdk.handle(ms(0), GCS, &typed(FENCE, count(fence.len() as u16)));
        assert_eq!(acks(&out), vec![MavMissionResult::MAV_MISSION_UNSUPPORTED]);
        let ask = MavMessage::COMMAND_LONG(crate::link::mav::COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_REQUEST_MESSAGE,
            param1: 148.0,
            ..Default::default()
        });
        for (flavour, holds) in [
            (Flavour::Px4, true),
            (Flavour::ArduPilot, true),
            (Flavour::Generic, false),
        ] {
            let out = server(flavour).handle(ms(0), GCS, &ask);
            let bits = out
                .iter()
                .find_map(|m| match m {
                    MavMessage::AUTOPILOT_VERSION(v) => Some(v.capabilities),
                    _ => None,
                })
                .expect("AUTOPILOT_VERSION");
            let caps = crate::link::support::Capabilities::from_bits(bits);
            assert_eq!((caps.fence, caps.rally), (holds, holds), "{flavour:?}");
        }
    }

    #[test]
    fn a_rally_point_in_an_absolute_frame_is_refused_by_ardupilot_and_a_fence_count_of_zero_clears()
    {
        let mut rally =
            crate::link::fence::rally_items(&crate::link::testing::rally(), Flavour::ArduPilot);
        rally[0].frame = MavFrame::MAV_FRAME_GLOBAL;
        let mut ap = server(Flavour::ArduPilot);
        let (out, read) = round_trip(&mut ap, &rally);
        assert_eq!(
            acks(&out),
            vec![MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME]
        );
        assert!(read.is_empty());
        let fence = crate::link::fence::fence_items(&crate::link::testing::fence());
        round_trip(&mut ap, &fence);
        let out = ap.handle(ms(9), GCS, &typed(FENCE, count(0)));
        assert_eq!(acks(&out), vec![MavMissionResult::MAV_MISSION_ACCEPTED]);
        assert!(ap.fence().is_empty());
    }

    #[test]
    fn ardupilot_reports_a_breach_when_the_vehicle_enters_an_exclusion_zone_and_px4_reports_none() {
        let fence = crate::link::testing::fence();
        let home = fence.breach_return.unwrap();
        let mut ap = server(Flavour::ArduPilot);
        assert!(
            ap.fence_status(0, home, [0.0, 0.0]).is_none(),
            "no fence, no status"
        );
        round_trip(&mut ap, &crate::link::fence::fence_items(&fence));
        let status = |m: Option<MavMessage>| match m {
            Some(MavMessage::FENCE_STATUS(s)) => (s.breach_status, s.breach_count, s.breach_time),
            other => panic!("{other:?}"),
        };
        // The breach return point lies east of the exclusion square, inside the pentagon.
        assert_eq!(status(ap.fence_status(1000, home, [0.0, 0.0])), (0, 0, 0));
        // The exclusion square's centre: 0.0001 deg north of its south edge, about 9 m east
        // of its west edge.
        let origin = crate::mission::Origin {
            home,
            height_above_home_m: 0.0,
        };
        let centre = origin.to_enu(crate::mission::Geodetic {
            lat_deg: 38.5365,
            lon_deg: -121.7887,
            alt_m: home.alt_m,
        });
        let inside = [centre.x_east_m, centre.y_north_m];
        assert_eq!(status(ap.fence_status(2000, home, inside)), (1, 1, 2000));
        assert_eq!(status(ap.fence_status(2500, home, inside)), (1, 1, 2000));
        assert_eq!(
            status(ap.fence_status(3000, home, [0.0, 0.0])),
            (0, 1, 2000)
        );
        let mut px4 = server(Flavour::Px4);
        round_trip(&mut px4, &crate::link::fence::fence_items(&fence));
        assert!(px4.fence_status(2000, home, inside).is_none());
    }
}
