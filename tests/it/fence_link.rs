//! A mission's geofence and rally points on the built-in mock: `session::load` uploads them
//! beside the mission and proves each by read-back, as PX4 and ArduPilot hold them; a mission
//! without them clears what the vehicle held; an autopilot that does not declare it holds a
//! fence is refused before anything goes up; `download` reads all three back, into the
//! `Mission` it writes and through the binary.

use emplan::link::mav::MISSION_ITEM_INT_DATA;
use emplan::link::Flavour;
use emplan::mission::fence::{Fence, Shape};
use emplan::mission::Mission;
use emplan::planner::FlightChoice;
use emplan::session::upload::ListUpload;
use emplan::session::{FlyError, Loaded};
use emplan::sim::{MockConfig, MockHandle};

use super::service::{ground_station, model, root};
use crate::emplan;

const MISSION: &str = "missions/paper-sample-8wp.toml";

/// The sample mission with the test fence (an inclusion pentagon, an exclusion square, an
/// exclusion circle, a breach return point) and one rally point, or with neither.
fn mission(fenced: bool) -> Mission {
    let mut mission = emplan::mission::load(&root().join(MISSION)).expect("mission");
    if fenced {
        mission.fence = emplan::link::testing::fence();
        mission.rally = emplan::link::testing::rally();
        // Written and read again, so the mission's validation checks the fence against its
        // points as it does a file's.
        let plan = emplan::mission::to_string(&mission, emplan::mission::Format::QgcPlan)
            .expect("written");
        let source = mission.source.clone();
        mission = emplan::mission::load_str(&plan, emplan::mission::Format::QgcPlan, None)
            .expect("the fenced sample is a valid mission");
        mission.source = source;
    }
    mission
}

/// A mock of `flavour` standing at the sample mission's origin.
async fn mock(flavour: Flavour) -> MockHandle {
    mock_at(&mission(false), flavour).await
}

/// A mock of `flavour` standing at `mission`'s origin.
pub(crate) async fn mock_at(mission: &Mission, flavour: Flavour) -> MockHandle {
    let home = mission.origin.home;
    emplan::sim::MockAutopilot::spawn(
        "udpin:127.0.0.1:0",
        MockConfig {
            flavour,
            home: emplan::sim::storage::Home {
                lat_e7: emplan::link::items::deg_e7(home.lat_deg),
                lon_e7: emplan::link::items::deg_e7(home.lon_deg),
                alt_m: home.alt_m as f32,
            },
            boot: std::time::Duration::ZERO,
            ..MockConfig::default()
        },
    )
    .await
    .expect("mock")
}

