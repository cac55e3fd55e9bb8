//! The session's side of the ledger (`crate::ledger`): every finished flight written to it, and
//! what earlier flights taught the next one (the pack's capacity, the vehicle's correction).
//!
//! One place for every caller: the recorder writes each flight whose report it wrote
//! ([`write_flight`], on its own thread: the store is blocking, and the `postgres` client must
//! not run inside the async runtime), whoever flies it (`fly`, `record`, the service). A
//! failure is a warning: the flight directory is the source of truth and is kept whatever the
//! ledger does. Reading ([`learned`]) never creates a ledger: a missing SQLite file means
//! nothing has been learned yet, and says so.

use std::path::Path;

use crate::flightlog::flight_plan::{PackSource, PackUse};
use crate::flightlog::guard::GuardStart;
use crate::flightlog::guard::PRIOR_SD_LN;
use crate::ledger::packs::{pack_prior, vehicle_prior};
use crate::ledger::{
    FlightQuery, Ledger, LedgerError, LedgerSpec, PackPrior, VehiclePrior, Written,
};
use crate::physics::Vehicle;

/// The ledger's file name in a log directory, beside the flight directories.
pub const LEDGER_FILE: &str = "ledger.sqlite";

/// The ledger flights in `log_dir` are written to when no other is named: `log_dir/ledger.sqlite`.
pub fn default_spec(log_dir: &Path) -> LedgerSpec {
    LedgerSpec::Sqlite(log_dir.join(LEDGER_FILE))
}

/// Writes the flight in `dir` (its report written) to the ledger at `spec`, creating the
/// ledger when it is not there yet. Blocking.
pub fn write_flight(spec: &LedgerSpec, dir: &Path) -> Result<Written, LedgerError> {
    let record = crate::ledger::record::from_dir(dir)?;
    Ledger::open(spec)?.write(&record)
}

/// [`write_flight`], a failure warned of (the flight stays in its directory whatever the
/// ledger does).
pub fn write_flight_or_warn(spec: &LedgerSpec, dir: &Path) -> Option<Written> {
    match write_flight(spec, dir) {
        Ok(written) => Some(written),
        Err(e) => {
            tracing::warn!(
                "flight {} kept but not written to the ledger: {e} (`emplan ledger rebuild` can add it later)",
                dir.display()
            );
            None
        }
    }
}

/// The longest pack name kept (characters).
pub const PACK_NAME_MAX: usize = 64;

/// Why a pack name is refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PackNameError {
    #[error("pack name is empty")]
    Empty,
    #[error("pack name is {chars} characters long (at most {PACK_NAME_MAX})")]
    TooLong { chars: usize },
    #[error("pack name holds a control character (at character {at})")]
    Control { at: usize },
}

/// A pack's name as the ledger keys it: `text` trimmed, not empty, at most [`PACK_NAME_MAX`]
/// characters, without control characters (a name from the user or from the radio).
pub fn pack_name(text: &str) -> Result<String, PackNameError> {
    let name = text.trim();
    if name.is_empty() {
        return Err(PackNameError::Empty);
    }
    let chars = name.chars().count();
    if chars > PACK_NAME_MAX {
        return Err(PackNameError::TooLong { chars });
    }
    if let Some(at) = name.chars().position(char::is_control) {
        return Err(PackNameError::Control { at: at + 1 });
    }
    Ok(name.to_string())
}

/// What earlier flights taught a flight: its pack's capacity and its vehicle's correction.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Learned {
    /// The pack's prior (None: no pack named, or none of its flights measured it).
    pub pack: Option<PackPrior>,
    /// The vehicle's prior (None: no guarded flight of it yet).
    pub vehicle: Option<VehiclePrior>,
    /// Why nothing (or less than asked) was learned, for the user: no ledger yet, no flight of
    /// the pack in it.
    pub notes: Vec<String>,
}

impl Learned {
    /// The pack's capacity against its label to plan with (1: the label).
    pub fn capacity_ratio(&self) -> f64 {
        self.pack
            .as_ref()
            .map(|p| p.capacity_ratio)
            .filter(|r| r.is_finite() && *r > 0.0)
            .unwrap_or(1.0)
    }

    /// `vehicle` on this pack: its usable energy times the pack's learned capacity against its
    /// label (the physics unchanged, so its energy tables still hold: their hash leaves the
    /// planning section out). What the battery check and a split into sorties plan with.
    pub fn on_pack(&self, vehicle: &Vehicle) -> Vehicle {
        let mut on_pack = vehicle.clone();
        on_pack.planning.usable_energy_wh *= self.capacity_ratio();
        on_pack
    }

    /// The flights of the pack its capacity was learned from.
    pub fn pack_flights(&self) -> usize {
        self.pack.as_ref().map_or(0, |p| p.flights)
    }

