//! `emplan record --connect URL --log-dir DIR`: records a flight flown from any ground station:
//! asks for the telemetry it needs, waits for arming, has the session measure the mission the
//! autopilot holds (`emplan::session::held`: named after `--mission`'s waypoints, priced with
//! the vehicle model), logs
//! until the vehicle has landed and disarmed (or Ctrl-C, which closes the files cleanly), and
//! prints the report.

use std::path::PathBuf;
use std::process::ExitCode;

use emplan::flightlog::watch::Policy;
use emplan::session::{
    held_flight_plan, keep_streams, request_streams, spawn_recorder, FlightEvent, Known,
    RecorderConfig,
};

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    link: super::LinkArgs,
    /// Directory the flight's log directory is made in
    #[arg(long, default_value = "flights")]
    log_dir: PathBuf,
    /// Mission file naming the waypoints of the mission the vehicle flies
    #[arg(long)]
    mission: Option<PathBuf>,
    #[command(flatten)]
    model: super::VehicleArgs,
    /// The energy guard: warn when the battery is projected to land below its reserve and at
    /// the point of no return (warn), or nothing (off); a flight another ground station flies
    /// is only warned about (no rtl)
    #[arg(long, value_name = "POLICY", default_value = "warn")]
    guard: Policy,
    #[command(flatten)]
    pack: super::pack::PackArgs,
    /// Print one JSON document (the report) instead of text
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if args.link.connect.is_none() {
        anyhow::bail!("record needs --connect URL: the vehicle whose flight to record (the built-in mock flies only for `emplan fly`)");
    }
    if args.guard == Policy::Rtl {
        anyhow::bail!("--guard rtl: record watches a flight another ground station flies and only warns (warn or off)");
    }
    let mission = args
        .mission
        .as_deref()
        .map(emplan::mission::load)
        .transpose()?;
    let model = args.model.model()?;
    emplan::flightlog::recorder::check_log_dir(&args.log_dir)?;
    let pack = args.pack.learned(&args.log_dir, &model.vehicle.name)?;
    let guard_start = pack.as_ref().and_then(|p| p.learned.guard_start());
    super::runtime()?.block_on(async {
        let opened = args.link.open().await?;
        let (link, target) = (&opened.link, opened.target);
        let recorder = spawn_recorder(
            link,
            RecorderConfig::new(&args.log_dir).with_ledger(args.pack.given()),
        );
        // Subscribed before asking for the streams: connecting and asking took 1.3 s on
        // ArduCopter SITL, and a vehicle armed meanwhile must not be missed.
        let mut events = recorder.subscribe();
        request_streams(link, &target).await?;
        let rally = mission.as_ref().map_or(&[][..], |m| &m.rally[..]);
        let autopilot_return = match args.guard {
            Policy::Off => emplan::session::guard::AutopilotReturn::defaults(target.flavour, 0.0, rally),
            _ => emplan::session::guard::autopilot_return(link, &target, rally).await?,
        };
        eprintln!(
            "recording flights of {:?} autopilot {} on {} into {}; Ctrl-C stops",
            target.flavour,
            target.system_id,
            opened.describe,
            args.log_dir.display()
        );
        let watch = async {
            loop {
                match events.recv().await {
                    Ok(FlightEvent::Started { dir, .. }) => {
                        eprintln!("armed: recording to {}", dir.display());
                        // What the vehicle flies: its mission, read back now.
                        let known = Known::Named(mission.as_ref());
                        match held_flight_plan(link, &target, opened.transfer, known, &model).await {
                            Ok(mut plan) => {
                                plan.pack = pack.as_ref().map(super::pack::Pack::used);
                                if args.guard != Policy::Off {
                                    match emplan::session::guard::setup(&model.vehicle, model.profile, target.flavour, &plan, args.guard, &autopilot_return, model.wind) {
                                        Ok(setup) => plan.guard = Some(emplan::flightlog::guard::GuardSetup { start: guard_start.clone(), ..setup }),
                                        Err(e) => eprintln!("the energy guard cannot price the way home: {e}; not guarding this flight"),
                                    }
                                }
                                recorder.set_plan(plan)
                            }
                            Err(e) => eprintln!("{e}; recording the telemetry only"),
                        }
                    }
                    Ok(FlightEvent::Part { kind, part, .. }) => {
                        eprintln!("  {}", super::report::part_line(kind, &part))
                    }
                    Ok(FlightEvent::Failed { error, .. }) => eprintln!("recording failed: {error}"),
                    Ok(FlightEvent::Guard { note, .. }) => eprintln!("  energy guard at {:.0} s: {}", note.t_s, note.message),
                    Ok(FlightEvent::Repriced { repriced, .. }) => eprintln!("  at {:.0} s: {}", repriced.t_s, emplan::flightlog::report::repriced_line(&repriced)),
                    Ok(FlightEvent::Ended { dir, report, .. }) => return Some((dir, report.map(|r| *r))),
                    Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => {}
                    Err(tokio::sync::broadcast::error::RecvError::Closed) => return None,
                }
            }
        };
        let ended = tokio::select! {
            ended = watch => ended,
            _ = tokio::signal::ctrl_c() => None,
            streams = keep_streams(link, &target) => {
                if let Err(e) = streams { eprintln!("telemetry requests: {e}"); }
                None
            }
        };
        recorder.close().await;
        match ended {
            Some((dir, Some(report))) => {
                if args.json {
                    println!("{}", serde_json::to_string_pretty(&report.json())?);
                } else {
                    super::report::print(&report);
                    println!("log: {}", dir.display());
                }
            }
            Some((dir, None)) => println!("log: {} (no mission to measure against)", dir.display()),
            None => eprintln!("stopped; every flight recorded so far is closed (replay it with `emplan replay DIR/flight.tlog`)"),
        }
        Ok(ExitCode::SUCCESS)
    })
}
