//! A physical battery for an autopilot whose own battery is not energy (PX4 SITL: its battery
//! simulator drains the voltage on a timer and reports a fake -1 A), sans-IO.
//!
//! It follows the vehicle's actual motion in the autopilot's telemetry and reports, as a smart
//! battery of the vehicle (MAVLink system 1, component 180 = MAV_COMP_ID_BATTERY), the
//! BATTERY_STATUS the vehicle model's pack would report flying that motion:
//! - motion: LOCAL_POSITION_NED velocity at its `time_boot_ms` (vehicle time, so PX4's lockstep
//!   speed-up does not matter); acceleration is the velocity differentiated sample to sample and
//!   low-passed with a first-order filter of cut-off `accel_cutoff_hz` (5 Hz: PX4's own
//!   numerical velocity derivative in the multicopter position controller is low-passed at
//!   MPC_VELD_LP = 5 Hz, mc_pos_control/multicopter_position_control_params.c);
//! - power: disarmed, the avionics; armed on the ground (EXTENDED_SYS_STATE ON_GROUND), the
//!   avionics and the idling motors (`flight::IDLE_SPIN_POWER_W`); taking off but still on the
//!   ground, PX4's thrust ramp (`physics::px4::ground_ramp_az`: from no thrust to the weight,
//!   counted from the first sample past ON_GROUND); in the air,
//!   `physics::power::Model::power_w` of the motion in its vertical plane: x along the
//!   horizontal velocity, z up, the horizontal force the body needs (mass x horizontal
//!   acceleration + drag along the velocity, `physics::body::demand`) taken whole in that
//!   plane, so a sideways acceleration costs its thrust too;
//! - pack: `battery::Pack` (terminal voltage OCV(SOC) - R I, current = P / V, the charge drawn
//!   lowers the state of charge), stepped at every velocity sample with the mean power over the
//!   step (trapezoidal rule);
//! - report: BATTERY_STATUS every 1 / `rate_hz` s of vehicle time: cell voltages in mV (the
//!   pack's cells, each V / cells), current in cA, consumed mAh, energy consumed in hJ,
//!   remaining charge in percent. PX4 takes it up (mavlink_receiver.cpp
//!   `handle_message_battery_status`: any component of its own system but the autopilot's) and
//!   reports it as its battery on every link (BATTERY_STATUS.hpp, SYS_STATUS).
//!
//! The machine only reads what the autopilot (`target_system`, `target_component`) sends;
//! `handle` returns the messages to send. Nothing here reads a clock.

use crate::link::mav::{
    MavBatteryChargeState, MavBatteryFunction, MavBatteryType, MavLandedState, MavMessage,
    MavModeFlag, BATTERY_STATUS_DATA,
};
use crate::physics::power::Model;
use crate::physics::{PhysicsError, Vehicle};

use super::battery::Pack;
use super::flight::IDLE_SPIN_POWER_W;

/// MAVLink component id of a smart battery (MAV_COMP_ID_BATTERY).
pub const BATTERY_COMPONENT: u8 = 180;

/// A velocity sample this long after the previous one starts the derivative afresh (a gap in
/// the telemetry: the acceleration across it is unknown).
const MAX_STEP_S: f64 = 0.5;

/// Landing within this height of the ground the vehicle stood on is touchdown.
const TOUCHDOWN_M: f64 = 0.1;

/// Landing, the vehicle has touched down once it has descended faster than
/// [`DESCENDING_M_S`] and then stayed slower than [`STOPPED_M_S`] vertically for
/// [`STOPPED_S`]: PX4 descends at MPC_LAND_SPEED or its crawl until the ground stops it, and its
/// height estimate drifts (PX4 SITL: the ground 0.5-1.9 m off where it took off), so the height
/// alone misses some touchdowns.
const DESCENDING_M_S: f64 = 0.2;
const STOPPED_M_S: f64 = 0.1;
const STOPPED_S: f64 = 0.3;

/// Below this horizontal speed the leg's plane follows the horizontal acceleration instead.
const STILL_M_S: f64 = 0.05;

