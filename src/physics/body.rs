//! The rigid body in the vertical plane of a leg (X horizontal along the leg, Z up, pitch
//! Theta), with quasi-static pitch: the attitude that points the total thrust where the planned
//! acceleration needs it (the paper's vehicle model; docs/energy-model.md):
//!
//! F_x = m X'' + C_BD X'|X'|,  F_z = m (Z'' + g) + C_BDz Z'|Z'|,  T = |F|,  Theta = atan2(F_x, F_z)
//!
//! (the paper neglects the vertical body drag C_BDz; docs/energy-model.md keeps it), and the rotor-frame inflow
//! v_x = X' cos Theta - Z' sin Theta, v_z = X' sin Theta + Z' cos Theta. The pitch-rate term
//! Theta' x_j of the paper's per-rotor inflow is dropped: with quasi-static pitch all rotors
//! share one operating point (energy effect below 1-2 %, research section 9.3).

use super::vehicle::Vehicle;

/// What one rotor must do at a kinematic state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotorDemand {
    pub thrust_n: f64,
    pub pitch_rad: f64,
    pub v_x_m_s: f64,
    pub v_z_m_s: f64,
}

/// The per-rotor thrust, pitch and rotor-frame inflow for velocity (vx, vz) and acceleration
/// (ax, az) in the leg's plane.
pub fn demand(
    vehicle: &Vehicle,
    vx_m_s: f64,
    vz_m_s: f64,
    ax_m_s2: f64,
    az_m_s2: f64,
) -> RotorDemand {
    let b = &vehicle.body;
    let fx = b.mass_kg * ax_m_s2 + b.drag_coefficient_n_s2_m2 * vx_m_s * vx_m_s.abs();
    let fz = b.mass_kg * (az_m_s2 + b.gravity_m_s2)
        + b.vertical_drag_coefficient_n_s2_m2 * vz_m_s * vz_m_s.abs();
    let pitch = fx.atan2(fz);
    let (s, c) = pitch.sin_cos();
    RotorDemand {
        thrust_n: fx.hypot(fz) / f64::from(vehicle.rotor.count),
        pitch_rad: pitch,
        v_x_m_s: vx_m_s * c - vz_m_s * s,
        v_z_m_s: vx_m_s * s + vz_m_s * c,
    }
}
