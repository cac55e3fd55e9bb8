//! How ArduCopter flies a chain of waypoints in AUTO mode when some of them are fast (flown
//! through without stopping), so the `ardupilot` profile prices each leg of a zero-hold mission
//! as ArduCopter flies it: its target position, velocity and acceleration in 3D over time, and
//! the moment ArduCopter counts each waypoint reached. Ported from ArduPilot (master of 2026-04,
//! the build the ArduCopter SITL of sitl/README.md runs):
//! - `ArduCopter/mode_auto.cpp` `wp_start` / `set_next_wp`: a NAV_WAYPOINT whose hold (`cmd.p1`,
//!   whole seconds: a hold under 1 s is 0) is 0 and which another NAV_WAYPOINT follows gives
//!   AC_WPNav the next destination (`set_wp_destination_next_loc`): the waypoint is fast. A
//!   waypoint with a hold, or one a NAV_LAND follows, is not: the leg ends at rest on it.
//! - `libraries/AC_WPNav/AC_WPNav.cpp` `set_wp_destination_next_NED_m`: the next leg is its own
//!   rest-to-rest S-curve (`calculate_track`, straight: a plain NAV_WAYPOINT passes no arc
//!   angle, so SCurve's arc segments are not used), computed ahead; `set_wp_destination_NED_m`
//!   keeps the finished leg as the previous leg (`_scurve_prev_leg`, still adding the rest of
//!   its motion) and reuses the next leg's S-curve, already running, as the current one.
//!   `advance_wp_target_along_track` counts a fast waypoint reached as soon as the S-curve says
//!   it is finished.
//! - `libraries/AP_Math/SCurve.cpp` `advance_target_along_track`: the target is the sum of the
//!   previous leg's remaining motion (relative to its destination), this leg's and, once it has
//!   started, the next leg's (each rest to rest). The next leg starts when this leg is fast, is
//!   decelerating, will end before the next one finishes accelerating, and at the turn's
//!   midpoint (half this leg's remaining time ahead) the summed target would be within
//!   WP_RADIUS_M of the waypoint, slower than both legs' speed limits, with a horizontal
//!   acceleration below the corner acceleration (WP_ACC_C; its default 0 means twice WP_ACC,
//!   AC_WPNav.h `get_corner_acceleration_mss`, which is what is used here) and a vertical one
//!   below WP_ACC_Z. This leg counts as finished once the next leg has run as long as this
//!   one has left: half-way through the turn.
//!
//! The S-curves' clock runs at real time here: ArduCopter slows it while the vehicle trails
//! its target (`track_dt_scalar`), which `physics::power` prices as a hover of
//! `tracking_lag_s` before a leg that starts at rest (see [`ChainLeg::from_rest`]).
//!
//! Pure: parameters and waypoints in, sampled motion per leg out.

use super::ardupilot::{leg_scurve, SCurve};
use super::profile::line_limit;
use super::px4::Samples;
use super::vehicle::ArdupilotParams;
use super::PhysicsError;

/// ArduCopter's position controller period (400 Hz main loop): the chain is stepped at it,
/// so the moment a turn starts and a waypoint is reached fall on its ticks as ArduCopter's do.
pub const TICK_S: f64 = 0.0025;

/// The longest chain simulated before it is refused.
const MAX_DURATION_S: f64 = 7200.0;

/// One waypoint of a chain: where it is (east, north, up, m) and whether it is fast.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChainPoint {
    pub enu_m: [f64; 3],
    pub fast: bool,
}

/// Whether ArduCopter flies through a waypoint holding `hold_s` that another waypoint follows
/// (`followed`): its hold is stored in whole seconds (AP_Mission `cmd.p1`), and only a hold of
/// 0 lets `set_next_wp` give AC_WPNav the next destination.
pub fn is_fast(hold_s: f64, followed: bool) -> bool {
    followed && hold_s.is_finite() && hold_s.trunc() <= 0.0
}

