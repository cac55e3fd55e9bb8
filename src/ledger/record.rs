//! A flight's record from its own files: a flight directory (plan.json, report.json,
//! samples.csv), read the same every time ([`from_dir`]), or a flight already measured from an
//! onboard log imported alone ([`of_flight`]).
//!
//! What a record holds and where each comes from:
//! - `id`: the directory's (or log's) name and a 16-hex FNV-1a-64 hash of plan.json's bytes
//!   (of the log's, for a log alone): the same flight copied elsewhere keeps its id, another
//!   flight never takes it;
//! - vehicle and profile: plan.json's `priced_by`; the pack: plan.json's `pack`; the wind:
//!   plan.json's `wind`;
//! - the autopilot: the log's format (a ULog is PX4's, a DataFlash log ArduPilot's), else the
//!   guard setup's return rule (its parameters are the autopilot's: `RTL_TYPE` PX4's,
//!   `RALLY_LIMIT_KM` ArduPilot's), else the profile the plan was priced with when it is an
//!   autopilot's own (`fly` prices with the autopilot's profile unless told otherwise); else
//!   not known;
//! - started_at: the first battery sample's wall time in samples.csv, else the directory's name
//!   (`YYYYmmdd-HHMMSS-mission`, the recorder's UTC start);
//! - the parts, the outcome and the totals: report.json; what the guard learned: its `guard`;
//! - the charge drawn and the pack fit: samples.csv, fitted with plan.json's guard setup's
//!   pack (its label and OCV curve: `logfit::battery::fit_flight`).

use std::path::Path;

use super::{FlightRecord, FlightSource, GuardLearned, LedgerError, Outcome, PackFit, PartRecord};
use crate::flightlog::csv::read_samples;
use crate::flightlog::flight_plan::FlightPlan;
use crate::flightlog::recorder::{self, PLAN_FILE, REPORT_FILE, SAMPLES_FILE};
use crate::flightlog::report::{FlightReport, PartReport};
use crate::logfit::battery::{fit_flight, PackModel, PackSeries};

/// FNV-1a, 64 bits (offset basis and prime: Fowler, Noll, Vo, the FNV specification), as
/// `Vehicle::parameter_hash` hashes.
pub fn fnv1a_64(bytes: &[u8]) -> u64 {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for byte in bytes {
        hash ^= u64::from(*byte);
        hash = hash.wrapping_mul(0x0100_0000_01b3);
    }
    hash
}

/// A flight's id: its name and the hash of the bytes that make it (plan.json's, or an onboard
/// log's).
pub fn id_of(name: &str, bytes: &[u8]) -> String {
    format!("{name}-{:016x}", fnv1a_64(bytes))
}

/// What a record is made of, read by the caller: a flight directory's files ([`from_dir`]), or
/// an onboard log measured alone (the caller names its id, source and autopilot).
#[derive(Debug, Clone, Copy)]
pub struct FlightInputs<'a> {
    pub id: &'a str,
    pub source: FlightSource,
    /// Where its files are, as given.
    pub path: &'a str,
    /// What it was measured against (None: a log alone, without one).
    pub plan: Option<&'a FlightPlan>,
    pub report: &'a FlightReport,
    /// Its pack samples (None: not any).
    pub pack: Option<&'a PackSeries>,
    /// When it started, `YYYY-MM-DDTHH:MM:SSZ` (None: not known).
    pub started_at: Option<&'a str>,
    /// The autopilot, when the caller knows it (an onboard log's format); else the plan says.
    pub autopilot: Option<&'a str>,
}

