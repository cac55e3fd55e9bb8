//! The ledger's commands through the binary: `ledger rebuild` of flown flights gives the rows
//! the flights wrote (and again changes nothing), `ledger import` of flight directories and
//! onboard logs names a bad file and imports the others, `flights` and `packs` read the ledger
//! (as tables, JSON and a figure) and never create one, and `calibrate --from-ledger` fits the
//! vehicle's flight directories the ledger knows as `--from-logs` fits them listed.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use emplan::ledger::{record, FlightQuery, FlightRecord, Ledger, LedgerSpec};

use crate::{emplan, json};

const ONBOARD: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/onboard");

/// Two flights of the 3-waypoint sample flown on the built-in mock (hvb profile: its table is
/// the quick one to rebuild), shared by the tests here, which only read them.
fn flown() -> &'static Path {
    static FLOWN: OnceLock<PathBuf> = OnceLock::new();
    FLOWN.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ledger-cli-flights");
        let _ = std::fs::remove_dir_all(&dir);
        for _ in 0..2 {
            json(&[
                "fly",
                "missions/paper-sample-3wp.toml",
                "--profile",
                "hvb",
                "--log-dir",
                dir.to_str().unwrap(),
                "--speedup",
                "50",
                "--json",
            ]);
        }
        dir
    })
}

/// The flight directories in `dir`, oldest first.
fn flight_dirs(dir: &Path) -> Vec<PathBuf> {
    let dirs = emplan::session::flight_dirs(dir).unwrap();
    assert_eq!(dirs.len(), 2, "{dirs:?}");
    dirs
}

/// Every flight of the SQLite ledger at `path`.
fn rows(path: &Path) -> Vec<FlightRecord> {
    Ledger::open(&LedgerSpec::Sqlite(path.to_path_buf()))
        .unwrap()
        .flights(&FlightQuery::default())
        .unwrap()
}

/// The ledger the flights wrote as they were flown: the one `fly` keeps beside them, else
/// (a `fly` that writes none) each flight's record written as the session writes it.
fn live_ledger(flights: &Path, tmp: &Path) -> PathBuf {
    let beside = flights.join("ledger.sqlite");
    if beside.is_file() {
        return beside;
    }
    let path = tmp.join("live.sqlite");
    let mut ledger = Ledger::open(&LedgerSpec::Sqlite(path.clone())).unwrap();
    for dir in flight_dirs(flights) {
        ledger.write(&record::from_dir(&dir).unwrap()).unwrap();
    }
    path
}

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

