//! Actions at waypoints: the commands a mission carries after each navigation item (a photo, a
//! gimbal pitch, a region of interest, a yaw, a speed, a payload, a hold), what each means to
//! emplan, and the state some of them leave in force.
//!
//! An autopilot runs the commands that follow a navigation item once that item completes (the
//! waypoint reached and its hold time passed), at the moment it starts for the next one:
//! ArduPilot `AP_Mission::advance_current_nav_cmd` starts every non-navigation command it
//! passes on its way to the next navigation command; PX4's navigator steps through them in the
//! same place. So the commands after a waypoint belong to it, in file order, and travel with it
//! when the waypoints are reordered. Commands between the take-off and the first waypoint
//! belong to the start.
//!
//! Four settings stay in force until changed ([`Setting`]): the speed, the region of interest,
//! the camera's trigger distance and the gimbal's orientation. In another visiting order a
//! waypoint would inherit whatever its new predecessor left; [`restore`] lists the commands that
//! put back, before leaving each waypoint, the state in force on the way to the next one in the
//! file's order.
//!
//! Invariant: pure; never panics on input; a command is kept exactly as the file gave it.

use std::fmt;

/// MAV_CMD ids (MAVLink common.xml) emplan gives a meaning to.
pub mod id {
    pub const NAV_WAYPOINT: u16 = 16;
    pub const NAV_LOITER_TIME: u16 = 19;
    pub const NAV_RETURN_TO_LAUNCH: u16 = 20;
    pub const NAV_LAND: u16 = 21;
    pub const NAV_TAKEOFF: u16 = 22;
    pub const NAV_SPLINE_WAYPOINT: u16 = 82;
    pub const NAV_DELAY: u16 = 93;
    /// The last navigation command id (MAV_CMD_NAV_LAST).
    pub const NAV_LAST: u16 = 95;
    pub const CONDITION_YAW: u16 = 115;
    /// The condition commands: MAV_CMD_CONDITION_DELAY (112) to MAV_CMD_CONDITION_LAST (159).
    pub const CONDITION_FIRST: u16 = 112;
    pub const CONDITION_LAST: u16 = 159;
    pub const DO_SET_MODE: u16 = 176;
    pub const DO_JUMP: u16 = 177;
    pub const DO_CHANGE_SPEED: u16 = 178;
    pub const DO_SET_HOME: u16 = 179;
    pub const DO_SET_RELAY: u16 = 181;
    pub const DO_SET_SERVO: u16 = 183;
    pub const DO_FLIGHTTERMINATION: u16 = 185;
    pub const DO_RETURN_PATH_START: u16 = 188;
    pub const DO_LAND_START: u16 = 189;
    pub const DO_GO_AROUND: u16 = 191;
    pub const DO_REPOSITION: u16 = 192;
    pub const DO_PAUSE_CONTINUE: u16 = 193;
    pub const DO_SET_ROI_LOCATION: u16 = 195;
    pub const DO_SET_ROI_WPNEXT_OFFSET: u16 = 196;
    pub const DO_SET_ROI_NONE: u16 = 197;
    pub const DO_SET_ROI: u16 = 201;
    pub const DO_DIGICAM_CONTROL: u16 = 203;
    pub const DO_MOUNT_CONTROL: u16 = 205;
    pub const DO_SET_CAM_TRIGG_DIST: u16 = 206;
    pub const DO_GRIPPER: u16 = 211;
    pub const NAV_SET_YAW_SPEED: u16 = 213;
    pub const DO_SET_MISSION_CURRENT: u16 = 224;
    pub const JUMP_TAG: u16 = 600;
    pub const DO_JUMP_TAG: u16 = 601;
    pub const DO_GIMBAL_MANAGER_PITCHYAW: u16 = 1000;
    pub const IMAGE_START_CAPTURE: u16 = 2000;
    pub const IMAGE_STOP_CAPTURE: u16 = 2001;
    pub const VIDEO_START_CAPTURE: u16 = 2500;
    pub const VIDEO_STOP_CAPTURE: u16 = 2501;
    pub const DO_WINCH: u16 = 42600;
}

