//! Criterion bench of one energy-table build, simulated in parallel on all cores (rayon): the
//! shipped S1000's `hvb` table on the full default grid (Xf 0..150 m every 1 m, Zf -60..+60 m
//! every 0.5 m: 36 391 operations), and its `px4` table (PX4's generator run in 10 ms steps, each
//! step priced) on a coarse grid of the same extent (every 5 m by every 2 m: 1891 operations), so
//! that ten samples finish in minutes. Full builds of every profile are timed with `time emplan
//! table build` (README). Run with `cargo bench --bench table`.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use emplan::physics::table::{Axis, DEFAULT_XF, DEFAULT_ZF};
use emplan::physics::{EnergyTable, Profile, VehicleSource};

fn table_bench(c: &mut Criterion) {
    let vehicle = VehicleSource::BuiltIn.vehicle().expect("built-in vehicle");
    let coarse_xf = Axis {
        count: 31,
        ..DEFAULT_XF
    };
    let coarse_zf = Axis {
        count: 61,
        ..DEFAULT_ZF
    };
    let mut group = c.benchmark_group("table_build");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(30));
    for (name, profile, xf, zf) in [
        ("hvb_full_grid", Profile::Hvb, DEFAULT_XF, DEFAULT_ZF),
        ("px4_coarse_grid", Profile::Px4, coarse_xf, coarse_zf),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                EnergyTable::build(&vehicle, profile, xf, zf, |_, _| {}).expect("the table builds")
            })
        });
    }
    group.finish();
}

criterion_group!(benches, table_bench);
criterion_main!(benches);
