//! The flight log end to end: a scripted flight as MAVLink frames through the telemetry edge, the
//! recorder and a replay of what it wrote; the recorder killed with SIGKILL mid-flight (a child
//! process: this test binary run again on one test); the flight directory left in the target
//! directory for the pymavlink check (`sitl/tlog_check.sh`).

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use emplan::flightlog::csv::read_samples;
use emplan::flightlog::energy::Flag;
use emplan::flightlog::recorder::{Recorder, SAMPLES_FILE, TLOG_FILE};
use emplan::flightlog::report::FlightReport;
use emplan::flightlog::segment::{SegmentConfig, SegmentKind, Segmenter};
use emplan::flightlog::synthetic::{square_plan, SyntheticConfig, SyntheticFlight};
use emplan::flightlog::tlog::read_tlog;
use emplan::link::mav::MavMessage;
use emplan::link::telemetry::{
    analyse_flight_dir, encode, frame_bytes, parse_frame, StreamConfig, StreamRequests, Telemetry,
};
use emplan::link::Flavour;
use mavlink::MavHeader;

fn now_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_micros() as u64)
}

/// The frames of a synthetic flight, as PX4 would send them, with the ground station's own
/// traffic (heartbeat once a second, the stream-rate requests) in between: (wall us, frame).
pub(crate) fn frames(flight: &SyntheticFlight) -> Vec<(u64, Vec<u8>)> {
    let vehicle = |sequence: u8| MavHeader {
        system_id: 1,
        component_id: 1,
        sequence,
    };
    let gcs = MavHeader {
        system_id: 255,
        component_id: 190,
        sequence: 0,
    };
    let mut requests = StreamRequests::new(
        StreamConfig::default(),
        emplan::link::telemetry::default_streams(),
    );
    let mut out = Vec::new();
    for m in requests.start(Duration::ZERO) {
        out.push((flight.messages[0].wall_us, frame_bytes(&gcs, &m)));
    }
    let mut next_heartbeat = 0.0;
    for (k, m) in flight.messages.iter().enumerate() {
        if m.t_s >= next_heartbeat {
            let hb = MavMessage::HEARTBEAT(emplan::link::mav::HEARTBEAT_DATA {
                mavtype: emplan::link::mav::MavType::MAV_TYPE_GCS,
                autopilot: emplan::link::mav::MavAutopilot::MAV_AUTOPILOT_INVALID,
                ..Default::default()
            });
            out.push((m.wall_us, frame_bytes(&gcs, &hb)));
            next_heartbeat += 1.0;
        }
        let message = encode(&m.reading, Flavour::Px4);
        out.push((m.wall_us, frame_bytes(&vehicle(k as u8), &message)));
    }
    out
}

fn is_battery_status(frame: &[u8]) -> bool {
    matches!(parse_frame(frame), Ok((_, MavMessage::BATTERY_STATUS(_))))
}

/// The directory the integration test binary was built in (target/).
fn target_dir() -> PathBuf {
    std::env::current_exe()
        .ok()
        .and_then(|exe| exe.ancestors().nth(3).map(Path::to_path_buf))
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target"))
}

fn only_subdir(dir: &Path) -> PathBuf {
    let dirs: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("log dir readable")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .collect();
    assert_eq!(dirs.len(), 1, "one flight directory in {dir:?}: {dirs:?}");
    dirs[0].clone()
}

