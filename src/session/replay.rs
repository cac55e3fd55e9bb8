//! Replaying a recorded flight: the .tlog through the same decoding, clock and segmentation the
//! live recorder used, measured against the flight's plan. The plan is the flight directory's
//! plan.json when there is one (what `fly` and the recorder write); otherwise the mission items
//! found in the log itself (the upload's items, or a read-back of them, are MAVLink frames like
//! any other), priced with the vehicle model and named after a mission file's waypoints. A
//! flight directory replayed this way also tells what is left of its mission to fly
//! ([`resume_flight`], `fly --resume`).

use std::path::Path;

use crate::flightlog::flight_plan::FlightPlan;
use crate::flightlog::recorder::{flight_name, is_flight_dir, PLAN_FILE, TLOG_FILE};
use crate::flightlog::resume::{check_same_mission, ResumeError, Resumption};
use crate::flightlog::segment::SegmentConfig;
use crate::flightlog::FlightLogError;
use crate::link::items::read_flight;
use crate::link::telemetry::{analyse_tlog, mission_in_tlog, Analysis, TelemetryError};
use crate::mission::Mission;
use crate::physics::VehicleModel;

use super::predict::{plan_from_items, repriced, FlightItemsError};

/// Why a log could not be replayed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error(transparent)]
    Telemetry(#[from] TelemetryError),
    #[error(
        "{file}: no plan.json beside it and no complete mission in the log: nothing to measure the flight against"
    )]
    NoPlan { file: String },
    #[error("{file}: the mission in the log: {cause}")]
    Items {
        file: String,
        cause: FlightItemsError,
    },
    #[error("{file}: re-pricing its plan with the vehicle {vehicle}: {cause}")]
    Repricing {
        file: String,
        vehicle: String,
        cause: FlightItemsError,
    },
}

/// The plan a log is measured against: plan.json beside it, or the mission in the log.
pub fn plan_for_tlog(
    tlog: &Path,
    mission: Option<&Mission>,
    model: Option<&VehicleModel>,
) -> Result<FlightPlan, ReplayError> {
    let file = tlog.display().to_string();
    if let Some(plan) = plan_beside(tlog) {
        return Ok(plan.map_err(TelemetryError::from)?);
    }
    let (items, flavour) = mission_in_tlog(tlog)?;
    let items = items.ok_or_else(|| ReplayError::NoPlan { file: file.clone() })?;
    let name = mission.map_or_else(|| "flight".to_string(), |m| m.name.clone());
    let home_alt_m = mission.map_or(0.0, |m| m.origin.home.alt_m);
    let items_error = |cause: FlightItemsError| ReplayError::Items {
        file: file.clone(),
        cause,
    };
    let read = read_flight(&items, flavour, home_alt_m)
        .map_err(|e| items_error(FlightItemsError::from(e)))?;
    plan_from_items(&name, &read, mission, model).map_err(items_error)
}

/// Replays a .tlog and measures it against its plan (see [`plan_for_tlog`]).
pub fn replay(
    tlog: &Path,
    mission: Option<&Mission>,
    model: Option<&VehicleModel>,
    cfg: SegmentConfig,
) -> Result<Analysis, ReplayError> {
    replay_priced(tlog, (mission, model), None, cfg)
}

/// Replays a .tlog against its plan ([`plan_for_tlog`] of `plan_from`: the mission and model),
/// priced anew with `price_with` when given (`report --vehicle`: every leg, settle, take-off,
/// landing and hover as that vehicle prices them).
pub fn replay_priced(
    tlog: &Path,
    plan_from: (Option<&Mission>, Option<&VehicleModel>),
    price_with: Option<&VehicleModel>,
    cfg: SegmentConfig,
) -> Result<Analysis, ReplayError> {
    let mut plan = plan_for_tlog(tlog, plan_from.0, plan_from.1)?;
    if let Some(model) = price_with {
        plan.predicted = Some(
            repriced(&plan, model).map_err(|cause| ReplayError::Repricing {
                file: tlog.display().to_string(),
                vehicle: model.vehicle.name.clone(),
                cause,
            })?,
        );
    }
    Ok(analyse_tlog(tlog, plan, &log_name(tlog), cfg)?)
}

/// The plan.json beside a log (a flight directory's), read, when there is one.
pub(super) fn plan_beside(log: &Path) -> Option<Result<FlightPlan, FlightLogError>> {
    let dir = log.parent()?;
    dir.join(PLAN_FILE)
        .is_file()
        .then(|| crate::flightlog::recorder::read_flight_plan(dir))
}

/// A log's flight name: its flight directory's when plan.json is beside it, else its file's
/// stem.
pub(super) fn log_name(log: &Path) -> String {
    match log.parent() {
        Some(dir) if dir.join(PLAN_FILE).is_file() => flight_name(dir),
        _ => log.file_stem().map_or_else(
            || "flight".to_string(),
            |s| s.to_string_lossy().into_owned(),
        ),
    }
}

/// Why a flight directory cannot be resumed.
#[derive(Debug, thiserror::Error)]
pub enum ResumeFlightError {
    #[error("{dir}: not a flight directory (no {TLOG_FILE})")]
    NotAFlight { dir: String },
    #[error(transparent)]
    Replay(#[from] ReplayError),
    #[error(transparent)]
    Resume(#[from] ResumeError),
}

/// What is left to fly of `mission` after the flight recorded in `dir`: its plan (plan.json, or
/// the mission in its log) checked to be of `mission` before anything else, then its log
/// replayed to find the waypoints it visited (`flightlog::resume`). Errors name `dir` or the
/// file at fault.
pub fn resume_flight(dir: &Path, mission: &Mission) -> Result<Resumption, ResumeFlightError> {
    let shown = dir.display().to_string();
    if !is_flight_dir(dir) {
        return Err(ResumeFlightError::NotAFlight { dir: shown });
    }
    let tlog = dir.join(TLOG_FILE);
    let plan = plan_for_tlog(&tlog, Some(mission), None)?;
    check_same_mission(mission, &plan, &shown)?;
    let name = flight_name(&dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf()));
    let analysis =
        analyse_tlog(&tlog, plan, &name, SegmentConfig::default()).map_err(ReplayError::from)?;
    let plan = analysis.segmenter.plan();
    Ok(crate::flightlog::resume::resume(
        mission,
        plan,
        &analysis.report,
        &shown,
    )?)
}
