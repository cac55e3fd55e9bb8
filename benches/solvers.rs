//! Criterion benches of the exact solvers: Held-Karp on random energy-priced missions of 10, 15
//! and 20 waypoints, and branch-and-cut (started from the heuristic, as `emplan tsp` runs it) on
//! TSPLIB's ftv70, kro124p and ftv170. Run with `cargo bench --bench solvers`.

mod common;

use std::time::Duration;

use common::energy_mission;
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use emplan::tour::{held_karp, solver, tsplib};

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
        let text = std::fs::read_to_string(format!("tests/fixtures/tsplib/{name}.atsp"))
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