/// How the battery process runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatterySimConfig {
    /// BATTERY_STATUS messages per second of vehicle time.
    pub rate_hz: f64,
    /// State of charge of the pack at start (0..1).
    pub state_of_charge: f64,
    /// Cut-off of the low-pass filter on the differentiated velocity (Hz; 0: unfiltered).
    pub accel_cutoff_hz: f64,
    /// The autopilot whose motion is followed.
    pub target_system: u8,
    pub target_component: u8,
    /// BATTERY_STATUS `id`.
    pub battery_id: u8,
}

impl Default for BatterySimConfig {
    fn default() -> Self {
        BatterySimConfig {
            rate_hz: 20.0,
            state_of_charge: 1.0,
            accel_cutoff_hz: 5.0,
            target_system: 1,
            target_component: 1,
            battery_id: 0,
        }
    }
}

/// What the vehicle is doing, as far as its power goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PowerState {
    Disarmed,
    /// Armed, on the ground: the motors idle.
    Ground,
    /// Flying: the physics model of the motion.
    Air,
}

/// The battery now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatteryNow {
    /// Vehicle time of the latest motion sample (s).
    pub t_s: f64,
    pub state: PowerState,
    pub power_w: f64,
    pub voltage_v: f64,
    pub current_a: f64,
    /// Charge and energy drawn since start.
    pub consumed_mah: f64,
    pub consumed_j: f64,
    pub state_of_charge: f64,
    /// Acceleration estimate, north-east-down (m/s^2).
    pub accel_ned: [f64; 3],
}

/// The battery process's state machine.
#[derive(Debug, Clone)]
pub struct BatterySim<'v> {
    cfg: BatterySimConfig,
    model: Model<'v>,
    pack: Pack<'v>,
    avionics_w: f64,
    mass_kg: f64,
    drag_n_s2_m2: f64,
    cells: u32,
    armed: bool,
    landed: Option<MavLandedState>,
    /// Height (NED z) of the ground: where the vehicle last stood.
    ground_z_m: Option<f64>,
    /// The latest height (NED z).
    z_m: f64,
    /// Landing: seen descending, and since when stopped (vehicle time).
    landing_descended: bool,
    stopped_since_s: Option<f64>,
    /// The latest vehicle time.
    t_s: f64,
    /// PX4's take-off ramp: px4 parameters, and when it began (vehicle time).
    px4: crate::physics::vehicle::Px4Params,
    ramp_start_s: Option<f64>,
    /// The latest velocity sample (t, v NED).
    last: Option<(f64, [f64; 3])>,
    accel_ned: [f64; 3],
    power_w: f64,
    consumed_mah: f64,
    consumed_j: f64,
    next_report_s: Option<f64>,
    physics_errors: u64,
}

