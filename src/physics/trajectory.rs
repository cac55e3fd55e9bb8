//! The motion of one operation in the leg's vertical plane, rest to rest: the path a profile
//! flies (the PTF's quintic along the line, HVB's axes each on its own trapezoid, PX4's
//! sampled trajectory generator), its kinematics in time, when it comes within the paper's 4 m
//! of the end point and when an autopilot accepts that point. Kinematics only: what it costs
//! along the way is `physics::power`.

use super::profile::{trapezoid, Schedule};
use super::px4;
use super::vehicle::{HvbParams, Px4Params};

/// The paper's operation-end rule: energy counts until within this distance of the end point.
pub const ARRIVAL_RADIUS_M: f64 = 4.0;

/// How the vehicle moves in the leg's plane.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Path {
    /// Along the straight line to the end point, unit direction `dir` = (ux, uz).
    Line {
        schedule: Schedule,
        length_m: f64,
        dir: (f64, f64),
    },
    /// Horizontal and vertical axes each on their own schedule (vertical in |Zf|).
    Axes {
        x: Schedule,
        z: Schedule,
        xf_m: f64,
        zf_m: f64,
    },
    /// A motion simulated in time steps (PX4's trajectory generator, `physics::px4`) to the
    /// end point (xf, zf).
    Sampled {
        samples: px4::Samples,
        xf_m: f64,
        zf_m: f64,
    },
}

impl Path {
    pub(super) fn duration_s(&self) -> f64 {
        match self {
            Path::Line { schedule, .. } => schedule.duration_s(),
            Path::Axes { x, z, .. } => x.duration_s().max(z.duration_s()),
            Path::Sampled { samples, .. } => samples.duration_s(),
        }
    }

    /// Velocity and acceleration (vx, vz, ax, az) at `t`.
    pub(super) fn kinematics(&self, t: f64) -> (f64, f64, f64, f64) {
        match self {
            Path::Line { schedule, dir, .. } => {
                let st = schedule.at(t);
                (
                    dir.0 * st.v_m_s,
                    dir.1 * st.v_m_s,
                    dir.0 * st.a_m_s2,
                    dir.1 * st.a_m_s2,
                )
            }
            Path::Axes { x, z, zf_m, .. } => {
                let (sx, sz) = (x.at(t), z.at(t));
                let sign = if *zf_m < 0.0 { -1.0 } else { 1.0 };
                (sx.v_m_s, sign * sz.v_m_s, sx.a_m_s2, sign * sz.a_m_s2)
            }
            Path::Sampled { samples, .. } => {
                let [_, _, vx, vz, ax, az] = samples.at(t);
                (vx, vz, ax, az)
            }
        }
    }

    /// Position (x horizontal along the leg, z up) relative to the start at `t`.
    fn position_m(&self, t: f64) -> (f64, f64) {
        match self {
            Path::Line { schedule, dir, .. } => {
                let s = schedule.at(t).s_m;
                (dir.0 * s, dir.1 * s)
            }
            Path::Axes { x, z, zf_m, .. } => {
                let sign = if *zf_m < 0.0 { -1.0 } else { 1.0 };
                (x.at(t).s_m, sign * z.at(t).s_m)
            }
            Path::Sampled { samples, .. } => {
                let [x, z, ..] = samples.at(t);
                (x, z)
            }
        }
    }

    /// Straight-line distance to the end point at `t`.
    fn remaining_m(&self, t: f64) -> f64 {
        match self {
            Path::Line {
                schedule, length_m, ..
            } => length_m - schedule.at(t).s_m,
            Path::Axes { x, z, xf_m, zf_m } => (xf_m - x.at(t).s_m).hypot(zf_m.abs() - z.at(t).s_m),
            Path::Sampled {
                samples,
                xf_m,
                zf_m,
            } => {
                let [x, z, ..] = samples.at(t);
                (xf_m - x).hypot(zf_m - z)
            }
        }
    }

