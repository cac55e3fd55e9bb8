//! ArduPilot DataFlash logs read into readings: a real ArduCopter SITL flight's `.bin` (trimmed
//! to the records emplan reads; tests/fixtures/onboard/README.md says how it was made) against
//! the mission emplan uploaded and the `.tlog` report of the same flight, and damaged files
//! (truncated, bit-flipped, random, another format) read without a panic.

use std::path::Path;

use emplan::flightlog::flight_plan::FlightPlan;
use emplan::flightlog::onboard::{self, dataflash, Format, OnboardError, OnboardLog};
use emplan::flightlog::report::FlightReport;
use emplan::flightlog::segment::{SegmentConfig, Segmenter};
use emplan::flightlog::telemetry::{FlightMode, LandedState, Reading};
use emplan::mission::Geodetic;
use emplan::rng::Rng;

const DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/onboard");

fn fixture_bytes() -> Vec<u8> {
    std::fs::read(Path::new(DIR).join("arducopter-8wp.bin")).expect("the fixture is there")
}

fn fixture() -> OnboardLog {
    let log = onboard::read(&Path::new(DIR).join("arducopter-8wp.bin")).expect("it reads");
    assert_eq!(log.format, Format::Dataflash);
    log
}

fn plan() -> FlightPlan {
    FlightPlan::read_json(&Path::new(DIR).join("arducopter-8wp.plan.json")).expect("the plan")
}

fn readings<'a, T>(
    log: &'a OnboardLog,
    pick: impl Fn(&'a Reading) -> Option<T> + 'a,
) -> impl Iterator<Item = (f64, T)> + 'a {
    log.stamped
        .iter()
        .filter_map(move |s| pick(&s.reading).map(|x| (s.t_s, x)))
}

#[test]
fn a_real_arducopter_log_reads_whole_with_battery_at_ten_hertz_and_its_energy_counter() {
    let log = fixture();
    assert!(log.tear.is_none(), "{:?}", log.tear);
    log.check_measurable().expect("measurable");
    let rate = log.battery_rate_hz().expect("battery readings");
    // ArduCopter logs BAT at 10 Hz (its 10 Hz logging loop).
    assert!((9.5..=11.0).contains(&rate), "{rate} Hz");
    let batteries: Vec<_> = readings(&log, |r| match r {
        Reading::Battery(b) => Some(*b),
        _ => None,
    })
    .collect();
    assert!(batteries.len() > 2000, "{}", batteries.len());
    let mut last_j = 0.0;
    for (t, b) in &batteries {
        let v = b.voltage_v.expect("a voltage");
        assert!((22.0..=25.3).contains(&v), "{v} V at {t}");
        assert!(b.current_a.is_some(), "a current at {t}");
        let j = b.energy_consumed_j.expect("EnrgTot");
        assert!(j >= last_j, "EnrgTot falls at {t}: {j} < {last_j}");
        last_j = j;
        assert!(b.consumed_mah.is_some());
    }
    // About 46 A at 23-24 V for 209 s of flight: some 220 kJ (the .tlog measured 215 kJ).
    assert!((180e3..260e3).contains(&last_j), "{last_j} J");
    let hover = batteries
        .iter()
        .filter(|(t, _)| (60.0..70.0).contains(t))
        .map(|(_, b)| b.current_a.unwrap_or_default())
        .fold(0.0, f64::max);
    assert!((35.0..60.0).contains(&hover), "{hover} A");
}

#[test]
fn positions_come_with_the_ekf_velocity_and_the_height_above_home() {
    let log = fixture();
    let positions: Vec<_> = readings(&log, |r| match r {
        Reading::Position(p) => Some(*p),
        _ => None,
    })
    .collect();
    // POS at 10 Hz over 209 s.
    assert!(positions.len() > 2000, "{}", positions.len());
    let top = positions
        .iter()
        .map(|(_, p)| p.relative_alt_m)
        .fold(f64::MIN, f64::max);
    // The highest points fly at 30 + 19 m above home.
    assert!((47.0..52.0).contains(&top), "{top} m");
    for (t, p) in &positions {
        assert!((p.alt_amsl_m - 16.1 - p.relative_alt_m).abs() < 0.5, "at {t}");
        assert!((p.lat_deg - 38.5362).abs() < 0.001 && (p.lon_deg + 121.7875).abs() < 0.001);
    }
    let fastest = positions
        .iter()
        .map(|(_, p)| p.speed_m_s())
        .fold(0.0, f64::max);
    assert!((2.0..20.0).contains(&fastest), "{fastest} m/s");
    let homes: Vec<_> = readings(&log, |r| match r {
        Reading::Home { alt_amsl_m, .. } => Some(*alt_amsl_m),
        _ => None,
    })
    .collect();
    assert!(!homes.is_empty());
    assert!(homes.iter().all(|(_, alt)| (alt - 16.1).abs() < 1e-3));
}

