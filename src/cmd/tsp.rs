//! `emplan tsp FILE.atsp`: solve a TSPLIB asymmetric TSP instance (exactly where the solver can
//! prove it) and report the tour, its cost, a proven lower bound and the time taken.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use emplan::tour::{solver, tsplib};

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

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let text = std::fs::read_to_string(&args.file)
        .with_context(|| format!("reading {}", args.file.display()))?;
    let instance = tsplib::parse(&text).with_context(|| format!("{}", args.file.display()))?;
    let options = args.solver.options()?;
    let solved = super::progress::solving(&format!("solving {}", instance.name), || {
        solver::solve(&instance.matrix, &options)
    })
    .with_context(|| format!("solving {}", instance.name))?;
    let report = tsplib::solution_json(&instance, &solved);
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
