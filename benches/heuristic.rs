//! Criterion benches of the direction-preserving iterated local search
//! (`emplan::tour::heuristic`) with a fixed kick budget: TSPLIB rbg443 (optimum 2720) and a
//! 1000-waypoint mission (the study's distribution, XY 50 m, Z 25 m) priced with the S1000
//! energy table. Run with `cargo bench --bench heuristic`.

mod common;

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use emplan::tour::heuristic::{solve, Options};
use emplan::tour::tsplib;

/// Kicks per run: about the default budget for 443 nodes, 40% of it for 1000.
const KICKS: u64 = 40_000;

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
        "/tests/fixtures/tsplib/rbg443.atsp"
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

    let mission = common::energy_mission(1000, 50.0, 25.0);
    group.bench_function("mission1000", |b| {
        b.iter(|| solve(black_box(&mission), None, &options()))
    });
    group.finish();
}

criterion_group!(benches, bench_heuristic);
criterion_main!(benches);
