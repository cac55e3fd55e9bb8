//! The service's ledger: `GET /api/packs` and the ledger's flights in `GET /api/flights`
//! (filtered by vehicle, pack, mission and date) from a ledger filled by hand, read as the wire's
//! types; a service whose ledger does not exist yet lists none and makes none; the pack named at
//! upload kept in the flight's plan.json, and the flight flown on the built-in mock landing in
//! the ledger under that pack.

use std::path::Path;

use emplan::flightlog::recorder::read_flight_plan;
use emplan::ledger::{
    packs, FlightRecord, FlightSource, Ledger, LedgerSpec, Outcome, PackFit, PartRecord,
};
use emplan::service::wire::{Failure, FlightsList, PacksView, UploadRequest};

use super::service::{builtin, connected, planned, poll, read, serve, serve_after, upload};
use super::service::{wait_end, wait_start};

/// A flight of `pack` (None: no pack named) with the capacity its voltage showed (Ah, of a
/// 10 Ah label) and the charge it drew.
fn record(
    id: &str,
    pack: Option<&str>,
    mission: &str,
    started_at: &str,
    capacity_ah: f64,
    charge_ah: f64,
) -> FlightRecord {
    FlightRecord {
        id: id.to_string(),
        source: FlightSource::Directory,
        path: format!("flights/{id}"),
        vehicle: Some("s1000".to_string()),
        pack: pack.map(str::to_string),
        mission: mission.to_string(),
        profile: Some("px4".to_string()),
        wind_m_s: None,
        wind_from_deg: None,
        autopilot: Some("px4".to_string()),
        started_at: Some(started_at.to_string()),
        outcome: Outcome::Completed,
        duration_s: 400.0,
        predicted_j: Some(150_000.0),
        measured_j: Some(155_000.0),
        charge_ah: Some(charge_ah),
        parts: vec![PartRecord {
            index: 0,
            kind: "takeoff".to_string(),
            name: String::new(),
            predicted_j: Some(10_000.0),
            measured_j: Some(10_400.0),
            duration_s: Some(12.0),
        }],
        guard: None,
        pack_fit: Some(PackFit {
            capacity_ah,
            label_capacity_ah: 10.0,
            capacity_sd_ah: 0.1,
            internal_resistance_ohm: 0.02,
            state_of_charge_at_takeoff: 0.98,
            samples: 2000,
            voltage_rms_v: 0.05,
        }),
    }
}

/// The flights written by hand: pack A three times (fading), pack B once, one without a pack.
fn hand_filled() -> Vec<FlightRecord> {
    vec![
        record("f1", Some("A"), "survey", "2026-03-01T09:00:00Z", 8.7, 6.0),
        record(
            "f2",
            Some("B"),
            "inspection",
            "2026-03-01T10:00:00Z",
            9.5,
            5.0,
        ),
        record("f3", Some("A"), "survey", "2026-03-02T09:00:00Z", 8.6, 6.0),
        record("f4", None, "survey", "2026-03-02T11:00:00Z", 9.0, 4.0),
        record(
            "f5",
            Some("A"),
            "inspection",
            "2026-03-03T09:00:00Z",
            8.5,
            6.0,
        ),
    ]
}

fn write_ledger(log_dir: &Path, records: &[FlightRecord]) {
    std::fs::create_dir_all(log_dir).expect("log dir");
    let mut ledger =
        Ledger::open(&LedgerSpec::Sqlite(log_dir.join("ledger.sqlite"))).expect("ledger");
    for r in records {
        ledger.write(r).expect("written");
    }
}

