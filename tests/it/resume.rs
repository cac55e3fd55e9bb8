//! Resuming a mission after a battery swap on the built-in mock: a flight sent home mid-mission
//! over the link (`link::commands::return_home`, what the energy guard's `rtl` does) leaves
//! waypoints unvisited; `fly --resume DIR` flies exactly those, in the energy order from the
//! origin, verified on upload; `report DIR1 DIR2` lists every waypoint once. The same after the
//! energy guard's own return (`--guard rtl`, a vehicle heavier than the plan's). A complete
//! flight, another mission's flight, and a missing or corrupt flight directory are refused
//! naming why, before any link is opened.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::Duration;

use emplan::flightlog::flight_plan::{FlightPlan, ORIGIN_NAME};
use emplan::mission::Mission;
use emplan::planner::FlightChoice;
use serde_json::Value;

use super::service::{ground_station, root};
use crate::emplan;

const MISSION: &str = "missions/paper-sample-8wp.toml";

fn mission() -> Mission {
    emplan::mission::load(&root().join(MISSION)).expect("mission")
}

/// The names of a plan's waypoints in flying order (the return to the origin left out).
fn flown(plan: &FlightPlan) -> Vec<String> {
    (plan.points.iter())
        .filter(|p| p.name != ORIGIN_NAME)
        .map(|p| p.name.clone())
        .collect()
}

