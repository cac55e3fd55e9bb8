//! Telemetry readings in SI units, free of MAVLink types: what `link::telemetry::decode` makes of
//! the autopilot's messages (the only place MAVLink units are converted), what the recorder writes
//! and what segmentation and energy integration consume. `Stamped` pairs a reading with its
//! vehicle time from [`super::clock`]; [`VehicleState`] keeps the latest of each kind.

use serde::{Deserialize, Serialize};

/// One decoded telemetry message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Reading {
    Battery(Battery),
    Position(Position),
    /// MISSION_CURRENT: the item the autopilot is flying to.
    MissionCurrent {
        seq: u16,
        /// Items in the mission, when the autopilot says (MAVLink 2 extension).
        total: Option<u16>,
        state: MissionState,
    },
    /// MISSION_ITEM_REACHED (PX4 repeats it about once a second: de-duplicate).
    ItemReached {
        seq: u16,
    },
    /// The autopilot's own HEARTBEAT.
    Heartbeat {
        armed: bool,
        mode: FlightMode,
    },
    /// EXTENDED_SYS_STATE's landed state.
    Landed(LandedState),
    StatusText {
        severity: u8,
        text: String,
    },
    /// HOME_POSITION: the home the autopilot holds; `relative_alt` is measured from its altitude
    /// (above mean sea level).
    Home {
        lat_deg: f64,
        lon_deg: f64,
        alt_amsl_m: f64,
        /// The autopilot's time since boot when this home was set (`time_usec`; PX4 stamps it
        /// with the moment it set home, ArduPilot with the moment it sent it), when given.
        set_boot_s: Option<f64>,
    },
    /// The autopilot's wind estimate (PX4's WIND_COV, ArduPilot's WIND).
    Wind(crate::mission::wind::Wind),
    /// A photo the autopilot reports taking (ArduPilot's CAMERA_FEEDBACK, PX4's CAMERA_TRIGGER
    /// and CAMERA_IMAGE_CAPTURED).
    Photo(Photo),
    /// FENCE_STATUS: the autopilot's geofence, breached or not.
    Fence(FenceStatus),
}

/// What FENCE_STATUS says of the autopilot's geofence.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FenceStatus {
    /// Outside the fence now (`breach_status` 1).
    pub breached: bool,
    /// Breaches since the autopilot booted.
    pub breach_count: u16,
    /// What the last breach broke.
    pub breach_type: BreachType,
    /// When the last breach began, in the autopilot's time since boot (s); None before any.
    pub last_breach_boot_s: Option<f64>,
}

/// What a fence breach broke (MAVLink FENCE_BREACH).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BreachType {
    None,
    MinAltitude,
    MaxAltitude,
    /// The fence's boundary: an inclusion zone left or an exclusion zone entered.
    Boundary,
}

impl BreachType {
    /// "boundary", "max_altitude": as the report writes it.
    pub fn name(self) -> &'static str {
        match self {
            BreachType::None => "none",
            BreachType::MinAltitude => "min_altitude",
            BreachType::MaxAltitude => "max_altitude",
            BreachType::Boundary => "boundary",
        }
    }
}

/// Which message reported a photo.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PhotoMessage {
    /// ArduPilot's CAMERA_FEEDBACK: one per photo, with where it was taken.
    CameraFeedback,
    /// PX4's CAMERA_TRIGGER: the trigger's sequence number only (no position).
    CameraTrigger,
    /// CAMERA_IMAGE_CAPTURED (PX4): the image's index, where and whether it was captured.
    ImageCaptured,
}

impl PhotoMessage {
    /// The MAVLink message's name.
    pub fn name(self) -> &'static str {
        match self {
            PhotoMessage::CameraFeedback => "CAMERA_FEEDBACK",
            PhotoMessage::CameraTrigger => "CAMERA_TRIGGER",
            PhotoMessage::ImageCaptured => "CAMERA_IMAGE_CAPTURED",
        }
    }
}

/// Where a photo was taken, as the autopilot says.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PhotoPosition {
    pub lat_deg: f64,
    pub lon_deg: f64,
    /// Altitude above mean sea level.
    pub alt_amsl_m: f64,
    /// Altitude above the vehicle's home.
    pub relative_alt_m: f64,
}

