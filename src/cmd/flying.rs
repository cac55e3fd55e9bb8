//! `emplan fly`'s options of the built-in mock, and what it prints while and after it flies,
//! alone or through a service: the parameter warnings and the "flying" line before the upload,
//! a line per part as the flight goes (and on a terminal the part in progress, rewritten), the
//! report at the end, and the failure document.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;

use emplan::flightlog::report::{FlightReport, PartReport};
use emplan::flightlog::segment::SegmentKind;
use emplan::service::remote::RemoteError;
use emplan::service::wire::UploadAnswer;
use emplan::service::wire::{segment_kind, Event};
use emplan::session::{
    parse_param, FlightEvent, FlyError, FlyFailure, FlyJson, Live, MockFlight, OpenError,
    ParamSection, Px4Parameters, Session,
};

/// How `fly` runs the built-in mock autopilot (no `--connect`).
#[derive(Debug, clap::Args)]
pub struct MockArgs {
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
    /// Built-in mock only: a steady wind it flies in and reports as PX4 does (WIND_COV),
    /// SPEED@FROM_DEG (6@270: 6 m/s from the west)
    #[arg(long, value_name = "SPEED@FROM_DEG", allow_hyphen_values = true)]
    mock_wind: Option<emplan::physics::Wind>,
    /// Built-in mock only: the wind changes in flight, T_S=SPEED@FROM_DEG: T_S seconds after
    /// arming it becomes SPEED@FROM_DEG (60=8@270), flown in and reported (what `--wind live`
    /// prices the rest of the flight again on)
    #[arg(long, value_name = "T_S=SPEED@FROM_DEG")]
    mock_wind_change: Option<emplan::sim::WindChange>,
    /// Built-in mock only (for tests): the serial number its smart battery gives in
    /// SMART_BATTERY_INFO, the pack's name without --pack
    #[arg(long, value_name = "SERIAL", hide = true)]
    mock_pack_serial: Option<u32>,
}

impl MockArgs {
    /// Refuses what no flight can take, before anything else (`--mock-loss`; with `service`,
    /// `--mock-vehicle`).
    pub fn check(&self, service: bool) -> anyhow::Result<()> {
        if !(0.0..=1.0).contains(&self.mock_loss) {
            anyhow::bail!(
                "--mock-loss {}: a probability between 0 and 1 is required",
                self.mock_loss
            );
        }
        if service && self.mock_vehicle.is_some() {
            anyhow::bail!("--mock-vehicle is for the built-in mock (not --service)");
        }
        Ok(())
    }

    /// The mock flying `mission` with `profile` (`planned`: the planning vehicle); `builtin`:
    /// no `--connect` was given (else its options are refused).
    pub fn mock(
        &self,
        mission: &emplan::mission::Mission,
        profile: emplan::physics::Profile,
        planned: &emplan::physics::Vehicle,
        builtin: bool,
    ) -> anyhow::Result<MockFlight> {
        let params = (self.mock_param.iter())
            .map(|p| parse_param(p).map_err(|e| anyhow::anyhow!("--mock-param {e}")))
            .collect::<anyhow::Result<Vec<_>>>()?;
        if !params.is_empty() && !builtin {
            anyhow::bail!("--mock-param is for the built-in mock (no --connect)");
        }
        let truth = match &self.mock_vehicle {
            Some(_) if !builtin => {
                anyhow::bail!("--mock-vehicle is for the built-in mock (no --connect)")
            }
            Some(dir) => emplan::physics::Vehicle::load(dir)
                .with_context(|| format!("--mock-vehicle {}", dir.display()))?,
            None => planned.clone(),
        };
        if self.mock_pack_serial.is_some() && !builtin {
            anyhow::bail!("--mock-pack-serial is for the built-in mock (no --connect)");
        }
        if (self.mock_wind.is_some() || self.mock_wind_change.is_some()) && !builtin {
            anyhow::bail!(
                "--mock-wind and --mock-wind-change are for the built-in mock (no --connect)"
            );
        }
        Ok(MockFlight {
            wind: self.mock_wind,
            wind_change: self.mock_wind_change,
            home: mission.origin.home,
            profile,
            truth,
            params,
            speedup: self.speedup,
            seed: self.mock_seed,
            loss: self.mock_loss,
            signing_key: None,
            pack_serial: self.mock_pack_serial,
        })
    }

    /// `err` from starting the built-in mock, naming `--mock-vehicle` when the mock could not
    /// fly that vehicle.
    pub fn explain(&self, err: anyhow::Error) -> anyhow::Error {
        let cannot_fly = matches!(
            err.downcast_ref::<OpenError>(),
            Some(OpenError::Mock(emplan::sim::SimError::Vehicle(_)))
        );
        match &self.mock_vehicle {
            Some(dir) if cannot_fly => err.context(format!("--mock-vehicle {}", dir.display())),
            _ => err,
        }
    }
}

