//! Waypoint missions: the in-memory model, file formats (emplan TOML, QGroundControl `.plan`,
//! `QGC WPL 110` `.waypoints`), validation with located errors, WGS84 <-> local ENU geodesy, and
//! the steady wind a mission may be flown in (`wind`).
//!
//! Invariant: pure apart from reading and writing the one file it is asked to; never panics on
//! input; every error names the file and the line or field at fault.

pub mod convert;
pub mod geodesy;
mod qgc_plan;
pub mod rehome;
mod toml_format;
pub mod wind;
mod wpl;

use std::collections::HashSet;
use std::fmt;
use std::path::{Path, PathBuf};

/// A geodetic position on the WGS84 ellipsoid.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Geodetic {
    pub lat_deg: f64,
    pub lon_deg: f64,
    /// Height of the point. For home this is its altitude above mean sea level (treated as the
    /// ellipsoidal height: a constant geoid offset cancels in every local difference we take).
    pub alt_m: f64,
}

/// A position in the local east-north-up frame whose origin is the mission origin.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Enu {
    pub x_east_m: f64,
    pub y_north_m: f64,
    pub z_up_m: f64,
}

/// Where every tour starts and ends: the home position (geodetic, AMSL altitude) and the
/// height above home at which the vehicle hovers at the origin after take-off.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Origin {
    pub home: Geodetic,
    pub height_above_home_m: f64,
}

/// One named waypoint, positioned relative to the origin.
#[derive(Debug, Clone, PartialEq)]
pub struct Waypoint {
    pub name: String,
    pub position: Enu,
    /// Time to hover at the waypoint before leaving it.
    pub hover_s: f64,
}

/// A validated mission: at least one waypoint, unique names, finite coordinates, every waypoint
/// at or above the minimum height above home.
#[derive(Debug, Clone, PartialEq)]
pub struct Mission {
    pub name: String,
    pub origin: Origin,
    pub waypoints: Vec<Waypoint>,
    /// Hover time used for waypoints that do not give their own.
    pub default_hover_s: f64,
    /// Lowest height above home a waypoint may have.
    pub min_height_above_home_m: f64,
    /// The file this mission was read from, if any (for error messages and reports).
    pub source: Option<PathBuf>,
}

/// Default lowest height above home of a waypoint, when the file sets none.
pub const DEFAULT_MIN_HEIGHT_ABOVE_HOME_M: f64 = 2.0;
/// Origin height above home for imported files that carry no take-off item.
pub const DEFAULT_TAKEOFF_HEIGHT_M: f64 = 10.0;
/// The most waypoints a mission may have: the largest the planner plans in reasonable memory
/// and time. Planning prices every ordered pair of points, so its cost matrices are (n + 1)^2
/// f64 (32 MB each at 2000 waypoints; the 86 129 points of a 5 MB `.waypoints` file asked for
/// 59 GB and aborted), and what runs besides the solver's time limit (pricing every leg,
/// candidate lists, the baselines) grows as n^2 too. Measured with `emplan generate --xy 50
/// --z 25` and `emplan plan --time-limit 20` (debug build, 2 cores shared with other builds): 1000 waypoints 42 s wall and 37 MB, 2000 waypoints 114 s and 88 MB, 5000
/// waypoints still running after 10 min at 425 MB (stopped); the service gives a plan 60 s of
/// solving. Checked once, where every format's waypoints are validated
/// ([`RawMission::build`]), before anything of that size is allocated.
pub const MAX_WAYPOINTS: usize = 2000;

/// The mission file formats emplan reads and writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// emplan's own TOML.
    Toml,
    /// QGroundControl `.plan` (JSON).
    QgcPlan,
    /// `QGC WPL 110` text (`.waypoints`, `.txt`), as Mission Planner writes it.
    Wpl,
}

impl Format {
    /// The format a path's extension names.
    pub fn from_path(path: &Path) -> Result<Format, MissionError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("toml") => Ok(Format::Toml),
            Some("plan") => Ok(Format::QgcPlan),
            Some("waypoints") | Some("txt") => Ok(Format::Wpl),
            _ => Err(MissionError::UnknownFormat {
                file: path.display().to_string(),
            }),
        }
    }
}

/// Where in a file a problem is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Place {
    /// The file as a whole.
    File,
    /// A 1-based line.
    Line(usize),
    /// A 0-based item of a `.plan` mission's `items` array.
    Item(usize),
}

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Place::File => Ok(()),
            Place::Line(n) => write!(f, " line {n}:"),
            Place::Item(k) => write!(f, " mission item {k}:"),
        }
    }
}