#[test]
fn a_flight_recorded_from_frames_at_ten_times_real_time_replays_to_the_live_report() {
    let plan = square_plan();
    let cfg = SyntheticConfig {
        speedup: 10.0,
        ..SyntheticConfig::default()
    };
    let flight = SyntheticFlight::fly(&plan, &cfg);
    let log_dir = target_dir().join("flightlog-sample");
    let _ = std::fs::remove_dir_all(&log_dir);
    let mut recorder =
        Recorder::create(&log_dir, &plan.mission, cfg.start_wall_us).expect("created");
    recorder.write_plan(&plan).expect("plan written");
    let mut telemetry = Telemetry::new();
    let mut live = Segmenter::new(plan.clone(), SegmentConfig::default()).expect("valid plan");
    let all = frames(&flight);
    for (wall_us, frame) in &all {
        let stamped = telemetry.frame(*wall_us, frame);
        if let Some(s) = &stamped {
            live.push(s);
        }
        recorder
            .record(*wall_us, frame, stamped.as_ref())
            .expect("recorded");
    }
    live.finish();
    let dir = recorder.close().expect("closed");
    assert!(
        (telemetry.clock().rate() - 10.0).abs() < 0.1,
        "rate {}",
        telemetry.clock().rate()
    );

    // The files: every frame in the .tlog, one CSV row per BATTERY_STATUS.
    let tlog = read_tlog(&dir.join(TLOG_FILE)).expect("tlog reads");
    assert_eq!(tlog.records.len(), all.len());
    assert_eq!(tlog.torn_tail, None);
    let batteries = tlog
        .records
        .iter()
        .filter(|r| is_battery_status(&r.frame))
        .count();
    let rows = read_samples(&dir.join(SAMPLES_FILE)).expect("csv reads");
    assert_eq!(rows.len(), batteries);
    assert!(rows
        .iter()
        .any(|r| r.armed == Some(true) && r.mission_seq == Some(2)));

    // The replay gives the live run's report, and it is the truth of the scripted flight.
    let analysis = analyse_flight_dir(&dir, SegmentConfig::default()).expect("replays");
    let live_report = FlightReport::build(&analysis.report.flight, &live);
    assert_eq!(
        serde_json::to_value(analysis.report.json()).expect("json"),
        serde_json::to_value(live_report.json()).expect("json")
    );
    let report = analysis.report;
    assert!(report.complete, "{:?}", report.flags);
    assert_eq!(report.legs.len(), plan.points.len());
    for (k, leg) in report.legs.iter().enumerate() {
        let truth = flight.part(SegmentKind::Leg(k)).expect("true leg");
        let measured = leg.measured_j.expect("measured");
        // The battery is stamped by the clock from wall time at 10x: a few ms of jitter.
        assert!(
            (measured - truth.energy_j()).abs() < 0.01 * truth.energy_j(),
            "leg {k}: {measured} J vs {} J",
            truth.energy_j()
        );
        assert!(leg.flags.is_empty(), "leg {k}: {:?}", leg.flags);
    }
    let total = report.measured_j.expect("measured");
    assert!((total - flight.total_j()).abs() < 0.005 * flight.total_j());
    assert_eq!(analysis.replay.undecodable, 0);
    // Written beside the other files for `sitl/tlog_check.sh` (pymavlink must count as many
    // BATTERY_STATUS as there are rows).
    emplan::flightlog::recorder::write_report(&dir, &report).expect("report written");
}

const CHILD: &str = "EMPLAN_TEST_RECORDER_CHILD";
const KILL_TEST: &str =
    "flightlog::the_recorder_killed_mid_flight_leaves_a_log_readable_to_the_last_second";

#[cfg(unix)]
/// The child's side: flies the scripted flight in real time (20x) into a recorder under `dir`,
/// writing the wall time of each frame recorded to `dir/progress` after recording it, until
/// killed.
fn record_until_killed(dir: &Path) -> ! {
    use std::os::unix::fs::FileExt;
    let plan = square_plan();
    let cfg = SyntheticConfig {
        speedup: 20.0,
        start_wall_us: now_us(),
        ..SyntheticConfig::default()
    };
    let flight = SyntheticFlight::fly(&plan, &cfg);
    let progress = std::fs::File::create(dir.join("progress")).expect("progress file");
    let mut recorder =
        Recorder::create(&dir.join("log"), &plan.mission, cfg.start_wall_us).expect("recorder");
    recorder.write_plan(&plan).expect("plan");
    let mut telemetry = Telemetry::new();
    for (wall_us, frame) in frames(&flight) {
        let now = now_us();
        if wall_us > now {
            std::thread::sleep(Duration::from_micros(wall_us - now));
        }
        let wall = now_us();
        let stamped = telemetry.frame(wall, &frame);
        recorder
            .record(wall, &frame, stamped.as_ref())
            .expect("recorded");
        progress.write_at(&wall.to_le_bytes(), 0).expect("progress");
    }
    loop {
        std::thread::sleep(Duration::from_secs(1));
    }
}

