//! `emplan serve`: one long-running process that holds the vehicle link all day, plans every
//! mission file dropped into a folder, uploads on request, records every flight whoever started
//! it, and reports each flight's per-leg energy when it lands; a local HTTP API and a stream of
//! server-sent events for the command line (`upload`/`fly --service`) and a dashboard.
//!
//! Shape (mini-redis): [`run`] takes the listener and the shutdown signal, so tests run the real
//! service on `127.0.0.1:0`. Tasks: the vehicle actor (`vehicle`: owns the link, the autopilot,
//! the recorder, the built-in mock; uploads and starts go to it as `(command, oneshot)`), the
//! missions task (`missions`: owns the catalog, watches the folder, plans), the event forwarder
//! (`events`: recorder events and telemetry to the hub that feeds the event stream), and the
//! axum routes (`api`), thin over them, served by `http` (time limits on connections, the
//! `Host` check, the bound on plots and downloads at once). No lock is held across an await.
//! `wire` holds every request, answer and event the HTTP side sends or takes, shared by the
//! server and `client`, the HTTP client of `--service` (`remote`: upload and fly through a
//! service); `token` the bearer token; `ledger` the flights and packs of the ledger the API
//! serves (`GET /api/flights`, `GET /api/packs`), read on a blocking thread per request.
//!
//! Shutdown: the signal stops the HTTP server (no new requests; event streams end; requests in
//! progress finish), then the vehicle actor closes the flight log (an open flight's files are
//! finished, its report written and marked incomplete) and the built-in mock stops. A restart
//! while the vehicle still flies goes on recording into the same flight directory.

pub mod api;
pub mod client;
pub mod dashboard;
pub mod events;
pub mod http;
pub mod ledger;
pub mod missions;
pub mod remote;
pub mod token;
pub mod vehicle;
pub mod wire;

use std::borrow::Cow;
use std::future::Future;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use tokio::net::TcpListener;
use tokio::sync::watch;

pub use client::{Client, ClientError};
pub use token::Token;
pub use vehicle::VehicleLink;
pub use wire::{LinkState, LinkStatus};

use crate::physics::VehicleModel;
use crate::session::RecorderConfig;
use crate::tour::solver;

/// Why the service could not run.
#[derive(Debug, thiserror::Error)]
pub enum ServiceError {
    #[error("token file {file}: {reason}")]
    Token { file: String, reason: String },
    #[error("missions folder {dir}: {reason}")]
    Missions { dir: String, reason: String },
    #[error("log directory {dir}: {reason}")]
    LogDir { dir: String, reason: String },
    #[error("vehicle thread: {0}")]
    Thread(#[source] std::io::Error),
}

/// A request refused or failed: the HTTP status and the failure document (`{"ok": false,
/// "stage", "accepted", "error", "item", "result"}`, as `emplan upload --json` prints it).
#[derive(Debug, Clone)]
pub struct Refusal {
    pub status: u16,
    pub doc: wire::Failure,
}

impl Refusal {
    pub fn new(status: u16, stage: &str, error: &str) -> Refusal {
        Refusal {
            status,
            doc: wire::Failure::new(stage, None, error),
        }
    }

