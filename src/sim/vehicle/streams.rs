//! The MAVLink telemetry streams: which messages go out at which default rate per flavour,
//! MAV_CMD_SET_MESSAGE_INTERVAL and MAV_CMD_REQUEST_MESSAGE, and each message encoded from the
//! flight and the battery monitor (units converted at this edge, telemetry faults applied).

use mavlink::MessageData;

use super::mode::Mode;
use super::{SimVehicle, STEP_S};

use crate::link::mav::{
    CameraFeedbackFlags, MavAutopilot, MavBatteryChargeState, MavBatteryFunction, MavBatteryType,
    MavBool, MavLandedState, MavMessage, MavModeFlag, MavResult, MavState, MavSysStatusSensor,
    MavType, MavVtolState, ATTITUDE_DATA, BATTERY_STATUS_DATA, CAMERA_FEEDBACK_DATA,
    CAMERA_IMAGE_CAPTURED_DATA, CAMERA_TRIGGER_DATA, EXTENDED_SYS_STATE_DATA,
    GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA, HOME_POSITION_DATA, LOCAL_POSITION_NED_DATA,
    MISSION_CURRENT_DATA, SYS_STATUS_DATA, WIND_COV_DATA, WIND_DATA,
};
use crate::link::Flavour;
use crate::mission::{Enu, Origin};
use crate::sim::battery::Reading;
use crate::sim::flight::Landed;

/// One telemetry stream: message id, interval in simulation steps (None: off), the flavour's
/// default, and the step it is next due at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Stream {
    pub(super) id: u32,
    pub(super) default_steps: Option<u64>,
    pub(super) interval_steps: Option<u64>,
    pub(super) next_step: u64,
}

/// A duration as a whole number of simulation steps (at least one, at most about 300 years).
pub(super) fn steps(duration_s: f64) -> u64 {
    (duration_s / STEP_S).round().clamp(1.0, 1e12) as u64
}

/// Streams the vehicle can send, in the order they go out within a step (messages carrying
/// `time_boot_ms` first, so a ground station stamping the others from them sees a fresh time).
const STREAM_IDS: [u32; 11] = [
    GLOBAL_POSITION_INT_DATA::ID,
    LOCAL_POSITION_NED_DATA::ID,
    ATTITUDE_DATA::ID,
    HEARTBEAT_DATA::ID,
    SYS_STATUS_DATA::ID,
    BATTERY_STATUS_DATA::ID,
    EXTENDED_SYS_STATE_DATA::ID,
    MISSION_CURRENT_DATA::ID,
    HOME_POSITION_DATA::ID,
    WIND_COV_DATA::ID,
    WIND_DATA::ID,
];

/// Default interval of a stream per flavour. PX4: its SITL GCS link (px4-rc.mavlink: position
/// 50 Hz) and the normal mode's 1 Hz status streams, BATTERY_STATUS 0.5 Hz, MISSION_CURRENT
/// 1 Hz (mavlink_mission.cpp `_slow_rate_limiter`); ATTITUDE off until asked (it carries nothing
/// the flight log uses). ArduPilot: approximate ArduCopter SRx defaults (position 3 Hz, status
/// and battery 2 Hz).
fn default_interval_s(flavour: Flavour, id: u32) -> Option<f64> {
    let hz = match (flavour, id) {
        (_, HEARTBEAT_DATA::ID) => 1.0,
        (
            Flavour::Px4 | Flavour::Generic,
            GLOBAL_POSITION_INT_DATA::ID | LOCAL_POSITION_NED_DATA::ID,
        ) => 50.0,
        (Flavour::Px4 | Flavour::Generic, BATTERY_STATUS_DATA::ID) => 0.5,
        (Flavour::Px4 | Flavour::Generic, SYS_STATUS_DATA::ID | EXTENDED_SYS_STATE_DATA::ID) => 1.0,
        (Flavour::Px4 | Flavour::Generic, MISSION_CURRENT_DATA::ID) => 1.0,
        // PX4's normal mode streams HOME_POSITION at 0.5 Hz (mavlink_main.cpp); ArduCopter
        // sends it when home is set, not as a stream (twice in an ArduCopter SITL flight log).
        (Flavour::Px4 | Flavour::Generic, HOME_POSITION_DATA::ID) => 0.5,
        // PX4's WIND_COV (from its wind estimate, 0.5-1 Hz); ArduPilot sends WIND instead.
        (Flavour::Px4 | Flavour::Generic, WIND_COV_DATA::ID) => 1.0,
        (Flavour::Px4 | Flavour::Generic, WIND_DATA::ID)
        | (Flavour::ArduPilot, WIND_COV_DATA::ID) => return None,
        (Flavour::ArduPilot, GLOBAL_POSITION_INT_DATA::ID | LOCAL_POSITION_NED_DATA::ID) => 3.0,
        (Flavour::ArduPilot, _) if id != ATTITUDE_DATA::ID && id != HOME_POSITION_DATA::ID => 2.0,
        _ => return None,
    };
    Some(1.0 / hz)
}