    /// What the energy guard starts from (None when nothing was learned).
    pub fn guard_start(&self) -> Option<GuardStart> {
        if self.pack.is_none() && self.vehicle.is_none() {
            return None;
        }
        let (correction, correction_sd_ln, vehicle_flights) = match &self.vehicle {
            Some(v) if v.correction.is_finite() && v.correction > 0.0 => (
                v.correction,
                if v.correction_sd_ln.is_finite() && v.correction_sd_ln > 0.0 {
                    v.correction_sd_ln
                } else {
                    PRIOR_SD_LN
                },
                v.flights,
            ),
            _ => (1.0, PRIOR_SD_LN, 0),
        };
        Some(GuardStart {
            capacity_ratio: self.capacity_ratio(),
            pack_flights: self.pack_flights(),
            correction,
            correction_sd_ln,
            vehicle_flights,
        })
    }

    /// plan.json's pack: `name`, named by `source`, with the capacity it started from.
    pub fn pack_use(&self, name: &str, source: PackSource) -> PackUse {
        PackUse {
            name: name.to_string(),
            source,
            capacity_ratio: self.pack.as_ref().map(|_| self.capacity_ratio()),
        }
    }
}

/// What the ledger at `spec` knows of `pack` (when one is named) and of `vehicle` (the vehicle
/// file's name). A SQLite ledger that does not exist is not created: nothing is learned, and a
/// note says so. Blocking.
pub fn learned(
    spec: &LedgerSpec,
    pack: Option<&str>,
    vehicle: &str,
) -> Result<Learned, LedgerError> {
    if let LedgerSpec::Sqlite(path) = spec {
        if !path.exists() {
            return Ok(Learned {
                notes: vec![format!(
                    "no ledger at {} yet: nothing learned of {} (each flight flown or recorded is written to it)",
                    path.display(),
                    match pack {
                        Some(p) => format!("pack {p} or vehicle {vehicle}"),
                        None => format!("vehicle {vehicle}"),
                    }
                )],
                ..Learned::default()
            });
        }
    }
    let mut ledger = Ledger::open_existing(spec)?;
    let flights = ledger.flights(&FlightQuery::default())?;
    let mut notes = Vec::new();
    let pack_prior = pack.and_then(|p| {
        let prior = pack_prior(&flights, p);
        if prior.is_none() {
            notes.push(format!(
                "pack {p}: no flight of it in the ledger {spec} measured its capacity yet: planned on its label"
            ));
        }
        prior
    });
    Ok(Learned {
        pack: pack_prior,
        vehicle: vehicle_prior(&flights, vehicle),
        notes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_ledger_is_not_created_and_says_nothing_was_learned() {
        let dir = tempfile::tempdir().expect("temp dir");
        let spec = default_spec(dir.path());
        let learned = learned(&spec, Some("P3"), "s1000").expect("no error");
        assert_eq!(learned.capacity_ratio(), 1.0);
        assert!(learned.guard_start().is_none());
        assert!(
            learned.notes[0].contains("no ledger at"),
            "{:?}",
            learned.notes
        );
        assert!(!dir.path().join(LEDGER_FILE).exists());
    }

    #[test]
    fn a_pack_name_is_trimmed_and_refused_empty_long_or_with_control_characters() {
        assert_eq!(pack_name("  P3 ").as_deref(), Ok("P3"));
        assert_eq!(pack_name(" "), Err(PackNameError::Empty));
        assert_eq!(
            pack_name(&"x".repeat(65)),
            Err(PackNameError::TooLong { chars: 65 })
        );
        assert_eq!(pack_name("P\u{1b}3"), Err(PackNameError::Control { at: 2 }));
    }

    #[test]
    fn the_guard_starts_from_the_pack_and_the_vehicle_learned() {
        let learned = Learned {
            pack: Some(PackPrior {
                pack: "P".into(),
                capacity_ratio: 0.85,
                capacity_ratio_sd: 0.01,
                internal_resistance_ohm: None,
                flights: 3,
            }),
            vehicle: Some(VehiclePrior {
                vehicle: "s1000".into(),
                correction: 1.1,
                correction_sd_ln: 0.05,
                flights: 3,
            }),
            notes: Vec::new(),
        };
        let start = learned.guard_start().expect("a start");
        assert_eq!(
            (
                start.capacity_ratio,
                start.pack_flights,
                start.vehicle_flights
            ),
            (0.85, 3, 3)
        );
        assert_eq!((start.correction, start.correction_sd_ln), (1.1, 0.05));
        let used = learned.pack_use("P", PackSource::User);
        assert_eq!(used.capacity_ratio, Some(0.85));
    }
}
