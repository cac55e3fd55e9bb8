//! The raw MAVLink stream as a `.tlog`, the format QGroundControl and MAVProxy write and
//! pymavlink's `mavutil.mavlink_connection` and MAVExplorer read: per frame an 8-byte big-endian
//! unix-epoch timestamp in microseconds, then the frame's bytes exactly as they went over the link.
//!
//! The writer appends through a buffer; the recorder decides when to flush and fsync. The reader
//! knows only the frame layout (start byte, payload length, incompatibility flags; not message
//! types): it yields every complete record, treats a torn last record (a crash or power cut in the
//! middle of a write) as the end of the file, and reports anything else that is not a frame with
//! the file and byte offset.

use std::fs::File;
use std::io::{BufReader, ErrorKind, Read};
use std::path::Path;

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

/// The total length of the frame whose first three bytes are `head`, or why it is not a frame.
pub fn frame_len(head: [u8; 3]) -> Result<usize, String> {
    let payload = usize::from(head[1]);
    match head[0] {
        STX_V1 => Ok(1 + 5 + payload + 2),
        STX_V2 => {
            let flags = head[2];
            if flags & !(IFLAG_SIGNED | IFLAG_SYSID32) != 0 {
                return Err(format!(
                    "unknown MAVLink 2 incompatibility flags {flags:#04x}"
                ));
            }
            let header = if flags & IFLAG_SYSID32 != 0 { 12 } else { 9 };
            let signature = if flags & IFLAG_SIGNED != 0 { 13 } else { 0 };
            Ok(1 + header + payload + 2 + signature)
        }
        other => Err(format!("byte {other:#04x} is not a MAVLink start byte")),
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

/// Streams the records of a .tlog. Yields `Err` once for a record that is not a frame and then
/// stops; a torn last record ends the iteration and is reported by [`TlogReader::torn_tail`].
pub struct TlogReader<R> {
    file: String,
    input: R,
    offset: u64,
    torn_tail: Option<u64>,
    done: bool,
}

impl TlogReader<BufReader<File>> {
    /// Opens a .tlog file.
    pub fn open(path: &Path) -> Result<Self, FlightLogError> {
        let file = File::open(path).map_err(io_error(path))?;
        Ok(TlogReader::new(
            &path.display().to_string(),
            BufReader::with_capacity(64 * 1024, file),
        ))
    }
}

/// Reads until `buf` is full or the input ends; returns the bytes read.
fn read_full<R: Read>(input: &mut R, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match input.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

impl<R: Read> TlogReader<R> {
    /// Reads records from `input`; `file` names it in errors.
    pub fn new(file: &str, input: R) -> TlogReader<R> {
        TlogReader {
            file: file.to_string(),
            input,
            offset: 0,
            torn_tail: None,
            done: false,
        }
    }

    /// The byte offset where an incomplete last record starts, if the file ends inside one.
    pub fn torn_tail(&self) -> Option<u64> {
        self.torn_tail
    }

    /// Bytes consumed so far (the offset of the next record).
    pub fn offset(&self) -> u64 {
        self.offset
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

    fn torn(&mut self, read: usize) -> Option<Result<TlogRecord, FlightLogError>> {
        self.done = true;
        if read > 0 {
            self.torn_tail = Some(self.offset);
        }
        None
    }
}

impl<R: Read> Iterator for TlogReader<R> {
    type Item = Result<TlogRecord, FlightLogError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let start = self.offset;
        let mut head = [0u8; 11];
        let got = match read_full(&mut self.input, &mut head) {
            Ok(n) => n,
            Err(e) => return self.failed(e),
        };
        if got < head.len() {
            return self.torn(got);
        }
        let mut stamp = [0u8; 8];
        stamp.copy_from_slice(&head[..8]);
        let wall_us = u64::from_be_bytes(stamp);
        let len = match frame_len([head[8], head[9], head[10]]) {
            Ok(len) => len,
            Err(reason) => return self.corrupt(start + 8, reason),
        };
        let mut frame = vec![0u8; len];
        frame[..3].copy_from_slice(&head[8..]);
        let rest = match read_full(&mut self.input, &mut frame[3..]) {
            Ok(n) => n,
            Err(e) => return self.failed(e),
        };
        if rest < len - 3 {
            return self.torn(got + rest);
        }
        self.offset = start + 8 + len as u64;
        Some(Ok(TlogRecord {
            offset: start,
            wall_us,
            frame,
        }))
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
