//! Survey blocks uploaded, flown and measured on the built-in mock (ArduPilot, the `ardupilot`
//! profile): a mission of points and two surveys, one flown reversed, goes up with each block's
//! items contiguous and whole, its camera trigger on at the end it enters and off at the end it
//! leaves (downloaded through the binary as plain waypoints: a `.plan` written back from items
//! has no complex items); flown through its zero-hold waypoints, the report measures each block
//! against its prediction and counts the photos its distance trigger took along its lines.
//!
//! The mission and the order are built here (`mission()`, `reversed_flight()`); the checks
//! (`check_held`, `check_report`) take any mission with blocks and the order flown.

use std::time::Duration;

use emplan::flightlog::report::BlockReport;
use emplan::link::Flavour;
use emplan::mission::actions::{id, Command};
use emplan::mission::blocks::{Block, BlockKind};
use emplan::mission::{Enu, Mission, Waypoint};
use emplan::physics::{Profile, VehicleModel, VehicleSource};
use emplan::planner::{Flight, FlightChoice, FlownOrder, Leg, Plan};

use super::service::{ground_station, root};
use crate::emplan;

/// A survey of `lines` lines `length_m` east from `at`, `spacing_m` apart northwards, flown back
/// and forth through waypoints without a hold, the trigger on every `trigger_m` at its entry
/// (a photo at once) and off at its exit, as QGroundControl writes a survey's items.
fn survey(m: &mut Mission, name: &str, at: Enu, lines: usize, length_m: f64, trigger_m: f64) {
    let spacing_m = 15.0;
    let first = m.waypoints.len();
    let trigger = |d: f64, now: f64| {
        Command::new(id::DO_SET_CAM_TRIGG_DIST, [d, 0.0, now, 0.0, 0.0, 0.0, 0.0])
    };
    for k in 0..2 * lines {
        let line = k / 2;
        let east_m = if (k % 2 == 0) == (line % 2 == 0) {
            0.0
        } else {
            length_m
        };
        m.waypoints.push(Waypoint {
            name: format!("{name}{}", k + 1),
            position: Enu {
                x_east_m: at.x_east_m + east_m,
                y_north_m: at.y_north_m + spacing_m * line as f64,
                z_up_m: at.z_up_m,
            },
            hover_s: 0.0,
            actions: match k {
                0 => vec![trigger(trigger_m, 1.0)],
                k if k + 1 == 2 * lines => vec![trigger(0.0, 0.0)],
                _ => Vec::new(),
            },
            ..Waypoint::default()
        });
    }
    m.blocks.push(Block {
        name: name.to_string(),
        kind: BlockKind::Survey,
        first,
        len: 2 * lines,
        reversible: true,
        source: None,
    });
}

/// The paper's three points with a survey after A (S) and one after B (T).
fn mission() -> Mission {
    let sample =
        emplan::mission::load(&root().join("missions/paper-sample-3wp.toml")).expect("the sample");
    let mut m = Mission {
        waypoints: Vec::new(),
        ..sample.clone()
    };
    let point = |k: usize| sample.waypoints[k].clone();
    m.waypoints.push(point(0));
    let at = |x_east_m, y_north_m| Enu {
        x_east_m,
        y_north_m,
        z_up_m: 25.0,
    };
    survey(&mut m, "S", at(20.0, 40.0), 3, 60.0, 20.0);
    m.waypoints.push(point(1));
    survey(&mut m, "T", at(-70.0, -50.0), 3, 50.0, 20.0);
    m.waypoints.push(point(2));
    m
}

/// Node `n` of `m` as flown with the blocks `reversed` (indices into its blocks): a reversed
/// block's waypoints last to first.
fn reversed_node(m: &Mission, reversed: &[usize], n: usize) -> usize {
    let Some(k) = n.checked_sub(1) else {
        return 0;
    };
    match (reversed.iter().filter_map(|&b| m.blocks.get(b))).find(|b| b.contains(k)) {
        Some(b) => 2 * b.first + b.len - 1 - k + 1,
        None => n,
    }
}

/// The file's order of `m` with the blocks `reversed` flown last to first, priced as flown: the
/// listed order of `m.oriented(reversed)` (whose file order lays them out reversed, so its legs
/// are the flown legs), its nodes named as `m` names them.
fn reversed_flight(
    m: &Mission,
    model: &VehicleModel,
    reversed: &[usize],
) -> (Plan, Vec<usize>, Vec<Leg>) {
    let choice = FlightChoice {
        order: FlownOrder::Listed,
        ..Default::default()
    };
    let plan = choice
        .plan(&m.oriented(reversed), model, Default::default())
        .expect("plan");
    let order = plan.flown();
    let nodes = (order.nodes.iter())
        .map(|&n| reversed_node(m, reversed, n))
        .collect();
    let legs = (order.legs.iter())
        .map(|l| Leg {
            from: reversed_node(m, reversed, l.from),
            to: reversed_node(m, reversed, l.to),
            ..l.clone()
        })
        .collect();
    (plan, nodes, legs)
}

