//! The flight and battery ledger: every flight remembered with its vehicle, its pack and what was
//! learned in it, so the next plan and the energy guard start from what is known.
//!
//! Flight directories stay the source of truth: a [`FlightRecord`] is a pure function of a
//! flight's own files (`ledger::record`), and the store (`ledger::store`: an embedded SQLite
//! file by default, or a team's PostgreSQL server) keeps one row per flight by its `id`, so
//! writing a flight twice changes nothing and `emplan ledger rebuild` recreates the same rows.
//! What a pack is now (its capacity and resistance, their trend over its cycles, its warnings)
//! and what a vehicle's model is off by are computed from its flights' records
//! (`ledger::packs`), never stored apart from them.
//!
//! The store is blocking (SQLite, and the `postgres` client, which runs its own runtime): async
//! callers move it to a blocking thread.

pub mod packs;
pub mod record;
pub mod store;

use serde::{Deserialize, Serialize};

pub use packs::{PackPrior, PackSummary, VehiclePrior};
pub use store::{FlightQuery, Ledger, LedgerSpec, Written};

/// Where a flight's record was read from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FlightSource {
    /// A flight directory (`fly`, `record`, the service, or one replayed from its .tlog).
    Directory,
    /// A PX4 ULog imported alone.
    Ulog,
    /// An ArduPilot DataFlash log imported alone.
    Dataflash,
}

/// How a flight ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Landed with every waypoint visited.
    Completed,
    /// Sent home by the energy guard.
    Returned,
    /// Landed with waypoints left, not sent home by the guard.
    Incomplete,
    /// The log ends before a landing.
    CutOff,
}

/// One part of a flight (take-off, a leg, a settle, a hover, the landing, the way home), as
/// predicted and as measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PartRecord {
    /// Its place in the flight, from 0.
    pub index: u32,
    /// `takeoff`, `leg`, `settle`, `hover`, `landing` or `return`.
    pub kind: String,
    /// The point it flies to or hovers at (the take-off and landing: empty).
    pub name: String,
    pub predicted_j: Option<f64>,
    pub measured_j: Option<f64>,
    pub duration_s: Option<f64>,
}

/// What the energy guard learned in a flight.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GuardLearned {
    /// Measured over predicted, as the guard learned it by the end.
    pub correction: f64,
    /// The pack's capacity against its label as the guard learned it.
    pub capacity_ratio: f64,
    pub state_of_charge_at_takeoff: Option<f64>,
    pub returned: bool,
}

/// The pack as one flight's voltage and current show it (`logfit::battery`'s model fitted to
/// this flight alone).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PackFit {
    /// The capacity fitted, and the label it is measured against (Ah).
    pub capacity_ah: f64,
    pub label_capacity_ah: f64,
    /// The capacity's standard error (Ah), from the fit's residuals.
    pub capacity_sd_ah: f64,
    pub internal_resistance_ohm: f64,
    pub state_of_charge_at_takeoff: f64,
    /// Samples fitted and the rms voltage residual.
    pub samples: usize,
    pub voltage_rms_v: f64,
}

/// One flight as the ledger keeps it: a pure function of its files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlightRecord {
    /// Its identity, the same wherever and however often it is read: the flight directory's
    /// name, or the log file's name, with a hash of its contents.
    pub id: String,
    pub source: FlightSource,
    /// Where its files are, as given when it was written.
    pub path: String,
    /// The vehicle file's name the flight was priced with (None: not known).
    pub vehicle: Option<String>,
    /// The pack flown (`--pack`, or the autopilot's SMART_BATTERY_INFO).
    pub pack: Option<String>,
    pub mission: String,
    /// The trajectory profile that priced it.
    pub profile: Option<String>,
    /// The steady wind it was priced in (m/s, from degrees).
    pub wind_m_s: Option<f64>,
    pub wind_from_deg: Option<f64>,
    /// `px4`, `ardupilot` or `generic`.
    pub autopilot: Option<String>,
    /// When it started, UTC, `YYYY-MM-DDTHH:MM:SSZ`.
    pub started_at: Option<String>,
    pub outcome: Outcome,
    pub duration_s: f64,
    pub predicted_j: Option<f64>,
    pub measured_j: Option<f64>,
    /// Charge drawn from the pack, arming to disarming (Ah).
    pub charge_ah: Option<f64>,
    pub parts: Vec<PartRecord>,
    pub guard: Option<GuardLearned>,
    pub pack_fit: Option<PackFit>,
}

/// A ledger failure: the store's, or a flight's files that cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum LedgerError {
    #[error("ledger {at}: {message}")]
    Store { at: String, message: String },
    #[error("ledger {at}: schema version {found} is newer than this emplan knows ({known})")]
    NewerSchema { at: String, found: u32, known: u32 },
    #[error("{path}: {message}")]
    Flight { path: String, message: String },
    /// A query's date bound that is neither a date nor a time (`field`: `since` or `until`).
    #[error("{field} `{value}`: not a date (YYYY-MM-DD) or a time (YYYY-MM-DDTHH:MM:SSZ)")]
    Query { field: String, value: String },
    /// A flight's file that cannot be read (the error names the file, and its line or field).
    #[error(transparent)]
    FlightFile(#[from] crate::flightlog::FlightLogError),
}
