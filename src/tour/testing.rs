//! Test fixtures shared by the solver tests: climb-averse random missions and the TSPLIB
//! instances beside the project.

use super::{tsplib, CostMatrix};
use crate::rng::Rng;

/// The origin at (0, 0, 0) and `n - 1` random points uniform in [-50, 50]^2 x [-25, 25] m; leg
/// cost = horizontal distance + 8 x climb + 0.5 x descent (the shape of a multirotor's energy,
/// not its scale).
pub fn drone(n: usize, seed: u64) -> CostMatrix {
    let mut rng = Rng::new(seed);
    let mut points = vec![[0.0; 3]];
    for _ in 1..n {
        points.push([
            rng.uniform(-50.0, 50.0),
            rng.uniform(-50.0, 50.0),
            rng.uniform(-25.0, 25.0),
        ]);
    }
    CostMatrix::from_fn(n, |i, j| {
        let (a, b) = (points[i], points[j]);
        let horizontal_m = (b[0] - a[0]).hypot(b[1] - a[1]);
        let climb_m = b[2] - a[2];
        horizontal_m + 8.0 * climb_m.max(0.0) + 0.5 * (-climb_m).max(0.0)
    })
}

/// The TSPLIB instance `name` (TSPLIB95's ATSP files, copied into tests/fixtures/tsplib so that
/// a clone alone passes its tests).
pub fn tsplib_instance(name: &str) -> CostMatrix {
    let path = format!(
        "{}/tests/fixtures/tsplib/{name}.atsp",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    tsplib::parse(&text)
        .unwrap_or_else(|e| panic!("{path}: {e}"))
        .matrix
}
