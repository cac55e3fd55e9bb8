//! Criterion benches of the direction-preserving iterated local search
//! (`emplan::plan::heuristic`) with a fixed kick budget: TSPLIB rbg443 (optimum 2720) and a
//! 1000-node "drone" instance (random 3-D points, cost = horizontal distance + 8 x climb +
//! 0.5 x descent). Run with `cargo bench --bench heuristic`.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use emplan::plan::heuristic::{solve, Options};
use emplan::plan::rng::Rng;
use emplan::plan::{tsplib, CostMatrix};

/// Kicks per run: about the default budget for 443 nodes, a tenth of it for 1000.
const KICKS: u64 = 40_000;

/// Random waypoints uniform in [-50, 50] m x [-50, 50] m x [-25, 25] m plus the origin at
/// (0, 0, 0); leg cost = horizontal distance + 8 x climb + 0.5 x descent (metres weighted like
/// the energy of a multirotor: climbing is expensive, descending cheap).
fn drone_matrix(n: usize, seed: u64) -> CostMatrix {
    let mut rng = Rng::new(seed);
    let mut points_m = vec![[0.0; 3]];
    for _ in 1..n {
        points_m.push([
            rng.uniform(-50.0, 50.0),
            rng.uniform(-50.0, 50.0),
            rng.uniform(-25.0, 25.0),
        ]);
    }
    CostMatrix::from_fn(n, |i, j| {
        let (a, b) = (points_m[i], points_m[j]);
        let horizontal_m = (b[0] - a[0]).hypot(b[1] - a[1]);
        let climb_m = b[2] - a[2];
        horizontal_m + 8.0 * climb_m.max(0.0) + 0.5 * (-climb_m).max(0.0)
    })
}

fn options() -> Options {
    Options {
        max_kicks: Some(KICKS),
        time_limit_s: 120.0,
        ..Options::default()
    }
}

fn bench_heuristic(c: &mut Criterion) {
    let mut group = c.benchmark_group("heuristic");
    group.sample_size(10);

    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/tsplib-atsp/rbg443.atsp"
    );
    match std::fs::read_to_string(path).map(|text| tsplib::parse(&text)) {
        Ok(Ok(instance)) => {
            group.bench_function("rbg443", |b| {
                b.iter(|| solve(black_box(&instance.matrix), None, &options()))
            });
        }
        Ok(Err(e)) => eprintln!("skipping rbg443: {path}: {e}"),
        Err(e) => eprintln!("skipping rbg443: {path}: {e}"),
    }

    let drone = drone_matrix(1000, 2024);
    group.bench_function("drone1000", |b| {
        b.iter(|| solve(black_box(&drone), None, &options()))
    });
    group.finish();
}

criterion_group!(benches, bench_heuristic);
criterion_main!(benches);
