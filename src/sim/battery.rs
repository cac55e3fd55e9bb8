//! The simulated battery pack and the autopilot's battery monitor, sans-IO.
//!
//! Pack (the physics model's lumped battery, `physics::powertrain`;
//! docs/energy-model.md): terminal voltage V = OCV(SOC) - R I, and the terminal power V I equals the load P, so
//! I = (OCV - sqrt(OCV^2 - 4 R P)) / (2 R); the state of charge falls by I dt / capacity.
//!
//! Monitor (what a power module and the autopilot's battery driver report): the true voltage and
//! current plus seeded Gaussian sensor noise, sampled every simulation step; the current passed
//! through PX4's low-pass filter (an `AlphaFilter` with time constant 0.5 s at the sample
//! interval: PX4 src/lib/battery/battery.cpp up to v1.14,
//! `_current_filter_a.setParameters(expected_filter_dt, .5f)`, which
//! src/modules/mavlink/streams/BATTERY_STATUS.hpp sends as `current_filtered_a * 100`; PX4 main
//! moved the filter to analog_battery.cpp as BAT${i}_I_FILT, default 0 = off); the consumed
//! charge summed from the unfiltered current (`Battery::sumDischarged`) and the consumed energy
//! from V I (ArduPilot's AP_BattMonitor `consumed_wh`).

use crate::physics::Vehicle;
use crate::rng::Rng;

/// Sensor noise, one standard deviation per sample ([assumed]: a hall-effect power module's
/// ADC noise, about 0.2 A and 20 mV on a 6S pack).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorNoise {
    pub voltage_v: f64,
    pub current_a: f64,
}

impl Default for SensorNoise {
    fn default() -> Self {
        SensorNoise {
            voltage_v: 0.02,
            current_a: 0.2,
        }
    }
}

/// The pack's electrical state at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Draw {
    pub voltage_v: f64,
    pub current_a: f64,
}

/// A lumped battery pack discharging under load.
#[derive(Debug, Clone)]
pub struct Pack<'v> {
    vehicle: &'v Vehicle,
    state_of_charge: f64,
}

impl<'v> Pack<'v> {
    /// `vehicle`'s pack at `state_of_charge` (0..1).
    pub fn new(vehicle: &'v Vehicle, state_of_charge: f64) -> Pack<'v> {
        Pack {
            vehicle,
            state_of_charge: state_of_charge.clamp(0.0, 1.0),
        }
    }

    /// State of charge (0..1).
    pub fn state_of_charge(&self) -> f64 {
        self.state_of_charge
    }

    /// The terminal voltage and current that deliver `power_w` now (an overload is capped at
    /// the pack's maximum power, OCV^2 / 4R).
    pub fn at(&self, power_w: f64) -> Draw {
        let ocv = self.vehicle.open_circuit_voltage_v(self.state_of_charge);
        let r = self.vehicle.battery.internal_resistance_ohm;
        let p = power_w.max(0.0);
        let current_a = if r > 0.0 {
            let disc = (ocv * ocv - 4.0 * r * p).max(0.0);
            (ocv - disc.sqrt()) / (2.0 * r)
        } else {
            p / ocv
        };
        Draw {
            voltage_v: ocv - r * current_a,
            current_a,
        }
    }

    /// Delivers `power_w` for `dt_s`: returns the draw and discharges the pack.
    pub fn draw(&mut self, power_w: f64, dt_s: f64) -> Draw {
        let draw = self.at(power_w);
        let capacity_as = self.vehicle.battery.capacity_ah * 3600.0;
        self.state_of_charge =
            (self.state_of_charge - draw.current_a * dt_s / capacity_as).clamp(0.0, 1.0);
        draw
    }
}

/// What the battery monitor reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    /// Measured pack voltage.
    pub voltage_v: f64,
    /// Measured current after the monitor's filter.
    pub current_a: f64,
    /// Charge drawn since boot (from the unfiltered measured current).
    pub consumed_mah: f64,
    /// Energy drawn since boot (measured V I).
    pub consumed_wh: f64,
    /// Remaining charge (0..1).
    pub remaining: f64,
}

/// The autopilot's battery monitor: noisy sensors, a current filter, consumed charge and energy.
#[derive(Debug, Clone)]
pub struct Monitor {
    noise: SensorNoise,
    filter_time_constant_s: f64,
    rng: Rng,
    filtered_a: Option<f64>,
    reading: Reading,
}

impl Monitor {
    /// A monitor whose current filter has time constant `filter_time_constant_s` (0: none),
    /// with sensor noise drawn from a generator seeded with `seed`.
    pub fn new(noise: SensorNoise, filter_time_constant_s: f64, seed: u64) -> Monitor {
        Monitor {
            noise,
            filter_time_constant_s: filter_time_constant_s.max(0.0),
            rng: Rng::new(seed),
            filtered_a: None,
            reading: Reading {
                voltage_v: 0.0,
                current_a: 0.0,
                consumed_mah: 0.0,
                consumed_wh: 0.0,
                remaining: 1.0,
            },
        }
    }

