//! The command line's figures (`plan --plot`, `report --plot`, `study --histogram`, `packs --plot`): drawn by
//! `emplan::plot` (which the service's dashboard draws with too) into a string and written once
//! through `emplan::output` (never an input, a flight's file or, unforced, an existing file), so
//! a write error is reported with the file name.

use anyhow::Context;
use emplan::mission::Mission;
use emplan::output::Output;
use emplan::physics::Profile;
use emplan::planner::study::Study;
use emplan::planner::Plan;

fn write_svg(out: &Output, svg: Result<String, emplan::plot::PlotError>) -> anyhow::Result<()> {
    let svg = svg.with_context(|| format!("plotting {}", out.path.display()))?;
    Ok(out.write(svg.as_bytes())?)
}

/// `plan --plot`: the orders of a planned mission.
pub fn plan_svg(out: &Output, mission: &Mission, plan: &Plan) -> anyhow::Result<()> {
    write_svg(out, emplan::plot::plan_svg(mission, plan))
}

/// `study --histogram`: histograms of the study's energy ratios.
pub fn study_histogram_svg(out: &Output, study: &Study, profile: Profile) -> anyhow::Result<()> {
    write_svg(out, emplan::plot::study_histogram_svg(study, profile))
}

/// `report --plot`: recorded flights, power over time and energy per leg.
pub fn flight_svg(
    out: &Output,
    analyses: &[emplan::flightlog::replay::Analysis],
) -> anyhow::Result<()> {
    write_svg(out, emplan::plot::flight_svg(analyses))
}

/// `packs --plot`: each pack's capacity and resistance over its cycles.
pub fn packs_svg(out: &Output, packs: &[emplan::plot::PackHistory]) -> anyhow::Result<()> {
    write_svg(out, emplan::plot::packs_svg(packs))
}
