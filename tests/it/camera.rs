//! Photos at waypoints on the built-in mock (a PX4, and an ArduCopter): a mission whose items carry a photo
//! (DO_DIGICAM_CONTROL, shoot 1) after each waypoint, uploaded by a ground station of the test's
//! own and flown by the mock, recorded and measured against the items the vehicle holds, as
//! `record` measures a flight: as many photos as photo items, each within 2 m of its waypoint,
//! every waypoint visited, and the flight directory's report read back the same. A camera that
//! misses one leaves its waypoint not visited, so a resumption flies it again.

use std::path::{Path, PathBuf};
use std::time::Duration;

use emplan::flightlog::flight_plan::FlightPlan;
use emplan::flightlog::report::FlightReport;
use emplan::flightlog::resume::{visits, Visit};
use emplan::link::items::{item, mission_items, read_flight, ItemOptions};
use emplan::link::mav::{MavCmd, MavFrame, MISSION_ITEM_INT_DATA};
use emplan::link::Flavour;
use emplan::mission::Mission;
use emplan::session::{plan_from_items, spawn_recorder, FlightEvent, RecorderConfig};

use super::service::{ground_station, root};

fn mission() -> Mission {
    emplan::mission::load(&root().join("missions/paper-sample-3wp.toml")).expect("mission")
}

/// The sample's items (B, C, A: the energy order) with a photo after each of its waypoints (not
/// after the return to the origin), numbered.
fn items_with_photos(mission: &Mission, flavour: Flavour) -> Vec<MISSION_ITEM_INT_DATA> {
    let opts = ItemOptions {
        flavour,
        ..ItemOptions::default()
    };
    let items = mission_items(mission, &[1, 2, 0], &opts).expect("items");
    let last_waypoint = items
        .iter()
        .rposition(|i| i.command == MavCmd::MAV_CMD_NAV_WAYPOINT);
    let photo = item(
        MavCmd::MAV_CMD_DO_DIGICAM_CONTROL,
        MavFrame::MAV_FRAME_MISSION,
        [0.0; 4],
        1,
        0,
        0.0,
    );
    let mut out = Vec::new();
    for (k, it) in items.iter().enumerate() {
        out.push(it.clone());
        // Not after ArduPilot's home (seq 0) either.
        let home = flavour == Flavour::ArduPilot && k == 0;
        if it.command == MavCmd::MAV_CMD_NAV_WAYPOINT && Some(k) != last_waypoint && !home {
            out.push(photo.clone());
        }
    }
    for (seq, it) in out.iter_mut().enumerate() {
        it.seq = seq as u16;
    }
    out
}

