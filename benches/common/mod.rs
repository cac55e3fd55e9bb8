//! Shared by the benches: a random mission of the study's distribution priced with the shipped
//! S1000 energy table (the vehicle's default profile), as `emplan plan` prices it.

use std::path::Path;

use emplan::physics::{EnergyTable, Vehicle};
use emplan::planner::study::{mission_geometry, StudySettings};
use emplan::tour::energy::energy_matrix;
use emplan::tour::CostMatrix;

/// The energy matrix (J) of mission 0 of the study setting (`waypoints`, `xy_m`, `z_m`, seed 1).
pub fn energy_mission(waypoints: usize, xy_m: f64, z_m: f64) -> CostMatrix {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000");
    let vehicle = Vehicle::load(&dir).expect("shipped vehicle");
    let table = EnergyTable::load(&dir, vehicle.default_profile(), &vehicle).expect("table");
    let settings = StudySettings {
        waypoints,
        xy_m,
        z_m,
        missions: 1,
        seed: 1,
    };
    let g = mission_geometry(&settings, 0);
    energy_matrix(&g, &[], |x, z| {
        table.lookup(x, z).map(|leg| leg.total_energy_j())
    })
    .expect("every leg inside the table")
}
