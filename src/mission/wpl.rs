//! `QGC WPL 110` text missions (`.waypoints`, `.txt`) as Mission Planner, MAVProxy and QGC write
//! them (docs/mission-files.md): a header line, then one item per line with 12
//! fields `seq current frame command p1 p2 p3 p4 lat lon alt autocontinue`; the first item is
//! home (AMSL altitude). Read: any whitespace, `#` comments and blank lines allowed. Write: tabs,
//! 10 decimals for degrees (about 0.01 mm). Names are not stored: imported waypoints are WP1..WPn.

use super::actions::Command;
use super::qgc_plan::{NAV_RETURN_TO_LAUNCH, NAV_TAKEOFF, NAV_WAYPOINT};
use super::sequence::{self, Item};
use super::{
    Geodetic, Mission, MissionError, Place, RawMission, DEFAULT_MIN_HEIGHT_ABOVE_HOME_M,
    DEFAULT_TAKEOFF_HEIGHT_M,
};

const HEADER: &str = "QGC WPL 110";
const COLUMNS: [&str; 12] = [
    "seq",
    "current",
    "frame",
    "command",
    "param1",
    "param2",
    "param3",
    "param4",
    "latitude",
    "longitude",
    "altitude",
    "autocontinue",
];

/// Why a first line `line` is not the header: what was expected, and what the line looks like
/// (a `.txt` file may hold another format than Mission Planner's).
fn not_a_header(line: &str) -> String {
    const SHOWN_CHARS: usize = 40;
    let shown: String = line.chars().take(SHOWN_CHARS).collect();
    let cut = if line.chars().count() > SHOWN_CHARS {
        "..."
    } else {
        ""
    };
    let looks = if line.starts_with("QGC WPL") {
        " (another version of the format, not supported: only 110 is read)"
    } else if line.starts_with('{') {
        " (JSON: a QGroundControl .plan? name it .plan)"
    } else if line.starts_with('[') || line.contains(" = ") {
        " (TOML: an emplan mission? name it .toml)"
    } else {
        ""
    };
    let found = format!("{shown}{cut}");
    format!(
        "expected the QGroundControl waypoint file header {HEADER:?} (read as a .waypoints \
         mission, as .txt files are), found {found:?}{looks}"
    )
}

pub(super) fn parse(text: &str, file: &str, stem: &str) -> Result<RawMission, MissionError> {
    let bad =
        |line: usize, problem: String| MissionError::invalid(file, Place::Line(line), problem);
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    match lines.next() {
        Some((_, l)) if l == HEADER => {}
        Some((n, l)) => return Err(bad(n, not_a_header(l))),
        None => {
            return Err(MissionError::invalid(
                file,
                Place::File,
                format!("empty file (expected the header {HEADER:?} and a home line)"),
            ))
        }
    }
    let mut home: Option<Geodetic> = None;
    let mut items = Vec::new();
    for (n, line) in lines {
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.len() != COLUMNS.len() {
            return Err(bad(
                n,
                format!(
                    "{} columns found, 12 expected ({})",
                    fields.len(),
                    COLUMNS.join(" ")
                ),
            ));
        }
        let mut values = [0.0f64; 12];
        for (c, (field, value)) in fields.iter().zip(values.iter_mut()).enumerate() {
            *value = field.parse::<f64>().map_err(|_| {
                bad(
                    n,
                    format!(
                        "column {} ({}): {field:?} is not a number",
                        c + 1,
                        COLUMNS[c]
                    ),
                )
            })?;
        }
        let integer = |c: usize| -> Result<u64, MissionError> {
            let v = values[c];
            if v >= 0.0 && v.fract() == 0.0 && v < 1e9 {
                Ok(v as u64)
            } else {
                Err(bad(
                    n,
                    format!(
                        "column {} ({}): {v} is not a non-negative integer",
                        c + 1,
                        COLUMNS[c]
                    ),
                ))
            }
        };
        let (command, frame) = (integer(3)?, integer(2)?);
        let Some(_) = home else {
            // The first item is home: latitude, longitude, altitude above mean sea level.
            home = Some(Geodetic {
                lat_deg: values[8],
                lon_deg: values[9],
                alt_m: values[10],
            });
            continue;
        };
        let params = [
            values[4], values[5], values[6], values[7], values[8], values[9], values[10],
        ];
        items.push(Item {
            command,
            frame,
            params,
            place: Place::Line(n),
            group: None,
        });
    }
    let home = home.ok_or_else(|| {
        MissionError::invalid(
            file,
            Place::File,
            "no home line (the first item must be home)",
        )
    })?;
    let mut seq = sequence::read(file, items, home.alt_m)?;
    for (i, w) in seq.waypoints.iter_mut().enumerate() {
        w.name = format!("WP{}", i + 1);
    }
    Ok(RawMission {
        blocks: Vec::new(),
        name: stem.to_string(),
        home,
        height_above_home_m: seq.height_above_home_m.unwrap_or(DEFAULT_TAKEOFF_HEIGHT_M),
        default_hover_s: 0.0,
        min_height_above_home_m: DEFAULT_MIN_HEIGHT_ABOVE_HOME_M,
        waypoints: seq.waypoints,
        start_actions: seq.start_actions,
        pois: Vec::new(),
        zones: Vec::new(),
        breach_return: None,
        rally: Vec::new(),
        place: Place::File,
    })
}

