//! The service's wire: every request, answer and event that crosses its HTTP boundary, as
//! types that serialise to the JSON the service sends (and the dashboard reads) and
//! deserialise from it, so the server (`api`, `events`, `vehicle`) and the clients (`emplan
//! upload/fly --service`, tests) share one definition and nobody reads the JSON by key.
//!
//! Events (`GET /api/events`, server-sent, each a JSON object with a `type`): `telemetry` (at
//! most 5 Hz: link, armed, mode, mission item, landed state, battery V/I/P, position, the part
//! in progress with its energy so far), `part` (a part of the flight completed, predicted vs
//! measured), `flight_started`, `flight_ended` (with the report), `recording_failed`,
//! `mission_planned`, `mission_error`, `mission_removed`, `link`, `upload`, `start`, and
//! `lagged` (to one follower that fell behind: it missed that many events).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::flightlog::report::{PartJson, PartReport, ReportJson};
use crate::flightlog::segment::SegmentKind;
use crate::flightlog::watch::{GuardNote, GuardView};
use crate::link::connection::{wall_us, Autopilot};
use crate::planner::FlownOrder;
use crate::session::recorder::{BatteryNow, Live};
use crate::session::upload::UploadJson;
use crate::session::Px4Parameters;

/// The state of the link to the vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LinkState {
    /// The transport does not open yet (a TCP port not listening, a serial device absent).
    Connecting,
    /// Open, no autopilot heard yet.
    WaitingForHeartbeat,
    /// The autopilot's heartbeat arrives.
    Connected,
    /// The autopilot's heartbeat stopped (radio out of range, vehicle off).
    Lost,
}

/// What a client sees of the link.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinkStatus {
    pub state: LinkState,
    pub url: String,
    /// The vehicle is emplan's built-in mock autopilot (it has no pilot: the service starts
    /// its missions).
    pub builtin_mock: bool,
    pub autopilot: Option<Autopilot>,
    /// Times the transport was reopened.
    pub reconnects: u64,
    /// The last connection error, while connecting.
    pub error: Option<String>,
}

/// One event.
// An event is built, serialised once and dropped, a few a second: its size does not matter,
// and boxing its largest views only moves the lint to the next largest.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Event {
    Telemetry(TelemetryJson),
    Part(PartEventJson),
    FlightStarted {
        flight: String,
        dir: PathBuf,
        resumed: bool,
    },
    FlightEnded {
        flight: String,
        dir: PathBuf,
        /// None when nothing was known to measure the flight against.
        report: Option<ReportJson>,
    },
    RecordingFailed {
        flight: String,
        error: String,
    },
    /// The energy guard saw or decided something (`note.kind` `return`: it sent the vehicle
    /// home).
    Guard {
        flight: String,
        note: GuardNote,
    },
    /// The rest of the flight was priced again in the wind the vehicle estimated in flight.
    Repriced {
        flight: String,
        repriced: crate::flightlog::report::RepricedNote,
    },
    MissionPlanned(MissionStatus),
    MissionError(MissionStatus),
    MissionRemoved {
        name: String,
    },
    Link(LinkStatus),
    /// An upload through the service ended: `result` is the upload document or the failure
    /// document (`ok` tells which).
    Upload {
        name: String,
        ok: bool,
        result: UploadResult,
    },
    /// A start through the service ended.
    Start {
        ok: bool,
        error: Option<String>,
    },
    /// Sent to one follower only: it fell behind and missed `missed` events.
    Lagged {
        missed: u64,
    },
}

/// What a part of a flight is, on the wire (its `kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PartKind {
    Takeoff,
    Leg,
    Settle,
    Hover,
    Landing,
}

impl PartKind {
    pub fn name(self) -> &'static str {
        match self {
            PartKind::Takeoff => "takeoff",
            PartKind::Leg => "leg",
            PartKind::Settle => "settle",
            PartKind::Hover => "hover",
            PartKind::Landing => "landing",
        }
    }
}

/// The kind of a part and the index of its point (legs, settles, hovers).
pub fn kind_name(kind: SegmentKind) -> (PartKind, Option<usize>) {
    match kind {
        SegmentKind::Takeoff => (PartKind::Takeoff, None),
        SegmentKind::Leg(k) => (PartKind::Leg, Some(k)),
        SegmentKind::Settle(k) => (PartKind::Settle, Some(k)),
        SegmentKind::Hover(k) => (PartKind::Hover, Some(k)),
        SegmentKind::Landing => (PartKind::Landing, None),
    }
}

