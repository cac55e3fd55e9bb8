//! Legs beyond the energy table, priced exactly where the profile flies them with a steady
//! cruise. A profile that accelerates, cruises and brakes (`hvb`: each axis a trapezoid; `px4`:
//! PX4's generator at MPC_XY_CRUISE / MPC_Z_V_AUTO_*) flies a long leg as a shorter leg of the
//! same shape with more cruise in the middle: cut a stretch of steady cruise out of the long
//! leg's trajectory and what is left is the trajectory of the shorter leg, whose operation the
//! table holds. So
//!
//! E(long) = E_table(long - cut displacement) + energy of the cut stretch,
//!
//! the cut stretch priced from the model's power along the long leg's own motion (a steady
//! state, so its power is constant; PX4's clock still recovers from the departure error and is
//! integrated as flown). The cut lies before the 4 m arrival and PX4's acceptance, so the
//! settle (everything after the 4 m rule) is the table leg's. A diagonal leg's cruise has both
//! components; an `hvb` leg whose axes finish at different times has two kinds of cruise (both
//! axes, then one), each cut as needed.
//!
//! Not composable, and still refused with a typed error naming the leg: the `ptf` profile (its
//! quintic never cruises: a longer leg is a different trajectory throughout), and any leg whose
//! steady cruise is too short to bring it inside the table. The table is never extrapolated.

use super::power::Model;
use super::px4::Start;
use super::table::{EnergyTable, LegEnergy};
use super::trajectory::Trajectory;
use super::{PhysicsError, Profile};

/// Sampling step for finding the steady cruise on a trajectory given in closed form (a sampled
/// one, PX4's, is searched at its own samples).
const SEARCH_STEP_S: f64 = 0.01;
/// Steady: every acceleration component at most this (m/s^2)...
const STEADY_ACCEL_M_S2: f64 = 0.05;
/// ...and no velocity step between samples above this (m/s), which splits cruises of different
/// velocity (an `hvb` axis stopping while the other cruises on).
const STEADY_JUMP_M_S: f64 = 0.05;
/// Kept from each end of a steady stretch when cutting it.
const EDGE_S: f64 = 0.1;
/// The shorter leg is brought this far inside the table's edges (m).
const INSIDE_M: f64 = 0.5;
/// Midpoint-rule steps per second of a cut (the power is steady; PX4's speed still creeps up).
const CUT_STEPS_PER_S: f64 = 1.0;

/// A long leg priced from a table leg and the steady cruise cut out of it.
#[derive(Debug, Clone, PartialEq)]
pub struct LongLeg {
    /// The leg's energy and times, as a table lookup would give them.
    pub leg: LegEnergy,
    /// The table leg it was composed from.
    pub table_xf_m: f64,
    pub table_zf_m: f64,
    /// The stretches of steady cruise added to it.
    pub cruises: Vec<Cruise>,
}

/// One stretch of steady cruise added to a table leg.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cruise {
    pub duration_s: f64,
    /// Horizontal and vertical displacement over it (m).
    pub xf_m: f64,
    pub zf_m: f64,
    /// Battery energy over it (J).
    pub energy_j: f64,
}

/// Prices the leg (`xf_m`, `zf_m`) of `model`'s vehicle flown with `table`'s profile: from the
/// table when inside it, else as [`price_outside`] does.
pub fn price(
    model: &Model,
    table: &EnergyTable,
    xf_m: f64,
    zf_m: f64,
) -> Result<LegEnergy, PhysicsError> {
    match table.lookup(xf_m, zf_m) {
        Err(PhysicsError::OutsideTable { .. }) => price_outside(model, table, xf_m, zf_m),
        other => other,
    }
}

