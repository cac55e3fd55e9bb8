//! The raw MAVLink stream as a `.tlog`, the format QGroundControl and MAVProxy write and
//! pymavlink's `mavutil.mavlink_connection` and MAVExplorer read: per frame an 8-byte big-endian
//! unix-epoch timestamp in microseconds, then the frame's bytes exactly as they went over the link.
//!
//! The writer appends through a buffer; the recorder decides when to flush and fsync. The reader
//! knows only the frame layout (start byte, payload length, incompatibility flags; not message
//! types): it yields every complete record and treats a torn last record (a crash or power cut in
//! the middle of a write) as the end of the file. Anything else that is not a frame is, read
//! strictly (resuming a log to append to it), an error with the file and byte offset; read to
//! replay, a gap: with a frame checker from the dialect (`link::telemetry::check_frame`: the
//! checksum with the message's CRC_EXTRA) the reader skips to the next record that checks and
//! follows in time, and keeps each gap's offset, length and the times either side of it.

use std::fs::File;
use std::io::{ErrorKind, Read};
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{io_error, AppendFile, FlightLogError};

/// MAVLink 1 start byte.
const STX_V1: u8 = 0xFE;
/// MAVLink 2 start byte.
const STX_V2: u8 = 0xFD;
/// MAVLink 2 incompatibility flag: the frame carries a 13-byte signature.
const IFLAG_SIGNED: u8 = 0x01;
/// rust-mavlink's extension: a 4-byte system id (3 more header bytes).
const IFLAG_SYSID32: u8 = 0x02;
/// Largest frame: MAVLink 2 with the widest header, 255 bytes of payload and a signature.
pub const MAX_FRAME_LEN: usize = 1 + 12 + 255 + 2 + 13;

/// Why three bytes do not begin a MAVLink frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum NotAFrame {
    #[error("unknown MAVLink 2 incompatibility flags {0:#04x}")]
    Flags(u8),
    #[error("byte {0:#04x} is not a MAVLink start byte")]
    Start(u8),
}

/// The total length of the frame whose first three bytes are `head`, or why it is not a frame.
pub fn frame_len(head: [u8; 3]) -> Result<usize, NotAFrame> {
    let payload = usize::from(head[1]);
    match head[0] {
        STX_V1 => Ok(1 + 5 + payload + 2),
        STX_V2 => {
            let flags = head[2];
            if flags & !(IFLAG_SIGNED | IFLAG_SYSID32) != 0 {
                return Err(NotAFrame::Flags(flags));
            }
            let header = if flags & IFLAG_SYSID32 != 0 { 12 } else { 9 };
            let signature = if flags & IFLAG_SIGNED != 0 { 13 } else { 0 };
            Ok(1 + header + payload + 2 + signature)
        }
        other => Err(NotAFrame::Start(other)),
    }
}

/// Appends records to a .tlog.
#[derive(Debug)]
pub struct TlogWriter {
    file: AppendFile,
    records: u64,
}

impl TlogWriter {
    /// Creates `path` (it must not exist: a flight's log is never overwritten).
    pub fn create(path: &Path) -> Result<TlogWriter, FlightLogError> {
        Ok(TlogWriter {
            file: AppendFile::create(path)?,
            records: 0,
        })
    }

    /// Opens an existing .tlog to go on appending to it (a flight resumed after a crash): a
    /// torn last record is cut off first, so that what follows reads. Returns the writer (its
    /// count includes the records kept) and the records kept. A log with anything but a torn
    /// tail wrong in it is refused (appending after a corrupt record would hide the new ones
    /// from every reader).
    pub fn resume(path: &Path) -> Result<(TlogWriter, Tlog), FlightLogError> {
        let log = read_tlog(path)?;
        let keep = log.torn_tail.unwrap_or_else(|| {
            log.records
                .last()
                .map_or(0, |r| r.offset + 8 + r.frame.len() as u64)
        });
        let writer = TlogWriter {
            file: AppendFile::reopen(path, keep)?,
            records: log.records.len() as u64,
        };
        Ok((writer, log))
    }

    pub fn path(&self) -> &Path {
        self.file.path()
    }

