//! The service's view of the flight and battery ledger (`crate::ledger`): the ledger's flights
//! for `GET /api/flights` and each pack, as `ledger::packs` sums it up, with the capacity each
//! of its flights measured over its cycles, for `GET /api/packs` and the dashboard's Packs page.
//!
//! The store is blocking: these functions run on a blocking thread (`spawn_blocking`), each
//! opening the ledger for its request, so no connection or lock is held across an await. The
//! service only reads here: a ledger that does not exist yet reads as no flights and is not
//! created (the first flight that lands creates it).

use std::path::Path;

use super::wire::{PackPoint, PackView};
use crate::ledger::{packs, FlightQuery, FlightRecord, Ledger, LedgerError, LedgerSpec, Written};

/// Where the ledger is, for a person: the SQLite file's path, or the PostgreSQL URL with its
/// password hidden.
pub fn describe(spec: &LedgerSpec) -> String {
    match spec {
        LedgerSpec::Sqlite(path) => path.display().to_string(),
        LedgerSpec::Postgres(url) => hide_password(url),
    }
}

/// `url` with the password of its user information (`postgres://user:secret@host/db`) written
/// as `***`.
fn hide_password(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else {
        return url.to_string();
    };
    let authority_end = rest.find(['/', '?']).unwrap_or(rest.len());
    let (authority, tail) = rest.split_at(authority_end);
    match authority.rsplit_once('@') {
        Some((user_info, host)) => match user_info.split_once(':') {
            Some((user, _password)) => format!("{scheme}://{user}:***@{host}{tail}"),
            None => url.to_string(),
        },
        None => url.to_string(),
    }
}

/// Whether the ledger at `spec` exists yet (a PostgreSQL ledger is taken to: its server says).
pub fn exists(spec: &LedgerSpec) -> bool {
    match spec {
        LedgerSpec::Sqlite(path) => path.is_file(),
        LedgerSpec::Postgres(_) => true,
    }
}

/// The flights of the ledger at `spec` matching `query`, oldest first; none when the ledger
/// does not exist yet (it is not created). Blocking.
pub fn flights(spec: &LedgerSpec, query: &FlightQuery) -> Result<Vec<FlightRecord>, LedgerError> {
    if !exists(spec) {
        return Ok(Vec::new());
    }
    Ledger::open(spec)?.flights(query)
}

/// Every pack of `records` (oldest first), as `ledger::packs::summarise` sums it up, each with
/// its flights' capacities over its cycles.
pub fn pack_views(records: &[FlightRecord]) -> Vec<PackView> {
    packs::summarise(records)
        .into_iter()
        .map(|summary| {
            let history = history(records, &summary.name, summary.label_capacity_ah);
            PackView { summary, history }
        })
        .collect()
}

/// The flights of `pack` in `records`, oldest first, each with the pack's age at its middle in
/// equivalent full cycles (the charge drawn on the pack so far against its label `label_ah`, as
/// `ledger::packs` places each flight on the pack's trend) and the capacity and resistance its
/// own voltage and current show.
fn history(records: &[FlightRecord], pack: &str, label_ah: Option<f64>) -> Vec<PackPoint> {
    let mut flights: Vec<&FlightRecord> = records
        .iter()
        .filter(|r| r.pack.as_deref() == Some(pack))
        .collect();
    flights.sort_by(|a, b| a.started_at.cmp(&b.started_at));
    let label_ah = label_ah.filter(|l| l.is_finite() && *l > 0.0);
    let mut charge_ah = 0.0;
    flights
        .into_iter()
        .map(|r| {
            let before = charge_ah;
            charge_ah += r
                .charge_ah
                .filter(|c| c.is_finite() && *c > 0.0)
                .unwrap_or(0.0);
            PackPoint {
                flight: r.id.clone(),
                started_at: r.started_at.clone(),
                cycles: label_ah.map(|l| 0.5 * (before + charge_ah) / l),
                capacity_ah: r.pack_fit.as_ref().map(|f| f.capacity_ah),
                capacity_sd_ah: r.pack_fit.as_ref().map(|f| f.capacity_sd_ah),
                label_capacity_ah: label_ah,
                internal_resistance_ohm: r.pack_fit.as_ref().map(|f| f.internal_resistance_ohm),
            }
        })
        .collect()
}

