//! Verified upload over loopback UDP against the mock autopilot with the settings every user gets
//! (no tuning): seeded loss, duplication and reordering, NACKs, a lost final ack, a reboot
//! mid-upload, each flavour's storage rules (the action commands included), a vehicle holding
//! something else than was sent, and the CLI's failure document.

use std::path::Path;
use std::time::Duration;

use emplan::link::connection::{Identity, Link};
use emplan::link::driver::{upload_verified, UploadError, UploadReport};
use emplan::link::items::{mission_items, ItemOptions};
use emplan::link::mav::{MavMissionResult, MISSION_ITEM_INT_DATA};
use emplan::link::transfer::{Stage, TransferConfig};
use emplan::link::{testing, Flavour};
use emplan::sim::{Faults, MockAutopilot, MockConfig};

fn sample_items(flavour: Flavour) -> Vec<MISSION_ITEM_INT_DATA> {
    let mission = emplan::mission::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/paper-sample-8wp.toml"),
    )
    .unwrap();
    let order =
        emplan::tour::order_waypoints(&mission, emplan::tour::Objective::Distance, None).unwrap();
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

/// Whether the mock holds exactly what was sent (NaN parameters included).
fn holds(stored: &[MISSION_ITEM_INT_DATA], items: &[MISSION_ITEM_INT_DATA]) -> bool {
    emplan::link::readback::verify(Flavour::Generic, items, stored).is_ok()
}

