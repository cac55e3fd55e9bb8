//! PX4 ULog (`.ulg`): the topics that measure a flight (`battery_status`, positions, home,
//! `mission_result`, `vehicle_status`, `vehicle_land_detected`) as stamped readings that mean
//! what `link::telemetry::decode` makes of PX4's MAVLink for the same flight.
//!
//! Records are parsed by the `px4-ulog` crate (PX4's own Rust reader: formats, subscriptions,
//! nested and padded fields). This module frames the records itself, so that a torn file is
//! located to the byte and every record is checked before the crate sees it: the crate indexes
//! into a few record kinds without checking their length (a subscription shorter than 3 bytes, a
//! parameter whose key runs past its end), and a format with no fields, an array of zero or
//! fewer elements, or thousands of formats nested in one another would make it loop or recurse
//! without bound. Such records are refused here, naming the byte, and so are formats that would
//! flatten past [`MAX_FLATTENED_BYTES`] (the crate names every array element's field in full,
//! several times over, and would allocate gigabytes for a few kilobytes of formats). The crate's
//! errors are said without its debug dumps, naming the topic where it is known.
//!
//! How each topic becomes a reading (the topics' definitions in PX4's msg directory; PX4's MAVLink
//! streams for what a ground station would have seen of the same flight):
//! - `battery_status`: of the instances logged, the one most often connected with a current;
//!   `voltage_v` 0 is unknown, `current_a` -1 unknown, `discharged_mah` -1 unknown, `remaining`
//!   0-1 (negative unknown) becomes percent. No energy integral is logged.
//! - `vehicle_global_position` (instance 0) with the latest `vehicle_local_position` velocity
//!   (north, east, down): a position; `relative_alt_m` is `alt` above the latest valid
//!   `home_position`'s `alt` (before any, `-z` of the local position, as PX4's
//!   GLOBAL_POSITION_INT does). `time_boot_ms` is the sample's own timestamp.
//! - `home_position` with a valid horizontal position: home, set at its timestamp.
//! - `mission_result`: MISSION_CURRENT (`seq_current`, `seq_total`, the state as PX4's
//!   MISSION_CURRENT stream derives it) when it changes; MISSION_ITEM_REACHED when `seq_reached`
//!   changes to an item.
//! - `vehicle_status`: the heartbeat (`arming_state` 2 armed; the mode from `nav_state`), on
//!   every change and at least once a second, as PX4's 1 Hz HEARTBEAT.
//! - `vehicle_land_detected` and `nav_state`: the landed state as EXTENDED_SYS_STATE's (on the
//!   ground; in the air, taking off or landing by the navigation state), on change.
//! - Logged strings: status texts (ULog's level characters '0'-'7' are MAVLink severities).
//!
//! Readings are ordered by their timestamps (topics are written in the logger's polling order,
//! not strictly in time); `t_s` counts from the first of them and `wall_us` is the autopilot's
//! own microseconds since boot.

use std::cell::RefCell;
use std::collections::{HashMap, HashSet};

use px4_ulog::stream_parser::model::{FlattenedFieldType, FlattenedFormat};
use px4_ulog::stream_parser::{DataMessage, LogParser, LoggedStringMessage};

use super::{Format, OnboardError, OnboardLog, Tear};
use crate::flightlog::telemetry::{
    Battery, BatterySource, FlightMode, LandedState, MissionState, Position, Reading, Stamped,
};

/// A ULog file's first bytes.
pub const MAGIC: &[u8] = b"ULog\x01\x12\x35";

/// The file header: magic, version byte, the logger's start time (u64 microseconds).
const HEADER_LEN: usize = 16;

/// A record's header: payload size (u16) and kind (one ASCII byte).
const RECORD_HEADER_LEN: usize = 3;

/// More formats than any PX4 build defines (about 250 uORB messages): beyond it, a file is
/// refused rather than have the crate recurse through formats nested in one another.
const MAX_FORMATS: usize = 1024;

/// What flattening the formats may cost, in bytes (see [`Flattening`]). The crate flattens every
/// format into one named field per array element, each name the whole path (`esc[3].esc_rpm`),
/// and keeps three copies of each name (the field list and a name index) and one more field list
/// per subscription. PX4's formats come to far less: the fixture's (`px4-sih-8wp.ulg`, 10
/// formats, 292 fields, 10 subscriptions) to 97 KB by this count, and PX4's whole uORB set (about
/// 250 messages, the largest arrays of nested messages a few hundred fields) would by estimate
/// come to a few MB. 64 MiB is well above that, and keeps what a few kilobytes of formats can
/// make the crate allocate (a 32 000-element array with a 60 000-character name would be 5.8 GB)
/// within a fixed bound whatever the formats say.
const MAX_FLATTENED_BYTES: u64 = 64 << 20;

/// Bytes a flattened field costs beside its name: the crate's field (a `String`, its type and
/// offset: 32 bytes) in the field list and again in the name index, with the index's own key and
/// slot.
const FLATTENED_FIELD_BYTES: u64 = 128;

/// The heartbeat is repeated at least this often, as PX4 sends HEARTBEAT at 1 Hz.
const HEARTBEAT_PERIOD_US: u64 = 1_000_000;

/// A local-position velocity older than this is not lent to a global position.
const VELOCITY_MAX_AGE_US: u64 = 500_000;

/// PX4's MAVLink component id (the autopilot), for the battery's source.
const PX4_COMPONENT: u8 = 1;

