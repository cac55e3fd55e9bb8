//! The store's tests. Each test body runs against SQLite (a temporary file) and PostgreSQL (its
//! own schema on the server `EMPLAN_TEST_POSTGRES` names, dropped after; when the variable is
//! unset the PostgreSQL run says so and returns, so a clone passes without a server).

use std::path::Path;
use std::sync::{Arc, Barrier};

use super::*;
use crate::ledger::{FlightSource, GuardLearned, PackFit, PartRecord};

/// The environment variable naming the PostgreSQL server the tests use.
const POSTGRES_VAR: &str = "EMPLAN_TEST_POSTGRES";

/// A schema of its own on the test server, dropped when the test ends.
struct TestPostgres {
    url: String,
    schema: String,
    spec: LedgerSpec,
}

impl TestPostgres {
    /// None (said on stdout) when no server is configured; a panic when one is and it cannot
    /// be reached, so that CI fails rather than skips.
    fn new(test: &str) -> Option<TestPostgres> {
        let Ok(url) = std::env::var(POSTGRES_VAR) else {
            println!("{test}: not run against PostgreSQL ({POSTGRES_VAR} is not set)");
            return None;
        };
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let schema = format!("emplan_test_{test}_{}_{nanos}", std::process::id());
        let mut client = ::postgres::Client::connect(&url, ::postgres::NoTls)
            .unwrap_or_else(|e| panic!("{POSTGRES_VAR}={url}: cannot connect: {e:?}"));
        client
            .batch_execute(&format!("CREATE SCHEMA \"{schema}\""))
            .unwrap_or_else(|e| panic!("{url}: cannot create schema {schema}: {e:?}"));
        let sep = if url.contains('?') { '&' } else { '?' };
        let spec = LedgerSpec::Postgres(format!("{url}{sep}options=-csearch_path%3D{schema}"));
        Some(TestPostgres { url, schema, spec })
    }
}

impl Drop for TestPostgres {
    fn drop(&mut self) {
        if let Ok(mut client) = ::postgres::Client::connect(&self.url, ::postgres::NoTls) {
            let _ = client.batch_execute(&format!("DROP SCHEMA \"{}\" CASCADE", self.schema));
        }
    }
}

/// Runs each named test body against both backends: `<body>::sqlite` and `<body>::postgres`.
macro_rules! on_both_backends {
    ($($body:ident),* $(,)?) => {$(
        mod $body {
            #[test]
            fn sqlite() {
                let dir = tempfile::tempdir().expect("a temporary directory");
                super::$body(&super::LedgerSpec::Sqlite(dir.path().join("ledger.sqlite")));
            }

            #[test]
            fn postgres() {
                if let Some(db) = super::TestPostgres::new(stringify!($body)) {
                    super::$body(&db.spec);
                }
            }
        }
    )*};
}

on_both_backends!(
    a_flight_reads_back_exactly,
    the_same_record_again_is_unchanged_and_rewrites_no_row,
    another_record_of_a_flight_replaces_it_and_its_parts,
    flights_are_filtered_and_ordered_oldest_first,
    deleting_a_flight_deletes_its_parts,
    a_ledger_made_at_version_1_opens_at_the_latest_with_its_rows,
    a_ledger_of_a_newer_schema_is_refused,
    two_ledgers_opened_at_once_migrate_once,
    two_writers_at_once_lose_nothing,
);

