//! The mission a vehicle holds, measured: read back from the autopilot when a flight starts
//! (whoever uploaded it: emplan, or a pilot with QGroundControl) and made the flight plan the
//! flight is measured against, its points named after the mission it is. `emplan record` and
//! the service's vehicle actor both ask [`held_flight_plan`]; the actor asks [`same_flight`]
//! whether what the vehicle holds is what it uploaded.

use crate::flightlog::flight_plan::FlightPlan;
use crate::link::connection::{Autopilot, Link};
use crate::link::driver::{download, DriverError};
use crate::link::items::{read_flight, FlightItems};
use crate::link::mav::MISSION_ITEM_INT_DATA;
use crate::link::transfer::TransferConfig;
use crate::link::Flavour;
use crate::mission::rehome::HomeOffset;
use crate::mission::{Enu, Geodetic, Mission};
use crate::physics::VehicleModel;

use super::predict::{plan_from_items, FlightItemsError};

/// Which mission the held flight is, as far as the caller knows.
#[derive(Debug, Clone, Copy)]
pub enum Known<'m> {
    /// The one the user named (`record --mission`), or none: the flight is read at its home
    /// altitude and named after it ("flight" without one).
    Named(Option<&'m Mission>),
    /// Whichever of these it is ([`mission_of`]; "flight" when none is): the service's
    /// catalog, several missions of a field sharing its home.
    Among(&'m [&'m Mission]),
}

/// Why the mission a vehicle holds could not be measured.
#[derive(Debug, thiserror::Error)]
pub enum HeldError {
    #[error("reading the vehicle's mission failed: {0}")]
    Download(#[from] DriverError),
    #[error("the vehicle's mission cannot be measured: {0}")]
    Unmeasurable(#[from] FlightItemsError),
}

/// What a vehicle flies: its mission read back now over `transfer`, as a FlightPlan named
/// after the mission it is (see [`Known`]), whose waypoints name the points ("origin" and
/// "item N" where none does); legs priced with `model`.
pub async fn held_flight_plan(
    link: &Link,
    target: &Autopilot,
    transfer: TransferConfig,
    known: Known<'_>,
    model: &VehicleModel,
) -> Result<FlightPlan, HeldError> {
    let items = download(link, target, transfer).await?;
    let (mission, read) = match known {
        Known::Named(mission) => {
            let home_alt_m = mission.map_or(0.0, |m| m.origin.home.alt_m);
            let read =
                read_flight(&items, target.flavour, home_alt_m).map_err(FlightItemsError::from)?;
            (mission, read)
        }
        Known::Among(missions) => {
            let read = read_flight(&items, target.flavour, 0.0).map_err(FlightItemsError::from)?;
            match mission_of(&items, target.flavour, read.home, missions) {
                Some((m, read)) => (Some(m), read),
                None => (None, read),
            }
        }
    };
    let name = mission.map_or("flight", |m| m.name.as_str());
    Ok(plan_from_items(name, &read, mission, Some(model))?)
}

/// Which of `missions` the flight `items` (taking off at `takeoff`) is: of those whose home is
/// the take-off point (within 2 m), the one whose waypoints are the most of its points (within
/// 1 m), then the one with the fewest waypoints besides (several missions of a field share its
/// home); with the flight read at that mission's home altitude.
pub fn mission_of<'m>(
    items: &[MISSION_ITEM_INT_DATA],
    flavour: Flavour,
    takeoff: Geodetic,
    missions: &[&'m Mission],
) -> Option<(&'m Mission, FlightItems)> {
    let near = |a: &Enu, b: &Enu| {
        (a.x_east_m - b.x_east_m)
            .hypot(a.y_north_m - b.y_north_m)
            .hypot(a.z_up_m - b.z_up_m)
            < 1.0
    };
    missions
        .iter()
        .filter_map(|&m| {
            if HomeOffset::of(m, takeoff).horizontal_m >= 2.0 {
                return None;
            }
            // The home altitude is the mission's when the autopilot keeps no home item.
            let read = read_flight(items, flavour, m.origin.home.alt_m).ok()?;
            let named = read
                .points
                .iter()
                .filter(|(_, enu, _)| m.waypoints.iter().any(|w| near(&w.position, enu)))
                .count();
            let others = m.waypoints.len().saturating_sub(named);
            Some(((std::cmp::Reverse(named), others), m, read))
        })
        // The first of the best.
        .min_by_key(|(score, _, _)| *score)
        .map(|(_, m, read)| (m, read))
}

/// Whether two flight plans fly the same points (same items, positions within 0.5 m, holds
/// within 1 s: ArduPilot keeps whole seconds), whatever their names and predictions.
pub fn same_flight(a: &FlightPlan, b: &FlightPlan) -> bool {
    a.takeoff_seq == b.takeoff_seq
        && a.land_seq == b.land_seq
        && (a.origin_height_m - b.origin_height_m).abs() < 0.5
        && a.points.len() == b.points.len()
        && a.points.iter().zip(&b.points).all(|(p, q)| {
            p.seq == q.seq
                && (p.hold_s - q.hold_s).abs() < 1.0
                && (p.enu.x_east_m - q.enu.x_east_m)
                    .hypot(p.enu.y_north_m - q.enu.y_north_m)
                    .hypot(p.enu.z_up_m - q.enu.z_up_m)
                    < 0.5
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::items::{mission_items, ItemOptions};

    fn sample(file: &str) -> Mission {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("missions")
            .join(file);
        crate::mission::load(&path).expect("a shipped mission")
    }

    fn read_back(mission: &Mission) -> Vec<MISSION_ITEM_INT_DATA> {
        let order: Vec<usize> = (0..mission.waypoints.len()).collect();
        mission_items(mission, &order, &ItemOptions::default()).expect("items")
    }

    #[test]
    fn a_flight_read_back_is_named_after_the_mission_it_is_among_several_of_the_same_home() {
        let three = sample("paper-sample-3wp.toml");
        let eight = sample("paper-sample-8wp.toml");
        assert!(HomeOffset::of(&three, eight.origin.home).horizontal_m < 0.5);
        let missions = [&three, &eight];
        for (flown, name) in [(&eight, "paper-sample-8wp"), (&three, "paper-sample-3wp")] {
            let items = read_back(flown);
            let read = read_flight(&items, Flavour::Px4, 0.0).expect("reads");
            let (m, read) = mission_of(&items, Flavour::Px4, read.home, &missions).expect("found");
            assert_eq!(m.name, name);
            assert_eq!(read.points.len(), flown.waypoints.len() + 1);
        }
    }
}