/// Parses a whole ULog held in memory; `file` names it in errors.
pub fn parse(file: &str, bytes: &[u8]) -> Result<OnboardLog, OnboardError> {
    let malformed = |offset: usize, reason: String| OnboardError::Malformed {
        file: file.to_string(),
        offset: offset as u64,
        reason,
    };
    let header = bytes
        .get(..HEADER_LEN)
        .ok_or_else(|| malformed(0, "the ULog header is cut short".into()))?;
    if !header.starts_with(MAGIC) {
        return Err(malformed(0, "not a ULog header".into()));
    }

    let topics = RefCell::new(Topics::default());
    let mut on_data = |m: &DataMessage| topics.borrow_mut().data(m);
    let mut on_string = |m: &LoggedStringMessage| topics.borrow_mut().string(m);
    let mut parser = LogParser::default();
    parser.set_data_message_callback(&mut on_data);
    parser.set_logged_string_message_callback(&mut on_string);
    parser
        .consume_bytes(header)
        .map_err(|e| malformed(0, crate_reason(&e.description)))?;

    let mut walk = Walk::new(bytes);
    let mut formats = 0usize;
    let mut flattening = Flattening::default();
    let mut tear = None;
    while let Some(step) = walk.next_record() {
        let (offset, kind, record) = match step {
            Ok(r) => r,
            Err((offset, reason)) => {
                if parser.in_data() {
                    tear = Some((offset, reason));
                    break;
                }
                return Err(malformed(offset, reason));
            }
        };
        if kind == b'F' {
            formats += 1;
        }
        let payload = record.get(RECORD_HEADER_LEN..).unwrap_or(&[]);
        let checked = check_record(kind, payload)
            .and_then(|()| {
                (formats <= MAX_FORMATS)
                    .then_some(())
                    .ok_or(Unsafe::TooManyFormats)
            })
            .map_err(|reason| (offset, format!("{}: {reason}", kind_name(kind))))
            .and_then(|()| flattening.admit(offset, kind, payload, parser.in_data()))
            .and_then(|()| {
                parser.consume_bytes(record).map_err(|e| {
                    let reason = flattening.crate_reason(&e.description, kind, payload);
                    (offset, format!("{}: {reason}", kind_name(kind)))
                })
            });
        if let Err((offset, reason)) = checked {
            if parser.in_data() {
                tear = Some((offset, reason));
                break;
            }
            return Err(malformed(offset, reason));
        }
        if kind == b'B' {
            walk.set_appended(parser.appended_offsets());
        }
    }
    if tear.is_none() && !parser.in_data() {
        return Err(malformed(
            bytes.len(),
            "the log ends before its data section".into(),
        ));
    }
    drop(parser);

    let stamped = topics.into_inner().finish();
    let tear = tear.map(|(offset, reason)| Tear {
        offset: offset as u64,
        after_s: stamped.last().map(|s| s.t_s),
        reason,
    });
    Ok(OnboardLog {
        format: Format::Ulog,
        file: file.to_string(),
        bytes: bytes.len() as u64,
        stamped,
        mission: None,
        tear,
        skipped: Vec::new(),
    })
}

/// The crate's error text as ours: lowercase first letter, one line, bounded length, without
/// the crate's debug dumps of its structures or of the bytes at fault.
fn crate_reason(description: &str) -> String {
    let mut line = description.lines().next().unwrap_or("");
    for dump in [", format:", " [", " {", "{", "["] {
        if let Some(at) = line.find(dump) {
            line = &line[..at];
        }
    }
    let mut reason: String = line.chars().take(120).collect();
    if let Some(first) = reason.get(..1) {
        reason.replace_range(..1, &first.to_lowercase());
    }
    reason.trim_end_matches(['.', ':', ' ']).to_string()
}

fn kind_name(kind: u8) -> String {
    let name = match kind {
        b'B' => "flag bits",
        b'F' => "format",
        b'I' => "info",
        b'M' => "multi info",
        b'P' => "parameter",
        b'Q' => "parameter default",
        b'A' => "subscription",
        b'R' => "unsubscription",
        b'D' => "data",
        b'L' => "logged string",
        b'C' => "tagged logged string",
        b'S' => "sync",
        b'O' => "dropout",
        _ => return format!("a record of unknown kind {kind}"),
    };
    format!("a {name} record")
}

/// What is wrong with a record the crate would index past or loop on.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
enum Unsafe {
    #[error("{0} bytes, fewer than 3")]
    Short(usize),
    #[error("its key runs past its end")]
    KeyPastEnd,
    #[error("{name}: an array of {count} elements")]
    EmptyArray { name: String, count: String },
    #[error("{0} has no fields")]
    NoFields(String),
    #[error("more than {MAX_FORMATS} formats")]
    TooManyFormats,
}

/// Refuses what the crate would index past or loop on (see the module doc).
fn check_record(kind: u8, payload: &[u8]) -> Result<(), Unsafe> {
    match kind {
        b'A' if payload.len() < 3 => Err(Unsafe::Short(payload.len())),
        b'P' => match payload.first() {
            Some(&key_len) if usize::from(key_len) < payload.len() => Ok(()),
            _ => Err(Unsafe::KeyPastEnd),
        },
        b'F' => check_format(payload),
        _ => Ok(()),
    }
}

