//! Criterion bench of `emplan ledger import` (`session::import`) on onboard logs, on 2 threads:
//! each log read, measured against its plan (a plan.json beside the PX4 ULog; the mission the
//! DataFlash log holds), its pack fitted to its voltage and current, and its record written to a
//! fresh SQLite ledger. Two field days: twenty 3-minute logs (the real SITL fixtures, ten of
//! each autopilot, under names of their own) and four 30-minute logs (the fixtures made long as
//! `benches/onboard.rs` makes them: the ULog by `ulog::synthetic_long`, the DataFlash log
//! repeated). Throughput is the logs' bytes; the target is at least 200 MB/s. Run with
//! `cargo bench --bench ledger`.

use std::path::{Path, PathBuf};

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use emplan::flightlog::onboard::ulog;
use emplan::ledger::{Ledger, LedgerSpec};
use emplan::session::import::{self, ImportOptions, Input};

const DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/onboard");
const MINUTES: f64 = 30.0;
const JOBS: usize = 2;

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(Path::new(DIR).join(name)).expect("the fixture is there")
}

/// Writes `count` copies each of `ulog` (each in a folder of its own with the PX4 flight's
/// plan.json beside it) and `dataflash` under `root/name`, and returns the inputs.
fn logs(root: &Path, name: &str, count: usize, ulog: &[u8], dataflash: &[u8]) -> Vec<Input> {
    let plan = fixture("px4-sih-8wp.plan.json");
    let dir = root.join(name);
    let mut paths: Vec<PathBuf> = Vec::new();
    for k in 0..count {
        let px4 = dir.join(format!("px4-{k:02}"));
        std::fs::create_dir_all(&px4).expect("a folder");
        std::fs::write(px4.join("plan.json"), &plan).expect("written");
        let log = px4.join(format!("{name}-px4-{k:02}.ulg"));
        std::fs::write(&log, ulog).expect("written");
        paths.push(log);
        let log = dir.join(format!("{name}-ardupilot-{k:02}.bin"));
        std::fs::write(&log, dataflash).expect("written");
        paths.push(log);
    }
    let found = import::inputs(&paths, true);
    assert!(found.failed.is_empty(), "{:?}", found.failed);
    found.inputs
}

fn bench(c: &mut Criterion) {
    let tmp = tempfile::tempdir().expect("a temporary folder");
    let template = fixture("px4-sih-8wp.ulg");
    let dataflash = fixture("arducopter-8wp.bin");
    let long = ulog::synthetic_long(&template, MINUTES).expect("a long ULog");
    let times = long.len().div_ceil(template.len());
    let long_dataflash: Vec<u8> = dataflash.repeat(times);
    let days = [
        (
            "twenty 3-minute logs",
            logs(tmp.path(), "short", 10, &template, &dataflash),
        ),
        (
            "four 30-minute logs",
            logs(tmp.path(), "long", 2, &long, &long_dataflash),
        ),
    ];
    let options = ImportOptions {
        jobs: Some(JOBS),
        ..ImportOptions::default()
    };
    let mut group = c.benchmark_group("ledger import");
    group.sample_size(10);
    let mut ledgers = 0;
    for (what, inputs) in &days {
        let bytes: u64 = inputs.iter().map(|i| i.bytes).sum();
        group.throughput(Throughput::Bytes(bytes));
        group.bench_function(format!("{what}, {JOBS} threads"), |b| {
            b.iter_batched(
                || {
                    ledgers += 1;
                    let spec = LedgerSpec::Sqlite(tmp.path().join(format!("l{ledgers}.sqlite")));
                    Ledger::open(&spec).expect("a fresh ledger")
                },
                |mut ledger| {
                    let summary =
                        import::import(inputs, &mut ledger, &options, &|_| {}).expect("imports");
                    assert!(summary.failed.is_empty(), "{:?}", summary.failed);
                    assert_eq!(summary.inserted, inputs.len());
                    ledger
                },
                BatchSize::PerIteration,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
