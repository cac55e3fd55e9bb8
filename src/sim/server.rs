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
//! What each flavour stores of an item is `sim::storage`.

use std::time::Duration;

use super::storage::{stored, Home};
#[allow(deprecated)]
use crate::link::mav::{
    MavCmd, MavFrame, MavMessage, MavMissionResult, MavMissionType, MISSION_ACK_DATA,
    MISSION_COUNT_DATA, MISSION_CURRENT_DATA, MISSION_ITEM_INT_DATA, MISSION_REQUEST_DATA,
    MISSION_REQUEST_INT_DATA,
};
use crate::link::Flavour;

/// Most items stored (PX4's dataman holds thousands; a bound keeps hostile counts out).
pub const MAX_ITEMS: u16 = 2000;

const MISSION: MavMissionType = MavMissionType::MAV_MISSION_TYPE_MISSION;

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
    pub uploads_accepted: u32,
    pub uploads_rejected: u32,
    pub uploads_abandoned: u32,
    pub downloads_abandoned: u32,
    pub rerequests: u32,
    pub reboots: u32,
    /// Uploads refused while booting (ArduPilot's MAV_MISSION_NO_SPACE).
    pub boot_refusals: u32,
}

/// The vehicle side of the mission protocol.
#[derive(Debug, Clone)]
pub struct MissionServer {
    flavour: Flavour,
    cfg: ServerConfig,
    /// The mission as received (what it answers is `storage::stored` of it).
    mission: Vec<MISSION_ITEM_INT_DATA>,
    revision: u64,
    receiving: Option<Receiving>,
    sending: Option<Sending>,
    /// ArduPilot: when the deferred final ack goes out.
    pending_ack: Option<Duration>,
    /// PX4: the item count of the upload completed last (a repeat of its last item is acked).
    completed: Option<u16>,
    /// (system, component) of the ground station being answered.
    gcs: (u8, u8),
    /// The current item (MISSION_SET_CURRENT), where a flight would resume.
    current: u16,
    pub stats: ServerStats,
}

