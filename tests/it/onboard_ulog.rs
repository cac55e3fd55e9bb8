//! PX4's own flight log read as stamped readings: a real SITL ULog (the fixture beside its
//! README) gives the battery at 5 Hz with its current, positions, mission progress through
//! every item, the arming and the landing, and segments into every leg of its plan; torn,
//! bit-flipped, random and foreign bytes give the readings before the damage with where it is,
//! or a located error, and never a panic.

use std::path::{Path, PathBuf};

use emplan::flightlog::flight_plan::FlightPlan;
use emplan::flightlog::onboard::{self, ulog, OnboardError, OnboardLog};
use emplan::flightlog::report::FlightReport;
use emplan::flightlog::segment::{SegmentConfig, Segmenter};
use emplan::flightlog::telemetry::{LandedState, Reading};
use emplan::rng::Rng;

fn fixture_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/onboard")
}

fn fixture() -> Vec<u8> {
    std::fs::read(fixture_dir().join("px4-sih-8wp.ulg")).expect("the ULog fixture")
}

fn parse(bytes: &[u8]) -> Result<OnboardLog, OnboardError> {
    onboard::parse("px4.ulg", bytes)
}

fn count(log: &OnboardLog, f: impl Fn(&Reading) -> bool) -> usize {
    log.stamped.iter().filter(|s| f(&s.reading)).count()
}

#[test]
fn a_real_px4_log_gives_the_battery_at_5_hz_with_its_current() {
    let log = parse(&fixture()).expect("the fixture parses");
    assert_eq!(log.format, onboard::Format::Ulog);
    assert!(log.tear.is_none(), "{:?}", log.tear);
    let rate = log.battery_rate_hz().expect("battery readings");
    assert!((4.5..5.5).contains(&rate), "battery at {rate} Hz");
    let batteries: Vec<_> = log
        .stamped
        .iter()
        .filter_map(|s| match &s.reading {
            Reading::Battery(b) => Some(*b),
            _ => None,
        })
        .collect();
    assert!(
        batteries.len() > 100,
        "{} battery readings",
        batteries.len()
    );
    // The injected battery (emplan battery-sim): about 25 V, a current of tens of amps in
    // flight, and PX4's own charge counter rising.
    for b in &batteries {
        let v = b.voltage_v.expect("a voltage");
        assert!((20.0..26.0).contains(&v), "{v} V");
        assert!(b.current_a.is_some() && !b.fake_current);
    }
    let max_a = batteries
        .iter()
        .filter_map(|b| b.current_a)
        .fold(0.0, f64::max);
    assert!(max_a > 10.0, "peak current {max_a} A");
    let consumed: Vec<f64> = batteries.iter().filter_map(|b| b.consumed_mah).collect();
    assert!(consumed.windows(2).all(|w| w[1] >= w[0] - 1e-6));
    assert!(
        consumed.last().copied().unwrap_or(0.0) > 100.0,
        "{consumed:?}"
    );
    log.check_measurable().expect("measurable");
}

#[test]
fn a_real_px4_log_gives_positions_progress_arming_and_landing() {
    let log = parse(&fixture()).expect("the fixture parses");
    assert!(log.stamped.windows(2).all(|w| w[0].t_s <= w[1].t_s));
    let positions = count(&log, |r| matches!(r, Reading::Position(_)));
    assert!(positions > 500, "{positions} positions");
    assert!(count(&log, |r| matches!(r, Reading::Home { .. })) >= 1);
    // Mission progress through every item of the 8-waypoint sample (take-off, 8 waypoints,
    // the origin, landing).
    let seqs: Vec<u16> = log
        .stamped
        .iter()
        .filter_map(|s| match s.reading {
            Reading::MissionCurrent { seq, .. } => Some(seq),
            _ => None,
        })
        .collect();
    let total = log.stamped.iter().find_map(|s| match s.reading {
        Reading::MissionCurrent { total, .. } => total,
        _ => None,
    });
    let total = total.expect("the mission's size");
    for seq in 0..total {
        assert!(
            seqs.contains(&seq),
            "seq {seq} of {total} never current: {seqs:?}"
        );
    }
    assert!(count(&log, |r| matches!(r, Reading::ItemReached { .. })) >= usize::from(total) - 2);
    // Armed, then disarmed after landing.
    let armed: Vec<bool> = log
        .stamped
        .iter()
        .filter_map(|s| match s.reading {
            Reading::Heartbeat { armed, .. } => Some(armed),
            _ => None,
        })
        .collect();
    let first_armed = armed.iter().position(|&a| a).expect("armed");
    assert!(armed[first_armed..].contains(&false), "never disarmed");
    let landed: Vec<LandedState> = log
        .stamped
        .iter()
        .filter_map(|s| match s.reading {
            Reading::Landed(l) => Some(l),
            _ => None,
        })
        .collect();
    let in_air = landed
        .iter()
        .position(|l| *l == LandedState::InAir)
        .expect("in the air");
    assert!(
        landed[in_air..].contains(&LandedState::OnGround),
        "{landed:?}"
    );
}

