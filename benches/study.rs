//! Criterion bench of the random-mission study: 5000 missions of 8 waypoints (XY 30 m, Z 25 m,
//! the paper's central setting) priced with the shipped S1000 px4 table, on all cores.
//! Run with `cargo bench --bench study`.

use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use emplan::physics::{EnergyTable, Vehicle};
use emplan::planner::study::{run_study, BaselineDirection, StudySettings};

fn study_bench(c: &mut Criterion) {
    let dir = Path::new("models/s1000");
    let vehicle = Vehicle::load(dir).expect("shipped vehicle");
    let table = EnergyTable::load(dir, vehicle.default_profile(), &vehicle).expect("table");
    let settings = StudySettings {
        waypoints: 8,
        xy_m: 30.0,
        z_m: 25.0,
        missions: 5000,
        seed: 1,
    };
    let mut group = c.benchmark_group("study");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    group.bench_function("n8_5000_missions", |b| {
        b.iter(|| {
            run_study(
                &settings,
                BaselineDirection::Better,
                |x, z| table.lookup(x, z).map(|leg| leg.total_energy_j()),
                &|| {},
            )
            .expect("study runs")
        })
    });
    group.finish();
}

criterion_group!(benches, study_bench);
criterion_main!(benches);
