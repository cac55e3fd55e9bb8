//! The trajectory parameters a PX4 or an ArduPilot really flies with: read from the autopilot by
//! name when connected, compared with the vehicle file's `[px4]` or `[ardupilot]` section (a real
//! octorotor's autopilot is rarely at defaults), and the vehicle as the autopilot will fly it, for
//! pricing the flight with the autopilot's values.

use crate::link::commands::read_params;
use crate::link::connection::{Autopilot, Link};
use crate::link::LinkError;
use crate::physics::vehicle::ParamDifference;
use crate::physics::Vehicle;

/// Which vehicle-file section the parameters checked are: the autopilot's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamSection {
    /// `[px4]`, read from a PX4.
    Px4,
    /// `[ardupilot]`, read from an ArduPilot.
    Ardupilot,
}

impl ParamSection {
    /// The autopilot's name, as warnings say it.
    pub fn autopilot(self) -> &'static str {
        match self {
            ParamSection::Px4 => "PX4",
            ParamSection::Ardupilot => "ArduPilot",
        }
    }

    /// The vehicle file's section name.
    pub fn section(self) -> &'static str {
        match self {
            ParamSection::Px4 => "px4",
            ParamSection::Ardupilot => "ardupilot",
        }
    }
}

/// What the autopilot holds against what the vehicle file says.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamCheck {
    /// Whose parameters these are.
    pub section: ParamSection,
    /// Every parameter asked for, with its value (None: not answered).
    pub read: Vec<(String, Option<f64>)>,
    /// The ones that differ from the vehicle file.
    pub differences: Vec<ParamDifference>,
    /// The vehicle with the autopilot's values in its `[px4]` or `[ardupilot]` section.
    pub vehicle: Vehicle,
}

impl ParamCheck {
    /// The names asked for that the autopilot never answered.
    pub fn unanswered(&self) -> Vec<&str> {
        self.read
            .iter()
            .filter(|(_, v)| v.is_none())
            .map(|(n, _)| n.as_str())
            .collect()
    }

    /// The one-line warning of a log (the service's) when the autopilot holds other values than
    /// the vehicle file, naming the autopilot and each parameter (None when none differs).
    pub fn warning(&self) -> Option<String> {
        if self.differences.is_empty() {
            return None;
        }
        let differing: Vec<String> = (self.differences.iter())
            .map(|d| format!("{} {} for {}", d.name, d.autopilot_value, d.file_value))
            .collect();
        Some(format!(
            "{} holds other trajectory parameters than the vehicle file ({}): the flight is \
             measured against its legs simulated with them",
            self.section.autopilot(),
            differing.join(", ")
        ))
    }
}

/// A parameter that differs, as `px4_parameters` lists it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DifferingJson {
    pub name: String,
    pub vehicle_file: f64,
    pub autopilot: f64,
}

/// `px4_parameters` (and `ardupilot_parameters`) of `fly --json` and of the service's upload
/// answer: how many parameters the autopilot answered, the ones it did not, and the ones that
/// differ from the vehicle file.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Px4Parameters {
    pub read: usize,
    pub unanswered: Vec<String>,
    pub differing: Vec<DifferingJson>,
}

impl From<&ParamCheck> for Px4Parameters {
    fn from(check: &ParamCheck) -> Px4Parameters {
        Px4Parameters {
            read: check.read.iter().filter(|(_, v)| v.is_some()).count(),
            unanswered: check.unanswered().into_iter().map(String::from).collect(),
            differing: check
                .differences
                .iter()
                .map(|d| DifferingJson {
                    name: d.name.to_string(),
                    vehicle_file: d.file_value,
                    autopilot: d.autopilot_value,
                })
                .collect(),
        }
    }
}

/// Why a `NAME=VALUE` parameter setting does not read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamSyntax {
    #[error("{0}: NAME=VALUE expected")]
    NoEquals(String),
    #[error("{0}: the value is not a number")]
    NotANumber(String),
}

