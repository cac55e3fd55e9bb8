//! Which autopilot answers (PX4, ArduPilot, or anything else), and what its mission protocol does
//! that the ground side must know to transfer a mission without tuning: when it abandons a
//! transfer, whether a fresh start may resume where the last one stopped, which refusals pass.
//! Every rule names its source. What each autopilot stores of an item is `link::readback`.
//!
//! Sources: PX4-Autopilot `src/modules/mavlink/mavlink_mission.cpp` (commit 001bb4d7, PX4 main),
//! ArduPilot `libraries/GCS_MAVLink/MissionItemProtocol.{h,cpp}`, MAVSDK
//! `cpp/src/mavsdk/core/mavlink_mission_transfer_server.cpp` (the MissionRawServer a `Generic`
//! autopilot is in our tests), and what the SITLs of sitl/README.md were seen to do.

use std::time::Duration;

use super::mav::{MavAutopilot, MavMissionResult};

/// Which autopilot firmware answers (from its HEARTBEAT's `autopilot` field).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Flavour {
    Px4,
    ArduPilot,
    /// Any other autopilot (MAVSDK's MissionRawServer says MAV_AUTOPILOT_GENERIC).
    Generic,
}

/// What a refusal (a MISSION_ACK other than ACCEPTED) means for a transfer in progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// Not about this transfer: carry on.
    Ignore,
    /// The autopilot gave the transfer up: start it again at once.
    Restart,
    /// Not now: wait a little and start again (within the time budget).
    Transient,
    /// The mission or the request is refused: stop.
    Final,
}

impl Flavour {
    /// The flavour a HEARTBEAT's autopilot field names.
    pub fn from_autopilot(autopilot: MavAutopilot) -> Flavour {
        match autopilot {
            MavAutopilot::MAV_AUTOPILOT_PX4 => Flavour::Px4,
            MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA => Flavour::ArduPilot,
            _ => Flavour::Generic,
        }
    }

    /// The HEARTBEAT autopilot field of this flavour (what the mock says it is).
    pub fn autopilot(self) -> MavAutopilot {
        match self {
            Flavour::Px4 => MavAutopilot::MAV_AUTOPILOT_PX4,
            Flavour::ArduPilot => MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            Flavour::Generic => MavAutopilot::MAV_AUTOPILOT_GENERIC,
        }
    }

    /// Whether a download, once (re)started, must request the items in order from item 0.
    /// - PX4 answers only the expected item or the one before it; any other request aborts the
    ///   download with MAV_MISSION_ERROR (`handle_mission_request_both`: `wpr.seq ==
    ///   _transfer_seq` or `_transfer_seq - 1`, else `send_mission_ack(.., MAV_MISSION_ERROR)`).
    /// - MAVSDK ignores a request beyond the next item ("In mission_request_int: sequence
    ///   incorrect", `SendOutgoingMission::process_mission_request_int`).
    /// - ArduPilot answers any item at any time (`MissionItemProtocol::handle_mission_request_int`
    ///   calls `get_item(packet.seq)`), so a restarted read-back resumes where it stopped.
    pub fn download_in_order(self) -> bool {
        self != Flavour::ArduPilot
    }

    /// How often the autopilot repeats an unanswered item request during an upload: PX4 every
    /// 250 ms (`MAVLINK_MISSION_RETRY_TIMEOUT_DEFAULT`), ArduPilot every second
    /// (`MissionItemProtocol::update`: `wp_recv_timeout_ms = 1000 + stream slowdown`), MAVSDK
    /// on its 0.5 s default timeout. A request that comes this long after our item is the
    /// autopilot's own repeat, not an answer: it does not measure the round trip.
    pub fn rerequest_period(self) -> Duration {
        Duration::from_millis(match self {
            Flavour::Px4 => 250,
            Flavour::ArduPilot => 1000,
            Flavour::Generic => 500,
        })
    }

    /// How long the autopilot may stay silent during a download before it is taken to have
    /// abandoned it and a fresh MISSION_REQUEST_LIST is sent; None when it never abandons one.
    /// - PX4 gives a transfer up after 5 s without hearing from the ground
    ///   (`MAVLINK_MISSION_PROTOCOL_TIMEOUT_DEFAULT`), and a REQUEST_LIST from the same ground
    ///   station before that restarts its download at item 0 (`handle_mission_request_list`), so
    ///   not earlier.
    /// - MAVSDK sends an item at most 5 times and gives the download up after 5 timeouts of
    ///   0.5 s (`retries = 5`); while its download lives it ignores a REQUEST_LIST (MissionRawServer
    ///   answers Busy), so asking early costs nothing: after 1 s of silence.
    /// - ArduPilot keeps no download state (every request is answered from storage).
    pub fn download_restart_after(self) -> Option<Duration> {
        match self {
            Flavour::Px4 => Some(Duration::from_millis(5_000)),
            Flavour::Generic => Some(Duration::from_millis(1_000)),
            Flavour::ArduPilot => None,
        }
    }

