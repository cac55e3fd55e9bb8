//! The energy guard's live side: its setup priced when a flight is loaded (the pack from the
//! vehicle file, and the autopilot's return from every point of the plan and every via point
//! of a leg round a fence zone, as that autopilot flies it), and its one action: sending the vehicle home when it decides to (policy `rtl`).
//!
//! What the guard sees and decides is `flightlog::watch`, run by the recorder's segmenter, so a
//! replay of the log sees the same; this module only prices and acts.
//!
//! The return is priced as the autopilot flies RTL: a climb to its return altitude when the
//! point is lower (PX4 RTL_RETURN_ALT, ArduCopter RTL_ALT, read from the autopilot, else their
//! defaults), the straight flight home at that height, then the descent: PX4's landing as the
//! profile flies it; ArduCopter's loiter over home (RTL_LOITER_TIME, default 5 s) and its
//! descent at WPNAV_SPEED_DN (default 1.5 m/s) down to LAND_ALT_LOW (default 10 m), then
//! LAND_SPEED (default 0.5 m/s), hovering: ArduCopter SITL's return from 41 m cost about three
//! times the profile's landing (docs/ardupilot-sitl.md).

use crate::flightlog::flight_plan::FlightPlan;
use crate::flightlog::watch::{GuardSetup, Policy};
use crate::link::commands::{read_params, return_home};
use crate::link::connection::{Autopilot, Link};
use crate::link::params::ReturnAltitude;
use crate::link::{Flavour, LinkError};
use crate::physics::power::Model;
use crate::physics::{heading_deg, PhysicsError, Profile, Vehicle, Wind};

/// ArduCopter's return: loiter over home, then descend (its defaults: RTL_LOITER_TIME 5000 ms,
/// WPNAV_SPEED_DN 150 cm/s, LAND_ALT_LOW 1000 cm, LAND_SPEED 50 cm/s).
const ARDUCOPTER_LOITER_S: f64 = 5.0;
const ARDUCOPTER_DESCENT_M_S: f64 = 1.5;
const ARDUCOPTER_LAND_ALT_LOW_M: f64 = 10.0;
const ARDUCOPTER_LAND_M_S: f64 = 0.5;

/// The return altitude `target` holds (m above home), or its default when it does not answer.
pub async fn return_altitude_m(link: &Link, target: &Autopilot) -> Result<f64, LinkError> {
    let param = ReturnAltitude::of(target.flavour);
    let read = read_params(link, target, &[param.name]).await?;
    Ok(match read.first().and_then(|(_, v)| *v) {
        Some(v) if v.is_finite() && v >= 0.0 => v * param.metres_per_unit,
        _ => {
            tracing::warn!(
                "the autopilot did not answer {}: its return is priced at its default {} m",
                param.name,
                param.default_m
            );
            param.default_m
        }
    })
}

/// Sends the vehicle home because the guard decided so, and says how it went: the autopilot's
/// refusal is logged (the guard keeps watching; the pilot can still act), a link failure
/// returned.
pub async fn send_home(link: &Link, target: &Autopilot) -> Result<(), LinkError> {
    match return_home(link, target).await? {
        // Said to the user by the guard's own note and the report; a log line for the service.
        Ok(()) => tracing::info!("sent home by the energy guard"),
        Err(e) => tracing::error!(
            "the energy guard sent the vehicle home and the autopilot did not go: {e}"
        ),
    }
    Ok(())
}

/// The guard's setup for `plan` flown by `vehicle` with `profile` on an autopilot of `flavour`
/// whose return flies home at `return_alt_m` above home, in a steady `wind` (the climb, the
/// descent and the hovers in its speed, the flight home on its heading).
pub fn setup(
    vehicle: &Vehicle,
    profile: Profile,
    flavour: Flavour,
    plan: &FlightPlan,
    policy: Policy,
    return_alt_m: f64,
    wind: Wind,
) -> Result<GuardSetup, PhysicsError> {
    let still = Model::new(vehicle);
    let model = still.clone().in_wind(wind.on_heading(0.0));
    let hover_w = model.hover_power_w()?;
    let home_from = |p: &crate::mission::Enu| -> Result<f64, PhysicsError> {
        {
            let height = plan.origin_height_m + p.z_up_m;
            let at = height.max(return_alt_m).max(0.0);
            let mut energy = 0.0;
            if at > height + 0.5 {
                energy += model.operation(profile, 0.0, at - height)?.total_energy_j();
            }
            let across = p.x_east_m.hypot(p.y_north_m);
            if across > 0.5 {
                let home = wind.on_heading(heading_deg(-p.x_east_m, -p.y_north_m));
                let homeward = still.clone().in_wind(home);
                energy += homeward.operation(profile, across, 0.0)?.total_energy_j();
            }
            energy += match flavour {
                Flavour::ArduPilot => {
                    let fast = (at - ARDUCOPTER_LAND_ALT_LOW_M).max(0.0);
                    let slow = at.min(ARDUCOPTER_LAND_ALT_LOW_M);
                    let seconds = ARDUCOPTER_LOITER_S
                        + fast / ARDUCOPTER_DESCENT_M_S
                        + slow / ARDUCOPTER_LAND_M_S;
                    seconds * hover_w
                }
                Flavour::Px4 | Flavour::Generic => model.landing(profile, at)?.total_energy_j(),
            };
            Ok(energy)
        }
    };
    let home_j = (plan.points.iter())
        .map(|p| home_from(&p.enu))
        .collect::<Result<Vec<f64>, PhysicsError>>()?;
    // The return from a leg's via points: the way round a zone can take the vehicle further
    // from home than either end of the leg.
    let via_home_j = if plan.points.iter().any(|p| !p.via.is_empty()) {
        (plan.points.iter())
            .map(|p| p.via.iter().map(|v| home_from(&v.enu)).collect())
            .collect::<Result<Vec<Vec<f64>>, PhysicsError>>()?
    } else {
        Vec::new()
    };
    let b = &vehicle.battery;
    Ok(GuardSetup {
        policy,
        usable_j: vehicle.planning.usable_energy_wh * 3600.0,
        reserve_pct: vehicle.planning.reserve_pct,
        cells: b.cells,
        capacity_ah: b.capacity_ah,
        internal_resistance_ohm: b.internal_resistance_ohm,
        ocv_soc: b.ocv_soc.clone(),
        ocv_cell_v: b.ocv_cell_v.clone(),
        home_j,
        via_home_j,
    })
}
