//! Uploading and flying through a running service (`emplan upload/fly --service URL`): the
//! mission file named on the command line is found in the service's folder (same file name,
//! same bytes), the upload request carries the command line's choice, and `fly` follows the
//! event stream from before the start until its flight's report arrives. The answers are the
//! documents the commands print without a service.

use std::path::Path;
use std::time::Duration;

use serde::Deserialize;

use super::client::{Client, ClientError, EventStream};
use super::missions::digest;
use crate::flightlog::report::{PartJson, PartReport, ReportJson};
use crate::flightlog::segment::SegmentKind;
use crate::physics::Profile;
use crate::planner::FlightChoice;
use crate::tour::solver;

/// Why an upload or a flight through the service did not succeed.
#[derive(Debug, thiserror::Error)]
pub enum RemoteError {
    #[error(transparent)]
    Client(#[from] ClientError),
    /// The mission file given is not the service's.
    #[error("{0}")]
    Mission(String),
    /// The service refused or failed: its failure document.
    #[error("{}", .doc.get("error").and_then(|e| e.as_str()).unwrap_or("refused by the service"))]
    Refused { status: u16, doc: serde_json::Value },
    #[error(
        "the flight did not end within {seconds:.0} s{}",
        .flight.as_ref().map(|f| format!(" (recorded so far in {f})")).unwrap_or_else(|| " (it never started: was it armed?)".into())
    )]
    Timeout {
        seconds: f64,
        flight: Option<String>,
    },
    #[error("the service stopped before the flight ended{}", .flight.as_ref().map(|f| format!(" (flight {f})")).unwrap_or_default())]
    Stopped { flight: Option<String> },
    #[error("the vehicle disarmed after {duration_s:.1} s without flying a leg of the mission (log in {dir})")]
    NotFlown { duration_s: f64, dir: String },
    #[error("the flight in {dir} has no report (nothing to measure it against)")]
    NoReport { dir: String },
}

impl RemoteError {
    /// The stage of the failure document.
    pub fn stage(&self) -> String {
        match self {
            RemoteError::Client(_) => "service".into(),
            RemoteError::Mission(_) => "mission".into(),
            RemoteError::Refused { doc, .. } => doc
                .get("stage")
                .and_then(|s| s.as_str())
                .unwrap_or("service")
                .to_string(),
            RemoteError::Timeout { .. }
            | RemoteError::NotFlown { .. }
            | RemoteError::NoReport { .. } => "flight".into(),
            RemoteError::Stopped { .. } => "record".into(),
        }
    }

    /// Whether the autopilot had accepted the mission.
    pub fn accepted(&self) -> bool {
        match self {
            RemoteError::Client(_) | RemoteError::Mission(_) => false,
            RemoteError::Refused { doc, .. } => doc
                .get("accepted")
                .and_then(|a| a.as_bool())
                .unwrap_or(false),
            _ => true,
        }
    }

    /// The upload failure document (`{"ok": false, "stage", "accepted", "error", "item",
    /// "result"}`): the service's own when it refused.
    pub fn document(&self) -> serde_json::Value {
        match self {
            RemoteError::Refused { doc, .. } => doc.clone(),
            other => serde_json::json!({
                "ok": false,
                "stage": other.stage(),
                "accepted": other.accepted(),
                "error": other.to_string(),
                "item": null,
                "result": null,
            }),
        }
    }
}

/// What to upload: the choice and the settings the command line would plan it with.
#[derive(Debug, Clone, PartialEq)]
pub struct UploadRequest {
    pub choice: FlightChoice,
    pub acceptance_radius_m: f32,
    /// Checked against the service's profile (None: the service's).
    pub profile: Option<Profile>,
    pub solver: solver::Options,
}