    /// The first time within `r` of the end point (straight-line distance).
    pub(super) fn arrival_s(&self, r: f64) -> f64 {
        let duration = self.duration_s();
        if let Path::Sampled {
            samples,
            xf_m,
            zf_m,
        } = self
        {
            return samples.first_within(*xf_m, *zf_m, r).unwrap_or(duration);
        }
        // The remaining distance never grows along a schedule: bisection on time.
        if self.remaining_m(0.0) <= r {
            return 0.0;
        }
        let (mut lo, mut hi) = (0.0, duration);
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if self.remaining_m(mid) <= r {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        hi
    }
}

/// The motion a profile flies for one operation, in the leg's vertical plane (x horizontal along
/// the leg, z up, both from the start point), rest to rest, and what ends it at the end point:
/// the profile's settle time in hover after it, or (PX4) the acceptance that starts the
/// waypoint's hold while the vehicle still brakes. The one trajectory construction: operations
/// are simulated along it and the mock autopilot (`sim`) flies it.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    pub(super) path: Path,
    pub(super) settle_s: f64,
    /// Midpoint-rule steps to price it with.
    pub(super) steps: usize,
    pub(super) acceptance: Option<Acceptance>,
    /// Hover before the path starts: the tracking controller's lag behind its reference (PTF,
    /// and ArduCopter's legs).
    pub(super) delay_s: f64,
}

/// Where an autopilot counts an end point reached and starts its hold, not waiting for the
/// vehicle to come to rest (PX4 mission_block.cpp `is_mission_item_reached_or_completed`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Acceptance {
    /// Within this horizontally (NAV_ACC_RAD, the item's acceptance radius)...
    pub horizontal_m: f64,
    /// ...and this vertically (NAV_MC_ALT_RAD).
    pub vertical_m: f64,
}

impl Trajectory {
    /// Time from the operation's start to coming to rest at the end point.
    pub fn duration_s(&self) -> f64 {
        self.delay_s + self.path.duration_s()
    }

    /// Hover at the start before the vehicle moves (the PTF's and ArduCopter's legs' tracking
    /// lag; 0 otherwise).
    pub fn delay_s(&self) -> f64 {
        self.delay_s
    }

    /// Velocity and acceleration (vx, vz, ax, az) at `t_s` (at rest outside the trajectory).
    pub fn kinematics(&self, t_s: f64) -> (f64, f64, f64, f64) {
        if t_s < self.delay_s {
            return (0.0, 0.0, 0.0, 0.0);
        }
        self.path.kinematics(t_s - self.delay_s)
    }

    /// Position (x, z) relative to the start at `t_s` (clamped to the trajectory).
    pub fn position_m(&self, t_s: f64) -> (f64, f64) {
        self.path.position_m((t_s - self.delay_s).max(0.0))
    }

    /// Straight-line distance to the end point at `t_s`.
    pub fn remaining_m(&self, t_s: f64) -> f64 {
        self.path.remaining_m((t_s - self.delay_s).max(0.0))
    }

    /// Hover time after the trajectory that the profile counts as settling at the end point.
    pub fn settle_s(&self) -> f64 {
        self.settle_s
    }

    /// The autopilot's acceptance of the end point, when it does not wait for rest (PX4).
    pub fn acceptance(&self) -> Option<Acceptance> {
        self.acceptance
    }

    /// The first time within the paper's 4 m of the end point (where its operation energy
    /// stops counting).
    pub fn arrival_s(&self) -> f64 {
        self.path.arrival_s(ARRIVAL_RADIUS_M)
    }