/// One photo the autopilot reported, in SI units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Photo {
    pub message: PhotoMessage,
    /// The image's number as the autopilot counts them (CAMERA_FEEDBACK `img_idx`,
    /// CAMERA_TRIGGER `seq`, CAMERA_IMAGE_CAPTURED `image_index`): PX4 numbers a photo's
    /// trigger and its capture alike.
    pub index: i64,
    /// Where it was taken (None: CAMERA_TRIGGER, which does not say).
    pub at: Option<PhotoPosition>,
    /// The autopilot's own time of the image (s; since boot or the UNIX epoch, as the autopilot
    /// fills it), when given: informative, never a clock anchor.
    pub camera_time_s: Option<f64>,
    /// Whether the camera says it captured the image (CAMERA_IMAGE_CAPTURED
    /// `capture_result`); the other messages report photos taken.
    pub captured: bool,
}

/// Where a battery reading came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(tag = "message", rename_all = "snake_case")]
pub enum BatterySource {
    /// BATTERY_STATUS of battery `id`, sent by component `component`.
    BatteryStatus { id: u8, component: u8 },
    /// SYS_STATUS (the fallback when no BATTERY_STATUS arrives).
    SysStatus,
}

impl BatterySource {
    /// The name used in samples.csv's `source` column.
    pub fn name(self) -> &'static str {
        match self {
            BatterySource::BatteryStatus { .. } => "battery_status",
            BatterySource::SysStatus => "sys_status",
        }
    }
}

/// A battery reading: pack voltage, current and the autopilot's own integrals.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Battery {
    pub source: BatterySource,
    /// Pack voltage; None = unknown.
    pub voltage_v: Option<f64>,
    /// Current drawn from the pack; None = unknown (MAVLink -1 cA), never 0 for unknown.
    pub current_a: Option<f64>,
    /// Charge consumed since boot as the autopilot integrates it; None = unknown (-1).
    pub consumed_mah: Option<f64>,
    /// Energy consumed since boot as the autopilot integrates it; None = unknown (-1).
    pub energy_consumed_j: Option<f64>,
    /// Remaining charge, 0-100; None = unknown (-1).
    pub remaining_pct: Option<f64>,
    /// PX4 SITL's battery simulator: a fixed -1 A that is not a measurement (see
    /// `link::telemetry::decode` for the rule). Never integrated.
    pub fake_current: bool,
}

/// GLOBAL_POSITION_INT in SI units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Position {
    /// The autopilot's time since boot when the position was valid.
    pub time_boot_ms: u32,
    pub lat_deg: f64,
    pub lon_deg: f64,
    /// Altitude above mean sea level.
    pub alt_amsl_m: f64,
    /// Altitude above the vehicle's home (what missions with relative altitude use).
    pub relative_alt_m: f64,
    pub vn_m_s: f64,
    pub ve_m_s: f64,
    /// Down velocity (positive descending).
    pub vd_m_s: f64,
}

impl Position {
    /// Ground speed plus vertical: the 3D speed.
    pub fn speed_m_s(&self) -> f64 {
        (self.vn_m_s.powi(2) + self.ve_m_s.powi(2) + self.vd_m_s.powi(2)).sqrt()
    }
}

/// MISSION_STATE (MISSION_CURRENT's extension).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MissionState {
    Unknown,
    NoMission,
    NotStarted,
    Active,
    Paused,
    Complete,
}

/// The flight mode, normalised across autopilots.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FlightMode {
    Mission,
    Takeoff,
    Land,
    Rtl,
    Hold,
    Manual,
    Guided,
    /// Anything else, named as the autopilot names it (or `custom N`).
    Other(String),
}

