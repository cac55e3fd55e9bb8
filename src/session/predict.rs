//! What a flight is measured against (`flightlog::flight_plan::FlightPlan`): from a planner `Plan` when emplan
//! planned and uploaded the mission (`fly`), or from the mission items the autopilot holds when
//! someone else did (`record` reads them back, `replay` finds them in the log), priced with the
//! vehicle's energy table.
//!
//! The items are read as a flight by `link::items::read_flight` (the MAVLink side).

use crate::flightlog::flight_plan::{
    FlightPlan, PlannedPoint, Predicted, PredictedLeg, PricedBy, ORIGIN_NAME,
};
use crate::flightlog::FlightLogError;
use crate::link::items::{flight_items_noted, FlightItems, ItemOptions, ReadItemsError};
use crate::link::Flavour;
use crate::mission::{Enu, Mission};
use crate::physics::power::Model;
use crate::physics::{start_case, Budget, Profile, Vehicle, VehicleModel};
use crate::planner::{Flight, Plan};

/// The prediction of `flight` (the flown order or a sortie of `plan`): each leg to the 4 m rule
/// and its settle, take-off, landing, hover power.
pub fn predicted(plan: &Plan, flight: &Flight<'_>) -> Predicted {
    Predicted {
        takeoff_j: plan.budget.takeoff.total_energy_j(),
        landing_j: plan.budget.landing.total_energy_j(),
        legs: flight
            .legs
            .iter()
            .map(|leg| PredictedLeg {
                energy_j: leg.predicted.energy_j,
                duration_s: leg.predicted.duration_s,
                settle_energy_j: leg.predicted.settle_energy_j,
                settle_duration_s: leg.predicted.settle_duration_s,
            })
            .collect(),
        hover_power_w: plan.budget.hover_power_w,
    }
}

/// The prediction of `flight` priced by simulating each leg, the take-off and the landing of
/// `vehicle` with `profile` directly, not from the table: for an autopilot whose trajectory
/// parameters differ from the vehicle file's (a few legs simulate in milliseconds); each leg at
/// the speed in force on the way to its end (`speeds_m_s[node]`, the plan's; None: the
/// vehicle's own).
///
/// A leg round a fence zone (`planner::Leg::via`, its ends the waypoints of `mission` its
/// nodes name) is priced as the chain of straight legs through its via points, each after the
/// one before it ([`chained`]).
pub fn predicted_by_simulation(
    vehicle: &Vehicle,
    profile: Profile,
    mission: &Mission,
    flight: &Flight<'_>,
    speeds_m_s: &[Option<f64>],
) -> Result<Predicted, FlightItemsError> {
    let pricing = |e: crate::physics::PhysicsError| FlightItemsError::Pricing(e.to_string());
    let origin_height_m = mission.origin.height_above_home_m;
    let budget = Budget::new(vehicle, profile, origin_height_m).map_err(pricing)?;
    let position = |node: usize| match node {
        0 => Some(Enu::default()),
        n => mission.waypoints.get(n - 1).map(|w| w.position),
    };
    let legs = flight
        .legs
        .iter()
        .map(|leg| {
            let at_speed = speeds_m_s
                .get(leg.to)
                .copied()
                .flatten()
                .map(|v| vehicle.at_speed(v));
            let model = Model::new(at_speed.as_ref().unwrap_or(vehicle));
            let price = |xf: f64, zf: f64, start| {
                let op = model.operation_from(profile, xf, zf, start).map_err(|e| {
                    FlightItemsError::Pricing(format!(
                        "leg {} (Xf {xf:.1} m, Zf {zf:.1} m): {e}",
                        leg.to
                    ))
                })?;
                Ok(PredictedLeg {
                    energy_j: op.energy_j,
                    duration_s: op.duration_s,
                    settle_energy_j: op.settle_energy_j,
                    settle_duration_s: op.settle_duration_s,
                })
            };
            let ends = position(leg.from).zip(position(leg.to));
            match ends {
                Some((from, to)) if !leg.via.is_empty() => {
                    let path: Vec<Enu> = std::iter::once(from)
                        .chain(leg.via.iter().copied())
                        .chain(std::iter::once(to))
                        .collect();
                    let mut previous = None;
                    let parts = path
                        .windows(2)
                        .map(|w| {
                            let (dx, dy) = (
                                w[1].x_east_m - w[0].x_east_m,
                                w[1].y_north_m - w[0].y_north_m,
                            );
                            let start = start_case(previous, (dx, dy));
                            previous = Some((dx, dy));
                            price(dx.hypot(dy), w[1].z_up_m - w[0].z_up_m, start)
                        })
                        .collect::<Result<Vec<_>, FlightItemsError>>()?;
                    Ok(chained(&parts))
                }
                _ => price(leg.horizontal_m, leg.vertical_m, leg.start),
            }
        })
        .collect::<Result<Vec<_>, FlightItemsError>>()?;
    Ok(Predicted {
        takeoff_j: budget.takeoff.total_energy_j(),
        landing_j: budget.landing.total_energy_j(),
        legs,
        hover_power_w: budget.hover_power_w,
    })
}

