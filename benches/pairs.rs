//! Criterion bench of ordering on pair costs (a leg priced by the turn into it, the `px4`
//! profile): `emplan plan`'s energy order of generated missions (the study's 30 m, 25 m
//! distribution, 5 s holds) with the shipped S1000's px4 table, through the planner as `plan`,
//! `upload` and `fly` run it. Up to 12 waypoints the pair-cost dynamic programming is exact; the
//! 20- and 50-waypoint missions run the local search from the pair-independent order with the
//! proven lower bound. Run with `cargo bench --bench pairs`.

use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use emplan::mission::{Geodetic, Mission};
use emplan::physics::{Profile, VehicleModel};
use emplan::planner::study::{random_mission, Site, StudySettings};
use emplan::planner::{plan_mission, Orders, PlanOptions};

fn mission(waypoints: usize) -> Mission {
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
        let m = mission(n);
        group.bench_with_input(BenchmarkId::from_parameter(n), &m, |b, m| {
            b.iter(|| plan_mission(m, &model, &options).expect("planned"))
        });
    }
    group.finish();
}

criterion_group!(benches, pairs_bench);
criterion_main!(benches);
