//! Flights into the ledger from their files (`emplan ledger rebuild`, `emplan ledger import`):
//! flight directories (`ledger::record::from_dir`) and the flight controller's own logs imported
//! alone (`.ulg`, `.bin`: measured as `emplan report LOG` measures them, `session::onboard`),
//! read and measured in parallel on a pool of threads while one writer puts each record in the
//! ledger as it is ready. A file that cannot be read or measured is named with its reason and
//! the others are still imported.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::flightlog::onboard;
use crate::flightlog::recorder::is_flight_dir;
use crate::flightlog::segment::SegmentConfig;
use crate::ledger::record::FlightInputs;
use crate::ledger::{self, FlightRecord, FlightSource, Ledger, LedgerError, Written};
use crate::logfit::battery::PackSeries;

use super::onboard::{replay_onboard, PlanFrom};

/// What one input is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputKind {
    /// A flight directory (flight.tlog, plan.json, report.json, samples.csv).
    Directory,
    /// A flight controller's own log (PX4 ULog or ArduPilot DataFlash).
    Onboard,
}

/// One flight to import, with the bytes it holds (what progress counts).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Input {
    pub kind: InputKind,
    pub path: PathBuf,
    pub bytes: u64,
}

/// A path that could not be imported, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Failed {
    pub path: PathBuf,
    pub reason: String,
}

/// The inputs found under the paths named, and the paths that named none.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Inputs {
    pub inputs: Vec<Input>,
    pub failed: Vec<Failed>,
}

/// What the import is told beyond the files.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ImportOptions {
    /// Threads measuring files (None: one per core).
    pub jobs: Option<usize>,
    /// The vehicle and pack of flights whose files do not say (an onboard log imported alone
    /// knows neither); a flight that says its own keeps it.
    pub vehicle: Option<String>,
    pub pack: Option<String>,
}

/// What an import did: the records written by what writing them did, and the inputs that
/// failed (in the order they were named).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ImportSummary {
    pub inserted: usize,
    pub unchanged: usize,
    pub replaced: usize,
    pub failed: Vec<Failed>,
}

/// Why an import could not run at all (a single flight's failure is in
/// [`ImportSummary::failed`]).
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    #[error("--jobs {jobs}: {reason}")]
    Pool { jobs: usize, reason: String },
}

/// Bytes of the flight directory's own files (not of directories inside it).
fn dir_bytes(dir: &Path) -> u64 {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok()?.metadata().ok())
                .filter(|m| m.is_file())
                .map(|m| m.len())
                .sum()
        })
        .unwrap_or(0)
}

fn file_bytes(path: &Path) -> u64 {
    std::fs::metadata(path).map_or(0, |m| m.len())
}

/// Whether `path` is named or starts like an onboard log.
fn looks_onboard(path: &Path) -> bool {
    let named = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("ulg") || e.eq_ignore_ascii_case("bin"));
    named || onboard::is_onboard_log(path)
}

/// The flights `paths` name: a flight directory; a file, as an onboard log; a folder, the
/// flight directories directly inside it and (with `logs`) the onboard logs beside them.
/// Without `logs` a file is refused (`ledger rebuild` reads flight directories only). A path
/// naming none is a [`Failed`] of its own.
pub fn inputs(paths: &[PathBuf], logs: bool) -> Inputs {
    let mut found = Inputs::default();
    let fail = |found: &mut Inputs, path: &Path, reason: String| {
        found.failed.push(Failed {
            path: path.to_path_buf(),
            reason,
        })
    };
    for path in paths {
        if is_flight_dir(path) {
            found.inputs.push(Input {
                kind: InputKind::Directory,
                path: path.clone(),
                bytes: dir_bytes(path),
            });
            continue;
        }
        if path.is_file() {
            if logs {
                found.inputs.push(Input {
                    kind: InputKind::Onboard,
                    path: path.clone(),
                    bytes: file_bytes(path),
                });
            } else {
                fail(
                    &mut found,
                    path,
                    "a file, not a flight directory (`emplan ledger import` reads onboard logs)"
                        .into(),
                );
            }
            continue;
        }
        let entries = match std::fs::read_dir(path) {
            Ok(entries) => entries,
            Err(e) => {
                fail(
                    &mut found,
                    path,
                    format!("not a flight directory nor a readable folder of them: {e}"),
                );
                continue;
            }
        };
        let mut inside: Vec<PathBuf> = entries.filter_map(|e| Some(e.ok()?.path())).collect();
        inside.sort();
        let before = found.inputs.len();
        for p in inside {
            if is_flight_dir(&p) {
                let bytes = dir_bytes(&p);
                found.inputs.push(Input {
                    kind: InputKind::Directory,
                    path: p,
                    bytes,
                });
            } else if logs && p.is_file() && looks_onboard(&p) {
                let bytes = file_bytes(&p);
                found.inputs.push(Input {
                    kind: InputKind::Onboard,
                    path: p,
                    bytes,
                });
            }
        }
        if found.inputs.len() == before {
            let what = if logs {
                "no flight directory (none holds flight.tlog) nor onboard log (.ulg, .bin) here"
            } else {
                "not a flight directory (no flight.tlog) and holds none"
            };
            fail(&mut found, path, what.into());
        }
    }
    // A flight named twice (alone and in its folder) is imported once.
    let mut seen = std::collections::HashSet::new();
    found.inputs.retain(|i| seen.insert(i.path.clone()));
    found
}

