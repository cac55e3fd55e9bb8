//! Waypoint missions: the in-memory model, file formats (emplan TOML, QGroundControl `.plan`,
//! `QGC WPL 110` `.waypoints`), validation with located errors, WGS84 <-> local ENU geodesy, the
//! actions a mission carries at its waypoints and the state they leave in force (`actions`), and
//! the steady wind a mission may be flown in (`wind`).
//!
//! Invariant: pure apart from reading and writing the one file it is asked to; never panics on
//! input; every error names the file and the line or field at fault.

pub mod actions;
#[cfg(test)]
mod block_files_tests;
pub mod blocks;
pub mod convert;
pub mod fence;
#[cfg(test)]
mod fence_tests;
pub mod geodesy;
mod qgc_plan;
pub mod rehome;
mod sequence;
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

/// How the autopilot flies to a waypoint.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum WaypointKind {
    /// NAV_WAYPOINT: a straight line to it.
    #[default]
    Waypoint,
    /// NAV_SPLINE_WAYPOINT: ArduCopter flies a curve through it (priced as the straight leg).
    Spline,
    /// NAV_LOITER_TIME at its own place: flown to, then held for the hover time; the loiter's
    /// parameters 2-4 (heading required, radius, exit) as the file gave them.
    LoiterTime { params: [f64; 3] },
}

impl WaypointKind {
    /// The MAV_CMD that flies it.
    pub fn command(self) -> u16 {
        match self {
            WaypointKind::Waypoint => actions::id::NAV_WAYPOINT,
            WaypointKind::Spline => actions::id::NAV_SPLINE_WAYPOINT,
            WaypointKind::LoiterTime { .. } => actions::id::NAV_LOITER_TIME,
        }
    }
}

/// One named waypoint, positioned relative to the origin, with the actions that follow it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Waypoint {
    pub name: String,
    pub position: Enu,
    /// Time to hover at the waypoint before leaving it (its own hold: MISSION_ITEM param1).
    pub hover_s: f64,
    pub kind: WaypointKind,
    /// The commands that follow it in the file, in order, until the next navigation item: the
    /// autopilot runs them once the waypoint is reached and its hover done ([`actions`]).
    pub actions: Vec<actions::Command>,
}

impl Waypoint {
    /// The time the vehicle holds at the waypoint: its hover and the holds of its actions
    /// (NAV_DELAY, NAV_LOITER_TIME where it is).
    pub fn hold_s(&self) -> f64 {
        self.hover_s
            + self
                .actions
                .iter()
                .map(|c| match c.action() {
                    actions::Action::Hold { duration_s } => duration_s,
                    _ => 0.0,
                })
                .sum::<f64>()
    }

    /// How many photos its actions take.
    pub fn photos(&self) -> u32 {
        self.actions
            .iter()
            .filter(|c| c.action() == actions::Action::Photo)
            .count() as u32
    }
}

/// A named point of interest a region-of-interest action looks at (TOML `roi = "NAME"`).
#[derive(Debug, Clone, PartialEq)]
pub struct Poi {
    pub name: String,
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_above_home_m: f64,
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
    /// The commands between the take-off and the first waypoint: run once the take-off
    /// completes, first in every order.
    pub start_actions: Vec<actions::Command>,
    /// Named points of interest (the names of the regions of interest the actions look at).
    pub pois: Vec<Poi>,
    /// The geofence the vehicle must respect (empty: none).
    pub fence: fence::Fence,
    /// Where the autopilot may return to instead of home.
    pub rally: Vec<fence::RallyPoint>,
    /// Runs of waypoints flown whole (surveys, scans, hand-written blocks), in file order.
    pub blocks: Vec<blocks::Block>,
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
    /// A field of a `.plan` file outside the mission's items, as a path
    /// (`geoFence.polygons[1].polygon[3]`).
    Field(String),
}

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Place::File => Ok(()),
            Place::Line(n) => write!(f, " line {n}:"),
            Place::Item(k) => write!(f, " mission item {k}:"),
            Place::Field(path) => write!(f, " {path}:"),
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