/// A hand-made record: `k` picks its id, its pack and vehicle, its start and its numbers.
fn record(k: usize) -> FlightRecord {
    let part = |index: u32, kind: &str, name: &str| PartRecord {
        index,
        kind: kind.to_string(),
        name: name.to_string(),
        predicted_j: Some(1000.0 + k as f64 / 3.0 + f64::from(index)),
        measured_j: (index != 1).then(|| 1012.5 * (1.0 + k as f64 * 1e-7)),
        duration_s: Some(12.1 + f64::from(index) * 0.1),
    };
    FlightRecord {
        id: format!("flight-{k:04}-{:08x}", k * 2_654_435_761 % 4_294_967_291),
        source: FlightSource::Directory,
        path: format!("flights/flight-{k:04}"),
        vehicle: Some(format!("s1000-{}", k % 2)),
        pack: (k % 5 != 4).then(|| format!("pack-{}", k % 3)),
        mission: "paper-sample-8wp".to_string(),
        profile: Some("px4".to_string()),
        wind_m_s: Some(3.0),
        wind_from_deg: Some(270.0),
        autopilot: Some("px4".to_string()),
        started_at: Some(format!(
            "2026-{:02}-{:02}T{:02}:{:02}:00Z",
            1 + k % 12,
            1 + k % 28,
            k % 24,
            k % 60
        )),
        outcome: Outcome::Completed,
        duration_s: 300.0 + k as f64 * 0.1,
        predicted_j: Some(0.1 + 0.2 + k as f64),
        measured_j: Some(std::f64::consts::PI * 1e5 + k as f64),
        charge_ah: Some(5.0 / 3.0),
        parts: vec![
            part(0, "takeoff", ""),
            part(1, "leg", "A"),
            part(2, "landing", ""),
        ],
        guard: Some(GuardLearned {
            correction: 1.0 + 1.0 / 7.0,
            capacity_ratio: 0.86,
            state_of_charge_at_takeoff: Some(0.97),
            returned: false,
        }),
        pack_fit: Some(PackFit {
            capacity_ah: 8.5 + 1e-13,
            label_capacity_ah: 10.0,
            capacity_sd_ah: 0.0421,
            internal_resistance_ohm: 0.0333,
            state_of_charge_at_takeoff: 0.99,
            samples: 3000 + k,
            voltage_rms_v: 0.012,
        }),
    }
}

fn open(spec: &LedgerSpec) -> Ledger {
    Ledger::open(spec).unwrap_or_else(|e| panic!("{e}"))
}

fn all(ledger: &mut Ledger) -> Vec<FlightRecord> {
    ledger
        .flights(&FlightQuery::default())
        .unwrap_or_else(|e| panic!("{e}"))
}

/// The rows of `parts` of one flight: (idx, kind, name, predicted_j).
fn parts_of(ledger: &mut Ledger, id: &str) -> Vec<(i64, String, String, Option<f64>)> {
    let rows = ledger
        .conn
        .query(
            "SELECT idx, kind, name, predicted_j FROM parts WHERE flight_id = $1 ORDER BY idx",
            &[Param::Text(Some(id.to_string()))],
        )
        .expect("parts read");
    rows.iter()
        .map(|r| {
            let real = match &r[3] {
                Cell::Real(v) => Some(*v),
                _ => None,
            };
            let text = |c: &Cell| c.text().unwrap_or("?").to_string();
            (r[0].int().expect("idx"), text(&r[1]), text(&r[2]), real)
        })
        .collect()
}

fn a_flight_reads_back_exactly(spec: &LedgerSpec) {
    let mut ledger = open(spec);
    let mut flight = record(7);
    // Floats that a shortest or lossy printing would not bring back.
    flight.measured_j = Some(5e-324);
    flight.charge_ah = Some(f64::MAX);
    flight.wind_m_s = Some(0.1 + 0.2);
    flight.parts[0].duration_s = Some(-1.0 / 3.0);
    flight.outcome = Outcome::CutOff;
    flight.started_at = None;
    flight.guard = None;
    assert_eq!(ledger.write(&flight).expect("written"), Written::Inserted);
    assert_eq!(all(&mut ledger), vec![flight.clone()]);
    assert_eq!(
        ledger.flight(&flight.id).expect("read"),
        Some(flight.clone())
    );
    assert_eq!(ledger.flight("no-such-flight").expect("read"), None);
    assert_eq!(ledger.count().expect("counted"), 1);
    // The columns for querying hold the record's values too.
    let row = ledger
        .conn
        .query(
            "SELECT outcome, measured_j, started_at FROM flights WHERE id = $1",
            &[Param::Text(Some(flight.id.clone()))],
        )
        .expect("row");
    assert_eq!(
        row,
        vec![vec![
            Cell::Text("cut_off".into()),
            Cell::Real(5e-324),
            Cell::Null
        ]]
    );
    // And another connection reads the same.
    drop(ledger);
    assert_eq!(all(&mut open(spec)), vec![flight]);
}