#[test]
fn a_real_px4_log_segments_into_every_leg_of_its_plan() {
    let log = parse(&fixture()).expect("the fixture parses");
    let plan = FlightPlan::read_json(&fixture_dir().join("px4-sih-8wp.plan.json")).expect("plan");
    let legs = plan.points.len();
    let segmenter =
        Segmenter::run(plan, SegmentConfig::default(), &log.stamped).expect("segmented");
    let report = FlightReport::build("px4-sih-8wp", &segmenter);
    let measured = report
        .legs
        .iter()
        .filter(|l| l.measured_j.is_some())
        .count();
    assert_eq!(measured, legs, "{report:#?}");
}

fn batteries(log: &OnboardLog) -> usize {
    count(log, |r| matches!(r, Reading::Battery(_)))
}

/// A parse that did not panic is either the readings (with where the file tore, if it did) or
/// an error locating the damage within the file.
fn assert_located(result: &Result<OnboardLog, OnboardError>, len: usize) {
    match result {
        Ok(log) => {
            if let Some(tear) = &log.tear {
                assert!(tear.offset <= len as u64, "{tear:?} past {len}");
                assert!(!tear.reason.is_empty());
            }
        }
        Err(OnboardError::Malformed { offset, reason, .. }) => {
            assert!(*offset <= len as u64, "{offset} past {len}: {reason}");
            assert!(!reason.is_empty());
        }
        Err(e) => panic!("an unexpected error: {e}"),
    }
}

#[test]
fn a_log_cut_anywhere_keeps_what_came_before_and_says_where_it_tore() {
    let bytes = fixture();
    let full = parse(&bytes).expect("the fixture parses");
    let cuts = (0..600)
        .step_by(7)
        .chain((0..160).map(|k| k * bytes.len() / 160 + k % 13));
    for cut in cuts.filter(|&c| c < bytes.len()) {
        let result = ulog::parse("px4.ulg", &bytes[..cut]);
        assert_located(&result, cut);
        if cut >= bytes.len() / 8 {
            // Past the definitions: the readings before the cut, and where it tore (unless the
            // cut fell between two records).
            let log = result.unwrap_or_else(|e| panic!("cut at {cut}: {e}"));
            assert!(log.stamped.len() <= full.stamped.len());
            assert!(batteries(&log) > 0, "cut at {cut}");
            if let Some(tear) = &log.tear {
                assert!(tear.offset <= cut as u64 && tear.offset + 65_538 >= cut as u64);
                assert!(tear.reason.contains("cut short"), "{}", tear.reason);
                let last = log.stamped.last().map(|s| s.t_s);
                assert_eq!(tear.after_s, last);
            }
        }
    }
    // The header alone, and less.
    for cut in [0, 3, 15, 16] {
        let err = ulog::parse("px4.ulg", &bytes[..cut]).err();
        assert!(
            matches!(err, Some(OnboardError::Malformed { .. })),
            "{cut}: {err:?}"
        );
    }
}