/// A mission rendered in one format. A `.waypoints` file holds mission items only: a
/// mission with a geofence or rally points is refused rather than written without them
/// ([`Mission::cannot_be_wpl`]), and so is one with blocks
/// ([`Mission::blocks_cannot_be_wpl`]; `emplan convert --lossy` writes its waypoints and says
/// the blocks are lost).
pub fn to_string(mission: &Mission, format: Format) -> Result<String, MissionError> {
    match format {
        Format::Toml => toml_format::write(mission),
        Format::QgcPlan => Ok(qgc_plan::write(mission)),
        Format::Wpl => match mission
            .cannot_be_wpl(&mission.name)
            .or_else(|| mission.blocks_cannot_be_wpl(&mission.name))
        {
            Some(e) => Err(e),
            None => Ok(wpl::write(mission)),
        },
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
    kind: WaypointKind,
    /// With the place each came from.
    actions: Vec<(actions::Command, Place)>,
    place: Place,
}

/// A fence zone as read from a file, with where it was given.
#[derive(Debug, Clone)]
struct RawZone {
    zone: fence::Zone,
    /// The zone's place: a line, or its `.plan` field (`geoFence.polygons[1]`).
    place: Place,
    /// The key its vertices are listed under (`polygon` in a `.plan`, `vertices_deg` or
    /// `vertices_m` in TOML), to name a vertex (`polygon[3]`).
    vertices_key: &'static str,
}

impl RawZone {
    /// Where vertex `k` (0-based) is, and the words that name it after the zone's: a `.plan`
    /// field path names it in full; a TOML line needs its index in the message.
    fn vertex(&self, k: usize) -> (Place, String) {
        match &self.place {
            Place::Field(path) => (
                Place::Field(format!("{path}.{}[{k}]", self.vertices_key)),
                String::new(),
            ),
            other => (other.clone(), format!(" {}[{k}]", self.vertices_key)),
        }
    }
}

/// A block as read from a file: waypoints `first..first + len` of the raw waypoints.
#[derive(Debug, Clone)]
struct RawBlock {
    name: String,
    kind: blocks::BlockKind,
    first: usize,
    len: usize,
    reversible: bool,
    source: Option<serde_json::Value>,
    /// Where it is given (a `.plan` complex item, a TOML `[[blocks]]` line).
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
    start_actions: Vec<(actions::Command, Place)>,
    pois: Vec<Poi>,
    /// The fence's zones, in file order (a `.plan`'s polygons, then its circles).
    zones: Vec<RawZone>,
    /// The fence's breach return point (altitude above home), with its place.
    breach_return: Option<(Geodetic, Place)>,
    /// The rally points, each with its place.
    rally: Vec<(fence::RallyPoint, Place)>,
    /// The blocks, in file order.
    blocks: Vec<RawBlock>,
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
        let raw_places: Vec<Place> = self.waypoints.iter().map(|w| w.place.clone()).collect();
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
            if let WaypointKind::LoiterTime { params } = w.kind {
                for (k, v) in params.iter().enumerate() {
                    if v.is_infinite() {
                        return Err(MissionError::invalid(
                            file,
                            w.place,
                            format!("{what}: loiter param{} is {v} (a finite number or empty is required)", k + 2),
                        ));
                    }
                }
            }
            let actions = check_actions(file, &what, w.actions)?;
            waypoints.push(Waypoint {
                name: w.name,
                position,
                hover_s,
                kind: w.kind,
                actions,
            });
        }
        let start_actions = check_actions(file, "the start", self.start_actions)?;
        let fence = check_fence(file, &origin, self.zones, self.breach_return)?;
        let rally = check_rally(file, &origin, &fence, self.rally)?;
        let blocks = check_blocks(file, &origin, &fence, &waypoints, self.blocks)?;
        for (w, raw_place) in waypoints.iter().zip(&raw_places) {
            let p = [w.position.x_east_m, w.position.y_north_m];
            if let Some(k) = fence.zone_broken_by(&origin, p) {
                return Err(breaks(
                    file,
                    raw_place.clone(),
                    &format!("waypoint {:?}", w.name),
                    &fence.zones[k],
                    k,
                ));
            }
        }
        if let Some(k) = fence.zone_broken_by(&origin, [0.0, 0.0]) {
            return Err(breaks(
                file,
                place.clone(),
                "the take-off point above home",
                &fence.zones[k],
                k,
            ));
        }
        for poi in &self.pois {
            check_lat_lon(
                file,
                place,
                &format!("point of interest {:?}", poi.name),
                poi.lat_deg,
                poi.lon_deg,
            )?;
            finite(
                file,
                place,
                &format!("point of interest {:?} alt_above_home_m", poi.name),
                poi.alt_above_home_m,
            )?;
        }
        Ok(Mission {
            name: self.name,
            origin,
            waypoints,
            default_hover_s: self.default_hover_s,
            min_height_above_home_m: self.min_height_above_home_m,
            start_actions,
            pois: self.pois,
            fence,
            rally,
            blocks,
            source: None,
        })
    }
}

