//! The ledger's record of real flights on the built-in mock (`emplan fly --mock-vehicle`): a
//! vehicle whose pack holds 0.85 of the label the plan is made with, flown three times; each
//! flight directory's record (`ledger::record::from_dir`) fits the pack from that flight's
//! voltage and current, and the three together give the capacity within 3% of the truth.

use std::path::{Path, PathBuf};

use emplan::ledger::packs::{pack_prior, summarise};
use emplan::ledger::record::from_dir;
use emplan::ledger::{FlightRecord, Outcome};

use super::service::root;

/// The truth's capacity against the plan's label.
const TRUTH_RATIO: f64 = 0.85;

/// The truth: a copy of the shipped S1000 (`models/s1000`) in `dir` with its pack's capacity
/// and usable energy 0.85 of the file's, nothing else changed.
fn weaker_pack(dir: &Path) -> PathBuf {
    let from = root().join("models/s1000");
    let to = dir.join("s1000-weaker-pack");
    std::fs::create_dir_all(&to).expect("truth dir");
    for entry in std::fs::read_dir(&from).expect("models/s1000") {
        let entry = entry.expect("entry");
        std::fs::copy(entry.path(), to.join(entry.file_name())).expect("copied");
    }
    let path = to.join("vehicle.toml");
    let text = std::fs::read_to_string(&path).expect("vehicle.toml");
    let mut changed = 0;
    let lines: Vec<String> = text
        .lines()
        .map(|line| {
            let key = line.split('=').next().unwrap_or("").trim();
            if key != "capacity_ah" && key != "usable_energy_wh" {
                return line.to_string();
            }
            let value: f64 = line
                .split('=')
                .nth(1)
                .unwrap()
                .split('#')
                .next()
                .unwrap()
                .trim()
                .parse()
                .unwrap();
            changed += 1;
            format!("{key} = {}", value * TRUTH_RATIO)
        })
        .collect();
    assert_eq!(changed, 2, "{text}");
    std::fs::write(&path, lines.join("\n") + "\n").expect("written");
    to
}

/// The flight directories in `log_dir`, by name.
fn flight_dirs(log_dir: &Path) -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(log_dir)
        .map(|d| {
            d.filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.is_dir())
                .collect()
        })
        .unwrap_or_default();
    dirs.sort();
    dirs
}

/// Flies the sample mission on the mock with `truth`'s pack; returns the new flight directory.
fn fly(truth: &Path, log_dir: &Path) -> PathBuf {
    let before = flight_dirs(log_dir);
    let mission = root().join("missions/paper-sample-8wp.toml");
    let (ok, out, err) = super::emplan(&[
        "fly",
        mission.to_str().unwrap(),
        "--mock-vehicle",
        truth.to_str().unwrap(),
        "--speedup",
        "50",
        "--log-dir",
        log_dir.to_str().unwrap(),
        "--json",
    ]);
    assert!(ok, "{out}{err}");
    let doc: serde_json::Value =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    assert_eq!(doc["complete"], true, "{out}");
    let new: Vec<PathBuf> = flight_dirs(log_dir)
        .into_iter()
        .filter(|d| !before.contains(d))
        .collect();
    assert_eq!(new.len(), 1, "{new:?}");
    new.into_iter().next().unwrap()
}