/// Ends `fly`: with `--json`, a failure prints its document (and the error) and exits 1.
pub fn finish(outcome: anyhow::Result<ExitCode>, json: bool) -> anyhow::Result<ExitCode> {
    match outcome {
        Err(err) if json => {
            println!("{}", serde_json::to_string_pretty(&failure(&err).json())?);
            eprintln!("error: {err:#}");
            Ok(ExitCode::FAILURE)
        }
        outcome => outcome,
    }
}

/// The `fly --json` failure document of `err`: its stage, whether the autopilot had accepted
/// the mission.
pub fn failure(err: &anyhow::Error) -> FlyFailure {
    let message = format!("{err:#}");
    if let Some(e) = err.downcast_ref::<FlyError>() {
        return FlyFailure::of(e, &message);
    }
    if let Some(r) = err.downcast_ref::<RemoteError>() {
        return FlyFailure::new(&r.stage(), r.accepted(), &message);
    }
    let stage = if err.downcast_ref::<emplan::service::ClientError>().is_some() {
        "service"
    } else if matches!(err.downcast_ref::<OpenError>(), Some(OpenError::Link(_)))
        || err.downcast_ref::<emplan::link::LinkError>().is_some()
    {
        "connect"
    } else {
        "plan"
    };
    FlyFailure::new(stage, false, &message)
}

/// What the "flying" line names.
pub struct Flying<'a> {
    pub mission: &'a str,
    pub legs: usize,
    pub predicted_kj: f64,
    pub flavour: emplan::link::Flavour,
    pub system_id: u8,
    /// `at URL` or `through the service at URL`.
    pub place: String,
    /// The log directory, when flights are recorded here.
    pub log_dir: Option<&'a std::path::Path>,
    /// The pilot starts the mission.
    pub pilot: bool,
}

impl Flying<'_> {
    /// A flight of `flight` (of `mission`) on `session`'s autopilot, logged in `log_dir`.
    pub fn of<'a>(
        session: &Session,
        mission: &'a emplan::mission::Mission,
        flight: &emplan::planner::Flight<'_>,
        log_dir: &'a std::path::Path,
        pilot: bool,
    ) -> Flying<'a> {
        Flying {
            mission: &mission.name,
            legs: flight.legs.len(),
            predicted_kj: flight.battery.total_j / 1000.0,
            flavour: session.target.flavour,
            system_id: session.target.system_id,
            place: format!("at {}", session.describe),
            log_dir: Some(log_dir),
            pilot,
        }
    }

    /// The flight a service answered an upload with (at `url`).
    pub fn uploaded<'a>(answer: &'a UploadAnswer, url: &str, pilot: bool) -> Flying<'a> {
        let (plan, autopilot) = (&answer.upload.plan, answer.upload.autopilot);
        Flying {
            mission: &plan.mission,
            legs: plan.sequence.len() + 1,
            predicted_kj: plan.predicted_mission_kj,
            flavour: autopilot.flavour,
            system_id: autopilot.system_id,
            place: format!("through the service at {url}"),
            log_dir: None,
            pilot,
        }
    }
}

/// The lines of one flight: quiet with `--json` (but parts still shown on a terminal).
#[derive(Debug, Clone, Copy)]
pub struct Lines {
    quiet: bool,
    live: bool,
}

impl Lines {
    pub fn new(json: bool) -> Lines {
        Lines {
            quiet: json,
            live: super::progress::shown(),
        }
    }

    /// Before the upload: the parameter warnings, then what is flown where.
    pub fn flying(&self, params: Option<(&Px4Parameters, ParamSection)>, f: &Flying<'_>) {
        if let Some((params, section)) = params {
            warn_params(params, section);
        }
        if self.quiet {
            return;
        }
        let logging = f
            .log_dir
            .map(|d| format!("; logging to {}", d.display()))
            .unwrap_or_default();
        eprintln!(
            "flying {} ({} legs, {:.1} kJ predicted) on {} autopilot {} {}{logging}",
            f.mission,
            f.legs,
            f.predicted_kj,
            autopilot_name(f.flavour),
            f.system_id,
            f.place
        );
        if f.pilot {
            eprintln!(
                "uploaded missions are started by the pilot: waiting for arming (or pass --arm)"
            );
        }
    }

    /// On a terminal: the part in progress on a line of its own, rewritten twice a second.
    pub fn ticker(
        &self,
        live: tokio::sync::watch::Receiver<Live>,
    ) -> Option<tokio::task::JoinHandle<()>> {
        self.live.then(|| tokio::spawn(progress_line(live)))
    }

