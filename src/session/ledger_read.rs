//! What the commands that only read the ledger ask of it beyond its flights (`emplan packs`,
//! `calibrate --from-ledger`): each pack's flights as points over its cycles with its trend
//! (drawn by `plot::packs_svg`), and a vehicle's flight directories still on disk.

use std::path::PathBuf;

use crate::ledger::packs::{PackSummary, MIN_TREND_FLIGHTS};
use crate::ledger::{FlightQuery, FlightRecord, FlightSource, Ledger, LedgerError};
use crate::plot::{PackHistory, PackPoint, PackTrend};

/// Each pack's flights (those with a pack fit) as points over the pack's equivalent full
/// cycles at each flight's middle, as `ledger::packs` places them, with the trend from
/// `summaries` (`ledger::packs::summarise` of the same flights: the capacity now, at the
/// pack's cycles so far, and its fade per cycle) from the first point to now; `flights` oldest
/// first, as the ledger lists them.
pub fn pack_histories(flights: &[FlightRecord], summaries: &[PackSummary]) -> Vec<PackHistory> {
    summaries
        .iter()
        .map(|summary| {
            let label = summary.label_capacity_ah.filter(|l| *l > 0.0);
            let points: Vec<PackPoint> = crate::ledger::packs::aged(flights, &summary.name)
                .into_iter()
                .filter_map(|a| {
                    let fit = a.flight.pack_fit.as_ref()?;
                    Some(PackPoint {
                        cycles: a.cycles?,
                        capacity_ah: fit.capacity_ah,
                        capacity_sd_ah: fit.capacity_sd_ah,
                        internal_resistance_ohm: fit.internal_resistance_ohm,
                    })
                })
                .collect();
            let trend = match (
                &summary.capacity_ah,
                &summary.fade_ah_per_cycle,
                points.first(),
            ) {
                (Some(now), Some(fade), Some(first)) if points.len() >= MIN_TREND_FLIGHTS => {
                    Some(PackTrend {
                        from_cycles: first.cycles,
                        to_cycles: summary.cycles,
                        capacity_from_ah: now.value + fade.value * (first.cycles - summary.cycles),
                        capacity_to_ah: now.value,
                    })
                }
                _ => None,
            };
            PackHistory {
                name: summary.name.clone(),
                label_capacity_ah: label,
                points,
                trend,
            }
        })
        .collect()
}

/// What [`vehicle_flight_dirs`] found: the vehicle's flight directories still on disk, and what
/// of its flights could not be used.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct VehicleFlights {
    pub dirs: Vec<PathBuf>,
    /// Its flights in the ledger, those imported from onboard logs, and the directories gone.
    pub flights: usize,
    pub onboard: usize,
    pub missing: Vec<PathBuf>,
}

/// The flight directories (oldest first) of `vehicle` (the vehicle file's name) that the
/// ledger knows and that still exist.
pub fn vehicle_flight_dirs(
    ledger: &mut Ledger,
    vehicle: &str,
) -> Result<VehicleFlights, LedgerError> {
    let flights = ledger.flights(&FlightQuery {
        vehicle: Some(vehicle.to_string()),
        ..FlightQuery::default()
    })?;
    let mut found = VehicleFlights {
        flights: flights.len(),
        ..VehicleFlights::default()
    };
    for flight in &flights {
        if flight.source != FlightSource::Directory {
            found.onboard += 1;
            continue;
        }
        let dir = PathBuf::from(&flight.path);
        if crate::flightlog::recorder::is_flight_dir(&dir) {
            if !found.dirs.contains(&dir) {
                found.dirs.push(dir);
            }
        } else {
            found.missing.push(dir);
        }
    }
    Ok(found)
}
