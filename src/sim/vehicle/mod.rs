//! The simulated vehicle's MAVLink face, sans-IO: arming, flight modes and commands as PX4 or
//! ArduCopter handle them, the simulated [`Flight`] and [`battery`](super::battery) stepped in
//! simulated time, and the telemetry they report at PX4's default rates (or as a ground station
//! asked with MAV_CMD_SET_MESSAGE_INTERVAL), with telemetry faults.
//!
//! [`SimVehicle::handle`] answers COMMAND_LONG / COMMAND_INT / SET_MODE; [`SimVehicle::step`]
//! advances simulated time in 10 ms steps and returns what the vehicle sends; the caller (the
//! mock's async shell, or a test with a fake clock) moves the messages and keeps the clock.
//!
//! What each flavour does (sources in the comments where it happens):
//! - PX4: boots in AUTO.LOITER; arms in any mode and disarms on the ground after 10 s without
//!   taking off (COM_DISARM_PRFLT); MAV_CMD_MISSION_START switches to AUTO.MISSION and arms
//!   (commander `VEHICLE_CMD_MISSION_START`), DENIED without a valid mission; armed in
//!   AUTO.MISSION with a valid mission it spools up 1 s (COM_SPOOLUP_TIME) and flies;
//!   MISSION_CURRENT at 1 Hz and at once on a change, with total, mission_state (2 not started,
//!   3 active, 5 complete) and mission_mode (1 mission, 2 suspended) as
//!   mavlink_mission.cpp `update_mission_state` computes them; MISSION_ITEM_REACHED at once and
//!   repeated at 1 Hz up to 10 more times (mavlink_mission.cpp), never for the last waypoint
//!   before an RTL item (PX4 SITL: the RTL item completes at once and its reached message
//!   replaces the waypoint's; before a LAND item PX4 SITL does report it); EXTENDED_SYS_STATE
//!   ON_GROUND, TAKEOFF, IN_AIR, LANDING, ON_GROUND, with LANDING until the land detector
//!   confirms the landing about 1.2 s after ground contact, then the LAND item reached,
//!   mission complete and a disarm about 0.5 s later (all as measured on PX4 SITL SIH
//!   with sitl/px4_fly_land.py);
//!   BATTERY_STATUS as streams/BATTERY_STATUS.hpp encodes it (pack voltage in voltages[0],
//!   UINT16_MAX in the others, filtered current in cA, energy_consumed -1); HEARTBEAT for the
//!   HEARTBEAT stream only: SET_MESSAGE_INTERVAL on it FAILS, as PX4's mavlink receiver does.
//! - ArduPilot (ArduCopter): boots in STABILIZE; refuses to arm in AUTO, RTL and LAND ("Arm:
//!   Mode not armable", FAILED); MAV_CMD_MISSION_START (params 1 and 2 zero, else DENIED)
//!   switches to AUTO and sets auto-armed (GCS_MAVLINK_Copter::handle_MAV_CMD_MISSION_START),
//!   so the mission flies once armed in AUTO; one MISSION_ITEM_REACHED per item with STATUSTEXT
//!   "Reached command #N" for waypoints (mode_auto.cpp `verify_nav_wp`); disarms as soon as
//!   the land detector confirms the landing, 1 s after ground contact
//!   (LAND_DETECTOR_TRIGGER_SEC), without reporting the LAND item reached (`verify_land`);
//!   BATTERY_STATUS unfiltered with energy_consumed in hJ (GCS_Common.cpp
//!   `send_battery_status`); the mission total excludes home at seq 0.
//! - Photos (a mission's DO_DIGICAM_CONTROL or IMAGE_START_CAPTURE, `sim::flight`): ArduCopter
//!   with a camera (CAM1_TYPE set) sends one CAMERA_FEEDBACK per photo, where the vehicle is, its
//!   `img_idx` counting from 0 (AP_Camera_Backend `send_camera_feedback`; one per photo on
//!   ArduCopter SITL); PX4 sends CAMERA_TRIGGER and CAMERA_IMAGE_CAPTURED, both numbered by the
//!   trigger's sequence (mavlink streams CAMERA_TRIGGER.hpp and CAMERA_IMAGE_CAPTURED.hpp).
//!
//! The vehicle is cut as PX4 is: `mode` (the flight modes and their numbers), `commander`
//! (arming, mission start, mode changes, the automatic disarms), `progress` (the navigator's
//! mission progress: the current item, MISSION_CURRENT and MISSION_ITEM_REACHED), `streams`
//! (the MAVLink telemetry streams and their rates) and `params` (the parameter server). This file holds the vehicle's state, its
//! configuration and the step loop that drives the others.

