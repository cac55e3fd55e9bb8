//! The HTTP API under `/api/` (axum), thin over the service's tasks: reads come from the mission
//! catalog (a watch channel), the event hub and the flight directories; what changes the
//! vehicle goes to the vehicle actor and needs the bearer token; the ledger is read on a
//! blocking thread per request (`service::ledger`). `/` is the dashboard (see
//! `dashboard`: one page and its script and style, embedded in the binary).
//!
//! - `GET /api/missions`: `{"dir", "missions": [SUMMARY]}`; `GET /api/missions/{name}`: the
//!   summary with `origin`, `points` and `plan` (what `emplan plan --json` prints).
//! - `POST /api/missions/{name}/upload` (token): body `{"order", "sortie", "allow_infeasible",
//!   "acceptance_radius_m", "profile", "solver", "time_limit_s", "seed", "kicks"}` (all
//!   optional); answers `emplan upload --json`'s document plus `"link"`, or the failure
//!   document `{"ok": false, "stage", "accepted", "error", "item", "result"}`. Refused (409)
//!   when the file is changing or its bytes are not the ones planned (`missions::unchanged`),
//!   and while another upload is under way (`vehicle::UploadSlot`).
//! - `POST /api/vehicle/start` (token): arm and start the mission the vehicle holds (refused
//!   while an upload is under way).
//! - `GET /api/vehicle`, `GET /api/link`, `GET /api/battery?since_ms=`: link, vehicle and
//!   battery state, the flight in progress with its parts so far, the battery's last minutes.
//! - `GET /api/flights?vehicle=&pack=&mission=&since=&until=`, `GET /api/flights/{name}`,
//!   `GET /api/flights/{name}/report`, `GET /api/flights/{name}/files/{file}`: recorded flights
//!   (the flight directories, and the ledger's flights matching the query), their reports and
//!   files.
//! - `GET /api/packs`: every pack of the ledger's flights (`ledger::packs`), with the capacity
//!   each flight measured over its cycles.
//! - `GET /api/missions/{name}/plot.svg`, `GET /api/flights/{name}/plot.svg`: the figures of
//!   `emplan plan --plot` and `emplan report --plot` (`crate::plot`) as `image/svg+xml`.
//! - `GET /api/events`: server-sent events (see `events`).
//!
//! Every request is first checked for its `Host` (`http::check_host`: 421 for a name the service
//! does not answer to); plots and file downloads pass the gate that bounds them (503 when busy);
//! files are streamed from disk.

use std::convert::Infallible;
use std::path::{Path as FsPath, PathBuf};
use std::sync::Arc;

