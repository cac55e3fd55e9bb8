//! One rotor: blade element theory coupled with momentum theory, in the paper's form
//! (the paper's rotor model):
//!
//! T = (1/2pi) int_psi int_{R0}^{B R} 1/2 N rho u_pl^2 c a (theta - u_pr/u_pl) dr dpsi
//! Q = (1/2pi) int_psi int_{R0}^{R} 1/2 N r rho u_pl^2 c (phi a (theta - u_pr/u_pl) + c_d) dr dpsi
//! u_pl = Omega r + v_x sin psi, u_pr = v_i + v_z, phi = u_pr/u_pl (small angle, as the paper).
//!
//! Under the paper's small-angle assumptions the integrands are polynomials in sin psi, so the
//! azimuth average is exact in closed form (<u_pl> = Omega r, <u_pl^2> = Omega^2 r^2 + v_x^2/2):
//!
//! T = 1/2 N rho a [Omega^2 I(c theta r^2) + v_x^2/2 I(c theta) - u_pr Omega I(c r)]     (B R)
//! Q = 1/2 N rho [a u_pr Omega I(c theta r^2) - a u_pr^2 I(c r) + c_d (Omega^2 I(c r^3)
//!     + v_x^2/2 I(c r))]                                                                (R)
//!
//! with the radial integrals I(.) computed once per rotor. The induced velocity comes from
//! Glauert's momentum theory, T = 2 rho A v_i sqrt(v_x^2 + (v_z + v_i)^2) (Leishman,
//! "Principles of Helicopter Aerodynamics", 2nd ed., eq. 2.128), which with the thrust known
//! gives v_i alone; the blade elements see kappa v_i (the induced power factor: non-uniform
//! inflow, Leishman section 3.3), and the thrust equation is then a quadratic in Omega. A rotor
//! solve is O(1).
//! The double integral itself is kept (`integrate_numerically`) and the tests check the closed
//! form against it.

use super::vehicle::Vehicle;
use super::PhysicsError;

/// Radial integrals of one rotor, and the constants in front of them.
#[derive(Debug, Clone, PartialEq)]
pub struct Rotor {
    /// 1/2 N rho (N blades).
    half_n_rho: f64,
    lift_slope_per_rad: f64,
    drag_coefficient: f64,
    /// kappa: the inflow through the blades is kappa times momentum theory's induced velocity.
    induced_power_factor: f64,
    disk_area_m2: f64,
    air_density_kg_m3: f64,
    /// Over R0..B R: I(c theta r^2), I(c theta), I(c r).
    thrust_c_theta_r2: f64,
    thrust_c_theta: f64,
    thrust_c_r: f64,
    /// Over R0..R: I(c theta r^2), I(c r), I(c r^3).
    torque_c_theta_r2: f64,
    torque_c_r: f64,
    torque_c_r3: f64,
}

/// The rotor's operating point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotorState {
    pub omega_rad_s: f64,
    pub induced_velocity_m_s: f64,
    pub torque_n_m: f64,
    pub thrust_n: f64,
}

/// Blade twist at radius `r`: helical from the geometric pitch plus a collective offset.
fn twist_rad(vehicle: &Vehicle, r_m: f64) -> f64 {
    let rp = &vehicle.rotor;
    (rp.geometric_pitch_m / (2.0 * std::f64::consts::PI * r_m)).atan()
        + rp.collective_offset_deg.to_radians()
}

/// Midpoint-rule integral of `f` over [a, b] with `n` panels.
fn integrate(a: f64, b: f64, n: usize, f: impl Fn(f64) -> f64) -> f64 {
    let h = (b - a) / n as f64;
    (0..n).map(|k| f(a + (k as f64 + 0.5) * h)).sum::<f64>() * h
}

impl Rotor {
    /// Precomputes the radial integrals for a vehicle's rotor (2000 panels: exact to 1e-7).
    pub fn new(vehicle: &Vehicle) -> Rotor {
        let rp = &vehicle.rotor;
        let c = rp.chord_m;
        let (r0, r_tip) = (rp.root_cutout_m, rp.radius_m);
        let r_thrust = rp.tip_loss_factor * r_tip;
        let n = 2000;
        let th = |r: f64| twist_rad(vehicle, r);
        Rotor {
            half_n_rho: 0.5 * f64::from(rp.blades) * vehicle.body.air_density_kg_m3,
            lift_slope_per_rad: rp.lift_slope_per_rad,
            drag_coefficient: rp.drag_coefficient,
            induced_power_factor: rp.induced_power_factor,
            disk_area_m2: std::f64::consts::PI * r_tip * r_tip,
            air_density_kg_m3: vehicle.body.air_density_kg_m3,
            thrust_c_theta_r2: integrate(r0, r_thrust, n, |r| c * th(r) * r * r),
            thrust_c_theta: integrate(r0, r_thrust, n, |r| c * th(r)),
            thrust_c_r: integrate(r0, r_thrust, n, |r| c * r),
            torque_c_theta_r2: integrate(r0, r_tip, n, |r| c * th(r) * r * r),
            torque_c_r: integrate(r0, r_tip, n, |r| c * r),
            torque_c_r3: integrate(r0, r_tip, n, |r| c * r * r * r),
        }
    }

