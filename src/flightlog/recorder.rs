//! The flight directory, written as the flight happens:
//! `LOG_DIR/<YYYYmmdd-HHMMSS>-<mission>/` (UTC start time; `-2`, `-3`, ... when two flights start
//! in the same second) holding
//! - `flight.tlog`: every frame, both directions, as QGroundControl and MAVProxy write it;
//! - `samples.csv`: one row per battery sample with the vehicle state (see [`super::csv`]);
//! - `plan.json`: the [`FlightPlan`], written at the start;
//! - `repriced.jsonl`: with `fly --wind live`, the rest of the flight priced again in the wind
//!   the vehicle estimated, a line each time (absent otherwise);
//! - `report.json`: the report, written when the flight ends (a replay can always rebuild it).
//!
//! Append-only. Buffers go to the operating system at least every `flush_every_us` (0.5 s) and
//! to disk (fsync) at least every `sync_every_us` (1 s) of wall time, and all of them together
//! whenever one is full, so a crash of emplan loses
//! at most the last half second and a power cut the last second, and every file stays readable
//! (the readers skip a torn last record or line). Time is the caller's: `record` flushes on the
//! frames' own wall times, `tick` when the link is quiet; the async task that owns the recorder
//! calls `tick` a few times a second.

use std::path::{Path, PathBuf};

use super::csv::{SampleRow, SamplesWriter};
use super::flight_plan::FlightPlan;
use super::report::FlightReport;
use super::samples::{BatteryFeed, FeedConfig};
use super::telemetry::{Reading, Stamped, VehicleState};
use super::tlog::{Tlog, TlogWriter};
use super::FlightLogError;

/// The files of a flight directory.
pub const TLOG_FILE: &str = "flight.tlog";
pub const SAMPLES_FILE: &str = "samples.csv";
pub const PLAN_FILE: &str = "plan.json";
pub const REPORT_FILE: &str = "report.json";
/// The rest of the flight priced again in a wind heard in flight (`fly --wind live`), a JSON
/// line each ([`super::flight_plan::Repricing`]), appended as they are made.
pub const REPRICED_FILE: &str = "repriced.jsonl";

/// Whether `dir` is a flight directory: the recorder creates its `flight.tlog` first, and
/// `report`, the service and `session::flight_dirs` know a flight by it.
pub fn is_flight_dir(dir: &Path) -> bool {
    dir.join(TLOG_FILE).is_file()
}

/// The flight directory that `path` is or lies inside, if any: the nearest of `path` and the
/// directories above it that exists, symlinks resolved, then each directory above that. A
/// path that does not exist yet (a file or directory about to be written) is judged by where
/// it would be made. Nothing but a flight's own files is ever written in one.
pub fn flight_dir_holding(path: &Path) -> Option<PathBuf> {
    let existing = path
        .ancestors()
        .map(|p| {
            if p.as_os_str().is_empty() {
                Path::new(".")
            } else {
                p
            }
        })
        .find_map(|p| p.canonicalize().ok())?;
    existing
        .ancestors()
        .find(|d| is_flight_dir(d))
        .map(Path::to_path_buf)
}

/// When the recorder hands data to the OS and to the disk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecorderConfig {
    pub flush_every_us: u64,
    pub sync_every_us: u64,
    pub feed: FeedConfig,
}

impl Default for RecorderConfig {
    fn default() -> Self {
        RecorderConfig {
            flush_every_us: 500_000,
            sync_every_us: 1_000_000,
            feed: FeedConfig::default(),
        }
    }
}

/// Days since 1970-01-01 to (year, month, day), proleptic Gregorian (H. Hinnant,
/// "chrono-Compatible Low-Level Date Algorithms", `civil_from_days`).
fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

