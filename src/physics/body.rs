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
//!
//! A descent's Z' < 0 enters the inflow scaled by `rotor.descent_inflow_factor` (1: the whole
//! descent, momentum theory's and the paper's; docs/energy-model.md "Descent"), and the whole
//! rotor-frame airspeed then by `rotor.airflow_factor` (1: all of it, as the paper's model; 0:
//! a rotor that works at every airspeed as in hover; docs/energy-model.md "Airflow"); the forces
//! change with neither.

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
    // A descent reaches the rotors' inflow by its share (1: momentum theory's whole descent).
    let vz_m_s = if vz_m_s < 0.0 {
        vz_m_s * vehicle.rotor.descent_inflow_factor
    } else {
        vz_m_s
    };
    let airflow = vehicle.rotor.airflow_factor;
    RotorDemand {
        thrust_n: fx.hypot(fz) / f64::from(vehicle.rotor.count),
        pitch_rad: pitch,
        v_x_m_s: airflow * (vx_m_s * c - vz_m_s * s),
        v_z_m_s: airflow * (vx_m_s * s + vz_m_s * c),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::vehicle::shipped;

    #[test]
    fn the_descent_inflow_factor_scales_only_a_descent_in_the_rotors_inflow() {
        let v = shipped();
        assert_eq!(v.rotor.descent_inflow_factor, 1.0);
        let mut none = v.clone();
        none.rotor.descent_inflow_factor = 0.0;
        let mut half = v.clone();
        half.rotor.descent_inflow_factor = 0.5;
        // A climb and level flight are the same whatever the factor.
        for (vx, vz, ax, az) in [(5.0, 2.0, 0.5, 0.1), (8.0, 0.0, 0.0, 0.0)] {
            assert_eq!(demand(&none, vx, vz, ax, az), demand(&v, vx, vz, ax, az));
        }
        // A descent: the same thrust and pitch, the inflow of a descent at the factor's share.
        let (vx, vz, ax, az) = (4.0, -2.0, 0.3, -0.2);
        let full = demand(&v, vx, vz, ax, az);
        let at_half = demand(&half, vx, vz, ax, az);
        let at_none = demand(&none, vx, vz, ax, az);
        assert_eq!(
            (at_half.thrust_n, at_half.pitch_rad),
            (full.thrust_n, full.pitch_rad)
        );
        let (s, c) = full.pitch_rad.sin_cos();
        assert!((at_half.v_z_m_s - (vx * s + 0.5 * vz * c)).abs() < 1e-12);
        assert!((at_none.v_z_m_s - vx * s).abs() < 1e-12);
        assert!((at_none.v_x_m_s - vx * c).abs() < 1e-12);
        assert!(full.v_z_m_s < at_half.v_z_m_s && at_half.v_z_m_s < at_none.v_z_m_s);
    }

    #[test]
    fn the_airflow_factor_scales_the_rotors_airspeed_and_leaves_the_forces() {
        let v = shipped();
        assert_eq!(v.rotor.airflow_factor, 1.0);
        let mut none = v.clone();
        none.rotor.airflow_factor = 0.0;
        let mut share = v.clone();
        share.rotor.airflow_factor = 0.3;
        for (vx, vz, ax, az) in [
            (5.0, 2.0, 0.5, 0.1),
            (8.0, 0.0, 0.0, 0.0),
            (4.0, -2.0, 0.3, -0.2),
        ] {
            let full = demand(&v, vx, vz, ax, az);
            let part = demand(&share, vx, vz, ax, az);
            let still = demand(&none, vx, vz, ax, az);
            for d in [part, still] {
                assert_eq!((d.thrust_n, d.pitch_rad), (full.thrust_n, full.pitch_rad));
            }
            assert!((part.v_x_m_s - 0.3 * full.v_x_m_s).abs() < 1e-12);
            assert!((part.v_z_m_s - 0.3 * full.v_z_m_s).abs() < 1e-12);
            assert_eq!((still.v_x_m_s, still.v_z_m_s), (0.0, 0.0));
        }
    }
}
