//! The flight controller's own logs: PX4 ULog (`.ulg`, [`ulog`]) and ArduPilot DataFlash (`.bin`,
//! [`dataflash`]) read into the same stamped readings a `.tlog` replay gives, so segmentation,
//! energy, flags and reports are the code that measures a recorded flight. A log is told by its
//! first bytes, not its name. A torn file (power cut mid-flight) gives what it held up to the tear
//! and says where it tore; a log without battery current, position or mission progress is refused
//! naming what is missing.

use std::path::Path;

use super::telemetry::{Reading, Stamped};

pub mod dataflash;
pub mod ulog;

/// Which onboard format a log is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Ulog,
    Dataflash,
}

impl Format {
    /// The report's `source`: `ulog` or `dataflash` (a `.tlog` is `tlog`).
    pub fn name(self) -> &'static str {
        match self {
            Format::Ulog => "ulog",
            Format::Dataflash => "dataflash",
        }
    }

    /// The format whose magic `head` (the file's first bytes) starts with.
    pub fn sniff(head: &[u8]) -> Option<Format> {
        if head.starts_with(ulog::MAGIC) {
            Some(Format::Ulog)
        } else if head.starts_with(dataflash::MAGIC) {
            Some(Format::Dataflash)
        } else {
            None
        }
    }
}

/// Where a log tore: the offset of its first incomplete or unreadable record.
#[derive(Debug, Clone, PartialEq)]
pub struct Tear {
    pub offset: u64,
    /// The log time (seconds, as the readings' `t_s`) of the last reading before it.
    pub after_s: Option<f64>,
    /// What was wrong there (`a record cut short`, `an unknown message id 212`, ...).
    pub reason: String,
}

/// A record read but refused as corrupt (a time that jumps, a battery sample no battery gives, a
/// format redescribing a message): skipped, and the flight measured as without it.
#[derive(Debug, Clone, PartialEq)]
pub struct Skipped {
    /// The record's byte offset and length.
    pub offset: u64,
    pub bytes: u64,
    /// The record's message (`BAT`, `PARM`, ...).
    pub record: String,
    /// Why it was refused (`its TimeUS jumps 4.6e12 s from the records around it`, ...).
    pub reason: String,
    /// The log time (seconds, as the readings' `t_s`) of the readings either side of it; None:
    /// none on that side.
    pub from_s: Option<f64>,
    pub to_s: Option<f64>,
}

/// One mission item as DataFlash's CMD records it (the whole mission is written at log start):
/// ArduPilot's stored item as MAVLink would send it back (`AP_Mission::mission_cmd_to_mavlink_int`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissionCommand {
    /// The item's place in the autopilot's mission (ArduPilot: 0 is home).
    pub seq: u16,
    /// MAV_CMD (`CId`).
    pub command: u16,
    /// MAV_FRAME (`Frame`) that `alt_m` is in: 0 GLOBAL, 3 GLOBAL_RELATIVE_ALT, 10
    /// GLOBAL_TERRAIN_ALT (ArduPilot stores no other).
    pub frame: u8,
    /// `Prm1`..`Prm4` as stored (ArduPilot keeps only what it uses: e.g. a waypoint's
    /// acceptance radius and yaw read 0).
    pub params: [f32; 4],
    /// Degrees (`Lat`, `Lng`, degE7 in the file); 0 for commands without a place.
    pub lat_deg: f64,
    pub lon_deg: f64,
    /// Metres in `frame`: above mean sea level for GLOBAL (item 0, home, is always this),
    /// above home for GLOBAL_RELATIVE_ALT, above terrain for GLOBAL_TERRAIN_ALT.
    pub alt_m: f64,
}

/// An onboard log read whole.
#[derive(Debug, Clone)]
pub struct OnboardLog {
    pub format: Format,
    /// The file as the user named it.
    pub file: String,
    pub bytes: u64,
    /// Every reading, in log time: `t_s` is seconds since the log's first timestamp (the
    /// autopilot's own clock), `wall_us` the same instant in microseconds.
    pub stamped: Vec<Stamped>,
    /// The mission the log itself holds (DataFlash's CMD records, in `seq` order); ULog holds
    /// only the current item: None.
    pub mission: Option<Vec<MissionCommand>>,
    /// Where the file tore, when it did: what came before is kept.
    pub tear: Option<Tear>,
    /// The records refused as corrupt, in file order.
    pub skipped: Vec<Skipped>,
}

impl OnboardLog {
    /// Battery readings per second of log (over the span from the first to the last of them).
    pub fn battery_rate_hz(&self) -> Option<f64> {
        let times: Vec<f64> = self
            .stamped
            .iter()
            .filter(|s| matches!(s.reading, Reading::Battery(_)))
            .map(|s| s.t_s)
            .collect();
        super::report::LogSource::of(self.format.name(), &times).battery_hz
    }

