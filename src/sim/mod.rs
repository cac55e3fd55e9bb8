//! The mock autopilot: a MAVLink vehicle that speaks the mission protocol as strictly as PX4
//! (or as ArduPilot), with seeded fault injection, for tests and for flights without a vehicle.
