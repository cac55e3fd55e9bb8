//! The pre-flight check that the vehicle stands where the plan starts: its home learned over the
//! link (`link::locate`: HOME_POSITION, else its position, within a bounded time) and measured
//! against the mission's origin (`mission::rehome`). Beyond [`ORIGIN_TOLERANCE_M`] nothing is
//! uploaded or armed: the plan's first and last legs, and its battery check, would describe
//! another flight. [`super::load`] runs it before every upload, for `fly`, `upload` and the
//! service alike; `--origin vehicle` re-plans the mission from the home [`vehicle_home`] learns.

use crate::link::commands::locate;
use crate::link::connection::{Autopilot, Link};
use crate::link::locate::{HomeSource, LocateConfig, LocateError, Located};
use crate::link::LinkError;
use crate::mission::rehome::{HomeOffset, ORIGIN_TOLERANCE_M};
use crate::mission::{Geodetic, Mission};
use crate::planner::Plan;

/// Why a flight did not pass the check: found before anything was uploaded or armed.
#[derive(Debug, thiserror::Error)]
pub enum PreflightError {
    /// The vehicle stands too far from where the plan starts.
    #[error(
        "{}{}: farther than the {ORIGIN_TOLERANCE_M} m a plan allows, nothing was uploaded (plan the mission from the vehicle's home, or take the vehicle to the mission's origin)",
        .offset.describe(),
        match .from { HomeSource::Position => " (its position: it sent no home)", HomeSource::HomePosition => "" }
    )]
    FarFromHome {
        offset: HomeOffset,
        from: HomeSource,
    },
    /// Where the vehicle is could not be learned.
    #[error(
        "{0}; nothing was uploaded (the plan cannot be checked against where the vehicle stands)"
    )]
    NoHome(#[from] LocateError),
    #[error("link: {0}")]
    Link(#[from] LinkError),
}

impl PreflightError {
    /// The stage it failed in (the `stage` of the failure JSON): `preflight`, or `connect` for
    /// the link.
    pub fn stage(&self) -> &'static str {
        match self {
            PreflightError::Link(_) => "connect",
            PreflightError::FarFromHome { .. } | PreflightError::NoHome(_) => "preflight",
        }
    }
}

/// Where a flight is planned from: the mission's origin (the check then requires the vehicle
/// there) or the vehicle's home (the mission re-planned from where it stands).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PlanOrigin {
    Mission,
    Vehicle,
}

impl IfHomeUnknown {
    /// What an origin asked for (None: not asked, the default) does with an unknown home: only
    /// the mission's origin asked for explicitly flies as planned.
    pub fn asked(origin: Option<PlanOrigin>) -> IfHomeUnknown {
        match origin {
            Some(PlanOrigin::Mission) => IfHomeUnknown::FlyAsPlanned,
            None | Some(PlanOrigin::Vehicle) => IfHomeUnknown::Refuse,
        }
    }
}

/// What the check does when the vehicle says nothing of where it is within the time allowed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum IfHomeUnknown {
    /// Refuse: neither the plan nor the energy guard can be trusted without knowing where the
    /// vehicle is (the default).
    #[default]
    Refuse,
    /// Fly the plan from the mission's origin, as the user said (`--origin mission` given
    /// explicitly), with a warning.
    FlyAsPlanned,
}

/// Learns `target`'s home (see [`crate::link::locate::Locate`]); an error when neither its home
/// nor its position came within the default budget.
pub async fn vehicle_home(link: &Link, target: &Autopilot) -> Result<Located, PreflightError> {
    Ok(locate(link, target, LocateConfig::default()).await??)
}

/// The check itself: `located` (None: the vehicle's home is unknown) against `mission`'s origin.
/// Returns the offset when it is within the tolerance, None when the home is unknown and
/// `if_unknown` lets the flight go ahead.
pub fn check(
    mission: &Mission,
    located: Result<Located, PreflightError>,
    if_unknown: IfHomeUnknown,
) -> Result<Option<HomeOffset>, PreflightError> {
    let located = match (located, if_unknown) {
        (Ok(located), _) => located,
        (Err(PreflightError::NoHome(e)), IfHomeUnknown::FlyAsPlanned) => {
            tracing::warn!("{e}; flying the plan from the mission's origin, as asked");
            return Ok(None);
        }
        (Err(e), _) => return Err(e),
    };
    let offset = HomeOffset::of(mission, located.home);
    if !offset.within(ORIGIN_TOLERANCE_M) {
        return Err(PreflightError::FarFromHome {
            offset,
            from: located.source,
        });
    }
    tracing::info!("{} (within {ORIGIN_TOLERANCE_M} m)", offset.describe());
    Ok(Some(offset))
}

