//! Onboard logs that lie, through the binary: a ULog whose formats would flatten to gigabytes is
//! refused naming the format, in bounded memory; ULog errors name the record without debug dumps;
//! a DataFlash record whose time jumps, a battery sample no battery gives and an FMT record
//! redescribing BAT are refused, counted and located, and the flight is measured as without them.
//! The damaged logs are made here from the real fixtures.

use std::path::{Path, PathBuf};

use emplan::flightlog::onboard::dataflash;
use serde_json::Value;

use crate::emplan;

const ULOG: &str = "tests/fixtures/onboard/px4-sih-8wp.ulg";
const DATAFLASH: &str = "tests/fixtures/onboard/arducopter-8wp.bin";
const MISSION: &str = "missions/paper-sample-8wp.toml";

fn read(fixture: &str) -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join(fixture)).expect("the fixture")
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("written");
    path
}

/// `emplan ARGS` with its address space capped at `limit_kib` (`ulimit -v`): an allocation past
/// it fails, and the binary aborts, instead of the test taking the machine's memory.
fn emplan_capped(limit_kib: u64, args: &[&str]) -> (bool, String, String) {
    let script = format!("ulimit -v {limit_kib} && exec \"$0\" \"$@\"");
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_emplan"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("emplan runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn report_json(path: &Path, extra: &[&str]) -> (Value, String) {
    let mut args = vec!["report", path.to_str().expect("UTF-8")];
    args.extend_from_slice(extra);
    args.push("--json");
    let (ok, stdout, stderr) = emplan(&args);
    assert!(ok, "{stderr}");
    let doc = serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("{e}: {stdout}"));
    (doc, stderr)
}

// ULog ----------------------------------------------------------------------------------------

/// A ULog record: payload size, kind, payload.
fn ulog_record(kind: u8, payload: &[u8]) -> Vec<u8> {
    let size = u16::try_from(payload.len()).expect("a record's size");
    let mut out = size.to_le_bytes().to_vec();
    out.push(kind);
    out.extend_from_slice(payload);
    out
}

/// Each record of a ULog: its offset, kind and payload.
fn ulog_records(bytes: &[u8]) -> Vec<(usize, u8, &[u8])> {
    let mut out = Vec::new();
    let mut pos = 16;
    while let Some(head) = bytes.get(pos..pos + 3) {
        let size = usize::from(u16::from_le_bytes([head[0], head[1]]));
        let Some(payload) = bytes.get(pos + 3..pos + 3 + size) else {
            break;
        };
        out.push((pos, head[2], payload));
        pos += 3 + size;
    }
    out
}

/// `bytes` with `extra` inserted at `at`.
fn inserted(bytes: &[u8], at: usize, extra: &[u8]) -> Vec<u8> {
    let mut out = bytes[..at].to_vec();
    out.extend_from_slice(extra);
    out.extend_from_slice(&bytes[at..]);
    out
}

/// The message id the fixture subscribes `topic` as, and the offset of its first subscription.
fn subscription(records: &[(usize, u8, &[u8])], topic: &str) -> (u16, usize) {
    let (offset, _, payload) = records
        .iter()
        .find(|(_, kind, p)| *kind == b'A' && &p[3..] == topic.as_bytes())
        .expect("the topic is subscribed");
    (u16::from_le_bytes([payload[1], payload[2]]), *offset)
}

