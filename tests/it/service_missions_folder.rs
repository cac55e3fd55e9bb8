//! The service's missions folder under files that change: a file written in pieces is never
//! listed planned half-written, an upload of a file changed since it was planned is refused
//! and the file planned again, a large file past its time limit ends as an error while a small
//! one added meanwhile is planned, and a large file deleted mid-plan leaves the list and stops
//! its plan. The service runs in this process on 127.0.0.1:0 (as in `service`), with a short
//! settle time and time limit; waits are hang guards only.

use std::path::{Path, PathBuf};
use std::time::Duration;

use emplan::service::client::Answer;
use emplan::service::missions::{digest, WatchSettings};
use emplan::service::wire::{
    Failure, LinkState, LinkStatus, MissionState, MissionStatus, MissionsFolder,
};
use emplan::service::{Client, ServiceConfig, ServiceError, Token, VehicleLink};
use emplan::sim::{FlightConfig, MockConfig};
use serde_json::json;

use super::service::{model, read, root};

/// A service running in this process, its missions folder empty at the start.
struct Running {
    client: Client,
    missions: PathBuf,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    task: tokio::task::JoinHandle<Result<(), ServiceError>>,
    _work: tempfile::TempDir,
}

impl Running {
    async fn shutdown(mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        tokio::time::timeout(Duration::from_secs(30), self.task)
            .await
            .expect("the service stops within 30 s")
            .expect("the service task")
            .expect("the service ran");
    }
}

/// The service's settings in these tests.
struct Settings {
    settle: Duration,
    time_limit: Duration,
    plans_at_once: usize,
}

async fn serve(settings: Settings) -> Running {
    let work = tempfile::tempdir().expect("temp dir");
    let missions = work.path().join("missions");
    std::fs::create_dir_all(&missions).expect("missions dir");
    let token = Token::random().expect("token");
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .expect("bound");
    let url = format!("http://{}", listener.local_addr().expect("addr"));
    let cfg = ServiceConfig {
        vehicle: VehicleLink::Mock {
            config: Box::new(MockConfig {
                flight: Some(FlightConfig::default()),
                speedup: 20.0,
                ..MockConfig::default()
            }),
            vehicle: None,
        },
        missions_dir: missions.clone(),
        log_dir: work.path().join("flights"),
        ledger: emplan::ledger::LedgerSpec::Sqlite(work.path().join("flights/ledger.sqlite")),
        token: token.clone(),
        model: model(),
        solver: emplan::tour::solver::Options {
            time_limit: settings.time_limit,
            ..Default::default()
        },
        transfer_budget: None,
        resume_within: emplan::service::DEFAULT_RESUME_WITHIN,
        guard: Default::default(),
        watch: WatchSettings {
            settle: settings.settle,
            plans_at_once: settings.plans_at_once,
        },
        http: Default::default(),
    };
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let task = tokio::spawn(emplan::service::run(listener, cfg, async move {
        let _ = stopped.await;
    }));
    Running {
        client: Client::new(&url, Some(token)).expect("client"),
        missions,
        stop: Some(stop),
        task,
        _work: work,
    }
}

/// The list entry of `name`, if listed.
async fn listed(client: &Client, name: &str) -> Option<MissionStatus> {
    let answer = client
        .get("/api/missions")
        .await
        .expect("GET /api/missions");
    assert_eq!(answer.status, 200, "{answer:?}");
    read::<MissionsFolder>(&answer)
        .missions
        .into_iter()
        .find(|m| m.name == name)
}