fn the_same_record_again_is_unchanged_and_rewrites_no_row(spec: &LedgerSpec) {
    let mut ledger = open(spec);
    let flight = record(1);
    assert_eq!(ledger.write(&flight).expect("written"), Written::Inserted);
    let changes = ledger.conn.changes().expect("changes");
    assert_eq!(ledger.write(&flight).expect("written"), Written::Unchanged);
    assert_eq!(
        ledger.write(&flight.clone()).expect("written"),
        Written::Unchanged
    );
    assert_eq!(
        ledger.conn.changes().expect("changes"),
        changes,
        "rows were changed"
    );
    assert_eq!(all(&mut ledger), vec![flight]);
}

fn another_record_of_a_flight_replaces_it_and_its_parts(spec: &LedgerSpec) {
    let mut ledger = open(spec);
    let first = record(2);
    let other = record(3);
    ledger.write(&first).expect("written");
    ledger.write(&other).expect("written");
    let mut changed = first.clone();
    changed.pack = Some("pack-9".into());
    changed.parts.truncate(2);
    changed.parts[1].name = "B".into();
    changed.parts[1].predicted_j = Some(42.0);
    assert_eq!(ledger.write(&changed).expect("written"), Written::Replaced);
    assert_eq!(ledger.count().expect("counted"), 2);
    assert_eq!(
        ledger.flight(&first.id).expect("read"),
        Some(changed.clone())
    );
    assert_eq!(
        parts_of(&mut ledger, &first.id),
        vec![
            (
                0,
                "takeoff".into(),
                String::new(),
                changed.parts[0].predicted_j
            ),
            (1, "leg".into(), "B".into(), Some(42.0)),
        ]
    );
    // The pack column followed the record; the other flight is untouched.
    let by_pack = FlightQuery {
        pack: Some("pack-9".into()),
        ..FlightQuery::default()
    };
    assert_eq!(ledger.flights(&by_pack).expect("query"), vec![changed]);
    assert_eq!(parts_of(&mut ledger, &other.id).len(), 3);
    assert_eq!(ledger.flight(&other.id).expect("read"), Some(other));
}