#[cfg(unix)]
#[test]
fn the_recorder_killed_mid_flight_leaves_a_log_readable_to_the_last_second() {
    if let Some(dir) = std::env::var_os(CHILD) {
        record_until_killed(Path::new(&dir));
    }
    let work = tempfile::tempdir().expect("temp dir");
    let mut child = std::process::Command::new(std::env::current_exe().expect("test binary"))
        .args([KILL_TEST, "--exact", "--nocapture", "--test-threads=1"])
        .env(CHILD, work.path())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("child runs");
    // Kill it once the samples show the vehicle 2 s into its second leg (reading the files while
    // they are written: the readers skip the torn tail).
    let truth = SyntheticFlight::fly(&square_plan(), &SyntheticConfig::default());
    let leg1 = truth.part(SegmentKind::Leg(1)).copied().expect("leg 1");
    let waited = std::time::Instant::now();
    loop {
        let flown = std::fs::read_dir(work.path().join("log"))
            .ok()
            .and_then(|mut d| d.next())
            .and_then(|e| e.ok())
            .and_then(|e| read_samples(&e.path().join(SAMPLES_FILE)).ok())
            .and_then(|rows| rows.last().map(|r| r.sample.t_s))
            .unwrap_or(0.0);
        if flown > leg1.start_s + 2.0 {
            // The files were just flushed; kill between two flushes, not right after one.
            std::thread::sleep(Duration::from_millis(300));
            break;
        }
        assert!(
            waited.elapsed() < Duration::from_secs(60),
            "the child never got there"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().expect("SIGKILL");
    child.wait().expect("reaped");

    let dir = only_subdir(&work.path().join("log"));
    let bytes = std::fs::read(work.path().join("progress")).expect("progress");
    let last_recorded = u64::from_le_bytes(bytes[..8].try_into().expect("8 bytes"));
    let tlog = read_tlog(&dir.join(TLOG_FILE)).expect("the tlog reads after SIGKILL");
    let last_on_disk = tlog.records.last().expect("records").wall_us;
    // Buffers go to the OS every 0.5 s of wall time (the record that crosses it included), so a
    // killed process loses less than the last half second.
    assert!(
        last_recorded.saturating_sub(last_on_disk) < 500_000,
        "lost {} us",
        last_recorded - last_on_disk
    );
    let rows = read_samples(&dir.join(SAMPLES_FILE)).expect("the csv reads after SIGKILL");
    let batteries = tlog
        .records
        .iter()
        .filter(|r| is_battery_status(&r.frame))
        .count();
    assert!(
        rows.len() <= batteries && rows.len() + 20 >= batteries,
        "{} rows, {batteries} BATTERY_STATUS",
        rows.len()
    );

    let analysis = analyse_flight_dir(&dir, SegmentConfig::default()).expect("replays");
    let report = analysis.report;
    assert!(!report.complete && report.flags.contains(&Flag::Incomplete));
    assert!(report.landing.is_none());
    let leg0 = &report.legs[0];
    assert!(!leg0.flags.contains(&Flag::Incomplete), "{:?}", leg0.flags);
    let truth0 = truth.part(SegmentKind::Leg(0)).expect("leg 0");
    let measured = leg0.measured_j.expect("measured");
    assert!(
        (measured - truth0.energy_j()).abs() < 0.03 * truth0.energy_j(),
        "{measured}"
    );
    // Exactly one part is cut off: the last one flown.
    let mut parts: Vec<_> = report.parts().collect();
    parts.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
    let cut: Vec<bool> = parts
        .iter()
        .map(|p| p.flags.contains(&Flag::Incomplete))
        .collect();
    assert_eq!(cut.iter().filter(|&&c| c).count(), 1, "{cut:?}");
    assert_eq!(cut.last(), Some(&true));
}