/// Checks every block (its waypoints in range, at least two, in no other block, its name
/// unique) and that no line of it (the segment between two consecutive waypoints of it)
/// crosses an exclusion zone or leaves an inclusion zone: the planner detours round the fence
/// between points, never inside a block, which is flown as written.
fn check_blocks(
    file: &str,
    origin: &Origin,
    fence: &fence::Fence,
    waypoints: &[Waypoint],
    raw: Vec<RawBlock>,
) -> Result<Vec<blocks::Block>, MissionError> {
    let zones: Vec<fence::LocalZone> = fence.zones.iter().map(|z| z.local(origin)).collect();
    let mut out: Vec<blocks::Block> = Vec::with_capacity(raw.len());
    for b in raw {
        let what = format!("block {:?}", b.name);
        if b.name.trim().is_empty() {
            return Err(MissionError::invalid(file, b.place, "block name is empty"));
        }
        if out.iter().any(|o| o.name == b.name) {
            return Err(MissionError::invalid(
                file,
                b.place,
                format!("{what}: duplicate name (block names must be unique)"),
            ));
        }
        if b.len < 2 {
            return Err(MissionError::invalid(
                file,
                b.place,
                format!(
                    "{what}: {} waypoint(s) (a block needs at least 2, flown whole from one \
                     end to the other)",
                    b.len
                ),
            ));
        }
        if b.first + b.len > waypoints.len() {
            return Err(MissionError::invalid(
                file,
                b.place,
                format!(
                    "{what}: waypoints {}..{} of a mission of {} (out of range)",
                    b.first + 1,
                    b.first + b.len,
                    waypoints.len()
                ),
            ));
        }
        let block = blocks::Block {
            name: b.name,
            kind: b.kind,
            first: b.first,
            len: b.len,
            reversible: b.reversible,
            source: b.source,
        };
        if let Some(other) = out
            .iter()
            .find(|o| block.waypoints().any(|k| o.contains(k)))
        {
            return Err(MissionError::invalid(
                file,
                b.place,
                format!(
                    "{what}: shares waypoints with block {:?} (a waypoint belongs to one block \
                     at most)",
                    other.name
                ),
            ));
        }
        for k in block.first..block.first + block.len - 1 {
            let (u, v) = (&waypoints[k], &waypoints[k + 1]);
            let a = [u.position.x_east_m, u.position.y_north_m];
            let c = [v.position.x_east_m, v.position.y_north_m];
            if let Some(z) = zones.iter().position(|z| z.segment_violates(a, c, 0.0)) {
                let zone = &fence.zones[z];
                let how = if zone.inclusion { "leaves" } else { "crosses" };
                return Err(MissionError::invalid(
                    file,
                    b.place,
                    format!(
                        "{what}: its line {:?}-{:?} {how} {} of the geofence (a block is flown \
                         as written, so the planner cannot detour round the zone inside it)",
                        u.name,
                        v.name,
                        zone.describe(z + 1)
                    ),
                ));
            }
        }
        out.push(block);
    }
    Ok(out)
}

/// The error of a point that breaks zone `k` of the fence (0-based): inside an exclusion zone
/// or outside an inclusion zone.
fn breaks(file: &str, place: Place, what: &str, zone: &fence::Zone, k: usize) -> MissionError {
    let (lies, rule) = if zone.inclusion {
        ("outside", "inside every inclusion zone")
    } else {
        ("inside", "outside every exclusion zone")
    };
    MissionError::invalid(
        file,
        place,
        format!(
            "{what} lies {lies} {} of the geofence (it must be {rule})",
            zone.describe(k + 1)
        ),
    )
}