/// The record of the flight directory `dir`: a pure function of its files.
pub fn from_dir(dir: &Path) -> Result<FlightRecord, LedgerError> {
    if !dir.join(REPORT_FILE).is_file() {
        return Err(LedgerError::Flight {
            path: dir.display().to_string(),
            message: format!(
                "no {REPORT_FILE}: the flight was not measured (`emplan report {}` measures it)",
                dir.display()
            ),
        });
    }
    let plan_path = dir.join(PLAN_FILE);
    let plan_bytes = std::fs::read(&plan_path).map_err(|e| LedgerError::Flight {
        path: plan_path.display().to_string(),
        message: io_message(&e),
    })?;
    let plan = recorder::read_flight_plan(dir)?;
    let report = recorder::read_report(dir)?;
    let samples_path = dir.join(SAMPLES_FILE);
    let rows = if samples_path.is_file() {
        read_samples(&samples_path)?
    } else {
        Vec::new()
    };
    let series = PackSeries::of_samples(0, rows.iter().map(|r| (&r.sample, r.armed)));
    let name = dir_name(dir);
    let started_at = rows
        .first()
        .and_then(|r| iso_of_wall_us(r.sample.wall_us))
        .or_else(|| iso_of_name(&name));
    let id = id_of(&name, &plan_bytes);
    let path = dir.display().to_string();
    Ok(of_flight(&FlightInputs {
        id: &id,
        source: FlightSource::Directory,
        path: &path,
        plan: Some(&plan),
        report: &report,
        pack: (!series.voltage_v.is_empty()).then_some(&series),
        started_at: started_at.as_deref(),
        autopilot: None,
    }))
}

/// An IO error in words, without its debug form.
fn io_message(e: &std::io::Error) -> String {
    match e.kind() {
        std::io::ErrorKind::NotFound => "not found".to_string(),
        _ => e.to_string(),
    }
}

/// The directory's own name (resolved when `dir` ends in `.` or `..`).
fn dir_name(dir: &Path) -> String {
    let named = dir
        .file_name()
        .filter(|n| !n.is_empty())
        .map(|n| n.to_string_lossy().into_owned());
    named
        .or_else(|| {
            dir.canonicalize()
                .ok()
                .and_then(|d| d.file_name().map(|n| n.to_string_lossy().into_owned()))
        })
        .unwrap_or_else(|| recorder::flight_name(dir))
}

/// `YYYY-MM-DDTHH:MM:SSZ` of a directory name `YYYYmmdd-HHMMSS[-...]` (None when it does not
/// start with a valid one).
pub fn iso_of_name(name: &str) -> Option<String> {
    let b = name.as_bytes();
    if b.len() < 15 || b[8] != b'-' || (b.len() > 15 && b[15] != b'-') {
        return None;
    }
    let digits = |r: std::ops::Range<usize>| -> Option<u32> {
        let s = name.get(r)?;
        s.bytes()
            .all(|c| c.is_ascii_digit())
            .then(|| s.parse().ok())
            .flatten()
    };
    let (y, mo, d) = (digits(0..4)?, digits(4..6)?, digits(6..8)?);
    let (h, mi, s) = (digits(9..11)?, digits(11..13)?, digits(13..15)?);
    let valid = (1..=12).contains(&mo) && (1..=31).contains(&d) && h < 24 && mi < 60 && s < 61;
    valid.then(|| format!("{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}Z"))
}

/// `YYYY-MM-DDTHH:MM:SSZ` of a unix time in microseconds, when it is a plausible wall time
/// (2000 to 2200: an autopilot's time since boot is not one).
pub fn iso_of_wall_us(wall_us: u64) -> Option<String> {
    const Y2000_US: u64 = 946_684_800_000_000;
    const Y2200_US: u64 = 7_258_118_400_000_000;
    (Y2000_US..Y2200_US)
        .contains(&wall_us)
        .then(|| iso_of_name(&recorder::timestamp_name(wall_us)))
        .flatten()
}

/// The autopilot a plan shows: its guard setup's return rule, else its profile when it is an
/// autopilot's own.
fn autopilot_of_plan(plan: &FlightPlan) -> Option<String> {
    let rule = plan.guard.as_ref().and_then(|g| g.return_rule.as_deref());
    match rule {
        Some(r) if r.starts_with("RTL_TYPE") => return Some("px4".into()),
        Some(r) if r.starts_with("RALLY_LIMIT_KM") => return Some("ardupilot".into()),
        _ => {}
    }
    let profile = plan.priced_by.as_ref().map(|p| p.profile.as_str());
    match profile {
        Some("px4") => Some("px4".into()),
        Some("ardupilot") => Some("ardupilot".into()),
        _ => None,
    }
}