/// A format `name:type field;type field;...` whose every field is one or more elements.
fn check_format(payload: &[u8]) -> Result<(), Unsafe> {
    let Ok(text) = std::str::from_utf8(payload) else {
        return Ok(()); // the crate refuses it
    };
    let Some((name, fields)) = text.split_once(':') else {
        return Ok(());
    };
    let mut any = false;
    for field in fields.split(';').filter(|f| !f.is_empty()) {
        any = true;
        let ty = field.split(' ').next().unwrap_or("");
        if let Some((_, count)) = ty.split_once('[') {
            let count = count.trim_end_matches(']');
            if count.parse::<i64>().is_ok_and(|n| n <= 0) {
                return Err(Unsafe::EmptyArray {
                    name: name.to_string(),
                    count: count.to_string(),
                });
            }
        }
    }
    if any {
        Ok(())
    } else {
        Err(Unsafe::NoFields(name.to_string()))
    }
}

/// One field of a format as the crate will flatten it.
#[derive(Debug, Clone)]
struct FormatField {
    /// The field's type: a primitive or the name of another format.
    ty: String,
    /// Elements: None for a single value.
    count: Option<u64>,
    name_len: u64,
}

/// What a format costs the crate once flattened: its fields (one per array element, nested
/// formats expanded) and the bytes of their path names.
#[derive(Debug, Clone, Copy, Default)]
struct Cost {
    fields: u64,
    name_bytes: u64,
}

impl Cost {
    fn bytes(self) -> u64 {
        (self.fields.saturating_mul(FLATTENED_FIELD_BYTES))
            .saturating_add(self.name_bytes.saturating_mul(3))
    }
}

/// The formats and subscriptions read so far, so that what flattening them will cost the crate
/// is known, and bounded by [`MAX_FLATTENED_BYTES`], before the crate does it: when the data
/// section begins it flattens every format defined, and each subscription copies its topic's.
#[derive(Debug, Default)]
struct Flattening {
    /// Each format defined before the data section: its record's offset, name and fields.
    formats: Vec<(usize, String, Vec<FormatField>)>,
    /// The flattened cost of each format, once the data section has begun.
    costs: HashMap<String, Cost>,
    spent_bytes: u64,
    /// The topic each message id was subscribed as.
    topics: HashMap<u16, String>,
}

const PRIMITIVES: [&str; 12] = [
    "int8_t", "uint8_t", "int16_t", "uint16_t", "int32_t", "uint32_t", "int64_t", "uint64_t",
    "float", "double", "bool", "char",
];

/// The characters of the element suffixes `[0]` to `[n-1]`.
fn brackets_len(n: u64) -> u64 {
    let mut total = 0u64;
    let mut digits = 1u64;
    let mut from = 0u64;
    while from < n {
        let to = n.min(from.saturating_mul(10).max(10));
        total = total.saturating_add((to - from).saturating_mul(digits + 2));
        from = to;
        digits += 1;
    }
    total
}

impl Flattening {
    /// Checks a record before the crate sees it: the formats, when the data section begins, and
    /// each subscription, against what flattening may cost; a subscription's topic name. The
    /// error is the offset and reason of the record at fault.
    fn admit(
        &mut self,
        offset: usize,
        kind: u8,
        payload: &[u8],
        in_data: bool,
    ) -> Result<(), (usize, String)> {
        if kind == b'F' && !in_data {
            if let Some(format) = parse_format(payload) {
                self.formats.push((offset, format.0, format.1));
            }
            return Ok(());
        }
        if !in_data && matches!(kind, b'A' | b'L' | b'C' | b'O' | b'S' | b'R') {
            self.flatten()?;
        }
        if kind != b'A' {
            return Ok(());
        }
        let at = |reason: String| (offset, format!("{}: {reason}", kind_name(kind)));
        let (Some(id), Some(name)) = (payload.get(1..3), payload.get(3..)) else {
            return Ok(()); // checked before
        };
        let id = u16::from_le_bytes([id[0], id[1]]);
        let name = std::str::from_utf8(name)
            .map_err(|_| at(format!("the topic name of message id {id} is not text")))?;
        if let Some(first) = self.topics.get(&id) {
            return Err(at(format!(
                "message id {id} subscribed twice ({first}, then {})",
                bounded(name)
            )));
        }
        let cost = self.costs.get(name).copied().unwrap_or_default();
        self.spent_bytes = self.spent_bytes.saturating_add(cost.bytes());
        if self.spent_bytes > MAX_FLATTENED_BYTES {
            return Err(at(format!(
                "subscribing {} (message id {id}) takes the formats past {} MiB flattened",
                bounded(name),
                MAX_FLATTENED_BYTES >> 20
            )));
        }
        self.topics.insert(id, bounded(name));
        Ok(())
    }

    /// The cost of every format, as the crate will flatten them all; the format at which the
    /// total passes the bound is refused.
    fn flatten(&mut self) -> Result<(), (usize, String)> {
        let defined: HashMap<&str, &[FormatField]> = (self.formats.iter())
            .map(|(_, name, fields)| (name.as_str(), fields.as_slice()))
            .collect();
        let mut costs = HashMap::new();
        for (offset, name, _) in &self.formats {
            let cost = cost_of(name, &defined, &mut costs, &mut Default::default());
            self.spent_bytes = self.spent_bytes.saturating_add(cost.bytes());
            if self.spent_bytes > MAX_FLATTENED_BYTES {
                return Err((
                    *offset,
                    format!(
                        "{}: {} flattens to {} fields with {} bytes of names: the formats come to more than the {} MiB PX4's ever need",
                        kind_name(b'F'),
                        bounded(name),
                        cost.fields,
                        cost.name_bytes,
                        MAX_FLATTENED_BYTES >> 20
                    ),
                ));
            }
        }
        self.costs = costs;
        self.formats = Vec::new();
        Ok(())
    }

