//! `emplan report LOG_DIR...`: each recorded flight replayed and measured against its plan
//! (predicted vs measured energy per leg, take-off, settles, hovers, landing, totals, flags);
//! several flights of the same legs combined (mean and spread per leg), and a flight with its
//! resumptions (`fly --resume`) as one mission, every waypoint once. Also the text views of a
//! report that `fly`, `record` and `replay` print.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use emplan::flightlog::flight_plan::FlightPlan;
use emplan::flightlog::replay::Analysis;
use emplan::flightlog::report::{combine, joined, FlightReport, PartReport};
use emplan::flightlog::resume::{CombinedMissionsJson, FlownMission};
use emplan::flightlog::segment::{SegmentConfig, SegmentKind};
use emplan::output::Output;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Flight directories (with flight.tlog), or directories holding them
    #[arg(required = true)]
    log_dirs: Vec<PathBuf>,
    /// Mission file naming the waypoints, for logs without plan.json
    #[arg(long)]
    mission: Option<PathBuf>,
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

/// The report as a table.
pub fn print(report: &FlightReport) {
    println!(
        "flight {}{}",
        report.flight,
        if report.complete { "" } else { " (incomplete)" }
    );
    println!(
        "{:<26} {:>12} {:>12} {:>8} {:>8}  flags",
        "part", "predicted_kj", "measured_kj", "error", "time_s"
    );
    let row = |name: String, p: &PartReport| {
        let kj = |j: Option<f64>| j.map_or("-".to_string(), |j| format!("{:.3}", j / 1000.0));
        println!(
            "{:<26} {:>12} {:>12} {:>8} {:>8.1}  {}",
            name,
            kj(p.predicted_j),
            kj(p.measured_j),
            p.error_pct().map_or("-".into(), |e| format!("{e:+.1}%")),
            p.duration_s,
            p.flags
                .iter()
                .map(|f| f.name())
                .collect::<Vec<_>>()
                .join(",")
        );
    };
    if let Some(t) = &report.takeoff {
        row("take-off".into(), t);
    }
    for (k, leg) in report.legs.iter().enumerate() {
        row(format!("leg {}: {} -> {}", k + 1, leg.from, leg.to), leg);
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
    let error = match (report.predicted_j, report.measured_j) {
        (Some(p), Some(m)) if p > 0.0 => format!("{:+.1}%", (m - p) / p * 100.0),
        _ => "-".into(),
    };
    let kj = |j: Option<f64>| j.map_or("-".to_string(), |j| format!("{:.3}", j / 1000.0));
    println!(
        "{:<26} {:>12} {:>12} {:>8} {:>8.1}  {}",
        "total",
        kj(report.predicted_j),
        kj(report.measured_j),
        error,
        report.duration_s,
        report
            .flags
            .iter()
            .map(|f| f.name())
            .collect::<Vec<_>>()
            .join(",")
    );
}

/// The flight directories named: each directory with a flight.tlog, or the ones inside it.
fn flights(dirs: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for dir in dirs {
        if emplan::flightlog::recorder::is_flight_dir(dir) {
            out.push(dir.clone());
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
        out.extend(inside);
    }
    Ok(out)
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

/// Replays one flight directory or .tlog.
pub fn analyse(
    tlog: &Path,
    mission: Option<&emplan::mission::Mission>,
    model: Option<&emplan::physics::VehicleModel>,
) -> anyhow::Result<Analysis> {
    emplan::session::replay(tlog, mission, model, SegmentConfig::default())
        .with_context(|| format!("replaying {}", tlog.display()))
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mission = args
        .mission
        .as_deref()
        .map(emplan::mission::load)
        .transpose()?;
    let dirs = flights(&args.log_dirs)?;
    // Checked before the replays: never a flight's file, the mission or the vehicle's files.
    let plot = match &args.plot {
        Some(path) => {
            let mut inputs = args.log_dirs.clone();
            inputs.extend(args.mission.iter().cloned());
            inputs.extend(args.model.files());
            let out = Output::new(path, inputs, args.force);
            out.check()?;
            Some(out)
        }
        None => None,
    };
    let model = args.model.model().ok();
    let mut analyses = Vec::new();
    for dir in dirs {
        let tlog = dir.join(emplan::flightlog::recorder::TLOG_FILE);
        let analysis = analyse(&tlog, mission.as_ref(), model.as_ref())?;
        warn_skipped(&tlog, &analysis.replay);
        analyses.push(analysis);
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
            println!("{}", serde_json::to_string_pretty(&report.json())?);
        } else {
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
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        for report in &reports {
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