/// The autopilot of an onboard log's format (`ulog`, `dataflash`).
fn autopilot_of_format(format: &str) -> Option<&'static str> {
    match format {
        "ulog" => Some("px4"),
        "dataflash" => Some("ardupilot"),
        _ => None,
    }
}

/// The parts of a report in the order flown: the take-off, then each point's leg, settle and
/// hover, then the landing or the way home.
pub fn parts_of(report: &FlightReport) -> Vec<PartRecord> {
    let mut parts: Vec<(u8, &str, &PartReport, String)> = Vec::new();
    if let Some(t) = &report.takeoff {
        parts.push((0, "takeoff", t, String::new()));
    }
    let mut middle: Vec<(u8, &str, &PartReport, String)> = Vec::new();
    middle.extend(report.legs.iter().map(|p| (1, "leg", p, p.to.clone())));
    middle.extend(
        report
            .settles
            .iter()
            .map(|p| (2, "settle", p, p.to.clone())),
    );
    middle.extend(report.hovers.iter().map(|p| (3, "hover", p, p.to.clone())));
    // Stable: equal start times keep leg, settle, hover order.
    middle.sort_by(|a, b| a.2.start_s.total_cmp(&b.2.start_s).then(a.0.cmp(&b.0)));
    parts.extend(middle);
    if let Some(l) = &report.landing {
        parts.push((4, "landing", l, String::new()));
    }
    if let Some(r) = &report.return_home {
        let to = report.return_to.clone().unwrap_or_else(|| "home".into());
        parts.push((5, "return", r, to));
    }
    parts
        .into_iter()
        .enumerate()
        .map(|(index, (_, kind, p, name))| PartRecord {
            index: u32::try_from(index).unwrap_or(u32::MAX),
            kind: kind.to_string(),
            name,
            predicted_j: p.predicted_j.filter(|v| v.is_finite()),
            measured_j: p.measured_j.filter(|v| v.is_finite()),
            duration_s: Some(p.duration_s).filter(|v| v.is_finite()),
        })
        .collect()
}

/// How a reported flight ended.
pub fn outcome_of(report: &FlightReport) -> Outcome {
    if !report.complete {
        Outcome::CutOff
    } else if report.guard.as_ref().is_some_and(|g| g.returned) {
        Outcome::Returned
    } else if report.incomplete() {
        Outcome::Incomplete
    } else {
        Outcome::Completed
    }
}

/// The log times of a report's first and last part.
fn span_of(report: &FlightReport) -> Option<(f64, f64)> {
    let start = report
        .parts()
        .map(|p| p.start_s)
        .fold(f64::INFINITY, f64::min);
    let end = report
        .parts()
        .map(|p| p.end_s)
        .fold(f64::NEG_INFINITY, f64::max);
    (start.is_finite() && end.is_finite() && end >= start).then_some((start, end))
}

/// The pack a plan was flown with, as its guard setup has it (None without one).
pub fn pack_model_of(plan: &FlightPlan) -> Option<PackModel> {
    let g = plan.guard.as_ref()?;
    PackModel {
        cells: g.cells,
        capacity_ah: g.capacity_ah,
        internal_resistance_ohm: g.internal_resistance_ohm,
        ocv_soc: g.ocv_soc.clone(),
        ocv_cell_v: g.ocv_cell_v.clone(),
    }
    .checked()
}

/// The pack fit of one flight's samples with `pack`'s label and curve.
pub fn pack_fit(pack: &PackModel, series: &PackSeries) -> Option<PackFit> {
    let fit = fit_flight(pack, series)?;
    Some(PackFit {
        capacity_ah: fit.capacity_ah,
        label_capacity_ah: pack.capacity_ah,
        capacity_sd_ah: fit.capacity_sd_ah,
        internal_resistance_ohm: fit.internal_resistance_ohm,
        state_of_charge_at_takeoff: fit.state_of_charge_at_start,
        samples: fit.samples,
        voltage_rms_v: fit.voltage_rms_v,
    })
}

