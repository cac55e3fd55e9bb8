//! Everything MAVLink on the ground-control side: connections, heartbeat, autopilot discovery,
//! mission item conversion, the mission protocol as sans-IO state machines with a thin async
//! driver.
//!
//! Invariant: this module and `sim` are the only ones that know MAVLink types; degE7 and the
//! MAVLink frames are converted here, once.

pub mod commands;
pub mod connection;
pub mod driver;
pub mod fence;
pub mod flavour;
pub mod flight;
pub mod home;
pub mod items;
pub mod locate;
pub mod pack;
pub mod params;
pub mod readback;
pub mod support;
pub mod telemetry;
pub mod testing;
pub mod transfer;
pub mod wind;

pub use flavour::Flavour;
pub use mavlink::dialects::ardupilotmega as mav;

/// Errors of the link layer.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    #[error("connection {url}: {reason}")]
    Connect { url: String, reason: String },
    /// A connection URL of no form the link opens (or naming a serial device that is absent),
    /// found before anything is opened or waited for.
    #[error("connection {url}: {reason} (expected {})", connection::URL_FORMS)]
    Url { url: String, reason: String },
    #[error("no autopilot heartbeat on {url} within {seconds} s")]
    NoAutopilot { url: String, seconds: f64 },
    #[error("link closed: {0}")]
    Closed(String),
    #[error("sending {what}: {reason}")]
    Send { what: String, reason: String },
    #[error("signing key {file}: {reason}")]
    SigningKey { file: String, reason: String },
}

/// How emplan signs with `key` (link id 0; unsigned frames from the vehicle refused).
pub fn signing_config(key: [u8; 32]) -> mavlink::SigningConfig {
    mavlink::SigningConfig::new(key, 0, true, false)
}

/// Reads a MAVLink 2 signing key file: 32 raw bytes, or 64 hexadecimal characters (optionally
/// surrounded by whitespace), the secret shared with the vehicle.
pub fn read_signing_key(path: &std::path::Path) -> Result<[u8; 32], LinkError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| LinkError::SigningKey {
        file: file.clone(),
        reason: e.to_string(),
    })?;
    if bytes.len() == 32 {
        let mut key = [0u8; 32];
        key.copy_from_slice(&bytes);
        return Ok(key);
    }
    let text = String::from_utf8_lossy(&bytes);
    let hex = text.trim();
    if hex.len() != 64 || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(LinkError::SigningKey {
            file,
            reason: "expected 32 raw bytes or 64 hexadecimal characters".into(),
        });
    }
    let mut key = [0u8; 32];
    for (k, byte) in key.iter_mut().enumerate() {
        *byte =
            u8::from_str_radix(&hex[2 * k..2 * k + 2], 16).map_err(|e| LinkError::SigningKey {
                file: file.clone(),
                reason: e.to_string(),
            })?;
    }
    Ok(key)
}

/// Every MAV_MISSION_RESULT, for parsing names given on the command line.
pub const MISSION_RESULTS: [mav::MavMissionResult; 16] = {
    use mav::MavMissionResult::*;
    [
        MAV_MISSION_ACCEPTED,
        MAV_MISSION_ERROR,
        MAV_MISSION_UNSUPPORTED_FRAME,
        MAV_MISSION_UNSUPPORTED,
        MAV_MISSION_NO_SPACE,
        MAV_MISSION_INVALID,
        MAV_MISSION_INVALID_PARAM1,
        MAV_MISSION_INVALID_PARAM2,
        MAV_MISSION_INVALID_PARAM3,
        MAV_MISSION_INVALID_PARAM4,
        MAV_MISSION_INVALID_PARAM5_X,
        MAV_MISSION_INVALID_PARAM6_Y,
        MAV_MISSION_INVALID_PARAM7,
        MAV_MISSION_INVALID_SEQUENCE,
        MAV_MISSION_DENIED,
        MAV_MISSION_OPERATION_CANCELLED,
    ]
};

/// A MAV_MISSION_RESULT from its name (`MAV_MISSION_DENIED` or `DENIED`, any case) or number.
pub fn parse_mission_result(text: &str) -> Option<mav::MavMissionResult> {
    let upper = text.trim().to_ascii_uppercase();
    if let Ok(n) = upper.parse::<usize>() {
        return MISSION_RESULTS.get(n).copied();
    }
    MISSION_RESULTS.iter().copied().find(|r| {
        let name = format!("{r:?}");
        name == upper || name.strip_prefix("MAV_MISSION_") == Some(upper.as_str())
    })
}

/// MAV_CMD_REQUEST_MESSAGE to `target` for the message `id` (sent once; the autopilot answers
/// with the message, and acknowledges or refuses the command).
pub(crate) fn request_message(target: &connection::Autopilot, id: u32) -> mav::MavMessage {
    mav::MavMessage::COMMAND_LONG(mav::COMMAND_LONG_DATA {
        command: mav::MavCmd::MAV_CMD_REQUEST_MESSAGE,
        param1: id as f32,
        target_system: target.system_id,
        target_component: target.component_id,
        ..Default::default()
    })
}
