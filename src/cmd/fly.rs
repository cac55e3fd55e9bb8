//! `emplan fly`: plan, battery check, verified upload, start (arming only with `--arm`; the
//! built-in mock has no pilot, so without `--connect` emplan starts it), record until landed,
//! and print the per-leg energy report. Without `--connect` the built-in mock autopilot flies
//! the mission in simulated time with the vehicle's physics.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use emplan::session::{fly, spawn_recorder, FlightEvent, FlyError, FlyOptions, RecorderConfig};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Mission file: emplan .toml, QGroundControl .plan or .waypoints
    mission: PathBuf,
    #[command(flatten)]
    link: super::LinkArgs,
    #[command(flatten)]
    flight: super::FlightArgs,
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
    /// Print one JSON document (the report) instead of text
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let json = args.json;
    match fly_mission(args) {
        Err(err) if json => {
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
                None => ("plan".to_string(), false),
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
    let live_lines = std::io::stderr().is_terminal();
    let quiet = args.json;
    super::runtime()?.block_on(async {
        let opened = args.link.open_with(mock, Some(model.vehicle.clone())).await?;
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
            ..FlyOptions::default()
        };
        let on_event = |event: &FlightEvent| {
            if quiet && !live_lines {
                return;
            }
            match event {
                FlightEvent::Started { dir, .. } => {
                    eprintln!("armed: recording to {}", dir.display())
                }
                FlightEvent::Part { part, kind, .. } => {
                    if matches!(kind, emplan::flightlog::segment::SegmentKind::Leg(_) | emplan::flightlog::segment::SegmentKind::Takeoff | emplan::flightlog::segment::SegmentKind::Landing) {
                        eprintln!("  {}", super::report::part_line(*kind, part));
                    }
                }
                FlightEvent::Failed { error, .. } => eprintln!("recording failed: {error}"),
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
        recorder.close().await;
        let flown = result?;
        let Some(report) = flown.report else {
            anyhow::bail!("the flight in {} has no report (no flight plan reached the recorder)", flown.dir.display());
        };
        if args.json {
            let mut doc = serde_json::to_value(report.json())?;
            if let Some(map) = doc.as_object_mut() {
                map.insert("ok".into(), true.into());
                map.insert("log_dir".into(), flown.dir.display().to_string().into());
            }
            println!("{}", serde_json::to_string_pretty(&doc)?);
        } else {
            super::report::print(&report);
            println!("log: {}", flown.dir.display());
        }
        Ok(ExitCode::SUCCESS)
    })
}
