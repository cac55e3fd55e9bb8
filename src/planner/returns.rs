//! The autopilot's return from every point of the flown order, as the plan sees it: where it
//! goes (home or a rally point, by the autopilot's rule at its defaults: the plan has not met
//! the autopilot; `mission::fence::ReturnRule`), what it costs (`physics::budget::return_j`, the
//! guard's own pricing), whether the battery still lands with its reserve after turning back
//! there, and whether its straight line crosses an exclusion zone of the mission's fence.
//!
//! Only a mission with a fence or rally points gets it: without them every return goes home
//! over no zone, as the plan always assumed.

use serde::Serialize;

use super::{Plan, PlannerError};
use crate::mission::fence::{exclusions_crossed, Destination, ReturnRule};
use crate::mission::Mission;
use crate::physics::budget::{return_j, ReturnDescent};
use crate::physics::{Profile, VehicleModel};

/// The return altitudes the plan assumes (the autopilots' defaults): ArduCopter RTL_ALT 1500 cm,
/// PX4 RTL_RETURN_ALT 60 m (`link::params::ReturnAltitude`, which the guard reads instead).
const ARDUCOPTER_RTL_ALT_M: f64 = 15.0;
const PX4_RTL_RETURN_ALT_M: f64 = 60.0;

/// The return from one point of the flown order.
#[derive(Debug, Clone, PartialEq)]
pub struct ReturnFrom {
    /// The waypoint turned back at.
    pub from: String,
    /// Where the return goes: "home", "rally point 1".
    pub to: String,
    /// The return, climb to landing (J).
    pub energy_j: f64,
    /// What the flight spent before turning back there: take-off, the legs and holds up to and
    /// with that waypoint's (J).
    pub spent_j: f64,
    /// The exclusion zones its straight line crosses ("exclusion polygon 2").
    pub crosses: Vec<String>,
}

/// The returns of the flown order.
#[derive(Debug, Clone, PartialEq)]
pub struct Returns {
    /// The rule and its parameters ("RTL_TYPE 0 (the autopilot's defaults)").
    pub rule: String,
    pub from: Vec<ReturnFrom>,
    /// What one battery may spend before its reserve (J).
    pub usable_j: f64,
    /// Every return lands with the reserve: spent and return within `usable_j`.
    pub fits: bool,
    /// What the user is told: each return over an exclusion zone, each that lands below the
    /// reserve.
    pub warnings: Vec<String>,
}

/// The autopilot whose rule the plan assumes: ArduCopter's for the `ardupilot` profile, PX4's
/// otherwise (the profiles `ptf` and `hvb` are flown on it here).
fn rule_for(profile: Profile) -> (ReturnRule, ReturnDescent, f64) {
    match profile {
        Profile::Ardupilot => (
            ReturnRule::default_for("ardupilot"),
            ReturnDescent::Ardupilot,
            ARDUCOPTER_RTL_ALT_M,
        ),
        _ => (
            ReturnRule::default_for("px4"),
            ReturnDescent::Landing,
            PX4_RTL_RETURN_ALT_M,
        ),
    }
}

