//! What a flight pays besides its legs, and what one battery may spend on it: the take-off from
//! the ground to the origin's hover height, hovering at the waypoints, the landing back down,
//! and the battery's usable energy after its reserve. Energies in J.
//!
//! Take-off and landing are simulated as the vertical operations (0, +h) and (0, -h) of the
//! mission's profile, start to settled hover, like every leg (paper notes section 2: an operation
//! is a hover-to-hover move), except with the `px4` profile, which flies them as PX4 does
//! (`Model::takeoff`, `Model::landing`: NAV_TAKEOFF climbs at MPC_TKO_SPEED below
//! MPC_LAND_ALT1 and is done NAV_MC_ALT_RAD below its altitude; NAV_LAND slows to
//! MPC_LAND_SPEED near the ground and ends at touchdown); hovering costs the model's hover power
//! for the waypoint's hover time.

use super::power::Model;
use super::{Operation, PhysicsError, Profile, Vehicle};
use crate::mission::wind::Wind;

/// The fixed costs of flights from one origin with one vehicle and profile, and its battery.
#[derive(Debug, Clone, PartialEq)]
pub struct Budget {
    /// The take-off from the ground to hover at the origin.
    pub takeoff: Operation,
    /// The landing from hover at the origin to the ground.
    pub landing: Operation,
    /// Battery power in hover (W).
    pub hover_power_w: f64,
    /// Energy one battery may spend on a flight, after its reserve (J).
    pub usable_j: f64,
    /// The reserve left in the battery (% of its usable energy).
    pub reserve_pct: f64,
}

/// One flight (take-off, legs, hovering, landing) against one battery.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatteryCheck {
    pub takeoff_j: f64,
    pub legs_j: f64,
    pub hover_j: f64,
    pub landing_j: f64,
    /// Everything: take-off and landing, then legs, then hovering.
    pub total_j: f64,
    /// What the battery may spend after its reserve.
    pub usable_j: f64,
    pub reserve_pct: f64,
    /// Whether the total fits the usable energy.
    pub feasible: bool,
    /// Energy over the usable energy (0 when feasible).
    pub excess_j: f64,
}

impl Budget {
    /// Prices the take-off and landing between the ground and `height_above_home_m` with
    /// `profile`, and the hover, for `vehicle`.
    pub fn new(
        vehicle: &Vehicle,
        profile: Profile,
        height_above_home_m: f64,
    ) -> Result<Budget, PhysicsError> {
        Budget::in_wind(vehicle, profile, height_above_home_m, Wind::CALM)
    }

    /// [`Budget::new`] in a steady `wind`: the take-off, landing and hover in it (a vertical
    /// move and a hover see only its speed).
    pub fn in_wind(
        vehicle: &Vehicle,
        profile: Profile,
        height_above_home_m: f64,
        wind: Wind,
    ) -> Result<Budget, PhysicsError> {
        let pricing = |what: &'static str| {
            move |e: PhysicsError| PhysicsError::Pricing {
                what,
                source: Box::new(e.in_wind(wind)),
            }
        };
        let h = height_above_home_m;
        if !h.is_finite() {
            return Err(pricing("take-off")(PhysicsError::NotFinite {
                what: "height_above_home_m",
                value: h,
            }));
        }
        let model = Model::new(vehicle).in_wind(wind.on_heading(0.0));
        Ok(Budget {
            takeoff: model.takeoff(profile, h).map_err(pricing("take-off"))?,
            landing: model.landing(profile, h).map_err(pricing("landing"))?,
            hover_power_w: model.hover_power_w().map_err(pricing("hover"))?,
            usable_j: vehicle.mission_budget_j(),
            reserve_pct: vehicle.planning.reserve_pct,
        })
    }

    /// Energy of the take-off, start to settled hover.
    pub fn takeoff_j(&self) -> f64 {
        self.takeoff.total_energy_j()
    }

    /// Energy of the landing, start to settled on the ground.
    pub fn landing_j(&self) -> f64 {
        self.landing.total_energy_j()
    }

    /// What every flight pays whatever it visits: take-off and landing.
    pub fn fixed_j(&self) -> f64 {
        self.takeoff_j() + self.landing_j()
    }

    /// Energy of hovering `hover_s` seconds.
    pub fn hover_j(&self, hover_s: f64) -> f64 {
        self.hover_power_w * hover_s
    }

    /// A flight whose legs take `legs_j` and whose hovering takes `hover_j` against the battery.
    pub fn check(&self, legs_j: f64, hover_j: f64) -> BatteryCheck {
        let total_j = self.fixed_j() + legs_j + hover_j;
        BatteryCheck {
            takeoff_j: self.takeoff_j(),
            legs_j,
            hover_j,
            landing_j: self.landing_j(),
            total_j,
            usable_j: self.usable_j,
            reserve_pct: self.reserve_pct,
            feasible: total_j <= self.usable_j,
            excess_j: (total_j - self.usable_j).max(0.0),
        }
    }
}

