//! The paper's random-mission study in a steady wind: for every mission of a study setting, the
//! minimum-energy order in still air (the vehicle's table) and in the wind (every leg simulated
//! on its heading, `VehicleModel::leg_on_heading`), both pair-independent as the study's; how
//! often the wind changes the order, and what the still-air order costs in the wind over the
//! wind-aware one (the saving of planning in the wind, % of the still-air order's price there).
//! Deterministic as the study: mission `k` is drawn from its own stream, results collected in
//! mission order.

use rayon::prelude::*;
use serde::Serialize;

use super::{mission_geometry, node_name, study_error, StudyError, StudySettings};
use crate::physics::{Pricing, Start, VehicleModel, Wind};
use crate::tour::energy::{energy_matrix, energy_matrix_on_headings};
use crate::tour::orders::{solve_order, Objective};
use crate::tour::PlanError;

use super::summary::Stats;

/// One wind over one study setting (the `"winds"` rows of `emplan study --wind --json`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct WindRow {
    pub speed_m_s: f64,
    pub from_deg: f64,
    pub missions: usize,
    /// Share of missions whose wind-aware energy order is not the still-air one (%); None when
    /// no mission could be flown in this wind (then there is no share, not a share of 0).
    pub order_changed_pct: Option<f64>,
    /// The still-air order's price in the wind over the wind-aware order's, % of the former;
    /// over every mission (0 where the order did not change). None when no mission was flown.
    pub saving: Option<Stats>,
    /// The wind-aware order's price in the wind against the still-air order's price in still
    /// air, mean over the missions (%): what the wind itself does to the mission. None when no
    /// mission was flown.
    pub wind_effect_mean_pct: Option<f64>,
    /// Missions with a leg the vehicle cannot fly in this wind (its motors or tilt at their
    /// limit): left out of the shares and statistics above, which count the others.
    pub infeasible_missions: usize,
}

/// What one mission gives in a wind.
enum InWind {
    /// (order changed, saving %, wind effect %).
    Flown(bool, f64, f64),
    /// A leg cannot be flown in this wind.
    Infeasible,
}

/// One mission in `wind`.
fn mission_in_wind(
    settings: &StudySettings,
    mission: u64,
    still: &VehicleModel,
    windy: &VehicleModel,
    pricing: Pricing,
) -> Result<InWind, StudyError> {
    let geometry = mission_geometry(settings, mission);
    let names: Vec<String> = (0..geometry.len()).map(node_name).collect();
    let leg_error = |e: PlanError| study_error(mission, e);
    let calm = energy_matrix(&geometry, &names, |x, z| {
        still.leg(x, z).map(|l| l.priced_energy_j(pricing))
    })
    .map_err(leg_error)?;
    // A leg the physics cannot fly in the wind (the still-air table flew it) makes the mission
    // infeasible in that wind, not the study wrong.
    let in_wind = match energy_matrix_on_headings(&geometry, &names, |x, z, heading| {
        windy
            .leg_on_heading(x, z, Start::Behind, heading)
            .map(|l| l.priced_energy_j(pricing))
    }) {
        Ok(m) => m,
        Err(PlanError::LegEnergy { .. }) => return Ok(InWind::Infeasible),
        Err(e) => return Err(leg_error(e)),
    };
    let plan_err = |source| StudyError::Plan { mission, source };
    let still_order = solve_order(&geometry, Objective::Energy, Some(&calm)).map_err(plan_err)?;
    let aware = solve_order(&geometry, Objective::Energy, Some(&in_wind)).map_err(plan_err)?;
    let still_in_wind = in_wind.tour_cost(&still_order);
    let aware_in_wind = in_wind.tour_cost(&aware);
    let saving = if still_in_wind > 0.0 {
        100.0 * (still_in_wind - aware_in_wind) / still_in_wind
    } else {
        0.0
    };
    let calm_cost = calm.tour_cost(&still_order);
    let effect = if calm_cost > 0.0 {
        100.0 * (aware_in_wind - calm_cost) / calm_cost
    } else {
        0.0
    };
    Ok(InWind::Flown(aware != still_order, saving, effect))
}