/// The record of one input, told the vehicle and pack its files do not say.
pub fn record(input: &Input, options: &ImportOptions) -> Result<FlightRecord, LedgerError> {
    let mut record = match input.kind {
        InputKind::Directory => ledger::record::from_dir(&input.path)?,
        InputKind::Onboard => onboard_record(&input.path)?,
    };
    if record.vehicle.is_none() {
        record.vehicle.clone_from(&options.vehicle);
    }
    if record.pack.is_none() {
        record.pack.clone_from(&options.pack);
    }
    Ok(record)
}

/// The record of an onboard log imported alone: measured as `emplan report LOG` measures it
/// (against the plan.json beside it, else the mission the log holds), its pack fitted to its
/// own voltage and current.
pub fn onboard_record(path: &Path) -> Result<FlightRecord, LedgerError> {
    let failed = |message: String| LedgerError::Flight {
        path: path.display().to_string(),
        message,
    };
    let source = match onboard::format_of(path) {
        Some(onboard::Format::Ulog) => FlightSource::Ulog,
        Some(onboard::Format::Dataflash) => FlightSource::Dataflash,
        // Unreadable, or no onboard log: the reader says which.
        None => {
            return Err(failed(onboard::read(path).err().map_or_else(
                || "not a PX4 ULog nor an ArduPilot DataFlash log".to_string(),
                |e| e.to_string(),
            )))
        }
    };
    let analysis = replay_onboard(path, PlanFrom::default(), SegmentConfig::default())
        .map_err(|e| failed(e.to_string()))?;
    let bytes = std::fs::read(path).map_err(|e| failed(e.to_string()))?;
    let name = path
        .file_name()
        .map_or_else(|| "log".to_string(), |n| n.to_string_lossy().into_owned());
    let id = ledger::record::id_of(&name, &bytes);
    let samples = analysis.segmenter.series().samples();
    let series = PackSeries::of_samples(0, samples.iter().map(|s| (s, None)));
    let started_at = (samples.first()).and_then(|s| ledger::record::iso_of_wall_us(s.wall_us));
    let autopilot = match source {
        FlightSource::Ulog => "px4",
        _ => "ardupilot",
    };
    Ok(ledger::record::of_flight(&FlightInputs {
        id: &id,
        source,
        path: &path.display().to_string(),
        plan: Some(analysis.segmenter.plan()),
        report: &analysis.report,
        pack: (!series.voltage_v.is_empty()).then_some(&series),
        started_at: started_at.as_deref(),
        autopilot: Some(autopilot),
        pack_model: None,
    }))
}

/// Imports `inputs` into `ledger`: each read and measured on a pool of `options.jobs` threads,
/// written by this thread as it is ready; `progress` is told the bytes of each input done
/// (failed ones too). A flight that fails (its files, or its write) is named in the summary and
/// the others are still written.
pub fn import(
    inputs: &[Input],
    ledger: &mut Ledger,
    options: &ImportOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<ImportSummary, ImportError> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(jobs) = options.jobs {
        if jobs == 0 {
            return Err(ImportError::Pool {
                jobs,
                reason: "expected at least one thread".into(),
            });
        }
        pool = pool.num_threads(jobs);
    }
    let pool = pool.build().map_err(|e| ImportError::Pool {
        jobs: options.jobs.unwrap_or(0),
        reason: e.to_string(),
    })?;
    let mut summary = ImportSummary::default();
    let mut failed: Vec<(usize, Failed)> = Vec::new();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::scope(|scope| {
        scope.spawn(move || {
            pool.install(|| {
                inputs
                    .par_iter()
                    .enumerate()
                    .for_each_with(tx, |tx, (k, input)| {
                        let record = record(input, options);
                        // The receiver lives until every sender is gone.
                        let _ = tx.send((k, record));
                    })
            })
        });
        for (k, record) in rx {
            let input = &inputs[k];
            let written = record.and_then(|r| ledger.write(&r));
            match written {
                Ok(Written::Inserted) => summary.inserted += 1,
                Ok(Written::Unchanged) => summary.unchanged += 1,
                Ok(Written::Replaced) => summary.replaced += 1,
                Err(e) => failed.push((
                    k,
                    Failed {
                        path: input.path.clone(),
                        reason: without_path(&e.to_string(), &input.path),
                    },
                )),
            }
            progress(input.bytes);
        }
    });
    failed.sort_by_key(|(k, _)| *k);
    summary.failed = failed.into_iter().map(|(_, f)| f).collect();
    Ok(summary)
}

/// An error's text without the leading `PATH: ` that [`Failed::path`] already says.
fn without_path(message: &str, path: &Path) -> String {
    let prefix = format!("{}: ", path.display());
    message.strip_prefix(&prefix).unwrap_or(message).to_string()
}
