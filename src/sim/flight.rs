//! The mock autopilot's simulated flight, sans-IO: the vehicle's motion along a stored mission,
//! item by item, and the electrical power it draws at each instant.
//!
//! The mission items (MISSION_ITEM_INT, as the mission server stores them) are read once into
//! [`Command`]s in a local east-north-up frame centred on home (`crate::mission` geodesy, exact).
//! With the ardupilot profile, waypoints ArduCopter flies through (no hold, another waypoint
//! next: `ardupilot_chain::is_fast`) are flown as its chain (`physics::ardupilot_chain`): the
//! target's 3D track, each such waypoint reached when its leg's S-curve finishes, half-way
//! through the turn, the power from the same planar kinematics the chain is priced with.
//! Every other motion between two points is a hover-to-hover operation flown with the profile's
//! [`Trajectory`] from `physics` (the same trajectory the energy tables were built from) along
//! the straight 3D line, followed by the profile's settle time in hover; electrical power at each
//! instant is `physics::power::Model::power_w` of the trajectory's kinematics in the leg's
//! plane (the leg's horizontal direction does not matter to the planar model). So a leg flown
//! here costs exactly the energy the planner predicted for it.
//!
//! Items: NAV_TAKEOFF climbs vertically from where the vehicle stands to the item's height (the
//! profile's take-off: PX4's NAV_TAKEOFF with its slow climb near the ground for the px4
//! profile); NAV_WAYPOINT flies to the point, is reached within its acceptance radius (param2,
//! PX4's NAV_ACC_RAD 2 m when 0; with the px4 profile as PX4 does: within it horizontally and
//! NAV_MC_ALT_RAD vertically) and completes once the hold time (param1) since reaching it has
//! passed: with the px4 profile at once, while the vehicle may still brake (PX4
//! mission_block.cpp `is_mission_item_reached_or_completed`), with the others also once it has
//! come to rest and settled (ArduCopter mode_auto.cpp `verify_nav_wp`: the hold counts from
//! reaching the radius); a take-off flown with the px4 profile completes NAV_MC_ALT_RAD below
//! its height, still climbing; NAV_LOITER_TIME / NAV_LOITER_UNLIM as waypoints with param1 /
//! forever; NAV_DELAY hovers param1 s; DO_CHANGE_SPEED sets the cruise speed of later legs;
//! DO_JUMP jumps param2 times; DO_DIGICAM_CONTROL with shoot (param5, MISSION_ITEM_INT `x`) 1
//! takes a photo, IMAGE_START_CAPTURE with no interval (param2 0) and param3 images (1 or more)
//! takes that many, at the moment the item runs (after the waypoint before it completes: ArduPilot
//! `AP_Mission::advance_current_nav_cmd` starts the DO commands that follow a navigation command
//! once it completes, PX4's navigator likewise) and without holding the flight (neither autopilot
//! waits for the camera); DO_SET_CAM_TRIGG_DIST sets the camera's distance trigger (param1 m, 0
//! off), taking one photo at once when param3 is 1 (ArduPilot `AP_Mission::start_command_camera`
//! takes a picture after setting the distance), then one each time the vehicle is the trigger
//! distance (horizontally) from where the last was taken, the first counted from where the
//! trigger was set (ArduPilot `AP_Camera` `update`: `last_location.get_distance(current_loc)
//! < trigg_dist` waits; PX4's camera_trigger distance mode likewise); NAV_LAND flies above the point at the current height (when not
//! there), settles, descends and touches down; NAV_RETURN_TO_LAUNCH (simplified: no climb to a
//! return altitude) flies above home, settles, descends and touches down. The descent is the
//! profile's landing (PX4's NAV_LAND, slowing near the ground, for the px4 profile), as the
//! planner prices it.
//!
//! Time is simulated seconds passed in by the caller ([`Flight::advance`]); nothing here reads a
//! clock.

use crate::link::mav::{MavCmd, MavFrame, MISSION_ITEM_INT_DATA};
use crate::mission::{Geodetic, Origin};
use crate::physics::power::Model;
use std::collections::VecDeque;
use std::sync::Arc;

use crate::physics::ardupilot_chain::{self, ChainPoint};
use crate::physics::trajectory::{Acceptance, Trajectory};
use crate::physics::{heading_deg, start_case, PhysicsError, Profile, Start, Vehicle, Wind};

/// A point in the home-centred local frame: metres east, north and up from home.
pub type Local = [f64; 3];

/// Acceptance radius used when an item gives none (PX4 NAV_ACC_RAD default, ArduCopter
/// WPNAV_RADIUS default: 2 m).
pub const DEFAULT_ACCEPTANCE_RADIUS_M: f64 = 2.0;

pub use crate::physics::power::IDLE_SPIN_POWER_W;

/// The last horizontal metres of a px4 leg over which the vehicle runs past its waypoint.
const OVERSHOOT_OVER_M: f64 = 1.0;

/// Below this horizontal distance the vehicle counts as above a point (no horizontal leg).
const ABOVE_POINT_M: f64 = 0.05;

/// What one mission item asks of the vehicle, read once from MISSION_ITEM_INT.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// Climb vertically to `up_m` above home.
    Takeoff { up_m: f64 },
    /// Fly to `at`, hold `hold_s` after coming within `radius_m`.
    Waypoint {
        at: Local,
        hold_s: f64,
        radius_m: f64,
    },
    /// Fly to `at` and hover there `hold_s` (None: until told otherwise).
    Loiter { at: Local, hold_s: Option<f64> },
    /// Land at `at` (east, north), or where the vehicle is.
    Land { at: Option<[f64; 2]> },
    /// Fly above home and land there.
    ReturnToLaunch,
    /// Cruise speed of the following legs.
    ChangeSpeed { speed_m_s: f64 },
    /// Hover this long.
    Delay { duration_s: f64 },
    /// Continue at item `to`, `repeat` times (negative: forever).
    Jump { to: u16, repeat: i32 },
    /// Take `count` photos now, where the vehicle is, and go on at once.
    Photo { count: u32 },
    /// The camera's distance trigger: a photo every `every_m` (0: off), one at once with `now`.
    TriggerDistance { every_m: f64, now: bool },
    /// Not flown (ArduPilot's home at seq 0, or a command the flight ignores).
    Skip,
}

impl Command {
    /// Whether completing it is a navigation event the autopilot reports (MISSION_ITEM_REACHED).
    pub fn is_navigation(&self) -> bool {
        !matches!(
            self,
            Command::ChangeSpeed { .. }
                | Command::Jump { .. }
                | Command::Photo { .. }
                | Command::TriggerDistance { .. }
                | Command::Skip
        )
    }

    /// Whether the vehicle ends on the ground after it.
    pub fn lands(&self) -> bool {
        matches!(self, Command::Land { .. } | Command::ReturnToLaunch)
    }
}

/// The landed state the vehicle reports (MAVLink MAV_LANDED_STATE).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Landed {
    OnGround,
    Takeoff,
    InAir,
    Landing,
}

/// What happened during an [`Flight::advance`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// The item being flown is now `seq`.
    Current(u16),
    /// Item `seq` is complete.
    Reached(u16),
    /// The vehicle left the ground.
    Liftoff,
    /// The vehicle touched down (ground contact).
    Touchdown,
    /// The land detector confirmed the landing (the landing item completes then).
    Landed,
    /// The last item is done.
    Complete,
    /// A photo was taken, now, where the vehicle is.
    Photo,
}

/// Errors setting up a flight.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FlightError {
    #[error("mission item {seq}: {problem}")]
    Item { seq: u16, problem: String },
    #[error("vehicle model: {0}")]
    Physics(#[from] PhysicsError),
}

/// Reads stored mission items into commands. `home` is the frame's origin (altitudes of
/// GLOBAL frames are AMSL, of relative frames above home); with `home_at_zero` (ArduPilot)
/// item 0 is home and not flown.
pub fn commands(
    items: &[MISSION_ITEM_INT_DATA],
    home: Geodetic,
    home_at_zero: bool,
) -> Result<Vec<Command>, FlightError> {
    let frame = Origin {
        home,
        height_above_home_m: 0.0,
    };
    items
        .iter()
        .enumerate()
        .map(|(k, item)| {
            if home_at_zero && k == 0 {
                return Ok(Command::Skip);
            }
            command(item, &frame)
        })
        .collect()
}

