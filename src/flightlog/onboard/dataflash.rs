//! ArduPilot DataFlash (`.bin`): its self-describing FMT records, and the messages that measure a
//! flight (BAT, POS, XKF1, ORGN, CMD, MODE, ARM, EV, MSG) as stamped readings meaning what
//! `link::telemetry::decode` makes of the same ArduCopter's MAVLink.
//!
//! The format (ArduPilot `AP_Logger/LogStructure.h`): every record is `0xA3 0x95 id` and a body
//! laid out by the FMT record (id 128) that described `id` earlier in the file: its length
//! (header included), name, format characters and comma-separated labels. Format characters:
//! `b B h H i I q Q` integers (8 to 64 bits, lower case signed), `f` f32, `d` f64, `g` IEEE 754
//! binary16, `n N Z` text of 4, 16, 64 bytes (NUL padded), `c C e E` int16, uint16, int32,
//! uint32 holding the value times 100, `L` int32 degrees times 1e7, `M` uint8 flight mode, `a`
//! int16\[32\]. All little endian. FMTU, UNIT and MULT (units) are ordinary records, unused here.
//!
//! Damage: bytes that are not a record (no header, an id no FMT described) are skipped up to the
//! next header and counted; a record after skipped bytes counts only if a header or the file's
//! end follows it. A last record cut short, or bytes after the last record that never become one,
//! are the tear: everything before it is kept and the tear says where it is. A record that lies
//! is refused, located ([`OnboardLog::skipped`]) and read as if it were not there: a `TimeUS`
//! that jumps (see [`MAX_TIME_STEP_US`]), a BAT sample no battery gives, an FMT record describing
//! again, otherwise, an id already described.
//!
//! Readings (times: `TimeUS`, the autopilot's microseconds since boot):
//! - BAT (`Volt`, `Curr`, `CurrTot` mAh, `EnrgTot` Wh, `RemPct`; NaN is unknown) -> Battery of
//!   one instance: the lowest that logs a current, else the lowest (`EnrgTot` in J).
//! - POS (`Lat`, `Lng`, `Alt` above mean sea level, `RelHomeAlt`) with the latest XKF1 of EKF core
//!   0 (`VN`, `VE`, `VD`) -> Position, as GLOBAL_POSITION_INT gives the same AHRS position and
//!   velocity (zero velocity before the first XKF1).
//! - ORGN of type 1 (the AHRS home; type 0 is the EKF origin) -> Home, set at its `TimeUS`.
//! - CMD: the whole mission is written as items 0 (home) to `CTot` - 1 in order when the log
//!   starts (and again when a mission is uploaded): that is [`OnboardLog::mission`]. Any other CMD
//!   is a command starting (`AP_Mission::start_command` logs it when `LOG_BITMASK` asks; the
//!   SITL's default does not).
//! - Mission progress: ArduPilot says it in MSG, the text it also sends as STATUSTEXT:
//!   `Mission: N <type>` as command N starts (`AP_Mission::start_command`), `Reached command #N`
//!   as waypoint N completes (ArduCopter `ModeAuto::verify_nav_wp`). A navigation command
//!   starting (by MSG or CMD) is what MISSION_CURRENT says: MissionCurrent. ArduCopter sends
//!   MISSION_ITEM_REACHED (`ModeAuto::verify_command`) for every command that completes, in the
//!   same update in which the next one starts, but writes `Reached command` only for waypoints:
//!   so "reached" is the text where there is one, and otherwise the previous navigation command
//!   is reached when a later one starts (a jump back, or the mission reset to 1 after landing,
//!   reaches nothing). DataFlash has no record of its own for an item reached.
//! - MODE (`Mode`, ArduCopter's numbering) and ARM (`ArmState`; EV 10/11 too) ->
//!   Heartbeat{armed, mode} on every change and once a second of log time after it, as the
//!   autopilot's HEARTBEAT streams. A log that opened as the vehicle armed (`LOG_DISARMED` 0 in
//!   its PARM records: ArduPilot opens the log at arming, and the arming's own ARM record does
//!   not make it into the file) is armed from its first record, disarmed just before it; a log
//!   whose first word on arming is an arming was disarmed before that. Without either, what came
//!   before the first arming record is left unknown (no heartbeat).
//! - EV 18 (land complete) -> Landed(OnGround), EV 28 (not landed) -> Landed(InAir).
//! - MSG -> StatusText of severity 6 (info: DataFlash keeps no severity).

use super::{Format, MissionCommand, OnboardError, OnboardLog, Skipped, Tear};
use crate::flightlog::csv::{MAX_CURRENT_A, MAX_VOLTAGE_V};
use crate::flightlog::telemetry::{
    Battery, BatterySource, FlightMode, LandedState, MissionState, Position, Reading, Stamped,
};

/// A DataFlash file's first bytes: a record's two header bytes and FMT's id (128).
pub const MAGIC: &[u8] = &[0xA3, 0x95, 0x80];

/// Every record's first two bytes.
const HEAD: [u8; 2] = [0xA3, 0x95];

/// FMT's id and its record length (header, type, length, name\[4\], format\[16\], labels\[64\]).
const FMT_ID: u8 = 128;
const FMT_LEN: usize = 89;

