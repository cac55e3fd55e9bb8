//! A corrupt .tlog through the binary: 100 bytes of garbage in the middle of a flight's log are
//! skipped, said on stderr with their offset and length, kept in the report's `log_gaps`, and
//! the parts of the flight they touch flagged `log_gap`; a file of random bytes is an error
//! naming it, not an empty flight.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::{emplan, json};

/// `n` bytes of noise from `seed` (the project's own generator).
fn noise(n: usize, seed: u64) -> Vec<u8> {
    let mut rng = emplan::rng::Rng::new(seed);
    (0..n).map(|_| (rng.next_u64() >> 24) as u8).collect()
}

/// Flies the 8-waypoint sample on the built-in mock into `log_dir`: its flight directory and
/// report.
fn fly_sample(log_dir: &Path) -> (PathBuf, Value) {
    let report = json(&[
        "fly",
        "missions/paper-sample-8wp.toml",
        "--log-dir",
        log_dir.to_str().expect("a UTF-8 temp path"),
        "--json",
        "--speedup",
        "50",
    ]);
    let dir = PathBuf::from(report["log_dir"].as_str().expect("log_dir"));
    (dir, report)
}

/// `log` with 100 bytes of noise inserted at byte `at`.
fn damaged(log: &[u8], at: usize) -> Vec<u8> {
    let mut out = log[..at].to_vec();
    out.extend(noise(100, 25));
    out.extend(&log[at..]);
    out
}

/// The offset of the first record of `tlog` whose reading is stamped at or after vehicle time
/// `t_s` (the same decoding and clock as the replay).
fn offset_at(tlog: &Path, t_s: f64) -> u64 {
    let log = emplan::flightlog::tlog::read_tlog(tlog).expect("the clean log reads");
    let mut telemetry = emplan::link::telemetry::Telemetry::new();
    log.records
        .iter()
        .find(|r| {
            telemetry
                .frame(r.wall_us, &r.frame)
                .is_some_and(|s| s.t_s >= t_s)
        })
        .map(|r| r.offset)
        .expect("a reading that late")
}

/// Every part of a report with its kind: (name, part).
fn parts(report: &Value) -> Vec<(String, &Value)> {
    let mut out = Vec::new();
    for key in ["takeoff", "landing"] {
        if report[key].is_object() {
            out.push((key.to_string(), &report[key]));
        }
    }
    for key in ["legs", "settles", "hovers"] {
        for (k, p) in report[key].as_array().into_iter().flatten().enumerate() {
            out.push((format!("{key}[{k}] {} -> {}", p["from"], p["to"]), p));
        }
    }
    out
}

fn flagged(part: &Value) -> bool {
    part["flags"]
        .as_array()
        .is_some_and(|f| f.iter().any(|x| x == "log_gap"))
}

/// Checks a replayed report of the damaged log and the stderr that came with it: one gap over
/// the garbage, named on stderr; all 9 legs; exactly the parts overlapping the gap flagged.
fn check_damaged(report: &Value, stderr: &str, tlog: &Path, inserted_at: u64) {
    let gaps = report["log_gaps"].as_array().expect("log_gaps");
    assert_eq!(gaps.len(), 1, "{gaps:?}");
    let gap = &gaps[0];
    let offset = gap["offset"].as_u64().expect("offset");
    let bytes = gap["bytes"].as_u64().expect("bytes");
    // The garbage, and at most the one record it landed in.
    assert!(
        offset <= inserted_at && inserted_at + 100 <= offset + bytes && bytes <= 100 + 8 + 285,
        "{gap}"
    );
    assert!(
        stderr.contains(&tlog.display().to_string())
            && stderr.contains(&format!("{bytes} bytes at byte {offset}")),
        "{stderr}"
    );
    let legs = report["legs"].as_array().expect("legs");
    assert_eq!(legs.len(), 9, "{report}");
    let from_s = gap["from_s"].as_f64().expect("a reading before the gap");
    let to_s = gap["to_s"].as_f64().expect("a reading after the gap");
    let mut touched = 0;
    for (name, part) in parts(report) {
        let (start, end) = (part["start_s"].as_f64(), part["end_s"].as_f64());
        let (start, end) = (start.expect("start_s"), end.expect("end_s"));
        let overlaps = from_s < end && to_s > start;
        assert_eq!(
            flagged(part),
            overlaps,
            "{name} ({start} .. {end}) against the gap {from_s} .. {to_s}: {}",
            part["flags"]
        );
        if overlaps {
            touched += 1;
            // The time lost counts as uncovered; a gap between two readings of the same
            // vehicle time (several messages of one autopilot step) loses none.
            if to_s > from_s {
                assert!(
                    part["coverage"].as_f64().is_some_and(|c| c < 1.0),
                    "{name}: {part} against the gap {from_s} .. {to_s}"
                );
            }
        }
    }
    assert!(touched >= 1, "the gap {gap} touches no part");
}