mod commander;
mod mode;
mod params;
mod progress;
mod streams;
#[cfg(test)]
mod tests;

pub use mode::Mode;

use mavlink::MessageData;

use super::battery::{Monitor, Pack, Reading, SensorNoise};
use super::flight::{Flight, FlightError, Landed};
use crate::link::mav::{
    MavMessage, MavModeFlag, MissionState, ATTITUDE_DATA, COMMAND_ACK_DATA,
    GLOBAL_POSITION_INT_DATA, LOCAL_POSITION_NED_DATA, MISSION_ITEM_INT_DATA,
};
use crate::link::Flavour;
use crate::mission::Geodetic;
use crate::physics::{Profile, Vehicle};
use streams::Streams;

/// Simulation step (s): the battery monitor samples and the streams are scheduled on it.
pub const STEP_S: f64 = 0.01;

/// PX4 COM_DISARM_PRFLT and ArduCopter DISARM_DELAY: armed on the ground this long without
/// taking off, the vehicle disarms.
pub const PREFLIGHT_DISARM_S: f64 = 10.0;

/// The field the sample missions and both SITL setups use.
pub const DEFAULT_HOME: Geodetic = Geodetic {
    lat_deg: 38.5362,
    lon_deg: -121.7875,
    alt_m: 16.0,
};

/// A stretch of simulated time without any telemetry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gap {
    pub start_s: f64,
    pub duration_s: f64,
}

/// Faults in what the vehicle reports (transport faults are the mock shell's).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TelemetryFaults {
    /// Silence: nothing at all is sent during the gap.
    pub gap: Option<Gap>,
    /// From this simulated time on the battery reports its current as unknown (-1).
    pub unknown_current_after_s: Option<f64>,
    /// PX4 SITL's battery simulator: current -100 cA (a fake -1 A) and consumed charge running
    /// negative.
    pub px4_fake_current: bool,
}

/// How the simulated vehicle flies and reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlightConfig {
    /// Profile the legs are flown with (None: the vehicle's default, as planning uses).
    pub profile: Option<Profile>,
    /// Where the vehicle stands at boot.
    pub home: Geodetic,
    /// Battery state of charge at boot (0..1).
    pub state_of_charge: f64,
    pub noise: SensorNoise,
    /// Time constant of the battery current filter (None: none, as PX4 main and ArduPilot;
    /// PX4 up to v1.14 filtered with 0.5 s, see `battery`).
    pub current_filter_s: Option<f64>,
    pub faults: TelemetryFaults,
    /// Seed of the sensor noise.
    pub seed: u64,
    /// A steady wind the vehicle flies in and reports (PX4: WIND_COV, ArduPilot: WIND); None:
    /// still air and no wind estimate, as an autopilot whose estimator does not run one.
    pub wind: Option<crate::physics::Wind>,
    /// The wind changes (and is reported changed) this long after the first arming.
    pub wind_change: Option<WindChange>,
    /// The camera misses this photo (0 the first the mission takes): it is neither taken nor
    /// reported, as a camera that did not fire.
    pub missed_photo: Option<u32>,
    /// The serial number its smart battery gives in SMART_BATTERY_INFO when asked (None: no
    /// smart battery, and the request fails, as PX4's `MavlinkReceiver` answers when the stream
    /// has nothing to send).
    pub pack_serial: Option<u32>,
}

/// A change of the wind in flight: `after_armed_s` after the first arming, the vehicle flies
/// in (and reports) `wind`. Written `T_S=SPEED@FROM_DEG` (`60=8@270`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindChange {
    pub after_armed_s: f64,
    pub wind: crate::physics::Wind,
}

/// Why a change of wind was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WindChangeError {
    #[error("{0:?}: expected T_S=SPEED@FROM_DEG, e.g. 60=8@270")]
    Usage(String),
    #[error("{0:?}: not a number of seconds")]
    Seconds(String),
    #[error("{0:?}: seconds after arming must be 0 or more")]
    Before(String),
    #[error(transparent)]
    Wind(#[from] crate::mission::wind::WindError),
}

impl std::str::FromStr for WindChange {
    type Err = WindChangeError;

