//! The ledger's store: an embedded SQLite file (the default, beside the flights) or a team's
//! PostgreSQL server (`postgres://...`), one versioned schema and its migrations for both, one
//! row per flight by its id.
//!
//! What both backends share lives here: the migrations' driver, writing a flight (by its id, in
//! one transaction: the same record again changes no row, another record of the same flight
//! replaces it and its parts) and the query. Each backend (`sqlite`, `postgres`) only opens its
//! connection, runs statements and brackets transactions; the SQL is written once, with
//! PostgreSQL's `$n` parameters (SQLite reads them as `?n`), and the few places where the two
//! speak differently are [`Dialect`]'s.
//!
//! Several writers at once (a live `fly` and `emplan ledger import`, or two ground stations on
//! one server) lose nothing: a write is one transaction that inserts the flight if its id is new
//! (`INSERT ... ON CONFLICT DO NOTHING`) and otherwise locks the row and compares; SQLite runs in
//! WAL mode, its writers take the lock at `BEGIN IMMEDIATE` and wait for each other (a busy
//! timeout); PostgreSQL's migrations run under a transaction-level advisory lock.

mod dates;
mod postgres;
mod rows;
mod schema;
mod sqlite;

use std::fmt;
use std::path::PathBuf;

use super::{FlightRecord, LedgerError};
use dates::{since_bound, until_bound};
use rows::{check_record, flight_row, insert_parts};

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

/// The file's path, or the URL with its password hidden (what errors and messages name).
impl fmt::Display for LedgerSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LedgerSpec::Sqlite(path) => write!(f, "{}", path.display()),
            LedgerSpec::Postgres(url) => f.write_str(&postgres::without_password(url)),
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

/// A value bound to a statement's parameter, typed (PostgreSQL must know a null's type).
#[derive(Debug, Clone, PartialEq)]
enum Param {
    Int(Option<i64>),
    Real(Option<f64>),
    Text(Option<String>),
}

/// A value read from a result's column.
#[derive(Debug, Clone, PartialEq)]
enum Cell {
    Null,
    Int(i64),
    Real(f64),
    Text(String),
}

impl Cell {
    fn int(&self) -> Option<i64> {
        match self {
            Cell::Int(v) => Some(*v),
            _ => None,
        }
    }
    fn text(&self) -> Option<&str> {
        match self {
            Cell::Text(v) => Some(v),
            _ => None,
        }
    }
}

/// Where the two backends' SQL differs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Dialect {
    Sqlite,
    Postgres,
}

impl Dialect {
    /// The statement as this backend reads it: SQLite's numbered parameters are `?n`.
    fn sql(self, text: &str) -> String {
        match self {
            Dialect::Sqlite => text.replace('$', "?"),
            Dialect::Postgres => text.to_string(),
        }
    }

    /// Text compared byte by byte (timestamps and ids order the same on either backend): SQLite's
    /// default, PostgreSQL's "C" collation (the database's own may be a locale's).
    fn bytewise(self) -> &'static str {
        match self {
            Dialect::Sqlite => "",
            Dialect::Postgres => " COLLATE \"C\"",
        }
    }

    /// The row read is locked until the transaction ends (SQLite's `BEGIN IMMEDIATE` already
    /// holds the whole file).
    fn for_update(self) -> &'static str {
        match self {
            Dialect::Sqlite => "",
            Dialect::Postgres => " FOR UPDATE",
        }
    }

    /// Whether a table of this name is in the ledger (one row, one count).
    fn table_exists(self, name: &str) -> String {
        match self {
            Dialect::Sqlite => {
                format!(
                    "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = '{name}'"
                )
            }
            Dialect::Postgres => format!(
                "SELECT count(*) FROM pg_catalog.pg_tables \
                 WHERE schemaname = current_schema() AND tablename = '{name}'"
            ),
        }
    }
}