/// The camera trigger distances a waypoint's commands set.
fn triggers(w: &Waypoint) -> Vec<f64> {
    (w.actions.iter())
        .filter(|c| c.command == id::DO_SET_CAM_TRIGG_DIST)
        .map(|c| c.params[0])
        .collect()
}

/// What the vehicle holds (`held`, downloaded, in the order flown) against `m` flown in
/// `order` (indices into its waypoints): every waypoint where the order puts it, each block's
/// waypoints contiguous and whole, forward or reversed, its trigger on at its entry (at the
/// file's distance) and off at its exit, nothing between; no trigger at any point.
fn check_held(m: &Mission, order: &[usize], held: &Mission) {
    assert!(
        held.waypoints.len() >= order.len(),
        "{} held",
        held.waypoints.len()
    );
    for (i, &k) in order.iter().enumerate() {
        let (a, b) = (m.waypoints[k].position, held.waypoints[i].position);
        let off_m = (a.x_east_m - b.x_east_m).hypot(a.y_north_m - b.y_north_m);
        assert!(
            off_m < 0.05,
            "item {i}: {} is {off_m} m off",
            m.waypoints[k].name
        );
    }
    let file = m.file_states();
    let mut in_blocks = vec![false; order.len()];
    for block in &m.blocks {
        let at = order
            .iter()
            .position(|&k| k == block.first || k == block.first + block.len - 1)
            .expect("the block is flown");
        let reversed = order[at] != block.first;
        assert_eq!(
            order[at..at + block.len],
            block.flown(reversed)[..],
            "{} contiguous and whole",
            block.name
        );
        let on = file.after[block.first]
            .get(emplan::mission::actions::Setting::TriggerDistance)
            .map(|c| c.params[0])
            .expect("the survey triggers");
        for (i, inside) in in_blocks.iter_mut().enumerate().skip(at).take(block.len) {
            *inside = true;
            let expected = match i - at {
                0 => vec![on],
                j if j + 1 == block.len => vec![0.0],
                _ => vec![],
            };
            assert_eq!(
                triggers(&held.waypoints[i]),
                expected,
                "{} ({}): item {i}",
                block.name,
                if reversed { "reversed" } else { "forward" }
            );
            assert_eq!(held.waypoints[i].hover_s, 0.0, "flown through");
        }
    }
    for (i, w) in held.waypoints.iter().enumerate().take(order.len()) {
        if !in_blocks[i] {
            assert!(triggers(w).is_empty(), "point {i}: {:?}", triggers(w));
        }
    }
}

