//! `emplan fly`: plan, battery check, verified upload, start (arming only with `--arm`; the
//! built-in mock, the default without `--connect`, has no pilot and is always started), record
//! until landed, and print the per-leg energy report. The flight is the library session's
//! (`emplan::session`); with `--service` the service's (`emplan::service::remote`).
//! `--resume FLIGHT_DIR` flies only what an earlier flight left (`emplan::flightlog::resume`).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use super::flying::{self, Flying, Lines};
use emplan::flightlog::watch::Policy;
use emplan::service::remote::{self, Starting};
use emplan::session::{FlyError, FlyOptions, Load, ParamSection, Px4Parameters, RecorderConfig};

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
    /// Resume an earlier flight of this mission cut short (sent home, a battery swap): fly only
    /// the waypoints it did not visit (a hover cut short is not a visit), nor any flight that
    /// resumed it since (found beside it or in --log-dir), planned again from the origin; the
    /// new flight's plan.json names the last of them (`resumes`)
    #[arg(long, value_name = "FLIGHT_DIR", conflicts_with = "service")]
    resume: Option<PathBuf>,
    /// The energy guard in flight: warn when the battery is projected to land below its
    /// reserve and at the point of no return (warn), and also send the vehicle home in time
    /// to keep the reserve (rtl), or nothing (off). A service's flights are guarded as
    /// `emplan serve --guard` says
    #[arg(long, value_name = "POLICY", conflicts_with = "service")]
    guard: Option<Policy>,
    #[command(flatten)]
    mock: flying::MockArgs,
    /// Print one JSON document (the report) instead of text
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let json = args.json;
    flying::finish(fly_mission(args), json)
}

fn fly_mission(mut args: Args) -> anyhow::Result<ExitCode> {
    let service = args.service.client()?;
    args.mock.check(service.is_some())?;
    let timeout = super::seconds("timeout-s", args.timeout_s)?;
    if let Some(client) = service {
        return fly_through(&args, &client, timeout);
    }
    // A flight log that cannot be written ends the command before anything is uploaded.
    emplan::flightlog::recorder::check_log_dir(&args.log_dir).map_err(FlyError::LogDir)?;
    let mission = emplan::mission::load(&args.mission)?;
    if let Some(warning) = mission.unknown_warning() {
        eprintln!("warning: {warning}");
    }
    let resumed = (args.resume.as_deref()).map(|d| resuming(&mission, d, &args.log_dir));
    let resumed = resumed.transpose()?;
    let mission = resumed.as_ref().map_or(mission, |(_, left)| left.clone());
    args.flight.learn(&args.log_dir)?;
    if let (Some(pack), false) = (&args.flight.on_pack, args.json) {
        eprintln!("{}", pack.line());
    }
    let (model, planned) = args.flight.plan_first(&mission)?;
    let builtin = args.link.connect.is_none();
    let mock = args
        .mock
        .mock(&mission, model.profile, &model.vehicle, builtin)?;
    let lines = Lines::new(args.json);
    super::runtime()?.block_on(async {
        let session = (args.link.open_with(Some(mock)).await).map_err(|e| args.mock.explain(e))?;
        let (model, planned) = autopilot_profile(&args.flight, &session, &mission, model, planned)?;
        let model = args.flight.in_live_wind(&session, model).await?;
        let (mission, plan) = (args.flight)
            .planned_at(&session, mission, planned, &model, args.json)
            .await?;
        let flight = args.flight.flight(&plan)?;
        let order = if args.json {
            None
        } else {
            Some(order_flown(&args.flight, &mission, &model, &plan)?)
        };
        let load = Load {
            guard: args.guard.unwrap_or_default(),
            resumes: resumed.as_ref().map(|(name, _)| name.as_str()),
            live_wind: args.flight.live_wind().then_some(&model),
            ..(args.flight).load(&mission, &plan, &flight, &model.vehicle)
        };
        let recorder = session
            .recorder(RecorderConfig::new(&args.log_dir).with_ledger(args.flight.pack.given()));
        let options = FlyOptions {
            arm: args.arm || builtin,
            timeout,
            ..FlyOptions::default()
        };
        let pilot = !args.arm && !builtin;
        let flying = Flying::of(&session, &mission, &flight, &args.log_dir, pilot);
        let checked = |check: Option<&emplan::session::ParamCheck>| {
            let params = check.map(|c| (Px4Parameters::from(c), c.section));
            lines.flying(params.as_ref().map(|(p, s)| (p, *s)), &flying)
        };
        let ticker = lines.ticker(recorder.live());
        let result = session
            .fly(&recorder, &load, &options, checked, |e| lines.event(e))
            .await;
        lines.stop(ticker);
        recorder.close().await;
        let (report, doc) = result?.reported()?;
        let after = flying::After {
            order,
            battery: Some(flight.battery),
            mission: &args.mission,
            log_dir: &args.log_dir,
        };
        flying::print(&report, &doc, args.json, &after)
    })
}

