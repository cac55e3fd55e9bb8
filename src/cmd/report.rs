//! `emplan report LOG_DIR...`: each recorded flight replayed and measured against its plan
//! (predicted vs measured energy per leg, take-off, settles, hovers, landing, totals, flags);
//! several flights of the same legs combined (mean and spread per leg), and a flight with its
//! resumptions (`fly --resume`) as one mission, every waypoint once. Also the text views of a
//! report that `fly`, `record` and `replay` print.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use emplan::flightlog::energy::Flag;
use emplan::flightlog::flight_plan::{FlightPlan, ORIGIN_NAME};
use emplan::flightlog::replay::Analysis;
use emplan::flightlog::report::{combine, joined, FlightReport, PartReport};
use emplan::flightlog::resume::{CombinedMissionsJson, FlownMission};
use emplan::flightlog::segment::{SegmentConfig, SegmentKind};
use emplan::output::Output;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Flight directories (with flight.tlog), directories holding them, or the flight
    /// controller's own logs (PX4 .ulg, ArduPilot .bin: told by their first bytes)
    #[arg(required = true)]
    log_dirs: Vec<PathBuf>,
    /// Mission file naming the waypoints, for logs without plan.json; an onboard log holding no
    /// mission (a ULog) is measured against it planned as `fly` plans it
    #[arg(long)]
    mission: Option<PathBuf>,
    /// The plan.json an onboard log is measured against (default: plan.json beside it, else
    /// the mission in the log, else --mission)
    #[arg(long, value_name = "PLAN_JSON")]
    plan: Option<PathBuf>,
    /// With one flight directory: the flight controller's own log of the same flight, measured
    /// against the flight's plan and shown leg by leg beside the .tlog's measurement
    #[arg(long, value_name = "FILE")]
    onboard: Option<PathBuf>,
    #[command(flatten)]
    model: super::VehicleArgs,
    /// Print one JSON document instead of text (one flight: its report; several: the combined
    /// report)
    #[arg(long)]
    json: bool,
    /// Draw power over time with the legs marked, and predicted vs measured energy per leg
    #[arg(long, value_name = "FILE.svg")]
    plot: Option<PathBuf>,
    /// Replace an existing --plot file (never an input nor a file inside a flight directory)
    #[arg(long)]
    force: bool,
}

