//! Criterion bench of planning a mission with actions at every waypoint (the target:
//! `plan` of a 30-waypoint mission with actions at every point as fast as without them):
//! `plan_mission` (every order) of a generated 30-waypoint mission (the study's 30 m, 25 m
//! distribution, 5 s holds) with the shipped S1000's px4 table, `bare`; with a gimbal pitch, a
//! photo and a yaw at every waypoint, `actions` (the yaw's turn is priced with each leg into its
//! waypoint); and the same with a speed change after the first waypoint, `speed` (every leg
//! after it flown at 8 m/s: simulated directly instead of looked up, as in wind).
//! Run with `cargo bench --bench actions`.

mod common;

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use emplan::mission::actions::{id, Command};
use emplan::mission::Mission;
use emplan::physics::{Profile, VehicleModel, VehicleSource};
use emplan::planner::{plan_mission, PlanOptions};

fn with_actions(m: &Mission, speed: bool) -> Mission {
    let mut m = m.clone();
    for (k, w) in m.waypoints.iter_mut().enumerate() {
        w.actions = vec![
            Command::new(id::DO_MOUNT_CONTROL, [-45.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0]),
            Command::new(id::DO_DIGICAM_CONTROL, [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]),
            Command::new(
                id::CONDITION_YAW,
                [(k * 37 % 360) as f64, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            ),
        ];
        if speed && k == 0 {
            w.actions.push(Command::new(
                id::DO_CHANGE_SPEED,
                [1.0, 8.0, -1.0, 0.0, 0.0, 0.0, 0.0],
            ));
        }
    }
    m
}

fn actions_bench(c: &mut Criterion) {
    let model = VehicleModel::open(&VehicleSource::BuiltIn, Some(Profile::Px4))
        .expect("the built-in vehicle");
    let mut group = c.benchmark_group("plan_with_actions");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    let options = PlanOptions::default();
    let bare = common::study_mission(30);
    for (name, m) in [
        ("bare", bare.clone()),
        ("actions", with_actions(&bare, false)),
        ("speed", with_actions(&bare, true)),
    ] {
        group.bench_with_input(BenchmarkId::new(name, 30), &m, |b, m| {
            b.iter(|| plan_mission(m, &model, &options).expect("planned"))
        });
    }
    group.finish();
}

criterion_group!(benches, actions_bench);
criterion_main!(benches);
