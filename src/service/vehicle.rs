//! The vehicle actor: one task owns everything that talks to the vehicle (the `Link`, the
//! autopilot found on it, the flight recorder on its tap, the built-in mock when there is no
//! `--connect`). Handlers send it `(command, oneshot)`: uploads and starts run one at a time, in
//! the order asked, so two clients never interleave on the radio. It keeps the queue and the
//! state; every decision about a flight is the session's (`session::connect_until_open`,
//! `session::load`, `session::arm_and_start`, `session::replan_from_vehicle`,
//! `session::held_flight_plan`). Between commands it keeps the
//! link (the session connecting until it works, the autopilot's heartbeat watched: `connecting`,
//! `waiting_for_heartbeat`, `connected`, `lost`), asks for the telemetry streams again after
//! every reconnect or return of the heartbeat, and when a flight starts reads back the mission
//! the vehicle holds: the flight is measured against what it flies, whoever uploaded it.
//!
//! A start is refused before anything is armed unless the vehicle holds a mission: the one this
//! service uploaded and read back (and nothing since may have changed: an upload begun, the
//! heartbeat lost, a start refused), or else one it reads back from the vehicle at the start (a
//! pilot's upload). A start the autopilot refuses after arming disarms at once
//! (`link::flight::Start`), and the flight folder that arming opened is removed when nothing was
//! flown in it.
//!
//! Reads (link state, telemetry, flights) never wait for it: they come from watch channels and
//! the event hub.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::{broadcast, mpsc, oneshot, watch};
use tokio::time::Instant;
use tracing::Instrument;

use super::events::{self, Hub};
use super::missions::CatalogRx;
use super::wire::{Failure, LinkNumbers, LinkState, LinkStatus, UploadAnswer};
use super::Refusal;
use crate::flightlog::flight_plan::FlightPlan;
use crate::flightlog::flight_plan::{PackSource, PackUse};
use crate::flightlog::watch::{NoteKind, Policy};
use crate::link::commands::{heartbeats, Heard};
use crate::link::connection::{Autopilot, Link};
use crate::link::driver::download;
use crate::link::flight::{StartConfig, StartError};
use crate::link::items::item_json;
use crate::link::mav::MISSION_ITEM_INT_DATA;
use crate::link::Flavour;
use crate::mission::{Geodetic, Mission, Origin};
use crate::physics::{Vehicle, VehicleModel};
use crate::planner::json::upload_document;
use crate::planner::{FlightChoice, Plan};
use crate::session::upload::UploadJson;
use crate::session::PlanOrigin;
use crate::session::{
    self, request_streams, spawn_recorder, FlightEvent, FlyError, Known, Load, ParamCheck,
    Px4Parameters, RecorderConfig, RecorderHandle,
};
use crate::sim::{MockAutopilot, MockConfig, MockHandle};

/// How to reach the vehicle: a session's target. The built-in mock's home follows the missions
/// uploaded (it is restarted at a mission's home before an upload from elsewhere, while
/// disarmed).
pub use crate::session::Target as VehicleLink;

/// The vehicle side of the service.
#[derive(Debug, Clone)]
pub struct VehicleConfig {
    pub link: VehicleLink,
    /// Time allowed for one transfer (None: the link's default for its item count).
    pub transfer_budget: Option<Duration>,
    pub recorder: RecorderConfig,
    /// What the energy guard may do in the service's flights.
    pub guard: Policy,
}

/// An upload asked of the vehicle: `choice` of `plan` (planned for that choice) of `mission`.
#[derive(Debug)]
pub struct UploadJob {
    /// The mission's name in the catalog (its file name).
    pub name: String,
    pub mission: Arc<Mission>,
    pub plan: Arc<Plan>,
    pub choice: FlightChoice,
    pub acceptance_radius_m: f32,
    /// Where the flight is planned from (None: the mission's origin, the vehicle required
    /// there).
    pub origin: Option<PlanOrigin>,
    /// The pack flown, as the request named it.
    pub pack: Option<String>,
    /// How `plan` was solved (the same for a re-planning from the vehicle's home).
    pub solver: crate::tour::solver::Options,
    /// The request's span (`upload`).
    pub span: tracing::Span,
}