#[test]
fn a_ulog_whose_formats_would_flatten_to_gigabytes_is_refused_naming_the_format_in_bounded_memory()
{
    let dir = tempfile::tempdir().expect("temp dir");
    let clean = read(ULOG);
    let records = ulog_records(&clean);
    // The formats go after the flag bits, the first record.
    let (_, kind, payload) = records[0];
    assert_eq!(kind, b'B');
    let at = 16 + 3 + payload.len();

    // One format: a 32 000-element array with a 60 000-character name (60 KB; the crate would
    // have flattened it to 32 000 names of 60 000 characters, three times over: 5.8 GB).
    let array = format!("hostile:float[32000] {};", "x".repeat(60_000));
    let one = write(
        dir.path(),
        "array.ulg",
        &inserted(&clean, at, &ulog_record(b'F', array.as_bytes())),
    );
    // 200 formats nested in one another, each field name 30 000 characters (3.1 GB).
    let nested: Vec<u8> = (0..200)
        .flat_map(|k| {
            let ty = if k < 199 {
                format!("n{}", k + 1)
            } else {
                "float".into()
            };
            let name = char::from(b'a' + (k % 26) as u8).to_string().repeat(30_000);
            ulog_record(b'F', format!("n{k}:{ty} {name};").as_bytes())
        })
        .collect();
    let many = write(dir.path(), "nested.ulg", &inserted(&clean, at, &nested));

    for (path, named) in [
        (
            &one,
            format!("byte {at}: a format record: hostile flattens to 32000 fields"),
        ),
        (&many, "a format record: n".to_string()),
    ] {
        let file = path.to_str().expect("UTF-8");
        // Within 1 GiB of address space, the binary's own included.
        let (ok, _, stderr) = emplan_capped(1 << 20, &["report", file, "--mission", MISSION]);
        assert!(!ok, "{stderr}");
        assert!(
            stderr.contains(&format!("{file}: byte ")) && stderr.contains(&named),
            "{stderr}"
        );
        assert!(
            stderr.contains("the formats come to more than the 64 MiB"),
            "{stderr}"
        );
        assert!(!stderr.contains("memory allocation"), "{stderr}");
    }
}

#[test]
fn ulog_errors_name_the_record_and_topic_without_debug_dumps() {
    let dir = tempfile::tempdir().expect("temp dir");
    let clean = read(ULOG);
    let records = ulog_records(&clean);
    let (battery, first_subscription) = subscription(&records, "battery_status");
    let mission = ["--mission", MISSION];

    // A data record of battery_status 5 bytes long, at the end: the log tears there.
    let mut data = battery.to_le_bytes().to_vec();
    data.extend_from_slice(&[1, 2, 3]);
    let mut short = clean.clone();
    short.extend_from_slice(&ulog_record(b'D', &data));
    let path = write(dir.path(), "short.ulg", &short);
    let (report, stderr) = report_json(&path, &mission);
    let tear = &report["source"]["tear"];
    assert_eq!(tear["offset"], clean.len() as u64, "{report}");
    assert_eq!(
        tear["reason"],
        format!(
            "a data record: 5 bytes of topic battery_status (message id {battery}), not the size of its format"
        ),
        "{tear}"
    );
    assert!(!stderr.contains("FlattenedFormat"), "{stderr}");

    // The same message id subscribed again, at the end.
    let mut twice = clean.clone();
    let mut again = vec![0u8];
    again.extend_from_slice(&battery.to_le_bytes());
    again.extend_from_slice(b"vehicle_status");
    twice.extend_from_slice(&ulog_record(b'A', &again));
    let path = write(dir.path(), "twice.ulg", &twice);
    let (report, stderr) = report_json(&path, &mission);
    assert_eq!(
        report["source"]["tear"]["reason"],
        format!(
            "a subscription record: message id {battery} subscribed twice (battery_status, then vehicle_status)"
        ),
        "{report}"
    );
    assert!(!stderr.contains("FlattenedFormat"), "{stderr}");

    // A subscription whose topic name is not text, before the others: the log is refused.
    let not_text = ulog_record(b'A', &[0, 0x60, 0xEA, 241, 179, 40]);
    let path = write(
        dir.path(),
        "name.ulg",
        &inserted(&clean, first_subscription, &not_text),
    );
    let file = path.to_str().expect("UTF-8");
    let (ok, _, stderr) = emplan(&["report", file, "--mission", MISSION]);
    assert!(!ok);
    assert!(
        stderr.contains(&format!(
            "{file}: byte {first_subscription}: a subscription record: the topic name of message id 60000 is not text"
        )),
        "{stderr}"
    );
    assert!(!stderr.contains("[241"), "{stderr}");
}

// DataFlash -----------------------------------------------------------------------------------

/// One DataFlash record: its offset, message name and each field's label, format character and
/// offset within the record.
struct DfRecord {
    offset: usize,
    name: String,
    fields: Vec<(String, u8, usize)>,
}

impl DfRecord {
    fn field(&self, label: &str) -> usize {
        self.fields
            .iter()
            .find(|(l, _, _)| l == label)
            .map(|(_, _, at)| self.offset + at)
            .unwrap_or_else(|| panic!("{} has no {label}", self.name))
    }
}

fn text(raw: &[u8]) -> String {
    let end = raw.iter().position(|&b| b == 0).unwrap_or(raw.len());
    String::from_utf8_lossy(&raw[..end]).into_owned()
}

