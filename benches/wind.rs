//! Criterion bench of planning in a steady wind (the timing targets: a 20-waypoint
//! mission under 2 s, a 100-waypoint one under 30 s, on 2 cores): `plan_mission` of generated
//! missions (the study's 30 m, 25 m distribution, 5 s holds) with the shipped S1000's px4 table
//! in a 6 m/s wind from the west. In wind every ordered leg is simulated directly on its
//! heading (both start cases of the px4 profile: 2 n (n + 1) legs), rows in parallel; the
//! still-air energy order is solved as well and priced in the wind. `energy`: the energy order
//! alone (`plan --order energy --wind`); `all`: with the distance baselines (`plan --wind`; of
//! a mission Held-Karp solves exactly they run on a thread of their own from the start).
//! Run with `cargo bench --bench wind`; `cargo bench --bench wind -- energy/20` for one.

mod common;

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use emplan::physics::{Profile, VehicleModel, VehicleSource, Wind};
use emplan::planner::{plan_mission, Orders, PlanOptions};

fn wind_bench(c: &mut Criterion) {
    let model = VehicleModel::open(&VehicleSource::BuiltIn, Some(Profile::Px4))
        .expect("the built-in vehicle")
        .with_wind(Wind::new(6.0, 270.0).expect("a wind"));
    let mut group = c.benchmark_group("plan_in_wind");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    for (orders, name, sizes) in [
        (Orders::Energy, "energy", &[20, 100][..]),
        (Orders::All, "all", &[20, 100][..]),
    ] {
        let options = PlanOptions {
            orders,
            ..PlanOptions::default()
        };
        for &n in sizes {
            let m = common::study_mission(n);
            group.bench_with_input(BenchmarkId::new(name, n), &m, |b, m| {
                b.iter(|| plan_mission(m, &model, &options).expect("planned"))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, wind_bench);
criterion_main!(benches);