/// Checks every zone (polygons of at least 3 vertices in range that do not cross themselves,
/// circles of a positive radius round a valid centre) and the breach return point, and
/// returns the fence.
fn check_fence(
    file: &str,
    origin: &Origin,
    zones: Vec<RawZone>,
    breach_return: Option<(Geodetic, Place)>,
) -> Result<fence::Fence, MissionError> {
    for (k, raw) in zones.iter().enumerate() {
        let what = raw.zone.describe(k + 1);
        match &raw.zone.shape {
            fence::Shape::Polygon(vertices) => {
                if vertices.len() < 3 {
                    return Err(MissionError::invalid(
                        file,
                        raw.place.clone(),
                        format!(
                            "{what}: {} vertices (a polygon needs at least 3)",
                            vertices.len()
                        ),
                    ));
                }
                for (i, v) in vertices.iter().enumerate() {
                    let (place, named) = raw.vertex(i);
                    check_lat_lon(
                        file,
                        &place,
                        &format!("{what}{named}"),
                        v.lat_deg,
                        v.lon_deg,
                    )?;
                }
                if let Some((i, j)) = raw.zone.local(origin).crossing_edges() {
                    let n = vertices.len();
                    let key = raw.vertices_key;
                    return Err(MissionError::invalid(
                        file,
                        raw.place.clone(),
                        format!(
                            "{what}: its edge {key}[{i}]-{key}[{}] crosses its edge \
                             {key}[{j}]-{key}[{}] (a fence polygon must not cross itself)",
                            (i + 1) % n,
                            (j + 1) % n
                        ),
                    ));
                }
            }
            fence::Shape::Circle { center, radius_m } => {
                check_lat_lon(
                    file,
                    &raw.place,
                    &format!("{what} center"),
                    center.lat_deg,
                    center.lon_deg,
                )?;
                if !(radius_m.is_finite() && *radius_m > 0.0) {
                    return Err(MissionError::invalid(
                        file,
                        raw.place.clone(),
                        format!(
                            "{what}: radius_m {radius_m} is not allowed (a positive number is \
                             required)"
                        ),
                    ));
                }
            }
        }
    }
    let breach_return = match breach_return {
        Some((g, place)) => {
            check_lat_lon(file, &place, "breach return", g.lat_deg, g.lon_deg)?;
            finite(file, &place, "breach return alt_above_home_m", g.alt_m)?;
            Some(g)
        }
        None => None,
    };
    Ok(fence::Fence {
        zones: zones.into_iter().map(|raw| raw.zone).collect(),
        breach_return,
    })
}

/// Checks every rally point (a valid, finite position that keeps the fence) and returns them.
fn check_rally(
    file: &str,
    origin: &Origin,
    fence: &fence::Fence,
    rally: Vec<(fence::RallyPoint, Place)>,
) -> Result<Vec<fence::RallyPoint>, MissionError> {
    let mut out = Vec::with_capacity(rally.len());
    for (k, (r, place)) in rally.into_iter().enumerate() {
        let what = format!("rally point {}", k + 1);
        check_lat_lon(file, &place, &what, r.lat_deg, r.lon_deg)?;
        finite(
            file,
            &place,
            &format!("{what} alt_above_home_m"),
            r.alt_above_home_m,
        )?;
        let p = r.local(origin);
        if let Some(z) = fence.zone_broken_by(origin, [p.x_east_m, p.y_north_m]) {
            return Err(breaks(file, place, &what, &fence.zones[z], z));
        }
        out.push(r);
    }
    Ok(out)
}

