//! The vehicle directory `calibrate --from-logs --out DIR` writes: the source vehicle.toml with
//! the fitted values put in place (every other line and comment kept; each fitted line's comment
//! says it was calibrated, against which logged flights, and what it was; the old comment's
//! continuation lines dropped), read back and checked, and the energy tables rebuilt for it with
//! `physics::table`'s build (the caller chooses which: `calibrate --from-logs` builds the
//! profile the flights were flown with); the tables are built before anything is written, so a
//! fit that cannot be written leaves nothing half-written; every file written through
//! `crate::output`.

use std::path::Path;

use super::{ErrorStats, Fitted, LogFitError};
use crate::output::Output;
use crate::physics::table::{DEFAULT_XF, DEFAULT_ZF};
use crate::physics::{EnergyTable, Profile, Vehicle};

/// The column of the comment on a line [`edit_vehicle_toml`] adds.
const NEW_KEY_COLUMN: usize = 37;

/// `text` (a vehicle.toml named `file` in errors) with each `section.key` of `values` set to its
/// value and its comment replaced by the note given; a key the section leaves out is added.
pub fn edit_vehicle_toml(
    text: &str,
    file: &str,
    values: &[(&str, f64, String)],
) -> Result<String, LogFitError> {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    for (path, value, note) in values {
        let (section, key) = path
            .split_once('.')
            .ok_or_else(|| LogFitError::VehicleFile {
                file: file.to_string(),
                reason: format!("{path}: not a section.key"),
            })?;
        let header = format!("[{section}]");
        let start = lines
            .iter()
            .position(|l| l.trim() == header)
            .ok_or_else(|| LogFitError::VehicleFile {
                file: file.to_string(),
                reason: format!("no {header} section"),
            })?;
        let section_lines = lines[start + 1..]
            .iter()
            .take_while(|l| !l.trim_start().starts_with('['))
            .count();
        let found = lines[start + 1..start + 1 + section_lines]
            .iter()
            .position(|l| {
                l.trim_start()
                    .strip_prefix(key)
                    .is_some_and(|rest| rest.trim_start().starts_with('='))
            })
            .map(|k| start + 1 + k);
        // A key the file leaves out (it reads its default: a file written before the key was
        // one) is added after the section's last line.
        let line = match found {
            Some(line) => line,
            None => {
                let last = lines[start + 1..start + 1 + section_lines]
                    .iter()
                    .rposition(|l| !l.trim().is_empty())
                    .map_or(start, |k| start + 1 + k);
                let placeholder = format!("{key} = 0");
                lines.insert(last + 1, format!("{placeholder:<NEW_KEY_COLUMN$}#"));
                last + 1
            }
        };
        // The comment stays in its column.
        let column = lines[line].find('#').unwrap_or(0);
        // Five significant digits, at least four decimals (0, of no magnitude, four).
        let magnitude = if *value == 0.0 {
            0.0
        } else {
            value.abs().log10().floor()
        };
        let decimals = (4.0 - magnitude).clamp(4.0, 9.0) as usize;
        let assignment = format!("{key} = {value:.decimals$}");
        let pad = column.saturating_sub(assignment.len()).max(1);
        lines[line] = format!("{assignment}{:pad$}# {note}", "");
        // The old comment's continuation: comment-only lines indented under it.
        let continued = lines[line + 1..]
            .iter()
            .take_while(|l| {
                let indent = l.len() - l.trim_start().len();
                l.trim_start().starts_with('#') && column > 0 && indent + 4 >= column
            })
            .count();
        lines.drain(line + 1..line + 1 + continued);
    }
    let mut out = lines.join("\n");
    out.push('\n');
    Ok(out)
}

/// The value of a key [`LogCalibration::values`](super::LogCalibration::values) may change
/// (NaN for another key): the leg fit's [`KNOBS`](super::KNOBS) by their own accessors, and the
/// pack's, the budget's and the tracking lag's.
pub fn value_of(v: &Vehicle, key: &str) -> f64 {
    if let Some(knob) = super::KNOBS.iter().find(|k| k.key == key) {
        return (knob.get)(v);
    }
    match key {
        "battery.internal_resistance_ohm" => v.battery.internal_resistance_ohm,
        "battery.capacity_ah" => v.battery.capacity_ah,
        "planning.usable_energy_wh" => v.planning.usable_energy_wh,
        "ardupilot.tracking_lag_s" => v.ardupilot.tracking_lag_s,
        _ => f64::NAN,
    }
}

