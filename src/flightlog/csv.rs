//! samples.csv: one row per battery sample (every BATTERY_STATUS, or SYS_STATUS while it stands in
//! for a missing BATTERY_STATUS) with the vehicle state at that moment, for people and plotting
//! tools. Plain comma-separated values with a header line; empty fields are unknown. The reader
//! skips a torn last line (no newline: the writer was cut off) and names the file, line and column
//! of anything else it cannot read, a number that is not finite and a value no sample can hold
//! (a voltage, current or position out of range) among them.

use std::fmt::Write as _;
use std::path::Path;

use super::samples::PowerSample;
use super::telemetry::{Battery, BatterySource, LandedState, VehicleState};
use super::{io_error, AppendFile, FlightLogError};

/// The columns of samples.csv, in order.
pub const COLUMNS: [&str; 22] = [
    "t_s",
    "wall_us",
    "source",
    "battery_id",
    "component",
    "primary",
    "voltage_v",
    "current_a",
    "power_w",
    "consumed_mah",
    "energy_consumed_j",
    "remaining_pct",
    "fake_current",
    "lat_deg",
    "lon_deg",
    "alt_amsl_m",
    "relative_alt_m",
    "mission_seq",
    "armed",
    "landed",
    "mode",
    "speed_m_s",
];

/// One row: a sample and the vehicle's state when it was taken.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleRow {
    pub sample: PowerSample,
    pub lat_deg: Option<f64>,
    pub lon_deg: Option<f64>,
    pub alt_amsl_m: Option<f64>,
    pub relative_alt_m: Option<f64>,
    pub mission_seq: Option<u16>,
    pub armed: Option<bool>,
    pub landed: Option<LandedState>,
    pub mode: Option<String>,
    pub speed_m_s: Option<f64>,
}

impl SampleRow {
    /// A row from a sample and the state the readings before it left.
    pub fn new(sample: PowerSample, state: &VehicleState) -> SampleRow {
        let p = state.position;
        SampleRow {
            sample,
            lat_deg: p.map(|p| p.lat_deg),
            lon_deg: p.map(|p| p.lon_deg),
            alt_amsl_m: p.map(|p| p.alt_amsl_m),
            relative_alt_m: p.map(|p| p.relative_alt_m),
            mission_seq: state.mission_seq,
            armed: state.armed,
            landed: state.landed,
            mode: state.mode.as_ref().map(|m| m.name().to_string()),
            speed_m_s: p.map(|p| p.speed_m_s()),
        }
    }
}

fn opt(out: &mut String, value: Option<f64>, decimals: usize) {
    out.push(',');
    if let Some(v) = value.filter(|v| v.is_finite()) {
        let _ = write!(out, "{v:.decimals$}");
    }
}

fn flag(out: &mut String, value: Option<bool>) {
    out.push(',');
    if let Some(b) = value {
        out.push(if b { '1' } else { '0' });
    }
}

/// Formats a row as one CSV line (with its newline) into `out`.
pub fn format_row(row: &SampleRow, out: &mut String) {
    let s = &row.sample;
    let b = &s.battery;
    let _ = write!(out, "{:.6},{}", s.t_s, s.wall_us);
    let (id, component) = match b.source {
        BatterySource::BatteryStatus { id, component } => (Some(id), Some(component)),
        BatterySource::SysStatus => (None, None),
    };
    let _ = write!(out, ",{}", b.source.name());
    out.push(',');
    if let Some(id) = id {
        let _ = write!(out, "{id}");
    }
    out.push(',');
    if let Some(c) = component {
        let _ = write!(out, "{c}");
    }
    flag(out, Some(s.primary));
    opt(out, b.voltage_v, 3);
    opt(out, b.current_a, 2);
    opt(out, s.power_w(), 3);
    opt(out, b.consumed_mah, 1);
    opt(out, b.energy_consumed_j, 0);
    opt(out, b.remaining_pct, 0);
    flag(out, Some(b.fake_current));
    opt(out, row.lat_deg, 7);
    opt(out, row.lon_deg, 7);
    opt(out, row.alt_amsl_m, 3);
    opt(out, row.relative_alt_m, 3);
    out.push(',');
    if let Some(seq) = row.mission_seq {
        let _ = write!(out, "{seq}");
    }
    flag(out, row.armed);
    out.push(',');
    if let Some(l) = row.landed {
        out.push_str(l.name());
    }
    out.push(',');
    if let Some(m) = &row.mode {
        // Modes are short identifiers; keep the file parseable whatever an autopilot names one.
        out.extend(m.chars().filter(|c| *c != ',' && *c != '\n' && *c != '\r'));
    }
    opt(out, row.speed_m_s, 2);
    out.push('\n');
}