/// A message as its FMT record describes it: its length, name and fields (see [`DfRecord`]).
type Described = (usize, String, Vec<(String, u8, usize)>);

/// The records of an undamaged DataFlash log, and each message's id by name.
fn df_records(bytes: &[u8]) -> (Vec<DfRecord>, Vec<(String, u8)>) {
    let mut formats: Vec<Option<Described>> = vec![None; 256];
    let mut ids = Vec::new();
    let mut out = Vec::new();
    let mut pos = 0;
    while pos + 3 <= bytes.len() {
        assert_eq!(&bytes[pos..pos + 2], &[0xA3, 0x95], "a record at {pos}");
        let id = bytes[pos + 2];
        if id == 128 {
            let r = &bytes[pos..pos + 89];
            let (name, format, labels) = (text(&r[5..9]), text(&r[9..25]), text(&r[25..89]));
            let mut at = 3;
            let mut fields = Vec::new();
            for (c, label) in format.bytes().zip(labels.split(',')) {
                fields.push((label.to_string(), c, at));
                at += dataflash::field_size(c).expect("a format character");
            }
            ids.push((name.clone(), r[3]));
            formats[usize::from(r[3])] = Some((usize::from(r[4]), name, fields));
            pos += 89;
            continue;
        }
        let (len, name, fields) = formats[usize::from(id)].clone().expect("described");
        out.push(DfRecord {
            offset: pos,
            name,
            fields,
        });
        pos += len;
    }
    (out, ids)
}

/// The `n`th record named `name`.
fn nth<'a>(records: &'a [DfRecord], name: &str, n: usize) -> &'a DfRecord {
    records
        .iter()
        .filter(|r| r.name == name)
        .nth(n)
        .unwrap_or_else(|| panic!("no {name} {n}"))
}

fn measured(part: &Value) -> f64 {
    part["measured_kj"]
        .as_f64()
        .unwrap_or_else(|| panic!("{part}"))
}

/// Every leg, take-off, landing and the total of `report` measured as `clean`'s, within
/// `tolerance` (a fraction), none unmeasurable; the total the sum of its parts.
fn measured_as(report: &Value, clean: &Value, tolerance: f64) {
    let legs = report["legs"].as_array().expect("legs");
    let clean_legs = clean["legs"].as_array().expect("legs");
    assert_eq!(legs.len(), clean_legs.len(), "{report}");
    let mut parts = vec![(&report["takeoff"], &clean["takeoff"])];
    parts.extend(legs.iter().zip(clean_legs));
    parts.push((&report["landing"], &clean["landing"]));
    parts.push((&report["total"], &clean["total"]));
    for (part, clean_part) in parts {
        let (e, c) = (measured(part), measured(clean_part));
        assert!(
            (e - c).abs() <= tolerance * c,
            "{part} against {clean_part}"
        );
        let flags = part["flags"].as_array().map_or(&[][..], |f| f.as_slice());
        assert!(!flags.iter().any(|f| f == "unmeasurable"), "{part}");
    }
    let at_points = report["at_points"].as_array().expect("at_points");
    let sum: f64 = [&report["takeoff"], &report["landing"]]
        .into_iter()
        .chain(legs)
        .chain(at_points)
        .map(measured)
        .sum();
    let total = measured(&report["total"]);
    assert!((total - sum).abs() <= 1e-6 * total, "{total} against {sum}");
}

/// The report's refused records, checked against what was damaged: `count` of them, the first
/// a `record` at `offset` whose reason contains `why`, said on stderr, each a log gap.
fn refused(report: &Value, stderr: &str, count: usize, offset: usize, record: &str, why: &str) {
    let skipped = &report["source"]["skipped"];
    assert_eq!(skipped["count"], count, "{report}");
    assert_eq!(skipped["offset"], offset, "{skipped}");
    assert_eq!(skipped["record"], record, "{skipped}");
    let reason = skipped["reason"].as_str().expect("a reason");
    assert!(reason.contains(why), "{reason}");
    let gaps = report["log_gaps"].as_array().expect("log_gaps");
    assert_eq!(gaps.len(), count, "{gaps:?}");
    assert_eq!(gaps[0]["offset"], offset, "{gaps:?}");
    assert!(
        stderr.contains(&format!(
            "{count} record{} refused as corrupt, the first at byte {offset} ({record}: {reason})",
            if count == 1 { "" } else { "s" }
        )),
        "{stderr}"
    );
}

