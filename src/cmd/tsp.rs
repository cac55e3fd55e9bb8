//! `emplan tsp FILE.atsp`: solve a TSPLIB asymmetric TSP instance (exactly where the solver can
//! prove it) and report the tour, its cost, a proven lower bound and the time taken.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use emplan::plan::{solver, tsplib};
use serde::Serialize;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// TSPLIB instance (TYPE ATSP, EXPLICIT FULL_MATRIX weights)
    file: PathBuf,
    /// Print one JSON document instead of text
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    solver: super::SolverArgs,
}

/// The JSON of DESIGN.md; `tour` lists TSPLIB's 1-based node ids, starting at node 1.
#[derive(Serialize)]
struct TspJson {
    instance: String,
    dimension: usize,
    cost: f64,
    optimal: bool,
    lower_bound: f64,
    tour: Vec<usize>,
    seconds: f64,
    solver: solver::Solver,
    gap_pct: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    heuristic_cost: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    nodes: Option<u64>,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let text = std::fs::read_to_string(&args.file)
        .with_context(|| format!("reading {}", args.file.display()))?;
    let instance = tsplib::parse(&text).with_context(|| format!("{}", args.file.display()))?;
    let solved = solver::solve(&instance.matrix, &args.solver.options()?)
        .with_context(|| format!("solving {}", instance.name))?;
    let tour = &solved.tour;
    let report = TspJson {
        instance: instance.name,
        dimension: instance.dimension,
        cost: tour.cost,
        optimal: tour.optimal,
        lower_bound: tour.lower_bound,
        tour: std::iter::once(1)
            .chain(tour.order.iter().map(|&k| k + 1))
            .collect(),
        seconds: solved.seconds,
        solver: solved.solver,
        gap_pct: solved.gap_pct,
        heuristic_cost: solved.heuristic_cost,
        nodes: solved.nodes,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{}: dimension {}, cost {}, {} (lower bound {}, gap {:.3}%), {} in {:.3} s",
            report.instance,
            report.dimension,
            report.cost,
            if report.optimal {
                "optimal"
            } else {
                "not proven optimal"
            },
            report.lower_bound,
            report.gap_pct,
            report.solver,
            report.seconds
        );
        println!(
            "tour: {}",
            report
                .tour
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    Ok(ExitCode::SUCCESS)
}
