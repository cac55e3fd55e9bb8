//! The power model along a trajectory: at each sample of an operation's motion the body
//! (`body`) gives the thrust and pitch it needs, the rotor model the rotor speed and torque that
//! make that thrust, the motor and ESC the electrical power; the battery terminal energy is
//! integrated with the midpoint rule. Operation energy follows the paper (docs/energy-model.md):
//! from the start until the vehicle first comes within 4 m of the end point; the rest of the
//! trajectory plus the profile's settle time in hover is recorded separately so mission totals
//! include everything. The PTF's trajectory is the one of least energy, so it is chosen here.

use super::ardupilot;
use super::body::demand_in_wind;
use super::minimise::golden_section;
use super::powertrain::Powertrain;
use super::profile::line_limit;
use super::px4::{self, Start};
use super::rotor::Rotor;
use super::trajectory::{
    path_peak_speed, px4_trajectory, quintic_line, sampled_trajectory, Acceptance, Path,
    Trajectory, ARRIVAL_RADIUS_M,
};
use super::vehicle::{Px4Params, Vehicle};
use super::{PhysicsError, Profile};
use crate::mission::wind::LegWind;

/// Power the spinning motors draw armed on the ground at idle, on top of the avionics: eight
/// motors at about 5 W each ([assumed]: PX4 idle throttle a few percent of hover thrust).
pub const IDLE_SPIN_POWER_W: f64 = 40.0;

/// One simulated operation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Operation {
    /// Battery energy from the start until first within 4 m of the end point.
    pub energy_j: f64,
    /// Time from the start until first within 4 m of the end point.
    pub duration_s: f64,
    /// Energy from there until settled in hover at the end point.
    pub settle_energy_j: f64,
    /// Time from there until settled in hover at the end point.
    pub settle_duration_s: f64,
    /// Largest speed along the path.
    pub peak_speed_m_s: f64,
}

impl Operation {
    /// Energy of the whole operation, start to settled hover.
    pub fn total_energy_j(&self) -> f64 {
        self.energy_j + self.settle_energy_j
    }

    /// Duration of the whole operation.
    pub fn total_duration_s(&self) -> f64 {
        self.duration_s + self.settle_duration_s
    }
}

/// `emplan energy --json`: one operation, the JSON of DESIGN.md plus the settle phase the 4 m
/// rule leaves out (kJ at this edge only).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct OperationJson {
    pub xf_m: f64,
    pub zf_m: f64,
    pub profile: Profile,
    pub energy_kj: f64,
    pub duration_s: f64,
    pub settle_energy_kj: f64,
    pub settle_duration_s: f64,
}

impl Operation {
    /// The JSON view of this operation, flown over `xf_m`, `zf_m` with `profile`.
    pub fn to_json(&self, xf_m: f64, zf_m: f64, profile: Profile) -> OperationJson {
        OperationJson {
            xf_m,
            zf_m,
            profile,
            energy_kj: self.energy_j / 1000.0,
            duration_s: self.duration_s,
            settle_energy_kj: self.settle_energy_j / 1000.0,
            settle_duration_s: self.settle_duration_s,
        }
    }
}

/// What the vehicle does at one kinematic state.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PowerState {
    power_w: f64,
    tilt_rad: f64,
    /// The blades' perpendicular inflow v_z + kappa v_i (negative: the windmill-brake state).
    inflow_m_s: f64,
    v_x_m_s: f64,
    v_z_m_s: f64,
}

/// The hover before a chain leg (`Model::ardupilot_chain`): the tracking lag for a leg that
/// starts at rest, none for one that starts in a blended turn. Pricing and the mock alike.
fn chain_lead_s(a: &super::vehicle::ArdupilotParams, from_rest: bool) -> f64 {
    if from_rest {
        a.tracking_lag_s.max(0.0)
    } else {
        0.0
    }
}

/// A chain leg's trajectory with its target's positions (east, north, up, m) a tick apart:
/// [`Model::ardupilot_chain_trajectories`].
pub type TrackedTrajectory = (Trajectory, Vec<[f64; 3]>);

/// A vehicle's models, built once and reused for many operations (table builds).
#[derive(Debug, Clone)]
pub struct Model<'a> {
    vehicle: &'a Vehicle,
    rotor: Rotor,
    powertrain: Powertrain,
    max_tilt_rad: f64,
    /// The wind the leg is flown in (calm: still air, the tables' model).
    wind: LegWind,
}

impl<'a> Model<'a> {
    /// The models of `vehicle` at its table state of charge.
    pub fn new(vehicle: &'a Vehicle) -> Model<'a> {
        Model {
            vehicle,
            rotor: Rotor::new(vehicle),
            powertrain: Powertrain::new(vehicle, vehicle.battery.table_state_of_charge),
            max_tilt_rad: vehicle.body.max_tilt_deg.to_radians(),
            wind: LegWind::CALM,
        }
    }

    /// The same models flying in a steady wind, as one leg sees it (`body::demand_in_wind`):
    /// every power, hover and operation priced by them is in that wind. The trajectories are
    /// the still-air ones (the autopilots fly their paths over the ground), except the PTF's,
    /// whose duration is chosen for least energy in the wind.
    pub fn in_wind(self, wind: LegWind) -> Model<'a> {
        Model { wind, ..self }
    }