#[test]
fn a_dataflash_record_whose_time_jumps_is_skipped_counted_located_and_the_flight_measured_without_it(
) {
    let dir = tempfile::tempdir().expect("temp dir");
    let bytes = read(DATAFLASH);
    let (records, _) = df_records(&bytes);
    let (clean, _) = report_json(Path::new(DATAFLASH), &[]);
    // A PARM written before take-off, and a BAT, a POS and an XKF1 mid-flight: bit 42 of their
    // TimeUS flipped (51 days later).
    let parms = records.iter().filter(|r| r.name == "PARM").count();
    let damaged = [
        nth(&records, "PARM", parms / 2),
        nth(&records, "BAT", 1100),
        nth(&records, "POS", 1100),
        nth(&records, "XKF1", 2200),
    ];
    for record in damaged {
        let mut flipped = bytes.clone();
        flipped[record.field("TimeUS") + 5] ^= 0x04;
        let path = write(dir.path(), &format!("{}.bin", record.name), &flipped);
        let (report, stderr) = report_json(&path, &[]);
        refused(
            &report,
            &stderr,
            1,
            record.offset,
            &record.name,
            "its TimeUS jumps +4.4e6 s from the records around it",
        );
        measured_as(&report, &clean, 0.002);
        assert_eq!(report["complete"], clean["complete"], "{report}");
    }
}

#[test]
fn a_battery_sample_no_battery_gives_is_refused_located_and_left_out_of_the_total() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut bytes = read(DATAFLASH);
    let (records, _) = df_records(&bytes);
    let (clean, _) = report_json(Path::new(DATAFLASH), &[]);
    let amps = nth(&records, "BAT", 1000);
    let volts = nth(&records, "BAT", 1500);
    bytes[amps.field("Curr")..amps.field("Curr") + 4].copy_from_slice(&1e9f32.to_le_bytes());
    bytes[volts.field("Volt")..volts.field("Volt") + 4].copy_from_slice(&(-24f32).to_le_bytes());
    let path = write(dir.path(), "amps.bin", &bytes);
    let (report, stderr) = report_json(&path, &[]);
    refused(
        &report,
        &stderr,
        2,
        amps.offset,
        "BAT",
        "its Curr 1.0e9 A is not physical (outside -1000 to 1000 A)",
    );
    measured_as(&report, &clean, 0.002);
    // The log's own energy counter agrees with the parts measured, as it does with the clean log.
    let mismatched = |doc: &Value| {
        let parts = [&doc["takeoff"], &doc["landing"]]
            .into_iter()
            .chain(doc["legs"].as_array().expect("legs"))
            .chain(doc["at_points"].as_array().expect("at_points"));
        (parts.chain([doc]))
            .filter(|p| {
                p["flags"]
                    .as_array()
                    .is_some_and(|f| f.iter().any(|f| f == "consumed_mismatch"))
            })
            .count()
    };
    assert_eq!(mismatched(&report), mismatched(&clean), "{report}");
}

#[test]
fn an_fmt_record_redescribing_bat_is_refused_located_and_bat_read_as_first_described() {
    let dir = tempfile::tempdir().expect("temp dir");
    let bytes = read(DATAFLASH);
    let (records, ids) = df_records(&bytes);
    let (clean, _) = report_json(Path::new(DATAFLASH), &[]);
    let bat = ids
        .iter()
        .find(|(n, _)| n == "BAT")
        .expect("BAT described")
        .1;
    // BAT described again before the first BAT record: 16 bytes of time, voltage and instance
    // (read so, no BAT record would hold a current).
    let mut fmt = vec![0xA3, 0x95, 128, bat, 16];
    for (text, n) in [("BAT", 4), ("QfB", 16), ("TimeUS,Volt,Inst", 64)] {
        let mut field = text.as_bytes().to_vec();
        field.resize(n, 0);
        fmt.extend_from_slice(&field);
    }
    let at = nth(&records, "BAT", 0).offset;
    let path = write(dir.path(), "fmt.bin", &inserted(&bytes, at, &fmt));
    let (report, stderr) = report_json(&path, &[]);
    refused(
        &report,
        &stderr,
        1,
        at,
        "FMT",
        &format!("it describes message id {bat} (BAT) again, as BAT of 16 bytes (QfB)"),
    );
    measured_as(&report, &clean, 0.002);
}
