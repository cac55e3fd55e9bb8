//! A vehicle ready to price legs: its parameters, the flight profile chosen for it and that
//! profile's energy table, loaded together so that a table is never used with another vehicle
//! or profile than its own.

use std::path::Path;

use super::budget::Budget;
use super::{EnergyTable, LegEnergy, PhysicsError, Profile, Vehicle};

/// A vehicle with the energy table of one profile.
#[derive(Debug, Clone)]
pub struct VehicleModel {
    pub vehicle: Vehicle,
    pub profile: Profile,
    pub table: EnergyTable,
}

impl VehicleModel {
    /// Loads `dir/vehicle.toml` and its table for `profile` (the vehicle's default profile when
    /// none is given); a missing or stale table is an error naming the file.
    pub fn load(dir: &Path, profile: Option<Profile>) -> Result<VehicleModel, PhysicsError> {
        let vehicle = Vehicle::load(dir)?;
        let profile = profile.unwrap_or(vehicle.default_profile());
        let table = EnergyTable::load(dir, profile, &vehicle)?;
        Ok(VehicleModel {
            vehicle,
            profile,
            table,
        })
    }

    /// One leg of horizontal distance `xf_m` and signed climb `zf_m`, from the table.
    pub fn leg(&self, xf_m: f64, zf_m: f64) -> Result<LegEnergy, PhysicsError> {
        self.table.lookup(xf_m, zf_m)
    }

    /// Take-off, landing and hover for an origin `height_above_home_m` up, and the battery.
    pub fn budget(&self, height_above_home_m: f64) -> Result<Budget, PhysicsError> {
        Budget::new(&self.vehicle, self.profile, height_above_home_m)
    }
}