/// Sets a key [`value_of`] knows (others are ignored).
pub fn set_value(v: &mut Vehicle, key: &str, value: f64) {
    if let Some(knob) = super::KNOBS.iter().find(|k| k.key == key) {
        (knob.set)(v, value);
        return;
    }
    match key {
        "battery.internal_resistance_ohm" => v.battery.internal_resistance_ohm = value,
        "battery.capacity_ah" => v.battery.capacity_ah = value,
        "planning.usable_energy_wh" => v.planning.usable_energy_wh = value,
        "ardupilot.tracking_lag_s" => v.ardupilot.tracking_lag_s = value,
        _ => {}
    }
}

/// The logged flights a calibration was fitted to, and how much of them.
#[derive(Debug, Clone, PartialEq)]
pub struct FittedTo {
    /// The flights' names (their reports').
    pub flights: Vec<String>,
    pub legs: usize,
    pub hovers: usize,
    /// Leave-one-flight-out per-leg errors.
    pub held_out: Option<ErrorStats>,
    /// The profile the flights were flown with and fitted with: the written vehicle's
    /// `planning.default_profile`, so it plans and prices with it unless told otherwise.
    pub profile: Profile,
}

/// `text` (a vehicle.toml) with `planning.default_profile` set to `profile` (its comment saying
/// why and what it was) when it names another; unchanged when it names it or has no such line
/// (the vehicle's own default then stands).
fn with_default_profile(text: &str, profile: Profile) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let Some(start) = lines.iter().position(|l| l.trim() == "[planning]") else {
        return text.to_string();
    };
    let section = lines[start + 1..]
        .iter()
        .take_while(|l| !l.trim_start().starts_with('['))
        .count();
    let found = (start + 1..start + 1 + section).find(|&k| {
        (lines[k].trim_start().strip_prefix("default_profile"))
            .is_some_and(|rest| rest.trim_start().starts_with('='))
    });
    let Some(k) = found else {
        return text.to_string();
    };
    let old = (lines[k].split_once('=').map(|(_, v)| v.trim())).and_then(|v| {
        v.strip_prefix('"')?
            .split_once('"')
            .map(|(p, _)| p.to_string())
    });
    if old.as_deref() == Some(&profile.to_string()) {
        return text.to_string();
    }
    let column = lines[k].find('#').unwrap_or(NEW_KEY_COLUMN);
    let assignment = format!("default_profile = \"{profile}\"");
    let pad = column.saturating_sub(assignment.len()).max(1);
    lines[k] = format!(
        "{assignment}{:pad$}# the profile the logged flights were flown with (`emplan calibrate --from-logs`); was {}",
        "",
        old.map_or("unset".to_string(), |p| format!("\"{p}\""))
    );
    let mut out = lines.join("\n");
    out.push('\n');
    out
}

/// `text` (a vehicle.toml) with its top-level `name` saying it was calibrated from logs, so a
/// report priced with it names it apart from its source (`report --vehicle`).
fn renamed(text: &str) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let top = lines
        .iter()
        .position(|l| l.trim_start().starts_with('['))
        .unwrap_or(lines.len());
    let name = lines[..top].iter().position(|l| {
        l.strip_prefix("name")
            .is_some_and(|r| r.trim_start().starts_with('='))
    });
    if let Some(k) = name {
        let old = (lines[k].split_once('=').map(|(_, v)| v.trim())).and_then(|v| {
            v.strip_prefix('"')?
                .split_once('"')
                .map(|(n, _)| n.to_string())
        });
        if let Some(old) = old {
            lines[k] = format!("name = \"{old}, calibrated from logged flights\"");
        }
    }
    let mut out = lines.join("\n");
    out.push('\n');
    out
}

/// The header comment of a written vehicle file.
fn header(fitted: &[Fitted], to: &FittedTo) -> String {
    let keys: Vec<&str> = fitted
        .iter()
        .map(|f| f.key)
        .filter(|k| !k.starts_with("battery.") && !k.starts_with("planning."))
        .collect();
    let (flights, legs, held_out) = (to.flights.len(), to.legs, to.held_out);
    let validation = held_out.map_or(String::new(), |e| {
        format!(
            "; leave-one-flight-out per-leg error rms {:.1}%, worst {:.1}%",
            e.rms_pct, e.worst_pct
        )
    });
    let at_bound: Vec<String> = (fitted.iter())
        .filter_map(|f| f.at_bound.map(|b| format!("{} at its {b} bound", f.key)))
        .collect();
    let at_bound = if at_bound.is_empty() {
        String::new()
    } else {
        format!("# Fitted at a bound: {}.\n", at_bound.join(", "))
    };
    format!(
        "# Calibrated from flight logs: `emplan calibrate --from-logs` fitted {} to {legs} legs\n\
         # and {} holds of {flights} flights ({}){validation}; the battery's values, where\n\
         # changed, to their pack voltage and current. Everything else is the source vehicle's.\n\
         {at_bound}",
        keys.join(", "),
        to.hovers,
        to.flights.join(", ")
    )
}

