//! `emplan fly`: plan, battery check, verified upload, start (arming only with `--arm`; the
//! built-in mock has no pilot, so without `--connect` emplan starts it), record until landed,
//! and print the per-leg energy report. Without `--connect` the built-in mock autopilot flies
//! the mission in simulated time with the vehicle's physics.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;

use emplan::flightlog::segment::SegmentKind;
use emplan::link::Flavour;
use emplan::physics::Profile;
use emplan::session::{
    check_px4_params, fly, spawn_recorder, FlightEvent, FlyError, FlyOptions, ParamCheck,
    RecorderConfig,
};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Mission file: emplan .toml, QGroundControl .plan or .waypoints
    mission: PathBuf,
    #[command(flatten)]
    link: super::LinkArgs,
    #[command(flatten)]
    flight: super::FlightArgs,
    #[command(flatten)]
    service: super::ServiceArgs,
    /// Directory the flight's log directory is made in
    #[arg(long, default_value = "flights")]
    log_dir: PathBuf,
    /// Arm the vehicle and start the mission (PX4: arm, MISSION_START; ArduPilot: GUIDED, arm,
    /// AUTO, MISSION_START). Without it emplan uploads and waits for the pilot to start the
    /// mission (the built-in mock is always started: it has no pilot)
    #[arg(long)]
    arm: bool,
    /// Give up when the flight has not landed this long after the upload (s)
    #[arg(long, default_value_t = 3600.0)]
    timeout_s: f64,
    /// Built-in mock only: simulated seconds per wall second
    #[arg(long, default_value_t = emplan::sim::DEFAULT_SPEEDUP)]
    speedup: f64,
    /// Built-in mock only: probability that a datagram is lost, each way (telemetry and
    /// mission protocol alike)
    #[arg(long, default_value_t = 0.0)]
    mock_loss: f64,
    /// Built-in mock only: seed of its faults and sensor noise
    #[arg(long, default_value_t = 1)]
    mock_seed: u64,
    /// Built-in mock only: a PX4 trajectory parameter the mock autopilot holds (and flies with)
    /// instead of the vehicle file's value, NAME=VALUE (e.g. MPC_XY_CRUISE=8); repeatable
    #[arg(long, value_name = "NAME=VALUE")]
    mock_param: Vec<String>,
    /// Built-in mock only: a vehicle directory whose physics and battery the mock flies (the
    /// truth measured against), instead of the planning vehicle's: flights of a vehicle that
    /// is not what the vehicle file says, for `calibrate --from-logs`
    #[arg(long, value_name = "DIR")]
    mock_vehicle: Option<PathBuf>,
    /// Print one JSON document (the report) instead of text
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let json = args.json;
    match fly_mission(args) {
        Err(err) if json => {
            let remote = err.downcast_ref::<emplan::service::remote::RemoteError>();
            let (stage, accepted) = match err.downcast_ref::<FlyError>() {
                Some(FlyError::Upload(e)) => (e.stage.to_string(), e.accepted),
                Some(e) => (
                    e.stage(),
                    matches!(
                        e,
                        FlyError::Start(_)
                            | FlyError::Timeout { .. }
                            | FlyError::Recorder(_)
                            | FlyError::NotFlown { .. }
                    ),
                ),
                None => match remote {
                    Some(r) => (r.stage(), r.accepted()),
                    None if err.downcast_ref::<emplan::service::ClientError>().is_some() => {
                        ("service".to_string(), false)
                    }
                    None if err.downcast_ref::<emplan::link::LinkError>().is_some() => {
                        ("connect".to_string(), false)
                    }
                    None => ("plan".to_string(), false),
                },
            };
            let doc = serde_json::json!({
                "ok": false,
                "stage": stage,
                "accepted": accepted,
                "error": format!("{err:#}"),
            });
            println!("{}", serde_json::to_string_pretty(&doc)?);
            eprintln!("error: {err:#}");
            Ok(ExitCode::FAILURE)
        }
        outcome => outcome,
    }
}

