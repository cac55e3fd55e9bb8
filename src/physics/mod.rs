//! The vehicle energy model: rotor (blade element + momentum theory), motor and ESC, battery,
//! planar rigid body, flight profiles, operation simulation and the precomputed energy table.
//!
//! The model is the paper's (Michel et al., arXiv 2410.17585; docs/energy-model.md): per time step of a planned
//! trajectory the rigid body gives the thrust and pitch it needs, the rotor model the rotor speed
//! and torque that make that thrust at the rotor-frame inflow, the motor and ESC the electrical
//! power, and the battery the terminal voltage. Energy is battery terminal energy (what a power
//! module measures).
//!
//! Invariant: pure; no IO beyond loading a vehicle or table file, no tokio, no MAVLink.

pub mod ardupilot;
pub mod ardupilot_chain;
pub mod body;
pub mod budget;
pub mod builtin;
pub mod calibration;
pub mod longleg;
pub mod minimise;
pub mod model;
pub mod power;
pub mod powertrain;
pub mod profile;
pub mod px4;
pub mod rotor;
pub mod table;
pub mod trajectory;
pub mod vehicle;

pub use crate::mission::wind::{heading_deg, LegWind, Wind};
pub use budget::{BatteryCheck, Budget};
pub use model::{VehicleModel, VehicleSource};
pub use power::{hover_power_w, level_flight_power_w, simulate_operation, Operation};
pub use profile::Profile;
pub use px4::{start_case, Start};
pub use table::{EnergyTable, LegEnergy, Pricing};
pub use vehicle::Vehicle;

/// Everything the physics layer can refuse.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PhysicsError {
    #[error("{file}: {source_text}")]
    Io { file: String, source_text: String },
    #[error("pricing the {what}: {source}")]
    Pricing {
        what: &'static str,
        source: Box<PhysicsError>,
    },
    #[error("{file}:{line} {key}: {problem}")]
    VehicleFile {
        file: String,
        line: String,
        key: String,
        problem: String,
    },
    #[error("{what}: {value} is not a finite number")]
    NotFinite { what: &'static str, value: f64 },
    #[error(
        "thrust {thrust_n:.1} N per rotor cannot be produced at inflow v_x {v_x_m_s:.2} m/s, \
         v_z {v_z_m_s:.2} m/s (no rotor speed solves blade element and momentum theory)"
    )]
    NoRotorSolution {
        thrust_n: f64,
        v_x_m_s: f64,
        v_z_m_s: f64,
    },
    #[error(
        "motors saturated: {required_v:.2} V needed at {omega_rad_s:.0} rad/s but the battery \
         gives {available_v:.2} V (thrust {thrust_n:.1} N per rotor is beyond the motors)"
    )]
    MotorSaturated {
        required_v: f64,
        available_v: f64,
        omega_rad_s: f64,
        thrust_n: f64,
    },
    #[error("battery overloaded: {power_w:.0} W asked, at most {max_power_w:.0} W available")]
    BatteryOverload { power_w: f64, max_power_w: f64 },
    #[error("tilt {tilt_deg:.1} deg exceeds the {max_deg:.1} deg limit")]
    TiltLimit { tilt_deg: f64, max_deg: f64 },
    #[error(
        "windmill-brake state: the air flows up through the rotors ({inflow_m_s:.2} m/s) at \
         {v_x_m_s:.1} m/s in plane and {v_z_m_s:.1} m/s along the axis"
    )]
    WindmillBrake {
        inflow_m_s: f64,
        v_x_m_s: f64,
        v_z_m_s: f64,
    },
    #[error(
        "no feasible trajectory for Xf {xf_m:.2} m, Zf {zf_m:.2} m with the {profile} profile: \
         {reason}"
    )]
    NoTrajectory {
        xf_m: f64,
        zf_m: f64,
        profile: Profile,
        reason: String,
    },
    #[error(
        "leg Xf {xf_m:.2} m, Zf {zf_m:.2} m is outside the {profile} energy table \
         (Xf 0..{max_xf_m} m, Zf {min_zf_m}..{max_zf_m} m); the table is never extrapolated"
    )]
    OutsideTable {
        xf_m: f64,
        zf_m: f64,
        profile: Profile,
        max_xf_m: f64,
        min_zf_m: f64,
        max_zf_m: f64,
    },
    #[error(
        "leg Xf {xf_m:.2} m, Zf {zf_m:.2} m is outside the {profile} energy table \
         (Xf 0..{max_xf_m} m, Zf {min_zf_m}..{max_zf_m} m) and cannot be priced exactly beyond \
         it: {reason}; the table is never extrapolated"
    )]
    LongLeg {
        xf_m: f64,
        zf_m: f64,
        profile: Profile,
        max_xf_m: f64,
        min_zf_m: f64,
        max_zf_m: f64,
        reason: String,
    },
    #[error("{file}: built from other vehicle parameters (table {table_hash}, vehicle {vehicle_hash}): run `emplan table build --profile {profile}`")]
    StaleTable {
        file: String,
        profile: Profile,
        table_hash: String,
        vehicle_hash: String,
    },
    #[error("{file}: line {line}: {problem}")]
    TableFormat {
        file: String,
        line: usize,
        problem: String,
    },
    /// What a leg, take-off, landing or hover meets in a steady wind (`source` says why it
    /// cannot be flown): the wind is named, as it is what the vehicle fails against.
    #[error(
        "in the wind of {} m/s from {} deg (the vehicle cannot fly it): {source}",
        wind.speed_m_s,
        wind.from_deg
    )]
    InWind {
        wind: Wind,
        source: Box<PhysicsError>,
    },
}

impl PhysicsError {
    /// This error, naming `wind` when there is one (still air: unchanged).
    pub fn in_wind(self, wind: Wind) -> PhysicsError {
        if wind.is_calm() {
            self
        } else {
            PhysicsError::InWind {
                wind,
                source: Box::new(self),
            }
        }
    }
}
