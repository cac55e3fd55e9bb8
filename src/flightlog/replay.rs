//! The replay of a recorded flight without MAVLink: a .tlog's records read in order (a torn tail
//! ends it quietly, a corrupt span is skipped and kept as a gap with the vehicle times either
//! side of it), each record turned into a reading by the decoder the caller passes
//! (`link::telemetry` decodes MAVLink), and the readings measured against the flight's plan.
//! A flight directory's recording (its plan.json and flight.tlog) is found here too.

use std::io::Read;
use std::path::{Path, PathBuf};

use super::flight_plan::FlightPlan;
use super::recorder::{flight_name, TLOG_FILE};
use super::report::FlightReport;
use super::segment::{SegmentConfig, Segmenter};
use super::telemetry::Stamped;
use super::tlog::{TlogGap, TlogReader};
use super::FlightLogError;

/// A .tlog replayed through a decoder (live: `link::telemetry::Telemetry`).
#[derive(Debug, Clone, Default)]
pub struct Replay {
    pub stamped: Vec<Stamped>,
    /// Records in the file.
    pub frames: u64,
    /// Frames that were not a known MAVLink message.
    pub undecodable: u64,
    /// Offset of a torn last record, skipped.
    pub torn_tail: Option<u64>,
    /// Spans of the file that were not records (corrupt), skipped: the replay went on from the
    /// next frame that checks. Their vehicle times are those of the readings either side.
    pub gaps: Vec<TlogGap>,
}

/// Replays `reader` from the start through `decode` (a record's wall time, unix microseconds,
/// and its frame to a stamped reading, or nothing): every stamped reading, in order, as the live
/// run made them, with the reader's gaps and torn tail. `undecodable` is the decoder's to fill.
pub fn replay<R: Read>(
    mut reader: TlogReader<R>,
    mut decode: impl FnMut(u64, &[u8]) -> Option<Stamped>,
) -> Result<Replay, FlightLogError> {
    let mut replay = Replay::default();
    // Gaps whose vehicle time after them is not known yet.
    let mut open_from = 0;
    while let Some(record) = reader.next() {
        let record = record?;
        replay.frames += 1;
        let before_s = replay.stamped.last().map(|s| s.t_s);
        for gap in &reader.gaps()[replay.gaps.len()..] {
            replay.gaps.push(TlogGap {
                from_s: before_s,
                ..gap.clone()
            });
        }
        if let Some(s) = decode(record.wall_us, &record.frame) {
            for gap in &mut replay.gaps[open_from..] {
                gap.to_s = Some(s.t_s);
            }
            open_from = replay.gaps.len();
            replay.stamped.push(s);
        }
    }
    let before_s = replay.stamped.last().map(|s| s.t_s);
    for gap in &reader.gaps()[replay.gaps.len()..] {
        replay.gaps.push(TlogGap {
            from_s: before_s,
            ..gap.clone()
        });
    }
    replay.torn_tail = reader.torn_tail();
    Ok(replay)
}

/// A recorded flight replayed and measured against its plan.
#[derive(Debug, Clone)]
pub struct Analysis {
    pub report: FlightReport,
    /// The segments and the battery series (for plots and live views).
    pub segmenter: Segmenter,
    pub replay: Replay,
}

/// Measures a replayed flight against `plan` and reports it as flight `name`: the replay's
/// gaps are the segmenter's log gaps and the report's.
pub fn analyse(
    replay: Replay,
    plan: FlightPlan,
    name: &str,
    cfg: SegmentConfig,
) -> Result<Analysis, FlightLogError> {
    let mut segmenter = Segmenter::run(plan, cfg, &replay.stamped)?;
    for gap in &replay.gaps {
        segmenter.log_gap(
            gap.from_s.unwrap_or(f64::NEG_INFINITY),
            gap.to_s.unwrap_or(f64::INFINITY),
        );
    }
    let mut report = FlightReport::build(name, &segmenter);
    report.log_gaps = replay.gaps.clone();
    Ok(Analysis {
        report,
        segmenter,
        replay,
    })
}

/// A flight directory's recording: the plan it was flown against, its .tlog and its name.
#[derive(Debug, Clone)]
pub struct FlightDir {
    pub plan: FlightPlan,
    pub tlog: PathBuf,
    pub name: String,
}

impl FlightDir {
    /// Reads `dir`'s plan.json; the flight is named by the directory.
    pub fn read(dir: &Path) -> Result<FlightDir, FlightLogError> {
        Ok(FlightDir {
            plan: super::recorder::read_flight_plan(dir)?,
            tlog: dir.join(TLOG_FILE),
            name: flight_name(dir),
        })
    }
}
