//! The mock autopilot: a MAVLink vehicle that speaks the mission protocol as strictly as PX4
//! (or as ArduPilot), with seeded fault injection, for tests and for flights without a vehicle.
//!
//! `server` is the sans-IO protocol machine (one behaviour per `link::Flavour`), `storage` what
//! each flavour keeps of an item; `mock` the async shell that owns a UDP socket, sends
//! heartbeats and injects transport faults.

pub mod mock;
pub mod server;
pub mod storage;

pub use mock::{Faults, MockAutopilot, MockConfig, MockHandle, SimError};
pub use storage::Home;