    /// The error message of the document.
    pub fn message(&self) -> String {
        self.doc.error.clone()
    }
}

/// Everything the service needs besides its listener and shutdown signal.
#[derive(Debug, Clone)]
pub struct ServiceConfig {
    /// How to reach the vehicle (a URL, or the built-in mock).
    pub vehicle: VehicleLink,
    /// The folder of mission files.
    pub missions_dir: PathBuf,
    /// Where flight directories are made.
    pub log_dir: PathBuf,
    /// The flight and battery ledger (`serve --ledger`; default `LOG_DIR/ledger.sqlite`).
    pub ledger: crate::ledger::LedgerSpec,
    /// What a request that changes the vehicle must carry.
    pub token: Token,
    /// The vehicle model (and profile) missions are planned and flights predicted with.
    pub model: Arc<VehicleModel>,
    pub solver: solver::Options,
    /// Time allowed for one transfer (None: the default for its item count).
    pub transfer_budget: Option<Duration>,
    /// Resume recording a flight cut off this recently (see `RecorderConfig::resume_within`).
    pub resume_within: Duration,
    /// What the energy guard may do in flight.
    pub guard: crate::flightlog::watch::Policy,
    /// How the missions folder is watched: the settle time, the plans run at once.
    pub watch: missions::WatchSettings,
    /// Limits of the HTTP side.
    pub http: HttpConfig,
}

/// Limits of the HTTP side, for a service that may be reachable beyond this machine.
#[derive(Debug, Clone)]
pub struct HttpConfig {
    /// Time a connection has to send a request's head, from its opening and again from the end
    /// of each response (so also how long a kept-alive connection may stay idle).
    pub header_timeout: Duration,
    /// Host names the service answers to besides IP addresses and `localhost` (see
    /// `http::HostCheck`).
    pub allowed_hosts: Vec<String>,
    /// Plots and file downloads served at once.
    pub heavy_requests: usize,
    /// How long a plot or download beyond those waits for one to finish before it is refused
    /// (503).
    pub heavy_wait: Duration,
}

impl Default for HttpConfig {
    fn default() -> HttpConfig {
        HttpConfig {
            header_timeout: Duration::from_secs(10),
            allowed_hosts: Vec::new(),
            heavy_requests: 2,
            heavy_wait: Duration::from_secs(5),
        }
    }
}

/// `text` with its control characters (C0, DEL, C1), line and paragraph separators and
/// bidirectional overrides written as escapes (`\n`, `\u{1b}`), for names from a file system or
/// a request written to the log: a name cannot forge a log line, move the cursor or colour a
/// terminal.
pub fn escape_controls(text: &str) -> Cow<'_, str> {
    let hidden = |c: char| {
        c.is_control()
            || matches!(c, '\u{2028}' | '\u{2029}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
    };
    if !text.chars().any(hidden) {
        return Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        if hidden(c) {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    Cow::Owned(out)
}

/// How long after its recording was cut off a flight is resumed by default: about a battery.
pub const DEFAULT_RESUME_WITHIN: Duration = Duration::from_secs(30 * 60);

/// Runs the service on `listener` until `shutdown` resolves; returns once the flight log is
/// closed.
pub async fn run(
    listener: TcpListener,
    cfg: ServiceConfig,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), ServiceError> {
    if !cfg.missions_dir.is_dir() {
        return Err(ServiceError::Missions {
            dir: cfg.missions_dir.display().to_string(),
            reason: "not a directory".into(),
        });
    }
    crate::flightlog::recorder::check_log_dir(&cfg.log_dir).map_err(|e| match e {
        crate::flightlog::FlightLogError::LogDir { dir, reason } => {
            ServiceError::LogDir { dir, reason }
        }
        other => ServiceError::LogDir {
            dir: cfg.log_dir.display().to_string(),
            reason: other.to_string(),
        },
    })?;
    // A flight cut off when the service last stopped (killed, the machine down) is measured
    // from its log before the recorder starts: it never stays without a report.
    let log_dir = cfg.log_dir.clone();
    let unfinished =
        tokio::task::spawn_blocking(move || crate::session::report_unfinished(&log_dir))
            .await
            .unwrap_or_default();
    for (dir, reported) in unfinished {
        match reported {
            Ok(report) => tracing::warn!(
                "flight {}: its recording stopped before its report was written; measured from its log ({})",
                escape_controls(&crate::flightlog::recorder::flight_name(&dir)),
                if report.complete { "complete" } else { "incomplete: the log ends in flight" }
            ),
            Err(e) => tracing::warn!(
                "flight {}: its recording stopped before its report was written, and it cannot be measured: {e}",
                escape_controls(&crate::flightlog::recorder::flight_name(&dir))
            ),
        }
    }
    let (http_stop_tx, http_stop) = watch::channel(false);
    let (stop_tx, stop) = watch::channel(false);
    let hub = Arc::new(events::Hub::new());
    let (catalog, missions_task) = missions::spawn(
        cfg.missions_dir.clone(),
        missions::PlanSettings {
            model: cfg.model.clone(),
            solver: cfg.solver,
            watch: cfg.watch,
        },
        hub.clone(),
        stop.clone(),
    );
    let (vehicle, vehicle_done) = vehicle::spawn(
        vehicle::VehicleConfig {
            link: cfg.vehicle.clone(),
            transfer_budget: cfg.transfer_budget,
            recorder: RecorderConfig {
                resume_within: Some(cfg.resume_within),
                ledger: Some(cfg.ledger.clone()),
                ..RecorderConfig::new(&cfg.log_dir)
            },
            guard: cfg.guard,
        },
        cfg.model.clone(),
        catalog.clone(),
        hub.clone(),
        stop.clone(),
    )
    .map_err(ServiceError::Thread)?;
    // No answer before the folder is read once: a mission file in it is never "not found".
    let _ = catalog.clone().wait_for(|c| c.scanned).await;
    let app = api::router(api::Shared {
        vehicle,
        catalog,
        hub,
        token: cfg.token.clone(),
        log_dir: cfg.log_dir.clone(),
        ledger: cfg.ledger.clone(),
        model: cfg.model.clone(),
        solver: cfg.solver,
        stop: http_stop,
        hosts: http::HostCheck::new(&cfg.http.allowed_hosts),
        heavy: http::Gate::new(cfg.http.heavy_requests, cfg.http.heavy_wait),
    });
    if let Ok(addr) = listener.local_addr() {
        tracing::info!(
            "serving on http://{addr}/api/ (missions in {}, flights in {}, ledger {})",
            cfg.missions_dir.display(),
            cfg.log_dir.display(),
            cfg.ledger
        );
    }
    http::serve(listener, app, cfg.http.header_timeout, async move {
        shutdown.await;
        tracing::info!("stopping: no new requests; closing the event streams");
        let _ = http_stop_tx.send(true);
    })
    .await;
    // Requests in progress have finished: the vehicle actor closes the flight log.
    let _ = stop_tx.send(true);
    let _ = vehicle_done.await;
    let _ = missions_task.await;
    tracing::info!("stopped; flight log closed");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn control_characters_in_a_name_are_escaped_and_other_text_kept() {
        assert!(matches!(
            escape_controls("sample 1 – été.toml"),
            Cow::Borrowed("sample 1 – été.toml")
        ));
        assert_eq!(
            escape_controls("a\nINFO forged\u{1b}[31mred\r\t\u{7f}\u{85}\u{202e}b"),
            "a\\nINFO forged\\u{1b}[31mred\\r\\t\\u{7f}\\u{85}\\u{202e}b"
        );
    }
}
