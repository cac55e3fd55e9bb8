//! A mission flown over several flights, a battery swap between them: which waypoints of a
//! flight it visited ([`visits`]), the mission of the waypoints it left (`emplan fly MISSION
//! --resume FLIGHT_DIR`: [`resume`], refused for a flight of another mission or one that left
//! nothing), and the mission view of a flight and its resumptions ([`missions`], what `emplan
//! report` adds when the flights given resume one another): every waypoint once, the flight
//! that visited it, energy per flight and in total, and what went wrong (a waypoint visited
//! twice or never).
//!
//! A waypoint counts as visited when the flight arrived there (its at-point part in the report:
//! the vehicle came within the arrival radius, or the autopilot accepted the point) and its
//! hover ran its course (that part is not `incomplete`). A waypoint arrived at whose hover was
//! cut short (the vehicle sent home while it hovered there, the log cut off) is not visited and
//! is flown again: the hover is what a waypoint is for (a photograph, a measurement), and flying
//! it again costs a leg where skipping it loses what it was for. A waypoint with no hover time
//! counts on arrival. A waypoint whose photos (its plan point's `photos`, the mission's photo
//! actions there) the autopilot did not all report taking is not visited either and is flown
//! again (`flightlog::photos` assigns the photos to the points).
//!
//! A flight links to the one it resumes by its plan.json's `resumes` (the resumed flight's
//! directory name, [`FlightPlan::resumes`]).

use serde::{Deserialize, Serialize};

use super::flight_plan::FlightPlan;
use super::report::{plan_waypoints as waypoints, CombinedJson, FlightReport};
pub use super::report::{visits, PointVisit, Visit};
use crate::mission::rehome::{HomeOffset, ORIGIN_TOLERANCE_M};
use crate::mission::{Enu, Geodetic, Mission};

/// How far a waypoint of a flight's plan may be from the mission's waypoint of its name and
/// still be that waypoint (m, 3D, both at their height above home). Converting a mission
/// between file formats moves a waypoint by about a centimetre (degE7 is 1.1 cm); the autopilots'
/// default acceptance radius is 2 m, so a waypoint moved by less than half of it is flown to
/// the same place.
pub const WAYPOINT_TOLERANCE_M: f64 = 1.0;

/// Why a flight cannot be resumed as a flight of a mission.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ResumeError {
    #[error("{flight} is a flight of mission {flown:?}, not of {mission:?}")]
    OtherMission {
        flight: String,
        flown: String,
        mission: String,
    },
    #[error(
        "{flight}: its origin is {distance_m:.0} m from the origin of mission {mission:?} (more than {ORIGIN_TOLERANCE_M} m): not the same mission"
    )]
    OtherOrigin {
        flight: String,
        mission: String,
        distance_m: f64,
    },
    #[error("{flight}: its waypoint {name:?} is not a waypoint of mission {mission:?}")]
    UnknownWaypoint {
        flight: String,
        name: String,
        mission: String,
    },
    #[error(
        "{flight}: its waypoint {name:?} is {distance_m:.1} m from the waypoint {name:?} of mission {mission:?} (more than {WAYPOINT_TOLERANCE_M} m): not the same mission"
    )]
    MovedWaypoint {
        flight: String,
        name: String,
        mission: String,
        distance_m: f64,
    },
    #[error("every waypoint was reached in {flight}{}: nothing left to fly", and_later(.later))]
    NothingLeft {
        flight: String,
        /// The flights that resumed it already, in the order they flew.
        later: Vec<String>,
    },
}

/// ` and in B, C, which resumed it` (nothing when no flight did).
fn and_later(later: &[String]) -> String {
    match later {
        [] => String::new(),
        [one] => format!(" and in {one}, which resumed it"),
        more => format!(" and in {}, which resumed it", more.join(", ")),
    }
}

/// Checks that `plan` (of `flight`) is a flight of `mission`: the same name, an origin within
/// `rehome::ORIGIN_TOLERANCE_M` of the mission's, and every waypoint flown one of the mission's
/// by name and position (within [`WAYPOINT_TOLERANCE_M`], compared by latitude, longitude and
/// height above home, so a plan re-homed within the tolerance still matches).
pub fn check_same_mission(
    mission: &Mission,
    plan: &FlightPlan,
    flight: &str,
) -> Result<(), ResumeError> {
    if plan.mission != mission.name {
        return Err(ResumeError::OtherMission {
            flight: flight.to_string(),
            flown: plan.mission.clone(),
            mission: mission.name.clone(),
        });
    }
    let offset = HomeOffset::of(mission, plan.home);
    if !offset.within(ORIGIN_TOLERANCE_M) {
        return Err(ResumeError::OtherOrigin {
            flight: flight.to_string(),
            mission: mission.name.clone(),
            distance_m: offset.horizontal_m,
        });
    }
    for (_, point) in waypoints(plan) {
        let Some(waypoint) = mission.waypoints.iter().find(|w| w.name == point.name) else {
            return Err(ResumeError::UnknownWaypoint {
                flight: flight.to_string(),
                name: point.name.clone(),
                mission: mission.name.clone(),
            });
        };
        let distance_m = distance(
            in_mission_frame(mission, plan, point.enu),
            waypoint.position,
        );
        if distance_m.is_nan() || distance_m > WAYPOINT_TOLERANCE_M {
            return Err(ResumeError::MovedWaypoint {
                flight: flight.to_string(),
                name: point.name.clone(),
                mission: mission.name.clone(),
                distance_m,
            });
        }
    }
    Ok(())
}

