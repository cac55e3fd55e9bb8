//! The command line's figures (`plan --plot`, `report --plot`, `study --plot`): drawn by
//! `emplan::plot` (which the service's dashboard draws with too) and written once to the file
//! named, so a write error is reported with the file name.

use std::path::Path;

use anyhow::Context;
use emplan::mission::Mission;
use emplan::physics::Profile;
use emplan::plan::study::Study;
use emplan::planner::Plan;

fn write_svg(path: &Path, svg: Result<String, emplan::plot::PlotError>) -> anyhow::Result<()> {
    let svg = svg.with_context(|| format!("plotting {}", path.display()))?;
    std::fs::write(path, svg).with_context(|| format!("writing {}", path.display()))
}

/// `plan --plot`: the orders of a planned mission.
pub fn plan_svg(path: &Path, mission: &Mission, plan: &Plan) -> anyhow::Result<()> {
    write_svg(path, emplan::plot::plan_svg(mission, plan))
}

/// `study --plot`: histograms of the study's energy ratios.
pub fn study_histogram_svg(path: &Path, study: &Study, profile: Profile) -> anyhow::Result<()> {
    write_svg(path, emplan::plot::study_histogram_svg(study, profile))
}

/// `report --plot`: recorded flights, power over time and energy per leg.
pub fn flight_svg(
    path: &Path,
    analyses: &[emplan::link::telemetry::Analysis],
) -> anyhow::Result<()> {
    write_svg(path, emplan::plot::flight_svg(analyses))
}