/// Every stream at `flavour`'s default interval, each first due at the first step.
pub(super) fn schedule(flavour: Flavour) -> Streams {
    STREAM_IDS.map(|id| {
        let default_steps = default_interval_s(flavour, id).map(steps);
        Stream {
            id,
            default_steps,
            interval_steps: default_steps,
            next_step: 1,
        }
    })
}

/// The vehicle's streams, in the order of [`STREAM_IDS`].
pub(super) type Streams = [Stream; STREAM_IDS.len()];

impl<'v> SimVehicle<'v> {
    /// MAV_CMD_SET_MESSAGE_INTERVAL: param1 message id, param2 interval in us (-1 off, 0 the
    /// default). PX4 refuses the HEARTBEAT and messages it has no stream for (FAILED).
    pub(super) fn set_interval(&mut self, id: f32, interval_us: f32) -> MavResult {
        let failed = MavResult::MAV_RESULT_FAILED;
        if !id.is_finite() || !interval_us.is_finite() || interval_us < -1.0 {
            return failed;
        }
        let id = id as u32;
        if self.flavour == Flavour::Px4 && id == HEARTBEAT_DATA::ID {
            return failed;
        }
        let step = self.step;
        let Some(stream) = self.streams.iter_mut().find(|s| s.id == id) else {
            return failed;
        };
        stream.interval_steps = if interval_us == -1.0 {
            None
        } else if interval_us == 0.0 {
            stream.default_steps
        } else {
            Some(steps(f64::from(interval_us) * 1e-6))
        };
        // Scheduled on multiples of the interval since boot, so streams of the same rate go out
        // in the same step, the timed ones (positions) first: a ground station stamping an
        // untimed message (BATTERY_STATUS has no time field) by the latest timed one then
        // stamps it exactly, even when a speed-up delivers a burst of steps at once.
        stream.next_step = match stream.interval_steps {
            Some(interval) if interval > 0 => (step / interval + 1) * interval,
            _ => step + 1,
        };
        MavResult::MAV_RESULT_ACCEPTED
    }

