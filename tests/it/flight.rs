//! The mock autopilot flies over loopback UDP: a verified upload of the sample mission, arm and
//! MAV_CMD_MISSION_START sent as COMMAND_LONGs on the link, telemetry watched until the vehicle
//! has landed and disarmed, in a few seconds of wall time thanks to the simulated-time speed-up.

use std::path::Path;
use std::time::{Duration, Instant};

use emplan::link::connection::{Autopilot, Identity, Link};
use emplan::link::driver::upload_verified;
use emplan::link::items::{mission_items, Ending, ItemOptions};
use emplan::link::mav::{
    MavCmd, MavLandedState, MavMessage, MavModeFlag, MavResult, MissionState, COMMAND_LONG_DATA,
    MISSION_ITEM_INT_DATA,
};
use emplan::link::transfer::TransferConfig;
use emplan::mission::{Enu, Mission, Waypoint};
use emplan::sim::{Faults, FlightConfig, MockAutopilot, MockConfig, MockHandle};

/// The sample mission as `fly` lays it out: take-off, the waypoints, back to the origin, land.
fn sample() -> (Mission, Vec<MISSION_ITEM_INT_DATA>) {
    let mission = emplan::mission::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/paper-sample-8wp.toml"),
    )
    .unwrap();
    let mut with_return = mission.clone();
    with_return.waypoints.push(Waypoint {
        name: "origin".into(),
        position: Enu::default(),
        hover_s: 0.0,
        ..Default::default()
    });
    let order: Vec<usize> = (0..with_return.waypoints.len()).collect();
    let opts = ItemOptions {
        ending: Ending::Land,
        ..ItemOptions::default()
    };
    let items = mission_items(&with_return, &order, &opts).unwrap();
    (mission, items)
}

/// Spawns a mock flying from the sample's home, connects, discovers it and uploads `items`
/// (verified).
async fn mock_with_mission(
    config: MockConfig,
    items: &[MISSION_ITEM_INT_DATA],
) -> (MockHandle, Link, Autopilot) {
    let (mission, _) = sample();
    let config = MockConfig {
        flight: Some(FlightConfig {
            home: mission.origin.home,
            ..config.flight.unwrap_or_default()
        }),
        ..config
    };
    let mock = MockAutopilot::spawn("udpin:127.0.0.1:0", config)
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
    let cfg = TransferConfig {
        target_system: target.system_id,
        target_component: target.component_id,
        flavour: target.flavour,
        ..TransferConfig::default()
    };
    let report = upload_verified(&link, &target, items, cfg, |_, _| {})
        .await
        .unwrap();
    assert!(report.verified);
    (mock, link, target)
}

/// Sends a COMMAND_LONG until its COMMAND_ACK arrives (every 300 ms, for up to 10 s).
async fn command(link: &Link, target: &Autopilot, command: MavCmd, params: [f32; 7]) -> MavResult {
    let mut rx = link.subscribe();
    let message = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1: params[0],
        param2: params[1],
        param3: params[2],
        param4: params[3],
        param5: params[4],
        param6: params[5],
        param7: params[6],
        command,
        target_system: target.system_id,
        target_component: target.component_id,
        confirmation: 0,
    });
    for _ in 0..33 {
        link.send(&message).await.unwrap();
        let waited = tokio::time::timeout(Duration::from_millis(300), async {
            loop {
                match rx.recv().await {
                    Ok((_, MavMessage::COMMAND_ACK(a))) if a.command == command => return a.result,
                    Ok(_) | Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => {}
                    Err(e) => panic!("link closed: {e}"),
                }
            }
        })
        .await;
        if let Ok(result) = waited {
            return result;
        }
    }
    panic!("no COMMAND_ACK for {command:?}");
}

/// What the ground saw of one flight.
#[derive(Debug, Default)]
struct Seen {
    mission_seqs: Vec<u16>,
    mission_states: Vec<MissionState>,
    landed_states: Vec<MavLandedState>,
    reached: Vec<u16>,
    armed: Vec<bool>,
    last_boot_ms: u32,
    battery_messages: usize,
}

fn push_new<T: PartialEq>(list: &mut Vec<T>, x: T) {
    if list.last() != Some(&x) {
        list.push(x);
    }
}

