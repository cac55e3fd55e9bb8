//! The date bounds of a query of flights: `since` and `until` as a date (`YYYY-MM-DD`, its whole
//! day) or a time as records keep them (`YYYY-MM-DDTHH:MM:SSZ`), compared with `started_at` as
//! text (a date is a prefix of every time that day).

use super::LedgerError;

/// A civil date `YYYY-MM-DD`, checked (month, day of the month, leap years).
fn parse_date(text: &str) -> Option<(i32, u32, u32)> {
    let b = text.as_bytes();
    if b.len() != 10 || b[4] != b'-' || b[7] != b'-' {
        return None;
    }
    let year = digits(&text[..4])?;
    let month = digits(&text[5..7])?;
    let day = digits(&text[8..])?;
    let year = i32::try_from(year).ok()?;
    ((1..=12).contains(&month) && (1..=days_in_month(year, month)).contains(&day))
        .then_some((year, month, day))
}

/// A number written in ASCII digits only (no sign, no space).
fn digits(text: &str) -> Option<u32> {
    if text.is_empty() || !text.bytes().all(|c| c.is_ascii_digit()) {
        return None;
    }
    text.parse().ok()
}

fn days_in_month(year: i32, month: u32) -> u32 {
    let leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
    match month {
        2 if leap => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// The day after a date, as `YYYY-MM-DD`.
fn day_after((year, month, day): (i32, u32, u32)) -> String {
    let (year, month, day) = if day < days_in_month(year, month) {
        (year, month, day + 1)
    } else if month < 12 {
        (year, month + 1, 1)
    } else {
        (year + 1, 1, 1)
    };
    format!("{year:04}-{month:02}-{day:02}")
}

/// Whether `text` is a timestamp as records keep them, `YYYY-MM-DDTHH:MM:SSZ`.
fn is_timestamp(text: &str) -> bool {
    let b = text.as_bytes();
    let time_ok = || {
        let time = &text[11..19];
        let tb = time.as_bytes();
        let field = |s: &str, max: u32| digits(s).is_some_and(|v| v <= max);
        tb[2] == b':'
            && tb[5] == b':'
            && field(&time[..2], 23)
            && field(&time[3..5], 59)
            && field(&time[6..], 60)
    };
    b.len() == 20
        && b[10] == b'T'
        && b[19] == b'Z'
        && parse_date(&text[..10]).is_some()
        && time_ok()
}

fn bad_bound(field: &str, value: &str) -> LedgerError {
    LedgerError::Query {
        field: field.to_string(),
        value: value.to_string(),
    }
}

/// The lower bound of `since`: its date (a prefix of every timestamp that day) or its time.
pub(super) fn since_bound(since: &str) -> Result<String, LedgerError> {
    if parse_date(since).is_some() || is_timestamp(since) {
        Ok(since.to_string())
    } else {
        Err(bad_bound("since", since))
    }
}

/// The upper bound of `until` and whether it is inclusive: a date takes its whole day (before
/// the day after), a time itself.
pub(super) fn until_bound(until: &str) -> Result<(String, bool), LedgerError> {
    if let Some(date) = parse_date(until) {
        Ok((day_after(date), false))
    } else if is_timestamp(until) {
        Ok((until.to_string(), true))
    } else {
        Err(bad_bound("until", until))
    }
}