use axum::body::{Body, Bytes};
use axum::extract::{Path, Query, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use serde::Deserialize;
use tokio::sync::{broadcast, watch};

use super::events::Hub;
use super::http::{Gate, HostCheck};
use super::missions::CatalogRx;
use super::vehicle::{UploadJob, VehicleHandle};
use super::wire::{
    BatteryView, Event, FlightDetail, FlightFiles, FlightSummary, FlightsList, LinkStatus,
    MissionDetail, MissionsFolder, PacksView, UploadAnswer, UploadRequest, UploadResult,
    VehicleView,
};
use super::{escape_controls, Refusal, Token};
use crate::flightlog::recorder::{
    is_flight_dir, read_report, PLAN_FILE, REPORT_FILE, SAMPLES_FILE, TLOG_FILE,
};
use crate::flightlog::report::ReportJson;
use crate::ledger::{FlightQuery, FlightRecord, LedgerSpec};
use crate::physics::{Profile, VehicleModel};
use crate::planner::FlightChoice;
use crate::session::flight_dirs;
use crate::tour::solver;

/// What every handler reaches.
#[derive(Debug)]
pub struct Shared {
    pub vehicle: VehicleHandle,
    pub catalog: CatalogRx,
    pub hub: Arc<Hub>,
    pub token: Token,
    pub log_dir: PathBuf,
    pub ledger: LedgerSpec,
    pub model: Arc<VehicleModel>,
    pub solver: solver::Options,
    /// Turns true when the service stops (event streams end).
    pub stop: watch::Receiver<bool>,
    /// The hosts requests may name.
    pub hosts: HostCheck,
    /// Bounds the plots and file downloads served at once.
    pub heavy: Gate,
}

type AppState = Arc<Shared>;

/// The routes.
pub fn router(shared: Shared) -> Router {
    let hosts = shared.hosts.clone();
    Router::new()
        .route("/", get(super::dashboard::page))
        .route("/dashboard.js", get(super::dashboard::script))
        .route("/dashboard.css", get(super::dashboard::style))
        .route("/api/missions", get(missions))
        .route("/api/missions/{name}", get(mission))
        .route("/api/missions/{name}/plot.svg", get(mission_plot))
        .route("/api/missions/{name}/upload", post(upload))
        .route("/api/vehicle", get(vehicle))
        .route("/api/vehicle/start", post(start))
        .route("/api/link", get(link))
        .route("/api/battery", get(battery))
        .route("/api/flights", get(flights))
        .route("/api/packs", get(packs))
        .route("/api/flights/{name}", get(flight))
        .route("/api/flights/{name}/report", get(report))
        .route("/api/flights/{name}/plot.svg", get(flight_plot))
        .route("/api/flights/{name}/files/{file}", get(file))
        .route("/api/events", get(events))
        .route("/api/{*rest}", get(not_found).post(not_found))
        .fallback(not_found)
        .layer(axum::middleware::map_response(json_errors))
        .layer(axum::middleware::from_fn_with_state(
            hosts,
            super::http::check_host,
        ))
        .with_state(Arc::new(shared))
}

/// Every error answered as a JSON failure document: axum's own refusals (a path or query that
/// does not parse, a method not allowed, a body too large) are plain text; they get the
/// document with their text as the message.
async fn json_errors(response: Response) -> Response {
    let status = response.status();
    let is_json = response
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(b"application/json"));
    if !(status.is_client_error() || status.is_server_error()) || is_json {
        return response;
    }
    let text = match axum::body::to_bytes(response.into_body(), 64 * 1024).await {
        Ok(bytes) if !bytes.is_empty() => String::from_utf8_lossy(&bytes).trim().to_string(),
        _ => status
            .canonical_reason()
            .unwrap_or("request refused")
            .to_lowercase(),
    };
    Refusal::new(status.as_u16(), "request", &text).into_response()
}