/// One leg of a chain as ArduCopter flies it, from the moment the waypoint before was
/// reached (or the chain's start) to the moment this one is.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainLeg {
    /// The motion in the leg's vertical plane: x the horizontal distance flown (along the
    /// turning path, not the chord), z the height above the leg's start, vx the horizontal
    /// speed, vz the climb rate, ax the horizontal acceleration's magnitude signed as its part
    /// along the velocity (see [`planar`]), az the vertical acceleration.
    pub samples: Samples,
    /// When the target first came within `arrival_radius_m` of the waypoint (the leg's end if
    /// never).
    pub arrival_s: f64,
    /// Whether the leg started at rest (the chain's start, or after a waypoint that is not
    /// fast or whose turn did not blend): ArduCopter's clock slowing while the vehicle trails
    /// its target then lengthens the leg as a hover before it (`tracking_lag_s`).
    pub from_rest: bool,
    /// Straight-line horizontal and vertical displacement of the leg (waypoint to waypoint).
    pub xf_m: f64,
    pub zf_m: f64,
    /// The target's position (east, north, up, m, the chain's frame) at each sample: where the
    /// built-in mock flies it.
    pub track_enu_m: Vec<[f64; 3]>,
}

/// One straight leg's S-curve and where its clock is (SCurve.cpp's `time`).
#[derive(Debug, Clone)]
struct Track {
    curve: SCurve,
    /// Origin to destination (east, north, up).
    delta: [f64; 3],
    unit: [f64; 3],
    /// SCurve.cpp `vel_max` (`get_speed_along_track`): the speed limit along the line.
    speed_max: f64,
    time_s: f64,
}

/// A target state: position (relative to some point), velocity, acceleration.
type State = ([f64; 3], [f64; 3], [f64; 3]);

impl Track {
    fn new(p: &ArdupilotParams, delta: [f64; 3]) -> Track {
        let xy = delta[0].hypot(delta[1]);
        let length = xy.hypot(delta[2]);
        let unit = if length > 0.0 {
            [delta[0] / length, delta[1] / length, delta[2] / length]
        } else {
            [0.0; 3]
        };
        let speed_max = if length > 0.0 {
            line_limit(
                xy / length,
                delta[2] / length,
                p.wp_spd_m_s,
                p.wp_spd_up_m_s,
                p.wp_spd_dn_m_s,
            )
        } else {
            0.0
        };
        Track {
            curve: leg_scurve(p, xy, delta[2]),
            delta,
            unit,
            speed_max,
            time_s: 0.0,
        }
    }

    fn end_s(&self) -> f64 {
        self.curve.duration_s()
    }

    fn remaining_s(&self) -> f64 {
        self.end_s() - self.time_s
    }

    fn finished(&self) -> bool {
        self.time_s >= self.end_s()
    }

    /// SCurve.cpp `advance_time`.
    fn advance(&mut self, dt: f64) {
        self.time_s = (self.time_s + dt).min(self.end_s());
    }

    /// The state at `t_s` relative to the origin (`move_from_time_pos_vel_accel`).
    fn at(&self, t_s: f64) -> State {
        let (_, a, v, s) = self.curve.at(t_s);
        let u = self.unit;
        (
            [u[0] * s, u[1] * s, u[2] * s],
            [u[0] * v, u[1] * v, u[2] * v],
            [u[0] * a, u[1] * a, u[2] * a],
        )
    }
}

fn add(a: &mut State, b: State) {
    for i in 0..3 {
        a.0[i] += b.0[i];
        a.1[i] += b.1[i];
        a.2[i] += b.2[i];
    }
}

fn norm(v: [f64; 3]) -> f64 {
    v[0].hypot(v[1]).hypot(v[2])
}

/// A 3D target state mapped to the power model's plane: (horizontal speed, climb rate,
/// horizontal acceleration, vertical acceleration). The planar model has one horizontal
/// axis, along the velocity; in a turn the horizontal acceleration also has a part across it
/// (the centripetal part). Its magnitude is what the rotors must tilt for, so the planar
/// acceleration is the whole horizontal acceleration's magnitude, signed as its part along
/// the velocity (speeding up or slowing down; along the leg when at rest). This is exact on
/// straight lines; in a turn it adds the centripetal thrust in line with the drag instead of
/// across it, an overestimate of at most the drag's share, small at the few m/s of a turn.
pub fn planar(vel: [f64; 3], accel: [f64; 3], along: [f64; 2]) -> (f64, f64, f64, f64) {
    let speed = vel[0].hypot(vel[1]);
    let a_xy = accel[0].hypot(accel[1]);
    let tangential = if speed > 1e-6 {
        (accel[0] * vel[0] + accel[1] * vel[1]) / speed
    } else {
        accel[0] * along[0] + accel[1] * along[1]
    };
    let sign = if tangential < 0.0 { -1.0 } else { 1.0 };
    (speed, vel[2], sign * a_xy, accel[2])
}

