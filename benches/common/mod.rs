//! Shared by the benches: a random mission of the study's distribution priced with the shipped
//! S1000 energy table (the vehicle's default profile), as `emplan plan` prices it, or as a
//! mission file would hold it.

use std::path::Path;

use emplan::mission::{Geodetic, Mission};
use emplan::physics::{EnergyTable, Vehicle};
use emplan::planner::study::{mission_geometry, random_mission, Site, StudySettings};
use emplan::tour::energy::energy_matrix;
use emplan::tour::CostMatrix;

/// The energy matrix (J) of mission 0 of the study setting (`waypoints`, `xy_m`, `z_m`, seed 1).
#[allow(dead_code)] // each bench compiles this module; not every one solves a bare matrix
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

/// Mission 0 of the study's 30 m, 25 m distribution (seed 1) with `waypoints` waypoints and 5 s
/// holds, as a mission file would hold it (the sample missions' field).
#[allow(dead_code)] // each bench compiles this module; not every one plans a whole mission
pub fn study_mission(waypoints: usize) -> Mission {
    let settings = StudySettings {
        waypoints,
        xy_m: 30.0,
        z_m: 25.0,
        missions: 1,
        seed: 1,
    };
    let site = Site {
        home: Geodetic {
            lat_deg: 38.5362,
            lon_deg: -121.7875,
            alt_m: 16.0,
        },
        hover_s: 5.0,
        name: None,
    };
    random_mission(&settings, 0, &site).expect("a generated mission")
}
