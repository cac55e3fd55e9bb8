//! emplan's own mission format (TOML), documented in docs/mission-files.md. Unknown keys are errors;
//! every error names its line.

use serde::{Deserialize, Serialize};
use toml::Spanned;

use super::{
    line_of, Enu, Geodetic, Mission, MissionError, Place, RawMission, RawPosition, RawWaypoint,
    DEFAULT_MIN_HEIGHT_ABOVE_HOME_M,
};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileMission {
    name: Option<String>,
    default_hover_s: Option<f64>,
    min_height_above_home_m: Option<f64>,
    origin: Spanned<FileOrigin>,
    #[serde(default)]
    waypoints: Vec<Spanned<FileWaypoint>>,
}

#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct FileOrigin {
    lat_deg: f64,
    lon_deg: f64,
    home_alt_amsl_m: f64,
    height_above_home_m: f64,
}

#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct FileWaypoint {
    name: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    x_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    y_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    z_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    lat_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    lon_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    alt_above_home_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    hover_s: Option<f64>,
}

pub(super) fn parse(text: &str, file: &str) -> Result<RawMission, MissionError> {
    let parsed: FileMission = toml::from_str(text).map_err(|e| {
        let place = e
            .span()
            .map_or(Place::File, |s| Place::Line(line_of(text, s.start)));
        MissionError::invalid(file, place, e.message().trim().to_string())
    })?;
    let origin_place = Place::Line(line_of(text, parsed.origin.span().start));
    let origin = parsed.origin.into_inner();
    let mut waypoints = Vec::with_capacity(parsed.waypoints.len());
    for spanned in parsed.waypoints {
        let place = Place::Line(line_of(text, spanned.span().start));
        let w = spanned.into_inner();
        let what = format!("waypoint {:?}", w.name);
        let enu = [w.x_m, w.y_m, w.z_m];
        let geo = [w.lat_deg, w.lon_deg, w.alt_above_home_m];
        let position = match (enu, geo) {
            ([Some(x), Some(y), Some(z)], [None, None, None]) => RawPosition::Enu(Enu {
                x_east_m: x,
                y_north_m: y,
                z_up_m: z,
            }),
            ([None, None, None], [Some(lat_deg), Some(lon_deg), Some(alt_above_home_m)]) => {
                RawPosition::Geodetic {
                    lat_deg,
                    lon_deg,
                    alt_above_home_m,
                }
            }
            _ => {
                let given: Vec<&str> = [
                    "x_m",
                    "y_m",
                    "z_m",
                    "lat_deg",
                    "lon_deg",
                    "alt_above_home_m",
                ]
                .into_iter()
                .zip(enu.iter().chain(geo.iter()))
                .filter(|(_, v)| v.is_some())
                .map(|(k, _)| k)
                .collect();
                return Err(MissionError::invalid(
                    file,
                    place,
                    format!(
                        "{what}: position needs exactly one of (x_m, y_m, z_m) or \
                         (lat_deg, lon_deg, alt_above_home_m); given: [{}]",
                        given.join(", ")
                    ),
                ));
            }
        };
        waypoints.push(RawWaypoint {
            name: w.name,
            position,
            hover_s: w.hover_s,
            place,
        });
    }
    Ok(RawMission {
        name: parsed.name.unwrap_or_else(|| "mission".to_string()),
        home: Geodetic {
            lat_deg: origin.lat_deg,
            lon_deg: origin.lon_deg,
            alt_m: origin.home_alt_amsl_m,
        },
        height_above_home_m: origin.height_above_home_m,
        default_hover_s: parsed.default_hover_s.unwrap_or(0.0),
        min_height_above_home_m: parsed
            .min_height_above_home_m
            .unwrap_or(DEFAULT_MIN_HEIGHT_ABOVE_HOME_M),
        waypoints,
        place: origin_place,
    })
}

#[derive(Serialize)]
struct WriteMission<'a> {
    name: &'a str,
    default_hover_s: f64,
    min_height_above_home_m: f64,
    origin: FileOrigin,
    waypoints: Vec<FileWaypoint>,
}

/// The mission as emplan TOML, waypoints in local ENU metres (full precision).
pub(super) fn write(mission: &Mission) -> Result<String, MissionError> {
    let doc = WriteMission {
        name: &mission.name,
        default_hover_s: mission.default_hover_s,
        min_height_above_home_m: mission.min_height_above_home_m,
        origin: FileOrigin {
            lat_deg: mission.origin.home.lat_deg,
            lon_deg: mission.origin.home.lon_deg,
            home_alt_amsl_m: mission.origin.home.alt_m,
            height_above_home_m: mission.origin.height_above_home_m,
        },
        waypoints: mission
            .waypoints
            .iter()
            .map(|w| FileWaypoint {
                name: w.name.clone(),
                x_m: Some(w.position.x_east_m),
                y_m: Some(w.position.y_north_m),
                z_m: Some(w.position.z_up_m),
                lat_deg: None,
                lon_deg: None,
                alt_above_home_m: None,
                hover_s: Some(w.hover_s),
            })
            .collect(),
    };
    toml::to_string(&doc).map_err(|e| {
        MissionError::invalid(
            &mission.name,
            Place::File,
            format!("cannot be written as TOML: {e}"),
        )
    })
}
