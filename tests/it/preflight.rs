//! The check before any upload that the vehicle stands where the plan starts, against mocks
//! standing elsewhere: a mission 2 km from the vehicle's home is refused before anything is
//! uploaded or armed, naming the distance; `--origin vehicle` plans it from the vehicle's home
//! (flown, or refused by the plan's own limits); a home within the tolerance changes nothing.

use emplan::mission::Geodetic;
use emplan::sim::{FlightConfig, MockAutopilot, MockConfig, MockHandle};
use serde_json::Value;

const SAMPLE: &str = "missions/paper-sample-3wp.toml";

/// The sample missions' origin, `north_deg` degrees of latitude to the north.
fn north_of_sample(north_deg: f64) -> Geodetic {
    Geodetic {
        lat_deg: 38.5362 + north_deg,
        lon_deg: -121.7875,
        alt_m: 16.0,
    }
}

/// A flying PX4 mock standing at `home`, on its own runtime.
fn mock_at(home: Geodetic) -> (tokio::runtime::Runtime, MockHandle) {
    let runtime = tokio::runtime::Runtime::new().expect("runtime");
    let config = MockConfig {
        flight: Some(FlightConfig {
            home,
            ..FlightConfig::default()
        }),
        speedup: 40.0,
        ..MockConfig::default()
    };
    let mock = runtime
        .block_on(MockAutopilot::spawn("udpin:127.0.0.1:0", config))
        .expect("mock");
    (runtime, mock)
}

/// Runs `emplan ARGS --connect <mock> --json`; returns (success, the document, stderr).
fn on_mock(mock: &MockHandle, args: &[&str]) -> (bool, Value, String) {
    let url = format!("udpout:{}", mock.local_addr());
    let mut all = args.to_vec();
    all.extend_from_slice(&["--connect", &url, "--json"]);
    let (ok, stdout, stderr) = crate::emplan(&all);
    let doc = serde_json::from_str(&stdout)
        .unwrap_or_else(|e| panic!("not one JSON document ({e}): {stdout}\n{stderr}"));
    (ok, doc, stderr)
}

fn nothing_uploaded_or_armed(mock: &MockHandle) {
    assert_eq!(mock.stats().uploads_accepted, 0, "{:?}", mock.stats());
    assert!(mock.mission().is_empty());
    assert_eq!(mock.vehicle().expect("it flies").arms, 0);
}

#[test]
fn a_mission_two_km_from_the_vehicles_home_is_refused_before_upload_naming_the_distance() {
    // 0.02 degrees of latitude: 2220 m.
    let (runtime, mock) = mock_at(north_of_sample(0.02));
    let logs = tempfile::tempdir().expect("dir");
    let log_dir = logs.path().to_str().unwrap();
    let (ok, doc, _) = on_mock(&mock, &["fly", SAMPLE, "--arm", "--log-dir", log_dir]);
    assert!(!ok, "{doc}");
    assert_eq!(
        (&doc["stage"], &doc["accepted"]),
        (&Value::from("preflight"), &Value::from(false)),
        "{doc}"
    );
    let error = doc["error"].as_str().expect("error");
    assert!(
        error.contains(
            "(38.556200, -121.787500) is 2220 m from the mission's origin (38.536200, -121.787500)"
        ),
        "both positions and the distance: {error}"
    );
    let (ok, doc, _) = on_mock(&mock, &["upload", SAMPLE]);
    assert!(!ok);
    assert_eq!(doc["stage"], "preflight", "{doc}");
    assert!(doc["error"].as_str().unwrap().contains("2220 m"), "{doc}");
    // From the vehicle's home the legs to the waypoints are over 2 km: the planner's limit.
    let (ok, doc, _) = on_mock(
        &mock,
        &[
            "fly",
            SAMPLE,
            "--arm",
            "--origin",
            "vehicle",
            "--log-dir",
            log_dir,
        ],
    );
    assert!(!ok);
    assert_eq!(doc["stage"], "plan", "{doc}");
    assert!(
        doc["error"].as_str().unwrap().contains("max_leg_m"),
        "{doc}"
    );
    nothing_uploaded_or_armed(&mock);
    assert_eq!(
        std::fs::read_dir(logs.path()).unwrap().count(),
        0,
        "no flight"
    );
    runtime.block_on(mock.shutdown()).unwrap();
}

