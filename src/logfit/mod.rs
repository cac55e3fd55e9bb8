//! Calibration from flight logs (`emplan calibrate --from-logs`): the vehicle's calibrated
//! parameters refitted to the leg energies measured in real flights, with leave-one-flight-out
//! validation, and a new vehicle directory written with rebuilt tables.
//!
//! Inputs are the flight directories `emplan fly` / `record` write (`flightlog::recorder`): the
//! legs' geometry comes from plan.json (the points flown, in the mission frame), their measured
//! energy from report.json (battery terminal energy from leaving hover to the 4 m crossing, the
//! same operation energy the model prices). Legs with any measurement flag (a gap, an unknown
//! current, a missed radius, an incomplete leg, ...) are left out and counted. A flight directory
//! that cannot be read (its recording cut off and never resumed, a torn file, a sample no battery
//! gives) is left out whole, named with its reason ([`Flights::skipped`]), and the others fitted.
//!
//! What each fitted parameter identifies, its bounds and their sources, how the fit keeps to
//! vehicles that can fly the envelope, and the fit itself: docs/calibration-from-logs.md.

pub mod battery;
pub mod vehicle_dir;

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::Serialize;

use crate::flightlog::flight_plan::FlightPlan;
use crate::flightlog::recorder::{read_report, PLAN_FILE, REPORT_FILE};
use crate::flightlog::report::FlightReport;
use crate::flightlog::FlightLogError;
use crate::mission::Enu;
use crate::physics::minimise::nelder_mead_restarted;
use crate::physics::power::{Model, Operation};
use crate::physics::table::{DEFAULT_XF, DEFAULT_ZF};
use crate::physics::{PhysicsError, Profile, Vehicle};

/// Everything calibration from logs can refuse; each names its flight directory or file.
#[derive(Debug, thiserror::Error)]
pub enum LogFitError {
    #[error("flight {dir}: {source}")]
    Log {
        dir: String,
        #[source]
        source: FlightLogError,
    },
    #[error("{dir}: {reason}")]
    Flight { dir: String, reason: String },
    #[error("flight {dir}, leg {leg}: {source}")]
    Pricing {
        dir: String,
        /// `from -> to (Xf .. m, Zf .. m)`.
        leg: String,
        #[source]
        source: Box<PhysicsError>,
    },
    #[error("no flight logs given")]
    NoFlights,
    #[error("flight {first} was flown with the {first_profile} profile and {other} with the {other_profile} profile: give --profile to fit them with one")]
    Profiles {
        first: String,
        first_profile: Profile,
        other: String,
        other_profile: Profile,
    },
    /// Every flight directory found was left out ([`Flights::skipped`] says why).
    #[error("no usable flight: every flight directory was left out ({})", .dirs.join(", "))]
    NoUsableFlight { dirs: Vec<String> },
    #[error("{file}: {reason}")]
    VehicleFile { file: String, reason: String },
    #[error("the {profile} table of the calibrated vehicle: {source}")]
    Table {
        profile: Profile,
        #[source]
        source: Box<LogFitError>,
    },
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    #[error(transparent)]
    Physics(Box<PhysicsError>),
}

impl From<PhysicsError> for LogFitError {
    fn from(e: PhysicsError) -> Self {
        LogFitError::Physics(Box::new(e))
    }
}

/// One leg measured in a flight.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoggedLeg {
    /// Index of its flight in [`Flights::flights`].
    pub flight: usize,
    pub from: String,
    pub to: String,
    pub xf_m: f64,
    pub zf_m: f64,
    /// Battery terminal energy from leaving hover to the 4 m crossing.
    pub measured_j: f64,
    /// Time from leaving hover to the 4 m crossing.
    pub duration_s: f64,
}

/// One hold at a waypoint measured in a flight.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoggedHover {
    /// Index of its flight in [`Flights::flights`].
    pub flight: usize,
    pub at: String,
    pub duration_s: f64,
    /// Battery terminal energy over the hold.
    pub measured_j: f64,
}

/// One flight directory read.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoggedFlight {
    pub dir: PathBuf,
    /// The flight's name (its report's).
    pub name: String,
    /// Legs measured cleanly (used).
    pub legs: usize,
    /// Legs left out: flagged, unmeasured or incomplete.
    pub skipped: usize,
    /// The profile it was flown with ([`flown_profile`]; None when its plan does not say).
    pub profile: Option<Profile>,
}

/// A flight directory left out of the fit, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SkippedFlight {
    pub dir: PathBuf,
    /// The error that left it out, naming its file (and line and column, or field).
    pub reason: String,
}

/// The flights read and their clean legs.
#[derive(Debug, Clone, PartialEq)]
pub struct Flights {
    pub flights: Vec<LoggedFlight>,
    pub legs: Vec<LoggedLeg>,
    /// The clean holds at the waypoints ([`hovers_of`]).
    pub hovers: Vec<LoggedHover>,
    /// The pack samples of the flights that have them (for [`battery::fit_battery`]).
    pub packs: Vec<battery::PackSeries>,
    /// Flight directories that could not be read (a recording cut off and never resumed, a
    /// torn or truncated file, a sample no battery can give): left out, the others fitted.
    pub skipped: Vec<SkippedFlight>,
}

/// Whether `dir` is a flight directory: it holds plan.json or flight.tlog (one without
/// plan.json was recorded with nothing to measure it against, and is left out when read).
fn is_flight_dir(dir: &Path) -> bool {
    dir.join(PLAN_FILE).is_file() || crate::flightlog::recorder::is_flight_dir(dir)
}

/// Whether `path` is a flight controller's own log (PX4 ULog, ArduPilot DataFlash): a flight
/// of its own, measured by the caller ([`read_flights_with`]).
fn is_onboard(path: &Path) -> bool {
    path.is_file() && crate::flightlog::onboard::is_onboard_log(path)
}

/// The flight directories under `paths`: a directory holding plan.json (or flight.tlog) is a
/// flight; any other directory is searched one level down for flights (the `--log-dir` that
/// `fly` makes them in).
pub fn flight_dirs(paths: &[PathBuf]) -> Result<Vec<PathBuf>, LogFitError> {
    let mut dirs = Vec::new();
    for path in paths {
        if is_flight_dir(path) || is_onboard(path) {
            dirs.push(path.clone());
            continue;
        }
        let entries = std::fs::read_dir(path).map_err(|e| LogFitError::Flight {
            dir: path.display().to_string(),
            reason: format!(
                "not a flight directory (no {PLAN_FILE}) nor a readable folder of them: {e}"
            ),
        })?;
        let mut found: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| is_flight_dir(p) || is_onboard(p))
            .collect();
        if found.is_empty() {
            return Err(LogFitError::Flight {
                dir: path.display().to_string(),
                reason: format!("no flight directory here (none holds {PLAN_FILE})"),
            });
        }
        found.sort();
        dirs.extend(found);
    }
    if dirs.is_empty() {
        return Err(LogFitError::NoFlights);
    }
    Ok(dirs)
}

/// Reads the flights in `paths` (see [`flight_dirs`]). A flight directory that cannot be read
/// is left out, named with its reason in [`Flights::skipped`] ([`calibrate`] refuses flights
/// of which none was read).
pub fn read_flights(paths: &[PathBuf]) -> Result<Flights, LogFitError> {
    read_flights_with(paths, &|path| {
        Err(format!(
            "{}: an onboard log, and this reader measures only flight directories",
            path.display()
        )
        .into())
    })
}

/// A flight controller's own log measured against its plan: the plan and the report, or why
/// not (naming the file).
pub type MeasureOnboard<'a> =
    dyn Fn(&Path) -> Result<(FlightPlan, FlightReport), OnboardError> + 'a;

/// Why the caller could not measure an onboard log (its own error, whole).
pub type OnboardError = Box<dyn std::error::Error + Send + Sync>;

/// A profile plan.json names that emplan does not know.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("priced_by.profile: {0}")]
pub struct UnknownProfile(pub crate::names::UnknownName);