/// MAV_FRAME_GLOBAL (altitude above mean sea level).
pub const FRAME_GLOBAL: u8 = 0;
/// MAV_FRAME_MISSION: a command without a position.
pub const FRAME_MISSION: u8 = 2;
/// MAV_FRAME_GLOBAL_RELATIVE_ALT: altitude above home.
pub const FRAME_GLOBAL_RELATIVE_ALT: u8 = 3;

/// One mission command as a file gives it: its MAV_CMD id, its frame and its seven parameters
/// (for a command with a position, parameters 5 and 6 are latitude and longitude in degrees and
/// 7 the altitude in the frame's reference). A parameter a file leaves empty (`null`) is NaN.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Command {
    pub command: u16,
    pub frame: u8,
    pub params: [f64; 7],
}

impl Command {
    /// A command in the mission frame with these parameters.
    pub fn new(command: u16, params: [f64; 7]) -> Command {
        Command {
            command,
            frame: FRAME_MISSION,
            params,
        }
    }

    /// Whether the command carries a position (parameters 5-7 in a global frame).
    pub fn has_position(&self) -> bool {
        matches!(self.frame, 0 | 3 | 5 | 6) && self.params[4] != 0.0 && self.params[4].is_finite()
    }

    /// What the command means to emplan.
    pub fn action(&self) -> Action {
        let p = &self.params;
        let finite = |v: f64| v.is_finite().then_some(v);
        match self.command {
            id::DO_DIGICAM_CONTROL if p[4] == 1.0 => Action::Photo,
            // A single image, or a burst of `total` at no interval: photos the autopilot takes
            // at once.
            id::IMAGE_START_CAPTURE if p[2] == 1.0 => Action::Photo,
            id::DO_DIGICAM_CONTROL
            | id::IMAGE_START_CAPTURE
            | id::IMAGE_STOP_CAPTURE
            | id::VIDEO_START_CAPTURE
            | id::VIDEO_STOP_CAPTURE => Action::Camera,
            id::DO_SET_CAM_TRIGG_DIST => Action::Set(Setting::TriggerDistance),
            id::DO_MOUNT_CONTROL | id::DO_GIMBAL_MANAGER_PITCHYAW => Action::Set(Setting::Gimbal),
            id::DO_SET_ROI_LOCATION | id::DO_SET_ROI_NONE | id::DO_SET_ROI => {
                Action::Set(Setting::RegionOfInterest)
            }
            // Speed type 0 (airspeed) and 1 (ground speed) are the horizontal speed; -1 is "no
            // change" (MAVLink common.xml); ArduCopter and PX4 treat 0 and 1 alike.
            id::DO_CHANGE_SPEED if p[1] == -1.0 => Action::Other,
            id::DO_CHANGE_SPEED if p[0] == 2.0 || p[0] == 3.0 => Action::Set(Setting::ClimbSpeed),
            id::DO_CHANGE_SPEED => Action::Set(Setting::Speed),
            id::CONDITION_YAW => Action::Yaw {
                angle_deg: finite(p[0]).unwrap_or(0.0),
                rate_deg_s: finite(p[1]).filter(|r| *r > 0.0),
                relative: p[3] != 0.0 && p[3].is_finite(),
            },
            id::DO_SET_SERVO | id::DO_SET_RELAY | id::DO_GRIPPER | id::DO_WINCH => Action::Payload,
            id::NAV_DELAY => Action::Hold {
                duration_s: finite(p[0]).unwrap_or(0.0).max(0.0),
            },
            id::NAV_LOITER_TIME => Action::Hold {
                duration_s: finite(p[0]).unwrap_or(0.0).max(0.0),
            },
            _ => Action::Other,
        }
    }

    /// The setting this command changes, and what it leaves in force: None when it returns the
    /// setting to the vehicle's own (a speed of -2, the region of interest cleared, the trigger
    /// distance 0, the gimbal level and ahead).
    fn sets(&self) -> Option<(Setting, Option<Command>)> {
        let Action::Set(setting) = self.action() else {
            return None;
        };
        let p = &self.params;
        let cleared = match self.command {
            id::DO_CHANGE_SPEED => p[1] == -2.0,
            id::DO_SET_ROI_NONE => true,
            // DO_SET_ROI param1 is MAV_ROI: 0 MAV_ROI_NONE.
            id::DO_SET_ROI => p[0] == 0.0,
            id::DO_SET_CAM_TRIGG_DIST => p[0] == 0.0,
            // Level and ahead is where a gimbal rests: the vehicle's own.
            id::DO_MOUNT_CONTROL => p[0] == 0.0 && p[1] == 0.0 && p[2] == 0.0,
            id::DO_GIMBAL_MANAGER_PITCHYAW => p[0] == 0.0 && p[1] == 0.0,
            _ => false,
        };
        Some((setting, (!cleared).then(|| self.clone())))
    }