    /// The crate's error for a record, said our way (see [`crate_reason`]).
    fn crate_reason(&self, description: &str, kind: u8, payload: &[u8]) -> String {
        let id = payload
            .get(..2)
            .map(|id| u16::from_le_bytes([id[0], id[1]]));
        match (kind, id) {
            (b'D', Some(id)) if description.starts_with("data message had wrong size") => {
                let topic = self.topics.get(&id).map_or("?", String::as_str);
                format!(
                    "{} bytes of topic {topic} (message id {id}), not the size of its format",
                    payload.len()
                )
            }
            _ => crate_reason(description),
        }
    }
}

/// At most 64 characters of a name from the file, for messages.
fn bounded(name: &str) -> String {
    match name.char_indices().nth(64) {
        Some((at, _)) => format!("{}...", &name[..at]),
        None => name.to_string(),
    }
}

/// A format record's name and fields, when the crate would read it.
fn parse_format(payload: &[u8]) -> Option<(String, Vec<FormatField>)> {
    let text = std::str::from_utf8(payload).ok()?;
    let (name, fields) = text.split_once(':')?;
    let fields = (fields.split(';').filter(|f| !f.is_empty()))
        .map(|field| {
            let (ty, field_name) = field.split_once(' ')?;
            let (ty, count) = match ty.split_once('[') {
                Some((ty, n)) => (ty, Some(n.trim_end_matches(']').parse::<u64>().ok()?)),
                None => (ty, None),
            };
            Some(FormatField {
                ty: ty.to_string(),
                count,
                name_len: field_name.len() as u64,
            })
        })
        .collect::<Option<Vec<_>>>()?;
    Some((name.to_string(), fields))
}

/// The flattened cost of format `name` (memoised in `costs`); a format nesting itself costs
/// what it has before the loop (the crate refuses it).
fn cost_of(
    name: &str,
    defined: &HashMap<&str, &[FormatField]>,
    costs: &mut HashMap<String, Cost>,
    open: &mut HashSet<String>,
) -> Cost {
    if let Some(cost) = costs.get(name) {
        return *cost;
    }
    let Some(fields) = defined.get(name) else {
        return Cost::default();
    };
    if !open.insert(name.to_string()) {
        return Cost::default();
    }
    let mut cost = Cost::default();
    for f in fields.iter() {
        let n = f.count.unwrap_or(1);
        let suffixes = f.count.map_or(0, brackets_len);
        let element = if PRIMITIVES.contains(&f.ty.as_str()) {
            Cost {
                fields: 1,
                name_bytes: 0,
            }
        } else {
            let inner = cost_of(&f.ty, defined, costs, open);
            // Each inner field's name carries this field's name and a dot before its own.
            Cost {
                fields: inner.fields,
                name_bytes: inner.name_bytes.saturating_add(inner.fields),
            }
        };
        cost.fields = cost.fields.saturating_add(n.saturating_mul(element.fields));
        cost.name_bytes = cost
            .name_bytes
            .saturating_add(n.saturating_mul(element.name_bytes))
            .saturating_add(n.saturating_mul(element.fields).saturating_mul(f.name_len))
            .saturating_add(suffixes.saturating_mul(element.fields));
    }
    open.remove(name);
    costs.insert(name.to_string(), cost);
    cost
}

/// The record framing: each record's offset and bytes, or where and why it cannot be read.
struct Walk<'a> {
    bytes: &'a [u8],
    pos: usize,
    /// Where appended data sections begin (the flag bits' offsets within the file, ascending).
    appended: Vec<usize>,
}

type Record<'a> = (usize, u8, &'a [u8]);

impl<'a> Walk<'a> {
    fn new(bytes: &'a [u8]) -> Walk<'a> {
        Walk {
            bytes,
            pos: HEADER_LEN,
            appended: Vec::new(),
        }
    }

    fn set_appended(&mut self, offsets: &[u64; 3]) {
        let mut appended: Vec<usize> = offsets
            .iter()
            .filter_map(|&o| usize::try_from(o).ok())
            .filter(|&o| o > self.pos && o <= self.bytes.len())
            .collect();
        appended.sort_unstable();
        appended.dedup();
        self.appended = appended;
    }

    fn next_record(&mut self) -> Option<Result<Record<'a>, (usize, String)>> {
        // A section ends where the next appended one begins (PX4 may leave a partial record
        // there when it appends): a record crossing the boundary is not read.
        while let Some(&next) = self.appended.first() {
            if self.pos < next {
                break;
            }
            self.appended.remove(0);
        }
        let pos = self.pos;
        let rest = self.bytes.get(pos..).filter(|r| !r.is_empty())?;
        let Some(head) = rest.get(..RECORD_HEADER_LEN) else {
            return Some(Err((pos, "a record header cut short".into())));
        };
        let size = usize::from(u16::from_le_bytes([head[0], head[1]]));
        let kind = head[2];
        let end = pos + RECORD_HEADER_LEN + size;
        if let Some(&next) = self.appended.first() {
            if end > next {
                self.pos = next;
                self.appended.remove(0);
                return self.next_record();
            }
        }
        match self.bytes.get(pos..end) {
            Some(record) => {
                self.pos = end;
                Some(Ok((pos, kind, record)))
            }
            None => Some(Err((
                pos,
                format!(
                    "{} cut short ({size} bytes promised, {} left)",
                    kind_name(kind),
                    rest.len() - RECORD_HEADER_LEN
                ),
            ))),
        }
    }
}

