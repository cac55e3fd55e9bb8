//! Criterion bench of a verified 500-item upload (upload + read-back) over loopback UDP against
//! the built-in mock autopilot (PX4 flavour), with the default transfer settings: what the link
//! code costs per item on a clean link. The same-run comparison with MAVSDK's and pymavlink's
//! clients against MAVSDK's server is `sitl/lossy-compare.sh speed`.
//! Run with `cargo bench --bench upload`.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use emplan::link::connection::{Identity, Link};
use emplan::link::driver::upload_verified;
use emplan::link::testing;
use emplan::link::transfer::TransferConfig;
use emplan::link::Flavour;
use emplan::sim::{MockAutopilot, MockConfig};

fn upload_bench(c: &mut Criterion) {
    // One thread, as `emplan upload` runs its link: no cross-thread wake-ups per message.
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("a tokio runtime");
    let (mock, link, target) = runtime.block_on(async {
        let mock = MockAutopilot::spawn("udpin:127.0.0.1:0", MockConfig::default())
            .await
            .expect("mock");
        let link = Link::connect(
            &format!("udpout:{}", mock.local_addr()),
            Identity::default(),
            None,
        )
        .await
        .expect("link");
        let target = link
            .discover(Duration::from_secs(5))
            .await
            .expect("mock heartbeat");
        (mock, link, target)
    });
    let items = testing::mission(Flavour::Px4, 500);
    let cfg = TransferConfig {
        target_system: target.system_id,
        target_component: target.component_id,
        ..TransferConfig::default()
    };
    let mut group = c.benchmark_group("upload");
    group.sample_size(20);
    group.bench_function("500_items_upload_and_read_back_loopback_mock", |b| {
        b.iter(|| {
            let report = runtime
                .block_on(upload_verified(&link, &target, &items, cfg, |_, _| {}))
                .expect("verified");
            assert!(report.verified);
        })
    });
    group.finish();
    drop(link);
    runtime.block_on(mock.shutdown()).expect("mock stops");
}

criterion_group!(benches, upload_bench);
criterion_main!(benches);