/// Checks each action (a take-able command, finite or empty parameters, a valid position where
/// it has one, a hold that can be priced) and returns them without their places.
fn check_actions(
    file: &str,
    what: &str,
    commands: Vec<(actions::Command, Place)>,
) -> Result<Vec<actions::Command>, MissionError> {
    commands
        .into_iter()
        .map(|(c, place)| {
            let name = format!("{what}: command {} ({})", c.command, c.describe());
            if let actions::Taken::Refused(why) = actions::take(c.command) {
                return Err(MissionError::invalid(
                    file,
                    place,
                    format!("command {} is not supported: {why}", c.command),
                ));
            }
            for (k, v) in c.params.iter().enumerate() {
                if v.is_infinite() {
                    return Err(MissionError::invalid(
                        file,
                        place,
                        format!(
                            "{name}: param{} is {v} (a finite number or empty is required)",
                            k + 1
                        ),
                    ));
                }
            }
            if c.has_position() {
                check_lat_lon(file, &place, &name, c.params[4], c.params[5])?;
            }
            if c.command == actions::id::NAV_DELAY && (c.params[0].is_nan() || c.params[0] < 0.0) {
                return Err(MissionError::invalid(
                    file,
                    place,
                    format!(
                        "{name}: a delay of {} s (until a time of day) cannot be priced or \
                         reordered (allowed: a delay of 0 s or more in param1)",
                        c.params[0]
                    ),
                ));
            }
            Ok(c)
        })
        .collect()
}

impl Mission {
    /// Why this mission cannot be written as the `.waypoints` file `file` (QGC WPL 110 holds
    /// mission items only; fence and rally items go up as their own MAVLink mission types): it
    /// carries a geofence or rally points, which would be lost. None when it can.
    pub fn cannot_be_wpl(&self, file: &str) -> Option<MissionError> {
        let fence = !self.fence.is_empty() || self.fence.breach_return.is_some();
        if !fence && self.rally.is_empty() {
            return None;
        }
        let mut carried = Vec::new();
        if fence {
            carried.push(format!("a geofence ({})", self.fence.summary()));
        }
        if !self.rally.is_empty() {
            carried.push(fence::rally_summary(&self.rally));
        }
        Some(MissionError::invalid(
            file,
            Place::File,
            format!(
                "a .waypoints file (QGC WPL 110) cannot hold {}, which mission {} carries; \
                 nothing written (write a .plan or .toml to keep them)",
                carried.join(" or "),
                self.name
            ),
        ))
    }

    /// Why this mission cannot be written as the `.waypoints` file `file` without losing its
    /// blocks (QGC WPL 110 has no complex items: a block would become free points), naming
    /// them. None when it has none.
    pub fn blocks_cannot_be_wpl(&self, file: &str) -> Option<MissionError> {
        if self.blocks.is_empty() {
            return None;
        }
        let named: Vec<String> = self
            .blocks
            .iter()
            .map(|b| {
                format!(
                    "block {:?} ({}, {} waypoints)",
                    b.name,
                    b.kind.word(),
                    b.len
                )
            })
            .collect();
        Some(MissionError::invalid(
            file,
            Place::File,
            format!(
                "a .waypoints file (QGC WPL 110) cannot hold {}, which mission {} carries; \
                 nothing written (write a .plan or .toml to keep them, or convert with --lossy \
                 to write the waypoints without the blocks)",
                named.join(", "),
                self.name
            ),
        ))
    }

    /// "fence: 1 inclusion polygon (7 vertices), 1 exclusion polygon (4 vertices); 1 rally
    /// point": what the mission carries besides its waypoints, in one line (None when it
    /// carries neither a fence nor rally points).
    pub fn fence_line(&self) -> Option<String> {
        let fence = !self.fence.is_empty() || self.fence.breach_return.is_some();
        if !fence && self.rally.is_empty() {
            return None;
        }
        let rally = if self.rally.is_empty() {
            "no rally point".to_string()
        } else {
            fence::rally_summary(&self.rally)
        };
        Some(format!("fence: {}; {rally}", self.fence.summary()))
    }

    /// Every command kept verbatim that emplan does not understand, with the waypoint it
    /// follows (None: the start), for the one warning that lists them.
    pub fn unknown_commands(&self) -> Vec<(Option<&str>, &actions::Command)> {
        let unknown = |c: &&actions::Command| actions::take(c.command) == actions::Taken::Unknown;
        self.start_actions
            .iter()
            .filter(unknown)
            .map(|c| (None, c))
            .chain(self.waypoints.iter().flat_map(|w| {
                w.actions
                    .iter()
                    .filter(unknown)
                    .map(move |c| (Some(w.name.as_str()), c))
            }))
            .collect()
    }