/// One field of a logged format, read as a number whatever its type.
#[derive(Debug, Clone, Copy)]
struct Field {
    offset: usize,
    ty: FieldType,
}

#[derive(Debug, Clone, Copy)]
enum FieldType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
    Bool,
}

impl Field {
    fn find(format: &FlattenedFormat, name: &str) -> Option<Field> {
        let f = format
            .field_iter()
            .find(|f| f.flattened_field_name == name)?;
        let ty = match f.field_type {
            FlattenedFieldType::Int8 => FieldType::I8,
            FlattenedFieldType::UInt8 => FieldType::U8,
            FlattenedFieldType::Int16 => FieldType::I16,
            FlattenedFieldType::UInt16 => FieldType::U16,
            FlattenedFieldType::Int32 => FieldType::I32,
            FlattenedFieldType::UInt32 => FieldType::U32,
            FlattenedFieldType::Int64 => FieldType::I64,
            FlattenedFieldType::UInt64 => FieldType::U64,
            FlattenedFieldType::Float => FieldType::F32,
            FlattenedFieldType::Double => FieldType::F64,
            FlattenedFieldType::Bool => FieldType::Bool,
            FlattenedFieldType::Char => return None,
        };
        Some(Field {
            offset: usize::from(f.offset),
            ty,
        })
    }

    fn bytes<const N: usize>(&self, data: &[u8]) -> Option<[u8; N]> {
        data.get(self.offset..self.offset + N)?.try_into().ok()
    }

    fn f64(&self, data: &[u8]) -> Option<f64> {
        Some(match self.ty {
            FieldType::I8 => f64::from(i8::from_le_bytes(self.bytes(data)?)),
            FieldType::U8 => f64::from(self.bytes::<1>(data)?[0]),
            FieldType::Bool => f64::from(u8::from(self.bytes::<1>(data)?[0] != 0)),
            FieldType::I16 => f64::from(i16::from_le_bytes(self.bytes(data)?)),
            FieldType::U16 => f64::from(u16::from_le_bytes(self.bytes(data)?)),
            FieldType::I32 => f64::from(i32::from_le_bytes(self.bytes(data)?)),
            FieldType::U32 => f64::from(u32::from_le_bytes(self.bytes(data)?)),
            FieldType::I64 => i64::from_le_bytes(self.bytes(data)?) as f64,
            FieldType::U64 => u64::from_le_bytes(self.bytes(data)?) as f64,
            FieldType::F32 => f64::from(f32::from_le_bytes(self.bytes(data)?)),
            FieldType::F64 => f64::from_le_bytes(self.bytes(data)?),
        })
    }

    fn u64(&self, data: &[u8]) -> Option<u64> {
        match self.ty {
            FieldType::U64 => Some(u64::from_le_bytes(self.bytes(data)?)),
            _ => self
                .f64(data)
                .filter(|v| v.is_finite() && *v >= 0.0)
                .map(|v| v as u64),
        }
    }

    fn bool(&self, data: &[u8]) -> Option<bool> {
        self.f64(data).map(|v| v != 0.0)
    }
}

/// The fields read of each topic; a topic lacking a required field is not read.
#[derive(Debug, Clone, Copy)]
enum Decoder {
    Ignored,
    Battery {
        timestamp: Field,
        connected: Option<Field>,
        voltage_v: Field,
        current_a: Field,
        discharged_mah: Option<Field>,
        remaining: Option<Field>,
    },
    Global {
        timestamp: Field,
        lat: Field,
        lon: Field,
        alt: Field,
    },
    Local {
        timestamp: Field,
        vx: Field,
        vy: Field,
        vz: Field,
        z: Option<Field>,
    },
    Home {
        timestamp: Field,
        lat: Field,
        lon: Field,
        alt: Field,
        valid_hpos: Option<Field>,
        valid_alt: Option<Field>,
    },
    MissionResult {
        timestamp: Field,
        seq_current: Field,
        seq_total: Field,
        seq_reached: Option<Field>,
        finished: Option<Field>,
    },
    Status {
        timestamp: Field,
        arming_state: Field,
        nav_state: Field,
    },
    Land {
        timestamp: Field,
        landed: Field,
    },
}

impl Decoder {
    fn for_format(format: &FlattenedFormat) -> Decoder {
        let f = |name: &str| Field::find(format, name);
        let decoder = match format.message_name() {
            "battery_status" => (|| {
                Some(Decoder::Battery {
                    timestamp: f("timestamp")?,
                    connected: f("connected"),
                    voltage_v: f("voltage_v")?,
                    current_a: f("current_a")?,
                    discharged_mah: f("discharged_mah"),
                    remaining: f("remaining"),
                })
            })(),
            "vehicle_global_position" => (|| {
                Some(Decoder::Global {
                    timestamp: f("timestamp")?,
                    lat: f("lat")?,
                    lon: f("lon")?,
                    alt: f("alt")?,
                })
            })(),
            "vehicle_local_position" => (|| {
                Some(Decoder::Local {
                    timestamp: f("timestamp")?,
                    vx: f("vx")?,
                    vy: f("vy")?,
                    vz: f("vz")?,
                    z: f("z"),
                })
            })(),
            "home_position" => (|| {
                Some(Decoder::Home {
                    timestamp: f("timestamp")?,
                    lat: f("lat")?,
                    lon: f("lon")?,
                    alt: f("alt")?,
                    valid_hpos: f("valid_hpos"),
                    valid_alt: f("valid_alt"),
                })
            })(),
            "mission_result" => (|| {
                Some(Decoder::MissionResult {
                    timestamp: f("timestamp")?,
                    seq_current: f("seq_current")?,
                    seq_total: f("seq_total")?,
                    seq_reached: f("seq_reached"),
                    finished: f("finished"),
                })
            })(),
            "vehicle_status" => (|| {
                Some(Decoder::Status {
                    timestamp: f("timestamp")?,
                    arming_state: f("arming_state")?,
                    nav_state: f("nav_state")?,
                })
            })(),
            "vehicle_land_detected" => (|| {
                Some(Decoder::Land {
                    timestamp: f("timestamp")?,
                    landed: f("landed")?,
                })
            })(),
            _ => None,
        };
        decoder.unwrap_or(Decoder::Ignored)
    }
}