/// Uploads `items` (the sample mission built for the mock's flavour when None) to a fresh mock
/// with the CLI's default transfer settings (`budget` overrides the time budget); returns the
/// outcome and what the mock stored.
async fn upload_once(
    config: MockConfig,
    items: Option<Vec<MISSION_ITEM_INT_DATA>>,
    budget: Option<Duration>,
) -> (
    Result<UploadReport, UploadError>,
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
    assert_eq!(target.flavour, config.flavour);
    let items = items.unwrap_or_else(|| sample_items(config.flavour));
    let cfg = TransferConfig {
        target_system: target.system_id,
        target_component: target.component_id,
        budget,
        ..TransferConfig::default()
    };
    let result = upload_verified(&link, &target, &items, cfg, |_, _| {}).await;
    let stored = mock.mission();
    drop(link);
    mock.shutdown().await.unwrap();
    (result, items, stored)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_hundred_seeded_uploads_with_default_settings_over_a_link_losing_thirty_percent_each_way_all_end_verified(
) {
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
        tasks.push(tokio::spawn(upload_once(config, None, None)));
    }
    let mut not_acked = 0;
    for (seed, task) in tasks.into_iter().enumerate() {
        let (result, items, stored) = task.await.unwrap();
        let report = result.unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        assert!(report.verified);
        assert!(
            holds(&stored, &items),
            "seed {seed}: the mock holds what was sent"
        );
        if !report.acked {
            not_acked += 1;
        }
    }
    // PX4 sends its final ack once: with 30% loss some are lost and read-back settles them.
    assert!(not_acked > 0, "no final ack was ever lost at 30% loss");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn twenty_seeded_thirty_item_uploads_to_a_mavsdk_like_mock_at_thirty_percent_loss_all_verify()
{
    // The Generic flavour gives a transfer up after five tries as MAVSDK's MissionRawServer
    // does; the upload and the read-back must start again and finish within their budget.
    let faults = Faults {
        loss_up: 0.3,
        loss_down: 0.3,
        ..Faults::default()
    };
    let mut tasks = Vec::new();
    for seed in 0..20u64 {
        let config = MockConfig {
            flavour: Flavour::Generic,
            faults,
            seed: 1000 + seed,
            ..MockConfig::default()
        };
        let items = testing::mission(Flavour::Generic, 30);
        tasks.push(tokio::spawn(upload_once(config, Some(items), None)));
    }
    for (seed, task) in tasks.into_iter().enumerate() {
        let (result, items, stored) = task.await.unwrap();
        let report = result.unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        assert!(report.verified);
        assert_eq!(stored.len(), items.len());
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_nack_on_an_item_is_never_reported_as_done() {
    let mut tasks = Vec::new();
    for seed in 0..20u64 {
        let lossy = seed % 2 == 1;
        let faults = Faults {
            loss_up: if lossy { 0.3 } else { 0.0 },
            loss_down: if lossy { 0.3 } else { 0.0 },
            nack_item: Some(3),
            nack_result: Some(MavMissionResult::MAV_MISSION_INVALID_PARAM7),
            ..Faults::default()
        };
        let config = MockConfig {
            faults,
            seed,
            ..MockConfig::default()
        };
        tasks.push(tokio::spawn(upload_once(
            config,
            None,
            Some(Duration::from_secs(15)),
        )));
    }
    for (seed, task) in tasks.into_iter().enumerate() {
        let (result, _, stored) = task.await.unwrap();
        let err = result.expect_err("a NACKed upload must not be done");
        assert!(!err.accepted);
        if seed % 2 == 0 {
            // Without loss the NACK itself arrives and is reported by name and item.
            assert_eq!(err.stage, Stage::Upload);
            assert_eq!(err.item, Some(3));
            assert_eq!(
                err.refusal,
                Some(MavMissionResult::MAV_MISSION_INVALID_PARAM7)
            );
            assert_eq!(
                err.to_string(),
                "upload: the autopilot refused at item 3: MAV_MISSION_INVALID_PARAM7"
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
    let (result, items, stored) = upload_once(config, None, None).await;
    let report = result.unwrap();
    assert!(!report.acked && report.verified);
    assert!(holds(&stored, &items));
}

#[tokio::test]
async fn a_reboot_mid_upload_is_outlasted_by_starting_again_from_count() {
    // The mock forgets the transfer at item 4 and goes silent, as a rebooted PX4 would; after
    // PX4's 5 s transfer timeout the upload starts again from MISSION_COUNT.
    let config = MockConfig {
        faults: Faults {
            reboot_at_item: Some(4),
            ..Faults::default()
        },
        ..MockConfig::default()
    };
    let (result, items, stored) = upload_once(config, None, None).await;
    let report = result.unwrap();
    assert!(report.verified && report.acked);
    assert_eq!(report.restarts, 1);
    assert!(holds(&stored, &items));
}

#[tokio::test]
async fn an_ardupilot_mock_is_waited_out_while_it_boots_and_verifies_despite_its_own_home() {
    // Item 0 reads back as the mock's home (16.1 m where the mission says 16.0), acceptance
    // radius and NaN yaw as 0: ArduPilot's storage, not a difference.
    let config = MockConfig {
        flavour: Flavour::ArduPilot,
        ..MockConfig::default()
    };
    let (result, items, stored) = upload_once(config, None, None).await;
    let report = result.unwrap();
    assert!(report.verified);
    assert!(report.refusals >= 1, "the 2 s boot refusal was seen");
    // Home, take-off, the 8 waypoints, the return to the origin, the landing.
    assert_eq!(stored.len(), 1 + 1 + 8 + 1 + 1);
    assert_eq!(stored[0].z, items[0].z);
}

/// Take-off, a waypoint, then every action command (camera, gimbal, region of interest, yaw,
/// payload, delay, speed, spline) with typical values, each in the frame `link::support` gives
/// for `flavour`; with `all`, also those the flavour does not take. ArduPilot: its home first.
fn actions(flavour: Flavour, all: bool) -> Vec<MISSION_ITEM_INT_DATA> {
    use emplan::link::items::item;
    use emplan::link::mav::{MavCmd, MavFrame};
    use emplan::link::support::{action_frame, takes};
    use num_traits::FromPrimitive;
    let (lat, lon) = (385_362_000, -1_217_875_000);
    let (wp_lat, wp_lon) = (385_366_500, -1_217_869_300);
    let relative = MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT;
    let mut items = Vec::new();
    if flavour == Flavour::ArduPilot {
        let home = [0.0; 4];
        items.push(item(
            MavCmd::MAV_CMD_NAV_WAYPOINT,
            MavFrame::MAV_FRAME_GLOBAL,
            home,
            lat,
            lon,
            16.0,
        ));
    }
    let nan = f32::NAN;
    items.push(item(
        MavCmd::MAV_CMD_NAV_TAKEOFF,
        relative,
        [0.0, 0.0, 0.0, nan],
        lat,
        lon,
        20.0,
    ));
    items.push(item(
        MavCmd::MAV_CMD_NAV_WAYPOINT,
        relative,
        [2.5, 0.0, 0.0, nan],
        wp_lat,
        wp_lon,
        25.0,
    ));
    // (command, params, x, y, z, has a position): as sitl/probe_actions.py sent them.
    let commands: [(u16, [f32; 4], i32, i32, f32, bool); 20] = [
        (203, [1.0, 2.0, 0.0, 0.0], 1, 3, 0.0, false),
        (2000, [0.0, 2.5, 3.0, 4.0], 0, 0, 0.0, false),
        (2001, [0.0; 4], 0, 0, 0.0, false),
        (2500, [0.0; 4], 0, 0, 0.0, false),
        (2501, [0.0; 4], 0, 0, 0.0, false),
        (206, [12.5, 0.0, 1.0, 0.0], 0, 0, 0.0, false),
        (205, [-90.0, 0.0, 30.0, 0.0], 0, 0, 2.0, false),
        (1000, [-45.5, 30.5, 0.0, 0.0], 12, 0, 1.0, false),
        (195, [0.0; 4], 385_367_000, -1_217_868_000, 10.55, true),
        (197, [0.0; 4], 0, 0, 0.0, false),
        (
            201,
            [3.0, 0.0, 0.0, 0.0],
            385_367_000,
            -1_217_868_000,
            10.55,
            true,
        ),
        (115, [90.0, 20.0, 1.0, 0.0], 0, 0, 0.0, false),
        (183, [9.0, 1900.0, 0.0, 0.0], 0, 0, 0.0, false),
        (181, [0.0, 1.0, 0.0, 0.0], 0, 0, 0.0, false),
        (211, [1.0, 0.0, 0.0, 0.0], 0, 0, 0.0, false),
        (42600, [1.0, 1.0, 2.5, 0.5], 0, 0, 0.0, false),
        (93, [7.5, -1.0, -1.0, -1.0], 0, 0, 0.0, false),
        (19, [12.5, 0.0, 0.0, 0.0], wp_lat, wp_lon, 25.55, true),
        (178, [1.0, 8.5, -1.0, 0.0], 0, 0, 0.0, false),
        (82, [2.5, 0.0, 0.0, 0.0], wp_lat, wp_lon, 25.55, true),
    ];
    for (command, params, x, y, z, located) in commands {
        if !all && !takes(flavour, command) {
            continue;
        }
        let frame = action_frame(flavour, command, located);
        items.push(item(
            MavCmd::from_u16(command).unwrap(),
            frame,
            params,
            x,
            y,
            z,
        ));
    }
    for (seq, it) in items.iter_mut().enumerate() {
        it.seq = seq as u16;
    }
    items
}

#[tokio::test]
async fn every_action_each_flavour_takes_uploads_to_its_mock_and_verifies_by_its_storage() {
    for (flavour, taken) in [
        (Flavour::Px4, 16),
        (Flavour::ArduPilot, 20),
        (Flavour::Generic, 20),
    ] {
        let config = MockConfig {
            flavour,
            ..MockConfig::default()
        };
        let items = actions(flavour, false);
        let before = if flavour == Flavour::ArduPilot { 3 } else { 2 };
        assert_eq!(items.len(), before + taken, "{flavour:?}");
        let (result, _, stored) = upload_once(config, Some(items.clone()), None).await;
        let report = result.unwrap_or_else(|e| panic!("{flavour:?}: {e}"));
        assert!(report.verified, "{flavour:?}");
        assert_eq!(stored.len(), items.len(), "{flavour:?}");
    }
}

#[tokio::test]
async fn a_px4_mock_refuses_a_condition_yaw_by_name_and_item() {
    let items = actions(Flavour::Px4, true);
    let yaw = items
        .iter()
        .position(|it| it.command as u32 == 115)
        .unwrap();
    let (result, _, stored) = upload_once(MockConfig::default(), Some(items), None).await;
    let err = result.expect_err("PX4 takes no CONDITION_YAW");
    assert_eq!(
        (err.stage, err.accepted, err.item, err.refusal),
        (
            Stage::Upload,
            false,
            Some(yaw as u16),
            Some(MavMissionResult::MAV_MISSION_UNSUPPORTED)
        )
    );
    assert!(stored.is_empty());
}

#[tokio::test]
async fn a_px4_mock_answering_in_int_frames_verifies() {
    let (result, _, _) = upload_once(MockConfig::default(), None, None).await;
    assert!(result.unwrap().verified);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_vehicle_holding_a_different_latitude_is_caught_for_every_flavour() {
    for flavour in [Flavour::Px4, Flavour::ArduPilot, Flavour::Generic] {
        let config = MockConfig {
            flavour,
            boot: Duration::ZERO,
            faults: Faults {
                corrupt_readback: Some(3),
                ..Faults::default()
            },
            ..MockConfig::default()
        };
        let (result, _, _) = upload_once(config, None, None).await;
        let err = result.expect_err("a different item must not verify");
        assert_eq!(
            (err.stage, err.accepted, err.item),
            (Stage::Verify, true, Some(3)),
            "{flavour:?}: {err}"
        );
        assert!(
            err.to_string()
                .starts_with("verify: item 3 x (latitude, degE7) differs"),
            "{err}"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_five_hundred_item_mission_uploads_and_verifies_over_loopback() {
    let items = testing::mission(Flavour::Px4, 500);
    let started = std::time::Instant::now();
    let (result, _, stored) = upload_once(MockConfig::default(), Some(items.clone()), None).await;
    let report = result.unwrap();
    println!(
        "500 items: upload {:.3} s, read-back {:.3} s, total {:.3} s",
        report.upload_s,
        report.verify_s,
        started.elapsed().as_secs_f64()
    );
    assert!(report.acked && report.verified);
    assert!(holds(&stored, &items));
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
        budget: Some(Duration::from_secs(2)),
        ..cfg
    };
    let err = upload_verified(&unsigned, &target, &items, cfg, |_, _| {})
        .await
        .unwrap_err();
    assert!(
        err.to_string().starts_with(
            "upload: gave up after 2.0 s (the time budget) waiting for the autopilot's first item request"
        ),
        "{err}"
    );
    assert_eq!(mock.stats(), before);
    drop(unsigned);
    mock.shutdown().await.unwrap();
}

#[tokio::test]
async fn set_current_and_clear_all_are_confirmed_by_the_mock() {
    use emplan::link::driver::{command, download};
    use emplan::link::transfer::{Command, Rto};
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
    let rto = Rto::new(cfg.timing);
    command(&link, &target, Command::set_current(cfg, rto, 4))
        .await
        .unwrap();
    command(&link, &target, Command::clear_all(cfg, rto))
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

#[tokio::test]
async fn a_tcp_autopilot_that_opens_its_port_late_is_waited_for() {
    // Reserve a port, close it, and open it again a moment after connecting starts.
    let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = probe.local_addr().unwrap();
    drop(probe);
    let url = format!("tcpout:{addr}");
    let late = tokio::spawn(async move {
        tokio::time::sleep(Duration::from_millis(600)).await;
        let listener = tokio::net::TcpListener::bind(addr).await.unwrap();
        let _ = listener.accept().await;
    });
    assert!(Link::connect(&url, Identity::default(), None)
        .await
        .is_err());
    let link = Link::connect_within(&url, Identity::default(), None, Duration::from_secs(5)).await;
    assert!(link.is_ok(), "{:?}", link.err());
    late.abort();
}

/// Runs `emplan upload --json` against a mock started here; returns (success, stdout JSON).
fn upload_json(config: MockConfig, extra: &[&str]) -> (bool, serde_json::Value) {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let mock = runtime
        .block_on(MockAutopilot::spawn("udpin:127.0.0.1:0", config))
        .unwrap();
    let url = format!("udpout:{}", mock.local_addr());
    let mut args = vec![
        "upload",
        "missions/paper-sample-3wp.toml",
        "--connect",
        url.as_str(),
        "--json",
    ];
    args.extend_from_slice(extra);
    let (ok, stdout, stderr) = crate::emplan(&args);
    runtime.block_on(mock.shutdown()).unwrap();
    let doc = serde_json::from_str(&stdout)
        .unwrap_or_else(|e| panic!("not one JSON document ({e}): {stdout}\n{stderr}"));
    (ok, doc)
}

#[test]
fn a_failed_upload_with_json_prints_one_document_naming_stage_acceptance_and_item() {
    let config = MockConfig {
        faults: Faults {
            corrupt_readback: Some(2),
            ..Faults::default()
        },
        ..MockConfig::default()
    };
    let (ok, doc) = upload_json(config, &[]);
    assert!(!ok, "a different read-back must fail: {doc}");
    assert_eq!(doc["ok"], false);
    assert_eq!(doc["stage"], "verify");
    assert_eq!(doc["accepted"], true);
    assert_eq!(doc["item"], 2);
    assert!(doc["error"]
        .as_str()
        .unwrap()
        .contains("item 2 x (latitude, degE7) differs"));
    let nacked = MockConfig {
        faults: Faults {
            nack_item: Some(1),
            nack_result: Some(MavMissionResult::MAV_MISSION_DENIED),
            ..Faults::default()
        },
        ..MockConfig::default()
    };
    let (ok, doc) = upload_json(nacked, &[]);
    assert!(!ok);
    assert_eq!(
        (
            &doc["stage"],
            &doc["accepted"],
            &doc["item"],
            &doc["result"]
        ),
        (
            &serde_json::json!("upload"),
            &serde_json::json!(false),
            &serde_json::json!(1),
            &serde_json::json!("MAV_MISSION_DENIED")
        )
    );
    // Nobody on the port: the connect stage.
    let (ok, stdout, _) = crate::emplan(&[
        "upload",
        "missions/paper-sample-3wp.toml",
        "--connect",
        "udpout:127.0.0.1:9",
        "--discover-s",
        "1",
        "--json",
    ]);
    assert!(!ok);
    let doc: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(
        (&doc["stage"], &doc["accepted"]),
        (&serde_json::json!("connect"), &serde_json::json!(false))
    );
}

/// Runs `emplan upload` (text) of the 3-waypoint sample, with `extra` arguments, to a mock of
/// `flavour` standing at its origin whose autopilot holds `held` (NAME, value) instead of the
/// built-in vehicle file's trajectory parameters; returns (success, stderr).
fn upload_to_a_mock_holding(
    flavour: Flavour,
    held: &[(&str, f64)],
    extra: &[&str],
) -> (bool, String) {
    let mission = emplan::mission::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/paper-sample-3wp.toml"),
    )
    .unwrap();
    let home = mission.origin.home;
    let held: Vec<(String, f64)> = held.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    let mut vehicle = emplan::physics::builtin::vehicle().unwrap();
    vehicle.px4 = vehicle.px4.with_autopilot_values(&held);
    vehicle.ardupilot = vehicle.ardupilot.with_autopilot_values(&held);
    let config = MockConfig {
        flavour,
        boot: Duration::ZERO,
        home: emplan::sim::storage::Home {
            lat_e7: emplan::link::items::deg_e7(home.lat_deg),
            lon_e7: emplan::link::items::deg_e7(home.lon_deg),
            alt_m: home.alt_m as f32,
        },
        // Standing at its home: its parameter server answers.
        flight: Some(emplan::sim::FlightConfig {
            home,
            ..emplan::sim::FlightConfig::default()
        }),
        ..MockConfig::default()
    };
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let mock = runtime
        .block_on(MockAutopilot::spawn_with_vehicle(
            "udpin:127.0.0.1:0",
            config,
            vehicle,
        ))
        .unwrap();
    let url = format!("udpout:{}", mock.local_addr());
    let mut args = vec![
        "upload",
        "missions/paper-sample-3wp.toml",
        "--connect",
        url.as_str(),
    ];
    args.extend_from_slice(extra);
    let (ok, _, stderr) = crate::emplan(&args);
    runtime.block_on(mock.shutdown()).unwrap();
    (ok, stderr)
}

#[test]
fn upload_warns_of_a_px4_holding_other_trajectory_parameters_by_name_as_fly_does() {
    let (ok, stderr) = upload_to_a_mock_holding(
        Flavour::Px4,
        &[("MPC_XY_CRUISE", 8.0), ("MPC_ACC_HOR", 2.0)],
        &[],
    );
    assert!(ok, "{stderr}");
    for (name, value) in [("MPC_XY_CRUISE", 8), ("MPC_ACC_HOR", 2)] {
        assert!(
            stderr.contains(&format!("warning: PX4 parameter {name} is {value}")),
            "{stderr}"
        );
    }
    // A PX4 at the vehicle file's values is not warned of.
    let (ok, stderr) = upload_to_a_mock_holding(Flavour::Px4, &[], &[]);
    assert!(ok, "{stderr}");
    assert!(!stderr.contains("parameter"), "{stderr}");
}

#[test]
fn upload_warns_of_an_ardupilot_holding_other_navigation_parameters_naming_ardupilot() {
    let file = emplan::physics::builtin::vehicle().unwrap();
    let (name, value) = file.ardupilot.autopilot_values()[0];
    let held = value + 2.0;
    let (ok, stderr) = upload_to_a_mock_holding(
        Flavour::ArduPilot,
        &[(name, held)],
        &["--profile", "ardupilot"],
    );
    assert!(ok, "{stderr}");
    assert!(
        stderr.contains(&format!("warning: ArduPilot parameter {name} is {held}")),
        "{stderr}"
    );
    assert!(!stderr.contains("PX4"), "{stderr}");
}