/// ArduPilot's component id for the autopilot: the battery readings' `component`.
const AUTOPILOT_COMPONENT: u8 = 1;

/// Heartbeats are repeated at this interval of log time (ArduPilot streams HEARTBEAT at 1 Hz).
const HEARTBEAT_INTERVAL_US: u64 = 1_000_000;

/// MAV_SEVERITY_INFO, for MSG records (which carry no severity).
const MSG_SEVERITY: u8 = 6;

/// How far a record's `TimeUS` may be from the records either side of it. ArduPilot stamps each
/// record as it puts it in the one buffer the log is written from, so records follow one another
/// by milliseconds (the fixture `arducopter-8wp.bin`: never backwards, at most 0.1 s forward). A
/// record further than this from both sides is corrupt (a bit flipped at or above bit 20 of its
/// `TimeUS`); a pause in logging moves the records after it as well, and is kept.
const MAX_TIME_STEP_US: u64 = 1_000_000;

/// One field's value, in the units its format character means (see the module doc): `c C e E`
/// divided by 100, `L` in degrees.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Int(i64),
    UInt(u64),
    Float(f64),
    Text(String),
    Array(Vec<i16>),
}

impl Value {
    /// The value as a number (None for text and arrays).
    pub fn as_f64(&self) -> Option<f64> {
        match *self {
            Value::Int(v) => Some(v as f64),
            Value::UInt(v) => Some(v as f64),
            Value::Float(v) => Some(v),
            Value::Text(_) | Value::Array(_) => None,
        }
    }

    /// The value as an integer, when it is one.
    pub fn as_i64(&self) -> Option<i64> {
        match *self {
            Value::Int(v) => Some(v),
            Value::UInt(v) => i64::try_from(v).ok(),
            _ => None,
        }
    }
}

/// Bytes a format character takes; None for a character ArduPilot does not define.
pub fn field_size(c: u8) -> Option<usize> {
    Some(match c {
        b'b' | b'B' | b'M' => 1,
        b'h' | b'H' | b'c' | b'C' | b'g' => 2,
        b'i' | b'I' | b'f' | b'e' | b'E' | b'L' | b'n' => 4,
        b'd' | b'q' | b'Q' => 8,
        b'N' => 16,
        b'Z' | b'a' => 64,
        _ => return None,
    })
}

/// IEEE 754 binary16 (ArduPilot's `g`, `Float16_t`) to f64.
pub fn half_to_f64(bits: u16) -> f64 {
    let sign = if bits & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exponent = i32::from((bits >> 10) & 0x1F);
    let fraction = f64::from(bits & 0x3FF);
    match exponent {
        0 => sign * fraction * 2f64.powi(-24),
        31 if fraction == 0.0 => sign * f64::INFINITY,
        31 => f64::NAN,
        e => sign * (1.0 + fraction / 1024.0) * 2f64.powi(e - 15),
    }
}

fn array<const N: usize>(raw: &[u8]) -> Option<[u8; N]> {
    raw.get(..N)?.try_into().ok()
}

fn text(raw: &[u8]) -> String {
    let end = raw.iter().position(|&b| b == 0).unwrap_or(raw.len());
    String::from_utf8_lossy(raw.get(..end).unwrap_or_default()).into_owned()
}

/// Decodes one field of format character `c` from the start of `raw`; None when `c` is not a
/// format character or `raw` is too short.
pub fn decode_field(c: u8, raw: &[u8]) -> Option<Value> {
    let v = match c {
        b'b' => Value::Int(i64::from(i8::from_le_bytes(array(raw)?))),
        b'B' | b'M' => Value::UInt(u64::from(*raw.first()?)),
        b'h' => Value::Int(i64::from(i16::from_le_bytes(array(raw)?))),
        b'H' => Value::UInt(u64::from(u16::from_le_bytes(array(raw)?))),
        b'i' => Value::Int(i64::from(i32::from_le_bytes(array(raw)?))),
        b'I' => Value::UInt(u64::from(u32::from_le_bytes(array(raw)?))),
        b'q' => Value::Int(i64::from_le_bytes(array(raw)?)),
        b'Q' => Value::UInt(u64::from_le_bytes(array(raw)?)),
        b'f' => Value::Float(f64::from(f32::from_le_bytes(array(raw)?))),
        b'd' => Value::Float(f64::from_le_bytes(array(raw)?)),
        b'g' => Value::Float(half_to_f64(u16::from_le_bytes(array(raw)?))),
        b'c' => Value::Float(f64::from(i16::from_le_bytes(array(raw)?)) * 0.01),
        b'C' => Value::Float(f64::from(u16::from_le_bytes(array(raw)?)) * 0.01),
        b'e' => Value::Float(f64::from(i32::from_le_bytes(array(raw)?)) * 0.01),
        b'E' => Value::Float(f64::from(u32::from_le_bytes(array(raw)?)) * 0.01),
        b'L' => Value::Float(f64::from(i32::from_le_bytes(array(raw)?)) * 1e-7),
        b'n' | b'N' | b'Z' => Value::Text(text(raw.get(..field_size(c)?)?)),
        b'a' => Value::Array(
            raw.get(..64)?
                .chunks_exact(2)
                .map(|p| i16::from_le_bytes([p[0], p[1]]))
                .collect(),
        ),
        _ => return None,
    };
    Some(v)
}