/// `YYYYmmdd-HHMMSS` (UTC) of a unix time in microseconds.
pub fn timestamp_name(wall_us: u64) -> String {
    let secs = i64::try_from(wall_us / 1_000_000).unwrap_or(i64::MAX);
    let (y, m, d) = civil_from_days(secs.div_euclid(86_400));
    let s = secs.rem_euclid(86_400);
    format!(
        "{y:04}{m:02}{d:02}-{:02}{:02}{:02}",
        s / 3600,
        (s / 60) % 60,
        s % 60
    )
}

/// A mission name made safe for a directory name.
fn safe_name(mission: &str) -> String {
    let name: String = mission
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .take(64)
        .collect();
    let name = name.trim_matches('.').to_string();
    if name.is_empty() {
        "flight".to_string()
    } else {
        name
    }
}

fn sync_dir(dir: &Path) {
    // Best effort: makes the new entries survive a power cut where the platform allows it.
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
}

/// Proves that flight directories can be made in `log_dir` before anything is flown: refuses a
/// flight directory or a directory inside one ([`flight_dir_holding`]), creates it (and its
/// parents) when missing, then creates, writes, syncs and removes a probe file in it.
/// A directory that cannot be written (an existing file, a path under a file, a read-only
/// filesystem, no permission, no space) is an error naming the path and the system's reason.
pub fn check_log_dir(log_dir: &Path) -> Result<(), FlightLogError> {
    let refused = |reason: String| FlightLogError::LogDir {
        dir: log_dir.display().to_string(),
        reason,
    };
    if log_dir.exists() && !log_dir.is_dir() {
        return Err(refused("exists and is not a directory".into()));
    }
    if let Some(flight) = flight_dir_holding(log_dir) {
        return Err(refused(format!(
            "it is inside the flight directory {}: flights are recorded beside one another, \
             never inside one (give the directory that holds the flights)",
            flight.display()
        )));
    }
    std::fs::create_dir_all(log_dir).map_err(|e| refused(format!("cannot create it: {e}")))?;
    let probe = log_dir.join(format!(".emplan-write-check-{}", std::process::id()));
    let written = std::fs::File::create(&probe).and_then(|mut file| {
        use std::io::Write;
        file.write_all(b"emplan checks it can write here\n")?;
        file.sync_all()
    });
    let removed = std::fs::remove_file(&probe);
    written.map_err(|e| refused(format!("cannot write {}: {e}", probe.display())))?;
    removed.map_err(|e| refused(format!("cannot remove {}: {e}", probe.display())))
}

/// Records one flight.
#[derive(Debug)]
pub struct Recorder {
    dir: PathBuf,
    tlog: TlogWriter,
    samples: SamplesWriter,
    state: VehicleState,
    feed: BatteryFeed,
    cfg: RecorderConfig,
    last_flush_us: u64,
    last_sync_us: u64,
}

impl Recorder {
    /// Creates a new flight directory under `log_dir` for `mission`, started at `start_wall_us`
    /// (unix microseconds).
    pub fn create(
        log_dir: &Path,
        mission: &str,
        start_wall_us: u64,
    ) -> Result<Recorder, FlightLogError> {
        Recorder::create_with(log_dir, mission, start_wall_us, RecorderConfig::default())
    }

    pub fn create_with(
        log_dir: &Path,
        mission: &str,
        start_wall_us: u64,
        cfg: RecorderConfig,
    ) -> Result<Recorder, FlightLogError> {
        std::fs::create_dir_all(log_dir).map_err(|source| FlightLogError::Io {
            file: log_dir.display().to_string(),
            source,
        })?;
        let base = format!("{}-{}", timestamp_name(start_wall_us), safe_name(mission));
        let mut dir = log_dir.join(&base);
        let mut n = 1;
        loop {
            match std::fs::create_dir(&dir) {
                Ok(()) => break,
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && n < 1000 => {
                    n += 1;
                    dir = log_dir.join(format!("{base}-{n}"));
                }
                Err(source) => {
                    return Err(FlightLogError::Io {
                        file: dir.display().to_string(),
                        source,
                    })
                }
            }
        }
        let tlog = TlogWriter::create(&dir.join(TLOG_FILE))?;
        let mut samples = SamplesWriter::create(&dir.join(SAMPLES_FILE))?;
        samples.sync()?;
        sync_dir(&dir);
        sync_dir(log_dir);
        Ok(Recorder {
            dir,
            tlog,
            samples,
            state: VehicleState::default(),
            feed: BatteryFeed::new(cfg.feed),
            cfg,
            last_flush_us: start_wall_us,
            last_sync_us: start_wall_us,
        })
    }

