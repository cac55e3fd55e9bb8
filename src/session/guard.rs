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
//!
//! "Home" is where the autopilot's return goes from that point: `mission::fence::ReturnRule`
//! (ArduPilot's nearest rally point within RALLY_LIMIT_KM, home when nearer and RALLY_INCL_HOME;
//! PX4's safe points by RTL_TYPE), its parameters read from the autopilot, else its defaults;
//! the vehicle lands there. The setup names each point's destination, so the guard's notes and
//! the report say where the return went.

use crate::flightlog::flight_plan::FlightPlan;
use crate::flightlog::watch::{GuardSetup, Policy};
use crate::link::commands::{read_params, return_home};
use crate::link::connection::{Autopilot, Link};
use crate::link::params::ReturnAltitude;
use crate::link::{Flavour, LinkError};
use crate::mission::fence::{Destination, RallyPoint, ReturnRule};
use crate::mission::Origin;
use crate::physics::budget::{return_j, ReturnDescent};
use crate::physics::{PhysicsError, Profile, Vehicle, Wind};

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

/// How an autopilot returns: the height it flies back at, where it goes and the mission's rally
/// points it may go to.
#[derive(Debug, Clone, PartialEq)]
pub struct AutopilotReturn {
    /// The return altitude (m above home).
    pub alt_m: f64,
    pub rule: ReturnRule,
    /// Whether the rule's parameters were read from the autopilot (else they are its defaults).
    pub rule_read: bool,
    pub rally: Vec<RallyPoint>,
}

impl AutopilotReturn {
    /// The defaults of an autopilot of `flavour` returning at `alt_m`, with `rally`.
    pub fn defaults(flavour: Flavour, alt_m: f64, rally: &[RallyPoint]) -> AutopilotReturn {
        AutopilotReturn {
            alt_m,
            rule: ReturnRule::default_for(flavour_name(flavour)),
            rule_read: false,
            rally: rally.to_vec(),
        }
    }

    /// "ardupilot RALLY_LIMIT_KM 0.3, RALLY_INCL_HOME 1 (read from the autopilot)": the rule
    /// and where its parameters came from.
    pub fn describe(&self) -> String {
        let source = if self.rule_read {
            "read from the autopilot"
        } else {
            "the autopilot's defaults"
        };
        let approximate = if self.rule.approximate() {
            "; it flies the mission back, priced as the straight return home"
        } else {
            ""
        };
        format!("{} ({source}{approximate})", self.rule.describe())
    }
}

fn flavour_name(flavour: Flavour) -> &'static str {
    match flavour {
        Flavour::ArduPilot => "ardupilot",
        Flavour::Px4 => "px4",
        Flavour::Generic => "generic",
    }
}