    /// Battery terminal power at a kinematic state in the leg's plane; also returns the tilt.
    pub fn power_w(&self, vx: f64, vz: f64, ax: f64, az: f64) -> Result<(f64, f64), PhysicsError> {
        self.state(vx, vz, ax, az).map(|s| (s.power_w, s.tilt_rad))
    }

    /// Power, tilt and the rotors' inflow at a kinematic state in the leg's plane.
    fn state(&self, vx: f64, vz: f64, ax: f64, az: f64) -> Result<PowerState, PhysicsError> {
        let d = demand_in_wind(self.vehicle, vx, vz, ax, az, self.wind);
        let rotor = self.rotor.solve(d.thrust_n, d.v_x_m_s, d.v_z_m_s)?;
        let electrical = self.powertrain.electrical(&rotor)?;
        Ok(PowerState {
            power_w: electrical.power_w,
            tilt_rad: d.pitch_rad.abs(),
            inflow_m_s: rotor.induced_velocity_m_s + d.v_z_m_s,
            v_x_m_s: d.v_x_m_s,
            v_z_m_s: d.v_z_m_s,
        })
    }

    /// Battery energy of `trajectory` from `t0_s` to `t1_s` (midpoint rule, `n` steps).
    pub fn trajectory_energy_j(
        &self,
        trajectory: &Trajectory,
        (t0_s, t1_s): (f64, f64),
        n: usize,
    ) -> Result<f64, PhysicsError> {
        self.energy_j(&trajectory.path, (t0_s, t1_s), n.max(1), false)
    }

    /// The vehicle these models were built for.
    pub fn vehicle(&self) -> &Vehicle {
        self.vehicle
    }

    /// Hover power.
    pub fn hover_power_w(&self) -> Result<f64, PhysicsError> {
        Ok(self.power_w(0.0, 0.0, 0.0, 0.0)?.0)
    }

    /// Energy of a path from `t0` to `t1`, `n` midpoint steps; errors when a state is
    /// infeasible, or (if `planned`: a trajectory the PTF chooses) beyond the tilt limit or in
    /// the windmill-brake state.
    ///
    /// The windmill-brake state (the air flowing up through the rotors, which then extract
    /// energy from it) is where Glauert's momentum theory lets a fast diagonal descent glide at
    /// no-load power. Talaeizadeh, Antunes, Nejat Pishkenari and Alasty ("Optimal-time
    /// quadcopter descent trajectories avoiding the vortex ring and autorotation states", arXiv
    /// 1909.09069) propose that a fixed-pitch multirotor avoid it as well as the vortex ring
    /// state, and plan descents that do. A planned trajectory here keeps out of it. What an
    /// autopilot flies (`hvb`, `px4`) is priced as flown.
    fn energy_j(
        &self,
        path: &Path,
        (t0, t1): (f64, f64),
        n: usize,
        planned: bool,
    ) -> Result<f64, PhysicsError> {
        if t1 <= t0 {
            return Ok(0.0);
        }
        let dt = (t1 - t0) / n as f64;
        let mut total = 0.0;
        for k in 0..n {
            let (vx, vz, ax, az) = path.kinematics(t0 + (k as f64 + 0.5) * dt);
            let s = self.state(vx, vz, ax, az)?;
            if planned && s.tilt_rad > self.max_tilt_rad {
                return Err(PhysicsError::TiltLimit {
                    tilt_deg: s.tilt_rad.to_degrees(),
                    max_deg: self.vehicle.body.max_tilt_deg,
                });
            }
            if planned && s.inflow_m_s < 0.0 {
                return Err(PhysicsError::WindmillBrake {
                    inflow_m_s: s.inflow_m_s,
                    v_x_m_s: s.v_x_m_s,
                    v_z_m_s: s.v_z_m_s,
                });
            }
            total += s.power_w * dt;
        }
        Ok(total)
    }

