//! `emplan serve`: the field-day service (`emplan::service`): holds the vehicle link, plans
//! every mission file in `--missions`, records every flight into `--log-dir`, and answers the
//! HTTP API on `--http` (loopback by default). Prints the service's URL on stdout once it
//! listens; Ctrl-C or SIGTERM stop it cleanly (exit 0).

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::Context;
use emplan::service::{HttpConfig, ServiceConfig, Token, VehicleLink, DEFAULT_RESUME_WITHIN};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// MAVLink connection to the vehicle: udpin:HOST:PORT, udpout:HOST:PORT, tcpin:, tcpout:,
    /// serial:DEV:BAUD. Without it the built-in mock autopilot (PX4 flavour) flies on
    /// loopback, started at each uploaded mission's home
    #[arg(long)]
    connect: Option<String>,
    /// Folder of mission files (.toml, .plan, .waypoints): each is planned when it appears or
    /// changes
    #[arg(long)]
    missions: PathBuf,
    /// Directory the flight directories are made in
    #[arg(long, default_value = "flights")]
    log_dir: PathBuf,
    /// The flight and battery ledger: a SQLite file or a postgres:// URL (default:
    /// LOG_DIR/ledger.sqlite, made when the first flight lands)
    #[arg(long, value_name = "PATH|URL")]
    ledger: Option<String>,
    /// Address of the HTTP API (port 0: any free port; the URL is printed on stdout)
    #[arg(long, default_value = "127.0.0.1:8080")]
    http: std::net::SocketAddr,
    /// File holding the token that requests changing the vehicle must carry (created with a
    /// fresh random token, readable by its owner only, when absent; default: LOG_DIR/token)
    #[arg(long)]
    token_file: Option<PathBuf>,
    /// A host name the API answers to besides IP addresses and localhost (repeatable): a
    /// request naming another host is refused, so a web page cannot rebind its own name to
    /// this machine and read the API
    #[arg(long = "allow-host", value_name = "NAME")]
    allow_hosts: Vec<String>,
    #[command(flatten)]
    model: super::VehicleArgs,
    /// Plan and price every mission in a steady wind, SPEED@FROM_DEG (6@270: 6 m/s from the
    /// west); default still air
    #[arg(long, value_name = "SPEED@FROM_DEG", allow_hyphen_values = true)]
    wind: Option<emplan::physics::Wind>,
    #[command(flatten)]
    solver: super::SolverArgs,
    /// Time allowed for one transfer, upload and read-back (s; default: 30 s plus two of the
    /// autopilot's re-request periods per item)
    #[arg(long)]
    budget_s: Option<f64>,
    /// MAVLink 2 signing key file (32 raw bytes or 64 hex characters)
    #[arg(long)]
    signing_key: Option<PathBuf>,
    /// After a restart, go on recording a flight still in the air if its log was cut off at
    /// most this long ago (s)
    #[arg(long, default_value_t = DEFAULT_RESUME_WITHIN.as_secs_f64())]
    resume_within_s: f64,
    /// The energy guard in the service's flights: warn when the battery is projected to land
    /// below its reserve and at the point of no return (warn), and also send the vehicle home
    /// in time to keep the reserve (rtl), or nothing (off)
    #[arg(long, value_name = "POLICY", default_value = "warn")]
    guard: emplan::flightlog::watch::Policy,
    /// A mission file is planned once its size and modification time have stayed the same
    /// this long (ms); until then it is listed as changing
    #[arg(long, default_value_t = emplan::service::missions::DEFAULT_SETTLE.as_millis() as u64)]
    settle_ms: u64,
    /// Built-in mock only: simulated seconds per wall second
    #[arg(long, default_value_t = emplan::sim::DEFAULT_SPEEDUP)]
    speedup: f64,
    /// Built-in mock only: seed of its sensor noise
    #[arg(long, default_value_t = 1)]
    mock_seed: u64,
    /// Built-in mock only: a PX4 trajectory parameter the mock autopilot holds (and flies with)
    /// instead of the vehicle file's value, NAME=VALUE (e.g. MPC_XY_CRUISE=8); repeatable
    #[arg(long, value_name = "NAME=VALUE")]
    mock_param: Vec<String>,
    /// Built-in mock only: a vehicle directory whose physics and battery the mock flies (the
    /// truth measured against), instead of the planning vehicle's: the plans and the guard's
    /// projections use the planning vehicle, the mock flies this one
    #[arg(long, value_name = "DIR")]
    mock_vehicle: Option<PathBuf>,
}