fn fly_mission(args: Args) -> anyhow::Result<ExitCode> {
    if !(0.0..=1.0).contains(&args.mock_loss) {
        anyhow::bail!(
            "--mock-loss {}: a probability between 0 and 1 is required",
            args.mock_loss
        );
    }
    if !(args.timeout_s.is_finite() && args.timeout_s > 0.0) {
        anyhow::bail!(
            "--timeout-s {}: a positive number of seconds is required",
            args.timeout_s
        );
    }
    if let Some(client) = args.service.client()? {
        if args.mock_vehicle.is_some() {
            anyhow::bail!("--mock-vehicle is for the built-in mock (not --service)");
        }
        return fly_through(&args, &client);
    }
    // A flight log that cannot be written ends the command before anything is uploaded.
    emplan::flightlog::recorder::check_log_dir(&args.log_dir).map_err(FlyError::LogDir)?;
    let mission = emplan::mission::load(&args.mission)?;
    let (model, plan) = args.flight.plan(&mission)?;
    let flight = args.flight.flight(&plan)?;
    let builtin = args.link.connect.is_none();
    let mock = emplan::sim::MockConfig {
        flight: Some(emplan::sim::FlightConfig {
            profile: Some(plan.profile),
            home: mission.origin.home,
            seed: args.mock_seed,
            ..Default::default()
        }),
        speedup: args.speedup,
        seed: args.mock_seed,
        faults: emplan::sim::Faults {
            loss_up: args.mock_loss,
            loss_down: args.mock_loss,
            ..Default::default()
        },
        ..Default::default()
    };
    let mock_params = parse_params(&args.mock_param)?;
    if !mock_params.is_empty() && !builtin {
        anyhow::bail!("--mock-param is for the built-in mock (no --connect)");
    }
    if args.mock_vehicle.is_some() && !builtin {
        anyhow::bail!("--mock-vehicle is for the built-in mock (no --connect)");
    }
    let mut mock_vehicle = match &args.mock_vehicle {
        Some(dir) => emplan::physics::Vehicle::load(dir)
            .with_context(|| format!("--mock-vehicle {}", dir.display()))?,
        None => model.vehicle.clone(),
    };
    mock_vehicle.px4 = mock_vehicle.px4.with_autopilot_values(&mock_params);
    let live_lines = super::progress::shown();
    let quiet = args.json;
    super::runtime()?.block_on(async {
        let opened = args.link.open_with(mock, Some(mock_vehicle)).await?;
        // PX4 flies the px4 profile with its own parameters: read them, say which differ from
        // the vehicle file, and measure against the legs as the autopilot will fly them.
        let params = if opened.target.flavour == Flavour::Px4 && plan.profile == Profile::Px4 {
            let check = check_px4_params(&opened.link, &opened.target, &model.vehicle).await?;
            warn_params(&check);
            Some(check)
        } else {
            None
        };
        let recorder = spawn_recorder(&opened.link, RecorderConfig::new(&args.log_dir));
        if !quiet {
            eprintln!(
                "flying {} ({} legs, {:.1} kJ predicted) on {:?} autopilot {} at {}; logging to {}",
                mission.name,
                flight.legs.len(),
                flight.battery.total_j / 1000.0,
                opened.target.flavour,
                opened.target.system_id,
                opened.describe,
                args.log_dir.display()
            );
            if !args.arm && !builtin {
                eprintln!("uploaded missions are started by the pilot: waiting for arming (or pass --arm)");
            }
        }
        let opts = FlyOptions {
            arm: args.arm || builtin,
            acceptance_radius_m: args.flight.acceptance_radius_m,
            timeout: std::time::Duration::from_secs_f64(args.timeout_s),
            priced_with: params
                .as_ref()
                .filter(|c| !c.differences.is_empty())
                .map(|c| c.vehicle.clone()),
            ..FlyOptions::default()
        };
        // On a terminal: the part in progress on a line of its own, rewritten twice a second.
        let ticker = live_lines.then(|| tokio::spawn(progress_line(recorder.live())));
        let clear = if live_lines { "\r\x1b[2K" } else { "" };
        let on_event = |event: &FlightEvent| {
            if quiet && !live_lines {
                return;
            }
            match event {
                FlightEvent::Started { dir, .. } => {
                    eprintln!("{clear}armed: recording to {}", dir.display())
                }
                FlightEvent::Part { part, kind, .. } => part_line(clear, *kind, part),
                FlightEvent::Failed { error, .. } => eprintln!("{clear}recording failed: {error}"),
                FlightEvent::Ended { .. } => {}
            }
        };
        let result = fly(
            &opened.link,
            &opened.target,
            opened.config,
            &recorder,
            &mission,
            &plan,
            &flight,
            &opts,
            on_event,
            |_, _| {},
        )
        .await;
        if let Some(ticker) = ticker {
            ticker.abort();
            eprint!("{clear}");
        }
        recorder.close().await;
        let flown = result?;
        let Some(report) = flown.report else {
            anyhow::bail!("the flight in {} has no report (no flight plan reached the recorder)", flown.dir.display());
        };
        let json = args.json.then(|| report.json());
        let params = params.as_ref().map(params_json);
        print_report(&report, &flown.dir.display().to_string(), json.as_ref(), params)
    })
}