enum Command {
    Upload(
        Box<UploadJob>,
        UploadSlot,
        oneshot::Sender<Result<UploadAnswer, Refusal>>,
    ),
    Start(oneshot::Sender<Result<(), Refusal>>),
}

/// How handlers reach the vehicle actor.
#[derive(Debug, Clone)]
pub struct VehicleHandle {
    commands: mpsc::Sender<Command>,
    status: watch::Receiver<LinkStatus>,
    /// The mission of the upload under way, if any (see [`UploadSlot`]).
    uploading: Arc<std::sync::Mutex<Option<String>>>,
}

/// The one upload under way, from the moment its request is taken (before it is planned) until
/// the vehicle's copy is verified or the upload fails: a second upload, or a start, asked
/// meanwhile is refused (409) rather than run after it, so that no answer says "verified" for a
/// mission the vehicle no longer holds. The request holds it, then the vehicle actor while it
/// transfers (a client that hangs up does not free it early); dropping it frees it.
#[derive(Debug)]
pub struct UploadSlot {
    uploading: Arc<std::sync::Mutex<Option<String>>>,
}

impl Drop for UploadSlot {
    fn drop(&mut self) {
        *lock(&self.uploading) = None;
    }
}

/// The lock of the upload under way (never held across an await; a panic while it was held
/// leaves the name, which is still true or soon cleared).
fn lock(uploading: &std::sync::Mutex<Option<String>>) -> std::sync::MutexGuard<'_, Option<String>> {
    uploading
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The refusal of what cannot run while the upload of `mission` is under way.
fn upload_under_way(mission: &str, asked: &str) -> Refusal {
    Refusal::new(
        409,
        "vehicle",
        &format!(
            "the upload of {} is under way: one transfer at a time; {asked} refused (ask again \
             once it has answered)",
            super::escape_controls(mission)
        ),
    )
}

impl std::fmt::Debug for Command {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Command::Upload(job, _, _) => write!(f, "Upload({})", job.name),
            Command::Start(_) => f.write_str("Start"),
        }
    }
}

fn gone() -> Refusal {
    Refusal::new(503, "service", "the service is stopping")
}

impl VehicleHandle {
    /// Takes the one upload's place for `mission`, refused (409) while another upload is
    /// under way.
    pub fn begin_upload(&self, mission: &str) -> Result<UploadSlot, Refusal> {
        let mut uploading = lock(&self.uploading);
        if let Some(other) = uploading.as_deref() {
            return Err(upload_under_way(
                other,
                &format!("this upload of {}", super::escape_controls(mission)),
            ));
        }
        *uploading = Some(mission.to_string());
        Ok(UploadSlot {
            uploading: self.uploading.clone(),
        })
    }

    /// Uploads (verified) and answers the upload document, or refuses; `slot` is held until
    /// the vehicle actor is done with it.
    pub async fn upload(&self, job: UploadJob, slot: UploadSlot) -> Result<UploadAnswer, Refusal> {
        let (tx, rx) = oneshot::channel();
        self.commands
            .send(Command::Upload(Box::new(job), slot, tx))
            .await
            .map_err(|_| gone())?;
        rx.await.unwrap_or_else(|_| Err(gone()))
    }

    /// Arms the vehicle and starts the mission it holds; refused (409) while an upload is
    /// under way (the mission is about to change).
    pub async fn start(&self) -> Result<(), Refusal> {
        if let Some(mission) = lock(&self.uploading).clone() {
            return Err(upload_under_way(&mission, "the start"));
        }
        let (tx, rx) = oneshot::channel();
        self.commands
            .send(Command::Start(tx))
            .await
            .map_err(|_| gone())?;
        rx.await.unwrap_or_else(|_| Err(gone()))
    }

    /// The link's state now.
    pub fn status(&self) -> LinkStatus {
        self.status.borrow().clone()
    }

    /// The link's state as it changes.
    pub fn watch_status(&self) -> watch::Receiver<LinkStatus> {
        self.status.clone()
    }
}