/// A calibrated vehicle file made and checked, not written yet ([`Calibrated::write`]), so
/// its tables can be built first and nothing is half-written.
#[derive(Debug, Clone)]
pub struct Calibrated {
    /// The vehicle as its file reads back.
    pub vehicle: Vehicle,
    text: String,
    out: Output,
}

impl Calibrated {
    /// Writes vehicle.toml into the output directory (made when new); returns its path.
    pub fn write(&self) -> Result<std::path::PathBuf, LogFitError> {
        self.out.create_dir()?;
        let file = self.out.file("vehicle.toml");
        file.write(self.text.as_bytes())?;
        Ok(file.path)
    }
}

/// Writes the calibrated vehicle.toml into the directory `out` ([`calibrated_vehicle`] then
/// [`Calibrated::write`]); returns the vehicle as read.
pub fn write_vehicle(
    source_dir: Option<&Path>,
    out: &Output,
    fitted: &[Fitted],
    to: &FittedTo,
) -> Result<Vehicle, LogFitError> {
    let calibrated = calibrated_vehicle(source_dir, out, fitted, to)?;
    calibrated.write()?;
    Ok(calibrated.vehicle)
}

/// The calibrated vehicle.toml for the directory `out` (new or empty unless forced, never an
/// input such as the source `source_dir`, through `crate::output`; `source_dir` None: the
/// built-in vehicle, whose source directories are never written either), read back and its
/// fitted values checked; nothing written.
pub fn calibrated_vehicle(
    source_dir: Option<&Path>,
    out: &Output,
    fitted: &[Fitted],
    to: &FittedTo,
) -> Result<Calibrated, LogFitError> {
    // The vehicle file edited: the directory's, or the built-in S1000's own text.
    let (text, source_file) = match source_dir {
        Some(dir) => {
            let source = dir.join("vehicle.toml");
            let source_file = source.display().to_string();
            let text = std::fs::read_to_string(&source).map_err(|e| LogFitError::VehicleFile {
                file: source_file.clone(),
                reason: e.to_string(),
            })?;
            (text, source_file)
        }
        None => (
            crate::physics::builtin::VEHICLE_TOML.to_string(),
            format!("{}/vehicle.toml", crate::physics::builtin::NAME),
        ),
    };
    let out_file = out.path.join("vehicle.toml").display().to_string();
    // Never over the source vehicle, whatever the caller counted as inputs.
    let mut out = out.clone();
    match source_dir {
        Some(dir) => out.inputs.push(dir.to_path_buf()),
        None => out.inputs.extend(
            crate::physics::builtin::source_dirs()
                .into_iter()
                .flat_map(|dir| [dir.join("vehicle.toml"), dir]),
        ),
    }
    out.check_dir()?;
    let values: Vec<(&str, f64, String)> = fitted
        .iter()
        .map(|f| {
            (
                f.key,
                f.value,
                match f.key {
                    _ if f.given => format!(
                        "weighed, given to `emplan calibrate --from-logs --mass-kg`; was {}",
                        f.before
                    ),
                    "planning.usable_energy_wh" => format!(
                        "scaled with battery.capacity_ah as fitted (`emplan calibrate --from-logs`); was {}",
                        f.before
                    ),
                    "battery.internal_resistance_ohm" | "battery.capacity_ah" => format!(
                        "calibrated against the pack voltage and current of logged flights (`emplan calibrate --from-logs`); was {}",
                        f.before
                    ),
                    "ardupilot.tracking_lag_s" => format!(
                        "calibrated against the leg durations of logged flights {} (`emplan calibrate --from-logs`){}; was {}",
                        to.flights.join(", "),
                        f.at_bound.map_or(String::new(), |b| format!(", at its {b} bound")),
                        f.before
                    ),
                    _ => format!(
                        "calibrated against the leg and hold energies of logged flights {} (`emplan calibrate --from-logs`){}; was {}",
                        to.flights.join(", "),
                        f.at_bound.map_or(String::new(), |b| format!(", at its {b} bound")),
                        f.before
                    ),
                },
            )
        })
        .collect();
    let edited = edit_vehicle_toml(&text, &source_file, &values)?;
    let edited = header(fitted, to) + &renamed(&with_default_profile(&edited, to.profile));
    let vehicle = Vehicle::from_toml(&edited, &out_file)?;
    for f in fitted {
        let written = value_of(&vehicle, f.key);
        if (written - f.value).abs().is_nan()
            || (written - f.value).abs() > 1e-4 * f.value.abs().max(1.0)
        {
            return Err(LogFitError::VehicleFile {
                file: out_file,
                reason: format!("{} reads back as {written}, not {}", f.key, f.value),
            });
        }
    }
    Ok(Calibrated {
        vehicle,
        text: edited,
        out,
    })
}