/// The segment a part's kind and index name (None: a leg, settle or hover without its index).
pub fn segment_kind(kind: PartKind, index: Option<usize>) -> Option<SegmentKind> {
    Some(match (kind, index) {
        (PartKind::Takeoff, _) => SegmentKind::Takeoff,
        (PartKind::Landing, _) => SegmentKind::Landing,
        (PartKind::Leg, Some(k)) => SegmentKind::Leg(k),
        (PartKind::Settle, Some(k)) => SegmentKind::Settle(k),
        (PartKind::Hover, Some(k)) => SegmentKind::Hover(k),
        _ => return None,
    })
}

/// A part of a flight: its kind (`takeoff`, `leg`, `settle`, `hover`, `landing`), the index of
/// the planned point it ends at, and the report's fields (kJ).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PartEventJson {
    pub flight: String,
    pub kind: PartKind,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub index: Option<usize>,
    #[serde(flatten)]
    pub part: PartJson,
}

impl PartEventJson {
    pub fn new(flight: &str, kind: SegmentKind, part: &PartReport) -> PartEventJson {
        let (kind, index) = kind_name(kind);
        PartEventJson {
            flight: flight.to_string(),
            kind,
            index,
            part: PartJson::from(part),
        }
    }
}

/// Where the vehicle is.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PositionJson {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_amsl_m: f64,
    pub relative_alt_m: f64,
    pub speed_m_s: f64,
}

/// The flight being recorded, as a telemetry event carries it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LiveFlightJson {
    pub flight: String,
    /// Vehicle time since the flight's log began.
    pub t_s: f64,
    /// Parts completed.
    pub parts: usize,
    /// The part in progress, with its energy so far.
    pub in_progress: Option<PartEventJson>,
    /// The energy guard's view, when the flight is guarded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub guard: Option<GuardView>,
}

/// The latest state of link and vehicle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TelemetryJson {
    /// When the service published it (unix ms).
    pub wall_ms: u64,
    pub link: LinkState,
    pub armed: Option<bool>,
    pub mode: Option<String>,
    pub mission_seq: Option<u16>,
    pub landed: Option<String>,
    pub battery: Option<BatteryNow>,
    pub position: Option<PositionJson>,
    pub flight: Option<LiveFlightJson>,
    /// Frames received and sent on the link so far.
    pub frames: u64,
}

impl TelemetryJson {
    pub fn new(live: &Live, link: LinkState) -> TelemetryJson {
        let v = &live.vehicle;
        TelemetryJson {
            wall_ms: wall_us() / 1000,
            link,
            armed: v.armed,
            mode: v.mode.as_ref().map(|m| m.name().to_string()),
            mission_seq: v.mission_seq,
            landed: v.landed.map(|l| l.name().to_string()),
            battery: live.battery,
            position: v.position.map(|p| PositionJson {
                lat_deg: p.lat_deg,
                lon_deg: p.lon_deg,
                alt_amsl_m: p.alt_amsl_m,
                relative_alt_m: p.relative_alt_m,
                speed_m_s: p.speed_m_s(),
            }),
            flight: live.flight.as_ref().map(|f| LiveFlightJson {
                flight: f.flight.clone(),
                t_s: f.t_s,
                parts: f.parts,
                in_progress: f
                    .in_progress
                    .as_ref()
                    .map(|(kind, part)| PartEventJson::new(&f.flight, *kind, part)),
                guard: f.guard.clone(),
            }),
            frames: live.frames,
        }
    }
}

/// One point of the battery history.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BatteryPoint {
    pub wall_ms: u64,
    pub voltage_v: Option<f64>,
    pub current_a: Option<f64>,
    pub power_w: Option<f64>,
}

/// The flight in progress (or the last one), with the parts completed so far.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlightView {
    pub flight: String,
    pub dir: PathBuf,
    pub resumed: bool,
    pub recording: bool,
    pub parts: Vec<PartEventJson>,
    /// The energy guard's notes so far.
    #[serde(default)]
    pub guard_notes: Vec<GuardNote>,
}