    /// Records appended so far.
    pub fn records(&self) -> u64 {
        self.records
    }

    /// Appends one frame received (or sent) at `wall_us`, unix microseconds.
    pub fn append(&mut self, wall_us: u64, frame: &[u8]) -> Result<(), FlightLogError> {
        self.file.write(&wall_us.to_be_bytes())?;
        self.file.write(frame)?;
        self.records += 1;
        Ok(())
    }

    /// Whether a record of `frame_len` bytes fits in the buffer without it spilling.
    pub fn has_room(&self, frame_len: usize) -> bool {
        self.file.has_room(8 + frame_len)
    }

    /// Hands buffered records to the operating system (survives a crash of this process).
    pub fn flush(&mut self) -> Result<(), FlightLogError> {
        self.file.flush()
    }

    /// Flushes and asks the OS to put the data on disk (survives a power cut).
    pub fn sync(&mut self) -> Result<(), FlightLogError> {
        self.file.sync()
    }
}

/// One record of a .tlog.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TlogRecord {
    /// Byte offset of the record's timestamp in the file.
    pub offset: u64,
    /// Unix microseconds.
    pub wall_us: u64,
    pub frame: Vec<u8>,
}

/// What the dialect makes of a whole frame's checksum. The reader knows frame layouts, not
/// message types: `link::telemetry::check_frame` judges with the dialect's CRC_EXTRA.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameCheck {
    /// A message id the dialect knows, and its checksum holds.
    Valid,
    /// A message id the dialect knows, and its checksum does not hold.
    BadCrc,
    /// A message id the dialect does not know: the checksum cannot be checked.
    UnknownMessage,
}

/// Judges a whole frame (start byte to signature).
pub type FrameChecker = fn(&[u8]) -> FrameCheck;

/// A span of a .tlog that is not records, skipped by a resynchronising reader.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TlogGap {
    /// Byte offset where the span begins: the first record that did not check.
    pub offset: u64,
    /// Bytes skipped: the next record begins at `offset + bytes`, or the file ends there.
    pub bytes: u64,
    /// Vehicle time of the last reading before the span and of the first after it, once the
    /// log has been replayed (the reader knows none); None: no reading on that side.
    pub from_s: Option<f64>,
    pub to_s: Option<f64>,
    /// Unix microseconds of the last record before the span and of the first after it.
    pub from_wall_us: Option<u64>,
    pub to_wall_us: Option<u64>,
}

/// How far a record's wall time may go back from the record before it (a clock stepped back)
/// and still be the next record: records are written in the order they arrive.
const STAMP_BACK_US: u64 = 60_000_000;
/// How far forward: a day, far beyond any pause in one flight's log, and a window that 1 in
/// 2e8 random 8-byte timestamps falls into.
const STAMP_FORWARD_US: u64 = 86_400_000_000;
/// Bytes read from the file at a time.
const CHUNK: usize = 64 * 1024;

/// Whether a record stamped `wall_us` may follow one stamped `last_us`.
fn plausible_after(last_us: u64, wall_us: u64) -> bool {
    wall_us.saturating_add(STAMP_BACK_US) >= last_us
        && wall_us <= last_us.saturating_add(STAMP_FORWARD_US)
}

/// What the bytes at the reader's position are.
enum Verdict {
    /// A record of this many bytes (timestamp and frame).
    Record(usize),
    /// A record the file ends inside.
    Torn,
    /// Not a record.
    Bad,
}

