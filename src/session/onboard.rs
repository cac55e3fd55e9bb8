//! Measuring a flight from the flight controller's own log (PX4 ULog, ArduPilot DataFlash):
//! the log read into stamped readings (`flightlog::onboard`), measured by the segmentation and
//! energy code a `.tlog` replay uses, against the flight's plan: a plan.json named or beside the
//! log, else the mission the log holds (DataFlash's CMD records, read as the autopilot's items),
//! else a mission file planned as `fly` plans it for that autopilot. The report says it measured
//! from `ulog` or `dataflash`, at what battery rate, and where the log tore.

use std::path::Path;

use crate::flightlog::flight_plan::FlightPlan;
use crate::flightlog::onboard::{self, Format, OnboardError, OnboardLog};
use crate::flightlog::replay::{analyse, Analysis, Replay};
use crate::flightlog::report::{SkippedJson, TearJson};
use crate::flightlog::segment::SegmentConfig;
use crate::flightlog::tlog::TlogGap;
use crate::flightlog::FlightLogError;
use crate::link::items::{item_from_numbers, read_flight};
use crate::link::Flavour;
use crate::mission::Mission;
use crate::physics::VehicleModel;
use crate::planner::FlightChoice;
use crate::tour::solver;

use super::predict::{flight_plan, plan_from_items, priced_by, repriced, FlightItemsError};
use super::replay::{log_name, plan_beside};

/// Why an onboard log could not be measured; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum OnboardReplayError {
    #[error(transparent)]
    Log(#[from] OnboardError),
    #[error(transparent)]
    Plan(#[from] FlightLogError),
    #[error(
        "{file}: no plan.json beside it and no mission in the log (a ULog holds only the current item): give --plan or --mission"
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
    #[error("{file}: item {seq} of the mission in the log: command {command} or frame {frame} is not MAVLink's")]
    UnknownItem {
        file: String,
        seq: u16,
        command: u16,
        frame: u8,
    },
    #[error("{file}: planning {mission} to measure the log against: {reason}")]
    Planning {
        file: String,
        mission: String,
        reason: String,
    },
}

/// The plan a log is measured against, in the order of preference.
#[derive(Debug, Clone, Copy, Default)]
pub struct PlanFrom<'a> {
    /// A plan.json (what `fly` wrote beside the flight's .tlog).
    pub plan: Option<&'a Path>,
    /// The mission file: names the waypoints of a mission read from the log, or is planned as
    /// `fly` plans it when the log holds no mission.
    pub mission: Option<&'a Mission>,
    pub model: Option<&'a VehicleModel>,
    /// Price the plan found anew with this vehicle (`report --vehicle`), whatever prices it
    /// carries ([`super::predict::repriced`]).
    pub price_with: Option<&'a VehicleModel>,
}

/// The autopilot that writes logs of `format`.
pub fn flavour_of(format: Format) -> Flavour {
    match format {
        Format::Ulog => Flavour::Px4,
        Format::Dataflash => Flavour::ArduPilot,
    }
}

/// The plan `log` (read from `path`) is measured against (see [`PlanFrom`]).
pub fn plan_for_onboard(
    path: &Path,
    log: &OnboardLog,
    from: PlanFrom<'_>,
) -> Result<FlightPlan, OnboardReplayError> {
    let file = path.display().to_string();
    if let Some(plan) = from.plan {
        return Ok(FlightPlan::read_json(plan)?);
    }
    if let Some(plan) = plan_beside(path) {
        return Ok(plan?);
    }
    let flavour = flavour_of(log.format);
    let name = from
        .mission
        .map_or_else(|| log_name(path), |m| m.name.clone());
    if let Some(commands) = &log.mission {
        let items = (commands.iter())
            .map(|c| {
                item_from_numbers(
                    c.seq, c.command, c.frame, c.params, c.lat_deg, c.lon_deg, c.alt_m,
                )
                .ok_or(OnboardReplayError::UnknownItem {
                    file: file.clone(),
                    seq: c.seq,
                    command: c.command,
                    frame: c.frame,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let home_alt_m = from.mission.map_or(0.0, |m| m.origin.home.alt_m);
        let items_error = |cause: FlightItemsError| OnboardReplayError::Items {
            file: file.clone(),
            cause,
        };
        let read = read_flight(&items, flavour, home_alt_m)
            .map_err(|e| items_error(FlightItemsError::from(e)))?;
        return plan_from_items(&name, &read, from.mission, from.model).map_err(items_error);
    }
    let (Some(mission), Some(model)) = (from.mission, from.model) else {
        return Err(OnboardReplayError::NoPlan { file });
    };
    let planning = |reason: String| OnboardReplayError::Planning {
        file: file.clone(),
        mission: mission.name.clone(),
        reason,
    };
    // The flight was flown: measured against its plan even where the battery check refuses it.
    let choice = FlightChoice {
        allow_infeasible: true,
        ..FlightChoice::default()
    };
    let plan = (choice.plan(mission, model, solver::Options::default()))
        .map_err(|e| planning(e.to_string()))?;
    let flight = choice.flight(&plan).map_err(|e| planning(e.to_string()))?;
    Ok(FlightPlan {
        priced_by: Some(priced_by(model)),
        ..flight_plan(mission, &plan, &flight, flavour)?
    })
}

/// Reads the onboard log at `path` and measures it against its plan ([`plan_for_onboard`]).
/// A log without battery current, position or mission progress is refused naming what it
/// lacks; a torn log is measured up to the tear (its parts after it incomplete or missing).
pub fn replay_onboard(
    path: &Path,
    from: PlanFrom<'_>,
    cfg: SegmentConfig,
) -> Result<Analysis, OnboardReplayError> {
    let log = onboard::read(path)?;
    log.check_measurable()?;
    let mut plan = plan_for_onboard(path, &log, from)?;
    if let Some(model) = from.price_with {
        plan.predicted =
            Some(
                repriced(&plan, model).map_err(|cause| OnboardReplayError::Repricing {
                    file: path.display().to_string(),
                    vehicle: model.vehicle.name.clone(),
                    cause,
                })?,
            );
        plan.priced_by = Some(priced_by(model));
        plan.wind = Some(model.wind).filter(|w| !w.is_calm());
    }
    let name = log_name(path);
    // A record refused as corrupt is a span of the file skipped, as a .tlog's corrupt spans are:
    // the parts overlapping it are flagged `log_gap`.
    let gaps = (log.skipped.iter())
        .map(|s| TlogGap {
            offset: s.offset,
            bytes: s.bytes,
            from_s: s.from_s,
            to_s: s.to_s,
            from_wall_us: None,
            to_wall_us: None,
        })
        .collect();
    let skipped = log.skipped.first().map(|first| SkippedJson {
        count: log.skipped.len(),
        offset: first.offset,
        record: first.record.clone(),
        reason: first.reason.clone(),
    });
    let replay = Replay {
        frames: log.stamped.len() as u64,
        undecodable: 0,
        torn_tail: log.tear.as_ref().map(|t| t.offset),
        gaps,
        stamped: log.stamped,
    };
    // The log's own energy counter (ArduPilot's EnrgTot) cross-checks each part where it has one.
    let mut cfg = cfg;
    cfg.energy.energy_counter = true;
    let mut analysis = analyse(replay, plan, &name, cfg)?;
    if let Some(source) = &mut analysis.report.source {
        source.format = log.format.name().to_string();
        source.tear = log.tear.map(|t| TearJson {
            offset: t.offset,
            after_s: t.after_s,
            reason: t.reason,
        });
        source.skipped = skipped;
    }
    Ok(analysis)
}