fn flights_are_filtered_and_ordered_oldest_first(spec: &LedgerSpec) {
    let mut ledger = open(spec);
    let at = |id: &str, started: Option<&str>, pack: &str, vehicle: &str, mission: &str| {
        let mut r = record(0);
        r.id = id.to_string();
        r.started_at = started.map(str::to_string);
        r.pack = Some(pack.to_string());
        r.vehicle = Some(vehicle.to_string());
        r.mission = mission.to_string();
        r
    };
    let flights = [
        at("c", Some("2026-03-01T10:00:00Z"), "p1", "v1", "m1"),
        // The same start: by id, byte by byte ("B" before "a" on either backend).
        at("a", Some("2026-03-01T09:00:00Z"), "p1", "v1", "m2"),
        at("B", Some("2026-03-01T09:00:00Z"), "p2", "v1", "m1"),
        at("d", Some("2026-02-28T23:59:59Z"), "p1", "v2", "m1"),
        at("e", Some("2026-03-02T00:00:00Z"), "p2", "v2", "m1"),
        at("f", None, "p1", "v1", "m1"),
    ];
    // Written out of order.
    for f in flights.iter().rev() {
        assert_eq!(ledger.write(f).expect("written"), Written::Inserted);
    }
    let ids = |ledger: &mut Ledger, q: FlightQuery| -> Vec<String> {
        ledger
            .flights(&q)
            .unwrap_or_else(|e| panic!("{e}"))
            .into_iter()
            .map(|r| r.id)
            .collect()
    };
    let q = FlightQuery::default;
    assert_eq!(ids(&mut ledger, q()), ["d", "B", "a", "c", "e", "f"]);
    let some = |s: &str| Some(s.to_string());
    assert_eq!(
        ids(
            &mut ledger,
            FlightQuery {
                pack: some("p1"),
                ..q()
            }
        ),
        ["d", "a", "c", "f"]
    );
    assert_eq!(
        ids(
            &mut ledger,
            FlightQuery {
                vehicle: some("v2"),
                ..q()
            }
        ),
        ["d", "e"]
    );
    assert_eq!(
        ids(
            &mut ledger,
            FlightQuery {
                mission: some("m2"),
                ..q()
            }
        ),
        ["a"]
    );
    assert_eq!(
        ids(
            &mut ledger,
            FlightQuery {
                pack: some("p1"),
                vehicle: some("v1"),
                mission: some("m1"),
                ..q()
            }
        ),
        ["c", "f"]
    );
    // A date bound takes its whole day; an undated flight is in no date range.
    let day = FlightQuery {
        since: some("2026-03-01"),
        until: some("2026-03-01"),
        ..q()
    };
    assert_eq!(ids(&mut ledger, day), ["B", "a", "c"]);
    assert_eq!(
        ids(
            &mut ledger,
            FlightQuery {
                until: some("2026-02-28"),
                ..q()
            }
        ),
        ["d"]
    );
    assert_eq!(
        ids(
            &mut ledger,
            FlightQuery {
                since: some("2026-03-02"),
                ..q()
            }
        ),
        ["e"]
    );
    // A time bound is the instant itself, both ends included.
    let times = FlightQuery {
        since: some("2026-03-01T09:00:00Z"),
        until: some("2026-03-01T10:00:00Z"),
        ..q()
    };
    assert_eq!(ids(&mut ledger, times), ["B", "a", "c"]);
    assert_eq!(
        ids(
            &mut ledger,
            FlightQuery {
                since: some("2026-03-01T09:00:01Z"),
                ..q()
            }
        ),
        ["c", "e"]
    );
    assert!(ids(
        &mut ledger,
        FlightQuery {
            pack: some("p3"),
            ..q()
        }
    )
    .is_empty());
    let bad = ledger.flights(&FlightQuery {
        until: some("2026-02-30"),
        ..q()
    });
    assert_eq!(
        bad.map(|_| ()).map_err(|e| e.to_string()),
        Err("until `2026-02-30`: not a date (YYYY-MM-DD) or a time (YYYY-MM-DDTHH:MM:SSZ)".into())
    );
}

fn deleting_a_flight_deletes_its_parts(spec: &LedgerSpec) {
    let mut ledger = open(spec);
    let (one, two) = (record(4), record(5));
    ledger.write(&one).expect("written");
    ledger.write(&two).expect("written");
    assert!(ledger.delete(&one.id).expect("deleted"));
    assert!(!ledger.delete(&one.id).expect("deleted"));
    assert!(
        parts_of(&mut ledger, &one.id).is_empty(),
        "its parts stayed"
    );
    assert_eq!(parts_of(&mut ledger, &two.id).len(), 3);
    assert_eq!(all(&mut ledger), vec![two]);
    // Written again after, it is new.
    assert_eq!(ledger.write(&one).expect("written"), Written::Inserted);
}

/// Whether the ledger has an index of this name (migration 2's).
fn has_index(ledger: &mut Ledger, name: &str) -> bool {
    let sql = match ledger.conn.dialect() {
        Dialect::Sqlite => {
            format!("SELECT count(*) FROM sqlite_master WHERE type = 'index' AND name = '{name}'")
        }
        Dialect::Postgres => format!(
            "SELECT count(*) FROM pg_catalog.pg_indexes \
             WHERE schemaname = current_schema() AND indexname = '{name}'"
        ),
    };
    single_int(&ledger.conn.query(&sql, &[]).expect("indexes")) == Some(1)
}