#[allow(deprecated)]
fn command(item: &MISSION_ITEM_INT_DATA, frame: &Origin) -> Result<Command, FlightError> {
    let fail = |problem: &str| FlightError::Item {
        seq: item.seq,
        problem: problem.to_string(),
    };
    let finite = |value: f32, default: f64| {
        if value.is_finite() {
            f64::from(value)
        } else {
            default
        }
    };
    let position = || -> Result<Local, FlightError> {
        let up_m = match item.frame {
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT
            | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => f64::from(item.z),
            MavFrame::MAV_FRAME_GLOBAL | MavFrame::MAV_FRAME_GLOBAL_INT => {
                f64::from(item.z) - frame.home.alt_m
            }
            _ => return Err(fail("position in a frame the simulated flight cannot fly")),
        };
        if !up_m.is_finite() {
            return Err(fail("altitude is not a finite number"));
        }
        let enu = frame.to_enu(Geodetic {
            lat_deg: f64::from(item.x) * 1e-7,
            lon_deg: f64::from(item.y) * 1e-7,
            alt_m: frame.home.alt_m + up_m,
        });
        Ok([enu.x_east_m, enu.y_north_m, enu.z_up_m])
    };
    let here = item.x == 0 && item.y == 0;
    Ok(match item.command {
        MavCmd::MAV_CMD_NAV_TAKEOFF => {
            let up_m = f64::from(item.z);
            if !up_m.is_finite() || up_m <= 0.0 {
                return Err(fail("take-off height must be above home"));
            }
            Command::Takeoff { up_m }
        }
        // A spline waypoint flown as a straight one (emplan prices it so: mission::actions).
        MavCmd::MAV_CMD_NAV_WAYPOINT | MavCmd::MAV_CMD_NAV_SPLINE_WAYPOINT => Command::Waypoint {
            at: position()?,
            hold_s: finite(item.param1, 0.0).max(0.0),
            radius_m: match finite(item.param2, 0.0) {
                r if r > 0.0 => r,
                _ => DEFAULT_ACCEPTANCE_RADIUS_M,
            },
        },
        MavCmd::MAV_CMD_NAV_LOITER_TIME => Command::Loiter {
            at: position()?,
            hold_s: Some(finite(item.param1, 0.0).max(0.0)),
        },
        MavCmd::MAV_CMD_NAV_LOITER_UNLIM => Command::Loiter {
            at: position()?,
            hold_s: None,
        },
        MavCmd::MAV_CMD_NAV_LAND => Command::Land {
            at: if here {
                None
            } else {
                let p = position()?;
                Some([p[0], p[1]])
            },
        },
        MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH => Command::ReturnToLaunch,
        MavCmd::MAV_CMD_DO_CHANGE_SPEED => {
            let speed_m_s = finite(item.param2, -1.0);
            if speed_m_s > 0.0 {
                Command::ChangeSpeed { speed_m_s }
            } else {
                Command::Skip // -1: no change (MAVLink spec)
            }
        }
        MavCmd::MAV_CMD_NAV_DELAY => Command::Delay {
            duration_s: finite(item.param1, 0.0).max(0.0),
        },
        MavCmd::MAV_CMD_DO_JUMP => {
            let to = finite(item.param1, -1.0);
            if !(0.0..65535.0).contains(&to) {
                return Err(fail("DO_JUMP target is not an item number"));
            }
            Command::Jump {
                to: to as u16,
                repeat: finite(item.param2, 0.0) as i32,
            }
        }
        MavCmd::MAV_CMD_DO_DIGICAM_CONTROL if item.x == 1 => Command::Photo { count: 1 },
        MavCmd::MAV_CMD_DO_SET_CAM_TRIGG_DIST => Command::TriggerDistance {
            every_m: finite(item.param1, 0.0).max(0.0),
            now: item.param3 == 1.0,
        },
        MavCmd::MAV_CMD_IMAGE_START_CAPTURE
            if finite(item.param2, -1.0) == 0.0 && finite(item.param3, 0.0) >= 1.0 =>
        {
            Command::Photo {
                count: f64::from(item.param3).min(f64::from(u32::MAX)) as u32,
            }
        }
        _ => Command::Skip,
    })
}

/// A straight 3D line flown with a profile's trajectory.
#[derive(Debug, Clone)]
struct Line {
    trajectory: Trajectory,
    from: Local,
    /// Unit horizontal direction (east, north) of the leg.
    heading: [f64; 2],
    start_s: f64,
    /// Where the vehicle is off the line when it starts (PX4 accepted the item before: the
    /// vehicle catches up with the line from the last point), closed exponentially over
    /// `catch_up_s`.
    offset: Local,
    catch_up_s: f64,
    /// Where the vehicle runs past the end point (PX4 SITL leaves a hold past its waypoint
    /// along the way it came), reached over the last [`OVERSHOOT_OVER_M`] of the leg (after
    /// the 4 m rule and PX4's acceptance).
    overshoot: Local,
    /// The leg's horizontal length (m).
    across_m: f64,
    /// ArduCopter's target along a leg of fast waypoints (`physics::ardupilot_chain`): its
    /// position a tick apart after the trajectory's delay, flown instead of the straight line;
    /// the waypoint counts reached when it ends (the S-curve finished, half-way through the
    /// turn).
    track: Option<Arc<Vec<Local>>>,
}

impl Line {
    fn end_s(&self) -> f64 {
        self.start_s + self.trajectory.duration_s()
    }

    fn at(&self, t_s: f64) -> (Local, Local) {
        if let Some(track) = &self.track {
            return on_track(track, t_s - self.start_s - self.trajectory.delay_s());
        }
        let tau = (t_s - self.start_s).max(0.0);
        let (x, z) = self.trajectory.position_m(tau);
        let (vx, vz, _, _) = self.trajectory.kinematics(tau);
        let [ex, ny] = self.heading;
        let left = (-tau / self.catch_up_s.max(1e-3)).exp();
        let closing = -left / self.catch_up_s.max(1e-3);
        let o = self.offset;
        let left_m = self.across_m - x;
        let (run, run_rate) = if self.across_m > 1e-9 && left_m < OVERSHOOT_OVER_M {
            let f = (1.0 - left_m / OVERSHOOT_OVER_M).clamp(0.0, 1.0);
            (f * f, 2.0 * f * vx / OVERSHOOT_OVER_M)
        } else {
            (0.0, 0.0)
        };
        let past = self.overshoot;
        (
            [
                self.from[0] + ex * x + o[0] * left + past[0] * run,
                self.from[1] + ny * x + o[1] * left + past[1] * run,
                self.from[2] + z + o[2] * left + past[2] * run,
            ],
            [
                ex * vx + o[0] * closing + past[0] * run_rate,
                ny * vx + o[1] * closing + past[1] * run_rate,
                vz + o[2] * closing + past[2] * run_rate,
            ],
        )
    }
}

/// Position and velocity `tau_s` along a target track sampled every
/// [`ardupilot_chain::TICK_S`] (at its ends outside it).
fn on_track(track: &[Local], tau_s: f64) -> (Local, Local) {
    let last = track.len().saturating_sub(1);
    let Some(&end) = track.get(last) else {
        return ([0.0; 3], [0.0; 3]);
    };
    let at = tau_s.max(0.0) / ardupilot_chain::TICK_S;
    let k = at.floor() as usize;
    if k >= last {
        return (end, [0.0; 3]);
    }
    let (a, b) = (track[k], track[k + 1]);
    let f = at - k as f64;
    let dt = ardupilot_chain::TICK_S;
    (
        [
            a[0] + f * (b[0] - a[0]),
            a[1] + f * (b[1] - a[1]),
            a[2] + f * (b[2] - a[2]),
        ],
        [(b[0] - a[0]) / dt, (b[1] - a[1]) / dt, (b[2] - a[2]) / dt],
    )
}