/// The record of a flight already measured: its report, the plan it was measured against and
/// its pack samples, read by the caller.
pub fn of_flight(inputs: &FlightInputs) -> FlightRecord {
    let report = inputs.report;
    let plan = inputs.plan;
    let format = report.source.as_ref().map(|s| s.format.as_str());
    let autopilot = inputs
        .autopilot
        .map(str::to_string)
        .or_else(|| format.and_then(autopilot_of_format).map(str::to_string))
        .or_else(|| plan.and_then(autopilot_of_plan));
    let priced_by = plan.and_then(|p| p.priced_by.as_ref());
    let wind = plan.and_then(|p| p.wind);
    let model = plan.and_then(pack_model_of);
    let fit = inputs
        .pack
        .zip(model.as_ref())
        .and_then(|(series, model)| pack_fit(model, series));
    FlightRecord {
        id: inputs.id.to_string(),
        source: inputs.source,
        path: inputs.path.to_string(),
        vehicle: priced_by.map(|p| p.vehicle.clone()),
        pack: plan.and_then(|p| p.pack.as_ref()).map(|p| p.name.clone()),
        mission: plan.map_or_else(|| report.flight.clone(), |p| p.mission.clone()),
        profile: priced_by.map(|p| p.profile.clone()),
        wind_m_s: wind.map(|w| w.speed_m_s),
        wind_from_deg: wind.map(|w| w.from_deg),
        autopilot,
        started_at: inputs.started_at.map(str::to_string),
        outcome: outcome_of(report),
        duration_s: report.duration_s,
        predicted_j: report.predicted_j,
        measured_j: report.measured_j,
        charge_ah: inputs.pack.and_then(|s| s.charge_ah(span_of(report))),
        parts: parts_of(report),
        guard: report.guard.as_ref().map(|g| GuardLearned {
            correction: g.correction,
            capacity_ratio: g.capacity_ratio,
            state_of_charge_at_takeoff: g.state_of_charge_at_takeoff,
            returned: g.returned,
        }),
        pack_fit: fit,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_directory_name_and_a_wall_time_read_as_utc() {
        assert_eq!(
            iso_of_name("20261129-105609-paper-sample-8wp").as_deref(),
            Some("2026-11-29T10:56:09Z")
        );
        assert_eq!(
            iso_of_name("20261129-105609").as_deref(),
            Some("2026-11-29T10:56:09Z")
        );
        assert_eq!(iso_of_name("20261329-105609-x"), None);
        assert_eq!(iso_of_name("2026112-1056091-x"), None);
        assert_eq!(iso_of_name("flight"), None);
        assert_eq!(iso_of_name("20261129-105609x"), None);
        assert_eq!(
            iso_of_wall_us(1_795_949_769_887_359).as_deref(),
            Some("2026-11-29T10:56:09Z")
        );
        // An autopilot's time since boot is not a date.
        assert_eq!(iso_of_wall_us(55_000_000), None);
    }

    #[test]
    fn the_id_is_the_name_and_the_hash_of_the_bytes() {
        // FNV-1a-64's published test vectors: "" and "a".
        assert_eq!(fnv1a_64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a_64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(id_of("x", b"a"), "x-af63dc4c8601ec8c");
        assert_ne!(id_of("x", b"a"), id_of("x", b"b"));
    }

    #[test]
    fn a_directory_without_its_report_is_refused_saying_how_to_measure_it() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("20261129-105609-square");
        std::fs::create_dir(&dir).unwrap();
        std::fs::write(dir.join(PLAN_FILE), "{}").unwrap();
        let err = from_dir(&dir).unwrap_err().to_string();
        assert!(err.starts_with(&dir.display().to_string()), "{err}");
        assert!(err.contains("no report.json"), "{err}");
        assert!(
            err.contains(&format!("emplan report {}", dir.display())),
            "{err}"
        );
    }
}