/// The order flown in a sentence: which, and (the energy order) what the plan predicts it
/// saves against the distance order, priced by the same vehicle.
fn order_flown(
    flight: &super::FlightArgs,
    mission: &emplan::mission::Mission,
    model: &emplan::physics::VehicleModel,
    plan: &emplan::planner::Plan,
) -> anyhow::Result<String> {
    use emplan::planner::{FlightChoice, FlownOrder};
    use emplan::tour::Objective;
    let choice = flight.choice();
    if let Some(k) = choice.sortie {
        return Ok(format!(
            "order flown: sortie {k} of the minimum-energy split into sorties"
        ));
    }
    let energy = match choice.order {
        FlownOrder::Distance => {
            return Ok("order flown: the distance order (--order distance)".into())
        }
        FlownOrder::Listed => {
            return Ok("order flown: the order the mission file lists (--order listed)".into())
        }
        FlownOrder::Energy => plan.cheapest(Objective::Energy),
    };
    let Some(energy) = energy else {
        return Ok("order flown: the energy order".into());
    };
    let proven = match &energy.proof {
        Some(p) if p.optimal => " (proven optimal)",
        _ => "",
    };
    let distance_choice = FlightChoice {
        order: FlownOrder::Distance,
        sortie: None,
        allow_infeasible: true,
    };
    let distance_plan = distance_choice.plan(mission, model, flight.solver.options()?)?;
    let Some(distance) = distance_plan.cheapest(Objective::Distance) else {
        return Ok(format!("order flown: the energy order{proven}"));
    };
    let direction = match distance.direction {
        emplan::tour::Direction::Forward => "forward",
        emplan::tour::Direction::Reverse => "reverse",
    };
    let saving_j = distance.energy_j - energy.energy_j;
    let against = if saving_j > 0.005e3 {
        format!(
            "predicted to save {:.2} kJ ({:.1}%) against the distance order flown {direction} ({:.2} kJ)",
            saving_j / 1e3,
            saving_j / distance.energy_j * 100.0,
            distance.energy_j / 1e3
        )
    } else {
        format!("the distance order flown {direction} costs the same: nothing to gain")
    };
    Ok(format!(
        "order flown: the energy order{proven}, legs {:.2} kJ, {against}",
        energy.energy_j / 1e3
    ))
}

/// The profile of the autopilot found (PX4: px4, ArduPilot: ardupilot), unless `--profile`
/// chose one: the model re-opened with it and the mission planned again (`planned` None stays
/// None: it is planned from the vehicle's home later). A vehicle directory without that
/// profile's table keeps the profile it had, with a warning.
fn autopilot_profile(
    flight: &super::FlightArgs,
    session: &emplan::session::Session,
    mission: &emplan::mission::Mission,
    model: emplan::physics::VehicleModel,
    planned: Option<emplan::planner::Plan>,
) -> anyhow::Result<(emplan::physics::VehicleModel, Option<emplan::planner::Plan>)> {
    use emplan::link::Flavour;
    use emplan::physics::Profile;
    let wanted = match session.target.flavour {
        Flavour::Px4 => Profile::Px4,
        Flavour::ArduPilot => Profile::Ardupilot,
        Flavour::Generic => return Ok((model, planned)),
    };
    if flight.model.profile.is_some() || model.profile == wanted {
        return Ok((model, planned));
    }
    let (source, _) = flight.model.source();
    let reopened = match emplan::physics::VehicleModel::open(&source, Some(wanted)) {
        Ok(m) => m.with_wind(model.wind),
        Err(e) => {
            eprintln!(
                "warning: the autopilot flies the {wanted} profile but {e}: pricing with {} (--profile chooses)",
                model.profile
            );
            return Ok((model, planned));
        }
    };
    eprintln!(
        "pricing with the {wanted} profile: the vehicle is {} (--profile chooses another)",
        flying::autopilot_name(session.target.flavour)
    );
    let planned = match planned {
        Some(_) => {
            let plan = flight.plan_with(mission, &reopened)?;
            flight.flight(&plan)?;
            Some(plan)
        }
        None => None,
    };
    Ok((reopened, planned))
}

/// `fly --resume DIR`: the flight the new one resumes (the one in `dir`, or the last that
/// resumed it since, found beside it or in `log_dir`) and the mission of the waypoints none of
/// them visited (said on stderr, with any warning of a torn log).
fn resuming(
    mission: &emplan::mission::Mission,
    dir: &std::path::Path,
    log_dir: &std::path::Path,
) -> anyhow::Result<(String, emplan::mission::Mission)> {
    let resumption = emplan::session::resume_flight(dir, mission, &[log_dir])
        .map_err(|e| anyhow::Error::new(e).context(format!("--resume {}", dir.display())))?;
    eprintln!("{}", resumption.summary());
    for note in &resumption.notes {
        eprintln!("warning: {note}");
    }
    Ok((resumption.resumes().to_string(), resumption.mission))
}

/// `fly --service URL`: upload, start and follow the flight through a running service, once
/// its vehicle link is up (within `--discover-s`).
fn fly_through(
    args: &Args,
    client: &emplan::service::Client,
    timeout: Duration,
) -> anyhow::Result<ExitCode> {
    if args.flight.wind.is_some() {
        anyhow::bail!(
            "--wind with --service: the service prices in the wind it was started with (emplan serve --wind)"
        );
    }
    let upload = args.flight.service_request()?;
    let lines = Lines::new(args.json);
    let asked = remote::FlyRequest {
        mission: &args.mission,
        upload: &upload,
        arm: args.arm,
        discover: Duration::from_secs_f64(args.link.discover_s.clamp(0.0, 3.2e7)),
        timeout,
    };
    super::runtime()?.block_on(async {
        let uploaded = |answer: &_, starting| {
            let flying = Flying::uploaded(answer, client.url(), starting == Starting::Pilot);
            let params = answer.px4_parameters.as_ref();
            lines.flying(params.map(|p| (p, ParamSection::Px4)), &flying);
        };
        let flown = remote::fly(client, asked, uploaded, |e| lines.remote_event(e)).await?;
        let (report, doc) = flown.reported();
        let after = flying::After {
            order: None,
            battery: None,
            mission: &args.mission,
            log_dir: &args.log_dir,
        };
        flying::print(&report, &doc, args.json, &after)
    })
}
