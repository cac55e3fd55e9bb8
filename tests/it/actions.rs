//! Missions with actions at their waypoints, as field teams write them in QGroundControl: read,
//! planned with their prices, converted between formats and back to the same plan, refused where
//! a reorder would break them, and uploaded in the energy order with the file's speed and region
//! of interest in force on the way to every waypoint.

use std::path::Path;
use std::time::Duration;

use emplan::link::connection::{Identity, Link};
use emplan::link::driver::upload_verified;
use emplan::link::items::{mission_items, ItemOptions, ItemsError};
use emplan::link::mav::{MavCmd, MISSION_ITEM_INT_DATA};
use emplan::link::transfer::TransferConfig;
use emplan::link::Flavour;
use emplan::mission::actions::{id, Command, Setting, State, FRAME_GLOBAL_RELATIVE_ALT};
use emplan::mission::{load, load_str, Format, Mission};
use emplan::sim::{MockAutopilot, MockConfig};

use crate::{emplan, json};

const FIELD: &str = "missions/orchard-inspection.plan";

fn field() -> Mission {
    load(&Path::new(env!("CARGO_MANIFEST_DIR")).join(FIELD)).unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The orders' sequences and energies of a plan document.
fn orders(doc: &serde_json::Value) -> Vec<(Vec<String>, f64)> {
    doc["orders"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| {
            (
                o["sequence"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|n| n.as_str().unwrap().to_string())
                    .collect(),
                o["energy_kj"].as_f64().unwrap(),
            )
        })
        .collect()
}

fn same_plan(a: &serde_json::Value, b: &serde_json::Value) {
    let (oa, ob) = (orders(a), orders(b));
    assert_eq!(oa.len(), ob.len());
    for ((sa, ea), (sb, eb)) in oa.iter().zip(&ob) {
        assert_eq!(sa, sb);
        assert!((ea - eb).abs() < 1e-6, "{ea} kJ against {eb} kJ");
    }
    assert_eq!(
        a["actions"].as_array().map(Vec::len),
        b["actions"].as_array().map(Vec::len)
    );
    let battery = |d: &serde_json::Value| d["battery"]["total_kj"].as_f64().unwrap();
    assert!((battery(a) - battery(b)).abs() < 1e-6);
}

#[test]
fn the_field_mission_keeps_a_photo_and_a_gimbal_pitch_at_every_waypoint_and_its_speed_roi_and_yaw()
{
    let m = field();
    assert_eq!(m.waypoints.len(), 8);
    for w in &m.waypoints {
        assert_eq!(w.photos(), 1, "{}", w.name);
        assert!(
            w.actions.iter().any(|c| c.command == id::DO_MOUNT_CONTROL),
            "{}",
            w.name
        );
    }
    let all: Vec<u16> = m
        .waypoints
        .iter()
        .flat_map(|w| w.actions.iter().map(|c| c.command))
        .collect();
    for c in [
        id::DO_CHANGE_SPEED,
        id::DO_SET_ROI_LOCATION,
        id::DO_SET_ROI_NONE,
        id::CONDITION_YAW,
    ] {
        assert!(all.contains(&c), "{c} missing");
    }
    // The speeds in force on the way to each waypoint: the vehicle's, then 4 m/s, then 8.
    let (to, home) = m.speeds_m_s();
    assert_eq!(
        to,
        vec![
            None,
            None,
            None,
            Some(4.0),
            Some(4.0),
            Some(4.0),
            Some(8.0),
            Some(8.0)
        ]
    );
    assert_eq!(home, Some(8.0));
}

#[test]
fn the_field_mission_is_planned_with_its_actions_priced_and_converted_to_toml_and_back_to_the_same_plan(
) {
    let tmp = tempfile::tempdir().unwrap();
    let toml = tmp.path().join("inspection.toml");
    let back = tmp.path().join("inspection.plan");
    let plan = json(&["plan", FIELD, "--json"]);
    // Legs after the speed change are priced at it; the turn of the yaw is priced.
    let legs = plan["orders"][0]["legs"].as_array().unwrap();
    assert!(legs.iter().any(|l| l["speed_m_s"] == 4.0), "{legs:?}");
    assert!(legs.iter().any(|l| l["speed_m_s"] == 8.0), "{legs:?}");
    assert!(plan["orders"][0]["actions_kj"].as_f64().unwrap() > 0.0);
    let actions = plan["actions"].as_array().unwrap();
    assert_eq!(actions.len(), 9, "the start and eight waypoints");
    let photos = actions
        .iter()
        .flat_map(|a| a["commands"].as_array().unwrap())
        .filter(|c| c["what"] == "photo")
        .count();
    assert_eq!(photos, 8);

    let (ok, _, stderr) = emplan(&["convert", FIELD, s(&toml)]);
    assert!(ok, "{stderr}");
    let text = std::fs::read_to_string(&toml).unwrap();
    assert!(
        text.contains("photo = true") && text.contains("gimbal_pitch_deg = -45"),
        "{text}"
    );
    assert!(
        text.contains("roi = \"roi1\"") && text.contains("[[pois]]"),
        "{text}"
    );
    let (ok, _, stderr) = emplan(&["convert", s(&toml), s(&back)]);
    assert!(ok, "{stderr}");
    same_plan(&plan, &json(&["plan", s(&toml), "--json"]));
    same_plan(&plan, &json(&["plan", s(&back), "--json"]));
    // The .plan written back holds the same commands, item for item.
    let again = load(&back).unwrap();
    for (a, b) in field().waypoints.iter().zip(&again.waypoints) {
        assert_eq!(a.actions.len(), b.actions.len());
        for (x, y) in a.actions.iter().zip(&b.actions) {
            assert_eq!(x.command, y.command);
            assert_eq!(x.frame, y.frame);
            for (p, q) in x.params.iter().zip(&y.params) {
                assert!(
                    (p.is_nan() && q.is_nan()) || (p - q).abs() < 1e-7,
                    "{x:?} {y:?}"
                );
            }
        }
    }
}

#[test]
fn a_speed_change_prices_the_legs_after_it_at_that_speed() {
    let base = r#"
name = "speed"
[origin]
lat_deg = 38.5418
lon_deg = -121.8132
home_alt_amsl_m = 16.0
height_above_home_m = 15.0
[[waypoints]]
name = "A"
x_m = 0.0
y_m = 60.0
z_m = 0.0
hover_s = 2.0
"#;
    let tail = "[[waypoints]]\nname = \"B\"\nx_m = 80.0\ny_m = 60.0\nz_m = 0.0\nhover_s = 2.0\n";
    let tmp = tempfile::tempdir().unwrap();
    let plain = tmp.path().join("plain.toml");
    let fast = tmp.path().join("fast.toml");
    std::fs::write(&plain, format!("{base}{tail}")).unwrap();
    std::fs::write(&fast, format!("{base}speed_m_s = 12.0\n{tail}")).unwrap();
    let leg = |doc: &serde_json::Value, to: &str| -> serde_json::Value {
        doc["orders"]
            .as_array()
            .unwrap()
            .iter()
            .find(|o| o["objective"] == "listed")
            .unwrap()["legs"]
            .as_array()
            .unwrap()
            .iter()
            .find(|l| l["to"] == to)
            .unwrap()
            .clone()
    };
    let a = json(&["plan", s(&plain), "--order", "listed", "--json"]);
    let b = json(&["plan", s(&fast), "--order", "listed", "--json"]);
    // The leg to A is flown before the change: the same price.
    assert_eq!(leg(&a, "A")["energy_kj"], leg(&b, "A")["energy_kj"]);
    // A -> B at 12 m/s (the px4 profile cruises at 5 m/s) costs less than at 5: shorter in time.
    let (slow, quick) = (
        leg(&a, "B")["energy_kj"].as_f64().unwrap(),
        leg(&b, "B")["energy_kj"].as_f64().unwrap(),
    );
    assert!(
        quick < 0.9 * slow,
        "{quick} kJ at 12 m/s against {slow} kJ at 5 m/s"
    );
    assert_eq!(leg(&b, "B")["speed_m_s"], 12.0);
    assert_eq!(leg(&b, "origin")["speed_m_s"], 12.0);
}

#[test]
fn commands_a_reorder_would_break_are_refused_naming_the_item_and_unknown_ones_are_kept_with_one_warning(
) {
    let plan = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(FIELD)).unwrap();
    let mut doc: serde_json::Value = serde_json::from_str(&plan).unwrap();
    let items = doc["mission"]["items"].as_array_mut().unwrap();
    items.insert(
        5,
        serde_json::json!({"type": "SimpleItem", "command": 177, "frame": 2, "autoContinue": true,
            "doJumpId": 99, "params": [2, 3, 0, 0, 0, 0, 0]}),
    );
    let err = load_str(&doc.to_string(), Format::QgcPlan, None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("mission item 5") && err.contains("command 177"),
        "{err}"
    );

    let mut doc: serde_json::Value = serde_json::from_str(&plan).unwrap();
    let items = doc["mission"]["items"].as_array_mut().unwrap();
    items.insert(
        3,
        serde_json::json!({"type": "SimpleItem", "command": 112, "frame": 2, "autoContinue": true,
            "doJumpId": 99, "params": [5, 0, 0, 0, 0, 0, 0]}),
    );
    let err = load_str(&doc.to_string(), Format::QgcPlan, None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("mission item 3") && err.contains("condition"),
        "{err}"
    );

    // DO_SET_PARAMETER (180) is kept verbatim with the waypoint before it, and said once.
    let mut doc: serde_json::Value = serde_json::from_str(&plan).unwrap();
    let items = doc["mission"]["items"].as_array_mut().unwrap();
    items.insert(
        2,
        serde_json::json!({"type": "SimpleItem", "command": 180, "frame": 2, "autoContinue": true,
            "doJumpId": 99, "params": [7, 1, 0, 0, 0, 0, 0]}),
    );
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("with-param.plan");
    std::fs::write(&path, doc.to_string()).unwrap();
    let m = load(&path).unwrap();
    assert!(m.waypoints[0].actions.iter().any(|c| c.command == 180));
    let (ok, _, stderr) = emplan(&["plan", s(&path)]);
    assert!(ok, "{stderr}");
    assert_eq!(stderr.matches("does not understand").count(), 1, "{stderr}");
    assert!(stderr.contains("180 after WP1"), "{stderr}");
}