    /// Simulates flying `trajectory`, then hovering its settle time.
    fn fly(&self, trajectory: &Trajectory) -> Result<Operation, PhysicsError> {
        let (path, steps, settle_s) = (&trajectory.path, trajectory.steps, trajectory.settle_s);
        let duration = path.duration_s();
        let t_arrive = path.arrival_s(ARRIVAL_RADIUS_M);
        // A sampled motion is integrated at its own samples.
        let steps = match path {
            Path::Sampled { samples, .. } => samples.points.len().max(steps),
            _ => steps,
        };
        let n1 = ((steps as f64 * t_arrive / duration.max(1e-9)).round() as usize).max(8);
        let n2 = steps.saturating_sub(n1).max(8);
        // Tilt is a planning limit: the PTF search enforces it; HVB and PX4 fly what they fly.
        let energy = self.energy_j(path, (0.0, t_arrive), n1, false)?;
        if let Some(t_accept) = trajectory.accepted_s() {
            // PX4: the waypoint's hold starts at its acceptance and overlaps the rest of the
            // braking. The settle is the motion from the 4 m crossing to the acceptance, plus
            // what the braking after it costs above hovering (the hold is priced as hover).
            let t_accept = t_accept.clamp(t_arrive, duration);
            let n_a = ((steps as f64 * (t_accept - t_arrive) / duration.max(1e-9)).round()
                as usize)
                .max(8);
            let n_b = ((steps as f64 * (duration - t_accept) / duration.max(1e-9)).round()
                as usize)
                .max(8);
            let to_accept = self.energy_j(path, (t_arrive, t_accept), n_a, false)?;
            let tail = self.energy_j(path, (t_accept, duration), n_b, false)?;
            let tail_over_hover = tail - self.hover_power_w()? * (duration - t_accept);
            // A leg that starts inside the acceptance (shorter than NAV_ACC_RAD across and
            // NAV_MC_ALT_RAD up or down) is accepted at once: its whole motion falls in the
            // hold, and a short level move or descent draws less than hovering, so its excess
            // over hover is negative (down to -26 J on the table's grid: a leg of -2 J between
            // such cells). The hold is priced as hover whatever the vehicle does in it, so a
            // motion inside it is credited nothing: the settle is never below zero.
            let settle_energy_j = (to_accept + tail_over_hover).max(0.0);
            let peak = path_peak_speed(path, steps);
            return Ok(Operation {
                energy_j: energy,
                duration_s: t_arrive,
                settle_energy_j,
                settle_duration_s: t_accept - t_arrive,
                peak_speed_m_s: peak,
            });
        }
        let rest = self.energy_j(path, (t_arrive, duration), n2, false)?;
        let peak = path_peak_speed(path, steps);
        // The tracking lag: hover at the start before the path begins.
        let lead_s = trajectory.delay_s;
        let lead_j = if lead_s > 0.0 {
            self.hover_power_w()? * lead_s
        } else {
            0.0
        };
        // Within 4 m from the start (t_arrive 0): the lag counts with the settle.
        let (lead_j, lead_s, late_j, late_s) = lead_split(lead_j, lead_s, t_arrive);
        Ok(Operation {
            energy_j: lead_j + energy,
            duration_s: lead_s + t_arrive,
            settle_energy_j: late_j + rest + self.hover_power_w()? * settle_s,
            settle_duration_s: late_s + duration - t_arrive + settle_s,
            peak_speed_m_s: peak,
        })
    }

    /// The operation from hover to hover over horizontal distance `xf_m` and signed vertical
    /// displacement `zf_m`, flown with `profile`.
    pub fn operation(
        &self,
        profile: Profile,
        xf_m: f64,
        zf_m: f64,
    ) -> Result<Operation, PhysicsError> {
        self.operation_from(profile, xf_m, zf_m, Start::Behind)
    }

    /// [`Model::operation`] for a leg starting `start` of PX4's trajectory (only the `px4`
    /// profile depends on it).
    pub fn operation_from(
        &self,
        profile: Profile,
        xf_m: f64,
        zf_m: f64,
        start: Start,
    ) -> Result<Operation, PhysicsError> {
        let trajectory = self.trajectory_from(profile, xf_m, zf_m, start)?;
        self.priced(&trajectory, xf_m, zf_m, profile)
    }

    /// The trajectory `profile` flies from hover to hover over horizontal distance `xf_m` and
    /// signed vertical displacement `zf_m` (a stationary one when both are zero).
    pub fn trajectory(
        &self,
        profile: Profile,
        xf_m: f64,
        zf_m: f64,
    ) -> Result<Trajectory, PhysicsError> {
        self.trajectory_from(profile, xf_m, zf_m, Start::Behind)
    }

