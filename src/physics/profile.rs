//! Flight profiles: how a hover-to-hover operation between two waypoints is flown. Every profile
//! flies the straight line from start to end (Xf horizontal, Zf vertical) with a rest-to-rest
//! speed schedule s(t) along it:
//! - `ptf`: the paper's energy-optimal polynomial trajectory, s = L p(t/T) with the quintic
//!   p = 10 tau^3 - 15 tau^4 + 6 tau^5 (zero speed and acceleration at both ends;
//!   docs/energy-model.md) and the duration T chosen to minimise energy under speed and tilt limits;
//! - `hvb`: the high-velocity baseline, a trapezoidal speed profile at the speed and
//!   acceleration limits, then a settle in hover;
//! - `px4`: PX4 mission mode, PX4's own trajectory generator run in time steps (`physics::px4`:
//!   jerk-limited velocity smoothing, the braking law near the waypoint, the trajectory slowed
//!   while the vehicle trails it), ending where PX4 accepts the point and starts its hold. Its
//!   price depends on the leg before: PX4 leaves a hold past its waypoint, so a leg turning
//!   less than 90 degrees starts ahead of its trajectory and is slowed less
//!   (`physics::px4::Start`, one table block per case). The other profiles do not depend on it;
//! - `ardupilot`: ArduCopter AUTO mode (`physics::ardupilot`: ArduPilot's S-curve along the
//!   line, its jerk phases raised cosines, its limits WP_SPD, WP_SPD_UP/DN, WP_ACC, WP_ACC_Z and
//!   WP_JERK), ending at rest on the waypoint where ArduCopter counts it reached.
//!
//! [`s_curve`] (the seven constant-jerk phases of a rest-to-rest move) is kept as the textbook
//! jerk-limited schedule.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// A flight profile.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    Ptf,
    Hvb,
    Px4,
    Ardupilot,
}

impl Profile {
    /// Every profile.
    pub const ALL: [Profile; 4] = [Profile::Ptf, Profile::Hvb, Profile::Px4, Profile::Ardupilot];
}

impl fmt::Display for Profile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Profile::Ptf => "ptf",
            Profile::Hvb => "hvb",
            Profile::Px4 => "px4",
            Profile::Ardupilot => "ardupilot",
        })
    }
}

impl FromStr for Profile {
    type Err = crate::names::UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        crate::names::choose(
            "profile",
            s,
            &[
                ("ptf", Profile::Ptf),
                ("hvb", Profile::Hvb),
                ("px4", Profile::Px4),
                ("ardupilot", Profile::Ardupilot),
            ],
        )
    }
}

/// Position, speed and acceleration along the line at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathState {
    pub s_m: f64,
    pub v_m_s: f64,
    pub a_m_s2: f64,
}

/// A rest-to-rest schedule along a line of length `length_m`.
#[derive(Debug, Clone, PartialEq)]
pub enum Schedule {
    /// s = L p(t / T), p the quintic.
    Quintic { length_m: f64, duration_s: f64 },
    /// Pieces of constant jerk; each starts from the explicit acceleration `a0` (so a
    /// trapezoid's acceleration steps are pieces with zero jerk).
    Pieces(Vec<Piece>),
}

/// One piece of a piecewise-polynomial schedule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Piece {
    pub duration_s: f64,
    pub jerk_m_s3: f64,
    pub a0_m_s2: f64,
}

impl Schedule {
    /// Total duration.
    pub fn duration_s(&self) -> f64 {
        match self {
            Schedule::Quintic { duration_s, .. } => *duration_s,
            Schedule::Pieces(pieces) => pieces.iter().map(|p| p.duration_s).sum(),
        }
    }