    /// Disk area A = pi R^2.
    pub fn disk_area_m2(&self) -> f64 {
        self.disk_area_m2
    }

    /// Blade-element thrust at rotor speed `omega` and perpendicular inflow `u_pr`.
    pub fn thrust_n(&self, omega_rad_s: f64, v_x_m_s: f64, u_pr_m_s: f64) -> f64 {
        self.half_n_rho
            * self.lift_slope_per_rad
            * (omega_rad_s * omega_rad_s * self.thrust_c_theta_r2
                + 0.5 * v_x_m_s * v_x_m_s * self.thrust_c_theta
                - u_pr_m_s * omega_rad_s * self.thrust_c_r)
    }

    /// Blade-element torque at rotor speed `omega` and perpendicular inflow `u_pr`.
    pub fn torque_n_m(&self, omega_rad_s: f64, v_x_m_s: f64, u_pr_m_s: f64) -> f64 {
        let a = self.lift_slope_per_rad;
        self.half_n_rho
            * (a * u_pr_m_s * omega_rad_s * self.torque_c_theta_r2
                - a * u_pr_m_s * u_pr_m_s * self.torque_c_r
                + self.drag_coefficient
                    * (omega_rad_s * omega_rad_s * self.torque_c_r3
                        + 0.5 * v_x_m_s * v_x_m_s * self.torque_c_r))
    }

    /// Induced velocity from Glauert's momentum theory for a rotor making `thrust_n` at
    /// rotor-frame inflow (`v_x` in plane, `v_z` along the axis, positive when the vehicle moves
    /// along its thrust, i.e. climbing). Safeguarded Newton on a bracket; always finite.
    pub fn induced_velocity_m_s(&self, thrust_n: f64, v_x_m_s: f64, v_z_m_s: f64) -> f64 {
        let target = thrust_n / (2.0 * self.air_density_kg_m3 * self.disk_area_m2);
        if target <= 0.0 {
            return 0.0;
        }
        let g = |vi: f64| vi * v_x_m_s.hypot(v_z_m_s + vi) - target;
        // Beyond vi = -v_z (the knee) the function increases monotonically: one root at most,
        // the normal working state. Below the knee (descent: the air flows up through the disk,
        // the windmill-brake state) g rises from -target, peaks where
        // 2 vi^2 - 3 k vi + k^2 + v_x^2 = 0 (k the knee) when k^2 > 8 v_x^2, and may dip again.
        // The windmill-brake root is the smallest one: below that peak when the peak reaches
        // zero (in axial descent: once faster than twice the hover induced velocity, Leishman
        // chapter 2), else below the knee when g(knee) >= 0. Only without either is the flow
        // down through the disk.
        let knee = (-v_z_m_s).max(0.0);
        let disc = knee * knee - 8.0 * v_x_m_s * v_x_m_s;
        let peak = (disc > 0.0).then(|| (3.0 * knee - disc.sqrt()) / 4.0);
        let (mut lo, mut hi) = if let Some(peak) = peak.filter(|&p| g(p) >= 0.0) {
            (0.0, peak)
        } else if g(knee) >= 0.0 {
            (0.0, knee)
        } else {
            let mut hi = knee + target.sqrt() + 1.0;
            while g(hi) < 0.0 {
                hi *= 2.0;
            }
            (knee, hi)
        };
        let mut vi = 0.5 * (lo + hi);
        for _ in 0..100 {
            let value = g(vi);
            if value.abs() <= 1e-12 * target.max(1.0) {
                break;
            }
            if value < 0.0 {
                lo = vi;
            } else {
                hi = vi;
            }
            let h = v_x_m_s.hypot(v_z_m_s + vi);
            let slope = if h > 0.0 {
                h + vi * (v_z_m_s + vi) / h
            } else {
                0.0
            };
            let newton = vi - value / slope;
            vi = if slope > 0.0 && newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            if hi - lo < 1e-13 {
                break;
            }
        }
        vi
    }