/// The messages read into readings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Bat,
    Pos,
    Xkf1,
    Orgn,
    Cmd,
    Mode,
    Arm,
    Ev,
    Msg,
    Parm,
    Other,
}

impl Kind {
    fn of(name: &str) -> Kind {
        match name {
            "BAT" => Kind::Bat,
            "POS" => Kind::Pos,
            "XKF1" => Kind::Xkf1,
            "ORGN" => Kind::Orgn,
            "CMD" => Kind::Cmd,
            "MODE" => Kind::Mode,
            "ARM" => Kind::Arm,
            "EV" => Kind::Ev,
            "MSG" => Kind::Msg,
            "PARM" => Kind::Parm,
            _ => Kind::Other,
        }
    }
}

/// One field of a message: its label, format character and offset in the record (header
/// included).
#[derive(Debug, Clone)]
struct Field {
    label: String,
    format: u8,
    offset: usize,
}

/// A message as its FMT record describes it.
#[derive(Debug, Clone)]
struct Message {
    name: String,
    /// The whole record's length, header included.
    len: usize,
    /// Empty when the format does not add up to the length (the records are stepped over).
    fields: Vec<Field>,
    kind: Kind,
    /// The offset of a `TimeUS` field of type `Q`.
    time_offset: Option<usize>,
    /// The FMT record's bytes after its own header (what a redescription is compared with).
    definition: Vec<u8>,
}

impl Message {
    /// The FMT record's own description (ArduPilot writes it first, describing itself).
    fn fmt() -> Message {
        Message::new("FMT", FMT_LEN, b"BBnNZ", "Type,Length,Name,Format,Columns")
    }

    fn new(name: &str, len: usize, format: &[u8], labels: &str) -> Message {
        let labels: Vec<&str> = labels.split(',').collect();
        let mut fields = Vec::with_capacity(format.len());
        let mut offset = HEAD.len() + 1;
        for (&c, label) in format.iter().zip(&labels) {
            let Some(size) = field_size(c) else {
                fields.clear();
                break;
            };
            fields.push(Field {
                label: (*label).to_string(),
                format: c,
                offset,
            });
            offset += size;
        }
        if offset != len || labels.len() != format.len() {
            fields.clear();
        }
        let time_offset = fields
            .iter()
            .find(|f| f.label == "TimeUS" && f.format == b'Q')
            .map(|f| f.offset);
        Message {
            name: name.to_string(),
            len,
            kind: if fields.is_empty() {
                Kind::Other
            } else {
                Kind::of(name)
            },
            fields,
            time_offset,
            definition: Vec::new(),
        }
    }

    fn get(&self, record: &[u8], label: &str) -> Option<Value> {
        let field = self.fields.iter().find(|f| f.label == label)?;
        decode_field(field.format, record.get(field.offset..)?)
    }

    fn number(&self, record: &[u8], label: &str) -> Option<f64> {
        self.get(record, label)?.as_f64()
    }

    /// A number that NaN (ArduPilot's "unknown") makes None.
    fn known(&self, record: &[u8], label: &str) -> Option<f64> {
        self.number(record, label).filter(|v| v.is_finite())
    }

    fn time_us(&self, record: &[u8]) -> Option<u64> {
        let at = self.time_offset?;
        Some(u64::from_le_bytes(array(record.get(at..)?)?))
    }
}

/// What a walk through the file found besides its records.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scan {
    /// Records read (FMT included).
    pub records: u64,
    /// Bytes skipped because they were not a record (resynchronised on the next header).
    pub skipped_bytes: u64,
    /// Where the file tore: its offset and why.
    pub tear: Option<(u64, String)>,
}

/// The offset of the next record header at or after `from`.
fn next_head(bytes: &[u8], from: usize) -> Option<usize> {
    let rest = bytes.get(from..)?;
    rest.windows(2).position(|w| w == HEAD).map(|i| from + i)
}