/// Each block of `m` in the report of its flight: predicted and measured within 10%, its
/// photos counted, about one per trigger distance of its lines.
fn check_report(m: &Mission, reversed: &[usize], blocks: &[BlockReport]) {
    assert_eq!(blocks.len(), m.blocks.len(), "{blocks:?}");
    for (b, flown) in m.blocks.iter().zip(blocks) {
        eprintln!("{}", flown.line());
        assert_eq!(flown.name, b.name);
        assert_eq!(
            flown.reversed,
            reversed.contains(&(m.blocks.iter().position(|x| x == b).unwrap()))
        );
        assert_eq!(flown.legs, b.len - 1);
        let e = flown.error_pct().expect("predicted and measured");
        assert!(e.abs() < 10.0, "{}: {e:+.1}%", b.name);
        assert!(flown.photos_expected > 0);
        assert!(
            flown.photos_taken > 0 && flown.photos_taken.abs_diff(flown.photos_expected) <= 2,
            "{}: {} photos taken, about {} expected",
            b.name,
            flown.photos_taken,
            flown.photos_expected
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_surveys_one_reversed_go_up_whole_and_are_measured_with_their_photos() {
    let work = tempfile::tempdir().unwrap();
    let m = mission();
    let reversed = [1];
    let model =
        VehicleModel::open(&VehicleSource::BuiltIn, Some(Profile::Ardupilot)).expect("model");
    let (plan, nodes, legs) = reversed_flight(&m, &model, &reversed);
    let flight = Flight {
        sortie: None,
        nodes: &nodes,
        legs: &legs,
        battery: &plan.battery,
    };
    let order = flight.waypoints();

    let mock = emplan::sim::MockAutopilot::spawn(
        "udpin:127.0.0.1:0",
        emplan::sim::MockConfig {
            flavour: Flavour::ArduPilot,
            flight: Some(emplan::sim::FlightConfig {
                profile: Some(Profile::Ardupilot),
                home: m.origin.home,
                ..Default::default()
            }),
            speedup: 20.0,
            ..Default::default()
        },
    )
    .await
    .expect("mock");
    let (link, target, cfg) = ground_station(&mock).await;
    let recorder = emplan::session::spawn_recorder(
        &link,
        emplan::session::RecorderConfig::new(work.path().join("logs")),
    );
    let load = emplan::session::Load {
        mission: &m,
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
        timeout: Duration::from_secs(900),
        ..Default::default()
    };
    let flown = emplan::session::fly(
        &link,
        &target,
        cfg,
        &recorder,
        &load,
        &options,
        |_| {},
        |_| {},
    )
    .await
    .expect("flown and landed");
    recorder.close().await;
    let (report, _) = flown.reported().expect("a report");
    assert!(
        report.complete && report.waypoints_left.is_empty(),
        "{report:?}"
    );
    check_report(&m, &reversed, &report.blocks);
    drop(link);

    // What the vehicle holds, downloaded through the binary.
    let url = format!("udpout:{}", mock.local_addr());
    let out = work.path().join("held.plan");
    let (ok, stdout, stderr) = emplan(&["download", "--connect", &url, out.to_str().unwrap()]);
    assert!(ok, "{stdout}\n{stderr}");
    let held = emplan::mission::load(&out).expect("the downloaded plan reads");
    check_held(&m, &order, &held);
    mock.shutdown().await.expect("mock stops");
}

/// The waypoint of `m` nearest each of `held`'s first waypoints (horizontally, within 5 cm):
/// the order the vehicle holds, as indices into `m`'s waypoints.
fn order_held(m: &Mission, held: &Mission) -> Vec<usize> {
    held.waypoints
        .iter()
        .take(m.waypoints.len())
        .map(|h| {
            let off = |k: usize| {
                let p = m.waypoints[k].position;
                (p.x_east_m - h.position.x_east_m).hypot(p.y_north_m - h.position.y_north_m)
            };
            let k = (0..m.waypoints.len())
                .min_by(|&a, &b| off(a).total_cmp(&off(b)))
                .expect("waypoints");
            assert!(off(k) < 0.05, "{} held is no waypoint of the file", h.name);
            k
        })
        .collect()
}

#[test]
fn the_shipped_orchard_survey_goes_up_in_the_energy_order_each_survey_whole_with_its_trigger_at_its_ends(
) {
    let file = root().join("missions/orchard-survey.plan");
    let m = emplan::mission::load(&file).expect("the shipped survey mission");
    assert_eq!(m.blocks.len(), 2);
    let runtime = tokio::runtime::Runtime::new().expect("runtime");
    let mock = runtime.block_on(super::fence_link::mock_at(&m, Flavour::ArduPilot));
    let url = format!("udpout:{}", mock.local_addr());
    let (ok, stdout, stderr) = emplan(&[
        "upload",
        file.to_str().expect("path"),
        "--order",
        "energy",
        "--profile",
        "ardupilot",
        "--connect",
        &url,
    ]);
    assert!(ok, "{stdout}\n{stderr}");
    let tmp = tempfile::tempdir().expect("temp dir");
    let out = tmp.path().join("held.plan");
    let (ok, stdout, stderr) = emplan(&["download", "--connect", &url, out.to_str().unwrap()]);
    assert!(ok, "{stdout}\n{stderr}");
    let held = emplan::mission::load(&out).expect("the downloaded plan reads");
    let order = order_held(&m, &held);
    // The order held is the plan's energy order with the same profile.
    let doc = crate::json(&[
        "plan",
        "missions/orchard-survey.plan",
        "--order",
        "energy",
        "--profile",
        "ardupilot",
        "--json",
    ]);
    let names: Vec<&str> = doc["orders"][0]["sequence"]
        .as_array()
        .expect("sequence")
        .iter()
        .filter_map(|s| s.as_str())
        .collect();
    let planned: Vec<usize> = names
        .iter()
        .map(|n| {
            m.waypoints
                .iter()
                .position(|w| w.name == *n)
                .expect("a waypoint")
        })
        .collect();
    assert_eq!(order, planned);
    check_held(&m, &order, &held);
    runtime.block_on(mock.shutdown()).expect("mock stops");
}