/// One line of a part: `leg A -> B: 5.62 kJ measured, 5.61 predicted (+0.2%), 11.3 s [flags]`.
pub fn part_line(kind: SegmentKind, p: &PartReport) -> String {
    let what = match kind {
        SegmentKind::Takeoff => "take-off".to_string(),
        SegmentKind::Leg(_) => format!("leg {} -> {}", p.from, p.to),
        SegmentKind::Settle(_) => format!("settle at {}", p.to),
        SegmentKind::Hover(_) => format!("hover at {}", p.to),
        SegmentKind::Landing if p.from != ORIGIN_NAME => format!("return: {} -> home", p.from),
        SegmentKind::Landing => "landing".to_string(),
    };
    let kj = |j: Option<f64>| j.map_or("-".to_string(), |j| format!("{:.2}", j / 1000.0));
    let error = p
        .error_pct()
        .map_or(String::new(), |e| format!(" ({e:+.1}%)"));
    let flags = if p.flags.is_empty() {
        String::new()
    } else {
        format!(
            " [{}]",
            p.flags
                .iter()
                .map(|f| f.name())
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    format!(
        "{what}: {} kJ measured, {} kJ predicted{error}, {:.1} s{flags}",
        kj(p.measured_j),
        kj(p.predicted_j),
        p.duration_s
    )
}

/// The report as a table, with a legend of what needs one and, for a mission left
/// unfinished, the waypoints left.
pub fn print(report: &FlightReport) {
    let source = report.source.as_ref().map_or(String::new(), |s| {
        let hz = s.battery_hz.map_or("-".into(), |h| format!("{h:.1}"));
        format!(", measured from its {} (battery {hz} Hz)", s.format)
    });
    println!(
        "flight {}{}{source}",
        report.flight,
        if report.complete { "" } else { " (incomplete)" }
    );
    let flags = |f: &[Flag]| f.iter().map(|f| f.name()).collect::<Vec<_>>().join(",");
    // The flags column only when a part has flags; the total's own `incomplete` (the flight
    // cut off) is said in the first line.
    let flagged = report.parts().any(|p| !p.flags.is_empty());
    let kj = |j: Option<f64>| j.map_or("-".to_string(), |j| format!("{:.3}", j / 1000.0));
    let line = |cells: [String; 5], f: String| {
        let [name, predicted, measured, error, time_s] = cells;
        let f = if flagged {
            format!("  {f}")
        } else {
            String::new()
        };
        println!("{name:<26} {predicted:>12} {measured:>12} {error:>8} {time_s:>8}{f}");
    };
    let header = ["part", "predicted_kj", "measured_kj", "error", "time_s"];
    line(header.map(String::from), "flags".into());
    let row = |name: String, p: &PartReport| {
        let error = p.error_pct().map_or("-".into(), |e| format!("{e:+.1}%"));
        let time_s = format!("{:.1}", p.duration_s);
        let cells = [name, kj(p.predicted_j), kj(p.measured_j), error, time_s];
        line(cells, flags(&p.flags));
    };
    if let Some(t) = &report.takeoff {
        row("take-off".into(), t);
    }
    for (k, leg) in report.legs.iter().enumerate() {
        let via = match leg.via_points {
            0 => String::new(),
            1 => " via 1 point".to_string(),
            n => format!(" via {n} points"),
        };
        row(
            format!("leg {}: {} -> {}{via}", k + 1, leg.from, leg.to),
            leg,
        );
    }
    // A point's settle and hover as one part: the model and the measurement split its time
    // at different moments (FlightReport::at_points), so apart they do not compare.
    let at_points = report.at_points();
    if let Some(all) = at_points.iter().cloned().reduce(|a, b| joined(&a, &b)) {
        row(format!("settle + hover ({})", at_points.len()), &all);
    }
    if let Some(l) = &report.landing {
        row("landing".into(), l);
    }
    if let Some(r) = &report.return_home {
        let to = report.return_to.as_deref().unwrap_or("home");
        row(format!("return: {} -> {to}", r.from), r);
    }
    let error = report
        .total_error_pct()
        .map_or("-".into(), |e| format!("{e:+.1}%"));
    let time_s = format!("{:.1}", report.duration_s);
    let total = [
        "total".into(),
        kj(report.predicted_j),
        kj(report.measured_j),
        error,
        time_s,
    ];
    line(total, String::new());
    legend(report, at_points.len(), flagged);
    for breach in &report.breaches {
        println!("FLAG {}", breach.line());
    }
    // Each block (a survey, a scan) as one: its legs predicted and measured, its photos.
    for block in &report.blocks {
        println!("{}", block.line());
    }
    // The photos the autopilot reported: one line per point with photos, one per photo apart.
    for line in emplan::flightlog::photos::lines(&report.photos) {
        println!("{line}");
    }
}

/// What the table's rows and flags mean, and what a mission cut short left.
fn legend(report: &FlightReport, points: usize, flagged: bool) {
    if points > 0 {
        println!(
            "settle + hover ({points}): the stops at the {points} points summed, the braking into each point and the hover there (apart they do not compare: the model and the measurement split a point's time at different moments)"
        );
    }
    if let Some(r) = &report.return_home {
        let price = r.predicted_j.map_or(String::new(), |j| {
            format!(", priced {:.1} kJ by the guard", j / 1000.0)
        });
        let to = report.return_to.as_deref().unwrap_or("home");
        println!(
            "return: the energy guard sent the vehicle home from {}{price}; it flew to {to} and landed in place of the plan",
            r.from
        );
    }
    if report.incomplete() {
        println!(
            "total: what the flight drew against the whole plan's price; no error, as the mission was not finished"
        );
    }
    if flagged {
        let mut seen: Vec<Flag> = report
            .parts()
            .flat_map(|p| p.flags.iter().copied())
            .collect();
        seen.sort();
        seen.dedup();
        let said: Vec<String> = (seen.iter())
            .map(|f| format!("{}: {}", f.name(), f.meaning()))
            .collect();
        println!("flags: {}", said.join("; "));
    }
    if report.incomplete() {
        println!(
            "mission incomplete: {} waypoint{} left: {}",
            report.waypoints_left.len(),
            if report.waypoints_left.len() == 1 {
                ""
            } else {
                "s"
            },
            report.waypoints_left.join(", ")
        );
    }
}

/// The logs named: a .tlog, a flight directory's flight.tlog, the flight.tlog of each flight
/// directory inside a directory, or an onboard log (any other file: refused by its reader when
/// it is none).
fn flights(dirs: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for dir in dirs {
        if dir.is_file() {
            out.push(dir.clone());
            continue;
        }
        if emplan::flightlog::recorder::is_flight_dir(dir) {
            out.push(dir.join(emplan::flightlog::recorder::TLOG_FILE));
            continue;
        }
        let inside = emplan::session::flight_dirs(dir)
            .with_context(|| format!("reading {}", dir.display()))?;
        if inside.is_empty() {
            anyhow::bail!(
                "{}: not a flight directory (no flight.tlog) and holds none",
                dir.display()
            );
        }
        out.extend((inside.into_iter()).map(|d| d.join(emplan::flightlog::recorder::TLOG_FILE)));
    }
    Ok(out)
}

/// Whether `path` is measured as a .tlog: not an onboard log by its first bytes nor named as one
/// (.ulg, .bin).
fn is_tlog(path: &Path) -> bool {
    let named_onboard = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ulg") || e.eq_ignore_ascii_case("bin"));
    !named_onboard && !emplan::flightlog::onboard::is_onboard_log(path)
}

/// Says on stderr what a replay of `tlog` skipped: a torn last record, each corrupt span.
pub fn warn_skipped(tlog: &Path, replay: &emplan::flightlog::replay::Replay) {
    if let Some(torn) = replay.torn_tail {
        eprintln!(
            "{}: the log ends in a torn record at byte {torn} (a recording cut short): replayed up to it",
            tlog.display()
        );
    }
    for gap in &replay.gaps {
        let time = |t: Option<f64>, none: &str| t.map_or(none.to_string(), |t| format!("{t:.1} s"));
        eprintln!(
            "warning: {}: {} bytes at byte {} are not MAVLink records: skipped, replayed on from the next frame (vehicle time {} to {} lost; parts overlapping it flagged log_gap)",
            tlog.display(),
            gap.bytes,
            gap.offset,
            time(gap.from_s, "the start"),
            time(gap.to_s, "the end"),
        );
    }
}

/// Says on stderr where an onboard log tore, and the records it refused as corrupt.
fn warn_torn(path: &Path, analysis: &Analysis) {
    let source = analysis.report.source.as_ref();
    if let Some(s) = source.and_then(|s| s.skipped.as_ref()) {
        eprintln!(
            "warning: {}: {} record{} refused as corrupt, the first at byte {} ({}: {}): measured without {} (parts overlapping {} flagged log_gap)",
            path.display(),
            s.count,
            if s.count == 1 { "" } else { "s" },
            s.offset,
            s.record,
            s.reason,
            if s.count == 1 { "it" } else { "them" },
            if s.count == 1 { "it" } else { "them" },
        );
    }
    let tear = source.and_then(|s| s.tear.as_ref());
    if let Some(t) = tear {
        eprintln!(
            "warning: {}: the log tore at byte {} ({}){}: measured up to it",
            path.display(),
            t.offset,
            t.reason,
            t.after_s
                .map_or(String::new(), |s| format!(", {s:.1} s into it"))
        );
    }
}

/// Measures one log: a .tlog (see [`analyse`]) or the flight controller's own.
pub fn measure(path: &Path, from: emplan::session::PlanFrom<'_>) -> anyhow::Result<Analysis> {
    if is_tlog(path) {
        let analysis = emplan::session::replay_priced(
            path,
            (from.mission, from.model),
            from.price_with,
            SegmentConfig::default(),
        )
        .with_context(|| format!("replaying {}", path.display()))?;
        warn_skipped(path, &analysis.replay);
        return Ok(analysis);
    }
    // Its errors name the file.
    let analysis = emplan::session::replay_onboard(path, from, SegmentConfig::default())?;
    warn_torn(path, &analysis);
    Ok(analysis)
}

/// The vehicle a report's predictions were priced with when `--vehicle` re-priced them, in the
/// JSON (`"priced_with"` at the report's top level, docs/json.md).
#[derive(Debug, Clone, serde::Serialize)]
pub struct PricedWith {
    /// The vehicle file's `name`.
    pub vehicle: String,
    /// The vehicle directory given.
    pub dir: String,
    pub profile: emplan::physics::Profile,
}

impl PricedWith {
    fn of(model: &emplan::physics::VehicleModel, dir: &Path) -> PricedWith {
        PricedWith {
            vehicle: model.vehicle.name.clone(),
            dir: dir.display().to_string(),
            profile: model.profile,
        }
    }

    fn line(&self) -> String {
        format!(
            "re-priced with the vehicle {} ({}, {} profile): every prediction below is its own, not the flight plan's",
            self.vehicle, self.dir, self.profile
        )
    }
}

/// What priced a flight's predictions, in the JSON (`"priced_by"`, docs/json.md): the vehicle
/// and profile (the flight plan's record of them, or the vehicle that priced it now), the
/// vehicle directory when one given priced it now, and the wind (None: still air).
#[derive(Debug, Clone, serde::Serialize)]
pub struct PricedBy {
    pub flight: String,
    /// The vehicle file's `name` (None: the flight plan does not say).
    pub vehicle: Option<String>,
    /// The vehicle directory `--vehicle` named, when it re-priced the flight.
    pub dir: Option<String>,
    /// None: the flight plan does not say.
    pub profile: Option<String>,
    pub wind: Option<emplan::physics::Wind>,
}

impl PricedBy {
    pub fn of(analysis: &Analysis, dir: Option<&Path>) -> PricedBy {
        let plan = analysis.segmenter.plan();
        let priced = plan.priced_by.as_ref();
        PricedBy {
            flight: analysis.report.flight.clone(),
            vehicle: priced.map(|p| p.vehicle.clone()),
            dir: dir.map(|d| d.display().to_string()),
            profile: priced.map(|p| p.profile.clone()),
            wind: plan.wind.filter(|w| !w.is_calm()),
        }
    }

    /// `priced by the vehicle V (DIR), the P profile, in still air`.
    pub fn line(&self) -> String {
        if self.vehicle.is_none() && self.profile.is_none() {
            return format!(
                "flight {}: its plan does not say which vehicle and profile priced it{}",
                self.flight,
                self.wind_words()
                    .map_or(String::new(), |w| format!(" (priced {w})"))
            );
        }
        let unknown = || "not recorded".to_string();
        format!(
            "flight {} priced by the vehicle {}{}, the {} profile, {}",
            self.flight,
            self.vehicle.clone().unwrap_or_else(unknown),
            self.dir
                .as_ref()
                .map_or(String::new(), |d| format!(" ({d})")),
            self.profile.clone().unwrap_or_else(unknown),
            self.wind_words().unwrap_or_else(|| "in still air".into())
        )
    }

    fn wind_words(&self) -> Option<String> {
        self.wind.map(|w| {
            format!(
                "in a wind of {:.1} m/s from {:.0} deg",
                w.speed_m_s, w.from_deg
            )
        })
    }
}

/// A report document with the vehicle that re-priced it and what priced each flight beside
/// its own fields.
#[derive(serde::Serialize)]
struct Priced<'a, T: serde::Serialize, B: serde::Serialize> {
    #[serde(flatten)]
    doc: &'a T,
    #[serde(skip_serializing_if = "Option::is_none")]
    priced_with: Option<&'a PricedWith>,
    priced_by: B,
}

/// Prints `doc` as JSON with `"priced_with"` when re-priced and `"priced_by"`.
pub fn print_json<T: serde::Serialize, B: serde::Serialize>(
    doc: &T,
    priced: Option<&PricedWith>,
    priced_by: B,
) -> anyhow::Result<()> {
    let doc = Priced {
        doc,
        priced_with: priced,
        priced_by,
    };
    println!("{}", serde_json::to_string_pretty(&doc)?);
    Ok(())
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mission = args
        .mission
        .as_deref()
        .map(emplan::mission::load)
        .transpose()?;
    let logs = flights(&args.log_dirs)?;
    if args.onboard.is_some() && logs.len() != 1 {
        anyhow::bail!("--onboard compares one flight: name one flight directory");
    }
    // Checked before the replays: never a flight's file, the mission or the vehicle's files.
    let plot = match &args.plot {
        Some(path) => {
            let mut inputs = args.log_dirs.clone();
            inputs.extend(args.mission.iter().cloned());
            inputs.extend(args.plan.iter().cloned());
            inputs.extend(args.onboard.iter().cloned());
            inputs.extend(args.model.files());
            let out = Output::new(path, inputs, args.force);
            out.check()?;
            Some(out)
        }
        None => None,
    };
    // Each flight priced with --profile, else the profile it was flown with (its plan's, else
    // its autopilot's: an onboard log's, a .tlog's), else the vehicle's.
    let profiles = match args.model.profile {
        Some(profile) => vec![Some(profile); logs.len()],
        None => (logs.iter())
            .map(|log| emplan::session::flown_profile(log, args.plan.as_deref()))
            .collect::<Result<Vec<_>, _>>()?,
    };
    // With --vehicle every flight is priced anew with it (plan.json keeps the prices of the
    // vehicle it was flown with); without, a plan found carries its own prices.
    let mut models = std::collections::HashMap::new();
    for &profile in &profiles {
        if models.contains_key(&profile) {
            continue;
        }
        let chosen = super::VehicleArgs {
            vehicle: args.model.vehicle.clone(),
            profile,
        };
        let model = match &args.model.vehicle {
            Some(_) => Some(chosen.model()?),
            None => chosen.model().ok(),
        };
        models.insert(profile, model);
    }
    let model_of = |k: usize| models.get(&profiles[k]).and_then(Option::as_ref);
    let priced = (args.model.vehicle.as_deref())
        .zip(model_of(0))
        .map(|(dir, model)| PricedWith::of(model, dir));
    let from_of = |k: usize| emplan::session::PlanFrom {
        plan: args.plan.as_deref(),
        mission: mission.as_ref(),
        model: model_of(k),
        price_with: priced.is_some().then_some(model_of(k)).flatten(),
    };
    let from = from_of(0);
    let mut analyses = Vec::new();
    for (k, log) in logs.iter().enumerate() {
        analyses.push(measure(log, from_of(k))?);
    }
    let priced_by: Vec<PricedBy> = (analyses.iter())
        .map(|a| PricedBy::of(a, args.model.vehicle.as_deref()))
        .collect();
    if let (Some(onboard), [tlog]) = (&args.onboard, analyses.as_slice()) {
        // Measured against the plan the .tlog was: one flight, two logs.
        let plan_json = logs[0].with_file_name(emplan::flightlog::recorder::PLAN_FILE);
        let from = emplan::session::PlanFrom {
            plan: plan_json
                .is_file()
                .then_some(plan_json.as_path())
                .or(from.plan),
            ..from
        };
        let other = measure(onboard, from)?;
        let sources = emplan::flightlog::report::compare_sources(&tlog.report, &other.report);
        if args.json {
            print_json(&sources, priced.as_ref(), &priced_by[0])?;
        } else {
            if let Some(p) = &priced {
                println!("{}", p.line());
            }
            println!("{}", priced_by[0].line());
            print_sources(&sources);
        }
        return Ok(ExitCode::SUCCESS);
    }
    if let Some(out) = &plot {
        super::plot::flight_svg(out, &analyses)?;
        eprintln!("wrote {}", out.path.display());
    }
    let plans: Vec<FlightPlan> = (analyses.iter())
        .map(|a| a.segmenter.plan().clone())
        .collect();
    let reports: Vec<FlightReport> = analyses.into_iter().map(|a| a.report).collect();
    if let [report] = reports.as_slice() {
        if args.json {
            print_json(&report.json(), priced.as_ref(), &priced_by[0])?;
        } else {
            if let Some(p) = &priced {
                println!("{}", p.line());
            }
            println!("{}", priced_by[0].line());
            print(report);
        }
        return Ok(ExitCode::SUCCESS);
    }
    let combined = combine(&reports);
    let flights: Vec<(&FlightPlan, &FlightReport)> = plans.iter().zip(&reports).collect();
    let missions = emplan::flightlog::resume::missions(&flights);
    if args.json {
        let doc = CombinedMissionsJson {
            combined: combined.json(),
            missions: missions.iter().map(FlownMission::json).collect(),
        };
        print_json(&doc, priced.as_ref(), &priced_by)?;
    } else {
        if let Some(p) = &priced {
            println!("{}", p.line());
        }
        for (report, by) in reports.iter().zip(&priced_by) {
            println!("{}", by.line());
            print(report);
            println!();
        }
        print_combined(&combined);
        for mission in &missions {
            println!();
            print_mission(mission);
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// A flight measured from its two logs, leg by leg.
fn print_sources(sources: &emplan::flightlog::report::SourcesJson) {
    let rate = |r: &emplan::flightlog::report::ReportJson| {
        r.source.as_ref().map_or("-".to_string(), |s| {
            let hz = s.battery_hz.map_or("-".into(), |h| format!("{h:.1}"));
            format!("{} (battery {hz} Hz)", s.format)
        })
    };
    println!(
        "flight {}: {} beside {}",
        sources.tlog.flight,
        rate(&sources.tlog),
        rate(&sources.onboard)
    );
    println!(
        "{:<26} {:>12} {:>10} {:>11} {:>8}",
        "leg", "predicted_kj", "tlog_kj", "onboard_kj", "diff"
    );
    let kj = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3}"));
    for (k, leg) in sources.legs.iter().enumerate() {
        println!(
            "{:<26} {:>12} {:>10} {:>11} {:>8}",
            format!("leg {}: {} -> {}", k + 1, leg.from, leg.to),
            kj(leg.predicted_kj),
            kj(leg.tlog_kj),
            kj(leg.onboard_kj),
            leg.difference_pct
                .map_or("-".into(), |d| format!("{d:+.1}%"))
        );
    }
}

/// A flight and its resumptions as one mission: every waypoint and the flight that visited it,
/// each flight's energy and the total, what went wrong.
fn print_mission(mission: &FlownMission) {
    let kj = |j: Option<f64>| j.map_or("-".to_string(), |j| format!("{:.2}", j / 1000.0));
    let names: Vec<&str> = mission.flights.iter().map(|f| f.flight.as_str()).collect();
    println!(
        "mission {} over {} flights ({}): {}",
        mission.mission,
        names.len(),
        names.join(", then "),
        if mission.every_waypoint_once() {
            "every waypoint visited once"
        } else {
            "NOT every waypoint visited once"
        }
    );
    for w in &mission.waypoints {
        let by = match w.visited_by.as_slice() {
            [] => "never visited".to_string(),
            by => by.join(" and "),
        };
        let cut = match w.cut_short_in.as_slice() {
            [] => String::new(),
            cut => format!(" (hover cut short in {})", cut.join(", ")),
        };
        println!(
            "  {}: {by}{cut}; leg {} kJ, settle + hover {} kJ",
            w.name,
            kj(w.leg_j),
            kj(w.at_point_j)
        );
    }
    for f in &mission.flights {
        println!(
            "  flight {}: {} waypoints visited, {} kJ measured, {} kJ predicted, {:.1} s{}",
            f.flight,
            f.visited.len(),
            kj(f.measured_j),
            kj(f.predicted_j),
            f.duration_s,
            if f.complete { "" } else { " (incomplete)" }
        );
    }
    let json = mission.json();
    let kj_json = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
    println!(
        "  total: {} kJ measured, {:.1} s (planned as one flight: {} kJ)",
        kj_json(json.total.measured_kj),
        json.total.duration_s,
        kj_json(json.planned_kj)
    );
    for problem in &mission.problems {
        println!("  problem: {problem}");
    }
}

fn print_combined(combined: &emplan::flightlog::report::CombinedReport) {
    let json = combined.json();
    println!(
        "{} flights combined: per leg, measured kJ mean ± std (n), predicted kJ, error of the mean",
        json.flights.len()
    );
    for leg in &json.legs {
        let measured = leg.measured_stats_kj.as_ref().map_or("-".to_string(), |s| {
            format!("{:.3} ± {:.3} ({})", s.mean, s.std, s.n)
        });
        println!(
            "  {} -> {}: {measured}, predicted {}, {}",
            leg.from,
            leg.to,
            leg.predicted_kj.map_or("-".into(), |p| format!("{p:.3}")),
            leg.error_pct.map_or("-".into(), |e| format!("{e:+.1}%"))
        );
    }
}
