//! The ledger's store: an embedded SQLite file (the default, beside the flights) or a team's
//! PostgreSQL server (`postgres://...`), one versioned schema and its migrations for both, one
//! row per flight by its id.

use std::path::PathBuf;

use super::{FlightRecord, LedgerError};

/// Where the ledger is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LedgerSpec {
    Sqlite(PathBuf),
    /// A `postgres://` or `postgresql://` connection string.
    Postgres(String),
}

impl LedgerSpec {
    /// A `postgres://` URL, else a path to a SQLite file.
    pub fn parse(text: &str) -> LedgerSpec {
        if text.starts_with("postgres://") || text.starts_with("postgresql://") {
            LedgerSpec::Postgres(text.to_string())
        } else {
            LedgerSpec::Sqlite(PathBuf::from(text))
        }
    }
}

/// What writing a flight did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Written {
    Inserted,
    /// The same record was there: nothing changed.
    Unchanged,
    /// Another record of the same flight was there (its files changed): replaced.
    Replaced,
}

/// Which flights to list (every field that is set must match).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FlightQuery {
    pub vehicle: Option<String>,
    pub pack: Option<String>,
    pub mission: Option<String>,
    /// `started_at` on or after / before, as `YYYY-MM-DD` or a full timestamp.
    pub since: Option<String>,
    pub until: Option<String>,
}

/// An open ledger.
pub struct Ledger {}

impl Ledger {
    /// Opens (creating and migrating as needed) the ledger at `spec`.
    pub fn open(_spec: &LedgerSpec) -> Result<Ledger, LedgerError> {
        todo!("helper: store")
    }

    /// Writes one flight's record (by its id: twice changes nothing).
    pub fn write(&mut self, _record: &FlightRecord) -> Result<Written, LedgerError> {
        todo!("helper: store")
    }

    /// The flights matching `query`, oldest first.
    pub fn flights(&mut self, _query: &FlightQuery) -> Result<Vec<FlightRecord>, LedgerError> {
        todo!("helper: store")
    }

    /// The schema version the ledger is at.
    pub fn schema_version(&mut self) -> Result<u32, LedgerError> {
        todo!("helper: store")
    }
}