/// The returns from every waypoint of `plan`'s flown order, for a mission with a fence or rally
/// points (None otherwise).
pub fn of(
    plan: &Plan,
    mission: &Mission,
    model: &VehicleModel,
) -> Result<Option<Returns>, PlannerError> {
    if mission.rally.is_empty() && mission.fence.is_empty() {
        return Ok(None);
    }
    let Some(order) = plan.orders.get(plan.flown) else {
        return Ok(None);
    };
    let (rule, descent, return_alt_m) = rule_for(model.profile);
    let origin = &mission.origin;
    let rally: Vec<[f64; 2]> = (mission.rally.iter())
        .map(|r| {
            let e = r.local(origin);
            [e.x_east_m, e.y_north_m]
        })
        .collect();
    let zones: Vec<_> = (mission.fence.zones.iter())
        .map(|z| z.local(origin))
        .collect();
    let mut spent_j = plan.budget.takeoff_j();
    let mut from = Vec::new();
    for leg in &order.legs {
        if leg.to == 0 {
            continue;
        }
        let Some(w) = mission.waypoints.get(leg.to - 1) else {
            continue;
        };
        spent_j += leg.settled_energy_j() + plan.budget.hover_j(w.hold_s());
        let here = [w.position.x_east_m, w.position.y_north_m];
        let height = origin.height_above_home_m + w.position.z_up_m;
        let to = rule.destination([0.0, 0.0], &rally, here);
        let at = to.at([0.0, 0.0], &rally, here);
        let dest_alt_m = match to {
            Destination::Rally(k) => mission.rally.get(k).map_or(0.0, |r| r.alt_above_home_m),
            Destination::Home | Destination::Here => 0.0,
        };
        let at_m = match (to, descent) {
            (Destination::Here, _) => height,
            (_, ReturnDescent::Landing) => height.max(return_alt_m + dest_alt_m),
            (_, ReturnDescent::Ardupilot) => height.max(return_alt_m).max(dest_alt_m),
        };
        let energy_j = return_j(
            &model.vehicle,
            model.profile,
            descent,
            [here[0], here[1], height],
            at,
            at_m,
            model.wind,
        )
        .map_err(|e| PlannerError::Return {
            waypoint: w.name.clone(),
            to: to.describe(),
            message: e.to_string(),
        })?;
        let crosses = exclusions_crossed(&zones, here, at, 0.0)
            .into_iter()
            .filter_map(|k| mission.fence.zones.get(k - 1).map(|z| z.describe(k)))
            .collect();
        from.push(ReturnFrom {
            from: w.name.clone(),
            to: to.describe(),
            energy_j,
            spent_j,
            crosses,
        });
    }
    let usable_j = plan.budget.usable_j;
    let mut warnings = Vec::new();
    for r in &from {
        for zone in &r.crosses {
            warnings.push(format!(
                "the autopilot's return from {} to {} flies straight across {zone}",
                r.from, r.to
            ));
        }
    }
    let short: Vec<&ReturnFrom> = (from.iter())
        .filter(|r| r.spent_j + r.energy_j > usable_j)
        .collect();
    if let Some(first) = short.first() {
        warnings.push(format!(
            "turning back at {} ({} of {} waypoints) and returning to {} would land below the {}% reserve: {:.1} kJ spent and {:.1} kJ to return against {:.1} kJ usable",
            first.from,
            short.len(),
            from.len(),
            first.to,
            plan.budget.reserve_pct,
            first.spent_j / 1e3,
            first.energy_j / 1e3,
            usable_j / 1e3
        ));
    }
    let source = if rule.approximate() {
        "the autopilot's defaults; approximated"
    } else {
        "the autopilot's defaults"
    };
    Ok(Some(Returns {
        rule: format!("{} ({source})", rule.describe()),
        fits: short.is_empty(),
        from,
        usable_j,
        warnings,
    }))
}

/// `"returns"` in `emplan plan --json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReturnsJson {
    pub rule: String,
    pub from: Vec<ReturnFromJson>,
    pub budget_kj: f64,
    pub fits: bool,
    pub warnings: Vec<String>,
}

/// One return in [`ReturnsJson`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReturnFromJson {
    pub from: String,
    pub to: String,
    pub energy_kj: f64,
    pub spent_kj: f64,
    pub crosses: Vec<String>,
}

impl Returns {
    /// Its JSON view.
    pub fn json(&self) -> ReturnsJson {
        ReturnsJson {
            rule: self.rule.clone(),
            from: (self.from.iter())
                .map(|r| ReturnFromJson {
                    from: r.from.clone(),
                    to: r.to.clone(),
                    energy_kj: r.energy_j / 1e3,
                    spent_kj: r.spent_j / 1e3,
                    crosses: r.crosses.clone(),
                })
                .collect(),
            budget_kj: self.usable_j / 1e3,
            fits: self.fits,
            warnings: self.warnings.clone(),
        }
    }
}