fn ids(list: &FlightsList) -> Vec<&str> {
    list.records.iter().map(|r| r.id.as_str()).collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_packs_and_the_ledgers_flights_are_served_typed_and_filtered_from_a_ledger_filled_by_hand(
) {
    let records = hand_filled();
    let service = serve_after(builtin(20.0), &[], |dir| write_ledger(dir, &records)).await;
    let client = &service.client;
    let ledger_file = service.log_dir.join("ledger.sqlite");

    let answer = client.get("/api/packs").await.expect("GET packs");
    assert!(answer.ok(), "{answer:?}");
    let view: PacksView = read(&answer);
    assert!(view.exists);
    assert_eq!(view.ledger, ledger_file.display().to_string());
    let names: Vec<&str> = view.packs.iter().map(|p| p.summary.name.as_str()).collect();
    assert_eq!(names, ["A", "B"]);
    // What the library makes of the same flights, served as it is.
    let expected = packs::summarise(&records);
    let summaries: Vec<_> = view.packs.iter().map(|p| p.summary.clone()).collect();
    assert_eq!(summaries, expected);
    assert_eq!(view.packs[0].summary.flights, 3);
    assert_eq!(view.packs[1].summary.flights, 1);
    // Pack A's flights, oldest first: each one's capacity, at the pack's age at its middle
    // (6 Ah drawn a flight from a 10 Ah label).
    let a = &view.packs[0].history;
    let flights: Vec<&str> = a.iter().map(|p| p.flight.as_str()).collect();
    assert_eq!(flights, ["f1", "f3", "f5"]);
    let capacities: Vec<f64> = a.iter().map(|p| p.capacity_ah.expect("fitted")).collect();
    assert_eq!(capacities, [8.7, 8.6, 8.5]);
    for (point, cycles) in a.iter().zip([0.3, 0.9, 1.5]) {
        let got = point.cycles.expect("a label");
        assert!(
            (got - cycles).abs() < 1e-9,
            "{}: {got} cycles",
            point.flight
        );
    }

    // The ledger's flights, newest first, filtered by each field.
    let all: FlightsList = read(&client.get("/api/flights").await.expect("GET"));
    assert_eq!(ids(&all), ["f5", "f4", "f3", "f2", "f1"]);
    assert_eq!(all.records[0], records[4]);
    assert_eq!(all.ledger_error, None);
    assert!(
        all.flights.is_empty(),
        "no flight directory: {:?}",
        all.flights
    );
    for (query, expected) in [
        ("?pack=A", vec!["f5", "f3", "f1"]),
        ("?pack=A&mission=survey", vec!["f3", "f1"]),
        ("?mission=inspection", vec!["f5", "f2"]),
        ("?vehicle=s1000&pack=B", vec!["f2"]),
        ("?vehicle=another", vec![]),
        ("?since=2026-03-02", vec!["f5", "f4", "f3"]),
        ("?until=2026-03-01T23:59:59Z", vec!["f2", "f1"]),
        (
            "?since=2026-03-01T09:30:00Z&until=2026-03-02T10:00:00Z",
            vec!["f3", "f2"],
        ),
        ("?pack=&vehicle=", vec!["f5", "f4", "f3", "f2", "f1"]),
    ] {
        let list: FlightsList = read(
            &client
                .get(&format!("/api/flights{query}"))
                .await
                .expect("GET"),
        );
        assert_eq!(ids(&list), expected, "{query}");
    }
    // A date that is none is refused, naming the field.
    let refused = client
        .get("/api/flights?since=yesterday")
        .await
        .expect("GET");
    assert_eq!(refused.status, 400, "{refused:?}");
    let failure: Failure = read(&refused);
    assert!(
        failure.error.starts_with("since \"yesterday\""),
        "{}",
        failure.error
    );
    let refused = client
        .get("/api/flights?until=2026-02-30")
        .await
        .expect("GET");
    assert_eq!(refused.status, 400, "{refused:?}");
    let failure: Failure = read(&refused);
    assert!(
        failure.error.starts_with("until `2026-02-30`"),
        "{}",
        failure.error
    );
    service.shutdown().await.expect("clean stop");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_service_whose_ledger_does_not_exist_yet_lists_no_packs_and_makes_none() {
    let service = serve(builtin(20.0), &[]).await;
    let client = &service.client;
    let answer = client.get("/api/packs").await.expect("GET packs");
    assert!(answer.ok(), "{answer:?}");
    let view: PacksView = read(&answer);
    assert!(!view.exists);
    assert!(view.packs.is_empty());
    let list: FlightsList = read(&client.get("/api/flights?pack=A").await.expect("GET"));
    assert!(list.records.is_empty());
    assert_eq!(list.ledger_error, None);
    assert!(!service.log_dir.join("ledger.sqlite").exists());
    service.shutdown().await.expect("clean stop");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pack_named_at_upload_is_kept_in_the_flights_plan_and_the_flight_lands_in_the_ledger_under_it(
) {
    let service = serve(builtin(50.0), &["paper-sample-3wp.toml"]).await;
    let client = &service.client;
    let mut events = client.events().await.expect("events");
    connected(client).await;
    planned(client, "paper-sample-3wp.toml").await;
    let with_pack = |pack: &str| {
        serde_json::to_value(UploadRequest {
            pack: Some(pack.to_string()),
            ..UploadRequest::default()
        })
        .expect("JSON")
    };
    // A name with a control character is no pack's name.
    let refused = upload(client, "paper-sample-3wp.toml", with_pack("P\n7")).await;
    assert_eq!(refused.status, 400, "{refused:?}");
    let failure: Failure = read(&refused);
    assert!(
        failure.error.starts_with("pack") && failure.error.contains("control character"),
        "{}",
        failure.error
    );

    let uploaded = upload(client, "paper-sample-3wp.toml", with_pack("P7")).await;
    assert!(uploaded.ok(), "{uploaded:?}");
    let start = client
        .post("/api/vehicle/start", &serde_json::json!({}))
        .await
        .expect("POST start");
    assert!(start.ok(), "{start:?}");
    let (name, dir) = wait_start(&mut events, 30).await;
    let (ended, _, _) = wait_end(&mut events, 90).await;
    assert_eq!(ended, name);
    let plan = read_flight_plan(&dir).expect("plan.json");
    assert_eq!(plan.pack.map(|p| p.name).as_deref(), Some("P7"));

    // Written once its files are complete: the pack appears with its flight.
    let answer = poll(client, "/api/packs", 30, |a| {
        a.parse::<PacksView>()
            .is_ok_and(|v| v.packs.iter().any(|p| p.summary.name == "P7"))
    })
    .await;
    let view: PacksView = read(&answer);
    assert!(view.exists);
    let pack = view
        .packs
        .iter()
        .find(|p| p.summary.name == "P7")
        .expect("P7");
    assert_eq!(pack.summary.flights, 1);
    assert_eq!(pack.history.len(), 1);
    let list: FlightsList = read(&client.get("/api/flights?pack=P7").await.expect("GET"));
    assert_eq!(list.records.len(), 1);
    assert_eq!(list.records[0].pack.as_deref(), Some("P7"));
    assert!(
        list.records[0].path.ends_with(&name),
        "{} is not the flight {name}",
        list.records[0].path
    );
    assert_eq!(list.flights[0].name, name);
    service.shutdown().await.expect("clean stop");
}