    /// A short description for plans and warnings (`photo`, `gimbal pitch -90 deg`).
    pub fn describe(&self) -> String {
        let p = &self.params;
        match (self.command, self.action()) {
            (_, Action::Photo) => "photo".into(),
            (id::DO_MOUNT_CONTROL, _) => format!("gimbal pitch {} deg yaw {} deg", p[0], p[2]),
            (id::DO_GIMBAL_MANAGER_PITCHYAW, _) => {
                format!("gimbal pitch {} deg yaw {} deg", p[0], p[1])
            }
            (id::DO_SET_ROI_LOCATION, _) => {
                format!("look at {:.6}, {:.6}, {} m", p[4], p[5], p[6])
            }
            (id::DO_SET_ROI, _) if p[0] != 0.0 => {
                format!("look at {:.6}, {:.6}, {} m", p[4], p[5], p[6])
            }
            (id::DO_SET_ROI_NONE | id::DO_SET_ROI, _) => "region of interest cleared".into(),
            (id::DO_SET_CAM_TRIGG_DIST, _) if p[0] == 0.0 => "camera trigger distance off".into(),
            (id::DO_SET_CAM_TRIGG_DIST, _) => format!("camera trigger every {} m", p[0]),
            (id::DO_CHANGE_SPEED, _) if p[1] == -2.0 => "speed back to the vehicle's".into(),
            (id::DO_CHANGE_SPEED, Action::Set(Setting::ClimbSpeed)) => {
                format!("vertical speed {} m/s", p[1])
            }
            (id::DO_CHANGE_SPEED, _) => format!("speed {} m/s", p[1]),
            (
                _,
                Action::Yaw {
                    angle_deg,
                    relative,
                    ..
                },
            ) => {
                if relative {
                    format!("yaw by {angle_deg} deg")
                } else {
                    format!("yaw to {angle_deg} deg")
                }
            }
            (id::NAV_DELAY | id::NAV_LOITER_TIME, Action::Hold { duration_s }) => {
                format!("hold {duration_s} s")
            }
            (id::DO_SET_SERVO, _) => format!("servo {} to {}", p[0], p[1]),
            (id::DO_SET_RELAY, _) => format!("relay {} to {}", p[0], p[1]),
            (id::DO_GRIPPER, _) => format!("gripper {} {}", p[0], p[1]),
            (id::DO_WINCH, _) => "winch".into(),
            (id::IMAGE_START_CAPTURE, _) => "image capture".into(),
            (id::IMAGE_STOP_CAPTURE, _) => "image capture stop".into(),
            (id::VIDEO_START_CAPTURE, _) => "video start".into(),
            (id::VIDEO_STOP_CAPTURE, _) => "video stop".into(),
            (id::DO_DIGICAM_CONTROL, _) => "camera control".into(),
            (c, _) => format!("command {c}"),
        }
    }
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.describe())
    }
}

/// A setting that stays in force until a later command changes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Setting {
    /// The horizontal speed (DO_CHANGE_SPEED, speed type 0 or 1).
    Speed,
    /// The climb or descent speed (DO_CHANGE_SPEED, speed type 2 or 3).
    ClimbSpeed,
    /// Where the vehicle and its camera look (DO_SET_ROI_LOCATION, DO_SET_ROI, DO_SET_ROI_NONE).
    RegionOfInterest,
    /// The camera's distance trigger (DO_SET_CAM_TRIGG_DIST).
    TriggerDistance,
    /// The gimbal's orientation (DO_MOUNT_CONTROL, DO_GIMBAL_MANAGER_PITCHYAW).
    Gimbal,
}

impl Setting {
    pub const ALL: [Setting; 5] = [
        Setting::Speed,
        Setting::ClimbSpeed,
        Setting::RegionOfInterest,
        Setting::TriggerDistance,
        Setting::Gimbal,
    ];

    fn index(self) -> usize {
        self as usize
    }