/// A heartbeat older than this means the link is lost.
const HEARTBEAT_LOST: Duration = Duration::from_secs(3);

/// Starts the vehicle actor on a thread of its own with its own single-threaded runtime (the
/// link's receive task, the heartbeat, the built-in mock and the actor share it, as in `fly`):
/// however busy the HTTP side is, nothing queues in front of the receive task, so the socket's
/// buffer does not overflow at high telemetry rates. It runs until `stop` turns true (then
/// closes the flight log); the returned receiver resolves when it has.
pub fn spawn(
    cfg: VehicleConfig,
    model: Arc<VehicleModel>,
    catalog: CatalogRx,
    hub: Arc<Hub>,
    stop: watch::Receiver<bool>,
) -> Result<(VehicleHandle, oneshot::Receiver<()>), std::io::Error> {
    let (commands, rx) = mpsc::channel(16);
    let (url, builtin_mock) = match &cfg.link {
        VehicleLink::Connect { url, .. } => (url.clone(), false),
        VehicleLink::Mock { .. } => ("the built-in mock autopilot".to_string(), true),
    };
    let (status_tx, status) = watch::channel(LinkStatus {
        state: LinkState::Connecting,
        url,
        builtin_mock,
        autopilot: None,
        reconnects: 0,
        error: None,
    });
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let (done_tx, done) = oneshot::channel();
    std::thread::Builder::new()
        .name("vehicle".into())
        .spawn(move || {
            runtime.block_on(run(cfg, model, catalog, hub, stop, rx, status_tx));
            let _ = done_tx.send(());
        })?;
    let handle = VehicleHandle {
        commands,
        status,
        uploading: Default::default(),
    };
    Ok((handle, done))
}