impl IntoResponse for Refusal {
    fn into_response(self) -> Response {
        let status = StatusCode::from_u16(self.status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
        let mut response = (status, Json(self.doc.json())).into_response();
        if status == StatusCode::UNAUTHORIZED {
            response.headers_mut().insert(
                header::WWW_AUTHENTICATE,
                header::HeaderValue::from_static("Bearer"),
            );
        }
        if status == StatusCode::SERVICE_UNAVAILABLE {
            response
                .headers_mut()
                .insert(header::RETRY_AFTER, header::HeaderValue::from_static("2"));
        }
        response
    }
}

async fn not_found() -> Refusal {
    Refusal::new(
        404,
        "request",
        "no such endpoint (see docs/service.md: the API)",
    )
}

/// The credentials of an `Authorization: Bearer TOKEN` header; the scheme's name in any case
/// (RFC 7235 section 2.1), one or more spaces after it.
fn bearer(value: &str) -> Option<&str> {
    let (scheme, credentials) = value.trim().split_once(' ')?;
    scheme
        .eq_ignore_ascii_case("bearer")
        .then(|| credentials.trim_start_matches(' '))
}

/// Checks the bearer token of a request that changes the vehicle.
fn authorize(headers: &HeaderMap, token: &Token) -> Result<(), Refusal> {
    let offered = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(bearer);
    match offered {
        None => Err(Refusal::new(
            401,
            "auth",
            "this request changes the vehicle: it needs the service's token (Authorization: Bearer TOKEN)",
        )),
        Some(t) if token.matches(t.trim()) => Ok(()),
        Some(_) => {
            tracing::warn!("a request with a wrong token was refused");
            Err(Refusal::new(401, "auth", "wrong token"))
        }
    }
}

async fn missions(State(s): State<AppState>) -> Json<MissionsFolder> {
    let catalog = s.catalog.borrow().clone();
    Json(MissionsFolder {
        dir: catalog.dir.clone(),
        missions: catalog.entries.values().map(|e| e.summary()).collect(),
    })
}

fn unknown_mission(dir: &FsPath, name: &str) -> Refusal {
    Refusal::new(
        404,
        "mission",
        &format!(
            "no mission file {name:?} in the missions folder {}",
            dir.display()
        ),
    )
}

async fn mission(
    State(s): State<AppState>,
    Path(name): Path<String>,
) -> Result<Json<MissionDetail>, Refusal> {
    let catalog = s.catalog.borrow().clone();
    let entry = catalog
        .get(&name)
        .ok_or_else(|| unknown_mission(&catalog.dir, &name))?;
    Ok(Json(entry.detail()))
}

/// An SVG document as an answer.
fn svg(document: String) -> Response {
    (
        [
            (header::CONTENT_TYPE, "image/svg+xml; charset=utf-8"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        document,
    )
        .into_response()
}

/// The orders of a planned mission, drawn as `emplan plan --plot` draws them.
async fn mission_plot(
    State(s): State<AppState>,
    Path(name): Path<String>,
) -> Result<Response, Refusal> {
    let catalog = s.catalog.borrow().clone();
    let entry = catalog
        .get(&name)
        .ok_or_else(|| unknown_mission(&catalog.dir, &name))?
        .clone();
    let (Some(mission), super::missions::Outcome::Planned { plan, .. }) =
        (entry.mission.clone(), &entry.outcome)
    else {
        let message = match &entry.outcome {
            super::missions::Outcome::Failed(p) => format!("{name}: {}", p.message),
            _ => format!("{name} is not planned yet"),
        };
        return Err(Refusal::new(409, "plan", &message));
    };
    let plan = plan.clone();
    let _permit = s.heavy.enter("mission plot").await?;
    let drawn = tokio::task::spawn_blocking(move || crate::plot::plan_svg(&mission, &plan))
        .await
        .map_err(|e| Refusal::new(500, "plot", &format!("drawing stopped: {e}")))?
        .map_err(|e| Refusal::new(500, "plot", &e.to_string()))?;
    Ok(svg(drawn))
}

/// A recorded flight replayed from its .tlog and drawn as `emplan report --plot` draws it.
async fn flight_plot(
    State(s): State<AppState>,
    Path(name): Path<String>,
) -> Result<Response, Refusal> {
    let dir = flight_dir(&s.log_dir, &name).ok_or_else(|| unknown_flight(&s.log_dir, &name))?;
    let model = s.model.clone();
    // The replay holds the whole log's readings in memory: a few at a time.
    let permit = s.heavy.enter("flight plot").await?;
    let drawn = tokio::task::spawn_blocking(move || {
        let _permit = permit;
        let analysis = crate::session::replay(
            &dir.join(TLOG_FILE),
            None,
            Some(&model),
            crate::flightlog::segment::SegmentConfig::default(),
        )
        .map_err(|e| Refusal::new(422, "flight", &format!("replaying {name}: {e}")))?;
        crate::plot::flight_svg(std::slice::from_ref(&analysis))
            .map_err(|e| Refusal::new(500, "plot", &e.to_string()))
    })
    .await
    .map_err(|e| Refusal::new(500, "plot", &format!("drawing stopped: {e}")))??;
    Ok(svg(drawn))
}

fn bad_request(message: String) -> Refusal {
    Refusal::new(400, "request", &message)
}

/// The upload request of `body` (none: every default).
fn parse_upload(body: &[u8]) -> Result<UploadRequest, Refusal> {
    if body.iter().all(u8::is_ascii_whitespace) {
        return Ok(UploadRequest::default());
    }
    serde_json::from_slice(body).map_err(|e| {
        bad_request(format!(
            "upload request body, line {} column {}: {e}",
            e.line(),
            e.column()
        ))
    })
}

/// The solver options `request` asks for, from the service's `defaults`.
fn solver_of(
    request: &UploadRequest,
    defaults: solver::Options,
) -> Result<solver::Options, Refusal> {
    let mut options = defaults;
    if let Some(name) = &request.solver {
        options.solver = name
            .parse()
            .map_err(|e| bad_request(format!("solver {name:?}: {e}")))?;
    }
    if let Some(t) = request.time_limit_s {
        if !(t.is_finite() && t >= 0.0) {
            return Err(bad_request(format!(
                "time_limit_s {t}: expected a non-negative number of seconds"
            )));
        }
        options.time_limit = std::time::Duration::from_secs_f64(t.min(1e9));
    }
    if let Some(seed) = request.seed {
        options.seed = seed;
    }
    if request.kicks.is_some() {
        options.kicks = request.kicks;
    }
    Ok(options)
}

async fn upload(
    State(s): State<AppState>,
    Path(name): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Json<UploadAnswer>, Refusal> {
    authorize(&headers, &s.token)?;
    let request = parse_upload(&body)?;
    let span = tracing::info_span!(
        "upload",
        mission = %escape_controls(&name),
        order = ?request.order,
        sortie = request.sortie,
    );
    let outcome = upload_mission(&s, &name, request, span.clone()).await;
    span.in_scope(|| match &outcome {
        Ok(_) => tracing::info!("uploaded and verified"),
        Err(r) => tracing::warn!(
            status = r.status,
            "refused: {}",
            escape_controls(&r.message())
        ),
    });
    let (ok, result) = match &outcome {
        Ok(answer) => (true, UploadResult::Uploaded(answer.clone())),
        Err(r) => (false, UploadResult::Failed(r.doc.clone())),
    };
    s.hub.publish(&Event::Upload { name, ok, result });
    outcome.map(Json)
}

async fn upload_mission(
    s: &Shared,
    name: &str,
    request: UploadRequest,
    span: tracing::Span,
) -> Result<UploadAnswer, Refusal> {
    let catalog = s.catalog.borrow().clone();
    let entry = catalog
        .get(name)
        .ok_or_else(|| unknown_mission(&catalog.dir, name))?;
    // One upload at a time, from its planning to its verified read-back.
    let slot = s.vehicle.begin_upload(name)?;
    super::missions::unchanged(&catalog, entry).await?;
    let Some(mission) = entry.mission.clone() else {
        let message = match &entry.outcome {
            super::missions::Outcome::Failed(p) => p.message.clone(),
            _ => format!("{name} is not read yet"),
        };
        return Err(Refusal::new(422, "mission", &message));
    };
    if let Some(profile) = &request.profile {
        let asked: Profile = profile
            .parse()
            .map_err(|e| bad_request(format!("profile {profile:?}: {e}")))?;
        if asked != s.model.profile {
            return Err(Refusal::new(
                422,
                "plan",
                &format!(
                    "the service plans with profile {} (serve --profile), not {asked}",
                    s.model.profile
                ),
            ));
        }
    }
    let solver = solver_of(&request, s.solver)?;
    let acceptance_radius_m = request.acceptance_radius_m.unwrap_or(2.0);
    if !(acceptance_radius_m.is_finite()
        && acceptance_radius_m > 0.0
        && acceptance_radius_m <= 100.0)
    {
        return Err(bad_request(format!(
            "acceptance_radius_m {acceptance_radius_m}: expected a radius in (0, 100] m"
        )));
    }
    let pack = (request.pack.as_deref())
        .map(crate::session::ledger::pack_name)
        .transpose()
        .map_err(|e| bad_request(format!("pack: {e}")))?;
    let choice = FlightChoice {
        order: request.order,
        sortie: request.sortie,
        allow_infeasible: request.allow_infeasible,
    };
    let model = s.model.clone();
    let planning = mission.clone();
    let plan = tokio::task::spawn_blocking(move || choice.plan(&planning, &model, solver))
        .await
        .map_err(|e| Refusal::new(500, "plan", &format!("planning stopped: {e}")))?
        .map_err(|e| Refusal::new(422, "plan", &e.to_string()))?;
    if let Err(e) = choice.flight(&plan) {
        let hint = match e {
            crate::planner::PlannerError::OverBudget { .. } => {
                ": not uploaded (upload one sortie, or send \"allow_infeasible\": true to override)"
            }
            _ => "",
        };
        return Err(Refusal::new(422, "plan", &format!("{e}{hint}")));
    }
    s.vehicle
        .upload(
            UploadJob {
                name: name.to_string(),
                mission,
                plan: Arc::new(plan),
                choice,
                acceptance_radius_m,
                origin: request.origin,
                solver,
                span,
                pack,
            },
            slot,
        )
        .await
}

async fn start(
    State(s): State<AppState>,
    headers: HeaderMap,
) -> Result<Json<super::wire::Started>, Refusal> {
    authorize(&headers, &s.token)?;
    s.vehicle.start().await?;
    Ok(Json(super::wire::Started { ok: true }))
}

async fn vehicle(State(s): State<AppState>) -> Json<VehicleView> {
    Json(VehicleView {
        link: s.vehicle.status(),
        telemetry: s.hub.telemetry(),
        flight: s.hub.flight(),
    })
}

async fn link(State(s): State<AppState>) -> Json<LinkStatus> {
    Json(s.vehicle.status())
}

#[derive(Debug, Deserialize)]
struct Since {
    since_ms: Option<u64>,
}

async fn battery(State(s): State<AppState>, Query(q): Query<Since>) -> Json<BatteryView> {
    Json(BatteryView {
        now: s.hub.telemetry().and_then(|t| t.battery),
        history: s.hub.battery_history(q.since_ms),
    })
}

/// The flight directory `name` under `log_dir`, if it is one (a plain name holding a .tlog).
pub fn flight_dir(log_dir: &FsPath, name: &str) -> Option<PathBuf> {
    let plain =
        !name.is_empty() && !name.starts_with('.') && !name.contains(['/', '\\']) && name != "..";
    let dir = log_dir.join(name);
    (plain && is_flight_dir(&dir)).then_some(dir)
}

/// The files of a flight directory that exist, as API paths.
fn files(dir: &FsPath, name: &str) -> FlightFiles {
    let path = |file: &str| {
        dir.join(file)
            .is_file()
            .then(|| format!("/api/flights/{name}/files/{file}"))
    };
    FlightFiles {
        tlog: path(TLOG_FILE),
        samples: path(SAMPLES_FILE),
        plan: path(PLAN_FILE),
        report: path(REPORT_FILE),
    }
}

fn flight_summary(dir: &FsPath, recording: Option<&str>) -> FlightSummary {
    let name = crate::flightlog::recorder::flight_name(dir);
    let report = read_report(dir).ok().map(|r| r.json());
    FlightSummary {
        recording: recording == Some(name.as_str()),
        complete: report.as_ref().map(|r| r.complete),
        total: report.as_ref().map(|r| r.total.clone()),
        legs: report.as_ref().map(|r| r.legs.len()),
        files: files(dir, &name),
        name,
    }
}

fn recording(hub: &Hub) -> Option<String> {
    hub.flight().filter(|f| f.recording).map(|f| f.flight)
}

/// The query of `GET /api/flights`: which of the ledger's flights (an empty field: any).
#[derive(Debug, Default, Deserialize)]
struct LedgerQuery {
    vehicle: Option<String>,
    pack: Option<String>,
    mission: Option<String>,
    since: Option<String>,
    until: Option<String>,
}

impl LedgerQuery {
    /// The ledger's query, its dates checked.
    fn query(self) -> Result<FlightQuery, Refusal> {
        let given = |v: Option<String>| v.filter(|v| !v.trim().is_empty());
        let (since, until) = (given(self.since), given(self.until));
        for (field, value) in [("since", &since), ("until", &until)] {
            if let Some(problem) = value
                .as_deref()
                .and_then(|v| super::ledger::check_date(field, v))
            {
                return Err(bad_request(escape_controls(&problem).into_owned()));
            }
        }
        Ok(FlightQuery {
            vehicle: given(self.vehicle),
            pack: given(self.pack),
            mission: given(self.mission),
            since,
            until,
        })
    }
}

/// The ledger's flights matching `query`, oldest first, read on a blocking thread; the inner
/// error says why the ledger cannot be read, the outer refuses the query.
async fn ledger_flights(
    s: &Shared,
    query: FlightQuery,
) -> Result<Result<Vec<FlightRecord>, String>, Refusal> {
    let spec = s.ledger.clone();
    let read = tokio::task::spawn_blocking(move || super::ledger::flights(&spec, &query)).await;
    Ok(match read {
        Ok(Ok(records)) => Ok(records),
        Ok(Err(e @ crate::ledger::LedgerError::Query { .. })) => {
            return Err(bad_request(escape_controls(&e.to_string()).into_owned()))
        }
        Ok(Err(e)) => Err(e.to_string()),
        Err(e) => Err(format!("reading the ledger stopped: {e}")),
    })
}

async fn flights(
    State(s): State<AppState>,
    query: Result<Query<LedgerQuery>, axum::extract::rejection::QueryRejection>,
) -> Result<Json<FlightsList>, Refusal> {
    let Query(query) = query.map_err(|e| bad_request(format!("the flights' query: {e}")))?;
    let query = query.query()?;
    let log_dir = s.log_dir.clone();
    let now = recording(&s.hub);
    let list = tokio::task::spawn_blocking(move || -> std::io::Result<Vec<FlightSummary>> {
        let dirs = match flight_dirs(&log_dir) {
            Ok(d) => d,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
            Err(e) => return Err(e),
        };
        // Newest first.
        Ok(dirs
            .iter()
            .rev()
            .map(|d| flight_summary(d, now.as_deref()))
            .collect())
    })
    .await
    .map_err(|e| Refusal::new(500, "service", &e.to_string()))?
    .map_err(|e| {
        Refusal::new(
            500,
            "service",
            &format!("log directory {}: {e}", s.log_dir.display()),
        )
    })?;
    // The flight directories are the flights' own record: a ledger that cannot be read is said,
    // the directories listed all the same.
    let (records, ledger_error) = match ledger_flights(&s, query).await? {
        Ok(mut records) => {
            records.reverse();
            (records, None)
        }
        Err(e) => {
            tracing::warn!("listing the ledger's flights: {}", escape_controls(&e));
            (Vec::new(), Some(e))
        }
    };
    Ok(Json(FlightsList {
        dir: s.log_dir.clone(),
        flights: list,
        ledger: s.ledger.to_string(),
        records,
        ledger_error,
    }))
}

/// Every pack of the ledger's flights, summed up by `ledger::packs`.
async fn packs(State(s): State<AppState>) -> Result<Json<PacksView>, Refusal> {
    let spec = s.ledger.clone();
    let ledger = spec.to_string();
    let (exists, packs) = tokio::task::spawn_blocking(move || {
        let records = super::ledger::flights(&spec, &FlightQuery::default())?;
        Ok::<_, crate::ledger::LedgerError>((
            super::ledger::exists(&spec),
            super::ledger::pack_views(&records),
        ))
    })
    .await
    .map_err(|e| Refusal::new(500, "ledger", &format!("reading the ledger stopped: {e}")))?
    .map_err(|e| Refusal::new(500, "ledger", &e.to_string()))?;
    Ok(Json(PacksView {
        ledger,
        exists,
        packs,
    }))
}

fn unknown_flight(log_dir: &FsPath, name: &str) -> Refusal {
    Refusal::new(
        404,
        "flight",
        &format!("no flight {name:?} under {}", log_dir.display()),
    )
}

async fn flight(
    State(s): State<AppState>,
    Path(name): Path<String>,
) -> Result<Json<FlightDetail>, Refusal> {
    let dir = flight_dir(&s.log_dir, &name).ok_or_else(|| unknown_flight(&s.log_dir, &name))?;
    let now = recording(&s.hub);
    let live = if now.as_deref() == Some(name.as_str()) {
        s.hub.flight()
    } else {
        None
    };
    Ok(Json(FlightDetail {
        summary: flight_summary(&dir, now.as_deref()),
        mission: crate::flightlog::recorder::read_flight_plan(&dir)
            .ok()
            .map(|p| p.mission),
        report: read_report(&dir).ok().map(|r| r.json()),
        dir,
        live,
    }))
}

async fn report(
    State(s): State<AppState>,
    Path(name): Path<String>,
) -> Result<Json<ReportJson>, Refusal> {
    let dir = flight_dir(&s.log_dir, &name).ok_or_else(|| unknown_flight(&s.log_dir, &name))?;
    let report = read_report(&dir).map_err(|e| {
        Refusal::new(
            404,
            "flight",
            &format!("flight {name} has no report yet ({e})"),
        )
    })?;
    Ok(Json(report.json()))
}

async fn file(
    State(s): State<AppState>,
    Path((name, file)): Path<(String, String)>,
) -> Result<Response, Refusal> {
    let dir = flight_dir(&s.log_dir, &name).ok_or_else(|| unknown_flight(&s.log_dir, &name))?;
    let content_type = match file.as_str() {
        TLOG_FILE => "application/octet-stream",
        SAMPLES_FILE => "text/csv",
        PLAN_FILE | REPORT_FILE => "application/json",
        _ => {
            return Err(Refusal::new(
                404,
                "flight",
                &format!(
                    "{file:?} is not a flight file ({TLOG_FILE}, {SAMPLES_FILE}, {PLAN_FILE}, {REPORT_FILE})"
                ),
            ))
        }
    };
    let permit = s.heavy.enter("file download").await?;
    let (body, length) = stream_file(&dir.join(&file), permit)
        .await
        .map_err(|e| Refusal::new(404, "flight", &format!("{name}/{file}: {e}")))?;
    let disposition = format!("attachment; filename=\"{name}-{file}\"");
    Ok((
        [
            (header::CONTENT_TYPE, content_type.to_string()),
            (header::CONTENT_DISPOSITION, disposition),
            (header::CONTENT_LENGTH, length.to_string()),
        ],
        body,
    )
        .into_response())
}

/// A file as a body read in chunks as it is sent (a log may be hundreds of megabytes), with its
/// length when opened: a log still being written is sent as it was then. `permit` is held until
/// the body is sent or dropped.
async fn stream_file(
    path: &FsPath,
    permit: tokio::sync::OwnedSemaphorePermit,
) -> std::io::Result<(Body, u64)> {
    use tokio::io::AsyncReadExt;
    const CHUNK_BYTES: usize = 64 * 1024;
    let file = tokio::fs::File::open(path).await?;
    let length = file.metadata().await?.len();
    let reader = file.take(length);
    let chunks = futures_util::stream::unfold(Some((reader, permit)), |state| async move {
        let (mut reader, permit) = state?;
        let mut chunk = vec![0u8; CHUNK_BYTES];
        match reader.read(&mut chunk).await {
            Ok(0) => None,
            Ok(n) => {
                chunk.truncate(n);
                Some((Ok(Bytes::from(chunk)), Some((reader, permit))))
            }
            Err(e) => Some((Err(e), None)),
        }
    });
    Ok((Body::from_stream(chunks), length))
}

async fn events(State(s): State<AppState>) -> Response {
    let rx = s.hub.subscribe();
    let stop = s.stop.clone();
    if *stop.borrow() {
        return Refusal::new(503, "service", "the service is stopping").into_response();
    }
    let stream = futures_util::stream::unfold((rx, stop), |(mut rx, mut stop)| async move {
        let event = tokio::select! {
            _ = stop.changed() => return None,
            received = rx.recv() => match received {
                Ok(text) => SseEvent::default().data(&*text),
                Err(broadcast::error::RecvError::Lagged(missed)) => {
                    let lagged = serde_json::to_string(&Event::Lagged { missed }).unwrap_or_default();
                    SseEvent::default().data(lagged)
                }
                Err(broadcast::error::RecvError::Closed) => return None,
            },
        };
        Some((Ok::<_, Infallible>(event), (rx, stop)))
    });
    // A subscriber learns the link's state at once, not only at its next change.
    let now = serde_json::to_string(&Event::Link(s.vehicle.status())).unwrap_or_default();
    let now =
        futures_util::stream::once(
            async move { Ok::<_, Infallible>(SseEvent::default().data(now)) },
        );
    Sse::new(futures_util::StreamExt::chain(now, stream))
        .keep_alive(KeepAlive::default())
        .into_response()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bearer_scheme_is_read_in_any_case_with_any_spaces() {
        for value in [
            "Bearer abc",
            "bearer abc",
            "BEARER abc",
            "bEaReR   abc",
            " Bearer abc ",
        ] {
            assert_eq!(bearer(value), Some("abc"), "{value:?}");
        }
        for value in ["Basic abc", "Bearerabc", "Bearer", "abc", "Bear abc"] {
            assert_eq!(bearer(value), None, "{value:?}");
        }
    }
}