/// Walks the records of a DataFlash file, FMT records defining the rest, calling `on_record`
/// with each non-FMT record's message and bytes (header included), and `on_refused` with the
/// offset, length and reason of each FMT record refused: one that describes an id already
/// described otherwise (ArduPilot describes each id once in a log: the records of that id go on
/// being read as first described).
fn walk(
    bytes: &[u8],
    mut on_record: impl FnMut(&Message, &[u8]),
    mut on_refused: impl FnMut(usize, usize, String),
) -> Scan {
    let mut table: Vec<Option<Message>> = vec![None; 256];
    table[usize::from(FMT_ID)] = Some(Message::fmt());
    let mut scan = Scan::default();
    let mut pos = 0usize;
    // The first unreadable spot since the last good record: the tear if nothing good follows.
    let mut bad: Option<(usize, String)> = None;
    while let Some(rest) = bytes.get(pos..).filter(|r| !r.is_empty()) {
        if rest.len() < 3 && HEAD.starts_with(rest) {
            scan.tear = Some((pos as u64, "a record header cut short".into()));
            bad = None;
            break;
        }
        let mut definition = None;
        let unreadable = if !rest.starts_with(&HEAD) {
            Some("bytes that are not a record".to_string())
        } else {
            let id = rest.get(2).copied().unwrap_or_default();
            match table.get(usize::from(id)).and_then(Option::as_ref) {
                None => Some(format!("an unknown message id {id}")),
                Some(message) => match rest.get(..message.len) {
                    None => {
                        scan.tear = Some((
                            pos as u64,
                            format!(
                                "a {} record cut short ({} of its {} bytes)",
                                message.name,
                                rest.len(),
                                message.len
                            ),
                        ));
                        bad = None;
                        break;
                    }
                    // After skipped bytes a header may be a chance pair inside other data:
                    // it counts only when a record or the end follows.
                    Some(_)
                        if bad.is_some()
                            && rest.get(message.len..).is_some_and(|after| {
                                !after.is_empty() && !after.starts_with(&HEAD[..after.len().min(2)])
                            }) =>
                    {
                        Some(format!("a {} record not followed by another", message.name))
                    }
                    Some(record) => {
                        scan.records += 1;
                        if id == FMT_ID {
                            definition = Some(record);
                        } else {
                            on_record(message, record);
                        }
                        bad = None;
                        pos += message.len;
                        None
                    }
                },
            }
        };
        if let Some(record) = definition {
            if let Err(reason) = define(&mut table, record) {
                on_refused(pos - record.len(), record.len(), reason.to_string());
            }
        }
        if let Some(reason) = unreadable {
            bad.get_or_insert((pos, reason));
            let next = next_head(bytes, pos + 1).unwrap_or(bytes.len());
            scan.skipped_bytes += (next - pos) as u64;
            pos = next;
        }
    }
    if scan.tear.is_none() {
        scan.tear = bad.map(|(at, reason)| (at as u64, reason));
    }
    scan
}

/// An FMT record that describes an already described message otherwise.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("it describes message id {id} ({first}) again, as {name} of {len} bytes ({format}): read as first described")]
struct Redefined {
    id: u8,
    first: String,
    name: String,
    len: usize,
    format: String,
}

/// Takes in an FMT record: the message it describes, unless its id is described already
/// otherwise (refused, saying how; the same description again changes nothing). FMT's own
/// description is fixed.
fn define(table: &mut [Option<Message>], record: &[u8]) -> Result<(), Redefined> {
    let (Some(&id), Some(&len)) = (record.get(3), record.get(4)) else {
        return Ok(());
    };
    let len = usize::from(len);
    if id == FMT_ID || len < HEAD.len() + 1 {
        return Ok(());
    }
    let definition = record.get(3..).unwrap_or_default();
    let name = text(record.get(5..9).unwrap_or_default());
    let format = text(record.get(9..25).unwrap_or_default());
    let labels = text(record.get(25..FMT_LEN).unwrap_or_default());
    let Some(slot) = table.get_mut(usize::from(id)) else {
        return Ok(());
    };
    match slot {
        Some(first) if first.definition != definition => Err(Redefined {
            id,
            first: first.name.clone(),
            name: if name.is_empty() {
                "nameless".to_string()
            } else {
                name
            },
            len,
            format: if format.is_empty() {
                "no fields".to_string()
            } else {
                format
            },
        }),
        Some(_) => Ok(()),
        None => {
            let mut message = Message::new(&name, len, format.as_bytes(), &labels);
            message.definition = definition.to_vec();
            *slot = Some(message);
            Ok(())
        }
    }
}

/// One record decoded whole (for inspection and tests).
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    pub name: String,
    /// Every field, labelled, in order.
    pub fields: Vec<(String, Value)>,
}

impl Record {
    pub fn get(&self, label: &str) -> Option<&Value> {
        self.fields.iter().find(|(l, _)| l == label).map(|(_, v)| v)
    }
}

/// Every record of a DataFlash file decoded whole (FMT records excepted), and the scan; records
/// whose format does not add up to their length come with no fields.
pub fn records(bytes: &[u8]) -> (Vec<Record>, Scan) {
    let mut out = Vec::new();
    let scan = walk(
        bytes,
        |message, record| {
            out.push(Record {
                name: message.name.clone(),
                fields: message
                    .fields
                    .iter()
                    .filter_map(|f| {
                        let value = decode_field(f.format, record.get(f.offset..)?)?;
                        Some((f.label.clone(), value))
                    })
                    .collect(),
            });
        },
        |_, _, _| {},
    );
    (out, scan)
}

/// Whether a MAV_CMD is a navigation command (ArduPilot `AP_Mission::is_nav_cmd`: up to
/// MAV_CMD_NAV_LAST, and NAV_SET_YAW_SPEED, NAV_SCRIPT_TIME, NAV_ATTITUDE_TIME).
fn is_nav_command(id: u16) -> bool {
    id <= 95 || matches!(id, 213 | 42702 | 42703)
}

/// A reading and its raw time; battery readings keep their instance for the choice of one,
/// heartbeats their mode's number (named once the vehicle is known) and whether anything had
/// said yet if the vehicle was armed.
struct Event {
    time_us: u64,
    battery_instance: Option<u64>,
    armed_unknown: bool,
    mode_number: Option<u64>,
    reading: Reading,
}