/// One `battery_status` sample of one instance, before the instance is chosen.
#[derive(Debug, Clone, Copy)]
struct BatterySample {
    timestamp_us: u64,
    battery: Battery,
    connected: bool,
}

/// PX4's `vehicle_status.nav_state` as the normalised mode (PX4 `vehicle_status.msg`; the same
/// modes `link::telemetry::decode` reads from the heartbeat's custom mode).
fn nav_state_mode(nav_state: u8) -> FlightMode {
    match nav_state {
        0 | 1 | 2 | 10 | 15 => FlightMode::Manual,
        3 => FlightMode::Mission,
        4 => FlightMode::Hold,
        5 => FlightMode::Rtl,
        14 => FlightMode::Other("offboard".into()),
        17 | 22 => FlightMode::Takeoff,
        18 | 20 => FlightMode::Land,
        19 => FlightMode::Other("follow_target".into()),
        n => FlightMode::Other(format!("px4 nav_state {n}")),
    }
}

const NAV_STATE_MISSION: u8 = 3;

/// What the topics read so far make.
#[derive(Debug, Default)]
struct Topics {
    decoders: Vec<Option<Decoder>>,
    readings: Vec<(u64, Reading)>,
    batteries: Vec<(u8, Vec<BatterySample>)>,
    /// The latest local position: timestamp, velocity north/east/down, z (down).
    velocity: Option<(u64, [f64; 3], Option<f64>)>,
    home_alt_m: Option<f64>,
    nav_state: Option<u8>,
    last_heartbeat: Option<(u64, bool, FlightMode)>,
    mission: Option<(u16, Option<u16>, MissionState)>,
    seq_reached: Option<i64>,
    landed: Option<bool>,
    landed_state: Option<LandedState>,
}