    fn from_str(s: &str) -> Result<WindChange, WindChangeError> {
        let (t, wind) = s
            .split_once('=')
            .ok_or_else(|| WindChangeError::Usage(s.to_string()))?;
        let after_armed_s: f64 = t
            .trim()
            .parse()
            .map_err(|_| WindChangeError::Seconds(t.to_string()))?;
        if !(after_armed_s.is_finite() && after_armed_s >= 0.0) {
            return Err(WindChangeError::Before(t.to_string()));
        }
        Ok(WindChange {
            after_armed_s,
            wind: wind.trim().parse()?,
        })
    }
}

impl Default for FlightConfig {
    fn default() -> Self {
        FlightConfig {
            profile: None,
            home: DEFAULT_HOME,
            state_of_charge: 1.0,
            noise: SensorNoise::default(),
            current_filter_s: None,
            faults: TelemetryFaults::default(),
            seed: 1,
            wind: None,
            wind_change: None,
            missed_photo: None,
            pack_serial: None,
        }
    }
}

/// The simulated vehicle's state at one instant (for the mock's handle and tests).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Snapshot {
    pub time_s: f64,
    pub armed: bool,
    /// Times armed since boot.
    pub arms: u32,
    pub mode: Mode,
    pub landed: Landed,
    /// East, north, up from home (m).
    pub position: [f64; 3],
    /// The item being flown.
    pub current: Option<u16>,
    /// Whether the stored mission has been flown to its end.
    pub mission_complete: bool,
    pub battery: Reading,
}

/// The simulated vehicle.
#[derive(Debug, Clone)]
pub struct SimVehicle<'v> {
    flavour: Flavour,
    system_id: u8,
    component_id: u8,
    config: FlightConfig,
    flight: Flight<'v>,
    pack: Pack<'v>,
    monitor: Monitor,
    /// Simulation steps since boot (time is `step * STEP_S`, counted, so it never drifts).
    step: u64,
    now_s: f64,
    mode: Mode,
    /// ArduCopter's auto-armed flag (MISSION_START): AUTO flies only with it.
    auto_armed: bool,
    mission: Vec<MISSION_ITEM_INT_DATA>,
    /// Where the mission resumes (MISSION_SET_CURRENT, or the item being flown).
    mission_current: u16,
    /// The mission server's current item last seen (a change is a MISSION_SET_CURRENT).
    server_current: u16,
    mission_finished: bool,
    /// The navigator's last reached item (PX4 mission_result.seq_reached).
    seq_reached: Option<u16>,
    /// The last reached item sent, and how often it was repeated (PX4 mavlink mission manager).
    reached_sent: Option<u16>,
    reached_repeats: u32,
    /// PX4 mission_state, kept between updates as PX4 keeps it.
    mission_state: MissionState,
    /// The waypoint PX4 never reports reached (the last before an RTL item).
    silent_reached: Option<u16>,
    streams: Streams,
    /// Next 1 Hz tick of PX4's mission manager (repeats of MISSION_ITEM_REACHED).
    slow_next_step: u64,
    idle_since_s: Option<f64>,
    /// Times armed since boot, and when first.
    arms: u32,
    first_armed_s: Option<f64>,
    /// When the land detector confirmed a landing (the disarm follows).
    landed_s: Option<f64>,
    heading_rad: f64,
    /// Photos the mission asked for so far (the camera's trigger count), and taken.
    photos_asked: u32,
    photos_taken: u32,
    /// The parameters it answers: a PX4's trajectory parameters (the vehicle's [px4] section,
    /// by PX4 name) or an ArduPilot's navigation parameters ([ardupilot], by ArduCopter name),
    /// and either flavour's return altitude (`link::params::ReturnAltitude`).
    params: Vec<(&'static str, f64)>,
    /// The rally points it holds (east, north of home; m): where its return may go.
    rally: Vec<[f64; 2]>,
    out: Vec<MavMessage>,
}