#[test]
fn ledger_rebuild_of_flown_flights_gives_the_rows_they_wrote_and_again_changes_nothing() {
    let flights = flown();
    let tmp = tempfile::tempdir().unwrap();
    let live = live_ledger(flights, tmp.path());
    let fresh = tmp.path().join("rebuilt.sqlite");
    let (ok, out, err) = emplan(&["ledger", "rebuild", s(flights), "--ledger", s(&fresh)]);
    assert!(ok, "{err}");
    assert!(out.contains("2 inserted, 0 unchanged, 0 replaced"), "{out}");
    let rebuilt = rows(&fresh);
    assert_eq!(rebuilt.len(), 2);
    assert_eq!(rebuilt, rows(&live));
    // Each flight directory named alone: the same rows, written again, change nothing.
    let dirs = flight_dirs(flights);
    let (ok, out, err) = emplan(&[
        "ledger",
        "rebuild",
        s(&dirs[0]),
        s(&dirs[1]),
        "--ledger",
        s(&fresh),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("0 inserted, 2 unchanged, 0 replaced"), "{out}");
    assert_eq!(rows(&fresh), rebuilt);
}

#[test]
fn ledger_rebuild_names_what_is_no_flight_directory_and_rebuilds_the_rest() {
    let flights = flown();
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("notes.txt");
    std::fs::write(&file, "not a flight").unwrap();
    let empty = tmp.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let ledger = tmp.path().join("l.sqlite");
    let (ok, out, err) = emplan(&[
        "ledger",
        "rebuild",
        s(&file),
        s(flights),
        s(&empty),
        "--ledger",
        s(&ledger),
    ]);
    assert!(!ok, "{out}");
    assert!(
        err.contains(&format!(
            "error: {}: a file, not a flight directory",
            s(&file)
        )),
        "{err}"
    );
    assert!(
        err.contains(&format!("error: {}: not a flight directory", s(&empty))),
        "{err}"
    );
    assert!(out.contains("2 inserted"), "{out}");
    assert_eq!(rows(&ledger).len(), 2);
}

#[test]
fn ledger_import_of_directories_and_onboard_logs_names_a_bad_file_and_imports_the_others() {
    let flights = flown();
    let tmp = tempfile::tempdir().unwrap();
    // The PX4 log with the plan it flew beside it; the ArduPilot log holds its mission.
    let px4 = tmp.path().join("px4");
    std::fs::create_dir(&px4).unwrap();
    std::fs::copy(
        Path::new(ONBOARD).join("px4-sih-8wp.plan.json"),
        px4.join("plan.json"),
    )
    .unwrap();
    std::fs::copy(
        Path::new(ONBOARD).join("px4-sih-8wp.ulg"),
        px4.join("sih.ulg"),
    )
    .unwrap();
    let bin = tmp.path().join("arducopter.bin");
    std::fs::copy(Path::new(ONBOARD).join("arducopter-8wp.bin"), &bin).unwrap();
    let broken = tmp.path().join("broken.ulg");
    std::fs::write(&broken, b"ULog\x01\x12\x35 cut short").unwrap();
    let ledger = tmp.path().join("l.sqlite");
    let (ok, out, err) = emplan(&[
        "ledger",
        "import",
        s(flights),
        s(&px4.join("sih.ulg")),
        s(&broken),
        s(&bin),
        "--pack",
        "field-7",
        "--jobs",
        "2",
        "--ledger",
        s(&ledger),
    ]);
    assert!(!ok, "a bad file fails the import: {out}");
    assert!(err.contains(&format!("error: {}: ", s(&broken))), "{err}");
    assert_eq!(err.matches("error:").count(), 1, "{err}");
    assert!(
        out.contains("4 inserted, 0 unchanged, 0 replaced (5 flights found)"),
        "{out}"
    );
    let doc = json(&["flights", "--json", "--ledger", s(&ledger)]);
    let listed = doc["flights"].as_array().unwrap();
    assert_eq!(listed.len(), 4, "{doc}");
    let sources: Vec<&str> = listed
        .iter()
        .map(|f| f["source"].as_str().unwrap())
        .collect();
    for source in ["directory", "ulog", "dataflash"] {
        assert!(sources.contains(&source), "{sources:?}");
    }
    // The logs imported alone say no pack: they take --pack's.
    for f in listed.iter().filter(|f| f["source"] != "directory") {
        assert_eq!(f["pack"], "field-7", "{f}");
    }
    // The same again: nothing changes; the bad file still named.
    let (ok, out, _) = emplan(&[
        "ledger",
        "import",
        s(flights),
        s(&px4.join("sih.ulg")),
        s(&bin),
        "--pack",
        "field-7",
        "--ledger",
        s(&ledger),
    ]);
    assert!(ok, "{out}");
    assert!(out.contains("0 inserted, 4 unchanged, 0 replaced"), "{out}");
}

#[test]
fn reading_commands_refuse_a_missing_ledger_naming_it_and_create_none() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("nowhere.sqlite");
    for args in [
        vec!["flights"],
        vec!["packs"],
        vec!["calibrate", "--from-ledger"],
    ] {
        let mut args = args;
        args.extend(["--ledger", s(&missing)]);
        let (ok, out, err) = emplan(&args);
        assert!(!ok, "{args:?}: {out}");
        assert!(
            err.contains(&format!("ledger {}: no such ledger", s(&missing)))
                && err.contains("emplan ledger rebuild"),
            "{args:?}: {err}"
        );
        assert!(!missing.exists(), "{args:?} created the ledger");
    }
}

