//! The flight log and what is measured from it: telemetry readings in SI units, the vehicle-time
//! clock, the crash-safe flight directory (raw `.tlog`, decoded `samples.csv`, the plan, the
//! report), segmentation of a flight into take-off, legs, settles, hovers and landing against the
//! plan that was flown, energy integration with flags, and per-leg reports predicted vs measured.
//!
//! Invariant: no tokio and no MAVLink types here; `link::telemetry` converts MAVLink at the edge,
//! once. Everything after the receive task is a pure function of (wall time, frame bytes), so a
//! replay of the `.tlog` gives the live run's report.

pub mod clock;
pub mod csv;
pub mod energy;
pub mod plan;
pub mod recorder;
pub mod report;
pub mod samples;
pub mod segment;
pub mod synthetic;
pub mod telemetry;
pub mod tlog;

/// Everything that can go wrong reading or writing a flight log; each names its file.
#[derive(Debug, thiserror::Error)]
pub enum FlightLogError {
    #[error("{file}: {source}")]
    Io {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: byte {offset}: {reason}")]
    Corrupt {
        file: String,
        offset: u64,
        reason: String,
    },
    #[error("{file} line {line}, column {column}: {reason}")]
    Csv {
        file: String,
        line: usize,
        column: String,
        reason: String,
    },
    #[error("{file}: {reason}")]
    Json { file: String, reason: String },
    #[error("flight directory {dir}: {reason}")]
    Directory { dir: String, reason: String },
    #[error("flight plan: {reason}")]
    Plan { reason: String },
}

/// Writes a whole small file so that it is either absent or complete, even across a power cut:
/// a temporary file beside it, fsync, rename over, fsync of the directory.
pub(crate) fn write_synced(path: &std::path::Path, bytes: &[u8]) -> Result<(), FlightLogError> {
    use std::io::Write;
    let io = |source| FlightLogError::Io {
        file: path.display().to_string(),
        source,
    };
    let mut tmp_name = path.file_name().unwrap_or_default().to_os_string();
    tmp_name.push(".tmp");
    let tmp = path.with_file_name(tmp_name);
    let mut file = std::fs::File::create(&tmp).map_err(io)?;
    file.write_all(bytes).map_err(io)?;
    file.sync_all().map_err(io)?;
    std::fs::rename(&tmp, path).map_err(io)?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        if let Ok(d) = std::fs::File::open(dir) {
            // Best effort: not every platform can fsync a directory.
            let _ = d.sync_all();
        }
    }
    Ok(())
}