/// A point of `plan`'s frame in `mission`'s: the same latitude, longitude and height above home.
fn in_mission_frame(mission: &Mission, plan: &FlightPlan, enu: Enu) -> Enu {
    let at = plan.origin().to_geodetic(enu);
    let height_m = at.alt_m - plan.home.alt_m;
    mission.origin.to_enu(Geodetic {
        alt_m: mission.origin.home.alt_m + height_m,
        ..at
    })
}

fn distance(a: Enu, b: Enu) -> f64 {
    (a.x_east_m - b.x_east_m)
        .hypot(a.y_north_m - b.y_north_m)
        .hypot(a.z_up_m - b.z_up_m)
}

/// What is left of a flight to fly.
#[derive(Debug, Clone, PartialEq)]
pub struct Resumption {
    /// The flight resumed (its report's name: the flight directory's).
    pub flight: String,
    /// The mission of the waypoints left: `mission`'s name, origin and settings, its
    /// waypoints (positions and hover times as the mission file gives them) that the flight's
    /// plan held and the flight did not visit, in the mission file's order.
    pub mission: Mission,
    /// What the flight did at each waypoint of its plan.
    pub visits: Vec<PointVisit>,
    /// The flights that resumed it already (each resuming it or one of these), in the order
    /// they flew: what they visited is not flown again.
    pub later: Vec<Resumer>,
    /// What the user should know of how the visits were judged (a torn log), one sentence
    /// each.
    pub notes: Vec<String>,
}

/// A flight that resumed the flight resumed now, or one that resumed it in turn.
#[derive(Debug, Clone, PartialEq)]
pub struct Resumer {
    /// Its name (its flight directory's).
    pub flight: String,
    /// The waypoints it visited, in flying order.
    pub visited: Vec<String>,
}

impl Resumption {
    /// The names of the waypoints with `visit`, in the flight's order.
    pub fn named(&self, visit: Visit) -> Vec<&str> {
        (self.visits.iter())
            .filter(|v| v.visit == visit)
            .map(|v| v.name.as_str())
            .collect()
    }

    /// The flight a new flight resumes: the last that resumed this one, else this one (so a
    /// mission's flights stay one chain).
    pub fn resumes(&self) -> &str {
        self.later.last().map_or(&self.flight, |r| &r.flight)
    }

