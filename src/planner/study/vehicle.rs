//! The study run with a vehicle: each setting checked against the vehicle's energy table before
//! any mission is drawn, the legs priced from the table (start to settled hover as `emplan plan`
//! prices them, or to the paper's 4 m rule with [`Pricing::Paper`]).

use std::time::Instant;

use super::{run_study, BaselineDirection, Study, StudyError, StudySettings};
use crate::physics::{EnergyTable, Pricing, Profile, VehicleModel};

/// A study run with a vehicle.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyRun {
    pub study: Study,
    pub profile: Profile,
    /// What each leg's energy counted.
    pub pricing: Pricing,
    /// Wall time of the run.
    pub seconds: f64,
}

/// What a study with a vehicle can refuse.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StudyRunError {
    #[error(
        "xy_m = {xy_m}: legs between opposite corners reach {reach_m:.1} m horizontally \
         (2 sqrt(2) XY) but the {profile} energy table covers Xf 0..{max_xf_m} m (allowed: up to \
         {allowed_xy_m:.2})"
    )]
    TooWide {
        xy_m: f64,
        reach_m: f64,
        profile: Profile,
        max_xf_m: f64,
        allowed_xy_m: f64,
    },
    #[error(
        "z_m = {z_m}: legs from the bottom to the top of the box climb {reach_m:.1} m (2 Z) but \
         the {profile} energy table covers Zf {min_zf_m}..{max_zf_m} m (allowed: up to \
         {allowed_z_m:.2})"
    )]
    TooHigh {
        z_m: f64,
        reach_m: f64,
        profile: Profile,
        min_zf_m: f64,
        max_zf_m: f64,
        allowed_z_m: f64,
    },
    #[error(
        "study of {} waypoints, XY {} m, Z {} m, seed {} ({profile} profile): {cause}",
        .settings.waypoints,
        .settings.xy_m,
        .settings.z_m,
        .settings.seed
    )]
    Run {
        settings: StudySettings,
        profile: Profile,
        cause: Box<StudyError>,
    },
}

/// Every leg of every mission of `s` must lie inside the table: refused up front, naming the
/// setting, rather than on the first unlucky mission.
pub fn check_envelope(s: &StudySettings, table: &EnergyTable) -> Result<(), StudyRunError> {
    let max_xf_m = table.xf.end_m;
    let reach_m = s.max_horizontal_leg_m();
    if reach_m > max_xf_m {
        return Err(StudyRunError::TooWide {
            xy_m: s.xy_m,
            reach_m,
            profile: table.profile,
            max_xf_m,
            allowed_xy_m: max_xf_m / (2.0 * std::f64::consts::SQRT_2),
        });
    }
    let max_zf_m = table.zf.end_m.min(-table.zf.start_m);
    let reach_m = s.max_vertical_leg_m();
    if reach_m > max_zf_m {
        return Err(StudyRunError::TooHigh {
            z_m: s.z_m,
            reach_m,
            profile: table.profile,
            min_zf_m: table.zf.start_m,
            max_zf_m: table.zf.end_m,
            allowed_z_m: max_zf_m / 2.0,
        });
    }
    Ok(())
}

/// Runs the study of `settings` with `model`'s energy table, each leg priced as `pricing` says and
/// each baseline flown in `direction`; `progress` is called once per finished mission, from any
/// thread.
pub fn run(
    settings: &StudySettings,
    model: &VehicleModel,
    pricing: Pricing,
    direction: BaselineDirection,
    progress: &(dyn Fn() + Sync),
) -> Result<StudyRun, StudyRunError> {
    check_envelope(settings, &model.table)?;
    let started = Instant::now();
    let leg_energy_j =
        |xf_m: f64, zf_m: f64| model.leg(xf_m, zf_m).map(|l| l.priced_energy_j(pricing));
    let study = run_study(settings, direction, leg_energy_j, progress).map_err(|cause| {
        StudyRunError::Run {
            settings: *settings,
            profile: model.profile,
            cause: Box::new(cause),
        }
    })?;
    Ok(StudyRun {
        study,
        profile: model.profile,
        pricing,
        seconds: started.elapsed().as_secs_f64(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planner::study::study_document;
    use crate::tour::Objective;

    fn model() -> VehicleModel {
        VehicleModel::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/s1000"),
            None,
        )
        .unwrap()
    }

    fn settings(xy_m: f64, z_m: f64) -> StudySettings {
        StudySettings {
            waypoints: 5,
            xy_m,
            z_m,
            missions: 20,
            seed: 3,
        }
    }

    #[test]
    fn settings_whose_legs_leave_the_table_are_refused_before_any_mission_is_drawn() {
        let m = model();
        let wide = run(
            &settings(60.0, 10.0),
            &m,
            Pricing::Settled,
            BaselineDirection::Better,
            &|| panic!("no mission runs"),
        )
        .unwrap_err();
        assert!(
            matches!(wide, StudyRunError::TooWide { reach_m, .. } if reach_m > 150.0),
            "{wide}"
        );
        let high = run(
            &settings(20.0, 31.0),
            &m,
            Pricing::Settled,
            BaselineDirection::Better,
            &|| panic!("no mission runs"),
        )
        .unwrap_err();
        assert!(
            matches!(high, StudyRunError::TooHigh { allowed_z_m, .. } if allowed_z_m == 30.0),
            "{high}"
        );
    }

    #[test]
    fn the_study_of_a_vehicle_prices_legs_from_its_table_and_its_view_names_the_worst_missions() {
        let m = model();
        let s = settings(30.0, 20.0);
        let done = run(&s, &m, Pricing::Settled, BaselineDirection::Better, &|| {}).unwrap();
        let direct = run_study(
            &s,
            BaselineDirection::Better,
            |x: f64, z: f64| m.table.lookup(x, z).map(|l| l.total_energy_j()),
            &|| {},
        )
        .unwrap();
        assert_eq!(done.study, direct);
        // The paper's pricing counts each leg to the 4 m rule only, and says so.
        let paper = run(&s, &m, Pricing::Paper, BaselineDirection::Better, &|| {}).unwrap();
        let direct_paper = run_study(
            &s,
            BaselineDirection::Better,
            |x: f64, z: f64| m.table.lookup(x, z).map(|l| l.energy_j),
            &|| {},
        )
        .unwrap();
        assert_eq!(paper.study, direct_paper);
        assert_ne!(paper.study, done.study);
        assert_eq!(study_document(&paper).pricing, Pricing::Paper);
        let doc = study_document(&done);
        assert_eq!(doc.summary.missions, 20);
        assert_eq!(doc.profile, m.profile);
        assert_eq!(
            doc.worst_mission.distance,
            direct.worst_mission(Objective::Distance)
        );
    }
}
