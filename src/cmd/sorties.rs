//! The sorties of `emplan plan --sorties` as text, after the plan's table (the split itself is
//! `emplan::planner`'s; this prints its JSON view).

use emplan::planner::json::SortiesJson;
use emplan::tour::sorties::Method;

/// The sorties as text.
pub fn print(report: &SortiesJson) {
    println!(
        "sorties: {} {}, {:.1} kJ in total ({}) against {:.1} kJ for the mission as one tour; a battery has {:.1} kJ usable",
        report.batteries,
        if report.batteries == 1 { "battery" } else { "batteries" },
        report.total_kj,
        match report.method {
            Method::Exact => "proven optimal: exact split",
            Method::Heuristic => "heuristic split, not proven optimal",
        },
        report.single_tour_kj,
        report.budget_kj,
    );
    for (k, s) in report.sorties.iter().enumerate() {
        println!(
            "  sortie {}: take-off {:.1} + legs {:.1} + hovering {:.1} + landing {:.1} = {:.1} kJ ({:.0}% of the budget)",
            k + 1,
            s.takeoff_kj,
            s.legs_kj,
            s.hover_kj,
            s.landing_kj,
            s.total_kj,
            s.budget_pct
        );
        println!("    origin -> {} -> origin", s.sequence.join(" -> "));
    }
}