/// Uploads the items to a mock of `flavour` that starts what it stores (its camera missing
/// photo `missed`, if any), records the flight in `log_dir` against the plan read from the
/// items, and returns the plan, the report and the flight directory.
async fn fly(
    log_dir: &Path,
    flavour: Flavour,
    missed: Option<u32>,
) -> (FlightPlan, FlightReport, PathBuf) {
    let mission = mission();
    let mock = emplan::sim::MockAutopilot::spawn(
        "udpin:127.0.0.1:0",
        emplan::sim::MockConfig {
            flavour,
            boot: Duration::from_millis(100),
            flight: Some(emplan::sim::FlightConfig {
                home: mission.origin.home,
                missed_photo: missed,
                ..Default::default()
            }),
            speedup: 50.0,
            autostart: true,
            ..Default::default()
        },
    )
    .await
    .expect("mock");
    let (link, target, cfg) = ground_station(&mock).await;
    let items = items_with_photos(&mission, flavour);
    let read = read_flight(&items, flavour, mission.origin.home.alt_m).expect("a flight");
    let plan = plan_from_items(&mission.name, &read, Some(&mission), None).expect("a plan");
    let recorder = spawn_recorder(&link, RecorderConfig::new(log_dir));
    let mut events = recorder.subscribe();
    recorder.set_plan(plan.clone());
    let uploaded = emplan::link::driver::upload_verified(&link, &target, &items, cfg, |_, _| {})
        .await
        .expect("the photo items are accepted and read back");
    assert!(uploaded.verified);
    let ended = tokio::time::timeout(Duration::from_secs(120), async {
        loop {
            match events.recv().await {
                Ok(FlightEvent::Ended { dir, report, .. }) => return (dir, report),
                Ok(_) | Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => {}
                Err(e) => panic!("the recorder stopped: {e}"),
            }
        }
    })
    .await
    .expect("the flight ends");
    recorder.close().await;
    mock.shutdown().await.expect("mock stops");
    let (dir, report) = ended;
    (plan, *report.expect("measured against the items"), dir)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_photo_after_each_waypoint_is_reported_at_its_waypoint_and_every_waypoint_is_visited() {
    let log_dir = tempfile::tempdir().expect("temp dir");
    let (plan, report, dir) = fly(log_dir.path(), Flavour::Px4, None).await;
    // The plan read from the items expects one photo at each waypoint, none at the origin.
    let expected: Vec<(&str, u32)> = (plan.points.iter())
        .map(|p| (p.name.as_str(), p.photos))
        .collect();
    assert_eq!(expected, [("B", 1), ("C", 1), ("A", 1), ("origin", 0)]);
    assert!(report.complete, "{:?}", report.flags);
    let photos = &report.photos;
    assert!(photos.apart.is_empty(), "{:?}", photos.apart);
    let at: Vec<(&str, u32, u32)> = (photos.points.iter())
        .map(|p| (p.point.as_str(), p.photos_expected, p.photos_taken))
        .collect();
    assert_eq!(at, [("B", 1, 1), ("C", 1, 1), ("A", 1, 1)]);
    for p in &photos.points {
        assert_eq!(p.missing, None);
        let photo = &p.photos[0];
        let d = photo.distance_m.expect("located");
        assert!(d < 2.0, "{}: photo {d:.2} m from its waypoint", p.point);
        // PX4's CAMERA_TRIGGER and CAMERA_IMAGE_CAPTURED of the photo, as one.
        assert_eq!(
            photo.photo.messages,
            ["CAMERA_TRIGGER", "CAMERA_IMAGE_CAPTURED"]
        );
    }
    let visited: Vec<Visit> = visits(&plan, &report).iter().map(|v| v.visit).collect();
    assert_eq!(visited, [Visit::Visited; 3]);
    // The flight directory's report.json and plan.json say the same.
    let saved = emplan::flightlog::recorder::read_report(&dir).expect("report.json");
    let saved_at: Vec<(String, u32)> = (saved.photos.points.iter())
        .map(|p| (p.point.clone(), p.photos_taken))
        .collect();
    assert_eq!(saved_at.len(), 3);
    assert!(saved_at.iter().all(|(_, taken)| *taken == 1));
    let saved_plan = emplan::flightlog::recorder::read_flight_plan(&dir).expect("plan.json");
    let kept = |p: &FlightPlan| -> Vec<(u16, String, u32)> {
        (p.points.iter())
            .map(|x| (x.seq, x.name.clone(), x.photos))
            .collect()
    };
    assert_eq!(kept(&saved_plan), kept(&plan));
    // A replay of the log measures the same photos.
    let (ok, stdout, stderr) =
        crate::emplan(&["report", dir.to_str().expect("a UTF-8 temp path"), "--json"]);
    assert!(ok, "{stderr}");
    let replayed: serde_json::Value = serde_json::from_str(&stdout).expect("JSON");
    let points = replayed["photo_points"].as_array().expect("photo_points");
    let taken: Vec<(String, u64)> = (points.iter())
        .map(|p| {
            (
                p["point"].as_str().expect("point").to_string(),
                p["photos_taken"].as_u64().expect("taken"),
            )
        })
        .collect();
    assert_eq!(
        taken,
        [("B", 1), ("C", 1), ("A", 1)].map(|(n, k)| (n.to_string(), k))
    );
    // The text report: one line per waypoint with photos.
    let (ok, stdout, stderr) = crate::emplan(&["report", dir.to_str().expect("a UTF-8 temp path")]);
    assert!(ok, "{stderr}");
    let lines: Vec<&str> = (stdout.lines())
        .filter(|l| l.starts_with("photos at "))
        .collect();
    assert_eq!(lines.len(), 3, "{stdout}");
    assert!(
        lines[0].starts_with("photos at B: 1 taken of 1 expected ("),
        "{stdout}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_photo_the_camera_missed_leaves_its_waypoint_not_visited_naming_why() {
    let log_dir = tempfile::tempdir().expect("temp dir");
    // The second photo (at C) is never taken.
    let (plan, report, _) = fly(log_dir.path(), Flavour::Px4, Some(1)).await;
    let at: Vec<(&str, u32)> = (report.photos.points.iter())
        .map(|p| (p.point.as_str(), p.photos_taken))
        .collect();
    assert_eq!(at, [("B", 1), ("C", 0), ("A", 1)]);
    assert_eq!(
        report.photos.points[1].missing.as_deref(),
        Some("0 of 1 photos reported taken: not visited")
    );
    let visited: Vec<(String, Visit)> = (visits(&plan, &report).into_iter())
        .map(|v| (v.name, v.visit))
        .collect();
    assert_eq!(
        visited,
        [
            ("B".to_string(), Visit::Visited),
            ("C".to_string(), Visit::PhotosMissing),
            ("A".to_string(), Visit::Visited)
        ]
    );
    let resumed = emplan::flightlog::resume::resume(&mission(), &plan, &report, "f")
        .expect("C is left to fly");
    let left: Vec<&str> = (resumed.mission.waypoints.iter())
        .map(|w| w.name.as_str())
        .collect();
    assert_eq!(left, ["C"]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn on_ardupilot_one_camera_feedback_per_photo_item_is_reported_at_its_waypoint() {
    let log_dir = tempfile::tempdir().expect("temp dir");
    let (plan, report, _) = fly(log_dir.path(), Flavour::ArduPilot, None).await;
    // Home at seq 0, take-off at 1: B at 2, its photo at 3, and so on.
    let expected: Vec<(u16, &str, u32)> = (plan.points.iter())
        .map(|p| (p.seq, p.name.as_str(), p.photos))
        .collect();
    assert_eq!(
        expected,
        [(2, "B", 1), (4, "C", 1), (6, "A", 1), (8, "origin", 0)]
    );
    assert!(report.photos.apart.is_empty(), "{:?}", report.photos.apart);
    assert_eq!(report.photos.points.len(), 3);
    for (k, p) in report.photos.points.iter().enumerate() {
        assert_eq!((p.photos_expected, p.photos_taken), (1, 1), "{}", p.point);
        let photo = &p.photos[0];
        assert_eq!(photo.photo.messages, ["CAMERA_FEEDBACK"]);
        assert_eq!(photo.photo.index, k as i64, "img_idx counts the photos");
        let d = photo.distance_m.expect("located");
        assert!(d < 2.0, "{}: photo {d:.2} m from its waypoint", p.point);
    }
    let visited: Vec<Visit> = visits(&plan, &report).iter().map(|v| v.visit).collect();
    assert_eq!(visited, [Visit::Visited; 3]);
}