#[test]
fn px4_gets_the_yaw_as_its_waypoints_own_and_a_servo_is_refused_naming_the_autopilot() {
    let m = field();
    let order: Vec<usize> = (0..m.waypoints.len()).rev().collect();
    let opts = ItemOptions {
        flavour: Flavour::Px4,
        ..ItemOptions::default()
    };
    let items = mission_items(&m, &order, &opts).unwrap();
    assert!(items
        .iter()
        .all(|i| i.command != MavCmd::MAV_CMD_CONDITION_YAW));
    let canal = m.waypoint_relative(6).unwrap();
    let at_canal = items
        .iter()
        .find(|i| {
            i.command == MavCmd::MAV_CMD_NAV_WAYPOINT && i.x == emplan::link::items::deg_e7(canal.0)
        })
        .unwrap();
    assert_eq!(at_canal.param4, 90.0);

    let mut servo = m.clone();
    servo.waypoints[2].actions.push(Command::new(
        id::DO_SET_SERVO,
        [9.0, 1500.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    ));
    let err = mission_items(&servo, &order, &opts).unwrap_err();
    assert!(
        matches!(err, ItemsError::Unsupported { command: 183, .. }),
        "{err}"
    );
    assert!(
        err.to_string().contains("PX4") && err.to_string().contains("WP3"),
        "{err}"
    );
    // ArduPilot takes it.
    let ap = ItemOptions {
        flavour: Flavour::ArduPilot,
        ..ItemOptions::default()
    };
    assert!(mission_items(&servo, &order, &ap).is_ok());
}

/// The state in force along `items` as flown, at each waypoint item: (its position in degE7,
/// the state on the way to it, the commands after it until the next navigation item).
fn walk(items: &[MISSION_ITEM_INT_DATA]) -> Vec<((i32, i32), State, Vec<u16>)> {
    let mut state = State::default();
    let mut out: Vec<((i32, i32), State, Vec<u16>)> = Vec::new();
    for item in items {
        let command = item.command as u16;
        match command {
            id::NAV_WAYPOINT | id::NAV_SPLINE_WAYPOINT | id::NAV_LOITER_TIME => {
                out.push(((item.x, item.y), state.clone(), Vec::new()))
            }
            id::NAV_TAKEOFF | id::NAV_LAND | id::NAV_RETURN_TO_LAUNCH => {}
            _ => {
                let located = command == id::DO_SET_ROI_LOCATION;
                let c = Command {
                    command,
                    frame: if located {
                        FRAME_GLOBAL_RELATIVE_ALT
                    } else {
                        2
                    },
                    params: [
                        f64::from(item.param1),
                        f64::from(item.param2),
                        f64::from(item.param3),
                        f64::from(item.param4),
                        if located {
                            f64::from(item.x) / 1e7
                        } else {
                            f64::from(item.x)
                        },
                        if located {
                            f64::from(item.y) / 1e7
                        } else {
                            f64::from(item.y)
                        },
                        f64::from(item.z),
                    ],
                };
                state = state.after([&c]);
                if let Some(last) = out.last_mut() {
                    last.2.push(command);
                }
            }
        }
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn uploaded_in_the_energy_order_to_the_mock_every_waypoint_holds_its_actions_and_the_files_speed_and_roi(
) {
    let m = field();
    let plan = json(&["plan", FIELD, "--order", "energy", "--json"]);
    let names: Vec<String> = plan["orders"][0]["sequence"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap().to_string())
        .collect();
    let order: Vec<usize> = names
        .iter()
        .map(|n| m.waypoints.iter().position(|w| &w.name == n).unwrap())
        .collect();
    // A harder order than the energy one: backwards, every setting to restore.
    let reversed: Vec<usize> = order.iter().rev().copied().collect();
    for (flavour, order) in [
        (Flavour::ArduPilot, order.clone()),
        (Flavour::Px4, reversed),
    ] {
        let mock = MockAutopilot::spawn(
            "udpin:127.0.0.1:0",
            MockConfig {
                flavour,
                ..MockConfig::default()
            },
        )
        .await
        .unwrap();
        let link = Link::connect(
            &format!("udpout:{}", mock.local_addr()),
            Identity::default(),
            None,
        )
        .await
        .unwrap();
        let target = link.discover(Duration::from_secs(20)).await.unwrap();
        let opts = ItemOptions {
            flavour,
            vehicle_speed_m_s: Some(5.0),
            ..ItemOptions::default()
        };
        let items = mission_items(&m, &order, &opts).unwrap();
        let cfg = TransferConfig {
            target_system: target.system_id,
            target_component: target.component_id,
            ..TransferConfig::default()
        };
        upload_verified(&link, &target, &items, cfg, |_, _| {})
            .await
            .unwrap_or_else(|e| panic!("{flavour:?}: {e}"));
        let held = emplan::link::driver::download(&link, &target, cfg)
            .await
            .unwrap();
        drop(link);
        mock.shutdown().await.unwrap();
        let states = m.file_states();
        // ArduPilot's item 0 is its home, not a waypoint flown.
        let flown = if flavour == Flavour::ArduPilot {
            &held[1..]
        } else {
            &held[..]
        };
        let walked = walk(flown);
        // The waypoints flown, then the return to the origin.
        assert_eq!(walked.len(), order.len() + 1);
        for (&k, (at, state, after)) in order.iter().zip(&walked) {
            let w = &m.waypoints[k];
            let (lat, lon, _) = m.waypoint_relative(k).unwrap();
            let e7 = emplan::link::items::deg_e7;
            assert_eq!(*at, (e7(lat), e7(lon)), "{flavour:?} {}", w.name);
            // The vehicle's own speed is 5 m/s here (restored as an explicit 5).
            assert_eq!(
                state.speed_m_s().unwrap_or(5.0),
                states.before[k].speed_m_s().unwrap_or(5.0),
                "{flavour:?}: speed on the way to {}",
                w.name
            );
            let roi = |s: &State| {
                s.get(Setting::RegionOfInterest)
                    .map(|c| ((c.params[4] * 1e5).round(), (c.params[5] * 1e5).round()))
            };
            assert_eq!(
                roi(state),
                roi(&states.before[k]),
                "{flavour:?}: region of interest on the way to {}",
                w.name
            );
            // Its own actions follow it (PX4 flies the yaw as the waypoint's own; the speed goes
            // first, link::items::speed_first), in order but for the speed.
            let own: Vec<u16> = w
                .actions
                .iter()
                .map(|c| c.command)
                .filter(|&c| !(flavour == Flavour::Px4 && c == id::CONDITION_YAW))
                .collect();
            let others = |cs: &[u16]| -> Vec<u16> {
                cs.iter()
                    .copied()
                    .filter(|&c| c != id::DO_CHANGE_SPEED)
                    .collect()
            };
            let held = others(after);
            assert_eq!(
                &held[..others(&own).len()],
                &others(&own)[..],
                "{flavour:?} {}",
                w.name
            );
            if own.contains(&id::DO_CHANGE_SPEED) {
                assert_eq!(after[0], id::DO_CHANGE_SPEED, "{flavour:?} {}", w.name);
            }
        }
    }
}