#[test]
fn flights_lists_the_ledger_by_pack_and_date_as_a_table_and_as_json() {
    let flights = flown();
    let tmp = tempfile::tempdir().unwrap();
    let ledger = tmp.path().join("l.sqlite");
    let dirs = flight_dirs(flights);
    let (ok, _, err) = emplan(&[
        "ledger",
        "import",
        s(&dirs[0]),
        "--pack",
        "alpha",
        "--ledger",
        s(&ledger),
    ]);
    assert!(ok, "{err}");
    let (ok, _, err) = emplan(&[
        "ledger",
        "import",
        s(&dirs[1]),
        "--pack",
        "beta",
        "--ledger",
        s(&ledger),
    ]);
    assert!(ok, "{err}");
    let all = json(&["flights", "--json", "--ledger", s(&ledger)]);
    let all = all["flights"].as_array().unwrap().clone();
    assert_eq!(all.len(), 2);
    let pack = all[1]["pack"].as_str().unwrap().to_string();
    let mission = all[0]["mission"].as_str().unwrap().to_string();
    let by_pack = json(&["flights", "--json", "--pack", &pack, "--ledger", s(&ledger)]);
    assert_eq!(
        by_pack["flights"].as_array().unwrap().len(),
        if all[0]["pack"] == all[1]["pack"] {
            2
        } else {
            1
        }
    );
    assert_eq!(by_pack["flights"][0]["pack"], pack.as_str());
    // Dates: the flights were flown today (UTC), none in the year 2000.
    let day = &all[0]["started_at"].as_str().unwrap()[..10];
    let since = json(&["flights", "--json", "--since", day, "--ledger", s(&ledger)]);
    assert_eq!(since["flights"].as_array().unwrap().len(), 2);
    let until = json(&[
        "flights",
        "--json",
        "--until",
        "2000-01-01",
        "--ledger",
        s(&ledger),
    ]);
    assert_eq!(until["flights"].as_array().unwrap().len(), 0);
    let (ok, _, err) = emplan(&["flights", "--since", "29/11/2026", "--ledger", s(&ledger)]);
    assert!(
        !ok && err.contains("since `29/11/2026`") && err.contains("YYYY-MM-DD"),
        "{err}"
    );
    // The table: a row per flight with its mission, pack and outcome.
    let (ok, out, err) = emplan(&["flights", "--ledger", s(&ledger)]);
    assert!(ok, "{err}");
    assert!(out.starts_with("2 flights in the ledger"), "{out}");
    let rows: Vec<&str> = out.lines().filter(|l| l.contains(&mission)).collect();
    assert_eq!(rows.len(), 2, "{out}");
    assert!(rows.iter().all(|r| r.contains("completed")), "{out}");
    assert!(rows[1].contains(&pack), "{out}");
}

