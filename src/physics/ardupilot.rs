//! How ArduCopter flies a mission leg, a take-off and a landing in AUTO mode, run in time steps in
//! the leg's vertical plane (x horizontal along the leg, z up), so the `ardupilot` profile prices
//! the motion ArduCopter really commands. Ported from ArduPilot (master of 2026-04, the build the
//! ArduCopter SITL of sitl/README.md runs; parameter names as that build gives them, in SI units):
//! - `libraries/AP_Math/SCurve.cpp`: a straight waypoint leg is one jerk-limited S-curve along
//!   the 3D line from the previous destination to the next: 23 segments (`add_segments`: an
//!   acceleration S-curve, seven empty speed-change segments, a constant-speed segment, a
//!   deceleration S-curve), each jerk phase a raised cosine of duration `tj` (its rate of change,
//!   the snap, limited) with the segment durations of `calculate_path`; the speed and
//!   acceleration along the line are the largest whose horizontal and vertical parts keep
//!   within their limits (`generate_path`, `libraries/AP_Math/control.cpp` `kinematic_limit`);
//! - `libraries/AC_WPNav/AC_WPNav.cpp`: the leg's limits are WP_SPD, WP_SPD_UP, WP_SPD_DN
//!   (`set_wp_destination` -> `calculate_track`), WP_ACC and WP_ACC_Z; its jerk is WP_JERK,
//!   capped by the attitude controller's rate limits ATC_RATE_R_MAX / ATC_RATE_P_MAX times g
//!   when set, and its snap jerk x pi / (2 ATC_INPUT_TC), capped by ATC_ACC_R_MAX /
//!   ATC_ACC_P_MAX times g, then halved (`calc_scurve_jerk_and_snap`). A waypoint with a hold is
//!   not a fast waypoint: the leg ends at rest on it, and ArduCopter counts it reached when the
//!   S-curve has finished and the vehicle is within WP_RADIUS_M (`advance_wp_target_along_track`),
//!   where its hold starts (ArduCopter/mode_auto.cpp `verify_nav_wp`). The trajectory's clock is
//!   slowed while the vehicle falls behind its target, which depends on the vehicle's response
//!   and is not modelled here: `physics::power` prices it as a hover of `tracking_lag_s` before
//!   the S-curve (calibrated to a vehicle's leg durations);
//! - `ArduCopter/takeoff.cpp` `_AutoTakeoff::run`: NAV_TAKEOFF moves the vertical position
//!   target to the take-off altitude through `AC_PosControl::input_pos_vel_accel_U`
//!   (`control.cpp` `shape_pos_vel_accel`: a square-root approach with speed limits WP_SPD_UP
//!   and WP_SPD_DN, acceleration WP_ACC_Z, jerk PSC_JERK_D); it is complete when the target is
//!   within the stopping distance from a tenth of WP_SPD_UP of the altitude and its climb rate
//!   below a tenth of WP_SPD_UP;
//! - `ArduCopter/mode.cpp` `land_run_vertical_control`: NAV_LAND descends at the square-root
//!   controller's rate towards LAND_ALT_LOW_M (gain PSC_D_POS_P, acceleration WP_ACC_Z),
//!   constrained between LAND_SPD_HIGH_MS (WP_SPD_DN when zero) and LAND_SPD_MS, so it descends
//!   fast above LAND_ALT_LOW_M and at LAND_SPD_MS below, into the ground; the velocity is shaped
//!   by `shape_vel_accel` (acceleration WP_ACC_Z, jerk PSC_JERK_D).
//!
//! Pure: parameters in, sampled motion out.

use std::f64::consts::PI;

use super::profile::line_limit;
use super::px4::Samples;
use super::vehicle::ArdupilotParams;
use super::PhysicsError;

/// Time step of the sampled motion (ArduCopter's position controller runs at 400 Hz; the
/// S-curve is exact at any instant, the vertical shapers are integrated at this step).
pub const STEP_S: f64 = 0.01;

/// The longest a single motion may take before it is refused.
const MAX_DURATION_S: f64 = 3600.0;

/// How long ArduCopter's land detector waits, its conditions met on the ground, before it says
/// landed (ArduCopter/land_detector.cpp LAND_DETECTOR_TRIGGER_SEC); AUTO's NAV_LAND then
/// disarms (mode_auto.cpp `verify_land`).
pub const LAND_DETECTOR_TRIGGER_S: f64 = 1.0;

/// ArduPilot's GRAVITY_MSS (libraries/AP_Math/definitions.h).
const GRAVITY_MSS: f64 = 9.80665;

