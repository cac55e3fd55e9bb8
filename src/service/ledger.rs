//! The service's view of the flight and battery ledger (`crate::ledger`): the ledger's flights
//! for `GET /api/flights` and each pack, as `ledger::packs` sums it up, with the capacity each
//! of its flights measured over its cycles, for `GET /api/packs` and the dashboard's Packs page.
//!
//! The store is blocking: these functions run on a blocking thread (`spawn_blocking`), each
//! opening the ledger for its request, so no connection or lock is held across an await. The
//! service only reads here: a ledger that does not exist yet reads as no flights and is not
//! created (the first flight that lands creates it).

use super::wire::{PackPoint, PackView};
use crate::ledger::{packs, FlightQuery, FlightRecord, Ledger, LedgerError, LedgerSpec};

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
    Ledger::open_existing(spec)?.flights(query)
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
    let label_ah = label_ah.filter(|l| l.is_finite() && *l > 0.0);
    packs::aged(records, pack)
        .into_iter()
        .map(|a| {
            let fit = a.flight.pack_fit.as_ref();
            PackPoint {
                flight: a.flight.id.clone(),
                started_at: a.flight.started_at.clone(),
                cycles: a.cycles,
                capacity_ah: fit.map(|f| f.capacity_ah),
                capacity_sd_ah: fit.map(|f| f.capacity_sd_ah),
                label_capacity_ah: label_ah,
                internal_resistance_ohm: fit.map(|f| f.internal_resistance_ohm),
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

#[cfg(test)]
mod tests {
    use super::*;

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