/// Turns records into readings (see the module doc).
#[derive(Default)]
struct Builder {
    first_us: Option<u64>,
    now_us: u64,
    events: Vec<Event>,
    /// Armed, once an arming record said so.
    armed: Option<bool>,
    /// The first arming record's word.
    first_armed: Option<bool>,
    /// The flight mode's number (MODE's `Mode`).
    mode: Option<u64>,
    last_heartbeat_us: Option<u64>,
    /// The `LOG_DISARMED` parameter, when logged.
    log_disarmed: Option<f64>,
    /// A MSG named a vehicle other than ArduCopter (anywhere in the log: the first MODE comes
    /// before the version's MSG): its mode numbers are not ArduCopter's.
    other_vehicle: bool,
    /// EKF core 0's latest velocity: north, east, down.
    velocity: Option<[f64; 3]>,
    /// The mission being written whole (items 0.. in order) and its `CTot`.
    dump: Vec<MissionCommand>,
    dump_total: u16,
    mission: Option<Vec<MissionCommand>>,
    /// The navigation command flying, and whether it was reported reached.
    current_nav: Option<(u16, bool)>,
    /// The records refused, with the raw times of the records read either side of them.
    skipped: Vec<SkippedAt>,
    /// The first of `skipped` whose time after is not known yet.
    open_skips: usize,
}

/// A record refused, located in the raw times of the records either side of it.
struct SkippedAt {
    offset: usize,
    bytes: usize,
    record: String,
    reason: String,
    before_us: Option<u64>,
    after_us: Option<u64>,
}

/// A number from the file as a message shows it: huge ones in scientific notation.
fn shown(v: f64) -> String {
    if v.abs() >= 1e6 {
        format!("{v:.1e}")
    } else {
        format!("{}", (v * 1000.0).round() / 1000.0)
    }
}

/// Why a BAT record is not a battery's: a voltage or current that is infinite or out of the
/// range any sample can hold (the bounds samples.csv's reader holds a .tlog's samples to); NaN
/// is ArduPilot's "unknown" and is not refused.
fn unphysical_battery(m: &Message, r: &[u8]) -> Option<String> {
    let bounds = [
        ("Volt", "V", 0.0, MAX_VOLTAGE_V),
        ("Curr", "A", -MAX_CURRENT_A, MAX_CURRENT_A),
    ];
    bounds.into_iter().find_map(|(label, unit, low, high)| {
        let v = m.number(r, label).filter(|v| !v.is_nan())?;
        (!(low..=high).contains(&v)).then(|| {
            format!(
                "its {label} {} {unit} is not physical (outside {low} to {high} {unit})",
                shown(v)
            )
        })
    })
}

/// The offsets of the records whose `TimeUS` jumps (see [`MAX_TIME_STEP_US`]), each with why,
/// from every timed record's offset and time in file order: a record further than the step
/// from the last record kept and from the next one is refused (the first record of the log, from
/// the next one when the one after that agrees with it; the last, from the last kept).
fn time_jumps(times: &[(usize, u64)]) -> Vec<(usize, String)> {
    let far = |a: u64, b: u64| a.abs_diff(b) > MAX_TIME_STEP_US;
    let mut kept: Option<u64> = None;
    let mut jumps = Vec::new();
    for (k, &(offset, t)) in times.iter().enumerate() {
        let next = times.get(k + 1).map(|&(_, t)| t);
        let jumped = match (kept, next) {
            (Some(before), Some(next)) => far(t, before) && far(t, next),
            (Some(before), None) => far(t, before),
            (None, Some(next)) => {
                far(t, next)
                    && times
                        .get(k + 2)
                        .is_some_and(|&(_, after)| !far(next, after))
            }
            (None, None) => false,
        };
        if jumped {
            let from = kept.or(next).unwrap_or(t);
            let step_s = (t as f64 - from as f64) * 1e-6;
            jumps.push((
                offset,
                format!(
                    "its TimeUS jumps {}{} s from the records around it",
                    if step_s > 0.0 { "+" } else { "" },
                    shown(step_s)
                ),
            ));
        } else {
            kept = Some(t);
        }
    }
    jumps
}

/// The number a text starts with after `prefix`.
fn number_after(text: &str, prefix: &str) -> Option<u16> {
    let rest = text.strip_prefix(prefix)?;
    let end = rest
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(rest.len());
    rest.get(..end)?.parse().ok()
}

impl Builder {
    fn push(&mut self, reading: Reading) {
        self.events.push(Event {
            time_us: self.now_us,
            battery_instance: None,
            armed_unknown: false,
            mode_number: None,
            reading,
        });
    }

    fn heartbeat(&mut self) {
        self.events.push(Event {
            time_us: self.now_us,
            battery_instance: None,
            armed_unknown: self.armed.is_none(),
            mode_number: self.mode,
            reading: Reading::Heartbeat {
                armed: self.armed.unwrap_or(false),
                mode: FlightMode::Other("unknown".into()),
            },
        });
        self.last_heartbeat_us = Some(self.now_us);
    }

    fn set_armed(&mut self, armed: bool) {
        self.first_armed.get_or_insert(armed);
        if self.armed != Some(armed) {
            self.armed = Some(armed);
            self.heartbeat();
        }
    }