/// How the jerk of one S-curve segment varies (SCurve.cpp `SegmentType`).
#[derive(Debug, Clone, Copy, PartialEq)]
enum JerkShape {
    Constant,
    /// A raised cosine from 0 to the segment's jerk.
    Rising,
    /// A raised cosine from the segment's jerk to 0.
    Falling,
}

/// One S-curve segment: its shape and jerk, and the state at its end.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Segment {
    shape: JerkShape,
    jerk: f64,
    end_s: f64,
    end_accel: f64,
    end_vel: f64,
    end_pos: f64,
}

/// (jerk, acceleration, velocity, position) after `t` of a segment of `shape` lasting `tj`
/// with jerk `jm`, from (a0, v0, p0): SCurve.cpp `calc_javp_for_segment_const_jerk`,
/// `_incr_jerk` and `_decr_jerk`.
fn segment_state(
    shape: JerkShape,
    t: f64,
    tj: f64,
    jm: f64,
    (a0, v0, p0): (f64, f64, f64),
) -> (f64, f64, f64, f64) {
    match shape {
        JerkShape::Constant => (
            jm,
            a0 + jm * t,
            v0 + a0 * t + 0.5 * jm * t * t,
            p0 + v0 * t + 0.5 * a0 * t * t + jm * t * t * t / 6.0,
        ),
        _ if tj <= 0.0 => (0.0, a0, v0, p0),
        JerkShape::Rising => {
            let (alpha, beta) = (0.5 * jm, PI / tj);
            (
                alpha * (1.0 - (beta * t).cos()),
                a0 + alpha * t - alpha / beta * (beta * t).sin(),
                v0 + a0 * t + 0.5 * alpha * t * t + alpha / (beta * beta) * (beta * t).cos()
                    - alpha / (beta * beta),
                p0 + v0 * t + 0.5 * a0 * t * t - alpha / (beta * beta) * t
                    + alpha * t * t * t / 6.0
                    + alpha / (beta * beta * beta) * (beta * t).sin(),
            )
        }
        JerkShape::Falling => {
            // The second half of a raised cosine of duration 2 tj, shifted to start at t = 0.
            let (alpha, beta) = (0.5 * jm, PI / tj);
            let at = alpha * tj;
            let vt = alpha * (tj * tj * 0.5 - 2.0 / (beta * beta));
            let pt = alpha * (-tj / (beta * beta) + tj * tj * tj / 6.0);
            let u = t + tj;
            (
                alpha * (1.0 - (beta * u).cos()),
                (a0 - at) + alpha * u - alpha / beta * (beta * u).sin(),
                (v0 - vt)
                    + (a0 - at) * t
                    + 0.5 * alpha * u * u
                    + alpha / (beta * beta) * (beta * u).cos()
                    - alpha / (beta * beta),
                (p0 - pt) + (v0 - vt) * t + 0.5 * (a0 - at) * t * t - alpha / (beta * beta) * u
                    + alpha / 6.0 * u * u * u
                    + alpha / (beta * beta * beta) * (beta * u).sin(),
            )
        }
    }
}

