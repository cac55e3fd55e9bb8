//! `fly`: upload the planned flight and prove it arrived, hand the recorder what to measure it
//! against, start it (arming only when asked: with a real vehicle the pilot may start it), and
//! wait until the recorder has seen it land and disarm; the recorder's report is the answer.
//! Before anything is uploaded, the vehicle's home is checked against the mission's origin
//! ([`super::home`]). With `fly --wind live` ([`Load::live_wind`]) the recorder is handed a
//! repricer too: the rest of the flight priced again, as [`load`] priced it, in the wind the
//! vehicle estimates in flight.
//! A start the autopilot refuses fails at once (`link::flight::Start` disarms a vehicle it
//! armed), and the flight folder that arming opened goes with it ([`discard_unflown`]).

use std::path::PathBuf;
use std::time::Duration;

use tokio::sync::broadcast::{self, error::RecvError};
use tracing::Instrument;

use super::home::{check_home, IfHomeUnknown, PreflightError};
use super::params::Px4Parameters;
use super::params::{check_ardupilot_params, check_px4_params, ParamCheck, ParamSection};
use super::predict::{
    flight_plan, flight_plan_predicted, predicted_by_simulation, repriced, with_fast_waypoints,
};
use super::recorder::{FlightEvent, RecorderHandle, RepriceError, Repricer};
use crate::flightlog::flight_plan::{FlightPlan, PackSource, PackUse, PricedBy, Repricing};
use crate::flightlog::guard::{GuardSetup, GuardStart};
use crate::flightlog::report::{FlightReport, ReportJson};
use crate::flightlog::watch::{NoteKind, Policy};
use crate::ledger::LedgerSpec;
use crate::link::commands::{drive, keep_streams, request_streams};
use crate::link::connection::{Autopilot, Link};
use crate::link::driver::{upload_verified, upload_verified_of, UploadError, UploadReport};
use crate::link::fence::{fence_items, rally_items, FENCE, RALLY};
use crate::link::flight::{Start, StartConfig, StartError};
use crate::link::items::{flight_items_noted, ItemOptions};
use crate::link::mav::MISSION_ITEM_INT_DATA;
use crate::link::pack::AskPackConfig;
use crate::link::support::{AskConfig, Capabilities, SupportError};
use crate::link::transfer::TransferConfig;
use crate::link::{Flavour, LinkError};
use crate::mission::rehome::HomeOffset;
use crate::mission::Mission;
use crate::physics::{Profile, Vehicle, VehicleModel, Wind};
use crate::planner::{Flight, Plan};

/// How to fly.
#[derive(Debug, Clone, PartialEq)]
pub struct FlyOptions {
    /// Arm and start the mission (PX4: arm, MISSION_START; ArduPilot: GUIDED, arm, AUTO,
    /// MISSION_START). Without it, emplan waits for the pilot to start the mission.
    pub arm: bool,
    pub start: StartConfig,
    /// The longest emplan waits (wall time) from the upload to the landing.
    pub timeout: Duration,
}

impl Default for FlyOptions {
    fn default() -> Self {
        FlyOptions {
            arm: false,
            start: StartConfig::default(),
            timeout: Duration::from_secs(3600),
        }
    }
}

/// What goes onto the vehicle: `flight` of `plan` (planned for `mission`), checked against
/// `vehicle`, the vehicle file it was planned with.
#[derive(Debug, Clone, Copy)]
pub struct Load<'a> {
    pub mission: &'a Mission,
    pub plan: &'a Plan,
    pub flight: &'a Flight<'a>,
    /// Acceptance radius sent with each waypoint (m).
    pub acceptance_radius_m: f32,
    pub vehicle: &'a Vehicle,
    /// The flight this one resumes (`fly --resume`), recorded in its plan.json.
    pub resumes: Option<&'a str>,
    /// What the energy guard may do in flight.
    pub guard: Policy,
    /// Whether a vehicle that does not say where it is is refused (the default) or flown from
    /// the mission's origin as planned.
    pub if_home_unknown: IfHomeUnknown,
    /// `fly --wind live`: the model the rest of the flight is priced again with whenever the
    /// vehicle's wind estimate moves in flight (`flightlog::wind`); None: priced once.
    pub live_wind: Option<&'a VehicleModel>,
    /// The pack flown and what the plan's battery check started from (`--pack`; plan.json's
    /// `pack`). None: not named (the autopilot's SMART_BATTERY_INFO names it when it can).
    pub pack: Option<&'a PackUse>,
    /// What the energy guard starts from: the pack's capacity and the vehicle's correction
    /// learned in earlier flights (`super::ledger::Learned::guard_start`).
    pub guard_start: Option<&'a GuardStart>,
    /// The ledger to learn the pack from when the autopilot names it (SMART_BATTERY_INFO, with
    /// no `pack` given); None: the autopilot's pack is recorded, nothing learned of it.
    pub ledger: Option<&'a LedgerSpec>,
}