/// More bytes than any samples.csv row takes.
pub const ROW_BOUND: usize = 1024;

/// Appends rows to samples.csv.
#[derive(Debug)]
pub struct SamplesWriter {
    file: AppendFile,
    line: String,
    rows: u64,
}

impl SamplesWriter {
    /// Creates `path` (never overwriting one) and writes the header line.
    pub fn create(path: &Path) -> Result<SamplesWriter, FlightLogError> {
        let mut file = AppendFile::create(path)?;
        file.write((COLUMNS.join(",") + "\n").as_bytes())?;
        Ok(SamplesWriter {
            file,
            line: String::with_capacity(256),
            rows: 0,
        })
    }

    /// Opens an existing samples.csv to go on appending rows (a flight resumed after a
    /// crash): a torn last line is cut off first. A file cut inside its header line gets the
    /// header again; a file with another header is refused. The row count includes the rows
    /// kept.
    pub fn resume(path: &Path) -> Result<SamplesWriter, FlightLogError> {
        let bytes = std::fs::read(path).map_err(io_error(path))?;
        let header = COLUMNS.join(",") + "\n";
        let keep = bytes
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |end| end + 1);
        if keep < header.len() {
            if !header
                .as_bytes()
                .starts_with(&bytes[..bytes.len().min(header.len())])
            {
                return Err(FlightLogError::Csv {
                    file: path.display().to_string(),
                    line: 1,
                    column: String::new(),
                    reason: "not samples.csv's header".into(),
                });
            }
            let mut file = AppendFile::reopen(path, 0)?;
            file.write(header.as_bytes())?;
            return Ok(SamplesWriter {
                file,
                line: String::with_capacity(256),
                rows: 0,
            });
        }
        if !bytes.starts_with(header.as_bytes()) {
            return Err(FlightLogError::Csv {
                file: path.display().to_string(),
                line: 1,
                column: String::new(),
                reason: "not samples.csv's header".into(),
            });
        }
        let rows = bytes[header.len()..keep]
            .split(|&b| b == b'\n')
            .filter(|l| !l.is_empty())
            .count() as u64;
        Ok(SamplesWriter {
            file: AppendFile::reopen(path, keep as u64)?,
            line: String::with_capacity(256),
            rows,
        })
    }

    pub fn path(&self) -> &Path {
        self.file.path()
    }

    /// Rows written so far.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    pub fn append(&mut self, row: &SampleRow) -> Result<(), FlightLogError> {
        self.line.clear();
        format_row(row, &mut self.line);
        self.file.write(self.line.as_bytes())?;
        self.rows += 1;
        Ok(())
    }

    /// Whether another row fits in the buffer without it spilling (a row is well under
    /// [`ROW_BOUND`] bytes).
    pub fn has_room(&self) -> bool {
        self.file.has_room(ROW_BOUND)
    }

    pub fn flush(&mut self) -> Result<(), FlightLogError> {
        self.file.flush()
    }

    pub fn sync(&mut self) -> Result<(), FlightLogError> {
        self.file.sync()
    }
}

struct Fields<'a> {
    file: &'a str,
    line: usize,
    fields: Vec<&'a str>,
}