    /// One line for the user: `resuming FLIGHT: visited A, B; hover cut short at C; resumed
    /// since by F2 (visited D); flying the 2 left: C, E`.
    pub fn summary(&self) -> String {
        let list = |visit| match self.named(visit).join(", ") {
            none if none.is_empty() => None,
            some => Some(some),
        };
        let cut_short =
            list(Visit::CutShort).map_or(String::new(), |c| format!("; hover cut short at {c}"));
        let photos = list(Visit::PhotosMissing)
            .map_or(String::new(), |c| format!("; photos missing at {c}"));
        let left: Vec<&str> = (self.mission.waypoints.iter())
            .map(|w| w.name.as_str())
            .collect();
        let later = match self.later.as_slice() {
            [] => String::new(),
            later => format!(
                "; resumed since by {}",
                (later.iter())
                    .map(|r| match r.visited.join(", ") {
                        none if none.is_empty() => format!("{} (visited none)", r.flight),
                        some => format!("{} (visited {some})", r.flight),
                    })
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        };
        format!(
            "resuming {}: visited {}{cut_short}{photos}{later}; flying the {} left: {}",
            self.flight,
            list(Visit::Visited).unwrap_or_else(|| "none".into()),
            left.len(),
            left.join(", ")
        )
    }
}

/// The mission that resumes `flight` (flown against `plan`, measured in `report`) of `mission`:
/// its waypoints the flight did not visit ([`visits`]). Refused for a flight of another mission
/// ([`check_same_mission`]) and when nothing is left. Waypoints of the mission the flight's plan
/// did not hold (another sortie, a flight this one resumed) are not its to fly.
pub fn resume(
    mission: &Mission,
    plan: &FlightPlan,
    report: &FlightReport,
    flight: &str,
) -> Result<Resumption, ResumeError> {
    check_same_mission(mission, plan, flight)?;
    resume_chain(
        mission,
        Resumption {
            flight: report.flight.clone(),
            mission: mission.clone(),
            visits: visits(plan, report),
            later: Vec::new(),
            notes: Vec::new(),
        },
        flight,
    )
}

/// The mission that resumes the flight `resumed` describes (its visits judged, checked to be
/// a flight of `mission`; `resumed.mission` is replaced; `flight` names it in errors), after the
/// flights in `resumed.later` that resumed it already: the waypoints its plan held that neither
/// it nor any of them visited, in the mission file's order. Refused when nothing is left,
/// naming them.
pub fn resume_chain(
    mission: &Mission,
    resumed: Resumption,
    flight: &str,
) -> Result<Resumption, ResumeError> {
    let by_later = |name: &str| (resumed.later.iter()).any(|r| r.visited.iter().any(|v| v == name));
    let left = |name: &str| {
        resumed
            .visits
            .iter()
            .any(|v| v.name == name && v.visit != Visit::Visited)
            && !by_later(name)
    };
    let kept: Vec<usize> = (mission.waypoints.iter().enumerate())
        .filter(|(_, w)| left(&w.name))
        .map(|(k, _)| k)
        .collect();
    // The waypoints left, each in the state the whole file has there (their actions kept).
    let left_mission = mission.keeping(&kept);
    if left_mission.waypoints.is_empty() {
        return Err(ResumeError::NothingLeft {
            flight: flight.to_string(),
            later: resumed.later.iter().map(|r| r.flight.clone()).collect(),
        });
    }
    Ok(Resumption {
        mission: left_mission,
        ..resumed
    })
}

/// One flight of a mission flown over several.
#[derive(Debug, Clone, PartialEq)]
pub struct MissionFlight {
    pub flight: String,
    pub resumes: Option<String>,
    /// Waypoints visited, and arrived at with the hover cut short or photos missing, in flying
    /// order.
    pub visited: Vec<String>,
    pub cut_short: Vec<String>,
    pub photos_missing: Vec<String>,
    pub predicted_j: Option<f64>,
    pub measured_j: Option<f64>,
    pub duration_s: f64,
    pub complete: bool,
}

/// One waypoint of a mission flown over several flights.
#[derive(Debug, Clone, PartialEq)]
pub struct MissionWaypoint {
    pub name: String,
    /// The flights that visited it (once is right).
    pub visited_by: Vec<String>,
    /// The flights that arrived there but cut its hover short.
    pub cut_short_in: Vec<String>,
    /// The flights that arrived there but did not report all its photos.
    pub photos_missing_in: Vec<String>,
    /// Measured energy of the leg that arrived there and of its settle and hover, in the
    /// first flight that visited it.
    pub leg_j: Option<f64>,
    pub at_point_j: Option<f64>,
}

/// A flight and its resumptions as one mission.
#[derive(Debug, Clone, PartialEq)]
pub struct FlownMission {
    pub mission: String,
    /// The first flight, then the ones resuming it, in the order they link.
    pub flights: Vec<MissionFlight>,
    /// Every waypoint of the first flight's plan (and any other a resumption flew), in the
    /// order visited, then the ones never visited.
    pub waypoints: Vec<MissionWaypoint>,
    /// Each as a sentence: a waypoint visited twice or never, a flight of another mission, a
    /// resumed flight not among the flights given.
    pub problems: Vec<String>,
}

impl FlownMission {
    /// Every waypoint visited by exactly one flight.
    pub fn every_waypoint_once(&self) -> bool {
        self.waypoints.iter().all(|w| w.visited_by.len() == 1)
    }

    fn total(&self, f: impl Fn(&MissionFlight) -> Option<f64>) -> Option<f64> {
        self.flights.iter().map(f).sum()
    }

