//! The shipped S1000 vehicle and its three energy tables, compiled into the binary so that
//! emplan plans and flies from any directory and after `cargo install` without the repository
//! beside it. The text is the committed `models/s1000/` (about 4.5 MB of tables); a table is
//! parsed, and checked against the vehicle's parameter hash like a file, when it is first used.

use super::{EnergyTable, PhysicsError, Profile, Vehicle};

/// How errors and reports name the built-in vehicle.
pub const NAME: &str = "models/s1000 (built in)";

/// The shipped vehicle.toml's text (what `calibrate --from-logs` edits when no directory is
/// given).
pub const VEHICLE_TOML: &str = include_str!("../../models/s1000/vehicle.toml");

/// The directories the built-in vehicle's files come from: the repository's `models/s1000` as
/// a command run from the repository names it, and as the build saw it. A command writing a
/// vehicle directory never writes over them, whatever the vehicle it read.
pub fn source_dirs() -> [std::path::PathBuf; 2] {
    [
        std::path::PathBuf::from("models/s1000"),
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000"),
    ]
}

/// The shipped S1000's parameters.
pub fn vehicle() -> Result<Vehicle, PhysicsError> {
    Vehicle::from_toml(VEHICLE_TOML, "models/s1000/vehicle.toml (built in)")
}

/// The shipped table of `profile`, refused if it was not built from `vehicle`.
pub fn table(profile: Profile, vehicle: &Vehicle) -> Result<EnergyTable, PhysicsError> {
    let text = match profile {
        Profile::Ptf => include_str!("../../models/s1000/ptf.table"),
        Profile::Hvb => include_str!("../../models/s1000/hvb.table"),
        Profile::Px4 => include_str!("../../models/s1000/px4.table"),
        Profile::Ardupilot => include_str!("../../models/s1000/ardupilot.table"),
    };
    let file = format!("models/s1000/{profile}.table (built in)");
    EnergyTable::from_text(text, &file)?.checked(profile, vehicle, file)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_built_in_vehicle_and_every_table_are_the_committed_files_and_fresh() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000");
        let v = vehicle().unwrap();
        assert_eq!(v, Vehicle::load(&dir).unwrap());
        for profile in Profile::ALL {
            let built_in = table(profile, &v).unwrap();
            assert_eq!(
                built_in,
                EnergyTable::load(&dir, profile, &v).unwrap(),
                "{profile}"
            );
        }
    }
}