/// The segment durations of SCurve.cpp `calculate_path`: from speed `v0` towards `vm` within
/// half the path `l`, with snap `sm`, jerk `jm`, acceleration `am`. Returns (jerk, tj, t2,
/// t4, t6): raised-cosine jerk phases of `tj` around a constant jerk of `t2` (rising) and `t6`
/// (falling), with `t4` of constant acceleration between them; all zero when no change fits.
fn calculate_path(
    sm: f64,
    jm: f64,
    v0: f64,
    am: f64,
    vm: f64,
    l: f64,
) -> (f64, f64, f64, f64, f64) {
    let none = (0.0, 0.0, 0.0, 0.0, 0.0);
    if !(sm > 0.0 && jm > 0.0 && am > 0.0 && vm > 0.0 && l > 0.0) || v0 >= vm {
        return none;
    }
    let (mut jm, mut am) = (jm, am);
    let mut tj = jm * PI / (2.0 * sm);
    let at = am
        .min((vm - v0) / (2.0 * tj))
        .min((l - 4.0 * v0 * tj) / (4.0 * tj * tj));
    if at <= 0.0 {
        return none;
    }
    // The constant-acceleration solution's t4 (SCurve.cpp's closed form, shared by its
    // solutions 2 and 7).
    let t4_of = |am: f64, jm: f64, tj: f64| -> f64 {
        let root = (am.powi(4) / 4.0
            + jm * jm * v0 * v0
            + am * am * jm * jm * tj * tj / 4.0
            + am * jm * jm * l * 2.0
            - am * am * jm * v0
            + am.powi(3) * jm * tj / 2.0
            - am * jm * jm * v0 * tj)
            .max(0.0)
            .sqrt();
        let base = am * am * (-1.5) - jm * v0 - am * jm * tj * 1.5;
        let plus = (base + root) / (am * jm);
        let minus = (base - root) / (am * jm);
        (-(v0 - vm + am * tj + am * am / jm) / am)
            .min(plus.max(minus))
            .max(0.0)
    };
    let (t2, t4, t6);
    if at.abs() < jm * tj {
        if v0 == 0.0 {
            tj = tj
                .min((l * PI / (8.0 * sm)).powf(0.25))
                .min((vm * PI / (4.0 * sm)).powf(1.0 / 3.0))
                .min((am * PI / (2.0 * sm)).max(0.0).sqrt());
            jm = 2.0 * sm * tj / PI;
            am = jm * tj;
        } else {
            am = at;
            jm = am / tj;
        }
        if vm <= v0 + 2.0 * am * tj || l <= 4.0 * v0 * tj + 4.0 * am * tj * tj {
            (t2, t4, t6) = (0.0, 0.0, 0.0);
        } else {
            (t2, t4, t6) = (0.0, t4_of(am, jm, tj), 0.0);
        }
    } else if vm < v0 + am * tj + am * am / jm
        || l < 1.0 / (jm * jm) * (am.powi(3) + am * jm * (v0 * 2.0 + am * tj * 2.0))
            + v0 * tj * 2.0
            + am * tj * tj
    {
        // No constant acceleration: the largest acceleration that fits the speed change and
        // the distance (SCurve.cpp's solution 5, its cubic's root by Cardano).
        let by_speed = (jm
            * (tj + ((v0 * -4.0 + vm * 4.0 + jm * tj * tj) / jm).max(0.0).sqrt())
            * -0.5)
            .max(jm * (tj - ((v0 * -4.0 + vm * 4.0 + jm * tj * tj) / jm).max(0.0).sqrt()) * -0.5);
        let q = -(jm * jm) * l * 0.5 + jm.powi(3) * tj.powi(3) * (8.0 / 27.0)
            - jm * tj * (jm * jm * tj * tj + jm * v0 * 2.0) / 3.0
            + jm * jm * v0 * tj;
        let p = jm * jm * tj * tj / 9.0 - jm * v0 * (2.0 / 3.0);
        let s = (q * q - p.powi(3)).max(0.0).sqrt();
        let by_distance =
            jm * tj * (-2.0 / 3.0) + p / (s - q).powf(1.0 / 3.0) + (s - q).powf(1.0 / 3.0);
        am = am.min(by_speed).min(by_distance);
        t2 = am / jm - tj;
        (t4, t6) = (0.0, t2);
    } else {
        t2 = am / jm - tj;
        t4 = t4_of(am, jm, tj);
        t6 = t2;
    }
    let outputs = [jm, tj, t2, t4, t6];
    if outputs.iter().any(|x| !x.is_finite() || *x < 0.0) {
        return none;
    }
    (jm, tj, t2, t4, t6)
}

/// ArduPilot's S-curve from rest to rest along a line (SCurve.cpp, `calculate_track` of a
/// straight segment with `add_segments`).
#[derive(Debug, Clone, PartialEq)]
pub struct SCurve {
    segments: Vec<Segment>,
}

impl SCurve {
    /// The rest-to-rest S-curve over `length_m` with speed, acceleration, jerk and snap limits
    /// along it.
    pub fn rest_to_rest(
        length_m: f64,
        speed_m_s: f64,
        accel_m_s2: f64,
        jerk_m_s3: f64,
        snap_m_s4: f64,
    ) -> SCurve {
        let mut c = SCurve {
            segments: vec![Segment {
                shape: JerkShape::Constant,
                jerk: 0.0,
                end_s: 0.0,
                end_accel: 0.0,
                end_vel: 0.0,
                end_pos: 0.0,
            }],
        };
        let limits = [length_m, speed_m_s, accel_m_s2, jerk_m_s3, snap_m_s4];
        if !limits.iter().all(|x| *x > 0.0) {
            return c;
        }
        let (jm, tj, t2, t4, t6) = calculate_path(
            snap_m_s4,
            jerk_m_s3,
            0.0,
            accel_m_s2,
            speed_m_s,
            length_m * 0.5,
        );
        c.jerk_phases(tj, jm, t2);
        c.add(JerkShape::Constant, t4, 0.0);
        c.jerk_phases(tj, -jm, t6);
        c.last_mut().end_accel = 0.0;
        for _ in 0..7 {
            c.add(JerkShape::Constant, 0.0, 0.0);
        }
        let top = *c.last_mut();
        let cruise = if top.end_vel > 0.0 {
            ((length_m - 2.0 * top.end_pos) / top.end_vel).max(0.0)
        } else {
            0.0
        };
        c.add(JerkShape::Constant, cruise, 0.0);
        c.jerk_phases(tj, -jm, t6);
        c.add(JerkShape::Constant, t4, 0.0);
        c.jerk_phases(tj, jm, t2);
        let end = c.last_mut();
        end.end_accel = 0.0;
        end.end_vel = 0.0;
        c
    }