/// Builds `profile`'s table of `vehicle` on the default grid (in parallel; `progress(done,
/// total)`) and writes it into the directory `dir` (through `crate::output`).
pub fn write_table(
    dir: &Output,
    vehicle: &Vehicle,
    profile: Profile,
    progress: impl Fn(usize, usize) + Sync,
) -> Result<std::path::PathBuf, LogFitError> {
    write_built_table(dir, &build_table(vehicle, profile, progress)?)
}

/// `profile`'s table of `vehicle` on the default grid (in parallel; `progress(done, total)`).
pub fn build_table(
    vehicle: &Vehicle,
    profile: Profile,
    progress: impl Fn(usize, usize) + Sync,
) -> Result<EnergyTable, LogFitError> {
    Ok(EnergyTable::build(
        vehicle, profile, DEFAULT_XF, DEFAULT_ZF, progress,
    )?)
}

/// A table a calibrated vehicle directory was written without, and why.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LeftOut {
    pub profile: Profile,
    /// The error that building it gave.
    pub reason: String,
}

/// The tables of `profiles`, each built by `build` (the calibrated vehicle's table of that
/// profile), before anything is written. A table that cannot be built refuses them all when
/// `required` (the user named it), naming its profile; otherwise it is left out with its
/// reason, never failing the fit over a table nobody asked for.
pub fn build_tables(
    profiles: &[Profile],
    required: bool,
    mut build: impl FnMut(Profile) -> Result<EnergyTable, LogFitError>,
) -> Result<(Vec<EnergyTable>, Vec<LeftOut>), LogFitError> {
    let mut built = Vec::new();
    let mut left_out = Vec::new();
    for &profile in profiles {
        match build(profile) {
            Ok(table) => built.push(table),
            Err(e) if required => {
                return Err(LogFitError::Table {
                    profile,
                    source: Box::new(e),
                })
            }
            Err(e) => left_out.push(LeftOut {
                profile,
                reason: e.to_string(),
            }),
        }
    }
    Ok((built, left_out))
}