/// One backend's connection: statements, and the transaction around them.
trait Conn: Send {
    fn dialect(&self) -> Dialect;
    /// Begins a transaction that writes (SQLite takes the write lock now, waiting its turn).
    fn begin(&mut self) -> Result<(), String>;
    fn commit(&mut self) -> Result<(), String>;
    fn rollback(&mut self) -> Result<(), String>;
    /// Within a transaction: waits until no other connection is migrating the schema.
    fn lock_schema(&mut self) -> Result<(), String>;
    /// Runs a statement (SQL in `$n` form), returning the rows it changed.
    fn execute(&mut self, sql: &str, params: &[Param]) -> Result<u64, String>;
    fn query(&mut self, sql: &str, params: &[Param]) -> Result<Vec<Vec<Cell>>, String>;
    /// Rows changed on this connection since it opened, as the database counts them.
    #[cfg(test)]
    fn changes(&mut self) -> Result<u64, String>;
}

/// An open ledger.
pub struct Ledger {
    /// What errors name: the file, or the URL without its password.
    at: String,
    conn: Box<dyn Conn>,
}

/// The columns of `flights`, in the order `rows::flight_row` binds them.
const FLIGHT_COLUMNS: &str =
    "id, vehicle, pack, mission, profile, autopilot, started_at, outcome, \
     duration_s, predicted_j, measured_j, charge_ah, record";

impl Ledger {
    /// Opens (creating and migrating as needed) the ledger at `spec`.
    pub fn open(spec: &LedgerSpec) -> Result<Ledger, LedgerError> {
        Ledger::open_with(spec, true, schema::latest())
    }

    /// Opens (migrating as needed) a ledger that must already exist: a missing SQLite file, or
    /// a PostgreSQL database without a ledger, is an error, and nothing is created. For commands
    /// that only read it.
    pub fn open_existing(spec: &LedgerSpec) -> Result<Ledger, LedgerError> {
        Ledger::open_with(spec, false, schema::latest())
    }

    fn open_with(spec: &LedgerSpec, create: bool, up_to: u32) -> Result<Ledger, LedgerError> {
        let at = spec.to_string();
        let store = |message: String| LedgerError::Store {
            at: at.clone(),
            message,
        };
        let conn: Box<dyn Conn> = match spec {
            LedgerSpec::Sqlite(path) => {
                if !create && !path.exists() {
                    return Err(store(
                        "no such ledger (one is made by `emplan ledger rebuild` or \
                         `emplan ledger import`, or by a flight flown with it)"
                            .to_string(),
                    ));
                }
                Box::new(sqlite::Db::open(path).map_err(store)?)
            }
            LedgerSpec::Postgres(url) => Box::new(postgres::Db::open(url).map_err(store)?),
        };
        let mut ledger = Ledger { at, conn };
        ledger.migrate(create, up_to)?;
        Ok(ledger)
    }

    /// Where the ledger is, as errors name it (the file, or the URL without its password).
    pub fn at(&self) -> &str {
        &self.at
    }

    fn store_error(&self, message: String) -> LedgerError {
        LedgerError::Store {
            at: self.at.clone(),
            message,
        }
    }

    /// Runs `body` in one transaction: committed if it returns Ok, rolled back otherwise.
    fn transaction<T>(
        &mut self,
        body: impl FnOnce(&mut dyn Conn) -> Result<T, LedgerError>,
    ) -> Result<T, LedgerError> {
        self.conn.begin().map_err(|e| self.store_error(e))?;
        match body(self.conn.as_mut()) {
            Ok(value) => {
                if let Err(e) = self.conn.commit() {
                    let _ = self.conn.rollback();
                    return Err(self.store_error(e));
                }
                Ok(value)
            }
            Err(e) => {
                // The error that stopped it is the one to tell.
                let _ = self.conn.rollback();
                Err(e)
            }
        }
    }