/// As [`read_flights`], with the flight controllers' own logs among `paths` (PX4 .ulg,
/// ArduPilot .bin, told by their first bytes) measured by `onboard` (the session's replay: it
/// reads the log and its plan). Their pack is not fitted (no samples.csv).
pub fn read_flights_with(
    paths: &[PathBuf],
    onboard: &MeasureOnboard<'_>,
) -> Result<Flights, LogFitError> {
    let mut flights = Flights {
        flights: Vec::new(),
        legs: Vec::new(),
        hovers: Vec::new(),
        packs: Vec::new(),
        skipped: Vec::new(),
    };
    for dir in flight_dirs(paths)? {
        let index = flights.flights.len();
        if is_onboard(&dir) {
            let read = onboard(&dir)
                .map_err(|e| e.to_string())
                .and_then(|(plan, report)| {
                    let (flight, legs) =
                        legs_of((&dir, &dir), &plan, &report, index).map_err(|e| e.to_string())?;
                    Ok((flight, legs, hovers_of(&report, index)))
                });
            match read {
                Ok((flight, legs, hovers)) => {
                    flights.flights.push(flight);
                    flights.legs.extend(legs);
                    flights.hovers.extend(hovers);
                }
                Err(reason) => flights.skipped.push(SkippedFlight { dir, reason }),
            }
            continue;
        }
        let read = read_flight(&dir, index).and_then(|(flight, legs)| {
            let log = |source| LogFitError::Log {
                dir: dir.display().to_string(),
                source,
            };
            let hovers = hovers_of(&read_report(&dir).map_err(log)?, index);
            Ok((flight, legs, hovers, battery::read_pack(&dir, index)?))
        });
        match read {
            Ok((flight, legs, hovers, pack)) => {
                flights.flights.push(flight);
                flights.legs.extend(legs);
                flights.hovers.extend(hovers);
                flights.packs.extend(pack);
            }
            Err(e) => flights.skipped.push(SkippedFlight {
                dir,
                reason: skip_reason(e),
            }),
        }
    }
    Ok(flights)
}

/// Why a flight directory is left out: the error, said plainly where a file is missing.
fn skip_reason(e: LogFitError) -> String {
    let missing = |file: &str| match &e {
        LogFitError::Log {
            source: FlightLogError::Io { file: f, source },
            ..
        } => source.kind() == std::io::ErrorKind::NotFound && f.ends_with(file),
        _ => false,
    };
    if missing(REPORT_FILE) {
        format!("no {REPORT_FILE}: its recording never ended (stopped mid-flight, never resumed)")
    } else if missing(PLAN_FILE) {
        format!(
            "no {PLAN_FILE}: recorded without a flight plan, nothing to measure its legs against"
        )
    } else {
        match e {
            LogFitError::Log { source, .. } => source.to_string(),
            other => other.to_string(),
        }
    }
}

/// One flight directory: its plan (geometry) and report (measured energies); `index` numbers
/// its legs.
pub fn read_flight(
    dir: &Path,
    index: usize,
) -> Result<(LoggedFlight, Vec<LoggedLeg>), LogFitError> {
    let log = |source| LogFitError::Log {
        dir: dir.display().to_string(),
        source,
    };
    let plan = FlightPlan::read_json(&dir.join(PLAN_FILE)).map_err(log)?;
    let report = read_report(dir).map_err(log)?;
    legs_of((dir, &dir.join(REPORT_FILE)), &plan, &report, index)
}

/// The profile a flight was flown with: the one its plan was priced with (plan.json's
/// `priced_by`, which `fly` writes), else, for a plan written before it was kept, its
/// autopilot's own (what `fly` flies with unless told otherwise), told by the mission's layout:
/// ArduPilot's take-off is item 1 (its home is item 0), PX4's item 0. None when neither says.
/// A profile plan.json names and emplan does not know is refused, naming it.
pub fn flown_profile(plan: &FlightPlan) -> Result<Option<Profile>, UnknownProfile> {
    if let Some(priced) = &plan.priced_by {
        return (priced.profile.parse::<Profile>())
            .map(Some)
            .map_err(UnknownProfile);
    }
    Ok(match plan.takeoff_seq {
        Some(0) => Some(Profile::Px4),
        Some(1) => Some(Profile::Ardupilot),
        _ => None,
    })
}

/// The one profile `flights` were flown with ([`LoggedFlight::profile`]; None when none
/// says); two flights flown with different profiles are refused, naming both.
pub fn flights_profile(flights: &[LoggedFlight]) -> Result<Option<Profile>, LogFitError> {
    let mut said = flights.iter().filter_map(|f| Some((f, f.profile?)));
    let Some((first, profile)) = said.next() else {
        return Ok(None);
    };
    match said.find(|(_, p)| *p != profile) {
        None => Ok(Some(profile)),
        Some((other, other_profile)) => Err(LogFitError::Profiles {
            first: first.dir.display().to_string(),
            first_profile: profile,
            other: other.dir.display().to_string(),
            other_profile,
        }),
    }
}

/// The clean legs of flight `at.0` measured in `report` (`at.1` names it in errors) against
/// `plan`; `index` numbers them.
pub fn legs_of(
    at: (&Path, &Path),
    plan: &FlightPlan,
    report: &FlightReport,
    index: usize,
) -> Result<(LoggedFlight, Vec<LoggedLeg>), LogFitError> {
    let (dir, file) = at;
    let mut legs = Vec::new();
    let mut skipped = 0;
    // Report legs come in flying order; each is matched to the next plan leg of its names.
    let mut next = 0;
    for part in &report.legs {
        let k = (next..plan.points.len())
            .find(|&k| plan.leg_names(k) == (part.from.clone(), part.to.clone()))
            .ok_or_else(|| LogFitError::Flight {
                dir: file.display().to_string(),
                reason: format!(
                    "leg {} -> {} is not a leg of {PLAN_FILE} after leg {next}",
                    part.from, part.to
                ),
            })?;
        next = k + 1;
        let measured = part
            .measured_j
            .filter(|j| j.is_finite() && *j > 0.0 && part.flags.is_empty());
        let Some(measured_j) = measured else {
            skipped += 1;
            continue;
        };
        let from = match k {
            0 => Enu::default(),
            _ => plan.points[k - 1].enu,
        };
        let to = plan.points[k].enu;
        legs.push(LoggedLeg {
            flight: index,
            from: part.from.clone(),
            to: part.to.clone(),
            xf_m: (to.x_east_m - from.x_east_m).hypot(to.y_north_m - from.y_north_m),
            zf_m: to.z_up_m - from.z_up_m,
            measured_j,
            duration_s: part.duration_s,
        });
    }
    let profile = flown_profile(plan).map_err(|reason| LogFitError::Flight {
        dir: dir.display().to_string(),
        reason: format!("{PLAN_FILE}: {reason}"),
    })?;
    let flight = LoggedFlight {
        dir: dir.to_path_buf(),
        name: report.flight.clone(),
        legs: legs.len(),
        skipped,
        profile,
    };
    Ok((flight, legs))
}

/// The holds at the waypoints of `report` measured cleanly (no flag, at least a second long);
/// `index` numbers them.
pub fn hovers_of(report: &FlightReport, index: usize) -> Vec<LoggedHover> {
    (report.hovers.iter())
        .filter(|h| h.flags.is_empty() && h.duration_s >= 1.0)
        .filter_map(|h| {
            let measured_j = h.measured_j.filter(|j| j.is_finite() && *j > 0.0)?;
            Some(LoggedHover {
                flight: index,
                at: h.to.clone(),
                duration_s: h.duration_s,
                measured_j,
            })
        })
        .collect()
}

/// Where a fitted parameter may go.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Bounds {
    /// Multiples of the vehicle's own value (a property of the airframe, any size).
    Factor(f64, f64),
    /// Physical limits whatever the vehicle (an efficiency, a ratio).
    Absolute(f64, f64),
}

/// A parameter the flights' energies identify: its vehicle.toml key and its bounds.
pub struct Knob {
    pub key: &'static str,
    pub bounds: Bounds,
    pub get: fn(&Vehicle) -> f64,
    pub set: fn(&mut Vehicle, f64),
}

impl Knob {
    /// Its range for a vehicle where it is `value` (an absolute range widened to hold it).
    pub fn range(&self, value: f64) -> (f64, f64) {
        match self.bounds {
            Bounds::Factor(low, high) => (value * low, value * high),
            Bounds::Absolute(low, high) => (low.min(value), high.max(value)),
        }
    }
}

/// The key of the airflow's knob: fitted only with a weighed mass ([`calibrate_weighed`]).
const AIRFLOW_KEY: &str = "rotor.airflow_factor";

