//! Everything MAVLink on the ground-control side: connections, heartbeat, autopilot discovery,
//! mission item conversion, the mission protocol as sans-IO state machines with a thin async
//! driver, telemetry subscription and signing.