    /// The setting's name in plans and messages.
    pub fn name(self) -> &'static str {
        match self {
            Setting::Speed => "speed",
            Setting::ClimbSpeed => "climb speed",
            Setting::RegionOfInterest => "region of interest",
            Setting::TriggerDistance => "camera trigger distance",
            Setting::Gimbal => "gimbal",
        }
    }
}

/// What a command means to emplan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Action {
    /// One photo, taken at once: the autopilot does not wait for it.
    Photo,
    /// Another camera command (video, an interval capture, a camera setting).
    Camera,
    /// A change of a setting that stays in force.
    Set(Setting),
    /// CONDITION_YAW: turn to (or by) an angle at a rate (the autopilot's own when None).
    Yaw {
        angle_deg: f64,
        rate_deg_s: Option<f64>,
        relative: bool,
    },
    /// A servo, relay, gripper or winch: run at once, no wait.
    Payload,
    /// NAV_DELAY, or NAV_LOITER_TIME where the waypoint is: a hold at the place.
    Hold { duration_s: f64 },
    /// A command emplan keeps verbatim and does not otherwise understand.
    Other,
}

/// How a command read from a file is taken.
#[derive(Debug, Clone, PartialEq)]
pub enum Taken {
    /// A navigation command the mission model reads itself (take-off, waypoint, landing, ...).
    Navigation,
    /// An action that follows the navigation item before it.
    Action,
    /// An action kept verbatim that emplan does not understand (listed in one warning).
    Unknown,
    /// Refused: a reordered mission would break it; the reason.
    Refused(String),
}

/// How a mission file's command is taken: navigation (16, 19, 20, 21, 22, 82, 93 are read by the
/// mission model), an action, a command kept without being understood, or refused because it
/// moves the vehicle or changes the mission's flow.
pub fn take(command: u16) -> Taken {
    use id::*;
    match command {
        NAV_WAYPOINT | NAV_LOITER_TIME | NAV_RETURN_TO_LAUNCH | NAV_LAND | NAV_TAKEOFF
        | NAV_SPLINE_WAYPOINT | NAV_DELAY => Taken::Navigation,
        CONDITION_YAW
        | DO_CHANGE_SPEED
        | DO_SET_RELAY
        | DO_SET_SERVO
        | DO_SET_ROI_LOCATION
        | DO_SET_ROI_NONE
        | DO_SET_ROI
        | DO_DIGICAM_CONTROL
        | DO_MOUNT_CONTROL
        | DO_SET_CAM_TRIGG_DIST
        | DO_GRIPPER
        | DO_GIMBAL_MANAGER_PITCHYAW
        | IMAGE_START_CAPTURE
        | IMAGE_STOP_CAPTURE
        | VIDEO_START_CAPTURE
        | VIDEO_STOP_CAPTURE
        | DO_WINCH => Taken::Action,
        DO_JUMP | DO_JUMP_TAG | JUMP_TAG => Taken::Refused(
            "a jump repeats items by their place in the file, which another order moves".into(),
        ),
        DO_SET_MODE
        | DO_LAND_START
        | DO_RETURN_PATH_START
        | DO_GO_AROUND
        | DO_PAUSE_CONTINUE
        | DO_SET_MISSION_CURRENT
        | DO_FLIGHTTERMINATION => {
            Taken::Refused("it changes the mission's flow, which another order would break".into())
        }
        DO_SET_HOME | DO_REPOSITION | DO_SET_ROI_WPNEXT_OFFSET | NAV_SET_YAW_SPEED => {
            Taken::Refused("it moves the vehicle or its home, which emplan cannot reorder".into())
        }
        c if c <= NAV_LAST => Taken::Refused(
            "a navigation command emplan does not handle (allowed: 16 NAV_WAYPOINT, 19 \
             NAV_LOITER_TIME, 20 NAV_RETURN_TO_LAUNCH, 21 NAV_LAND, 22 NAV_TAKEOFF, 82 \
             NAV_SPLINE_WAYPOINT, 93 NAV_DELAY)"
                .into(),
        ),
        c if (CONDITION_FIRST..=CONDITION_LAST).contains(&c) => Taken::Refused(
            "a condition holds the mission until it is met, which another order changes (only \
             115 CONDITION_YAW is allowed)"
                .into(),
        ),
        _ => Taken::Unknown,
    }
}