/// How an autopilot comes down at the end of its return.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReturnDescent {
    /// ArduCopter: a loiter over the destination (RTL_LOITER_TIME, default 5 s), the descent at
    /// WPNAV_SPEED_DN (default 1.5 m/s) down to LAND_ALT_LOW (default 10 m), then LAND_SPEED
    /// (default 0.5 m/s), all priced as hovering: ArduCopter SITL's return from 41 m cost about
    /// three times the profile's landing (docs/ardupilot-sitl.md).
    Ardupilot,
    /// The profile's landing (PX4's NAV_LAND as the `px4` profile flies it).
    Landing,
}

/// ArduCopter's return: loiter over the destination, then descend (its defaults: RTL_LOITER_TIME
/// 5000 ms, WPNAV_SPEED_DN 150 cm/s, LAND_ALT_LOW 1000 cm, LAND_SPEED 50 cm/s).
const ARDUCOPTER_LOITER_S: f64 = 5.0;
const ARDUCOPTER_DESCENT_M_S: f64 = 1.5;
const ARDUCOPTER_LAND_ALT_LOW_M: f64 = 10.0;
const ARDUCOPTER_LAND_M_S: f64 = 0.5;

/// One return flown as the autopilot flies it, in a steady `wind`: from `from` (east, north,
/// height above home; m) the climb to `at_m` above home when it is higher, the straight
/// flight at that height to `to` (east, north), then the descent there and the landing (J).
pub fn return_j(
    vehicle: &Vehicle,
    profile: Profile,
    descent: ReturnDescent,
    from: [f64; 3],
    to: [f64; 2],
    at_m: f64,
    wind: Wind,
) -> Result<f64, PhysicsError> {
    let still = Model::new(vehicle);
    let model = still.clone().in_wind(wind.on_heading(0.0));
    let height = from[2];
    let at = at_m.max(height).max(0.0);
    let mut energy = 0.0;
    if at > height + 0.5 {
        energy += model.operation(profile, 0.0, at - height)?.total_energy_j();
    }
    let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
    let across = dx.hypot(dy);
    if across > 0.5 {
        let on = wind.on_heading(crate::mission::wind::heading_deg(dx, dy));
        energy += still
            .in_wind(on)
            .operation(profile, across, 0.0)?
            .total_energy_j();
    }
    energy += match descent {
        ReturnDescent::Ardupilot => {
            let fast = (at - ARDUCOPTER_LAND_ALT_LOW_M).max(0.0);
            let slow = at.min(ARDUCOPTER_LAND_ALT_LOW_M);
            let seconds =
                ARDUCOPTER_LOITER_S + fast / ARDUCOPTER_DESCENT_M_S + slow / ARDUCOPTER_LAND_M_S;
            seconds * model.hover_power_w()?
        }
        ReturnDescent::Landing => model.landing(profile, at)?.total_energy_j(),
    };
    Ok(energy)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::hover_power_w;
    use crate::physics::simulate_operation;
    use crate::physics::vehicle::shipped;

    #[test]
    fn the_budget_prices_take_off_as_a_climb_and_landing_as_a_descent_of_the_origin_height() {
        let v = shipped();
        let b = Budget::new(&v, Profile::Hvb, 30.0).unwrap();
        let climb = simulate_operation(&v, Profile::Hvb, 0.0, 30.0).unwrap();
        let descent = simulate_operation(&v, Profile::Hvb, 0.0, -30.0).unwrap();
        assert_eq!(b.takeoff_j(), climb.total_energy_j());
        assert_eq!(b.landing_j(), descent.total_energy_j());
        assert!(b.takeoff_j() > b.hover_j(climb.total_duration_s()) * 0.5);
        assert_eq!(b.hover_j(10.0), 10.0 * hover_power_w(&v).unwrap());
        // 200 Wh usable, 20 % reserve.
        assert_eq!(b.usable_j, 576_000.0);
        assert_eq!(b.reserve_pct, 20.0);
    }

    #[test]
    fn the_px4_budget_prices_px4s_own_take_off_and_landing() {
        let v = shipped();
        let b = Budget::new(&v, Profile::Px4, 30.0).unwrap();
        let model = Model::new(&v);
        assert_eq!(b.takeoff, model.takeoff(Profile::Px4, 30.0).unwrap());
        assert_eq!(b.landing, model.landing(Profile::Px4, 30.0).unwrap());
        // NAV_TAKEOFF's slow climb below MPC_LAND_ALT1 and NAV_LAND's slow final metres take
        // longer than the plain vertical operations.
        let climb = simulate_operation(&v, Profile::Px4, 0.0, 30.0).unwrap();
        let descent = simulate_operation(&v, Profile::Px4, 0.0, -30.0).unwrap();
        assert!(b.takeoff.total_duration_s() > climb.total_duration_s() + 2.0);
        assert!(b.landing.total_duration_s() > descent.total_duration_s() + 5.0);
        assert!(b.landing_j() > descent.total_energy_j());
    }

    #[test]
    fn a_flight_over_the_usable_energy_is_infeasible_by_its_excess() {
        let b = Budget::new(&shipped(), Profile::Px4, 20.0).unwrap();
        let fits = b.check(100_000.0, 50_000.0);
        assert!(fits.feasible);
        assert_eq!(fits.excess_j, 0.0);
        assert_eq!(fits.total_j, b.fixed_j() + 100_000.0 + 50_000.0);
        let over = b.check(500_000.0, 100_000.0);
        assert!(!over.feasible);
        assert!((over.excess_j - (over.total_j - 576_000.0)).abs() < 1e-9);
    }

    #[test]
    fn a_return_costs_more_the_farther_its_destination_and_its_climb() {
        let v = shipped();
        let price = |to: [f64; 2], at_m: f64| {
            return_j(
                &v,
                Profile::Px4,
                ReturnDescent::Landing,
                [60.0, 0.0, 20.0],
                to,
                at_m,
                Wind::CALM,
            )
            .unwrap()
        };
        let home = price([0.0, 0.0], 20.0);
        let near = price([50.0, 0.0], 20.0);
        let here = price([60.0, 0.0], 20.0);
        assert!(here < near && near < home, "{here} {near} {home}");
        let landing = Model::new(&v).landing(Profile::Px4, 20.0).unwrap();
        assert!(
            (here / landing.total_energy_j() - 1.0).abs() < 1e-9,
            "{here}"
        );
        assert!(price([0.0, 0.0], 40.0) > home);
    }

    #[test]
    fn a_take_off_the_model_cannot_fly_is_an_error_naming_it() {
        let err = Budget::new(&shipped(), Profile::Px4, f64::NAN).unwrap_err();
        assert!(
            err.to_string().starts_with("pricing the take-off: "),
            "{err}"
        );
    }
}