    /// Standard normal deviate (Box-Muller on two uniforms).
    fn gaussian(&mut self) -> f64 {
        let u1 = self.rng.next_f64().max(1e-300);
        let u2 = self.rng.next_f64();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// Takes one sample of `draw` covering `dt_s`, with the pack at `remaining` charge.
    pub fn sample(&mut self, draw: Draw, dt_s: f64, remaining: f64) -> Reading {
        let voltage_v = draw.voltage_v + self.noise.voltage_v * self.gaussian();
        let current_a = draw.current_a + self.noise.current_a * self.gaussian();
        // PX4 AlphaFilter: alpha = dt / (tau + dt), state += alpha (sample - state), started at
        // the first sample (Battery::updateBatteryStatus resets it while not initialised).
        let filtered = match self.filtered_a {
            None => current_a,
            Some(state) => {
                let alpha = dt_s / (self.filter_time_constant_s + dt_s);
                state + alpha * (current_a - state)
            }
        };
        self.filtered_a = Some(filtered);
        self.reading = Reading {
            voltage_v,
            current_a: filtered,
            consumed_mah: self.reading.consumed_mah + current_a * dt_s / 3.6,
            consumed_wh: self.reading.consumed_wh + voltage_v * current_a * dt_s / 3600.0,
            remaining,
        };
        self.reading
    }

    /// The latest reading.
    pub fn reading(&self) -> Reading {
        self.reading
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::vehicle::shipped;

    #[test]
    fn the_pack_delivers_the_asked_power_at_a_voltage_sagging_with_load() {
        let v = shipped();
        let pack = Pack::new(&v, 1.0);
        let idle = pack.at(10.0);
        let hover = pack.at(550.0);
        assert!((hover.voltage_v * hover.current_a - 550.0).abs() < 1e-9);
        assert!(idle.voltage_v > hover.voltage_v && idle.voltage_v < 25.2);
        // V = OCV - R I with the shipped 0.02 ohm.
        assert!((25.2 - 0.02 * hover.current_a - hover.voltage_v).abs() < 1e-9);
    }

    #[test]
    fn the_pack_discharges_by_the_charge_drawn() {
        let v = shipped();
        let mut pack = Pack::new(&v, 1.0);
        let mut charge_as = 0.0;
        for _ in 0..1200 {
            charge_as += pack.draw(550.0, 1.0).current_a;
        }
        let expected = 1.0 - charge_as / (v.battery.capacity_ah * 3600.0);
        assert!((pack.state_of_charge() - expected).abs() < 1e-12);
        // Twenty minutes of hover (about 23 A) use most of a 10 Ah pack; the voltage falls.
        assert!(pack.state_of_charge() < 0.3, "{}", pack.state_of_charge());
        assert!(pack.at(550.0).voltage_v < 23.0);
    }

    #[test]
    fn px4s_current_filter_reaches_63_percent_of_a_step_after_its_time_constant() {
        let quiet = SensorNoise {
            voltage_v: 0.0,
            current_a: 0.0,
        };
        let mut m = Monitor::new(quiet, 0.5, 1);
        let dt = 0.01;
        m.sample(
            Draw {
                voltage_v: 24.0,
                current_a: 0.0,
            },
            dt,
            1.0,
        );
        let mut r = m.reading();
        for _ in 0..50 {
            r = m.sample(
                Draw {
                    voltage_v: 24.0,
                    current_a: 10.0,
                },
                dt,
                1.0,
            );
        }
        // Discrete first-order filter: 1 - (tau / (tau + dt))^n at n = tau / dt.
        let expected = 10.0 * (1.0 - (0.5f64 / 0.51).powi(50));
        assert!((r.current_a - expected).abs() < 1e-9, "{}", r.current_a);
        assert!((r.current_a - 6.32).abs() < 0.05);
        // The consumed charge counts the unfiltered current: 50 samples of 10 A for 10 ms.
        assert!((r.consumed_mah - 10.0 * 0.5 / 3.6).abs() < 1e-9);
    }

    #[test]
    fn sensor_noise_is_seeded_and_has_the_configured_spread() {
        let draw = Draw {
            voltage_v: 24.0,
            current_a: 20.0,
        };
        let series = |seed| {
            let mut m = Monitor::new(SensorNoise::default(), 0.0, seed);
            (0..4000)
                .map(|_| m.sample(draw, 0.01, 1.0).current_a)
                .collect::<Vec<_>>()
        };
        let (a, b, c) = (series(7), series(7), series(8));
        assert_eq!(a, b);
        assert_ne!(a, c);
        let mean = a.iter().sum::<f64>() / a.len() as f64;
        let sd = (a.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / a.len() as f64).sqrt();
        assert!(
            (mean - 20.0).abs() < 0.02 && (sd - 0.2).abs() < 0.02,
            "{mean} {sd}"
        );
    }
}
