//! The one way a command writes a file the user named (a converted or generated mission, a
//! downloaded one, an SVG figure, a TSPLIB export, a calibrated vehicle directory): never over
//! one of the command's inputs (compared as files: through symlinks, and by device and inode on
//! unix, so a hard link or `./` is the same file), never inside a flight directory (the
//! recorder's record of a flight, `flight.tlog` and the files beside it), an existing file only
//! when forced, and written atomically: to a temporary file beside it, synced, then linked or
//! renamed into place, so a failure leaves the old file or none, never half of one.
//!
//! A module of its own at the top of the library rather than in `mission`: what it writes is
//! not only missions, and it must know a flight directory (`flightlog`), which `mission` may not
//! import. Commands build an [`Output`], [`Output::check`] it before any long work or link work
//! (fail fast), then [`Output::write`] the bytes, which checks again; a new directory likewise
//! with [`Output::check_dir`] and [`Output::create_dir`], its files written with
//! [`Output::file`].

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::flightlog::recorder::flight_dir_holding;

/// Why a file was not written; each names it.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{file}: refusing to write over the input {input} (give another output file)")]
    Input { file: String, input: String },
    #[error(
        "{file}: inside the flight directory {dir}; refusing to write there, even with --force \
         (a flight's files are its record: give a file outside it)"
    )]
    FlightDir { file: String, dir: String },
    #[error("{file}: is a directory; give a file name")]
    Directory { file: String },
    #[error("{file}: exists and is not a directory")]
    NotDirectory { file: String },
    #[error("{file}: exists; refusing to replace it without --force")]
    Exists { file: String },
    #[error("{dir}: exists and is not empty; refusing to write into it without --force")]
    NotEmpty { dir: String },
    #[error("{file}: {source}")]
    Io {
        file: String,
        #[source]
        source: std::io::Error,
    },
}

/// A file (or, for [`Output::create_dir`], a directory) a command is asked to write.
#[derive(Debug, Clone)]
pub struct Output {
    pub path: PathBuf,
    /// What the command reads (and any other file it writes): never written over, even forced.
    pub inputs: Vec<PathBuf>,
    /// Replace an existing file (the commands' `--force`); never an input nor a flight's file.
    pub force: bool,
}

impl Output {
    pub fn new(path: impl Into<PathBuf>, inputs: Vec<PathBuf>, force: bool) -> Output {
        Output {
            path: path.into(),
            inputs,
            force,
        }
    }

    /// The file `name` inside this output directory, with the same inputs and force.
    pub fn file(&self, name: impl AsRef<Path>) -> Output {
        Output::new(self.path.join(name), self.inputs.clone(), self.force)
    }

    /// Whether the file may be written: not an input, not in a flight directory, not a
    /// directory, and not existing unless forced.
    pub fn check(&self) -> Result<(), OutputError> {
        let file = self.path.display().to_string();
        self.check_place()?;
        if self.path.file_name().is_none() || self.path.is_dir() {
            return Err(OutputError::Directory { file });
        }
        match std::fs::symlink_metadata(&self.path) {
            Ok(_) if !self.force => Err(OutputError::Exists { file }),
            Ok(_) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
            Err(source) => Err(OutputError::Io { file, source }),
        }
    }

    /// Writes `bytes` to the file, after [`Output::check`]: to a temporary file beside it,
    /// synced, then put in place in one step. Unforced, it is hard-linked into place, which
    /// fails if a file appeared there since the check; forced, renamed over (keeping the
    /// replaced file's permissions).
    pub fn write(&self, bytes: &[u8]) -> Result<(), OutputError> {
        self.check()?;
        let io = |source| OutputError::Io {
            file: self.path.display().to_string(),
            source,
        };
        let (temp, mut file) = create_temp(&self.path).map_err(io)?;
        let written = file
            .write_all(bytes)
            .and_then(|()| file.sync_all())
            .and_then(|()| match std::fs::metadata(&self.path) {
                Ok(old) if self.force => file.set_permissions(old.permissions()),
                _ => Ok(()),
            });
        drop(file);
        let placed = written.map_err(io).and_then(|()| self.place(&temp));
        // Gone after a hard link or a failure; after a rename there is nothing to remove.
        let _ = std::fs::remove_file(&temp);
        placed?;
        if let Some(dir) = self.path.parent().filter(|d| !d.as_os_str().is_empty()) {
            if let Ok(d) = std::fs::File::open(dir) {
                // Best effort: not every platform can fsync a directory.
                let _ = d.sync_all();
            }
        }
        Ok(())
    }

