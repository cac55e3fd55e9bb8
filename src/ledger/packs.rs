//! What each pack is now, from its flights' records: capacity and internal resistance, their
//! trend over its cycles with its uncertainty, charge and energy throughput, and warnings; and
//! what a vehicle's model is off by (the guard's correction over its flights).

use serde::{Deserialize, Serialize};

use super::FlightRecord;

/// An estimate with its standard error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    pub value: f64,
    pub sd: f64,
}

/// One pack, from its flights.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PackSummary {
    pub name: String,
    pub flights: usize,
    /// Equivalent full cycles: the charge drawn over all its flights against its label.
    pub cycles: f64,
    pub charge_throughput_ah: f64,
    pub energy_throughput_wh: f64,
    pub label_capacity_ah: Option<f64>,
    /// The capacity now (Ah) and against the label.
    pub capacity_ah: Option<Estimate>,
    pub capacity_ratio: Option<Estimate>,
    pub internal_resistance_ohm: Option<Estimate>,
    /// The capacity's change per equivalent full cycle (Ah).
    pub fade_ah_per_cycle: Option<Estimate>,
    pub first_flight: Option<String>,
    pub last_flight: Option<String>,
    pub warnings: Vec<String>,
}

/// What the next flight on a pack starts from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PackPrior {
    pub pack: String,
    /// Capacity against the label, and its standard error.
    pub capacity_ratio: f64,
    pub capacity_ratio_sd: f64,
    pub internal_resistance_ohm: Option<f64>,
    /// Flights it was learned from.
    pub flights: usize,
}

/// What a vehicle's model is off by, over its flights.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VehiclePrior {
    pub vehicle: String,
    /// Measured over predicted, and the standard deviation of its logarithm.
    pub correction: f64,
    pub correction_sd_ln: f64,
    pub flights: usize,
}

/// Every pack in `flights`, by name.
pub fn summarise(_flights: &[FlightRecord]) -> Vec<PackSummary> {
    todo!("helper: pack summaries")
}

/// What a flight on `pack` starts from (None before any flight measured it).
pub fn pack_prior(_flights: &[FlightRecord], _pack: &str) -> Option<PackPrior> {
    todo!("helper: pack prior")
}

/// What `vehicle`'s model is off by (None before any guarded flight of it).
pub fn vehicle_prior(_flights: &[FlightRecord], _vehicle: &str) -> Option<VehiclePrior> {
    todo!("helper: vehicle prior")
}