impl<'v> SimVehicle<'v> {
    /// A vehicle of `flavour` standing disarmed at the configured home, flying `vehicle`'s
    /// physics. `ids` are its MAVLink system and component ids.
    pub fn new(
        flavour: Flavour,
        vehicle: &'v Vehicle,
        config: FlightConfig,
        ids: (u8, u8),
    ) -> Result<SimVehicle<'v>, FlightError> {
        // Each flavour flies as its autopilot does unless told otherwise.
        let profile = config.profile.unwrap_or(match flavour {
            Flavour::ArduPilot => crate::physics::Profile::Ardupilot,
            Flavour::Px4 | Flavour::Generic => vehicle.default_profile(),
        });
        let filter_s = config.current_filter_s.unwrap_or(0.0);
        Ok(SimVehicle {
            flavour,
            system_id: ids.0,
            component_id: ids.1,
            config,
            // Ground contact to a confirmed landing: PX4 SITL 1.1-1.3 s (measured), ArduCopter
            // LAND_DETECTOR_TRIGGER_SEC 1 s.
            flight: match flavour {
                Flavour::Px4 | Flavour::Generic => Flight::new(vehicle, profile)?
                    .with_land_detection(1.2)
                    .with_instant_rtl_item(),
                Flavour::ArduPilot => Flight::new(vehicle, profile)?
                    .with_land_detection(crate::physics::ardupilot::LAND_DETECTOR_TRIGGER_S),
            }
            .with_wind(config.wind.unwrap_or_default())?,
            pack: Pack::new(vehicle, config.state_of_charge),
            monitor: Monitor::new(config.noise, filter_s, config.seed),
            step: 0,
            now_s: 0.0,
            mode: match flavour {
                Flavour::Px4 | Flavour::Generic => Mode::Hold,
                Flavour::ArduPilot => Mode::Stabilized,
            },
            auto_armed: false,
            mission: Vec::new(),
            mission_current: 0,
            server_current: 0,
            mission_finished: false,
            seq_reached: None,
            reached_sent: None,
            reached_repeats: 0,
            mission_state: MissionState::MISSION_STATE_NO_MISSION,
            silent_reached: None,
            streams: streams::schedule(flavour),
            slow_next_step: 1,
            idle_since_s: None,
            arms: 0,
            first_armed_s: None,
            landed_s: None,
            heading_rad: 0.0,
            photos_asked: 0,
            photos_taken: 0,
            params: params::held(flavour, vehicle),
            rally: Vec::new(),
            out: Vec::new(),
        })
    }

    /// Holds `rally` as its rally points (the uploaded MISSION_TYPE_RALLY items): its return
    /// goes to one of them when its autopilot's rule says so (`mission::fence::ReturnRule`).
    pub fn set_rally_points(&mut self, rally: &[crate::mission::fence::RallyPoint]) {
        let home = crate::mission::Origin {
            home: self.config.home,
            height_above_home_m: 0.0,
        };
        self.rally = rally
            .iter()
            .map(|r| {
                let e = r.local(&home);
                [e.x_east_m, e.y_north_m]
            })
            .collect();
    }

    /// Where its return goes from where it is now, by its flavour's rule and the parameters it
    /// holds, and that place (east, north of home).
    pub fn return_destination(&self) -> (crate::mission::fence::Destination, [f64; 2]) {
        let name = match self.flavour {
            Flavour::ArduPilot => "ardupilot",
            Flavour::Px4 => "px4",
            Flavour::Generic => "generic",
        };
        let rule = crate::mission::fence::ReturnRule::default_for(name)
            .with_params(&|n: &str| self.param(n));
        let p = self.flight.position();
        let here = [p[0], p[1]];
        let to = rule.destination([0.0, 0.0], &self.rally, here);
        (to, to.at([0.0, 0.0], &self.rally, here))
    }

    /// Simulated time (s since boot).
    pub fn now_s(&self) -> f64 {
        self.now_s
    }

    /// Whether the motors are armed.
    pub fn armed(&self) -> bool {
        self.flight.armed()
    }

    /// The flight mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// The simulated flight (position, landed state, progress).
    pub fn flight(&self) -> &Flight<'v> {
        &self.flight
    }

    /// The battery monitor's latest reading.
    pub fn battery(&self) -> Reading {
        self.monitor.reading()
    }

    /// The stored mission the vehicle flies.
    pub fn mission(&self) -> &[MISSION_ITEM_INT_DATA] {
        &self.mission
    }

    /// The state now.
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            time_s: self.now_s,
            armed: self.flight.armed(),
            arms: self.arms,
            mode: self.mode,
            landed: self.flight.landed(),
            position: self.flight.position(),
            current: self.flight.current(),
            mission_complete: self.mission_finished,
            battery: self.monitor.reading(),
        }
    }

    /// Reacts to a message from `(system, component)`: commands get a COMMAND_ACK, SET_MODE
    /// changes the mode; everything else is not the vehicle's business.
    #[allow(deprecated)] // SET_MODE: superseded, still handled by PX4 and ArduPilot
    pub fn handle(&mut self, from: (u8, u8), message: &MavMessage) -> Vec<MavMessage> {
        let (command, params, target) = match message {
            MavMessage::COMMAND_LONG(c) => (
                c.command,
                [
                    c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7,
                ],
                (c.target_system, c.target_component),
            ),
            MavMessage::COMMAND_INT(c) => (
                c.command,
                [
                    c.param1, c.param2, c.param3, c.param4, c.x as f32, c.y as f32, c.z,
                ],
                (c.target_system, c.target_component),
            ),
            MavMessage::SET_MODE(m) => {
                if m.target_system == self.system_id
                    && m.base_mode
                        .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
                {
                    if let Some(mode) = Mode::from_custom(self.flavour, m.custom_mode) {
                        self.set_mode(mode);
                    }
                }
                return self.take_out();
            }
            MavMessage::PARAM_REQUEST_READ(r) => return self.param_value(from, r),
            _ => return Vec::new(),
        };
        let for_us = (target.0 == 0 || target.0 == self.system_id)
            && (target.1 == 0 || target.1 == self.component_id);
        if !for_us {
            return Vec::new();
        }
        let result = self.command(command, params);
        self.out.push(MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command,
            result,
            progress: 0,
            result_param2: 0,
            target_system: from.0,
            target_component: from.1,
        }));
        self.take_out()
    }

    pub(super) fn take_out(&mut self) -> Vec<MavMessage> {
        let out = std::mem::take(&mut self.out);
        if self.silent(self.now_s) {
            return Vec::new();
        }
        out
    }

    pub(super) fn silent(&self, t_s: f64) -> bool {
        self.config
            .faults
            .gap
            .is_some_and(|g| t_s >= g.start_s && t_s < g.start_s + g.duration_s)
    }

    /// The configured change of wind, once its time after the first arming has come.
    fn change_wind(&mut self, t: f64) {
        let (Some(change), Some(armed_s)) = (self.config.wind_change, self.first_armed_s) else {
            return;
        };
        if t - armed_s < change.after_armed_s {
            return;
        }
        self.config.wind_change = None;
        match self.flight.set_wind(change.wind) {
            Ok(()) => self.config.wind = Some(change.wind),
            Err(e) => tracing::warn!("the mock cannot fly in the changed wind: {e}"),
        }
    }

    /// Advances simulated time to `now_s` in steps of [`STEP_S`] and returns what the vehicle
    /// sends meanwhile (in time order).
    pub fn step(&mut self, now_s: f64) -> Vec<MavMessage> {
        let mut sent = Vec::new();
        while (self.step + 1) as f64 * STEP_S <= now_s + 1e-9 {
            self.step += 1;
            let t = self.step as f64 * STEP_S;
            self.tick(t);
            let out = std::mem::take(&mut self.out);
            if !self.silent(t) {
                sent.extend(out);
            }
        }
        sent
    }

    fn tick(&mut self, t: f64) {
        self.now_s = t;
        self.change_wind(t);
        let events = self.flight.advance(t);
        let power_w = self.flight.power_w();
        let draw = self.pack.draw(power_w, STEP_S);
        self.monitor
            .sample(draw, STEP_S, self.pack.state_of_charge());
        let v = self.flight.velocity();
        if v[0].hypot(v[1]) > 0.5 {
            self.heading_rad = v[0].atan2(v[1]);
        }
        // Timed streams first, then the events of this step, then the others.
        let step = self.step;
        let due = self.due_streams(step);
        let timed = [
            GLOBAL_POSITION_INT_DATA::ID,
            LOCAL_POSITION_NED_DATA::ID,
            ATTITUDE_DATA::ID,
        ];
        for &id in due.iter().filter(|id| timed.contains(id)) {
            self.send_stream(id, t);
        }
        self.events(&events);
        self.timers(t);
        for &id in due.iter().filter(|id| !timed.contains(id)) {
            self.send_stream(id, t);
        }
        self.repeat_reached(step);
    }
}
#[test]
fn a_wind_change_is_read_as_seconds_after_arming_and_the_new_wind() {
    let change: WindChange = "60=8@270".parse().expect("a change");
    assert_eq!(change.after_armed_s, 60.0);
    assert_eq!(change.wind, crate::physics::Wind::new(8.0, 270.0).unwrap());
    for bad in ["8@270", "-1=8@270", "x=8@270", "60=8"] {
        assert!(bad.parse::<WindChange>().is_err(), "{bad}");
    }
}