/// The settings in force: for each [`Setting`], the command that set it (None: the vehicle's
/// own).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct State {
    set: [Option<Command>; 5],
}

impl State {
    /// The command in force for `setting` (None: the vehicle's own).
    pub fn get(&self, setting: Setting) -> Option<&Command> {
        self.set[setting.index()].as_ref()
    }

    /// The state after `commands` run, in order.
    pub fn after<'a>(&self, commands: impl IntoIterator<Item = &'a Command>) -> State {
        let mut state = self.clone();
        for c in commands {
            if let Some((setting, value)) = c.sets() {
                state.set[setting.index()] = value;
            }
        }
        state
    }

    /// The horizontal speed in force (m/s), None for the vehicle's own.
    pub fn speed_m_s(&self) -> Option<f64> {
        self.get(Setting::Speed)
            .map(|c| c.params[1])
            .filter(|v| v.is_finite() && *v > 0.0)
    }

    /// The settings that differ between `self` and `other`.
    pub fn differences(&self, other: &State) -> Vec<Setting> {
        Setting::ALL
            .into_iter()
            .filter(|s| self.get(*s) != other.get(*s))
            .collect()
    }
}

/// The command that puts `setting` back to `wanted` (None: the vehicle's own): the command that
/// set it, or the one that returns it to the vehicle's own (`default_speed_m_s`: the speed to
/// command for the vehicle's own; -2, "the vehicle's default" in MAVLink, where it is not known).
pub fn restoring(
    setting: Setting,
    wanted: Option<&Command>,
    default_speed_m_s: Option<f64>,
) -> Command {
    if let Some(c) = wanted {
        return c.clone();
    }
    match setting {
        Setting::Speed => Command::new(
            id::DO_CHANGE_SPEED,
            [
                1.0,
                default_speed_m_s.unwrap_or(-2.0),
                -1.0,
                0.0,
                0.0,
                0.0,
                0.0,
            ],
        ),
        Setting::ClimbSpeed => {
            Command::new(id::DO_CHANGE_SPEED, [2.0, -2.0, -1.0, 0.0, 0.0, 0.0, 0.0])
        }
        Setting::RegionOfInterest => Command::new(id::DO_SET_ROI_NONE, [0.0; 7]),
        Setting::TriggerDistance => Command::new(id::DO_SET_CAM_TRIGG_DIST, [0.0; 7]),
        // Level and ahead, in MAV_MOUNT_MODE_MAVLINK_TARGETING (2), as QGroundControl writes it.
        Setting::Gimbal => Command::new(id::DO_MOUNT_CONTROL, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0]),
    }
}

/// The time (s) the yaw actions among `actions` turn in hover, arriving on `arrival_heading_deg`
/// (degrees clockwise from north: the autopilots face their direction of travel, ArduCopter's
/// WP_YAW_BEHAVIOR 2 and PX4's MPC_YAW_MODE 0), each at its own rate or `default_rate_deg_s`:
/// an absolute yaw turns the shorter way to its heading, a relative one by its angle.
pub fn yaw_s(actions: &[Command], arrival_heading_deg: f64, default_rate_deg_s: f64) -> f64 {
    let mut heading = arrival_heading_deg;
    let mut total_s = 0.0;
    for c in actions {
        if let Action::Yaw {
            angle_deg,
            rate_deg_s,
            relative,
        } = c.action()
        {
            let turn_deg = if relative {
                heading += angle_deg;
                angle_deg.abs()
            } else {
                let d = (angle_deg - heading).rem_euclid(360.0);
                heading = angle_deg;
                d.min(360.0 - d)
            };
            let rate = rate_deg_s.unwrap_or(default_rate_deg_s).max(1e-3);
            total_s += turn_deg / rate;
        }
    }
    total_s
}

/// The states of a mission flown in its file's order: `before[k]` is in force on the way to
/// waypoint k (before its own actions), `after[k]` once its actions ran; `start` after the
/// start's actions; `end` after the last waypoint's (on the way home).
#[derive(Debug, Clone, PartialEq)]
pub struct FileStates {
    pub before: Vec<State>,
    pub after: Vec<State>,
    pub end: State,
}