/// The FlightPlan of `flight` uploaded to an autopilot of `flavour` with `link::items`' layout.
pub fn flight_plan(
    mission: &Mission,
    plan: &Plan,
    flight: &Flight<'_>,
    flavour: Flavour,
) -> Result<FlightPlan, FlightLogError> {
    flight_plan_predicted(mission, flight, flavour, predicted(plan, flight))
}

/// The FlightPlan of `flight` uploaded to an autopilot of `flavour`, measured against
/// `predicted`.
pub fn flight_plan_predicted(
    mission: &Mission,
    flight: &Flight<'_>,
    flavour: Flavour,
    predicted: Predicted,
) -> Result<FlightPlan, FlightLogError> {
    let first_seq = if flavour == Flavour::ArduPilot { 1 } else { 0 };
    let plan = FlightPlan::for_mission(mission, &flight.waypoints(), first_seq, Some(predicted))?;
    let via = flight_via(flight);
    let routed = via.iter().any(|v| !v.is_empty());
    if !mission.has_actions() && !routed {
        return Ok(plan);
    }
    // Commands and via points sit between the waypoints' items: number the points as the
    // items do.
    let options = ItemOptions {
        flavour,
        ..ItemOptions::default()
    };
    let (_, _, layout) =
        flight_items_noted(mission, &flight.waypoints(), &via, &options).map_err(|e| {
            FlightLogError::Plan {
                reason: format!("mission items: {e}"),
            }
        })?;
    plan.renumbered(layout.takeoff_seq, &layout.point_seqs, layout.land_seq)?
        .routed(&via, &layout.via_seqs)
}

/// Each leg's via points round a fence zone, in the flight's order (the return leg last).
pub fn flight_via(flight: &Flight<'_>) -> Vec<Vec<Enu>> {
    flight.legs.iter().map(|leg| leg.via.clone()).collect()
}

/// One leg flown as a chain of `parts` (the straight legs to its via points, then to its end):
/// to the arrival at its end is every part but the last whole (each to its via point as
/// priced, settle included), then the last to its arrival; the settle is the last's.
pub fn chained(parts: &[PredictedLeg]) -> PredictedLeg {
    let Some((last, before)) = parts.split_last() else {
        return PredictedLeg {
            energy_j: 0.0,
            duration_s: 0.0,
            settle_energy_j: 0.0,
            settle_duration_s: 0.0,
        };
    };
    let (energy_j, duration_s) = before.iter().fold((0.0, 0.0), |(e, t), p| {
        (
            e + p.energy_j + p.settle_energy_j,
            t + p.duration_s + p.settle_duration_s,
        )
    });
    PredictedLeg {
        energy_j: energy_j + last.energy_j,
        duration_s: duration_s + last.duration_s,
        ..*last
    }
}

/// Why a flight could not be read or priced.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FlightItemsError {
    #[error(transparent)]
    Items(#[from] ReadItemsError),
    #[error("pricing the legs: {0}")]
    Pricing(String),
    #[error("{0}")]
    Plan(String),
}

impl From<FlightLogError> for FlightItemsError {
    fn from(e: FlightLogError) -> Self {
        FlightItemsError::Plan(e.to_string())
    }
}