/// Streams the records of a .tlog, a chunk at a time (memory does not grow with the file).
///
/// Strict (as [`TlogReader::new`] and [`TlogReader::open`] make it): yields `Err` once for a
/// record that is not a frame and then stops; a torn last record ends the iteration and is
/// reported by [`TlogReader::torn_tail`].
///
/// Resynchronising ([`TlogReader::resynchronising`]): every frame is also judged by the dialect
/// and a record must follow the one before it in time (back at most 60 s, forward at most a
/// day); a frame of a message the dialect does not know must also be followed by a record. A
/// record that does not pass begins a gap: the reader scans on, a byte at a time, to the next
/// record whose frame checks and whose time follows, or (a frame of an unknown message, or
/// after a jump of the clock) the next two records that follow each other and of which one
/// checks. Each gap is kept ([`TlogReader::gaps`]) and the records after it are yielded. A file
/// without one record is an error naming its length.
pub struct TlogReader<R> {
    file: String,
    input: R,
    /// Bytes read and not consumed: `buf[pos..]`, the first at file offset `offset`.
    buf: Vec<u8>,
    pos: usize,
    offset: u64,
    eof: bool,
    torn_tail: Option<u64>,
    done: bool,
    check: Option<FrameChecker>,
    gaps: Vec<TlogGap>,
    /// Where the span being skipped began.
    gap_start: Option<u64>,
    last_wall_us: Option<u64>,
    records: u64,
}

impl TlogReader<File> {
    /// Opens a .tlog file.
    pub fn open(path: &Path) -> Result<Self, FlightLogError> {
        let file = File::open(path).map_err(io_error(path))?;
        Ok(TlogReader::new(&path.display().to_string(), file))
    }
}

impl<R: Read> TlogReader<R> {
    /// Reads records from `input`; `file` names it in errors.
    pub fn new(file: &str, input: R) -> TlogReader<R> {
        TlogReader {
            file: file.to_string(),
            input,
            buf: Vec::with_capacity(CHUNK),
            pos: 0,
            offset: 0,
            eof: false,
            torn_tail: None,
            done: false,
            check: None,
            gaps: Vec::new(),
            gap_start: None,
            last_wall_us: None,
            records: 0,
        }
    }

    /// Skips what is not records instead of stopping there, judging frames with `check`.
    pub fn resynchronising(mut self, check: FrameChecker) -> TlogReader<R> {
        self.check = Some(check);
        self
    }

    /// The byte offset where an incomplete last record starts, if the file ends inside one.
    pub fn torn_tail(&self) -> Option<u64> {
        self.torn_tail
    }

    /// Bytes consumed so far (the offset of the next record).
    pub fn offset(&self) -> u64 {
        self.offset
    }

    /// The spans skipped so far (resynchronising), in file order.
    pub fn gaps(&self) -> &[TlogGap] {
        &self.gaps
    }

    /// Reads until `n` bytes are buffered past the position or the input ends; returns how
    /// many of the `n` are there.
    fn fill(&mut self, n: usize) -> std::io::Result<usize> {
        while self.buf.len() - self.pos < n && !self.eof {
            if self.pos > 0 && self.pos >= self.buf.len() / 2 {
                self.buf.drain(..self.pos);
                self.pos = 0;
            }
            let old = self.buf.len();
            self.buf.resize(old + CHUNK, 0);
            let got = loop {
                match self.input.read(&mut self.buf[old..]) {
                    Err(e) if e.kind() == ErrorKind::Interrupted => {}
                    other => break other,
                }
            };
            self.buf.truncate(old + got.as_ref().map_or(0, |n| *n));
            if got? == 0 {
                self.eof = true;
            }
        }
        Ok((self.buf.len() - self.pos).min(n))
    }

    /// The timestamp and total length (timestamp and frame) of the record `at` bytes past the
    /// position, whose first 11 bytes must be buffered.
    fn head(&self, at: usize) -> Result<(u64, usize), NotAFrame> {
        let b = &self.buf[self.pos + at..self.pos + at + 11];
        let mut stamp = [0u8; 8];
        stamp.copy_from_slice(&b[..8]);
        let len = frame_len([b[8], b[9], b[10]])?;
        Ok((u64::from_be_bytes(stamp), 8 + len))
    }

    /// The frame of the record of `total` bytes `at` bytes past the position (buffered).
    fn frame(&self, at: usize, total: usize) -> &[u8] {
        &self.buf[self.pos + at + 8..self.pos + at + total]
    }

    fn corrupt(
        &mut self,
        offset: u64,
        reason: String,
    ) -> Option<Result<TlogRecord, FlightLogError>> {
        self.done = true;
        Some(Err(FlightLogError::Corrupt {
            file: self.file.clone(),
            offset,
            reason,
        }))
    }