#[test]
fn a_log_cut_mid_flight_measures_the_legs_flown_up_to_the_tear() {
    let bytes = fixture();
    let cut = bytes.len() * 6 / 10 + 5;
    let log = parse(&bytes[..cut]).expect("the part before the tear");
    let tear = log.tear.clone().expect("a tear");
    assert!(tear.offset <= cut as u64);
    let plan = FlightPlan::read_json(&fixture_dir().join("px4-sih-8wp.plan.json")).expect("plan");
    let legs = plan.points.len();
    let segmenter =
        Segmenter::run(plan, SegmentConfig::default(), &log.stamped).expect("segmented");
    let report = FlightReport::build("torn", &segmenter);
    let measured = report
        .legs
        .iter()
        .filter(|l| l.measured_j.is_some())
        .count();
    assert!(
        measured >= 3 && measured < legs,
        "{measured} of {legs} legs measured"
    );
}

#[test]
fn bit_flips_give_readings_or_a_located_error_never_a_panic() {
    let bytes = fixture();
    let mut rng = Rng::new(28);
    for trial in 0..120 {
        let mut damaged = bytes.clone();
        // The definitions (the first tenth) as often as the data.
        let span = if trial % 2 == 0 {
            bytes.len() / 10
        } else {
            bytes.len()
        };
        for _ in 0..1 + rng.below(4) {
            let at = rng.below(span);
            damaged[at] ^= 1 << rng.below(8);
        }
        assert_located(&parse(&damaged), damaged.len());
    }
}

#[test]
fn random_and_foreign_bytes_are_refused_naming_the_file_or_the_byte() {
    let mut rng = Rng::new(7);
    for n in [0usize, 1, 10, 100, 5_000] {
        let noise: Vec<u8> = (0..n).map(|_| (rng.next_u64() >> 24) as u8).collect();
        // Noise is no onboard log at all...
        let err = onboard::parse("noise.bin", &noise).map(|_| ()).unwrap_err();
        if !noise.starts_with(onboard::dataflash::MAGIC) {
            assert!(err.to_string().starts_with("noise.bin: "), "{err}");
        }
        // ...and noise after a ULog header is a located error (or readings with a tear).
        let mut framed = ulog::MAGIC.to_vec();
        framed.extend_from_slice(&[0; 9]);
        framed.extend_from_slice(&noise);
        assert_located(&ulog::parse("noise.ulg", &framed), framed.len());
        // Read as a ULog, bytes that are not one are refused at byte 0.
        match ulog::parse("noise.ulg", &noise) {
            Err(OnboardError::Malformed { offset: 0, .. }) => {}
            other => panic!("{other:?}"),
        }
    }
}

/// A record: its kind and payload.
type RawRecord = (u8, Vec<u8>);

/// A ULog header, flag bits, then `records`.
fn crafted(records: &[RawRecord]) -> Vec<u8> {
    let mut out = ulog::MAGIC.to_vec();
    out.push(1);
    out.extend_from_slice(&0u64.to_le_bytes());
    let flag_bits = (b'B', vec![0u8; 40]);
    for (kind, payload) in std::iter::once(&flag_bits).chain(records) {
        out.extend_from_slice(&(payload.len() as u16).to_le_bytes());
        out.push(*kind);
        out.extend_from_slice(payload);
    }
    out
}

#[test]
fn records_the_crate_would_index_past_or_loop_on_are_refused_at_their_byte() {
    // The header is 16 bytes, the flag bits record 43: the record under test is at byte 59.
    let cases: Vec<(Vec<RawRecord>, &str)> = vec![
        (vec![(b'F', b"empty:".to_vec())], "empty has no fields"),
        (
            vec![(b'F', b"a:uint64_t timestamp;uint8_t[0] x".to_vec())],
            "an array of 0 elements",
        ),
        (vec![(b'P', vec![200, 1, 2])], "its key runs past its end"),
        (
            vec![(b'F', b"a:uint64_t timestamp".to_vec()), (b'A', vec![0])],
            "fewer than 3",
        ),
    ];
    for (records, reason) in cases {
        let bytes = crafted(&records);
        let at = if records.len() > 1 {
            59 + 3 + records[0].1.len()
        } else {
            59
        };
        match ulog::parse("crafted.ulg", &bytes) {
            Err(e @ OnboardError::Malformed { .. }) => {
                let text = e.to_string();
                assert!(
                    text.starts_with(&format!("crafted.ulg: byte {at}: ")) && text.contains(reason),
                    "{text}"
                );
            }
            other => panic!("{reason}: {other:?}"),
        }
    }
}