fn supported(flavour: Flavour, item: &MISSION_ITEM_INT_DATA) -> Result<(), MavMissionResult> {
    use MavCmd::*;
    use MavFrame::*;
    let navigation = super::storage::navigation(item.command);
    let command = matches!(
        item.command,
        MAV_CMD_NAV_RETURN_TO_LAUNCH
            | MAV_CMD_DO_CHANGE_SPEED
            | MAV_CMD_NAV_DELAY
            | MAV_CMD_DO_JUMP
            | MAV_CMD_DO_DIGICAM_CONTROL
            | MAV_CMD_IMAGE_START_CAPTURE
            | MAV_CMD_IMAGE_STOP_CAPTURE
    );
    if !navigation && !command {
        return Err(MavMissionResult::MAV_MISSION_UNSUPPORTED);
    }
    #[allow(deprecated)]
    let frame_ok = match item.frame {
        MAV_FRAME_GLOBAL
        | MAV_FRAME_GLOBAL_RELATIVE_ALT
        | MAV_FRAME_GLOBAL_INT
        | MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => true,
        MAV_FRAME_MISSION => command,
        _ => false,
    };
    let ardupilot_home = flavour == Flavour::ArduPilot && item.seq == 0;
    if !(frame_ok || ardupilot_home) {
        return Err(MavMissionResult::MAV_MISSION_UNSUPPORTED_FRAME);
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
            revision: 0,
            receiving: None,
            sending: None,
            pending_ack: None,
            completed: None,
            gcs: (255, 190),
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

    /// Changes whenever the stored mission does.
    pub fn revision(&self) -> u64 {
        self.revision
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

    fn count(&self) -> MavMessage {
        MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: self.mission.len() as u16,
            target_system: self.gcs.0,
            target_component: self.gcs.1,
            mission_type: MISSION,
            opaque_id: 0,
        })
    }

    #[allow(deprecated)]
    fn request(&self, seq: u16) -> MavMessage {
        if self.flavour == Flavour::ArduPilot {
            // ArduPilot still requests with the legacy MISSION_REQUEST (queued_request_send).
            return MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
                seq,
                target_system: self.gcs.0,
                target_component: self.gcs.1,
                mission_type: MISSION,
            });
        }
        MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: self.gcs.0,
            target_component: self.gcs.1,
            mission_type: MISSION,
        })
    }

    /// Item `seq` as this flavour answers a read-back of it.
    fn item(&self, seq: u16) -> Option<MavMessage> {
        let mut item = stored(
            self.flavour,
            self.mission.get(usize::from(seq))?,
            &self.cfg.home,
        );
        if self.cfg.faults.corrupt_readback == Some(seq) {
            item.x = item.x.wrapping_add(1);
        }
        item.target_system = self.gcs.0;
        item.target_component = self.gcs.1;
        item.mission_type = MISSION;
        Some(MavMessage::MISSION_ITEM_INT(item))
    }

    fn store(&mut self, items: Vec<MISSION_ITEM_INT_DATA>) {
        self.mission = items;
        self.revision += 1;
    }

    fn reject(&mut self, result: MavMissionResult) -> Vec<MavMessage> {
        self.receiving = None;
        self.stats.uploads_rejected += 1;
        vec![self.ack(result, MISSION)]
    }

    /// Reacts to a message from the ground station `(system, component)`.
    #[allow(deprecated)]
    pub fn handle(
        &mut self,
        now: Duration,
        from: (u8, u8),
        message: &MavMessage,
    ) -> Vec<MavMessage> {
        match message {
            MavMessage::MISSION_COUNT(c) => {
                self.gcs = from;
                if c.mission_type != MISSION {
                    return vec![
                        self.ack(MavMissionResult::MAV_MISSION_UNSUPPORTED, c.mission_type)
                    ];
                }
                self.count_received(now, c.count)
            }
            MavMessage::MISSION_ITEM_INT(item) => self.item_received(now, item),
            MavMessage::MISSION_REQUEST_LIST(r) => {
                self.gcs = from;
                if r.mission_type != MISSION {
                    return vec![
                        self.ack(MavMissionResult::MAV_MISSION_UNSUPPORTED, r.mission_type)
                    ];
                }
                self.list_requested(now)
            }
            MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
                seq, mission_type, ..
            })
            | MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
                seq, mission_type, ..
            }) => {
                self.gcs = from;
                if *mission_type != MISSION {
                    return vec![self.ack(MavMissionResult::MAV_MISSION_UNSUPPORTED, *mission_type)];
                }
                self.item_requested(now, *seq)
            }
            MavMessage::MISSION_ACK(a) if a.mission_type == MISSION => {
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
                if c.mission_type == MISSION
                    || c.mission_type == MavMissionType::MAV_MISSION_TYPE_ALL
                {
                    self.store(Vec::new());
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

    fn count_received(&mut self, now: Duration, count: u16) -> Vec<MavMessage> {
        if self.flavour == Flavour::ArduPilot && now < self.cfg.boot {
            self.stats.boot_refusals += 1;
            return vec![self.ack(MavMissionResult::MAV_MISSION_NO_SPACE, MISSION)];
        }
        if let Some(rx) = self.receiving.as_mut() {
            match self.flavour {
                Flavour::Px4 if rx.items.is_empty() => {
                    // "looks like our MISSION_REQUEST was lost, try again"
                    rx.last_progress = now;
                    rx.last_request = now;
                    return vec![self.request(0)];
                }
                Flavour::Px4 => return vec![self.ack(MavMissionResult::MAV_MISSION_ERROR, MISSION)],
                Flavour::Generic => return Vec::new(),
                Flavour::ArduPilot => self.receiving = None, // the same ground station restarts
            }
        }
        if self.sending.is_some() {
            match self.flavour {
                Flavour::Px4 => return vec![self.ack(MavMissionResult::MAV_MISSION_ERROR, MISSION)],
                _ => return Vec::new(),
            }
        }
        if count > MAX_ITEMS {
            return self.reject(MavMissionResult::MAV_MISSION_NO_SPACE);
        }
        if count == 0 {
            self.store(Vec::new());
            self.stats.uploads_accepted += 1;
            return vec![self.ack(MavMissionResult::MAV_MISSION_ACCEPTED, MISSION)];
        }
        if self.flavour == Flavour::ArduPilot {
            let mut kept = std::mem::take(&mut self.mission);
            kept.truncate(usize::from(count));
            self.store(kept);
        }
        self.completed = None;
        self.receiving = Some(Receiving {
            count,
            items: Vec::with_capacity(usize::from(count)),
            last_request: now,
            last_progress: now,
            requests: 1,
        });
        vec![self.request(0)]
    }

    fn item_received(&mut self, now: Duration, item: &MISSION_ITEM_INT_DATA) -> Vec<MavMessage> {
        if item.mission_type != MISSION {
            return Vec::new();
        }
        let Some(rx) = self.receiving.as_mut() else {
            return match self.flavour {
                // The last item again after the upload completed: PX4 acks it again
                // ("the GCS did not receive the last ack and sent the same item again").
                Flavour::Px4 if self.completed == Some(item.seq.wrapping_add(1)) => {
                    if self.cfg.faults.drop_final_ack {
                        Vec::new()
                    } else {
                        vec![self.ack(MavMissionResult::MAV_MISSION_ACCEPTED, MISSION)]
                    }
                }
                Flavour::ArduPilot if self.pending_ack.is_some() => {
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
                    vec![self.ack(MavMissionResult::MAV_MISSION_INVALID_SEQUENCE, MISSION)]
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
            return self.reject(result);
        }
        if let Err(result) = supported(self.flavour, item) {
            return self.reject(result);
        }
        let mut item = item.clone();
        item.target_system = 0;
        item.target_component = 0;
        rx.items.push(item.clone());
        rx.last_progress = now;
        rx.last_request = now;
        rx.requests = 1;
        let (received, count) = (rx.items.len(), rx.count);
        if self.flavour == Flavour::ArduPilot {
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
            return vec![self.request(received as u16)];
        }
        let items = self.receiving.take().map(|r| r.items).unwrap_or_default();
        self.store(items);
        self.stats.uploads_accepted += 1;
        self.completed = Some(count);
        if self.flavour == Flavour::ArduPilot {
            self.pending_ack = Some(now + ARDUPILOT_ACK_DELAY);
            return Vec::new();
        }
        if self.cfg.faults.drop_final_ack {
            return Vec::new();
        }
        vec![self.ack(MavMissionResult::MAV_MISSION_ACCEPTED, MISSION)]
    }

    fn list_requested(&mut self, now: Duration) -> Vec<MavMessage> {
        let count = self.mission.len() as u16;
        match self.flavour {
            Flavour::ArduPilot => {
                if self.receiving.is_some() || self.pending_ack.is_some() {
                    return vec![self.ack(MavMissionResult::MAV_MISSION_DENIED, MISSION)];
                }
                vec![self.count()]
            }
            Flavour::Px4 => {
                if self.receiving.is_some() {
                    // "Mission download request ignored, already active"
                    return Vec::new();
                }
                // A new REQUEST_LIST restarts the download at item 0.
                self.sending = (count > 0).then_some(Sending {
                    count,
                    next: 0,
                    last_heard: now,
                    retries: 0,
                    first_request_seen: false,
                });
                vec![self.count()]
            }
            Flavour::Generic => {
                if self.sending.is_some() || self.receiving.is_some() {
                    return Vec::new(); // Busy
                }
                self.sending = (count > 0).then_some(Sending {
                    count,
                    next: 0,
                    last_heard: now,
                    retries: 1,
                    first_request_seen: false,
                });
                vec![self.count()]
            }
        }
    }

    fn item_requested(&mut self, now: Duration, seq: u16) -> Vec<MavMessage> {
        match self.flavour {
            Flavour::ArduPilot => {
                if self.receiving.is_some() || self.pending_ack.is_some() {
                    return vec![self.ack(MavMissionResult::MAV_MISSION_DENIED, MISSION)];
                }
                match self.item(seq) {
                    Some(item) => vec![item],
                    None => vec![
                        self.count(),
                        self.ack(MavMissionResult::MAV_MISSION_INVALID_SEQUENCE, MISSION),
                    ],
                }
            }
            Flavour::Px4 => {
                let Some(tx) = self.sending.as_mut() else {
                    return Vec::new(); // no transfer: silently ignored
                };
                tx.last_heard = now;
                if seq == tx.next && tx.next < tx.count {
                    tx.next += 1;
                } else if seq.wrapping_add(1) != tx.next {
                    // "REJ. CMD: Req. WP was unexpected": the download ends.
                    self.sending = None;
                    self.stats.downloads_abandoned += 1;
                    return vec![self.ack(MavMissionResult::MAV_MISSION_ERROR, MISSION)];
                }
                self.item(seq).into_iter().collect()
            }
            Flavour::Generic => {
                let Some(tx) = self.sending.as_mut() else {
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
                self.item(seq).into_iter().collect()
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
                out.push(self.ack(MavMissionResult::MAV_MISSION_OPERATION_CANCELLED, MISSION));
            }
            return out;
        }
        if now.saturating_sub(rx.last_request) >= period {
            rx.last_request = now;
            rx.requests += 1;
            let seq = rx.items.len() as u16;
            self.stats.rerequests += 1;
            out.push(self.request(seq));
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
                        out.push(self.count());
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
        let fence = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: 2,
            mission_type: MavMissionType::MAV_MISSION_TYPE_FENCE,
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
}