/// A flight on the vehicle, verified, and what it will be measured against.
#[derive(Debug, Clone)]
pub struct Loaded {
    pub upload: UploadReport,
    /// The items sent and read back.
    pub items: Vec<MISSION_ITEM_INT_DATA>,
    /// The flight plan handed to the recorder.
    pub measured_against: FlightPlan,
    /// What a PX4 flying the px4 profile holds of the vehicle file's `[px4]` parameters, or an
    /// ArduPilot flying the ardupilot profile of its `[ardupilot]` ones (None for any other
    /// autopilot or profile). When they differ, the legs are priced as the
    /// autopilot flies them: simulated with its values.
    pub params: Option<ParamCheck>,
    /// The vehicle's home against the mission's origin (None: its home is unknown and the
    /// flight went ahead as [`Load::if_home_unknown`] allowed).
    pub home: Option<HomeOffset>,
    /// What the autopilot declared it holds besides the mission.
    pub capabilities: Capabilities,
    /// The mission's fence uploaded and verified (none: its old fence cleared); None when the
    /// autopilot holds no fence (and the mission has none).
    pub fence: Option<super::upload::ListUpload>,
    /// The mission's rally points, as the fence.
    pub rally: Option<super::upload::ListUpload>,
}

/// Puts a flight onto the vehicle, the one way every command and the service do it: checks
/// that the vehicle's home is the mission's origin (within `mission::rehome`'s tolerance), on a PX4
/// flying the px4 profile, reads its trajectory parameters and prices the legs with them when
/// they differ from the vehicle file's (`checked` sees the outcome before anything is sent),
/// builds the items, uploads them and proves they arrived by reading them back, then hands the
/// recorder (when there is one: `emplan upload` records nothing) the flight plan to measure the
/// next flight against.
///
/// The mission's geofence and rally points go up with it, each as the autopilot's list of its
/// mission type, verified by read-back; an empty one clears what the vehicle held from its last
/// site. A mission with a fence (or rally points) for an autopilot that does not declare it
/// holds one (AUTOPILOT_VERSION) is refused before anything is sent: it is never flown without.
#[allow(clippy::too_many_arguments)]
pub async fn load(
    link: &Link,
    target: &Autopilot,
    transfer: TransferConfig,
    recorder: Option<&RecorderHandle>,
    load: &Load<'_>,
    checked: impl FnOnce(Option<&ParamCheck>),
    progress: impl FnMut(usize, usize),
) -> Result<Loaded, FlyError> {
    let home = check_home(link, target, load.mission, load.if_home_unknown).await?;
    let params = match (target.flavour, load.plan.profile) {
        (Flavour::Px4, Profile::Px4) => Some(check_px4_params(link, target, load.vehicle).await?),
        (Flavour::ArduPilot, Profile::Ardupilot) => {
            Some(check_ardupilot_params(link, target, load.vehicle).await?)
        }
        _ => None,
    };
    let declared = crate::link::commands::capabilities(link, target, AskConfig::default()).await?;
    declared.check(
        &autopilot_name(target),
        !load.mission.fence.is_empty(),
        !load.mission.rally.is_empty(),
    )?;
    // Only PX4 and ArduPilot are known to keep a list per mission type. MAVSDK's mission server
    // (a generic autopilot) declares fence and rally points and takes any MISSION_COUNT as its
    // mission's: the empty fence that clears an old one wiped the mission just sent there
    // (sitl/mavsdk_peer.sh). A generic autopilot is held to hold neither.
    let capabilities = match target.flavour {
        Flavour::Generic => crate::link::support::Capabilities {
            fence: false,
            rally: false,
            ..declared
        },
        Flavour::Px4 | Flavour::ArduPilot => declared,
    };
    if target.flavour == Flavour::Generic
        && (!load.mission.fence.is_empty() || !load.mission.rally.is_empty())
    {
        return Err(crate::link::support::SupportError::Cannot {
            what: "a geofence or rally points",
            autopilot: autopilot_name(target),
            how: "is neither PX4 nor ArduPilot, whose fence and rally lists emplan knows (a \
                  generic autopilot may take them for its mission)"
                .into(),
        }
        .into());
    }
    checked(params.as_ref());
    let (mission, plan, flight) = (load.mission, load.plan, load.flight);
    let items = items(target.flavour, load)?;
    let priced_with = params
        .as_ref()
        .filter(|c| !c.differences.is_empty())
        .map(|c| &c.vehicle);
    let measured_against = match priced_with {
        None => flight_plan(mission, plan, flight, target.flavour),
        Some(vehicle) => {
            let predicted =
                predicted_by_simulation(vehicle, plan.profile, mission, flight, &plan.speeds_m_s)
                    .map_err(|e| FlyError::Plan(e.to_string()))?;
            flight_plan_predicted(mission, flight, target.flavour, predicted)
        }
    }
    .map_err(|e| FlyError::Plan(e.to_string()))?;
    // ArduCopter flies zero-hold waypoints through, blending the corners: the flown order's
    // legs are priced that way (the plan's table prices are rest to rest).
    let mut measured_against = measured_against;
    let predicted = (measured_against.predicted.take())
        .map(|p| {
            let vehicle = priced_with.unwrap_or(load.vehicle);
            // A chain is flown at one speed: the mission's, when a DO_CHANGE_SPEED set one for
            // the whole flight; with speeds that change along it the legs keep their rest to
            // rest prices.
            let first = plan.speeds_m_s.first().copied().flatten();
            if plan.speeds_m_s.iter().any(|v| *v != first) {
                return Ok(p);
            }
            let at_speed = first.map(|v| vehicle.at_speed(v));
            with_fast_waypoints(
                at_speed.as_ref().unwrap_or(vehicle),
                plan.profile,
                &measured_against.points,
                p,
                plan.wind,
            )
        })
        .transpose()
        .map_err(|e| FlyError::Plan(e.to_string()))?;
    // The pack: the one named, else (when the flight is recorded) the one the autopilot names,
    // with what the ledger learned of it.
    let vehicle = priced_with.unwrap_or(load.vehicle).name.clone();
    let (pack, guard_start) = match (load.pack, recorder) {
        // Learned by the caller (`fly` before planning), or nowhere to learn it from.
        (Some(pack), _) if load.guard_start.is_some() || load.ledger.is_none() => {
            (Some(pack.clone()), load.guard_start.cloned())
        }
        (Some(pack), _) => learned_pack(&pack.name, pack.source, load.ledger, vehicle).await,
        (None, None) => (None, load.guard_start.cloned()),
        (None, Some(_)) => {
            let named =
                crate::link::commands::pack_named(link, target, AskPackConfig::default()).await?;
            match named.map(|n| super::ledger::pack_name(&n)) {
                Some(Ok(name)) => {
                    learned_pack(&name, PackSource::Autopilot, load.ledger, vehicle).await
                }
                Some(Err(e)) => {
                    tracing::warn!("the autopilot's SMART_BATTERY_INFO names no usable pack: {e}");
                    (None, load.guard_start.cloned())
                }
                None => (None, load.guard_start.cloned()),
            }
        }
    };
    let mut measured_against = FlightPlan {
        resumes: load.resumes.map(str::to_string),
        pack,
        wind: (!plan.wind.is_calm()).then_some(plan.wind),
        priced_by: predicted.as_ref().map(|_| PricedBy {
            vehicle: priced_with.unwrap_or(load.vehicle).name.clone(),
            profile: plan.profile.to_string(),
        }),
        predicted,
        ..measured_against
    };
    let mut autopilot_return = None;
    if load.guard != Policy::Off {
        let ret = super::guard::autopilot_return(link, target, &load.mission.rally).await?;
        let setup = super::guard::setup(
            priced_with.unwrap_or(load.vehicle),
            plan.profile,
            target.flavour,
            &measured_against,
            load.guard,
            &ret,
            plan.wind,
        )
        .map_err(|e| FlyError::Plan(format!("the energy guard's return prices: {e}")))?;
        measured_against.guard = Some(GuardSetup {
            start: guard_start,
            ..setup
        });
        autopilot_return = Some(ret);
    }
    let upload = upload_verified(link, target, &items, transfer, progress).await?;
    let fence = match capabilities.fence {
        false => None,
        true => {
            let sent = fence_items(&mission.fence);
            let report =
                upload_verified_of(FENCE, link, target, &sent, transfer, |_, _| {}).await?;
            Some(super::upload::ListUpload::new(
                mission.fence.zones.len(),
                &report,
            ))
        }
    };
    let rally = match capabilities.rally {
        false => None,
        true => {
            let sent = rally_items(&mission.rally, target.flavour);
            let report =
                upload_verified_of(RALLY, link, target, &sent, transfer, |_, _| {}).await?;
            Some(super::upload::ListUpload::new(mission.rally.len(), &report))
        }
    };
    match (recorder, load.live_wind) {
        (None, _) => {}
        (Some(recorder), Some(model)) => {
            let model = VehicleModel {
                vehicle: priced_with.unwrap_or(load.vehicle).clone(),
                ..model.clone()
            };
            let repricer = repricer(model, target.flavour, autopilot_return);
            recorder.set_plan_repriced(measured_against.clone(), repricer);
        }
        (Some(recorder), None) => recorder.set_plan(measured_against.clone()),
    }
    Ok(Loaded {
        upload,
        items,
        measured_against,
        params,
        home,
        capabilities,
        fence,
        rally,
    })
}

