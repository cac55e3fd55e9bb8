//! Criterion bench of the flight controller's own logs: reading a 30-minute PX4 ULog (the real
//! SITL fixture's flight repeated with shifted timestamps, `ulog::synthetic_long`: ten flights
//! one after the other) and an ArduPilot DataFlash log of the same length (the trimmed real
//! fixture's records repeated), and reporting the ULog whole (read, measured against the
//! flight's plan, the report built). Targets: at least 100 MB/s read, a 30-minute ULog reported
//! in under 2 s. Run with `cargo bench --bench onboard`.

use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use emplan::flightlog::flight_plan::FlightPlan;
use emplan::flightlog::onboard::{self, ulog};
use emplan::flightlog::replay::{analyse, Replay};
use emplan::flightlog::segment::SegmentConfig;

const DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/onboard");
const MINUTES: f64 = 30.0;

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(Path::new(DIR).join(name)).expect("the fixture is there")
}

/// The DataFlash fixture repeated `times` times, as many times as the ULog repeats its flight
/// (its FMT records and timestamps repeat too: a reading bench, not a flight).
fn long_dataflash(times: usize) -> Vec<u8> {
    let one = fixture("arducopter-8wp.bin");
    let mut out = Vec::with_capacity(one.len() * times);
    for _ in 0..times {
        out.extend_from_slice(&one);
    }
    out
}

fn bench(c: &mut Criterion) {
    let template = fixture("px4-sih-8wp.ulg");
    let long = ulog::synthetic_long(&template, MINUTES).expect("a long ULog");
    let times = long.len().div_ceil(template.len());
    let plan = FlightPlan::read_json(&Path::new(DIR).join("px4-sih-8wp.plan.json")).expect("plan");

    let mut group = c.benchmark_group("onboard");
    group.sample_size(10);
    group.throughput(Throughput::Bytes(long.len() as u64));
    group.bench_function("read a 30-minute ulog", |b| {
        b.iter(|| onboard::parse("long.ulg", &long).expect("reads"))
    });
    group.bench_function("report a 30-minute ulog", |b| {
        b.iter(|| {
            let log = onboard::parse("long.ulg", &long).expect("reads");
            let replay = Replay {
                frames: log.stamped.len() as u64,
                stamped: log.stamped,
                ..Replay::default()
            };
            analyse(replay, plan.clone(), "long", SegmentConfig::default()).expect("measured")
        })
    });
    let dataflash = long_dataflash(times);
    group.throughput(Throughput::Bytes(dataflash.len() as u64));
    group.bench_function("read a dataflash log as long", |b| {
        b.iter(|| onboard::parse("long.bin", &dataflash).expect("reads"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
