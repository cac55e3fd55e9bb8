//! Telemetry at the MAVLink edge: the one place MAVLink units become SI ([`decode`]: cA, mV, degE7,
//! mm, cm/s, custom modes), the autopilot filter and vehicle clock in front of the flight log
//! ([`Telemetry`]: the same path live and in replay), raw frames to messages and back
//! ([`parse_frame`], [`frame_bytes`]), the inverse of `decode` for tests and simulations
//! ([`encode`]), and the stream-rate requests ([`StreamRequests`]: a sans-IO machine that sends
//! MAV_CMD_SET_MESSAGE_INTERVAL for each wanted message, one at a time, until COMMAND_ACK).
//!
//! The replay of a recorded .tlog is in two parts: what reads the file and measures the flight
//! (`flightlog::replay`: records, gaps, segmentation, the report; no MAVLink types) and what
//! needs MAVLink to do it (`tlog`: each frame's checksum and decoding, the mission it carries).

mod decode;
mod encode;
mod frame;
mod pipeline;
mod streams;
mod tlog;

/// What a replay gives (they live in `flightlog::replay`; here beside the functions that make them).
pub use crate::flightlog::replay::{Analysis, Replay};
pub use decode::{decode, is_autopilot, pack_named, Decoded, TelemetryDecoder};
pub use encode::encode;
pub use frame::{check_frame, frame_bytes, frame_bytes_versioned, parse_frame, TelemetryError};
pub use pipeline::Telemetry;
pub use streams::{
    default_streams, RequestOutcome, StreamConfig, StreamRequest, StreamRequests, StreamStats,
};
pub use tlog::{analyse_flight_dir, analyse_tlog, mission_in_tlog, open_tlog, replay_tlog};