/// Pack `name` (named by `source`) and what the energy guard starts from: what the ledger at
/// `ledger` learned of it and of `vehicle` (read on a blocking thread: the store must not run
/// inside the async runtime); the label when there is no ledger or it cannot be read (warned
/// of).
async fn learned_pack(
    name: &str,
    source: PackSource,
    ledger: Option<&LedgerSpec>,
    vehicle: String,
) -> (Option<PackUse>, Option<GuardStart>) {
    let bare = PackUse {
        name: name.to_string(),
        source,
        capacity_ratio: None,
    };
    let Some(spec) = ledger.cloned() else {
        return (Some(bare), None);
    };
    let asked = name.to_string();
    let learned =
        tokio::task::spawn_blocking(move || super::ledger::learned(&spec, Some(&asked), &vehicle))
            .await;
    match learned {
        Ok(Ok(learned)) => {
            for note in &learned.notes {
                tracing::info!("{note}");
            }
            (Some(learned.pack_use(name, source)), learned.guard_start())
        }
        Ok(Err(e)) => {
            tracing::warn!("pack {name}: {e}: the guard starts from its label");
            (Some(bare), None)
        }
        Err(e) => {
            tracing::warn!(
                "pack {name}: reading the ledger stopped: {e}: the guard starts from its label"
            );
            (Some(bare), None)
        }
    }
}