    fn failed(&mut self, source: std::io::Error) -> Option<Result<TlogRecord, FlightLogError>> {
        self.done = true;
        Some(Err(FlightLogError::Io {
            file: self.file.clone(),
            source,
        }))
    }

    /// The record of `total` bytes at the position, consumed; a gap open ends before it.
    fn take(&mut self, wall_us: u64, total: usize) -> TlogRecord {
        let record = TlogRecord {
            offset: self.offset,
            wall_us,
            frame: self.frame(0, total).to_vec(),
        };
        if let Some(start) = self.gap_start.take() {
            self.gaps.push(TlogGap {
                offset: start,
                bytes: self.offset - start,
                from_s: None,
                to_s: None,
                from_wall_us: self.last_wall_us,
                to_wall_us: Some(wall_us),
            });
        }
        self.last_wall_us = Some(wall_us);
        self.records += 1;
        self.pos += total;
        self.offset += total as u64;
        record
    }

    /// The end of the input, what is left of it buffered: a gap open runs to the end, else a
    /// remainder is a torn record. Resynchronising, a file without a record is an error.
    fn end(&mut self) -> Option<Result<TlogRecord, FlightLogError>> {
        self.done = true;
        let rest = (self.buf.len() - self.pos) as u64;
        if let Some(start) = self.gap_start.take() {
            self.gaps.push(TlogGap {
                offset: start,
                bytes: self.offset + rest - start,
                from_s: None,
                to_s: None,
                from_wall_us: self.last_wall_us,
                to_wall_us: None,
            });
        } else if rest > 0 {
            self.torn_tail = Some(self.offset);
        }
        if self.check.is_some() && self.records == 0 {
            return Some(Err(FlightLogError::NoFrame {
                file: self.file.clone(),
                bytes: self.offset + rest,
            }));
        }
        None
    }

    /// Whether the record of `total` bytes at the position (judged `first`, stamped
    /// `wall_us`) is confirmed by the record after it: a frame that does not fail its check
    /// and follows in time, and with `one_valid`, one of the two frames checking. The end of
    /// the file (or a torn record there) confirms a frame that checks, and without `one_valid`
    /// any frame.
    fn confirmed_by_next(
        &mut self,
        check: FrameChecker,
        first: FrameCheck,
        wall_us: u64,
        total: usize,
        one_valid: bool,
    ) -> std::io::Result<bool> {
        let at_end = first == FrameCheck::Valid || !one_valid;
        if self.fill(total + 11)? < total + 11 {
            return Ok(at_end);
        }
        let Ok((next_us, next_total)) = self.head(total) else {
            return Ok(false);
        };
        if !plausible_after(wall_us, next_us) {
            return Ok(false);
        }
        if self.fill(total + next_total)? < total + next_total {
            return Ok(at_end);
        }
        let second = check(self.frame(total, next_total));
        Ok(second != FrameCheck::BadCrc
            && (!one_valid || first == FrameCheck::Valid || second == FrameCheck::Valid))
    }

    /// Judges the bytes at the position (11 of them buffered) as a record. In step (not
    /// skipping a gap, after a record): a frame that checks and follows in time, or one of an
    /// unknown message that follows and is followed by a record. Else (the first record, an
    /// anchor to go on from after a gap, or after a jump of the clock): a frame that checks and
    /// follows the last record, or two records that follow each other, one of them checking.
    fn judge(&mut self, check: FrameChecker) -> std::io::Result<Verdict> {
        let skipping = self.gap_start.is_some();
        if !matches!(self.buf[self.pos + 8], STX_V1 | STX_V2) {
            return Ok(Verdict::Bad);
        }
        let Ok((wall_us, total)) = self.head(0) else {
            return Ok(Verdict::Bad);
        };
        if self.fill(total)? < total {
            return Ok(if skipping {
                Verdict::Bad
            } else {
                Verdict::Torn
            });
        }
        let judged = check(self.frame(0, total));
        if judged == FrameCheck::BadCrc {
            return Ok(Verdict::Bad);
        }
        let follows = self
            .last_wall_us
            .is_some_and(|last| plausible_after(last, wall_us));
        let record = if follows && judged == FrameCheck::Valid {
            true
        } else if follows && !skipping {
            self.confirmed_by_next(check, judged, wall_us, total, false)?
        } else {
            self.confirmed_by_next(check, judged, wall_us, total, true)?
        };
        Ok(if record {
            Verdict::Record(total)
        } else {
            Verdict::Bad
        })
    }

