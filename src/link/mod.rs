//! Everything MAVLink on the ground-control side: connections, heartbeat, autopilot discovery,
//! mission item conversion, the mission protocol as sans-IO state machines with a thin async
//! driver.
//!
//! Invariant: this module and `sim` are the only ones that know MAVLink types; degE7 and the
//! MAVLink frames are converted here, once.

pub mod connection;
pub mod driver;
pub mod items;
pub mod transfer;

pub use mavlink::dialects::ardupilotmega as mav;

/// Which autopilot firmware answers (from its HEARTBEAT's `autopilot` field).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Flavour {
    Px4,
    ArduPilot,
    Generic,
}

impl Flavour {
    /// The flavour a HEARTBEAT's autopilot field names.
    pub fn from_autopilot(autopilot: mav::MavAutopilot) -> Flavour {
        match autopilot {
            mav::MavAutopilot::MAV_AUTOPILOT_PX4 => Flavour::Px4,
            mav::MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA => Flavour::ArduPilot,
            _ => Flavour::Generic,
        }
    }
}

/// Errors of the link layer.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    #[error("connection {url}: {reason}")]
    Connect { url: String, reason: String },
    #[error("no autopilot heartbeat on {url} within {seconds} s")]
    NoAutopilot { url: String, seconds: f64 },
    #[error("link closed: {0}")]
    Closed(String),
    #[error("sending {what}: {reason}")]
    Send { what: String, reason: String },
    #[error("signing key {file}: {reason}")]
    SigningKey { file: String, reason: String },
}