    fn last_mut(&mut self) -> &mut Segment {
        let last = self.segments.len() - 1;
        &mut self.segments[last]
    }

    /// SCurve.cpp `add_segments_jerk`: a rising raised cosine, constant jerk, a falling one.
    fn jerk_phases(&mut self, tj: f64, jm: f64, t_const: f64) {
        self.add(JerkShape::Rising, tj, jm);
        self.add(JerkShape::Constant, t_const, jm);
        self.add(JerkShape::Falling, tj, jm);
    }

    fn add(&mut self, shape: JerkShape, duration_s: f64, jerk: f64) {
        let prev = *self.last_mut();
        let start = (prev.end_accel, prev.end_vel, prev.end_pos);
        // A segment of no duration copies the previous state (SCurve.cpp).
        let (shape, jerk, duration_s) = if duration_s > 0.0 {
            (shape, jerk, duration_s)
        } else {
            (
                JerkShape::Constant,
                if shape == JerkShape::Constant {
                    jerk
                } else {
                    0.0
                },
                0.0,
            )
        };
        let (_, a, v, p) = segment_state(shape, duration_s, duration_s, jerk, start);
        self.segments.push(Segment {
            shape,
            jerk,
            end_s: prev.end_s + duration_s,
            end_accel: a,
            end_vel: v,
            end_pos: p,
        });
    }

    /// Time from start to rest at the end.
    pub fn duration_s(&self) -> f64 {
        self.segments.last().map_or(0.0, |s| s.end_s)
    }

    /// Whether the path has all of SCurve.cpp's 23 segments (a path of no length has only its
    /// initial one: SCurve.cpp `num_segs != segments_max`, its times then all 0).
    fn complete(&self) -> bool {
        self.segments.len() == 23
    }

    /// When the acceleration ends and the constant speed begins (SCurve.cpp `time_accel_end`:
    /// the end of segment 7).
    pub fn time_accel_end_s(&self) -> f64 {
        if self.complete() {
            self.segments[7].end_s
        } else {
            0.0
        }
    }

    /// When the constant speed ends and the deceleration begins (SCurve.cpp
    /// `time_decel_start`: the end of segment 15).
    pub fn time_decel_start_s(&self) -> f64 {
        if self.complete() {
            self.segments[15].end_s
        } else {
            0.0
        }
    }

    /// Length of the path.
    pub fn length_m(&self) -> f64 {
        self.segments.last().map_or(0.0, |s| s.end_pos)
    }

    /// (jerk, acceleration, speed, position) along the line at `t_s` (SCurve.cpp
    /// `get_jerk_accel_vel_pos_at_time`).
    pub fn at(&self, t_s: f64) -> (f64, f64, f64, f64) {
        let k = self.segments.iter().position(|s| t_s < s.end_s);
        match k {
            Some(0) | None => {
                let s = if k.is_none() {
                    self.segments[self.segments.len() - 1]
                } else {
                    self.segments[0]
                };
                let (_, a, v, p) = segment_state(
                    JerkShape::Constant,
                    t_s - s.end_s,
                    0.0,
                    0.0,
                    (s.end_accel, s.end_vel, s.end_pos),
                );
                (0.0, a, v, p.max(0.0))
            }
            Some(k) => {
                let (prev, seg) = (self.segments[k - 1], self.segments[k]);
                let (j, a, v, p) = segment_state(
                    seg.shape,
                    t_s - prev.end_s,
                    seg.end_s - prev.end_s,
                    seg.jerk,
                    (prev.end_accel, prev.end_vel, prev.end_pos),
                );
                (j, a, v, p.max(0.0))
            }
        }
    }
}

