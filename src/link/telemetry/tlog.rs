//! The MAVLink side of a recorded .tlog: each record checked against its checksum and decoded
//! through [`Telemetry`](super::Telemetry), the flight measured against its plan
//! (`flightlog::replay` does the rest), and the mission a recording carries.

use std::path::Path;

use super::decode::is_autopilot;
use super::frame::{check_frame, parse_frame, TelemetryError};
use super::pipeline::Telemetry;
use crate::flightlog::flight_plan::FlightPlan;
use crate::flightlog::replay::{self, Analysis, FlightDir, Replay};
use crate::flightlog::segment::SegmentConfig;
use crate::flightlog::tlog::TlogReader;
use crate::link::mav::{self, MavMessage};
use crate::link::Flavour;

/// Opens a .tlog to replay: corrupt spans skipped and kept as gaps (see [`check_frame`]).
pub fn open_tlog(path: &Path) -> Result<TlogReader<std::fs::File>, TelemetryError> {
    Ok(TlogReader::open(path)?.resynchronising(check_frame))
}

/// Replays a .tlog from the start: every stamped reading, in order, as the live run made them.
/// A torn tail ends the replay quietly; a corrupt span is skipped, the replay going on from the
/// next frame that checks, and kept in `gaps` with the vehicle times either side of it. A file
/// without a single record is an error.
pub fn replay_tlog(path: &Path) -> Result<Replay, TelemetryError> {
    let mut telemetry = Telemetry::new();
    let mut replay = replay::replay(open_tlog(path)?, |wall_us, frame| {
        telemetry.frame(wall_us, frame)
    })?;
    replay.undecodable = telemetry.undecodable();
    Ok(replay)
}

/// Replays a .tlog against `plan` and reports it as flight `name`.
pub fn analyse_tlog(
    tlog: &Path,
    plan: FlightPlan,
    name: &str,
    cfg: SegmentConfig,
) -> Result<Analysis, TelemetryError> {
    Ok(replay::analyse(replay_tlog(tlog)?, plan, name, cfg)?)
}

/// Replays a flight directory (its flight.tlog against its plan.json), named by the directory.
pub fn analyse_flight_dir(dir: &Path, cfg: SegmentConfig) -> Result<Analysis, TelemetryError> {
    let flight = FlightDir::read(dir)?;
    analyse_tlog(&flight.tlog, flight.plan, &flight.name, cfg)
}

/// The last complete mission (every item of the latest MISSION_COUNT, in either direction) in a
/// .tlog, and the flavour of the autopilot that flew it.
pub fn mission_in_tlog(
    path: &Path,
) -> Result<(Option<Vec<mav::MISSION_ITEM_INT_DATA>>, Flavour), TelemetryError> {
    let mut flavour = Flavour::Generic;
    let mut count: Option<u16> = None;
    let mut items: Vec<Option<mav::MISSION_ITEM_INT_DATA>> = Vec::new();
    let mut complete: Option<Vec<mav::MISSION_ITEM_INT_DATA>> = None;
    for record in open_tlog(path)? {
        let record = record?;
        let Ok((_, message)) = parse_frame(&record.frame) else {
            continue;
        };
        match message {
            MavMessage::HEARTBEAT(hb) if is_autopilot(&hb) => {
                flavour = Flavour::from_autopilot(hb.autopilot)
            }
            MavMessage::MISSION_COUNT(c)
                if c.mission_type == mav::MavMissionType::MAV_MISSION_TYPE_MISSION =>
            {
                count = Some(c.count);
                items = vec![None; usize::from(c.count)];
            }
            MavMessage::MISSION_ITEM_INT(item)
                if item.mission_type == mav::MavMissionType::MAV_MISSION_TYPE_MISSION =>
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
