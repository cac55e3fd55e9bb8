//! Replaying a recorded flight: the .tlog through the same decoding, clock and segmentation the
//! live recorder used, measured against the flight's plan. The plan is the flight directory's
//! plan.json when there is one (what `fly` and the recorder write); otherwise the mission items
//! found in the log itself (the upload's items, or a read-back of them, are MAVLink frames like
//! any other), priced with the vehicle model and named after a mission file's waypoints. A
//! flight directory replayed this way also tells what is left of its mission to fly
//! ([`resume_flight`], `fly --resume`), and a flight whose recording stopped before its report
//! was written gets one measured from its log ([`report_unfinished`], `serve` at its start).

use std::path::Path;

use crate::flightlog::flight_plan::FlightPlan;
use crate::flightlog::recorder::{
    flight_name, is_flight_dir, read_report, PLAN_FILE, REPORT_FILE, TLOG_FILE,
};
use crate::flightlog::report::FlightReport;
use crate::flightlog::resume::{
    check_same_mission, resume_chain, visits, PointVisit, ResumeError, Resumer, Resumption, Visit,
};
use crate::flightlog::segment::SegmentConfig;
use crate::flightlog::FlightLogError;
use crate::link::items::read_flight;
use crate::link::telemetry::{analyse_tlog, mission_in_tlog, Analysis, TelemetryError};
use crate::link::Flavour;
use crate::mission::Mission;
use crate::physics::{Profile, VehicleModel};

use super::predict::{plan_from_items, priced_by, repriced, FlightItemsError};
use super::recorder::flight_dirs;

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
    #[error("{file}: {reason}")]
    Profile { file: String, reason: String },
}

/// The profile an autopilot flies its missions with (`fly`'s choice unless told otherwise);
/// None for an autopilot emplan does not know.
pub fn autopilot_profile(flavour: Flavour) -> Option<Profile> {
    match flavour {
        Flavour::Px4 => Some(Profile::Px4),
        Flavour::ArduPilot => Some(Profile::Ardupilot),
        Flavour::Generic => None,
    }
}

/// The profile the flight logged at `log` was flown with: its plan's (`plan` when given, else
/// plan.json beside the log; `logfit::flown_profile`), else its autopilot's own: an onboard
/// log's (ULog: PX4, DataFlash: ArduPilot), a .tlog's by its heartbeat. None when nothing
/// says (a plan that cannot be read is left to the replay to refuse). A plan naming a profile
/// emplan does not know is refused, naming the file.
pub fn flown_profile(log: &Path, plan: Option<&Path>) -> Result<Option<Profile>, ReplayError> {
    let plan_file = match plan {
        Some(plan) => Some(plan.to_path_buf()),
        None => (log.parent().map(|d| d.join(PLAN_FILE))).filter(|p| p.is_file()),
    };
    if let Some(file) = plan_file {
        if let Ok(plan) = FlightPlan::read_json(&file) {
            let profile =
                crate::logfit::flown_profile(&plan).map_err(|reason| ReplayError::Profile {
                    file: file.display().to_string(),
                    reason: reason.to_string(),
                })?;
            if profile.is_some() {
                return Ok(profile);
            }
        }
    }
    use crate::flightlog::onboard::{format_of, Format};
    match format_of(log) {
        Some(Format::Ulog) => return Ok(Some(Profile::Px4)),
        Some(Format::Dataflash) => return Ok(Some(Profile::Ardupilot)),
        None => {}
    }
    Ok(mission_in_tlog(log)
        .ok()
        .and_then(|(_, flavour)| autopilot_profile(flavour)))
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
        plan.priced_by = Some(priced_by(model));
        plan.wind = Some(model.wind).filter(|w| !w.is_calm());
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
    #[error("{dir}: it resumes {resumes}: {cause}")]
    Later {
        dir: String,
        resumes: String,
        cause: Box<ResumeFlightError>,
    },
    #[error("{dir}: {source}")]
    Listing {
        dir: String,
        #[source]
        source: std::io::Error,
    },
}

/// What is left to fly of `mission` after the flight recorded in `dir` and every flight that
/// resumed it since (directly or down the chain: a flight directory in `dir`'s own log
/// directory or in one of `also_in` whose plan.json `resumes` it or one of them): the
/// waypoints of its plan that none of them visited. Each flight's plan (plan.json, or the
/// mission in its log) is checked to be of `mission` before anything else, then its log
/// replayed to find the waypoints it visited ([`flight_visits`]). The new flight resumes the
/// last of the chain ([`Resumption::resumes`]). Errors name the directory or the file at fault.
pub fn resume_flight(
    dir: &Path,
    mission: &Mission,
    also_in: &[&Path],
) -> Result<Resumption, ResumeFlightError> {
    let shown = dir.display().to_string();
    let first = flight_visits(dir, mission)?;
    let mut resumption = Resumption {
        flight: first.name.clone(),
        mission: mission.clone(),
        visits: first.visits,
        later: Vec::new(),
        notes: first.notes,
    };
    for later in resumed_since(dir, &first.name, also_in)? {
        let resumes = later.resumes.clone();
        let flown =
            flight_visits(&later.dir, mission).map_err(|cause| ResumeFlightError::Later {
                dir: later.dir.display().to_string(),
                resumes: resumes.clone(),
                cause: Box::new(cause),
            })?;
        resumption.notes.extend(flown.notes);
        resumption.later.push(Resumer {
            flight: flown.name,
            visited: (flown.visits.into_iter())
                .filter(|v| v.visit == Visit::Visited)
                .map(|v| v.name)
                .collect(),
        });
    }
    Ok(resume_chain(mission, resumption, &shown)?)
}