impl UploadRequest {
    /// The body of `POST /api/missions/{name}/upload`.
    pub fn body(&self) -> serde_json::Value {
        serde_json::json!({
            "order": self.choice.order,
            "sortie": self.choice.sortie,
            "allow_infeasible": self.choice.allow_infeasible,
            "acceptance_radius_m": self.acceptance_radius_m,
            "profile": self.profile.map(|p| p.to_string()),
            "solver": self.solver.solver.to_string(),
            "time_limit_s": self.solver.time_limit.as_secs_f64(),
            "seed": self.solver.seed,
            "kicks": self.solver.kicks,
        })
    }
}

fn refused(answer: super::client::Answer) -> RemoteError {
    let doc = if answer.body.get("ok").is_some() {
        answer.body
    } else {
        serde_json::json!({
            "ok": false, "stage": "service", "accepted": false,
            "error": format!("HTTP {}: {}", answer.status, answer.body), "item": null, "result": null,
        })
    };
    RemoteError::Refused {
        status: answer.status,
        doc,
    }
}

/// The service's name for the mission file at `path` (its file name), once the service has
/// read it: the same bytes (digest), not being planned any more (waiting up to `patience`).
pub async fn find_mission(
    client: &Client,
    path: &Path,
    patience: Duration,
) -> Result<String, RemoteError> {
    let bytes = std::fs::read(path)
        .map_err(|e| RemoteError::Mission(format!("{}: {e}", path.display())))?;
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| RemoteError::Mission(format!("{}: no file name", path.display())))?
        .to_string();
    let mine = digest(&bytes);
    let deadline = tokio::time::Instant::now() + patience;
    loop {
        let answer = client.get(&format!("/api/missions/{name}")).await?;
        if answer.status == 404 {
            let dir = client
                .get("/api/missions")
                .await
                .ok()
                .and_then(|a| a.body.get("dir").and_then(|d| d.as_str()).map(String::from))
                .unwrap_or_else(|| "its missions folder".into());
            return Err(RemoteError::Mission(format!(
                "{name} is not in the service's missions folder {dir}: copy it there (the service plans what it finds there)"
            )));
        }
        if !answer.ok() {
            return Err(refused(answer));
        }
        let entry = &answer.body;
        let theirs = entry.get("digest").and_then(|d| d.as_str()).unwrap_or("");
        let file = entry.get("file").and_then(|f| f.as_str()).unwrap_or(&name);
        let status = entry.get("status").and_then(|s| s.as_str()).unwrap_or("");
        if theirs != mine {
            if tokio::time::Instant::now() < deadline {
                // A copy just made may not be read yet.
                tokio::time::sleep(Duration::from_millis(200)).await;
                continue;
            }
            return Err(RemoteError::Mission(format!(
                "the service's {file} differs from {}: copy yours into its missions folder",
                path.display()
            )));
        }
        match status {
            "planning" | "changing" if tokio::time::Instant::now() < deadline => {
                tokio::time::sleep(Duration::from_millis(200)).await;
            }
            "error" if entry.get("mission").is_none_or(|m| m.is_null()) => {
                let message = entry
                    .pointer("/error/message")
                    .and_then(|m| m.as_str())
                    .unwrap_or("cannot be read");
                return Err(RemoteError::Mission(message.to_string()));
            }
            _ => return Ok(name),
        }
    }
}

/// Uploads mission `name` of the service's folder; the upload document (with `"link"`: round
/// trip, restarts, refusals) or the service's failure document.
pub async fn upload(
    client: &Client,
    name: &str,
    request: &UploadRequest,
) -> Result<serde_json::Value, RemoteError> {
    let answer = client
        .post(&format!("/api/missions/{name}/upload"), &request.body())
        .await?;
    if answer.ok() {
        Ok(answer.body)
    } else {
        Err(refused(answer))
    }
}

/// A part event of the stream, read back.
#[derive(Debug, Clone, Deserialize)]
struct PartEvent {
    kind: String,
    index: Option<usize>,
    #[serde(flatten)]
    part: PartJson,
}

