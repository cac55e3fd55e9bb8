//! ArduPilot DataFlash logs read into readings: a real ArduCopter SITL flight's `.bin` (trimmed
//! to the records emplan reads; tests/fixtures/onboard/README.md says how it was made) against
//! the mission emplan uploaded and the `.tlog` report of the same flight, and damaged files
//! (truncated, bit-flipped, random, another format) read without a panic.

use std::path::Path;

use emplan::flightlog::flight_plan::FlightPlan;
use emplan::flightlog::onboard::{self, dataflash, Format, OnboardError, OnboardLog};
use emplan::flightlog::report::FlightReport;
use emplan::flightlog::segment::{SegmentConfig, Segmenter};
use emplan::flightlog::telemetry::{FlightMode, LandedState, Reading, Stamped};
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
        assert!(
            (p.alt_amsl_m - 16.1 - p.relative_alt_m).abs() < 0.5,
            "at {t}"
        );
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
        assert!(
            off < 0.05,
            "item {} is {off} m off {}",
            point.seq,
            point.name
        );
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
    assert!(
        gaps.clone().all(|g| g <= 1.2),
        "{:?}",
        gaps.collect::<Vec<_>>()
    );
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
            (leg.start_s + offset - start_s).abs() < 0.4
                && (leg.end_s + offset - end_s).abs() < 0.4,
            "{from} -> {to}: {}..{} + {offset} against {start_s}..{end_s}",
            leg.start_s,
            leg.end_s
        );
        let j = leg.measured_j.expect("measured");
        let error = (j - tlog_j) / tlog_j;
        assert!(
            error.abs() < 0.03,
            "{from} -> {to}: {j} J against {tlog_j} J"
        );
    }
}

fn padded(text: &str, n: usize) -> Vec<u8> {
    let mut v = text.as_bytes().to_vec();
    v.resize(n, 0);
    v
}

/// An FMT record describing message `id`.
fn fmt(id: u8, name: &str, format: &str, labels: &str) -> Vec<u8> {
    let len: usize = 3 + format
        .bytes()
        .map(|c| dataflash::field_size(c).expect("a format character"))
        .sum::<usize>();
    let mut r = vec![0xA3, 0x95, 128, id, u8::try_from(len).expect("short")];
    r.extend(padded(name, 4));
    r.extend(padded(format, 16));
    r.extend(padded(labels, 64));
    r
}

fn record(id: u8, body: &[u8]) -> Vec<u8> {
    let mut r = vec![0xA3, 0x95, id];
    r.extend_from_slice(body);
    r
}