fn a_ledger_made_at_version_1_opens_at_the_latest_with_its_rows(spec: &LedgerSpec) {
    let flights = [record(10), record(11)];
    {
        let mut old = Ledger::open_with(spec, true, 1).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(old.schema_version().expect("version"), 1);
        assert!(!has_index(&mut old, "flights_by_pack"));
        for f in &flights {
            old.write(f).expect("written at version 1");
        }
    }
    let mut ledger = open(spec);
    assert_eq!(ledger.schema_version().expect("version"), schema::latest());
    assert_eq!(schema::latest(), 2);
    for index in ["flights_by_pack", "flights_by_vehicle", "flights_by_start"] {
        assert!(has_index(&mut ledger, index), "{index} missing");
    }
    assert_eq!(all(&mut ledger), flights.to_vec());
    assert_eq!(parts_of(&mut ledger, &flights[1].id).len(), 3);
    // Opened again, nothing more to do.
    drop(ledger);
    assert_eq!(open(spec).schema_version().expect("version"), 2);
}

fn a_ledger_of_a_newer_schema_is_refused(spec: &LedgerSpec) {
    let mut ledger = open(spec);
    ledger
        .conn
        .execute(
            "INSERT INTO schema_version (version) VALUES ($1)",
            &[Param::Int(Some(99))],
        )
        .expect("a version from the future");
    drop(ledger);
    match Ledger::open(spec) {
        Err(LedgerError::NewerSchema { at, found, known }) => {
            assert_eq!((found, known), (99, schema::latest()));
            assert_eq!(at, spec.to_string());
        }
        Err(e) => panic!("another error: {e}"),
        Ok(_) => panic!("a ledger of schema 99 opened"),
    }
}

fn two_ledgers_opened_at_once_migrate_once(spec: &LedgerSpec) {
    let start = Arc::new(Barrier::new(4));
    let openers: Vec<_> = (0..4)
        .map(|_| {
            let (spec, start) = (spec.clone(), start.clone());
            std::thread::spawn(move || {
                start.wait();
                let mut ledger = Ledger::open(&spec).unwrap_or_else(|e| panic!("{e}"));
                ledger.schema_version().unwrap_or_else(|e| panic!("{e}"))
            })
        })
        .collect();
    for opener in openers {
        assert_eq!(opener.join().expect("opened"), schema::latest());
    }
    let mut ledger = open(spec);
    let rows = ledger
        .conn
        .query("SELECT count(*) FROM schema_version", &[])
        .expect("versions");
    assert_eq!(single_int(&rows), Some(i64::from(schema::latest())));
}

fn two_writers_at_once_lose_nothing(spec: &LedgerSpec) {
    // 200 flights: the first writer writes 0..120, the second 80..200 from the end, each on its
    // own connection, started together; the 40 in both are the same records.
    open(spec);
    let start = Arc::new(Barrier::new(2));
    let writer = |ks: Vec<usize>| {
        let (spec, start) = (spec.clone(), start.clone());
        std::thread::spawn(move || {
            let mut ledger = Ledger::open(&spec).unwrap_or_else(|e| panic!("{e}"));
            start.wait();
            ks.into_iter()
                .map(|k| ledger.write(&record(k)).unwrap_or_else(|e| panic!("{e}")))
                .collect::<Vec<_>>()
        })
    };
    let first = writer((0..120).collect());
    let second = writer((80..200).rev().collect());
    let mut written = first.join().expect("first writer");
    written.extend(second.join().expect("second writer"));
    let count = |w: Written| written.iter().filter(|&&x| x == w).count();
    assert_eq!(
        (
            count(Written::Inserted),
            count(Written::Unchanged),
            count(Written::Replaced)
        ),
        (200, 40, 0)
    );
    let mut ledger = open(spec);
    let mut stored = all(&mut ledger);
    stored.sort_by(|a, b| a.id.cmp(&b.id));
    let mut expected: Vec<FlightRecord> = (0..200).map(record).collect();
    expected.sort_by(|a, b| a.id.cmp(&b.id));
    assert_eq!(stored.len(), 200);
    assert!(
        stored == expected,
        "the ledger does not hold the 200 flights written"
    );
    let parts = ledger
        .conn
        .query("SELECT count(*) FROM parts", &[])
        .expect("parts");
    assert_eq!(single_int(&parts), Some(600));
}

