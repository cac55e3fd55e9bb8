//! Races and silent re-flights: two uploads to the service at once (one answered, the other
//! refused 409, never both "verified"); `fly --resume` following the chain of a mission's
//! flights and saying when a flight's log is torn (the flights resumed are scripted flights
//! recorded as PX4 would send them, cut off mid-leg); a flight whose recording the service lost
//! measured when the service starts again; nothing recorded inside a flight directory
//! (`fly --log-dir`, `serve --token-file`); `calibrate --out` never over the built-in vehicle's
//! source directory, however it is spelled.

use std::path::{Path, PathBuf};
use std::time::Duration;

use emplan::flightlog::flight_plan::{FlightPlan, ORIGIN_NAME};
use emplan::flightlog::recorder::{Recorder, TLOG_FILE};
use emplan::flightlog::report::{FlightReport, ReportJson};
use emplan::flightlog::segment::{SegmentConfig, SegmentKind, Segmenter};
use emplan::flightlog::synthetic::{SyntheticConfig, SyntheticFlight};
use emplan::flightlog::tlog::read_tlog;
use emplan::link::telemetry::Telemetry;
use emplan::mission::Mission;
use emplan::service::wire::{Failure, UploadAnswer};
use serde_json::{json, Value};

use super::flightlog::frames;
use super::service::{builtin, connected, planned, root, serve, serve_after, upload};
use crate::emplan;

const MISSION: &str = "missions/paper-sample-8wp.toml";

fn mission() -> Mission {
    emplan::mission::load(&root().join(MISSION)).expect("mission")
}

/// The plan of the 8-waypoint mission visiting its waypoints `order` (PX4 numbering), resuming
/// the flight `resumes`.
fn plan_of(order: &[usize], resumes: Option<&str>) -> FlightPlan {
    let mut plan = FlightPlan::for_mission(&mission(), order, 0, None).expect("plan");
    plan.resumes = resumes.map(str::to_string);
    plan
}

/// A flight of `plan` recorded in a new flight directory under `log_dir` from `start_wall_us`,
/// its recording cut off halfway along leg `cut_leg` (the leg to the plan's point of that
/// index: the points before it visited); with its report.json as the live recorder writes it
/// when `with_report`. Returns the directory and the whole flight scripted.
fn flight_cut(
    log_dir: &Path,
    plan: &FlightPlan,
    cut_leg: usize,
    start_wall_us: u64,
    with_report: bool,
) -> (PathBuf, SyntheticFlight) {
    let cfg = SyntheticConfig {
        start_wall_us,
        ..SyntheticConfig::default()
    };
    let flight = SyntheticFlight::fly(plan, &cfg);
    let leg = flight
        .part(SegmentKind::Leg(cut_leg))
        .expect("the leg is flown");
    let t_cut_s = 0.5 * (leg.start_s + leg.end_s);
    let cut_wall_us = (flight.messages.iter())
        .find(|m| m.t_s >= t_cut_s)
        .expect("a message after the cut")
        .wall_us;
    let mut recorder = Recorder::create(log_dir, &plan.mission, start_wall_us).expect("created");
    recorder.write_plan(plan).expect("plan written");
    let mut telemetry = Telemetry::new();
    let mut live = Segmenter::new(plan.clone(), SegmentConfig::default()).expect("valid plan");
    for (wall_us, frame) in frames(&flight).iter().filter(|(w, _)| *w < cut_wall_us) {
        let stamped = telemetry.frame(*wall_us, frame);
        if let Some(s) = &stamped {
            live.push(s);
        }
        recorder
            .record(*wall_us, frame, stamped.as_ref())
            .expect("recorded");
    }
    let dir = recorder.close().expect("closed");
    if with_report {
        live.finish();
        let name = emplan::flightlog::recorder::flight_name(&dir);
        let report = FlightReport::build(&name, &live);
        emplan::flightlog::recorder::write_report(&dir, &report).expect("report written");
    }
    (dir, flight)
}

/// The waypoints a plan flies, in order (the return to the origin left out).
fn flown(plan: &FlightPlan) -> Vec<String> {
    (plan.points.iter())
        .filter(|p| p.name != ORIGIN_NAME)
        .map(|p| p.name.clone())
        .collect()
}

/// The waypoints a report.json counts as visited (arrived, hover not cut short).
fn visited(report: &ReportJson) -> Vec<String> {
    let report = FlightReport::from_json(report);
    (report.at_points().iter())
        .filter(|p| {
            !p.flags
                .contains(&emplan::flightlog::energy::Flag::Incomplete)
        })
        .map(|p| p.to.clone())
        .filter(|n| n != ORIGIN_NAME)
        .collect()
}

fn read_report(dir: &Path) -> ReportJson {
    let text = std::fs::read_to_string(dir.join("report.json")).expect("report.json");
    serde_json::from_str(&text).expect("a report")
}