    /// The one warning that lists the commands kept verbatim that emplan does not understand
    /// (None when there are none).
    pub fn unknown_warning(&self) -> Option<String> {
        let unknown = self.unknown_commands();
        if unknown.is_empty() {
            return None;
        }
        let listed: Vec<String> = unknown
            .iter()
            .map(|(at, c)| format!("{} after {}", c.command, at.unwrap_or("the take-off")))
            .collect();
        Some(format!(
            "mission {}: emplan keeps {} command(s) it does not understand with their waypoints, \
             unpriced: {}",
            self.name,
            unknown.len(),
            listed.join(", ")
        ))
    }

    /// Whether any waypoint or the start carries actions.
    pub fn has_actions(&self) -> bool {
        !self.start_actions.is_empty() || self.waypoints.iter().any(|w| !w.actions.is_empty())
    }

    /// The states the file's order leaves in force ([`actions::file_states`]).
    pub fn file_states(&self) -> actions::FileStates {
        actions::file_states(
            &self.start_actions,
            self.waypoints.iter().map(|w| w.actions.as_slice()),
        )
    }

    /// The horizontal speed in force on the way to each waypoint in the file's order (None: the
    /// vehicle's own), and on the way home: what every order flies, since emplan restores it.
    pub fn speeds_m_s(&self) -> (Vec<Option<f64>>, Option<f64>) {
        let states = self.file_states();
        (
            states
                .before
                .iter()
                .map(actions::State::speed_m_s)
                .collect(),
            states.end.speed_m_s(),
        )
    }

    /// The commands to insert so that `order` flies each waypoint in the file's state
    /// ([`actions::restore`]).
    pub fn restoring(
        &self,
        order: &[usize],
        default_speed_m_s: Option<f64>,
    ) -> Vec<Vec<(actions::Setting, actions::Command)>> {
        let states = self.file_states();
        let start = actions::State::default().after(&self.start_actions);
        let refs: Vec<&[actions::Command]> = self
            .waypoints
            .iter()
            .map(|w| w.actions.as_slice())
            .collect();
        actions::restore(&states, &start, &refs, order, default_speed_m_s)
    }

    /// The mission of the waypoints `kept` (indices, in file order) alone, each in the state
    /// the whole file has there: the commands that would have changed a setting at a waypoint
    /// left out are carried, as restoring commands, by the waypoint before it (the start
    /// before the first), so a resume or any subset flies what remains as the file does. A
    /// block keeps the waypoints of it that remain when they still follow each other (at least
    /// two); otherwise what is left of it is flown as points.
    pub fn keeping(&self, kept: &[usize]) -> Mission {
        let inserted = self.restoring(kept, None);
        let commands = |i: usize| {
            inserted
                .get(i)
                .into_iter()
                .flatten()
                .map(|(_, c)| c.clone())
                .collect::<Vec<_>>()
        };
        let mut start_actions = self.start_actions.clone();
        start_actions.extend(commands(0));
        let waypoints = kept
            .iter()
            .enumerate()
            .filter_map(|(i, &k)| {
                let mut w = self.waypoints.get(k)?.clone();
                w.actions.extend(commands(i + 1));
                Some(w)
            })
            .collect();
        let blocks = self
            .blocks
            .iter()
            .filter_map(|b| {
                let at: Vec<usize> = (0..kept.len()).filter(|&i| b.contains(kept[i])).collect();
                let follow = at
                    .windows(2)
                    .all(|w| w[1] == w[0] + 1 && kept[w[1]] == kept[w[0]] + 1);
                (at.len() >= 2 && follow).then(|| blocks::Block {
                    first: at[0],
                    len: at.len(),
                    ..b.clone()
                })
            })
            .collect();
        Mission {
            waypoints,
            start_actions,
            blocks,
            ..self.clone()
        }
    }

    /// Geodetic position of waypoint `k`, with altitude above home (MAVLink's relative frame).
    pub fn waypoint_relative(&self, k: usize) -> Option<(f64, f64, f64)> {
        let w = self.waypoints.get(k)?;
        let g = self.origin.to_geodetic(w.position);
        Some((g.lat_deg, g.lon_deg, g.alt_m - self.origin.home.alt_m))
    }
}