/// How errors name the autopilot: its kind and system id.
fn autopilot_name(target: &Autopilot) -> String {
    let kind = match target.flavour {
        Flavour::Px4 => "PX4",
        Flavour::ArduPilot => "ArduPilot",
        Flavour::Generic => "a generic MAVLink autopilot",
    };
    format!("{kind}, system {}", target.system_id)
}

/// The items `load` sends to an autopilot of `flavour`: its waypoints in the flight's order
/// with their actions, each accepted within the load's radius, at the vehicle's cruise speed,
/// and each leg's via points round a fence zone flown through without a hold.
pub fn items(flavour: Flavour, load: &Load<'_>) -> Result<Vec<MISSION_ITEM_INT_DATA>, FlyError> {
    let options = ItemOptions {
        flavour,
        acceptance_radius_m: load.acceptance_radius_m,
        vehicle_speed_m_s: Some(load.vehicle.cruise_speed_m_s(flavour == Flavour::ArduPilot)),
        ..ItemOptions::default()
    };
    let via = super::predict::flight_via(load.flight);
    flight_items_noted(load.mission, &load.flight.waypoints(), &via, &options)
        .map(|(items, _, _)| items)
        .map_err(FlyError::Items)
}

/// Prices the rest of a flight again in a wind heard in flight, as `load` priced it before it
/// flew: every leg after the one before it on its heading (ArduCopter's fast waypoints as its
/// chain), the settles, the hovers and the landing in that wind, and the guard's return from
/// every point (when the flight is guarded: `ret` is then the autopilot's return).
fn repricer(
    model: VehicleModel,
    flavour: Flavour,
    ret: Option<super::guard::AutopilotReturn>,
) -> Repricer {
    Box::new(move |plan: &FlightPlan, wind: Wind, from_point: usize| {
        let model = model.clone().with_wind(wind);
        let predicted = repriced(plan, &model)?;
        let home_j = match (&plan.guard, &ret) {
            (Some(guard), Some(ret)) => {
                super::guard::setup(
                    &model.vehicle,
                    model.profile,
                    flavour,
                    plan,
                    guard.policy,
                    ret,
                    wind,
                )
                .map_err(RepriceError::Guard)?
                .home_j
            }
            _ => Vec::new(),
        };
        let legs = predicted
            .legs
            .get(from_point..)
            .unwrap_or_default()
            .to_vec();
        let mut repricing = Repricing {
            t_s: 0.0,
            wind,
            from_point,
            legs,
            hover_power_w: predicted.hover_power_w,
            landing_j: predicted.landing_j,
            home_j,
            rest_before_j: plan.predicted_rest_j(from_point).unwrap_or(0.0),
            rest_after_j: 0.0,
        };
        // The rest as the plan prices it with this repricing: the plan's own sum.
        let mut after = plan.clone();
        after.repricings.push(repricing.clone());
        repricing.rest_after_j = after.predicted_rest_j(from_point).unwrap_or(0.0);
        Ok(repricing)
    })
}