/// A flight directory that resumes another.
struct Resuming {
    dir: std::path::PathBuf,
    /// The flight it resumes (plan.json's `resumes`).
    resumes: String,
}

/// The flights that resumed the flight `name` (in `dir`) since, and those that resumed them in
/// turn, in the order they flew (their directory names begin with their start time): flight
/// directories of `dir`'s log directory and of `also_in`, each once. A directory whose
/// plan.json cannot be read resumes nothing here (it is not a flight of the chain that can be
/// told).
fn resumed_since(
    dir: &Path,
    name: &str,
    also_in: &[&Path],
) -> Result<Vec<Resuming>, ResumeFlightError> {
    let own = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());
    let log_dirs = own.parent().into_iter().chain(also_in.iter().copied());
    let mut seen = std::collections::BTreeSet::new();
    let mut candidates = Vec::new();
    for log_dir in log_dirs {
        let dirs = match flight_dirs(log_dir) {
            Ok(dirs) => dirs,
            // A log directory not made yet holds no flight.
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            Err(source) => {
                return Err(ResumeFlightError::Listing {
                    dir: log_dir.display().to_string(),
                    source,
                })
            }
        };
        for d in dirs {
            let canonical = d.canonicalize().unwrap_or_else(|_| d.clone());
            if canonical == own || !seen.insert(canonical) {
                continue;
            }
            if let Ok(Some(resumes)) = FlightPlan::read_json(&d.join(PLAN_FILE)).map(|p| p.resumes)
            {
                candidates.push((flight_name(&d), Resuming { dir: d, resumes }));
            }
        }
    }
    candidates.sort_by(|a, b| a.0.cmp(&b.0));
    let mut chain_names = vec![name.to_string()];
    let mut chain = Vec::new();
    // In flying order a flight comes after the one it resumes; going round again until nothing
    // joins keeps a chain whose names do not sort so.
    loop {
        let before = chain.len();
        for (flight, resuming) in std::mem::take(&mut candidates) {
            if chain_names.contains(&resuming.resumes) {
                chain_names.push(flight.clone());
                chain.push((flight, resuming));
            } else {
                candidates.push((flight, resuming));
            }
        }
        if chain.len() == before {
            break;
        }
    }
    chain.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(chain.into_iter().map(|(_, r)| r).collect())
}

/// What one flight did at the waypoints of its plan.
#[derive(Debug, Clone)]
pub struct FlightVisits {
    /// Its name (its flight directory's).
    pub name: String,
    pub visits: Vec<PointVisit>,
    /// What the user should know of how they were judged.
    pub notes: Vec<String>,
}

/// What the flight recorded in `dir` did at each waypoint of its plan, its plan checked to be
/// of `mission` first: its log replayed (`flightlog::resume::visits`). A log that is torn or
/// ends before the flight did (its last records lost) is said so in a note; a waypoint its
/// report.json (written from the whole live recording) counts as visited is visited even when
/// the log no longer shows it, and the note names those waypoints.
pub fn flight_visits(dir: &Path, mission: &Mission) -> Result<FlightVisits, ResumeFlightError> {
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
    let mut visits = visits(plan, &analysis.report);
    let torn = analysis.replay.torn_tail.map(|offset| {
        format!(
            "{} is torn at byte {offset} (its last record cut off)",
            tlog.display()
        )
    });
    let mut restored = Vec::new();
    if let Ok(recorded) = read_report(dir) {
        for (v, r) in visits
            .iter_mut()
            .zip(crate::flightlog::resume::visits(plan, &recorded))
        {
            if r.visit == Visit::Visited && v.visit != Visit::Visited && r.name == v.name {
                restored.push(r.name.clone());
                *v = r;
            }
        }
    }
    let report_file = dir.join(REPORT_FILE);
    let notes = match (torn, restored.is_empty()) {
        (Some(torn), true) => vec![format!(
            "{torn}: the flight is judged by what it holds up to there"
        )],
        (torn, false) => vec![format!(
            "{}: {} lists {} as visited, which the log no longer shows: they count as visited and are not flown again",
            torn.unwrap_or_else(|| format!("{} ends before its flight did", tlog.display())),
            report_file.display(),
            restored.join(", ")
        )],
        (None, true) => Vec::new(),
    };
    Ok(FlightVisits {
        name,
        visits,
        notes,
    })
}

/// The flights under `log_dir` whose recording stopped before their report was written (emplan
/// killed, or the machine stopped, mid-flight): each measured from its log against its plan and
/// its report.json written, `complete` false when the log ends in flight. A flight whose
/// recording is resumed later (the vehicle still flying) has that report replaced at its end.
/// Returns each flight directory without a report and the report written, or why none could
/// be.
pub fn report_unfinished(
    log_dir: &Path,
) -> Vec<(std::path::PathBuf, Result<FlightReport, ReplayError>)> {
    let Ok(dirs) = flight_dirs(log_dir) else {
        return Vec::new();
    };
    (dirs.into_iter())
        .filter(|dir| !dir.join(REPORT_FILE).exists())
        .map(|dir| {
            let measured = replay(&dir.join(TLOG_FILE), None, None, SegmentConfig::default())
                .and_then(|analysis| {
                    crate::flightlog::recorder::write_report(&dir, &analysis.report)
                        .map_err(TelemetryError::from)?;
                    Ok(analysis.report)
                });
            (dir, measured)
        })
        .collect()
}