#[test]
fn a_long_log_made_from_the_fixture_reads_as_its_flights_one_after_another() {
    let bytes = fixture();
    let long = ulog::synthetic_long(&bytes, 30.0).expect("a long log");
    assert!(long.len() > 6 * bytes.len(), "{} bytes", long.len());
    let one = parse(&bytes).expect("the fixture");
    let log = parse(&long).expect("the long log");
    assert!(log.tear.is_none(), "{:?}", log.tear);
    let span_s = log.stamped.last().map_or(0.0, |s| s.t_s);
    assert!(span_s >= 1800.0, "{span_s} s");
    let copies = batteries(&log) / batteries(&one);
    assert!(copies >= 7, "{copies} copies");
    assert!(log.stamped.windows(2).all(|w| w[0].t_s <= w[1].t_s));
    let rate = log.battery_rate_hz().expect("battery");
    assert!((4.0..5.5).contains(&rate), "{rate} Hz");
}

#[test]
fn formats_nested_as_deep_as_allowed_are_read_in_bounded_time() {
    // 1024 formats, each a field of the next: the deepest nesting the reader lets the crate
    // flatten (a 1025th format is refused).
    let n = 1024;
    let mut records: Vec<RawRecord> = (0..n)
        .map(|i| {
            let ty = if i + 1 == n {
                "uint8_t".to_string()
            } else {
                format!("n{}", i + 1)
            };
            (b'F', format!("n{i}:{ty} x").into_bytes())
        })
        .collect();
    records.push((b'A', b"\x00\x00\x00n0".to_vec()));
    let bytes = crafted(&records);
    assert_located(&ulog::parse("deep.ulg", &bytes), bytes.len());
    records.insert(0, (b'F', b"extra:uint8_t x".to_vec()));
    let bytes = crafted(&records);
    let err = ulog::parse("deep.ulg", &bytes).map(|_| ()).unwrap_err();
    assert!(err.to_string().contains("more than 1024 formats"), "{err}");
}

#[test]
fn the_ulog_measures_every_leg_within_3_percent_of_the_tlog_of_the_same_flight() {
    // The .tlog's report of the same flight, made by `emplan fly` while it flew (its
    // report.json, copied beside the fixture): the ground station's view at 10 Hz battery.
    let text = std::fs::read_to_string(fixture_dir().join("px4-sih-8wp.tlog-report.json"))
        .expect("the .tlog's report");
    let tlog: serde_json::Value = serde_json::from_str(&text).expect("json");
    let log = parse(&fixture()).expect("the fixture parses");
    let plan = FlightPlan::read_json(&fixture_dir().join("px4-sih-8wp.plan.json")).expect("plan");
    let segmenter =
        Segmenter::run(plan, SegmentConfig::default(), &log.stamped).expect("segmented");
    let report = FlightReport::build("px4-sih-8wp", &segmenter);
    let tlog_legs = tlog["legs"].as_array().expect("legs");
    assert_eq!(report.legs.len(), tlog_legs.len());
    for (ulog_leg, tlog_leg) in report.legs.iter().zip(tlog_legs) {
        let u = ulog_leg.measured_j.expect("measured from the ULog");
        let t = tlog_leg["measured_kj"]
            .as_f64()
            .expect("measured from the .tlog")
            * 1e3;
        let error_pct = 100.0 * (u - t) / t;
        assert!(
            error_pct.abs() < 3.0,
            "{} -> {}: ULog {u:.0} J, .tlog {t:.0} J ({error_pct:+.1}%)",
            ulog_leg.from,
            ulog_leg.to
        );
    }
}