/// A FlightPlan from the mission items an autopilot holds, read by `link::items::read_flight`
/// (its home altitude from the mission's when there is no home item). Points are named after the
/// waypoints of `mission` they coincide with (within 1 m), "origin" for the origin, or
/// "item N"; legs are priced with `model` when given. The flight returns to the origin: a last
/// point away from the origin gets the origin appended only in the name of its leg (the
/// landing then starts there).
pub fn plan_from_items(
    name: &str,
    read: &FlightItems,
    mission: Option<&Mission>,
    model: Option<&VehicleModel>,
) -> Result<FlightPlan, FlightItemsError> {
    let name_of = |enu: &Enu| {
        let near = |a: &Enu, b: &Enu| {
            (a.x_east_m - b.x_east_m)
                .hypot(a.y_north_m - b.y_north_m)
                .hypot(a.z_up_m - b.z_up_m)
                < 1.0
        };
        if near(enu, &Enu::default()) {
            return Some(ORIGIN_NAME.to_string());
        }
        mission.and_then(|m| {
            m.waypoints
                .iter()
                .find(|w| near(&w.position, enu))
                .map(|w| w.name.clone())
        })
    };
    let points: Vec<PlannedPoint> = read
        .points
        .iter()
        .enumerate()
        .map(|(k, &(seq, enu, hold_s))| PlannedPoint {
            seq,
            name: name_of(&enu).unwrap_or_else(|| format!("item {seq}")),
            enu,
            hold_s,
            photos: read.photos.get(k).copied().unwrap_or(0),
            via: Vec::new(),
        })
        .collect();
    let predicted = match model {
        Some(model) => Some(price_points(model, read.origin_height_m, &points)?),
        None => None,
    };
    let plan = FlightPlan {
        mission: name.to_string(),
        home: read.home,
        origin_height_m: read.origin_height_m,
        points,
        takeoff_seq: Some(read.takeoff_seq),
        land_seq: read.land_seq,
        predicted,
        resumes: None,
        guard: None,
        wind: model.map(|m| m.wind).filter(|w| !w.is_calm()),
        repricings: Vec::new(),
        priced_by: model.map(priced_by),
        blocks: Vec::new(),
        pack: None,
    };
    plan.validate()?;
    Ok(plan)
}

/// What `model` prices with, as plan.json keeps it.
pub fn priced_by(model: &VehicleModel) -> PricedBy {
    PricedBy {
        vehicle: model.vehicle.name.clone(),
        profile: model.profile.to_string(),
    }
}

/// `plan` priced anew with `model` (its vehicle, profile and table): every leg after the leg
/// before it, its settle, the take-off, the landing and hover power, as [`plan_from_items`]
/// prices a mission read from a log; `report --vehicle` shows recorded flights this way.
pub fn repriced(plan: &FlightPlan, model: &VehicleModel) -> Result<Predicted, FlightItemsError> {
    price_points(model, plan.origin_height_m, &plan.points)
}

/// `predicted` with its legs priced as ArduCopter flies `points` (from the origin) when the
/// profile is `ardupilot` and one of them is a fast waypoint (a hold under a second, another
/// waypoint after it: `physics::ardupilot_chain`) or a leg passes via points round a fence
/// zone (each a fast waypoint): the corners blended, each leg from the moment the waypoint
/// before is reached to the moment its own is, a leg round a zone the chain through its via
/// points as one ([`chained`]). Unchanged otherwise (every
/// leg then ends at rest on its waypoint, as the table prices it). The planner's order and
/// the table stay rest to rest; only the flown order's prediction is priced this way.
pub fn with_fast_waypoints(
    vehicle: &Vehicle,
    profile: Profile,
    points: &[PlannedPoint],
    predicted: Predicted,
    wind: crate::physics::Wind,
) -> Result<Predicted, FlightItemsError> {
    use crate::physics::ardupilot_chain::{is_fast, ChainPoint};
    let at = |e: &Enu| [e.x_east_m, e.y_north_m, e.z_up_m];
    // Every point's via points first (fast: a NAV_WAYPOINT without a hold, another next),
    // then the point itself.
    let mut chain: Vec<ChainPoint> = Vec::new();
    for (k, point) in points.iter().enumerate() {
        chain.extend(point.via.iter().map(|v| ChainPoint {
            enu_m: at(&v.enu),
            fast: is_fast(0.0, true),
        }));
        chain.push(ChainPoint {
            enu_m: at(&point.enu),
            fast: is_fast(point.hold_s, k + 1 < points.len()),
        });
    }
    if profile != Profile::Ardupilot
        || predicted.legs.len() != points.len()
        || !chain.iter().any(|p| p.fast)
    {
        return Ok(predicted);
    }
    let model = Model::new(vehicle);
    let ops = model
        .ardupilot_chain_in_wind([0.0; 3], &chain, wind)
        .map_err(|e| FlightItemsError::Pricing(format!("the legs with fast waypoints: {e}")))?;
    let ops: Vec<PredictedLeg> = ops
        .iter()
        .map(|op| PredictedLeg {
            energy_j: op.energy_j,
            duration_s: op.duration_s,
            settle_energy_j: op.settle_energy_j,
            settle_duration_s: op.settle_duration_s,
        })
        .collect();
    // A leg round a zone is the chain's legs through its via points, as one.
    let mut rest = ops.as_slice();
    let mut legs = Vec::with_capacity(points.len());
    for point in points {
        let (leg, after) = rest.split_at((point.via.len() + 1).min(rest.len()));
        legs.push(chained(leg));
        rest = after;
    }
    Ok(Predicted { legs, ..predicted })
}

