//! Replaying a recorded flight: the .tlog through the same decoding, clock and segmentation the
//! live recorder used, measured against the flight's plan. The plan is the flight directory's
//! plan.json when there is one (what `fly` and the recorder write); otherwise the mission items
//! found in the log itself (the upload's items, or a read-back of them, are MAVLink frames like
//! any other), priced with the vehicle model and named after a mission file's waypoints.

use std::path::Path;

use crate::flightlog::plan::FlightPlan;
use crate::flightlog::recorder::{flight_name, PLAN_FILE};
use crate::flightlog::segment::SegmentConfig;
use crate::flightlog::tlog::TlogReader;
use crate::link::mav::{MavMessage, MISSION_ITEM_INT_DATA};
use crate::link::telemetry::{analyse_tlog, is_autopilot, parse_frame, Analysis, TelemetryError};
use crate::link::Flavour;
use crate::mission::Mission;
use crate::physics::VehicleModel;

use super::plan::{plan_from_items, FlightItemsError};

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
}

/// The last complete mission (every item of the latest MISSION_COUNT, in either direction) in a
/// .tlog, and the flavour of the autopilot that flew it.
pub fn mission_in_tlog(
    path: &Path,
) -> Result<(Option<Vec<MISSION_ITEM_INT_DATA>>, Flavour), TelemetryError> {
    let mut flavour = Flavour::Generic;
    let mut count: Option<u16> = None;
    let mut items: Vec<Option<MISSION_ITEM_INT_DATA>> = Vec::new();
    let mut complete: Option<Vec<MISSION_ITEM_INT_DATA>> = None;
    for record in TlogReader::open(path)? {
        let Ok(record) = record else { break };
        let Ok((_, message)) = parse_frame(&record.frame) else {
            continue;
        };
        match message {
            MavMessage::HEARTBEAT(hb) if is_autopilot(&hb) => {
                flavour = Flavour::from_autopilot(hb.autopilot)
            }
            MavMessage::MISSION_COUNT(c)
                if c.mission_type == crate::link::mav::MavMissionType::MAV_MISSION_TYPE_MISSION =>
            {
                count = Some(c.count);
                items = vec![None; usize::from(c.count)];
            }
            MavMessage::MISSION_ITEM_INT(item)
                if item.mission_type
                    == crate::link::mav::MavMissionType::MAV_MISSION_TYPE_MISSION =>
            {
                if let Some(slot) = items.get_mut(usize::from(item.seq)) {
                    *slot = Some(item);
                }
                if count.is_some() && items.iter().all(Option::is_some) {
                    complete = Some(items.iter().flatten().cloned().collect());
                }
            }
            _ => {}
        }
    }
    Ok((complete, flavour))
}

/// The plan a log is measured against: plan.json beside it, or the mission in the log.
pub fn plan_for_tlog(
    tlog: &Path,
    mission: Option<&Mission>,
    model: Option<&VehicleModel>,
) -> Result<FlightPlan, ReplayError> {
    let file = tlog.display().to_string();
    if let Some(dir) = tlog.parent() {
        let beside = dir.join(PLAN_FILE);
        if beside.is_file() {
            return Ok(FlightPlan::read_json(&beside).map_err(TelemetryError::from)?);
        }
    }
    let (items, flavour) = mission_in_tlog(tlog)?;
    let items = items.ok_or_else(|| ReplayError::NoPlan { file: file.clone() })?;
    let name = mission.map_or_else(|| "flight".to_string(), |m| m.name.clone());
    plan_from_items(&name, &items, flavour, mission, model)
        .map_err(|cause| ReplayError::Items { file, cause })
}

/// Replays a .tlog and measures it against its plan (see [`plan_for_tlog`]).
pub fn replay(
    tlog: &Path,
    mission: Option<&Mission>,
    model: Option<&VehicleModel>,
    cfg: SegmentConfig,
) -> Result<Analysis, ReplayError> {
    let plan = plan_for_tlog(tlog, mission, model)?;
    let name = tlog
        .parent()
        .filter(|d| d.join(PLAN_FILE).is_file())
        .map_or_else(
            || {
                tlog.file_stem().map_or_else(
                    || "flight".to_string(),
                    |s| s.to_string_lossy().into_owned(),
                )
            },
            flight_name,
        );
    Ok(analyse_tlog(tlog, plan, &name, cfg)?)
}