/// The parameters fitted to the flights' legs and holds (module docs: why these, what each
/// changes, why these bounds).
pub const KNOBS: [Knob; 6] = [
    Knob {
        key: "motor.esc_efficiency",
        bounds: Bounds::Absolute(0.5, 1.0),
        get: |v| v.motor.esc_efficiency,
        set: |v, x| v.motor.esc_efficiency = x,
    },
    Knob {
        key: "rotor.induced_power_factor",
        bounds: Bounds::Absolute(1.0, 1.5),
        get: |v| v.rotor.induced_power_factor,
        set: |v, x| v.rotor.induced_power_factor = x,
    },
    Knob {
        key: "body.mass_kg",
        bounds: Bounds::Factor(0.6, 1.6),
        get: |v| v.body.mass_kg,
        set: |v, x| v.body.mass_kg = x,
    },
    Knob {
        key: "body.drag_coefficient_n_s2_m2",
        bounds: Bounds::Factor(0.25, 4.0),
        get: |v| v.body.drag_coefficient_n_s2_m2,
        set: |v, x| v.body.drag_coefficient_n_s2_m2 = x,
    },
    Knob {
        key: "rotor.descent_inflow_factor",
        bounds: Bounds::Absolute(0.0, 1.0),
        get: |v| v.rotor.descent_inflow_factor,
        set: |v, x| v.rotor.descent_inflow_factor = x,
    },
    Knob {
        key: AIRFLOW_KEY,
        bounds: Bounds::Absolute(0.0, 1.0),
        get: |v| v.rotor.airflow_factor,
        set: |v, x| v.rotor.airflow_factor = x,
    },
];

/// A fitted parameter: its key, the value before and after, the range searched, and the bound
/// it sits at (if any).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Fitted {
    pub key: &'static str,
    pub before: f64,
    pub value: f64,
    pub low: f64,
    pub high: f64,
    /// `"low"` or `"high"` when the value sits at that bound (within 0.5% of the range): the
    /// flights asked for more than the parameter can give.
    pub at_bound: Option<&'static str>,
    /// Given, not fitted (`calibrate --mass-kg`: the weighed mass); serialised only when true.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub given: bool,
}

impl Fitted {
    /// A fitted value and its range, with the bound it sits at.
    pub fn new(key: &'static str, before: f64, value: f64, low: f64, high: f64) -> Fitted {
        let at_bound = bound_at(value, low, high);
        Fitted {
            key,
            before,
            value,
            low,
            high,
            at_bound,
            given: false,
        }
    }

    /// A value given, not fitted: no range searched, no bound.
    pub fn given(key: &'static str, before: f64, value: f64) -> Fitted {
        Fitted {
            key,
            before,
            value,
            low: value,
            high: value,
            at_bound: None,
            given: true,
        }
    }
}

/// `"low"` or `"high"` when `value` sits at that bound of `low..high` (within 0.5% of the range).
fn bound_at(value: f64, low: f64, high: f64) -> Option<&'static str> {
    let near = 0.005 * (high - low).abs();
    if value <= low + near {
        Some("low")
    } else if value >= high - near {
        Some("high")
    } else {
        None
    }
}

/// The model's operation for each leg of `legs`.
pub fn operations(
    vehicle: &Vehicle,
    profile: Profile,
    flights: &Flights,
    legs: &[&LoggedLeg],
) -> Result<Vec<Operation>, LogFitError> {
    let model = Model::new(vehicle);
    // Repeated flights of a mission repeat its legs: each geometry is simulated once, the
    // geometries in parallel.
    let mut first: Vec<usize> = Vec::new();
    let mut slot = Vec::with_capacity(legs.len());
    for (k, leg) in legs.iter().enumerate() {
        let same = |&j: &usize| {
            let other: &LoggedLeg = legs[j];
            (other.xf_m - leg.xf_m).abs() < 1e-3 && (other.zf_m - leg.zf_m).abs() < 1e-3
        };
        match first.iter().position(same) {
            Some(u) => slot.push(u),
            None => {
                slot.push(first.len());
                first.push(k);
            }
        }
    }
    let energies = first
        .par_iter()
        .map(|&k| {
            let leg = legs[k];
            model
                .operation(profile, leg.xf_m, leg.zf_m)
                .map_err(|source| LogFitError::Pricing {
                    dir: flights
                        .flights
                        .get(leg.flight)
                        .map_or_else(String::new, |f| f.dir.display().to_string()),
                    leg: format!(
                        "{} -> {} (Xf {:.1} m, Zf {:.1} m)",
                        leg.from, leg.to, leg.xf_m, leg.zf_m
                    ),
                    source: Box::new(source),
                })
        })
        .collect::<Result<Vec<Operation>, LogFitError>>()?;
    Ok(slot.iter().map(|&u| energies[u]).collect())
}

/// The model's energy for each leg of `legs` (from leaving hover to the 4 m crossing).
pub fn predict(
    vehicle: &Vehicle,
    profile: Profile,
    flights: &Flights,
    legs: &[&LoggedLeg],
) -> Result<Vec<f64>, LogFitError> {
    Ok(operations(vehicle, profile, flights, legs)?
        .iter()
        .map(|op| op.energy_j)
        .collect())
}

/// The range [`ArdupilotParams::tracking_lag_s`](crate::physics::vehicle::ArdupilotParams)
/// is fitted in: none to 3 s (a vehicle trailing its S-curve by more is not flying it).
pub const TRACKING_LAG_RANGE_S: (f64, f64) = (0.0, 3.0);

/// `vehicle` with the `ardupilot` profile's tracking lag fitted to `legs`' durations: the mean
/// of each leg's measured duration (leaving hover to the 4 m crossing) less the S-curve's own
/// (the lag set to none), within [`TRACKING_LAG_RANGE_S`]. What it is fitted to is time, not
/// energy, so it is fitted first and apart; the energy fit then starts from it. Another
/// profile: `vehicle` as it is and None.
pub fn fit_tracking_lag(
    vehicle: &Vehicle,
    profile: Profile,
    flights: &Flights,
    legs: &[&LoggedLeg],
) -> Result<(Vehicle, Option<Fitted>), LogFitError> {
    let timed: Vec<&LoggedLeg> = legs
        .iter()
        .copied()
        .filter(|l| l.duration_s.is_finite() && l.duration_s > 0.0)
        .collect();
    if profile != Profile::Ardupilot || timed.is_empty() {
        return Ok((vehicle.clone(), None));
    }
    let mut none = vehicle.clone();
    none.ardupilot.tracking_lag_s = 0.0;
    let own = operations(&none, profile, flights, &timed)?;
    let extra: f64 = (own.iter().zip(&timed))
        .map(|(op, l)| l.duration_s - op.duration_s)
        .sum::<f64>()
        / timed.len() as f64;
    let (low, high) = TRACKING_LAG_RANGE_S;
    let lag = extra.clamp(low, high);
    let fitted = Fitted::new(
        "ardupilot.tracking_lag_s",
        vehicle.ardupilot.tracking_lag_s,
        lag,
        low,
        high,
    );
    let mut v = vehicle.clone();
    v.ardupilot.tracking_lag_s = lag;
    Ok((v, Some(fitted)))
}

/// The legs a fitted vehicle must be able to fly with `profile`: the corners, edges and middle
/// of the energy tables' grid (`physics::table`'s default, Xf 0-150 m, Zf -60..+60 m), and the
/// legs whose slope lets the autopilot fly its horizontal and vertical speed limits at once
/// (the most thrust a leg asks for). A vehicle that cannot fly one of them (its motors
/// saturate, its battery cannot give the power) could not fly legs the autopilot flies,
/// whatever it fits.
pub fn envelope_legs(vehicle: &Vehicle, profile: Profile) -> Vec<(f64, f64)> {
    let (up, down, across) = match profile {
        Profile::Ardupilot => {
            let a = &vehicle.ardupilot;
            (a.wp_spd_up_m_s, a.wp_spd_dn_m_s, a.wp_spd_m_s)
        }
        Profile::Px4 => {
            let x = &vehicle.px4;
            (
                x.mpc_z_v_auto_up_m_s,
                x.mpc_z_v_auto_dn_m_s,
                x.mpc_xy_cruise_m_s,
            )
        }
        Profile::Hvb => {
            let h = &vehicle.hvb;
            (h.speed_up_m_s, h.speed_down_m_s, h.speed_xy_m_s)
        }
        Profile::Ptf => {
            let p = &vehicle.ptf;
            (p.max_speed_up_m_s, p.max_speed_down_m_s, p.max_speed_xy_m_s)
        }
    };
    let corners = [0.5 * DEFAULT_XF.end_m, DEFAULT_XF.end_m]
        .into_iter()
        .flat_map(|x| [(x, x * up / across), (x, -x * down / across)])
        .map(|(x, z): (f64, f64)| (x, z.clamp(DEFAULT_ZF.start_m, DEFAULT_ZF.end_m)));
    grid_legs().chain(corners).collect()
}