/// A live line for the parts `fly` shows as they complete (take-off, legs, landing).
/// `clear` first wipes the live progress line when there is one.
fn part_line(clear: &str, kind: SegmentKind, part: &emplan::flightlog::report::PartReport) {
    if matches!(
        kind,
        SegmentKind::Leg(_) | SegmentKind::Takeoff | SegmentKind::Landing
    ) {
        eprintln!("{clear}  {}", super::report::part_line(kind, part));
    }
}

/// What `fly` prints at the end: the report (JSON with `ok` and `log_dir`, or the table).
fn print_report(
    report: &emplan::flightlog::report::FlightReport,
    dir: &str,
    json: Option<&emplan::flightlog::report::ReportJson>,
    px4_parameters: Option<serde_json::Value>,
) -> anyhow::Result<ExitCode> {
    if let Some(report) = json {
        let mut doc = serde_json::to_value(report)?;
        if let Some(map) = doc.as_object_mut() {
            map.insert("ok".into(), true.into());
            map.insert("log_dir".into(), dir.into());
            if let Some(params) = px4_parameters {
                map.insert("px4_parameters".into(), params);
            }
        }
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        super::report::print(report);
        println!("log: {dir}");
    }
    Ok(ExitCode::SUCCESS)
}

/// `fly --service URL`: upload, start and follow the flight through a running service.
fn fly_through(args: &Args, client: &emplan::service::Client) -> anyhow::Result<ExitCode> {
    use emplan::service::remote::{self, Starting};
    let request = args.flight.service_request()?;
    let live_lines = super::progress::shown();
    let quiet = args.json;
    super::runtime()?.block_on(async {
        let name = remote::find_mission(client, &args.mission, std::time::Duration::from_secs(60))
            .await?;
        let link = client.get("/api/link").await?.body;
        let builtin = link
            .get("builtin_mock")
            .and_then(|b| b.as_bool())
            .unwrap_or(false);
        let starting = if args.arm || builtin {
            Starting::Service
        } else {
            Starting::Pilot
        };
        let describe = format!("the service at {}", client.url());
        let uploaded = |doc: &serde_json::Value| {
            if quiet {
                return;
            }
            let legs = doc
                .get("sequence")
                .and_then(|s| s.as_array())
                .map_or(0, |s| s.len() + 1);
            eprintln!(
                "flying {} ({legs} legs, {:.1} kJ predicted) on {} autopilot {} through {describe}",
                doc.get("mission").and_then(|m| m.as_str()).unwrap_or(&name),
                doc.get("predicted_mission_kj")
                    .and_then(|k| k.as_f64())
                    .unwrap_or(f64::NAN),
                doc.pointer("/autopilot/flavour")
                    .and_then(|f| f.as_str())
                    .unwrap_or("?"),
                doc.pointer("/autopilot/system_id")
                    .and_then(|f| f.as_u64())
                    .unwrap_or(0),
            );
            if starting == Starting::Pilot {
                eprintln!("uploaded missions are started by the pilot: waiting for arming (or pass --arm)");
            }
        };
        let on_event = |event: &serde_json::Value| {
            if quiet && !live_lines {
                return;
            }
            match event.get("type").and_then(|t| t.as_str()) {
                Some("flight_started") => eprintln!(
                    "armed: recording to {}",
                    event.get("dir").and_then(|d| d.as_str()).unwrap_or("?")
                ),
                Some("part") => {
                    if let Some((kind, part)) = remote::part_of(event) {
                        part_line("", kind, &part);
                    }
                }
                Some("recording_failed") => eprintln!(
                    "recording failed: {}",
                    event.get("error").and_then(|e| e.as_str()).unwrap_or("?")
                ),
                _ => {}
            }
        };
        let flown = remote::fly(
            client,
            &name,
            &request,
            starting,
            std::time::Duration::from_secs_f64(args.timeout_s),
            uploaded,
            on_event,
        )
        .await?;
        let report = emplan::flightlog::report::FlightReport::from_json(&flown.report);
        print_report(&report, &flown.dir, args.json.then_some(&flown.report), None)
    })
}