impl Fields<'_> {
    fn err(&self, column: usize, reason: impl Into<String>) -> FlightLogError {
        FlightLogError::Csv {
            file: self.file.to_string(),
            line: self.line,
            column: COLUMNS.get(column).copied().unwrap_or("?").to_string(),
            reason: reason.into(),
        }
    }

    fn text(&self, column: usize) -> &str {
        self.fields.get(column).copied().unwrap_or("")
    }

    fn parse<T: std::str::FromStr>(&self, column: usize) -> Result<Option<T>, FlightLogError> {
        let text = self.text(column);
        if text.is_empty() {
            return Ok(None);
        }
        text.parse()
            .map(Some)
            .map_err(|_| self.err(column, format!("cannot read {text:?}")))
    }

    /// A number, finite and inside `range` (`unit` for the message), or empty.
    fn number(
        &self,
        column: usize,
        range: std::ops::RangeInclusive<f64>,
        unit: &str,
    ) -> Result<Option<f64>, FlightLogError> {
        let Some(value) = self.parse::<f64>(column)? else {
            return Ok(None);
        };
        let text = self.text(column);
        if !value.is_finite() {
            return Err(self.err(column, format!("{text} is not a finite number")));
        }
        if !range.contains(&value) {
            return Err(self.err(
                column,
                format!(
                    "{text} {unit} is not physical (outside {} to {} {unit})",
                    range.start(),
                    range.end()
                ),
            ));
        }
        Ok(Some(value))
    }

    /// A finite number, or empty.
    fn finite(&self, column: usize) -> Result<Option<f64>, FlightLogError> {
        self.number(column, f64::MIN..=f64::MAX, "")
    }

    fn required<T: std::str::FromStr>(&self, column: usize) -> Result<T, FlightLogError> {
        self.parse(column)?
            .ok_or_else(|| self.err(column, "empty, expected a value"))
    }

    fn flag(&self, column: usize) -> Result<Option<bool>, FlightLogError> {
        match self.text(column) {
            "" => Ok(None),
            "1" => Ok(Some(true)),
            "0" => Ok(Some(false)),
            other => Err(self.err(column, format!("expected 0 or 1, found {other:?}"))),
        }
    }
}

fn landed_from(name: &str) -> Option<LandedState> {
    [
        LandedState::Undefined,
        LandedState::OnGround,
        LandedState::InAir,
        LandedState::Takeoff,
        LandedState::Landing,
    ]
    .into_iter()
    .find(|l| l.name() == name)
}

/// The widest pack voltage a sample can hold: BATTERY_STATUS carries at most 14 cells
/// (`voltages` and `voltages_ext`) of at most 65.534 V each (uint16 mV), 917 V in all.
pub const MAX_VOLTAGE_V: f64 = 1000.0;
/// The largest current magnitude a sample can hold: BATTERY_STATUS and SYS_STATUS carry it as
/// int16 cA, at most 327.67 A; the bound leaves room for other sources.
pub const MAX_CURRENT_A: f64 = 1000.0;

fn parse_row(f: &Fields) -> Result<SampleRow, FlightLogError> {
    if f.fields.len() < COLUMNS.len() {
        // Named by the first column missing.
        return Err(f.err(
            f.fields.len(),
            format!(
                "missing: the row has {} fields, {} expected",
                f.fields.len(),
                COLUMNS.len()
            ),
        ));
    }
    if f.fields.len() > COLUMNS.len() {
        return Err(FlightLogError::Csv {
            file: f.file.to_string(),
            line: f.line,
            column: format!(
                "{} (after {})",
                COLUMNS.len() + 1,
                COLUMNS[COLUMNS.len() - 1]
            ),
            reason: format!(
                "the row has {} fields, {} expected",
                f.fields.len(),
                COLUMNS.len()
            ),
        });
    }
    let source = match f.text(2) {
        "battery_status" => BatterySource::BatteryStatus {
            id: f.required(3)?,
            component: f.required(4)?,
        },
        "sys_status" => BatterySource::SysStatus,
        other => return Err(f.err(2, format!("unknown source {other:?}"))),
    };
    let landed = match f.text(19) {
        "" => None,
        name => Some(landed_from(name).ok_or_else(|| f.err(19, format!("unknown {name:?}")))?),
    };
    let mode = Some(f.text(20).to_string()).filter(|m| !m.is_empty());
    Ok(SampleRow {
        sample: PowerSample {
            t_s: f
                .finite(0)?
                .ok_or_else(|| f.err(0, "empty, expected a value"))?,
            wall_us: f.required(1)?,
            battery: Battery {
                source,
                voltage_v: f.number(6, 0.0..=MAX_VOLTAGE_V, "V")?,
                current_a: f.number(7, -MAX_CURRENT_A..=MAX_CURRENT_A, "A")?,
                consumed_mah: f.finite(9)?,
                energy_consumed_j: f.finite(10)?,
                remaining_pct: f.finite(11)?,
                fake_current: f.flag(12)?.unwrap_or(false),
            },
            primary: f.flag(5)?.unwrap_or(false),
        },
        lat_deg: f.number(13, -90.0..=90.0, "deg")?,
        lon_deg: f.number(14, -180.0..=180.0, "deg")?,
        alt_amsl_m: f.finite(15)?,
        relative_alt_m: f.finite(16)?,
        mission_seq: f.parse(17)?,
        armed: f.flag(18)?,
        landed,
        mode,
        speed_m_s: f.finite(21)?,
    })
}