/// The S-curve's jerk and snap for waypoint legs (AC_WPNav.cpp `calc_scurve_jerk_and_snap`).
pub fn scurve_jerk_snap(p: &ArdupilotParams) -> (f64, f64) {
    let rate_max = [p.atc_rate_r_max_deg_s, p.atc_rate_p_max_deg_s]
        .into_iter()
        .map(f64::to_radians)
        .fold(f64::INFINITY, f64::min);
    // ATC_RATE_*_MAX of 0 is no limit: the jerk is WP_JERK.
    let jerk = if rate_max > 0.0 && rate_max.is_finite() {
        (rate_max * GRAVITY_MSS).min(p.wp_jerk_m_s3)
    } else {
        p.wp_jerk_m_s3
    };
    let mut snap = jerk * PI / (2.0 * p.atc_input_tc_s.max(0.1));
    let accel_max = p
        .atc_acc_r_max_deg_s2
        .min(p.atc_acc_p_max_deg_s2)
        .to_radians()
        * GRAVITY_MSS;
    if accel_max > 0.0 {
        snap = snap.min(accel_max);
    }
    (jerk, 0.5 * snap)
}

/// The S-curve ArduCopter flies a waypoint leg of `xf_m` horizontally and `zf_m` up with.
pub fn leg_scurve(p: &ArdupilotParams, xf_m: f64, zf_m: f64) -> SCurve {
    let length = xf_m.hypot(zf_m);
    if length <= 0.0 {
        return SCurve::rest_to_rest(0.0, 1.0, 1.0, 1.0, 1.0);
    }
    let (ux, uz) = (xf_m / length, zf_m / length);
    let speed = line_limit(ux, uz, p.wp_spd_m_s, p.wp_spd_up_m_s, p.wp_spd_dn_m_s);
    let accel = line_limit(ux, uz, p.wp_acc_m_s2, p.wp_acc_z_m_s2, p.wp_acc_z_m_s2);
    let (jerk, snap) = scurve_jerk_snap(p);
    SCurve::rest_to_rest(length, speed, accel, jerk, snap)
}

/// A mission leg from hover to hover over `xf_m` horizontally and `zf_m` up: the S-curve
/// sampled every [`STEP_S`], ending at rest on the waypoint (where ArduCopter counts it
/// reached).
pub fn leg(p: &ArdupilotParams, xf_m: f64, zf_m: f64) -> Result<Samples, PhysicsError> {
    let curve = leg_scurve(p, xf_m, zf_m);
    let duration = curve.duration_s();
    if !duration.is_finite() || duration > MAX_DURATION_S {
        return Err(no_arrival(xf_m, zf_m, "leg"));
    }
    let length = xf_m.hypot(zf_m);
    let (ux, uz) = if length > 0.0 {
        (xf_m / length, zf_m / length)
    } else {
        (0.0, 0.0)
    };
    let n = (duration / STEP_S).ceil() as usize;
    let mut points: Vec<[f64; 6]> = (0..n)
        .map(|k| {
            let (_, a, v, s) = curve.at(k as f64 * STEP_S);
            [ux * s, uz * s, ux * v, uz * v, ux * a, uz * a]
        })
        .collect();
    points.push([xf_m, zf_m, 0.0, 0.0, 0.0, 0.0]);
    Ok(Samples {
        step_s: STEP_S,
        points,
    })
}

/// One vertical axis of AC_PosControl's target: position, velocity, acceleration (up).
#[derive(Debug, Clone, Copy, Default)]
struct Vertical {
    pos: f64,
    vel: f64,
    accel: f64,
}

/// control.cpp `sqrt_controller`.
fn sqrt_controller(error: f64, p: f64, second_ord_lim: f64, dt: f64) -> f64 {
    let rate = if second_ord_lim <= 0.0 {
        error * p
    } else if p == 0.0 {
        error.signum() * (2.0 * second_ord_lim * error.abs()).sqrt()
    } else {
        let linear = second_ord_lim / (p * p);
        if error > linear {
            (2.0 * second_ord_lim * (error - linear / 2.0)).sqrt()
        } else if error < -linear {
            -(2.0 * second_ord_lim * (-error - linear / 2.0)).sqrt()
        } else {
            error * p
        }
    };
    if dt > 0.0 {
        rate.clamp(-error.abs() / dt, error.abs() / dt)
    } else {
        rate
    }
}

impl Vertical {
    /// control.cpp `update_pos_vel_accel`: the target moved on by `dt`.
    fn advance(&mut self, dt: f64) {
        self.pos += self.vel * dt + 0.5 * self.accel * dt * dt;
        self.vel += self.accel * dt;
    }

