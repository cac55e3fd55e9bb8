//! Waypoint missions: the in-memory model, file formats (emplan TOML, QGroundControl `.plan`,
//! `QGC WPL 110` `.waypoints`), validation with located errors, and WGS84 <-> local ENU geodesy.
//!
//! Invariant: pure apart from reading and writing the one file it is asked to; never panics on
//! input; every error names the file and the line or field at fault.

pub mod geodesy;

use std::path::PathBuf;

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
