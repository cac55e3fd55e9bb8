//! Criterion bench of ordering on pair costs (a leg priced by the turn into it, the `px4`
//! profile): `emplan plan`'s energy order of generated missions (the study's 30 m, 25 m
//! distribution, 5 s holds) with the shipped S1000's px4 table, through the planner as `plan`,
//! `upload` and `fly` run it. Up to 12 waypoints the pair-cost dynamic programming is exact; the
//! 20- and 50-waypoint missions run the local search from the pair-independent order with the
//! proven lower bound. Run with `cargo bench --bench pairs`.

mod common;

use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use emplan::physics::{Profile, VehicleModel};
use emplan::planner::{plan_mission, Orders, PlanOptions};

fn pairs_bench(c: &mut Criterion) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000");
    let model = VehicleModel::load(&dir, Some(Profile::Px4)).expect("the shipped vehicle");
    let options = PlanOptions {
        orders: Orders::Energy,
        solver: Default::default(),
        sorties: false,
        pricing: Default::default(),
    };
    let mut group = c.benchmark_group("pair_energy_order");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    for n in [8, 10, 12, 20, 50] {
        let m = common::study_mission(n);
        group.bench_with_input(BenchmarkId::from_parameter(n), &m, |b, m| {
            b.iter(|| plan_mission(m, &model, &options).expect("planned"))
        });
    }
    group.finish();
}

criterion_group!(benches, pairs_bench);
criterion_main!(benches);