    /// [`Model::trajectory`] for a leg starting `start` of PX4's trajectory.
    pub fn trajectory_from(
        &self,
        profile: Profile,
        xf_m: f64,
        zf_m: f64,
        start: Start,
    ) -> Result<Trajectory, PhysicsError> {
        for (what, value) in [("xf_m", xf_m), ("zf_m", zf_m)] {
            if !value.is_finite() {
                return Err(PhysicsError::NotFinite { what, value });
            }
        }
        let no_trajectory = |reason: String| PhysicsError::NoTrajectory {
            xf_m,
            zf_m,
            profile,
            reason,
        };
        if xf_m < 0.0 {
            return Err(no_trajectory(
                "the horizontal distance must not be negative".into(),
            ));
        }
        let length = xf_m.hypot(zf_m);
        if length < 1e-9 {
            return Ok(Trajectory::stationary());
        }
        let dir = (xf_m / length, zf_m / length);
        let v = self.vehicle;
        match profile {
            Profile::Ptf => {
                let p = &v.ptf;
                // Peak speed of the quintic is 15/8 L / T.
                let v_line = line_limit(
                    dir.0,
                    dir.1,
                    p.max_speed_xy_m_s,
                    p.max_speed_up_m_s,
                    p.max_speed_down_m_s,
                )
                .min(p.max_speed_m_s);
                let t_min = (1.875 * length / v_line).max(0.2);
                let steps = p.steps as usize;
                let quintic = |t: f64| quintic_line(length, dir, t);
                let cost = |t: f64| {
                    self.energy_j(&quintic(t), (0.0, t), steps, true)
                        .unwrap_or(f64::INFINITY)
                };
                // Golden-section search of the duration (E(T) is unimodal: infeasible or
                // expensive when short, hover-dominated when long). When the fastest duration
                // breaks a limit (tilt, the windmill-brake state), the search starts from the
                // shortest feasible one, found by bisection: a descent is cheapest there.
                let t_max = t_min * 4.0 + 20.0;
                let mut t_lo = t_min;
                if !cost(t_min).is_finite() && cost(t_max).is_finite() {
                    let mut hi = t_max;
                    for _ in 0..40 {
                        let mid = 0.5 * (t_lo + hi);
                        if cost(mid).is_finite() {
                            hi = mid;
                        } else {
                            t_lo = mid;
                        }
                    }
                    t_lo = hi;
                }
                let search = golden_section(&cost, (t_lo, t_max), 1e-5, 60);
                let t_best = search.best;
                if !search.best_value.is_finite() {
                    return Err(no_trajectory(
                        "every duration breaks the tilt, motor or battery limits".into(),
                    ));
                }
                Ok(Trajectory {
                    path: quintic(t_best),
                    settle_s: 0.0,
                    steps,
                    acceptance: None,
                    delay_s: p.tracking_lag_s,
                })
            }
            Profile::Hvb => Ok(Trajectory::hvb(&v.hvb, xf_m, zf_m)),
            Profile::Px4 => {
                let x = &v.px4;
                let samples = px4::leg_from(x, xf_m, zf_m, start).map_err(|e| match e {
                    // It names the leg already.
                    PhysicsError::NoTrajectory { .. } => e,
                    other => no_trajectory(other.to_string()),
                })?;
                Ok(px4_trajectory(x, samples, xf_m, zf_m))
            }
            Profile::Ardupilot => {
                let a = &v.ardupilot;
                let samples = ardupilot::leg(a, xf_m, zf_m).map_err(|e| match e {
                    PhysicsError::NoTrajectory { .. } => e,
                    other => no_trajectory(other.to_string()),
                })?;
                // The vehicle trailing its S-curve makes the leg longer by the tracking lag,
                // priced as hover before it moves (as the PTF's).
                Ok(Trajectory {
                    delay_s: a.tracking_lag_s,
                    ..sampled_trajectory(samples, xf_m, zf_m, a.steps, None)
                })
            }
        }
    }

    /// The legs of a chain of waypoints as ArduCopter flies them with fast waypoints
    /// (`ardupilot_chain::chain`: corners blended, each waypoint
    /// reached half-way through its turn), each priced from the moment the waypoint before
    /// was reached to the moment its own is, as a flight log cuts its legs: to the first
    /// moment within the arrival radius (the 4 m rule), the rest as its settle. A leg that
    /// starts at rest is lengthened by `tracking_lag_s` of hover before it, as a rest-to-rest
    /// leg is; a leg that starts in a blended turn is not: the lag was fitted to the vehicle
    /// trailing an S-curve that starts from a standstill (its clock slowed most while the
    /// vehicle gathers speed), and in a blended turn the vehicle is already moving with its
    /// target.
    pub fn ardupilot_chain(
        &self,
        start_enu_m: [f64; 3],
        points: &[super::ardupilot_chain::ChainPoint],
    ) -> Result<Vec<Operation>, PhysicsError> {
        self.ardupilot_chain_in_wind(start_enu_m, points, crate::mission::wind::Wind::CALM)
    }

    /// [`Model::ardupilot_chain`] in a steady `wind`, each leg in what its heading (from the
    /// point before to its own) meets of it, as the mock flies it.
    pub fn ardupilot_chain_in_wind(
        &self,
        start_enu_m: [f64; 3],
        points: &[super::ardupilot_chain::ChainPoint],
        wind: crate::mission::wind::Wind,
    ) -> Result<Vec<Operation>, PhysicsError> {
        let a = &self.vehicle.ardupilot;
        let legs = super::ardupilot_chain::chain(a, start_enu_m, points, ARRIVAL_RADIUS_M)?;
        let froms = std::iter::once(start_enu_m).chain(points.iter().map(|p| p.enu_m));
        let headings: Vec<f64> = froms
            .zip(points)
            .map(|(from, to)| {
                crate::mission::wind::heading_deg(to.enu_m[0] - from[0], to.enu_m[1] - from[1])
            })
            .collect();
        legs.into_iter()
            .zip(headings)
            .map(|(leg, heading)| {
                let model = self.clone().in_wind(wind.on_heading(heading));
                let this = &model;
                let duration = leg.samples.duration_s();
                let arrival = leg.arrival_s.clamp(0.0, duration);
                let n = leg.samples.points.len().max(8);
                let n1 = ((n as f64 * arrival / duration.max(1e-9)).round() as usize).max(8);
                let n2 = n.saturating_sub(n1).max(8);
                let (xf_m, zf_m) = (leg.xf_m, leg.zf_m);
                let t = sampled_trajectory(leg.samples, xf_m, zf_m, a.steps, None);
                let to_arrival = this.energy_j(&t.path, (0.0, arrival), n1, false)?;
                let rest = this.energy_j(&t.path, (arrival, duration), n2, false)?;
                let peak = path_peak_speed(&t.path, n);
                let lead_s = chain_lead_s(a, leg.from_rest);
                let lead_j = if lead_s > 0.0 {
                    this.hover_power_w()? * lead_s
                } else {
                    0.0
                };
                // Within 4 m from the start: the lag counts with the settle (as `fly`).
                let (head_j, head_s, tail_j, tail_s) = lead_split(lead_j, lead_s, arrival);
                Ok(Operation {
                    energy_j: head_j + to_arrival,
                    duration_s: head_s + arrival,
                    settle_energy_j: tail_j + rest,
                    settle_duration_s: tail_s + duration - arrival,
                    peak_speed_m_s: peak,
                })
            })
            .collect()
    }