impl<'v> BatterySim<'v> {
    /// A battery for `vehicle`, full to `cfg.state_of_charge`.
    pub fn new(
        vehicle: &'v Vehicle,
        cfg: BatterySimConfig,
    ) -> Result<BatterySim<'v>, PhysicsError> {
        let model = Model::new(vehicle);
        model.hover_power_w()?;
        for (what, value) in [
            ("rate_hz", cfg.rate_hz),
            ("state_of_charge", cfg.state_of_charge),
            ("accel_cutoff_hz", cfg.accel_cutoff_hz),
        ] {
            if !value.is_finite() || value < 0.0 {
                return Err(PhysicsError::NotFinite { what, value });
            }
        }
        Ok(BatterySim {
            cfg,
            model,
            pack: Pack::new(vehicle, cfg.state_of_charge),
            avionics_w: vehicle.body.avionics_power_w,
            mass_kg: vehicle.body.mass_kg,
            drag_n_s2_m2: vehicle.body.drag_coefficient_n_s2_m2,
            cells: vehicle.battery.cells,
            armed: false,
            landed: None,
            ground_z_m: None,
            z_m: 0.0,
            landing_descended: false,
            stopped_since_s: None,
            t_s: 0.0,
            px4: vehicle.px4.clone(),
            ramp_start_s: None,
            last: None,
            accel_ned: [0.0; 3],
            power_w: vehicle.body.avionics_power_w,
            consumed_mah: 0.0,
            consumed_j: 0.0,
            next_report_s: None,
            physics_errors: 0,
        })
    }

    /// Instants the physics could not price (an acceleration beyond the motors): the power of
    /// the sample before was kept.
    pub fn physics_errors(&self) -> u64 {
        self.physics_errors
    }

    /// The battery now.
    pub fn now(&self) -> BatteryNow {
        let draw = self.pack.at(self.power_w);
        BatteryNow {
            t_s: self.last.map_or(0.0, |(t, _)| t),
            state: self.state(),
            power_w: self.power_w,
            voltage_v: draw.voltage_v,
            current_a: draw.current_a,
            consumed_mah: self.consumed_mah,
            consumed_j: self.consumed_j,
            state_of_charge: self.pack.state_of_charge(),
            accel_ned: self.accel_ned,
        }
    }

    fn state(&self) -> PowerState {
        match (self.armed, self.landed) {
            (false, _) => PowerState::Disarmed,
            (true, Some(MavLandedState::MAV_LANDED_STATE_ON_GROUND)) => PowerState::Ground,
            // Touched down: the land detector confirms it a second or so later (PX4 SITL
            // 1.1-1.3 s), while the motors already idle.
            (true, Some(MavLandedState::MAV_LANDED_STATE_LANDING))
                if self.ground_z_m.is_some_and(|g| self.z_m >= g - TOUCHDOWN_M)
                    || self
                        .stopped_since_s
                        .is_some_and(|since| self.t_s - since >= STOPPED_S) =>
            {
                PowerState::Ground
            }
            (true, _) => PowerState::Air,
        }
    }

    /// Takes in one message from `(system, component)`; returns the BATTERY_STATUS messages due.
    pub fn handle(&mut self, system: u8, component: u8, message: &MavMessage) -> Vec<MavMessage> {
        if system != self.cfg.target_system || component != self.cfg.target_component {
            return Vec::new();
        }
        match message {
            MavMessage::HEARTBEAT(hb) => {
                self.armed = hb
                    .base_mode
                    .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
                Vec::new()
            }
            MavMessage::EXTENDED_SYS_STATE(s) => {
                self.landed = Some(s.landed_state);
                Vec::new()
            }
            MavMessage::LOCAL_POSITION_NED(p) => self
                .motion(
                    f64::from(p.time_boot_ms) * 1e-3,
                    f64::from(p.z),
                    [f64::from(p.vx), f64::from(p.vy), f64::from(p.vz)],
                )
                .into_iter()
                .collect(),
            _ => Vec::new(),
        }
    }

    /// A motion sample at vehicle time `t_s`: height `z_m` (NED, down) and velocity (north,
    /// east, down; m/s). Steps the pack and returns a BATTERY_STATUS when one is due.
    pub fn motion(&mut self, t_s: f64, z_m: f64, v_ned: [f64; 3]) -> Option<MavMessage> {
        if !t_s.is_finite() || !z_m.is_finite() || v_ned.iter().any(|v| !v.is_finite()) {
            return None;
        }
        if self.last.is_some_and(|(t0, _)| t_s <= t0) {
            return None;
        }
        self.z_m = z_m;
        self.t_s = t_s;
        if self.landed == Some(MavLandedState::MAV_LANDED_STATE_LANDING) {
            let down_m_s = v_ned[2];
            if down_m_s > DESCENDING_M_S {
                self.landing_descended = true;
                self.stopped_since_s = None;
            } else if self.landing_descended && down_m_s.abs() < STOPPED_M_S {
                self.stopped_since_s.get_or_insert(t_s);
            } else {
                self.stopped_since_s = None;
            }
        } else {
            self.landing_descended = false;
            self.stopped_since_s = None;
        }
        if matches!(self.state(), PowerState::Disarmed | PowerState::Ground) {
            self.ground_z_m = Some(z_m);
            self.ramp_start_s = None;
        } else if self.ramp_start_s.is_none() {
            self.ramp_start_s = Some(t_s);
        }
        match self.last {
            Some((t0, v0)) if t_s - t0 <= MAX_STEP_S => {
                let dt = t_s - t0;
                let alpha = if self.cfg.accel_cutoff_hz > 0.0 {
                    let tau = 1.0 / (std::f64::consts::TAU * self.cfg.accel_cutoff_hz);
                    dt / (tau + dt)
                } else {
                    1.0
                };
                for k in 0..3 {
                    let raw = (v_ned[k] - v0[k]) / dt;
                    self.accel_ned[k] += alpha * (raw - self.accel_ned[k]);
                }
                let before = self.power_w;
                self.power_w = self.power_now(t_s, v_ned);
                let mean_w = 0.5 * (before + self.power_w);
                let draw = self.pack.draw(mean_w, dt);
                self.consumed_mah += draw.current_a * dt / 3.6;
                self.consumed_j += draw.voltage_v * draw.current_a * dt;
            }
            // The first sample, or one after a gap: the derivative starts afresh.
            _ => {
                self.accel_ned = [0.0; 3];
                self.power_w = self.power_now(t_s, v_ned);
            }
        }
        self.last = Some((t_s, v_ned));
        let due = *self.next_report_s.get_or_insert(t_s);
        if t_s + 1e-9 < due {
            return None;
        }
        let period = if self.cfg.rate_hz > 0.0 {
            1.0 / self.cfg.rate_hz
        } else {
            f64::INFINITY
        };
        // The next report on the grid, never behind now (a gap skips the reports it covered).
        let mut next = due + period;
        if next <= t_s {
            next = t_s + period;
        }
        self.next_report_s = Some(next);
        Some(self.battery_status())
    }

    /// Battery terminal power for the current state and velocity.
    fn power_now(&mut self, t_s: f64, v_ned: [f64; 3]) -> f64 {
        match self.state() {
            PowerState::Disarmed => self.avionics_w,
            PowerState::Ground => self.avionics_w + IDLE_SPIN_POWER_W,
            PowerState::Air if self.ramping(t_s, v_ned) => {
                let since = t_s - self.ramp_start_s.unwrap_or(t_s);
                let az = crate::physics::px4::ground_ramp_az(&self.px4, since);
                match self.model.power_w(0.0, 0.0, 0.0, az) {
                    Ok((p, _)) => p,
                    Err(_) => {
                        self.physics_errors += 1;
                        self.power_w
                    }
                }
            }
            PowerState::Air => match self.flying_power_w(v_ned) {
                Ok(p) => p,
                Err(_) => {
                    self.physics_errors += 1;
                    self.power_w
                }
            },
        }
    }

    /// Taking off but not yet lifted: still at ground height, not climbing, and within PX4's
    /// ramp to lift-off.
    fn ramping(&self, t_s: f64, v_ned: [f64; 3]) -> bool {
        let on_ground = self
            .ground_z_m
            .is_some_and(|g| self.z_m >= g - TOUCHDOWN_M && v_ned[2] > -STILL_M_S);
        let since = self.ramp_start_s.map(|s| t_s - s);
        on_ground
            && self.landed != Some(MavLandedState::MAV_LANDED_STATE_LANDING)
            && since.is_some_and(|s| s < crate::physics::px4::lift_off_s(&self.px4))
    }

    /// The physics model's power for the velocity and the filtered acceleration, in the plane
    /// of the horizontal velocity.
    fn flying_power_w(&self, v_ned: [f64; 3]) -> Result<f64, PhysicsError> {
        let [a_n, a_e, a_d] = self.accel_ned;
        let speed = v_ned[0].hypot(v_ned[1]);
        let (ux, uy) = if speed > STILL_M_S {
            (v_ned[0] / speed, v_ned[1] / speed)
        } else {
            let a = a_n.hypot(a_e);
            if a > 1e-9 {
                (a_n / a, a_e / a)
            } else {
                (1.0, 0.0)
            }
        };
        let along = a_n * ux + a_e * uy;
        let across = -a_n * uy + a_e * ux;
        // The horizontal force is m a_along + C v|v| along the velocity and m a_across across it;
        // its magnitude, put along the velocity, is what the planar body model is given.
        let drag_n = self.drag_n_s2_m2 * speed * speed;
        let f_along = self.mass_kg * along + drag_n;
        let f = f_along.hypot(self.mass_kg * across).copysign(f_along);
        let ax = (f - drag_n) / self.mass_kg;
        Ok(self.model.power_w(speed, -v_ned[2], ax, -a_d)?.0)
    }

    /// The BATTERY_STATUS of the pack now.
    pub fn battery_status(&self) -> MavMessage {
        let draw = self.pack.at(self.power_w);
        let mut voltages = [u16::MAX; 10];
        let cells = self.cells as usize;
        if (1..=voltages.len()).contains(&cells) {
            let cell_mv = (draw.voltage_v / cells as f64 * 1000.0)
                .round()
                .clamp(0.0, 65534.0);
            for v in voltages.iter_mut().take(cells) {
                *v = cell_mv as u16;
            }
        } else {
            // Cells unknown to MAVLink's ten slots: the pack in the first (MAVLink spec).
            voltages[0] = (draw.voltage_v * 1000.0).round().clamp(0.0, 65534.0) as u16;
        }
        MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
            current_consumed: self.consumed_mah.round().clamp(0.0, f64::from(i32::MAX)) as i32,
            energy_consumed: (self.consumed_j / 100.0)
                .round()
                .clamp(0.0, f64::from(i32::MAX)) as i32,
            temperature: i16::MAX,
            voltages,
            current_battery: (draw.current_a * 100.0).round().clamp(0.0, 32767.0) as i16,
            id: self.cfg.battery_id,
            battery_function: MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
            mavtype: MavBatteryType::MAV_BATTERY_TYPE_LIPO,
            battery_remaining: (self.pack.state_of_charge() * 100.0)
                .round()
                .clamp(0.0, 100.0) as i8,
            time_remaining: 0,
            charge_state: MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_OK,
            voltages_ext: [0; 4],
            ..Default::default()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::telemetry::Reading;
    use crate::link::mav::{EXTENDED_SYS_STATE_DATA, HEARTBEAT_DATA, LOCAL_POSITION_NED_DATA};
    use crate::link::telemetry::decode;
    use crate::physics::power::Model;
    use crate::physics::vehicle::shipped;
    use crate::physics::Profile;

    fn heartbeat(armed: bool) -> MavMessage {
        let mut hb = HEARTBEAT_DATA::default();
        if armed {
            hb.base_mode = MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
        }
        MavMessage::HEARTBEAT(hb)
    }

    fn landed(state: MavLandedState) -> MavMessage {
        MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
            landed_state: state,
            ..Default::default()
        })
    }

    fn position(t_s: f64, v_ned: [f64; 3]) -> MavMessage {
        MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
            time_boot_ms: (t_s * 1000.0).round() as u32,
            z: -10.0,
            vx: v_ned[0] as f32,
            vy: v_ned[1] as f32,
            vz: v_ned[2] as f32,
            ..Default::default()
        })
    }

    fn flying(sim: &mut BatterySim) {
        sim.handle(1, 1, &heartbeat(true));
        sim.handle(1, 1, &landed(MavLandedState::MAV_LANDED_STATE_IN_AIR));
    }

    #[test]
    fn hovering_draws_the_models_hover_power_and_reports_it_at_the_asked_rate() {
        let v = shipped();
        let mut sim = BatterySim::new(&v, BatterySimConfig::default()).unwrap();
        flying(&mut sim);
        let mut reports = Vec::new();
        // 10 s at 50 Hz.
        for k in 0..=500 {
            reports.extend(sim.handle(1, 1, &position(k as f64 * 0.02, [0.0; 3])));
        }
        let hover = Model::new(&v).hover_power_w().unwrap();
        let now = sim.now();
        assert_eq!(now.state, PowerState::Air);
        assert!(
            (now.power_w - hover).abs() < 1e-9,
            "{} {hover}",
            now.power_w
        );
        assert!((now.voltage_v * now.current_a - hover).abs() < 1e-6);
        assert!((now.consumed_j - 10.0 * hover).abs() < 1e-6 * hover);
        // 20 per second of vehicle time, the first at the first sample.
        assert_eq!(reports.len(), 201);
        // What emplan decodes is the pack: six cells, the current, a real (not fake) current.
        let header = mavlink::MavHeader {
            system_id: 1,
            component_id: BATTERY_COMPONENT,
            sequence: 0,
        };
        let Some(Reading::Battery(b)) = decode(&header, &reports[200]).reading else {
            panic!("not a battery reading");
        };
        assert!(
            (b.voltage_v.unwrap() - now.voltage_v).abs() < 0.006,
            "{b:?}"
        );
        assert!(
            (b.current_a.unwrap() - now.current_a).abs() < 0.006,
            "{b:?}"
        );
        assert!(!b.fake_current);
        assert!((b.energy_consumed_j.unwrap() - now.consumed_j).abs() <= 50.0);
        let MavMessage::BATTERY_STATUS(raw) = &reports[200] else {
            panic!()
        };
        assert_eq!(raw.voltages.iter().filter(|&&c| c != u16::MAX).count(), 6);
        assert_eq!(
            raw.battery_remaining,
            (now.state_of_charge * 100.0).round() as i8
        );
    }

    #[test]
    fn disarmed_it_draws_the_avionics_and_armed_on_the_ground_the_idling_motors_too() {
        let v = shipped();
        let mut sim = BatterySim::new(&v, BatterySimConfig::default()).unwrap();
        sim.handle(1, 1, &position(0.0, [0.0; 3]));
        assert_eq!(sim.now().state, PowerState::Disarmed);
        assert_eq!(sim.now().power_w, v.body.avionics_power_w);
        sim.handle(1, 1, &heartbeat(true));
        sim.handle(1, 1, &landed(MavLandedState::MAV_LANDED_STATE_ON_GROUND));
        sim.handle(1, 1, &position(0.02, [0.0; 3]));
        assert_eq!(sim.now().state, PowerState::Ground);
        assert_eq!(
            sim.now().power_w,
            v.body.avionics_power_w + IDLE_SPIN_POWER_W
        );
        // Another component's or system's messages are not the autopilot's.
        sim.handle(1, 190, &landed(MavLandedState::MAV_LANDED_STATE_IN_AIR));
        sim.handle(2, 1, &heartbeat(false));
        sim.handle(1, 1, &position(0.04, [0.0; 3]));
        assert_eq!(sim.now().state, PowerState::Ground);
    }

    #[test]
    fn landing_it_idles_once_the_ground_stops_the_descent_wherever_the_height_estimate_puts_it() {
        let v = shipped();
        let hover = Model::new(&v).hover_power_w().unwrap();
        let idle = v.body.avionics_power_w + IDLE_SPIN_POWER_W;
        let mut sim = BatterySim::new(&v, BatterySimConfig::default()).unwrap();
        sim.handle(1, 1, &heartbeat(true));
        sim.handle(1, 1, &landed(MavLandedState::MAV_LANDED_STATE_ON_GROUND));
        sim.motion(0.0, 0.0, [0.0; 3]);
        sim.handle(1, 1, &landed(MavLandedState::MAV_LANDED_STATE_IN_AIR));
        sim.motion(1.0, -10.0, [0.0; 3]);
        // Landing: hovering first, then down at 0.7 m/s; the estimate puts the ground 1 m
        // above where the vehicle took off, so the height never comes back to it.
        sim.handle(1, 1, &landed(MavLandedState::MAV_LANDED_STATE_LANDING));
        let mut t = 1.0;
        for _ in 0..25 {
            t += 0.02;
            sim.motion(t, -10.0, [0.0; 3]);
        }
        assert_eq!(
            sim.now().state,
            PowerState::Air,
            "hovering before the descent"
        );
        let mut z = -10.0;
        while z < -1.0 {
            t += 0.02;
            z += 0.7 * 0.02;
            sim.motion(t, z, [0.0, 0.0, 0.7]);
        }
        assert_eq!(sim.now().state, PowerState::Air);
        assert!((sim.now().power_w - hover).abs() < 0.2 * hover);
        // Stopped by the ground: 0.3 s later the motors idle.
        for k in 1..=10 {
            sim.motion(t + 0.02 * f64::from(k), -1.0, [0.0, 0.0, 0.01]);
        }
        assert_eq!(sim.now().state, PowerState::Air, "0.2 s stopped");
        for k in 11..=20 {
            sim.motion(t + 0.02 * f64::from(k), -1.0, [0.0, 0.0, 0.01]);
        }
        assert_eq!(sim.now().state, PowerState::Ground);
        assert_eq!(sim.now().power_w, idle);
    }

    #[test]
    fn taking_off_on_the_ground_it_draws_pxs_thrust_ramp_from_idle_to_hover_until_lift_off() {
        let v = shipped();
        let model = Model::new(&v);
        let hover_w = model.hover_power_w().unwrap();
        let mut sim = BatterySim::new(&v, BatterySimConfig::default()).unwrap();
        sim.handle(1, 1, &heartbeat(true));
        sim.handle(1, 1, &landed(MavLandedState::MAV_LANDED_STATE_ON_GROUND));
        sim.handle(1, 1, &position(0.0, [0.0; 3]));
        sim.handle(1, 1, &landed(MavLandedState::MAV_LANDED_STATE_TAKEOFF));
        let lift_off = crate::physics::px4::lift_off_s(&v.px4);
        let mut powers = Vec::new();
        for k in 1..=40 {
            let t = 0.1 * f64::from(k);
            sim.handle(1, 1, &position(t, [0.0; 3]));
            powers.push((t, sim.now().power_w));
        }
        // Rising through the ramp, below hover before lift-off, hover once it is done.
        let during: Vec<f64> = powers
            .iter()
            .filter(|(t, _)| *t < lift_off - 0.05)
            .map(|&(_, p)| p)
            .collect();
        assert!(during.windows(2).all(|w| w[1] >= w[0]), "{powers:?}");
        assert!(during[0] < 0.3 * hover_w, "{powers:?}");
        assert!(during.iter().all(|&p| p < hover_w));
        let after = powers.last().unwrap().1;
        assert!(
            (after - hover_w).abs() < 1e-6 * hover_w,
            "{after} {hover_w}"
        );
    }

    /// Feeds the velocity of `profile`'s trajectory over (xf, zf), flown on `heading` (rad from
    /// north), at `hz`, as f32 like LOCAL_POSITION_NED, with `hover_s` of hover on each side;
    /// returns the energy the battery drew and the model's energy for the same stretch.
    fn fly_trajectory(xf: f64, zf: f64, heading: f64, hz: f64, hover_s: f64) -> (f64, f64) {
        let v = shipped();
        let model = Model::new(&v);
        let trajectory = model.trajectory(Profile::Px4, xf, zf).unwrap();
        let mut sim = BatterySim::new(&v, BatterySimConfig::default()).unwrap();
        flying(&mut sim);
        let total_s = trajectory.duration_s() + 2.0 * hover_s;
        let n = (total_s * hz).round() as usize;
        for k in 0..=n {
            let t = k as f64 / hz;
            let (vx, vz, _, _) = trajectory.kinematics(t - hover_s);
            let v_ned = [vx * heading.cos(), vx * heading.sin(), -vz];
            sim.handle(1, 1, &position(t, v_ned));
        }
        let hover = model.hover_power_w().unwrap();
        let op = model.operation(Profile::Px4, xf, zf).unwrap();
        // The operation ends at PX4's acceptance, what the braking after it costs above hover
        // included: the rest of the trajectory is hover in its price.
        let after_s = trajectory.duration_s() - op.total_duration_s();
        let expected = op.total_energy_j() + hover * (2.0 * hover_s + after_s);
        (sim.now().consumed_j, expected)
    }

    #[test]
    fn a_legs_velocity_at_fifty_hertz_costs_the_models_energy_for_that_leg_within_half_a_percent() {
        for (xf, zf, heading) in [(40.0, 0.0, 0.3), (28.3, 8.0, 2.0), (20.0, -19.0, -1.2)] {
            let (drawn, expected) = fly_trajectory(xf, zf, heading, 50.0, 2.0);
            assert!(
                (drawn - expected).abs() < 0.005 * expected,
                "({xf}, {zf}): {drawn} J drawn, {expected} J for the model's leg"
            );
        }
    }

    #[test]
    fn an_unfiltered_derivative_of_a_noisy_velocity_costs_more_than_a_filtered_one() {
        // Measurement noise on the velocity: the filter keeps its derivative from adding thrust.
        let v = shipped();
        let run = |cutoff_hz: f64| {
            let mut sim = BatterySim::new(
                &v,
                BatterySimConfig {
                    accel_cutoff_hz: cutoff_hz,
                    ..BatterySimConfig::default()
                },
            )
            .unwrap();
            flying(&mut sim);
            let mut rng = crate::rng::Rng::new(3);
            // 20 s at 50 Hz of hover with +-1.5 cm/s of noise on each axis.
            for k in 0..=1000 {
                let jitter = [0.0, 1.0, 2.0].map(|_| 0.03 * (rng.next_f64() - 0.5));
                sim.handle(1, 1, &position(k as f64 * 0.02, jitter));
            }
            sim.now().consumed_j
        };
        let hover_20s = Model::new(&v).hover_power_w().unwrap() * 20.0;
        let (raw, filtered) = (run(0.0), run(5.0));
        assert!(raw > filtered, "{raw} {filtered}");
        assert!(
            (filtered - hover_20s).abs() < 0.002 * hover_20s,
            "{filtered} {hover_20s}"
        );
    }

    #[test]
    fn a_gap_in_the_telemetry_restarts_the_derivative_instead_of_a_spike() {
        let v = shipped();
        let mut sim = BatterySim::new(&v, BatterySimConfig::default()).unwrap();
        flying(&mut sim);
        sim.handle(1, 1, &position(0.0, [0.0; 3]));
        // 2 s later at 5 m/s: no acceleration is made of it.
        sim.handle(1, 1, &position(2.0, [5.0, 0.0, 0.0]));
        assert_eq!(sim.now().accel_ned, [0.0; 3]);
        // Old or repeated samples are ignored; hostile values never panic.
        assert!(sim.motion(1.0, 0.0, [0.0; 3]).is_none());
        assert!(sim.motion(3.0, 0.0, [f64::NAN, 0.0, 0.0]).is_none());
        sim.handle(1, 1, &position(2.02, [5.0, 0.0, -1e6]));
        assert!(sim.now().power_w.is_finite());
    }

    #[test]
    fn following_the_mocks_px4_flight_it_draws_what_the_mocks_own_battery_drew() {
        use crate::link::items::{mission_items, ItemOptions};
        use crate::link::mav::{MavCmd, COMMAND_LONG_DATA};
        use crate::sim::battery::SensorNoise;
        use crate::sim::vehicle::{FlightConfig, SimVehicle, STEP_S};
        use mavlink::MessageData;
        let v = shipped();
        let mission = crate::mission::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("missions/paper-sample-8wp.toml"),
        )
        .unwrap();
        let order: Vec<usize> = (0..mission.waypoints.len()).collect();
        let items = mission_items(&mission, &order, &ItemOptions::default()).unwrap();
        let quiet = SensorNoise {
            voltage_v: 0.0,
            current_a: 0.0,
        };
        let config = FlightConfig {
            home: mission.origin.home,
            noise: quiet,
            ..FlightConfig::default()
        };
        let mut mock = SimVehicle::new(crate::link::Flavour::Px4, &v, config, (1, 1)).unwrap();
        mock.set_mission(&items, 0);
        let start = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_MISSION_START,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        });
        mock.handle((255, 190), &start);
        // PX4's onboard link streams the landed state at 5 Hz (mavlink_main.cpp, ONBOARD mode).
        let landed_at_5_hz = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            param1: EXTENDED_SYS_STATE_DATA::ID as f32,
            param2: 2e5,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        });
        mock.handle((255, 190), &landed_at_5_hz);
        let mut sim = BatterySim::new(&v, BatterySimConfig::default()).unwrap();
        // (time, energy the mock's battery drew, energy the battery process drew)
        let mut trace = Vec::new();
        let mut flew = false;
        for k in 1..=60_000u32 {
            for m in mock.step(f64::from(k) * STEP_S) {
                sim.handle(1, 1, &m);
            }
            trace.push((
                mock.now_s(),
                mock.battery().consumed_wh * 3600.0,
                sim.now().consumed_j,
            ));
            flew |= mock.armed();
            if flew && !mock.armed() && mock.flight().complete() {
                break;
            }
        }
        assert!(flew && !mock.armed(), "the mock did not fly to the end");
        assert_eq!(sim.physics_errors(), 0);
        let &(end_s, mock_j, sim_j) = trace.last().unwrap();
        // Landing: the land detector confirms ground contact 1.2 s late, and until then the
        // battery process prices hover (the mock idles): about 0.6 kJ of 120.
        let at = |t: f64| trace.iter().find(|x| x.0 >= t).copied().unwrap();
        let (a, b) = (at(25.0), at(end_s - 30.0));
        let (mock_air, sim_air) = (b.1 - a.1, b.2 - a.2);
        assert!(
            (sim_j - mock_j).abs() < 0.01 * mock_j,
            "whole flight ({end_s:.0} s): mock {mock_j:.0} J, battery process {sim_j:.0} J"
        );
        // In the air, from the first leg to the last waypoint, they agree closely.
        assert!(
            (sim_air - mock_air).abs() < 0.005 * mock_air,
            "in the air: mock {mock_air:.0} J, battery process {sim_air:.0} J"
        );
    }
}