/// What the vehicle is physically doing.
#[derive(Debug, Clone)]
enum Motion {
    /// On the ground (motors off or idling).
    Ground,
    /// On the ground after a descent, until the land detector confirms it at `until_s`.
    Touchdown { until_s: f64 },
    /// Armed on the ground, motors spooling up until `until_s`, then taking off.
    SpoolUp { until_s: f64 },
    /// Flying a line; `purpose` says what comes at its end.
    Flying { line: Box<Line>, purpose: Purpose },
    /// Hovering in place.
    Hover,
}

/// Why a line is flown.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Purpose {
    /// A leg to a point (an item's, or above a landing point), then a settle in hover.
    Leg,
    /// The take-off climb from the ground (the profile's take-off: PX4's NAV_TAKEOFF).
    Climb,
    /// The landing descent, then touchdown.
    Descent,
}

/// Progress through the current item.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Progress {
    seq: u16,
    /// When the vehicle came within the acceptance radius.
    reached_s: Option<f64>,
    /// When the last line of the item ended (the vehicle at rest).
    rest_s: Option<f64>,
    /// The profile's settle time after that line.
    settle_s: f64,
    /// The autopilot's acceptance of the item's point when it does not wait for rest (PX4):
    /// reached by this rule, the hold counts from there and the item completes without rest.
    acceptance: Option<Acceptance>,
}

/// The simulated vehicle's flight: position, motion, mission progress and electrical power.
#[derive(Debug, Clone)]
pub struct Flight<'v> {
    vehicle: &'v Vehicle,
    model: Model<'v>,
    profile: Profile,
    hover_power_w: f64,
    commands: Vec<Command>,
    jumps_left: Vec<Option<i32>>,
    progress: Option<Progress>,
    motion: Motion,
    armed: bool,
    position: Local,
    velocity: Local,
    cruise_m_s: Option<f64>,
    now_s: f64,
    physics_errors: u32,
    complete: bool,
    /// Ground contact to a confirmed landing (the autopilot's land detector).
    land_detect_s: f64,
    /// An RTL mission item completes at once (PX4: the vehicle then returns in RTL mode).
    instant_rtl_item: bool,
    /// Flying the stored mission (else a landing or return outside it: no mission events).
    in_mission: bool,
    /// Items started since time last advanced (bounds a DO_JUMP loop of instant items).
    chain: usize,
    /// Where the last line flown ends: the autopilot's setpoint while it hovers there, and
    /// where its next line starts (PX4's trajectory continues from its own position, not the
    /// vehicle's); `None` once it holds or lands where it is.
    setpoint: Option<Local>,
    /// The horizontal displacement (east, north) of the last leg flown (None after a take-off
    /// or landing): with the px4 profile the next leg starts behind or ahead of PX4's
    /// trajectory by the turn between them (`physics::start_case`).
    last_leg_xy: Option<(f64, f64)>,
    /// With the ardupilot profile, the legs still ahead in a chain of fast waypoints: the item
    /// each flies to, its trajectory and its target track (`physics::ardupilot_chain`).
    chain_ahead: VecDeque<(u16, Trajectory, Arc<Vec<Local>>)>,
    /// The steady wind it flies in: the power of each line in what its heading meets of it,
    /// the hover in its speed (`mission::wind`). The paths over the ground are the still-air
    /// ones, as the autopilots fly them.
    wind: Wind,
    /// The camera's distance trigger while on: every how many metres, and where the last photo
    /// was taken (or the trigger set).
    trigger: Option<(f64, Local)>,
}

/// Most items started without time passing before the flight stops and hovers.
const MAX_CHAIN: usize = 1000;

impl<'v> Flight<'v> {
    /// A vehicle standing disarmed at home, flying `profile`'s trajectories.
    pub fn new(vehicle: &'v Vehicle, profile: Profile) -> Result<Flight<'v>, FlightError> {
        let model = Model::new(vehicle);
        let hover_power_w = model.hover_power_w()?;
        Ok(Flight {
            vehicle,
            model,
            profile,
            hover_power_w,
            commands: Vec::new(),
            jumps_left: Vec::new(),
            progress: None,
            motion: Motion::Ground,
            armed: false,
            position: [0.0; 3],
            velocity: [0.0; 3],
            cruise_m_s: None,
            now_s: 0.0,
            physics_errors: 0,
            complete: false,
            land_detect_s: 0.0,
            instant_rtl_item: false,
            in_mission: false,
            chain: 0,
            setpoint: None,
            last_leg_xy: None,
            chain_ahead: VecDeque::new(),
            wind: Wind::CALM,
            trigger: None,
        })
    }

    /// The same flight in a steady `wind`.
    pub fn with_wind(self, wind: Wind) -> Result<Flight<'v>, FlightError> {
        let hover_power_w = self
            .model
            .clone()
            .in_wind(wind.on_heading(0.0))
            .hover_power_w()?;
        Ok(Flight {
            wind,
            hover_power_w,
            ..self
        })
    }

    /// From now on the flight is in `wind` (a change of the wind in flight).
    pub fn set_wind(&mut self, wind: Wind) -> Result<(), FlightError> {
        self.hover_power_w = self
            .model
            .clone()
            .in_wind(wind.on_heading(0.0))
            .hover_power_w()?;
        self.wind = wind;
        Ok(())
    }