fn grid_legs() -> impl Iterator<Item = (f64, f64)> {
    let (xf, zf) = (DEFAULT_XF, DEFAULT_ZF);
    let xs = [xf.start_m, 0.2 * xf.end_m, 0.5 * xf.end_m, xf.end_m];
    let zs = [
        zf.start_m,
        zf.start_m / 3.0,
        zf.start_m / 7.5,
        0.0,
        zf.end_m / 7.5,
        zf.end_m / 3.0,
        zf.end_m,
    ];
    xs.into_iter()
        .flat_map(move |x| zs.into_iter().map(move |z| (x, z)))
        .filter(|&(x, z)| x > 0.0 || z != 0.0)
}

/// The thrust headroom the envelope keeps: its legs are flown [`ENVELOPE_MASS_MARGIN`] times
/// heavier. The envelope samples the tables' grid; a fit pressed against the motors' limit at
/// a sampled leg can fail a cell beside it (measured: a fit flying the 75 m leg climbing
/// 18.75 m with 0.00 V to spare, whose table then failed at 76 m climbing 19 m).
pub const ENVELOPE_MASS_MARGIN: f64 = 1.02;

/// The first leg of [`envelope_legs`] `vehicle` cannot fly with `profile` (with the
/// [`ENVELOPE_MASS_MARGIN`]), and why.
pub fn envelope_failure(vehicle: &Vehicle, profile: Profile) -> Option<(f64, f64, PhysicsError)> {
    let mut heavier = vehicle.clone();
    heavier.body.mass_kg *= ENVELOPE_MASS_MARGIN;
    let model = Model::new(&heavier);
    envelope_legs(vehicle, profile)
        .into_par_iter()
        .filter_map(|(x, z)| model.operation(profile, x, z).err().map(|e| (x, z, e)))
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)))
}

/// How the flight envelope bound a fit ([`fit`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EnvelopeBound {
    /// The fit's objective (the sum of squared relative errors of the legs and holds) at the
    /// vehicle fitted.
    pub objective: f64,
    /// The lowest objective of a vehicle refused for not flying the envelope.
    pub refused_objective: f64,
    /// Why that vehicle was refused: the leg and the error.
    pub refused_because: String,
}

/// (measured - predicted) / predicted in percent, the convention of the flight reports.
pub fn error_pct(predicted_j: f64, measured_j: f64) -> f64 {
    100.0 * (measured_j - predicted_j) / predicted_j
}

/// The model's energy for each hold of `hovers`: its hover power times the hold's measured time.
pub fn predict_hovers(vehicle: &Vehicle, hovers: &[&LoggedHover]) -> Result<Vec<f64>, LogFitError> {
    let power_w = crate::physics::hover_power_w(vehicle)?;
    Ok(hovers.iter().map(|h| power_w * h.duration_s).collect())
}

/// Fits [`KNOBS`] to `legs` and `hovers` (Nelder-Mead, `iterations`), starting from
/// `vehicle`'s values; the knobs keyed in `fixed` keep `vehicle`'s values (a weighed mass).
pub fn fit(
    vehicle: &Vehicle,
    profile: Profile,
    flights: &Flights,
    parts: (&[&LoggedLeg], &[&LoggedHover]),
    iterations: usize,
    fixed: &[&str],
) -> (Vehicle, Vec<Fitted>, Option<EnvelopeBound>) {
    let (legs, hovers) = parts;
    let ranges: Vec<(f64, f64, f64)> = KNOBS
        .iter()
        .map(|k| {
            let x = (k.get)(vehicle);
            let (lo, hi) = k.range(x);
            if fixed.contains(&k.key) {
                return (x, x, x);
            }
            (x, lo, hi)
        })
        .collect();
    // Searched in units of the starting values (every parameter near 1; a parameter starting
    // at 0 in units of its range's middle).
    let scales: Vec<f64> = ranges
        .iter()
        .map(|&(x, lo, hi)| if x != 0.0 { x } else { 0.5 * (lo + hi) })
        .collect();
    let apply = |x: &[f64]| {
        let mut v = vehicle.clone();
        for ((knob, (&(_, lo, hi), scale)), &u) in
            KNOBS.iter().zip(ranges.iter().zip(&scales)).zip(x)
        {
            (knob.set)(&mut v, (scale * u).clamp(lo, hi));
        }
        v
    };
    // Outside its range a parameter is clamped, which leaves the objective flat there and lets
    // the simplex wander off and stall: a penalty, growing with the distance past the bound
    // (in units of the range), leads it back. Zero within every range.
    let outside = |x: &[f64]| -> f64 {
        (ranges.iter().zip(&scales).zip(x))
            .map(|((&(_, lo, hi), scale), &u)| {
                let value = scale * u;
                let past = (lo - value).max(value - hi).max(0.0) / (hi - lo).max(f64::EPSILON);
                10.0 * past * past
            })
            .sum()
    };
    let objective = |x: &[f64]| -> f64 {
        let v = apply(x);
        let (Ok(leg_j), Ok(hover_j)) = (
            predict(&v, profile, flights, legs),
            predict_hovers(&v, hovers),
        ) else {
            return f64::INFINITY;
        };
        let squared = |p: &f64, m: f64| (m / p - 1.0).powi(2);
        let legs: f64 = (leg_j.iter().zip(legs))
            .map(|(p, l)| squared(p, l.measured_j))
            .sum();
        let holds: f64 = (hover_j.iter().zip(hovers))
            .map(|(p, h)| squared(p, h.measured_j))
            .sum();
        legs + holds + outside(x)
    };
    // Only vehicles that can fly the profile's envelope: the lowest objective of one refused
    // is kept, to say whether the envelope bound the fit.
    let refused: std::sync::Mutex<Option<(f64, String)>> = std::sync::Mutex::new(None);
    let refuse = |value: f64, (xf, zf, e): (f64, f64, PhysicsError)| {
        let why = match e {
            // It names the leg.
            PhysicsError::NoTrajectory { .. } => e.to_string(),
            e => format!("Xf {xf} m, Zf {zf} m: {e}"),
        };
        if let Ok(mut r) = refused.lock() {
            if r.as_ref().is_none_or(|(v, _)| value < *v) {
                *r = Some((value, why));
            }
        }
    };
    let constrained = |x: &[f64]| -> f64 {
        let value = objective(x);
        if !value.is_finite() {
            return value;
        }
        match envelope_failure(&apply(x), profile) {
            None => value,
            Some(failure) => {
                refuse(value, failure);
                f64::INFINITY
            }
        }
    };
    // Each first step into the range: down from a value at its high bound (an efficiency of 1,
    // a descent inflow of 1), where a step up would clamp back onto the start and leave the
    // simplex flat in that direction.
    let step: Vec<f64> = ranges
        .iter()
        .zip(&scales)
        .map(|(&(x, lo, hi), scale)| {
            if lo == hi {
                0.0
            } else if x + 0.1 * scale > hi {
                -0.1
            } else {
                0.1
            }
        })
        .collect();
    // The free fit first: when it flies the envelope, the envelope did not bind and the search
    // never meets its wall (a wall of infinities can stall the simplex short of the optimum).
    // Only a free fit that cannot fly the envelope is searched again within it.
    let search = |start: &[f64]| {
        let minimise = |f: &dyn Fn(&[f64]) -> f64| {
            nelder_mead_restarted(start, &step, iterations, RESTARTS, TOLERANCE, &f).0
        };
        let free = minimise(&objective);
        match envelope_failure(&apply(&free), profile) {
            None => free,
            Some(failure) => {
                refuse(objective(&free), failure);
                minimise(&constrained)
            }
        }
    };
    // Two starts: the vehicle's values, and the same with every parameter that sits at a bound
    // of its physical range (an efficiency of 1, a descent inflow of 1) started from the
    // range's middle. From a bound the simplex can settle in another valley (measured on
    // ArduCopter SITL's flights: a descent inflow left at 1 and the legs' rms 6.9%, against
    // 3.9% with it at 0.43 when started from 0.5); the lower objective is kept.
    let scored = |start: &[f64]| {
        let x = search(start);
        (objective(&x), x)
    };
    let (vehicle_start, middle_start) = fit_starts(&ranges, &scales);
    let (mut best_value, mut best) = scored(&vehicle_start);
    if let Some((value, x)) = middle_start.map(|start| scored(&start)) {
        if value < best_value {
            (best_value, best) = (value, x);
        }
    }
    let bound = refused
        .into_inner()
        .ok()
        .flatten()
        .filter(|(v, _)| *v < best_value)
        .map(|(v, why)| EnvelopeBound {
            objective: best_value,
            refused_objective: v,
            refused_because: why,
        });
    let fitted_vehicle = apply(&best);
    let fitted = KNOBS
        .iter()
        .zip(&ranges)
        .map(|(knob, &(before, low, high))| {
            let value = (knob.get)(&fitted_vehicle);
            if fixed.contains(&knob.key) {
                Fitted::given(knob.key, before, value)
            } else {
                Fitted::new(knob.key, before, value, low, high)
            }
        })
        .collect();
    (fitted_vehicle, fitted, bound)
}