/// A `NAME=VALUE` parameter setting (`MPC_XY_CRUISE=8`).
pub fn parse_param(pair: &str) -> Result<(String, f64), ParamSyntax> {
    let (name, value) = pair
        .split_once('=')
        .ok_or_else(|| ParamSyntax::NoEquals(pair.to_string()))?;
    let value: f64 = value
        .trim()
        .parse()
        .map_err(|_| ParamSyntax::NotANumber(pair.to_string()))?;
    Ok((name.trim().to_string(), value))
}

/// Reads the `[px4]` trajectory parameters from `target` and compares them with `vehicle`'s.
pub async fn check_px4_params(
    link: &Link,
    target: &Autopilot,
    vehicle: &Vehicle,
) -> Result<ParamCheck, LinkError> {
    let names: Vec<&str> = vehicle
        .px4
        .autopilot_values()
        .into_iter()
        .map(|(n, _)| n)
        .collect();
    let read = read_params(link, target, &names).await?;
    let differences = vehicle.px4.differences(&read);
    let answered: Vec<(String, f64)> = read
        .iter()
        .filter_map(|(n, v)| v.map(|v| (n.clone(), v)))
        .collect();
    let mut flown = vehicle.clone();
    flown.px4 = vehicle.px4.with_autopilot_values(&answered);
    Ok(ParamCheck {
        section: ParamSection::Px4,
        read,
        differences,
        vehicle: flown,
    })
}

/// Reads the `[ardupilot]` navigation parameters from `target` (ArduCopter's names) and compares
/// them with `vehicle`'s.
pub async fn check_ardupilot_params(
    link: &Link,
    target: &Autopilot,
    vehicle: &Vehicle,
) -> Result<ParamCheck, LinkError> {
    let names: Vec<&str> = vehicle
        .ardupilot
        .autopilot_values()
        .into_iter()
        .map(|(n, _)| n)
        .collect();
    let read = read_params(link, target, &names).await?;
    let differences = vehicle.ardupilot.differences(&read);
    let answered: Vec<(String, f64)> = read
        .iter()
        .filter_map(|(n, v)| v.map(|v| (n.clone(), v)))
        .collect();
    let mut flown = vehicle.clone();
    flown.ardupilot = vehicle.ardupilot.with_autopilot_values(&answered);
    Ok(ParamCheck {
        section: ParamSection::Ardupilot,
        read,
        differences,
        vehicle: flown,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(
        section: ParamSection,
        vehicle: &Vehicle,
        read: Vec<(String, Option<f64>)>,
    ) -> ParamCheck {
        let differences = match section {
            ParamSection::Px4 => vehicle.px4.differences(&read),
            ParamSection::Ardupilot => vehicle.ardupilot.differences(&read),
        };
        ParamCheck {
            section,
            read,
            differences,
            vehicle: vehicle.clone(),
        }
    }

    #[test]
    fn the_warning_of_other_parameters_names_the_autopilot_that_holds_them() {
        let vehicle = crate::physics::builtin::vehicle().expect("the built-in vehicle");
        for (section, values) in [
            (ParamSection::Px4, vehicle.px4.autopilot_values()),
            (
                ParamSection::Ardupilot,
                vehicle.ardupilot.autopilot_values(),
            ),
        ] {
            let (name, value) = values[0];
            let same = vec![(name.to_string(), Some(value))];
            assert_eq!(check(section, &vehicle, same).warning(), None);
            let other = vec![(name.to_string(), Some(value + 1.0))];
            let warning = check(section, &vehicle, other)
                .warning()
                .expect("a warning");
            let autopilot = section.autopilot();
            assert!(
                warning.starts_with(&format!("{autopilot} holds other trajectory parameters")),
                "{warning}"
            );
            assert!(
                warning.contains(&format!("{name} {}", value + 1.0)),
                "{warning}"
            );
            let wrong = match section {
                ParamSection::Px4 => "ArduPilot",
                ParamSection::Ardupilot => "PX4",
            };
            assert!(!warning.contains(wrong), "{warning}");
        }
    }
}
