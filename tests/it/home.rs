//! Sending a flying vehicle home over the link (`link::commands::return_home`, the energy
//! guard's `rtl` action) against the built-in mock: acknowledged, the vehicle in its return mode,
//! and landed at home, its mission left unfinished.

use std::time::Duration;

use emplan::link::flight::{Start, StartConfig};
use emplan::sim::vehicle::Mode;

use super::service::{ground_station, own_mock, root};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_vehicle_sent_home_mid_mission_returns_and_lands_at_home() {
    let mock = own_mock(40.0).await;
    let (link, target, cfg) = ground_station(&mock).await;
    let mission =
        emplan::mission::load(&root().join("missions/paper-sample-8wp.toml")).expect("mission");
    let order: Vec<usize> = (0..mission.waypoints.len()).collect();
    let items = emplan::link::items::mission_items(
        &mission,
        &order,
        &emplan::link::items::ItemOptions::default(),
    )
    .expect("items");
    emplan::link::driver::upload_verified(&link, &target, &items, cfg, |_, _| {})
        .await
        .expect("uploaded");
    let mut start = Start::new(target, StartConfig::default());
    emplan::link::commands::drive(&link, &target, &mut start)
        .await
        .expect("link");
    assert_eq!(start.finished(), Some(&Ok(())));

    // Out on the mission: past its second waypoint.
    let deadline = tokio::time::Instant::now() + Duration::from_secs(60);
    loop {
        let v = mock.vehicle().expect("the mock flies");
        if v.current.is_some_and(|c| c >= 4) {
            break;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "never got out: {v:?}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let sent = emplan::link::commands::return_home(&link, &target)
        .await
        .expect("link");
    assert_eq!(sent, Ok(()));
    assert_eq!(mock.vehicle().expect("flies").mode, Mode::Rtl);

    let deadline = tokio::time::Instant::now() + Duration::from_secs(60);
    let landed = loop {
        let v = mock.vehicle().expect("the mock flies");
        if !v.armed {
            break v;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "never landed: {v:?}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    let [e, n, u] = landed.position;
    assert!(
        e.hypot(n) < 1.0 && u.abs() < 0.5,
        "landed at {:?}",
        landed.position
    );
    assert!(!landed.mission_complete, "{landed:?}");
}