/// The fit's starting points in search units ([`fit`]): the vehicle's values (all 1), and,
/// when any parameter of an absolute range sits at one of its bounds, the same with those
/// parameters at their range's middle.
fn fit_starts(ranges: &[(f64, f64, f64)], scales: &[f64]) -> (Vec<f64>, Option<Vec<f64>>) {
    let vehicle: Vec<f64> = ranges
        .iter()
        .zip(scales)
        .map(|(&(x, _, _), scale)| x / scale)
        .collect();
    let at_bound = |&(x, lo, hi): &(f64, f64, f64)| bound_at(x, lo, hi).is_some();
    let absolute = KNOBS
        .iter()
        .map(|k| matches!(k.bounds, Bounds::Absolute(..)));
    let middle: Vec<f64> = ranges
        .iter()
        .zip(scales)
        .zip(absolute)
        .map(|((r, scale), absolute)| {
            if absolute && at_bound(r) {
                0.5 * (r.1 + r.2) / scale
            } else {
                r.0 / scale
            }
        })
        .collect();
    let second = (middle != vehicle).then_some(middle);
    (vehicle, second)
}

/// Per-leg error statistics, percent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorStats {
    pub legs: usize,
    pub rms_pct: f64,
    pub mean_pct: f64,
    /// The largest absolute error.
    pub worst_pct: f64,
}