    fn set_mode(&mut self, mode: u64) {
        if self.mode != Some(mode) {
            self.mode = Some(mode);
            self.heartbeat();
        }
    }

    /// Refuses the record at `offset` (its message `m`, `bytes` long) for `reason`.
    fn skip(&mut self, offset: usize, bytes: usize, record: &str, reason: String) {
        self.skipped.push(SkippedAt {
            offset,
            bytes,
            record: record.to_string(),
            reason,
            before_us: self.first_us.map(|_| self.now_us),
            after_us: None,
        });
    }

    /// Log time moved on to `time_us`: the heartbeat repeats once a second.
    fn tick(&mut self, time_us: u64) {
        self.first_us.get_or_insert(time_us);
        self.now_us = time_us;
        for skip in &mut self.skipped[self.open_skips..] {
            skip.after_us = Some(time_us);
        }
        self.open_skips = self.skipped.len();
        if let Some(last) = self.last_heartbeat_us {
            if time_us >= last.saturating_add(HEARTBEAT_INTERVAL_US) {
                self.heartbeat();
            }
        }
    }

    fn record(&mut self, m: &Message, r: &[u8], offset: usize) {
        if let Some(t) = m.time_us(r) {
            self.tick(t);
        }
        if m.kind == Kind::Bat {
            if let Some(reason) = unphysical_battery(m, r) {
                self.skip(offset, r.len(), &m.name, reason);
                return;
            }
        }
        match m.kind {
            Kind::Bat => self.battery(m, r),
            Kind::Pos => self.position(m, r),
            Kind::Xkf1 => {
                if m.number(r, "C").unwrap_or(0.0) == 0.0 {
                    if let (Some(n), Some(e), Some(d)) =
                        (m.known(r, "VN"), m.known(r, "VE"), m.known(r, "VD"))
                    {
                        self.velocity = Some([n, e, d]);
                    }
                }
            }
            Kind::Orgn => {
                if m.number(r, "Type") == Some(1.0) {
                    if let (Some(lat), Some(lon), Some(alt)) =
                        (m.known(r, "Lat"), m.known(r, "Lng"), m.known(r, "Alt"))
                    {
                        let set_boot_s = m.time_us(r).map(|t| t as f64 * 1e-6);
                        self.push(Reading::Home {
                            lat_deg: lat,
                            lon_deg: lon,
                            alt_amsl_m: alt,
                            set_boot_s,
                        });
                    }
                }
            }
            Kind::Cmd => self.command(m, r),
            Kind::Mode => {
                if let Some(n) = m.get(r, "Mode").and_then(|v| v.as_i64()) {
                    self.set_mode(n.unsigned_abs());
                }
            }
            Kind::Arm => {
                if let Some(state) = m.number(r, "ArmState") {
                    self.set_armed(state != 0.0);
                }
            }
            Kind::Ev => match m.get(r, "Id").and_then(|v| v.as_i64()) {
                Some(10) => self.set_armed(true),
                Some(11) => self.set_armed(false),
                Some(18) => self.push(Reading::Landed(LandedState::OnGround)),
                Some(28) => self.push(Reading::Landed(LandedState::InAir)),
                _ => {}
            },
            Kind::Msg => {
                if let Some(Value::Text(text)) = m.get(r, "Message") {
                    self.message(text);
                }
            }
            Kind::Parm => {
                if m.get(r, "Name") == Some(Value::Text("LOG_DISARMED".into())) {
                    self.log_disarmed = m.known(r, "Value");
                }
            }
            Kind::Other => {}
        }
    }

    fn message(&mut self, text: String) {
        let vehicles = [
            "ArduPlane",
            "ArduRover",
            "ArduSub",
            "Blimp",
            "AntennaTracker",
        ];
        if vehicles.iter().any(|v| text.starts_with(v)) {
            self.other_vehicle = true;
        }
        if let Some(seq) = number_after(&text, "Mission: ") {
            let command = self
                .mission
                .as_ref()
                .and_then(|m| m.iter().find(|c| c.seq == seq))
                .map(|c| c.command);
            // Without the mission, a command named in the text is taken for a navigation one.
            if command.is_none_or(is_nav_command) {
                self.nav_started(seq);
            }
        } else if let Some(seq) = number_after(&text, "Reached command #") {
            self.reached(seq);
        }
        self.push(Reading::StatusText {
            severity: MSG_SEVERITY,
            text,
        });
    }

    fn reached(&mut self, seq: u16) {
        if let Some((current, reached)) = self.current_nav.as_mut() {
            if *current == seq {
                if *reached {
                    return;
                }
                *reached = true;
            }
        }
        self.push(Reading::ItemReached { seq });
    }

    /// Navigation command `seq` started (see the module doc for what MAVLink says then).
    fn nav_started(&mut self, seq: u16) {
        if let Some((previous, reached)) = self.current_nav {
            if previous == seq {
                return;
            }
            if seq > previous && !reached {
                self.reached(previous);
            }
        }
        self.current_nav = Some((seq, false));
        let total = self
            .mission
            .as_ref()
            .and_then(|m| u16::try_from(m.len()).ok());
        self.push(Reading::MissionCurrent {
            seq,
            total,
            state: MissionState::Active,
        });
    }