#[test]
fn packs_summarises_each_pack_as_a_table_and_json_and_plots_capacity_over_cycles() {
    let flights = flown();
    let tmp = tempfile::tempdir().unwrap();
    let ledger = tmp.path().join("l.sqlite");
    let (ok, _, err) = emplan(&[
        "ledger",
        "import",
        s(flights),
        "--pack",
        "field-3",
        "--ledger",
        s(&ledger),
    ]);
    assert!(ok, "{err}");
    let listed = json(&["flights", "--json", "--ledger", s(&ledger)]);
    let mut names: Vec<String> = listed["flights"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["pack"].as_str().unwrap().to_string())
        .collect();
    names.sort();
    let doc = json(&["packs", "--json", "--ledger", s(&ledger)]);
    let packs = doc["packs"].as_array().unwrap();
    let mut counted: Vec<(String, u64)> = packs
        .iter()
        .map(|p| {
            (
                p["name"].as_str().unwrap().to_string(),
                p["flights"].as_u64().unwrap(),
            )
        })
        .collect();
    counted.sort();
    let mut expected: Vec<(String, u64)> = Vec::new();
    for name in names {
        match expected.last_mut() {
            Some((n, c)) if *n == name => *c += 1,
            _ => expected.push((name, 1)),
        }
    }
    assert_eq!(counted, expected, "{doc}");
    let (ok, out, err) = emplan(&["packs", "--ledger", s(&ledger)]);
    assert!(ok, "{err}");
    for (name, _) in &expected {
        assert!(out.lines().any(|l| l.starts_with(name.as_str())), "{out}");
    }
    let svg = tmp.path().join("packs.svg");
    let (ok, out, err) = emplan(&["packs", "--plot", s(&svg), "--ledger", s(&ledger)]);
    assert!(ok, "{err}");
    assert!(out.contains(&format!("wrote {}", s(&svg))), "{out}");
    let drawn = std::fs::read_to_string(&svg).unwrap();
    assert!(drawn.starts_with("<svg"), "{drawn}");
    assert!(drawn.contains("capacity fitted per flight"));
    for (name, _) in &expected {
        assert!(drawn.contains(name.as_str()), "{name} not in the figure");
    }
    // An existing figure is not replaced unforced, and the ledger never.
    let (ok, _, err) = emplan(&["packs", "--plot", s(&svg), "--ledger", s(&ledger)]);
    assert!(!ok && err.contains("--force"), "{err}");
    let (ok, _, err) = emplan(&[
        "packs",
        "--plot",
        s(&ledger),
        "--force",
        "--ledger",
        s(&ledger),
    ]);
    assert!(
        !ok && err.contains("refusing to write over the input"),
        "{err}"
    );
}

#[test]
fn calibrate_from_ledger_fits_the_vehicles_flight_directories_as_from_logs_fits_them_listed() {
    let flights = flown();
    let tmp = tempfile::tempdir().unwrap();
    let ledger = tmp.path().join("l.sqlite");
    let (ok, _, err) = emplan(&["ledger", "rebuild", s(flights), "--ledger", s(&ledger)]);
    assert!(ok, "{err}");
    let listed = json(&[
        "calibrate",
        "--from-logs",
        s(flights),
        "--profile",
        "hvb",
        "--json",
    ]);
    let ledgered = json(&[
        "calibrate",
        "--from-ledger",
        "--ledger",
        s(&ledger),
        "--profile",
        "hvb",
        "--json",
    ]);
    assert_eq!(
        ledgered["flights"].as_array().unwrap().len(),
        2,
        "{ledgered}"
    );
    assert_eq!(ledgered["flights"], listed["flights"]);
    assert_eq!(ledgered["legs"], listed["legs"]);
    assert_eq!(ledgered["fitted"], listed["fitted"]);

    // Another vehicle (the same airframe under another name) has no flight in the ledger.
    let other = tmp.path().join("other");
    std::fs::create_dir(&other).unwrap();
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000/vehicle.toml"),
    )
    .unwrap();
    let renamed: String = text
        .lines()
        .map(|l| {
            if l.starts_with("name =") {
                "name = \"another S1000\"".to_string()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(other.join("vehicle.toml"), renamed).unwrap();
    let (ok, out, err) = emplan(&[
        "calibrate",
        "--from-ledger",
        "--vehicle",
        s(&other),
        "--ledger",
        s(&ledger),
    ]);
    assert!(!ok, "{out}");
    assert!(
        err.contains(&format!(
            "--from-ledger: the ledger {} holds no flight directory of the vehicle another S1000",
            s(&ledger)
        )) && err.contains("0 flights of it"),
        "{err}"
    );
}