impl FlightMode {
    /// ArduCopter's mode `number` (ArduCopter `mode.h`, `enum class Number`: HEARTBEAT's
    /// `custom_mode`, DataFlash's MODE `ModeNum`).
    pub fn arducopter(number: u64) -> FlightMode {
        match number {
            0 | 1 | 2 | 11 | 13 | 16 | 22 => FlightMode::Manual,
            3 => FlightMode::Mission,
            4 | 20 => FlightMode::Guided,
            5 | 17 => FlightMode::Hold,
            6 | 21 | 27 => FlightMode::Rtl,
            9 => FlightMode::Land,
            7 => FlightMode::Other("circle".into()),
            n => FlightMode::Other(format!("arducopter {n}")),
        }
    }

    /// A short lowercase name (samples.csv's `mode` column).
    pub fn name(&self) -> &str {
        match self {
            FlightMode::Mission => "mission",
            FlightMode::Takeoff => "takeoff",
            FlightMode::Land => "land",
            FlightMode::Rtl => "rtl",
            FlightMode::Hold => "hold",
            FlightMode::Manual => "manual",
            FlightMode::Guided => "guided",
            FlightMode::Other(name) => name,
        }
    }
}

/// MAV_LANDED_STATE.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LandedState {
    Undefined,
    OnGround,
    InAir,
    Takeoff,
    Landing,
}

impl LandedState {
    /// A short lowercase name (samples.csv's `landed` column).
    pub fn name(self) -> &'static str {
        match self {
            LandedState::Undefined => "undefined",
            LandedState::OnGround => "on_ground",
            LandedState::InAir => "in_air",
            LandedState::Takeoff => "takeoff",
            LandedState::Landing => "landing",
        }
    }
}

/// A reading with its vehicle time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Stamped {
    /// Vehicle seconds since the flight's first message (see [`super::clock`]).
    pub t_s: f64,
    /// When the frame arrived (unix microseconds).
    pub wall_us: u64,
    pub reading: Reading,
}

/// The latest state of the vehicle, as readings report it.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct VehicleState {
    pub position: Option<Position>,
    pub mission_seq: Option<u16>,
    pub armed: Option<bool>,
    pub mode: Option<FlightMode>,
    pub landed: Option<LandedState>,
}

impl VehicleState {
    /// Takes in one reading.
    pub fn update(&mut self, reading: &Reading) {
        match reading {
            Reading::Position(p) => self.position = Some(*p),
            Reading::MissionCurrent { seq, .. } => self.mission_seq = Some(*seq),
            Reading::Heartbeat { armed, mode } => {
                self.armed = Some(*armed);
                if self.mode.as_ref() != Some(mode) {
                    self.mode = Some(mode.clone());
                }
            }
            Reading::Landed(state) => self.landed = Some(*state),
            Reading::Battery(_)
            | Reading::ItemReached { .. }
            | Reading::StatusText { .. }
            | Reading::Home { .. }
            | Reading::Wind(_)
            | Reading::Photo(_)
            | Reading::Fence(_) => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vehicle_state_keeps_the_latest_of_each_kind() {
        let mut state = VehicleState::default();
        state.update(&Reading::MissionCurrent {
            seq: 3,
            total: None,
            state: MissionState::Active,
        });
        state.update(&Reading::Heartbeat {
            armed: true,
            mode: FlightMode::Mission,
        });
        state.update(&Reading::MissionCurrent {
            seq: 4,
            total: Some(9),
            state: MissionState::Active,
        });
        state.update(&Reading::Landed(LandedState::InAir));
        assert_eq!(state.mission_seq, Some(4));
        assert_eq!(state.armed, Some(true));
        assert_eq!(state.mode, Some(FlightMode::Mission));
        assert_eq!(state.landed, Some(LandedState::InAir));
        assert_eq!(state.position, None);
    }

    #[test]
    fn a_reading_survives_a_json_round_trip() {
        let reading = Reading::Battery(Battery {
            source: BatterySource::BatteryStatus {
                id: 0,
                component: 1,
            },
            voltage_v: Some(22.2),
            current_a: None,
            consumed_mah: Some(120.0),
            energy_consumed_j: None,
            remaining_pct: Some(87.0),
            fake_current: false,
        });
        let text = serde_json::to_string(&reading).expect("serialises");
        let back: Reading = serde_json::from_str(&text).expect("parses");
        assert_eq!(back, reading);
    }
}