    /// Stops the ticker and clears its line.
    pub fn stop(&self, ticker: Option<tokio::task::JoinHandle<()>>) {
        if let Some(ticker) = ticker {
            ticker.abort();
            eprint!("{}", self.clear());
        }
    }

    fn clear(&self) -> &'static str {
        if self.live {
            "\r\x1b[2K"
        } else {
            ""
        }
    }

    fn shown(&self) -> bool {
        !self.quiet || self.live
    }

    /// A flight event of the recorder here.
    pub fn event(&self, event: &FlightEvent) {
        if !self.shown() {
            return;
        }
        let clear = self.clear();
        match event {
            FlightEvent::Started { dir, .. } => {
                eprintln!("{clear}armed: recording to {}", dir.display())
            }
            FlightEvent::Part { part, kind, .. } => part_line(clear, *kind, part),
            FlightEvent::Failed { error, .. } => eprintln!("{clear}recording failed: {error}"),
            FlightEvent::Guard { note, .. } => guard_line(clear, note),
            FlightEvent::Repriced { repriced, .. } => eprintln!(
                "{clear}  at {:.0} s: {}",
                repriced.t_s,
                emplan::flightlog::report::repriced_line(repriced)
            ),
            FlightEvent::Ended { .. } => {}
        }
    }

    /// An event of the service's stream (its recorder's).
    pub fn remote_event(&self, event: &Event) {
        if !self.shown() {
            return;
        }
        match event {
            Event::FlightStarted { dir, .. } => {
                eprintln!("armed: recording to {}", dir.display())
            }
            Event::Part(p) => {
                if let Some(kind) = segment_kind(p.kind, p.index) {
                    part_line("", kind, &p.part.to_part());
                }
            }
            Event::RecordingFailed { error, .. } => eprintln!("recording failed: {error}"),
            Event::Guard { note, .. } => guard_line("", note),
            _ => {}
        }
    }
}

/// A line for each of the energy guard's notes: what it saw, what it did.
fn guard_line(clear: &str, note: &emplan::flightlog::watch::GuardNote) {
    eprintln!(
        "{clear}  energy guard at {:.0} s: {}",
        note.t_s, note.message
    );
}

/// A live line for the parts `fly` shows as they complete (take-off, legs, landing).
/// `clear` first wipes the live progress line when there is one.
fn part_line(clear: &str, kind: SegmentKind, part: &PartReport) {
    if matches!(
        kind,
        SegmentKind::Leg(_) | SegmentKind::Takeoff | SegmentKind::Landing
    ) {
        eprintln!("{clear}  {}", super::report::part_line(kind, part));
    }
}

/// The exit code of a flight that landed with waypoints of its mission left (the energy guard
/// sent it home, the pilot took over): the report says which, and how to fly them.
pub const EXIT_INCOMPLETE: u8 = 3;

/// An autopilot's name as its makers write it.
pub fn autopilot_name(flavour: emplan::link::Flavour) -> &'static str {
    match flavour {
        emplan::link::Flavour::Px4 => "PX4",
        emplan::link::Flavour::ArduPilot => "ArduPilot",
        emplan::link::Flavour::Generic => "a generic MAVLink",
    }
}

/// What `fly` says after the table: the order flown, the battery at landing, the next step.
pub struct After<'a> {
    /// The order flown and its saving, in a sentence (None: not known here).
    pub order: Option<String>,
    /// The plan's battery check (None: flown through a service).
    pub battery: Option<&'a emplan::physics::budget::BatteryCheck>,
    pub mission: &'a std::path::Path,
    pub log_dir: &'a std::path::Path,
}

/// A word for a POSIX shell: as it is when it holds nothing the shell reads, else in single
/// quotes.
pub fn shell_word(word: &str) -> String {
    let plain = !word.is_empty()
        && word
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-./:=@%+,".contains(c));
    if plain {
        word.to_string()
    } else {
        format!("'{}'", word.replace('\'', "'\\''"))
    }
}

/// The battery at landing against the reserve: the pack as the energy guard measured it when
/// the flight was guarded, else the vehicle file's, full at take-off.
fn battery_line(
    report: &FlightReport,
    battery: &emplan::physics::budget::BatteryCheck,
) -> Option<String> {
    let drawn_j = report.measured_j?;
    let share = battery.reserve_pct / 100.0;
    if share >= 1.0 {
        return None;
    }
    let pack_j = battery.usable_j / (1.0 - share);
    let (scale, soc, whose) = match &report.guard {
        Some(g) => (
            g.capacity_ratio,
            g.state_of_charge_at_takeoff.unwrap_or(1.0),
            format!(
                "the pack as the energy guard measured it: {:.2} of its label, {:.0}% charged at take-off",
                g.capacity_ratio,
                g.state_of_charge_at_takeoff.unwrap_or(1.0) * 100.0
            ),
        ),
        None => (1.0, 1.0, "the vehicle file's pack, full at take-off".to_string()),
    };
    let reserve_j = pack_j * scale * share;
    let left_j = pack_j * scale * soc - drawn_j;
    let verdict = if left_j >= reserve_j {
        "kept"
    } else {
        "NOT kept"
    };
    Some(format!(
        "battery: {:.1} kJ drawn, {:.1} kJ left at landing against the {:.1} kJ reserve: reserve {verdict} ({whose})",
        drawn_j / 1e3,
        left_j / 1e3,
        reserve_j / 1e3
    ))
}