    /// Reopens the flight directory `dir` to go on recording a flight whose recording was cut
    /// off (emplan killed mid-flight and restarted): flight.tlog and samples.csv are appended
    /// to after their torn tails are cut off, and a report.json written when the recording
    /// stopped is removed (the flight is not over). Returns the recorder and the frames already
    /// in the log: decode them and hand their readings to [`Recorder::restore`] so that the
    /// vehicle state and the battery feed go on where they were.
    pub fn resume(
        dir: &Path,
        now_wall_us: u64,
        cfg: RecorderConfig,
    ) -> Result<(Recorder, Tlog), FlightLogError> {
        let (tlog, kept) = TlogWriter::resume(&dir.join(TLOG_FILE))?;
        let samples_path = dir.join(SAMPLES_FILE);
        let samples = if samples_path.exists() {
            SamplesWriter::resume(&samples_path)?
        } else {
            SamplesWriter::create(&samples_path)?
        };
        let report = dir.join(REPORT_FILE);
        if report.exists() {
            std::fs::remove_file(&report).map_err(super::io_error(&report))?;
        }
        sync_dir(dir);
        let recorder = Recorder {
            dir: dir.to_path_buf(),
            tlog,
            samples,
            state: VehicleState::default(),
            feed: BatteryFeed::new(cfg.feed),
            cfg,
            last_flush_us: now_wall_us,
            last_sync_us: now_wall_us,
        };
        Ok((recorder, kept))
    }

    /// Takes in a reading already in the log of a resumed flight, without writing anything.
    pub fn restore(&mut self, stamped: &Stamped) {
        self.state.update(&stamped.reading);
        if let Reading::Battery(b) = &stamped.reading {
            let _ = self.feed.push(stamped.t_s, stamped.wall_us, b);
        }
    }

    /// The flight directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Frames and sample rows written so far.
    pub fn counts(&self) -> (u64, u64) {
        (self.tlog.records(), self.samples.rows())
    }

    /// Writes plan.json (complete or absent, never torn), without the repricings made in
    /// flight: those are repriced.jsonl's ([`Self::append_repricing`]).
    pub fn write_plan(&self, plan: &FlightPlan) -> Result<(), FlightLogError> {
        let path = self.dir.join(PLAN_FILE);
        if plan.repricings.is_empty() {
            return plan.write_json(&path);
        }
        FlightPlan {
            repricings: Vec::new(),
            ..plan.clone()
        }
        .write_json(&path)
    }

    /// Appends a repricing of the rest of the flight to repriced.jsonl, on disk before it
    /// returns (a torn last line is skipped by [`read_flight_plan`]).
    pub fn append_repricing(
        &self,
        repricing: &super::flight_plan::Repricing,
    ) -> Result<(), FlightLogError> {
        use std::io::Write;
        let path = self.dir.join(REPRICED_FILE);
        let mut line = serde_json::to_string(repricing).map_err(|e| FlightLogError::Json {
            file: path.display().to_string(),
            reason: e.to_string(),
        })?;
        line.push('\n');
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .map_err(super::io_error(&path))?;
        file.write_all(line.as_bytes())
            .and_then(|()| file.sync_data())
            .map_err(super::io_error(&path))
    }

