//! The energy guard in the service (`emplan serve --guard rtl --mock-vehicle DIR`): the
//! built-in mock flies a vehicle heavier than the plan's with a smaller pack; the service's
//! event stream carries the guard's warning and its return, and the flight's report says the
//! vehicle was sent home. `--mock-vehicle` with `--connect` is refused.

use emplan::service::{Client, Token};
use serde_json::json;

use super::emplan;
use super::guard::{heavier_vehicle, mission};
use super::service::{
    connected, flight_ended, planned, spawn_serve, upload, wait_for, wait_start, Reaped,
};
use emplan::flightlog::watch::{GuardNote, NoteKind};
use emplan::service::wire::Event;

#[test]
fn serve_refuses_a_mock_vehicle_with_connect() {
    let work = tempfile::tempdir().expect("temp dir");
    let truth = heavier_vehicle(work.path());
    let (ok, _, err) = emplan(&[
        "serve",
        "--connect",
        "udpin:127.0.0.1:0",
        "--missions",
        work.path().to_str().unwrap(),
        "--log-dir",
        work.path().join("flights").to_str().unwrap(),
        "--mock-vehicle",
        truth.to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(
        err.contains("--mock-vehicle is for the built-in mock (no --connect)"),
        "{err}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn serve_flies_the_mock_vehicle_and_its_guard_sends_it_home() {
    let work = tempfile::tempdir().expect("temp dir");
    let missions = work.path().join("missions");
    std::fs::create_dir_all(&missions).expect("dir");
    let written = mission(&missions);
    let name = written.file_name().unwrap().to_str().unwrap().to_string();
    let truth = heavier_vehicle(work.path());
    let token_file = work.path().join("token");
    let log_dir = work.path().join("flights");
    let args = [
        "--missions",
        missions.to_str().unwrap(),
        "--log-dir",
        log_dir.to_str().unwrap(),
        "--http",
        "127.0.0.1:0",
        "--token-file",
        token_file.to_str().unwrap(),
        "--guard",
        "rtl",
        "--mock-vehicle",
        truth.to_str().unwrap(),
        "--speedup",
        "50",
    ];
    let (serve, url) = spawn_serve(&args, &work.path().join("serve.log"));
    let _serve = Reaped(serve);
    let token = Token::new(&std::fs::read_to_string(&token_file).expect("token")).expect("token");
    let client = Client::new(&url, Some(token)).expect("client");
    connected(&client).await;
    planned(&client, &name).await;
    let mut events = client.events().await.expect("events");
    let uploaded = upload(&client, &name, json!({})).await;
    assert!(uploaded.ok(), "{uploaded:?}");
    let started = client
        .post("/api/vehicle/start", &json!({}))
        .await
        .expect("POST start");
    assert!(started.ok(), "{started:?}");
    let (flown, _) = wait_start(&mut events, 30).await;
    // The guard's notes as events, up to the flight's end.
    let notes = std::cell::RefCell::new(Vec::<GuardNote>::new());
    let ended = wait_for(&mut events, 120, |e| {
        if let Event::Guard { flight, note } = e {
            assert_eq!(flight, &flown, "{e:?}");
            notes.borrow_mut().push(note.clone());
        }
        flight_ended(e).is_some()
    })
    .await;
    let notes = notes.into_inner();
    assert!(
        notes.iter().any(|n| n.verdict == "below_reserve"),
        "{notes:?}"
    );
    assert_eq!(
        notes.iter().filter(|n| n.kind == NoteKind::Return).count(),
        1,
        "{notes:?}"
    );
    let (_, _, report) = flight_ended(&ended).expect("an end");
    let guard = report.and_then(|r| r.guard).expect("the guard's report");
    assert!(guard.returned, "{guard:?}");
    assert!(
        guard.notes.iter().any(|n| n.kind == NoteKind::Return),
        "{guard:?}"
    );
    assert!(
        guard.notes.iter().any(|n| n.verdict == "below_reserve"),
        "{guard:?}"
    );
}