/// Resolves on Ctrl-C or SIGTERM.
async fn stop_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{signal, SignalKind};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = tokio::signal::ctrl_c() => {}
                    _ = term.recv() => {}
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    use super::seconds;
    let transfer_budget = args.budget_s.map(|b| seconds("budget-s", b)).transpose()?;
    let resume_within = seconds("resume-within-s", args.resume_within_s)?;
    let model = args
        .model
        .model()?
        .with_wind(args.wind.unwrap_or(emplan::physics::Wind::CALM));
    let signing_key = match &args.signing_key {
        Some(path) => Some(emplan::link::read_signing_key(path)?),
        None => None,
    };
    if let Some(url) = &args.connect {
        // Its form only: the service waits for a serial device plugged in later.
        emplan::link::connection::parse_url(url).context("--connect")?;
    }
    let mock_params = (args.mock_param.iter())
        .map(|p| emplan::session::parse_param(p).map_err(|e| anyhow::anyhow!("--mock-param {e}")))
        .collect::<anyhow::Result<Vec<_>>>()?;
    if !mock_params.is_empty() && args.connect.is_some() {
        anyhow::bail!("--mock-param is for the built-in mock (no --connect)");
    }
    if args.mock_vehicle.is_some() && args.connect.is_some() {
        anyhow::bail!("--mock-vehicle is for the built-in mock (no --connect)");
    }
    let mut mock_vehicle = match &args.mock_vehicle {
        Some(dir) => emplan::physics::Vehicle::load(dir)
            .with_context(|| format!("--mock-vehicle {}", dir.display()))?,
        None => model.vehicle.clone(),
    };
    mock_vehicle.px4 = mock_vehicle.px4.with_autopilot_values(&mock_params);
    let vehicle = match &args.connect {
        Some(url) => VehicleLink::Connect {
            url: url.clone(),
            signing_key,
        },
        None => VehicleLink::Mock {
            config: Box::new(emplan::sim::MockConfig {
                flight: Some(emplan::sim::FlightConfig {
                    profile: Some(model.profile),
                    seed: args.mock_seed,
                    ..Default::default()
                }),
                speedup: args.speedup,
                seed: args.mock_seed,
                signing_key,
                ..Default::default()
            }),
            vehicle: Some(Box::new(mock_vehicle)),
        },
    };
    let token_file = args
        .token_file
        .clone()
        .unwrap_or_else(|| args.log_dir.join("token"));
    for name in &args.allow_hosts {
        let plain = !name.is_empty()
            && name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '.' | '_'));
        if !plain {
            anyhow::bail!("--allow-host {name:?}: expected a host name (letters, digits, '-', '.'), without a port");
        }
    }
    // A flight's directory holds that flight's files only: the token is never made there.
    if let Some(flight) = emplan::flightlog::recorder::flight_dir_holding(&token_file) {
        anyhow::bail!(
            "--token-file {}: inside the flight directory {}; refusing to keep the token there \
             (a flight's files are its record: give a file outside it)",
            token_file.display(),
            flight.display()
        );
    }
    let ledger = match &args.ledger {
        Some(text) => emplan::ledger::LedgerSpec::parse(text),
        None => emplan::ledger::LedgerSpec::Sqlite(args.log_dir.join("ledger.sqlite")),
    };
    if let emplan::ledger::LedgerSpec::Sqlite(path) = &ledger {
        if let Some(flight) = emplan::flightlog::recorder::flight_dir_holding(path) {
            anyhow::bail!(
                "--ledger {}: inside the flight directory {}; a flight's directory holds its own files only (give a file outside it)",
                path.display(),
                flight.display()
            );
        }
    }
    let (token, created) = Token::load_or_create(&token_file)?;
    for weakness in emplan::service::token::weaknesses(&token_file, &token) {
        tracing::warn!("{weakness}");
    }
    if !args.http.ip().is_loopback() {
        tracing::warn!(
            "the API listens on {} beyond this machine: reads need no token",
            args.http
        );
    }
    let cfg = ServiceConfig {
        vehicle,
        missions_dir: args.missions.clone(),
        log_dir: args.log_dir.clone(),
        ledger,
        token,
        model: Arc::new(model),
        solver: args.solver.options()?,
        transfer_budget,
        resume_within,
        guard: args.guard,
        watch: emplan::service::missions::WatchSettings {
            settle: std::time::Duration::from_millis(args.settle_ms),
            ..Default::default()
        },
        http: HttpConfig {
            allowed_hosts: args.allow_hosts.clone(),
            ..HttpConfig::default()
        },
    };
    // Several threads: HTTP clients and the link's tasks side by side (the recorder writes on
    // a thread of its own).
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind(args.http)
            .await
            .with_context(|| format!("--http {}", args.http))?;
        let addr = listener.local_addr()?;
        // `/api/` itself is no route (404): the API is named by one that answers.
        eprintln!(
            "emplan serve: dashboard on http://{addr}/ ; API on http://{addr}/api/vehicle (the rest in docs/service.md) ; missions from {} ; flights into {} ; token in {}{}; Ctrl-C stops",
            args.missions.display(),
            args.log_dir.display(),
            token_file.display(),
            if created { " (new)" } else { "" }
        );
        println!("http://{addr}");
        use std::io::Write;
        let _ = std::io::stdout().flush();
        emplan::service::run(listener, cfg, stop_signal()).await?;
        Ok(ExitCode::SUCCESS)
    })
}