/// ArduCopter flying from rest at `start` (east, north, up, m) through `points` in turn,
/// stepped at [`TICK_S`]: one [`ChainLeg`] per point, from the moment the point before was
/// reached to the moment it is. The last point is never fast (nothing follows it).
pub fn chain(
    p: &ArdupilotParams,
    start: [f64; 3],
    points: &[ChainPoint],
    arrival_radius_m: f64,
) -> Result<Vec<ChainLeg>, PhysicsError> {
    let dt = TICK_S;
    let corner_accel = 2.0 * p.wp_acc_m_s2;
    let accel_z = p.wp_acc_z_m_s2;
    let mut legs = Vec::with_capacity(points.len());
    let mut origin = start;
    let mut prev: Option<Track> = None;
    let mut this = match points.first() {
        Some(first) => Track::new(p, sub(first.enu_m, start)),
        None => return Ok(legs),
    };
    let mut from_rest = true;
    let mut now_s = 0.0;
    for (k, point) in points.iter().enumerate() {
        let fast = point.fast && k + 1 < points.len();
        let mut next = if fast {
            Some(Track::new(p, sub(points[k + 1].enu_m, point.enu_m)))
        } else {
            None
        };
        let leg_start = [origin[0], origin[1], origin[2]];
        let along = {
            let d = sub(point.enu_m, leg_start);
            let h = d[0].hypot(d[1]);
            if h > 0.0 {
                [d[0] / h, d[1] / h]
            } else {
                [0.0, 0.0]
            }
        };
        // The leg's samples start where the last leg's ended (the same instant).
        let first = legs
            .last()
            .map(|l: &ChainLeg| {
                let q = l.samples.points[l.samples.points.len() - 1];
                [0.0, 0.0, q[2], q[3], q[4], q[5]]
            })
            .unwrap_or([0.0; 6]);
        let mut samples = vec![first];
        let mut last_pos = target_of(origin, prev.as_ref(), &this, next.as_ref()).0;
        let mut track = vec![last_pos];
        let (mut x_m, z0) = (0.0, last_pos[2]);
        let mut arrival_s = None;
        let leg_t0 = now_s;
        loop {
            if now_s - leg_t0 > MAX_DURATION_S {
                return Err(PhysicsError::NoTrajectory {
                    xf_m: 0.0,
                    zf_m: 0.0,
                    profile: super::Profile::Ardupilot,
                    reason: format!(
                        "ardupilot leg {} of a chain does not arrive within {MAX_DURATION_S} s",
                        k + 1
                    ),
                });
            }
            now_s += dt;
            // SCurve.cpp `advance_target_along_track`.
            if let Some(prev) = prev.as_mut() {
                prev.advance(dt);
            }
            this.advance(dt);
            let mut finished = this.finished();
            if let Some(next) = next.as_mut() {
                let remaining = this.remaining_s();
                if next.time_s == 0.0
                    && this.time_s >= this.curve.time_decel_start_s()
                    && remaining <= next.curve.time_accel_end_s()
                {
                    let mut turn = this.at(this.time_s + 0.5 * remaining);
                    for i in 0..3 {
                        turn.0[i] -= this.delta[i];
                    }
                    add(&mut turn, next.at(0.5 * remaining));
                    let speed_min = this.speed_max.min(next.speed_max);
                    if norm(turn.0) < p.wp_radius_m
                        && norm(turn.1) < speed_min
                        && turn.2[0].hypot(turn.2[1]) < corner_accel
                        && turn.2[2].abs() < accel_z
                    {
                        next.advance(dt);
                    }
                } else if next.time_s > 0.0 {
                    next.advance(dt);
                    if next.time_s >= this.remaining_s() {
                        // Half-way through the turn.
                        finished = true;
                    }
                }
            }
            let (pos, vel, accel) = target_of(origin, prev.as_ref(), &this, next.as_ref());
            x_m += (pos[0] - last_pos[0]).hypot(pos[1] - last_pos[1]);
            last_pos = pos;
            let (vx, vz, ax, az) = planar(vel, accel, along);
            samples.push([x_m, pos[2] - z0, vx, vz, ax, az]);
            track.push(pos);
            if arrival_s.is_none() && norm(sub(pos, point.enu_m)) <= arrival_radius_m {
                arrival_s = Some(now_s - leg_t0);
            }
            if finished {
                break;
            }
        }
        let duration_s = now_s - leg_t0;
        let d = sub(point.enu_m, leg_start);
        legs.push(ChainLeg {
            samples: Samples {
                step_s: dt,
                points: samples,
            },
            arrival_s: arrival_s.unwrap_or(duration_s),
            from_rest,
            xf_m: d[0].hypot(d[1]),
            zf_m: d[2],
            track_enu_m: track,
        });
        // AC_WPNav.cpp `set_wp_destination_NED_m`: the finished leg is kept as the previous
        // leg; the next leg's S-curve, running or not, becomes this one. Without a next leg the
        // vehicle has stopped on the waypoint: the following leg starts at rest.
        origin = point.enu_m;
        match next {
            Some(next) => {
                from_rest = next.time_s == 0.0;
                prev = Some(std::mem::replace(&mut this, next));
            }
            None => {
                from_rest = true;
                prev = None;
                if let Some(following) = points.get(k + 1) {
                    this = Track::new(p, sub(following.enu_m, point.enu_m));
                }
            }
        }
    }
    Ok(legs)
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The summed target: `origin` (this leg's), the previous leg's remaining motion relative to
/// its destination (SCurve.cpp `move_to_pos_vel_accel`), this leg's from its origin, and the
/// next leg's from its own origin once it has started (`move_from_pos_vel_accel`: added to this
/// leg's, which then approaches this leg's destination).
fn target_of(origin: [f64; 3], prev: Option<&Track>, this: &Track, next: Option<&Track>) -> State {
    let mut s: State = (origin, [0.0; 3], [0.0; 3]);
    if let Some(prev) = prev {
        let mut q = prev.at(prev.time_s);
        for i in 0..3 {
            q.0[i] -= prev.delta[i];
        }
        add(&mut s, q);
    }
    add(&mut s, this.at(this.time_s));
    if let Some(next) = next.filter(|n| n.time_s > 0.0) {
        add(&mut s, next.at(next.time_s));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::ardupilot;
    use crate::physics::vehicle::shipped;

    fn params() -> ArdupilotParams {
        shipped().ardupilot
    }

    fn points(enu: &[[f64; 3]], fast: bool) -> Vec<ChainPoint> {
        enu.iter()
            .map(|&enu_m| ChainPoint { enu_m, fast })
            .collect()
    }

    #[test]
    fn a_hold_of_under_a_second_is_zero_and_the_last_waypoint_is_never_fast() {
        assert!(is_fast(0.0, true) && is_fast(0.9, true));
        assert!(!is_fast(1.0, true) && !is_fast(5.0, true));
        assert!(!is_fast(0.0, false));
    }

    #[test]
    fn waypoints_that_are_not_fast_are_flown_rest_to_rest_as_the_single_leg_s_curve() {
        let p = params();
        let wps = [[30.0, 0.0, 0.0], [30.0, 20.0, 10.0], [0.0, 0.0, 0.0]];
        let legs = chain(&p, [0.0; 3], &points(&wps, false), 4.0).unwrap();
        let mut from = [0.0; 3];
        for (leg, to) in legs.iter().zip(wps) {
            let d = sub(to, from);
            let single = ardupilot::leg_scurve(&p, d[0].hypot(d[1]), d[2]);
            // Each ends on the tick after its S-curve ends.
            assert!(
                (leg.samples.duration_s() - single.duration_s()).abs() <= TICK_S,
                "{} vs {}",
                leg.samples.duration_s(),
                single.duration_s()
            );
            assert!(leg.from_rest);
            let end = leg.samples.points.last().unwrap();
            assert!((end[0] - d[0].hypot(d[1])).abs() < 1e-6 && (end[1] - d[2]).abs() < 1e-6);
            assert!(end[2].abs() < 1e-9 && end[3].abs() < 1e-9);
            from = to;
        }
    }

    #[test]
    fn a_fast_waypoint_blends_its_corner_and_counts_reached_half_way_through_the_turn() {
        // A right-angle turn 40 m east then 40 m north, both legs level.
        let p = params();
        let wps = [[40.0, 0.0, 0.0], [40.0, 40.0, 0.0]];
        let rest = chain(&p, [0.0; 3], &points(&wps, false), 4.0).unwrap();
        let fast = chain(&p, [0.0; 3], &points(&wps, true), 4.0).unwrap();
        // The corner is not stopped at: the first leg ends moving, the second starts moving.
        let end = fast[0].samples.points.last().unwrap();
        assert!(end[2] > 0.5, "{end:?}");
        assert!(!fast[1].from_rest && fast[0].from_rest);
        // Both legs are shorter than rest to rest, the mission too.
        assert!(fast[0].samples.duration_s() < rest[0].samples.duration_s() - 0.5);
        let total = |legs: &[ChainLeg]| legs.iter().map(|l| l.samples.duration_s()).sum::<f64>();
        assert!(total(&fast) < total(&rest) - 1.0);
        // Half-way through the turn the target is within WP_RADIUS_M of the corner, and it
        // passes no farther from it than that (the blending condition).
        let pos = |leg: &ChainLeg, t: f64| leg.samples.at(t);
        let corner_gap = {
            // The first leg's end: its horizontal path flown against the chord to the corner.
            let q = pos(&fast[0], fast[0].samples.duration_s());
            40.0 - q[0]
        };
        assert!(corner_gap.abs() < p.wp_radius_m, "{corner_gap}");
        // The second leg still ends at rest on the last waypoint.
        let last = fast[1].samples.points.last().unwrap();
        assert!(last[2].abs() < 1e-9 && last[3].abs() < 1e-9);
    }

    #[test]
    fn the_turn_starts_once_its_midpoint_comes_within_the_waypoint_radius() {
        // Straight back from 150 m: the two legs' speeds cancel at the turn's midpoint, which
        // comes nearer the waypoint as this leg's remaining time shrinks; the turn starts when
        // it is within WP_RADIUS_M, so a smaller radius turns later and the legs take longer.
        let wps = [[150.0, 0.0, 0.0], [0.0, 0.0, 0.0]];
        let durations = |radius_m: f64| {
            let mut p = params();
            p.wp_radius_m = radius_m;
            let legs = chain(&p, [0.0; 3], &points(&wps, true), 4.0).unwrap();
            assert!(!legs[1].from_rest);
            (legs[0].samples.duration_s(), legs[1].samples.duration_s())
        };
        let rest = leg_scurve(&params(), 150.0, 0.0).duration_s();
        let (tight, default, wide) = (durations(0.5), durations(2.0), durations(50.0));
        assert!(
            tight.0 > default.0 && default.0 > wide.0,
            "{tight:?} {default:?} {wide:?}"
        );
        assert!(tight.0 < rest, "{tight:?} {rest}");
        // The second leg ends at rest on the origin whatever the radius.
        for (_, second) in [tight, default, wide] {
            assert!(second > 0.0);
        }
    }

    #[test]
    fn in_a_turn_the_planar_acceleration_carries_the_centripetal_part() {
        // Moving east at 3 m/s, accelerating 2 m/s^2 north (all centripetal): the planar
        // horizontal acceleration is 2, speeding up (no part along the velocity).
        let (vx, vz, ax, az) = planar([3.0, 0.0, 0.5], [0.0, 2.0, 0.1], [1.0, 0.0]);
        assert_eq!((vx, vz, ax, az), (3.0, 0.5, 2.0, 0.1));
        // Braking 1 m/s^2 along the velocity with 1 m/s^2 across: magnitude sqrt 2, slowing.
        let (_, _, ax, _) = planar([0.0, 4.0, 0.0], [1.0, -1.0, 0.0], [1.0, 0.0]);
        assert!((ax + 2f64.sqrt()).abs() < 1e-12);
    }
}