    fn next_strict(&mut self) -> Option<Result<TlogRecord, FlightLogError>> {
        let got = match self.fill(11) {
            Ok(n) => n,
            Err(e) => return self.failed(e),
        };
        if got < 11 {
            return self.end();
        }
        let (wall_us, total) = match self.head(0) {
            Ok(head) => head,
            Err(reason) => return self.corrupt(self.offset + 8, reason.to_string()),
        };
        match self.fill(total) {
            Ok(n) if n < total => self.end(),
            Ok(_) => Some(Ok(self.take(wall_us, total))),
            Err(e) => self.failed(e),
        }
    }

    fn next_resynchronising(
        &mut self,
        check: FrameChecker,
    ) -> Option<Result<TlogRecord, FlightLogError>> {
        loop {
            let got = match self.fill(11) {
                Ok(n) => n,
                Err(e) => return self.failed(e),
            };
            if got < 11 {
                return self.end();
            }
            match self.judge(check) {
                Ok(Verdict::Record(total)) => {
                    let wall_us = self.head(0).map_or(0, |h| h.0);
                    return Some(Ok(self.take(wall_us, total)));
                }
                Ok(Verdict::Torn) => return self.end(),
                Ok(Verdict::Bad) => {
                    self.gap_start.get_or_insert(self.offset);
                    self.pos += 1;
                    self.offset += 1;
                }
                Err(e) => return self.failed(e),
            }
        }
    }
}

impl<R: Read> Iterator for TlogReader<R> {
    type Item = Result<TlogRecord, FlightLogError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        match self.check {
            Some(check) => self.next_resynchronising(check),
            None => self.next_strict(),
        }
    }
}

/// A whole .tlog read into memory.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Tlog {
    pub records: Vec<TlogRecord>,
    /// Offset of a torn last record (skipped), if any.
    pub torn_tail: Option<u64>,
}