/// `fly MISSION --resume DIR --log-dir LOG_DIR` on the built-in mock at 50x: its stderr and the
/// new flight's plan.json.
fn fly_resuming(dir: &Path, log_dir: &Path) -> (String, FlightPlan) {
    let (ok, stdout, stderr) = emplan(&[
        "fly",
        MISSION,
        "--resume",
        dir.to_str().unwrap(),
        "--log-dir",
        log_dir.to_str().unwrap(),
        "--json",
        "--speedup",
        "50",
    ]);
    assert!(ok, "fly --resume failed: {stderr}");
    let doc: Value = serde_json::from_str(&stdout).expect("JSON");
    let new = PathBuf::from(doc["log_dir"].as_str().expect("log_dir"));
    let plan = FlightPlan::read_json(&new.join("plan.json")).expect("plan.json");
    (stderr, plan)
}

#[test]
fn fly_resume_of_a_flight_resumed_already_flies_only_what_no_flight_of_the_chain_visited() {
    let work = tempfile::tempdir().unwrap();
    let log_dir = work.path().join("flights");
    let start_us = 1_750_000_000_000_000;
    // The first flight visits A, B and C; the second, resuming it, D and E.
    let (first, _) = flight_cut(
        &log_dir,
        &plan_of(&[0, 1, 2, 3, 4, 5, 6, 7], None),
        3,
        start_us,
        false,
    );
    let first_name = emplan::flightlog::recorder::flight_name(&first);
    let second_plan = plan_of(&[3, 4, 5, 6, 7], Some(&first_name));
    let (second, _) = flight_cut(&log_dir, &second_plan, 2, start_us + 3_600_000_000, false);
    let second_name = emplan::flightlog::recorder::flight_name(&second);

    // Resuming the first flight again flies only F, G and H, and resumes the second.
    let (stderr, third) = fly_resuming(&first, &log_dir);
    let mut left = flown(&third);
    left.sort();
    assert_eq!(left, ["F", "G", "H"], "{stderr}");
    assert_eq!(third.resumes.as_deref(), Some(second_name.as_str()));
    assert!(
        stderr.contains(&format!("resumed since by {second_name} (visited D, E)")),
        "{stderr}"
    );
}

