//! The flight log and what is measured from it: telemetry readings in SI units, the vehicle-time
//! clock, the crash-safe flight directory (raw `.tlog`, decoded `samples.csv`, the plan, the
//! report), segmentation of a flight into take-off, legs, settles, hovers and landing against the
//! plan that was flown, energy integration with flags, and per-leg reports predicted vs measured.
//!
//! Invariant: no tokio and no MAVLink types here; `link::telemetry` converts MAVLink at the edge,
//! once. Everything after the receive task is a pure function of (wall time, frame bytes), so a
//! replay of the `.tlog` gives the live run's report.

pub mod breach;
pub mod clock;
pub mod csv;
pub mod energy;
pub mod flight_plan;
pub mod guard;
pub mod onboard;
pub mod part;
pub mod photos;
pub mod recorder;
pub mod replay;
pub mod report;
pub mod resume;
pub mod samples;
pub mod segment;
pub mod synthetic;
pub mod telemetry;
pub mod tlog;
pub mod watch;
pub mod wind;

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
    #[error("{file}: no MAVLink frame found in {bytes} bytes")]
    NoFrame { file: String, bytes: u64 },
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
    /// The directory flight directories are made in cannot be written.
    #[error("log directory {dir}: {reason}")]
    LogDir { dir: String, reason: String },
    #[error("flight plan: {reason}")]
    Plan { reason: String },
}

/// The error of an IO operation on `path`.
pub(crate) fn io_error(
    path: &std::path::Path,
) -> impl FnOnce(std::io::Error) -> FlightLogError + '_ {
    move |source| FlightLogError::Io {
        file: path.display().to_string(),
        source,
    }
}

/// A file written only at its end through a buffer, flushed to the OS and synced to disk when
/// its owner says: new, or reopened to go on after a crash.
#[derive(Debug)]
pub(crate) struct AppendFile {
    path: std::path::PathBuf,
    out: std::io::BufWriter<std::fs::File>,
}

impl AppendFile {
    /// Creates `path`, which must not exist: a flight's files are never overwritten.
    pub(crate) fn create(path: &std::path::Path) -> Result<AppendFile, FlightLogError> {
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
            .map_err(io_error(path))?;
        Ok(AppendFile {
            path: path.to_path_buf(),
            out: std::io::BufWriter::with_capacity(64 * 1024, file),
        })
    }

    /// Opens an existing `path` to append to it after its first `keep` bytes (what follows
    /// them, a record torn by a crash, is cut off first).
    pub(crate) fn reopen(path: &std::path::Path, keep: u64) -> Result<AppendFile, FlightLogError> {
        use std::io::{Seek, SeekFrom};
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(io_error(path))?;
        file.set_len(keep).map_err(io_error(path))?;
        file.seek(SeekFrom::End(0)).map_err(io_error(path))?;
        file.sync_data().map_err(io_error(path))?;
        Ok(AppendFile {
            path: path.to_path_buf(),
            out: std::io::BufWriter::with_capacity(64 * 1024, file),
        })
    }

    pub(crate) fn path(&self) -> &std::path::Path {
        &self.path
    }

    /// Whether `bytes` more fit in the buffer without it spilling to the OS on its own.
    pub(crate) fn has_room(&self, bytes: usize) -> bool {
        self.out.buffer().len() + bytes <= self.out.capacity()
    }

    pub(crate) fn write(&mut self, bytes: &[u8]) -> Result<(), FlightLogError> {
        use std::io::Write;
        self.out.write_all(bytes).map_err(io_error(&self.path))
    }

    /// Hands the buffer to the operating system (survives a crash of this process).
    pub(crate) fn flush(&mut self) -> Result<(), FlightLogError> {
        use std::io::Write;
        self.out.flush().map_err(io_error(&self.path))
    }

    /// Flushes and asks the OS to put the data on disk (survives a power cut).
    pub(crate) fn sync(&mut self) -> Result<(), FlightLogError> {
        self.flush()?;
        self.out.get_ref().sync_data().map_err(io_error(&self.path))
    }
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