/// Why the built-in mock did not start.
#[derive(Debug, thiserror::Error)]
pub enum MockError {
    /// The built-in vehicle it flies did not load.
    #[error(transparent)]
    Vehicle(#[from] crate::physics::PhysicsError),
    #[error(transparent)]
    Sim(#[from] crate::sim::SimError),
}

/// The built-in mock and how to start it again elsewhere.
struct BuiltinMock {
    handle: Option<MockHandle>,
    config: MockConfig,
    vehicle: Vehicle,
    addr: SocketAddr,
}

impl BuiltinMock {
    async fn spawn(
        config: MockConfig,
        vehicle: Option<Box<Vehicle>>,
    ) -> Result<BuiltinMock, MockError> {
        let vehicle = match vehicle {
            Some(v) => *v,
            None => crate::physics::builtin::vehicle()?,
        };
        let handle =
            MockAutopilot::spawn_with_vehicle("udpin:127.0.0.1:0", config, vehicle.clone()).await?;
        Ok(BuiltinMock {
            addr: handle.local_addr(),
            handle: Some(handle),
            config,
            vehicle,
        })
    }

    fn home(&self) -> Option<Geodetic> {
        self.config.flight.map(|f| f.home)
    }

    /// Stops the mock and starts it again at `home`, on the same port.
    async fn move_home(&mut self, home: Geodetic) -> Result<(), MockError> {
        let Some(mut flight) = self.config.flight else {
            return Ok(());
        };
        if let Some(old) = self.handle.take() {
            let _ = old.shutdown().await;
        }
        flight.home = home;
        self.config.flight = Some(flight);
        let handle = MockAutopilot::spawn_with_vehicle(
            &format!("udpin:{}", self.addr),
            self.config,
            self.vehicle.clone(),
        )
        .await?;
        self.handle = Some(handle);
        Ok(())
    }

    async fn shutdown(mut self) {
        if let Some(handle) = self.handle.take() {
            let _ = handle.shutdown().await;
        }
    }
}

/// Whether two homes are the same place (within 0.5 m, 0.1 m in altitude).
fn same_home(a: Geodetic, b: Geodetic) -> bool {
    let origin = Origin {
        home: a,
        height_above_home_m: 0.0,
    };
    let d = origin.to_enu(b);
    d.x_east_m.hypot(d.y_north_m) < 0.5 && d.z_up_m.abs() < 0.1
}

/// Answers a command that cannot be served now.
fn refuse(command: Command, refusal: Refusal) {
    match command {
        Command::Upload(_, _, reply) => {
            let _ = reply.send(Err(refusal));
        }
        Command::Start(reply) => {
            let _ = reply.send(Err(refusal));
        }
    }
}

async fn run(
    cfg: VehicleConfig,
    model: Arc<VehicleModel>,
    catalog: CatalogRx,
    hub: Arc<Hub>,
    mut stop: watch::Receiver<bool>,
    mut commands: mpsc::Receiver<Command>,
    status: watch::Sender<LinkStatus>,
) {
    let (url, signing_key, mock) = match cfg.link.clone() {
        VehicleLink::Connect { url, signing_key } => (url, signing_key, None),
        VehicleLink::Mock { config, vehicle } => match BuiltinMock::spawn(*config, vehicle).await {
            Ok(mock) => (format!("udpout:{}", mock.addr), None, Some(mock)),
            Err(e) => {
                tracing::error!("the built-in mock autopilot did not start: {e}");
                let e = e.to_string();
                status.send_modify(|s| s.error = Some(e.clone()));
                loop {
                    tokio::select! {
                        _ = stop.changed() => return,
                        command = commands.recv() => match command {
                            Some(c) => refuse(c, Refusal::new(503, "connect", &e)),
                            None => return,
                        },
                    }
                }
            }
        },
    };
    // The session connects until it works; commands meanwhile are refused.
    let link = {
        let connecting = session::connect_until_open(&url, signing_key, |e| {
            tracing::warn!("{e}; trying again");
            status.send_modify(|s| s.error = Some(e.to_string()));
        });
        tokio::pin!(connecting);
        loop {
            tokio::select! {
                _ = stop.changed() => {
                    if let Some(mock) = mock { mock.shutdown().await; }
                    return;
                }
                command = commands.recv() => match command {
                    Some(c) => refuse(c, Refusal::new(503, "connect", &format!("not connected to {url} yet"))),
                    None => return,
                },
                link = &mut connecting => break link,
            }
        }
    };
    tracing::info!("link open on {url}");
    let recorder = spawn_recorder(&link, cfg.recorder.clone());
    let (heard, monitor) = heartbeats(&link);
    let forward = tokio::spawn(events::forward(
        hub.clone(),
        recorder.subscribe(),
        recorder.live(),
        status.subscribe(),
        stop.clone(),
    ));
    status.send_modify(|s| {
        s.state = LinkState::WaitingForHeartbeat;
        s.error = None;
    });
    let mut actor = Actor {
        url,
        link,
        recorder,
        mock,
        model,
        catalog,
        hub,
        status,
        heard,
        target: None,
        transfer_budget: cfg.transfer_budget,
        guard: cfg.guard,
        ledger: cfg.recorder.ledger.clone(),
        expected: None,
        mission_verified: false,
        started: None,
    };
    actor.serve(&mut stop, &mut commands).await;
    // Stopping: nothing more is asked of the vehicle; the flight log is finished and closed.
    commands.close();
    while let Ok(command) = commands.try_recv() {
        refuse(command, gone());
    }
    let Actor {
        recorder,
        mock,
        link,
        ..
    } = actor;
    recorder.close().await;
    monitor.abort();
    let _ = forward.await;
    drop(link);
    if let Some(mock) = mock {
        mock.shutdown().await;
    }
}

struct Actor {
    url: String,
    link: Link,
    recorder: RecorderHandle,
    mock: Option<BuiltinMock>,
    model: Arc<VehicleModel>,
    catalog: CatalogRx,
    hub: Arc<Hub>,
    status: watch::Sender<LinkStatus>,
    heard: watch::Receiver<Option<Heard>>,
    /// The autopilot, once heard.
    target: Option<Autopilot>,
    transfer_budget: Option<Duration>,
    guard: Policy,
    /// The ledger the recorder writes flights to, which a flight's pack is learned from.
    ledger: Option<crate::ledger::LedgerSpec>,
    /// The plan the service set for the next flight (its upload).
    expected: Option<FlightPlan>,
    /// The vehicle holds the mission this service last uploaded and read back, as far as the
    /// actor knows: set by a verified upload; cleared when an upload begins (a failed one
    /// leaves the vehicle's mission unknown), when the link is reopened or the heartbeat lost
    /// (the vehicle may have rebooted), and when the autopilot refuses a start.
    mission_verified: bool,
    /// When the service last armed the vehicle (true), or disarmed it again after a start the
    /// autopilot refused (false).
    started: Option<(Instant, bool)>,
}

impl Actor {
    async fn serve(
        &mut self,
        stop: &mut watch::Receiver<bool>,
        commands: &mut mpsc::Receiver<Command>,
    ) {
        let mut flights = self.recorder.subscribe();
        let mut reconnects = self.link.reconnects();
        let mut tick = tokio::time::interval(Duration::from_millis(500));
        loop {
            tokio::select! {
                _ = stop.changed() => return,
                command = commands.recv() => match command {
                    Some(Command::Upload(job, slot, reply)) => {
                        let span = job.span.clone();
                        let outcome = self.upload(*job).instrument(span).await;
                        // Free before the answer: a client told "verified" may upload again.
                        drop(slot);
                        let _ = reply.send(outcome);
                    }
                    Some(Command::Start(reply)) => {
                        let outcome = self.start().await;
                        let _ = reply.send(outcome);
                    }
                    None => return,
                },
                event = flights.recv() => match event {
                    Ok(FlightEvent::Started { flight, dir, resumed }) => {
                        let span = tracing::info_span!("flight", flight = %flight);
                        self.measure(&dir, resumed).instrument(span).await;
                    }
                    Ok(FlightEvent::Ended { .. }) => self.expected = None,
                    Ok(FlightEvent::Guard { note, .. }) if note.kind == NoteKind::Return => {
                        self.send_home().await;
                    }
                    Ok(_) | Err(broadcast::error::RecvError::Lagged(_)) => {}
                    Err(broadcast::error::RecvError::Closed) => return,
                },
                changed = reconnects.changed() => {
                    if changed.is_ok() {
                        let n = *reconnects.borrow_and_update();
                        self.status.send_modify(|s| s.reconnects = n);
                        self.mission_verified = false;
                        self.ask_streams().await;
                    }
                }
                changed = self.heard.changed() => {
                    if changed.is_ok() {
                        self.check_link().await;
                    }
                }
                _ = tick.tick() => self.check_link().await,
            }
        }
    }

    /// The energy guard decided: home now.
    async fn send_home(&mut self) {
        let Some(target) = self.target else {
            tracing::error!("the energy guard would send the vehicle home: no autopilot heard");
            return;
        };
        if let Err(e) = session::guard::send_home(&self.link, &target).await {
            tracing::error!("the energy guard could not send the vehicle home: {e}");
        }
    }

    /// Follows the heartbeat: the autopilot is found, lost, back.
    async fn check_link(&mut self) {
        let heard = *self.heard.borrow_and_update();
        let state = match heard {
            None => LinkState::WaitingForHeartbeat,
            Some(beat) if beat.at.elapsed() < HEARTBEAT_LOST => LinkState::Connected,
            Some(_) => LinkState::Lost,
        };
        if self.target.is_none() {
            if let Some(Heard { autopilot, .. }) = heard {
                tracing::info!(
                    "autopilot {} ({:?}) found on {}",
                    autopilot.system_id,
                    autopilot.flavour,
                    self.url
                );
                self.target = Some(autopilot);
                self.status.send_modify(|s| s.autopilot = Some(autopilot));
            }
        }
        let before = self.status.borrow().state;
        if state != before {
            self.status.send_modify(|s| s.state = state);
            match state {
                LinkState::Connected => {
                    tracing::info!("link to the autopilot up");
                    self.ask_streams().await;
                }
                LinkState::Lost => {
                    self.mission_verified = false;
                    tracing::warn!(
                        "no heartbeat from the autopilot for {} s",
                        HEARTBEAT_LOST.as_secs()
                    )
                }
                _ => {}
            }
        }
    }

    /// Asks for the telemetry the flight log needs (again after a reconnect or a reboot).
    async fn ask_streams(&mut self) {
        if let Some(target) = self.target {
            if let Err(e) = request_streams(&self.link, &target).await {
                tracing::warn!("telemetry rates not requested: {e}");
            }
        }
    }

    fn connected(&self) -> Result<Autopilot, Refusal> {
        let status = self.status.borrow();
        match (self.target, status.state) {
            (Some(target), LinkState::Connected) => Ok(target),
            (_, state) => Err(Refusal::new(
                503,
                "connect",
                &format!("the vehicle is not connected ({}: {state:?})", self.url),
            )),
        }
    }

    /// Whether the vehicle is armed: its last heartbeat says so, unless none has come since the
    /// service armed it or disarmed it again.
    fn armed(&self) -> bool {
        match (*self.heard.borrow(), self.started) {
            (Some(beat), Some((at, armed))) if beat.at <= at => armed,
            (Some(beat), _) => beat.armed,
            (None, _) => false,
        }
    }

    async fn upload(&mut self, mut job: UploadJob) -> Result<UploadAnswer, Refusal> {
        let mut target = self.connected()?;
        if self.armed() {
            tracing::warn!("upload refused: the vehicle is armed");
            return Err(Refusal::new(
                409,
                "vehicle",
                "the vehicle is armed: missions are not uploaded in flight (land and disarm first)",
            ));
        }
        // The built-in mock is moved to each mission's origin below: only a real vehicle is
        // somewhere else.
        if job.origin == Some(PlanOrigin::Vehicle) && self.mock.is_none() {
            self.rehome_job(&mut job, &target).await?;
        }
        let flight = job
            .choice
            .flight(&job.plan)
            .map_err(|e| Refusal::new(422, "plan", &e.to_string()))?;
        // From here the vehicle's mission may change, whatever the outcome.
        self.mission_verified = false;
        if let Some(mock) = self.mock.as_mut() {
            let home = job.mission.origin.home;
            if mock.home().is_some_and(|h| !same_home(h, home)) {
                tracing::info!(
                    "moving the built-in mock to the mission's home ({:.6}, {:.6})",
                    home.lat_deg,
                    home.lon_deg
                );
                let since = Instant::now();
                mock.move_home(home).await.map_err(|e| {
                    Refusal::new(
                        503,
                        "connect",
                        &format!("the built-in mock did not start again: {e}"),
                    )
                })?;
                target = self.wait_for_heartbeat(since).await?;
                self.ask_streams().await;
            }
        }
        let planned = upload_document(&job.plan, &flight);
        let pack = (job.pack.as_deref()).map(|name| PackUse {
            name: name.to_string(),
            source: PackSource::User,
            capacity_ratio: None,
        });
        let load = Load {
            mission: &job.mission,
            plan: &job.plan,
            flight: &flight,
            acceptance_radius_m: job.acceptance_radius_m,
            vehicle: &self.model.vehicle,
            resumes: None,
            guard: self.guard,
            if_home_unknown: session::IfHomeUnknown::asked(job.origin),
            live_wind: None,
            pack: pack.as_ref(),
            guard_start: None,
            ledger: self.ledger.as_ref(),
        };
        tracing::info!("uploading");
        let loaded = session::load(
            &self.link,
            &target,
            session::transfer_config(&target, self.transfer_budget),
            Some(&self.recorder),
            &load,
            |params| {
                if let Some(warning) = params.and_then(ParamCheck::warning) {
                    tracing::warn!("{warning}");
                }
            },
            |_, _| {},
        )
        .await
        .map_err(|e| {
            tracing::warn!("upload failed: {e}");
            let (stage, upload) = match &e {
                FlyError::Upload(u) => (u.stage.to_string(), Some(u)),
                other => (other.stage(), None),
            };
            let status = match e {
                FlyError::Items(_)
                | FlyError::Plan(_)
                | FlyError::Preflight(session::PreflightError::FarFromHome { .. }) => 422,
                _ => 502,
            };
            Refusal {
                status,
                doc: Failure::new(
                    &stage,
                    upload,
                    &match upload {
                        Some(_) => format!("uploading {} to {}: {e}", job.name, self.url),
                        None => e.to_string(),
                    },
                ),
            }
        })?;
        let report = loaded.upload;
        tracing::info!(
            upload_s = report.upload_s,
            verify_s = report.verify_s,
            "verified"
        );
        let link = LinkNumbers {
            rtt_ms: report.rtt_ms,
            restarts: report.restarts,
            refusals: report.refusals,
        };
        let measured_against = loaded.measured_against;
        self.expected = Some(measured_against);
        self.mission_verified = true;
        let answer = UploadAnswer {
            upload: UploadJson {
                plan: planned,
                autopilot: target,
                report,
                items: loaded.items.iter().map(item_json).collect(),
                fence: loaded.fence,
                rally: loaded.rally,
            },
            link,
            px4_parameters: (loaded.params.as_ref())
                .filter(|c| c.section == crate::session::ParamSection::Px4)
                .map(Px4Parameters::from),
        };
        Ok(answer)
    }

    /// `origin: "vehicle"`: `job`'s mission re-planned from `target`'s home by the session, as
    /// `job` was planned (its choice, its solver), off the vehicle's thread.
    async fn rehome_job(&self, job: &mut UploadJob, target: &Autopilot) -> Result<(), Refusal> {
        let (model, choice, solver) = (self.model.clone(), job.choice, job.solver);
        let replanned =
            session::replan_from_vehicle(&self.link, target, &job.mission, |mission, moved| {
                tracing::info!(
                    "origin moved to the vehicle's home, {:.0} m from the mission's",
                    moved.offset.horizontal_m
                );
                let planning = mission.clone();
                async move {
                    tokio::task::spawn_blocking(move || choice.plan(&planning, &model, solver))
                        .await
                        .map_err(|e| Refusal::new(500, "plan", &format!("planning stopped: {e}")))?
                        .map_err(|e| Refusal::new(422, "plan", &e.to_string()))
                }
            })
            .await
            .map_err(|e| match e {
                session::ReplanError::Home(e) => Refusal::new(502, e.stage(), &e.to_string()),
                session::ReplanError::Plan(refusal) => refusal,
            })?;
        job.mission = Arc::new(replanned.mission);
        job.plan = Arc::new(replanned.plan);
        Ok(())
    }

    /// Waits (up to 10 s) for the autopilot's heartbeat after `since`.
    async fn wait_for_heartbeat(&mut self, since: Instant) -> Result<Autopilot, Refusal> {
        let mut heard = self.heard.clone();
        let waited = tokio::time::timeout(Duration::from_secs(10), async {
            loop {
                if let Some(beat) = *heard.borrow_and_update() {
                    if beat.at > since {
                        return Some(beat.autopilot);
                    }
                }
                if heard.changed().await.is_err() {
                    return None;
                }
            }
        })
        .await;
        match waited {
            Ok(Some(autopilot)) => {
                self.check_link().await;
                Ok(autopilot)
            }
            _ => Err(Refusal::new(
                503,
                "connect",
                "no heartbeat from the built-in mock after it moved",
            )),
        }
    }

    async fn start(&mut self) -> Result<(), Refusal> {
        let target = self.connected()?;
        if self.armed() {
            return Err(Refusal::new(409, "vehicle", "the vehicle is already armed"));
        }
        let span = tracing::info_span!("start");
        let outcome = match self.mission_held(&target).instrument(span.clone()).await {
            Ok(()) => self.start_tracked(target, &span).await,
            Err(refusal) => Err(refusal),
        };
        span.in_scope(|| match &outcome {
            Ok(()) => tracing::info!("armed and started"),
            Err(r) => tracing::warn!("start failed: {}", r.message()),
        });
        self.hub.publish(&events::Event::Start {
            ok: outcome.is_ok(),
            error: outcome.as_ref().err().map(|r| r.message()),
        });
        outcome
    }

    /// Refuses a start (before anything is armed) unless the vehicle holds a mission: this
    /// service's verified upload, or one read back from the vehicle now.
    async fn mission_held(&mut self, target: &Autopilot) -> Result<(), Refusal> {
        if self.mission_verified {
            return Ok(());
        }
        let items = download(
            &self.link,
            target,
            session::transfer_config(target, self.transfer_budget),
        )
        .await
        .map_err(|e| {
            Refusal::new(
                502,
                "start",
                &format!("reading the vehicle's mission before arming failed: {e}"),
            )
        })?;
        let held = mission_len(&items, target.flavour);
        if held == 0 {
            return Err(Refusal::new(
                409,
                "vehicle",
                "no mission on the vehicle: upload one first (POST /api/missions/FILE/upload); \
                 nothing was armed",
            ));
        }
        tracing::info!(
            items = held,
            "starting the mission the vehicle holds (not this service's upload)"
        );
        Ok(())
    }

    /// The session's arm and start, and what the actor keeps of its outcome.
    async fn start_tracked(
        &mut self,
        target: Autopilot,
        span: &tracing::Span,
    ) -> Result<(), Refusal> {
        let started =
            session::arm_and_start(&self.link, &target, StartConfig::default(), &self.recorder)
                .instrument(span.clone())
                .await;
        match started {
            Ok(()) => {
                self.started = Some((Instant::now(), true));
                Ok(())
            }
            // The flight folder a refused start opened is removed on its own task (when it
            // was): the actor goes on serving.
            Err(session::StartFailed {
                error: FlyError::Start(e),
                ..
            }) => {
                // The autopilot did not take it: what it holds is read back next time.
                self.mission_verified = false;
                if let Some(disarmed) = e.disarmed() {
                    self.started = Some((Instant::now(), !disarmed));
                }
                Err(start_refusal(&e))
            }
            Err(session::StartFailed {
                error: FlyError::Link(e),
                ..
            }) => Err(Refusal::new(502, "start", &e.to_string())),
            Err(other) => Err(Refusal::new(502, "start", &other.error.to_string())),
        }
    }

    /// A flight started: what does the vehicle fly? Its mission read back is compared with the
    /// plan the recorder has (the service's upload, or the resumed flight's plan.json); when
    /// they differ, or there is none, the flight is measured against what the vehicle holds.
    async fn measure(&mut self, dir: &std::path::Path, resumed: bool) {
        let Some(target) = self.target else {
            return;
        };
        let current = if resumed {
            crate::flightlog::recorder::read_flight_plan(dir).ok()
        } else {
            self.expected.clone()
        };
        let catalog = self.catalog.borrow().clone();
        let missions: Vec<&Mission> = catalog.missions().collect();
        match session::held_flight_plan(
            &self.link,
            &target,
            session::transfer_config(&target, self.transfer_budget),
            Known::Among(&missions),
            &self.model,
        )
        .await
        {
            Ok(held) => match current.filter(|c| session::same_flight(c, &held)) {
                // Named after the upload: missions sharing a home read back alike.
                Some(current) => {
                    tracing::info!(
                        "flying the mission {} planned",
                        super::escape_controls(&current.mission)
                    )
                }
                None => {
                    tracing::info!(
                        points = held.points.len(),
                        "measuring against the mission the vehicle holds ({})",
                        super::escape_controls(&held.mission)
                    );
                    self.recorder.set_plan(held);
                }
            },
            Err(e) => tracing::warn!("{e}; recording the telemetry only"),
        }
    }
}

/// The refusal of a start the autopilot did not take: its answer in `result`.
fn start_refusal(e: &StartError) -> Refusal {
    let mut refusal = Refusal::new(502, "start", &e.to_string());
    if let Some(result) = e.result() {
        refusal.doc.result = Some(format!("{result:?}"));
    }
    refusal
}

/// The items of a mission `items` holds (ArduPilot's home at seq 0 is none).
fn mission_len(items: &[MISSION_ITEM_INT_DATA], flavour: Flavour) -> usize {
    items
        .iter()
        .filter(|i| !(flavour == Flavour::ArduPilot && i.seq == 0))
        .count()
}