/// The kind and the part of a `part` event.
pub fn part_of(event: &serde_json::Value) -> Option<(SegmentKind, PartReport)> {
    let p: PartEvent = serde_json::from_value(event.clone()).ok()?;
    let kind = match (p.kind.as_str(), p.index) {
        ("takeoff", _) => SegmentKind::Takeoff,
        ("landing", _) => SegmentKind::Landing,
        ("leg", Some(k)) => SegmentKind::Leg(k),
        ("settle", Some(k)) => SegmentKind::Settle(k),
        ("hover", Some(k)) => SegmentKind::Hover(k),
        _ => return None,
    };
    Some((kind, p.part.to_part()))
}

/// A flight flown through the service.
#[derive(Debug, Clone)]
pub struct RemoteFlight {
    /// The upload document.
    pub upload: serde_json::Value,
    pub flight: String,
    /// The flight directory (on the service's machine).
    pub dir: String,
    pub report: ReportJson,
}

/// How a flight through the service starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Starting {
    /// The service arms the vehicle and starts the mission.
    Service,
    /// The pilot does.
    Pilot,
}

fn text<'a>(event: &'a serde_json::Value, key: &str) -> Option<&'a str> {
    event.get(key).and_then(|v| v.as_str())
}

/// Uploads mission `name`, starts it (or waits for the pilot), and waits until its flight has
/// landed and been reported, for at most `timeout` after the upload. `uploaded` sees the upload
/// document at once; `on_event` sees every event of the stream after it.
pub async fn fly(
    client: &Client,
    name: &str,
    request: &UploadRequest,
    starting: Starting,
    timeout: Duration,
    uploaded: impl FnOnce(&serde_json::Value),
    mut on_event: impl FnMut(&serde_json::Value),
) -> Result<RemoteFlight, RemoteError> {
    // Following the events from before the start: none of the flight's is missed.
    let mut events: EventStream = client.events().await?;
    let upload_doc = upload(client, name, request).await?;
    uploaded(&upload_doc);
    if starting == Starting::Service {
        let answer = client
            .post("/api/vehicle/start", &serde_json::json!({}))
            .await?;
        if !answer.ok() {
            let mut err = refused(answer);
            if let RemoteError::Refused { doc, .. } = &mut err {
                // The mission was accepted before the start failed.
                doc["accepted"] = true.into();
            }
            return Err(err);
        }
    }
    let began = tokio::time::Instant::now();
    let mut flight: Option<String> = None;
    loop {
        let left = timeout.saturating_sub(began.elapsed());
        let event = match events.next_within(left).await {
            Err(_) => {
                return Err(RemoteError::Timeout {
                    seconds: began.elapsed().as_secs_f64(),
                    flight,
                })
            }
            Ok(None) => return Err(RemoteError::Stopped { flight }),
            Ok(Some(event)) => event?,
        };
        let kind = text(&event, "type").unwrap_or("");
        let ours = |f: &Option<String>| {
            text(&event, "flight").is_some() && f.as_deref() == text(&event, "flight")
        };
        match kind {
            "flight_started" if flight.is_none() => {
                flight = text(&event, "flight").map(String::from);
                on_event(&event);
            }
            "flight_ended" if ours(&flight) => {
                on_event(&event);
                let dir = text(&event, "dir").unwrap_or("").to_string();
                let report = match event.get("report") {
                    Some(r) if !r.is_null() => serde_json::from_value::<ReportJson>(r.clone())
                        .map_err(|e| {
                            RemoteError::Client(ClientError::Http {
                                url: client.url().to_string(),
                                what: "flight report".into(),
                                reason: e.to_string(),
                            })
                        })?,
                    _ => return Err(RemoteError::NoReport { dir }),
                };
                if report.legs.is_empty() {
                    return Err(RemoteError::NotFlown {
                        duration_s: report.total.duration_s,
                        dir,
                    });
                }
                return Ok(RemoteFlight {
                    upload: upload_doc,
                    flight: flight.unwrap_or_default(),
                    dir,
                    report,
                });
            }
            "part" | "recording_failed" if ours(&flight) => on_event(&event),
            _ => {}
        }
    }
}