/// What `fly` prints at the end: the JSON document, or the table, the log directory, the order
/// flown, the battery at landing and the next step. Exits [`EXIT_INCOMPLETE`] when waypoints
/// of the mission were left.
pub fn print(
    report: &FlightReport,
    doc: &FlyJson,
    json: bool,
    after: &After<'_>,
) -> anyhow::Result<ExitCode> {
    if json {
        println!("{}", serde_json::to_string_pretty(&doc.json())?);
    } else {
        super::report::print(report);
        println!("log: {}", doc.log_dir);
        if let Some(order) = &after.order {
            println!("{order}");
        }
        if let Some(line) = after.battery.and_then(|b| battery_line(report, b)) {
            println!("{line}");
        }
        let dir = shell_word(&doc.log_dir);
        if report.incomplete() {
            let log_dir = if after.log_dir == std::path::Path::new("flights") {
                String::new()
            } else {
                format!(
                    " --log-dir {}",
                    shell_word(&after.log_dir.to_string_lossy())
                )
            };
            println!(
                "next: after a battery swap, fly the {} waypoint{} left with: emplan fly {} --resume {dir}{log_dir}",
                report.waypoints_left.len(),
                if report.waypoints_left.len() == 1 { "" } else { "s" },
                shell_word(&after.mission.to_string_lossy()),
            );
        } else {
            println!("next: emplan report {dir} (again, with --plot FILE.svg to draw it)");
        }
    }
    if report.incomplete() {
        return Ok(ExitCode::from(EXIT_INCOMPLETE));
    }
    Ok(ExitCode::SUCCESS)
}

/// Warns (stderr) of every parameter the autopilot holds at another value than the vehicle
/// file, and of the ones it did not answer.
pub fn warn_params(params: &Px4Parameters, section: ParamSection) {
    let autopilot = section.autopilot();
    for d in &params.differing {
        eprintln!(
            "warning: {autopilot} parameter {} is {} on the vehicle, {} in the vehicle file's [{}] section",
            d.name,
            d.autopilot,
            d.vehicle_file,
            section.section()
        );
    }
    if !params.differing.is_empty() {
        eprintln!(
            "warning: the flight is measured against its legs simulated with the vehicle's values (the planned order is the vehicle file's)"
        );
    }
    if !params.unanswered.is_empty() {
        eprintln!(
            "warning: {autopilot} did not answer for {}: the vehicle file's values are assumed",
            params.unanswered.join(", ")
        );
    }
}

/// Rewrites one terminal line with the part in progress: `leg C -> D: 4.1 s, 2.31 kJ so far of
/// 3.66 kJ predicted`.
/// The guard's view on the live line: energy left at landing against the reserve, the
/// correction learned, the point of no return.
fn guard_summary(g: &emplan::flightlog::watch::GuardView) -> String {
    if let Some(reason) = &g.reason {
        return format!("; guard: cannot judge ({reason})");
    }
    format!(
        "; at landing {:.0} kJ ({:.0}..{:.0}) vs {:.0} kJ reserve, x{:.2}{}{}",
        g.left_at_landing_kj,
        g.left_at_landing_band_kj[0],
        g.left_at_landing_band_kj[1],
        g.reserve_kj,
        g.correction,
        g.point_of_no_return
            .as_ref()
            .map_or(String::new(), |p| format!(", no return after {p}")),
        if g.returning { ", RETURNING" } else { "" }
    )
}

async fn progress_line(mut live: tokio::sync::watch::Receiver<Live>) {
    let mut every = tokio::time::interval(std::time::Duration::from_millis(500));
    loop {
        every.tick().await;
        let line = {
            let state = live.borrow_and_update();
            state
                .flight
                .as_ref()
                .and_then(|f| f.in_progress.as_ref().map(|p| (f, p)))
                .map(|(f, (kind, part))| {
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
                    let guard = f.guard.as_ref().map_or(String::new(), guard_summary);
                    format!(
                        "{what}: {:.1} s, {so_far} kJ so far{predicted}{guard}",
                        part.duration_s
                    )
                })
        };
        if let Some(line) = line {
            eprint!("\r\x1b[2K  {line}");
        }
    }
}