    /// State at time `t_s` (clamped to the schedule).
    pub fn at(&self, t_s: f64) -> PathState {
        match self {
            Schedule::Quintic {
                length_m,
                duration_s,
            } => {
                if *duration_s <= 0.0 {
                    return PathState {
                        s_m: *length_m,
                        v_m_s: 0.0,
                        a_m_s2: 0.0,
                    };
                }
                let tau = (t_s / duration_s).clamp(0.0, 1.0);
                let (t2, t3) = (tau * tau, tau * tau * tau);
                let p = t3 * (10.0 - 15.0 * tau + 6.0 * t2);
                let dp = 30.0 * t2 * (1.0 - tau) * (1.0 - tau);
                let ddp = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau);
                PathState {
                    s_m: length_m * p,
                    v_m_s: length_m * dp / duration_s,
                    a_m_s2: length_m * ddp / (duration_s * duration_s),
                }
            }
            Schedule::Pieces(pieces) => {
                let (mut s, mut v) = (0.0, 0.0);
                let mut t = t_s.max(0.0);
                // After the last piece the vehicle is at rest at the end of the line.
                let after_end = t_s >= self.duration_s();
                for (k, p) in pieces.iter().enumerate() {
                    let last = k + 1 == pieces.len();
                    if t <= p.duration_s || last {
                        let t = t.min(p.duration_s);
                        if after_end {
                            return PathState {
                                s_m: s
                                    + v * t
                                    + p.a0_m_s2 * t * t / 2.0
                                    + p.jerk_m_s3 * t * t * t / 6.0,
                                v_m_s: 0.0,
                                a_m_s2: 0.0,
                            };
                        }
                        return PathState {
                            s_m: s
                                + v * t
                                + p.a0_m_s2 * t * t / 2.0
                                + p.jerk_m_s3 * t * t * t / 6.0,
                            v_m_s: v + p.a0_m_s2 * t + p.jerk_m_s3 * t * t / 2.0,
                            a_m_s2: p.a0_m_s2 + p.jerk_m_s3 * t,
                        };
                    }
                    let d = p.duration_s;
                    s += v * d + p.a0_m_s2 * d * d / 2.0 + p.jerk_m_s3 * d * d * d / 6.0;
                    v += p.a0_m_s2 * d + p.jerk_m_s3 * d * d / 2.0;
                    t -= d;
                }
                PathState {
                    s_m: s,
                    v_m_s: v,
                    a_m_s2: 0.0,
                }
            }
        }
    }
}

/// The largest speed along a line with direction (ux, uz) (unit vector, uz up) whose horizontal
/// and vertical components respect their limits.
pub fn line_limit(ux: f64, uz: f64, horizontal: f64, up: f64, down: f64) -> f64 {
    let mut limit = f64::INFINITY;
    if ux.abs() > 1e-12 {
        limit = limit.min(horizontal / ux.abs());
    }
    if uz > 1e-12 {
        limit = limit.min(up / uz);
    } else if uz < -1e-12 {
        limit = limit.min(down / -uz);
    }
    limit
}

/// Trapezoidal rest-to-rest schedule over `length_m` at speed limit `v_max`, acceleration `a_max`
/// (a triangle when the line is too short to reach `v_max`).
pub fn trapezoid(length_m: f64, v_max: f64, a_max: f64) -> Schedule {
    let v_peak = v_max.min((length_m * a_max).sqrt());
    let t_acc = v_peak / a_max;
    let cruise = (length_m - v_peak * t_acc).max(0.0) / v_peak.max(1e-12);
    Schedule::Pieces(vec![
        Piece {
            duration_s: t_acc,
            jerk_m_s3: 0.0,
            a0_m_s2: a_max,
        },
        Piece {
            duration_s: cruise,
            jerk_m_s3: 0.0,
            a0_m_s2: 0.0,
        },
        Piece {
            duration_s: t_acc,
            jerk_m_s3: 0.0,
            a0_m_s2: -a_max,
        },
    ])
}

/// Distance covered by a symmetric jerk-limited speed-up from rest to `v` and back to rest:
/// returns (distance, jerk time, constant-acceleration time).
fn s_curve_ramp(v: f64, a_max: f64, j_max: f64) -> (f64, f64, f64) {
    let (t_j, t_a) = if v * j_max >= a_max * a_max {
        (a_max / j_max, v / a_max - a_max / j_max)
    } else {
        ((v / j_max).sqrt(), 0.0)
    };
    // Speed-up distance is v (t_a + 2 t_j) / 2; a speed-up plus a slow-down is twice that.
    (v * (t_a + 2.0 * t_j), t_j, t_a)
}