/// Polls the list until `accept` takes the entry of `name` (absent: `None`); a hang guard of
/// `seconds`, never a measure of speed.
async fn until(
    client: &Client,
    name: &str,
    seconds: u64,
    accept: impl Fn(Option<&MissionStatus>) -> bool,
) -> Option<MissionStatus> {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(seconds);
    loop {
        let entry = listed(client, name).await;
        if accept(entry.as_ref()) {
            return entry;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "{name}: not as expected within {seconds} s (hang guard): {entry:?}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

fn status_is(status: MissionState) -> impl Fn(Option<&MissionStatus>) -> bool {
    move |e| e.is_some_and(|e| e.status == status)
}

/// Listed planned from the bytes of digest `digest`.
fn planned_from(digest: &str) -> impl Fn(Option<&MissionStatus>) -> bool + '_ {
    move |e| e.is_some_and(|e| e.status == MissionState::Planned && e.digest == digest)
}

/// Writes `bytes` to `dir/name` whole: written beside, then renamed.
fn drop_in(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let beside = dir.join(format!(".{name}.part"));
    std::fs::write(&beside, bytes).expect("written");
    let path = dir.join(name);
    std::fs::rename(&beside, &path).expect("renamed");
    path
}

/// A random mission of `waypoints` waypoints, as TOML bytes.
fn large_mission(waypoints: u32) -> Vec<u8> {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = crate::generated_mission(dir.path(), waypoints, 100, 20, 5);
    std::fs::read(path).expect("generated")
}

fn sample_8wp() -> Vec<u8> {
    std::fs::read(root().join("missions/paper-sample-8wp.toml")).expect("sample mission")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_mission_written_in_pieces_is_never_listed_planned_with_part_of_its_waypoints() {
    // Pauses of 350 ms between pieces: past the old 250 ms debounce, within the 1 s settle.
    let service = serve(Settings {
        settle: Duration::from_millis(1000),
        time_limit: Duration::from_secs(60),
        plans_at_once: 2,
    })
    .await;
    let text = String::from_utf8(sample_8wp()).expect("UTF-8");
    // Every piece ends at a whole waypoint: each stage reads as a mission of 1, 2, ... 8.
    let at = text.find("[[waypoints]]").expect("a waypoint");
    let mut pieces = vec![text[..at].to_string()];
    for block in text[at..].split_inclusive("\n\n") {
        if block.trim().is_empty() {
            continue;
        }
        pieces.push(block.to_string());
    }
    assert_eq!(pieces.len(), 9, "{pieces:?}");
    let path = service.missions.join("growing.toml");
    // What the list says of the file, every 30 ms while it is written.
    let (seen_tx, mut seen_rx) = tokio::sync::mpsc::unbounded_channel();
    let client = service.client.clone();
    let looking = tokio::spawn(async move {
        loop {
            if let Some(e) = listed(&client, "growing.toml").await {
                let _ = seen_tx.send((e.status, e.waypoints, e.digest));
            }
            tokio::time::sleep(Duration::from_millis(30)).await;
        }
    });
    let mut file = std::fs::File::create(&path).expect("created");
    for piece in &pieces {
        use std::io::Write;
        file.write_all(piece.as_bytes()).expect("written");
        file.flush().expect("flushed");
        tokio::time::sleep(Duration::from_millis(350)).await;
    }
    drop(file);
    let whole = digest(text.as_bytes());
    until(&service.client, "growing.toml", 30, planned_from(&whole)).await;
    // The poller may not have looked since the plan was listed: wait until it has seen it too.
    let mut seen = Vec::new();
    let _ = tokio::time::timeout(Duration::from_secs(10), async {
        while let Some(s) = seen_rx.recv().await {
            let planned = s.0 == MissionState::Planned;
            seen.push(s);
            if planned {
                break;
            }
        }
    })
    .await;
    looking.abort();
    while let Ok(s) = seen_rx.try_recv() {
        seen.push(s);
    }
    let planned: Vec<&(MissionState, Option<usize>, String)> = seen
        .iter()
        .filter(|(s, _, _)| *s == MissionState::Planned)
        .collect();
    assert!(!planned.is_empty(), "{seen:?}");
    for (_, waypoints, d) in &planned {
        assert_eq!(
            (*waypoints, d.as_str()),
            (Some(8), whole.as_str()),
            "listed planned half-written: {seen:?}"
        );
    }
    assert!(
        seen.iter().any(|(s, _, _)| *s == MissionState::Changing),
        "never listed as changing while written: {seen:?}"
    );
    service.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn an_upload_of_a_mission_changed_since_it_was_planned_is_refused_and_it_is_planned_again() {
    let service = serve(Settings {
        settle: Duration::from_millis(300),
        time_limit: Duration::from_secs(60),
        plans_at_once: 2,
    })
    .await;
    let before = sample_8wp();
    let path = drop_in(&service.missions, "sample.toml", &before);
    until(
        &service.client,
        "sample.toml",
        30,
        status_is(MissionState::Planned),
    )
    .await;
    // Same length, same modification time: only the bytes tell (a rewrite within one
    // timestamp tick, or a tool that keeps the time).
    let stamp = std::fs::metadata(&path)
        .expect("metadata")
        .modified()
        .expect("mtime");
    let text = String::from_utf8(before.clone()).expect("UTF-8");
    let after = text.replacen("x_m = -20.0", "x_m = -21.0", 1);
    assert_eq!(after.len(), text.len());
    assert_ne!(after, text);
    {
        let file = std::fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .expect("opened");
        use std::io::Write;
        (&file).write_all(after.as_bytes()).expect("rewritten");
        file.set_modified(stamp).expect("mtime kept");
    }
    // The vehicle is there: nothing but the check of the bytes stops the upload.
    let deadline = tokio::time::Instant::now() + Duration::from_secs(20);
    loop {
        let link = service
            .client
            .get("/api/link")
            .await
            .expect("GET /api/link");
        if link
            .parse::<LinkStatus>()
            .is_ok_and(|l| l.state == LinkState::Connected)
        {
            break;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "not connected within 20 s (hang guard): {link:?}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let answer: Answer = service
        .client
        .post("/api/missions/sample.toml/upload", &json!({}))
        .await
        .expect("POST upload");
    assert_eq!(answer.status, 409, "{answer:?}");
    let failure: Failure = read(&answer);
    assert!(
        failure
            .error
            .contains("sample.toml changed since it was planned"),
        "{failure:?}"
    );
    assert_eq!(failure.stage, "mission");
    // Planned again, from the bytes now in the file.
    let now = digest(after.as_bytes());
    until(&service.client, "sample.toml", 30, planned_from(&now)).await;
    service.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_large_mission_past_its_time_limit_ends_as_an_error_while_a_small_one_added_meanwhile_is_planned(
) {
    let service = serve(Settings {
        settle: Duration::from_millis(200),
        time_limit: Duration::from_secs(3),
        plans_at_once: 2,
    })
    .await;
    // 1000 waypoints: its assignment bound alone is 10^9 steps; pricing, solving and the
    // sorties' split take far longer than 3 s.
    drop_in(&service.missions, "large.toml", &large_mission(1000));
    until(
        &service.client,
        "large.toml",
        30,
        status_is(MissionState::Planning),
    )
    .await;
    drop_in(&service.missions, "small.toml", &sample_8wp());
    until(
        &service.client,
        "small.toml",
        30,
        status_is(MissionState::Planned),
    )
    .await;
    let large = listed(&service.client, "large.toml").await.expect("listed");
    assert_eq!(
        large.status,
        MissionState::Planning,
        "the small mission was planned only after the large one: {large:?}"
    );
    let large = until(
        &service.client,
        "large.toml",
        30,
        status_is(MissionState::Error),
    )
    .await
    .expect("listed");
    let problem = large.error.expect("an error");
    let message = problem.message;
    assert_eq!(problem.stage, "plan");
    assert!(
        message.contains("planning exceeded the 3 s limit"),
        "{message}"
    );
    service.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_large_mission_deleted_while_planned_leaves_the_list_and_its_plan_stops() {
    // One plan at a time: the small mission is planned only once the large one's plan has
    // stopped and given its thread back.
    let service = serve(Settings {
        settle: Duration::from_millis(200),
        time_limit: Duration::from_secs(600),
        plans_at_once: 1,
    })
    .await;
    let large = drop_in(&service.missions, "large.toml", &large_mission(1000));
    until(
        &service.client,
        "large.toml",
        30,
        status_is(MissionState::Planning),
    )
    .await;
    std::fs::remove_file(&large).expect("deleted");
    until(&service.client, "large.toml", 20, |e| e.is_none()).await;
    drop_in(&service.missions, "small.toml", &sample_8wp());
    until(
        &service.client,
        "small.toml",
        20,
        status_is(MissionState::Planned),
    )
    .await;
    service.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_mission_larger_than_the_planner_holds_is_listed_as_an_error_naming_the_limit() {
    let service = serve(Settings {
        settle: Duration::from_millis(200),
        time_limit: Duration::from_secs(60),
        plans_at_once: 2,
    })
    .await;
    let limit = emplan::mission::MAX_WAYPOINTS;
    // Home on line 2, waypoint k (1-based) on line k + 2.
    let mut text =
        String::from("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t38.5362\t-121.7875\t16\t1\n");
    for k in 1..=limit + 10 {
        let (row, col) = ((k / 300) as f64, (k % 300) as f64);
        text.push_str(&format!(
            "{k}\t0\t3\t16\t0\t0\t0\t0\t{:.7}\t{:.7}\t20\t1\n",
            38.5362 + row * 1e-5,
            -121.7875 + col * 1e-5
        ));
    }
    drop_in(&service.missions, "huge.waypoints", text.as_bytes());
    let huge = until(
        &service.client,
        "huge.waypoints",
        30,
        status_is(MissionState::Error),
    )
    .await
    .expect("listed");
    let message = huge.error.expect("an error").message;
    assert!(
        message.contains(&format!(
            "line {}: waypoint {} of {}: a mission may have at most {limit} waypoints",
            limit + 3,
            limit + 1,
            limit + 10
        )),
        "{message}"
    );
    // The folder goes on: a mission added after it is planned.
    drop_in(&service.missions, "small.toml", &sample_8wp());
    until(
        &service.client,
        "small.toml",
        30,
        status_is(MissionState::Planned),
    )
    .await;
    service.shutdown().await;
}