    /// Refuses a log that cannot measure a flight, naming what it lacks: a battery current,
    /// a position, or the mission's progress.
    pub fn check_measurable(&self) -> Result<(), OnboardError> {
        let has = |f: &dyn Fn(&Reading) -> bool| self.stamped.iter().any(|s| f(&s.reading));
        let missing = if !has(&|r| matches!(r, Reading::Battery(b) if b.current_a.is_some())) {
            Some("battery current")
        } else if !has(&|r| matches!(r, Reading::Position(_))) {
            Some("position")
        } else if !has(&|r| {
            matches!(
                r,
                Reading::MissionCurrent { .. } | Reading::ItemReached { .. }
            )
        }) {
            Some("mission progress")
        } else {
            None
        };
        match missing {
            Some(what) => Err(OnboardError::Missing {
                file: self.file.clone(),
                what,
            }),
            None => Ok(()),
        }
    }
}

/// Why an onboard log could not be read.
#[derive(Debug, thiserror::Error)]
pub enum OnboardError {
    #[error("{file}: {source}")]
    Io {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "{file}: neither a PX4 ULog nor an ArduPilot DataFlash log (its first bytes are {head})"
    )]
    UnknownFormat { file: String, head: String },
    #[error("{file}: byte {offset}: {reason}")]
    Malformed {
        file: String,
        offset: u64,
        reason: String,
    },
    #[error("{file}: the log has no {what}: it cannot measure a flight")]
    Missing { file: String, what: &'static str },
}

/// Whether `path` starts like an onboard log (for commands that take flight directories too).
pub fn is_onboard_log(path: &Path) -> bool {
    format_of(path).is_some()
}

/// The onboard format `path` starts like (None: not an onboard log, or unreadable).
pub fn format_of(path: &Path) -> Option<Format> {
    use std::io::Read;
    let mut head = [0u8; 16];
    let n = std::fs::File::open(path)
        .and_then(|mut f| f.read(&mut head))
        .ok()?;
    Format::sniff(&head[..n])
}

/// Reads the onboard log at `path`, of either format, told by its first bytes.
pub fn read(path: &Path) -> Result<OnboardLog, OnboardError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| OnboardError::Io {
        file: file.clone(),
        source,
    })?;
    parse(&file, &bytes)
}

/// Parses an onboard log held in memory; `file` names it in errors.
pub fn parse(file: &str, bytes: &[u8]) -> Result<OnboardLog, OnboardError> {
    match Format::sniff(bytes) {
        Some(Format::Ulog) => ulog::parse(file, bytes),
        Some(Format::Dataflash) => dataflash::parse(file, bytes),
        None => Err(OnboardError::UnknownFormat {
            file: file.to_string(),
            head: bytes
                .iter()
                .take(8)
                .map(|b| format!("{b:02x}"))
                .collect::<Vec<_>>()
                .join(" "),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::telemetry::{Battery, BatterySource, MissionState, Position};

    fn log(readings: Vec<Reading>) -> OnboardLog {
        OnboardLog {
            format: Format::Dataflash,
            file: "f.bin".into(),
            bytes: 0,
            stamped: (readings.into_iter().enumerate())
                .map(|(k, reading)| Stamped {
                    t_s: k as f64,
                    wall_us: 0,
                    reading,
                })
                .collect(),
            mission: None,
            tear: None,
            skipped: Vec::new(),
        }
    }

    fn battery(current_a: Option<f64>) -> Reading {
        Reading::Battery(Battery {
            source: BatterySource::BatteryStatus {
                id: 0,
                component: 1,
            },
            voltage_v: Some(24.0),
            current_a,
            consumed_mah: None,
            energy_consumed_j: None,
            remaining_pct: None,
            fake_current: false,
        })
    }

    fn position() -> Reading {
        Reading::Position(Position {
            time_boot_ms: 0,
            lat_deg: 38.5,
            lon_deg: -121.7,
            alt_amsl_m: 40.0,
            relative_alt_m: 24.0,
            vn_m_s: 0.0,
            ve_m_s: 0.0,
            vd_m_s: 0.0,
        })
    }

    fn progress() -> Reading {
        Reading::MissionCurrent {
            seq: 1,
            total: Some(4),
            state: MissionState::Active,
        }
    }

    #[test]
    fn a_log_that_cannot_measure_a_flight_is_refused_naming_what_it_lacks() {
        let missing = |readings| match log(readings).check_measurable() {
            Err(OnboardError::Missing { file, what }) => {
                assert_eq!(file, "f.bin");
                Some(what)
            }
            Err(other) => panic!("{other}"),
            Ok(()) => None,
        };
        let full = || vec![battery(Some(20.0)), position(), progress()];
        assert_eq!(missing(full()), None);
        let mut no_current = full();
        no_current[0] = battery(None);
        assert_eq!(missing(no_current), Some("battery current"));
        assert_eq!(
            missing(vec![battery(Some(20.0)), progress()]),
            Some("position")
        );
        assert_eq!(
            missing(vec![battery(Some(20.0)), position()]),
            Some("mission progress")
        );
        let message = log(vec![position()])
            .check_measurable()
            .unwrap_err()
            .to_string();
        assert_eq!(
            message,
            "f.bin: the log has no battery current: it cannot measure a flight"
        );
    }

    #[test]
    fn the_battery_rate_is_readings_per_second_of_log() {
        let l = log(vec![battery(Some(1.0)), position(), battery(Some(1.0))]);
        assert_eq!(l.battery_rate_hz(), Some(0.5));
        assert_eq!(log(vec![battery(Some(1.0))]).battery_rate_hz(), None);
    }
}