/// Jerk-limited (S-curve) rest-to-rest schedule over `length_m`: seven constant-jerk phases,
/// the peak speed lowered (bisection) when the line is too short to reach `v_max`.
pub fn s_curve(length_m: f64, v_max: f64, a_max: f64, j_max: f64) -> Schedule {
    let mut v = v_max;
    if s_curve_ramp(v, a_max, j_max).0 > length_m {
        let (mut lo, mut hi) = (0.0, v_max);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if s_curve_ramp(mid, a_max, j_max).0 > length_m {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        v = lo;
    }
    let (ramp, t_j, t_a) = s_curve_ramp(v, a_max, j_max);
    let a_peak = j_max * t_j;
    let cruise = if v > 0.0 {
        (length_m - ramp).max(0.0) / v
    } else {
        0.0
    };
    let piece = |duration_s, jerk_m_s3, a0_m_s2| Piece {
        duration_s,
        jerk_m_s3,
        a0_m_s2,
    };
    Schedule::Pieces(vec![
        piece(t_j, j_max, 0.0),
        piece(t_a, 0.0, a_peak),
        piece(t_j, -j_max, a_peak),
        piece(cruise, 0.0, 0.0),
        piece(t_j, -j_max, 0.0),
        piece(t_a, 0.0, -a_peak),
        piece(t_j, j_max, -a_peak),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_schedule_ends_at_rest_at_the_end_of_the_line() {
        for (schedule, length) in [
            (
                Schedule::Quintic {
                    length_m: 47.0,
                    duration_s: 8.0,
                },
                47.0,
            ),
            (trapezoid(47.0, 11.0, 4.0), 47.0),
            (trapezoid(3.0, 11.0, 4.0), 3.0),
            (s_curve(47.0, 5.0, 3.0, 4.0), 47.0),
            (s_curve(2.0, 5.0, 3.0, 4.0), 2.0),
            (s_curve(60.0, 12.0, 3.0, 4.0), 60.0),
        ] {
            let end = schedule.at(schedule.duration_s());
            assert!(
                (end.s_m - length).abs() < 1e-6,
                "{schedule:?} ends at {end:?}"
            );
            assert!(end.v_m_s.abs() < 1e-9, "{end:?}");
        }
    }

    #[test]
    fn after_the_end_a_schedule_stays_at_rest() {
        for schedule in [trapezoid(10.0, 3.0, 1.0), s_curve(10.0, 3.0, 1.0, 2.0)] {
            let later = schedule.at(schedule.duration_s() + 5.0);
            assert!((later.s_m - 10.0).abs() < 1e-9, "{later:?}");
            assert_eq!((later.v_m_s, later.a_m_s2), (0.0, 0.0));
        }
    }

    #[test]
    fn the_s_curve_respects_its_speed_acceleration_and_jerk_limits() {
        let schedule = s_curve(80.0, 5.0, 3.0, 4.0);
        let (mut v_peak, mut a_peak) = (0.0f64, 0.0f64);
        let n = 4000;
        let mut prev_a = 0.0;
        let dt = schedule.duration_s() / n as f64;
        for k in 0..=n {
            let st = schedule.at(k as f64 * dt);
            v_peak = v_peak.max(st.v_m_s);
            a_peak = a_peak.max(st.a_m_s2.abs());
            assert!(((st.a_m_s2 - prev_a) / dt).abs() <= 4.0 + 1e-6 || k == 0);
            prev_a = st.a_m_s2;
        }
        assert!((v_peak - 5.0).abs() < 1e-9, "{v_peak}");
        assert!(a_peak <= 3.0 + 1e-9, "{a_peak}");
        // 80 m at 5 m/s plus the ramps: accelerating to 5 m/s takes 5/3 + 3/4 s.
        assert!((schedule.duration_s() - (16.0 + 5.0 / 3.0 + 0.75)).abs() < 1e-9);
    }

    #[test]
    fn line_limits_respect_each_axis() {
        // A 45-degree climb with 5 m/s horizontal and 3 m/s up: the vertical limit binds.
        let u = std::f64::consts::FRAC_1_SQRT_2;
        assert!((line_limit(u, u, 5.0, 3.0, 1.5) - 3.0 / u).abs() < 1e-12);
        assert!((line_limit(u, -u, 5.0, 3.0, 1.5) - 1.5 / u).abs() < 1e-12);
        assert_eq!(line_limit(1.0, 0.0, 5.0, 3.0, 1.5), 5.0);
        assert!("PX4".parse::<Profile>().is_ok() && "fast".parse::<Profile>().is_err());
    }
}
