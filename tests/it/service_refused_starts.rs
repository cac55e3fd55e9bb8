//! Starts through the service (`POST /api/vehicle/start`) that cannot fly: with no mission on
//! the vehicle the start is refused before anything is armed, and the upload after it is served
//! at once; a start the autopilot denies (its mission cleared behind the service's back)
//! disarms, ends at once naming the autopilot's answer, and leaves no flight folder. And the
//! service's log names the mission uploaded, not another of the folder's at the same home.

use std::path::Path;
use std::time::Duration;

use emplan::link::transfer::{Command, Rto};
use emplan::service::client::Answer;
use emplan::service::wire::{Event, Failure};
use emplan::service::{Client, Token, VehicleLink};
use serde_json::json;

use super::service::{
    connected, ground_station, own_mock, planned, root, serve, spawn_serve, upload, wait_end,
    wait_start, Reaped,
};

/// Hang guard for a request that must not wait on the vehicle (the defect made them wait
/// 60 s); not a measure of speed.
const PROMPT: Duration = Duration::from_secs(20);

fn connect_to(mock: &emplan::sim::MockHandle) -> VehicleLink {
    VehicleLink::Connect {
        url: format!("udpout:{}", mock.local_addr()),
        signing_key: None,
    }
}

/// The flight folders in `log_dir`.
fn flight_dirs(log_dir: &Path) -> Vec<String> {
    std::fs::read_dir(log_dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok())
                .filter(|e| e.path().is_dir())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default()
}