/// Everything that can be wrong with a mission file.
#[derive(Debug, thiserror::Error)]
pub enum MissionError {
    #[error("{file}: {source}")]
    Io {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: unknown mission format (allowed extensions: .toml, .plan, .waypoints, .txt)")]
    UnknownFormat { file: String },
    #[error("{file}:{place} {problem}")]
    Invalid {
        file: String,
        place: Place,
        problem: String,
    },
}

impl MissionError {
    fn invalid(file: &str, place: Place, problem: impl Into<String>) -> MissionError {
        MissionError::Invalid {
            file: file.to_string(),
            place,
            problem: problem.into(),
        }
    }
}

/// The 1-based line of a byte offset in `text` (for errors from parsers that give spans).
pub(crate) fn line_of(text: &str, offset: usize) -> usize {
    text.as_bytes()
        .iter()
        .take(offset)
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// Reads and validates a mission file, choosing the format by extension.
pub fn load(path: &Path) -> Result<Mission, MissionError> {
    let format = Format::from_path(path)?;
    let bytes = std::fs::read(path).map_err(|source| MissionError::Io {
        file: path.display().to_string(),
        source,
    })?;
    let text = String::from_utf8(bytes).map_err(|e| {
        MissionError::invalid(
            &path.display().to_string(),
            Place::File,
            format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })?;
    load_str(&text, format, Some(path))
}

/// Parses and validates a mission from text; `source` names the file in errors.
pub fn load_str(
    text: &str,
    format: Format,
    source: Option<&Path>,
) -> Result<Mission, MissionError> {
    let file = source.map_or_else(|| "<mission>".to_string(), |p| p.display().to_string());
    let stem = source
        .and_then(|p| p.file_stem())
        .and_then(|s| s.to_str())
        .unwrap_or("mission")
        .to_string();
    let raw = match format {
        Format::Toml => toml_format::parse(text, &file)?,
        Format::QgcPlan => qgc_plan::parse(text, &file, &stem)?,
        Format::Wpl => wpl::parse(text, &file, &stem)?,
    };
    let mut mission = raw.build(&file)?;
    mission.source = source.map(Path::to_path_buf);
    Ok(mission)
}

/// A mission rendered in one format.
pub fn to_string(mission: &Mission, format: Format) -> Result<String, MissionError> {
    match format {
        Format::Toml => toml_format::write(mission),
        Format::QgcPlan => Ok(qgc_plan::write(mission)),
        Format::Wpl => Ok(wpl::write(mission)),
    }
}

/// How a waypoint's position was given in a file.
#[derive(Debug, Clone, Copy)]
enum RawPosition {
    Enu(Enu),
    /// Latitude, longitude and altitude above home.
    Geodetic {
        lat_deg: f64,
        lon_deg: f64,
        alt_above_home_m: f64,
    },
}

#[derive(Debug, Clone)]
struct RawWaypoint {
    name: String,
    position: RawPosition,
    hover_s: Option<f64>,
    place: Place,
}

/// A mission as read from a file, before validation.
#[derive(Debug, Clone)]
struct RawMission {
    name: String,
    home: Geodetic,
    height_above_home_m: f64,
    default_hover_s: f64,
    min_height_above_home_m: f64,
    waypoints: Vec<RawWaypoint>,
    /// Where the origin and the mission-level fields are defined.
    place: Place,
}

fn finite(file: &str, place: &Place, what: &str, value: f64) -> Result<f64, MissionError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(MissionError::invalid(
            file,
            place.clone(),
            format!("{what}: {value} is not allowed (a finite number is required)"),
        ))
    }
}

fn check_lat_lon(
    file: &str,
    place: &Place,
    what: &str,
    lat: f64,
    lon: f64,
) -> Result<(), MissionError> {
    finite(file, place, &format!("{what} lat_deg"), lat)?;
    finite(file, place, &format!("{what} lon_deg"), lon)?;
    if !(-90.0..=90.0).contains(&lat) {
        return Err(MissionError::invalid(
            file,
            place.clone(),
            format!("{what} lat_deg: {lat} is out of range (allowed: -90 to 90)"),
        ));
    }
    if !(-180.0..=180.0).contains(&lon) {
        return Err(MissionError::invalid(
            file,
            place.clone(),
            format!("{what} lon_deg: {lon} is out of range (allowed: -180 to 180)"),
        ));
    }
    Ok(())
}

impl RawMission {
    /// Validates everything and converts positions into the origin's ENU frame.
    fn build(self, file: &str) -> Result<Mission, MissionError> {
        let place = &self.place;
        check_lat_lon(file, place, "origin", self.home.lat_deg, self.home.lon_deg)?;
        finite(file, place, "origin home_alt_amsl_m", self.home.alt_m)?;
        finite(
            file,
            place,
            "origin height_above_home_m",
            self.height_above_home_m,
        )?;
        finite(file, place, "default_hover_s", self.default_hover_s)?;
        finite(
            file,
            place,
            "min_height_above_home_m",
            self.min_height_above_home_m,
        )?;
        if self.default_hover_s < 0.0 {
            return Err(MissionError::invalid(
                file,
                place.clone(),
                format!(
                    "default_hover_s: {} is negative (allowed: 0 or more)",
                    self.default_hover_s
                ),
            ));
        }
        if self.height_above_home_m < self.min_height_above_home_m {
            return Err(MissionError::invalid(
                file,
                place.clone(),
                format!(
                    "origin height_above_home_m: {} m is below the minimum height above home of {} m",
                    self.height_above_home_m, self.min_height_above_home_m
                ),
            ));
        }
        if self.waypoints.is_empty() {
            return Err(MissionError::invalid(
                file,
                Place::File,
                "the mission has no waypoints (at least 1 is required)",
            ));
        }
        if let Some(first_over) = self.waypoints.get(MAX_WAYPOINTS) {
            return Err(MissionError::invalid(
                file,
                first_over.place.clone(),
                format!(
                    "waypoint {} of {}: a mission may have at most {MAX_WAYPOINTS} waypoints \
                     (the planner prices every pair of them; split the mission into smaller \
                     files)",
                    MAX_WAYPOINTS + 1,
                    self.waypoints.len()
                ),
            ));
        }
        let origin = Origin {
            home: self.home,
            height_above_home_m: self.height_above_home_m,
        };
        let mut names = HashSet::new();
        let mut waypoints = Vec::with_capacity(self.waypoints.len());
        for w in self.waypoints {
            let what = format!("waypoint {:?}", w.name);
            if w.name.trim().is_empty() {
                return Err(MissionError::invalid(
                    file,
                    w.place,
                    "waypoint name is empty",
                ));
            }
            if !names.insert(w.name.clone()) {
                return Err(MissionError::invalid(
                    file,
                    w.place,
                    format!("{what}: duplicate name (waypoint names must be unique)"),
                ));
            }
            let position = match w.position {
                RawPosition::Enu(p) => {
                    finite(file, &w.place, &format!("{what}: x_m"), p.x_east_m)?;
                    finite(file, &w.place, &format!("{what}: y_m"), p.y_north_m)?;
                    finite(file, &w.place, &format!("{what}: z_m"), p.z_up_m)?;
                    p
                }
                RawPosition::Geodetic {
                    lat_deg,
                    lon_deg,
                    alt_above_home_m,
                } => {
                    check_lat_lon(file, &w.place, &format!("{what}:"), lat_deg, lon_deg)?;
                    finite(
                        file,
                        &w.place,
                        &format!("{what}: alt_above_home_m"),
                        alt_above_home_m,
                    )?;
                    origin.to_enu(Geodetic {
                        lat_deg,
                        lon_deg,
                        alt_m: self.home.alt_m + alt_above_home_m,
                    })
                }
            };
            let height = origin.height_above_home_m(position);
            if height < self.min_height_above_home_m {
                return Err(MissionError::invalid(
                    file,
                    w.place,
                    format!(
                        "{what}: {height:.2} m above home is below the minimum of {} m \
                         (raise it or set min_height_above_home_m)",
                        self.min_height_above_home_m
                    ),
                ));
            }
            let hover_s = w.hover_s.unwrap_or(self.default_hover_s);
            finite(file, &w.place, &format!("{what}: hover_s"), hover_s)?;
            if hover_s < 0.0 {
                return Err(MissionError::invalid(
                    file,
                    w.place,
                    format!("{what}: hover_s {hover_s} is negative (allowed: 0 or more)"),
                ));
            }
            waypoints.push(Waypoint {
                name: w.name,
                position,
                hover_s,
            });
        }
        Ok(Mission {
            name: self.name,
            origin,
            waypoints,
            default_hover_s: self.default_hover_s,
            min_height_above_home_m: self.min_height_above_home_m,
            source: None,
        })
    }
}

impl Mission {
    /// Geodetic position of waypoint `k`, with altitude above home (MAVLink's relative frame).
    pub fn waypoint_relative(&self, k: usize) -> Option<(f64, f64, f64)> {
        let w = self.waypoints.get(k)?;
        let g = self.origin.to_geodetic(w.position);
        Some((g.lat_deg, g.lon_deg, g.alt_m - self.origin.home.alt_m))
    }
}
