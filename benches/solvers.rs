//! Criterion benches of the exact solvers: Held-Karp on random energy-priced missions of 10, 15
//! and 20 waypoints, and branch-and-cut (started from the heuristic, as `emplan tsp` runs it) on
//! TSPLIB's ftv70, kro124p and ftv170. Run with `cargo bench --bench solvers`.

use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use emplan::physics::{EnergyTable, Vehicle};
use emplan::plan::study::{random_points, StudySettings};
use emplan::plan::{held_karp, solver, tsplib, CostMatrix, Geometry};

/// The energy matrix (J) of mission 0 of a study setting, priced with the shipped S1000 table.
pub fn energy_mission(waypoints: usize, xy_m: f64, z_m: f64) -> CostMatrix {
    let dir = Path::new("models/s1000");
    let vehicle = Vehicle::load(dir).expect("shipped vehicle");
    let table = EnergyTable::load(dir, vehicle.default_profile(), &vehicle).expect("table");
    let settings = StudySettings {
        waypoints,
        xy_m,
        z_m,
        missions: 1,
        seed: 1,
    };
    let points = std::iter::once(Default::default())
        .chain(random_points(&settings, 0))
        .collect();
    let g = Geometry::from_points(points);
    CostMatrix::from_fn(g.len(), |i, j| {
        table
            .lookup(g.horizontal_m(i, j), g.vertical_m(i, j))
            .map(|leg| leg.total_energy_j())
            .expect("leg inside the table")
    })
}

fn held_karp_bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("held_karp");
    group.sample_size(10);
    for n in [10, 15, 20] {
        let m = energy_mission(n, 30.0, 25.0);
        group.bench_with_input(BenchmarkId::from_parameter(n), &m, |b, m| {
            b.iter(|| held_karp::solve(m).expect("solved"))
        });
    }
    group.finish();
}

fn branch_cut_bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("branch_cut");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(30));
    for name in ["ftv70", "kro124p", "ftv170"] {
        let text = std::fs::read_to_string(format!("../shared/tsplib-atsp/{name}.atsp"))
            .expect("TSPLIB instance beside the project");
        let inst = tsplib::parse(&text).expect("valid instance");
        let options = solver::Options {
            solver: solver::Solver::BranchCut,
            ..Default::default()
        };
        group.bench_with_input(BenchmarkId::from_parameter(name), &inst.matrix, |b, m| {
            b.iter(|| {
                let solved = solver::solve(m, &options).expect("solved");
                assert!(solved.tour.optimal);
                solved
            })
        });
    }
    group.finish();
}

criterion_group!(benches, held_karp_bench, branch_cut_bench);
criterion_main!(benches);