async fn start(client: &Client) -> Answer {
    tokio::time::timeout(PROMPT, client.post("/api/vehicle/start", &json!({})))
        .await
        .expect("the start answers without waiting out a resend loop")
        .expect("POST start")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_start_with_no_mission_on_the_vehicle_is_refused_before_arming_and_an_upload_after_it_is_served(
) {
    let mock = own_mock(20.0).await;
    let service = serve(connect_to(&mock), &["paper-sample-3wp.toml"]).await;
    let client = &service.client;
    connected(client).await;
    planned(client, "paper-sample-3wp.toml").await;

    let refused = start(client).await;
    assert_eq!(refused.status, 409, "{refused:?}");
    let doc: Failure = serde_json::from_value(refused.body.clone()).expect("a failure document");
    assert_eq!(doc.stage, "vehicle", "{refused:?}");
    assert!(
        doc.error.contains("no mission on the vehicle"),
        "{}",
        doc.error
    );
    let vehicle = mock.vehicle().expect("the mock flies");
    assert_eq!(vehicle.arms, 0, "the mock was armed");
    assert!(!vehicle.armed);
    assert_eq!(flight_dirs(&service.log_dir), Vec::<String>::new());

    // The vehicle actor is free at once.
    let uploaded = tokio::time::timeout(PROMPT, upload(client, "paper-sample-3wp.toml", json!({})))
        .await
        .expect("the upload is served without waiting for the start");
    assert!(uploaded.ok(), "{uploaded:?}");
    assert_eq!(mock.vehicle().expect("the mock").arms, 0);
    service.shutdown().await.expect("clean stop");
    mock.shutdown().await.expect("mock stops");
}

/// Clears the mock's mission from a ground station of the test's own.
async fn clear_mission(mock: &emplan::sim::MockHandle) {
    let (link, target, cfg) = ground_station(mock).await;
    emplan::link::driver::command(
        &link,
        &target,
        Command::clear_all(cfg, Rto::new(cfg.timing)),
    )
    .await
    .expect("cleared");
    assert!(mock.mission().is_empty());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_start_the_autopilot_denies_disarms_and_ends_at_once_naming_its_answer_and_leaves_no_flight_folder(
) {
    let mock = own_mock(20.0).await;
    let service = serve(connect_to(&mock), &["paper-sample-3wp.toml"]).await;
    let client = &service.client;
    connected(client).await;
    planned(client, "paper-sample-3wp.toml").await;
    let uploaded = upload(client, "paper-sample-3wp.toml", json!({})).await;
    assert!(uploaded.ok(), "{uploaded:?}");
    // Another ground station clears it: the service still believes its upload is there.
    clear_mission(&mock).await;
    let mut events = client.events().await.expect("events");

    let denied = start(client).await;
    assert_eq!(denied.status, 502, "{denied:?}");
    let doc: Failure = serde_json::from_value(denied.body.clone()).expect("a failure document");
    assert_eq!(doc.stage, "start");
    assert_eq!(
        doc.result.as_deref(),
        Some("MAV_RESULT_DENIED"),
        "{denied:?}"
    );
    let error = doc.error.as_str();
    assert!(
        error.contains("mission start") && error.contains("No valid mission"),
        "{error}"
    );
    assert!(error.contains("disarmed again"), "{error}");
    let vehicle = mock.vehicle().expect("the mock flies");
    assert_eq!(vehicle.arms, 1, "armed once, never again");
    assert!(!vehicle.armed, "left armed");

    // The flight folder the arming opened (when a heartbeat showed it armed) goes.
    let mut dir = None;
    let window = tokio::time::Instant::now() + Duration::from_secs(3);
    while let Ok(Some(Ok(event))) = events
        .next_within(window.saturating_duration_since(tokio::time::Instant::now()))
        .await
    {
        if let Ok(Event::FlightStarted { dir: opened, .. }) = serde_json::from_value(event) {
            dir = Some(opened);
            wait_end(&mut events, 20).await;
            break;
        }
    }
    let deadline = tokio::time::Instant::now() + PROMPT;
    while !flight_dirs(&service.log_dir).is_empty() {
        assert!(
            tokio::time::Instant::now() < deadline,
            "flight folders left: {:?} (opened {dir:?})",
            flight_dirs(&service.log_dir)
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }

    // An upload after it is served, and the mission is there again.
    let again = tokio::time::timeout(PROMPT, upload(client, "paper-sample-3wp.toml", json!({})))
        .await
        .expect("the upload is served at once");
    assert!(again.ok(), "{again:?}");
    assert!(!mock.mission().is_empty());
    service.shutdown().await.expect("clean stop");
    mock.shutdown().await.expect("mock stops");
}

#[cfg(unix)]
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_serve_log_names_the_mission_uploaded_not_another_at_the_same_home() {
    let work = tempfile::tempdir().expect("temp dir");
    let missions = work.path().join("missions");
    std::fs::create_dir_all(&missions).expect("dir");
    // Both samples take off from the same home; 3wp is listed first.
    for f in ["paper-sample-3wp.toml", "paper-sample-8wp.toml"] {
        std::fs::copy(root().join("missions").join(f), missions.join(f)).expect("copied");
    }
    let log_dir = work.path().join("flights");
    let token_file = work.path().join("token");
    let log = work.path().join("serve.log");
    let args = [
        "--missions",
        missions.to_str().unwrap(),
        "--log-dir",
        log_dir.to_str().unwrap(),
        "--http",
        "127.0.0.1:0",
        "--token-file",
        token_file.to_str().unwrap(),
        "--speedup",
        "20",
    ];
    let (serve, url) = spawn_serve(&args, &log);
    let _serve = Reaped(serve);
    let token = Token::new(&std::fs::read_to_string(&token_file).expect("token")).expect("token");
    let client = Client::new(&url, Some(token)).expect("client");
    connected(&client).await;
    planned(&client, "paper-sample-8wp.toml").await;
    let mut events = client.events().await.expect("events");
    let uploaded = upload(&client, "paper-sample-8wp.toml", json!({})).await;
    assert!(uploaded.ok(), "{uploaded:?}");
    let started = start(&client).await;
    assert!(started.ok(), "{started:?}");
    wait_start(&mut events, 30).await;
    // The flight's mission as the service logs it, once it has read the vehicle's back.
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    let line = loop {
        let text = std::fs::read_to_string(&log).unwrap_or_default();
        if let Some(line) = text
            .lines()
            .find(|l| l.contains("flying the mission") || l.contains("measuring against"))
        {
            break line.to_string();
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "no line naming the flight's mission in the log:\n{text}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    assert!(
        line.contains("flying the mission paper-sample-8wp planned"),
        "{line}"
    );
}