    /// How long the autopilot may stay silent during an upload (no request for an item) before
    /// it is taken to have abandoned it and the upload starts again from MISSION_COUNT.
    /// - PX4 re-requests every 250 ms and gives up after 5 s without receiving
    ///   (`MAVLINK_MISSION_RETRY_TIMEOUT_DEFAULT`, `..._PROTOCOL_TIMEOUT_DEFAULT`); a COUNT
    ///   before then is refused with MAV_MISSION_ERROR ("busy", `handle_mission_count`).
    /// - ArduPilot re-requests every second and gives up after 8 s (`upload_timeout_ms = 8000`,
    ///   MissionItemProtocol.h), announcing it with MAV_MISSION_OPERATION_CANCELLED; a COUNT
    ///   before then restarts its upload at item 0 (`cancel_upload`).
    /// - MAVSDK requests an item 5 times, 0.5 s apart, then gives up silently
    ///   (`ReceiveIncomingMission::process_timeout`); a COUNT while it receives is ignored.
    pub fn upload_restart_after(self) -> Duration {
        match self {
            Flavour::Px4 => Duration::from_millis(5_500),
            Flavour::ArduPilot => Duration::from_millis(8_500),
            Flavour::Generic => Duration::from_millis(2_500),
        }
    }

    /// What a refusal during an upload means.
    /// - MAV_MISSION_INVALID_SEQUENCE: ArduPilot's answer to a repeated or early item, the
    ///   upload goes on (`MissionItemProtocol::handle_mission_item`).
    /// - MAV_MISSION_OPERATION_CANCELLED: the autopilot timed the upload out (ArduPilot's
    ///   `MissionItemProtocol::update`).
    /// - ArduPilot MAV_MISSION_NO_SPACE: its mission storage is not ready for the first seconds
    ///   after boot (`count > max_items()`; seen on SITL for about 10 s); MAV_MISSION_DENIED:
    ///   another ground station is uploading (`cancel_upload`).
    /// - PX4 MAV_MISSION_ERROR: busy with another transfer or a COUNT during one
    ///   (`handle_mission_count`).
    pub fn upload_refusal(self, result: MavMissionResult) -> Refusal {
        use MavMissionResult::*;
        match (self, result) {
            (_, MAV_MISSION_ACCEPTED | MAV_MISSION_INVALID_SEQUENCE) => Refusal::Ignore,
            (_, MAV_MISSION_OPERATION_CANCELLED) => Refusal::Restart,
            (Flavour::ArduPilot, MAV_MISSION_NO_SPACE | MAV_MISSION_DENIED) => Refusal::Transient,
            (Flavour::Px4, MAV_MISSION_ERROR) => Refusal::Transient,
            _ => Refusal::Final,
        }
    }

    /// What a refusal during a download means.
    /// - ArduPilot MAV_MISSION_DENIED: an upload is in progress (its own, until the deferred
    ///   final ack; `handle_mission_request_list`, `handle_mission_request_int`).
    /// - PX4 MAV_MISSION_ERROR: it aborted the download (an unexpected request,
    ///   `handle_mission_request_both`); ArduPilot MAV_MISSION_INVALID_SEQUENCE: the mission
    ///   is shorter than the count we hold; OPERATION_CANCELLED: given up. All start again.
    pub fn download_refusal(self, result: MavMissionResult) -> Refusal {
        use MavMissionResult::*;
        match (self, result) {
            (_, MAV_MISSION_ACCEPTED) => Refusal::Ignore,
            (_, MAV_MISSION_OPERATION_CANCELLED | MAV_MISSION_INVALID_SEQUENCE) => Refusal::Restart,
            (Flavour::Px4, MAV_MISSION_ERROR) => Refusal::Restart,
            (Flavour::ArduPilot, MAV_MISSION_DENIED) => Refusal::Transient,
            _ => Refusal::Final,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_heartbeat_names_the_flavour_and_the_flavour_its_heartbeat() {
        for flavour in [Flavour::Px4, Flavour::ArduPilot, Flavour::Generic] {
            assert_eq!(Flavour::from_autopilot(flavour.autopilot()), flavour);
        }
        assert_eq!(
            Flavour::from_autopilot(MavAutopilot::MAV_AUTOPILOT_INVALID),
            Flavour::Generic
        );
    }

    #[test]
    fn ardupilot_waits_out_no_space_at_boot_and_px4_takes_it_as_final() {
        use MavMissionResult::*;
        assert_eq!(
            Flavour::ArduPilot.upload_refusal(MAV_MISSION_NO_SPACE),
            Refusal::Transient
        );
        assert_eq!(
            Flavour::Px4.upload_refusal(MAV_MISSION_NO_SPACE),
            Refusal::Final
        );
        assert_eq!(
            Flavour::ArduPilot.upload_refusal(MAV_MISSION_INVALID_SEQUENCE),
            Refusal::Ignore
        );
        assert_eq!(
            Flavour::Generic.upload_refusal(MAV_MISSION_INVALID_PARAM7),
            Refusal::Final
        );
    }
}