/// Why a flight did not end in a report.
#[derive(Debug, thiserror::Error)]
pub enum FlyError {
    #[error("mission items: {0}")]
    Items(crate::link::items::ItemsError),
    /// The vehicle is not where the plan starts, or did not say where it is: found before
    /// anything was uploaded or armed.
    #[error(transparent)]
    Preflight(#[from] PreflightError),
    #[error(transparent)]
    Upload(#[from] UploadError),
    #[error("flight plan: {0}")]
    Plan(String),
    /// The mission holds what the autopilot cannot (a fence, rally points): found before
    /// anything was uploaded.
    #[error(transparent)]
    Unsupported(#[from] SupportError),
    #[error("start: {0}")]
    Start(#[from] StartError),
    #[error("link: {0}")]
    Link(#[from] LinkError),
    #[error(
        "the flight did not end within {seconds:.0} s{}",
        .dir.as_ref().map(|d| format!(" (recorded so far in {})", d.display())).unwrap_or_else(|| " (it never started: was it armed?)".into())
    )]
    Timeout { seconds: f64, dir: Option<PathBuf> },
    #[error("recording: {0}")]
    Recorder(String),
    /// The flight log cannot be written: found before anything was uploaded or armed.
    #[error("recording: {0}")]
    LogDir(crate::flightlog::FlightLogError),
    #[error("the vehicle disarmed after {duration_s:.1} s without flying a leg of the mission (log in {})", .dir.display())]
    NotFlown { duration_s: f64, dir: PathBuf },
    #[error("the flight in {} has no report (no flight plan reached the recorder)", .dir.display())]
    NoReport { dir: PathBuf },
}

impl FlyError {
    /// The stage it failed in (the `stage` of the failure JSON).
    pub fn stage(&self) -> String {
        match self {
            FlyError::Items(_) | FlyError::Plan(_) => "plan".into(),
            FlyError::Unsupported(_) => "preflight".into(),
            FlyError::Preflight(e) => e.stage().into(),
            FlyError::Upload(e) => e.stage.to_string(),
            FlyError::Start(_) => "start".into(),
            FlyError::Link(_) => "connect".into(),
            FlyError::Timeout { .. } => "flight".into(),
            FlyError::Recorder(_) | FlyError::LogDir(_) | FlyError::NoReport { .. } => {
                "record".into()
            }
            FlyError::NotFlown { .. } => "flight".into(),
        }
    }

    /// Whether the autopilot had accepted the mission when it failed: from the start on.
    pub fn accepted(&self) -> bool {
        match self {
            FlyError::Upload(e) => e.accepted,
            FlyError::Start(_)
            | FlyError::Timeout { .. }
            | FlyError::Recorder(_)
            | FlyError::NotFlown { .. }
            | FlyError::NoReport { .. } => true,
            FlyError::Items(_)
            | FlyError::Plan(_)
            | FlyError::Link(_)
            | FlyError::LogDir(_)
            | FlyError::Unsupported(_)
            | FlyError::Preflight(_) => false,
        }
    }
}

/// A flight flown and recorded.
#[derive(Debug, Clone)]
pub struct Flown {
    pub upload: UploadReport,
    /// What the PX4 held of the vehicle file's trajectory parameters (see [`Loaded::params`]).
    pub params: Option<ParamCheck>,
    pub dir: PathBuf,
    pub report: Option<FlightReport>,
}

impl Flown {
    /// Its report and the document `fly --json` prints of it; a flight the recorder could not
    /// measure (no plan reached it) is an error naming its directory.
    pub fn reported(self) -> Result<(FlightReport, FlyJson), FlyError> {
        let Some(report) = self.report else {
            return Err(FlyError::NoReport { dir: self.dir });
        };
        let dir = self.dir.display().to_string();
        let doc = match self.params.as_ref() {
            Some(check) if check.section == ParamSection::Ardupilot => FlyJson {
                ardupilot_parameters: Some(Px4Parameters::from(check)),
                ..FlyJson::new(report.json(), &dir, None)
            },
            params => FlyJson::new(report.json(), &dir, params.map(Px4Parameters::from)),
        };
        Ok((report, doc))
    }
}

/// Flies `load` on `target`, recorded by `recorder` (spawned on the same link): the telemetry
/// rates asked for, the flight [`load`]ed, started when `opts.arm` (else the pilot starts it),
/// followed until it has landed. `checked` sees the parameter check before the upload;
/// `on_event` every flight event as it comes (for live lines).
#[allow(clippy::too_many_arguments)]
pub async fn fly(
    link: &Link,
    target: &Autopilot,
    transfer: TransferConfig,
    recorder: &RecorderHandle,
    flight: &Load<'_>,
    opts: &FlyOptions,
    checked: impl FnOnce(Option<&ParamCheck>),
    mut on_event: impl FnMut(&FlightEvent),
) -> Result<Flown, FlyError> {
    // The rates first: at its defaults PX4 sends BATTERY_STATUS every 2 s.
    request_streams(link, target).await?;
    let Loaded { upload, params, .. } = load(
        link,
        target,
        transfer,
        Some(recorder),
        flight,
        checked,
        |_, _| {},
    )
    .await?;
    let mut events = recorder.subscribe();
    let flying = async {
        if opts.arm {
            if let Err(refused) = arm_and_start(link, target, opts.start, recorder).await {
                if let Some(discarding) = refused.discarding {
                    let _ = discarding.await;
                }
                return Err(refused.error);
            }
        }
        let mut dir = None;
        loop {
            match events.recv().await {
                Ok(event) => {
                    on_event(&event);
                    match event {
                        FlightEvent::Started { dir: d, .. } => dir = Some(d),
                        FlightEvent::Ended { dir, report, .. } => {
                            if let Some(r) = report.as_ref().filter(|r| r.legs.is_empty()) {
                                return Err(FlyError::NotFlown {
                                    duration_s: r.duration_s,
                                    dir,
                                });
                            }
                            return Ok((dir, report.map(|r| *r)));
                        }
                        // The flight's directory could not be made: nothing of it will be
                        // recorded, and no end will ever come.
                        FlightEvent::Failed { error, .. } if dir.is_none() => {
                            return Err(FlyError::Recorder(error));
                        }
                        FlightEvent::Failed { error, .. } => {
                            tracing::error!("recording: {error}");
                        }
                        FlightEvent::Guard { note, .. } if note.kind == NoteKind::Return => {
                            super::guard::send_home(link, target).await?;
                        }
                        FlightEvent::Part { .. }
                        | FlightEvent::Guard { .. }
                        | FlightEvent::Repriced { .. } => {}
                    }
                }
                Err(RecvError::Lagged(n)) => tracing::warn!("{n} flight events missed"),
                Err(RecvError::Closed) => {
                    return Err(FlyError::Recorder(format!(
                        "the recorder stopped{}",
                        dir.as_ref()
                            .map(|d: &PathBuf| format!(" (flight in {})", d.display()))
                            .unwrap_or_default()
                    )))
                }
            }
        }
    };
    let started = std::time::Instant::now();
    let outcome = tokio::select! {
        outcome = tokio::time::timeout(opts.timeout, flying) => outcome,
        streams = keep_streams(link, target) => {
            return Err(streams.err().map_or_else(|| FlyError::Recorder("telemetry requests ended".into()), FlyError::Link))
        }
    };
    match outcome {
        Ok(Ok((dir, report))) => Ok(Flown {
            upload,
            params,
            dir,
            report,
        }),
        Ok(Err(e)) => Err(e),
        Err(_) => Err(FlyError::Timeout {
            seconds: started.elapsed().as_secs_f64(),
            dir: recorder
                .live()
                .borrow()
                .flight
                .as_ref()
                .map(|f| f.dir.clone()),
        }),
    }
}

/// The document `emplan fly --json` prints for a flight flown, alone or through a service: the
/// report, `ok`, the flight's directory and, on a PX4 flying the px4 profile, the trajectory
/// parameters it held.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FlyJson {
    #[serde(flatten)]
    pub report: ReportJson,
    pub ok: bool,
    pub log_dir: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub px4_parameters: Option<Px4Parameters>,
    /// As `px4_parameters`, on an ArduPilot flying the ardupilot profile.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ardupilot_parameters: Option<Px4Parameters>,
}

impl FlyJson {
    pub fn new(report: ReportJson, log_dir: &str, px4_parameters: Option<Px4Parameters>) -> Self {
        FlyJson {
            report,
            ok: true,
            log_dir: log_dir.to_string(),
            px4_parameters,
            ardupilot_parameters: None,
        }
    }

    /// As JSON, its keys in the order `fly --json` prints them.
    pub fn json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or(serde_json::Value::Null)
    }
}

/// The document `emplan fly --json` prints when the flight failed: the stage, whether the
/// autopilot had accepted the mission, the error.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FlyFailure {
    pub ok: bool,
    pub stage: String,
    pub accepted: bool,
    pub error: String,
}