/// How `target` returns with the mission's `rally` points: its return altitude and its rule's
/// parameters (ArduPilot RALLY_LIMIT_KM and RALLY_INCL_HOME, PX4 RTL_TYPE) as it reports them,
/// each it does not answer at its default.
pub async fn autopilot_return(
    link: &Link,
    target: &Autopilot,
    rally: &[RallyPoint],
) -> Result<AutopilotReturn, LinkError> {
    let alt_m = return_altitude_m(link, target).await?;
    let mut ret = AutopilotReturn::defaults(target.flavour, alt_m, rally);
    let names = ret.rule.param_names();
    if names.is_empty() {
        return Ok(ret);
    }
    let read = read_params(link, target, names).await?;
    let value = |name: &str| {
        read.iter()
            .find(|(n, _)| n == name)
            .and_then(|(_, v)| *v)
            .filter(|v| v.is_finite())
    };
    ret.rule = ret.rule.with_params(&value);
    ret.rule_read = names.iter().all(|n| value(n).is_some());
    if !ret.rule_read {
        tracing::warn!(
            "the autopilot did not answer {}: its return is chosen by its defaults",
            names.join(", ")
        );
    }
    Ok(ret)
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

/// The rally points of `ret` in `plan`'s local frame (east, north; m).
fn rally_local(plan: &FlightPlan, ret: &AutopilotReturn) -> Vec<[f64; 2]> {
    let origin = Origin {
        home: plan.home,
        height_above_home_m: plan.origin_height_m,
    };
    (ret.rally.iter())
        .map(|r| {
            let e = r.local(&origin);
            [e.x_east_m, e.y_north_m]
        })
        .collect()
}

/// Where the return from `from` goes by `ret`'s rule: the destination, its east and north (m,
/// the mission's frame) and the height it is flown to at least (m above home: a rally point's
/// own altitude; home's is 0).
fn destination(
    ret: &AutopilotReturn,
    rally: &[[f64; 2]],
    from: &crate::mission::Enu,
) -> (Destination, [f64; 2], f64) {
    let from = [from.x_east_m, from.y_north_m];
    let to = ret.rule.destination([0.0, 0.0], rally, from);
    let alt_m = match to {
        Destination::Rally(k) => ret.rally.get(k).map_or(0.0, |r| r.alt_above_home_m),
        Destination::Home | Destination::Here => 0.0,
    };
    (to, to.at([0.0, 0.0], rally, from), alt_m)
}

/// Where the return from each of `plan`'s points goes by `ret`'s rule ([`destination`]).
pub fn destinations(plan: &FlightPlan, ret: &AutopilotReturn) -> Vec<(Destination, [f64; 2], f64)> {
    let rally = rally_local(plan, ret);
    (plan.points.iter())
        .map(|p| destination(ret, &rally, &p.enu))
        .collect()
}

/// The height (m above home) an autopilot of `flavour` flies its return to `to` at, from
/// `height`, with its return altitude `return_alt_m` and the destination's own altitude
/// `dest_alt_m`: ArduCopter climbs to the higher of RTL_ALT and the rally point's altitude
/// (mode_rtl.cpp), PX4 to RTL_RETURN_ALT above the destination (rtl.cpp
/// `computeReturnAltitude`); neither climbs to land where it is, nor descends first.
pub fn return_height_m(
    flavour: Flavour,
    to: Destination,
    height: f64,
    return_alt_m: f64,
    dest_alt_m: f64,
) -> f64 {
    let at = match (to, flavour) {
        (Destination::Here, _) => height,
        (_, Flavour::Px4) => height.max(return_alt_m + dest_alt_m),
        _ => height.max(return_alt_m).max(dest_alt_m),
    };
    at.max(0.0)
}

/// The guard's setup for `plan` flown by `vehicle` with `profile` on an autopilot of `flavour`
/// returning as `ret` says (its altitude, and where: home or a rally point, by its rule), in a
/// steady `wind` (the climb, the descent and the hovers in its speed, the flight back on its
/// heading).
pub fn setup(
    vehicle: &Vehicle,
    profile: Profile,
    flavour: Flavour,
    plan: &FlightPlan,
    policy: Policy,
    ret: &AutopilotReturn,
    wind: Wind,
) -> Result<GuardSetup, PhysicsError> {
    let return_alt_m = ret.alt_m;
    let rally = rally_local(plan, ret);
    let descent = match flavour {
        Flavour::ArduPilot => ReturnDescent::Ardupilot,
        Flavour::Px4 | Flavour::Generic => ReturnDescent::Landing,
    };
    let home_from = |p: &crate::mission::Enu| -> Result<f64, PhysicsError> {
        let (to, at_xy, dest_alt_m) = destination(ret, &rally, p);
        let height = plan.origin_height_m + p.z_up_m;
        let at_m = return_height_m(flavour, to, height, return_alt_m, dest_alt_m);
        let from = [p.x_east_m, p.y_north_m, height];
        return_j(vehicle, profile, descent, from, at_xy, at_m, wind)
    };
    let destinations = destinations(plan, ret);
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
        return_to: destinations
            .iter()
            .map(|(to, _, _)| to.describe())
            .collect(),
        return_rule: Some(ret.describe()),
        via_home_j,
        start: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::synthetic::square_plan;
    use crate::mission::Enu;

    fn rally_at(plan: &FlightPlan, x_east_m: f64, y_north_m: f64) -> RallyPoint {
        let origin = Origin {
            home: plan.home,
            height_above_home_m: plan.origin_height_m,
        };
        let g = origin.to_geodetic(Enu {
            x_east_m,
            y_north_m,
            z_up_m: 0.0,
        });
        RallyPoint {
            lat_deg: g.lat_deg,
            lon_deg: g.lon_deg,
            alt_above_home_m: 15.0,
        }
    }

    #[test]
    fn the_guard_prices_the_return_to_the_rally_point_arducopter_would_land_at() {
        let vehicle = crate::physics::builtin::vehicle().expect("the built-in vehicle");
        let plan = square_plan();
        let price = |ret: &AutopilotReturn| {
            setup(
                &vehicle,
                Profile::Ardupilot,
                Flavour::ArduPilot,
                &plan,
                Policy::Rtl,
                ret,
                Wind::CALM,
            )
            .expect("priced")
        };
        let home = price(&AutopilotReturn::defaults(Flavour::ArduPilot, 15.0, &[]));
        // A rally point beside B (60, 60): from A (60, 0) it is 55 m away against home's 60 m,
        // from B 5 m; from C (0, 60) 60.2 m against 60 m, so C (RALLY_INCL_HOME 1) and the
        // origin return home.
        let rally = [rally_at(&plan, 60.0, 55.0)];
        let ret = AutopilotReturn::defaults(Flavour::ArduPilot, 15.0, &rally);
        let to_rally = price(&ret);
        assert_eq!(
            to_rally.return_to,
            ["rally point 1", "rally point 1", "home", "home"]
        );
        assert_eq!(home.return_to, ["home"; 4]);
        assert!(to_rally.home_j[1] < home.home_j[1], "{to_rally:?} {home:?}");
        assert!(to_rally.home_j[0] < home.home_j[0]);
        assert_eq!(to_rally.home_j[2], home.home_j[2]);
        assert_eq!(to_rally.home_j[3], home.home_j[3]);
        let d = destinations(&plan, &ret)[1].1;
        assert!(
            (d[0] - 60.0).abs() < 1e-3 && (d[1] - 55.0).abs() < 1e-3,
            "{d:?}"
        );
        assert!(to_rally
            .return_rule
            .as_deref()
            .is_some_and(|r| r.contains("RALLY_LIMIT_KM 0.3") && r.contains("defaults")));
    }

    #[test]
    fn the_return_rule_takes_the_parameters_the_autopilot_answered() {
        let answered = |name: &str| match name {
            "RALLY_LIMIT_KM" => Some(0.0),
            _ => None,
        };
        assert_eq!(
            ReturnRule::default_for("ardupilot").with_params(&answered),
            ReturnRule::Ardupilot {
                limit_km: 0.0,
                include_home: true
            }
        );
        let px4 = |name: &str| (name == "RTL_TYPE").then_some(1.0);
        assert_eq!(
            ReturnRule::default_for("px4").with_params(&px4),
            ReturnRule::Px4 { rtl_type: 1 }
        );
    }
}