/// The study `settings` flown in `wind` by `model` (its table for still air), missions in
/// parallel; `progress` is called once a mission. On failure, the lowest-numbered failing
/// mission's error.
pub fn run_wind(
    settings: &StudySettings,
    model: &VehicleModel,
    pricing: Pricing,
    wind: Wind,
    progress: &(dyn Fn() + Sync),
) -> Result<WindRow, StudyError> {
    settings.validate()?;
    let still = model.clone().with_wind(Wind::CALM);
    let windy = model.clone().with_wind(wind);
    let results: Vec<Result<InWind, StudyError>> = (0..settings.missions as u64)
        .into_par_iter()
        .map(|k| {
            let outcome = mission_in_wind(settings, k, &still, &windy, pricing);
            progress();
            outcome
        })
        .collect();
    let all = results.into_iter().collect::<Result<Vec<_>, _>>()?;
    let outcomes: Vec<(bool, f64, f64)> = all
        .iter()
        .filter_map(|o| match o {
            InWind::Flown(changed, saving, effect) => Some((*changed, *saving, *effect)),
            InWind::Infeasible => None,
        })
        .collect();
    let flown = !outcomes.is_empty();
    let n = outcomes.len() as f64;
    let savings: Vec<f64> = outcomes.iter().map(|o| o.1).collect();
    Ok(WindRow {
        speed_m_s: wind.speed_m_s,
        from_deg: wind.from_deg,
        missions: outcomes.len(),
        order_changed_pct: flown
            .then(|| 100.0 * outcomes.iter().filter(|o| o.0).count() as f64 / n),
        saving: flown.then(|| Stats::of(&savings)),
        wind_effect_mean_pct: flown.then(|| outcomes.iter().map(|o| o.2).sum::<f64>() / n),
        infeasible_missions: all.len() - outcomes.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> VehicleModel {
        VehicleModel::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000"),
            None,
        )
        .unwrap()
    }

    #[test]
    fn no_wind_changes_no_order_and_a_strong_wind_changes_some_and_never_costs() {
        let settings = StudySettings {
            waypoints: 6,
            xy_m: 30.0,
            z_m: 25.0,
            missions: 8,
            seed: 3,
        };
        let m = model();
        let calm = run_wind(&settings, &m, Pricing::Settled, Wind::CALM, &|| {}).unwrap();
        assert_eq!(calm.order_changed_pct, Some(0.0));
        assert_eq!(calm.saving.map(|s| s.max_pct), Some(0.0));
        assert_eq!(calm.wind_effect_mean_pct, Some(0.0));
        assert_eq!(calm.infeasible_missions, 0);
        let strong = Wind::new(8.0, 270.0).unwrap();
        let row = run_wind(&settings, &m, Pricing::Settled, strong, &|| {}).unwrap();
        assert_eq!(row.missions, 8);
        assert!(row.order_changed_pct.is_some_and(|p| p > 0.0), "{row:?}");
        // The wind-aware order is optimal in the wind: never dearer there than the still-air one.
        let saving = row.saving.expect("missions flown");
        assert!(saving.mean_pct >= 0.0 && saving.max_pct > 0.0, "{row:?}");
    }

    #[test]
    fn a_wind_no_mission_can_fly_has_no_share_saving_or_effect_rather_than_zeros() {
        let settings = StudySettings {
            waypoints: 4,
            xy_m: 40.0,
            z_m: 20.0,
            missions: 2,
            seed: 1,
        };
        let storm = Wind::new(13.0, 270.0).unwrap();
        let row = run_wind(&settings, &model(), Pricing::Settled, storm, &|| {}).unwrap();
        assert_eq!((row.missions, row.infeasible_missions), (0, 2), "{row:?}");
        assert_eq!(row.order_changed_pct, None);
        assert_eq!(row.saving, None);
        assert_eq!(row.wind_effect_mean_pct, None);
    }
}