    /// The legs of a chain of waypoints as ArduCopter flies them (`ardupilot_chain::chain`),
    /// each as the trajectory [`Model::ardupilot_chain`] prices (a leg from rest after its
    /// `tracking_lag_s` of hover) with the target's positions along it (east, north, up, a
    /// sample each [`ardupilot_chain::TICK_S`](super::ardupilot_chain::TICK_S) after the lag):
    /// what the built-in mock flies.
    pub fn ardupilot_chain_trajectories(
        &self,
        start_enu_m: [f64; 3],
        points: &[super::ardupilot_chain::ChainPoint],
    ) -> Result<Vec<TrackedTrajectory>, PhysicsError> {
        let a = &self.vehicle.ardupilot;
        let legs = super::ardupilot_chain::chain(a, start_enu_m, points, ARRIVAL_RADIUS_M)?;
        Ok(legs
            .into_iter()
            .map(|leg| {
                let delay_s = chain_lead_s(a, leg.from_rest);
                let t = sampled_trajectory(leg.samples, leg.xf_m, leg.zf_m, a.steps, None);
                (Trajectory { delay_s, ..t }, leg.track_enu_m)
            })
            .collect())
    }

    /// The take-off `profile` flies from the ground to `height_m` (PX4: NAV_TAKEOFF, its slow
    /// climb near the ground; the others: the operation (0, +h)).
    pub fn takeoff_trajectory(
        &self,
        profile: Profile,
        height_m: f64,
    ) -> Result<Trajectory, PhysicsError> {
        match profile {
            Profile::Px4 if height_m > 0.0 => {
                let x = &self.vehicle.px4;
                let samples = px4::takeoff(x, height_m)?;
                Ok(px4_trajectory(x, samples, 0.0, height_m))
            }
            Profile::Ardupilot if height_m > 0.0 => {
                let a = &self.vehicle.ardupilot;
                let samples = ardupilot::takeoff(a, height_m)?;
                // Complete a stopping distance below the altitude (takeoff.cpp).
                let complete = Acceptance {
                    horizontal_m: a.wp_radius_m,
                    vertical_m: ardupilot::takeoff_complete_below_m(a),
                };
                Ok(sampled_trajectory(
                    samples,
                    0.0,
                    height_m,
                    a.steps,
                    Some(complete),
                ))
            }
            _ => self.trajectory(profile, 0.0, height_m),
        }
    }

    /// The landing `profile` flies from hover `height_m` above the ground to touchdown (PX4:
    /// NAV_LAND, slowing to MPC_LAND_SPEED near the ground; the others: the operation (0, -h)).
    pub fn landing_trajectory(
        &self,
        profile: Profile,
        height_m: f64,
    ) -> Result<Trajectory, PhysicsError> {
        let rise_m = self.vehicle.px4.landing_home_rise_m;
        self.landing_trajectory_home_risen(profile, height_m, rise_m)
    }

    /// [`Model::landing_trajectory`] with PX4's home risen `home_rise_m` in flight instead of
    /// the vehicle's `landing_home_rise_m` (the built-in mock's height estimate does not drift:
    /// 0).
    pub fn landing_trajectory_home_risen(
        &self,
        profile: Profile,
        height_m: f64,
        home_rise_m: f64,
    ) -> Result<Trajectory, PhysicsError> {
        match profile {
            Profile::Px4 if height_m > 0.0 => {
                let x = &Px4Params {
                    landing_home_rise_m: home_rise_m,
                    ..self.vehicle.px4.clone()
                };
                let samples = px4::landing(x, height_m)?;
                Ok(Trajectory {
                    // On the ground at the end: no acceptance, no settle.
                    acceptance: None,
                    ..px4_trajectory(x, samples, 0.0, -px4::landing_descent_m(x, height_m))
                })
            }
            Profile::Ardupilot if height_m > 0.0 => {
                let a = &self.vehicle.ardupilot;
                let samples = ardupilot::landing(a, height_m)?;
                Ok(sampled_trajectory(samples, 0.0, -height_m, a.steps, None))
            }
            _ => self.trajectory(profile, 0.0, -height_m),
        }
    }