#[test]
fn the_sqlite_file_and_its_directory_are_made_on_open_in_wal_mode() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = dir
        .path()
        .join("flights")
        .join("team")
        .join("ledger.sqlite");
    let mut ledger = open(&LedgerSpec::Sqlite(path.clone()));
    assert!(path.is_file());
    assert_eq!(ledger.at(), path.display().to_string());
    let mode = ledger.conn.query("PRAGMA journal_mode", &[]).expect("mode");
    assert_eq!(mode, vec![vec![Cell::Text("wal".into())]]);
    let keys = ledger.conn.query("PRAGMA foreign_keys", &[]).expect("keys");
    assert_eq!(keys, vec![vec![Cell::Int(1)]]);
}

#[test]
fn a_missing_ledger_opened_to_read_is_an_error_naming_it_and_is_not_made() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = dir.path().join("flights").join("ledger.sqlite");
    let err = Ledger::open_existing(&LedgerSpec::Sqlite(path.clone()))
        .map(|_| ())
        .expect_err("a missing file opened");
    let text = err.to_string();
    assert!(
        text.starts_with(&format!("ledger {}: no such ledger", path.display())),
        "{text}"
    );
    assert!(text.contains("emplan ledger rebuild"), "{text}");
    assert!(!path.exists() && !path.parent().is_some_and(Path::exists));
    // Once made, it opens to read.
    open(&LedgerSpec::Sqlite(path.clone()))
        .write(&record(1))
        .expect("written");
    let mut ledger = Ledger::open_existing(&LedgerSpec::Sqlite(path)).expect("opened");
    assert_eq!(all(&mut ledger), vec![record(1)]);
}

#[test]
fn a_file_that_is_not_a_ledger_is_an_error_naming_it() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let path = dir.path().join("notes.sqlite");
    std::fs::write(
        &path,
        "these are not the flights you are looking for\n".repeat(200),
    )
    .expect("written");
    let err = Ledger::open(&LedgerSpec::Sqlite(path.clone()))
        .map(|_| ())
        .expect_err("a text file opened as a ledger");
    let text = err.to_string();
    assert!(
        text.starts_with(&format!("ledger {}: ", path.display())),
        "{text}"
    );
    assert!(text.contains("not a database"), "{text}");
    // A directory where the file should be.
    let err = Ledger::open(&LedgerSpec::Sqlite(dir.path().to_path_buf()))
        .map(|_| ())
        .expect_err("a directory opened as a ledger");
    assert!(err
        .to_string()
        .starts_with(&format!("ledger {}: ", dir.path().display())));
}

#[test]
fn a_record_with_a_number_json_cannot_hold_is_refused_naming_its_field() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let mut ledger = open(&LedgerSpec::Sqlite(dir.path().join("ledger.sqlite")));
    let mut flight = record(3);
    flight.parts[2].measured_j = Some(f64::NAN);
    let err = ledger.write(&flight).map(|_| ()).expect_err("NaN written");
    assert_eq!(
        err.to_string(),
        format!(
            "flights/flight-0003: record `{}`: parts[2].measured_j is NaN, which the ledger \
             cannot keep",
            flight.id
        )
    );
    flight.parts[2].measured_j = None;
    flight.duration_s = f64::INFINITY;
    assert!(ledger.write(&flight).is_err());
    flight.duration_s = 1.0;
    flight.id = String::new();
    assert!(ledger.write(&flight).is_err());
    assert_eq!(ledger.count().expect("counted"), 0);
}