    /// The intervals (start, end) in s, before the 4 m arrival and before the autopilot's
    /// acceptance, in which the motion is a steady cruise: sampled every `step_s`, every
    /// acceleration component at most `max_accel_m_s2` and no velocity step above
    /// `max_jump_m_s` between samples, faster than 0.1 m/s (not the first instants of a
    /// start from rest). Cutting such an interval out leaves the motion of the
    /// same leg made shorter by the interval's displacement (`physics::longleg`).
    pub fn steady_windows(
        &self,
        step_s: f64,
        max_accel_m_s2: f64,
        max_jump_m_s: f64,
    ) -> Vec<(f64, f64)> {
        let end = self
            .accepted_s()
            .map_or(self.arrival_s(), |a| a.min(self.arrival_s()));
        let step_s = match &self.path {
            Path::Sampled { samples, .. } => samples.step_s,
            _ => step_s,
        };
        if step_s.is_nan() || step_s <= 0.0 || end.is_nan() || end <= 0.0 {
            return Vec::new();
        }
        let count = (end / step_s).floor() as usize;
        let mut windows = Vec::new();
        let mut open: Option<f64> = None;
        let mut previous: Option<(f64, f64)> = None;
        for k in 0..=count {
            let t = k as f64 * step_s;
            let (vx, vz, ax, az) = self.path.kinematics(t);
            let calm =
                ax.abs() <= max_accel_m_s2 && az.abs() <= max_accel_m_s2 && vx.hypot(vz) > 0.1;
            let jump = previous.map_or(0.0, |(px, pz)| (vx - px).hypot(vz - pz));
            previous = Some((vx, vz));
            if let Some(start) = open {
                if !calm || jump > max_jump_m_s {
                    let last = t - step_s;
                    if last > start {
                        windows.push((start, last));
                    }
                    open = None;
                }
            }
            if open.is_none() && calm {
                open = Some(t);
            }
        }
        if let Some(start) = open {
            let last = count as f64 * step_s;
            if last > start {
                windows.push((start, last));
            }
        }
        windows
    }

    /// The first time the autopilot counts the end point reached by its acceptance (None:
    /// no acceptance rule, or never).
    pub fn accepted_s(&self) -> Option<f64> {
        let a = self.acceptance?;
        match &self.path {
            Path::Sampled {
                samples,
                xf_m,
                zf_m,
            } => samples.first_accepted(*xf_m, *zf_m, a.horizontal_m, a.vertical_m),
            _ => None,
        }
    }
}

/// The largest speed along `path`, sampled `steps` times.
pub(super) fn path_peak_speed(path: &Path, steps: usize) -> f64 {
    let duration = path.duration_s();
    (0..=steps)
        .map(|k| {
            let (vx, vz, _, _) = path.kinematics(duration * k as f64 / steps as f64);
            vx.hypot(vz)
        })
        .fold(0.0, f64::max)
}

impl Trajectory {
    /// No motion at all (a leg of zero length).
    pub(super) fn stationary() -> Trajectory {
        Trajectory {
            path: Path::Line {
                schedule: Schedule::Pieces(Vec::new()),
                length_m: 0.0,
                dir: (1.0, 0.0),
            },
            settle_s: 0.0,
            steps: 8,
            acceptance: None,
            delay_s: 0.0,
        }
    }

    /// What a stock position controller flies (HVB): each axis runs to its target at its own
    /// limits, so a climbing leg finishes horizontally first and climbs on.
    pub(super) fn hvb(h: &HvbParams, xf_m: f64, zf_m: f64) -> Trajectory {
        let vertical = if zf_m >= 0.0 {
            h.speed_up_m_s
        } else {
            h.speed_down_m_s
        };
        let path = Path::Axes {
            x: trapezoid(xf_m, h.speed_xy_m_s, h.acceleration_m_s2),
            z: trapezoid(zf_m.abs(), vertical, h.acceleration_m_s2),
            xf_m,
            zf_m,
        };
        Trajectory {
            path,
            settle_s: h.settle_s,
            steps: h.steps as usize,
            acceptance: None,
            delay_s: 0.0,
        }
    }
}