    /// control.cpp `shape_vel_accel` (no acceleration input): the acceleration moved towards
    /// the one that corrects the velocity, within `accel_max` and `jerk_max`.
    fn shape_vel(&mut self, vel_input: f64, accel_max: f64, jerk_max: f64, dt: f64) {
        let error = vel_input - self.vel;
        let kpa = jerk_max / accel_max;
        let target = sqrt_controller(error, kpa, jerk_max, dt).clamp(-accel_max, accel_max);
        let step = jerk_max * dt;
        self.accel += (target - self.accel).clamp(-step, step);
    }

    /// control.cpp `shape_pos_vel_accel` (no velocity or acceleration input): the velocity that
    /// closes the position error, within (-down, up), then shaped.
    fn shape_pos(
        &mut self,
        pos_input: f64,
        down: f64,
        up: f64,
        accel_max: f64,
        jerk_max: f64,
        dt: f64,
    ) {
        let error = pos_input - self.pos;
        let (accel_tc, kpv) = (0.5 * accel_max, 0.5 * jerk_max / accel_max);
        let vel = sqrt_controller(error, kpv, accel_tc, dt).clamp(-down, up);
        self.shape_vel(vel, accel_max, jerk_max, dt);
    }
}

/// NAV_TAKEOFF from the ground to `height_m`: the vertical target shaped to the altitude, until
/// ArduCopter counts the take-off complete (`takeoff_complete_s`), then on to rest.
pub fn takeoff(p: &ArdupilotParams, height_m: f64) -> Result<Samples, PhysicsError> {
    let dt = STEP_S;
    let mut axis = Vertical::default();
    let mut points = vec![[0.0; 6]];
    let max_steps = (MAX_DURATION_S / dt) as usize;
    for _ in 0..max_steps {
        let prev = axis;
        axis.advance(dt);
        axis.shape_pos(
            height_m,
            p.wp_spd_dn_m_s,
            p.wp_spd_up_m_s,
            p.wp_acc_z_m_s2,
            p.psc_jerk_d_m_s3,
            dt,
        );
        points.push([
            0.0,
            axis.pos,
            0.0,
            axis.vel,
            0.0,
            (axis.vel - prev.vel) / dt,
        ]);
        if (height_m - axis.pos).abs() <= 1e-3 && axis.vel.abs() <= 1e-3 {
            if let Some(last) = points.last_mut() {
                *last = [0.0, height_m, 0.0, 0.0, 0.0, 0.0];
            }
            return Ok(Samples { step_s: dt, points });
        }
    }
    Err(no_arrival(0.0, height_m, "take-off"))
}

/// How far below the take-off altitude ArduCopter counts the take-off complete (the stopping
/// distance from a tenth of WP_SPD_UP at WP_ACC_Z; the climb rate is below that tenth there).
pub fn takeoff_complete_below_m(p: &ArdupilotParams) -> f64 {
    let v = 0.1 * p.wp_spd_up_m_s;
    0.5 * v * v / p.wp_acc_z_m_s2
}

/// The descent rate (m/s, positive down) NAV_LAND commands `height_m` above the ground
/// (mode.cpp `land_run_vertical_control`).
pub fn land_rate_m_s(p: &ArdupilotParams, height_m: f64) -> f64 {
    let fastest = if p.land_spd_high_m_s > 0.0 {
        p.land_spd_high_m_s
    } else {
        p.wp_spd_dn_m_s
    }
    .max(p.land_spd_m_s);
    let toward_low = sqrt_controller(
        p.land_alt_low_m.max(1.0) - height_m,
        p.psc_d_pos_p,
        p.wp_acc_z_m_s2,
        0.0,
    );
    (-toward_low).clamp(p.land_spd_m_s, fastest)
}

/// NAV_LAND from hover `height_m` above the ground to touchdown.
pub fn landing(p: &ArdupilotParams, height_m: f64) -> Result<Samples, PhysicsError> {
    let dt = STEP_S;
    let mut axis = Vertical::default();
    let mut points = vec![[0.0; 6]];
    let max_steps = (MAX_DURATION_S / dt) as usize;
    for _ in 0..max_steps {
        let prev = axis;
        axis.advance(dt);
        let rate = land_rate_m_s(p, height_m + axis.pos);
        axis.shape_vel(-rate, p.wp_acc_z_m_s2, p.psc_jerk_d_m_s3, dt);
        points.push([
            0.0,
            axis.pos,
            0.0,
            axis.vel,
            0.0,
            (axis.vel - prev.vel) / dt,
        ]);
        if axis.pos <= -height_m {
            if let Some(last) = points.last_mut() {
                *last = [0.0, -height_m, 0.0, 0.0, 0.0, 0.0];
            }
            return Ok(Samples { step_s: dt, points });
        }
    }
    Err(no_arrival(0.0, -height_m, "landing"))
}

