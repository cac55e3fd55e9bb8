//! Verified upload over loopback UDP against the mock autopilot, under seeded loss, duplication
//! and reordering, with NACKs, a lost final ack and a reboot mid-upload.

use std::path::Path;
use std::time::Duration;

use emplan::link::connection::{Identity, Link};
use emplan::link::driver::{upload_verified, DriverError};
use emplan::link::items::{mission_items, ItemOptions};
use emplan::link::mav::{MavMissionResult, MISSION_ITEM_INT_DATA};
use emplan::link::transfer::{TransferConfig, TransferError};
use emplan::link::Flavour;
use emplan::sim::{Faults, MockAutopilot, MockConfig};

fn sample_items(flavour: Flavour) -> Vec<MISSION_ITEM_INT_DATA> {
    let mission = emplan::mission::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/paper-sample-8wp.toml"),
    )
    .unwrap();
    let order =
        emplan::plan::order_waypoints(&mission, emplan::plan::Objective::Distance, None).unwrap();
    mission_items(
        &mission,
        &order,
        &ItemOptions {
            flavour,
            ..ItemOptions::default()
        },
    )
    .unwrap()
}

/// Timeouts for a very lossy link: wait 300 ms, retry many times.
fn lossy() -> TransferConfig {
    TransferConfig {
        timeout: Duration::from_millis(300),
        retries: 40,
        ..TransferConfig::default()
    }
}