    /// The same flight with a land detector that confirms a landing `land_detect_s` after
    /// ground contact (the vehicle reports LANDING until then).
    pub fn with_land_detection(self, land_detect_s: f64) -> Flight<'v> {
        Flight {
            land_detect_s: land_detect_s.max(0.0),
            ..self
        }
    }

    /// The same flight where an RTL mission item completes at once (PX4 hands over to its RTL
    /// mode: the caller then calls [`Flight::land`] with `home_first`).
    pub fn with_instant_rtl_item(self) -> Flight<'v> {
        Flight {
            instant_rtl_item: true,
            ..self
        }
    }

    /// Simulated time (s).
    pub fn now_s(&self) -> f64 {
        self.now_s
    }

    /// Position east, north, up from home (m).
    pub fn position(&self) -> Local {
        self.position
    }

    /// Velocity east, north, up (m/s).
    pub fn velocity(&self) -> Local {
        self.velocity
    }

    /// Whether the motors are armed.
    pub fn armed(&self) -> bool {
        self.armed
    }

    /// Whether the vehicle stands on the ground.
    pub fn on_ground(&self) -> bool {
        matches!(
            self.motion,
            Motion::Ground | Motion::SpoolUp { .. } | Motion::Touchdown { .. }
        )
    }

    /// The item being flown, if a mission is running.
    pub fn current(&self) -> Option<u16> {
        self.progress.filter(|_| self.in_mission).map(|p| p.seq)
    }

    /// Whether the mission's last item is done.
    pub fn complete(&self) -> bool {
        self.complete
    }

    /// How many instants or legs the physics could not price (hover power, or a jump to the
    /// point, then).
    pub fn physics_errors(&self) -> u32 {
        self.physics_errors
    }

    /// Whether the vehicle stands at ground height (a take-off from here climbs from the ground).
    fn on_ground_height(&self) -> bool {
        self.on_ground() || self.position[2] <= ABOVE_POINT_M
    }

    /// The landed state (MAV_LANDED_STATE).
    pub fn landed(&self) -> Landed {
        match &self.motion {
            Motion::Ground | Motion::SpoolUp { .. } => Landed::OnGround,
            Motion::Touchdown { .. } => Landed::Landing,
            Motion::Flying { purpose, .. } if *purpose == Purpose::Descent => Landed::Landing,
            Motion::Flying { .. }
                if matches!(self.current_command(), Some(Command::Takeoff { .. })) =>
            {
                Landed::Takeoff
            }
            _ => Landed::InAir,
        }
    }

    fn current_command(&self) -> Option<Command> {
        self.progress
            .and_then(|p| self.commands.get(usize::from(p.seq)).copied())
    }

    /// Battery terminal power now: avionics when disarmed, idle spin armed on the ground, the
    /// physics model in the air.
    pub fn power_w(&mut self) -> f64 {
        let avionics = self.vehicle.body.avionics_power_w;
        if !self.armed {
            return avionics;
        }
        match &self.motion {
            Motion::Ground | Motion::SpoolUp { .. } | Motion::Touchdown { .. } => {
                avionics + IDLE_SPIN_POWER_W
            }
            Motion::Hover => self.hover_power_w,
            Motion::Flying { line, .. } => {
                let (vx, vz, ax, az) = line
                    .trajectory
                    .kinematics((self.now_s - line.start_s).max(0.0));
                let [east, north] = line.heading;
                let wind = self.wind.on_heading(heading_deg(east, north));
                match self.model.clone().in_wind(wind).power_w(vx, vz, ax, az) {
                    Ok((p, _)) => p,
                    Err(_) => {
                        self.physics_errors += 1;
                        self.hover_power_w
                    }
                }
            }
        }
    }

    /// Arms the motors (on the ground: they idle).
    pub fn arm(&mut self) {
        self.armed = true;
    }

    /// Disarms. In the air (a forced disarm) the vehicle drops to the ground and the mission ends.
    pub fn disarm(&mut self) {
        self.armed = false;
        if !self.on_ground() {
            self.position[2] = 0.0;
        }
        self.motion = Motion::Ground;
        self.velocity = [0.0; 3];
        self.progress = None;
    }

    /// Starts flying `commands` at item `from`, after a motor spool-up of `spool_up_s` when on
    /// the ground. The vehicle must be armed.
    pub fn start(&mut self, commands: Vec<Command>, from: u16, spool_up_s: f64) -> Vec<Event> {
        self.jumps_left = vec![None; commands.len()];
        self.commands = commands;
        self.complete = false;
        self.in_mission = true;
        self.cruise_m_s = None;
        self.trigger = None;
        if self.on_ground() {
            self.motion = Motion::SpoolUp {
                until_s: self.now_s + spool_up_s,
            };
        }
        let mut events = Vec::new();
        self.begin(from, &mut events);
        events
    }

    /// Stops where it is and hovers (PX4 HOLD / ArduCopter LOITER); the mission pauses.
    pub fn hold(&mut self) {
        self.progress = None;
        self.setpoint = None;
        if !self.on_ground() {
            self.motion = Motion::Hover;
            self.velocity = [0.0; 3];
        }
    }

    /// Lands where it is (or flies home first for a return), outside any mission (no
    /// Current, Reached or Complete events).
    pub fn land(&mut self, home_first: bool) -> Vec<Event> {
        self.land_with(if home_first {
            Command::ReturnToLaunch
        } else {
            Command::Land { at: None }
        })
    }

    /// Flies to `at` (east, north of home) at its height and lands there, outside any mission:
    /// a return to a rally point.
    pub fn land_at(&mut self, at: [f64; 2]) -> Vec<Event> {
        self.land_with(Command::Land { at: Some(at) })
    }

    fn land_with(&mut self, command: Command) -> Vec<Event> {
        let mut events = Vec::new();
        if self.on_ground() {
            return events;
        }
        self.in_mission = false;
        self.commands = vec![command];
        self.jumps_left = vec![None];
        self.motion = Motion::Hover;
        self.velocity = [0.0; 3];
        self.setpoint = None;
        self.begin(0, &mut events);
        events
    }

    /// Advances simulated time to `now_s` (one step: the caller steps finely).
    pub fn advance(&mut self, now_s: f64) -> Vec<Event> {
        let mut events = Vec::new();
        if now_s <= self.now_s {
            return events;
        }
        self.now_s = now_s;
        self.chain = 0;
        let mut line_end = None;
        match &self.motion {
            Motion::Touchdown { until_s } if now_s >= *until_s => {
                self.motion = Motion::Ground;
                events.push(Event::Landed);
                if let Some(p) = self.progress {
                    self.finish(p.seq, &mut events);
                }
            }
            Motion::SpoolUp { until_s } if now_s >= *until_s => {
                self.motion = Motion::Hover;
                events.push(Event::Liftoff);
                // The take-off (or whatever the current item is) starts now.
                self.run_item(&mut events);
            }
            Motion::Flying { line, purpose } => {
                let (position, velocity) = line.at(now_s);
                self.position = position;
                self.velocity = velocity;
                if now_s >= line.end_s() {
                    line_end = Some((*purpose, line.end_s(), line.trajectory.settle_s()));
                    // ArduCopter counts a waypoint of a chain reached when its S-curve
                    // finishes, wherever the vehicle is.
                    if line.track.is_some() {
                        if let Some(p) = self.progress.as_mut() {
                            p.reached_s.get_or_insert(line.end_s());
                        }
                    }
                }
            }
            _ => {}
        }
        self.distance_trigger(&mut events);
        if let Some((purpose, end_s, settle_s)) = line_end {
            self.velocity = [0.0; 3];
            self.line_done(purpose, end_s, settle_s, &mut events);
        }
        self.check_progress(&mut events);
        events
    }

    /// A photo of the distance trigger when the vehicle is its distance (horizontally) from
    /// where the last was taken.
    fn distance_trigger(&mut self, events: &mut Vec<Event>) {
        let Some((every_m, last)) = self.trigger else {
            return;
        };
        let here = self.position;
        if self.in_mission && (here[0] - last[0]).hypot(here[1] - last[1]) >= every_m {
            events.push(Event::Photo);
            self.trigger = Some((every_m, here));
        }
    }

    /// Starts item `seq` (or completes the mission when there is none).
    fn begin(&mut self, seq: u16, events: &mut Vec<Event>) {
        self.chain += 1;
        if self.chain > MAX_CHAIN {
            // A loop of items that take no time (DO_JUMP forever over commands): stop here.
            self.progress = None;
            if !self.on_ground() {
                self.motion = Motion::Hover;
            }
            return;
        }
        if usize::from(seq) >= self.commands.len() {
            self.progress = None;
            if self.in_mission {
                self.complete = true;
                events.push(Event::Complete);
            }
            if !self.on_ground() {
                self.motion = Motion::Hover;
            }
            return;
        }
        self.progress = Some(Progress {
            seq,
            reached_s: None,
            rest_s: None,
            settle_s: 0.0,
            acceptance: None,
        });
        if self.in_mission {
            events.push(Event::Current(seq));
        }
        if !matches!(self.motion, Motion::SpoolUp { .. }) {
            self.run_item(events);
        }
    }

    /// Sets the current item's motion going.
    fn run_item(&mut self, events: &mut Vec<Event>) {
        let (Some(progress), Some(command)) = (self.progress, self.current_command()) else {
            return;
        };
        let here = self.position;
        match command {
            Command::Takeoff { up_m } => {
                let purpose = if self.on_ground_height() {
                    Purpose::Climb
                } else {
                    Purpose::Leg
                };
                self.fly_to([here[0], here[1], up_m.max(here[2])], purpose, events);
            }
            Command::Waypoint { at, .. } | Command::Loiter { at, .. } => {
                self.fly_to(at, Purpose::Leg, events)
            }
            Command::Land { at } => {
                let [x, y] = at.unwrap_or([here[0], here[1]]);
                self.head_for_landing([x, y], events);
            }
            Command::ReturnToLaunch if self.instant_rtl_item && self.in_mission => {
                self.finish(progress.seq, events)
            }
            Command::ReturnToLaunch => self.head_for_landing([0.0, 0.0], events),
            Command::ChangeSpeed { speed_m_s } => {
                self.cruise_m_s = Some(speed_m_s);
                self.finish(progress.seq, events);
            }
            Command::Delay { .. } => {
                self.progress = Some(Progress {
                    rest_s: Some(self.now_s),
                    ..progress
                });
            }
            Command::Jump { to, repeat } => {
                let k = usize::from(progress.seq);
                let left = self.jumps_left.get(k).copied().flatten().unwrap_or(repeat);
                if left != 0 {
                    if let Some(slot) = self.jumps_left.get_mut(k) {
                        *slot = Some(left - 1);
                    }
                    self.begin(to, events);
                } else {
                    self.finish(progress.seq, events);
                }
            }
            Command::Photo { count } => {
                if self.in_mission {
                    events.extend((0..count).map(|_| Event::Photo));
                }
                self.finish(progress.seq, events);
            }
            Command::TriggerDistance { every_m, now } => {
                self.trigger = (every_m > 0.0).then_some((every_m, here));
                if now && self.in_mission {
                    events.push(Event::Photo);
                }
                self.finish(progress.seq, events);
            }
            Command::Skip => self.finish(progress.seq, events),
        }
    }

    /// Flies a line to `to` (when already there, the line is stationary and ends at once).
    fn fly_to(&mut self, to: Local, purpose: Purpose, events: &mut Vec<Event>) {
        // A leg begun while the take-off still climbs (PX4 accepted it NAV_MC_ALT_RAD below its
        // height) runs from the take-off point, as PX4's line from the previous waypoint does;
        // the vehicle closes the gap to it as it goes.
        let from = match &self.motion {
            Motion::Flying {
                line,
                purpose: Purpose::Climb,
            } if purpose == Purpose::Leg => line.at(line.end_s()).0,
            // From a hover, the line starts where the last one ended: a vehicle a few
            // centimetres off its waypoint flies the next leg from the waypoint, so a vertical
            // leg stays vertical (and is not slowed as a horizontal one).
            Motion::Hover => self.setpoint.unwrap_or(self.position),
            _ => self.position,
        };
        self.fly_line(from, to, purpose, events);
    }

    /// Flies the line `from` -> `to`; the vehicle, where it is, closes the gap to the line.
    fn fly_line(&mut self, from: Local, to: Local, purpose: Purpose, events: &mut Vec<Event>) {
        let offset = [
            self.position[0] - from[0],
            self.position[1] - from[1],
            self.position[2] - from[2],
        ];
        let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
        let xf_m = dx.hypot(dy);
        let heading = if xf_m > 1e-9 {
            [dx / xf_m, dy / xf_m]
        } else {
            [1.0, 0.0]
        };
        let zf_m = to[2] - from[2];
        self.setpoint = Some(to);
        let start = start_case(self.last_leg_xy, (dx, dy));
        self.last_leg_xy = (purpose == Purpose::Leg).then_some((dx, dy));
        // PX4 runs past a waypoint along the way it came and holds there: the next leg starts
        // that far off its line.
        // Only before a leg that moves across (a vertical leg after it stays vertical in the
        // mock, as the planner prices it).
        let next_across = self
            .progress
            .and_then(|p| self.flown_after(usize::from(p.seq)))
            .is_some_and(|c| match c {
                Command::Waypoint { at, .. } | Command::Loiter { at, .. } => {
                    (at[0] - to[0]).hypot(at[1] - to[1]) > 0.1
                }
                _ => false,
            });
        let to_waypoint =
            next_across && matches!(self.current_command(), Some(Command::Waypoint { .. }));
        let overshoot =
            if self.profile == Profile::Px4 && purpose == Purpose::Leg && to_waypoint && xf_m > 0.1
            {
                let e = self.vehicle.px4.departure_error_m;
                [e * heading[0], e * heading[1], 0.0]
            } else {
                [0.0; 3]
            };
        if let Some((trajectory, track)) = self.chain_leg(from, purpose) {
            let line = Line {
                trajectory,
                from,
                heading,
                start_s: self.now_s,
                offset: [0.0; 3],
                catch_up_s: self.vehicle.px4.departure_error_decay_s,
                overshoot: [0.0; 3],
                across_m: xf_m,
                track: Some(track),
            };
            self.motion = Motion::Flying {
                line: Box::new(line),
                purpose,
            };
            return;
        }
        let trajectory = match purpose {
            Purpose::Leg => self.trajectory(xf_m, zf_m, start),
            Purpose::Climb if xf_m < ABOVE_POINT_M => {
                self.model.takeoff_trajectory(self.profile, zf_m)
            }
            Purpose::Descent if xf_m < ABOVE_POINT_M => {
                // The mock's height estimate does not drift: its home stays where it was.
                self.model
                    .landing_trajectory_home_risen(self.profile, -zf_m, 0.0)
            }
            Purpose::Climb | Purpose::Descent => self.trajectory(xf_m, zf_m, start),
        };
        let trajectory = match trajectory {
            Ok(t) => t,
            Err(_) => {
                // The physics cannot fly it: move there at once so the mission goes on.
                self.physics_errors += 1;
                self.position = to;
                self.motion = Motion::Hover;
                self.line_done(purpose, self.now_s, 0.0, events);
                return;
            }
        };
        if let Some(p) = self.progress.as_mut() {
            p.acceptance = trajectory.acceptance();
        }
        let line = Line {
            trajectory,
            from,
            heading,
            start_s: self.now_s,
            offset,
            catch_up_s: self.vehicle.px4.departure_error_decay_s,
            overshoot,
            across_m: xf_m,
            track: None,
        };
        if line.trajectory.duration_s() <= 0.0 {
            self.motion = Motion::Hover;
            self.line_done(purpose, self.now_s, 0.0, events);
            return;
        }
        self.motion = Motion::Flying {
            line: Box::new(line),
            purpose,
        };
    }

    /// With the ardupilot profile, the leg to the current waypoint when ArduCopter flies it in
    /// a chain of fast waypoints (the waypoint, or the one before it, fast: a hold under a
    /// second and another waypoint next, `ardupilot_chain::is_fast`): the chain from `from`
    /// through the waypoints ahead to the first that is not fast is simulated when its first
    /// leg starts and its legs kept for the items that follow. None for a leg rest to rest.
    fn chain_leg(
        &mut self,
        from: Local,
        purpose: Purpose,
    ) -> Option<(Trajectory, Arc<Vec<Local>>)> {
        let seq = self.progress?.seq;
        if let Some((next, _, _)) = self.chain_ahead.front() {
            if *next == seq && purpose == Purpose::Leg {
                return self.chain_ahead.pop_front().map(|(_, t, track)| (t, track));
            }
        }
        self.chain_ahead.clear();
        if self.profile != Profile::Ardupilot || purpose != Purpose::Leg {
            return None;
        }
        let waypoint = |k: usize| match self.commands.get(k) {
            Some(Command::Waypoint { at, hold_s, .. }) => Some((*at, *hold_s)),
            _ => None,
        };
        // The waypoint after item k, past the photos between (the autopilots look ahead to the
        // next navigation item, ArduPilot `AP_Mission::get_next_nav_cmd`).
        let next = |k: usize| (k + 1..self.commands.len()).find(|&j| !self.is_photo(j));
        let mut points = Vec::new();
        let mut k = usize::from(seq);
        while let Some((at, hold_s)) = waypoint(k) {
            let after = next(k);
            let fast = ardupilot_chain::is_fast(hold_s, after.and_then(waypoint).is_some());
            points.push((k, ChainPoint { enu_m: at, fast }));
            match after {
                Some(j) if fast => k = j,
                _ => break,
            }
        }
        if points.first().is_none_or(|(_, p)| !p.fast) {
            return None;
        }
        let chain_points: Vec<ChainPoint> = points.iter().map(|(_, p)| *p).collect();
        let flown = match self.cruising() {
            None => self.model.ardupilot_chain_trajectories(from, &chain_points),
            Some(v) => Model::new(&v).ardupilot_chain_trajectories(from, &chain_points),
        };
        let Ok(flown) = flown else {
            // The physics cannot fly it: the legs rest to rest instead.
            self.physics_errors += 1;
            return None;
        };
        for ((k, _), (trajectory, track)) in points.iter().zip(flown) {
            let seq = u16::try_from(*k).ok()?;
            self.chain_ahead
                .push_back((seq, trajectory, Arc::new(track)));
        }
        self.chain_ahead.pop_front().map(|(_, t, track)| (t, track))
    }

    /// Whether item `k` runs in passing, between the items the vehicle flies: a photo, a speed
    /// change, a command the flight ignores (a gimbal, a region of interest, a servo: the
    /// autopilots look past them to the next navigation item, ArduPilot
    /// `AP_Mission::get_next_nav_cmd`).
    fn is_photo(&self, k: usize) -> bool {
        matches!(
            self.commands.get(k),
            Some(
                Command::Photo { .. }
                    | Command::TriggerDistance { .. }
                    | Command::ChangeSpeed { .. }
                    | Command::Skip
            )
        )
    }

    /// The first command after item `k` that does not run in passing.
    fn flown_after(&self, k: usize) -> Option<&Command> {
        (k + 1..self.commands.len())
            .find(|&j| !self.is_photo(j))
            .and_then(|j| self.commands.get(j))
    }

    /// The profile's trajectory, at the cruise speed a DO_CHANGE_SPEED set.
    fn trajectory(&self, xf_m: f64, zf_m: f64, start: Start) -> Result<Trajectory, PhysicsError> {
        match self.cruising() {
            None => self.model.trajectory_from(self.profile, xf_m, zf_m, start),
            Some(v) => Model::new(&v).trajectory_from(self.profile, xf_m, zf_m, start),
        }
    }

    /// The vehicle with every profile's cruise speed at the one a DO_CHANGE_SPEED set (None:
    /// none set, the vehicle's own).
    fn cruising(&self) -> Option<Vehicle> {
        Some(self.vehicle.at_speed(self.cruise_m_s?))
    }

    /// Heads for the landing point: a horizontal leg first when not above it, else the descent.
    fn head_for_landing(&mut self, at: [f64; 2], events: &mut Vec<Event>) {
        let here = self.position;
        // PX4 moves to the landing point first only when it is farther than NAV_ACC_RAD
        // (mission.cpp `do_need_move_to_land`); else it descends at once.
        let above_m = if self.profile == Profile::Px4 {
            self.vehicle.px4.nav_acc_rad_m.max(ABOVE_POINT_M)
        } else {
            ABOVE_POINT_M
        };
        if (at[0] - here[0]).hypot(at[1] - here[1]) > above_m {
            self.fly_to([at[0], at[1], here[2]], Purpose::Leg, events);
        } else {
            // The descent's setpoint is the landing point: the vehicle drifts onto it.
            let above = [at[0], at[1], here[2]];
            self.fly_line(above, [at[0], at[1], 0.0], Purpose::Descent, events);
        }
    }

    /// A line ended at `end_s` with the vehicle at rest; `settle_s` of hover settles it.
    fn line_done(&mut self, purpose: Purpose, end_s: f64, settle_s: f64, events: &mut Vec<Event>) {
        if purpose == Purpose::Descent {
            self.position[2] = 0.0;
            events.push(Event::Touchdown);
            if self.land_detect_s > 0.0 {
                self.motion = Motion::Touchdown {
                    until_s: end_s + self.land_detect_s,
                };
                return;
            }
            self.motion = Motion::Ground;
            events.push(Event::Landed);
            if let Some(p) = self.progress {
                self.finish(p.seq, events);
            }
            return;
        }
        // A leg, or the horizontal leg before a landing: settle in hover (check_progress goes on).
        self.motion = Motion::Hover;
        if let Some(p) = self.progress {
            self.progress = Some(Progress {
                rest_s: Some(end_s),
                settle_s,
                ..p
            });
        }
    }

    /// Completes the current item when its conditions hold.
    fn check_progress(&mut self, events: &mut Vec<Event>) {
        let (Some(mut p), Some(command)) = (self.progress, self.current_command()) else {
            return;
        };
        let now = self.now_s;
        let target = match command {
            Command::Waypoint { at, radius_m, .. } => Some((at, radius_m)),
            Command::Loiter { at, .. } => Some((at, DEFAULT_ACCEPTANCE_RADIUS_M)),
            _ => None,
        };
        if let Some((at, radius_m)) = target {
            let inside = match p.acceptance {
                // PX4: within the item's radius horizontally and NAV_MC_ALT_RAD vertically.
                Some(a) => {
                    let horizontal = (self.position[0] - at[0]).hypot(self.position[1] - at[1]);
                    horizontal <= radius_m && (self.position[2] - at[2]).abs() <= a.vertical_m
                }
                None => distance(self.position, at) <= radius_m,
            };
            if p.reached_s.is_none() && inside {
                p.reached_s = Some(now);
                self.progress = Some(p);
            }
        }
        // PX4 does not wait for rest: a waypoint is done its hold after being reached, a
        // take-off once within NAV_MC_ALT_RAD of its height (mission_block.cpp).
        if let Some(a) = p.acceptance.filter(|_| p.rest_s.is_none()) {
            let done = match command {
                Command::Waypoint { hold_s, .. } => p.reached_s.is_some_and(|r| now >= r + hold_s),
                Command::Takeoff { up_m } => self.position[2] >= up_m - a.vertical_m,
                _ => false,
            };
            if done {
                self.finish(p.seq, events);
            }
            return;
        }
        let Some(rest_s) = p.rest_s else {
            return;
        };
        let settled = now >= rest_s + p.settle_s;
        let done = match command {
            Command::Takeoff { .. } => settled,
            Command::Waypoint { hold_s, .. } => {
                (settled || p.acceptance.is_some())
                    && p.reached_s.is_some_and(|r| now >= r + hold_s)
            }
            Command::Loiter { hold_s, .. } => match (hold_s, p.reached_s) {
                (Some(h), Some(r)) => settled && now >= r + h,
                _ => false,
            },
            Command::Delay { duration_s } => now >= rest_s + duration_s,
            Command::Land { .. } | Command::ReturnToLaunch => {
                // Settled above the landing point: descend.
                if settled && matches!(self.motion, Motion::Hover) {
                    self.progress = Some(Progress { rest_s: None, ..p });
                    let here = self.position;
                    self.fly_to([here[0], here[1], 0.0], Purpose::Descent, events);
                }
                false
            }
            _ => false,
        };
        if done {
            self.finish(p.seq, events);
        }
    }

    /// Item `seq` is done: report it and go on with the next.
    fn finish(&mut self, seq: u16, events: &mut Vec<Event>) {
        if self.in_mission
            && self
                .commands
                .get(usize::from(seq))
                .is_some_and(Command::is_navigation)
        {
            events.push(Event::Reached(seq));
        }
        self.begin(seq.saturating_add(1), events);
    }
}