#[test]
fn a_postgres_url_is_named_without_its_password() {
    let shown = |url: &str| LedgerSpec::parse(url).to_string();
    assert_eq!(
        shown("postgres://team:s3cr%40t@db.example:5432/ledger"),
        "postgres://team:***@db.example:5432/ledger"
    );
    assert_eq!(
        shown("postgresql://team@db/ledger?password=s3cret&sslmode=disable"),
        "postgresql://team@db/ledger?password=***&sslmode=disable"
    );
    assert_eq!(shown("postgres://db/ledger"), "postgres://db/ledger");
    assert_eq!(shown("flights/ledger.sqlite"), "flights/ledger.sqlite");
}

#[test]
fn an_unreachable_postgres_server_is_an_error_naming_it_without_its_password() {
    // Port 1 on the loopback: nothing listens there, the connection is refused at once.
    let spec = LedgerSpec::parse("postgres://team:s3cret@127.0.0.1:1/ledger?connect_timeout=5");
    let err = Ledger::open(&spec)
        .map(|_| ())
        .expect_err("connected to port 1");
    let text = err.to_string();
    assert!(
        text.starts_with(
            "ledger postgres://team:***@127.0.0.1:1/ledger?connect_timeout=5: cannot connect:"
        ),
        "{text}"
    );
    assert!(!text.contains("s3cret"), "{text}");
}

#[test]
fn the_postgres_ledger_refuses_the_async_runtime_rather_than_panic() {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .build()
        .expect("a runtime");
    let spec = LedgerSpec::parse("postgres://team@127.0.0.1:1/ledger");
    let err = runtime.block_on(async { Ledger::open(&spec).map(|_| ()) });
    let text = err.expect_err("opened on the runtime").to_string();
    assert!(text.contains("spawn_blocking"), "{text}");
}

#[test]
fn date_bounds_take_whole_days_and_refuse_what_is_not_a_date() {
    let until = |s: &str| until_bound(s).map_err(|e| e.to_string());
    assert_eq!(until("2026-03-01"), Ok(("2026-03-02".into(), false)));
    assert_eq!(until("2026-02-28"), Ok(("2026-03-01".into(), false)));
    assert_eq!(until("2028-02-28"), Ok(("2028-02-29".into(), false)));
    assert_eq!(until("2100-02-28"), Ok(("2100-03-01".into(), false)));
    assert_eq!(until("2000-02-29"), Ok(("2000-03-01".into(), false)));
    assert_eq!(until("2026-04-30"), Ok(("2026-05-01".into(), false)));
    assert_eq!(until("2026-12-31"), Ok(("2027-01-01".into(), false)));
    assert_eq!(
        until("2026-03-01T12:00:00Z"),
        Ok(("2026-03-01T12:00:00Z".into(), true))
    );
    for bad in [
        "2026-02-29",
        "2026-13-01",
        "2026-00-10",
        "2026-1-1",
        "yesterday",
        "",
        "2026-03-01T24:00:00Z",
        "2026-03-01 12:00:00",
        "२०२६-03-01",
    ] {
        assert!(until_bound(bad).is_err(), "{bad} accepted as until");
        assert_eq!(
            since_bound(bad).map_err(|e| e.to_string()),
            Err(format!(
                "since `{bad}`: not a date (YYYY-MM-DD) or a time (YYYY-MM-DDTHH:MM:SSZ)"
            ))
        );
    }
}

#[test]
fn the_sql_is_written_once_with_numbered_parameters() {
    assert_eq!(
        Dialect::Sqlite.sql("SELECT a FROM t WHERE b = $1 AND c = $12"),
        "SELECT a FROM t WHERE b = ?1 AND c = ?12"
    );
    let sql = "SELECT record FROM flights WHERE id = $1";
    assert_eq!(Dialect::Postgres.sql(sql), sql);
}
