//! The vehicle energy model: rotor (blade element + momentum theory), motor and ESC, battery,
//! planar rigid body, flight profiles, operation simulation and the precomputed energy table.
//!
//! Invariant: pure; no IO beyond loading a vehicle or table file, no tokio, no MAVLink.