    /// The JSON view (kJ).
    pub fn json(&self) -> FlownMissionJson {
        let kj = |j: Option<f64>| j.map(|j| j / 1000.0);
        FlownMissionJson {
            mission: self.mission.clone(),
            flights: (self.flights.iter())
                .map(|f| MissionFlightJson {
                    flight: f.flight.clone(),
                    resumes: f.resumes.clone(),
                    visited: f.visited.clone(),
                    cut_short: f.cut_short.clone(),
                    photos_missing: f.photos_missing.clone(),
                    predicted_kj: kj(f.predicted_j),
                    measured_kj: kj(f.measured_j),
                    duration_s: f.duration_s,
                    complete: f.complete,
                })
                .collect(),
            waypoints: (self.waypoints.iter())
                .map(|w| MissionWaypointJson {
                    name: w.name.clone(),
                    visited_by: w.visited_by.clone(),
                    cut_short_in: w.cut_short_in.clone(),
                    photos_missing_in: w.photos_missing_in.clone(),
                    leg_kj: kj(w.leg_j),
                    at_point_kj: kj(w.at_point_j),
                })
                .collect(),
            planned_kj: kj(self.flights.first().and_then(|f| f.predicted_j)),
            total: MissionTotalJson {
                measured_kj: kj(self.total(|f| f.measured_j)),
                duration_s: self.flights.iter().map(|f| f.duration_s).sum(),
            },
            every_waypoint_once: self.every_waypoint_once(),
            problems: self.problems.clone(),
        }
    }
}

/// The flights among `flights` (each its plan and report, the report named as the flights'
/// `resumes` name them) that resume one another, each chain as one mission: a flight that
/// resumes none of the others, and every flight that resumes it or one of its resumptions.
/// Flights that resume nothing and are resumed by nothing (repeats of a mission) make none.
pub fn missions(flights: &[(&FlightPlan, &FlightReport)]) -> Vec<FlownMission> {
    let parent = |k: usize| {
        let resumes = flights[k].0.resumes.as_deref()?;
        flights.iter().position(|(_, r)| r.flight == resumes)
    };
    let parents: Vec<Option<usize>> = (0..flights.len()).map(parent).collect();
    let mut out = Vec::new();
    for root in (0..flights.len()).filter(|&k| parents[k].is_none()) {
        // The chain in link order: each flight after the one it resumes.
        let mut chain = vec![root];
        let mut k = 0;
        while k < chain.len() {
            let at = chain[k];
            chain.extend((0..flights.len()).filter(|&j| parents[j] == Some(at)));
            k += 1;
        }
        if chain.len() > 1 {
            let of: Vec<(&FlightPlan, &FlightReport)> = chain.iter().map(|&k| flights[k]).collect();
            out.push(flown_mission(&of));
        }
    }
    out
}

/// One chain of flights (the first, then its resumptions) as one mission.
fn flown_mission(chain: &[(&FlightPlan, &FlightReport)]) -> FlownMission {
    let (first_plan, first) = chain[0];
    let mut problems = Vec::new();
    if let Some(resumed) = &first_plan.resumes {
        problems.push(format!(
            "{} resumes {resumed}, which is not among the flights given: the waypoints visited there are missing",
            first.flight
        ));
    }
    let mut waypoints: Vec<MissionWaypoint> = waypoints(first_plan)
        .map(|(_, p)| MissionWaypoint {
            name: p.name.clone(),
            visited_by: Vec::new(),
            cut_short_in: Vec::new(),
            photos_missing_in: Vec::new(),
            leg_j: None,
            at_point_j: None,
        })
        .collect();
    // Visit order: (flight in the chain, point in its plan) of the first visit.
    let mut first_visit: Vec<Option<(usize, usize)>> = vec![None; waypoints.len()];
    let mut flights = Vec::with_capacity(chain.len());
    for (f, &(plan, report)) in chain.iter().enumerate() {
        if plan.mission != first_plan.mission {
            problems.push(format!(
                "{} is a flight of mission {:?}, not of {:?}",
                report.flight, plan.mission, first_plan.mission
            ));
        }
        let visits = visits(plan, report);
        for (k, v) in visits.iter().enumerate() {
            let w = match waypoints.iter().position(|w| w.name == v.name) {
                Some(w) => w,
                None => {
                    problems.push(format!(
                        "{} flew waypoint {:?}, which {} did not plan",
                        report.flight, v.name, first.flight
                    ));
                    waypoints.push(MissionWaypoint {
                        name: v.name.clone(),
                        visited_by: Vec::new(),
                        cut_short_in: Vec::new(),
                        photos_missing_in: Vec::new(),
                        leg_j: None,
                        at_point_j: None,
                    });
                    first_visit.push(None);
                    waypoints.len() - 1
                }
            };
            let waypoint = &mut waypoints[w];
            match v.visit {
                Visit::Visited => {
                    if waypoint.visited_by.is_empty() {
                        waypoint.leg_j = v.leg.as_ref().and_then(|l| l.measured_j);
                        waypoint.at_point_j = v.at_point.as_ref().and_then(|p| p.measured_j);
                        first_visit[w] = Some((f, k));
                    }
                    waypoint.visited_by.push(report.flight.clone());
                }
                Visit::CutShort => waypoint.cut_short_in.push(report.flight.clone()),
                Visit::PhotosMissing => waypoint.photos_missing_in.push(report.flight.clone()),
                Visit::NotReached => {}
            }
        }
        let named = |visit: Visit| {
            (visits.iter())
                .filter(|v| v.visit == visit)
                .map(|v| v.name.clone())
                .collect()
        };
        flights.push(MissionFlight {
            flight: report.flight.clone(),
            resumes: plan.resumes.clone(),
            visited: named(Visit::Visited),
            cut_short: named(Visit::CutShort),
            photos_missing: named(Visit::PhotosMissing),
            predicted_j: report.predicted_j,
            measured_j: report.measured_j,
            duration_s: report.duration_s,
            complete: report.complete,
        });
    }
    for w in &waypoints {
        match w.visited_by.len() {
            0 => problems.push(format!("waypoint {:?} was never visited", w.name)),
            1 => {}
            n => problems.push(format!(
                "waypoint {:?} was visited {n} times: by {}",
                w.name,
                w.visited_by.join(", ")
            )),
        }
    }
    let mut order: Vec<usize> = (0..waypoints.len()).collect();
    order.sort_by_key(|&w| first_visit[w].unwrap_or((usize::MAX, w)));
    let mut slots: Vec<Option<MissionWaypoint>> = waypoints.into_iter().map(Some).collect();
    let waypoints = order.iter().filter_map(|&w| slots[w].take()).collect();
    FlownMission {
        mission: first_plan.mission.clone(),
        flights,
        waypoints,
        problems,
    }
}

/// `emplan report --json` of several flights: the combined report and, when some of the
/// flights resume others, each flight and its resumptions as one mission (absent otherwise).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CombinedMissionsJson {
    #[serde(flatten)]
    pub combined: CombinedJson,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub missions: Vec<FlownMissionJson>,
}