    /// Brings the schema to `up_to`, in one transaction under the schema lock.
    fn migrate(&mut self, create: bool, up_to: u32) -> Result<(), LedgerError> {
        let at = self.at.clone();
        let store = |message: String| LedgerError::Store {
            at: at.clone(),
            message,
        };
        self.transaction(|conn| {
            conn.lock_schema().map_err(store)?;
            let dialect = conn.dialect();
            let exists = conn
                .query(&dialect.table_exists("schema_version"), &[])
                .map_err(store)?;
            if single_int(&exists) != Some(1) {
                if !create {
                    return Err(store(
                        "no ledger there (no schema_version table; one is made by \
                         `emplan ledger rebuild` or `emplan ledger import`)"
                            .to_string(),
                    ));
                }
                conn.execute(schema::VERSION_TABLE, &[]).map_err(store)?;
            }
            let found = conn
                .query("SELECT max(version) FROM schema_version", &[])
                .map_err(store)?;
            let found = single_int(&found).unwrap_or(0);
            let known = schema::latest();
            if found > i64::from(known) {
                return Err(LedgerError::NewerSchema {
                    at: at.clone(),
                    found: u32::try_from(found).unwrap_or(u32::MAX),
                    known,
                });
            }
            for m in schema::MIGRATIONS
                .iter()
                .filter(|m| i64::from(m.version) > found && m.version <= up_to)
            {
                for statement in m.statements {
                    conn.execute(statement, &[])
                        .map_err(|e| store(format!("migration to version {}: {e}", m.version)))?;
                }
                conn.execute(
                    "INSERT INTO schema_version (version) VALUES ($1)",
                    &[Param::Int(Some(i64::from(m.version)))],
                )
                .map_err(store)?;
            }
            Ok(())
        })
    }

    /// Writes one flight's record (by its id: twice changes nothing).
    pub fn write(&mut self, record: &FlightRecord) -> Result<Written, LedgerError> {
        check_record(record)?;
        let json = serde_json::to_string(record).map_err(|e| LedgerError::Flight {
            path: record.path.clone(),
            message: format!("record `{}` does not serialise: {e}", record.id),
        })?;
        let at = self.at.clone();
        let store = |message: String| LedgerError::Store {
            at: at.clone(),
            message: format!("flight `{}`: {message}", record.id),
        };
        let row = flight_row(record, &json);
        self.transaction(|conn| {
            let dialect = conn.dialect();
            let placeholders = (1..=row.len())
                .map(|k| format!("${k}"))
                .collect::<Vec<_>>()
                .join(", ");
            let inserted = conn
                .execute(
                    &format!(
                        "INSERT INTO flights ({FLIGHT_COLUMNS}) VALUES ({placeholders}) \
                         ON CONFLICT (id) DO NOTHING"
                    ),
                    &row,
                )
                .map_err(store)?;
            if inserted == 1 {
                insert_parts(conn, record).map_err(store)?;
                return Ok(Written::Inserted);
            }
            let stored = conn
                .query(
                    &format!(
                        "SELECT record FROM flights WHERE id = $1{}",
                        dialect.for_update()
                    ),
                    &row[..1],
                )
                .map_err(store)?;
            let stored = stored.first().and_then(|r| r.first()).and_then(Cell::text);
            let same = stored.is_some_and(|text| {
                text == json
                    || serde_json::from_str::<FlightRecord>(text).ok().as_ref() == Some(record)
            });
            if same {
                return Ok(Written::Unchanged);
            }
            let assignments = FLIGHT_COLUMNS
                .split(", ")
                .enumerate()
                .skip(1)
                .map(|(k, column)| format!("{column} = ${}", k + 1))
                .collect::<Vec<_>>()
                .join(", ");
            conn.execute(
                &format!("UPDATE flights SET {assignments} WHERE id = $1"),
                &row,
            )
            .map_err(store)?;
            conn.execute("DELETE FROM parts WHERE flight_id = $1", &row[..1])
                .map_err(store)?;
            insert_parts(conn, record).map_err(store)?;
            Ok(Written::Replaced)
        })
    }

