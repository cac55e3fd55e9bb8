//! Criterion bench of planning a fenced mission: generated missions (the study's 30 m, 25 m
//! distribution, 5 s holds) with an exclusion rectangle in their field and a circle across
//! it, every order `emplan plan` computes, with the shipped S1000's default
//! profile. Routing round the zones (`planner::detour`: the visibility graph built once, only
//! the pairs near a zone routed, each candidate path priced as its chain of legs) runs before
//! the solvers. Run with `cargo bench --bench detours`.

mod common;

use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use emplan::mission::fence::{LatLon, LocalShape, LocalZone, Shape, Zone};
use emplan::mission::{Enu, Mission};
use emplan::physics::VehicleModel;
use emplan::planner::{plan_mission, PlanOptions};

/// `n` waypoints of the study mission, those in or near the zones dropped, with the zones.
fn fenced(n: usize) -> Mission {
    let mut mission = common::study_mission(n);
    let shapes = [
        LocalShape::Polygon(vec![
            [5.0, -20.0],
            [21.0, -20.0],
            [21.0, -12.0],
            [5.0, -12.0],
        ]),
        LocalShape::Circle {
            center: [-15.0, 15.0],
            radius_m: 4.0,
        },
    ];
    let local: Vec<LocalZone> = shapes
        .iter()
        .map(|shape| LocalZone {
            inclusion: false,
            shape: shape.clone(),
        })
        .collect();
    mission.waypoints.retain(|w| {
        let p = [w.position.x_east_m, w.position.y_north_m];
        local
            .iter()
            .all(|z| !z.contains(p) && z.distance_to_boundary_m(p) > 8.0)
    });
    let origin = mission.origin;
    let ll = |p: [f64; 2]| {
        let g = origin.to_geodetic(Enu {
            x_east_m: p[0],
            y_north_m: p[1],
            z_up_m: 0.0,
        });
        LatLon {
            lat_deg: g.lat_deg,
            lon_deg: g.lon_deg,
        }
    };
    mission.fence.zones = shapes
        .iter()
        .map(|shape| Zone {
            inclusion: false,
            shape: match shape {
                LocalShape::Polygon(v) => Shape::Polygon(v.iter().map(|&p| ll(p)).collect()),
                LocalShape::Circle { center, radius_m } => Shape::Circle {
                    center: ll(*center),
                    radius_m: *radius_m,
                },
            },
        })
        .collect();
    mission
}

fn detours_bench(c: &mut Criterion) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000");
    let model = VehicleModel::load(&dir, None).expect("the shipped vehicle");
    let options = PlanOptions::default();
    let mut group = c.benchmark_group("plan_fenced");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    for n in [20, 100, 400] {
        let m = fenced(n);
        group.bench_with_input(BenchmarkId::from_parameter(n), &m, |b, m| {
            b.iter(|| plan_mission(m, &model, &options).expect("planned"))
        });
    }
    group.finish();
}

criterion_group!(benches, detours_bench);
criterion_main!(benches);