/// Flies the mission in its energy order on a mock of the test's own, recorded in `log_dir`,
/// and sends the vehicle home once it has left its second waypoint: the flight's directory.
async fn flight_sent_home(log_dir: &Path) -> PathBuf {
    let mission = mission();
    let model = emplan::physics::VehicleModel::open(&emplan::physics::VehicleSource::BuiltIn, None)
        .expect("model");
    let choice = FlightChoice::default();
    let plan = choice
        .plan(&mission, &model, Default::default())
        .expect("plan");
    let flight = choice.flight(&plan).expect("feasible");
    let mock = emplan::sim::MockAutopilot::spawn(
        "udpin:127.0.0.1:0",
        emplan::sim::MockConfig {
            flight: Some(emplan::sim::FlightConfig {
                profile: Some(plan.profile),
                home: mission.origin.home,
                ..Default::default()
            }),
            speedup: 50.0,
            ..Default::default()
        },
    )
    .await
    .expect("mock");
    let (link, target, cfg) = ground_station(&mock).await;
    let recorder = emplan::session::spawn_recorder(
        &link,
        emplan::session::RecorderConfig::new(log_dir.to_path_buf()),
    );
    let load = emplan::session::Load {
        mission: &mission,
        plan: &plan,
        flight: &flight,
        acceptance_radius_m: 2.0,
        vehicle: &model.vehicle,
        guard: emplan::flightlog::watch::Policy::Off,
        resumes: None,
        if_home_unknown: Default::default(),
        live_wind: None,
        pack: None,
        guard_start: None,
        ledger: None,
    };
    let options = emplan::session::FlyOptions {
        arm: true,
        ..Default::default()
    };
    // PX4 layout: take-off at seq 0, the waypoints from seq 1: the third one is seq 3.
    let send_home = async {
        let deadline = tokio::time::Instant::now() + Duration::from_secs(60);
        loop {
            let v = mock.vehicle().expect("the mock flies");
            if v.current.is_some_and(|c| c >= 3) {
                break;
            }
            assert!(
                tokio::time::Instant::now() < deadline,
                "never got out: {v:?}"
            );
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        emplan::link::commands::return_home(&link, &target)
            .await
            .expect("link")
    };
    let (flown, sent) = tokio::join!(
        emplan::session::fly(
            &link,
            &target,
            cfg,
            &recorder,
            &load,
            &options,
            |_| {},
            |_| {}
        ),
        send_home
    );
    assert_eq!(sent, Ok(()));
    let flown = flown.expect("flown and landed");
    recorder.close().await;
    let landed = mock.vehicle().expect("the mock");
    assert!(!landed.mission_complete, "{landed:?}");
    flown.dir
}

/// The waypoints a report's flight arrived at and hovered its time at (its at-point parts not
/// cut short), read from report.json.
fn visited_in(report: &Value) -> Vec<String> {
    (report["at_points"].as_array().expect("at_points").iter())
        .filter(|p| {
            !p["flags"]
                .as_array()
                .is_some_and(|f| f.contains(&"incomplete".into()))
        })
        .map(|p| p["to"].as_str().expect("a name").to_string())
        .filter(|n| n != ORIGIN_NAME)
        .collect()
}

fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).expect("JSON")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flight_sent_home_is_finished_by_fly_resume_and_the_two_visit_every_waypoint_once() {
    let work = tempfile::tempdir().unwrap();
    let first = flight_sent_home(&work.path().join("first")).await;
    let first_plan = FlightPlan::read_json(&first.join("plan.json")).expect("plan.json");
    assert_eq!(first_plan.resumes, None);
    let visited = visited_in(&read_json(&first.join("report.json")));
    let all = flown(&first_plan);
    assert!(
        !visited.is_empty() && visited.len() < all.len(),
        "sent home after {visited:?} of {all:?}"
    );
    // Visited in flying order, first to last.
    assert_eq!(visited, all[..visited.len()]);
    let left: BTreeSet<String> = all[visited.len()..].iter().cloned().collect();

    let log = work.path().join("second");
    let (first_s, log_s) = (first.to_str().unwrap(), log.to_str().unwrap());
    let (ok, stdout, stderr) = emplan(&[
        "fly",
        MISSION,
        "--resume",
        first_s,
        "--log-dir",
        log_s,
        "--json",
        "--speedup",
        "50",
    ]);
    assert!(ok, "fly --resume failed: {stderr}");
    assert!(stderr.contains("resuming "), "{stderr}");
    let doc: Value = serde_json::from_str(&stdout).expect("JSON");
    assert_eq!(
        (&doc["ok"], &doc["complete"]),
        (&Value::Bool(true), &Value::Bool(true))
    );
    let second = PathBuf::from(doc["log_dir"].as_str().expect("log_dir"));
    let second_plan = FlightPlan::read_json(&second.join("plan.json")).expect("plan.json");
    let first_name = first.file_name().unwrap().to_str().unwrap();
    assert_eq!(second_plan.resumes.as_deref(), Some(first_name));
    assert_eq!(second_plan.mission, first_plan.mission);
    // Exactly the waypoints left, each flown and hovered at ...
    let second_order = flown(&second_plan);
    assert_eq!(second_order.iter().cloned().collect::<BTreeSet<_>>(), left);
    assert_eq!(visited_in(&doc), second_order);
    // ... in the minimum-energy order of those waypoints from the origin.
    let whole = mission();
    let rest = Mission {
        waypoints: (whole.waypoints.iter())
            .filter(|w| left.contains(&w.name))
            .cloned()
            .collect(),
        ..whole.clone()
    };
    let model = emplan::physics::VehicleModel::open(&emplan::physics::VehicleSource::BuiltIn, None)
        .expect("model");
    let plan = FlightChoice::default()
        .plan(&rest, &model, Default::default())
        .expect("plan");
    let energy_order: Vec<String> = (plan.flight(None).expect("flight").waypoints().iter())
        .map(|&w| rest.waypoints[w].name.clone())
        .collect();
    assert_eq!(second_order, energy_order);

    // The two flights' report: every waypoint of the mission once.
    let second_s = second.to_str().unwrap();
    let report = crate::json(&["report", first_s, second_s, "--json"]);
    assert_eq!(report["flights"].as_array().map(Vec::len), Some(2));
    let missions = report["missions"].as_array().expect("missions");
    assert_eq!(missions.len(), 1, "{report}");
    let m = &missions[0];
    assert_eq!(m["mission"], "paper-sample-8wp");
    assert_eq!(m["every_waypoint_once"], true, "{m}");
    assert_eq!(m["problems"], serde_json::json!([]));
    let waypoints = m["waypoints"].as_array().expect("waypoints");
    let names: BTreeSet<&str> = waypoints
        .iter()
        .filter_map(|w| w["name"].as_str())
        .collect();
    let mission_names: BTreeSet<&str> = whole.waypoints.iter().map(|w| w.name.as_str()).collect();
    assert_eq!((waypoints.len(), names), (8, mission_names));
    let second_name = second.file_name().unwrap().to_str().unwrap();
    for w in waypoints {
        let by = if visited.iter().any(|v| w["name"] == v.as_str()) {
            first_name
        } else {
            second_name
        };
        assert_eq!(w["visited_by"], serde_json::json!([by]), "{w}");
        assert!(w["leg_kj"].as_f64().is_some_and(|kj| kj > 0.0), "{w}");
    }
    assert_eq!(m["flights"][1]["resumes"], first_name);
    let per_flight: f64 = (m["flights"].as_array().unwrap().iter())
        .map(|f| f["measured_kj"].as_f64().expect("measured"))
        .sum();
    let total = m["total"]["measured_kj"].as_f64().expect("total");
    assert!((total - per_flight).abs() < 1e-9 && total > 0.0, "{m}");
    // The text says the same.
    let (ok, text, stderr) = emplan(&["report", first_s, second_s]);
    assert!(ok, "{stderr}");
    assert!(
        text.contains("over 2 flights") && text.contains("every waypoint visited once"),
        "{text}"
    );

    // Nothing is left after the resumption: refused, naming it.
    let (ok, stdout, stderr) = emplan(&["fly", MISSION, "--resume", second_s, "--log-dir", log_s]);
    assert!(!ok && stdout.is_empty(), "{stdout}");
    assert!(
        stderr.contains(&format!("every waypoint was reached in {second_s}")),
        "{stderr}"
    );
}