    /// The take-off to `height_m` priced: to the end of the climb (PX4: to its acceptance
    /// NAV_MC_ALT_RAD below, where the mission goes on), and its settle.
    pub fn takeoff(&self, profile: Profile, height_m: f64) -> Result<Operation, PhysicsError> {
        let t = self.takeoff_trajectory(profile, height_m)?;
        self.priced(&t, 0.0, height_m, profile)
    }

    /// The landing from `height_m` priced: the descent to touchdown (its last 4 m as the
    /// settle), then the motors idling on the ground, added to the settle, until the autopilot
    /// disarms: PX4's land detector's three phases (ground contact, maybe landed, landed:
    /// `land_detector_s`) and COM_DISARM_LAND after them (commander's auto-disarm); ArduCopter's
    /// land detector ([`ardupilot::LAND_DETECTOR_TRIGGER_S`]), after which it disarms.
    pub fn landing(&self, profile: Profile, height_m: f64) -> Result<Operation, PhysicsError> {
        let t = self.landing_trajectory(profile, height_m)?;
        let mut op = self.priced(&t, 0.0, -height_m, profile)?;
        let on_ground_s = match profile {
            Profile::Px4 => {
                let x = &self.vehicle.px4;
                x.land_detector_s + x.com_disarm_land_s
            }
            Profile::Ardupilot => ardupilot::LAND_DETECTOR_TRIGGER_S,
            Profile::Ptf | Profile::Hvb => 0.0,
        };
        if on_ground_s > 0.0 && height_m > 0.0 {
            op.settle_duration_s += on_ground_s;
            op.settle_energy_j +=
                (self.vehicle.body.avionics_power_w + IDLE_SPIN_POWER_W) * on_ground_s;
        }
        Ok(op)
    }

    fn priced(
        &self,
        trajectory: &Trajectory,
        xf_m: f64,
        zf_m: f64,
        profile: Profile,
    ) -> Result<Operation, PhysicsError> {
        if trajectory.duration_s() <= 0.0 {
            return Ok(Operation {
                energy_j: 0.0,
                duration_s: 0.0,
                settle_energy_j: 0.0,
                settle_duration_s: 0.0,
                peak_speed_m_s: 0.0,
            });
        }
        self.fly(trajectory).map_err(|e| match e {
            PhysicsError::NoTrajectory { .. } => e,
            other => PhysicsError::NoTrajectory {
                xf_m,
                zf_m,
                profile,
                reason: other.to_string(),
            },
        })
    }
}

/// The tracking lag's hover `lead_j`, `lead_s` before a leg: with the leg when the leg reaches its
/// point `arrival_s` after it starts, with the settle when it starts within 4 m of it (as `fly`
/// segments it). Returns (leg energy, leg time, settle energy, settle time).
fn lead_split(lead_j: f64, lead_s: f64, arrival_s: f64) -> (f64, f64, f64, f64) {
    if arrival_s > 0.0 {
        (lead_j, lead_s, 0.0, 0.0)
    } else {
        (0.0, 0.0, lead_j, lead_s)
    }
}

/// One operation of `vehicle` flown with `profile` (direct simulation, not the table).
pub fn simulate_operation(
    vehicle: &Vehicle,
    profile: Profile,
    xf_m: f64,
    zf_m: f64,
) -> Result<Operation, PhysicsError> {
    Model::new(vehicle).operation(profile, xf_m, zf_m)
}

/// Battery terminal power in hover.
pub fn hover_power_w(vehicle: &Vehicle) -> Result<f64, PhysicsError> {
    Model::new(vehicle).hover_power_w()
}