    /// The rotor speed and torque that make `thrust_n` at the given rotor-frame inflow.
    pub fn solve(
        &self,
        thrust_n: f64,
        v_x_m_s: f64,
        v_z_m_s: f64,
    ) -> Result<RotorState, PhysicsError> {
        for (what, value) in [
            ("thrust_n", thrust_n),
            ("v_x_m_s", v_x_m_s),
            ("v_z_m_s", v_z_m_s),
        ] {
            if !value.is_finite() {
                return Err(PhysicsError::NotFinite { what, value });
            }
        }
        let no_solution = PhysicsError::NoRotorSolution {
            thrust_n,
            v_x_m_s,
            v_z_m_s,
        };
        if thrust_n < 0.0 {
            return Err(no_solution);
        }
        // Momentum theory's uniform induced velocity, made non-uniform-equivalent by kappa.
        let v_i = self.induced_power_factor * self.induced_velocity_m_s(thrust_n, v_x_m_s, v_z_m_s);
        let u_pr = v_i + v_z_m_s;
        // Thrust equation A Omega^2 - B Omega + C = 0; the larger root is the physical one.
        let k = self.half_n_rho * self.lift_slope_per_rad;
        let a = self.thrust_c_theta_r2;
        let b = u_pr * self.thrust_c_r;
        let c = 0.5 * v_x_m_s * v_x_m_s * self.thrust_c_theta - thrust_n / k;
        let disc = b * b - 4.0 * a * c;
        if disc < 0.0 || a <= 0.0 {
            return Err(no_solution);
        }
        let omega = (b + disc.sqrt()) / (2.0 * a);
        if !(omega > 0.0 && omega.is_finite()) {
            return Err(no_solution);
        }
        Ok(RotorState {
            omega_rad_s: omega,
            induced_velocity_m_s: v_i,
            torque_n_m: self.torque_n_m(omega, v_x_m_s, u_pr),
            thrust_n,
        })
    }
}