    /// The flights matching `query`, oldest first (by `started_at`, then id; flights without a
    /// start time last).
    pub fn flights(&mut self, query: &FlightQuery) -> Result<Vec<FlightRecord>, LedgerError> {
        let dialect = self.conn.dialect();
        let c = dialect.bytewise();
        let mut conditions = Vec::new();
        let mut params = Vec::new();
        let mut condition = |clause: String, value: String| {
            params.push(Param::Text(Some(value)));
            conditions.push(clause.replace("$?", &format!("${}", params.len())));
        };
        for (column, value) in [
            ("vehicle", &query.vehicle),
            ("pack", &query.pack),
            ("mission", &query.mission),
        ] {
            if let Some(value) = value {
                condition(format!("{column} = $?"), value.clone());
            }
        }
        if let Some(since) = &query.since {
            let bound = since_bound(since)?;
            condition(format!("started_at{c} >= $?"), bound);
        }
        if let Some(until) = &query.until {
            let (bound, inclusive) = until_bound(until)?;
            let op = if inclusive { "<=" } else { "<" };
            condition(format!("started_at{c} {op} $?"), bound);
        }
        let filter = if conditions.is_empty() {
            String::new()
        } else {
            format!(" WHERE {}", conditions.join(" AND "))
        };
        self.read_records(
            &format!(
                "SELECT id, record FROM flights{filter} \
                 ORDER BY started_at{c} ASC NULLS LAST, id{c} ASC"
            ),
            &params,
        )
    }

    /// The flight of this id, if the ledger has it.
    pub fn flight(&mut self, id: &str) -> Result<Option<FlightRecord>, LedgerError> {
        let records = self.read_records(
            "SELECT id, record FROM flights WHERE id = $1",
            &[Param::Text(Some(id.to_string()))],
        )?;
        Ok(records.into_iter().next())
    }

    /// Deletes the flight of this id and its parts; whether it was there.
    pub fn delete(&mut self, id: &str) -> Result<bool, LedgerError> {
        let at = self.at.clone();
        self.transaction(|conn| {
            conn.execute(
                "DELETE FROM flights WHERE id = $1",
                &[Param::Text(Some(id.to_string()))],
            )
            .map(|n| n > 0)
            .map_err(|message| LedgerError::Store {
                at,
                message: format!("flight `{id}`: {message}"),
            })
        })
    }

    /// How many flights the ledger holds.
    pub fn count(&mut self) -> Result<usize, LedgerError> {
        let rows = self
            .conn
            .query("SELECT count(*) FROM flights", &[])
            .map_err(|e| self.store_error(e))?;
        Ok(single_int(&rows)
            .and_then(|n| usize::try_from(n).ok())
            .unwrap_or(0))
    }

    /// The schema version the ledger is at.
    pub fn schema_version(&mut self) -> Result<u32, LedgerError> {
        let rows = self
            .conn
            .query("SELECT max(version) FROM schema_version", &[])
            .map_err(|e| self.store_error(e))?;
        Ok(single_int(&rows)
            .and_then(|v| u32::try_from(v).ok())
            .unwrap_or(0))
    }

    fn read_records(
        &mut self,
        sql: &str,
        params: &[Param],
    ) -> Result<Vec<FlightRecord>, LedgerError> {
        let rows = self
            .conn
            .query(sql, params)
            .map_err(|e| self.store_error(e))?;
        rows.iter()
            .map(|row| {
                let id = row.first().and_then(Cell::text).unwrap_or("");
                let text = row.get(1).and_then(Cell::text).ok_or_else(|| {
                    self.store_error(format!("flight `{id}`: its record is not text"))
                })?;
                serde_json::from_str(text).map_err(|e| {
                    self.store_error(format!("flight `{id}`: its record does not read: {e}"))
                })
            })
            .collect()
    }
}

/// The one integer a one-row, one-column result holds (None: null or no row).
fn single_int(rows: &[Vec<Cell>]) -> Option<i64> {
    rows.first().and_then(|r| r.first()).and_then(Cell::int)
}

#[cfg(test)]
mod tests;
