//! The ledger learning a pack through the binary: five flights on the built-in mock of a pack
//! whose truth capacity is 0.85 of its label (`--mock-vehicle`), each written to the ledger as
//! it lands; after three the ledger knows the capacity within 3%, and the fourth flight's
//! battery check and energy guard start from it. Also: a pack named by the autopilot
//! (SMART_BATTERY_INFO) is the flight's pack when none is given.

use std::path::{Path, PathBuf};

use serde_json::Value;

use emplan::ledger::{packs, FlightQuery, Ledger, LedgerSpec};

use super::service::root;

/// The truth: the shipped S1000 (its tables too) with its pack's capacity and usable energy
/// 0.85 of the label's, in `dir`.
fn aged_pack_vehicle(dir: &Path) -> PathBuf {
    let from = root().join("models/s1000");
    let to = dir.join("s1000-aged-pack");
    std::fs::create_dir_all(&to).expect("made");
    for entry in std::fs::read_dir(&from).expect("listed").flatten() {
        std::fs::copy(entry.path(), to.join(entry.file_name())).expect("copied");
    }
    let text = std::fs::read_to_string(to.join("vehicle.toml")).expect("read");
    let mut scaled = 0;
    let lines: Vec<String> = text
        .lines()
        .map(|line| {
            let key = line.split('=').next().unwrap_or("").trim();
            if !["capacity_ah", "usable_energy_wh"].contains(&key) {
                return line.to_string();
            }
            let value: f64 = (line.split('=').nth(1).unwrap().split('#').next().unwrap())
                .trim()
                .parse()
                .expect("a number");
            scaled += 1;
            format!("{key} = {}", value * 0.85)
        })
        .collect();
    assert_eq!(scaled, 2, "both keys found in {text}");
    std::fs::write(to.join("vehicle.toml"), lines.join("\n") + "\n").expect("written");
    to
}

/// Runs `emplan` from the crate root: (success, stdout, stderr).
fn emplan(args: &[&str]) -> (bool, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_emplan"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("emplan runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Flies the shipped 8-waypoint mission on the mock flying `truth`, logged in `logs`, with
/// `extra` arguments: its `fly --json` document.
fn fly(truth: &Path, logs: &Path, extra: &[&str]) -> Value {
    let mut args = vec![
        "fly",
        "missions/paper-sample-8wp.toml",
        "--mock-vehicle",
        truth.to_str().unwrap(),
        "--speedup",
        "50",
        "--log-dir",
        logs.to_str().unwrap(),
        "--json",
    ];
    args.extend(extra);
    let (ok, out, err) = emplan(&args);
    assert!(ok, "{out}{err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}{err}"))
}

/// A flight's plan.json.
fn plan_json(doc: &Value) -> Value {
    let dir = PathBuf::from(doc["log_dir"].as_str().expect("its directory"));
    let text = std::fs::read_to_string(dir.join("plan.json")).expect("plan.json");
    serde_json::from_str(&text).expect("JSON")
}

fn within_3_pct(value: f64, truth: f64) -> bool {
    (value / truth - 1.0).abs() < 0.03
}