/// A flight directory of the 8-waypoint mission as `fly` leaves one: its plan.json (every
/// waypoint in the listed order), and a log of `tlog` bytes.
fn flight_dir(dir: &Path, tlog: &[u8]) -> String {
    std::fs::create_dir_all(dir).unwrap();
    let order: Vec<usize> = (0..8).collect();
    FlightPlan::for_mission(&mission(), &order, 0, None)
        .expect("plan")
        .write_json(&dir.join("plan.json"))
        .expect("written");
    std::fs::write(dir.join("flight.tlog"), tlog).unwrap();
    dir.to_str().unwrap().to_string()
}

/// `fly --resume`'s refusal (stderr), which comes before any link or flight.
fn refused(mission: &str, resume: &str, log_dir: &Path) -> String {
    let (ok, stdout, stderr) = emplan(&[
        "fly",
        mission,
        "--resume",
        resume,
        "--log-dir",
        log_dir.to_str().unwrap(),
    ]);
    assert!(!ok && stdout.is_empty(), "{stdout}{stderr}");
    assert!(stderr.contains(&format!("--resume {resume}")), "{stderr}");
    assert_eq!(
        std::fs::read_dir(log_dir).map(|d| d.count()).unwrap_or(0),
        0,
        "nothing flown"
    );
    stderr
}

#[test]
fn a_flight_of_another_mission_is_refused_naming_the_mission_or_the_waypoint() {
    let work = tempfile::tempdir().unwrap();
    let log = work.path().join("flights");
    let dir = flight_dir(&work.path().join("earlier"), b"");
    let stderr = refused("missions/paper-sample-3wp.toml", &dir, &log);
    assert!(
        stderr.contains(r#"is a flight of mission "paper-sample-8wp", not of "paper-sample-3wp""#),
        "{stderr}"
    );
    // Same name, one waypoint moved 5 m east.
    let text = std::fs::read_to_string(root().join(MISSION)).unwrap();
    let moved = text.replacen("x_m = -20.0", "x_m = -15.0", 1);
    assert_ne!(moved, text);
    let moved_path = work.path().join("moved.toml");
    std::fs::write(&moved_path, moved).unwrap();
    let stderr = refused(moved_path.to_str().unwrap(), &dir, &log);
    assert!(
        stderr.contains(r#"its waypoint "A" is 5.0 m from the waypoint "A" of mission"#),
        "{stderr}"
    );
}

#[test]
fn a_missing_or_corrupt_flight_directory_is_refused_naming_the_file() {
    let work = tempfile::tempdir().unwrap();
    let log = work.path().join("flights");
    let missing = work.path().join("no-such-flight");
    let missing = missing.to_str().unwrap();
    let stderr = refused(MISSION, missing, &log);
    assert!(
        stderr.contains(&format!(
            "{missing}: not a flight directory (no flight.tlog)"
        )),
        "{stderr}"
    );
    // plan.json that is not JSON.
    let dir = flight_dir(&work.path().join("bad-plan"), b"");
    std::fs::write(Path::new(&dir).join("plan.json"), "{\"mission\": ").unwrap();
    let stderr = refused(MISSION, &dir, &log);
    assert!(stderr.contains(&format!("{dir}/plan.json: ")), "{stderr}");
    // A log that holds no MAVLink at all.
    let dir = flight_dir(&work.path().join("bad-log"), &[0x5a; 300]);
    let stderr = refused(MISSION, &dir, &log);
    assert!(stderr.contains(&format!("{dir}/flight.tlog")), "{stderr}");
}

#[test]
fn the_guards_return_home_is_finished_by_fly_resume_and_the_two_visit_every_waypoint_once() {
    let work = tempfile::tempdir().unwrap();
    let mission = super::guard::mission(work.path());
    let truth = super::guard::heavier_vehicle(work.path());
    // A vehicle heavier than the plan's with a smaller pack, sent home by the guard.
    let guarded = super::guard::fly(&mission, &work.path().join("rtl"), "rtl", Some(&truth));
    assert_eq!(guarded["guard"]["returned"], true, "{}", guarded["guard"]);
    let first = guarded["log_dir"].as_str().expect("log_dir").to_string();
    // After the battery swap, the plan's own vehicle flies the rest.
    let (ok, stdout, stderr) = emplan(&[
        "fly",
        mission.to_str().unwrap(),
        "--resume",
        &first,
        "--log-dir",
        work.path().join("resumed").to_str().unwrap(),
        "--speedup",
        "50",
        "--json",
    ]);
    assert!(ok, "{stderr}");
    let second: Value = serde_json::from_str(&stdout).expect("JSON");
    assert_eq!(second["complete"], true);
    let second = second["log_dir"].as_str().expect("log_dir").to_string();
    let report = crate::json(&["report", &first, &second, "--json"]);
    let m = &report["missions"][0];
    assert_eq!(m["every_waypoint_once"], true, "{m}");
    let all = emplan::mission::load(&mission)
        .expect("mission")
        .waypoints
        .len();
    assert_eq!(m["waypoints"].as_array().map(Vec::len), Some(all));
    assert!(
        m["flights"][0]["visited"]
            .as_array()
            .is_some_and(|v| !v.is_empty() && v.len() < all),
        "{m}"
    );
}
