//! `emplan fly`: plan, battery check, verified upload, start (arming only with `--arm`; the
//! built-in mock has no pilot, so without `--connect` emplan starts it), record until landed,
//! and print the per-leg energy report. Without `--connect` the built-in mock autopilot flies
//! the mission in simulated time with the vehicle's physics. The flight itself is the library
//! session's (`emplan::session`); with `--service` the service's (`emplan::service::remote`).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;

use super::flight_output::{self as output, Flying, Lines};
use emplan::service::remote::{self, Starting};
use emplan::session::{
    parse_param, FlyError, FlyJson, FlyOptions, Load, MockFlight, Px4Parameters, RecorderConfig,
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
            println!(
                "{}",
                serde_json::to_string_pretty(&output::failure(&err).json())?
            );
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
    let params = (args.mock_param.iter())
        .map(|p| parse_param(p).map_err(|e| anyhow::anyhow!("--mock-param {e}")))
        .collect::<anyhow::Result<Vec<_>>>()?;
    if !params.is_empty() && !builtin {
        anyhow::bail!("--mock-param is for the built-in mock (no --connect)");
    }
    let truth = match &args.mock_vehicle {
        Some(_) if !builtin => {
            anyhow::bail!("--mock-vehicle is for the built-in mock (no --connect)")
        }
        Some(dir) => emplan::physics::Vehicle::load(dir)
            .with_context(|| format!("--mock-vehicle {}", dir.display()))?,
        None => model.vehicle.clone(),
    };
    let (home, profile) = (mission.origin.home, plan.profile);
    let (speedup, seed, loss) = (args.speedup, args.mock_seed, args.mock_loss);
    let mock = MockFlight {
        home,
        profile,
        truth,
        params,
        speedup,
        seed,
        loss,
        signing_key: None,
    };
    let radius = args.flight.acceptance_radius_m;
    let load = Load {
        mission: &mission,
        plan: &plan,
        flight: &flight,
        acceptance_radius_m: radius,
        vehicle: &model.vehicle,
    };
    let lines = Lines::new(args.json);
    super::runtime()?.block_on(async {
        let session = args.link.open_with(Some(mock)).await?;
        let recorder = session.recorder(RecorderConfig::new(&args.log_dir));
        let timeout = Duration::from_secs_f64(args.timeout_s);
        let options = FlyOptions {
            arm: args.arm || builtin,
            timeout,
            ..FlyOptions::default()
        };
        let flying = Flying {
            mission: &mission.name,
            legs: flight.legs.len(),
            predicted_kj: flight.battery.total_j / 1000.0,
            flavour: session.target.flavour,
            system_id: session.target.system_id,
            place: format!("at {}", session.describe),
            log_dir: Some(&args.log_dir),
            pilot: !args.arm && !builtin,
        };
        let ticker = lines.ticker(recorder.live());
        let checked =
            |params: Option<&_>| lines.flying(params.map(Px4Parameters::from).as_ref(), &flying);
        let result = session
            .fly(&recorder, &load, &options, checked, |e| lines.event(e))
            .await;
        lines.stop(ticker);
        recorder.close().await;
        let flown = result?;
        let Some(report) = flown.report else {
            anyhow::bail!(
                "the flight in {} has no report (no flight plan reached the recorder)",
                flown.dir.display()
            );
        };
        let params = flown.params.as_ref().map(Px4Parameters::from);
        let doc = FlyJson::new(report.json(), &flown.dir.display().to_string(), params);
        output::print(&report, &doc, args.json)
    })
}

/// `fly --service URL`: upload, start and follow the flight through a running service, once
/// its vehicle link is up (within `--discover-s`).
fn fly_through(args: &Args, client: &emplan::service::Client) -> anyhow::Result<ExitCode> {
    let request = args.flight.service_request()?;
    let lines = Lines::new(args.json);
    let discover = Duration::from_secs_f64(args.link.discover_s.clamp(0.0, 3.2e7));
    super::runtime()?.block_on(async {
        let name = remote::find_mission(client, &args.mission, Duration::from_secs(60)).await?;
        let link = remote::wait_for_vehicle(client, discover).await?;
        let builtin = link.builtin_mock;
        let starting = if args.arm || builtin {
            Starting::Service
        } else {
            Starting::Pilot
        };
        let uploaded = |answer: &emplan::service::wire::UploadAnswer| {
            let flying = Flying {
                mission: &answer.upload.plan.mission,
                legs: answer.upload.plan.sequence.len() + 1,
                predicted_kj: answer.upload.plan.predicted_mission_kj,
                flavour: answer.upload.autopilot.flavour,
                system_id: answer.upload.autopilot.system_id,
                place: format!("through the service at {}", client.url()),
                log_dir: None,
                pilot: starting == Starting::Pilot,
            };
            lines.flying(answer.px4_parameters.as_ref(), &flying);
        };
        let timeout = Duration::from_secs_f64(args.timeout_s);
        let flown = remote::fly(client, &name, &request, starting, timeout, uploaded, |e| {
            lines.remote_event(e)
        })
        .await?;
        let report = emplan::flightlog::report::FlightReport::from_json(&flown.report);
        let doc = FlyJson::new(flown.report, &flown.dir, flown.upload.px4_parameters);
        output::print(&report, &doc, args.json)
    })
}