fn no_arrival(xf_m: f64, zf_m: f64, what: &str) -> PhysicsError {
    PhysicsError::NoTrajectory {
        xf_m,
        zf_m,
        profile: super::Profile::Ardupilot,
        reason: format!("ardupilot {what} does not arrive within {MAX_DURATION_S} s"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::vehicle::shipped;

    fn params() -> ArdupilotParams {
        shipped().ardupilot
    }

    #[test]
    fn the_jerk_and_snap_are_wp_jerk_and_its_attitude_time_constant() {
        // WP_JERK 1, ATC_INPUT_TC 0.15, rate limits off, ATC_ACC_*_MAX 1100 deg/s^2 (19.2
        // rad/s^2 x g, far above): snap = 1 x pi / 0.3, halved.
        let (jerk, snap) = scurve_jerk_snap(&params());
        assert_eq!(jerk, 1.0);
        assert!((snap - PI / 0.3 / 2.0).abs() < 1e-12, "{snap}");
        // Roll- and pitch-rate limits of 3 deg/s cap the jerk at 3 deg/s x g; one of them
        // alone does not (the smaller, 0, means no limit).
        let mut p = params();
        p.atc_rate_r_max_deg_s = 3.0;
        assert_eq!(scurve_jerk_snap(&p).0, 1.0);
        p.atc_rate_p_max_deg_s = 4.0;
        let (jerk, _) = scurve_jerk_snap(&p);
        assert!((jerk - 3f64.to_radians() * GRAVITY_MSS).abs() < 1e-12);
    }

    #[test]
    fn a_long_leg_reaches_wp_spd_and_wp_acc_in_the_hand_computed_time() {
        // 400 m level, WP_SPD 10, WP_ACC 2.5, jerk 1, snap pi/0.6: tj = jerk pi / (2 snap)
        // = 0.3 s; the acceleration ramps in tj + t2 + tj to Am = jerk (tj + t2) = 2.5, so t2
        // = 2.2 s.
        let p = params();
        let c = leg_scurve(&p, 400.0, 0.0);
        let (tj, am, jm) = (0.3, 2.5, 1.0);
        let t2 = am / jm - tj;
        // Each jerk group (rising, constant, falling: 2 tj + t2, symmetric) changes the
        // acceleration by Am at a mean of Am / 2; the group up and the group down gain
        // Am (2 tj + t2) = 7 m/s, the constant acceleration the rest: t4 = (10 - 7) / 2.5.
        let t4 = (10.0 - am * (2.0 * tj + t2)) / am;
        let accel_time = 2.0 * (2.0 * tj + t2) + t4;
        // Distance of the symmetric speed-up: average speed 5 m/s over it.
        let accel_dist = 5.0 * accel_time;
        let expected = 2.0 * accel_time + (400.0 - 2.0 * accel_dist) / 10.0;
        assert!(
            (c.duration_s() - expected).abs() < 1e-6,
            "{} vs {expected}",
            c.duration_s()
        );
        assert!((c.length_m() - 400.0).abs() < 1e-6);
        // Limits: speed, acceleration, jerk all within, and rest at both ends.
        let (mut v_peak, mut a_peak, mut j_peak) = (0.0f64, 0.0f64, 0.0f64);
        let n = 20_000;
        for k in 0..=n {
            let (j, a, v, _) = c.at(c.duration_s() * k as f64 / n as f64);
            v_peak = v_peak.max(v);
            a_peak = a_peak.max(a.abs());
            j_peak = j_peak.max(j.abs());
        }
        assert!((v_peak - 10.0).abs() < 1e-9, "{v_peak}");
        assert!((a_peak - 2.5).abs() < 1e-9, "{a_peak}");
        assert!(j_peak <= 1.0 + 1e-9, "{j_peak}");
        let end = c.at(c.duration_s());
        assert!(end.2.abs() < 1e-9 && (end.3 - 400.0).abs() < 1e-6);
    }

    #[test]
    fn a_short_leg_never_reaches_its_limits_and_still_ends_at_rest_on_the_waypoint() {
        let p = params();
        for (xf, zf) in [
            (33.0, 0.0),
            (5.0, 0.0),
            (0.5, 0.0),
            (20.0, 10.0),
            (10.0, -20.0),
            (0.0, 24.0),
            (0.0, -3.0),
        ] {
            let s = leg(&p, xf, zf).unwrap();
            let end = s.points.last().unwrap();
            assert_eq!(*end, [xf, zf, 0.0, 0.0, 0.0, 0.0]);
            let last_moving = s.points[s.points.len() - 2];
            assert!(
                (last_moving[0] - xf).abs() < 1e-3 && (last_moving[1] - zf).abs() < 1e-3,
                "{xf} {zf}: {last_moving:?}"
            );
            for q in &s.points {
                assert!(q[2].abs() <= p.wp_spd_m_s + 1e-9);
                assert!(
                    q[3] <= p.wp_spd_up_m_s + 1e-9 && -q[3] <= p.wp_spd_dn_m_s + 1e-9,
                    "{xf} {zf}: {q:?}"
                );
                assert!(q[4].abs() <= p.wp_acc_m_s2 + 1e-9 && q[5].abs() <= p.wp_acc_z_m_s2 + 1e-9);
                // Never past the waypoint, never backwards.
                assert!(q[0] * xf.signum() <= xf.abs() + 1e-9 && q[2] * xf.signum() >= -1e-9);
            }
        }
    }

    #[test]
    fn a_33_m_leg_takes_the_hand_computed_time() {
        // 33 m level with jerk 1, snap pi/0.6 (tj 0.3 s), WP_ACC 2.5, WP_SPD 10: half the
        // path (16.5 m) does not fit the full acceleration; the S-curve's solution 5 lowers
        // the acceleration until the speed-up (no constant acceleration, t2 = Am / jerk - tj,
        // top speed Am (2 tj + t2), symmetric: its distance top speed x its time / 2) is
        // exactly half the leg; bisection on Am finds it.
        let p = params();
        let c = leg_scurve(&p, 33.0, 0.0);
        let (tj, jm) = (0.3f64, 1.0f64);
        let ramp = |am: f64| {
            let t2 = am / jm - tj;
            let v_top = am * (2.0 * tj + t2);
            let time = 2.0 * (2.0 * tj + t2);
            (v_top, time, v_top * time / 2.0)
        };
        let (mut lo, mut hi) = (jm * tj, 2.5);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if ramp(mid).2 > 16.5 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let (v_top, time, dist) = ramp(lo);
        let expected = 2.0 * time + (33.0 - 2.0 * dist) / v_top;
        assert!(
            (c.duration_s() - expected).abs() < 1e-3,
            "{} vs {expected}",
            c.duration_s()
        );
    }

    #[test]
    fn a_climb_keeps_within_wp_spd_up_and_the_takeoff_is_complete_near_its_altitude() {
        let p = params();
        let s = takeoff(&p, 20.0).unwrap();
        let peak = s.points.iter().map(|q| q[3]).fold(0.0, f64::max);
        assert!((peak - p.wp_spd_up_m_s).abs() < 1e-6, "{peak}");
        let top = s.points.iter().map(|q| q[1]).fold(0.0, f64::max);
        // The discrete shaper overshoots by about a centimetre at this step.
        assert!(top <= 20.02, "{top}");
        // 20 m at 2.5 m/s is 8 s plus the ramps.
        let done = s
            .first_accepted(0.0, 20.0, 1.0, takeoff_complete_below_m(&p))
            .unwrap();
        assert!(done > 8.0 && done < 14.0, "{done}");
    }

    #[test]
    fn a_landing_descends_at_wp_spd_dn_above_land_alt_low_and_at_land_spd_below() {
        let p = params();
        assert_eq!(land_rate_m_s(&p, 30.0), p.wp_spd_dn_m_s);
        assert_eq!(land_rate_m_s(&p, 5.0), p.land_spd_m_s);
        assert_eq!(land_rate_m_s(&p, 10.0), p.land_spd_m_s);
        let s = landing(&p, 20.0).unwrap();
        // 8.4 m at 1.5 m/s, ~1 m slowing, 10.6 m at 0.5 m/s: about 28 s.
        assert!(
            s.duration_s() > 26.0 && s.duration_s() < 31.0,
            "{}",
            s.duration_s()
        );
        let at = |h: f64| s.points.iter().find(|q| q[1] <= h - 20.0).unwrap()[3];
        assert!((at(15.0) + 1.5).abs() < 1e-6 && (at(5.0) + 0.5).abs() < 1e-6);
    }
}