#[test]
fn three_mock_flights_on_a_weaker_pack_find_its_capacity_within_three_percent() {
    let work = tempfile::tempdir().expect("temp dir");
    let truth = weaker_pack(work.path());
    let log_dir = work.path().join("flights");
    let mut records: Vec<FlightRecord> = Vec::new();
    for _ in 0..3 {
        let dir = fly(&truth, &log_dir);
        let record = from_dir(&dir).unwrap_or_else(|e| panic!("{e}"));
        let fit = record.pack_fit.clone().expect("a pack fit");
        let ratio = fit.capacity_ah / fit.label_capacity_ah;
        eprintln!(
            "{}: capacity {:.3} Ah of {:.1} (ratio {:.4} +- {:.4}), R {:.4} ohm, SOC0 {:.3}, {} samples, rms {:.4} V, charge {:.3} Ah",
            record.id,
            fit.capacity_ah,
            fit.label_capacity_ah,
            ratio,
            fit.capacity_sd_ah / fit.label_capacity_ah,
            fit.internal_resistance_ohm,
            fit.state_of_charge_at_takeoff,
            fit.samples,
            fit.voltage_rms_v,
            record.charge_ah.unwrap_or(f64::NAN)
        );
        // The plan's label is the shipped vehicle file's; the truth holds 0.85 of it.
        assert_eq!(fit.label_capacity_ah, 10.0);
        // One flight alone: within its own error (three standard errors) of the truth.
        assert!(
            (ratio - TRUTH_RATIO).abs() < 3.0 * fit.capacity_sd_ah / fit.label_capacity_ah + 0.01,
            "{fit:?}"
        );
        assert!(
            fit.capacity_sd_ah > 0.0 && fit.capacity_sd_ah < 0.5,
            "{fit:?}"
        );
        // The truth's pack resistance (the shipped file's 0.02 ohm), seen through the
        // monitor's noise and its current filter.
        assert!(
            (fit.internal_resistance_ohm - 0.02).abs() < 0.005,
            "{fit:?}"
        );
        assert!(
            (fit.state_of_charge_at_takeoff - 1.0).abs() < 0.03,
            "{fit:?}"
        );
        // The record's other fields, from the directory's files.
        assert_eq!(record.outcome, Outcome::Completed);
        assert_eq!(record.mission, "paper-sample-8wp");
        assert_eq!(record.autopilot.as_deref(), Some("px4"));
        assert_eq!(record.profile.as_deref(), Some("px4"));
        assert!(
            record
                .vehicle
                .as_deref()
                .is_some_and(|v| v.contains("S1000")),
            "{record:?}"
        );
        let name = dir.file_name().unwrap().to_str().unwrap();
        assert!(
            record.id.starts_with(name) && record.id.len() == name.len() + 17,
            "{}",
            record.id
        );
        let started = record.started_at.clone().expect("a start");
        assert_eq!(
            (&started[0..4], &started[5..7], &started[8..10]),
            (&name[0..4], &name[4..6], &name[6..8]),
            "{started} {name}"
        );
        // Take-off first, then each point's leg, settle and hover, then the landing.
        let kinds: Vec<&str> = record.parts.iter().map(|p| p.kind.as_str()).collect();
        assert_eq!(kinds.first(), Some(&"takeoff"));
        assert_eq!(kinds.last(), Some(&"landing"));
        assert_eq!(&kinds[1..4], ["leg", "settle", "hover"]);
        assert!(record
            .parts
            .iter()
            .enumerate()
            .all(|(k, p)| p.index as usize == k));
        // The charge drawn, arming to disarming: the energy measured over it is at a 6S pack's
        // voltage under load (between its empty 3.5 V and full 4.2 V a cell).
        let charge = record.charge_ah.expect("charge");
        let volts = record.measured_j.unwrap() / 3600.0 / charge;
        assert!((21.0..25.2).contains(&volts), "{charge} Ah at {volts} V");
        // The same flight copied elsewhere is the same record but for its path.
        let copy = work.path().join("copy").join(name);
        std::fs::create_dir_all(&copy).unwrap();
        for f in ["plan.json", "report.json", "samples.csv", "flight.tlog"] {
            std::fs::copy(dir.join(f), copy.join(f)).unwrap();
        }
        let again = from_dir(&copy).unwrap();
        assert_eq!(
            FlightRecord {
                path: record.path.clone(),
                ..again
            },
            record
        );
        records.push(record);
    }
    // Three flights are three records.
    assert_ne!(records[0].id, records[1].id);
    assert_ne!(records[1].id, records[2].id);
    // The pack's capacity from the three: within 3% of the truth.
    for r in &mut records {
        r.pack = Some("pack 1".into());
    }
    let summary = &summarise(&records)[0];
    let now = summary.capacity_ratio.expect("a capacity");
    eprintln!(
        "pack over 3 flights: capacity ratio {:.4} +- {:.4}, R {:?}, cycles {:.3}",
        now.value, now.sd, summary.internal_resistance_ohm, summary.cycles
    );
    assert!((now.value / TRUTH_RATIO - 1.0).abs() < 0.03, "{summary:?}");
    assert!(now.sd < 0.03, "{summary:?}");
    assert_eq!(summary.flights, 3);
    assert!(summary.warnings.is_empty(), "{summary:?}");
    let prior = pack_prior(&records, "pack 1").expect("a prior");
    assert_eq!(prior.flights, 3);
    assert!((prior.capacity_ratio - now.value).abs() < 1e-12);
}