#[test]
fn five_mock_flights_on_a_pack_of_085_teach_the_ledger_its_capacity_and_the_fourth_starts_from_it()
{
    let work = tempfile::tempdir().expect("temp dir");
    let truth = aged_pack_vehicle(work.path());
    let logs = work.path().join("flights");
    let ledger = logs.join("ledger.sqlite");
    let pack = ["--pack", "P3"];
    let label_ah = 10.0;
    for flight in 1..=5 {
        if flight == 4 {
            // After three: the ledger's capacity of P3 within 3% of the truth's.
            let mut store = Ledger::open(&LedgerSpec::Sqlite(ledger.clone())).expect("opened");
            let records = store.flights(&FlightQuery::default()).expect("listed");
            assert_eq!(records.len(), 3, "one record per flight");
            assert!(records.iter().all(|r| r.pack.as_deref() == Some("P3")));
            let summary = packs::summarise(&records);
            let p3 = summary.iter().find(|p| p.name == "P3").expect("P3");
            let capacity = p3.capacity_ah.expect("a capacity learned").value;
            assert!(within_3_pct(capacity, 0.85 * label_ah), "{p3:?}");
            let ratio = p3.capacity_ratio.expect("a ratio").value;
            assert!(within_3_pct(ratio, 0.85), "{p3:?}");
            // The fourth flight's battery check: the plan on that pack, its budget scaled.
            let (ok, out, err) = emplan(&[
                "plan",
                "missions/paper-sample-8wp.toml",
                "--order",
                "energy",
                "--pack",
                "P3",
                "--ledger",
                ledger.to_str().unwrap(),
                "--json",
            ]);
            assert!(ok, "{err}");
            let doc: Value = serde_json::from_str(&out).expect("JSON");
            let battery = &doc["battery"];
            assert_eq!(battery["pack"], "P3", "{battery}");
            assert_eq!(battery["pack_flights"], 3, "{battery}");
            let checked = battery["capacity_ratio"].as_f64().expect("a ratio");
            assert!(within_3_pct(checked, 0.85), "{battery}");
            let (budget, label) = (
                battery["budget_kj"].as_f64().unwrap(),
                battery["label_budget_kj"].as_f64().unwrap(),
            );
            assert!((budget / label - checked).abs() < 1e-9, "{battery}");
            // 576 kJ on the label (200 Wh, 20% reserve).
            assert!((label - 576.0).abs() < 1e-6, "{battery}");
        }
        let doc = fly(&truth, &logs, &pack);
        let plan = plan_json(&doc);
        assert_eq!(plan["pack"]["name"], "P3");
        assert_eq!(plan["pack"]["source"], "user");
        if flight == 1 {
            // Nothing learned yet: the label.
            assert!(
                plan["pack"].get("capacity_ratio").is_none(),
                "{}",
                plan["pack"]
            );
        }
        if flight == 4 {
            let used = plan["pack"]["capacity_ratio"].as_f64().expect("learned");
            assert!(within_3_pct(used, 0.85), "{}", plan["pack"]);
            let start = &plan["guard"]["start"];
            assert_eq!(start["capacity_ratio"].as_f64(), Some(used), "{start}");
            assert_eq!(start["pack_flights"], 3, "{start}");
            assert_eq!(start["vehicle_flights"], 3, "{start}");
            // The guard judged the flight on that pack: the capacity it ends with is the
            // truth's.
            let learned = doc["guard"]["capacity_ratio"].as_f64().expect("guarded");
            assert!(within_3_pct(learned, 0.85), "{}", doc["guard"]);
        }
    }
    let mut store = Ledger::open(&LedgerSpec::Sqlite(ledger)).expect("opened");
    assert_eq!(store.flights(&FlightQuery::default()).unwrap().len(), 5);
}

#[test]
fn the_pack_the_autopilot_names_is_the_flights_pack_unless_one_is_given() {
    let work = tempfile::tempdir().expect("temp dir");
    let logs = work.path().join("flights");
    let args = |extra: &[&'static str]| {
        let mut a = vec![
            "fly",
            "missions/paper-sample-3wp.toml",
            "--speedup",
            "50",
            "--log-dir",
            logs.to_str().unwrap(),
            "--json",
            "--mock-pack-serial",
            "4711",
        ];
        a.extend(extra);
        a
    };
    let (ok, out, err) = emplan(&args(&[]));
    assert!(ok, "{err}");
    let plan = plan_json(&serde_json::from_str(&out).expect("JSON"));
    assert_eq!(plan["pack"]["name"], "4711", "{}", plan["pack"]);
    assert_eq!(plan["pack"]["source"], "autopilot");
    let (ok, out, err) = emplan(&args(&["--pack", "P1"]));
    assert!(ok, "{err}");
    let plan = plan_json(&serde_json::from_str(&out).expect("JSON"));
    assert_eq!(plan["pack"]["name"], "P1");
    assert_eq!(plan["pack"]["source"], "user");
    // Both flights are in the ledger beside them.
    let mut store = Ledger::open(&LedgerSpec::Sqlite(logs.join("ledger.sqlite"))).expect("opened");
    let packs: Vec<Option<String>> = (store.flights(&FlightQuery::default()).unwrap())
        .into_iter()
        .map(|r| r.pack)
        .collect();
    assert_eq!(packs, [Some("4711".to_string()), Some("P1".to_string())]);
}

#[test]
fn a_pack_name_is_refused_empty_and_a_missing_ledger_is_not_created_by_plan() {
    let work = tempfile::tempdir().expect("temp dir");
    let ledger = work.path().join("none.sqlite");
    let (ok, out, err) = emplan(&[
        "plan",
        "missions/paper-sample-3wp.toml",
        "--pack",
        "P9",
        "--ledger",
        ledger.to_str().unwrap(),
        "--json",
    ]);
    assert!(ok, "{err}");
    assert!(
        err.contains("no ledger at") && err.contains("nothing learned"),
        "{err}"
    );
    assert!(!ledger.exists());
    let doc: Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(doc["battery"]["pack"], "P9");
    assert!(
        doc["battery"].get("capacity_ratio").is_none(),
        "{}",
        doc["battery"]
    );
    assert_eq!(
        doc["battery"]["budget_kj"],
        doc["battery"]["label_budget_kj"]
    );
    let (ok, _, err) = emplan(&["plan", "missions/paper-sample-3wp.toml", "--pack", " "]);
    assert!(!ok);
    assert!(err.contains("--pack: pack name is empty"), "{err}");
}