async fn upload_once(
    config: MockConfig,
    cfg: TransferConfig,
) -> (
    Result<emplan::link::driver::UploadReport, DriverError>,
    Vec<MISSION_ITEM_INT_DATA>,
    Vec<MISSION_ITEM_INT_DATA>,
) {
    let mock = MockAutopilot::spawn("udpin:127.0.0.1:0", config)
        .await
        .unwrap();
    let url = format!("udpout:{}", mock.local_addr());
    let link = Link::connect(&url, Identity::default(), None)
        .await
        .unwrap();
    let target = link.discover(Duration::from_secs(20)).await.unwrap();
    let flavour = match config.flavour {
        emplan::sim::Flavour::Px4 => Flavour::Px4,
        emplan::sim::Flavour::ArduPilot => Flavour::ArduPilot,
    };
    assert_eq!(target.flavour, flavour);
    let items = sample_items(flavour);
    let cfg = TransferConfig {
        target_system: target.system_id,
        target_component: target.component_id,
        ..cfg
    };
    let result = upload_verified(&link, &target, &items, cfg, |_, _| {}).await;
    let stored = mock.mission();
    drop(link);
    mock.shutdown().await.unwrap();
    (result, items, stored)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_hundred_seeded_uploads_over_a_link_losing_thirty_percent_each_way_all_end_verified() {
    let faults = Faults {
        loss_up: 0.3,
        loss_down: 0.3,
        duplicate: 0.1,
        reorder: 0.1,
        ..Faults::default()
    };
    let mut tasks = Vec::new();
    for seed in 0..200u64 {
        let config = MockConfig {
            faults,
            seed,
            ..MockConfig::default()
        };
        tasks.push(tokio::spawn(upload_once(config, lossy())));
    }
    let mut not_acked = 0;
    for (seed, task) in tasks.into_iter().enumerate() {
        let (result, items, stored) = task.await.unwrap();
        let report = result.unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        assert!(report.verified);
        assert_eq!(stored.len(), items.len(), "seed {seed}");
        if !report.acked {
            not_acked += 1;
        }
    }
    // PX4 sends its final ack once: with 30% loss some are lost and read-back settles them.
    assert!(not_acked > 0, "no final ack was ever lost at 30% loss");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_nack_on_an_item_is_never_reported_as_done() {
    let mut tasks = Vec::new();
    for seed in 0..20u64 {
        let faults = Faults {
            loss_up: if seed % 2 == 0 { 0.0 } else { 0.3 },
            loss_down: if seed % 2 == 0 { 0.0 } else { 0.3 },
            nack_item: Some(3),
            nack_result: Some(MavMissionResult::MAV_MISSION_INVALID_PARAM7),
            ..Faults::default()
        };
        let config = MockConfig {
            faults,
            seed,
            ..MockConfig::default()
        };
        let cfg = TransferConfig {
            timeout: Duration::from_millis(200),
            retries: 10,
            ..TransferConfig::default()
        };
        tasks.push(tokio::spawn(upload_once(config, cfg)));
    }
    for (seed, task) in tasks.into_iter().enumerate() {
        let (result, _, stored) = task.await.unwrap();
        let err = result.expect_err("a NACKed upload must not be done");
        if seed % 2 == 0 {
            // Without loss the NACK itself arrives and is reported by name.
            assert!(
                matches!(&err, DriverError::Transfer(TransferError::Rejected { seq: 3, result }) if result == "MAV_MISSION_INVALID_PARAM7"),
                "{err}"
            );
        }
        assert!(
            stored.is_empty(),
            "seed {seed}: the PX4 mock keeps its previous (empty) mission"
        );
    }
}

#[tokio::test]
async fn a_lost_final_ack_is_settled_by_read_back() {
    let config = MockConfig {
        faults: Faults {
            drop_final_ack: true,
            ..Faults::default()
        },
        ..MockConfig::default()
    };
    let cfg = TransferConfig {
        timeout: Duration::from_millis(200),
        retries: 2,
        ..TransferConfig::default()
    };
    let (result, items, stored) = upload_once(config, cfg).await;
    let report = result.unwrap();
    assert!(!report.acked && report.verified);
    assert_eq!(stored.len(), items.len());
}

#[tokio::test]
async fn a_reboot_mid_upload_ends_in_an_error_naming_the_item_and_keeps_the_old_mission() {
    let config = MockConfig {
        faults: Faults {
            reboot_at_item: Some(4),
            ..Faults::default()
        },
        ..MockConfig::default()
    };
    let cfg = TransferConfig {
        timeout: Duration::from_millis(150),
        retries: 3,
        ..TransferConfig::default()
    };
    let (result, _, stored) = upload_once(config, cfg).await;
    let err = result.unwrap_err();
    assert!(err.to_string().starts_with("item 4:"), "{err}");
    assert!(stored.is_empty());
}

#[tokio::test]
async fn an_ardupilot_mock_gets_its_home_item_and_verifies() {
    let config = MockConfig {
        flavour: emplan::sim::Flavour::ArduPilot,
        ..MockConfig::default()
    };
    let (result, items, stored) = upload_once(config, TransferConfig::default()).await;
    assert!(result.unwrap().verified);
    assert_eq!(stored[0].frame, items[0].frame);
    assert_eq!(stored.len(), 8 + 3);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_five_hundred_item_mission_uploads_and_verifies_over_loopback() {
    let mock = MockAutopilot::spawn("udpin:127.0.0.1:0", MockConfig::default())
        .await
        .unwrap();
    let link = Link::connect(
        &format!("udpout:{}", mock.local_addr()),
        Identity::default(),
        None,
    )
    .await
    .unwrap();
    let target = link.discover(Duration::from_secs(10)).await.unwrap();
    let mut items = sample_items(Flavour::Px4);
    let waypoint = items[1].clone();
    items.truncate(1);
    for k in 0..498 {
        let mut it = waypoint.clone();
        it.x += k * 10;
        items.push(it);
    }
    items.push(sample_items(Flavour::Px4).last().unwrap().clone());
    for (seq, it) in items.iter_mut().enumerate() {
        it.seq = seq as u16;
    }
    assert_eq!(items.len(), 500);
    let cfg = TransferConfig {
        target_system: target.system_id,
        target_component: target.component_id,
        ..TransferConfig::default()
    };
    let started = std::time::Instant::now();
    let report = upload_verified(&link, &target, &items, cfg, |_, _| {})
        .await
        .unwrap();
    println!(
        "500 items: upload {:.3} s, read-back {:.3} s, total {:.3} s",
        report.upload_s,
        report.verify_s,
        started.elapsed().as_secs_f64()
    );
    assert!(report.acked && report.verified);
    assert_eq!(mock.mission().len(), 500);
}

#[tokio::test]
async fn a_signed_link_accepts_the_correctly_signed_mock_and_a_wrong_key_or_no_key_is_rejected() {
    let key = [7u8; 32];
    let config = MockConfig {
        signing_key: Some(key),
        ..MockConfig::default()
    };
    let mock = MockAutopilot::spawn("udpin:127.0.0.1:0", config)
        .await
        .unwrap();
    let url = format!("udpout:{}", mock.local_addr());
    let signed = |key: [u8; 32]| Some(mavlink::SigningConfig::new(key, 0, true, false));

    let link = Link::connect(&url, Identity::default(), signed(key))
        .await
        .unwrap();
    let target = link.discover(Duration::from_secs(5)).await.unwrap();
    let items = sample_items(Flavour::Px4);
    let cfg = TransferConfig {
        target_system: target.system_id,
        target_component: target.component_id,
        ..TransferConfig::default()
    };
    assert!(
        upload_verified(&link, &target, &items, cfg, |_, _| {})
            .await
            .unwrap()
            .verified
    );
    drop(link);

    // A wrong key: the mock's signed heartbeats fail verification here, and ours are dropped there.
    let wrong = Link::connect(&url, Identity::default(), signed([8u8; 32]))
        .await
        .unwrap();
    assert!(wrong.discover(Duration::from_millis(2500)).await.is_err());
    drop(wrong);
    // No key at all: the mock drops unsigned frames, so nothing we send reaches its server.
    let unsigned = Link::connect(&url, Identity::default(), None)
        .await
        .unwrap();
    let before = mock.stats();
    let target = unsigned.discover(Duration::from_secs(3)).await.unwrap();
    let cfg = TransferConfig {
        timeout: Duration::from_millis(200),
        retries: 2,
        target_system: target.system_id,
        target_component: target.component_id,
    };
    let err = upload_verified(&unsigned, &target, &items, cfg, |_, _| {})
        .await
        .unwrap_err();
    assert!(err.to_string().starts_with("count:"), "{err}");
    assert_eq!(mock.stats(), before);
    drop(unsigned);
    mock.shutdown().await.unwrap();
}

#[tokio::test]
async fn set_current_and_clear_all_are_confirmed_by_the_mock() {
    use emplan::link::driver::{download, run};
    use emplan::link::transfer::Command;
    let mock = MockAutopilot::spawn("udpin:127.0.0.1:0", MockConfig::default())
        .await
        .unwrap();
    let link = Link::connect(
        &format!("udpout:{}", mock.local_addr()),
        Identity::default(),
        None,
    )
    .await
    .unwrap();
    let target = link.discover(Duration::from_secs(5)).await.unwrap();
    let cfg = TransferConfig {
        target_system: target.system_id,
        target_component: target.component_id,
        ..TransferConfig::default()
    };
    upload_verified(&link, &target, &sample_items(Flavour::Px4), cfg, |_, _| {})
        .await
        .unwrap();
    run(&link, &target, &mut Command::set_current(cfg, 4), |_, _| {})
        .await
        .unwrap();
    run(&link, &target, &mut Command::clear_all(cfg), |_, _| {})
        .await
        .unwrap();
    assert!(mock.mission().is_empty());
    assert!(download(&link, &target, cfg).await.unwrap().is_empty());
    drop(link);
    mock.shutdown().await.unwrap();
}

#[tokio::test]
async fn a_tcp_link_reconnects_after_the_autopilot_closes_the_connection() {
    use tokio::io::AsyncWriteExt;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let url = format!("tcpout:{}", listener.local_addr().unwrap());
    let link = Link::connect(&url, Identity::default(), None)
        .await
        .unwrap();
    let heartbeat = |autopilot| {
        let mut bytes = Vec::new();
        let hb = emplan::link::mav::MavMessage::HEARTBEAT(emplan::link::mav::HEARTBEAT_DATA {
            autopilot,
            mavtype: emplan::link::mav::MavType::MAV_TYPE_OCTOROTOR,
            ..Default::default()
        });
        mavlink::write_v2_msg(
            &mut bytes,
            mavlink::MavHeader {
                system_id: 1,
                component_id: 1,
                sequence: 0,
            },
            &hb,
        )
        .unwrap();
        bytes
    };
    let (mut first, _) = listener.accept().await.unwrap();
    first
        .write_all(&heartbeat(
            emplan::link::mav::MavAutopilot::MAV_AUTOPILOT_PX4,
        ))
        .await
        .unwrap();
    assert_eq!(
        link.discover(Duration::from_secs(5)).await.unwrap().flavour,
        Flavour::Px4
    );
    drop(first);
    // The link notices the closed stream and dials again.
    let (mut second, _) = tokio::time::timeout(Duration::from_secs(10), listener.accept())
        .await
        .expect("reconnected")
        .unwrap();
    let rediscover = tokio::spawn(async move {
        link.discover(Duration::from_secs(5))
            .await
            .map(|a| a.flavour)
    });
    tokio::time::sleep(Duration::from_millis(100)).await;
    second
        .write_all(&heartbeat(
            emplan::link::mav::MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        ))
        .await
        .unwrap();
    assert_eq!(rediscover.await.unwrap().unwrap(), Flavour::ArduPilot);
}
