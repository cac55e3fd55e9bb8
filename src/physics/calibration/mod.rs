//! Calibration against the paper's published operation energies (docs/energy-model.md): the
//! paper's targets (`targets`), the model-vs-paper comparison (`compare`), and a Nelder-Mead
//! fit of the few parameters the paper does not publish (`fit`). PTF fits the vehicle mass,
//! the drags and its speed limits; HVB then fits its own speed and acceleration limits with the
//! vehicle held fixed. `calibrate` puts them together as `emplan calibrate` reports them.

mod compare;
mod fit;
mod targets;

pub use compare::{
    compare, compare_missions, compare_priced, marginal_costs, min_power_speed_m_s, rms, rms_pct,
    sample_1_tour, MissionRow, Row, TourCheck,
};
pub use fit::{fit, Fitted};
pub use targets::{
    path_legs, MissionTarget, Rank, Target, PAPER, PAPER_MARGINAL_J_M, PAPER_MISSIONS, SAMPLE_1,
    SAMPLE_2,
};

use super::vehicle::Vehicle;
use super::{PhysicsError, Pricing, Profile};

/// The model against the paper (what `emplan calibrate` reports), after an optional refit.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// The PTF operations, model vs paper.
    pub ptf: Vec<Row>,
    /// The HVB operations, model vs paper.
    pub hvb: Vec<Row>,
    /// The sample missions' published energies, model vs paper.
    pub missions: Vec<MissionRow>,
    /// The paper's min-energy tour of sample mission 1 against the model's.
    pub tour: TourCheck,
    /// What each row's `priced_kj` counts (the comparison is always in the paper's convention).
    pub pricing: Pricing,
    /// PTF marginal costs (J/m): climbing, level, descending saves ([`marginal_costs`]).
    pub marginal_j_m: [f64; 3],
    pub hover_power_w: f64,
    pub min_power_speed_m_s: f64,
    /// The refitted parameters (empty without a refit).
    pub fitted: Vec<Fitted>,
}

/// Compares `vehicle` with the paper (operations, sample missions, the paper's tour); with
/// `refit`, first refits the calibrated parameters (PTF: mass, drags, induced power factor,
/// speed limits, tracking lag; HVB: its limits; 300 Nelder-Mead iterations each, to the
/// operations and the sample missions of the profile together). `pricing` sets each row's
/// `priced_kj`; the comparison with the paper is always in its own convention.
pub fn calibrate(
    vehicle: &Vehicle,
    refit: bool,
    pricing: Pricing,
) -> Result<Calibration, PhysicsError> {
    let mut vehicle = vehicle.clone();
    let mut fitted = Vec::new();
    if refit {
        let (v, values) = fit(&vehicle, &[Profile::Ptf, Profile::Hvb], 600);
        vehicle = v;
        fitted.extend(values);
    }
    let ptf = compare_priced(&vehicle, Profile::Ptf, pricing)?;
    let hvb = compare_priced(&vehicle, Profile::Hvb, pricing)?;
    Ok(Calibration {
        missions: compare_missions(&vehicle, pricing)?,
        tour: sample_1_tour(&vehicle)?,
        pricing,
        marginal_j_m: marginal_costs(&ptf),
        ptf,
        hvb,
        hover_power_w: super::hover_power_w(&vehicle)?,
        min_power_speed_m_s: min_power_speed_m_s(&vehicle),
        fitted,
    })
}

impl Calibration {
    /// `emplan calibrate --json` (keys in alphabetical order).
    pub fn to_json(&self) -> serde_json::Value {
        let mission_errors: Vec<f64> = self.missions.iter().map(|r| r.error_pct).collect();
        serde_json::json!({
            "pricing": self.pricing,
            "missions": {
                "rows": self.missions,
                "rms_pct": rms(&mission_errors),
                "sample_1_tour": self.tour,
            },
            "ptf": {"rows": self.ptf, "rms_pct": rms_pct(&self.ptf)},
            "hvb": {"rows": self.hvb, "rms_pct": rms_pct(&self.hvb)},
            "marginal_j_m": {"model": self.marginal_j_m, "paper": PAPER_MARGINAL_J_M},
            "hover_power_w": self.hover_power_w,
            "min_power_speed_m_s": self.min_power_speed_m_s,
            "fitted": self.fitted,
        })
    }
}