impl Topics {
    fn data(&mut self, m: &DataMessage) {
        let id = usize::from(m.msg_id);
        if id >= self.decoders.len() {
            self.decoders.resize(id + 1, None);
        }
        let Some(slot) = self.decoders.get_mut(id) else {
            return;
        };
        let decoder = *slot.get_or_insert_with(|| Decoder::for_format(m.flattened_format));
        let instance = m.multi_id.value();
        let d = m.data;
        match decoder {
            Decoder::Ignored => {}
            Decoder::Battery {
                timestamp,
                connected,
                voltage_v,
                current_a,
                discharged_mah,
                remaining,
            } => {
                let Some(timestamp_us) = timestamp.u64(d).filter(|&t| t > 0) else {
                    return;
                };
                let known =
                    |v: Option<f64>, unknown: f64| v.filter(|v| v.is_finite() && *v != unknown);
                let battery = Battery {
                    source: BatterySource::BatteryStatus {
                        id: instance,
                        component: PX4_COMPONENT,
                    },
                    voltage_v: known(voltage_v.f64(d), 0.0),
                    current_a: known(current_a.f64(d), -1.0),
                    consumed_mah: known(discharged_mah.and_then(|f| f.f64(d)), -1.0),
                    energy_consumed_j: None,
                    remaining_pct: remaining
                        .and_then(|f| f.f64(d))
                        .filter(|r| r.is_finite() && *r >= 0.0)
                        .map(|r| r * 100.0),
                    fake_current: false,
                };
                let sample = BatterySample {
                    timestamp_us,
                    battery,
                    connected: connected.and_then(|f| f.bool(d)).unwrap_or(true),
                };
                match self.batteries.iter_mut().find(|(i, _)| *i == instance) {
                    Some((_, samples)) => samples.push(sample),
                    None => self.batteries.push((instance, vec![sample])),
                }
            }
            Decoder::Local {
                timestamp,
                vx,
                vy,
                vz,
                z,
            } if instance == 0 => {
                if let (Some(t), Some(vn), Some(ve), Some(vd)) =
                    (timestamp.u64(d), vx.f64(d), vy.f64(d), vz.f64(d))
                {
                    if vn.is_finite() && ve.is_finite() && vd.is_finite() {
                        let z = z.and_then(|f| f.f64(d)).filter(|z| z.is_finite());
                        self.velocity = Some((t, [vn, ve, vd], z));
                    }
                }
            }
            Decoder::Global {
                timestamp,
                lat,
                lon,
                alt,
            } if instance == 0 => self.global(d, timestamp, lat, lon, alt),
            Decoder::Home {
                timestamp,
                lat,
                lon,
                alt,
                valid_hpos,
                valid_alt,
            } if instance == 0 => {
                let (Some(t), Some(lat), Some(lon), Some(alt)) =
                    (timestamp.u64(d), lat.f64(d), lon.f64(d), alt.f64(d))
                else {
                    return;
                };
                let valid = |f: Option<Field>| f.and_then(|f| f.bool(d)).unwrap_or(true);
                if !alt.is_finite() || !valid(valid_alt) {
                    return;
                }
                self.home_alt_m = Some(alt);
                if valid(valid_hpos) && (lat != 0.0 || lon != 0.0) && t > 0 {
                    self.readings.push((
                        t,
                        Reading::Home {
                            lat_deg: lat,
                            lon_deg: lon,
                            alt_amsl_m: alt,
                            set_boot_s: Some(t as f64 * 1e-6),
                        },
                    ));
                }
            }
            Decoder::MissionResult {
                timestamp,
                seq_current,
                seq_total,
                seq_reached,
                finished,
            } if instance == 0 => {
                let (Some(t), Some(current), Some(total)) =
                    (timestamp.u64(d), seq_current.f64(d), seq_total.f64(d))
                else {
                    return;
                };
                let (current, total) = (current as u16, total as u16);
                let finished = finished.and_then(|f| f.bool(d)).unwrap_or(false);
                // PX4's MISSION_CURRENT stream: no mission, complete, active while in mission
                // mode, paused once under way, else not started.
                let state = if total == 0 {
                    MissionState::NoMission
                } else if finished {
                    MissionState::Complete
                } else if self.nav_state == Some(NAV_STATE_MISSION) {
                    MissionState::Active
                } else if current > 0 {
                    MissionState::Paused
                } else {
                    MissionState::NotStarted
                };
                let now = (current, (total > 0).then_some(total), state);
                if self.mission != Some(now) {
                    self.mission = Some(now);
                    self.readings.push((
                        t,
                        Reading::MissionCurrent {
                            seq: now.0,
                            total: now.1,
                            state,
                        },
                    ));
                }
                let reached = seq_reached.and_then(|f| f.f64(d)).map(|r| r as i64);
                if let Some(r) = reached {
                    if self.seq_reached != Some(r) {
                        self.seq_reached = Some(r);
                        if let Ok(seq) = u16::try_from(r) {
                            self.readings.push((t, Reading::ItemReached { seq }));
                        }
                    }
                }
            }
            Decoder::Status {
                timestamp,
                arming_state,
                nav_state,
            } if instance == 0 => {
                let (Some(t), Some(arming), Some(nav)) =
                    (timestamp.u64(d), arming_state.f64(d), nav_state.f64(d))
                else {
                    return;
                };
                let nav = nav as u8;
                let armed = arming as u8 == 2;
                self.nav_state = Some(nav);
                let mode = nav_state_mode(nav);
                let due = match &self.last_heartbeat {
                    Some((last_t, last_armed, last_mode)) => {
                        *last_armed != armed
                            || *last_mode != mode
                            || t.saturating_sub(*last_t) >= HEARTBEAT_PERIOD_US
                    }
                    None => true,
                };
                if due && t > 0 {
                    self.readings.push((
                        t,
                        Reading::Heartbeat {
                            armed,
                            mode: mode.clone(),
                        },
                    ));
                    self.last_heartbeat = Some((t, armed, mode));
                }
                self.landed_changed(t);
            }
            Decoder::Land { timestamp, landed } if instance == 0 => {
                if let (Some(t), Some(landed)) = (timestamp.u64(d), landed.bool(d)) {
                    self.landed = Some(landed);
                    self.landed_changed(t);
                }
            }
            _ => {}
        }
    }

    fn global(&mut self, d: &[u8], timestamp: Field, lat: Field, lon: Field, alt: Field) {
        let (Some(t), Some(lat), Some(lon), Some(alt)) =
            (timestamp.u64(d), lat.f64(d), lon.f64(d), alt.f64(d))
        else {
            return;
        };
        let Some((vt, [vn, ve, vd], z)) = self.velocity else {
            return;
        };
        if t.abs_diff(vt) > VELOCITY_MAX_AGE_US
            || !(lat.is_finite() && lon.is_finite() && alt.is_finite())
            || (lat == 0.0 && lon == 0.0)
        {
            return;
        }
        let relative_alt_m = match (self.home_alt_m, z) {
            (Some(home), _) => alt - home,
            (None, Some(z)) => -z,
            (None, None) => return,
        };
        self.readings.push((
            t,
            Reading::Position(Position {
                time_boot_ms: u32::try_from(t / 1000).unwrap_or(u32::MAX),
                lat_deg: lat,
                lon_deg: lon,
                alt_amsl_m: alt,
                relative_alt_m,
                vn_m_s: vn,
                ve_m_s: ve,
                vd_m_s: vd,
            }),
        ));
    }

    /// EXTENDED_SYS_STATE's landed state as PX4 derives it: on the ground when landed, else
    /// taking off or landing by the navigation state, else in the air.
    fn landed_changed(&mut self, t: u64) {
        let Some(landed) = self.landed else {
            return;
        };
        let state = if landed {
            LandedState::OnGround
        } else {
            match self.nav_state.map(nav_state_mode) {
                Some(FlightMode::Takeoff) => LandedState::Takeoff,
                Some(FlightMode::Land) => LandedState::Landing,
                _ => LandedState::InAir,
            }
        };
        if self.landed_state != Some(state) && t > 0 {
            self.landed_state = Some(state);
            self.readings.push((t, Reading::Landed(state)));
        }
    }