/// Prices a leg outside `table`: composed from a table leg and steady cruise, else (`ptf`,
/// which never cruises, or a leg whose cruise is too short to bring it inside the table: a
/// slow acceleration to a high speed) simulated directly, the very operation a table cell
/// holds. What is not a leg at all (not finite, negative across) is the table's own refusal,
/// and a leg the model cannot fly is its error.
pub fn price_outside(
    model: &Model,
    table: &EnergyTable,
    xf_m: f64,
    zf_m: f64,
) -> Result<LegEnergy, PhysicsError> {
    price_outside_from(model, table, xf_m, zf_m, Start::Behind)
}

/// [`price_outside`] for a leg starting `start` of PX4's trajectory: the long leg flown from
/// that start, composed from the table block of the same start.
pub fn price_outside_from(
    model: &Model,
    table: &EnergyTable,
    xf_m: f64,
    zf_m: f64,
    start: Start,
) -> Result<LegEnergy, PhysicsError> {
    if !(xf_m.is_finite() && zf_m.is_finite() && xf_m >= 0.0) {
        return table.lookup_from(xf_m, zf_m, start);
    }
    match compose_from(model, table, xf_m, zf_m, start) {
        Ok(long) => Ok(long.leg),
        Err(PhysicsError::LongLeg { .. }) => model
            .operation_from(table.profile, xf_m, zf_m, start)
            .map(|op| LegEnergy::from(&op)),
        Err(e) => Err(e),
    }
}

/// Composes the leg (`xf_m`, `zf_m`), outside `table`, from a table leg and steady cruise.
pub fn compose(
    model: &Model,
    table: &EnergyTable,
    xf_m: f64,
    zf_m: f64,
) -> Result<LongLeg, PhysicsError> {
    compose_from(model, table, xf_m, zf_m, Start::Behind)
}