    /// Records one frame received or sent at `wall_us`, with its reading if it decoded to one.
    pub fn record(
        &mut self,
        wall_us: u64,
        frame: &[u8],
        stamped: Option<&Stamped>,
    ) -> Result<(), FlightLogError> {
        // The files go to the OS together, whatever the clock says: one buffer spilling alone
        // (a recorder backlogged by a slow fsync writes a second of frames at once) would
        // leave the .tlog ahead of samples.csv after a crash.
        if !(self.tlog.has_room(frame.len()) && self.samples.has_room()) {
            self.tlog.flush()?;
            self.samples.flush()?;
        }
        self.tlog.append(wall_us, frame)?;
        if let Some(s) = stamped {
            self.state.update(&s.reading);
            if let Reading::Battery(b) = &s.reading {
                if let Some(sample) = self.feed.push(s.t_s, s.wall_us, b) {
                    self.samples.append(&SampleRow::new(sample, &self.state))?;
                }
            }
        }
        self.tick(wall_us)
    }

    /// Flushes and syncs when their time has come (call it when the link is quiet too).
    pub fn tick(&mut self, wall_us: u64) -> Result<(), FlightLogError> {
        if wall_us.saturating_sub(self.last_sync_us) >= self.cfg.sync_every_us {
            self.tlog.sync()?;
            self.samples.sync()?;
            self.last_sync_us = wall_us;
            self.last_flush_us = wall_us;
        } else if wall_us.saturating_sub(self.last_flush_us) >= self.cfg.flush_every_us {
            self.tlog.flush()?;
            self.samples.flush()?;
            self.last_flush_us = wall_us;
        }
        Ok(())
    }

    /// Puts everything on disk and ends the recording; returns the flight directory.
    pub fn close(mut self) -> Result<PathBuf, FlightLogError> {
        self.tlog.sync()?;
        self.samples.sync()?;
        sync_dir(&self.dir);
        Ok(self.dir)
    }
}

/// The plan of a flight directory: plan.json with the repricings made in flight
/// (repriced.jsonl, when there is one; a torn last line, from a crash while it was written, is
/// skipped). Errors name the file and, for repriced.jsonl, the line.
pub fn read_flight_plan(dir: &Path) -> Result<FlightPlan, FlightLogError> {
    let mut plan = FlightPlan::read_json(&dir.join(PLAN_FILE))?;
    let path = dir.join(REPRICED_FILE);
    if !path.is_file() {
        return Ok(plan);
    }
    let text = std::fs::read_to_string(&path).map_err(super::io_error(&path))?;
    let lines: Vec<&str> = text.split_inclusive('\n').collect();
    plan.repricings.clear();
    for (n, line) in lines.iter().enumerate() {
        let torn = n + 1 == lines.len() && !line.ends_with('\n');
        match serde_json::from_str(line.trim()) {
            Ok(r) => plan.repricings.push(r),
            Err(_) if torn || line.trim().is_empty() => {}
            Err(e) => {
                return Err(FlightLogError::Json {
                    file: format!("{}:{}", path.display(), n + 1),
                    reason: e.to_string(),
                })
            }
        }
    }
    plan.validate().map_err(|e| FlightLogError::Json {
        file: path.display().to_string(),
        reason: e.to_string(),
    })?;
    Ok(plan)
}

/// Writes report.json into a flight directory (complete or absent, never torn).
pub fn write_report(dir: &Path, report: &FlightReport) -> Result<(), FlightLogError> {
    let path = dir.join(REPORT_FILE);
    let text = serde_json::to_string_pretty(&report.json()).map_err(|e| FlightLogError::Json {
        file: path.display().to_string(),
        reason: e.to_string(),
    })?;
    super::write_synced(&path, text.as_bytes())
}