    /// Whether the output directory may be written: not an input, not a flight directory nor
    /// in one, and not an existing file nor, unless forced, a directory holding anything.
    pub fn check_dir(&self) -> Result<(), OutputError> {
        let file = self.path.display().to_string();
        self.check_place()?;
        match std::fs::read_dir(&self.path).map(|mut entries| entries.next().is_some()) {
            Ok(true) if !self.force => Err(OutputError::NotEmpty { dir: file }),
            Ok(_) => Ok(()),
            Err(_) if std::fs::symlink_metadata(&self.path).is_ok() => {
                Err(OutputError::NotDirectory { file })
            }
            Err(_) => Ok(()),
        }
    }

    /// Creates the output directory (and its parents) after [`Output::check_dir`]; write its
    /// files with [`Output::file`].
    pub fn create_dir(&self) -> Result<(), OutputError> {
        self.check_dir()?;
        std::fs::create_dir_all(&self.path).map_err(|source| OutputError::Io {
            file: self.path.display().to_string(),
            source,
        })
    }

    /// The rules that no `force` lifts: not an input, not inside a flight directory.
    fn check_place(&self) -> Result<(), OutputError> {
        let file = self.path.display().to_string();
        if let Some(input) = self.inputs.iter().find(|i| same_file(&self.path, i)) {
            return Err(OutputError::Input {
                file,
                input: input.display().to_string(),
            });
        }
        if let Some(dir) = flight_dir_holding(&self.path) {
            return Err(OutputError::FlightDir {
                file,
                dir: dir.display().to_string(),
            });
        }
        Ok(())
    }

    /// Puts the written temporary file in place of the output.
    fn place(&self, temp: &Path) -> Result<(), OutputError> {
        let file = self.path.display().to_string();
        if self.force {
            return std::fs::rename(temp, &self.path)
                .map_err(|source| OutputError::Io { file, source });
        }
        match std::fs::hard_link(temp, &self.path) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                Err(OutputError::Exists { file })
            }
            // A file system without hard links: checked again, then renamed.
            Err(_) if std::fs::symlink_metadata(&self.path).is_ok() => {
                Err(OutputError::Exists { file })
            }
            Err(_) => {
                std::fs::rename(temp, &self.path).map_err(|source| OutputError::Io { file, source })
            }
        }
    }
}

/// A new temporary file beside `path`: `.NAME.PID-K.emplan-tmp`.
fn create_temp(path: &Path) -> std::io::Result<(PathBuf, std::fs::File)> {
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let mut k = 0;
    loop {
        let temp = path.with_file_name(format!(".{name}.{}-{k}.emplan-tmp", std::process::id()));
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temp)
        {
            Ok(file) => return Ok((temp, file)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && k < 100 => k += 1,
            Err(e) => return Err(e),
        }
    }
}

/// The directory holding `path`, made absolute with symlinks resolved where it exists.
fn parent_of(path: &Path) -> Option<PathBuf> {
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    parent.canonicalize().ok()
}

/// `path` made absolute with symlinks resolved: itself if it exists, else its directory's.
fn resolved(path: &Path) -> Option<PathBuf> {
    path.canonicalize()
        .ok()
        .or_else(|| Some(parent_of(path)?.join(path.file_name()?)))
}