/// [`compose`] for a leg starting `start` of PX4's trajectory.
pub fn compose_from(
    model: &Model,
    table: &EnergyTable,
    xf_m: f64,
    zf_m: f64,
    start: Start,
) -> Result<LongLeg, PhysicsError> {
    let profile = table.profile;
    let refuse = |reason: String| PhysicsError::LongLeg {
        xf_m,
        zf_m,
        profile,
        max_xf_m: table.xf.end_m,
        min_zf_m: table.zf.start_m,
        max_zf_m: table.zf.end_m,
        reason,
    };
    if !(xf_m.is_finite() && zf_m.is_finite() && xf_m >= 0.0) {
        return Err(refuse("not a leg".into()));
    }
    if profile == Profile::Ptf {
        return Err(refuse(
            "the ptf quintic never flies a steady cruise, so a longer leg is another \
             trajectory throughout"
                .into(),
        ));
    }
    let trajectory = model
        .trajectory_from(profile, xf_m, zf_m, start)
        .map_err(|e| refuse(e.to_string()))?;
    // How far the leg must shrink along each axis to fit inside the table.
    let mut need_x = (xf_m - (table.xf.end_m - INSIDE_M)).max(0.0);
    let mut need_z = if zf_m >= 0.0 {
        (zf_m - (table.zf.end_m - INSIDE_M)).max(0.0)
    } else {
        ((table.zf.start_m + INSIDE_M) - zf_m).max(0.0)
    };
    let mut windows: Vec<Window> = trajectory
        .steady_windows(SEARCH_STEP_S, STEADY_ACCEL_M_S2, STEADY_JUMP_M_S)
        .into_iter()
        .filter_map(|(start, end)| Window::new(&trajectory, start + EDGE_S, end - EDGE_S))
        .collect();
    // Cruise along one axis first (it shrinks only what must shrink), then both.
    windows.sort_by_key(|w| !(w.rate_x < 1e-6 || w.rate_z < 1e-6));
    let mut cuts = Vec::new();
    for w in &windows {
        if need_x <= 0.0 && need_z <= 0.0 {
            break;
        }
        let for_x = if w.rate_x > 1e-6 {
            need_x / w.rate_x
        } else {
            0.0
        };
        let for_z = if w.rate_z > 1e-6 {
            need_z / w.rate_z
        } else {
            0.0
        };
        let room_s = w.end_s - w.start_s;
        let mut cut_s = for_x.max(for_z).min(room_s);
        if cut_s <= 0.0 {
            continue;
        }
        // Cut the end of the stretch: the steadiest part (PX4's clock has recovered most). The
        // speed still creeps up there, so the cut's displacement is measured, and the cut
        // lengthened by what it falls short.
        let displacement = |cut_s: f64| {
            let (x0, z0) = trajectory.position_m(w.end_s - cut_s);
            let (x1, z1) = trajectory.position_m(w.end_s);
            (x1 - x0, z1 - z0)
        };
        for _ in 0..8 {
            let (dx, dz) = displacement(cut_s);
            let mut short_s: f64 = 0.0;
            if w.rate_x > 1e-6 {
                short_s = short_s.max((need_x - dx) / w.rate_x);
            }
            if w.rate_z > 1e-6 {
                short_s = short_s.max((need_z - dz.abs()) / w.rate_z);
            }
            if short_s < 1e-9 || cut_s >= room_s {
                break;
            }
            cut_s = (cut_s + short_s + 1e-6).min(room_s);
        }
        let (t0, t1) = (w.end_s - cut_s, w.end_s);
        let (dx, dz) = displacement(cut_s);
        need_x = (need_x - dx).max(0.0);
        need_z = (need_z - dz.abs()).max(0.0);
        let steps = ((cut_s * CUT_STEPS_PER_S).ceil() as usize).max(8);
        let energy_j = model
            .trajectory_energy_j(&trajectory, (t0, t1), steps)
            .map_err(|e| refuse(e.to_string()))?;
        cuts.push(Cruise {
            duration_s: cut_s,
            xf_m: dx,
            zf_m: dz,
            energy_j,
        });
    }
    if need_x > 1e-9 || need_z > 1e-9 {
        let cruise_s: f64 = windows.iter().map(|w| w.end_s - w.start_s).sum();
        return Err(refuse(format!(
            "its steady cruise ({cruise_s:.1} s before the 4 m rule) is too short to bring \
             it inside the table ({need_x:.1} m across and {need_z:.1} m vertically still \
             outside)"
        )));
    }
    let table_xf_m = xf_m - cuts.iter().map(|c| c.xf_m).sum::<f64>();
    let table_zf_m = zf_m - cuts.iter().map(|c| c.zf_m).sum::<f64>();
    let base = table
        .lookup_from(table_xf_m, table_zf_m, start)
        .map_err(|e| refuse(e.to_string()))?;
    let leg = LegEnergy {
        energy_j: base.energy_j + cuts.iter().map(|c| c.energy_j).sum::<f64>(),
        duration_s: base.duration_s + cuts.iter().map(|c| c.duration_s).sum::<f64>(),
        ..base
    };
    Ok(LongLeg {
        leg,
        table_xf_m,
        table_zf_m,
        cruises: cuts,
    })
}

/// A stretch of steady cruise that may be cut, with how fast it covers each axis.
#[derive(Debug, Clone, Copy)]
struct Window {
    start_s: f64,
    end_s: f64,
    rate_x: f64,
    rate_z: f64,
}