impl FlyFailure {
    pub fn new(stage: &str, accepted: bool, error: &str) -> Self {
        FlyFailure {
            ok: false,
            stage: stage.to_string(),
            accepted,
            error: error.to_string(),
        }
    }

    /// The failure of `error` (its message is `message`, with the context it gathered).
    pub fn of(error: &FlyError, message: &str) -> Self {
        FlyFailure::new(&error.stage(), error.accepted(), message)
    }

    /// As JSON, its keys in the order `fly --json` prints them.
    pub fn json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or(serde_json::Value::Null)
    }
}

/// How long [`arm_and_start`], after a refused start it disarmed, waits for the flight its
/// arming opened: the recorder opens it at the first heartbeat showing the vehicle armed, and
/// PX4 and ArduPilot send one a second. 3 s (the service's; `fly` had 2 s): one heartbeat lost
/// on the radio must not leave the empty folder behind, and the longer wait costs only a
/// failing `fly` up to a second more, when no flight opened at all.
pub const DISCARD_OPENED_WITHIN: Duration = Duration::from_secs(3);
/// How long [`arm_and_start`] then waits for that flight to end: the disarm's heartbeat (one
/// a second) and the recorder's tail after it (half a second). 10 s (the service's; `fly` had
/// 5 s): a slow or lossy radio delays the disarmed heartbeat, and the wait ends as soon as the
/// flight does, so the margin costs nothing when the link is good.
pub const DISCARD_ENDED_WITHIN: Duration = Duration::from_secs(10);