/// Whether `output` names the file (or directory) `input`: the same device and inode on unix
/// when both exist (hard links, symlinks), else the same resolved path.
fn same_file(output: &Path, input: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(a), Ok(b)) = (std::fs::metadata(output), std::fs::metadata(input)) {
            return a.dev() == b.dev() && a.ino() == b.ino();
        }
    }
    match (resolved(output), resolved(input)) {
        (Some(a), Some(b)) => a == b,
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::recorder::TLOG_FILE;

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .expect("readable")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_new_file_is_written_whole_and_no_temporary_file_stays_beside_it() {
        let dir = tempfile::tempdir().expect("temp dir");
        let out = Output::new(dir.path().join("a.svg"), vec![], false);
        out.write(b"<svg/>").expect("written");
        assert_eq!(std::fs::read(&out.path).expect("read"), b"<svg/>");
        assert_eq!(entries(dir.path()), ["a.svg"]);
    }

    #[test]
    fn an_existing_file_is_kept_unforced_and_replaced_forced() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("a.json");
        std::fs::write(&path, "old").expect("written");
        let error = Output::new(&path, vec![], false)
            .write(b"new")
            .expect_err("refused");
        assert!(matches!(error, OutputError::Exists { .. }), "{error}");
        assert!(error.to_string().contains("without --force"), "{error}");
        assert_eq!(std::fs::read_to_string(&path).expect("read"), "old");
        Output::new(&path, vec![], true)
            .write(b"new")
            .expect("forced");
        assert_eq!(std::fs::read_to_string(&path).expect("read"), "new");
        assert_eq!(entries(dir.path()), ["a.json"]);
    }

    #[test]
    fn an_input_is_refused_even_forced_by_another_name_a_symlink_or_a_hard_link() {
        let dir = tempfile::tempdir().expect("temp dir");
        let input = dir.path().join("m.toml");
        std::fs::write(&input, "mission").expect("written");
        let by_dot = dir.path().join(".").join("m.toml");
        let mut names = vec![input.clone(), by_dot];
        #[cfg(unix)]
        {
            let symlink = dir.path().join("link.toml");
            std::os::unix::fs::symlink(&input, &symlink).expect("symlink");
            names.push(symlink);
        }
        let hard = dir.path().join("hard.toml");
        if std::fs::hard_link(&input, &hard).is_ok() {
            names.push(hard);
        }
        for name in names {
            let error = Output::new(&name, vec![input.clone()], true)
                .write(b"svg")
                .expect_err("refused");
            assert!(
                matches!(error, OutputError::Input { .. }),
                "{name:?}: {error}"
            );
            assert!(error
                .to_string()
                .contains("refusing to write over the input"));
        }
        assert_eq!(std::fs::read_to_string(&input).expect("read"), "mission");
    }

    #[test]
    fn a_file_inside_a_flight_directory_is_refused_even_forced_new_or_not() {
        let dir = tempfile::tempdir().expect("temp dir");
        let flight = dir.path().join("20260101-000000-m");
        std::fs::create_dir_all(flight.join("sub")).expect("dirs");
        std::fs::write(flight.join(TLOG_FILE), "frames").expect("written");
        for name in [TLOG_FILE, "report.json", "plot.svg", "sub/plot.svg"] {
            let error = Output::new(flight.join(name), vec![], true)
                .write(b"svg")
                .expect_err("refused");
            assert!(
                matches!(error, OutputError::FlightDir { .. }),
                "{name}: {error}"
            );
            assert!(error.to_string().contains(&flight.display().to_string()));
        }
        assert_eq!(
            std::fs::read_to_string(flight.join(TLOG_FILE)).expect("read"),
            "frames"
        );
        assert_eq!(entries(&flight), [TLOG_FILE, "sub"]);
        // Beside the flight directory is fine.
        Output::new(dir.path().join("plot.svg"), vec![], false)
            .write(b"svg")
            .expect("written");
    }

    #[test]
    fn a_directory_is_never_replaced_by_a_file() {
        let dir = tempfile::tempdir().expect("temp dir");
        let error = Output::new(dir.path(), vec![], true)
            .write(b"x")
            .expect_err("refused");
        assert!(matches!(error, OutputError::Directory { .. }), "{error}");
    }

    #[test]
    fn a_missing_directory_is_an_error_naming_the_file_and_leaves_nothing() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("nowhere/a.svg");
        let error = Output::new(&path, vec![], false)
            .write(b"x")
            .expect_err("fails");
        assert!(error.to_string().starts_with(&path.display().to_string()));
        assert!(entries(dir.path()).is_empty());
    }

    #[test]
    fn an_output_directory_is_created_new_or_empty_and_an_occupied_one_only_forced() {
        let dir = tempfile::tempdir().expect("temp dir");
        let out = Output::new(dir.path().join("v/w"), vec![], false);
        out.create_dir().expect("created");
        out.create_dir().expect("empty is fine");
        out.file("vehicle.toml").write(b"x").expect("written");
        let error = out.create_dir().expect_err("occupied");
        assert!(matches!(error, OutputError::NotEmpty { .. }), "{error}");
        let forced = Output::new(&out.path, vec![], true);
        forced.create_dir().expect("forced");
        forced.file("vehicle.toml").write(b"y").expect("replaced");
        assert_eq!(entries(&out.path), ["vehicle.toml"]);

        let input = Output::new(&out.path, vec![out.path.clone()], true);
        let error = input.create_dir().expect_err("an input directory");
        assert!(matches!(error, OutputError::Input { .. }), "{error}");

        let flight = dir.path().join("flight");
        std::fs::create_dir(&flight).expect("dir");
        std::fs::write(flight.join(TLOG_FILE), "frames").expect("written");
        for path in [flight.clone(), flight.join("v")] {
            let error = Output::new(&path, vec![], true)
                .create_dir()
                .expect_err("a flight directory");
            assert!(matches!(error, OutputError::FlightDir { .. }), "{error}");
        }
        let file = Output::new(flight.join(TLOG_FILE), vec![], true);
        let error = file.create_dir().expect_err("in a flight");
        assert!(matches!(error, OutputError::FlightDir { .. }), "{error}");
        let plain = dir.path().join("plain");
        std::fs::write(&plain, "x").expect("written");
        let error = Output::new(&plain, vec![], true)
            .create_dir()
            .expect_err("a file");
        assert!(matches!(error, OutputError::NotDirectory { .. }), "{error}");
    }
}