/// The rows of samples.csv text; `file` names it in errors. A last line without its newline is
/// torn (the writer was cut off) and skipped.
pub fn parse_samples(text: &str, file: &str) -> Result<Vec<SampleRow>, FlightLogError> {
    let complete = match text.rfind('\n') {
        Some(end) => &text[..=end],
        None => "",
    };
    let mut lines = complete.lines().enumerate();
    let header = COLUMNS.join(",");
    match lines.next() {
        Some((_, first)) if first == header => {}
        Some((_, first)) => {
            return Err(FlightLogError::Csv {
                file: file.to_string(),
                line: 1,
                column: String::new(),
                reason: format!("header {first:?} is not samples.csv's"),
            })
        }
        None => return Ok(Vec::new()),
    }
    lines
        .filter(|(_, l)| !l.is_empty())
        .map(|(k, l)| {
            parse_row(&Fields {
                file,
                line: k + 1,
                fields: l.split(',').collect(),
            })
        })
        .collect()
}

/// Reads samples.csv (see [`parse_samples`]).
pub fn read_samples(path: &Path) -> Result<Vec<SampleRow>, FlightLogError> {
    let bytes = std::fs::read(path).map_err(io_error(path))?;
    // A torn write can cut a UTF-8 sequence only in the last line, which is skipped anyway.
    let text = String::from_utf8_lossy(&bytes);
    parse_samples(&text, &path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::telemetry::{FlightMode, Position, Reading};

    fn row(k: u32) -> SampleRow {
        let mut state = VehicleState::default();
        state.update(&Reading::Position(Position {
            time_boot_ms: k,
            lat_deg: 38.5362 + f64::from(k) * 1e-6,
            lon_deg: -121.7875,
            alt_amsl_m: 46.0,
            relative_alt_m: 30.0,
            vn_m_s: 3.0,
            ve_m_s: 4.0,
            vd_m_s: 0.0,
        }));
        state.update(&Reading::Heartbeat {
            armed: true,
            mode: FlightMode::Mission,
        });
        state.update(&Reading::Landed(LandedState::InAir));
        SampleRow::new(
            PowerSample {
                t_s: f64::from(k) * 0.1,
                wall_us: 1_700_000_000_000_000 + u64::from(k) * 10_000,
                battery: Battery {
                    source: BatterySource::BatteryStatus {
                        id: 0,
                        component: 1,
                    },
                    voltage_v: Some(22.25),
                    current_a: if k.is_multiple_of(3) {
                        None
                    } else {
                        Some(41.5)
                    },
                    consumed_mah: Some(100.0 + f64::from(k)),
                    energy_consumed_j: None,
                    remaining_pct: Some(80.0),
                    fake_current: false,
                },
                primary: true,
            },
            &state,
        )
    }

    fn close(a: &SampleRow, b: &SampleRow) -> bool {
        let near = |x: Option<f64>, y: Option<f64>, tol: f64| match (x, y) {
            (Some(x), Some(y)) => (x - y).abs() <= tol,
            (None, None) => true,
            _ => false,
        };
        near(Some(a.sample.t_s), Some(b.sample.t_s), 1e-6)
            && a.sample.wall_us == b.sample.wall_us
            && a.sample.battery.source == b.sample.battery.source
            && near(a.sample.battery.voltage_v, b.sample.battery.voltage_v, 1e-3)
            && near(a.sample.battery.current_a, b.sample.battery.current_a, 1e-2)
            && near(a.lat_deg, b.lat_deg, 1e-7)
            && a.mission_seq == b.mission_seq
            && a.armed == b.armed
            && a.landed == b.landed
            && a.mode == b.mode
            && near(a.speed_m_s, b.speed_m_s, 0.01)
    }

    #[test]
    fn rows_written_read_back_to_their_printed_precision() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("samples.csv");
        let mut w = SamplesWriter::create(&path).expect("created");
        let rows: Vec<SampleRow> = (0..20).map(row).collect();
        for r in &rows {
            w.append(r).expect("appended");
        }
        w.sync().expect("synced");
        let back = read_samples(&path).expect("read");
        assert_eq!(back.len(), rows.len());
        for (a, b) in rows.iter().zip(&back) {
            assert!(close(a, b), "{a:?}\n{b:?}");
        }
        assert_eq!(back[1].speed_m_s, Some(5.0));
        assert_eq!(back[0].sample.power_w(), None);
    }

    #[test]
    fn a_file_cut_at_any_byte_reads_every_whole_row_before_the_cut() {
        let mut text = COLUMNS.join(",") + "\n";
        let mut ends = Vec::new();
        for k in 0..5 {
            format_row(&row(k), &mut text);
            ends.push(text.len());
        }
        for cut in 0..=text.len() {
            let rows = parse_samples(&text[..cut], "cut.csv")
                .unwrap_or_else(|e| panic!("cut at {cut}: {e}"));
            assert_eq!(
                rows.len(),
                ends.iter().filter(|&&e| e <= cut).count(),
                "cut {cut}"
            );
        }
    }

    #[test]
    fn a_resumed_file_cut_at_any_byte_goes_on_with_whole_rows_only() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("samples.csv");
        let mut text = COLUMNS.join(",") + "\n";
        let mut ends = Vec::new();
        for k in 0..3 {
            format_row(&row(k), &mut text);
            ends.push(text.len());
        }
        for cut in 0..=text.len() {
            std::fs::write(&path, &text.as_bytes()[..cut]).expect("written");
            let mut w = SamplesWriter::resume(&path).expect("resumed");
            let kept = ends.iter().filter(|&&e| e <= cut).count();
            assert_eq!(w.rows(), kept as u64, "cut {cut}");
            w.append(&row(9)).expect("appended");
            w.sync().expect("synced");
            let back = read_samples(&path).unwrap_or_else(|e| panic!("cut at {cut}: {e}"));
            assert_eq!(back.len(), kept + 1, "cut {cut}");
            assert!(close(&back[kept], &row(9)), "cut {cut}");
        }
        std::fs::write(&path, "time,volts\n1,2\n").expect("written");
        assert!(SamplesWriter::resume(&path).is_err());
    }

    #[test]
    fn a_bad_field_is_an_error_naming_file_line_and_column() {
        let mut text = COLUMNS.join(",") + "\n";
        format_row(&row(1), &mut text);
        let mut bad = String::new();
        format_row(&row(2), &mut bad);
        text.push_str(&bad.replacen("22.250", "22x", 1));
        let err = parse_samples(&text, "s.csv").expect_err("bad voltage");
        let msg = err.to_string();
        assert!(
            msg.contains("s.csv") && msg.contains("line 3") && msg.contains("voltage_v"),
            "{msg}"
        );
    }

    #[test]
    fn a_non_finite_or_non_physical_number_is_an_error_naming_file_line_and_column() {
        let mut good = String::new();
        format_row(&row(1), &mut good);
        for (from, to, column) in [
            ("22.250", "1e308", "voltage_v"),
            ("22.250", "-3.0", "voltage_v"),
            ("41.50", "NaN", "current_a"),
            ("41.50", "inf", "current_a"),
            ("41.50", "5000", "current_a"),
            ("38.5362010", "138.5", "lat_deg"),
        ] {
            let mut text = COLUMNS.join(",") + "\n" + &good;
            text.push_str(&good.replacen(from, to, 1));
            let err = parse_samples(&text, "s.csv").expect_err(to).to_string();
            assert!(
                err.contains("s.csv line 3") && err.contains(column) && err.contains(to),
                "{to}: {err}"
            );
        }
    }
}