/// A start that failed: why, and (when the autopilot had been armed and was disarmed again)
/// the removal of the flight folder its arming opened, under way.
#[derive(Debug)]
pub struct StartFailed {
    /// [`FlyError::Link`] when the exchange failed, [`FlyError::Start`] when the autopilot
    /// refused.
    pub error: FlyError,
    /// [`discard_unflown`] running on its own task: awaited by a caller about to stop (the
    /// CLI), left to run by one that stays (the service's actor).
    pub discarding: Option<tokio::task::JoinHandle<Option<PathBuf>>>,
}

/// Arms the vehicle and starts the mission it holds (`link::flight::Start`: PX4 arm,
/// MISSION_START; ArduPilot GUIDED, arm, AUTO, MISSION_START), the one way every caller does.
/// A start refused after arming disarms at once, and the flight folder that arming opened on
/// `recorder` is removed when nothing was flown in it ([`discard_unflown`], on a task of its
/// own).
pub async fn arm_and_start(
    link: &Link,
    target: &Autopilot,
    config: StartConfig,
    recorder: &RecorderHandle,
) -> Result<(), StartFailed> {
    // Subscribed before arming: the flight the arming opens is seen.
    let opened = recorder.subscribe();
    let mut start = Start::new(*target, config);
    if let Err(e) = drive(link, target, &mut start).await {
        return Err(StartFailed {
            error: FlyError::Link(e),
            discarding: None,
        });
    }
    match start.finished() {
        Some(Err(e)) => {
            let discarding = (e.disarmed() == Some(true)).then(|| {
                tokio::spawn(
                    discard_unflown(opened, DISCARD_OPENED_WITHIN, DISCARD_ENDED_WITHIN)
                        .in_current_span(),
                )
            });
            Err(StartFailed {
                error: FlyError::Start(e.clone()),
                discarding,
            })
        }
        _ => Ok(()),
    }
}