/// NAME=VALUE pairs.
fn parse_params(pairs: &[String]) -> anyhow::Result<Vec<(String, f64)>> {
    pairs
        .iter()
        .map(|pair| {
            let (name, value) = pair
                .split_once('=')
                .ok_or_else(|| anyhow::anyhow!("--mock-param {pair}: NAME=VALUE expected"))?;
            let value: f64 = value
                .trim()
                .parse()
                .map_err(|_| anyhow::anyhow!("--mock-param {pair}: the value is not a number"))?;
            Ok((name.trim().to_string(), value))
        })
        .collect()
}

/// Warns (stderr) of every parameter the autopilot holds at another value than the vehicle
/// file, and of the ones it did not answer.
fn warn_params(check: &ParamCheck) {
    for d in &check.differences {
        eprintln!(
            "warning: PX4 parameter {} is {} on the vehicle, {} in the vehicle file's [px4] section",
            d.name, d.autopilot_value, d.file_value
        );
    }
    if !check.differences.is_empty() {
        eprintln!(
            "warning: the flight is measured against its legs simulated with the vehicle's values (the planned order is the vehicle file's)"
        );
    }
    let unanswered = check.unanswered();
    if !unanswered.is_empty() {
        eprintln!(
            "warning: PX4 did not answer for {}: the vehicle file's values are assumed",
            unanswered.join(", ")
        );
    }
}

/// `{"read": N, "unanswered": [..], "differing": [{"name", "vehicle_file", "autopilot"}]}`.
fn params_json(check: &ParamCheck) -> serde_json::Value {
    serde_json::json!({
        "read": check.read.iter().filter(|(_, v)| v.is_some()).count(),
        "unanswered": check.unanswered(),
        "differing": check.differences.iter().map(|d| serde_json::json!({
            "name": d.name,
            "vehicle_file": d.file_value,
            "autopilot": d.autopilot_value,
        })).collect::<Vec<_>>(),
    })
}

/// Rewrites one terminal line with the part in progress: `leg C -> D: 4.1 s, 2.31 kJ so far of
/// 3.66 kJ predicted`.
async fn progress_line(mut live: tokio::sync::watch::Receiver<emplan::session::Live>) {
    use emplan::flightlog::segment::SegmentKind;
    let mut every = tokio::time::interval(std::time::Duration::from_millis(500));
    loop {
        every.tick().await;
        let line = {
            let state = live.borrow_and_update();
            state
                .flight
                .as_ref()
                .and_then(|f| f.in_progress.as_ref())
                .map(|(kind, part)| {
                    let what = match kind {
                        SegmentKind::Takeoff => "take-off".to_string(),
                        SegmentKind::Leg(_) => format!("leg {} -> {}", part.from, part.to),
                        SegmentKind::Settle(_) => format!("settling at {}", part.to),
                        SegmentKind::Hover(_) => format!("hovering at {}", part.to),
                        SegmentKind::Landing => "landing".to_string(),
                    };
                    let so_far = part
                        .measured_j
                        .map_or("-".into(), |j| format!("{:.2}", j / 1000.0));
                    let predicted = part.predicted_j.map_or(String::new(), |j| {
                        format!(" of {:.2} kJ predicted", j / 1000.0)
                    });
                    format!(
                        "{what}: {:.1} s, {so_far} kJ so far{predicted}",
                        part.duration_s
                    )
                })
        };
        if let Some(line) = line {
            eprint!("\r\x1b[2K  {line}");
        }
    }
}
