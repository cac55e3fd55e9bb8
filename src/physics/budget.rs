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
    fn a_take_off_the_model_cannot_fly_is_an_error_naming_it() {
        let err = Budget::new(&shipped(), Profile::Px4, f64::NAN).unwrap_err();
        assert!(
            err.to_string().starts_with("pricing the take-off: "),
            "{err}"
        );
    }
}