/// After a start that failed once it had armed the vehicle, and disarmed it again: removes the
/// flight folder that arming opened (the first flight `events`, subscribed before the start,
/// sees open within `opened_within`) once it has ended (within `ended_within`), when no leg of
/// a mission was flown in it. A refused start leaves no empty flight folder behind. Returns the
/// folder removed.
pub async fn discard_unflown(
    mut events: broadcast::Receiver<FlightEvent>,
    opened_within: Duration,
    ended_within: Duration,
) -> Option<PathBuf> {
    let opened = tokio::time::timeout(opened_within, async {
        loop {
            match events.recv().await {
                Ok(FlightEvent::Started {
                    dir,
                    resumed: false,
                    ..
                }) => return Some(dir),
                Ok(_) | Err(RecvError::Lagged(_)) => {}
                Err(RecvError::Closed) => return None,
            }
        }
    })
    .await
    .ok()
    .flatten()?;
    let unflown = tokio::time::timeout(ended_within, async {
        loop {
            match events.recv().await {
                Ok(FlightEvent::Ended { dir, report, .. }) if dir == opened => {
                    return report.is_none_or(|r| r.legs.is_empty());
                }
                Ok(_) | Err(RecvError::Lagged(_)) => {}
                Err(RecvError::Closed) => return false,
            }
        }
    })
    .await
    .unwrap_or(false);
    if !unflown {
        return None;
    }
    match tokio::fs::remove_dir_all(&opened).await {
        Ok(()) => {
            tracing::info!(
                "removed {}: the start failed before anything was flown",
                opened.display()
            );
            Some(opened)
        }
        Err(e) => {
            tracing::warn!("{}: not removed: {e}", opened.display());
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::report::{FlightReport, PartReport};

    fn started(dir: &std::path::Path) -> FlightEvent {
        FlightEvent::Started {
            flight: "f".into(),
            dir: dir.to_path_buf(),
            resumed: false,
        }
    }

    fn ended(dir: &std::path::Path, legs: usize) -> FlightEvent {
        let leg = PartReport {
            from: "origin".into(),
            to: "A".into(),
            predicted_j: None,
            measured_j: None,
            consumed_j: None,
            duration_s: 1.0,
            predicted_duration_s: None,
            start_s: 0.0,
            end_s: 1.0,
            coverage: 1.0,
            flags: Vec::new(),
            start_offset_m: None,
            start_speed_m_s: None,
            via_points: 0,
        };
        FlightEvent::Ended {
            flight: "f".into(),
            dir: dir.to_path_buf(),
            report: Some(Box::new(FlightReport {
                flight: "f".into(),
                takeoff: None,
                legs: vec![leg; legs],
                settles: Vec::new(),
                hovers: Vec::new(),
                landing: None,
                return_home: None,
                return_to: None,
                breaches: Vec::new(),
                waypoints_left: Vec::new(),
                predicted_j: None,
                measured_j: None,
                duration_s: 1.0,
                complete: true,
                flags: Vec::new(),
                log_gaps: Vec::new(),
                guard: None,
                source: None,
                repriced: Vec::new(),
                photos: Default::default(),
                blocks: Vec::new(),
            })),
        }
    }

    const S: Duration = Duration::from_secs(1);

    #[tokio::test]
    async fn the_folder_a_refused_start_opened_is_removed_once_it_ends_with_nothing_flown() {
        let work = tempfile::tempdir().unwrap();
        let (other, ours) = (work.path().join("other"), work.path().join("ours"));
        for d in [&other, &ours] {
            std::fs::create_dir(d).unwrap();
        }
        let (tx, rx) = broadcast::channel(16);
        tx.send(started(&ours)).unwrap();
        tx.send(ended(&other, 0)).unwrap();
        tx.send(ended(&ours, 0)).unwrap();
        assert_eq!(discard_unflown(rx, S, S).await, Some(ours.clone()));
        assert!(!ours.exists() && other.exists());
    }

    #[tokio::test]
    async fn a_flight_with_a_leg_flown_is_kept() {
        let work = tempfile::tempdir().unwrap();
        let (tx, rx) = broadcast::channel(16);
        tx.send(started(work.path())).unwrap();
        tx.send(ended(work.path(), 1)).unwrap();
        assert_eq!(discard_unflown(rx, S, S).await, None);
        assert!(work.path().exists());
    }

    #[tokio::test]
    async fn a_flight_not_ended_in_time_is_kept_and_none_opened_is_waited_for_no_longer() {
        let short = Duration::from_millis(20);
        let work = tempfile::tempdir().unwrap();
        let (tx, rx) = broadcast::channel(16);
        tx.send(started(work.path())).unwrap();
        assert_eq!(discard_unflown(rx, S, short).await, None);
        assert!(work.path().exists());
        let (_tx, rx) = broadcast::channel(16);
        assert_eq!(discard_unflown(rx, short, S).await, None);
    }
}