    pub(super) fn send_stream(&mut self, id: u32, t: f64) {
        let message = match id {
            HEARTBEAT_DATA::ID => self.heartbeat(),
            GLOBAL_POSITION_INT_DATA::ID => self.global_position(t),
            LOCAL_POSITION_NED_DATA::ID => {
                let (p, v) = (self.flight.position(), self.flight.velocity());
                MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
                    time_boot_ms: boot_ms(t),
                    x: p[1] as f32,
                    y: p[0] as f32,
                    z: -p[2] as f32,
                    vx: v[1] as f32,
                    vy: v[0] as f32,
                    vz: -v[2] as f32,
                })
            }
            ATTITUDE_DATA::ID => MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms: boot_ms(t),
                yaw: self.heading_rad as f32,
                ..Default::default()
            }),
            SYS_STATUS_DATA::ID => self.sys_status(t),
            BATTERY_STATUS_DATA::ID => self.battery_status(t),
            EXTENDED_SYS_STATE_DATA::ID => {
                MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
                    vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
                    landed_state: match self.flight.landed() {
                        Landed::OnGround => MavLandedState::MAV_LANDED_STATE_ON_GROUND,
                        Landed::Takeoff => MavLandedState::MAV_LANDED_STATE_TAKEOFF,
                        Landed::InAir => MavLandedState::MAV_LANDED_STATE_IN_AIR,
                        Landed::Landing => MavLandedState::MAV_LANDED_STATE_LANDING,
                    },
                })
            }
            MISSION_CURRENT_DATA::ID => self.mission_current_message(),
            HOME_POSITION_DATA::ID => {
                let home = self.config.home;
                MavMessage::HOME_POSITION(HOME_POSITION_DATA {
                    latitude: (home.lat_deg * 1e7).round() as i32,
                    longitude: (home.lon_deg * 1e7).round() as i32,
                    altitude: (home.alt_m * 1000.0).round() as i32,
                    q: [1.0, 0.0, 0.0, 0.0],
                    ..Default::default()
                })
            }
            // Only a vehicle told its wind estimates one (PX4: EKF2 with drag fusion;
            // ArduPilot: EK3 drag): without, no message, as theirs.
            WIND_COV_DATA::ID => {
                let Some(wind) = self.config.wind else { return };
                let (east, north) = wind.velocity_en_m_s();
                MavMessage::WIND_COV(WIND_COV_DATA {
                    time_usec: (t * 1e6) as u64,
                    wind_x: north as f32,
                    wind_y: east as f32,
                    wind_z: 0.0,
                    // PX4 puts the variance north + east here ((m/s)^2).
                    var_horiz: 0.01,
                    var_vert: 0.0,
                    wind_alt: (self.config.home.alt_m + self.flight.position()[2]) as f32,
                    horiz_accuracy: 0.0,
                    vert_accuracy: 0.0,
                })
            }
            WIND_DATA::ID => {
                let Some(wind) = self.config.wind else { return };
                MavMessage::WIND(WIND_DATA {
                    direction: wind.from_deg as f32,
                    speed: wind.speed_m_s as f32,
                    speed_z: 0.0,
                })
            }
            _ => return,
        };
        self.out.push(message);
    }

    pub(super) fn heartbeat(&self) -> MavMessage {
        let armed = self.flight.armed();
        let mut base_mode = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
        match self.flavour {
            Flavour::Px4 | Flavour::Generic => {
                if matches!(
                    self.mode,
                    Mode::Hold | Mode::Mission | Mode::Takeoff | Mode::Land | Mode::Rtl
                ) {
                    base_mode |= MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED
                        | MavModeFlag::MAV_MODE_FLAG_GUIDED_ENABLED
                        | MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED;
                }
            }
            // GCS_MAVLINK_Copter::base_mode.
            Flavour::ArduPilot => {
                base_mode |= MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED
                    | MavModeFlag::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED;
            }
        }
        if armed {
            base_mode |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
        }
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: self.mode.custom_mode(self.flavour),
            mavtype: MavType::MAV_TYPE_OCTOROTOR,
            autopilot: match self.flavour {
                Flavour::Px4 | Flavour::Generic => MavAutopilot::MAV_AUTOPILOT_PX4,
                Flavour::ArduPilot => MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
            },
            base_mode,
            system_status: if armed {
                MavState::MAV_STATE_ACTIVE
            } else {
                MavState::MAV_STATE_STANDBY
            },
            mavlink_version: 3,
        })
    }

    /// Where the vehicle is, on the WGS84 ellipsoid.
    fn geodetic_here(&self) -> crate::mission::Geodetic {
        let p = self.flight.position();
        Origin {
            home: self.config.home,
            height_above_home_m: 0.0,
        }
        .to_geodetic(Enu {
            x_east_m: p[0],
            y_north_m: p[1],
            z_up_m: p[2],
        })
    }

    pub(super) fn global_position(&self, t: f64) -> MavMessage {
        let v = self.flight.velocity();
        let home = self.config.home;
        let g = self.geodetic_here();
        let cm_s = |x: f64| (x * 100.0).round().clamp(-32767.0, 32767.0) as i16;
        let heading_cdeg = self.heading_rad.to_degrees().rem_euclid(360.0) * 100.0;
        MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            time_boot_ms: boot_ms(t),
            lat: (g.lat_deg * 1e7).round() as i32,
            lon: (g.lon_deg * 1e7).round() as i32,
            alt: (g.alt_m * 1000.0).round() as i32,
            relative_alt: ((g.alt_m - home.alt_m) * 1000.0).round() as i32,
            vx: cm_s(v[1]),
            vy: cm_s(v[0]),
            vz: cm_s(-v[2]),
            hdg: (heading_cdeg.round() as u16) % 36000,
        })
    }

    /// A photo taken now, where the vehicle is: what the flavour sends (see the module doc of
    /// `vehicle`). The configured missed photo is neither taken nor sent.
    pub(super) fn photo(&mut self) {
        let asked = self.photos_asked;
        self.photos_asked = self.photos_asked.saturating_add(1);
        if self.config.missed_photo == Some(asked) {
            return;
        }
        let index = self.photos_taken;
        self.photos_taken = self.photos_taken.saturating_add(1);
        let home = self.config.home;
        let g = self.geodetic_here();
        let (lat, lon) = (
            (g.lat_deg * 1e7).round() as i32,
            (g.lon_deg * 1e7).round() as i32,
        );
        let t = self.now_s;
        let time_usec = (t * 1e6).round() as u64;
        match self.flavour {
            Flavour::ArduPilot => {
                self.out
                    .push(MavMessage::CAMERA_FEEDBACK(CAMERA_FEEDBACK_DATA {
                        time_usec,
                        target_system: 0,
                        cam_idx: 0,
                        img_idx: (index % (u32::from(u16::MAX) + 1)) as u16,
                        lat,
                        lng: lon,
                        alt_msl: g.alt_m as f32,
                        alt_rel: (g.alt_m - home.alt_m) as f32,
                        roll: 0.0,
                        pitch: 0.0,
                        yaw: self.heading_rad.to_degrees().rem_euclid(360.0) as f32,
                        foc_len: 0.0,
                        flags: CameraFeedbackFlags::CAMERA_FEEDBACK_PHOTO,
                        completed_captures: (index.saturating_add(1) % (u32::from(u16::MAX) + 1))
                            as u16,
                    }));
            }
            Flavour::Px4 | Flavour::Generic => {
                self.out
                    .push(MavMessage::CAMERA_TRIGGER(CAMERA_TRIGGER_DATA {
                        time_usec,
                        seq: index,
                    }));
                self.out.push(MavMessage::CAMERA_IMAGE_CAPTURED(
                    CAMERA_IMAGE_CAPTURED_DATA {
                        time_boot_ms: boot_ms(t),
                        lat,
                        lon,
                        alt: (g.alt_m * 1000.0).round() as i32,
                        relative_alt: ((g.alt_m - home.alt_m) * 1000.0).round() as i32,
                        q: [1.0, 0.0, 0.0, 0.0],
                        image_index: i32::try_from(index).unwrap_or(i32::MAX),
                        camera_id: 1,
                        capture_result: MavBool::MAV_BOOL_TRUE,
                        ..Default::default()
                    },
                ));
            }
        }
    }

    /// Current (cA) and consumed charge (mAh) as the battery reports them now, faults applied.
    pub(super) fn reported_current(&self, t: f64, reading: &Reading) -> (i16, i32) {
        let faults = self.config.faults;
        if faults.px4_fake_current {
            // PX4 SITL battery simulator: -1 A, summed into a negative consumed charge.
            return (-100, (-t / 3.6) as i32);
        }
        if faults
            .unknown_current_after_s
            .is_some_and(|after| t >= after)
        {
            return (-1, -1);
        }
        let ca = (reading.current_a * 100.0).round().clamp(-32767.0, 32767.0) as i16;
        (ca, reading.consumed_mah as i32)
    }

    pub(super) fn sys_status(&self, t: f64) -> MavMessage {
        let reading = self.monitor.reading();
        let (current, _) = self.reported_current(t, &reading);
        let sensors = MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_GYRO
            | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_ACCEL
            | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_3D_MAG
            | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
            | MavSysStatusSensor::MAV_SYS_STATUS_SENSOR_GPS;
        MavMessage::SYS_STATUS(SYS_STATUS_DATA {
            onboard_control_sensors_present: sensors,
            onboard_control_sensors_enabled: sensors,
            onboard_control_sensors_health: sensors,
            voltage_battery: millivolts(reading.voltage_v),
            current_battery: current,
            battery_remaining: percent(reading.remaining),
            ..Default::default()
        })
    }

    pub(super) fn battery_status(&self, t: f64) -> MavMessage {
        let reading = self.monitor.reading();
        let (current, consumed) = self.reported_current(t, &reading);
        let mut voltages = [u16::MAX; 10];
        voltages[0] = millivolts(reading.voltage_v);
        let (function, kind, energy) = match self.flavour {
            Flavour::Px4 | Flavour::Generic => (
                MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
                MavBatteryType::MAV_BATTERY_TYPE_LIPO,
                -1,
            ),
            Flavour::ArduPilot => (
                MavBatteryFunction::MAV_BATTERY_FUNCTION_UNKNOWN,
                MavBatteryType::MAV_BATTERY_TYPE_UNKNOWN,
                if current == -1 {
                    -1
                } else {
                    (reading.consumed_wh * 36.0) as i32
                },
            ),
        };
        MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
            current_consumed: consumed,
            energy_consumed: energy,
            temperature: i16::MAX,
            voltages,
            current_battery: current,
            id: 0,
            battery_function: function,
            mavtype: kind,
            battery_remaining: percent(reading.remaining),
            time_remaining: 0,
            charge_state: MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_OK,
            voltages_ext: [0; 4],
            ..Default::default()
        })
    }

    /// The streams due at `step`, each scheduled again one interval on.
    pub(super) fn due_streams(&mut self, step: u64) -> Vec<u32> {
        let mut due = Vec::new();
        for stream in &mut self.streams {
            if let Some(interval) = stream.interval_steps {
                if step >= stream.next_step {
                    due.push(stream.id);
                    stream.next_step = stream.next_step.saturating_add(interval).max(step + 1);
                }
            }
        }
        due
    }
}

fn boot_ms(t: f64) -> u32 {
    (t * 1000.0).round().clamp(0.0, f64::from(u32::MAX)) as u32
}

fn millivolts(v: f64) -> u16 {
    (v * 1000.0).round().clamp(0.0, 65534.0) as u16
}

fn percent(fraction: f64) -> i8 {
    (fraction * 100.0).round().clamp(0.0, 100.0) as i8
}
