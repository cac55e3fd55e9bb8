//! A vehicle ready to price legs: its parameters, the flight profile chosen for it and that
//! profile's energy table, loaded together so that a table is never used with another vehicle
//! or profile than its own. Legs beyond the table are composed from it where that is exact
//! (`longleg`).

use std::path::{Path, PathBuf};

use super::budget::Budget;
use super::longleg;
use super::power::Model;
use super::px4::{start_case, Start};
use super::{builtin, EnergyTable, LegEnergy, PhysicsError, Profile, Vehicle};
use crate::mission::wind::{heading_deg, Wind};

/// Where a vehicle and its tables come from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum VehicleSource {
    /// The shipped S1000, compiled into the binary ([`builtin`]).
    BuiltIn,
    /// A directory holding `vehicle.toml` and its `<profile>.table` files.
    Dir(PathBuf),
}

impl VehicleSource {
    /// The vehicle's parameters.
    pub fn vehicle(&self) -> Result<Vehicle, PhysicsError> {
        match self {
            VehicleSource::BuiltIn => builtin::vehicle(),
            VehicleSource::Dir(dir) => Vehicle::load(dir),
        }
    }
}

impl std::fmt::Display for VehicleSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            VehicleSource::BuiltIn => f.write_str(builtin::NAME),
            VehicleSource::Dir(dir) => write!(f, "{}", dir.display()),
        }
    }
}

/// A vehicle with the energy table of one profile, and the wind it flies in.
///
/// In still air a leg is looked up in the table. In wind ([`VehicleModel::with_wind`]) every
/// leg is simulated directly in the wind its heading meets (`Model::in_wind`): the table is
/// a still-air table, and a leg's price in wind depends on its direction as well as on its
/// size (docs/energy-model.md "Wind": the choice, its accuracy and its time).
#[derive(Debug, Clone)]
pub struct VehicleModel {
    pub vehicle: Vehicle,
    pub profile: Profile,
    pub table: EnergyTable,
    /// The steady wind legs are priced in (calm: the table).
    pub wind: Wind,
    /// The horizontal speed legs are flown at when a DO_CHANGE_SPEED set one other than the
    /// vehicle's (None: the vehicle's own, the table's): every leg then simulated directly at
    /// it ([`Vehicle::at_speed`]).
    pub speed_m_s: Option<f64>,
}

impl VehicleModel {
    /// Loads `dir/vehicle.toml` and its table for `profile` (the vehicle's default profile when
    /// none is given); a missing or stale table is an error naming the file.
    pub fn load(dir: &Path, profile: Option<Profile>) -> Result<VehicleModel, PhysicsError> {
        Self::open(&VehicleSource::Dir(dir.to_path_buf()), profile)
    }

    /// The vehicle of `source` with its table for `profile` (the vehicle's default profile
    /// when none is given).
    pub fn open(
        source: &VehicleSource,
        profile: Option<Profile>,
    ) -> Result<VehicleModel, PhysicsError> {
        let vehicle = source.vehicle()?;
        let profile = profile.unwrap_or(vehicle.default_profile());
        let table = match source {
            VehicleSource::BuiltIn => builtin::table(profile, &vehicle)?,
            VehicleSource::Dir(dir) => EnergyTable::load(dir, profile, &vehicle)?,
        };
        Ok(VehicleModel {
            vehicle,
            profile,
            table,
            wind: Wind::CALM,
            speed_m_s: None,
        })
    }

    /// The same vehicle flying in a steady `wind`.
    pub fn with_wind(self, wind: Wind) -> VehicleModel {
        VehicleModel { wind, ..self }
    }

    /// The horizontal speed the profile cruises at: the autopilot's parameter (ArduPilot's
    /// WP_SPD for `ardupilot`, PX4's MPC_XY_CRUISE otherwise).
    pub fn cruise_speed_m_s(&self) -> f64 {
        self.vehicle
            .cruise_speed_m_s(self.profile == Profile::Ardupilot)
    }

    /// The same vehicle flying its legs at `speed_m_s` (a DO_CHANGE_SPEED; None, or the
    /// profile's own cruise speed: as the table prices them).
    pub fn at_speed(&self, speed_m_s: Option<f64>) -> VehicleModel {
        let own = self.cruise_speed_m_s();
        VehicleModel {
            speed_m_s: speed_m_s.filter(|v| (v - own).abs() > 1e-6),
            ..self.clone()
        }
    }

    /// One leg of horizontal distance `xf_m` and signed climb `zf_m`: from the table, or beyond
    /// it composed exactly from a table leg and the profile's steady cruise
    /// ([`super::longleg`]). The `ptf` quintic never cruises, so its long legs are simulated
    /// directly, the very operation a table cell holds (about 20 ms a leg instead of a lookup),
    /// as is a leg whose cruise is too short to bring it inside the table; a leg that is none
    /// of these is an error naming it.
    pub fn leg(&self, xf_m: f64, zf_m: f64) -> Result<LegEnergy, PhysicsError> {
        self.leg_from(xf_m, zf_m, Start::Behind)
    }

    /// [`VehicleModel::leg`] for a leg starting `start` of PX4's trajectory (the `px4`
    /// profile's price depends on the leg before: [`super::px4::start_case`]).
    pub fn leg_from(&self, xf_m: f64, zf_m: f64, start: Start) -> Result<LegEnergy, PhysicsError> {
        match self.table.lookup_from(xf_m, zf_m, start) {
            Err(PhysicsError::OutsideTable { .. }) => longleg::price_outside_from(
                &Model::new(&self.vehicle),
                &self.table,
                xf_m,
                zf_m,
                start,
            ),
            other => other,
        }
    }

    /// [`VehicleModel::leg_from`] flown on `heading_deg` (its direction of travel, degrees
    /// clockwise from north) in the model's wind: in still air the same, in wind simulated
    /// directly in what that heading meets of it.
    pub fn leg_on_heading(
        &self,
        xf_m: f64,
        zf_m: f64,
        start: Start,
        heading_deg: f64,
    ) -> Result<LegEnergy, PhysicsError> {
        if self.wind.is_calm() && self.speed_m_s.is_none() {
            return self.leg_from(xf_m, zf_m, start);
        }
        let vehicle = match self.speed_m_s {
            Some(v) => self.vehicle.at_speed(v),
            None => self.vehicle.clone(),
        };
        let model = Model::new(&vehicle).in_wind(self.wind.on_heading(heading_deg));
        let op = model
            .operation_from(self.profile, xf_m, zf_m, start)
            .map_err(|e| e.in_wind(self.wind))?;
        Ok(LegEnergy::from(&op))
    }

    /// The leg from `from` to `to` (east, north, up; m) flown after the leg `previous` (None
    /// after the take-off), priced with the start case PX4 gives it, in the model's wind.
    pub fn leg_after(
        &self,
        previous: Option<[f64; 3]>,
        from: [f64; 3],
        to: [f64; 3],
    ) -> Result<LegEnergy, PhysicsError> {
        let (dx, dy, dz) = (to[0] - from[0], to[1] - from[1], to[2] - from[2]);
        let start = start_case(previous.map(|p| (p[0], p[1])), (dx, dy));
        self.leg_on_heading(dx.hypot(dy), dz, start, heading_deg(dx, dy))
    }

    /// Take-off, landing and hover for an origin `height_above_home_m` up, and the battery, in
    /// the model's wind.
    pub fn budget(&self, height_above_home_m: f64) -> Result<Budget, PhysicsError> {
        Budget::in_wind(&self.vehicle, self.profile, height_above_home_m, self.wind)
    }
}