fn distance(a: Local, b: Local) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::vehicle::shipped;

    const HOME: Geodetic = Geodetic {
        lat_deg: 38.5362,
        lon_deg: -121.7875,
        alt_m: 16.0,
    };

    /// `link::items::item` numbered `seq`, addressed to system 1 (what the ground sends).
    fn item(
        seq: u16,
        command: MavCmd,
        frame: MavFrame,
        params: [f32; 4],
        xyz: (i32, i32, f32),
    ) -> MISSION_ITEM_INT_DATA {
        MISSION_ITEM_INT_DATA {
            seq,
            target_system: 1,
            target_component: 1,
            ..crate::link::items::item(command, frame, params, xyz.0, xyz.1, xyz.2)
        }
    }

    /// Take-off to 20 m, a waypoint 40 m east (hold 4 s, radius 2 m), then item 2: `command`
    /// with `params` at `xyz`.
    fn east_waypoint_then(
        command: MavCmd,
        params: [f32; 4],
        xyz: (i32, i32, f32),
    ) -> [MISSION_ITEM_INT_DATA; 3] {
        let (x, y) = at(40.0, 0.0);
        let frame = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT;
        [
            item(
                0,
                MavCmd::MAV_CMD_NAV_TAKEOFF,
                frame,
                [0.0; 4],
                (0, 0, 20.0),
            ),
            item(
                1,
                MavCmd::MAV_CMD_NAV_WAYPOINT,
                frame,
                [4.0, 2.0, 0.0, 0.0],
                (x, y, 20.0),
            ),
            item(2, command, frame, params, xyz),
        ]
    }

    /// degE7 of a point `east_m`, `north_m` from home.
    fn at(east_m: f64, north_m: f64) -> (i32, i32) {
        let g = Origin {
            home: HOME,
            height_above_home_m: 0.0,
        }
        .to_geodetic(crate::mission::Enu {
            x_east_m: east_m,
            y_north_m: north_m,
            z_up_m: 0.0,
        });
        (
            (g.lat_deg * 1e7).round() as i32,
            (g.lon_deg * 1e7).round() as i32,
        )
    }

    #[test]
    #[allow(deprecated)] // PX4 reads back MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    fn relative_and_amsl_frames_give_the_same_point_and_bad_items_are_located_errors() {
        let (x, y) = at(30.0, -40.0);
        let relative = item(
            0,
            MavCmd::MAV_CMD_NAV_WAYPOINT,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            [5.0, 0.0, 0.0, f32::NAN],
            (x, y, 25.0),
        );
        let amsl = item(
            1,
            MavCmd::MAV_CMD_NAV_WAYPOINT,
            MavFrame::MAV_FRAME_GLOBAL,
            [5.0, 3.0, 0.0, 0.0],
            (x, y, 41.0),
        );
        let c = commands(&[relative, amsl], HOME, false).unwrap();
        let (
            Command::Waypoint {
                at: a,
                hold_s,
                radius_m,
            },
            Command::Waypoint {
                at: b,
                radius_m: r2,
                ..
            },
        ) = (c[0], c[1])
        else {
            panic!("{c:?}");
        };
        assert!(
            (a[0] - 30.0).abs() < 0.02 && (a[1] + 40.0).abs() < 0.02 && (a[2] - 25.0).abs() < 1e-3,
            "{a:?}"
        );
        assert!((0..3).all(|k| (a[k] - b[k]).abs() < 1e-6));
        assert_eq!(
            (hold_s, radius_m, r2),
            (5.0, DEFAULT_ACCEPTANCE_RADIUS_M, 3.0)
        );
        let mut local = item(
            4,
            MavCmd::MAV_CMD_NAV_WAYPOINT,
            MavFrame::MAV_FRAME_LOCAL_NED,
            [0.0; 4],
            (x, y, 5.0),
        );
        let err = commands(std::slice::from_ref(&local), HOME, false).unwrap_err();
        assert!(err.to_string().starts_with("mission item 4:"), "{err}");
        local.frame = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT;
        local.z = f32::NAN;
        assert!(commands(&[local], HOME, false).is_err());
        // Land at 0, 0 means here; ArduPilot's item 0 is home.
        let land = item(
            0,
            MavCmd::MAV_CMD_NAV_LAND,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
            [0.0; 4],
            (0, 0, 0.0),
        );
        assert_eq!(
            commands(std::slice::from_ref(&land), HOME, false).unwrap(),
            [Command::Land { at: None }]
        );
        assert_eq!(commands(&[land], HOME, true).unwrap(), [Command::Skip]);
    }

    /// Steps a flight in 10 ms until `done` or `max_s`, returning the events with their times.
    fn run(f: &mut Flight, max_s: f64, done: impl Fn(&Flight) -> bool) -> Vec<(f64, Event)> {
        let mut events = Vec::new();
        let start = f.now_s();
        let mut k = 0u64;
        while !done(f) && (k as f64) * 0.01 < max_s {
            k += 1;
            let t = start + k as f64 * 0.01;
            events.extend(f.advance(t).into_iter().map(|e| (t, e)));
        }
        events
    }

    /// Flies take-off to 20 m, a waypoint 40 m east (hold 4 s, radius 2 m) and a landing there
    /// with `profile`; returns the events with their times.
    fn fly_one_waypoint(v: &Vehicle, profile: Profile) -> (Flight<'_>, Vec<(f64, Event)>) {
        let mut f = Flight::new(v, profile).unwrap();
        f.arm();
        let (x, y) = at(40.0, 0.0);
        let items = east_waypoint_then(MavCmd::MAV_CMD_NAV_LAND, [0.0; 4], (x, y, 0.0));
        let events = f.start(commands(&items, HOME, false).unwrap(), 0, 1.0);
        assert_eq!(events, [Event::Current(0)]);
        let events = run(&mut f, 300.0, |f| f.complete());
        (f, events)
    }

    fn when(events: &[(f64, Event)], e: Event) -> f64 {
        events
            .iter()
            .find(|(_, x)| *x == e)
            .map(|(t, _)| *t)
            .unwrap()
    }

    fn mission_events(events: &[(f64, Event)]) -> Vec<Event> {
        events
            .iter()
            .map(|(_, e)| *e)
            .filter(|e| {
                matches!(
                    e,
                    Event::Reached(_) | Event::Touchdown | Event::Landed | Event::Complete
                )
            })
            .collect()
    }

    #[test]
    fn the_distance_trigger_takes_a_photo_every_trigger_distance_between_on_and_off() {
        // Take-off to 20 m, a waypoint 10 m east; trigger every 20 m, one at once; a waypoint
        // 110 m east (a 100 m line); trigger off; a waypoint back at 10 m east; land.
        let v = shipped();
        let frame = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT;
        let mission = MavFrame::MAV_FRAME_MISSION;
        let waypoint = |seq: u16, east_m: f64| {
            let (x, y) = at(east_m, 0.0);
            item(
                seq,
                MavCmd::MAV_CMD_NAV_WAYPOINT,
                frame,
                [0.0, 2.0, 0.0, f32::NAN],
                (x, y, 20.0),
            )
        };
        let trigger = |seq: u16, every_m: f32| {
            item(
                seq,
                MavCmd::MAV_CMD_DO_SET_CAM_TRIGG_DIST,
                mission,
                // Once at once when switched on, as QGroundControl writes a survey's.
                [every_m, 0.0, if every_m > 0.0 { 1.0 } else { 0.0 }, 0.0],
                (0, 0, 0.0),
            )
        };
        let (x, y) = at(10.0, 0.0);
        let items = [
            item(
                0,
                MavCmd::MAV_CMD_NAV_TAKEOFF,
                frame,
                [0.0; 4],
                (0, 0, 20.0),
            ),
            waypoint(1, 10.0),
            trigger(2, 20.0),
            waypoint(3, 110.0),
            trigger(4, 0.0),
            waypoint(5, 10.0),
            item(6, MavCmd::MAV_CMD_NAV_LAND, frame, [0.0; 4], (x, y, 0.0)),
        ];
        for profile in [Profile::Ardupilot, Profile::Px4] {
            let mut f = Flight::new(&v, profile).unwrap();
            f.arm();
            f.start(commands(&items, HOME, false).unwrap(), 0, 1.0);
            let mut photos = Vec::new();
            for k in 1..60_000 {
                let t = k as f64 * 0.01;
                for e in f.advance(t) {
                    if e == Event::Photo {
                        photos.push(f.position()[0]);
                    }
                }
                if f.complete() {
                    break;
                }
            }
            assert!(f.complete(), "{profile}");
            // One as it is switched on (near 10 m east: PX4 accepts the waypoint within its
            // 2 m radius), then every 20 m from there up to the line's end (the last not when
            // the vehicle stops short of the distance); none on the way back with the trigger
            // off.
            assert!((5..=6).contains(&photos.len()), "{profile}: {photos:?}");
            assert!((photos[0] - 10.0).abs() < 2.5, "{profile}: {photos:?}");
            for (k, east_m) in photos.iter().enumerate() {
                let expected = photos[0] + 20.0 * k as f64;
                assert!((east_m - expected).abs() < 0.5, "{profile}: {photos:?}");
            }
        }
    }

    #[test]
    fn ardupilot_flies_waypoints_without_holds_through_their_blended_corners_as_priced() {
        // Take-off to 20 m, then three waypoints without holds (the last followed by a landing,
        // so not fast): ArduCopter flies the first two through, each reached half-way through
        // its turn, and stops on the third.
        let v = shipped();
        let frame = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT;
        let enu = [[40.0, 0.0, 20.0], [40.0, 30.0, 25.0], [0.0, 30.0, 20.0]];
        let mut items = vec![item(
            0,
            MavCmd::MAV_CMD_NAV_TAKEOFF,
            frame,
            [0.0; 4],
            (0, 0, 20.0),
        )];
        for (k, p) in enu.iter().enumerate() {
            let (x, y) = at(p[0], p[1]);
            items.push(item(
                k as u16 + 1,
                MavCmd::MAV_CMD_NAV_WAYPOINT,
                frame,
                [0.0; 4],
                (x, y, p[2] as f32),
            ));
        }
        let (x, y) = at(0.0, 30.0);
        items.push(item(
            4,
            MavCmd::MAV_CMD_NAV_LAND,
            frame,
            [0.0; 4],
            (x, y, 0.0),
        ));
        let mut f = Flight::new(&v, Profile::Ardupilot).unwrap();
        f.arm();
        f.start(commands(&items, HOME, false).unwrap(), 0, 1.0);
        let mut events = Vec::new();
        let mut jumps = 0.0f64;
        let mut last = f.position();
        let mut energy = [0.0f64; 3];
        let mut leg: Option<usize> = None;
        let dt = 0.01;
        for k in 1..30_000 {
            let t = k as f64 * dt;
            for e in f.advance(t) {
                match e {
                    Event::Current(s @ 1..=3) => leg = Some(usize::from(s) - 1),
                    Event::Reached(3) => leg = None,
                    _ => {}
                }
                events.push((t, e));
            }
            let here = f.position();
            jumps = jumps.max(distance(here, last));
            last = here;
            if let Some(l) = leg {
                energy[l] += f.power_w() * dt;
            }
            if f.complete() {
                break;
            }
        }
        assert!(f.complete(), "{events:?}");
        // No jump in position: each leg's track starts where the last one ended.
        assert!(jumps < 0.2, "{jumps} m in a step");
        assert_eq!(f.physics_errors(), 0);
        // The legs as the profile prices them: the same chain, from the take-off's end.
        let model = Model::new(&v);
        let points: Vec<ChainPoint> = (enu.iter().enumerate())
            .map(|(k, &enu_m)| ChainPoint { enu_m, fast: k < 2 })
            .collect();
        let top = [0.0, 0.0, 20.0];
        let priced = model.ardupilot_chain(top, &points).unwrap();
        let flown = model.ardupilot_chain_trajectories(top, &points).unwrap();
        let start = when(&events, Event::Current(1));
        let mut end = start;
        for (k, ((op, (t, _)), measured)) in priced.iter().zip(&flown).zip(energy).enumerate() {
            // Each fast waypoint is reached when its leg's trajectory ends.
            if k < 2 {
                end += t.duration_s();
                let reached = when(&events, Event::Reached(k as u16 + 1));
                assert!((reached - end).abs() < 0.011, "leg {k}: {reached} vs {end}");
            }
            let price = op.energy_j + op.settle_energy_j;
            assert!(
                (measured / price - 1.0).abs() < 0.01,
                "leg {k}: {measured} J flown, {price} J priced"
            );
        }
        // The third is reached on arrival, at rest: its leg ends on it.
        let third = when(&events, Event::Reached(3));
        assert!(third >= end + flown[2].0.duration_s() - 0.011, "{third}");
    }

    #[test]
    fn px4_takes_a_point_reached_within_its_acceptance_and_leaves_after_the_hold_while_still_braking(
    ) {
        let v = shipped();
        let (f, events) = fly_one_waypoint(&v, Profile::Px4);
        assert!((when(&events, Event::Liftoff) - 1.0).abs() < 0.011);
        let model = Model::new(&v);
        // The take-off is done NAV_MC_ALT_RAD below its height, still climbing.
        let climb = model.takeoff_trajectory(Profile::Px4, 20.0).unwrap();
        let climb_done = climb.accepted_s().unwrap();
        assert!(climb_done < climb.duration_s() - 1.0);
        let leg_start = when(&events, Event::Current(1));
        assert!(
            (leg_start - (1.0 + climb_done)).abs() < 0.011,
            "{leg_start} {climb_done}"
        );
        // The waypoint is reached within 2 m horizontally and 0.8 m vertically, from 0.8 m
        // below: later than the trajectory from the origin height says, but well before its
        // end; the 4 s hold counts from there and the vehicle leaves before it is at rest.
        let leg = model.trajectory(Profile::Px4, 40.0, 0.0).unwrap();
        let accepted = leg.accepted_s().unwrap();
        let done = when(&events, Event::Reached(1));
        assert!(
            done > leg_start + accepted + 4.0 && done < leg_start + accepted + 4.5,
            "{done} {leg_start} {accepted}"
        );
        assert!(done < leg_start + leg.duration_s());
        assert_eq!(
            mission_events(&events),
            [
                Event::Reached(0),
                Event::Reached(1),
                Event::Touchdown,
                Event::Landed,
                Event::Reached(2),
                Event::Complete
            ]
        );
        assert!(f.on_ground() && f.position()[2] == 0.0);
        assert_eq!(f.physics_errors(), 0);
    }

    #[test]
    fn px4_holds_a_waypoint_past_it_along_the_way_it_came() {
        let v = shipped();
        // Where the vehicle is when it leaves the waypoint 40 m east (its hold done).
        let leaves = |profile: Profile| {
            let items = east_waypoint_then(
                MavCmd::MAV_CMD_NAV_WAYPOINT,
                [4.0, 2.0, 0.0, 0.0],
                (at(40.0, 0.0).0, at(0.0, 40.0).1, 20.0),
            );
            let mut f = Flight::new(&v, profile).unwrap();
            f.arm();
            f.start(commands(&items, HOME, false).unwrap(), 0, 1.0);
            // Until the next leg starts.
            let events = run(&mut f, 300.0, |f| f.current() == Some(2));
            assert!(events.iter().any(|(_, e)| *e == Event::Reached(1)));
            f.position()
        };
        let p = leaves(Profile::Px4);
        // Past it (still creeping on when the hold ends), by at most the offset.
        assert!(
            p[0] > 40.3 && p[0] <= 40.0 + v.px4.departure_error_m + 1e-9 && p[1].abs() < 0.02,
            "{p:?}"
        );
        // The other profiles hold on the waypoint.
        let p = leaves(Profile::Hvb);
        assert!((p[0] - 40.0).abs() < 0.02, "{p:?}");
    }

    #[test]
    fn without_an_acceptance_rule_a_waypoint_completes_once_settled_and_its_hold_has_passed() {
        let v = shipped();
        let (f, events) = fly_one_waypoint(&v, Profile::Hvb);
        let model = Model::new(&v);
        let climb = model.trajectory(Profile::Hvb, 0.0, 20.0).unwrap();
        let leg = model.trajectory(Profile::Hvb, 40.0, 0.0).unwrap();
        let settle = v.hvb.settle_s;
        let leg_start = when(&events, Event::Current(1));
        assert!(
            (leg_start - (1.0 + climb.duration_s() + settle)).abs() < 0.011,
            "{leg_start}"
        );
        // Within 2 m before the trajectory ends; the 4 s hold from there ends after the
        // trajectory's end plus its settle.
        let mut t_radius = 0.0;
        while leg.remaining_m(t_radius) > 2.0 {
            t_radius += 0.001;
        }
        let done = when(&events, Event::Reached(1));
        assert!(
            (done - (leg_start + t_radius + 4.0)).abs() < 0.02,
            "{done} {leg_start} {t_radius}"
        );
        assert!(done > leg_start + leg.duration_s() + settle);
        assert_eq!(mission_events(&events).len(), 6);
        assert!(f.on_ground() && f.physics_errors() == 0);
    }

    #[test]
    fn a_do_jump_loop_of_instant_items_stops_the_mission_instead_of_hanging() {
        let v = shipped();
        let mut f = Flight::new(&v, Profile::Px4).unwrap();
        f.arm();
        let items = [
            item(
                0,
                MavCmd::MAV_CMD_DO_CHANGE_SPEED,
                MavFrame::MAV_FRAME_MISSION,
                [1.0, 3.0, -1.0, 0.0],
                (0, 0, 0.0),
            ),
            item(
                1,
                MavCmd::MAV_CMD_DO_JUMP,
                MavFrame::MAV_FRAME_MISSION,
                [0.0, -1.0, 0.0, 0.0],
                (0, 0, 0.0),
            ),
        ];
        let events = f.start(commands(&items, HOME, false).unwrap(), 0, 0.0);
        assert!(events.len() <= 2 * MAX_CHAIN + 2);
        run(&mut f, 1.0, |_| false);
        assert_eq!(f.current(), None);
        assert!(!f.complete());
    }
}