/// Battery terminal power in steady level flight at `speed_m_s`.
pub fn level_flight_power_w(vehicle: &Vehicle, speed_m_s: f64) -> Result<f64, PhysicsError> {
    Ok(Model::new(vehicle).power_w(speed_m_s, 0.0, 0.0, 0.0)?.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::profile::Schedule;
    use crate::physics::vehicle::shipped;

    #[test]
    fn a_ptf_descent_keeps_the_rotors_out_of_the_windmill_brake_state() {
        let v = shipped();
        let model = Model::new(&v);
        let line = |xf: f64, zf: f64, duration_s: f64| Path::Line {
            schedule: Schedule::Quintic {
                length_m: xf.hypot(zf),
                duration_s,
            },
            length_m: xf.hypot(zf),
            dir: (xf / xf.hypot(zf), zf / xf.hypot(zf)),
        };
        for (xf, zf) in [(24.0, -22.0), (40.0, -38.0), (40.0, -25.0), (16.97, -11.0)] {
            let t = model.trajectory(Profile::Ptf, xf, zf).unwrap();
            let n = 400;
            let mut least = f64::INFINITY;
            for k in 0..=n {
                let (vx, vz, ax, az) = t.kinematics(t.duration_s() * k as f64 / n as f64);
                least = least.min(model.state(vx, vz, ax, az).unwrap().inflow_m_s);
            }
            // Checked at the 200 integration points; between them it may dip by a hair.
            assert!(least >= -0.01, "({xf}, {zf}): inflow {least} m/s");
            // And it flies as fast as that allows: 5% faster would enter the state.
            let faster = line(xf, zf, 0.95 * (t.duration_s() - t.delay_s()));
            let e = model.energy_j(&faster, (0.0, faster.duration_s()), 200, true);
            assert!(
                matches!(
                    e,
                    Err(PhysicsError::WindmillBrake { .. } | PhysicsError::TiltLimit { .. })
                ),
                "({xf}, {zf}): {e:?}"
            );
        }
        // Glauert's theory would let the same leg glide at no-load power: flown with a 9 m/s
        // peak, without the limit, part of it is below 100 W.
        let fast = line(24.0, -22.0, 1.875 * 24.0f64.hypot(22.0) / 9.0);
        let least_power = (0..200)
            .map(|k| {
                let (vx, vz, ax, az) = fast.kinematics(fast.duration_s() * k as f64 / 200.0);
                model.power_w(vx, vz, ax, az).unwrap().0
            })
            .fold(f64::INFINITY, f64::min);
        assert!(least_power < 100.0, "{least_power} W");
    }

    #[test]
    fn hover_power_is_plausible_for_a_five_and_a_half_kilogram_octorotor() {
        // Ideal (momentum) hover power (mg)^1.5 / sqrt(2 rho 8 A) is 263 W at 5.5 kg; a figure
        // of merit near 0.6 and motor/ESC efficiency near 0.8 put the electrical power near
        // 500-560 W (DJI: 1500 W at 9.5 kg, which scales as m^1.5 to 640 W at 5.5 kg).
        let p = hover_power_w(&shipped()).unwrap();
        assert!((450.0..650.0).contains(&p), "hover {p} W");
    }

    #[test]
    fn level_flight_power_has_its_minimum_between_five_and_twelve_metres_per_second() {
        let v = shipped();
        // Up to the vehicle's top speed, 16 m/s (NASA prog_models' S1000).
        let speeds: Vec<f64> = (0..=32).map(|k| 0.5 * k as f64).collect();
        let powers: Vec<f64> = speeds
            .iter()
            .map(|&s| level_flight_power_w(&v, s).unwrap())
            .collect();
        let (k_min, p_min) = powers
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .map(|(k, &p)| (k, p))
            .unwrap();
        assert!(
            (5.0..=12.0).contains(&speeds[k_min]),
            "minimum at {} m/s",
            speeds[k_min]
        );
        // A bucket: cheaper than hover at the minimum, dearer again at high speed.
        assert!(
            p_min < 0.95 * powers[0] && powers[32] > p_min * 1.2,
            "{powers:?}"
        );
    }

    fn energy(x: f64, z: f64) -> f64 {
        simulate_operation(&shipped(), Profile::Ptf, x, z)
            .unwrap()
            .energy_j
    }

    #[test]
    fn climbing_costs_more_per_metre_than_level_flight_which_costs_more_than_descending() {
        // Marginal costs from a 40 m level leg, as the paper's table gives them (research
        // section 5.1: climbing 105 J/m, level 76 J/m, descending -49 J/m).
        let base = energy(40.0, 0.0);
        let climb = (energy(40.0, 25.0) - base) / 25.0;
        let level = (energy(56.6, 0.0) - base) / 16.6;
        let descent = (energy(40.0, -25.0) - base) / 25.0;
        assert!(
            climb > level && level > descent,
            "{climb} {level} {descent} J/m"
        );
        assert!(descent < 0.0, "descending saves energy: {descent} J/m");
        assert!(energy(40.0, -25.0) < energy(40.0, -1.0));
        assert!(energy(40.0, -1.0) < energy(40.0, 1.0));
        assert!(energy(40.0, 1.0) < energy(40.0, 25.0));
    }

    #[test]
    fn a_diagonal_leg_costs_far_less_than_its_horizontal_and_vertical_parts_flown_apart() {
        let diagonal = energy(50.0, 30.0);
        let apart = energy(50.0, 0.0) + energy(0.0, 30.0);
        assert!(diagonal < 0.8 * apart, "{diagonal} vs {apart}");
    }

    #[test]
    fn climbing_and_descending_the_same_leg_cost_different_energies() {
        for (x, z) in [(40.0, 25.0), (0.0, 24.0), (40.0, 1.0)] {
            let (up, down) = (energy(x, z), energy(x, -z));
            assert!(up > down * 1.02, "E({x},{z}) {up} vs E({x},-{z}) {down}");
        }
    }

    #[test]
    fn every_profile_ends_settled_and_reports_the_four_metre_rule() {
        let v = shipped();
        for profile in Profile::ALL {
            let op = simulate_operation(&v, profile, 40.0, 10.0).unwrap();
            assert!(
                op.energy_j > 0.0 && op.settle_energy_j > 0.0,
                "{profile}: {op:?}"
            );
            assert!(op.duration_s > 0.0 && op.total_duration_s() > op.duration_s);
            // Within 4 m already: all the energy is settling.
            let short = simulate_operation(&v, profile, 3.0, 0.0).unwrap();
            assert_eq!(short.energy_j, 0.0);
            assert!(short.settle_energy_j > 0.0);
        }
    }

    #[test]
    fn every_profile_trajectory_ends_at_rest_at_the_end_point_and_prices_its_operation() {
        let v = shipped();
        let model = Model::new(&v);
        for profile in Profile::ALL {
            let t = model.trajectory(profile, 40.0, -10.0).unwrap();
            let (x, z) = t.position_m(t.duration_s());
            assert!(
                (x - 40.0).abs() < 1e-6 && (z + 10.0).abs() < 1e-6,
                "{profile}: {x} {z}"
            );
            assert_eq!(t.kinematics(t.duration_s() + 1.0), (0.0, 0.0, 0.0, 0.0));
            assert!(t.remaining_m(0.0) > 41.0 && t.remaining_m(t.duration_s()) < 1e-6);
            let op = model.operation(profile, 40.0, -10.0).unwrap();
            match t.accepted_s() {
                // PX4 ends the operation where it accepts the point (its hold starts there).
                Some(accepted) => {
                    assert!(accepted < t.duration_s() && t.acceptance().is_some());
                    assert!((op.total_duration_s() - accepted).abs() < 1e-9, "{op:?}");
                }
                None => {
                    assert!((op.total_duration_s() - t.duration_s() - t.settle_s()).abs() < 1e-9)
                }
            }
        }
        assert_eq!(
            model
                .trajectory(Profile::Px4, 0.0, 0.0)
                .unwrap()
                .duration_s(),
            0.0
        );
    }

    #[test]
    fn infeasible_inputs_are_typed_errors() {
        let v = shipped();
        assert!(matches!(
            simulate_operation(&v, Profile::Ptf, f64::NAN, 0.0),
            Err(PhysicsError::NotFinite { .. })
        ));
        assert!(matches!(
            simulate_operation(&v, Profile::Px4, -1.0, 0.0),
            Err(PhysicsError::NoTrajectory { .. })
        ));
        // Four times the vehicle's mass is beyond what the motors can lift at this battery voltage.
        let mut heavy = v.clone();
        heavy.body.mass_kg *= 4.0;
        assert!(matches!(
            hover_power_w(&heavy),
            Err(PhysicsError::MotorSaturated { .. })
        ));
        let err = simulate_operation(&heavy, Profile::Hvb, 40.0, 25.0).unwrap_err();
        assert!(matches!(err, PhysicsError::NoTrajectory { .. }), "{err}");
        assert!(err.to_string().contains("motors saturated"), "{err}");
    }

    #[test]
    fn a_px4_landing_ends_when_px4_disarms_the_motors_idling_through_the_land_detector() {
        let v = crate::physics::vehicle::shipped();
        let mut none = v.clone();
        none.px4.land_detector_s = 0.0;
        none.px4.com_disarm_land_s = 0.0;
        let with = Model::new(&v).landing(Profile::Px4, 30.0).unwrap();
        let without = Model::new(&none).landing(Profile::Px4, 30.0).unwrap();
        let on_ground_s = v.px4.land_detector_s + v.px4.com_disarm_land_s;
        assert!(
            (on_ground_s - 3.2).abs() < 1e-12,
            "1.2 s measured, PX4's default 2 s"
        );
        assert_eq!(with.energy_j, without.energy_j);
        assert!((with.total_duration_s() - without.total_duration_s() - on_ground_s).abs() < 1e-9);
        let idle_j = (v.body.avionics_power_w + IDLE_SPIN_POWER_W) * on_ground_s;
        assert!((with.total_energy_j() - without.total_energy_j() - idle_j).abs() < 1e-6);
        // The other profiles end at touchdown.
        let ptf = Model::new(&v).landing(Profile::Ptf, 30.0).unwrap();
        assert_eq!(ptf, Model::new(&none).landing(Profile::Ptf, 30.0).unwrap());
    }

    #[test]
    fn an_ardupilot_landing_ends_when_its_land_detector_says_landed_the_motors_idling() {
        let v = crate::physics::vehicle::shipped();
        let model = Model::new(&v);
        let op = model.landing(Profile::Ardupilot, 20.0).unwrap();
        let descent = model.landing_trajectory(Profile::Ardupilot, 20.0).unwrap();
        let on_ground_s = ardupilot::LAND_DETECTOR_TRIGGER_S;
        assert_eq!(on_ground_s, 1.0);
        assert!(
            (op.total_duration_s() - descent.duration_s() - on_ground_s).abs() < 1e-9,
            "{op:?}"
        );
        let in_air_j = model
            .trajectory_energy_j(&descent, (0.0, descent.duration_s()), 4000)
            .unwrap();
        let idle_j = (v.body.avionics_power_w + IDLE_SPIN_POWER_W) * on_ground_s;
        let rel = (op.total_energy_j() - in_air_j - idle_j) / op.total_energy_j();
        assert!(rel.abs() < 1e-3, "{rel}");
    }
}
