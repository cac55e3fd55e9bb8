//! The mock autopilot: a MAVLink vehicle that speaks the mission protocol as strictly as PX4
//! (or as ArduPilot), with seeded fault injection, for tests and for flights without a vehicle.
//!
//! `server` is the sans-IO protocol machine; `mock` the async shell that owns a UDP socket,
//! sends heartbeats and injects transport faults.

pub mod mock;
pub mod server;

pub use mock::{Faults, MockAutopilot, MockConfig, MockHandle, SimError};
pub use server::Flavour;