/// Learns `target`'s home and [`check`]s it against `mission`'s origin.
pub async fn check_home(
    link: &Link,
    target: &Autopilot,
    mission: &Mission,
    if_unknown: IfHomeUnknown,
) -> Result<Option<HomeOffset>, PreflightError> {
    check(mission, vehicle_home(link, target).await, if_unknown)
}

/// Where the vehicle's home is, against the mission's origin, when a flight is re-planned from
/// it.
#[derive(Debug, Clone, Copy)]
pub struct Moved {
    pub home: Geodetic,
    pub offset: HomeOffset,
}

/// A mission re-planned from the vehicle's home.
#[derive(Debug, Clone)]
pub struct Replanned {
    /// The mission re-expressed from the vehicle's home (`mission::rehome`).
    pub mission: Mission,
    pub plan: Plan,
    pub moved: Moved,
}

/// Why a re-planning from the vehicle's home failed: where the vehicle is could not be
/// learned, or the caller's planning failed (its own error).
#[derive(Debug)]
pub enum ReplanError<E> {
    Home(PreflightError),
    Plan(E),
}

/// `--origin vehicle`, the one way every caller does it: `target`'s home learned over `link`,
/// `mission` re-expressed from it and planned again by `plan` (the caller's planner, as it plans:
/// the CLI with its spinner, the service off its vehicle thread), which sees the mission moved
/// and where to.
pub async fn replan_from_vehicle<E, Fut>(
    link: &Link,
    target: &Autopilot,
    mission: &Mission,
    plan: impl FnOnce(&Mission, Moved) -> Fut,
) -> Result<Replanned, ReplanError<E>>
where
    Fut: std::future::Future<Output = Result<Plan, E>>,
{
    let located = vehicle_home(link, target)
        .await
        .map_err(ReplanError::Home)?;
    let moved = Moved {
        home: located.home,
        offset: HomeOffset::of(mission, located.home),
    };
    let mission = crate::mission::rehome::rehomed(mission, located.home);
    let plan = plan(&mission, moved).await.map_err(ReplanError::Plan)?;
    Ok(Replanned {
        mission,
        plan,
        moved,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::{load_str, Format, Geodetic};
    use crate::session::FlyError;

    fn sample() -> Mission {
        let text = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/paper-sample-3wp.toml"),
        )
        .unwrap();
        load_str(&text, Format::Toml, None).unwrap()
    }

    fn at(mission: &Mission, north_deg: f64) -> Result<Located, PreflightError> {
        Ok(Located {
            home: Geodetic {
                lat_deg: mission.origin.home.lat_deg + north_deg,
                ..mission.origin.home
            },
            source: HomeSource::HomePosition,
        })
    }

    fn unknown() -> Result<Located, PreflightError> {
        Err(PreflightError::NoHome(LocateError::Timeout {
            budget_s: 30.0,
            requests: 30,
            answer: None,
        }))
    }

    #[test]
    fn a_home_within_the_tolerance_passes_and_one_beyond_is_refused_naming_the_distance() {
        let m = sample();
        // 1e-4 degrees of latitude: about 11 m.
        let near = check(&m, at(&m, 1e-4), IfHomeUnknown::Refuse).unwrap();
        assert!(near.is_some_and(|o| (o.horizontal_m - 11.1).abs() < 0.2));
        // 0.02 degrees: about 2.2 km.
        let far = check(&m, at(&m, 0.02), IfHomeUnknown::FlyAsPlanned).unwrap_err();
        assert!(matches!(far, PreflightError::FarFromHome { .. }));
        let text = far.to_string();
        assert!(
            text.contains("2221 m") || text.contains("2220 m"),
            "the distance: {text}"
        );
        assert!(text.contains("(38.556200, -121.787500)"), "{text}");
        let far = FlyError::from(far);
        assert_eq!((far.stage().as_str(), far.accepted()), ("preflight", false));
    }

    #[test]
    fn an_unknown_home_is_refused_unless_the_mission_origin_was_asked_for() {
        let m = sample();
        let refused = check(&m, unknown(), IfHomeUnknown::Refuse).unwrap_err();
        assert!(matches!(refused, PreflightError::NoHome(_)));
        assert_eq!(refused.stage(), "preflight");
        assert_eq!(
            check(&m, unknown(), IfHomeUnknown::FlyAsPlanned).unwrap(),
            None
        );
    }
}