/// The PTF's straight line of `length_m` along unit direction `dir`, a quintic of `duration_s`
/// (rest to rest, peak speed 15/8 L / T).
pub(super) fn quintic_line(length_m: f64, dir: (f64, f64), duration_s: f64) -> Path {
    Path::Line {
        schedule: Schedule::Quintic {
            length_m,
            duration_s,
        },
        length_m,
        dir,
    }
}

/// A PX4 motion as a trajectory: sampled, no settle hover, PX4's acceptance of the end point.
pub(super) fn px4_trajectory(
    x: &Px4Params,
    samples: px4::Samples,
    xf_m: f64,
    zf_m: f64,
) -> Trajectory {
    let acceptance = Acceptance {
        horizontal_m: x.nav_acc_rad_m,
        vertical_m: x.nav_mc_alt_rad_m,
    };
    sampled_trajectory(samples, xf_m, zf_m, x.steps, Some(acceptance))
}

/// An autopilot's sampled motion as a trajectory: no settle hover (a PX4 leg ends where PX4
/// accepts the point; an ArduCopter leg at rest on the waypoint, where ArduCopter counts it
/// reached), priced in `steps` steps, with the acceptance of its end point if it has one (an
/// ArduCopter take-off: where ArduCopter counts it complete).
pub(super) fn sampled_trajectory(
    samples: px4::Samples,
    xf_m: f64,
    zf_m: f64,
    steps: u32,
    acceptance: Option<Acceptance>,
) -> Trajectory {
    Trajectory {
        path: Path::Sampled {
            samples,
            xf_m,
            zf_m,
        },
        settle_s: 0.0,
        steps: steps as usize,
        acceptance,
        delay_s: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use crate::physics::power::Model;
    use crate::physics::vehicle::shipped;
    use crate::physics::Profile;

    #[test]
    fn steady_windows_are_the_cruises_before_the_four_metre_rule() {
        // hvb limits where (300, 40) cruises on both axes, then on one (the shipped fit's slow
        // acceleration to 13 m/s leaves no cruise on the horizontal axis alone).
        let mut v = shipped();
        v.hvb.speed_xy_m_s = 8.879;
        v.hvb.speed_up_m_s = 2.003;
        v.hvb.acceleration_m_s2 = 1.002;
        let model = Model::new(&v);
        // hvb (300, 40): both axes cruise, then the horizontal axis alone once the climb ends.
        let t = model.trajectory(Profile::Hvb, 300.0, 40.0).unwrap();
        let windows = t.steady_windows(0.01, 0.05, 0.05);
        assert_eq!(windows.len(), 2, "{windows:?}");
        let h = &v.hvb;
        let (vx, vz, _, _) = t.kinematics(0.5 * (windows[0].0 + windows[0].1));
        assert!((vx - h.speed_xy_m_s).abs() < 1e-9 && (vz - h.speed_up_m_s).abs() < 1e-9);
        let (vx, vz, _, _) = t.kinematics(0.5 * (windows[1].0 + windows[1].1));
        assert!((vx - h.speed_xy_m_s).abs() < 1e-9 && vz.abs() < 1e-12);
        assert!(windows[1].1 <= t.arrival_s());
        // px4 (300, 0): one cruise at MPC_XY_CRUISE, ended by the braking before the 4 m rule.
        let t = model.trajectory(Profile::Px4, 300.0, 0.0).unwrap();
        let windows = t.steady_windows(0.01, 0.05, 0.05);
        assert_eq!(windows.len(), 1, "{windows:?}");
        let (vx, _, _, _) = t.kinematics(windows[0].1);
        assert!((vx - v.px4.mpc_xy_cruise_m_s).abs() < 1e-3, "{vx}");
        assert!(t.remaining_m(windows[0].1) > 10.0);
        // ptf's quintic never holds its speed.
        let t = model.trajectory(Profile::Ptf, 140.0, 0.0).unwrap();
        assert!(t
            .steady_windows(0.01, 0.05, 0.05)
            .iter()
            .all(|(a, b)| b - a < 1.0));
    }
}