/// A flight of a mission flown over several, in JSON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MissionFlightJson {
    pub flight: String,
    pub resumes: Option<String>,
    pub visited: Vec<String>,
    pub cut_short: Vec<String>,
    /// Waypoints arrived at whose photos the autopilot did not all report (absent when none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub photos_missing: Vec<String>,
    pub predicted_kj: Option<f64>,
    pub measured_kj: Option<f64>,
    pub duration_s: f64,
    pub complete: bool,
}

/// A waypoint of a mission flown over several flights, in JSON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MissionWaypointJson {
    pub name: String,
    pub visited_by: Vec<String>,
    pub cut_short_in: Vec<String>,
    /// Flights that arrived there without reporting all its photos (absent when none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub photos_missing_in: Vec<String>,
    pub leg_kj: Option<f64>,
    pub at_point_kj: Option<f64>,
}

/// The flights' sums (a sum only when every flight has the number).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MissionTotalJson {
    pub measured_kj: Option<f64>,
    pub duration_s: f64,
}

/// A flight and its resumptions as one mission, in JSON (`emplan report --json`'s `missions`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlownMissionJson {
    pub mission: String,
    pub flights: Vec<MissionFlightJson>,
    pub waypoints: Vec<MissionWaypointJson>,
    /// The first flight's prediction: the mission as planned in one flight (the flights'
    /// predictions do not add up: each predicts a whole flight, the first one cut short).
    pub planned_kj: Option<f64>,
    pub total: MissionTotalJson,
    pub every_waypoint_once: bool,
    pub problems: Vec<String>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::segment::{SegmentConfig, SegmentKind, Segmenter};
    use crate::flightlog::synthetic::{square_plan, SyntheticConfig, SyntheticFlight};
    use crate::flightlog::telemetry::{FlightMode, Reading, Stamped};
    use crate::mission::Waypoint;

    /// The mission `square_plan` flies, its waypoints in the file in another order (C, A, B).
    fn square() -> Mission {
        let plan = square_plan();
        let mut waypoints: Vec<Waypoint> = waypoints(&plan)
            .map(|(_, p)| Waypoint {
                name: p.name.clone(),
                position: p.enu,
                hover_s: p.hold_s,
                ..Default::default()
            })
            .collect();
        waypoints.rotate_right(1);
        Mission {
            name: plan.mission.clone(),
            origin: plan.origin(),
            waypoints,
            default_hover_s: 3.0,
            min_height_above_home_m: 2.0,
            source: None,
            start_actions: Vec::new(),
            pois: Vec::new(),
            fence: Default::default(),
            rally: Vec::new(),
            blocks: Vec::new(),
        }
    }

    /// `plan` flown to the end (`cut` None), or sent home (RTL) halfway through part `cut`.
    fn flown(plan: &FlightPlan, name: &str, cut: Option<SegmentKind>) -> FlightReport {
        let flight = SyntheticFlight::fly(plan, &SyntheticConfig::default());
        let mut s = Segmenter::new(plan.clone(), SegmentConfig::default()).expect("valid");
        let stamped = flight.stamped();
        let Some(kind) = cut else {
            for m in &stamped {
                s.push(m);
            }
            s.finish();
            return FlightReport::build(name, &s);
        };
        let part = flight.part(kind).expect("the part is flown");
        let t_cut = 0.5 * (part.start_s + part.end_s);
        for m in stamped.iter().filter(|m| m.t_s < t_cut) {
            s.push(m);
        }
        for (t_s, armed) in [(t_cut, true), (t_cut + 40.0, false)] {
            s.push(&Stamped {
                t_s,
                wall_us: 0,
                reading: Reading::Heartbeat {
                    armed,
                    mode: FlightMode::Rtl,
                },
            });
        }
        FlightReport::build(name, &s)
    }

    fn names(w: &[Waypoint]) -> Vec<&str> {
        w.iter().map(|w| w.name.as_str()).collect()
    }

    #[test]
    fn a_flight_sent_home_on_a_leg_leaves_that_waypoint_and_the_rest_in_the_mission_order() {
        let plan = square_plan();
        let report = flown(&plan, "f1", Some(SegmentKind::Leg(1)));
        let visits = visits(&plan, &report);
        let seen: Vec<(&str, Visit)> = visits.iter().map(|v| (v.name.as_str(), v.visit)).collect();
        assert_eq!(
            seen,
            [
                ("A", Visit::Visited),
                ("B", Visit::NotReached),
                ("C", Visit::NotReached)
            ]
        );
        assert!(visits[0]
            .leg
            .as_ref()
            .is_some_and(|l| l.measured_j.is_some()));
        // The leg to B was begun, not finished.
        assert!(visits[1].leg.is_some() && visits[1].at_point.is_none());
        let resumed = resume(&square(), &plan, &report, "f1").expect("resumable");
        // The mission file lists C, A, B: the left ones keep its order, hover times and origin.
        assert_eq!(names(&resumed.mission.waypoints), ["C", "B"]);
        assert_eq!(resumed.mission.name, "square");
        assert_eq!(resumed.mission.origin, square().origin);
        assert!(resumed.mission.waypoints.iter().all(|w| w.hover_s == 3.0));
        assert_eq!(resumed.named(Visit::Visited), ["A"]);
        assert_eq!(resumed.named(Visit::NotReached), ["B", "C"]);
    }

    #[test]
    fn a_via_point_passed_is_no_waypoint_visited_and_its_leg_is_flown_again_whole() {
        // The leg A -> B round a zone through (75, 10, 2) (take-off 0, A 1, via 2, B 3, C 4,
        // origin 5, land 6), sent home half-way through it, past the via point.
        let via = Enu {
            x_east_m: 75.0,
            y_north_m: 10.0,
            z_up_m: 2.0,
        };
        let plan = square_plan()
            .renumbered(Some(0), &[1, 3, 4, 5], 6)
            .and_then(|p| p.routed(&[vec![], vec![via]], &[vec![], vec![2]]))
            .expect("valid");
        let flight = SyntheticFlight::fly(&plan, &SyntheticConfig::default());
        let leg = flight.part(SegmentKind::Leg(1)).expect("leg 1");
        let passed = (flight.messages.iter())
            .find(|m| matches!(m.reading, Reading::ItemReached { seq: 2 }))
            .map(|m| m.t_s)
            .expect("the via point passed");
        assert!(passed < 0.5 * (leg.start_s + leg.end_s));
        let report = flown(&plan, "f1", Some(SegmentKind::Leg(1)));
        let seen: Vec<(String, Visit)> = (visits(&plan, &report).into_iter())
            .map(|v| (v.name, v.visit))
            .collect();
        assert_eq!(
            seen,
            [
                ("A".to_string(), Visit::Visited),
                ("B".to_string(), Visit::NotReached),
                ("C".to_string(), Visit::NotReached)
            ]
        );
        assert_eq!(report.waypoints_left, ["B", "C"]);
        let resumed = resume(&square(), &plan, &report, "f1").expect("resumable");
        assert_eq!(names(&resumed.mission.waypoints), ["C", "B"]);
    }

    #[test]
    fn a_waypoint_whose_hover_was_cut_short_is_flown_again() {
        let plan = square_plan();
        let report = flown(&plan, "f1", Some(SegmentKind::Hover(1)));
        let resumed = resume(&square(), &plan, &report, "f1").expect("resumable");
        assert_eq!(resumed.named(Visit::Visited), ["A"]);
        assert_eq!(resumed.named(Visit::CutShort), ["B"]);
        assert_eq!(names(&resumed.mission.waypoints), ["C", "B"]);
    }

    #[test]
    fn a_waypoint_without_hover_time_counts_on_arrival_even_cut_short() {
        let mut plan = square_plan();
        plan.points[0].hold_s = 0.0;
        let mut report = flown(&square_plan(), "f1", Some(SegmentKind::Hover(0)));
        assert_eq!(visits(&plan, &report)[0].visit, Visit::Visited);
        // With its hover time the same part is a hover cut short.
        assert_eq!(visits(&square_plan(), &report)[0].visit, Visit::CutShort);
        // No part at the point at all: not reached, whatever its hover time.
        report.settles.clear();
        report.hovers.clear();
        assert_eq!(visits(&plan, &report)[0].visit, Visit::NotReached);
    }

    #[test]
    fn a_complete_flight_leaves_nothing_to_resume() {
        let plan = square_plan();
        let report = flown(&plan, "f1", None);
        assert!(report.complete, "{report:?}");
        let err = resume(&square(), &plan, &report, "flights/f1").expect_err("nothing left");
        assert_eq!(
            err.to_string(),
            "every waypoint was reached in flights/f1: nothing left to fly"
        );
    }

    #[test]
    fn a_flight_resumed_already_leaves_only_what_neither_it_nor_its_resumptions_visited() {
        let plan = square_plan();
        let report = flown(&plan, "f1", Some(SegmentKind::Leg(1)));
        let first = resume(&square(), &plan, &report, "flights/f1").expect("resumable");
        assert_eq!(first.resumes(), "f1");
        let with = |later: &[(&str, &[&str])]| Resumption {
            later: (later.iter())
                .map(|(f, v)| Resumer {
                    flight: f.to_string(),
                    visited: v.iter().map(|v| v.to_string()).collect(),
                })
                .collect(),
            ..first.clone()
        };
        // f2 resumed f1 and visited B: only C is left, and the next flight resumes f2.
        let resumed =
            resume_chain(&square(), with(&[("f2", &["B"])]), "flights/f1").expect("resumable");
        assert_eq!(names(&resumed.mission.waypoints), ["C"]);
        assert_eq!(resumed.resumes(), "f2");
        assert!(
            resumed
                .summary()
                .contains("resumed since by f2 (visited B)"),
            "{}",
            resumed.summary()
        );
        // f2 visited nothing, f3 (resuming f2) visited C and B: nothing left, both named.
        let err = resume_chain(
            &square(),
            with(&[("f2", &[]), ("f3", &["C", "B"])]),
            "flights/f1",
        )
        .expect_err("nothing left");
        assert_eq!(
            err.to_string(),
            "every waypoint was reached in flights/f1 and in f2, f3, which resumed it: \
             nothing left to fly"
        );
    }

    #[test]
    fn a_flight_of_another_mission_is_refused_naming_what_differs() {
        let plan = square_plan();
        let report = flown(&plan, "f1", Some(SegmentKind::Leg(1)));
        let refused = |mission: Mission| {
            resume(&mission, &plan, &report, "f1")
                .expect_err("another mission")
                .to_string()
        };
        let renamed = Mission {
            name: "triangle".into(),
            ..square()
        };
        assert_eq!(
            refused(renamed),
            r#"f1 is a flight of mission "square", not of "triangle""#
        );
        let mut moved_origin = square();
        moved_origin.origin = crate::mission::Origin {
            home: moved_origin.origin.to_geodetic(Enu {
                x_east_m: 100.0,
                y_north_m: 0.0,
                z_up_m: 0.0,
            }),
            ..moved_origin.origin
        };
        assert!(
            refused(moved_origin).contains("its origin is 100 m from the origin of mission"),
            "moved origin"
        );
        let mut other_names = square();
        other_names.waypoints[1].name = "A2".into();
        assert_eq!(
            refused(other_names),
            r#"f1: its waypoint "A" is not a waypoint of mission "square""#
        );
        let mut moved = square();
        moved.waypoints[2].position.z_up_m += 5.0;
        assert_eq!(
            refused(moved),
            r#"f1: its waypoint "B" is 5.0 m from the waypoint "B" of mission "square" (more than 1 m): not the same mission"#
        );
        // A centimetre (a mission converted between formats) is the same waypoint.
        let mut converted = square();
        converted.waypoints[2].position.x_east_m += 0.01;
        assert!(resume(&converted, &plan, &report, "f1").is_ok());
    }

    #[test]
    fn a_plan_re_homed_a_few_metres_away_is_the_same_mission_by_latitude_longitude_and_height() {
        let mission = square();
        let home = mission.origin.to_geodetic(Enu {
            x_east_m: 6.0,
            y_north_m: -3.0,
            z_up_m: -mission.origin.height_above_home_m + 1.5,
        });
        let rehomed = crate::mission::rehome::rehomed(&mission, home);
        let mut plan = FlightPlan::for_mission(&rehomed, &[1, 2, 0], 0, None).expect("valid");
        plan.resumes = None;
        assert!(check_same_mission(&mission, &plan, "f1").is_ok());
    }

    #[test]
    fn a_flight_and_its_resumption_visit_every_waypoint_once_with_the_energy_summed() {
        let mission = square();
        let plan1 = square_plan();
        let f1 = flown(&plan1, "f1", Some(SegmentKind::Hover(1)));
        let left = resume(&mission, &plan1, &f1, "f1").expect("resumable");
        // The rest flown from the origin, C first.
        let mut plan2 = FlightPlan::for_mission(&left.mission, &[0, 1], 0, None).expect("plan");
        plan2.resumes = Some("f1".into());
        let f2 = flown(&plan2, "f2", None);
        let views = missions(&[(&plan1, &f1), (&plan2, &f2)]);
        assert_eq!(views.len(), 1);
        let view = &views[0];
        assert_eq!(view.mission, "square");
        let by: Vec<(&str, Vec<&str>)> = (view.waypoints.iter())
            .map(|w| {
                let by = w.visited_by.iter().map(String::as_str).collect();
                (w.name.as_str(), by)
            })
            .collect();
        assert_eq!(
            by,
            [("A", vec!["f1"]), ("C", vec!["f2"]), ("B", vec!["f2"])]
        );
        assert_eq!(view.waypoints[2].cut_short_in, ["f1"]);
        assert!(
            view.every_waypoint_once() && view.problems.is_empty(),
            "{view:?}"
        );
        let (m1, m2) = (
            f1.measured_j.expect("measured"),
            f2.measured_j.expect("measured"),
        );
        let json = view.json();
        assert!((json.total.measured_kj.expect("both measured") - (m1 + m2) / 1000.0).abs() < 1e-9);
        assert_eq!(json.flights[1].resumes.as_deref(), Some("f1"));
        assert_eq!(json.planned_kj, f1.predicted_j.map(|j| j / 1000.0));
        assert_eq!(json.flights[1].visited, ["C", "B"]);
        assert_eq!(json.flights[0].cut_short, ["B"]);
        // Given in any order, the same mission.
        assert_eq!(missions(&[(&plan2, &f2), (&plan1, &f1)]), views);
    }

    #[test]
    fn a_waypoint_visited_twice_or_never_is_a_problem_and_repeats_make_no_mission() {
        let mission = square();
        let plan1 = square_plan();
        let f1 = flown(&plan1, "f1", Some(SegmentKind::Leg(1)));
        // A "resumption" that flies the whole mission again, and is itself cut short.
        let mut plan2 = FlightPlan::for_mission(&mission, &[1, 0, 2], 0, None).expect("plan");
        plan2.resumes = Some("f1".into());
        let f2 = flown(&plan2, "f2", Some(SegmentKind::Leg(2)));
        let view = &missions(&[(&plan1, &f1), (&plan2, &f2)])[0];
        assert!(!view.every_waypoint_once());
        assert_eq!(
            view.problems,
            [
                r#"waypoint "A" was visited 2 times: by f1, f2"#,
                r#"waypoint "B" was never visited"#
            ]
        );
        // Two flights of a mission that do not resume one another are repeats: no mission view.
        let f3 = flown(&plan1, "f3", None);
        assert!(missions(&[(&plan1, &f1), (&plan1, &f3)]).is_empty());
        // A resumption given without the flight it resumes: its own mission is not one.
        assert!(missions(&[(&plan2, &f2), (&plan1, &f3)]).is_empty());
    }

    #[test]
    fn a_waypoint_whose_photo_the_autopilot_did_not_report_is_not_visited_and_flown_again() {
        let mut plan = square_plan();
        for (point, photos) in plan.points.iter_mut().zip([1, 2, 1, 0]) {
            point.photos = photos;
        }
        let stamped = SyntheticFlight::fly(&plan, &SyntheticConfig::default()).stamped();
        let report = |keep: &dyn Fn(&Stamped) -> bool| {
            let kept: Vec<Stamped> = stamped.iter().filter(|m| keep(m)).cloned().collect();
            let s = Segmenter::run(plan.clone(), SegmentConfig::default(), &kept).expect("valid");
            FlightReport::build("f1", &s)
        };
        // Every photo reported: every waypoint visited, nothing to resume.
        let all = report(&|_| true);
        let visited: Vec<Visit> = visits(&plan, &all).iter().map(|v| v.visit).collect();
        assert_eq!(visited, [Visit::Visited; 3]);
        assert!(resume(&square(), &plan, &all, "f1").is_err());
        // B's second photo (index 2) never reported: B is not visited, and flown again.
        let short = report(&|m| !matches!(&m.reading, Reading::Photo(p) if p.index == 2));
        let resumed = resume(&square(), &plan, &short, "f1").expect("B left");
        assert_eq!(resumed.named(Visit::Visited), ["A", "C"]);
        assert_eq!(resumed.named(Visit::PhotosMissing), ["B"]);
        assert_eq!(names(&resumed.mission.waypoints), ["B"]);
        assert!(
            resumed.summary().contains("; photos missing at B;"),
            "{}",
            resumed.summary()
        );
        // A plan expecting photos from a flight that reported none: none visited.
        let none = report(&|m| !matches!(m.reading, Reading::Photo(_)));
        let visited: Vec<Visit> = visits(&plan, &none).iter().map(|v| v.visit).collect();
        assert_eq!(visited, [Visit::PhotosMissing; 3]);
        // The mission view of the flight and its resumption says where photos were missing.
        let mut again = plan.clone();
        again.resumes = Some("f1".into());
        let view = missions(&[(&plan, &short), (&again, &all)]);
        let json = view[0].json();
        assert_eq!(json.flights[0].photos_missing, ["B"]);
        let b = json.waypoints.iter().find(|w| w.name == "B").expect("B");
        assert_eq!(b.photos_missing_in, ["f1"]);
    }
}
