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

mod postgres;
mod schema;
mod sqlite;

use std::fmt;
use std::path::PathBuf;

use super::{FlightRecord, LedgerError, Outcome};

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

/// The columns of `flights`, in the order [`flight_row`] binds them.
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

/// The flight's row of `flights`, in [`FLIGHT_COLUMNS`]' order.
fn flight_row(record: &FlightRecord, json: &str) -> Vec<Param> {
    let text = |v: &Option<String>| Param::Text(v.clone());
    vec![
        Param::Text(Some(record.id.clone())),
        text(&record.vehicle),
        text(&record.pack),
        Param::Text(Some(record.mission.clone())),
        text(&record.profile),
        text(&record.autopilot),
        text(&record.started_at),
        Param::Text(Some(outcome_name(record.outcome).to_string())),
        Param::Real(Some(record.duration_s)),
        Param::Real(record.predicted_j),
        Param::Real(record.measured_j),
        Param::Real(record.charge_ah),
        Param::Text(Some(json.to_string())),
    ]
}

fn insert_parts(conn: &mut dyn Conn, record: &FlightRecord) -> Result<(), String> {
    for (k, part) in record.parts.iter().enumerate() {
        conn.execute(
            "INSERT INTO parts (flight_id, idx, kind, name, predicted_j, measured_j, duration_s) \
             VALUES ($1, $2, $3, $4, $5, $6, $7)",
            &[
                Param::Text(Some(record.id.clone())),
                Param::Int(Some(i64::try_from(k).unwrap_or(i64::MAX))),
                Param::Text(Some(part.kind.clone())),
                Param::Text(Some(part.name.clone())),
                Param::Real(part.predicted_j),
                Param::Real(part.measured_j),
                Param::Real(part.duration_s),
            ],
        )?;
    }
    Ok(())
}

/// The outcome as the record's JSON names it.
fn outcome_name(outcome: Outcome) -> &'static str {
    match outcome {
        Outcome::Completed => "completed",
        Outcome::Returned => "returned",
        Outcome::Incomplete => "incomplete",
        Outcome::CutOff => "cut_off",
    }
}

/// A record the ledger can keep: an id, and every number finite (JSON has no NaN: one would
/// come back as a null, or not at all).
fn check_record(record: &FlightRecord) -> Result<(), LedgerError> {
    let refuse = |message: String| LedgerError::Flight {
        path: record.path.clone(),
        message,
    };
    if record.id.is_empty() {
        return Err(refuse("the record has no id".to_string()));
    }
    let mut numbers: Vec<(String, Option<f64>)> = vec![
        ("wind_m_s".into(), record.wind_m_s),
        ("wind_from_deg".into(), record.wind_from_deg),
        ("duration_s".into(), Some(record.duration_s)),
        ("predicted_j".into(), record.predicted_j),
        ("measured_j".into(), record.measured_j),
        ("charge_ah".into(), record.charge_ah),
    ];
    for (k, part) in record.parts.iter().enumerate() {
        numbers.push((format!("parts[{k}].predicted_j"), part.predicted_j));
        numbers.push((format!("parts[{k}].measured_j"), part.measured_j));
        numbers.push((format!("parts[{k}].duration_s"), part.duration_s));
    }
    if let Some(g) = &record.guard {
        numbers.push(("guard.correction".into(), Some(g.correction)));
        numbers.push(("guard.capacity_ratio".into(), Some(g.capacity_ratio)));
        numbers.push((
            "guard.state_of_charge_at_takeoff".into(),
            g.state_of_charge_at_takeoff,
        ));
    }
    if let Some(p) = &record.pack_fit {
        for (name, value) in [
            ("capacity_ah", p.capacity_ah),
            ("label_capacity_ah", p.label_capacity_ah),
            ("capacity_sd_ah", p.capacity_sd_ah),
            ("internal_resistance_ohm", p.internal_resistance_ohm),
            ("state_of_charge_at_takeoff", p.state_of_charge_at_takeoff),
            ("voltage_rms_v", p.voltage_rms_v),
        ] {
            numbers.push((format!("pack_fit.{name}"), Some(value)));
        }
    }
    match numbers
        .into_iter()
        .find(|(_, v)| v.is_some_and(|v| !v.is_finite()))
    {
        Some((field, Some(value))) => Err(refuse(format!(
            "record `{}`: {field} is {value}, which the ledger cannot keep",
            record.id
        ))),
        _ => Ok(()),
    }
}

/// A civil date `YYYY-MM-DD`, checked (month, day of the month, leap years).
fn parse_date(text: &str) -> Option<(i32, u32, u32)> {
    let b = text.as_bytes();
    if b.len() != 10 || b[4] != b'-' || b[7] != b'-' {
        return None;
    }
    let year = digits(&text[..4])?;
    let month = digits(&text[5..7])?;
    let day = digits(&text[8..])?;
    let year = i32::try_from(year).ok()?;
    ((1..=12).contains(&month) && (1..=days_in_month(year, month)).contains(&day))
        .then_some((year, month, day))
}

/// A number written in ASCII digits only (no sign, no space).
fn digits(text: &str) -> Option<u32> {
    if text.is_empty() || !text.bytes().all(|c| c.is_ascii_digit()) {
        return None;
    }
    text.parse().ok()
}

fn days_in_month(year: i32, month: u32) -> u32 {
    let leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
    match month {
        2 if leap => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// The day after a date, as `YYYY-MM-DD`.
fn day_after((year, month, day): (i32, u32, u32)) -> String {
    let (year, month, day) = if day < days_in_month(year, month) {
        (year, month, day + 1)
    } else if month < 12 {
        (year, month + 1, 1)
    } else {
        (year + 1, 1, 1)
    };
    format!("{year:04}-{month:02}-{day:02}")
}

/// Whether `text` is a timestamp as records keep them, `YYYY-MM-DDTHH:MM:SSZ`.
fn is_timestamp(text: &str) -> bool {
    let b = text.as_bytes();
    let time_ok = || {
        let time = &text[11..19];
        let tb = time.as_bytes();
        let field = |s: &str, max: u32| digits(s).is_some_and(|v| v <= max);
        tb[2] == b':'
            && tb[5] == b':'
            && field(&time[..2], 23)
            && field(&time[3..5], 59)
            && field(&time[6..], 60)
    };
    b.len() == 20
        && b[10] == b'T'
        && b[19] == b'Z'
        && parse_date(&text[..10]).is_some()
        && time_ok()
}

fn bad_bound(field: &str, value: &str) -> LedgerError {
    LedgerError::Query {
        field: field.to_string(),
        value: value.to_string(),
    }
}

/// The lower bound of `since`: its date (a prefix of every timestamp that day) or its time.
fn since_bound(since: &str) -> Result<String, LedgerError> {
    if parse_date(since).is_some() || is_timestamp(since) {
        Ok(since.to_string())
    } else {
        Err(bad_bound("since", since))
    }
}

/// The upper bound of `until` and whether it is inclusive: a date takes its whole day (before
/// the day after), a time itself.
fn until_bound(until: &str) -> Result<(String, bool), LedgerError> {
    if let Some(date) = parse_date(until) {
        Ok((day_after(date), false))
    } else if is_timestamp(until) {
        Ok((until.to_string(), true))
    } else {
        Err(bad_bound("until", until))
    }
}

#[cfg(test)]
mod tests;
