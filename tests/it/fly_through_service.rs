//! `emplan fly --service` against `emplan serve`, both the binary: a fly started the moment the
//! service's port answers waits for the service's vehicle link and measures every leg, and its
//! report has the keys and legs `fly` alone gives; on a PX4 holding other trajectory
//! parameters than the vehicle file, it warns and re-prices as `fly` alone does; an upload
//! through a service whose vehicle is not heard yet waits for it (`--discover-s`); every event
//! the service sends reads as `service::wire::Event` and writes back as the same JSON.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use emplan::service::wire::{Event, LinkState, LinkStatus, MissionState};
use emplan::service::{Client, Token};
use serde_json::Value;

use crate::service::{root, Reaped};

/// The mock's speed-up in these tests.
const SPEEDUP: &str = "50";

/// A loopback port free now.
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

/// A service started on its own port with the 8-waypoint sample in its folder, its URL and its
/// token file; returned once the port answers (not once the vehicle is connected).
struct Served {
    _child: Reaped,
    url: String,
    token: PathBuf,
    mission: PathBuf,
    _work: tempfile::TempDir,
}

fn serve(extra: &[&str]) -> Served {
    let work = tempfile::tempdir().expect("temp dir");
    let missions = work.path().join("missions");
    std::fs::create_dir_all(&missions).expect("dir");
    let mission = missions.join("paper-sample-8wp.toml");
    std::fs::copy(root().join("missions/paper-sample-8wp.toml"), &mission).expect("copied");
    let logs = work.path().join("flights");
    let token = work.path().join("token");
    let port = free_port();
    let http = format!("127.0.0.1:{port}");
    let mut args = vec![
        "serve",
        "--missions",
        missions.to_str().unwrap(),
        "--log-dir",
        logs.to_str().unwrap(),
        "--http",
        &http,
        "--token-file",
        token.to_str().unwrap(),
        "--speedup",
        SPEEDUP,
    ];
    args.extend_from_slice(extra);
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_emplan"))
        .args(&args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(std::process::Stdio::null())
        .stderr(std::fs::File::create(work.path().join("serve.log")).expect("log"))
        .spawn()
        .expect("emplan serve runs");
    let child = Reaped(child);
    let began = Instant::now();
    while std::net::TcpStream::connect(&http).is_err() {
        assert!(
            began.elapsed() < Duration::from_secs(20),
            "the port never answered"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    Served {
        _child: child,
        url: format!("http://{http}"),
        token,
        mission,
        _work: work,
    }
}

/// `emplan fly MISSION ... --json` with `extra` arguments: (success, the document, stderr).
fn fly(mission: &Path, extra: &[&str]) -> (bool, Value, String) {
    let mut args = vec!["fly", mission.to_str().unwrap(), "--json"];
    args.extend_from_slice(extra);
    let (ok, stdout, stderr) = crate::emplan(&args);
    let doc = serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("{e}: {stdout}\n{stderr}"));
    (ok, doc, stderr)
}

fn fly_alone(log_dir: &Path, extra: &[&str]) -> (Value, String) {
    let mut args = vec!["--speedup", SPEEDUP, "--log-dir", log_dir.to_str().unwrap()];
    args.extend_from_slice(extra);
    let (ok, doc, stderr) = fly(&root().join("missions/paper-sample-8wp.toml"), &args);
    assert!(ok, "fly alone failed: {stderr}");
    (doc, stderr)
}

fn fly_through(served: &Served) -> (Value, String) {
    let token = served.token.to_str().unwrap();
    let (ok, doc, stderr) = fly(
        &served.mission,
        &["--service", &served.url, "--token-file", token],
    );
    assert!(ok, "fly --service failed: {doc}\n{stderr}");
    (doc, stderr)
}

/// Where the key sets of two documents differ (objects key by key, arrays item by item).
fn key_differences(a: &Value, b: &Value, at: &str, out: &mut Vec<String>) {
    match (a, b) {
        (Value::Object(a), Value::Object(b)) => {
            let (ka, kb): (Vec<&String>, Vec<&String>) = (a.keys().collect(), b.keys().collect());
            if ka != kb {
                out.push(format!("{at}: {ka:?} vs {kb:?}"));
            }
            for (k, v) in a {
                if let Some(w) = b.get(k) {
                    key_differences(v, w, &format!("{at}.{k}"), out);
                }
            }
        }
        (Value::Array(a), Value::Array(b)) => {
            for (i, (v, w)) in a.iter().zip(b).enumerate() {
                key_differences(v, w, &format!("{at}[{i}]"), out);
            }
        }
        _ => {}
    }
}

fn legs(report: &Value) -> Vec<(String, String)> {
    report["legs"]
        .as_array()
        .expect("legs")
        .iter()
        .map(|l| (l["from"].to_string(), l["to"].to_string()))
        .collect()
}

fn every_leg_measured(report: &Value) {
    let legs = report["legs"].as_array().expect("legs");
    assert_eq!(legs.len(), 9, "{report}");
    for leg in legs {
        assert!(leg["measured_kj"].as_f64().is_some(), "{leg}");
    }
}

/// The warning lines of `fly`'s stderr.
fn warnings(stderr: &str) -> Vec<&str> {
    stderr
        .lines()
        .filter(|l| l.starts_with("warning: PX4"))
        .collect()
}

#[test]
fn fly_through_a_service_started_this_moment_waits_for_its_vehicle_and_reports_as_fly_alone() {
    let served = serve(&[]);
    let (through, _) = fly_through(&served);
    every_leg_measured(&through);
    let alone_logs = tempfile::tempdir().expect("temp dir");
    let (alone, _) = fly_alone(alone_logs.path(), &[]);
    let mut differences = Vec::new();
    key_differences(&through, &alone, "", &mut differences);
    assert!(differences.is_empty(), "{differences:#?}");
    assert_eq!(legs(&through), legs(&alone));
    assert_eq!(through["px4_parameters"], alone["px4_parameters"]);
}

#[test]
fn fly_through_a_service_warns_of_other_px4_parameters_and_reprices_as_fly_alone() {
    let params = [
        "--mock-param",
        "MPC_XY_CRUISE=8",
        "--mock-param",
        "MPC_ACC_HOR=2",
    ];
    let served = serve(&params);
    let (through, through_err) = fly_through(&served);
    let alone_logs = tempfile::tempdir().expect("temp dir");
    let (alone, alone_err) = fly_alone(alone_logs.path(), &params);
    assert_eq!(warnings(&through_err), warnings(&alone_err));
    assert!(
        warnings(&alone_err)
            .iter()
            .any(|w| w.contains("MPC_XY_CRUISE is 8")),
        "{alone_err}"
    );
    assert_eq!(through["px4_parameters"], alone["px4_parameters"]);
    assert_eq!(
        through["px4_parameters"]["differing"]
            .as_array()
            .map(Vec::len),
        Some(2)
    );
    let predicted = |r: &Value| -> Vec<Value> {
        (r["legs"].as_array().expect("legs").iter())
            .map(|l| l["predicted_kj"].clone())
            .collect()
    };
    assert_eq!(predicted(&through), predicted(&alone));
    every_leg_measured(&through);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_event_of_a_flight_reads_as_a_wire_event_and_writes_back_as_the_same_json() {
    let served = serve(&[]);
    let token = std::fs::read_to_string(&served.token).ok();
    let token = token.and_then(|t| Token::new(&t).ok());
    let client = Client::new(&served.url, token).expect("client");
    let mut events = loop {
        // The port answers before the routes do.
        match client.events().await {
            Ok(events) => break events,
            Err(_) => tokio::time::sleep(Duration::from_millis(20)).await,
        }
    };
    let (mission, url, token_file) = (
        served.mission.clone(),
        served.url.clone(),
        served.token.clone(),
    );
    let flying = tokio::task::spawn_blocking(move || {
        let token = token_file.to_str().unwrap().to_string();
        fly(&mission, &["--service", &url, "--token-file", &token])
    });
    // The kinds of event the stream carried, by the wire's names.
    let kind = |e: &Event| {
        match e {
            Event::Telemetry(_) => "telemetry",
            Event::Part(_) => "part",
            Event::FlightStarted { .. } => "flight_started",
            Event::Link(_) => "link",
            Event::Upload { .. } => "upload",
            Event::Start { .. } => "start",
            _ => "other",
        }
        .to_string()
    };
    let mut kinds = std::collections::BTreeSet::new();
    loop {
        let event = match events.next_within(Duration::from_secs(60)).await {
            Ok(Some(Ok(event))) => event,
            other => panic!("the event stream: {other:?}"),
        };
        let read: Event =
            serde_json::from_value(event.clone()).unwrap_or_else(|e| panic!("{e}: {event}"));
        assert_eq!(serde_json::to_value(&read).expect("written"), event);
        kinds.insert(kind(&read));
        if matches!(read, Event::FlightEnded { .. }) {
            break;
        }
    }
    let (ok, _, stderr) = flying.await.expect("ran");
    assert!(ok, "{stderr}");
    for kind in [
        "telemetry",
        "part",
        "flight_started",
        "link",
        "upload",
        "start",
    ] {
        assert!(kinds.contains(kind), "no {kind} event among {kinds:?}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_upload_through_a_service_whose_vehicle_is_not_heard_yet_waits_for_it() {
    let work = tempfile::tempdir().expect("temp dir");
    let missions = work.path().join("missions");
    std::fs::create_dir_all(&missions).expect("dir");
    let mission = missions.join("paper-sample-3wp.toml");
    std::fs::copy(root().join("missions/paper-sample-3wp.toml"), &mission).expect("copied");
    let (logs, token) = (work.path().join("flights"), work.path().join("token"));
    let vehicle = format!("127.0.0.1:{}", free_port());
    let (serve, url) = crate::service::spawn_serve(
        &[
            "--connect",
            &format!("udpout:{vehicle}"),
            "--missions",
            missions.to_str().unwrap(),
            "--log-dir",
            logs.to_str().unwrap(),
            "--http",
            "127.0.0.1:0",
            "--token-file",
            token.to_str().unwrap(),
            "--settle-ms",
            "100",
        ],
        &work.path().join("serve.log"),
    );
    let _serve = Reaped(serve);
    // The mission is planned and the vehicle not heard: today's answer would be a refusal.
    let client = Client::new(&url, None).expect("client");
    let began = Instant::now();
    loop {
        let entry = client.get("/api/missions/paper-sample-3wp.toml").await;
        if entry.is_ok_and(|a| crate::service::status_of(&a) == Some(MissionState::Planned)) {
            break;
        }
        assert!(began.elapsed() < Duration::from_secs(30), "never planned");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let link = client.get("/api/link").await.expect("link");
    let link: LinkStatus = crate::service::read(&link);
    assert_eq!(link.state, LinkState::WaitingForHeartbeat, "{link:?}");
    let uploading = tokio::task::spawn_blocking(move || {
        crate::emplan(&[
            "upload",
            mission.to_str().unwrap(),
            "--service",
            &url,
            "--token-file",
            token.to_str().unwrap(),
            "--discover-s",
            "60",
            "--json",
        ])
    });
    // The vehicle appears while the upload waits for it.
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let mock = std::process::Command::new(env!("CARGO_BIN_EXE_emplan"))
        .args(["mock-autopilot", "--listen", &format!("udpin:{vehicle}")])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("emplan mock-autopilot runs");
    let _mock = Reaped(mock);
    let (ok, stdout, stderr) = uploading.await.expect("ran");
    assert!(ok, "{stdout}\n{stderr}");
    let doc: Value = serde_json::from_str(&stdout).expect("the upload document");
    assert_eq!(doc["report"]["verified"], true, "{doc}");
}
