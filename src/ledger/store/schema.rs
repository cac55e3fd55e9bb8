//! The ledger's schema: one numbered list of migrations that both backends apply in order, in
//! the SQL that SQLite and PostgreSQL both speak (`BIGINT`, `DOUBLE PRECISION`, `TEXT`, foreign
//! keys with `ON DELETE CASCADE`), so one ledger's rows mean the same in either.
//!
//! A migration is never edited once released: a change to the schema is a new migration at the
//! end of the list. The version a ledger is at is the highest in its `schema_version` table.

/// One step of the schema: the statements that take a ledger from `version - 1` to `version`.
pub(super) struct Migration {
    pub version: u32,
    pub statements: &'static [&'static str],
}

/// The table that records the migrations applied (one row each), made before the first.
pub(super) const VERSION_TABLE: &str = "CREATE TABLE schema_version (version BIGINT PRIMARY KEY)";

/// Every migration, oldest first; the last one's version is the schema this emplan writes.
pub(super) const MIGRATIONS: &[Migration] = &[
    Migration {
        version: 1,
        statements: &[
            // One row per flight: the columns one filters or sorts on, and the whole record as
            // JSON (`record`), which is what is read back.
            "CREATE TABLE flights (
                id TEXT PRIMARY KEY,
                vehicle TEXT,
                pack TEXT,
                mission TEXT NOT NULL,
                profile TEXT,
                autopilot TEXT,
                started_at TEXT,
                outcome TEXT NOT NULL,
                duration_s DOUBLE PRECISION NOT NULL,
                predicted_j DOUBLE PRECISION,
                measured_j DOUBLE PRECISION,
                charge_ah DOUBLE PRECISION,
                record TEXT NOT NULL
            )",
            // Each flight's parts, by their place in the record's list.
            "CREATE TABLE parts (
                flight_id TEXT NOT NULL REFERENCES flights (id) ON DELETE CASCADE,
                idx BIGINT NOT NULL,
                kind TEXT NOT NULL,
                name TEXT NOT NULL,
                predicted_j DOUBLE PRECISION,
                measured_j DOUBLE PRECISION,
                duration_s DOUBLE PRECISION,
                PRIMARY KEY (flight_id, idx)
            )",
        ],
    },
    Migration {
        version: 2,
        statements: &[
            "CREATE INDEX flights_by_pack ON flights (pack, started_at)",
            "CREATE INDEX flights_by_vehicle ON flights (vehicle, started_at)",
            "CREATE INDEX flights_by_start ON flights (started_at)",
        ],
    },
];

/// The schema version this emplan writes.
pub(super) fn latest() -> u32 {
    MIGRATIONS.last().map_or(0, |m| m.version)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn migrations_are_numbered_from_one_without_gaps() {
        for (k, m) in MIGRATIONS.iter().enumerate() {
            assert_eq!(m.version as usize, k + 1, "migration {k} of the list");
            assert!(!m.statements.is_empty());
        }
        assert_eq!(latest() as usize, MIGRATIONS.len());
    }
}