/// Why a date of a query is refused (None: it is one).
pub fn check_date(field: &str, text: &str) -> Option<String> {
    let b = text.as_bytes();
    let digits = |range: std::ops::Range<usize>| b[range].iter().all(u8::is_ascii_digit);
    let date = b.len() >= 10 && digits(0..4) && b[4] == b'-' && digits(5..7) && b[7] == b'-';
    let date = date && digits(8..10);
    let time = b.len() == 20
        && b[10] == b'T'
        && digits(11..13)
        && b[13] == b':'
        && digits(14..16)
        && b[16] == b':'
        && digits(17..19)
        && b[19] == b'Z';
    if date && (b.len() == 10 || time) {
        None
    } else {
        Some(format!(
            "{field} {text:?}: expected a UTC date YYYY-MM-DD or a time YYYY-MM-DDTHH:MM:SSZ"
        ))
    }
}

/// Writes the flight of directory `dir` to the ledger at `spec` (created when absent). Blocking.
// FIXME: the session writes each finished flight to the ledger (it also has the pack and the
// vehicle); until it does, the service writes the flights it recorded here.
pub fn write_flight(spec: &LedgerSpec, dir: &Path) -> Result<Written, LedgerError> {
    let record = crate::ledger::record::from_dir(dir)?;
    Ledger::open(spec)?.write(&record)
}

/// Writes every flight the recorder finishes to the ledger at `spec`, each on a blocking thread;
/// a flight whose write fails is kept (its files are its record) and the failure logged.
// FIXME: see `write_flight`.
pub async fn write_finished(
    spec: LedgerSpec,
    mut flights: tokio::sync::broadcast::Receiver<crate::session::FlightEvent>,
) {
    use tokio::sync::broadcast::error::RecvError;
    loop {
        let (flight, dir) = match flights.recv().await {
            Ok(crate::session::FlightEvent::Ended { flight, dir, .. }) => (flight, dir),
            Ok(_) => continue,
            Err(RecvError::Lagged(n)) => {
                tracing::warn!("{n} flight events missed by the ledger writer");
                continue;
            }
            Err(RecvError::Closed) => return,
        };
        let spec = spec.clone();
        let written = tokio::task::spawn_blocking(move || write_flight(&spec, &dir)).await;
        let name = super::escape_controls(&flight).into_owned();
        match written {
            Ok(Ok(w)) => tracing::info!(
                "flight {name}: {} the ledger",
                match w {
                    Written::Inserted => "written to",
                    Written::Unchanged => "already in",
                    Written::Replaced => "replaced in",
                }
            ),
            Ok(Err(e)) => tracing::warn!(
                "flight {name}: not written to the ledger ({}); its directory keeps it",
                super::escape_controls(&e.to_string())
            ),
            Err(e) => tracing::warn!("flight {name}: the ledger write stopped: {e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_postgres_url_is_described_without_its_password() {
        assert_eq!(
            describe(&LedgerSpec::parse(
                "postgres://team:s3cret@db.local:5432/ledger"
            )),
            "postgres://team:***@db.local:5432/ledger"
        );
        assert_eq!(
            describe(&LedgerSpec::parse("postgresql://db.local/ledger?user=x")),
            "postgresql://db.local/ledger?user=x"
        );
        assert_eq!(
            describe(&LedgerSpec::parse("flights/ledger.sqlite")),
            "flights/ledger.sqlite"
        );
    }

    #[test]
    fn dates_and_times_of_a_query_are_checked_and_named() {
        assert_eq!(check_date("since", "2026-11-29"), None);
        assert_eq!(check_date("until", "2026-11-29T10:15:00Z"), None);
        for bad in [
            "yesterday",
            "2026-11-2",
            "2026-11-29T10:15",
            "2026/11/29",
            "",
            "é2026-11-29",
        ] {
            let e = check_date("since", bad).expect(bad);
            assert!(e.starts_with("since "), "{e}");
        }
    }
}