#[test]
fn the_mission_from_cmd_records_is_the_one_emplan_uploaded() {
    let log = fixture();
    let plan = plan();
    let mission = log.mission.as_ref().expect("CMD records");
    let seqs: Vec<u16> = mission.iter().map(|c| c.seq).collect();
    assert_eq!(seqs, (0..12).collect::<Vec<u16>>());
    // 0: home (MAV_CMD_NAV_WAYPOINT, MAV_FRAME_GLOBAL: metres above mean sea level).
    assert_eq!((mission[0].command, mission[0].frame), (16, 0));
    assert!((mission[0].alt_m - 16.1).abs() < 1e-3);
    // 1: NAV_TAKEOFF to the origin's height above home (MAV_FRAME_GLOBAL_RELATIVE_ALT).
    assert_eq!((mission[1].command, mission[1].frame), (22, 3));
    assert!((mission[1].alt_m - plan.origin_height_m).abs() < 1e-3);
    // The plan's points: waypoints holding their hover time, at their place.
    let origin = plan.origin();
    for point in &plan.points {
        let c = &mission[usize::from(point.seq)];
        assert_eq!((c.command, c.frame), (16, 3), "item {}", point.seq);
        assert!((f64::from(c.params[0]) - point.hold_s).abs() < 1e-6);
        let at = origin.to_enu(Geodetic {
            lat_deg: c.lat_deg,
            lon_deg: c.lon_deg,
            alt_m: plan.home.alt_m + c.alt_m,
        });
        let off = ((at.x_east_m - point.enu.x_east_m).powi(2)
            + (at.y_north_m - point.enu.y_north_m).powi(2)
            + (at.z_up_m - point.enu.z_up_m).powi(2))
        .sqrt();
        assert!(off < 0.05, "item {} is {off} m off {}", point.seq, point.name);
    }
    // The last: NAV_LAND.
    assert_eq!(mission[11].command, 21);
}

#[test]
fn the_flight_arms_flies_the_mission_in_order_lands_and_disarms() {
    let log = fixture();
    let beats: Vec<_> = readings(&log, |r| match r {
        Reading::Heartbeat { armed, mode } => Some((*armed, mode.clone())),
        _ => None,
    })
    .collect();
    // Disarmed just before the log (it opened at arming), armed through the flight, disarmed.
    assert_eq!(beats.first().map(|b| b.1 .0), Some(false));
    let arm = beats.iter().position(|b| b.1 .0).expect("armed");
    let disarm = arm + beats[arm..].iter().position(|b| !b.1 .0).expect("disarmed");
    let flight_s = beats[disarm].0 - beats[arm].0;
    assert!((200.0..220.0).contains(&flight_s), "{flight_s} s armed");
    // Once a second while armed, as HEARTBEAT streams.
    let gaps = beats[arm..=disarm].windows(2).map(|w| w[1].0 - w[0].0);
    assert!(gaps.clone().all(|g| g <= 1.2), "{:?}", gaps.collect::<Vec<_>>());
    assert!(beats.iter().any(|b| b.1 .1 == FlightMode::Mission));
    assert!(beats.iter().any(|b| b.1 .1 == FlightMode::Guided));
    let disarm_s = beats[disarm].0;
    let current: Vec<u16> = readings(&log, |r| match r {
        Reading::MissionCurrent { seq, .. } => Some(*seq),
        _ => None,
    })
    .filter(|(t, _)| *t < disarm_s)
    .map(|(_, s)| s)
    .collect();
    assert_eq!(current, (1..=11).collect::<Vec<u16>>());
    let reached: Vec<u16> = readings(&log, |r| match r {
        Reading::ItemReached { seq } => Some(*seq),
        _ => None,
    })
    .filter(|(t, _)| *t < disarm_s)
    .map(|(_, s)| s)
    .collect();
    assert_eq!(reached, (1..=10).collect::<Vec<u16>>());
    let landed: Vec<_> = readings(&log, |r| match r {
        Reading::Landed(l) => Some(*l),
        _ => None,
    })
    .collect();
    assert_eq!(
        landed.iter().map(|l| l.1).collect::<Vec<_>>(),
        [LandedState::InAir, LandedState::OnGround]
    );
    assert!(landed[1].0 < disarm_s);
}

/// The .tlog report of the same flight (`emplan fly` recorded it over MAVLink), its legs as
/// (from, to, start_s, end_s, measured J).
fn tlog_legs() -> Vec<(String, String, f64, f64, f64)> {
    let text = std::fs::read_to_string(Path::new(DIR).join("arducopter-8wp.tlog-report.json"))
        .expect("the .tlog report");
    let json: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    json["legs"]
        .as_array()
        .expect("legs")
        .iter()
        .map(|l| {
            (
                l["from"].as_str().unwrap_or_default().to_string(),
                l["to"].as_str().unwrap_or_default().to_string(),
                l["start_s"].as_f64().unwrap_or(f64::NAN),
                l["end_s"].as_f64().unwrap_or(f64::NAN),
                l["measured_kj"].as_f64().unwrap_or(f64::NAN) * 1e3,
            )
        })
        .collect()
}

#[test]
fn the_onboard_log_segments_into_the_tlogs_legs_with_the_same_energy() {
    let log = fixture();
    let segmenter =
        Segmenter::run(plan(), SegmentConfig::default(), &log.stamped).expect("a valid plan");
    let report = FlightReport::build("arducopter-8wp", &segmenter);
    assert!(report.complete);
    let tlog = tlog_legs();
    assert_eq!(report.legs.len(), tlog.len());
    // The two clocks: the .tlog's starts at its first message, the log's at arming; the first
    // leg's start tells the offset.
    let offset = tlog[0].2 - report.legs[0].start_s;
    for (leg, (from, to, start_s, end_s, tlog_j)) in report.legs.iter().zip(&tlog) {
        assert_eq!((&leg.from, &leg.to), (from, to));
        assert!(leg.flags.is_empty(), "{from} -> {to}: {:?}", leg.flags);
        // The .tlog's positions come at 4 Hz over the radio, the log's at 10 Hz.
        assert!(
            (leg.start_s + offset - start_s).abs() < 0.4 && (leg.end_s + offset - end_s).abs() < 0.4,
            "{from} -> {to}: {}..{} + {offset} against {start_s}..{end_s}",
            leg.start_s,
            leg.end_s
        );
        let j = leg.measured_j.expect("measured");
        let error = (j - tlog_j) / tlog_j;
        assert!(error.abs() < 0.03, "{from} -> {to}: {j} J against {tlog_j} J");
    }
}