/// Writes a built `table` into the directory `dir` (through `crate::output`); returns its path.
pub fn write_built_table(
    dir: &Output,
    table: &EnergyTable,
) -> Result<std::path::PathBuf, LogFitError> {
    let path = EnergyTable::path(&dir.path, table.profile);
    Output::new(&path, dir.inputs.clone(), dir.force).write(table.to_text().as_bytes())?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shipped_text() -> String {
        std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000/vehicle.toml"),
        )
        .expect("the shipped vehicle file")
    }

    #[test]
    fn fitted_values_replace_their_lines_and_everything_else_is_kept() {
        let text = shipped_text();
        let edited = edit_vehicle_toml(
            &text,
            "v.toml",
            &[
                ("body.mass_kg", 7.6543, "from logs".into()),
                ("body.drag_coefficient_n_s2_m2", 0.41, "from logs".into()),
            ],
        )
        .expect("edited");
        let v = Vehicle::from_toml(&edited, "v.toml").expect("valid");
        let before = Vehicle::from_toml(&text, "v.toml").expect("valid");
        assert_eq!(v.body.mass_kg, 7.6543);
        assert_eq!(v.body.drag_coefficient_n_s2_m2, 0.41);
        // Only those two lines differ, and their old comments' continuation lines are gone;
        // the rotor's drag_coefficient is another key.
        assert_eq!(v.rotor, before.rotor);
        let kept: Vec<&str> = text.lines().filter(|l| edited.contains(*l)).collect();
        let removed: Vec<&str> = text.lines().filter(|l| !edited.contains(*l)).collect();
        assert_eq!(kept.len() + removed.len(), text.lines().count());
        assert_eq!(removed.len(), 4, "{removed:?}");
        assert!(
            removed
                .iter()
                .filter(|l| l.trim_start().starts_with('#'))
                .count()
                == 2,
            "{removed:?}"
        );
        assert_eq!(edited.lines().count(), text.lines().count() - 2);
        assert!(edited.contains("mass_kg = 7.6543"), "{edited}");
        assert!(!edited.contains("window 6-11 kg"), "{edited}");
    }

    #[test]
    fn a_table_that_cannot_be_built_is_left_out_unless_it_was_asked_for() {
        let vehicle = crate::physics::builtin::vehicle().unwrap();
        let small = |profile| {
            EnergyTable::build(
                &vehicle,
                profile,
                crate::physics::table::Axis::new(0.0, 10.0, 2),
                crate::physics::table::Axis::new(-5.0, 5.0, 2),
                |_, _| {},
            )
            .map_err(LogFitError::from)
        };
        // The ptf table fails to build (as a fit the ptf profile cannot fly would).
        let build = |profile| match profile {
            Profile::Ptf => Err(LogFitError::from(
                crate::physics::PhysicsError::NoTrajectory {
                    xf_m: 75.0,
                    zf_m: 19.0,
                    profile,
                    reason: "every duration breaks the tilt, motor or battery limits".into(),
                },
            )),
            other => small(other),
        };
        let asked = [Profile::Ptf, Profile::Hvb];
        let (built, left_out) = build_tables(&asked, false, build).unwrap();
        assert_eq!(
            built.iter().map(|t| t.profile).collect::<Vec<_>>(),
            [Profile::Hvb]
        );
        assert_eq!(left_out.len(), 1);
        assert_eq!(left_out[0].profile, Profile::Ptf);
        assert!(
            left_out[0]
                .reason
                .contains("Xf 75.00 m, Zf 19.00 m with the ptf profile"),
            "{}",
            left_out[0].reason
        );
        // Named: refused, naming the table.
        let err = build_tables(&asked, true, build).unwrap_err().to_string();
        assert!(
            err.starts_with("the ptf table of the calibrated vehicle: no feasible trajectory"),
            "{err}"
        );
    }

    #[test]
    fn a_value_of_zero_is_written_with_four_decimals() {
        let edited = edit_vehicle_toml(
            &shipped_text(),
            "v.toml",
            &[("rotor.descent_inflow_factor", 0.0, "fitted".into())],
        )
        .unwrap();
        assert!(
            edited.contains("descent_inflow_factor = 0.0000"),
            "{edited}"
        );
        let v = Vehicle::from_toml(&edited, "v.toml").unwrap();
        assert_eq!(v.rotor.descent_inflow_factor, 0.0);
    }

    #[test]
    fn a_key_the_file_leaves_out_is_added_to_its_section_and_a_missing_section_refused() {
        // A vehicle file written before the airflow was a key reads it as 1.
        let older: String = shipped_text()
            .lines()
            .filter(|l| !l.starts_with("airflow_factor") && !l.contains("\"Airflow\""))
            .map(|l| format!("{l}\n"))
            .collect();
        assert_eq!(
            Vehicle::from_toml(&older, "v.toml")
                .unwrap()
                .rotor
                .airflow_factor,
            1.0
        );
        let edited = edit_vehicle_toml(
            &older,
            "v.toml",
            &[("rotor.airflow_factor", 0.25, "fitted".into())],
        )
        .unwrap();
        let v = Vehicle::from_toml(&edited, "v.toml").unwrap();
        assert_eq!(v.rotor.airflow_factor, 0.25);
        assert_eq!(edited.lines().count(), older.lines().count() + 1);
        let line = edited
            .lines()
            .find(|l| l.starts_with("airflow_factor"))
            .unwrap();
        assert_eq!(line.find('#'), Some(NEW_KEY_COLUMN), "{line}");
        assert!(line.ends_with("# fitted"), "{line}");
        // In its section: the line before it is the rotor's.
        let at = edited.lines().position(|l| l == line).unwrap();
        let section = edited
            .lines()
            .take(at)
            .filter(|l| l.starts_with('['))
            .last();
        assert_eq!(section, Some("[rotor]"));

        let err = edit_vehicle_toml(&older, "v.toml", &[("wings.count", 2.0, "x".into())])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("v.toml") && err.contains("no [wings] section"),
            "{err}"
        );
    }
}