impl Window {
    fn new(trajectory: &Trajectory, start_s: f64, end_s: f64) -> Option<Window> {
        if end_s <= start_s {
            return None;
        }
        let (vx, vz, _, _) = trajectory.kinematics(end_s);
        Some(Window {
            start_s,
            end_s,
            rate_x: vx.abs(),
            rate_z: vz.abs(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::table::Axis;
    use crate::physics::vehicle::shipped;
    use crate::physics::{simulate_operation, Vehicle};

    /// A coarse table (Xf 0..150 every 5 m, Zf -60..60 every 2 m) built for the test.
    fn table(vehicle: &Vehicle, profile: Profile) -> EnergyTable {
        let xf = Axis::new(0.0, 150.0, 31);
        let zf = Axis::new(-60.0, 60.0, 61);
        EnergyTable::build(vehicle, profile, xf, zf, |_, _| {}).unwrap()
    }

    #[test]
    fn a_long_leg_is_a_table_leg_plus_steady_cruise_within_a_fraction_of_a_percent() {
        let v = shipped();
        let model = Model::new(&v);
        for profile in [Profile::Hvb, Profile::Px4] {
            let t = table(&v, profile);
            for (x, z) in [
                (300.0, 0.0),
                (800.0, 0.0),
                (300.0, 40.0),
                (800.0, -50.0),
                (20.0, 110.0),
                (0.0, -120.0),
                (600.0, 110.0),
            ] {
                let direct = simulate_operation(&v, profile, x, z).unwrap();
                let long = match compose(&model, &t, x, z) {
                    Ok(long) => long,
                    // A cruise too short to bring the leg inside the table (hvb accelerates
                    // slowly to a high speed): priced by direct simulation instead.
                    Err(PhysicsError::LongLeg { reason, .. }) if reason.contains("too short") => {
                        let priced = price(&model, &t, x, z).unwrap();
                        assert_eq!(priced, LegEnergy::from(&direct), "{profile} ({x}, {z})");
                        continue;
                    }
                    Err(e) => panic!("{profile} ({x}, {z}): {e}"),
                };
                let err =
                    (long.leg.total_energy_j() - direct.total_energy_j()) / direct.total_energy_j();
                assert!(err.abs() < 0.005, "{profile} ({x}, {z}): {err:+.4}");
                let dt = long.leg.total_duration_s() - direct.total_duration_s();
                assert!(dt.abs() < 0.5, "{profile} ({x}, {z}): {dt} s");
                assert!(t.lookup(long.table_xf_m, long.table_zf_m).is_ok());
                assert!(!long.cruises.is_empty());
            }
        }
    }

    #[test]
    fn inside_the_table_the_price_is_the_lookup_and_ptf_beyond_it_is_refused_naming_the_leg() {
        let v = shipped();
        let model = Model::new(&v);
        let t = table(&v, Profile::Px4);
        assert_eq!(
            price(&model, &t, 100.0, -20.0).unwrap(),
            t.lookup(100.0, -20.0).unwrap()
        );
        // ptf never cruises: its long legs are simulated directly.
        let ptf = table(&v, Profile::Ptf);
        let direct = LegEnergy::from(&model.operation(Profile::Ptf, 300.0, 0.0).unwrap());
        assert_eq!(price(&model, &ptf, 300.0, 0.0).unwrap(), direct);
        let err = compose(&model, &ptf, 300.0, 0.0).unwrap_err();
        assert!(matches!(err, PhysicsError::LongLeg { .. }), "{err}");
        assert!(err.to_string().contains("Xf 300.00 m"), "{err}");
        // Not a leg at all: the table's own refusal.
        assert!(matches!(
            price(&model, &t, f64::NAN, 0.0),
            Err(PhysicsError::OutsideTable { .. })
        ));
    }

    #[test]
    fn a_leg_whose_cruise_cannot_bring_it_inside_the_table_is_simulated_directly() {
        // A table too small for the leg's braking: no stretch of cruise is long enough, so
        // composing refuses and pricing simulates the leg itself.
        let v = shipped();
        let model = Model::new(&v);
        let xf = Axis::new(0.0, 10.0, 3);
        let zf = Axis::new(-5.0, 5.0, 3);
        let tiny = EnergyTable::build(&v, Profile::Px4, xf, zf, |_, _| {}).unwrap();
        let err = compose(&model, &tiny, 300.0, 0.0).unwrap_err();
        assert!(
            matches!(err, PhysicsError::LongLeg { ref reason, .. } if reason.contains("too short")),
            "{err}"
        );
        let direct = LegEnergy::from(&model.operation(Profile::Px4, 300.0, 0.0).unwrap());
        assert_eq!(price(&model, &tiny, 300.0, 0.0).unwrap(), direct);
    }
}
