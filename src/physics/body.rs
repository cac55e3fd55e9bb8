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
//!
//! In wind ([`demand_in_wind`]) the body and rotors see the airspeed, the ground velocity
//! minus the wind, in 3D: the horizontal drag opposes the air-relative horizontal velocity (a
//! crosswind adds a force across the leg the thrust must lean into, the vehicle crabs), the
//! thrust axis is the required force's direction, and the rotor's through-disk and in-plane
//! airflow are the air-relative velocity's components along and across that axis. In still air
//! it is [`demand`] itself.

use super::vehicle::Vehicle;
use crate::mission::wind::LegWind;

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

/// [`demand`] in a steady wind `wind` (the air's velocity along and across the leg): the
/// horizontal body drag `C_BD |u| u` on the air-relative horizontal velocity
/// `u = (X' - w_along, -w_cross)`, the thrust along the required force
/// `F = (m X'' + C_BD |u| u_along, C_BD |u| u_cross, m (Z'' + g) + C_BDz Z'|Z'|)`, and the
/// rotor-frame inflow from the air-relative velocity `(u, Z')`: `v_z` its component along the
/// thrust axis, `v_x` the magnitude of the rest (the rotor model uses only its square). Its
/// `pitch_rad` is the tilt from upright (not signed). A calm wind is [`demand`] exactly.
pub fn demand_in_wind(
    vehicle: &Vehicle,
    vx_m_s: f64,
    vz_m_s: f64,
    ax_m_s2: f64,
    az_m_s2: f64,
    wind: LegWind,
) -> RotorDemand {
    if wind.is_calm() {
        return demand(vehicle, vx_m_s, vz_m_s, ax_m_s2, az_m_s2);
    }
    let b = &vehicle.body;
    let (u_along, u_cross) = (vx_m_s - wind.along_m_s, -wind.cross_m_s);
    let u_h = u_along.hypot(u_cross);
    let drag = b.drag_coefficient_n_s2_m2 * u_h;
    let f = [
        b.mass_kg * ax_m_s2 + drag * u_along,
        drag * u_cross,
        b.mass_kg * (az_m_s2 + b.gravity_m_s2)
            + b.vertical_drag_coefficient_n_s2_m2 * vz_m_s * vz_m_s.abs(),
    ];
    let f_h = f[0].hypot(f[1]);
    let thrust = f_h.hypot(f[2]);
    let vz_m_s = if vz_m_s < 0.0 {
        vz_m_s * vehicle.rotor.descent_inflow_factor
    } else {
        vz_m_s
    };
    let u = [u_along, u_cross, vz_m_s];
    let through = if thrust > 0.0 {
        (u[0] * f[0] + u[1] * f[1] + u[2] * f[2]) / thrust
    } else {
        u[2]
    };
    let speed_sq = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    let in_plane = (speed_sq - through * through).max(0.0).sqrt();
    let airflow = vehicle.rotor.airflow_factor;
    RotorDemand {
        thrust_n: thrust / f64::from(vehicle.rotor.count),
        pitch_rad: f_h.atan2(f[2]),
        v_x_m_s: airflow * in_plane,
        v_z_m_s: airflow * through,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::vehicle::shipped;

    #[test]
    fn in_a_wind_that_dies_away_the_demand_becomes_the_still_air_one() {
        let v = shipped();
        for (vx, vz, ax, az) in [
            (5.0, 2.0, 0.5, 0.1),
            (8.0, 0.0, 0.0, 0.0),
            (4.0, -2.0, 0.3, -0.2),
            (-1.0, 0.5, -0.4, 0.0),
        ] {
            let still = demand(&v, vx, vz, ax, az);
            assert_eq!(demand_in_wind(&v, vx, vz, ax, az, LegWind::CALM), still);
            let faint = demand_in_wind(
                &v,
                vx,
                vz,
                ax,
                az,
                LegWind {
                    along_m_s: 1e-9,
                    cross_m_s: 1e-9,
                },
            );
            assert!((faint.thrust_n - still.thrust_n).abs() < 1e-6);
            assert!((faint.pitch_rad - still.pitch_rad.abs()).abs() < 1e-6);
            assert!((faint.v_x_m_s - still.v_x_m_s.abs()).abs() < 1e-6);
            assert!((faint.v_z_m_s - still.v_z_m_s).abs() < 1e-6);
        }
    }

    #[test]
    fn a_headwind_is_flying_faster_through_the_air_and_a_crosswind_leans_the_thrust_across() {
        let v = shipped();
        // Hovering in a 6 m/s wind from ahead is flying at 6 m/s in still air.
        let head = LegWind {
            along_m_s: -6.0,
            cross_m_s: 0.0,
        };
        let hover_in_wind = demand_in_wind(&v, 0.0, 0.0, 0.0, 0.0, head);
        let flying = demand(&v, 6.0, 0.0, 0.0, 0.0);
        assert!((hover_in_wind.thrust_n - flying.thrust_n).abs() < 1e-9);
        assert!((hover_in_wind.pitch_rad - flying.pitch_rad).abs() < 1e-12);
        assert!((hover_in_wind.v_x_m_s - flying.v_x_m_s).abs() < 1e-9);
        assert!((hover_in_wind.v_z_m_s - flying.v_z_m_s).abs() < 1e-9);
        // The same wind across the leg: the same magnitudes, whichever side it comes from.
        for side in [-6.0, 6.0] {
            let cross = demand_in_wind(
                &v,
                0.0,
                0.0,
                0.0,
                0.0,
                LegWind {
                    along_m_s: 0.0,
                    cross_m_s: side,
                },
            );
            assert!((cross.thrust_n - flying.thrust_n).abs() < 1e-9);
            assert!((cross.v_x_m_s - flying.v_x_m_s).abs() < 1e-9);
            assert!((cross.v_z_m_s - flying.v_z_m_s).abs() < 1e-9);
        }
        // Flying at 5 m/s with 3 m/s behind is flying at 2 m/s through the air.
        let tail = LegWind {
            along_m_s: 3.0,
            cross_m_s: 0.0,
        };
        let d = demand_in_wind(&v, 5.0, 0.0, 0.0, 0.0, tail);
        let slow = demand(&v, 2.0, 0.0, 0.0, 0.0);
        assert!((d.thrust_n - slow.thrust_n).abs() < 1e-9);
        assert!((d.v_z_m_s - slow.v_z_m_s).abs() < 1e-9);
    }

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
