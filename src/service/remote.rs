//! Uploading and flying through a running service (`emplan upload/fly --service URL`): the
//! mission file named on the command line is found in the service's folder (same file name,
//! same bytes), the upload request carries the command line's choice, and `fly` follows the
//! event stream from before the start until its flight's report arrives. The answers are the
//! documents the commands print without a service.

use std::path::Path;
use std::time::Duration;

use serde::de::DeserializeOwned;

use super::client::{Answer, Client, ClientError, EventStream};
use super::missions::digest;
use super::wire::{
    Event, Failure, LinkState, LinkStatus, MissionState, MissionStatus, MissionsFolder,
    UploadAnswer, UploadRequest,
};
use crate::flightlog::report::{FlightReport, ReportJson};
use crate::session::FlyJson;

/// Why an upload or a flight through the service did not succeed.
#[derive(Debug, thiserror::Error)]
pub enum RemoteError {
    #[error(transparent)]
    Client(#[from] ClientError),
    /// The mission file given is not the service's.
    #[error("{0}")]
    Mission(String),
    /// The service refused or failed: its failure document.
    #[error("{}", .doc.error)]
    Refused { status: u16, doc: Failure },
    /// The service's link to the vehicle did not come up in time.
    #[error("the vehicle is not connected ({url}: {state:?}) after {seconds:.0} s")]
    NotConnected {
        url: String,
        state: LinkState,
        seconds: f64,
    },
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
            RemoteError::Refused { doc, .. } => doc.stage.clone(),
            RemoteError::NotConnected { .. } => "connect".into(),
            RemoteError::Timeout { .. }
            | RemoteError::NotFlown { .. }
            | RemoteError::NoReport { .. } => "flight".into(),
            RemoteError::Stopped { .. } => "record".into(),
        }
    }

    /// Whether the autopilot had accepted the mission.
    pub fn accepted(&self) -> bool {
        match self {
            RemoteError::Client(_) | RemoteError::Mission(_) | RemoteError::NotConnected { .. } => {
                false
            }
            RemoteError::Refused { doc, .. } => doc.accepted,
            _ => true,
        }
    }

    /// The upload failure document (`{"ok": false, "stage", "accepted", "error", "item",
    /// "result"}`): the service's own when it refused.
    pub fn document(&self) -> serde_json::Value {
        match self {
            RemoteError::Refused { doc, .. } => doc.json(),
            other => Failure {
                ok: false,
                stage: other.stage(),
                accepted: other.accepted(),
                error: other.to_string(),
                item: None,
                result: None,
            }
            .json(),
        }
    }
}

fn refused(answer: Answer) -> RemoteError {
    let doc = serde_json::from_value::<Failure>(answer.body.clone()).unwrap_or_else(|_| Failure {
        ok: false,
        stage: "service".into(),
        accepted: false,
        error: format!("HTTP {}: {}", answer.status, answer.body),
        item: None,
        result: None,
    });
    RemoteError::Refused {
        status: answer.status,
        doc,
    }
}

/// The body of a successful answer as `T`, or the refusal it is.
fn answered<T: DeserializeOwned>(
    client: &Client,
    what: &str,
    answer: Answer,
) -> Result<T, RemoteError> {
    if !answer.ok() {
        return Err(refused(answer));
    }
    serde_json::from_value(answer.body).map_err(|e| {
        RemoteError::Client(ClientError::Http {
            url: client.url().to_string(),
            what: what.to_string(),
            reason: e.to_string(),
        })
    })
}

/// Waits (up to `patience`) until the service's link to the vehicle is up: a service just
/// started is still connecting, as every command waits for its autopilot (`--discover-s`).
pub async fn wait_for_vehicle(
    client: &Client,
    patience: Duration,
) -> Result<LinkStatus, RemoteError> {
    let began = tokio::time::Instant::now();
    loop {
        let status: LinkStatus = answered(client, "GET /api/link", client.get("/api/link").await?)?;
        if status.state == LinkState::Connected {
            return Ok(status);
        }
        if began.elapsed() >= patience {
            return Err(RemoteError::NotConnected {
                url: status.url,
                state: status.state,
                seconds: began.elapsed().as_secs_f64(),
            });
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
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
            let dir = match client.get("/api/missions").await {
                Ok(a) => answered::<MissionsFolder>(client, "GET /api/missions", a)
                    .map(|f| f.dir.display().to_string())
                    .ok(),
                Err(_) => None,
            }
            .unwrap_or_else(|| "its missions folder".into());
            return Err(RemoteError::Mission(format!(
                "{name} is not in the service's missions folder {dir}: copy it there (the service plans what it finds there)"
            )));
        }
        let entry: MissionStatus = answered(client, "GET /api/missions/NAME", answer)?;
        if entry.digest != mine {
            if tokio::time::Instant::now() < deadline {
                // A copy just made may not be read yet.
                tokio::time::sleep(Duration::from_millis(200)).await;
                continue;
            }
            return Err(RemoteError::Mission(format!(
                "the service's {} differs from {}: copy yours into its missions folder",
                entry.file.display(),
                path.display()
            )));
        }
        match entry.status {
            MissionState::Planning | MissionState::Changing
                if tokio::time::Instant::now() < deadline =>
            {
                tokio::time::sleep(Duration::from_millis(200)).await;
            }
            MissionState::Error if entry.mission.is_none() => {
                let message = entry
                    .error
                    .map_or_else(|| "cannot be read".to_string(), |e| e.message);
                return Err(RemoteError::Mission(message));
            }
            _ => return Ok(name),
        }
    }
}

