//! Motor, ESC and battery: from a rotor's speed and torque to battery terminal power.
//!
//! Motor (DC brushless, steady state; docs/energy-model.md): i_m = Q/K_t + i_0,
//! V_m = R_m i_m + K_e Omega with K_e = K_t = 60 / (2 pi KV). ESC: V_m = d V_t with duty d <= 1,
//! input power V_m i_m / eta_esc. Battery (lumped; section 9.7): V_t = OCV(SOC) - R_b I_b, and the
//! terminal power V_t I_b (what a power module measures) equals the load, so
//! I_b = (OCV - sqrt(OCV^2 - 4 R_b P)) / (2 R_b).

use super::rotor::RotorState;
use super::vehicle::Vehicle;
use super::PhysicsError;

/// The electrical side of the vehicle at one battery state of charge.
#[derive(Debug, Clone, PartialEq)]
pub struct Powertrain {
    rotors: f64,
    ke_v_s_rad: f64,
    resistance_ohm: f64,
    no_load_current_a: f64,
    esc_efficiency: f64,
    avionics_power_w: f64,
    open_circuit_v: f64,
    battery_resistance_ohm: f64,
}

/// Electrical operating point of the whole vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Electrical {
    /// Battery terminal power (V_t I_b).
    pub power_w: f64,
    pub battery_current_a: f64,
    pub terminal_voltage_v: f64,
    pub motor_current_a: f64,
    pub duty: f64,
}

impl Powertrain {
    /// The powertrain of `vehicle` at battery state of charge `soc`.
    pub fn new(vehicle: &Vehicle, soc: f64) -> Powertrain {
        Powertrain {
            rotors: f64::from(vehicle.rotor.count),
            ke_v_s_rad: 60.0 / (2.0 * std::f64::consts::PI * vehicle.motor.kv_rpm_per_v),
            resistance_ohm: vehicle.motor.resistance_ohm,
            no_load_current_a: vehicle.motor.no_load_current_a,
            esc_efficiency: vehicle.motor.esc_efficiency,
            avionics_power_w: vehicle.body.avionics_power_w,
            open_circuit_v: vehicle.open_circuit_voltage_v(soc),
            battery_resistance_ohm: vehicle.battery.internal_resistance_ohm,
        }
    }

    /// Electrical state when every rotor runs at `rotor`.
    pub fn electrical(&self, rotor: &RotorState) -> Result<Electrical, PhysicsError> {
        let motor_current_a = rotor.torque_n_m.max(0.0) / self.ke_v_s_rad + self.no_load_current_a;
        let motor_voltage_v =
            self.resistance_ohm * motor_current_a + self.ke_v_s_rad * rotor.omega_rad_s;
        let power_w = self.rotors * motor_voltage_v * motor_current_a / self.esc_efficiency
            + self.avionics_power_w;
        let ocv = self.open_circuit_v;
        let (current_a, terminal_v) = if self.battery_resistance_ohm > 0.0 {
            let disc = ocv * ocv - 4.0 * self.battery_resistance_ohm * power_w;
            if disc < 0.0 {
                return Err(PhysicsError::BatteryOverload {
                    power_w,
                    max_power_w: ocv * ocv / (4.0 * self.battery_resistance_ohm),
                });
            }
            let i = (ocv - disc.sqrt()) / (2.0 * self.battery_resistance_ohm);
            (i, ocv - self.battery_resistance_ohm * i)
        } else {
            (power_w / ocv, ocv)
        };
        let duty = motor_voltage_v / terminal_v;
        if duty > 1.0 {
            return Err(PhysicsError::MotorSaturated {
                required_v: motor_voltage_v,
                available_v: terminal_v,
                omega_rad_s: rotor.omega_rad_s,
                thrust_n: rotor.thrust_n,
            });
        }
        Ok(Electrical {
            power_w,
            battery_current_a: current_a,
            terminal_voltage_v: terminal_v,
            motor_current_a,
            duty,
        })
    }
}