/// Uploads the sample, arms, starts it and watches until disarmed with the mission complete.
async fn fly(config: MockConfig, wall_limit: Duration) -> (Seen, Duration) {
    let (_, items) = sample();
    let (mock, link, target) = mock_with_mission(config, &items).await;
    let started = Instant::now();
    // BATTERY_STATUS at 20 Hz; the landed state at 10 Hz, so the 1 s spool-up on the ground is
    // seen from the ack on.
    let accepted = MavResult::MAV_RESULT_ACCEPTED;
    for (id, interval_us) in [(147.0, 50_000.0), (245.0, 100_000.0)] {
        let params = [id, interval_us, 0.0, 0.0, 0.0, 0.0, 0.0];
        let result = command(&link, &target, MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL, params).await;
        assert_eq!(result, accepted);
    }
    let arm = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    assert_eq!(
        command(&link, &target, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, arm).await,
        accepted
    );
    assert_eq!(
        command(&link, &target, MavCmd::MAV_CMD_MISSION_START, [0.0; 7]).await,
        accepted
    );
    // Watch from the start on (a lost command retried after PX4's 10 s pre-flight disarm
    // would otherwise show an early disarm).
    let mut rx = link.subscribe();
    let mut seen = Seen::default();
    let watched = tokio::time::timeout(wall_limit, async {
        loop {
            let message = match rx.recv().await {
                Ok((_, m)) => m,
                Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => continue,
                Err(e) => panic!("link closed: {e}"),
            };
            match message {
                MavMessage::MISSION_CURRENT(c) => {
                    push_new(&mut seen.mission_seqs, c.seq);
                    push_new(&mut seen.mission_states, c.mission_state);
                    let complete = c.mission_state == MissionState::MISSION_STATE_COMPLETE;
                    if complete && seen.armed.ends_with(&[true, false]) {
                        return;
                    }
                }
                MavMessage::EXTENDED_SYS_STATE(e) => {
                    push_new(&mut seen.landed_states, e.landed_state)
                }
                MavMessage::MISSION_ITEM_REACHED(r) => push_new(&mut seen.reached, r.seq),
                MavMessage::GLOBAL_POSITION_INT(p) => {
                    seen.last_boot_ms = seen.last_boot_ms.max(p.time_boot_ms)
                }
                MavMessage::BATTERY_STATUS(_) => seen.battery_messages += 1,
                MavMessage::HEARTBEAT(h) => {
                    let armed = h
                        .base_mode
                        .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
                    push_new(&mut seen.armed, armed);
                }
                _ => {}
            }
        }
    })
    .await;
    let elapsed = started.elapsed();
    assert!(
        watched.is_ok(),
        "not landed and disarmed within {wall_limit:?}: {seen:?}"
    );
    drop(link);
    mock.shutdown().await.unwrap();
    (seen, elapsed)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_mock_flies_the_uploaded_sample_to_landing_and_disarm_in_seconds_of_wall_time() {
    let (seen, elapsed) = fly(MockConfig::default(), Duration::from_secs(60)).await;
    // Every item in turn, PX4's mission states, landed states and reached messages.
    assert_eq!(
        seen.mission_seqs,
        (0..=10).collect::<Vec<u16>>(),
        "{seen:?}"
    );
    assert_eq!(
        seen.mission_states.last(),
        Some(&MissionState::MISSION_STATE_COMPLETE)
    );
    assert_eq!(
        seen.landed_states,
        [
            MavLandedState::MAV_LANDED_STATE_ON_GROUND,
            MavLandedState::MAV_LANDED_STATE_TAKEOFF,
            MavLandedState::MAV_LANDED_STATE_IN_AIR,
            MavLandedState::MAV_LANDED_STATE_LANDING,
            MavLandedState::MAV_LANDED_STATE_ON_GROUND
        ]
    );
    assert_eq!(seen.reached, (0..=10).collect::<Vec<u16>>());
    // The flight takes minutes of vehicle time and seconds of wall time (about 8 s at the
    // default 20x; the bound only shows the speed-up works, even on a loaded machine).
    let flown_s = f64::from(seen.last_boot_ms) / 1000.0;
    eprintln!("{flown_s} s of simulated flight in {elapsed:?} of wall time");
    assert!(flown_s > 150.0, "{flown_s} s of simulated flight");
    assert!(
        elapsed < Duration::from_secs(20),
        "{elapsed:?} of wall time"
    );
    assert!(
        seen.battery_messages as f64 > 15.0 * flown_s,
        "BATTERY_STATUS at 20 Hz as asked"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_mock_flies_to_the_end_with_twenty_percent_loss_each_way() {
    let lossy = MockConfig {
        faults: Faults {
            loss_up: 0.2,
            loss_down: 0.2,
            ..Faults::default()
        },
        seed: 11,
        speedup: 50.0,
        ..MockConfig::default()
    };
    let (seen, _) = fly(lossy, Duration::from_secs(60)).await;
    assert_eq!(
        seen.mission_states.last(),
        Some(&MissionState::MISSION_STATE_COMPLETE)
    );
    assert_eq!(seen.mission_seqs.last(), Some(&10));
    assert_eq!(
        seen.landed_states.last(),
        Some(&MavLandedState::MAV_LANDED_STATE_ON_GROUND)
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_autostarting_ardupilot_mock_flies_an_uploaded_mission_by_itself() {
    let (mission, _) = sample();
    let opts = ItemOptions {
        flavour: emplan::link::Flavour::ArduPilot,
        ending: Ending::Land,
        ..ItemOptions::default()
    };
    // Only the first two waypoints, then land where the vehicle is: a short flight.
    let items = mission_items(&mission, &[0, 1], &opts).unwrap();
    let config = MockConfig {
        flavour: emplan::link::Flavour::ArduPilot,
        speedup: 50.0,
        autostart: true,
        ..MockConfig::default()
    };
    let (mock, link, _) = mock_with_mission(config, &items).await;
    let flew = tokio::time::timeout(Duration::from_secs(20), async {
        let mut was_armed = false;
        loop {
            tokio::time::sleep(Duration::from_millis(50)).await;
            let state = mock.vehicle().unwrap();
            was_armed |= state.armed;
            if was_armed && !state.armed {
                return state;
            }
        }
    })
    .await
    .expect("the mock armed, flew and disarmed by itself");
    assert!(flew.mission_complete, "{flew:?}");
    assert_eq!(flew.mode, emplan::sim::vehicle::Mode::Mission);
    drop(link);
    mock.shutdown().await.unwrap();
}