/// Uploads mission `name` of the service's folder; the upload answer or the service's failure
/// document.
pub async fn upload(
    client: &Client,
    name: &str,
    request: &UploadRequest,
) -> Result<UploadAnswer, RemoteError> {
    let body = serde_json::to_value(request).map_err(|e| ClientError::Http {
        url: client.url().to_string(),
        what: "upload request".into(),
        reason: e.to_string(),
    })?;
    let answer = client
        .post(&format!("/api/missions/{name}/upload"), &body)
        .await?;
    answered(client, "upload answer", answer)
}

/// A flight flown through the service.
#[derive(Debug, Clone)]
pub struct RemoteFlight {
    pub upload: UploadAnswer,
    pub flight: String,
    /// The flight directory (on the service's machine).
    pub dir: String,
    pub report: ReportJson,
}

impl RemoteFlight {
    /// Its report and the document `fly --service --json` prints: what `fly` prints of the
    /// same flight, the service's flight directory and PX4 parameter check included.
    pub fn reported(self) -> (FlightReport, FlyJson) {
        let report = FlightReport::from_json(&self.report);
        let doc = FlyJson::new(self.report, &self.dir, self.upload.px4_parameters);
        (report, doc)
    }
}

/// How a flight through the service starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Starting {
    /// The service arms the vehicle and starts the mission.
    Service,
    /// The pilot does.
    Pilot,
}

/// A flight asked of a service: the mission file (found in the service's folder by its bytes),
/// the upload request, whether to arm, how long to wait for the service's vehicle link, and
/// for the flight after the upload.
#[derive(Debug, Clone, Copy)]
pub struct FlyRequest<'a> {
    pub mission: &'a Path,
    pub upload: &'a UploadRequest,
    /// Arm and start (always, on the service's built-in mock: it has no pilot).
    pub arm: bool,
    pub discover: Duration,
    pub timeout: Duration,
}

/// Flies `asked` through the service: finds its mission file, waits for the vehicle link (within
/// `discover`), uploads it, starts it (or waits for the pilot), and waits until its flight has
/// landed and been reported, for at most `timeout` after the upload. `uploaded` sees the upload
/// answer at once, and who starts the flight; `on_event` sees every event of the stream after it
/// that concerns the flight.
pub async fn fly(
    client: &Client,
    asked: FlyRequest<'_>,
    uploaded: impl FnOnce(&UploadAnswer, Starting),
    mut on_event: impl FnMut(&Event),
) -> Result<RemoteFlight, RemoteError> {
    let name = find_mission(client, asked.mission, Duration::from_secs(60)).await?;
    let link = wait_for_vehicle(client, asked.discover).await?;
    let starting = match asked.arm || link.builtin_mock {
        true => Starting::Service,
        false => Starting::Pilot,
    };
    let timeout = asked.timeout;
    // Following the events from before the start: none of the flight's is missed.
    let mut events: EventStream = client.events().await?;
    let upload_answer = upload(client, &name, asked.upload).await?;
    uploaded(&upload_answer, starting);
    if starting == Starting::Service {
        let answer = client
            .post("/api/vehicle/start", &serde_json::json!({}))
            .await?;
        if !answer.ok() {
            let mut err = refused(answer);
            if let RemoteError::Refused { doc, .. } = &mut err {
                // The mission was accepted before the start failed.
                doc.accepted = true;
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
        let event: Event = match serde_json::from_value(event) {
            Ok(event) => event,
            Err(e) => {
                tracing::debug!("an event of the service not read: {e}");
                continue;
            }
        };
        let ours = |f: &str| flight.as_deref() == Some(f);
        match &event {
            Event::FlightStarted { flight: f, .. } if flight.is_none() => {
                flight = Some(f.clone());
                on_event(&event);
            }
            Event::FlightEnded {
                flight: f,
                dir,
                report,
            } if ours(f) => {
                on_event(&event);
                let dir = dir.display().to_string();
                let Some(report) = report.clone() else {
                    return Err(RemoteError::NoReport { dir });
                };
                if report.legs.is_empty() {
                    return Err(RemoteError::NotFlown {
                        duration_s: report.total.duration_s,
                        dir,
                    });
                }
                return Ok(RemoteFlight {
                    upload: upload_answer,
                    flight: f.clone(),
                    dir,
                    report,
                });
            }
            Event::Part(p) if ours(&p.flight) => on_event(&event),
            Event::RecordingFailed { flight: f, .. } if ours(f) => on_event(&event),
            _ => {}
        }
    }
}