fn row(seq: usize, frame: u64, command: u64, p1: f64, lat: f64, lon: f64, alt: f64) -> String {
    full_row(seq, frame, command, [p1, 0.0, 0.0, 0.0, lat, lon, alt])
}

/// A parameter as Mission Planner writes it (NaN as `nan`, which it reads back).
fn param(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else {
        format!("{v}")
    }
}

fn full_row(seq: usize, frame: u64, command: u64, p: [f64; 7]) -> String {
    format!(
        "{seq}\t{}\t{frame}\t{command}\t{}\t{}\t{}\t{}\t{:.10}\t{:.10}\t{:.4}\t1\n",
        u8::from(seq == 0),
        param(p[0]),
        param(p[1]),
        param(p[2]),
        param(p[3]),
        p[4],
        p[5],
        p[6],
    )
}

fn command_row(seq: usize, c: &Command) -> String {
    full_row(seq, u64::from(c.frame), u64::from(c.command), c.params)
}

/// The mission as `QGC WPL 110`: home, take-off to the origin, the waypoints, return to launch.
pub(super) fn write(mission: &Mission) -> String {
    let home = mission.origin.home;
    let mut text = format!("{HEADER}\n");
    text += &row(
        0,
        0,
        NAV_WAYPOINT,
        0.0,
        home.lat_deg,
        home.lon_deg,
        home.alt_m,
    );
    text += &row(
        1,
        3,
        NAV_TAKEOFF,
        0.0,
        home.lat_deg,
        home.lon_deg,
        mission.origin.height_above_home_m,
    );
    let mut seq = 2;
    for c in &mission.start_actions {
        text += &command_row(seq, c);
        seq += 1;
    }
    for w in &mission.waypoints {
        let g = mission.origin.to_geodetic(w.position);
        let [p2, p3, p4] = match w.kind {
            super::WaypointKind::LoiterTime { params } => params,
            _ => [0.0; 3],
        };
        text += &full_row(
            seq,
            3,
            u64::from(w.kind.command()),
            [
                w.hover_s,
                p2,
                p3,
                p4,
                g.lat_deg,
                g.lon_deg,
                g.alt_m - home.alt_m,
            ],
        );
        seq += 1;
        for c in &w.actions {
            text += &command_row(seq, c);
            seq += 1;
        }
    }
    text += &row(seq, 2, NAV_RETURN_TO_LAUNCH, 0.0, 0.0, 0.0, 0.0);
    text
}