/// The states in force along the file's order, from the start's actions and each waypoint's.
pub fn file_states<'a>(
    start: &[Command],
    waypoints: impl IntoIterator<Item = &'a [Command]>,
) -> FileStates {
    let mut state = State::default().after(start);
    let (mut before, mut after) = (Vec::new(), Vec::new());
    for actions in waypoints {
        before.push(state.clone());
        state = state.after(actions);
        after.push(state.clone());
    }
    FileStates {
        before,
        after,
        end: state,
    }
}

/// The commands to insert so that `order` (waypoint indices) flies every waypoint in the state
/// the file's order has there: `inserted[0]` goes after the start's actions, `inserted[i + 1]`
/// after the actions of `order[i]` (the last: before the way home, which is flown in the file's
/// last state). Each entry lists the restoring commands with the setting they restore.
pub fn restore(
    states: &FileStates,
    start: &State,
    actions: &[&[Command]],
    order: &[usize],
    default_speed_m_s: Option<f64>,
) -> Vec<Vec<(Setting, Command)>> {
    let mut out = Vec::with_capacity(order.len() + 1);
    let mut state = start.clone();
    let wanted_at = |i: usize| -> &State {
        match order.get(i) {
            Some(&k) => &states.before[k],
            None => &states.end,
        }
    };
    for i in 0..=order.len() {
        if i > 0 {
            state = state.after(actions[order[i - 1]]);
        }
        let wanted = wanted_at(i);
        let mut inserted = Vec::new();
        for setting in state.differences(wanted) {
            let command = restoring(setting, wanted.get(setting), default_speed_m_s);
            inserted.push((setting, command));
        }
        // The file's state, whatever the command restoring the vehicle's own speed says.
        state = wanted.clone();
        out.push(inserted);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn speed(v: f64) -> Command {
        Command::new(id::DO_CHANGE_SPEED, [1.0, v, -1.0, 0.0, 0.0, 0.0, 0.0])
    }
    fn roi(lat: f64) -> Command {
        Command {
            command: id::DO_SET_ROI_LOCATION,
            frame: FRAME_GLOBAL_RELATIVE_ALT,
            params: [0.0, 0.0, 0.0, 0.0, lat, -121.0, 5.0],
        }
    }
    fn roi_none() -> Command {
        Command::new(id::DO_SET_ROI_NONE, [0.0; 7])
    }
    fn photo() -> Command {
        Command::new(id::DO_DIGICAM_CONTROL, [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
    }
    fn gimbal(pitch: f64) -> Command {
        Command::new(id::DO_MOUNT_CONTROL, [pitch, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0])
    }
    fn trigger(d: f64) -> Command {
        Command::new(id::DO_SET_CAM_TRIGG_DIST, [d, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    }

    #[test]
    fn commands_are_taken_as_the_issue_lists_them() {
        for c in [
            203, 2000, 2001, 2500, 2501, 206, 205, 1000, 195, 197, 201, 115, 183, 181, 211, 42600,
            178,
        ] {
            assert_eq!(take(c), Taken::Action, "{c}");
        }
        for c in [16, 19, 20, 21, 22, 82, 93] {
            assert_eq!(take(c), Taken::Navigation, "{c}");
        }
        for c in [177, 112, 113, 114, 17, 18, 31, 189, 179, 192] {
            assert!(matches!(take(c), Taken::Refused(_)), "{c}");
        }
        for c in [184, 202, 2003, 530] {
            assert_eq!(take(c), Taken::Unknown, "{c}");
        }
    }

    #[test]
    fn a_photo_a_hold_and_a_yaw_mean_what_they_say() {
        assert_eq!(photo().action(), Action::Photo);
        let single = Command::new(
            id::IMAGE_START_CAPTURE,
            [0.0, 0.0, 1.0, 0.0, f64::NAN, f64::NAN, f64::NAN],
        );
        assert_eq!(single.action(), Action::Photo);
        let interval = Command::new(id::IMAGE_START_CAPTURE, [0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(interval.action(), Action::Camera);
        let delay = Command::new(id::NAV_DELAY, [7.5, -1.0, -1.0, -1.0, 0.0, 0.0, 0.0]);
        assert_eq!(delay.action(), Action::Hold { duration_s: 7.5 });
        let yaw = Command::new(id::CONDITION_YAW, [90.0, 30.0, 1.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(
            yaw.action(),
            Action::Yaw {
                angle_deg: 90.0,
                rate_deg_s: Some(30.0),
                relative: false
            }
        );
        assert_eq!(speed(-1.0).action(), Action::Other);
    }

    #[test]
    fn settings_stay_until_changed_and_clearing_returns_them_to_the_vehicles_own() {
        let s = State::default().after(&[speed(8.0), roi(38.0), photo()]);
        assert_eq!(s.speed_m_s(), Some(8.0));
        assert_eq!(s.get(Setting::RegionOfInterest), Some(&roi(38.0)));
        let s = s.after(&[roi_none(), speed(-2.0), trigger(0.0)]);
        assert_eq!(s, State::default());
        // "No change" changes nothing.
        let s = State::default().after(&[speed(6.0), speed(-1.0)]);
        assert_eq!(s.speed_m_s(), Some(6.0));
    }

    #[test]
    fn a_reversed_order_gets_the_files_state_back_on_the_way_to_each_waypoint() {
        // File: A (speed 8 after it), B (roi set), C (roi cleared).
        let actions: Vec<Vec<Command>> = vec![vec![speed(8.0)], vec![roi(38.0)], vec![roi_none()]];
        let refs: Vec<&[Command]> = actions.iter().map(Vec::as_slice).collect();
        let states = file_states(&[], refs.iter().copied());
        let inserted = restore(&states, &State::default(), &refs, &[2, 1, 0], Some(5.0));
        // On the way to C the file flies at 8 m/s with the ROI set.
        assert_eq!(inserted[0].len(), 2);
        // After C (ROI cleared) to B: the file has speed 8 and no ROI: nothing to do.
        assert!(inserted[1].is_empty());
        // After B (ROI set) to A: the file has neither: speed back to 5 m/s, ROI cleared.
        let settings: Vec<Setting> = inserted[2].iter().map(|(s, _)| *s).collect();
        assert_eq!(settings, vec![Setting::Speed, Setting::RegionOfInterest]);
        assert_eq!(inserted[2][0].1.params[1], 5.0);
        // After A (speed 8) home: the file ends with speed 8 and no ROI: nothing to do.
        assert!(inserted[3].is_empty());
    }

    fn command_strategy() -> impl Strategy<Value = Command> {
        prop_oneof![
            (1.0f64..15.0).prop_map(|v| speed((v * 2.0).round() / 2.0)),
            Just(speed(-2.0)),
            Just(speed(-1.0)),
            (0u8..3).prop_map(|k| roi(38.0 + f64::from(k))),
            Just(roi_none()),
            Just(photo()),
            (-90i8..0).prop_map(|p| gimbal(f64::from(p))),
            (0u8..3).prop_map(|d| trigger(f64::from(d) * 10.0)),
            Just(Command::new(
                id::CONDITION_YAW,
                [90.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
            )),
        ]
    }

    proptest! {
        /// In any order, the state in force on the way to each waypoint and while at it (after
        /// its own actions) equals the file's, and the way home is flown in the file's last
        /// state.
        #[test]
        fn every_order_flies_each_waypoint_in_the_files_state(
            start in prop::collection::vec(command_strategy(), 0..3),
            actions in prop::collection::vec(prop::collection::vec(command_strategy(), 0..4), 1..9),
            seed in any::<u64>(),
        ) {
            let n = actions.len();
            let mut order: Vec<usize> = (0..n).collect();
            // A permutation from the seed (Fisher-Yates with a small LCG).
            let mut x = seed;
            for i in (1..n).rev() {
                x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                order.swap(i, (x >> 33) as usize % (i + 1));
            }
            let refs: Vec<&[Command]> = actions.iter().map(Vec::as_slice).collect();
            let states = file_states(&start, refs.iter().copied());
            let start_state = State::default().after(&start);
            let inserted = restore(&states, &start_state, &refs, &order, None);
            prop_assert_eq!(inserted.len(), n + 1);
            // Fly the new order, command by command.
            let mut state = start_state.after(inserted[0].iter().map(|(_, c)| c));
            for (i, &k) in order.iter().enumerate() {
                prop_assert_eq!(&state, &states.before[k]);
                state = state.after(refs[k]);
                prop_assert_eq!(&state, &states.after[k]);
                state = state.after(inserted[i + 1].iter().map(|(_, c)| c));
            }
            prop_assert_eq!(&state, &states.end);
        }
    }
}