/// Reads every complete record of a .tlog; a torn last record is skipped (and noted), anything
/// else that is not a frame is an error naming the file and offset.
pub fn read_tlog(path: &Path) -> Result<Tlog, FlightLogError> {
    let mut reader = TlogReader::open(path)?;
    let records = reader.by_ref().collect::<Result<Vec<_>, _>>()?;
    Ok(Tlog {
        records,
        torn_tail: reader.torn_tail(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reads the tlog at `path`, checks it whole and holding exactly `records`.
    fn read_whole(path: &Path, records: &[(u64, Vec<u8>)]) -> Tlog {
        let log = read_tlog(path).expect("read");
        assert_eq!(log.torn_tail, None);
        let back: Vec<(u64, Vec<u8>)> = log
            .records
            .iter()
            .map(|r| (r.wall_us, r.frame.clone()))
            .collect();
        assert_eq!(back, records);
        log
    }

    /// A MAVLink 2 frame of `payload` bytes (the reader does not check CRCs or ids).
    fn frame_v2(payload: u8, signed: bool, fill: u8) -> Vec<u8> {
        let flags = if signed { IFLAG_SIGNED } else { 0 };
        let mut f = vec![STX_V2, payload, flags, 0, 7, 1, 1, 147, 0, 0];
        f.extend(std::iter::repeat_n(fill, usize::from(payload) + 2));
        if signed {
            f.extend([9u8; 13]);
        }
        f
    }

    fn frame_v1(payload: u8) -> Vec<u8> {
        let mut f = vec![STX_V1, payload, 3, 1, 1, 0];
        f.extend(std::iter::repeat_n(0xAB, usize::from(payload) + 2));
        f
    }

    fn sample_bytes() -> (Vec<u8>, Vec<(u64, Vec<u8>)>) {
        let records = vec![
            (1_000_000u64, frame_v2(36, false, 1)),
            (1_100_000, frame_v1(9)),
            (1_200_000, frame_v2(28, true, 2)),
            (1_300_000, frame_v2(0, false, 3)),
        ];
        let mut bytes = Vec::new();
        for (t, f) in &records {
            bytes.extend(t.to_be_bytes());
            bytes.extend(f);
        }
        (bytes, records)
    }

    #[test]
    fn frame_lengths_follow_the_mavlink_1_and_2_layouts() {
        assert_eq!(frame_len([STX_V1, 9, 0]), Ok(17));
        assert_eq!(frame_len([STX_V2, 36, 0]), Ok(48));
        assert_eq!(frame_len([STX_V2, 36, IFLAG_SIGNED]), Ok(61));
        assert_eq!(frame_len([STX_V2, 36, IFLAG_SYSID32]), Ok(51));
        assert!(frame_len([STX_V2, 36, 0x80]).is_err());
        assert!(frame_len([0x55, 36, 0]).is_err());
    }

    #[test]
    fn written_records_read_back_exactly() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("flight.tlog");
        let (_, records) = sample_bytes();
        let mut w = TlogWriter::create(&path).expect("created");
        for (t, f) in &records {
            w.append(*t, f).expect("appended");
        }
        w.sync().expect("synced");
        assert_eq!(w.records(), 4);
        let log = read_whole(&path, &records);
        assert_eq!(log.records[1].offset, 8 + 48);
    }

    #[test]
    fn a_log_cut_at_any_byte_reads_every_record_before_the_cut() {
        let (bytes, records) = sample_bytes();
        let mut ends = Vec::new();
        let mut end = 0;
        for (_, f) in &records {
            end += 8 + f.len();
            ends.push(end);
        }
        for cut in 0..=bytes.len() {
            let mut reader = TlogReader::new("cut.tlog", &bytes[..cut]);
            let got: Vec<TlogRecord> = reader
                .by_ref()
                .collect::<Result<_, _>>()
                .unwrap_or_else(|e| panic!("cut at {cut}: {e}"));
            let whole = ends.iter().filter(|&&e| e <= cut).count();
            assert_eq!(got.len(), whole, "cut at {cut}");
            for (r, (t, f)) in got.iter().zip(&records) {
                assert_eq!((&r.wall_us, &r.frame), (t, f));
            }
            let expect_torn = !ends.contains(&cut) && cut != 0;
            assert_eq!(reader.torn_tail().is_some(), expect_torn, "cut at {cut}");
        }
    }

    #[test]
    fn garbage_in_the_middle_is_an_error_naming_the_file_and_offset() {
        let (mut bytes, _) = sample_bytes();
        // The second record's start byte.
        let at = 8 + 48 + 8;
        bytes[at] = 0x42;
        let result: Result<Vec<_>, _> = TlogReader::new("bad.tlog", &bytes[..]).collect();
        let err = result.expect_err("corrupt");
        let text = err.to_string();
        assert!(
            text.contains("bad.tlog") && text.contains(&format!("byte {at}")),
            "{text}"
        );
    }

    /// MAVLink's checksum, CRC-16/MCRF4XX (mavlink.io, "Serialization: checksum"), for the
    /// test dialect's frames.
    fn mcrf4xx(bytes: &[u8]) -> u16 {
        let mut crc: u16 = 0xFFFF;
        for &b in bytes {
            let mut tmp = b ^ (crc & 0xFF) as u8;
            tmp ^= tmp << 4;
            let tmp = u16::from(tmp);
            crc = (crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4);
        }
        crc
    }

    /// The test dialect: message ids below 100, CRC_EXTRA 7 id + 3.
    fn extra(id: u32) -> Option<u8> {
        (id < 100).then(|| (id * 7 + 3) as u8)
    }

    /// Judges a MAVLink 2 frame (unsigned, 8-bit system id) in the test dialect.
    fn check_test(frame: &[u8]) -> FrameCheck {
        if frame[0] != STX_V2 || frame[2] != 0 {
            return FrameCheck::BadCrc;
        }
        let id = u32::from_le_bytes([frame[7], frame[8], frame[9], 0]);
        let Some(extra) = extra(id) else {
            return FrameCheck::UnknownMessage;
        };
        let end = 10 + usize::from(frame[1]);
        let mut covered = frame[1..end].to_vec();
        covered.push(extra);
        if frame[end..end + 2] == mcrf4xx(&covered).to_le_bytes() {
            FrameCheck::Valid
        } else {
            FrameCheck::BadCrc
        }
    }

    /// A MAVLink 2 frame of message `id` whose checksum holds in the test dialect.
    fn frame_checked(id: u32, seq: u8, payload: &[u8]) -> Vec<u8> {
        let [a, b, c, _] = id.to_le_bytes();
        let mut f = vec![STX_V2, payload.len() as u8, 0, 0, seq, 1, 1, a, b, c];
        f.extend(payload);
        let mut covered = f[1..].to_vec();
        covered.push(extra(id).unwrap_or(0));
        f.extend(mcrf4xx(&covered).to_le_bytes());
        f
    }

    /// (wall time, frame) of each record.
    type Records = Vec<(u64, Vec<u8>)>;

    /// `n` records at 10 Hz of checked frames of varied ids and lengths: the log, its records
    /// and their offsets.
    fn checked_log(n: u64) -> (Vec<u8>, Records, Vec<usize>) {
        let mut bytes = Vec::new();
        let mut records = Vec::new();
        let mut offsets = Vec::new();
        for k in 0..n {
            let id = (k * 13 % 97) as u32;
            let payload: Vec<u8> = (0..(k * 5 % 40 + 1)).map(|i| (i * k) as u8).collect();
            let t = 1_700_000_000_000_000 + k * 100_000;
            let f = frame_checked(id, k as u8, &payload);
            offsets.push(bytes.len());
            bytes.extend(t.to_be_bytes());
            bytes.extend(&f);
            records.push((t, f));
        }
        (bytes, records, offsets)
    }

    /// `n` bytes of noise from `seed` (the project's own generator).
    fn noise(n: usize, seed: u64) -> Vec<u8> {
        let mut rng = crate::rng::Rng::new(seed);
        (0..n).map(|_| (rng.next_u64() >> 24) as u8).collect()
    }

    fn read_resynchronising(bytes: &[u8]) -> (Vec<TlogRecord>, Vec<TlogGap>, Option<u64>) {
        let mut reader = TlogReader::new("gap.tlog", bytes).resynchronising(check_test);
        let got = reader
            .by_ref()
            .collect::<Result<Vec<_>, _>>()
            .expect("reads");
        (got, reader.gaps().to_vec(), reader.torn_tail())
    }

    #[test]
    fn a_clean_log_read_resynchronising_gives_every_record_and_no_gap() {
        let (mut bytes, records, _) = checked_log(40);
        // A frame of a message the dialect does not know, in time: kept.
        let unknown = frame_checked(4000, 0, &[1, 2, 3]);
        bytes.extend(1_700_000_004_000_000u64.to_be_bytes());
        bytes.extend(&unknown);
        let (got, gaps, torn) = read_resynchronising(&bytes);
        assert_eq!(got.len(), 41);
        for (r, (t, f)) in got.iter().zip(&records) {
            assert_eq!((&r.wall_us, &r.frame), (t, f));
        }
        assert_eq!(got[40].frame, unknown);
        assert!(gaps.is_empty(), "{gaps:?}");
        assert_eq!(torn, None);
        // A torn last record is still a torn tail, not a gap.
        let (got, gaps, torn) = read_resynchronising(&bytes[..bytes.len() - 3]);
        assert_eq!((got.len(), gaps.len()), (40, 0));
        assert_eq!(torn, Some(got[39].offset + 8 + got[39].frame.len() as u64));
    }

    #[test]
    fn garbage_inserted_mid_log_is_skipped_and_every_record_after_it_read() {
        let (clean, records, offsets) = checked_log(60);
        let at = offsets[30];
        let mut bytes = clean[..at].to_vec();
        bytes.extend(noise(100, 7));
        bytes.extend(&clean[at..]);
        let (got, gaps, torn) = read_resynchronising(&bytes);
        assert_eq!(torn, None);
        let back: Vec<(u64, Vec<u8>)> = got.iter().map(|r| (r.wall_us, r.frame.clone())).collect();
        assert_eq!(back, records);
        assert_eq!(got[30].offset, at as u64 + 100);
        assert_eq!(
            gaps,
            vec![TlogGap {
                offset: at as u64,
                bytes: 100,
                from_s: None,
                to_s: None,
                from_wall_us: Some(records[29].0),
                to_wall_us: Some(records[30].0),
            }]
        );
        // The strict reader stops at the garbage.
        let strict: Result<Vec<_>, _> = TlogReader::new("gap.tlog", &bytes[..]).collect();
        assert!(strict.is_err());
    }

    #[test]
    fn garbage_inserted_inside_a_record_loses_that_record_alone() {
        let (clean, records, offsets) = checked_log(60);
        let at = offsets[30] + 13;
        let mut bytes = clean[..at].to_vec();
        bytes.extend(noise(100, 11));
        bytes.extend(&clean[at..]);
        let (got, gaps, _) = read_resynchronising(&bytes);
        let back: Vec<(u64, Vec<u8>)> = got.iter().map(|r| (r.wall_us, r.frame.clone())).collect();
        let mut expected = records.clone();
        expected.remove(30);
        assert_eq!(back, expected);
        assert_eq!(gaps.len(), 1, "{gaps:?}");
        assert_eq!(gaps[0].offset, offsets[30] as u64);
        assert_eq!(gaps[0].bytes, (offsets[31] - offsets[30]) as u64 + 100);
    }

    #[test]
    fn garbage_to_the_end_is_a_gap_to_the_end() {
        let (mut bytes, _, _) = checked_log(20);
        let at = bytes.len() as u64;
        bytes.extend(noise(5000, 3));
        let (got, gaps, torn) = read_resynchronising(&bytes);
        assert_eq!(got.len(), 20);
        assert_eq!(torn, None);
        assert_eq!(gaps.len(), 1);
        assert_eq!((gaps[0].offset, gaps[0].bytes), (at, 5000));
        assert_eq!(gaps[0].to_wall_us, None);
    }

    #[test]
    fn noise_without_a_frame_is_an_error_naming_the_file_and_its_length() {
        // Noise thick with start bytes: every position is tried and none anchors.
        let mut bytes = noise(300_000, 5);
        for (k, b) in bytes.iter_mut().enumerate() {
            if k % 37 == 0 {
                *b = STX_V2;
            }
        }
        let result: Result<Vec<_>, _> = TlogReader::new("noise.tlog", &bytes[..])
            .resynchronising(check_test)
            .collect();
        let text = result.expect_err("no frame").to_string();
        assert_eq!(text, "noise.tlog: no MAVLink frame found in 300000 bytes");
    }

    #[test]
    fn a_resumed_log_cuts_its_torn_tail_and_reads_old_and_new_records_in_order() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("flight.tlog");
        let (bytes, records) = sample_bytes();
        // Killed in the middle of the third record.
        let cut = 8 + 48 + 8 + 17 + 20;
        std::fs::write(&path, &bytes[..cut]).expect("written");
        let (mut w, kept) = TlogWriter::resume(&path).expect("resumed");
        assert_eq!(kept.records.len(), 2);
        assert_eq!(kept.torn_tail, Some(8 + 48 + 8 + 17));
        assert_eq!(w.records(), 2);
        for (t, f) in &records[2..] {
            w.append(*t, f).expect("appended");
        }
        w.sync().expect("synced");
        read_whole(&path, &records);
    }

    #[test]
    fn a_log_with_garbage_in_the_middle_is_not_resumed() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("flight.tlog");
        let (mut bytes, _) = sample_bytes();
        bytes[8 + 48 + 8] = 0x42;
        std::fs::write(&path, &bytes).expect("written");
        assert!(TlogWriter::resume(&path).is_err());
        assert_eq!(std::fs::read(&path).expect("read"), bytes);
    }

    #[test]
    fn an_existing_log_is_never_overwritten() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("flight.tlog");
        std::fs::write(&path, b"old").expect("written");
        assert!(TlogWriter::create(&path).is_err());
        assert_eq!(std::fs::read(&path).expect("read"), b"old");
    }
}