/// A file's start: FMT describing itself, as ArduPilot writes it.
fn start() -> Vec<u8> {
    fmt(128, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns")
}

#[test]
fn every_format_character_arducopter_uses_decodes_to_its_value_and_unit() {
    let mut file = start();
    file.extend(fmt(
        200,
        "ONE",
        "QbBhHiIfdnNZ",
        "TimeUS,b,B,h,H,i,I,f,d,n,N,Z",
    ));
    file.extend(fmt(201, "TWO", "QcCeELMqQag", "TimeUS,c,C,e,E,L,M,q,Q,a,g"));
    let mut one = 7u64.to_le_bytes().to_vec();
    one.extend((-5i8).to_le_bytes());
    one.push(250);
    one.extend((-1234i16).to_le_bytes());
    one.extend(65000u16.to_le_bytes());
    one.extend((-100_000i32).to_le_bytes());
    one.extend(4_000_000_000u32.to_le_bytes());
    one.extend(1.5f32.to_le_bytes());
    one.extend((-2.25f64).to_le_bytes());
    one.extend(padded("ab", 4));
    one.extend(padded("sixteen-chars-ok", 16));
    one.extend(padded("a message", 64));
    file.extend(record(200, &one));
    let mut two = 8u64.to_le_bytes().to_vec();
    two.extend((-1234i16).to_le_bytes());
    two.extend(65000u16.to_le_bytes());
    two.extend((-123_456i32).to_le_bytes());
    two.extend(4_000_000_000u32.to_le_bytes());
    two.extend((-1_217_875_000i32).to_le_bytes());
    two.push(3);
    two.extend((-9_000_000_000_000_000i64).to_le_bytes());
    two.extend(u64::MAX.to_le_bytes());
    for k in 0..32i16 {
        two.extend((k * -3).to_le_bytes());
    }
    two.extend(0xC170u16.to_le_bytes());
    file.extend(record(201, &two));
    let (records, scan) = dataflash::records(&file);
    assert_eq!((scan.records, scan.skipped_bytes, scan.tear), (5, 0, None));
    let [one, two] = &records[..] else {
        panic!("two records: {records:?}");
    };
    use dataflash::Value::{Array, Float, Int, Text, UInt};
    let exact = [
        ("TimeUS", UInt(7)),
        ("b", Int(-5)),
        ("B", UInt(250)),
        ("h", Int(-1234)),
        ("H", UInt(65000)),
        ("i", Int(-100_000)),
        ("I", UInt(4_000_000_000)),
        ("f", Float(1.5)),
        ("d", Float(-2.25)),
        ("n", Text("ab".into())),
        ("N", Text("sixteen-chars-ok".into())),
        ("Z", Text("a message".into())),
    ];
    for (label, value) in exact {
        assert_eq!(one.get(label), Some(&value), "{label}");
    }
    let scaled = [
        ("c", -12.34),
        ("C", 650.0),
        ("e", -1234.56),
        ("E", 40_000_000.0),
        ("L", -121.7875),
        ("g", -2.71875),
    ];
    for (label, want) in scaled {
        let got = two.get(label).and_then(|v| v.as_f64()).expect(label);
        assert!(
            (got - want).abs() < 1e-9 * want.abs().max(1.0),
            "{label}: {got}"
        );
    }
    assert_eq!(two.get("M"), Some(&UInt(3)));
    assert_eq!(two.get("q"), Some(&Int(-9_000_000_000_000_000)));
    assert_eq!(two.get("Q"), Some(&UInt(u64::MAX)));
    let a: Vec<i16> = (0..32).map(|k| k * -3).collect();
    assert_eq!(two.get("a"), Some(&Array(a)));
}

#[test]
fn half_floats_decode_as_ieee_binary16() {
    let cases = [
        (0x0000, 0.0),
        (0x3C00, 1.0),
        (0xC000, -2.0),
        (0x3555, 0.333_251_953_125),
        (0x7BFF, 65504.0),
        (0x0001, 2f64.powi(-24)),
        (0x0400, 2f64.powi(-14)),
        (0xFC00, f64::NEG_INFINITY),
    ];
    for (bits, want) in cases {
        assert_eq!(dataflash::half_to_f64(bits), want, "{bits:#06x}");
    }
    assert!(dataflash::half_to_f64(0x7E00).is_nan());
}

const BAT: &str = "QBfffffcfBBB";
const BAT_LABELS: &str = "TimeUS,Inst,Volt,VoltR,Curr,CurrTot,EnrgTot,Temp,Res,RemPct,H,SH";

fn bat(t_us: u64, instance: u8, volt: f32, curr: f32, enrg_wh: f32) -> Vec<u8> {
    let mut b = t_us.to_le_bytes().to_vec();
    b.push(instance);
    for v in [volt, volt, curr, f32::NAN, enrg_wh] {
        b.extend(v.to_le_bytes());
    }
    b.extend(2500i16.to_le_bytes());
    b.extend(0.01f32.to_le_bytes());
    b.extend([80, 1, 0]);
    record(210, &b)
}

fn arm(t_us: u64, armed: bool) -> Vec<u8> {
    let mut b = t_us.to_le_bytes().to_vec();
    b.push(u8::from(armed));
    b.extend(0u32.to_le_bytes());
    b.extend([0, 0]);
    record(211, &b)
}

/// A hand-made log: two batteries (instance 0 without a current sensor), armed after 1 s,
/// disarmed after 3 s.
fn small_log() -> Vec<u8> {
    let mut file = start();
    file.extend(fmt(210, "BAT", BAT, BAT_LABELS));
    file.extend(fmt(
        211,
        "ARM",
        "QBIBB",
        "TimeUS,ArmState,ArmChecks,Forced,Method",
    ));
    file.extend(fmt(212, "MODE", "QMBB", "TimeUS,Mode,ModeNum,Rsn"));
    let mut mode = 1_000_000u64.to_le_bytes().to_vec();
    mode.extend([5, 5, 1]);
    file.extend(record(212, &mode));
    for k in 0..40u64 {
        let t = 1_000_000 + k * 100_000;
        if k == 10 {
            file.extend(arm(t, true));
        }
        if k == 30 {
            file.extend(arm(t, false));
        }
        file.extend(bat(t, 0, 25.0, f32::NAN, f32::NAN));
        file.extend(bat(t, 1, 24.0, 40.0, k as f32 * 0.01));
    }
    file
}

#[test]
fn the_battery_with_a_current_is_chosen_and_an_unknown_current_is_none() {
    let log = dataflash::parse("small.bin", &small_log()).expect("it reads");
    let batteries: Vec<_> = readings(&log, |r| match r {
        Reading::Battery(b) => Some(*b),
        _ => None,
    })
    .collect();
    assert_eq!(batteries.len(), 40);
    for (_, b) in &batteries {
        assert_eq!(b.current_a, Some(40.0));
        assert_eq!(b.voltage_v, Some(24.0));
        assert_eq!(b.consumed_mah, None, "NaN is unknown");
    }
    assert!((batteries[39].1.energy_consumed_j.expect("EnrgTot") - 0.39 * 3600.0).abs() < 1e-3);
    // Instance 0 alone: its current stays unknown, never 0.
    let mut only0 = start();
    only0.extend(fmt(210, "BAT", BAT, BAT_LABELS));
    only0.extend(bat(5, 0, 25.0, f32::NAN, f32::NAN));
    let log = dataflash::parse("only0.bin", &only0).expect("it reads");
    assert!(matches!(&log.stamped[..], [s] if matches!(s.reading,
        Reading::Battery(b) if b.current_a.is_none() && b.voltage_v == Some(25.0))));
}

#[test]
fn an_arming_record_first_says_the_vehicle_was_disarmed_before_it() {
    let log = dataflash::parse("small.bin", &small_log()).expect("it reads");
    let beats: Vec<_> = readings(&log, |r| match r {
        Reading::Heartbeat { armed, mode } => Some((*armed, mode.clone())),
        _ => None,
    })
    .collect();
    // The first arming record is an arming: disarmed before it (from the mode's record at the
    // log's start, and the once-a-second repeat just before the arming), armed from it, once a
    // second, then the disarm.
    let armed: Vec<(f64, bool)> = beats.iter().map(|(t, b)| (*t, b.0)).collect();
    assert_eq!(
        armed,
        [
            (0.0, false),
            (1.0, false),
            (1.0, true),
            (2.0, true),
            (3.0, true),
            (3.0, false)
        ]
    );
    assert!(beats.iter().all(|(_, b)| b.1 == FlightMode::Hold));
}

#[test]
fn bytes_between_records_are_skipped_counted_and_change_nothing() {
    let clean = small_log();
    let fmts = start().len() + 3 * 89;
    // After the MODE record (14 bytes), before the first BAT.
    let mut dirty = clean[..fmts + 14].to_vec();
    let garbage: Vec<u8> = (0..57u8).map(|k| k % 0x90).collect();
    dirty.extend(&garbage);
    dirty.extend(&clean[fmts + 14..]);
    let (a, scan_a) = dataflash::parse_scanned("clean.bin", &clean).expect("reads");
    let (b, scan_b) = dataflash::parse_scanned("dirty.bin", &dirty).expect("reads");
    assert_eq!(scan_a.skipped_bytes, 0);
    assert_eq!(scan_b.skipped_bytes, garbage.len() as u64);
    assert_eq!(scan_a.records, scan_b.records);
    assert_eq!(a.stamped, b.stamped);
    assert!(b.tear.is_none());
    // The same bytes at the end, with no record after them, are where the file tore.
    let mut tail = clean.clone();
    tail.extend(&garbage);
    let c = dataflash::parse("tail.bin", &tail).expect("reads");
    let tear = c.tear.expect("torn");
    assert_eq!(tear.offset, clean.len() as u64);
    assert_eq!(c.stamped, a.stamped);
}

#[test]
fn a_record_whose_format_does_not_add_up_is_stepped_over() {
    let mut file = start();
    let mut bad = fmt(220, "BAD", "QB", "TimeUS,B");
    bad[4] = 20; // says 20 bytes where the format takes 12
    file.extend(bad);
    file.extend(fmt(210, "BAT", BAT, BAT_LABELS));
    file.extend(record(220, &[1; 17]));
    file.extend(bat(9, 0, 24.5, 30.0, 1.0));
    let (records, scan) = dataflash::records(&file);
    assert_eq!(scan.tear, None);
    assert_eq!(records.len(), 2);
    assert!(records[0].fields.is_empty());
    assert_eq!(records[1].name, "BAT");
}

#[test]
fn a_truncated_real_log_keeps_what_came_before_the_cut_and_says_where_it_tore() {
    let bytes = fixture_bytes();
    let full = dataflash::parse("full.bin", &bytes).expect("reads");
    let parameters_end = 64_000;
    let mut rng = Rng::new(28);
    let mut cuts: Vec<usize> = (0..120).map(|_| rng.below(bytes.len())).collect();
    cuts.extend(0..40);
    cuts.extend([bytes.len() - 1, bytes.len() - 2, bytes.len() - 3]);
    for cut in cuts {
        let part = &bytes[..cut];
        match dataflash::parse("cut.bin", part) {
            Ok(log) => {
                // Once its parameters are read (LOG_DISARMED: the log opened at arming), a cut
                // log's readings are the whole log's up to the cut; before, all but the
                // heartbeats (the arming state is not known yet).
                let beat = |s: &&Stamped| matches!(s.reading, Reading::Heartbeat { .. });
                if cut > parameters_end {
                    assert!(full.stamped.starts_with(&log.stamped), "cut at {cut}");
                } else {
                    let whole: Vec<_> = full.stamped.iter().filter(|s| !beat(s)).collect();
                    let part: Vec<_> = log.stamped.iter().filter(|s| !beat(s)).collect();
                    assert!(whole.starts_with(&part), "cut at {cut}");
                }
                if let Some(tear) = &log.tear {
                    assert!(tear.offset <= cut as u64, "cut at {cut}: {tear:?}");
                    assert!(!tear.reason.is_empty());
                }
            }
            Err(OnboardError::Malformed { offset, .. }) => {
                assert!(cut < 3 && offset == 0, "cut at {cut}");
            }
            Err(e) => panic!("cut at {cut}: {e}"),
        }
    }
    // Cut inside a record: torn there, with the time of the last reading before it.
    let cut = bytes.len() - 5;
    let log = dataflash::parse("cut.bin", &bytes[..cut]).expect("reads");
    let tear = log.tear.expect("torn");
    assert!(tear.offset < cut as u64 && cut as u64 - tear.offset < 100);
    assert!(tear.reason.contains("cut short"), "{}", tear.reason);
    assert_eq!(tear.after_s, log.stamped.last().map(|s| s.t_s));
}

#[test]
fn bit_flips_and_random_bytes_never_panic() {
    let bytes = fixture_bytes();
    let full = dataflash::parse("full.bin", &bytes).expect("reads");
    let batteries = |log: &OnboardLog| {
        log.stamped
            .iter()
            .filter(|s| matches!(s.reading, Reading::Battery(_)))
            .count()
    };
    let mut rng = Rng::new(2028);
    for round in 0..60 {
        let mut flipped = bytes.clone();
        for _ in 0..1 + round % 8 {
            let at = rng.below(flipped.len());
            flipped[at] ^= 1 << rng.below(8);
        }
        match dataflash::parse("flipped.bin", &flipped) {
            // A few flipped bits lose a few records, not the log.
            Ok(log) => assert!(
                batteries(&log) * 10 >= batteries(&full) * 9,
                "round {round}"
            ),
            Err(OnboardError::Malformed { offset: 0, .. }) => {}
            Err(e) => panic!("round {round}: {e}"),
        }
    }
    for round in 0..300 {
        let len = rng.below(3000);
        let mut random: Vec<u8> = (0..len).map(|_| rng.below(256) as u8).collect();
        if round % 2 == 0 {
            // Start like a log, and sprinkle headers and FMT records in.
            let mut head = start();
            head.extend(fmt(
                rng.below(256) as u8,
                "XX",
                "QBfL",
                "TimeUS,Inst,Volt,Lat",
            ));
            random.splice(0..0, head);
            for _ in 0..20 {
                let at = rng.below(random.len() - 1);
                random[at] = 0xA3;
                random[at + 1] = 0x95;
            }
        }
        let _ = dataflash::parse("random.bin", &random);
        let _ = dataflash::records(&random);
        let _ = onboard::parse("random.bin", &random);
    }
}

#[test]
fn a_file_of_another_format_is_refused_naming_it() {
    let err = dataflash::parse("notes.txt", b"hello, this is not a log").expect_err("refused");
    let text = err.to_string();
    assert!(
        text.contains("notes.txt") && text.contains("byte 0"),
        "{text}"
    );
    match onboard::parse("notes.txt", b"hello") {
        Err(OnboardError::UnknownFormat { file, .. }) => assert_eq!(file, "notes.txt"),
        other => panic!("{other:?}"),
    }
    // A ULog is not read as DataFlash.
    assert!(dataflash::parse("x.ulg", b"ULog\x01\x12\x35\x01").is_err());
}

#[test]
fn a_log_torn_mid_flight_gives_the_legs_flown_before_the_tear() {
    let bytes = fixture_bytes();
    // Halfway through the file: in leg G -> B (the fifth) by the .tlog's times.
    let cut = bytes.len() / 2 + 11;
    let log = dataflash::parse("torn.bin", &bytes[..cut]).expect("reads");
    let tear = log.tear.as_ref().expect("torn");
    assert!(tear.offset <= cut as u64);
    log.check_measurable().expect("measurable up to the tear");
    let segmenter =
        Segmenter::run(plan(), SegmentConfig::default(), &log.stamped).expect("a valid plan");
    let report = FlightReport::build("torn", &segmenter);
    assert!(!report.complete);
    let tlog = tlog_legs();
    let whole: Vec<_> = report
        .legs
        .iter()
        .take_while(|l| l.end_s < tear.after_s.unwrap_or_default())
        .filter(|l| l.flags.is_empty())
        .collect();
    assert!(whole.len() >= 3, "{} legs before the tear", whole.len());
    for (leg, (from, to, .., tlog_j)) in whole.iter().zip(&tlog) {
        assert_eq!((&leg.from, &leg.to), (from, to));
        let j = leg.measured_j.expect("measured");
        assert!((j - tlog_j).abs() < 0.03 * tlog_j, "{from} -> {to}");
    }
}

#[test]
fn mode_numbers_are_arducopters_unless_the_log_names_another_vehicle() {
    let mut file = start();
    file.extend(fmt(212, "MODE", "QMBB", "TimeUS,Mode,ModeNum,Rsn"));
    file.extend(fmt(213, "MSG", "QZ", "TimeUS,Message"));
    file.extend(fmt(
        211,
        "ARM",
        "QBIBB",
        "TimeUS,ArmState,ArmChecks,Forced,Method",
    ));
    let mut mode = 10u64.to_le_bytes().to_vec();
    mode.extend([3, 3, 1]);
    let modes = |log: &OnboardLog| -> Vec<FlightMode> {
        readings(log, |r| match r {
            Reading::Heartbeat { mode, .. } => Some(mode.clone()),
            _ => None,
        })
        .map(|(_, m)| m)
        .collect()
    };
    // The version's MSG comes after the log's first MODE, as ArduPilot writes them.
    let with = |version: &str| {
        let mut f = file.clone();
        f.extend(record(212, &mode));
        let mut msg = 11u64.to_le_bytes().to_vec();
        msg.extend(padded(version, 64));
        f.extend(record(213, &msg));
        f.extend(arm(12, true));
        dataflash::parse("modes.bin", &f).expect("reads")
    };
    let copter = with("ArduCopter V4.8.0-dev (14ff23ec)");
    assert!(!modes(&copter).is_empty());
    assert!(modes(&copter).iter().all(|m| *m == FlightMode::Mission));
    let plane = with("ArduPlane V4.6.0 (abcdef01)");
    assert!(!modes(&plane).is_empty());
    assert!(modes(&plane)
        .iter()
        .all(|m| *m == FlightMode::Other("custom 3".into())));
}