/// The paper's double integral evaluated numerically (midpoint rule, `nr` radial by `npsi`
/// azimuthal points): the reference the closed form is tested against. Returns (T, Q).
pub fn integrate_numerically(
    vehicle: &Vehicle,
    omega_rad_s: f64,
    v_x_m_s: f64,
    u_pr_m_s: f64,
    nr: usize,
    npsi: usize,
) -> (f64, f64) {
    let rp = &vehicle.rotor;
    let rho = vehicle.body.air_density_kg_m3;
    let n_b = f64::from(rp.blades);
    let (a, cd, c) = (rp.lift_slope_per_rad, rp.drag_coefficient, rp.chord_m);
    let two_pi = 2.0 * std::f64::consts::PI;
    let element = |r: f64, psi: f64, torque: bool| {
        let u_pl = omega_rad_s * r + v_x_m_s * psi.sin();
        let theta = twist_rad(vehicle, r);
        if torque {
            // phi a (theta - u_pr/u_pl) u_pl^2 with phi = u_pr/u_pl, expanded to avoid 0/0.
            0.5 * n_b
                * r
                * rho
                * c
                * (a * (theta * u_pr_m_s * u_pl - u_pr_m_s * u_pr_m_s) + cd * u_pl * u_pl)
        } else {
            0.5 * n_b * rho * c * a * (theta * u_pl * u_pl - u_pr_m_s * u_pl)
        }
    };
    let thrust = integrate(0.0, two_pi, npsi, |psi| {
        integrate(
            rp.root_cutout_m,
            rp.tip_loss_factor * rp.radius_m,
            nr,
            |r| element(r, psi, false),
        )
    }) / two_pi;
    let torque = integrate(0.0, two_pi, npsi, |psi| {
        integrate(rp.root_cutout_m, rp.radius_m, nr, |r| element(r, psi, true))
    }) / two_pi;
    (thrust, torque)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::vehicle::shipped;

    #[test]
    fn the_closed_form_matches_the_papers_double_integral_in_hover_climb_and_forward_flight() {
        let v = shipped();
        let rotor = Rotor::new(&v);
        for &(omega, v_x, u_pr) in &[
            (520.0, 0.0, 5.0),
            (600.0, 0.0, 9.0),
            (480.0, 12.0, 3.0),
            (450.0, 6.0, -1.0),
        ] {
            let (t_num, q_num) = integrate_numerically(&v, omega, v_x, u_pr, 400, 64);
            let t = rotor.thrust_n(omega, v_x, u_pr);
            let q = rotor.torque_n_m(omega, v_x, u_pr);
            assert!((t - t_num).abs() < 1e-4 * t_num.abs(), "T {t} vs {t_num}");
            assert!((q - q_num).abs() < 1e-4 * q_num.abs(), "Q {q} vs {q_num}");
        }
    }

    #[test]
    fn a_solved_rotor_state_satisfies_both_blade_element_and_momentum_theory() {
        let v = shipped();
        let rotor = Rotor::new(&v);
        for &(thrust, v_x, v_z) in &[
            (7.4, 0.0, 0.0),
            (9.0, 0.0, 3.0),
            (7.5, 10.0, 1.0),
            (7.0, 0.0, -4.0),
            (6.0, 3.0, -9.0),
        ] {
            let s = rotor.solve(thrust, v_x, v_z).unwrap();
            let bet = rotor.thrust_n(s.omega_rad_s, v_x, s.induced_velocity_m_s + v_z);
            // The blades see kappa times momentum theory's induced velocity.
            let vi = s.induced_velocity_m_s / v.rotor.induced_power_factor;
            let momentum = 2.0 * 1.2 * rotor.disk_area_m2() * vi * v_x.hypot(v_z + vi);
            assert!(
                (bet - thrust).abs() < 1e-9 * thrust,
                "BET {bet} vs {thrust}"
            );
            assert!(
                (momentum - thrust).abs() < 1e-8 * thrust,
                "momentum {momentum} vs {thrust}"
            );
            // Deep descent (v_z = -9 m/s, beyond twice the hover induced velocity) windmills:
            // the air drives the rotor, so only there may the torque be negative.
            assert!(
                s.omega_rad_s > 100.0 && (s.torque_n_m > 0.0 || v_z < -8.0),
                "{s:?}"
            );
        }
    }

    #[test]
    fn fast_axial_descent_is_the_windmill_brake_state_of_momentum_theory() {
        let rotor = Rotor::new(&shipped());
        let thrust = 7.4;
        let vh = (thrust / (2.0 * 1.2 * rotor.disk_area_m2())).sqrt();
        // Axial flight: v_i (v_z + v_i) = +-v_h^2. Climb and hover: the normal working state.
        let vi = rotor.induced_velocity_m_s(thrust, 0.0, 0.5 * vh);
        assert!((vi - vh * ((1.0 / 16.0 + 1.0f64).sqrt() - 0.25)).abs() < 1e-9 * vh);
        // Descending slower than 2 v_h there is no windmill root: the normal state's formula
        // (the flow still down through the disk) is kept, as before.
        let vi = rotor.induced_velocity_m_s(thrust, 0.0, -1.5 * vh);
        assert!((vi - vh * ((0.5625f64 + 1.0).sqrt() + 0.75)).abs() < 1e-9 * vh);
        // Faster than 2 v_h the air flows up through the disk: v_i/v_h = -x/2 - sqrt(x^2/4 - 1)
        // with x = v_z/v_h; at x = -2.5 that is 0.5 (the normal-state root, 2.0 + ..., is not).
        let vi = rotor.induced_velocity_m_s(thrust, 0.0, -2.5 * vh);
        assert!((vi - 0.5 * vh).abs() < 1e-9 * vh, "{vi} vs {}", 0.5 * vh);
        // With a little forward speed the root stays on that branch (no jump back up).
        let vi_fwd = rotor.induced_velocity_m_s(thrust, 0.05 * vh, -2.5 * vh);
        assert!((vi_fwd - vi).abs() < 0.01 * vh, "{vi_fwd} vs {vi}");
        for (v_x, v_z) in [(0.0, -2.5 * vh), (0.05 * vh, -2.5 * vh), (1.0, -3.0 * vh)] {
            let vi = rotor.induced_velocity_m_s(thrust, v_x, v_z);
            let momentum = 2.0 * 1.2 * rotor.disk_area_m2() * vi * f64::hypot(v_x, v_z + vi);
            assert!((momentum - thrust).abs() < 1e-8 * thrust, "{momentum}");
            assert!(
                v_z + vi < 0.0,
                "windmill-brake: the flow is up through the disk"
            );
        }
    }

    #[test]
    fn hover_induced_velocity_is_the_momentum_theory_value() {
        let v = shipped();
        let rotor = Rotor::new(&v);
        let thrust = 7.4;
        let vh = (thrust / (2.0 * 1.2 * rotor.disk_area_m2())).sqrt();
        let s = rotor.solve(thrust, 0.0, 0.0).unwrap();
        let kappa = v.rotor.induced_power_factor;
        assert!((s.induced_velocity_m_s - kappa * vh).abs() < 1e-9);
    }

    #[test]
    fn non_finite_or_negative_inputs_are_typed_errors() {
        let rotor = Rotor::new(&shipped());
        assert!(matches!(
            rotor.solve(f64::NAN, 0.0, 0.0),
            Err(PhysicsError::NotFinite { .. })
        ));
        assert!(matches!(
            rotor.solve(7.0, f64::INFINITY, 0.0),
            Err(PhysicsError::NotFinite { .. })
        ));
        assert!(matches!(
            rotor.solve(-1.0, 0.0, 0.0),
            Err(PhysicsError::NoRotorSolution { .. })
        ));
    }
}