/// Reads report.json of a flight directory.
pub fn read_report(dir: &Path) -> Result<FlightReport, FlightLogError> {
    let path = dir.join(REPORT_FILE);
    let file = path.display().to_string();
    let text = std::fs::read_to_string(&path).map_err(|source| FlightLogError::Io {
        file: file.clone(),
        source,
    })?;
    let json = serde_json::from_str(&text).map_err(|e| FlightLogError::Json {
        file,
        reason: e.to_string(),
    })?;
    Ok(FlightReport::from_json(&json))
}

/// The name of a flight: its directory's name.
pub fn flight_name(dir: &Path) -> String {
    dir.file_name().map_or_else(
        || dir.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::csv::read_samples;
    use crate::flightlog::telemetry::{Battery, BatterySource};
    use crate::flightlog::tlog::read_tlog;

    #[test]
    fn the_repricings_of_a_flight_directory_come_back_with_its_plan_a_torn_last_line_skipped() {
        use crate::flightlog::flight_plan::{PredictedLeg, Repricing};
        let tmp = tempfile::tempdir().unwrap();
        let recorder = Recorder::create(tmp.path(), "square", 1_700_000_000_000_000).unwrap();
        let plan = crate::flightlog::synthetic::square_plan();
        recorder.write_plan(&plan).unwrap();
        let n = plan.points.len();
        let leg = PredictedLeg {
            energy_j: 1.0,
            duration_s: 1.0,
            settle_energy_j: 1.0,
            settle_duration_s: 1.0,
        };
        let r = Repricing {
            t_s: 12.5,
            wind: crate::mission::wind::Wind::new(4.0, 200.0).unwrap(),
            from_point: 1,
            legs: vec![leg; n - 1],
            hover_power_w: 900.0,
            landing_j: 30_000.0,
            home_j: Vec::new(),
            rest_before_j: 1.0,
            rest_after_j: 2.0,
        };
        recorder.append_repricing(&r).unwrap();
        let path = recorder.dir().join(REPRICED_FILE);
        let mut text = std::fs::read_to_string(&path).unwrap();
        text.push_str("{\"t_s\": 20.0, \"wi");
        std::fs::write(&path, &text).unwrap();
        let back = read_flight_plan(recorder.dir()).unwrap();
        assert_eq!(back.repricings, vec![r]);
        // A broken line that is not the last is an error naming the file and line.
        std::fs::write(&path, format!("oops\n{text}")).unwrap();
        let err = read_flight_plan(recorder.dir()).unwrap_err().to_string();
        assert!(err.contains("repriced.jsonl:1"), "{err}");
    }

    #[test]
    fn timestamps_name_directories_in_utc() {
        assert_eq!(timestamp_name(0), "19700101-000000");
        // 2000-02-29 12:34:56 UTC = 951827696 s.
        assert_eq!(timestamp_name(951_827_696_000_000), "20000229-123456");
        // 2026-03-01 00:00:00 UTC = 1772323200 s.
        assert_eq!(timestamp_name(1_772_323_200_999_999), "20260301-000000");
    }

    #[test]
    fn a_flight_directory_is_named_by_start_and_mission_and_never_reused() {
        let log = tempfile::tempdir().expect("temp dir");
        let start = 951_827_696_000_000;
        let a = Recorder::create(log.path(), "paper sample/8wp", start).expect("created");
        let b = Recorder::create(log.path(), "paper sample/8wp", start).expect("created");
        assert_eq!(flight_name(a.dir()), "20000229-123456-paper_sample_8wp");
        assert_eq!(flight_name(b.dir()), "20000229-123456-paper_sample_8wp-2");
        assert!(a.dir().join(TLOG_FILE).is_file() && a.dir().join(SAMPLES_FILE).is_file());
    }

    #[test]
    fn a_log_dir_that_cannot_be_written_is_refused_naming_it_and_a_new_one_is_made() {
        let tmp = tempfile::tempdir().expect("temp dir");
        let file = tmp.path().join("file");
        std::fs::write(&file, "x").expect("written");
        let err = check_log_dir(&file).expect_err("a file").to_string();
        assert!(
            err.contains(&file.display().to_string()) && err.contains("not a directory"),
            "{err}"
        );
        let under = file.join("sub");
        let err = check_log_dir(&under).expect_err("under a file").to_string();
        assert!(
            err.contains(&under.display().to_string()) && err.contains("os error"),
            "{err}"
        );
        let fresh = tmp.path().join("a/b/flights");
        check_log_dir(&fresh).expect("made");
        assert!(fresh.is_dir());
        assert_eq!(
            std::fs::read_dir(&fresh).expect("listed").count(),
            0,
            "no probe left"
        );
    }

    fn battery(t_s: f64) -> Stamped {
        Stamped {
            t_s,
            wall_us: 0,
            reading: Reading::Battery(Battery {
                source: BatterySource::BatteryStatus {
                    id: 0,
                    component: 1,
                },
                voltage_v: Some(22.0),
                current_a: Some(30.0),
                consumed_mah: None,
                energy_consumed_j: None,
                remaining_pct: None,
                fake_current: false,
            }),
        }
    }

    #[test]
    fn a_burst_of_frames_in_the_same_instant_reaches_the_disk_with_its_samples() {
        // A recorder catching up on a backlog records many frames at once, no flush due by the
        // clock: whenever the .tlog's buffer is full, samples.csv goes to the OS with it.
        let log = tempfile::tempdir().expect("temp dir");
        let start = 1_750_000_000_000_000u64;
        let mut r = Recorder::create(log.path(), "m", start).expect("created");
        let dir = r.dir().to_path_buf();
        // A MAVLink 2 frame of 255 payload bytes (the reader checks its framing, not its CRC).
        let mut frame = vec![0xFDu8, 255, 0, 0, 0, 1, 1, 0, 0, 0];
        frame.extend([0u8; 255]);
        frame.extend([0xAA, 0xBB]);
        let mut spilled = 0;
        for k in 0..2_000u64 {
            r.record(start, &frame, Some(&battery(k as f64 * 0.01)))
                .expect("recorded");
            let on_disk = read_tlog(&dir.join(TLOG_FILE)).expect("read").records.len();
            if on_disk > 0 {
                spilled += 1;
                let rows = read_samples(&dir.join(SAMPLES_FILE)).expect("read").len();
                assert!(rows >= on_disk, "{on_disk} frames on disk, {rows} rows");
            }
        }
        assert!(spilled > 0, "the .tlog's buffer never spilled");
    }

    #[test]
    fn what_was_recorded_is_on_disk_within_half_a_second_of_wall_time_without_close() {
        let log = tempfile::tempdir().expect("temp dir");
        let start = 1_750_000_000_000_000u64;
        let mut r = Recorder::create(log.path(), "m", start).expect("created");
        let dir = r.dir().to_path_buf();
        let frame = [0xFDu8, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0xAA, 0xBB];
        // 100 frames over 0.49 s: still buffered.
        for k in 0..100u64 {
            r.record(start + k * 4_900, &frame, Some(&battery(k as f64 * 0.0049)))
                .expect("recorded");
        }
        assert_eq!(
            read_tlog(&dir.join(TLOG_FILE)).expect("read").records.len(),
            0
        );
        // Quiet link: the tick at 0.5 s flushes.
        r.tick(start + 500_000).expect("ticked");
        assert_eq!(
            read_tlog(&dir.join(TLOG_FILE)).expect("read").records.len(),
            100
        );
        assert_eq!(
            read_samples(&dir.join(SAMPLES_FILE)).expect("read").len(),
            100
        );
        r.record(start + 600_000, &frame, None).expect("recorded");
        assert_eq!(r.counts(), (101, 100));
        let dir = r.close().expect("closed");
        assert_eq!(
            read_tlog(&dir.join(TLOG_FILE)).expect("read").records.len(),
            101
        );
    }
}
