//! The mock autopilot: a MAVLink vehicle that speaks the mission protocol as strictly as PX4
//! (or as ArduPilot), with seeded fault injection, for tests and for flights without a vehicle.
//!
//! `server` is the sans-IO protocol machine (one behaviour per `link::Flavour`), `storage` what
//! each flavour keeps of an item; `mock` the async shell that owns a UDP socket, sends
//! heartbeats and injects transport faults. The simulated flight is sans-IO too: `flight` (the
//! motion along the mission, physics power), `battery` (pack and monitor) and `vehicle`
//! (commands, modes, telemetry streams and faults, per flavour). `battery_sim` is the same pack
//! for a real autopilot that has none (PX4 SITL): it follows the vehicle's motion in its
//! telemetry and reports the physics model's battery as a smart battery (`emplan battery-sim`);
//! `battery_link` is its socket.

pub mod battery;
pub mod battery_link;
pub mod battery_sim;
pub mod flight;
pub mod mock;
pub mod server;
pub mod storage;
pub mod vehicle;

pub use mock::{Faults, MockAutopilot, MockConfig, MockHandle, SimError, DEFAULT_SPEEDUP};
pub use storage::Home;
pub use vehicle::{FlightConfig, Gap, SimVehicle, Snapshot, TelemetryFaults, WindChange};