    fn battery(&mut self, m: &Message, r: &[u8]) {
        let instance = m.get(r, "Inst").and_then(|v| v.as_i64()).unwrap_or(0);
        let battery = Battery {
            source: BatterySource::BatteryStatus {
                id: u8::try_from(instance).unwrap_or(u8::MAX),
                component: AUTOPILOT_COMPONENT,
            },
            voltage_v: m.known(r, "Volt"),
            current_a: m.known(r, "Curr"),
            consumed_mah: m.known(r, "CurrTot"),
            energy_consumed_j: m.known(r, "EnrgTot").map(|wh| wh * 3600.0),
            remaining_pct: m.known(r, "RemPct"),
            fake_current: false,
        };
        self.events.push(Event {
            time_us: self.now_us,
            battery_instance: Some(instance.unsigned_abs()),
            armed_unknown: false,
            mode_number: None,
            reading: Reading::Battery(battery),
        });
    }

    fn position(&mut self, m: &Message, r: &[u8]) {
        let (Some(lat), Some(lon), Some(alt), Some(rel)) = (
            m.known(r, "Lat"),
            m.known(r, "Lng"),
            m.known(r, "Alt"),
            m.known(r, "RelHomeAlt"),
        ) else {
            return;
        };
        if lat == 0.0 && lon == 0.0 {
            return;
        }
        let [vn, ve, vd] = self.velocity.unwrap_or_default();
        let time_boot_ms = m
            .time_us(r)
            .map_or(0, |t| u32::try_from(t / 1000).unwrap_or(u32::MAX));
        self.push(Reading::Position(Position {
            time_boot_ms,
            lat_deg: lat,
            lon_deg: lon,
            alt_amsl_m: alt,
            relative_alt_m: rel,
            vn_m_s: vn,
            ve_m_s: ve,
            vd_m_s: vd,
        }));
    }

    fn command(&mut self, m: &Message, r: &[u8]) {
        let int = |label: &str| {
            m.get(r, label)
                .and_then(|v| v.as_i64())
                .and_then(|v| u16::try_from(v).ok())
        };
        let float = |label: &str| m.number(r, label).unwrap_or(f64::NAN);
        let (Some(seq), Some(command), Some(total)) = (int("CNum"), int("CId"), int("CTot")) else {
            return;
        };
        let c = MissionCommand {
            seq,
            command,
            frame: int("Frame").and_then(|f| u8::try_from(f).ok()).unwrap_or(0),
            params: ["Prm1", "Prm2", "Prm3", "Prm4"].map(|p| float(p) as f32),
            lat_deg: float("Lat"),
            lon_deg: float("Lng"),
            alt_m: float("Alt"),
        };
        let continues = self
            .dump
            .last()
            .is_some_and(|last| last.seq.checked_add(1) == Some(seq) && total == self.dump_total);
        if seq == 0 {
            self.dump = vec![c];
            self.dump_total = total;
        } else if continues {
            self.dump.push(c);
        } else {
            self.dump.clear();
            if is_nav_command(command) {
                self.nav_started(seq);
            }
            return;
        }
        if self.dump.len() == usize::from(self.dump_total) {
            let whole = std::mem::take(&mut self.dump);
            // The mission flown: the last written before the first command started.
            if self.current_nav.is_none() || self.mission.is_none() {
                self.mission = Some(whole);
            }
        }
    }

    /// Whether the vehicle was armed before the first arming record (see the module doc), and
    /// whether it was disarmed just before the log began.
    fn armed_before(&self) -> Option<(bool, bool)> {
        let opened_at_arming = self.log_disarmed == Some(0.0);
        match self.first_armed {
            Some(true) => Some((false, false)),
            Some(false) | None if opened_at_arming => Some((true, true)),
            Some(false) => Some((true, false)),
            None => None,
        }
    }

    /// The readings stamped in log time, of one battery instance: the lowest that logs a
    /// current, else the lowest; and the records refused.
    fn stamped(self) -> (Vec<Stamped>, Option<Vec<MissionCommand>>, Vec<Skipped>) {
        let with_current =
            |e: &&Event| matches!(&e.reading, Reading::Battery(b) if b.current_a.is_some());
        let battery = self
            .events
            .iter()
            .filter(with_current)
            .filter_map(|e| e.battery_instance)
            .min()
            .or_else(|| self.events.iter().filter_map(|e| e.battery_instance).min());
        let before = self.armed_before();
        let first = self.first_us.unwrap_or(0);
        let stamp = |time_us: u64, reading: Reading| Stamped {
            t_s: (time_us as f64 - first as f64) * 1e-6,
            wall_us: time_us.saturating_sub(first),
            reading,
        };
        let in_log_s = |t: Option<u64>| t.map(|t| (t as f64 - first as f64) * 1e-6);
        let skipped = (self.skipped.into_iter())
            .map(|s| Skipped {
                offset: s.offset as u64,
                bytes: s.bytes as u64,
                record: s.record,
                reason: s.reason,
                from_s: in_log_s(s.before_us),
                to_s: in_log_s(s.after_us),
            })
            .collect();
        let other_vehicle = self.other_vehicle;
        let mode = |number: Option<u64>| match number {
            Some(n) if other_vehicle => FlightMode::Other(format!("custom {n}")),
            Some(n) => FlightMode::arducopter(n),
            None => FlightMode::Other("unknown".into()),
        };
        let mut stamped = Vec::with_capacity(self.events.len() + 1);
        if let Some((true, true)) = before {
            let first_mode = self
                .events
                .iter()
                .find(|e| matches!(e.reading, Reading::Heartbeat { .. }))
                .and_then(|e| e.mode_number);
            stamped.push(stamp(
                first,
                Reading::Heartbeat {
                    armed: false,
                    mode: mode(first_mode),
                },
            ));
        }
        for e in self.events {
            if e.battery_instance.is_some() && e.battery_instance != battery {
                continue;
            }
            let reading = match (e.reading, e.armed_unknown) {
                (Reading::Heartbeat { .. }, true) => match before {
                    Some((armed, _)) => Reading::Heartbeat {
                        armed,
                        mode: mode(e.mode_number),
                    },
                    None => continue,
                },
                (Reading::Heartbeat { armed, .. }, false) => Reading::Heartbeat {
                    armed,
                    mode: mode(e.mode_number),
                },
                (reading, _) => reading,
            };
            stamped.push(stamp(e.time_us, reading));
        }
        (stamped, self.mission, skipped)
    }
}