    fn string(&mut self, m: &LoggedStringMessage) {
        if m.timestamp > 0 {
            self.readings.push((
                m.timestamp,
                Reading::StatusText {
                    severity: m.log_level.saturating_sub(b'0').min(7),
                    text: m.logged_message.to_string(),
                },
            ));
        }
    }

    /// The readings in time order, with the battery instance that measures the flight: the
    /// one most often connected with a current (then the most often connected, then the first).
    fn finish(mut self) -> Vec<Stamped> {
        let score = |samples: &Vec<BatterySample>| {
            let with_current = samples
                .iter()
                .filter(|s| s.connected && s.battery.current_a.is_some())
                .count();
            let connected = samples.iter().filter(|s| s.connected).count();
            (with_current, connected)
        };
        let chosen = self
            .batteries
            .iter()
            .enumerate()
            .max_by_key(|(k, (_, samples))| (score(samples), std::cmp::Reverse(*k)))
            .map(|(k, _)| k);
        if let Some(k) = chosen {
            let (_, samples) = self.batteries.swap_remove(k);
            self.readings.extend(
                samples
                    .into_iter()
                    .map(|s| (s.timestamp_us, Reading::Battery(s.battery))),
            );
        }
        self.readings.sort_by_key(|(t, _)| *t);
        let first = self.readings.first().map_or(0, |(t, _)| *t);
        self.readings
            .into_iter()
            .map(|(t, reading)| Stamped {
                t_s: (t - first) as f64 * 1e-6,
                wall_us: t,
                reading,
            })
            .collect()
    }
}

/// A long ULog for benches: `template` (a real log) followed by copies of its data records
/// (data and logged strings) with their timestamps shifted one template span (plus a second)
/// further each time, until the log covers at least `minutes`. Each copy is the template's
/// flight again: a log of several flights one after the other.
pub fn synthetic_long(template: &[u8], minutes: f64) -> Result<Vec<u8>, OnboardError> {
    let file = "the template";
    let malformed = |offset: usize, reason: String| OnboardError::Malformed {
        file: file.to_string(),
        offset: offset as u64,
        reason,
    };
    let header = template
        .get(..HEADER_LEN)
        .filter(|h| h.starts_with(MAGIC))
        .ok_or_else(|| malformed(0, "not a ULog header".into()))?;
    // Each data record's timestamp offset (within the record's payload), and the span.
    let stamps = RefCell::new((Vec::<Option<usize>>::new(), u64::MAX, 0u64));
    let mut on_data = |m: &DataMessage| {
        let mut s = stamps.borrow_mut();
        let offset = m
            .flattened_format
            .timestamp_field
            .as_ref()
            .map(|f| usize::from(f.offset));
        let id = usize::from(m.msg_id);
        if s.0.len() <= id {
            s.0.resize(id + 1, None);
        }
        if let Some(slot) = s.0.get_mut(id) {
            *slot = offset;
        }
        let t = offset
            .and_then(|o| m.data.get(o..o + 8))
            .and_then(|b| b.try_into().ok())
            .map(u64::from_le_bytes)
            .filter(|&t| t > 0);
        if let Some(t) = t {
            s.1 = s.1.min(t);
            s.2 = s.2.max(t);
        }
    };
    let mut parser = LogParser::default();
    parser.set_data_message_callback(&mut on_data);
    parser
        .consume_bytes(header)
        .map_err(|e| malformed(0, crate_reason(&e.description)))?;
    let mut walk = Walk::new(template);
    let mut records = Vec::new();
    let mut end = HEADER_LEN;
    while let Some(Ok((offset, kind, record))) = walk.next_record() {
        check_record(kind, record.get(RECORD_HEADER_LEN..).unwrap_or(&[]))
            .map_err(|problem| problem.to_string())
            .and_then(|()| {
                parser
                    .consume_bytes(record)
                    .map_err(|e| crate_reason(&e.description))
            })
            .map_err(|reason| malformed(offset, reason))?;
        if kind == b'B' {
            walk.set_appended(parser.appended_offsets());
        }
        if matches!(kind, b'D' | b'L' | b'C') {
            records.push((kind, record));
        }
        end = offset + record.len();
    }
    drop(parser);
    let (stamp_offsets, first, last) = stamps.into_inner();
    if first >= last {
        return Err(malformed(
            end,
            "the template has no timestamped data".into(),
        ));
    }
    let period_us = last - first + 1_000_000;
    let wanted_us = (minutes.max(0.0) * 60e6) as u64;
    let mut out = template.get(..end).unwrap_or(template).to_vec();
    let mut shift = period_us;
    while shift <= wanted_us {
        for &(kind, record) in &records {
            let at = out.len();
            out.extend_from_slice(record);
            let stamp_at = match kind {
                b'D' => record
                    .get(RECORD_HEADER_LEN..RECORD_HEADER_LEN + 2)
                    .map(|id| usize::from(u16::from_le_bytes([id[0], id[1]])))
                    .and_then(|id| stamp_offsets.get(id).copied().flatten()),
                b'L' => Some(1),
                _ => Some(3),
            };
            let Some(stamp) = stamp_at.map(|o| at + RECORD_HEADER_LEN + o) else {
                continue;
            };
            if let Some(bytes) = out.get_mut(stamp..stamp + 8) {
                let t = u64::from_le_bytes(bytes.try_into().unwrap_or([0; 8]));
                if t > 0 {
                    bytes.copy_from_slice(&t.saturating_add(shift).to_le_bytes());
                }
            }
        }
        shift += period_us;
    }
    Ok(out)
}