/// The body of `POST /api/missions/{name}/upload` (every field optional): the choice and the
/// settings the command line would plan it with.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UploadRequest {
    #[serde(default)]
    pub order: FlownOrder,
    pub sortie: Option<usize>,
    #[serde(default)]
    pub allow_infeasible: bool,
    pub acceptance_radius_m: Option<f32>,
    /// Refused unless it is the service's own profile.
    pub profile: Option<String>,
    pub solver: Option<String>,
    pub time_limit_s: Option<f64>,
    pub seed: Option<u64>,
    pub kicks: Option<u64>,
    /// "mission" (the default: the vehicle must stand at the mission's origin) or "vehicle"
    /// (the mission re-planned from the vehicle's home).
    pub origin: Option<crate::session::PlanOrigin>,
    /// The battery pack flown (its name; plan.json's `pack`), whose capacity the ledger learned.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pack: Option<String>,
}

impl UploadRequest {
    /// The request for `choice`, planned with `profile` (None: the service's) and `solver`.
    pub fn new(
        choice: &crate::planner::FlightChoice,
        acceptance_radius_m: f32,
        profile: Option<crate::physics::Profile>,
        solver: &crate::tour::solver::Options,
    ) -> UploadRequest {
        UploadRequest {
            order: choice.order,
            sortie: choice.sortie,
            allow_infeasible: choice.allow_infeasible,
            acceptance_radius_m: Some(acceptance_radius_m),
            profile: profile.map(|p| p.to_string()),
            solver: Some(solver.solver.to_string()),
            time_limit_s: Some(solver.time_limit.as_secs_f64()),
            seed: Some(solver.seed),
            kicks: solver.kicks,
            origin: None,
            pack: None,
        }
    }
}

/// What the link did during an upload (the numbers of the CLI's text line; not in `upload
/// --json`'s document).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct LinkNumbers {
    pub rtt_ms: Option<f64>,
    pub restarts: u32,
    pub refusals: u32,
}

/// The answer to an upload: `emplan upload --json`'s document, the link's numbers, and on a
/// PX4 flying the px4 profile the trajectory parameters it holds (as `emplan fly --json`
/// reports them; the flight is measured against its legs priced with them).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UploadAnswer {
    #[serde(flatten)]
    pub upload: UploadJson,
    pub link: LinkNumbers,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub px4_parameters: Option<Px4Parameters>,
}

/// How an upload through the service ended: its answer, or why it failed.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum UploadResult {
    Failed(Failure),
    Uploaded(UploadAnswer),
}

/// `GET /api/vehicle`: the link, the latest telemetry and the flight in progress (or the last).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VehicleView {
    pub link: LinkStatus,
    pub telemetry: Option<TelemetryJson>,
    pub flight: Option<FlightView>,
}

/// `GET /api/battery`: the battery now and its history since the time asked.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BatteryView {
    pub now: Option<BatteryNow>,
    pub history: Vec<BatteryPoint>,
}

/// The files of a flight directory that exist, as API paths.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FlightFiles {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tlog: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plan: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub report: Option<String>,
}

/// A recorded flight as `GET /api/flights` lists it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlightSummary {
    pub name: String,
    /// Being recorded now.
    pub recording: bool,
    /// From its report, once it has one.
    pub complete: Option<bool>,
    pub total: Option<crate::flightlog::report::TotalJson>,
    pub legs: Option<usize>,
    pub files: FlightFiles,
}

/// `GET /api/flights?vehicle=&pack=&mission=&since=&until=`: the log directory and its
/// flights (every flight directory in it, newest first), and the ledger's flights matching the
/// query (every field given must match; none: all), newest first.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlightsList {
    pub dir: PathBuf,
    pub flights: Vec<FlightSummary>,
    /// Where the ledger is (a PostgreSQL URL without its password).
    #[serde(default)]
    pub ledger: String,
    /// The ledger's flights matching the query, newest first (none while the ledger does not
    /// exist yet, or cannot be read: then `ledger_error` says why).
    #[serde(default)]
    pub records: Vec<crate::ledger::FlightRecord>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ledger_error: Option<String>,
}

/// `GET /api/packs`: every pack of the ledger's flights.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PacksView {
    /// Where the ledger is (a PostgreSQL URL without its password).
    pub ledger: String,
    /// False until the first flight lands in it (the service does not create it before).
    pub exists: bool,
    /// By name.
    pub packs: Vec<PackView>,
}