#[test]
fn garbage_mid_log_is_skipped_said_and_flagged_and_random_bytes_are_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let (flight, live) = fly_sample(dir.path());
    let tlog = flight.join("flight.tlog");
    let clean = std::fs::read(&tlog).unwrap();
    let tlog_arg = tlog.to_str().unwrap();

    // Inside a record in the middle of leg 5 (G -> B, the long one): that leg alone flagged,
    // still measured.
    let leg5 = &live["legs"][4];
    let (start, end) = (
        leg5["start_s"].as_f64().unwrap(),
        leg5["end_s"].as_f64().unwrap(),
    );
    let at = offset_at(&tlog, 0.5 * (start + end)) as usize + 13;
    std::fs::write(&tlog, damaged(&clean, at)).unwrap();
    let (ok, stdout, stderr) = emplan(&["replay", tlog_arg, "--json"]);
    assert!(ok, "{stderr}");
    let replayed: Value = serde_json::from_str(&stdout).expect("JSON");
    check_damaged(&replayed, &stderr, &tlog, at as u64);
    for (k, leg) in replayed["legs"].as_array().unwrap().iter().enumerate() {
        assert_eq!(flagged(leg), k == 4, "leg {}: {}", k + 1, leg["flags"]);
    }
    assert!(replayed["legs"][4]["measured_kj"].as_f64().is_some());

    // At half the log's length, as the issue did it.
    let at = clean.len() / 2;
    std::fs::write(&tlog, damaged(&clean, at)).unwrap();
    let (ok, stdout, stderr) = emplan(&["replay", tlog_arg, "--json"]);
    assert!(ok, "{stderr}");
    let replayed: Value = serde_json::from_str(&stdout).expect("JSON");
    check_damaged(&replayed, &stderr, &tlog, at as u64);
    assert!(stderr.contains("warning"), "{stderr}");

    let (ok, stdout, stderr) = emplan(&["report", flight.to_str().unwrap(), "--json"]);
    assert!(ok, "{stderr}");
    let reported: Value = serde_json::from_str(&stdout).expect("JSON");
    check_damaged(&reported, &stderr, &tlog, at as u64);

    // A file of random bytes, alone or as a flight directory's log: an error naming it.
    let random = dir.path().join("random.tlog");
    std::fs::write(&random, noise(3_000_000, 9)).unwrap();
    let (ok, _, stderr) = emplan(&["replay", random.to_str().unwrap()]);
    assert!(!ok, "{stderr}");
    assert!(
        stderr.contains(&format!(
            "{}: no MAVLink frame found in 3000000 bytes",
            random.display()
        )),
        "{stderr}"
    );
    std::fs::copy(&random, &tlog).unwrap();
    let (ok, _, stderr) = emplan(&["report", flight.to_str().unwrap()]);
    assert!(!ok, "{stderr}");
    assert!(
        stderr.contains(&format!(
            "{}: no MAVLink frame found in 3000000 bytes",
            tlog.display()
        )),
        "{stderr}"
    );
}