/// `session::load` of `mission` (its energy order) onto `mock`.
async fn load(mock: &MockHandle, mission: &Mission) -> Result<Loaded, FlyError> {
    let model = model();
    let choice = FlightChoice::default();
    let plan = choice
        .plan(mission, &model, Default::default())
        .expect("plan");
    let flight = choice.flight(&plan).expect("feasible");
    let (link, target, cfg) = ground_station(mock).await;
    let load = emplan::session::Load {
        mission,
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
    emplan::session::load(&link, &target, cfg, None, &load, |_| {}, |_, _| {}).await
}

/// The fence read back is the fence sent, to the degE7 the wire carries.
pub(crate) fn assert_same_fence(read: &Fence, sent: &Fence) {
    assert_eq!(read.zones.len(), sent.zones.len(), "{read:?}");
    for (a, b) in read.zones.iter().zip(&sent.zones) {
        assert_eq!(a.inclusion, b.inclusion);
        match (&a.shape, &b.shape) {
            (Shape::Polygon(p), Shape::Polygon(q)) => {
                assert_eq!(p.len(), q.len());
                for (u, v) in p.iter().zip(q) {
                    // degE7 on the wire: 1e-7 degrees.
                    assert!((u.lat_deg - v.lat_deg).abs() <= 0.6e-7, "{u:?} {v:?}");
                    assert!((u.lon_deg - v.lon_deg).abs() <= 0.6e-7, "{u:?} {v:?}");
                }
            }
            (
                Shape::Circle {
                    center: c,
                    radius_m: r,
                },
                Shape::Circle {
                    center: d,
                    radius_m: s,
                },
            ) => {
                assert!((c.lat_deg - d.lat_deg).abs() <= 0.6e-7);
                assert_eq!(r, s);
            }
            _ => panic!("zone shapes differ: {a:?} {b:?}"),
        }
    }
    match (read.breach_return, sent.breach_return) {
        (Some(r), Some(s)) => assert!((r.lat_deg - s.lat_deg).abs() <= 0.6e-7),
        (r, s) => assert_eq!(r.is_some(), s.is_some(), "breach return {r:?} {s:?}"),
    }
}

fn commands(items: &[MISSION_ITEM_INT_DATA]) -> Vec<u32> {
    items.iter().map(|i| i.command as u32).collect()
}

#[tokio::test]
async fn the_fence_and_rally_points_go_up_verified_and_come_back_in_the_downloaded_mission() {
    for flavour in [Flavour::Px4, Flavour::ArduPilot] {
        let mock = mock(flavour).await;
        let sent = mission(true);
        let loaded = load(&mock, &sent).await.expect("loaded");
        assert_eq!(
            loaded.fence,
            Some(ListUpload {
                count: 3,
                items: 11,
                acked: true,
                verified: true
            }),
            "{flavour:?}"
        );
        assert_eq!(
            loaded.rally,
            Some(ListUpload {
                count: 1,
                items: 1,
                acked: true,
                verified: true
            })
        );
        assert!(loaded.capabilities.fence && loaded.capabilities.rally);
        assert_eq!(
            commands(&mock.fence()),
            [5000, 5001, 5001, 5001, 5001, 5001, 5002, 5002, 5002, 5002, 5004]
        );
        assert_eq!(commands(&mock.rally()), [5100]);

        // Read back whole: the Mission `download OUT.plan` writes has them.
        let (link, target, cfg) = ground_station(&mock).await;
        let held = emplan::session::download_held(&link, &target, cfg)
            .await
            .expect("downloaded");
        let back = held.mission("held").expect("a mission");
        assert_same_fence(&back.fence, &sent.fence);
        assert_eq!(back.rally.len(), 1);
        let alt_m = back.rally[0].alt_above_home_m;
        match flavour {
            // ArduPilot holds a rally point's altitude in whole metres: 25.4 went up as 25.
            Flavour::ArduPilot => assert_eq!(alt_m, 25.0),
            _ => assert!((alt_m - 25.4).abs() < 1e-5, "{alt_m}"),
        }
        assert!((back.rally[0].lat_deg - sent.rally[0].lat_deg).abs() <= 0.6e-7);
        assert_eq!(back.waypoints.len(), sent.waypoints.len());
        mock.shutdown().await.unwrap();
    }
}

#[tokio::test]
async fn a_mission_without_a_fence_clears_the_fence_and_rally_points_the_vehicle_held() {
    let mock = mock(Flavour::ArduPilot).await;
    load(&mock, &mission(true)).await.expect("fenced");
    assert_eq!(mock.fence().len(), 11);
    let loaded = load(&mock, &mission(false)).await.expect("unfenced");
    assert_eq!(
        loaded.fence,
        Some(ListUpload {
            count: 0,
            items: 0,
            acked: true,
            verified: true
        })
    );
    assert_eq!(loaded.rally.map(|r| r.count), Some(0));
    assert!(mock.fence().is_empty());
    assert!(mock.rally().is_empty());
    mock.shutdown().await.unwrap();
}

#[tokio::test]
async fn a_fence_is_refused_before_anything_goes_up_to_an_autopilot_that_does_not_declare_it() {
    let mock = mock(Flavour::Generic).await;
    let err = load(&mock, &mission(true)).await.unwrap_err();
    assert!(matches!(err, FlyError::Unsupported(_)), "{err}");
    assert_eq!(err.stage(), "preflight");
    assert!(!err.accepted());
    let text = err.to_string();
    assert!(
        text.contains("a geofence")
            && text.contains("a generic MAVLink autopilot, system 1")
            && text.contains("MAV_PROTOCOL_CAPABILITY_MISSION_FENCE"),
        "{text}"
    );
    assert!(mock.mission().is_empty(), "nothing was uploaded");
    // Without a fence it flies: the mission goes up, no fence list is touched.
    let loaded = load(&mock, &mission(false)).await.expect("loaded");
    assert_eq!((loaded.fence, loaded.rally), (None, None));
    assert!(!mock.mission().is_empty());
    mock.shutdown().await.unwrap();
}

#[test]
fn upload_through_the_binary_clears_an_old_fence_and_download_reads_all_three() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let mock = runtime.block_on(mock(Flavour::Px4));
    runtime
        .block_on(load(&mock, &mission(true)))
        .expect("fenced");
    let url = format!("udpout:{}", mock.local_addr());
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("held.plan");

    let (ok, stdout, stderr) = emplan(&["download", "--connect", &url, out.to_str().unwrap()]);
    assert!(ok, "{stderr}");
    assert!(
        stdout.contains("fence 11 items, rally points 1 items"),
        "{stdout}"
    );
    assert!(out.exists());

    // The same site's mission without a fence: the vehicle's old fence goes.
    let (ok, stdout, stderr) = emplan(&["upload", MISSION, "--connect", &url, "--json"]);
    assert!(ok, "{stderr}");
    let doc: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(doc["fence"]["count"], 0, "{doc}");
    assert_eq!(doc["fence"]["verified"], true);
    assert_eq!(doc["rally"]["count"], 0);
    assert!(runtime.block_on(async { mock.fence() }).is_empty());
    let (ok, stdout, _) = emplan(&["upload", MISSION, "--connect", &url]);
    assert!(ok);
    assert!(
        stdout.contains("verified: fence cleared on the vehicle (the mission has none)"),
        "{stdout}"
    );
    runtime.block_on(mock.shutdown()).unwrap();
}