#[test]
fn fly_resume_of_a_flight_whose_log_is_torn_says_so_and_does_not_refly_what_its_report_lists() {
    let work = tempfile::tempdir().unwrap();
    let log_dir = work.path().join("flights");
    let plan = plan_of(&[0, 1, 2, 3, 4, 5, 6, 7], None);
    // Recorded to halfway along the leg to D, its report written: A, B and C visited.
    let (dir, flight) = flight_cut(&log_dir, &plan, 3, 1_750_000_000_000_000, true);
    assert_eq!(visited(&read_report(&dir)), ["A", "B", "C"]);
    // The log torn inside a record halfway along the leg to B: it shows A visited only.
    let leg = flight.part(SegmentKind::Leg(1)).expect("flown");
    let t_tear_s = 0.5 * (leg.start_s + leg.end_s);
    let tear_wall_us = (flight.messages.iter())
        .find(|m| m.t_s >= t_tear_s)
        .expect("a message there")
        .wall_us;
    let tlog = dir.join(TLOG_FILE);
    let records = read_tlog(&tlog).expect("reads").records;
    let record = (records.iter())
        .find(|r| r.wall_us >= tear_wall_us)
        .expect("a record there");
    let torn_at = record.offset;
    let bytes = std::fs::read(&tlog).expect("read");
    std::fs::write(&tlog, &bytes[..torn_at as usize + 5]).expect("torn");

    let (stderr, resumed) = fly_resuming(&dir, &work.path().join("resumed"));
    let mut left = flown(&resumed);
    left.sort();
    assert_eq!(left, ["D", "E", "F", "G", "H"], "{stderr}");
    assert!(
        stderr.contains(&format!("{} is torn at byte {torn_at}", tlog.display()))
            && stderr.contains("lists B, C as visited, which the log no longer shows"),
        "{stderr}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flight_the_service_stopped_recording_is_measured_from_its_log_when_it_starts_again() {
    let mut cut = PathBuf::new();
    let running = serve_after(builtin(20.0), &["paper-sample-8wp.toml"], |log_dir| {
        let plan = plan_of(&[0, 1, 2, 3, 4, 5, 6, 7], None);
        cut = flight_cut(log_dir, &plan, 3, 1_750_000_000_000_000, false).0;
        assert!(!cut.join("report.json").exists());
    })
    .await;
    let name = emplan::flightlog::recorder::flight_name(&cut);
    let answer = (running.client)
        .get(&format!("/api/flights/{name}/report"))
        .await
        .expect("GET");
    assert_eq!(answer.status, 200, "{:?}", answer.body);
    let report: ReportJson = serde_json::from_value(answer.body).expect("a report");
    assert_eq!(report.flight, name);
    assert!(!report.complete);
    assert_eq!(visited(&report), ["A", "B", "C"]);
    assert_eq!(read_report(&cut).flight, name);
    running.shutdown().await.expect("stopped");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_uploads_at_once_are_never_both_verified_the_second_is_refused_409() {
    let running = serve(builtin(20.0), &["paper-sample-8wp.toml"]).await;
    let client = &running.client;
    connected(client).await;
    planned(client, "paper-sample-8wp.toml").await;
    // A slow plan (the heuristic for its whole time limit) and a fast one, asked together.
    let slow = json!({"solver": "heuristic", "kicks": 1_000_000_000_000u64, "time_limit_s": 3});
    let (a, b) = tokio::join!(
        upload(client, "paper-sample-8wp.toml", slow),
        upload(client, "paper-sample-8wp.toml", json!({})),
    );
    let (answered, refused) = match (a.ok(), b.ok()) {
        (true, false) => (a, b),
        (false, true) => (b, a),
        _ => panic!("one answered and one refused: {a:?} {b:?}"),
    };
    let verified: UploadAnswer = serde_json::from_value(answered.body).expect("an upload answer");
    assert!(!verified.upload.items.is_empty());
    assert_eq!(refused.status, 409);
    let failure: Failure = serde_json::from_value(refused.body).expect("a failure");
    assert!(!failure.ok && failure.stage == "vehicle");
    assert!(
        failure
            .error
            .contains("the upload of paper-sample-8wp.toml is under way"),
        "{}",
        failure.error
    );
    // Once answered, the next upload is taken.
    let again = upload(client, "paper-sample-8wp.toml", json!({})).await;
    assert!(again.ok(), "{again:?}");
    running.shutdown().await.expect("stopped");
}

/// A directory that looks like a flight directory (it holds a flight.tlog).
fn fake_flight(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join(TLOG_FILE), b"").unwrap();
    dir.to_path_buf()
}

#[test]
fn fly_refuses_a_log_dir_that_is_or_lies_inside_a_flight_directory() {
    let work = tempfile::tempdir().unwrap();
    let flight = fake_flight(&work.path().join("flights/20250101-000000-m"));
    for log_dir in [flight.clone(), flight.join("more/flights")] {
        let (ok, stdout, stderr) = emplan(&[
            "fly",
            "missions/paper-sample-3wp.toml",
            "--log-dir",
            log_dir.to_str().unwrap(),
            "--speedup",
            "50",
        ]);
        assert!(!ok && stdout.is_empty(), "{stdout}{stderr}");
        assert!(
            stderr.contains(&format!(
                "it is inside the flight directory {}",
                flight.canonicalize().unwrap().display()
            )),
            "{stderr}"
        );
        let entries: Vec<_> = std::fs::read_dir(&flight).unwrap().collect();
        assert_eq!(entries.len(), 1, "nothing but its flight.tlog");
    }
}

#[test]
fn serve_refuses_a_token_file_inside_a_flight_directory() {
    let work = tempfile::tempdir().unwrap();
    let flight = fake_flight(&work.path().join("flights/20250101-000000-m"));
    let missions = work.path().join("missions");
    std::fs::create_dir_all(&missions).unwrap();
    let token = flight.join("token");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_emplan"))
        .args(["serve", "--missions", missions.to_str().unwrap()])
        .args(["--log-dir", work.path().join("log").to_str().unwrap()])
        .args([
            "--http",
            "127.0.0.1:0",
            "--token-file",
            token.to_str().unwrap(),
        ])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("emplan serve runs");
    // A hang guard: a service that started serving is killed and fails the test.
    let mut waited = Duration::ZERO;
    let status = loop {
        if let Some(status) = child.try_wait().expect("waited") {
            break status;
        }
        if waited > Duration::from_secs(30) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("serve started with its token file inside a flight directory");
        }
        std::thread::sleep(Duration::from_millis(50));
        waited += Duration::from_millis(50);
    };
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    assert!(!status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "--token-file {}: inside the flight directory",
            token.display()
        )),
        "{stderr}"
    );
    assert!(!token.exists());
}

#[test]
fn calibrate_out_never_writes_over_the_built_in_vehicles_source_directory_even_forced() {
    // Run from a copy of the repository's vehicle directory, so nothing of the repository is at
    // stake.
    let work = tempfile::tempdir().unwrap();
    let source = work.path().join("models/s1000");
    std::fs::create_dir_all(&source).unwrap();
    let original = std::fs::read(root().join("models/s1000/vehicle.toml")).unwrap();
    std::fs::write(source.join("vehicle.toml"), &original).unwrap();
    let flight = fake_flight(&work.path().join("flights/20250101-000000-m"));
    for out in ["models/s1000", "./models/../models/s1000/", "models//s1000"] {
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_emplan"))
            .args(["calibrate", "--from-logs", flight.to_str().unwrap()])
            .args(["--out", out, "--force", "--tables", "none"])
            .env_remove("EMPLAN_VEHICLE")
            .current_dir(work.path())
            .output()
            .expect("emplan runs");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{stderr}");
        assert!(
            stderr.contains("refusing to write over the input"),
            "--out {out}: {stderr}"
        );
        assert_eq!(
            std::fs::read(source.join("vehicle.toml")).unwrap(),
            original
        );
    }
}