/// Parses a whole DataFlash log held in memory; `file` names it in errors.
pub fn parse(file: &str, bytes: &[u8]) -> Result<OnboardLog, OnboardError> {
    parse_scanned(file, bytes).map(|(log, _)| log)
}

/// [`parse`], and what the walk through the file found (records read, bytes skipped).
pub fn parse_scanned(file: &str, bytes: &[u8]) -> Result<(OnboardLog, Scan), OnboardError> {
    if !bytes.starts_with(MAGIC) {
        return Err(OnboardError::Malformed {
            file: file.to_string(),
            offset: 0,
            reason: "not a DataFlash log: it does not start with an FMT record".into(),
        });
    }
    let offset_of = |record: &[u8]| record.as_ptr() as usize - bytes.as_ptr() as usize;
    let mut times = Vec::new();
    walk(
        bytes,
        |message, record| {
            if let Some(t) = message.time_us(record) {
                times.push((offset_of(record), t));
            }
        },
        |_, _, _| {},
    );
    let jumps = time_jumps(&times);
    drop(times);
    let mut jumps = jumps.into_iter().peekable();
    // Both callbacks feed the one builder, in file order.
    let builder = std::cell::RefCell::new(Builder::default());
    let scan = walk(
        bytes,
        |message, record| {
            let offset = offset_of(record);
            let mut builder = builder.borrow_mut();
            match jumps.next_if(|(at, _)| *at == offset) {
                Some((_, reason)) => builder.skip(offset, record.len(), &message.name, reason),
                None => builder.record(message, record, offset),
            }
        },
        |offset, bytes, reason| builder.borrow_mut().skip(offset, bytes, "FMT", reason),
    );
    let (stamped, mission, skipped) = builder.into_inner().stamped();
    let tear = scan.tear.as_ref().map(|(offset, reason)| Tear {
        offset: *offset,
        after_s: stamped.last().map(|s| s.t_s),
        reason: reason.clone(),
    });
    let log = OnboardLog {
        format: Format::Dataflash,
        file: file.to_string(),
        bytes: bytes.len() as u64,
        stamped,
        mission,
        tear,
        skipped,
    };
    Ok((log, scan))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The offsets `time_jumps` refuses among records at offsets 0, 1, 2, ... of `times_s`.
    fn refused(times_s: &[f64]) -> Vec<usize> {
        let times: Vec<(usize, u64)> = (times_s.iter().enumerate())
            .map(|(k, t)| (k, (t * 1e6) as u64))
            .collect();
        time_jumps(&times).into_iter().map(|(at, _)| at).collect()
    }

    #[test]
    fn a_time_far_from_both_sides_is_refused_and_a_pause_in_logging_is_kept() {
        // Records 0.1 s apart, a pause of a minute: all kept.
        assert!(refused(&[10.0, 10.1, 10.2, 70.2, 70.3, 70.4]).is_empty());
        // A small step back (records written a little out of order): kept.
        assert!(refused(&[10.0, 10.1, 9.8, 10.2]).is_empty());
        // One record a long way forward or back, mid-log, first or last: refused.
        assert_eq!(refused(&[10.0, 10.1, 4e6, 10.2, 10.3]), [2]);
        assert_eq!(refused(&[10.0, 10.1, 0.0, 10.2, 10.3]), [2]);
        assert_eq!(refused(&[4e6, 10.0, 10.1, 10.2]), [0]);
        assert_eq!(refused(&[10.0, 10.1, 10.2, 4e6]), [3]);
        // Two in a row, each its own jump: both refused.
        assert_eq!(refused(&[10.0, 10.1, 4e6, 8e6, 10.2, 10.3]), [2, 3]);
        let reason = time_jumps(&[(0, 10_000_000), (1, 4_000_000_000_000), (2, 10_100_000)]);
        assert_eq!(
            reason[0].1,
            "its TimeUS jumps +4.0e6 s from the records around it"
        );
    }
}