/// One pack: what `ledger::packs::summarise` makes of its flights (flights, cycles, capacity
/// and resistance with their standard errors, fade per cycle, warnings), and each flight's own
/// measure of it, oldest first (the capacity over cycles the dashboard draws).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PackView {
    #[serde(flatten)]
    pub summary: crate::ledger::PackSummary,
    pub history: Vec<PackPoint>,
}

/// One flight of a pack, as its voltage and current measured the pack.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PackPoint {
    /// The flight's id in the ledger.
    pub flight: String,
    pub started_at: Option<String>,
    /// The pack's age at the flight's middle in equivalent full cycles (the charge drawn on it
    /// so far against its label, as `ledger::packs` places the flight on its trend; None: no
    /// label known).
    pub cycles: Option<f64>,
    /// The capacity the flight's voltage and current show, its standard error and the label
    /// (Ah; None: not fitted).
    pub capacity_ah: Option<f64>,
    pub capacity_sd_ah: Option<f64>,
    pub label_capacity_ah: Option<f64>,
    pub internal_resistance_ohm: Option<f64>,
}

/// `GET /api/flights/{name}`: the summary, the mission it flew, its report and, while it is
/// recorded, the live view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlightDetail {
    #[serde(flatten)]
    pub summary: FlightSummary,
    pub mission: Option<String>,
    pub dir: PathBuf,
    pub report: Option<ReportJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub live: Option<FlightView>,
}

/// The answer to `POST /api/vehicle/start`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Started {
    pub ok: bool,
}

/// The mission folder as `GET /api/missions` lists it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MissionsFolder {
    pub dir: PathBuf,
    #[serde(default)]
    pub missions: Vec<MissionStatus>,
}

/// Where a mission file is in its life: being written, being planned, planned, or failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MissionState {
    /// Its size or modification time changed less than the settle time ago: not read yet.
    Changing,
    /// Being planned (or waiting for a free planning thread).
    Planning,
    Planned,
    Error,
}

/// A mission file as `GET /api/missions` lists it and the `mission_planned` and
/// `mission_error` events carry it: its state, the error, or the headline numbers of its plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MissionStatus {
    pub name: String,
    pub file: PathBuf,
    /// The digest of the bytes planned (`missions::digest`; empty while the file changes).
    pub digest: String,
    /// The file's modification time (unix ms).
    pub modified_ms: u64,
    pub status: MissionState,
    /// The mission's name, when the file reads as one.
    pub mission: Option<String>,
    pub waypoints: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<MissionProblem>,
    /// The plan's headline numbers, once planned.
    #[serde(flatten, default, skip_serializing_if = "Option::is_none")]
    pub planned: Option<PlannedNumbers>,
}

/// A planned mission's headline numbers (kJ).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlannedNumbers {
    pub profile: crate::physics::Profile,
    pub energy_kj: Option<f64>,
    pub distance_kj: Option<f64>,
    /// What the energy order saves over the cheaper distance order (%).
    pub saving_pct: Option<f64>,
    pub total_kj: f64,
    pub budget_kj: f64,
    pub feasible: bool,
    /// Sorties of the split, when one battery cannot fly it.
    pub sorties: Option<usize>,
    /// Why the sorties are missing, when no split was found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sorties_error: Option<String>,
}

/// The mission's origin as `GET /api/missions/{name}` gives it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OriginJson {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub home_alt_amsl_m: f64,
    pub height_above_home_m: f64,
}

/// A waypoint as `GET /api/missions/{name}` gives it (local frame, m).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointJson {
    pub name: String,
    pub x_m: f64,
    pub y_m: f64,
    pub z_m: f64,
    pub hover_s: f64,
}

/// `GET /api/missions/{name}`: the status, the mission's origin and points, and the plan
/// document (`emplan plan --json` of it, docs/json.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MissionDetail {
    #[serde(flatten)]
    pub status: MissionStatus,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub origin: Option<OriginJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub points: Option<Vec<PointJson>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plan: Option<serde_json::Value>,
}

/// Why a mission has no plan, located.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MissionProblem {
    /// `mission` (the file cannot be read as a mission) or `plan` (it cannot be planned).
    pub stage: String,
    pub message: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub line: Option<usize>,
    /// The 0-based item of a `.plan` file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub item: Option<usize>,
}

pub use crate::session::upload::Failure;