/// Prices the legs origin -> points[0] -> ... with the vehicle's table, each after the leg
/// before it (`physics::start_case`; a leg round a zone as the chain through its via points,
/// [`chained`]), or as ArduCopter's chain of fast waypoints
/// ([`with_fast_waypoints`]), and the take-off and landing at the origin height.
fn price_points(
    model: &VehicleModel,
    origin_height_m: f64,
    points: &[PlannedPoint],
) -> Result<Predicted, FlightItemsError> {
    let pricing = |e: crate::physics::PhysicsError| FlightItemsError::Pricing(e.to_string());
    let budget = model.budget(origin_height_m).map_err(pricing)?;
    let mut from = Enu::default();
    let mut previous: Option<(f64, f64)> = None;
    let mut legs = Vec::with_capacity(points.len());
    for point in points {
        // A leg round a zone: the chain of straight legs through its via points.
        let mut parts = Vec::with_capacity(point.via.len() + 1);
        for to in point
            .via
            .iter()
            .map(|v| v.enu)
            .chain(std::iter::once(point.enu))
        {
            let (dx, dy) = (to.x_east_m - from.x_east_m, to.y_north_m - from.y_north_m);
            let xf = dx.hypot(dy);
            let zf = to.z_up_m - from.z_up_m;
            // PX4 leaves the previous hold past its waypoint: this leg's start depends on it.
            let start = start_case(previous, (dx, dy));
            previous = Some((dx, dy));
            let heading = crate::physics::heading_deg(dx, dy);
            let leg = model.leg_on_heading(xf, zf, start, heading).map_err(|e| {
                FlightItemsError::Pricing(format!(
                    "leg to {} (Xf {xf:.1} m, Zf {zf:.1} m): {e}",
                    point.name
                ))
            })?;
            parts.push(PredictedLeg {
                energy_j: leg.energy_j,
                duration_s: leg.duration_s,
                settle_energy_j: leg.settle_energy_j,
                settle_duration_s: leg.settle_duration_s,
            });
            from = to;
        }
        legs.push(chained(&parts));
    }
    let predicted = Predicted {
        takeoff_j: budget.takeoff.total_energy_j(),
        landing_j: budget.landing.total_energy_j(),
        legs,
        hover_power_w: budget.hover_power_w,
    };
    with_fast_waypoints(&model.vehicle, model.profile, points, predicted, model.wind)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::items::{mission_items, read_flight, ItemOptions};
    use crate::link::mav::{MavCmd, MISSION_ITEM_INT_DATA};
    use crate::physics::Wind;

    fn from_items(
        items: &[MISSION_ITEM_INT_DATA],
        flavour: Flavour,
        mission: Option<&Mission>,
    ) -> Result<FlightPlan, FlightItemsError> {
        let home_alt_m = mission.map_or(0.0, |m| m.origin.home.alt_m);
        let read = read_flight(items, flavour, home_alt_m)?;
        plan_from_items("x", &read, mission, None)
    }

    fn sample() -> Mission {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/paper-sample-3wp.toml");
        crate::mission::load(&path).unwrap()
    }

    #[test]
    fn uploaded_items_read_back_as_the_flight_plan_fly_would_write() {
        let m = sample();
        for flavour in [Flavour::Px4, Flavour::ArduPilot] {
            let opts = ItemOptions {
                flavour,
                ..ItemOptions::default()
            };
            let items = mission_items(&m, &[2, 0, 1], &opts).unwrap();
            let read = from_items(&items, flavour, Some(&m)).unwrap();
            let direct = FlightPlan::for_mission(
                &m,
                &[2, 0, 1],
                u16::from(flavour == Flavour::ArduPilot),
                None,
            )
            .unwrap();
            assert_eq!(read.takeoff_seq, direct.takeoff_seq);
            assert_eq!(read.land_seq, direct.land_seq);
            assert_eq!(read.points.len(), direct.points.len());
            for (a, b) in read.points.iter().zip(&direct.points) {
                assert_eq!((a.seq, &a.name, a.hold_s), (b.seq, &b.name, b.hold_s));
                // degE7 rounding: about a centimetre.
                assert!(
                    (a.enu.x_east_m - b.enu.x_east_m).abs() < 0.02,
                    "{a:?} {b:?}"
                );
                assert!(
                    (a.enu.y_north_m - b.enu.y_north_m).abs() < 0.02,
                    "{a:?} {b:?}"
                );
                assert!((a.enu.z_up_m - b.enu.z_up_m).abs() < 0.02, "{a:?} {b:?}");
            }
        }
    }

    #[test]
    fn items_without_a_takeoff_or_waypoints_are_refused_with_what_was_found() {
        let m = sample();
        let items = mission_items(&m, &[0], &ItemOptions::default()).unwrap();
        let no_takeoff: Vec<_> = items
            .iter()
            .filter(|i| i.command != MavCmd::MAV_CMD_NAV_TAKEOFF)
            .cloned()
            .collect();
        let err = from_items(&no_takeoff, Flavour::Px4, None).unwrap_err();
        assert!(
            matches!(err, FlightItemsError::Items(ReadItemsError::NoTakeoff(_))),
            "{err}"
        );
        let only_takeoff = &items[..1];
        assert_eq!(
            from_items(only_takeoff, Flavour::Px4, None).unwrap_err(),
            FlightItemsError::Items(ReadItemsError::NoWaypoints)
        );
    }

    #[test]
    fn a_leg_round_a_zone_is_priced_as_the_chain_through_its_via_points_as_one() {
        use crate::flightlog::flight_plan::ViaPoint;
        use crate::physics::ardupilot_chain::ChainPoint;
        let vehicle = crate::physics::vehicle::shipped();
        let enu = |x: f64, y: f64, z: f64| Enu {
            x_east_m: x,
            y_north_m: y,
            z_up_m: z,
        };
        let point = |name: &str, at: Enu, via: Vec<ViaPoint>| PlannedPoint {
            seq: 0,
            name: name.to_string(),
            enu: at,
            hold_s: 5.0,
            photos: 0,
            via,
        };
        let v = enu(60.0, 20.0, 5.0);
        let points = vec![
            point("A", enu(40.0, 0.0, 5.0), Vec::new()),
            point("B", enu(40.0, 40.0, 0.0), vec![ViaPoint { seq: 0, enu: v }]),
            point(ORIGIN_NAME, Enu::default(), Vec::new()),
        ];
        let leg = PredictedLeg {
            energy_j: 1.0,
            duration_s: 1.0,
            settle_energy_j: 0.0,
            settle_duration_s: 0.0,
        };
        let table = Predicted {
            takeoff_j: 1.0,
            landing_j: 2.0,
            legs: vec![leg; 3],
            hover_power_w: 3.0,
        };
        // Every point holds, but the via point is flown through: the chain prices the flight.
        let priced =
            with_fast_waypoints(&vehicle, Profile::Ardupilot, &points, table, Wind::CALM).unwrap();
        assert_eq!(priced.legs.len(), 3);
        let chain = |p: [f64; 3], fast: bool| ChainPoint { enu_m: p, fast };
        let ops = Model::new(&vehicle)
            .ardupilot_chain(
                [0.0; 3],
                &[
                    chain([40.0, 0.0, 5.0], false),
                    chain([60.0, 20.0, 5.0], true),
                    chain([40.0, 40.0, 0.0], false),
                    chain([0.0; 3], false),
                ],
            )
            .unwrap();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1.0);
        // To B: the whole way to the via point, then to B's arrival; B's settle.
        let to_b = &priced.legs[1];
        assert!(close(
            to_b.energy_j,
            ops[1].total_energy_j() + ops[2].energy_j
        ));
        assert!(close(
            to_b.duration_s,
            ops[1].total_duration_s() + ops[2].duration_s
        ));
        assert!(close(to_b.settle_energy_j, ops[2].settle_energy_j));
        assert!(close(priced.legs[0].energy_j, ops[0].energy_j));
        assert!(close(priced.legs[2].energy_j, ops[3].energy_j));
        // The way round costs more than the straight leg rest to rest.
        let straight = Model::new(&vehicle)
            .ardupilot_chain([40.0, 0.0, 5.0], &[chain([40.0, 40.0, 0.0], false)])
            .unwrap();
        assert!(to_b.energy_j > straight[0].energy_j * 1.3);
        // Re-priced from plan.json (`report --vehicle`): the same legs.
        let model = VehicleModel::open(
            &crate::physics::VehicleSource::BuiltIn,
            Some(Profile::Ardupilot),
        )
        .unwrap();
        let again = price_points(&model, 30.0, &points).unwrap();
        assert!(close(again.legs[1].energy_j, to_b.energy_j));
    }

    #[test]
    fn a_chain_of_parts_is_every_part_whole_but_the_last_to_its_arrival() {
        let part = |e: f64, t: f64, se: f64, st: f64| PredictedLeg {
            energy_j: e,
            duration_s: t,
            settle_energy_j: se,
            settle_duration_s: st,
        };
        let one = chained(&[part(10.0, 2.0, 1.0, 0.5), part(20.0, 3.0, 4.0, 1.5)]);
        assert_eq!(one, part(31.0, 5.5, 4.0, 1.5));
        assert_eq!(
            chained(&[part(7.0, 1.0, 2.0, 3.0)]),
            part(7.0, 1.0, 2.0, 3.0)
        );
    }

    #[test]
    fn zero_hold_points_are_priced_as_arducopter_chains_them_and_held_ones_as_before() {
        let vehicle = crate::physics::vehicle::shipped();
        let point = |name: &str, x: f64, y: f64, z: f64, hold_s: f64| PlannedPoint {
            seq: 0,
            name: name.to_string(),
            enu: Enu {
                x_east_m: x,
                y_north_m: y,
                z_up_m: z,
            },
            hold_s,
            photos: 0,
            via: Vec::new(),
        };
        let points = |hold_s: f64| {
            vec![
                point("A", 40.0, 0.0, 5.0, hold_s),
                point("B", 40.0, 40.0, 0.0, hold_s),
                point(ORIGIN_NAME, 0.0, 0.0, 0.0, 0.0),
            ]
        };
        let leg = PredictedLeg {
            energy_j: 1.0,
            duration_s: 1.0,
            settle_energy_j: 0.0,
            settle_duration_s: 0.0,
        };
        let table = Predicted {
            takeoff_j: 1.0,
            landing_j: 2.0,
            legs: vec![leg; 3],
            hover_power_w: 3.0,
        };
        // Holds of a second or more: every leg stops, the table's prices stand.
        let held = with_fast_waypoints(
            &vehicle,
            Profile::Ardupilot,
            &points(1.0),
            table.clone(),
            Wind::CALM,
        );
        assert_eq!(held.unwrap(), table);
        // Another profile: unchanged whatever the holds.
        let px4 = with_fast_waypoints(
            &vehicle,
            Profile::Px4,
            &points(0.0),
            table.clone(),
            Wind::CALM,
        );
        assert_eq!(px4.unwrap(), table);
        // Zero holds: the chain's legs, the rest of the prediction kept.
        let fast = with_fast_waypoints(
            &vehicle,
            Profile::Ardupilot,
            &points(0.5),
            table.clone(),
            Wind::CALM,
        )
        .unwrap();
        assert_eq!(fast.legs.len(), 3);
        assert_eq!((fast.takeoff_j, fast.landing_j), (1.0, 2.0));
        let rest = Model::new(&vehicle).ardupilot_chain(
            [0.0; 3],
            &points(0.0)
                .iter()
                .map(|p| crate::physics::ardupilot_chain::ChainPoint {
                    enu_m: [p.enu.x_east_m, p.enu.y_north_m, p.enu.z_up_m],
                    fast: false,
                })
                .collect::<Vec<_>>(),
        );
        let rest = rest.unwrap();
        let total = |e: f64, s: f64| e + s;
        for (k, (f, r)) in fast.legs.iter().zip(&rest).enumerate() {
            let (tf, tr) = (
                total(f.duration_s, f.settle_duration_s),
                total(r.duration_s, r.settle_duration_s),
            );
            assert!(
                tf < tr - 0.5,
                "leg {k}: {tf} s blended, {tr} s rest to rest"
            );
        }
    }

    #[test]
    fn points_far_from_every_named_waypoint_are_named_by_their_item() {
        let m = sample();
        let mut items = mission_items(&m, &[0, 1], &ItemOptions::default()).unwrap();
        items[1].x += 1000; // about 11 m north
        let plan = from_items(&items, Flavour::Px4, Some(&m)).unwrap();
        assert_eq!(plan.points[0].name, "item 1");
        assert_eq!(plan.points[1].name, m.waypoints[1].name);
        assert_eq!(plan.points[2].name, ORIGIN_NAME);
    }
}