#[test]
fn with_origin_vehicle_the_mission_is_planned_from_the_vehicles_home_and_flown() {
    // 0.0013 degrees of latitude: 145 m north, beyond the tolerance, within the legs' limit.
    let home = north_of_sample(0.0013);
    let (runtime, mock) = mock_at(home);
    let logs = tempfile::tempdir().expect("dir");
    let log_dir = logs.path().to_str().unwrap();
    let (ok, doc, _) = on_mock(&mock, &["fly", SAMPLE, "--arm", "--log-dir", log_dir]);
    assert!(!ok && doc["stage"] == "preflight", "{doc}");
    nothing_uploaded_or_armed(&mock);

    let (ok, doc, _) = on_mock(
        &mock,
        &[
            "fly",
            SAMPLE,
            "--arm",
            "--origin",
            "vehicle",
            "--log-dir",
            log_dir,
        ],
    );
    assert!(ok, "{doc}");
    assert_eq!(doc["complete"], true, "{doc}");
    // Planned from where the vehicle stands: no leg starts far from where it was planned to,
    // and the mission's first leg costs what the plan from the vehicle's home says.
    let legs = doc["legs"].as_array().expect("legs");
    assert_eq!(legs.len(), 4, "{doc}");
    for leg in legs {
        assert!(
            !leg["flags"].to_string().contains("far_start"),
            "a leg flown from elsewhere than planned: {leg}"
        );
    }
    let from_origin = crate::json(&["plan", SAMPLE, "--json"]);
    let flown_kj = doc["legs"][0]["predicted_kj"].as_f64().expect("priced");
    let planned_kj = from_origin["orders"][0]["legs"][0]["energy_kj"]
        .as_f64()
        .expect("priced");
    assert!(
        (flown_kj - planned_kj).abs() > 0.1,
        "{flown_kj} kJ against {planned_kj} kJ: the first leg is priced from the vehicle's home, not the mission's origin"
    );
    // The same places as the mission file: each waypoint's latitude and longitude.
    let mission = emplan::mission::load(&crate::service::root().join(SAMPLE)).expect("mission");
    let stored = mock.mission();
    for k in 0..mission.waypoints.len() {
        let (lat, lon, _) = mission.waypoint_relative(k).unwrap();
        let (x, y) = (
            emplan::link::items::deg_e7(lat),
            emplan::link::items::deg_e7(lon),
        );
        assert!(
            stored
                .iter()
                .any(|i| (i.x - x).abs() <= 1 && (i.y - y).abs() <= 1),
            "waypoint {k} at ({lat}, {lon}) not among the items flown"
        );
    }
    assert_eq!(mock.stats().uploads_accepted, 1);
    runtime.block_on(mock.shutdown()).unwrap();
}

#[test]
fn a_home_within_the_tolerance_changes_nothing() {
    // 1e-4 degrees of latitude: 11 m.
    let (runtime, mock) = mock_at(north_of_sample(1e-4));
    let (ok, doc, stderr) = on_mock(&mock, &["upload", SAMPLE]);
    assert!(ok, "{doc}\n{stderr}");
    assert_eq!(doc["report"]["verified"], true, "{doc}");
    let (ok, explicit, _) = on_mock(&mock, &["upload", SAMPLE, "--origin", "mission"]);
    assert!(ok, "{explicit}");
    assert_eq!(explicit["items"], doc["items"], "the same mission uploaded");
    runtime.block_on(mock.shutdown()).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_service_refuses_an_upload_to_a_vehicle_far_from_the_missions_origin() {
    use crate::service::{connected, planned, serve, upload};
    let config = MockConfig {
        flight: Some(FlightConfig {
            home: north_of_sample(0.02),
            ..FlightConfig::default()
        }),
        ..MockConfig::default()
    };
    let mock = MockAutopilot::spawn("udpin:127.0.0.1:0", config)
        .await
        .expect("mock");
    let vehicle = emplan::service::VehicleLink::Connect {
        url: format!("udpout:{}", mock.local_addr()),
        signing_key: None,
    };
    let service = serve(vehicle, &["paper-sample-3wp.toml"]).await;
    let client = &service.client;
    connected(client).await;
    planned(client, "paper-sample-3wp.toml").await;
    let refused = upload(client, "paper-sample-3wp.toml", serde_json::json!({})).await;
    assert_eq!(refused.status, 422, "{refused:?}");
    assert_eq!(
        (&refused.body["stage"], &refused.body["accepted"]),
        (&Value::from("preflight"), &Value::from(false)),
        "{refused:?}"
    );
    assert!(
        refused.body["error"].as_str().unwrap().contains("2220 m"),
        "{refused:?}"
    );
    nothing_uploaded_or_armed(&mock);
    service.shutdown().await.expect("clean stop");
    mock.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_service_plans_from_the_vehicles_home_when_the_upload_asks_for_it() {
    use crate::service::{connected, planned, serve, upload};
    // 145 m north: beyond the tolerance, within the legs' limit.
    let config = MockConfig {
        flight: Some(FlightConfig {
            home: north_of_sample(0.0013),
            ..FlightConfig::default()
        }),
        ..MockConfig::default()
    };
    let mock = MockAutopilot::spawn("udpin:127.0.0.1:0", config)
        .await
        .expect("mock");
    let vehicle = emplan::service::VehicleLink::Connect {
        url: format!("udpout:{}", mock.local_addr()),
        signing_key: None,
    };
    let service = serve(vehicle, &["paper-sample-3wp.toml"]).await;
    let client = &service.client;
    connected(client).await;
    planned(client, "paper-sample-3wp.toml").await;
    let body = |origin: &str| serde_json::json!({ "origin": origin });
    let refused = upload(client, "paper-sample-3wp.toml", body("mission")).await;
    assert_eq!(
        (refused.status, &refused.body["stage"]),
        (422, &Value::from("preflight")),
        "{refused:?}"
    );
    nothing_uploaded_or_armed(&mock);
    let moved = upload(client, "paper-sample-3wp.toml", body("vehicle")).await;
    assert!(moved.ok(), "{moved:?}");
    assert_eq!(moved.body["report"]["verified"], true, "{moved:?}");
    assert_eq!(mock.stats().uploads_accepted, 1);
    // Priced from the vehicle's home: not the plan the service made from the mission's origin.
    let listed = client
        .get("/api/missions/paper-sample-3wp.toml")
        .await
        .expect("GET");
    let kj = |v: &Value| v.as_f64().expect("kJ");
    assert!(
        (kj(&moved.body["predicted_mission_kj"]) - kj(&listed.body["plan"]["battery"]["total_kj"]))
            .abs()
            > 0.1,
        "{moved:?}"
    );
    service.shutdown().await.expect("clean stop");
    mock.shutdown().await.unwrap();
}
