//! The ledger in an embedded SQLite file: made with its directory on open, in WAL mode (readers
//! never wait, a writer waits for the other at most [`BUSY_TIMEOUT`]), foreign keys on.

use std::path::Path;
use std::time::Duration;

use rusqlite::types::{ToSqlOutput, ValueRef};
use rusqlite::{Connection, ToSql};

use super::{Cell, Conn, Dialect, Param};

/// How long a writer waits for another (a live `fly` and `emplan ledger import` at once) before
/// its write fails: each write is one short transaction, so a wait this long means a writer is
/// stuck.
pub(super) const BUSY_TIMEOUT: Duration = Duration::from_secs(30);

pub(super) struct Db {
    conn: Connection,
}

impl Db {
    /// Opens the file, making it and its directory if absent.
    pub(super) fn open(path: &Path) -> Result<Db, String> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .map_err(|e| format!("cannot make its directory {}: {e}", dir.display()))?;
        }
        let conn = Connection::open(path).map_err(|e| format!("cannot open: {e}"))?;
        conn.busy_timeout(BUSY_TIMEOUT).map_err(|e| e.to_string())?;
        // WAL: readers and one writer at once, and a writer waits for another (busy timeout)
        // rather than failing. Synchronous NORMAL is safe from corruption in WAL mode; a power
        // cut may lose the last writes, which `emplan ledger rebuild` recreates from the flights.
        // The mode it ends in is not checked: a file another connection holds in a transaction
        // keeps its rollback journal this once, and writers then still wait for each other.
        let _mode: String = conn
            .query_row("PRAGMA journal_mode = WAL", [], |row| row.get(0))
            .map_err(|e| format!("not a ledger (a SQLite database): {e}"))?;
        conn.execute_batch("PRAGMA synchronous = NORMAL; PRAGMA foreign_keys = ON;")
            .map_err(|e| e.to_string())?;
        Ok(Db { conn })
    }
}

impl ToSql for Param {
    fn to_sql(&self) -> rusqlite::Result<ToSqlOutput<'_>> {
        match self {
            Param::Int(v) => v.to_sql(),
            Param::Real(v) => v.to_sql(),
            Param::Text(v) => v.to_sql(),
        }
    }
}

impl Conn for Db {
    fn dialect(&self) -> Dialect {
        Dialect::Sqlite
    }

    fn begin(&mut self) -> Result<(), String> {
        // IMMEDIATE: the write lock now, so that a read and the write after it see one state,
        // and a second writer waits here (busy timeout) instead of failing at its first write.
        self.conn
            .execute_batch("BEGIN IMMEDIATE")
            .map_err(|e| e.to_string())
    }

    fn commit(&mut self) -> Result<(), String> {
        self.conn.execute_batch("COMMIT").map_err(|e| e.to_string())
    }

    fn rollback(&mut self) -> Result<(), String> {
        self.conn
            .execute_batch("ROLLBACK")
            .map_err(|e| e.to_string())
    }

    fn lock_schema(&mut self) -> Result<(), String> {
        // BEGIN IMMEDIATE already excludes every other writer.
        Ok(())
    }

    fn execute(&mut self, sql: &str, params: &[Param]) -> Result<u64, String> {
        self.conn
            .execute(
                &Dialect::Sqlite.sql(sql),
                rusqlite::params_from_iter(params),
            )
            .map(|n| n as u64)
            .map_err(|e| e.to_string())
    }

    fn query(&mut self, sql: &str, params: &[Param]) -> Result<Vec<Vec<Cell>>, String> {
        let mut statement = self
            .conn
            .prepare(&Dialect::Sqlite.sql(sql))
            .map_err(|e| e.to_string())?;
        let columns = statement.column_count();
        let mut rows = statement
            .query(rusqlite::params_from_iter(params))
            .map_err(|e| e.to_string())?;
        let mut out = Vec::new();
        while let Some(row) = rows.next().map_err(|e| e.to_string())? {
            let mut cells = Vec::with_capacity(columns);
            for k in 0..columns {
                cells.push(match row.get_ref(k).map_err(|e| e.to_string())? {
                    ValueRef::Null => Cell::Null,
                    ValueRef::Integer(v) => Cell::Int(v),
                    ValueRef::Real(v) => Cell::Real(v),
                    ValueRef::Text(bytes) => Cell::Text(
                        String::from_utf8(bytes.to_vec())
                            .map_err(|_| format!("column {k} is not UTF-8 text"))?,
                    ),
                    ValueRef::Blob(_) => return Err(format!("column {k} is a blob, not text")),
                });
            }
            out.push(cells);
        }
        Ok(out)
    }

    #[cfg(test)]
    fn changes(&mut self) -> Result<u64, String> {
        Ok(self.conn.total_changes())
    }
}