impl ErrorStats {
    pub fn of(errors: &[f64]) -> ErrorStats {
        let n = errors.len().max(1) as f64;
        ErrorStats {
            legs: errors.len(),
            rms_pct: (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt(),
            mean_pct: errors.iter().sum::<f64>() / n,
            worst_pct: errors.iter().map(|e| e.abs()).fold(0.0, f64::max),
        }
    }
}

/// One leg before and after, and left out.
#[derive(Debug, Clone, PartialEq)]
pub struct LegResult {
    pub leg: LoggedLeg,
    /// The given vehicle's prediction.
    pub before_j: f64,
    /// The prediction of the vehicle fitted to every flight.
    pub after_j: f64,
    /// The prediction of the vehicle fitted to every other flight (leave-one-flight-out).
    pub held_out_j: Option<f64>,
}

/// One flight left out: what the others fitted and the error on it.
#[derive(Debug, Clone, PartialEq)]
pub struct HeldOut {
    pub flight: usize,
    pub fitted: Vec<Fitted>,
    pub errors: ErrorStats,
}

/// The result of `calibrate --from-logs`.
#[derive(Debug, Clone)]
pub struct LogCalibration {
    pub profile: Profile,
    pub flights: Vec<LoggedFlight>,
    pub legs: Vec<LegResult>,
    /// Fitted to every flight.
    pub fitted: Vec<Fitted>,
    pub vehicle: Vehicle,
    /// One per flight (none with a single flight).
    pub held_out: Vec<HeldOut>,
    /// The pack fitted to the flights' voltage and current (None without samples).
    pub battery: Option<battery::BatteryFit>,
    /// Flight directories left out, and why ([`Flights::skipped`]).
    pub skipped: Vec<SkippedFlight>,
    /// The holds' errors (hover power times the measured time against the measured energy)
    /// with the given vehicle and the fitted one (None: no clean hold).
    pub hovers: Option<(ErrorStats, ErrorStats)>,
    /// Every value changed ([`LogCalibration::values`]).
    values: Vec<Fitted>,
    /// Where the fit was held to vehicles that can fly the profile's envelope
    /// ([`envelope_legs`]) against flights that asked for one that cannot (None: it did not
    /// bind).
    pub envelope: Option<EnvelopeBound>,
}

/// The values a calibration changes in the vehicle file (see [`LogCalibration::values`]).
fn changed_values(
    vehicle: &Vehicle,
    fitted: &[Fitted],
    battery: Option<&battery::BatteryFit>,
) -> Vec<Fitted> {
    let mut values = fitted.to_vec();
    if let Some(b) = battery {
        values.extend(b.fitted.iter().cloned());
        if let Some(c) = b.fitted.iter().find(|f| f.key == "battery.capacity_ah") {
            let wh = vehicle.planning.usable_energy_wh;
            values.push(Fitted::new(
                "planning.usable_energy_wh",
                wh,
                wh * c.value / c.before,
                wh * c.low / c.before,
                wh * c.high / c.before,
            ));
        }
    }
    values
}

/// Nelder-Mead iterations of each fit and start (five parameters; at 160 the simplex stopped
/// short on ArduCopter SITL's flights, objectives 0.04-0.06 against 0.014-0.019 at 600).
pub const ITERATIONS: usize = 600;

/// How often a fit's simplex is restarted from where it stopped, at most; a restart that no
/// longer lowers the objective by [`TOLERANCE`] ends the search.
const RESTARTS: usize = 4;

/// The relative spread of the simplex's objectives at which it has converged.
const TOLERANCE: f64 = 1e-9;

/// Fits `vehicle` flown with `profile` to `flights`: before, after, and leave-one-flight-out.
pub fn calibrate(
    vehicle: &Vehicle,
    profile: Profile,
    flights: &Flights,
) -> Result<LogCalibration, LogFitError> {
    calibrate_weighed(vehicle, profile, flights, None)
}

/// [`calibrate`] with the airframe's weighed take-off mass when known (`calibrate --mass-kg`):
/// set, not fitted. Mass, efficiency and kappa all raise the hover power, and the holds and
/// legs of a few flights tell them apart only by the climbs' m g v_z and the accelerations, so
/// a fit of all three wanders along that valley (module docs); a scale fixes the one that can
/// be measured.
pub fn calibrate_weighed(
    vehicle: &Vehicle,
    profile: Profile,
    flights: &Flights,
    mass_kg: Option<f64>,
) -> Result<LogCalibration, LogFitError> {
    let original = vehicle;
    let mut weighed = vehicle.clone();
    let mut fixed: Vec<&str> = Vec::new();
    if let Some(mass) = mass_kg {
        weighed.body.mass_kg = mass;
        weighed.validate("--mass-kg")?;
        fixed.push("body.mass_kg");
    }
    // Unweighed, the airflow is held at the vehicle's value, not fitted: a climb's work through
    // the disk is the airflow times m g v_z / eta, so without the mass the airflow, mass and
    // efficiency trade along the climbs (measured on the built-in mock's flights of a vehicle
    // at airflow 1: a fit of all six put it at 0.81 with the mass at 3.99 kg against 6.39 and
    // the efficiency at its 0.5 bound). Held knobs are left out of `fitted`.
    let held: &[&str] = if mass_kg.is_some() {
        &[]
    } else {
        &[AIRFLOW_KEY]
    };
    fixed.extend_from_slice(held);
    let vehicle = &weighed;
    if flights.flights.is_empty() {
        return Err(LogFitError::NoUsableFlight {
            dirs: flights
                .skipped
                .iter()
                .map(|s| s.dir.display().to_string())
                .collect(),
        });
    }
    if flights.legs.is_empty() {
        return Err(LogFitError::Flight {
            dir: flights
                .flights
                .iter()
                .map(|f| f.dir.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
            reason: "no cleanly measured leg in these flights (every leg flagged or unmeasured)"
                .into(),
        });
    }
    let all: Vec<&LoggedLeg> = flights.legs.iter().collect();
    let holds: Vec<&LoggedHover> = flights.hovers.iter().collect();
    let before = predict(original, profile, flights, &all)?;
    // The pack first (its resistance sags the voltage the motors have: what the envelope
    // needs), then the tracking lag from the legs' durations, then the energies.
    let battery = battery::fit_battery(vehicle, &flights.packs);
    let mut packed = vehicle.clone();
    for f in battery.iter().flat_map(|b| &b.fitted) {
        vehicle_dir::set_value(&mut packed, f.key, f.value);
    }
    let (lagged, lag) = fit_tracking_lag(&packed, profile, flights, &all)?;
    let (mut fitted_vehicle, mut fitted, envelope) = fit(
        &lagged,
        profile,
        flights,
        (&all, &holds),
        ITERATIONS,
        &fixed,
    );
    // A given value was the original vehicle's before.
    for (f, knob) in fitted.iter_mut().zip(&KNOBS) {
        if f.given {
            f.before = (knob.get)(original);
        }
    }
    fitted.retain(|f| !held.contains(&f.key));
    let after = predict(&fitted_vehicle, profile, flights, &all)?;
    let hover_errors = |v: &Vehicle| -> Result<ErrorStats, LogFitError> {
        let predicted = predict_hovers(v, &holds)?;
        let errors: Vec<f64> = (predicted.iter().zip(&holds))
            .map(|(p, h)| error_pct(*p, h.measured_j))
            .collect();
        Ok(ErrorStats::of(&errors))
    };
    let hovers = (!holds.is_empty())
        .then(|| Ok::<_, LogFitError>((hover_errors(original)?, hover_errors(&fitted_vehicle)?)))
        .transpose()?;
    let mut held_out_j: Vec<Option<f64>> = vec![None; all.len()];
    let mut held_out = Vec::new();
    let flown: Vec<usize> = (0..flights.flights.len())
        .filter(|&f| flights.legs.iter().any(|l| l.flight == f))
        .collect();
    if flown.len() >= 2 {
        for &f in &flown {
            let train: Vec<&LoggedLeg> = all.iter().copied().filter(|l| l.flight != f).collect();
            let train_holds: Vec<&LoggedHover> =
                holds.iter().copied().filter(|h| h.flight != f).collect();
            let test: Vec<usize> = (0..all.len()).filter(|&k| all[k].flight == f).collect();
            let (train_lagged, _) = fit_tracking_lag(&packed, profile, flights, &train)?;
            let (v, mut values, _) = fit(
                &train_lagged,
                profile,
                flights,
                (&train, &train_holds),
                ITERATIONS,
                &fixed,
            );
            values.retain(|f| !held.contains(&f.key));
            let test_legs: Vec<&LoggedLeg> = test.iter().map(|&k| all[k]).collect();
            let predicted = predict(&v, profile, flights, &test_legs)?;
            let errors: Vec<f64> = predicted
                .iter()
                .zip(&test_legs)
                .map(|(p, l)| error_pct(*p, l.measured_j))
                .collect();
            for (&k, &p) in test.iter().zip(&predicted) {
                held_out_j[k] = Some(p);
            }
            held_out.push(HeldOut {
                flight: f,
                fitted: values,
                errors: ErrorStats::of(&errors),
            });
        }
    }
    let legs = all
        .iter()
        .zip(before.iter().zip(&after).zip(&held_out_j))
        .map(|(leg, ((&b, &a), &h))| LegResult {
            leg: (*leg).clone(),
            before_j: b,
            after_j: a,
            held_out_j: h,
        })
        .collect();
    let with_lag: Vec<Fitted> = fitted.iter().cloned().chain(lag).collect();
    let values = changed_values(vehicle, &with_lag, battery.as_ref());
    for f in &values {
        vehicle_dir::set_value(&mut fitted_vehicle, f.key, f.value);
    }
    Ok(LogCalibration {
        profile,
        flights: flights.flights.clone(),
        legs,
        fitted,
        vehicle: fitted_vehicle,
        held_out,
        battery,
        skipped: flights.skipped.clone(),
        hovers,
        values,
        envelope,
    })
}

impl LogCalibration {
    /// Every value the calibrated vehicle file changes: the leg fit's, the pack's, and the
    /// planning budget's usable energy scaled with the fitted capacity.
    pub fn values(&self) -> Vec<Fitted> {
        self.values.clone()
    }

    /// The fitted values sitting at a bound of their range (the leg fit's and the pack's).
    pub fn at_bound(&self) -> Vec<&Fitted> {
        self.values
            .iter()
            .filter(|f| f.at_bound.is_some())
            .collect()
    }

    /// Errors of the given vehicle on every leg.
    pub fn before(&self) -> ErrorStats {
        ErrorStats::of(&self.errors(|l| Some(l.before_j)))
    }

    /// Errors of the vehicle fitted to every flight, on every leg (in sample).
    pub fn after(&self) -> ErrorStats {
        ErrorStats::of(&self.errors(|l| Some(l.after_j)))
    }

    /// Leave-one-flight-out errors over every leg (None with a single flight).
    pub fn held_out_errors(&self) -> Option<ErrorStats> {
        let e = self.errors(|l| l.held_out_j);
        (!e.is_empty()).then(|| ErrorStats::of(&e))
    }

    /// Percent errors of one prediction of each leg (where it has one) against its measurement.
    fn errors(&self, predicted_j: impl Fn(&LegResult) -> Option<f64>) -> Vec<f64> {
        self.legs
            .iter()
            .filter_map(|l| predicted_j(l).map(|p| error_pct(p, l.leg.measured_j)))
            .collect()
    }

    /// `emplan calibrate --from-logs --json` (kJ at this edge; `fitted` as in `calibrate --fit`,
    /// with each value's `before`).
    pub fn to_json(&self) -> serde_json::Value {
        let kj = |j: f64| j / 1000.0;
        let legs: Vec<serde_json::Value> = self
            .legs
            .iter()
            .map(|l| {
                let m = l.leg.measured_j;
                serde_json::json!({
                    "flight": self.flights.get(l.leg.flight).map(|f| f.name.clone()),
                    "from": l.leg.from,
                    "to": l.leg.to,
                    "xf_m": l.leg.xf_m,
                    "zf_m": l.leg.zf_m,
                    "measured_kj": kj(m),
                    "before_kj": kj(l.before_j),
                    "before_error_pct": error_pct(l.before_j, m),
                    "after_kj": kj(l.after_j),
                    "after_error_pct": error_pct(l.after_j, m),
                    "held_out_kj": l.held_out_j.map(kj),
                    "held_out_error_pct": l.held_out_j.map(|p| error_pct(p, m)),
                })
            })
            .collect();
        serde_json::json!({
            "profile": self.profile,
            "flights": self.flights.iter().map(|f| serde_json::json!({
                "dir": f.dir.display().to_string(),
                "flight": f.name,
                "legs": f.legs,
                "skipped": f.skipped,
                "profile": f.profile,
            })).collect::<Vec<_>>(),
            "legs": legs,
            "before": self.before(),
            "after": self.after(),
            "held_out": self.held_out_errors(),
            "leave_one_out": self.held_out.iter().map(|h| serde_json::json!({
                "flight": self.flights.get(h.flight).map(|f| f.name.clone()),
                "fitted": h.fitted,
                "errors": h.errors,
            })).collect::<Vec<_>>(),
            "fitted": self.fitted,
            "at_bound": self.at_bound().iter().map(|f| serde_json::json!({
                "key": f.key,
                "bound": f.at_bound,
                "value": f.value,
            })).collect::<Vec<_>>(),
            "hovers": self.hovers.map(|(before, after)| serde_json::json!({
                "before": before,
                "after": after,
            })),
            "battery": self.battery,
            "envelope_bound": self.envelope,
            "changed": self.values,
            "skipped_flights": self.skipped,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shipped() -> Vehicle {
        Vehicle::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000"))
            .expect("the shipped vehicle")
    }

    /// Legs "measured" as `truth` prices them with the hvb profile, two per flight.
    fn flights_of(truth: &Vehicle) -> Flights {
        let geometry = [
            (40.0, 25.0),
            (40.0, -1.0),
            (56.6, 0.0),
            (0.0, -24.0),
            (80.0, 10.0),
            (20.0, 0.0),
        ];
        flights_flown(truth, Profile::Hvb, &geometry)
    }

    /// Legs of `geometry` "measured" (energy and duration) as `truth` prices them with
    /// `profile`, two per flight, and two 5 s holds a flight.
    fn flights_flown(truth: &Vehicle, profile: Profile, geometry: &[(f64, f64)]) -> Flights {
        let model = Model::new(truth);
        let legs = geometry
            .iter()
            .enumerate()
            .map(|(k, &(xf_m, zf_m))| LoggedLeg {
                flight: k / 2,
                from: format!("P{k}"),
                to: format!("P{}", k + 1),
                xf_m,
                zf_m,
                measured_j: model.operation(profile, xf_m, zf_m).unwrap().energy_j,
                duration_s: model.operation(profile, xf_m, zf_m).unwrap().duration_s,
            })
            .collect();
        let count = geometry.len().div_ceil(2);
        Flights {
            flights: (0..count)
                .map(|f| LoggedFlight {
                    dir: PathBuf::from(format!("flight{f}")),
                    name: format!("flight{f}"),
                    legs: 2,
                    skipped: 0,
                    profile: None,
                })
                .collect(),
            legs,
            // Two 5 s holds a flight, at the truth's hover power.
            hovers: (0..2 * count)
                .map(|k| LoggedHover {
                    flight: k / 2,
                    at: format!("P{k}"),
                    duration_s: 5.0,
                    measured_j: 5.0 * crate::physics::hover_power_w(truth).unwrap(),
                })
                .collect(),
            packs: Vec::new(),
            skipped: Vec::new(),
        }
    }

    #[test]
    fn the_fit_recovers_a_vehicle_less_efficient_heavier_and_draggier() {
        let given = shipped();
        let mut truth = given.clone();
        truth.motor.esc_efficiency = 0.75;
        truth.rotor.induced_power_factor = 1.2;
        truth.body.mass_kg *= 1.1;
        truth.body.drag_coefficient_n_s2_m2 *= 1.3;
        let flights = flights_of(&truth);
        let c = calibrate(&given, Profile::Hvb, &flights).unwrap();
        assert!(c.before().rms_pct > 20.0, "{:?}", c.before());
        assert!(c.after().worst_pct < 1.0, "{:?}", c.after());
        let held_out = c.held_out_errors().expect("three flights");
        assert!(held_out.worst_pct < 2.0, "{held_out:?}");
        assert_eq!(c.held_out.len(), 3);
        let (hovers_before, hovers_after) = c.hovers.expect("holds measured");
        assert!(hovers_before.rms_pct > 20.0, "{hovers_before:?}");
        assert!(hovers_after.worst_pct < 1.0, "{hovers_after:?}");
        // Most of the difference is the powertrain's efficiency, found within a few percent.
        let eta = c.vehicle.motor.esc_efficiency / truth.motor.esc_efficiency;
        assert!((eta - 1.0).abs() < 0.05, "{eta}");
        // Only the descent's inflow sits at a bound: the truth's, momentum theory's 1.
        let at: Vec<_> = c.at_bound().iter().map(|f| (f.key, f.at_bound)).collect();
        assert_eq!(at, [("rotor.descent_inflow_factor", Some("high"))]);
    }

    #[test]
    fn a_weighed_mass_is_kept_and_the_propulsion_fitted_around_it() {
        let given = shipped();
        let mut truth = given.clone();
        truth.motor.esc_efficiency = 0.75;
        truth.body.mass_kg *= 1.2;
        truth.rotor.descent_inflow_factor = 0.4;
        let flights = flights_of(&truth);
        let c =
            calibrate_weighed(&given, Profile::Hvb, &flights, Some(truth.body.mass_kg)).unwrap();
        assert_eq!(c.vehicle.body.mass_kg, truth.body.mass_kg);
        let mass = c.fitted.iter().find(|f| f.key == "body.mass_kg").unwrap();
        assert!(mass.given && mass.at_bound.is_none(), "{mass:?}");
        assert_eq!(mass.before, given.body.mass_kg);
        assert_eq!(c.to_json()["changed"][2]["given"], true);
        assert!(c.after().worst_pct < 1.0, "{:?}", c.after());
        let eta = c.vehicle.motor.esc_efficiency / truth.motor.esc_efficiency;
        assert!((eta - 1.0).abs() < 0.03, "{eta}");
        let descent = c.vehicle.rotor.descent_inflow_factor;
        assert!((descent - 0.4).abs() < 0.1, "{descent}");
        // Fitted, the mass is not `given`.
        let free = calibrate(&given, Profile::Hvb, &flights).unwrap();
        assert!(free.fitted.iter().all(|f| !f.given));
        assert!(free.to_json()["changed"][2].get("given").is_none());
    }

    #[test]
    fn the_airflow_is_fitted_with_a_weighed_mass_and_held_without_one() {
        let given = shipped();
        let mut truth = given.clone();
        truth.motor.esc_efficiency = 0.7;
        truth.rotor.airflow_factor = 0.3;
        let flights = flights_of(&truth);
        let weighed =
            calibrate_weighed(&given, Profile::Hvb, &flights, Some(truth.body.mass_kg)).unwrap();
        let airflow = weighed.vehicle.rotor.airflow_factor;
        assert!((airflow - 0.3).abs() < 0.05, "{airflow}");
        assert!(weighed.after().worst_pct < 1.0, "{:?}", weighed.after());
        assert!(weighed.fitted.iter().any(|f| f.key == AIRFLOW_KEY));
        // Unweighed: held at the vehicle's 1, and not listed as fitted.
        let free = calibrate(&given, Profile::Hvb, &flights).unwrap();
        assert_eq!(free.vehicle.rotor.airflow_factor, 1.0);
        assert!(free.fitted.iter().all(|f| f.key != AIRFLOW_KEY));
        assert!(free
            .held_out
            .iter()
            .all(|h| h.fitted.len() == KNOBS.len() - 1));
    }

    #[test]
    fn a_weighed_mass_out_of_range_is_refused_naming_the_flag_and_key() {
        let flights = flights_of(&shipped());
        let err = calibrate_weighed(&shipped(), Profile::Hvb, &flights, Some(500.0))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("--mass-kg") && err.contains("body.mass_kg"),
            "{err}"
        );
    }

    #[test]
    fn a_parameter_at_a_bound_of_its_physical_range_gets_a_second_start_from_the_middle() {
        // (value, low, high) in KNOBS' order: efficiency inside, kappa at its low bound, mass
        // and drag (ranges of factors) inside, the descent inflow at its high bound.
        let ranges = [
            (0.95, 0.5, 1.0),
            (1.0, 1.0, 1.5),
            (5.0, 3.0, 8.0),
            (0.2, 0.05, 0.8),
            (1.0, 0.0, 1.0),
        ];
        let scales = [0.95, 1.0, 5.0, 0.2, 1.0];
        let (vehicle, middle) = fit_starts(&ranges, &scales);
        assert_eq!(vehicle, vec![1.0; 5]);
        assert_eq!(middle, Some(vec![1.0, 1.25, 1.0, 1.0, 0.5]));
        // Nothing at a bound: one start.
        let inside = [
            (0.9, 0.5, 1.0),
            (1.2, 1.0, 1.5),
            (5.0, 3.0, 8.0),
            (0.2, 0.05, 0.8),
            (0.5, 0.0, 1.0),
        ];
        assert_eq!(fit_starts(&inside, &[0.9, 1.2, 5.0, 0.2, 0.5]).1, None);
    }

    #[test]
    fn arducopter_sitl_flights_with_the_frames_weighed_mass_fit_rotors_that_hardly_feel_the_airflow(
    ) {
        // ArduCopter SITL's frame (s1000.json, 6.971 kg) draws power in proportion to its
        // thrust whatever its airspeed (SIM_Motor.cpp): given its mass, the fit finds little of
        // the airspeed in the rotors' aerodynamics, the induced power factor back off its
        // bound, and the legs closer than the fits without the airflow could bring them (rms
        // 3.3-3.4% with the descent's inflow alone, 5.3-5.8% with neither).
        let flights = arducopter_sitl_flights();
        let c = calibrate_weighed(&shipped(), Profile::Ardupilot, &flights, Some(6.971)).unwrap();
        let airflow = c.vehicle.rotor.airflow_factor;
        assert!(airflow < 0.4, "{airflow}");
        assert!(c.vehicle.rotor.induced_power_factor < 1.4, "{:?}", c.fitted);
        assert!(c.after().rms_pct < 2.5, "{:?}", c.after());
        let held_out = c.held_out_errors().expect("two flights");
        assert!(held_out.worst_pct < 6.0, "{held_out:?}");
        assert!(c.envelope.is_none(), "{:?}", c.envelope);
    }

    #[test]
    fn the_tracking_lag_is_the_time_the_legs_take_beyond_the_ardupilot_scurve() {
        let given = shipped();
        let mut truth = given.clone();
        truth.ardupilot.tracking_lag_s = 1.1;
        let flights = flights_flown(&truth, Profile::Ardupilot, &[(40.0, 25.0), (33.0, -8.0)]);
        let legs: Vec<&LoggedLeg> = flights.legs.iter().collect();
        let (v, lag) = fit_tracking_lag(&given, Profile::Ardupilot, &flights, &legs).unwrap();
        let lag = lag.expect("fitted for the ardupilot profile");
        assert_eq!(lag.key, "ardupilot.tracking_lag_s");
        assert!((lag.value - 1.1).abs() < 1e-6, "{lag:?}");
        assert!((lag.before - given.ardupilot.tracking_lag_s).abs() < 1e-12);
        assert_eq!(v.ardupilot.tracking_lag_s, lag.value);
        // Priced with it, each leg takes as long as measured.
        let ops = operations(&v, Profile::Ardupilot, &flights, &legs).unwrap();
        for (op, leg) in ops.iter().zip(&legs) {
            assert!((op.duration_s - leg.duration_s).abs() < 1e-6, "{leg:?}");
        }
        // The other profiles have no such lag.
        let (same, none) = fit_tracking_lag(&given, Profile::Px4, &flights, &legs).unwrap();
        assert!(none.is_none());
        assert_eq!(same, given);
    }

    /// ArduCopter SITL's flights of the two paper samples (`sitl/ardupilot-calibrate.sh`,
    /// docs/ardupilot-sitl.md): each leg's Xf, Zf, measured energy (J) and duration (s), and each
    /// hold's duration and energy. Their 17-57 m legs never reach WP_SPD.
    fn arducopter_sitl_flights() -> Flights {
        let legs = [
            (16.971, -11.0, 8081.8, 8.070),
            (32.985, -8.0, 8702.9, 8.453),
            (56.569, 0.0, 11248.4, 10.445),
            (32.985, 8.0, 9263.0, 8.410),
            (24.0, 22.0, 11658.2, 10.288),
            (32.985, 8.0, 9193.6, 8.340),
            (56.569, 0.0, 11280.2, 10.477),
            (32.985, -8.0, 8643.7, 8.397),
            (16.971, -11.0, 8465.0, 8.419),
            (40.0, 25.0, 13880.3, 12.287),
            (40.0, -1.0, 9594.6, 9.020),
            (40.0, 1.0, 9510.3, 8.863),
            (40.0, -25.0, 18038.0, 17.902),
        ];
        let holds = [
            (6.183, 6502.6),
            (5.894, 6184.6),
            (5.995, 6289.2),
            (5.908, 6192.2),
            (6.084, 6359.3),
            (5.918, 6202.6),
            (5.990, 6283.1),
            (5.913, 6204.9),
            (1.180, 1263.4),
            (6.005, 6282.7),
            (5.868, 6154.4),
            (5.824, 6108.3),
            (1.203, 1290.3),
        ];
        let flight_of = |k: usize| usize::from(k >= 9);
        Flights {
            flights: (0..2)
                .map(|f| LoggedFlight {
                    dir: PathBuf::from(format!("flight{f}")),
                    name: format!("flight{f}"),
                    legs: if f == 0 { 9 } else { 4 },
                    skipped: 0,
                    profile: None,
                })
                .collect(),
            legs: (legs.iter().enumerate())
                .map(|(k, &(xf_m, zf_m, measured_j, duration_s))| LoggedLeg {
                    flight: flight_of(k),
                    from: format!("P{k}"),
                    to: format!("P{}", k + 1),
                    xf_m,
                    zf_m,
                    measured_j,
                    duration_s,
                })
                .collect(),
            hovers: (holds.iter().enumerate())
                .map(|(k, &(duration_s, measured_j))| LoggedHover {
                    flight: flight_of(k),
                    at: format!("P{k}"),
                    duration_s,
                    measured_j,
                })
                .collect(),
            packs: Vec::new(),
            skipped: Vec::new(),
        }
    }

    #[test]
    fn a_fit_to_arducopter_sitl_flights_is_held_to_a_vehicle_that_flies_the_profiles_envelope() {
        // Fitted freely with the descent's inflow and the airflow as momentum theory has them
        // (the four knobs before they were knobs), they ask for a vehicle so heavy and draggy that its motors
        // saturate on a 75 m leg climbing at WP_SPD and WP_SPD_UP at once.
        let flights = arducopter_sitl_flights();
        let given = shipped();
        let legs: Vec<&LoggedLeg> = flights.legs.iter().collect();
        let holds: Vec<&LoggedHover> = flights.hovers.iter().collect();
        let (lagged, lag) = fit_tracking_lag(&given, Profile::Ardupilot, &flights, &legs).unwrap();
        let lag = lag.expect("fitted").value;
        assert!((lag - 0.685).abs() < 0.01, "{lag}");
        let (v, _, bound) = fit(
            &lagged,
            Profile::Ardupilot,
            &flights,
            (&legs, &holds),
            ITERATIONS,
            &["rotor.descent_inflow_factor", "rotor.airflow_factor"],
        );
        assert!(
            envelope_failure(&v, Profile::Ardupilot).is_none(),
            "mass {} kg, drag {}",
            v.body.mass_kg,
            v.body.drag_coefficient_n_s2_m2
        );
        let bound = bound.expect("the envelope bound the fit");
        assert!(bound.refused_objective < bound.objective, "{bound:?}");
        assert!(
            bound.refused_because.contains("motors saturated"),
            "{bound:?}"
        );
        // The shipped vehicle flies every leg of the envelope of every profile.
        for profile in [Profile::Ptf, Profile::Hvb, Profile::Px4, Profile::Ardupilot] {
            assert!(envelope_failure(&given, profile).is_none(), "{profile:?}");
        }
    }

    #[test]
    fn a_value_the_flights_push_past_its_physical_bound_is_reported_at_it() {
        let given = shipped();
        let mut truth = given.clone();
        // Three times the power: more than the powertrain's efficiency (at least 0.5) and the
        // rotor's induced power factor (at most 1.5) can give together.
        truth.motor.esc_efficiency = given.motor.esc_efficiency / 3.0;
        let c = calibrate(&given, Profile::Hvb, &flights_of(&truth)).unwrap();
        let at: Vec<(&str, Option<&str>)> =
            c.at_bound().iter().map(|f| (f.key, f.at_bound)).collect();
        assert!(
            at.contains(&("motor.esc_efficiency", Some("low"))),
            "{at:?}"
        );
        let json = c.to_json();
        assert!(
            json["at_bound"]
                .as_array()
                .unwrap()
                .iter()
                .any(|b| b["key"] == "motor.esc_efficiency" && b["bound"] == "low"),
            "{json}"
        );
    }

    #[test]
    fn one_flight_is_fitted_without_leave_one_out_and_no_legs_is_refused() {
        let given = shipped();
        let mut flights = flights_of(&given);
        flights.legs.retain(|l| l.flight == 0);
        let c = calibrate(&given, Profile::Hvb, &flights).unwrap();
        assert!(c.held_out.is_empty() && c.held_out_errors().is_none());
        flights.legs.clear();
        let err = calibrate(&given, Profile::Hvb, &flights).unwrap_err();
        assert!(err.to_string().contains("flight0"), "{err}");
    }

    #[test]
    fn an_unreadable_flight_is_left_out_with_its_reason_and_none_readable_is_refused() {
        let tmp = tempfile::tempdir().expect("temp dir");
        let plan = r#"{"mission": "m", "home": {"lat_deg": 38.5, "lon_deg": -121.7, "alt_m": 16.0},
            "origin_height_m": 20.0, "points": [{"seq": 1, "name": "origin",
            "enu": {"x_east_m": 0.0, "y_north_m": 0.0, "z_up_m": 0.0}, "hold_s": 0.0}],
            "takeoff_seq": 0, "land_seq": 2, "predicted": null}"#;
        let killed = tmp.path().join("a-killed");
        std::fs::create_dir_all(&killed).expect("made");
        std::fs::write(killed.join(PLAN_FILE), plan).expect("written");
        // Recorded without a plan: only its log.
        let planless = tmp.path().join("b-planless");
        std::fs::create_dir_all(&planless).expect("made");
        std::fs::write(planless.join(crate::flightlog::recorder::TLOG_FILE), b"").expect("written");
        let flights = read_flights(&[tmp.path().to_path_buf()]).expect("read");
        assert!(flights.flights.is_empty());
        let reasons: Vec<(&Path, &str)> = flights
            .skipped
            .iter()
            .map(|s| (s.dir.as_path(), s.reason.as_str()))
            .collect();
        assert_eq!(reasons.len(), 2, "{reasons:?}");
        assert_eq!(reasons[0].0, killed);
        assert!(reasons[0].1.contains("no report.json"), "{reasons:?}");
        assert_eq!(reasons[1].0, planless);
        assert!(reasons[1].1.contains("no plan.json"), "{reasons:?}");
        let err = calibrate(&shipped(), Profile::Hvb, &flights)
            .expect_err("nothing to fit")
            .to_string();
        assert!(
            err.contains("no usable flight")
                && err.contains(&killed.display().to_string())
                && err.contains(&planless.display().to_string()),
            "{err}"
        );
    }
}
